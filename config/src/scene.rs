//! Validated scene types and stage two of loading: raw structs → [`Scene`].

use std::collections::HashMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::check::{fmt_f64, fmt_f64s, Check};
use crate::error::ConfigError;
use crate::raw::{
    RawBody, RawBodyHeat, RawCollision, RawDevice, RawFem, RawGc, RawHeat, RawLop, RawMsd,
    RawRates, RawScene, RawTool, RawWorkspace,
};
use crate::source::{KeyPath, Source};
use crate::workspace::{mat_vec, rotation_xyz_deg, WorkspaceMap};

/// A validated scene: what `lopd` simulates and renders.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// `[scene] name`; the file stem when absent.
    pub name: String,
    /// `[scene] description`; empty when absent.
    pub description: String,
    /// The scene file (absolute).
    pub path: PathBuf,
    /// Gravity, m/s², y up.
    pub gravity: [f64; 3],
    /// The bodies, in file order (at least one).
    pub bodies: Vec<BodySpec>,
    /// The tool (god-object) and its force law.
    pub tool: ToolSpec,
    /// Device-to-scene workspace map.
    pub workspace: WorkspaceMap,
    /// Loop rates.
    pub rates: Rates,
    /// Device defaults for this scene.
    pub device: DeviceDefaults,
    /// When bodies switch between their levels of precision.
    pub lop: LopSpec,
    /// Air and contact for the heat model, `[heat]`.
    pub heat: HeatSpec,
    /// Organ-to-organ collision, `[collision]`.
    pub collision: CollisionSpec,
}

impl Scene {
    /// The body called `name`, if any.
    pub fn body(&self, name: &str) -> Option<&BodySpec> {
        self.bodies.iter().find(|b| b.name == name)
    }
}

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

/// Pins a body to one model instead of letting the LoP controller choose.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelPin {
    /// The LoP controller decides: GC at rest, FEM or MSD (by importance) when touched.
    #[default]
    Auto,
    /// Always Green coordinates.
    Gc,
    /// Always mass-spring-damper.
    Msd,
    /// Always FEM.
    Fem,
}

/// Time integrator of the mass-spring model (thesis ch. 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Integrator {
    /// Forward Euler: cheapest, least stable.
    ExplicitEuler,
    /// Semi-implicit (symplectic) Euler: velocity first, then position.
    #[default]
    SymplecticEuler,
    /// Velocity Verlet (the same positions as Störmer–Verlet).
    Verlet,
    /// Classic fourth-order Runge-Kutta.
    Rk4,
    /// Backward Euler: unconditionally stable, numerically damped.
    ImplicitEuler,
}

/// FEM formulation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum FemMode {
    /// Linear elasticity, as in the thesis; inflates under large rotations.
    Linear,
    /// Corotational (stiffness warping): rotation-invariant.
    #[default]
    Corotational,
}

/// Force law of the tool contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ForceLaw {
    /// Thesis eq. 5.2: `F = k d² N`; `stiffness` in N/m².
    Quadratic,
    /// A spring: `F = k d N`; `stiffness` in N/m.
    #[default]
    Linear,
}

/// One deformable body.
#[derive(Debug, Clone, PartialEq)]
pub struct BodySpec {
    /// Unique in the scene, non-empty.
    pub name: String,
    /// Mesh path, resolved against the scene file's directory: a TetGen base path (`.node`,
    /// `.ele`, optional `.face` and `.bnd` beside it) or a mesh file.
    pub mesh: PathBuf,
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
    /// sRGB colour in 0..=1 for viewers.
    pub color: [f32; 3],
    /// Tool stiffness against this body (units of `[tool] force_law`), or `None` for the
    /// tool's own `stiffness`.
    pub tool_stiffness: Option<f64>,
    /// FEM parameters (present if important or pinned to FEM).
    pub fem: Option<FemParams>,
    /// Mass-spring parameters (present unless pinned to FEM).
    pub msd: Option<MsdParams>,
    /// Green-coordinates cage parameters (present if pinned to GC).
    pub gc: Option<GcParams>,
    /// Thermal parameters, `[body.heat]` (every body has them; defaults: liver-like tissue).
    pub heat: HeatParams,
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

/// Linear-tetrahedron FEM parameters (thesis §4.2).
#[derive(Debug, Clone, PartialEq)]
pub struct FemParams {
    /// Young's modulus, Pa (> 0).
    pub young: f64,
    /// Poisson's ratio, 0 <= ν < 0.5.
    pub poisson: f64,
    /// Density, kg/m³ (> 0).
    pub density: f64,
    /// Mass-proportional damping α, 1/s (>= 0): `D = α M`.
    pub damping: f64,
    /// Time step, s (0 < dt <= 1).
    pub dt: f64,
    /// Formulation.
    pub mode: FemMode,
}

/// How node masses of a mass-spring body are given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MassSpec {
    /// Density, kg/m³: node masses lumped from tetrahedron volumes.
    Density(f64),
    /// The same mass for every node, kg.
    NodeMass(f64),
}

/// Mass-spring-damper parameters (thesis §4.1, eq. 4.2).
#[derive(Debug, Clone, PartialEq)]
pub struct MsdParams {
    /// Spring stiffness, N/m (> 0).
    pub stiffness: f64,
    /// Node masses.
    pub mass: MassSpec,
    /// γ of eq. 4.2, N·s/m per node (>= 0).
    pub damping: f64,
    /// Time step, s (0 < dt <= 1).
    pub dt: f64,
    /// Time integrator.
    pub integrator: Integrator,
}

/// Shape of a body's Green-coordinates cage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CageKind {
    /// The padded bounding box cut into roughly cubic cells (each axis gets
    /// `round(extent / smallest extent)` segments): a long body can bend along its length.
    #[default]
    Fitted,
    /// The thesis' cage: the padded bounding box, 8 vertices and 12 triangles.
    Box,
    /// The padded bounding box with every edge cut into `subdivisions` segments.
    SubdividedBox,
}

/// What moves a body's cage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GcDynamics {
    /// The body's precise model (FEM if important, else mass-spring) projected onto the cage,
    /// with the stiffness matched to its compliance: nothing to tune.
    #[default]
    Projected,
    /// The plain Galerkin projection (`GᵀKG`): stiffer than the body, kept for comparison.
    Galerkin,
    /// The thesis' mass-spring cage with the hand-tuned `stiffness`, `density` and `damping`.
    MassSpring,
}

/// Which level of precision bodies start at.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum StartLevel {
    /// The cage (thesis §4.4).
    #[default]
    Gc,
    /// The precise model, handing over to the cage once settled.
    Precise,
}

/// Green-coordinates cage parameters (thesis §4.3, Tables 6.1 and 6.2).
#[derive(Debug, Clone, PartialEq)]
pub struct GcParams {
    /// Cage shape.
    pub cage: CageKind,
    /// Segments per box edge for [`CageKind::SubdividedBox`] (1..=8).
    pub subdivisions: u32,
    /// Gap between the body's bounding box and the cage, m (> 0); `None`: 5 % of the body's
    /// smallest extent.
    pub padding: Option<f64>,
    /// What moves the cage.
    pub dynamics: GcDynamics,
    /// Mass-spring cage: spring stiffness, N/m (> 0). Required for `mass-spring`.
    pub stiffness: Option<f64>,
    /// Mass-spring cage: density, kg/m³ (> 0). Required for `mass-spring`.
    pub density: Option<f64>,
    /// Mass-spring cage: damping, N·s/m per cage vertex (>= 0). Required for `mass-spring`.
    pub damping: Option<f64>,
    /// Time step, s (0 < dt <= 1); `None`: the body's precise model's.
    pub dt: Option<f64>,
}

impl Default for GcParams {
    fn default() -> Self {
        GcParams {
            cage: CageKind::Fitted,
            subdivisions: 2,
            padding: None,
            dynamics: GcDynamics::Projected,
            stiffness: None,
            density: None,
            damping: None,
            dt: None,
        }
    }
}

/// Organ-to-organ collision (thesis §6.3.4.1), `[collision]`: see `lop_sim::collide`.
#[derive(Debug, Clone, PartialEq)]
pub struct CollisionSpec {
    /// Whether bodies push each other.
    pub enabled: bool,
    /// Stiffness of each contact spring, N/m (> 0).
    pub stiffness: f64,
    /// Contact starts this far before the surfaces meet, m (>= 0).
    pub skin: f64,
    /// Vertices deeper than this inside another body are ignored, m (> 0).
    pub depth_limit: f64,
}

impl Default for CollisionSpec {
    fn default() -> Self {
        CollisionSpec {
            enabled: true,
            stiffness: 20.0,
            skin: 0.0005,
            depth_limit: 0.01,
        }
    }
}

/// Scene-level heat settings (thesis §5.3), `[heat]`.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatSpec {
    /// Air temperature, °C.
    pub air_temperature: f64,
    /// Convective coefficient from tissue surfaces to the air, W/m²/K (>= 0; 0 insulates).
    pub air_coefficient: f64,
    /// Contact conductance between touching organs, W/m²/K (>= 0; 0: no heat crosses).
    pub contact_conductance: f64,
    /// Heat time step, s (0 < dt <= 1); `None`: one heat step per deformation step.
    pub dt: Option<f64>,
}

impl Default for HeatSpec {
    fn default() -> Self {
        HeatSpec {
            air_temperature: 22.0,
            air_coefficient: 10.0,
            contact_conductance: 500.0,
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

/// Levels-of-precision switching (thesis §4.4, fig. 4.4), `[lop]`.
#[derive(Debug, Clone, PartialEq)]
pub struct LopSpec {
    /// A precise body counts as settled below this largest nodal speed, m/s (> 0) …
    pub rest_speed: f64,
    /// … held this long without contact before it hands over to its cage, s (>= 0).
    pub hold: f64,
    /// The shape the cage cannot represent fades out over this long after a hand-over, s (>= 0).
    pub blend: f64,
    /// Level every `auto` body starts at.
    pub start: StartLevel,
}

impl Default for LopSpec {
    fn default() -> Self {
        LopSpec {
            rest_speed: 2e-3,
            hold: 0.3,
            blend: 0.2,
            start: StartLevel::Gc,
        }
    }
}

/// The tool: a sphere driven by the device, rendered as a god-object.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolSpec {
    /// Tip radius, m (> 0).
    pub radius: f64,
    /// Force law.
    pub force_law: ForceLaw,
    /// N/m for the linear law, N/m² for the quadratic law (> 0).
    pub stiffness: f64,
    /// Damping on the penetration speed, N·s/m (>= 0).
    pub damping: f64,
    /// Force clamp for this scene, N (> 0).
    pub max_force: f64,
    /// Cautery heating power, W (>= 0).
    pub heat_power: f64,
}

impl Default for ToolSpec {
    fn default() -> Self {
        ToolSpec {
            radius: 0.003,
            force_law: ForceLaw::Linear,
            stiffness: 300.0,
            damping: 0.0,
            max_force: 3.0,
            heat_power: 20.0,
        }
    }
}

/// Loop rates.
#[derive(Debug, Clone, PartialEq)]
pub struct Rates {
    /// Haptic loop rate, Hz (100..=10000).
    pub haptic_hz: f64,
    /// Upper bound on deformation steps per second (> 0).
    pub deform_max_hz: f64,
    /// Upper bound on published frames per second (> 0).
    pub publish_hz: f64,
}

impl Default for Rates {
    fn default() -> Self {
        Rates {
            haptic_hz: 1000.0,
            deform_max_hz: 1000.0,
            publish_hz: 250.0,
        }
    }
}

/// Per-scene device defaults.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DeviceDefaults {
    /// Mock-device script used when the daemon runs with the mock device and no script is given;
    /// resolved against the scene file's directory. Its existence is checked by the driver that
    /// reads it, not here, so a scene stays loadable on a rig with a real device.
    pub mock_script: Option<PathBuf>,
}

/// Default viewer colours, by body index (sRGB).
const PALETTE: [[f32; 3]; 6] = [
    [0.55, 0.16, 0.13],
    [0.36, 0.52, 0.78],
    [0.42, 0.15, 0.35],
    [0.93, 0.66, 0.60],
    [0.90, 0.78, 0.52],
    [0.40, 0.65, 0.40],
];

/// Reads and validates the scene file at `path`.
pub fn load_scene(path: &Path) -> Result<Scene, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
        file: path.to_path_buf(),
        source,
    })?;
    parse_scene(&text, path)
}

/// Parses and validates scene text. `path` is used only in messages and to resolve relative
/// paths (mesh files, mock script) against its directory; the mesh files must exist.
pub fn parse_scene(text: &str, path: &Path) -> Result<Scene, ConfigError> {
    let src = Source::parse(path, text)?;
    let raw: RawScene = src.deserialize()?;
    validate_scene(&src, raw)
}

fn validate_scene(src: &Source<'_>, raw: RawScene) -> Result<Scene, ConfigError> {
    let abs = std::path::absolute(src.file).unwrap_or_else(|_| src.file.to_path_buf());
    let dir = abs.parent().map(Path::to_path_buf).unwrap_or_default();
    let c = Check { src, body: None };

    let meta = KeyPath::top("scene");
    let name = match raw.scene.name {
        Some(n) => n,
        None => src
            .file
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .filter(|s| !s.trim().is_empty())
            .unwrap_or_else(|| "unnamed".to_owned()),
    };
    check_name(&c, &meta.key("name"), &name, "scene name")?;
    let gravity = c.finite3(
        &meta.key("gravity"),
        raw.scene.gravity.unwrap_or([0.0; 3]),
        "gravity",
    )?;

    let tool = validate_tool(&c, raw.tool)?;
    let workspace = validate_workspace(&c, raw.workspace)?;
    let rates = validate_rates(&c, raw.rates)?;
    let device = validate_device(&c, raw.device, &dir)?;
    let lop = validate_lop(&c, raw.lop)?;
    let heat = validate_heat(&c, raw.heat)?;
    let collision = validate_collision(&c, raw.collision)?;

    if raw.body.is_empty() {
        return Err(c.invalid(
            &KeyPath::top("body"),
            "(none)",
            "a scene needs at least one [[body]] table",
        ));
    }
    let mut seen: HashMap<String, usize> = HashMap::new();
    let mut bodies = Vec::with_capacity(raw.body.len());
    for (i, rb) in raw.body.into_iter().enumerate() {
        let key = KeyPath::top("body").index(i);
        if let Some(first) = seen.get(&rb.name) {
            let c = Check {
                src,
                body: Some(&rb.name),
            };
            return Err(c.invalid(
                &key.key("name"),
                format!("{:?}", rb.name),
                format!("duplicate body name: body[{first}] already has it; names must be unique"),
            ));
        }
        seen.insert(rb.name.clone(), i);
        bodies.push(validate_body(src, &key, i, rb, &dir)?);
    }

    Ok(Scene {
        name,
        description: raw.scene.description.unwrap_or_default(),
        path: abs,
        gravity,
        bodies,
        tool,
        workspace,
        rates,
        device,
        lop,
        heat,
        collision,
    })
}

fn validate_collision(c: &Check<'_, '_>, raw: RawCollision) -> Result<CollisionSpec, ConfigError> {
    let k = KeyPath::top("collision");
    let d = CollisionSpec::default();
    let skin = c.non_negative(
        &k.key("skin"),
        raw.skin.unwrap_or(d.skin),
        "collision skin (m)",
    )?;
    let depth_limit = c.positive(
        &k.key("depth_limit"),
        raw.depth_limit.unwrap_or(d.depth_limit),
        "collision depth limit (m)",
    )?;
    if skin > 0.01 {
        return Err(c.invalid(
            &k.key("skin"),
            skin.to_string(),
            "collision skin (m): at most 0.01 (10 mm); bodies would push each other from afar",
        ));
    }
    Ok(CollisionSpec {
        enabled: raw.enabled.unwrap_or(d.enabled),
        stiffness: c.positive(
            &k.key("stiffness"),
            raw.stiffness.unwrap_or(d.stiffness),
            "collision stiffness (N/m)",
        )?,
        skin,
        depth_limit,
    })
}

fn validate_heat(c: &Check<'_, '_>, raw: RawHeat) -> Result<HeatSpec, ConfigError> {
    let k = KeyPath::top("heat");
    let d = HeatSpec::default();
    Ok(HeatSpec {
        air_temperature: c.temperature(
            &k.key("air_temperature"),
            raw.air_temperature.unwrap_or(d.air_temperature),
            "air temperature",
        )?,
        air_coefficient: c.non_negative(
            &k.key("air_coefficient"),
            raw.air_coefficient.unwrap_or(d.air_coefficient),
            "air heat-transfer coefficient (W/m²/K)",
        )?,
        contact_conductance: c.non_negative(
            &k.key("contact_conductance"),
            raw.contact_conductance.unwrap_or(d.contact_conductance),
            "contact conductance (W/m²/K)",
        )?,
        dt: raw.dt.map(|v| c.time_step(&k.key("dt"), v)).transpose()?,
    })
}

fn validate_body_heat(
    c: &Check<'_, '_>,
    k: &KeyPath,
    raw: RawBodyHeat,
) -> Result<HeatParams, ConfigError> {
    let d = HeatParams::default();
    let initial = c.temperature(
        &k.key("initial"),
        raw.initial.unwrap_or(d.initial),
        "initial temperature",
    )?;
    let coagulation = c.temperature(
        &k.key("coagulation"),
        raw.coagulation.unwrap_or(d.coagulation),
        "coagulation temperature",
    )?;
    // Both are finite here (checked above).
    if coagulation <= initial {
        return Err(c.invalid(
            &k.key("coagulation"),
            fmt_f64(coagulation),
            format!(
                "coagulation temperature must be above the initial temperature ({} °C), or \
                 the whole body starts burned",
                fmt_f64(initial)
            ),
        ));
    }
    Ok(HeatParams {
        conductivity: c.positive(
            &k.key("conductivity"),
            raw.conductivity.unwrap_or(d.conductivity),
            "thermal conductivity (W/m/K)",
        )?,
        specific_heat: c.positive(
            &k.key("specific_heat"),
            raw.specific_heat.unwrap_or(d.specific_heat),
            "specific heat (J/kg/K)",
        )?,
        density: c.positive(
            &k.key("density"),
            raw.density.unwrap_or(d.density),
            "density (kg/m³)",
        )?,
        initial,
        coagulation,
        burn_stiffening: c.positive(
            &k.key("burn_stiffening"),
            raw.burn_stiffening.unwrap_or(d.burn_stiffening),
            "burn_stiffening (stiffness factor of burned tissue)",
        )?,
    })
}

fn validate_lop(c: &Check<'_, '_>, raw: RawLop) -> Result<LopSpec, ConfigError> {
    let k = KeyPath::top("lop");
    let d = LopSpec::default();
    Ok(LopSpec {
        rest_speed: c.positive(
            &k.key("rest_speed"),
            raw.rest_speed.unwrap_or(d.rest_speed),
            "rest speed (m/s)",
        )?,
        hold: c.non_negative(&k.key("hold"), raw.hold.unwrap_or(d.hold), "hold time (s)")?,
        blend: c.non_negative(
            &k.key("blend"),
            raw.blend.unwrap_or(d.blend),
            "blend time (s)",
        )?,
        start: raw.start.unwrap_or(d.start),
    })
}

/// Names: non-empty, not just whitespace, no control characters.
fn check_name(c: &Check<'_, '_>, key: &KeyPath, name: &str, what: &str) -> Result<(), ConfigError> {
    if name.trim().is_empty() {
        return Err(c.invalid(
            key,
            format!("{name:?}"),
            format!("{what} must not be empty"),
        ));
    }
    if name.chars().any(char::is_control) {
        return Err(c.invalid(
            key,
            format!("{name:?}"),
            format!("{what} must not contain control characters"),
        ));
    }
    Ok(())
}

fn validate_tool(c: &Check<'_, '_>, raw: RawTool) -> Result<ToolSpec, ConfigError> {
    let k = KeyPath::top("tool");
    let d = ToolSpec::default();
    let force_law = raw.force_law.unwrap_or(d.force_law);
    let unit = match force_law {
        ForceLaw::Linear => "tool stiffness (N/m, linear law)",
        ForceLaw::Quadratic => "tool stiffness (N/m², quadratic law)",
    };
    Ok(ToolSpec {
        radius: c.positive(
            &k.key("radius"),
            raw.radius.unwrap_or(d.radius),
            "tool radius (m)",
        )?,
        force_law,
        stiffness: c.positive(
            &k.key("stiffness"),
            raw.stiffness.unwrap_or(d.stiffness),
            unit,
        )?,
        damping: c.non_negative(
            &k.key("damping"),
            raw.damping.unwrap_or(d.damping),
            "tool damping (N·s/m)",
        )?,
        max_force: c.positive(
            &k.key("max_force"),
            raw.max_force.unwrap_or(d.max_force),
            "tool max_force (N)",
        )?,
        heat_power: c.non_negative(
            &k.key("heat_power"),
            raw.heat_power.unwrap_or(d.heat_power),
            "tool heat_power (W)",
        )?,
    })
}

fn validate_workspace(c: &Check<'_, '_>, raw: RawWorkspace) -> Result<WorkspaceMap, ConfigError> {
    let k = KeyPath::top("workspace");
    let d = WorkspaceMap::default();
    Ok(WorkspaceMap {
        scale: c.positive(
            &k.key("scale"),
            raw.scale.unwrap_or(d.scale),
            "workspace scale (scene m per device m)",
        )?,
        rotate_deg: c.finite3(
            &k.key("rotate_deg"),
            raw.rotate_deg.unwrap_or(d.rotate_deg),
            "workspace rotate_deg",
        )?,
        offset: c.finite3(
            &k.key("offset"),
            raw.offset.unwrap_or(d.offset),
            "workspace offset (m)",
        )?,
    })
}

fn validate_rates(c: &Check<'_, '_>, raw: RawRates) -> Result<Rates, ConfigError> {
    let k = KeyPath::top("rates");
    let d = Rates::default();
    Ok(Rates {
        haptic_hz: c.within(
            &k.key("haptic_hz"),
            raw.haptic_hz.unwrap_or(d.haptic_hz),
            100.0,
            10_000.0,
            "haptic rate (Hz)",
        )?,
        deform_max_hz: c.positive(
            &k.key("deform_max_hz"),
            raw.deform_max_hz.unwrap_or(d.deform_max_hz),
            "deform_max_hz (steps/s)",
        )?,
        publish_hz: c.positive(
            &k.key("publish_hz"),
            raw.publish_hz.unwrap_or(d.publish_hz),
            "publish_hz (frames/s)",
        )?,
    })
}

fn validate_device(
    c: &Check<'_, '_>,
    raw: RawDevice,
    dir: &Path,
) -> Result<DeviceDefaults, ConfigError> {
    let mock_script = match raw.mock_script {
        None => None,
        Some(s) if s.trim().is_empty() => {
            return Err(c.invalid(
                &KeyPath::top("device").key("mock_script"),
                "\"\"",
                "mock_script must be a path (relative to the scene file) or be left out",
            ));
        }
        Some(s) => Some(dir.join(s)),
    };
    Ok(DeviceDefaults { mock_script })
}

fn validate_body(
    src: &Source<'_>,
    key: &KeyPath,
    index: usize,
    rb: RawBody,
    dir: &Path,
) -> Result<BodySpec, ConfigError> {
    let c = Check {
        src,
        body: Some(&rb.name),
    };
    check_name(&c, &key.key("name"), &rb.name, "body name")?;
    let importance = rb.importance.unwrap_or_default();
    let model = rb.model.unwrap_or_default();

    // Which parameter tables the body's possible models need.
    if rb.fem.is_none() {
        if model == ModelPin::Fem {
            return Err(c.invalid(
                &key.key("fem"),
                "(missing)",
                "model = \"fem\" needs a [body.fem] table",
            ));
        }
        if importance == Importance::Important {
            return Err(c.invalid(
                &key.key("fem"),
                "(missing)",
                "importance = \"important\" needs a [body.fem] table: important bodies switch \
                 to FEM when touched",
            ));
        }
    }
    if rb.msd.is_none() && model != ModelPin::Fem {
        return Err(c.invalid(
            &key.key("msd"),
            "(missing)",
            "every body needs a [body.msd] table unless model = \"fem\": mass-spring is the \
             fallback model of every body",
        ));
    }
    let translate = c.finite3(
        &key.key("translate"),
        rb.translate.unwrap_or([0.0; 3]),
        "translate (m)",
    )?;
    let rotate_deg = c.finite3(
        &key.key("rotate_deg"),
        rb.rotate_deg.unwrap_or([0.0; 3]),
        "rotate_deg",
    )?;
    let scale = c.positive(&key.key("scale"), rb.scale.unwrap_or(1.0), "body scale")?;
    let color = match rb.color {
        None => PALETTE[index % PALETTE.len()],
        Some(col) => {
            if col.iter().all(|x| (0.0..=1.0).contains(x)) {
                col
            } else {
                let as_f64 = col.map(f64::from);
                return Err(c.invalid(
                    &key.key("color"),
                    fmt_f64s(&as_f64),
                    "color must be three sRGB components in 0..=1",
                ));
            }
        }
    };
    let tool_stiffness = rb
        .tool_stiffness
        .map(|k| {
            c.positive(
                &key.key("tool_stiffness"),
                k,
                "tool stiffness against the body",
            )
        })
        .transpose()?;
    let fem = rb
        .fem
        .map(|f| validate_fem(&c, &key.key("fem"), f))
        .transpose()?;
    let msd = rb
        .msd
        .map(|m| validate_msd(&c, &key.key("msd"), m))
        .transpose()?;
    let gc = rb
        .gc
        .map(|g| validate_gc(&c, &key.key("gc"), g))
        .transpose()?;
    let heat = validate_body_heat(&c, &key.key("heat"), rb.heat.unwrap_or_default())?;
    let mesh = resolve_mesh(&c, &key.key("mesh"), &rb.mesh, dir)?;

    Ok(BodySpec {
        name: rb.name.clone(),
        mesh,
        importance,
        model,
        translate,
        rotate_deg,
        scale,
        fixed_nodes: rb.fixed_nodes.unwrap_or_default(),
        color,
        tool_stiffness,
        fem,
        msd,
        gc,
        heat,
    })
}

fn validate_fem(c: &Check<'_, '_>, k: &KeyPath, raw: RawFem) -> Result<FemParams, ConfigError> {
    let poisson_key = k.key("poisson");
    let poisson = raw.poisson;
    if !(poisson.is_finite() && (0.0..0.5).contains(&poisson)) {
        return Err(c.invalid(
            &poisson_key,
            fmt_f64(poisson),
            "Poisson's ratio must be >= 0 and < 0.5 (0.5 is incompressible, which makes the \
             Lamé λ = Eν/((1+ν)(1−2ν)) infinite)",
        ));
    }
    Ok(FemParams {
        young: c.positive(&k.key("young"), raw.young, "Young's modulus (Pa)")?,
        poisson,
        density: c.positive(&k.key("density"), raw.density, "density (kg/m³)")?,
        damping: c.non_negative(
            &k.key("damping"),
            raw.damping,
            "FEM damping α (1/s, D = αM)",
        )?,
        dt: c.time_step(&k.key("dt"), raw.dt)?,
        mode: raw.mode.unwrap_or_default(),
    })
}

fn validate_msd(c: &Check<'_, '_>, k: &KeyPath, raw: RawMsd) -> Result<MsdParams, ConfigError> {
    let stiffness = c.positive(&k.key("stiffness"), raw.stiffness, "spring stiffness (N/m)")?;
    let mass = match (raw.density, raw.node_mass) {
        (Some(d), None) => {
            MassSpec::Density(c.positive(&k.key("density"), d, "density (kg/m³)")?)
        }
        (None, Some(m)) => {
            MassSpec::NodeMass(c.positive(&k.key("node_mass"), m, "node_mass (kg)")?)
        }
        (Some(d), Some(m)) => {
            return Err(c.invalid(
                k,
                format!("{{ density = {}, node_mass = {} }}", fmt_f64(d), fmt_f64(m)),
                "give exactly one of density (kg/m³) or node_mass (kg), not both",
            ));
        }
        (None, None) => {
            return Err(c.invalid(
                k,
                "(neither density nor node_mass)",
                "give exactly one of density (kg/m³) or node_mass (kg)",
            ));
        }
    };
    Ok(MsdParams {
        stiffness,
        mass,
        damping: c.non_negative(
            &k.key("damping"),
            raw.damping,
            "MSD damping γ (N·s/m per node)",
        )?,
        dt: c.time_step(&k.key("dt"), raw.dt)?,
        integrator: raw.integrator.unwrap_or_default(),
    })
}

fn validate_gc(c: &Check<'_, '_>, k: &KeyPath, raw: RawGc) -> Result<GcParams, ConfigError> {
    let dynamics = raw.dynamics.unwrap_or_default();
    let subdivisions = match raw.subdivisions {
        None => 2,
        Some(n) if (1..=8).contains(&n) => n as u32,
        Some(n) => {
            return Err(c.invalid(
                &k.key("subdivisions"),
                n.to_string(),
                "subdivisions must be 1..=8 segments per cage edge (8 gives 386 cage vertices)",
            ))
        }
    };
    let padding = raw
        .padding
        .map(|p| c.positive(&k.key("padding"), p, "cage padding (m)"))
        .transpose()?;
    let need = |key: &str, v: Option<f64>| -> Result<Option<f64>, ConfigError> {
        match (dynamics, v) {
            (GcDynamics::MassSpring, None) => Err(c.invalid(
                &k.key(key),
                "(missing)",
                format!("dynamics = \"mass-spring\" needs the cage's {key}"),
            )),
            _ => Ok(v),
        }
    };
    let stiffness = need("stiffness", raw.stiffness)?
        .map(|v| c.positive(&k.key("stiffness"), v, "GC stiffness (N/m)"))
        .transpose()?;
    let density = need("density", raw.density)?
        .map(|v| c.positive(&k.key("density"), v, "GC density (kg/m³)"))
        .transpose()?;
    let damping = need("damping", raw.damping)?
        .map(|v| c.non_negative(&k.key("damping"), v, "GC damping (N·s/m)"))
        .transpose()?;
    let dt = raw.dt.map(|v| c.time_step(&k.key("dt"), v)).transpose()?;
    Ok(GcParams {
        cage: raw.cage.unwrap_or_default(),
        subdivisions,
        padding,
        dynamics,
        stiffness,
        density,
        damping,
        dt,
    })
}

/// Resolves `given` against `dir` and checks that it names a mesh: either an existing file or a
/// TetGen base path whose `.node` file exists.
fn resolve_mesh(
    c: &Check<'_, '_>,
    key: &KeyPath,
    given: &str,
    dir: &Path,
) -> Result<PathBuf, ConfigError> {
    if given.trim().is_empty() {
        return Err(c.invalid(
            key,
            "\"\"",
            "mesh must be a path (relative to the scene file)",
        ));
    }
    let path = dir.join(given);
    if path.is_file() {
        return Ok(path);
    }
    let mut node = OsString::from(path.as_os_str());
    node.push(".node");
    let node = PathBuf::from(node);
    if node.is_file() {
        return Ok(path);
    }
    Err(ConfigError::MeshNotFound {
        at: Box::new(c.src.locate(key)),
        key: key.to_string(),
        body: c.body.map(str::to_owned),
        given: given.to_owned(),
        tried: vec![path, node],
    })
}
