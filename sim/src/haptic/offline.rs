//! The god-object over a [`World`] in one process: what the haptic loop does against published
//! frames, for `lopd simulate`, benchmarks and tests; and the same world as the
//! [`ContactSurfaces`] a [`HapticPipeline`](super::HapticPipeline) renders against offline
//! ([`WorldProbe::contact_surfaces`]).

use super::god::{GodObject, GodState};
use super::local::LocalModel;
use super::pipeline::ContactSurfaces;
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
    /// The tool this probe is, in the order the world's rounds are given the tools (0 for
    /// one tool): whose contact patch its god-object rests on.
    tool: usize,
    /// Rebuilt after a cut, and no pipeline told yet ([`ContactSurfaces::topology_changed`]).
    topology_changed: bool,
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
            tool: 0,
            topology_changed: false,
        };
        probe.sync(world);
        probe
    }

    /// The same probe over `world`'s surfaces after a cut changed them (allocates): the
    /// god-object keeps its proxy ([`GodObject::keep_proxy_of`]), the coupling waits for the
    /// next [`tick`](Self::tick).
    pub fn rebuilt(&self, world: &World) -> WorldProbe {
        let mut probe = WorldProbe::new(world, self.god.radius()).for_tool(self.tool);
        probe.god.keep_proxy_of(&self.god);
        probe.topology_changed = true;
        probe
    }

    /// The same probe as tool `tool` of the world's rounds (see [`crate::world::Round::tools`]).
    pub fn for_tool(self, tool: usize) -> WorldProbe {
        WorldProbe { tool, ..self }
    }

    /// The tool this probe is.
    pub fn tool(&self) -> usize {
        self.tool
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
        if let Some((b, p)) = world.contact_proxy(self.tool, self.coupling) {
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
        self.follow(Some(&s));
        s
    }

    /// Keeps the coupling of a god-object state (`None`: the god-object did not move, so it
    /// touches nothing).
    pub fn follow(&mut self, state: Option<&GodState>) {
        self.coupling = Coupling::GodObject(state.and_then(|s| s.anchor).map(|a| {
            let local = a.triangle - self.set.body_triangles(a.body).start;
            (
                a.body,
                ToolAnchor {
                    triangle: local as u32,
                    bary: a.bary,
                    offset: a.offset,
                    grab: state.is_some_and(|s| s.grabbing),
                },
            )
        }));
    }

    /// `world` as the surfaces a haptic pipeline renders against, with `local` the local model
    /// of the patch the world's last round balanced (`World::contact_local`) taken `elapsed`
    /// seconds after that step. After the tick, pass the god-object's state to
    /// [`follow`](Self::follow).
    pub fn contact_surfaces<'a>(
        &'a mut self,
        world: &'a World,
        local: Option<(usize, LocalModel)>,
        elapsed: f64,
    ) -> WorldSurfaces<'a> {
        WorldSurfaces {
            probe: self,
            world,
            local,
            elapsed,
        }
    }
}

/// A world seen by a haptic pipeline ([`WorldProbe::contact_surfaces`]).
pub struct WorldSurfaces<'a> {
    probe: &'a mut WorldProbe,
    world: &'a World,
    local: Option<(usize, LocalModel)>,
    elapsed: f64,
}

impl ContactSurfaces for WorldSurfaces<'_> {
    fn refresh(&mut self, _tip: Option<[f64; 3]>) -> bool {
        self.probe.sync(self.world);
        true
    }

    fn god_object(&mut self) -> Option<(&mut GodObject, &mut SurfaceSet)> {
        Some((&mut self.probe.god, &mut self.probe.set))
    }

    fn local_model(&self) -> Option<(usize, LocalModel, f64)> {
        self.local.map(|(b, m)| (b, m, self.elapsed))
    }

    fn topology_changed(&mut self) -> bool {
        std::mem::take(&mut self.probe.topology_changed)
    }
}
