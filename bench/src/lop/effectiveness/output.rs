//! Output of part 3 of `lop-bench lop`: the per-case CSV files, the figure panels (SVG), the
//! text tables and the accuracy targets of the effectiveness study.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;

use lop_sim::lop::CageShape;

use super::super::{shape_label, write_file, DynKind, Target, SHAPES};
use super::{
    variant_names, CaseReport, Reference, Runner, VariantRow, CALIBRATION_DIRECTION,
    CALIBRATION_FORCE_FACTOR, TARGET_BOX_MS_FEM, TARGET_BOX_MS_MSD, TARGET_PROJECTED_FEM,
};
use crate::plot::{Panel, Series};
use crate::table::{table, Align};

pub(super) fn write_csv(path: &Path, dt: f64, disp: &[f64], runners: &[Runner]) -> Result<()> {
    let mut s = String::from("iteration,time_s,reference_displacement_max_pct");
    for r in runners {
        let k = r.row.variant.replace('-', "_");
        let _ = write!(s, ",{k}_mean_pct,{k}_max_pct");
    }
    s.push('\n');
    for (n, d) in disp.iter().enumerate() {
        let _ = write!(s, "{n},{:.6},{d:.6}", n as f64 * dt);
        for r in runners {
            let _ = write!(s, ",{:.6},{:.6}", r.mean[n], r.max[n]);
        }
        s.push('\n');
    }
    write_file(path, &s)
}

/// Colour of an approximation: one per cage shape, the mass-spring line one step along.
fn variant_color(row: &VariantRow) -> usize {
    match (row.shape.as_deref(), row.dynamics.as_deref()) {
        (Some("box"), Some("projected")) => 1,
        (Some("box"), _) => 3,
        (Some("fitted"), Some("projected")) => 2,
        (Some("fitted"), _) => 5,
        (Some(_), Some("projected")) => 6,
        (Some(_), _) => 7,
        (None, _) => 4,
    }
}

pub(super) fn panel(
    reference: Reference,
    dt: f64,
    disp: &[f64],
    runners: &[Runner],
    seconds: f64,
) -> Panel {
    let mut top: f64 = disp.iter().copied().fold(0.0, f64::max);
    for r in runners {
        top = top.max(r.row.max_error_pct);
    }
    // Headroom for the legend (upper left).
    let top = if top > 0.0 { top * 1.8 } else { 1.0 };
    // The plot keeps to the default and the thesis' dynamics (the Galerkin and best-fit rows
    // are in the CSV and the table).
    let series = runners
        .iter()
        .filter(|r| {
            matches!(
                r.row.dynamics.as_deref(),
                None | Some("projected" | "mass-spring")
            )
        })
        .map(|r| Series {
            label: if r.row.blow_ups > 0 {
                format!("{} ({} blow-ups)", r.row.label, r.row.blow_ups)
            } else {
                r.row.label.clone()
            },
            points: r
                .max
                .iter()
                .enumerate()
                .map(|(n, &v)| (n as f64 * dt, v.min(top)))
                .collect(),
            color: variant_color(&r.row),
        })
        .collect();
    Panel {
        title: format!(
            "GC vs {} (the rest shape's error = its displacement)",
            reference.label()
        ),
        x_desc: "time (s)".into(),
        y_desc: "max error (% of smallest dimension)".into(),
        x_range: (0.0, seconds),
        y_range: (0.0, top),
        series,
    }
}

/// Part 3's tables for stdout.
pub fn render(reports: &[CaseReport]) -> String {
    let mut s = String::from(
        "Part 3: effectiveness, GC approximation error (per iteration over all nodes: |x_gc - \
         x_ref|, % of the body's smallest rest extent)\n",
    );
    for c in reports {
        let _ = writeln!(
            s,
            "\n{} ({}): {} nodes, {} tets, smallest extent {:.1} mm, gravity {:?}; a load along \
             {:?} on {} surface nodes (-x side, upper half), ramped over {} s, released at {} s, \
             {} s simulated",
            c.body,
            c.scene,
            c.nodes,
            c.tets,
            c.smallest_extent_m * 1e3,
            c.gravity,
            c.load_direction,
            c.loaded_nodes,
            c.ramp_end_s,
            c.hold_end_s,
            c.simulated_s
        );
        for r in &c.references {
            let _ = writeln!(
                s,
                "\nvs {} (dt {} s, {} steps, load {} N): reference max displacement {:.2} mm = \
                 {:.2} % (at the end of the hold {:.2} mm, at the end {:.2} mm){}",
                r.label,
                r.dt,
                r.steps,
                r.total_force_n,
                r.max_displacement_mm,
                r.max_displacement_pct,
                r.hold_end_displacement_mm,
                r.final_displacement_mm,
                if r.blow_ups > 0 {
                    format!("; {} BLOW-UPS", r.blow_ups)
                } else {
                    String::new()
                }
            );
            let cells: Vec<Vec<String>> = c
                .variants
                .iter()
                .filter(|v| v.reference == r.reference)
                .map(|v| {
                    vec![
                        v.label.clone(),
                        v.cage_vertices.map_or("-".into(), |n| n.to_string()),
                        format!("{:.2}", v.max_error_pct),
                        format!("{:.2}", v.max_error_at_s),
                        format!("{:.2}", v.max_error_relative),
                        format!("{:.2}", v.mean_error_pct),
                        format!("{:.2}", v.hold_end_max_error_pct),
                        format!("{:.2}", v.final_max_error_pct),
                        v.blow_ups.to_string(),
                    ]
                })
                .collect();
            s += &table(
                &[
                    ("approximation", Align::Left),
                    ("cage V", Align::Right),
                    ("max err %", Align::Right),
                    ("at s", Align::Right),
                    ("/ ref disp", Align::Right),
                    ("mean err %", Align::Right),
                    ("max at hold end %", Align::Right),
                    ("max at end %", Align::Right),
                    ("blow-ups", Align::Right),
                ],
                &cells,
            );
            for v in c.variants.iter().filter(|v| v.reference == r.reference) {
                if let Some(t) = &v.tuned {
                    let _ = writeln!(
                        s,
                        "{}: k {:.4} N/m, rho {:.4} kg/m^3, gamma {:.5} N s/m, found in {} runs \
                         on the calibration load ({:?}, {} x the force): max error {:.2} % \
                         there (table values {:.2} %)",
                        v.label,
                        t.stiffness,
                        t.density,
                        t.damping,
                        t.runs,
                        CALIBRATION_DIRECTION,
                        CALIBRATION_FORCE_FACTOR,
                        t.calibration_pct,
                        t.calibration_start_pct
                    );
                }
            }
        }
    }
    s
}

/// The error targets, on both bodies (the thesis measured the cylinder).
pub fn targets(reports: &[CaseReport]) -> Vec<Target> {
    let mut out = Vec::new();
    for c in reports {
        let find = |reference: &str, variant: &str| {
            c.variants
                .iter()
                .find(|v| v.reference == reference && v.variant == variant)
        };
        let (box_ms, _) = variant_names(CageShape::Box, DynKind::MassSpring);
        let thesis = [
            (
                "gc-box-mass-spring-tuned",
                "parameters searched (thesis' way)",
            ),
            (box_ms.as_str(), "Table 6.1/6.2 values"),
        ];
        for ((reference, limit), (variant, how)) in
            [("fem", TARGET_BOX_MS_FEM), ("msd", TARGET_BOX_MS_MSD)]
                .into_iter()
                .flat_map(|r| thesis.map(|t| (r, t)))
        {
            if let Some(v) = find(reference, variant) {
                out.push(Target {
                    target: format!(
                        "{}: box cage + mass-spring, {how}, vs {} max error ≤ {limit} %",
                        c.case,
                        reference.to_uppercase()
                    ),
                    measured: format!("{:.2} % (at {:.2} s)", v.max_error_pct, v.max_error_at_s),
                    value: v.max_error_pct,
                    limit,
                    met: v.max_error_pct <= limit,
                });
            }
        }
        for shape in SHAPES {
            let (variant, _) = variant_names(shape, DynKind::Projected);
            if let Some(v) = find("fem", &variant) {
                out.push(Target {
                    target: format!(
                        "{}: {} cage + projected vs FEM max error ≤ {TARGET_PROJECTED_FEM} %",
                        c.case,
                        shape_label(shape)
                    ),
                    measured: format!("{:.2} % (at {:.2} s)", v.max_error_pct, v.max_error_at_s),
                    value: v.max_error_pct,
                    limit: TARGET_PROJECTED_FEM,
                    met: v.max_error_pct <= TARGET_PROJECTED_FEM,
                });
            }
        }
    }
    out
}
