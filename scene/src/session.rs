//! The one offline path: a world, the god-objects that probe it (one per tool), the rounds that
//! step it and the record of each tick — what `lopd simulate`, the closed loop with the
//! simulated hands and every benchmark that steps a world drive, instead of wiring the pieces
//! by hand.
//!
//! An offline tick has the live pipeline's order:
//!
//! 1. every tool's god-object moves against the world as its last round left it
//!    ([`OfflineSession::probe`], or a [`HapticPipeline`](lop_sim::haptic::HapticPipeline)
//!    per tool rendering against [`OfflineSession::tool_surfaces`]);
//! 2. the world runs one round to the next time with every tool of that tick
//!    ([`OfflineSession::advance_tools`], or [`OfflineSession::advance`] with one tool: each
//!    tool's centre, its god-object's coupling, the heat button and the stiffness its hand
//!    felt).
//!
//! A session of one tool ([`OfflineSession::new`]) is a session of several
//! ([`OfflineSession::with_tools`]) with one: the methods without a tool index act on tool 0.
//!
//! Everything runs on simulated time: a run is deterministic and can be compared bit for bit.

use std::path::Path;

use anyhow::Result;
use lop_drivers::mock::{MockDevice, MockScript};
use lop_drivers::replay::Recording;
use lop_drivers::{DeviceLimits, DeviceSample};
use lop_sim::haptic::{GodState, WorldProbe, WorldSurfaces};
use lop_sim::world::{Coupling, World, MAX_TOOLS};

use crate::rounds::{Rounds, TickTool};
use crate::ToolLaws;

/// The tool of one round: where the device is and what the hand does, as the haptic side
/// resolved it (the coupling is the session's god-object's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoundInput {
    /// Device tip in the scene, m.
    pub center: [f64; 3],
    /// The heat button is pressed.
    pub heat: bool,
    /// The cut button is pressed ([`TickTool::cut`]).
    pub cut: bool,
    /// The stiffness the hand feels against the held body (device-clamped); `None`: the
    /// scene law's.
    pub stiffness: Option<f64>,
}

impl RoundInput {
    /// The tool at `center`, heat off, the scene law's stiffness.
    pub fn at(center: [f64; 3]) -> RoundInput {
        RoundInput {
            center,
            heat: false,
            cut: false,
            stiffness: None,
        }
    }
}

/// A world stepped offline with a god-object per tool probing it (see the module docs).
pub struct OfflineSession {
    world: World,
    /// Per tool, in the scene's order, its god-object over the world (`probes[k]` is tool `k`
    /// of the rounds: it rests on that tool's contact patch).
    probes: Vec<WorldProbe>,
    rounds: Rounds,
    /// Per tool, the coupling the world's last round ran with: that tool's contact report and
    /// local model belong to it.
    stepped_with: Vec<Coupling>,
    /// Per body: the simulated time the round of its last step advanced to (`-inf`: none yet).
    last_step_until: Vec<f64>,
}

impl OfflineSession {
    /// A session over `world` with one tool of `laws` (the probe's tip is the laws' tool).
    /// Rounds advance on simulated time alone ([`Rounds::offline`]).
    pub fn new(world: World, laws: ToolLaws) -> OfflineSession {
        OfflineSession::with_tools(world, vec![laws])
    }

    /// A session over `world` with one tool per entry of `laws`, in the scene's order
    /// (`laws[k]` for tool `k`, as [`ToolLaws::of_tool`] gives them; at most [`MAX_TOOLS`],
    /// the rest dropped): each tool its own god-object ([`WorldProbe::for_tool`]) and its own
    /// laws in the rounds ([`Rounds::with_tools`]). Rounds advance on simulated time alone
    /// ([`Rounds::offline`]).
    ///
    /// # Panics
    /// `laws` is empty: a session has at least one tool.
    pub fn with_tools(world: World, mut laws: Vec<ToolLaws>) -> OfflineSession {
        assert!(
            !laws.is_empty(),
            "an offline session needs at least one tool"
        );
        laws.truncate(MAX_TOOLS);
        let probes: Vec<WorldProbe> = laws
            .iter()
            .enumerate()
            .map(|(k, l)| WorldProbe::new(&world, l.tool.radius).for_tool(k))
            .collect();
        OfflineSession {
            stepped_with: probes.iter().map(WorldProbe::coupling).collect(),
            last_step_until: vec![f64::NEG_INFINITY; world.bodies.len()],
            world,
            probes,
            rounds: Rounds::offline(laws[0].clone()).with_tools(laws),
        }
    }

    /// The same session taking every step due in each round ([`Rounds::catching_up`]): for a
    /// caller that advances by fixed ticks, as the benchmarks' presses do.
    pub fn catching_up(mut self) -> OfflineSession {
        let laws = self.rounds.tool_laws().to_vec();
        self.rounds = Rounds::catching_up(laws[0].clone()).with_tools(laws);
        self
    }

    /// The world.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The world, to change between rounds (parameters, pins).
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    /// The world, as the session ends.
    pub fn into_world(self) -> World {
        self.world
    }

    /// How many tools the session has (at least one).
    pub fn tools(&self) -> usize {
        self.probes.len()
    }

    /// The first tool's laws.
    pub fn laws(&self) -> &ToolLaws {
        self.rounds.laws()
    }

    /// Every tool's laws, in the scene's order.
    pub fn tool_laws(&self) -> &[ToolLaws] {
        self.rounds.tool_laws()
    }

    /// How the last tick's god-object of the first tool acts on the tissue.
    pub fn coupling(&self) -> Coupling {
        self.tool_coupling(0)
    }

    /// How the last tick's god-object of tool `tool` acts on the tissue.
    ///
    /// # Panics
    /// `tool` is not one of the session's.
    pub fn tool_coupling(&self, tool: usize) -> Coupling {
        self.probes[tool].coupling()
    }

    /// The coupling the world's last round ran with for the first tool.
    pub fn stepped_with(&self) -> Coupling {
        self.stepped_with[0]
    }

    /// Step 1 with the first tool's bare god-object: it moves towards `device` (scene, m) with
    /// the grab button `grab` against the world as its last round left it.
    pub fn probe(&mut self, device: [f64; 3], grab: bool) -> GodState {
        self.probe_tool(0, device, grab)
    }

    /// Step 1 with tool `tool`'s bare god-object, as [`probe`](Self::probe).
    ///
    /// # Panics
    /// `tool` is not one of the session's.
    pub fn probe_tool(&mut self, tool: usize, device: [f64; 3], grab: bool) -> GodState {
        self.probes[tool].tick(&self.world, device, grab)
    }

    /// Step 1 through a haptic pipeline for the first tool: [`tool_surfaces`](Self::tool_surfaces)
    /// of tool 0.
    pub fn surfaces(&mut self, now: f64, period: f64) -> WorldSurfaces<'_> {
        self.tool_surfaces(0, now, period)
    }

    /// Step 1 through a haptic pipeline for tool `tool` at the tick of simulated time `now`,
    /// the ticks `period` apart: the world as the surfaces it renders against, with the local
    /// model of that tool's share of the patch the touched body's last step balanced. Pass the
    /// pipeline's god-object state to [`follow_tool`](Self::follow_tool) afterwards. Every
    /// tool of a tick renders against the same world: advance only after the last.
    ///
    /// The local model extrapolates over the frame's age as the live loop sees it: the last
    /// step took the tool of the tick one `period` before its round's end, so the model is
    /// `now − end + period` old: one tick when the body steps every tick, up to its step period
    /// when it steps slower (a touched organ whose rate follows its cost).
    ///
    /// # Panics
    /// `tool` is not one of the session's.
    pub fn tool_surfaces(&mut self, tool: usize, now: f64, period: f64) -> WorldSurfaces<'_> {
        let probe = &mut self.probes[tool];
        let local = self.world.contact_local(tool, self.stepped_with[tool]);
        let elapsed = local
            .and_then(|(b, _)| self.last_step_until.get(b))
            .map_or(period, |&end| (now - end + period).max(period));
        probe.contact_surfaces(&self.world, local, elapsed)
    }

    /// Keeps the coupling of the first tool's pipeline god-object state (`None`: it did not
    /// move).
    pub fn follow(&mut self, state: Option<&GodState>) {
        self.follow_tool(0, state);
    }

    /// Keeps the coupling of tool `tool`'s pipeline god-object state (`None`: it did not
    /// move).
    ///
    /// # Panics
    /// `tool` is not one of the session's.
    pub fn follow_tool(&mut self, tool: usize, state: Option<&GodState>) {
        self.probes[tool].follow(state);
    }

    /// Step 2 with the first tool alone: [`advance_tools`](Self::advance_tools) with `tool`
    /// (`None`: no device) as tool 0 and no other.
    pub fn advance(
        &mut self,
        until: f64,
        tool: Option<RoundInput>,
        skip: &[bool],
        clock: impl FnMut() -> u64,
    ) {
        self.advance_tools(until, &[tool], skip, clock);
    }

    /// Step 2: one round of the world to simulated time `until` with `tools` indexed by tool
    /// (`None`: that tool has no device this round and acts on no body; a tool of the session
    /// past the end of `tools` neither; entries past the session's tools are ignored), each
    /// with its god-object's coupling of this tick; bodies marked in
    /// `skip` are left alone (empty: none). `clock` times the round's stages, ns. The report
    /// is `world().last_round()`, each tool's contact under its own index. Allocation-free.
    pub fn advance_tools(
        &mut self,
        until: f64,
        tools: &[Option<RoundInput>],
        skip: &[bool],
        clock: impl FnMut() -> u64,
    ) {
        let n = tools.len().min(self.probes.len());
        let mut round = [None; MAX_TOOLS];
        for (k, (slot, t)) in round.iter_mut().zip(&tools[..n]).enumerate() {
            let coupling = self.probes[k].coupling();
            *slot = t.map(|t| TickTool {
                center: t.center,
                coupling,
                heat: t.heat,
                cut: t.cut,
                stiffness: t.stiffness,
            });
        }
        self.rounds
            .advance_tools(&mut self.world, until, &round[..n], skip, false, clock);
        if self
            .world
            .last_round()
            .cuts
            .iter()
            .any(|e| matches!(e, lop_sim::cut::CutEvent::Landed { .. }))
        {
            // The god-objects go on over the new surfaces, their proxies where they were.
            for p in &mut self.probes {
                *p = p.rebuilt(&self.world);
            }
        }
        for (with, probe) in self.stepped_with.iter_mut().zip(&self.probes) {
            *with = probe.coupling();
        }
        for (end, b) in self
            .last_step_until
            .iter_mut()
            .zip(&self.world.last_round().bodies)
        {
            if b.steps > 0 {
                *end = until;
            }
        }
    }

    /// The force the touched body's last step balanced on the tissue, every tool's together,
    /// N (0 out of contact).
    pub fn tissue_force(&self, state: Option<&GodState>) -> f64 {
        state
            .and_then(|g| g.anchor)
            .and_then(|a| self.world.bodies.get(a.body))
            .map_or(0.0, |b| norm(b.force_on_tissue()))
    }

    /// The force tool `tool` gave the tissue in the touched body's last step (its share of the
    /// patch), N (0 out of contact). With one tool, [`tissue_force`](Self::tissue_force).
    pub fn tool_tissue_force(&self, tool: usize, state: Option<&GodState>) -> f64 {
        state
            .and_then(|g| g.anchor)
            .and_then(|a| self.world.bodies.get(a.body))
            .and_then(|b| b.contacts.get(tool))
            .map_or(0.0, |c| norm(c.force_on_tissue))
    }
}

fn norm(f: [f64; 3]) -> f64 {
    (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt()
}

/// Where an open-loop offline run takes the tool from: a mock script or a session recording,
/// both sampled on simulated time, so the run is deterministic either way.
pub enum ToolSource {
    /// `--script NAME|PATH` (or `--device mock:SCRIPT`).
    Script(MockScript),
    /// `--device replay:PATH`: a recorded session, by tick index.
    Replay(Recording),
}

impl ToolSource {
    /// Loads the script or the recording, if one is given (a script wins; the command line
    /// refuses both).
    pub fn load(script: Option<&Path>, replay: Option<&Path>) -> Result<Option<ToolSource>> {
        Ok(match (script, replay) {
            (Some(p), _) => Some(ToolSource::Script(MockScript::load(p)?)),
            (None, Some(p)) => Some(ToolSource::Replay(Recording::load(p)?)),
            (None, None) => None,
        })
    }

    /// The limits of the device this trajectory stands for: the mock's (an Omni's), or the
    /// recorded device's.
    pub fn limits(&self) -> DeviceLimits {
        match self {
            ToolSource::Script(_) => MockDevice::omni_limits(),
            ToolSource::Replay(r) => r.header().limits,
        }
    }

    /// The device sample at simulated time `t`, s.
    pub fn sample(&self, t: f64) -> DeviceSample {
        match self {
            ToolSource::Script(s) => s.sample(t),
            ToolSource::Replay(r) => r.sample(t),
        }
    }
}

/// One tick of a closed-loop run, in the device's frame (metres, newtons): the one record
/// offline runs write per tick (`hand.csv` of `lopd simulate --device hand`, the stability
/// map's `stability.csv`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickRecord {
    /// Simulated time, s.
    pub t: f64,
    /// The stylus tip, device frame, m.
    pub stylus: [f64; 3],
    /// The force rendered on the hand this tick, device frame, N.
    pub force: [f64; 3],
    /// The god-object touched a body.
    pub contact: bool,
    /// The force came from the frame's local model.
    pub local: bool,
    /// The work the hand's grip has done on the stylus since the start, J.
    pub grip_work: f64,
    /// The force's magnitude on the tissue the step balanced (the touched body's last
    /// contact report), N.
    pub tissue_force: f64,
}

impl TickRecord {
    /// The CSV columns of [`write_csv`](Self::write_csv).
    pub const CSV_HEADER: &'static str =
        "t_s,fx_n,fy_n,fz_n,x_mm,y_mm,z_mm,contact,local_model,grip_work_j,tissue_force_n";

    /// The record as one CSV row (no newline), columns as [`CSV_HEADER`](Self::CSV_HEADER).
    pub fn write_csv(&self, w: &mut impl std::fmt::Write) -> std::fmt::Result {
        let [fx, fy, fz] = self.force;
        let [x, y, z] = self.stylus.map(|c| c * 1e3);
        write!(
            w,
            "{:.4},{fx:.6e},{fy:.6e},{fz:.6e},{x:.6},{y:.6},{z:.6},{},{},{:.6e},{:.6e}",
            self.t,
            u8::from(self.contact),
            u8::from(self.local),
            self.grip_work,
            self.tissue_force
        )
    }
}
