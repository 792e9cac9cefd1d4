//! Faults a shared server meets, with real processes: a client process killed in the
//! middle of an episode has its env closed by the server (seen through `ServerInfo`).

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;

#[test]
fn a_client_process_killed_mid_episode_has_its_env_closed() {
    let common::Harness { runtime, server, endpoint } = common::serve();
    // `arena play` in real time: a 40 s highway episode, far longer than this test.
    let mut player = Command::new(env!("CARGO_BIN_EXE_arena"))
        .args(["play", "--connect", &endpoint, "--scenario", "highway", "--policy", "idle", "--speed", "1"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start arena play");
    let wait_for = |what: &str, done: &dyn Fn() -> bool| {
        let started = Instant::now();
        while !done() {
            assert!(started.elapsed() < Duration::from_secs(15), "waited 15 s for {what}");
            std::thread::sleep(Duration::from_millis(20));
        }
        started.elapsed()
    };
    wait_for("the player's env", &|| server.registry().len() == 1);
    std::thread::sleep(Duration::from_millis(300));
    assert!(player.try_wait().expect("status").is_none(), "the player is still playing when it is killed");
    assert_eq!(server.registry().len(), 1, "and its env is open");
    player.kill().expect("SIGKILL the player");
    player.wait().expect("reaped");
    // No close request came: the server learns from the client's liveliness token (its
    // session's link dropped) and closes the env.
    let took = wait_for("the env to be closed", &|| server.registry().is_empty());
    assert!(took < Duration::from_secs(10), "{took:?}");
    runtime.block_on(server.close()).expect("close");
}
