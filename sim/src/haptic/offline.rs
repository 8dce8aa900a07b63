//! The god-object over a [`World`] in one process: what the haptic loop does against published
//! frames, for `lopd simulate`, benchmarks and tests.

use super::god::{GodObject, GodState};
use super::surface::SurfaceSet;
use crate::model::ToolAnchor;
use crate::world::{Coupling, World};

/// A god-object probing a world's bodies.
#[derive(Debug, Clone)]
pub struct WorldProbe {
    set: SurfaceSet,
    god: GodObject,
    node_offsets: Vec<usize>,
    /// How the last tick's god-object acts on the tissue.
    coupling: Coupling,
}

impl WorldProbe {
    /// A probe with a tip of `radius` m over every body of `world` (allocates).
    pub fn new(world: &World, radius: f64) -> WorldProbe {
        let mut node_offsets = Vec::with_capacity(world.bodies.len());
        let mut n = 0;
        let mut global: Vec<Vec<[u32; 3]>> = Vec::with_capacity(world.bodies.len());
        for b in &world.bodies {
            node_offsets.push(n);
            let off = n as u32;
            global.push(b.mesh.surface.iter().map(|t| t.map(|v| v + off)).collect());
            n += b.mesh.nodes.len();
        }
        let slices: Vec<&[[u32; 3]]> = global.iter().map(|v| v.as_slice()).collect();
        let set = SurfaceSet::new(n, &slices);
        let god = GodObject::new(radius, set.triangles().len());
        let mut probe = WorldProbe {
            set,
            god,
            node_offsets,
            coupling: Coupling::GodObject(None),
        };
        probe.sync(world);
        probe
    }

    /// The surfaces as last synchronised.
    pub fn surfaces(&self) -> &SurfaceSet {
        &self.set
    }

    /// Copies the bodies' current positions in (and carries an anchored proxy along).
    pub fn sync(&mut self, world: &World) {
        let offsets = &self.node_offsets;
        let mut body = 0;
        self.set.set_positions(|i| {
            while body + 1 < offsets.len() && i >= offsets[body + 1] {
                body += 1;
            }
            world.bodies[body].model.positions()[i - offsets[body]]
        });
        self.god.follow_surface(&self.set);
        // A press balanced as a contact patch: the proxy rests where the tissue put it.
        if let Some((b, p)) = world.contact_proxy(self.coupling) {
            self.god.rest_at(&self.set, b, p);
        }
    }

    /// How the last [`tick`](Self::tick)'s god-object acts on the tissue: the anchor to pass to
    /// the next round (or [`World::step_body_coupled`]) so the tissue receives the force the
    /// hand feels. `GodObject(None)` before the first tick and out of contact.
    pub fn coupling(&self) -> Coupling {
        self.coupling
    }

    /// One tick: synchronises with `world`, moves the god-object towards `device` with the grab
    /// button `grab`, and keeps the matching [`coupling`](Self::coupling).
    pub fn tick(&mut self, world: &World, device: [f64; 3], grab: bool) -> GodState {
        self.sync(world);
        let s = self.god.update(&mut self.set, device, grab);
        self.coupling = Coupling::GodObject(s.anchor.map(|a| {
            let local = a.triangle - self.set.body_triangles(a.body).start;
            (
                a.body,
                ToolAnchor {
                    triangle: local as u32,
                    bary: a.bary,
                    offset: a.offset,
                    grab: s.grabbing,
                },
            )
        }));
        s
    }
}
