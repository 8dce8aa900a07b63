//! The haptic loop's statistics, split so the RT thread only records: it fills a window of
//! preallocated histograms (wake-up jitter, tick compute, frame age, frame age in contact) and,
//! about four times a second, swaps the full window for an empty one through two lock-free
//! rings. The publisher thread takes the full window, computes its quantiles (the scans over
//! every bucket that used to run on the RT thread), adds it to the totals since warm-up,
//! clears it and sends it back. With no empty window to swap in (the publisher fell behind) the
//! RT thread keeps recording into the one it has: the next sample covers a longer window and
//! nothing is allocated, freed or lost.

use anyhow::Result;
use hdrhistogram::Histogram;
use lop_ipc::{HapticTelemetry, Percentiles, CONTRACT_VERSION};

/// The quantities timed per tick, by index.
pub(crate) const JITTER: usize = 0;
pub(crate) const COMPUTE: usize = 1;
pub(crate) const FRAME_AGE: usize = 2;
/// The frame age of ticks that rendered a contact (the tool pressing or holding a body): how
/// old the surface under the hand was.
pub(crate) const FRAME_AGE_CONTACT: usize = 3;
const QUANTITIES: usize = 4;
/// Windows in circulation: one being recorded, the others in flight or waiting empty.
const WINDOWS: usize = 4;

fn histogram() -> Result<Histogram<u64>> {
    Ok(Histogram::<u64>::new_with_bounds(1, 10_000_000_000, 2)?)
}

/// One window of the loop's statistics: the counters at its end and its histograms.
pub struct TelemetryWindow {
    /// The sample without its quantiles (the publisher fills them in).
    counters: HapticTelemetry,
    histograms: [Histogram<u64>; QUANTITIES],
}

impl TelemetryWindow {
    fn new() -> Result<Box<TelemetryWindow>> {
        Ok(Box::new(TelemetryWindow {
            counters: HapticTelemetry::default(),
            histograms: [histogram()?, histogram()?, histogram()?, histogram()?],
        }))
    }
}

/// The RT thread's end: records into the current window, swaps it when asked.
pub struct TelemetryTx {
    current: Box<TelemetryWindow>,
    full: rtrb::Producer<Box<TelemetryWindow>>,
    empty: rtrb::Consumer<Box<TelemetryWindow>>,
}

impl TelemetryTx {
    /// Records `v` ns of quantity `which` (allocation-free).
    #[inline]
    pub(crate) fn record(&mut self, which: usize, v: u64) {
        // saturating_record never allocates and never fails.
        self.current.histograms[which].saturating_record(v.max(1));
    }

    /// Ends the window with `counters` if an empty one can take its place; false (and the
    /// window goes on) otherwise. Allocation-free.
    pub(crate) fn send(&mut self, counters: HapticTelemetry) -> bool {
        if self.full.is_full() {
            return false;
        }
        let Ok(next) = self.empty.pop() else {
            return false;
        };
        let mut done = std::mem::replace(&mut self.current, next);
        done.counters = counters;
        // Cannot fail: checked for room above, and only this thread pushes.
        let _ = self.full.push(done);
        true
    }
}

/// The publisher's end: turns full windows into telemetry samples.
pub struct TelemetryRx {
    full: rtrb::Consumer<Box<TelemetryWindow>>,
    empty: rtrb::Producer<Box<TelemetryWindow>>,
    totals: [Histogram<u64>; QUANTITIES],
    /// Windows that end by this tick are start-up, left out of the totals.
    warmup_ticks: u64,
}

impl TelemetryRx {
    /// The next sample, if a window has arrived: its quantiles and the totals since warm-up.
    pub fn pop(&mut self) -> Option<HapticTelemetry> {
        let mut w = self.full.pop().ok()?;
        let h = &w.histograms;
        let mut t = w.counters;
        t.contract_version = CONTRACT_VERSION;
        t.window_jitter = percentiles(&h[JITTER]);
        t.window_compute = percentiles(&h[COMPUTE]);
        t.window_frame_age = percentiles(&h[FRAME_AGE]);
        t.window_frame_age_contact = percentiles(&h[FRAME_AGE_CONTACT]);
        if t.ticks > self.warmup_ticks {
            for (total, window) in self.totals.iter_mut().zip(h) {
                // Same bounds: never fails.
                let _ = total.add(window);
            }
        }
        t.total_jitter = percentiles(&self.totals[JITTER]);
        t.total_compute = percentiles(&self.totals[COMPUTE]);
        t.total_frame_age = percentiles(&self.totals[FRAME_AGE]);
        t.total_frame_age_contact = percentiles(&self.totals[FRAME_AGE_CONTACT]);
        w.histograms.iter_mut().for_each(|h| h.reset());
        // The RT thread holds one window, so the ring always has room for the others.
        let _ = self.empty.push(w);
        Some(t)
    }
}

/// Both ends, with every window allocated up front; windows ending by tick `warmup_ticks` are
/// left out of the totals.
pub fn telemetry(warmup_ticks: u64) -> Result<(TelemetryTx, TelemetryRx)> {
    let (full_tx, full_rx) = rtrb::RingBuffer::new(WINDOWS);
    let (mut empty_tx, empty_rx) = rtrb::RingBuffer::new(WINDOWS);
    for _ in 1..WINDOWS {
        let _ = empty_tx.push(TelemetryWindow::new()?);
    }
    Ok((
        TelemetryTx {
            current: TelemetryWindow::new()?,
            full: full_tx,
            empty: empty_rx,
        },
        TelemetryRx {
            full: full_rx,
            empty: empty_tx,
            totals: [histogram()?, histogram()?, histogram()?, histogram()?],
            warmup_ticks,
        },
    ))
}

fn percentiles(h: &Histogram<u64>) -> Percentiles {
    if h.is_empty() {
        return Percentiles::default();
    }
    Percentiles {
        count: h.len(),
        p50: h.value_at_quantile(0.5),
        p99: h.value_at_quantile(0.99),
        p999: h.value_at_quantile(0.999),
        max: h.max(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_circulate_and_totals_skip_the_warm_up() {
        let (mut tx, mut rx) = telemetry(2).unwrap();
        let sample = |ticks| HapticTelemetry {
            ticks,
            ..Default::default()
        };
        tx.record(COMPUTE, 1000);
        assert!(tx.send(sample(2)));
        tx.record(COMPUTE, 3000);
        assert!(tx.send(sample(4)));
        let a = rx.pop().unwrap();
        assert_eq!(a.window_compute.count, 1);
        assert_eq!(a.total_compute.count, 0, "the warm-up window is left out");
        let b = rx.pop().unwrap();
        assert_eq!(b.window_compute.count, 1);
        assert!(b.window_compute.max >= 2990);
        assert_eq!(b.total_compute.count, 1);
        // The publisher falls behind: the RT side keeps one window and never blocks.
        let mut sent = 0;
        for i in 0..10 {
            tx.record(JITTER, 5);
            sent += usize::from(tx.send(sample(10 + i)));
        }
        assert_eq!(
            sent,
            WINDOWS - 1,
            "every empty window used, then the window goes on"
        );
        let mut got = 0;
        while rx.pop().is_some() {
            got += 1;
        }
        assert_eq!(got, WINDOWS - 1);
        // The window that went on holds the rest.
        assert!(tx.send(sample(30)));
        assert_eq!(
            rx.pop().unwrap().window_jitter.count,
            10 - (WINDOWS as u64 - 1)
        );
    }
}
