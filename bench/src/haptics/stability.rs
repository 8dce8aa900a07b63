//! Part 3 of `lop-bench haptics`: **stability** of the coupling between a hand and the tissue.
//!
//! The closed loop (`lop_scene::closed_loop`: the simulated hand holding the stylus, the
//! haptic loop's god-object, local model, passivity controller and safety, and the
//! deformation rounds, on simulated time) runs a brisk press on the `abdomen` scene's liver:
//! the hand's intent rests 15 mm (device) out, comes to 1 mm off the surface, pushes 5 mm
//! (device; 10 mm in the scene) in 60 ms, holds, and withdraws. The map crosses
//!
//! - the tool stiffness felt at the stylus, up to the device's nominal maximum (the Omni's
//!   0.7 N/mm, 350 N/m in the scene at the workspace's scale 2) and beyond it, where a real
//!   device buzzes (lop clamps the tool law to the maximum; here it is left unclamped to see
//!   where the coupling itself would give way);
//! - the liver's Young's modulus from 1 kPa to 100 kPa;
//! - two hands: the default (an Omni held with a moderate grip, with the stylus' own damping
//!   and friction), and the hard case for stability, a light grip on a stylus with neither;
//! - the passivity controller off and on (on is the shipped default).
//!
//! A second sweep crosses the **frame period**: the liver stepping every 1, 2, 5 and 10 ms (the
//! periods the deformation process picks live for an organ whose step costs more than a tick),
//! the hand feeling each frame as it ages from one tick to the period and the local model
//! extrapolating over that age, at the nominal tissue and the device's maximum stiffness, both
//! hands, the controller off and on. Besides the map's figures it counts the contact changes
//! over the cycle and the largest force step from one tick to the next in contact.
//!
//! Each run reports the held force; the **oscillation** after contact onset (the force's
//! deviation from its 21 ms quadratic trend, [`oscillation`]: its largest, and how long after
//! onset until it stays within 2 % of the held force); the **energy at the device port** (the
//! work the hand's grip did on the stylus: the stylus with its damping and friction plus a
//! passive rendered tissue never gives back more than it got, so its lowest over the cycle is
//! zero; below zero, the coupling generated energy) and at the rendered environment's port
//! (`Σ −F·Δx`, what the passivity controller observes); and the penetration (the tool spring's
//! longest stretch).
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use lop_config::{load_scene, DaemonConfig, Scene};
use lop_drivers::hand::HandParameters;
use lop_drivers::mock::{MockDevice, MockScript};
use lop_scene::closed_loop::{port_energy, run, ClosedLoopOptions};
use lop_scene::session::TickRecord;
use serde::Serialize;

use crate::models::workspace_root;
use crate::plot::{self, Panel, Series};

/// The scene and the body pressed.
const SCENE: &str = "config/scenes/abdomen.toml";
const BODY: &str = "liver";

/// The press, device millimetres: at rest, and at the poke script's contact point on the liver
/// (`config/scripts/abdomen-poke.toml`); the push goes along the script's inward direction.
const REST_MM: [f64; 3] = [-26.14, 9.1, 34.57];
const CONTACT_MM: [f64; 3] = [-26.94, 9.45, 27.12];
const PUSHED_MM: [f64; 3] = [-27.58, 9.71, 21.18];
/// How far the intent stops short of the contact before the push, and how far past it the
/// push goes, device mm.
const APPROACH_MM: f64 = 1.0;
const PUSH_MM: f64 = 4.0;
/// Times of the cycle, s: approach done, push done, hold done, back at rest, end.
const T_APPROACH: f64 = 0.6;
const T_PUSHED: f64 = 0.66;
const T_HOLD_END: f64 = 1.2;
const T_REST: f64 = 1.5;
const T_END: f64 = 1.6;
/// The held force is the mean over this last part of the hold, s.
const HELD_WINDOW: f64 = 0.2;
/// The oscillation target: within this fraction of the held force …
pub const SETTLE_BAND: f64 = 0.02;
/// … within this long after contact onset, s.
pub const SETTLE_LIMIT: f64 = 0.1;

/// Half-width of the window, ticks, over which the force's trend is fitted (see
/// [`oscillation`]): 21 ms.
const TREND_HALF: usize = 10;

/// The force's oscillation: its deviation from its local trend, the least-squares quadratic
/// over the `2 m + 1` ticks around each one (the Savitzky–Golay smoother: at the centre the fit
/// is `Σ c_k F_{i+k}` with `c_k = (3 (3m² + 3m − 1) − 15 k²) / ((2m + 3)(2m + 1)(2m − 1))`).
/// Over 21 ms a quadratic follows what the hand's own motion does to the force (a hand moves
/// below about 10 Hz; a 5 Hz swing is fitted to within 0.5 % of its amplitude), so what is left
/// is ringing and buzz: the stylus in the fingers (about 36 Hz with the default grip) and the
/// sampled coupling's limit cycles (tens to hundreds of hertz). Zero where the window does not
/// fit.
fn oscillation(f: &[f64], m: usize) -> Vec<f64> {
    let mf = m as f64;
    let den = (2.0 * mf + 3.0) * (2.0 * mf + 1.0) * (2.0 * mf - 1.0);
    let c: Vec<f64> = (0..=2 * m)
        .map(|j| {
            let k = j as f64 - mf;
            (3.0 * (3.0 * mf * mf + 3.0 * mf - 1.0) - 15.0 * k * k) / den
        })
        .collect();
    let mut out = vec![0.0; f.len()];
    for i in m..f.len().saturating_sub(m) {
        let trend: f64 = c.iter().zip(&f[i - m..=i + m]).map(|(c, x)| c * x).sum();
        out[i] = f[i] - trend;
    }
    out
}

/// The device's nominal maximum stiffness at the stylus, N/mm (the Omni's, as the mock's).
fn device_max_n_per_mm() -> f64 {
    MockDevice::omni_limits().max_stiffness_n_per_mm
}

/// One run of the map.
#[derive(Debug, Clone, Serialize)]
pub struct StabilityRun {
    pub young_pa: f64,
    /// The liver's step period, ms: how far apart the frames the hand feels are.
    pub period_ms: f64,
    /// The tool spring in the scene, N/m, and as felt at the stylus, N/mm.
    pub tool_n_per_m: f64,
    pub stylus_n_per_mm: f64,
    /// Above the device's nominal maximum (unclamped).
    pub beyond_device: bool,
    pub grip: Grip,
    pub passivity: bool,
    /// Mean force over the end of the hold, N.
    pub held_n: f64,
    /// Contact onset, s.
    pub onset_s: f64,
    /// From onset until the force stays within 2 % of the held force, ms (`None`: never).
    pub settle_ms: Option<f64>,
    /// The oscillation (the force's deviation from its 21 ms quadratic trend, see
    /// [`oscillation`]) after contact onset: its largest, as a fraction of the held force, and
    /// from onset until it stays within 2 % of the held force, ms (`None`: never).
    pub oscillation_max: f64,
    pub oscillation_settle_ms: Option<f64>,
    /// Largest `| |F| − held |` after the intent stopped (hold start + 20 ms), as a fraction
    /// of the held force.
    pub swing: f64,
    /// Lowest running energy into the environment over the cycle, J (a passive coupling: ≥ 0),
    /// the energy at the end of the cycle, and the largest, J.
    pub energy_min_j: f64,
    pub energy_end_j: f64,
    pub energy_max_j: f64,
    /// The work the hand's grip did on the stylus: its lowest over the cycle and at the end, J
    /// (the stylus with its own damping and friction plus a passive environment: ≥ 0).
    pub hand_min_j: f64,
    pub hand_end_j: f64,
    /// Largest stretch of the tool spring, mm (scene).
    pub penetration_mm: f64,
    /// Energy the passivity controller dissipated, J, and on how many ticks it acted.
    pub dissipated_j: f64,
    pub passivity_ticks: u64,
    /// Ticks rendered through the local model, of those in contact.
    pub local_ticks: usize,
    pub contact_ticks: usize,
    /// Times contact was made or lost over the cycle (2 for one clean press).
    pub contact_changes: usize,
    /// Largest change of the force from one tick to the next, both in contact, N.
    pub max_step_n: f64,
}

/// The press script (see the module docs).
fn press_script() -> Result<MockScript> {
    let dir: Vec<f64> = (0..3).map(|k| PUSHED_MM[k] - CONTACT_MM[k]).collect();
    let len = dir.iter().map(|d| d * d).sum::<f64>().sqrt();
    let at = |s: f64| -> [f64; 3] { std::array::from_fn(|k| CONTACT_MM[k] + dir[k] / len * s) };
    let fmt = |p: [f64; 3]| format!("[{:.4}, {:.4}, {:.4}]", p[0], p[1], p[2]);
    let mut text = String::from(
        "name = \"stability press\"\ndescription = \"brisk press, hold, withdraw\"\n\
         end = \"hold\"\ninterpolation = \"smooth\"\n",
    );
    for (t, p) in [
        (0.0, REST_MM),
        (0.2, REST_MM),
        (T_APPROACH, at(-APPROACH_MM)),
        (T_PUSHED, at(PUSH_MM)),
        (T_HOLD_END, at(PUSH_MM)),
        (T_REST, REST_MM),
    ] {
        writeln!(
            text,
            "[[waypoint]]\nt = {t}\nposition = {}\nbuttons = []",
            fmt(p)
        )?;
    }
    MockScript::parse(&text, Path::new("stability-press.toml")).map_err(|e| anyhow::anyhow!("{e}"))
}

/// The scene with the liver's modulus, step period (s) and the tool's stiffness set.
fn scene_with(base: &Scene, young: f64, tool: f64, period: f64) -> Result<Scene> {
    let mut scene = base.clone();
    scene.tools[0].stiffness = tool;
    let body = scene
        .bodies
        .iter_mut()
        .find(|b| b.name == BODY)
        .with_context(|| format!("no body {BODY:?} in {SCENE}"))?;
    body.tool_stiffness = Some(tool);
    if let Some(fem) = &mut body.fem {
        fem.young = young;
        fem.dt = period;
    }
    Ok(scene)
}

/// The hand holding the stylus.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Grip {
    /// The simulated hand's defaults: an Omni held with a moderate grip, the stylus with its
    /// own damping (0.2 N·s/m) and friction (0.1 N).
    Firm,
    /// The hard case for stability: a light grip (arm 100 N/m and 1 N·s/m, fingers 500 N/m
    /// and 0.3 N·s/m) on a stylus without damping or friction, so nothing but the rendered
    /// force decides whether the stylus rings.
    Light,
}

impl Grip {
    /// The hand's parameters.
    pub(crate) fn parameters(self) -> HandParameters {
        match self {
            Grip::Firm => HandParameters::default(),
            Grip::Light => HandParameters::light_grip(),
        }
    }

    /// Its name in tables.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Grip::Firm => "firm grip",
            Grip::Light => "light grip, bare stylus",
        }
    }
}

/// One run of the closed loop, measured.
fn run_case(
    base: &Scene,
    script: &MockScript,
    grip: Grip,
    young: f64,
    tool: f64,
    passivity: bool,
    period: f64,
) -> Result<(StabilityRun, Vec<TickRecord>)> {
    let scene = scene_with(base, young, tool, period)?;
    let scale = scene.tool().workspace.scale;
    let stylus_n_per_mm = tool * 1e-3 * scale;
    let beyond_device = stylus_n_per_mm > device_max_n_per_mm() * (1.0 + 1e-9);
    let mut limits = MockDevice::omni_limits();
    limits.max_stiffness_n_per_mm = f64::INFINITY;
    let mut config = DaemonConfig::default();
    if !passivity {
        config.haptic.passivity_max_damping = 0.0;
    }
    let r = run(ClosedLoopOptions {
        scene,
        script: script.clone(),
        hand: Some(grip.parameters()),
        limits,
        config,
        seconds: T_END,
    })?;
    let ticks = r.ticks;
    let norm = |f: [f64; 3]| (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
    let held_n = mean_force(&ticks, T_HOLD_END - HELD_WINDOW, T_HOLD_END);
    let onset = ticks.iter().position(|t| t.contact && t.t > 0.2);
    let onset_s = onset.map_or(f64::NAN, |i| ticks[i].t);
    let in_hold = |t: &TickRecord| t.t >= onset_s && t.t < T_HOLD_END;
    let magnitudes: Vec<f64> = ticks.iter().map(|t| norm(t.force)).collect();
    let osc = oscillation(&magnitudes, TREND_HALF);
    let osc_max = ticks
        .iter()
        .zip(&osc)
        .filter(|(t, _)| in_hold(t))
        .map(|(_, o)| o.abs())
        .fold(0.0, f64::max)
        / held_n.max(1e-12);
    let osc_last = ticks
        .iter()
        .zip(&osc)
        .filter(|(t, o)| in_hold(t) && o.abs() > SETTLE_BAND * held_n)
        .map(|(t, _)| t.t)
        .fold(f64::NAN, f64::max);
    let osc_settle_ms = if onset.is_none() || !(held_n > 0.0) {
        None
    } else if osc_last.is_nan() {
        Some(0.0)
    } else if osc_last >= T_HOLD_END - 2e-3 - TREND_HALF as f64 * 1e-3 {
        None
    } else {
        Some((osc_last + 1e-3 - onset_s) * 1e3)
    };
    let last_out = ticks
        .iter()
        .filter(|t| in_hold(t) && (norm(t.force) - held_n).abs() > SETTLE_BAND * held_n)
        .map(|t| t.t)
        .fold(f64::NAN, f64::max);
    let settle_ms = if onset.is_none() || !(held_n > 0.0) {
        None
    } else if last_out.is_nan() {
        Some(0.0)
    } else if last_out >= T_HOLD_END - 2e-3 {
        None
    } else {
        Some((last_out + 1e-3 - onset_s) * 1e3)
    };
    let swing = ticks
        .iter()
        .filter(|t| t.t >= T_PUSHED + 0.02 && t.t < T_HOLD_END)
        .map(|t| (norm(t.force) - held_n).abs())
        .fold(0.0, f64::max)
        / held_n.max(1e-12);
    let energy = port_energy(&ticks);
    let k_scene = r.stiffness.first().copied().unwrap_or(tool).max(1e-12);
    let penetration_mm = ticks.iter().map(|t| norm(t.force)).fold(0.0, f64::max) / k_scene * 1e3;
    let contact_changes = contact_changes(&ticks);
    let max_step_n = ticks
        .windows(2)
        .filter(|w| w[0].contact && w[1].contact)
        .map(|w| norm([0, 1, 2].map(|k| w[1].force[k] - w[0].force[k])))
        .fold(0.0, f64::max);
    let run = StabilityRun {
        young_pa: young,
        period_ms: period * 1e3,
        tool_n_per_m: tool,
        stylus_n_per_mm,
        beyond_device,
        grip,
        passivity,
        held_n,
        onset_s,
        settle_ms,
        oscillation_max: osc_max,
        oscillation_settle_ms: osc_settle_ms,
        swing,
        energy_min_j: energy.environment_min,
        energy_end_j: energy.environment_end,
        energy_max_j: energy.environment_max,
        hand_min_j: energy.device_min,
        hand_end_j: energy.device_end,
        penetration_mm,
        dissipated_j: r.dissipated,
        passivity_ticks: r.passivity_ticks,
        local_ticks: ticks.iter().filter(|t| t.local).count(),
        contact_ticks: ticks.iter().filter(|t| t.contact).count(),
        contact_changes,
        max_step_n,
    };
    Ok((run, ticks))
}

/// The mean magnitude of the force over the ticks in `[from, to)` s, N (0 without ticks).
pub(crate) fn mean_force(ticks: &[TickRecord], from: f64, to: f64) -> f64 {
    let held: Vec<f64> = ticks
        .iter()
        .filter(|t| t.t >= from && t.t < to)
        .map(|t| t.force.iter().map(|f| f * f).sum::<f64>().sqrt())
        .collect();
    held.iter().sum::<f64>() / held.len().max(1) as f64
}

/// Times contact was made or lost over `ticks`.
pub(crate) fn contact_changes(ticks: &[TickRecord]) -> usize {
    ticks
        .windows(2)
        .filter(|w| w[0].contact != w[1].contact)
        .count()
}

/// A pass/fail target.
#[derive(Debug, Serialize)]
pub struct StabilityTarget {
    pub name: String,
    pub value: f64,
    pub limit: f64,
    pub pass: bool,
}

/// What the passivity controller did where the coupling generated energy: per hand, the
/// energy generated at the device port without it and with it, summed over those runs, J.
#[derive(Debug, Serialize)]
pub struct ControllerEffect {
    pub grip: Grip,
    pub runs: usize,
    pub generated_off_j: f64,
    pub generated_on_j: f64,
}

/// Everything part 3 measured, for `--json`.
#[derive(Debug, Serialize)]
pub struct StabilityReport {
    pub runs: Vec<StabilityRun>,
    /// The frame-period sweep.
    pub periods: Vec<StabilityRun>,
    pub controller: Vec<ControllerEffect>,
    pub targets: Vec<StabilityTarget>,
    pub seconds: f64,
}

/// Energy below this counts as none, J: the port integrals are exact sums of the run's own
/// numbers (forces and positions), so only rounding is left — 1 nJ against the 2–3 mJ a
/// press moves.
pub const ENERGY_TOLERANCE: f64 = 1e-9;

/// The energy a run generated at the device port, J (zero when passive).
fn generated(r: &StabilityRun) -> f64 {
    // `+ 0.0` turns a −0 into 0 for printing.
    (-r.hand_min_j).max(0.0) + 0.0
}

/// Runs the map (`quick`: the firm grip on the nominal and the stiffest tissue, at the
/// device's maximum and four times it).
pub fn run_map(quick: bool, out: &Path) -> Result<StabilityReport> {
    let clock = Instant::now();
    let root = workspace_root();
    let base = load_scene(&root.join(SCENE)).map_err(|e| anyhow::anyhow!("{e}"))?;
    let nominal_young = base
        .bodies
        .iter()
        .find(|b| b.name == BODY)
        .and_then(|b| b.fem.as_ref())
        .map(|f| f.young)
        .with_context(|| format!("{SCENE}: no FEM {BODY}"))?;
    let nominal_period = base
        .bodies
        .iter()
        .find(|b| b.name == BODY)
        .and_then(|b| b.fem.as_ref())
        .map_or(1e-3, |f| f.dt);
    let script = press_script()?;
    let max_scene = device_max_n_per_mm() / (1e-3 * base.tool().workspace.scale);
    let (grips, youngs, factors): (&[Grip], Vec<f64>, &[f64]) = if quick {
        (&[Grip::Firm], vec![nominal_young, 1e5], &[1.0, 4.0])
    } else {
        (
            &[Grip::Firm, Grip::Light],
            vec![1e3, nominal_young, 1e4, 3e4, 1e5],
            &[0.25, 0.5, 1.0, 2.0, 4.0],
        )
    };
    println!(
        "\nPart 3: stability: the simulated hand presses the liver (brisk 5 mm push, hold, \
         withdraw), closed loop at 1 kHz"
    );
    println!(
        "{:<24} {:>7} {:>12} {:>3} {:>8} {:>8} {:>9} {:>11} {:>11} {:>8} {:>6}",
        "hand",
        "E kPa",
        "k N/mm",
        "PC",
        "held N",
        "osc %",
        "osc ms",
        "device uJ",
        "env uJ",
        "pen mm",
        "PC tk"
    );
    let mut runs = Vec::new();
    let mut nominal_trace = Vec::new();
    let mut csv = format!(
        "grip,young_pa,stylus_n_per_mm,passivity,{}\n",
        TickRecord::CSV_HEADER
    );
    for &grip in grips {
        for &young in &youngs {
            for &factor in factors {
                let tool = factor * max_scene;
                for passivity in [false, true] {
                    let (r, ticks) =
                        run_case(&base, &script, grip, young, tool, passivity, nominal_period)?;
                    println!(
                        "{:<24} {:>7.1} {:>12} {:>3} {:>8.3} {:>8.1} {:>9} {:>11.3} {:>11.3} {:>8.2} {:>6}",
                        grip.name(),
                        young * 1e-3,
                        format!(
                            "{:.3}{}",
                            r.stylus_n_per_mm,
                            if r.beyond_device { " (>)" } else { "" }
                        ),
                        if passivity { "on" } else { "off" },
                        r.held_n,
                        100.0 * r.oscillation_max,
                        r.oscillation_settle_ms
                            .map_or("never".to_string(), |s| format!("{s:.0}")),
                        generated(&r) * 1e6,
                        ((-r.energy_min_j).max(0.0) + 0.0) * 1e6,
                        r.penetration_mm,
                        r.passivity_ticks,
                    );
                    for t in &ticks {
                        write!(
                            csv,
                            "{grip:?},{young},{:.4},{},",
                            r.stylus_n_per_mm,
                            u8::from(passivity)
                        )?;
                        t.write_csv(&mut csv)?;
                        csv.push('\n');
                    }
                    if grip == Grip::Firm && young == nominal_young && factor == 1.0 && passivity {
                        nominal_trace = ticks;
                    }
                    runs.push(r);
                }
            }
        }
    }
    std::fs::write(out.join("stability.csv"), csv)?;
    let periods = period_sweep(&base, &script, grips, nominal_young, max_scene, quick)?;

    // The controller where the coupling generated energy without it.
    let mut controller = Vec::new();
    for &grip in grips {
        let pairs: Vec<(&StabilityRun, &StabilityRun)> = runs
            .chunks_exact(2)
            .filter(|p| p[0].grip == grip && generated(&p[0]) > ENERGY_TOLERANCE)
            .map(|p| (&p[0], &p[1]))
            .collect();
        controller.push(ControllerEffect {
            grip,
            runs: pairs.len(),
            generated_off_j: pairs.iter().map(|p| generated(p.0)).sum(),
            generated_on_j: pairs.iter().map(|p| generated(p.1)).sum(),
        });
    }

    // Targets.
    let nominal = runs
        .iter()
        .find(|r| {
            r.grip == Grip::Firm
                && r.young_pa == nominal_young
                && r.passivity
                && (r.stylus_n_per_mm - device_max_n_per_mm()).abs() < 1e-9
        })
        .context("the nominal run")?;
    let in_range: Vec<&StabilityRun> = runs
        .iter()
        .filter(|r| r.grip == Grip::Firm && r.passivity && !r.beyond_device)
        .collect();
    let worst_in_range = in_range.iter().map(|r| generated(r)).fold(0.0, f64::max);
    let settle = nominal
        .oscillation_settle_ms
        .map_or(f64::INFINITY, |s| s * 1e-3);
    let targets = vec![
        StabilityTarget {
            name: format!(
                "default scene, {:.2} N/mm: oscillation within {:.0} % of the held force after (s)",
                device_max_n_per_mm(),
                100.0 * SETTLE_BAND
            ),
            value: settle,
            limit: SETTLE_LIMIT,
            pass: settle <= SETTLE_LIMIT,
        },
        StabilityTarget {
            name: format!(
                "default scene, {:.2} N/mm: energy generated over the cycle (J)",
                device_max_n_per_mm()
            ),
            value: generated(nominal).max(-nominal.energy_min_j),
            limit: ENERGY_TOLERANCE,
            pass: generated(nominal) <= ENERGY_TOLERANCE
                && -nominal.energy_min_j <= ENERGY_TOLERANCE,
        },
        StabilityTarget {
            name: format!(
                "firm grip, {} runs up to the device's maximum: most energy generated (J)",
                in_range.len()
            ),
            value: worst_in_range,
            limit: ENERGY_TOLERANCE,
            pass: worst_in_range <= ENERGY_TOLERANCE,
        },
        {
            let on: Vec<&StabilityRun> = periods.iter().filter(|r| r.passivity).collect();
            let worst = on.iter().map(|r| generated(r)).fold(0.0, f64::max);
            StabilityTarget {
                name: format!(
                    "frame periods {}: {} runs, controller on: most energy generated (J)",
                    period_list(&periods),
                    on.len()
                ),
                value: worst,
                limit: ENERGY_TOLERANCE,
                pass: worst <= ENERGY_TOLERANCE,
            }
        },
    ];
    println!(
        "\n(device uJ: the energy the hand got back beyond what it put in, at the device port; \
         env uJ: the same at the rendered environment's port; (>): beyond the device's nominal \
         maximum, unclamped)"
    );
    for c in &controller {
        println!(
            "passivity controller, {}: {} runs generated energy without it, {:.2} uJ in all; with it {:.2} uJ ({:.0} % removed)",
            c.grip.name(),
            c.runs,
            c.generated_off_j * 1e6,
            c.generated_on_j * 1e6,
            if c.generated_off_j > 0.0 {
                100.0 * (1.0 - c.generated_on_j / c.generated_off_j)
            } else {
                0.0
            }
        );
    }
    println!("\nTargets (stability)");
    for t in &targets {
        println!(
            "  {:<4} {:<86} {:>10.3e} (limit {:.0e})",
            if t.pass { "PASS" } else { "FAIL" },
            t.name,
            t.value,
            t.limit
        );
    }
    plot(out, &runs, &nominal_trace, grips, &youngs)?;
    Ok(StabilityReport {
        runs,
        periods,
        controller,
        targets,
        seconds: clock.elapsed().as_secs_f64(),
    })
}

/// The frame periods of the sweep, ms (the quick run: the shortest and the longest).
fn sweep_periods(quick: bool) -> &'static [f64] {
    if quick {
        &[1.0, 10.0]
    } else {
        &[1.0, 2.0, 5.0, 10.0]
    }
}

/// "1, 2, 5, 10 ms": the periods a sweep ran.
fn period_list(runs: &[StabilityRun]) -> String {
    let mut ms: Vec<f64> = runs.iter().map(|r| r.period_ms).collect();
    ms.sort_by(f64::total_cmp);
    ms.dedup();
    let list: Vec<String> = ms.iter().map(|p| format!("{p}")).collect();
    format!("{} ms", list.join(", "))
}

/// The frame-period sweep (module docs): nominal tissue, the device's maximum stiffness.
fn period_sweep(
    base: &Scene,
    script: &MockScript,
    grips: &[Grip],
    young: f64,
    tool: f64,
    quick: bool,
) -> Result<Vec<StabilityRun>> {
    println!(
        "\nPart 3b: the same press with the liver stepping every 1 to 10 ms (frames that far \
         apart, the local model extrapolating over their age), {:.1} kPa, {:.3} N/mm",
        young * 1e-3,
        tool * 1e-3 * base.tool().workspace.scale
    );
    println!(
        "{:<24} {:>9} {:>3} {:>8} {:>8} {:>9} {:>11} {:>11} {:>8} {:>10}",
        "hand",
        "period ms",
        "PC",
        "held N",
        "osc %",
        "osc ms",
        "device uJ",
        "env uJ",
        "contacts",
        "max step N"
    );
    let mut runs = Vec::new();
    for &grip in grips {
        for &period_ms in sweep_periods(quick) {
            for passivity in [false, true] {
                let (r, _) =
                    run_case(base, script, grip, young, tool, passivity, period_ms * 1e-3)?;
                println!(
                    "{:<24} {:>9} {:>3} {:>8.3} {:>8.1} {:>9} {:>11.3} {:>11.3} {:>8} {:>10.4}",
                    grip.name(),
                    period_ms,
                    if passivity { "on" } else { "off" },
                    r.held_n,
                    100.0 * r.oscillation_max,
                    r.oscillation_settle_ms
                        .map_or("never".to_string(), |s| format!("{s:.0}")),
                    generated(&r) * 1e6,
                    ((-r.energy_min_j).max(0.0) + 0.0) * 1e6,
                    r.contact_changes,
                    r.max_step_n,
                );
                runs.push(r);
            }
        }
    }
    Ok(runs)
}

/// `stability.svg`: the oscillation's settling time and the energy generated at the device
/// port over the map, and the nominal run's force.
fn plot(
    out: &Path,
    runs: &[StabilityRun],
    nominal: &[TickRecord],
    grips: &[Grip],
    youngs: &[f64],
) -> Result<()> {
    let x_max = runs.iter().map(|r| r.stylus_n_per_mm).fold(0.0, f64::max) * 1.05;
    let mut panels = Vec::new();
    for &grip in grips {
        for passivity in [false, true] {
            let pick = |f: &dyn Fn(&StabilityRun) -> f64| -> Vec<Series> {
                youngs
                    .iter()
                    .enumerate()
                    .map(|(i, &e)| Series {
                        label: format!("E {} kPa", e * 1e-3),
                        points: runs
                            .iter()
                            .filter(|r| {
                                r.grip == grip && r.passivity == passivity && r.young_pa == e
                            })
                            .map(|r| (r.stylus_n_per_mm, f(r)))
                            .collect(),
                        color: i,
                    })
                    .collect()
            };
            let pc = if passivity { "on" } else { "off" };
            let energy = pick(&|r| generated(r) * 1e6);
            let e_max = energy
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.1))
                .fold(0.0, f64::max)
                .max(1.0)
                * 1.6;
            panels.push(Panel {
                title: format!(
                    "{}, passivity controller {pc}: energy generated",
                    grip.name()
                ),
                x_desc: "tool stiffness at the stylus, N/mm".into(),
                y_desc: "energy at the device port, uJ".into(),
                x_range: (0.0, x_max),
                y_range: (0.0, e_max),
                series: energy,
            });
            let settle = pick(&|r| r.oscillation_settle_ms.unwrap_or(1e3));
            panels.push(Panel {
                title: format!(
                    "{}, passivity controller {pc}: oscillation within 2 % after",
                    grip.name()
                ),
                x_desc: "tool stiffness at the stylus, N/mm".into(),
                y_desc: "ms after contact onset (never: off the chart)".into(),
                x_range: (0.0, x_max),
                y_range: (0.0, 600.0),
                series: settle,
            });
        }
    }
    let force: Vec<(f64, f64)> = nominal
        .iter()
        .map(|t| {
            let f = t.force;
            (t.t, (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt())
        })
        .collect();
    let f_max = force.iter().map(|p| p.1).fold(0.0, f64::max).max(1e-3) * 1.5;
    panels.push(Panel {
        title: "default scene at the device's maximum, firm grip: force on the hand".into(),
        x_desc: "time, s".into(),
        y_desc: "force, N".into(),
        x_range: (0.0, T_END),
        y_range: (0.0, f_max),
        series: vec![Series {
            label: "|F|".into(),
            points: force,
            color: 1,
        }],
    });
    plot::line_grid(
        &out.join("stability.svg"),
        "Stability of the coupling: the simulated hand presses the liver",
        &panels,
        2,
        (560, 360),
    )
}
