//! The surfaces the tool can touch: every body's outward triangles over one shared node array,
//! with what the contact queries need — vertex adjacency for the greedy walk, vertex → triangle
//! incidence, and one refittable bounding-volume hierarchy per body.
//!
//! Built once per topology ([`SurfaceSet::new`] allocates everything); after that, updating the
//! positions and every query are allocation-free, so the 1 kHz loop can own one.

use glam::DVec3;

use crate::collide::bvh::{box_d2, Bvh};
use crate::contact::{bary_point, closest_bary, unit_normal, SurfaceHit};
use crate::vec3::v;

/// How far a node may move before its body's hierarchy is refitted, m. Until then queries
/// treat the boxes as grown by the largest distance a node has moved since the last refit, so
/// answers stay exact; a refit costs one pass over the body's triangles. Tissue under the tool
/// moves a few mm/s to cm/s, so on an organ's centimetre triangles most frames need no refit.
pub const REFIT_MARGIN: f64 = 0.002;

/// A sphere query that meets more leaf triangles than this on a body whose nodes have moved
/// since its last refit refits it before the next query. The slack costs the queries: a tool
/// sphere of radius `r` resting on a surface reaches boxes within `√(2 r s)` of its contact at
/// slack `s`, hundreds of triangles on a surface meshed at 0.2 mm under a 3 mm tool at
/// `s` = 0.25 mm. A coarse organ stays under this at the full [`REFIT_MARGIN`]; a finely
/// meshed one is refitted as often as its queries need.
const CROWDED_QUERY: usize = 64;

/// A surface query's answer: the body, the triangle (index into [`SurfaceSet::triangles`]) and
/// the closest point on it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Closest {
    /// Body index.
    pub body: usize,
    /// The closest point; `hit.triangle` is the global triangle index.
    pub hit: SurfaceHit,
    /// The surface vertex the walk ended on (the warm start of the next query).
    pub vertex: u32,
}

/// What the last queries cost, for benchmarks and tests.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct QueryStats {
    /// Greedy-walk queries run.
    pub walks: u64,
    /// Vertices visited by the walks.
    pub walk_steps: u64,
    /// Queries where the hierarchy found a closer triangle than the walk (the walk was stuck in
    /// a local minimum).
    pub fallbacks: u64,
    /// Hierarchy refits.
    pub refits: u64,
}

/// Every body's surface over one node array.
#[derive(Debug, Clone)]
pub struct SurfaceSet {
    tris: Vec<[u32; 3]>,
    /// Per body: its triangles are `tris[start..end]`.
    body_tris: Vec<(usize, usize)>,
    /// Per body: bounding box of its nodes (updated with the positions).
    body_box: Vec<(DVec3, DVec3)>,
    /// Per body: its surface nodes (the nodes its triangles use, each once, ascending) are
    /// `surface_nodes[start..end]`. Only these are copied from a frame: a tetrahedral organ
    /// has several times more interior nodes than surface ones, and the tool touches none of
    /// them.
    body_nodes: Vec<(usize, usize)>,
    surface_nodes: Vec<u32>,
    /// Per body: its last sphere query met more than [`CROWDED_QUERY`] triangles.
    crowded: Vec<bool>,
    /// Per body: whether queries consider it (its positions are current).
    active: Vec<bool>,
    /// Per body: the stamp of the positions it holds (see [`SurfaceSet::refresh_reachable`]).
    body_frame: Vec<Option<u64>>,
    /// Per body: a surface vertex to start walks from.
    warm: Vec<u32>,
    /// Surface-vertex adjacency (CSR over all nodes; non-surface nodes have none).
    adj_ptr: Vec<u32>,
    adj: Vec<u32>,
    /// Vertex → incident global triangles (CSR).
    vtri_ptr: Vec<u32>,
    vtri: Vec<u32>,
    bvh: Vec<Bvh>,
    dirty: Vec<bool>,
    x: Vec<[f64; 3]>,
    /// Positions at each body's last refit, and per body the largest distance a node has
    /// moved since (squared): the hierarchies' boxes carry [`REFIT_MARGIN`], so a body whose
    /// nodes all stayed within it needs no refit.
    refit_x: Vec<[f64; 3]>,
    drift2: Vec<f64>,
    stats: QueryStats,
}

impl SurfaceSet {
    /// The surfaces of bodies whose triangles are `body_triangles[b]` (global node indices into a
    /// node array of `node_count` nodes). Indices out of range are dropped.
    pub fn new(node_count: usize, body_triangles: &[&[[u32; 3]]]) -> SurfaceSet {
        let mut tris: Vec<[u32; 3]> = Vec::new();
        let mut body_tris = Vec::new();
        for bt in body_triangles {
            let start = tris.len();
            tris.extend(
                bt.iter()
                    .filter(|t| t.iter().all(|&v| (v as usize) < node_count)),
            );
            body_tris.push((start, tris.len()));
        }
        // Vertex → triangles.
        let mut count = vec![0u32; node_count + 1];
        for t in &tris {
            for &v in t {
                count[v as usize + 1] += 1;
            }
        }
        for i in 0..node_count {
            count[i + 1] += count[i];
        }
        let vtri_ptr = count.clone();
        let mut fill = count;
        let mut vtri = vec![0u32; tris.len() * 3];
        for (t, tri) in tris.iter().enumerate() {
            for &v in tri {
                vtri[fill[v as usize] as usize] = t as u32;
                fill[v as usize] += 1;
            }
        }
        // Vertex adjacency from triangle edges, deduplicated.
        let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); node_count];
        for t in &tris {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                neighbours[a as usize].push(b);
                neighbours[b as usize].push(a);
            }
        }
        let mut adj_ptr = Vec::with_capacity(node_count + 1);
        let mut adj = Vec::new();
        adj_ptr.push(0);
        for n in &mut neighbours {
            n.sort_unstable();
            n.dedup();
            adj.extend_from_slice(n);
            adj_ptr.push(adj.len() as u32);
        }
        let warm = body_tris
            .iter()
            .map(|&(s, e)| if s < e { tris[s][0] } else { 0 })
            .collect();
        let bvh = body_tris.iter().map(|&(s, e)| Bvh::new(e - s)).collect();
        let bodies = body_tris.len();
        let mut surface_nodes = Vec::new();
        let body_nodes = body_tris
            .iter()
            .map(|&(s, e)| {
                let mut nodes: Vec<u32> = tris[s..e].iter().flatten().copied().collect();
                nodes.sort_unstable();
                nodes.dedup();
                let start = surface_nodes.len();
                surface_nodes.extend(nodes);
                (start, surface_nodes.len())
            })
            .collect();
        SurfaceSet {
            tris,
            body_tris,
            body_box: vec![(DVec3::ZERO, DVec3::ZERO); bodies],
            body_nodes,
            surface_nodes,
            crowded: vec![false; bodies],
            active: vec![true; bodies],
            body_frame: vec![None; bodies],
            warm,
            adj_ptr,
            adj,
            vtri_ptr,
            vtri,
            bvh,
            dirty: vec![true; bodies],
            x: vec![[0.0; 3]; node_count],
            refit_x: vec![[0.0; 3]; node_count],
            drift2: vec![f64::INFINITY; bodies],
            stats: QueryStats::default(),
        }
    }

    /// Number of bodies.
    pub fn bodies(&self) -> usize {
        self.body_tris.len()
    }

    /// All triangles, bodies concatenated (global node indices).
    pub fn triangles(&self) -> &[[u32; 3]] {
        &self.tris
    }

    /// The global triangle range of body `b`.
    pub fn body_triangles(&self, b: usize) -> std::ops::Range<usize> {
        let (s, e) = self.body_tris[b];
        s..e
    }

    /// The body owning global triangle `t`.
    pub fn body_of(&self, t: usize) -> Option<usize> {
        self.body_tris.iter().position(|&(s, e)| t >= s && t < e)
    }

    /// Current positions of the surface nodes (indexed by node; interior nodes are not kept
    /// and read as the origin or an old value).
    pub fn positions(&self) -> &[[f64; 3]] {
        &self.x
    }

    /// Query statistics since creation.
    pub fn stats(&self) -> QueryStats {
        self.stats
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.x.len()
    }

    /// Replaces the positions: `at(i)` for every surface node `i` (interior nodes are not
    /// asked for). Hierarchies are refitted lazily, only for bodies a query reaches.
    /// Allocation-free.
    pub fn set_positions(&mut self, mut at: impl FnMut(usize) -> [f64; 3]) {
        for &i in &self.surface_nodes {
            self.x[i as usize] = at(i as usize);
        }
        for b in 0..self.body_tris.len() {
            let (s, e) = self.body_tris[b];
            let mut lo = DVec3::INFINITY;
            let mut hi = DVec3::NEG_INFINITY;
            for t in &self.tris[s..e] {
                for &i in t {
                    let p = v(self.x[i as usize]);
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
            }
            self.body_box[b] = (lo, hi);
            self.dirty[b] = true;
            self.drift2[b] = f64::INFINITY;
            self.active[b] = true;
        }
    }

    /// Replaces the positions of body `b`'s surface nodes only (`at(i)` for each of them) and
    /// makes it active; the other bodies keep theirs. Allocation-free.
    pub fn set_body_positions(&mut self, b: usize, mut at: impl FnMut(usize) -> [f64; 3]) {
        let Some(&(n0, n1)) = self.body_nodes.get(b) else {
            return;
        };
        let mut lo = DVec3::INFINITY;
        let mut hi = DVec3::NEG_INFINITY;
        let mut drift2 = self.drift2[b];
        for &i in &self.surface_nodes[n0..n1] {
            let i = i as usize;
            let p = at(i);
            self.x[i] = p;
            let p = v(p);
            let d = p - v(self.refit_x[i]);
            drift2 = drift2.max(d.dot(d));
            lo = lo.min(p);
            hi = hi.max(p);
        }
        self.body_box[b] = (lo, hi);
        self.drift2[b] = drift2;
        self.dirty[b] = true;
        self.active[b] = true;
    }

    /// Brings the set up to date with a frame for the bodies the tool can reach: a body whose
    /// bounds `bounds(b)` (from the frame) are within `reach` of one of `points` gets its
    /// positions from `at` — once per stamp `stamp(b)`, which changes whenever the body's
    /// positions may have (a frame sequence, or something that changes with each of the body's
    /// steps) — and takes part in queries; the others are left out until they come within
    /// reach. Copying only what the tool can touch, and only when it moved, keeps a frame's
    /// arrival cheap on the haptic tick. Returns whether any positions changed.
    pub fn refresh_reachable(
        &mut self,
        stamp: impl Fn(usize) -> u64,
        points: &[[f64; 3]],
        reach: f64,
        bounds: impl Fn(usize) -> ([f64; 3], [f64; 3]),
        mut at: impl FnMut(usize) -> [f64; 3],
    ) -> bool {
        let mut moved = false;
        for b in 0..self.body_tris.len() {
            let (lo, hi) = bounds(b);
            let near = points
                .iter()
                .any(|p| (0..3).all(|k| p[k] >= lo[k] - reach && p[k] <= hi[k] + reach));
            if !near {
                self.active[b] = false;
                continue;
            }
            let fresh = stamp(b);
            if self.body_frame[b] != Some(fresh) {
                self.body_frame[b] = Some(fresh);
                self.set_body_positions(b, &mut at);
                moved = true;
            } else {
                self.active[b] = true;
            }
        }
        moved
    }

    /// Takes body `b` out of (or back into) the queries, e.g. while its positions are stale.
    pub fn set_active(&mut self, b: usize, active: bool) {
        if let Some(a) = self.active.get_mut(b) {
            *a = active;
        }
    }

    /// Whether body `b` is considered by queries.
    pub fn is_active(&self, b: usize) -> bool {
        self.active.get(b).copied().unwrap_or(false)
    }

    /// Whether `p` is within `margin` of body `b`'s bounding box (false for an inactive body).
    pub fn near_body(&self, b: usize, p: [f64; 3], margin: f64) -> bool {
        if !self.active[b] {
            return false;
        }
        let (lo, hi) = self.body_box[b];
        let p = v(p);
        p.cmpge(lo - margin).all() && p.cmple(hi + margin).all()
    }

    /// Refits body `b`'s hierarchy if a node has moved farther than [`REFIT_MARGIN`] since the
    /// last refit or its last sphere query was crowded, and otherwise widens its queries by how
    /// far the nodes did move (a frame that barely moved the body costs nothing here).
    fn refit(&mut self, b: usize) {
        let crowded = std::mem::take(&mut self.crowded[b]);
        if !self.dirty[b] && !crowded {
            return;
        }
        self.dirty[b] = false;
        if !crowded && self.drift2[b] <= REFIT_MARGIN * REFIT_MARGIN {
            self.bvh[b].set_slack(self.drift2[b].sqrt());
            return;
        }
        let (s, e) = self.body_tris[b];
        self.bvh[b].update(&self.x, &self.tris[s..e]);
        let (n0, n1) = self.body_nodes[b];
        for &i in &self.surface_nodes[n0..n1] {
            self.refit_x[i as usize] = self.x[i as usize];
        }
        self.drift2[b] = 0.0;
        self.bvh[b].set_slack(0.0);
        self.stats.refits += 1;
    }

    /// The greedy walk of thesis Algorithm 1: from `start`, move to the neighbour closest to `p`
    /// while one is closer. Returns the vertex it stops on and its squared distance.
    fn walk(&mut self, start: u32, p: DVec3) -> (u32, f64) {
        let d2 = |x: [f64; 3]| {
            let d = p - v(x);
            d.dot(d)
        };
        let mut v = start;
        let mut best = d2(self.x[v as usize]);
        loop {
            let (s, e) = (
                self.adj_ptr[v as usize] as usize,
                self.adj_ptr[v as usize + 1] as usize,
            );
            let mut next = v;
            for &w in &self.adj[s..e] {
                let dw = d2(self.x[w as usize]);
                if dw < best {
                    best = dw;
                    next = w;
                }
            }
            self.stats.walk_steps += 1;
            if next == v {
                return (v, best);
            }
            v = next;
        }
    }

    fn hit(&self, t: usize, p: DVec3) -> SurfaceHit {
        let [a, b, c] = self.corners_v(t);
        let w = closest_bary(p, a, b, c);
        let q = bary_point(a, b, c, w);
        let n = unit_normal(a, b, c);
        let d = p - q;
        SurfaceHit {
            triangle: t,
            point: q.to_array(),
            barycentric: w,
            normal: n.to_array(),
            distance: d.dot(d).sqrt(),
            inside: d.dot(n) < 0.0,
        }
    }

    /// The closest point of body `b`'s surface to `p`, if within `reach`:
    /// 1. the greedy vertex walk from the body's last answer (thesis Algorithm 1);
    /// 2. the closest of the triangles around the vertex it stops on (thesis §5.2);
    /// 3. a check in the body's hierarchy for anything strictly closer — the walk can stop in a
    ///    local minimum on a non-convex surface, or the closest point can lie on a triangle that
    ///    does not touch the closest vertex. The walk's answer bounds the search, so the check
    ///    usually opens a handful of boxes; when it finds something closer, that is the answer
    ///    (counted in [`QueryStats::fallbacks`]).
    ///
    /// Exact (the same triangle as a brute-force search up to ties), allocation-free.
    pub fn closest_in_body(&mut self, b: usize, p: [f64; 3], reach: f64) -> Option<Closest> {
        let (s, e) = self.body_tris[b];
        if s == e || !p.iter().all(|c| c.is_finite()) {
            return None;
        }
        self.stats.walks += 1;
        let (vertex, _) = self.walk(self.warm[b], v(p));
        self.warm[b] = vertex;
        let mut best: Option<SurfaceHit> = None;
        let (ts, te) = (
            self.vtri_ptr[vertex as usize] as usize,
            self.vtri_ptr[vertex as usize + 1] as usize,
        );
        for i in ts..te {
            let t = self.vtri[i] as usize;
            let h = self.hit(t, v(p));
            if best.is_none_or(|bh| h.distance < bh.distance) {
                best = Some(h);
            }
        }
        let walk_d = best.map_or(f64::INFINITY, |h| h.distance);
        let bound = walk_d.min(reach);
        self.refit(b);
        let (found, _) = self.bvh[b].nearest(&self.x, &self.tris[s..e], p, bound * bound);
        if let Some(n) = found {
            if n.d2.sqrt() < walk_d {
                if walk_d <= reach {
                    self.stats.fallbacks += 1;
                }
                best = Some(self.hit(s + n.triangle as usize, v(p)));
            }
        }
        let h = best?;
        if h.distance > reach {
            return None;
        }
        Some(Closest {
            body: b,
            hit: h,
            vertex,
        })
    }

    /// Whether `p` lies behind the surface at its closest point `c` (inside the body), by the
    /// angle-weighted pseudo-normal of the feature the closest point lies on: the face's normal
    /// inside a face, the sum of the two faces' normals on an edge, the faces' normals weighted
    /// by their angles at a corner. For a closed surface that sign is exact whichever feature is
    /// closest; one face's normal alone misjudges points whose closest point is an edge or
    /// corner between faces more than 90° apart ([`SurfaceHit::inside`] is that cheaper test).
    /// Allocation-free.
    pub fn behind(&self, p: [f64; 3], c: &Closest) -> bool {
        let t = c.hit.triangle;
        if t >= self.tris.len() {
            return false;
        }
        let d = v(p) - v(c.hit.point);
        let w = c.hit.barycentric;
        const ON: f64 = 1e-9;
        let on: [bool; 3] = w.map(|x| x > ON);
        let corners = self.tris[t];
        let n = match on.iter().filter(|x| **x).count() {
            // A corner: every face around it, weighted by its angle there.
            1 => {
                let k = on.iter().position(|x| *x).unwrap_or(0);
                let vtx = corners[k] as usize;
                let (s, e) = (self.vtri_ptr[vtx] as usize, self.vtri_ptr[vtx + 1] as usize);
                self.vtri[s..e].iter().fold(DVec3::ZERO, |acc, &u| {
                    let tri = self.tris[u as usize];
                    let Some(j) = tri.iter().position(|&i| i as usize == vtx) else {
                        return acc;
                    };
                    let [a, b, c] = self.corners_v(u as usize);
                    let (o, e1, e2) = match j {
                        0 => (a, b, c),
                        1 => (b, c, a),
                        _ => (c, a, b),
                    };
                    let angle = (e1 - o).angle_between(e2 - o);
                    acc + unit_normal(a, b, c) * if angle.is_finite() { angle } else { 0.0 }
                })
            }
            // An edge: the faces that share it (two on a closed surface).
            2 => {
                let (i, j) = match on {
                    [true, true, _] => (corners[0], corners[1]),
                    [true, _, true] => (corners[0], corners[2]),
                    _ => (corners[1], corners[2]),
                };
                let (s, e) = (
                    self.vtri_ptr[i as usize] as usize,
                    self.vtri_ptr[i as usize + 1] as usize,
                );
                self.vtri[s..e]
                    .iter()
                    .filter(|&&u| self.tris[u as usize].contains(&j))
                    .fold(DVec3::ZERO, |acc, &u| acc + self.normal_of_v(u as usize))
            }
            _ => self.normal_of_v(t),
        };
        d.dot(n) < 0.0
    }

    /// The closest surface point over every body whose box is within `reach` of `p`.
    pub fn closest(&mut self, p: [f64; 3], reach: f64) -> Option<Closest> {
        let mut best: Option<Closest> = None;
        for b in 0..self.body_tris.len() {
            if !self.near_body(b, p, reach) {
                continue;
            }
            if let Some(c) = self.closest_in_body(b, p, reach) {
                if best.is_none_or(|bc| c.hit.distance < bc.hit.distance) {
                    best = Some(c);
                }
            }
        }
        best
    }

    /// Calls `f(global triangle)` for every triangle of every body whose box overlaps
    /// `[lo, hi]` (refitting those bodies' hierarchies first).
    pub fn triangles_in_box(&mut self, lo: [f64; 3], hi: [f64; 3], f: impl FnMut(usize)) {
        self.triangles_in_box_v(v(lo), v(hi), f)
    }

    /// [`triangles_in_box`](Self::triangles_in_box) on `DVec3`s.
    pub(crate) fn triangles_in_box_v(&mut self, lo: DVec3, hi: DVec3, mut f: impl FnMut(usize)) {
        for b in 0..self.body_tris.len() {
            let (blo, bhi) = self.body_box[b];
            if !(self.active[b] && blo.cmple(hi).all() && bhi.cmpge(lo).all()) {
                continue;
            }
            self.refit(b);
            let s = self.body_tris[b].0;
            self.bvh[b].overlapping(lo, hi, |t| f(s + t as usize));
        }
    }

    /// Calls `f(global triangle)` for every triangle of every active body that comes within
    /// `radius` of `centre` (its own bounding box does; refitting those bodies' hierarchies
    /// first). The god-object's queries: on a surface finely meshed under a large tool, the
    /// cube around the tool sphere holds thousands of triangles that the sphere never
    /// reaches, and each would be tested exactly.
    pub(crate) fn triangles_near_v(
        &mut self,
        centre: DVec3,
        radius: f64,
        mut f: impl FnMut(usize),
    ) {
        let r2 = radius * radius;
        for b in 0..self.body_tris.len() {
            let (blo, bhi) = self.body_box[b];
            if !(self.active[b] && box_d2(blo, bhi, centre) <= r2) {
                continue;
            }
            self.refit(b);
            let s = self.body_tris[b].0;
            let (tris, x) = (&self.tris, &self.x);
            let mut met = 0;
            self.bvh[b].near_sphere(centre, radius, |t| {
                met += 1;
                let t = s + t as usize;
                let [a, b, c] = tris[t].map(|i| v(x[i as usize]));
                if box_d2(a.min(b).min(c), a.max(b).max(c), centre) <= r2 {
                    f(t);
                }
            });
            if met > CROWDED_QUERY && self.drift2[b] > 0.0 {
                self.crowded[b] = true;
            }
        }
    }

    /// The point with barycentric weights `w` on global triangle `t`.
    pub fn point_on(&self, t: usize, w: [f64; 3]) -> [f64; 3] {
        self.point_on_v(t, w).to_array()
    }

    /// [`point_on`](Self::point_on) as a `DVec3`.
    pub(crate) fn point_on_v(&self, t: usize, w: [f64; 3]) -> DVec3 {
        let [a, b, c] = self.corners_v(t);
        bary_point(a, b, c, w)
    }

    /// Unit outward normal of global triangle `t`.
    pub fn normal_of(&self, t: usize) -> [f64; 3] {
        self.normal_of_v(t).to_array()
    }

    /// [`normal_of`](Self::normal_of) as a `DVec3`.
    pub(crate) fn normal_of_v(&self, t: usize) -> DVec3 {
        let [a, b, c] = self.corners_v(t);
        unit_normal(a, b, c)
    }

    /// The corners of global triangle `t`.
    pub fn corners(&self, t: usize) -> [[f64; 3]; 3] {
        self.tris[t].map(|i| self.x[i as usize])
    }

    /// [`corners`](Self::corners) as `DVec3`s.
    pub(crate) fn corners_v(&self, t: usize) -> [DVec3; 3] {
        self.tris[t].map(|i| v(self.x[i as usize]))
    }
}
