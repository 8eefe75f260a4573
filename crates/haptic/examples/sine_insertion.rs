//! Drives the haptic loop with a simulated device: a sinusoidal insertion of the paper's
//! needle into its 639-node cube (`scenes/paper_insertion_lshm.toml`), 4 cm in and back
//! out in 4 s, at 1 kHz on one CPU thread. Writes every tick (device and needle position,
//! force sent, tissue force, depth, timing) to a CSV and prints the timing percentiles;
//! `crates/haptic/examples/plot_sine.py` plots the CSV.
//!
//! ```text
//! cargo run --release -p needlesim-haptic --example sine_insertion -- [SCENE] [OUT.csv]
//! ```

use needlesim::core::scene::BackendChoice;
use needlesim::{start_simulation, Scene};
use needlesim_haptic::{Clock, HapticConfig, HapticLoop, SineDevice};
use std::io::Write;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let scene_path = args.next().unwrap_or_else(|| {
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../scenes/paper_insertion_lshm.toml"
        )
        .into()
    });
    let out = args
        .next()
        .unwrap_or_else(|| "out/haptic/sine_insertion.csv".into());
    let scene = Scene::from_file(&scene_path)?;
    let (sim, _) = start_simulation(&scene, Some(BackendChoice::Cpu), None)?;
    let needle = sim.needle().ok_or("the scene has no needle")?;
    let device = SineDevice::along(needle, 0.04, 0.25, Clock::Wall);
    let config = HapticConfig {
        max_ticks: Some(4000),
        ..HapticConfig::default()
    };
    println!(
        "{} nodes, {} Hz, coupling K {} N/m; passive on devices with more than {:.3} N s/m of damping",
        sim.editor().n_mesh(),
        config.rate,
        config.coupling.stiffness,
        config.coupling.min_device_damping(1.0 / config.rate)
    );
    let stopped = HapticLoop::start(sim, device, config)?.join()?;
    if let Some(e) = stopped.error {
        return Err(e.into());
    }
    let s = stopped.stats;
    println!(
        "{} ticks, {} overruns; period p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms; work p50 {:.3} ms, p99 {:.3} ms; latency p50 {:.3} ms, p99 {:.3} ms",
        s.ticks, s.overruns, s.period.p50 * 1e3, s.period.p99 * 1e3, s.period.max * 1e3,
        s.work.p50 * 1e3, s.work.p99 * 1e3, s.latency.p50 * 1e3, s.latency.p99 * 1e3
    );
    let out = std::path::Path::new(&out);
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let mut f = std::io::BufWriter::new(std::fs::File::create(out)?);
    writeln!(f, "tick,wall_s,period_s,work_s,latency_s,device_x,needle_x,force_x,force_y,force_z,tissue_x,depth_m,state")?;
    for r in &stopped.records {
        writeln!(
            f,
            "{},{:.6},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:?}",
            r.index,
            r.wall,
            r.period,
            r.work,
            r.latency,
            r.device[0],
            r.needle[0],
            r.force[0],
            r.force[1],
            r.force[2],
            r.tissue[0],
            r.depth,
            r.state
        )?;
    }
    println!("wrote {}", out.display());
    Ok(())
}
