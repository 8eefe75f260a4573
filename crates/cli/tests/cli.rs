//! The command line tool, run as a user would.

use std::process::Command;

fn needlesim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_needlesim"))
}

#[test]
fn run_default_scene_writes_csv_and_paraview_frames() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("paper");
    let o = needlesim()
        .args(["run", "--steps", "600", "--threads", "1", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        stdout.contains("steps/s") && stdout.contains("needle      Inside"),
        "{stdout}"
    );
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], needlesim::output::CSV_HEADER);
    // The paper scene writes every 100 steps: frames at 0, 100, ..., 600.
    assert_eq!(lines.len(), 8, "{csv}");
    let last: Vec<f64> = lines[7].split(',').map(|x| x.parse().unwrap()).collect();
    assert_eq!(last[1], 600.0);
    assert!(
        last[4] > 0.0,
        "the needle dents the cube: max displacement {}",
        last[4]
    );
    let pvd = std::fs::read_to_string(out.join("surface.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet").count(), 7);
    // Needle force: one row per step, the PNG plots.
    let force = std::fs::read_to_string(out.join("needle_force.csv")).unwrap();
    assert_eq!(force.lines().count(), 601);
    assert!(out.join("needle_force.png").exists() && out.join("needle_force_time.png").exists());
    // Before contact the surface has the cube's 704 triangles; once the needle is in, the
    // touched one is split in three and the needle nodes are vertex cells.
    let first = std::fs::read_to_string(out.join("surface/surface_00000.vtp")).unwrap();
    assert!(first.contains("NumberOfPolys=\"704\"") && first.contains("NumberOfVerts=\"0\""));
    let vtp = std::fs::read_to_string(out.join("surface/surface_00006.vtp")).unwrap();
    assert!(vtp.contains("NumberOfPolys=\"706\"") && vtp.contains("Name=\"displacement\""));
    assert!(!vtp.contains("NumberOfVerts=\"0\""), "needle nodes written");
}

#[test]
fn info_lists_the_arrays_of_the_chosen_model_only() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../..");
    let o = needlesim()
        .args(["info", &format!("{root}/scenes/cube_sag_msm.toml")])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}");
    assert!(
        stdout.contains("rest_length") && !stdout.contains("shape_vector"),
        "{stdout}"
    );
    let o = needlesim()
        .args(["info", &format!("{root}/scenes/cube_sag_lshm.toml")])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("shape_vector") && !stdout.contains("rest_length"),
        "{stdout}"
    );
}

/// A body 1 m from the origin is kept in a frame of its own (`needlesim::core::frame`);
/// `info` still gives its bounds in world coordinates and says where the frame is.
#[test]
fn info_gives_world_bounds_and_the_frame_of_a_far_body() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("far.toml");
    std::fs::write(
        &scene,
        "[tissue]\ngeometry = { kind = \"box\", min = [1.0, 1.0, 1.0], max = [1.1, 1.1, 1.1], \
         nodes = 125 }\n[material]\nmodel = \"mass_spring\"\nstiffness = 100.0\n",
    )
    .unwrap();
    let o = needlesim().arg("info").arg(&scene).output().unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}");
    assert!(
        stdout.contains("[1.0000, 1.0000, 1.0000] .. [1.1000, 1.1000, 1.1000] m"),
        "{stdout}"
    );
    assert!(stdout.contains("relative to [1, 1, 1] m"), "{stdout}");
}

#[test]
fn a_bad_scene_fails_with_a_message_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bad.toml");
    std::fs::write(&scene, "[tissue]\ngeometry = { kind = \"box\", min = [0,0,0], max = [1,1,1], spacing = 0.5 }\n[material]\nmodel = \"mass_spring\"\nstiffness = 1.0\n[physics]\ndt = -1.0\n").unwrap();
    let o = needlesim().arg("run").arg(&scene).output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr.contains("physics.dt") && !stderr.contains("panicked"),
        "{stderr}"
    );
    let o = needlesim()
        .args(["run", "no/such/scene.toml"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && stderr.contains("no/such/scene.toml"),
        "{stderr}"
    );
}

#[test]
fn every_shipped_scene_loads() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let scene = needlesim::Scene::from_file(&path)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            needlesim::SceneInfo::of(&scene).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            n += 1;
        }
    }
    assert!(n >= 4, "found {n} scenes");
    let default =
        needlesim::Scene::from_toml_str(needlesim::DEFAULT_SCENE, std::path::Path::new("."))
            .unwrap();
    assert_eq!(
        default,
        needlesim::Scene::from_file(dir.join("paper_insertion_lshm.toml"))
            .map(|mut s| {
                s.base_dir = ".".into();
                s
            })
            .unwrap()
    );
}

/// Every shipped scene runs its first 300 steps on the CPU without a divergence (the
/// sphere's diverged at step 200 with a fixed time step too long for its small surface
/// cells).
#[test]
fn every_shipped_scene_runs_its_first_steps() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let out = tempfile::tempdir().unwrap();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let scene = needlesim::Scene::from_file(&path).unwrap();
        let mut options = needlesim::RunOptions::new(out.path().join("run"));
        options.steps = Some(300);
        options.threads = Some(0);
        options.write_files = false;
        let summary = needlesim::run_scene(&scene, &options, |_, _| {})
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(
            summary.frames.last().is_some_and(|f| f.step == 300),
            "{}: no frame at the last step",
            path.display()
        );
    }
}

/// `--backend auto` runs on the GPU when wgpu finds an adapter (always under scripts/test,
/// which installs lavapipe and sets NEEDLESIM_REQUIRE_GPU) and otherwise falls back to the
/// CPU with a warning; the frames match the CPU run's to 1e-6 m. A bad backend name is a
/// clear error.
#[test]
fn backend_option_selects_the_gpu_or_falls_back() {
    let dir = tempfile::tempdir().unwrap();
    let run = |backend: &str| {
        let out = dir.path().join(backend);
        let o = needlesim()
            .args(["run", "--steps", "300", "--backend", backend, "--out"])
            .arg(&out)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
        let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{stdout}\n{stderr}");
        let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
        let last: Vec<f64> = csv
            .lines()
            .last()
            .unwrap()
            .split(',')
            .map(|x| x.parse().unwrap())
            .collect();
        (stdout, stderr, last)
    };
    let (auto_out, auto_err, auto_last) = run("auto");
    let (_, _, cpu_last) = run("cpu");
    if std::env::var("NEEDLESIM_REQUIRE_GPU").is_ok() {
        assert!(auto_out.contains("backend     gpu ("), "{auto_out}");
    } else if !auto_out.contains("backend     gpu (") {
        assert!(
            auto_err.contains("warning: GPU backend unavailable"),
            "{auto_err}"
        );
    }
    // Max displacement after 300 steps.
    assert!(
        (auto_last[4] - cpu_last[4]).abs() < 1e-6,
        "{auto_last:?} vs {cpu_last:?}"
    );
    let o = needlesim()
        .args(["run", "--backend", "banana"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("invalid value 'banana'"), "{err}");
    assert!(
        err.contains("cpu-parallel"),
        "the error lists the backends: {err}"
    );
}

/// `needlesim view --screenshot` renders offscreen (lavapipe under scripts/test) and
/// writes a PNG of the asked size; a zero size and a missing scene are errors with a
/// message, not a panic and not an empty file.
#[test]
fn view_writes_a_screenshot_and_rejects_bad_sizes() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("shot.png");
    let o = needlesim()
        .args([
            "view",
            "--steps",
            "20",
            "--width",
            "64",
            "--height",
            "48",
            "--screenshot",
        ])
        .arg(&png)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    let gpu = std::env::var("NEEDLESIM_REQUIRE_GPU").is_ok();
    if o.status.success() {
        let bytes = std::fs::read(&png).unwrap();
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        // IHDR holds the width and height, big-endian, at bytes 16..24.
        assert_eq!(u32::from_be_bytes(bytes[16..20].try_into().unwrap()), 64);
        assert_eq!(u32::from_be_bytes(bytes[20..24].try_into().unwrap()), 48);
    } else {
        assert!(!gpu, "{stderr}");
        assert!(stderr.contains("no GPU adapter"), "{stderr}");
    }
    let o = needlesim()
        .args(["view", "--width", "0", "--screenshot"])
        .arg(&png)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && stderr.contains("out of range"),
        "{stderr}"
    );
    let o = needlesim()
        .args(["view", "nosuch.toml", "--screenshot"])
        .arg(dir.path().join("none.png"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && stderr.contains("nosuch.toml"),
        "{stderr}"
    );
    assert!(!dir.path().join("none.png").exists());
}

/// `needlesim view` opens its window under a virtual X server (Xvfb, lavapipe), draws the
/// asked number of frames on the GPU backend and says the simulation ran on the window's
/// device; skipped without `xvfb-run` unless NEEDLESIM_REQUIRE_GPU is set (scripts/test
/// installs it).
#[test]
fn view_window_draws_frames_on_the_simulations_device() {
    let have_xvfb = std::process::Command::new("sh")
        .args(["-c", "command -v xvfb-run"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !have_xvfb {
        assert!(
            std::env::var("NEEDLESIM_REQUIRE_GPU").is_err(),
            "xvfb-run is missing (apt-get install xvfb xauth)"
        );
        eprintln!("skipped: no xvfb-run");
        return;
    }
    // `timeout` ends a window that would never close (the test fails on its status).
    let window = |args: &[&str]| -> String {
        let o = std::process::Command::new("timeout")
            .args(["300", "xvfb-run", "-a", "-s", "-screen 0 1024x768x24"])
            .arg(env!("CARGO_BIN_EXE_needlesim"))
            .arg("view")
            .args(args)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{stdout}\n{stderr}");
        stdout
    };
    let gpu = [
        "--backend",
        "gpu",
        "--frames",
        "8",
        "--width",
        "320",
        "--height",
        "240",
    ];
    let stdout = window(&gpu);
    assert!(stdout.contains("window  8 frames"), "{stdout}");
    assert!(
        stdout.contains("(simulation on the same device)"),
        "{stdout}"
    );
    // Some simulated time passed: the frames stepped the scene.
    let t: f64 = stdout
        .split("t = ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no simulated time in {stdout}"));
    assert!(t > 0.0, "{stdout}");
    // On the CPU backend the window has a device of its own.
    let stdout = window(&["--threads", "1", "--frames", "3", "--width", "160"]);
    assert!(stdout.contains("window  3 frames"), "{stdout}");
    assert!(
        stdout.contains("(simulation on the CPU or a device of its own)"),
        "{stdout}"
    );
}

/// `needlesim sweep` writes each variant's rows as it finishes; SIGINT stops it with
/// status 130 and the finished variants complete in the CSV (it wrote the CSV only at the
/// end, so Ctrl-C lost every finished variant).
#[cfg(unix)]
#[test]
fn sweep_streams_rows_and_keeps_the_finished_variants_on_sigint() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("sweep.csv");
    let steps = 5000;
    let child = needlesim()
        .arg("sweep")
        .arg(root.join("scenes/needle_insert_extract.toml"))
        .args([
            "--vary",
            "needle.cutting=0.005,0.01,0.015,0.02,0.025,0.03,0.035,0.04,0.045,0.05,0.055,0.06,0.065,0.07,0.075,0.08,0.085,0.09,0.095,0.1,0.105,0.11,0.115,0.12",
            "--steps",
            &steps.to_string(),
            "--jobs",
            "1",
            "--out",
        ])
        .arg(&csv)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait for the first variant's rows.
    let rows = |text: &str, v: &str| {
        text.lines()
            .filter(|l| l.split(',').next() == Some(v))
            .count()
    };
    let t0 = std::time::Instant::now();
    loop {
        let text = std::fs::read_to_string(&csv).unwrap_or_default();
        if rows(&text, "0") == steps {
            break;
        }
        assert!(t0.elapsed().as_secs() < 120, "no variant finished");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    let killed = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("sweep interrupted"), "{stderr}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let done: Vec<String> = (0..24)
        .map(|v| v.to_string())
        .filter(|v| rows(&text, v) > 0)
        .collect();
    assert!(!done.is_empty() && done.len() < 24, "{done:?}");
    for v in &done {
        assert_eq!(rows(&text, v), steps, "variant {v} is complete");
    }
}

/// A key varied twice is an error before anything runs (it wrote two columns of one key,
/// the later overriding the earlier).
#[test]
fn sweep_refuses_a_key_varied_twice() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("sweep.csv");
    let o = needlesim()
        .arg("sweep")
        .arg(root.join("scenes/needle_insert_extract.toml"))
        .args([
            "--vary",
            "needle.cutting=0.1,0.2",
            "--vary",
            "needle.cutting=0.3",
            "--steps",
            "10",
            "--out",
        ])
        .arg(&csv)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "accepted: {stderr}");
    assert!(
        stderr.contains("needle.cutting") && stderr.contains("twice"),
        "{stderr}"
    );
    assert!(!csv.exists(), "a CSV was written");
}

/// What a fuzzing pass found in sweeps (issue 45): a misspelt last key part ran every
/// variant into the same error and exited 0; a sweep where every variant failed exited
/// 0; a scene without a needle wrote a header and no row; and array values were split at
/// their commas into string fragments. The first three are errors now (no CSV for the
/// first and third), and arrays sweep whole.
#[test]
fn sweep_names_unknown_keys_and_needleless_scenes_and_keeps_arrays_whole() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = tempfile::tempdir().unwrap();
    let sweep = |scene: &str, vary: &str, csv: &std::path::Path| {
        let o = needlesim()
            .arg("sweep")
            .arg(root.join(scene))
            .args(["--vary", vary, "--steps", "5", "--out"])
            .arg(csv)
            .output()
            .unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let csv = dir.path().join("typo.csv");
    let (ok, stderr) = sweep(
        "scenes/needle_insert_extract.toml",
        "material.stifness=1,2",
        &csv,
    );
    assert!(
        !ok && stderr.contains("--vary material.stifness"),
        "{stderr}"
    );
    assert!(!csv.exists(), "a CSV was written");
    let csv = dir.path().join("bad.csv");
    let (ok, stderr) = sweep(
        "scenes/needle_insert_extract.toml",
        "material.stiffness=-1,-2",
        &csv,
    );
    assert!(
        !ok && stderr.contains("every one of the 2 variants failed"),
        "{stderr}"
    );
    let csv = dir.path().join("none.csv");
    let (ok, stderr) = sweep(
        "scenes/cube_sag_msm.toml",
        "material.stiffness=50,100",
        &csv,
    );
    assert!(!ok && stderr.contains("no [needle]"), "{stderr}");
    assert!(!csv.exists(), "a CSV was written");
    let csv = dir.path().join("arrays.csv");
    let (ok, stderr) = sweep(
        "scenes/needle_insert_extract.toml",
        "needle.base=[-0.11,0.0513,0.0487],[-0.11,0.05,0.05]",
        &csv,
    );
    assert!(ok, "{stderr}");
    let mut rows = csv::Reader::from_path(&csv).unwrap();
    let bases: std::collections::BTreeSet<String> =
        rows.records().map(|r| r.unwrap()[1].to_string()).collect();
    assert_eq!(
        bases.into_iter().collect::<Vec<_>>(),
        ["[-0.11, 0.05, 0.05]", "[-0.11, 0.0513, 0.0487]"]
    );
}

/// `needlesim sweep` runs the grid of the --vary values on two threads: every variant's
/// needle force history is bitwise the one of the same scene run alone (one CPU thread,
/// in this process), and a failing variant gets its error while the others complete.
#[test]
fn sweep_matches_runs_alone_and_reports_failures() {
    use needlesim::core::scene::BackendChoice;
    use needlesim::needle::Simulation;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let scene = root.join("scenes/needle_insert_extract.toml");
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("sweep.csv");
    let o = needlesim()
        .arg("sweep")
        .arg(&scene)
        .args([
            "--vary",
            "needle.friction.coefficient=0.1,0.5,-2",
            "--steps",
            "2000",
        ])
        .args(["--jobs", "2", "--out"])
        .arg(&csv)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{stderr}");
    assert!(stderr.contains("variant 2 (-2) failed"), "{stderr}");
    // Read with a CSV reader: the error message is one quoted field, whatever it holds.
    let rows: Vec<csv::StringRecord> = csv::Reader::from_path(&csv)
        .unwrap()
        .records()
        .map(Result::unwrap)
        .collect();
    assert!(rows.iter().all(|r| r.len() == 9), "ragged rows");
    let failed: Vec<_> = rows.iter().filter(|r| &r[0] == "2").collect();
    assert_eq!(failed.len(), 1);
    assert!(failed[0][8].contains("coefficient"), "{:?}", failed[0]);
    let base = std::fs::read_to_string(&scene).unwrap();
    for (variant, mu) in [("0", 0.1), ("1", 0.5)] {
        let alone = base.replace(
            "friction = { coefficient = 0.3 }",
            &format!("friction = {{ coefficient = {mu} }}"),
        );
        assert_ne!(alone, base);
        let s = needlesim::Scene::from_toml_str(&alone, &root.join("scenes")).unwrap();
        let prep = Simulation::prepare(&s).unwrap();
        let (b, _) =
            needlesim::make_backend(&s, prep.tissue.clone(), Some(BackendChoice::Cpu), None)
                .unwrap();
        let mut sim = prep.start(b).unwrap();
        sim.step_n(2000).unwrap();
        let axial: Vec<f64> = sim.history().iter().map(|h| h.force.axial).collect();
        let swept: Vec<f64> = rows
            .iter()
            .filter(|r| &r[0] == variant)
            .map(|r| r[5].parse().unwrap())
            .collect();
        assert_eq!(swept.len(), 2000);
        // Rust prints an f64 with the fewest digits that read back to the same bits.
        assert!(
            axial
                .iter()
                .zip(&swept)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "variant {variant} differs from its run alone"
        );
        assert!(
            axial.iter().any(|&f| f != 0.0),
            "the needle touched the tissue"
        );
    }
}

/// `--jobs 0` is an error naming the option (it was silently run as 1), and a sweep CSV
/// that cannot be written names the file.
#[test]
fn sweep_refuses_zero_jobs_and_names_an_unwritable_csv() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let scene = root.join("scenes/needle_insert_extract.toml");
    // A sweep of one 5-step variant with `extra` options: it must fail; its stderr.
    let refused = |extra: &[&str]| {
        let o = needlesim()
            .arg("sweep")
            .arg(&scene)
            .args(["--vary", "needle.cutting=0.1", "--steps", "5"])
            .args(extra)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(!o.status.success(), "accepted: {stderr}");
        stderr
    };
    let stderr = refused(&["--jobs", "0"]);
    assert!(stderr.contains("--jobs"), "{stderr}");
    if std::path::Path::new("/dev/full").exists() {
        let stderr = refused(&["--out", "/dev/full"]);
        assert!(stderr.contains("/dev/full"), "{stderr}");
    }
}

/// A time step in seconds far above the stable one is warned of (a scene with dt = 1 s ran
/// its needle script between two steps without a word); the shipped scene is not.
#[test]
fn a_time_step_above_the_stable_one_is_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    // The sagging cube without gravity: nothing loads it, so even a step far too large
    // does not diverge.
    let text = std::fs::read_to_string(scenes.join("cube_sag_msm.toml"))
        .unwrap()
        .replace("gravity = [0.0, -9.81, 0.0]", "gravity = [0.0, 0.0, 0.0]");
    assert!(text.contains("dt = 1e-3"), "the scene's time step moved");
    assert!(
        text.contains("gravity = [0.0, 0.0, 0.0]"),
        "the scene's gravity moved"
    );
    for (dt, warned) in [("1e-3", false), ("1.0", true)] {
        let path = dir.path().join(format!("dt_{dt}.toml"));
        std::fs::write(&path, text.replace("dt = 1e-3", &format!("dt = {dt}"))).unwrap();
        let o = needlesim()
            .args(["run", "--steps", "3", "--threads", "1", "--out"])
            .arg(dir.path().join(format!("out_{dt}")))
            .arg(&path)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{dt}: {stderr}");
        assert_eq!(
            stderr.contains("warning: physics.dt"),
            warned,
            "{dt}: {stderr}"
        );
    }
}
