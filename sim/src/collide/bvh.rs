//! A bounding-volume hierarchy of axis-aligned boxes over one body's surface triangles, for
//! exact closest-point queries on a deforming surface.
//!
//! - **Build**: top-down, median split of the triangle centroids along the longest axis of their
//!   bounds, at most [`LEAF_SIZE`] triangles per leaf. Nodes are stored in pre-order (a node's
//!   left child follows it, its right child comes after the whole left subtree), so every child
//!   has a larger index than its parent and a refit is one reverse sweep. The ordering is total
//!   (coordinate, then triangle index), so the tree is a pure function of the positions.
//! - **Refit**: every step, the leaf boxes are recomputed from the current positions and merged
//!   upwards: `O(T)`, no allocation. A refitted tree stays correct but loosens as the surface
//!   deforms; when the summed surface area of the inner boxes (relative to the root's, the usual
//!   SAH proxy for query cost) grows past [`REBUILD_GROWTH`]× its value right after the last
//!   build, the tree is rebuilt in place into the same buffers.
//! - **Query**: depth-first nearest-triangle search, nearer child first, pruning boxes farther
//!   than the best distance so far. Ties are broken by the smaller triangle index and only boxes
//!   strictly farther than the best are pruned, so the answer does not depend on the tree's shape
//!   (nor on when it was last rebuilt).

use glam::DVec3;

use crate::contact::closest_bary;
use crate::vec3::v;
// The tests below check against plain-array brute force.
#[cfg(test)]
use crate::contact::closest_point_on_triangle;
#[cfg(test)]
use crate::vec3::{dot, sub};

/// Most triangles in a leaf.
const LEAF_SIZE: usize = 4;
/// Rebuild when the refitted tree's cost proxy exceeds this multiple of its value at build.
const REBUILD_GROWTH: f64 = 1.5;
/// Traversal stack size. Median splits halve the range at every level, so the depth is at most
/// `⌈log2(T)⌉ + 1 ≤ 33` for `u32` triangle indices and the stack never holds more than depth + 1
/// entries.
const STACK: usize = 64;

#[derive(Debug, Clone, Copy)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: first slot in `order`. Inner: index of the right child (the left one is `self + 1`).
    first: u32,
    /// Leaf: number of triangles (> 0). Inner: 0.
    count: u32,
}

/// Closest point of a surface to a query, as found by [`Bvh::nearest`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Nearest {
    /// Triangle index in the surface.
    pub triangle: u32,
    /// Barycentric coordinates of the closest point on it.
    pub bary: [f64; 3],
    /// Query minus closest point, computed as `Σ wᵢ (p − vᵢ)` so that a query lying in the
    /// triangle's plane gives an exact zero along its normal.
    pub offset: DVec3,
    /// Squared length of `offset`.
    pub d2: f64,
}

/// The hierarchy of one surface. All buffers are sized at construction.
#[derive(Debug, Clone)]
pub(crate) struct Bvh {
    nodes: Vec<Node>,
    /// Triangle indices; every leaf owns a contiguous range.
    order: Vec<u32>,
    /// Build scratch: triangle centroids.
    centroids: Vec<DVec3>,
    built: bool,
    /// Cost proxy right after the last build.
    built_cost: f64,
    /// Builds so far (the first one included).
    builds: u64,
    /// Queries treat every box as grown by this much, m (see [`Bvh::set_slack`]).
    slack: f64,
}

#[inline]
fn union(a: &mut Node, lo: DVec3, hi: DVec3) {
    a.lo = a.lo.min(lo);
    a.hi = a.hi.max(hi);
}

#[inline]
fn half_area(lo: DVec3, hi: DVec3) -> f64 {
    let e = hi - lo;
    e.x * e.y + e.y * e.z + e.z * e.x
}

/// Squared distance from `p` to the box `[lo, hi]` (0 inside).
#[inline]
pub(crate) fn box_d2(lo: DVec3, hi: DVec3, p: DVec3) -> f64 {
    let d = (lo - p).max(p - hi).max(DVec3::ZERO);
    d.dot(d)
}

const EMPTY: Node = Node {
    lo: DVec3::INFINITY,
    hi: DVec3::NEG_INFINITY,
    first: 0,
    count: 0,
};

impl Bvh {
    /// Buffers for a surface of `triangles` triangles; the tree itself is built by the first
    /// [`update`](Self::update).
    pub fn new(triangles: usize) -> Bvh {
        Bvh {
            // A binary tree with L ≥ 1 leaves has 2L − 1 nodes, and L ≤ T.
            nodes: Vec::with_capacity((2 * triangles).max(1)),
            order: (0..triangles as u32).collect(),
            centroids: vec![DVec3::ZERO; triangles],
            built: false,
            built_cost: 0.0,
            builds: 0,
            slack: 0.0,
        }
    }

    /// Queries treat every box as grown by `slack` m until the next call: a caller that moved
    /// the vertices by at most `slack` since the last [`update`](Self::update) can query
    /// without one, and the answers stay exact (pruning is looser by `slack`). Tracking how far
    /// the vertices moved lets a caller refit only once that grows past what it accepts,
    /// while a query near an unmoved surface prunes with tight boxes.
    pub fn set_slack(&mut self, slack: f64) {
        self.slack = if slack.is_finite() {
            slack.max(0.0)
        } else {
            0.0
        };
    }

    /// Squared distance from `p` to node `n`'s box grown by the slack (0 inside).
    #[inline]
    fn node_d2(&self, n: &Node, p: DVec3) -> f64 {
        box_d2(n.lo - self.slack, n.hi + self.slack, p)
    }

    /// Number of (re)builds so far.
    pub fn builds(&self) -> u64 {
        self.builds
    }

    /// The box around the whole surface (`lo > hi` for an empty one).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.nodes
            .first()
            .map_or((EMPTY.lo, EMPTY.hi), |r| (r.lo, r.hi))
    }

    /// Brings the boxes up to date with `positions`: a refit, or a rebuild on the first call
    /// and when the refitted tree has loosened too much.
    pub fn update(&mut self, positions: &[[f64; 3]], tris: &[[u32; 3]]) {
        if !self.built {
            self.build(positions, tris);
            return;
        }
        let cost = self.refit(positions, tris);
        if !(cost <= REBUILD_GROWTH * self.built_cost) {
            self.build(positions, tris);
        }
    }

    fn build(&mut self, positions: &[[f64; 3]], tris: &[[u32; 3]]) {
        self.nodes.clear();
        self.built = true;
        self.builds += 1;
        if tris.is_empty() {
            return;
        }
        for (c, t) in self.centroids.iter_mut().zip(tris) {
            let [a, b, d] = t.map(|i| v(positions[i as usize]));
            *c = (a + b + d) / 3.0;
        }
        for (i, o) in self.order.iter_mut().enumerate() {
            *o = i as u32;
        }
        self.split(positions, tris, 0, tris.len());
        self.built_cost = self.cost();
    }

    /// Builds the subtree over `order[s..e]` (non-empty) at the next free node; recursion depth
    /// is the tree depth (≤ 33).
    fn split(&mut self, positions: &[[f64; 3]], tris: &[[u32; 3]], s: usize, e: usize) {
        let me = self.nodes.len();
        let mut node = EMPTY;
        let (mut clo, mut chi) = (EMPTY.lo, EMPTY.hi);
        for &t in &self.order[s..e] {
            for &i in &tris[t as usize] {
                let p = v(positions[i as usize]);
                union(&mut node, p, p);
            }
            let c = self.centroids[t as usize];
            clo = clo.min(c);
            chi = chi.max(c);
        }
        if e - s <= LEAF_SIZE {
            node.first = s as u32;
            node.count = (e - s) as u32;
            self.nodes.push(node);
            return;
        }
        self.nodes.push(node);
        let ext = chi - clo;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let mid = s + (e - s) / 2;
        let centroids = &self.centroids;
        self.order[s..e].select_nth_unstable_by(mid - s, |&a, &b| {
            centroids[a as usize][axis]
                .total_cmp(&centroids[b as usize][axis])
                .then(a.cmp(&b))
        });
        self.split(positions, tris, s, mid);
        self.nodes[me].first = self.nodes.len() as u32;
        self.split(positions, tris, mid, e);
    }

    /// Recomputes every box from `positions`; returns the new cost proxy.
    fn refit(&mut self, positions: &[[f64; 3]], tris: &[[u32; 3]]) -> f64 {
        for i in (0..self.nodes.len()).rev() {
            let n = self.nodes[i];
            let mut fresh = Node {
                first: n.first,
                count: n.count,
                ..EMPTY
            };
            if n.count > 0 {
                let (s, e) = (n.first as usize, (n.first + n.count) as usize);
                for &t in &self.order[s..e] {
                    for &i in &tris[t as usize] {
                        let p = v(positions[i as usize]);
                        union(&mut fresh, p, p);
                    }
                }
            } else {
                let (l, r) = (self.nodes[i + 1], self.nodes[n.first as usize]);
                union(&mut fresh, l.lo, l.hi);
                union(&mut fresh, r.lo, r.hi);
            }
            self.nodes[i] = fresh;
        }
        self.cost()
    }

    /// Summed half surface area of the inner nodes over the root's (1 for a single leaf).
    fn cost(&self) -> f64 {
        let Some(root) = self.nodes.first() else {
            return 0.0;
        };
        let root_area = half_area(root.lo, root.hi);
        if !(root_area > 0.0) {
            return 1.0;
        }
        let inner: f64 = self
            .nodes
            .iter()
            .filter(|n| n.count == 0)
            .map(|n| half_area(n.lo, n.hi))
            .sum();
        (inner / root_area).max(1.0)
    }

    /// The closest triangle to `p` (ties: the smaller index) if it is at most `sqrt(max_d2)`
    /// away (`f64::INFINITY`: any distance); `None` if none is, or the surface is empty.
    /// Returns the number of triangles tested too.
    pub fn nearest(
        &self,
        positions: &[[f64; 3]],
        tris: &[[u32; 3]],
        p: [f64; 3],
        max_d2: f64,
    ) -> (Option<Nearest>, usize) {
        let p = v(p);
        let mut best: Option<Nearest> = None;
        let mut best_d2 = max_d2;
        let mut tested = 0;
        if self.nodes.is_empty() {
            return (None, 0);
        }
        let mut stack = [0u32; STACK];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let n = &self.nodes[stack[top] as usize];
            if self.node_d2(n, p) > best_d2 {
                continue;
            }
            if n.count > 0 {
                let (s, e) = (n.first as usize, (n.first + n.count) as usize);
                for &t in &self.order[s..e] {
                    tested += 1;
                    let [a, b, c] = tris[t as usize].map(|i| v(positions[i as usize]));
                    let w = closest_bary(p, a, b, c);
                    let (pa, pb, pc) = (p - a, p - b, p - c);
                    let offset = pa * w[0] + pb * w[1] + pc * w[2];
                    let d2 = offset.dot(offset);
                    let better = match best {
                        None => d2 <= best_d2,
                        Some(b) => d2 < best_d2 || (d2 == best_d2 && t < b.triangle),
                    };
                    if better {
                        best_d2 = d2;
                        best = Some(Nearest {
                            triangle: t,
                            bary: w,
                            offset,
                            d2,
                        });
                    }
                }
            } else {
                let (l, r) = (stack[top] + 1, n.first);
                let (dl, dr) = (
                    self.node_d2(&self.nodes[l as usize], p),
                    self.node_d2(&self.nodes[r as usize], p),
                );
                // Push the farther child first so the nearer one is searched first.
                let (near, d_near, far, d_far) = if dl <= dr {
                    (l, dl, r, dr)
                } else {
                    (r, dr, l, dl)
                };
                if d_far <= best_d2 {
                    stack[top] = far;
                    top += 1;
                }
                if d_near <= best_d2 {
                    stack[top] = near;
                    top += 1;
                }
            }
        }
        (best, tested)
    }
}

impl Bvh {
    /// Calls `f` with every triangle whose box overlaps the box `[lo, hi]` (each once, in tree
    /// order). Allocation-free.
    pub fn overlapping(&self, lo: DVec3, hi: DVec3, f: impl FnMut(u32)) {
        let (lo, hi) = (lo - self.slack, hi + self.slack);
        self.visit(|n| n.lo.cmple(hi).all() && n.hi.cmpge(lo).all(), f);
    }

    /// Calls `f` with every triangle whose box comes within `radius` of `centre` (each once,
    /// in tree order): a sphere's query, which on a fine surface visits far fewer boxes than
    /// the cube around the sphere (the cube's faces cut the surface over an area of `(2r)²`,
    /// the sphere over a cap). Allocation-free.
    pub fn near_sphere(&self, centre: DVec3, radius: f64, f: impl FnMut(u32)) {
        let r2 = radius * radius;
        self.visit(|n| self.node_d2(n, centre) <= r2, f);
    }

    /// Depth-first over the nodes `keep` accepts: `f` with the triangles of every accepted
    /// leaf, in tree order.
    fn visit(&self, keep: impl Fn(&Node) -> bool, mut f: impl FnMut(u32)) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = [0u32; STACK];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let i = stack[top] as usize;
            let n = &self.nodes[i];
            if !keep(n) {
                continue;
            }
            if n.count > 0 {
                let (s, e) = (n.first as usize, (n.first + n.count) as usize);
                self.order[s..e].iter().for_each(|&t| f(t));
            } else {
                stack[top] = n.first;
                stack[top + 1] = i as u32 + 1;
                top += 2;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force over every triangle, same tie rule.
    fn brute(positions: &[[f64; 3]], tris: &[[u32; 3]], p: [f64; 3]) -> (u32, f64) {
        let mut best = (u32::MAX, f64::INFINITY);
        for (t, tri) in tris.iter().enumerate() {
            let [a, b, c] = tri.map(|v| positions[v as usize]);
            let w = closest_point_on_triangle(p, a, b, c);
            let (pa, pb, pc) = (sub(p, a), sub(p, b), sub(p, c));
            let o = [0, 1, 2].map(|k| w[0] * pa[k] + w[1] * pb[k] + w[2] * pc[k]);
            let d2 = dot(o, o);
            if d2 < best.1 {
                best = (t as u32, d2);
            }
        }
        best
    }

    /// A bumpy closed-ish grid surface (a height field), enough triangles for several levels.
    fn sheet(n: u32, bump: f64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let mut pos = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (i as f64 / n as f64, j as f64 / n as f64);
                pos.push([x, y, bump * (7.0 * x).sin() * (5.0 * y).cos()]);
            }
        }
        let mut tris = Vec::new();
        let id = |i: u32, j: u32| j * (n + 1) + i;
        for j in 0..n {
            for i in 0..n {
                tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        (pos, tris)
    }

    #[test]
    fn nearest_matches_brute_force_after_build_refit_and_rebuild() {
        let (mut pos, tris) = sheet(12, 0.05);
        let mut bvh = Bvh::new(tris.len());
        let queries: Vec<[f64; 3]> = (0..200)
            .map(|i| {
                let f = i as f64;
                [
                    (f * 0.137).fract() * 1.4 - 0.2,
                    (f * 0.291).fract() * 1.4 - 0.2,
                    (f * 0.533).fract() * 0.6 - 0.3,
                ]
            })
            .collect();
        for step in 0..6 {
            bvh.update(&pos, &tris);
            for &q in &queries {
                let (hit, tested) = bvh.nearest(&pos, &tris, q, f64::INFINITY);
                let hit = hit.unwrap();
                let (t, d2) = brute(&pos, &tris, q);
                assert_eq!((hit.triangle, hit.d2), (t, d2), "step {step}, query {q:?}");
                assert!(tested <= tris.len());
                // Bounded: the same hit within reach, nothing beyond.
                let (near, _) = bvh.nearest(&pos, &tris, q, d2 * (1.0 + 1e-9));
                assert_eq!(near.map(|h| (h.triangle, h.d2)), Some((t, d2)));
                let (far, _) = bvh.nearest(&pos, &tris, q, d2 * 0.999);
                assert!(far.is_none() || d2 == 0.0);
            }
            // Deform: a twist and stretch (refit), then a fold that scatters neighbouring
            // vertices across the sheet, so the refitted boxes balloon and the tree is rebuilt.
            if step == 3 {
                for p in pos.iter_mut() {
                    p[0] = (p[0] * 3.7).fract();
                }
                continue;
            }
            for p in pos.iter_mut() {
                let a = 0.3 * (p[0] - 0.5);
                let (c, s) = (a.cos(), a.sin());
                let (y, z) = (p[1] - 0.5, p[2]);
                p[1] = 0.5 + c * y - s * z;
                p[2] = s * y + c * z;
                p[0] *= 1.3;
            }
        }
        assert!(bvh.builds() >= 2, "the scattered tree was never rebuilt");
        assert!(
            bvh.builds() < 6,
            "smooth deformation should refit, not rebuild"
        );
    }

    /// With the vertices moved by up to `s` since the last update and the slack set to `s`,
    /// the sphere query still meets every triangle that comes within the radius (checked on the
    /// moved positions by brute force), and the box query every triangle overlapping the box.
    #[test]
    fn slack_keeps_sphere_and_box_queries_complete() {
        let (pos, tris) = sheet(12, 0.05);
        let mut bvh = Bvh::new(tris.len());
        bvh.update(&pos, &tris);
        let s = 0.02;
        let moved: Vec<[f64; 3]> = pos
            .iter()
            .map(|p| {
                let k = (p[0] * 31.0 + p[1] * 17.0).sin();
                [p[0] + 0.5 * s * k, p[1] - 0.5 * s * k, p[2] + 0.5 * s * k]
            })
            .collect();
        let tri_box = |t: usize| {
            let [a, b, c] = tris[t].map(|i| v(moved[i as usize]));
            (a.min(b).min(c), a.max(b).max(c))
        };
        let mut missed_without_slack = 0;
        for i in 0..100 {
            let f = i as f64;
            let c = DVec3::new((f * 0.137).fract(), (f * 0.291).fract(), 0.06);
            let r = 0.02 + 0.1 * (f * 0.533).fract();
            let want: Vec<u32> = (0..tris.len())
                .filter(|&t| {
                    let (lo, hi) = tri_box(t);
                    box_d2(lo, hi, c) <= r * r
                })
                .map(|t| t as u32)
                .collect();
            let got = |bvh: &Bvh| {
                let mut got = Vec::new();
                bvh.near_sphere(c, r, |t| got.push(t));
                got
            };
            bvh.set_slack(0.0);
            let tight = got(&bvh);
            missed_without_slack += want.iter().filter(|t| !tight.contains(t)).count();
            bvh.set_slack(s);
            let loose = got(&bvh);
            for t in &want {
                assert!(loose.contains(t), "query {i}: triangle {t} missed");
            }
            let mut in_box = Vec::new();
            bvh.overlapping(c - r, c + r, |t| in_box.push(t));
            for t in 0..tris.len() {
                let (lo, hi) = tri_box(t);
                if lo.cmple(c + r).all() && hi.cmpge(c - r).all() {
                    assert!(in_box.contains(&(t as u32)), "box {i}: triangle {t} missed");
                }
            }
        }
        // The motion matters: without the slack the stale boxes miss some.
        assert!(missed_without_slack > 0);
    }

    #[test]
    fn empty_surface() {
        let mut bvh = Bvh::new(0);
        bvh.update(&[], &[]);
        assert!(bvh.nearest(&[], &[], [0.0; 3], f64::INFINITY).0.is_none());
        let (lo, hi) = bvh.bounds();
        assert!(lo[0] > hi[0]);
    }
}
