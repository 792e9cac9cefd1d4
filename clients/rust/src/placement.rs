//! Where new envs go when several servers serve one prefix: spread by load as the servers
//! report it (`ServerInfo`: envs held, cores), so a client given one router address fills
//! every server. An env stays on the server it was created on for its life. A server has
//! room for the envs below both its `max_envs` and this party's `max_envs_per_client`.

use std::cmp::Ordering;

use arena_protocol::{ClientTag, ServerInfo};

/// One server's load as placement sees it.
struct Load<'a> {
    envs: u128,
    cores: u128,
    room: u128,
    /// This client's own order among equally loaded servers.
    turn: u64,
    id: &'a str,
}

/// Servers for `count` new envs, in order: each on the server with the fewest envs per
/// core, counting those placed before it and skipping servers at their `max_envs` or
/// where this party holds `max_envs_per_client`; ties
/// go to the fewest envs, then to an order of this client's own (a hash of its tag and
/// the server id), so clients placing at the same moment do not all pick one server.
/// Shorter than `count` when the servers are full; empty when there are none.
pub fn spread(servers: &[ServerInfo], count: usize, client: ClientTag) -> Vec<String> {
    let mut load: Vec<Load> = servers
        .iter()
        .map(|s| Load {
            envs: u128::from(s.envs),
            cores: u128::from(s.cores.max(1)),
            room: u128::from(s.max_envs.saturating_sub(s.envs).min(s.max_envs_per_client.saturating_sub(s.yours))),
            turn: turn(client, &s.server_id),
            id: s.server_id.as_str(),
        })
        .collect();
    let room: u128 = load.iter().map(|server| server.room).sum();
    let mut placed = Vec::with_capacity(count.min(usize::try_from(room).unwrap_or(usize::MAX)));
    for _ in 0..count {
        let open = (0..load.len()).filter(|&i| load[i].room > 0);
        let Some(best) = open.min_by(|&a, &b| lighter(&load[a], &load[b])) else { break };
        load[best].envs += 1;
        load[best].room -= 1;
        placed.push(load[best].id.to_string());
    }
    placed
}

/// By envs per core (exact: cross-multiplied, in u128 so no report can overflow it),
/// then envs, then the client's turn, then id.
fn lighter(a: &Load, b: &Load) -> Ordering {
    (a.envs * b.cores).cmp(&(b.envs * a.cores)).then(a.envs.cmp(&b.envs)).then(a.turn.cmp(&b.turn)).then(a.id.cmp(b.id))
}

/// A stable hash (FNV-1a) of the client's tag and a server id.
fn turn(client: ClientTag, server: &str) -> u64 {
    client
        .0
        .to_be_bytes()
        .iter()
        .chain(server.as_bytes())
        .fold(0xcbf2_9ce4_8422_2325, |hash, &byte| (hash ^ u64::from(byte)).wrapping_mul(0x0000_0100_0000_01b3))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn server(id: &str, envs: u32, cores: u32) -> ServerInfo {
        ServerInfo {
            server_id: id.into(),
            version: "0".into(),
            protocol: arena_protocol::PROTOCOL_VERSION,
            scenarios: vec![],
            envs,
            max_envs: 1024,
            max_envs_per_client: 256,
            yours: 0,
            steps: 0,
            cores,
            rss_bytes: 0,
        }
    }

    const ME: ClientTag = ClientTag(7);

    fn count(placed: &[String], id: &str) -> usize {
        placed.iter().filter(|s| *s == id).count()
    }

    #[test]
    fn equal_servers_take_turns() {
        let servers = [server("b", 0, 2), server("a", 0, 2), server("c", 0, 2)];
        let placed = spread(&servers, 6, ME);
        assert_eq!([count(&placed, "a"), count(&placed, "b"), count(&placed, "c")], [2, 2, 2], "{placed:?}");
        assert_ne!(placed[0], placed[1], "{placed:?}");
    }

    #[test]
    fn a_busy_server_gets_new_envs_only_once_the_others_catch_up() {
        let servers = [server("a", 4, 2), server("b", 0, 2)];
        let placed = spread(&servers, 6, ME);
        assert_eq!(placed[..4], ["b", "b", "b", "b"], "{placed:?}");
        assert_eq!(count(&placed, "a"), 1, "{placed:?}");
    }

    #[test]
    fn more_cores_take_more_envs() {
        // 8 cores against 2: four envs there for each one here.
        let servers = [server("big", 0, 8), server("small", 0, 2)];
        let placed = spread(&servers, 10, ME);
        assert_eq!(count(&placed, "big"), 8, "{placed:?}");
    }

    #[test]
    fn clients_placing_at_once_do_not_all_pick_the_same_idle_server() {
        let servers: Vec<ServerInfo> = (0..4).map(|k| server(&format!("server-{k}"), 0, 2)).collect();
        let first: std::collections::BTreeSet<String> =
            (0..16u128).map(|client| spread(&servers, 1, ClientTag(client))[0].clone()).collect();
        assert!(first.len() >= 3, "16 clients' first envs went to {first:?}");
    }

    #[test]
    fn full_servers_are_skipped_and_reports_cannot_overflow() {
        let mut full = server("full", 1024, 64);
        full.max_envs = 1024;
        let placed = spread(&[full, server("open", 10, 2)], 3, ME);
        assert_eq!(placed, ["open", "open", "open"]);
        let mut huge = server("huge", u32::MAX - 1, u32::MAX);
        huge.max_envs = u32::MAX;
        // "small" is past its max_envs; "huge" has room for one more, then the list ends.
        assert_eq!(spread(&[huge, server("small", u32::MAX - 1, 1)], 2, ME), ["huge"]);
    }

    #[test]
    fn a_server_where_this_party_holds_its_share_is_skipped() {
        let mut mine = server("mine", 10, 8);
        (mine.max_envs_per_client, mine.yours) = (12, 10);
        // Two more fit this party's share on "mine", whatever room the server has.
        let placed = spread(&[mine, server("other", 40, 2)], 5, ME);
        assert_eq!(count(&placed, "mine"), 2, "{placed:?}");
        assert_eq!(count(&placed, "other"), 3, "{placed:?}");
    }

    #[test]
    fn no_server_no_placement() {
        assert!(spread(&[], 3, ME).is_empty());
        assert!(spread(&[server("a", 0, 0)], 2, ME) == ["a", "a"], "a server reporting 0 cores counts as 1");
    }
}
