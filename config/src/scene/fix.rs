//! Fixed-node selectors, `[[body.fix]]`: regions whose nodes a body holds fixed, in the scene's
//! coordinates (see the crate docs). A selector is `lop-sim`'s [`NodeSelector`]; it is validated
//! here (every key named in its error) and evaluated where the mesh is loaded (`lop-scene`),
//! since this crate never reads meshes.

use std::path::Path;

use lop_sim::mesh::{NodeSelector, FACING_ANGLE_DEFAULT_DEG};
use serde::{Deserialize, Serialize};

use crate::check::{fmt_f64, fmt_f64s, Check};
use crate::error::ConfigError;
use crate::source::{KeyPath, Source};

/// The kinds of selector, `kind = "..."`: the tag of [`NodeSelector`], read here so that a
/// key of another kind is reported by name (see [`validate_fix`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub(crate) enum FixKind {
    /// Inside an axis-aligned box.
    Box,
    /// Inside a sphere.
    Sphere,
    /// Behind a plane, optionally within a thickness of it.
    Slab,
    /// Surface nodes whose normal faces a direction.
    Facing,
}

/// Raw `[[body.fix]]` table: every key of every kind, checked against `kind` in validation.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct RawFix {
    pub kind: FixKind,
    pub min: Option<[f64; 3]>,
    pub max: Option<[f64; 3]>,
    pub center: Option<[f64; 3]>,
    pub radius: Option<f64>,
    pub point: Option<[f64; 3]>,
    pub normal: Option<[f64; 3]>,
    pub thickness: Option<f64>,
    pub direction: Option<[f64; 3]>,
    pub angle_deg: Option<f64>,
    pub within: Option<Box<RawFix>>,
}

impl RawFix {
    /// The keys given besides `kind`.
    fn given(&self) -> Vec<&'static str> {
        let mut keys = Vec::new();
        let mut add = |present: bool, key| {
            if present {
                keys.push(key)
            }
        };
        add(self.min.is_some(), "min");
        add(self.max.is_some(), "max");
        add(self.center.is_some(), "center");
        add(self.radius.is_some(), "radius");
        add(self.point.is_some(), "point");
        add(self.normal.is_some(), "normal");
        add(self.thickness.is_some(), "thickness");
        add(self.direction.is_some(), "direction");
        add(self.angle_deg.is_some(), "angle_deg");
        add(self.within.is_some(), "within");
        keys
    }
}

fn kind_name(kind: FixKind) -> &'static str {
    match kind {
        FixKind::Box => "box",
        FixKind::Sphere => "sphere",
        FixKind::Slab => "slab",
        FixKind::Facing => "facing",
    }
}

/// The keys each kind takes.
fn keys_of(kind: FixKind) -> &'static [&'static str] {
    match kind {
        FixKind::Box => &["min", "max"],
        FixKind::Sphere => &["center", "radius"],
        FixKind::Slab => &["point", "normal", "thickness"],
        FixKind::Facing => &["direction", "angle_deg", "within"],
    }
}

pub(crate) fn validate_fix(
    c: &Check<'_, '_>,
    k: &KeyPath,
    raw: RawFix,
) -> Result<NodeSelector, ConfigError> {
    let name = kind_name(raw.kind);
    let allowed = keys_of(raw.kind);
    if let Some(extra) = raw.given().into_iter().find(|g| !allowed.contains(g)) {
        return Err(c.invalid(
            &k.key(extra),
            "(given)",
            format!(
                "a {name} selector takes {}; `{extra}` belongs to another kind",
                allowed.join(", ")
            ),
        ));
    }
    let need3 = |key: &str, v: Option<[f64; 3]>, what: &str| -> Result<[f64; 3], ConfigError> {
        match v {
            Some(v) => c.finite3(&k.key(key), v, what),
            None => Err(c.invalid(
                &k.key(key),
                "(missing)",
                format!("a {name} selector needs `{key}` ({what})"),
            )),
        }
    };
    let nonzero = |key: &str, v: [f64; 3], what: &str| -> Result<[f64; 3], ConfigError> {
        if v.iter().any(|x| *x != 0.0) {
            Ok(v)
        } else {
            Err(c.invalid(
                &k.key(key),
                fmt_f64s(&v),
                format!("{what} must not be the zero vector"),
            ))
        }
    };
    Ok(match raw.kind {
        FixKind::Box => {
            let min = need3("min", raw.min, "lowest corner, m")?;
            let max = need3("max", raw.max, "highest corner, m")?;
            if !(0..3).all(|i| min[i] < max[i]) {
                return Err(c.invalid(
                    &k.key("max"),
                    fmt_f64s(&max),
                    format!(
                        "every component of max must be above min's ({})",
                        fmt_f64s(&min)
                    ),
                ));
            }
            NodeSelector::Box { min, max }
        }
        FixKind::Sphere => {
            let center = need3("center", raw.center, "centre, m")?;
            let Some(radius) = raw.radius else {
                return Err(c.invalid(
                    &k.key("radius"),
                    "(missing)",
                    "a sphere selector needs `radius` (m)",
                ));
            };
            NodeSelector::Sphere {
                center,
                radius: c.positive(&k.key("radius"), radius, "sphere radius (m)")?,
            }
        }
        FixKind::Slab => {
            let point = need3("point", raw.point, "a point of the plane, m")?;
            let normal = need3("normal", raw.normal, "the plane's normal")?;
            NodeSelector::Slab {
                point,
                normal: nonzero("normal", normal, "the plane's normal")?,
                thickness: raw
                    .thickness
                    .map(|t| c.positive(&k.key("thickness"), t, "slab thickness (m)"))
                    .transpose()?,
            }
        }
        FixKind::Facing => {
            let direction = need3("direction", raw.direction, "the direction the patch faces")?;
            let angle_deg = raw.angle_deg.unwrap_or(FACING_ANGLE_DEFAULT_DEG);
            if !(angle_deg > 0.0 && angle_deg <= 180.0) {
                return Err(c.invalid(
                    &k.key("angle_deg"),
                    fmt_f64(angle_deg),
                    "angle_deg must be above 0 and at most 180 (degrees)",
                ));
            }
            NodeSelector::Facing {
                direction: nonzero("direction", direction, "the facing direction")?,
                angle_deg,
                within: raw
                    .within
                    .map(|w| validate_fix(c, &k.key("within"), *w).map(Box::new))
                    .transpose()?,
            }
        }
    })
}

/// Parses one selector as written on a command line (`lopd mesh info --select`): the inside of
/// a TOML inline table, with or without its braces, e.g.
/// `kind = "sphere", center = [0, 0, 0], radius = 0.01`. Errors name the key as
/// `select.radius` and the source as `--select`.
pub fn parse_selector(text: &str) -> Result<NodeSelector, ConfigError> {
    let t = text.trim();
    let doc = if t.starts_with('{') {
        format!("select = {t}\n")
    } else {
        format!("select = {{ {t} }}\n")
    };
    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Wrapper {
        select: RawFix,
    }
    let file = Path::new("--select");
    let src = Source::parse(file, &doc)?;
    let raw: Wrapper = src.deserialize()?;
    let c = Check {
        src: &src,
        body: None,
    };
    validate_fix(&c, &KeyPath::top("select"), raw.select)
}

/// The selector as it would be written in a scene file or on the command line (an inline
/// table, keys in [`NodeSelector`]'s order), e.g. for a generated scene's comments or an error
/// message. Written by the `toml` crate from the selector's serde form.
pub fn selector_toml(s: &NodeSelector) -> String {
    let mut out = String::new();
    s.serialize(toml::ser::ValueSerializer::new(&mut out))
        .expect("a node selector is a TOML inline table");
    out
}
