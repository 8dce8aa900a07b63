//! `--device` values parse into a `DeviceSpec`, print back to the same text, and a bad value is
//! refused with a message that quotes it and lists the accepted forms.

use std::path::PathBuf;

use lop_drivers::{DeviceSpec, DeviceSpecError};

#[test]
fn every_form_parses_and_round_trips() {
    let cases = [
        ("mock", DeviceSpec::Mock { script: None }),
        (
            "mock:beam-poke",
            DeviceSpec::Mock {
                script: Some("beam-poke".into()),
            },
        ),
        (
            "mock:/tmp/my script.toml",
            DeviceSpec::Mock {
                script: Some("/tmp/my script.toml".into()),
            },
        ),
        ("hand", DeviceSpec::Hand { script: None }),
        (
            "hand:abdomen-poke",
            DeviceSpec::Hand {
                script: Some("abdomen-poke".into()),
            },
        ),
        (
            "hand:/tmp/a b.toml",
            DeviceSpec::Hand {
                script: Some("/tmp/a b.toml".into()),
            },
        ),
        (
            "replay:runs/omni-1.csv",
            DeviceSpec::Replay {
                path: PathBuf::from("runs/omni-1.csv"),
            },
        ),
        ("openhaptics", DeviceSpec::OpenHaptics { name: None }),
        (
            "openhaptics:Default Device",
            DeviceSpec::OpenHaptics {
                name: Some("Default Device".into()),
            },
        ),
        (
            "openhaptics:left:arm",
            DeviceSpec::OpenHaptics {
                name: Some("left:arm".into()),
            },
        ),
        ("dhd", DeviceSpec::ForceDimension { id: None }),
        ("dhd:0", DeviceSpec::ForceDimension { id: Some(0) }),
        ("dhd:1", DeviceSpec::ForceDimension { id: Some(1) }),
        ("dhd:127", DeviceSpec::ForceDimension { id: Some(127) }),
    ];
    for (text, spec) in cases {
        let parsed: DeviceSpec = text.parse().unwrap();
        assert_eq!(parsed, spec, "{text}");
        assert_eq!(parsed.to_string(), text);
        assert_eq!(parsed.to_string().parse::<DeviceSpec>().unwrap(), spec);
    }
}

#[test]
fn bad_values_are_quoted_and_the_forms_listed() {
    for bad in [
        "",
        "Mock",
        "phantom",
        "replay",
        "mock:",
        "openhaptics:",
        "replay:",
        "hand:",
        "Hand",
        "dhd:",
        "DHD",
    ] {
        let error: DeviceSpecError = bad.parse::<DeviceSpec>().unwrap_err();
        assert_eq!(error.value, bad);
        let message = error.to_string();
        assert!(message.contains(&format!("`{bad}`")), "{message}");
        for form in [
            "mock:SCRIPT",
            "hand:SCRIPT",
            "replay:PATH",
            "openhaptics:NAME",
            "dhd:ID",
        ] {
            assert!(message.contains(form), "{message}");
        }
    }
}

/// A Force Dimension ID is the SDK's device index: a plain whole number the SDK can take
/// (0 to 127), written the one way that prints back the same.
#[test]
fn bad_force_dimension_ids_are_refused_with_the_reason() {
    for bad in [
        "dhd:-1", "dhd:128", "dhd:256", "dhd:one", "dhd:1.0", "dhd:+1", "dhd: 1", "dhd:01",
        "dhd:0x1", "dhd:1:2",
    ] {
        let error = bad.parse::<DeviceSpec>().unwrap_err();
        assert_eq!(error.value, bad);
        let message = error.to_string();
        assert!(message.contains(&format!("`{bad}`")), "{message}");
        assert!(
            message.contains("device index") && message.contains("0 to 127"),
            "{message}"
        );
        assert!(message.contains("lopd doctor --device dhd"), "{message}");
    }
}
