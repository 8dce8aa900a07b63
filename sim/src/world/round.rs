//! One round of the world: the straight line of stages every caller runs.
//!
//! 1. **Tool input**: per tool, the device tip, each body's tool law and who the tool touches
//!    (the nearest surface, or the god-object's anchor) arrive as arguments ([`RoundTool`]),
//!    up to [`super::MAX_TOOLS`] tools.
//! 2. **Organ collision detection** at the current shapes, once, when a body is due (and at most
//!    once per [`World::set_collision_interval`]): the contact springs hold for every step of
//!    the round, and of the rounds until the next detection.
//! 3. **The bodies that are due**, each on its own `dt`, at most [`Round::max_catch_up`] steps
//!    each, and the second and later only within the round's [`Round::budget_ns`]; on the wall
//!    clock ([`Round::drop_lag`]) a body still due after them drops the rest of its simulated
//!    time beyond [`Round::max_lag`] periods (counted as lag) rather than spiral behind.
//! 4. **Heat**: the cautery on the held point, then the heat steps that are due (at most
//!    [`MAX_HEAT_CATCH_UP`]); a failed heat step stops the heat model, never the bodies.
//!    A body's cut due at a step lands just before it ([`crate::cut`]).
//! 5. **Cuts** ([`World::set_cutting`]): a tool holding the cut button asks for the tissue the
//!    heat vaporised under its tip to be cut away; the cut is prepared on a thread of its own
//!    and lands a fixed number of the body's steps later.
//! 6. **A report** of what happened and how long each stage took ([`RoundReport`]), timed with
//!    the clock the caller passes (the physics crate reads no clock itself).
//!
//! `lopd deform` calls it once per loop iteration with the wall clock's simulated time; `lopd
//! simulate` and the benchmarks call it with simulated time alone. The same inputs give the same
//! positions, bit for bit, whoever calls. Allocation-free after the first rounds, but for the
//! rounds that ask for a cut or land one.

use super::{BodyTool, Coupling, World, MAX_TOOLS};
use crate::collide::CollisionStats;
use crate::contact::ToolSphere;
use crate::cut::CutEvent;
use crate::heat::HeatError;
use crate::model::BlowUp;

/// Most heat steps in one round; beyond that the heat model drops simulated time.
pub const MAX_HEAT_CATCH_UP: u32 = 8;

/// One tool as one round sees it.
#[derive(Debug, Clone, Copy)]
pub struct RoundTool<'a> {
    /// Device tip in the scene, m.
    pub center: [f64; 3],
    /// The tool law against each body, in body order: radius, stiffness and force law (the
    /// centre is ignored). One value per body, the same the hand feels.
    pub laws: &'a [ToolSphere],
    /// Which body the tool acts on, and where.
    pub coupling: Coupling,
    /// Cautery power delivered at the god-object's anchor this round, W: 0 with the heat button
    /// up. Heats only a touched (not grabbed) point.
    pub heat_power: f64,
    /// The cut button is held: with `heat_power`, the tissue under the tip that the heat
    /// vaporises is cut away ([`crate::cut`], once the world cuts: [`World::set_cutting`]).
    pub cut: bool,
}

/// No tools (a round without a device).
const NO_TOOLS: &[RoundTool<'static>] = &[];

impl RoundTool<'_> {
    /// The tool sphere against body `i` (its law, centred on the device tip).
    pub fn sphere(&self, i: usize) -> Option<ToolSphere> {
        self.laws.get(i).map(|law| ToolSphere {
            center: self.center,
            ..*law
        })
    }
}

/// What one round is asked to do.
#[derive(Debug, Clone, Copy)]
pub struct Round<'a> {
    /// Simulated time to advance to, s: every body steps while its next step ends by then.
    pub until: f64,
    /// Most steps one body takes in this round.
    pub max_catch_up: u32,
    /// A body still due after `max_catch_up` steps drops the rest of its simulated time (the
    /// wall-clock pace of `lopd deform`), all but `max_lag` of its periods; `false`: it stays
    /// due for the next round (`lopd simulate`, which advances on simulated time alone).
    pub drop_lag: bool,
    /// With `drop_lag`: how many of its periods a body still due after its steps may stay
    /// behind (it catches up in the rounds that follow, which its caller runs at once:
    /// [`BodyRound::due`]); the rest is dropped. 0: everything still due is dropped.
    pub max_lag: u32,
    /// A body's second and later steps are taken only while the round has run for less than
    /// this, ns (by the round's clock; 0: no limit): a body catching up publishes a frame at
    /// least this often, instead of after all its steps.
    pub budget_ns: u64,
    /// The tools, in the scene's order (empty without a device): their index is the one
    /// [`super::Body::contacts`] reports them by. At most [`MAX_TOOLS`]; the rest are ignored.
    pub tools: &'a [RoundTool<'a>],
    /// Bodies left alone this round (`lopd simulate` once a body has taken its steps); empty
    /// or shorter than the bodies: none.
    pub skip: &'a [bool],
    /// Paused: no body steps and no collision is detected (their clocks are the caller's to
    /// hold); the heat model goes on.
    pub paused: bool,
}

impl<'a> Round<'a> {
    /// A round to simulated time `until`, `max_catch_up` steps per body at most (then it drops
    /// its lag), no tool.
    pub fn to(until: f64, max_catch_up: u32) -> Round<'a> {
        Round {
            until,
            max_catch_up,
            drop_lag: true,
            max_lag: 0,
            budget_ns: 0,
            tools: NO_TOOLS,
            skip: &[],
            paused: false,
        }
    }

    /// The same round with `tools`.
    pub fn with_tools(self, tools: &'a [RoundTool<'a>]) -> Round<'a> {
        Round { tools, ..self }
    }
}

/// What one body did in a round.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BodyRound {
    /// Steps taken.
    pub steps: u32,
    /// Duration of the last step taken, ns (0 without a step).
    pub last_step_ns: u64,
    /// Duration of all its steps, ns.
    pub step_ns: u64,
    /// The last blow-up (the body was reset to rest), if any.
    pub blow_up: Option<BlowUp>,
    /// Simulated time dropped as lag this round, s: how far its clock was moved past its
    /// steps when it was still due after [`Round::max_catch_up`] of them (0 at a hand-over's
    /// join, see [`World::round`]). In live rounds, where every body is stepped to the wall
    /// clock or drops the rest, the time a body fell behind real time; a real-time meter's
    /// measure.
    pub dropped: f64,
    /// Still due after the round (behind by up to [`Round::max_lag`] periods, or on simulated
    /// time): the next round has a step for it at once.
    pub due: bool,
}

impl BodyRound {
    /// Still due after [`Round::max_catch_up`] steps, and not at a hand-over: time was
    /// dropped as lag.
    pub fn lagged(&self) -> bool {
        self.dropped > 0.0
    }
}

/// What the last round did, stage by stage.
#[derive(Debug, Clone, Default)]
pub struct RoundReport {
    /// Organ-to-organ detection, if it ran (collision on and a body due).
    pub collisions: Option<CollisionStats>,
    /// Whether detection ran this round (collision on and a body due).
    pub detected: bool,
    /// Detection time, ns.
    pub collision_ns: u64,
    /// Per body, in body order.
    pub bodies: Vec<BodyRound>,
    /// Heat steps taken.
    pub heat_steps: u32,
    /// Heat time (sources and steps), ns.
    pub heat_ns: u64,
    /// The heat model failed in this round (it stops from now on).
    pub heat_error: Option<HeatError>,
    /// Cuts asked for, landed or refused this round ([`crate::cut`]).
    pub cuts: Vec<CutEvent>,
    /// The whole round, ns.
    pub total_ns: u64,
}

impl RoundReport {
    /// Whether anything advanced: a body step or a heat step.
    pub fn stepped(&self) -> bool {
        self.heat_steps > 0 || self.bodies.iter().any(|b| b.steps > 0)
    }
}

impl World {
    /// Runs one round (the stages of the module docs) and returns its report; `clock` gives
    /// monotonic nanoseconds for the stage timings (pass `|| 0` where time does not matter).
    /// Allocation-free after the first rounds, except when the heat model fails and when a cut
    /// is asked for or lands.
    pub fn round(&mut self, round: &Round<'_>, mut clock: impl FnMut() -> u64) -> &RoundReport {
        let start = clock();
        let n = self.bodies.len();
        self.report.bodies.resize(n, BodyRound::default());
        self.report.bodies.fill(BodyRound::default());
        self.report.collisions = None;
        self.report.detected = false;
        self.report.collision_ns = 0;
        self.report.heat_steps = 0;
        self.report.heat_ns = 0;
        self.report.heat_error = None;
        self.report.cuts.clear();
        let skipped = |i: usize| round.skip.get(i).copied().unwrap_or(false);
        let tools = &round.tools[..round.tools.len().min(MAX_TOOLS)];
        // Each tool's coupling, moved to the new surface of a body a cut lands on this round.
        let mut couplings = [Coupling::GodObject(None); MAX_TOOLS];
        for (c, t) in couplings.iter_mut().zip(tools) {
            *c = t.coupling;
        }
        let couplings = &mut couplings[..tools.len()];

        if !round.paused {
            // Organ-to-organ contacts at the current shapes, for the steps about to be taken.
            if self.detection_due(round.until)
                && (0..n).any(|i| !skipped(i) && self.body_due(i, round.until))
            {
                let t0 = clock();
                self.report.collisions = self.detect_collisions();
                self.detected_at(round.until);
                self.report.detected = true;
                self.report.collision_ns = clock().saturating_sub(t0);
            }
            for i in (0..n).filter(|&i| !skipped(i)) {
                let of_body = |couplings: &[Coupling]| {
                    let mut body_tools = [None; MAX_TOOLS];
                    for ((slot, t), &coupling) in body_tools.iter_mut().zip(tools).zip(couplings) {
                        *slot = t.sphere(i).map(|sphere| BodyTool { sphere, coupling });
                    }
                    body_tools
                };
                let mut body_tools = of_body(couplings);
                let mut r = BodyRound::default();
                let dt_before = self.bodies[i].model.dt();
                while self.body_due(i, round.until)
                    && r.steps < round.max_catch_up
                    && (r.steps == 0
                        || round.budget_ns == 0
                        || clock().saturating_sub(start) < round.budget_ns)
                {
                    // A cut due at this step lands before it (the tools' contacts on the
                    // old surface are dropped with it).
                    if let Some(event) = self.land_due_cut(i, couplings) {
                        self.report.cuts.push(event);
                        body_tools = of_body(couplings);
                    }
                    let t0 = clock();
                    if let Err(cause) = self.step_body_tools(i, &body_tools[..tools.len()]) {
                        r.blow_up = Some(cause);
                    }
                    self.count_cut_step(i);
                    r.last_step_ns = clock().saturating_sub(t0);
                    r.step_ns += r.last_step_ns;
                    r.steps += 1;
                }
                let stepped_to = self.bodies[i].time;
                if round.drop_lag && self.body_due(i, round.until) {
                    // A hand-over to a finer model (the cage at 20 ms to the FEM at 1 ms)
                    // happens when the coarse step is due, and the fine model starts from the
                    // coarse model's last state, up to one coarse period behind the wall clock:
                    // joining the clock then is the coarse model's hold, not lag. Any other
                    // time still due is dropped as lag.
                    //
                    // The clock moves to the last multiple of the body's period at or before
                    // the round's end, not to the end itself: live rounds come on a grid of
                    // whole periods (plus the wake-up latency), so a clock on the same grid
                    // has one step due per round, where a clock a fraction of a period off it
                    // would have none or two by the latency's whim (frames 2 ms apart at 1 ms).
                    //
                    // A body may stay up to `max_lag` periods behind that grid (not at a
                    // hand-over): it catches up one step a round, each round's frame published.
                    let dt = self.bodies[i].model.dt();
                    let grid = ((round.until + 1e-12) / dt).floor() * dt;
                    let keep = if dt >= dt_before {
                        f64::from(round.max_lag) * dt
                    } else {
                        0.0
                    };
                    self.bodies[i].time = (grid - keep).max(stepped_to);
                    if dt >= dt_before {
                        r.dropped = self.bodies[i].time - stepped_to;
                    }
                }
                r.due = self.body_due(i, round.until);
                self.report.bodies[i] = r;
            }
        }

        if let Some(h) = self.heat.as_mut().filter(|h| !h.failed) {
            let t0 = clock();
            for b in 0..n {
                if let Ok(hb) = h.model.body_mut(b) {
                    hb.clear_sources();
                }
            }
            for (t, coupling) in tools.iter().zip(couplings.iter()) {
                if t.heat_power <= 0.0 {
                    continue;
                }
                if let Coupling::GodObject(Some((b, a))) = *coupling {
                    if !a.grab {
                        let tri = self.bodies[b]
                            .mesh
                            .surface
                            .get(a.triangle as usize)
                            .copied();
                        if let (Some(tri), Ok(hb)) = (tri, h.model.body_mut(b)) {
                            let _ = hb.heat_point(tri, a.bary, t.heat_power);
                        }
                    }
                }
            }
            if let Some(dt) = h.model.bodies().first().map(|b| b.dt()) {
                while h.time + dt <= round.until + 1e-12
                    && self.report.heat_steps < MAX_HEAT_CATCH_UP
                {
                    if let Err(e) = h.model.step() {
                        h.failed = true;
                        self.report.heat_error = Some(e);
                        break;
                    }
                    h.time += dt;
                    self.report.heat_steps += 1;
                }
                if h.time + dt <= round.until {
                    h.time = round.until; // fell behind: drop simulated heat time
                }
            }
            self.report.heat_ns = clock().saturating_sub(t0);
        }
        let mut events = std::mem::take(&mut self.report.cuts);
        self.request_cuts(tools, couplings, &mut events);
        self.report.cuts = events;
        self.report.total_ns = clock().saturating_sub(start);
        &self.report
    }
}
