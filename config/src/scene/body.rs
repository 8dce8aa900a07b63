//! Body spec types of a validated scene: [`BodySpec`] and the parameter tables that have no
//! model type of their own in `lop-sim` (`[body.gc]`, `[body.heat]`). `[body.fem]` and
//! `[body.msd]` validate into `lop-sim`'s [`FemParameters`] and [`MsdParameters`], and the
//! model pin, FEM mode, integrator and fixed-node selectors are `lop-sim`'s types too.

use std::path::PathBuf;

use lop_sim::fem::FemParameters;
use lop_sim::lop::{CageDynamics, CageShape, CageSprings};
use lop_sim::mesh::NodeSelector;
use lop_sim::model::ModelPin;
use lop_sim::msd::MsdParameters;
use serde::Deserialize;

use crate::{mat_vec, rotation_xyz_deg};

/// How much a body matters: decides its precise model when touched (thesis §4.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Importance {
    /// Switches to FEM when touched.
    Important,
    /// Switches to mass-spring when touched.
    #[default]
    Normal,
}

/// One deformable body.
#[derive(Debug, Clone, PartialEq)]
pub struct BodySpec {
    /// Unique in the scene, non-empty.
    pub name: String,
    /// Mesh path, resolved against the scene file's directory: a TetGen base path (`.node`,
    /// `.ele`, optional `.face` and `.bnd` beside it) or a mesh file.
    pub mesh: PathBuf,
    /// The surface to draw, resolved like `mesh` (STL, OBJ, PLY or VTK, in the mesh's units and
    /// frame: the body's scale, rotation and translation apply to it too), or `None` to draw
    /// the mesh's own boundary. Each of its vertices follows the tetrahedron it lies in.
    pub render_surface: Option<PathBuf>,
    /// Which precise model the body gets when touched.
    pub importance: Importance,
    /// Model pin; `Auto` lets the LoP controller decide.
    pub model: ModelPin,
    /// Translation (m), applied after scale and rotation.
    pub translate: [f64; 3],
    /// Rotation, XYZ Euler degrees (see [`crate::rotation_xyz_deg`]).
    pub rotate_deg: [f64; 3],
    /// Uniform scale (> 0), applied first.
    pub scale: f64,
    /// Extra fixed nodes (0-based mesh node indices), in addition to the mesh's `.bnd` file.
    pub fixed_nodes: Vec<u32>,
    /// Fixed-node selectors, `[[body.fix]]`, in scene coordinates (m): every node any of them
    /// picks is fixed too. Each must pick at least one node (checked when the mesh is loaded).
    pub fix: Vec<NodeSelector>,
    /// sRGB colour in 0..=1 for viewers.
    pub color: [f32; 3],
    /// Tool stiffness against this body (units of `[tool] force_law`), or `None` for the
    /// tool's own `stiffness`.
    pub tool_stiffness: Option<f64>,
    /// FEM parameters (present if important or pinned to FEM).
    pub fem: Option<FemParameters>,
    /// Mass-spring parameters (present unless pinned to FEM).
    pub msd: Option<MsdParameters>,
    /// Green-coordinates cage parameters (present if pinned to GC).
    pub gc: Option<GcParams>,
    /// Thermal parameters, `[body.heat]` (every body has them; defaults: liver-like tissue).
    pub heat: HeatParams,
    /// Whether a cautery's cut button cuts this body (`cut`, default false; refused on a body
    /// pinned to its cage, `model = "gc"`, which cannot represent a cut).
    pub cut: bool,
}

impl BodySpec {
    /// Places a mesh node into the scene: `R(rotate_deg) · (scale · p) + translate`.
    pub fn transform_point(&self, p: [f64; 3]) -> [f64; 3] {
        let r = mat_vec(
            &rotation_xyz_deg(self.rotate_deg),
            [p[0] * self.scale, p[1] * self.scale, p[2] * self.scale],
        );
        [
            r[0] + self.translate[0],
            r[1] + self.translate[1],
            r[2] + self.translate[2],
        ]
    }
}

/// Green-coordinates cage parameters, `[body.gc]` (thesis §4.3), in `lop-sim`'s types.
#[derive(Debug, Clone, PartialEq)]
pub struct GcParams {
    /// Cage shape (`cage`, with `subdivisions` for a subdivided box).
    pub shape: CageShape,
    /// Gap between the body's bounding box and the cage, m (> 0); `None`: 5 % of the body's
    /// smallest extent.
    pub padding: Option<f64>,
    /// What moves the cage (`dynamics`; a mass-spring cage carries its `stiffness`, `density`
    /// and `damping`).
    pub dynamics: CageDynamics,
    /// The mass-spring cage's `stiffness`, `density` and `damping` when the table gives them,
    /// whatever `dynamics` is: the bench compares the thesis' cage with them.
    pub springs: Option<CageSprings>,
    /// Time step, s (0 < dt <= 1); `None`: the body's precise model's.
    pub dt: Option<f64>,
}

impl Default for GcParams {
    fn default() -> Self {
        GcParams {
            shape: CageShape::Fitted,
            padding: None,
            dynamics: CageDynamics::Projected,
            springs: None,
            dt: None,
        }
    }
}

/// Thermal parameters of one body, `[body.heat]`. The defaults are liver-like soft tissue
/// (typical literature values, e.g. the IT'IS Foundation tissue database).
#[derive(Debug, Clone, PartialEq)]
pub struct HeatParams {
    /// Thermal conductivity, W/m/K (> 0).
    pub conductivity: f64,
    /// Specific heat capacity, J/kg/K (> 0).
    pub specific_heat: f64,
    /// Density for the heat capacity, kg/m³ (> 0); independent of the deformation models'
    /// densities, which are tuned for dynamics.
    pub density: f64,
    /// Initial (body) temperature, °C.
    pub initial: f64,
    /// Coagulation temperature, °C (> `initial`): hotter tissue is burned.
    pub coagulation: f64,
    /// Stiffness factor of burned tissue (> 0); 1 = burns do not change stiffness.
    pub burn_stiffening: f64,
}

impl Default for HeatParams {
    fn default() -> Self {
        HeatParams {
            conductivity: 0.52,
            specific_heat: 3540.0,
            density: 1060.0,
            initial: 37.0,
            coagulation: 60.0,
            burn_stiffening: 1.0,
        }
    }
}
