//! Output of part 1 of `lop-bench lop`: the per-run CSV files, the figures (SVG) and the
//! text tables of the efficiency trials.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::Result;

use super::super::{kind_label, quantile_sorted, write_file};
use super::{Detection, RunRow, Sample, Trace, Trial, PROPAGATED_M, TRIALS};
use crate::models::us;
use crate::plot::{self, Panel, Series};
use crate::table::{table, Align};

pub(super) fn write_csv(path: &Path, row: &RunRow, samples: &[Sample]) -> Result<()> {
    let mut s = String::from("iteration,body,time_s,model,step_us\n");
    for x in samples {
        let _ = writeln!(
            s,
            "{},{},{:.6},{},{:.3}",
            x.iteration,
            row.bodies[x.body].body,
            x.time,
            kind_label(x.kind),
            x.us
        );
    }
    write_file(path, &s)
}

pub(super) fn write_detection_csv(path: &Path, detections: &[Detection]) -> Result<()> {
    let mut s = String::from("round,time_s,detect_us,penetrations,max_depth_mm,tree_builds\n");
    for d in detections {
        let _ = writeln!(
            s,
            "{},{:.6},{:.3},{},{:.4},{}",
            d.round,
            d.time,
            d.us,
            d.penetrations,
            d.max_depth * 1e3,
            d.tree_builds
        );
    }
    write_file(path, &s)
}

/// Colour of the collision detection's line.
const DETECTION_COLOR: usize = 4;

/// Colour of body `i` (the same in every plot of a scene).
fn body_color(i: usize) -> usize {
    [1, 5, 2, 3, 0, 6][i % 6]
}

pub(super) fn write_svg(path: &Path, trial: &Trial, traces: &[(RunRow, Trace)]) -> Result<()> {
    // One y scale per configuration (the row of panels: without GC | with GC), so the saving
    // is visible at a glance; set by the largest 99.9th percentile of the row, not its single
    // largest step (one preempted step would flatten every line). Steps above it are drawn at
    // the top edge.
    let mut panels = Vec::new();
    for pair in traces.chunks(2) {
        let mut top: f64 = 0.0;
        for (row, trace) in pair {
            for i in 0..row.bodies.len() {
                let mut v: Vec<f64> = trace
                    .samples
                    .iter()
                    .filter(|s| s.body == i)
                    .map(|s| s.us / 1e3)
                    .collect();
                v.sort_by(f64::total_cmp);
                top = top.max(quantile_sorted(&v, 0.999));
            }
        }
        // Headroom for the legend (upper left).
        let top = if top > 0.0 { top * 1.6 } else { 1.0 };
        for (row, trace) in pair {
            let samples = &trace.samples;
            let mut series: Vec<Series> = row
                .bodies
                .iter()
                .enumerate()
                .map(|(i, b)| Series {
                    label: format!(
                        "{} ({}{})",
                        b.body,
                        b.precise,
                        if row.with_gc { " / GC" } else { "" }
                    ),
                    points: samples
                        .iter()
                        .filter(|s| s.body == i)
                        .map(|s| (s.iteration as f64, (s.us / 1e3).min(top)))
                        .collect(),
                    color: body_color(i),
                })
                .collect();
            // The detection, once per round (x = round: the bodies' iteration when they step
            // every tick, as the cylinders do).
            if row.collision.is_some() {
                series.push(Series {
                    label: "collision detection (per round)".into(),
                    points: trace
                        .detections
                        .iter()
                        .map(|d| (d.round as f64, (d.us / 1e3).min(top)))
                        .collect(),
                    color: DETECTION_COLOR,
                });
            }
            let steps = row.bodies.iter().map(|b| b.steps).max().unwrap_or(1);
            panels.push(Panel {
                title: format!(
                    "{}, {}",
                    row.configuration,
                    if row.with_gc { "with GC" } else { "without GC" }
                ),
                x_desc: "iteration".into(),
                y_desc: "ms per step".into(),
                x_range: (0.0, steps as f64),
                y_range: (0.0, top),
                series,
            });
        }
    }
    plot::line_grid(
        path,
        &format!(
            "{} analogue: {}, {} — time per iteration per body (left: without GC, right: with GC)",
            trial.thesis, trial.scene, trial.name
        ),
        &panels,
        2,
        (560, 300),
    )
}

fn opt_us(v: Option<f64>) -> String {
    v.map_or("-".into(), us)
}

/// Part 1's tables for stdout.
pub fn render(rows: &[RunRow]) -> String {
    let mut s = String::from(
        "Part 1: efficiency, time per iteration per body (every body step of World::round timed, \
         no warm-up; organ-to-organ collision detection timed on its own), µs\n",
    );
    for trial in &TRIALS {
        let mine: Vec<&RunRow> = rows
            .iter()
            .filter(|r| r.scene == trial.scene && r.trial == trial.name)
            .collect();
        let Some(first) = mine.first() else {
            continue;
        };
        let _ = writeln!(
            s,
            "\n{} / {} ({}): {:.1} s simulated, tick {} s{}{}{}",
            trial.scene,
            trial.name,
            trial.thesis,
            first.simulated_s,
            first.tick_s,
            match &first.script {
                Some(p) => format!(
                    ", tool from {}{}",
                    Path::new(p)
                        .file_name()
                        .map_or(p.clone(), |f| f.to_string_lossy().into_owned()),
                    if first.script_offset_s > 0.0 {
                        format!(" started at {} s", first.script_offset_s)
                    } else {
                        String::new()
                    }
                ),
                None => ", no tool".into(),
            },
            match mine
                .iter()
                .find(|r| r.with_gc)
                .and_then(|r| r.start_level.clone())
            {
                Some(l) => format!("; with GC the bodies start at {l}"),
                None => String::new(),
            },
            match &first.collision {
                Some(c) => format!(
                    "; collision on (springs {} N/m, skin {} mm, depth limit {} mm), detected \
                     once per round",
                    c.stiffness_n_per_m, c.skin_mm, c.depth_limit_mm
                ),
                None => "; collision off".into(),
            }
        );
        let mut cells = Vec::new();
        for r in &mine {
            for b in &r.bodies {
                let log: Vec<String> = b
                    .switch_log
                    .iter()
                    .map(|w| format!("{:.2}s {}>{}", w.time_s, w.from, w.to))
                    .collect();
                let mut row = vec![
                    format!(
                        "{}, {}",
                        r.configuration,
                        if r.with_gc { "GC" } else { "no GC" }
                    ),
                    b.body.clone(),
                    b.precise.clone(),
                    b.steps.to_string(),
                    opt_us(b.median_gc_us),
                    opt_us(b.median_precise_us),
                    us(b.mean_us),
                    format!("{:.0} %", 100.0 * b.gc_share),
                    b.switches.to_string(),
                    b.final_model.clone(),
                    b.resets.to_string(),
                    log.join(", "),
                ];
                if trial.collision {
                    row.insert(7, b.colliding_steps.to_string());
                    row.insert(8, opt_us(b.median_colliding_us));
                }
                cells.push(row);
            }
        }
        let mut columns = vec![
            ("configuration", Align::Left),
            ("body", Align::Left),
            ("precise", Align::Left),
            ("steps", Align::Right),
            ("GC median", Align::Right),
            ("precise median", Align::Right),
            ("mean", Align::Right),
            ("on GC", Align::Right),
            ("switches", Align::Right),
            ("final", Align::Left),
            ("resets", Align::Right),
            ("switch log", Align::Left),
        ];
        if trial.collision {
            columns.insert(7, ("colliding", Align::Right));
            columns.insert(8, ("colliding median", Align::Right));
        }
        s += &table(&columns, &cells);
        if trial.collision {
            s += &render_collision(trial, &mine);
        }
    }
    s
}

/// The collision trial's second table: the detection's cost per round and whether the push
/// reached the other body.
fn render_collision(trial: &Trial, runs: &[&RunRow]) -> String {
    let pushed = trial.pushed.unwrap_or("-");
    let mut s = String::from(
        "Collision detection: once per World::round, timed on its own (not in \
         the step times above), µs.\n\
         \x20 median: over all rounds / the rounds in contact (a penetrating vertex found) / \
         apart; the first detection builds the trees\n\
         \x20 of compute: share of the run's detections + steps; contact: rounds in contact; \
         max depth: mm, counts the skin\n",
    );
    let _ = writeln!(
        s,
        "  the push: max +x = largest displacement of any node along +x, mm; control = \
         {pushed}'s max +x in the same run without collision\n\
         \x20 force: largest x component of the contact springs' total force on {pushed}, mN; \
         control depth: deepest vertex of one cylinder\n\
         \x20 inside the other without collision, mm; moved: {pushed} went at least {} mm \
         farther along +x than in the control",
        PROPAGATED_M * 1e3
    );
    let mut cells = Vec::new();
    let mut failed = Vec::new();
    for r in runs {
        let Some(c) = &r.collision else {
            continue;
        };
        let disp = |name: &str| {
            r.bodies
                .iter()
                .find(|b| b.body == name)
                .map_or("-".into(), |b| format!("{:.2}", b.max_dx_mm))
        };
        let other = r
            .bodies
            .iter()
            .find(|b| b.body != pushed)
            .map_or("-", |b| b.body.as_str());
        let moved = r.bodies.iter().find(|b| b.body == pushed);
        if !c.propagated {
            failed.push(r.key.clone());
        }
        cells.push(vec![
            format!(
                "{}, {}",
                r.configuration,
                if r.with_gc { "GC" } else { "no GC" }
            ),
            c.detections.to_string(),
            us(c.median_us),
            opt_us(c.median_contact_us),
            opt_us(c.median_apart_us),
            us(c.mean_us),
            us(c.p99_us),
            us(c.max_us),
            format!("{:.1} %", c.share_pct),
            c.contact_detections.to_string(),
            c.max_penetrations.to_string(),
            format!("{:.2}", c.max_depth_mm),
            disp(other),
            disp(pushed),
            c.control_pushed_max_dx_mm
                .map_or("-".into(), |v| format!("{v:.2}")),
            moved.map_or("-".into(), |b| format!("{:.1}", b.max_contact_force_x_mn)),
            c.control_max_interpenetration_mm
                .map_or("-".into(), |v| format!("{v:.1}")),
            if c.propagated { "yes" } else { "NO" }.into(),
        ]);
    }
    s += &table(
        &[
            ("configuration", Align::Left),
            ("detections", Align::Right),
            ("median", Align::Right),
            ("in contact", Align::Right),
            ("apart", Align::Right),
            ("mean", Align::Right),
            ("p99", Align::Right),
            ("max", Align::Right),
            ("of compute", Align::Right),
            ("contact", Align::Right),
            ("max vertices", Align::Right),
            ("max depth mm", Align::Right),
            ("pusher max +x", Align::Right),
            ("pushed max +x", Align::Right),
            ("control", Align::Right),
            ("force mN", Align::Right),
            ("control depth", Align::Right),
            ("moved", Align::Left),
        ],
        &cells,
    );
    if !failed.is_empty() {
        let _ = writeln!(
            s,
            "WARNING: the push did not move {pushed} ({} mm or more farther along +x than without \
             collision) in: {}",
            PROPAGATED_M * 1e3,
            failed.join(", ")
        );
    }
    s
}
