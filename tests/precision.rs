//! Displacements below f32 resolution (issue 41, item 2): the integrator's compensated
//! position sum (`needlesim::core::integrator`) against loads so small, and a body so far
//! from the origin, that a plain `x + dt v` drops the increments.
//!
//! The setting that froze the plain sum on the dev machine: a 10 cm cube clamped on one
//! face, dt 1e-4 s, damping 60/s. At 0.01% of gravity its free end reached 1.4% of the
//! sag linear scaling predicts; translated 1 m from the origin it did not move at 0.1%.

mod common;

use common::*;
use needlesim::core::scene::{Axis, NodeSet, Prescribed};
use needlesim::gpu::{GpuBackend, GpuError};
use needlesim::{Backend, Material, NodeField, Scene, Tissue};

const DT: f64 = 1e-4;
const DAMPING: f64 = 60.0;
/// 1 s: the slowest mode of every model's cube has decayed by more than e^-15 (the
/// results change by less than 1e-5 relative between 1 and 2 s).
const STEPS: u64 = 10_000;

fn cube(material: Material, gravity: f64, shift: [f64; 3]) -> Scene {
    Scene::builder()
        .box_with_nodes(shift, shift.map(|s| s + 0.1), 125)
        .material(material)
        .dt(DT)
        .damping(DAMPING)
        .gravity([0.0, -gravity, 0.0])
        .fixed(NodeSet::below(Axis::X, shift[0] + 0.001))
        .build()
        .unwrap()
}

/// Displacement of every node from rest after settling: the world position read as
/// position plus remainder (`NodeField::PositionRemainder`), less the rest position, in
/// f64.
fn settled(b: &mut dyn Backend, rest: &[[f64; 3]]) -> Vec<[f64; 3]> {
    b.step(STEPS);
    displacements(b, rest)
}

/// Every node's displacement from `rest`: position plus remainder less the rest position,
/// in f64.
fn displacements(b: &mut dyn Backend, rest: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let p = read(b, NodeField::Position);
    let e = read(b, NodeField::PositionRemainder);
    rest.iter()
        .zip(p.iter().zip(&e))
        .map(|(r, (p, e))| [0, 1, 2].map(|k| (p[k] as f64 - r[k]) + e[k] as f64))
        .collect()
}

/// Mean y displacement of the free face (x = 0.1 m from the cube's corner at `x0`).
fn free_end_sag(u: &[[f64; 3]], rest: &[[f64; 3]], x0: f64) -> f64 {
    let face: Vec<usize> = (0..rest.len())
        .filter(|&i| rest[i][0] > x0 + 0.099)
        .collect();
    face.iter().map(|&i| u[i][1]).sum::<f64>() / face.len() as f64
}

fn cpu_sag(material: Material, gravity: f64, shift: [f64; 3]) -> (Vec<[f64; 3]>, f64) {
    let scene = cube(material, gravity, shift);
    let rest = rest_positions(&scene);
    let mut b = backend(&scene, needlesim::Threading::Single);
    let u = settled(&mut b, &rest);
    let sag = free_end_sag(&u, &rest, shift[0]);
    (u, sag)
}

/// The largest node displacement of `u0` and the largest difference between `u0` and
/// `u1`, m.
fn largest_and_difference(u0: &[[f64; 3]], u1: &[[f64; 3]]) -> (f64, f64) {
    let norm = |d: [f64; 3]| (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let scale = u0.iter().map(|u| norm(*u)).fold(0.0, f64::max);
    let worst = u0
        .iter()
        .zip(u1)
        .map(|(a, b)| norm([0, 1, 2].map(|k| a[k] - b[k])))
        .fold(0.0, f64::max);
    (scale, worst)
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
        let (_, big) = cpu_sag(material, 9.81e-2, [0.0; 3]);
        let (_, small) = cpu_sag(material, 9.81e-2 * fraction, [0.0; 3]);
        let ratio = small / big / fraction;
        eprintln!("{name}: sag {big:.4e} m at 1% of g, ratio {ratio:.6} at {fraction} of that");
        assert!(big < -1e-4, "{name}: the cube did not sag ({big:e} m)");
        assert!(
            (ratio - 1.0).abs() < tolerance,
            "{name}: {fraction} of the load gives {ratio} x {fraction} of the sag"
        );
    }
}

/// The same cube moved 1 m from the origin, where f32's spacing is 16 times coarser
/// (1.2e-7 m), at 0.1% of gravity (sags of 3 to 15 um, like the 23 um one), and
/// to a place that is no multiple of anything (-2.3, 0.7, 5.1 m; spacing 4.8e-7 m) at 1%:
/// every node's displacement (read as position plus remainder) is the same within 1e-4 of
/// the largest, the bound.
///
/// With the tissue's frame (`needlesim::core::frame`) the first differs by 1e-10 or less
/// (the same frame coordinates); in world coordinates it differed by 1.3e-5 to 6.3e-5 at
/// a 100 times larger load, and at this load f32's spacing at 1 m alone is 1e-2 of the
/// sag. The second sits in other frame coordinates, so it differs by what f32 resolves
/// of the cube at the origin itself (about 4e-9 m, half the spacing at 0.1 m): 1e-5 at
/// this load, 2e-4 at ten times less, which is why it is held at 1%.
#[test]
fn a_body_placed_far_from_the_origin_deforms_the_same() {
    for (name, material) in all_models() {
        for (shift, gravity) in [([1.0; 3], 9.81e-3), ([-2.3, 0.7, 5.1], 9.81e-2)] {
            let (u0, _) = cpu_sag(material, gravity, [0.0; 3]);
            let (u1, _) = cpu_sag(material, gravity, shift);
            let (scale, worst) = largest_and_difference(&u0, &u1);
            eprintln!(
                "{name} at {shift:?}: largest displacement {scale:.4e} m, difference {:.2e}",
                worst / scale
            );
            assert!(scale > 1e-6, "{name}: the cube hardly moved ({scale:e} m)");
            assert!(
                worst < 1e-4 * scale,
                "{name}: moved to {shift:?}, displacements differ by {worst:e} m of {scale:e} m"
            );
        }
    }
}

/// A prescribed displacement far from the origin: the cube clamped at x = 0 and its far
/// face pulled 20 um in y, at the origin and moved by 1 m. The held positions are written
/// in the backend's frame with their remainders (`Boundary::project`), so the fields
/// agree within 1e-4 of the largest displacement (1.7e-10 on the dev machine). Written as
/// world f32 positions they were off by up to half the spacing, 3.7e-9 m at the origin's
/// 0.1 m and 6e-8 m at 1 m: 3e-3 of the field.
#[test]
fn a_prescribed_displacement_far_from_the_origin_is_exact_too() {
    let field = |shift: [f64; 3]| {
        let scene = Scene::builder()
            .box_with_nodes(shift, shift.map(|s| s + 0.1), 125)
            .material(LINEAR_DEB.1)
            .dt(DT)
            .damping(DAMPING)
            .gravity([0.0; 3])
            .fixed(NodeSet::below(Axis::X, shift[0] + 0.001))
            .prescribed(Prescribed::displacement(
                NodeSet::above(Axis::X, shift[0] + 0.099),
                [0.0, 2e-5, 0.0],
                0.1,
            ))
            .build()
            .unwrap();
        let rest = rest_positions(&scene);
        let mut b = backend(&scene, needlesim::Threading::Single);
        let mut sim_time = 0.0;
        let boundary = b.tissue().boundary.clone();
        for _ in 0..STEPS {
            b.compute_forces();
            b.integrate();
            sim_time += DT;
            boundary.project(&mut b, sim_time).unwrap();
        }
        displacements(&mut b, &rest)
    };
    let (u0, u1) = (field([0.0; 3]), field([1.0; 3]));
    let (scale, worst) = largest_and_difference(&u0, &u1);
    eprintln!(
        "prescribed 20 um, moved 1 m: largest displacement {scale:.4e} m, difference {:.2e}",
        worst / scale
    );
    assert!(scale > 1.9e-5, "the face did not move ({scale:e} m)");
    assert!(worst < 1e-4 * scale, "{worst:e} m of {scale:e} m");
}

/// Every shipped scene lies within about its size of the origin, so its tissue keeps the
/// world frame and its results are those from before the frame existed, bit for bit.
#[test]
fn every_shipped_scene_keeps_the_world_frame() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let scene = Scene::from_file(&path).unwrap();
        let cloud =
            needlesim::core::geometry::build(&scene.tissue.geometry, &scene.base_dir).unwrap();
        let frame = needlesim::core::frame::PositionFrame::for_body(&cloud.positions);
        assert!(
            frame.is_world(),
            "{}: origin {:?}",
            path.display(),
            frame.origin()
        );
        seen += 1;
    }
    assert!(seen >= 10, "only {seen} scenes");
}

/// Points or vectors, m.
type Points = Vec<[f64; 3]>;

/// The displacements and rest positions of the cube settled on the GPU; `None` (the test
/// skipped) without an adapter unless `NEEDLESIM_REQUIRE_GPU` is set.
fn gpu_settled(material: Material, gravity: f64, shift: [f64; 3]) -> Option<(Points, Points)> {
    let scene = cube(material, gravity, shift);
    let rest = rest_positions(&scene);
    let tissue = Tissue::from_scene(&scene).unwrap();
    let mut b = match GpuBackend::new(&tissue) {
        Ok(b) => b,
        Err(GpuError::NoAdapter(m)) if std::env::var("NEEDLESIM_REQUIRE_GPU").is_err() => {
            eprintln!("skipped, no GPU adapter: {m}");
            return None;
        }
        Err(e) => panic!("GPU backend: {e}"),
    };
    Some((settled(&mut b, &rest), rest))
}

/// The GPU backend keeps the same frame: the cube 1 m away, at 0.1% of gravity, deforms
/// as at the origin within 1e-4 of the largest displacement (the backend converts
/// positions and remainders read back on the host).
#[test]
fn a_body_far_from_the_origin_deforms_the_same_on_the_gpu() {
    for (name, material) in [MODELS[0], LINEAR_DEB] {
        let Some((u0, _)) = gpu_settled(material, 9.81e-3, [0.0; 3]) else {
            return;
        };
        let (u1, _) = gpu_settled(material, 9.81e-3, [1.0; 3]).expect("adapter");
        let (scale, worst) = largest_and_difference(&u0, &u1);
        eprintln!(
            "{name} on the GPU, 1 m away: largest displacement {scale:.4e} m, difference {:.2e}",
            worst / scale
        );
        assert!(scale > 1e-6, "{name}: the cube hardly moved ({scale:e} m)");
        assert!(worst < 1e-4 * scale, "{name}: {worst:e} m of {scale:e} m");
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
            let Some((u, rest)) = gpu_settled(material, gravity, [0.0; 3]) else {
                return;
            };
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
    let scene = cube(LINEAR_DEB.1, 9.81e-4, [1.0; 3]);
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
