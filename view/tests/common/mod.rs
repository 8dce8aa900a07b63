//! Helpers for lop-view's tests: spawn `lop-view` on a free port and kill it on drop; keep its
//! stderr (the refusal log lines) for the test to read.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A running `lop-view`, killed when dropped (and by a watchdog after `limit`).
#[allow(dead_code)] // each test binary uses a part
pub struct Viewer {
    pub child: Child,
    /// The printed URL, `http://127.0.0.1:PORT/#token=…` (no fragment when read-only).
    pub url: String,
    /// `127.0.0.1:PORT` as printed (the bound address).
    pub addr: String,
    /// The printed token, if any.
    pub token: Option<String>,
    /// The whole first stdout line.
    pub line: String,
    stderr: Arc<Mutex<String>>,
}

#[allow(dead_code)]
impl Viewer {
    pub fn spawn(prefix: &str, limit: Duration) -> Viewer {
        Viewer::spawn_with(prefix, limit, &["--bind", "127.0.0.1:0"])
    }

    /// Spawns with `args` after `--prefix`, which must include `--bind`.
    pub fn spawn_with(prefix: &str, limit: Duration, args: &[&str]) -> Viewer {
        let exe = lop_system_tests::sibling_binary("lop-view");
        let mut child = Command::new(exe)
            .args(["--prefix", prefix])
            .args(args)
            .env_remove("LOP_VIEW_TOKEN")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawn lop-view");
        let pid = child.id() as i32;
        std::thread::spawn(move || {
            std::thread::sleep(limit);
            // SAFETY: kill on a process this test started; harmless if it is gone.
            unsafe { libc::kill(pid, libc::SIGKILL) };
        });
        let stderr = Arc::new(Mutex::new(String::new()));
        {
            let stderr = stderr.clone();
            let pipe = child.stderr.take().expect("stderr");
            std::thread::spawn(move || {
                for line in BufReader::new(pipe).lines().map_while(Result::ok) {
                    eprintln!("{line}");
                    let mut s = stderr.lock().unwrap();
                    s.push_str(&line);
                    s.push('\n');
                }
            });
        }
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("stdout"))
            .read_line(&mut line)
            .expect("lop-view prints its URL");
        // "lop-view: http://127.0.0.1:PORT/#token=… (prefix …; …)"
        let url = line
            .split_whitespace()
            .find(|w| w.starts_with("http://"))
            .unwrap_or_else(|| panic!("no URL in {line:?}"))
            .to_string();
        let addr = url
            .trim_start_matches("http://")
            .split('/')
            .next()
            .unwrap()
            .to_string();
        let token = url.split_once("#token=").map(|(_, t)| t.to_string());
        Viewer {
            child,
            url,
            addr,
            token,
            line,
            stderr,
        }
    }

    /// `127.0.0.1:PORT` for a viewer bound to any address.
    pub fn loopback_addr(&self) -> String {
        let port = self.addr.rsplit(':').next().unwrap();
        format!("127.0.0.1:{port}")
    }

    /// Waits (up to 5 s) for a stderr line containing all of `parts`; returns it.
    pub fn log_line(&self, parts: &[&str]) -> String {
        let start = Instant::now();
        loop {
            let text = self.stderr.lock().unwrap().clone();
            if let Some(l) = text.lines().find(|l| parts.iter().all(|p| l.contains(p))) {
                return l.to_string();
            }
            assert!(
                start.elapsed() < Duration::from_secs(5),
                "no stderr line with {parts:?} in:\n{text}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Viewer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
