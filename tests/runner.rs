//! The scene runner stops with a typed error instead of writing NaN.

use needlesim::{run_scene, RunError, RunOptions, Scene, SimError};
use std::path::Path;

#[test]
fn a_diverging_scene_stops_with_the_step_and_node() {
    // dt far above the explicit stability limit of these springs (about 1e-4 s).
    let text = "[tissue]\ngeometry = { kind = \"box\", min = [0,0,0], max = [0.1,0.1,0.1], nodes = 639 }\n\
                [material]\nmodel = \"mass_spring\"\nstiffness = 1e5\n[physics]\ndt = 1e-2\n\
                [initial]\nstretch = [1.3, 1.0, 1.0]\n[run]\nsteps = 5000\noutput_every = 10\n";
    let scene = Scene::from_toml_str(text, Path::new(".")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let err = run_scene(&scene, &RunOptions::new(dir.path()), |_, _| {}).unwrap_err();
    match err {
        RunError::Sim(SimError::Diverged { step, node, .. }) => {
            assert!(step > 0 && step < 5000 && step % 10 == 0, "step {step}");
            assert!(node < 648);
        }
        other => panic!("expected divergence, got {other}"),
    }
    // Every CSV row written before the stop is finite.
    let csv = std::fs::read_to_string(dir.path().join("frames.csv")).unwrap();
    assert!(csv.lines().count() >= 2);
    assert!(
        !csv.to_lowercase().contains("nan") && !csv.contains("inf"),
        "{csv}"
    );
}
