//! The stable time step estimated from the model (`core::stability`) against the
//! behaviour of the time stepping itself: every model stays bounded just below the
//! estimate and runs away above it. The measured limit by bisection, next to the
//! estimate, is the stable-dt map of `needlesim report` (`crates/report/src/stable_dt.rs`).

mod common;
use common::*;
use needlesim::core::backend::check_bounded;
use needlesim::core::scene::{DebunneParams, ShapeMatchingForces, ShapeMatchingParams, TimeStep};
use needlesim::core::stability::max_eigenvalue;
use needlesim::{Backend, CpuBackend, Material, Scene, Threading, Tissue};

/// The 10 cm cube of about 343 nodes with velocity damping `damping`, at rest except for a 0.1 mm random
/// perturbation, with time step `dt`.
fn cube(material: Material, dt: f64, damping: f64) -> CpuBackend {
    let scene = Scene::builder()
        .box_with_nodes([0.0; 3], [0.1; 3], 343)
        .material(material)
        .dt(dt)
        .damping(damping)
        .build()
        .unwrap();
    let mut b = CpuBackend::new(Tissue::from_scene(&scene).unwrap(), Threading::Single).unwrap();
    let mut p = read(&mut b, needlesim::NodeField::Position);
    let mut s = 11u64;
    for c in p.iter_mut().flat_map(|q| q[..3].iter_mut()) {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        *c += 1e-4 * ((s >> 11) as f64 / (1u64 << 53) as f64 - 0.5) as f32;
    }
    b.write(needlesim::NodeField::Position, 0, &p).unwrap();
    b
}

/// Whether `steps` steps stay below 1 m/s (the perturbation moves nodes at mm/s).
fn bounded(b: &mut CpuBackend, steps: u64) -> bool {
    for _ in 0..steps / 50 {
        b.step(50);
        if check_bounded(b, 1.0).is_err() {
            return false;
        }
    }
    true
}

#[test]
fn estimated_critical_dt_separates_stable_from_unstable_steps() {
    for (name, material) in all_models() {
        // The paper's per-node shape matching forces feed energy in and need damping at
        // any time step (local_shape_matching module docs); the others run undamped.
        let damping = if name == "lshm-node" { 20.0 } else { 0.0 };
        let mut probe = cube(material, 1e-4, damping);
        let est = max_eigenvalue(&mut probe, 60).unwrap();
        let dt = est.critical_dt;
        assert!(dt.is_finite() && dt > 0.0, "{name}: {est:?}");
        let mut below = cube(material, 0.8 * dt, damping);
        let mut above = cube(material, 1.5 * dt, damping);
        let (b, a) = (bounded(&mut below, 3000), bounded(&mut above, 3000));
        eprintln!("{name}: critical dt {dt:.3e} s; 0.8x bounded {b}, 1.5x bounded {a}");
        assert!(b, "{name}: unstable at 0.8 x the estimate {dt:e}");
        assert!(!a, "{name}: still bounded at 1.5 x the estimate {dt:e}");
    }
}

/// `dt = "auto"` keeps every model stable at 1000 times its default stiffness, released
/// from a 20% stretch, where the default 1 ms step runs away. At E = 10 MPa the wave
/// speed is 100 m/s and the released corner nodes (an eighth of an interior node's mass)
/// really move at up to 110 m/s, at a tenth of the step as at half of it: the bound is
/// 1000 m/s, which an unstable run crosses within a few steps of its growth.
#[test]
fn auto_dt_is_stable_on_stiff_scenes() {
    const RUNAWAY_SPEED: f64 = 1000.0;
    let stiff = [
        ("msm", Material::mass_spring(1e5), 0.0),
        // The paper's node forces gain energy at a rate growing like sqrt(k); they need
        // damping at any step (20/s at the default stiffness, times sqrt(1000)).
        (
            "lshm-node",
            Material::LocalShapeMatching(
                ShapeMatchingParams::new(2e4).with_forces(ShapeMatchingForces::Node),
            ),
            630.0,
        ),
        (
            "lshm-cluster",
            Material::LocalShapeMatching(
                ShapeMatchingParams::new(2e4).with_forces(ShapeMatchingForces::Cluster),
            ),
            0.0,
        ),
        ("deb", Material::debunne(1e7, 0.3), 0.0),
        (
            "deb-corotated",
            Material::DebunneMeshfree(DebunneParams::new(1e7, 0.3).with_corotated(true)),
            0.0,
        ),
        ("pba", Material::point_based(1e7, 0.3), 0.0),
    ];
    for (name, material, damping) in stiff {
        let scene = |dt: TimeStep| {
            Scene::builder()
                .box_with_nodes([0.0; 3], [0.1; 3], 343)
                .material(material)
                .time_step(dt)
                .damping(damping)
                .stretch([1.2, 1.0, 1.0])
                .build()
                .unwrap()
        };
        let auto = Tissue::from_scene(&scene(TimeStep::Auto)).unwrap();
        let dt = auto.step.dt as f64;
        let mut b = CpuBackend::new(auto, Threading::Parallel).unwrap();
        let mut ok = true;
        for _ in 0..40 {
            b.step(50);
            ok &= check_bounded(&mut b, RUNAWAY_SPEED).is_ok();
        }
        let mut fixed = CpuBackend::new(
            Tissue::from_scene(&scene(TimeStep::Seconds(1e-3))).unwrap(),
            Threading::Parallel,
        )
        .unwrap();
        let mut fixed_ok = true;
        for _ in 0..40 {
            fixed.step(50);
            fixed_ok &= check_bounded(&mut fixed, RUNAWAY_SPEED).is_ok();
        }
        eprintln!("{name}: auto dt {dt:.2e} s bounded {ok}; 1 ms bounded {fixed_ok}");
        assert!(ok, "{name}: dt = auto ({dt:e} s) ran away");
        assert!(
            !fixed_ok,
            "{name}: the stiff scene is stable at 1 ms too: not a stiff case"
        );
    }
}
