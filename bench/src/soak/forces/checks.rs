//! The checks on the force records of every tool (the audits in the module above are their
//! evidence): within the clamp, zero at a stop, ramps, broken samples caught, the stream seen.

use super::*;

/// Safety invariant 1 on both records of every tool: every published force and every force
/// the device received finite and within the clamp.
pub(in crate::soak) fn within_clamp(e: &Evidence<'_>) -> Check {
    let settings = e.settings;
    let mut pass = true;
    let detail = per_tool(settings, |k| {
        let a = &e.audits[k];
        let (log_ok, log_detail) = match &e.force_logs[k] {
            Ok(l) => (
                l.non_finite == 0 && l.over_clamp == 0 && l.rows > 0,
                format!(
                    "force log {} rows (the device's last {:.0} s), {} with a force, max {:.3} N, \
                     {} non-finite, {} over",
                    l.rows,
                    l.rows as f64 / settings.rate_hz,
                    l.loaded_rows,
                    l.max_force,
                    l.non_finite,
                    l.over_clamp
                ),
            ),
            Err(e) => (false, format!("force log unreadable: {e}")),
        };
        pass &= a.counts.non_finite == 0 && a.counts.over_clamp == 0 && log_ok;
        format!(
            "{} tool states ({} with a force on the hand), max |F| {:.3} N, clamp {:.2} N, {} \
             non-finite, {} over; {log_detail}",
            a.received,
            a.loaded_ticks,
            a.max_force,
            settings.clamp_n,
            a.counts.non_finite,
            a.counts.over_clamp
        )
    });
    let together = match settings.devices {
        1 => String::new(),
        _ => format!(
            "; {} ticks with a force on every hand at once",
            e.all_loaded_ticks
        ),
    };
    check(
        "every force finite and within the clamp",
        pass,
        detail + &together,
    )
}

/// Safety invariant 3: every device's last force is zero.
pub(in crate::soak) fn zero_at_stop(e: &Evidence<'_>) -> Check {
    let mut pass = true;
    let detail = per_tool(e.settings, |k| {
        let last = e.force_logs[k].as_ref().ok().and_then(|l| l.last);
        pass &= last == Some([0.0; 3]);
        format!("last force in the device's record: {last:?}")
    });
    check(
        "zero force written when the haptic process stopped",
        pass,
        format!(
            "{detail}; haptic exits: 1 (at the end){}",
            match e.supervisor.haptic_restarts {
                Some(n) if n > 0 => format!(" + {n} restarts (earlier force logs overwritten)"),
                _ => String::new(),
            }
        ),
    )
}

/// Safety invariant 2: every episode of every tool ramps (see the module docs).
pub(in crate::soak) fn ramped(e: &Evidence<'_>) -> Check {
    let settings = e.settings;
    let mut pass = true;
    let detail = per_tool(settings, |k| {
        let (a, t) = (&e.audits[k], &e.tools[k]);
        pass &= a.counts.ramp() == 0 && t.episodes > 0;
        format!(
            "{} episodes ({} with a force on the hand), {} stale-frame, {} broken-sample, \
             longest {} ticks; violations: {} not flagged ramping, {} cut, {} held, {} late",
            t.episodes,
            t.episodes_loaded,
            t.episodes_stale,
            t.episodes_device,
            t.longest_episode_ticks,
            a.counts.not_ramping,
            a.counts.cut,
            a.counts.held,
            a.counts.late,
        )
    });
    check(
        "force ramped down on every stale frame and broken sample (not cut, not held, zero in time)",
        pass,
        format!(
            "{detail} (ramp {} ticks: at most {:.3} N a tick, zero from its {}th tick)",
            settings.ramp_ticks,
            settings.clamp_n / settings.ramp_ticks as f64,
            settings.ramp_ticks
        ),
    )
}

/// Every device's planned broken samples flagged on its tool's ticks, and no device error
/// elsewhere (a device's broken sample flags its own tool only).
pub(in crate::soak) fn samples_caught(e: &Evidence<'_>) -> Check {
    let plan = e.plan;
    let mut pass = true;
    let detail = per_tool(e.settings, |k| {
        let (a, t) = (&e.audits[k], &e.tools[k]);
        let samples = plan.samples.get(k).map_or(&[][..], Vec::as_slice);
        let by_kind = |f: SampleFault| samples.iter().filter(|s| s.fault == f).count();
        let (seen, flagged) = (t.planned_samples_seen, t.planned_samples_flagged);
        pass &=
            a.counts.sample_not_flagged == 0 && flagged == seen && a.unexpected_device_errors == 0;
        format!(
            "{} runs planned ({} NaN, {} out of the workspace), {seen} seen, {flagged} flagged \
             on every tick; {} planned ticks not flagged; {} device-error ticks elsewhere",
            samples.len(),
            by_kind(SampleFault::Nan),
            by_kind(SampleFault::OutOfWorkspace),
            a.counts.sample_not_flagged,
            a.unexpected_device_errors
        )
    });
    check(
        "every planned broken sample caught, and no other device error",
        pass,
        detail,
    )
}

/// The bench saw enough of every tool's stream for the checks above to mean something, and
/// every state it saw belongs to a tool of the run.
pub(in crate::soak) fn stream_observed(e: &Evidence<'_>) -> Check {
    let mut pass = e.foreign == 0;
    let detail = per_tool(e.settings, |k| {
        let (a, t) = (&e.audits[k], &e.tools[k]);
        pass &= t.coverage >= MIN_COVERAGE;
        format!(
            "{} of {} tool states received ({:.2} %)",
            a.received,
            a.received + a.missed,
            100.0 * t.coverage,
        )
    });
    check(
        "the tool stream was observed",
        pass,
        format!(
            "{detail}; {} haptic ticks in all{}",
            e.supervisor
                .haptic_ticks
                .map_or("?".into(), |t| t.to_string()),
            if e.foreign > 0 {
                format!("; {} states of a tool the run does not have", e.foreign)
            } else {
                String::new()
            }
        ),
    )
}
