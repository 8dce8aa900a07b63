//! The deformation side's rounds, shared by `lopd deform` (on the wall clock) and every offline
//! run ([`OfflineSession`](crate::OfflineSession), on simulated time): the tools as the haptic
//! side resolved them ([`TickTool`]), each with its own laws from the scene, become one
//! [`lop_sim::world::World::round`]. Nothing else advances a world.
//!
//! The callers differ only in where the tools come from (the haptic loop's tool states, or an
//! offline god-object) and in the catch-up policy ([`Rounds::live`] drops the lag of a body
//! that cannot keep up with the wall clock; [`Rounds::offline`] never does).

use crate::ToolLaws;
use lop_sim::contact::ToolSphere;
use lop_sim::world::{Coupling, Round, RoundTool, World, MAX_TOOLS};

/// Most steps a body takes in one live round to catch up with the wall clock, and most periods
/// it may be behind after them; beyond that its simulated time is dropped rather than
/// spiralling (counted as lag). Its second and later steps come only within the round's budget
/// (one loop period): a body whose steps are long takes one a round and `lopd deform` runs the
/// next round at once, a frame published after each, where taking them all in one round
/// published nothing until the last (frames of a 10k-tetrahedra organ 4 steps apart).
pub const MAX_CATCH_UP: u32 = 4;

/// One tool for one round, as the haptic side resolved it.
#[derive(Debug, Clone, Copy)]
pub struct TickTool {
    /// Device tip in the scene, m.
    pub center: [f64; 3],
    /// Which body the god-object touches or holds, and where (`GodObject(None)`: none).
    pub coupling: Coupling,
    /// The heat button is pressed.
    pub heat: bool,
    /// The cut button is pressed (a cautery's cut: it heats as `heat` does, and the tissue it
    /// vaporises is cut away where the scene cuts).
    pub cut: bool,
    /// The stiffness the hand feels against the held body, as the haptic loop rendered it
    /// (device-clamped); `None`: the scene law's.
    pub stiffness: Option<f64>,
}

/// Rounds of one world with its scene's tool laws, one set per tool.
#[derive(Debug, Clone)]
pub struct Rounds {
    /// Per tool, in the scene's order, the laws it presses with (at least one; a tool beyond
    /// them presses with the first tool's).
    laws: Vec<ToolLaws>,
    /// This round's laws, per tool one per body: the tool's own, with its hand's stiffness
    /// on the body it holds. Filled by `advance_tools`, read by the world's round through
    /// each tool's slice.
    round_laws: Vec<ToolSphere>,
    max_catch_up: u32,
    drop_lag: bool,
    max_lag: u32,
    budget_ns: u64,
}

impl Rounds {
    /// Rounds on the wall clock (`lopd deform`): at most [`MAX_CATCH_UP`] steps a body, the
    /// second and later only while the round has run for less than `budget_ns` (the loop's
    /// period); a body still behind after them may stay up to `MAX_CATCH_UP − 1` periods
    /// behind (the rest is dropped as lag) and is [`due`](lop_sim::world::BodyRound::due) for
    /// the next round at once. Every tool presses with `laws` until
    /// [`Rounds::with_tools`] gives each its own.
    pub fn live(laws: ToolLaws, budget_ns: u64) -> Rounds {
        Rounds {
            budget_ns,
            ..Rounds::new(laws, MAX_CATCH_UP, true, MAX_CATCH_UP - 1)
        }
    }

    /// Rounds on simulated time (`lopd simulate`): each round advances to the earliest next
    /// step, one step per body due, and no time is ever dropped. Every tool presses with
    /// `laws` until [`Rounds::with_tools`] gives each its own.
    pub fn offline(laws: ToolLaws) -> Rounds {
        Rounds::new(laws, 1, false, 0)
    }

    /// Rounds on simulated time that take every step due by the round's end (a caller that
    /// ticks at a fixed period and expects every body to be there after each tick; one step per
    /// round can leave a body a step behind when rounding puts its next step a hair past the
    /// tick). Every tool presses with `laws` until [`Rounds::with_tools`] gives each its own.
    pub fn catching_up(laws: ToolLaws) -> Rounds {
        Rounds::new(laws, u32::MAX, false, 0)
    }

    fn new(laws: ToolLaws, max_catch_up: u32, drop_lag: bool, max_lag: u32) -> Rounds {
        Rounds {
            round_laws: Vec::with_capacity(MAX_TOOLS * laws.bodies.len()),
            laws: vec![laws],
            max_catch_up,
            drop_lag,
            max_lag,
            budget_ns: 0,
        }
    }

    /// The same rounds with every tool's own laws, in the scene's order (`laws[k]` for tool
    /// `k`, as [`ToolLaws::of_tool`] gives them): a scene of several tools, each with its
    /// radius, force law, spring and cautery power. A tool beyond `laws` presses with the
    /// first tool's; empty `laws` keep the ones the rounds had; laws past [`MAX_TOOLS`] are
    /// dropped.
    pub fn with_tools(mut self, mut laws: Vec<ToolLaws>) -> Rounds {
        if laws.is_empty() {
            return self;
        }
        laws.truncate(MAX_TOOLS);
        let bodies = laws.iter().map(|l| l.bodies.len()).max().unwrap_or(0);
        self.round_laws = Vec::with_capacity(MAX_TOOLS * bodies);
        self.laws = laws;
        self
    }

    /// The first tool's laws (the scene's one tool, in a scene of one).
    pub fn laws(&self) -> &ToolLaws {
        &self.laws[0]
    }

    /// Every tool's laws, in the scene's order (one entry when the rounds were given one).
    pub fn tool_laws(&self) -> &[ToolLaws] {
        &self.laws
    }

    /// Runs one round of `world` to simulated time `until` with `tools`, every one present
    /// (in the scene's order, at most [`MAX_TOOLS`]; see [`Rounds::advance_tools`]).
    pub fn advance(
        &mut self,
        world: &mut World,
        until: f64,
        tools: &[TickTool],
        skip: &[bool],
        paused: bool,
        clock: impl FnMut() -> u64,
    ) {
        let n = tools.len().min(MAX_TOOLS);
        let mut present = [None; MAX_TOOLS];
        for (slot, t) in present.iter_mut().zip(tools) {
            *slot = Some(*t);
        }
        self.advance_tools(world, until, &present[..n], skip, paused, clock);
    }

    /// Runs one round of `world` to simulated time `until` with `tools` indexed by tool (in
    /// the scene's order, at most [`MAX_TOOLS`]; see [`World::round`]): `None` is a tool
    /// absent this round (no state from its device), which acts on no body and keeps the
    /// index of every tool after it, so that each tool's report in
    /// [`lop_sim::world::Body::contacts`] stays under its own index. Bodies marked in `skip`
    /// are left alone; `paused` steps no body. Tool `k` presses with its own laws
    /// ([`Rounds::with_tools`]), and with the stiffness its hand feels on the body it holds.
    /// The report is `world.last_round()`. Allocation-free after the first round with the
    /// most tools.
    pub fn advance_tools(
        &mut self,
        world: &mut World,
        until: f64,
        tools: &[Option<TickTool>],
        skip: &[bool],
        paused: bool,
        clock: impl FnMut() -> u64,
    ) {
        let tools = &tools[..tools.len().min(MAX_TOOLS)];
        let laws = &self.laws;
        let of_tool = |k: usize| laws.get(k).unwrap_or(&laws[0]);
        self.round_laws.clear();
        // Per tool: its laws' span of `round_laws` (empty for an absent tool: no law against
        // any body, so no body's step sees it).
        let mut spans = [(0usize, 0usize); MAX_TOOLS];
        for (k, t) in tools.iter().enumerate() {
            let Some(t) = t else {
                continue;
            };
            let first = self.round_laws.len();
            self.round_laws.extend_from_slice(&of_tool(k).bodies);
            spans[k] = (first, self.round_laws.len());
            if let TickTool {
                coupling: Coupling::GodObject(Some((b, _))),
                stiffness: Some(s),
                ..
            } = t
            {
                if let Some(law) = self.round_laws[first..].get_mut(*b) {
                    if s.is_finite() && *s > 0.0 {
                        law.stiffness = *s;
                    }
                }
            }
        }
        let mut packed = [RoundTool {
            center: [0.0; 3],
            laws: &[],
            coupling: Coupling::GodObject(None),
            heat_power: 0.0,
            cut: false,
        }; MAX_TOOLS];
        for (k, (slot, t)) in packed.iter_mut().zip(tools).enumerate() {
            if let Some(t) = t {
                let (first, end) = spans[k];
                *slot = RoundTool {
                    center: t.center,
                    laws: &self.round_laws[first..end],
                    coupling: t.coupling,
                    heat_power: match (t.cut, t.heat) {
                        (true, _) => of_tool(k).cut_power,
                        (false, true) => of_tool(k).heat_power,
                        _ => 0.0,
                    },
                    cut: t.cut,
                };
            }
        }
        let round = Round {
            until,
            max_catch_up: self.max_catch_up,
            drop_lag: self.drop_lag,
            max_lag: self.max_lag,
            budget_ns: self.budget_ns,
            tools: &packed[..tools.len()],
            skip,
            paused,
        };
        world.round(&round, clock);
    }
}
