//! Scene-level section types of a validated scene: `[tool]`, `[rates]`, `[device]`, `[lop]`,
//! `[heat]` and `[collision]`, with their defaults. The force law and the start level are
//! `lop-sim`'s ([`ForceLaw`], [`StartLevel`]).

use std::path::PathBuf;

use crate::WorkspaceMap;
use lop_sim::contact::ForceLaw;
use lop_sim::lop::StartLevel;

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
    /// Simulated time between two detections, s (>= 0; 0: every round in which a body steps).
    pub interval: f64,
}

impl Default for CollisionSpec {
    fn default() -> Self {
        CollisionSpec {
            enabled: true,
            stiffness: 20.0,
            skin: 0.0005,
            depth_limit: 0.01,
            interval: 0.0,
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
    /// Heat time step, s (0 < dt <= 1); `None`: `lop_scene::HEAT_DT_DEFAULT` (0.01 s).
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

/// Cutting, `[cut]`: how a cautery holding the cut button cuts the bodies that allow it
/// (`[[body]] cut = true`; `lop_sim::cut`).
#[derive(Debug, Clone, PartialEq)]
pub struct CutSpec {
    /// Node temperature at which tissue under a cutting tip vaporises and is cut away, °C
    /// (intracellular water boils at 100 °C).
    pub vaporization: f64,
    /// Steps of the body from a cut's request to the step it lands before, while the new mesh
    /// is prepared off the stepping thread (1–1000).
    pub delay_steps: u32,
}

impl Default for CutSpec {
    /// The physics crate's defaults (`lop_sim::cut::CutParams`): one owner.
    fn default() -> Self {
        let d = lop_sim::cut::CutParams::default();
        CutSpec {
            vaporization: d.vaporization,
            delay_steps: d.delay_steps,
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

/// What a tool is, and so what its device's buttons do (`[tool] kind`). Every kind presses
/// the tissue with its tip, a sphere rendered as a god-object.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum ToolKind {
    /// A probe (the default): its grab button holds the tissue at the point it touches, its
    /// heat button cauterizes there.
    #[default]
    Probe,
    /// A grasper: its grab button closes the jaws, which hold the surface within `jaw_radius`
    /// (m) of the point the tip touches until the button opens them; no cautery.
    Grasper {
        /// How far around the touched point the closed jaws hold the surface, m (> 0).
        jaw_radius: f64,
    },
    /// An electrosurgical hook: its heat button cauterizes where the tip touches; it does not
    /// hold tissue (its grab button is ignored).
    Hook,
}

impl ToolKind {
    /// The name written in `kind`.
    pub fn name(&self) -> &'static str {
        match self {
            ToolKind::Probe => "probe",
            ToolKind::Grasper { .. } => "grasper",
            ToolKind::Hook => "hook",
        }
    }

    /// Whether the grab button holds the tissue (a probe's point, a grasper's jaws).
    pub fn holds(&self) -> bool {
        !matches!(self, ToolKind::Hook)
    }

    /// Whether the heat button cauterizes.
    pub fn cauterizes(&self) -> bool {
        !matches!(self, ToolKind::Grasper { .. })
    }

    /// A grasper's jaw radius, m; `None` for the other kinds (they hold at a point).
    pub fn jaw_radius(&self) -> Option<f64> {
        match *self {
            ToolKind::Grasper { jaw_radius } => Some(jaw_radius),
            _ => None,
        }
    }
}

/// A tool: a sphere driven by a device, rendered as a god-object.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolSpec {
    /// Name (unique in the scene, non-empty): `tool` for a scene's only or first tool unless
    /// named, `toolN` for the N-th.
    pub name: String,
    /// What the tool is, and what its buttons do.
    pub kind: ToolKind,
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
    /// A cautery's power in cut mode (the cut button), W (>= 0).
    pub cut_power: f64,
    /// How this tool's device maps into the scene: its `[tool.workspace]`, else the scene's
    /// `[workspace]`.
    pub workspace: WorkspaceMap,
    /// The script a scripted device (mock, hand) driving this tool plays when none is named;
    /// resolved against the scene file's directory. The first tool falls back to
    /// `[device] mock_script`.
    pub mock_script: Option<PathBuf>,
}

impl Default for ToolSpec {
    fn default() -> Self {
        ToolSpec {
            name: "tool".to_owned(),
            kind: ToolKind::Probe,
            workspace: WorkspaceMap::default(),
            mock_script: None,
            radius: 0.003,
            force_law: ForceLaw::Linear,
            stiffness: 300.0,
            damping: 0.0,
            max_force: 3.0,
            heat_power: 20.0,
            cut_power: 80.0,
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
