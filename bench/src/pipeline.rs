//! Spawning the real pipeline (`lopd run`) and other helper processes so that nothing is ever left
//! behind: every child sits in a [`ChildGuard`] that stops it when dropped (SIGTERM, then SIGKILL
//! after a grace period), on success and on every error path alike, and every child gets SIGTERM
//! from the kernel if the bench itself dies (`PR_SET_PDEATHSIG`). `lopd run` passes the same on
//! to its own children.

use std::fs::File;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, Context, Result};
use lop_client::Attachment;

/// Makes SIGINT, SIGTERM and SIGHUP set a flag instead of killing the bench, so that the waiting
/// loops (which call [`Lopd::check_alive`]) end with an error and every guard stops its child.
/// The same handler as `lopd`'s.
pub fn install_stop_handler() {
    lop_ipc::signals::install();
}

/// Whether the bench was asked to stop.
pub fn interrupted() -> bool {
    lop_ipc::signals::stop_requested()
}

/// A child process that is stopped when the guard is dropped.
pub struct ChildGuard {
    name: String,
    child: Option<Child>,
    grace: Duration,
    status: Option<ExitStatus>,
}

impl ChildGuard {
    /// Spawns `cmd`; the child gets SIGTERM if this process dies. `grace` is how long
    /// [`ChildGuard::stop`] waits after SIGTERM before SIGKILL.
    pub fn spawn(name: &str, mut cmd: Command, grace: Duration) -> Result<ChildGuard> {
        // SAFETY: prctl is async-signal-safe and touches nothing of the parent.
        unsafe {
            cmd.pre_exec(|| {
                lop_ipc::signals::die_with_parent();
                Ok(())
            });
        }
        let child = cmd
            .spawn()
            .with_context(|| format!("starting {name} ({:?})", cmd.get_program()))?;
        Ok(ChildGuard {
            name: name.to_string(),
            child: Some(child),
            grace,
            status: None,
        })
    }

    /// The child's process id.
    pub fn id(&self) -> u32 {
        self.child.as_ref().map_or(0, |c| c.id())
    }

    /// The child, e.g. to take its pipes.
    pub fn child_mut(&mut self) -> Option<&mut Child> {
        self.child.as_mut()
    }

    /// The exit status if the child has exited (reaps it), without waiting.
    pub fn try_wait(&mut self) -> Option<ExitStatus> {
        if self.status.is_none() {
            if let Some(child) = &mut self.child {
                if let Ok(Some(s)) = child.try_wait() {
                    self.status = Some(s);
                }
            }
        }
        self.status
    }

    /// Waits up to `limit` for the child to exit by itself.
    pub fn wait_for(&mut self, limit: Duration) -> Option<ExitStatus> {
        let until = Instant::now() + limit;
        loop {
            if let Some(s) = self.try_wait() {
                return Some(s);
            }
            if Instant::now() >= until {
                return None;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// SIGTERM, wait up to the grace period, then SIGKILL. Returns the exit status (`None` if
    /// it had to be killed).
    pub fn stop(&mut self) -> Option<ExitStatus> {
        if let Some(s) = self.try_wait() {
            return Some(s);
        }
        let Some(child) = &mut self.child else {
            return None;
        };
        // SAFETY: kill on our own, not yet reaped child: the pid cannot have been reused.
        unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
        if let Some(s) = self.wait_for(self.grace) {
            return Some(s);
        }
        eprintln!(
            "lop-bench: {} (pid {}) did not stop within {:?} of SIGTERM; killing it",
            self.name,
            self.id(),
            self.grace
        );
        if let Some(child) = &mut self.child {
            let _ = child.kill();
            let _ = child.wait();
        }
        self.child = None;
        None
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The `lopd` binary: `explicit` if given, else the `lopd` next to this executable (the same
/// cargo profile).
pub fn find_lopd(explicit: Option<&Path>) -> Result<PathBuf> {
    if let Some(p) = explicit {
        if p.is_file() {
            return Ok(p.to_path_buf());
        }
        bail!("--lopd {}: no such file", p.display());
    }
    let exe = std::env::current_exe().context("locating the lop-bench executable")?;
    let p = exe.with_file_name("lopd");
    if p.is_file() {
        return Ok(p);
    }
    let profile = if cfg!(debug_assertions) {
        ""
    } else {
        " --release"
    };
    bail!(
        "lopd not found next to {} ({} does not exist): build it in the same profile with \
         `cargo build{profile} -p lop-daemon`, or pass --lopd PATH",
        exe.display(),
        p.display()
    )
}

/// A service prefix no other rig or bench run uses: `lopbench-<pid>` (then `-2`, `-3`, … for
/// further pipelines of the same process).
pub fn unique_prefix() -> String {
    static N: AtomicU32 = AtomicU32::new(0);
    match N.fetch_add(1, Ordering::Relaxed) {
        0 => format!("lopbench-{}", std::process::id()),
        n => format!("lopbench-{}-{}", std::process::id(), n + 1),
    }
}

/// How to run the pipeline.
#[derive(Debug, Clone)]
pub struct LopdOptions {
    /// The `lopd` binary.
    pub lopd: PathBuf,
    /// Scene name or path.
    pub scene: String,
    /// `--device`.
    pub device: String,
    /// `--duration`: a backstop only, the bench stops the pipeline itself.
    pub duration: Duration,
    /// Service prefix.
    pub prefix: String,
    /// More arguments of `lopd run` (`--force-log`, `--record`, `--view`, …).
    pub extra_args: Vec<String>,
    /// Where the log goes, kept after a clean stop; `None`: `TMPDIR/PREFIX.lopd.log`, removed
    /// after a clean stop.
    pub log: Option<PathBuf>,
}

/// A running `lopd run`, its output going to a log file (removed after a clean stop unless
/// [`LopdOptions::log`] placed it).
pub struct Lopd {
    guard: ChildGuard,
    /// The service prefix.
    pub prefix: String,
    /// The log of `lopd run` and its children (stdout and stderr).
    pub log: PathBuf,
    keep_log: bool,
}

/// How long `lopd run` gets between SIGTERM and SIGKILL (it gives its own children 3 s).
const LOPD_GRACE: Duration = Duration::from_secs(5);

impl Lopd {
    /// Starts `lopd run --scene … --device … --duration … --prefix … --quiet`.
    pub fn spawn(opts: &LopdOptions) -> Result<Lopd> {
        let log = opts
            .log
            .clone()
            .unwrap_or_else(|| std::env::temp_dir().join(format!("{}.lopd.log", opts.prefix)));
        let out = File::create(&log).with_context(|| format!("creating {}", log.display()))?;
        let err = out.try_clone()?;
        let mut cmd = Command::new(&opts.lopd);
        cmd.arg("run")
            .args(["--scene", &opts.scene])
            .args(["--device", &opts.device])
            .args(["--duration", &format!("{:.3}", opts.duration.as_secs_f64())])
            .args(["--prefix", &opts.prefix])
            .arg("--quiet")
            .args(&opts.extra_args)
            .stdin(Stdio::null())
            .stdout(Stdio::from(out))
            .stderr(Stdio::from(err));
        let guard = ChildGuard::spawn("lopd run", cmd, LOPD_GRACE)?;
        Ok(Lopd {
            guard,
            prefix: opts.prefix.clone(),
            log,
            keep_log: opts.log.is_some(),
        })
    }

    /// The process id of `lopd run`.
    pub fn pid(&self) -> u32 {
        self.guard.id()
    }

    /// The last `n` lines of the log, introduced by its path ("end of its log PATH:\n…").
    pub fn log_tail(&self, n: usize) -> String {
        let text = std::fs::read_to_string(&self.log).unwrap_or_default();
        let lines: Vec<&str> = text.lines().collect();
        if lines.is_empty() {
            return format!("its log {} is empty", self.log.display());
        }
        format!(
            "end of its log {}:\n{}",
            self.log.display(),
            lines[lines.len().saturating_sub(n)..].join("\n")
        )
    }

    /// An error if `lopd run` has exited (with the end of its log), or if the bench was
    /// interrupted.
    pub fn check_alive(&mut self) -> Result<()> {
        if interrupted() {
            bail!("interrupted");
        }
        match self.guard.try_wait() {
            None => Ok(()),
            Some(status) => Err(anyhow!(
                "lopd run exited early ({status}); {}",
                self.log_tail(20)
            )),
        }
    }

    /// Attaches read-only, retrying until `timeout` while checking that `lopd` still runs.
    pub fn attach(&mut self, timeout: Duration) -> Result<Attachment> {
        let start = Instant::now();
        loop {
            self.check_alive()?;
            match Attachment::open(&self.prefix, Duration::from_millis(250)) {
                Ok(a) => return Ok(a),
                Err(e) if start.elapsed() >= timeout => {
                    return Err(anyhow!(e)).with_context(|| {
                        format!(
                            "attaching to lopd (prefix {:?}) within {timeout:?}; {}",
                            self.prefix,
                            self.log_tail(20)
                        )
                    })
                }
                Err(_) => {}
            }
        }
    }

    /// SIGTERM (SIGKILL after 5 s) and wait. A clean exit removes the log (unless it was
    /// placed); otherwise the error names it.
    pub fn stop(mut self) -> Result<ExitStatus> {
        let status = self.guard.stop();
        self.judge(status)
    }

    /// Waits up to `limit` for `lopd run` to end by itself (its `--duration`), then as
    /// [`stop`](Self::stop).
    pub fn wait(mut self, limit: Duration) -> Result<ExitStatus> {
        let status = match self.guard.wait_for(limit) {
            Some(s) => Some(s),
            None => self.guard.stop(),
        };
        self.judge(status)
    }

    fn judge(self, status: Option<ExitStatus>) -> Result<ExitStatus> {
        match status {
            Some(s) if s.success() => {
                if !self.keep_log {
                    let _ = std::fs::remove_file(&self.log);
                }
                Ok(s)
            }
            Some(s) => bail!("lopd run exited with {s}; {}", self.log_tail(20)),
            None => bail!(
                "lopd run did not stop within {LOPD_GRACE:?} of SIGTERM and was killed; log: {}",
                self.log.display()
            ),
        }
    }
}
