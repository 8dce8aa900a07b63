//! The soak's mock scripts: the scene's four shipped scripts (`poke`, `grab`, `heat`, `drag`)
//! played one after the other in a loop, and the device's planned broken samples as `[[fault]]`
//! windows. With two devices the second plays the same four starting from the second
//! (`grab`, `heat`, `drag`, `poke`): the loops are equally long, and each script presses the
//! tissue from about 1 s to 3.5 s after it starts, so the two tools are in the tissue at the
//! same time for much of the loop (each in its own script's way), and a haptic fault often
//! catches both there.
//!
//! Each shipped script is an `end = "loop"` script, so it starts and ends at the same rest point,
//! which its authors placed in free space in front of the tissue (`config/scripts/*.toml` say
//! where and why). Between two scripts the tool moves in a straight line from one rest point to
//! the next in [`TRANSIT_S`]; on the shipped scenes the rest points are a few millimetres apart
//! at the same distance from the tissue, so the transit touches nothing.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result};
use lop_drivers::mock::{MockScript, SampleFault, Waypoint};

use super::schedule::{SampleEvent, Schedule};

/// The shipped scripts the soak plays, in the first device's order.
pub const PARTS: [&str; 4] = ["poke", "grab", "heat", "drag"];

/// The order in which device `device` plays [`PARTS`]: the first device's order started
/// `device` scripts later.
pub fn order(device: usize) -> [&'static str; 4] {
    std::array::from_fn(|i| PARTS[(i + device) % PARTS.len()])
}

/// Seconds from one script's rest point to the next one's.
pub const TRANSIT_S: f64 = 1.0;

/// The soak script's text and what it is made of.
pub struct SoakScript {
    /// The TOML text.
    pub text: String,
    /// The shipped scripts played, in order.
    pub parts: Vec<PathBuf>,
    /// One loop of the waypoints, s.
    pub period_s: f64,
}

fn buttons(bits: u32) -> String {
    let mut names = Vec::new();
    if bits & lop_drivers::BUTTON_GRAB != 0 {
        names.push("\"grab\"");
    }
    if bits & lop_drivers::BUTTON_HEAT != 0 {
        names.push("\"heat\"");
    }
    format!("[{}]", names.join(", "))
}

fn waypoint(out: &mut String, t: f64, w: &Waypoint) {
    let [x, y, z] = w.position_mm;
    let _ = writeln!(
        out,
        "\n[[waypoint]]\nt = {t:?}\nposition = [{x:?}, {y:?}, {z:?}]\nbuttons = {}",
        buttons(w.buttons)
    );
}

/// Builds the script of device `device` (its parts in [`order`]) for scene `scene` (a shipped
/// scene name: its scripts are `SCENE-poke` … `SCENE-drag`) with the broken samples of
/// `samples` at `rate_hz`.
pub fn build(
    scene: &str,
    device: usize,
    samples: &[SampleEvent],
    rate_hz: f64,
) -> Result<SoakScript> {
    let mut parts = Vec::new();
    let mut scripts = Vec::new();
    let order = order(device);
    for part in order {
        let name = format!("{scene}-{part}");
        let path = lop_config::resolve_script(&name).with_context(|| {
            format!(
                "the soak plays the scene's shipped scripts {}: {name} is missing (a soak \
                 runs on a shipped scene: abdomen, organs, beam or cylinders)",
                PARTS.map(|p| format!("{scene}-{p}")).join(", ")
            )
        })?;
        let script = MockScript::load(&path)?;
        parts.push(path);
        scripts.push(script);
    }

    let mut text = format!(
        "# Written by `lop-bench soak`: {} in a loop, {TRANSIT_S} s between two, and the\n\
         # planned broken samples of device {device}.\nname = \"soak\"\nend = \"loop\"\n\
         interpolation = \"smooth\"\n",
        order.map(|p| format!("{scene}-{p}")).join(", ")
    );
    let mut t0 = 0.0;
    let first = scripts[0].waypoints()[0];
    for script in &scripts {
        let wps = script.waypoints();
        for (i, w) in wps.iter().enumerate() {
            // A part's first waypoint is where the transit into it ends (the previous part's
            // last waypoint is its rest point, written already).
            if i == 0 && t0 > 0.0 {
                t0 += TRANSIT_S;
            }
            waypoint(&mut text, t0 + w.t, w);
        }
        t0 += script.duration();
    }
    // Back to the first rest point, so the loop closes.
    t0 += TRANSIT_S;
    waypoint(&mut text, t0, &first);

    for e in samples {
        let (from, until) = Schedule::window_s(e, rate_hz);
        let kind = match e.fault {
            SampleFault::Nan => "nan",
            SampleFault::OutOfWorkspace => "out_of_workspace",
        };
        let _ = writeln!(
            text,
            "\n[[fault]]\nfrom = {from:?}\nuntil = {until:?}\nsample = \"{kind}\""
        );
    }
    Ok(SoakScript {
        text,
        parts,
        period_s: t0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn the_abdomen_soak_script_loads_loops_and_holds_the_planned_faults() {
        let schedule = Schedule::draw(3, 60.0, 1000.0, 1);
        let samples = &schedule.samples[0];
        let s = build("abdomen", 0, samples, 1000.0).unwrap();
        let script = MockScript::parse(&s.text, Path::new("soak.toml")).unwrap();
        assert_eq!(script.duration(), s.period_s);
        let total: f64 = s
            .parts
            .iter()
            .map(|p| MockScript::load(p).unwrap().duration())
            .sum();
        assert!((s.period_s - total - PARTS.len() as f64 * TRANSIT_S).abs() < 1e-9);
        // Every planned tick reads a broken sample, and its neighbours do not.
        assert_eq!(script.sample_faults().len(), samples.len());
        for e in samples {
            let at = |k: u64| script.sample_fault_at(k as f64 / 1000.0);
            assert_eq!(at(e.first_tick), Some(e.fault));
            assert_eq!(at(e.first_tick + e.ticks - 1), Some(e.fault));
            assert_eq!(at(e.first_tick - 1), None);
            assert_eq!(at(e.first_tick + e.ticks), None);
        }
        // The buttons of the parts are kept: grab and heat are pressed somewhere in the loop.
        let pressed = script.waypoints().iter().fold(0, |acc, w| acc | w.buttons);
        assert_eq!(pressed, lop_drivers::BUTTON_GRAB | lop_drivers::BUTTON_HEAT);
    }

    #[test]
    fn the_second_device_plays_the_same_loop_from_its_second_script() {
        let first = build("abdomen", 0, &[], 1000.0).unwrap();
        let second = build("abdomen", 1, &[], 1000.0).unwrap();
        assert_eq!(second.parts[..3], first.parts[1..]);
        assert_eq!(second.parts[3], first.parts[0]);
        assert!((second.period_s - first.period_s).abs() < 1e-9);
        let a = MockScript::parse(&first.text, Path::new("a.toml")).unwrap();
        let b = MockScript::parse(&second.text, Path::new("b.toml")).unwrap();
        assert_ne!(a.waypoints()[2].position_mm, b.waypoints()[2].position_mm);
    }

    #[test]
    fn a_scene_without_the_four_scripts_is_refused_by_name() {
        let e = build("nosuchscene", 0, &[], 1000.0).err().unwrap();
        assert!(format!("{e:#}").contains("nosuchscene-poke"), "{e:#}");
    }
}
