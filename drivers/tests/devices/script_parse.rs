//! Mock scripts: every shipped script loads and stays inside the Omni workspace; interpolation
//! hits waypoints exactly, is continuous, and (smooth) stops at every waypoint; `end` wraps or
//! holds; every invalid script is refused with an error naming the file, the key and the value.

use std::path::{Path, PathBuf};

use lop_drivers::mock::{Interpolation, MockDevice, MockScript, ScriptEnd, ScriptError};
use lop_drivers::{BUTTON_CUT, BUTTON_GRAB, BUTTON_HEAT};

fn scripts_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../config/scripts")
}

fn parse(text: &str) -> Result<MockScript, ScriptError> {
    MockScript::parse(text, Path::new("test-script.toml"))
}

const POKE: &str = r#"
name = "poke"
end = "loop"
[[waypoint]]
t = 0.0
position = [0.0, 40.0, 10.0]
[[waypoint]]
t = 1.0
position = [0.0, 20.0, 10.0]
buttons = ["grab"]
[[waypoint]]
t = 1.5
position = [5.0, 20.0, 10.0]
buttons = ["grab", "heat"]
[[waypoint]]
t = 3.0
position = [0.0, 40.0, 10.0]
"#;

#[test]
fn every_shipped_script_loads_and_fits_the_omni_workspace() {
    let limits = MockDevice::omni_limits();
    let mut names: Vec<String> = std::fs::read_dir(scripts_dir())
        .expect("config/scripts exists")
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|e| e == "toml"))
        .map(|path| {
            let script = MockScript::load(&path).unwrap_or_else(|e| panic!("{e}"));
            let file = path.file_stem().unwrap().to_string_lossy().into_owned();
            assert_eq!(script.ends(), ScriptEnd::Loop, "{file}");
            assert!(
                (4.0..=8.0).contains(&script.duration()),
                "{file}: duration {}",
                script.duration()
            );
            for w in script.waypoints() {
                assert!(
                    limits.in_workspace(w.position_mm),
                    "{file}: waypoint at t = {} is outside the Omni workspace: {:?}",
                    w.t,
                    w.position_mm
                );
            }
            let pressed = script.waypoints().iter().fold(0, |acc, w| acc | w.buttons);
            // A grab script and the two-handed scene's grasper hold; a heat script and its
            // hook burn; a cut script cuts.
            let expected = match file.rsplit('-').next().unwrap() {
                "grab" | "grasper" => BUTTON_GRAB,
                "heat" | "hook" => BUTTON_HEAT,
                "cut" => BUTTON_CUT,
                _ => 0,
            };
            assert_eq!(pressed, expected, "{file}: buttons used");
            file
        })
        .collect();
    names.sort();
    let mut expected: Vec<String> = ["abdomen", "beam", "cylinders", "organs"]
        .iter()
        .flat_map(|scene| {
            ["drag", "grab", "heat", "poke"].map(|action| format!("{scene}-{action}"))
        })
        .collect();
    // The cylinders' sideways push into the other cylinder (`lop-bench lop`'s collision trial).
    expected.push("cylinders-push".into());
    // The electrosurgical cut into the abdomen's liver.
    expected.push("abdomen-cut".into());
    // The two hands of `abdomen-two-hands`.
    expected.push("abdomen-two-hands-grasper".into());
    expected.push("abdomen-two-hands-hook".into());
    expected.sort();
    assert_eq!(names, expected);
}

#[test]
fn defaults_are_smooth_and_hold_and_name_is_the_file_stem() {
    let script = MockScript::parse(
        "[[waypoint]]\nt = 0\nposition = [1, 2, 3]\n",
        Path::new("dir/still.toml"),
    )
    .unwrap();
    assert_eq!(script.name(), "still");
    assert_eq!(script.interpolation(), Interpolation::Smooth);
    assert_eq!(script.ends(), ScriptEnd::Hold);
    assert_eq!(script.duration(), 0.0);
    let sample = script.sample(12.0);
    assert_eq!(sample.position_mm, [1.0, 2.0, 3.0]);
    assert_eq!(sample.velocity_mm_s, [0.0; 3]);
}

#[test]
fn interpolation_hits_waypoints_exactly_with_their_buttons() {
    for interpolation in ["linear", "smooth"] {
        let text = format!("interpolation = \"{interpolation}\"\n{POKE}");
        let script = parse(&text).unwrap();
        for w in script.waypoints() {
            let sample = script.sample(w.t);
            let expected = if w.t == script.duration() {
                // `loop` wraps the end back onto the first waypoint (the same position).
                script.waypoints()[0]
            } else {
                *w
            };
            assert_eq!(
                sample.position_mm, expected.position_mm,
                "{interpolation} t={}",
                w.t
            );
            assert_eq!(
                sample.buttons, expected.buttons,
                "{interpolation} t={}",
                w.t
            );
        }
    }
}

#[test]
fn interpolation_is_continuous_and_velocity_is_its_derivative() {
    for interpolation in ["linear", "smooth"] {
        let script = parse(&format!("interpolation = \"{interpolation}\"\n{POKE}")).unwrap();
        let h = 1e-6;
        let mut t = 0.0;
        while t < script.duration() {
            let (a, b) = (script.sample(t), script.sample(t + h));
            for k in 0..3 {
                // Continuous: the fastest smooth segment peaks at 30 mm/s.
                assert!(
                    (b.position_mm[k] - a.position_mm[k]).abs() <= 40.0 * h,
                    "t={t}"
                );
            }
            // Away from waypoints, velocity matches a central difference of position.
            let on_waypoint = script.waypoints().iter().any(|w| (w.t - t).abs() < 1e-3);
            if !on_waypoint {
                let (before, after) = (script.sample(t - h), script.sample(t + h));
                for k in 0..3 {
                    let numeric = (after.position_mm[k] - before.position_mm[k]) / (2.0 * h);
                    assert!(
                        (numeric - a.velocity_mm_s[k]).abs() < 1e-3,
                        "{interpolation} t={t}: {numeric} vs {}",
                        a.velocity_mm_s[k]
                    );
                }
            }
            t += 0.01;
        }
    }
}

#[test]
fn smooth_interpolation_stops_at_every_waypoint() {
    let script = parse(POKE).unwrap();
    for w in script.waypoints() {
        for t in [w.t, w.t + 1e-9, (w.t - 1e-9).max(0.0)] {
            let v = script.sample(t).velocity_mm_s;
            assert!(v.iter().all(|v| v.abs() < 1e-6), "t={t}: {v:?}");
        }
    }
    // ...and moves in between.
    assert!(script.sample(0.5).velocity_mm_s[1] < -1.0);
}

#[test]
fn loop_wraps_modulo_the_duration() {
    let script = parse(POKE).unwrap();
    // Binary fractions, so `t + 3.0` wraps back to `t` exactly.
    for t in [0.0, 0.25, 1.125, 2.875] {
        assert_eq!(script.sample(t), script.sample(t + 3.0));
        assert_eq!(script.sample(t), script.sample(t + 3000.0));
    }
    assert_eq!(script.sample(3.0), script.sample(0.0));
    assert_eq!(script.sample(f64::INFINITY), script.sample(0.0));
}

#[test]
fn hold_and_stop_hold_the_last_waypoint_at_rest() {
    for end in ["hold", "stop"] {
        let text = POKE.replace("end = \"loop\"", &format!("end = \"{end}\""));
        let script = parse(&text).unwrap();
        let last = script.waypoints().last().unwrap();
        for t in [3.0, 3.5, 1e6, f64::INFINITY] {
            let sample = script.sample(t);
            assert_eq!(sample.position_mm, last.position_mm);
            assert_eq!(sample.velocity_mm_s, [0.0; 3]);
            assert_eq!(sample.buttons, last.buttons);
        }
    }
}

#[test]
fn before_the_start_is_the_first_waypoint() {
    let script = parse(POKE).unwrap();
    assert_eq!(script.sample(-1.0), script.sample(0.0));
    assert_eq!(script.sample(f64::NAN), script.sample(0.0));
}

#[test]
fn buttons_are_held_until_the_next_waypoint() {
    let script = parse(POKE).unwrap();
    assert_eq!(script.sample(0.99).buttons, 0);
    assert_eq!(script.sample(1.2).buttons, BUTTON_GRAB);
    assert_eq!(script.sample(2.0).buttons, BUTTON_GRAB | BUTTON_HEAT);
    assert!(script.sample(2.0).pressed(BUTTON_HEAT));
}

/// Asserts `text` is refused with an `Invalid` error naming `key` and `value`, and that the
/// message names the file too.
fn assert_invalid(text: &str, key: &str, value: &str) {
    let error = parse(text).expect_err("script must be refused");
    let message = error.to_string();
    assert!(message.contains("test-script.toml"), "{message}");
    match error {
        ScriptError::Invalid {
            key: k, value: v, ..
        } => {
            assert_eq!((k.as_str(), v.as_str()), (key, value), "{message}");
        }
        other => panic!("expected Invalid for {key}, got {other}"),
    }
    assert!(
        message.contains(key) && message.contains(value),
        "{message}"
    );
}

#[test]
fn non_increasing_time_names_the_key_and_value() {
    let text = POKE.replace("t = 1.5", "t = 1.0");
    assert_invalid(&text, "waypoint[2].t", "1.0");
}

#[test]
fn first_waypoint_must_be_at_zero() {
    let text = POKE.replacen("t = 0.0", "t = 0.5", 1);
    assert_invalid(&text, "waypoint[0].t", "0.5");
}

#[test]
fn nan_time_and_position_are_refused() {
    assert_invalid(&POKE.replace("t = 1.5", "t = nan"), "waypoint[2].t", "nan");
    assert_invalid(
        &POKE.replace("[5.0, 20.0, 10.0]", "[5.0, inf, 10.0]"),
        "waypoint[2].position[1]",
        "inf",
    );
    assert_invalid(
        &POKE.replace("[5.0, 20.0, 10.0]", "[5.0, 20.0, nan]"),
        "waypoint[2].position[2]",
        "nan",
    );
}

#[test]
fn position_outside_the_sanity_box_is_refused() {
    let text = POKE.replace("[5.0, 20.0, 10.0]", "[250.0, 20.0, 10.0]");
    assert_invalid(&text, "waypoint[2].position[0]", "250.0");
}

#[test]
fn unknown_button_is_refused() {
    let text = POKE.replace(r#"["grab", "heat"]"#, r#"["grab", "grap"]"#);
    assert_invalid(&text, "waypoint[2].buttons[1]", "\"grap\"");
}

#[test]
fn loop_must_end_where_it_starts() {
    let text = POKE.replace(
        "t = 3.0\nposition = [0.0, 40.0, 10.0]",
        "t = 3.0\nposition = [0.0, 41.0, 10.0]",
    );
    assert_invalid(&text, "waypoint[3].position", "[0.0, 41.0, 10.0]");
    // The same path is fine when it does not loop.
    assert!(parse(&text.replace("end = \"loop\"", "end = \"hold\"")).is_ok());
}

#[test]
fn no_waypoints_is_refused() {
    let error = parse("name = \"empty\"\n").unwrap_err();
    assert!(matches!(error, ScriptError::NoWaypoints { .. }), "{error}");
    assert!(error.to_string().contains("test-script.toml"));
}

#[test]
fn unknown_keys_and_values_are_refused_naming_them() {
    let error = parse(&POKE.replace("name = \"poke\"", "nmae = \"poke\"")).unwrap_err();
    let message = error.to_string();
    assert!(matches!(error, ScriptError::Syntax { .. }), "{message}");
    assert!(
        message.contains("test-script.toml") && message.contains("nmae"),
        "{message}"
    );

    let error = parse(&POKE.replace("t = 1.0\n", "t = 1.0\nspeed = 2\n")).unwrap_err();
    assert!(error.to_string().contains("speed"), "{error}");

    let error = parse(&POKE.replace("\"loop\"", "\"looop\"")).unwrap_err();
    assert!(error.to_string().contains("looop"), "{error}");

    let error = parse(&POKE.replace("[5.0, 20.0, 10.0]", "[5.0, 20.0]")).unwrap_err();
    assert!(matches!(error, ScriptError::Syntax { .. }), "{error}");
}

#[test]
fn fault_windows_are_validated() {
    let fault = "\n[[fault]]\nfrom = 2.0\nuntil = 1.0\nerror = \"communication\"\n";
    assert_invalid(&format!("{POKE}{fault}"), "fault[0].until", "1.0");
    let fault = "\n[[fault]]\nfrom = -1.0\nerror = \"fault\"\n";
    assert_invalid(&format!("{POKE}{fault}"), "fault[0].from", "-1.0");
    let fault = "\n[[fault]]\nfrom = 1.0\nerror = \"gremlins\"\n";
    assert!(parse(&format!("{POKE}{fault}"))
        .unwrap_err()
        .to_string()
        .contains("gremlins"));
}

#[test]
fn sample_fault_windows_are_validated() {
    use lop_drivers::mock::{SampleFault, SampleFaultWindow};
    let faults = "\n[[fault]]\nfrom = 1.0\nuntil = 1.25\nsample = \"nan\"\n\
                  [[fault]]\nfrom = 2.0\nsample = \"out_of_workspace\"\n\
                  [[fault]]\nfrom = 3.0\nerror = \"fault\"\n";
    let script = parse(&format!("{POKE}{faults}")).unwrap();
    assert_eq!(
        script.sample_faults(),
        [
            SampleFaultWindow {
                from: 1.0,
                until: 1.25,
                fault: SampleFault::Nan
            },
            SampleFaultWindow {
                from: 2.0,
                until: f64::INFINITY,
                fault: SampleFault::OutOfWorkspace
            },
        ]
    );
    assert_eq!(script.faults().len(), 1);
    assert_eq!(script.sample_fault_at(0.99), None);
    assert_eq!(script.sample_fault_at(1.0), Some(SampleFault::Nan));
    assert_eq!(script.sample_fault_at(1.25), None);
    assert_eq!(
        script.sample_fault_at(1e9),
        Some(SampleFault::OutOfWorkspace)
    );
    // The script's own samples stay finite in the windows: the device breaks them.
    assert!(script.sample(1.1).is_finite());

    let both = "\n[[fault]]\nfrom = 1.0\nerror = \"fault\"\nsample = \"nan\"\n";
    assert_invalid(&format!("{POKE}{both}"), "fault[0].sample", "\"nan\"");
    let neither = "\n[[fault]]\nfrom = 1.5\n";
    let error = parse(&format!("{POKE}{neither}")).unwrap_err();
    assert!(
        matches!(&error, ScriptError::Invalid { key, .. } if key == "fault[0]"),
        "{error}"
    );
    assert!(error.to_string().contains("from = 1.5"), "{error}");
    let window = "\n[[fault]]\nfrom = 2.0\nuntil = nan\nsample = \"nan\"\n";
    assert_invalid(&format!("{POKE}{window}"), "fault[0].until", "nan");
    let unknown = "\n[[fault]]\nfrom = 1.0\nsample = \"glitch\"\n";
    assert!(parse(&format!("{POKE}{unknown}"))
        .unwrap_err()
        .to_string()
        .contains("glitch"));
}

#[test]
fn hand_table_overrides_defaults_and_is_validated_by_key() {
    use lop_drivers::hand::HandParameters;
    assert_eq!(parse(POKE).unwrap().hand(), None);
    let script = parse(&format!(
        "{POKE}\n[hand]\nhand_stiffness = 150.0\ngrip_damping = 0.0\n"
    ))
    .unwrap();
    let expected = HandParameters {
        hand_stiffness: 150.0,
        grip_damping: 0.0,
        ..HandParameters::default()
    };
    assert_eq!(script.hand(), Some(expected));
    // An empty table is the defaults.
    assert_eq!(
        parse(&format!("{POKE}\n[hand]\n")).unwrap().hand(),
        Some(HandParameters::default())
    );
    for (line, key, value) in [
        ("hand_mass = 0.0", "hand.hand_mass", "0.0"),
        ("hand_stiffness = -300.0", "hand.hand_stiffness", "-300.0"),
        ("stylus_mass = nan", "hand.stylus_mass", "nan"),
        ("hand_damping = inf", "hand.hand_damping", "inf"),
        ("stylus_friction = -0.1", "hand.stylus_friction", "-0.1"),
        // Too light for the 10 kHz step with the default grip on it.
        ("stylus_mass = 0.00001", "hand.stylus_mass", "1e-5"),
    ] {
        assert_invalid(&format!("{POKE}\n[hand]\n{line}\n"), key, value);
    }
    let error = parse(&format!("{POKE}\n[hand]\nhand_stifness = 200.0\n")).unwrap_err();
    let message = error.to_string();
    assert!(matches!(error, ScriptError::Syntax { .. }), "{message}");
    assert!(
        message.contains("hand_stifness") && message.contains("test-script.toml"),
        "{message}"
    );
}

#[test]
fn missing_file_names_the_path() {
    let error = MockScript::load(Path::new("/nonexistent/nowhere.toml")).unwrap_err();
    assert!(matches!(error, ScriptError::Read { .. }));
    assert!(
        error.to_string().contains("/nonexistent/nowhere.toml"),
        "{error}"
    );
}

#[test]
fn resolve_script_takes_names_from_the_folder_and_paths_as_given() {
    use lop_drivers::mock::resolve_script;
    let dir = Path::new("config/scripts");
    assert_eq!(resolve_script("beam-poke", dir), dir.join("beam-poke.toml"));
    assert_eq!(resolve_script("my.toml", dir), PathBuf::from("my.toml"));
    assert_eq!(resolve_script("/tmp/x", dir), PathBuf::from("/tmp/x"));
}
