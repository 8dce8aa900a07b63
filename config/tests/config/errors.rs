//! Every bad input gives an error naming the file, the key path and the offending value.

use crate::common;

use common::{good_with, line_of, scene_path, GOOD};
use lop_config::{parse_scene, ConfigError, Integrator, NodeMass};
use lop_test_support::rng::Rng;

/// Parses `text` expecting an error; asserts the message names the scene file and contains
/// every string of `needles`. Returns the error for further checks.
fn expect_err(text: &str, needles: &[&str]) -> ConfigError {
    let err = match parse_scene(text, &scene_path()) {
        Ok(scene) => panic!("expected an error, got {scene:#?}"),
        Err(e) => e,
    };
    let msg = err.to_string();
    assert!(
        msg.contains("test-scene.toml"),
        "message does not name the file: {msg}"
    );
    for needle in needles {
        assert!(msg.contains(needle), "message lacks {needle:?}: {msg}");
    }
    err
}

#[test]
fn the_fixture_itself_is_valid() {
    let scene = parse_scene(GOOD, &scene_path()).unwrap();
    assert_eq!(scene.bodies.len(), 2);
    assert_eq!(
        scene.bodies[1].msd.as_ref().unwrap().integrator,
        Integrator::Rk4
    );
    assert_eq!(
        scene.bodies[1].msd.as_ref().unwrap().mass,
        NodeMass::PerNode(0.001)
    );
}

#[test]
fn unknown_top_level_key() {
    let text = format!("colour = \"red\"\n{GOOD}");
    let err = expect_err(&text, &["colour", "unknown field"]);
    assert_eq!(err.line(), Some(1));
}

#[test]
fn unknown_table() {
    expect_err(
        &format!("{GOOD}\n[camera]\nfov = 60\n"),
        &["camera", "unknown field"],
    );
}

#[test]
fn unknown_key_inside_body_fem() {
    let text = good_with("young = 600.0", "youngs = 600.0");
    let err = expect_err(&text, &["body[0].fem", "youngs", "unknown field"]);
    assert_eq!(err.line(), Some(line_of(&text, "youngs")));
}

#[test]
fn unknown_key_inside_second_body() {
    let text = good_with("integrator = \"rk4\"", "integrator = \"rk4\"\nsprings = 3");
    expect_err(&text, &["body[1].msd", "springs"]);
}

#[test]
fn nan_young() {
    let text = good_with("young = 600.0", "young = nan");
    let err = expect_err(&text, &["body[0].fem.young", "nan", "body \"a\""]);
    assert_eq!(err.key(), Some("body[0].fem.young"));
    assert_eq!(err.line(), Some(line_of(&text, "young = nan")));
}

#[test]
fn infinite_young() {
    expect_err(
        &good_with("young = 600.0", "young = inf"),
        &["body[0].fem.young", "inf"],
    );
}

#[test]
fn negative_density() {
    expect_err(
        &good_with("density = 30.0", "density = -30.0"),
        &["body[0].fem.density", "-30"],
    );
}

#[test]
fn poisson_one_half() {
    expect_err(
        &good_with("poisson = 0.3", "poisson = 0.5"),
        &["body[0].fem.poisson", "0.5"],
    );
}

#[test]
fn nan_poisson() {
    expect_err(
        &good_with("poisson = 0.3", "poisson = nan"),
        &["body[0].fem.poisson", "nan"],
    );
}

#[test]
fn duplicate_body_name() {
    let text = good_with("name = \"b\"", "name = \"a\"");
    let err = expect_err(&text, &["body[1].name", "\"a\"", "duplicate"]);
    let second = text.rfind("name = \"a\"").unwrap();
    assert_eq!(err.line(), Some(text[..second].matches('\n').count() + 1));
}

#[test]
fn empty_body_name() {
    expect_err(
        &good_with("name = \"b\"", "name = \" \""),
        &["body[1].name", "empty"],
    );
}

#[test]
fn missing_mesh_file() {
    let err = expect_err(
        &good_with("mesh = \"m\"", "mesh = \"organs/nope\""),
        &["body[0].mesh", "organs/nope", "nope.node"],
    );
    assert!(matches!(err, ConfigError::MeshNotFound { .. }));
}

#[test]
fn important_body_without_fem() {
    let text = GOOD.replacen(
        "[body.fem]\nyoung = 600.0\npoisson = 0.3\ndensity = 30.0\ndamping = 1.0\ndt = 0.02\n",
        "",
        1,
    );
    assert_ne!(text, GOOD);
    expect_err(&text, &["body[0].fem", "important", "(missing)"]);
}

#[test]
fn body_without_msd() {
    let text = GOOD.replacen(
        "[body.msd]\nstiffness = 700.0\nnode_mass = 0.001\ndamping = 0.4\ndt = 0.02\nintegrator = \"rk4\"\n",
        "",
        1,
    );
    assert_ne!(text, GOOD);
    expect_err(&text, &["body[1].msd", "(missing)"]);
    // ... unless it is pinned to FEM (which then needs fem).
    let pinned = text.replacen(
        "name = \"b\"\nmesh = \"m\"\n",
        "name = \"b\"\nmesh = \"m\"\nmodel = \"fem\"\n",
        1,
    );
    expect_err(&pinned, &["body[1].fem", "model = \"fem\""]);
    let with_fem = format!(
        "{pinned}[body.fem]\nyoung = 1.0\npoisson = 0.0\ndensity = 1.0\ndamping = 0.0\ndt = 0.01\n"
    );
    parse_scene(&with_fem, &scene_path()).unwrap();
}

#[test]
fn mass_spring_cage_needs_its_parameters() {
    expect_err(
        &good_with(
            "name = \"b\"\nmesh = \"m\"\n",
            "name = \"b\"\nmesh = \"m\"\nmodel = \"gc\"\n[body.gc]\ndynamics = \"mass-spring\"\nstiffness = 50.0\n",
        ),
        &["body[1].gc.density", "(missing)", "mass-spring"],
    );
}

/// The three spring values describe one mass-spring cage: a table that gives some of them
/// beside another dynamics is refused too, rather than silently keeping half a cage.
#[test]
fn cage_springs_come_all_together() {
    expect_err(
        &good_with(
            "name = \"b\"\nmesh = \"m\"\n",
            "name = \"b\"\nmesh = \"m\"\n[body.gc]\nstiffness = 50.0\ndensity = 20.0\n",
        ),
        &["body[1].gc.damping", "(missing)", "all three or none"],
    );
}

#[test]
fn cage_subdivisions_out_of_range() {
    expect_err(
        &good_with(
            "name = \"b\"\nmesh = \"m\"\n",
            "name = \"b\"\nmesh = \"m\"\n[body.gc]\ncage = \"subdivided-box\"\nsubdivisions = 0\n",
        ),
        &["body[1].gc.subdivisions", "0", "1..=8"],
    );
}

#[test]
fn lop_rest_speed_must_be_positive() {
    expect_err(
        &format!("[lop]\nrest_speed = -1.0\n{}", good_with("", "")),
        &["lop.rest_speed", "-1"],
    );
}

#[test]
fn both_density_and_node_mass() {
    let err = expect_err(
        &good_with("node_mass = 0.001", "node_mass = 0.001\ndensity = 5.0"),
        &[
            "body[1].msd = { density = 5.0, node_mass = 0.001 }",
            "exactly one",
        ],
    );
    assert_eq!(err.key(), Some("body[1].msd"));
}

#[test]
fn neither_density_nor_node_mass() {
    expect_err(
        &good_with("node_mass = 0.001\n", ""),
        &["body[1].msd", "exactly one"],
    );
}

#[test]
fn bad_enum_string() {
    let text = good_with("integrator = \"rk4\"", "integrator = \"rk5\"");
    let err = expect_err(
        &text,
        &["body[1].msd.integrator", "rk5", "symplectic-euler"],
    );
    assert_eq!(err.line(), Some(line_of(&text, "rk5")));
    expect_err(
        &good_with("importance = \"important\"", "importance = \"vital\""),
        &["body[0].importance", "vital"],
    );
}

#[test]
fn wrong_type() {
    expect_err(
        &good_with("young = 600.0", "young = \"600\""),
        &["body[0].fem.young", "600"],
    );
    expect_err(
        &good_with("gravity = [0.0, -9.81, 0.0]", "gravity = [0.0, -9.81]"),
        &["scene.gravity", "length 2"],
    );
}

#[test]
fn missing_required_key() {
    expect_err(
        &good_with("dt = 0.02\n", ""),
        &["body[0].fem", "missing field `dt`"],
    );
}

#[test]
fn toml_syntax_error_keeps_line_and_column() {
    let text = good_with("damping = 1.0", "damping = = 1.0");
    let line = line_of(&text, "damping = = 1.0");
    let err = expect_err(&text, &[&format!("line {line}"), "column"]);
    assert!(matches!(err, ConfigError::Syntax { .. }));
    assert_eq!(err.line(), Some(line));
}

#[test]
fn duplicate_key_is_a_syntax_error() {
    let text = good_with("young = 600.0", "young = 600.0\nyoung = 700.0");
    expect_err(&text, &["young", "line"]);
}

#[test]
fn no_bodies() {
    expect_err("[scene]\nname = \"empty\"\n", &["body", "at least one"]);
    expect_err("", &["body", "at least one"]);
}

#[test]
fn out_of_range_odds_and_ends() {
    expect_err(
        &good_with("dt = 0.02", "dt = 20.0"),
        &["body[0].fem.dt", "20.0", "seconds"],
    );
    expect_err(
        &good_with("dt = 0.02", "dt = 0.0"),
        &["body[0].fem.dt", "0.0"],
    );
    expect_err(
        &good_with(
            "mesh = \"m\"\n\n[body.msd]",
            "mesh = \"m\"\ncolor = [1.0, 2.0, 0.0]\n\n[body.msd]",
        ),
        &["body[1].color", "2.0"],
    );
    expect_err(
        &format!("[rates]\nhaptic_hz = 50.0\n{GOOD}"),
        &["rates.haptic_hz", "50.0", "100"],
    );
    expect_err(
        &format!("[tool]\nradius = -0.001\n{GOOD}"),
        &["tool.radius", "-0.001"],
    );
    expect_err(
        &format!("[workspace]\nscale = 0.0\n{GOOD}"),
        &["workspace.scale", "0.0"],
    );
    expect_err(
        &format!("[workspace]\noffset = [0.0, nan, 0.0]\n{GOOD}"),
        &["workspace.offset", "[0.0, nan, 0.0]"],
    );
    expect_err(
        &good_with("gravity = [0.0, -9.81, 0.0]", "gravity = [0.0, -inf, 0.0]"),
        &["scene.gravity", "-inf"],
    );
    expect_err(
        &good_with(
            "mesh = \"m\"\n\n[body.msd]",
            "mesh = \"m\"\nfixed_nodes = [1, -2]\n\n[body.msd]",
        ),
        &["body[1].fixed_nodes", "-2"],
    );
}

/// `GOOD` with a `[body.heat]` table holding `line` added to the second body.
fn with_body_heat(line: &str) -> String {
    good_with(
        "integrator = \"rk4\"\n",
        &format!("integrator = \"rk4\"\n\n[body.heat]\n{line}\n"),
    )
}

#[test]
fn heat_keys_out_of_range() {
    let err = expect_err(
        &with_body_heat("conductivity = nan"),
        &["body[1].heat.conductivity", "nan", "body \"b\"", "W/m/K"],
    );
    assert_eq!(err.key(), Some("body[1].heat.conductivity"));
    let text = with_body_heat("specific_heat = 0.0");
    let err = expect_err(&text, &["body[1].heat.specific_heat", "0.0", "J/kg/K"]);
    assert_eq!(err.line(), Some(line_of(&text, "specific_heat = 0.0")));
    expect_err(
        &with_body_heat("density = -1060.0"),
        &["body[1].heat.density", "-1060.0"],
    );
    expect_err(
        &with_body_heat("initial = 2000.0"),
        &["body[1].heat.initial", "2000.0", "°C"],
    );
    expect_err(
        &with_body_heat("initial = -300.0"),
        &["body[1].heat.initial", "-300.0", "-273.15"],
    );
    expect_err(
        &with_body_heat("coagulation = 30.0"),
        &[
            "body[1].heat.coagulation",
            "30.0",
            "above the initial temperature (37.0 °C)",
        ],
    );
    expect_err(
        &with_body_heat("coagulation = inf"),
        &["body[1].heat.coagulation", "inf"],
    );
    expect_err(
        &with_body_heat("burn_stiffening = 0.0"),
        &["body[1].heat.burn_stiffening", "0.0"],
    );
    expect_err(
        &with_body_heat("conductivty = 0.5"),
        &["body[1].heat", "conductivty", "unknown field"],
    );
    expect_err(
        &format!("[heat]\nair_temperature = nan\n{GOOD}"),
        &["heat.air_temperature", "nan", "°C"],
    );
    let text = format!("[heat]\nair_coefficient = -10.0\n{GOOD}");
    let err = expect_err(&text, &["heat.air_coefficient", "-10.0", "W/m²/K"]);
    assert_eq!(err.line(), Some(2));
    expect_err(
        &format!("[heat]\ncontact_conductance = -inf\n{GOOD}"),
        &["heat.contact_conductance", "-inf"],
    );
    expect_err(
        &format!("[heat]\ndt = 10.0\n{GOOD}"),
        &["heat.dt", "10.0", "seconds"],
    );
    expect_err(
        &format!("[heat]\npower = 20.0\n{GOOD}"),
        &["heat", "power", "unknown field"],
    );
}

/// Every prefix of a valid scene, and many byte-mangled variants, load or fail without
/// panicking.
#[test]
fn never_panics_on_mangled_input() {
    let path = scene_path();
    for end in (0..=GOOD.len()).filter(|i| GOOD.is_char_boundary(*i)) {
        let _ = parse_scene(&GOOD[..end], &path);
    }
    // Replace single bytes with TOML-significant characters, at seeded places.
    let specials = b"[]{}=\"'.,#\n -0123456789eEnaif";
    let mut rng = Rng::new(0x2545_f491_4f6c_dd1d);
    for _ in 0..3000 {
        let mut bytes = GOOD.as_bytes().to_vec();
        for _ in 0..3 {
            let i = rng.below(bytes.len());
            bytes[i] = rng.pick(specials);
        }
        if let Ok(text) = String::from_utf8(bytes) {
            if let Err(e) = parse_scene(&text, &path) {
                // Formatting the message must not panic either.
                let _ = e.to_string();
            }
        }
    }
}

#[test]
fn collision_keys_out_of_range() {
    let text = format!("[collision]\nstiffness = -5.0\n\n{GOOD}");
    let err = expect_err(&text, &["collision.stiffness", "-5", "N/m"]);
    assert_eq!(err.line(), Some(line_of(&text, "stiffness = -5.0")));
    let text = format!("[collision]\nskin = 0.5\n\n{GOOD}");
    expect_err(&text, &["collision.skin", "0.5", "at most 0.01"]);
    let text = format!("[collision]\ninterval = -0.01\n\n{GOOD}");
    expect_err(&text, &["collision.interval", "-0.01"]);
    let text = format!("[collision]\ninterval = 2.0\n\n{GOOD}");
    expect_err(&text, &["collision.interval", "2", "at most 1"]);
    let text = format!("[collision]\ninterval = nan\n\n{GOOD}");
    expect_err(&text, &["collision.interval", "nan", "finite"]);
    let text = format!("[collision]\nenabled = \"yes\"\n\n{GOOD}");
    expect_err(&text, &["enabled"]);
    let scene = parse_scene(
        &format!("[collision]\nenabled = false\n\n{GOOD}"),
        &scene_path(),
    )
    .unwrap();
    assert!(!scene.collision.enabled);
    assert_eq!(scene.collision.stiffness, 20.0);
}

#[test]
fn tool_radius_and_stiffness_missing_zero_negative_or_nan() {
    let tool = |radius: &str, stiffness: &str| {
        let mut t = String::from("[tool]\n");
        if !radius.is_empty() {
            t += &format!("radius = {radius}\n");
        }
        if !stiffness.is_empty() {
            t += &format!("stiffness = {stiffness}\n");
        }
        format!("{t}{GOOD}")
    };
    for bad in ["", "0.0", "-0.003", "nan", "inf"] {
        let value = if bad.is_empty() { "(missing)" } else { bad };
        expect_err(&tool(bad, "300.0"), &["tool.radius", value]);
        expect_err(&tool("0.003", bad), &["tool.stiffness", value]);
    }
    // The quadratic law has its own unit: the message says which.
    expect_err(
        &format!("[tool]\nradius = 0.003\nforce_law = \"quadratic\"\n{GOOD}"),
        &["tool.stiffness", "(missing)", "N/m²"],
    );
    // Friction is not modelled (the tip is frictionless): the key is refused, not ignored.
    expect_err(
        &format!("[tool]\nradius = 0.003\nstiffness = 300.0\nfriction = 0.3\n{GOOD}"),
        &["friction"],
    );
    // Per-body contact stiffness against the tool.
    for bad in ["0.0", "-1.0", "nan"] {
        expect_err(
            &good_with(
                "importance = \"important\"",
                &format!("importance = \"important\"\ntool_stiffness = {bad}"),
            ),
            &["body[0].tool_stiffness", bad],
        );
    }
    // Without a [tool] section the scene gets the default tool.
    let scene = lop_config::parse_scene(GOOD, &scene_path()).unwrap();
    assert_eq!(scene.tool(), &lop_config::ToolSpec::default());
}

/// `[cut]` and a body's `cut`: bad values are refused naming the key, and a body pinned to its
/// cage cannot be cut.
#[test]
fn cutting_keys_are_checked() {
    let scene = parse_scene(GOOD, &scene_path()).unwrap();
    assert_eq!(scene.cut, lop_config::CutSpec::default());
    assert!(scene.bodies.iter().all(|b| !b.cut));
    let with_cut = format!("[cut]\nvaporization = 110.0\ndelay_steps = 20\n{GOOD}");
    let scene = parse_scene(&with_cut, &scene_path()).unwrap();
    assert_eq!((scene.cut.vaporization, scene.cut.delay_steps), (110.0, 20));
    expect_err(
        &format!("[cut]\ndelay_steps = 0\n{GOOD}"),
        &["cut.delay_steps", "0", "1 to 1000"],
    );
    expect_err(
        &format!("[cut]\nvaporization = -300.0\n{GOOD}"),
        &["cut.vaporization", "-300"],
    );
    let cut_body = good_with(
        "name = \"b\"\nmesh = \"m\"\n",
        "name = \"b\"\nmesh = \"m\"\ncut = true\n",
    );
    let scene = parse_scene(&cut_body, &scene_path()).unwrap();
    assert!(scene.bodies[1].cut);
    expect_err(
        &good_with(
            "name = \"b\"\nmesh = \"m\"\n",
            "name = \"b\"\nmesh = \"m\"\ncut = true\nmodel = \"gc\"\n[body.gc]\ndynamics = \"projected\"\n",
        ),
        &["body[1].cut", "true", "cannot be cut"],
    );
}
