//! Who may serve the arena's keys, and who may fill a server. A default server (a Zenoh
//! peer its clients connect to) lets no other session declare a queryable or a server
//! token on any expression that reaches its keys, and reclaims the envs of clients that
//! show no liveliness token.
//! Then the authenticated deployment of deploy/auth/, as separate processes on loopback: a
//! router with user/password authentication and an access-control list, an arena-server
//! logged in as a server, and clients. Shows that a client without credentials is
//! refused, one with them is served, and one that tries to pose as a server (declare a
//! server's queryable or liveliness token) reaches nobody.

mod common;

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use arena_client::{Client, ClientError, CreateOptions, ErrorCode, RemoteEnv, ScenarioSource};
use arena_protocol::session::{ConnectionFlags, Mode, Role};
use arena_protocol::{ClientId, Reply, ReplyBody, Request, RequestBody, decode, encode, keys};
use common::{Process, free_port, repo_root};

fn deploy_file(name: &str) -> PathBuf {
    repo_root().join("deploy/auth").join(name)
}

/// A client of the deployment, logged in as `config` says (None: no credentials).
fn flags(router: &str, config: Option<PathBuf>) -> ConnectionFlags {
    ConnectionFlags {
        mode: Some(Mode::Client),
        zenoh_config: config,
        timeout: 3.0,
        retries: 1,
        ..ConnectionFlags::connecting_to(router)
    }
}

/// `client.json5` as written, with alice's login swapped for another one.
fn client_config_as(user: &str, password: &str) -> PathBuf {
    let text = std::fs::read_to_string(deploy_file("client.json5")).expect("deploy/auth/client.json5");
    let text = text.replace("\"alice\"", &format!("{user:?}")).replace("\"change-me-alice\"", &format!("{password:?}"));
    let path = std::env::temp_dir().join(format!("arena-client-{user}-{}.json5", std::process::id()));
    std::fs::write(&path, text).expect("write a client config");
    path
}

/// Key expressions an attacker declares queryables on to catch a server's requests: the
/// exact key, and every broader expression that intersects it (`server` is its id).
fn capturing_keys(server: &str) -> Vec<String> {
    let mut keys: Vec<String> =
        ["**", "*/**", "*/*/rpc", "**/rpc", "**/rpc/**", "arena/**", "arena/*/rpc", "arena/*/rpc/*"]
            .map(String::from)
            .to_vec();
    keys.extend([
        format!("*/{server}/rpc"),
        format!("arena/{server}/**"),
        format!("arena/{server}/rpc"),
        format!("arena/{server}/rpc/*"),
        format!("arena/{server}/rpc/alice"),
        format!("arena/{server}/echo"),
    ]);
    keys
}

/// Liveliness tokens an attacker declares to pose as servers.
fn server_tokens() -> Vec<String> {
    ["**", "arena/**", "arena/servers/**", "arena/servers/*", "*/servers/impostor", "arena/servers/impostor"]
        .map(String::from)
        .to_vec()
}

/// A session that tries to serve in a server's place: queryables on `keys` (counting what
/// reaches them, answering with a forged reply) and liveliness `tokens` of its own.
struct Impostor {
    asked: Arc<AtomicUsize>,
    _queryables: Vec<zenoh::query::Queryable<()>>,
    _tokens: Vec<zenoh::liveliness::LivelinessToken>,
}

async fn pose_with(session: &zenoh::Session, keys: &[String], tokens: &[String]) -> Impostor {
    let asked = Arc::new(AtomicUsize::new(0));
    let mut queryables = Vec::new();
    for key in keys {
        let counter = Arc::clone(&asked);
        let queryable = session
            .declare_queryable(key.as_str())
            .callback(move |query| {
                counter.fetch_add(1, Ordering::SeqCst);
                let _ = zenoh::Wait::wait(query.reply(query.key_expr().clone(), b"forged".to_vec()));
            })
            .await
            .unwrap_or_else(|e| panic!("declare a queryable on {key}: {e}"));
        queryables.push(queryable);
    }
    let mut declared = Vec::new();
    for token in tokens {
        declared.push(session.liveliness().declare_token(token.as_str()).await.expect("declare a token"));
    }
    Impostor { asked, _queryables: queryables, _tokens: declared }
}

/// `client` asks `server_id` for its info `times` times, each answered by the real server.
async fn served_by(client: &Client, server_id: &str, times: usize) {
    for _ in 0..times {
        let info = client.server_info(server_id).await.expect("server info");
        assert_eq!(info.server_id, server_id);
    }
}

/// `client` creates an env on `server`, resets it and steps it: every request a client
/// makes with its id, where a capturing queryable would see them.
async fn drive_an_env(client: &Client, server: &str) {
    let mut env = client.create_env(server, ScenarioSource::Named("merge".into()), CreateOptions::default()).await;
    let env = env.as_mut().expect("create an env");
    env.reset(Some(0), vec![]).await.expect("reset");
    for _ in 0..5 {
        env.step(vec![]).await.expect("a step");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn on_a_default_server_no_other_session_can_serve_or_capture_its_keys() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let server = Process::start(&["--listen", &endpoint]);
    let server_id = server.server_id();
    // A Zenoh client session is routed by the peer server it connects to, so without the
    // server's guard its queryables would be sent every request (client ids included).
    // Zenoh's access control applies a rule to the expressions it includes, so each of
    // these broader expressions got through a deny list on `arena/**` (07e7a7d).
    let mut rogues = Vec::new();
    for mode in [Mode::Client, Mode::Peer] {
        let rogue_flags = ConnectionFlags { mode: Some(mode), ..ConnectionFlags::connecting_to(&endpoint) };
        let rogue = zenoh::open(rogue_flags.zenoh_config(Role::Client).unwrap()).await.expect("the rogue connects");
        let impostor = pose_with(&rogue, &capturing_keys(&server_id), &server_tokens()).await;
        rogues.push((rogue, impostor));
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    for mode in [Mode::Peer, Mode::Client] {
        let flags =
            ConnectionFlags { mode: Some(mode), timeout: 3.0, retries: 1, ..ConnectionFlags::connecting_to(&endpoint) };
        let client = Client::connect(&flags).await.expect("a client");
        client.pick_server().await.expect("the server");
        served_by(&client, &server_id, 20).await;
        drive_an_env(&client, &server_id).await;
        client.echo(&server_id, 16, 16).await.expect("an echo");
        assert_eq!(
            client.servers().await.unwrap(),
            std::slice::from_ref(&server_id),
            "{mode:?}: an impostor's token is seen"
        );
        client.close().await.unwrap();
    }
    for (rogue, impostor) in rogues {
        assert_eq!(impostor.asked.load(Ordering::SeqCst), 0, "a request reached a rogue's queryable");
        rogue.close().await.unwrap();
    }
}

/// A raw request from `session` as client `id`, answered by `server`'s session.
async fn ask_as(session: &zenoh::Session, server: &str, id: ClientId, body: RequestBody) -> ReplyBody {
    let replies = session
        .get(keys::server_rpc("arena", server).unwrap())
        .payload(encode(&Request::new(id, body)))
        .timeout(Duration::from_secs(5))
        .await
        .expect("a get");
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result() {
            return decode::<Reply>(&sample.payload().to_bytes()).expect("a reply").body;
        }
    }
    panic!("no reply from {server}");
}

fn create_merge() -> RequestBody {
    RequestBody::CreateEnv { scenario: ScenarioSource::Named("merge".into()), options: CreateOptions::default() }
}

/// Fills the server with envs of fresh client ids, one per create, until it refuses one
/// for being full; with `tokens`, each id also shows a liveliness token, as a client's
/// does. Returns the envs made and the tokens.
async fn fill_with_minted_ids(
    session: &zenoh::Session,
    server: &str,
    tokens: bool,
) -> (usize, Vec<zenoh::liveliness::LivelinessToken>) {
    let (mut made, mut declared) = (0, Vec::new());
    for _ in 0..100 {
        let id = ClientId(rand::random::<u128>());
        if tokens {
            let key = keys::client_liveliness("arena", &id.tag().to_string()).unwrap();
            declared.push(session.liveliness().declare_token(key).await.expect("a token"));
        }
        match ask_as(session, server, id, create_merge()).await {
            ReplyBody::Created { .. } => made += 1,
            ReplyBody::Error(e) if e.code == ErrorCode::TooManyEnvs => return (made, declared),
            other => panic!("create: {other:?}"),
        }
    }
    panic!("the server never filled up");
}

/// Polls `client` creating an env on `server` until it is served; how long it took, and
/// the env.
async fn served_within(client: &Client, server: &str, limit: Duration) -> (Duration, RemoteEnv) {
    let started = std::time::Instant::now();
    loop {
        match client.create_env(server, ScenarioSource::Named("merge".into()), CreateOptions::default()).await {
            Ok(env) => return (started.elapsed(), env),
            Err(ClientError::Server(e)) if e.code == ErrorCode::TooManyEnvs => {}
            Err(other) => panic!("create: {other}"),
        }
        assert!(started.elapsed() < limit, "a new client was not served within {limit:?} of the attacker stopping");
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_open_server_filled_by_minted_ids_serves_a_new_client_once_the_attacker_stops() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let server = Process::start(&["--listen", &endpoint, "--max-envs", "6", "--max-envs-per-client", "2"]);
    let server_id = server.server_id();
    let newcomer_flags = ConnectionFlags { timeout: 5.0, retries: 1, ..ConnectionFlags::connecting_to(&endpoint) };
    for tokens in [false, true] {
        let attacker = zenoh::open(ConnectionFlags::connecting_to(&endpoint).zenoh_config(Role::Client).unwrap())
            .await
            .expect("the attacker connects");
        let (made, declared) = fill_with_minted_ids(&attacker, &server_id, tokens).await;
        assert_eq!(made, 6, "tokens {tokens}: one session took every place");
        let newcomer = Client::connect(&newcomer_flags).await.expect("a newcomer");
        // What an open server cannot prevent: while the attacker goes on, it is full.
        let refused = newcomer.create_env(&server_id, ScenarioSource::Named("merge".into()), CreateOptions::default());
        assert!(matches!(refused.await, Err(ClientError::Server(e)) if e.code == ErrorCode::TooManyEnvs));
        drop(declared);
        attacker.close().await.unwrap();
        let (took, mut env) = served_within(&newcomer, &server_id, Duration::from_secs(10)).await;
        eprintln!("tokens {tokens}: a newcomer was served {took:?} after the attacker stopped");
        // Closed by its owner, an env frees its place at once: the next round starts empty.
        env.close().await.unwrap();
        newcomer.close().await.unwrap();
    }
}

struct Deployment {
    router: String,
    server_id: String,
    _processes: (Process, Process),
}

fn deploy() -> Deployment {
    deploy_with(&[])
}

/// The router of deploy/auth/ and one server logged in to it, with `server_args` besides.
fn deploy_with(server_args: &[&str]) -> Deployment {
    let router = format!("tcp/127.0.0.1:{}", free_port());
    let router_process = Process::start(&[
        "--mode",
        "router",
        "--route-only",
        "--zenoh-config",
        "deploy/auth/router.json5",
        "--listen",
        &router,
    ]);
    assert!(router_process.banner.contains("routing only"), "{}", router_process.banner);
    let mut args = vec!["--mode", "client", "--connect", &router, "--zenoh-config", "deploy/auth/server.json5"];
    args.extend_from_slice(server_args);
    let server = Process::start(&args);
    assert!(server.banner.contains(&format!("serving through {router}")), "{}", server.banner);
    Deployment { router, server_id: server.server_id(), _processes: (router_process, server) }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn only_authenticated_users_are_served_and_no_client_can_pose_as_a_server() {
    let deployment = deploy();

    // No credentials, or a wrong password: the router refuses the session.
    let anonymous = Client::connect(&flags(&deployment.router, None)).await;
    assert!(anonymous.is_err(), "a client without credentials got a session");
    let wrong = client_config_as("alice", "not-her-password");
    let impostor = Client::connect(&flags(&deployment.router, Some(wrong.clone()))).await;
    std::fs::remove_file(wrong).ok();
    assert!(impostor.is_err(), "a client with a wrong password got a session");

    // bob, a named user, tries to serve and to capture: queryables on the server's
    // request keys and broader ones, and liveliness tokens of servers of his own.
    let bob_config = client_config_as("bob", "change-me-bob");
    let bob = zenoh::open(flags(&deployment.router, Some(bob_config.clone())).zenoh_config(Role::Client).unwrap())
        .await
        .expect("bob logs in");
    std::fs::remove_file(bob_config).ok();
    let bobs = pose_with(&bob, &capturing_keys(&deployment.server_id), &server_tokens()).await;

    // alice is served, by the real server only.
    let alice = Client::connect(&flags(&deployment.router, Some(deploy_file("client.json5")))).await.expect("alice");
    alice.pick_server().await.expect("alice finds a server");
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(
        alice.servers().await.unwrap(),
        std::slice::from_ref(&deployment.server_id),
        "bob's token must not be seen"
    );
    drive_an_env(&alice, &deployment.server_id).await;
    served_by(&alice, &deployment.server_id, 20).await;
    assert_eq!(bobs.asked.load(Ordering::SeqCst), 0, "a request reached bob's queryable");
    alice.close().await.unwrap();
    bob.close().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_routers_own_login_cannot_serve() {
    let deployment = deploy();
    // Until 07e7a7d's successor, every router's config carried a login that the
    // router's rules let relay (so serve) everything under the prefix: a session logged
    // in with it received alice's requests. A site has one router, which logs in nowhere.
    let router_login = client_config_as("arena-router", "change-me-router");
    let session =
        zenoh::open(flags(&deployment.router, Some(router_login.clone())).zenoh_config(Role::Client).unwrap()).await;
    std::fs::remove_file(router_login).ok();
    assert!(session.is_err(), "the router's old login still opens a session");
    let router_text = std::fs::read_to_string(deploy_file("router.json5")).unwrap();
    assert!(!router_text.contains("router-relays"), "deploy/auth/router.json5 still lets a login relay");
    let credentials = std::fs::read_to_string(deploy_file("credentials.txt")).unwrap();
    assert!(credentials.lines().all(|line| !line.starts_with("arena-router:")), "the router has a login");

    // alice is served as before.
    let alice = Client::connect(&flags(&deployment.router, Some(deploy_file("client.json5")))).await.expect("alice");
    alice.pick_server().await.expect("alice finds a server");
    drive_an_env(&alice, &deployment.server_id).await;
    alice.close().await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn under_auth_the_env_limit_is_per_user_however_many_ids_a_user_mints() {
    let deployment = deploy_with(&["--max-envs-per-client", "2"]);
    let alice_flags = flags(&deployment.router, Some(deploy_file("client.json5")));
    let bob_config = client_config_as("bob", "change-me-bob");
    let bob_flags = flags(&deployment.router, Some(bob_config.clone()));
    // alice opens three clients, three client ids: they share her limit of 2.
    let mut alices = Vec::new();
    for _ in 0..3 {
        let alice = Client::connect(&alice_flags).await.expect("alice");
        alice.pick_server().await.expect("a server");
        alices.push(alice);
    }
    let merge = || ScenarioSource::Named("merge".into());
    for alice in &alices[..2] {
        alice.create_env(&deployment.server_id, merge(), CreateOptions::default()).await.expect("within her limit");
    }
    let refused = alices[2].create_env(&deployment.server_id, merge(), CreateOptions::default()).await;
    match refused {
        Err(ClientError::Server(e)) => {
            assert_eq!(e.code, ErrorCode::TooManyEnvs, "{e}");
            assert!(e.message.contains("user 'alice' holds its limit of 2"), "{e}");
        }
        other => panic!("alice's third id was served: {other:?}"),
    }
    let info = alices[2].server_info(&deployment.server_id).await.expect("server info");
    assert_eq!((info.yours, info.max_envs_per_client), (2, 2), "the server counts alice's envs together");
    assert!(alices[2].place(1).await.is_err(), "placement offers a server where alice holds her share");

    // bob is served.
    let bob = Client::connect(&bob_flags).await.expect("bob");
    std::fs::remove_file(bob_config).ok();
    bob.pick_server().await.expect("a server");
    bob.create_env(&deployment.server_id, merge(), CreateOptions::default()).await.expect("bob is served");
    assert_eq!(bob.server_info(&deployment.server_id).await.unwrap().yours, 1);

    // A user cannot ask on another user's key, nor on the unnamed one.
    let alice_session = zenoh::open(alice_flags.zenoh_config(Role::Client).unwrap()).await.expect("alice");
    for key in [
        keys::user_rpc("arena", &deployment.server_id, "bob").unwrap(),
        keys::server_rpc("arena", &deployment.server_id).unwrap(),
    ] {
        let replies = alice_session
            .get(&key)
            .payload(encode(&Request::new(ClientId(9), create_merge())))
            .timeout(Duration::from_secs(2))
            .await
            .expect("a get");
        let answered = replies.recv_async().await.is_ok_and(|reply| reply.result().is_ok());
        assert!(!answered, "alice was answered on {key}");
    }
    alice_session.close().await.unwrap();
    for alice in alices {
        alice.close().await.unwrap();
    }
    bob.close().await.unwrap();
}

/// A throwaway certificate authority and a router certificate for localhost, as
/// deploy/auth/make-certs.sh makes them, in `dir`: ca.pem, router.pem, router.key.
fn make_certs(dir: &std::path::Path) {
    use rcgen::{BasicConstraints, CertificateParams, IsCa, Issuer, KeyPair};
    let mut ca = CertificateParams::new(Vec::<String>::new()).expect("CA params");
    ca.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
    let ca_key = KeyPair::generate().expect("CA key");
    let ca_cert = ca.self_signed(&ca_key).expect("CA certificate");
    let router = CertificateParams::new(vec!["localhost".to_string(), "127.0.0.1".to_string()]).expect("params");
    let router_key = KeyPair::generate().expect("router key");
    let router_cert = router.signed_by(&router_key, &Issuer::new(ca, ca_key)).expect("router certificate");
    std::fs::create_dir_all(dir).expect("a certificate folder");
    std::fs::write(dir.join("ca.pem"), ca_cert.pem()).expect("ca.pem");
    std::fs::write(dir.join("router.pem"), router_cert.pem()).expect("router.pem");
    std::fs::write(dir.join("router.key"), router_key.serialize_pem()).expect("router.key");
}

/// deploy/auth/`name` with its certificate paths pointed at `certs`, written beside them.
fn with_certs(name: &str, certs: &std::path::Path) -> PathBuf {
    let text = std::fs::read_to_string(deploy_file(name)).expect("a deploy/auth file");
    let path = certs.join(name);
    std::fs::write(&path, text.replace("deploy/auth/certs/", &format!("{}/", certs.display()))).expect("write");
    path
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn over_tls_only_clients_that_trust_the_sites_authority_are_served() {
    let certs = std::env::temp_dir().join(format!("arena-tls-{}", std::process::id()));
    make_certs(&certs);
    let (router_config, server_config, client_config) =
        (with_certs("router.json5", &certs), with_certs("server.json5", &certs), with_certs("client.json5", &certs));
    let port = free_port();
    let router = Process::start(&[
        "--mode",
        "router",
        "--route-only",
        "--zenoh-config",
        router_config.to_str().unwrap(),
        "--listen",
        &format!("tls/127.0.0.1:{port}"),
    ]);
    assert!(router.banner.contains("routing only"), "{}", router.banner);
    let endpoint = format!("tls/localhost:{port}");
    let server = Process::start(&[
        "--mode",
        "client",
        "--connect",
        &endpoint,
        "--zenoh-config",
        server_config.to_str().unwrap(),
    ]);
    assert!(server.banner.contains("serving through tls/"), "{}", server.banner);

    let alice = Client::connect(&flags(&endpoint, Some(client_config))).await.expect("alice, over TLS");
    let id = alice.pick_server().await.expect("a server");
    assert_eq!(id, server.server_id());
    let mut env = alice.create_env(&id, ScenarioSource::Named("merge".into()), CreateOptions::default()).await.unwrap();
    env.reset(Some(0), vec![]).await.expect("reset over TLS");
    env.step(vec![]).await.expect("a step over TLS");
    alice.close().await.unwrap();

    // Her credentials without the site's authority: the router's certificate is not
    // trusted, so no session.
    let text = std::fs::read_to_string(deploy_file("client.json5")).unwrap();
    let untrusting = certs.join("untrusting.json5");
    std::fs::write(&untrusting, text.replace("root_ca_certificate: \"deploy/auth/certs/ca.pem\"", "")).unwrap();
    let untrusting = flags(&endpoint, Some(untrusting));
    assert!(untrusting.zenoh_config(Role::Client).is_ok(), "the config itself is fine");
    assert!(Client::connect(&untrusting).await.is_err(), "a client that trusts no CA got in");
    drop((router, server));
    std::fs::remove_dir_all(&certs).ok();
}
