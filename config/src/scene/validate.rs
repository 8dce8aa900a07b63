//! Validation of the scene-level sections (`[tool]`, `[workspace]`, `[rates]`, `[device]`,
//! `[lop]`, `[heat]`, `[collision]`) and of names.

use std::path::Path;

use crate::check::Check;
use crate::error::ConfigError;
use crate::raw::{
    RawCollision, RawCut, RawDevice, RawHeat, RawLop, RawRates, RawTool, RawTools, RawWorkspace,
};
use crate::source::KeyPath;
use crate::WorkspaceMap;

use lop_sim::contact::ForceLaw;
use lop_sim::world::MAX_TOOLS;

use super::{CollisionSpec, CutSpec, DeviceDefaults, HeatSpec, LopSpec, Rates, ToolKind, ToolSpec};

pub(super) fn validate_collision(
    c: &Check<'_, '_>,
    raw: RawCollision,
) -> Result<CollisionSpec, ConfigError> {
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
    let interval = c.non_negative(
        &k.key("interval"),
        raw.interval.unwrap_or(d.interval),
        "collision interval (s)",
    )?;
    if interval > 1.0 {
        return Err(c.invalid(
            &k.key("interval"),
            interval.to_string(),
            "collision interval (s): at most 1; organs would pass through each other between detections",
        ));
    }
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
        interval,
    })
}

pub(super) fn validate_heat(c: &Check<'_, '_>, raw: RawHeat) -> Result<HeatSpec, ConfigError> {
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

pub(super) fn validate_cut(c: &Check<'_, '_>, raw: RawCut) -> Result<CutSpec, ConfigError> {
    let k = KeyPath::top("cut");
    let d = CutSpec::default();
    let vaporization = c.temperature(
        &k.key("vaporization"),
        raw.vaporization.unwrap_or(d.vaporization),
        "vaporisation temperature",
    )?;
    let delay = raw.delay_steps.unwrap_or(i64::from(d.delay_steps));
    if !(1..=1000).contains(&delay) {
        return Err(c.invalid(
            &k.key("delay_steps"),
            delay,
            "delay_steps must be 1 to 1000 (steps of the body between a cut's request and its \
             landing)",
        ));
    }
    Ok(CutSpec {
        vaporization,
        delay_steps: delay as u32,
    })
}

pub(super) fn validate_lop(c: &Check<'_, '_>, raw: RawLop) -> Result<LopSpec, ConfigError> {
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
pub(super) fn check_name(
    c: &Check<'_, '_>,
    key: &KeyPath,
    name: &str,
    what: &str,
) -> Result<(), ConfigError> {
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

/// The tools: without a `[tool]` section the scene gets one default tool; one `[tool]` table
/// is one tool; `[[tool]]` tables are several, in order (at most [`MAX_TOOLS`]). Each table
/// must state `radius` and `stiffness` itself: they decide what the hand feels, and a default
/// stiffness in N/m would be meaningless for the quadratic law (N/m²). A tool maps its device
/// with its own `[tool.workspace]` (`workspace` in a `[[tool]]` table), else with the scene's
/// `[workspace]`; it plays its own `mock_script` on a scripted device, the first tool else
/// `[device] mock_script`.
pub(super) fn validate_tools(
    c: &Check<'_, '_>,
    raw: Option<RawTools>,
    workspace: RawWorkspace,
    dir: &Path,
) -> Result<Vec<ToolSpec>, ConfigError> {
    let shared = validate_workspace(c, &KeyPath::top("workspace"), workspace)?;
    let (raws, many) = match raw {
        None => {
            return Ok(vec![ToolSpec {
                workspace: shared,
                ..ToolSpec::default()
            }])
        }
        Some(RawTools::One(t)) => (vec![*t], false),
        Some(RawTools::Many(v)) => (v, true),
    };
    let top = KeyPath::top("tool");
    if raws.is_empty() || raws.len() > MAX_TOOLS {
        return Err(c.invalid(
            &top,
            format!("{} tables", raws.len()),
            format!("a scene has 1 to {MAX_TOOLS} tools"),
        ));
    }
    let mut tools: Vec<ToolSpec> = Vec::with_capacity(raws.len());
    for (i, raw) in raws.into_iter().enumerate() {
        let k = if many { top.index(i) } else { top.clone() };
        let tool = validate_tool(c, &k, raw, &shared, dir, i)?;
        if let Some(first) = tools.iter().position(|t| t.name == tool.name) {
            return Err(c.invalid(
                &k.key("name"),
                format!("{:?}", tool.name),
                format!("duplicate tool name: tool[{first}] already has it; names must be unique"),
            ));
        }
        tools.push(tool);
    }
    Ok(tools)
}

/// One tool table at `k`, the `index`-th.
fn validate_tool(
    c: &Check<'_, '_>,
    k: &KeyPath,
    raw: RawTool,
    shared: &WorkspaceMap,
    dir: &Path,
    index: usize,
) -> Result<ToolSpec, ConfigError> {
    let d = ToolSpec::default();
    let force_law = raw.force_law.unwrap_or(d.force_law);
    let unit = match force_law {
        ForceLaw::Linear => "tool stiffness (N/m, linear law)",
        ForceLaw::Quadratic => "tool stiffness (N/m², quadratic law)",
    };
    let required = |key: &str, v: Option<f64>, what: &str| {
        v.ok_or_else(|| {
            c.invalid(
                &k.key(key),
                "(missing)",
                format!("a [tool] table must give the {what}"),
            )
        })
    };
    let name = match raw.name {
        Some(n) => n,
        None if index == 0 => d.name.clone(),
        None => format!("tool{}", index + 1),
    };
    check_name(c, &k.key("name"), &name, "tool name")?;
    let radius = c.positive(
        &k.key("radius"),
        required("radius", raw.radius, "tool radius (m)")?,
        "tool radius (m)",
    )?;
    let stiffness = c.positive(
        &k.key("stiffness"),
        required("stiffness", raw.stiffness, unit)?,
        unit,
    )?;
    let workspace = match raw.workspace {
        Some(w) => validate_workspace(c, &k.key("workspace"), w)?,
        None => shared.clone(),
    };
    let mock_script = match raw.mock_script {
        None => None,
        Some(s) if s.trim().is_empty() => {
            return Err(c.invalid(
                &k.key("mock_script"),
                "\"\"",
                "mock_script must be a path (relative to the scene file) or be left out",
            ));
        }
        Some(s) => Some(dir.join(s)),
    };
    let kind = validate_kind(c, k, &raw.kind, raw.jaw_radius, radius)?;
    for (key, given) in [("heat_power", raw.heat_power), ("cut_power", raw.cut_power)] {
        if let (Some(v), false) = (given, kind.cauterizes()) {
            return Err(c.invalid(
                &k.key(key),
                format!("{v}"),
                format!("a {} does not cauterize: leave {key} out", kind.name()),
            ));
        }
    }
    Ok(ToolSpec {
        name,
        kind,
        radius,
        force_law,
        stiffness,
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
        cut_power: c.non_negative(
            &k.key("cut_power"),
            raw.cut_power.unwrap_or(d.cut_power),
            "tool cut_power (W)",
        )?,
        workspace,
        mock_script,
    })
}

/// A tool's `kind` (and a grasper's `jaw_radius`, by default its tip's `radius`).
fn validate_kind(
    c: &Check<'_, '_>,
    k: &KeyPath,
    kind: &Option<String>,
    jaw_radius: Option<f64>,
    radius: f64,
) -> Result<ToolKind, ConfigError> {
    let kind = match kind.as_deref() {
        None | Some("probe") => ToolKind::Probe,
        Some("hook") => ToolKind::Hook,
        Some("grasper") => ToolKind::Grasper {
            jaw_radius: c.positive(
                &k.key("jaw_radius"),
                jaw_radius.unwrap_or(radius),
                "grasper jaw_radius (m)",
            )?,
        },
        Some("blade") => {
            return Err(c.invalid(
                &k.key("kind"),
                "\"blade\"",
                "a blade's sweeping cut is not built yet: cut with a cautery's cut button \
                 (kind = \"probe\" or \"hook\", [cut]); kind is probe, grasper or hook",
            ))
        }
        Some(other) => {
            return Err(c.invalid(
                &k.key("kind"),
                format!("{other:?}"),
                "kind is probe, grasper or hook",
            ))
        }
    };
    if let (Some(j), None) = (jaw_radius, kind.jaw_radius()) {
        return Err(c.invalid(
            &k.key("jaw_radius"),
            format!("{j}"),
            format!("only a grasper has jaws; this tool is a {}", kind.name()),
        ));
    }
    Ok(kind)
}

fn validate_workspace(
    c: &Check<'_, '_>,
    k: &KeyPath,
    raw: RawWorkspace,
) -> Result<WorkspaceMap, ConfigError> {
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

pub(super) fn validate_rates(c: &Check<'_, '_>, raw: RawRates) -> Result<Rates, ConfigError> {
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

pub(super) fn validate_device(
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
