//! The daemon configuration (`lopd --config PATH`).

use std::path::Path;

use crate::check::{fmt_f64, Check};
use crate::error::ConfigError;
use crate::raw::RawDaemon;
use crate::source::{KeyPath, Source};

/// Daemon settings. Every key has a default, so an empty file is a valid configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct DaemonConfig {
    /// The real-time haptic loop.
    pub haptic: HapticConfig,
    /// The deformation process.
    pub deform: DeformConfig,
    /// Interval of the status line / status publication, ms (> 0). Default 500.
    pub status_interval_ms: u64,
    /// Device drivers (`[device]`).
    pub device: DeviceConfig,
    /// The scene carried to other hosts (`[remote]`, `lopd run --remote`).
    pub remote: crate::remote::RemoteConfig,
}

impl Default for DaemonConfig {
    fn default() -> Self {
        DaemonConfig {
            haptic: HapticConfig::default(),
            deform: DeformConfig::default(),
            status_interval_ms: 500,
            device: DeviceConfig::default(),
            remote: crate::remote::RemoteConfig::default(),
        }
    }
}

/// Settings of the real-time haptic thread.
#[derive(Debug, Clone, PartialEq)]
pub struct HapticConfig {
    /// CPU to pin the RT thread to; `None`: the last core.
    pub core: Option<usize>,
    /// `SCHED_FIFO` priority, 1..=99. Default 80.
    pub rt_priority: u8,
    /// `mlockall` the process. Default true.
    pub lock_memory: bool,
    /// A frame older than this (ms) ramps the force to zero. Default 100.
    pub stale_frame_ms: f64,
    /// Ramp-down time to zero force, ms (0..=100). Default 5.
    pub ramp_ms: f64,
    /// Global force clamp, N. The effective clamp is `min(this, tool.max_force, device limit)`.
    /// Default 3.0.
    pub max_force_n: f64,
    /// Busy-wait before each deadline, µs (0..=1000). Default 50.
    pub spin_us: f64,
    /// Largest force change per tick beyond what the stylus's motion explains, N (contact onset
    /// included). Default 0.05.
    pub max_force_step_n: f64,
    /// Render between frames with the frame's local model of the contact patch (the force
    /// follows the hand tick by tick); false: against the frame's surface alone. Default true.
    pub local_model: bool,
    /// Most damping the passivity controller adds at the stylus, N·s/m (0..=40; 0 turns the
    /// controller off). Default 5: inside the range of a hand's own damping (1–10 N·s/m), and
    /// far below what a 45 g stylus sampled at 1 kHz takes from a backward-difference damper
    /// (`α T / m < 1`: `α` < 45 N·s/m).
    pub passivity_max_damping: f64,
}

impl Default for HapticConfig {
    fn default() -> Self {
        HapticConfig {
            core: None,
            rt_priority: 80,
            lock_memory: true,
            stale_frame_ms: 100.0,
            ramp_ms: 5.0,
            max_force_n: 3.0,
            spin_us: 50.0,
            max_force_step_n: 0.05,
            local_model: true,
            passivity_max_damping: 5.0,
        }
    }
}

/// Settings of the deformation process.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DeformConfig {
    /// CPU to pin the deformation thread to; `None`: not pinned.
    pub core: Option<usize>,
    /// Threads the touched body's FEM step runs on (`[deform] threads`), resolved: at least
    /// 1, at most the machine's cores. 0 or missing in the file: [`default_deform_threads`].
    pub threads: usize,
    /// The longest period a touched body may step at when its step costs more than its
    /// configured period on this machine (`[deform] max_period_ms`, 1..=100; default 10): the
    /// deformation process lengthens the period so that simulated time keeps up with the wall
    /// clock (`lop_sim::world::pace`), and the haptic loop renders the local model between the
    /// frames. A period at or below the body's own keeps the body at its own.
    pub max_period_ms: u32,
    /// `SCHED_FIFO` priority of the deformation thread (`[deform] rt_priority`), below the
    /// haptic loop's and its frame thread's; 0: the normal scheduler. Where the process may not
    /// take it (no `CAP_SYS_NICE` or rtprio limit) it runs normally, with a warning. Default
    /// [`DEFAULT_DEFORM_RT_PRIORITY`] (at most the haptic priority − 2): a rig's renderer and
    /// anything else at the normal scheduler then no longer delay the tissue (two busy
    /// processes beside `lopd run` made the default poke peak at 1.19 N against 0.71 N quiet;
    /// `docs/benchmarks.md`, pipeline latency).
    pub rt_priority: u8,
}

/// `[deform] rt_priority` when missing (lowered to the haptic priority − 2 when that is
/// lower, 0 when it is under 1).
pub const DEFAULT_DEFORM_RT_PRIORITY: u8 = 40;

/// `[deform] max_period_ms` when missing: 10 ms, the longest frame interval at which the local
/// model keeps the coupling smooth on the organs measured (`docs/benchmarks.md`, pipeline
/// latency).
pub const DEFAULT_MAX_PERIOD_MS: u32 = 10;

impl Default for DeformConfig {
    fn default() -> Self {
        DeformConfig {
            core: None,
            threads: default_deform_threads(),
            max_period_ms: DEFAULT_MAX_PERIOD_MS,
            rt_priority: default_deform_priority(HapticConfig::default().rt_priority),
        }
    }
}

/// `[deform] rt_priority` when missing, for a haptic loop at `haptic` (its frame thread runs at
/// `haptic − 1`).
pub fn default_deform_priority(haptic: u8) -> u8 {
    DEFAULT_DEFORM_RT_PRIORITY.min(haptic.saturating_sub(2))
}

/// The machine's cores (logical CPUs available to this process).
pub fn machine_cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// `[deform] threads` when 0 or missing: every core but one, at least 1 — the haptic loop
/// keeps a core of its own (on the 2-core development machine: 1).
pub fn default_deform_threads() -> usize {
    machine_cores().saturating_sub(1).max(1)
}

/// Reads and validates a daemon configuration file.
pub fn load_daemon_config(path: &Path) -> Result<DaemonConfig, ConfigError> {
    let text = crate::source::read_text(path)?;
    parse_daemon_config(&text, path)
}

/// Parses and validates daemon configuration text; `path` is used only in messages.
pub fn parse_daemon_config(text: &str, path: &Path) -> Result<DaemonConfig, ConfigError> {
    let src = Source::parse(path, text)?;
    let raw: RawDaemon = src.deserialize()?;
    let c = Check {
        src: &src,
        body: None,
    };
    let d = DaemonConfig::default();
    let dh = &d.haptic;
    let h = raw.haptic;
    let k = KeyPath::top("haptic");

    let rt_priority = h.rt_priority.unwrap_or(dh.rt_priority);
    if !(1..=99).contains(&rt_priority) {
        return Err(c.invalid(
            &k.key("rt_priority"),
            rt_priority,
            "SCHED_FIFO priority must be between 1 and 99",
        ));
    }
    let status_interval_ms = raw.status_interval_ms.unwrap_or(d.status_interval_ms);
    if status_interval_ms == 0 {
        return Err(c.invalid(
            &KeyPath::top("status_interval_ms"),
            0,
            "status_interval_ms must be > 0",
        ));
    }
    let stale_frame_ms = c.positive(
        &k.key("stale_frame_ms"),
        h.stale_frame_ms.unwrap_or(dh.stale_frame_ms),
        "stale_frame_ms",
    )?;
    // Safety invariant 2: a stale frame ramps the force to zero "within a few ticks".
    let ramp_ms = c.within(
        &k.key("ramp_ms"),
        h.ramp_ms.unwrap_or(dh.ramp_ms),
        0.0,
        100.0,
        "ramp_ms (ramp-down to zero force)",
    )?;
    let max_force_n = c.positive(
        &k.key("max_force_n"),
        h.max_force_n.unwrap_or(dh.max_force_n),
        "max_force_n",
    )?;
    let spin_us = c.within(
        &k.key("spin_us"),
        h.spin_us.unwrap_or(dh.spin_us),
        0.0,
        1000.0,
        "spin_us (busy-wait before the deadline, µs)",
    )?;
    let max_force_step_n = c.positive(
        &k.key("max_force_step_n"),
        h.max_force_step_n.unwrap_or(dh.max_force_step_n),
        "max_force_step_n",
    )?;
    // A backward-difference damper on a 45 g stylus at 1 kHz is stable below about 45 N·s/m.
    let passivity_max_damping = c.within(
        &k.key("passivity_max_damping"),
        h.passivity_max_damping.unwrap_or(dh.passivity_max_damping),
        0.0,
        40.0,
        "passivity_max_damping (N·s/m)",
    )?;
    if max_force_step_n > max_force_n {
        return Err(c.invalid(
            &k.key("max_force_step_n"),
            fmt_f64(max_force_step_n),
            format!(
                "max_force_step_n must not exceed max_force_n = {}",
                fmt_f64(max_force_n)
            ),
        ));
    }

    let cores = machine_cores();
    let threads = match raw.deform.threads.unwrap_or(0) {
        0 => default_deform_threads(),
        n if n > cores => {
            return Err(c.invalid(
                &KeyPath::top("deform").key("threads"),
                n,
                format!("{n} threads asked, but this machine has {cores} cores"),
            ))
        }
        n => n,
    };
    let max_period_ms = raw.deform.max_period_ms.unwrap_or(DEFAULT_MAX_PERIOD_MS);
    if !(1..=100).contains(&max_period_ms) {
        return Err(c.invalid(
            &KeyPath::top("deform").key("max_period_ms"),
            max_period_ms,
            "the longest step period must be between 1 and 100 ms",
        ));
    }
    let deform_priority = match raw.deform.rt_priority {
        None => default_deform_priority(rt_priority),
        Some(0) => 0,
        Some(p) if p + 1 < u32::from(rt_priority) => p as u8,
        Some(p) => {
            return Err(c.invalid(
                &KeyPath::top("deform").key("rt_priority"),
                p,
                format!(
                    "the deformation thread's SCHED_FIFO priority must be below the haptic \
                     loop's frame thread ([haptic] rt_priority {rt_priority} - 1 = {}), or 0 for \
                     the normal scheduler",
                    rt_priority - 1
                ),
            ))
        }
    };
    Ok(DaemonConfig {
        haptic: HapticConfig {
            core: h.core.or(dh.core),
            rt_priority,
            lock_memory: h.lock_memory.unwrap_or(dh.lock_memory),
            stale_frame_ms,
            ramp_ms,
            max_force_n,
            spin_us,
            max_force_step_n,
            local_model: h.local_model.unwrap_or(dh.local_model),
            passivity_max_damping,
        },
        deform: DeformConfig {
            core: raw.deform.core,
            threads,
            max_period_ms,
            rt_priority: deform_priority,
        },
        status_interval_ms,
        device: device_config(&c, raw.device, path)?,
        remote: crate::remote::remote_config(&c, raw.remote, path)?,
    })
}

/// Settings of the device drivers (`[device]`).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct DeviceConfig {
    /// The OpenHaptics HD library (`libHD.so`) to load for `--device openhaptics`; a relative
    /// path is relative to the config file. `None`: the loader's search and the usual install
    /// directories. The environment variable `LOP_HD_LIBRARY` wins over this key.
    pub hd_library: Option<std::path::PathBuf>,
    /// The Force Dimension DHD library (`libdhd.so`) to load for `--device dhd`; a relative
    /// path is relative to the config file. `None`: the loader's search and the usual install
    /// directories. The environment variable `LOP_DHD_LIBRARY` wins over this key.
    pub dhd_library: Option<std::path::PathBuf>,
}

fn device_config(
    c: &Check,
    raw: crate::raw::RawDaemonDevice,
    config_path: &Path,
) -> Result<DeviceConfig, ConfigError> {
    let resolve = |p: std::path::PathBuf| {
        if p.is_relative() {
            config_path.parent().unwrap_or(Path::new(".")).join(p)
        } else {
            p
        }
    };
    if raw
        .dhd_library
        .as_ref()
        .is_some_and(|p| p.as_os_str().is_empty())
    {
        return Err(c.invalid(
            &KeyPath::top("device").key("dhd_library"),
            "\"\"",
            "dhd_library must name the DHD library file (libdhd.so); leave the key out to \
             search the usual places",
        ));
    }
    Ok(DeviceConfig {
        hd_library: raw.hd_library.map(resolve),
        dhd_library: raw.dhd_library.map(resolve),
    })
}
