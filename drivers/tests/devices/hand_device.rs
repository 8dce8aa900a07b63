//! The simulated hand against references it was not tuned to: the exact solution of the same
//! linear ODE (matrix exponential, computed here independently of the device's integrator), the
//! statics of two springs in series, and conservation of energy with the damping removed; plus
//! determinism, refused forces and the device lifecycle.

use std::path::Path;

use lop_drivers::hand::{HandDevice, HandParameters};
use lop_drivers::mock::{MockDevice, MockScript};
use lop_drivers::{DeviceError, HapticDevice, Pacing};

/// Where the intent holds still, mm.
const INTENT_MM: [f64; 3] = [5.0, 10.0, -3.0];

fn linear(params: HandParameters) -> HandParameters {
    HandParameters {
        stylus_friction: 0.0,
        ..params
    }
}

fn device(params: HandParameters, start_mm: [f64; 3]) -> HandDevice {
    let script = MockScript::stationary(INTENT_MM);
    let mut d = HandDevice::with_parameters(script, params, MockDevice::omni_limits())
        .unwrap()
        .starting_at(start_mm);
    d.start().unwrap();
    d
}

type Mat4 = [[f64; 4]; 4];

fn mat_mul(a: &Mat4, b: &Mat4) -> Mat4 {
    let mut c = [[0.0; 4]; 4];
    for i in 0..4 {
        for j in 0..4 {
            c[i][j] = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

/// `exp(A t)` by scaling and squaring with a 30-term Taylor series: exact to rounding for the
/// small matrices here, and nothing like the device's Runge–Kutta stepping.
fn expm(a: &Mat4, t: f64) -> Mat4 {
    let norm: f64 = a
        .iter()
        .map(|row| row.iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max)
        * t;
    let squarings = (norm / 0.25).log2().ceil().max(0.0) as i32;
    let scale = t / 2f64.powi(squarings);
    let mut result = [[0.0; 4]; 4];
    let mut term = [[0.0; 4]; 4];
    for i in 0..4 {
        result[i][i] = 1.0;
        term[i][i] = 1.0;
    }
    let scaled = a.map(|row| row.map(|v| v * scale));
    for n in 1..30 {
        term = mat_mul(&term, &scaled).map(|row| row.map(|v| v / n as f64));
        for i in 0..4 {
            for j in 0..4 {
                result[i][j] += term[i][j];
            }
        }
    }
    for _ in 0..squarings {
        result = mat_mul(&result, &result);
    }
    result
}

/// The model's matrix on one axis, friction-free, in the coordinates (stylus position, stylus
/// velocity, hand position, hand velocity) measured from the (constant) intent.
fn system_matrix(p: &HandParameters) -> Mat4 {
    let (ms, mh) = (p.stylus_mass, p.hand_mass);
    let (bs, kg, bg) = (p.stylus_damping, p.grip_stiffness, p.grip_damping);
    let (kh, bh) = (p.hand_stiffness, p.hand_damping);
    [
        [0.0, 1.0, 0.0, 0.0],
        [-kg / ms, -(bs + bg) / ms, kg / ms, bg / ms],
        [0.0, 0.0, 0.0, 1.0],
        [kg / mh, bg / mh, -(kh + kg) / mh, -(bh + bg) / mh],
    ]
}

#[test]
fn step_in_the_intent_follows_the_exact_linear_solution() {
    for (label, params) in [
        ("default grip", linear(HandParameters::default())),
        (
            "light grip",
            linear(HandParameters {
                hand_mass: 0.1,
                hand_stiffness: 100.0,
                hand_damping: 1.0,
                grip_damping: 0.5,
                ..HandParameters::default()
            }),
        ),
    ] {
        // Start 10 mm below the intent on y (and off on x, z): a step of the intent at t = 0.
        let start = [0.0, 0.0, 0.0];
        let mut d = device(params, start);
        let a = system_matrix(&params);
        let mut worst = 0.0f64;
        for tick in 1..=1000 {
            let t = tick as f64 * 1e-3;
            let sample = d.read(t).unwrap();
            d.write_force([0.0; 3]).unwrap();
            let e = expm(&a, t);
            for k in 0..3 {
                let e0 = start[k] - INTENT_MM[k];
                // Both masses start at rest at `start`: error state (e0, 0, e0, 0).
                let x = INTENT_MM[k] + (e[0][0] + e[0][2]) * e0;
                let v = (e[1][0] + e[1][2]) * e0;
                worst = worst.max((sample.position_mm[k] - x).abs());
                worst = worst.max((sample.velocity_mm_s[k] - v).abs() * 1e-3);
            }
        }
        println!("{label}: worst deviation from the exact solution over 1 s: {worst:.3e} mm");
        // Classical RK4 at 0.1 ms: the global error is about (ω h)⁴ / 120 per radian of
        // motion times the mode's amplitude; for the grip mode (ω ≈ 230 rad/s, ω h ≈ 0.023,
        // 230 rad in 1 s, amplitude under 1 mm) that is ~ 5e-8 mm, the slow mode far less.
        assert!(worst < 1e-7, "{label}: {worst:e} mm");

        // Steady state: the stylus reaches the intent, at rest.
        let mut sample = d.read(1.0).unwrap();
        for tick in 1001..=20_000 {
            sample = d.read(tick as f64 * 1e-3).unwrap();
        }
        for (k, intent) in INTENT_MM.iter().enumerate() {
            assert!(
                (sample.position_mm[k] - intent).abs() < 1e-9,
                "{label}: {sample:?}"
            );
            assert!(sample.velocity_mm_s[k].abs() < 1e-9, "{label}: {sample:?}");
        }
    }
}

#[test]
fn with_friction_the_stylus_still_settles_on_the_intent() {
    let mut d = device(HandParameters::default(), [0.0, 0.0, 0.0]);
    let mut sample = d.read(0.0).unwrap();
    for tick in 1..=10_000 {
        sample = d.read(tick as f64 * 1e-3).unwrap();
        d.write_force([0.0; 3]).unwrap();
    }
    for (position, intent) in sample.position_mm.iter().zip(INTENT_MM) {
        assert!((position - intent).abs() < 1e-9, "{sample:?}");
    }
}

#[test]
fn a_constant_force_deflects_the_stylus_by_the_series_compliance() {
    let params = HandParameters::default();
    let force = [0.3, -0.5, 0.2]; // N
    let mut d = device(params, INTENT_MM);
    let mut sample = d.read(0.0).unwrap();
    for tick in 1..=10_000 {
        d.write_force(force).unwrap();
        sample = d.read(tick as f64 * 1e-3).unwrap();
    }
    let (hand, _) = d.hand_state();
    let compliance_mm_per_n = 1e3 * (1.0 / params.hand_stiffness + 1.0 / params.grip_stiffness);
    for k in 0..3 {
        let expected = INTENT_MM[k] + force[k] * compliance_mm_per_n;
        assert!(
            (sample.position_mm[k] - expected).abs() < 1e-9,
            "axis {k}: {} vs {expected}",
            sample.position_mm[k]
        );
        let hand_expected = INTENT_MM[k] + force[k] * 1e3 / params.hand_stiffness;
        assert!((hand[k] - hand_expected).abs() < 1e-9, "hand axis {k}");
    }
    println!(
        "0.5 N on y deflects the stylus {:.6} mm (F (1/k_h + 1/k_g) = {:.6} mm)",
        sample.position_mm[1] - INTENT_MM[1],
        -0.5 * compliance_mm_per_n
    );
}

#[test]
fn without_damping_energy_is_conserved() {
    let p = HandParameters {
        stylus_damping: 0.0,
        stylus_friction: 0.0,
        hand_damping: 0.0,
        grip_damping: 0.0,
        ..HandParameters::default()
    };
    // Stylus and hand 8 mm off the intent on y, 3 mm on x: the arm spring is loaded.
    let mut d = device(p, [2.0, 2.0, -3.0]);
    let energy = |d: &HandDevice, sample: &lop_drivers::DeviceSample| {
        let (hand_x, hand_v) = d.hand_state();
        (0..3)
            .map(|k| {
                let (xs, vs) = (sample.position_mm[k] * 1e-3, sample.velocity_mm_s[k] * 1e-3);
                let (xh, vh) = (hand_x[k] * 1e-3, hand_v[k] * 1e-3);
                let xi = INTENT_MM[k] * 1e-3;
                0.5 * p.stylus_mass * vs * vs
                    + 0.5 * p.hand_mass * vh * vh
                    + 0.5 * p.hand_stiffness * (xh - xi) * (xh - xi)
                    + 0.5 * p.grip_stiffness * (xh - xs) * (xh - xs)
            })
            .sum::<f64>()
    };
    let first = d.read(0.0).unwrap();
    let e0 = energy(&d, &first);
    let mut worst = 0.0f64;
    let mut max_stylus_speed = 0.0f64;
    for tick in 1..=1000 {
        let sample = d.read(tick as f64 * 1e-3).unwrap();
        d.write_force([0.0; 3]).unwrap();
        worst = worst.max((energy(&d, &sample) - e0).abs() / e0);
        max_stylus_speed = max_stylus_speed.max(sample.velocity_mm_s[1].abs());
    }
    println!("energy {e0:.6e} J, worst relative drift over 1 s {worst:.3e}");
    assert!(max_stylus_speed > 10.0, "the system did move");
    // RK4's energy error per step is ~ (ω h)⁶ for the fastest mode (ω h ≈ 0.023): ~1e-10
    // over 10,000 steps at most.
    assert!(worst < 1e-8, "{worst:e}");
}

fn poke_script() -> MockScript {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config/scripts/abdomen-poke.toml");
    MockScript::load(&path).unwrap()
}

/// A closed loop against a wall at z = 24 mm (0.5 N/mm), with irregular read times; every
/// sample.
fn closed_loop_run() -> Vec<[f64; 7]> {
    let mut d = HandDevice::new(poke_script(), MockDevice::omni_limits());
    d.start().unwrap();
    let mut out = Vec::new();
    let mut t = 0.0;
    for tick in 0..5000u64 {
        t += 1e-3 * (0.9 + 0.2 * ((tick * 7919) % 11) as f64 / 10.0);
        let s = d.read(t).unwrap();
        let depth = (24.0 - s.position_mm[2]).max(0.0);
        d.write_force([0.0, 0.0, (0.5 * depth).min(3.3)]).unwrap();
        out.push([
            s.position_mm[0],
            s.position_mm[1],
            s.position_mm[2],
            s.velocity_mm_s[0],
            s.velocity_mm_s[1],
            s.velocity_mm_s[2],
            s.buttons as f64,
        ]);
    }
    d.stop();
    out
}

#[test]
fn same_reads_and_writes_give_bit_identical_samples() {
    let (a, b) = (closed_loop_run(), closed_loop_run());
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.map(f64::to_bits), y.map(f64::to_bits));
    }
    // The wall held the stylus short of the intent (which goes to z = 21.18 mm).
    let deepest = a.iter().map(|s| s[2]).fold(f64::INFINITY, f64::min);
    println!("deepest stylus z against the wall: {deepest:.3} mm (intent 21.18 mm)");
    assert!(deepest > 21.5 && deepest < 24.0, "{deepest}");
}

#[test]
fn refused_forces_render_zero_and_are_counted() {
    let mut d = HandDevice::new(poke_script(), MockDevice::omni_limits());
    assert_eq!(d.pacing(), Pacing::SelfPaced);
    assert_eq!(d.name(), "hand (abdomen: poke)");
    assert_eq!(d.read(0.0), Err(DeviceError::NotStarted));
    d.start().unwrap();
    d.read(0.001).unwrap();
    d.write_force([0.0, 1.0, 0.0]).unwrap();
    assert_eq!(d.last_force(), [0.0, 1.0, 0.0]);
    for (bad, error) in [
        ([f64::NAN, 0.0, 0.0], DeviceError::NonFiniteForce),
        ([0.0, f64::INFINITY, 0.0], DeviceError::NonFiniteForce),
        ([0.0, 0.0, 4.0], DeviceError::ForceLimitExceeded),
    ] {
        assert_eq!(d.write_force(bad), Err(error));
        assert_eq!(d.last_force(), [0.0; 3]);
    }
    assert_eq!(d.rejected_forces(), 3);
    // Exactly the peak is fine.
    d.write_force([0.0, 3.3, 0.0]).unwrap();
    assert_eq!(d.rejected_forces(), 3);
    d.stop();
    assert!(d.stopped());
    assert_eq!(d.force_record().last(), Some((0.001, [0.0; 3])));
    assert_eq!(d.force_record().total_writes(), 6);
    assert_eq!(d.read(0.002), Err(DeviceError::Stopped));
    assert_eq!(d.write_force([0.0; 3]), Err(DeviceError::Stopped));
}

#[test]
fn time_that_does_not_advance_leaves_the_state_alone() {
    let mut d = device(HandParameters::default(), [0.0; 3]);
    let s1 = d.read(0.5).unwrap();
    for t in [0.4, 0.5, f64::NAN, f64::NEG_INFINITY, f64::INFINITY] {
        let s = d.read(t).unwrap();
        assert_eq!(s.position_mm, s1.position_mm, "t = {t}");
    }
    // A huge jump catches up at most one second: still finite, and settled.
    let s = d.read(1e12).unwrap();
    assert!(s.is_finite());
}

#[test]
fn a_sample_fault_breaks_the_report_not_the_stylus() {
    let text = "[[waypoint]]\nt = 0.0\nposition = [5.0, 10.0, -3.0]\n\
                [[fault]]\nfrom = 0.1\nuntil = 0.2\nsample = \"nan\"\n";
    let script = MockScript::parse(text, Path::new("hand-sample-fault.toml")).unwrap();
    let run = |script: MockScript| {
        let mut d = HandDevice::new(script, MockDevice::omni_limits());
        d.start().unwrap();
        (1..=300)
            .map(|i| d.read(i as f64 * 1e-3).unwrap())
            .collect::<Vec<_>>()
    };
    let broken = run(script);
    let clean = run(MockScript::stationary(INTENT_MM));
    for (i, (b, c)) in broken.iter().zip(&clean).enumerate() {
        let t = (i + 1) as f64 * 1e-3;
        if (0.1..0.2).contains(&t) {
            assert!(b.position_mm.iter().all(|v| v.is_nan()), "t = {t}: {b:?}");
        } else {
            // The stylus moved on as if nothing happened.
            assert_eq!(b, c, "t = {t}");
        }
    }
}
