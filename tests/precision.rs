//! Displacements below f32 resolution (issue 41, item 2): the integrator's compensated
//! position sum (`needlesim::core::integrator`) against loads so small, and a body so far
//! from the origin, that a plain `x + dt v` drops the increments.
//!
//! The setting that froze the plain sum on the dev machine: a 10 cm cube clamped on one
//! face, dt 1e-4 s, damping 60/s. At 0.01% of gravity its free end reached 1.4% of the
//! sag linear scaling predicts; translated 1 m from the origin it did not move at 0.1%.

mod common;

use common::*;
use needlesim::core::scene::{Axis, NodeSet};
use needlesim::gpu::{GpuBackend, GpuError};
use needlesim::{Backend, Material, NodeField, Scene, Tissue};

const DT: f64 = 1e-4;
const DAMPING: f64 = 60.0;
/// 1 s: the slowest mode of every model's cube has decayed by more than e^-15 (the
/// results change by less than 1e-5 relative between 1 and 2 s).
const STEPS: u64 = 10_000;

fn cube(material: Material, gravity: f64, shift: f64) -> Scene {
    Scene::builder()
        .box_with_nodes([shift; 3], [shift + 0.1; 3], 125)
        .material(material)
        .dt(DT)
        .damping(DAMPING)
        .gravity([0.0, -gravity, 0.0])
        .fixed(NodeSet::below(Axis::X, shift + 0.001))
        .build()
        .unwrap()
}

/// Displacement of every node from rest after settling.
fn settled(b: &mut dyn Backend, rest: &[[f64; 3]]) -> Vec<[f64; 3]> {
    b.step(STEPS);
    let p = read(b, NodeField::Position);
    rest.iter()
        .zip(&p)
        .map(|(r, p)| [0, 1, 2].map(|k| p[k] as f64 - r[k]))
        .collect()
}

/// Mean y displacement of the free face (x = 0.1 m from the cube's corner).
fn free_end_sag(u: &[[f64; 3]], rest: &[[f64; 3]], x0: f64) -> f64 {
    let face: Vec<usize> = (0..rest.len())
        .filter(|&i| rest[i][0] > x0 + 0.099)
        .collect();
    face.iter().map(|&i| u[i][1]).sum::<f64>() / face.len() as f64
}

fn cpu_sag(material: Material, gravity: f64, shift: f64) -> (Vec<[f64; 3]>, f64) {
    let scene = cube(material, gravity, shift);
    let rest = rest_positions(&scene);
    let mut b = backend(&scene, needlesim::Threading::Single);
    let u = settled(&mut b, &rest);
    let sag = free_end_sag(&u, &rest, shift);
    (u, sag)
}

/// At 1% and 0.01% of gravity (sags of about 3e-4 and 3e-6 m, 40,000 and 400 f32 steps
/// at 0.1 m) the response is linear, so the second is 1% of the first. Tolerance 0.5%
/// (the issue's); the compensated sum gives 0.07% or better, the plain one gave 99%.
/// Shape matching is held to 0.1% of gravity (a 40 um sag, like the 23 um one):
/// its rotation's dead band (`mueller2016_rotation::ANGLE_TOLERANCE`) costs it 3% (node
/// forces) and 19% (cluster forces) at 0.01%, and 0.3% and 1.8% at 0.1%, so its bound
/// there is 2.5%.
#[test]
fn a_small_load_gives_a_proportionally_small_displacement_with_every_model() {
    for (name, material) in all_models() {
        let shape_matching = matches!(material, Material::LocalShapeMatching(_));
        let (fraction, tolerance) = if shape_matching {
            (1e-1, 2.5e-2)
        } else {
            (1e-2, 5e-3)
        };
        let (_, big) = cpu_sag(material, 9.81e-2, 0.0);
        let (_, small) = cpu_sag(material, 9.81e-2 * fraction, 0.0);
        let ratio = small / big / fraction;
        eprintln!("{name}: sag {big:.4e} m at 1% of g, ratio {ratio:.6} at {fraction} of that");
        assert!(big < -1e-4, "{name}: the cube did not sag ({big:e} m)");
        assert!(
            (ratio - 1.0).abs() < tolerance,
            "{name}: {fraction} of the load gives {ratio} x {fraction} of the sag"
        );
    }
}

/// The same cube 1 m from the origin, where f32's spacing is 16 times coarser (1.2e-7 m),
/// at 10% of gravity (a sag of about 3 mm): every node's displacement is the same within
/// 1e-4 of the largest. What is left is the spacing at 1.1 m, 4e-5 of the sag, in the
/// forces' view of the positions and in reading them back.
#[test]
fn a_body_placed_1_m_from_the_origin_deforms_the_same() {
    for (name, material) in all_models() {
        let (u0, _) = cpu_sag(material, 0.981, 0.0);
        let (u1, _) = cpu_sag(material, 0.981, 1.0);
        let scale = u0
            .iter()
            .map(|u| (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt())
            .fold(0.0, f64::max);
        let worst = u0
            .iter()
            .zip(&u1)
            .map(|(a, b)| {
                let d = [0, 1, 2].map(|k| a[k] - b[k]);
                (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
            })
            .fold(0.0, f64::max);
        eprintln!(
            "{name}: largest displacement {scale:.4e} m, difference {:.2e}",
            worst / scale
        );
        assert!(scale > 1e-3, "{name}: the cube hardly moved ({scale:e} m)");
        assert!(
            worst < 1e-4 * scale,
            "{name}: translated 1 m, displacements differ by {worst:e} m of {scale:e} m"
        );
    }
}

/// The GPU's integrator sums the same way (a compiler that reassociated the TwoSum would
/// lose the remainder): the small-load ratio on the device, one linear and one discrete
/// model.
#[test]
fn the_gpu_integrator_keeps_small_increments_too() {
    for (name, material) in [MODELS[0], LINEAR_DEB] {
        let mut sags = Vec::new();
        for gravity in [9.81e-2, 9.81e-4] {
            let scene = cube(material, gravity, 0.0);
            let rest = rest_positions(&scene);
            let tissue = Tissue::from_scene(&scene).unwrap();
            let mut b = match GpuBackend::new(&tissue) {
                Ok(b) => b,
                Err(GpuError::NoAdapter(m)) if std::env::var("NEEDLESIM_REQUIRE_GPU").is_err() => {
                    eprintln!("skipped, no GPU adapter: {m}");
                    return;
                }
                Err(e) => panic!("GPU backend: {e}"),
            };
            let u = settled(&mut b, &rest);
            sags.push(free_end_sag(&u, &rest, 0.0));
        }
        let ratio = sags[1] / sags[0] / 1e-2;
        eprintln!("{name} on the GPU: ratio {ratio:.6}");
        assert!(
            (ratio - 1.0).abs() < 5e-3,
            "{name}: 0.01% of gravity gives {ratio} x 1% of the 1% sag on the GPU"
        );
    }
}

/// A written position is exact: writing it clears the node's remainder, and the
/// remainder can be read and written back (checkpoints restore it after the positions).
#[test]
fn writing_a_position_clears_its_remainder() {
    let scene = cube(LINEAR_DEB.1, 9.81e-4, 1.0);
    let mut b = backend(&scene, needlesim::Threading::Single);
    b.step(200);
    let r = read(&mut b, NodeField::PositionRemainder);
    let moving = r.iter().filter(|r| r[1] != 0.0).count();
    assert!(moving > 0, "no node carries a remainder after 200 steps");
    let p = read(&mut b, NodeField::Position);
    b.write(NodeField::Position, 0, &p).unwrap();
    let cleared = read(&mut b, NodeField::PositionRemainder);
    assert!(cleared.iter().all(|r| *r == [0.0; 4]));
    b.write(NodeField::PositionRemainder, 0, &r).unwrap();
    assert_eq!(read(&mut b, NodeField::PositionRemainder), r);
}
