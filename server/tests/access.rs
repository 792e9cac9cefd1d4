//! Who may serve the arena's keys. A default server (a Zenoh peer its clients connect
//! to) lets no other session declare a queryable or a server token under the prefix.
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

use arena_client::{Client, CreateOptions, ScenarioSource};
use arena_protocol::keys;
use arena_protocol::session::{ConnectionFlags, Mode, Role};
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

/// A session that tries to serve in a server's place: a queryable on its request key
/// (counting what reaches it, answering with a forged reply) and a server token of its own.
struct Impostor {
    asked: Arc<AtomicUsize>,
    _queryable: zenoh::query::Queryable<()>,
    _token: zenoh::liveliness::LivelinessToken,
}

async fn pose_as(session: &zenoh::Session, server_id: &str) -> Impostor {
    let asked = Arc::new(AtomicUsize::new(0));
    let counter = Arc::clone(&asked);
    let _queryable = session
        .declare_queryable(keys::server_rpc("arena", server_id).unwrap())
        .callback(move |query| {
            counter.fetch_add(1, Ordering::SeqCst);
            let _ = zenoh::Wait::wait(query.reply(query.key_expr().clone(), b"forged".to_vec()));
        })
        .await
        .unwrap();
    let _token =
        session.liveliness().declare_token(keys::server_liveliness("arena", "impostor").unwrap()).await.unwrap();
    Impostor { asked, _queryable, _token }
}

/// `client` asks `server_id` for its info `times` times, each answered by the real server.
async fn served_by(client: &Client, server_id: &str, times: usize) {
    for _ in 0..times {
        let info = client.server_info(server_id).await.expect("server info");
        assert_eq!(info.server_id, server_id);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn on_a_default_server_no_other_session_can_serve_its_keys() {
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let server = Process::start(&["--listen", &endpoint]);
    let server_id = server.server_id();
    // A Zenoh client session is routed by the peer server it connects to, so without the
    // server's guard its queryable would be sent every request (client ids included).
    let rogue_flags = ConnectionFlags { mode: Some(Mode::Client), ..ConnectionFlags::connecting_to(&endpoint) };
    let rogue = zenoh::open(rogue_flags.zenoh_config(Role::Client).unwrap()).await.expect("the rogue connects");
    let impostor = pose_as(&rogue, &server_id).await;
    for mode in [Mode::Peer, Mode::Client] {
        let flags =
            ConnectionFlags { mode: Some(mode), timeout: 3.0, retries: 1, ..ConnectionFlags::connecting_to(&endpoint) };
        let client = Client::connect(&flags).await.expect("a client");
        client.pick_server().await.expect("the server");
        served_by(&client, &server_id, 20).await;
        assert_eq!(
            client.servers().await.unwrap(),
            std::slice::from_ref(&server_id),
            "{mode:?}: the impostor's token is seen"
        );
        client.close().await.unwrap();
    }
    assert_eq!(impostor.asked.load(Ordering::SeqCst), 0, "a request reached the rogue's queryable");
    rogue.close().await.unwrap();
}

struct Deployment {
    router: String,
    server_id: String,
    _processes: (Process, Process),
}

fn deploy() -> Deployment {
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
    let server =
        Process::start(&["--mode", "client", "--connect", &router, "--zenoh-config", "deploy/auth/server.json5"]);
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

    // bob, a named user, tries to serve: a queryable on the server's request key that
    // answers with a forged reply, and a liveliness token of a server of his own.
    let bob_config = client_config_as("bob", "change-me-bob");
    let bob = zenoh::open(flags(&deployment.router, Some(bob_config.clone())).zenoh_config(Role::Client).unwrap())
        .await
        .expect("bob logs in");
    std::fs::remove_file(bob_config).ok();
    let bobs = pose_as(&bob, &deployment.server_id).await;

    // alice is served, by the real server only.
    let alice = Client::connect(&flags(&deployment.router, Some(deploy_file("client.json5")))).await.expect("alice");
    alice.pick_server().await.expect("alice finds a server");
    tokio::time::sleep(Duration::from_millis(300)).await;
    assert_eq!(
        alice.servers().await.unwrap(),
        std::slice::from_ref(&deployment.server_id),
        "bob's token must not be seen"
    );
    let mut env = alice
        .create_env(&deployment.server_id, ScenarioSource::Named("merge".into()), CreateOptions::default())
        .await
        .expect("alice creates an env");
    env.reset(Some(0), vec![]).await.expect("reset");
    for _ in 0..5 {
        assert!(env.step(vec![]).await.is_ok());
    }
    let info = alice.server_info(&deployment.server_id).await.expect("server info");
    assert_eq!(info.server_id, deployment.server_id);
    served_by(&alice, &deployment.server_id, 20).await;
    assert_eq!(bobs.asked.load(Ordering::SeqCst), 0, "a request reached bob's queryable");
    alice.close().await.unwrap();
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
    assert!(env.step(vec![]).await.is_ok());
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
