//! `arena-server` processes for the tests of this folder: started on free loopback
//! ports, their banner read, killed when the test ends however it ends.

#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};

pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).map(|a| a.port()).expect("a free port")
}

/// The repository's root: deploy/ and scenarios/ are found from it.
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A running `arena-server` process, its banner (first line) and the rest of its stdout.
pub struct Process {
    pub child: Child,
    pub banner: String,
    /// The rest of its stdout; `None` once closed on purpose.
    pub lines: Option<std::io::Lines<BufReader<ChildStdout>>>,
}

impl Process {
    /// Starts `arena-server` with `args` in the repository's root and reads its banner.
    /// `$ARENA_TEST_SERVER` names another binary (an older build, to show a test fails there).
    pub fn start(args: &[&str]) -> Process {
        let binary =
            std::env::var("ARENA_TEST_SERVER").unwrap_or_else(|_| env!("CARGO_BIN_EXE_arena-server").to_string());
        let mut child = Command::new(binary)
            .args(args)
            .current_dir(repo_root())
            .stdout(Stdio::piped())
            .spawn()
            .expect("start arena-server");
        let mut lines = BufReader::new(child.stdout.take().expect("stdout")).lines();
        let banner = match lines.next() {
            Some(Ok(line)) => line,
            other => {
                let _ = child.kill();
                let status = child.wait();
                panic!("arena-server {args:?} printed no banner ({other:?}); it exited with {status:?}");
            }
        };
        Process { child, banner, lines: Some(lines) }
    }

    /// The server id its banner names ("... (server id X) ...").
    pub fn server_id(&self) -> String {
        let id = self.banner.split("server id ").nth(1).and_then(|rest| rest.split(')').next());
        id.unwrap_or_else(|| panic!("no server id in {:?}", self.banner)).to_string()
    }

    /// Sends SIGTERM and waits for the exit.
    pub fn terminate(&mut self) -> std::process::ExitStatus {
        let killed = Command::new("kill").args(["-TERM", &self.child.id().to_string()]).status().expect("kill");
        assert!(killed.success(), "kill -TERM failed");
        self.child.wait().expect("exit")
    }

    /// SIGKILL: the process vanishes without a word.
    pub fn kill(&mut self) {
        self.child.kill().expect("kill");
        self.child.wait().expect("exit");
    }

    /// What it printed after the banner, up to its exit.
    pub fn rest(&mut self) -> Vec<String> {
        self.lines.take().map(|lines| lines.map_while(Result::ok).collect()).unwrap_or_default()
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
