//! Load: 64 clients, each on its own Zenoh session, step their own envs at once through
//! one server; every reply is for the right env and sequence, with no cross-talk: each
//! client's observations equal a replay of its episode in process.

mod common;

use arena_protocol::{AgentStart, CreateOptions, Observation, ResetOptions};
use arena_server::env::Env;
use arena_sim::builtin_scenario;

const CLIENTS: u64 = 64;
const STEPS: usize = 15;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sixty_four_clients_stepping_at_once_each_get_their_own_world() {
    let harness = common::start().await;
    // Every client and env first, then all of them step at once.
    let mut clients = Vec::new();
    for _ in 0..CLIENTS {
        let client = harness.client().await;
        let env = harness.env(&client, "merge-random").await;
        clients.push((client, env));
    }
    let mut runs = Vec::new();
    for (k, (client, mut env)) in (0..CLIENTS).zip(clients) {
        runs.push(tokio::spawn(async move {
            let first = env.reset(Some(k), vec![]).await.expect("reset");
            let (start, mut observations) = (first.agents, Vec::new());
            let mut seq = first.seq;
            for _ in 0..STEPS {
                let reply = env.step(vec![]).await.expect("no step fails under load");
                assert_eq!(reply.seq, seq + 1, "client {k}: replies come in sequence");
                seq = reply.seq;
                observations.push(reply.steps.into_iter().map(|s| (s.agent, s.observation)).collect::<Vec<_>>());
            }
            env.close().await.expect("close");
            client.close().await.expect("client close");
            (start, observations)
        }));
    }
    let scenario = builtin_scenario("merge-random").expect("shipped").expect("loads");
    for (k, run) in runs.into_iter().enumerate() {
        let (remote_start, remote): (Vec<AgentStart>, Vec<Vec<(String, Observation)>>) =
            run.await.expect("a client task");
        let mut local = Env::new(scenario.clone(), &CreateOptions::default(), 0).expect("env");
        let reset = local.reset(Some(k as u64), &ResetOptions::default()).expect("reset");
        assert_eq!(remote_start, reset, "client {k} started in another world than its own");
        let mut expected: Vec<Vec<(String, Observation)>> = Vec::new();
        for _ in 0..STEPS {
            let steps = local.step(&[]).expect("step");
            expected.push(steps.into_iter().map(|s| (s.agent, s.observation)).collect());
        }
        assert_eq!(remote, expected, "client {k} saw another world than its own");
    }
    assert!(harness.server.registry().is_empty(), "every env closed");
}
