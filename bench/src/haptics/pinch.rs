//! Part 4 of `lop-bench haptics`: a **bimanual pinch** through the closed loop with two
//! simulated hands.
//!
//! A free 20 mm cube of soft tissue (corotational FEM on 2.5 mm cells, E 20 kPa, ν 0.45,
//! 1050 kg/m³, α 30 /s as the `abdomen` scene's organs, a step every tick; nothing holding it,
//! no gravity) is squeezed between two tools (R 3 mm, 300 N/m) from −x and +x, each held by its
//! own simulated hand on its own device (the mock Omni's limits; a workspace of scale 1 per
//! tool, the two devices' origins 25 mm either side of the cube's centre). The scene (two
//! `[[tool]]` tables) and the cube's mesh are written to the output folder and loaded as `lopd`
//! loads a scene; `lop_scene::closed_loop::run_tools` runs both hands, both haptic pipelines
//! and the world's rounds on simulated time: every hand read, every pipeline rendered against
//! the same world, every hand written, then one round with both tools (one contact patch per
//! body, each tool with its own share).
//!
//! Each hand's intent rests 12 mm off its face, comes to 1 mm off it, pushes 5 mm past the
//! surface in 100 ms, holds for 600 ms and withdraws in 300 ms. The runs cross the two hands:
//! both the firm grip, both the light grip on a bare stylus, and one of each (the body, free,
//! moves until the two hands' pushes balance). For comparison, each hand also presses alone
//! against the cube with its far face clamped (the same loop with one tool): what a hand's
//! port does without a second tool.
//!
//! Per hand: the **held force** (the mean magnitude on the hand over the last 300 ms of the
//! hold), the force its tool gave the tissue, and the **energy at its device port** (the work
//! its grip did on the stylus: a passive coupling never takes it below zero, so its lowest over
//! the cycle is the energy the coupling generated) and at the rendered environment's port. Per
//! run: the **balance** over the same window, `|F_left + F_right|` over the mean of the two
//! magnitudes, tick by tick. Nothing but the two tools acts on the free cube, so once it has
//! settled the tissue's two forces are equal and opposite (its momentum balance), and each
//! hand feels what its tool gave the tissue one tick earlier (the multirate delay: nothing
//! while the hold is still).
//!
//! Passivity: energy one hand pushes into the cube may leave through the other tool, so it is
//! the two ports together that a passive environment bounds, not each alone (in the pinch of a
//! light and a firm hand, the firm one's environment port gives back more than it took while
//! the two together never fall below zero). Both are reported. As the tools withdraw the tissue
//! follows them and a sampled contact would give back a little more than it took; the firm
//! grip's stylus damping would absorb it, a light grip on a bare stylus has none: the passivity
//! controller keeps each tool's account from being overdrawn
//! (`lop_sim::haptic::PassivityController`, which predicts the coming period).
//!
//! Targets: every hand in contact through the measured hold; the balance within
//! [`BALANCE_LIMIT`]; no energy generated at the device port of any hand, firm grip or light
//! (the stability map's [`ENERGY_TOLERANCE`], as its target for the default hand).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use lop_config::{load_scene, DaemonConfig, Scene};
use lop_drivers::mock::{MockDevice, MockScript};
use lop_scene::closed_loop::{run_tools, ClosedLoopRun, ClosedLoopToolsOptions, ToolHand};
use lop_scene::session::TickRecord;
use lop_sim::fem::box_mesh;
use lop_sim::mesh::write_vtk;
use serde::Serialize;

use super::stability::{contact_changes, mean_force, Grip, StabilityTarget, ENERGY_TOLERANCE};
use crate::plot::{self, Panel, Series};

/// The cube's edge, m, and its cells per edge (1 cube = 6 tetrahedra; 8: 729 nodes, 3,072
/// tetrahedra, 2.5 mm cells, finer than the tool).
const EDGE: f64 = 0.020;
const CELLS: usize = 8;
/// The tissue: Young's modulus, Pa; Poisson's ratio; density, kg/m³; mass-proportional
/// damping, 1/s (it also drags the free body's motion, as a surrounding fluid would, but holds
/// nothing still); the step, s: every haptic tick.
const YOUNG: f64 = 2e4;
const POISSON: f64 = 0.45;
const DENSITY: f64 = 1050.0;
const DAMPING: f64 = 30.0;
const STEP: f64 = 1e-3;
/// Both tools: radius, m; linear spring, N/m (0.3 N/mm at the stylus at scale 1).
const RADIUS: f64 = 0.003;
const STIFFNESS: f64 = 300.0;
/// Where each device's origin lands along x, m: the cube's centre ± this.
const DEVICE_ORIGIN: f64 = 0.025;
/// The intent along its press, device mm from the contact (the sphere touching the face): at
/// rest, before the push, and pushed.
const REST_MM: f64 = -12.0;
const APPROACH_MM: f64 = -1.0;
const PUSH_MM: f64 = 5.0;
/// Times of the cycle, s: approach done, push done, hold done, back at rest, end.
const T_APPROACH: f64 = 0.5;
const T_PUSHED: f64 = 0.6;
const T_HOLD_END: f64 = 1.2;
const T_REST: f64 = 1.5;
const T_END: f64 = 1.6;
/// The hold is measured over its last this long, s.
const HELD_WINDOW: f64 = 0.3;
/// The balance target: `|F_left + F_right|` within this fraction of the force, tick by tick
/// over the measured hold.
pub const BALANCE_LIMIT: f64 = 0.01;

/// One hand of a pinch (or alone against the clamped cube).
#[derive(Debug, Clone, Serialize)]
pub struct PinchHand {
    /// `"left"` (presses along +x) or `"right"` (along −x).
    pub side: String,
    pub grip: Grip,
    /// Mean magnitude of the force on the hand over the measured hold, N.
    pub held_n: f64,
    /// Mean magnitude of the force its tool gave the tissue over the measured hold, N.
    pub tissue_n: f64,
    /// The stylus' mean position along the press over the measured hold, mm past where the
    /// tool first touches the undeformed cube.
    pub stylus_mm: f64,
    /// Ticks in contact over the measured hold (all of them when the hand holds), and times
    /// contact was made or lost over the cycle (2 for one clean press; more where the tissue
    /// follows the withdrawing tool and touches it again).
    pub hold_contact_ticks: usize,
    pub contact_changes: usize,
    /// The work the grip did on the stylus: at the end of the cycle (what the hand put in),
    /// and the energy the coupling generated at the device port (how far below zero it fell;
    /// 0 when passive), J.
    pub device_end_j: f64,
    pub device_generated_j: f64,
    /// The same at the rendered environment's port (`Σ −F·Δx`): generated, J.
    pub environment_generated_j: f64,
    /// The passivity controller: ticks it acted on, energy it dissipated, J.
    pub passivity_ticks: u64,
    pub dissipated_j: f64,
}

/// One pinch: the two hands and their balance.
#[derive(Debug, Clone, Serialize)]
pub struct PinchRun {
    /// Left, then right.
    pub hands: Vec<PinchHand>,
    /// `|F_left + F_right| / mean(|F_left|, |F_right|)` over the measured hold: its largest and
    /// its mean.
    pub balance_max: f64,
    pub balance_mean: f64,
    /// The two ports together (what a passive two-port bounds): the energy generated at the
    /// device ports (how far the sum of the grips' work fell below zero) and at the
    /// environment ports, J.
    pub device_pair_generated_j: f64,
    pub environment_pair_generated_j: f64,
    /// The midpoint of the two styli at the end of the hold, mm along x from the cube's
    /// centre: where the free cube settled between the two hands (0 for two equal hands).
    pub drift_mm: f64,
}

/// Everything part 4 measured, for `--json`.
#[derive(Debug, Serialize)]
pub struct PinchReport {
    pub runs: Vec<PinchRun>,
    /// Each grip's hand alone against the cube with its far face clamped (full run only).
    pub alone: Vec<PinchHand>,
    pub targets: Vec<StabilityTarget>,
    pub seconds: f64,
}

/// The pinch scene, the cube's mesh `mesh` beside it; `clamped`: the cube's +x face fixed.
fn scene_text(mesh: &str, clamped: bool) -> String {
    let tool = |name: &str, x: f64| {
        format!(
            "[[tool]]\nname = \"{name}\"\nradius = {RADIUS}\nstiffness = {STIFFNESS}\n\
             max_force = 3.0\nworkspace = {{ scale = 1.0, offset = [{x}, 0.0, 0.0] }}\n\n"
        )
    };
    let fix = if clamped {
        format!(
            "\n[[body.fix]]\nkind = \"slab\"\npoint = [{x}, 0.0, 0.0]\nnormal = [-1.0, 0.0, 0.0]\n\
             thickness = 1e-4\n",
            x = EDGE / 2.0 - 1e-5
        )
    } else {
        String::new()
    };
    format!(
        "# lop-bench haptics part 4: a cube pinched by two tools{}. Written by\n\
         # bench/src/haptics/pinch.rs; edit the code, not this file.\n\
         [scene]\nname = \"pinch\"\ngravity = [0.0, 0.0, 0.0]\n\n\
         {left}{right}\
         [rates]\nhaptic_hz = 1000.0\ndeform_max_hz = 1000.0\n\n\
         [[body]]\nname = \"cube\"\nmesh = \"{mesh}\"\nmodel = \"fem\"\n\
         translate = [{h}, {h}, {h}]\n\n\
         [body.fem]\nyoung = {YOUNG}\npoisson = {POISSON}\ndensity = {DENSITY}\n\
         damping = {DAMPING}\ndt = {STEP}\n{fix}",
        if clamped {
            " (its +x face clamped)"
        } else {
            ""
        },
        left = tool("left", -DEVICE_ORIGIN),
        right = tool("right", DEVICE_ORIGIN),
        h = -EDGE / 2.0,
    )
}

/// Writes the cube's mesh and the two scenes (free, and clamped on +x) to `out` and loads
/// them.
fn write_scenes(out: &Path) -> Result<[Scene; 2]> {
    let mesh = box_mesh([EDGE; 3], [CELLS; 3], |_| false);
    let mesh_path = out.join("pinch-cube.vtk");
    write_vtk(&mesh, &mesh_path).with_context(|| format!("writing {}", mesh_path.display()))?;
    let load = |name: &str, clamped: bool| -> Result<Scene> {
        let path: PathBuf = out.join(name);
        std::fs::write(&path, scene_text("pinch-cube.vtk", clamped))
            .with_context(|| format!("writing {}", path.display()))?;
        load_scene(&path).map_err(|e| anyhow::anyhow!("{e}"))
    };
    Ok([
        load("pinch.toml", false)?,
        load("pinch-clamped.toml", true)?,
    ])
}

/// The press of the hand on side `sign` (−1: left, pressing along +x; +1: right, along −x),
/// in its device's frame, mm.
fn press_script(sign: f64) -> Result<MockScript> {
    // The device's origin is `DEVICE_ORIGIN` from the centre; the tool touches the face with
    // its centre `EDGE / 2 + RADIUS` from the centre.
    let contact = -sign * (DEVICE_ORIGIN - EDGE / 2.0 - RADIUS) * 1e3;
    let at = |s: f64| format!("[{:.4}, 0.0, 0.0]", contact - sign * s);
    let mut text = format!(
        "name = \"pinch {}\"\ndescription = \"press, hold, withdraw\"\n\
         end = \"hold\"\ninterpolation = \"smooth\"\n",
        if sign < 0.0 { "left" } else { "right" }
    );
    for (t, s) in [
        (0.0, REST_MM),
        (0.1, REST_MM),
        (T_APPROACH, APPROACH_MM),
        (T_PUSHED, PUSH_MM),
        (T_HOLD_END, PUSH_MM),
        (T_REST, REST_MM),
    ] {
        writeln!(
            text,
            "[[waypoint]]\nt = {t}\nposition = {}\nbuttons = []",
            at(s)
        )?;
    }
    MockScript::parse(&text, Path::new("pinch.toml")).map_err(|e| anyhow::anyhow!("{e}"))
}

/// The hand of `grip` on side `sign` (as in [`press_script`]), on a mock Omni.
fn hand(grip: Grip, sign: f64) -> Result<ToolHand> {
    Ok(ToolHand {
        script: press_script(sign)?,
        hand: Some(grip.parameters()),
        limits: MockDevice::omni_limits(),
    })
}

fn norm(f: [f64; 3]) -> f64 {
    (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt()
}

/// `|a + b| / mean(|a|, |b|)` of two forces (0 when both are zero).
fn balance(a: [f64; 3], b: [f64; 3]) -> f64 {
    let mean = 0.5 * (norm(a) + norm(b));
    if mean > 0.0 {
        norm([a[0] + b[0], a[1] + b[1], a[2] + b[2]]) / mean
    } else {
        0.0
    }
}

/// Whether tick time `t` is in the measured hold.
fn in_hold(t: f64) -> bool {
    (T_HOLD_END - HELD_WINDOW..T_HOLD_END).contains(&t)
}

/// The energy into the rendered environment up to each tick, J (`Σ −F_{n−1}·(x_n − x_{n−1})`,
/// as [`lop_scene::closed_loop::port_energy`] sums it).
fn environment_energy(ticks: &[TickRecord]) -> Vec<f64> {
    let mut e = 0.0;
    std::iter::once(0.0)
        .chain(ticks.windows(2).map(|w| {
            e -= (0..3)
                .map(|k| w[0].force[k] * (w[1].stylus[k] - w[0].stylus[k]))
                .sum::<f64>();
            e
        }))
        .collect()
}

/// How far the sum of two running energies falls below zero, J (0 when it never does).
fn pair_generated(a: impl Iterator<Item = f64>, b: impl Iterator<Item = f64>) -> f64 {
    (-a.zip(b).map(|(a, b)| a + b).fold(0.0, f64::min)).max(0.0) + 0.0
}

/// One hand's figures from its run (`sign` as in [`press_script`]).
fn hand_figures(side: &str, grip: Grip, sign: f64, run: &ClosedLoopRun) -> PinchHand {
    let ticks = &run.ticks;
    let held: Vec<&TickRecord> = ticks.iter().filter(|t| in_hold(t.t)).collect();
    let mean = |f: &dyn Fn(&TickRecord) -> f64| {
        held.iter().map(|t| f(t)).sum::<f64>() / held.len().max(1) as f64
    };
    let contact_x = -sign * (DEVICE_ORIGIN - EDGE / 2.0 - RADIUS);
    let energy = run.port_energy();
    PinchHand {
        side: side.to_string(),
        grip,
        held_n: mean_force(ticks, T_HOLD_END - HELD_WINDOW, T_HOLD_END),
        tissue_n: mean(&|t| t.tissue_force),
        stylus_mm: mean(&|t| -sign * (t.stylus[0] - contact_x)) * 1e3,
        hold_contact_ticks: held.iter().filter(|t| t.contact).count(),
        contact_changes: contact_changes(ticks),
        device_end_j: energy.device_end,
        device_generated_j: (-energy.device_min).max(0.0) + 0.0,
        environment_generated_j: (-energy.environment_min).max(0.0) + 0.0,
        passivity_ticks: run.passivity_ticks,
        dissipated_j: run.dissipated,
    }
}

/// One pinch of the free cube with the left hand's `left` grip and the right's `right`.
fn pinch(scene: &Scene, left: Grip, right: Grip) -> Result<(PinchRun, [ClosedLoopRun; 2])> {
    let runs = run_tools(ClosedLoopToolsOptions {
        scene: scene.clone(),
        hands: vec![hand(left, -1.0)?, hand(right, 1.0)?],
        config: DaemonConfig::default(),
        seconds: T_END,
    })?;
    let [l, r]: [ClosedLoopRun; 2] = runs
        .try_into()
        .map_err(|_| anyhow::anyhow!("two hands, not two runs"))?;
    let balances: Vec<f64> = l
        .ticks
        .iter()
        .zip(&r.ticks)
        .filter(|(a, _)| in_hold(a.t))
        .map(|(a, b)| balance(a.force, b.force))
        .collect();
    // The two devices' origins sit symmetrically about the cube's centre at scale 1: the
    // styli's midpoint in the scene is the mean of their device positions.
    let end = l.ticks.iter().rposition(|t| t.t < T_HOLD_END).unwrap_or(0);
    let drift_mm = 0.5 * (l.ticks[end].stylus[0] + r.ticks[end].stylus[0]) * 1e3;
    let grip_work = |run: &ClosedLoopRun| run.ticks.iter().map(|t| t.grip_work).collect::<Vec<_>>();
    let run = PinchRun {
        hands: vec![
            hand_figures("left", left, -1.0, &l),
            hand_figures("right", right, 1.0, &r),
        ],
        balance_max: balances.iter().copied().fold(0.0, f64::max),
        balance_mean: balances.iter().sum::<f64>() / balances.len().max(1) as f64,
        device_pair_generated_j: pair_generated(
            grip_work(&l).into_iter(),
            grip_work(&r).into_iter(),
        ),
        environment_pair_generated_j: pair_generated(
            environment_energy(&l.ticks).into_iter(),
            environment_energy(&r.ticks).into_iter(),
        ),
        drift_mm,
    };
    Ok((run, [l, r]))
}

/// The left hand of `grip` alone against the cube clamped on its far face (`scene`), through
/// the same loop with one tool.
fn alone(scene: &Scene, grip: Grip) -> Result<PinchHand> {
    let runs = run_tools(ClosedLoopToolsOptions {
        scene: scene.clone(),
        hands: vec![hand(grip, -1.0)?],
        config: DaemonConfig::default(),
        seconds: T_END,
    })?;
    let run = runs.first().context("one hand, no run")?;
    Ok(hand_figures("alone", grip, -1.0, run))
}

/// A row of the table.
fn print_hand(h: &PinchHand, balance: &str) {
    println!(
        "{:<24} {:<6} {:>8.3} {:>9.3} {:>10.3} {:>9} {:>10.4} {:>11.3} {:>11.3} {:>6} {:>12}",
        h.grip.name(),
        h.side,
        h.held_n,
        h.tissue_n,
        h.stylus_mm,
        h.contact_changes,
        h.device_end_j * 1e3,
        h.device_generated_j * 1e6,
        h.environment_generated_j * 1e6,
        h.passivity_ticks,
        balance,
    );
}

/// Runs the pinch (`quick`: two firm hands, and a light with a firm one; no hand alone).
pub fn run(quick: bool, out: &Path) -> Result<PinchReport> {
    let clock = Instant::now();
    let [free, clamped] = write_scenes(out)?;
    let cases: &[(Grip, Grip)] = if quick {
        &[(Grip::Firm, Grip::Firm), (Grip::Light, Grip::Firm)]
    } else {
        &[
            (Grip::Firm, Grip::Firm),
            (Grip::Light, Grip::Light),
            (Grip::Light, Grip::Firm),
        ]
    };
    println!(
        "\nPart 4: bimanual pinch: two simulated hands squeeze a free 20 mm cube (E {:.0} kPa) \
         from either side ({PUSH_MM} mm push, hold, withdraw), closed loop at 1 kHz",
        YOUNG * 1e-3
    );
    println!(
        "{:<24} {:<6} {:>8} {:>9} {:>10} {:>9} {:>10} {:>11} {:>11} {:>6} {:>12}",
        "hand",
        "side",
        "held N",
        "tissue N",
        "stylus mm",
        "contacts",
        "device mJ",
        "dev gen uJ",
        "env gen uJ",
        "PC tk",
        "balance %"
    );
    let mut runs = Vec::new();
    let mut traces = Vec::new();
    let mut csv = format!("left_grip,right_grip,side,{}\n", TickRecord::CSV_HEADER);
    for &(left, right) in cases {
        let (r, ticks) = pinch(&free, left, right)?;
        print_hand(&r.hands[0], &format!("{:.3}", 100.0 * r.balance_max));
        print_hand(
            &r.hands[1],
            &format!("(mean {:.3})", 100.0 * r.balance_mean),
        );
        for (h, hand_ticks) in r.hands.iter().zip(&ticks) {
            for t in &hand_ticks.ticks {
                write!(csv, "{left:?},{right:?},{},", h.side)?;
                t.write_csv(&mut csv)?;
                csv.push('\n');
            }
        }
        traces.push(((left, right), ticks));
        runs.push(r);
    }
    std::fs::write(out.join("pinch.csv"), csv)?;
    let mut lone = Vec::new();
    if !quick {
        for grip in [Grip::Firm, Grip::Light] {
            let h = alone(&clamped, grip)?;
            print_hand(&h, "");
            lone.push(h);
        }
    }
    println!(
        "\n(held N: mean |F| on the hand over the last {:.0} ms of the hold; tissue N: what its \
         tool gave the tissue; stylus mm: past the undeformed face; contacts: contact changes \
         over the cycle; device mJ: the work the grip did on the stylus; gen uJ: energy the \
         coupling generated at that port; PC tk: ticks the passivity controller acted on; \
         balance: |F_left + F_right| over the mean |F|, largest and mean over the hold; \
         alone: the hand against the cube with its far face clamped, one tool)",
        HELD_WINDOW * 1e3
    );
    for r in &runs {
        println!(
            "{} / {}: the cube settled at {:+.3} mm along x; both ports together generated \
             {:.3} uJ at the devices, {:.3} uJ at the environment",
            r.hands[0].grip.name(),
            r.hands[1].grip.name(),
            r.drift_mm,
            r.device_pair_generated_j * 1e6,
            r.environment_pair_generated_j * 1e6,
        );
    }

    let hands: Vec<&PinchHand> = runs.iter().flat_map(|r| &r.hands).collect();
    let let_go = hands
        .iter()
        .filter(|h| {
            h.hold_contact_ticks < (HELD_WINDOW * 1e3).round() as usize || !(h.held_n > 0.0)
        })
        .count();
    let worst_balance = runs.iter().map(|r| r.balance_max).fold(0.0, f64::max);
    let firm: Vec<&&PinchHand> = hands.iter().filter(|h| h.grip == Grip::Firm).collect();
    let worst_firm = firm
        .iter()
        .map(|h| h.device_generated_j)
        .fold(0.0, f64::max);
    // The light grips of the pinches and alone: only the rendered force can dissipate there.
    let light: Vec<&PinchHand> = hands
        .iter()
        .copied()
        .chain(lone.iter())
        .filter(|h| h.grip == Grip::Light)
        .collect();
    let worst_light = light
        .iter()
        .map(|h| h.device_generated_j)
        .fold(0.0, f64::max);
    let targets = vec![
        StabilityTarget {
            name: format!(
                "{} hands: hands not in contact through the hold",
                hands.len()
            ),
            value: let_go as f64,
            limit: 0.0,
            pass: let_go == 0,
        },
        StabilityTarget {
            name: format!(
                "{} pinches: largest |F_left + F_right| / |F| over the hold",
                runs.len()
            ),
            value: worst_balance,
            limit: BALANCE_LIMIT,
            pass: worst_balance <= BALANCE_LIMIT,
        },
        StabilityTarget {
            name: format!(
                "{} firm-grip hands: most energy generated at a device port (J)",
                firm.len()
            ),
            value: worst_firm,
            limit: ENERGY_TOLERANCE,
            pass: worst_firm <= ENERGY_TOLERANCE,
        },
        StabilityTarget {
            name: format!(
                "{} light-grip hands: most energy generated at a device port (J)",
                light.len()
            ),
            value: worst_light,
            limit: ENERGY_TOLERANCE,
            pass: worst_light <= ENERGY_TOLERANCE,
        },
    ];
    println!("\nTargets (pinch)");
    for t in &targets {
        println!(
            "  {:<4} {:<86} {:>10.3e} (limit {:.0e})",
            if t.pass { "PASS" } else { "FAIL" },
            t.name,
            t.value,
            t.limit
        );
    }
    plot_pinch(out, &traces)?;
    Ok(PinchReport {
        runs,
        alone: lone,
        targets,
        seconds: clock.elapsed().as_secs_f64(),
    })
}

/// `pinch.svg`: per pinch, the force on each hand along x and their sum.
fn plot_pinch(out: &Path, traces: &[((Grip, Grip), [ClosedLoopRun; 2])]) -> Result<()> {
    let f_max = traces
        .iter()
        .flat_map(|(_, runs)| {
            runs.iter()
                .flat_map(|r| r.ticks.iter().map(|t| norm(t.force)))
        })
        .fold(0.0, f64::max)
        .max(1e-3)
        * 1.5;
    let panels: Vec<Panel> = traces
        .iter()
        .map(|((left, right), [l, r])| {
            let x = |ticks: &[TickRecord]| -> Vec<(f64, f64)> {
                ticks.iter().map(|t| (t.t, t.force[0])).collect()
            };
            let sum: Vec<(f64, f64)> = l
                .ticks
                .iter()
                .zip(&r.ticks)
                .map(|(a, b)| (a.t, a.force[0] + b.force[0]))
                .collect();
            Panel {
                title: format!("left: {}, right: {}", left.name(), right.name()),
                x_desc: "time, s".into(),
                y_desc: "force on the hand along x, N".into(),
                x_range: (0.0, T_END),
                y_range: (-f_max, f_max),
                series: vec![
                    Series {
                        label: "left".into(),
                        points: x(&l.ticks),
                        color: 0,
                    },
                    Series {
                        label: "right".into(),
                        points: x(&r.ticks),
                        color: 1,
                    },
                    Series {
                        label: "sum".into(),
                        points: sum,
                        color: 4,
                    },
                ],
            }
        })
        .collect();
    plot::line_grid(
        &out.join("pinch.svg"),
        "Bimanual pinch: two simulated hands squeeze a free cube",
        &panels,
        panels.len().min(3),
        (560, 360),
    )
}
