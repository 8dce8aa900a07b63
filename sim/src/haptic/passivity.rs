//! A passivity observer and controller at the device port (time-domain passivity, Hannaford
//! and Ryu): the haptic loop's guard against a coupling that generates energy.
//!
//! The tissue, the tool spring and the god-object are passive on paper; sampling, the frames'
//! delay and the local model's linearisation are not, and a light grip on a stiff tool against
//! stiff tissue can ring. The observer integrates the energy that flowed *into* the virtual
//! environment through the port since the contact began,
//!
//! ```text
//! E_n = E_{n−1} − F_{n−1} · (x_n − x_{n−1})
//! ```
//!
//! with `F` the force the device rendered on the hand over the last period (zero-order hold)
//! and `x` the stylus position. A passive environment never has `E < 0`: it can only give back
//! what the hand put in.
//!
//! **The controller acts on the coming period, not the last one.** With the force held over a
//! period, the observer learns what a force did only one tick after it was rendered; a
//! controller that waits for `E < 0` (Hannaford and Ryu's) is always a period late, and at a
//! release that period is the last one in contact: the tissue follows the tool out and gives
//! back, through a force that then vanishes, what is left of the account and a little more
//! (the sampled spring, the frame one tick old), and once the tool has let go there is no force
//! left to dissipate the surplus with. A bare stylus passes it whole to the hand (measured on
//! two light grips letting go of a pinched cube: 1.5 µJ at each device port, with the
//! controller acting on every tick it could). So the controller predicts the period ahead:
//! the stylus keeps moving by `Δx = x_n − x_{n−1}`, give or take [`MOTION_ALLOWANCE`], and the
//! force `f` would carry `−f · Δx` into the environment. If that would take `E` below zero, it
//! subtracts `α v` along the stylus' velocity `v = Δx / T`, in two parts:
//!
//! - the environment's push along the motion beyond what the account holds, `α v² T' =
//!   f · v T' − E` (`T' = T (1 + MOTION_ALLOWANCE)`): the environment may give back what the
//!   account holds, not more. This only takes away part of `f` along the motion, never more
//!   than all of it, so it needs no cap and acts at any speed: a light hand slowing to a stop
//!   against tissue that still pushes is where a capped damping (`α ≤ 5 N·s/m` at a few mm/s)
//!   let 0.8 µJ through;
//! - a surplus already there (`E < 0`: the stylus moved more than allowed): a damping
//!   `α = −E / (T' |v|²)`, at most [`max_damping`](PassivityController::new), above
//!   [`STILL_SPEED`].
//!
//! While the account holds more than a period can give back (a press, a hold), nothing
//! changes. The observer is reset once no force has been
//! rendered for [`RESET_AFTER_S`] (between contacts), so a long dissipative press does not
//! bank energy that would hide a surplus in a later contact; a stylus bouncing on the tissue
//! keeps one account over its bounces, since a bounce's release is where a sampled coupling
//! generates energy.
//!
//! Positions and forces are taken in the device's frame (metres, newtons): the energy is the
//! one at the stylus, whatever the workspace's scale. Allocation-free.

use glam::DVec3;

use crate::vec3::v;

/// Below this speed the stylus is taken as still and no damping is added, m/s (1 µm per 1 ms
/// tick: under the Omni's position resolution).
const STILL_SPEED: f64 = 1e-3;

/// How much farther than in the last period the stylus may move in the next one, as a
/// fraction, when the controller predicts the energy the coming period carries: the account
/// is kept at zero against the larger move, so a stylus speeding up at a release (the light
/// grip's: 1–3 % per tick as the tissue lets go) cannot carry it below. A larger allowance
/// only lets the controller start one period earlier, when the account is nearly spent.
pub const MOTION_ALLOWANCE: f64 = 0.5;

/// Out of contact this long, the observer forgets the contact's energy, s: longer than a
/// stylus bouncing on tissue stays in the air (a few ms to tens of ms), shorter than a
/// deliberate lift between two touches.
pub const RESET_AFTER_S: f64 = 0.1;

/// The observer and controller of one device port.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassivityController {
    max_damping: f64,
    energy: f64,
    last_position: Option<DVec3>,
    last_force: DVec3,
    /// Energy the controller dissipated since creation, J.
    dissipated: f64,
    /// Ticks on which it acted.
    active_ticks: u64,
    /// Time without force since the last contact, s.
    idle: f64,
}

impl PassivityController {
    /// A controller adding at most `max_damping` N·s/m of damping to dissipate a surplus (not
    /// finite, zero or negative: a controller that never acts, the observer alone).
    pub fn new(max_damping: f64) -> PassivityController {
        PassivityController {
            max_damping: if max_damping.is_finite() {
                max_damping.max(0.0)
            } else {
                0.0
            },
            energy: 0.0,
            last_position: None,
            last_force: DVec3::ZERO,
            dissipated: 0.0,
            active_ticks: 0,
            idle: 0.0,
        }
    }

    /// One tick: the stylus at `position` (m), the environment's force on the hand `force`
    /// (N), `period` seconds since the last tick. Returns the force to render. Report what
    /// was actually rendered with [`rendered`](Self::rendered) before the next tick.
    pub fn condition(&mut self, position: [f64; 3], force: [f64; 3], period: f64) -> [f64; 3] {
        let x = v(position);
        let f = v(force);
        let Some(prev) = self.last_position.filter(|_| x.is_finite()) else {
            self.last_position = x.is_finite().then_some(x);
            return force;
        };
        self.last_position = Some(x);
        let dx = x - prev;
        let flowed = -self.last_force.dot(dx);
        if flowed.is_finite() {
            self.energy += flowed;
        }
        if f == DVec3::ZERO || !f.is_finite() {
            if period.is_finite() {
                self.idle += period.max(0.0);
            }
            if self.idle >= RESET_AFTER_S {
                self.energy = 0.0;
            }
            return force;
        }
        self.idle = 0.0;
        let vel = dx / period;
        let speed2 = vel.length_squared();
        // `max_damping` 0 turns the controller off (the observer keeps counting).
        if self.max_damping == 0.0 || !(period > 0.0) || !(speed2 > 0.0) || !speed2.is_finite() {
            return force;
        }
        // Over the coming period (the stylus moving by `Δx (1 + allowance)`), `f` would give
        // back `give` (its push along the motion) or take `take` (its resistance).
        let ahead = period * (1.0 + MOTION_ALLOWANCE);
        let push = f.dot(vel) * ahead;
        let (give, take) = (push.max(0.0), (-push).max(0.0));
        // The push beyond what the account holds is taken away: never more than the push, so
        // the force only loses its part along the motion, and needs no cap.
        let excess = give - self.energy.max(0.0);
        let mut alpha = excess.max(0.0) / (ahead * speed2);
        // A surplus already there (the stylus moved more than allowed) is dissipated by a
        // damping of at most `max_damping`, where the stylus moves enough to measure.
        let deficit = (-self.energy).max(0.0) - take;
        if deficit > 0.0 && speed2 > STILL_SPEED * STILL_SPEED {
            alpha += (deficit / (ahead * speed2)).min(self.max_damping);
        }
        if !(alpha > 0.0) {
            return force;
        }
        self.active_ticks += 1;
        self.dissipated += alpha * speed2 * period;
        (f - vel * alpha).to_array()
    }

    /// The force the device actually rendered this tick (after the safety's clamp and ramp),
    /// N: the observer's `F` for the next period.
    pub fn rendered(&mut self, force: [f64; 3]) {
        let f = v(force);
        self.last_force = if f.is_finite() { f } else { DVec3::ZERO };
    }

    /// The force last reported [`rendered`](Self::rendered), N (zero after a reset).
    pub fn last_rendered(&self) -> [f64; 3] {
        self.last_force.to_array()
    }

    /// Forgets the port's history (the device or the contact restarted).
    pub fn reset(&mut self) {
        self.energy = 0.0;
        self.idle = 0.0;
        self.last_position = None;
        self.last_force = DVec3::ZERO;
    }

    /// The observed energy of the current contact, J (negative: the coupling generated it).
    pub fn energy(&self) -> f64 {
        self.energy
    }

    /// Energy dissipated by the controller so far, J.
    pub fn dissipated(&self) -> f64 {
        self.dissipated
    }

    /// Ticks on which the controller added damping.
    pub fn active_ticks(&self) -> u64 {
        self.active_ticks
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A spring rendered with a one-tick delay (an active element): driven through a press and
    /// release it generates energy; with the controller the port's energy never stays below
    /// what one period can carry, and the observer's sum matches the work done.
    #[test]
    fn a_delayed_spring_is_made_passive() {
        let k = 500.0;
        let period = 1e-3;
        let run = |pc: Option<&mut PassivityController>| -> f64 {
            let mut pc = pc;
            let mut work_into_env = 0.0;
            let mut last_f = [0.0; 3];
            let mut last_x = 0.0;
            let mut delayed = 0.0;
            for n in 0..400 {
                // Press 2 mm at 5 cm/s… and back out.
                let t = n as f64 * period;
                let x = -0.002 * (std::f64::consts::PI * t / 0.4).sin();
                work_into_env += -last_f[2] * (x - last_x);
                let f_env = if delayed < 0.0 {
                    [0.0, 0.0, -k * delayed]
                } else {
                    [0.0; 3]
                };
                delayed = x;
                let f = match pc.as_deref_mut() {
                    Some(pc) => {
                        let f = pc.condition([0.0, 0.0, x], f_env, period);
                        pc.rendered(f);
                        f
                    }
                    None => f_env,
                };
                last_f = f;
                last_x = x;
            }
            work_into_env
        };
        let open = run(None);
        let mut pc = PassivityController::new(50.0);
        let closed = run(Some(&mut pc));
        // One period of the delayed spring generates about `k Δx²` with `Δx` the stylus' move
        // per period (at most 2 mm · π / 0.4 s · 1 ms); the controller acts one period after a
        // surplus shows, so a few periods' worth may remain of a surplus 100 times larger.
        let dx = 0.002 * std::f64::consts::PI / 0.4 * period;
        assert!(
            open < -100.0 * k * dx * dx,
            "the delayed spring generates energy: {open}"
        );
        assert!(
            closed > -4.0 * k * dx * dx,
            "with the controller: {closed} J"
        );
        assert!(pc.active_ticks() > 0 && pc.dissipated() > 0.0);
    }

    /// A damper is passive at the port even sampled (while the stylus does not reverse, the
    /// force of one period opposes the motion of the next): the controller never acts.
    #[test]
    fn a_passive_damper_is_left_alone() {
        let mut pc = PassivityController::new(50.0);
        let b = 2.0;
        let mut last_x = 0.0;
        for n in 1..200 {
            let t = n as f64 * 1e-3;
            let x = -0.01 * t * t;
            let f = [0.0, 0.0, -b * (x - last_x) / 1e-3];
            last_x = x;
            let out = pc.condition([0.0, 0.0, x], f, 1e-3);
            assert_eq!(out, f);
            pc.rendered(out);
        }
        assert!(pc.energy() > 0.0);
        assert_eq!(pc.active_ticks(), 0);
    }

    #[test]
    fn nan_and_no_force_are_harmless() {
        let mut pc = PassivityController::new(f64::NAN);
        assert_eq!(
            pc.condition([f64::NAN; 3], [1.0, 0.0, 0.0], 1e-3),
            [1.0, 0.0, 0.0]
        );
        pc.rendered([f64::NAN; 3]);
        assert_eq!(pc.condition([0.0; 3], [0.0; 3], 1e-3), [0.0; 3]);
        assert_eq!(pc.energy(), 0.0);
        // A surplus survives a short lift and is forgotten after a long one.
        pc.rendered([0.0, 0.0, 1.0]);
        pc.condition([0.0, 0.0, 0.001], [0.0, 0.0, 1.0], 1e-3);
        assert!(pc.energy() < 0.0);
        let surplus = pc.energy();
        pc.rendered([0.0; 3]);
        for _ in 0..50 {
            pc.condition([0.0, 0.0, 0.001], [0.0; 3], 1e-3);
        }
        assert_eq!(pc.energy(), surplus);
        for _ in 0..60 {
            pc.condition([0.0, 0.0, 0.001], [0.0; 3], 1e-3);
        }
        assert_eq!(pc.energy(), 0.0);
    }
}
