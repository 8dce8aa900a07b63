//! Organ-to-organ collision: which surface vertices of each body are inside another body, and
//! the penalty loads that push them out (thesis §6.3.4.1).
//!
//! # Detection
//! As in the thesis' PQP-based method, collision is a property of surface *vertices*: a vertex of
//! body A collides with body B when it lies inside B's closed, outward-wound surface. For every
//! ordered pair of bodies whose bounding boxes overlap, each surface vertex of A inside B's box
//! (padded by the [skin](Collisions::set_skin)) is projected onto B's surface with an exact
//! closest-point query in B's bounding-volume hierarchy (`O(log T)` triangle tests per vertex
//! instead of `T`). The vertex is inside when the vector from the closest point to it points
//! against the closest feature's **angle-weighted pseudo-normal** (Bærentzen & Aanæs 2005): the
//! face normal when the closest point is inside a triangle, the sum of the two face normals when
//! it is on an edge, the angle-weighted sum of the incident face normals when it is a vertex.
//! Unlike the closest triangle's own normal, this decides correctly at edges and corners, convex
//! or concave. The depth is the distance to the closest point.
//!
//! A query costs a few dozen triangle tests for a vertex near the surface, but far more for one
//! deep inside the other's box and far from its surface, which is common where organs' boxes
//! overlap much more than the organs do. [`Collisions::set_depth_limit`] bounds the search: a
//! vertex deeper than the limit is not reported, and the search stops at that distance.
//!
//! Each body's hierarchy is refitted to the current positions every step (`O(T)`), and rebuilt
//! in place when the deformation has loosened it too much; the result of a query does not
//! depend on the tree's shape (ties go to the smaller triangle index), so detection is a pure
//! function of the positions: same input, same [`Penetration`]s in the same order (body, then
//! other body, then node index ascending), bit for bit.
//!
//! # Response
//! The world's response is [`Collisions::add_springs`]: each penetration becomes a pair of
//! [`ContactSpring`]s, one on the penetrating vertex and one on the other body's closest point,
//! each pushing its side half the depth apart, which every model then integrates *implicitly*
//! in its own step (their stiffness joins FEM's and implicit mass-spring's system matrices and
//! the projected cage's reduced matrix). A displacement or an explicit penalty cannot hold
//! light, soft tissue: undone by the next step, it acts like a penalty of `m/Δt²` per node
//! (about 0.1 N/m for a cylinder node at 20 ms, so 0.03 N drove one cylinder 14 mm into
//! another). Implicit springs hold any stiffness. Their targets stay where the contact was at
//! the start of the step, so while in contact they also act as a damper of `k Δt` along the
//! normal: a pushed body follows at a speed of at most (half the depth)/`Δt`, and the
//! stiffness trades penetration (`2F/k` per vertex pair at rest) against that drag. Letting the
//! targets move with the contact's velocity was tried and feeds energy in (the stiff targets
//! turn velocity into position and back), so they do not.
//!
//! [`Collisions::add_penalty_loads`] (explicit loads, for tools that want them) puts a linear penalty force `k · depth · n` on each
//! penetrating vertex, `n` the unit normal out of the other body at the closest point, and
//! exactly the opposite force on the other body, spread over the closest triangle's three nodes
//! by the closest point's barycentric weights: the loads sum to zero (action = reaction). When
//! the vertex is not on the surface, `n` is the direction from the vertex to its closest point,
//! so action and reaction are collinear and the torques balance too.
//!
//! Both bodies' vertices are tested, so two flat faces pressed together are held by the
//! penetrating vertices of both: at equilibrium under a load `F` across the contact,
//! `k · Σ depth = F`, the sum over every penetrating vertex of either body.
//!
//! # Limitations
//! - Only vertices are tested: two surfaces whose edges cross without either having a vertex
//!   inside the other (sharp features meeting on a coarse mesh) are not detected. On organ
//!   meshes of similar resolution pressed together this does not happen for long.
//! - A vertex pushed past the other body's medial surface is closer to the far side and is
//!   pushed out through it. Penalty stiffness must keep depths well below the bodies' half
//!   thickness.
//! - On a faceted curved surface the normal is the faceted surface's, not the smooth one's: off
//!   by up to half the angle between neighbouring facets (on the shipped 14-sided cylinder, at
//!   most 13° and 6° on average off radial). Smoothed (interpolated vertex) normals would round
//!   sharp edges off too, and break the torque balance.
//! - Self-collision is not handled.
//!
//! # parry3d
//! The design names parry3d. Its `f64` build, `parry3d-f64` 0.31, supports deformable meshes
//! (`TriMesh::set_vertices` refits its BVH; with the `ORIENTED` flag it also recomputes the
//! angle-weighted pseudo-normals that make `is_inside` right at edges and corners), and the
//! same vertex-in-body test written on it finds the same penetrating vertices as this module,
//! with depths equal to within rounding but not bit for bit. Not adopted: with its
//! pseudo-normals its update per frame costs more than our whole detection and allocates (hash
//! maps and vectors in `compute_pseudo_normals`); without them the inside test would have to be
//! rebuilt on our side; and its last-bit differences would change the shipped trajectories,
//! which must not change. Its queries being faster than ours
//! says our hierarchy and traversal have room to improve. Measured by `lop-bench collide`
//! (feature `parry`); figures in `docs/benchmarks.md`, "Collision and tool queries against
//! parry3d".
//!
//! # Real-time properties
//! [`Collisions::new`] sizes every buffer (the hierarchies' nodes, the penetration list for every
//! surface vertex inside every other body at once), so [`Collisions::detect`] (the first call,
//! which builds the hierarchies, included) and [`Collisions::add_penalty_loads`] never
//! allocate. Cost on the organs scene (liver, spleen, stomach, pancreas: 2 360 surface
//! triangles), release build: ~0.45 ms per detection with no depth limit, ~0.09 ms with a 5 mm
//! one.

pub(crate) mod bvh;

use bvh::{Bvh, Nearest};

use glam::DVec3;

use crate::contact::unit_normal;
use crate::model::ContactSpring;
use crate::vec3::v;

/// One body as collision sees it in one step.
#[derive(Debug, Clone, Copy)]
pub struct CollisionBody<'a> {
    /// Current node positions, m (every surface node must be in range).
    pub positions: &'a [[f64; 3]],
    /// Outward-wound surface triangles, node indices: the same surface, in the same order, as
    /// given to [`Collisions::new`] for this body (checked in debug builds).
    pub surface: &'a [[u32; 3]],
}

/// One surface vertex of body `body` found inside body `other`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Penetration {
    /// Index of the penetrating body.
    pub body: usize,
    /// The penetrating surface node of `body`.
    pub node: u32,
    /// Index of the penetrated body.
    pub other: usize,
    /// Index in `other`'s surface of the triangle holding the closest point.
    pub triangle: u32,
    /// Barycentric coordinates of the closest point on that triangle (sum 1, each in [0, 1]).
    pub bary: [f64; 3],
    /// Penetration depth, m, > 0: the distance from the node to the closest point of `other`'s
    /// surface, plus the skin (with a skin, nodes up to `skin` outside count too, with depth
    /// `skin − distance`).
    pub depth: f64,
    /// Unit normal out of `other` at the closest point: the direction from the node to the
    /// closest point (from the closest point to the node for a node outside, within the skin),
    /// or the closest feature's pseudo-normal when the node is exactly on the surface.
    pub normal: [f64; 3],
}

/// The penalty law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CollisionParams {
    /// Penalty stiffness per penetrating vertex, N/m: force `stiffness × depth`.
    pub stiffness: f64,
}

/// What the last [`Collisions::detect`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CollisionStats {
    /// Unordered body pairs whose (padded) bounding boxes overlapped.
    pub body_pairs: usize,
    /// Vertices inside another body's padded box: closest-point queries run.
    pub vertex_queries: usize,
    /// Point–triangle distance evaluations in those queries.
    pub triangle_tests: usize,
    /// Queried vertices with no surface within reach (the larger of the depth limit and the
    /// skin): outside, or deeper inside than the [depth limit](Collisions::set_depth_limit).
    pub out_of_reach: usize,
    /// Penetrating vertices found.
    pub penetrations: usize,
    /// Largest depth, m (0 without penetrations).
    pub max_depth: f64,
    /// Bounding-volume hierarchies built from scratch (first step, or loosened by deformation);
    /// the others were refitted.
    pub tree_builds: usize,
}

/// No neighbour across an edge (open or non-manifold surface).
const NONE: u32 = u32::MAX;

/// One body's surface topology (fixed) and hierarchy (refitted every step).
#[derive(Debug, Clone)]
struct Surface {
    tris: Vec<[u32; 3]>,
    /// Surface nodes, sorted, unique: the vertices tested against other bodies.
    verts: Vec<u32>,
    /// Per triangle corner: index into `verts`.
    corner_vert: Vec<[u32; 3]>,
    /// Per triangle: the neighbour across the edge opposite each corner, or [`NONE`].
    nbr: Vec<[u32; 3]>,
    /// Incident (triangle, corner) pairs of each vertex: `incident[start[v]..start[v + 1]]`.
    start: Vec<u32>,
    incident: Vec<[u32; 2]>,
    /// Smallest position count the surface needs (largest node index + 1).
    min_nodes: usize,
    bvh: Bvh,
}

impl Surface {
    fn new(tris: &[[u32; 3]]) -> Surface {
        let mut verts: Vec<u32> = tris.iter().flatten().copied().collect();
        verts.sort_unstable();
        verts.dedup();
        let vid = |n: u32| verts.binary_search(&n).expect("surface node") as u32;
        let corner_vert: Vec<[u32; 3]> = tris.iter().map(|t| t.map(vid)).collect();

        let mut start = vec![0u32; verts.len() + 1];
        for cv in &corner_vert {
            for &v in cv {
                start[v as usize + 1] += 1;
            }
        }
        for v in 0..verts.len() {
            start[v + 1] += start[v];
        }
        let mut fill = start.clone();
        let mut incident = vec![[0u32; 2]; 3 * tris.len()];
        for (t, cv) in corner_vert.iter().enumerate() {
            for (k, &v) in cv.iter().enumerate() {
                incident[fill[v as usize] as usize] = [t as u32, k as u32];
                fill[v as usize] += 1;
            }
        }

        // Edges as (lo, hi, triangle, opposite corner), sorted: a manifold edge is a run of two.
        let mut edges: Vec<(u32, u32, u32, u32)> = Vec::with_capacity(3 * tris.len());
        for (t, tri) in tris.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[(k + 1) % 3], tri[(k + 2) % 3]);
                edges.push((a.min(b), a.max(b), t as u32, k as u32));
            }
        }
        edges.sort_unstable();
        let mut nbr = vec![[NONE; 3]; tris.len()];
        let mut i = 0;
        while i < edges.len() {
            let mut j = i + 1;
            while j < edges.len() && (edges[j].0, edges[j].1) == (edges[i].0, edges[i].1) {
                j += 1;
            }
            if j - i == 2 {
                let (e, f) = (edges[i], edges[i + 1]);
                nbr[e.2 as usize][e.3 as usize] = f.2;
                nbr[f.2 as usize][f.3 as usize] = e.2;
            }
            i = j;
        }

        Surface {
            tris: tris.to_vec(),
            min_nodes: verts.last().map_or(0, |&n| n as usize + 1),
            verts,
            corner_vert,
            nbr,
            start,
            incident,
            bvh: Bvh::new(tris.len()),
        }
    }

    fn face_normal(&self, x: &[[f64; 3]], t: u32) -> DVec3 {
        let [a, b, c] = self.tris[t as usize].map(|i| v(x[i as usize]));
        unit_normal(a, b, c)
    }

    /// Angle-weighted pseudo-normal of the feature holding the closest point (not normalised).
    fn pseudo_normal(&self, x: &[[f64; 3]], hit: &Nearest) -> DVec3 {
        let t = hit.triangle;
        let zeros = hit.bary.iter().filter(|&&w| w == 0.0).count();
        match zeros {
            2 => {
                let k = hit.bary.iter().position(|&w| w != 0.0).unwrap_or(0);
                let vi = self.corner_vert[t as usize][k] as usize;
                let mut n = DVec3::ZERO;
                for &[tt, kk] in
                    &self.incident[self.start[vi] as usize..self.start[vi + 1] as usize]
                {
                    let tri = self.tris[tt as usize];
                    let kk = kk as usize;
                    let p = v(x[tri[kk] as usize]);
                    let e1 = v(x[tri[(kk + 1) % 3] as usize]) - p;
                    let e2 = v(x[tri[(kk + 2) % 3] as usize]) - p;
                    let angle = e1.cross(e2).length().atan2(e1.dot(e2));
                    n += self.face_normal(x, tt) * angle;
                }
                n
            }
            1 => {
                let z = hit.bary.iter().position(|&w| w == 0.0).unwrap_or(0);
                let n = self.face_normal(x, t);
                match self.nbr[t as usize][z] {
                    NONE => n,
                    o => n + self.face_normal(x, o),
                }
            }
            _ => self.face_normal(x, t),
        }
    }
}

/// Per-body acceleration structures and scratch, reused every step.
#[derive(Debug, Clone)]
pub struct Collisions {
    surfaces: Vec<Surface>,
    skin: f64,
    depth_limit: f64,
    found: Vec<Penetration>,
    stats: CollisionStats,
}

impl Collisions {
    /// Collision structures for bodies with these outward-wound surfaces (one per body, in the
    /// order [`detect`](Self::detect) will receive the bodies). Skin 0.
    pub fn new(surfaces: &[&[[u32; 3]]]) -> Collisions {
        let surfaces: Vec<Surface> = surfaces.iter().map(|s| Surface::new(s)).collect();
        let others = surfaces.len().saturating_sub(1);
        let capacity = surfaces.iter().map(|s| s.verts.len()).sum::<usize>() * others;
        Collisions {
            surfaces,
            skin: 0.0,
            depth_limit: f64::INFINITY,
            found: Vec::with_capacity(capacity),
            stats: CollisionStats::default(),
        }
    }

    /// Contact starts `skin` metres before the surfaces touch: vertices up to `skin` outside
    /// another body count as penetrating, with depth `skin − distance` (so the penalty force
    /// grows continuously from zero there). Default 0.
    ///
    /// # Panics
    /// If `skin` is negative or not finite.
    pub fn set_skin(&mut self, skin: f64) {
        assert!(
            skin >= 0.0 && skin.is_finite(),
            "collision skin must be finite and ≥ 0, got {skin}"
        );
        self.skin = skin;
    }

    /// The skin, m.
    pub fn skin(&self) -> f64 {
        self.skin
    }

    /// Vertices more than `limit` metres inside another body are not reported (default
    /// `f64::INFINITY`: every depth). A finite reach lets each closest-point query stop at that
    /// distance instead of finding the closest point of vertices that are far outside, the bulk
    /// of the cost when bodies' boxes overlap much more than their surfaces do: on the organs
    /// scene a 5 mm reach makes detection ~5× faster. Set it well above the deepest penetration
    /// the penalty stiffness allows; a vertex that gets deeper loses its contact and may tunnel
    /// through (it would be near the other body's medial surface by then anyway).
    ///
    /// # Panics
    /// If `limit` is not positive (NaN included).
    pub fn set_depth_limit(&mut self, limit: f64) {
        assert!(
            limit > 0.0,
            "collision depth limit must be > 0, got {limit}"
        );
        self.depth_limit = limit;
    }

    /// The depth limit, m.
    pub fn depth_limit(&self) -> f64 {
        self.depth_limit
    }

    /// Number of bodies.
    pub fn len(&self) -> usize {
        self.surfaces.len()
    }

    /// True without bodies.
    pub fn is_empty(&self) -> bool {
        self.surfaces.is_empty()
    }

    /// Finds the surface vertices of each body that are inside another body (every pair whose
    /// bounding boxes overlap). Ordered by body, then other body, then node. Allocation-free.
    ///
    /// # Panics
    /// If `bodies` does not match the surfaces given to [`new`](Self::new) in number, or a
    /// body has fewer positions than its surface needs.
    pub fn detect(&mut self, bodies: &[CollisionBody<'_>]) -> &[Penetration] {
        assert_eq!(
            bodies.len(),
            self.surfaces.len(),
            "collision: {} bodies for {} surfaces",
            bodies.len(),
            self.surfaces.len()
        );
        self.found.clear();
        self.stats = CollisionStats::default();
        for (i, (s, b)) in self.surfaces.iter_mut().zip(bodies).enumerate() {
            assert!(
                b.positions.len() >= s.min_nodes,
                "collision body {i}: {} positions, surface needs {}",
                b.positions.len(),
                s.min_nodes
            );
            debug_assert!(
                b.surface == s.tris.as_slice(),
                "collision body {i}: surface differs from the one given to Collisions::new"
            );
            let before = s.bvh.builds();
            s.bvh.update(b.positions, &s.tris);
            self.stats.tree_builds += (s.bvh.builds() - before) as usize;
        }
        let (skin, limit) = (self.skin, self.depth_limit);
        let reach = limit.max(skin);
        for (a, body) in bodies.iter().enumerate() {
            let (alo, ahi) = self.surfaces[a].bvh.bounds();
            for (o, other) in bodies.iter().enumerate() {
                if o == a {
                    continue;
                }
                let so = &self.surfaces[o];
                let (olo, ohi) = so.bvh.bounds();
                let (olo, ohi) = (olo - skin, ohi + skin);
                if !(alo.cmple(ohi).all() && olo.cmple(ahi).all()) {
                    continue;
                }
                if a < o {
                    self.stats.body_pairs += 1;
                }
                for &node in &self.surfaces[a].verts {
                    let p = body.positions[node as usize];
                    if !(olo.cmple(v(p)).all() && v(p).cmple(ohi).all()) {
                        continue;
                    }
                    self.stats.vertex_queries += 1;
                    let (hit, tested) = so.bvh.nearest(other.positions, &so.tris, p, reach * reach);
                    self.stats.triangle_tests += tested;
                    let Some(hit) = hit else {
                        self.stats.out_of_reach += 1;
                        continue;
                    };
                    let dist = hit.d2.sqrt();
                    let pn = so.pseudo_normal(other.positions, &hit);
                    let inside = hit.offset.dot(pn) < 0.0;
                    let depth = if inside { dist } else { -dist } + skin;
                    if !(depth > 0.0) || (inside && dist > limit) {
                        continue;
                    }
                    let normal = if dist > 0.0 {
                        hit.offset * (if inside { -1.0 } else { 1.0 } / dist)
                    } else {
                        let l = pn.length();
                        if l > 0.0 {
                            pn * (1.0 / l)
                        } else {
                            continue;
                        }
                    };
                    self.stats.max_depth = self.stats.max_depth.max(depth);
                    self.found.push(Penetration {
                        body: a,
                        node,
                        other: o,
                        triangle: hit.triangle,
                        bary: hit.bary,
                        depth,
                        normal: normal.to_array(),
                    });
                }
            }
        }
        self.stats.penetrations = self.found.len();
        &self.found
    }

    /// The penetrations of the last [`detect`](Self::detect).
    pub fn penetrations(&self) -> &[Penetration] {
        &self.found
    }

    /// Penalty loads for the last detection, added into `loads[body][node]` (N): `+k · depth ·
    /// normal` on each penetrating vertex and exactly the opposite on the other body's closest
    /// triangle, spread by the barycentric weights, so the loads sum to zero.
    ///
    /// # Panics
    /// If the stiffness is negative or not finite, `loads` has not one slice per body, or a
    /// slice is shorter than its body's surface needs.
    pub fn add_penalty_loads(&self, params: &CollisionParams, loads: &mut [&mut [[f64; 3]]]) {
        let k = params.stiffness;
        assert!(
            k >= 0.0 && k.is_finite(),
            "collision stiffness must be finite and ≥ 0, got {k}"
        );
        assert_eq!(
            loads.len(),
            self.surfaces.len(),
            "collision loads: {} slices for {} bodies",
            loads.len(),
            self.surfaces.len()
        );
        for p in &self.found {
            let f = v(p.normal) * (k * p.depth);
            let l = &mut loads[p.body][p.node as usize];
            *l = (v(*l) + f).to_array();
            let tri = self.surfaces[p.other].tris[p.triangle as usize];
            for (&i, &w) in tri.iter().zip(&p.bary) {
                let l = &mut loads[p.other][i as usize];
                *l = (v(*l) - f * w).to_array();
            }
        }
    }

    /// Contact springs for the last detection (see [`ContactSpring`]), pushed onto
    /// `springs[body]`, for a response implicit in each body's step. Each penetration of depth
    /// `d` along `n` gives two springs of stiffness `k`: one pushes the vertex out along `n` by
    /// `d/2`, the other pushes the other body's closest point the other way by `d/2`. Both move
    /// to the middle (neither body is the obstacle of the other) and, at rest, each receives
    /// `k · (its remaining share of d)`: equal and opposite. Allocation-free if each vector has
    /// the capacity (every surface vertex of every body once, plus as many for the others).
    ///
    /// # Panics
    /// If the stiffness is negative or not finite, or `bodies` / `springs` do not have one entry
    /// per body.
    pub fn add_springs(
        &self,
        params: &CollisionParams,
        bodies: &[CollisionBody<'_>],
        springs: &mut [Vec<ContactSpring>],
    ) {
        let k = params.stiffness;
        assert!(
            k >= 0.0 && k.is_finite(),
            "collision stiffness must be finite and ≥ 0, got {k}"
        );
        assert_eq!(
            bodies.len(),
            self.surfaces.len(),
            "collision springs: bodies"
        );
        assert_eq!(
            springs.len(),
            self.surfaces.len(),
            "collision springs: lists"
        );
        for p in &self.found {
            let n = v(p.normal);
            let x = v(bodies[p.body].positions[p.node as usize]);
            springs[p.body].push(ContactSpring {
                nodes: [p.node; 3],
                weights: [1.0, 0.0, 0.0],
                normal: p.normal,
                target: n.dot(x) + 0.5 * p.depth,
                stiffness: k,
            });
            let tri = self.surfaces[p.other].tris[p.triangle as usize];
            let xo = bodies[p.other].positions;
            let c = (0..3).fold(DVec3::ZERO, |acc, j| {
                acc + v(xo[tri[j] as usize]) * p.bary[j]
            });
            let m = n * -1.0;
            springs[p.other].push(ContactSpring {
                nodes: tri,
                weights: p.bary,
                normal: m.to_array(),
                target: m.dot(c) + 0.5 * p.depth,
                stiffness: k,
            });
        }
    }

    /// Per body, the capacity of the spring list [`add_springs`](Self::add_springs) may need.
    pub fn spring_capacity(&self, body: usize) -> usize {
        let others = self.surfaces.len().saturating_sub(1);
        let own = self.surfaces[body].verts.len() * others;
        let theirs: usize = (0..self.surfaces.len())
            .filter(|&o| o != body)
            .map(|o| self.surfaces[o].verts.len())
            .sum();
        own + theirs
    }

    /// Counts of the last [`detect`](Self::detect).
    pub fn stats(&self) -> CollisionStats {
        self.stats
    }
}
