//! What the hand felt: every tool state the haptic loop published (`PREFIX/tool`, one a tick
//! per tool) checked as it streams in, and each device's own force record read after the run.
//!
//! Every tool is audited on its own ([`ToolAudits`]): the loop publishes each tick one state per
//! tool, all with the tick's sequence and each with its tool's index, so only the states of
//! one tool follow each other tick by tick, and only they say what that tool's hand felt. A
//! device's broken samples are its own (they flag its tool only), and so is its force log.
//!
//! Per tool state:
//! - the force is finite and its magnitude within the clamp (safety invariant 1);
//! - a tick whose frame was stale or whose device sample was broken is flagged as ramping
//!   (invariant 2), and a planned broken sample is flagged as a device error on exactly its
//!   tick; a device error on any other tick is counted as unexpected.
//!
//! Per **episode** (a run of consecutive ramping ticks), the force ramps down: it is not *cut*,
//! not *held*, and reaches zero in time. `ForceSafety` (daemon/src/safety.rs) scales the last
//! force by `(L − 1) / L` on each unhealthy tick, `L` its ramp level (at most `R`, the ramp
//! length in ticks). Since the force before an episode is at most `(L / R) · clamp`, each tick
//! of the ramp takes off at most `clamp / R`; so, between two consecutive ticks of an episode:
//! - **not cut**: `|F|` drops by at most `clamp / R` per tick (a force cut to zero from above
//!   that fails);
//! - **not held**: while `|F| > 0` it strictly decreases (a force frozen at its last value, or
//!   rising, fails);
//! - **in time**: from the episode's `R`-th tick on, `|F| = 0`.
//!
//! Every tool state also goes to the rise-and-restart audit (`steps.rs`), told how it follows
//! the last one.
//!
//! The stream is sampled by a subscriber with a bounded buffer, so a busy machine can make the
//! bench miss tool states; missed ones are counted (coverage), a check never spans a gap, and
//! an episode that a gap cuts is not judged on its length. A sequence that goes back means the
//! haptic process restarted; the audit then starts a new segment.
//!
//! The checks on this evidence (the end of the file): forces finite and within the clamp, zero
//! written last, every episode ramped, every planned broken sample caught, and enough of the
//! stream seen.

use lop_client::{ToolState, TOOL_FLAG_DEVICE_ERROR, TOOL_FLAG_RAMPING, TOOL_FLAG_STALE_FRAME};
use serde::Serialize;

use lop_drivers::mock::SampleFault;

mod checks;

pub(super) use checks::{ramped, samples_caught, stream_observed, within_clamp, zero_at_stop};

use super::report::{check, per_tool, Check, Evidence};
use super::schedule::{SampleEvent, Schedule};
use super::steps::{Follows, RestartKind, StepAudit, StepLimits, StepViolation};

/// Relative slack on the clamp and on the per-tick ramp step: rounding only.
const REL_TOL: f64 = 1e-9;
/// Violations kept with their details (all are counted).
const KEPT: usize = 20;
/// Missed tool states from which a gap is kept as a blind stretch (50 ms at 1 kHz: a third of
/// a stale-frame episode's shortest start-up).
pub const BLIND_TICKS: u64 = 50;

/// One ramping episode.
#[derive(Debug, Clone, Serialize)]
pub struct Episode {
    /// Tick of its first ramping tool state.
    pub first_tick: u64,
    /// Its first ramping tool state's stamp (`CLOCK_MONOTONIC`, ns).
    pub first_ns: u64,
    /// Its last ramping tool state's stamp.
    pub last_ns: u64,
    /// Ramping ticks seen.
    pub ticks: u64,
    /// Some tick had a stale frame.
    pub stale: bool,
    /// Some tick had a broken sample / device error.
    pub device: bool,
    /// |F| on the tick before it (if seen), N.
    pub force_before: Option<f64>,
    /// Whether the bench missed tool states inside it.
    pub gapped: bool,
    /// Whether it broke a ramp rule.
    pub violated: bool,
}

impl Episode {
    /// Whether the hand felt a force when it began (a ramp with something to ramp).
    pub fn loaded(&self) -> bool {
        self.force_before.is_some_and(|f| f > 0.0)
    }
}

/// The running audit of the tool-state stream.
#[derive(Debug)]
pub struct ForceAudit {
    clamp: f64,
    ramp_ticks: u64,
    samples_plan: Vec<SampleEvent>,
    /// Per planned sample event: ticks of it seen, and of those flagged as a device error.
    plan_seen: Vec<(u64, u64)>,
    last: Option<ToolState>,
    open: Option<Episode>,
    /// Tool states received.
    pub received: u64,
    /// Tool states the bench missed (sequence gaps).
    pub missed: u64,
    /// Haptic-process restarts seen (the sequence went back).
    pub segments: u64,
    /// Largest |F| published, N.
    pub max_force: f64,
    /// Ticks with a force on the hand.
    pub loaded_ticks: u64,
    /// Ticks flagged stale.
    pub stale_ticks: u64,
    /// Ticks flagged as a device error.
    pub device_error_ticks: u64,
    /// Device-error ticks outside every planned broken sample.
    pub unexpected_device_errors: u64,
    /// Every episode, in order.
    pub episodes: Vec<Episode>,
    /// Rises and restarts (`steps.rs`).
    pub steps: StepAudit,
    /// Stretches the bench did not see ([`BLIND_TICKS`] missed tool states or more): the
    /// stamps of the states before and after, ns.
    pub gaps: Vec<(u64, u64)>,
    /// Violations by rule: non-finite, over the clamp, unhealthy but not ramping, planned
    /// sample not flagged, cut, held or rising, not zero in time.
    pub counts: ViolationCounts,
    /// The first violations, described.
    pub violations: Vec<String>,
}

/// Violations by rule.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ViolationCounts {
    /// A force with a NaN or infinite component.
    pub non_finite: u64,
    /// |F| above the clamp.
    pub over_clamp: u64,
    /// A stale or device-error tick not flagged as ramping.
    pub not_ramping: u64,
    /// A planned broken sample's tick not flagged as a device error.
    pub sample_not_flagged: u64,
    /// |F| dropped by more than clamp / R in one tick of a ramp.
    pub cut: u64,
    /// |F| did not decrease in a ramp.
    pub held: u64,
    /// |F| not zero from a ramp's R-th tick on.
    pub late: u64,
    /// |F| rose by more than the step limit plus the stylus's motion in one tick.
    pub jump: u64,
    /// A restarted loop's first force was more than one step (it went on from the old one).
    pub not_from_zero: u64,
}

impl ViolationCounts {
    /// All violations.
    #[cfg(test)]
    pub fn total(&self) -> u64 {
        self.non_finite
            + self.over_clamp
            + self.not_ramping
            + self.sample_not_flagged
            + self.cut
            + self.held
            + self.late
            + self.jump
            + self.not_from_zero
    }

    /// The ramp rules' violations (cut, held, late, not ramping).
    pub fn ramp(&self) -> u64 {
        self.not_ramping + self.cut + self.held + self.late
    }
}

fn norm(f: [f64; 3]) -> f64 {
    (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt()
}

impl ForceAudit {
    /// An audit against `clamp` N and a ramp of `ramp_ticks`, expecting the broken samples of
    /// `samples` (sorted by tick).
    pub fn new(
        clamp: f64,
        ramp_ticks: u64,
        samples: &[SampleEvent],
        limits: StepLimits,
    ) -> ForceAudit {
        ForceAudit {
            clamp,
            ramp_ticks: ramp_ticks.max(1),
            plan_seen: vec![(0, 0); samples.len()],
            samples_plan: samples.to_vec(),
            last: None,
            open: None,
            received: 0,
            missed: 0,
            segments: 0,
            max_force: 0.0,
            loaded_ticks: 0,
            stale_ticks: 0,
            device_error_ticks: 0,
            unexpected_device_errors: 0,
            episodes: Vec::new(),
            steps: StepAudit::new(limits),
            gaps: Vec::new(),
            counts: ViolationCounts::default(),
            violations: Vec::new(),
        }
    }

    fn violation(&mut self, what: String) {
        if self.violations.len() < KEPT {
            self.violations.push(what);
        }
    }

    /// The planned sample event covering `tick`, by index.
    fn planned(&self, tick: u64) -> Option<usize> {
        let i = self
            .samples_plan
            .partition_point(|e| e.first_tick + e.ticks <= tick);
        (i < self.samples_plan.len() && self.samples_plan[i].covers(tick)).then_some(i)
    }

    fn close_episode(&mut self) {
        if let Some(e) = self.open.take() {
            self.episodes.push(e);
        }
    }

    /// Checks one tool state (in the order published).
    pub fn feed(&mut self, s: &ToolState) {
        self.received += 1;
        // Continuity with the previous state: the next tick, a gap, or a new haptic process.
        let stale_ns = self.steps.limits.stale_ns;
        let mut follows = Follows::Unknown;
        let last = self.last;
        let prev = match &last {
            Some(p)
                if s.sequence == p.sequence + 1
                    && s.stamp_ns.saturating_sub(p.stamp_ns) > stale_ns =>
            {
                // The loop did not tick for longer than the stale limit: it was stopped.
                self.gaps.push((p.stamp_ns, s.stamp_ns));
                follows = Follows::Restart {
                    kind: RestartKind::Pause,
                    before: p,
                    first: true,
                };
                None
            }
            Some(p) if s.sequence == p.sequence + 1 => {
                follows = Follows::Tick(p);
                Some(*p)
            }
            Some(p) if s.sequence > p.sequence + 1 => {
                let missed = s.sequence - p.sequence - 1;
                self.missed += missed;
                // Longer than the ticks missed explain (at most 2 ms each): a pause among
                // them, whose first tick may be one of those missed.
                let silent = s.stamp_ns.saturating_sub(p.stamp_ns);
                let paused = silent > stale_ns.saturating_add(missed * 2_000_000);
                if missed >= BLIND_TICKS || paused {
                    self.gaps.push((p.stamp_ns, s.stamp_ns));
                }
                if paused {
                    follows = Follows::Restart {
                        kind: RestartKind::Pause,
                        before: p,
                        first: false,
                    };
                }
                if let Some(e) = &mut self.open {
                    e.gapped = true;
                }
                None
            }
            Some(p) => {
                self.segments += 1;
                self.gaps.push((p.stamp_ns, s.stamp_ns));
                self.close_episode();
                // The new process's first tick is its sequence 0.
                follows = Follows::Restart {
                    kind: RestartKind::Process,
                    before: p,
                    first: s.sequence == 0,
                };
                None
            }
            None => None,
        };
        match self.steps.feed(s, follows) {
            Some(StepViolation::Jump(what)) => {
                self.counts.jump += 1;
                self.violation(what);
            }
            Some(StepViolation::NotFromZero(what)) => {
                self.counts.not_from_zero += 1;
                self.violation(what);
            }
            None => {}
        }
        self.last = Some(*s);

        // Invariant 1: finite, within the clamp.
        let f = s.force;
        let mag = norm(f);
        if !f.iter().all(|c| c.is_finite()) {
            self.counts.non_finite += 1;
            self.violation(format!("tick {}: non-finite force {f:?}", s.sequence));
        } else {
            self.max_force = self.max_force.max(mag);
            if mag > self.clamp * (1.0 + REL_TOL) {
                self.counts.over_clamp += 1;
                self.violation(format!(
                    "tick {}: |F| = {mag} N above the {} N clamp",
                    s.sequence, self.clamp
                ));
            }
        }
        if mag > 0.0 {
            self.loaded_ticks += 1;
        }

        // Invariant 2: unhealthy ticks ramp; planned broken samples are caught.
        let stale = s.flags & TOOL_FLAG_STALE_FRAME != 0;
        let device = s.flags & TOOL_FLAG_DEVICE_ERROR != 0;
        let ramping = s.flags & TOOL_FLAG_RAMPING != 0;
        self.stale_ticks += u64::from(stale);
        self.device_error_ticks += u64::from(device);
        if (stale || device) && !ramping {
            self.counts.not_ramping += 1;
            self.violation(format!(
                "tick {}: {} but not ramping (flags {:#x})",
                s.sequence,
                if stale { "stale frame" } else { "device error" },
                s.flags
            ));
        }
        match self.planned(s.sequence) {
            Some(i) => {
                self.plan_seen[i].0 += 1;
                if device {
                    self.plan_seen[i].1 += 1;
                } else {
                    self.counts.sample_not_flagged += 1;
                    self.violation(format!(
                        "tick {}: a planned {:?} sample not flagged as a device error",
                        s.sequence, self.samples_plan[i].fault
                    ));
                }
            }
            None if device => self.unexpected_device_errors += 1,
            None => {}
        }

        // Episodes: consecutive ramping ticks.
        if !ramping {
            // (After a gap the open episode is marked already: it may have gone on in the
            // ticks missed.)
            self.close_episode();
            return;
        }
        let prev_mag = prev.map(|p| norm(p.force));
        let continuing = prev.is_some_and(|p| p.flags & TOOL_FLAG_RAMPING != 0);
        if !continuing {
            self.close_episode();
            self.open = Some(Episode {
                first_tick: s.sequence,
                first_ns: s.stamp_ns,
                last_ns: s.stamp_ns,
                ticks: 0,
                stale: false,
                device: false,
                force_before: prev_mag,
                // Started after a gap: its true first tick is unknown.
                gapped: prev.is_none(),
                violated: false,
            });
        }
        let step = self.clamp / self.ramp_ticks as f64 * (1.0 + REL_TOL) + 1e-12;
        let ramp_ticks = self.ramp_ticks;
        let Some(e) = self.open.as_mut() else {
            return;
        };
        e.ticks += 1;
        e.last_ns = s.stamp_ns;
        e.stale |= stale;
        e.device |= device;
        let mut broke = Vec::new();
        if let Some(pm) = prev_mag {
            if pm - mag > step {
                self.counts.cut += 1;
                broke.push(format!(
                    "tick {}: force cut from {pm} N to {mag} N in one tick (a ramp takes at most \
                     {step} N a tick)",
                    s.sequence
                ));
            }
            if pm > 0.0 && mag >= pm {
                self.counts.held += 1;
                broke.push(format!(
                    "tick {}: force held or rising in a ramp: {pm} N then {mag} N",
                    s.sequence
                ));
            }
        }
        if !e.gapped && e.ticks >= ramp_ticks && mag != 0.0 {
            self.counts.late += 1;
            broke.push(format!(
                "tick {}: |F| = {mag} N on the ramp's tick {} (zero from tick {ramp_ticks} on)",
                s.sequence, e.ticks
            ));
        }
        if !broke.is_empty() {
            e.violated = true;
            for b in broke {
                self.violation(b);
            }
        }
    }

    /// Ends the stream (closes the open episode).
    pub fn finish(&mut self) {
        self.close_episode();
    }

    /// Planned sample events with at least one tick seen, and those whose every seen tick was
    /// flagged.
    pub fn planned_samples(&self) -> (usize, usize) {
        let seen = self.plan_seen.iter().filter(|(s, _)| *s > 0).count();
        let flagged = self
            .plan_seen
            .iter()
            .filter(|(s, f)| *s > 0 && s == f)
            .count();
        (seen, flagged)
    }
}

/// The tool-state stream split by tool (`ToolState::tool`), one [`ForceAudit`] each.
#[derive(Debug)]
pub struct ToolAudits {
    /// Tool `k`'s audit at `k`.
    pub tools: Vec<ForceAudit>,
    /// States naming a tool the run does not have.
    pub foreign: u64,
    /// Ticks on which every tool had a force on the hand (all in the tissue at once).
    pub all_loaded_ticks: u64,
    /// Per tool, the (haptic process, tick) of its last state with a force on the hand.
    loaded_at: Vec<Option<(u64, u64)>>,
}

impl ToolAudits {
    /// One audit per tool, in the scene's order.
    pub fn new(tools: Vec<ForceAudit>) -> ToolAudits {
        ToolAudits {
            loaded_at: vec![None; tools.len()],
            tools,
            foreign: 0,
            all_loaded_ticks: 0,
        }
    }

    /// Checks one tool state in its tool's audit.
    pub fn feed(&mut self, s: &ToolState) {
        let k = s.tool as usize;
        let Some(a) = self.tools.get_mut(k) else {
            self.foreign += 1;
            return;
        };
        a.feed(s);
        if norm(s.force) > 0.0 {
            let at = Some((a.segments, s.sequence));
            self.loaded_at[k] = at;
            // Counted on the last tool's state: a tick's states come in the tools' order.
            if k + 1 == self.tools.len() && self.loaded_at.iter().all(|l| *l == at) {
                self.all_loaded_ticks += 1;
            }
        }
    }

    /// Ends every tool's stream.
    pub fn finish(&mut self) {
        for a in &mut self.tools {
            a.finish();
        }
    }
}

/// A device's record of the forces it was sent (`--force-log`, one file per device: the mock's
/// ring of the last two minutes), read after the run.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ForceLog {
    /// Rows read.
    pub rows: u64,
    /// Rows with a force on the hand.
    pub loaded_rows: u64,
    /// Largest |F|, N.
    pub max_force: f64,
    /// Rows with a non-finite force.
    pub non_finite: u64,
    /// Rows above the clamp.
    pub over_clamp: u64,
    /// The last row's force.
    pub last: Option<[f64; 3]>,
}

impl ForceLog {
    /// Parses the CSV written by `lopd haptic --force-log` (`t,fx,fy,fz`).
    pub fn parse(text: &str, clamp: f64) -> Result<ForceLog, String> {
        let mut log = ForceLog::default();
        let mut lines = text.lines();
        match lines.next() {
            Some("t,fx,fy,fz") => {}
            other => return Err(format!("header {other:?}, expected \"t,fx,fy,fz\"")),
        }
        for (i, line) in lines.enumerate() {
            let v: Vec<f64> = line
                .split(',')
                .map(|x| x.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|e| format!("line {}: {line:?}: {e}", i + 2))?;
            let [_, fx, fy, fz] = v[..] else {
                return Err(format!("line {}: {line:?}: expected 4 numbers", i + 2));
            };
            let f = [fx, fy, fz];
            let mag = norm(f);
            log.rows += 1;
            if !f.iter().all(|c| c.is_finite()) {
                log.non_finite += 1;
            } else {
                log.max_force = log.max_force.max(mag);
                if mag > clamp * (1.0 + REL_TOL) {
                    log.over_clamp += 1;
                }
            }
            if mag > 0.0 {
                log.loaded_rows += 1;
            }
            log.last = Some(f);
        }
        Ok(log)
    }
}

// ---------------------------------------------------------------------------------------------
// The checks on this evidence.

/// The run is judged only if the bench saw at least this share of the tool states.
const MIN_COVERAGE: f64 = 0.5;

/// One tool's stream in the report: what its audit saw.
#[derive(Debug, Clone, Serialize)]
pub struct ToolStreamReport {
    /// The tool's index (`ToolState::tool`).
    pub tool: usize,
    /// Its name in the scene.
    pub name: String,
    pub received: u64,
    pub missed: u64,
    pub coverage: f64,
    pub segments: u64,
    pub max_force_n: f64,
    pub loaded_ticks: u64,
    pub stale_ticks: u64,
    pub device_error_ticks: u64,
    pub unexpected_device_errors: u64,
    pub episodes: u64,
    pub episodes_loaded: u64,
    pub episodes_stale: u64,
    pub episodes_device: u64,
    pub episodes_gapped: u64,
    pub longest_episode_ticks: u64,
    pub restarts: u64,
    pub largest_rise_excess_n: f64,
    pub planned_samples: usize,
    pub planned_samples_seen: usize,
    pub planned_samples_flagged: usize,
    pub violations: ViolationCounts,
    pub first_violations: Vec<String>,
}

impl ToolStreamReport {
    /// Tool `tool`'s (named `name`) audit's figures, against its device's planned broken
    /// samples.
    pub fn new(tool: usize, name: &str, a: &ForceAudit, plan: &Schedule) -> ToolStreamReport {
        let (seen, flagged) = a.planned_samples();
        let coverage = a.received as f64 / (a.received + a.missed).max(1) as f64;
        ToolStreamReport {
            tool,
            name: name.to_string(),
            received: a.received,
            missed: a.missed,
            coverage,
            segments: a.segments,
            max_force_n: a.max_force,
            loaded_ticks: a.loaded_ticks,
            stale_ticks: a.stale_ticks,
            device_error_ticks: a.device_error_ticks,
            unexpected_device_errors: a.unexpected_device_errors,
            episodes: a.episodes.len() as u64,
            episodes_loaded: a.episodes.iter().filter(|e| e.loaded()).count() as u64,
            episodes_stale: a.episodes.iter().filter(|e| e.stale).count() as u64,
            episodes_device: a.episodes.iter().filter(|e| e.device).count() as u64,
            episodes_gapped: a.episodes.iter().filter(|e| e.gapped).count() as u64,
            longest_episode_ticks: a.episodes.iter().map(|e| e.ticks).max().unwrap_or(0),
            restarts: a.steps.restarts.len() as u64,
            largest_rise_excess_n: a.steps.largest_rise_excess,
            planned_samples: plan.samples.get(tool).map_or(0, Vec::len),
            planned_samples_seen: seen,
            planned_samples_flagged: flagged,
            violations: a.counts.clone(),
            first_violations: a.violations.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lop_drivers::mock::SampleFault;

    fn state(seq: u64, fy: f64, flags: u32) -> ToolState {
        ToolState {
            sequence: seq,
            stamp_ns: seq * 1_000_000,
            force: [0.0, fy, 0.0],
            flags,
            ..Default::default()
        }
    }

    const UNHEALTHY: u32 = TOOL_FLAG_RAMPING | TOOL_FLAG_STALE_FRAME;

    fn run(forces: &[(f64, u32)]) -> ForceAudit {
        let mut a = ForceAudit::new(3.0, 5, &[], StepLimits::none());
        for (i, &(f, flags)) in forces.iter().enumerate() {
            a.feed(&state(100 + i as u64, f, flags));
        }
        a.finish();
        a
    }

    #[test]
    fn the_safety_stage_s_own_ramp_passes() {
        // The real ForceSafety arithmetic: 2 N held, then unhealthy.
        let mut forces = vec![(2.0, 0); 3];
        let mut f = 2.0;
        for level in (0..5u32).rev() {
            f = f * level as f64 / (level + 1) as f64;
            forces.push((f, UNHEALTHY));
        }
        forces.extend([(0.0, UNHEALTHY); 10]);
        forces.push((0.4, 0));
        let a = run(&forces);
        assert_eq!(a.counts.total(), 0, "{:?}", a.violations);
        assert_eq!(a.episodes.len(), 1);
        let e = &a.episodes[0];
        assert!(e.loaded() && e.stale && !e.device && !e.violated && !e.gapped);
        assert_eq!(e.ticks, 15);
        assert_eq!(a.max_force, 2.0);
    }

    #[test]
    fn a_cut_a_hold_and_a_late_zero_are_each_caught() {
        let cut = run(&[(2.0, 0), (0.0, UNHEALTHY)]);
        assert_eq!(cut.counts.cut, 1, "{:?}", cut.violations);
        assert!(cut.episodes[0].violated);
        let held = run(&[(2.0, 0), (2.0, UNHEALTHY), (1.6, UNHEALTHY)]);
        assert_eq!(held.counts.held, 1, "{:?}", held.violations);
        // Slow ramp: 0.1 N a tick from 2 N is not zero after 5 ticks.
        let slow: Vec<(f64, u32)> = std::iter::once((2.0, 0))
            .chain((1..=8).map(|k| (2.0 - 0.1 * k as f64, UNHEALTHY)))
            .collect();
        let late = run(&slow);
        assert_eq!(late.counts.late, 4, "{:?}", late.violations);
        assert_eq!(late.counts.cut + late.counts.held, 0);
    }

    #[test]
    fn non_finite_and_over_clamp_forces_and_unflagged_ticks_are_caught() {
        let a = run(&[
            (f64::NAN, 0),
            (3.5, 0),
            (3.0, 0),
            (0.0, TOOL_FLAG_STALE_FRAME),
        ]);
        assert_eq!(a.counts.non_finite, 1);
        assert_eq!(a.counts.over_clamp, 1);
        assert_eq!(a.counts.not_ramping, 1);
        assert_eq!(a.max_force, 3.5);
    }

    #[test]
    fn gaps_are_counted_and_never_judged_across() {
        let mut a = ForceAudit::new(3.0, 5, &[], StepLimits::none());
        a.feed(&state(10, 2.0, 0));
        // 20 ticks missed, then a ramp already at zero: no cut, no late verdict.
        a.feed(&state(31, 0.0, UNHEALTHY));
        for k in 32..45 {
            a.feed(&state(k, 0.0, UNHEALTHY));
        }
        a.feed(&state(45, 0.0, 0));
        a.finish();
        assert_eq!(a.missed, 20);
        assert_eq!(a.counts.total(), 0, "{:?}", a.violations);
        assert!(a.episodes[0].gapped);
        // A restarted haptic process starts a new segment.
        a.feed(&state(0, 0.0, 0));
        assert_eq!(a.segments, 1);
    }

    #[test]
    fn planned_broken_samples_must_be_flagged_and_others_are_unexpected() {
        let plan = [SampleEvent {
            first_tick: 5,
            ticks: 2,
            fault: SampleFault::Nan,
        }];
        let dev = TOOL_FLAG_RAMPING | TOOL_FLAG_DEVICE_ERROR;
        let mut a = ForceAudit::new(3.0, 5, &plan, StepLimits::none());
        for (k, flags) in [(4, 0), (5, dev), (6, dev), (7, 0), (8, dev)] {
            a.feed(&state(k, 0.0, flags));
        }
        a.finish();
        assert_eq!(a.planned_samples(), (1, 1));
        assert_eq!(a.unexpected_device_errors, 1);
        assert_eq!(a.counts.total(), 0);
        let mut b = ForceAudit::new(3.0, 5, &plan, StepLimits::none());
        b.feed(&state(5, 0.0, 0));
        assert_eq!(b.planned_samples(), (1, 0));
        assert_eq!(b.counts.sample_not_flagged, 1);
    }

    /// Two tools as the loop publishes them: each tick tool 0's state then tool 1's, with the
    /// tick's sequence and stamp. Tool 0 presses 2 N and ramps down on a stale stretch; tool 1
    /// presses 1 N and reads its device's planned broken samples; the loop restarts once.
    /// Each tool's audit sees its own stream only: no restart but the one, every ramp clean,
    /// the broken samples on tool 1 alone; a state of a third tool is foreign.
    #[test]
    fn each_tool_is_audited_on_its_own_stream() {
        let stale = 30..42u64;
        let broken = SampleEvent {
            first_tick: 50,
            ticks: 3,
            fault: SampleFault::OutOfWorkspace,
        };
        let dev = TOOL_FLAG_RAMPING | TOOL_FLAG_DEVICE_ERROR;
        let limits = StepLimits {
            max_step: 0.1,
            stiffness: 300.0,
            stale_ns: 100_000_000,
        };
        let mut audits = ToolAudits::new(vec![
            ForceAudit::new(3.0, 5, &[], limits),
            ForceAudit::new(3.0, 5, &[broken], limits),
        ]);
        // The safety's ramp on the `n`-th unhealthy tick of an episode (ramp of 5 ticks).
        let ramp = |f: f64, n: u64| {
            let level = (5 - n.min(5)) as f64;
            f * (level - 1.0).max(0.0) / level.max(1.0)
        };
        // One tick of the loop: tool 0 rises 0.1 N a tick to 2 N, tool 1 0.05 N to 1 N; both
        // ramp down while the frame is stale, tool 1 alone on its broken samples.
        let tick = |audits: &mut ToolAudits, f: &mut [f64; 2], seq: u64, stamp: u64| {
            let mut a = ToolState {
                tool: 0,
                stamp_ns: stamp,
                ..state(seq, 0.0, 0)
            };
            let mut b = ToolState { tool: 1, ..a };
            if stale.contains(&seq) {
                f[0] = ramp(f[0], seq - stale.start);
                f[1] = ramp(f[1], seq - stale.start);
                (a.flags, b.flags) = (UNHEALTHY, UNHEALTHY);
            } else if broken.covers(seq) {
                f[0] = (f[0] + 0.1f64).min(2.0);
                f[1] = ramp(f[1], seq - broken.first_tick);
                b.flags = dev;
            } else {
                f[0] = (f[0] + 0.1f64).min(2.0);
                f[1] = (f[1] + 0.05f64).min(1.0);
            }
            (a.force[1], b.force[1]) = (f[0], f[1]);
            audits.feed(&a);
            audits.feed(&b);
        };
        let mut f = [0.0; 2];
        for seq in 0..80 {
            tick(&mut audits, &mut f, seq, seq * 1_000_000);
        }
        // The loop killed and restarted: its sequence starts over, both forces from zero.
        let mut f = [0.0; 2];
        for seq in 0..10 {
            tick(&mut audits, &mut f, seq, (500 + seq) * 1_000_000);
        }
        audits.feed(&ToolState {
            tool: 2,
            ..state(10, 0.0, 0)
        });
        audits.finish();

        for (k, a) in audits.tools.iter().enumerate() {
            assert_eq!((a.received, a.missed), (90, 0), "tool {k}");
            assert_eq!(a.counts.total(), 0, "tool {k}: {:?}", a.violations);
            assert_eq!(a.segments, 1, "tool {k}");
            assert_eq!(a.steps.restarts.len(), 1, "tool {k}");
            assert_eq!(a.unexpected_device_errors, 0, "tool {k}");
        }
        let (t0, t1) = (&audits.tools[0], &audits.tools[1]);
        assert_eq!((t0.max_force, t1.max_force), (2.0, 1.0));
        assert_eq!(t0.steps.restarts[0].force_before, 2.0);
        assert_eq!(t1.steps.restarts[0].force_before, 1.0);
        assert_eq!((t0.device_error_ticks, t1.device_error_ticks), (0, 3));
        assert_eq!(t1.planned_samples(), (1, 1));
        assert_eq!((t0.episodes.len(), t1.episodes.len()), (1, 2));
        assert!(t0
            .episodes
            .iter()
            .chain(&t1.episodes)
            .all(|e| e.loaded() && !e.violated));
        assert_eq!(audits.foreign, 1);
        // Both pressing on every tick but those of the stale stretch from its 5th tick on
        // (both at zero; tool 1's three broken samples only take its force down to 0.2 N).
        assert_eq!(audits.all_loaded_ticks, 90 - 8);
    }

    #[test]
    fn the_force_log_is_read_and_judged() {
        let log = ForceLog::parse("t,fx,fy,fz\n0.1,0,2,0\n0.2,0,0,0\n", 3.0).unwrap();
        assert_eq!((log.rows, log.loaded_rows, log.max_force), (2, 1, 2.0));
        assert_eq!(log.last, Some([0.0; 3]));
        let bad = ForceLog::parse("t,fx,fy,fz\n0.1,NaN,0,0\n0.2,0,4,0\n", 3.0).unwrap();
        assert_eq!((bad.non_finite, bad.over_clamp), (1, 1));
        assert!(ForceLog::parse("x\n", 3.0).is_err());
        assert!(ForceLog::parse("t,fx,fy,fz\n1,2\n", 3.0)
            .unwrap_err()
            .contains("line 2"));
    }
}
