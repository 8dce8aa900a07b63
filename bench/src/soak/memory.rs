//! The pipeline's processes, found and sampled from `/proc` once a second: `lopd run` itself
//! and its children (`lopd haptic`, `lopd deform`, and the web viewer, which `lopd view`
//! replaces with `lop-view`). Each sample is the resident memory (`VmRSS`, with its anonymous
//! and shared-memory parts) and the thread count from `/proc/PID/status`.
//!
//! ## Flat after warm-up
//!
//! A process instance (one pid: a restarted process is a new instance and warms up again) is
//! watched from the end of its warm-up to its last sample, `T` minutes; that window is cut in
//! two halves, and its growth is the high-water mark of `VmRSS` in the second half minus that
//! of the first:
//!
//! `growth ≤ RSS_ALLOWANCE_KIB + RSS_ALLOWANCE_KIB_PER_MIN × T / 2`
//!
//! Why high-water marks and not the last sample minus the first: the deformation process's
//! heap breathes. A control request that rebuilds a body's model allocates the new model before
//! it frees the old one, and the allocator hands some of it back, so under the control hammer
//! its RSS swings between 55 and 70 MiB from one minute to the next (a 30-minute soak, sampled
//! each minute by hand: 56, 58, 63, 67, 63, 65, 66, 65, 62 MiB); the last sample minus the
//! first then says on which side of a swing the run happened to end. A leak lifts every later
//! peak: the second half's peak rises above the first's by the leak's rate times `T / 2`.
//!
//! Why these bounds: the soak is there to find memory that grows with work — per haptic tick,
//! per frame, per control request, per viewer connection, per restart of the other process.
//! The loop ticks and the deformation process publishes at 1 kHz, so a leak of a single
//! 16-byte allocation per tick or per frame is 0.9 MiB a minute; the control hammer sends about
//! 35 requests a second, so 450 bytes kept per request is the same. The per-minute allowance is
//! a quarter of that; with the fixed 4 MiB, such a leak fails any instance watched for 14
//! minutes or more (the deformation process restarted last in a 30-minute soak is watched for
//! about 15, the others for 29). The fixed allowance takes the one-off steps that are no leak:
//! the allocator's arenas and free lists settling at their high-water mark, shared-memory pages
//! first touched when a sample slot is first used, and the peaks of the breathing above, which
//! differ a little between two halves of a few minutes. Warm-up is the first [`warmup_s`] of an
//! instance's life: its start-up and one whole loop of the soak script (measured: a
//! deformation process judged after 10 s, before it had heated or dragged anything, grew by
//! 14 MiB in the next 20 s). An instance observed for less than [`MIN_OBSERVED_S`] after its
//! warm-up (a deformation process killed soon after its restart) is reported, not judged.
//!
//! Threads are judged the same way with no allowance: the most threads in the second half are
//! at most the most in the first (every thread lop starts is started at set-up).

use std::collections::BTreeMap;

use serde::Serialize;

use super::report::{check, not_applicable, Check, Evidence};

/// Fixed allowance for RSS growth after warm-up, KiB.
pub const RSS_ALLOWANCE_KIB: u64 = 4096;
/// Allowance per minute observed after warm-up, KiB (see the module docs).
pub const RSS_ALLOWANCE_KIB_PER_MIN: u64 = 256;
/// Least time after warm-up for an instance to be judged, s.
pub const MIN_OBSERVED_S: f64 = 10.0;

/// Warm-up of a process instance when the soak script loops every `period_s`: one loop, so the
/// instance has met every situation of the run once (every body touched, grabbed, heated,
/// dragged, every model switch), plus [`WARMUP_LOAD_S`] for its start-up.
pub fn warmup_s(period_s: f64) -> f64 {
    period_s + WARMUP_LOAD_S
}

/// The shortest soak whose memory is judged when the script loops every `period_s`: the
/// warm-up, the least watch and a second, in whole seconds.
pub fn shortest_judged_s(period_s: f64) -> f64 {
    (warmup_s(period_s) + MIN_OBSERVED_S + 1.0).ceil()
}

/// The start-up part of the warm-up, s: a process starting, the scene loaded, the first frame.
pub const WARMUP_LOAD_S: f64 = 10.0;

/// One reading of `/proc/PID/status`.
#[derive(Debug, Clone, Copy, Default, Serialize, PartialEq)]
pub struct Reading {
    /// Seconds since the instance was first seen.
    pub age_s: f64,
    /// `VmRSS`, KiB.
    pub rss_kib: u64,
    /// `RssAnon`, KiB.
    pub anon_kib: u64,
    /// `RssShmem`, KiB.
    pub shmem_kib: u64,
    /// `Threads`.
    pub threads: u64,
}

/// Parses the fields of [`Reading`] from `/proc/PID/status` text.
pub fn parse_status(text: &str) -> Option<Reading> {
    let field = |name: &str| -> Option<u64> {
        let line = text.lines().find(|l| l.starts_with(name))?;
        line[name.len()..].split_whitespace().next()?.parse().ok()
    };
    Some(Reading {
        age_s: 0.0,
        rss_kib: field("VmRSS:")?,
        anon_kib: field("RssAnon:").unwrap_or(0),
        shmem_kib: field("RssShmem:").unwrap_or(0),
        threads: field("Threads:")?,
    })
}

/// One process instance's history.
#[derive(Debug, Clone, Serialize)]
pub struct Instance {
    /// Process id.
    pub pid: u32,
    /// `run`, `haptic`, `deform` or `view`.
    pub role: String,
    /// Seconds after the bench's start it was first seen.
    pub first_seen_s: f64,
    /// Whether it was alive at the last scan.
    pub alive: bool,
    #[serde(skip)]
    readings: Vec<Reading>,
}

/// How an instance's memory and threads came out.
#[derive(Debug, Clone, Serialize)]
pub struct Verdict {
    /// Process id.
    pub pid: u32,
    /// Role.
    pub role: String,
    /// Seconds after the bench's start it was first seen.
    pub first_seen_s: f64,
    /// Seconds it was watched.
    pub watched_s: f64,
    /// First reading.
    pub start: Reading,
    /// Reading at the end of warm-up, if it lived that long.
    pub warm: Option<Reading>,
    /// Last reading.
    pub end: Reading,
    /// Minutes observed after warm-up (`T`).
    pub observed_min: f64,
    /// Highest RSS in the first half of the window after warm-up, KiB.
    pub first_half_max_kib: u64,
    /// Highest RSS in the second half, KiB.
    pub second_half_max_kib: u64,
    /// Most threads in the first half and in the second.
    pub threads_max: (u64, u64),
    /// `second_half_max − first_half_max`, KiB (negative: lower).
    pub growth_kib: i64,
    /// The bound it is judged against, KiB.
    pub allowance_kib: u64,
    /// `Some(pass)` if judged, `None` if it did not live long enough after warm-up.
    pub rss_flat: Option<bool>,
    /// `Some(pass)`: the most threads in the second half ≤ the most in the first.
    pub threads_flat: Option<bool>,
    /// Seconds of age and RSS in KiB, one reading every [`SERIES_EVERY_S`].
    pub series: Vec<(f64, u64)>,
}

/// Spacing of the readings kept in a verdict's series, s.
pub const SERIES_EVERY_S: f64 = 10.0;

impl Instance {
    /// Judges the instance against a warm-up of `warmup` seconds.
    pub fn verdict(&self, warmup: f64) -> Option<Verdict> {
        let start = *self.readings.first()?;
        let end = *self.readings.last()?;
        let post: Vec<&Reading> = self.readings.iter().filter(|r| r.age_s >= warmup).collect();
        let warm = post.first().map(|r| **r);
        let observed_s = warm.map_or(0.0, |w| end.age_s - w.age_s);
        let mid = warm.map_or(0.0, |w| w.age_s) + observed_s / 2.0;
        let half = |second: bool| {
            post.iter()
                .filter(|r| (r.age_s >= mid) == second)
                .fold((0, 0), |(rss, th), r| {
                    (rss.max(r.rss_kib), th.max(r.threads))
                })
        };
        let (first_rss, first_threads) = half(false);
        let (second_rss, second_threads) = half(true);
        let observed_min = observed_s / 60.0;
        let allowance = RSS_ALLOWANCE_KIB
            + (RSS_ALLOWANCE_KIB_PER_MIN as f64 * observed_min / 2.0).round() as u64;
        let judged = warm.is_some() && observed_s >= MIN_OBSERVED_S;
        let growth = second_rss as i64 - first_rss as i64;
        let mut series = Vec::new();
        let mut next = 0.0;
        for r in &self.readings {
            if r.age_s >= next {
                series.push((r.age_s.round(), r.rss_kib));
                next = r.age_s + SERIES_EVERY_S;
            }
        }
        Some(Verdict {
            pid: self.pid,
            role: self.role.clone(),
            first_seen_s: self.first_seen_s,
            watched_s: end.age_s,
            start,
            warm,
            end,
            observed_min,
            first_half_max_kib: first_rss,
            second_half_max_kib: second_rss,
            threads_max: (first_threads, second_threads),
            growth_kib: growth,
            allowance_kib: allowance,
            rss_flat: judged.then_some(growth <= allowance as i64),
            threads_flat: judged.then_some(second_threads <= first_threads),
            series,
        })
    }
}

/// The watched processes.
#[derive(Debug, Default)]
pub struct ProcessWatch {
    supervisor: u32,
    instances: BTreeMap<u32, Instance>,
}

/// Parent pid from `/proc/PID/stat` text (the field after the parenthesised command name,
/// which may itself hold spaces and parentheses).
pub fn parent_pid(stat: &str) -> Option<u32> {
    let rest = &stat[stat.rfind(')')? + 1..];
    rest.split_whitespace().nth(1)?.parse().ok()
}

/// A process's arguments.
pub fn cmdline(pid: u32) -> Vec<String> {
    std::fs::read(format!("/proc/{pid}/cmdline"))
        .map(|raw| {
            raw.split(|&b| b == 0)
                .filter(|a| !a.is_empty())
                .map(|a| String::from_utf8_lossy(a).into_owned())
                .collect()
        })
        .unwrap_or_default()
}

/// The role of a child of `lopd run` from its arguments.
fn role(args: &[String]) -> String {
    let exe = args.first().map(String::as_str).unwrap_or("");
    if exe.ends_with("lop-view") {
        return "view".into();
    }
    args.get(1).cloned().unwrap_or_else(|| "?".into())
}

/// Every process whose parent is `parent`.
pub fn children(parent: u32) -> Vec<u32> {
    let mut out: Vec<u32> = pids()
        .filter(|&pid| {
            std::fs::read_to_string(format!("/proc/{pid}/stat"))
                .is_ok_and(|stat| parent_pid(&stat) == Some(parent))
        })
        .collect();
    out.sort_unstable();
    out
}

/// Every process id in `/proc` now (none if it cannot be read).
pub fn pids() -> impl Iterator<Item = u32> {
    std::fs::read_dir("/proc")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|entry| entry.file_name().to_string_lossy().parse::<u32>().ok())
}

impl ProcessWatch {
    /// Watches `lopd run` (pid `supervisor`) and its children.
    pub fn new(supervisor: u32) -> ProcessWatch {
        ProcessWatch {
            supervisor,
            instances: BTreeMap::new(),
        }
    }

    /// Scans for the processes and samples each; `now_s` is seconds since the bench started.
    pub fn sample(&mut self, now_s: f64) {
        let mut live = children(self.supervisor);
        live.push(self.supervisor);
        for inst in self.instances.values_mut() {
            inst.alive = false;
        }
        for pid in live {
            let Some(mut r) = std::fs::read_to_string(format!("/proc/{pid}/status"))
                .ok()
                .as_deref()
                .and_then(parse_status)
            else {
                continue;
            };
            let inst = self.instances.entry(pid).or_insert_with(|| Instance {
                pid,
                role: if pid == self.supervisor {
                    "run".into()
                } else {
                    role(&cmdline(pid))
                },
                first_seen_s: now_s,
                alive: true,
                readings: Vec::new(),
            });
            inst.alive = true;
            r.age_s = now_s - inst.first_seen_s;
            inst.readings.push(r);
        }
    }

    /// The live instance of `role`, if exactly one is alive.
    pub fn live(&self, role: &str) -> Option<u32> {
        let mut it = self
            .instances
            .values()
            .filter(|i| i.alive && i.role == role);
        let first = it.next()?;
        it.next().is_none().then_some(first.pid)
    }

    /// Every pid seen.
    pub fn pids(&self) -> Vec<u32> {
        self.instances.keys().copied().collect()
    }

    /// Instances per role.
    pub fn instances_of(&self, role: &str) -> usize {
        self.instances.values().filter(|i| i.role == role).count()
    }

    /// Every instance's verdict, in order of first sight.
    pub fn verdicts(&self, warmup: f64) -> Vec<Verdict> {
        let mut v: Vec<Verdict> = self
            .instances
            .values()
            .filter_map(|i| i.verdict(warmup))
            .collect();
        v.sort_by(|a, b| a.first_seen_s.total_cmp(&b.first_seen_s));
        v
    }
}

// ---------------------------------------------------------------------------------------------
// The checks on this evidence.

/// A size in KiB as MiB, for the report.
pub fn kib(k: u64) -> String {
    format!("{:.1} MiB", k as f64 / 1024.0)
}

/// Every long-lived process's memory and threads flat after its warm-up (the bound and why:
/// the module docs).
pub(super) fn check_flat(e: &Evidence<'_>) -> Check {
    const NAME: &str = "memory and threads of every process flat after warm-up";
    let memory = e.memory;
    let warmup = e.settings.warmup_s;
    if e.settings.seconds < e.settings.memory_from_s {
        return not_applicable(
            NAME,
            format!(
                "not judged: the run lasted {:.0} s, and a process's memory is judged after a \
                 warm-up of {warmup:.0} s (a loop of the script and the start-up), then watched \
                 for at least {MIN_OBSERVED_S:.0} s: from {:.0} s on",
                e.settings.seconds, e.settings.memory_from_s
            ),
        );
    }
    let judged: Vec<&Verdict> = memory.iter().filter(|m| m.rss_flat.is_some()).collect();
    let grew: Vec<String> = judged
        .iter()
        .filter(|m| m.rss_flat == Some(false) || m.threads_flat == Some(false))
        .map(|m| {
            format!(
                "{} {}: peak {} in the first half, {} in the second ({:+.1} MiB over {:.1} min, \
                 allowed {}), threads {} then {}",
                m.role,
                m.pid,
                kib(m.first_half_max_kib),
                kib(m.second_half_max_kib),
                m.growth_kib as f64 / 1024.0,
                m.observed_min,
                kib(m.allowance_kib),
                m.threads_max.0,
                m.threads_max.1
            )
        })
        .collect();
    // The haptic process must be judged too unless it was killed too late in the run for the
    // new one to outlive its warm-up and the watch (a short run; its lives are reported).
    let last_haptic_kill = e
        .injections
        .iter()
        .filter(|i| i.process == "haptic" && i.kind == "kill")
        .filter_map(|i| i.at_s)
        .fold(f64::NEG_INFINITY, f64::max);
    let haptic_judgeable = e.settings.seconds - last_haptic_kill >= warmup + MIN_OBSERVED_S + 5.0;
    let long_lived = ["run", "haptic", "view"]
        .iter()
        .filter(|r| **r != "haptic" || haptic_judgeable)
        .all(|r| judged.iter().any(|m| m.role == *r));
    check(
        NAME,
        grew.is_empty() && long_lived,
        format!(
            "{} of {} process instances judged (warm-up {:.0} s, then at least {:.0} s \
             watched): the RSS peak of the second half of the watched time over the first's \
             at most {} + {} per minute of half (the others did not live that long){}",
            judged.len(),
            memory.len(),
            warmup,
            MIN_OBSERVED_S,
            kib(RSS_ALLOWANCE_KIB),
            kib(RSS_ALLOWANCE_KIB_PER_MIN),
            if grew.is_empty() {
                if long_lived {
                    String::new()
                } else {
                    "; lopd run, haptic and view must each be judged: run longer".into()
                }
            } else {
                format!("; grew: {}", grew.join("; "))
            }
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn status_and_stat_are_parsed() {
        let status = "Name:\tlopd\nVmRSS:\t  51200 kB\nRssAnon:\t 30000 kB\nRssFile:\t 1000 kB\n\
                      RssShmem:\t 20200 kB\nThreads:\t7\n";
        let r = parse_status(status).unwrap();
        assert_eq!(
            (r.rss_kib, r.anon_kib, r.shmem_kib, r.threads),
            (51200, 30000, 20200, 7)
        );
        assert!(parse_status("Name:\tx\n").is_none());
        assert_eq!(parent_pid("123 (lop d) (x) S 77 123 123 0 -1"), Some(77));
        // Our own process: its parent is the test harness's.
        let me = std::fs::read_to_string("/proc/self/stat").unwrap();
        assert!(parent_pid(&me).is_some());
    }

    fn instance(rss: &[(f64, u64, u64)]) -> Instance {
        Instance {
            pid: 1,
            role: "deform".into(),
            first_seen_s: 0.0,
            alive: true,
            readings: rss
                .iter()
                .map(|&(age_s, rss_kib, threads)| Reading {
                    age_s,
                    rss_kib,
                    threads,
                    ..Reading::default()
                })
                .collect(),
        }
    }

    #[test]
    fn growth_after_warm_up_is_judged_against_the_allowance() {
        // Grows during warm-up (not counted), then flat within the allowance.
        let flat = instance(&[(0.0, 1000, 5), (10.0, 90_000, 7), (70.0, 92_000, 7)]);
        let v = flat.verdict(10.0).unwrap();
        assert_eq!(
            (v.first_half_max_kib, v.second_half_max_kib),
            (90_000, 92_000)
        );
        assert_eq!(v.growth_kib, 2000);
        assert_eq!(
            v.allowance_kib,
            RSS_ALLOWANCE_KIB + RSS_ALLOWANCE_KIB_PER_MIN / 2
        );
        assert_eq!((v.rss_flat, v.threads_flat), (Some(true), Some(true)));
        // A leak of 1 MiB a minute over 20 minutes, one reading a minute.
        let leak: Vec<(f64, u64, u64)> = std::iter::once((0.0, 1000, 5))
            .chain((0..=20).map(|m| (10.0 + 60.0 * m as f64, 90_000 + 1024 * m, 7)))
            .collect();
        let v = instance(&leak).verdict(10.0).unwrap();
        assert_eq!(v.growth_kib, 11 * 1024);
        assert_eq!(v.rss_flat, Some(false));
        // Breathing by 12 MiB from minute to minute, no trend: flat.
        let breathing: Vec<(f64, u64, u64)> = std::iter::once((0.0, 1000, 5))
            .chain((0..=20).map(|m| (10.0 + 60.0 * m as f64, 56_000 + 12_000 * (m % 2), 7)))
            .collect();
        let v = instance(&breathing).verdict(10.0).unwrap();
        assert_eq!(v.growth_kib, 0);
        assert_eq!(v.rss_flat, Some(true));
        // A thread more at the end.
        let threads = instance(&[(0.0, 1000, 5), (10.0, 90_000, 7), (70.0, 90_000, 8)]);
        assert_eq!(threads.verdict(10.0).unwrap().threads_flat, Some(false));
        // Killed 5 s after its warm-up: reported, not judged.
        let short = instance(&[(0.0, 1000, 5), (10.0, 90_000, 7), (15.0, 99_000, 7)]);
        assert_eq!(short.verdict(10.0).unwrap().rss_flat, None);
    }

    #[test]
    fn warm_up_is_one_script_loop_and_the_start_up() {
        assert_eq!(warmup_s(23.0), 33.0);
    }
}
