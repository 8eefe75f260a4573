//! `needlesim`: run a scene and write its frames, describe what a scene builds, or write
//! the validation report.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use needlesim::core::scene::BackendChoice;
use needlesim::gpu::GpuContext;
use needlesim::needle::{Checkpoint, SceneText};
use needlesim::{run_scene, RunError, RunOptions, Scene, SceneInfo, DEFAULT_SCENE};
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
        /// Steps to run (overrides the scene's run.steps or run.duration).
        #[arg(long)]
        steps: Option<u64>,
        /// Backend, overriding the scene's.
        #[arg(long, value_parser = backend_parser())]
        backend: Option<BackendChoice>,
        /// CPU threads: 1 for the single-threaded backend, 0 for all threads (overrides
        /// --backend).
        #[arg(long)]
        threads: Option<usize>,
        /// Write the whole state to <out>/checkpoint.bin at the first frame at or after
        /// every N steps.
        #[arg(long, value_name = "N")]
        checkpoint_every: Option<u64>,
        /// Continue the run whose output folder DIR holds a checkpoint.bin (the scene is
        /// the one stored in the checkpoint when none is given); its files keep what was
        /// written before the checkpoint.
        #[arg(long, value_name = "DIR", conflicts_with = "out")]
        resume: Option<PathBuf>,
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
        /// Only the needle force realism section (every shipped needle scene audited,
        /// friction off, spacing, model, speed and spin studies of the liver scene):
        /// writes realism.md, realism.csv and its plots.
        #[arg(long)]
        realism: bool,
        /// Leave the needle force realism section out of the full or reduced report (it
        /// runs alone with --realism).
        #[arg(long, conflicts_with = "realism")]
        no_realism: bool,
        /// Backends to time every case on, comma separated [default: cpu,cpu-parallel and
        /// gpu when an adapter is found].
        #[arg(long, value_delimiter = ',', value_parser = backend_parser())]
        backends: Vec<BackendChoice>,
    },
    /// Show a scene: a window that steps it in real time (keys: Space pause, N step,
    /// R reset, +/- speed, arrows and PageUp/PageDown move the needle; right-drag moves
    /// the needle, left-drag orbits, wheel zooms), or with --screenshot a PNG after
    /// --steps steps, without a window.
    View(ViewArgs),
    /// Run a scene once per combination of the --vary values, on local cores (one CPU
    /// thread per run), and write every run's needle force history to one CSV; a failing
    /// variant gets a row with its error and the others complete.
    Sweep {
        /// Scene file (TOML); the shipped default when omitted.
        scene: Option<PathBuf>,
        /// KEY=V1,V2,...: a dotted scene key (`material.stiffness`,
        /// `needle.keyframe.0.speed`) and its values (TOML literals); repeat for a grid.
        #[arg(long, required = true, value_name = "KEY=V1,V2,...")]
        vary: Vec<String>,
        /// Steps per run [default: the scene's run.steps or run.duration].
        #[arg(long)]
        steps: Option<u64>,
        /// Runs at once, at least 1 [default: the machine's cores].
        #[arg(long, value_parser = clap::value_parser!(u64).range(1..=4096))]
        jobs: Option<u64>,
        /// The CSV to write [default: out/<scene name>_sweep.csv].
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Print node count, neighbour statistics and the bytes of every allocated array.
    Info {
        /// Scene file (TOML); the shipped default when omitted.
        scene: Option<PathBuf>,
    },
}

/// The arguments of `needlesim view`.
#[derive(clap::Args, Debug)]
struct ViewArgs {
    /// Scene file (TOML); the shipped default when omitted.
    scene: Option<PathBuf>,
    /// Write a PNG here after the steps instead of opening a window.
    #[arg(long, value_name = "PNG")]
    screenshot: Option<PathBuf>,
    /// Steps before the screenshot [default: the scene's run.steps or run.duration].
    #[arg(long, requires = "screenshot")]
    steps: Option<u64>,
    /// Image or window width in pixels [default: 800 for a screenshot, 1024 for a
    /// window].
    #[arg(long)]
    width: Option<u32>,
    /// Image or window height in pixels [default: 600 for a screenshot, 768 for a
    /// window].
    #[arg(long)]
    height: Option<u32>,
    /// Backend, overriding the scene's.
    #[arg(long, value_parser = backend_parser())]
    backend: Option<BackendChoice>,
    /// CPU threads: 1 for the single-threaded backend, 0 for all threads (overrides
    /// --backend).
    #[arg(long)]
    threads: Option<usize>,
    /// Close the window after this many drawn frames (a smoke test under Xvfb).
    #[arg(long, conflicts_with = "screenshot")]
    frames: Option<u64>,
}

/// The `--backend` values, parsed by clap (its help lists them, its errors suggest the
/// nearest); the scene's [`BackendChoice`] itself stays free of the CLI's dependencies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum BackendArg {
    /// One CPU thread.
    Cpu,
    /// All CPU threads.
    CpuParallel,
    /// The wgpu compute backend; an error if no GPU adapter is found.
    Gpu,
    /// The GPU when an adapter is found, else all CPU threads.
    Auto,
}

impl From<BackendArg> for BackendChoice {
    fn from(b: BackendArg) -> BackendChoice {
        match b {
            BackendArg::Cpu => BackendChoice::Cpu,
            BackendArg::CpuParallel => BackendChoice::CpuParallel,
            BackendArg::Gpu => BackendChoice::Gpu,
            BackendArg::Auto => BackendChoice::Auto,
        }
    }
}

/// clap's parser of [`BackendArg`], giving a [`BackendChoice`].
fn backend_parser() -> impl clap::builder::TypedValueParser<Value = BackendChoice> {
    use clap::builder::TypedValueParser as _;
    clap::builder::EnumValueParser::<BackendArg>::new().map(BackendChoice::from)
}

fn load(scene: &Option<PathBuf>) -> Result<(Scene, String)> {
    let (s, stem, _) = load_with_text(scene)?;
    Ok((s, stem))
}

/// The scene, its name for the output folder, and its text (checkpoints carry it).
fn load_with_text(scene: &Option<PathBuf>) -> Result<(Scene, String, SceneText)> {
    match scene {
        Some(path) => {
            let s = Scene::from_file(path)?;
            let stem = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scene".into());
            let text = SceneText {
                toml: std::fs::read_to_string(path)
                    .with_context(|| format!("reading {}", path.display()))?,
                base_dir: s.base_dir.clone(),
            };
            Ok((s, stem, text))
        }
        None => Ok((
            Scene::from_toml_str(DEFAULT_SCENE, Path::new("."))?,
            "default".into(),
            SceneText {
                toml: DEFAULT_SCENE.to_string(),
                base_dir: PathBuf::from("."),
            },
        )),
    }
}

/// Exit status of a run stopped by SIGINT or SIGTERM (128 + SIGINT, as shells report it).
const INTERRUPTED: u8 = 130;

/// A flag that SIGINT and SIGTERM set (the run or sweep looks at it between steps); a
/// second signal ends the process at once with [`INTERRUPTED`].
fn stop_on_signals() -> Result<std::sync::Arc<std::sync::atomic::AtomicBool>> {
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || {
        if flag.swap(true, std::sync::atomic::Ordering::Relaxed) {
            std::process::exit(INTERRUPTED as i32);
        }
    })
    .context("installing the SIGINT/SIGTERM handler")?;
    Ok(stop)
}

/// Rust's panic message stays out of the way of a surface reader's panic, which the
/// library turns into an error naming the file (printed once, as `error: ...`).
fn quiet_guarded_panics() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !needlesim::core::geometry::panic_is_guarded() {
            default(info);
        }
    }));
}

/// `eprintln!` that ignores a write error (stderr on a closed pipe, `2>&1 | head`)
/// instead of panicking: the exit status still says what happened.
macro_rules! tell {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

fn main() -> std::process::ExitCode {
    quiet_guarded_panics();
    match run(Cli::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        // The reader of stdout went away (`needlesim ... | head`): nothing more to say.
        Err(e) if is_broken_pipe(&e) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            tell!("error: {}", message(&e));
            let interrupted = e.chain().any(|c| {
                matches!(
                    c.downcast_ref::<RunError>(),
                    Some(RunError::Interrupted { .. })
                ) || matches!(
                    c.downcast_ref::<needlesim::sweep::SweepError>(),
                    Some(needlesim::sweep::SweepError::Interrupted)
                )
            });
            std::process::ExitCode::from(if interrupted { INTERRUPTED } else { 1 })
        }
    }
}

/// The error and its causes joined by `: `, leaving out a cause whose text the message
/// already ends with (errors that print their source).
fn message(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for c in e.chain() {
        let text = c.to_string();
        if !out.ends_with(&text) {
            if !out.is_empty() {
                out.push_str(": ");
            }
            out.push_str(&text);
        }
    }
    out
}

fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// `println!` that returns the write error (a closed pipe) instead of panicking.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        writeln!(std::io::stdout(), $($arg)*)
    }};
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Info { scene } => {
            let (scene, _) = load(&scene)?;
            // One build serves the summary and the stability probe.
            let tissue = needlesim::needle::Simulation::prepare(&scene)?.tissue;
            say!("{}", SceneInfo::of_tissue(&scene, &tissue))?;
            let dt = tissue.step.dt as f64;
            // The probe of `dt = "auto"`: with a viscous tissue, its dashpot's damping in.
            let critical = tissue.critical_dt()?;
            let what = if tissue.shape.viscous() {
                "with the tissue's viscosity"
            } else {
                "undamped"
            };
            say!(
                "stability  critical dt {critical:.3e} s ({what}, at the initial state), scene dt {dt:.3e} s ({:.2} of it)",
                dt / critical
            )?;
        }
        Command::Report {
            out,
            full,
            realism: true,
            ..
        } => {
            let out = out.unwrap_or_else(|| PathBuf::from("out/report"));
            let mut pipe: std::io::Result<()> = Ok(());
            let r = needlesim_report::realism::run_and_write(full, &out, &mut |line| {
                if pipe.is_ok() {
                    pipe = say!("{line}");
                }
            });
            pipe?;
            let r = r?;
            say!(
                "report      {} ({:.0} s): realism.md, realism.csv, realism_spacing.png, realism_models.png",
                out.display(),
                r.seconds
            )?;
        }
        Command::Report {
            out,
            full,
            backends,
            no_realism,
            ..
        } => {
            use needlesim_report::{run_report, ReportOptions, ReportSize};
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
                realism: !no_realism,
            };
            // A closed stdout stops the report at the next line.
            let mut pipe: std::io::Result<()> = Ok(());
            let summary = run_report(&options, |line| {
                if pipe.is_ok() {
                    pipe = say!("{line}");
                }
            });
            pipe?;
            let summary = summary?;
            say!(
                "report      {} ({:.0} s): report.md, accuracy.csv, timing.csv, stable_dt.csv, extreme.csv, PNG plots",
                options.out.display(),
                summary.elapsed.as_secs_f64()
            )?;
        }
        Command::View(args) => view(args)?,
        Command::Sweep {
            scene,
            vary,
            steps,
            jobs,
            out,
        } => sweep(scene, &vary, steps, jobs, out)?,
        Command::Adapter => {
            let ctx = GpuContext::new(0)?;
            say!("{}", ctx.describe())?;
        }
        Command::Run {
            scene,
            out,
            steps,
            backend,
            threads,
            checkpoint_every,
            resume,
        } => {
            // The checkpoint to continue from, read once.
            let checkpoint = resume
                .as_ref()
                .map(|dir| Checkpoint::read(dir.join(needlesim::CHECKPOINT_FILE)))
                .transpose()?;
            let (scene, stem, text) = match (&scene, &checkpoint, &resume) {
                // Resuming without a scene: the one the checkpoint carries.
                (None, Some(c), Some(dir)) => {
                    let text = c
                        .scene
                        .clone()
                        .ok_or(needlesim::needle::CheckpointError::NoScene)?;
                    let stem = dir
                        .file_name()
                        .map(|s| s.to_string_lossy().into_owned())
                        .unwrap_or_else(|| "scene".into());
                    (
                        text.scene_stored_in(&dir.join("checkpoint.bin"))?,
                        stem,
                        text,
                    )
                }
                _ => load_with_text(&scene)?,
            };
            let out = resume
                .clone()
                .or(out)
                .unwrap_or_else(|| PathBuf::from("out").join(&stem));
            // SIGINT and SIGTERM stop the run at a step boundary with its files complete
            // up to the last frame; a second signal ends the process at once.
            let stop = stop_on_signals()?;
            let options = RunOptions {
                out_dir: out.clone(),
                steps,
                backend,
                threads,
                write_files: true,
                stop: Some(stop),
                checkpoint_every,
                resume: checkpoint,
                scene_text: Some(text),
            };
            // The run's length is known once dt is (run.duration with dt = "auto").
            let bar = ProgressBar::new(steps.unwrap_or(scene.run.steps));
            bar.set_style(
                ProgressStyle::with_template("{bar:40} {pos}/{len} steps  {per_sec}  eta {eta}")
                    .context("progress bar template")?,
            );
            let summary = run_scene(&scene, &options, |done, total| {
                bar.set_length(total);
                bar.set_position(done);
            });
            bar.finish_and_clear();
            // The needle force plots, from needle_force.csv, however the run ended (a run
            // that failed before writing anything leaves an earlier run's CSV, and so its
            // plots, as they were).
            let plots = if out.join("needle_force.csv").exists() {
                let plots = needlesim_report::needle_plots::needle_plots(&out).with_context(|| {
                    format!("drawing the needle force plots in {}", out.display())
                });
                match (&summary, plots) {
                    (_, Ok(p)) => p,
                    (Ok(_), Err(e)) => return Err(e),
                    (Err(_), Err(e)) => {
                        tell!("warning: {}", message(&e));
                        Vec::new()
                    }
                }
            } else {
                Vec::new()
            };
            let failed_write = matches!(&summary, Err(RunError::Io { .. }));
            let summary = summary.with_context(|| {
                // Only a run that wrote frames left output to point at (a configuration
                // error, a held or unusable folder, wrote none).
                if failed_write {
                    format!(
                        "running scene `{stem}` (a write failed: the output so far in {} \
                         may end with a partial row or frame)",
                        out.display()
                    )
                } else if out.join("frames.csv").is_file() {
                    format!(
                        "running scene `{stem}` (output so far, complete up to its last \
                         frame: {})",
                        out.display()
                    )
                } else {
                    format!("running scene `{stem}`")
                }
            })?;
            for w in &summary.warnings {
                tell!("warning: {w}");
            }
            let last = summary.frames.last().copied();
            say!("scene       {stem} ({})", scene.material.short_name())?;
            say!("backend     {}", summary.backend)?;
            say!("nodes       {}", summary.nodes)?;
            say!(
                "steps       {} in {:.3} s of stepping: {:.0} steps/s ({:.3} s total)",
                summary.steps,
                summary.step_time.as_secs_f64(),
                summary.steps_per_second(),
                summary.total_time.as_secs_f64()
            )?;
            if let Some(m) = last {
                say!(
                    "final       t = {:.4} s, kinetic energy {:.3e} J, max displacement {:.3e} m",
                    m.time,
                    m.kinetic_energy,
                    m.max_displacement
                )?;
            }
            if let Some(h) = summary.needle.as_ref().and_then(|h| h.last()) {
                say!(
                    "needle      {:?}, {} needle nodes, force axial {:.4} N lateral {:.4} N",
                    h.state,
                    h.needle_nodes,
                    h.force.axial,
                    h.force.lateral
                )?;
            }
            let needle_files = if summary.needle.is_some() {
                ", needle_force.csv, needle_force.png"
            } else {
                ""
            };
            say!(
                "output      {} ({} files: frames.csv, surface.pvd for ParaView{needle_files})",
                out.display(),
                summary.files.len() + plots.len()
            )?;
        }
    }
    Ok(())
}

/// `needlesim view`: a screenshot after some steps, or the interactive window.
fn view(args: ViewArgs) -> Result<()> {
    let ViewArgs {
        scene: scene_path,
        screenshot,
        steps,
        width,
        height,
        backend,
        threads,
        frames,
    } = args;
    use needlesim::needle::Simulation;
    let (w, h) = match screenshot {
        Some(_) => (width.unwrap_or(800), height.unwrap_or(600)),
        None => (width.unwrap_or(1024), height.unwrap_or(768)),
    };
    needlesim_view::render::check_size(w, h, needlesim_view::MAX_SIZE)?;
    let (scene, stem) = load(&scene_path)?;
    // On the GPU backend the picture is drawn on the simulation's own device: the device
    // is made for the scene's largest buffer (the renderer's, or the window's adapter).
    let on_gpu = threads.is_none() && backend.unwrap_or(scene.backend) == BackendChoice::Gpu;
    let mut prepared = match on_gpu {
        true => Some(Simulation::prepare(&scene)?),
        false => None,
    };
    let largest = prepared
        .as_ref()
        .map(|p| needlesim::gpu::largest_buffer(&p.tissue));
    let shared = scene.clone();
    let mut build = move |ctx: Option<&GpuContext>| -> Result<Simulation> {
        if let Some(ctx) = ctx {
            // The first build starts the tissue prepared for the buffer size; a reset
            // prepares it anew.
            let prep = match prepared.take() {
                Some(p) => p,
                None => Simulation::prepare(&shared)?,
            };
            return Ok(needlesim::start_simulation_on(prep, ctx)?);
        }
        let (sim, warning) = needlesim::start_simulation(&shared, backend, threads)?;
        if let Some(w) = warning {
            tell!("warning: {w}");
        }
        Ok(sim)
    };
    match screenshot {
        Some(path) => {
            // The renderer first: no adapter is found out before the steps, not after.
            let (mut renderer, mut sim) = match largest {
                Some(bytes) => {
                    let ctx = GpuContext::new(bytes)?;
                    (needlesim_view::Renderer::from_gpu(&ctx), build(Some(&ctx))?)
                }
                None => (needlesim_view::Renderer::headless()?, build(None)?),
            };
            let n = match steps {
                Some(n) => n,
                None => scene.run.steps_at(sim.dt())?,
            };
            sim.step_n(n)
                .with_context(|| format!("stepping scene `{stem}` ({n} steps)"))?;
            let frame = needlesim_view::Frame::gather(&mut sim)?;
            let camera = needlesim_view::Camera::frame(&frame);
            renderer
                .render_to_image(&frame, &camera, w, h)?
                .save_png(&path)?;
            say!(
                "screenshot  {} ({w}x{h}, scene `{stem}` after {n} steps, t = {:.3} s)",
                path.display(),
                sim.time()
            )?;
        }
        None => {
            let options = needlesim_view::window::WindowOptions {
                width: w,
                height: h,
                title: format!("needlesim: {stem}"),
                share_gpu: largest,
                frames,
                ..Default::default()
            };
            let report = needlesim_view::window::run_window(
                Box::new(move |ctx| build(ctx).map_err(Into::into)),
                options,
            )?;
            let device = match report.shared_gpu {
                true => "simulation on the same device",
                false => "simulation on the CPU or a device of its own",
            };
            say!(
                "window  {} frames, t = {:.3} s simulated in {:.3} s, drawn on {} ({device})",
                report.frames,
                report.simulated,
                report.wall,
                report.adapter
            )?;
        }
    }
    Ok(())
}

/// `needlesim sweep`: the grid of the --vary values, run on local cores, to one CSV.
fn sweep(
    scene_path: Option<PathBuf>,
    vary: &[String],
    steps: Option<u64>,
    jobs: Option<u64>,
    out: Option<PathBuf>,
) -> Result<()> {
    use needlesim::sweep;
    let (scene, stem, text) = load_with_text(&scene_path)?;
    if scene.needle.is_none() {
        anyhow::bail!(
            "a sweep records the needle's force and depth every step, and this scene has no \
             [needle] table: nothing to record (`needlesim run` it, or add a needle)"
        );
    }
    let vary = sweep::parse_vary_all(vary)?;
    let variants = sweep::grid(&vary);
    // Every override must apply to the scene before anything runs (a typo fails at once):
    // each value once, the other keys at their first values, so the check costs the sum
    // of the value counts, not their product (a 10^6-variant grid spent 45 s here).
    let firsts: Vec<sweep::Override> = vary
        .iter()
        .map(|(k, v)| (k.clone(), v[0].clone()))
        .collect();
    for (i, (_, values)) in vary.iter().enumerate() {
        for v in values {
            let mut one = firsts.clone();
            one[i].1 = v.clone();
            sweep::apply(&text.toml, &one)?;
        }
    }
    // ... and name a key the scene's tables know: a misspelt last part applied (a new
    // key may be an optional one) and then failed every variant on its own.
    for (key, values) in &vary {
        let one = sweep::apply(&text.toml, &[(key.clone(), values[0].clone())])?;
        if let Err(e) = Scene::from_toml_str(&one, &scene.base_dir) {
            let last = key.rsplit('.').next().unwrap_or(key);
            let message = e.to_string();
            if message.contains(&format!("unknown field `{last}`")) {
                anyhow::bail!("--vary {key}: the scene does not know this key: {message}");
            }
        }
    }
    // clap refuses 0 and more than 4096.
    let jobs = jobs.map_or_else(
        || std::thread::available_parallelism().map_or(1, |n| n.get()),
        |j| j as usize,
    );
    let out = out.unwrap_or_else(|| PathBuf::from(format!("out/{stem}_sweep.csv")));
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    // Rows go out as each variant finishes, flushed: a sweep stopped by SIGINT or SIGTERM
    // (or killed) keeps every variant that finished; a second signal ends the process at
    // once.
    let stop = stop_on_signals()?;
    // The csv crate quotes what needs it (RFC 4180): values and error messages with
    // commas, quotes or line breaks come back whole.
    let mut f = csv::WriterBuilder::new().has_headers(false).from_writer(
        std::fs::File::create(&out).with_context(|| format!("creating {}", out.display()))?,
    );
    let mut header = vec!["variant".to_string()];
    header.extend(vary.iter().map(|(k, _)| k.clone()));
    header.extend(
        [
            "step",
            "time_s",
            "depth_m",
            "axial_force_n",
            "lateral_force_n",
            "state",
            "error",
        ]
        .map(String::from),
    );
    f.write_record(&header)
        .and_then(|_| f.flush().map_err(csv::Error::from))
        .with_context(|| format!("writing {}", out.display()))?;
    let t0 = std::time::Instant::now();
    let (mut failed, mut finished, mut interrupted) = (0, 0, 0);
    let mut first_error: Option<String> = None;
    let mut write_error: Option<csv::Error> = None;
    let mut write =
        |i: usize, r: Result<sweep::VariantRun, sweep::SweepError>| -> csv::Result<()> {
            // Each value as its TOML literal (a string keeps its quotes), as --vary gave it.
            let values: Vec<String> = variants[i].iter().map(|(_, x)| x.to_string()).collect();
            let mut record = |tail: [String; 7]| {
                let mut row = vec![i.to_string()];
                row.extend(values.iter().cloned());
                row.extend(tail);
                f.write_record(&row)
            };
            match r {
                Ok(run) => {
                    finished += 1;
                    for (s, depth) in run.samples.iter().zip(&run.depths) {
                        record([
                            s.step.to_string(),
                            s.time.to_string(),
                            depth.to_string(),
                            s.force.axial.to_string(),
                            s.force.lateral.to_string(),
                            format!("{:?}", s.state).to_lowercase(),
                            String::new(),
                        ])?;
                    }
                }
                Err(sweep::SweepError::Interrupted) => interrupted += 1,
                Err(e) => {
                    failed += 1;
                    let msg = e.to_string();
                    first_error.get_or_insert_with(|| msg.clone());
                    record(std::array::from_fn(|k| {
                        if k == 6 {
                            msg.clone()
                        } else {
                            String::new()
                        }
                    }))?;
                    tell!("variant {i} ({}) failed: {msg}", values.join(", "));
                }
            }
            f.flush().map_err(csv::Error::from)
        };
    sweep::sweep_each(
        &text.toml,
        &scene.base_dir,
        &variants,
        steps,
        jobs,
        Some(&stop),
        |i, r| {
            if write_error.is_none() {
                if let Err(e) = write(i, r) {
                    write_error = Some(e);
                }
            }
        },
    );
    if let Some(e) = write_error {
        return Err(e).with_context(|| format!("writing {}", out.display()));
    }
    let wall = t0.elapsed().as_secs_f64();
    if stop.load(std::sync::atomic::Ordering::Relaxed) {
        return Err(anyhow::Error::new(sweep::SweepError::Interrupted)).with_context(|| {
            format!(
                "sweep interrupted: {finished} of {} variants finished and written to {} \
                 ({interrupted} stopped, {} not started)",
                variants.len(),
                out.display(),
                variants.len() - finished - failed - interrupted
            )
        });
    }
    if failed > 0 && failed == variants.len() {
        anyhow::bail!(
            "every one of the {failed} variants failed (their errors are in {}); the first: {}",
            out.display(),
            first_error.unwrap_or_default()
        );
    }
    say!(
        "sweep       {} variants ({failed} failed) on {jobs} threads in {wall:.1} s ({:.1} variants/min)\nwritten     {}",
        variants.len(),
        variants.len() as f64 / wall * 60.0,
        out.display()
    )?;
    Ok(())
}
