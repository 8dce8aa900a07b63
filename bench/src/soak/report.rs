//! The soak's report: the PASS/FAIL [`Check`]s, the [`Evidence`] every check reads, what
//! `soak.json` holds ([`SoakReport`]) and the printed `soak.txt` ([`render`]). Each check lives
//! beside its evidence (`forces.rs`, `injections.rs`, `supervisor.rs`, `control.rs`,
//! `viewers.rs`, `recording.rs`, `leftovers.rs`, `memory.rs`) as `fn(&Evidence) -> Check`;
//! `mod.rs` gathers the evidence and lists the checks in the report's order.

use std::collections::BTreeSet;

use serde::Serialize;

use super::control::{CtlReport, HammerReport};
use super::forces::{ForceAudit, ForceLog, ToolStreamReport};
use super::injections::{delivered, Injection};
use super::leftovers::Leftovers;
use super::memory::{kib, ProcessWatch, Verdict};
use super::recording::RecordingReport;
use super::schedule::Schedule;
use super::supervisor::SupervisorReport;
use super::viewers::ViewerReport;
use super::Settings;

/// A PASS/FAIL line.
#[derive(Debug, Clone, Serialize)]
pub struct Check {
    /// What is checked.
    pub name: String,
    /// Whether it held.
    pub pass: bool,
    /// The figures behind it.
    pub detail: String,
}

/// A check named `name`.
pub(super) fn check(name: &str, pass: bool, detail: String) -> Check {
    Check {
        name: name.into(),
        pass,
        detail,
    }
}

/// Everything the checks read: what the run was asked to do, what the bench observed while it
/// ran, and what it found after.
pub(super) struct Evidence<'a> {
    pub(super) settings: &'a Settings,
    pub(super) plan: &'a Schedule,
    /// The tool stream as it came in.
    pub(super) audit: &'a ForceAudit,
    /// Its figures.
    pub(super) tool: &'a ToolStreamReport,
    /// The device's force record, or why it could not be read.
    pub(super) force_log: &'a Result<ForceLog, String>,
    /// The process faults, each with whether it was answered.
    pub(super) injections: &'a [Injection],
    pub(super) supervisor: &'a SupervisorReport,
    pub(super) hammer: &'a HammerReport,
    pub(super) ctl: &'a CtlReport,
    pub(super) viewers: &'a ViewerReport,
    pub(super) recording: &'a RecordingReport,
    pub(super) leftovers: &'a Leftovers,
    /// The processes' memory verdicts after warm-up.
    pub(super) memory: &'a [Verdict],
    /// The processes watched.
    pub(super) watch: &'a ProcessWatch,
}

/// Everything `soak.json` holds.
#[derive(Debug, Clone, Serialize)]
pub(super) struct SoakReport {
    pub(super) settings: Settings,
    pub(super) plan: Schedule,
    pub(super) injections: Vec<Injection>,
    pub(super) tool_stream: ToolStreamReport,
    pub(super) force_log: Option<ForceLog>,
    pub(super) recording: RecordingReport,
    pub(super) supervisor: SupervisorReport,
    pub(super) hammer: HammerReport,
    pub(super) ctl: CtlReport,
    pub(super) viewers: ViewerReport,
    pub(super) memory: Vec<Verdict>,
    pub(super) leftovers: Leftovers,
    pub(super) telemetry: Option<TelemetryReport>,
    pub(super) checks: Vec<Check>,
    pub(super) pass: bool,
}

/// The haptic loop's own counters, from its telemetry.
#[derive(Debug, Clone, Serialize)]
pub(super) struct TelemetryReport {
    pub(super) ticks: u64,
    pub(super) overruns: u64,
    pub(super) stale_ticks: u64,
    pub(super) device_faults: u64,
}

/// The printed report (also `soak.txt`).
pub(super) fn render(r: &SoakReport) -> String {
    const W: usize = 100;
    let s = &r.settings;
    let mut out = format!(
        "\nlop-bench soak — scene {}, {:.1} min after the first frame, seed {}, haptic {:.0} Hz, \
         clamp {:.2} N, ramp {} ticks, stale limit {:.0} ms\n",
        s.scene,
        s.seconds / 60.0,
        s.seed,
        s.rate_hz,
        s.clamp_n,
        s.ramp_ticks,
        s.stale_ms
    );
    let p = &r.plan;
    out += &crate::table::note(
        &format!(
            "injected: {} deformation kills and {} stops, {} haptic kills and {} stops, {} runs \
             of broken samples ({} ticks), {} viewer sessions, {} lopd ctl bursts, control \
             requests every {} ms; the script loops every {:.1} s",
            delivered(&r.injections, "deform", "kill"),
            delivered(&r.injections, "deform", "stop"),
            delivered(&r.injections, "haptic", "kill"),
            delivered(&r.injections, "haptic", "stop"),
            p.samples.len(),
            p.samples.iter().map(|e| e.ticks).sum::<u64>(),
            p.viewers.len(),
            p.ctl.len(),
            s.hammer_ms,
            s.script_period_s
        ),
        W,
    );
    out += "\n";
    for c in &r.checks {
        out += &format!("{} {}\n", if c.pass { "PASS" } else { "FAIL" }, c.name);
        out += &crate::table::note(&c.detail, W);
    }
    out += "\nmemory (VmRSS) of the process instances judged (peaks of the two halves of the \
            time watched after warm-up):\n";
    out += &format!(
        "  {:<7} {:>8} {:>9} {:>10} {:>10} {:>10} {:>10} {:>9} {:>8}  {}\n",
        "process",
        "pid",
        "watched",
        "start",
        "warm",
        "1st half",
        "2nd half",
        "growth",
        "threads",
        "verdict"
    );
    for m in r.memory.iter().filter(|m| m.rss_flat.is_some()) {
        out += &format!(
            "  {:<7} {:>8} {:>8.0}s {:>10} {:>10} {:>10} {:>10} {:>9} {:>8}  {}\n",
            m.role,
            m.pid,
            m.watched_s,
            kib(m.start.rss_kib),
            m.warm.map_or("-".into(), |w| kib(w.rss_kib)),
            kib(m.first_half_max_kib),
            kib(m.second_half_max_kib),
            format!("{:+.1}M", m.growth_kib as f64 / 1024.0),
            format!("{}/{}", m.threads_max.0, m.threads_max.1),
            match (m.rss_flat, m.threads_flat) {
                (Some(true), Some(true)) => "flat",
                _ => "GREW",
            }
        );
    }
    let short: Vec<&Verdict> = r.memory.iter().filter(|m| m.rss_flat.is_none()).collect();
    if !short.is_empty() {
        let watched = short.iter().map(|m| m.watched_s);
        let end = short.iter().map(|m| m.end.rss_kib);
        out += &format!(
            "  not judged: {} instances ({}) killed {:.0}–{:.0} s after they started, RSS at \
             their end {}–{}\n",
            short.len(),
            short
                .iter()
                .map(|m| m.role.as_str())
                .collect::<BTreeSet<_>>()
                .into_iter()
                .collect::<Vec<_>>()
                .join(", "),
            watched.clone().fold(f64::INFINITY, f64::min),
            watched.fold(0.0, f64::max),
            kib(end.clone().min().unwrap_or(0)),
            kib(end.max().unwrap_or(0))
        );
    }
    let mut violations: Vec<&String> = r.tool_stream.first_violations.iter().collect();
    violations.extend(&r.hammer.violations);
    violations.extend(&r.ctl.violations);
    violations.extend(&r.viewers.violations);
    if !violations.is_empty() {
        out += "\nfirst violations:\n";
        for v in violations {
            out += &crate::table::note(v, W);
        }
    }
    out += &format!(
        "\n{}\n",
        if r.pass {
            "soak: every check passed"
        } else {
            "soak: FAILED"
        }
    );
    out
}
