//! Heat and burns (`lop_sim::heat`): energy conservation, the 1-D analytic solution on a bar
//! with its convergence under refinement, cooling to the air at the lumped rate, conduction
//! between touching bodies, burns, no allocation per step, and stability at any time step.
//!
//! Structured meshes are Kuhn-split boxes (`fem::box_mesh`): their tetrahedra are
//! orthoschemes (no obtuse dihedral angle), so the scheme obeys the maximum principle there
//! and the x-modes of a bar are exact discrete eigenvectors. The shipped beam and liver are
//! unstructured TetGen meshes.

use crate::common;

use common::shipped_mesh as shipped;
use lop_sim::fem::box_mesh;
use lop_sim::heat::{HeatBody, HeatError, HeatParameters, HeatWorld, Link};
use lop_sim::mesh::TetMesh;
use lop_test_support::alloc;
use lop_test_support::rng::Rng;

// The counting allocator (`Counting::armed_threads`) is installed once for this
// test binary, in `main.rs`.

fn insulated(dt: f64) -> HeatParameters {
    HeatParameters {
        air_coefficient: 0.0,
        dt,
        ..HeatParameters::default()
    }
}

/// Total capacity `Σ Cᵢ` and the capacity-weighted mean temperature.
fn mean_temperature(b: &HeatBody) -> f64 {
    let c: f64 = b.capacities().iter().sum();
    b.heat_content() / c
}

/// A surface triangle of `mesh` whose nodes all satisfy `pred`.
fn surface_triangle(mesh: &TetMesh, pred: impl Fn([f64; 3]) -> bool) -> [u32; 3] {
    *mesh
        .surface
        .iter()
        .find(|t| t.iter().all(|&i| pred(mesh.nodes[i as usize])))
        .expect("a surface triangle matching the predicate")
}

/// (1) Insulated: the heat content rises by exactly the injected energy `P t` (to round-off,
/// 1e-10 relative), a uniform field stays put, and once the power stops the peak falls while
/// the content stays constant, ending uniform at the mean.
#[test]
fn heat_is_conserved_with_the_air_exchange_off() {
    let mesh = box_mesh([0.02; 3], [4, 4, 4], |_| false);
    let mut body = HeatBody::new(&mesh, insulated(0.01)).unwrap();
    let capacity: f64 = body.capacities().iter().sum();
    // Σ Cᵢ = ρ c V exactly.
    let rho_c_v = 1060.0 * 3540.0 * 0.02f64.powi(3);
    assert!((capacity - rho_c_v).abs() < 1e-12 * rho_c_v, "{capacity}");

    // A uniform field is a steady state.
    let e0 = body.heat_content();
    for _ in 0..10 {
        body.step().unwrap();
    }
    let drift = body
        .temperatures()
        .iter()
        .map(|t| (t - 37.0).abs())
        .fold(0.0, f64::max);
    assert!(drift < 1e-12, "uniform field drifted by {drift} K");

    // 20 W on one surface triangle for 1 s: 20 J.
    let tri = surface_triangle(&mesh, |p| p[1] == 0.02);
    let power = 20.0;
    let steps = 100;
    for _ in 0..steps {
        body.heat_point(tri, [0.2, 0.3, 0.5], power).unwrap();
        let r = body.step().unwrap();
        assert!((r.injected - power * 0.01).abs() < 1e-15);
        assert_eq!(r.to_air, 0.0);
    }
    let injected = power * 0.01 * steps as f64;
    let gained = body.heat_content() - e0;
    let rel = (gained - injected).abs() / injected;
    println!("injected {injected} J, heat content gained {gained} J, relative error {rel:e}");
    assert!(rel < 1e-10, "relative energy error {rel:e}");

    // Power off: the peak falls every step, the content does not change.
    let e1 = body.heat_content();
    let mut peak = body.max_temperature();
    for _ in 0..200 {
        let r = body.step().unwrap();
        assert!(r.max_temperature < peak, "{} !< {peak}", r.max_temperature);
        peak = r.max_temperature;
    }
    assert!((body.heat_content() - e1).abs() < 1e-12 * e1);
    // A huge step reaches the steady state: uniform at the mean 37 + 20 J / ΣC.
    // (Slowest mode: α π²/L² · Δt ≈ 3400, so each step leaves 3e-4 of the deviation.)
    body.set_dt(1e6).unwrap();
    for _ in 0..4 {
        body.step().unwrap();
    }
    let mean = 37.0 + injected / capacity;
    for &t in body.temperatures() {
        assert!((t - mean).abs() < 1e-9, "{t} vs {mean}");
    }
    let rel = (body.heat_content() - e1).abs() / e1;
    // At Δt = 1e6 s, K outweighs C/Δt ~1e4-fold in the step matrix, and so does the round-off
    // of the balance (still 1e-10 of the content at most).
    println!("after 4 steps of 1e6 s: relative energy error {rel:e}");
    assert!(rel < 1e-10);
}

/// Amplitude of the `cos(πx/L)` mode of `T − mean`, by the capacity-weighted projection.
fn cos_amplitude(body: &HeatBody, mesh: &TetMesh, x0: f64, l: f64) -> f64 {
    let mean = mean_temperature(body);
    let (mut num, mut den) = (0.0, 0.0);
    for ((p, &t), &c) in mesh
        .nodes
        .iter()
        .zip(body.temperatures())
        .zip(body.capacities())
    {
        let phi = (std::f64::consts::PI * (p[0] - x0) / l).cos();
        num += c * (t - mean) * phi;
        den += c * phi * phi;
    }
    num / den
}

/// Decay rate of the `cos(πx/L)` mode on an insulated bar over `t_end`, 1/s.
fn bar_decay_rate(mesh: &TetMesh, x0: f64, l: f64, p: HeatParameters, t_end: f64) -> f64 {
    let dt = p.dt;
    let mut body = HeatBody::new(mesh, p).unwrap();
    let field: Vec<f64> = mesh
        .nodes
        .iter()
        .map(|p| 37.0 + 5.0 * (std::f64::consts::PI * (p[0] - x0) / l).cos())
        .collect();
    body.set_temperatures(&field).unwrap();
    let a0 = cos_amplitude(&body, mesh, x0, l);
    let steps = (t_end / dt).round() as usize;
    for _ in 0..steps {
        body.step().unwrap();
    }
    let a1 = cos_amplitude(&body, mesh, x0, l);
    -(a1 / a0).ln() / (steps as f64 * dt)
}

/// (2) The 1-D analytic solution: on a bar insulated everywhere, `T = T₀ + A cos(πx/L)` decays
/// as `exp(−α π² t / L²)`. On Kuhn-split bars of n cells along x the error is the spatial one
/// of the lumped linear elements, `(πh/L)²/12` (0.8 % at n = 10), plus the backward-Euler
/// time error `λΔt/2` (2.5e-5 here): second-order convergence, the error quartering at each
/// refinement. On the shipped, unstructured beam mesh it is within a few percent.
#[test]
fn bar_matches_the_1d_analytic_solution_and_converges() {
    let p = HeatParameters::default();
    let alpha = p.diffusivity();
    let (l, w) = (0.1, 0.01);
    let rate = alpha * std::f64::consts::PI.powi(2) / (l * l);
    let dt = 5e-5 / rate;
    let t_end = 0.25 / rate;
    let mut errors = Vec::new();
    for n in [5, 10, 20, 40] {
        let mesh = box_mesh([l, w, w], [n, 2, 2], |_| false);
        let measured = bar_decay_rate(&mesh, 0.0, l, insulated(dt), t_end);
        let err = (measured - rate).abs() / rate;
        let predicted = (std::f64::consts::PI / n as f64).powi(2) / 12.0;
        println!(
            "bar n = {n:2}: rate {measured:.6e} 1/s vs analytic {rate:.6e}: error {:.4} % \
             (predicted spatial {:.4} %)",
            100.0 * err,
            100.0 * predicted
        );
        // Within 10 % (plus the time error) of the predicted spatial error.
        assert!(
            (err - predicted).abs() < 0.1 * predicted + 5e-5,
            "n = {n}: {err} vs {predicted}"
        );
        errors.push(err);
    }
    assert!(errors[1] < 0.01, "n = 10: {} >= 1 %", errors[1]);
    for k in 1..errors.len() {
        let ratio = errors[k - 1] / errors[k];
        println!("error ratio per halving of h: {ratio:.3}");
        assert!(ratio > 3.5 && ratio < 4.5, "convergence ratio {ratio}");
    }

    // The shipped beam: 0.4 m along x from x = 0, unstructured.
    let beam = shipped("beam");
    let (lo, hi) = lop_sim::mesh::bounds(&beam.nodes);
    let l = hi[0] - lo[0];
    let rate = alpha * std::f64::consts::PI.powi(2) / (l * l);
    let measured = bar_decay_rate(&beam, lo[0], l, insulated(1e-3 / rate), 0.25 / rate);
    let err = (measured - rate).abs() / rate;
    println!(
        "shipped beam: rate {measured:.6e} 1/s vs analytic {rate:.6e}: error {:.3} %",
        100.0 * err
    );
    assert!(err < 0.03, "beam error {err}");
}

/// (3) Air exchange. A 1 cm cube at 37 °C in 22 °C air with h = 10 W/m²/K has Biot number
/// `h (V/A) / k` = 0.032: it cools almost uniformly, at close to the lumped rate
/// `hA/(ρcV)`, and — exactly — at the rate of the slowest mode of the continuum problem,
/// `3 α λ₁² / a²` with `λ₁ tan λ₁ = h a / k` (half-width `a`), which is 3.1 % below the lumped
/// one. The insulated twin keeps its heat; with the air on, the reported balance holds.
#[test]
fn body_cools_to_the_air_at_the_lumped_rate() {
    let a = 0.005;
    let mesh = box_mesh([2.0 * a; 3], [6, 6, 6], |_| false);
    let p = HeatParameters::default();
    let (h, t_air) = (p.air_coefficient, p.air_temperature);
    let rho_c = p.density * p.specific_heat;
    let lumped = h * 6.0 * (2.0 * a) * (2.0 * a) / (rho_c * (2.0 * a).powi(3));
    // λ tan λ = Bi by Newton.
    let bi = h * a / p.conductivity;
    let mut lam = bi.sqrt();
    for _ in 0..50 {
        let f = lam * lam.tan() - bi;
        let df = lam.tan() + lam / lam.cos().powi(2);
        lam -= f / df;
    }
    let exact = 3.0 * p.diffusivity() * lam * lam / (a * a);

    let dt = 1e-3 / lumped;
    let mut cooled = HeatBody::new(&mesh, HeatParameters { dt, ..p }).unwrap();
    let mut kept = HeatBody::new(&mesh, insulated(dt)).unwrap();
    let e_kept = kept.heat_content();
    // Let the fast modes (rate ≥ α π²/a² ≈ 0.055 1/s) die out, then measure.
    let (t1, t2) = (0.3 / lumped, 1.0 / lumped);
    let mut excess = [0.0; 2];
    let mut t = 0.0;
    let mut k = 0;
    while k < 2 {
        let e = cooled.heat_content();
        let r = cooled.step().unwrap();
        kept.step().unwrap();
        let balance = cooled.heat_content() - (e - r.to_air);
        assert!(
            balance.abs() < 1e-12 * e,
            "energy balance off by {balance} J"
        );
        t += dt;
        if t >= [t1, t2][k] - 1e-9 * dt {
            excess[k] = mean_temperature(&cooled) - t_air;
            k += 1;
        }
    }
    let measured = -(excess[1] / excess[0]).ln() / (t2 - t1);
    println!(
        "cube cooling rate {measured:.6e} 1/s; lumped hA/(ρcV) {lumped:.6e} ({:+.3} %), \
         continuum slowest mode {exact:.6e} ({:+.3} %)",
        100.0 * (measured / lumped - 1.0),
        100.0 * (measured / exact - 1.0)
    );
    assert!((measured / lumped - 1.0).abs() < 0.05);
    assert!((measured / exact - 1.0).abs() < 0.005);
    assert!((kept.heat_content() - e_kept).abs() < 1e-12 * e_kept);
    assert_eq!(
        kept.temperatures().iter().copied().fold(0.0, f64::max),
        37.0
    );
}

/// Two boxes `size` side by side along x, touching at `x = size[0]`, with the links joining
/// the coincident nodes of the shared face (contact coefficient `coef`, W/m²/K).
fn touching_boxes(size: [f64; 3], cells: [usize; 3], coef: f64, p: HeatParameters) -> HeatWorld {
    let a = box_mesh(size, cells, |_| false);
    let mut b = box_mesh(size, cells, |_| false);
    for n in &mut b.nodes {
        n[0] += size[0];
    }
    let mut world = HeatWorld::new(vec![
        HeatBody::new(&a, p).unwrap(),
        HeatBody::new(&b, p).unwrap(),
    ])
    .unwrap();
    let mut links = Vec::new();
    for (i, pa) in a.nodes.iter().enumerate() {
        if pa[0] != size[0] {
            continue;
        }
        let j = b.nodes.iter().position(|pb| pb == pa).unwrap();
        links.push(world.contact_link(0, i as u32, 1, j as u32, coef).unwrap());
    }
    world.set_links(&links).unwrap();
    world
}

/// (4) Two insulated bodies touching over a face, one at 50 °C and one at 20 °C: heat crosses
/// the links (the near side of the cold body warms first), the total heat content is conserved
/// to round-off every step, and both end at the capacity-weighted mean, 35 °C.
#[test]
fn touching_bodies_equalise_and_conserve_energy() {
    let size = [0.02, 0.01, 0.01];
    let mut world = touching_boxes(size, [4, 2, 2], 500.0, insulated(1.0));
    // The face is 1e-4 m², 0.05 W/K at 500 W/m²/K; the links give more, because a node on the
    // face's rim also stands for the side faces around it (a third of every incident surface
    // triangle): 3 × 5 nodes of the 4 × 2 face grid, 23/12 of the face's conductance in all.
    let g: f64 = world.links().iter().map(|l| l.conductance).sum();
    println!("Σ G = {g} W/K");
    assert!((g - 0.05 * 23.0 / 12.0).abs() < 1e-15, "{g}");
    let hot = vec![50.0; world.bodies()[0].node_count()];
    let cold = vec![20.0; world.bodies()[1].node_count()];
    world.body_mut(0).unwrap().set_temperatures(&hot).unwrap();
    world.body_mut(1).unwrap().set_temperatures(&cold).unwrap();
    let e0 = world.heat_content();
    for _ in 0..20 {
        let r = world.step().unwrap();
        assert!(r.exchanged > 0.0);
        assert!((world.heat_content() - e0).abs() < 1e-12 * e0);
    }
    // After 20 s: the cold body's face nodes (x = 0.02) are warmer than its far end (x = 0.04).
    let b = &world.bodies()[1];
    let mesh_b_x = |i: usize| 0.02 * (i % 5) as f64 / 4.0 + 0.02; // node order: x fastest
    let (mut near, mut far) = (f64::NEG_INFINITY, f64::INFINITY);
    for (i, &t) in b.temperatures().iter().enumerate() {
        let x = mesh_b_x(i);
        if x == 0.02 {
            near = t;
        }
        if x == 0.04 {
            far = far.min(t);
        }
    }
    println!("after 20 s: cold body near face {near:.4} °C, far end {far:.6} °C");
    assert!(near > 20.1 && far < near);

    world.set_dt(100.0).unwrap();
    for _ in 0..600 {
        world.step().unwrap();
        assert!((world.heat_content() - e0).abs() < 1e-12 * e0);
    }
    for body in world.bodies() {
        for &t in body.temperatures() {
            assert!((t - 35.0).abs() < 1e-6, "{t}");
        }
    }
}

/// (5) Burns appear exactly at the nodes whose temperature has ended a step above the
/// coagulation temperature, stay, carry the stiffening factor, and go with a reset.
#[test]
fn burns_mark_exactly_the_nodes_that_crossed_coagulation() {
    let mesh = box_mesh([0.01; 3], [4, 4, 4], |_| false);
    let p = HeatParameters {
        burn_stiffening: 3.0,
        dt: 0.01,
        ..HeatParameters::default()
    };
    let mut body = HeatBody::new(&mesh, p).unwrap();
    let tri = surface_triangle(&mesh, |q| q[1] == 0.01);
    let mut crossed = vec![false; mesh.nodes.len()];
    let mut total = 0;
    // 4 W for 1 s, 3 s of cooling, then 200 s in 1 s steps (the cube evens out at ~38 °C).
    for step in 0..600 {
        if step < 100 {
            body.heat_point(tri, [1.0, 1.0, 1.0], 4.0).unwrap();
        }
        if step == 400 {
            body.set_dt(1.0).unwrap();
        }
        let r = body.step().unwrap();
        let mut new = 0;
        for (i, &t) in body.temperatures().iter().enumerate() {
            if t > 60.0 && !crossed[i] {
                crossed[i] = true;
                new += 1;
            }
        }
        total += new;
        assert_eq!(r.newly_burned, new, "step {step}");
        assert_eq!(body.burned(), &crossed[..], "step {step}");
        assert_eq!(body.burned_count(), total);
        if step == 399 {
            println!(
                "{total} of {} nodes burned; hottest after 3 s of cooling {:.2} °C",
                mesh.nodes.len(),
                body.max_temperature()
            );
        }
    }
    assert!(total >= 3 && total < mesh.nodes.len() / 4);
    // Every node has cooled below 60 °C by now; the burned ones stay burned.
    assert!(body.max_temperature() < 40.0, "{}", body.max_temperature());
    assert_eq!(body.burned_count(), total);
    for (&f, &b) in body.stiffness_factors().iter().zip(body.burned()) {
        assert_eq!(f, if b { 3.0 } else { 1.0 });
    }
    // A field set above coagulation burns too; reset clears everything.
    body.reset();
    assert_eq!(body.burned_count(), 0);
    assert!(body.stiffness_factors().iter().all(|&f| f == 1.0));
    let mut field = vec![37.0; mesh.nodes.len()];
    field[7] = 60.0; // not above
    field[8] = 60.5;
    body.set_temperatures(&field).unwrap();
    assert_eq!(body.burned_count(), 1);
    assert!(body.burned()[8] && !body.burned()[7]);
}

/// (6) After the first step, stepping a world (links replaced every step, a heated point)
/// allocates nothing.
#[test]
fn step_is_allocation_free() {
    assert!(alloc::this_thread(|| drop(std::hint::black_box(vec![0u8; 16]))).allocations >= 1);
    let mut world = touching_boxes(
        [0.02, 0.01, 0.01],
        [4, 2, 2],
        500.0,
        HeatParameters::default(),
    );
    let links: Vec<Link> = world.links().to_vec();
    let liver = shipped("liver");
    let mut liver = HeatBody::new(&liver, HeatParameters::default()).unwrap();
    world.step().unwrap();
    liver.step().unwrap();
    let t0 = [0u32, 1, 5];
    let n = alloc::this_thread(|| {
        for _ in 0..3 {
            world.set_links(&links).unwrap();
            world
                .body_mut(0)
                .unwrap()
                .heat_point(t0, [0.2, 0.3, 0.5], 20.0)
                .unwrap();
            world.step().unwrap();
            liver.heat_node(0, 20.0).unwrap();
            liver.step().unwrap();
        }
    })
    .allocations;
    assert_eq!(n, 0, "allocated {n} times in 3 steps");
}

/// (7) Stability at any time step. On a non-obtuse (Kuhn) mesh a step never leaves the range
/// of the old field and the air temperature, even at Δt = 1e6 s (it jumps to the steady
/// state). On the unstructured liver, with the air off and Δt = 1e6 s, energy is conserved and
/// the capacity-weighted variance never grows; slight over/undershoots near obtuse elements
/// are allowed and measured.
#[test]
fn huge_time_steps_stay_bounded() {
    let mut rng = Rng::new(0x9e37_79b9_7f4a_7c15);
    let mesh = box_mesh([0.02, 0.01, 0.015], [5, 3, 4], |_| false);
    for dt in [1e-3, 1.0, 1e3, 1e6] {
        let mut body = HeatBody::new(
            &mesh,
            HeatParameters {
                dt,
                ..HeatParameters::default()
            },
        )
        .unwrap();
        let field: Vec<f64> = (0..mesh.nodes.len())
            .map(|_| 25.0 + 30.0 * rng.unit())
            .collect();
        body.set_temperatures(&field).unwrap();
        for _ in 0..5 {
            let lo = body.temperatures().iter().copied().fold(22.0, f64::min);
            let hi = body.temperatures().iter().copied().fold(22.0, f64::max);
            body.step().unwrap();
            for &t in body.temperatures() {
                assert!(
                    t >= lo - 1e-9 && t <= hi + 1e-9,
                    "dt {dt}: {t} outside [{lo}, {hi}]"
                );
            }
        }
        if dt == 1e6 {
            for &t in body.temperatures() {
                assert!((t - 22.0).abs() < 1e-6, "{t}");
            }
        }
    }

    let liver = shipped("liver");
    let mut body = HeatBody::new(&liver, insulated(1.0)).unwrap();
    let field: Vec<f64> = (0..liver.nodes.len())
        .map(|_| 25.0 + 30.0 * rng.unit())
        .collect();
    let variance = |b: &HeatBody| {
        let m = mean_temperature(b);
        b.capacities()
            .iter()
            .zip(b.temperatures())
            .map(|(c, t)| c * (t - m) * (t - m))
            .sum::<f64>()
    };
    let (lo, hi) = (
        field.iter().copied().fold(f64::INFINITY, f64::min),
        field.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    );
    let mut worst: f64 = 0.0;
    for dt in [1e-2, 1e-1, 1.0, 10.0, 100.0, 1e3, 1e6] {
        body.set_dt(dt).unwrap();
        body.set_temperatures(&field).unwrap();
        let e0 = body.heat_content();
        let v0 = variance(&body);
        let mut v = v0;
        for _ in 0..5 {
            body.step().unwrap();
            let v1 = variance(&body);
            assert!(v1 <= v + 1e-12 * v0, "dt {dt}: variance grew: {v} -> {v1}");
            v = v1;
            assert!((body.heat_content() - e0).abs() < 1e-10 * e0, "dt {dt}");
            for &t in body.temperatures() {
                worst = worst.max(lo - t).max(t - hi);
            }
        }
    }
    println!(
        "liver, white noise in {lo:.2}..{hi:.2} °C, dt 0.01 s .. 1e6 s: worst excursion beyond \
         the initial range {worst:e} K"
    );
    assert!(worst < 0.05 * (hi - lo));

    // The sharpest test of the maximum principle: one node 30 K above the rest. Near obtuse
    // elements neighbours dip below the base temperature: by 3e-3 K at Δt = 0.01 s, 0.3 K at
    // 1 s and 2 K (7 % of the pulse) at 100 s; at 1e6 s the step lands on the uniform mean.
    let mut body = HeatBody::new(&liver, insulated(1.0)).unwrap();
    for (dt, bound) in [(1e-2, 0.01), (1.0, 0.5), (100.0, 3.0), (1e6, 1e-9)] {
        let mut worst: f64 = 0.0;
        body.set_dt(dt).unwrap();
        for hot in (0..liver.nodes.len()).step_by(5) {
            let mut field = vec![37.0; liver.nodes.len()];
            field[hot] = 67.0;
            body.set_temperatures(&field).unwrap();
            for _ in 0..3 {
                body.step().unwrap();
                for &t in body.temperatures() {
                    worst = worst.max(37.0 - t).max(t - 67.0);
                }
            }
        }
        println!(
            "liver, 30 K pulse at one node, dt {dt} s: worst excursion beyond 37..67 °C \
             {worst:.3e} K"
        );
        assert!(worst < bound, "dt {dt}: {worst} K");
    }
}

/// The same inputs give the same field, bit for bit (and a clone steps like its original).
#[test]
fn stepping_is_deterministic() {
    let run = || {
        let mut world = touching_boxes(
            [0.02, 0.01, 0.01],
            [4, 2, 2],
            500.0,
            HeatParameters::default(),
        );
        for k in 0..50 {
            let b = world.body_mut(k % 2).unwrap();
            b.heat_point([0, 1, 5], [0.1, 0.2, 0.7], 10.0).unwrap();
            world.step().unwrap();
        }
        world
    };
    let (a, b) = (run(), run());
    let mut c = a.clone();
    let mut a = a;
    a.step().unwrap();
    c.step().unwrap();
    for k in 0..2 {
        let bits = |w: &HeatWorld| -> Vec<u64> {
            w.bodies()[k]
                .temperatures()
                .iter()
                .map(|t| t.to_bits())
                .collect()
        };
        assert_eq!(bits(&a), bits(&c));
        assert_ne!(bits(&a), bits(&b)); // one more step
    }
    let mut b = b;
    b.step().unwrap();
    for k in 0..2 {
        assert_eq!(a.bodies()[k].temperatures(), b.bodies()[k].temperatures());
        assert_eq!(a.bodies()[k].burned(), b.bodies()[k].burned());
    }
}

/// Bad input gives an error naming the value, and changes nothing.
#[test]
fn bad_input_is_rejected_without_side_effects() {
    let mesh = box_mesh([0.01; 3], [2, 2, 2], |_| false);
    for (name, p) in [
        (
            "conductivity",
            HeatParameters {
                conductivity: f64::NAN,
                ..Default::default()
            },
        ),
        (
            "specific_heat",
            HeatParameters {
                specific_heat: 0.0,
                ..Default::default()
            },
        ),
        (
            "density",
            HeatParameters {
                density: -1.0,
                ..Default::default()
            },
        ),
        (
            "initial",
            HeatParameters {
                initial: -300.0,
                ..Default::default()
            },
        ),
        (
            "coagulation",
            HeatParameters {
                coagulation: 30.0,
                ..Default::default()
            },
        ),
        (
            "burn_stiffening",
            HeatParameters {
                burn_stiffening: 0.0,
                ..Default::default()
            },
        ),
        (
            "air_temperature",
            HeatParameters {
                air_temperature: f64::INFINITY,
                ..Default::default()
            },
        ),
        (
            "air_coefficient",
            HeatParameters {
                air_coefficient: -1.0,
                ..Default::default()
            },
        ),
        (
            "dt",
            HeatParameters {
                dt: 0.0,
                ..Default::default()
            },
        ),
    ] {
        match HeatBody::new(&mesh, p) {
            Err(HeatError::InvalidParameter { name: n, .. }) => assert_eq!(n, name),
            other => panic!("{name}: {other:?}"),
        }
    }
    let mut body = HeatBody::new(&mesh, HeatParameters::default()).unwrap();
    let n = body.node_count() as u32;
    assert!(matches!(
        body.heat_point([0, 1, n], [1.0, 0.0, 0.0], 1.0),
        Err(HeatError::NodeOutOfRange { .. })
    ));
    assert!(matches!(
        body.heat_point([0, 1, 2], [0.5, -0.1, 0.6], 1.0),
        Err(HeatError::InvalidWeights { .. })
    ));
    assert!(matches!(
        body.heat_point([0, 1, 2], [0.0; 3], 1.0),
        Err(HeatError::InvalidWeights { .. })
    ));
    assert!(body.heat_node(0, f64::NAN).is_err());
    assert!(body.heat_node(0, -5.0).is_err());
    assert!(matches!(
        body.set_temperatures(&[37.0; 3]),
        Err(HeatError::WrongLength { got: 3, .. })
    ));
    let mut field = vec![37.0; n as usize];
    field[4] = f64::NAN;
    assert!(matches!(
        body.set_temperatures(&field),
        Err(HeatError::InvalidTemperature { node: 4, .. })
    ));
    assert!(body.set_dt(-1.0).is_err());
    assert_eq!(body.dt(), 0.01);
    // Nothing was queued or changed by the failed calls.
    let r = body.step().unwrap();
    assert_eq!(r.injected, 0.0);

    // A node that no tetrahedron uses cannot be heated or linked.
    let mut nodes = mesh.nodes.clone();
    nodes.push([1.0, 1.0, 1.0]);
    let loose = TetMesh::from_parts(nodes, mesh.tets.clone(), vec![], "loose".into()).unwrap();
    let mut lb = HeatBody::new(&loose, HeatParameters::default()).unwrap();
    assert!(matches!(
        lb.heat_node(n, 1.0),
        Err(HeatError::NoCapacity { .. })
    ));
    lb.step().unwrap();
    assert_eq!(lb.temperatures()[n as usize], 37.0);

    // Worlds: one time step, links to existing nodes, no self links, finite conductance.
    let a = HeatBody::new(&mesh, HeatParameters::default()).unwrap();
    let b = HeatBody::new(
        &mesh,
        HeatParameters {
            dt: 0.02,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(matches!(
        HeatWorld::new(vec![a.clone(), b]),
        Err(HeatError::TimeStepMismatch { body: 1, .. })
    ));
    let mut world = HeatWorld::new(vec![a.clone(), a]).unwrap();
    let link = |body_b, node_b, conductance| Link {
        body_a: 0,
        node_a: 0,
        body_b,
        node_b,
        conductance,
    };
    world.set_links(&[link(1, 0, 0.1)]).unwrap();
    for (bad, what) in [
        (link(2, 0, 0.1), "body"),
        (link(1, n, 0.1), "node"),
        (link(0, 0, 0.1), "self"),
        (link(1, 0, f64::NAN), "conductance"),
    ] {
        let err = world.set_links(&[bad]).unwrap_err();
        println!("{what}: {err}");
        assert_eq!(world.links(), &[link(1, 0, 0.1)], "{what}");
    }
}
