//! What `lopd run`'s log says about its supervision (restarts, its exit, the services it
//! removed), and the checks on it: every killed process restarted, and no other; a clean
//! stop.

use serde::Serialize;

use super::report::{check, Check, Evidence};

/// What the supervisor's log says.
#[derive(Debug, Clone, Default, Serialize)]
pub(super) struct SupervisorReport {
    pub(super) exit: String,
    pub(super) haptic_restarts: Option<u64>,
    pub(super) deform_restarts: Option<u64>,
    pub(super) no_service_left: bool,
    pub(super) haptic_ticks: Option<u64>,
}

impl SupervisorReport {
    /// The report from `lopd run`'s exit (`exit`: its status, or why stopping it failed) and
    /// its log.
    pub(super) fn read(exit: String, log: &str) -> SupervisorReport {
        SupervisorReport {
            exit,
            haptic_restarts: log_line(log, &["lopd run: stopped"])
                .and_then(|l| number_after(&l, "haptic restarts")),
            deform_restarts: log_line(log, &["lopd run: stopped"])
                .and_then(|l| number_after(&l, "deform restarts")),
            no_service_left: log_line(log, &["no service left under"]).is_some(),
            haptic_ticks: log_line(log, &["haptic loop stopped after"])
                .and_then(|l| number_after(&l, "stopped after")),
        }
    }
}

/// The first line of `log` containing every one of `parts`.
pub(super) fn log_line(log: &str, parts: &[&str]) -> Option<String> {
    log.lines()
        .rev()
        .find(|l| parts.iter().all(|p| l.contains(p)))
        .map(str::to_string)
}

/// The number right after `label` in `line`.
pub(super) fn number_after(line: &str, label: &str) -> Option<u64> {
    let rest = &line[line.find(label)? + label.len()..];
    let digits: String = rest
        .trim_start()
        .chars()
        .take_while(char::is_ascii_digit)
        .collect();
    digits.parse().ok()
}

// ---------------------------------------------------------------------------------------------
// The checks on this evidence.

/// Safety invariant 4: the supervisor restarted every killed process, and no other: the
/// haptic loop only when it was killed.
pub(super) fn check_restarts(e: &Evidence<'_>) -> Check {
    let kills = super::injections::delivered(e.injections, "deform", "kill");
    let haptic_kills = super::injections::delivered(e.injections, "haptic", "kill");
    let segments: Vec<String> = e.audits.iter().map(|a| a.segments.to_string()).collect();
    check(
        "supervisor restarted every killed process, and only those",
        e.supervisor.deform_restarts == Some(kills as u64)
            && e.supervisor.haptic_restarts == Some(haptic_kills as u64)
            && e.audits.iter().all(|a| a.segments == haptic_kills as u64),
        format!(
            "deform restarts {:?} for {kills} kills, haptic restarts {:?} for {haptic_kills} \
             kills ({} new haptic processes seen in the tool stream{}), {} deformation and {} \
             haptic processes in all",
            e.supervisor.deform_restarts,
            e.supervisor.haptic_restarts,
            segments.join(" / "),
            if segments.len() > 1 {
                " of each tool"
            } else {
                ""
            },
            e.watch.instances_of("deform"),
            e.watch.instances_of("haptic")
        ),
    )
}

/// `lopd run` exited 0 and said it removed its services.
pub(super) fn check_clean_exit(e: &Evidence<'_>) -> Check {
    let supervisor = e.supervisor;
    check(
        "lopd run stopped cleanly and removed its services",
        supervisor.exit.contains("exit status: 0") && supervisor.no_service_left,
        format!(
            "exit: {}; \"no service left\" logged: {}",
            supervisor.exit, supervisor.no_service_left
        ),
    )
}
