//! Run-time changes to a world, for the daemon's control service: swap a body's models (new
//! parameters, a pin to one model, a release to the levels-of-precision controller) carrying its
//! motion over, reset a body to rest, retune a controller.
//!
//! Building a model (a FEM factorisation, a cage's projected operators) is the caller's job and
//! may take milliseconds; these functions only swap what was built, so they are cheap and the
//! world stays valid whatever was asked.

use crate::lop::{LopPolicy, PrecisionController};
use crate::model::Model;
use crate::world::World;

impl World {
    /// Replaces body `i`'s model (and controller: `None` pins it to `model`) with freshly built
    /// ones, carrying the current node positions and velocities over so the body does not jump.
    /// Returns the largest nodal distance between the old and the new model's shape after the
    /// hand-over (zero for a precise model; a cage's fit residual otherwise). Out-of-range `i`
    /// is ignored (returns 0).
    pub fn replace_models(
        &mut self,
        i: usize,
        mut model: Model,
        lop: Option<PrecisionController>,
    ) -> f64 {
        let Some(b) = self.bodies.get_mut(i) else {
            return 0.0;
        };
        if model.positions().len() != b.model.positions().len() {
            return 0.0;
        }
        model.set_state(b.model.positions(), b.model.velocities());
        let jump = b
            .model
            .positions()
            .iter()
            .zip(model.positions())
            .map(|(p, q)| {
                let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
            })
            .fold(0.0, f64::max);
        b.model = model;
        b.lop = lop;
        jump
    }

    /// Puts body `i` back to rest with the given (freshly built, at rest) model and controller:
    /// rest shape, zero velocity, no loads, no contact. Its clock and reset count are kept.
    pub fn reset_body(&mut self, i: usize, model: Model, lop: Option<PrecisionController>) {
        let Some(b) = self.bodies.get_mut(i) else {
            return;
        };
        if model.positions().len() != b.model.positions().len() {
            return;
        }
        b.model = model;
        b.lop = lop;
        b.loads.iter_mut().for_each(|f| *f = [0.0; 3]);
        b.forget_contacts();
    }

    /// Holds every body's clock at `time` (a paused simulation): nothing is due, and after a
    /// resume nothing tries to catch up on the paused time.
    pub fn hold_time(&mut self, time: f64) {
        for b in &mut self.bodies {
            b.time = time;
        }
    }
}

impl PrecisionController {
    /// Replaces the switching policy; takes effect at the next step. The body keeps its level.
    pub fn set_policy(&mut self, policy: LopPolicy) {
        self.policy = policy;
    }
}
