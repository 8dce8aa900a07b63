//! Part 3 of `lop-bench models`: the thesis' chapter-3 integrator study (§3.2, Figs. 3.7–3.10)
//! on the beam, and the Fig. 3.11 analogue (time per step per integrator, from part 1). See the
//! parent module's docs for the set-up; this file runs it and writes the CSV and SVG files.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use lop_sim::mesh::TetMesh;
use lop_sim::msd::{Integrator, MassSpring, MsdParameters, NodeMass, SubstepPolicy};
use serde::Serialize;

use super::{integrator_key, integrator_label, summarize, us, StepRow};
use crate::pipeline;
use crate::plot::{self, Panel, Series};
use crate::table::{table, Align};

/// Node mass of the thesis' bar, kg.
const NODE_MASS: f64 = 0.1;
/// Gravity, m/s².
const GRAVITY: [f64; 3] = [0.0, -9.81, 0.0];
/// Where the two recorded points are looked for (nearest node), m.
const FIRST_POINT: [f64; 3] = [0.2, 0.05, 0.0];
const SECOND_POINT: [f64; 3] = [0.4, 0.05, 0.05];

/// The integrators of Figs. 3.7–3.9: the thesis' three plus symplectic and implicit Euler.
const STUDY_INTEGRATORS: [Integrator; 5] = Integrator::ALL;
/// Fig. 3.10: RK4 (the thesis), and for comparison symplectic Euler, Verlet and implicit Euler,
/// at growing steps (explicit Euler already fails at the smallest).
const FIG3_10_INTEGRATORS: [Integrator; 4] = [
    Integrator::SymplecticEuler,
    Integrator::Verlet,
    Integrator::Rk4,
    Integrator::ImplicitEuler,
];
/// Fig. 3.10's time steps, s: the thesis' 0.005 and 0.0054, then growing past every explicit
/// integrator's limit.
const FIG3_10_DTS: [f64; 7] = [0.005, 0.0054, 0.007, 0.008, 0.01, 0.02, 0.04];
/// The stability search brackets `dt` in this range, s.
const LIMIT_SEARCH: (f64, f64) = (1e-4, 0.08);
/// Bisection steps of the stability search (geometric: the bracket shrinks to a ratio of
/// `(0.08 / 1e-4)^(1/2^9)` ≈ 1.3 %).
const LIMIT_BISECTIONS: usize = 9;

/// How long each run is.
#[derive(Debug, Clone, Copy)]
pub struct StudyConfig {
    /// Simulated time per run, s.
    pub seconds: f64,
}

impl StudyConfig {
    /// 5 s per run.
    pub fn full() -> StudyConfig {
        StudyConfig { seconds: 5.0 }
    }
    /// 0.5 s per run.
    pub fn quick() -> StudyConfig {
        StudyConfig { seconds: 0.5 }
    }
}

/// One parameter set: one row of panels of a thesis figure.
#[derive(Debug, Clone)]
struct ParamSet {
    /// Caption text, e.g. "stiffness 250".
    label: String,
    /// File-name part, e.g. "k250".
    tag: String,
    stiffness: f64,
    damping: f64,
    dt: f64,
}

/// One thesis figure.
#[derive(Debug, Clone)]
struct FigureSpec {
    /// File-name stem, e.g. "fig3_7".
    id: &'static str,
    /// "Fig. 3.7".
    thesis: &'static str,
    /// What the figure compares.
    title: &'static str,
    sets: Vec<ParamSet>,
    integrators: Vec<Integrator>,
}

fn set(label: String, tag: String, stiffness: f64, damping: f64, dt: f64) -> ParamSet {
    ParamSet {
        label,
        tag,
        stiffness,
        damping,
        dt,
    }
}

fn figures() -> Vec<FigureSpec> {
    let all = STUDY_INTEGRATORS.to_vec();
    vec![
        FigureSpec {
            id: "fig3_7",
            thesis: "Fig. 3.7",
            title: "stiffness 250 vs 300 N/m (mass 0.1 kg, damping 0.01, dt 0.0048 s)",
            sets: [250.0, 300.0]
                .iter()
                .map(|&k| set(format!("stiffness {k}"), format!("k{k}"), k, 0.01, 0.0048))
                .collect(),
            integrators: all.clone(),
        },
        FigureSpec {
            id: "fig3_8",
            thesis: "Fig. 3.8",
            title: "time step 0.0050 vs 0.0054 s (mass 0.1 kg, stiffness 250, damping 0.01)",
            sets: [0.005, 0.0054]
                .iter()
                .map(|&dt| set(format!("dt {dt:.4}"), format!("dt{dt:.4}"), 250.0, 0.01, dt))
                .collect(),
            integrators: all.clone(),
        },
        FigureSpec {
            id: "fig3_9",
            thesis: "Fig. 3.9",
            title: "damping 0.01 vs 0.1 (mass 0.1 kg, stiffness 250, dt 0.005 s)",
            sets: [0.01, 0.1]
                .iter()
                .map(|&c| set(format!("damping {c}"), format!("c{c}"), 250.0, c, 0.005))
                .collect(),
            integrators: all,
        },
        FigureSpec {
            id: "fig3_10",
            thesis: "Fig. 3.10",
            title: "RK4 (with symplectic Euler, Verlet, implicit Euler) at growing time steps \
                    (mass 0.1 kg, stiffness 250, damping 0.01)",
            sets: FIG3_10_DTS
                .iter()
                .map(|&dt| set(format!("dt {dt:.4}"), format!("dt{dt:.4}"), 250.0, 0.01, dt))
                .collect(),
            integrators: FIG3_10_INTEGRATORS.to_vec(),
        },
    ]
}

/// A recorded node.
#[derive(Debug, Clone, Serialize)]
pub struct PointInfo {
    /// What it stands for.
    pub name: String,
    /// Where it was looked for, m.
    pub target: [f64; 3],
    /// The nearest node (0-based) and its rest position, m.
    pub node: u32,
    pub position: [f64; 3],
}

/// One run (figure × parameter set × integrator).
#[derive(Debug, Clone, Serialize)]
pub struct RunSummary {
    pub figure: String,
    pub set: String,
    pub integrator: String,
    pub stiffness: f64,
    pub damping: f64,
    pub dt: f64,
    /// Steps done (up to and including a blow-up).
    pub steps: usize,
    /// Simulated time reached, s.
    pub simulated_s: f64,
    /// The step that blew up ended at this time, s.
    pub blow_up_at_s: Option<f64>,
    /// "NonFinite" or "Runaway".
    pub blow_up_cause: Option<String>,
    /// Displacement at the end (or just before the blow-up), mm.
    pub final_first_mm: f64,
    pub final_second_mm: f64,
    /// Largest displacement over the run, mm.
    pub peak_first_mm: f64,
    pub peak_second_mm: f64,
    /// Median wall time of one step, µs.
    pub step_median_us: f64,
}

/// Part 3's report.
#[derive(Debug, Clone, Serialize)]
pub struct StudyReport {
    pub mesh: String,
    pub nodes: usize,
    pub springs: usize,
    pub fixed_nodes: usize,
    pub node_mass_kg: f64,
    pub gravity: [f64; 3],
    pub simulated_s: f64,
    pub first_point: PointInfo,
    pub second_point: PointInfo,
    pub runs: Vec<RunSummary>,
    /// Each integrator's stability limit on the bar (stiffness 250, damping 0.01).
    pub stability_limits: Vec<StabilityLimit>,
}

/// One integrator's cost per step on the beam (Fig. 3.11).
#[derive(Debug, Clone, Serialize)]
pub struct StepCost {
    pub integrator: String,
    pub median_us: f64,
    pub p99_us: f64,
    /// Median relative to explicit Euler's.
    pub relative: f64,
}

fn nearest_node(mesh: &TetMesh, target: [f64; 3]) -> u32 {
    let mut best = (0u32, f64::INFINITY);
    for (i, p) in mesh.nodes.iter().enumerate() {
        let d2: f64 = (0..3).map(|k| (p[k] - target[k]).powi(2)).sum();
        if d2 < best.1 {
            best = (i as u32, d2);
        }
    }
    best.0
}

fn point(mesh: &TetMesh, name: &str, target: [f64; 3]) -> PointInfo {
    let node = nearest_node(mesh, target);
    PointInfo {
        name: name.into(),
        target,
        node,
        position: mesh.nodes[node as usize],
    }
}

/// A run's samples: displacement (mm) of the two points after each step (index 0 = rest).
struct Trace {
    first: Vec<f64>,
    second: Vec<f64>,
}

fn displacement(x: [f64; 3], rest: [f64; 3]) -> f64 {
    ((x[0] - rest[0]).powi(2) + (x[1] - rest[1]).powi(2) + (x[2] - rest[2]).powi(2)).sqrt()
}

/// What one simulation did.
struct Outcome {
    trace: Trace,
    /// Step wall times, ns.
    ns: Vec<u64>,
    /// Steps done (a blow-up's included).
    steps: usize,
    /// Time at the end of the step that blew up, s, and the cause.
    blow_up: Option<(f64, String)>,
}

/// The thesis' bar with `stiffness`, `damping` and exactly one `integrator` step per `dt`, from
/// rest for `seconds` (stopped at a blow-up).
fn simulate(
    mesh: &TetMesh,
    ps: &ParamSet,
    integrator: Integrator,
    points: [u32; 2],
    seconds: f64,
) -> Result<Outcome> {
    let params = MsdParameters {
        stiffness: ps.stiffness,
        mass: NodeMass::PerNode(NODE_MASS),
        damping: ps.damping,
        dt: ps.dt,
        integrator,
    };
    let mut body = MassSpring::new(mesh, params).with_substep_policy(SubstepPolicy::Fixed(1));
    let rest = points.map(|p| mesh.nodes[p as usize]);
    let steps = (seconds / ps.dt).round() as usize;
    let external = vec![[0.0; 3]; mesh.nodes.len()];
    let mut trace = Trace {
        first: Vec::with_capacity(steps + 1),
        second: Vec::with_capacity(steps + 1),
    };
    trace.first.push(0.0);
    trace.second.push(0.0);
    let mut ns = Vec::with_capacity(steps);
    let mut blow_up = None;
    let mut done = 0;
    for s in 1..=steps {
        let t = Instant::now();
        let r = body.step(GRAVITY, &external, None);
        ns.push(t.elapsed().as_nanos() as u64);
        done = s;
        match r {
            Ok(_) => {
                let x = body.positions();
                trace
                    .first
                    .push(1e3 * displacement(x[points[0] as usize], rest[0]));
                trace
                    .second
                    .push(1e3 * displacement(x[points[1] as usize], rest[1]));
            }
            Err(cause) => {
                blow_up = Some((s as f64 * ps.dt, format!("{cause:?}")));
                break;
            }
        }
        if pipeline::interrupted() {
            bail!("interrupted");
        }
    }
    Ok(Outcome {
        trace,
        ns,
        steps: done,
        blow_up,
    })
}

fn run_one(
    mesh: &TetMesh,
    fig: &FigureSpec,
    ps: &ParamSet,
    integrator: Integrator,
    points: [u32; 2],
    seconds: f64,
) -> Result<(RunSummary, Trace)> {
    let Outcome {
        trace,
        mut ns,
        steps,
        blow_up,
    } = simulate(mesh, ps, integrator, points, seconds)?;
    let (median, ..) = summarize(&mut ns);
    let peak = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    let summary = RunSummary {
        figure: fig.id.into(),
        set: ps.label.clone(),
        integrator: integrator_key(integrator).into(),
        stiffness: ps.stiffness,
        damping: ps.damping,
        dt: ps.dt,
        steps,
        simulated_s: steps as f64 * ps.dt,
        blow_up_at_s: blow_up.as_ref().map(|b| b.0),
        blow_up_cause: blow_up.map(|b| b.1),
        final_first_mm: *trace.first.last().unwrap_or(&0.0),
        final_second_mm: *trace.second.last().unwrap_or(&0.0),
        peak_first_mm: peak(&trace.first),
        peak_second_mm: peak(&trace.second),
        step_median_us: median,
    };
    Ok((summary, trace))
}

/// Where an integrator stops being stable on the bar (stiffness 250, damping 0.01).
#[derive(Debug, Clone, Serialize)]
pub struct StabilityLimit {
    pub integrator: String,
    /// Largest `dt` found that ran the whole simulated time without blowing up, s (`None`:
    /// not even the smallest tried).
    pub largest_stable_dt: Option<f64>,
    /// Smallest `dt` found that blew up, s (`None`: not even the largest tried).
    pub smallest_unstable_dt: Option<f64>,
}

/// Bisects (geometrically) for each integrator's largest stable `dt` in [`LIMIT_SEARCH`].
fn stability_limits(mesh: &TetMesh, points: [u32; 2], seconds: f64) -> Result<Vec<StabilityLimit>> {
    let mut out = Vec::new();
    for integrator in Integrator::ALL {
        eprintln!("models: stability limit / {}", integrator_label(integrator));
        let stable = |dt: f64| -> Result<bool> {
            let ps = set(String::new(), String::new(), 250.0, 0.01, dt);
            Ok(simulate(mesh, &ps, integrator, points, seconds)?
                .blow_up
                .is_none())
        };
        let (mut lo, mut hi) = LIMIT_SEARCH;
        let limit = if stable(hi)? {
            StabilityLimit {
                integrator: integrator_key(integrator).into(),
                largest_stable_dt: Some(hi),
                smallest_unstable_dt: None,
            }
        } else if !stable(lo)? {
            StabilityLimit {
                integrator: integrator_key(integrator).into(),
                largest_stable_dt: None,
                smallest_unstable_dt: Some(lo),
            }
        } else {
            for _ in 0..LIMIT_BISECTIONS {
                let mid = (lo * hi).sqrt();
                if stable(mid)? {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            StabilityLimit {
                integrator: integrator_key(integrator).into(),
                largest_stable_dt: Some(lo),
                smallest_unstable_dt: Some(hi),
            }
        };
        out.push(limit);
    }
    Ok(out)
}

fn rel(out: &Path, name: &str) -> String {
    out.join(name).display().to_string()
}

/// Runs every figure, writes `<id>-<set>.csv` per parameter set and `<id>.svg` per figure into
/// `out`, and appends their paths to `files`.
pub fn run(
    mesh: &TetMesh,
    cfg: &StudyConfig,
    out: &Path,
    files: &mut Vec<String>,
) -> Result<StudyReport> {
    let first = point(mesh, "first point: middle of the top edge", FIRST_POINT);
    let second = point(mesh, "second point: free-end top corner", SECOND_POINT);
    let points = [first.node, second.node];
    let mut runs = Vec::new();
    for fig in figures() {
        // traces[set][integrator]
        let mut traces: Vec<Vec<(RunSummary, Trace)>> = Vec::new();
        for ps in &fig.sets {
            let mut row = Vec::new();
            for &integ in &fig.integrators {
                eprintln!(
                    "models: {} {} / {}",
                    fig.thesis,
                    ps.label,
                    integrator_label(integ)
                );
                row.push(run_one(mesh, &fig, ps, integ, points, cfg.seconds)?);
            }
            let name = format!("{}-{}.csv", fig.id, ps.tag);
            write_csv(&out.join(&name), ps, &fig.integrators, &row)?;
            files.push(rel(out, &name));
            traces.push(row);
        }
        let name = format!("{}.svg", fig.id);
        write_svg(&out.join(&name), &fig, &traces, cfg.seconds)?;
        files.push(rel(out, &name));
        runs.extend(traces.into_iter().flatten().map(|(s, _)| s));
    }
    let stability_limits = stability_limits(mesh, points, cfg.seconds)?;
    Ok(StudyReport {
        mesh: mesh.source.display().to_string(),
        nodes: mesh.nodes.len(),
        springs: mesh.edges().len(),
        fixed_nodes: mesh.fixed.len(),
        node_mass_kg: NODE_MASS,
        gravity: GRAVITY,
        simulated_s: cfg.seconds,
        first_point: first,
        second_point: second,
        runs,
        stability_limits,
    })
}

fn write_csv(
    path: &Path,
    ps: &ParamSet,
    integrators: &[Integrator],
    row: &[(RunSummary, Trace)],
) -> Result<()> {
    let mut s = String::from("time_s");
    for &i in integrators {
        let k = integrator_key(i).replace('-', "_");
        let _ = write!(s, ",{k}_first_mm,{k}_second_mm");
    }
    s.push('\n');
    let len = row.iter().map(|r| r.1.first.len()).max().unwrap_or(0);
    for n in 0..len {
        let _ = write!(s, "{:.6}", n as f64 * ps.dt);
        for (_, tr) in row {
            match (tr.first.get(n), tr.second.get(n)) {
                (Some(a), Some(b)) => {
                    let _ = write!(s, ",{a:.6},{b:.6}");
                }
                _ => s.push_str(",,"),
            }
        }
        s.push('\n');
    }
    std::fs::write(path, s).with_context(|| format!("writing {}", path.display()))
}

/// Colour index of an integrator (the same in every plot).
fn color(i: Integrator) -> usize {
    match i {
        Integrator::ExplicitEuler => 0,
        Integrator::SymplecticEuler => 1,
        Integrator::Verlet => 2,
        Integrator::Rk4 => 3,
        Integrator::ImplicitEuler => 4,
    }
}

fn write_svg(
    path: &Path,
    fig: &FigureSpec,
    traces: &[Vec<(RunSummary, Trace)>],
    seconds: f64,
) -> Result<()> {
    // A common y range per column, from the runs that did not blow up (so a diverging run is
    // cut where it leaves the chart instead of squashing the others); if every run blew up,
    // from the first fifth of each run.
    let mut top = [0.0f64; 2];
    let mut any_stable = false;
    for (s, _) in traces.iter().flatten() {
        if s.blow_up_at_s.is_none() {
            any_stable = true;
            top[0] = top[0].max(s.peak_first_mm);
            top[1] = top[1].max(s.peak_second_mm);
        }
    }
    if !any_stable {
        for (_, t) in traces.iter().flatten() {
            let n = (t.first.len() / 5).max(1);
            top[0] = top[0].max(t.first[..n].iter().copied().fold(0.0, f64::max));
            top[1] = top[1].max(t.second[..n].iter().copied().fold(0.0, f64::max));
        }
    }
    // Headroom for the legend (upper left).
    let top = top.map(|t| if t > 0.0 { t * 1.6 } else { 1.0 });
    let mut panels = Vec::new();
    for (ps, row) in fig.sets.iter().zip(traces) {
        for (col, name) in ["first point", "second point"].iter().enumerate() {
            let series = row
                .iter()
                .map(|(s, tr)| {
                    let values = if col == 0 { &tr.first } else { &tr.second };
                    let integ = STUDY_INTEGRATORS
                        .into_iter()
                        .find(|&i| integrator_key(i) == s.integrator)
                        .unwrap_or(Integrator::ExplicitEuler);
                    let mut label = integrator_label(integ).to_string();
                    if let Some(t) = s.blow_up_at_s {
                        let _ = write!(label, " (blew up at {t:.3} s)");
                    }
                    Series {
                        label,
                        points: values
                            .iter()
                            .enumerate()
                            .map(|(n, &v)| (n as f64 * ps.dt, v))
                            .collect(),
                        color: color(integ),
                    }
                })
                .collect();
            panels.push(Panel {
                title: format!("{}: {name}", ps.label),
                x_desc: "time (s)".into(),
                y_desc: "displacement (mm)".into(),
                x_range: (0.0, seconds),
                y_range: (0.0, top[col]),
                series,
            });
        }
    }
    plot::line_grid(
        path,
        &format!("{} analogue: {}", fig.thesis, fig.title),
        &panels,
        2,
        (560, 300),
    )
}

/// Fig. 3.11: the beam's MSD rows of part 1, written as `fig3_11.csv` and `fig3_11.svg`.
pub fn fig3_11(rows: &[StepRow], out: &Path, files: &mut Vec<String>) -> Result<Vec<StepCost>> {
    let beam: Vec<&StepRow> = rows
        .iter()
        .filter(|r| r.mesh == "beam" && r.model.starts_with("msd-"))
        .collect();
    let base = beam
        .iter()
        .find(|r| r.model == "msd-explicit-euler")
        .map_or(0.0, |r| r.timing.median_us);
    let costs: Vec<StepCost> = Integrator::ALL
        .iter()
        .filter_map(|&i| {
            let key = format!("msd-{}", integrator_key(i));
            beam.iter().find(|r| r.model == key).map(|r| StepCost {
                integrator: integrator_key(i).into(),
                median_us: r.timing.median_us,
                p99_us: r.timing.p99_us,
                relative: if base > 0.0 {
                    r.timing.median_us / base
                } else {
                    0.0
                },
            })
        })
        .collect();
    let mut csv = String::from("integrator,median_us,p99_us,relative_to_explicit_euler\n");
    for c in &costs {
        let _ = writeln!(
            csv,
            "{},{:.3},{:.3},{:.3}",
            c.integrator, c.median_us, c.p99_us, c.relative
        );
    }
    let path = out.join("fig3_11.csv");
    std::fs::write(&path, csv).with_context(|| format!("writing {}", path.display()))?;
    files.push(rel(out, "fig3_11.csv"));
    let bars: Vec<(String, f64)> = costs
        .iter()
        .map(|c| {
            let i = Integrator::ALL
                .into_iter()
                .find(|&i| integrator_key(i) == c.integrator)
                .unwrap_or(Integrator::ExplicitEuler);
            (integrator_label(i).to_string(), c.median_us)
        })
        .collect();
    plot::bars(
        &out.join("fig3_11.svg"),
        "Fig. 3.11 analogue: time per step on the beam (MSD, one step, median)",
        "µs per step (log scale)",
        &bars,
    )?;
    files.push(rel(out, "fig3_11.svg"));
    Ok(costs)
}

/// Part 3's summary for stdout.
pub fn render(r: &StudyReport) -> String {
    let mut s = format!(
        "Part 3: thesis ch. 3 study: beam ({} nodes, {} springs, {} fixed at x = 0), MSD, node \
         mass {} kg, gravity 9.81 down, one integrator step per dt (no sub-stepping), {} s \
         simulated per run\n",
        r.nodes, r.springs, r.fixed_nodes, r.node_mass_kg, r.simulated_s
    );
    for p in [&r.first_point, &r.second_point] {
        let _ = writeln!(
            s,
            "{} = node {} at ({:.4}, {:.4}, {:.4}) m, nearest to ({}, {}, {})",
            p.name,
            p.node,
            p.position[0],
            p.position[1],
            p.position[2],
            p.target[0],
            p.target[1],
            p.target[2]
        );
    }
    let mut last_fig = String::new();
    let mut cells: Vec<Vec<String>> = Vec::new();
    let flush = |s: &mut String, fig: &str, cells: &mut Vec<Vec<String>>| {
        if cells.is_empty() {
            return;
        }
        let _ = writeln!(s, "\n{fig}:");
        *s += &table(
            &[
                ("set", Align::Left),
                ("integrator", Align::Left),
                ("outcome", Align::Left),
                ("first final", Align::Right),
                ("first peak", Align::Right),
                ("second final", Align::Right),
                ("second peak", Align::Right),
                ("µs/step", Align::Right),
            ],
            cells,
        );
        cells.clear();
    };
    for run in &r.runs {
        if run.figure != last_fig {
            flush(&mut s, &last_fig.replace("fig3_", "Fig. 3."), &mut cells);
            last_fig = run.figure.clone();
        }
        let outcome = match (&run.blow_up_at_s, &run.blow_up_cause) {
            (Some(t), Some(c)) => format!("BLEW UP at {t:.3} s ({c})"),
            _ => "stable".into(),
        };
        let mm = |v: f64| format!("{v:.2}");
        cells.push(vec![
            run.set.clone(),
            run.integrator.clone(),
            outcome,
            mm(run.final_first_mm),
            mm(run.peak_first_mm),
            mm(run.final_second_mm),
            mm(run.peak_second_mm),
            us(run.step_median_us),
        ]);
    }
    flush(&mut s, &last_fig.replace("fig3_", "Fig. 3."), &mut cells);
    s.push_str(
        "(displacements in mm; \"final\" is at the end of the run or just before a blow-up)\n",
    );
    let _ = writeln!(
        s,
        "\nStability limit (stiffness 250, damping 0.01, {} s runs; bisection in {}..{} s):",
        r.simulated_s, LIMIT_SEARCH.0, LIMIT_SEARCH.1
    );
    let dt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.5}"));
    let cells: Vec<Vec<String>> = r
        .stability_limits
        .iter()
        .map(|l| {
            vec![
                l.integrator.clone(),
                dt(l.largest_stable_dt),
                dt(l.smallest_unstable_dt),
            ]
        })
        .collect();
    s += &table(
        &[
            ("integrator", Align::Left),
            ("largest stable dt (s)", Align::Right),
            ("smallest unstable dt (s)", Align::Right),
        ],
        &cells,
    );
    s
}

/// The Fig. 3.11 table for stdout.
pub fn render_fig3_11(costs: &[StepCost]) -> String {
    let mut s =
        String::from("\nFig. 3.11 analogue: time per step on the beam (part 1's MSD rows), µs\n");
    let cells: Vec<Vec<String>> = costs
        .iter()
        .map(|c| {
            vec![
                c.integrator.clone(),
                us(c.median_us),
                us(c.p99_us),
                format!("{:.2}x", c.relative),
            ]
        })
        .collect();
    s += &table(
        &[
            ("integrator", Align::Left),
            ("median", Align::Right),
            ("p99", Align::Right),
            ("vs explicit Euler", Align::Right),
        ],
        &cells,
    );
    s
}
