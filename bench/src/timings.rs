//! `lop-bench timings`: micro-timings of two inner loops, printed (they assert nothing, so they
//! are not tests):
//!
//! - collision detection plus penalty loads on the four shipped organs (they touch with ~1 mm
//!   gaps, so a 2 mm skin makes contacts), with and without the skin and the depth limit;
//! - the Green-coordinates cage deformation (`GcBinding::deform_into`) and the cage's scaled
//!   normals for the shipped liver's nodes, with box cages of 1, 2 and 3 subdivisions, and the
//!   time to bind the nodes to each cage.
//!
//! Run in release: `cargo run --release -p lop-bench -- timings`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use lop_sim::collide::{CollisionBody, CollisionParams, Collisions};
use lop_sim::gc::{subdivided_box_cage, GreenCoordinates};
use lop_sim::mesh::{read_mesh, TetMesh};

use crate::stats::quantile_sorted;

/// Arguments of `lop-bench timings`.
#[derive(clap::Args)]
pub struct TimingsArgs {
    /// Fewer repetitions: a quick look, with noisier numbers.
    #[arg(long)]
    quick: bool,
}

/// Runs both timings.
pub fn run(a: TimingsArgs) -> Result<()> {
    if cfg!(debug_assertions) {
        eprintln!("note: a debug build; the numbers mean something in release (`--release`)");
    }
    collisions(&a)?;
    cage_deformation(&a)
}

fn shipped(name: &str) -> Result<TetMesh> {
    let p: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/meshes")
        .join(name);
    read_mesh(&p).with_context(|| format!("shipped mesh {name}"))
}

/// Detection plus penalty loads on the organs scene's meshes, per call.
fn collisions(a: &TimingsArgs) -> Result<()> {
    let organs = ["liver", "spleen", "stomach", "pancreas"]
        .into_iter()
        .map(shipped)
        .collect::<Result<Vec<_>>>()?;
    let surfaces: Vec<&[[u32; 3]]> = organs.iter().map(|m| m.surface.as_slice()).collect();
    let mut c = Collisions::new(&surfaces);
    let bodies: Vec<CollisionBody> = organs
        .iter()
        .map(|m| CollisionBody {
            positions: &m.nodes,
            surface: &m.surface,
        })
        .collect();
    let mut loads: Vec<Vec<[f64; 3]>> = organs
        .iter()
        .map(|m| vec![[0.0; 3]; m.nodes.len()])
        .collect();
    let calls = if a.quick { 200 } else { 2000 };
    println!("collision detection + penalty loads, organs ({calls} calls each):");
    for (skin, limit) in [(0.0, f64::INFINITY), (0.002, f64::INFINITY), (0.002, 0.005)] {
        c.set_skin(skin);
        c.set_depth_limit(limit);
        let mut times = Vec::with_capacity(calls);
        for _ in 0..calls {
            let t0 = Instant::now();
            c.detect(&bodies);
            let mut slices: Vec<&mut [[f64; 3]]> =
                loads.iter_mut().map(|l| l.as_mut_slice()).collect();
            c.add_penalty_loads(&CollisionParams { stiffness: 10.0 }, &mut slices);
            times.push(t0.elapsed().as_secs_f64() * 1e6);
        }
        times.sort_by(f64::total_cmp);
        println!(
            "  skin {:.0} mm, depth limit {:.0} mm: {:?}; median {:.1} µs, p99 {:.1} µs, max {:.1} µs",
            skin * 1e3,
            limit * 1e3,
            c.stats(),
            quantile_sorted(&times, 0.50),
            quantile_sorted(&times, 0.99),
            times[times.len() - 1]
        );
    }
    Ok(())
}

/// Rotation by `angle` about `axis` (Rodrigues).
fn rotation(axis: [f64; 3], angle: f64) -> [[f64; 3]; 3] {
    let n = (axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]).sqrt();
    let k = axis.map(|c| c / n);
    let (s, c) = angle.sin_cos();
    let cross = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]];
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let id = if i == j { 1.0 } else { 0.0 };
            r[i][j] = c * id + s * cross[i][j] + (1.0 - c) * k[i] * k[j];
        }
    }
    r
}

/// `deform_into` and `scaled_normals` for the liver's nodes: best of 10 rounds, per call.
fn cage_deformation(a: &TimingsArgs) -> Result<()> {
    let mesh = shipped("liver")?;
    let nodes = &mesh.nodes;
    let (reps, rounds) = if a.quick { (200, 3) } else { (20_000, 10) };
    println!("Green-coordinates cage deformation, liver (best of {rounds} × {reps} calls):");
    for n in [1, 2, 3] {
        let cage = subdivided_box_cage(nodes, 0.01, n);
        let gc = GreenCoordinates::new(&cage.vertices, &cage.triangles)
            .with_context(|| format!("the box cage of {n} subdivisions"))?;
        let t = Instant::now();
        let binding = gc
            .bind(nodes)
            .context("binding the liver's nodes to the cage")?;
        let bind_time = t.elapsed();
        let r = rotation([0.2, 1.0, 0.3], 0.1);
        let moved: Vec<[f64; 3]> = cage
            .vertices
            .iter()
            .map(|v| r.map(|row| row[0] * v[0] + row[1] * v[1] + row[2] * v[2]))
            .collect();
        let mut sn = vec![[0.0; 3]; gc.triangle_count()];
        let mut out = vec![[0.0; 3]; nodes.len()];
        let mut best = f64::INFINITY;
        let mut best_sn = f64::INFINITY;
        for _ in 0..rounds {
            let t = Instant::now();
            for _ in 0..reps {
                binding.deform_into(std::hint::black_box(&moved), &sn, &mut out);
                std::hint::black_box(&mut out);
            }
            best = best.min(t.elapsed().as_secs_f64() / reps as f64);
            let t = Instant::now();
            for _ in 0..reps {
                gc.scaled_normals(std::hint::black_box(&moved), &mut sn);
                std::hint::black_box(&mut sn);
            }
            best_sn = best_sn.min(t.elapsed().as_secs_f64() / reps as f64);
        }
        println!(
            "  {} points, cage {} vertices + {} triangles: deform_into {:.2} µs, scaled_normals {:.3} µs, bind {:.2} ms",
            nodes.len(),
            gc.vertex_count(),
            gc.triangle_count(),
            best * 1e6,
            best_sn * 1e6,
            bind_time.as_secs_f64() * 1e3
        );
    }
    Ok(())
}
