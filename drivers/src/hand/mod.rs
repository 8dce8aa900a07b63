//! A simulated hand holding the stylus: the stand-in for a person in tests, benchmarks and demos
//! (`--device hand[:SCRIPT]`).
//!
//! The mock ([`crate::mock`]) moves the stylus exactly along its script whatever force it is
//! sent; a person does not. [`HandDevice`] plays the same script as a hand's *intent* and
//! reports where the stylus ends up when that hand, the stylus' own inertia and friction, and
//! the forces lop renders all act on it. Pushing into stiff tissue, the stylus stops short of
//! the intent; a light grip lets the stylus ring against a wall.
//!
//! # Model
//!
//! Two masses per axis (SI units inside; the device reports millimetres as every driver does):
//! the stylus tip `x_s` (mass `m_s`) and the hand `x_h` (mass `m_h`). The hand is pulled toward
//! the scripted intent `x_i(t)` (the script sampled at `t`, with its velocity `v_i`) by the arm's
//! stiffness and damping; the fingers couple hand and stylus through the grip's; the rendered
//! force `F` acts on the stylus, which also has viscous damping and smoothed Coulomb friction:
//!
//! ```text
//! m_s ẍ_s = F − b_s ẋ_s − f_c ẋ_s / sqrt(|ẋ_s|² + v_c²) + k_g (x_h − x_s) + b_g (ẋ_h − ẋ_s)
//! m_h ẍ_h = k_h (x_i − x_h) + b_h (v_i − ẋ_h) − k_g (x_h − x_s) − b_g (ẋ_h − ẋ_s)
//! ```
//!
//! The arm's damping acts on the velocity relative to the intent, so a hand that follows a
//! steadily moving intent feels no drag from its own damping. The axes are independent except
//! through the friction, which opposes the stylus' velocity vector. At rest under a constant
//! force the friction vanishes and the stylus sits at
//! `x_s = x_i + F (1/k_h + 1/k_g)`: the arm and the grip are springs in series.
//!
//! Parameters and their defaults (an Omni held with a moderate grip) are in
//! [`HandParameters`]; a script's optional `[hand]` table overrides any of them (see
//! [`crate::mock::MockScript`]).
//!
//! # Integration
//!
//! Classical fourth-order Runge–Kutta with a fixed step of at most [`INTEGRATION_STEP_S`]
//! (0.1 ms: at least 10 kHz). `read(t)` advances the state from the previous read's time to `t`
//! in `ceil((t − t_prev) / 0.1 ms)` equal steps — ten per 1 kHz tick — sampling the intent at
//! each stage, with the last written force held constant over the interval (the zero-order hold
//! of a real device's amplifier). The parameters are checked against the step (a stylus too light
//! for its grip is refused), and a stalled caller catches up at most [`MAX_CATCH_UP_S`].
//! Everything is allocated in `new`.

mod device;
mod params;

pub use device::{HandDevice, MAX_CATCH_UP_S};
pub(crate) use params::RawHand;
pub use params::{
    HandParameterError, HandParameters, FRICTION_SMOOTHING_SPEED_M_S, INTEGRATION_STEP_S,
};
