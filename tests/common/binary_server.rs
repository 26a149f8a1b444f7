//! The real `mesobake serve` binary, started from a directory of the test's choosing on its
//! default configuration (only the port, and what a test names, set by `MESOBAKE_*`).
#![allow(dead_code)] // each test file uses part of it

use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// A `mesobake serve` process; SIGKILLed when dropped.
pub struct BinaryServer {
    child: Child,
    /// `127.0.0.1:PORT`.
    pub addr: String,
    /// Where its stderr (the log) goes.
    pub log: PathBuf,
}

/// A free port on the loopback interface.
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

impl BinaryServer {
    /// Starts `mesobake serve` in `cwd` with the environment variables `env` (the
    /// configuration's other `MESOBAKE_*` variables removed) and waits until it answers.
    pub async fn start(cwd: &Path, env: &[(&str, &str)]) -> BinaryServer {
        let addr = format!("127.0.0.1:{}", free_port());
        let log = cwd.join(format!("serve-{}.log", addr.replace([':', '.'], "-")));
        let mut command = Command::new(env!("CARGO_BIN_EXE_mesobake"));
        for (key, _) in std::env::vars() {
            if key.starts_with("MESOBAKE_") && !key.starts_with("MESOBAKE_REQUIRE") {
                command.env_remove(key);
            }
        }
        let child = command
            .arg("serve")
            .current_dir(cwd)
            .env("MESOBAKE_LISTEN", &addr)
            .envs(env.iter().copied())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap();
        let mut server = BinaryServer { child, addr, log };
        let start = Instant::now();
        while reqwest::get(server.url("/healthz")).await.is_err() {
            if let Some(status) = server.child.try_wait().unwrap() {
                panic!("mesobake serve exited with {status}: {}", server.log_text());
            }
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "the server did not start: {}",
                server.log_text()
            );
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        server
    }

    /// The URL of `path`.
    pub fn url(&self, path: &str) -> String {
        format!("http://{}{path}", self.addr)
    }

    /// What it logged so far.
    pub fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    /// Sends SIGTERM and waits up to `limit` for the exit; `None` if it did not exit.
    pub fn terminate(&mut self, limit: Duration) -> Option<(ExitStatus, Duration)> {
        let start = Instant::now();
        let status = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
        while start.elapsed() < limit {
            if let Some(status) = self.child.try_wait().unwrap() {
                return Some((status, start.elapsed()));
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        None
    }
}

impl Drop for BinaryServer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
