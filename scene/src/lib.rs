//! `lop-scene`: a validated scene file turned into what runs it — the [`World`] (every body's
//! mesh placed, its models and levels-of-precision controller, organ collision, the heat model),
//! the static [`Topology`] the frames refer to, and each body's one tool law ([`ToolLaws`]:
//! scene values, the body's `tool_stiffness`, the device's clamps).
//!
//! The haptic loop, the deformation process, `lopd simulate` and every benchmark build their
//! scene here, so they see the same bodies in the same order and the tissue receives the same
//! spring the hand feels. The haptic pipeline's settings come from here too
//! ([`pipeline_settings`]), and so does the one offline path: the rounds both `lopd deform` and
//! `lopd simulate` run ([`Rounds`]), the [`OfflineSession`] every offline run and benchmark
//! steps, and the closed loop with a simulated hand on each tool ([`closed_loop`]).

use anyhow::{bail, Context, Result};
use lop_config::{BodySpec, Scene, ToolSpec};
use lop_sim::contact::{ForceLaw, ToolSphere};
use lop_sim::fem::{Fem, RefactorPolicy};
use lop_sim::lop::{CageModel, GcParameters, LopPolicy, PrecisionController};
pub use lop_sim::mesh::smallest_extent;
use lop_sim::mesh::{read_surface, Embedding, TetMesh};
use lop_sim::model::{Model, ModelPin};
use lop_sim::msd::MassSpring;
use lop_sim::world::World;

pub mod closed_loop;
mod haptic;
mod place;
mod rounds;
pub mod session;
pub use haptic::{pipeline_settings, tool_pipeline_settings};
pub use place::{place_bodies, place_body};
pub use rounds::{Rounds, TickTool, MAX_CATCH_UP};
pub use session::{OfflineSession, ToolSource};

/// A loaded scene: the world and its topology.
pub struct LoadedScene {
    /// The validated scene description.
    pub scene: Scene,
    /// The bodies, ready to step, with collision and heat as the scene sets them.
    pub world: World,
    /// Which nodes, triangles and tetrahedra of a frame belong to which body.
    pub topology: Topology,
}

/// One body's place in the scene-wide node, triangle and tetrahedron lists.
#[derive(Debug, Clone, PartialEq)]
pub struct BodyTopology {
    /// Name from the scene.
    pub name: String,
    /// First node of the body in a frame.
    pub node_offset: usize,
    /// Its nodes.
    pub node_count: usize,
    /// First surface triangle of the body.
    pub triangle_offset: usize,
    /// Its surface triangles.
    pub triangle_count: usize,
    /// First tetrahedron of the body.
    pub tet_offset: usize,
    /// Its tetrahedra.
    pub tet_count: usize,
    /// Display colour, linear RGB.
    pub color: [f32; 3],
    /// Marked important in the scene (runs FEM when touched).
    pub important: bool,
    /// First vertex of the body's render surface in the scene-wide render vertex list.
    pub render_vertex_offset: usize,
    /// Its render vertices (0: the body has no render surface; draw its surface triangles).
    pub render_vertex_count: usize,
    /// First triangle of the body's render surface.
    pub render_triangle_offset: usize,
    /// Its render triangles.
    pub render_triangle_count: usize,
}

/// The static topology of a scene: fixed for a load, published once.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Topology {
    /// Every body, in scene order.
    pub bodies: Vec<BodyTopology>,
    /// Nodes of all bodies.
    pub node_count: usize,
    /// Surface triangles of all bodies.
    pub triangle_count: usize,
    /// Tetrahedra of all bodies.
    pub tet_count: usize,
    /// Render vertices of all bodies.
    pub render_vertex_count: usize,
    /// Render triangles of all bodies.
    pub render_triangle_count: usize,
    /// Triangles (3 indices each) then tetrahedra (4 each), global node indices; then the
    /// render triangles (3 global render vertex indices each); then, per render vertex, the
    /// four global nodes it follows and its four weights as `f32` bits ([`f32::to_bits`]).
    pub indices: Vec<u32>,
}

/// `u32`s per render vertex in [`Topology::indices`]: four nodes, four weights.
pub const RENDER_VERTEX_WORDS: usize = 8;

/// A body's render surface, placed in the scene and embedded in its placed mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderSurface {
    /// Triangles over the surface's own vertices, outward as the file winds them.
    pub triangles: Vec<[u32; 3]>,
    /// Where each vertex sits in the body's mesh.
    pub embedding: Embedding,
}

/// Reads a body's `render_surface`, places it like the body's mesh and embeds it in `mesh`
/// (the placed mesh), or `None` when the body has none.
///
/// # Errors
/// The file cannot be read as a surface, or a vertex lies too far outside the mesh; both name
/// the scene, the body and the file.
pub fn render_surface(
    scene: &Scene,
    index: usize,
    mesh: &TetMesh,
) -> Result<Option<RenderSurface>> {
    let spec = &scene.bodies[index];
    let Some(path) = &spec.render_surface else {
        return Ok(None);
    };
    let what = || {
        format!(
            "{}: body {:?}: render_surface {}",
            scene.path.display(),
            spec.name,
            path.display()
        )
    };
    let surface = read_surface(path).with_context(what)?;
    if surface.triangles.is_empty() {
        bail!("{}: the file holds no triangles", what());
    }
    let placed: Vec<[f64; 3]> = surface
        .vertices
        .iter()
        .map(|&p| spec.transform_point(p))
        .collect();
    let embedding = Embedding::new(mesh, &placed).with_context(what)?;
    Ok(Some(RenderSurface {
        triangles: surface.triangles,
        embedding,
    }))
}

impl Topology {
    /// Node offset of each body in a frame.
    pub fn node_offsets(&self) -> Vec<usize> {
        self.bodies.iter().map(|b| b.node_offset).collect()
    }

    /// The topology of `world` after cuts changed some of its bodies' meshes (`lop_sim::cut`),
    /// `self` the topology before: the same bodies, nodes and node offsets, each body's surface
    /// triangles and tetrahedra as its mesh has them now. A body that was never cut (epoch 0)
    /// keeps its render surface; a cut one is drawn by its own surface from then on (a render
    /// surface embedded in the uncut mesh would cover the wound).
    ///
    /// # Panics
    /// `world` does not have `self`'s bodies and nodes (another scene's world).
    pub fn after_cuts(&self, world: &lop_sim::world::World) -> Topology {
        assert_eq!(world.bodies.len(), self.bodies.len(), "the same bodies");
        let mut triangles: Vec<u32> = Vec::new();
        let mut tets: Vec<u32> = Vec::new();
        let mut render_triangles: Vec<u32> = Vec::new();
        let mut render_vertices: Vec<u32> = Vec::new();
        let tet_end = 3 * self.triangle_count + 4 * self.tet_count;
        let render_tri_end = tet_end + 3 * self.render_triangle_count;
        let mut bodies = Vec::with_capacity(self.bodies.len());
        for (old, b) in self.bodies.iter().zip(&world.bodies) {
            assert_eq!(b.mesh.nodes.len(), old.node_count, "the same nodes");
            let off = old.node_offset as u32;
            let mut bt = BodyTopology {
                triangle_offset: triangles.len() / 3,
                triangle_count: b.mesh.surface.len(),
                tet_offset: tets.len() / 4,
                tet_count: b.mesh.tets.len(),
                render_vertex_offset: render_vertices.len() / RENDER_VERTEX_WORDS,
                render_vertex_count: 0,
                render_triangle_offset: render_triangles.len() / 3,
                render_triangle_count: 0,
                ..old.clone()
            };
            triangles.extend(b.mesh.surface.iter().flatten().map(|&k| k + off));
            tets.extend(b.mesh.tets.iter().flatten().map(|&k| k + off));
            if b.epoch == 0 && old.render_triangle_count > 0 {
                // Its render part, moved to the new offsets.
                let voff =
                    (bt.render_vertex_offset as u32).wrapping_sub(old.render_vertex_offset as u32);
                let t0 = tet_end + 3 * old.render_triangle_offset;
                render_triangles.extend(
                    self.indices[t0..t0 + 3 * old.render_triangle_count]
                        .iter()
                        .map(|&k| k.wrapping_add(voff)),
                );
                let v0 = render_tri_end + RENDER_VERTEX_WORDS * old.render_vertex_offset;
                render_vertices.extend_from_slice(
                    &self.indices[v0..v0 + RENDER_VERTEX_WORDS * old.render_vertex_count],
                );
                bt.render_vertex_count = old.render_vertex_count;
                bt.render_triangle_count = old.render_triangle_count;
            }
            bodies.push(bt);
        }
        let mut topology = Topology {
            bodies,
            node_count: self.node_count,
            triangle_count: triangles.len() / 3,
            tet_count: tets.len() / 4,
            render_vertex_count: render_vertices.len() / RENDER_VERTEX_WORDS,
            render_triangle_count: render_triangles.len() / 3,
            indices: triangles,
        };
        topology.indices.extend(tets);
        topology.indices.extend(render_triangles);
        topology.indices.extend(render_vertices);
        topology
    }
}

/// What the device can render, for clamping the tool law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceClamp {
    /// Largest stiffness the device renders at the stylus, N/mm (`∞`, 0 or not finite: none).
    pub max_stiffness_n_per_mm: f64,
}

impl DeviceClamp {
    /// No clamp (no device, or one without a stiffness limit).
    pub const NONE: DeviceClamp = DeviceClamp {
        max_stiffness_n_per_mm: f64::INFINITY,
    };
}

/// The tool law of a scene against each body: derived once, from the scene's `[tool]`, each
/// body's `tool_stiffness` and the device's clamp, and used by whoever renders or receives the
/// tool's force (the haptic loop, the deformation process, `lopd simulate`, the benchmarks).
///
/// The device renders at most `max_stiffness_n_per_mm` at the stylus; a scene spring `k` (N/m)
/// is felt as `k · 1e-3 · scale` N/mm there (the workspace scales motion, not force). A linear
/// law stiffer than that is clamped to it. The quadratic law's stiffness grows with depth: it is
/// not clamped (the haptic process warns at start).
#[derive(Debug, Clone, PartialEq)]
pub struct ToolLaws {
    /// The scene's tool (its own stiffness, clamped), centred at the origin.
    pub tool: ToolSphere,
    /// The law against each body, in scene order (centre at the origin).
    pub bodies: Vec<ToolSphere>,
    /// Damping on the penetration speed, N·s/m.
    pub damping: f64,
    /// Cautery power, W.
    pub heat_power: f64,
    /// Cautery power in cut mode, W.
    pub cut_power: f64,
}

impl ToolLaws {
    /// One `law` against each of `bodies` bodies, no damping, no cautery: a world built by
    /// hand (the benchmarks' blocks).
    pub fn uniform(law: ToolSphere, bodies: usize) -> ToolLaws {
        ToolLaws {
            tool: law,
            bodies: vec![law; bodies],
            damping: 0.0,
            heat_power: 0.0,
            cut_power: 0.0,
        }
    }

    /// The laws of `scene`'s first tool on a device that renders at most `clamp`.
    pub fn new(scene: &Scene, clamp: DeviceClamp) -> ToolLaws {
        ToolLaws::of_tool(scene, 0, clamp)
    }

    /// The laws of `scene`'s tool `tool` (the first for an index past the last) on a device
    /// that renders at most `clamp`. A body's `tool_stiffness` replaces every tool's own
    /// stiffness against it.
    pub fn of_tool(scene: &Scene, tool: usize, clamp: DeviceClamp) -> ToolLaws {
        let spec = scene.tools.get(tool).unwrap_or(scene.tool());
        let m = clamp.max_stiffness_n_per_mm;
        let k_max = if m.is_finite() && m > 0.0 {
            m / (1e-3 * spec.workspace.scale)
        } else {
            f64::INFINITY
        };
        let clamp_k = |k: f64| match spec.force_law {
            ForceLaw::Linear => k.min(k_max),
            ForceLaw::Quadratic => k,
        };
        let law = |k: f64| ToolSphere {
            stiffness: clamp_k(k),
            ..tool_sphere(spec, [0.0; 3])
        };
        ToolLaws {
            tool: law(spec.stiffness),
            bodies: scene
                .bodies
                .iter()
                .map(|b| law(b.tool_stiffness.unwrap_or(spec.stiffness)))
                .collect(),
            damping: spec.damping,
            heat_power: spec.heat_power,
            cut_power: spec.cut_power,
        }
    }

    /// Stiffness against body `body` (the scene tool's for an unknown body).
    pub fn stiffness(&self, body: usize) -> f64 {
        self.bodies.get(body).unwrap_or(&self.tool).stiffness
    }
}

/// The tool sphere of a scene at `center`, with the scene's own stiffness (unclamped).
pub fn tool_sphere(tool: &ToolSpec, center: [f64; 3]) -> ToolSphere {
    ToolSphere {
        center,
        radius: tool.radius,
        stiffness: tool.stiffness,
        law: tool.force_law,
    }
}

/// The precise model of a body: FEM when it is pinned to FEM, or is important and not pinned
/// to mass-spring; mass-spring otherwise.
pub fn precise_model(scene: &Scene, spec: &BodySpec, mesh: &TetMesh) -> Result<Model> {
    let wants_fem = match spec.model {
        ModelPin::Fem => true,
        ModelPin::Auto | ModelPin::Gc => spec.importance == lop_config::Importance::Important,
        ModelPin::Msd => false,
    };
    if let (true, Some(params)) = (wants_fem, spec.fem) {
        let mut fem = Fem::new(mesh, params)
            .with_context(|| format!("{}: body {:?}: FEM", scene.path.display(), spec.name))?;
        fem.set_refactor_policy(refactor_policy(scene, fem.dt(), None));
        return Ok(Model::Fem(fem));
    }
    let params = spec.msd.with_context(|| {
        format!(
            "{}: body {:?} has no [body.msd] parameters; it needs them to run mass-spring",
            scene.path.display(),
            spec.name
        )
    })?;
    Ok(Model::MassSpring(MassSpring::new(mesh, params)))
}

/// Whether a model of step `dt` runs at the scene's haptic rate or faster: the body is then
/// on the real-time path of the hand whenever the tool touches it, and a corotational FEM body
/// refreshes its lagged factor only when CG needs it ([`RefactorPolicy::RealTime`]: no
/// refactorisation spikes), instead of by amortized cost.
pub fn haptic_rate(scene: &Scene, dt: f64) -> bool {
    dt * scene.rates.haptic_hz <= 1.0 + 1e-9
}

/// A body refreshes its lagged factor by amortized cost at a period longer than the haptic
/// one only when a factorisation costs at most this many periods ([`refactor_policy`]): the
/// step that factorises then costs at most about two periods. With 2 (a step of three
/// periods, which the deformation round's catch-up of three periods would absorb on paper)
/// `lop-bench organs --sizes 5000,10000 --surfaces liver,kidney --threads 1` still gave step
/// p99 13.8 ms (kidney-5000 at 5 ms), 25.4 ms (liver-10000 at 10 ms) and 38.8 ms with a
/// real-time factor of 0.53 (kidney-10000 at 10 ms): the factor timed at rest at load is
/// cheaper than live, and the spikes come every few dozen steps.
pub const FACTOR_SPIKE_PERIODS: f64 = 1.0;

/// The refactor policy of a corotational FEM body of `scene` stepping at period `dt` (s),
/// whose factorisation costs `factor_cost` (s) on this machine when known:
/// [`RefactorPolicy::RealTime`] at the haptic rate (no refactorisation spikes on the hand's
/// path; the mass dominates the system, so the lagged factor keeps CG at a few iterations)
/// and where a factorisation costs more than [`FACTOR_SPIKE_PERIODS`] periods (a spike the
/// body would not catch up); else [`RefactorPolicy::Amortized`] (least work). The scene's
/// loader chooses by the configured period alone; the deformation process chooses again, with
/// the factor timed at load, whenever a body's pace changes its period (`lopd deform`'s pace).
pub fn refactor_policy(scene: &Scene, dt: f64, factor_cost: Option<f64>) -> RefactorPolicy {
    let spike = factor_cost.is_some_and(|f| f > FACTOR_SPIKE_PERIODS * dt);
    if haptic_rate(scene, dt) || spike {
        RefactorPolicy::RealTime
    } else {
        RefactorPolicy::Amortized
    }
}

/// Padding of a cage when the scene gives none: 5 % of the body's smallest extent (the cage
/// must not touch a node, and a snug cage follows the body best).
pub const DEFAULT_CAGE_PADDING: f64 = 0.05;

/// The GC parameters of a body (`[body.gc]`, or the defaults), for a precise model of step
/// `precise_dt`.
pub fn gc_parameters(spec: &BodySpec, mesh: &TetMesh, precise_dt: f64) -> GcParameters {
    let gc = spec.gc.clone().unwrap_or_default();
    let padding = gc
        .padding
        .unwrap_or_else(|| DEFAULT_CAGE_PADDING * smallest_extent(&mesh.nodes));
    GcParameters {
        shape: gc.shape,
        padding,
        dynamics: gc.dynamics,
        dt: gc.dt.unwrap_or(precise_dt),
    }
}

/// The controller policy of a scene.
pub fn lop_policy(scene: &Scene) -> LopPolicy {
    LopPolicy {
        rest_speed: scene.lop.rest_speed,
        hold: scene.lop.hold,
        blend: scene.lop.blend,
        start: scene.lop.start,
    }
}

/// A body's models: the one to run now and, for `model = "auto"`, the levels-of-precision
/// controller holding the other. Pinned bodies get no controller.
pub fn body_models(
    scene: &Scene,
    spec: &BodySpec,
    mesh: &TetMesh,
) -> Result<(Model, Option<PrecisionController>)> {
    let precise = precise_model(scene, spec, mesh)?;
    if matches!(spec.model, ModelPin::Msd | ModelPin::Fem) {
        return Ok((precise, None));
    }
    let params = gc_parameters(spec, mesh, precise.dt());
    let gc = CageModel::from_precise_under(mesh, params, &precise, scene.gravity).with_context(
        || {
            format!(
                "{}: body {:?}: Green-coordinates cage",
                scene.path.display(),
                spec.name
            )
        },
    )?;
    if spec.model == ModelPin::Gc {
        return Ok((Model::Gc(Box::new(gc)), None));
    }
    let (active, lop) = PrecisionController::new(precise, gc, lop_policy(scene));
    Ok((active, Some(lop)))
}

/// Loads every body's mesh, places it, builds its models and controller, and attaches organ
/// collision and the heat model as the scene sets them, and each grasper's jaws
/// ([`lop_sim::World::set_grip`]).
pub fn load(scene: Scene) -> Result<LoadedScene> {
    let mut world = World::new(scene.gravity);
    let mut topology = Topology::default();
    let mut triangles: Vec<u32> = Vec::new();
    let mut tets: Vec<u32> = Vec::new();
    let mut render_triangles: Vec<u32> = Vec::new();
    let mut render_vertices: Vec<u32> = Vec::new();
    let mut node_offset = 0usize;
    for (index, spec) in scene.bodies.iter().enumerate() {
        let mesh = place_body(&scene, index)?;
        let render = render_surface(&scene, index, &mesh)?;
        let (model, lop) = body_models(&scene, spec, &mesh)?;
        let render_vertex_offset = render_vertices.len() / RENDER_VERTEX_WORDS;
        let render_triangle_offset = render_triangles.len() / 3;
        if let Some(r) = &render {
            let (off, voff) = (node_offset as u32, render_vertex_offset as u32);
            render_triangles.extend(r.triangles.iter().flatten().map(|&k| k + voff));
            for (n, w) in r.embedding.nodes.iter().zip(&r.embedding.weights) {
                render_vertices.extend(n.iter().map(|&k| k + off));
                render_vertices.extend(w.iter().map(|&x| (x as f32).to_bits()));
            }
        }
        topology.bodies.push(BodyTopology {
            name: spec.name.clone(),
            node_offset,
            node_count: mesh.nodes.len(),
            triangle_offset: triangles.len() / 3,
            triangle_count: mesh.surface.len(),
            tet_offset: tets.len() / 4,
            tet_count: mesh.tets.len(),
            color: spec.color,
            important: spec.importance == lop_config::Importance::Important,
            render_vertex_offset,
            render_vertex_count: render.as_ref().map_or(0, |r| r.embedding.len()),
            render_triangle_offset,
            render_triangle_count: render.as_ref().map_or(0, |r| r.triangles.len()),
        });
        let off = node_offset as u32;
        triangles.extend(mesh.surface.iter().flatten().map(|&k| k + off));
        tets.extend(mesh.tets.iter().flatten().map(|&k| k + off));
        node_offset += mesh.nodes.len();
        match lop {
            Some(lop) => world.add_lop_body(&spec.name, mesh, model, lop),
            None => world.add_model(&spec.name, mesh, model),
        };
    }
    if scene.collision.enabled {
        world.enable_collisions(
            lop_sim::collide::CollisionParams {
                stiffness: scene.collision.stiffness,
            },
            scene.collision.skin,
            scene.collision.depth_limit,
        );
        world.set_collision_interval(scene.collision.interval);
    }
    let heat = heat_world(&scene, &world)?;
    world.set_heat(heat);
    if scene.bodies.iter().any(|b| b.cut) {
        world.set_cutting(Some(lop_sim::cut::CutParams {
            vaporization: scene.cut.vaporization,
            delay_steps: scene.cut.delay_steps,
            bodies: scene.bodies.iter().map(|b| b.cut).collect(),
        }));
    }
    // A grasper's jaws hold a footprint of the surface; every other tool a point.
    for (t, tool) in scene.tools.iter().enumerate() {
        if let Some(radius) = tool.kind.jaw_radius() {
            world.set_grip(t, lop_sim::grasp::Grip::Jaws { radius });
        }
    }
    topology.node_count = node_offset;
    topology.triangle_count = triangles.len() / 3;
    topology.tet_count = tets.len() / 4;
    topology.render_vertex_count = render_vertices.len() / RENDER_VERTEX_WORDS;
    topology.render_triangle_count = render_triangles.len() / 3;
    topology.indices = triangles;
    topology.indices.extend(tets);
    topology.indices.extend(render_triangles);
    topology.indices.extend(render_vertices);
    Ok(LoadedScene {
        scene,
        world,
        topology,
    })
}

/// Surface nodes of two bodies closer than this at rest are linked for heat conduction, m.
pub const HEAT_LINK_DISTANCE: f64 = 0.002;
/// Heat time step when the scene does not set `[heat] dt`, s.
pub const HEAT_DT_DEFAULT: f64 = 0.01;

/// The scene's heat model: one body per scene body (its `[body.heat]` and the scene's
/// `[heat]`), linked where two organs touch at rest (surface nodes within
/// [`HEAT_LINK_DISTANCE`], conductance from `[heat] contact_conductance`). Allocates; built once.
pub fn heat_world(scene: &Scene, world: &World) -> Result<lop_sim::heat::HeatWorld> {
    use lop_sim::heat::{HeatBody, HeatParameters, HeatWorld};
    let dt = scene.heat.dt.unwrap_or(HEAT_DT_DEFAULT);
    let mut bodies = Vec::with_capacity(world.bodies.len());
    for (spec, body) in scene.bodies.iter().zip(&world.bodies) {
        let h = &spec.heat;
        let params = HeatParameters {
            conductivity: h.conductivity,
            specific_heat: h.specific_heat,
            density: h.density,
            initial: h.initial,
            coagulation: h.coagulation,
            burn_stiffening: h.burn_stiffening,
            air_temperature: scene.heat.air_temperature,
            air_coefficient: scene.heat.air_coefficient,
            dt,
        };
        bodies.push(
            HeatBody::new(&body.mesh, params)
                .with_context(|| format!("heat model of body {:?}", spec.name))?,
        );
    }
    let mut heat = HeatWorld::new(bodies).context("heat model")?;
    let mut links = Vec::new();
    if scene.heat.contact_conductance > 0.0 {
        let surface_nodes = |b: &lop_sim::world::Body| {
            let mut v: Vec<u32> = b.mesh.surface.iter().flatten().copied().collect();
            v.sort_unstable();
            v.dedup();
            v
        };
        for a in 0..world.bodies.len() {
            let na = surface_nodes(&world.bodies[a]);
            for b in a + 1..world.bodies.len() {
                let nb = surface_nodes(&world.bodies[b]);
                let (xa, xb) = (&world.bodies[a].mesh.nodes, &world.bodies[b].mesh.nodes);
                for &i in &na {
                    let p = xa[i as usize];
                    let best = nb
                        .iter()
                        .map(|&j| {
                            let q = xb[j as usize];
                            let d2 = (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f64>();
                            (d2, j)
                        })
                        .min_by(|x, y| x.0.total_cmp(&y.0));
                    if let Some((d2, j)) = best {
                        if d2.sqrt() < HEAT_LINK_DISTANCE {
                            links.push(heat.contact_link(
                                a,
                                i,
                                b,
                                j,
                                scene.heat.contact_conductance,
                            )?);
                        }
                    }
                }
            }
        }
    }
    heat.set_links(&links).context("heat links")?;
    Ok(heat)
}
