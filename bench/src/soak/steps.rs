//! The safety's rule on a rising force, checked on the tool-state stream: between consecutive
//! tool states `|F|` never rises by more than the step limit plus what the stylus's own motion
//! explains (`max_step + k · |Δx|`, `k` the tool spring, `Δx` the stylus's move since the last
//! healthy tick; none after an unhealthy one) — no pop, however the surface, the frames or the
//! processes behave. And a haptic loop that **restarts** — a new process after a kill (its
//! sequence starts over), or one that did not tick for longer than the stale limit (stopped) —
//! starts its force over from zero: its first force is at most one step (`max_step`), never
//! the force it had before.
//!
//! [`super::forces::ForceAudit`] tells this audit how each tool state follows the last (the
//! next tick, or a restart); the check on it is `injections::check_haptic_restarts`, beside
//! the haptic faults that cause the restarts.

use lop_client::{ToolState, TOOL_FLAG_RAMPING};
use serde::Serialize;

/// Relative slack on the limits: rounding only.
const REL_TOL: f64 = 1e-9;

/// The safety's rules for a rising force (the daemon config's `max_force_step_n`, the scene's
/// tool spring, the stale limit).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct StepLimits {
    /// Largest rise per tick beyond the stylus's motion, N.
    pub max_step: f64,
    /// The tool spring, N/m (the law's stiffness against a body, when larger, is in each tool
    /// state).
    pub stiffness: f64,
    /// A loop that did not tick for longer than this starts its force over, ns.
    pub stale_ns: u64,
}

impl StepLimits {
    /// No rule on a rising force (tests of the other rules).
    #[cfg(test)]
    pub fn none() -> StepLimits {
        StepLimits {
            max_step: f64::INFINITY,
            stiffness: 0.0,
            stale_ns: u64::MAX,
        }
    }
}

/// How the haptic loop came back.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RestartKind {
    /// A new process (the sequence started over).
    Process,
    /// The same process after a pause longer than the stale limit (stopped).
    Pause,
}

/// A restart of the haptic loop seen in the stream.
#[derive(Debug, Clone, Serialize)]
pub struct Restart {
    /// How.
    pub kind: RestartKind,
    /// Stamp of the first tool state after it, ns.
    pub first_ns: u64,
    /// How long the stream was silent, ms.
    pub silent_ms: f64,
    /// |F| before it, N (the last state seen).
    pub force_before: f64,
    /// |F| on the first tick after it, N (`None`: the bench missed that tick).
    pub first_force: Option<f64>,
}

/// How a tool state follows the one seen before it.
#[derive(Debug, Clone, Copy)]
pub enum Follows<'a> {
    /// The next tick of the same loop.
    Tick(&'a ToolState),
    /// The loop came back after `before`; `first` tells whether this is its first tick.
    Restart {
        kind: RestartKind,
        before: &'a ToolState,
        first: bool,
    },
    /// Nothing to judge against (the first state, or missed ones in between).
    Unknown,
}

/// A broken rule.
#[derive(Debug, Clone, PartialEq)]
pub enum StepViolation {
    /// `|F|` rose faster than the limit allows.
    Jump(String),
    /// A restarted loop's first force was more than one step.
    NotFromZero(String),
}

/// The running audit of rises and restarts.
#[derive(Debug)]
pub struct StepAudit {
    /// The rules.
    pub limits: StepLimits,
    /// Every restart of the haptic loop, in order.
    pub restarts: Vec<Restart>,
    /// The largest rise of `|F|` in one tick beyond its allowance (negative: within it), N.
    pub largest_rise_excess: f64,
}

fn norm(f: [f64; 3]) -> f64 {
    (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt()
}

impl StepAudit {
    /// An audit of `limits`.
    pub fn new(limits: StepLimits) -> StepAudit {
        StepAudit {
            limits,
            restarts: Vec::new(),
            largest_rise_excess: f64::NEG_INFINITY,
        }
    }

    /// Judges `s`, which follows the last state as `follows` says; the rules it broke.
    pub fn feed(&mut self, s: &ToolState, follows: Follows<'_>) -> Option<StepViolation> {
        let mag = norm(s.force);
        match follows {
            Follows::Restart {
                kind,
                before,
                first,
            } => {
                let first_force = first.then_some(mag);
                self.restarts.push(Restart {
                    kind,
                    first_ns: s.stamp_ns,
                    silent_ms: s.stamp_ns.saturating_sub(before.stamp_ns) as f64 * 1e-6,
                    force_before: norm(before.force),
                    first_force,
                });
                let within = |f: f64| f <= self.limits.max_step * (1.0 + REL_TOL);
                first_force.filter(|f| !within(*f)).map(|_| {
                    StepViolation::NotFromZero(format!(
                        "tick {}: the loop came back ({kind:?}) with |F| = {mag} N, more than one \
                         {} N step from zero ({} N before)",
                        s.sequence,
                        self.limits.max_step,
                        norm(before.force)
                    ))
                })
            }
            Follows::Tick(p) => {
                // What the stylus moved since the last healthy tick times the spring, plus the
                // step; nothing moved after an unhealthy tick.
                let moved = if p.flags & TOOL_FLAG_RAMPING == 0 {
                    norm(std::array::from_fn(|k| {
                        s.device_position[k] - p.device_position[k]
                    }))
                } else {
                    0.0
                };
                let k = s.tool_stiffness.max(self.limits.stiffness);
                let allowance = self.limits.max_step + k * moved;
                let rise = mag - norm(p.force);
                if !(rise.is_finite() && allowance.is_finite()) {
                    return None;
                }
                self.largest_rise_excess = self.largest_rise_excess.max(rise - allowance);
                (rise > allowance * (1.0 + REL_TOL) + 1e-12).then(|| {
                    StepViolation::Jump(format!(
                        "tick {}: |F| rose from {} N to {mag} N in one tick; the step limit and \
                         the stylus's {:.4} mm allow {allowance} N",
                        s.sequence,
                        norm(p.force),
                        moved * 1e3
                    ))
                })
            }
            Follows::Unknown => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::soak::forces::ForceAudit;
    use lop_client::TOOL_FLAG_STALE_FRAME;

    const UNHEALTHY: u32 = TOOL_FLAG_RAMPING | TOOL_FLAG_STALE_FRAME;

    /// The stylus pressing a spring surface and moving on, with frames that land elsewhere,
    /// stale stretches and a pause, through the daemon's own `ForceSafety`: the audit finds
    /// nothing. The same stream with one pop, or with a pause the loop did not start over
    /// from, is caught.
    #[test]
    fn the_safety_stage_s_step_limit_and_restart_pass_and_pops_are_caught() {
        use lop_sim::haptic::ForceSafety;
        let limits = StepLimits {
            max_step: 0.05,
            stiffness: 700.0,
            stale_ns: 100_000_000,
        };
        // (sequence, stamp, device, force, flags) as the loop publishes them.
        let stream = |restart_after_pause: bool| {
            let mut safety = ForceSafety::new(3.3, 0.05, 5);
            let mut out = Vec::new();
            let mut stamp = 0u64;
            for tick in 0..4000u64 {
                // Paused deep in the third press.
                stamp += if tick == 2250 { 600_000_000 } else { 1_000_000 };
                if tick == 2250 && restart_after_pause {
                    safety.restart();
                }
                let t = tick as f64 * 1e-3;
                // 12 mm into the surface and out, twice a second; frames every 10 ms that
                // move the surface by up to 1 mm (a desired force that jumps).
                let y = 0.004 - 0.016 * (t * std::f64::consts::PI * 2.0).sin().abs();
                let surface = 0.001 * ((tick / 10) % 3) as f64 / 2.0;
                let depth = (surface - y).max(0.0);
                let stale = (1200..1260).contains(&tick);
                let desired = [0.0, 700.0 * depth, 0.0];
                let device = [0.0, y, 0.0];
                let f = safety.condition_moving(desired, !stale, Some(device), 700.0);
                let flags = if stale { UNHEALTHY } else { 0 };
                out.push(ToolState {
                    sequence: tick,
                    stamp_ns: stamp,
                    device_position: device,
                    force: f,
                    flags,
                    ..Default::default()
                });
            }
            out
        };
        let audit = |states: &[ToolState]| {
            let mut a = ForceAudit::new(3.3, 5, &[], limits);
            for st in states {
                a.feed(st);
            }
            a.finish();
            a
        };
        let good = stream(true);
        let a = audit(&good);
        assert_eq!(a.counts.total(), 0, "{:?}", a.violations);
        assert_eq!(a.steps.restarts.len(), 1);
        assert_eq!(a.steps.restarts[0].kind, RestartKind::Pause);
        assert!(
            a.max_force > 1.0,
            "the press must load the hand: {}",
            a.max_force
        );
        // The frames' jumps did reach the limit (the rule is tested where it binds).
        assert!(
            a.steps.largest_rise_excess > -1e-9,
            "{}",
            a.steps.largest_rise_excess
        );

        // One pop of 0.2 N on a tick in the press.
        let mut popped = good.clone();
        let k = (300..2400)
            .find(|&k| norm(good[k].force) > 0.5 && good[k].flags == 0)
            .unwrap();
        popped[k].force[1] += 0.2;
        assert_eq!(audit(&popped).counts.jump, 1);
        // A pause that the loop went on from.
        let b = audit(&stream(false));
        assert!(
            b.steps.restarts[0].force_before > 1.0,
            "{:?}",
            b.steps.restarts
        );
        assert_eq!(b.counts.not_from_zero, 1, "{:?}", b.violations);
        // A new process (the sequence starts over) that starts with a force.
        let mut new_process = good[..1000].to_vec();
        new_process.push(ToolState {
            sequence: 0,
            stamp_ns: good[999].stamp_ns + 500_000_000,
            force: [0.0, 0.4, 0.0],
            ..Default::default()
        });
        let c = audit(&new_process);
        assert_eq!((c.segments, c.counts.not_from_zero), (1, 1));
        assert_eq!(c.steps.restarts[0].kind, RestartKind::Process);
    }
}
