//! The control service `PREFIX/control`, served by the deformation process between world steps:
//! get and set a body's parameters, pin a body to one model or release it to the
//! levels-of-precision controller, reset the scene, pause and resume.
//!
//! Why here and not in the haptic process: the haptic loop never sees a request, so no request
//! can make it miss a deadline. The worst a request does is what any slow deformation step does:
//! frames age, and past the stale limit the haptic loop ramps the force to zero.
//!
//! Rebuilding a model (new FEM parameters refactorise the stiffness and rebuild the cage's
//! projected operators; a pin or release builds the other model) runs on a helper thread; the
//! deformation loop keeps stepping the old model meanwhile and swaps the new one in, with the
//! body's motion carried over, when it is ready. One rebuild at a time: a second one is answered
//! `CONTROL_STATUS_BUSY` (so is a rebuild of a body the tool is touching: its model is never
//! swapped under the hand). `lopd ctl` retries on busy.
//!
//! Every request is answered; a bad one gets a typed status and a message naming the key and
//! the bad value, and changes nothing. A request is first decoded by [`decode`], a pure
//! function of the request and the bodies' names (so any bytes that arrive can be checked
//! without iceoryx2: `tests/fuzz_control.rs`), then checked against the simulation's state
//! (a model the body lacks, a rebuild running, the tool touching the body) here.

use std::thread::JoinHandle;

use anyhow::Result;
use iceoryx2::active_request::ActiveRequest;
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use lop_config::{BodySpec, ModelPin, Scene};
use lop_ipc::control::*;
use lop_ipc::services::Role;
use lop_ipc::{BodyModel, ServiceNames, CONTRACT_VERSION};
use lop_sim::lop::{LopPolicy, PrecisionController};
use lop_sim::mesh::TetMesh;
use lop_sim::model::Model;
use lop_sim::world::World;

use crate::deform::body_model;
use lop_scene as scene;

/// Requests served per deformation-loop iteration, so a flood of requests cannot starve the
/// stepping.
const REQUESTS_PER_POLL: usize = 4;

type Request = ActiveRequest<ipc::Service, ControlRequest, (), ControlResponse, ()>;
type Built = Result<(Model, Option<PrecisionController>), String>;

/// A model rebuild running on a helper thread.
struct Rebuild {
    body: usize,
    spec: BodySpec,
    what: String,
    request: Request,
    job: JoinHandle<Built>,
}

/// The server side of `PREFIX/control`, owned by the deformation loop.
pub struct ControlServer {
    _service: Option<ControlService>,
    server: Option<Server<ipc::Service, ControlRequest, (), ControlResponse, ()>>,
    /// The scene as changed by requests (each body's pin and parameters).
    scene: Scene,
    /// Each body's controller policy (per body: `lop.*` requests retune one body).
    policies: Vec<LopPolicy>,
    /// Each body's models as built, at rest: what a reset restores.
    rest: Vec<(Model, Option<PrecisionController>)>,
    paused: bool,
    rebuild: Option<Rebuild>,
}

impl ControlServer {
    /// Creates the service. A failure is logged and control is off: the simulation must run
    /// without it.
    pub fn new(
        node: &Node<ipc::Service>,
        names: &ServiceNames,
        scene: &Scene,
        world: &World,
    ) -> ControlServer {
        let service = match control_service(node, names, Role::Owner) {
            Ok(s) => Some(s),
            Err(e) => {
                tracing::warn!("control service off: {e}");
                None
            }
        };
        let server = service
            .as_ref()
            .and_then(|s| match s.server_builder().create() {
                Ok(server) => Some(server),
                Err(e) => {
                    tracing::warn!("control service off: create server: {e:?}");
                    None
                }
            });
        let policies = world
            .bodies
            .iter()
            .map(|b| {
                b.lop
                    .as_ref()
                    .map_or_else(|| scene::lop_policy(scene), |l| *l.policy())
            })
            .collect();
        let rest = world
            .bodies
            .iter()
            .map(|b| (b.model.clone(), b.lop.clone()))
            .collect();
        ControlServer {
            _service: service,
            server,
            scene: scene.clone(),
            policies,
            rest,
            paused: false,
            rebuild: None,
        }
    }

    /// Serves pending requests and finishes a rebuild that is ready. Call once per loop
    /// iteration with the simulated time; returns whether the simulation is paused (then the
    /// caller skips stepping and keeps publishing frames; the bodies' clocks are held here).
    pub fn poll(&mut self, world: &mut World, sim_now: f64) -> bool {
        self.finish_rebuild(world);
        if let Some(server) = &self.server {
            let mut requests = Vec::new();
            while requests.len() < REQUESTS_PER_POLL {
                match server.receive() {
                    Ok(Some(r)) => requests.push(r),
                    _ => break,
                }
            }
            for r in requests {
                let req = *r.payload();
                if let Some(resp) = self.handle(&req, r, world) {
                    let _ = resp.0.send_copy(resp.1);
                }
            }
        }
        if self.paused {
            world.hold_time(sim_now);
        }
        self.paused
    }

    /// Answers `req` now (returns the request handle and the response) or keeps the handle
    /// for a rebuild that answers later.
    fn handle(
        &mut self,
        req: &ControlRequest,
        handle: Request,
        world: &mut World,
    ) -> Option<(Request, ControlResponse)> {
        let resp = match self.decide(req, world) {
            Decision::Answer(r) => r,
            Decision::Rebuild { body, spec, what } => {
                self.start_rebuild(body, spec, what, handle, world);
                return None;
            }
        };
        Some((handle, resp))
    }

    fn decide(&mut self, req: &ControlRequest, world: &mut World) -> Decision {
        use Decision::Answer;
        let names: Vec<&str> = world.bodies.iter().map(|b| b.name.as_str()).collect();
        let command = match decode(req, &names) {
            Ok(command) => command,
            Err(refusal) => {
                return Answer(match refusal.body {
                    Some(i) => self.describe(i, world, refusal.status, &refusal.message),
                    None => {
                        self.with_paused(ControlResponse::with(refusal.status, &refusal.message))
                    }
                })
            }
        };
        match command {
            Command::Reset => {
                if self.rebuild.is_some() {
                    return Answer(self.busy_rebuilding());
                }
                for (i, (model, lop)) in self.rest.iter().enumerate() {
                    world.reset_body(i, model.clone(), lop.clone());
                    if let Some(l) = &mut world.bodies[i].lop {
                        l.set_policy(self.policies[i]);
                    }
                }
                tracing::info!("control: scene reset to rest");
                Answer(self.ok("every body reset to rest"))
            }
            Command::Pause => {
                self.paused = true;
                tracing::info!("control: paused");
                Answer(self.ok("paused"))
            }
            Command::Resume => {
                self.paused = false;
                tracing::info!("control: resumed");
                Answer(self.ok("resumed"))
            }
            Command::Get { body } => Answer(self.describe(body, world, CONTROL_STATUS_OK, "")),
            Command::Set { body, key, value } => self.set(body, key, value, world),
            Command::Pin { body: i, pin } => {
                let spec = &self.scene.bodies[i];
                if pin == ModelPin::Fem && spec.fem.is_none() {
                    return Answer(self.not_allowed(
                        i,
                        world,
                        "it has no [body.fem] parameters to run FEM",
                    ));
                }
                if matches!(pin, ModelPin::Msd | ModelPin::Gc)
                    && spec.msd.is_none()
                    && spec.fem.is_none()
                {
                    return Answer(self.not_allowed(i, world, "it has no precise model"));
                }
                if pin == ModelPin::Msd && spec.msd.is_none() {
                    return Answer(self.not_allowed(
                        i,
                        world,
                        "it has no [body.msd] parameters to run mass-spring",
                    ));
                }
                let mut spec = spec.clone();
                spec.model = pin;
                self.rebuild_or_busy(i, spec, format!("pin to {pin:?}"), world)
            }
            Command::Release { body: i } => {
                if self.scene.bodies[i].model == ModelPin::Auto {
                    return Answer(self.describe(
                        i,
                        world,
                        CONTROL_STATUS_OK,
                        "already under the levels-of-precision controller",
                    ));
                }
                let mut spec = self.scene.bodies[i].clone();
                spec.model = ModelPin::Auto;
                self.rebuild_or_busy(i, spec, "release to the controller".into(), world)
            }
        }
    }

    /// Applies `key = value` (already checked by [`decode`]) to body `i`.
    fn set(&mut self, i: usize, key: &str, value: f64, world: &mut World) -> Decision {
        use Decision::Answer;
        if let Some(field) = key.strip_prefix("lop.") {
            let Some(lop) = &mut world.bodies[i].lop else {
                return Answer(self.not_allowed(
                    i,
                    world,
                    "it is pinned to one model (no controller); release it first",
                ));
            };
            let p = &mut self.policies[i];
            match field {
                "rest_speed" => p.rest_speed = value,
                _ => p.hold = value,
            }
            lop.set_policy(*p);
            if let Some(l) = &mut self.rest[i].1 {
                l.set_policy(*p);
            }
            tracing::info!("control: {}: {key} = {value}", world.bodies[i].name);
            return Answer(self.describe(i, world, CONTROL_STATUS_OK, &format!("{key} = {value}")));
        }
        let mut spec = self.scene.bodies[i].clone();
        if let Some(field) = key.strip_prefix("fem.") {
            let Some(fem) = &mut spec.fem else {
                return Answer(self.not_allowed(i, world, "it has no [body.fem] parameters"));
            };
            match field {
                "young" => fem.young = value,
                "poisson" => fem.poisson = value,
                _ => fem.damping = value,
            }
        } else if let Some(field) = key.strip_prefix("msd.") {
            let Some(msd) = &mut spec.msd else {
                return Answer(self.not_allowed(i, world, "it has no [body.msd] parameters"));
            };
            match field {
                "stiffness" => msd.stiffness = value,
                _ => msd.damping = value,
            }
        }
        self.rebuild_or_busy(i, spec, format!("{key} = {value}"), world)
    }

    fn rebuild_or_busy(
        &mut self,
        i: usize,
        spec: BodySpec,
        what: String,
        world: &World,
    ) -> Decision {
        if self.rebuild.is_some() {
            return Decision::Answer(self.busy_rebuilding());
        }
        if world.bodies[i].touched() {
            return Decision::Answer(self.describe(
                i,
                world,
                CONTROL_STATUS_BUSY,
                "the tool is touching it: its model is not swapped under the hand; retry",
            ));
        }
        Decision::Rebuild {
            body: i,
            spec,
            what,
        }
    }

    fn start_rebuild(
        &mut self,
        body: usize,
        spec: BodySpec,
        what: String,
        request: Request,
        world: &World,
    ) {
        let scene = self.scene.clone();
        let mesh: TetMesh = world.bodies[body].mesh.clone();
        let job_spec = spec.clone();
        let job = std::thread::Builder::new()
            .name("lop-control-build".into())
            .spawn(move || {
                scene::body_models(&scene, &job_spec, &mesh).map_err(|e| format!("{e:#}"))
            });
        match job {
            Ok(job) => {
                self.rebuild = Some(Rebuild {
                    body,
                    spec,
                    what,
                    request,
                    job,
                })
            }
            Err(e) => {
                let r = self.describe(
                    body,
                    world,
                    CONTROL_STATUS_FAILED,
                    &format!("cannot start the build: {e}"),
                );
                let _ = request.send_copy(r);
            }
        }
    }

    fn finish_rebuild(&mut self, world: &mut World) {
        if !self.rebuild.as_ref().is_some_and(|r| r.job.is_finished()) {
            return;
        }
        let Rebuild {
            body,
            spec,
            what,
            request,
            job,
        } = self.rebuild.take().expect("checked");
        let name = world.bodies[body].name.clone();
        let resp = match job.join() {
            Ok(Ok((model, mut lop))) => {
                if let Some(l) = &mut lop {
                    l.set_policy(self.policies[body]);
                }
                self.rest[body] = (model.clone(), lop.clone());
                let jump = world.replace_models(body, model, lop);
                self.scene.bodies[body] = spec;
                tracing::info!("control: {name}: {what} (hand-over residual {jump:.2e} m)");
                self.describe(body, world, CONTROL_STATUS_OK, &what)
            }
            Ok(Err(e)) => {
                tracing::warn!("control: {name}: {what} failed: {e}");
                self.describe(body, world, CONTROL_STATUS_FAILED, &format!("{what}: {e}"))
            }
            Err(_) => self.describe(
                body,
                world,
                CONTROL_STATUS_FAILED,
                &format!("{what}: the build panicked"),
            ),
        };
        let _ = request.send_copy(resp);
    }

    fn ok(&self, message: &str) -> ControlResponse {
        self.with_paused(ControlResponse::with(CONTROL_STATUS_OK, message))
    }

    fn busy_rebuilding(&self) -> ControlResponse {
        let what = self
            .rebuild
            .as_ref()
            .map_or(String::new(), |r| r.what.clone());
        self.with_paused(ControlResponse::with(
            CONTROL_STATUS_BUSY,
            &format!("another rebuild is running ({what}); retry"),
        ))
    }

    fn not_allowed(&self, i: usize, world: &World, why: &str) -> ControlResponse {
        let msg = format!("{}: not allowed: {why}", world.bodies[i].name);
        self.describe(i, world, CONTROL_STATUS_NOT_ALLOWED, &msg)
    }

    fn with_paused(&self, mut r: ControlResponse) -> ControlResponse {
        r.paused = self.paused as u8;
        r
    }

    /// A response describing body `i`: pin, current model, parameters.
    fn describe(&self, i: usize, world: &World, status: u32, message: &str) -> ControlResponse {
        let mut r = self.with_paused(ControlResponse::with(status, message));
        let spec = &self.scene.bodies[i];
        r.body_index = i as i32;
        put_str(&mut r.body, &spec.name);
        r.pin = match spec.model {
            ModelPin::Auto => CONTROL_PIN_AUTO,
            ModelPin::Gc => BodyModel::Gc as u8,
            ModelPin::Msd => BodyModel::Msd as u8,
            ModelPin::Fem => BodyModel::Fem as u8,
        };
        r.model = body_model(world.bodies[i].model.kind()) as u8;
        if let Some(f) = &spec.fem {
            r.push_param("fem.young", f.young, true);
            r.push_param("fem.poisson", f.poisson, true);
            r.push_param("fem.damping", f.damping, true);
            r.push_param("fem.density", f.density, false);
            r.push_param("fem.dt", f.dt, false);
        }
        if let Some(m) = &spec.msd {
            r.push_param("msd.stiffness", m.stiffness, true);
            r.push_param("msd.damping", m.damping, true);
            r.push_param("msd.dt", m.dt, false);
        }
        let p = &self.policies[i];
        let controlled = world.bodies[i].lop.is_some();
        r.push_param("lop.rest_speed", p.rest_speed, controlled);
        r.push_param("lop.hold", p.hold, controlled);
        r.push_param("lop.blend", p.blend, false);
        r.push_param(
            "switches",
            world.bodies[i].lop.as_ref().map_or(0, |l| l.switches()) as f64,
            false,
        );
        r.push_param("resets", world.bodies[i].resets as f64, false);
        r
    }
}

/// What to do with a request: answer now, or rebuild a body's models and answer then. Lives
/// for one call on the stack, so the size difference of its variants does not matter.
#[allow(clippy::large_enum_variant)]
enum Decision {
    Answer(ControlResponse),
    Rebuild {
        body: usize,
        spec: BodySpec,
        what: String,
    },
}

/// What a request asks for, checked against the scene's bodies: the body resolved to its
/// index, a `SET` key known and its value in range, a `PIN` model known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// Every body back to rest.
    Reset,
    /// Hold the simulation.
    Pause,
    /// Step again.
    Resume,
    /// Describe body `body`.
    Get {
        /// Index of the body.
        body: usize,
    },
    /// Set a live parameter of body `body`.
    Set {
        /// Index of the body.
        body: usize,
        /// One of [`CONTROL_KEYS`].
        key: &'static str,
        /// The new value, finite and in the key's range.
        value: f64,
    },
    /// Pin body `body` to one model.
    Pin {
        /// Index of the body.
        body: usize,
        /// The model (never `Auto`).
        pin: ModelPin,
    },
    /// Release body `body` to the levels-of-precision controller.
    Release {
        /// Index of the body.
        body: usize,
    },
}

/// Why [`decode`] refused a request: the response's status and message, and the body when the
/// request named one that exists (the answer then describes it).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Refusal {
    /// A `CONTROL_STATUS_*` other than OK.
    pub status: u32,
    /// What is wrong, quoting the offending field's value.
    pub message: String,
    /// The body the request named, if it exists.
    pub body: Option<usize>,
}

/// Decodes and checks a request against the names of the scene's bodies (`bodies[i]` is body
/// `i`): everything that does not depend on the simulation's state, so any request, whatever
/// its bytes, is either a [`Command`] or refused with a message that quotes the bad field —
/// the contract version, the op, the body (index or name), the key or the value (NaN fails
/// every range), the model. Never panics.
pub fn decode(req: &ControlRequest, bodies: &[&str]) -> Result<Command, Refusal> {
    let refuse = |status, message: String, body| Refusal {
        status,
        message,
        body,
    };
    if req.contract_version != CONTRACT_VERSION {
        return Err(refuse(
            CONTROL_STATUS_BAD_REQUEST,
            format!(
                "contract version {}: this daemon speaks {CONTRACT_VERSION}",
                req.contract_version
            ),
            None,
        ));
    }
    match req.op {
        CONTROL_OP_RESET => return Ok(Command::Reset),
        CONTROL_OP_PAUSE => return Ok(Command::Pause),
        CONTROL_OP_RESUME => return Ok(Command::Resume),
        CONTROL_OP_GET | CONTROL_OP_SET | CONTROL_OP_PIN | CONTROL_OP_RELEASE => {}
        op => {
            return Err(refuse(
                CONTROL_STATUS_BAD_REQUEST,
                format!("op {op}: not a control operation (1 get … 7 resume)"),
                None,
            ))
        }
    }
    let found = match usize::try_from(req.body_index) {
        Ok(i) => (i < bodies.len()).then_some(i),
        Err(_) => bodies
            .iter()
            .position(|&b| b.as_bytes() == until_nul(&req.body)),
    };
    let Some(body) = found else {
        let asked = if req.body_index >= 0 {
            format!("index {}", req.body_index)
        } else {
            format!("{:?}", field_text(&req.body))
        };
        return Err(refuse(
            CONTROL_STATUS_UNKNOWN_BODY,
            format!("no body {asked}; bodies: {}", bodies.join(", ")),
            None,
        ));
    };
    match req.op {
        CONTROL_OP_GET => Ok(Command::Get { body }),
        CONTROL_OP_SET => {
            let value = req.value;
            let found = CONTROL_KEYS
                .iter()
                .find(|(k, _)| k.as_bytes() == until_nul(&req.key));
            let Some(&(key, range)) = found else {
                let keys: Vec<&str> = CONTROL_KEYS.iter().map(|(k, _)| *k).collect();
                return Err(refuse(
                    CONTROL_STATUS_UNKNOWN_KEY,
                    format!(
                        "key {:?} unknown; live keys: {}",
                        field_text(&req.key),
                        keys.join(" ")
                    ),
                    Some(body),
                ));
            };
            // Written so that NaN fails every range.
            let ok = match key {
                "fem.young" | "msd.stiffness" | "lop.rest_speed" => {
                    value > 0.0 && value.is_finite()
                }
                "fem.poisson" => (0.0..0.5).contains(&value),
                _ => value >= 0.0 && value.is_finite(),
            };
            if !ok {
                return Err(refuse(
                    CONTROL_STATUS_BAD_VALUE,
                    format!("{key} = {value}: out of range ({range})"),
                    Some(body),
                ));
            }
            Ok(Command::Set { body, key, value })
        }
        CONTROL_OP_PIN => {
            let pin = match req.model {
                0 => ModelPin::Gc,
                1 => ModelPin::Msd,
                2 => ModelPin::Fem,
                m => {
                    return Err(refuse(
                        CONTROL_STATUS_BAD_VALUE,
                        format!("model = {m}: use 0 (GC), 1 (MSD) or 2 (FEM)"),
                        Some(body),
                    ))
                }
            };
            Ok(Command::Pin { body, pin })
        }
        _ => Ok(Command::Release { body }),
    }
}

/// A NUL-padded field's bytes up to the first NUL.
fn until_nul(field: &[u8]) -> &[u8] {
    let end = field.iter().position(|&b| b == 0).unwrap_or(field.len());
    &field[..end]
}

/// A NUL-padded field as text for a message: bytes that are not UTF-8 shown as U+FFFD, so a
/// refusal quotes what was sent rather than a placeholder.
pub fn field_text(field: &[u8]) -> std::borrow::Cow<'_, str> {
    String::from_utf8_lossy(until_nul(field))
}
