//! Needle insertion (paper section 5) through the `Simulation`: the puncture state
//! machine, node addition and removal along the shaft, the needle force curve, and the
//! GPU backend against the CPU on the paper's scene.

mod common;

use common::{cpu_sim, gpu_sim, same_states_force_difference};

use needlesim::core::models::ShapeArray;
use needlesim::core::{NodeSelection, Vec4};
use needlesim::needle::{PunctureState, Simulation};
use needlesim::needle_output::read_needle_csv;
use needlesim::{
    run_scene, Backend, CpuBackend, NodeField, RunOptions, Scene, SimError, Threading,
};
use std::ops::Range;
use std::path::Path;

const INSERT_EXTRACT: &str = include_str!("../scenes/needle_insert_extract.toml");

/// The insert-extract scene with other keyframes.
fn scene_with_keyframes(keyframes: &str) -> Scene {
    let base = INSERT_EXTRACT
        .split("[[needle.keyframe]]")
        .next()
        .unwrap()
        .to_string();
    Scene::from_toml_str(&(base + keyframes), Path::new("scenes")).unwrap()
}

/// Runs `steps` steps, checking after each that the neighbour lists are mutual (Newton's
/// third law, paper 5.1), and returns the distinct states in order.
fn run_checked(sim: &mut Simulation, steps: u64) -> Vec<PunctureState> {
    let mut seen = vec![sim.state()];
    for _ in 0..steps {
        sim.step().unwrap();
        let n = sim.editor().n_active();
        if let Err((i, j)) = sim.editor().neighbours().check_mutual(n) {
            panic!("step {}: pair {i}-{j} is not mutual", sim.steps());
        }
        if *seen.last().unwrap() != sim.state() {
            seen.push(sim.state());
        }
    }
    seen
}

/// Depth before contact is the same whether or not the run ever touches: a needle stopped
/// 5 mm short of the surface reads -5 mm, as a run that goes on into the tissue reads at
/// the same steps (it was measured from the start tip when there was no contact, so it
/// read +5 mm of travel); a needle aimed past the body measures from its start.
#[test]
fn depth_before_contact_does_not_depend_on_whether_the_tissue_is_reached() {
    let run = |scene: Scene, steps: u64| {
        let mut c = cpu_sim(&scene);
        c.step_n(steps).unwrap();
        let depth: Vec<f64> = c
            .history()
            .iter()
            .map(|s| c.depth_of(s.tip, s.direction))
            .collect();
        (c.entry_point(), depth)
    };
    let short = "[[needle.keyframe]]\naction = \"move\"\ndirection = [1.0, 0.0, 0.0]\n\
                 speed = 0.025\nduration = ";
    // 200 steps of 25 um: the tip ends 5 mm short of the face at x = 0.
    let scene = scene_with_keyframes(&format!("{short}0.2\n"));
    let face = cpu_sim(&scene)
        .rest_positions()
        .iter()
        .map(|p| p[0])
        .fold(f64::INFINITY, f64::min);
    let (entry, never) = run(scene.clone(), 200);
    assert!(entry.is_none());
    let last = *never.last().unwrap();
    let tip = {
        let mut c = cpu_sim(&scene);
        c.step_n(200).unwrap();
        c.history().last().unwrap().tip[0]
    };
    assert!(tip < -0.004, "the tip at x = {tip} m");
    assert!(
        (last - (tip - face)).abs() < 1e-9,
        "never touching: {last} m, face at x = {face} m"
    );
    let (entry, goes_in) = run(scene_with_keyframes(&format!("{short}1.0\n")), 600);
    // The contact point is on the surface as it is when touched, the aim on the rest
    // surface: they differ by how far the face has moved (here 0.25 um of drift of the
    // f32 shape matching at rest, 1% of a step's travel; a sag under gravity elsewhere).
    let entry = entry.unwrap();
    assert!(entry[0].abs() < 1e-6, "entry {entry:?}");
    // The first 150 steps: the short keyframe slows the needle down over its end.
    for (k, (a, b)) in never.iter().zip(&goes_in).take(150).enumerate() {
        assert!((a - b).abs() < 1e-6, "step {k}: {a} m against {b} m");
    }
    // Aimed 0.3 m above the body: no surface on its line, depth from the first step's tip.
    let base = INSERT_EXTRACT.split("[[needle.keyframe]]").next().unwrap();
    let past = base.replace("[-0.11, 0.0513, 0.0487]", "[-0.11, 0.3513, 0.0487]");
    assert_ne!(past, base);
    let past = Scene::from_toml_str(&format!("{past}{short}0.2\n"), Path::new("scenes")).unwrap();
    let aside_start = {
        let mut c = cpu_sim(&past);
        c.step_n(1).unwrap();
        c.history()[0].tip[0]
    };
    let (entry, aside) = run(past, 200);
    assert!(entry.is_none());
    assert!(
        (aside.last().unwrap() - (tip - aside_start)).abs() < 1e-9,
        "{aside:?}"
    );
}

/// The tip reaches 1 mm past the surface (the cone needs about 2 mm to reach 80 degrees
/// with corners 1.2 cm apart) and goes back: Touching, never Inside, and the surface is
/// restored exactly.
#[test]
fn touch_without_puncture_then_retreat_restores_the_surface() {
    let scene = scene_with_keyframes(
        "[[needle.keyframe]]\naction = \"move\"\ndirection = [1.0, 0.0, 0.0]\nspeed = 0.01\nduration = 1.1\n\
         [[needle.keyframe]]\naction = \"extract\"\nspeed = 0.01\nduration = 0.5\n",
    );
    let mut sim = cpu_sim(&scene);
    let triangles = sim.triangles().to_vec();
    let nb = sim.editor().neighbours().clone();
    let shape = sim.editor().shape().clone();
    let n = sim.editor().n_active();
    let states = run_checked(&mut sim, 1600);
    assert_eq!(
        states,
        [
            PunctureState::Outside,
            PunctureState::Touching,
            PunctureState::Outside
        ]
    );
    assert_eq!(sim.triangles(), &triangles[..]);
    assert_eq!(sim.editor().n_active(), n);
    assert!(sim.editor().neighbours() == &nb && sim.editor().shape() == &shape);
}

/// Insertion to 4 cm and full extraction: Outside -> Touching -> Inside -> Outside, nodes
/// added along the shaft and removed one by one, and every neighbour row, shape array and
/// triangle bitwise as at the start.
#[test]
fn insert_and_extract_adds_and_removes_nodes_and_restores_every_array() {
    let scene = Scene::from_toml_str(INSERT_EXTRACT, Path::new("scenes")).unwrap();
    let mut sim = cpu_sim(&scene);
    let triangles = sim.triangles().to_vec();
    let nb = sim.editor().neighbours().clone();
    let shape = sim.editor().shape().clone();
    let states = run_checked(&mut sim, scene.run.steps);
    assert_eq!(
        states,
        [
            PunctureState::Outside,
            PunctureState::Touching,
            PunctureState::Inside,
            PunctureState::Outside
        ]
    );
    let most = sim.history().iter().map(|s| s.needle_nodes).max().unwrap();
    // 4 cm at h = 1.16 cm: the Surface node, 2 or 3 Shaft nodes and the Tip node.
    assert!((4..=6).contains(&most), "{most} needle nodes at most");
    // Nodes leave one at a time: the count never drops by more than one per step while
    // the needle is pulled out at 2.5 cm/s (a thirtieth of the spacing per step).
    for w in sim.history().windows(2) {
        assert!(
            w[0].needle_nodes <= w[1].needle_nodes + 2,
            "step {}",
            w[1].step
        );
    }
    assert_eq!(sim.needle_nodes().len(), 0);
    assert_eq!(sim.triangles(), &triangles[..]);
    assert!(sim.editor().neighbours() == &nb, "neighbour rows differ");
    assert!(sim.editor().shape() == &shape, "shape information differs");
}

/// The force curve of the insert-extract scene, read from the CSV the runner writes:
/// it rises while Touching, drops at puncture, and is negative during extraction. The
/// surface is given a membrane of 0.15 N (three times the cutting force): under the
/// scene's cone angle rule, the sub-grid contact of an 18 G tip on this soft tissue
/// punctures at 0.015 N, below the cutting force, so there is no drop to see.
///
/// The far half of the cube is a region named with a comma and quotes: `needle_force.csv`
/// quotes it and the csv reader gives it back whole.
#[test]
fn force_curve_rises_drops_at_puncture_and_turns_negative_on_extraction() {
    let text = INSERT_EXTRACT.replace(
        "cutting = 0.05 ",
        "puncture_force = 0.15\ncontact_radius = 0.003\ncutting = 0.05 ",
    ) + "\n[[region]]\nname = 'far, \"deep\" half'\n\
         geometry = { kind = \"box\", min = [0.03, 0.0, 0.0], max = [0.1, 0.1, 0.1] }\n\
         material = { stiffness = 20.0 }\n";
    assert!(text.contains("puncture_force"));
    let scene = Scene::from_toml_str(&text, Path::new("scenes")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut opts = RunOptions::new(dir.path());
    opts.threads = Some(1);
    run_scene(&scene, &opts, |_, _| {}).unwrap();
    let table = read_needle_csv(&dir.path().join("needle_force.csv")).unwrap();
    // Its plots are drawn by the command line tool (crates/cli/tests/cli.rs).
    assert!(
        table.iter().any(|r| r.region == "far, \"deep\" half"),
        "the quoted region name does not come back whole"
    );
    struct Row {
        time: f64,
        depth: f64,
        axial: f64,
        state: String,
    }
    let rows: Vec<Row> = table
        .into_iter()
        .map(|r| {
            assert!([r.time_s, r.depth_m, r.axial_force_n, r.lateral_force_n]
                .iter()
                .all(|v| v.is_finite()));
            Row {
                time: r.time_s,
                depth: r.depth_m,
                axial: r.axial_force_n,
                state: r.state,
            }
        })
        .collect();
    assert_eq!(rows.len() as u64, scene.run.steps);
    let touching: Vec<&Row> = rows.iter().filter(|r| r.state == "touching").collect();
    assert!(touching.len() >= 10, "{} touching steps", touching.len());
    // Rises: the resisting force grows with the dimple's depth.
    let (first, last) = (touching[1], *touching.last().unwrap());
    assert!(last.depth > first.depth && last.axial > 0.05 && last.axial > 3.0 * first.axial);
    for w in touching[1..].windows(2) {
        assert!(
            w[1].axial >= w[0].axial - 1e-3,
            "falls at t = {}",
            w[1].time
        );
    }
    // Drops at puncture: the membrane's load beyond the cutting force goes within the
    // tear (30 ms), to less than half of the peak.
    let puncture = rows.iter().position(|r| r.state == "inside").unwrap();
    let after = rows[puncture..]
        .iter()
        .take_while(|r| r.time < rows[puncture].time + 0.05)
        .map(|r| r.axial)
        .fold(f64::INFINITY, f64::min);
    assert!(
        after < 0.5 * last.axial,
        "{after} after a peak of {}",
        last.axial
    );
    // Extraction (from t = 2.5 s while Inside): negative on average and at its extreme.
    let out: Vec<f64> = rows
        .iter()
        .filter(|r| r.time > 2.6 && r.state == "inside")
        .map(|r| r.axial)
        .collect();
    let mean = out.iter().sum::<f64>() / out.len() as f64;
    let min = out.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(
        mean < -0.02 && min < -0.1,
        "extraction mean {mean} N, min {min} N"
    );
    // Depth: negative before contact, 4 cm at the deepest.
    assert!(rows[0].depth < 0.0);
    let deepest = rows.iter().map(|r| r.depth).fold(f64::MIN, f64::max);
    assert!((deepest - 0.04).abs() < 2e-3, "deepest {deepest}");
}

/// Every model runs the paper's experiment (insertion, then the 25-degree rotation) on
/// the CPU: punctured, nodes added, finite forces, no divergence.
#[test]
fn paper_experiment_runs_on_every_model() {
    for m in ["msm", "lshm", "deb", "pba"] {
        let path = format!("scenes/paper_insertion_{m}.toml");
        let scene = Scene::from_file(&path).unwrap();
        let prep = Simulation::prepare(&scene).unwrap();
        let b = CpuBackend::new(prep.tissue.clone(), Threading::Parallel).unwrap();
        let mut sim = prep.start(Box::new(b)).unwrap();
        sim.step_n(scene.run.steps).unwrap();
        sim.backend().check_finite().unwrap();
        let h = sim.history();
        assert_eq!(sim.state(), PunctureState::Inside, "{m}");
        assert!(sim.needle_nodes().len() >= 6, "{m}");
        assert!(h
            .iter()
            .all(|s| s.force.axial.is_finite() && s.force.lateral.is_finite()));
        // The rotation pushes the shaft sideways: the lateral force during the rotation
        // (3 to 4 s) is far above that of the straight insertion.
        let lateral = |a: f64, b: f64| {
            h.iter()
                .filter(|s| s.time > a && s.time <= b)
                .map(|s| s.force.lateral)
                .fold(0.0, f64::max)
        };
        assert!(lateral(3.5, 4.0) > 5.0 * lateral(2.0, 3.0), "{m}");
    }
}

/// The paper's scene (LSHM) on the GPU and on the CPU: the same state and needle node
/// count at every step; the needle force within 0.1% of its scale at every step of the
/// straight insertion; during the rotation, where sticking and slipping nodes switch every
/// few steps and f32 round-off decides on which step, the force averaged over 0.1 s within
/// 5%.
#[test]
fn gpu_and_cpu_agree_on_the_paper_scene() {
    let scene = Scene::from_file("scenes/paper_insertion_lshm.toml").unwrap();
    let Some(mut g) = gpu_sim(&scene) else { return };
    let mut c = cpu_sim(&scene);
    // Through puncture, six Shaft nodes and the first 0.4 s (10 degrees) of the rotation.
    let steps = 3400;
    g.step_n(steps).unwrap();
    c.step_n(steps).unwrap();
    let (hg, hc) = (g.history(), c.history());
    let (scale, straight) = same_states_force_difference(hg, hc, 3.0);
    let mut windowed = 0.0f64;
    for (a, b) in hg.chunks(100).zip(hc.chunks(100)) {
        let mean = |h: &[needlesim::needle::NeedleSample]| {
            h.iter().map(|s| s.force.axial).sum::<f64>() / h.len() as f64
        };
        windowed = windowed.max((mean(a) - mean(b)).abs() / scale);
    }
    eprintln!(
        "force scale {scale:.3} N; largest difference {straight:.2e} (straight), \
         {windowed:.2e} (0.1 s means)"
    );
    assert!(straight < 1e-3 && windowed < 0.05, "{straight} {windowed}");
}

/// The liver scene (co-rotated Debunne with hourglass control, per-length friction,
/// cutting and the force puncture rule) at 10 mm spacing, on the GPU and on the CPU,
/// through puncture and the first 2.4 cm of insertion: the same puncture state and needle
/// node count at every step, the axial force within 2% of the largest force at every step
/// and within 5% averaged over 0.1 s (measured on lavapipe: 1.2e-2 per step, 3.2e-4 over
/// 0.1 s). The per-step margin is the tissue's: at this spacing the block's weakly damped
/// modes (mass-proportional damping only) ring at up to about 0.8% of the force during
/// insertion, and f32 rounding shifts their phase between the backends over seconds, so
/// two runs differ per step by up to twice that while their means agree.
#[test]
fn gpu_and_cpu_agree_on_the_liver_scene() {
    let text = include_str!("../scenes/liver_insertion.toml")
        .replace("spacing = 0.005 }", "spacing = 0.01 }");
    let scene = Scene::from_toml_str(&text, Path::new("scenes")).unwrap();
    let Some(mut g) = gpu_sim(&scene) else { return };
    let mut c = cpu_sim(&scene);
    let steps = (6.0 / c.dt()) as u64;
    g.step_n(steps).unwrap();
    c.step_n(steps).unwrap();
    let (hg, hc) = (g.history(), c.history());
    assert!(
        hc.iter().any(|s| s.state == PunctureState::Inside),
        "the run must reach puncture"
    );
    let (scale, per_step) = same_states_force_difference(hg, hc, f64::INFINITY);
    let window = (0.1 / c.dt()).ceil() as usize;
    let mut windowed = 0.0f64;
    for (a, b) in hg.chunks(window).zip(hc.chunks(window)) {
        let mean = |h: &[needlesim::needle::NeedleSample]| {
            h.iter().map(|s| s.force.axial).sum::<f64>() / h.len() as f64
        };
        windowed = windowed.max((mean(a) - mean(b)).abs() / scale);
    }
    eprintln!(
        "liver: force scale {scale:.3} N; largest difference {per_step:.2e} (per step), \
         {windowed:.2e} (0.1 s means)"
    );
    assert!(per_step < 0.02 && windowed < 0.05, "{per_step} {windowed}");
}

/// A needle jerked through the tissue (3 cm per step in, then out as fast, with no speed
/// ramp: a haptic device's glitch): several nodes are added, and removed, within one step;
/// the lists stay mutual and the arrays come back.
#[test]
fn fast_needle_adds_and_removes_several_nodes_per_step() {
    let scene = scene_with_keyframes(
        "speed_ramp = 0.0\n[[needle.keyframe]]\naction = \"move\"\ndirection = [1.0, 0.0, 0.0]\nspeed = 0.5\nduration = 0.02\n\
         [[needle.keyframe]]\naction = \"move\"\ndirection = [1.0, 0.0, 0.0]\nspeed = 30.0\nduration = 0.002\n\
         [[needle.keyframe]]\naction = \"extract\"\nspeed = 30.0\nduration = 0.004\n",
    );
    let mut sim = cpu_sim(&scene);
    let nb = sim.editor().neighbours().clone();
    let shape = sim.editor().shape().clone();
    let states = run_checked(&mut sim, 40);
    assert_eq!(states.last(), Some(&PunctureState::Outside), "{states:?}");
    assert!(states.contains(&PunctureState::Inside), "{states:?}");
    let h = sim.history();
    let jump_in = h
        .windows(2)
        .map(|w| w[1].needle_nodes as i64 - w[0].needle_nodes as i64);
    let (most_in, most_out) = jump_in.fold((0, 0), |(a, b), d| (a.max(d), b.min(d)));
    assert!(
        most_in >= 2 && most_out <= -2,
        "per-step changes {most_in} / {most_out}"
    );
    assert!(sim.editor().neighbours() == &nb && sim.editor().shape() == &shape);
}

/// The caller can drive the needle instead of a script (a haptic device): setting the
/// script's poses by hand every step gives the same run, bit for bit.
#[test]
fn set_pose_every_step_reproduces_the_script() {
    let scene = Scene::from_toml_str(INSERT_EXTRACT, Path::new("scenes")).unwrap();
    let cfg = needlesim::needle::NeedleConfig::from_table(scene.needle.as_ref().unwrap()).unwrap();
    let script = cfg.script().unwrap().unwrap();
    let mut scripted = cpu_sim(&scene);
    let mut driven = cpu_sim(&scene);
    let dt = driven.dt();
    for _ in 0..1500 {
        let pose = script.pose_at(driven.time() + dt);
        driven.set_pose(pose.base(), pose.direction()).unwrap();
        driven.step().unwrap();
        scripted.step().unwrap();
    }
    let first = driven
        .history()
        .iter()
        .zip(scripted.history())
        .position(|(a, b)| a != b);
    if let Some(i) = first {
        panic!(
            "step {i}: {:?}\n{:?}",
            driven.history()[i],
            scripted.history()[i]
        );
    }
    assert_eq!(driven.state(), PunctureState::Inside);
}

/// A CPU backend that counts its read calls as [`Backend::readbacks`]: each `read`,
/// `read_nodes`, `read_many` and `read_shape_bytes` is one, as each is one readback on the
/// GPU backend when it reads fewer nodes than the backend holds. It lets the readback
/// budget of a needle step be checked without a GPU.
struct CountingReads {
    inner: CpuBackend,
    reads: u64,
}

impl Backend for CountingReads {
    fn name(&self) -> String {
        self.inner.name()
    }
    fn capacity(&self) -> usize {
        self.inner.capacity()
    }
    fn n_active(&self) -> usize {
        self.inner.n_active()
    }
    fn set_n_active(&mut self, n: usize) -> Result<(), SimError> {
        self.inner.set_n_active(n)
    }
    fn compute_forces(&mut self) {
        self.inner.compute_forces()
    }
    fn compute_forces_on(&mut self, nodes: &[u32]) {
        self.inner.compute_forces_on(nodes)
    }
    fn integrate(&mut self) {
        self.inner.integrate()
    }
    fn step(&mut self, n: u64) {
        self.inner.step(n)
    }
    fn steps_taken(&self) -> u64 {
        self.inner.steps_taken()
    }
    fn set_steps_taken(&mut self, steps: u64) {
        self.inner.set_steps_taken(steps)
    }
    fn read(
        &mut self,
        field: NodeField,
        range: Range<usize>,
        out: &mut [Vec4],
    ) -> Result<(), SimError> {
        self.reads += 1;
        self.inner.read(field, range, out)
    }
    fn read_nodes(
        &mut self,
        field: NodeField,
        nodes: &[u32],
        out: &mut [Vec4],
    ) -> Result<(), SimError> {
        self.reads += 1;
        self.inner.read_nodes(field, nodes, out)
    }
    fn read_many(
        &mut self,
        requests: &[(NodeField, NodeSelection<'_>)],
        outs: &mut [&mut [Vec4]],
    ) -> Result<(), SimError> {
        self.reads += 1;
        self.inner.read_many(requests, outs)
    }
    fn readbacks(&self) -> u64 {
        self.reads
    }
    fn position_frame(&self) -> needlesim::core::frame::PositionFrame {
        self.inner.position_frame()
    }
    fn write(&mut self, field: NodeField, first: usize, data: &[Vec4]) -> Result<(), SimError> {
        self.inner.write(field, first, data)
    }
    fn write_neighbour_rows(
        &mut self,
        first: usize,
        index: &[u32],
        weight: &[f32],
    ) -> Result<(), SimError> {
        self.inner.write_neighbour_rows(first, index, weight)
    }
    fn write_shape_bytes(
        &mut self,
        array: ShapeArray,
        offset: usize,
        data: &[u8],
    ) -> Result<(), SimError> {
        self.inner.write_shape_bytes(array, offset, data)
    }
    fn read_shape_bytes(
        &mut self,
        array: ShapeArray,
        offset: usize,
        out: &mut [u8],
    ) -> Result<(), SimError> {
        self.reads += 1;
        self.inner.read_shape_bytes(array, offset, out)
    }
}

/// Readbacks of each of the next `steps` steps, with whether the step edited the needle
/// nodes (their count changed) or ran the divergence guard.
fn readbacks_per_step(sim: &mut Simulation, steps: u64, check_every: u64) -> Vec<(u64, bool)> {
    (0..steps)
        .map(|_| {
            let (before, nodes) = (sim.readbacks(), sim.needle_nodes().len());
            sim.step().unwrap();
            let irregular =
                sim.needle_nodes().len() != nodes || sim.steps().is_multiple_of(check_every);
            (sim.readbacks() - before, irregular)
        })
        .collect()
}

fn summary(counts: &[(u64, bool)]) -> String {
    let total: u64 = counts.iter().map(|c| c.0).sum();
    let mut hist = std::collections::BTreeMap::new();
    for c in counts {
        *hist.entry(c.0).or_insert(0) += 1;
    }
    format!(
        "{:.3} readbacks per step over {} steps (readbacks: steps {hist:?})",
        total as f64 / counts.len() as f64,
        counts.len()
    )
}

/// Readbacks of an inserted needle step, on the CPU (counted read calls) and on the GPU
/// (counted readbacks). A step that edits no needle node reads back once (issue 46, item
/// 4): the needle nodes' forces after the force evaluation, with the positions of the
/// mesh nodes around the tip (and of the contact patch's) in one `read_many`. Their
/// positions and velocities at the start of the step are the host's own integration of
/// what it wrote in the last one (`Simulation` module docs, "One readback"). Before, a
/// step read back twice (four times before issue 20). Steps that add, remove or refresh
/// needle nodes read more (a node edit settles the new nodes in equilibrium: a few force
/// evaluations, each read back; the neighbourhood is read once per settle, not at every
/// re-placement), and so does the divergence guard every `check_every` steps. Here a
/// Tip refresh reads back 8 or 9 times (7 before refreshes were handed over, 2026-11-27)
/// and a node addition 15 (they were 15 and 35 before
/// the editor kept its reads during a settle, the reads of an addition and of the Tip's
/// removal were merged and a refresh kept the velocities it knows): at most 18 per step
/// is asserted, the room of three more force evaluations in a settle.
#[test]
fn an_inserted_needle_step_reads_back_once() {
    // The insert-extract scene with 2,000 nodes instead of 639: the far-side test's reach
    // (two spacings and a grid cell) leaves the tip clear of every face from 3 to 5 cm
    // deep; at 639 nodes (14 mm apart) it is within reach of the entry face or the far
    // one for most of the way, and such a step reads the candidate corners too.
    let text = INSERT_EXTRACT.replace("nodes = 639", "nodes = 2000");
    let scene = Scene::from_toml_str(&text, Path::new("scenes")).unwrap();
    let check_every = scene.physics.check_every;
    let prep = Simulation::prepare(&scene).unwrap();
    let b = CountingReads {
        inner: CpuBackend::new(prep.tissue.clone(), Threading::Single).unwrap(),
        reads: 0,
    };
    let mut sims = vec![("cpu", prep.start(Box::new(b)).unwrap())];
    if let Some(g) = gpu_sim(&scene) {
        sims.push(("gpu", g));
    }
    for (name, sim) in &mut sims {
        // 4.25 cm in, advancing at 2.5 cm/s (clear of the far-side test's reach of the
        // entry and far faces, both within about 4 cm); then (from step 2000) held still.
        sim.step_n(1700).unwrap();
        assert_eq!(sim.state(), PunctureState::Inside);
        let moving = readbacks_per_step(sim, 200, check_every);
        sim.step_n(2100 - 1900).unwrap();
        let held = readbacks_per_step(sim, 200, check_every);
        assert_eq!(sim.state(), PunctureState::Inside);
        eprintln!("{name}: advancing {}", summary(&moving));
        eprintln!("{name}: held {}", summary(&held));
        // Held: every step but the guard's reads back once.
        for (k, &(n, irregular)) in held.iter().enumerate() {
            assert!(irregular || n == 1, "{name}: held step {k}: {n} readbacks");
        }
        // Advancing: once, but a node edit or Tip refresh (which leaves the number of
        // nodes as it was) every few dozen steps reads more.
        let over = moving.iter().filter(|c| c.0 > 1).count();
        let mean = moving.iter().map(|c| c.0).sum::<u64>() as f64 / moving.len() as f64;
        assert!(over <= 12 && mean <= 1.5, "{name}: {}", summary(&moving));
        let most = moving.iter().map(|c| c.0).max().unwrap_or(0);
        assert!(most <= 18, "{name}: an edit step read {most} times");
    }
}

/// The host's integration of the needle nodes (what lets a step read back once) is the
/// CPU backend's, bit for bit: a run that makes every step read the nodes back (mutable
/// access to the backend drops the host's copy) records the same force history and ends
/// in the same state, for the per-length and the paper's friction models, through the
/// puncture, insertion, hold and extraction.
#[test]
fn the_host_integration_of_needle_nodes_is_the_backends() {
    let paper = INSERT_EXTRACT.replace("cutting = 0.05 ", "# ").replace(
        "friction = { coefficient = 0.3 }",
        "friction = { model = \"paper\", static_threshold = 0.02, dynamic = 0.3, viscous = 0.5 }",
    );
    for text in [INSERT_EXTRACT.to_string(), paper] {
        let scene = Scene::from_toml_str(&text, Path::new("scenes")).unwrap();
        let mut a = cpu_sim(&scene);
        let mut b = cpu_sim(&scene);
        for _ in 0..4500 {
            a.step().unwrap();
            let _ = b.backend();
            b.step().unwrap();
        }
        assert!(a.readbacks() == 0 && a.history().len() == 4500);
        for (x, y) in a.history().iter().zip(b.history()) {
            assert_eq!(
                x.force.axial.to_bits(),
                y.force.axial.to_bits(),
                "step {}",
                x.step
            );
            assert_eq!(x.tissue_depth, y.tissue_depth, "step {}", x.step);
        }
        let n = a.backend().n_active();
        assert_eq!(n, b.backend().n_active());
        for field in [NodeField::Position, NodeField::Velocity] {
            let (mut pa, mut pb) = (vec![[0.0f32; 4]; n], vec![[0.0f32; 4]; n]);
            a.backend().read(field, 0..n, &mut pa).unwrap();
            b.backend().read(field, 0..n, &mut pb).unwrap();
            assert!(pa == pb, "{field:?}");
        }
    }
}

/// Advancing again after a partial withdrawal (the liver scene at 10 mm spacing: 4 s in,
/// 1.5 s out, then in again): the Tip node the withdrawal took off goes on again behind
/// the crack front, handed over like a Shaft node and without friction or normal load of
/// its own, so no step in the 50 ms after it changes the axial or the lateral force by
/// more than 2% of the axial force there (measured: 0.90% and 0.05%; before, 2.5% and
/// 4.5%: the new node took its share of the shaft's friction and changed its neighbours'
/// rows at once). On the 5 mm liver the Shaft node behind it slid at 0.45 m/s and the
/// force rang at about 280 Hz for 20 ms: 5 steps over 5% of the force and 3.0% buzz,
/// now none and 2.5% (the largest at the later withdrawal; `force_audit.py`, dev machine,
/// 2026-11-27).
#[test]
fn advancing_again_after_a_withdrawal_is_smooth() {
    let keyframes = |t: String| {
        let i = t.find("[[needle.keyframe]]").unwrap();
        let j = t.find("[run]").unwrap();
        let moves = "[[needle.keyframe]]\naction = \"move\"\ndirection = [1.0, 0.0, 0.0]\n\
                     speed = 0.005\nduration = 4.0\n\n[[needle.keyframe]]\naction = \
                     \"extract\"\nspeed = 0.005\nduration = 1.5\n\n[[needle.keyframe]]\n\
                     action = \"move\"\ndirection = [1.0, 0.0, 0.0]\nspeed = 0.005\n\
                     duration = 1.5\n\n";
        format!("{}{}{}", &t[..i], moves, &t[j..])
    };
    let (c, depth) = liver_run(&keyframes, 7.0);
    let h = c.history();
    let dt = c.dt();
    // The turn: the first advancing step after the withdrawal.
    let r = (1..h.len())
        .find(|&k| h[k].time > 5.2 && depth[k] > depth[k - 1] + 1e-9)
        .expect("advancing again");
    assert_eq!(h[r].state, PunctureState::Inside);
    // The Tip node going on again (the stack grows) once the tip is half a spacing past
    // the last node.
    let r = (r..h.len())
        .find(|&k| h[k].needle_nodes > h[k - 1].needle_nodes)
        .expect("the Tip node put on again");
    let window = (0.05 / dt) as usize;
    let level = h[r - 1].force.axial.abs();
    let worst = h[r - 1..(r + window).min(h.len())]
        .windows(2)
        .map(|w| (w[1].force.axial - w[0].force.axial).abs())
        .fold(0.0, f64::max);
    let lateral = h[r - 1..(r + window).min(h.len())]
        .windows(2)
        .map(|w| (w[1].force.lateral - w[0].force.lateral).abs())
        .fold(0.0, f64::max);
    eprintln!(
        "Tip node on again at {:.4} s: largest step {:.3}% of {level:.3} N, lateral step {lateral:.4} N, {} needle nodes",
        h[r].time,
        100.0 * worst / level,
        h[r].needle_nodes
    );
    assert!(worst < 0.02 * level, "step {worst} N at {level} N");
    assert!(
        lateral < 0.02 * level,
        "lateral step {lateral} N at {level} N"
    );
}

/// A Tip refresh (the Tip node taken off and put on again at the tip, every tenth of a
/// spacing of cut) is handed over like a Shaft node event, within the time to the next
/// refresh (`needlesim::needle::handover`): the force does not kick or ring after it. On
/// the liver scene at 10 mm spacing (5 mm/s), over the refreshes from 0.3 s after the
/// puncture, the largest excursion of the axial force from its 20 ms centred mean in the
/// 20 ms after a refresh is at most 1% of the force (measured 0.48%; 2.31% before
/// refreshes were handed over, when a refresh moved the shaft's friction by up to 50 mN
/// within 3 ms on the 5 mm liver).
#[test]
fn tip_refreshes_leave_the_force_smooth() {
    use needlesim::needle::NodeRole;
    let text = include_str!("../scenes/liver_insertion.toml")
        .replace("spacing = 0.005 }", "spacing = 0.01 }");
    let scene = Scene::from_toml_str(&text, Path::new("scenes")).unwrap();
    let mut c = cpu_sim(&scene);
    let steps = (6.0 / c.dt()) as u64;
    // The steps whose Tip node was put on again where the stack kept its size.
    let mut refreshes = Vec::new();
    let tip_rest = |c: &Simulation| {
        let last = c.needle_nodes().last()?;
        (last.role == NodeRole::Tip).then(|| {
            (
                c.needle_nodes().len(),
                c.editor().rest_position(last.index as usize),
            )
        })
    };
    let mut before = tip_rest(&c);
    for k in 0..steps {
        c.step().unwrap();
        let now = tip_rest(&c);
        if let (Some(a), Some(b)) = (before, now) {
            if a.0 == b.0 && a.1 != b.1 {
                refreshes.push(k as usize);
            }
        }
        before = now;
    }
    let h = c.history();
    let f: Vec<f64> = h.iter().map(|s| s.force.axial).collect();
    let w = (0.02 / c.dt()).round() as usize;
    let punctured = (1..h.len())
        .find(|&k| h[k].state == PunctureState::Inside && h[k - 1].state != PunctureState::Inside)
        .expect("a puncture");
    let settled = punctured + (0.3 / c.dt()) as usize;
    let mut worst = (0.0f64, 0usize);
    let mut counted = 0;
    for &r in refreshes
        .iter()
        .filter(|&&r| r > settled && r + 2 * w < f.len())
    {
        counted += 1;
        for i in r..r + w {
            let mean = f[i - w / 2..i + w / 2].iter().sum::<f64>() / (2 * (w / 2)) as f64;
            let off = (f[i] - mean).abs() / f[r].abs();
            if off > worst.0 {
                worst = (off, r);
            }
        }
    }
    eprintln!(
        "{} refreshes, {counted} after the puncture settled: largest excursion {:.3}% of the force (refresh at {:.4} s)",
        refreshes.len(),
        100.0 * worst.0,
        h[worst.1].time
    );
    assert!(counted >= 5, "only {counted} refreshes to look at");
    assert!(
        worst.0 < 0.01,
        "{:.3}% after the refresh at step {}",
        100.0 * worst.0,
        worst.1
    );
}

/// The liver scene at 10 mm spacing, inserted 7 s at 5 mm/s, held 1 s and pulled back for
/// the rest: its force history with the tip's depth per step.
fn liver_run(edit: &dyn Fn(String) -> String, seconds: f64) -> (Simulation, Vec<f64>) {
    let text = edit(
        include_str!("../scenes/liver_insertion.toml")
            .replace("spacing = 0.005 }", "spacing = 0.01 }"),
    );
    let scene = Scene::from_toml_str(&text, Path::new("scenes")).unwrap();
    let mut c = cpu_sim(&scene);
    c.step_n((seconds / c.dt()) as u64).unwrap();
    let depth = c
        .history()
        .iter()
        .map(|s| c.depth_of(s.tip, s.direction))
        .collect();
    (c, depth)
}

/// The puncture releases the membrane's load over the tear (the scene's 4 ms), not in one step; the
/// axial force is never negative while the needle advances; at the turn from holding to
/// withdrawing, the friction reverses through the sheath's pre-sliding: no step in the
/// 50 ms after it changes the force by more than 2% of the force there (measured: 0.10%;
/// largest step of the tear 0.11 N of 1 N, at this 10 mm spacing),
/// and the force falls continuously from pushing to pulling: the sheath's pre-sliding
/// (`2 mu q / k`, 4.3 mm at this spacing) and the tissue dragged along let go over about
/// 5 mm of withdrawal, so it pulls 1.5 s (7.5 mm) after the turn.
#[test]
fn liver_puncture_tears_and_the_reversal_is_continuous() {
    let (c, depth) = liver_run(&|t| t, 9.5);
    let h = c.history();
    let dt = c.dt();
    let p = h
        .iter()
        .position(|s| s.state == PunctureState::Inside)
        .expect("punctured");
    let peak = h[p.saturating_sub(1)].force.axial;
    assert!((0.95..=1.05).contains(&peak), "puncture at 1 N: {peak}");
    let worst_drop = h[p.saturating_sub(1)..]
        .windows(2)
        .map(|w| w[0].force.axial - w[1].force.axial)
        .fold(0.0, f64::max);
    assert!(
        worst_drop < 0.2 * peak,
        "the membrane tears over several steps: largest drop {worst_drop} N"
    );
    // Within 30 ms the load is released down to the cutting force plus the friction.
    let after = h[p + (0.03 / dt) as usize].force.axial;
    assert!(after < 0.7 * peak, "released: {after}");
    for (k, w) in h.windows(2).enumerate() {
        if depth[k + 1] > depth[k] + 1e-9 && w[1].state == PunctureState::Inside {
            assert!(
                w[1].force.axial >= 0.0,
                "negative while advancing at {}",
                w[1].time
            );
        }
    }
    // The reversal: the first withdrawing step after the hold.
    let r = (1..h.len())
        .find(|&k| h[k].time > 7.5 && depth[k] < depth[k - 1] - 1e-9)
        .expect("withdrawn");
    let level = h[r].force.axial.abs();
    let window = (0.05 / dt) as usize;
    let worst = h[r - 1..(r + window).min(h.len())]
        .windows(2)
        .map(|w| (w[1].force.axial - w[0].force.axial).abs())
        .fold(0.0, f64::max);
    eprintln!(
        "largest drop at puncture {worst_drop:.4} N of {peak:.3} N; reversal: largest step {:.3}% of {level:.3} N",
        100.0 * worst / level
    );
    assert!(worst < 0.02 * level, "reversal step {worst} N at {level} N");
    let end = h.last().unwrap().force.axial;
    assert!(
        end < 0.0,
        "pulled back, the friction resists extraction: {end}"
    );
}

/// Node removals on the way out hand their change of the tissue's forces over in 40 ms
/// ([`needlesim::needle::handover`]): across every removal while the needle is pulled
/// out, the Tip node's included, no step in the 20 steps after it changes the axial
/// force by more than 1% of the local force (the mean |force| over 50 ms, at least a
/// tenth of the largest, as the force audit counts). Measured (CPU, 2026-11-27): 0.28%;
/// 2.14% when the Tip node's removal (the first, where the needle is pulled back off
/// the crack front) was not handed over (the Shaft node behind it jerked back), 3.23%
/// without any handover (the restored neighbour rows changed the elastic forces at
/// once); the audit counts a jump at 5%.
#[test]
fn removals_on_the_way_out_leave_the_force_continuous() {
    let (c, depth) = liver_run(&|t| t, 15.0);
    let h = c.history();
    let dt = c.dt();
    let f: Vec<f64> = h.iter().map(|s| s.force.axial).collect();
    let peak = f.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let w = (0.025 / dt) as usize;
    let local = |k: usize| {
        let (a, b) = (k.saturating_sub(w), (k + w).min(f.len()));
        (f[a..b].iter().map(|x| x.abs()).sum::<f64>() / (b - a) as f64).max(0.1 * peak)
    };
    let mut removals = 0;
    let (mut worst, mut lateral): (f64, f64) = (0.0, 0.0);
    for k in 1..h.len() - 21 {
        let out = depth[k] < depth[k - 1] - 1e-9;
        if out && h[k].needle_nodes < h[k - 1].needle_nodes && h[k].state == PunctureState::Inside {
            removals += 1;
            for j in k - 1..k + 20 {
                worst = worst.max((f[j + 1] - f[j]).abs() / local(j));
            }
            lateral = lateral.max((h[k].force.lateral - h[k - 1].force.lateral).abs());
        }
    }
    eprintln!(
        "{removals} removals on the way out; largest step after one {:.2}% of the local force, \
         lateral step at one {:.1} mN",
        100.0 * worst,
        1e3 * lateral
    );
    // The removed node's push on the shaft leaves the lateral force with its length
    // (its share), not at once, and the Tip node's removal is handed over: measured
    // 0.2 mN at this spacing (of a lateral force of about 0.1 N), 29.2 mN before the Tip
    // node's removal was handed over, 74.5 mN when the whole push was counted to the end.
    assert!(
        lateral < 0.01,
        "a removal stepped the lateral force by {lateral} N"
    );
    assert!(removals >= 3, "{removals} removals");
    assert!(
        worst < 0.01,
        "a removal stepped the force by {:.2}%",
        100.0 * worst
    );
}

/// With the friction coefficient 0 the needle force after puncture is the cutting force
/// alone, whatever the node events: within 2% of 0.3 N on every advancing step from 20 ms
/// after the puncture to the end of the insertion (measured: 0.0%).
#[test]
fn liver_without_friction_feels_only_the_cutting_force() {
    let (c, depth) = liver_run(
        &|t| t.replace("coefficient = 0.3, grip", "coefficient = 0.0, grip"),
        7.0,
    );
    let h = c.history();
    let p = h
        .iter()
        .position(|s| s.state == PunctureState::Inside)
        .expect("punctured");
    let from = p + (0.02 / c.dt()) as usize;
    let mut checked = 0;
    for k in from..h.len() - 1 {
        if depth[k + 1] > depth[k] + 1e-9 {
            let f = h[k].force.axial;
            assert!((f - 0.3).abs() < 0.006, "{f} N at {} s", h[k].time);
            checked += 1;
        }
    }
    let worst = (from..h.len() - 1)
        .filter(|&k| depth[k + 1] > depth[k] + 1e-9)
        .map(|k| (h[k].force.axial - 0.3).abs() / 0.3)
        .fold(0.0, f64::max);
    eprintln!(
        "friction off: within {:.3}% of the cutting force",
        100.0 * worst
    );
    assert!(checked > 1000, "{checked} rows");
}

/// A spin keyframe (360 degrees per second while inserting, `spin` on the move) turns
/// the needle about its axis; the shaft's friction then has a circumferential part (a
/// torque on the needle) and its axial part is lower than without the spin, as Coulomb
/// friction on the helical path predicts: at 5 mm/s with an 18 G shaft the axial share
/// is 5 / hypot(5, 4.0) = 0.78 in steady slip (measured, 10 mm spacing: 0.72, the tissue
/// being dragged along lowers the axial sliding speed).
#[test]
fn spinning_the_needle_lowers_the_axial_friction() {
    let friction = |spin: bool| {
        let (c, _) = liver_run(
            &|t| match spin {
                true => t.replacen("duration = 7.0\n", "duration = 7.0\nspin = 360.0\n", 1),
                false => t,
            },
            6.0,
        );
        let s = *c.history().last().unwrap();
        (s.force.axial - s.force.tip, s.force.torque)
    };
    let (still, t0) = friction(false);
    let (spun, t1) = friction(true);
    assert!(t0 == 0.0 && t1 > 0.0, "{t0} {t1}");
    let ratio = spun / still;
    eprintln!("friction {still:.4} N, spinning {spun:.4} N: x{ratio:.3}");
    assert!((0.6..0.85).contains(&ratio), "{spun} / {still} = {ratio}");
}

/// The shipped insert/pause/extract scene with its default speed ramp: when the
/// extraction starts, no step changes the axial force by more than 5% of the force there
/// (measured, CPU, 2026-11-27: 3.9%, 5.3 mN of its 0.135 N mean over the 90 ms around
/// the start; 12.4% with
/// `speed_ramp = 0`, the sheath's dashpot answering an instant change of speed).
#[test]
fn the_extraction_starts_without_a_force_step() {
    let scene = Scene::from_toml_str(INSERT_EXTRACT, Path::new("scenes")).unwrap();
    let mut sim = cpu_sim(&scene);
    sim.step_n((2.56 / sim.dt()) as u64).unwrap();
    let h: Vec<_> = sim
        .history()
        .iter()
        .filter(|s| s.time > 2.47 && s.time < 2.56)
        .map(|s| s.force.axial)
        .collect();
    let mean = h.iter().map(|f| f.abs()).sum::<f64>() / h.len() as f64;
    let step = h
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0, f64::max);
    eprintln!("extraction start: largest step {step:.5} N over a mean force {mean:.4} N");
    assert!(step < 0.05 * mean, "{step} N against {mean} N");
}

/// A needle that turns from holding still to withdrawing at once (`speed_ramp = 0`): in
/// the first step the sheath around the shaft (stiffness `K` per unit length, set here,
/// and no viscosity) takes the
/// needle's motion once, implicitly, so the shaft's force changes by at most `K L v dt` (`L` the inserted
/// length; less as the tissue starts to follow). Counting the step's change of speed a
/// second time, as an earlier form did, nearly doubled the first step (measured: 1.79
/// times the bound then, 0.89 times now).
#[test]
fn a_reversal_moves_the_sheath_by_the_needles_travel_once() {
    let k = 20_000.0;
    let v = 0.025;
    let base = INSERT_EXTRACT
        .split("[[needle.keyframe]]")
        .next()
        .unwrap()
        .replace(
            "friction = { coefficient = 0.3 }",
            &format!(
            "friction = {{ coefficient = 0.3, shear_stiffness = {k:.1}, sheath_viscosity = 0.0 }}\nspeed_ramp = 0.0"
        ),
        );
    assert!(base.contains("shear_stiffness"));
    let keyframes = "[[needle.keyframe]]\naction = \"move\"\ndirection = [1.0, 0.0, 0.0]\n\
        speed = 0.025\nduration = 2.0\n[[needle.keyframe]]\naction = \"pause\"\n\
        duration = 0.5\n[[needle.keyframe]]\naction = \"extract\"\nspeed = 0.025\n\
        duration = 0.05\n";
    let scene = Scene::from_toml_str(&(base + keyframes), Path::new("scenes")).unwrap();
    let mut sim = cpu_sim(&scene);
    let dt = sim.dt();
    sim.step_n((2.52 / dt) as u64).unwrap();
    let h = sim.history();
    let depth: Vec<f64> = h.iter().map(|s| sim.depth_of(s.tip, s.direction)).collect();
    let r = (1..h.len())
        .find(|&i| depth[i] < depth[i - 1] - 0.5 * v * dt)
        .expect("withdrawn");
    let shaft = |i: usize| h[i].force.axial - h[i].force.tip;
    let change = shaft(r - 1) - shaft(r);
    let bound = k * depth[r - 1] * v * dt;
    eprintln!("first withdrawing step: shaft force -{change:.5} N, K L v dt {bound:.5} N");
    assert!(
        change > 0.2 * bound && change <= 1.05 * bound,
        "shaft force change {change} N against K L v dt {bound} N"
    );
}

/// A needle entering 9 mm from the edge of the gel phantom (10 mm spacing): the contact
/// patch (radius `2 h`) reaches round the edge, and only the face the needle touches may
/// carry it. When the side face's nodes were taken in, their deeper mean put the patch
/// behind the tip, the tip was let go at once and the needle never entered.
#[test]
fn a_needle_entering_near_an_edge_punctures_and_goes_in() {
    let text = include_str!("../scenes/phantom_insertion.toml").replace(
        "base = [-0.102, 0.0312, 0.0288]",
        "base = [-0.102, 0.0092, 0.0288]",
    );
    assert!(text.contains("0.0092"));
    punctures_and_goes_in(&text, "9 mm from the edge");
}

/// Runs a variant of the phantom scene to its end: it must go from Outside through
/// Touching to Inside, with at least three needle nodes at the end.
fn punctures_and_goes_in(text: &str, what: &str) {
    let scene = Scene::from_toml_str(text, Path::new("scenes")).unwrap();
    let mut sim = cpu_sim(&scene);
    let steps = (scene.run.duration.unwrap() / sim.dt()) as u64;
    let states = run_checked(&mut sim, steps);
    assert_eq!(
        states,
        [
            PunctureState::Outside,
            PunctureState::Touching,
            PunctureState::Inside
        ],
        "{what}"
    );
    let n = sim.needle_nodes().len();
    assert!(n >= 3, "{what}: {n} needle nodes");
}

/// A needle tilted off the surface normal touches, punctures and goes in. The contact
/// patch's nodes lie at different depths along a tilted needle, and the tip let go of the
/// surface when it was behind their weighted mean with no force on the patch: at the
/// second step, before the patch had any force, for a tilt toward +y of 5 to 30 degrees
/// on the phantom's lattice (the needle then passed through the tissue untouched, state
/// Outside to the end; found 2026-11-28 on the liver scene tilted by 10 degrees). The
/// tip now lets go when it is behind the touched point as the patch has carried it.
#[test]
fn a_tilted_needle_punctures_and_goes_in() {
    for degrees in [10.0f64, 30.0] {
        let (s, c) = degrees.to_radians().sin_cos();
        // The axis meets the entry face where the straight scene's does.
        let base_y = 0.0312 - 0.102 / c * s;
        let text = include_str!("../scenes/phantom_insertion.toml")
            .replace(
                "base = [-0.102, 0.0312, 0.0288]",
                &format!("base = [-0.102, {base_y}, 0.0288]"),
            )
            .replace(
                "direction = [1.0, 0.0, 0.0]",
                &format!("direction = [{c}, {s}, 0.0]"),
            );
        assert_eq!(text.matches(&format!("{s}, 0.0]")).count(), 2, "{degrees}");
        punctures_and_goes_in(&text, &format!("tilted {degrees} degrees"));
    }
}

/// The dent at the puncture force does not depend on where the needle's axis meets the
/// node lattice. The Surface node is put at that point; through a lattice node it sat
/// next to that node, and the patch's Boussinesq estimate took the pair as two point loads
/// a fraction of a millimetre apart: the estimate of what the lattice resolves grew as
/// `1 / r`, the sub-grid element fell to its floor, and the dent at 1 N was 2.58 mm
/// through a node against 7.66 mm between nodes (gel phantom, 10 mm spacing, dev
/// machine, 2026-11-28). Pairs closer than their cells' size now count as overlapping
/// cells: 7.37 against 7.66 mm. The bound, 8%, lies between.
#[test]
fn the_dent_at_puncture_does_not_depend_on_where_the_axis_meets_the_lattice() {
    let dent = |y: f64, z: f64| {
        let text = include_str!("../scenes/phantom_insertion.toml").replace(
            "base = [-0.102, 0.0312, 0.0288]",
            &format!("base = [-0.102, {y}, {z}]"),
        );
        assert!(text.contains(&format!("[-0.102, {y}, {z}]")));
        let scene = Scene::from_toml_str(&text, Path::new("scenes")).unwrap();
        let mut sim = cpu_sim(&scene);
        while sim.state() != PunctureState::Inside {
            assert!(sim.time() < 1.5, "no puncture at ({y}, {z})");
            sim.step().unwrap();
        }
        let h = sim.history();
        let last = &h[h.len() - 2];
        assert_eq!(last.state, PunctureState::Touching);
        sim.depth_of(last.tip, last.direction)
    };
    // Through the lattice node at (0, 0.03, 0.03), and half a spacing from every node.
    let (at_node, between) = (dent(0.03, 0.03), dent(0.035, 0.035));
    assert!(between > 5e-3, "dent between nodes {between}");
    assert!(
        (at_node - between).abs() < 0.08 * between,
        "dent through a node {at_node} m, between nodes {between} m"
    );
}

/// Issue 39 item 4: while the needle is pulled back the tip's material point (its depth
/// in the undeformed tissue) moves with the needle, also when a needle node is removed.
/// The front node hands its length over to the node before it and goes when its share
/// is 0; the material point is blended over to the one seen from the node before by the
/// same share. Measured over the first four removals of the shipped insert/extract scene
/// (25 um of needle travel a step): the largest step of the depth was 0.39 to 0.81 mm at
/// each removal when it switched nodes at the removal, 0.036 mm now (CPU, 2026-11-27;
/// 0.10 mm before the Tip node's removal was handed over); the bound, 0.2 mm, lies
/// between.
#[test]
fn the_tips_material_point_does_not_jump_at_node_removals_while_withdrawing() {
    let scene = Scene::from_toml_str(INSERT_EXTRACT, Path::new("scenes")).unwrap();
    let mut sim = cpu_sim(&scene);
    let nodes_at_reversal = {
        sim.step_n((2.5 / sim.dt()) as u64).unwrap();
        sim.needle_nodes().len()
    };
    sim.step_n((1.2 / sim.dt()) as u64).unwrap();
    let h: Vec<_> = sim.history().iter().filter(|s| s.time > 2.5).collect();
    let removed = nodes_at_reversal - h.last().unwrap().needle_nodes;
    assert!(
        removed >= 3,
        "{nodes_at_reversal} -> {} needle nodes",
        h.last().unwrap().needle_nodes
    );
    let mut largest: f64 = 0.0;
    for w in h.windows(2) {
        if let (Some(a), Some(b)) = (w[0].tissue_depth, w[1].tissue_depth) {
            largest = largest.max((b - a).abs());
        }
    }
    eprintln!(
        "{removed} needle nodes removed; largest step of the tip's material depth {:.3} mm",
        1e3 * largest
    );
    assert!(
        largest < 2e-4,
        "the tip's material point jumped by {largest} m"
    );
}
