//! The scene runner stops with a typed error instead of writing NaN.

use needlesim::{run_scene, Material, RunError, RunOptions, Scene, SimError};

#[test]
fn a_diverging_scene_stops_with_the_step_and_node() {
    // dt far above the explicit stability limit of these springs (about 1e-4 s).
    let scene = Scene::builder()
        .box_with_nodes([0.0; 3], [0.1; 3], 639)
        .material(Material::mass_spring(1e5))
        .dt(1e-2)
        .check_every(1)
        .stretch([1.3, 1.0, 1.0])
        .steps(5000)
        .output_every(10)
        .build()
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let err = run_scene(&scene, &RunOptions::new(dir.path()), |_, _| {}).unwrap_err();
    // Checked every step (physics.check_every = 1), the speed guard (physics.max_speed,
    // 100 m/s) trips while every value is still finite: the growth is geometric, so the
    // bound is crossed before f32 overflows.
    match err {
        RunError::Sim(SimError::Runaway {
            step,
            node,
            speed,
            limit,
        }) => {
            assert!(step > 0 && step < 50, "step {step}");
            assert!(node < 648 && speed.is_finite() && speed > limit && limit == 100.0);
        }
        other => panic!("expected a runaway, got {other}"),
    }
    // Every CSV row written before the stop is finite.
    let csv = std::fs::read_to_string(dir.path().join("frames.csv")).unwrap();
    assert!(csv.lines().count() >= 2);
    assert!(
        !csv.to_lowercase().contains("nan") && !csv.contains("inf"),
        "{csv}"
    );
}

/// `run.duration` on a `dt = "auto"` scene: the run lasts the duration whatever dt the
/// stiffness gives (two moduli, two time steps, one simulated time), and the progress
/// callback is told the step count the duration makes.
#[test]
fn a_duration_runs_as_long_whatever_the_auto_time_step() {
    let mut dts = Vec::new();
    for e in [1e4, 4e4] {
        let scene = Scene::builder()
            .box_with_nodes([0.0; 3], [0.1; 3], 125)
            .material(Material::debunne(e, 0.3))
            .dt_auto()
            .duration(0.05)
            .output_every(1)
            .build()
            .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let mut options = RunOptions::new(dir.path());
        options.write_files = false;
        let mut told = 0;
        let summary = run_scene(&scene, &options, |_, total| told = total).unwrap();
        let dt = summary.frames.last().map(|f| f.time).unwrap() / summary.steps as f64;
        assert_eq!(told, summary.steps);
        // ceil(0.05 / dt) steps: at least the duration, less than one step more.
        let t = summary.steps as f64 * dt;
        assert!(
            t >= 0.05 * (1.0 - 1e-6) && t < 0.05 + dt,
            "{t} s with dt {dt}"
        );
        dts.push(dt);
    }
    // Four times stiffer, twice the wave speed: the auto step halves.
    assert!((dts[0] / dts[1] - 2.0).abs() < 0.1, "{dts:?}");
}
