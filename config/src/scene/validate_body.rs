//! Validation of one `[[body]]` table and its parameter tables, and resolving its mesh path.

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use crate::check::{fmt_f64, fmt_f64s, Check};
use crate::error::ConfigError;
use crate::raw::{CageKind, GcDynamics, RawBody, RawBodyHeat, RawFem, RawGc, RawMsd};
use crate::source::{KeyPath, Source};

use super::fix::validate_fix;
use super::validate::check_name;
use lop_sim::fem::FemParameters;
use lop_sim::lop::{CageDynamics, CageShape, CageSprings};
use lop_sim::model::ModelPin;
use lop_sim::msd::{MsdParameters, NodeMass};

use super::{BodySpec, GcParams, HeatParams, Importance};

/// Default viewer colours, by body index (sRGB).
const PALETTE: [[f32; 3]; 6] = [
    [0.55, 0.16, 0.13],
    [0.36, 0.52, 0.78],
    [0.42, 0.15, 0.35],
    [0.93, 0.66, 0.60],
    [0.90, 0.78, 0.52],
    [0.40, 0.65, 0.40],
];

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

pub(super) fn validate_body(
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
    let cut = rb.cut.unwrap_or(false);
    if cut && model == ModelPin::Gc {
        return Err(c.invalid(
            &key.key("cut"),
            "true",
            "a body pinned to its cage (model = \"gc\") cannot be cut: the cage's deformation \
             cannot open a wound. Give it model = \"auto\", \"fem\" or \"msd\"",
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
    let fix = rb
        .fix
        .unwrap_or_default()
        .into_iter()
        .enumerate()
        .map(|(i, f)| validate_fix(&c, &key.key("fix").index(i), f))
        .collect::<Result<Vec<_>, _>>()?;
    let mesh = resolve_mesh(&c, &key.key("mesh"), &rb.mesh, dir)?;
    let render_surface = rb
        .render_surface
        .as_deref()
        .map(|given| resolve_surface(&c, &key.key("render_surface"), given, dir))
        .transpose()?;

    Ok(BodySpec {
        name: rb.name.clone(),
        mesh,
        render_surface,
        importance,
        model,
        translate,
        rotate_deg,
        scale,
        fixed_nodes: rb.fixed_nodes.unwrap_or_default(),
        fix,
        color,
        tool_stiffness,
        fem,
        msd,
        gc,
        heat,
        cut,
    })
}

fn validate_fem(c: &Check<'_, '_>, k: &KeyPath, raw: RawFem) -> Result<FemParameters, ConfigError> {
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
    Ok(FemParameters {
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

fn validate_msd(c: &Check<'_, '_>, k: &KeyPath, raw: RawMsd) -> Result<MsdParameters, ConfigError> {
    let stiffness = c.positive(&k.key("stiffness"), raw.stiffness, "spring stiffness (N/m)")?;
    let mass = match (raw.density, raw.node_mass) {
        (Some(d), None) => {
            NodeMass::Density(c.positive(&k.key("density"), d, "density (kg/m³)")?)
        }
        (None, Some(m)) => {
            NodeMass::PerNode(c.positive(&k.key("node_mass"), m, "node_mass (kg)")?)
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
    Ok(MsdParameters {
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
    let tag = raw.dynamics.unwrap_or_default();
    let subdivisions = match raw.subdivisions {
        None => 2,
        Some(n) if (1..=8).contains(&n) => n as usize,
        Some(n) => {
            return Err(c.invalid(
                &k.key("subdivisions"),
                n.to_string(),
                "subdivisions must be 1..=8 segments per cage edge (8 gives 386 cage vertices)",
            ))
        }
    };
    let shape = match raw.cage.unwrap_or_default() {
        CageKind::Fitted => CageShape::Fitted,
        CageKind::Box => CageShape::Box,
        CageKind::SubdividedBox => CageShape::SubdividedBox(subdivisions),
    };
    let padding = raw
        .padding
        .map(|p| c.positive(&k.key("padding"), p, "cage padding (m)"))
        .transpose()?;
    let stiffness = raw
        .stiffness
        .map(|v| c.positive(&k.key("stiffness"), v, "GC stiffness (N/m)"))
        .transpose()?;
    let density = raw
        .density
        .map(|v| c.positive(&k.key("density"), v, "GC density (kg/m³)"))
        .transpose()?;
    let damping = raw
        .damping
        .map(|v| c.non_negative(&k.key("damping"), v, "GC damping (N·s/m)"))
        .transpose()?;
    // The three describe one mass-spring cage: all or none (a mass-spring cage needs all).
    let springs = match (stiffness, density, damping) {
        (Some(stiffness), Some(density), Some(damping)) => Some(CageSprings {
            stiffness,
            density,
            damping,
        }),
        (None, None, None) if tag != GcDynamics::MassSpring => None,
        given => {
            let missing = [
                ("stiffness", given.0),
                ("density", given.1),
                ("damping", given.2),
            ]
            .into_iter()
            .find(|(_, v)| v.is_none())
            .map_or("stiffness", |(key, _)| key);
            let why = if tag == GcDynamics::MassSpring {
                format!("dynamics = \"mass-spring\" needs the cage's {missing}")
            } else {
                format!(
                    "stiffness, density and damping describe the mass-spring cage together: \
                     give all three or none ({missing} is missing)"
                )
            };
            return Err(c.invalid(&k.key(missing), "(missing)", why));
        }
    };
    let dynamics = match tag {
        GcDynamics::Projected => CageDynamics::Projected,
        GcDynamics::Galerkin => CageDynamics::Galerkin,
        // `springs` is `Some` here: a mass-spring table without them was refused above.
        GcDynamics::MassSpring => CageDynamics::MassSpring(springs.unwrap_or(CageSprings::THESIS)),
    };
    let dt = raw.dt.map(|v| c.time_step(&k.key("dt"), v)).transpose()?;
    Ok(GcParams {
        shape,
        padding,
        dynamics,
        springs,
        dt,
    })
}

/// Resolves `given` against `dir` and checks that it names an existing file.
fn resolve_surface(
    c: &Check<'_, '_>,
    key: &KeyPath,
    given: &str,
    dir: &Path,
) -> Result<PathBuf, ConfigError> {
    let path = dir.join(given);
    if !given.trim().is_empty() && path.is_file() {
        return Ok(path);
    }
    Err(not_found(c, key, given, vec![path]))
}

/// The error for a `key` whose file `given` is none of the paths `tried`.
fn not_found(c: &Check<'_, '_>, key: &KeyPath, given: &str, tried: Vec<PathBuf>) -> ConfigError {
    ConfigError::MeshNotFound {
        at: Box::new(c.src.locate(key)),
        key: key.to_string(),
        body: c.body.map(str::to_owned),
        given: given.to_owned(),
        tried,
    }
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
    Err(not_found(c, key, given, vec![path, node]))
}
