//! The press through lop: the block as one linear FEM body in a [`World`], the tool driven as
//! the daemon drives it — the offline god-object ([`WorldProbe`]) ticks against the current
//! shapes, then one [`World::round`] with the probe's coupling — and the force on the hand
//! taken from the god-object's state with the linear tool law ([`hand_force`]).
//!
//! The device descends quasi-statically along a path through the contact point (vertical, or
//! tilted in the x–z plane) until the proxy's indentation `d = (20 mm + R) − proxy_z` reaches
//! the hold depth, holds still for the hold time, then descends again to the final depth. The
//! proxy — not the device — sets the depth, so the device's travel adapts to each mesh's
//! compliance. One tick per millisecond, the FEM body on a 1 ms step (the body under the tool
//! runs at the haptic rate, as in `lopd`).

use anyhow::{Context, Result};
use lop_scene::session::RoundInput;
use lop_scene::{OfflineSession, ToolLaws};
use lop_sim::contact::{ForceLaw, ToolSphere};
use lop_sim::fem::{Fem, FemMode, FemParameters};
use lop_sim::haptic::hand_force;
use lop_sim::model::Model;
use lop_sim::world::World;

use super::block::{Block, CONTACT};

/// The block's material and the tool, as in the issue.
#[derive(Debug, Clone, Copy)]
pub struct Setup {
    /// Young's modulus, Pa.
    pub young: f64,
    /// Poisson's ratio.
    pub poisson: f64,
    /// Density, kg/m³.
    pub density: f64,
    /// Mass-proportional damping, 1/s.
    pub damping: f64,
    /// Tool radius, m.
    pub radius: f64,
    /// Tool spring (linear law), N/m.
    pub tool_stiffness: f64,
}

/// One press.
#[derive(Debug, Clone, Copy)]
pub struct PressPlan {
    /// Tilt of the device's path from the vertical (towards +x), degrees.
    pub tilt_deg: f64,
    /// Device speed along the path, m/s.
    pub speed: f64,
    /// Gap between the proxy and the surface at the start, m.
    pub start_gap: f64,
    /// Indentation at which the device holds still, m.
    pub hold_depth: f64,
    /// How long it holds, s; the first [`PressPlan::settle`] of it is not measured.
    pub hold: f64,
    /// Part of the hold left to settle, s.
    pub settle: f64,
    /// Indentation at which the press ends, m.
    pub final_depth: f64,
}

/// What the press does at a tick.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Descending to the hold depth.
    Descend,
    /// Holding still.
    Hold,
    /// Descending to the final depth.
    Deeper,
}

/// One tick of the press.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    /// Time, s.
    pub t: f64,
    /// Indentation of the proxy, m.
    pub depth: f64,
    /// Force on the hand, N.
    pub force: [f64; 3],
    /// Phase.
    pub phase: Phase,
}

/// The hold's steadiness.
#[derive(Debug, Clone, Copy, Default)]
pub struct Hold {
    /// Mean force magnitude, N.
    pub mean: f64,
    /// Mean vertical force (pushing the hand up), N.
    pub mean_z: f64,
    /// `(max − min)/mean` of the force magnitude.
    pub variation: f64,
    /// Largest `|F_xy| / |F|`.
    pub sideways: f64,
    /// Mean indentation, m.
    pub depth: f64,
}

/// A whole press.
#[derive(Debug, Clone)]
pub struct Press {
    /// Every tick.
    pub samples: Vec<Sample>,
    /// Whether the final depth was reached (the device's travel is bounded).
    pub reached: bool,
    /// The measured part of the hold.
    pub hold: Hold,
}

impl Press {
    /// The force on the hand (z, pushing up) where the first descent crosses `depth`,
    /// interpolated between the two ticks around it; `None` if it never got there.
    pub fn force_at(&self, depth: f64) -> Option<f64> {
        let descent: Vec<&Sample> = self
            .samples
            .iter()
            .filter(|s| s.phase != Phase::Hold)
            .collect();
        let k = descent.iter().position(|s| s.depth >= depth)?;
        let b = descent[k];
        if k == 0 {
            return Some(b.force[2]);
        }
        let a = descent[k - 1];
        let w = if b.depth > a.depth {
            (depth - a.depth) / (b.depth - a.depth)
        } else {
            1.0
        };
        Some(a.force[2] + w.clamp(0.0, 1.0) * (b.force[2] - a.force[2]))
    }
}

/// Longest device travel before a press gives up, m.
const MAX_TRAVEL: f64 = 0.004;
/// Haptic tick and FEM step, s.
const TICK: f64 = 1e-3;

/// Runs one press on `block`.
///
/// # Errors
/// The FEM body cannot be built.
pub fn press(block: &Block, setup: &Setup, plan: &PressPlan) -> Result<Press> {
    let params = FemParameters {
        young: setup.young,
        poisson: setup.poisson,
        density: setup.density,
        damping: setup.damping,
        dt: TICK,
        mode: FemMode::Linear,
    };
    let fem = Fem::new(&block.mesh, params).context("building the FEM block")?;
    let mut world = World::new([0.0; 3]);
    world.add_model("block", block.mesh.clone(), Model::Fem(fem));
    let law = ToolSphere {
        center: [0.0; 3],
        radius: setup.radius,
        stiffness: setup.tool_stiffness,
        law: ForceLaw::Linear,
    };
    let mut session = OfflineSession::new(world, ToolLaws::uniform(law, 1)).catching_up();
    let tilt = plan.tilt_deg.to_radians();
    let dir = [tilt.sin(), 0.0, -tilt.cos()];
    // The path passes through the point a radius above the contact, starting start_gap higher.
    let top = [CONTACT[0], CONTACT[1], CONTACT[2] + setup.radius];
    let back = plan.start_gap / tilt.cos();
    let start = [0, 1, 2].map(|c| top[c] - back * dir[c]);
    let mut travel = 0.0;
    let mut phase = Phase::Descend;
    let mut hold_start = 0.0;
    let mut samples = Vec::new();
    let mut reached = false;
    let mut tick = 0usize;
    loop {
        tick += 1;
        let t = tick as f64 * TICK;
        if phase != Phase::Hold {
            travel += plan.speed * TICK;
        }
        let device = [0, 1, 2].map(|c| start[c] + travel * dir[c]);
        let state = session.probe(device, false);
        let force = hand_force(
            &state,
            ForceLaw::Linear,
            setup.tool_stiffness,
            0.0,
            [0.0; 3],
        );
        let depth = top[2] - state.proxy[2];
        samples.push(Sample {
            t,
            depth,
            force,
            phase,
        });
        session.advance(t, Some(RoundInput::at(device)), &[], || 0);
        match phase {
            Phase::Descend if depth >= plan.hold_depth => {
                phase = Phase::Hold;
                hold_start = t;
            }
            Phase::Hold if t - hold_start >= plan.hold => phase = Phase::Deeper,
            Phase::Deeper if depth >= plan.final_depth => {
                reached = true;
                break;
            }
            _ => {}
        }
        if travel > MAX_TRAVEL + back {
            break;
        }
    }
    let measured: Vec<&Sample> = samples
        .iter()
        .filter(|s| s.phase == Phase::Hold && s.t - hold_start > plan.settle)
        .collect();
    let hold = hold_stats(&measured);
    Ok(Press {
        samples,
        reached,
        hold,
    })
}

fn hold_stats(samples: &[&Sample]) -> Hold {
    if samples.is_empty() {
        return Hold {
            mean: f64::NAN,
            mean_z: f64::NAN,
            variation: f64::NAN,
            sideways: f64::NAN,
            depth: f64::NAN,
        };
    }
    let mag = |f: [f64; 3]| (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
    let n = samples.len() as f64;
    let mean = samples.iter().map(|s| mag(s.force)).sum::<f64>() / n;
    let max = samples
        .iter()
        .map(|s| mag(s.force))
        .fold(f64::MIN, f64::max);
    let min = samples
        .iter()
        .map(|s| mag(s.force))
        .fold(f64::MAX, f64::min);
    let sideways = samples
        .iter()
        .map(|s| {
            let m = mag(s.force);
            if m > 0.0 {
                s.force[0].hypot(s.force[1]) / m
            } else {
                0.0
            }
        })
        .fold(0.0, f64::max);
    Hold {
        mean,
        mean_z: samples.iter().map(|s| s.force[2]).sum::<f64>() / n,
        variation: if mean > 0.0 {
            (max - min) / mean
        } else {
            f64::INFINITY
        },
        sideways,
        depth: samples.iter().map(|s| s.depth).sum::<f64>() / n,
    }
}
