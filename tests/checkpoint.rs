//! Checkpoints (`needlesim_needle::checkpoint`): a simulation restored from one continues
//! bitwise as the uninterrupted one, every model, with the needle inserted at the
//! checkpoint; damaged files, other versions and other scenes are typed errors. The
//! command line tool's `--resume` is tested in crates/cli/tests/resume.rs.

mod common;

use needlesim::needle::{
    Checkpoint, CheckpointError, NodeRole, PunctureState, Simulation, SimulationError,
};
use needlesim::{CpuBackend, Material, NodeField, Scene, Threading};
use std::path::Path;

const INSERT_EXTRACT: &str = include_str!("../scenes/needle_insert_extract.toml");

/// The insert-extract scene with another material.
fn scene(material: Material) -> Scene {
    let mut scene = Scene::from_toml_str(INSERT_EXTRACT, Path::new("scenes")).unwrap();
    scene.material = material;
    scene.validate().unwrap();
    scene
}

fn start(scene: &Scene, threading: Threading) -> Simulation {
    let prep = Simulation::prepare(scene).unwrap();
    let b = CpuBackend::new(prep.tissue.clone(), threading).unwrap();
    prep.start(Box::new(b)).unwrap()
}

fn resume(scene: &Scene, c: Checkpoint) -> Result<Simulation, SimulationError> {
    let prep = Simulation::prepare(scene).unwrap();
    let b = CpuBackend::new(prep.tissue.clone(), Threading::Parallel).unwrap();
    prep.resume(Box::new(b), c)
}

/// Everything a run leaves: every slot of the node arrays, the neighbour rows, every shape
/// array, and the history, as bits.
fn fingerprint(sim: &mut Simulation) -> (Vec<u32>, Vec<u32>, Vec<u8>, String) {
    let cap = sim.backend().capacity();
    let mut bits = Vec::new();
    for f in [
        NodeField::Position,
        NodeField::Velocity,
        NodeField::Force,
        NodeField::PositionRemainder,
    ] {
        let mut out = vec![[0.0f32; 4]; cap];
        sim.backend().read(f, 0..cap, &mut out).unwrap();
        bits.extend(out.iter().flatten().map(|x| x.to_bits()));
    }
    let nb = sim.editor().neighbours();
    let mut rows = nb.index.clone();
    rows.extend(nb.weight.iter().map(|w| w.to_bits()));
    let mut shape = Vec::new();
    let arrays: Vec<_> = sim
        .editor()
        .shape()
        .bytes()
        .iter()
        .map(|(n, b)| (*n, b.len()))
        .collect();
    for (name, len) in arrays {
        let mut out = vec![0u8; len];
        sim.backend().read_shape_bytes(name, 0, &mut out).unwrap();
        shape.extend(out);
    }
    // Debug output of floats is their shortest exact form: equal text, equal bits.
    let history = format!("{:?} {:?}", sim.history(), sim.needle_nodes());
    (bits, rows, shape, history)
}

/// Steps to the checkpoint (the tip about 2.7 cm in, inside with shaft nodes) and after it
/// (more insertion, the hold, and 0.3 s of extraction, which removes nodes the checkpoint
/// holds).
const BEFORE: u64 = 1_500;
const AFTER: u64 = 1_300;

#[test]
fn a_resumed_run_is_bitwise_the_uninterrupted_one_for_every_model() {
    for (label, material) in common::all_models() {
        let scene = scene(material);
        let mut sim = start(&scene, Threading::Parallel);
        sim.step_n(BEFORE).unwrap();
        assert!(
            sim.state() == PunctureState::Inside && sim.needle_nodes().len() >= 3,
            "{label}: the needle must be inside with shaft nodes at the checkpoint ({:?}, {} nodes)",
            sim.state(),
            sim.needle_nodes().len()
        );
        let bytes = sim.checkpoint().unwrap().to_bytes();
        sim.step_n(AFTER).unwrap();
        let straight = fingerprint(&mut sim);

        let c = Checkpoint::from_bytes(&bytes, Path::new("mem")).unwrap();
        assert_eq!(c.steps(), BEFORE);
        let mut resumed = resume(&scene, c).unwrap();
        assert_eq!(resumed.steps(), BEFORE);
        resumed.step_n(AFTER).unwrap();
        let again = fingerprint(&mut resumed);
        assert!(straight.0 == again.0, "{label}: node arrays differ");
        assert!(straight.1 == again.1, "{label}: neighbour rows differ");
        assert!(straight.2 == again.2, "{label}: shape arrays differ");
        assert!(straight.3 == again.3, "{label}: histories differ");
        assert_eq!(resumed.steps(), BEFORE + AFTER);
    }
}

/// The insert-extract scene 1 m from the origin (its tissue in a translated frame,
/// `needlesim::core::frame`).
fn far_scene(material: Material) -> Scene {
    let text = INSERT_EXTRACT
        .replace(
            "min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1]",
            "min = [1.0, 1.0, 1.0], max = [1.1, 1.1, 1.1]",
        )
        .replace("above = 0.099", "above = 1.099")
        .replace(
            "base = [-0.11, 0.0513, 0.0487]",
            "base = [0.89, 1.0513, 1.0487]",
        );
    let mut scene = Scene::from_toml_str(&text, Path::new("scenes")).unwrap();
    scene.material = material;
    scene.validate().unwrap();
    scene
}

/// A checkpoint saves the positions as the backend stores them, so a body kept in a
/// translated frame resumes bit for bit too (saving world f32 positions and their world
/// remainders loses the low bits of the stored ones).
#[test]
fn a_body_far_from_the_origin_resumes_bitwise_too() {
    for (label, material) in common::all_models() {
        let scene = far_scene(material);
        let mut sim = start(&scene, Threading::Parallel);
        assert_eq!(sim.backend().position_frame().origin(), [1.0; 3], "{label}");
        sim.step_n(BEFORE).unwrap();
        assert_eq!(sim.state(), PunctureState::Inside, "{label}");
        let bytes = sim.checkpoint().unwrap().to_bytes();
        sim.step_n(AFTER).unwrap();
        let straight = fingerprint(&mut sim);
        let c = Checkpoint::from_bytes(&bytes, Path::new("mem")).unwrap();
        let mut resumed = resume(&scene, c).unwrap();
        resumed.step_n(AFTER).unwrap();
        let again = fingerprint(&mut resumed);
        assert!(straight.0 == again.0, "{label}: node arrays differ");
        assert!(straight.2 == again.2, "{label}: shape arrays differ");
        assert!(straight.3 == again.3, "{label}: histories differ");
    }
}

/// A diverged state (a non-finite position) is neither written nor read back (`save()`
/// after a divergence wrote it and `load()` accepted it), and a checkpoint never replaces
/// something that is not a regular file (it renamed a file over a device node).
#[test]
fn a_non_finite_state_or_a_path_that_is_not_a_file_is_refused() {
    let scene = scene(common::LINEAR_DEB.1);
    let mut sim = start(&scene, Threading::Single);
    sim.step_n(10).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let good_path = dir.path().join("good.ckpt");
    sim.checkpoint().unwrap().write(&good_path).unwrap();
    // Break node 3's position and try to save.
    let mut p = [[0.0f32; 4]; 1];
    sim.backend()
        .read(NodeField::Position, 3..4, &mut p)
        .unwrap();
    p[0][1] = f32::NAN;
    sim.backend().write(NodeField::Position, 3, &p).unwrap();
    let path = dir.path().join("diverged.ckpt");
    let e = sim.checkpoint().unwrap().write(&path).unwrap_err();
    assert!(
        matches!(e, CheckpointError::NonFinite { node: 3, .. }),
        "{e}"
    );
    assert!(!path.exists(), "a file was written");
    // A file holding such a state (as an older build wrote it) is refused on reading.
    let bytes = sim.checkpoint().unwrap().to_bytes();
    std::fs::write(&path, bytes).unwrap();
    let e = Checkpoint::read(&path).unwrap_err();
    assert!(e.to_string().contains("not finite"), "{e}");
    // Over a folder, or a device: refused, the target untouched.
    let folder = dir.path().join("folder");
    std::fs::create_dir(&folder).unwrap();
    let good = Checkpoint::read(&good_path).unwrap();
    let e = good.write(&folder).unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
    assert!(folder.is_dir());
    #[cfg(unix)]
    {
        let e = good.write("/dev/null").unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
    }
}

#[test]
fn a_checkpoint_round_trips_through_a_file_and_damage_is_a_typed_error() {
    let scene = scene(common::LINEAR_DEB.1);
    let mut sim = start(&scene, Threading::Single);
    sim.step_n(600).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("state.ckpt");
    sim.checkpoint().unwrap().write(&path).unwrap();
    let good = std::fs::read(&path).unwrap();
    let c = Checkpoint::read(&path).unwrap();
    assert_eq!(c.steps(), 600);
    assert_eq!(c.to_bytes(), good, "write and read are inverse");

    // Cut short: the header says how long the payload is.
    std::fs::write(&path, &good[..good.len() - 100]).unwrap();
    let e = Checkpoint::read(&path).unwrap_err();
    assert!(
        matches!(e, CheckpointError::Truncated { .. }),
        "truncated: {e}"
    );
    assert!(e.to_string().contains("truncated"), "{e}");
    // Cut inside the header.
    std::fs::write(&path, &good[..30]).unwrap();
    assert!(matches!(
        Checkpoint::read(&path).unwrap_err(),
        CheckpointError::Truncated { .. }
    ));
    // Another format version.
    let mut other = good.clone();
    other[needlesim::needle::checkpoint::MAGIC.len()] ^= 0x7f;
    std::fs::write(&path, &other).unwrap();
    let e = Checkpoint::read(&path).unwrap_err();
    assert!(matches!(e, CheckpointError::Version { .. }), "{e}");
    assert!(e.to_string().contains("format version"), "{e}");
    // One flipped bit in the payload.
    let mut flipped = good.clone();
    let at = good.len() / 2;
    flipped[at] ^= 1;
    std::fs::write(&path, &flipped).unwrap();
    let e = Checkpoint::read(&path).unwrap_err();
    assert!(matches!(e, CheckpointError::Corrupt { .. }), "{e}");
    // Not a checkpoint at all.
    std::fs::write(&path, b"[tissue]\n").unwrap();
    let e = Checkpoint::read(&path).unwrap_err();
    assert!(matches!(e, CheckpointError::NotACheckpoint { .. }), "{e}");
    // A folder.
    assert!(matches!(
        Checkpoint::read(dir.path()).unwrap_err(),
        CheckpointError::Io { .. }
    ));
    // A scene stored in it that does not parse names the checkpoint (it said
    // `scene <string>`).
    let mut c = sim.checkpoint().unwrap();
    c.scene = Some(needlesim::needle::SceneText {
        toml: "[ame = 1".into(),
        base_dir: ".".into(),
    });
    c.write(&path).unwrap();
    let text = Checkpoint::read(&path).unwrap().scene.unwrap();
    let e = text.scene_stored_in(&path).unwrap_err().to_string();
    assert!(e.contains(&format!("stored in {}", path.display())), "{e}");
}

#[test]
fn a_checkpoint_of_another_scene_is_refused_naming_the_part() {
    let deb = scene(common::LINEAR_DEB.1);
    let mut sim = start(&deb, Threading::Single);
    sim.step_n(10).unwrap();
    let c = sim.checkpoint().unwrap();
    let pba = scene(common::MODELS[4].1);
    match resume(&pba, c.clone()) {
        Err(SimulationError::Checkpoint(CheckpointError::SceneMismatch { part })) => {
            assert_eq!(part, "material")
        }
        other => panic!("expected a scene mismatch, got {:?}", other.err()),
    }
    // The run settings may change (a longer run resumes from the checkpoint).
    let mut longer = deb.clone();
    longer.run.steps *= 2;
    longer.name = "longer".into();
    assert!(resume(&longer, c).is_ok());
}

/// A checkpoint taken while a node edit's change of the tissue's forces is still being
/// handed over ([`needlesim::needle::handover`], 40 ms after a Shaft node event): the
/// resumed run continues bitwise as the uninterrupted one (the handover is part of the
/// saved state; without it the resumed run would apply the new rows' forces at once).
#[test]
fn a_checkpoint_during_a_handover_resumes_bitwise() {
    let scene = Scene::from_toml_str(INSERT_EXTRACT, Path::new("scenes")).unwrap();
    let mut sim = start(&scene, Threading::Parallel);
    sim.step_n(BEFORE).unwrap();
    // The next step that adds a Shaft node, then 10 steps (10 ms) into its handover.
    let shaft = |sim: &Simulation| {
        sim.needle_nodes()
            .iter()
            .filter(|n| n.role == NodeRole::Shaft)
            .count()
    };
    let nodes = shaft(&sim);
    let mut waited = 0;
    while shaft(&sim) <= nodes {
        sim.step().unwrap();
        waited += 1;
        assert!(waited < 2_000, "no Shaft node added");
    }
    sim.step_n(10).unwrap();
    let at = sim.steps();
    let bytes = sim.checkpoint().unwrap().to_bytes();
    sim.step_n(100).unwrap();
    let straight = fingerprint(&mut sim);
    let c = Checkpoint::from_bytes(&bytes, Path::new("mem")).unwrap();
    let mut resumed = resume(&scene, c).unwrap();
    assert_eq!(resumed.steps(), at);
    resumed.step_n(100).unwrap();
    let again = fingerprint(&mut resumed);
    assert!(straight == again, "the resumed run differs");
}
