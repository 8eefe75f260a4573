//! The wgpu backend against the CPU reference, on whatever adapter wgpu finds (Mesa's
//! lavapipe in CI: scripts/test installs it and sets NEEDLESIM_REQUIRE_GPU=1, so a missing
//! adapter fails there instead of skipping).

mod common;

use common::*;
use needlesim::core::models::ShapeArray;
use needlesim::core::scene::{
    Axis, Components, DebunneParams, FixedSelection, LoadSpec, NodeSet, Prescribed,
};
use needlesim::gpu::{GpuBackend, GpuError};
use needlesim::{Backend, Material, NodeField, Scene, Threading, Tissue};

fn gpu(tissue: &Tissue) -> Option<GpuBackend> {
    match GpuBackend::new(tissue) {
        Ok(b) => {
            eprintln!("adapter: {}", b.adapter());
            Some(b)
        }
        Err(GpuError::NoAdapter(m)) if std::env::var("NEEDLESIM_REQUIRE_GPU").is_err() => {
            eprintln!("skipped, no GPU adapter: {m}");
            None
        }
        Err(e) => panic!("GPU backend: {e}"),
    }
}

/// Largest distance between the two backends' positions, over the largest displacement
/// from rest at the start (the initial stretch, the motion that could differ).
fn relative_difference(
    cpu: &[[f32; 4]],
    gpu: &[[f32; 4]],
    start: &[[f32; 4]],
    rest: &[[f64; 3]],
) -> f64 {
    let diff = cpu
        .iter()
        .zip(gpu)
        .map(|(a, b)| norm3([a[0] - b[0], a[1] - b[1], a[2] - b[2], 0.0]))
        .fold(0.0, f64::max);
    let motion = start
        .iter()
        .zip(rest)
        .map(|(a, r)| {
            (0..3)
                .map(|k| (a[k] as f64 - r[k]).powi(2))
                .sum::<f64>()
                .sqrt()
        })
        .fold(0.0, f64::max);
    diff / motion
}

/// Steps `g` and a single-threaded CPU backend of the same scene `steps` times and returns
/// their [`relative_difference`].
fn steps_apart(scene: &needlesim::Scene, g: &mut GpuBackend, steps: u64) -> f64 {
    let mut c = backend(scene, Threading::Single);
    let start = read(&mut c, NodeField::Position);
    c.step(steps);
    g.step(steps);
    let (pc, pg) = (
        read(&mut c, NodeField::Position),
        read(g, NodeField::Position),
    );
    relative_difference(&pc, &pg, &start, &rest_positions(scene))
}

/// Every model: 500 steps of a cube stretched by 30% and released, GPU against one CPU
/// thread. Tolerance 1e-4 of the largest displacement (the criterion): the kernels
/// do the same f32 arithmetic in the same order except where the shader compiler fuses
/// multiply-adds, so the two drift apart only by round-off.
#[test]
fn gpu_matches_cpu_for_every_model() {
    for (label, material) in all_models() {
        let scene = cube_scene(material, 639, 20.0, [1.3, 1.0, 1.0]);
        let tissue = Tissue::from_scene(&scene).unwrap();
        let Some(mut g) = gpu(&tissue) else { return };
        let rel = steps_apart(&scene, &mut g, 500);
        g.check_finite().unwrap();
        eprintln!("{label}: relative difference {rel:e}");
        assert!(
            rel < 1e-4,
            "{label}: GPU and CPU differ by {rel:e} of the motion"
        );
    }
}

/// Writing a range of nodes and reading it back returns the same bits, for every field;
/// neighbour rows written on the GPU change the forces like on the CPU.
#[test]
fn range_writes_round_trip() {
    let scene = cube_scene(MODELS[0].1, 639, 0.0, [1.0; 3]);
    let tissue = Tissue::from_scene(&scene).unwrap();
    let Some(mut g) = gpu(&tissue) else { return };
    let data: Vec<[f32; 4]> = (0..37)
        .map(|i| {
            [
                i as f32 * 0.5,
                -1.25,
                3.0e-7 * i as f32,
                1.0 / (i + 1) as f32,
            ]
        })
        .collect();
    for field in [NodeField::Position, NodeField::Velocity, NodeField::Force] {
        g.write(field, 100, &data).unwrap();
        let mut back = vec![[0.0f32; 4]; 37];
        g.read(field, 100..137, &mut back).unwrap();
        assert_eq!(back, data, "{field:?}");
    }
    assert!(g
        .read(NodeField::Position, 600..700, &mut [[0.0; 4]; 100])
        .is_err());
    // Break node 5's neighbour rows on both backends: the forces agree again.
    let Some(mut g) = gpu(&tissue) else { return };
    let mut c = backend(&scene, Threading::Single);
    let k = tissue.neighbours.k;
    let (idx, w) = tissue.neighbours.row(5);
    let mut w = w.to_vec();
    w[..4].fill(0.0);
    for b in [&mut c as &mut dyn Backend, &mut g] {
        b.write_neighbour_rows(5, idx, &w).unwrap();
        let mut x = read(b, NodeField::Position);
        x[5][0] += 0.01;
        b.write(NodeField::Position, 0, &x).unwrap();
        b.compute_forces();
    }
    let (fc, fg) = (
        read(&mut c, NodeField::Force),
        read(&mut g, NodeField::Force),
    );
    for i in 0..fc.len() {
        let d = norm3([
            fc[i][0] - fg[i][0],
            fc[i][1] - fg[i][1],
            fc[i][2] - fg[i][2],
            0.0,
        ]);
        assert!(d <= 1e-5 * norm3(fc[5]).max(1e-9), "node {i}: {d:e}");
    }
    assert_eq!(k, scene.tissue.neighbours);
}

/// A scene wider than one dispatch dimension: capping x at 2 workgroups makes the 639-node
/// cube use a 2 x 6 grid (the path 4.2 million nodes take with the 65535 limit).
#[test]
fn dispatch_beyond_one_grid_dimension() {
    let (label, material) = MODELS[2];
    let scene = cube_scene(material, 639, 20.0, [1.3, 1.0, 1.0]);
    let tissue = Tissue::from_scene(&scene).unwrap();
    let Some(mut g) = gpu(&tissue) else { return };
    g.set_max_groups_x(2);
    let rel = steps_apart(&scene, &mut g, 100);
    assert!(rel < 1e-4, "{label}: {rel:e}");
}

/// Shape information rows written through the `Backend` trait change the forces the same
/// way on both backends (here: node 7's spring rest lengths, and PBA's inverse moment and
/// rest position and volume of node 9); bad writes are typed errors on both.
#[test]
fn shape_rows_written_on_either_backend_agree() {
    use needlesim::SimError;
    // Rest-length rows are K wide (the scene's default K).
    let k = Tissue::from_scene(&cube_scene(MODELS[0].1, 639, 0.0, [1.0; 3]))
        .unwrap()
        .neighbours
        .k;
    for (label, material, array, offset, bytes) in [
        (
            "msm",
            MODELS[0].1,
            ShapeArray::RestLength,
            7 * k * 4,
            vec![0.02f32; k],
        ),
        // Node 9's rest position moved, with its volume (the w lane) changed.
        (
            "pba",
            MODELS[4].1,
            ShapeArray::RestPosition,
            9 * 16,
            vec![0.01f32, 0.02, 0.03, 2e-6],
        ),
        (
            "pba",
            MODELS[4].1,
            ShapeArray::InverseMoment,
            9 * 4 * needlesim::core::models::mls::MOMENT_ROW,
            vec![1e4f32; 9],
        ),
    ] {
        let scene = cube_scene(material, 639, 0.0, [1.0; 3]);
        let tissue = Tissue::from_scene(&scene).unwrap();
        let mut c = backend(&scene, Threading::Single);
        let data: &[u8] = bytemuck::cast_slice(&bytes);
        let bad = |b: &mut dyn Backend| {
            // An array the model does not have.
            let absent = match array {
                ShapeArray::RestLength => ShapeArray::Rotation,
                _ => ShapeArray::RestLength,
            };
            for (name, off, len) in [(absent, 0, 4), (array, offset + 2, 4), (array, 1 << 30, 4)] {
                let e = b.write_shape_bytes(name, off, &vec![0u8; len]).unwrap_err();
                assert!(matches!(e, SimError::BadShapeWrite { .. }), "{label}: {e}");
            }
        };
        bad(&mut c);
        c.write_shape_bytes(array, offset, data).unwrap();
        let Some(mut g) = gpu(&tissue) else { continue };
        bad(&mut g);
        g.write_shape_bytes(array, offset, data).unwrap();
        push_and_compare_forces(&mut c, &mut g, 8, 1, 0.003, &format!("{label} {array}"));
    }
}

/// The GPU stores the per-slot arrays slot-major (`crates/gpu/src/layout.rs`); through
/// the `Backend` API they still read and write node-major. Rest lengths written at element
/// ranges that start and end inside rows, and whole neighbour rows, read back exactly what
/// the CPU backend holds after the same writes, and the forces then agree to f32
/// round-off (1e-5 of the largest, as above). The writes mix short runs, which the GPU
/// backend batches until the next submit (`crates/gpu/src/scatter.rs`), with a run of
/// 100 whole rows written directly over them, short writes after it, and one element
/// written twice in a batch: the last write wins everywhere, as on the CPU.
#[test]
fn per_slot_arrays_round_trip_at_any_element_range() {
    let scene = cube_scene(MODELS[0].1, 639, 0.0, [1.0; 3]);
    let tissue = Tissue::from_scene(&scene).unwrap();
    let k = tissue.neighbours.k;
    let Some(mut g) = gpu(&tissue) else { return };
    let mut c = backend(&scene, Threading::Single);
    let total = tissue.n_mesh * k * 4;
    let writes = [
        (7 * k + 3, 2 * k + 5),
        (0, 1),
        (k - 1, 2),
        (5 * k, k),
        (3 * k, 2),
        (0, 100 * k + 7),
        (50 * k + 1, 3),
        (50 * k + 2, 1),
        (120 * k, 2 * k),
    ];
    for (w, (first, count)) in writes.into_iter().enumerate() {
        let values: Vec<f32> = (0..count)
            .map(|e| 0.01 + 1e-4 * e as f32 + 1e-6 * w as f32)
            .collect();
        for b in [&mut c as &mut dyn Backend, &mut g] {
            b.write_shape_bytes(
                ShapeArray::RestLength,
                first * 4,
                bytemuck::cast_slice(&values),
            )
            .unwrap();
        }
    }
    // Node 11's row: its slots in reverse order with new weights.
    let row = 11..12;
    let index: Vec<u32> = tissue.neighbours.index[row.start * k..row.end * k]
        .iter()
        .rev()
        .copied()
        .collect();
    let weight: Vec<f32> = (0..k).map(|s| 0.5 + 0.01 * s as f32).collect();
    for b in [&mut c as &mut dyn Backend, &mut g] {
        b.write_neighbour_rows(row.start, &index, &weight).unwrap();
    }
    let (mut on_cpu, mut on_gpu) = (vec![0u8; total], vec![0u8; total]);
    c.read_shape_bytes(ShapeArray::RestLength, 0, &mut on_cpu)
        .unwrap();
    g.read_shape_bytes(ShapeArray::RestLength, 0, &mut on_gpu)
        .unwrap();
    assert!(
        on_cpu == on_gpu,
        "rest lengths differ after the same writes"
    );
    // A read that starts and ends inside rows.
    let (mut a, mut b) = (vec![0u8; 4 * (3 * k + 1)], vec![0u8; 4 * (3 * k + 1)]);
    c.read_shape_bytes(ShapeArray::RestLength, 4 * (2 * k + 5), &mut a)
        .unwrap();
    g.read_shape_bytes(ShapeArray::RestLength, 4 * (2 * k + 5), &mut b)
        .unwrap();
    assert!(a == b, "a partial read differs");
    push_and_compare_forces(&mut c, &mut g, 11, 0, 0.002, "per-slot arrays");
}

/// A shape array stored as the host has it (point based animation's rest positions) takes
/// short writes, which the GPU backend batches until the next submit, a write of more
/// than 1 KiB over them (written directly, after what waits), and short writes after
/// it: it reads back exactly what the CPU backend holds after the same writes.
#[test]
fn short_and_long_shape_writes_land_in_order() {
    let scene = cube_scene(MODELS[4].1, 639, 0.0, [1.0; 3]);
    let tissue = Tissue::from_scene(&scene).unwrap();
    let Some(mut g) = gpu(&tissue) else { return };
    let mut c = backend(&scene, Threading::Single);
    let array = ShapeArray::RestPosition;
    // (first float, floats): rest positions are 4 floats per node.
    let writes = [
        (9 * 4, 4),
        (30 * 4 + 1, 2),
        (0, 100 * 4),
        (9 * 4 + 2, 1),
        (9 * 4 + 2, 1),
    ];
    for (w, (first, count)) in writes.into_iter().enumerate() {
        let values: Vec<f32> = (0..count)
            .map(|e| 0.01 + 1e-4 * e as f32 + 1e-6 * w as f32)
            .collect();
        for b in [&mut c as &mut dyn Backend, &mut g] {
            b.write_shape_bytes(array, first * 4, bytemuck::cast_slice(&values))
                .unwrap();
        }
    }
    let total = 200 * 16;
    let (mut on_cpu, mut on_gpu) = (vec![0u8; total], vec![0u8; total]);
    c.read_shape_bytes(array, 0, &mut on_cpu).unwrap();
    g.read_shape_bytes(array, 0, &mut on_gpu).unwrap();
    assert!(
        on_cpu == on_gpu,
        "rest positions differ after the same writes"
    );
}

/// Moves node `node` by `by` m along `axis` on both backends, evaluates the forces and
/// checks they agree within 1e-5 of the largest (f32 round-off of the force kernels).
fn push_and_compare_forces(
    c: &mut dyn Backend,
    g: &mut GpuBackend,
    node: usize,
    axis: usize,
    by: f32,
    label: &str,
) {
    let mut x = read(c, NodeField::Position);
    x[node][axis] += by;
    for b in [c as &mut dyn Backend, g] {
        b.write(NodeField::Position, 0, &x).unwrap();
        b.compute_forces();
    }
    let (fc, fg) = (read(c, NodeField::Force), read(g, NodeField::Force));
    let scale = max_norm(&fc);
    assert!(scale > 0.0);
    for i in 0..fc.len() {
        let d = norm3([
            fc[i][0] - fg[i][0],
            fc[i][1] - fg[i][1],
            fc[i][2] - fg[i][2],
            0.0,
        ]);
        assert!(d <= 1e-5 * scale, "{label}: node {i} differs by {d:e}");
    }
}

/// Boundary conditions on the GPU: a cube on a roller floor, its top pushed down by a
/// prescribed displacement and one side under a 20 Pa pressure, run 400 steps through the
/// needle crate's `Simulation` on the GPU and on one CPU thread. The positions agree
/// within 1e-3 of the largest displacement and every reaction component within 1e-3 of
/// the largest reaction (f32 round-off in the force kernels; the held components are set
/// by the same host code on both backends), and the held components are exactly held.
/// Measured on lavapipe: 9.4e-6 and 1.7e-6; the margin is for real GPUs' fused
/// multiply-adds.
#[test]
fn boundary_conditions_agree_on_gpu_and_cpu() {
    let scene = Scene::builder()
        .density(1000.0)
        .box_with_spacing([0.0; 3], [0.1; 3], 0.0125)
        .material(Material::debunne(1e4, 0.3))
        .dt_auto()
        .damping(120.0)
        .fixed(
            FixedSelection::new(NodeSet::below(Axis::Y, 0.001))
                .with_components(Components::of(&[Axis::Y]))
                .with_name("floor"),
        )
        .prescribed(
            Prescribed::displacement(NodeSet::above(Axis::Y, 0.099), [0.0, -0.001, 0.0], 0.02)
                .with_components(Components::of(&[Axis::Y]))
                .with_name("plate"),
        )
        .load(LoadSpec::pressure(NodeSet::above(Axis::X, 0.099), 20.0).with_name("side"))
        .build()
        .unwrap();
    // Final positions and reaction forces, or None without a GPU adapter.
    type Outcome = (Vec<[f32; 4]>, Vec<[f64; 3]>);
    let run = |gpu_backend: bool| -> Option<Outcome> {
        let prep = needlesim::needle::Simulation::prepare(&scene).unwrap();
        let backend: Box<dyn Backend> = if gpu_backend {
            Box::new(gpu(&prep.tissue)?)
        } else {
            Box::new(needlesim::CpuBackend::new(prep.tissue.clone(), Threading::Single).unwrap())
        };
        let mut sim = prep.start(backend).unwrap();
        sim.step_n(400).unwrap();
        let reactions = sim.reactions().unwrap().iter().map(|r| r.force).collect();
        Some((read(sim.backend(), NodeField::Position), reactions))
    };
    let Some((pg, rg)) = run(true) else { return };
    let (pc, rc) = run(false).unwrap();
    let rest = rest_positions(&scene);
    // relative_difference scales by the motion of its third argument: the CPU's final one.
    let motion_diff = relative_difference(&pc, &pg, &pc, &rest);
    let scale = rc.iter().flatten().fold(0.0f64, |m, f| m.max(f.abs()));
    let reaction_diff = rc
        .iter()
        .flatten()
        .zip(rg.iter().flatten())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
        / scale;
    eprintln!("positions {motion_diff:.2e}, reactions {reaction_diff:.2e} of {scale:.3e} N: cpu {rc:?} gpu {rg:?}");
    assert!(motion_diff < 1e-3 && reaction_diff < 1e-3);
    for (i, r) in rest.iter().enumerate() {
        if r[1] < 0.001 {
            assert_eq!(pg[i][1], 0.0, "floor node {i}");
        }
        if r[1] > 0.099 {
            assert_eq!(pg[i][1], pc[i][1], "plate node {i}");
        }
    }
}

/// A checkpoint taken on the GPU (needle inside, model with warm-start rotations) and
/// restored onto a fresh GPU backend gives back the same bytes when taken again: every
/// node and shape array goes to the device and comes back whole.
#[test]
fn a_checkpoint_round_trips_through_the_gpu() {
    use needlesim::needle::{Checkpoint, PunctureState, Simulation};
    let mut scene = needlesim::Scene::from_toml_str(
        include_str!("../scenes/needle_insert_extract.toml"),
        std::path::Path::new("scenes"),
    )
    .unwrap();
    scene.material = Material::DebunneMeshfree(DebunneParams::new(1e4, 0.3).with_corotated(true));
    scene.validate().unwrap();
    let prep = Simulation::prepare(&scene).unwrap();
    let Some(b) = gpu(&prep.tissue) else { return };
    let mut sim = prep.start(Box::new(b)).unwrap();
    sim.step_n(1_500).unwrap();
    assert_eq!(sim.state(), PunctureState::Inside);
    let first = sim.checkpoint().unwrap().to_bytes();
    let prep = Simulation::prepare(&scene).unwrap();
    let b = gpu(&prep.tissue).unwrap();
    let c = Checkpoint::from_bytes(&first, std::path::Path::new("mem")).unwrap();
    let mut again = prep.resume(Box::new(b), c).unwrap();
    assert!(again.checkpoint().unwrap().to_bytes() == first);
    again.step_n(10).unwrap();
    assert_eq!(again.steps(), 1_510);
}

/// Kernel profiling: where the device has timestamp queries (lavapipe has), a profiled run
/// reports every kernel of the model, in order, with its dispatch count and a positive
/// time, and steps exactly as an unprofiled one (same bits); a reset forgets the times and
/// profiling off records nothing. Without timestamp queries enabling it is a typed error.
#[test]
fn profiled_runs_time_every_kernel_and_change_nothing() {
    for (label, material) in all_models() {
        let scene = cube_scene(material, 639, 20.0, [1.3, 1.0, 1.0]);
        let tissue = Tissue::from_scene(&scene).unwrap();
        let Some(mut g) = gpu(&tissue) else { return };
        if !g.profiling_supported() {
            eprintln!("{label}: no timestamp queries on {}", g.adapter());
            assert!(matches!(
                g.enable_profiling(true),
                Err(GpuError::ProfilingUnsupported { .. })
            ));
            assert!(g.kernel_times().is_err());
            continue;
        }
        let mut plain = gpu(&tissue).unwrap();
        // Nothing is timed before profiling is on.
        g.step(3);
        plain.step(3);
        g.enable_profiling(true).unwrap();
        assert!(g.profiling());
        // Two batches (200 + 50 steps), then one step the way the needle runs it.
        for b in [&mut g, &mut plain] {
            b.step(250);
            b.compute_forces();
            b.integrate();
        }
        let before = g.readbacks();
        let times = g.kernel_times().unwrap();
        assert_eq!(g.readbacks(), before + 1, "one readback for the times");
        let kernels = if matches!(label, "msm" | "lshm-node") {
            2
        } else {
            3
        };
        assert_eq!(times.len(), kernels, "{label}: {times:?}");
        assert_eq!(times.last().unwrap().name, "integrate");
        for t in &times {
            eprintln!(
                "{label}: {:<32} {:>4} dispatches, {:.4} ms each",
                t.name, t.dispatches, t.mean_ms
            );
            assert_eq!(t.dispatches, 251, "{label}: {t:?}");
            assert!(t.total_ms > 0.0 && t.total_ms.is_finite(), "{label}: {t:?}");
            assert!((t.mean_ms * 251.0 - t.total_ms).abs() <= 1e-9 * t.total_ms);
        }
        assert_eq!(
            read(&mut g, NodeField::Position),
            read(&mut plain, NodeField::Position),
            "{label}: profiling changed the result"
        );
        g.reset_kernel_times();
        g.enable_profiling(false).unwrap();
        g.step(5);
        assert!(g.kernel_times().unwrap().iter().all(|t| t.dispatches == 0));
    }
}

/// More timed dispatches than the timestamp log holds (8192): it is read back on the
/// way and every dispatch is still counted.
#[test]
fn profiling_outlasts_the_timestamp_log() {
    let scene = cube_scene(MODELS[0].1, 639, 20.0, [1.0; 3]);
    let tissue = Tissue::from_scene(&scene).unwrap();
    let Some(mut g) = gpu(&tissue) else { return };
    if g.enable_profiling(true).is_err() {
        return;
    }
    g.step(4300);
    let times = g.kernel_times().unwrap();
    assert!(times
        .iter()
        .all(|t| t.dispatches == 4300 && t.total_ms > 0.0));
    assert_eq!(g.readbacks(), 2, "one full log, then the rest");
}

/// `read_many` gathers ranges and node lists of several fields in one readback, with the
/// same values as separate reads, on the GPU and (one read at a time) on the CPU; reads
/// larger than the staging buffer are split; bad requests are typed errors that read
/// nothing.
#[test]
fn read_many_gathers_in_one_readback() {
    use needlesim::core::NodeSelection;
    use needlesim::SimError;
    let scene = cube_scene(MODELS[2].1, 639, 20.0, [1.3, 1.0, 1.0]);
    let tissue = Tissue::from_scene(&scene).unwrap();
    let mut c = backend(&scene, Threading::Single);
    let Some(mut g) = gpu(&tissue) else { return };
    let n = tissue.state.capacity();
    let list = [7u32, 8, 9, 600, 3, 3];
    for b in [&mut c as &mut dyn Backend, &mut g] {
        b.step(20);
        b.compute_forces();
        let (p, v, f) = (
            read(b, NodeField::Position),
            read(b, NodeField::Velocity),
            read(b, NodeField::Force),
        );
        let (mut a, mut bv, mut cf) = (vec![[0.0; 4]; 37], vec![[0.0; 4]; 1], vec![[0.0; 4]; 6]);
        let before = b.readbacks();
        b.read_many(
            &[
                (NodeField::Position, (100..137).into()),
                (NodeField::Velocity, (5..6).into()),
                (NodeField::Force, NodeSelection::List(&list)),
            ],
            &mut [&mut a, &mut bv, &mut cf],
        )
        .unwrap();
        if b.name().starts_with("gpu") {
            assert_eq!(b.readbacks(), before + 1);
        }
        assert_eq!(a, p[100..137]);
        assert_eq!(bv, v[5..6]);
        assert_eq!(cf, list.map(|i| f[i as usize]));
        // Everything, twice the staging buffer: two readbacks on the GPU.
        let (mut pa, mut va) = (vec![[0.0; 4]; n], vec![[0.0; 4]; n]);
        let before = b.readbacks();
        b.read_many(
            &[
                (NodeField::Position, (0..n).into()),
                (NodeField::Velocity, (0..n).into()),
            ],
            &mut [&mut pa, &mut va],
        )
        .unwrap();
        if b.name().starts_with("gpu") {
            assert_eq!(b.readbacks(), before + 2);
        }
        assert!(pa == p && va == v);
        // Bad requests: another number of outputs, a short output, nodes out of range.
        let before = b.readbacks();
        let e = b
            .read_many(&[(NodeField::Position, (0..2).into())], &mut [])
            .unwrap_err();
        assert!(
            matches!(
                e,
                SimError::BadReadLength {
                    what: "outputs",
                    ..
                }
            ),
            "{e}"
        );
        let e = b
            .read_many(&[(NodeField::Position, (0..2).into())], &mut [&mut a])
            .unwrap_err();
        assert!(
            matches!(e, SimError::BadReadLength { what: "nodes", .. }),
            "{e}"
        );
        let e = b
            .read_many(
                &[(NodeField::Position, NodeSelection::List(&[n as u32]))],
                &mut [&mut bv],
            )
            .unwrap_err();
        assert!(matches!(e, SimError::OutOfRange { .. }), "{e}");
        assert_eq!(b.readbacks(), before);
    }
    assert_eq!(c.readbacks(), 0, "the CPU backend has no readbacks");
}

/// The two-layer test scenes, per model: (label, `[material]` keys, the `stiff` region's
/// material). The region (x <= 5 cm, half the cube) is 4 times as stiff, and every other
/// constant a node row carries differs too (mass-spring damping, Debunne and neo-Hookean
/// hourglass, point based volume stiffness and viscosity, neo-Hookean viscosity), so that a
/// kernel reading any lane of the wrong node or the uniform parameters instead shows.
const LAYERED: [(&str, &str, &str); 7] = [
    (
        "msm",
        "model = \"mass_spring\"\nstiffness = 100.0\nspring_damping = 0.01",
        "{ stiffness = 400.0, spring_damping = 0.04 }",
    ),
    (
        "lshm-node",
        "model = \"local_shape_matching\"\nstiffness = 20.0\nforces = \"node\"",
        "{ stiffness = 80.0 }",
    ),
    (
        "lshm-cluster",
        "model = \"local_shape_matching\"\nstiffness = 20.0\nforces = \"cluster\"",
        "{ stiffness = 80.0 }",
    ),
    (
        "deb",
        "model = \"debunne_meshfree\"\nyoung_modulus = 10000.0\npoisson_ratio = 0.3",
        "{ young_modulus = 40000.0, poisson_ratio = 0.3, hourglass = 0.5 }",
    ),
    (
        "deb-corotated",
        "model = \"debunne_meshfree\"\nyoung_modulus = 10000.0\npoisson_ratio = 0.3\n\
         corotated = true",
        "{ young_modulus = 40000.0, poisson_ratio = 0.3, hourglass = 0.5 }",
    ),
    // Point based animation's hourglass alpha is one for the whole tissue (its rows hold
    // the viscosity instead): the region gives a viscosity.
    (
        "pba",
        "model = \"point_based\"\nyoung_modulus = 10000.0\npoisson_ratio = 0.3\n\
         volume_stiffness = 1000.0\nhourglass = 0.5",
        "{ young_modulus = 40000.0, poisson_ratio = 0.3, volume_stiffness = 4000.0, \
         viscosity = 2.0 }",
    ),
    (
        "nh",
        "model = \"neo_hookean\"\nyoung_modulus = 10000.0\npoisson_ratio = 0.3",
        "{ young_modulus = 40000.0, poisson_ratio = 0.3, hourglass = 0.5, viscosity = 2.0 }",
    ),
];

/// A free 10 cm cube of about 400 nodes stretched by 30% along x, with `material`, and
/// with the `stiff` region of `region` over its x <= 5 cm half when that is given.
fn layered_scene(material: &str, region: Option<&str>) -> Scene {
    let mut toml = format!(
        "name = \"two layers\"\n\
         [tissue]\n\
         density = 1000.0\n\
         geometry = {{ kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], nodes = 400 }}\n\
         [material]\n{material}\n\
         [physics]\n\
         dt = 1e-3\n\
         damping = 20.0\n\
         [initial]\n\
         stretch = [1.3, 1.0, 1.0]\n"
    );
    if let Some(region) = region {
        toml += &format!(
            "[[region]]\n\
             name = \"stiff\"\n\
             geometry = {{ kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.05, 0.1, 0.1] }}\n\
             material = {region}\n"
        );
    }
    Scene::from_toml_str(&toml, std::path::Path::new(".")).unwrap()
}

/// Largest distance between two force fields, over the largest force of the first.
fn force_difference(a: &[[f32; 4]], b: &[[f32; 4]]) -> f64 {
    let d = a
        .iter()
        .zip(b)
        .map(|(x, y)| norm3([x[0] - y[0], x[1] - y[1], x[2] - y[2], 0.0]))
        .fold(0.0, f64::max);
    d / max_norm(a)
}

/// Two materials (`[[region]]`, per-node `node_material` rows) on the GPU, for every
/// model variant: the forces of the stretched two-layer cube, then the positions after
/// 100 and 500 steps, against one CPU thread.
///
/// Tolerances: forces within 1e-5 of the largest force (as `range_writes_round_trip` and
/// `shape_rows_written_on_either_backend_agree`: one kernel evaluation, f32 round-off
/// only), positions within 1e-4 of the largest initial displacement (as
/// `gpu_matches_cpu_for_every_model`: the mixed kernels do the CPU's f32 operations in its
/// order, so only the shader compiler's fused multiply-adds can separate them). Measured
/// on lavapipe: forces 0 (msm) to 1.1e-6 (lshm-node), positions 0 (msm) to 4.4e-6
/// (lshm-cluster).
///
/// So that the test could fail: the two-layer result must differ from the one-material
/// cube (the base material everywhere) by more than 1000 times each tolerance, both on
/// the CPU (its mixed path is taken) and between the GPU's two runs (with the uniform
/// constants the GPU's two-layer run would equal its one-material run). Measured: 0.75 of
/// the largest force (the stiff half's forces are 4 times the soft one's), and 0.25
/// (lshm-cluster) to 0.75 (lshm-node) of the motion after 100 steps.
#[test]
fn gpu_matches_cpu_with_two_materials() {
    const FORCE_TOL: f64 = 1e-5;
    const POSITION_TOL: f64 = 1e-4;
    for (label, material, region) in LAYERED {
        let layered = layered_scene(material, Some(region));
        let single = layered_scene(material, None);
        let tissue = Tissue::from_scene(&layered).unwrap();
        assert!(tissue.shape.node_material().is_some(), "{label}");
        assert!(Tissue::from_scene(&single)
            .unwrap()
            .shape
            .node_material()
            .is_none());
        let Some(mut g) = gpu(&tissue) else { return };
        assert!(
            g.buffers()
                .sizes()
                .iter()
                .any(|(n, _)| *n == "node_material"),
            "{label}"
        );
        let mut gs = gpu(&Tissue::from_scene(&single).unwrap()).unwrap();
        let mut c = backend(&layered, Threading::Single);
        let mut cs = backend(&single, Threading::Single);
        let start = read(&mut c, NodeField::Position);
        // One force evaluation of the stretched cube.
        for b in [
            &mut c as &mut dyn Backend,
            &mut cs as &mut dyn Backend,
            &mut g,
            &mut gs,
        ] {
            b.compute_forces();
        }
        let f = [&mut c as &mut dyn Backend, &mut cs, &mut g, &mut gs]
            .map(|b| read(b, NodeField::Force));
        let force_rel = force_difference(&f[0], &f[2]);
        let force_layers = force_difference(&f[0], &f[1]).min(force_difference(&f[2], &f[3]));
        // 100 steps (the layers' motions still far apart), then 400 more.
        let rest = rest_positions(&layered);
        let (mut rel, mut layers) = (0.0f64, 0.0f64);
        for steps in [100, 400] {
            for b in [&mut c as &mut dyn Backend, &mut cs, &mut g, &mut gs] {
                b.step(steps);
            }
            let x = [&mut c as &mut dyn Backend, &mut cs, &mut g, &mut gs]
                .map(|b| read(b, NodeField::Position));
            rel = rel.max(relative_difference(&x[0], &x[2], &start, &rest));
            layers = layers.max(
                relative_difference(&x[0], &x[1], &start, &rest)
                    .min(relative_difference(&x[2], &x[3], &start, &rest)),
            );
        }
        g.check_finite().unwrap();
        eprintln!(
            "{label}: forces differ by {force_rel:.2e} (layers {force_layers:.2e}), positions \
             by {rel:.2e} (layers {layers:.2e})"
        );
        assert!(
            force_rel < FORCE_TOL,
            "{label}: forces differ by {force_rel:e}"
        );
        assert!(rel < POSITION_TOL, "{label}: positions differ by {rel:e}");
        assert!(
            force_layers > 1e3 * FORCE_TOL && layers > 1e3 * POSITION_TOL,
            "{label}: the layers change too little ({force_layers:e}, {layers:e})"
        );
    }
}

/// The GPU's divergence guard (`Backend::guard`): while nothing is flagged it reads one
/// word back instead of every position and velocity, and when something is (a node made
/// too fast, or not finite) its error is the one the full check gives, node and all.
#[test]
fn the_gpu_guard_reads_a_flag_and_names_what_the_full_check_names() {
    use needlesim::core::backend::check_bounded;
    let scene = cube_scene(Material::mass_spring(20.0), 639, 20.0, [1.3, 1.0, 1.0]);
    let tissue = Tissue::from_scene(&scene).unwrap();
    let Some(mut g) = gpu(&tissue) else { return };
    g.set_n_active(tissue.state.n_active).unwrap();
    let bound = 100.0;
    // The first call with a bound checks everything (the steps before it were watched
    // against no bound): a full read, two readbacks here (positions, then velocities).
    g.step(50);
    g.guard(bound).unwrap();
    let before = g.readbacks();
    g.step(50);
    g.guard(bound).unwrap();
    assert_eq!(g.readbacks() - before, 1, "a sound run reads the flag only");
    // A free node thrown far faster than the bound, then one given a non-finite
    // velocity: flagged by the integration, and the guard's error is the full check's.
    let node = 300;
    for (speed, cause) in [(5e3f32, "100 m/s"), (f32::NAN, "non-finite")] {
        let mut v = [[0.0f32; 4]];
        g.read(NodeField::Velocity, node..node + 1, &mut v).unwrap();
        v[0][1] = speed;
        g.write(NodeField::Velocity, node, &v).unwrap();
        g.step(1);
        let full = check_bounded(&mut g, bound).unwrap_err().to_string();
        let guarded = g.guard(bound).unwrap_err().to_string();
        assert_eq!(guarded, full);
        assert!(guarded.contains(cause), "{guarded}");
    }
}

/// A local force evaluation (`Backend::compute_forces_on`, what the needle's node events
/// ask for, several times per event) leaves co-rotated Debunne's warm-start rotations as
/// they were, on the CPU (which evaluates the few nodes asked for) and on the GPU (which
/// evaluates every node and copies the rotations back), and gives the asked nodes the
/// forces a whole evaluation gives. Before, the GPU refined every node's rotation once
/// more per local evaluation and the CPU the asked nodes' ring: the layered GPU/CPU test
/// of `tests/layers.rs` drifted by three steps at its events when the Tip refreshes were
/// handed over (2026-11-27). A whole evaluation does refine them: the check can fail.
#[test]
fn local_force_evaluations_keep_the_warm_start_rotations() {
    use needlesim::core::models::viscoelastic::{Prony, PronyTerm};
    let elastic = DebunneParams::new(1e4, 0.3).with_corotated(true);
    let visco = elastic.with_viscoelastic(Prony::new(&[PronyTerm { g: 0.3, tau: 0.05 }]));
    for (label, params) in [("co-rotated", elastic), ("co-rotated viscoelastic", visco)] {
        let scene = cube_scene(Material::DebunneMeshfree(params), 639, 5.0, [1.3, 1.0, 1.0]);
        let tissue = Tissue::from_scene(&scene).unwrap();
        let mut backends: Vec<(&str, Box<dyn Backend>)> = vec![(
            "cpu",
            Box::new(needlesim::CpuBackend::new(tissue.clone(), Threading::Single).unwrap()),
        )];
        if let Some(g) = gpu(&tissue) {
            backends.push(("gpu", Box::new(g)));
        }
        for (name, mut b) in backends {
            b.step(30);
            let n = b.n_active();
            let rotations = |b: &mut dyn Backend| {
                let mut out = vec![0u8; n * 16];
                b.read_shape_bytes(ShapeArray::Rotation, 0, &mut out)
                    .unwrap();
                out
            };
            let subset = [(n - 1) as u32, 0, 333, 17];
            // A rotation written just before, with no readback in between (a node the
            // needle adds writes its own): the GPU records it ahead of the copy aside, so
            // it is what comes back.
            let turned = [0.0f32, 0.0, 0.38268343, 0.9238795];
            let mut before = rotations(b.as_mut());
            before[17 * 16..18 * 16].copy_from_slice(bytemuck::cast_slice(&turned));
            b.write_shape_bytes(ShapeArray::Rotation, 17 * 16, bytemuck::cast_slice(&turned))
                .unwrap();
            b.compute_forces_on(&subset);
            let local = read(b.as_mut(), NodeField::Force);
            assert!(
                rotations(b.as_mut()) == before,
                "{label}, {name}: a local evaluation changed the warm-start rotations"
            );
            b.compute_forces();
            let whole = read(b.as_mut(), NodeField::Force);
            assert!(
                rotations(b.as_mut()) != before,
                "{label}, {name}: a whole evaluation left every rotation as it was"
            );
            // The same forces on the asked nodes (bitwise on the CPU; the GPU's two
            // passes are the same kernels on the same data).
            for &i in &subset {
                let i = i as usize;
                assert!(
                    norm3(local[i]) > 0.0,
                    "{label}, {name}: node {i} carries no force"
                );
                assert_eq!(
                    local[i].map(f32::to_bits),
                    whole[i].map(f32::to_bits),
                    "{label}, {name}: node {i}"
                );
            }
        }
    }
}

/// The integration corrections (`core/src/models/consistency.rs`) on the GPU: a resampled
/// ball, where they are large (on the cubes above they nearly vanish), squeezed by 2% and
/// bent (a quadratic field: the gradient's correction is blind to linear ones) and its
/// forces computed on both backends, for each continuum model. Tolerance 1e-4 of the
/// largest force: the same f32 arithmetic up to fused multiply-adds (measured 1e-6 to
/// 2e-6 on lavapipe; with the shader's gradient correction left out, 0.15).
#[test]
fn gpu_and_cpu_agree_on_the_integration_corrections() {
    use needlesim::core::models::consistency::CORRECTION_OFFSET;
    use needlesim::core::scene::{NeoHookeanParams, PointBasedParams};
    use needlesim::CpuBackend;
    let materials = [
        ("deb", Material::debunne(1e4, 0.3)),
        (
            "deb-corotated",
            Material::DebunneMeshfree(DebunneParams::new(1e4, 0.3).with_corotated(true)),
        ),
        ("pba", Material::PointBased(PointBasedParams::new(1e4, 0.3))),
        ("nh", Material::NeoHookean(NeoHookeanParams::new(1e4, 0.3))),
    ];
    for (label, material) in materials {
        let tissue = resampled_ball(material);
        let n = tissue.n_mesh;
        let largest_correction = tissue
            .shape
            .bytes()
            .into_iter()
            .find(|(a, _)| *a == ShapeArray::InverseMoment)
            .map(|(_, bytes)| {
                let rows: &[f32] = bytemuck::cast_slice(bytes);
                rows.chunks(needlesim::core::models::mls::MOMENT_ROW)
                    .take(n)
                    .flat_map(|row| row[CORRECTION_OFFSET..].iter().map(|v| v.abs()))
                    .fold(0.0f32, f32::max)
            })
            .unwrap();
        assert!(largest_correction > 0.0, "{label}: no correction to test");
        let Some(mut g) = gpu(&tissue) else { return };
        let mut c = CpuBackend::new(tissue.clone(), Threading::Single).unwrap();
        let squeezed: Vec<[f32; 4]> = read(&mut c, NodeField::Position)
            .iter()
            .map(|p| {
                // A squeeze and a bend: the correction acts on the quadratic part only.
                let [x, y, z] = [p[0], p[1], p[2]];
                [
                    0.98 * x + 0.5 * y * y,
                    1.01 * y + 0.4 * x * z,
                    1.005 * z - 0.3 * x * y,
                    p[3],
                ]
            })
            .collect();
        for b in [&mut c as &mut dyn Backend, &mut g] {
            b.write(NodeField::Position, 0, &squeezed).unwrap();
            b.compute_forces();
        }
        let (fc, fg) = (
            read(&mut c, NodeField::Force),
            read(&mut g, NodeField::Force),
        );
        let scale = fc.iter().map(|f| norm3(*f)).fold(0.0, f64::max);
        let diff = fc
            .iter()
            .zip(&fg)
            .map(|(a, b)| norm3([a[0] - b[0], a[1] - b[1], a[2] - b[2], 0.0]))
            .fold(0.0, f64::max);
        eprintln!(
            "{label}: largest correction {largest_correction:e}, force difference {:e}",
            diff / scale
        );
        assert!(
            diff < 1e-4 * scale,
            "{label}: forces differ by {:e} of the largest",
            diff / scale
        );
    }
}
