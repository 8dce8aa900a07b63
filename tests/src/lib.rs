//! Helpers for lop's multi-process system tests: locate the `lopd` binary, spawn it with a unique
//! service prefix and a watchdog, find its children, and clean up on every path; the two-tool
//! scene the two-hands tests run.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

/// The `lopd` binary of the same build as the running test (target/<profile>/lopd).
pub fn lopd_path() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    // target/<profile>/deps/<test> -> target/<profile>/lopd
    let dir = exe.parent().and_then(|d| d.parent()).expect("target dir");
    let p = dir.join("lopd");
    assert!(
        p.exists(),
        "{} not found: build it first (`cargo test --workspace` builds it; or `cargo build -p lop-daemon`)",
        p.display()
    );
    p
}

/// Another binary of the same build (e.g. `lop-record`).
pub fn sibling_binary(name: &str) -> PathBuf {
    let p = lopd_path().with_file_name(name);
    assert!(
        p.exists(),
        "{} not found: run `cargo test --workspace`",
        p.display()
    );
    p
}

/// A service prefix no other test or rig uses.
pub fn unique_prefix(tag: &str) -> String {
    static N: AtomicU32 = AtomicU32::new(0);
    format!(
        "systest-{tag}-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    )
}

/// A spawned `lopd` that is killed (whole process group) when dropped, and by a watchdog thread
/// after `limit`, so a hung test can never leave processes behind.
pub struct Daemon {
    /// The supervisor process.
    pub child: Child,
    /// Its service prefix.
    pub prefix: String,
    /// Where its stdout and stderr go.
    pub log: PathBuf,
}

impl Daemon {
    /// Spawns `lopd ARGS` in its own process group with output to a log file.
    pub fn spawn(args: &[&str], prefix: &str, limit: Duration) -> Daemon {
        Daemon::spawn_in(args, prefix, limit, None, "")
    }

    /// [`Daemon::spawn`] in the working directory `dir` (whose `config/iceoryx2.toml` names
    /// the iceoryx2 domain), logging to `PREFIX{log_tag}.log`.
    pub fn spawn_in(
        args: &[&str],
        prefix: &str,
        limit: Duration,
        dir: Option<&Path>,
        log_tag: &str,
    ) -> Daemon {
        let log = std::env::temp_dir().join(format!("{prefix}{log_tag}.log"));
        let out = std::fs::File::create(&log).expect("log file");
        let err = out.try_clone().expect("log file");
        let mut cmd = Command::new(lopd_path());
        cmd.args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::from(out))
            .stderr(Stdio::from(err))
            .env("RUST_BACKTRACE", "0");
        if let Some(d) = dir {
            cmd.current_dir(d);
        }
        use std::os::unix::process::CommandExt;
        cmd.process_group(0);
        let child = cmd.spawn().expect("spawn lopd");
        let pid = child.id() as i32;
        std::thread::spawn(move || {
            std::thread::sleep(limit);
            // SAFETY: kill on a process group we created; harmless if it is gone.
            unsafe { libc::kill(-pid, libc::SIGKILL) };
        });
        Daemon {
            child,
            prefix: prefix.to_string(),
            log,
        }
    }

    /// Sends `sig` to the supervisor.
    pub fn signal(&self, sig: i32) {
        // SAFETY: plain kill on our child.
        unsafe { libc::kill(self.child.id() as i32, sig) };
    }

    /// Waits for the supervisor to exit, up to `limit`.
    pub fn wait(&mut self, limit: Duration) -> Option<std::process::ExitStatus> {
        let start = Instant::now();
        while start.elapsed() < limit {
            if let Ok(Some(s)) = self.child.try_wait() {
                return Some(s);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        None
    }

    /// The log so far (for assertion messages).
    pub fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            // SAFETY: kill on the process group we created.
            unsafe { libc::kill(-(self.child.id() as i32), libc::SIGKILL) };
            let _ = self.child.wait();
        }
    }
}

/// PIDs of processes whose command line contains every one of `needles`.
pub fn find_processes(needles: &[&str]) -> Vec<i32> {
    let mut pids = Vec::new();
    let Ok(dir) = std::fs::read_dir("/proc") else {
        return pids;
    };
    for entry in dir.flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<i32>() else {
            continue;
        };
        let Ok(raw) = std::fs::read(entry.path().join("cmdline")) else {
            continue;
        };
        let args: Vec<String> = raw
            .split(|&b| b == 0)
            .map(|a| String::from_utf8_lossy(a).into_owned())
            .collect();
        if needles.iter().all(|n| args.iter().any(|a| a == n)) {
            pids.push(pid);
        }
    }
    pids
}

/// A `--force-log` CSV's rows (mock and hand devices): the time, s, and |F|, N.
pub fn force_rows(path: &Path) -> Vec<(f64, f64)> {
    let csv = std::fs::read_to_string(path).expect("force log");
    csv.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|v| v.parse().unwrap()).collect();
            (f[0], (f[1] * f[1] + f[2] * f[2] + f[3] * f[3]).sqrt())
        })
        .collect()
}

/// Ctrl-C to `lopd run`: it must exit 0 within 20 s. Its log.
pub fn interrupt(daemon: &mut Daemon) -> String {
    daemon.signal(libc::SIGINT);
    let status = daemon
        .wait(Duration::from_secs(20))
        .expect("lopd run did not stop");
    let log = daemon.log_text();
    assert!(status.success(), "exit {status}\n{log}");
    log
}
