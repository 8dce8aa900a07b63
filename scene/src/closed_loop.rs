//! The haptic pipeline and the deformation rounds coupled in one process on simulated time,
//! with a simulated hand holding each tool's stylus: what `lopd run --device hand` does,
//! without shared memory or the wall clock, so that a press can be replayed deterministically
//! and the coupling's stability measured (`lopd simulate --device hand[:SCRIPT]`,
//! `lop-bench haptics` parts 3 and 4, and the tests).
//!
//! Each tick `n` at `t = n T` (`T` the scene's haptic period), in the live loop's order:
//!
//! 1. every hand device is read at `t` (each integrates its hand and stylus at 10 kHz under
//!    the force written to it the tick before);
//! 2. every tool's own [`HapticPipeline`], with the live loop's settings for that tool
//!    ([`tool_pipeline_settings`](crate::tool_pipeline_settings)), renders against the world
//!    as its last round left it ([`OfflineSession::tool_surfaces`]: the surfaces, the proxy
//!    resting where the patch balanced, that tool's local model of the patch) — every tool
//!    against the same world;
//! 3. every force is written to its device;
//! 4. the world runs one round to `t + T` with every tool of this tick
//!    ([`OfflineSession::advance_tools`]): tissue pressed by several tools is one contact
//!    patch, each tool with its own spring and its own share of the force.
//!
//! [`run`] is this loop with one tool (the scene's first), [`run_tools`] with a hand on each of
//! the scene's first tools.
//!
//! So a frame is one tick old when the hand feels it if the touched body steps every tick (the
//! live loop's frame age is then 0.5–1.4 ms, `lop-bench latency`). A body that steps at a
//! longer period `P` (its FEM `dt`, as the deformation process chooses it live for an organ
//! whose step costs more than a tick) changes its surface every `P`, and the frame the hand
//! feels ages from one tick to `P` between steps: the local model extrapolates over that age,
//! as live. Everything else that depends on the wall clock live (the step's own duration,
//! scheduling) is absent here.

use anyhow::{ensure, Context, Result};
use lop_config::{DaemonConfig, Scene};
use lop_drivers::hand::{HandDevice, HandParameters};
use lop_drivers::mock::MockScript;
use lop_drivers::{DeviceLimits, DeviceSample, HapticDevice, BUTTON_CUT, BUTTON_GRAB, BUTTON_HEAT};
use lop_sim::haptic::{DeviceReading, HapticPipeline, TickOutput};
use lop_sim::world::MAX_TOOLS;

use crate::session::{OfflineSession, RoundInput, TickRecord};
use crate::{DeviceClamp, ToolLaws};

/// What to run with one tool.
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

/// The hand on one tool and the device it holds.
#[derive(Debug, Clone)]
pub struct ToolHand {
    /// The hand's intent.
    pub script: MockScript,
    /// The hand; `None`: the script's `[hand]` table, else the defaults.
    pub hand: Option<HandParameters>,
    /// The device; its stiffness limit clamps this tool's law as live.
    pub limits: DeviceLimits,
}

/// What to run with several tools.
#[derive(Debug, Clone)]
pub struct ClosedLoopToolsOptions {
    /// The scene (as loaded; callers may change its parameters first).
    pub scene: Scene,
    /// One hand per tool, in the scene's order: `hands[k]` holds tool `k` (at least one, at
    /// most the scene's tools and [`MAX_TOOLS`]; a tool past the last hand has no device and
    /// acts on nothing).
    pub hands: Vec<ToolHand>,
    /// The daemon's settings (the haptic loop's local model, passivity, safety).
    pub config: DaemonConfig,
    /// Simulated seconds.
    pub seconds: f64,
}

/// A run's ticks and the passivity controller's account, for one tool.
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

impl ClosedLoopRun {
    /// The energy through this tool's two ports ([`port_energy`] of its ticks).
    pub fn port_energy(&self) -> PortEnergy {
        port_energy(&self.ticks)
    }
}

/// Runs the closed loop with one tool, the scene's first (see the module docs).
pub fn run(opts: ClosedLoopOptions) -> Result<ClosedLoopRun> {
    let mut runs = run_tools(ClosedLoopToolsOptions {
        scene: opts.scene,
        hands: vec![ToolHand {
            script: opts.script,
            hand: opts.hand,
            limits: opts.limits,
        }],
        config: opts.config,
        seconds: opts.seconds,
    })?;
    Ok(runs.swap_remove(0))
}

/// One tool of the loop: the device its hand holds and the pipeline that renders its force.
struct ToolLoop {
    device: HandDevice,
    pipeline: HapticPipeline,
    /// What this tool's hand felt, tick by tick.
    ticks: Vec<TickRecord>,
    /// The tool stiffness against each body, N/m (the pipeline's settings).
    stiffness: Vec<f64>,
}

/// Runs the closed loop with a hand on each of the scene's first tools (see the module docs);
/// one run per hand, in the scene's order.
///
/// # Errors
/// No hand, more hands than the scene has tools, a hand's parameters refused, the scene not
/// loading, or a device refusing a read or a force (each named by its tool).
pub fn run_tools(opts: ClosedLoopToolsOptions) -> Result<Vec<ClosedLoopRun>> {
    let ClosedLoopToolsOptions {
        scene,
        hands,
        config,
        seconds,
    } = opts;
    ensure!(!hands.is_empty(), "the closed loop needs a hand on a tool");
    ensure!(
        hands.len() <= scene.tools.len().max(1) && hands.len() <= MAX_TOOLS,
        "{} hands for the {} tools of scene {:?} (at most {MAX_TOOLS})",
        hands.len(),
        scene.tools.len(),
        scene.name
    );
    let mut tools = Vec::with_capacity(hands.len());
    let mut laws = Vec::with_capacity(hands.len());
    for (k, h) in hands.into_iter().enumerate() {
        let settings = crate::tool_pipeline_settings(&config, &scene, k, &h.limits);
        laws.push(ToolLaws::of_tool(
            &scene,
            k,
            DeviceClamp {
                max_stiffness_n_per_mm: h.limits.max_stiffness_n_per_mm,
            },
        ));
        let mut device = match h.hand {
            Some(p) => HandDevice::with_parameters(h.script, p, h.limits)
                .with_context(|| format!("tool {k}: hand parameters"))?,
            None => HandDevice::new(h.script, h.limits),
        };
        device
            .start()
            .map_err(|e| anyhow::anyhow!("tool {k}: starting the hand device: {e}"))?;
        tools.push(ToolLoop {
            device,
            stiffness: settings.body_stiffness.clone(),
            pipeline: HapticPipeline::new(settings),
            ticks: Vec::new(),
        });
    }
    let loaded = crate::load(scene)?;
    let mut session = OfflineSession::with_tools(loaded.world, laws);
    // Every tool's pipeline ticks at the scene's haptic rate.
    let period = tools[0].pipeline.settings().period();
    let ticks = (seconds / period).round() as usize;
    for tool in &mut tools {
        tool.ticks.reserve_exact(ticks);
    }
    let mut samples = vec![DeviceSample::default(); tools.len()];
    let mut outputs: Vec<TickOutput> = Vec::with_capacity(tools.len());
    let mut inputs: Vec<Option<RoundInput>> = vec![None; tools.len()];
    // Stage timings on a counter: the run stays deterministic.
    let mut clock = 0u64;
    for n in 0..ticks {
        let t = n as f64 * period;
        // 1. Every hand is read.
        for (k, (tool, sample)) in tools.iter_mut().zip(&mut samples).enumerate() {
            *sample = tool
                .device
                .read(t)
                .map_err(|e| anyhow::anyhow!("tool {k}: hand device at {t} s: {e}"))?;
        }
        // 2. Every pipeline renders against the same world. The frame each hand feels is the
        // touched body's last step: one tick old when it steps every tick, up to its step
        // period old when it steps slower.
        outputs.clear();
        for (k, (tool, sample)) in tools.iter_mut().zip(&samples).enumerate() {
            let reading = DeviceReading {
                position_mm: sample.position_mm,
                velocity_mm_s: sample.velocity_mm_s,
                grab: sample.pressed(BUTTON_GRAB),
            };
            let mut surfaces = session.tool_surfaces(k, t, period);
            let tick = tool.pipeline.tick(Some(reading), true, &mut surfaces, || {
                clock += 1;
                clock
            });
            session.follow_tool(k, tick.god.as_ref());
            outputs.push(tick);
        }
        // 3. Every force is written, and what each hand felt recorded.
        for (k, ((tool, sample), tick)) in tools.iter_mut().zip(&samples).zip(&outputs).enumerate()
        {
            tool.device.write_force(tick.device_force).map_err(|e| {
                anyhow::anyhow!(
                    "tool {k}: hand device refused {:?} N: {e}",
                    tick.device_force
                )
            })?;
            tool.ticks.push(TickRecord {
                t,
                stylus: sample.position_mm.map(|c| c * 1e-3),
                force: tick.device_force,
                contact: tick.anchor().is_some(),
                local: tick.local,
                grip_work: tool.device.grip_work(),
                tissue_force: session.tool_tissue_force(k, tick.god.as_ref()),
            });
        }
        // 4. One round of the world with every tool.
        for (((input, sample), tick), tool) in inputs
            .iter_mut()
            .zip(&samples)
            .zip(&outputs)
            .zip(tools.iter())
        {
            *input = tick.tip.map(|center| RoundInput {
                center,
                heat: tool.pipeline.settings().cauterizes && sample.pressed(BUTTON_HEAT),
                cut: tool.pipeline.settings().cauterizes && sample.pressed(BUTTON_CUT),
                stiffness: tick.anchor().map(|_| tick.stiffness),
            });
        }
        session.advance_tools(t + period, &inputs, &[], || {
            clock += 1;
            clock
        });
    }
    Ok(tools
        .into_iter()
        .map(|mut tool| {
            tool.device.stop();
            ClosedLoopRun {
                ticks: tool.ticks,
                dissipated: tool.pipeline.passivity().dissipated(),
                passivity_ticks: tool.pipeline.passivity().active_ticks(),
                stiffness: tool.stiffness,
            }
        })
        .collect())
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
