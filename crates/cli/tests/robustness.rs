//! Nothing lost, nothing crashes: runs stopped by a signal keep their files complete up to
//! the last frame, a re-run does not mix its frames with an earlier run's, a closed stdout
//! ends the CLI quietly, and devices are not read as input files.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn needlesim() -> Command {
    Command::new(env!("CARGO_BIN_EXE_needlesim"))
}

/// Rows of a CSV after its header, each split into fields; panics on a ragged row.
fn csv_rows(path: &Path, header: &str) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(header), "{}", path.display());
    let width = header.split(',').count();
    lines
        .map(|l| {
            let f: Vec<String> = l.split(',').map(str::to_string).collect();
            assert_eq!(f.len(), width, "{}: ragged row {l:?}", path.display());
            f
        })
        .collect()
}

/// The files `surface.pvd` lists; each must exist and be a complete VTK file.
fn pvd_frames(out: &Path) -> Vec<String> {
    let pvd = std::fs::read_to_string(out.join("surface.pvd")).unwrap();
    assert!(pvd.trim_end().ends_with("</VTKFile>"), "{pvd}");
    let files: Vec<String> = pvd
        .lines()
        .filter_map(|l| l.split("file=\"").nth(1))
        .map(|r| r.split('"').next().unwrap().to_string())
        .collect();
    for f in &files {
        let text = std::fs::read_to_string(out.join(f)).unwrap();
        assert!(text.trim_end().ends_with("</VTKFile>"), "{f} is cut short");
    }
    files
}

/// The paper scene (a needle) runs for far longer than the test waits; SIGINT arrives at
/// a moment that varies from run to run (0.2 to 1.2 s after the second frame). The run
/// ends with status 130 and a message naming the output folder, and `frames.csv`,
/// `needle_force.csv`, `surface.pvd` and its frames are complete: every row parses, every
/// listed frame is a whole file, one surface frame per CSV frame, and the needle rows run
/// up to at least the last frame's step.
#[test]
fn sigint_leaves_complete_files_up_to_the_last_frame() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("paper");
    let child = needlesim()
        .args(["run", "--steps", "100000000", "--threads", "1", "--out"])
        .arg(&out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let frames = out.join("frames.csv");
    while std::fs::read_to_string(&frames).map_or(0, |t| t.lines().count()) < 3 {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "no frames written"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .subsec_nanos();
    std::thread::sleep(Duration::from_millis(200 + (nanos % 1000) as u64));
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(130), "{stderr}");
    assert!(
        stderr.contains("interrupted at step") && stderr.contains(&out.display().to_string()),
        "{stderr}"
    );
    let rows = csv_rows(&frames, needlesim::output::CSV_HEADER);
    assert!(rows.len() >= 2);
    for r in &rows {
        assert!(
            r.iter().all(|x| x.parse::<f64>().is_ok_and(f64::is_finite)),
            "{r:?}"
        );
    }
    let last_step: u64 = rows.last().unwrap()[1].parse().unwrap();
    assert_eq!(pvd_frames(&out).len(), rows.len());
    let needle = csv_rows(
        &out.join("needle_force.csv"),
        needlesim::needle_output::NEEDLE_CSV_HEADER,
    );
    let needle_last: u64 = needle.last().unwrap()[0].parse().unwrap();
    assert!(needle_last >= last_step, "{needle_last} < {last_step}");
    assert!(out.join("needle_force.png").exists());
}

/// A second run into the same folder removes the first run's frames (fewer steps: fewer
/// frames) and leaves files it does not write alone.
#[test]
fn a_rerun_clears_the_previous_runs_frames() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("paper");
    let run = |steps: &str| {
        let o = needlesim()
            .args(["run", "--steps", steps, "--threads", "1", "--out"])
            .arg(&out)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run("600");
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    assert_eq!(pvd_frames(&out).len(), 7);
    run("200");
    let vtp = std::fs::read_dir(out.join("surface")).unwrap().count();
    assert_eq!((pvd_frames(&out).len(), vtp), (3, 3));
    let rows = csv_rows(&out.join("frames.csv"), needlesim::output::CSV_HEADER);
    assert_eq!(rows.len(), 3);
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "mine"
    );
}

/// `needlesim info | head -c 1` style: the reader goes away before the output is
/// written. The CLI ends without a panic message and with status 0.
#[test]
fn a_closed_stdout_ends_the_cli_quietly() {
    let mut child = needlesim()
        .args(["info"])
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cube_sag_deb.toml"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(o.status.success(), "{:?}: {stderr}", o.status);
}

/// An error with stderr on a closed pipe (`needlesim ... 2>&1 | head -1` once `head` has
/// gone) exits 1, not 101: printing the error panicked on the broken pipe.
#[test]
fn a_closed_stderr_leaves_the_error_exit_status() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[tissue]\nnot a scene").unwrap();
    for args in [vec!["info"], vec!["run", "--steps", "1"]] {
        let mut child = needlesim()
            .args(&args)
            .arg(&bad)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stderr.take());
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(1), "{args:?}: {status:?}");
    }
}

/// A device or a folder given as the surface file or the scene file is refused before it
/// is read (`/dev/zero` used to be read until memory ran out).
#[test]
fn devices_and_folders_are_not_read_as_input_files() {
    let dir = tempfile::tempdir().unwrap();
    for path in ["/dev/zero", "."] {
        let text = format!(
            "[tissue]\ngeometry = {{ kind = \"obj\", path = \"{path}\", spacing = 0.01 }}\n\
             [material]\nmodel = \"mass_spring\"\nstiffness = 100.0\n"
        );
        let scene = needlesim::Scene::from_toml_str(&text, dir.path()).unwrap();
        let err = needlesim::Tissue::from_scene(&scene)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("tissue.geometry.path") && err.contains("not a regular file"),
            "{path}: {err}"
        );
    }
    let err = needlesim::Scene::from_file("/dev/zero")
        .unwrap_err()
        .to_string();
    assert!(err.contains("not a regular file"), "{err}");
}

/// Values that pass an f64 check but break in f32, where the kernels compute: a step that
/// rounds to 0 or to infinity in f32 (it froze the clock, or wrote `NaN` times), and a
/// density whose node mass or inverse mass leaves the f32 range (the body froze, or
/// diverged at step 0). Each is an error naming its key.
#[test]
fn values_outside_the_f32_range_are_errors_naming_the_key() {
    let scene = |density: &str, dt: &str| {
        format!(
            "[tissue]\ndensity = {density}\n\
             geometry = {{ kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], spacing = 0.02 }}\n\
             [material]\nmodel = \"mass_spring\"\nstiffness = 100.0\n[physics]\ndt = {dt}\n"
        )
    };
    let error = |text: String| -> String {
        match needlesim::Scene::from_toml_str(&text, Path::new(".")) {
            Err(e) => e.to_string(),
            Ok(s) => needlesim::Tissue::from_scene(&s)
                .err()
                .map(|e| e.to_string())
                .unwrap_or_default(),
        }
    };
    for (density, dt, key) in [
        ("1000.0", "1e-50", "physics.dt"),
        ("1000.0", "1e300", "physics.dt"),
        ("1e300", "1e-4", "tissue.density"),
        ("1e-300", "1e-4", "tissue.density"),
    ] {
        let e = error(scene(density, dt));
        assert!(
            e.contains(key) && e.contains("f32"),
            "density {density}, dt {dt}: {e:?}"
        );
    }
    assert_eq!(error(scene("1000.0", "1e-4")), "");
}

/// A needle direction whose norm overflows or underflows in f64 still normalises to the
/// unit vector along it (it used to normalise [1e300, 0, 0] to zero).
#[test]
fn extreme_needle_directions_normalise() {
    use needlesim::needle::needle::unit;
    for v in [[1e300, 0.0, 0.0], [0.0, -1e-200, 0.0], [3e300, 4e300, 0.0]] {
        let u = unit(v).unwrap();
        let n = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
        assert!((n - 1.0).abs() < 1e-15, "{v:?} -> {u:?}");
        assert!((0..3).all(|a| u[a] * v[a] >= 0.0), "{v:?} -> {u:?}");
    }
    assert!(unit([0.0; 3]).is_err());
}

/// A surface file that makes its reader panic (binary legacy VTK whose POLYGONS count
/// disagrees with its cell list: vtkio asserts; an ASCII one is now caught before the
/// reader, naming the cell list) is one error naming the file, without Rust's panic
/// message before it.
#[test]
fn a_reader_panic_is_one_error_without_a_panic_message() {
    let dir = tempfile::tempdir().unwrap();
    let mut vtk =
        b"# vtk DataFile Version 3.0\nx\nBINARY\nDATASET POLYDATA\nPOINTS 6 float\n".to_vec();
    for v in [
        [1.0f32, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
    ] {
        for c in v {
            vtk.extend(c.to_be_bytes());
        }
    }
    vtk.extend(b"\nPOLYGONS 1 32\n");
    for t in [
        [0, 2, 4],
        [2, 1, 4],
        [1, 3, 4],
        [3, 0, 4],
        [2, 0, 5],
        [1, 2, 5],
        [3, 1, 5],
        [0, 3, 5],
    ] {
        for v in [3i32, t[0], t[1], t[2]] {
            vtk.extend(v.to_be_bytes());
        }
    }
    vtk.extend(b"\n");
    std::fs::write(dir.path().join("bad.vtk"), vtk).unwrap();
    let scene = dir.path().join("bad.toml");
    std::fs::write(
        &scene,
        "[tissue]\nneighbours = 6\ngeometry = { kind = \"vtk\", path = \"bad.vtk\", spacing = 0.5 }\n\
         [material]\nmodel = \"mass_spring\"\nstiffness = 1.0\n",
    )
    .unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_needlesim"))
        .arg("info")
        .arg(&scene)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains("bad.vtk") && stderr.contains("malformed"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
}
