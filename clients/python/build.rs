//! Empty: it exists so Cargo counts the feature pins under [build-dependencies] in
//! Cargo.toml, which keep this crate's host-side features equal to the workspace's.
fn main() {}
