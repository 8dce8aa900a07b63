//! `lopd run`: starts `lopd haptic` and `lopd deform` as child processes of the same binary,
//! supervises them, prints a live status line and shuts both down cleanly.
//!
//! - A crashed deformation process is restarted with exponential back-off (0.2 s doubling to
//!   5 s; reset after 10 s of healthy running) while the haptic loop keeps running: the loop sees
//!   the frames go stale and ramps the force to zero, then picks up the new topology.
//! - A crashed haptic process is restarted the same way (it wrote zero force on its way out,
//!   unless it was killed); the deformation process keeps running. A process killed while
//!   writing the tool blackboard leaves its entry held, so the deformation process closes the
//!   blackboard once the tool state is 150 ms old and the new haptic process makes it anew
//!   (`deform::TOOL_DROP_NS`, `haptic::tool_board_writer`); its force starts from zero.
//! - Ctrl-C / SIGTERM / `--duration`: SIGTERM to both children (each writes zero force / stops
//!   stepping), SIGKILL after 3 s if one hangs, then dead-node clean-up and a check that no
//!   service under the prefix is left.
//! - The children get SIGTERM if the supervisor itself dies (`PR_SET_PDEATHSIG`).
//! - `--view`: the web viewer is a third child. Its control token is fixed here for the whole
//!   run (given, or 128 random bits on a loopback bind) so the printed URL stays valid across
//!   the viewer's restarts; it reaches the viewer through `LOP_VIEW_TOKEN`, not the command
//!   line other users can read.
//! - `--remote`: `lopd remote serve` is a fourth child (`crate::remote`), restarted the same
//!   way; it runs the Zenoh link tunnel as its own child and restarts it when it exits.

use std::io::{IsTerminal, Write};
use std::os::unix::process::CommandExt;
use std::path::PathBuf;
use std::process::{Child, Command};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use lop_ipc::{services, ServiceNames};

use crate::signals;
use crate::status::StatusMonitor;

/// Options of `lopd run`.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Resolved scene file.
    pub scene: PathBuf,
    /// `--device` as given, one per tool in order (already validated; empty: each tool's
    /// mock).
    pub devices: Vec<String>,
    /// Stop after this long.
    pub duration: Option<Duration>,
    /// Service prefix.
    pub prefix: String,
    /// `--config`.
    pub config: Option<PathBuf>,
    /// `--force-log`, one per device, passed to the haptic process.
    pub force_log: Vec<PathBuf>,
    /// `--record`, passed to the haptic process (a restarted one records to `NAME-N.EXT`).
    pub record: Option<PathBuf>,
    /// Status line interval.
    pub status_interval: Duration,
    /// Print the status line.
    pub status: bool,
    /// `--view`: also run the web viewer (`lopd view`, which runs `lop-view`) bound here.
    pub view: Option<String>,
    /// `--view-token` (or `LOP_VIEW_TOKEN`), already checked: the viewer's control token.
    pub view_token: Option<String>,
    /// `--view-allow-origin`: origins the viewer accepts besides its own.
    pub view_allow_origins: Vec<String>,
    /// `--remote`: the arguments of `lopd remote serve` (the tunnel already checked), run as
    /// a fourth child and restarted like the others; the rig never waits on it.
    pub remote: Option<Vec<String>>,
}

/// Environment variable through which the viewer gets its control token.
pub const VIEW_TOKEN_ENV: &str = lop_ipc::view_token::ENV;

/// Checks a user's viewer token: the viewer's own rule ([`lop_ipc::view_token::check`]).
pub fn check_view_token(token: &str) -> std::result::Result<(), String> {
    lop_ipc::view_token::check(token)
}

/// The viewer's token for this run: the given one; else, on a loopback bind, 128 bits from
/// `/dev/urandom` in hex; else none (the viewer is read-only).
fn view_control_token(bind: &str, given: Option<&str>) -> Result<Option<String>> {
    use std::net::ToSocketAddrs;
    if let Some(t) = given {
        return Ok(Some(t.to_string()));
    }
    let loopback = bind
        .to_socket_addrs()
        .ok()
        .and_then(|mut a| a.next())
        .is_some_and(|a| a.ip().is_loopback());
    if !loopback {
        return Ok(None);
    }
    let token = lop_ipc::view_token::generate()
        .context("reading /dev/urandom for the viewer's control token")?;
    Ok(Some(token))
}

/// Where `lopd run --view` and `lop-view` listen unless told otherwise: loopback only.
pub const VIEW_BIND_DEFAULT: &str = "127.0.0.1:8733";

/// A child process restarted with back-off when it exits: one of `lopd`'s roles (`lopd ROLE
/// ARGS`), or another program ([`Supervised::program`], e.g. the Zenoh link tunnel).
pub struct Supervised {
    /// What the logs call it: `lopd haptic`, `the Zenoh link tunnel`.
    name: String,
    /// The program and its arguments (for a role: this `lopd`, then the role).
    program: Option<PathBuf>,
    args: Vec<String>,
    /// Working directory; `None`: this process's.
    dir: Option<PathBuf>,
    /// Environment set (`Some`) or removed (`None`) for the child.
    env: Vec<(&'static str, Option<String>)>,
    child: Option<Child>,
    started: Instant,
    backoff: Duration,
    next_start: Option<Instant>,
    restarts: u32,
}

const BACKOFF_MIN: Duration = Duration::from_millis(200);
const BACKOFF_MAX: Duration = Duration::from_secs(5);
const HEALTHY_AFTER: Duration = Duration::from_secs(10);
const STOP_GRACE: Duration = Duration::from_secs(3);

impl Supervised {
    /// `lopd ROLE ARGS`.
    fn new(role: &'static str, args: Vec<String>) -> Supervised {
        let mut all = vec![role.to_string()];
        all.extend(args);
        Supervised::with(format!("lopd {role}"), None, all, None)
    }

    /// `program ARGS` in `dir`, called `name` in the logs.
    pub fn program(name: &str, program: PathBuf, args: Vec<String>, dir: PathBuf) -> Supervised {
        Supervised::with(name.to_string(), Some(program), args, Some(dir))
    }

    fn with(
        name: String,
        program: Option<PathBuf>,
        args: Vec<String>,
        dir: Option<PathBuf>,
    ) -> Supervised {
        Supervised {
            name,
            program,
            args,
            dir,
            env: Vec::new(),
            child: None,
            started: Instant::now(),
            backoff: BACKOFF_MIN,
            next_start: Some(Instant::now()),
            restarts: 0,
        }
    }

    fn spawn(&mut self) -> Result<()> {
        let program = match &self.program {
            Some(p) => p.clone(),
            None => std::env::current_exe().context("locating the lopd binary")?,
        };
        let mut cmd = Command::new(&program);
        cmd.args(&self.args);
        if let Some(d) = &self.dir {
            cmd.current_dir(d);
        }
        for (k, v) in &self.env {
            match v {
                Some(v) => cmd.env(k, v),
                None => cmd.env_remove(k),
            };
        }
        // SAFETY: prctl is async-signal-safe; nothing else runs between fork and exec.
        unsafe {
            cmd.pre_exec(|| {
                signals::die_with_parent();
                Ok(())
            });
        }
        let child = match cmd.spawn() {
            Ok(c) => c,
            Err(e) => {
                // Tried again after the back-off by whoever keeps going.
                self.next_start = Some(Instant::now() + self.backoff);
                self.backoff = (self.backoff * 2).min(BACKOFF_MAX);
                return Err(anyhow::Error::new(e).context(format!(
                    "starting {} ({})",
                    self.name,
                    program.display()
                )));
            }
        };
        tracing::info!("started {} (pid {})", self.name, child.id());
        self.child = Some(child);
        self.started = Instant::now();
        self.next_start = None;
        Ok(())
    }

    /// Reaps an exited child and schedules its restart.
    pub fn check(&mut self) {
        let Some(child) = &mut self.child else {
            return;
        };
        if let Ok(Some(status)) = child.try_wait() {
            if self.started.elapsed() > HEALTHY_AFTER {
                self.backoff = BACKOFF_MIN;
            }
            tracing::warn!(
                "{} (pid {}) exited: {status}; restarting in {:?}",
                self.name,
                child.id(),
                self.backoff
            );
            self.child = None;
            self.next_start = Some(Instant::now() + self.backoff);
            self.backoff = (self.backoff * 2).min(BACKOFF_MAX);
            self.restarts += 1;
        }
    }

    /// Starts the child when it is due.
    pub fn maybe_start(&mut self) -> Result<()> {
        if let Some(at) = self.next_start {
            if Instant::now() >= at {
                self.spawn()?;
            }
        }
        Ok(())
    }

    /// SIGTERM to the child, if running.
    pub fn terminate(&mut self) {
        if let Some(child) = &self.child {
            // SAFETY: plain kill on our own child's pid.
            unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
        }
    }

    /// Waits for the child until `until`, then kills it.
    pub fn wait_or_kill(&mut self, until: Instant) {
        let Some(child) = &mut self.child else {
            return;
        };
        loop {
            match child.try_wait() {
                Ok(Some(status)) => {
                    tracing::info!("{} stopped: {status}", self.name);
                    break;
                }
                Ok(None) if Instant::now() < until => std::thread::sleep(Duration::from_millis(10)),
                _ => {
                    tracing::warn!("{} did not stop in time; killing it", self.name);
                    let _ = child.kill();
                    let _ = child.wait();
                    break;
                }
            }
        }
        self.child = None;
    }

    /// How often it was restarted.
    pub fn restarts(&self) -> u32 {
        self.restarts
    }
}

/// Runs the supervisor until a stop signal or the duration. Returns the process exit code.
pub fn run(opts: RunOptions) -> Result<i32> {
    let names = ServiceNames::new(&opts.prefix)?;
    let mut common = vec![
        "--scene".to_string(),
        opts.scene.display().to_string(),
        "--prefix".to_string(),
        opts.prefix.clone(),
    ];
    if let Some(c) = &opts.config {
        common.extend(["--config".to_string(), c.display().to_string()]);
    }
    let mut haptic_args = common.clone();
    for d in &opts.devices {
        haptic_args.extend(["--device".to_string(), d.clone()]);
    }
    for f in &opts.force_log {
        haptic_args.extend(["--force-log".to_string(), f.display().to_string()]);
    }
    if let Some(r) = &opts.record {
        haptic_args.extend(["--record".to_string(), r.display().to_string()]);
    }
    let mut haptic = Supervised::new("haptic", haptic_args);
    let mut deform = Supervised::new("deform", common);
    // The web viewer, supervised like the other two (restarted if it dies; the daemon never
    // waits on it).
    let mut view = match &opts.view {
        None => None,
        Some(bind) => {
            let token = view_control_token(bind, opts.view_token.as_deref())?;
            match &token {
                Some(t) => println!(
                    "lop-view: http://{bind}/#token={t} (control with this URL; without its token a page is read-only)"
                ),
                None => println!(
                    "lop-view: http://{bind}/ (read-only: bound beyond loopback; give --view-token to control)"
                ),
            }
            let mut args = vec![
                "--prefix".to_string(),
                opts.prefix.clone(),
                "--bind".to_string(),
                bind.clone(),
            ];
            for o in &opts.view_allow_origins {
                args.extend(["--allow-origin".to_string(), o.clone()]);
            }
            let mut v = Supervised::new("view", args);
            v.env.push((VIEW_TOKEN_ENV, token));
            Some(v)
        }
    };

    let mut remote = opts
        .remote
        .as_ref()
        .map(|args| Supervised::new("remote", args.clone()));

    let mut monitor = StatusMonitor::new(&names)?;
    let tty = std::io::stdout().is_terminal();
    let start = Instant::now();
    let mut last_status = Instant::now();
    let mut code = 0;
    while !signals::stop_requested() && opts.duration.is_none_or(|d| start.elapsed() < d) {
        haptic.check();
        deform.check();
        if let Some(v) = &mut view {
            v.check();
            if let Err(e) = v.maybe_start() {
                tracing::warn!("web viewer: {e:#}");
            }
        }
        if let Some(r) = &mut remote {
            r.check();
            if let Err(e) = r.maybe_start() {
                tracing::warn!("remote: {e:#}");
            }
        }
        if let Err(e) = haptic.maybe_start().and_then(|()| deform.maybe_start()) {
            tracing::error!("{e:#}");
            code = 1;
            break;
        }
        monitor.poll();
        if opts.status && last_status.elapsed() >= opts.status_interval {
            last_status = Instant::now();
            let line = monitor.line(deform.restarts);
            let mut out = std::io::stdout().lock();
            if tty {
                let _ = write!(out, "\r\x1b[2K{line}");
            } else {
                let _ = writeln!(out, "status: {line}");
            }
            let _ = out.flush();
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    if tty && opts.status {
        println!();
    }

    // Shut down: the haptic loop first (zero force), then the deformation process.
    monitor.detach();
    haptic.terminate();
    deform.terminate();
    if let Some(v) = &mut view {
        v.terminate();
    }
    if let Some(r) = &mut remote {
        r.terminate();
    }
    let until = Instant::now() + STOP_GRACE;
    haptic.wait_or_kill(until);
    deform.wait_or_kill(until);
    if let Some(v) = &mut view {
        v.wait_or_kill(until);
    }
    if let Some(r) = &mut remote {
        r.wait_or_kill(until);
    }
    drop(monitor);

    let node = services::node("lopd-run-cleanup")?;
    let cleaned = services::cleanup_dead_nodes(&node);
    drop(node);
    if cleaned > 0 {
        tracing::info!("cleaned {cleaned} dead node(s)");
    }
    let left = services::list_services(&opts.prefix);
    if left.is_empty() {
        tracing::info!("stopped cleanly; no service left under {:?}", opts.prefix);
    } else {
        tracing::warn!("services left under {:?}: {left:?}", opts.prefix);
    }
    println!(
        "lopd run: stopped; haptic restarts {}, deform restarts {}",
        haptic.restarts, deform.restarts
    );
    Ok(code)
}
