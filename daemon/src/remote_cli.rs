//! `lopd remote attach | serve` and `lopd run --remote`'s child: the command line over
//! [`lop_daemon::remote`], `[remote]` of the daemon config with the flags' replacements.

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Result;
use clap::{Args, Subcommand};
use lop_config::{load_daemon_config, DaemonConfig, RemoteConfig, RemoteOverrides};
use lop_ipc::ServiceNames;

use crate::bad;

#[derive(Subcommand)]
pub(crate) enum RemoteCommand {
    /// On a far host: bring one rig's scene into this host's iceoryx2 domain, so `lop-view`,
    /// `lop-record` and the Python consumer attach here as on the rig (same --prefix). Runs
    /// until Ctrl-C.
    Attach(RemoteArgs),
    /// On the rig (started by `lopd run --remote`): copy the renderer-facing services into an
    /// export domain and run the tunnel there. Runs until Ctrl-C.
    Serve(RemoteArgs),
}

#[derive(Args, Clone)]
pub(crate) struct RemoteArgs {
    /// The rig's service prefix.
    #[arg(long, default_value = lop_ipc::SERVICE_PREFIX_DEFAULT)]
    prefix: String,
    /// Daemon configuration TOML whose `[remote]` section is the starting point.
    #[arg(long)]
    config: Option<PathBuf>,
    /// A Zenoh endpoint to listen on (peer mode), e.g. tcp/0.0.0.0:7447; repeatable; replaces
    /// `[remote] listen`.
    #[arg(long, value_name = "ENDPOINT")]
    listen: Vec<String>,
    /// A Zenoh endpoint to connect to: the rig (tcp/RIG:7447) or a router; repeatable;
    /// replaces `[remote] connect`.
    #[arg(long, value_name = "ENDPOINT")]
    connect: Vec<String>,
    /// peer | client (of a Zenoh router named by --connect).
    #[arg(long)]
    mode: Option<String>,
    /// The tunnel program (default: lop-tunnel beside lopd, then on PATH).
    #[arg(long)]
    tunnel: Option<PathBuf>,
    /// A Zenoh configuration file given to the tunnel as is (mode and endpoints unused).
    #[arg(long)]
    zenoh_config: Option<PathBuf>,
    /// Stop after this many seconds.
    #[arg(long)]
    duration: Option<f64>,
}

impl RemoteArgs {
    /// `[remote]` of `--config` (or the defaults) with the flags' replacements.
    fn resolve(&self) -> Result<RemoteConfig> {
        let base = match &self.config {
            Some(p) => bad(load_daemon_config(p))?.remote,
            None => RemoteConfig::default(),
        };
        let overrides = RemoteOverrides {
            listen: self.listen.clone(),
            connect: self.connect.clone(),
            mode: self.mode.clone(),
            tunnel: self.tunnel.clone(),
            zenoh_config: self.zenoh_config.clone(),
        };
        bad(base.with_overrides(&overrides).map_err(anyhow::Error::msg))
    }
}

/// `lopd run --remote`: the arguments of its `lopd remote serve` child, or `None` when the
/// tunnel cannot run (logged: the rig runs without it). `config` is the run's loaded daemon
/// config (at `config_path`), `listen` its `--remote-listen`.
pub(crate) fn rig_child(
    prefix: &str,
    config_path: Option<&Path>,
    config: &DaemonConfig,
    listen: &[String],
) -> Result<Option<Vec<String>>> {
    let overrides = RemoteOverrides {
        listen: listen.to_vec(),
        ..RemoteOverrides::default()
    };
    let remote = bad(config
        .remote
        .clone()
        .with_overrides(&overrides)
        .map_err(|e| anyhow::anyhow!("{}", e.replace("--listen", "--remote-listen"))))?;
    if let Err(e) = lop_daemon::remote::check_tunnel(&remote.tunnel) {
        tracing::error!("--remote: {e:#}; the rig runs without it");
        return Ok(None);
    }
    let mut args = vec![
        "serve".to_string(),
        "--prefix".to_string(),
        prefix.to_string(),
    ];
    if let Some(c) = config_path {
        args.extend(["--config".to_string(), c.display().to_string()]);
    }
    for e in listen {
        args.extend(["--listen".to_string(), e.clone()]);
    }
    Ok(Some(args))
}

/// `lopd remote …`.
pub(crate) fn run(command: RemoteCommand) -> Result<i32> {
    match command {
        RemoteCommand::Serve(a) => {
            let names = bad(ServiceNames::new(&a.prefix))?;
            lop_daemon::remote::serve(&names, &a.resolve()?)
        }
        RemoteCommand::Attach(a) => {
            bad(ServiceNames::new(&a.prefix))?;
            let mut r = a.resolve()?;
            // A far host connects; it listens only where told.
            if a.listen.is_empty() && a.config.is_none() {
                r.listen.clear();
            }
            if r.connect.is_empty() && r.zenoh_config.is_none() && r.listen.is_empty() {
                bad(Err::<(), _>(anyhow::anyhow!(
                    "lopd remote attach needs the rig: --connect tcp/RIG:7447 (or a router's \
                     endpoint, or --listen for a rig that connects here)"
                )))?;
            }
            let duration = match a.duration {
                Some(s) if s.is_finite() && s > 0.0 => Some(Duration::from_secs_f64(s)),
                Some(s) => bad(Err(anyhow::anyhow!("--duration {s}: must be > 0 seconds")))?,
                None => None,
            };
            lop_daemon::remote::attach(&lop_daemon::remote::AttachOptions {
                prefix: a.prefix,
                remote: r,
                duration,
            })
        }
    }
}
