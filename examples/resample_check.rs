//! Resamples a closed OBJ or STL surface at a spacing and prints what came out: node and
//! triangle counts, the closest two nodes, the worst triangle, and volumes.
//!
//! `cargo run --release --example resample_check -- MESH SPACING [SCALE]`
use needlesim_core::geometry::{obj, resample, signed_volume};
use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let path = Path::new(&args[1]);
    let h: f64 = args[2].parse()?;
    let scale: f64 = args.get(3).map_or(Ok(1.0), |s| s.parse())?;
    let surface = if path.extension().is_some_and(|e| e == "stl") {
        obj::load_closed_stl(path, scale)?
    } else {
        obj::load_closed_surface(path, scale)?
    };
    let t0 = std::time::Instant::now();
    let c = resample::resample(&surface, h, path)?;
    let took = t0.elapsed();
    let n_surf = c
        .triangles
        .iter()
        .flatten()
        .map(|&v| v as usize + 1)
        .max()
        .unwrap_or(0);
    let mut min_d = f64::INFINITY;
    for i in 0..c.positions.len() {
        for j in 0..i {
            let d: f64 = (0..3)
                .map(|a| (c.positions[i][a] - c.positions[j][a]).powi(2))
                .sum::<f64>()
                .sqrt();
            min_d = min_d.min(d);
        }
    }
    let mut worst = f64::INFINITY;
    for t in &c.triangles {
        let [a, b, d] = t.map(|v| c.positions[v as usize]);
        let e = |p: [f64; 3], q: [f64; 3]| (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>();
        let u: [f64; 3] = std::array::from_fn(|i| b[i] - a[i]);
        let v: [f64; 3] = std::array::from_fn(|i| d[i] - a[i]);
        let cr = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let area = 0.5 * (cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]).sqrt();
        let l2 = e(a, b) + e(b, d) + e(d, a);
        // 1 for equilateral
        worst = worst.min(4.0 * 3f64.sqrt() * area / l2);
    }
    let vmin = c.node_volumes.iter().cloned().fold(f64::INFINITY, f64::min);
    println!(
        "input {} vertices {} triangles volume {:.5e}\nnodes {} (surface {}), triangles {}, resampled volume {:.5e} ({:+.2}%), in {:.2?}\nmin node distance {:.3} h, worst triangle quality {:.3}, min cell volume {:.3} h^3, box-equivalent nodes {:.0}",
        surface.vertices.len(), surface.triangles.len(), surface.volume,
        c.positions.len(), n_surf, c.triangles.len(),
        signed_volume(&c.positions, &c.triangles),
        100.0 * (signed_volume(&c.positions, &c.triangles) / surface.volume - 1.0), took,
        min_d / h, worst, vmin / h.powi(3), surface.volume / h.powi(3)
    );
    Ok(())
}
