//! The haptic pipeline and the deformation rounds coupled in one process on simulated time,
//! with the simulated hand holding the stylus: what `lopd run --device hand` does, without
//! shared memory or the wall clock, so that a press can be replayed deterministically and the
//! coupling's stability measured (`lopd simulate --device hand[:SCRIPT]`, `lop-bench haptics`
//! part 3, and the tests).
//!
//! Each tick `n` at `t = n T` (`T` the scene's haptic period), in the live loop's order:
//!
//! 1. the hand device is read at `t` (it integrates the hand and the stylus at 10 kHz under the
//!    force written the tick before);
//! 2. the live loop's own [`HapticPipeline`], with the same settings
//!    ([`pipeline_settings`](crate::pipeline_settings)), renders against the world as its last
//!    round left it ([`OfflineSession::surfaces`]: the surfaces, the proxy resting where the
//!    patch balanced, the patch's local model);
//! 3. the force is written to the device;
//! 4. the world runs its round to `t + T` with this tick's tool ([`OfflineSession::advance`]).
//!
//! So a frame is one tick old when the hand feels it if the touched body steps every tick (the
//! live loop's frame age is then 0.5–1.4 ms, `lop-bench latency`). A body that steps at a
//! longer period `P` (its FEM `dt`, as the deformation process chooses it live for an organ
//! whose step costs more than a tick) changes its surface every `P`, and the frame the hand
//! feels ages from one tick to `P` between steps: the local model extrapolates over that age,
//! as live. Everything else that depends on the wall clock live (the step's own duration,
//! scheduling) is absent here.

use anyhow::{Context, Result};
use lop_config::{DaemonConfig, Scene};
use lop_drivers::hand::{HandDevice, HandParameters};
use lop_drivers::mock::MockScript;
use lop_drivers::{DeviceLimits, HapticDevice, BUTTON_GRAB, BUTTON_HEAT};
use lop_sim::haptic::{DeviceReading, HapticPipeline};

use crate::session::{OfflineSession, RoundInput, TickRecord};
use crate::{DeviceClamp, ToolLaws};

/// What to run.
#[derive(Debug, Clone)]
pub struct ClosedLoopOptions {
    /// The scene (as loaded; callers may change its parameters first).
    pub scene: Scene,
    /// The hand's intent.
    pub script: MockScript,
    /// The hand; `None`: the script's `[hand]` table, else the defaults.
    pub hand: Option<HandParameters>,
    /// The device; its stiffness limit clamps the tool law as live.
    pub limits: DeviceLimits,
    /// The daemon's settings (the haptic loop's local model, passivity, safety).
    pub config: DaemonConfig,
    /// Simulated seconds.
    pub seconds: f64,
}

/// A run's ticks and the passivity controller's account.
#[derive(Debug, Clone)]
pub struct ClosedLoopRun {
    /// Every tick.
    pub ticks: Vec<TickRecord>,
    /// Energy the passivity controller dissipated, J.
    pub dissipated: f64,
    /// Ticks on which it acted.
    pub passivity_ticks: u64,
    /// The tool stiffness felt against each body (scene N/m, after the device's clamp).
    pub stiffness: Vec<f64>,
}

/// Runs the closed loop (see the module docs).
pub fn run(opts: ClosedLoopOptions) -> Result<ClosedLoopRun> {
    let settings = crate::pipeline_settings(&opts.config, &opts.scene, &opts.limits);
    let laws = ToolLaws::new(
        &opts.scene,
        DeviceClamp {
            max_stiffness_n_per_mm: opts.limits.max_stiffness_n_per_mm,
        },
    );
    let mut device = match opts.hand {
        Some(p) => HandDevice::with_parameters(opts.script.clone(), p, opts.limits)
            .context("hand parameters")?,
        None => HandDevice::new(opts.script.clone(), opts.limits),
    };
    device
        .start()
        .map_err(|e| anyhow::anyhow!("starting the hand device: {e}"))?;
    let loaded = crate::load(opts.scene.clone())?;
    let mut session = OfflineSession::new(loaded.world, laws);
    let period = settings.period();
    let ticks = (opts.seconds / period).round() as usize;
    let stiffness = settings.body_stiffness.clone();
    let mut pipeline = HapticPipeline::new(settings);
    let mut out = Vec::with_capacity(ticks);
    // Stage timings on a counter: the run stays deterministic.
    let mut clock = 0u64;
    for n in 0..ticks {
        let t = n as f64 * period;
        let sample = device
            .read(t)
            .map_err(|e| anyhow::anyhow!("hand device at {t} s: {e}"))?;
        let reading = DeviceReading {
            position_mm: sample.position_mm,
            velocity_mm_s: sample.velocity_mm_s,
            grab: sample.pressed(BUTTON_GRAB),
        };
        // The frame the hand feels is the touched body's last step: one tick old when it
        // steps every tick, up to its step period old when it steps slower.
        let mut surfaces = session.surfaces(t, period);
        let tick = pipeline.tick(Some(reading), true, &mut surfaces, || {
            clock += 1;
            clock
        });
        session.follow(tick.god.as_ref());
        device
            .write_force(tick.device_force)
            .map_err(|e| anyhow::anyhow!("hand device refused {:?} N: {e}", tick.device_force))?;
        out.push(TickRecord {
            t,
            stylus: sample.position_mm.map(|c| c * 1e-3),
            force: tick.device_force,
            contact: tick.anchor().is_some(),
            local: tick.local,
            grip_work: device.grip_work(),
            tissue_force: session.tissue_force(tick.god.as_ref()),
        });
        let tool = tick.tip.map(|center| RoundInput {
            center,
            heat: sample.pressed(BUTTON_HEAT),
            stiffness: tick.anchor().map(|_| tick.stiffness),
        });
        session.advance(t + period, tool, &[], || {
            clock += 1;
            clock
        });
    }
    device.stop();
    Ok(ClosedLoopRun {
        ticks: out,
        dissipated: pipeline.passivity().dissipated(),
        passivity_ticks: pipeline.passivity().active_ticks(),
        stiffness,
    })
}

/// What `lopd simulate --device hand` writes beside `hand.csv`.
#[derive(Debug, serde::Serialize)]
pub struct HandSummary {
    /// Scene and script names.
    pub scene: String,
    pub script: String,
    /// Simulated seconds and ticks.
    pub seconds: f64,
    pub ticks: usize,
    /// Ticks in contact, and of those rendered through the frames' local model.
    pub contact_ticks: usize,
    pub local_model_ticks: usize,
    /// Largest force on the hand, N.
    pub max_force_n: f64,
    /// The work the hand's grip did on the stylus: lowest over the run (below zero: the
    /// coupling gave back more than it received) and at the end, J.
    pub device_port_min_j: f64,
    pub device_port_end_j: f64,
    /// The same at the rendered environment's port (`Σ −F·Δx`), J.
    pub environment_port_min_j: f64,
    /// The passivity controller: ticks it acted on, energy it dissipated, J.
    pub passivity_ticks: u64,
    pub passivity_dissipated_j: f64,
}

/// `lopd simulate --device hand[:SCRIPT]`: one pass of `script` (its duration) on `scene` with
/// the simulated hand, the Omni's limits and the default daemon settings; writes `hand.csv`
/// and `hand_summary.json` to `out` and prints the summary.
pub fn simulate(scene: Scene, script: MockScript, out: &std::path::Path) -> Result<HandSummary> {
    use std::io::Write as _;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let seconds = script.duration().max(0.001);
    let name = scene.name.clone();
    let script_name = script.name().to_string();
    let r = run(ClosedLoopOptions {
        scene,
        script,
        hand: None,
        limits: lop_drivers::mock::MockDevice::omni_limits(),
        config: DaemonConfig::default(),
        seconds,
    })?;
    let csv_path = out.join("hand.csv");
    let mut csv = std::io::BufWriter::new(
        std::fs::File::create(&csv_path)
            .with_context(|| format!("creating {}", csv_path.display()))?,
    );
    writeln!(csv, "{}", TickRecord::CSV_HEADER)?;
    let mut row = String::new();
    for t in &r.ticks {
        row.clear();
        t.write_csv(&mut row)?;
        writeln!(csv, "{row}")?;
    }
    csv.flush()?;
    let norm = |f: [f64; 3]| (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
    let energy = port_energy(&r.ticks);
    let summary = HandSummary {
        scene: name,
        script: script_name,
        seconds,
        ticks: r.ticks.len(),
        contact_ticks: r.ticks.iter().filter(|t| t.contact).count(),
        local_model_ticks: r.ticks.iter().filter(|t| t.local).count(),
        max_force_n: r.ticks.iter().map(|t| norm(t.force)).fold(0.0, f64::max),
        device_port_min_j: energy.device_min,
        device_port_end_j: energy.device_end,
        environment_port_min_j: energy.environment_min,
        passivity_ticks: r.passivity_ticks,
        passivity_dissipated_j: r.dissipated,
    };
    std::fs::write(
        out.join("hand_summary.json"),
        serde_json::to_string_pretty(&summary)? + "\n",
    )?;
    println!(
        "{} with the simulated hand ({}): {} ticks, {} in contact ({} through the local model), \
         largest force {:.3} N; device port lowest {:.3e} J (end {:.3e} J), environment port \
         lowest {:.3e} J; passivity controller {} ticks\nwrote {}",
        summary.scene,
        summary.script,
        summary.ticks,
        summary.contact_ticks,
        summary.local_model_ticks,
        summary.max_force_n,
        summary.device_port_min_j,
        summary.device_port_end_j,
        summary.environment_port_min_j,
        summary.passivity_ticks,
        out.display()
    );
    Ok(summary)
}

/// The energy through the two ports of a run, J (`+ 0.0` on the minima: no −0 in reports).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PortEnergy {
    /// Into the rendered environment, `Σ −F_{n−1} · (x_n − x_{n−1})` with the force held over
    /// each period (what the passivity controller observes): lowest, highest and at the end.
    pub environment_min: f64,
    pub environment_max: f64,
    pub environment_end: f64,
    /// The work the hand's grip did on the stylus ([`TickRecord::grip_work`]): lowest and
    /// at the end. A passive coupling never takes it below zero.
    pub device_min: f64,
    pub device_end: f64,
}

/// The energy through both ports over `ticks` (from the first tick, where both are zero).
pub fn port_energy(ticks: &[TickRecord]) -> PortEnergy {
    let (mut e, mut lo, mut hi) = (0.0, 0.0f64, 0.0f64);
    for w in ticks.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        e -= (0..3)
            .map(|k| a.force[k] * (b.stylus[k] - a.stylus[k]))
            .sum::<f64>();
        lo = lo.min(e);
        hi = hi.max(e);
    }
    PortEnergy {
        environment_min: lo + 0.0,
        environment_max: hi,
        environment_end: e,
        device_min: ticks.iter().map(|t| t.grip_work).fold(0.0, f64::min) + 0.0,
        device_end: ticks.last().map_or(0.0, |t| t.grip_work),
    }
}
