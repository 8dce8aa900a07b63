//! The local model between frames: how the force on the hand follows the hand's motion tick by
//! tick while the tissue's next frame is being computed.
//!
//! A frame's contact patch comes with its [`PatchResponse`](crate::interaction::PatchResponse):
//! the force the step balanced `R_k` against the device at `c_k`, and `K_k = ∂R/∂c`, the tool
//! spring in series with the tissue's compliance at the patch over one step. The deformation
//! process adds the patch's *free motion*: how fast the force changed between its last two
//! steps beyond what the device's move explains, `Ṙ_k = (R_k − R_{k−1} − K_{k−1} (c_k −
//! c_{k−1})) / h` (the tissue still settling, or still catching up with an earlier push). Each
//! haptic tick then renders
//!
//! ```text
//! R(c, t) = R_k + K_k (c − c_k) + Ṙ_k · min(t − t_k, h)
//! ```
//!
//! on the tissue, the opposite on the hand: the coupling of device and tissue solved with the
//! frame's linearisation, so the force follows the hand between frames and a new frame, which
//! solves the same coupling with the full model, lands where the local model already was (the
//! jump is the linearisation's error, not the age of the frame). The free motion is
//! extrapolated for at most one step `h` of the body: beyond, a frame is late and the tissue is
//! held where the last one left it rather than guessed at.
//!
//! The patch only pushes: a predicted force that no longer presses along the frame's force
//! (the device pulled back past the point where the tissue lets go) renders zero. The model is
//! used only when every number in it is finite and the stiffness is symmetric and no stiffer
//! than the tool spring ([`LocalModel::is_valid`]); a frame without one, or with a broken one,
//! leaves the haptic loop on the god-object's force against the frame's surface.
//!
//! Everything here is `Copy` arithmetic on fixed arrays: allocation-free.

use glam::DVec3;

use super::god::{hand_force, GodState};
use crate::contact::ForceLaw;
use crate::vec3::v;

/// What a frame tells the haptic loop about the contact patch it balanced.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LocalModel {
    /// The device position the step balanced against, m.
    pub device: [f64; 3],
    /// The force the tissue received, N.
    pub force: [f64; 3],
    /// `∂(force on tissue) / ∂(device position)`, row-major, N/m.
    pub stiffness: [[f64; 3]; 3],
    /// The free motion: the rate the force changes with the device held, N/s.
    pub drift: [f64; 3],
    /// How long the free motion may be extrapolated, s (the body's step).
    pub horizon: f64,
}

impl LocalModel {
    /// Whether the model can be used against a tool spring of `tool_stiffness` N/m: every
    /// number finite, a force that presses, a stiffness that is symmetric, positive
    /// semi-definite on the axes and no stiffer than the tool (to a relative 1e-6), a horizon
    /// of at most one second.
    pub fn is_valid(&self, tool_stiffness: f64) -> bool {
        let finite = self
            .device
            .iter()
            .chain(&self.force)
            .chain(self.stiffness.iter().flatten())
            .chain(&self.drift)
            .all(|x| x.is_finite());
        if !(finite && tool_stiffness.is_finite() && tool_stiffness > 0.0) {
            return false;
        }
        let k = &self.stiffness;
        let limit = tool_stiffness * (1.0 + 1e-6);
        let symmetric =
            (0..3).all(|i| (0..3).all(|j| (k[i][j] - k[j][i]).abs() <= 1e-6 * tool_stiffness));
        let bounded = (0..3).all(|i| k[i][i] >= -1e-9 * tool_stiffness && k[i][i] <= limit);
        symmetric && bounded && v(self.force).length() > 0.0 && (0.0..=1.0).contains(&self.horizon)
    }

    /// The force on the tissue with the device at `device`, `elapsed` seconds after the step
    /// (see the module docs); zero once it no longer presses.
    pub fn force_on_tissue(&self, device: [f64; 3], elapsed: f64) -> [f64; 3] {
        let t = if elapsed.is_finite() {
            elapsed.clamp(0.0, self.horizon)
        } else {
            0.0
        };
        let r0 = v(self.force);
        let r = v(self.force_on_tissue_linear(device)) + v(self.drift) * t;
        if r.dot(r0) > 0.0 && r.is_finite() {
            r.to_array()
        } else {
            [0.0; 3]
        }
    }
}

/// What the hand feels this tick: with a valid local model of the patch on the body the
/// god-object rests on (not grabbing, linear law), the opposite of the model's force on the
/// tissue at the device `device`, `elapsed` seconds after its step; otherwise the force law
/// on the god-object's gap ([`hand_force`]). Damping (N·s/m, on the device's `velocity`
/// along the force) as `hand_force` applies it. Returns the force on the hand and whether the
/// local model rendered it.
#[allow(clippy::too_many_arguments)]
pub fn contact_force(
    god: &GodState,
    local: Option<(usize, &LocalModel)>,
    elapsed: f64,
    device: [f64; 3],
    law: ForceLaw,
    stiffness: f64,
    damping: f64,
    velocity: [f64; 3],
) -> ([f64; 3], bool) {
    let usable = match (god.anchor, local) {
        (Some(a), Some((body, m))) => {
            a.body == body && !god.grabbing && law == ForceLaw::Linear && m.is_valid(stiffness)
        }
        _ => false,
    };
    let Some((_, m)) = local.filter(|_| usable) else {
        return (hand_force(god, law, stiffness, damping, velocity), false);
    };
    let on_tissue = v(m.force_on_tissue(device, elapsed));
    let mut hand = -on_tissue;
    let len = hand.length();
    if len > 0.0 && damping > 0.0 && velocity.iter().all(|c| c.is_finite()) {
        let u = hand / len;
        hand = u * (len - damping * v(velocity).dot(u)).max(0.0);
    }
    if hand.is_finite() {
        (hand.to_array(), true)
    } else {
        ([0.0; 3], false)
    }
}

/// Builds the frames' free motion from a body's consecutive patch steps: feed it every step of
/// the body ([`FreeMotion::step`]); it pairs a step with the previous one when both pressed a
/// patch.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FreeMotion {
    last: Option<LocalModel>,
}

impl FreeMotion {
    /// Records a step of `h` seconds that balanced `force` against `device` with the
    /// response `stiffness` (`None`: the step pressed no patch), and returns the step's local
    /// model with its free motion (zero when the previous step pressed no patch).
    pub fn step(
        &mut self,
        h: f64,
        response: Option<(crate::interaction::PatchResponse, [f64; 3])>,
    ) -> Option<LocalModel> {
        let Some((r, force)) = response else {
            self.last = None;
            return None;
        };
        let mut m = LocalModel {
            device: r.device,
            force,
            stiffness: r.stiffness,
            drift: [0.0; 3],
            horizon: h.max(0.0),
        };
        if let Some(p) = self.last {
            if h > 0.0 {
                let explained = v(p.force_on_tissue_linear(r.device));
                let drift = (v(force) - explained) / h;
                if drift.is_finite() {
                    m.drift = drift.to_array();
                }
            }
        }
        self.last = Some(m);
        Some(m)
    }

    /// Forgets the last step (the body was reset or changed model).
    pub fn reset(&mut self) {
        self.last = None;
    }
}

impl LocalModel {
    /// `R_k + K_k (c − c_k)`, without the free motion and the one-sidedness.
    fn force_on_tissue_linear(&self, device: [f64; 3]) -> [f64; 3] {
        let d = v(device) - v(self.device);
        let k = &self.stiffness;
        (v(self.force) + DVec3::new(v(k[0]).dot(d), v(k[1]).dot(d), v(k[2]).dot(d))).to_array()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::interaction::PatchResponse;

    fn model() -> LocalModel {
        LocalModel {
            device: [0.0, 0.0, -0.001],
            force: [0.0, 0.0, -0.2],
            stiffness: [[20.0, 0.0, 0.0], [0.0, 20.0, 0.0], [0.0, 0.0, 100.0]],
            drift: [0.0, 0.0, 5.0],
            horizon: 1e-3,
        }
    }

    #[test]
    fn follows_the_device_and_lets_go() {
        let m = model();
        assert!(m.is_valid(300.0));
        assert_eq!(m.force_on_tissue(m.device, 0.0), m.force);
        // 1 mm deeper (−z): 0.1 N more on the tissue.
        let f = m.force_on_tissue([0.0, 0.0, -0.002], 0.0);
        assert!((f[2] + 0.3).abs() < 1e-12, "{f:?}");
        // The free motion for at most one step: 5 N/s × 1 ms.
        let f = m.force_on_tissue(m.device, 0.5e-3);
        assert!((f[2] + 0.1975).abs() < 1e-12, "{f:?}");
        assert_eq!(
            m.force_on_tissue(m.device, 1.0),
            m.force_on_tissue(m.device, 1e-3)
        );
        // Pulled back 2 mm: the tissue lets go.
        assert_eq!(m.force_on_tissue([0.0, 0.0, 0.001], 0.0), [0.0; 3]);
        assert_eq!(m.force_on_tissue([f64::NAN; 3], 0.0), [0.0; 3]);
    }

    /// Without a model, with a broken one, on another body or while grabbing, the force is the
    /// god-object's law; with a good one, the model's.
    #[test]
    fn falls_back_to_the_force_law() {
        use super::super::god::Anchor;
        let god = GodState {
            proxy: [0.0, 0.0, 0.0],
            anchor: Some(Anchor {
                body: 2,
                triangle: 7,
                bary: [1.0, 0.0, 0.0],
                offset: [0.0, 0.0, 0.003],
            }),
            grabbing: false,
            depth: 0.001,
            direction: [0.0, 0.0, 1.0],
        };
        let device = [0.0, 0.0, -0.001];
        let law = hand_force(&god, ForceLaw::Linear, 300.0, 0.0, [0.0; 3]);
        let call = |g: &GodState, local: Option<(usize, &LocalModel)>| {
            let (f, used) = contact_force(
                g,
                local,
                0.0,
                device,
                ForceLaw::Linear,
                300.0,
                0.0,
                [0.0; 3],
            );
            let usable = local.is_some_and(|(b, m)| b == 2 && !g.grabbing && m.is_valid(300.0));
            assert_eq!(used, usable);
            f
        };
        assert_eq!(call(&god, None), law);
        let mut nan = model();
        nan.stiffness[2][2] = f64::NAN;
        assert_eq!(call(&god, Some((2, &nan))), law);
        let good = model();
        assert_eq!(call(&god, Some((1, &good))), law, "another body");
        let grab = GodState {
            grabbing: true,
            ..god
        };
        assert_eq!(
            call(&grab, Some((2, &good))),
            hand_force(&grab, ForceLaw::Linear, 300.0, 0.0, [0.0; 3])
        );
        let f = call(&god, Some((2, &good)));
        assert_eq!(f, good.force_on_tissue(device, 0.0).map(|c| -c));
    }

    #[test]
    fn broken_models_are_refused() {
        let ok = model();
        assert!(!ok.is_valid(50.0), "stiffer than the tool");
        let mut m = ok;
        m.stiffness[0][1] = 5.0;
        assert!(!m.is_valid(300.0), "not symmetric");
        let mut m = ok;
        m.drift[1] = f64::NAN;
        assert!(!m.is_valid(300.0), "NaN");
        let mut m = ok;
        m.force = [0.0; 3];
        assert!(!m.is_valid(300.0), "no press");
        assert!(!LocalModel::default().is_valid(300.0));
    }

    #[test]
    fn free_motion_is_what_the_device_does_not_explain() {
        let mut fm = FreeMotion::default();
        let k = [[0.0; 3], [0.0; 3], [0.0, 0.0, 100.0]];
        let step = |fm: &mut FreeMotion, c: f64, f: f64| {
            fm.step(
                1e-3,
                Some((
                    PatchResponse {
                        device: [0.0, 0.0, c],
                        stiffness: k,
                    },
                    [0.0, 0.0, f],
                )),
            )
            .unwrap()
        };
        assert_eq!(step(&mut fm, 0.0, -0.1).drift, [0.0; 3]);
        // The device moved 0.1 mm along −z (explains −0.01 N); the force moved −0.012 N.
        let m = step(&mut fm, -1e-4, -0.112);
        assert!((m.drift[2] + 2.0).abs() < 1e-9, "{:?}", m.drift);
        assert_eq!(fm.step(1e-3, None), None);
        assert_eq!(step(&mut fm, 0.0, -0.1).drift, [0.0; 3]);
    }
}
