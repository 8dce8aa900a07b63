//! One organ's temperature field: [`HeatBody`], its parameters and errors.

use thiserror::Error;

use super::system::{HeatSystem, PAIRS};
use crate::fem::element::Element;
use crate::mesh::TetMesh;
use crate::vec3::{cross, norm, sub};

/// Absolute zero, °C: temperatures must stay above it.
pub const ABSOLUTE_ZERO: f64 = -273.15;
/// Highest temperature accepted as input, °C: far above anything tissue survives, low enough to
/// catch a kelvin or millikelvin value given by mistake.
pub const MAX_TEMPERATURE: f64 = 1000.0;

/// Thermal parameters of one body, and the air around it. SI units and °C.
///
/// [`HeatParameters::default`] is soft tissue like liver (typical literature values, e.g. the
/// IT'IS Foundation tissue database and Duck, *Physical Properties of Tissue*, 1990), in room air
/// with natural convection, with protein coagulation at 60 °C.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeatParameters {
    /// Thermal conductivity `k`, W/m/K (> 0). Liver ≈ 0.52.
    pub conductivity: f64,
    /// Specific heat capacity `c`, J/kg/K (> 0). Liver ≈ 3540.
    pub specific_heat: f64,
    /// Density `ρ` for the heat capacity, kg/m³ (> 0). Liver ≈ 1060. Deliberately separate from
    /// the deformation models' densities, which are tuned for dynamics, not heat.
    pub density: f64,
    /// Initial (body) temperature, °C, and the value [`HeatBody::reset`] returns to. 37.
    pub initial: f64,
    /// Coagulation temperature, °C (> `initial`): a node hotter than this is burned. 60.
    pub coagulation: f64,
    /// Stiffness factor of burned tissue (> 0); 1 = burns do not change stiffness. 1.
    pub burn_stiffening: f64,
    /// Air temperature, °C. 22.
    pub air_temperature: f64,
    /// Convective coefficient to the air `h`, W/m²/K (>= 0; 0 insulates the body). 10
    /// (natural convection).
    pub air_coefficient: f64,
    /// Time step, s (0 < dt <= 1e6: the scheme is stable at any step; the bound only catches
    /// nonsense). 0.01.
    pub dt: f64,
}

impl Default for HeatParameters {
    fn default() -> Self {
        HeatParameters {
            conductivity: 0.52,
            specific_heat: 3540.0,
            density: 1060.0,
            initial: 37.0,
            coagulation: 60.0,
            burn_stiffening: 1.0,
            air_temperature: 22.0,
            air_coefficient: 10.0,
            dt: 0.01,
        }
    }
}

impl HeatParameters {
    /// Thermal diffusivity `α = k / (ρ c)`, m²/s.
    #[must_use]
    pub fn diffusivity(&self) -> f64 {
        self.conductivity / (self.density * self.specific_heat)
    }

    /// Checks every field (NaN fails every check).
    ///
    /// # Errors
    /// [`HeatError::InvalidParameter`] naming the first bad field.
    pub fn validate(&self) -> Result<(), HeatError> {
        let bad = |name, value, expected| {
            Err(HeatError::InvalidParameter {
                name,
                value,
                expected,
            })
        };
        let positive = |v: f64| v.is_finite() && v > 0.0;
        let temperature = |v: f64| v > ABSOLUTE_ZERO && v <= MAX_TEMPERATURE;
        if !positive(self.conductivity) {
            return bad(
                "conductivity",
                self.conductivity,
                "a finite number > 0 (W/m/K)",
            );
        }
        if !positive(self.specific_heat) {
            return bad(
                "specific_heat",
                self.specific_heat,
                "a finite number > 0 (J/kg/K)",
            );
        }
        if !positive(self.density) {
            return bad("density", self.density, "a finite number > 0 (kg/m³)");
        }
        if !temperature(self.initial) {
            return bad(
                "initial",
                self.initial,
                "°C, above -273.15 and at most 1000",
            );
        }
        if !(temperature(self.coagulation) && self.coagulation > self.initial) {
            return bad(
                "coagulation",
                self.coagulation,
                "°C, above the initial temperature and at most 1000",
            );
        }
        if !positive(self.burn_stiffening) {
            return bad(
                "burn_stiffening",
                self.burn_stiffening,
                "a finite number > 0",
            );
        }
        if !temperature(self.air_temperature) {
            return bad(
                "air_temperature",
                self.air_temperature,
                "°C, above -273.15 and at most 1000",
            );
        }
        if !(self.air_coefficient.is_finite() && self.air_coefficient >= 0.0) {
            return bad(
                "air_coefficient",
                self.air_coefficient,
                "a finite number >= 0 (W/m²/K)",
            );
        }
        if !(positive(self.dt) && self.dt <= 1e6) {
            return bad("dt", self.dt, "> 0 and <= 1e6 (s)");
        }
        Ok(())
    }
}

/// Why a heat body or world could not be built, changed or stepped.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum HeatError {
    /// A parameter is out of range or not finite.
    #[error("heat parameter `{name}` = {value} is invalid: expected {expected}")]
    InvalidParameter {
        /// Field of [`HeatParameters`] (or `power`, `conductance`, ...).
        name: &'static str,
        /// The value given.
        value: f64,
        /// The valid range.
        expected: &'static str,
    },
    /// A tetrahedron is flat or inverted at rest.
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
    /// A node index names no node.
    #[error("node {node} (0-based) does not exist: the body has {nodes} nodes")]
    NodeOutOfRange {
        /// The index given.
        node: u32,
        /// Nodes of the body.
        nodes: usize,
    },
    /// A node that no tetrahedron uses has no heat capacity: it cannot take or exchange heat.
    #[error("node {node} (0-based) belongs to no tetrahedron: it has no heat capacity")]
    NoCapacity {
        /// The node.
        node: u32,
    },
    /// Barycentric weights that are negative, not finite or sum to zero.
    #[error("barycentric weights {weights:?} are invalid: expected finite numbers >= 0 with a positive sum")]
    InvalidWeights {
        /// The weights given.
        weights: [f64; 3],
    },
    /// A temperature field of the wrong length.
    #[error("temperature field has {got} values, expected one per node: {expected}")]
    WrongLength {
        /// Values given.
        got: usize,
        /// Nodes of the body.
        expected: usize,
    },
    /// A temperature that is not finite or outside (-273.15, 1000] °C.
    #[error(
        "temperature {value} °C at node {node} is invalid: expected above -273.15 and at most 1000"
    )]
    InvalidTemperature {
        /// 0-based node.
        node: usize,
        /// The value given.
        value: f64,
    },
    /// A body index names no body of the world.
    #[error("body {body} does not exist: the world has {bodies} bodies")]
    BodyOutOfRange {
        /// The index given.
        body: usize,
        /// Bodies of the world.
        bodies: usize,
    },
    /// The bodies of a world step together and must share one time step.
    #[error("body {body} has time step {dt} s, but the world steps with {expected} s")]
    TimeStepMismatch {
        /// 0-based body.
        body: usize,
        /// Its time step.
        dt: f64,
        /// The world's (body 0's) time step.
        expected: f64,
    },
    /// A link joins a node to itself.
    #[error("link {index} joins node {node} of body {body} to itself")]
    SelfLink {
        /// 0-based link.
        index: usize,
        /// The body.
        body: usize,
        /// The node.
        node: u32,
    },
    /// The step produced a non-finite temperature; the state was left as before the step.
    #[error("the heat step produced a non-finite temperature at node {node}; state rolled back")]
    NonFinite {
        /// First bad node.
        node: usize,
    },
    /// The step matrix is not positive definite (not expected for valid parameters).
    #[error("the heat step matrix is not positive definite")]
    NotPositiveDefinite,
    /// faer could not build the sparse structures (out of memory, index overflow).
    #[error("sparse solver setup failed: {0}")]
    Solver(String),
}

/// What one [`HeatBody::step`] did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HeatReport {
    /// Energy injected by the heat sources during the step, J.
    pub injected: f64,
    /// Energy given to the air during the step, J (negative when the air warms the body).
    pub to_air: f64,
    /// Hottest node after the step, °C.
    pub max_temperature: f64,
    /// Nodes burned during this step.
    pub newly_burned: usize,
}

/// One organ's temperature field on its tetrahedral mesh, stepped by backward Euler (see the
/// [module docs](super)). `new` allocates and factorises; `step`, `heat_point`,
/// `set_temperatures` and `reset` do not allocate.
#[derive(Debug, Clone)]
pub struct HeatBody {
    params: HeatParameters,
    /// Node temperatures, °C: the state.
    temperature: Vec<f64>,
    /// Lumped heat capacity per node `Cᵢ = Σₑ ρcVₑ/4`, J/K (0 for unused nodes).
    capacity: Vec<f64>,
    /// Surface area per node, one third of each incident surface triangle, m².
    area: Vec<f64>,
    /// Air conductance per node `Hᵢ = h Aᵢ`, W/K.
    air: Vec<f64>,
    /// Heat source per node for the next step, W. Filled by `heat_point` / `heat_node`, read
    /// and cleared by `step`.
    source: Vec<f64>,
    /// Burned nodes (temperature has exceeded `coagulation` since the last reset).
    burned: Vec<bool>,
    burned_count: usize,
    /// Per node: `burn_stiffening` if burned, else 1.
    stiffness_factor: Vec<f64>,
    /// `K`, its pattern and the factor of `C/Δt + K + H`.
    system: Box<HeatSystem>,
    /// Scratch of `step`: `K T`, then the right-hand side and the increment `T⁺ − T`.
    scratch: Vec<f64>,
    /// Scratch of `step`: the diagonal `C/Δt + H` (1 on unused nodes), kept from the last
    /// factorisation.
    diagonal: Vec<f64>,
}

impl HeatBody {
    /// Builds the conductance matrix, capacities and air conductances from the mesh's rest
    /// geometry and factorises the step matrix. Every node starts at `params.initial`.
    ///
    /// # Errors
    /// [`HeatError::InvalidParameter`], [`HeatError::DegenerateElement`],
    /// [`HeatError::Solver`], [`HeatError::NotPositiveDefinite`].
    pub fn new(mesh: &TetMesh, params: HeatParameters) -> Result<HeatBody, HeatError> {
        params.validate()?;
        let n = mesh.nodes.len();
        if let Some(t) = mesh.tets.iter().flatten().find(|&&t| t as usize >= n) {
            return Err(HeatError::NodeOutOfRange { node: *t, nodes: n });
        }
        let mut system =
            HeatSystem::new(n, &mesh.tets).map_err(|e| HeatError::Solver(e.to_string()))?;
        let mut capacity = vec![0.0; n];
        let rho_c = params.density * params.specific_heat;
        for (e, t) in mesh.tets.iter().enumerate() {
            let corners = t.map(|i| mesh.nodes[i as usize]);
            let Some(el) = Element::new(*t, corners) else {
                return Err(HeatError::DegenerateElement {
                    element: e,
                    nodes: *t,
                    volume: mesh.tet_volume(e),
                });
            };
            // K_ab = k V ∇N_a·∇N_b; rows sum to zero because Σ ∇N = 0.
            let kv = params.conductivity * el.volume;
            for (p, &(a, b)) in PAIRS.iter().enumerate() {
                let g = el.grad;
                let kab = kv * (g[a][0] * g[b][0] + g[a][1] * g[b][1] + g[a][2] * g[b][2]);
                system.conductance[system.scatter[e][p] as usize] += kab;
            }
            for &i in t {
                capacity[i as usize] += rho_c * el.volume / 4.0;
            }
        }
        let mut area = vec![0.0; n];
        for tri in &mesh.surface {
            let [a, b, c] = tri.map(|i| mesh.nodes[i as usize]);
            let third = norm(cross(sub(b, a), sub(c, a))) / 6.0;
            for &i in tri {
                area[i as usize] += third;
            }
        }
        let air = area.iter().map(|a| params.air_coefficient * a).collect();
        let mut body = HeatBody {
            params,
            temperature: vec![params.initial; n],
            capacity,
            area,
            air,
            source: vec![0.0; n],
            burned: vec![false; n],
            burned_count: 0,
            stiffness_factor: vec![1.0; n],
            system: Box::new(system),
            scratch: vec![0.0; n],
            diagonal: vec![0.0; n],
        };
        body.refactorize()?;
        Ok(body)
    }

    /// `A = C/Δt + K + H`, factorised into the existing buffers (no allocation). Unused nodes
    /// (no capacity, no conductance) get a unit diagonal: their row reads `ΔT = 0`.
    fn refactorize(&mut self) -> Result<(), HeatError> {
        let dt = self.params.dt;
        for i in 0..self.diagonal.len() {
            self.diagonal[i] = if self.capacity[i] > 0.0 {
                self.capacity[i] / dt + self.air[i]
            } else {
                1.0
            };
        }
        self.system
            .factorize_with_diagonal(&self.diagonal)
            .map_err(|_| HeatError::NotPositiveDefinite)
    }

    /// The parameters.
    #[must_use]
    pub fn params(&self) -> &HeatParameters {
        &self.params
    }

    /// Time step, s.
    #[must_use]
    pub fn dt(&self) -> f64 {
        self.params.dt
    }

    /// Number of nodes (the mesh's, unused ones included).
    #[must_use]
    pub fn node_count(&self) -> usize {
        self.temperature.len()
    }

    /// Changes the time step and refactorises (no allocation).
    ///
    /// # Errors
    /// [`HeatError::InvalidParameter`] (the body is unchanged).
    pub fn set_dt(&mut self, dt: f64) -> Result<(), HeatError> {
        let params = HeatParameters { dt, ..self.params };
        params.validate()?;
        self.params = params;
        self.refactorize()
    }

    /// Changes the air temperature (°C) and convective coefficient (W/m²/K, 0 insulates) and
    /// refactorises (no allocation).
    ///
    /// # Errors
    /// [`HeatError::InvalidParameter`] (the body is unchanged).
    pub fn set_air(&mut self, temperature: f64, coefficient: f64) -> Result<(), HeatError> {
        let params = HeatParameters {
            air_temperature: temperature,
            air_coefficient: coefficient,
            ..self.params
        };
        params.validate()?;
        self.params = params;
        for (h, a) in self.air.iter_mut().zip(&self.area) {
            *h = coefficient * a;
        }
        self.refactorize()
    }

    /// Heats a point of the surface for the next step: `power` W spread over the triangle's
    /// nodes by the barycentric weights (normalised to sum 1, so exactly `power · Δt` joules
    /// enter). Calls before one step add up.
    ///
    /// # Errors
    /// [`HeatError::NodeOutOfRange`], [`HeatError::NoCapacity`], [`HeatError::InvalidWeights`],
    /// [`HeatError::InvalidParameter`] (`power` not finite or negative). Nothing is applied on
    /// error.
    pub fn heat_point(
        &mut self,
        triangle: [u32; 3],
        weights: [f64; 3],
        power: f64,
    ) -> Result<(), HeatError> {
        for &i in &triangle {
            self.check_node(i)?;
        }
        let sum: f64 = weights.iter().sum();
        if !(weights.iter().all(|w| w.is_finite() && *w >= 0.0) && sum > 0.0 && sum.is_finite()) {
            return Err(HeatError::InvalidWeights { weights });
        }
        check_power(power)?;
        for (&i, w) in triangle.iter().zip(weights) {
            self.source[i as usize] += power * w / sum;
        }
        Ok(())
    }

    /// Heats one node with `power` W for the next step.
    ///
    /// # Errors
    /// As [`HeatBody::heat_point`].
    pub fn heat_node(&mut self, node: u32, power: f64) -> Result<(), HeatError> {
        self.check_node(node)?;
        check_power(power)?;
        self.source[node as usize] += power;
        Ok(())
    }

    /// Drops the heat sources queued for the next step.
    pub fn clear_sources(&mut self) {
        self.source.fill(0.0);
    }

    /// Advances by one time step: `(C/Δt + K + H) ΔT = Q + H (T_air − T) − K T`, `T ← T + ΔT`,
    /// with the queued sources `Q` (then cleared), and marks burns. Allocation-free.
    ///
    /// # Errors
    /// [`HeatError::NonFinite`] if the solve produced a non-finite value (not expected: inputs
    /// are validated); the temperatures and sources are then left as they were.
    pub fn step(&mut self) -> Result<HeatReport, HeatError> {
        let dt = self.params.dt;
        let t_air = self.params.air_temperature;
        // Right-hand side in increment form: solving for ΔT rather than T⁺ keeps a uniform
        // field exactly uniform and the energy balance at round-off of the increment.
        self.system
            .conductance_times(&self.temperature, &mut self.scratch);
        for i in 0..self.scratch.len() {
            self.scratch[i] = if self.capacity[i] > 0.0 {
                self.source[i] + self.air[i] * (t_air - self.temperature[i]) - self.scratch[i]
            } else {
                0.0
            };
        }
        self.system.solve_in_place(&mut self.scratch);
        if let Some(node) = self.scratch.iter().position(|d| !d.is_finite()) {
            return Err(HeatError::NonFinite { node });
        }
        let mut report = HeatReport {
            max_temperature: f64::NEG_INFINITY,
            ..HeatReport::default()
        };
        for i in 0..self.temperature.len() {
            let t = self.temperature[i] + self.scratch[i];
            self.temperature[i] = t;
            report.injected += self.source[i] * dt;
            report.to_air += self.air[i] * (t - t_air) * dt;
            report.max_temperature = report.max_temperature.max(t);
        }
        self.source.fill(0.0);
        report.newly_burned = self.mark_burns();
        Ok(report)
    }

    /// Node temperatures, °C.
    #[must_use]
    pub fn temperatures(&self) -> &[f64] {
        &self.temperature
    }

    /// Sets the whole field (one value per node, °C) and marks the nodes it burns.
    ///
    /// # Errors
    /// [`HeatError::WrongLength`], [`HeatError::InvalidTemperature`]; the field is unchanged.
    pub fn set_temperatures(&mut self, temperatures: &[f64]) -> Result<(), HeatError> {
        if temperatures.len() != self.temperature.len() {
            return Err(HeatError::WrongLength {
                got: temperatures.len(),
                expected: self.temperature.len(),
            });
        }
        if let Some((node, &value)) = temperatures
            .iter()
            .enumerate()
            .find(|(_, &t)| !(t > ABSOLUTE_ZERO && t <= MAX_TEMPERATURE))
        {
            return Err(HeatError::InvalidTemperature { node, value });
        }
        self.temperature.copy_from_slice(temperatures);
        self.mark_burns();
        Ok(())
    }

    /// Takes the state of `old`, the same body before a cut removed tetrahedra from its mesh
    /// (the nodes keep their numbers): temperatures and burns, node by node. A node the cut
    /// left unused keeps its temperature, which no step changes any more. Queued sources are
    /// not carried: they are refilled every round.
    ///
    /// # Errors
    /// [`HeatError::WrongLength`] if `old` has another number of nodes; `self` is unchanged.
    pub fn take_state(&mut self, old: &HeatBody) -> Result<(), HeatError> {
        if old.temperature.len() != self.temperature.len() {
            return Err(HeatError::WrongLength {
                got: old.temperature.len(),
                expected: self.temperature.len(),
            });
        }
        self.temperature.copy_from_slice(&old.temperature);
        self.burned.copy_from_slice(&old.burned);
        self.burned_count = old.burned_count;
        self.stiffness_factor.copy_from_slice(&old.stiffness_factor);
        Ok(())
    }

    /// Back to the initial temperature everywhere, no burns, no queued sources.
    pub fn reset(&mut self) {
        self.temperature.fill(self.params.initial);
        self.source.fill(0.0);
        self.burned.fill(false);
        self.burned_count = 0;
        self.stiffness_factor.fill(1.0);
    }

    /// Per node: burned, i.e. its temperature has exceeded the coagulation temperature at the
    /// end of some step (or in a field set) since the last reset.
    #[must_use]
    pub fn burned(&self) -> &[bool] {
        &self.burned
    }

    /// Number of burned nodes.
    #[must_use]
    pub fn burned_count(&self) -> usize {
        self.burned_count
    }

    /// Per node: the factor a deformation model may multiply the stiffness around the node by,
    /// `burn_stiffening` where burned and 1 elsewhere (for an element, e.g. the mean of its
    /// four nodes' factors).
    #[must_use]
    pub fn stiffness_factors(&self) -> &[f64] {
        &self.stiffness_factor
    }

    /// Lumped heat capacity per node, J/K (0 for nodes no tetrahedron uses).
    #[must_use]
    pub fn capacities(&self) -> &[f64] {
        &self.capacity
    }

    /// Surface area per node (a third of each incident surface triangle), m²; 0 inside.
    #[must_use]
    pub fn surface_areas(&self) -> &[f64] {
        &self.area
    }

    /// Heat content `Σ Cᵢ Tᵢ`, J (relative to 0 °C): what the scheme conserves.
    #[must_use]
    pub fn heat_content(&self) -> f64 {
        self.capacity
            .iter()
            .zip(&self.temperature)
            .map(|(c, t)| c * t)
            .sum()
    }

    /// Hottest node, °C.
    #[must_use]
    pub fn max_temperature(&self) -> f64 {
        self.temperature
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Stored non-zeros of the step matrix (one triangle) and of its Cholesky factor.
    #[must_use]
    pub fn nnz(&self) -> (usize, usize) {
        self.system.nnz()
    }

    pub(crate) fn check_node(&self, node: u32) -> Result<(), HeatError> {
        match self.capacity.get(node as usize) {
            None => Err(HeatError::NodeOutOfRange {
                node,
                nodes: self.capacity.len(),
            }),
            Some(&c) if !(c > 0.0) => Err(HeatError::NoCapacity { node }),
            Some(_) => Ok(()),
        }
    }

    /// The temperatures, for the world's link exchange (which checks its node indices).
    pub(crate) fn temperature_mut(&mut self) -> &mut [f64] {
        &mut self.temperature
    }

    /// Marks nodes above the coagulation temperature; returns how many are new.
    fn mark_burns(&mut self) -> usize {
        let coag = self.params.coagulation;
        let mut new = 0;
        for i in 0..self.temperature.len() {
            if !self.burned[i] && self.temperature[i] > coag {
                self.burned[i] = true;
                self.stiffness_factor[i] = self.params.burn_stiffening;
                new += 1;
            }
        }
        self.burned_count += new;
        new
    }
}

fn check_power(power: f64) -> Result<(), HeatError> {
    if power.is_finite() && power >= 0.0 {
        Ok(())
    } else {
        Err(HeatError::InvalidParameter {
            name: "power",
            value: power,
            expected: "a finite number >= 0 (W)",
        })
    }
}
