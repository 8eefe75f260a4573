//! The command line tool's checkpoints: a run resumed with `--resume` writes the same
//! files as the uninterrupted one. (The library's checkpoint tests are in the root
//! package's tests/checkpoint.rs.)

use needlesim::needle::Checkpoint;
use std::path::Path;

fn needlesim() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_needlesim"))
}

fn cli(args: &[&str], out: &Path) -> String {
    let o = needlesim().args(args).arg(out).output().unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{args:?}: {stderr}");
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The shipped paper scene, 1,500 steps: once straight, once as a run that wrote
/// checkpoints every 500 steps and went on to step 1,100 before it stopped (as a killed
/// run would), then `--resume` without the scene (the checkpoint carries it). The resumed
/// folder holds the same bytes in every file as the straight one.
#[test]
fn the_cli_resumes_from_the_checkpoint_and_writes_the_same_files() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("straight"), dir.path().join("resumed"));
    cli(&["run", "--steps", "1500", "--threads", "1", "--out"], &a);
    cli(
        &[
            "run",
            "--steps",
            "1100",
            "--threads",
            "1",
            "--checkpoint-every",
            "500",
            "--out",
        ],
        &b,
    );
    let c = Checkpoint::read(b.join(needlesim::CHECKPOINT_FILE)).unwrap();
    assert_eq!(c.steps(), 1000, "the last checkpoint before step 1,100");
    assert!(c.scene.is_some());
    let said = cli(
        &["run", "--steps", "1500", "--threads", "1", "--resume"],
        &b,
    );
    assert!(said.contains("steps       500 "), "{said}");
    let listing = |d: &Path| {
        let mut names: Vec<String> = std::fs::read_dir(d.join("surface"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    };
    assert_eq!(listing(&a), listing(&b));
    let mut files = vec![
        "frames.csv".to_string(),
        "needle_force.csv".into(),
        "surface.pvd".into(),
    ];
    if a.join("reactions.csv").exists() {
        files.push("reactions.csv".into());
    }
    files.extend(listing(&a).into_iter().map(|n| format!("surface/{n}")));
    for f in files {
        let (x, y) = (
            std::fs::read(a.join(&f)).unwrap(),
            std::fs::read(b.join(&f)).unwrap(),
        );
        assert!(
            x == y,
            "{f} differs between the straight and the resumed run"
        );
    }
    // A folder without a checkpoint.
    let o = needlesim()
        .args(["run", "--resume"])
        .arg(dir.path())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(stderr.contains("checkpoint.bin"), "{stderr}");
}

/// `--resume DIR --steps M` with M below the checkpoint's step is an error that changes
/// nothing in the folder (it deleted the rows and frames past M and exited 0).
#[test]
fn resuming_to_a_step_before_the_checkpoint_is_an_error_and_loses_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    cli(
        &[
            "run",
            "--steps",
            "600",
            "--threads",
            "1",
            "--checkpoint-every",
            "500",
            "--out",
        ],
        &out,
    );
    let snapshot = |d: &Path| -> Vec<(String, Vec<u8>)> {
        let mut files: Vec<(String, Vec<u8>)> = Vec::new();
        for sub in [d.to_path_buf(), d.join("surface")] {
            for e in std::fs::read_dir(&sub).unwrap() {
                let p = e.unwrap().path();
                if p.is_file() {
                    files.push((p.display().to_string(), std::fs::read(&p).unwrap()));
                }
            }
        }
        files.sort();
        files
    };
    let before = snapshot(&out);
    let o = needlesim()
        .args(["run", "--steps", "200", "--threads", "1", "--resume"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "accepted: {stderr}");
    assert!(
        stderr.contains("step 200") && stderr.contains("500"),
        "{stderr}"
    );
    assert!(before == snapshot(&out), "the folder changed");
}

/// A second run into a folder a running process writes to is refused and changes nothing
/// (it deleted the first run's files while they were being written); the first run ends
/// as it would alone, and the folder is free again after it.
#[test]
fn a_second_run_into_a_folder_in_use_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let mut first = needlesim()
        .args(["run", "--steps", "50000", "--threads", "1", "--out"])
        .arg(&out)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let lock = out.join(needlesim::folder_lock::LOCK_FILE);
    let t0 = std::time::Instant::now();
    while !out.join("frames.csv").exists() {
        assert!(t0.elapsed().as_secs() < 60, "the first run did not start");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert!(lock.exists(), "the running process holds a lock file");
    let o = needlesim()
        .args(["run", "--steps", "10", "--threads", "1", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    let still_running = first.try_wait().unwrap().is_none();
    assert!(!o.status.success(), "accepted: {stderr}");
    assert!(stderr.contains("in use"), "{stderr}");
    assert!(still_running || stderr.contains("in use"));
    assert!(first.wait().unwrap().success(), "the first run failed");
    assert!(!lock.exists(), "the lock is released at the end");
    let rows = std::fs::read_to_string(out.join("needle_force.csv"))
        .unwrap()
        .lines()
        .count();
    assert_eq!(rows, 50001, "the first run's rows are all there");
    // Free again: a run into it now works.
    cli(&["run", "--steps", "10", "--threads", "1", "--out"], &out);
}

/// A run that wrote no surface frames before its checkpoint (`surface_frames = false`),
/// resumed with them switched on, lists in `surface.pvd` only the frames it wrote (it
/// listed every earlier frame of frames.csv, files that do not exist).
#[test]
fn a_resume_lists_only_the_surface_frames_on_disk() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let text = std::fs::read_to_string(root.join("scenes/needle_insert_extract.toml")).unwrap();
    assert!(text.contains("[run]\n"));
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, frames: bool| {
        let path = dir.path().join(name);
        let t = text.replace("[run]\n", &format!("[run]\nsurface_frames = {frames}\n"));
        std::fs::write(&path, t).unwrap();
        path
    };
    let (off, on) = (write("off.toml", false), write("on.toml", true));
    let out = dir.path().join("run");
    let o = needlesim()
        .arg("run")
        .arg(&off)
        .args([
            "--steps",
            "600",
            "--threads",
            "1",
            "--checkpoint-every",
            "300",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!out.join("surface.pvd").exists());
    let resumed_at = Checkpoint::read(out.join(needlesim::CHECKPOINT_FILE))
        .unwrap()
        .time();
    let o = needlesim()
        .arg("run")
        .arg(&on)
        .args(["--steps", "1000", "--threads", "1", "--resume"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let pvd = std::fs::read_to_string(out.join("surface.pvd")).unwrap();
    let listed: Vec<&str> = pvd
        .split("file=\"")
        .skip(1)
        .map(|s| s.split('"').next().unwrap())
        .collect();
    let on_disk = std::fs::read_dir(out.join("surface")).unwrap().count();
    assert!(on_disk > 0, "the resumed run wrote no frame");
    assert_eq!(listed.len(), on_disk, "{listed:?}");
    for f in &listed {
        assert!(
            out.join(f).is_file(),
            "surface.pvd lists {f}, which is not there"
        );
    }
    // Only the resumed part's frames: every listed time is at or after the checkpoint's.
    for t in pvd.split("timestep=\"").skip(1) {
        let t: f64 = t.split('"').next().unwrap().parse().unwrap();
        assert!(
            t >= resumed_at - 1e-6,
            "a frame at {t} s, before the checkpoint at {resumed_at} s"
        );
    }
}
