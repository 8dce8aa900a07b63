//! `lop-tunnel`'s command line: the version lopd checks, and bad input named. (The tunnel
//! carrying a scene between two iceoryx2 domains is `tests/tests/remote.rs`.)

use std::process::Command;

const TUNNEL: &str = env!("CARGO_BIN_EXE_lop-tunnel");

fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(TUNNEL)
        .args(args)
        .output()
        .expect("lop-tunnel runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn its_version_ends_with_the_iceoryx2_version_lopd_checks() {
    let (code, out, err) = run(&["--version"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(
        out.split_whitespace().last(),
        Some(lop_ipc::ICEORYX2_VERSION),
        "{out}"
    );
    assert!(out.starts_with("lop-tunnel "), "{out}");
}

#[test]
fn bad_input_is_named() {
    let (code, _, err) = run(&["--poll", "0"]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("--poll 0"), "{err}");

    let dir = std::env::temp_dir().join(format!("lop-tunnel-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let missing = dir.join("no-such-zenoh.json5");
    let (code, _, err) = run(&["--zenoh-config", missing.to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains(&format!("the Zenoh config {}", missing.display())),
        "{err}"
    );
    let broken = dir.join("broken.json5");
    std::fs::write(
        &broken,
        "{ mode: \"peer\", listen: { endpoints: [\"tcp/nowhere\"] }",
    )
    .unwrap();
    let (code, _, err) = run(&["--zenoh-config", broken.to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("broken.json5"), "{err}");

    let (code, _, err) = run(&["--allow"]);
    assert_eq!(code, 2, "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
