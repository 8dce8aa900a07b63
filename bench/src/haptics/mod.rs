//! `lop-bench haptics`: what the hand feels, measured against what it should feel.
//!
//! Part 1, **transparency** (`transparency.rs`): a 3 mm tool pressed into a clamped
//! 40 × 40 × 20 mm block (E 30 kPa, ν 0.3, linear FEM, tool spring 600 N/m) on graded meshes of
//! 0.8, 0.4 and 0.2 mm at the contact (`block.rs`, generated with gmsh). The force lop renders
//! (`press.rs`: the offline god-object and `World::round`, as the daemon runs them) against an
//! independent static FE contact reference on the same mesh and on a finer one
//! (`reference.rs`) and against Hertz (`hertz.rs`); then the force's steadiness while the hand
//! holds still. Targets: within 10 % of the same-mesh reference, the meshes within 15 % of each
//! other, the finest within 20 % of Hertz; hold variation ≤ 5 %, sideways part < 10 %.
//!
//! Part 2, **the liver** (`liver.rs`): the same press on the `abdomen` scene's liver as
//! `lop_scene` builds it (555 nodes, 13 mm surface edges at the contact, the posterior patch
//! fixed, E 4.1 kPa, ν 0.45), alone and as linear FEM (the scene runs it corotational; the
//! reference is linear), with the scene's tool (R 3 mm, 300 N/m): at the poke script's target
//! along the inward normal, held at 0.5–3 mm (`--quick`: 1 and 3 mm), against the reference on
//! the same mesh — there a curved surface, and the sphere resting on faces, not only on the
//! node (`reference.rs`: face samples). Target: within 10 % at every hold.
//!
//! Part 3, **stability** (`stability.rs`): the simulated hand presses the liver through the
//! closed loop (`lop_scene::closed_loop`) across tool stiffness (up to four times the device's
//! nominal maximum) × tissue (1–100 kPa) × two hands × the passivity controller off and on:
//! the force's oscillation after contact onset and the energy at the device port. Targets: on
//! the default scene at the device's maximum the oscillation is within 2 % of the held force
//! within 100 ms and the cycle generates no energy; with the default hand no run up to the
//! device's maximum generates any.
//!
//! Part 4, **the pinch** (`pinch.rs`): two simulated hands, each on its own tool and device,
//! squeeze a free soft cube from opposite sides through the closed loop of several tools
//! (`lop_scene::closed_loop::run_tools`): press, hold, withdraw, across the two hands. Per hand
//! the held force and the energy at its device port; per pinch the balance of the two forces.
//! Targets: every hand in contact through the hold, `|F_left + F_right| / |F|` within 1 % over
//! it, and no energy generated at a firm-grip hand's device port.

// `!(x > 0.0)` is how a check is written so that NaN fails it (as in lop-sim); 3×3 blocks read
// best as index loops.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::needless_range_loop)]

pub(crate) mod block;
mod hertz;
mod liver;
mod pinch;
mod press;
mod reference;
pub(crate) mod stability;
mod transparency;

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use serde::Serialize;

/// Options of `lop-bench haptics`.
#[derive(Args, Debug)]
pub struct HapticsArgs {
    /// Small and fast (for the smoke test): the 0.8 and 0.4 mm meshes, four reference depths, no
    /// converged reference; the liver held at 1 and 3 mm only; two pinches, no hand alone.
    #[arg(long)]
    quick: bool,
    /// Where the CSV and SVG files go (created if missing).
    #[arg(long, default_value = "target/lop-bench/haptics")]
    out: PathBuf,
    /// Also write every number as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Only part 3, the stability map (about a minute; with `--quick`, seconds).
    #[arg(long, conflicts_with = "pinch_only")]
    stability_only: bool,
    /// Only part 4, the bimanual pinch (seconds).
    #[arg(long)]
    pinch_only: bool,
}

/// Everything `--json` writes: part 1's figures at the top level, part 2's under `liver`,
/// part 3's under `stability`, part 4's under `pinch` (with `--stability-only` or
/// `--pinch-only`, only that part).
#[derive(Debug, Serialize)]
struct Report {
    #[serde(flatten)]
    transparency: Option<transparency::Report>,
    #[serde(skip_serializing_if = "Option::is_none")]
    liver: Option<liver::LiverReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    stability: Option<stability::StabilityReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pinch: Option<pinch::PinchReport>,
}

/// Runs the benchmark.
pub fn run(a: HapticsArgs) -> Result<()> {
    let clock = Instant::now();
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let report = if a.stability_only {
        Report {
            transparency: None,
            liver: None,
            stability: Some(stability::run_map(a.quick, &a.out)?),
            pinch: None,
        }
    } else if a.pinch_only {
        Report {
            transparency: None,
            liver: None,
            stability: None,
            pinch: Some(pinch::run(a.quick, &a.out)?),
        }
    } else {
        Report {
            transparency: Some(transparency::run(a.quick, &a.out)?),
            liver: Some(liver::run(a.quick, &a.out)?),
            stability: Some(stability::run_map(a.quick, &a.out)?),
            pinch: Some(pinch::run(a.quick, &a.out)?),
        }
    };
    println!(
        "\nlop-bench haptics{} took {:.1} s",
        if a.quick { " --quick" } else { "" },
        clock.elapsed().as_secs_f64()
    );
    if let Some(path) = a.json {
        let body = serde_json::to_string_pretty(&report)?;
        std::fs::write(&path, body).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}
