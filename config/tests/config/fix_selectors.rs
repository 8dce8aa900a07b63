//! `[[body.fix]]` selectors: each kind parses into its typed form; a bad value, a missing key, a
//! key of another kind or an unknown kind is refused naming the key path and the value; the
//! command-line form (`lopd mesh info --select`) takes the same syntax.

use crate::common;

use common::{scene_path, GOOD};
use lop_config::{parse_scene, parse_selector, selector_toml, NodeSelector};

/// `GOOD` with `fix` (TOML text of one or more `[[body.fix]]` tables) added to the last body.
fn with_fix(fix: &str) -> String {
    format!("{GOOD}\n{fix}\n")
}

fn expect_err(text: &str, needles: &[&str]) {
    let msg = match parse_scene(text, &scene_path()) {
        Ok(s) => panic!("expected an error, got {:#?}", s.bodies[1].fix),
        Err(e) => e.to_string(),
    };
    for n in needles {
        assert!(msg.contains(n), "message lacks {n:?}: {msg}");
    }
}

#[test]
fn every_kind_parses() {
    let text = with_fix(
        r#"[[body.fix]]
kind = "box"
min = [-0.1, -0.1, -0.1]
max = [0.1, 0.0, 0.1]

[[body.fix]]
kind = "sphere"
center = [0.0, 0.01, 0.0]
radius = 0.005

[[body.fix]]
kind = "slab"
point = [0.0, 0.0, -0.03]
normal = [0.0, 0.0, 1.0]
thickness = 0.01

[[body.fix]]
kind = "facing"
direction = [0.0, -1.0, 0.0]
within = { kind = "slab", point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }
"#,
    );
    let scene = parse_scene(&text, &scene_path()).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.bodies[0].fix.is_empty());
    let fix = &scene.bodies[1].fix;
    assert_eq!(
        fix[0],
        NodeSelector::Box {
            min: [-0.1, -0.1, -0.1],
            max: [0.1, 0.0, 0.1]
        }
    );
    assert_eq!(
        fix[1],
        NodeSelector::Sphere {
            center: [0.0, 0.01, 0.0],
            radius: 0.005
        }
    );
    assert_eq!(
        fix[2],
        NodeSelector::Slab {
            point: [0.0, 0.0, -0.03],
            normal: [0.0, 0.0, 1.0],
            thickness: Some(0.01)
        }
    );
    assert_eq!(
        fix[3],
        NodeSelector::Facing {
            direction: [0.0, -1.0, 0.0],
            angle_deg: 45.0,
            within: Some(Box::new(NodeSelector::Slab {
                point: [0.0; 3],
                normal: [0.0, 1.0, 0.0],
                thickness: None
            }))
        }
    );
    // Written back as inline tables, each parses to itself.
    for f in fix {
        assert_eq!(&parse_selector(&selector_toml(f)).unwrap(), f);
    }
}

#[test]
fn bad_values_are_refused_naming_the_key() {
    let cases: [(&str, &[&str]); 10] = [
        (
            "kind = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius = -0.01",
            &["body[1].fix[0].radius", "-0.01", "> 0", "body \"b\""],
        ),
        (
            "kind = \"sphere\"\ncenter = [0.0, nan, 0.0]\nradius = 0.01",
            &["body[1].fix[0].center", "nan"],
        ),
        (
            "kind = \"sphere\"\ncenter = [0.0, 0.0, 0.0]",
            &["body[1].fix[0].radius", "(missing)"],
        ),
        (
            "kind = \"box\"\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 0.0, 1.0]",
            &["body[1].fix[0].max", "[1.0, 0.0, 1.0]", "above min"],
        ),
        (
            "kind = \"box\"\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\nradius = 2.0",
            &["body[1].fix[0].radius", "a box selector takes min, max"],
        ),
        (
            "kind = \"slab\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 0.0]",
            &["body[1].fix[0].normal", "zero vector"],
        ),
        (
            "kind = \"slab\"\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\nthickness = 0.0",
            &["body[1].fix[0].thickness", "0.0"],
        ),
        (
            "kind = \"facing\"\ndirection = [0.0, 0.0, 1.0]\nangle_deg = 0.0",
            &["body[1].fix[0].angle_deg", "0.0", "above 0"],
        ),
        (
            "kind = \"facing\"\ndirection = [0.0, 0.0, 1.0]\nwithin = { kind = \"sphere\", center = [0.0, 0.0, 0.0], radius = nan }",
            &["body[1].fix[0].within.radius", "nan"],
        ),
        (
            "kind = \"cylinder\"\ncenter = [0.0, 0.0, 0.0]",
            &["body[1].fix[0].kind", "cylinder"],
        ),
    ];
    for (table, needles) in cases {
        expect_err(&with_fix(&format!("[[body.fix]]\n{table}")), needles);
    }
    // An unknown key is refused by name.
    expect_err(
        &with_fix("[[body.fix]]\nkind = \"sphere\"\ncentre = [0.0, 0.0, 0.0]\nradius = 0.1"),
        &["centre", "unknown field"],
    );
}

#[test]
fn command_line_form() {
    assert_eq!(
        parse_selector("kind = \"sphere\", center = [0, 0, 0.5], radius = 0.25").unwrap(),
        NodeSelector::Sphere {
            center: [0.0, 0.0, 0.5],
            radius: 0.25
        }
    );
    assert_eq!(
        parse_selector("{ kind = \"box\", min = [0, 0, 0], max = [1, 1, 1] }").unwrap(),
        NodeSelector::Box {
            min: [0.0; 3],
            max: [1.0; 3]
        }
    );
    let e = parse_selector("kind = \"sphere\", center = [0, 0, 0], radius = -1").unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("--select") && msg.contains("select.radius") && msg.contains("-1"),
        "{msg}"
    );
}
