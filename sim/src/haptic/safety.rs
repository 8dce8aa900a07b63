//! The last stage before the device: every force leaving the haptic loop passes through
//! [`ForceSafety`], which enforces the first two of lop's safety invariants (README § Safety):
//! every force is finite and clamped, and bad data ramps it to zero.
//!
//! - The output is always finite and its magnitude never exceeds the clamp.
//! - While the input is unhealthy (stale frame, NaN, device fault) the force ramps linearly to
//!   zero within `ramp_ticks`, and it ramps back in the same way once healthy again, so a
//!   recovering stream cannot kick the hand.
//! - Otherwise the force changes by at most `max_step` per tick beyond what the hand's own
//!   motion explains (the tool spring times the device's move this tick, passed by the loop:
//!   [`ForceSafety::condition_moving`]). The limit stops jumps nothing moved for (a frame that
//!   lands elsewhere, a proxy that snaps), not the stiffness the hand pushes into: a slew limit
//!   on that would lag the force behind the stylus, and a lagging force on a stiff contact
//!   generates energy (`lop-bench haptics`, part 3, measured it driving the simulated hand
//!   unstable from 1.4 N/mm on stiff tissue).
//! - Contact onset (from zero force) is limited the same way. A touch's first force is the
//!   tool spring over the penetration of one tick, which the motion allowance covers; a force
//!   from zero that nothing moved for (a loop that starts, or starts again, with the stylus in
//!   the tissue; a surface that lands on a still stylus) ramps in at the step limit instead of
//!   arriving at once.
//! - With a continuous-force limit (the device's `HD_NOMINAL_MAX_CONTINUOUS_FORCE`, set by
//!   [`ForceSafety::with_continuous`]): the motors heat with the square of the force, so the
//!   root mean square of the output over the last seconds (an exponential average) is kept at
//!   or under that limit by lowering the clamp towards it while the average is over. Peaks up to
//!   the peak force stay possible; holding more than the continuous force for long is not. A
//!   ramp to zero starts from the last force all the same (never cut to the lowered clamp).

/// Force conditioning state. Pure and allocation-free.
#[derive(Debug, Clone)]
pub struct ForceSafety {
    max_force: f64,
    max_step: f64,
    /// Ticks of the ramp; the gain is `level / ramp_ticks`, counted in integers so that it
    /// reaches exactly 0 and 1.
    ramp_ticks: u32,
    level: u32,
    last: [f64; 3],
    /// The device position of the last healthy tick, for the motion allowance.
    last_device: Option<[f64; 3]>,
    /// Continuous-force limit, N (infinite: none).
    continuous: f64,
    /// Weight of the newest tick in the mean square (1 / averaging ticks).
    alpha: f64,
    /// Exponential mean of |F|² over recent ticks, N².
    mean_square: f64,
}

impl ForceSafety {
    /// `max_force` in N (> 0), `max_step` N per tick, `ramp_ticks` ticks from full force to zero.
    pub fn new(max_force: f64, max_step: f64, ramp_ticks: u32) -> ForceSafety {
        ForceSafety {
            max_force: if max_force.is_finite() {
                max_force.max(0.0)
            } else {
                0.0
            },
            max_step: if max_step.is_finite() {
                max_step.max(0.0)
            } else {
                0.0
            },
            ramp_ticks: ramp_ticks.max(1),
            level: ramp_ticks.max(1),
            last: [0.0; 3],
            last_device: None,
            continuous: f64::INFINITY,
            alpha: 0.0,
            mean_square: 0.0,
        }
    }

    /// Adds a continuous-force limit `continuous` N, averaged over about `ticks` ticks (see the
    /// module docs). A non-finite or non-positive limit means none.
    pub fn with_continuous(mut self, continuous: f64, ticks: u32) -> ForceSafety {
        if continuous.is_finite() && continuous > 0.0 {
            self.continuous = continuous;
            self.alpha = 1.0 / ticks.max(1) as f64;
        }
        self
    }

    /// The clamp this tick: the peak force while the recent mean square force is under 90 % of
    /// the continuous limit's square, the continuous force once it reaches it, and in between
    /// a linear blend — continuous in the average, which moves slowly, so the clamp never
    /// chatters. A force held above the limit settles at it.
    fn clamp_now(&self) -> f64 {
        if !self.continuous.is_finite() || self.continuous >= self.max_force {
            return self.max_force;
        }
        let c2 = self.continuous * self.continuous;
        let over = ((self.mean_square - 0.9 * c2) / (0.1 * c2)).clamp(0.0, 1.0);
        self.max_force + (self.continuous - self.max_force) * over
    }

    /// The force to write this tick for the `desired` force. `healthy` is false when the data
    /// behind `desired` cannot be trusted; then `desired` is ignored and the output ramps down.
    pub fn condition(&mut self, desired: [f64; 3], healthy: bool) -> [f64; 3] {
        self.condition_moving(desired, healthy, None, 0.0)
    }

    /// As [`condition`](Self::condition), with the device at `device` (m, any fixed frame;
    /// `None`: unknown) and a tool spring of `stiffness` N/m: the step allowed this tick grows
    /// by the force change the hand's motion explains, `stiffness × |device − last healthy
    /// tick's device|`. Not finite or negative: none; at most the clamp.
    pub fn condition_moving(
        &mut self,
        desired: [f64; 3],
        healthy: bool,
        device: Option<[f64; 3]>,
        stiffness: f64,
    ) -> [f64; 3] {
        let moved = match (device, self.last_device) {
            (Some(p), Some(q)) if healthy => {
                let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
            }
            _ => 0.0,
        };
        self.last_device = device.filter(|_| healthy);
        let motion = stiffness * moved;
        let motion = if motion.is_finite() {
            motion.clamp(0.0, self.max_force)
        } else {
            0.0
        };
        let finite = desired.iter().all(|c| c.is_finite());
        let healthy = healthy && finite;
        let previous = self.level;
        if healthy {
            self.level = (self.level + 1).min(self.ramp_ticks);
        } else {
            self.level = self.level.saturating_sub(1);
        }
        let gain = self.level as f64 / self.ramp_ticks as f64;
        let target = if healthy { desired } else { self.last };
        // A ramp starts from the force last written, under the peak clamp only: re-clamped to
        // a continuous limit that has just come down (the healthy path walks down to it at the
        // step limit), its first tick would cut the force at once. The ramp is over within
        // `ramp_ticks`, far too short to heat a motor.
        let clamp = if healthy {
            self.clamp_now()
        } else {
            self.max_force
        };
        let mut f = clamp_norm(target, clamp);
        if healthy {
            f = limit_step(self.last, f, self.max_step + motion);
            f = scale(f, gain);
        } else if self.level == 0 {
            f = [0.0; 3];
        } else {
            // Ramp the last force down linearly: exactly zero when the level reaches 0.
            f = scale(f, self.level as f64 / previous.max(1) as f64);
        }
        if !f.iter().all(|c| c.is_finite()) {
            f = [0.0; 3];
        }
        if self.alpha > 0.0 {
            let f2 = f[0] * f[0] + f[1] * f[1] + f[2] * f[2];
            self.mean_square += self.alpha * (f2 - self.mean_square);
        }
        self.last = f;
        f
    }

    /// Starts over from zero force: the device was not driven for a while (the loop was
    /// stopped, or it is a new one), so the force it renders now is none, and the next ones ramp
    /// in from zero as after unhealthy data (the first at most a `ramp_ticks`-th of the force
    /// asked, the next by the step limit). Allocation-free.
    pub fn restart(&mut self) {
        self.level = 0;
        self.last = [0.0; 3];
        self.last_device = None;
    }

    /// The last force returned.
    pub fn last(&self) -> [f64; 3] {
        self.last
    }

    /// The clamp, N.
    pub fn max_force(&self) -> f64 {
        self.max_force
    }
}

fn scale(v: [f64; 3], s: f64) -> [f64; 3] {
    [v[0] * s, v[1] * s, v[2] * s]
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// `v` shortened to at most `max` (NaN-safe: a non-finite norm yields zero).
pub fn clamp_norm(v: [f64; 3], max: f64) -> [f64; 3] {
    let n = norm(v);
    if !n.is_finite() {
        return [0.0; 3];
    }
    if n > max {
        scale(v, max / n)
    } else {
        v
    }
}

fn limit_step(from: [f64; 3], to: [f64; 3], max_step: f64) -> [f64; 3] {
    let d = [to[0] - from[0], to[1] - from[1], to[2] - from[2]];
    let n = norm(d);
    if n > max_step && n > 0.0 {
        let s = max_step / n;
        [from[0] + d[0] * s, from[1] + d[1] * s, from[2] + d[2] * s]
    } else {
        to
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clamps_and_stays_finite() {
        let mut s = ForceSafety::new(3.0, 10.0, 5);
        let f = s.condition([30.0, 40.0, 0.0], true);
        assert!((norm(f) - 3.0).abs() < 1e-12);
        let f = s.condition([f64::NAN, 0.0, 0.0], true);
        assert!(f.iter().all(|c| c.is_finite()));
        let f = s.condition([f64::INFINITY, 0.0, 0.0], true);
        assert!(f.iter().all(|c| c.is_finite()));
    }

    #[test]
    fn unhealthy_ramps_to_zero_within_ramp_ticks() {
        let mut s = ForceSafety::new(3.0, 10.0, 5);
        for _ in 0..3 {
            s.condition([0.0, 2.0, 0.0], true);
        }
        assert!((s.last()[1] - 2.0).abs() < 1e-12);
        let mut mags = Vec::new();
        for _ in 0..5 {
            mags.push(norm(s.condition([0.0, 2.0, 0.0], false)));
        }
        // Strictly decreasing, linear, exactly zero at the 5th tick.
        assert!((mags[0] - 1.6).abs() < 1e-12, "{mags:?}");
        assert!(mags.windows(2).all(|w| w[1] < w[0]));
        assert_eq!(mags[4], 0.0);
        // And it ramps back in over 5 ticks.
        let back: Vec<f64> = (0..5)
            .map(|_| norm(s.condition([0.0, 2.0, 0.0], true)))
            .collect();
        assert!((back[0] - 0.4).abs() < 1e-12, "{back:?}");
        assert!((back[4] - 2.0).abs() < 1e-12, "{back:?}");
    }

    #[test]
    fn restart_ramps_in_from_zero_not_from_the_last_force() {
        let mut s = ForceSafety::new(3.0, 10.0, 5);
        for _ in 0..10 {
            s.condition([0.0, 2.0, 0.0], true);
        }
        let mut going_on = s.clone();
        // Without a restart the force goes on from 2 N (the step limit does not bind here).
        assert_eq!(going_on.condition([0.0, 2.5, 0.0], true), [0.0, 2.5, 0.0]);
        // After one, it starts over: a fifth of the force asked, then linearly to all of it.
        s.restart();
        let back: Vec<f64> = (0..6)
            .map(|_| norm(s.condition([0.0, 2.5, 0.0], true)))
            .collect();
        assert!((back[0] - 0.5).abs() < 1e-12, "{back:?}");
        assert!(back.windows(2).all(|w| w[1] > w[0] - 1e-12), "{back:?}");
        assert!((back[4] - 2.5).abs() < 1e-12, "{back:?}");
    }

    #[test]
    fn continuous_limit_lowers_a_held_force_but_allows_peaks() {
        // Peak 3.3 N, continuous 0.88 N averaged over 1000 ticks.
        let mut s = ForceSafety::new(3.3, 10.0, 5).with_continuous(0.88, 1000);
        // A short 3 N peak goes through.
        for _ in 0..50 {
            let f = s.condition([0.0, 3.0, 0.0], true);
            assert!((f[1] - 3.0).abs() < 1e-12);
        }
        // Held for 10 s, the output's RMS settles at the continuous limit, never far above.
        let mut last = 0.0;
        for _ in 0..10_000 {
            last = s.condition([0.0, 3.0, 0.0], true)[1];
        }
        assert!((last - 0.88).abs() < 0.05, "{last}");
        // Without a limit nothing changes.
        let mut s = ForceSafety::new(3.3, 10.0, 5);
        for _ in 0..10_000 {
            last = s.condition([0.0, 3.0, 0.0], true)[1];
        }
        assert_eq!(last, 3.0);
    }

    #[test]
    fn a_ramp_under_a_continuous_limit_that_came_down_starts_from_the_last_force() {
        // Held at 3 N until the continuous limit brings the clamp down faster than the output
        // may follow (0.05 N a tick).
        let mut s = ForceSafety::new(3.0, 0.05, 5).with_continuous(0.88, 1000);
        let mut last = 0.0;
        for _ in 0..100_000 {
            last = norm(s.condition([0.0, 3.0, 0.0], true));
            if last - s.clamp_now() > 0.5 {
                break;
            }
        }
        assert!(
            last - s.clamp_now() > 0.5,
            "{last} against {}",
            s.clamp_now()
        );
        // Then unhealthy: linear from the last force, a fifth of it off a tick (the soak's
        // audit saw 1.71 N cut to 0.99 N, the lowered clamp's 4/5, in one tick).
        let ramp: Vec<f64> = (0..5)
            .map(|_| norm(s.condition([0.0, 3.0, 0.0], false)))
            .collect();
        for (k, f) in ramp.iter().enumerate() {
            let want = last * (4 - k) as f64 / 5.0;
            assert!((f - want).abs() < 1e-9, "{last} N, then {ramp:?}");
        }
    }

    #[test]
    fn step_limit_at_onset_too() {
        // Onset with nothing moving (a loop that starts with the stylus in the tissue): the
        // force ramps in at the step limit.
        let mut still = ForceSafety::new(3.0, 0.05, 5);
        let ramp: Vec<f64> = (0..4)
            .map(|_| still.condition_moving([0.0, 0.9, 0.0], true, Some([0.0; 3]), 1000.0)[1])
            .collect();
        for (k, f) in ramp.iter().enumerate() {
            assert!((f - 0.05 * (k + 1) as f64).abs() < 1e-12, "{ramp:?}");
        }
        // A touch: the stylus moved 0.3 mm into a 1000 N/m spring this tick; its 0.3 N is what
        // the motion explains and comes through at once.
        let mut s = ForceSafety::new(3.0, 0.05, 5);
        s.condition_moving([0.0; 3], true, Some([0.0; 3]), 1000.0);
        let f = s.condition_moving([0.0, 0.3, 0.0], true, Some([0.0, 3e-4, 0.0]), 1000.0);
        assert_eq!(f, [0.0, 0.3, 0.0]);
        // The hand's motion widens the step by what it explains, no more.
        let mut m = s.clone();
        let f = m.condition_moving([0.0, 0.3, 0.0], true, Some([0.0; 3]), 1000.0);
        assert_eq!(f, [0.0, 0.3, 0.0], "no change asked");
        let f = m.condition_moving([0.0, 0.6, 0.0], true, Some([0.0, 0.0, 2e-4]), 1000.0);
        assert!(
            (f[1] - 0.55).abs() < 1e-12,
            "0.2 mm at 1000 N/m: 0.2 N more: {f:?}"
        );
        let f = m.condition_moving([0.0, 0.9, 0.0], true, Some([0.0, 0.0, 4e-4]), f64::NAN);
        assert!((f[1] - 0.6).abs() < 1e-12, "{f:?}");
        // Then limited to 0.05 N per tick.
        let f = s.condition([0.0, 1.3, 0.0], true);
        assert!((f[1] - 0.35).abs() < 1e-12);
    }
}
