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

/// A PASS/FAIL line, or one that does not apply to the run (N/A, with the reason).
#[derive(Debug, Clone, Serialize)]
pub struct Check {
    /// What is checked.
    pub name: String,
    /// Whether it held (true for a check that does not apply: it fails nothing).
    pub pass: bool,
    /// Whether it applies to this run (false: not checked, `detail` says why).
    pub applies: bool,
    /// The figures behind it.
    pub detail: String,
}

/// A check named `name`.
pub(super) fn check(name: &str, pass: bool, detail: String) -> Check {
    Check {
        name: name.into(),
        pass,
        applies: true,
        detail,
    }
}

/// A check named `name` that this run cannot make, and `why`.
pub(super) fn not_applicable(name: &str, why: String) -> Check {
    Check {
        name: name.into(),
        pass: true,
        applies: false,
        detail: why,
    }
}

/// The figures of every tool, `figures(k)` for tool `k`: as they are with one tool, each after
/// its tool's index and name (`tool 1 (device2): …`) with several.
pub(super) fn per_tool(settings: &Settings, mut figures: impl FnMut(usize) -> String) -> String {
    if settings.devices == 1 {
        return figures(0);
    }
    (0..settings.devices)
        .map(|k| format!("tool {k} ({}): {}", settings.tool_names[k], figures(k)))
        .collect::<Vec<_>>()
        .join("; ")
}

/// Everything the checks read: what the run was asked to do, what the bench observed while it
/// ran, and what it found after.
pub(super) struct Evidence<'a> {
    pub(super) settings: &'a Settings,
    pub(super) plan: &'a Schedule,
    /// Each tool's stream as it came in (tool `k`'s at `k`).
    pub(super) audits: &'a [ForceAudit],
    /// Tool states of a tool the run does not have.
    pub(super) foreign: u64,
    /// Ticks on which every tool had a force on the hand.
    pub(super) all_loaded_ticks: u64,
    /// Each tool's figures.
    pub(super) tools: &'a [ToolStreamReport],
    /// Each device's force record (tool `k`'s at `k`), or why it could not be read.
    pub(super) force_logs: &'a [Result<ForceLog, String>],
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
    /// Each tool's stream.
    pub(super) tool_streams: Vec<ToolStreamReport>,
    /// Ticks seen on which every tool had a force on the hand (with one tool: its loaded
    /// ticks).
    pub(super) ticks_every_hand_loaded: u64,
    /// Each device's force log (`null`: unreadable; its check says why).
    pub(super) force_logs: Vec<Option<ForceLog>>,
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
        "\nlop-bench soak — scene {}, {} device{}, {:.1} min after the first frame, seed {}, \
         haptic {:.0} Hz, clamp {:.2} N, ramp {} ticks, stale limit {:.0} ms\n",
        s.scene,
        s.devices,
        if s.devices == 1 { "" } else { "s" },
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
             of broken samples ({} ticks){}, {} viewer sessions, {} lopd ctl bursts, control \
             requests every {} ms; the script loops every {:.1} s",
            delivered(&r.injections, "deform", "kill"),
            delivered(&r.injections, "deform", "stop"),
            delivered(&r.injections, "haptic", "kill"),
            delivered(&r.injections, "haptic", "stop"),
            p.samples.iter().map(Vec::len).sum::<usize>(),
            p.samples.iter().flatten().map(|e| e.ticks).sum::<u64>(),
            if s.devices == 1 {
                String::new()
            } else {
                format!(
                    " on the {} devices ({})",
                    s.devices,
                    p.samples
                        .iter()
                        .map(|d| d.len().to_string())
                        .collect::<Vec<_>>()
                        .join(" + ")
                )
            },
            p.viewers.len(),
            p.ctl.len(),
            s.hammer_ms,
            s.script_period_s
        ),
        W,
    );
    out += "\n";
    for c in &r.checks {
        let verdict = match (c.applies, c.pass) {
            (false, _) => "N/A ",
            (true, true) => "PASS",
            (true, false) => "FAIL",
        };
        out += &format!("{verdict} {}\n", c.name);
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
    let mut violations: Vec<String> = Vec::new();
    for t in &r.tool_streams {
        violations.extend(t.first_violations.iter().map(|v| match r.settings.devices {
            1 => v.clone(),
            _ => format!("tool {}: {v}", t.tool),
        }));
    }
    let mut violations: Vec<&String> = violations.iter().collect();
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
