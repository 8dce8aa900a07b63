//! The haptic loop and the deformation rounds coupled in one process on simulated time, with
//! the simulated hand holding the stylus: what `lopd run --device hand` does, without shared
//! memory or the wall clock, so that a press can be replayed deterministically and the
//! coupling's stability measured (`lopd simulate --device hand[:SCRIPT]`, `lop-bench haptics`
//! part 3, and the tests).
//!
//! Each tick `n` at `t = n T` (`T` the scene's haptic period), in the live loop's order:
//!
//! 1. the hand device is read at `t` (it integrates the hand and the stylus at 10 kHz under the
//!    force written the tick before);
//! 2. the god-object moves against the world as its last round left it (`WorldProbe`: the
//!    surfaces, and the proxy resting where the patch balanced);
//! 3. the force on the hand is the frame's local model when it has one, the force law on the
//!    god-object's gap otherwise ([`lop_sim::haptic::contact_force`]), then the passivity
//!    controller at the device port and the loop's safety (clamp, rate limit: [`ForceSafety`]),
//!    all as [`crate::haptic`] does with the same settings ([`HapticSettings`]);
//! 4. the force is written to the device;
//! 5. the world runs its round to `t + T` with this tick's tool ([`Rounds::offline`]).
//!
//! So a frame is one tick old when the hand feels it, and the local model extrapolates over
//! that tick: the live loop's frame age is 0.5–1.4 ms (`lop-bench latency`). Everything that
//! depends on the wall clock live (the deformation's lag, scheduling) is absent here.

use anyhow::{Context, Result};
use lop_config::{DaemonConfig, Scene};
use lop_drivers::hand::{HandDevice, HandParameters};
use lop_drivers::mock::MockScript;
use lop_drivers::{DeviceLimits, HapticDevice, BUTTON_GRAB, BUTTON_HEAT};
use lop_scene::{DeviceClamp, ToolLaws};
use lop_sim::haptic::{contact_force, PassivityController, WorldProbe};

use crate::haptic::HapticSettings;
use crate::rounds::{Rounds, TickTool};
use crate::safety::ForceSafety;

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

/// One tick of the run, in the device's frame (metres, newtons).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosedLoopTick {
    /// Simulated time, s.
    pub t: f64,
    /// The stylus tip, device frame, m.
    pub stylus: [f64; 3],
    /// The force rendered on the hand this tick, device frame, N.
    pub force: [f64; 3],
    /// The god-object touched a body.
    pub contact: bool,
    /// The force came from the frame's local model.
    pub local: bool,
    /// The work the hand's grip has done on the stylus since the start, J
    /// ([`HandDevice::grip_work`]).
    pub grip_work: f64,
    /// The force's magnitude on the tissue the step balanced (the touched body's last
    /// contact report), N.
    pub tissue_force: f64,
}

/// A run's ticks and the passivity controller's account.
#[derive(Debug, Clone)]
pub struct ClosedLoopRun {
    /// Every tick.
    pub ticks: Vec<ClosedLoopTick>,
    /// Energy the passivity controller dissipated, J.
    pub dissipated: f64,
    /// Ticks on which it acted.
    pub passivity_ticks: u64,
    /// The tool stiffness felt against each body (scene N/m, after the device's clamp).
    pub stiffness: Vec<f64>,
}

/// Runs the closed loop (see the module docs).
pub fn run(opts: ClosedLoopOptions) -> Result<ClosedLoopRun> {
    let settings = HapticSettings::new(&opts.config, &opts.scene, opts.limits);
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
    let loaded = lop_scene::load(opts.scene.clone())?;
    let mut world = loaded.world;
    let mut probe = WorldProbe::new(&world, settings.tool.radius);
    let mut rounds = Rounds::offline(laws);
    let mut safety = ForceSafety::new(settings.max_force, settings.max_step, settings.ramp_ticks)
        .with_continuous(
            settings.limits.max_continuous_force_n,
            (2.0 * settings.rate_hz) as u32,
        );
    let mut passivity = PassivityController::new(settings.passivity_max_damping);
    let period = 1.0 / settings.rate_hz;
    let ticks = (opts.seconds / period).round() as usize;
    let skip = vec![false; world.bodies.len()];
    let ws = settings.workspace;
    let scale = ws.scale;
    let mut out = Vec::with_capacity(ticks);
    // The coupling the world's last round ran with (its contact report belongs to it).
    let mut stepped_with = probe.coupling();
    for n in 0..ticks {
        let t = n as f64 * period;
        let sample = device
            .read(t)
            .map_err(|e| anyhow::anyhow!("hand device at {t} s: {e}"))?;
        let p = ws.device_to_scene(sample.position_mm);
        let g = probe.tick(&world, p, sample.pressed(BUTTON_GRAB));
        let mut desired = [0.0; 3];
        let mut local_used = false;
        let mut k = settings.tool.stiffness;
        if let Some(a) = g.anchor {
            k = settings
                .body_stiffness
                .get(a.body)
                .copied()
                .unwrap_or(settings.tool.stiffness);
            let local = world
                .contact_local(stepped_with)
                .filter(|_| settings.local_model);
            let vel = ws
                .device_dir_to_scene(sample.velocity_mm_s)
                .map(|c| c * 1e-3 * scale);
            let (f, used) = contact_force(
                &g,
                local.as_ref().map(|(b, m)| (*b, m)),
                period,
                p,
                settings.tool.law,
                k,
                settings.damping,
                vel,
            );
            desired = f;
            local_used = used;
        }
        desired = passivity.condition(p.map(|c| c / scale), desired, period);
        let force = safety.condition_moving(desired, true, Some(p), k.max(settings.tool.stiffness));
        passivity.rendered(force);
        let device_force = ws.scene_dir_to_device(force);
        device
            .write_force(device_force)
            .map_err(|e| anyhow::anyhow!("hand device refused {device_force:?} N: {e}"))?;
        let tissue_force = g
            .anchor
            .and_then(|a| world.bodies.get(a.body))
            .map_or(0.0, |b| {
                let f = b.last_contact.force_on_tissue;
                (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt()
            });
        out.push(ClosedLoopTick {
            t,
            stylus: sample.position_mm.map(|c| c * 1e-3),
            force: device_force,
            contact: g.anchor.is_some(),
            local: local_used,
            grip_work: device.grip_work(),
            tissue_force,
        });
        stepped_with = probe.coupling();
        let tool = TickTool {
            center: p,
            coupling: stepped_with,
            heat: sample.pressed(BUTTON_HEAT),
            stiffness: g.anchor.map(|_| k),
        };
        let mut clock = 0u64;
        rounds.advance(&mut world, t + period, Some(&tool), &skip, false, || {
            clock += 1;
            clock
        });
    }
    device.stop();
    Ok(ClosedLoopRun {
        ticks: out,
        dissipated: passivity.dissipated(),
        passivity_ticks: passivity.active_ticks(),
        stiffness: settings.body_stiffness.clone(),
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
    writeln!(
        csv,
        "t_s,fx_n,fy_n,fz_n,x_mm,y_mm,z_mm,contact,local_model,grip_work_j,tissue_force_n"
    )?;
    for t in &r.ticks {
        let [fx, fy, fz] = t.force;
        let [x, y, z] = t.stylus.map(|c| c * 1e3);
        writeln!(
            csv,
            "{:.4},{fx:.6e},{fy:.6e},{fz:.6e},{x:.6},{y:.6},{z:.6},{},{},{:.6e},{:.6e}",
            t.t,
            u8::from(t.contact),
            u8::from(t.local),
            t.grip_work,
            t.tissue_force
        )?;
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
    /// The work the hand's grip did on the stylus ([`ClosedLoopTick::grip_work`]): lowest and
    /// at the end. A passive coupling never takes it below zero.
    pub device_min: f64,
    pub device_end: f64,
}

/// The energy through both ports over `ticks` (from the first tick, where both are zero).
pub fn port_energy(ticks: &[ClosedLoopTick]) -> PortEnergy {
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
