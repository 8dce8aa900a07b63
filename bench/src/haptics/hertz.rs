//! Closed-form references for a rigid sphere pressed into an elastic body, frictionless.
//!
//! - [`hertz_force`]: a half-space (Hertz 1882), `F = 4/3 · E/(1−ν²) · √R · d^{3/2}`, contact
//!   radius `a = √(R d)`.
//! - [`bonded_layer_factor`]: how much stiffer a layer of thickness `h` bonded to a rigid base
//!   is, as a function of `χ = a/h` (Dimitriadis et al. 2002, *Biophys. J.* 82:2798, eq. 12,
//!   fourth order, their fit of the coefficients in ν). The bench's block is 20 mm thick and
//!   40 mm wide under a contact radius of ≤ 1.1 mm, so the layer term (a few per cent) is the
//!   main way the block differs from a half-space; its finite width adds less (a free side
//!   face 20 mm away).

use std::f64::consts::PI;

/// Hertz's force of a rigid sphere of radius `radius` pressed `depth` into an elastic
/// half-space of Young's modulus `young` and Poisson's ratio `poisson` (SI units), N.
pub fn hertz_force(young: f64, poisson: f64, radius: f64, depth: f64) -> f64 {
    if !(depth > 0.0) {
        return 0.0;
    }
    4.0 / 3.0 * young / (1.0 - poisson * poisson) * radius.sqrt() * depth.powf(1.5)
}

/// `F_layer / F_Hertz` for a layer of thickness `thickness` bonded to a rigid base, sphere of
/// `radius`, indentation `depth` (Dimitriadis et al. 2002, bonded case):
/// `1 − 2α/π χ + 4α²/π² χ² − 8/π³ (α³ + 4π²β/15) χ³ + 16α/π⁴ (α³ + 3π²β/5) χ⁴`,
/// `χ = √(R d)/h`, `α = −(1.2876 − 1.4678ν + 1.3442ν²)/(1−ν)`,
/// `β = (0.6387 − 1.0277ν + 1.5164ν²)/(1−ν)`. Valid while `χ` is well below 1.
pub fn bonded_layer_factor(poisson: f64, radius: f64, depth: f64, thickness: f64) -> f64 {
    let nu = poisson;
    let chi = (radius * depth.max(0.0)).sqrt() / thickness;
    let alpha = -(1.2876 - 1.4678 * nu + 1.3442 * nu * nu) / (1.0 - nu);
    let beta = (0.6387 - 1.0277 * nu + 1.5164 * nu * nu) / (1.0 - nu);
    1.0 - 2.0 * alpha / PI * chi + 4.0 * alpha * alpha / (PI * PI) * chi.powi(2)
        - 8.0 / PI.powi(3) * (alpha.powi(3) + 4.0 * PI * PI * beta / 15.0) * chi.powi(3)
        + 16.0 * alpha / PI.powi(4) * (alpha.powi(3) + 3.0 * PI * PI * beta / 5.0) * chi.powi(4)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hertz_matches_the_figure_of_the_issue() {
        // 3 mm sphere, 0.3 mm into E 30 kPa, ν 0.3: 12.5 mN.
        let f = hertz_force(30e3, 0.3, 3e-3, 0.3e-3);
        assert!((f - 12.5e-3).abs() < 0.05e-3, "{f}");
    }

    #[test]
    fn a_thick_layer_is_a_half_space_and_a_thinner_one_is_stiffer() {
        assert!((bonded_layer_factor(0.3, 3e-3, 1e-9, 0.02) - 1.0).abs() < 1e-3);
        let f = bonded_layer_factor(0.3, 3e-3, 0.3e-3, 0.02);
        // χ = 0.047: about +4 %.
        assert!(f > 1.03 && f < 1.06, "{f}");
        assert!(bonded_layer_factor(0.3, 3e-3, 0.3e-3, 0.01) > f);
    }
}
