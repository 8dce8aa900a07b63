//! Is a triangle surface fit to be filled with tetrahedra? [`check_surface`] answers for a
//! [`SurfaceMesh`] (a segmented organ exported as STL, OBJ or PLY) before it is handed to a
//! mesher, and [`close_holes`] closes the small holes segmentation tools tend to leave.
//!
//! A mesher needs a closed, manifold, consistently wound surface that does not cross itself;
//! otherwise it fails with a message about a facet number, or worse, fills the wrong region.
//! Every defect found here names the triangles (index and vertices, with their coordinates) so
//! that it can be found in a surface editor:
//!
//! - **degenerate** triangle: a repeated vertex, or an area `<= 1e-12 · (longest edge)²`;
//! - **open edge**: an edge of one triangle only (a hole in the surface);
//! - **non-manifold edge**: an edge of three or more triangles;
//! - **non-manifold vertex**: the triangles around a vertex form two or more fans that share
//!   only the vertex (two sheets touching at a point);
//! - **misoriented** pair: two triangles traverse their shared edge in the same direction (one
//!   of them is wound the other way round);
//! - **self-intersection**: two triangles with no vertex in common intersect (found through a
//!   uniform grid over the triangles' bounding boxes, so the check is near-linear in the number
//!   of triangles). Triangles that share a vertex or an edge are not tested against each other.
//!
//! A surface without these defects whose enclosed (signed) volume is negative is wound inward
//! throughout: that is not a defect but a note ([`SurfaceReport::inverted`]), since flipping
//! every triangle fixes it ([`SurfaceMesh::flip`]).
//!
//! Each kind keeps the first [`DEFECTS_LISTED`] defects and counts all of them.

use std::collections::HashMap;
use std::fmt;

use glam::DVec3;

use super::SurfaceMesh;

/// Defects of one kind kept in a report for display; the rest are only counted.
pub const DEFECTS_LISTED: usize = 8;

/// A triangle as a defect names it: its index and vertices in the surface, and where it is.
#[derive(Debug, Clone, PartialEq)]
pub struct TriangleRef {
    /// 0-based triangle index in the surface.
    pub index: u32,
    /// Its vertices, 0-based, in the file's winding.
    pub vertices: [u32; 3],
    /// The vertices' positions.
    pub positions: [[f64; 3]; 3],
}

impl TriangleRef {
    fn new(surface: &SurfaceMesh, index: u32) -> TriangleRef {
        let vertices = surface.triangles[index as usize];
        TriangleRef {
            index,
            vertices,
            positions: vertices.map(|v| surface.vertices[v as usize]),
        }
    }
}

impl fmt::Display for TriangleRef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "triangle {} (vertices", self.index)?;
        for (v, p) in self.vertices.iter().zip(&self.positions) {
            write!(f, " {v} ({}, {}, {})", p[0], p[1], p[2])?;
        }
        write!(f, ")")
    }
}

/// The kinds of defect, in the order a report lists them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum DefectKind {
    /// A triangle with a repeated vertex or (almost) no area.
    Degenerate,
    /// An edge of one triangle only: a hole.
    OpenEdge,
    /// An edge of three or more triangles.
    NonManifoldEdge,
    /// A vertex whose triangles form several fans joined only at it.
    NonManifoldVertex,
    /// Two triangles traverse their shared edge in the same direction.
    Misoriented,
    /// Two triangles without a common vertex intersect.
    SelfIntersection,
}

impl DefectKind {
    /// Every kind, in report order.
    pub const ALL: [DefectKind; 6] = [
        DefectKind::Degenerate,
        DefectKind::OpenEdge,
        DefectKind::NonManifoldEdge,
        DefectKind::NonManifoldVertex,
        DefectKind::Misoriented,
        DefectKind::SelfIntersection,
    ];

    fn describe(self) -> &'static str {
        match self {
            DefectKind::Degenerate => "degenerate triangles (repeated vertex or no area)",
            DefectKind::OpenEdge => "open edges (in one triangle only: the surface has holes)",
            DefectKind::NonManifoldEdge => "non-manifold edges (in three or more triangles)",
            DefectKind::NonManifoldVertex => {
                "non-manifold vertices (surface sheets touching at a point)"
            }
            DefectKind::Misoriented => {
                "inconsistently wound triangle pairs (a shared edge traversed the same way)"
            }
            DefectKind::SelfIntersection => "self-intersections (triangles crossing each other)",
        }
    }
}

/// One defect, with the triangles involved.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceDefect {
    /// What is wrong.
    pub kind: DefectKind,
    /// The edge (`[lo, hi]` vertex indices) for edge defects.
    pub edge: Option<[u32; 2]>,
    /// The vertex for [`DefectKind::NonManifoldVertex`].
    pub vertex: Option<u32>,
    /// The triangles involved (at most a few for a vertex defect).
    pub triangles: Vec<TriangleRef>,
}

impl fmt::Display for SurfaceDefect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some([a, b]) = self.edge {
            write!(f, "edge {a}-{b}: ")?;
        }
        if let Some(v) = self.vertex {
            write!(f, "vertex {v}: ")?;
        }
        for (i, t) in self.triangles.iter().enumerate() {
            if i > 0 {
                write!(f, "; ")?;
            }
            write!(f, "{t}")?;
        }
        Ok(())
    }
}

/// What [`check_surface`] found.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SurfaceReport {
    /// Vertices of the surface.
    pub vertices: usize,
    /// Triangles of the surface.
    pub triangles: usize,
    /// The first [`DEFECTS_LISTED`] defects of each kind, in [`DefectKind::ALL`] order.
    pub defects: Vec<SurfaceDefect>,
    /// How many defects of each kind there are, indexed like [`DefectKind::ALL`].
    pub counts: [usize; 6],
    /// Signed enclosed volume, in the surface's units cubed (meaningful for a closed surface;
    /// negative when it is wound inward).
    pub volume: f64,
    /// The surface has no defect but is wound inward throughout (negative volume): flip it.
    pub inverted: bool,
}

impl SurfaceReport {
    /// No defect of any kind (an inverted surface is still fine: flip it).
    pub fn is_ok(&self) -> bool {
        self.counts.iter().all(|&c| c == 0)
    }

    /// How many defects of `kind` there are.
    pub fn count(&self, kind: DefectKind) -> usize {
        self.counts[kind_index(kind)]
    }

    /// The listed defects of `kind`.
    pub fn of(&self, kind: DefectKind) -> impl Iterator<Item = &SurfaceDefect> {
        self.defects.iter().filter(move |d| d.kind == kind)
    }

    fn push(&mut self, defect: SurfaceDefect) {
        let k = kind_index(defect.kind);
        self.counts[k] += 1;
        if self.counts[k] <= DEFECTS_LISTED {
            self.defects.push(defect);
        }
    }
}

impl fmt::Display for SurfaceReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} vertices, {} triangles, enclosed volume {:.4e} (the file's units, cubed)",
            self.vertices, self.triangles, self.volume
        )?;
        if self.is_ok() {
            write!(
                f,
                ": closed, manifold, consistently wound, no self-intersection"
            )?;
            if self.inverted {
                write!(f, "; wound inward throughout (negative volume)")?;
            }
            return Ok(());
        }
        for kind in DefectKind::ALL {
            let n = self.count(kind);
            if n == 0 {
                continue;
            }
            write!(f, "\n{n} {}", kind.describe())?;
            for d in self.of(kind) {
                write!(f, "\n  {d}")?;
            }
            if n > DEFECTS_LISTED {
                write!(f, "\n  ... and {} more", n - DEFECTS_LISTED)?;
            }
        }
        Ok(())
    }
}

fn kind_index(kind: DefectKind) -> usize {
    DefectKind::ALL
        .iter()
        .position(|&k| k == kind)
        .unwrap_or_default()
}

impl SurfaceMesh {
    /// Reverses the winding of every triangle (outward ↔ inward).
    pub fn flip(&mut self) {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
    }

    /// Multiplies every coordinate by `factor` (e.g. 0.01 for centimetres to metres).
    pub fn scale(&mut self, factor: f64) {
        for p in &mut self.vertices {
            *p = p.map(|c| c * factor);
        }
    }

    /// Area of the triangles, in the coordinates' units squared.
    pub fn area(&self) -> f64 {
        let p = |i: u32| DVec3::from_array(self.vertices[i as usize]);
        self.triangles
            .iter()
            .map(|&[a, b, c]| 0.5 * (p(b) - p(a)).cross(p(c) - p(a)).length())
            .sum()
    }

    /// Signed volume enclosed by the triangles (`Σ a·(b×c) / 6`): positive when they are wound
    /// counter-clockwise seen from outside. Meaningful for a closed surface.
    pub fn signed_volume(&self) -> f64 {
        let p = |i: u32| DVec3::from_array(self.vertices[i as usize]);
        self.triangles
            .iter()
            .map(|&[a, b, c]| p(a).dot(p(b).cross(p(c))))
            .sum::<f64>()
            / 6.0
    }
}

/// Checks `surface` for everything that stops it from being tetrahedralised (see the
/// [module docs](self)). Indices must name vertices, as [`super::read_surface`] guarantees; a
/// triangle with an index out of range is reported as degenerate.
pub fn check_surface(surface: &SurfaceMesh) -> SurfaceReport {
    let mut report = SurfaceReport {
        vertices: surface.vertices.len(),
        triangles: surface.triangles.len(),
        ..SurfaceReport::default()
    };
    let nv = surface.vertices.len();
    let valid = |t: &[u32; 3]| t.iter().all(|&v| (v as usize) < nv);

    // Degenerate triangles.
    let mut degenerate = vec![false; surface.triangles.len()];
    for (i, t) in surface.triangles.iter().enumerate() {
        if !valid(t) || is_degenerate(surface, t) {
            degenerate[i] = true;
            let triangles = if valid(t) {
                vec![TriangleRef::new(surface, i as u32)]
            } else {
                Vec::new()
            };
            report.push(SurfaceDefect {
                kind: DefectKind::Degenerate,
                edge: None,
                vertex: None,
                triangles,
            });
        }
    }

    // Edges: which triangles use each undirected edge, and in which direction.
    let mut edges: HashMap<[u32; 2], Vec<(u32, bool)>> = HashMap::new();
    for (i, t) in surface.triangles.iter().enumerate() {
        if degenerate[i] {
            continue;
        }
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let key = [a.min(b), a.max(b)];
            edges.entry(key).or_default().push((i as u32, a < b));
        }
    }
    let mut sorted: Vec<_> = edges.iter().collect();
    sorted.sort_unstable_by_key(|(e, _)| **e);
    for (&edge, users) in sorted {
        let refs = |users: &[(u32, bool)]| {
            users
                .iter()
                .map(|&(t, _)| TriangleRef::new(surface, t))
                .collect::<Vec<_>>()
        };
        let kind = match users.len() {
            1 => Some(DefectKind::OpenEdge),
            2 if users[0].1 == users[1].1 => Some(DefectKind::Misoriented),
            2 => None,
            _ => Some(DefectKind::NonManifoldEdge),
        };
        if let Some(kind) = kind {
            report.push(SurfaceDefect {
                kind,
                edge: Some(edge),
                vertex: None,
                triangles: refs(users),
            });
        }
    }

    // Non-manifold vertices: the fans around each vertex (triangles joined through an edge at
    // the vertex they share). A fin on a non-manifold edge joins the fan of that edge, so it is
    // reported once, as the edge.
    let mut around: Vec<Vec<u32>> = vec![Vec::new(); nv];
    for (i, t) in surface.triangles.iter().enumerate() {
        if !degenerate[i] {
            for &v in t {
                around[v as usize].push(i as u32);
            }
        }
    }
    for (v, tris) in around.iter().enumerate() {
        if tris.len() < 2 {
            continue;
        }
        let fans = count_fans(surface, v as u32, tris, &edges);
        if fans > 1 {
            report.push(SurfaceDefect {
                kind: DefectKind::NonManifoldVertex,
                edge: None,
                vertex: Some(v as u32),
                triangles: tris
                    .iter()
                    .take(6)
                    .map(|&t| TriangleRef::new(surface, t))
                    .collect(),
            });
        }
    }

    // Self-intersections.
    for [a, b] in intersecting_pairs(surface, &degenerate) {
        report.push(SurfaceDefect {
            kind: DefectKind::SelfIntersection,
            edge: None,
            vertex: None,
            triangles: vec![TriangleRef::new(surface, a), TriangleRef::new(surface, b)],
        });
    }

    report.volume = if surface.triangles.iter().all(valid) {
        surface.signed_volume()
    } else {
        0.0
    };
    report.inverted = report.is_ok() && report.volume < 0.0;
    report
}

/// A repeated vertex, or `|(b-a)×(c-a)| <= 1e-12 · (longest edge)²`.
fn is_degenerate(surface: &SurfaceMesh, t: &[u32; 3]) -> bool {
    if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
        return true;
    }
    let [a, b, c] = t.map(|v| DVec3::from_array(surface.vertices[v as usize]));
    let longest2 = (b - a)
        .length_squared()
        .max((c - b).length_squared())
        .max((a - c).length_squared());
    let area2 = (b - a).cross(c - a).length();
    !(area2 > 1e-12 * longest2)
}

/// Connected components of the triangles `tris` around vertex `v`, joined where they share an
/// edge `v`–`w`.
fn count_fans(
    surface: &SurfaceMesh,
    v: u32,
    tris: &[u32],
    edges: &HashMap<[u32; 2], Vec<(u32, bool)>>,
) -> usize {
    let mut parent: Vec<usize> = (0..tris.len()).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    let local = |t: u32| tris.iter().position(|&x| x == t);
    for &t in tris {
        for &w in &surface.triangles[t as usize] {
            if w == v {
                continue;
            }
            let Some(users) = edges.get(&[v.min(w), v.max(w)]) else {
                continue;
            };
            // Every triangle on the edge joins the first one's fan (an open edge joins none).
            let Some(i) = local(users[0].0) else { continue };
            for u in &users[1..] {
                if let Some(j) = local(u.0) {
                    let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
                    parent[ri] = rj;
                }
            }
        }
    }
    (0..tris.len())
        .filter(|&i| find(&mut parent, i) == i)
        .count()
}

/// Pairs `[a, b]` (`a < b`) of non-degenerate triangles without a common vertex that
/// intersect, sorted. Candidates come from a uniform grid over the triangles' bounding boxes
/// (cell size about twice the mean triangle extent), then a bounding-box test, then the exact
/// test in floating point.
fn intersecting_pairs(surface: &SurfaceMesh, degenerate: &[bool]) -> Vec<[u32; 2]> {
    let tri =
        |i: usize| surface.triangles[i].map(|v| DVec3::from_array(surface.vertices[v as usize]));
    let live: Vec<usize> = (0..surface.triangles.len())
        .filter(|&i| !degenerate[i])
        .collect();
    if live.len() < 2 {
        return Vec::new();
    }
    let boxes: Vec<(DVec3, DVec3)> = (0..surface.triangles.len())
        .map(|i| {
            let [a, b, c] = tri(i);
            (a.min(b).min(c), a.max(b).max(c))
        })
        .collect();
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    let mut mean_extent = 0.0;
    for &i in &live {
        lo = lo.min(boxes[i].0);
        hi = hi.max(boxes[i].1);
        mean_extent += (boxes[i].1 - boxes[i].0).max_element();
    }
    mean_extent /= live.len() as f64;
    let size = (hi - lo).max_element();
    // At least 2× the mean triangle extent, and at most ~64 cells a side.
    let cell = (2.0 * mean_extent).max(size / 64.0).max(f64::MIN_POSITIVE);
    let dims = ((hi - lo) / cell).floor().as_uvec3() + 1;
    let index = |p: DVec3| {
        ((p - lo) / cell)
            .floor()
            .max(DVec3::ZERO)
            .as_uvec3()
            .min(dims - 1)
    };
    let mut grid: HashMap<[u32; 3], Vec<u32>> = HashMap::new();
    for &i in &live {
        let (a, b) = (index(boxes[i].0), index(boxes[i].1));
        for x in a.x..=b.x {
            for y in a.y..=b.y {
                for z in a.z..=b.z {
                    grid.entry([x, y, z]).or_default().push(i as u32);
                }
            }
        }
    }
    let mut pairs = Vec::new();
    for cell_tris in grid.values() {
        for (k, &i) in cell_tris.iter().enumerate() {
            for &j in &cell_tris[k + 1..] {
                let (i, j) = (i.min(j), i.max(j));
                let (bi, bj) = (boxes[i as usize], boxes[j as usize]);
                if bi.0.cmpgt(bj.1).any() || bj.0.cmpgt(bi.1).any() {
                    continue;
                }
                let (ti, tj) = (surface.triangles[i as usize], surface.triangles[j as usize]);
                if ti.iter().any(|v| tj.contains(v)) {
                    continue;
                }
                pairs.push([i, j]);
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs.retain(|&[i, j]| triangles_intersect(tri(i as usize), tri(j as usize)));
    pairs
}

/// Whether two triangles intersect (touching counts), in floating point with a tolerance
/// relative to their size. Not-coplanar: an edge of one crosses the other. Coplanar: their
/// projections onto the plane's dominant axis overlap.
pub(crate) fn triangles_intersect(p: [DVec3; 3], q: [DVec3; 3]) -> bool {
    let scale = p
        .iter()
        .chain(&q)
        .fold(0.0f64, |m, v| m.max((*v - p[0]).abs().max_element()));
    let eps = 1e-12 * scale.max(f64::MIN_POSITIVE);
    let np = (p[1] - p[0]).cross(p[2] - p[0]);
    let nq = (q[1] - q[0]).cross(q[2] - q[0]);
    let coplanar = q
        .iter()
        .all(|&v| np.normalize_or_zero().dot(v - p[0]).abs() <= eps);
    if coplanar {
        return coplanar_overlap(p, q, np);
    }
    (0..3).any(|k| segment_hits_triangle(p[k], p[(k + 1) % 3], q, nq, eps))
        || (0..3).any(|k| segment_hits_triangle(q[k], q[(k + 1) % 3], p, np, eps))
}

/// Whether segment `a`–`b` meets triangle `t` (normal `n`, unnormalised).
fn segment_hits_triangle(a: DVec3, b: DVec3, t: [DVec3; 3], n: DVec3, eps: f64) -> bool {
    let n1 = n.normalize_or_zero();
    let (da, db) = (n1.dot(a - t[0]), n1.dot(b - t[0]));
    if (da > eps && db > eps) || (da < -eps && db < -eps) {
        return false;
    }
    if (da - db).abs() <= eps {
        // Parallel to the plane and on it: the coplanar test handles whole triangles.
        return false;
    }
    let x = a + (b - a) * (da / (da - db));
    // Inside test: x on the inner side of each edge, with a little slack.
    (0..3).all(|k| {
        let e = t[(k + 1) % 3] - t[k];
        n1.dot(e.cross(x - t[k])) >= -eps * e.length().max(eps)
    })
}

/// Whether two coplanar triangles overlap: projected onto the plane of the dominant normal
/// component, an edge of one crosses an edge of the other, or a vertex of one is inside the
/// other.
fn coplanar_overlap(p: [DVec3; 3], q: [DVec3; 3], n: DVec3) -> bool {
    let a = n.abs();
    let (i, j) = if a.x >= a.y && a.x >= a.z {
        (1, 2)
    } else if a.y >= a.z {
        (0, 2)
    } else {
        (0, 1)
    };
    let pr = |v: DVec3| [v[i], v[j]];
    let (p2, q2) = (p.map(pr), q.map(pr));
    let orient = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    let inside = |t: [[f64; 2]; 3], x: [f64; 2]| {
        let s = [
            orient(t[0], t[1], x),
            orient(t[1], t[2], x),
            orient(t[2], t[0], x),
        ];
        s.iter().all(|&v| v >= 0.0) || s.iter().all(|&v| v <= 0.0)
    };
    let cross = |a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]| {
        let (d1, d2) = (orient(a, b, c), orient(a, b, d));
        let (d3, d4) = (orient(c, d, a), orient(c, d, b));
        d1 * d2 <= 0.0 && d3 * d4 <= 0.0 && !(d1 == 0.0 && d2 == 0.0)
    };
    for k in 0..3 {
        for m in 0..3 {
            if cross(p2[k], p2[(k + 1) % 3], q2[m], q2[(m + 1) % 3]) {
                return true;
            }
        }
    }
    inside(q2, p2[0]) || inside(p2, q2[0])
}

/// What [`close_holes`] did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct HoleClosing {
    /// Edge counts of the holes closed.
    pub closed: Vec<usize>,
    /// Edge counts of the holes left open (longer than allowed, or not a simple loop).
    pub left_open: Vec<usize>,
}

/// Closes the holes of `surface` bounded by at most `max_edges` edges: a triangle for a
/// three-edge hole, otherwise a fan from a new vertex at the loop's centroid, wound to match
/// the triangles around the hole. A hole is a loop of open edges (edges of one triangle);
/// a loop through a vertex with several open edges (two holes touching) is left alone.
/// Meant for the small gaps segmentation leaves, not to repair a surface: the fan is only
/// right for a roughly flat, star-shaped hole, so run [`check_surface`] afterwards.
pub fn close_holes(surface: &mut SurfaceMesh, max_edges: usize) -> HoleClosing {
    // Open directed edges (a → b of one triangle, whose reverse no triangle has).
    let mut count: HashMap<[u32; 2], usize> = HashMap::new();
    for t in &surface.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *count.entry([a.min(b), a.max(b)]).or_default() += 1;
        }
    }
    // The hole's loop runs the other way round: b → a.
    let mut next: HashMap<u32, Vec<u32>> = HashMap::new();
    for t in &surface.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if count[&[a.min(b), a.max(b)]] == 1 {
                next.entry(b).or_default().push(a);
            }
        }
    }
    let mut starts: Vec<u32> = next.keys().copied().collect();
    starts.sort_unstable();
    let mut done: std::collections::HashSet<u32> = std::collections::HashSet::new();
    let mut result = HoleClosing::default();
    for start in starts {
        if done.contains(&start) {
            continue;
        }
        let mut lp = vec![start];
        let mut simple = true;
        let mut v = start;
        loop {
            let Some(nx) = next.get(&v) else {
                simple = false;
                break;
            };
            if nx.len() != 1 {
                simple = false;
            }
            v = nx[0];
            if v == start {
                break;
            }
            if lp.contains(&v) || lp.len() > next.len() {
                simple = false;
                break;
            }
            lp.push(v);
        }
        done.extend(lp.iter().copied());
        if !simple || lp.len() < 3 || lp.len() > max_edges {
            result.left_open.push(lp.len());
            continue;
        }
        if lp.len() == 3 {
            surface.triangles.push([lp[0], lp[1], lp[2]]);
        } else {
            let c = lp.iter().fold(DVec3::ZERO, |s, &i| {
                s + DVec3::from_array(surface.vertices[i as usize])
            }) / lp.len() as f64;
            let ci = surface.vertices.len() as u32;
            surface.vertices.push(c.to_array());
            for k in 0..lp.len() {
                surface.triangles.push([lp[k], lp[(k + 1) % lp.len()], ci]);
            }
        }
        result.closed.push(lp.len());
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(v: [[f64; 3]; 3]) -> [DVec3; 3] {
        v.map(DVec3::from_array)
    }

    #[test]
    fn crossing_triangles_intersect_and_separate_ones_do_not() {
        let a = t([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        let b = t([[0.2, 0.2, -0.5], [0.2, 0.2, 0.5], [0.3, 0.3, 0.5]]);
        assert!(triangles_intersect(a, b));
        let c = t([[0.2, 0.2, 0.1], [0.2, 0.2, 0.5], [0.3, 0.3, 0.5]]);
        assert!(!triangles_intersect(a, c));
        // Coplanar overlap and coplanar disjoint.
        let d = t([[0.1, 0.1, 0.0], [2.0, 0.1, 0.0], [0.1, 2.0, 0.0]]);
        assert!(triangles_intersect(a, d));
        let e = t([[2.0, 2.0, 0.0], [3.0, 2.0, 0.0], [2.0, 3.0, 0.0]]);
        assert!(!triangles_intersect(a, e));
    }
}
