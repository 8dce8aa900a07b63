//! Several tools in a scene: `[[tool]]` tables, each with its name, kind, law, workspace and
//! script; one `[tool]` table as before; bad tool tables refused naming the table and the key.

use crate::common;

use common::{line_of, scene_path, GOOD};
use lop_config::{parse_scene, ForceLaw, ToolKind, WorkspaceMap};

const TWO_HANDS: &str = r#"
[[tool]]
name = "grasper"
radius = 0.004
stiffness = 250.0
mock_script = "scripts/left.toml"
workspace = { scale = 1.5, offset = [-0.05, 0.0, 0.0] }

[[tool]]
name = "hook"
radius = 0.002
force_law = "quadratic"
stiffness = 9e4
heat_power = 30.0
"#;

#[test]
fn two_tools_each_with_their_own_law_workspace_and_script() {
    let text = format!("[workspace]\nscale = 2.0\n{TWO_HANDS}\n{GOOD}");
    let scene = parse_scene(&text, &scene_path()).unwrap();
    assert_eq!(scene.tools.len(), 2);
    let [grasper, hook] = [&scene.tools[0], &scene.tools[1]];
    assert_eq!(grasper.name, "grasper");
    assert_eq!((grasper.radius, grasper.stiffness), (0.004, 250.0));
    assert_eq!(grasper.workspace.scale, 1.5);
    assert_eq!(grasper.workspace.offset, [-0.05, 0.0, 0.0]);
    let dir = scene_path().parent().unwrap().to_path_buf();
    let dir = std::path::absolute(&dir).unwrap();
    assert_eq!(
        grasper.mock_script.as_deref(),
        Some(dir.join("scripts/left.toml").as_path())
    );
    assert_eq!(hook.name, "hook");
    assert_eq!(hook.force_law, ForceLaw::Quadratic);
    assert_eq!(hook.heat_power, 30.0);
    // Without its own, a tool maps its device with the scene's [workspace].
    assert_eq!(
        hook.workspace,
        WorkspaceMap {
            scale: 2.0,
            ..WorkspaceMap::default()
        }
    );
    assert_eq!(hook.mock_script, None);
    assert_eq!(scene.tool(), grasper);
    assert_eq!(scene.tool_script(1), None);
}

#[test]
fn one_tool_table_is_the_scene_tool_and_unnamed_tools_are_numbered() {
    let one = format!("[tool]\nradius = 0.003\nstiffness = 300.0\n{GOOD}");
    let scene = parse_scene(&one, &scene_path()).unwrap();
    assert_eq!(scene.tools.len(), 1);
    assert_eq!(scene.tool().name, "tool");
    let two = format!(
        "[[tool]]\nradius = 0.003\nstiffness = 300.0\n[[tool]]\nradius = 0.002\nstiffness = 200.0\n{GOOD}"
    );
    let scene = parse_scene(&two, &scene_path()).unwrap();
    let names: Vec<&str> = scene.tools.iter().map(|t| t.name.as_str()).collect();
    assert_eq!(names, ["tool", "tool2"]);
}

fn expect_err(text: &str, needles: &[&str]) -> lop_config::ConfigError {
    let err = parse_scene(text, &scene_path()).expect_err("a bad tool table");
    let msg = err.to_string();
    assert!(msg.contains("test-scene.toml"), "{msg}");
    for needle in needles {
        assert!(msg.contains(needle), "message lacks {needle:?}: {msg}");
    }
    err
}

#[test]
fn bad_tool_tables_are_refused_naming_the_table_and_key() {
    // A missing radius in the second table.
    let text = format!(
        "[[tool]]\nradius = 0.003\nstiffness = 300.0\n[[tool]]\nname = \"hook\"\nstiffness = 200.0\n{GOOD}"
    );
    expect_err(&text, &["tool[1].radius", "(missing)"]);
    // A bad workspace scale of one tool.
    let text = format!(
        "[[tool]]\nradius = 0.003\nstiffness = 300.0\nworkspace = {{ scale = -1.0 }}\n{GOOD}"
    );
    let err = expect_err(&text, &["tool[0].workspace.scale", "-1"]);
    assert_eq!(err.line(), Some(line_of(&text, "workspace = ")));
    // Two tools of one name.
    let text = format!(
        "[[tool]]\nname = \"hook\"\nradius = 0.003\nstiffness = 300.0\n[[tool]]\nname = \"hook\"\nradius = 0.002\nstiffness = 200.0\n{GOOD}"
    );
    expect_err(&text, &["tool[1].name", "\"hook\"", "duplicate"]);
    // More tools than a scene holds.
    let five = "[[tool]]\nradius = 0.003\nstiffness = 300.0\n".repeat(5);
    expect_err(&format!("{five}{GOOD}"), &["tool", "5 tables", "1 to 4"]);
    // An unknown key in a tool table, and a tool that is not a table.
    expect_err(
        &format!("[[tool]]\nradius = 0.003\nstiffness = 300.0\n[[tool]]\nradius = 0.003\nstiffness = 300.0\nfriction = 0.3\n{GOOD}"),
        &["tool[1]", "friction"],
    );
    expect_err(&format!("tool = 3\n{GOOD}"), &["tool", "integer"]);
    expect_err(
        &format!("[[tool]]\nradius = 0.003\nstiffness = 300.0\nmock_script = \"\"\n{GOOD}"),
        &["tool[0].mock_script"],
    );
}

#[test]
fn a_tool_kind_says_what_its_buttons_do() {
    let text = format!(
        "[[tool]]\nkind = \"grasper\"\nradius = 0.003\nstiffness = 300.0\njaw_radius = 0.005\n\
         [[tool]]\nkind = \"hook\"\nradius = 0.002\nstiffness = 300.0\nheat_power = 25.0\n\
         [[tool]]\nkind = \"grasper\"\nradius = 0.004\nstiffness = 300.0\n\
         [[tool]]\nradius = 0.003\nstiffness = 300.0\n{GOOD}"
    );
    let scene = parse_scene(&text, &scene_path()).unwrap();
    let kinds: Vec<ToolKind> = scene.tools.iter().map(|t| t.kind).collect();
    assert_eq!(
        kinds,
        [
            ToolKind::Grasper { jaw_radius: 0.005 },
            ToolKind::Hook,
            // A grasper's jaws hold what its tip covers unless told otherwise.
            ToolKind::Grasper { jaw_radius: 0.004 },
            ToolKind::Probe,
        ]
    );
    let does = |k: ToolKind| (k.holds(), k.cauterizes());
    assert_eq!(does(kinds[0]), (true, false));
    assert_eq!(does(kinds[1]), (false, true));
    assert_eq!(does(kinds[3]), (true, true));
    assert_eq!(scene.tools[1].heat_power, 25.0);
    // The one [tool] of the shipped scenes is a probe.
    let one = format!("[tool]\nradius = 0.003\nstiffness = 300.0\n{GOOD}");
    assert_eq!(
        parse_scene(&one, &scene_path()).unwrap().tool().kind,
        ToolKind::Probe
    );
}

#[test]
fn a_bad_tool_kind_is_refused_naming_it() {
    let tool =
        |extra: &str| format!("[[tool]]\nradius = 0.003\nstiffness = 300.0\n{extra}\n{GOOD}");
    let err = expect_err(
        &tool("kind = \"forceps\""),
        &["tool[0].kind", "\"forceps\"", "probe, grasper or hook"],
    );
    assert_eq!(
        err.line(),
        Some(line_of(&tool("kind = \"forceps\""), "kind = "))
    );
    expect_err(
        &tool("kind = \"blade\""),
        &["tool[0].kind", "not built yet"],
    );
    expect_err(&tool("kind = 3"), &["tool[0]", "kind"]);
    expect_err(
        &tool("jaw_radius = 0.004"),
        &["tool[0].jaw_radius", "0.004", "only a grasper", "probe"],
    );
    expect_err(
        &tool("kind = \"hook\"\njaw_radius = 0.004"),
        &["tool[0].jaw_radius", "hook"],
    );
    expect_err(
        &tool("kind = \"grasper\"\njaw_radius = -0.001"),
        &["tool[0].jaw_radius", "-0.001"],
    );
    expect_err(
        &tool("kind = \"grasper\"\nheat_power = 20.0"),
        &["tool[0].heat_power", "grasper does not cauterize"],
    );
}
