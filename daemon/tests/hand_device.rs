//! `--device hand`: bad scripts and `[hand]` tables are bad input (exit 2, the file and key
//! named), and `lopd run --device hand` runs the default scene end to end with the hand
//! following the scene's default poke script and feeling its force.

use std::path::PathBuf;
use std::process::Command;

fn lopd() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_lopd"));
    c.env("RUST_BACKTRACE", "0").env("LOP_LOG", "info");
    c
}

fn run(c: &mut Command) -> (i32, String) {
    let out = c.output().expect("run lopd");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lopd-hand-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn bad_hand_scripts_are_bad_input_naming_file_and_key() {
    let (code, err) = run(lopd().args(["run", "--duration", "1", "--device", "hand:no-such"]));
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("no-such"), "{err}");

    let dir = temp_dir("bad");
    let waypoint = "[[waypoint]]\nt = 0.0\nposition = [0.0, 0.0, 0.0]\n";
    for (table, needle) in [
        ("[hand]\nhand_mass = -1.0\n", "hand.hand_mass"),
        ("[hand]\nhand_mas = 1.0\n", "hand_mas"),
    ] {
        let path = dir.join("bad-hand.toml");
        std::fs::write(&path, format!("{waypoint}{table}")).unwrap();
        let device = format!("hand:{}", path.display());
        let (code, err) = run(lopd().args(["run", "--duration", "1", "--device", &device]));
        assert_eq!(code, 2, "{table}: {err}");
        assert!(
            err.contains(needle) && err.contains("bad-hand.toml"),
            "{table}: {err}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn run_with_the_hand_feels_the_default_poke() {
    let dir = temp_dir("run");
    let forces = dir.join("forces.csv");
    let prefix = format!("hand-{}", std::process::id());
    let (code, err) = run(lopd()
        .args(["run", "--device", "hand", "--duration", "2.5", "--quiet"])
        .args(["--prefix", &prefix, "--force-log"])
        .arg(&forces));
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("simulated hand following"), "{err}");
    assert!(err.contains("abdomen-poke.toml"), "{err}");
    let text = std::fs::read_to_string(&forces).unwrap();
    let magnitudes: Vec<f64> = text
        .lines()
        .skip(1)
        .map(|l| {
            // t, fx, fy, fz, grip_work_j: the force's three columns.
            l.split(',')
                .skip(1)
                .take(3)
                .map(|v| v.parse::<f64>().unwrap().powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .collect();
    assert!(magnitudes.len() > 2000, "{} forces", magnitudes.len());
    let peak = magnitudes.iter().copied().fold(0.0, f64::max);
    // The poke pushes 12 mm into the liver from 1.3 s; the hand yields, so the force stays
    // under the mock's rigid push (about 0.7 N) but is clearly there.
    assert!(peak > 0.1 && peak < 3.3, "peak {peak} N");
    // The grip's work: the hand pushed the stylus into the tissue, so it put energy in, and a
    // passive coupling never gives back more than it received.
    assert!(
        text.starts_with("t,fx,fy,fz,grip_work_j\n"),
        "{}",
        &text[..40]
    );
    let work: Vec<f64> = text
        .lines()
        .skip(1)
        .map(|l| l.rsplit(',').next().unwrap().parse().unwrap())
        .collect();
    let (low, end) = (
        work.iter().copied().fold(0.0, f64::min),
        work[work.len() - 1],
    );
    assert!(end > 1e-4, "grip work at the end {end} J");
    assert!(low > -1e-6, "grip work fell to {low} J");
    std::fs::remove_dir_all(&dir).unwrap();
}
