//! Helpers for lop-view's tests: spawn `lop-view` on a free loopback port and kill it on drop.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// A running `lop-view`, killed when dropped (and by a watchdog after `limit`).
#[allow(dead_code)] // each test binary uses a part
pub struct Viewer {
    pub child: Child,
    /// `http://127.0.0.1:PORT/`
    pub url: String,
    /// `127.0.0.1:PORT`
    pub addr: String,
}

impl Viewer {
    pub fn spawn(prefix: &str, limit: Duration) -> Viewer {
        let exe = lop_system_tests::sibling_binary("lop-view");
        let mut child = Command::new(exe)
            .args(["--prefix", prefix, "--bind", "127.0.0.1:0"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("spawn lop-view");
        let pid = child.id() as i32;
        std::thread::spawn(move || {
            std::thread::sleep(limit);
            // SAFETY: kill on a process this test started; harmless if it is gone.
            unsafe { libc::kill(pid, libc::SIGKILL) };
        });
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("stdout"))
            .read_line(&mut line)
            .expect("lop-view prints its URL");
        // "lop-view: http://127.0.0.1:PORT/ (prefix …)"
        let url = line
            .split_whitespace()
            .find(|w| w.starts_with("http://"))
            .unwrap_or_else(|| panic!("no URL in {line:?}"))
            .to_string();
        let addr = url
            .trim_start_matches("http://")
            .trim_end_matches('/')
            .to_string();
        Viewer { child, url, addr }
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
