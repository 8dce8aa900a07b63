//! A touch rehearsed at load: what a body's touched step costs on this machine, before any
//! tool reaches it.
//!
//! The pace ([`super::pace`]) starts a body at the shortest period its step fits in. A step
//! from rest (no tool, nothing moving) is the cheapest a body ever takes: the solver converges
//! at once and there is no contact patch. A touched step costs 3–8 times more on the organs a
//! lab brings (the god-object's patch with its columns of `K̃⁻¹`, a moving body, CG iterating),
//! so a pace started from rest started every 5k organ at 1 ms and lost time at its first touch
//! until its window moved it. [`World::rehearse_touch`] pokes the body with the tool before
//! the run, as a hand would: the god-object resting on a surface triangle far from the fixed
//! nodes, the device going into the tissue along the triangle's normal at a steady speed, to
//! `depth` past the surface at the last step (2 mm over 50 steps of 1 ms is 40 mm/s, a brisk
//! poke), the first `warm` steps untimed and the other `timed` timed, then the body back at
//! rest. Their median is what a live touched step costs, up to the live round's own work.
//! (A first version put the device `depth` in at once: the sudden press made CG iterate as no
//! poke does, and it read the shipped liver's step 2–4 times dearer than live.)

use super::World;
use crate::contact::{ForceLaw, ToolSphere};
use crate::model::{ToolAnchor, ToolContact};
use crate::patch::{gather, GatherScratch, GatherSphere, PatchTool, ToolPatch, MAX_PATCH};
use crate::vec3::{add, cross, norm, scale, sub, v};

/// What [`World::rehearse_touch`] measured.
#[derive(Debug, Clone, PartialEq)]
pub struct Rehearsal {
    /// The surface triangle pressed.
    pub triangle: u32,
    /// Each timed step's wall time, s, in order.
    pub costs: Vec<f64>,
    /// The force on the tissue at the last step, N.
    pub force: f64,
}

impl Rehearsal {
    /// The median of [`Rehearsal::costs`], s.
    pub fn median(&self) -> f64 {
        let mut c = self.costs.clone();
        c.sort_by(f64::total_cmp);
        c.get(c.len() / 2).copied().unwrap_or(0.0)
    }
}

impl World {
    /// Pokes body `i`'s precise FEM model (running, or parked behind its levels-of-precision
    /// controller) with `tool` (its radius and stiffness; its centre and law are ignored: the
    /// god-object's press is linear) as the god-object would, the device reaching `depth` (m)
    /// past the surface at a steady speed over `warm` + `timed` steps, timing the last `timed`
    /// with `now_ns` (module docs). The model is put back at rest afterwards
    /// (positions, velocities, rotations; a factor it made meanwhile is kept), the body's time
    /// and reports untouched. `None` for a body without an FEM model, or with no surface
    /// triangle whose nodes are all free.
    pub fn rehearse_touch(
        &mut self,
        i: usize,
        tool: ToolSphere,
        depth: f64,
        warm: usize,
        timed: usize,
        now_ns: &mut dyn FnMut() -> u64,
    ) -> Option<Rehearsal> {
        let gravity = self.gravity;
        let surface = self.bodies.get(i)?.mesh.surface.clone();
        let node_triangles = self.bodies[i].node_triangles.clone();
        let fem = self.fem_mut(i)?;
        let x0 = fem.positions().to_vec();
        let triangle = far_free_triangle(&surface, &x0, &|k| fem.is_held(k))?;
        let [a, b, c] = surface[triangle as usize].map(|k| x0[k as usize]);
        let centroid = ((v(a) + v(b) + v(c)) / 3.0).to_array();
        let normal = cross(sub(b, a), sub(c, a));
        let area = norm(normal);
        if !(area > 0.0 && area.is_finite()) {
            return None;
        }
        let n = scale(normal, 1.0 / area);
        let radius = tool.radius.max(1e-4);
        let proxy = add(centroid, scale(n, radius));
        let anchor = ToolAnchor::from_proxy(&surface, &x0, triangle, [1.0 / 3.0; 3], proxy, false)?;
        let mut points = Vec::with_capacity(MAX_PATCH);
        let mut scratch = GatherScratch::new(surface.len(), x0.len());
        let mut costs = Vec::with_capacity(timed);
        let mut force = 0.0;
        let steps = warm + timed;
        for k in 0..steps {
            let device = sub(proxy, scale(n, depth * (k + 1) as f64 / steps as f64));
            let sphere = ToolSphere {
                center: device,
                radius,
                stiffness: tool.stiffness,
                law: ForceLaw::Linear,
            };
            let tools = [PatchTool {
                device,
                stiffness: tool.stiffness,
            }];
            points.clear();
            let x = fem.positions();
            let Some(proxy) = anchor.proxy(&surface, x) else {
                break;
            };
            gather(
                &surface,
                &node_triangles,
                x,
                GatherSphere {
                    start: triangle,
                    proxy,
                    radius,
                    tool: 0,
                },
                MAX_PATCH,
                &mut points,
                &mut scratch,
            );
            let contact = ToolContact {
                tool: sphere,
                surface: &surface,
                candidates: &[],
                anchor: Some(anchor),
                patch: (!points.is_empty()).then_some(ToolPatch {
                    tools: &tools,
                    points: &points,
                    holds: &[],
                }),
            };
            let t0 = now_ns();
            let r = fem.step(gravity, &[], Some(&contact));
            let t1 = now_ns();
            match r {
                Ok(report) => force = norm(report.force_on_tissue),
                Err(_) => break,
            }
            if k >= warm {
                costs.push(t1.saturating_sub(t0) as f64 * 1e-9);
            }
        }
        fem.reset();
        (!costs.is_empty()).then_some(Rehearsal {
            triangle,
            costs,
            force,
        })
    }
}

/// The surface triangle, of those whose three nodes are free, whose centroid lies farthest
/// from the fixed nodes' centroid (from the body's centroid when nothing is fixed): where a
/// press moves the most tissue.
fn far_free_triangle(
    surface: &[[u32; 3]],
    x: &[[f64; 3]],
    held: &dyn Fn(usize) -> bool,
) -> Option<u32> {
    let mean = |nodes: &mut dyn Iterator<Item = [f64; 3]>| {
        let (sum, n) = nodes.fold((glam::DVec3::ZERO, 0usize), |(s, n), p| (s + v(p), n + 1));
        (n > 0).then(|| sum / n as f64)
    };
    let from = mean(&mut (0..x.len()).filter(|&k| held(k)).map(|k| x[k]))
        .or_else(|| mean(&mut x.iter().copied()))?;
    surface
        .iter()
        .enumerate()
        .filter(|(_, t)| {
            t.iter()
                .all(|&k| (k as usize) < x.len() && !held(k as usize))
        })
        .map(|(i, t)| {
            let c = t.iter().map(|&k| v(x[k as usize])).sum::<glam::DVec3>() / 3.0;
            (i as u32, c.distance_squared(from))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::{box_mesh, Fem, FemMode, FemParameters};
    use crate::model::Model;

    /// A 20 × 10 × 10 mm bar of 2 mm cells held on its x = 0 face.
    fn bar() -> World {
        let mesh = box_mesh([0.02, 0.01, 0.01], [10, 5, 5], |p| p[0] < 1e-9);
        let params = FemParameters {
            young: 5e3,
            poisson: 0.3,
            density: 1050.0,
            damping: 20.0,
            dt: 1e-3,
            mode: FemMode::Corotational,
        };
        let fem = Fem::new(&mesh, params).unwrap();
        let mut w = World::new([0.0, 0.0, -9.81]);
        w.add_model("bar", mesh, Model::Fem(fem));
        w
    }

    #[test]
    fn a_rehearsed_touch_presses_the_free_end_and_leaves_the_body_at_rest() {
        let mut w = bar();
        let rest = w.bodies[0].model.positions().to_vec();
        let tool = ToolSphere {
            center: [1.0; 3],
            radius: 0.002,
            stiffness: 300.0,
            law: ForceLaw::Linear,
        };
        let mut clock = 0u64;
        let mut now = || {
            clock += 1_000;
            clock
        };
        let r = w.rehearse_touch(0, tool, 0.002, 4, 12, &mut now).unwrap();
        // The far end: the x = 20 mm face.
        let tri = w.bodies[0].mesh.surface[r.triangle as usize];
        for k in tri {
            assert!(
                (rest[k as usize][0] - 0.02).abs() < 1e-12,
                "{:?}",
                rest[k as usize]
            );
        }
        // One cost per timed step (the made-up clock's 1 µs between its two reads).
        assert_eq!(r.costs.len(), 12);
        assert!(
            r.costs.iter().all(|&c| (c - 1e-6).abs() < 1e-15),
            "{:?}",
            r.costs
        );
        assert!((r.median() - 1e-6).abs() < 1e-15);
        // The tool pressed: a force on the tissue, at most its spring stretched by the whole
        // depth (the tissue only gives way; this soft bar gives most of it).
        assert!(
            r.force > 1e-3 && r.force <= 300.0 * 0.002 * (1.0 + 1e-9),
            "{}",
            r.force
        );
        // And the body is back at rest, its clock and reports as they were.
        assert_eq!(w.bodies[0].model.positions(), &rest[..]);
        assert_eq!(w.bodies[0].time, 0.0);
        assert!(!w.bodies[0].touched());
    }

    #[test]
    fn a_body_held_everywhere_is_not_rehearsed() {
        let mesh = box_mesh([0.01; 3], [2, 2, 2], |_| true);
        let params = FemParameters {
            young: 5e3,
            poisson: 0.3,
            density: 1050.0,
            damping: 20.0,
            dt: 1e-3,
            mode: FemMode::Linear,
        };
        let fem = Fem::new(&mesh, params).unwrap();
        let mut w = World::new([0.0; 3]);
        w.add_model("held", mesh, Model::Fem(fem));
        let tool = ToolSphere {
            center: [0.0; 3],
            radius: 0.002,
            stiffness: 300.0,
            law: ForceLaw::Linear,
        };
        assert!(w.rehearse_touch(0, tool, 0.002, 1, 1, &mut || 0).is_none());
    }
}
