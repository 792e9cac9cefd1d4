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
    let runtime = tokio::runtime::Runtime::new().expect("runtime");
    // A port free a moment ago can be taken before Zenoh binds it (by another test's
    // outgoing connection, whose local port comes from the same range): try another.
    let mut attempts = 0;
    loop {
        let port = std::net::TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).expect("a free port").port();
        let endpoint = format!("tcp/127.0.0.1:{port}");
        let flags = ConnectionFlags { listen: vec![endpoint.clone()], ..ConnectionFlags::default() };
        let config = flags.zenoh_config(Role::Server).expect("config");
        let opened = runtime.block_on(async { zenoh::open(config).await });
        let session = match opened {
            Ok(session) => session,
            Err(error) if attempts < 10 && error.to_string().contains("Address already in use") => {
                attempts += 1;
                continue;
            }
            Err(error) => panic!("open session on {endpoint}: {error}"),
        };
        let server = runtime.block_on(async {
            let scenarios = Scenarios::load(None).expect("the built-in scenarios load");
            Server::start(session, "arena", scenarios, Limits::default()).await.expect("start server")
        });
        return Harness { runtime, server, endpoint };
    }
}
