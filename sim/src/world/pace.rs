//! The rate follows the cost: the period a body steps at in real time, chosen from what its
//! steps cost on this machine.
//!
//! A body's precise model is configured at one step period (`[body.fem] dt`, 1 ms at the
//! haptic rate). On an organ whose step costs more than that period, stepping at it makes the
//! simulated tissue fall behind the wall clock. [`Pace`] watches the wall time of each step and
//! moves the body along a ladder of periods — the configured one times 1, 2, 4, 5, 10, 20, 25,
//! 50, 100, up to a longest period:
//!
//! - **Longer** when the step cannot keep up on its own: the median of a window of [`WINDOW`]
//!   steps (fewer at long periods: half a second's worth) costs more than [`STAY`] of the period, or [`FAST_STEPS`] steps in a row each cost
//!   more than [`FAST_FACTOR`] periods (the tissue is losing time fast). It goes to the shortest
//!   period on which that cost is at most [`FIT`] of it.
//! - **Longer** too when the body keeps losing time at its period: the time its steps cost
//!   beyond the period, each step's excess counted up to one period and paid back by the
//!   cheaper steps, passes [`DEBT`] or two periods, whichever is longer (a body behind by that
//!   much drops time the round cannot catch up: the real-time factor of its second falls; at
//!   4 and 5 ms two periods, so that a body whose rare dear steps cost one period each does not
//!   leave for 10 ms, where its frames come twice as far apart). It goes to the shortest
//!   period that fits the median of the window so far, at least one rung up. Without it, an organ whose
//!   step costs 1.2–1.5 ms at 1 ms lost time for a whole window (128 steps, 0.2–0.3 s) before
//!   the median moved it: about 0.1 s dropped in that second, a real-time factor of 0.9.
//! - **Shorter** only when the median of a full window fits in [`DOWN`] of the shorter period,
//!   and every step of that window was touched (a tool pressing or holding the body). A step
//!   costs more at a longer period (the system is less dominated by the mass, so CG takes
//!   more iterations), so the margin is wide and the period does not hunt between two rungs.
//!   The steps out of contact (the tool approaching a body the precise model already runs, or
//!   gone and the body settling) cost a fraction of a touched one: judged by them, a 5k organ
//!   that the deformation process's rehearsed touch started at 2 ms came down to 1 ms before
//!   the tool arrived (a step at rest 0.22 ms) and lost time at the touch. They still move it
//!   up when they are dear.
//!
//! The median, not a high quantile: a longer period is a cost to the feel (frames arrive less
//! often and the coupling between hand and tissue sees an older surface), so it is taken only
//! for a step that is too dear most of the time — not for the preemptions of a shared machine
//! or a short run of dearer steps in a press, which the round's catch-up absorbs. Measured on the shipped
//! liver (2-core machine): a pace that judged by the 90th percentile moved it between 1, 2 and
//! 4 ms during pokes and its peak force rose from 0.71 N to 1.0–1.45 N in some of them, as with
//! the liver pinned at 4 ms.
//!
//! The pace reads no clock: the caller passes the costs it measured (the deformation process
//! its wall clock; tests a made-up sequence), so the same costs always give the same periods.
//! It only chooses; the caller applies the period (`crate::fem::Fem::set_dt`, whose new factor
//! is made off the critical path under the background refactor policy), and the step stays
//! continuous across the change: positions and velocities carry over as they are.

/// Steps whose median cost judges a period: at 1 ms, 128 ms of evidence. At longer periods
/// fewer, so that a window spans at most [`WINDOW_SPAN`] of simulated time (a touch lasts a few
/// seconds), but never fewer than [`FAST_STEPS`] × 2.
pub const WINDOW: usize = 128;
/// Simulated time a window spans at most, s.
pub const WINDOW_SPAN: f64 = 0.5;
/// Consecutive steps each costing more than [`FAST_FACTOR`] periods that move it up at once.
pub const FAST_STEPS: usize = 8;
/// See [`FAST_STEPS`].
pub const FAST_FACTOR: f64 = 2.0;
/// A period is kept while the median step costs at most this share of it.
pub const STAY: f64 = 1.1;
/// Moving up, the period chosen is the shortest on which the median step costs at most this
/// share of it.
pub const FIT: f64 = 0.75;
/// A shorter period is taken only when the median step costs at most this share of it.
pub const DOWN: f64 = 0.4;
/// Time a body may fall behind at one period before the pace moves it up, s, or two periods
/// if longer (each step's excess over the period counted up to one period, the cheaper steps
/// paying it back): the
/// round keeps up to 3 periods of it and drops the rest as lag, so at 1 ms a move costs at most
/// about 3 ms of the second's simulated time, under the 1 % the real-time target allows.
pub const DEBT: f64 = 0.006;
/// Steps of a window the pace needs before debt may move it (their median chooses the period).
pub const DEBT_STEPS: usize = 16;
/// Steps not judged after [`Pace::restart`] and after a change of period: the first steps of
/// a precise model taking over from the cage cost more than the steady ones (the rotations
/// start cold), and the first at a new period may wait for its factor.
pub const SETTLE_STEPS: usize = 8;
/// The ladder's multiples of the configured period.
pub const MULTIPLES: [u32; 9] = [1, 2, 4, 5, 10, 20, 25, 50, 100];

/// The period a body steps at, from its step costs (module docs).
#[derive(Debug, Clone)]
pub struct Pace {
    periods: Vec<f64>,
    index: usize,
    costs: [f64; WINDOW],
    len: usize,
    /// Steps in a row costing more than [`FAST_FACTOR`] periods, and the cheapest of them.
    over: usize,
    over_cheapest: f64,
    /// Steps still to be ignored after a restart.
    skip: usize,
    /// Time lost at this period so far ([`DEBT`]), s.
    debt: f64,
    /// Steps of the window so far taken untouched (they cannot bring the period down).
    untouched: usize,
    changes: u64,
    /// The cost the last change was judged by, s.
    judged: f64,
    /// The median step of the last full window at the longest period, when it was too dear
    /// even for that, s.
    behind: Option<f64>,
}

impl Pace {
    /// A pace starting at `base` (s), the body's configured period, that may lengthen it up
    /// to `longest` (s; at or below `base`: the period never changes).
    pub fn new(base: f64, longest: f64) -> Pace {
        let periods = MULTIPLES
            .iter()
            .map(|&m| base * f64::from(m))
            .take_while(|&p| p == base || p <= longest * (1.0 + 1e-9))
            .collect();
        Pace {
            periods,
            index: 0,
            costs: [0.0; WINDOW],
            len: 0,
            over: 0,
            over_cheapest: f64::INFINITY,
            skip: 0,
            debt: 0.0,
            untouched: 0,
            changes: 0,
            judged: 0.0,
            behind: None,
        }
    }

    /// Forgets the costs seen and ignores the next [`SETTLE_STEPS`] (the model just took over
    /// the body); keeps the period.
    pub fn restart(&mut self) {
        self.len = 0;
        self.untouched = 0;
        self.over = 0;
        self.over_cheapest = f64::INFINITY;
        self.debt = 0.0;
        self.skip = SETTLE_STEPS;
    }

    /// The periods it chooses from, shortest first, s.
    pub fn periods(&self) -> &[f64] {
        &self.periods
    }

    /// The period chosen, s.
    pub fn period(&self) -> f64 {
        self.periods[self.index]
    }

    /// The step cost the last change of period was judged by (a window's median, or the
    /// cheapest of the steps that moved it up at once), s.
    pub fn judged_cost(&self) -> f64 {
        self.judged
    }

    /// At the longest period, the median step of the last full window if it costs more than
    /// [`STAY`] of that period: the body falls behind the wall clock whatever the pace does.
    pub fn behind(&self) -> Option<f64> {
        self.behind
    }

    /// Changes of period so far.
    pub fn changes(&self) -> u64 {
        self.changes
    }

    /// The shortest period on which a step of `cost` (s) takes at most `headroom` of it, or
    /// `None` if even the longest one is too short.
    pub fn fitting(&self, cost: f64, headroom: f64) -> Option<f64> {
        self.periods.iter().copied().find(|&p| cost <= headroom * p)
    }

    /// Starts at the period that fits an estimated step `cost` (s), or the longest if none
    /// does; forgets the costs seen. Returns the period.
    pub fn start_at(&mut self, cost: f64) -> f64 {
        let period = self
            .fitting(cost, FIT)
            .unwrap_or(self.periods[self.periods.len() - 1]);
        self.set(period);
        self.period()
    }

    /// Records the wall time of one step taken at [`Pace::period`], s, and whether a tool
    /// touched the body in it; returns the new period when it changes (the caller applies it).
    pub fn observe(&mut self, cost: f64, touched: bool) -> Option<f64> {
        if self.skip > 0 {
            self.skip -= 1;
            return None;
        }
        let cost = if cost.is_finite() { cost.max(0.0) } else { 0.0 };
        let period = self.period();
        let longest = self.periods[self.periods.len() - 1];
        if cost > FAST_FACTOR * period {
            self.over += 1;
            self.over_cheapest = self.over_cheapest.min(cost);
        } else {
            self.over = 0;
            self.over_cheapest = f64::INFINITY;
        }
        self.debt = (self.debt + cost.min(2.0 * period) - period).max(0.0);
        let window = ((WINDOW_SPAN / period).ceil() as usize).clamp(2 * FAST_STEPS, WINDOW);
        if self.len < window {
            self.costs[self.len] = cost;
            self.len += 1;
            self.untouched += usize::from(!touched);
        }
        let last = period == longest;
        if self.debt > DEBT.max(2.0 * period) && self.len >= DEBT_STEPS && !last {
            // Losing time at this period: judged by the window so far.
            let median = median(&mut self.costs[..self.len]);
            return self.move_up(median);
        }
        if self.over >= FAST_STEPS && !last {
            // Losing time fast: judged by the cheapest of those steps.
            return self.move_up(self.over_cheapest);
        }
        if self.len < window {
            return None;
        }
        let median = median(&mut self.costs[..window]);
        self.len = 0;
        let untouched = std::mem::take(&mut self.untouched);
        self.judged = median;
        self.behind = (last && median > STAY * period).then_some(median);
        if median > STAY * period && !last {
            let to = self.fitting(median, FIT).unwrap_or(longest);
            return self.change(to);
        }
        match self.fitting(median, DOWN) {
            Some(to) if to < period && untouched == 0 => self.change(to),
            _ => None,
        }
    }

    /// Moves to the shortest period that fits a step of `cost` (s), at least one rung up;
    /// not at the longest period.
    fn move_up(&mut self, cost: f64) -> Option<f64> {
        let next = self.periods[self.index + 1];
        let longest = self.periods[self.periods.len() - 1];
        let to = self.fitting(cost, FIT).map_or(longest, |p| p.max(next));
        self.judged = cost;
        self.change(to)
    }

    fn change(&mut self, to: f64) -> Option<f64> {
        let before = self.period();
        self.set(to);
        (self.period() != before).then(|| {
            // The first steps at a new period wait for its factor (made within the step with
            // one deformation thread): not what the period costs.
            self.skip = SETTLE_STEPS;
            self.changes += 1;
            self.period()
        })
    }

    fn set(&mut self, period: f64) {
        self.index = self
            .periods
            .iter()
            .position(|&p| p >= period)
            .unwrap_or(self.periods.len() - 1);
        self.len = 0;
        self.untouched = 0;
        self.over = 0;
        self.over_cheapest = f64::INFINITY;
        self.debt = 0.0;
    }
}

/// The median of a window by nearest rank (the 64th of 128 smallest); reorders it.
fn median(costs: &mut [f64]) -> f64 {
    let (_, q, _) = costs.select_nth_unstable_by(costs.len().div_ceil(2) - 1, f64::total_cmp);
    *q
}

/// The real-time factor of a body: simulated time kept over wall time, per window of wall
/// time. A body in a live round is stepped up to the wall clock or drops the time still due
/// (lag, [`crate::world::BodyRound::dropped`]), so the window's factor is `1 − dropped /
/// elapsed`: 1 for a body that keeps real time, below for one that falls behind. Counting the
/// time dropped rather than the steps taken keeps the factor exact whatever the body's period:
/// a body stepping every 20 ms would read 0.98 for a window that ended 19 ms after its last
/// step.
#[derive(Debug, Clone, Copy)]
pub struct RealTimeMeter {
    window: f64,
    start: Option<f64>,
    dropped: f64,
    factor: Option<f64>,
}

impl RealTimeMeter {
    /// A meter over windows of `window` s of wall time.
    pub fn new(window: f64) -> RealTimeMeter {
        RealTimeMeter {
            window,
            start: None,
            dropped: 0.0,
            factor: None,
        }
    }

    /// Records `dropped` s of simulated time lost since the previous record, at wall time
    /// `now` (s). Ends the window once it is `window` long. The first record only starts the
    /// window.
    pub fn record(&mut self, now: f64, dropped: f64) {
        let Some(start) = self.start else {
            self.start = Some(now);
            return;
        };
        self.dropped += dropped;
        if now - start >= self.window {
            self.factor = Some((1.0 - self.dropped / (now - start)).max(0.0));
            self.start = Some(now);
            self.dropped = 0.0;
        }
    }

    /// Restarts the window at `now` (after a pause: held time is not lost time).
    pub fn restart(&mut self, now: f64) {
        self.start = Some(now);
        self.dropped = 0.0;
    }

    /// The factor of the last full window; `None` before one has ended.
    pub fn factor(&self) -> Option<f64> {
        self.factor
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: f64 = 1e-3;

    fn feed(p: &mut Pace, cost: f64, steps: usize) -> Vec<f64> {
        (0..steps).filter_map(|_| p.observe(cost, true)).collect()
    }

    #[test]
    fn the_ladder_stops_at_the_longest_period() {
        let p = Pace::new(MS, 10.0 * MS);
        let ms: Vec<f64> = p.periods().iter().map(|p| (p / MS).round()).collect();
        assert_eq!(ms, [1.0, 2.0, 4.0, 5.0, 10.0]);
        assert_eq!(Pace::new(MS, 0.5 * MS).periods(), [MS]);
        assert_eq!(Pace::new(2.0 * MS, 10.0 * MS).periods().len(), 4); // 2, 4, 8, 10
    }

    #[test]
    fn a_cheap_step_keeps_the_configured_period() {
        let mut p = Pace::new(MS, 10.0 * MS);
        assert!(feed(&mut p, 0.5 * MS, 1000).is_empty());
        // 0.9 ms of 1 ms: dear, but it keeps up.
        assert!(feed(&mut p, 0.9 * MS, 1000).is_empty());
        assert_eq!(p.period(), MS);
    }

    #[test]
    fn a_step_far_over_its_period_moves_up_within_eight_steps() {
        let mut p = Pace::new(MS, 10.0 * MS);
        // 2.5 ms per step: 2.5 / 0.75 = 3.3 ms, so 4 ms is the shortest that fits.
        let changes = feed(&mut p, 2.5 * MS, FAST_STEPS);
        assert_eq!(changes, [4.0 * MS]);
        // And it stays there: 2.5 ms is 62.5 % of 4 ms; 2 ms would need it at 40 %.
        assert!(feed(&mut p, 2.5 * MS, 10 * WINDOW).is_empty());
    }

    /// A run of dear steps that spans the end of a window (found by the soak: the run was
    /// looked up in the window, which had just been emptied).
    #[test]
    fn a_dear_run_across_a_window_end_moves_up() {
        let mut p = Pace::new(MS, 10.0 * MS);
        assert!(feed(&mut p, 0.5 * MS, WINDOW - 4).is_empty());
        assert_eq!(feed(&mut p, 2.5 * MS, FAST_STEPS), [4.0 * MS]);
    }

    #[test]
    fn a_step_just_over_its_period_moves_up_once_it_has_lost_the_debt() {
        let mut p = Pace::new(MS, 10.0 * MS);
        // 1.2 ms: too dear for 1 ms, not enough for the fast move. It loses 0.2 ms a step, so
        // after 31 steps it is more than 6 ms behind: 2 ms, long before a window's end.
        assert!(feed(&mut p, 1.2 * MS, 30).is_empty());
        assert_eq!(feed(&mut p, 1.2 * MS, 1), [2.0 * MS]);
        assert_eq!(p.judged_cost(), 1.2 * MS);
        assert!(feed(&mut p, 1.2 * MS, 10 * WINDOW).is_empty());
    }

    #[test]
    fn a_step_just_under_its_period_never_moves_it() {
        let mut p = Pace::new(MS, 10.0 * MS);
        // Dear steps paid back by cheaper ones: 0.8 and 1.15 ms in turn lose nothing.
        for i in 0..20 * WINDOW {
            let cost = if i % 2 == 0 { 0.8 * MS } else { 1.15 * MS };
            assert_eq!(p.observe(cost, true), None, "step {i}");
        }
        // The same with 1.3 ms loses 0.05 ms every two steps: 6 ms after 240.
        let changes: Vec<f64> = (0..2 * WINDOW)
            .filter_map(|i| p.observe(if i % 2 == 0 { 0.8 * MS } else { 1.3 * MS }, true))
            .collect();
        assert_eq!(changes, [2.0 * MS]);
    }

    #[test]
    fn it_comes_down_only_with_room_to_spare() {
        let mut p = Pace::new(MS, 10.0 * MS);
        p.start_at(6.0 * MS); // 10 ms
        assert_eq!(p.period(), 10.0 * MS);
        // 1.2 ms fits 2 ms at 60 %, above the 40 % to go there: it goes to 4 ms (30 %) only.
        assert_eq!(feed(&mut p, 1.2 * MS, WINDOW), [4.0 * MS]);
        assert!(feed(&mut p, 1.2 * MS, 10 * WINDOW).is_empty());
        // 0.35 ms: back to the configured period.
        assert_eq!(feed(&mut p, 0.35 * MS, 2 * WINDOW), [MS]);
    }

    /// Started at a longer period by the rehearsed touch, a body stepped out of contact (the
    /// tool approaching) stays there however cheap those steps; touched, it comes down.
    #[test]
    fn only_touched_steps_bring_it_down() {
        let mut p = Pace::new(MS, 10.0 * MS);
        p.start_at(1.2 * MS); // 2 ms
        assert_eq!(p.period(), 2.0 * MS);
        let untouched: Vec<f64> = (0..10 * WINDOW)
            .filter_map(|_| p.observe(0.2 * MS, false))
            .collect();
        assert!(untouched.is_empty(), "{untouched:?}");
        // One untouched step in a window of touched ones is enough to hold it.
        let mixed: Vec<f64> = (0..WINDOW)
            .filter_map(|i| p.observe(0.2 * MS, i != 5))
            .collect();
        assert!(mixed.is_empty(), "{mixed:?}");
        assert_eq!(feed(&mut p, 0.2 * MS, WINDOW), [MS]);
        // Dear steps out of contact still move it up.
        let up: Vec<f64> = (0..SETTLE_STEPS + FAST_STEPS)
            .filter_map(|_| p.observe(2.5 * MS, false))
            .collect();
        assert_eq!(up, [4.0 * MS]);
    }

    #[test]
    fn the_steps_after_a_restart_are_not_judged() {
        let mut p = Pace::new(MS, 10.0 * MS);
        p.restart();
        // The cold start of a take-over: eight dear steps, then cheap ones.
        assert!(feed(&mut p, 5.0 * MS, SETTLE_STEPS).is_empty());
        assert!(feed(&mut p, 0.5 * MS, 10 * WINDOW).is_empty());
        assert_eq!(p.period(), MS);
    }

    #[test]
    fn spikes_and_short_dear_stretches_do_not_move_it() {
        let mut p = Pace::new(MS, 10.0 * MS);
        // In every window: seven preemptions of 20 ms (never eight in a row, each counted as
        // one period lost) and a stretch of 10 steps at 1.5 ms (a press, 5 ms lost), the rest
        // normal steps that pay the time back: the median is a normal step.
        for i in 0..10 * WINDOW {
            let k = i % WINDOW;
            let cost = match k {
                _ if k.is_multiple_of(16) && k < 112 => 20.0 * MS,
                _ if (113..123).contains(&k) => 1.5 * MS,
                _ => 0.6 * MS,
            };
            assert_eq!(p.observe(cost, true), None, "step {i}");
        }
    }

    #[test]
    fn at_a_long_period_it_may_lose_two_periods() {
        let mut p = Pace::new(MS, 10.0 * MS);
        p.start_at(3.5 * MS); // 5 ms
        assert_eq!(p.period(), 5.0 * MS);
        // Normal steps of 2.5 ms, and every 20th a dear one of 12 ms (one period lost): the
        // normal ones pay it back. Two of them close together lose 10 ms, within two periods.
        let mut costs = vec![2.5 * MS; 40];
        costs[20] = 12.0 * MS;
        costs[22] = 12.0 * MS;
        for c in costs.iter().cycle().take(10 * WINDOW) {
            assert_eq!(p.observe(*c, true), None);
        }
        // Three close together lose 12.5 ms: more than two periods, so 10 ms.
        let changes: Vec<f64> = [2.5, 12.0, 12.0, 12.0]
            .iter()
            .filter_map(|&c| p.observe(c * MS, true))
            .collect();
        assert_eq!(changes, [10.0 * MS]);
    }

    #[test]
    fn a_long_dear_stretch_moves_it() {
        let mut p = Pace::new(MS, 10.0 * MS);
        assert!(feed(&mut p, 0.6 * MS, WINDOW / 2).is_empty());
        // A press of 1.45 ms steps: 0.45 ms lost a step, more than 6 ms after 14. The
        // window's median is still a normal step, which fits 1 ms: one rung up.
        assert!(feed(&mut p, 1.45 * MS, 13).is_empty());
        assert_eq!(feed(&mut p, 1.45 * MS, 1), [2.0 * MS]);
    }

    #[test]
    fn a_step_beyond_the_longest_period_stays_at_it() {
        let mut p = Pace::new(MS, 10.0 * MS);
        assert_eq!(p.fitting(9.0 * MS, FIT), None);
        assert_eq!(feed(&mut p, 30.0 * MS, FAST_STEPS), [10.0 * MS]);
        // A full window there (50 steps: half a second at 10 ms) tells it falls behind anyway.
        assert_eq!(p.behind(), None);
        assert!(feed(&mut p, 30.0 * MS, SETTLE_STEPS + 49).is_empty());
        assert_eq!(p.behind(), None);
        assert!(feed(&mut p, 30.0 * MS, 1).is_empty());
        assert_eq!(p.behind(), Some(30.0 * MS));
        assert_eq!(p.period(), 10.0 * MS);
        assert_eq!(p.changes(), 1);
        feed(&mut p, 5.0 * MS, 50);
        assert_eq!(p.behind(), None);
        // Not a number is not a cost.
        assert_eq!(p.observe(f64::NAN, true), None);
    }

    #[test]
    fn the_meter_reads_simulated_over_wall_time() {
        let mut m = RealTimeMeter::new(1.0);
        assert_eq!(m.factor(), None);
        // Nothing dropped for a second: real time, whatever the steps.
        for k in 0..=1000 {
            m.record(k as f64 * MS, 0.0);
        }
        assert!((m.factor().unwrap() - 1.0).abs() < 1e-9);
        // Then 1 ms dropped every other ms: half.
        for k in 1001..=2000 {
            m.record(k as f64 * MS, if k % 2 == 0 { MS } else { 0.0 });
        }
        assert!((m.factor().unwrap() - 0.5).abs() < 1e-9);
        // A restart (a pause) forgets what the window had dropped.
        m.record(2.5, 0.3);
        m.restart(2.5);
        m.record(3.6, 0.0);
        assert!((m.factor().unwrap() - 1.0).abs() < 1e-9);
    }
}
