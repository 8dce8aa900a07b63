//! Turns a validated scene file into the simulation world and the static topology that the
//! deformation process publishes. Shared by `lopd deform`, `lopd simulate`-style tools and the
//! benchmarks, so every one of them sees the same bodies in the same order.

use anyhow::{Context, Result};
use lop_config::{BodySpec, MassSpec, ModelPin, Scene, ToolSpec};
use lop_ipc::{
    TopologyHeader, CONTRACT_VERSION, IMPORTANCE_IMPORTANT, IMPORTANCE_NORMAL, MAX_BODIES,
};
use lop_sim::contact::{ForceLaw, ToolSphere};
use lop_sim::fem::{Fem, FemMode, FemParameters};
use lop_sim::mesh::{read_mesh, TetMesh};
use lop_sim::model::Model;
use lop_sim::msd::{Integrator, MassSpring, MsdParameters, NodeMass};
use lop_sim::world::World;

/// A loaded scene: the world plus what the wire needs.
pub struct LoadedScene {
    /// The validated scene description.
    pub scene: Scene,
    /// The bodies, ready to step.
    pub world: World,
    /// Topology header (ids filled in by the publisher).
    pub topology: TopologyHeader,
    /// Triangles then tetrahedra, global node indices (the topology payload).
    pub topology_indices: Vec<u32>,
    /// Node offset of each body in a frame.
    pub node_offsets: Vec<usize>,
    /// Scene names of integrators requested but not available yet, for one warning each.
    pub integrator_notes: Vec<String>,
}

/// The tool sphere of a scene at `center`.
pub fn tool_sphere(tool: &ToolSpec, center: [f64; 3]) -> ToolSphere {
    ToolSphere {
        center,
        radius: tool.radius,
        stiffness: tool.stiffness,
        law: match tool.force_law {
            lop_config::ForceLaw::Linear => ForceLaw::Linear,
            lop_config::ForceLaw::Quadratic => ForceLaw::Quadratic,
        },
    }
}

/// The simulation's integrator for a scene's.
pub fn integrator(i: lop_config::Integrator) -> Integrator {
    match i {
        lop_config::Integrator::ExplicitEuler => Integrator::ExplicitEuler,
        lop_config::Integrator::SymplecticEuler => Integrator::SymplecticEuler,
        lop_config::Integrator::Verlet => Integrator::Verlet,
        lop_config::Integrator::Rk4 => Integrator::Rk4,
        lop_config::Integrator::ImplicitEuler => Integrator::ImplicitEuler,
    }
}

/// The model a body runs until the levels-of-precision controller exists: FEM when the body is
/// pinned to FEM, or is important and not pinned to something else; mass-spring otherwise (a
/// body pinned to GC runs mass-spring for now, with a note).
pub fn body_model(
    scene: &Scene,
    spec: &BodySpec,
    mesh: &TetMesh,
    notes: &mut Vec<String>,
) -> Result<Model> {
    let wants_fem = match spec.model {
        ModelPin::Fem => true,
        ModelPin::Auto => spec.importance == lop_config::Importance::Important,
        ModelPin::Msd | ModelPin::Gc => false,
    };
    if spec.model == ModelPin::Gc {
        notes.push(format!(
            "body {:?}: Green-coordinates cages are not available yet; running mass-spring",
            spec.name
        ));
    }
    if let (true, Some(fem)) = (wants_fem, &spec.fem) {
        let params = FemParameters {
            young: fem.young,
            poisson: fem.poisson,
            density: fem.density,
            damping: fem.damping,
            dt: fem.dt,
            mode: match fem.mode {
                lop_config::FemMode::Linear => FemMode::Linear,
                lop_config::FemMode::Corotational => FemMode::Corotational,
            },
        };
        let fem = Fem::new(mesh, params)
            .with_context(|| format!("{}: body {:?}: FEM", scene.path.display(), spec.name))?;
        return Ok(Model::Fem(fem));
    }
    let msd = spec.msd.as_ref().with_context(|| {
        format!(
            "{}: body {:?} has no [body.msd] parameters; it needs them to run mass-spring",
            scene.path.display(),
            spec.name
        )
    })?;
    let params = MsdParameters {
        stiffness: msd.stiffness,
        mass: match msd.mass {
            MassSpec::Density(d) => NodeMass::Density(d),
            MassSpec::NodeMass(m) => NodeMass::PerNode(m),
        },
        damping: msd.damping,
        dt: msd.dt,
        integrator: integrator(msd.integrator),
    };
    Ok(Model::MassSpring(MassSpring::new(mesh, params)))
}

/// Loads every body's mesh, places it, and builds its mass-spring model.
pub fn load(scene: Scene) -> Result<LoadedScene> {
    if scene.bodies.len() > MAX_BODIES {
        anyhow::bail!(
            "scene {} has {} bodies; the frame format holds at most {MAX_BODIES}",
            scene.path.display(),
            scene.bodies.len()
        );
    }
    let mut world = World::new(scene.gravity);
    let mut topology = TopologyHeader {
        contract_version: CONTRACT_VERSION,
        body_count: scene.bodies.len() as u32,
        ..Default::default()
    };
    let mut triangles: Vec<u32> = Vec::new();
    let mut tets: Vec<u32> = Vec::new();
    let mut node_offsets = Vec::new();
    let mut integrator_notes = Vec::new();
    let mut node_offset = 0usize;
    for (i, spec) in scene.bodies.iter().enumerate() {
        let mut mesh = read_mesh(&spec.mesh)
            .with_context(|| format!("body {:?} of scene {}", spec.name, scene.path.display()))?;
        for p in mesh.nodes.iter_mut() {
            *p = spec.transform_point(*p);
        }
        for &f in &spec.fixed_nodes {
            if f as usize >= mesh.nodes.len() {
                anyhow::bail!(
                    "{}: body {:?}: fixed_nodes has {f}, but the mesh has {} nodes",
                    scene.path.display(),
                    spec.name,
                    mesh.nodes.len()
                );
            }
            mesh.fixed.push(f);
        }
        mesh.fixed.sort_unstable();
        mesh.fixed.dedup();
        let model = body_model(&scene, spec, &mesh, &mut integrator_notes)?;
        let bt = &mut topology.bodies[i];
        bt.set_name(&spec.name);
        bt.node_offset = node_offset as u32;
        bt.node_count = mesh.nodes.len() as u32;
        bt.triangle_offset = (triangles.len() / 3) as u32;
        bt.triangle_count = mesh.surface.len() as u32;
        bt.tet_offset = (tets.len() / 4) as u32;
        bt.tet_count = mesh.tets.len() as u32;
        bt.color = spec.color;
        bt.importance = match spec.importance {
            lop_config::Importance::Important => IMPORTANCE_IMPORTANT,
            lop_config::Importance::Normal => IMPORTANCE_NORMAL,
        };
        let off = node_offset as u32;
        triangles.extend(mesh.surface.iter().flatten().map(|&k| k + off));
        tets.extend(mesh.tets.iter().flatten().map(|&k| k + off));
        node_offsets.push(node_offset);
        node_offset += mesh.nodes.len();
        world.add_model(&spec.name, mesh, model);
    }
    topology.node_count = node_offset as u32;
    topology.triangle_count = (triangles.len() / 3) as u32;
    topology.tet_count = (tets.len() / 4) as u32;
    let mut topology_indices = triangles;
    topology_indices.extend(tets);
    Ok(LoadedScene {
        scene,
        world,
        topology,
        topology_indices,
        node_offsets,
        integrator_notes,
    })
}
