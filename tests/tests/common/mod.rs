//! A real arena-server on its own Zenoh session listening on a free 127.0.0.1 port, and
//! clients on other sessions connecting to it over TCP, multicast scouting off.

#![allow(dead_code)]

use std::time::Duration;

use arena_client::{Client, CreateOptions, RemoteEnv, ScenarioSource};
use arena_protocol::session::{ConnectionFlags, Mode, Role};
use arena_server::transport::{Limits, Scenarios, Server};

pub struct Harness {
    pub server: Server,
    pub endpoint: String,
    /// The router the server connects to, when it is not reached directly.
    pub router: Option<zenoh::Session>,
}

fn free_port() -> u16 {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind a free port");
    listener.local_addr().expect("local address").port()
}

/// A session in `mode` listening on a free 127.0.0.1 port, and its endpoint. A port free
/// a moment ago can be taken before Zenoh binds it (by another test's outgoing
/// connection, whose local port comes from the same range): then another is tried.
async fn listening(mode: Mode) -> (zenoh::Session, String) {
    for _ in 0..10 {
        let endpoint = format!("tcp/127.0.0.1:{}", free_port());
        let flags = ConnectionFlags { mode: Some(mode), listen: vec![endpoint.clone()], ..ConnectionFlags::default() };
        match zenoh::open(flags.zenoh_config(Role::Server).expect("config")).await {
            Ok(session) => return (session, endpoint),
            Err(error) if error.to_string().contains("Address already in use") => continue,
            Err(error) => panic!("open a session listening on {endpoint}: {error}"),
        }
    }
    panic!("ten free ports were taken before Zenoh could bind them")
}

pub async fn start() -> Harness {
    start_with(Limits::default()).await
}

pub async fn start_with(limits: Limits) -> Harness {
    start_as(Mode::Peer, limits).await
}

/// A server whose session is a Zenoh router: it routes between the sessions that
/// connect to it, as the meeting point of a site does.
pub async fn start_router() -> Harness {
    start_as(Mode::Router, Limits::default()).await
}

/// A plain Zenoh router, and a server connected to it as a Zenoh client; `endpoint` is
/// the router's, so every other session is as near the server as the server's own.
pub async fn start_behind_router() -> Harness {
    let (router, endpoint) = listening(Mode::Router).await;
    let connect = ConnectionFlags { mode: Some(Mode::Client), ..ConnectionFlags::connecting_to(&endpoint) };
    let session = zenoh::open(connect.zenoh_config(Role::Server).expect("config")).await.expect("open server session");
    let scenarios = Scenarios::load(None).expect("the built-in scenarios load");
    let server = Server::start(session, "arena", scenarios, Limits::default()).await.expect("start server");
    Harness { server, endpoint, router: Some(router) }
}

async fn start_as(mode: Mode, limits: Limits) -> Harness {
    let (session, endpoint) = listening(mode).await;
    let scenarios = Scenarios::load(None).expect("the built-in scenarios load");
    let server = Server::start(session, "arena", scenarios, limits).await.expect("start server");
    Harness { server, endpoint, router: None }
}

impl Harness {
    pub async fn client(&self) -> Client {
        self.client_as(Mode::Peer).await
    }

    /// A client whose session is in `mode` (a Zenoh client is routed by a router server).
    pub async fn client_as(&self, mode: Mode) -> Client {
        let flags = ConnectionFlags {
            mode: Some(mode),
            timeout: 5.0,
            retries: 1,
            ..ConnectionFlags::connecting_to(&self.endpoint)
        };
        let client = Client::connect(&flags).await.expect("connect client");
        // Liveliness of a fresh peer takes a moment to propagate.
        for _ in 0..100 {
            if client.servers().await.map(|s| s.contains(&self.server.id().to_string())).unwrap_or(false) {
                return client;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        panic!("the client never saw the server's liveliness token");
    }

    pub async fn env(&self, client: &Client, scenario: &str) -> RemoteEnv {
        self.env_with(client, scenario, CreateOptions::default()).await
    }

    pub async fn env_with(&self, client: &Client, scenario: &str, options: CreateOptions) -> RemoteEnv {
        client.create_env(self.server.id(), ScenarioSource::Named(scenario.into()), options).await.expect("create env")
    }
}
