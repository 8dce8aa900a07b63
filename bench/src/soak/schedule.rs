//! The fault plan of a soak: what is injected when, drawn once from a seeded generator before
//! the run starts, so the same `--seed` and length give the same plan (the pipeline's own timing
//! still varies from run to run: the plan fixes the injections, not their outcome).
//!
//! Times of process, viewer and `lopd ctl` events are seconds after the first frame; broken
//! device samples are placed in haptic ticks (the mock plays its script on the loop's tick
//! clock, `t = tick / rate`), so they hit exactly the ticks planned whatever the machine's load.
//! Each kind of event is spread over the run by cutting its window into as many equal slots as
//! there are events and drawing one event in each slot, so events of one kind never bunch up
//! and the run's first and last seconds stay quiet (start-up, and a last recovery before the
//! checks).

use lop_drivers::mock::SampleFault;
use serde::Serialize;

pub use lop_test_support::rng::Rng;

/// What is done to a process of the pipeline (`lopd deform` or `lopd haptic`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ProcessFault {
    /// SIGKILL: the supervisor must restart it. A killed deformation process: the haptic loop
    /// ramps the force down on the frames that stopped coming. A killed haptic process: the new
    /// one starts its force over from zero.
    Kill,
    /// SIGSTOP for `seconds`, then SIGCONT. A stopped deformation process: its frames go stale.
    /// A stopped haptic loop: it starts its force over from zero when it runs again.
    Stop {
        /// How long it stays stopped.
        seconds: f64,
    },
}

/// A planned process fault.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ProcessEvent {
    /// Seconds after the first frame.
    pub at_s: f64,
    /// What is done.
    pub fault: ProcessFault,
}

/// A planned run of broken device samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SampleEvent {
    /// First haptic tick that reads a broken sample.
    pub first_tick: u64,
    /// How many consecutive ticks do.
    pub ticks: u64,
    /// `nan` or `out_of_workspace`.
    #[serde(serialize_with = "sample_fault_name")]
    pub fault: SampleFault,
}

impl SampleEvent {
    /// Whether haptic tick `tick` reads a broken sample of this event.
    pub fn covers(&self, tick: u64) -> bool {
        tick >= self.first_tick && tick < self.first_tick + self.ticks
    }
}

fn sample_fault_name<S: serde::Serializer>(f: &SampleFault, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(match f {
        SampleFault::Nan => "nan",
        SampleFault::OutOfWorkspace => "out_of_workspace",
    })
}

/// How a viewer session connects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ViewerKind {
    /// With the token of the URL the daemon printed: its control requests are answered.
    Token,
    /// Without a token: read-only, its control requests refused.
    NoToken,
    /// With a wrong token: read-only too.
    WrongToken,
    /// From a page of another origin: the handshake is refused (HTTP 403).
    CrossOrigin,
}

impl ViewerKind {
    /// Every kind, in report order.
    pub const ALL: [ViewerKind; 4] = [
        ViewerKind::Token,
        ViewerKind::NoToken,
        ViewerKind::WrongToken,
        ViewerKind::CrossOrigin,
    ];

    /// Report label.
    pub fn label(self) -> &'static str {
        match self {
            ViewerKind::Token => "with the printed token",
            ViewerKind::NoToken => "without a token",
            ViewerKind::WrongToken => "with a wrong token",
            ViewerKind::CrossOrigin => "from another origin",
        }
    }
}

/// A planned viewer session.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ViewerEvent {
    /// Seconds after the first frame.
    pub at_s: f64,
    /// How it connects.
    pub kind: ViewerKind,
    /// How long it stays connected, reading, s.
    pub hold_s: f64,
    /// Dropped without a WebSocket close (as a crashed browser tab), else closed politely.
    pub abrupt: bool,
}

/// A planned burst of `lopd ctl` processes (each its own iceoryx2 node and control client).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CtlEvent {
    /// Seconds after the first frame.
    pub at_s: f64,
}

/// The whole plan.
#[derive(Debug, Clone, Serialize)]
pub struct Schedule {
    /// The seed it was drawn from.
    pub seed: u64,
    /// Length of the run after the first frame, s.
    pub seconds: f64,
    /// Deformation-process kills and stops, in time order.
    pub deform: Vec<ProcessEvent>,
    /// Haptic-process kills and stops, in time order.
    pub haptic: Vec<ProcessEvent>,
    /// Broken device samples per device (`samples[k]`: the device of tool `k`), each in tick
    /// order, never overlapping.
    pub samples: Vec<Vec<SampleEvent>>,
    /// Viewer sessions, in time order.
    pub viewers: Vec<ViewerEvent>,
    /// `lopd ctl` bursts, in time order.
    pub ctl: Vec<CtlEvent>,
    /// Seed of the control hammer's request sequence.
    pub hammer_seed: u64,
}

/// Events per minute of run, and the least of each kind in any run.
pub mod rates {
    /// Deformation-process kills per minute of run (at least 1), all in its first half: one
    /// every 30 s there. The supervisor's back-off is reset after 10 s of healthy running, so
    /// every kill is restarted after 0.2 s.
    pub const KILLS: f64 = 1.0;
    /// Deformation-process stops per minute (at least 1).
    pub const STOPS: f64 = 1.0;
    /// Shortest and longest stop, s: beyond the 100 ms stale limit by 3×, up to a hang that
    /// a user would notice.
    pub const STOP_S: (f64, f64) = (0.3, 3.0);
    /// Runs of NaN samples per minute on each device (at least 2).
    pub const NAN: f64 = 4.0;
    /// Runs of out-of-workspace samples per minute on each device (at least 2).
    pub const OUT_OF_WORKSPACE: f64 = 4.0;
    /// Longest run of broken samples, ticks (a glitch, or a cable that comes loose for 40 ms).
    pub const SAMPLE_TICKS_MAX: u64 = 40;
    /// Viewer sessions per minute (at least 4: one of each kind).
    pub const VIEWERS: f64 = 8.0;
    /// `lopd ctl` bursts per minute (at least 1).
    pub const CTL: f64 = 2.0;
    /// Haptic-process kills per minute (at least 1), in the first half of the fault window like
    /// the deformation process's.
    pub const HAPTIC_KILLS: f64 = 0.5;
    /// Haptic-process stops per minute (at least 1).
    pub const HAPTIC_STOPS: f64 = 0.5;
    /// Shortest and longest haptic stop, s: beyond the 100 ms stale limit by 2× (the loop
    /// starts its force over), up to a stall a user would feel as the device going limp.
    pub const HAPTIC_STOP_S: (f64, f64) = (0.2, 1.5);
}

/// Seconds after the first frame before the first event: start-up, the first contact.
const LEAD_S: f64 = 3.0;
/// Share of the fault window, from its start, in which the kills fall.
const KILL_SHARE: f64 = 0.5;
/// Seconds before the end after the last process fault: time to recover (a restarted
/// deformation process loads the scene again) before the run is stopped and checked.
const TAIL_S: f64 = 8.0;
/// The shortest run that fits every kind of event with room to recover.
pub const MIN_SECONDS: f64 = 20.0;

fn count(per_minute: f64, seconds: f64, least: usize) -> usize {
    ((per_minute * seconds / 60.0).round() as usize).max(least)
}

/// `n` times in `[from, to)`, one in each of `n` equal slots, drawn in the first `fill` of the
/// slot (so consecutive events are at least `(1 − fill)` slots apart).
fn spread(rng: &mut Rng, n: usize, from: f64, to: f64, fill: f64) -> Vec<f64> {
    let slot = (to - from) / n.max(1) as f64;
    (0..n)
        .map(|i| from + slot * (i as f64 + fill * rng.unit()))
        .collect()
}

/// A process's faults in time order: `kills` in `[LEAD_S, mid)` (the process restarted last
/// lives through the rest, and its memory can be judged), `stops` of `stop_s` seconds anywhere
/// in `[LEAD_S, end − TAIL_S)`.
fn process_faults(
    rng: &mut Rng,
    kills: usize,
    stops: usize,
    (mid, end): (f64, f64),
    (lo, hi): (f64, f64),
) -> Vec<ProcessEvent> {
    let mut events: Vec<ProcessEvent> = spread(rng, kills, LEAD_S, mid, 0.5)
        .into_iter()
        .map(|at_s| ProcessEvent {
            at_s,
            fault: ProcessFault::Kill,
        })
        .collect();
    for at_s in spread(rng, stops, LEAD_S, end - TAIL_S, 0.5) {
        events.push(ProcessEvent {
            at_s,
            fault: ProcessFault::Stop {
                seconds: rng.range(lo, hi),
            },
        });
    }
    events.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
    events
}

/// One device's broken samples: NaN and out-of-workspace runs interleaved in shuffled order,
/// from 2 s of haptic time to the end of the run (the haptic loop starts before the first frame,
/// so every planned tick is reached before the bench stops it).
fn sample_runs(rng: &mut Rng, seconds: f64, end: f64, rate_hz: f64) -> Vec<SampleEvent> {
    let nan = count(rates::NAN, seconds, 2);
    let out = count(rates::OUT_OF_WORKSPACE, seconds, 2);
    let mut faults: Vec<SampleFault> = std::iter::repeat_n(SampleFault::Nan, nan)
        .chain(std::iter::repeat_n(SampleFault::OutOfWorkspace, out))
        .collect();
    for i in (1..faults.len()).rev() {
        let j = rng.below(i + 1);
        faults.swap(i, j);
    }
    let first_s = 2.0;
    let starts = spread(rng, faults.len(), first_s, end, 0.5);
    faults
        .iter()
        .zip(starts)
        .map(|(&fault, at_s)| SampleEvent {
            first_tick: (at_s * rate_hz).round() as u64,
            ticks: 1 + rng.below(rates::SAMPLE_TICKS_MAX as usize) as u64,
            fault,
        })
        .collect()
}

impl Schedule {
    /// Draws the plan of a run of `seconds` (≥ [`MIN_SECONDS`]) whose haptic loop ticks at
    /// `rate_hz` with `devices` devices.
    pub fn draw(seed: u64, seconds: f64, rate_hz: f64, devices: usize) -> Schedule {
        let mut rng = Rng::new(seed);
        let end = seconds.max(MIN_SECONDS);

        // Deformation process: kills in the first half of the fault window, so the process
        // restarted last lives through the second half and its memory can be judged; stops
        // anywhere. The bench delivers them in time order, a fault waiting while a stop lasts.
        let mid = LEAD_S + KILL_SHARE * (end - TAIL_S - LEAD_S);
        let deform = process_faults(
            &mut rng,
            count(rates::KILLS, seconds, 1),
            count(rates::STOPS, seconds, 1),
            (mid, end),
            rates::STOP_S,
        );

        // Broken samples, in ticks, on every device: the first device's from this generator,
        // each other's from a generator of its own (so a seed's one-device plan is what it was
        // before a second device could be faulted too, and the devices break apart).
        let mut samples = vec![sample_runs(&mut rng, seconds, end, rate_hz)];
        for k in 1..devices.max(1) {
            let mut own = Rng::for_seed(seed, &format!("samples of device {k}"));
            samples.push(sample_runs(&mut own, seconds, end, rate_hz));
        }

        // Viewer sessions: one of each kind first (in shuffled order), then any kind.
        let n = count(rates::VIEWERS, seconds, ViewerKind::ALL.len());
        let mut kinds: Vec<ViewerKind> = ViewerKind::ALL.to_vec();
        for i in (1..kinds.len()).rev() {
            let j = rng.below(i + 1);
            kinds.swap(i, j);
        }
        while kinds.len() < n {
            kinds.push(ViewerKind::ALL[rng.below(ViewerKind::ALL.len())]);
        }
        let times = spread(&mut rng, n, LEAD_S, end - 2.0, 0.5);
        let viewers = kinds
            .into_iter()
            .zip(times)
            .map(|(kind, at_s)| ViewerEvent {
                at_s,
                kind,
                hold_s: rng.range(0.5, 3.0),
                abrupt: rng.below(2) == 0,
            })
            .collect();

        let n = count(rates::CTL, seconds, 1);
        let ctl = spread(&mut rng, n, LEAD_S, end - TAIL_S, 0.5)
            .into_iter()
            .map(|at_s| CtlEvent { at_s })
            .collect();

        // Haptic process: drawn from a generator of its own, so a seed's other events are what
        // they were before the haptic process was faulted too.
        let haptic = process_faults(
            &mut Rng::for_seed(seed, "haptic"),
            count(rates::HAPTIC_KILLS, seconds, 1),
            count(rates::HAPTIC_STOPS, seconds, 1),
            (mid, end),
            rates::HAPTIC_STOP_S,
        );

        Schedule {
            seed,
            seconds,
            deform,
            haptic,
            samples,
            viewers,
            ctl,
            hammer_seed: rng.next_u64(),
        }
    }

    /// The mock script's `[[fault]]` window of a sample event: from half a tick before its first
    /// tick to half a tick before the tick after its last, so rounding `tick / rate` can never
    /// move a tick in or out.
    pub fn window_s(event: &SampleEvent, rate_hz: f64) -> (f64, f64) {
        let from = (event.first_tick as f64 - 0.5) / rate_hz;
        let until = ((event.first_tick + event.ticks) as f64 - 0.5) / rate_hz;
        (from.max(0.0), until)
    }

    /// How many deformation kills are planned.
    #[cfg(test)]
    pub fn kills(&self) -> usize {
        self.deform
            .iter()
            .filter(|e| e.fault == ProcessFault::Kill)
            .count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_plan_other_seed_other_plan() {
        let a = Schedule::draw(7, 120.0, 1000.0, 1);
        let b = Schedule::draw(7, 120.0, 1000.0, 1);
        assert_eq!(a.deform, b.deform);
        assert_eq!(a.haptic, b.haptic);
        assert_eq!(a.samples, b.samples);
        assert_eq!(a.viewers, b.viewers);
        assert_eq!(a.ctl, b.ctl);
        assert_eq!(a.hammer_seed, b.hammer_seed);
        let c = Schedule::draw(8, 120.0, 1000.0, 1);
        assert_ne!(a.samples, c.samples);
    }

    #[test]
    fn a_second_device_gets_its_own_broken_samples_and_changes_nothing_else() {
        let one = Schedule::draw(7, 120.0, 1000.0, 1);
        let two = Schedule::draw(7, 120.0, 1000.0, 2);
        assert_eq!((one.samples.len(), two.samples.len()), (1, 2));
        assert_eq!(one.samples[0], two.samples[0]);
        assert_eq!(one.deform, two.deform);
        assert_eq!(one.haptic, two.haptic);
        assert_eq!(one.viewers, two.viewers);
        assert_eq!(one.hammer_seed, two.hammer_seed);
        // The second device breaks at other ticks, as many times.
        assert_eq!(two.samples[1].len(), two.samples[0].len());
        assert_ne!(two.samples[1], two.samples[0]);
    }

    #[test]
    fn a_short_run_still_has_every_kind_inside_its_window() {
        for seed in 0..50 {
            let s = Schedule::draw(seed, 30.0, 1000.0, 2);
            assert!(s.kills() >= 1, "seed {seed}");
            assert!(s.deform.len() >= 2, "seed {seed}");
            for samples in &s.samples {
                assert!(samples
                    .iter()
                    .any(|e| e.fault == SampleFault::OutOfWorkspace));
                assert!(samples.iter().any(|e| e.fault == SampleFault::Nan));
            }
            for k in ViewerKind::ALL {
                assert!(s.viewers.iter().any(|v| v.kind == k), "seed {seed}: {k:?}");
            }
            assert!(!s.ctl.is_empty());
            // Process faults: in order, inside [lead, end − tail], kills in its first half.
            assert!(
                s.deform.windows(2).all(|w| w[0].at_s <= w[1].at_s),
                "seed {seed}"
            );
            for e in &s.deform {
                assert!(e.at_s >= LEAD_S && e.at_s <= 30.0 - TAIL_S, "{e:?}");
                match e.fault {
                    ProcessFault::Stop { seconds } => {
                        assert!(seconds >= rates::STOP_S.0 && seconds <= rates::STOP_S.1)
                    }
                    ProcessFault::Kill => {
                        assert!(e.at_s <= LEAD_S + KILL_SHARE * (30.0 - TAIL_S - LEAD_S))
                    }
                }
            }
            // Haptic faults: at least a kill and a stop, in order, inside the same window.
            let hk = s
                .haptic
                .iter()
                .filter(|e| e.fault == ProcessFault::Kill)
                .count();
            assert!(hk >= 1 && s.haptic.len() - hk >= 1, "seed {seed}");
            assert!(s.haptic.windows(2).all(|w| w[0].at_s <= w[1].at_s));
            for e in &s.haptic {
                assert!(e.at_s >= LEAD_S && e.at_s <= 30.0 - TAIL_S, "{e:?}");
                match e.fault {
                    ProcessFault::Stop { seconds } => assert!(
                        seconds >= rates::HAPTIC_STOP_S.0 && seconds <= rates::HAPTIC_STOP_S.1
                    ),
                    ProcessFault::Kill => {
                        assert!(e.at_s <= LEAD_S + KILL_SHARE * (30.0 - TAIL_S - LEAD_S))
                    }
                }
            }
            // Sample runs of each device: in order, apart, inside the run's ticks.
            for samples in &s.samples {
                for w in samples.windows(2) {
                    assert!(w[0].first_tick + w[0].ticks < w[1].first_tick, "{w:?}");
                }
                for e in samples {
                    assert!(e.ticks >= 1 && e.ticks <= rates::SAMPLE_TICKS_MAX);
                    assert!(e.first_tick >= 2000 && e.first_tick + e.ticks <= 30_000);
                }
            }
        }
    }

    #[test]
    fn counts_follow_the_rates_on_a_long_run() {
        let s = Schedule::draw(1, 1800.0, 1000.0, 1);
        assert_eq!(s.kills(), 30);
        assert_eq!(s.deform.len(), 60);
        assert_eq!(s.samples[0].len(), 240);
        assert_eq!(s.viewers.len(), 240);
        assert_eq!(s.ctl.len(), 60);
        assert_eq!(s.haptic.len(), 30);
    }

    #[test]
    fn the_script_window_holds_exactly_the_planned_ticks() {
        let e = SampleEvent {
            first_tick: 12_345,
            ticks: 3,
            fault: SampleFault::Nan,
        };
        let (from, until) = Schedule::window_s(&e, 1000.0);
        let hit: Vec<u64> = (12_340..12_350)
            .filter(|&k| {
                let t = k as f64 / 1000.0;
                t >= from && t < until
            })
            .collect();
        assert_eq!(hit, [12_345, 12_346, 12_347]);
        assert!((12_345..12_350).all(|k| e.covers(k) == (k < 12_348)));
    }
}
