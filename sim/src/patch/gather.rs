//! Gathering a tool's contact points: the walk over the surface from where the god-object
//! rests, outwards, to the points its sphere covers (see the module above).

use super::{bary_point_of, PatchPoint, MAX_PATCH};
use crate::contact::{bary_point, closest_bary, unit_normal};
use crate::vec3::v;

/// Scratch for [`gather`], sized once for a surface.
#[derive(Debug, Clone, Default)]
pub struct GatherScratch {
    pub(crate) queue: Vec<u32>,
    pub(crate) tri_stamp: Vec<u32>,
    pub(crate) node_stamp: Vec<u32>,
    stamp: u32,
}

impl GatherScratch {
    /// Scratch for a surface of `triangles` triangles over `nodes` nodes.
    pub fn new(triangles: usize, nodes: usize) -> GatherScratch {
        GatherScratch {
            queue: Vec::with_capacity(triangles),
            tri_stamp: vec![0; triangles],
            node_stamp: vec![0; nodes],
            stamp: 0,
        }
    }

    /// A fresh stamp for a walk (every triangle and node unmarked).
    pub(crate) fn next_stamp(&mut self) -> u32 {
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.tri_stamp.iter_mut().for_each(|t| *t = 0);
            self.node_stamp.iter_mut().for_each(|t| *t = 0);
            self.stamp = 1;
        }
        self.stamp
    }
}

/// How far beyond the sphere a point is still gathered, as a fraction of the radius: it may
/// come into contact during the step (its force stays zero if it does not).
pub const REACH_MARGIN: f64 = 0.05;

/// The sphere of one tool for [`gather`]: where it rests and its radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GatherSphere {
    /// The triangle the god-object rests on: the walk starts there.
    pub start: u32,
    /// The sphere's centre (the god-object's proxy), m.
    pub proxy: [f64; 3],
    /// The tool's radius, m.
    pub radius: f64,
    /// The tool the points are for ([`PatchPoint::tool`]).
    pub tool: u32,
}

/// Appends to `out` the contact points of `sphere` on a surface at positions `x`, walking
/// outwards over the triangles from the sphere's start through `node_triangles` (for each
/// node, the triangles using it), until `out` holds `max` points (at most [`MAX_PATCH`]).
/// Call once per tool pressing the body, after clearing `out`. Allocation-free once the
/// scratch is sized.
pub fn gather(
    surface: &[[u32; 3]],
    node_triangles: &[Vec<u32>],
    x: &[[f64; 3]],
    sphere: GatherSphere,
    max: usize,
    out: &mut Vec<PatchPoint>,
    s: &mut GatherScratch,
) {
    let GatherSphere {
        start,
        proxy,
        radius,
        tool,
    } = sphere;
    let max = max.min(MAX_PATCH);
    let first = out.len();
    if s.tri_stamp.len() < surface.len() || s.node_stamp.len() < x.len() {
        return;
    }
    let Some(tri0) = surface.get(start as usize) else {
        return;
    };
    if tri0.iter().any(|&k| k as usize >= x.len()) || !(radius > 0.0) {
        return;
    }
    let stamp = s.next_stamp();
    let c = v(proxy);
    let reach = radius * (1.0 + REACH_MARGIN);
    s.queue.clear();
    s.queue.push(start);
    s.tri_stamp[start as usize] = stamp;
    let mut head = 0;
    while head < s.queue.len() && out.len() < max {
        let t = s.queue[head];
        head += 1;
        let tri = surface[t as usize];
        if tri.iter().any(|&k| k as usize >= x.len()) {
            continue;
        }
        let [a, b, cc] = tri.map(|k| v(x[k as usize]));
        let w = closest_bary(c, a, b, cc);
        let p = bary_point(a, b, cc, w);
        let dist = (p - c).length();
        if !(dist < reach) && t != start {
            continue;
        }
        // Node points.
        for &k in &tri {
            if s.node_stamp[k as usize] == stamp {
                continue;
            }
            s.node_stamp[k as usize] = stamp;
            let d = v(x[k as usize]) - c;
            let len = d.length();
            if len < reach && len > 1e-9 * radius && out.len() < max {
                out.push(PatchPoint {
                    nodes: [k; 3],
                    weights: [1.0, 0.0, 0.0],
                    normal: (d / len).to_array(),
                    reach: radius,
                    tool,
                });
            }
        }
        // The face point, unless it is a vertex (a node point), with the face's allowance.
        let on_vertex = w.iter().filter(|&&wi| wi > 1e-9).count() <= 1;
        let longest = (b - a)
            .length()
            .max((cc - b).length())
            .max((a - cc).length());
        // The allowance: how far the face may dip into the sphere between its nodes. A face
        // within the tool's footprint sags between nodes that carry the tool, by about
        // `h²/(6r)` where they rest on the sphere, so its face point must not hold the sphere
        // up there. A face reaching beyond the tool (an organ meshed coarser than the tool)
        // carries the tool itself and gets none, or the tool would sink into it. Between the
        // two the allowance fades with the distance of the face's farthest node beyond reach,
        // to nothing one tool radius further out: a function of the positions alone, so the
        // force stays continuous as nodes come into reach.
        let sag = (longest * longest / (6.0 * radius)).min(radius / 20.0);
        let farthest = tri
            .iter()
            .map(|&k| (v(x[k as usize]) - c).length())
            .fold(0.0f64, f64::max);
        let allowance = sag * (1.0 - (farthest - reach) / radius).clamp(0.0, 1.0);
        if !on_vertex && dist < reach && out.len() < max {
            let normal = if dist > 1e-9 * radius {
                (p - c) / dist
            } else {
                -unit_normal(a, b, cc)
            };
            if normal.is_finite() {
                let duplicate = out[first..].iter().any(|q| {
                    q.nodes != [q.nodes[0]; 3]
                        && (bary_point_of(q, x) - p).length() < 1e-12 * radius.max(1.0)
                });
                if !duplicate {
                    out.push(PatchPoint {
                        nodes: tri,
                        weights: w,
                        normal: normal.to_array(),
                        reach: radius - allowance,
                        tool,
                    });
                }
            }
        }
        // Walk on through the triangles around this one.
        for &k in &tri {
            for &n in &node_triangles[k as usize] {
                if s.tri_stamp[n as usize] != stamp {
                    s.tri_stamp[n as usize] = stamp;
                    s.queue.push(n);
                }
            }
        }
    }
}
