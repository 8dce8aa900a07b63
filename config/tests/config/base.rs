//! A scene written over another (`base = "…"`): the base's bodies and sections, this file's
//! tools, mapping, rates and device; errors name the file that has them.

use crate::common;

use common::{fixture_dir, line_of, GOOD};
use lop_config::{load_scene, parse_scene, ToolKind};

/// A directory of its own under the fixtures (the base's fake mesh beside it), with `files`
/// written into it; returns it.
fn dir_with(tag: &str, files: &[(&str, &str)]) -> std::path::PathBuf {
    let dir = fixture_dir().join(tag);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("m.node"), "4 3 0 0\n").unwrap();
    for (name, text) in files {
        std::fs::write(dir.join(name), text).unwrap();
    }
    dir
}

const TWO_TOOLS: &str = r#"base = "../base/scene.toml"

[scene]
name = "two"

[[tool]]
name = "grasper"
kind = "grasper"
radius = 0.003
stiffness = 300.0
mock_script = "left.toml"

[[tool]]
name = "hook"
kind = "hook"
radius = 0.002
stiffness = 250.0

[workspace]
scale = 1.5
"#;

#[test]
fn a_scene_over_a_base_takes_its_bodies_and_gives_its_own_tools() {
    let base_dir = dir_with("base", &[("scene.toml", GOOD)]);
    let base = load_scene(&base_dir.join("scene.toml")).unwrap();
    let dir = dir_with("over", &[("two.toml", TWO_TOOLS)]);
    let scene = load_scene(&dir.join("two.toml")).unwrap();
    assert_eq!(scene.name, "two");
    // The base's bodies (their mesh found beside the base, not beside this file), gravity,
    // rates, levels of precision, heat and collision.
    assert_eq!(scene.bodies, base.bodies);
    assert!(scene.bodies[0].mesh.starts_with(&base_dir));
    assert_eq!(scene.gravity, base.gravity);
    assert_eq!((&scene.rates, &scene.lop), (&base.rates, &base.lop));
    assert_eq!(
        (&scene.heat, &scene.collision),
        (&base.heat, &base.collision)
    );
    // This file's tools, mapped by its [workspace], their scripts beside it.
    let kinds: Vec<ToolKind> = scene.tools.iter().map(|t| t.kind).collect();
    assert_eq!(
        kinds,
        [ToolKind::Grasper { jaw_radius: 0.003 }, ToolKind::Hook]
    );
    assert!(scene.tools.iter().all(|t| t.workspace.scale == 1.5));
    assert_eq!(scene.tool_script(0), Some(dir.join("left.toml").as_path()));
    assert!(scene.path.ends_with("over/two.toml"));
}

fn expect_err(path: &std::path::Path, needles: &[&str]) -> lop_config::ConfigError {
    let err = load_scene(path).expect_err("a bad scene over a base");
    let msg = err.to_string();
    for needle in needles {
        assert!(msg.contains(needle), "message lacks {needle:?}: {msg}");
    }
    err
}

#[test]
fn a_bad_base_is_refused_naming_the_file_and_key() {
    // A base of its own: the other test writes `base/` at the same time (tests run in
    // parallel), and a file read while it is rewritten is empty.
    dir_with("base-b", &[("scene.toml", GOOD)]);
    // Bodies over a base.
    let text = format!("base = \"../base-b/scene.toml\"\n{GOOD}");
    let dir = dir_with("over-bodies", &[("s.toml", &text)]);
    let err = expect_err(&dir.join("s.toml"), &["s.toml", "body", "from the base"]);
    assert!(err.line().is_some());
    // A base that is not there.
    let dir = dir_with("over-missing", &[("s.toml", "base = \"nowhere.toml\"\n")]);
    let err = expect_err(
        &dir.join("s.toml"),
        &["s.toml", "base", "nowhere.toml", "cannot be read"],
    );
    assert_eq!(err.line(), Some(1));
    // A base that stands on itself.
    let dir = dir_with("over-self", &[("s.toml", "base = \"s.toml\"\n")]);
    expect_err(&dir.join("s.toml"), &["base", "leads back to itself"]);
    // A bad value in the base: named in the base's file, at its line.
    let bad = GOOD.replace("young = 600.0", "young = -1.0");
    let dir = dir_with(
        "over-bad-base",
        &[("base.toml", &bad), ("s.toml", "base = \"base.toml\"\n")],
    );
    let err = expect_err(&dir.join("s.toml"), &["base.toml", "young", "-1"]);
    assert_eq!(err.line(), Some(line_of(&bad, "young = ")));
    // A bad tool of this file: named here.
    let text = "base = \"../base-b/scene.toml\"\n[tool]\nradius = 0.003\nstiffness = -2.0\n";
    let dir = dir_with("over-bad-tool", &[("s.toml", text)]);
    let err = expect_err(&dir.join("s.toml"), &["s.toml", "tool.stiffness", "-2"]);
    assert_eq!(err.line(), Some(4));
    // A base in text parsed on its own resolves against the given path's directory.
    let text = "base = \"scene.toml\"\n";
    let scene = parse_scene(text, &fixture_dir().join("base-b").join("x.toml")).unwrap();
    assert_eq!(scene.name, "x");
}
