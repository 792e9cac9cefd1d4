//! A busy env never stalls another client: two attacking Zenoh sessions, one of them
//! through a router, keep the server computing expensive requests within their bounds
//! (steps of a knot of game-theoretic cars, renders at a large size, resets), several at
//! once each, while a bystander with a 3 s timeout and no retries steps its own env and
//! asks for `ServerInfo`. Every bystander request is answered. (A server that computed
//! requests on Zenoh's two receive threads queued the bystander's behind the attackers'.)

mod common;

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use arena_client::{Client, ClientError, RemoteEnv, ScenarioSource};
use arena_protocol::session::{ConnectionFlags, Mode};
use arena_protocol::{CreateOptions, RenderMode};
use common::{Process, free_port};

/// How long the attack lasts.
const ATTACK: Duration = Duration::from_secs(12);
/// Requests each attacker keeps in flight.
const IN_FLIGHT: usize = 4;

async fn connect(endpoint: &str, mode: Mode, timeout: f64, retries: u32) -> Client {
    let flags = ConnectionFlags { mode: Some(mode), timeout, retries, ..ConnectionFlags::connecting_to(endpoint) };
    Client::connect(&flags).await.expect("connect")
}

/// A knot of game-theoretic cars around one learner: four lanes, rows of four 12 m apart,
/// every style and both games, so every car plays its games every period.
fn knot(rows: usize) -> String {
    let mut text = String::from(
        "name = \"knot\"\n[sim]\nphysics_dt = 0.02\nstep_dt = 1.0\nmax_cycles = 40\n\
         [road]\nlanes = 4\nspeed_limits = [30.0, 30.0, 30.0, 30.0]\nsections = [{ length = 5000.0 }]\n\
         [[vehicle]]\nname = \"ego\"\nlane = 1\ns = 30.0\nspeed = 25.0\n\
         driver = { kind = \"agent\", style = \"normal\", action = \"meta\" }\n",
    );
    let styles = ["aggressive", "normal", "conservative"];
    for row in 0..rows {
        for lane in 0..4 {
            let k = row * 4 + lane;
            let game = if k % 2 == 0 { "nash" } else { "stackelberg" };
            text += &format!(
                "[[vehicle]]\nname = \"gt{k}\"\nlane = {lane}\ns = {}\nspeed = {}\n\
                 driver = {{ kind = \"gt\", style = \"{}\", game = \"{game}\", role = \"leader\" }}\n",
                50.0 + 12.0 * row as f64,
                22.0 + (k % 5) as f64,
                styles[k % 3],
            );
        }
    }
    text
}

/// Keeps `IN_FLIGHT` expensive requests of `attacker` going until `until`; counts those
/// answered.
async fn attack(attacker: Client, server: String, until: Instant, answered: Arc<AtomicUsize>) {
    let mut tasks = Vec::new();
    for k in 0..IN_FLIGHT {
        let (attacker, server, answered) = (attacker.clone(), server.clone(), Arc::clone(&answered));
        tasks.push(tokio::spawn(async move {
            let options = CreateOptions { render_size: Some((1024, 1024)), ..CreateOptions::default() };
            let scenario = ScenarioSource::Inline { file_name: "knot.toml".into(), text: knot(8) };
            let mut env = attacker.create_env(&server, scenario, options).await.expect("the knot is within bounds");
            let mut seed = k as u64;
            while Instant::now() < until {
                seed += IN_FLIGHT as u64;
                let worked = heavy(&mut env, seed).await;
                if worked.is_ok() {
                    answered.fetch_add(1, Ordering::Relaxed);
                }
            }
        }));
    }
    for task in tasks {
        task.await.expect("an attacking task");
    }
}

async fn heavy(env: &mut RemoteEnv, seed: u64) -> Result<(), ClientError> {
    env.reset(Some(seed), vec![]).await?;
    env.step(vec![]).await?;
    env.render(RenderMode::RgbArray, None).await?;
    env.step(vec![]).await?;
    Ok(())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn a_bystander_is_answered_while_two_clients_keep_the_server_busy() {
    let direct = format!("tcp/127.0.0.1:{}", free_port());
    let routed = format!("tcp/127.0.0.1:{}", free_port());
    let server = Process::start(&["--listen", &direct]);
    let _router = Process::start(&["--mode", "router", "--route-only", "--listen", &routed, "--connect", &direct]);
    let id = server.server_id();

    // Generous timeouts for the attackers: their requests are meant to be slow.
    let first = connect(&direct, Mode::Peer, 120.0, 0).await;
    let second = connect(&routed, Mode::Client, 120.0, 0).await;
    let bystander = connect(&direct, Mode::Peer, 3.0, 0).await;
    for client in [&first, &second] {
        for _ in 0..200 {
            if client.servers().await.expect("servers").contains(&id) {
                break;
            }
            tokio::time::sleep(Duration::from_millis(25)).await;
        }
    }
    let mut mine = bystander
        .create_env(&id, ScenarioSource::Named("merge".into()), CreateOptions::default())
        .await
        .expect("the bystander's env");
    mine.reset(Some(0), vec![]).await.expect("the bystander's reset");

    let until = Instant::now() + ATTACK;
    let answered = Arc::new(AtomicUsize::new(0));
    let attacks = [first.clone(), second.clone()]
        .map(|attacker| tokio::spawn(attack(attacker, id.clone(), until, Arc::clone(&answered))));
    // Once the attackers' envs exist and their first requests are being computed.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let (mut steps, mut infos) = (0, 0);
    while Instant::now() < until {
        match mine.step(vec![]).await {
            Ok(reply) if reply.agents.is_empty() => drop(mine.reset(None, vec![]).await.expect("a reset under attack")),
            Ok(_) => {}
            Err(e) => panic!("the bystander's step {steps} under attack: {e}"),
        }
        steps += 1;
        bystander.server_info(&id).await.unwrap_or_else(|e| panic!("ServerInfo {infos} under attack: {e}"));
        infos += 1;
    }
    for attack in attacks {
        attack.await.expect("an attacker");
    }
    assert!(answered.load(Ordering::Relaxed) >= 2, "the attackers got nothing computed: no load was made");
    assert!(steps >= 10, "the bystander stepped only {steps} times in {ATTACK:?}");
    mine.close().await.expect("close");
}
