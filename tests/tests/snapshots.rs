//! Env snapshots over real Zenoh sessions (issue 27, point 4): a snapshot taken on one
//! server and restored into a fresh env on another continues bit for bit; a snapshot of
//! another scenario, resolved content, protocol version, or a damaged one, is refused
//! with a message naming what, and the server and the env keep serving.

mod common;

use arena_client::{Action, ClientError, CreateOptions, ErrorCode, MetaAction, OptionValue, RemoteEnv};
use arena_protocol::{StepReply, encode};

/// A step reply's rows, agents and frames as bytes (its `seq` is the env's own count).
fn bits(reply: &StepReply) -> Vec<u8> {
    encode(&(&reply.steps, &reply.agents, &reply.world))
}

/// Steps `env` `n` times with a fixed cycle of meta actions for every live agent; each
/// step's reply (or refusal) as bytes.
async fn run(env: &mut RemoteEnv, live: &mut Vec<String>, n: usize) -> Vec<Vec<u8>> {
    use MetaAction::{Faster, Idle, LaneLeft, LaneRight, Slower};
    let cycle = [Idle, Faster, Idle, Slower, Idle, Idle, LaneLeft, Idle, Idle, Idle, Slower, Idle, LaneRight, Idle];
    let mut replies = Vec::new();
    for k in 0..n {
        let action = Action::Meta(cycle[k % cycle.len()].code());
        let actions = live.iter().map(|agent| (agent.clone(), action.clone())).collect();
        match env.step(actions).await {
            Ok(reply) => {
                *live = reply.agents.clone();
                replies.push(bits(&reply));
            }
            Err(ClientError::Server(e)) => replies.push(format!("{:?}: {}", e.code, e.message).into_bytes()),
            Err(e) => panic!("step {k}: {e}"),
        }
    }
    replies
}

fn refusal(result: Result<impl std::fmt::Debug, ClientError>) -> String {
    match result {
        Err(ClientError::Server(e)) => {
            assert_eq!(e.code, ErrorCode::InvalidSnapshot, "{e}");
            assert!(e.env_usable, "{e}");
            e.message
        }
        other => panic!("expected InvalidSnapshot, got {other:?}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_snapshot_restored_on_another_server_continues_bit_for_bit() {
    let (one, two) = (common::start().await, common::start().await);
    let (client_one, client_two) = (one.client().await, two.client().await);
    for scenario in ["highway-gt", "merge-random"] {
        // highway-gt's 40 steps of 1 s are too few for 50 + 50.
        let options = CreateOptions { max_cycles: Some(150), ..CreateOptions::default() };
        let mut original = one.env_with(&client_one, scenario, options.clone()).await;
        let reset = original.reset(Some(27), vec![]).await.unwrap();
        let mut live: Vec<String> = reset.agents.iter().map(|a| a.agent.clone()).collect();
        run(&mut original, &mut live, 50).await;
        let snapshot = original.snapshot().await.unwrap();
        let live_at_snapshot = live.clone();
        let a = run(&mut original, &mut live, 50).await;
        let stepped = a.iter().filter(|reply| !reply.starts_with(b"AgentNotLive")).count();
        assert!(stepped >= 30, "{scenario}: only {stepped} of the 50 steps after the snapshot had agents");

        // A fresh env on the other server, never reset.
        let mut fresh = two.env_with(&client_two, scenario, options).await;
        let restored = fresh.restore(snapshot.clone()).await.unwrap();
        let mut live: Vec<String> = restored.agents.iter().map(|a| a.agent.clone()).collect();
        assert_eq!(live, live_at_snapshot, "{scenario}: the restored env's agents are those live at the snapshot");
        assert!(fresh.snapshot().await.unwrap() == snapshot, "{scenario}: the restored state is the snapshot's");
        let b = run(&mut fresh, &mut live, 50).await;
        for (k, (a, b)) in a.iter().zip(&b).enumerate() {
            assert!(a == b, "{scenario}: step {k} after the snapshot differs (observations, rewards or infos)");
        }
        assert_eq!(a.len(), b.len());
        println!("{scenario}: snapshot of {} bytes", snapshot.len());
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn snapshots_of_another_scenario_version_or_damaged_are_refused_and_serving_goes_on() {
    let (one, two) = (common::start().await, common::start().await);
    let (client_one, client_two) = (one.client().await, two.client().await);
    let mut merge = one.env(&client_one, "merge").await;
    merge.reset(Some(1), vec![]).await.unwrap();
    merge.step(vec![]).await.unwrap();
    let snapshot = merge.snapshot().await.unwrap();

    let mut highway = two.env(&client_two, "highway-gt").await;
    highway.reset(Some(1), vec![]).await.unwrap();
    let message = refusal(highway.restore(snapshot.clone()).await);
    assert!(message.contains("scenario 'merge'") && message.contains("scenario 'highway-gt'"), "{message}");
    assert!(highway.step(vec![]).await.is_ok(), "the refused env steps on");

    let faster = CreateOptions {
        overrides: vec![("vehicle.ac.speed".into(), OptionValue::Float(19.0))],
        ..CreateOptions::default()
    };
    let mut overridden = two.env_with(&client_two, "merge", faster).await;
    let message = refusal(overridden.restore(snapshot.clone()).await);
    assert!(message.contains("resolved content"), "{message}");

    let mut target = two.env(&client_two, "merge").await;
    target.reset(Some(5), vec![]).await.unwrap();
    let mut versioned = snapshot.clone();
    versioned[8] = 6;
    let message = refusal(target.restore(versioned).await);
    let ours = format!("speaks version {}", arena_protocol::PROTOCOL_VERSION);
    assert!(message.contains("protocol version 6") && message.contains(&ours), "{message}");
    let message = refusal(target.restore(snapshot[..snapshot.len() / 2].to_vec()).await);
    assert!(message.contains("truncated"), "{message}");
    let mut corrupted = snapshot.clone();
    corrupted[snapshot.len() / 2] ^= 0x40;
    let message = refusal(target.restore(corrupted).await);
    assert!(message.contains("corrupted"), "{message}");
    let message = refusal(target.restore(b"not a snapshot".to_vec()).await);
    assert!(message.contains("not an env snapshot"), "{message}");

    // The server serves on, and the env restores a good snapshot after the refusals.
    assert!(client_two.server_info(two.server.id()).await.is_ok());
    assert!(target.step(vec![]).await.is_ok());
    let restored = target.restore(snapshot).await.unwrap();
    assert_eq!(restored.agents.len(), 1);
    let (a, b) = (merge.step(vec![]).await.unwrap(), target.step(vec![]).await.unwrap());
    assert!(bits(&a) == bits(&b), "the branch continues as the original");
}
