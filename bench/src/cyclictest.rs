//! `cyclictest` (Debian/Ubuntu package `rt-tests`) as a yardstick: the wake-up latency of a bare
//! `SCHED_FIFO` thread on this machine, measured while the pipeline runs. The haptic loop can
//! never wake up more precisely than this floor; on a shared VM it is the honest comparison.
//!
//! How it is run (and why):
//! - one thread, absolute `clock_nanosleep` every `interval` µs (its default clock and mode), for
//!   exactly `loops` wake-ups, so it covers the bench's measuring window;
//! - `SCHED_FIFO` one priority below the haptic loop, so it can never delay the loop it is
//!   compared with; not pinned (the haptic loop owns its core);
//! - `--default-system`: cyclictest would otherwise write 0 to `/dev/cpu_dma_latency` (no deep
//!   C-states) for its lifetime, which would also improve the haptic loop's figures and make the
//!   run unrepresentative of the pipeline alone;
//! - `--histogram`: the per-µs histogram printed at exit, from which p50/p99/p99.9 are derived
//!   (max, min, avg come from its summary).
//!
//! `--mlockall` and `--priority` need privileges; [`probe`] tries without `--mlockall` and then
//! without `--priority` before giving up (cyclictest 2.x refuses to run entirely without
//! real-time privileges).

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::thread::JoinHandle;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use serde::Serialize;

use crate::pipeline::ChildGuard;
use crate::table::Row;

/// Largest latency the histogram tracks, µs; beyond it samples count as overflows.
const HISTOGRAM_MAX_US: u64 = 10_000;

/// `cyclictest` on `PATH`, if installed.
pub fn find() -> Option<PathBuf> {
    use std::os::unix::fs::PermissionsExt;
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join("cyclictest"))
        .find(|p| {
            std::fs::metadata(p)
                .map(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
                .unwrap_or(false)
        })
}

/// How cyclictest will be run (what the privileges allow).
#[derive(Debug, Clone)]
pub struct Plan {
    exe: PathBuf,
    /// `--priority`, if permitted.
    pub priority: Option<u8>,
    /// `--mlockall`, if permitted.
    pub mlock: bool,
}

fn base_args(plan: &Plan, interval_us: u64, loops: u64) -> Vec<String> {
    let mut args = vec![
        "--quiet".to_string(),
        "--threads=1".to_string(),
        "--default-system".to_string(),
        format!("--interval={interval_us}"),
        format!("--loops={loops}"),
        format!("--histogram={HISTOGRAM_MAX_US}"),
    ];
    if plan.mlock {
        args.push("--mlockall".into());
    }
    if let Some(p) = plan.priority {
        args.push(format!("--priority={p}"));
    }
    args
}

/// Finds the options this process may use by running a few 1 ms loops: with `--mlockall` and
/// `--priority`, then without `--mlockall`, then without `--priority`. Errors with cyclictest's
/// own message if none runs.
pub fn probe(exe: &Path, priority: u8) -> Result<Plan> {
    let mut last_err = String::new();
    for (prio, mlock) in [
        (Some(priority), true),
        (Some(priority), false),
        (None, false),
    ] {
        let plan = Plan {
            exe: exe.to_path_buf(),
            priority: prio,
            mlock,
        };
        let mut cmd = Command::new(exe);
        cmd.args(base_args(&plan, 1000, 5))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        let mut guard = ChildGuard::spawn("cyclictest probe", cmd, Duration::from_secs(1))?;
        let stderr = guard.child_mut().and_then(|c| c.stderr.take());
        let status = guard.wait_for(Duration::from_secs(5));
        let mut err = String::new();
        if let Some(mut s) = stderr {
            let _ = s.read_to_string(&mut err);
        }
        if status.is_some_and(|s| s.success()) {
            return Ok(plan);
        }
        last_err = err.trim().replace('\n', " ");
    }
    bail!(
        "{last_err} (cyclictest needs real-time privileges: root, CAP_SYS_NICE or an \
         RLIMIT_RTPRIO limit)"
    )
}

/// A cyclictest running concurrently with the pipeline.
pub struct Running {
    guard: ChildGuard,
    stdout: Option<JoinHandle<String>>,
    stderr: Option<JoinHandle<String>>,
    /// The command line, for the report.
    pub command: String,
    plan: Plan,
}

fn reader<R: Read + Send + 'static>(pipe: Option<R>) -> Option<JoinHandle<String>> {
    let mut pipe = pipe?;
    Some(std::thread::spawn(move || {
        let mut s = String::new();
        let _ = pipe.read_to_string(&mut s);
        s
    }))
}

/// Starts `loops` wake-ups every `interval_us`.
pub fn start(plan: &Plan, interval_us: u64, loops: u64) -> Result<Running> {
    let args = base_args(plan, interval_us, loops);
    let command = format!("cyclictest {}", args.join(" "));
    let mut cmd = Command::new(&plan.exe);
    cmd.args(&args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut guard = ChildGuard::spawn("cyclictest", cmd, Duration::from_secs(2))?;
    let child = guard.child_mut().expect("just spawned");
    let stdout = reader(child.stdout.take());
    let stderr = reader(child.stderr.take());
    Ok(Running {
        guard,
        stdout,
        stderr,
        command,
        plan: plan.clone(),
    })
}

/// What cyclictest measured.
#[derive(Debug, Clone, Serialize)]
pub struct Outcome {
    /// The command line.
    pub command: String,
    /// `SCHED_FIFO` priority it ran at (`None`: its default).
    pub priority: Option<u8>,
    /// Whether it locked its memory.
    pub mlocked: bool,
    /// Smallest latency, µs.
    pub min_us: f64,
    /// Mean latency, µs.
    pub avg_us: f64,
    /// Samples above the histogram's range.
    pub overflows: u64,
    /// Percentiles (derived from the 1 µs histogram; max from the summary).
    pub row: Row,
}

impl Running {
    /// Waits up to `limit` for it to finish (then SIGTERM, which makes it print what it has) and
    /// parses its output.
    pub fn finish(mut self, limit: Duration, key: &str, label: &str) -> Result<Outcome> {
        let status = match self.guard.wait_for(limit) {
            Some(s) => Some(s),
            None => self.guard.stop(),
        };
        let out = self
            .stdout
            .take()
            .and_then(|h| h.join().ok())
            .unwrap_or_default();
        let err = self
            .stderr
            .take()
            .and_then(|h| h.join().ok())
            .unwrap_or_default();
        let parsed = parse(&out).with_context(|| {
            format!(
                "{} ({}): {}",
                self.command,
                status.map_or("killed".to_string(), |s| s.to_string()),
                err.trim()
            )
        })?;
        Ok(Outcome {
            command: self.command.clone(),
            priority: self.plan.priority,
            mlocked: self.plan.mlock,
            min_us: parsed.min_us as f64,
            avg_us: parsed.avg_us as f64,
            overflows: parsed.overflows,
            row: parsed.row(key, label),
        })
    }
}

/// cyclictest's `--histogram` output, summed over threads.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Parsed {
    /// `(latency µs, samples)` for non-empty buckets, ascending.
    pub buckets: Vec<(u64, u64)>,
    /// `# Total:`.
    pub total: u64,
    /// `# Min Latencies:` (smallest over threads), µs.
    pub min_us: u64,
    /// `# Avg Latencies:` (first thread), µs.
    pub avg_us: u64,
    /// `# Max Latencies:` (largest over threads), µs.
    pub max_us: u64,
    /// `# Histogram Overflows:`.
    pub overflows: u64,
}

fn summary_values(rest: &str) -> Vec<u64> {
    rest.split_whitespace()
        .filter_map(|v| v.parse().ok())
        .collect()
}

/// Parses the histogram lines (`NNNNNN CCCCCC [CCCCCC…]`) and the `# …:` summary.
pub fn parse(text: &str) -> Result<Parsed> {
    let mut p = Parsed::default();
    let mut saw_total = false;
    for line in text.lines() {
        let line = line.trim();
        if let Some(rest) = line.strip_prefix('#') {
            let Some((name, rest)) = rest.split_once(':') else {
                continue;
            };
            let vals = summary_values(rest);
            match name.trim() {
                "Total" => {
                    p.total = vals.iter().sum();
                    saw_total = true;
                }
                "Min Latencies" => p.min_us = vals.iter().copied().min().unwrap_or(0),
                "Avg Latencies" => p.avg_us = vals.first().copied().unwrap_or(0),
                "Max Latencies" => p.max_us = vals.iter().copied().max().unwrap_or(0),
                "Histogram Overflows" => p.overflows = vals.iter().sum(),
                _ => {}
            }
            continue;
        }
        let mut fields = line.split_whitespace();
        let Some(Ok(bucket)) = fields.next().map(str::parse::<u64>) else {
            continue;
        };
        let counts: Option<Vec<u64>> = fields.map(|f| f.parse().ok()).collect();
        let Some(counts) = counts.filter(|c| !c.is_empty()) else {
            continue;
        };
        let n: u64 = counts.iter().sum();
        if n > 0 {
            p.buckets.push((bucket, n));
        }
    }
    if !saw_total {
        bail!("no histogram summary in cyclictest's output");
    }
    p.buckets.sort_unstable();
    Ok(p)
}

impl Parsed {
    /// The latency (µs) at quantile `q`: the smallest bucket whose cumulative count reaches
    /// `q × total`; in the overflow the summary's max.
    pub fn quantile_us(&self, q: f64) -> u64 {
        let total = self.total.max(self.buckets.iter().map(|b| b.1).sum());
        if total == 0 {
            return 0;
        }
        let want = ((q * total as f64).ceil() as u64).max(1);
        let mut seen = 0;
        for &(v, n) in &self.buckets {
            seen += n;
            if seen >= want {
                return v;
            }
        }
        self.max_us
    }

    /// As a table row.
    pub fn row(&self, key: &str, label: &str) -> Row {
        let max = self.max_us.max(self.buckets.last().map_or(0, |b| b.0));
        Row {
            key: key.into(),
            label: label.into(),
            count: self.total,
            p50_us: self.quantile_us(0.5) as f64,
            p99_us: self.quantile_us(0.99) as f64,
            p999_us: self.quantile_us(0.999) as f64,
            max_us: max as f64,
            devices: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SAMPLE: &str = "# /dev/cpu_dma_latency set to 0us
# Histogram
000000 000000
000014 000000
000015 000102
000016 001038
000017 000231
000018 000347
000019 000149
000020 000063
000021 000028
000030 000036
000040 000005
000130 000001
000131 000000
# Total: 000002000
# Min Latencies: 00015
# Avg Latencies: 00017
# Max Latencies: 00130
# Histogram Overflows: 00000
# Histogram Overflow at cycle number:
# Thread 0:
";

    #[test]
    fn parses_histogram_and_summary() {
        let p = parse(SAMPLE).unwrap();
        assert_eq!(p.total, 2000);
        assert_eq!(
            (p.min_us, p.avg_us, p.max_us, p.overflows),
            (15, 17, 130, 0)
        );
        assert_eq!(p.buckets.first(), Some(&(15, 102)));
        assert_eq!(p.buckets.iter().map(|b| b.1).sum::<u64>(), 2000);
        // 1000th sample is in the 16 µs bucket (102 + 1038 ≥ 1000).
        assert_eq!(p.quantile_us(0.5), 16);
        // 99 % = 1980th sample: cumulative 1958 up to 21 µs, 1994 up to 30 µs.
        assert_eq!(p.quantile_us(0.99), 30);
        assert_eq!(p.quantile_us(0.999), 40);
        let r = p.row("c", "c");
        assert_eq!((r.count, r.max_us), (2000, 130.0));
    }

    #[test]
    fn overflow_quantiles_use_the_max() {
        let text = "000010 000009\n# Total: 000000010\n# Max Latencies: 20000\n# Histogram Overflows: 00001\n";
        let p = parse(text).unwrap();
        assert_eq!(p.quantile_us(0.5), 10);
        assert_eq!(p.quantile_us(0.999), 20000);
        assert_eq!(p.overflows, 1);
    }

    #[test]
    fn output_without_summary_is_an_error() {
        assert!(parse("Unable to change scheduling policy!\n").is_err());
    }
}
