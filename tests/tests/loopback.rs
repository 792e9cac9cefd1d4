//! Traffic stays where it is sent: a client session listens on nothing and opens TCP
//! connections only to the endpoint it was given, so two clients never connect to each
//! other (read from this process's sockets in /proc, Linux).

mod common;

use std::collections::HashSet;

/// This process's socket inodes.
fn own_sockets() -> HashSet<u64> {
    let links = std::fs::read_dir("/proc/self/fd").expect("/proc/self/fd");
    links
        .flatten()
        .filter_map(|entry| std::fs::read_link(entry.path()).ok())
        .filter_map(|target| {
            let target = target.to_string_lossy().into_owned();
            target.strip_prefix("socket:[")?.strip_suffix(']')?.parse().ok()
        })
        .collect()
}

/// Every TCP socket of the network namespace: (inode, listening, remote port).
fn tcp_sockets() -> Vec<(u64, bool, u16)> {
    let mut out = Vec::new();
    for table in ["/proc/net/tcp", "/proc/net/tcp6"] {
        let Ok(text) = std::fs::read_to_string(table) else { continue };
        for line in text.lines().skip(1) {
            let fields: Vec<&str> = line.split_whitespace().collect();
            let (Some(remote), Some(state), Some(inode)) = (fields.get(2), fields.get(3), fields.get(9)) else {
                continue;
            };
            let port = remote.rsplit(':').next().and_then(|p| u16::from_str_radix(p, 16).ok()).unwrap_or(0);
            if let Ok(inode) = inode.parse() {
                out.push((inode, *state == "0A", port));
            }
        }
    }
    out
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn client_sessions_listen_on_nothing_and_connect_only_to_their_endpoint() {
    let harness = common::start().await;
    let server_port: u16 = harness.endpoint.rsplit(':').next().and_then(|p| p.parse().ok()).expect("a port");
    let before = own_sockets();
    let (first, second) = (harness.client().await, harness.client().await);
    // Both clients find the server and work.
    let server = first.pick_server().await.expect("a server");
    second.server_info(&server).await.expect("an answer");
    tokio::time::sleep(std::time::Duration::from_millis(500)).await;
    let new: HashSet<u64> = own_sockets().difference(&before).copied().collect();
    let sockets: Vec<(u64, bool, u16)> = tcp_sockets().into_iter().filter(|(inode, ..)| new.contains(inode)).collect();
    assert!(!sockets.is_empty(), "the clients opened their connections");
    // The server's side of each connection is the server's (it lives in this process
    // too): the other end is the client's ephemeral port. Clients' own sockets point at
    // the server's port.
    let listening: Vec<_> = sockets.iter().filter(|(_, listening, _)| *listening).collect();
    assert!(listening.is_empty(), "a client session listens: {listening:?}");
    let clients_side: Vec<u16> = sockets.iter().map(|&(_, _, port)| port).collect();
    let to_server = clients_side.iter().filter(|&&port| port == server_port).count();
    assert!(to_server >= 2, "each client connects to the server: {clients_side:?}");
    first.close().await.unwrap();
    second.close().await.unwrap();
}
