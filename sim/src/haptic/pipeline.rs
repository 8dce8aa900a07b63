//! The haptic tick as one pure value: [`HapticPipeline`].
//!
//! Every force a hand feels comes out of [`HapticPipeline::tick`], whoever drives it: the live
//! loop of `lopd haptic` (its own deadlines, the device's driver, frames from shared memory),
//! the OpenHaptics servo callback (the device's scheduler is the clock) and the offline closed
//! loop (a simulated hand, the world stepped in the same process on simulated time). The
//! drivers are thin adapters: they read the device, hand the pipeline the surfaces it renders
//! against ([`ContactSurfaces`]), write the force it returns and publish the tool state. The
//! stages, in order, each timed ([`Stage`]):
//!
//! 1. **validate**: the reading is finite and inside the device's workspace (with a slack), and
//!    is mapped into the scene; a missing or broken reading makes the tick unhealthy;
//! 2. **surface**: the newest surface is brought up to date around the tool (the adapter's
//!    [`ContactSurfaces::refresh`]: copy what the tool can reach from the newest frame, or
//!    synchronise with the world);
//! 3. **god-object**: the proxy moves towards the device against that surface;
//! 4. **force**: the frame's local model of the contact patch when it has one, the force law on
//!    the god-object's gap otherwise ([`contact_force`]); for [`TOPOLOGY_GLIDE_TICKS`] after the
//!    surfaces changed topology (a cut, [`ContactSurfaces::topology_changed`]) it glides from the
//!    last force rendered to that one, a 1/n-th of the way on the tick with n ticks left: the
//!    tissue that vanished under the tool is felt giving way over 50 ms, not in one tick;
//! 5. **passivity**: the observer and controller at the device port
//!    ([`PassivityController`]);
//! 6. **safety**: finite, clamped, ramped to zero on unhealthy data, step-limited
//!    ([`ForceSafety`]).
//!
//! The pipeline allocates nothing after [`HapticPipeline::new`], takes no lock and formats
//! nothing: the live loop's real-time promise holds through it (the daemon's allocation tests
//! drive it). The clock is passed in, as the world's round takes it, so offline runs time their
//! stages on a counter and stay deterministic.

use super::god::{Anchor, GodObject, GodState};
use super::local::{contact_force, LocalModel};
use super::passivity::PassivityController;
use super::safety::ForceSafety;
use super::surface::SurfaceSet;
use super::workspace::WorkspaceTransform;
use crate::contact::ToolSphere;

/// Device samples farther than this outside the device's workspace are rejected as broken, mm.
pub const WORKSPACE_SLACK_MM: f64 = 20.0;

/// Everything the pipeline needs that is decided before the first tick.
#[derive(Debug, Clone)]
pub struct PipelineSettings {
    /// Tick rate, Hz.
    pub rate_hz: f64,
    /// Ticks from full force to zero when data goes bad.
    pub ramp_ticks: u32,
    /// Force clamp, N: the smallest of the daemon's, the scene tool's and the device's.
    pub max_force: f64,
    /// The device's continuous force, N (infinite: none), averaged over about two seconds.
    pub max_continuous_force: f64,
    /// Largest force change per tick beyond what the hand's motion explains, N.
    pub max_step: f64,
    /// Device → scene mapping.
    pub workspace: WorkspaceTransform,
    /// The device's usable workspace box, mm (a reading beyond it by more than
    /// [`WORKSPACE_SLACK_MM`] is broken).
    pub workspace_min_mm: [f64; 3],
    pub workspace_max_mm: [f64; 3],
    /// The tool tip (its centre is the device's each tick) and the scene's law.
    pub tool: ToolSphere,
    /// Tool stiffness against each body, in topology order (the body's own, else the tool's;
    /// clamped to what the device renders).
    pub body_stiffness: Vec<f64>,
    /// Tool damping, N·s/m.
    pub damping: f64,
    /// Render with the frames' local model between frames.
    pub local_model: bool,
    /// The passivity controller's largest damping, N·s/m (0: off).
    pub passivity_max_damping: f64,
    /// The grab button holds the tissue (the tool's kind: a probe or a grasper; a hook does
    /// not hold, its grab button is ignored).
    pub holds: bool,
    /// The heat button cauterizes (a probe or a hook; not a grasper). The pipeline renders no
    /// heat; the loops that pass the button to the deformation read it here.
    pub cauterizes: bool,
}

impl PipelineSettings {
    /// Tick period, s.
    pub fn period(&self) -> f64 {
        1.0 / self.rate_hz
    }

    /// Whether a reading at `mm` is inside the workspace box with its slack (NaN is not).
    pub fn in_workspace(&self, mm: [f64; 3]) -> bool {
        (0..3).all(|k| {
            mm[k] >= self.workspace_min_mm[k] - WORKSPACE_SLACK_MM
                && mm[k] <= self.workspace_max_mm[k] + WORKSPACE_SLACK_MM
        })
    }

    /// The tool's stiffness against `body` (the tool's own for an unknown body), N/m.
    pub fn stiffness(&self, body: usize) -> f64 {
        self.body_stiffness
            .get(body)
            .copied()
            .unwrap_or(self.tool.stiffness)
    }
}

/// One reading of the device, in its own frame and units.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DeviceReading {
    /// Tool-tip position, mm.
    pub position_mm: [f64; 3],
    /// Tool-tip velocity, mm/s.
    pub velocity_mm_s: [f64; 3],
    /// The grab button is pressed.
    pub grab: bool,
}

/// What the pipeline renders against: the god-object over the newest surfaces, and the local
/// model of the newest frame. The live loop implements it over a frame from shared memory, the
/// offline closed loop over the world it steps.
pub trait ContactSurfaces {
    /// The surface stage: brings the surfaces up to date for the tool at `tip` (scene m;
    /// `None` without a valid reading). False when there is nothing to touch (no surface yet,
    /// or one that does not match): the god-object then does not move.
    fn refresh(&mut self, tip: Option<[f64; 3]>) -> bool;

    /// The god-object and the surfaces it moves against (`None` while there are none).
    fn god_object(&mut self) -> Option<(&mut GodObject, &mut SurfaceSet)>;

    /// The newest frame's local model of the contact patch (the body it pressed and the
    /// model), and the seconds since the step it linearises balanced; `None` without one.
    fn local_model(&self) -> Option<(usize, LocalModel, f64)>;

    /// Whether the surfaces' topology changed since the last call (a cut landed): true once
    /// per change. The default: never.
    fn topology_changed(&mut self) -> bool {
        false
    }
}

/// Ticks over which the force glides to the new surfaces' after a topology change (a cut): at
/// 1 kHz 50 ms. The shipped liver's cut under a pressing tool drops 0.28 N; over 50 ticks that
/// is 6 mN a tick, under the 8–10 mN a tick of the same poke's contact onset (measured live).
pub const TOPOLOGY_GLIDE_TICKS: u32 = 50;

/// The timed stages of a tick, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    Validate,
    Surface,
    GodObject,
    Force,
    Passivity,
    Safety,
}

impl Stage {
    /// Every stage, in order.
    pub const ALL: [Stage; 6] = [
        Stage::Validate,
        Stage::Surface,
        Stage::GodObject,
        Stage::Force,
        Stage::Passivity,
        Stage::Safety,
    ];

    /// Its name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Validate => "validate",
            Stage::Surface => "surface",
            Stage::GodObject => "god_object",
            Stage::Force => "force",
            Stage::Passivity => "passivity",
            Stage::Safety => "safety",
        }
    }
}

/// What one tick decided.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickOutput {
    /// The reading passed validation.
    pub valid: bool,
    /// The data behind the force can be trusted (a valid reading and a fresh surface); when
    /// false the force is ramping to zero.
    pub healthy: bool,
    /// The tool tip in the scene, m (`None` without a valid reading).
    pub tip: Option<[f64; 3]>,
    /// The surfaces were ready and the god-object moved against them.
    pub surface_ready: bool,
    /// The god-object after the tick (`None` when it did not move).
    pub god: Option<GodState>,
    /// The tool stiffness against the touched body, N/m (0 without contact).
    pub stiffness: f64,
    /// The force came from the frame's local model.
    pub local: bool,
    /// The force on the hand, scene frame, N: finite and clamped.
    pub force: [f64; 3],
    /// The same in the device's frame: what to write to the device.
    pub device_force: [f64; 3],
}

impl TickOutput {
    /// The material point the god-object rests on or holds.
    pub fn anchor(&self) -> Option<Anchor> {
        self.god.and_then(|g| g.anchor)
    }

    /// The tool presses a surface (the device behind the proxy).
    pub fn pressing(&self) -> bool {
        self.god
            .is_some_and(|g| g.anchor.is_some() && g.depth > 0.0)
    }

    /// The tool holds tissue.
    pub fn grabbing(&self) -> bool {
        self.god.is_some_and(|g| g.anchor.is_some() && g.grabbing)
    }
}

/// The haptic tick's state across ticks: the passivity account and the safety's memory.
#[derive(Debug, Clone)]
pub struct HapticPipeline {
    settings: PipelineSettings,
    passivity: PassivityController,
    safety: ForceSafety,
    /// Ticks left of a glide after a topology change ([`TOPOLOGY_GLIDE_TICKS`]), from the last
    /// force rendered (the passivity controller's, [`PassivityController::last_rendered`]).
    glide: u32,
    /// Nanoseconds each stage took in the last tick, by [`Stage`] order (filled by `tick`).
    stage_ns: [u64; Stage::ALL.len()],
}

impl HapticPipeline {
    /// A pipeline with `settings` (its only allocation is the settings themselves).
    pub fn new(settings: PipelineSettings) -> HapticPipeline {
        HapticPipeline {
            passivity: PassivityController::new(settings.passivity_max_damping),
            // The device's continuous force, as a mean over about 2 s.
            safety: ForceSafety::new(settings.max_force, settings.max_step, settings.ramp_ticks)
                .with_continuous(
                    settings.max_continuous_force,
                    (2.0 * settings.rate_hz) as u32,
                ),
            settings,
            glide: 0,
            stage_ns: [0; Stage::ALL.len()],
        }
    }

    /// The settings.
    pub fn settings(&self) -> &PipelineSettings {
        &self.settings
    }

    /// The passivity controller's account.
    pub fn passivity(&self) -> &PassivityController {
        &self.passivity
    }

    /// How long each stage took in the last tick, ns, in [`Stage::ALL`] order.
    pub fn stage_ns(&self) -> [u64; Stage::ALL.len()] {
        self.stage_ns
    }

    /// The device was not driven for a while: the force starts over from zero and ramps in
    /// ([`ForceSafety::restart`]).
    pub fn restart_force(&mut self) {
        self.safety.restart();
    }

    /// One tick (see the module docs). `reading` is the device's (`None`: it failed);
    /// `surface_fresh` tells whether the newest surface is within the stale limit; `clock`
    /// gives nanoseconds for the stage timings. Allocation-free.
    pub fn tick(
        &mut self,
        reading: Option<DeviceReading>,
        surface_fresh: bool,
        surfaces: &mut impl ContactSurfaces,
        mut clock: impl FnMut() -> u64,
    ) -> TickOutput {
        let s = &self.settings;
        let t0 = clock();

        // 1. Validate and map into the scene.
        let reading = reading.filter(|r| {
            r.position_mm
                .iter()
                .chain(&r.velocity_mm_s)
                .all(|c| c.is_finite())
                && s.in_workspace(r.position_mm)
        });
        let tip = reading.map(|r| s.workspace.device_to_scene(r.position_mm));
        let healthy = reading.is_some() && surface_fresh;
        let t1 = clock();

        // 2. The newest surface around the tool.
        let surface_ready = surfaces.refresh(tip);
        if surfaces.topology_changed() {
            self.glide = TOPOLOGY_GLIDE_TICKS;
        }
        let t2 = clock();

        // 3. The god-object against it.
        let god = match (reading, tip) {
            (Some(r), Some(p)) if surface_ready => surfaces
                .god_object()
                .map(|(god, set)| god.update(set, p, r.grab && s.holds)),
            _ => None,
        };
        let t3 = clock();

        // 4. The force: the frame's local model between frames, else the law on the gap.
        let mut desired = [0.0; 3];
        let mut stiffness = 0.0;
        let mut local = false;
        if let (Some(g), Some(r), Some(p)) = (god, reading, tip) {
            if let Some(a) = g.anchor {
                stiffness = s.stiffness(a.body);
                let scale = 1e-3 * s.workspace.scale;
                let velocity = s
                    .workspace
                    .device_dir_to_scene(r.velocity_mm_s)
                    .map(|c| c * scale);
                let model = surfaces.local_model().filter(|_| s.local_model);
                let (f, used) = contact_force(
                    &g,
                    model.as_ref().map(|(b, m, _)| (*b, m)),
                    model.map_or(0.0, |(_, _, e)| e),
                    p,
                    s.tool.law,
                    stiffness,
                    s.damping,
                    velocity,
                );
                desired = f;
                local = used;
            }
        }
        if self.glide > 0 {
            let n = f64::from(self.glide);
            for (d, l) in desired.iter_mut().zip(self.passivity.last_rendered()) {
                *d = l + (*d - l) / n;
            }
            self.glide -= 1;
        }
        let t4 = clock();

        // 5. Passivity at the device port (the stylus in metres, device scale).
        match tip {
            Some(p) if healthy => {
                let port = p.map(|c| c / s.workspace.scale);
                desired = self.passivity.condition(port, desired, s.period());
            }
            _ => self.passivity.reset(),
        }
        let t5 = clock();

        // 6. Safety: the force may follow the tool spring as fast as the device moves.
        let k = stiffness.max(s.tool.stiffness);
        let force = self.safety.condition_moving(desired, healthy, tip, k);
        self.passivity.rendered(force);
        let device_force = s.workspace.scene_dir_to_device(force);
        let t6 = clock();

        let t = [t0, t1, t2, t3, t4, t5, t6];
        self.stage_ns = std::array::from_fn(|i| t[i + 1].saturating_sub(t[i]));
        TickOutput {
            valid: reading.is_some(),
            healthy,
            tip,
            surface_ready,
            god,
            stiffness,
            local,
            force,
            device_force,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contact::ForceLaw;
    use crate::haptic::workspace::WorkspaceMap;

    /// A 20 cm square floor at z = 0, facing +z, as one body.
    struct Floor {
        set: SurfaceSet,
        god: GodObject,
        /// A topology change not yet reported.
        changed: bool,
    }

    impl Floor {
        fn new(radius: f64) -> Floor {
            let tris: &[[u32; 3]] = &[[0, 1, 2], [0, 2, 3]];
            let mut set = SurfaceSet::new(4, &[tris]);
            let c = [
                [-0.1, -0.1, 0.0],
                [0.1, -0.1, 0.0],
                [0.1, 0.1, 0.0],
                [-0.1, 0.1, 0.0],
            ];
            set.set_positions(|i| c[i]);
            let god = GodObject::new(radius, 2);
            Floor {
                set,
                god,
                changed: false,
            }
        }

        /// A cut takes the floor's top `dz` metres away: the surface is that much lower, a new
        /// topology, the god-object's proxy carried over as the live index carries it.
        fn cut_down(&mut self, dz: f64) {
            let c = [
                [-0.1, -0.1, -dz],
                [0.1, -0.1, -dz],
                [0.1, 0.1, -dz],
                [-0.1, 0.1, -dz],
            ];
            self.set.set_positions(|i| c[i]);
            let old = self.god.clone();
            self.god.keep_proxy_of(&old);
            self.changed = true;
        }
    }

    impl ContactSurfaces for Floor {
        fn refresh(&mut self, _tip: Option<[f64; 3]>) -> bool {
            true
        }
        fn god_object(&mut self) -> Option<(&mut GodObject, &mut SurfaceSet)> {
            Some((&mut self.god, &mut self.set))
        }
        fn local_model(&self) -> Option<(usize, LocalModel, f64)> {
            None
        }
        fn topology_changed(&mut self) -> bool {
            std::mem::take(&mut self.changed)
        }
    }

    fn settings() -> PipelineSettings {
        PipelineSettings {
            rate_hz: 1000.0,
            ramp_ticks: 10,
            max_force: 3.0,
            max_continuous_force: f64::INFINITY,
            max_step: 0.05,
            workspace: WorkspaceMap::default().transform(),
            workspace_min_mm: [-100.0; 3],
            workspace_max_mm: [100.0; 3],
            tool: ToolSphere {
                center: [0.0; 3],
                radius: 0.002,
                stiffness: 500.0,
                law: ForceLaw::Linear,
            },
            body_stiffness: vec![500.0],
            damping: 0.0,
            local_model: true,
            passivity_max_damping: 0.0,
            holds: true,
            cauterizes: true,
        }
    }

    fn at(z_mm: f64) -> Option<DeviceReading> {
        Some(DeviceReading {
            position_mm: [0.0, 0.0, z_mm],
            ..Default::default()
        })
    }

    fn counter() -> impl FnMut() -> u64 {
        let mut n = 0;
        move || {
            n += 10;
            n
        }
    }

    #[test]
    fn a_press_renders_the_spring_on_the_gap_and_every_stage_is_timed() {
        let mut p = HapticPipeline::new(settings());
        let mut floor = Floor::new(0.002);
        // Approach from above (the god-object starts where the device first is), then press
        // 1 mm below the resting proxy, slowly enough for the step limit.
        let mut out = p.tick(at(10.0), true, &mut floor, counter());
        assert_eq!(out.force, [0.0; 3]);
        for k in 0..=40 {
            out = p.tick(at(2.0 - 0.025 * k as f64), true, &mut floor, counter());
        }
        assert!(out.pressing() && out.healthy && out.valid);
        // Proxy on the floor at z = r = 2 mm, device at 1 mm: 1 mm × 500 N/m upward (the
        // god-object rests 0.1 µm off the surface: 50 µN more at most).
        assert!((out.force[2] - 0.5).abs() < 1e-4, "{:?}", out.force);
        assert!(out.force[0].abs() < 1e-12 && out.force[1].abs() < 1e-12);
        assert_eq!(out.stiffness, 500.0);
        assert_eq!(out.device_force, out.force, "identity workspace");
        assert_eq!(p.stage_ns(), [10; 6]);
    }

    #[test]
    fn a_cut_under_the_tool_is_felt_giving_way_over_the_glide() {
        for glide in [true, false] {
            let mut p = HapticPipeline::new(settings());
            let mut floor = Floor::new(0.002);
            let mut out = p.tick(at(10.0), true, &mut floor, counter());
            for k in 0..=40 {
                out = p.tick(at(2.0 - 0.025 * k as f64), true, &mut floor, counter());
            }
            let pressed = out.force[2];
            assert!((pressed - 0.5).abs() < 1e-3, "{pressed}");
            // The tissue under the tool goes (5 mm): the device, 1 mm below the old surface,
            // is now 4 mm above the new one.
            floor.cut_down(0.005);
            floor.changed = glide;
            let mut largest: f64 = 0.0;
            let mut last = pressed;
            for _ in 0..TOPOLOGY_GLIDE_TICKS + 5 {
                out = p.tick(at(1.0), true, &mut floor, counter());
                largest = largest.max((out.force[2] - last).abs());
                last = out.force[2];
            }
            assert_eq!(out.force, [0.0; 3], "the tool hangs free in the wound");
            if glide {
                // 0.5 N over 50 ticks: 10 mN a tick, evenly.
                let even = pressed / f64::from(TOPOLOGY_GLIDE_TICKS);
                assert!((largest - even).abs() < 1e-9, "{largest} N a tick");
            } else {
                // Without the glide only the safety's step limit (50 mN a tick) holds it.
                assert!((largest - 0.05).abs() < 1e-9, "{largest} N a tick");
            }
        }
    }

    #[test]
    fn the_grab_button_holds_only_with_a_tool_that_holds() {
        let grab = |z_mm: f64| at(z_mm).map(|r| DeviceReading { grab: true, ..r });
        for holds in [true, false] {
            let mut p = HapticPipeline::new(PipelineSettings {
                holds,
                ..settings()
            });
            let mut floor = Floor::new(0.002);
            let mut out = p.tick(at(10.0), true, &mut floor, counter());
            for k in 0..=40 {
                out = p.tick(grab(2.0 - 0.025 * k as f64), true, &mut floor, counter());
            }
            // Touching with the button held: a probe or grasper holds, a hook presses.
            assert_eq!(out.grabbing(), holds);
            assert!(out.pressing());
        }
    }

    #[test]
    fn broken_readings_and_stale_surfaces_ramp_the_force_to_zero() {
        for broken in [
            None,
            Some(DeviceReading {
                position_mm: [f64::NAN, 0.0, 1.0],
                ..Default::default()
            }),
            // Beyond the workspace and its slack.
            at(100.0 + WORKSPACE_SLACK_MM + 1.0),
        ] {
            for stale in [false, true] {
                let mut p = HapticPipeline::new(settings());
                let mut floor = Floor::new(0.002);
                p.tick(at(10.0), true, &mut floor, counter());
                let mut out = p.tick(at(2.0), true, &mut floor, counter());
                for k in 0..40 {
                    out = p.tick(at(2.0 - 0.025 * k as f64), true, &mut floor, counter());
                }
                let held = out.force[2];
                assert!(held > 0.4, "{held}");
                let (reading, fresh) = if stale {
                    (out.tip.map(|_| at(1.0).unwrap()), false)
                } else {
                    (broken, true)
                };
                let mut forces = Vec::new();
                for _ in 0..10 {
                    let o = p.tick(reading, fresh, &mut floor, counter());
                    assert!(!o.healthy);
                    assert_eq!(o.valid, stale, "{reading:?}");
                    forces.push(o.force[2]);
                }
                // Linear to exactly zero within the ramp's ten ticks.
                assert!(forces.windows(2).all(|w| w[1] < w[0]), "{forces:?}");
                assert_eq!(forces[9], 0.0);
                assert!((forces[0] - 0.9 * held).abs() < 1e-12);
            }
        }
    }
}
