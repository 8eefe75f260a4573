//! The neo-Hookean model against the exact homogeneous solution of a free uniaxial
//! stretch and compression, and against the linear models at small strain.
//!
//! A cube of 13^3 = 2197 nodes is held between two frictionless plates (the end nodes'
//! axial coordinate fixed, the lateral ones free) at a stretch `s` of 0.6, 0.8, 1.2 and
//! 1.4, and relaxed from a lateral stretch of 1 to equilibrium. The lateral faces are free,
//! so the exact state is homogeneous, `F = diag(s, t, t)` with the lateral stretch `t` the
//! root of `P_22 = mu (t - 1/t) + lambda ln(s t^2) / t = 0`, and the nominal stress is
//! `P_11 = mu (s - 1/s) + lambda ln(s t^2) / s` (the law of `models::neo_hookean`). The
//! model's stress is the plate's reaction force over the reference cross-section, its
//! lateral stretch the least-squares slope of the lateral coordinates against the rest
//! ones.

mod common;

use needlesim::core::models::neo_hookean::NeoHookeanParams;
use needlesim::core::scene::lame;
use needlesim::{Backend, CpuBackend, Material, NodeField, Scene, Threading, Tissue};

/// Side of the cube, m.
const SIDE: f64 = 0.012;
/// Nodes per edge.
const NODES: usize = 13;
const YOUNG: f64 = 3000.0;
const POISSON: f64 = 0.4;

/// The exact lateral stretch and nominal stress (Pa) at axial stretch `s`.
fn exact(s: f64) -> (f64, f64) {
    let (lambda, mu) = lame(YOUNG, POISSON);
    // mu (t^2 - 1) + lambda ln(s t^2) is increasing in t: bisection.
    let g = |t: f64| mu * (t * t - 1.0) + lambda * (s * t * t).ln();
    let (mut lo, mut hi) = (0.1f64, 3.0f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if g(mid) > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    let t = 0.5 * (lo + hi);
    (t, mu * (s - 1.0 / s) + lambda * (s * t * t).ln() / s)
}

fn scene(material: Material) -> Scene {
    Scene::builder()
        .box_with_nodes([0.0; 3], [SIDE; 3], NODES * NODES * NODES)
        .material(material)
        .dt_auto()
        .build()
        .expect("valid scene")
}

/// The plate's nominal stress (Pa) and the lateral stretch after relaxing `material` at
/// axial stretch `s`, and the largest speed left (m/s).
fn uniaxial(material: Material, s: f64) -> (f64, f64, f64) {
    let sc = scene(material);
    let tissue = Tissue::from_scene(&sc).unwrap();
    let dt = tissue.step.dt as f64;
    let rest = common::rest_positions(&sc);
    let n = rest.len();
    assert_eq!(n, NODES * NODES * NODES);
    let h = SIDE / (NODES - 1) as f64;
    let mut b = CpuBackend::new(tissue, Threading::Parallel).unwrap();
    let mut pos = common::read(&mut b, NodeField::Position);
    for (p, r) in pos.iter_mut().zip(&rest) {
        p[0] = (r[0] * s) as f32;
    }
    b.write(NodeField::Position, 0, &pos).unwrap();
    let plate: Vec<(usize, f32)> = (0..n)
        .filter(|&i| rest[i][0] < 0.25 * h || rest[i][0] > SIDE - 0.25 * h)
        .map(|i| (i, (rest[i][0] * s) as f32))
        .collect();
    let top: Vec<u32> = plate
        .iter()
        .filter(|(_, x)| *x > 0.0)
        .map(|(i, _)| *i as u32)
        .collect();
    // Velocity damping near critical for the slowest lateral mode (a quarter wave across
    // the cube), applied as v *= 1 - c dt after each step.
    let (lambda, mu) = lame(YOUNG, POISSON);
    let c_p = ((lambda + 2.0 * mu) / 1000.0).sqrt();
    let omega = std::f64::consts::PI * c_p / SIDE;
    let keep = (1.0 - 2.0 * omega * dt).max(0.0) as f32;
    let steps = (40.0 / omega / dt).ceil() as usize;
    let mut vel = vec![[0.0f32; 4]; n];
    for _ in 0..steps {
        b.step(1);
        b.read(NodeField::Position, 0..n, &mut pos).unwrap();
        b.read(NodeField::Velocity, 0..n, &mut vel).unwrap();
        for v in vel.iter_mut() {
            v.iter_mut().take(3).for_each(|c| *c *= keep);
        }
        for &(i, x) in &plate {
            pos[i][0] = x;
            vel[i][0] = 0.0;
        }
        b.write(NodeField::Position, 0, &pos).unwrap();
        b.write(NodeField::Velocity, 0, &vel).unwrap();
    }
    let speed = common::max_norm(&vel);
    b.compute_forces();
    let mut f = vec![[0.0f32; 4]; top.len()];
    b.read_nodes(NodeField::Force, &top, &mut f).unwrap();
    // The plate pulls the body with minus the body's internal force on its nodes.
    let stress = -f.iter().map(|f| f[0] as f64).sum::<f64>() / (SIDE * SIDE);
    // Lateral stretch: slope of y and z against their rest values.
    let slope = |a: usize| {
        let m0 = rest.iter().map(|r| r[a]).sum::<f64>() / n as f64;
        let m = pos.iter().map(|p| p[a] as f64).sum::<f64>() / n as f64;
        let (mut sxy, mut sxx) = (0.0, 0.0);
        for (p, r) in pos.iter().zip(&rest) {
            sxy += (r[a] - m0) * (p[a] as f64 - m);
            sxx += (r[a] - m0) * (r[a] - m0);
        }
        sxy / sxx
    };
    (stress, 0.5 * (slope(1) + slope(2)), speed)
}

/// Uniaxial stretch and compression to 20% and 40% at 2197 nodes: the nominal stress and
/// the lateral stretch within 1% of the exact neo-Hookean values. Measured (dev machine,
/// K = 18): see the assertion messages (`cargo test --test neo_hookean -- --nocapture`).
#[test]
fn uniaxial_stretch_and_compression_match_the_exact_solution() {
    let material = Material::NeoHookean(NeoHookeanParams::new(YOUNG, POISSON));
    for s in [0.6, 0.8, 1.2, 1.4] {
        let (t, p) = exact(s);
        let (stress, lateral, speed) = uniaxial(material, s);
        let (e_p, e_t) = (stress / p - 1.0, (lateral - 1.0) / (t - 1.0) - 1.0);
        eprintln!(
            "stretch {s}: stress {stress:.2} Pa vs exact {p:.2} ({:+.3}%), lateral stretch \
             {lateral:.5} vs {t:.5} (contraction {:+.3}%), speed left {speed:.1e} m/s",
            100.0 * e_p,
            100.0 * e_t
        );
        assert!(e_p.abs() < 0.01, "stretch {s}: stress error {e_p}");
        assert!(
            (lateral / t - 1.0).abs() < 0.01,
            "stretch {s}: lateral stretch {lateral} vs {t}"
        );
        assert!(speed < 1e-4, "stretch {s}: not settled, speed {speed}");
    }
}

/// At 0.2% stretch the neo-Hookean plate stress is within 0.5% of that of the linear
/// Debunne model with the same E and nu (their laws differ by O(strain) = 0.2%, the
/// discretisation is the same).
#[test]
fn small_strain_matches_the_linear_model() {
    let s = 1.002;
    let (nh, nh_lateral, _) = uniaxial(
        Material::NeoHookean(NeoHookeanParams::new(YOUNG, POISSON)),
        s,
    );
    let (deb, deb_lateral, _) = uniaxial(Material::debunne(YOUNG, POISSON), s);
    eprintln!("0.2%: neo-Hookean {nh:.4} Pa, Debunne {deb:.4} Pa; lateral {nh_lateral:.7} vs {deb_lateral:.7}");
    assert!((nh / deb - 1.0).abs() < 0.005, "{nh} vs {deb}");
    assert!(
        ((nh_lateral - 1.0) / (deb_lateral - 1.0) - 1.0).abs() < 0.01,
        "{nh_lateral} vs {deb_lateral}"
    );
}
