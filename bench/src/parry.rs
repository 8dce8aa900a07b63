//! `lop-bench collide` (cargo feature `parry`, off by default): our collision detection and tool
//! queries against `parry3d-f64` (parry's `f64` build), on the shipped `organs` scene.
//!
//! ```text
//! cargo run --release -p lop-bench --features parry -- collide
//! ```
//!
//! - **Organ-to-organ detection** (liver, spleen, stomach, pancreas; the scene's skin and depth
//!   limit): [`lop_sim::collide::Collisions::detect`] (which refits its hierarchies every call)
//!   against the same vertex-in-body test written on parry — for every ordered pair of bodies
//!   whose boxes overlap, each surface vertex inside the other's padded box is projected on the
//!   other's `TriMesh` (`ORIENTED`, so `is_inside` comes from its angle-weighted pseudo-normals)
//!   with `project_local_point_and_get_location_with_max_dist`. At rest (as loaded) and
//!   overlapped (every body moved 3 mm towards the scene's centre), on a surface that is
//!   rigid (nothing to update) and deforming (a small wobble every frame: our detection refits
//!   inside `detect`; parry's mesh is updated with `set_vertices` — refit plus pseudo-normals —
//!   or rebuilt from scratch, timed separately).
//! - **Tool queries** (tool-sized points around the liver's surface): our brute-force
//!   [`closest_on_surface`](lop_sim::contact::closest_on_surface), the god-object's
//!   [`SurfaceSet::closest_in_body`](lop_sim::haptic::SurfaceSet::closest_in_body) (greedy walk
//!   plus hierarchy check, bounded by the reach), parry's `project_local_point_and_get_location`
//!   (unbounded and bounded) and `contains_local_point`.
//!
//! Every row gives the time per call (median and p99 over single calls for detection and
//! updates; mean over a batch for the sub-microsecond queries), the heap allocations per call
//! counted by a counting global allocator (this module installs it; it exists only with the
//! feature), and whether the answers agree with ours.

use std::time::Instant;

use anyhow::Result;
use clap::Args;
use lop_sim::collide::{CollisionBody, Collisions};
use lop_sim::contact::closest_on_surface;
use lop_sim::haptic::SurfaceSet;
use lop_test_support::alloc::{allocations, Counting};
use lop_test_support::rng::Rng;
use parry3d_f64::math::Vector;
use parry3d_f64::query::{PointQuery, PointQueryWithLocation};
use parry3d_f64::shape::{TriMesh, TriMeshFlags};

use crate::lop::shipped_scene;

#[global_allocator]
static GLOBAL: Counting = Counting::every_thread();

/// Options of `lop-bench collide`.
#[derive(Args, Debug)]
pub struct CollideArgs {
    /// Fewer repetitions (smoke test).
    #[arg(long)]
    quick: bool,
}

/// One printed row.
struct Line {
    what: String,
    p50_us: f64,
    p99_us: f64,
    allocs: f64,
    agree: String,
}

/// Times `reps` single calls of `f` (after one warm-up call): median and p99 in µs, and
/// allocations per call.
fn time_calls(reps: usize, mut f: impl FnMut()) -> (f64, f64, f64) {
    f();
    let mut ns = Vec::with_capacity(reps);
    let a0 = allocations();
    for _ in 0..reps {
        let t0 = Instant::now();
        f();
        ns.push(t0.elapsed().as_nanos() as f64);
    }
    let allocs = (allocations() - a0) as f64 / reps as f64;
    ns.sort_by(f64::total_cmp);
    let q = |p: f64| ns[((ns.len() - 1) as f64 * p).round() as usize] / 1e3;
    (q(0.5), q(0.99), allocs)
}

/// Times a batch of `n` queries run by `f` (after one warm-up batch): mean µs per query and
/// allocations per query.
fn time_batch(n: usize, rounds: usize, mut f: impl FnMut()) -> (f64, f64) {
    f();
    let a0 = allocations();
    let t0 = Instant::now();
    for _ in 0..rounds {
        f();
    }
    let us = t0.elapsed().as_secs_f64() * 1e6 / (n * rounds) as f64;
    let allocs = (allocations() - a0) as f64 / (n * rounds) as f64;
    (us, allocs)
}

fn pv(p: [f64; 3]) -> Vector {
    Vector::new(p[0], p[1], p[2])
}

/// One body as parry sees it: its surface vertices only (parry wants a compact buffer), the
/// triangles re-indexed onto them.
struct ParryBody {
    /// Global node of each parry vertex.
    nodes: Vec<u32>,
    indices: Vec<[u32; 3]>,
    /// Scratch for the vertex copy of each update.
    buffer: Vec<Vector>,
    mesh: TriMesh,
}

const FLAGS: TriMeshFlags = TriMeshFlags::ORIENTED.union(TriMeshFlags::DEFORMABLE);

impl ParryBody {
    fn new(positions: &[[f64; 3]], surface: &[[u32; 3]]) -> Result<ParryBody> {
        ParryBody::with_flags(positions, surface, FLAGS)
    }

    fn with_flags(
        positions: &[[f64; 3]],
        surface: &[[u32; 3]],
        flags: TriMeshFlags,
    ) -> Result<ParryBody> {
        let mut nodes: Vec<u32> = surface.iter().flatten().copied().collect();
        nodes.sort_unstable();
        nodes.dedup();
        let local = |n: u32| nodes.binary_search(&n).expect("surface node") as u32;
        let indices: Vec<[u32; 3]> = surface.iter().map(|t| t.map(local)).collect();
        let buffer: Vec<Vector> = nodes.iter().map(|&n| pv(positions[n as usize])).collect();
        let mesh = TriMesh::with_flags(buffer.clone(), indices.clone(), flags)
            .map_err(|e| anyhow::anyhow!("parry TriMesh: {e:?}"))?;
        Ok(ParryBody {
            nodes,
            indices,
            buffer,
            mesh,
        })
    }

    /// Copies the positions in and refits (`set_vertices`: BVH refit + pseudo-normals).
    fn refit(&mut self, positions: &[[f64; 3]]) {
        for (b, &n) in self.buffer.iter_mut().zip(&self.nodes) {
            *b = pv(positions[n as usize]);
        }
        self.mesh.set_vertices(&self.buffer);
    }

    /// Builds a new mesh from the positions (BVH build + pseudo-normals).
    fn rebuild(&mut self, positions: &[[f64; 3]]) {
        for (b, &n) in self.buffer.iter_mut().zip(&self.nodes) {
            *b = pv(positions[n as usize]);
        }
        self.mesh = TriMesh::with_flags(self.buffer.clone(), self.indices.clone(), FLAGS)
            .expect("same topology");
    }
}

/// A penetration as both detectors report it: body, node, other body, depth.
type Hit = (usize, u32, usize, f64);

/// The vertex-in-body detection of `Collisions::detect`, written on parry.
// `!(depth > 0.0)` as in lop-sim: a NaN depth must fail the test.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
fn parry_detect(
    bodies: &[ParryBody],
    positions: &[Vec<[f64; 3]>],
    skin: f64,
    limit: f64,
    out: &mut Vec<Hit>,
) {
    out.clear();
    let reach = limit.max(skin);
    for (a, ba) in bodies.iter().enumerate() {
        let aa = ba.mesh.local_aabb();
        for (o, bo) in bodies.iter().enumerate() {
            if o == a {
                continue;
            }
            let ao = bo.mesh.local_aabb();
            let (olo, ohi) = (ao.mins - Vector::splat(skin), ao.maxs + Vector::splat(skin));
            if !(aa.mins.cmple(ohi).all() && olo.cmple(aa.maxs).all()) {
                continue;
            }
            for &node in &ba.nodes {
                let p = pv(positions[a][node as usize]);
                if !(olo.cmple(p).all() && p.cmple(ohi).all()) {
                    continue;
                }
                let Some((proj, _)) = bo
                    .mesh
                    .project_local_point_and_get_location_with_max_dist(p, false, reach)
                else {
                    continue;
                };
                let dist = (proj.point - p).length();
                let inside = proj.is_inside && dist > 0.0;
                let depth = if inside { dist } else { -dist } + skin;
                if !(depth > 0.0) || (inside && dist > limit) {
                    continue;
                }
                out.push((a, node, o, depth));
            }
        }
    }
}

/// How two detections compare: same (body, node, other) set, largest depth difference.
fn compare(ours: &[Hit], theirs: &[Hit]) -> String {
    let key = |h: &Hit| (h.0, h.1, h.2);
    let mut a: Vec<Hit> = ours.to_vec();
    let mut b: Vec<Hit> = theirs.to_vec();
    a.sort_by_key(key);
    b.sort_by_key(key);
    let (mut only_ours, mut only_theirs, mut dmax) = (0, 0, 0.0f64);
    let (mut i, mut j) = (0, 0);
    while i < a.len() || j < b.len() {
        match (a.get(i), b.get(j)) {
            (Some(x), Some(y)) if key(x) == key(y) => {
                dmax = dmax.max((x.3 - y.3).abs());
                i += 1;
                j += 1;
            }
            (Some(x), Some(y)) if key(x) < key(y) => {
                only_ours += 1;
                i += 1;
            }
            (Some(_), None) => {
                only_ours += 1;
                i += 1;
            }
            _ => {
                only_theirs += 1;
                j += 1;
            }
        }
    }
    if only_ours == 0 && only_theirs == 0 {
        format!("same {} hits, depth Δ ≤ {dmax:.1e} m", a.len())
    } else {
        format!(
            "{} vs {} hits: {only_ours} only ours, {only_theirs} only parry, depth Δ ≤ {dmax:.1e} m",
            a.len(),
            b.len()
        )
    }
}

/// Runs the comparison.
pub fn run(a: CollideArgs) -> Result<()> {
    let reps = if a.quick { 20 } else { 300 };
    let scene = shipped_scene("organs")?;
    let (skin, limit) = (scene.collision.skin, scene.collision.depth_limit);
    let loaded = lop_scene::load(scene)?;
    let world = loaded.world;
    let rest: Vec<Vec<[f64; 3]>> = world
        .bodies
        .iter()
        .map(|b| b.model.positions().to_vec())
        .collect();
    let surfaces: Vec<&[[u32; 3]]> = world.bodies.iter().map(|b| &b.mesh.surface[..]).collect();
    let triangles: usize = surfaces.iter().map(|s| s.len()).sum();

    // Overlapped: every body 3 mm towards the centre of the bodies' centroids.
    let centroid = |x: &[[f64; 3]]| {
        let s = x
            .iter()
            .fold([0.0; 3], |a, p| [a[0] + p[0], a[1] + p[1], a[2] + p[2]]);
        s.map(|c| c / x.len() as f64)
    };
    let cs: Vec<[f64; 3]> = rest.iter().map(|x| centroid(x)).collect();
    let centre = centroid(&cs);
    let overlapped: Vec<Vec<[f64; 3]>> = rest
        .iter()
        .zip(&cs)
        .map(|(x, c)| {
            let d = [0, 1, 2].map(|k| centre[k] - c[k]);
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let m = d.map(|v| 0.003 * v / l);
            x.iter()
                .map(|p| [p[0] + m[0], p[1] + m[1], p[2] + m[2]])
                .collect()
        })
        .collect();

    let mut lines = Vec::new();
    println!(
        "lop-bench collide: organs scene, {} bodies, {triangles} surface triangles, skin {} mm, depth limit {} mm\n",
        world.bodies.len(),
        skin * 1e3,
        limit * 1e3
    );

    for (label, base) in [("rest", &rest), ("overlapped 3 mm", &overlapped)] {
        let mut ours = Collisions::new(&surfaces);
        ours.set_skin(skin);
        ours.set_depth_limit(limit);
        let mut parry: Vec<ParryBody> = base
            .iter()
            .zip(&surfaces)
            .map(|(x, s)| ParryBody::new(x, s))
            .collect::<Result<_>>()?;
        let mut theirs: Vec<Hit> = Vec::with_capacity(
            surfaces.iter().map(|s| s.len() * 3).sum::<usize>() * surfaces.len(),
        );

        // Rigid surfaces.
        let cb: Vec<CollisionBody<'_>> = base
            .iter()
            .zip(&surfaces)
            .map(|(x, s)| CollisionBody {
                positions: x,
                surface: s,
            })
            .collect();
        let our_hits: Vec<Hit> = ours
            .detect(&cb)
            .iter()
            .map(|p| (p.body, p.node, p.other, p.depth))
            .collect();
        parry_detect(&parry, base, skin, limit, &mut theirs);
        let agree = compare(&our_hits, &theirs);
        let stats = ours.stats();
        let (p50, p99, al) = time_calls(reps, || {
            std::hint::black_box(ours.detect(&cb));
        });
        lines.push(Line {
            what: format!(
                "detect {label}: ours (refit + {} vertex queries)",
                stats.vertex_queries
            ),
            p50_us: p50,
            p99_us: p99,
            allocs: al,
            agree: format!("{} penetrations", our_hits.len()),
        });
        let (p50, p99, al) = time_calls(reps, || {
            parry_detect(&parry, base, skin, limit, &mut theirs);
        });
        lines.push(Line {
            what: format!("detect {label}: parry (queries only)"),
            p50_us: p50,
            p99_us: p99,
            allocs: al,
            agree,
        });

        // Deforming: a ±0.5 mm wobble, a new one every frame (computed untimed).
        let frames: Vec<Vec<Vec<[f64; 3]>>> = (0..8)
            .map(|f| {
                base.iter()
                    .map(|x| {
                        x.iter()
                            .map(|p| {
                                let ph = f as f64 * 0.7 + 300.0 * (p[0] + 2.0 * p[1] + 3.0 * p[2]);
                                [
                                    p[0] + 5e-4 * ph.sin(),
                                    p[1] + 5e-4 * (1.3 * ph).cos(),
                                    p[2] + 5e-4 * (0.7 * ph).sin(),
                                ]
                            })
                            .collect()
                    })
                    .collect()
            })
            .collect();
        let frame_bodies: Vec<Vec<CollisionBody<'_>>> = frames
            .iter()
            .map(|x| {
                x.iter()
                    .zip(&surfaces)
                    .map(|(x, s)| CollisionBody {
                        positions: x,
                        surface: s,
                    })
                    .collect()
            })
            .collect();
        let mut frame = 0;
        let (p50, p99, al) = time_calls(reps, || {
            frame = (frame + 1) % frames.len();
            std::hint::black_box(ours.detect(&frame_bodies[frame]));
        });
        lines.push(Line {
            what: format!("detect {label}, deforming: ours (refit inside)"),
            p50_us: p50,
            p99_us: p99,
            allocs: al,
            agree: String::new(),
        });
        let (p50, p99, al) = time_calls(reps, || {
            frame = (frame + 1) % frames.len();
            for (b, x) in parry.iter_mut().zip(&frames[frame]) {
                b.refit(x);
            }
        });
        lines.push(Line {
            what: "  parry update: copy + set_vertices (refit + pseudo-normals), all bodies"
                .to_string(),
            p50_us: p50,
            p99_us: p99,
            allocs: al,
            agree: String::new(),
        });
        let mut plain: Vec<ParryBody> = base
            .iter()
            .zip(&surfaces)
            .map(|(x, s)| ParryBody::with_flags(x, s, TriMeshFlags::DEFORMABLE))
            .collect::<Result<_>>()?;
        let (p50, p99, al) = time_calls(reps, || {
            frame = (frame + 1) % frames.len();
            for (b, x) in plain.iter_mut().zip(&frames[frame]) {
                b.refit(x);
            }
        });
        lines.push(Line {
            what: "  parry update without ORIENTED: copy + set_vertices (refit only)".to_string(),
            p50_us: p50,
            p99_us: p99,
            allocs: al,
            agree: "no inside test".into(),
        });
        let (p50, p99, al) = time_calls(reps.min(100), || {
            frame = (frame + 1) % frames.len();
            for (b, x) in parry.iter_mut().zip(&frames[frame]) {
                b.rebuild(x);
            }
        });
        lines.push(Line {
            what: "  parry update: rebuild TriMesh, all bodies".to_string(),
            p50_us: p50,
            p99_us: p99,
            allocs: al,
            agree: String::new(),
        });
        // Agreement on a deformed frame after parry's refit.
        let x = &frames[3];
        for (b, xb) in parry.iter_mut().zip(x) {
            b.refit(xb);
        }
        let our_hits: Vec<Hit> = ours
            .detect(&frame_bodies[3])
            .iter()
            .map(|p| (p.body, p.node, p.other, p.depth))
            .collect();
        parry_detect(&parry, x, skin, limit, &mut theirs);
        let worst = compare(&our_hits, &theirs);
        let (p50, p99, al) = time_calls(reps, || {
            parry_detect(&parry, x, skin, limit, &mut theirs);
        });
        lines.push(Line {
            what: "  parry detect on the refitted meshes (queries only)".to_string(),
            p50_us: p50,
            p99_us: p99,
            allocs: al,
            agree: worst,
        });
    }

    // Tool queries around the liver (body 0).
    let liver = &rest[0];
    let tris = surfaces[0];
    let mut rng = Rng::new(0x5eed);
    let queries: Vec<[f64; 3]> = (0..2000)
        .map(|_| {
            let t = tris[(rng.unit() * tris.len() as f64) as usize];
            let (u, v) = (rng.unit(), rng.unit());
            let (u, v) = if u + v > 1.0 {
                (1.0 - u, 1.0 - v)
            } else {
                (u, v)
            };
            let [a, b, c] = t.map(|i| liver[i as usize]);
            let p = [0, 1, 2].map(|k| a[k] + u * (b[k] - a[k]) + v * (c[k] - a[k]));
            // Within ±6 mm of the surface, in a random direction.
            let d = [rng.unit() - 0.5, rng.unit() - 0.5, rng.unit() - 0.5];
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-9);
            let r = 0.006 * rng.unit();
            [0, 1, 2].map(|k| p[k] + r * d[k] / l)
        })
        .collect();
    // A coherent path (what the god-object asks tick after tick): 20 steps between
    // successive random points.
    let path: Vec<[f64; 3]> = queries
        .windows(2)
        .take(100)
        .flat_map(|w| {
            (0..20).map(move |s| {
                let f = s as f64 / 20.0;
                [0, 1, 2].map(|k| w[0][k] + f * (w[1][k] - w[0][k]))
            })
        })
        .collect();
    let n = queries.len();
    let rounds = if a.quick { 2 } else { 20 };
    let reach = 0.003 + 4e-7;
    let mesh = ParryBody::new(liver, tris)?.mesh;
    let mut set = SurfaceSet::new(liver.len(), &[tris]);
    set.set_positions(|i| liver[i]);

    // Answers: ours brute force vs parry's projection (distance and inside flag).
    let (mut dist_max, mut inside_diff, mut set_diff) = (0.0f64, 0, 0);
    for &q in &queries {
        let h = closest_on_surface(liver.as_slice(), tris, q).expect("non-empty");
        let (proj, _) = mesh.project_local_point_and_get_location(pv(q), false);
        let d = (proj.point - pv(q)).length();
        dist_max = dist_max.max((d - h.distance).abs());
        if proj.is_inside != h.inside && h.distance > 0.0 {
            inside_diff += 1;
        }
        let c = set.closest_in_body(0, q, f64::INFINITY).expect("non-empty");
        if c.hit.distance != h.distance {
            set_diff += 1;
        }
    }

    let (us, al) = time_batch(n, rounds.min(4), || {
        for &q in &queries {
            std::hint::black_box(closest_on_surface(liver.as_slice(), tris, q));
        }
    });
    lines.push(Line {
        what: format!(
            "tool query, liver ({} tris): ours brute force closest_on_surface",
            tris.len()
        ),
        p50_us: us,
        p99_us: f64::NAN,
        allocs: al,
        agree: "reference".into(),
    });
    let (us, al) = time_batch(n, rounds, || {
        for &q in &queries {
            std::hint::black_box(set.closest_in_body(0, q, f64::INFINITY));
        }
    });
    lines.push(Line {
        what: "tool query: ours SurfaceSet::closest_in_body (walk + BVH), unbounded".into(),
        p50_us: us,
        p99_us: f64::NAN,
        allocs: al,
        agree: format!("{set_diff} distance differences"),
    });
    let (us, al) = time_batch(path.len(), rounds, || {
        for &q in &path {
            std::hint::black_box(set.closest_in_body(0, q, f64::INFINITY));
        }
    });
    lines.push(Line {
        what: "tool query: ours closest_in_body, unbounded, coherent path".into(),
        p50_us: us,
        p99_us: f64::NAN,
        allocs: al,
        agree: String::new(),
    });
    let (us, al) = time_batch(path.len(), rounds, || {
        for &q in &path {
            std::hint::black_box(mesh.project_local_point_and_get_location(pv(q), false));
        }
    });
    lines.push(Line {
        what: "tool query: parry project_local_point_and_get_location, coherent path".into(),
        p50_us: us,
        p99_us: f64::NAN,
        allocs: al,
        agree: String::new(),
    });
    let (us, al) = time_batch(n, rounds, || {
        for &q in &queries {
            std::hint::black_box(set.closest_in_body(0, q, reach));
        }
    });
    lines.push(Line {
        what: "tool query: ours closest_in_body, reach = tip radius (god-object)".into(),
        p50_us: us,
        p99_us: f64::NAN,
        allocs: al,
        agree: String::new(),
    });
    let (us, al) = time_batch(n, rounds, || {
        for &q in &queries {
            std::hint::black_box(mesh.project_local_point_and_get_location(pv(q), false));
        }
    });
    lines.push(Line {
        what: "tool query: parry project_local_point_and_get_location, unbounded".into(),
        p50_us: us,
        p99_us: f64::NAN,
        allocs: al,
        agree: format!(
            "distance Δ ≤ {dist_max:.1e} m; inside differs {inside_diff}/{n} (ours: face normal)"
        ),
    });
    let (us, al) = time_batch(n, rounds, || {
        for &q in &queries {
            std::hint::black_box(mesh.project_local_point_and_get_location_with_max_dist(
                pv(q),
                false,
                reach,
            ));
        }
    });
    lines.push(Line {
        what: "tool query: parry ..._with_max_dist, reach = tip radius".into(),
        p50_us: us,
        p99_us: f64::NAN,
        allocs: al,
        agree: String::new(),
    });
    let (us, al) = time_batch(n, rounds, || {
        for &q in &queries {
            std::hint::black_box(mesh.contains_local_point(pv(q)));
        }
    });
    lines.push(Line {
        what: "tool query: parry contains_local_point".into(),
        p50_us: us,
        p99_us: f64::NAN,
        allocs: al,
        agree: String::new(),
    });

    let w = lines
        .iter()
        .map(|l| l.what.chars().count())
        .max()
        .unwrap_or(0);
    println!(
        "{:w$}  {:>9}  {:>9}  {:>10}  answers",
        "what (µs per call; queries: mean)", "p50 µs", "p99 µs", "allocs"
    );
    for l in &lines {
        let p99 = if l.p99_us.is_nan() {
            "-".to_string()
        } else {
            format!("{:.2}", l.p99_us)
        };
        println!(
            "{:w$}  {:>9.3}  {:>9}  {:>10.2}  {}",
            l.what, l.p50_us, p99, l.allocs, l.agree
        );
    }
    Ok(())
}
