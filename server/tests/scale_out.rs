//! A site as separate processes on loopback: one router (`--route-only`), three servers
//! connected to it as Zenoh clients, two clients given only the router's address. Envs
//! are placed on all three servers and stepped in batches that span them; one server is
//! killed, and its envs report the loss at once, naming it, while the others keep stepping
//! and new envs go elsewhere.

mod common;

use std::collections::BTreeMap;
use std::time::Duration;

use arena_client::{Client, ClientError, RemoteEnv, ScenarioSource};
use arena_protocol::session::{ConnectionFlags, Mode};
use common::{Process, free_port};

async fn client(router: &str) -> Client {
    let flags = ConnectionFlags {
        mode: Some(Mode::Client),
        timeout: 3.0,
        retries: 1,
        ..ConnectionFlags::connecting_to(router)
    };
    Client::connect(&flags).await.expect("connect through the router")
}

/// Waits until the client sees `n` servers.
async fn sees(client: &Client, n: usize) -> Vec<String> {
    for _ in 0..200 {
        let servers = client.servers().await.expect("servers");
        if servers.len() == n {
            return servers;
        }
        tokio::time::sleep(Duration::from_millis(25)).await;
    }
    panic!("never saw {n} servers");
}

async fn create(client: &Client, count: usize) -> Vec<RemoteEnv> {
    let mut envs = Vec::new();
    for server in client.place(count).await.expect("placement") {
        let mut env = client
            .create_env(&server, ScenarioSource::Named("merge-random".into()), Default::default())
            .await
            .expect("create");
        env.reset(Some(envs.len() as u64), vec![]).await.expect("reset");
        envs.push(env);
    }
    envs
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn envs_spread_over_three_servers_and_survive_the_loss_of_one() {
    let router = format!("tcp/127.0.0.1:{}", free_port());
    let _router = Process::start(&["--mode", "router", "--route-only", "--listen", &router]);
    let mut servers: Vec<Process> =
        (0..3).map(|_| Process::start(&["--mode", "client", "--connect", &router])).collect();
    let ids: Vec<String> = servers.iter().map(Process::server_id).collect();

    let (alice, bob) = (client(&router).await, client(&router).await);
    assert_eq!(sees(&alice, 3).await.len(), 3);
    let mut envs = create(&alice, 15).await;
    envs.extend(create(&bob, 15).await);

    // Every server holds ten: placement counted the envs of both clients.
    let mut held: BTreeMap<String, u32> = BTreeMap::new();
    for info in alice.server_infos().await.expect("infos") {
        held.insert(info.server_id, info.envs);
    }
    let expected: BTreeMap<String, u32> = ids.iter().map(|id| (id.clone(), 10)).collect();
    assert_eq!(held, expected);

    let (mut of_alice, mut of_bob): (Vec<_>, Vec<_>) = envs.iter_mut().enumerate().partition(|(i, _)| *i < 15);
    let mut of_alice: Vec<&mut RemoteEnv> = of_alice.iter_mut().map(|(_, env)| &mut **env).collect();
    let mut of_bob: Vec<&mut RemoteEnv> = of_bob.iter_mut().map(|(_, env)| &mut **env).collect();
    for _ in 0..3 {
        for (client, batch) in [(&alice, &mut of_alice), (&bob, &mut of_bob)] {
            let actions = batch.iter().map(|_| Vec::new()).collect();
            let results = client.step_batch(batch, actions).await.expect("a batch");
            assert!(results.iter().all(Result::is_ok), "{results:?}");
        }
    }

    let lost = ids[1].clone();
    servers[1].kill();
    for (client, batch) in [(&alice, &mut of_alice), (&bob, &mut of_bob)] {
        let actions = batch.iter().map(|_| Vec::new()).collect();
        let results = client.step_batch(batch, actions).await.expect("a batch");
        for (env, result) in batch.iter().zip(&results) {
            match result {
                Ok(_) => assert_ne!(env.server(), lost, "an env of the lost server stepped"),
                // ServerGone, not Timeout: no attempt waited out its timeout.
                Err(ClientError::ServerGone { server, .. }) => assert_eq!((env.server(), server), (&*lost, &lost)),
                Err(other) => panic!("{other:?}"),
            }
        }
        assert_eq!(results.iter().filter(|r| r.is_err()).count(), 5, "this client's five envs there are lost");
    }

    // New envs go to the two servers left.
    let mut left: Vec<String> = ids.iter().filter(|id| **id != lost).cloned().collect();
    left.sort();
    assert_eq!(sees(&alice, 2).await, left);
    let placed = alice.place(4).await.expect("placement");
    assert!(placed.iter().all(|server| *server != lost), "{placed:?}");
    alice.close().await.unwrap();
    bob.close().await.unwrap();
}

/// A router that restarts takes every client's liveliness token away from the servers
/// for a moment (so does a link that drops: zenoh-link-tls 1.10.2 closes TLS links under
/// load); Zenoh reconnects both sides and the tokens come back. The envs live on.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn envs_live_on_through_a_router_restart() {
    let router = format!("tcp/127.0.0.1:{}", free_port());
    let mut first_router = Process::start(&["--mode", "router", "--route-only", "--listen", &router]);
    let server = Process::start(&["--mode", "client", "--connect", &router]);
    let alice = client(&router).await;
    assert_eq!(sees(&alice, 1).await, vec![server.server_id()]);
    let mut env = alice
        .create_env(&server.server_id(), ScenarioSource::Named("merge".into()), Default::default())
        .await
        .expect("create");
    env.reset(Some(0), vec![]).await.expect("reset");
    env.step(vec![]).await.expect("a step");

    first_router.kill();
    let _second_router = Process::start(&["--mode", "router", "--route-only", "--listen", &router]);
    assert_eq!(sees(&alice, 1).await, vec![server.server_id()], "the server is found through the new router");
    let step = env.step(vec![]).await.expect("the env steps on after the restart");
    assert!(!step.agents.is_empty(), "the episode goes on");
    let infos = alice.server_infos().await.expect("infos");
    assert_eq!(infos.iter().map(|info| info.envs).collect::<Vec<_>>(), vec![1]);
    alice.close().await.unwrap();
}
