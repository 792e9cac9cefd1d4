//! The `arena-server` binary itself: it serves on the endpoint it is given, answers a
//! request over a real Zenoh session, and shuts down cleanly on SIGTERM.

mod common;

use std::process::Command;

use common::{Process, free_port};
use std::time::Duration;

use arena_protocol::session::{ConnectionFlags, Role};
use arena_protocol::{ClientId, PROTOCOL_VERSION, Reply, ReplyBody, Request, RequestBody, decode, encode, keys};

/// An `arena-server` process listening on a free loopback port, and the server id its
/// banner names.
struct Running {
    process: Process,
    endpoint: String,
    server_id: String,
}

fn run_server(extra: &[&str]) -> Running {
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let process = Process::start(&[&["--listen", endpoint.as_str()], extra].concat());
    assert!(process.banner.contains(&format!("serving on {endpoint}")), "{}", process.banner);
    let server_id = process.server_id();
    Running { process, endpoint, server_id }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn serves_then_stops_on_sigterm() {
    let Running { mut process, endpoint, server_id } = run_server(&["--max-envs", "4"]);

    let flags = ConnectionFlags::connecting_to(&endpoint);
    let session = zenoh::open(flags.zenoh_config(Role::Client).unwrap()).await.unwrap();
    let request = encode(&Request { version: PROTOCOL_VERSION, client: ClientId(1), body: RequestBody::ServerInfo });
    let key = keys::server_rpc("arena", &server_id).unwrap();
    let mut info = None;
    for _ in 0..100 {
        let replies = session.get(&key).payload(request.clone()).timeout(Duration::from_secs(5)).await.unwrap();
        if let Ok(reply) = replies.recv_async().await {
            let bytes = reply.result().expect("ok reply").payload().to_bytes().into_owned();
            info = Some(decode::<Reply>(&bytes).expect("a reply"));
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    match info.expect("the server answered").body {
        ReplyBody::ServerInfo(info) => {
            assert_eq!((info.server_id.as_str(), info.max_envs, info.envs), (server_id.as_str(), 4, 0));
            let expected = [
                "highway",
                "highway-gt",
                "merge",
                "merge-ac",
                "merge-duo",
                "merge-random",
                "merge-random-1hz",
                "merge-random-1hz-v2",
                "overtake",
                "overtake-random",
                "overtake-random-1hz",
                "overtake-random-1hz-v2",
            ];
            assert_eq!(info.scenarios, expected);
        }
        other => panic!("{other:?}"),
    }
    session.close().await.unwrap();

    let status = process.terminate();
    assert!(status.success(), "arena-server exited with {status}");
    let rest = process.rest();
    assert!(rest.iter().any(|line| line.contains("shutting down")), "{rest:?}");
}

#[test]
fn bad_flags_are_refused_with_a_message() {
    let output = Command::new(env!("CARGO_BIN_EXE_arena-server")).args(["--idle-timeout", "0"]).output().expect("run");
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("--idle-timeout must be a positive number of seconds"), "{stderr}");
    let output = Command::new(env!("CARGO_BIN_EXE_arena-server")).args(["--prefix", "a*b"]).output().expect("run");
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("cannot be used in a key expression"));
}

fn run_with_scenarios(dir: &std::path::Path) -> std::process::Output {
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    Command::new(env!("CARGO_BIN_EXE_arena-server"))
        .args(["--listen", &endpoint, "--scenarios"])
        .arg(dir)
        .output()
        .expect("run arena-server")
}

#[test]
fn a_scenario_folder_that_is_missing_or_holds_a_bad_file_stops_the_server_naming_it() {
    let missing = std::env::temp_dir().join(format!("arena-no-such-folder-{}", std::process::id()));
    let output = run_with_scenarios(&missing);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("cannot read the scenario folder") && stderr.contains("arena-no-such-folder"), "{stderr}");

    let dir = std::env::temp_dir().join(format!("arena-bad-scenarios-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("broken.toml"), "name = \"broken\"\n[road]\nlanes = 0\n").unwrap();
    let output = run_with_scenarios(&dir);
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("broken.toml") && stderr.contains("speed_limits"), "{stderr}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_scenario_file_is_served_under_the_name_it_declares() {
    let dir = std::env::temp_dir().join(format!("arena-named-scenarios-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let merge = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/merge.toml")).unwrap();
    std::fs::write(dir.join("file-stem.toml"), merge.replace("name = \"merge\"", "name = \"declared\"")).unwrap();
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let mut process = Process::start(&["--listen", &endpoint, "--scenarios", dir.to_str().expect("a utf-8 path")]);
    let lines: Vec<String> = process.lines.as_mut().expect("stdout").take(1).map_while(Result::ok).collect();
    drop(process);
    std::fs::remove_dir_all(&dir).unwrap();
    let listed = lines.iter().find(|l| l.starts_with("scenarios:")).expect("the scenarios line");
    assert!(listed.contains("declared") && !listed.contains("file-stem"), "{listed}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_echo_key_answers_at_most_its_cap_however_much_is_asked() {
    let Running { process, endpoint, server_id } = run_server(&[]);
    let flags = ConnectionFlags::connecting_to(&endpoint);
    let session = zenoh::open(flags.zenoh_config(Role::Client).unwrap()).await.unwrap();
    let key = keys::server_echo("arena", &server_id).unwrap();
    let mut sizes = Vec::new();
    for asked in [100u32, 16 * 1024 * 1024] {
        for _ in 0..100 {
            let replies =
                session.get(&key).payload(asked.to_le_bytes().to_vec()).timeout(Duration::from_secs(5)).await.unwrap();
            if let Ok(reply) = replies.recv_async().await {
                sizes.push(reply.result().expect("ok reply").payload().len());
                break;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }
    session.close().await.unwrap();
    drop(process);
    // A 4-byte request cannot ask for megabytes: 64 KiB at most.
    assert_eq!(sizes, [100, arena_server::transport::ECHO_MAX_REPLY]);
}

/// One request over `session` to `key`: its reply, or None when none came within 2 s.
async fn ask(session: &zenoh::Session, key: &str, body: RequestBody) -> Option<ReplyBody> {
    let request = encode(&Request { version: PROTOCOL_VERSION, client: ClientId(7), body });
    let replies = session.get(key).payload(request).timeout(Duration::from_secs(2)).await.ok()?;
    let reply = replies.recv_async().await.ok()?;
    let bytes = reply.result().ok()?.payload().to_bytes().into_owned();
    decode::<Reply>(&bytes).ok().map(|reply| reply.body)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_under_load_answers_every_request_then_exits_0() {
    let Running { mut process, endpoint, server_id } = run_server(&[]);
    let flags = ConnectionFlags::connecting_to(&endpoint);
    let session = zenoh::open(flags.zenoh_config(Role::Client).unwrap()).await.unwrap();
    let key = keys::server_rpc("arena", &server_id).unwrap();
    let mut ready = false;
    for _ in 0..100 {
        if ask(&session, &key, RequestBody::ServerInfo).await.is_some() {
            ready = true;
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert!(ready, "the server answered");

    // Four loops, each stepping its own env as fast as replies come.
    let mut loops = Vec::new();
    for _ in 0..4 {
        let (session, key) = (session.clone(), key.clone());
        loops.push(tokio::spawn(async move {
            let create = RequestBody::CreateEnv {
                scenario: arena_protocol::ScenarioSource::Named("highway".into()),
                options: Default::default(),
            };
            let Some(ReplyBody::Created { env, .. }) = ask(&session, &key, create).await else { panic!("created") };
            let reset = RequestBody::Reset { env, seq: 0, seed: Some(1), options: Default::default() };
            assert!(matches!(ask(&session, &key, reset).await, Some(ReplyBody::Reset(_))));
            let (mut steps, mut seq) = (0u64, 0u64);
            loop {
                seq += 1;
                match ask(&session, &key, RequestBody::Step { env, seq, actions: vec![] }).await {
                    Some(ReplyBody::Step(_)) => steps += 1,
                    // An episode ran out (40 steps): start another.
                    Some(ReplyBody::Error(e)) if e.code == arena_protocol::ErrorCode::AgentNotLive => {
                        seq += 1;
                        let reset = RequestBody::Reset { env, seq, seed: None, options: Default::default() };
                        match ask(&session, &key, reset).await {
                            Some(ReplyBody::Reset(_)) => {}
                            other => return (steps, other),
                        }
                    }
                    other => return (steps, other),
                }
            }
        }));
    }
    tokio::time::sleep(Duration::from_millis(500)).await;
    let status = tokio::task::spawn_blocking(move || process.terminate()).await.unwrap();
    assert!(status.success(), "arena-server exited with {status}");
    for handle in loops {
        let (steps, last) = handle.await.expect("a loop");
        // Every loop was stepping when SIGTERM came; its request in flight was answered and
        // the next one told ShuttingDown, not left to time out.
        assert!(steps > 0, "the loop stepped before the signal");
        match last {
            Some(ReplyBody::Error(e)) => {
                assert_eq!(e.code, arena_protocol::ErrorCode::ShuttingDown, "{e}");
                assert!(e.message.contains(&server_id), "{e}");
            }
            other => panic!("after {steps} steps: {other:?}"),
        }
    }
    session.close().await.unwrap();
}

#[test]
fn a_closed_stdout_does_not_stop_the_server() {
    // Piped into `head`, say: the server's stdout goes away while it serves.
    let Running { mut process, .. } = run_server(&[]);
    drop(process.lines.take());
    std::thread::sleep(Duration::from_millis(200));
    let status = process.terminate();
    assert!(status.success(), "its last line had nowhere to go, and it exited with {status}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_whose_server_was_killed_and_restarted_is_told_its_env_is_gone_at_once() {
    let Running { process, endpoint, server_id } = run_server(&[]);
    let flags = ConnectionFlags { timeout: 5.0, retries: 2, ..ConnectionFlags::connecting_to(&endpoint) };
    let client = arena_client::Client::connect(&flags).await.expect("connect");
    let server = client.pick_server().await.expect("a server");
    assert_eq!(server, server_id);
    let mut env = client
        .create_env(&server, arena_protocol::ScenarioSource::Named("merge".into()), Default::default())
        .await
        .expect("create");
    env.reset(Some(0), vec![]).await.expect("reset");
    env.step(vec![]).await.expect("a step");

    drop(process); // SIGKILL: no goodbye
    let restarted = Process::start(&["--listen", &endpoint]);
    assert!(restarted.banner.contains(&format!("serving on {endpoint}")), "{}", restarted.banner);
    assert_ne!(restarted.server_id(), server_id, "a restarted server is another server");

    let error = env.step(vec![]).await.expect_err("the env died with its server");
    // ServerGone, not Timeout: the client says so only when no attempt waited out its
    // timeout (the old server's key has no queryable left), i.e. at once, not a hang.
    match &error {
        arena_client::ClientError::ServerGone { server, .. } => assert_eq!(server, &server_id),
        other => panic!("expected ServerGone, got {other:?}"),
    }
    let message = error.to_string();
    assert!(message.contains(&server_id) && message.contains("no longer exist"), "{message}");
    // The new server serves the same client.
    assert_eq!(client.pick_server().await.expect("the new server"), restarted.server_id());
    client.close().await.unwrap();
}
