//! What a finite-element body is built from: its elasticity ([`FemMode`]), its parameters
//! ([`FemParameters`]) and what can go wrong building or solving it ([`FemError`]).

use thiserror::Error;

/// Which elasticity the elements use; a scene's `[body.fem] mode` (`"linear"`,
/// `"corotational"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum FemMode {
    /// Linear elasticity (thesis §4.2): one factorisation per scene; inflates under rotation.
    Linear,
    /// Corotational (stiffness warping): rotation-invariant; solved by preconditioned CG.
    #[default]
    Corotational,
}

/// Parameters of a finite-element body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FemParameters {
    /// Young's modulus `E`, Pa.
    pub young: f64,
    /// Poisson's ratio `ν`, in (−1, 0.5).
    pub poisson: f64,
    /// Density `ρ`, kg/m³.
    pub density: f64,
    /// Mass-proportional damping `α`, 1/s: `D = αM`.
    pub damping: f64,
    /// Time step, s.
    pub dt: f64,
    /// Linear or corotational elements.
    pub mode: FemMode,
}

/// Why a finite-element body could not be built or solved.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FemError {
    /// A parameter is out of range or not finite.
    #[error("FEM parameter `{name}` = {value} is invalid: expected {expected}")]
    InvalidParameter {
        /// Field of [`FemParameters`].
        name: &'static str,
        /// The value given.
        value: f64,
        /// The valid range.
        expected: &'static str,
    },
    /// A tetrahedron is flat, inverted or collapsed at rest.
    #[error(
        "tetrahedron {element} (nodes {nodes:?}, 0-based) is degenerate or inverted: \
         signed volume {volume:e} m^3"
    )]
    DegenerateElement {
        /// 0-based tetrahedron index.
        element: usize,
        /// Its 0-based node indices.
        nodes: [u32; 4],
        /// Its signed rest volume.
        volume: f64,
    },
    /// A static solve on a body with no fixed node (it has no equilibrium under a net load).
    #[error("the body has no fixed nodes: a static equilibrium needs supports")]
    Unsupported,
    /// The stiffness matrix is not positive definite: the fixed nodes leave a rigid motion free.
    #[error("the stiffness matrix is singular: the fixed nodes do not prevent every rigid motion")]
    Singular,
    /// The corotational static iteration did not reach the tolerance.
    #[error(
        "static solve did not converge in {iterations} iterations \
         (relative residual {residual:e})"
    )]
    NotConverged {
        /// Iterations done.
        iterations: usize,
        /// Final residual relative to the load.
        residual: f64,
    },
    /// faer could not build the sparse structures (out of memory, index overflow).
    #[error("sparse solver setup failed: {0}")]
    Solver(String),
}

pub(super) fn validate(p: &FemParameters) -> Result<(), FemError> {
    let bad = |name, value, expected| {
        Err(FemError::InvalidParameter {
            name,
            value,
            expected,
        })
    };
    if !(p.young > 0.0 && p.young.is_finite()) {
        return bad("young", p.young, "a finite modulus > 0 Pa");
    }
    if !(p.poisson > -1.0 && p.poisson < 0.5) {
        return bad("poisson", p.poisson, "a ratio in (-1, 0.5)");
    }
    if !(p.density > 0.0 && p.density.is_finite()) {
        return bad("density", p.density, "a finite density > 0 kg/m^3");
    }
    if !(p.damping >= 0.0 && p.damping.is_finite()) {
        return bad("damping", p.damping, "a finite alpha >= 0 1/s");
    }
    if !(p.dt > 0.0 && p.dt.is_finite()) {
        return bad("dt", p.dt, "a finite time step > 0 s");
    }
    Ok(())
}
