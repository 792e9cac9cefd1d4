//! Feeds arbitrary bytes to the server's request handler (`Registry::handle`), which
//! decodes them and acts on them as it does for every request arriving over Zenoh. Holds:
//! no panic, and every reply decodes as a `Reply`. One registry for the whole run, as a
//! server has: envs created along the way accumulate up to `Limits::default()`.
#![no_main]

use std::sync::LazyLock;

use arena_protocol::{Reply, decode};
use arena_server::transport::{Limits, Registry, Scenarios};
use libfuzzer_sys::fuzz_target;

static REGISTRY: LazyLock<Registry> = LazyLock::new(|| {
    Registry::new("fuzz".into(), Scenarios::load(None).expect("built-in scenarios"), Limits::default())
});

fuzz_target!(|bytes: &[u8]| {
    let reply = REGISTRY.handle(bytes);
    if let Err(e) = decode::<Reply>(&reply) {
        panic!("the reply to {bytes:?} does not decode: {e}");
    }
});
