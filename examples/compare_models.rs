//! Steps the same clamped cube with each of the four tissue models and prints how far its
//! free end sags and how long the steps took.
//!
//! `cargo run --release --example compare_models [steps]`

use needlesim::{Backend, CpuBackend, NodeField, Scene, Threading, Tissue};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let steps: u64 = std::env::args()
        .nth(1)
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(3000);
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    println!(
        "{:<16} {:>8} {:>12} {:>10}",
        "scene", "nodes", "sag (mm)", "steps/s"
    );
    for name in ["msm", "lshm", "deb", "deb_corotated", "pba"] {
        let scene = Scene::from_file(dir.join(format!("cube_sag_{name}.toml")))?;
        let tissue = Tissue::from_scene(&scene)?;
        let n = tissue.n_mesh;
        let mut backend = CpuBackend::new(tissue, Threading::Parallel)?;
        let mut start = vec![[0.0f32; 4]; n];
        backend.read(NodeField::Position, 0..n, &mut start)?;
        let t = std::time::Instant::now();
        backend.step(steps);
        let elapsed = t.elapsed().as_secs_f64();
        backend.check_finite()?;
        let mut end = vec![[0.0f32; 4]; n];
        backend.read(NodeField::Position, 0..n, &mut end)?;
        // Sag: the largest downward (-y) displacement.
        let sag = start
            .iter()
            .zip(&end)
            .map(|(a, b)| a[1] - b[1])
            .fold(0.0f32, f32::max);
        println!(
            "{:<16} {:>8} {:>12.2} {:>10.0}",
            name,
            n,
            sag * 1e3,
            steps as f64 / elapsed
        );
    }
    Ok(())
}
