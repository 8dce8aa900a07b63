//! The deployment files in `deploy/` are usable as shipped: the rig config is a valid daemon
//! config, the systemd unit has the real-time limits, affinity, restart policy and an
//! `ExecStart` whose every flag `lopd run` accepts (and passes `systemd-analyze verify` where
//! that tool exists), the limits and udev files are well-formed.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::Command;

fn deploy(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../deploy")
        .join(name)
}

/// `[Section] → key → values` of a unit file (comments and blank lines skipped).
fn parse_unit(text: &str) -> BTreeMap<String, BTreeMap<String, Vec<String>>> {
    let mut out: BTreeMap<String, BTreeMap<String, Vec<String>>> = BTreeMap::new();
    let mut section = String::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') || line.starts_with(';') {
            continue;
        }
        if line.starts_with('[') {
            assert!(line.ends_with(']'), "line {}: {line}", i + 1);
            section = line[1..line.len() - 1].to_string();
            continue;
        }
        let (k, v) = line
            .split_once('=')
            .unwrap_or_else(|| panic!("line {}: not key=value: {line}", i + 1));
        assert!(!section.is_empty(), "line {}: key outside a section", i + 1);
        out.entry(section.clone())
            .or_default()
            .entry(k.trim().to_string())
            .or_default()
            .push(v.trim().to_string());
    }
    out
}

#[test]
fn rig_config_is_valid() {
    let c = lop_config::load_daemon_config(&deploy("lopd.toml")).unwrap();
    assert!(c.haptic.lock_memory);
    assert_eq!(c.haptic.max_force_n, 3.0);
}

#[test]
fn systemd_unit_has_rt_limits_affinity_restart_and_a_valid_command() {
    let text = std::fs::read_to_string(deploy("lopd.service")).unwrap();
    let unit = parse_unit(&text);
    assert_eq!(
        unit.keys().collect::<Vec<_>>(),
        ["Install", "Service", "Unit"]
    );
    let s = &unit["Service"];
    let one = |k: &str| {
        let v = s.get(k).unwrap_or_else(|| panic!("no {k}"));
        assert_eq!(v.len(), 1, "{k}");
        v[0].as_str()
    };
    assert_eq!(one("LimitRTPRIO"), "99");
    assert_eq!(one("LimitMEMLOCK"), "infinity");
    assert_eq!(one("Restart"), "on-failure");
    assert!(one("RestartSec").ends_with('s'));
    assert!(!one("CPUAffinity").is_empty());
    assert_eq!(one("KillSignal"), "SIGTERM");
    assert_eq!(
        one("PrivateTmp"),
        "no",
        "viewers attach through /tmp/iceoryx2"
    );
    assert_eq!(unit["Install"]["WantedBy"], ["multi-user.target"]);

    // ExecStart: lopd run with the standard config; every flag is one `lopd run` knows.
    let exec: Vec<&str> = one("ExecStart").split_whitespace().collect();
    assert_eq!(&exec[..2], ["/usr/local/bin/lopd", "run"]);
    let config = exec.iter().position(|a| *a == "--config").unwrap();
    assert_eq!(exec[config + 1], "/etc/lop/lopd.toml");
    let help = Command::new(env!("CARGO_BIN_EXE_lopd"))
        .args(["run", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    for flag in exec.iter().filter(|a| a.starts_with("--")) {
        assert!(help.contains(&format!("{flag} ")), "lopd run has no {flag}");
    }
    let pre = one("ExecStartPre");
    assert!(pre.starts_with("-/usr/local/bin/lopd doctor"), "{pre}");

    // Where systemd is installed, let it judge (with our binary in place of the install path).
    let Ok(version) = Command::new("systemd-analyze").arg("--version").output() else {
        return;
    };
    if !version.status.success() {
        return;
    }
    let dir = std::env::temp_dir().join(format!("lop-unit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let unit_path = dir.join("lopd.service");
    std::fs::write(
        &unit_path,
        text.replace("/usr/local/bin/lopd", env!("CARGO_BIN_EXE_lopd")),
    )
    .unwrap();
    let out = Command::new("systemd-analyze")
        .arg("verify")
        .arg(&unit_path)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    for line in err
        .lines()
        .filter(|l| l.contains(unit_path.to_str().unwrap()))
    {
        // Only the back-off keys of systemd >= 254 may be unknown to an older systemd.
        assert!(
            line.contains("RestartSteps") || line.contains("RestartMaxDelaySec"),
            "systemd-analyze verify: {line}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn limits_and_udev_files_are_well_formed() {
    let limits = std::fs::read_to_string(deploy("99-lop.conf")).unwrap();
    let mut items = Vec::new();
    for line in limits
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
    {
        let f: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(f.len(), 4, "{line}");
        assert_eq!((f[0], f[1]), ("@lop", "-"), "{line}");
        assert!(f[3] == "unlimited" || f[3].parse::<u32>().is_ok(), "{line}");
        items.push(f[2].to_string());
    }
    assert_eq!(items, ["rtprio", "memlock"]);

    let rules = std::fs::read_to_string(deploy("99-lop-haptics.rules")).unwrap();
    let rules: Vec<&str> = rules
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .collect();
    assert!(rules.len() >= 3);
    for r in &rules {
        assert!(
            r.contains("GROUP=\"plugdev\"") && r.contains("MODE=\"0660\""),
            "{r}"
        );
        for part in r.split(", ") {
            assert!(part.contains("==") || part.contains('='), "{r}");
        }
    }
    assert!(rules.iter().any(|r| r.contains("fw[0-9]*")));
    assert!(rules.iter().any(|r| r.contains("ttyACM[0-9]*")));
    assert!(rules
        .iter()
        .any(|r| r.contains("ATTRS{idVendor}==\"1451\"")));
}
