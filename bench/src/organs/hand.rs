//! The poke pressed live by the simulated hand with the light grip: `lopd run --device
//! hand:SCRIPT` on the organ's scene, the script its generated poke with a `[hand]` table of
//! [`HandParameters::light_grip`], the force log read back (the hand's log carries the grip's
//! work on the stylus, `grip_work_j`).

use std::path::Path;
use std::time::Duration;

use anyhow::{bail, Context, Result};

use lop_drivers::hand::HandParameters;

use super::{HELD_WINDOW_S, HOLD_END_S};
use crate::pipeline::{self, Lopd, LopdOptions};

/// What the hand felt live over the poke's press and hold (to [`HOLD_END_S`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct Live {
    /// The mean force over the hold's last [`HELD_WINDOW_S`], N.
    pub held_n: f64,
    /// The energy the coupling generated at the device port: how far the grip's work on the
    /// stylus fell below zero, J (0 for a passive coupling).
    pub generated_j: f64,
    /// Times the force went from zero to not zero or back: contact made or lost, as the hand
    /// feels it (a stale frame's ramp to zero counts as a loss).
    pub contact_changes: usize,
}

/// Seconds `lopd run` runs past the hold's end (the hand's clock starts with the haptic loop,
/// so the whole press and hold is in the log).
const RUN_PAST_HOLD_S: f64 = 0.5;
/// Seconds to wait for `lopd run` beyond its `--duration` before stopping it.
const EXIT_GRACE_S: f64 = 20.0;

/// Runs the poke live with the light grip on `scene` under `config` (module docs); the poke's
/// script and the force log are written in `dir` under `tag`.
pub(super) fn live(
    lopd: &Path,
    scene: &Path,
    config: &Path,
    dir: &Path,
    tag: &str,
) -> Result<Live> {
    let loaded = lop_config::load_scene(scene)
        .with_context(|| format!("loading scene {}", scene.display()))?;
    let poke =
        loaded.device.mock_script.clone().with_context(|| {
            format!("{}: no [device] mock_script to press with", scene.display())
        })?;
    let mut text =
        std::fs::read_to_string(&poke).with_context(|| format!("reading {}", poke.display()))?;
    text +=
        "\n# The light grip (lop-bench organs): nothing but the rendered force decides whether \
             the stylus rings.\n[hand]\n";
    for (key, value) in HandParameters::light_grip().entries() {
        text += &format!("{key} = {value:?}\n");
    }
    let script = dir.join(format!("{tag}-light-grip.toml"));
    std::fs::write(&script, text).with_context(|| format!("writing {}", script.display()))?;
    let log = dir.join(format!("{tag}-light-grip-forces.csv"));
    let _ = std::fs::remove_file(&log);

    let duration = HOLD_END_S + RUN_PAST_HOLD_S;
    let lopd = Lopd::spawn(&LopdOptions {
        lopd: lopd.to_path_buf(),
        scene: scene.display().to_string(),
        device: format!("hand:{}", script.display()),
        duration: Duration::from_secs_f64(duration),
        prefix: pipeline::unique_prefix(),
        extra_args: vec![
            "--config".into(),
            config.display().to_string(),
            "--force-log".into(),
            log.display().to_string(),
        ],
        log: None,
    })?;
    lopd.wait(Duration::from_secs_f64(duration + EXIT_GRACE_S))?;
    let csv = std::fs::read_to_string(&log)
        .with_context(|| format!("reading the hand's force log {}", log.display()))?;
    parse(&csv).with_context(|| format!("the hand's force log {}", log.display()))
}

/// The figures of a hand's force log (`t,fx,fy,fz,grip_work_j`).
fn parse(csv: &str) -> Result<Live> {
    let mut lines = csv.lines().enumerate();
    match lines.next() {
        Some((_, "t,fx,fy,fz,grip_work_j")) => {}
        other => bail!(
            "header {:?}, expected \"t,fx,fy,fz,grip_work_j\"",
            other.map(|o| o.1)
        ),
    }
    let (mut held_sum, mut held_count) = (0.0, 0usize);
    let (mut low_work, mut changes, mut touching) = (0.0f64, 0usize, false);
    for (i, line) in lines {
        let v: Vec<f64> = line
            .split(',')
            .map(str::parse)
            .collect::<Result<_, _>>()
            .with_context(|| format!("line {}: {line:?}", i + 1))?;
        let [t, fx, fy, fz, work] = v[..] else {
            bail!("line {}: {line:?}: expected 5 values", i + 1);
        };
        let f = (fx * fx + fy * fy + fz * fz).sqrt();
        if (HOLD_END_S - HELD_WINDOW_S..HOLD_END_S).contains(&t) {
            held_sum += f;
            held_count += 1;
        }
        if t <= HOLD_END_S {
            low_work = low_work.min(work);
            let now = f > 0.0;
            changes += usize::from(now != touching);
            touching = now;
        }
    }
    if held_count == 0 {
        bail!("no force recorded over {HOLD_END_S} s (the run ended early?)");
    }
    Ok(Live {
        held_n: held_sum / held_count as f64,
        generated_j: -low_work + 0.0,
        contact_changes: changes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_log_gives_the_held_force_the_generated_energy_and_the_contacts() {
        let csv = "t,fx,fy,fz,grip_work_j\n\
                   0.5,0,0,0,0\n\
                   1.5,0,0.3,0.4,0.002\n\
                   2.0,0,0,0,0.001\n\
                   2.5,0,0.6,0,-0.000001\n\
                   2.85,0,0,0.5,0.003\n\
                   2.95,0,0,0.7,0.003\n\
                   3.5,0,0,0,-1\n";
        let l = parse(csv).unwrap();
        assert!((l.held_n - 0.6).abs() < 1e-12, "{}", l.held_n);
        assert!((l.generated_j - 1e-6).abs() < 1e-15, "{}", l.generated_j);
        // On at 1.5, off at 2.0, on at 2.5 (after the hold's end nothing counts).
        assert_eq!(l.contact_changes, 3);
        assert!(parse("t,fx,fy,fz\n1,0,0,0\n").is_err());
        let e = parse("t,fx,fy,fz,grip_work_j\n1,0,x,0,0\n").unwrap_err();
        assert!(format!("{e:#}").contains("line 2"), "{e:#}");
        assert!(parse("t,fx,fy,fz,grip_work_j\n").is_err());
    }
}
