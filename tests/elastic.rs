//! Physical checks of the two elasticity models (Debunne meshfree FEM and point based
//! animation) against linear elasticity theory.

mod common;

use common::*;
use needlesim::core::models::{mls, point_based};
use needlesim::core::scene::lame;
use needlesim::{Backend, CpuBackend, NodeField, Scene, Threading, Tissue};
use std::path::Path;

const E: f64 = 10e3;
const NU: f64 = 0.3;

fn bar_scene(material: &str, dt: f64, damping: f64) -> Scene {
    let text = format!(
        "[tissue]\ngeometry = {{ kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.3, 0.1, 0.1], spacing = 0.0125 }}\n\
         [material]\n{material}\n[physics]\ndt = {dt}\ndamping = {damping}\n\
         [[fixed]]\naxis = \"x\"\nbelow = 0.001\n[[fixed]]\naxis = \"x\"\nabove = 0.299\n"
    );
    Scene::from_toml_str(&text, Path::new(".")).unwrap()
}

fn deb(corotated: bool) -> String {
    format!("model = \"debunne_meshfree\"\nyoung_modulus = {E}\npoisson_ratio = {NU}\ncorotated = {corotated}")
}
fn pba() -> String {
    format!(
        "model = \"point_based\"\nyoung_modulus = {E}\npoisson_ratio = {NU}\nhourglass = {}",
        std::env::var("HG").unwrap_or("0.1".into())
    )
}

/// Clamped bar stretched by `eps`: returns (reaction stress on the +x clamp / (E eps),
/// mid-section lateral strain / (-nu eps), mid interior sigma_xx / (E eps)).
fn stretched_bar(material: &str, eps: f64) -> (f64, f64, f64) {
    let scene = bar_scene(material, 2e-4, 30.0);
    let rest = rest_positions(&scene);
    let mut b = backend(&scene, Threading::Parallel);
    let n = b.n_active();
    let mut x = read(&mut b, NodeField::Position);
    for (p, r) in x.iter_mut().zip(&rest) {
        p[0] = (r[0] * (1.0 + eps)) as f32;
    }
    b.write(NodeField::Position, 0, &x).unwrap();
    for _ in 0..std::env::var("STEPS_X100")
        .map(|s| s.parse().unwrap())
        .unwrap_or(30)
    {
        b.step(100);
        b.check_finite().unwrap();
    }
    b.compute_forces();
    let f = read(&mut b, NodeField::Force);
    let x = read(&mut b, NodeField::Position);
    let reaction: f64 = (0..n)
        .filter(|&i| rest[i][0] >= 0.299)
        .map(|i| f[i][0] as f64)
        .sum();
    let stress = -reaction / (0.1 * 0.1);
    let mid: Vec<usize> = (0..n)
        .filter(|&i| (rest[i][0] - 0.15).abs() < 0.001)
        .collect();
    let width = |p: &dyn Fn(usize) -> f64| {
        let (lo, hi) = mid.iter().fold((f64::MAX, f64::MIN), |(a, b), &i| {
            (a.min(p(i)), b.max(p(i)))
        });
        hi - lo
    };
    let w0 = width(&|i| rest[i][1]);
    let w = width(&|i| x[i][1] as f64);
    let lateral = (w - w0) / w0;
    // Interior stress at the mid-section from the MLS gradient of the positions.
    let t = Tissue::from_scene(&scene).unwrap();
    let rest4: Vec<[f32; 4]> = rest
        .iter()
        .map(|p| [p[0] as f32, p[1] as f32, p[2] as f32, 0.0])
        .collect();
    let (lambda, mu) = lame(E, NU);
    let centre = mid
        .iter()
        .copied()
        .min_by(|&a, &c| {
            let d = |i: usize| (rest[i][1] - 0.05).powi(2) + (rest[i][2] - 0.05).powi(2);
            d(a).partial_cmp(&d(c)).unwrap()
        })
        .unwrap();
    let ainv = mls::inverse_moment(centre, &rest4, &t.neighbours);
    let (j, _) = mls::displacement_gradient(centre, &x, &rest4, &t.neighbours, &ainv);
    let s = point_based::green_stress(&j, lambda as f32, mu as f32);
    (
        stress / (E * eps),
        lateral / (-NU * eps),
        s[0][0] as f64 / (E * eps),
    )
}

#[test]
fn explore() {
    for (name, m) in [("deb", deb(false)), ("pba", pba())] {
        let r = stretched_bar(&m, 1e-3);
        println!("{name}: {r:?}");
    }
}

#[test]
fn explore_growth() {
    for (name, m) in [("deb", deb(false)), ("pba", pba())] {
        let scene = bar_scene(&m, 2e-4, 30.0);
        let mut b = backend(&scene, Threading::Parallel);
        let mut x = read(&mut b, NodeField::Position);
        let mut s = 12345u64;
        for p in x.iter_mut() {
            for a in 0..3 {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                if p[3] > 0.0 {
                    p[a] += ((s >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 1e-5;
                }
            }
        }
        b.write(NodeField::Position, 0, &x).unwrap();
        for it in 0..8 {
            b.step(1000);
            let x1 = read(&mut b, NodeField::Position);
            let rest = rest_positions(&scene);
            let mut maxd: f64 = 0.0;
            let mut arg = 0;
            for (i, (p, r)) in x1.iter().zip(&rest).enumerate() {
                let d = ((p[0] as f64 - r[0]).powi(2)
                    + (p[1] as f64 - r[1]).powi(2)
                    + (p[2] as f64 - r[2]).powi(2))
                .sqrt();
                if d > maxd {
                    maxd = d;
                    arg = i;
                }
            }
            println!(
                "{name} {it}: max disp {maxd:.3e} at {arg} rest {:?}",
                rest[arg]
            );
        }
    }
}

#[test]
fn explore_patch_forces() {
    for (name, m) in [("deb", deb(false)), ("pba", pba())] {
        let scene = bar_scene(&m, 2e-4, 30.0);
        let rest = rest_positions(&scene);
        let mut b = backend(&scene, Threading::Parallel);
        let eps = 1e-3;
        let x: Vec<[f32; 4]> = rest
            .iter()
            .map(|r| {
                [
                    (r[0] * (1.0 + eps)) as f32,
                    (r[1] - 0.05 * 0.0 - NU * eps * (r[1] - 0.05)) as f32,
                    (r[2] - NU * eps * (r[2] - 0.05)) as f32,
                    1.0,
                ]
            })
            .collect();
        b.write(NodeField::Position, 0, &x).unwrap();
        b.compute_forces();
        let f = read(&mut b, NodeField::Force);
        let fscale = E * eps * 0.0125 * 0.0125;
        let mut worst = (0.0, 0);
        for i in 0..rest.len() {
            let r = rest[i];
            let interior = (0..3).all(|a| r[a] > 0.02 && r[a] < [0.3, 0.1, 0.1][a] - 0.02);
            let fn_ = norm3(f[i]) / fscale;
            if interior && fn_ > worst.0 {
                worst = (fn_, i);
            }
        }
        let lateral: f64 = (0..rest.len())
            .filter(|&i| rest[i][1] > 0.0999 && rest[i][0] > 0.02 && rest[i][0] < 0.28)
            .map(|i| norm3(f[i]) / fscale)
            .fold(0.0, f64::max);
        let reaction: f64 = (0..rest.len())
            .filter(|&i| rest[i][0] >= 0.299)
            .map(|i| f[i][0] as f64)
            .sum::<f64>()
            / (-E * eps * 0.01);
        println!("{name}: worst interior {:?} rest {:?}, lateral face max {lateral}, reaction {reaction}", worst, rest[worst.1]);
    }
}

#[test]
fn explore_row() {
    let scene = bar_scene(&pba(), 2e-4, 30.0);
    let rest = rest_positions(&scene);
    let t = Tissue::from_scene(&scene).unwrap();
    let (idx, w) = t.neighbours.row(513);
    let mut m = [0.0; 3];
    for s in 0..16 {
        let d: Vec<f64> = (0..3)
            .map(|a| ((rest[idx[s] as usize][a] - rest[513][a]) / 0.0125).round())
            .collect();
        println!("{:?} {}", d, w[s]);
        for a in 0..3 {
            m[a] += w[s] as f64 * d[a];
        }
    }
    println!("m = {m:?}");
}
