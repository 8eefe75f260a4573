//! `needlesim`: run a scene and write its frames, or describe what a scene builds.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use needlesim::core::scene::BackendChoice;
use needlesim::gpu::GpuContext;
use needlesim::{run_scene, RunOptions, Scene, SceneInfo, DEFAULT_SCENE};
use std::path::{Path, PathBuf};

#[derive(Parser)]
#[command(
    name = "needlesim",
    version,
    about = "Needle insertion into meshfree soft tissue"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene (the shipped default when none is given) and write frames.csv and
    /// surface frames for ParaView.
    Run {
        /// Scene file (TOML).
        scene: Option<PathBuf>,
        /// Output directory [default: out/<scene name>].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Steps to run (overrides the scene's run.steps).
        #[arg(long)]
        steps: Option<u64>,
        /// Backend, overriding the scene's: cpu, cpu-parallel, gpu or auto.
        #[arg(long, value_parser = parse_backend)]
        backend: Option<BackendChoice>,
        /// CPU threads: 1 for the single-threaded backend, 0 for all threads (overrides
        /// --backend).
        #[arg(long)]
        threads: Option<usize>,
    },
    /// Print the GPU adapter wgpu finds (or why there is none).
    Adapter,
    /// Accuracy against reference solutions, wall time, stable time steps and extreme
    /// cases for every model: writes CSV files, PNG plots and report.md.
    Report {
        /// Output directory [default: out/report].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Full size (resolutions up to about 12,000 nodes; long) instead of the reduced one.
        #[arg(long)]
        full: bool,
        /// Backends to time every case on, comma separated [default: cpu,cpu-parallel and
        /// gpu when an adapter is found].
        #[arg(long, value_delimiter = ',', value_parser = parse_backend)]
        backends: Vec<BackendChoice>,
    },
    /// Print node count, neighbour statistics and the bytes of every allocated array.
    Info {
        /// Scene file (TOML); the shipped default when omitted.
        scene: Option<PathBuf>,
    },
}

fn parse_backend(s: &str) -> Result<BackendChoice, String> {
    match s {
        "cpu" => Ok(BackendChoice::Cpu),
        "cpu-parallel" => Ok(BackendChoice::CpuParallel),
        "gpu" => Ok(BackendChoice::Gpu),
        "auto" => Ok(BackendChoice::Auto),
        _ => Err(format!(
            "unknown backend `{s}` (expected cpu, cpu-parallel, gpu or auto)"
        )),
    }
}

fn load(scene: &Option<PathBuf>) -> Result<(Scene, String)> {
    match scene {
        Some(path) => {
            let s = Scene::from_file(path)?;
            let stem = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scene".into());
            Ok((s, stem))
        }
        None => Ok((
            Scene::from_toml_str(DEFAULT_SCENE, Path::new("."))?,
            "default".into(),
        )),
    }
}

fn main() -> std::process::ExitCode {
    match run(Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Info { scene } => {
            let (scene, _) = load(&scene)?;
            // One build serves the summary and the stability probe.
            let tissue = needlesim::needle::Simulation::prepare(&scene)?.tissue;
            println!("{}", SceneInfo::of_tissue(&scene, &tissue));
            let dt = tissue.step.dt as f64;
            let mut b = needlesim::CpuBackend::new(tissue, needlesim::Threading::Parallel)?;
            let est = needlesim::core::stability::max_eigenvalue(&mut b, 40)?;
            println!(
                "stability  critical dt {:.3e} s (undamped, at the initial state), scene dt {:.3e} s ({:.2} of it)",
                est.critical_dt,
                dt,
                dt / est.critical_dt
            );
        }
        Command::Report {
            out,
            full,
            backends,
        } => {
            use needlesim::report::{run_report, ReportOptions, ReportSize};
            let timing_backends = if backends.is_empty() {
                let mut b = vec![BackendChoice::Cpu, BackendChoice::CpuParallel];
                if GpuContext::new(0).is_ok() {
                    b.push(BackendChoice::Gpu);
                }
                b
            } else {
                backends
            };
            let options = ReportOptions {
                out: out.unwrap_or_else(|| PathBuf::from("out/report")),
                size: if full {
                    ReportSize::Full
                } else {
                    ReportSize::Reduced
                },
                timing_backends,
            };
            let summary = run_report(&options, |line| println!("{line}"))?;
            println!(
                "report      {} ({:.0} s): report.md, accuracy.csv, timing.csv, stable_dt.csv, extreme.csv, PNG plots",
                options.out.display(),
                summary.elapsed.as_secs_f64()
            );
        }
        Command::Adapter => {
            let ctx = GpuContext::new(0)?;
            println!("{}", ctx.describe());
        }
        Command::Run {
            scene,
            out,
            steps,
            backend,
            threads,
        } => {
            let (scene, stem) = load(&scene)?;
            let out = out.unwrap_or_else(|| PathBuf::from("out").join(&stem));
            let options = RunOptions {
                out_dir: out.clone(),
                steps,
                backend,
                threads,
                write_files: true,
            };
            let total = steps.unwrap_or(scene.run.steps);
            let bar = ProgressBar::new(total);
            bar.set_style(
                ProgressStyle::with_template("{bar:40} {pos}/{len} steps  {per_sec}  eta {eta}")
                    .context("progress bar template")?,
            );
            let summary = run_scene(&scene, &options, |done, _| bar.set_position(done))
                .with_context(|| format!("running scene `{stem}`"))?;
            bar.finish_and_clear();
            for w in &summary.warnings {
                eprintln!("warning: {w}");
            }
            let last = summary.frames.last().copied();
            println!("scene       {stem} ({})", scene.material.short_name());
            println!("backend     {}", summary.backend);
            println!("nodes       {}", summary.nodes);
            println!(
                "steps       {} in {:.3} s of stepping: {:.0} steps/s ({:.3} s total)",
                summary.steps,
                summary.step_time.as_secs_f64(),
                summary.steps_per_second(),
                summary.total_time.as_secs_f64()
            );
            if let Some(m) = last {
                println!(
                    "final       t = {:.4} s, kinetic energy {:.3e} J, max displacement {:.3e} m",
                    m.time, m.kinetic_energy, m.max_displacement
                );
            }
            if let Some(h) = summary.needle.as_ref().and_then(|h| h.last()) {
                println!(
                    "needle      {:?}, {} needle nodes, force axial {:.4} N lateral {:.4} N",
                    h.state, h.needle_nodes, h.force.axial, h.force.lateral
                );
            }
            let needle_files = if summary.needle.is_some() {
                ", needle_force.csv, needle_force.png"
            } else {
                ""
            };
            println!(
                "output      {} ({} files: frames.csv, surface.pvd for ParaView{needle_files})",
                out.display(),
                summary.files.len()
            );
        }
    }
    Ok(())
}
