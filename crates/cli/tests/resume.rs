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
