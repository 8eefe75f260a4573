//! Viscoelastic continuum tissue (`viscoelastic = [{ g, tau }, ...]`,
//! `needlesim_core::models::viscoelastic`) against the closed forms of the Prony series,
//! which do not come from our code: a cube's plate reaction relaxing under a held
//! compression, its creep under a held pressure, and the phase lag of its reaction under a
//! harmonic compression, each on the CPU and on the GPU (lavapipe in CI); plus bad input,
//! the one combination the GPU refuses, and a checkpoint taken mid-relaxation with a
//! needle inside.

mod common;

use needlesim::core::models::viscoelastic::{
    complex_modulus, creep_ramp_response, ramp_response, Prony, PronyTerm,
};
use needlesim::core::scene::{
    Axis, Components, DebunneParams, FixedSelection, LoadSpec, NeoHookeanParams, NodeSet,
    PointBasedParams, Prescribed,
};
use needlesim::gpu::{GpuBackend, GpuError};
use needlesim::needle::{Checkpoint, PunctureState, Simulation};
use needlesim::{Backend, CpuBackend, Material, NodeField, Scene, Threading, Tissue};
use std::path::Path;

const E: f64 = 1e4;
const NU: f64 = 0.3;

fn two_terms() -> Prony {
    Prony::new(&[
        PronyTerm { g: 0.3, tau: 0.15 },
        PronyTerm { g: 0.2, tau: 1.0 },
    ])
}

/// The continuum models with the series `p`.
fn models(p: Prony) -> Vec<(&'static str, Material)> {
    vec![
        (
            "deb",
            Material::DebunneMeshfree(DebunneParams::new(E, NU).with_viscoelastic(p)),
        ),
        (
            "deb-corotated",
            Material::DebunneMeshfree(
                DebunneParams::new(E, NU)
                    .with_corotated(true)
                    .with_viscoelastic(p),
            ),
        ),
        (
            "pba",
            Material::PointBased(PointBasedParams::new(E, NU).with_viscoelastic(p)),
        ),
        (
            "nh",
            Material::NeoHookean(NeoHookeanParams::new(E, NU).with_viscoelastic(p)),
        ),
    ]
}

/// A 10 cm cube (9 x 9 x 9 nodes) on a roller floor (held in y only).
fn cube(material: Material, damping: f64) -> needlesim::core::SceneBuilder {
    Scene::builder()
        .box_with_spacing([0.0; 3], [0.1; 3], 0.0125)
        .material(material)
        .dt_auto()
        .damping(damping)
        .fixed(
            FixedSelection::new(NodeSet::below(Axis::Y, 0.001))
                .with_components(Components::of(&[Axis::Y]))
                .with_name("bottom"),
        )
}

/// Where the tests run: all CPU threads, and the GPU when wgpu finds an adapter (lavapipe
/// in CI, where `NEEDLESIM_REQUIRE_GPU` makes a missing adapter a failure).
#[derive(Debug, Clone, Copy, PartialEq)]
enum On {
    Cpu,
    Gpu,
}

fn backend(tissue: Tissue, on: On) -> Option<Box<dyn Backend>> {
    match on {
        On::Cpu => Some(Box::new(
            CpuBackend::new(tissue, Threading::Parallel).unwrap(),
        )),
        On::Gpu => match GpuBackend::new(&tissue) {
            Ok(g) => Some(Box::new(g)),
            Err(GpuError::NoAdapter(m)) if std::env::var("NEEDLESIM_REQUIRE_GPU").is_err() => {
                eprintln!("GPU skipped, no adapter: {m}");
                None
            }
            Err(e) => panic!("GPU backend: {e}"),
        },
    }
}

fn start_on(scene: &Scene, on: On) -> Option<Simulation> {
    let prep = Simulation::prepare(scene).unwrap();
    let b = backend(prep.tissue.clone(), on)?;
    Some(prep.start(b).unwrap())
}

fn start(scene: &Scene) -> Simulation {
    start_on(scene, On::Cpu).unwrap()
}

/// Step strain: the top plate pushes 0.2 mm (0.2%) down over 50 ms and holds. The plate
/// reaction relaxes as the series says, `E eps A` times [`ramp_response`] (uniaxial stress:
/// both Lame constants relax alike, so the lateral strain does not change and the
/// uniaxial modulus is `E g(t)`). Sampled from 0.2 s (four times the ramp, after the
/// ramp's elastic waves have been damped) to 3 s (three times the longest tau), within 2%
/// for every continuum model (the tolerance). Damping 120/s is about critical for
/// the cube's slowest mode; it adds a drag proportional to the nodes' velocity, which is
/// small once the ramp ends (the relaxation itself moves the nodes only laterally and
/// slowly). Measured (dev machine, 729 nodes): largest error DEB and co-rotated DEB 0.24%,
/// PBA 0.39%, neo-Hookean 0.39%, the same within 0.01 point on lavapipe.
#[test]
fn step_strain_relaxes_as_the_prony_series() {
    let p = two_terms();
    let (eps, area, ramp) = (-0.002, 0.01, 0.05);
    for (on, (label, material)) in [On::Cpu, On::Gpu]
        .into_iter()
        .flat_map(|on| models(p).into_iter().map(move |m| (on, m)))
    {
        let scene = cube(material, 120.0)
            .prescribed(
                Prescribed::displacement(NodeSet::above(Axis::Y, 0.099), [0.0, -0.0002, 0.0], ramp)
                    .with_components(Components::of(&[Axis::Y]))
                    .with_name("top"),
            )
            .build()
            .unwrap();
        let Some(mut sim) = start_on(&scene, on) else {
            continue;
        };
        let mut worst: f64 = 0.0;
        for t in [0.2, 0.3, 0.5, 0.8, 1.2, 2.0, 3.0] {
            let steps = ((t - sim.time()) / sim.dt()).round() as u64;
            sim.step_n(steps).unwrap();
            let r = sim.reactions().unwrap();
            let top = r.iter().find(|r| r.name == "top").unwrap().force[1];
            let want = E * eps * area * ramp_response(&p, sim.time(), ramp);
            let err = (top / want - 1.0).abs();
            eprintln!(
                "{on:?} {label}: t {:.3} s reaction {top:.5} N, closed form {want:.5} N, error {:.3}%",
                sim.time(),
                100.0 * err
            );
            worst = worst.max(err);
        }
        assert!(
            worst < 0.02,
            "{on:?} {label}: worst relaxation error {worst}"
        );
    }
}

/// Creep: a 20 Pa pressure on the top face, ramped over 50 ms and held, on a one-term
/// series (the standard linear solid, whose creep compliance is closed form: the strain
/// grows from `p / E` towards `p / (E g_inf)` with the retardation time `tau / g_inf`).
/// The mean axial strain follows [`creep_ramp_response`] within 2% from 0.4 s to 4 s.
/// The mass-proportional damping resists the creep itself (a drag `m c v` on every
/// moving node): with 120/s the strain lagged the closed form by 6.3% at 0.2 s, so this
/// test damps with 20/s and ramps over 0.2 s (twice the slowest elastic period), which
/// excites little ringing. Measured (dev machine): largest error DEB 0.40%, PBA 0.72%,
/// neo-Hookean 0.61%, the same on lavapipe.
#[test]
fn creep_under_a_held_pressure_follows_the_compliance() {
    let p = Prony::new(&[PronyTerm { g: 0.4, tau: 0.5 }]);
    let (pressure, ramp) = (20.0, 0.2);
    for (on, (label, material)) in [On::Cpu, On::Gpu]
        .into_iter()
        .flat_map(|on| models(p).into_iter().map(move |m| (on, m)))
    {
        let scene = cube(material, 20.0)
            .load(
                LoadSpec::pressure(NodeSet::in_box([-1.0, 0.099, -1.0], [1.0; 3]), pressure)
                    .with_ramp(ramp),
            )
            .build()
            .unwrap();
        let Some(mut sim) = start_on(&scene, on) else {
            continue;
        };
        let mut worst: f64 = 0.0;
        for t in [0.4, 0.6, 0.8, 1.0, 1.5, 2.5, 4.0] {
            let steps = ((t - sim.time()) / sim.dt()).round() as u64;
            sim.step_n(steps).unwrap();
            let strain = common::mean_strain(&mut sim, 1);
            let want = -pressure / E * creep_ramp_response(&p, sim.time(), ramp).unwrap();
            let err = (strain / want - 1.0).abs();
            eprintln!(
                "{on:?} {label}: t {:.3} s strain {strain:.4e}, closed form {want:.4e}, error {:.3}%",
                sim.time(),
                100.0 * err
            );
            worst = worst.max(err);
        }
        assert!(worst < 0.02, "{on:?} {label}: worst creep error {worst}");
    }
}

/// A harmonic compression: the top nodes are driven `u_y = A sin(w t)` (A = 0.1 mm, rollers
/// below, w = 1 / tau so that the loss is near its peak), the reaction on them lags the
/// strain by the loss angle `atan(E'' / E')` of the series ([`complex_modulus`]). The
/// reaction's sine and cosine parts are fitted over the third and fourth periods; the angle
/// agrees within 2 degrees (the tolerance). Inertia adds a part in phase with the
/// displacement and little damping (1/s) a small one in phase with the velocity (about
/// 0.1 degree here, `rho L^2 c w / 2E`). Measured (dev machine): 14.09 degrees for every
/// model, on the CPU and on lavapipe, against 14.04.
#[test]
fn harmonic_strain_lags_by_the_loss_angle() {
    let p = Prony::new(&[PronyTerm { g: 0.4, tau: 0.5 }]);
    let omega = 1.0 / 0.5;
    let (re, im) = complex_modulus(&p, omega);
    let want = im.atan2(re).to_degrees();
    for (on, (label, material)) in [On::Cpu, On::Gpu]
        .into_iter()
        .flat_map(|on| models(p).into_iter().map(move |m| (on, m)))
    {
        let scene = cube(material, 1.0).build().unwrap();
        let tissue = Tissue::from_scene(&scene).unwrap();
        let rest: Vec<[f32; 4]> = tissue.state.positions.clone();
        let n = tissue.n_mesh;
        let top: Vec<usize> = (0..n).filter(|&i| rest[i][1] > 0.099).collect();
        let bottom: Vec<usize> = (0..n).filter(|&i| rest[i][1] < 0.001).collect();
        let dt = tissue.step.dt as f64;
        let Some(mut b) = backend(tissue, on) else {
            continue;
        };
        let amplitude = 1e-4f64;
        let period = 2.0 * std::f64::consts::PI / omega;
        let steps = (4.0 * period / dt).round() as u64;
        let (mut x, mut v, mut f) = (
            vec![[0.0f32; 4]; n],
            vec![[0.0f32; 4]; n],
            vec![[0.0f32; 4]; n],
        );
        let (mut ss, mut sc, mut cc, mut fs, mut fc) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for step in 1..=steps {
            let t = step as f64 * dt;
            b.read(NodeField::Position, 0..n, &mut x).unwrap();
            b.read(NodeField::Velocity, 0..n, &mut v).unwrap();
            for &i in &top {
                x[i][1] = (rest[i][1] as f64 + amplitude * (omega * t).sin()) as f32;
                v[i][1] = (amplitude * omega * (omega * t).cos()) as f32;
            }
            for &i in &bottom {
                x[i][1] = rest[i][1];
                v[i][1] = 0.0;
            }
            b.write(NodeField::Position, 0, &x).unwrap();
            b.write(NodeField::Velocity, 0, &v).unwrap();
            b.compute_forces();
            if t >= 2.0 * period {
                b.read(NodeField::Force, 0..n, &mut f).unwrap();
                // The plate's reaction: minus the tissue's force on the driven nodes.
                let reaction: f64 = -top.iter().map(|&i| f[i][1] as f64).sum::<f64>();
                let (s, c) = ((omega * t).sin(), (omega * t).cos());
                ss += s * s;
                sc += s * c;
                cc += c * c;
                fs += reaction * s;
                fc += reaction * c;
            }
            b.integrate();
        }
        // Least squares reaction = a sin + b cos.
        let det = ss * cc - sc * sc;
        let a = (fs * cc - fc * sc) / det;
        let bb = (fc * ss - fs * sc) / det;
        let got = bb.atan2(a).to_degrees();
        eprintln!(
            "{on:?} {label}: loss angle {got:.3} deg, closed form {want:.3} deg (storage part {a:.4e} N)"
        );
        assert!(
            (got - want).abs() < 2.0,
            "{on:?} {label}: {got} against {want} degrees"
        );
    }
}

/// Bad series are typed errors naming the key, from the TOML the user writes.
#[test]
fn bad_prony_terms_name_the_key() {
    let base = "[tissue]\ngeometry = { kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], nodes = 125 }\n[material]\nmodel = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3\n";
    for (line, key) in [
        ("viscoelastic = [{ g = 1.2, tau = 0.5 }]", "material.viscoelastic[0].g"),
        ("viscoelastic = [{ g = 0.2, tau = -1.0 }]", "material.viscoelastic[0].tau"),
        ("viscoelastic = [{ g = 0.2, tau = 0.0 }]", "material.viscoelastic[0].tau"),
        ("viscoelastic = [{ g = 0.6, tau = 0.5 }, { g = 0.5, tau = 2.0 }]", "material.viscoelastic"),
        (
            "viscoelastic = [{ g = 0.1, tau = 1.0 }, { g = 0.1, tau = 1.0 }, { g = 0.1, tau = 1.0 }, { g = 0.1, tau = 1.0 }, { g = 0.1, tau = 1.0 }]",
            "at most 4",
        ),
        ("viscoelastic = [{ g = 0.2, tau = 0.5, beta = 1.0 }]", "beta"),
    ] {
        let text = format!("{base}{line}\n");
        let e = Scene::from_toml_str(&text, Path::new(".")).unwrap_err().to_string();
        assert!(e.contains(key), "{line}: {e}");
    }
    let ok =
        format!("{base}viscoelastic = [{{ g = 0.3, tau = 0.15 }}, {{ g = 0.2, tau = 1.0 }}]\n");
    let scene = Scene::from_toml_str(&ok, Path::new(".")).unwrap();
    assert_eq!(scene.material.prony(), two_terms());
}

/// The one combination the GPU kernels do not run (co-rotated viscoelastic Debunne with
/// several materials: 9 storage buffers in one kernel, the device is asked for 8) is a
/// typed error, not an elastic run. Checked without an adapter: the refusal comes first.
#[test]
fn the_gpu_refuses_corotated_viscoelastic_with_two_materials() {
    let text = "[tissue]\ngeometry = { kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], nodes = 125 }\n\
                [material]\nmodel = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3\ncorotated = true\n\
                viscoelastic = [{ g = 0.3, tau = 0.15 }]\n\
                [[region]]\nname = \"stiff\"\ngeometry = { kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.05, 0.1, 0.1] }\n\
                material = { young_modulus = 2e4 }\n";
    let scene = Scene::from_toml_str(text, Path::new(".")).unwrap();
    let tissue = Tissue::from_scene(&scene).unwrap();
    assert!(tissue.shape.node_material.is_some());
    match GpuBackend::new(&tissue) {
        Err(GpuError::Unsupported { feature }) => assert!(feature.contains("viscoelastic")),
        Err(e) => panic!("another error: {e}"),
        Ok(_) => panic!("the GPU accepted co-rotated viscoelastic Debunne with two materials"),
    }
}

/// The insert-extract scene with viscoelastic tissue: a checkpoint taken with the needle
/// inside while the tissue relaxes resumes bitwise (the viscous state is a shape array, so
/// it travels with the checkpoint and with the needle's node additions and removals).
#[test]
fn a_checkpoint_mid_relaxation_resumes_bitwise() {
    let text = include_str!("../scenes/needle_insert_extract.toml");
    for (label, material) in models(two_terms()) {
        let mut scene = Scene::from_toml_str(text, Path::new("scenes")).unwrap();
        scene.material = material;
        scene.validate().unwrap();
        let mut sim = start(&scene);
        sim.step_n(1_500).unwrap();
        assert!(sim.needle_nodes().len() >= 3, "{label}: needle not inside");
        let bytes = sim.checkpoint().unwrap().to_bytes();
        sim.step_n(1_300).unwrap();
        let prep = Simulation::prepare(&scene).unwrap();
        let b = CpuBackend::new(prep.tissue.clone(), Threading::Parallel).unwrap();
        let c = Checkpoint::from_bytes(&bytes, Path::new("mem")).unwrap();
        let mut resumed = prep.resume(Box::new(b), c).unwrap();
        resumed.step_n(1_300).unwrap();
        let cap = sim.backend().capacity();
        for field in [NodeField::Position, NodeField::Velocity, NodeField::Force] {
            let (mut a, mut r) = (vec![[0.0f32; 4]; cap], vec![[0.0f32; 4]; cap]);
            sim.backend().read(field, 0..cap, &mut a).unwrap();
            resumed.backend().read(field, 0..cap, &mut r).unwrap();
            assert!(a == r, "{label}: {field:?} differs after resuming");
        }
        assert_eq!(
            format!("{:?}", sim.history()),
            format!("{:?}", resumed.history()),
            "{label}"
        );
    }
}

/// The viscoelastic liver (`scenes/liver_insertion_viscoelastic.toml`, at 10 mm spacing)
/// against its elastic twin: the force at 25 mm rises with the insertion speed (5 to
/// 20 mm/s), and while the needle is held 3 s it relaxes; the elastic scene does neither
/// (within 2% and 3%: its force is rate independent; what the elastic hold loses is its
/// tissue settling after the stop). The force at 25 mm is the mean over 24 to 26 mm of
/// depth. Measured (dev machine, this test, 2026-11-26): 1.149 -> 1.280 N (+11.4%)
/// against 1.344 -> 1.349 N; held after 20 mm/s 1.458 -> 1.253 N (-14.1% from 50 ms
/// after the stop to 2.95 s), elastic 1.564 -> 1.553 N (-0.7%). The bounds: a rise above
/// 8% and a drop above 8%.
#[test]
fn the_viscoelastic_liver_force_rises_with_speed_and_relaxes_when_held() {
    let run = |name: &str, speed: f64| -> (f64, f64, f64) {
        let text = match name {
            "visco" => include_str!("../scenes/liver_insertion_viscoelastic.toml"),
            _ => include_str!("../scenes/liver_insertion.toml"),
        };
        let travel = 0.035;
        let text = text
            .replace("spacing = 0.005 }", "spacing = 0.01 }")
            .replacen(
                "speed = 0.005\nduration = 7.0",
                &format!("speed = {speed}\nduration = {}", travel / speed),
                1,
            )
            .replacen(
                "action = \"pause\"\nduration = 1.0",
                "action = \"pause\"\nduration = 3.0",
                1,
            );
        let scene = Scene::from_toml_str(&text, Path::new("scenes")).unwrap();
        let mut sim = start(&scene);
        let stop = travel / speed;
        let steps = ((stop + 3.0) / sim.dt()).ceil() as u64;
        sim.step_n(steps).unwrap();
        let h = sim.history();
        let at = |f: &dyn Fn(&needlesim::needle::NeedleSample) -> bool| {
            h.iter().find(|s| f(s)).map(|s| s.force.axial).unwrap()
        };
        // Depth past the first contact along the needle (as the report measures it).
        let touch = h
            .iter()
            .find(|s| s.state != PunctureState::Outside)
            .unwrap()
            .tip;
        let depth_of = |s: &needlesim::needle::NeedleSample| {
            (0..3)
                .map(|a| (s.tip[a] - touch[a]) * s.direction[a])
                .sum::<f64>()
        };
        // The mean over 24-26 mm: at 10 mm spacing a Shaft node is added near 25 mm, and
        // the force a single step reads there depends on where in that event it falls.
        let window: Vec<f64> = h
            .iter()
            .filter(|s| (0.024..=0.026).contains(&depth_of(s)) && s.state == PunctureState::Inside)
            .map(|s| s.force.axial)
            .collect();
        let f25 = window.iter().sum::<f64>() / window.len() as f64;
        let held = at(&|s| s.time >= stop + 0.05);
        let end = at(&|s| s.time >= stop + 2.95);
        (f25, held, end)
    };
    let (v5, _, _) = run("visco", 0.005);
    let (v20, vh, ve) = run("visco", 0.02);
    let (e5, _, _) = run("elastic", 0.005);
    let (e20, eh, ee) = run("elastic", 0.02);
    eprintln!("viscoelastic: {v5:.3} -> {v20:.3} N, held {vh:.3} -> {ve:.3} N; elastic: {e5:.3} -> {e20:.3} N, held {eh:.3} -> {ee:.3} N");
    assert!(
        v20 / v5 > 1.08,
        "viscoelastic force should rise with speed: {v5} -> {v20}"
    );
    assert!(
        (e20 / e5 - 1.0).abs() < 0.02,
        "elastic force should not: {e5} -> {e20}"
    );
    assert!(
        ve / vh < 0.92,
        "viscoelastic hold should relax: {vh} -> {ve}"
    );
    assert!(ee / eh > 0.97, "elastic hold: {eh} -> {ee}");
}

/// The GPU holds the viscoelastic state twice (committed and next rows in one buffer):
/// the device is asked for a storage binding at least that large, and `needlesim info`'s
/// array list counts both copies. (At 1M nodes the single copy fitted the 128 MiB binding but the
/// buffer did not: found on an H200, a validation error at bind-group creation.)
#[test]
fn the_viscoelastic_state_is_counted_twice() {
    let scene = cube(models(two_terms())[0].1, 10.0).build().unwrap();
    let tissue = Tissue::from_scene(&scene).unwrap();
    let arrays = tissue.allocations();
    let bytes = |name: &str| arrays.iter().find(|a| a.name == name).map(|a| a.bytes);
    let one = bytes("viscous_state").expect("the committed state");
    assert_eq!(bytes("viscous_state_next"), Some(one));
    assert_eq!(one, 120 * tissue.state.capacity());
    // The device's largest binding is the doubled state or a larger array (since the
    // integration corrections, the 264-byte moment rows).
    let others = arrays
        .iter()
        .filter(|a| !a.name.starts_with("viscous_state"))
        .map(|a| a.bytes as u64)
        .max()
        .unwrap_or(0);
    assert_eq!(
        needlesim::gpu::largest_buffer(&tissue),
        others.max(2 * one as u64)
    );
}

/// The GPU stores the viscoelastic state component-major; through the `Backend` API it
/// reads and writes as the host's rows: a write that starts and ends inside rows reads
/// back the same on both backends, and so does the state after 50 steps of a stretched
/// cube, to f32 round-off between the kernels: within 2e-4 of the largest entry (measured
/// on lavapipe, point based animation: 6.5e-5; the stresses carry the positions' round-off
/// divided by the spacing).
#[test]
fn viscous_rows_round_trip_on_the_gpu() {
    use needlesim::core::models::ShapeArray;
    let scene = cube(models(two_terms())[2].1, 10.0)
        .stretch([1.0, 1.05, 1.0])
        .build()
        .unwrap();
    let tissue = Tissue::from_scene(&scene).unwrap();
    let Some(mut g) = backend(tissue.clone(), On::Gpu) else {
        return;
    };
    let mut c = backend(tissue.clone(), On::Cpu).unwrap();
    let total = 120 * tissue.state.capacity();
    let values: Vec<f32> = (0..47).map(|e| 1e-3 * e as f32).collect();
    for b in [&mut c, &mut g] {
        b.write_shape_bytes(ShapeArray::Viscous, 4 * 37, bytemuck::cast_slice(&values))
            .unwrap();
    }
    let read = |b: &mut Box<dyn Backend>| {
        let mut out = vec![0u8; total];
        b.read_shape_bytes(ShapeArray::Viscous, 0, &mut out)
            .unwrap();
        bytemuck::cast_slice::<u8, f32>(&out).to_vec()
    };
    assert!(read(&mut c) == read(&mut g), "written rows differ");
    for b in [&mut c, &mut g] {
        b.step(50);
    }
    let (a, b) = (read(&mut c), read(&mut g));
    let scale = a.iter().fold(0.0f32, |m, x| m.max(x.abs()));
    assert!(scale > 0.0);
    let worst = a
        .iter()
        .zip(&b)
        .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
    assert!(
        worst <= 2e-4 * scale,
        "state differs by {worst:e} of {scale:e}"
    );
}

/// `needlesim info` writes the relaxation function out; an elastic scene has no such line.
#[test]
fn info_writes_the_relaxation_function() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let visco = Scene::from_file(dir.join("cube_relaxation_deb.toml")).unwrap();
    let text = needlesim::SceneInfo::of(&visco).unwrap().to_string();
    assert!(
        text.contains("relaxation g(t) = 0.5000 + 0.3 exp(-t / 0.15 s) + 0.2 exp(-t / 1 s)"),
        "{text}"
    );
    let elastic = Scene::from_file(dir.join("cube_compression_deb.toml")).unwrap();
    let text = needlesim::SceneInfo::of(&elastic).unwrap().to_string();
    assert!(!text.contains("relaxation"), "{text}");
}
