//! The hand device: the two-mass model of the module docs, integrated between reads.

use std::io;
use std::path::Path;

use super::params::{HandParameterError, HandParameters, FRICTION_SMOOTHING_SPEED_M_S};
use super::INTEGRATION_STEP_S;
use crate::device::{
    DeviceError, DeviceLimits, DeviceOpenError, DeviceSample, HapticDevice, Pacing,
};
use crate::mock::{
    write_force_csv_with, ForceRecord, ForceRing, MockScript, Ring, FORCE_LIMIT_TOLERANCE,
    FORCE_RECORD_CAPACITY,
};

/// The longest stretch of time one `read` integrates, seconds. A larger jump of the clock (a
/// stalled caller) integrates only its last second, so one read costs at most 10,000 steps.
pub const MAX_CATCH_UP_S: f64 = 1.0;

/// Millimetres per metre: the model runs in SI units, the device speaks millimetres.
const MM: f64 = 1e3;

/// Where the device is in its `new → start → stop` life.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Created,
    Running,
    Stopped,
}

/// Positions (m) and velocities (m/s) of the stylus tip and the hand.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct State {
    stylus_x: [f64; 3],
    stylus_v: [f64; 3],
    hand_x: [f64; 3],
    hand_v: [f64; 3],
    /// Work the grip did on the stylus since the start, J (integrated with the state).
    grip_work: f64,
}

impl State {
    /// Both at rest at `position_m`.
    fn at_rest(position_m: [f64; 3]) -> State {
        State {
            stylus_x: position_m,
            hand_x: position_m,
            ..State::default()
        }
    }

    /// `self + h · d`, `d` a derivative (velocities in the position slots, accelerations in the
    /// velocity slots).
    fn plus(&self, h: f64, d: &State) -> State {
        let mut out = *self;
        for k in 0..3 {
            out.stylus_x[k] += h * d.stylus_x[k];
            out.stylus_v[k] += h * d.stylus_v[k];
            out.hand_x[k] += h * d.hand_x[k];
            out.hand_v[k] += h * d.hand_v[k];
        }
        out.grip_work += h * d.grip_work;
        out
    }
}

/// A stylus held by a simulated hand that follows a [`MockScript`]: the mock's script is the
/// hand's intent, the rendered forces push the stylus back, and the device reports where the
/// stylus actually is. See the [module docs](super) for the model.
///
/// Deterministic: the state advances only in `read(t)`, from the previous read's time to `t`, in
/// equal steps of at most [`INTEGRATION_STEP_S`], under the force last written; the same
/// sequence of reads and writes gives bit-identical samples. Like the mock it refuses a
/// non-finite or over-limit force (renders zero, counts it in
/// [`rejected_forces`](Self::rejected_forces)), plays the script's buttons and injected faults,
/// and records every force it renders. `new` allocates everything; `read`, `write_force` and
/// `stop` allocate nothing.
#[derive(Debug)]
pub struct HandDevice {
    script: MockScript,
    params: HandParameters,
    limits: DeviceLimits,
    /// `"hand (<script name>)"`, built once so `name()` never formats.
    name: String,
    phase: Phase,
    /// Where the stylus and hand start, at rest, m.
    start_position_m: [f64; 3],
    state: State,
    /// Run time the state is at, s.
    t: f64,
    /// Run time of the latest `read` as given (injected faults are looked up at it).
    last_read_t: f64,
    /// The force being rendered, N (zero after a refusal and after `stop`).
    force_n: [f64; 3],
    record: ForceRing,
    /// The grip's work on the stylus at each recorded force, J (beside `record`, entry for
    /// entry).
    grip_record: Ring<f64>,
    rejected_forces: u64,
}

impl HandDevice {
    /// A hand following `script` with the parameters of the script's `[hand]` table (the
    /// defaults without one), rendering within `limits`. Stylus and hand start at rest at the
    /// script's first position.
    pub fn new(script: MockScript, limits: DeviceLimits) -> HandDevice {
        let params = script.hand().unwrap_or_default();
        Self::build(script, params, limits)
    }

    /// As [`new`](Self::new) with explicit `params`, checked by
    /// [`HandParameters::validate`].
    pub fn with_parameters(
        script: MockScript,
        params: HandParameters,
        limits: DeviceLimits,
    ) -> Result<HandDevice, HandParameterError> {
        params.validate()?;
        Ok(Self::build(script, params, limits))
    }

    fn build(script: MockScript, params: HandParameters, limits: DeviceLimits) -> HandDevice {
        let start_position_m = script.sample(0.0).position_mm.map(|p| p / MM);
        HandDevice {
            name: format!("hand ({})", script.name()),
            script,
            params,
            limits,
            phase: Phase::Created,
            start_position_m,
            state: State::at_rest(start_position_m),
            t: 0.0,
            last_read_t: 0.0,
            force_n: [0.0; 3],
            record: ForceRing::with_capacity(FORCE_RECORD_CAPACITY),
            grip_record: Ring::with_capacity(FORCE_RECORD_CAPACITY),
            rejected_forces: 0,
        }
    }

    /// Starts the stylus and the hand at rest at `position_mm` instead of the script's first
    /// position (a step in the intent at `t = 0`, when the two differ).
    pub fn starting_at(mut self, position_mm: [f64; 3]) -> HandDevice {
        self.start_position_m = position_mm.map(|p| p / MM);
        self.state = State::at_rest(self.start_position_m);
        self
    }

    /// The script the hand follows.
    pub fn script(&self) -> &MockScript {
        &self.script
    }

    /// The model's parameters.
    pub fn parameters(&self) -> &HandParameters {
        &self.params
    }

    /// The hand's position (mm) and velocity (mm/s) at the latest read.
    pub fn hand_state(&self) -> ([f64; 3], [f64; 3]) {
        (
            self.state.hand_x.map(|x| x * MM),
            self.state.hand_v.map(|v| v * MM),
        )
    }

    /// The forces rendered so far, as the mock's [`force_record`](crate::mock::MockDevice::force_record).
    pub fn force_record(&self) -> ForceRecord<'_> {
        self.record.view()
    }

    /// The force currently rendered, N.
    pub fn last_force(&self) -> [f64; 3] {
        self.force_n
    }

    /// Whether `stop` has been called (and `start` not since).
    pub fn stopped(&self) -> bool {
        self.phase == Phase::Stopped
    }

    /// Forces refused as non-finite or above the force limit.
    pub fn rejected_forces(&self) -> u64 {
        self.rejected_forces
    }

    /// Writes the force record as CSV, as the mock does, with one more column: `grip_work_j`,
    /// the [`grip_work`](Self::grip_work) when each force was written, so that the energy at
    /// the device port of a live run can be read from the file (it falls below zero only
    /// where the coupling generated energy).
    pub fn write_force_csv(&self, path: &Path) -> io::Result<()> {
        write_force_csv_with(
            self.force_record(),
            Some(("grip_work_j", &self.grip_record)),
            path,
        )
    }

    fn check_running(&self) -> Result<(), DeviceError> {
        match self.phase {
            Phase::Running => Ok(()),
            Phase::Created => Err(DeviceError::NotStarted),
            Phase::Stopped => Err(DeviceError::Stopped),
        }
    }

    fn check_force(&self, force_n: [f64; 3]) -> Result<(), DeviceError> {
        if !force_n.iter().all(|f| f.is_finite()) {
            return Err(DeviceError::NonFiniteForce);
        }
        let magnitude = force_n.iter().map(|f| f * f).sum::<f64>().sqrt();
        if magnitude > self.limits.max_force_n * (1.0 + FORCE_LIMIT_TOLERANCE) {
            return Err(DeviceError::ForceLimitExceeded);
        }
        Ok(())
    }

    /// Advances the state to run time `t`. Time never runs backwards: a `t` that is not later
    /// than the state's (or is not finite) leaves the state as it is.
    fn advance(&mut self, t: f64) {
        if !t.is_finite() || t <= self.t {
            return;
        }
        let from = self.t.max(t - MAX_CATCH_UP_S);
        let span = t - from;
        // The tiny allowance keeps a 1 ms read at 10 steps despite `1e-3 / 1e-4` rounding up.
        let steps = ((span / INTEGRATION_STEP_S) * (1.0 - 1e-12))
            .ceil()
            .max(1.0) as u64;
        let h = span / steps as f64;
        for i in 0..steps {
            self.state = self.rk4_step(from + i as f64 * h, h);
        }
        self.t = t;
    }

    /// One classical fourth-order Runge–Kutta step of length `h` from time `t0`.
    fn rk4_step(&self, t0: f64, h: f64) -> State {
        let y = &self.state;
        let k1 = self.derivative(t0, y);
        let k2 = self.derivative(t0 + 0.5 * h, &y.plus(0.5 * h, &k1));
        let k3 = self.derivative(t0 + 0.5 * h, &y.plus(0.5 * h, &k2));
        let k4 = self.derivative(t0 + h, &y.plus(h, &k3));
        let mut out = *y;
        let w = h / 6.0;
        for k in 0..3 {
            out.stylus_x[k] +=
                w * (k1.stylus_x[k] + 2.0 * (k2.stylus_x[k] + k3.stylus_x[k]) + k4.stylus_x[k]);
            out.stylus_v[k] +=
                w * (k1.stylus_v[k] + 2.0 * (k2.stylus_v[k] + k3.stylus_v[k]) + k4.stylus_v[k]);
            out.hand_x[k] +=
                w * (k1.hand_x[k] + 2.0 * (k2.hand_x[k] + k3.hand_x[k]) + k4.hand_x[k]);
            out.hand_v[k] +=
                w * (k1.hand_v[k] + 2.0 * (k2.hand_v[k] + k3.hand_v[k]) + k4.hand_v[k]);
        }
        out.grip_work += w * (k1.grip_work + 2.0 * (k2.grip_work + k3.grip_work) + k4.grip_work);
        out
    }

    /// The right-hand side of the model at time `t` in state `y`.
    fn derivative(&self, t: f64, y: &State) -> State {
        let p = &self.params;
        let intent = self.script.sample(t);
        let speed_sq: f64 = y.stylus_v.iter().map(|v| v * v).sum();
        // Smoothed Coulomb friction: f_c · v / sqrt(|v|² + v_c²), against the velocity.
        let friction_per_speed = p.stylus_friction
            / (speed_sq + FRICTION_SMOOTHING_SPEED_M_S * FRICTION_SMOOTHING_SPEED_M_S).sqrt();
        let mut d = State::default();
        for k in 0..3 {
            let intent_x = intent.position_mm[k] / MM;
            let intent_v = intent.velocity_mm_s[k] / MM;
            let grip = p.grip_stiffness * (y.hand_x[k] - y.stylus_x[k])
                + p.grip_damping * (y.hand_v[k] - y.stylus_v[k]);
            let arm = p.hand_stiffness * (intent_x - y.hand_x[k])
                + p.hand_damping * (intent_v - y.hand_v[k]);
            let stylus_force = self.force_n[k]
                - p.stylus_damping * y.stylus_v[k]
                - friction_per_speed * y.stylus_v[k]
                + grip;
            d.stylus_x[k] = y.stylus_v[k];
            d.stylus_v[k] = stylus_force / p.stylus_mass;
            d.hand_x[k] = y.hand_v[k];
            d.hand_v[k] = (arm - grip) / p.hand_mass;
            d.grip_work += grip * y.stylus_v[k];
        }
        d
    }

    /// The work the hand's grip has done on the stylus since the device started, J: the energy
    /// the hand put into the device and, through it, into the rendered environment. The stylus
    /// with its own damping and friction, plus a passive environment, can never give back
    /// more than it received, so this never falls below zero when the coupling is passive
    /// (integrated with the state, to the integrator's accuracy).
    pub fn grip_work(&self) -> f64 {
        self.state.grip_work
    }

    /// The stylus as a device sample, with the intent's buttons at the state's time.
    fn sample(&self) -> DeviceSample {
        DeviceSample {
            position_mm: self.state.stylus_x.map(|x| x * MM),
            velocity_mm_s: self.state.stylus_v.map(|v| v * MM),
            buttons: self.script.sample(self.t).buttons,
        }
    }
}

impl HapticDevice for HandDevice {
    fn name(&self) -> &str {
        &self.name
    }

    fn limits(&self) -> DeviceLimits {
        self.limits
    }

    fn pacing(&self) -> Pacing {
        Pacing::SelfPaced
    }

    /// Starts (or restarts after `stop`) from rest at the start position, clock at zero, no
    /// force; never fails.
    fn start(&mut self) -> Result<(), DeviceOpenError> {
        self.state = State::at_rest(self.start_position_m);
        self.t = 0.0;
        self.last_read_t = 0.0;
        self.force_n = [0.0; 3];
        self.phase = Phase::Running;
        Ok(())
    }

    /// Integrates to `t` under the force last written, then reports the stylus (broken as a
    /// sample fault active at `t` says; the stylus itself moves on unharmed); or the injected
    /// device fault active at `t` (the hand keeps moving meanwhile, with no force on it).
    fn read(&mut self, t: f64) -> Result<DeviceSample, DeviceError> {
        self.check_running()?;
        self.last_read_t = t;
        self.advance(t);
        let device_fault = self
            .script
            .faults()
            .iter()
            .find(|fault| fault.contains(t) && !fault.error.is_recoverable());
        match device_fault {
            Some(fault) => {
                self.force_n = [0.0; 3];
                Err(fault.error)
            }
            None => {
                let sample = self.sample();
                Ok(match self.script.sample_fault_at(t) {
                    Some(fault) => fault.apply(sample, &self.limits),
                    None => sample,
                })
            }
        }
    }

    /// Renders `force_n` on the stylus until the next write, or zero (with an error) if it is
    /// non-finite, above the force limit, or an injected fault is active at the last read.
    fn write_force(&mut self, force_n: [f64; 3]) -> Result<(), DeviceError> {
        self.check_running()?;
        let read_t = self.last_read_t;
        let injected = self.script.faults().iter().find(|f| f.contains(read_t));
        let verdict = match injected {
            Some(fault) => Err(fault.error),
            None => self
                .check_force(force_n)
                .inspect_err(|_| self.rejected_forces += 1),
        };
        self.force_n = if verdict.is_ok() { force_n } else { [0.0; 3] };
        self.record.push(self.t, self.force_n);
        self.grip_record.push_entry(self.state.grip_work);
        verdict
    }

    /// Renders zero force (recorded) if running, then marks the device stopped. Idempotent.
    fn stop(&mut self) {
        if self.phase == Phase::Running {
            self.force_n = [0.0; 3];
            self.record.push(self.t, [0.0; 3]);
            self.grip_record.push_entry(self.state.grip_work);
        }
        self.phase = Phase::Stopped;
    }
}
