//! Several heat bodies and the conduction links between organs that touch: [`HeatWorld`].

use super::body::{HeatBody, HeatError, HeatReport};

/// A thermal contact between a node of one body and a node of another (or of the same body,
/// for self-contact): heat flows at `conductance · (T_a − T_b)` watts from `a` to `b`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Link {
    /// Body of the first node (index into the world's bodies).
    pub body_a: usize,
    /// First node, 0-based in its body's mesh.
    pub node_a: u32,
    /// Body of the second node.
    pub body_b: usize,
    /// Second node.
    pub node_b: u32,
    /// Contact conductance `G`, W/K (>= 0). [`HeatWorld::contact_link`] derives it from a
    /// contact coefficient (W/m²/K) and the nodes' surface areas.
    pub conductance: f64,
}

/// What one [`HeatWorld::step`] did, summed over the bodies.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HeatWorldReport {
    /// Energy injected by heat sources, J.
    pub injected: f64,
    /// Energy given to the air, J.
    pub to_air: f64,
    /// Energy carried across links, J (sum of `|q|` over links).
    pub exchanged: f64,
    /// Hottest node of any body, °C.
    pub max_temperature: f64,
    /// Nodes burned during this step.
    pub newly_burned: usize,
}

/// Heat bodies that step together, and the links between organs that touch. All bodies share
/// one time step. `new` and [`HeatWorld::reserve_links`] allocate; `step` never does, and
/// `set_links` does not while the link capacity suffices.
#[derive(Debug, Clone)]
pub struct HeatWorld {
    bodies: Vec<HeatBody>,
    /// Current links, set by `set_links`, read by `step`.
    links: Vec<Link>,
}

impl HeatWorld {
    /// A world of these bodies, which must share one time step.
    ///
    /// # Errors
    /// [`HeatError::TimeStepMismatch`].
    pub fn new(bodies: Vec<HeatBody>) -> Result<HeatWorld, HeatError> {
        if let Some(first) = bodies.first() {
            let dt = first.dt();
            if let Some((body, b)) = bodies.iter().enumerate().find(|(_, b)| b.dt() != dt) {
                return Err(HeatError::TimeStepMismatch {
                    body,
                    dt: b.dt(),
                    expected: dt,
                });
            }
        }
        Ok(HeatWorld {
            bodies,
            links: Vec::new(),
        })
    }

    /// The bodies, in the order given.
    #[must_use]
    pub fn bodies(&self) -> &[HeatBody] {
        &self.bodies
    }

    /// One body, to heat it or read it. Do not change its time step here: use
    /// [`HeatWorld::set_dt`], which keeps the bodies in step.
    pub fn body_mut(&mut self, body: usize) -> Result<&mut HeatBody, HeatError> {
        let bodies = self.bodies.len();
        self.bodies
            .get_mut(body)
            .ok_or(HeatError::BodyOutOfRange { body, bodies })
    }

    /// Sets every body's time step (refactorises each; no allocation).
    ///
    /// # Errors
    /// [`HeatError::InvalidParameter`]; no body is changed.
    pub fn set_dt(&mut self, dt: f64) -> Result<(), HeatError> {
        if let Some(b) = self.bodies.first() {
            super::HeatParameters { dt, ..*b.params() }.validate()?;
        }
        for b in &mut self.bodies {
            b.set_dt(dt)?;
        }
        Ok(())
    }

    /// Replaces body `body` by `new` (the same body after a cut: build it on the cut mesh and
    /// give it the old one's state with [`HeatBody::take_state`]), and drops the links that
    /// reach one of its nodes `new` gives no capacity (nodes the cut left unused). No other
    /// body changes.
    ///
    /// # Errors
    /// [`HeatError::BodyOutOfRange`], [`HeatError::TimeStepMismatch`] (`new`'s step is not the
    /// world's); nothing changes.
    pub fn replace_body(&mut self, body: usize, new: HeatBody) -> Result<(), HeatError> {
        let bodies = self.bodies.len();
        let Some(old) = self.bodies.get(body) else {
            return Err(HeatError::BodyOutOfRange { body, bodies });
        };
        if new.dt() != old.dt() {
            return Err(HeatError::TimeStepMismatch {
                body,
                dt: new.dt(),
                expected: old.dt(),
            });
        }
        let live = |b: usize, n: u32| {
            b != body || new.capacities().get(n as usize).is_some_and(|&c| c > 0.0)
        };
        self.links
            .retain(|l| live(l.body_a, l.node_a) && live(l.body_b, l.node_b));
        self.bodies[body] = new;
        Ok(())
    }

    /// Room for `n` links, so that `set_links` with up to `n` links never allocates.
    pub fn reserve_links(&mut self, n: usize) {
        self.links.reserve(n.saturating_sub(self.links.len()));
    }

    /// Replaces the links (e.g. every step, from collision detection). Allocation-free when
    /// `links.len()` fits the capacity (see [`HeatWorld::reserve_links`]).
    ///
    /// # Errors
    /// [`HeatError::BodyOutOfRange`], [`HeatError::NodeOutOfRange`], [`HeatError::NoCapacity`],
    /// [`HeatError::SelfLink`], [`HeatError::InvalidParameter`] (`conductance`). On error the
    /// links are unchanged.
    pub fn set_links(&mut self, links: &[Link]) -> Result<(), HeatError> {
        for (index, l) in links.iter().enumerate() {
            self.body(l.body_a)?.check_node(l.node_a)?;
            self.body(l.body_b)?.check_node(l.node_b)?;
            if l.body_a == l.body_b && l.node_a == l.node_b {
                return Err(HeatError::SelfLink {
                    index,
                    body: l.body_a,
                    node: l.node_a,
                });
            }
            if !(l.conductance.is_finite() && l.conductance >= 0.0) {
                return Err(HeatError::InvalidParameter {
                    name: "conductance",
                    value: l.conductance,
                    expected: "a finite number >= 0 (W/K)",
                });
            }
        }
        self.links.clear();
        self.links.extend_from_slice(links);
        Ok(())
    }

    /// The current links.
    #[must_use]
    pub fn links(&self) -> &[Link] {
        &self.links
    }

    /// A link between two touching surface nodes with the conductance of a contact patch:
    /// `coefficient` (W/m²/K) times the smaller of the two nodes' surface areas (each node
    /// stands for a third of its incident surface triangles), so a fine mesh against a coarse
    /// one does not count the same patch twice. Not validated until `set_links`.
    ///
    /// # Errors
    /// [`HeatError::BodyOutOfRange`], [`HeatError::NodeOutOfRange`].
    pub fn contact_link(
        &self,
        body_a: usize,
        node_a: u32,
        body_b: usize,
        node_b: u32,
        coefficient: f64,
    ) -> Result<Link, HeatError> {
        let area = |body: usize, node: u32| -> Result<f64, HeatError> {
            let b = self.body(body)?;
            b.surface_areas()
                .get(node as usize)
                .copied()
                .ok_or(HeatError::NodeOutOfRange {
                    node,
                    nodes: b.node_count(),
                })
        };
        let a = area(body_a, node_a)?.min(area(body_b, node_b)?);
        Ok(Link {
            body_a,
            node_a,
            body_b,
            node_b,
            conductance: coefficient * a,
        })
    }

    /// Advances every body by one time step: first the links exchange heat, each by the exact
    /// solution of its two-node equation over `Δt` (see the [module docs](super)), then every
    /// body steps implicitly with its queued sources. Allocation-free.
    ///
    /// # Errors
    /// [`HeatError::NonFinite`] from a body (that body keeps its pre-solve field; the link
    /// exchange of this step stays applied, and energy is still conserved).
    pub fn step(&mut self) -> Result<HeatWorldReport, HeatError> {
        let mut report = HeatWorldReport {
            max_temperature: f64::NEG_INFINITY,
            ..HeatWorldReport::default()
        };
        let Some(dt) = self.bodies.first().map(HeatBody::dt) else {
            return Ok(report);
        };
        // Stage 1: links, in order (operator splitting; each exchange conserves energy and
        // moves both temperatures towards each other without passing the mean).
        for l in &self.links {
            let (ca, cb) = (
                self.bodies[l.body_a].capacities()[l.node_a as usize],
                self.bodies[l.body_b].capacities()[l.node_b as usize],
            );
            let ta = self.bodies[l.body_a].temperatures()[l.node_a as usize];
            let tb = self.bodies[l.body_b].temperatures()[l.node_b as usize];
            let q = exchange(ca, cb, l.conductance, ta - tb, dt);
            self.bodies[l.body_a].temperature_mut()[l.node_a as usize] -= q / ca;
            self.bodies[l.body_b].temperature_mut()[l.node_b as usize] += q / cb;
            report.exchanged += q.abs();
        }
        // Stage 2: diffusion, air and sources inside each body.
        for b in &mut self.bodies {
            let r: HeatReport = b.step()?;
            report.injected += r.injected;
            report.to_air += r.to_air;
            report.max_temperature = report.max_temperature.max(r.max_temperature);
            report.newly_burned += r.newly_burned;
        }
        Ok(report)
    }

    /// Heat content of all bodies, J (relative to 0 °C).
    #[must_use]
    pub fn heat_content(&self) -> f64 {
        self.bodies.iter().map(HeatBody::heat_content).sum()
    }

    /// Back to the initial temperatures, no burns, no sources; the links stay.
    pub fn reset(&mut self) {
        for b in &mut self.bodies {
            b.reset();
        }
    }

    fn body(&self, body: usize) -> Result<&HeatBody, HeatError> {
        self.bodies.get(body).ok_or(HeatError::BodyOutOfRange {
            body,
            bodies: self.bodies.len(),
        })
    }
}

/// Heat (J) that flows from `a` to `b` over `dt` through conductance `g` when their difference
/// is `d = T_a − T_b`, exactly: `d` decays as `exp(−g dt / μ)` with the reduced capacity
/// `μ = C_a C_b / (C_a + C_b)`, and `q = μ (d − d(dt))`. `0 <= q/d <= μ`, so neither node
/// passes the pair's mean temperature, at any `dt`.
pub(crate) fn exchange(ca: f64, cb: f64, g: f64, d: f64, dt: f64) -> f64 {
    let mu = ca * cb / (ca + cb);
    -mu * d * (-g * dt / mu).exp_m1()
}

#[cfg(test)]
mod tests {
    use super::exchange;

    #[test]
    fn two_node_exchange_is_exact_and_bounded() {
        let (ca, cb, g) = (2.0, 3.0, 0.7);
        // Tiny step: q = g d dt (1 − g dt / (2μ) + …), μ = 1.2.
        let q = exchange(ca, cb, g, 10.0, 1e-6);
        let want = 0.7 * 10.0 * 1e-6 * (1.0 - 0.7e-6 / 2.4);
        assert!((q - want).abs() < 1e-18, "{q} vs {want}");
        // Two half steps equal one full step (the exact flow is a semigroup).
        let d0 = 10.0;
        let q1 = exchange(ca, cb, g, d0, 0.5);
        let d1 = d0 - q1 / ca - q1 / cb;
        let q2 = exchange(ca, cb, g, d1, 0.5);
        let q = exchange(ca, cb, g, d0, 1.0);
        assert!((q1 + q2 - q).abs() < 1e-13, "{} vs {q}", q1 + q2);
        // Infinite step: both reach the capacity-weighted mean, no overshoot.
        let q = exchange(ca, cb, g, d0, 1e300);
        let (ta, tb) = (d0 - q / ca, q / cb);
        assert!((ta - tb).abs() < 1e-12);
        assert!((ta - 2.0 * d0 / 5.0).abs() < 1e-12);
    }
}
