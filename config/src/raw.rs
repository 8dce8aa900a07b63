//! Raw, unvalidated mirrors of the TOML files. Every struct denies unknown keys; every key that
//! has a default is an `Option` so validation knows whether it was written.

use serde::Deserialize;

use lop_sim::contact::ForceLaw;
use lop_sim::fem::FemMode;
use lop_sim::lop::StartLevel;
use lop_sim::model::ModelPin;
use lop_sim::msd::Integrator;

use crate::scene::Importance;

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawScene {
    /// Another scene file this one starts from (see `Scene`'s loading docs).
    pub base: Option<String>,
    #[serde(default)]
    pub scene: RawSceneMeta,
    /// `None` when the scene has no `[tool]` section (the default tool); one `[tool]` table or
    /// several `[[tool]]` tables.
    pub tool: Option<RawTools>,
    #[serde(default)]
    pub workspace: RawWorkspace,
    #[serde(default)]
    pub rates: RawRates,
    #[serde(default)]
    pub device: RawDevice,
    #[serde(default)]
    pub lop: RawLop,
    #[serde(default)]
    pub heat: RawHeat,
    #[serde(default)]
    pub collision: RawCollision,
    #[serde(default)]
    pub cut: RawCut,
    #[serde(default)]
    pub body: Vec<RawBody>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawHeat {
    pub air_temperature: Option<f64>,
    pub air_coefficient: Option<f64>,
    pub contact_conductance: Option<f64>,
    pub dt: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawCollision {
    pub enabled: Option<bool>,
    pub stiffness: Option<f64>,
    pub skin: Option<f64>,
    pub depth_limit: Option<f64>,
    pub interval: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawCut {
    pub vaporization: Option<f64>,
    pub delay_steps: Option<i64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawLop {
    pub rest_speed: Option<f64>,
    pub hold: Option<f64>,
    pub blend: Option<f64>,
    pub start: Option<StartLevel>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawSceneMeta {
    pub name: Option<String>,
    pub description: Option<String>,
    pub gravity: Option<[f64; 3]>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawTool {
    pub name: Option<String>,
    pub kind: Option<String>,
    pub jaw_radius: Option<f64>,
    pub mock_script: Option<String>,
    pub workspace: Option<RawWorkspace>,
    pub radius: Option<f64>,
    pub force_law: Option<ForceLaw>,
    pub stiffness: Option<f64>,
    pub damping: Option<f64>,
    pub max_force: Option<f64>,
    pub heat_power: Option<f64>,
    pub cut_power: Option<f64>,
}

/// The scene's tools as written: one `[tool]` table, or an array of `[[tool]]` tables.
#[derive(Debug)]
pub(crate) enum RawTools {
    One(Box<RawTool>),
    Many(Vec<RawTool>),
}

impl<'de> Deserialize<'de> for RawTools {
    /// A table is one tool, an array of tables several; each table is read as a [`RawTool`]
    /// (unknown keys refused), an error naming the table's place in the array.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<RawTools, D::Error> {
        use serde::de::Error;
        match toml::Value::deserialize(d)? {
            toml::Value::Array(tables) => tables
                .into_iter()
                .enumerate()
                .map(|(i, t)| {
                    RawTool::deserialize(t).map_err(|e| D::Error::custom(format!("tool[{i}]: {e}")))
                })
                .collect::<Result<Vec<_>, _>>()
                .map(RawTools::Many),
            t @ toml::Value::Table(_) => RawTool::deserialize(t)
                .map(|t| RawTools::One(Box::new(t)))
                .map_err(|e| D::Error::custom(format!("tool: {e}"))),
            other => Err(D::Error::custom(format!(
                "tool must be a [tool] table or [[tool]] tables, not a {}",
                other.type_str()
            ))),
        }
    }
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawWorkspace {
    pub scale: Option<f64>,
    pub rotate_deg: Option<[f64; 3]>,
    pub offset: Option<[f64; 3]>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawRates {
    pub haptic_hz: Option<f64>,
    pub deform_max_hz: Option<f64>,
    pub publish_hz: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawDevice {
    pub mock_script: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawBody {
    pub name: String,
    pub mesh: String,
    pub render_surface: Option<String>,
    pub importance: Option<Importance>,
    pub model: Option<ModelPin>,
    pub translate: Option<[f64; 3]>,
    pub rotate_deg: Option<[f64; 3]>,
    pub scale: Option<f64>,
    pub fixed_nodes: Option<Vec<u32>>,
    pub fix: Option<Vec<crate::scene::fix::RawFix>>,
    pub color: Option<[f32; 3]>,
    pub tool_stiffness: Option<f64>,
    pub fem: Option<RawFem>,
    pub msd: Option<RawMsd>,
    pub gc: Option<RawGc>,
    pub heat: Option<RawBodyHeat>,
    pub cut: Option<bool>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawBodyHeat {
    pub conductivity: Option<f64>,
    pub specific_heat: Option<f64>,
    pub density: Option<f64>,
    pub initial: Option<f64>,
    pub coagulation: Option<f64>,
    pub burn_stiffening: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawFem {
    pub young: f64,
    pub poisson: f64,
    pub density: f64,
    pub damping: f64,
    pub dt: f64,
    pub mode: Option<FemMode>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawMsd {
    pub stiffness: f64,
    pub density: Option<f64>,
    pub node_mass: Option<f64>,
    pub damping: f64,
    pub dt: f64,
    pub integrator: Option<Integrator>,
}

/// `[body.gc] cage`: the tag of `lop-sim`'s `CageShape` (a subdivided box takes its count
/// from `subdivisions`).
#[derive(Debug, Clone, Copy, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum CageKind {
    #[default]
    Fitted,
    Box,
    SubdividedBox,
}

/// `[body.gc] dynamics`: the tag of `lop-sim`'s `CageDynamics` (a mass-spring cage takes its
/// parameters from the table's `stiffness`, `density` and `damping`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum GcDynamics {
    #[default]
    Projected,
    Galerkin,
    MassSpring,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawGc {
    pub cage: Option<CageKind>,
    pub subdivisions: Option<i64>,
    pub padding: Option<f64>,
    pub dynamics: Option<GcDynamics>,
    pub stiffness: Option<f64>,
    pub density: Option<f64>,
    pub damping: Option<f64>,
    pub dt: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawDaemon {
    #[serde(default)]
    pub haptic: RawHaptic,
    #[serde(default)]
    pub deform: RawDeform,
    pub status_interval_ms: Option<u64>,
    #[serde(default)]
    pub device: RawDaemonDevice,
    #[serde(default)]
    pub remote: crate::remote::RawRemote,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawHaptic {
    pub core: Option<usize>,
    pub rt_priority: Option<u8>,
    pub lock_memory: Option<bool>,
    pub stale_frame_ms: Option<f64>,
    pub ramp_ms: Option<f64>,
    pub max_force_n: Option<f64>,
    pub spin_us: Option<f64>,
    pub max_force_step_n: Option<f64>,
    pub local_model: Option<bool>,
    pub passivity_max_damping: Option<f64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawDeform {
    pub core: Option<usize>,
    pub threads: Option<usize>,
    pub max_period_ms: Option<u32>,
    pub rt_priority: Option<u32>,
}

/// `[device]` of the daemon config: the vendor libraries (OpenHaptics, Force Dimension DHD).
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawDaemonDevice {
    pub hd_library: Option<std::path::PathBuf>,
    pub dhd_library: Option<std::path::PathBuf>,
}
