//! How `arena` reports an error: what went wrong and its causes, and a backtrace only
//! when asked (`-v`, or RUST_LOG set), even with RUST_BACKTRACE=1 in the environment.

use std::process::{Command, Output};

/// `arena play` at an endpoint no Zenoh config takes: refused before any network.
fn bad_endpoint(extra: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_arena"))
        .args(["play", "--connect", "nowhere"])
        .args(extra)
        .env_remove("RUST_LOG")
        .envs(env.iter().copied())
        .output()
        .expect("run arena play")
}

#[test]
fn errors_print_no_backtrace_unless_asked() {
    let quiet = bad_endpoint(&[], &[("RUST_BACKTRACE", "1")]);
    let text = String::from_utf8_lossy(&quiet.stderr);
    assert!(!quiet.status.success());
    assert!(text.starts_with("Error: ") && text.contains("nowhere"), "{text}");
    assert!(!text.contains("backtrace"), "{text}");
    assert!(text.lines().count() <= 5, "{text}");
    for (extra, env) in
        [(&["-v"][..], &[("RUST_BACKTRACE", "1")][..]), (&[], &[("RUST_BACKTRACE", "1"), ("RUST_LOG", "warn")])]
    {
        let verbose = bad_endpoint(extra, env);
        let text = String::from_utf8_lossy(&verbose.stderr);
        assert!(text.contains("Stack backtrace"), "{extra:?} {env:?}: {text}");
    }
}
