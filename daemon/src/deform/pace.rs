//! The deformation process's pace at load: each FEM body's starting period, from a touch
//! rehearsed on it, and the warning for a body that cannot keep real time at any period.

use lop_config::Scene;
use lop_scene::ToolLaws;
use lop_sim::fem::{FemError, RefactorPolicy};
use lop_sim::world::pace::{Pace, FIT, STAY};
use lop_sim::world::World;

use crate::rt;

/// Steps from asking for a new period's factor to stepping with it (the factor is made on the
/// body's factor thread meanwhile): long enough for the liver's factor at 1 ms steps, short
/// enough that a body falling behind is helped within a few dozen milliseconds.
pub(super) const PERIOD_CHANGE_DELAY_STEPS: u32 = 16;
/// Factorisations timed at load; their median is the body's factor cost.
const FACTOR_TIMINGS: usize = 3;
/// Steps timed at load to estimate a body's step cost from rest (after two untimed ones).
const ESTIMATE_STEPS: usize = 8;
/// The touch rehearsed at load ([`World::rehearse_touch`]): how far past the surface the device
/// goes (m; with the shipped tool's 300 N/m, 0.6 N on a surface that does not give), the
/// steps left untimed (the contact forming: the patch's first columns, the rotations starting
/// cold) and the steps timed. 50 steps: 40 mm/s at 1 ms; a 20k organ's 50 steps of ~10 ms
/// add half a second to its load.
const REHEARSAL_DEPTH: f64 = 0.002;
const REHEARSAL_WARM: usize = 20;
const REHEARSAL_TIMED: usize = 30;

/// Gives every body with an FEM model (running, or parked behind its levels-of-precision
/// controller) a pace that may lengthen its period up to `max_period_ms`. The pace starts at
/// the period a touched step's cost allows, from a touch rehearsed now with the first tool's
/// law against the body ([`World::rehearse_touch`]: the body poked by the god-object's patch
/// for 50 steps, then back at rest). A step from rest is 3–8 times cheaper than a touched
/// step on the organs a lab brings (measured on the recipe's 2k–10k organs), so a pace
/// started from it started every 5k organ at 1 ms and lost time at its first touch until its
/// window moved it; both figures are logged. A body that cannot keep real time even at the
/// longest period is warned about with the period it would need.
///
/// With two or more deformation threads (`threads`, a machine of three cores or more) the body
/// also gets the factor thread that makes a new period's factor off the critical path
/// ([`RefactorPolicy::Background`]). With one, a period change factorises within one step and
/// the body takes the policy of its period ([`set_period`]: real-time at the haptic rate,
/// amortized beyond): measured on the 2-core machine, the factor thread sharing the
/// deformation core with the steps made the shipped liver's touched step dearer (median 0.76
/// → 1.1–1.2 ms) and its poke's peak force 1.25–1.69 N instead of 0.71 N, every run, without
/// any change of period — it refactorises whenever CG stalls, and each factor takes the step's
/// core for milliseconds.
pub(super) fn pace_bodies(
    world: &mut World,
    scene: &Scene,
    laws: &ToolLaws,
    max_period_ms: u32,
    threads: usize,
) -> Vec<Option<Paced>> {
    let longest = f64::from(max_period_ms) * 1e-3;
    let gravity = world.gravity;
    (0..world.bodies.len())
        .map(|i| {
            let name = world.bodies[i].name.clone();
            let fem = world.fem_mut(i)?;
            let base = fem.dt();
            let mut pace = Pace::new(base, longest);
            if pace.periods().len() == 1 {
                return Some(Paced {
                    pace,
                    factor_cost: None,
                });
            }
            // A body with the factor thread keeps its policy at every period: no need to know
            // what a factorisation costs.
            let factor_cost = if threads >= 2 {
                fem.set_refactor_policy(RefactorPolicy::Background {
                    delay_steps: PERIOD_CHANGE_DELAY_STEPS,
                });
                None
            } else {
                Some(time_factor(fem))
            };
            let rest = estimate_step(fem, gravity);
            let law = laws.bodies.get(i).copied().unwrap_or(laws.tool);
            let touched = world
                .rehearse_touch(
                    i,
                    law,
                    REHEARSAL_DEPTH,
                    REHEARSAL_WARM,
                    REHEARSAL_TIMED,
                    &mut rt::now_ns,
                )
                .map(|r| r.median());
            let cost = touched.unwrap_or(rest).max(rest);
            let period = pace.start_at(cost);
            if cost > STAY * longest {
                warn_behind(&name, cost, longest);
            }
            match touched {
                Some(t) => tracing::info!(
                    "{name}: a touched step costs about {:.2} ms here (a rehearsed poke; \
                     {:.2} ms from rest{}); it starts at {} ms",
                    t * 1e3,
                    rest * 1e3,
                    factor_cost.map_or(String::new(), |f| format!(
                        ", a factorisation {:.1} ms",
                        f * 1e3
                    )),
                    period * 1e3
                ),
                None => tracing::info!(
                    "{name}: a step from rest costs about {:.2} ms here (no touch rehearsed: \
                     no surface triangle with all its nodes free); it starts at {} ms",
                    rest * 1e3,
                    period * 1e3
                ),
            }
            if period != base {
                if let Err(e) = set_period(world, scene, i, period, factor_cost) {
                    tracing::warn!("{name}: period not changed: {e}");
                }
            }
            Some(Paced { pace, factor_cost })
        })
        .collect()
}

/// A body's pace and what a factorisation of its system costs here (s, timed at load; `None`
/// for a body with the factor thread or a pace that never changes its period).
pub(super) struct Paced {
    pub(super) pace: Pace,
    pub(super) factor_cost: Option<f64>,
}

/// Body `i`'s FEM model to period `period` (s), with the refactor policy of that period given
/// what a factorisation of its system costs here (`factor_cost`, s;
/// [`lop_scene::refactor_policy`]: real-time at the haptic rate, and beyond it amortized when
/// a factorisation costs at most one period, else real-time), unless it has the factor thread
/// ([`RefactorPolicy::Background`], kept at every period).
///
/// The real-time policy (a new factor only when CG fails to converge) kept at a longer
/// period lets the factor go stale as the stiffness's share of the system grows. Measured
/// on the shipped two-handed scene's liver, grabbed and retracted (`lopd simulate --device
/// mock --device mock`, the liver's period set in the scene; medians by phase of the
/// script): at 5 ms a step took 2.2–3.5 ms (14–21 CG iterations, no factorisation) under
/// the real-time policy against 1.1–1.5 ms (4.2–4.6 iterations, a factorisation every
/// 11–17 steps) under the amortized one; at 2 ms 1.7–2.1 ms against 1.0–1.1 ms. Live, its
/// pace moved it 1 → 2 → 4 → 5 → 10 ms within a second of the grab. But a factorisation
/// within a step is a spike of its cost: the recipe's 5k organs factorise in 6–12 ms and
/// its 10k organs in 14–61 ms (release, this 2-core machine), and with the amortized policy
/// at every longer period `lop-bench organs --sizes 5000,10000 --surfaces liver,kidney
/// --threads 1` gave step p99 11.5 ms against 3.4 (kidney-5000), 17.5 against 5.6
/// (liver-10000) and 36.8 against 9.2 (kidney-10000), real-time factors 0.83–0.93.
///
/// # Errors
/// A period that is not finite and positive.
pub(super) fn set_period(
    world: &mut World,
    scene: &Scene,
    i: usize,
    period: f64,
    factor_cost: Option<f64>,
) -> Result<(), FemError> {
    let Some(fem) = world.fem_mut(i) else {
        return Ok(());
    };
    if !matches!(fem.refactor_policy(), RefactorPolicy::Background { .. }) {
        fem.set_refactor_policy(lop_scene::refactor_policy(scene, period, factor_cost));
    }
    fem.set_dt(period)
}

/// The median wall time of [`FACTOR_TIMINGS`] factorisations of `fem`'s system at rest, s.
fn time_factor(fem: &mut lop_sim::fem::Fem) -> f64 {
    let mut t = [0.0; FACTOR_TIMINGS];
    for s in &mut t {
        let start = rt::now_ns();
        fem.refactorize_at_rest();
        *s = rt::now_ns().saturating_sub(start) as f64 * 1e-9;
    }
    t.sort_by(f64::total_cmp);
    t[FACTOR_TIMINGS / 2]
}

/// Warns that body `name`, whose touched step costs `cost` (s), falls behind the wall clock even
/// at the longest period `longest` (s), and what to do about it: at load from the estimate, live
/// from the steps in contact.
pub(super) fn warn_behind(name: &str, cost: f64, longest: f64) {
    tracing::warn!(
        "{name}: a step costs about {:.1} ms on this machine, more than the longest period \
         ({} ms): it falls behind the wall clock while touched (it needs about {:.0} ms). Mesh \
         it coarser (lopd mesh tetrahedralize --tets N) or raise [deform] max_period_ms",
        cost * 1e3,
        longest * 1e3,
        (cost / FIT * 1e3).ceil()
    );
}

/// The median wall time of a step of `fem` from rest under `gravity`, s; `fem` is back at rest
/// afterwards. From rest, without the tool: the cheapest step the body takes.
fn estimate_step(fem: &mut lop_sim::fem::Fem, gravity: [f64; 3]) -> f64 {
    let mut costs = [0.0f64; ESTIMATE_STEPS];
    for k in 0..ESTIMATE_STEPS + 2 {
        let t0 = rt::now_ns();
        let _ = fem.step(gravity, &[], None);
        if k >= 2 {
            costs[k - 2] = (rt::now_ns() - t0) as f64 * 1e-9;
        }
    }
    fem.reset();
    costs.sort_by(f64::total_cmp);
    costs[ESTIMATE_STEPS / 2]
}
