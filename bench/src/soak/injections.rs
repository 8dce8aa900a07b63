//! The process faults the soak delivers (SIGKILL, or SIGSTOP then SIGCONT, to the deformation
//! or the haptic process), and the checks that each was answered **on every tool**: a
//! stale-frame ramp for the deformation process's, a loop that started every device's force
//! over from zero for the haptic one's. Each injection keeps what each tool showed of it
//! ([`ToolAnswer`]): whether it answered, and for a haptic fault the force the tool had before
//! (in the tissue or not) and its first force after.

use std::time::Instant;

use serde::Serialize;

use super::forces::ForceAudit;
use super::memory;
use super::report::{check, per_tool, Check, Evidence};
use super::steps::{Restart, RestartKind};

/// An injection is answered by a stale-frame episode that begins at most this long after it.
const ANSWER_WITHIN_NS: u64 = 2_000_000_000;
/// A killed haptic process is answered by a new one publishing within this long (the
/// supervisor's back-off, the process's start-up and its device's).
const HAPTIC_BACK_WITHIN_NS: u64 = 15_000_000_000;

/// One delivered (or skipped) process fault.
#[derive(Debug, Clone, Serialize)]
pub struct Injection {
    /// `deform` or `haptic`.
    pub process: &'static str,
    /// Planned time, s after the first frame.
    pub planned_s: f64,
    /// When it was delivered, s after the first frame (`None`: skipped).
    pub at_s: Option<f64>,
    /// `kill` or `stop`.
    pub kind: &'static str,
    /// Planned stop length, s.
    pub stop_s: Option<f64>,
    /// The process it hit.
    pub pid: u32,
    /// `CLOCK_MONOTONIC` at delivery, ns.
    #[serde(skip)]
    pub start_ns: u64,
    /// Whether it was answered on every tool: a stale-frame ramp (deformation process), the
    /// loop back with its force from zero (haptic process). `None`: on some tool the bench saw
    /// no tool state then (and on none was it unanswered).
    pub answered: Option<bool>,
    /// What each tool showed of it (tool `k`'s at `k`).
    pub tools: Vec<ToolAnswer>,
}

/// What one tool's stream showed of an injection.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ToolAnswer {
    /// Whether it answered (`None`: the bench missed this tool's states then).
    pub answered: Option<bool>,
    /// A haptic fault: `|F|` on the last tick before the loop went away, N (`> 0`: the tool was
    /// in the tissue, pressing or holding).
    pub force_before_n: Option<f64>,
    /// A haptic fault: `|F|` on the loop's first tick back, N (`None`: that tick was missed).
    pub first_force_n: Option<f64>,
}

impl Injection {
    /// Records what each tool's audit (`audits[k]`: tool `k`'s) showed of it, and whether it
    /// was answered on every tool.
    pub(super) fn judge(&mut self, audits: &[ForceAudit]) {
        self.tools = audits.iter().map(|a| answer(self, a)).collect();
        self.answered = if self.at_s.is_none() {
            None
        } else if self.tools.iter().any(|t| t.answered == Some(false)) {
            Some(false)
        } else if self.tools.iter().all(|t| t.answered == Some(true)) {
            Some(true)
        } else {
            None
        };
    }
}

/// Sends `sig` to `pid` if it is still the run's `role` process (`deform`, `haptic`).
pub(super) fn signal_process(pid: u32, prefix: &str, role: &str, sig: i32) -> bool {
    let args = memory::cmdline(pid);
    let ours = args.iter().any(|a| a == role) && args.iter().any(|a| a == prefix);
    // SAFETY: kill on a grandchild of this bench, checked to be the run's process of `role`.
    ours && unsafe { libc::kill(pid as i32, sig) } == 0
}

/// A stopped process, continued when dropped (on every path, errors included).
pub(super) struct StoppedProcess {
    pub(super) pid: u32,
    pub(super) prefix: String,
    pub(super) role: &'static str,
    pub(super) resume_at: Instant,
}

impl Drop for StoppedProcess {
    fn drop(&mut self) {
        signal_process(self.pid, &self.prefix, self.role, libc::SIGCONT);
    }
}

/// What one tool's `audit` showed of the injection (see [`Injection::answered`]): answered by
/// a stale-frame episode that overlaps its moment and began at most [`ANSWER_WITHIN_NS`] after
/// it (the deformation process's); by a new haptic process (the sequence started over) within
/// [`HAPTIC_BACK_WITHIN_NS`] of a kill, or the same loop back after a pause within a stop and
/// 2 s (the haptic process's; whether its force started from zero is the audit's rule on
/// every restart, and the restart's forces are kept). `None` if the bench missed the tool
/// states then.
fn answer(inj: &Injection, audit: &ForceAudit) -> ToolAnswer {
    let mut out = ToolAnswer::default();
    if inj.at_s.is_none() {
        return out;
    }
    let within = match (inj.process, inj.kind) {
        ("haptic", "kill") => HAPTIC_BACK_WITHIN_NS,
        ("haptic", _) => (inj.stop_s.unwrap_or(0.0) * 1e9) as u64 + 2_000_000_000,
        _ => ANSWER_WITHIN_NS,
    };
    let (from, to) = (inj.start_ns, inj.start_ns + within);
    let hit = if inj.process == "haptic" {
        let kind = if inj.kind == "kill" {
            RestartKind::Process
        } else {
            RestartKind::Pause
        };
        let restart: Option<&Restart> = audit
            .steps
            .restarts
            .iter()
            .find(|r| r.kind == kind && r.first_ns >= from && r.first_ns <= to);
        if let Some(r) = restart {
            out.force_before_n = Some(r.force_before);
            out.first_force_n = r.first_force;
        }
        restart.is_some()
    } else {
        audit
            .episodes
            .iter()
            .any(|e| e.stale && e.first_ns <= to && e.last_ns >= from)
    };
    let blind = audit.gaps.iter().any(|&(a, b)| a <= to && b >= from);
    out.answered = if hit {
        Some(true)
    } else {
        (!blind).then_some(false)
    };
    out
}

/// How many injections of `kind` (`kill`, `stop`) were delivered to `process`.
pub(super) fn delivered(injections: &[Injection], process: &str, kind: &str) -> usize {
    injections
        .iter()
        .filter(|i| i.process == process && i.kind == kind && i.at_s.is_some())
        .count()
}

/// Of the injections into `process`: how many were not answered, how many the bench did not
/// see (delivered, answer unknown), how many were skipped (no process to signal).
fn outcomes(injections: &[Injection], process: &str) -> (usize, usize, usize) {
    let of = || injections.iter().filter(|i| i.process == process);
    (
        of().filter(|i| i.answered == Some(false)).count(),
        of().filter(|i| i.at_s.is_some() && i.answered.is_none())
            .count(),
        of().filter(|i| i.at_s.is_none()).count(),
    )
}

// ---------------------------------------------------------------------------------------------
// The checks on this evidence.

/// Safety invariant 2 seen from the injections: every stop and kill of the deformation
/// process made the frames stale and every tool's force ramp.
pub(super) fn check_answered(e: &Evidence<'_>) -> Check {
    let (unanswered, blind, skipped) = outcomes(e.injections, "deform");
    let kills = delivered(e.injections, "deform", "kill");
    let stops = delivered(e.injections, "deform", "stop");
    check(
        "every deformation stop and kill answered by a stale-frame ramp",
        unanswered == 0 && kills + stops > 0,
        format!(
            "{kills} kills, {stops} stops (0.3–3 s) delivered, {skipped} skipped (no process), \
             {unanswered} without a stale-frame episode{}, {blind} unseen (the bench missed \
             those ticks)",
            if e.settings.devices > 1 {
                " on some tool"
            } else {
                ""
            }
        ),
    )
}

/// The haptic process's own faults (issue of the restart): every kill answered by a new
/// process and every stop by the loop coming back, on every tool, each device's force started
/// over from zero (the audit's rule on every restart), and no tool's force rising faster than
/// the step limit plus its stylus's motion anywhere in the run.
pub(super) fn check_haptic_restarts(e: &Evidence<'_>) -> Check {
    let (unanswered, blind, _) = outcomes(e.injections, "haptic");
    let kills = delivered(e.injections, "haptic", "kill");
    let stops = delivered(e.injections, "haptic", "stop");
    let mut pass = unanswered == 0 && kills + stops > 0;
    let detail = per_tool(e.settings, |k| {
        let a = &e.audits[k];
        pass &= a.counts.not_from_zero == 0 && a.counts.jump == 0;
        let loaded = a
            .steps
            .restarts
            .iter()
            .filter(|r| r.force_before > 0.0)
            .count();
        let first_max = a
            .steps
            .restarts
            .iter()
            .filter_map(|r| r.first_force)
            .fold(0.0, f64::max);
        format!(
            "{} restarts in the stream ({loaded} with a force on the hand before), largest \
             first force after one {first_max:.4} N, {} not from zero; {} rises over the limit \
             (largest rise beyond its allowance {:+.4} N)",
            a.steps.restarts.len(),
            a.counts.not_from_zero,
            a.counts.jump,
            a.steps.largest_rise_excess
        )
    });
    let in_tissue = if e.settings.devices > 1 {
        let haptic = || {
            e.injections
                .iter()
                .filter(|i| i.process == "haptic" && i.answered == Some(true))
        };
        let loaded = |i: &Injection| {
            i.tools
                .iter()
                .filter(|t| t.force_before_n.is_some_and(|f| f > 0.0))
                .count()
        };
        format!(
            "; of those come back, {} caught every tool with a force on the hand, {} at least \
             one",
            haptic().filter(|i| loaded(i) == i.tools.len()).count(),
            haptic().filter(|i| loaded(i) > 0).count()
        )
    } else {
        String::new()
    };
    check(
        "the haptic loop, killed or stopped, came back with its force from zero; no force rose \
         faster than the step limit and the stylus's motion",
        pass,
        format!(
            "{kills} kills, {stops} stops (0.2–1.5 s) delivered, {unanswered} not seen coming \
             back{}, {blind} unseen{in_tissue}; {detail}",
            if e.settings.devices > 1 {
                " on every tool"
            } else {
                ""
            }
        ),
    )
}
