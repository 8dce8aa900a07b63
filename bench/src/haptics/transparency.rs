//! Part 1 of `lop-bench haptics`: transparency. Per mesh: the static reference's `F(d)`, the
//! press through lop (vertical, and tilted 5° for the sideways test), the force at
//! `d = 0.3 mm`, the hold's steadiness; then the targets, PASS or FAIL. Tables on stdout, CSV
//! and SVG in the output folder, every figure in the JSON report.
//!
//! Nothing here knows how lop's tool contact works: the press only drives the public round and
//! god-object, so a new contact model shows its figures without a change here.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use serde::Serialize;

use super::block::{self, Block};
use super::hertz::{bonded_layer_factor, hertz_force};
use super::press::{press, Hold, Phase, Press, PressPlan, Setup};
use super::reference::{ContactReference, Material, Penalty};
use crate::plot::{self, Panel, Series};

/// The block and tool.
pub const SETUP: Setup = Setup {
    young: 30e3,
    poisson: 0.3,
    density: 1050.0,
    damping: 10.0,
    radius: 3e-3,
    tool_stiffness: 600.0,
};
/// The depth at which forces are compared, m.
pub const COMPARE_DEPTH: f64 = 0.3e-3;
/// The deepest indentation, m.
pub const MAX_DEPTH: f64 = 0.4e-3;
/// Targets.
const SAME_MESH_LIMIT: f64 = 0.10;
const SPREAD_LIMIT: f64 = 0.15;
const HERTZ_LIMIT: f64 = 0.20;
const HOLD_VARIATION_LIMIT: f64 = 0.05;
const SIDEWAYS_LIMIT: f64 = 0.10;
/// Tilt of the second press's path, degrees.
const TILT_DEG: f64 = 5.0;

/// The candidate radius of the reference: the sphere's intersection radius with the undeformed
/// top face at the deepest indentation, `√(2Rd − d²)` (the contact radius is about `√(Rd)`,
/// smaller: the surface sinks around the tool), plus 10 %.
pub fn candidate_radius(radius: f64, depth: f64) -> f64 {
    1.1 * (2.0 * radius * depth - depth * depth).sqrt()
}

/// Everything measured, for `--json`.
#[derive(Debug, Serialize)]
pub struct Report {
    /// `gmsh --version`.
    pub gmsh: String,
    /// One row per mesh of the press (0.8, 0.4, 0.2 mm).
    pub meshes: Vec<MeshRow>,
    /// The reference's `F(d)`, every mesh and depth, with Hertz.
    pub reference: Vec<ReferenceRow>,
    /// The targets.
    pub targets: Vec<Target>,
}

/// One mesh.
#[derive(Debug, Serialize)]
pub struct MeshRow {
    /// `block_0.8mm` and the like.
    pub key: String,
    /// Element size asked at the contact, mm.
    pub size_mm: f64,
    /// Measured mean edge length at the contact, mm.
    pub edge_mm: f64,
    pub nodes: usize,
    pub tets: usize,
    /// Whether lop pressed on it (the converged reference mesh is not pressed).
    pub pressed: bool,
    /// Reference: free DOFs, non-zeros of the Cholesky factor, candidate nodes, seconds to
    /// assemble, factorise and condense.
    pub dofs: usize,
    pub factor_nnz: usize,
    pub candidates: usize,
    pub reference_setup_s: f64,
    /// Force on the hand through lop at d = 0.3 mm, mN: the vertical press's hold (static; its
    /// depth is in `hold_vertical`).
    pub lop_mn: Option<f64>,
    /// The same while the device descends (interpolated at 0.3 mm): includes the one-tick lag
    /// of the god-object behind the device, about `k v Δt`.
    pub lop_moving_mn: Option<f64>,
    /// The static reference on this mesh at 0.3 mm, mN; its deepest penetration (mm) and its
    /// equilibrium residual `|Σ reactions − F| / |F|`.
    pub reference_mn: f64,
    pub reference_penetration_mm: f64,
    pub reference_equilibrium: f64,
    /// lop against the same-mesh reference and against Hertz, relative.
    pub error_same: Option<f64>,
    pub error_hertz: Option<f64>,
    /// Hold at 0.3 mm, vertical path and tilted path.
    pub hold_vertical: Option<HoldRow>,
    pub hold_tilted: Option<HoldRow>,
    /// Whether the presses reached 0.4 mm.
    pub reached: bool,
}

/// The hold's steadiness.
#[derive(Debug, Serialize)]
pub struct HoldRow {
    pub mean_mn: f64,
    pub depth_mm: f64,
    pub variation: f64,
    pub sideways: f64,
}

impl From<Hold> for HoldRow {
    fn from(h: Hold) -> HoldRow {
        HoldRow {
            mean_mn: h.mean * 1e3,
            depth_mm: h.depth * 1e3,
            variation: h.variation,
            sideways: h.sideways,
        }
    }
}

/// The static reference at one depth on one mesh.
#[derive(Debug, Serialize)]
pub struct ReferenceRow {
    pub mesh: String,
    pub depth_mm: f64,
    pub force_mn: f64,
    pub active_nodes: usize,
    pub iterations: usize,
    pub hertz_mn: f64,
    /// Hertz times the bonded-layer factor (Dimitriadis et al. 2002).
    pub hertz_layer_mn: f64,
}

/// One target.
#[derive(Debug, Serialize)]
pub struct Target {
    pub name: String,
    pub value: f64,
    pub limit: f64,
    pub pass: bool,
}

/// Runs part 1.
pub fn run(quick: bool, out: &Path) -> Result<Report> {
    let gmsh = block::gmsh_version().unwrap_or_else(|| "not found".into());
    let sizes: &[f64] = if quick {
        &[0.8e-3, 0.4e-3]
    } else {
        &[0.8e-3, 0.4e-3, 0.2e-3]
    };
    let converged = (!quick).then_some(0.1e-3);
    let depths: Vec<f64> = if quick {
        vec![0.1e-3, 0.2e-3, 0.3e-3, 0.4e-3]
    } else {
        (1..=8).map(|k| k as f64 * 0.05e-3).collect()
    };
    let material = Material {
        young: SETUP.young,
        poisson: SETUP.poisson,
    };
    let plan = PressPlan {
        tilt_deg: 0.0,
        // Quick: twice the speed and a shorter hold (0.5 s measured), so the smoke test's
        // four presses take 1.7 s of simulated time each instead of 3.
        speed: if quick { 0.5e-3 } else { 0.1e-3 },
        start_gap: 0.05e-3,
        hold_depth: COMPARE_DEPTH,
        hold: if quick { 0.7 } else { 1.2 },
        settle: 0.2,
        final_depth: MAX_DEPTH,
    };
    println!(
        "lop-bench haptics, part 1: transparency (gmsh {gmsh})\n\
         tool R {} mm, linear spring {} N/m; block 40 x 40 x 20 mm, E {} kPa, nu {}, linear FEM, \
         bottom clamped; press at {} mm/s, hold {} s at d = {} mm (first {} s not measured)\n",
        SETUP.radius * 1e3,
        SETUP.tool_stiffness,
        SETUP.young * 1e-3,
        SETUP.poisson,
        plan.speed * 1e3,
        plan.hold,
        COMPARE_DEPTH * 1e3,
        plan.settle
    );
    let cache = block::cache_dir();
    let mut all_sizes: Vec<f64> = sizes.to_vec();
    all_sizes.extend(converged);
    let mut meshes = Vec::new();
    let mut reference_rows = Vec::new();
    let mut curves: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut presses: Vec<Option<(Press, Press)>> = Vec::new();
    let mut blocks = Vec::new();
    for &size in &all_sizes {
        let b = block::block(size, &cache)?;
        let t0 = Instant::now();
        let reference = ContactReference::new(
            &b.mesh,
            material,
            SETUP.radius,
            block::CONTACT,
            block::NORMAL,
            candidate_radius(SETUP.radius, MAX_DEPTH),
            0,
        )
        .with_context(|| format!("the reference on the {} mesh", b.label()))?;
        let setup_s = t0.elapsed().as_secs_f64();
        let mut curve = Vec::new();
        let mut at_compare = f64::NAN;
        let (mut penetration, mut equilibrium) = (f64::NAN, f64::NAN);
        for &d in &depths {
            let c = reference.solve(d, Penalty::Exact)?;
            curve.push((d * 1e3, c.force() * 1e3));
            if (d - COMPARE_DEPTH).abs() < 1e-9 {
                at_compare = c.force();
                penetration = c.penetration;
                equilibrium = reference.equilibrium_residual(&c);
            }
            reference_rows.push(ReferenceRow {
                mesh: b.label(),
                depth_mm: d * 1e3,
                force_mn: c.force() * 1e3,
                active_nodes: c.active,
                iterations: c.iterations,
                hertz_mn: hertz(d) * 1e3,
                hertz_layer_mn: hertz_layer(d) * 1e3,
            });
        }
        curves.push(curve);
        let pressed = sizes.contains(&size);
        let runs = if pressed {
            let vertical = press(&b, &SETUP, &plan)?;
            let tilted = press(
                &b,
                &SETUP,
                &PressPlan {
                    tilt_deg: TILT_DEG,
                    ..plan
                },
            )?;
            write_press_csv(out, &b, "vertical", &vertical)?;
            write_press_csv(out, &b, "tilted", &tilted)?;
            Some((vertical, tilted))
        } else {
            None
        };
        let lop = runs
            .as_ref()
            .map(|(v, _)| v.hold.mean_z)
            .filter(|f| f.is_finite());
        let moving = runs.as_ref().and_then(|(v, _)| v.force_at(COMPARE_DEPTH));
        meshes.push(MeshRow {
            key: format!("block_{}mm", block::size_mm(size)),
            size_mm: size * 1e3,
            edge_mm: b.edge_at_contact * 1e3,
            nodes: b.mesh.nodes.len(),
            tets: b.mesh.tets.len(),
            pressed,
            dofs: reference.stiffness().n_dof(),
            factor_nnz: reference.stiffness().nnz.1,
            candidates: reference.candidates(),
            reference_setup_s: setup_s,
            lop_mn: lop.map(|f| f * 1e3),
            lop_moving_mn: moving.map(|f| f * 1e3),
            reference_mn: at_compare * 1e3,
            reference_penetration_mm: penetration * 1e3,
            reference_equilibrium: equilibrium,
            error_same: lop.map(|f| f / at_compare - 1.0),
            error_hertz: lop.map(|f| f / hertz(COMPARE_DEPTH) - 1.0),
            hold_vertical: runs.as_ref().map(|(v, _)| v.hold.into()),
            hold_tilted: runs.as_ref().map(|(_, t)| t.hold.into()),
            reached: runs.as_ref().is_some_and(|(v, t)| v.reached && t.reached),
        });
        presses.push(runs);
        blocks.push(b);
    }
    let targets = targets(&meshes);
    print_tables(&meshes, &reference_rows, &depths, &all_sizes, &targets);
    write_reference_csv(out, &reference_rows)?;
    plot_force(out, &blocks, &curves, &presses, converged.is_some())?;
    plot_error(out, &meshes)?;
    println!(
        "\nwrote {0}/reference.csv, {0}/press_*.csv, {0}/force_vs_depth.svg, {0}/error_vs_mesh.svg",
        out.display()
    );
    Ok(Report {
        gmsh,
        meshes,
        reference: reference_rows,
        targets,
    })
}

fn hertz(d: f64) -> f64 {
    hertz_force(SETUP.young, SETUP.poisson, SETUP.radius, d)
}

fn hertz_layer(d: f64) -> f64 {
    hertz(d) * bonded_layer_factor(SETUP.poisson, SETUP.radius, d, block::HEIGHT)
}

fn targets(meshes: &[MeshRow]) -> Vec<Target> {
    let mut out = Vec::new();
    let pressed: Vec<&MeshRow> = meshes.iter().filter(|m| m.pressed).collect();
    let target = |name: String, value: f64, limit: f64| Target {
        name,
        value,
        limit,
        // NaN (no figure) fails.
        pass: value <= limit,
    };
    for m in &pressed {
        out.push(target(
            format!("{}: |lop / same-mesh reference − 1| at 0.3 mm", m.key),
            m.error_same.map_or(f64::NAN, f64::abs),
            SAME_MESH_LIMIT,
        ));
    }
    let forces: Vec<f64> = pressed
        .iter()
        .map(|m| m.lop_mn.unwrap_or(f64::NAN))
        .collect();
    let max = forces.iter().copied().fold(f64::MIN, f64::max);
    let min = forces.iter().copied().fold(f64::MAX, f64::min);
    let spread = if forces.iter().all(|f| f.is_finite() && *f > 0.0) {
        max / min - 1.0
    } else {
        f64::NAN
    };
    out.push(target(
        "spread across meshes at 0.3 mm (max/min − 1)".into(),
        spread,
        SPREAD_LIMIT,
    ));
    if let Some(finest) = pressed.last() {
        out.push(target(
            format!("{}: |lop / Hertz − 1| at 0.3 mm", finest.key),
            finest.error_hertz.map_or(f64::NAN, f64::abs),
            HERTZ_LIMIT,
        ));
    }
    for m in &pressed {
        for (path, hold) in [("vertical", &m.hold_vertical), ("tilted", &m.hold_tilted)] {
            let Some(h) = hold else { continue };
            out.push(target(
                format!("{}: hold variation (max−min)/mean, {path}", m.key),
                h.variation,
                HOLD_VARIATION_LIMIT,
            ));
            out.push(target(
                format!("{}: hold sideways max |F_xy|/|F|, {path}", m.key),
                h.sideways,
                SIDEWAYS_LIMIT,
            ));
        }
    }
    out
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.filter(|v| v.is_finite())
        .map_or("-".into(), |v| format!("{v:.digits$}"))
}

fn pct(v: Option<f64>) -> String {
    v.filter(|v| v.is_finite())
        .map_or("-".into(), |v| format!("{:+.1} %", v * 100.0))
}

fn print_tables(
    meshes: &[MeshRow],
    reference: &[ReferenceRow],
    depths: &[f64],
    sizes: &[f64],
    targets: &[Target],
) {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Meshes (gmsh, graded) and the static FE contact reference on them (exact multipliers; \
         cand: candidate nodes; pen: deepest penetration at 0.3 mm; equil: |sum of reactions - F|/|F|)"
    );
    let _ = writeln!(
        s,
        "{:<14} {:>8} {:>7} {:>7} {:>7} {:>9} {:>6} {:>8} {:>10} {:>9}",
        "mesh",
        "edge mm",
        "nodes",
        "tets",
        "dofs",
        "L nnz",
        "cand",
        "setup s",
        "pen@0.3 m",
        "equil"
    );
    for m in meshes {
        let _ = writeln!(
            s,
            "{:<14} {:>8.3} {:>7} {:>7} {:>7} {:>9} {:>6} {:>8.1} {:>10.1e} {:>9.1e}",
            m.key,
            m.edge_mm,
            m.nodes,
            m.tets,
            m.dofs,
            m.factor_nnz,
            m.candidates,
            m.reference_setup_s,
            m.reference_penetration_mm * 1e-3,
            m.reference_equilibrium
        );
    }
    let _ = writeln!(
        s,
        "\nStatic reference F(d), mN (Hertz: half-space; ×layer: bonded 20 mm layer)"
    );
    let mut head = format!("{:>7} {:>8} {:>8}", "d mm", "Hertz", "×layer");
    for &size in sizes {
        head += &format!(" {:>9}", format!("ref {}", block::size_mm(size)));
    }
    head += &format!(" {:>11}", "finest/Hz");
    let _ = writeln!(s, "{head}");
    for &d in depths {
        let rows: Vec<&ReferenceRow> = reference
            .iter()
            .filter(|r| (r.depth_mm - d * 1e3).abs() < 1e-9)
            .collect();
        let Some(first) = rows.first() else { continue };
        let mut line = format!(
            "{:>7.2} {:>8.2} {:>8.2}",
            d * 1e3,
            first.hertz_mn,
            first.hertz_layer_mn
        );
        for r in &rows {
            line += &format!(" {:>9.2}", r.force_mn);
        }
        let finest = rows.last().map_or(f64::NAN, |r| r.force_mn / r.hertz_mn);
        line += &format!(" {:>11.3}", finest);
        let _ = writeln!(s, "{line}");
    }
    let _ = writeln!(
        s,
        "\nForce on the hand through lop at d = {} mm, mN: held still (static), and while \
         descending at the press speed (the god-object lags the device by a tick: + k v dt)",
        COMPARE_DEPTH * 1e3
    );
    let _ = writeln!(
        s,
        "{:<14} {:>9} {:>9} {:>9} {:>10} {:>9} {:>10}",
        "mesh", "lop held", "moving", "ref same", "vs same", "Hertz", "vs Hertz"
    );
    for m in meshes.iter().filter(|m| m.pressed) {
        let _ = writeln!(
            s,
            "{:<14} {:>9} {:>9} {:>9.2} {:>10} {:>9.2} {:>10}",
            m.key,
            opt(m.lop_mn, 3),
            opt(m.lop_moving_mn, 3),
            m.reference_mn,
            pct(m.error_same),
            hertz(COMPARE_DEPTH) * 1e3,
            pct(m.error_hertz)
        );
    }
    let _ = writeln!(
        s,
        "\nHold at d ≈ {} mm (measured part of the hold)",
        COMPARE_DEPTH * 1e3
    );
    let _ = writeln!(
        s,
        "{:<14} {:<9} {:>9} {:>8} {:>11} {:>10} {:>8}",
        "mesh", "path", "mean mN", "d mm", "variation", "sideways", "reached"
    );
    for m in meshes.iter().filter(|m| m.pressed) {
        for (path, h) in [("vertical", &m.hold_vertical), ("tilt 5°", &m.hold_tilted)] {
            let Some(h) = h else { continue };
            let _ = writeln!(
                s,
                "{:<14} {:<9} {:>9.2} {:>8.3} {:>9.1} % {:>8.1} % {:>8}",
                m.key,
                path,
                h.mean_mn,
                h.depth_mm,
                h.variation * 100.0,
                h.sideways * 100.0,
                if m.reached { "yes" } else { "NO" }
            );
        }
    }
    let _ = writeln!(s, "\nTargets");
    for t in targets {
        let _ = writeln!(
            s,
            "  {:<4} {:<62} {:>9} (limit {:.0} %)",
            if t.pass { "PASS" } else { "FAIL" },
            t.name,
            if t.value.is_finite() {
                format!("{:.1} %", t.value * 100.0)
            } else {
                "-".into()
            },
            t.limit * 100.0
        );
    }
    print!("{s}");
}

fn write_press_csv(out: &Path, b: &Block, path: &str, p: &Press) -> Result<()> {
    let file = out.join(format!("press_{}mm_{path}.csv", block::size_mm(b.size)));
    let mut text = String::from("t_s,depth_mm,fx_mn,fy_mn,fz_mn,phase\n");
    for s in &p.samples {
        let _ = writeln!(
            text,
            "{:.4},{:.6},{:.5},{:.5},{:.5},{}",
            s.t,
            s.depth * 1e3,
            s.force[0] * 1e3,
            s.force[1] * 1e3,
            s.force[2] * 1e3,
            match s.phase {
                Phase::Descend => "descend",
                Phase::Hold => "hold",
                Phase::Deeper => "deeper",
            }
        );
    }
    std::fs::write(&file, text).with_context(|| format!("writing {}", file.display()))
}

fn write_reference_csv(out: &Path, rows: &[ReferenceRow]) -> Result<()> {
    let file = out.join("reference.csv");
    let mut text =
        String::from("mesh,depth_mm,force_mn,active_nodes,iterations,hertz_mn,hertz_layer_mn\n");
    for r in rows {
        let _ = writeln!(
            text,
            "{},{:.3},{:.5},{},{},{:.5},{:.5}",
            r.mesh,
            r.depth_mm,
            r.force_mn,
            r.active_nodes,
            r.iterations,
            r.hertz_mn,
            r.hertz_layer_mn
        );
    }
    std::fs::write(&file, text).with_context(|| format!("writing {}", file.display()))
}

/// One panel per pressed mesh: lop's descent, the same-mesh reference, the converged one,
/// Hertz.
fn plot_force(
    out: &Path,
    blocks: &[Block],
    curves: &[Vec<(f64, f64)>],
    presses: &[Option<(Press, Press)>],
    has_converged: bool,
) -> Result<()> {
    let depths: Vec<f64> = (0..=40).map(|k| k as f64 * 0.01).collect();
    let hertz_line: Vec<(f64, f64)> = depths.iter().map(|&d| (d, hertz(d * 1e-3) * 1e3)).collect();
    let y_max = curves
        .iter()
        .flatten()
        .map(|p| p.1)
        .fold(hertz(MAX_DEPTH) * 1e3, f64::max)
        * 1.4;
    let mut panels = Vec::new();
    for (i, b) in blocks.iter().enumerate() {
        let Some((vertical, _)) = &presses[i] else {
            continue;
        };
        let lop: Vec<(f64, f64)> = vertical
            .samples
            .iter()
            .filter(|s| s.phase != Phase::Hold && s.depth > 0.0)
            .map(|s| (s.depth * 1e3, s.force[2] * 1e3))
            .collect();
        let mut series = vec![
            Series {
                label: "lop (god-object, vertical press)".into(),
                points: lop,
                color: 0,
            },
            Series {
                label: "static FE reference, same mesh".into(),
                points: curves[i].clone(),
                color: 1,
            },
        ];
        if has_converged {
            series.push(Series {
                label: format!(
                    "static FE reference, {}",
                    blocks.last().map_or(String::new(), Block::label)
                ),
                points: curves.last().cloned().unwrap_or_default(),
                color: 2,
            });
        }
        series.push(Series {
            label: "Hertz (half-space)".into(),
            points: hertz_line.clone(),
            color: 4,
        });
        panels.push(Panel {
            title: format!(
                "{} mesh (edge {:.2} mm)",
                b.label(),
                b.edge_at_contact * 1e3
            ),
            x_desc: "indentation d, mm".into(),
            y_desc: "force, mN".into(),
            x_range: (0.0, MAX_DEPTH * 1e3),
            y_range: (0.0, y_max),
            series,
        });
    }
    let cols = panels.len().min(3);
    plot::line_grid(
        &out.join("force_vs_depth.svg"),
        "Tool force vs indentation: lop against the static references",
        &panels,
        cols,
        (520, 400),
    )
}

/// Relative error at 0.3 mm against the edge length at the contact.
fn plot_error(out: &Path, meshes: &[MeshRow]) -> Result<()> {
    let pressed: Vec<&MeshRow> = meshes.iter().filter(|m| m.pressed).collect();
    let points = |f: &dyn Fn(&MeshRow) -> Option<f64>| -> Vec<(f64, f64)> {
        let mut p: Vec<(f64, f64)> = pressed
            .iter()
            .filter_map(|m| f(m).map(|e| (m.edge_mm, e * 100.0)))
            .collect();
        p.sort_by(|a, b| a.0.total_cmp(&b.0));
        p
    };
    let finest_ref = meshes.last().map_or(f64::NAN, |m| m.reference_mn);
    let series = vec![
        Series {
            label: "lop vs same-mesh reference".into(),
            points: points(&|m| m.error_same),
            color: 0,
        },
        Series {
            label: "lop vs Hertz".into(),
            points: points(&|m| m.error_hertz),
            color: 4,
        },
        Series {
            label: "same-mesh reference vs finest reference".into(),
            points: points(&|m| Some(m.reference_mn / finest_ref - 1.0)),
            color: 1,
        },
    ];
    let all: Vec<f64> = series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1))
        .collect();
    let lo = all.iter().copied().fold(-25.0, f64::min);
    let hi = all.iter().copied().fold(25.0, f64::max);
    let x_hi = pressed.iter().map(|m| m.edge_mm).fold(0.0, f64::max) * 1.1;
    plot::line_grid(
        &out.join("error_vs_mesh.svg"),
        "Force error at d = 0.3 mm against the mesh size at the contact",
        &[Panel {
            title: "relative error, %".into(),
            x_desc: "edge length at the contact, mm".into(),
            y_desc: "error, %".into(),
            x_range: (0.0, x_hi),
            y_range: (lo - 10.0, hi + 0.3 * (hi - lo)),
            series,
        }],
        1,
        (640, 440),
    )
}
