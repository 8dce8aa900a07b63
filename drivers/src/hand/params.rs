//! The simulated hand's physical parameters, their defaults, their checks, and the optional
//! `[hand]` table of a device script that overrides them.

use serde::Deserialize;

/// The fixed upper bound on the internal integration step, seconds: 0.1 ms, i.e. at least
/// 10 kHz. A read that advances the clock by `Δt` takes `ceil(Δt / INTEGRATION_STEP_S)` equal
/// steps.
pub const INTEGRATION_STEP_S: f64 = 1e-4;

/// Speed, m/s, over which the stylus' Coulomb friction rises smoothly from zero to its full
/// value: the friction force is `f_c · v / sqrt(|v|² + v_c²)`, which points against the velocity
/// and reaches 89 % of `f_c` at `|v| = 2 v_c`. 2 mm/s.
pub const FRICTION_SMOOTHING_SPEED_M_S: f64 = 2e-3;

/// How far inside the integrator's stability limit the parameters must keep it: for each mass,
/// `h · (sqrt(Σk / m) + Σc / m)` must not exceed this (classical Runge–Kutta stays stable up to
/// about 2.8 on both the real and the imaginary axis; this keeps it accurate too).
pub(crate) const STEP_RATE_LIMIT: f64 = 0.5;

/// The physical parameters of a stylus held by a hand (SI units: kg, N/m, N·s/m, N).
///
/// The defaults model a Phantom Omni held with a moderate grip:
///
/// | parameter | default | where it comes from |
/// |---|---|---|
/// | `stylus_mass` | 0.045 kg | the Omni's apparent mass at the tip (the vendor's published specifications; the Touch is similar) |
/// | `stylus_damping` | 0.2 N·s/m | assumed: the vendor publishes no viscous figure, the back-drive resistance is mostly friction |
/// | `stylus_friction` | 0.1 N | assumed, under the vendor's published back-drive friction bound of 0.26 N |
/// | `hand_mass` | 0.3 kg | a moderate grip, within the 0.1–1 kg that haptics stability studies quote for a hand on a stylus |
/// | `hand_stiffness` | 300 N/m | moderate, within the quoted 100–1000 N/m |
/// | `hand_damping` | 4 N·s/m | moderate, within the quoted 1–10 N·s/m |
/// | `grip_stiffness` | 2000 N/m | assumed: the fingers hold the stylus more stiffly than the arm holds the hand; in series with `hand_stiffness` it gives 261 N/m at the tip, inside the quoted range |
/// | `grip_damping` | 2 N·s/m | assumed: lightly damped fingertip pads (damping ratio about 0.1 for the stylus-in-fingers mode, near 36 Hz) |
///
/// A light grip (small `hand_stiffness`, `hand_damping`) is the case that tests the loop's
/// stability; a stiff grip the one that tests its transparency.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HandParameters {
    /// Stylus mass at the tip, kg.
    pub stylus_mass: f64,
    /// Viscous damping of the stylus to ground, N·s/m.
    pub stylus_damping: f64,
    /// Coulomb (back-drive) friction of the stylus, N, smoothed over
    /// [`FRICTION_SMOOTHING_SPEED_M_S`].
    pub stylus_friction: f64,
    /// Effective mass of the hand and arm, kg.
    pub hand_mass: f64,
    /// Stiffness pulling the hand toward the scripted intent, N/m.
    pub hand_stiffness: f64,
    /// Damping of the hand relative to the intent's motion, N·s/m.
    pub hand_damping: f64,
    /// Stiffness of the grip between the hand and the stylus, N/m.
    pub grip_stiffness: f64,
    /// Damping of the grip, N·s/m.
    pub grip_damping: f64,
}

impl Default for HandParameters {
    fn default() -> Self {
        HandParameters {
            stylus_mass: 0.045,
            stylus_damping: 0.2,
            stylus_friction: 0.1,
            hand_mass: 0.3,
            hand_stiffness: 300.0,
            hand_damping: 4.0,
            grip_stiffness: 2000.0,
            grip_damping: 2.0,
        }
    }
}

impl HandParameters {
    /// The hard case for stability: a light grip (arm 100 N/m and 1 N·s/m, fingers 500 N/m and
    /// 0.3 N·s/m) on a stylus without damping or friction, so nothing but the rendered force
    /// decides whether the stylus rings. The other parameters are the defaults.
    pub fn light_grip() -> HandParameters {
        HandParameters {
            hand_stiffness: 100.0,
            hand_damping: 1.0,
            grip_stiffness: 500.0,
            grip_damping: 0.3,
            stylus_damping: 0.0,
            stylus_friction: 0.0,
            ..HandParameters::default()
        }
    }
}

/// A parameter that is out of range: its key (as in the `[hand]` table), its value, and why.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("`{key}` = {value}: {reason}")]
pub struct HandParameterError {
    /// The key, e.g. `hand_mass`.
    pub key: &'static str,
    /// The offending value.
    pub value: f64,
    /// What the value must be.
    pub reason: String,
}

impl HandParameters {
    /// The parameters as `(key, value)` pairs, in the `[hand]` table's key order.
    pub fn entries(&self) -> [(&'static str, f64); 8] {
        [
            ("stylus_mass", self.stylus_mass),
            ("stylus_damping", self.stylus_damping),
            ("stylus_friction", self.stylus_friction),
            ("hand_mass", self.hand_mass),
            ("hand_stiffness", self.hand_stiffness),
            ("hand_damping", self.hand_damping),
            ("grip_stiffness", self.grip_stiffness),
            ("grip_damping", self.grip_damping),
        ]
    }

    /// Checks every value: masses and stiffnesses finite and positive, dampings and friction
    /// finite and not negative (zero is a legitimate idealisation, e.g. for an energy test), and
    /// both masses heavy enough for the internal step given what is attached to them. The
    /// first failing key is named. NaN fails every check.
    pub fn validate(&self) -> Result<(), HandParameterError> {
        for (key, value) in self.entries() {
            let positive_only = key.ends_with("mass") || key.ends_with("stiffness");
            let ok = if positive_only {
                value.is_finite() && value > 0.0
            } else {
                value.is_finite() && value >= 0.0
            };
            if !ok {
                let reason = if positive_only {
                    "must be a finite number greater than zero"
                } else {
                    "must be a finite number, zero or greater"
                };
                return Err(HandParameterError {
                    key,
                    value,
                    reason: reason.into(),
                });
            }
        }
        let friction_slope = self.stylus_friction / FRICTION_SMOOTHING_SPEED_M_S;
        let stylus = (
            "stylus_mass",
            self.stylus_mass,
            self.grip_stiffness,
            self.stylus_damping + self.grip_damping + friction_slope,
        );
        let hand = (
            "hand_mass",
            self.hand_mass,
            self.hand_stiffness + self.grip_stiffness,
            self.hand_damping + self.grip_damping,
        );
        for (key, mass, stiffness, damping) in [stylus, hand] {
            let rate = INTEGRATION_STEP_S * ((stiffness / mass).sqrt() + damping / mass);
            if rate > STEP_RATE_LIMIT {
                return Err(HandParameterError {
                    key,
                    value: mass,
                    reason: format!(
                        "too light for the internal {:.0} kHz integration with {stiffness} N/m \
                         and {damping:.4} N·s/m attached to it (including the smoothed \
                         friction): at least {:.3e} kg",
                        1e-3 / INTEGRATION_STEP_S,
                        lightest_mass(stiffness, damping)
                    ),
                });
            }
        }
        Ok(())
    }
}

/// The lightest mass for which `h (sqrt(k/m) + c/m) <= STEP_RATE_LIMIT`: with `s = 1/sqrt(m)`,
/// the positive root of `h c s² + h sqrt(k) s - limit = 0`.
fn lightest_mass(stiffness: f64, damping: f64) -> f64 {
    let h = INTEGRATION_STEP_S;
    let root_k = stiffness.sqrt();
    let s = if damping > 0.0 {
        (-h * root_k + (h * h * stiffness + 4.0 * h * damping * STEP_RATE_LIMIT).sqrt())
            / (2.0 * h * damping)
    } else {
        STEP_RATE_LIMIT / (h * root_k)
    };
    1.0 / (s * s)
}

/// The `[hand]` table as written: every key optional (a missing key keeps its default), unknown
/// keys refused by name.
#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawHand {
    stylus_mass: Option<f64>,
    stylus_damping: Option<f64>,
    stylus_friction: Option<f64>,
    hand_mass: Option<f64>,
    hand_stiffness: Option<f64>,
    hand_damping: Option<f64>,
    grip_stiffness: Option<f64>,
    grip_damping: Option<f64>,
}

impl RawHand {
    /// The defaults with this table's values laid over them (not yet validated).
    pub(crate) fn over_defaults(&self) -> HandParameters {
        let d = HandParameters::default();
        HandParameters {
            stylus_mass: self.stylus_mass.unwrap_or(d.stylus_mass),
            stylus_damping: self.stylus_damping.unwrap_or(d.stylus_damping),
            stylus_friction: self.stylus_friction.unwrap_or(d.stylus_friction),
            hand_mass: self.hand_mass.unwrap_or(d.hand_mass),
            hand_stiffness: self.hand_stiffness.unwrap_or(d.hand_stiffness),
            hand_damping: self.hand_damping.unwrap_or(d.hand_damping),
            grip_stiffness: self.grip_stiffness.unwrap_or(d.grip_stiffness),
            grip_damping: self.grip_damping.unwrap_or(d.grip_damping),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid() {
        HandParameters::default().validate().unwrap();
    }

    #[test]
    fn bad_values_are_refused_by_key() {
        type Spoil = fn(&mut HandParameters);
        let cases: [(&str, Spoil); 5] = [
            ("stylus_mass", |p| p.stylus_mass = 0.0),
            ("hand_stiffness", |p| p.hand_stiffness = -1.0),
            ("grip_damping", |p| p.grip_damping = f64::NAN),
            ("stylus_friction", |p| p.stylus_friction = f64::INFINITY),
            ("stylus_mass", |p| p.stylus_mass = 1e-5),
        ];
        for (key, spoil) in cases {
            let mut p = HandParameters::default();
            spoil(&mut p);
            let e = p.validate().unwrap_err();
            assert_eq!(e.key, key, "{e}");
        }
        let zero_damping = HandParameters {
            hand_damping: 0.0,
            stylus_friction: 0.0,
            ..HandParameters::default()
        };
        zero_damping.validate().unwrap();
    }

    #[test]
    fn the_lightest_mass_sits_on_the_limit() {
        let (k, c) = (2000.0, 53.2);
        let m = lightest_mass(k, c);
        let rate = INTEGRATION_STEP_S * ((k / m).sqrt() + c / m);
        assert!((rate - STEP_RATE_LIMIT).abs() < 1e-12, "{rate}");
    }
}
