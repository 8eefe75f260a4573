//! Needle poses the contact cannot follow are typed errors, not silent nonsense: a needle
//! that starts inside the body, a needle that moves more than 4 node spacings in one step
//! (very fast, or a pose that jumped while in contact), and a friction law that lets the
//! tissue run ahead of the needle.

use needlesim::needle::{PunctureState, Simulation, SimulationError};
use needlesim::{CpuBackend, Scene, Threading};
use std::path::Path;

const INSERT_EXTRACT: &str = include_str!("../scenes/needle_insert_extract.toml");

/// The insert-extract scene (a 10 cm cube, entry face x = 0, needle along +x at
/// y = 0.0513, z = 0.0487) with lines replaced: `(prefix, new line)`.
fn scene(edits: &[(&str, &str)]) -> Scene {
    let text: Vec<String> = INSERT_EXTRACT
        .lines()
        .map(|l| {
            edits
                .iter()
                .find(|(p, _)| l.starts_with(p))
                .map_or(l.to_string(), |(_, new)| new.to_string())
        })
        .collect();
    Scene::from_toml_str(&text.join("\n"), Path::new("scenes")).unwrap()
}

fn start(scene: &Scene) -> Result<Simulation, SimulationError> {
    let prep = Simulation::prepare(scene)?;
    let b = CpuBackend::new(prep.tissue.clone(), Threading::Single).unwrap();
    prep.start(Box::new(b))
}

#[test]
fn a_needle_starting_inside_the_body_is_an_error_naming_the_part() {
    let cases = [
        // Tip 4 cm deep, base outside.
        ("base = [-0.06, 0.0513, 0.0487]", "length = 0.1", "tip"),
        // The whole needle inside.
        ("base = [0.02, 0.0513, 0.0487]", "length = 0.05", "tip"),
        // Base inside, tip out past the far face.
        ("base = [0.02, 0.0513, 0.0487]", "length = 0.1", "base"),
        // Base 1 cm before the entry face, tip 1 cm past the far face: only the shaft is in.
        ("base = [-0.01, 0.0513, 0.0487]", "length = 0.12", "shaft"),
    ];
    for (b, len, part) in cases {
        let base = b;
        let s = scene(&[("base =", b), ("length =", len)]);
        match start(&s) {
            Err(e @ SimulationError::StartsInside { what, .. }) => {
                assert_eq!(what, part, "{base}");
                assert!(e.to_string().contains("starts inside the tissue"), "{e}");
            }
            other => panic!("{base}: expected StartsInside, got {:?}", other.err()),
        }
    }
    // The shipped pose (tip 1 cm before the face) starts.
    assert!(start(&scene(&[])).is_ok());
}

#[test]
fn a_needle_faster_than_four_node_spacings_per_step_is_an_error() {
    // 90 m/s at dt = 1 ms: 9 cm a step, about 8 node spacings.
    let s = scene(&[("speed = 0.025", "speed = 90.0")]);
    let mut sim = start(&s).unwrap();
    match sim.step_n(10) {
        Err(e @ SimulationError::TooFast { moved, limit, .. }) => {
            assert!(moved > limit, "{e}");
            assert!(e.to_string().contains("entering the body"), "{e}");
        }
        other => panic!("expected TooFast, got {other:?}"),
    }
    // 30 m/s: 3 cm a step, 2.7 spacings: runs (tests/needle.rs adds and removes several
    // nodes per step at this speed).
    let s = scene(&[("speed = 0.025", "speed = 30.0")]);
    let mut sim = start(&s).unwrap();
    sim.step_n(2).unwrap();
    assert_ne!(sim.state(), PunctureState::Outside);
}

#[test]
fn a_pose_that_jumps_while_touching_is_an_error_but_free_motion_is_not() {
    let s = scene(&[]);
    let mut sim = start(&s).unwrap();
    // Outside, the needle may jump anywhere (a haptic device moved in the air).
    sim.set_pose([-0.5, 0.3, 0.2], [1.0, 0.0, 0.0]).unwrap();
    sim.step().unwrap();
    sim.set_pose([-0.11, 0.0513, 0.0487], [1.0, 0.0, 0.0])
        .unwrap();
    sim.step().unwrap();
    let mut x = -0.11;
    while sim.state() != PunctureState::Touching {
        x += 2.5e-5;
        sim.set_pose([x, 0.0513, 0.0487], [1.0, 0.0, 0.0]).unwrap();
        sim.step().unwrap();
        assert!(sim.steps() < 2_000, "never touched");
    }
    // A glitch: 30 cm sideways in one step.
    let (steps, tip) = (sim.steps(), sim.needle().unwrap().tip());
    sim.set_pose([x, 0.35, 0.0487], [1.0, 0.0, 0.0]).unwrap();
    match sim.step() {
        Err(e @ SimulationError::TooFast { .. }) => {
            assert!(e.to_string().contains("touching the surface"), "{e}")
        }
        other => panic!("expected TooFast, got {other:?}"),
    }
    // The refused step left no trace: the needle is where it was, a second step does
    // not make the jump (it did: the refused pose had become the last one), and the
    // needle goes on from there.
    assert_eq!(sim.steps(), steps);
    assert_eq!(sim.needle().unwrap().tip(), tip);
    sim.step().unwrap();
    assert_eq!(sim.needle().unwrap().tip(), tip);
    assert_eq!(sim.state(), PunctureState::Touching);
    sim.set_pose([x + 2.5e-5, 0.0513, 0.0487], [1.0, 0.0, 0.0])
        .unwrap();
    sim.step().unwrap();
}

/// The paper's friction model with a viscous coefficient of 1000 N s/m drives the Surface
/// node ahead of the tip at puncture; the run must stop (it used to drop the node and let
/// the needle pass through the tissue with no error).
#[test]
fn a_friction_law_that_lets_the_tissue_run_ahead_stops_the_run() {
    let s = scene(&[
        (
            "friction =",
            "friction = { model = \"paper\", static_threshold = 0.02, dynamic = 0.3, viscous = 1000.0 }",
        ),
        ("cutting =", ""),
    ]);
    let mut sim = start(&s).unwrap();
    match sim.step_n(2_000) {
        Err(e @ SimulationError::NodesLost { .. }) => {
            assert!(e.to_string().contains("no longer holds the tissue"), "{e}")
        }
        other => panic!("expected NodesLost, got {other:?}"),
    }
}

/// A needle whose length over spacing asks for billions of node slots is refused before
/// anything is allocated, naming the key.
#[test]
fn a_needle_needing_billions_of_slots_names_its_spacing() {
    let s = scene(&[("length =", "length = 0.1\nspacing = 1e-12")]);
    match Simulation::prepare(&s) {
        Err(e) => assert!(
            e.to_string().contains("needle.spacing") && e.to_string().contains("bytes"),
            "{e}"
        ),
        Ok(_) => panic!("a needle of 1e11 slots was built"),
    }
}
