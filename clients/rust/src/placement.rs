//! Where new envs go when several servers serve one prefix: spread by load as the servers
//! report it (`ServerInfo`: envs held, cores), so a client given one router address fills
//! every server. An env stays on the server it was created on for its life.

use std::cmp::Ordering;

use arena_protocol::ServerInfo;

/// Servers for `count` new envs, in order: each on the server with the fewest envs per
/// core, counting those placed before it; ties go to the fewest envs, then the lowest
/// id. Empty when `servers` is.
pub fn spread(servers: &[ServerInfo], count: usize) -> Vec<String> {
    let mut load: Vec<(u64, u64, &str)> =
        servers.iter().map(|s| (u64::from(s.envs), u64::from(s.cores.max(1)), s.server_id.as_str())).collect();
    let mut placed = Vec::with_capacity(count);
    for _ in 0..count {
        let Some(best) = (0..load.len()).min_by(|&a, &b| lighter(load[a], load[b])) else { break };
        load[best].0 += 1;
        placed.push(load[best].2.to_string());
    }
    placed
}

/// Compares (envs, cores, id) by envs per core (exact: cross-multiplied), then envs, then id.
fn lighter(a: (u64, u64, &str), b: (u64, u64, &str)) -> Ordering {
    (a.0 * b.1).cmp(&(b.0 * a.1)).then(a.0.cmp(&b.0)).then(a.2.cmp(b.2))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn server(id: &str, envs: u32, cores: u32) -> ServerInfo {
        ServerInfo {
            server_id: id.into(),
            version: "0".into(),
            protocol: 3,
            scenarios: vec![],
            envs,
            max_envs: 1024,
            max_envs_per_client: 256,
            steps: 0,
            cores,
            rss_bytes: 0,
        }
    }

    #[test]
    fn equal_servers_take_turns_in_id_order() {
        let servers = [server("b", 0, 2), server("a", 0, 2), server("c", 0, 2)];
        assert_eq!(spread(&servers, 5), ["a", "b", "c", "a", "b"]);
    }

    #[test]
    fn a_busy_server_gets_new_envs_only_once_the_others_catch_up() {
        let servers = [server("a", 4, 2), server("b", 0, 2)];
        assert_eq!(spread(&servers, 6), ["b", "b", "b", "b", "a", "b"]);
    }

    #[test]
    fn more_cores_take_more_envs() {
        // 8 cores against 2: four envs there for each one here.
        let servers = [server("big", 0, 8), server("small", 0, 2)];
        let placed = spread(&servers, 10);
        assert_eq!(placed.iter().filter(|s| *s == "big").count(), 8, "{placed:?}");
    }

    #[test]
    fn no_server_no_placement() {
        assert!(spread(&[], 3).is_empty());
        assert!(spread(&[server("a", 0, 0)], 2) == ["a", "a"], "a server reporting 0 cores counts as 1");
    }
}
