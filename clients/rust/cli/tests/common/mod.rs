//! A real arena-server for the CLI's tests: its own Zenoh session on a free 127.0.0.1
//! port, kept alive with its runtime while a test runs.

// Each test file uses the part it needs.
#![allow(dead_code)]

use arena_protocol::session::{ConnectionFlags, Role};
use arena_server::transport::{Limits, Scenarios, Server};

pub struct Harness {
    pub runtime: tokio::runtime::Runtime,
    pub server: Server,
    pub endpoint: String,
}

pub fn serve() -> Harness {
    let port = std::net::TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).expect("a free port").port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let runtime = tokio::runtime::Runtime::new().expect("runtime");
    let flags = ConnectionFlags { listen: vec![endpoint.clone()], ..ConnectionFlags::default() };
    let server = runtime.block_on(async {
        let session = zenoh::open(flags.zenoh_config(Role::Server).expect("config")).await.expect("open session");
        let scenarios = Scenarios::load(None).expect("the built-in scenarios load");
        Server::start(session, "arena", scenarios, Limits::default()).await.expect("start server")
    });
    Harness { runtime, server, endpoint }
}
