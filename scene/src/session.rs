//! The one offline path: a world, the god-object that probes it, the rounds that step it and
//! the record of each tick — what `lopd simulate`, the closed loop with the simulated hand and
//! every benchmark that steps a world drive, instead of wiring the pieces by hand.
//!
//! An offline tick has the live pipeline's order:
//!
//! 1. the god-object moves against the world as its last round left it
//!    ([`OfflineSession::probe`], or a [`HapticPipeline`](lop_sim::haptic::HapticPipeline)
//!    rendering against [`OfflineSession::surfaces`]);
//! 2. the world runs its round to the next time with that tick's tool
//!    ([`OfflineSession::advance`]: the tool's centre, the god-object's coupling, the heat
//!    button and the stiffness the hand felt).
//!
//! Everything runs on simulated time: a run is deterministic and can be compared bit for bit.

use std::path::Path;

use anyhow::Result;
use lop_drivers::mock::{MockDevice, MockScript};
use lop_drivers::replay::Recording;
use lop_drivers::{DeviceLimits, DeviceSample};
use lop_sim::haptic::{GodState, WorldProbe, WorldSurfaces};
use lop_sim::world::{Coupling, World};

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
            stiffness: None,
        }
    }
}

/// A world stepped offline with a god-object probing it (see the module docs).
pub struct OfflineSession {
    world: World,
    probe: WorldProbe,
    rounds: Rounds,
    /// The coupling the world's last round ran with: its contact report and local model
    /// belong to it.
    stepped_with: Coupling,
    /// Per body: the simulated time the round of its last step advanced to (`-inf`: none yet).
    last_step_until: Vec<f64>,
}

impl OfflineSession {
    /// A session over `world` with the tool `laws` (the probe's tip is the laws' tool).
    /// Rounds advance on simulated time alone ([`Rounds::offline`]).
    pub fn new(world: World, laws: ToolLaws) -> OfflineSession {
        let probe = WorldProbe::new(&world, laws.tool.radius);
        OfflineSession {
            stepped_with: probe.coupling(),
            last_step_until: vec![f64::NEG_INFINITY; world.bodies.len()],
            world,
            probe,
            rounds: Rounds::offline(laws),
        }
    }

    /// The same session taking every step due in each round ([`Rounds::catching_up`]): for a
    /// caller that advances by fixed ticks, as the benchmarks' presses do.
    pub fn catching_up(mut self) -> OfflineSession {
        self.rounds = Rounds::catching_up(self.rounds.laws().clone());
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

    /// The tool laws.
    pub fn laws(&self) -> &ToolLaws {
        self.rounds.laws()
    }

    /// How the last tick's god-object acts on the tissue.
    pub fn coupling(&self) -> Coupling {
        self.probe.coupling()
    }

    /// The coupling the world's last round ran with.
    pub fn stepped_with(&self) -> Coupling {
        self.stepped_with
    }

    /// Step 1 with a bare god-object: it moves towards `device` (scene, m) with the grab
    /// button `grab` against the world as its last round left it.
    pub fn probe(&mut self, device: [f64; 3], grab: bool) -> GodState {
        self.probe.tick(&self.world, device, grab)
    }

    /// Step 1 through a haptic pipeline at the tick of simulated time `now`, the ticks
    /// `period` apart: the world as the surfaces it renders against, with the local model of
    /// the patch the touched body's last step balanced. Pass the pipeline's god-object state
    /// to [`follow`](Self::follow) afterwards.
    ///
    /// The local model extrapolates over the frame's age as the live loop sees it: the last
    /// step took the tool of the tick one `period` before its round's end, so the model is
    /// `now − end + period` old: one tick when the body steps every tick, up to its step period
    /// when it steps slower (a touched organ whose rate follows its cost).
    pub fn surfaces(&mut self, now: f64, period: f64) -> WorldSurfaces<'_> {
        let local = self
            .world
            .contact_local(self.probe.tool(), self.stepped_with);
        let elapsed = local
            .and_then(|(b, _)| self.last_step_until.get(b))
            .map_or(period, |&end| (now - end + period).max(period));
        self.probe.contact_surfaces(&self.world, local, elapsed)
    }

    /// Keeps the coupling of the pipeline's god-object state (`None`: it did not move).
    pub fn follow(&mut self, state: Option<&GodState>) {
        self.probe.follow(state);
    }

    /// Step 2: one round of the world to simulated time `until` with `tool` (`None`: no
    /// device) and this tick's coupling; bodies marked in `skip` are left alone (empty:
    /// none). `clock` times the round's stages, ns. The report is `world().last_round()`.
    pub fn advance(
        &mut self,
        until: f64,
        tool: Option<RoundInput>,
        skip: &[bool],
        clock: impl FnMut() -> u64,
    ) {
        let coupling = self.probe.coupling();
        let tool = tool.map(|t| TickTool {
            center: t.center,
            coupling,
            heat: t.heat,
            stiffness: t.stiffness,
        });
        self.rounds
            .advance(&mut self.world, until, tool.as_slice(), skip, false, clock);
        self.stepped_with = coupling;
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

    /// The force the touched body's last step balanced on the tissue, N (0 out of contact).
    pub fn tissue_force(&self, state: Option<&GodState>) -> f64 {
        state
            .and_then(|g| g.anchor)
            .and_then(|a| self.world.bodies.get(a.body))
            .map_or(0.0, |b| norm(b.force_on_tissue()))
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
