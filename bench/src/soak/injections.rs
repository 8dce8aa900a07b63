//! The deformation-process faults the soak delivers (SIGKILL, or SIGSTOP then SIGCONT), and
//! the check that a stale-frame ramp answered every one.

use std::time::Instant;

use serde::Serialize;

use super::forces::ForceAudit;
use super::memory;
use super::report::{check, Check, Evidence};

/// An injection is answered by a stale-frame episode that begins at most this long after it.
const ANSWER_WITHIN_NS: u64 = 2_000_000_000;

/// One delivered (or skipped) deformation-process fault.
#[derive(Debug, Clone, Serialize)]
pub struct Injection {
    /// Planned time, s after the first frame.
    pub planned_s: f64,
    /// When it was delivered, s after the first frame (`None`: skipped).
    pub at_s: Option<f64>,
    /// `kill` or `stop`.
    pub kind: &'static str,
    /// Planned stop length, s.
    pub stop_s: Option<f64>,
    /// The deformation process it hit.
    pub pid: u32,
    /// `CLOCK_MONOTONIC` at delivery, ns.
    #[serde(skip)]
    pub start_ns: u64,
    /// Whether a stale-frame ramp answered it (`None`: the bench saw no tool state then).
    pub answered: Option<bool>,
}

/// Sends `sig` to `pid` if it is still a deformation process of the run.
pub(super) fn signal_deform(pid: u32, prefix: &str, sig: i32) -> bool {
    let args = memory::cmdline(pid);
    let ours = args.iter().any(|a| a == "deform") && args.iter().any(|a| a == prefix);
    // SAFETY: kill on a grandchild of this bench, checked to be the run's deformation process.
    ours && unsafe { libc::kill(pid as i32, sig) } == 0
}

/// A stopped deformation process, continued when dropped (on every path, errors included).
pub(super) struct StoppedDeform {
    pub(super) pid: u32,
    pub(super) prefix: String,
    pub(super) resume_at: Instant,
}

impl Drop for StoppedDeform {
    fn drop(&mut self) {
        signal_deform(self.pid, &self.prefix, libc::SIGCONT);
    }
}

/// Whether a stale-frame episode answered the injection: one that overlaps its moment and began
/// at most [`ANSWER_WITHIN_NS`] after it. `None` if the bench missed the tool states then.
pub(super) fn answered(inj: &Injection, audit: &ForceAudit) -> Option<bool> {
    inj.at_s?;
    let (from, to) = (inj.start_ns, inj.start_ns + ANSWER_WITHIN_NS);
    let hit = audit
        .episodes
        .iter()
        .any(|e| e.stale && e.first_ns <= to && e.last_ns >= from);
    if hit {
        return Some(true);
    }
    let blind = audit.gaps.iter().any(|&(a, b)| a <= to && b >= from);
    (!blind).then_some(false)
}

/// How many injections of `kind` (`kill`, `stop`) were delivered.
pub(super) fn delivered(injections: &[Injection], kind: &str) -> usize {
    injections
        .iter()
        .filter(|i| i.kind == kind && i.at_s.is_some())
        .count()
}

// ---------------------------------------------------------------------------------------------
// The checks on this evidence.

/// Safety invariant 2 seen from the injections: every stop and kill made the frames stale and
/// the force ramp.
pub(super) fn check_answered(e: &Evidence<'_>) -> Check {
    let injections = e.injections;
    let unanswered = injections
        .iter()
        .filter(|i| i.answered == Some(false))
        .count();
    let blind = injections
        .iter()
        .filter(|i| i.at_s.is_some() && i.answered.is_none())
        .count();
    let skipped = injections.iter().filter(|i| i.at_s.is_none()).count();
    let kills = delivered(injections, "kill");
    check(
        "every deformation stop and kill answered by a stale-frame ramp",
        unanswered == 0 && kills + delivered(injections, "stop") > 0,
        format!(
            "{kills} kills, {} stops (0.3–3 s) delivered, {skipped} skipped (no process), \
             {unanswered} without a stale-frame episode, {blind} unseen (the bench missed those \
             ticks)",
            delivered(injections, "stop")
        ),
    )
}
