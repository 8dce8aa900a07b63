//! The levels-of-precision state machine of one body (thesis §4.4, fig. 4.4).

use crate::model::{Model, ModelKind};
use crate::vec3::{norm, sub};

use super::CageModel;

/// Which level a body starts at; a scene's `[lop] start` (`"gc"`, `"precise"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "kebab-case"))]
pub enum StartLevel {
    /// The cage, as thesis §4.4 describes ("initially, all objects are simulated using the
    /// fastest method").
    #[default]
    Gc,
    /// The precise model, handing over to the cage once settled (what the thesis' gravity
    /// trials of fig. 6.5 show).
    Precise,
}

/// When a body switches.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LopPolicy {
    /// A body counts as settled while its largest nodal speed stays below this, m/s …
    pub rest_speed: f64,
    /// … for this long without tool contact, s.
    pub hold: f64,
    /// On the way back to the cage, the part of the shape the cage cannot represent fades out
    /// over this long, s (0: snap).
    pub blend: f64,
    /// Starting level.
    pub start: StartLevel,
}

impl Default for LopPolicy {
    /// 2 mm/s for 0.3 s, blended over 0.2 s: tissue that slow is visually still, and a poke's
    /// ring-down on the shipped scenes is over well before it.
    fn default() -> Self {
        LopPolicy {
            rest_speed: 2e-3,
            hold: 0.3,
            blend: 0.2,
            start: StartLevel::Gc,
        }
    }
}

/// Why a body switched.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SwitchReason {
    /// The tool touched a body running as a cage.
    Contact,
    /// The precise model settled.
    Settled,
    /// Asked for by the caller ([`PrecisionController::to_precise`]).
    Requested,
}

/// One transition.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Switch {
    /// Body time of the switch, s.
    pub time: f64,
    /// Model before.
    pub from: ModelKind,
    /// Model after.
    pub to: ModelKind,
    /// Why.
    pub reason: SwitchReason,
    /// Largest displayed vertex jump at the switch, m (the pop a viewer would see).
    pub jump: f64,
    /// Going to the cage: the largest distance between the precise shape and the cage's fit of
    /// it, which the blend fades out instead of popping, m. Zero going to the precise model.
    pub residual: f64,
}

/// A body's controller: the model that is not running (parked) and the switching state.
#[derive(Debug, Clone)]
pub struct PrecisionController {
    parked: Model,
    pub(crate) policy: LopPolicy,
    calm: f64,
    switches: u32,
    last: Option<Switch>,
    unread: bool,
}

impl PrecisionController {
    /// A controller over a body's `precise` model and its cage model `gc`; returns the model
    /// to run first (per `policy.start`) and the controller holding the other.
    pub fn new(precise: Model, gc: CageModel, policy: LopPolicy) -> (Model, PrecisionController) {
        let gc = Model::Gc(Box::new(gc));
        let (active, parked) = match policy.start {
            StartLevel::Gc => (gc, precise),
            StartLevel::Precise => (precise, gc),
        };
        (
            active,
            PrecisionController {
                parked,
                policy,
                calm: 0.0,
                switches: 0,
                last: None,
                unread: false,
            },
        )
    }

    /// The policy.
    pub fn policy(&self) -> &LopPolicy {
        &self.policy
    }
    /// The model not running now.
    pub fn parked(&self) -> &Model {
        &self.parked
    }
    /// The model not running now, to configure it (its threads, its refactor policy).
    pub fn parked_mut(&mut self) -> &mut Model {
        &mut self.parked
    }
    /// Transitions so far.
    pub fn switches(&self) -> u32 {
        self.switches
    }
    /// The most recent transition.
    pub fn last_switch(&self) -> Option<&Switch> {
        self.last.as_ref()
    }
    /// The most recent transition if it has not been taken yet (for logs).
    pub fn take_switch(&mut self) -> Option<Switch> {
        if self.unread {
            self.unread = false;
            self.last
        } else {
            None
        }
    }

    /// Before a step: a body running as a cage that the tool touches switches to its precise
    /// model, which starts from the cage's exact shape and velocities (no jump). Allocation-free.
    pub fn before_step(&mut self, active: &mut Model, touching: bool, time: f64) {
        if touching {
            self.to_precise(active, time, SwitchReason::Contact);
        }
    }

    /// Switches a body running as a cage to its precise model now (no-op if it already runs
    /// it), e.g. for a static solve.
    pub fn to_precise(&mut self, active: &mut Model, time: f64, reason: SwitchReason) {
        if active.kind() != ModelKind::Gc {
            return;
        }
        self.parked
            .set_state(active.positions(), active.velocities());
        let jump = max_distance(self.parked.positions(), active.positions());
        std::mem::swap(active, &mut self.parked);
        self.record(time, self.parked.kind(), active.kind(), reason, jump, 0.0);
        self.calm = 0.0;
    }

    /// After a step of `dt`: a precise model that has stayed slow and untouched for the hold
    /// time hands over to the cage (fitted to its shape, the remainder blended out). Returns
    /// whether it switched. The hand-over allocates (a least-squares fit); it happens once per
    /// contact episode, off any real-time path.
    pub fn after_step(&mut self, active: &mut Model, touched: bool, dt: f64, time: f64) -> bool {
        if active.kind() == ModelKind::Gc {
            return false;
        }
        if touched || !(active.max_speed() < self.policy.rest_speed) {
            self.calm = 0.0;
            return false;
        }
        self.calm += dt;
        if self.calm + 1e-12 < self.policy.hold {
            return false;
        }
        let Model::Gc(gc) = &mut self.parked else {
            return false;
        };
        let residual = gc.take_over(active.positions(), active.velocities(), self.policy.blend);
        let jump = max_distance(gc.positions(), active.positions());
        std::mem::swap(active, &mut self.parked);
        self.record(
            time,
            self.parked.kind(),
            ModelKind::Gc,
            SwitchReason::Settled,
            jump,
            residual,
        );
        self.calm = 0.0;
        true
    }

    fn record(
        &mut self,
        time: f64,
        from: ModelKind,
        to: ModelKind,
        reason: SwitchReason,
        jump: f64,
        residual: f64,
    ) {
        self.switches += 1;
        self.last = Some(Switch {
            time,
            from,
            to,
            reason,
            jump,
            residual,
        });
        self.unread = true;
    }
}

fn max_distance(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| norm(sub(*p, *q)))
        .fold(0.0, f64::max)
}
