//! Validated scene types and stage two of loading: raw structs → [`Scene`].
//!
//! This file holds [`Scene`] and the loading entry points; the submodules hold the body spec
//! types (`body`), the scene-level section types (`sections`) and the validation of the
//! sections (`validate`) and of the bodies (`validate_body`).

mod body;
pub(crate) mod fix;
mod sections;
mod validate;
mod validate_body;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::check::Check;
use crate::error::ConfigError;
use crate::raw::RawScene;
use crate::source::{KeyPath, Source};

pub use body::{BodySpec, GcParams, HeatParams, Importance};
pub use fix::{parse_selector, selector_toml};
pub use sections::{
    CollisionSpec, CutSpec, DeviceDefaults, HeatSpec, LopSpec, Rates, ToolKind, ToolSpec,
};
use validate::{
    check_name, validate_collision, validate_cut, validate_device, validate_heat, validate_lop,
    validate_rates, validate_tools,
};
use validate_body::validate_body;

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
    /// The tools (god-objects), in file order (at least one, at most
    /// [`lop_sim::world::MAX_TOOLS`]): each with its force law, its device's workspace map and
    /// its default script.
    pub tools: Vec<ToolSpec>,
    /// Loop rates.
    pub rates: Rates,
    /// Device defaults for this scene.
    pub device: DeviceDefaults,
    /// When bodies switch between their levels of precision.
    pub lop: LopSpec,
    /// Air and contact for the heat model, `[heat]`.
    pub heat: HeatSpec,
    /// Cutting, `[cut]` (the bodies a cut may reach say so themselves, `[[body]] cut`).
    pub cut: CutSpec,
    /// Organ-to-organ collision, `[collision]`.
    pub collision: CollisionSpec,
}

impl Scene {
    /// The first tool: a scene's only tool, or the one a single device drives.
    pub fn tool(&self) -> &ToolSpec {
        &self.tools[0]
    }

    /// The script a scripted device driving tool `tool` plays when none is named: the tool's
    /// own, for the first tool else `[device] mock_script`.
    pub fn tool_script(&self, tool: usize) -> Option<&Path> {
        let own = self.tools.get(tool)?.mock_script.as_deref();
        own.or(if tool == 0 {
            self.device.mock_script.as_deref()
        } else {
            None
        })
    }

    /// The body called `name`, if any.
    pub fn body(&self, name: &str) -> Option<&BodySpec> {
        self.bodies.iter().find(|b| b.name == name)
    }
}

/// Reads and validates the scene file at `path`.
pub fn load_scene(path: &Path) -> Result<Scene, ConfigError> {
    let text = crate::source::read_text(path)?;
    parse_scene(&text, path)
}

/// Parses and validates scene text. `path` is used only in messages and to resolve relative
/// paths (mesh files, mock script, a base scene) against its directory; the mesh files must
/// exist.
pub fn parse_scene(text: &str, path: &Path) -> Result<Scene, ConfigError> {
    parse_scene_at(text, path, 0)
}

/// Bases a scene may stand on, one on another (a scene that is its own base is refused here).
const MAX_BASES: usize = 4;

/// The top-level sections a scene with a `base` gives itself; the rest come from the base.
const OVER_BASE: [&str; 6] = ["base", "scene", "tool", "workspace", "rates", "device"];

fn parse_scene_at(text: &str, path: &Path, depth: usize) -> Result<Scene, ConfigError> {
    let src = Source::parse(path, text)?;
    let raw: RawScene = src.deserialize()?;
    match raw.base.clone() {
        None => validate_scene(&src, raw),
        Some(base) => over_base(&src, raw, &base, depth),
    }
}

/// A scene written over another (`base = "abdomen.toml"`): the base's bodies, `[lop]`,
/// `[heat]`, `[collision]` and `[cut]`, with this file's `[scene]`, tools and `[workspace]`, `[rates]`
/// and `[device]` where it gives them — a scene of other tools, devices or mappings over the
/// same organs, without copying them. The base is loaded as a scene of its own first (its
/// errors name its file); a section given here replaces the base's whole (tools given here
/// map with this file's `[workspace]`, the default one if it gives none).
fn over_base(
    src: &Source<'_>,
    raw: RawScene,
    base: &str,
    depth: usize,
) -> Result<Scene, ConfigError> {
    let abs = std::path::absolute(src.file).unwrap_or_else(|_| src.file.to_path_buf());
    let dir = abs.parent().map(Path::to_path_buf).unwrap_or_default();
    let c = Check { src, body: None };
    let key = KeyPath::top("base");
    let given = src.top_keys();
    if let Some(other) = given.iter().find(|k| !OVER_BASE.contains(&k.as_str())) {
        return Err(c.invalid(
            &KeyPath::top(other),
            "(given)",
            format!(
                "a scene with a base takes its bodies, [lop], [heat], [collision] and [cut] from the \
                 base ({base:?}); over it, a scene gives only {}",
                OVER_BASE[1..].join(", ")
            ),
        ));
    }
    if base.trim().is_empty() {
        return Err(c.invalid(
            &key,
            "\"\"",
            "base must be a scene file's path (relative to this file)",
        ));
    }
    if depth >= MAX_BASES {
        return Err(c.invalid(
            &key,
            format!("{base:?}"),
            format!("more than {MAX_BASES} scenes stand on one another (a base that leads back to itself?)"),
        ));
    }
    let base_path = dir.join(base);
    let text = crate::source::read_text(&base_path).map_err(|e| match e {
        ConfigError::Read { source, .. } => c.invalid(
            &key,
            format!("{base:?}"),
            format!(
                "the base scene {} cannot be read: {source}",
                base_path.display()
            ),
        ),
        other => other,
    })?;
    // `../base/x.toml` resolved, so the base's meshes are named as the base names them.
    let base_path = base_path.canonicalize().unwrap_or(base_path);
    let mut scene = parse_scene_at(&text, &base_path, depth + 1)?;
    let meta = KeyPath::top("scene");
    scene.name = match raw.scene.name {
        Some(n) => n,
        None => src
            .file
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .filter(|s| !s.trim().is_empty())
            .unwrap_or_else(|| "unnamed".to_owned()),
    };
    check_name(&c, &meta.key("name"), &scene.name, "scene name")?;
    if let Some(d) = raw.scene.description {
        scene.description = d;
    }
    if let Some(g) = raw.scene.gravity {
        scene.gravity = c.finite3(&meta.key("gravity"), g, "gravity")?;
    }
    let has = |k: &str| given.iter().any(|g| g == k);
    if has("tool") || has("workspace") {
        scene.tools = validate_tools(&c, raw.tool, raw.workspace, &dir)?;
    }
    if has("rates") {
        scene.rates = validate_rates(&c, raw.rates)?;
    }
    if has("device") {
        scene.device = validate_device(&c, raw.device, &dir)?;
    }
    scene.path = abs;
    Ok(scene)
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

    let tools = validate_tools(&c, raw.tool, raw.workspace, &dir)?;
    let rates = validate_rates(&c, raw.rates)?;
    let device = validate_device(&c, raw.device, &dir)?;
    let lop = validate_lop(&c, raw.lop)?;
    let heat = validate_heat(&c, raw.heat)?;
    let collision = validate_collision(&c, raw.collision)?;
    let cut = validate_cut(&c, raw.cut)?;

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
        tools,
        rates,
        device,
        lop,
        heat,
        collision,
        cut,
    })
}
