//! Runs a scene: builds the tissue and a backend, steps it, and writes per-frame metrics
//! (CSV) and surface meshes (VTK XML PolyData with a .pvd time series).

use crate::frame::FrameMetrics;
use crate::output::{CsvWriter, SurfaceWriter};
use needlesim_core::scene::BackendChoice;
use needlesim_core::{
    Backend, CpuBackend, NodeField, Scene, SceneError, SimError, Threading, Tissue,
};
use needlesim_gpu::{GpuBackend, GpuContext};
use needlesim_needle::{NeedleSample, Prepared, Simulation, SimulationError};
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use thiserror::Error;

/// Why a run failed.
#[derive(Debug, Error)]
pub enum RunError {
    /// The scene could not be built.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The simulation failed (diverged).
    #[error(transparent)]
    Sim(#[from] SimError),
    /// An output file could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The thread pool could not be created.
    #[error(transparent)]
    Threads(#[from] needlesim_core::cpu::ThreadPoolError),
    /// The needle simulation failed (bad `[needle]` table, capacity reached, ...).
    #[error(transparent)]
    Needle(SimulationError),
    /// The GPU backend was asked for and cannot run.
    #[error(transparent)]
    Gpu(#[from] needlesim_gpu::GpuError),
    /// [`RunOptions::stop`] was set (the CLI sets it on SIGINT and SIGTERM).
    #[error("interrupted at step {step}{}{}", match out_dir {
        Some(d) => format!("; {frames} frames written to {} (complete up to the last frame)", d.display()),
        None => String::new(),
    }, match checkpoint {
        Some(c) => format!("; a checkpoint at step {c} is in the same folder: continue with `--resume`"),
        None => String::new(),
    })]
    Interrupted {
        /// Steps completed.
        step: u64,
        /// Frames written.
        frames: usize,
        /// Where the output is, if files were written.
        out_dir: Option<PathBuf>,
        /// Step of the last checkpoint written, if any.
        checkpoint: Option<u64>,
    },
    /// A checkpoint cannot be written or resumed from.
    #[error(transparent)]
    Checkpoint(#[from] needlesim_needle::CheckpointError),
    /// `checkpoint_every` is 0.
    #[error("checkpoint_every must be at least 1 step")]
    CheckpointEvery,
    /// A resumed run asked to end before the checkpoint it resumes from: it would have
    /// nothing to run and would cut the rows and frames past its end from the folder.
    #[error(
        "the run would end at step {steps}, before the checkpoint's step {checkpoint}: resume \
         with more steps (or none: the scene's own), or start a new run in another folder; \
         nothing in the folder was changed"
    )]
    ResumeBeforeCheckpoint {
        /// Step of the checkpoint.
        checkpoint: u64,
        /// Steps the run asked for.
        steps: u64,
    },
    /// Another running process writes into the output folder
    /// ([`crate::folder_lock`]): nothing in it was changed.
    #[error(
        "{} is in use by another needlesim run (process {pid}, lock file {}): wait for it \
         to end or choose another --out; nothing in the folder was changed",
        dir.display(),
        crate::folder_lock::LOCK_FILE
    )]
    FolderInUse {
        /// The folder.
        dir: PathBuf,
        /// The process holding it.
        pid: u32,
    },
}

impl From<SimulationError> for RunError {
    /// Scene and divergence errors keep their own variants.
    fn from(e: SimulationError) -> Self {
        match e {
            SimulationError::Scene(s) => RunError::Scene(s),
            SimulationError::Sim(s) => RunError::Sim(s),
            SimulationError::Checkpoint(c) => RunError::Checkpoint(c),
            other => RunError::Needle(other),
        }
    }
}

/// Options of a run that are not part of the scene.
#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Output directory (created).
    pub out_dir: PathBuf,
    /// Overrides the scene's `run.steps`.
    pub steps: Option<u64>,
    /// Overrides the scene's backend.
    pub backend: Option<BackendChoice>,
    /// CPU threads (0 = all); implies a CPU backend and overrides `backend`.
    pub threads: Option<usize>,
    /// Write output files (CSV and surface frames); off for benchmarks.
    pub write_files: bool,
    /// When set (from a signal handler or another thread), the run stops at the next step
    /// boundary with [`RunError::Interrupted`]; it is looked at every 16 steps, or after
    /// more steps when 16 take less than 50 ms.
    pub stop: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    /// Writes `checkpoint.bin` into the output folder at the first frame at or after every
    /// this many steps (atomically: an interruption leaves the previous one intact).
    pub checkpoint_every: Option<u64>,
    /// Continues the run from this checkpoint (read from `checkpoint.bin` in the output
    /// folder; taken with the same scene, `run.steps` may be larger): the files keep their
    /// rows and frames before the checkpoint's step and go on from there.
    pub resume: Option<needlesim_needle::Checkpoint>,
    /// The scene's text, stored in the checkpoints so that they are enough to resume.
    pub scene_text: Option<needlesim_needle::SceneText>,
}

impl RunOptions {
    /// Defaults: the scene's steps and backend, files written to `out_dir`.
    pub fn new(out_dir: impl Into<PathBuf>) -> RunOptions {
        RunOptions {
            out_dir: out_dir.into(),
            steps: None,
            backend: None,
            threads: None,
            write_files: true,
            stop: None,
            checkpoint_every: None,
            resume: None,
            scene_text: None,
        }
    }
}

/// What a run did.
#[derive(Debug, Clone)]
pub struct RunSummary {
    /// Backend name.
    pub backend: String,
    /// Active nodes.
    pub nodes: usize,
    /// Steps run.
    pub steps: u64,
    /// Wall time spent stepping (not building or writing).
    pub step_time: Duration,
    /// Wall time of the whole run.
    pub total_time: Duration,
    /// Metrics of every frame.
    pub frames: Vec<FrameMetrics>,
    /// Files written.
    pub files: Vec<PathBuf>,
    /// Warnings (for example the GPU fallback of `backend = "auto"`).
    pub warnings: Vec<String>,
    /// The needle's record of every step (scenes with a needle).
    pub needle: Option<Vec<NeedleSample>>,
}

impl RunSummary {
    /// Steps per second of stepping time.
    pub fn steps_per_second(&self) -> f64 {
        self.steps as f64 / self.step_time.as_secs_f64().max(1e-12)
    }
}

/// The scene's simulation, started on the backend [`make_backend`] picks, and its warning
/// (a GPU fallback), if any.
pub fn start_simulation(
    scene: &Scene,
    backend: Option<BackendChoice>,
    threads: Option<usize>,
) -> Result<(Simulation, Option<String>), RunError> {
    let prep = Simulation::prepare(scene)?;
    let (b, warning) = make_backend(scene, prep.tissue.clone(), backend, threads)?;
    Ok((prep.start(b)?, warning))
}

/// The prepared simulation started on the GPU backend on the device of `ctx` (one the
/// caller shares: a window's, a renderer's). Make `ctx` with storage bindings of at least
/// [`needlesim_gpu::largest_buffer`] of `prep.tissue`.
pub fn start_simulation_on(prep: Prepared, ctx: &GpuContext) -> Result<Simulation, RunError> {
    let backend = GpuBackend::with_context(ctx.clone(), &prep.tissue)?;
    Ok(prep.start(Box::new(backend))?)
}

/// The backend a scene asks for (or `backend`, or a CPU backend with `threads` threads,
/// 0 = all), and a warning when `auto` fell back to the CPU.
pub fn make_backend(
    scene: &Scene,
    tissue: Tissue,
    backend: Option<BackendChoice>,
    threads: Option<usize>,
) -> Result<(Box<dyn Backend>, Option<String>), RunError> {
    let cpu = |tissue, threading| -> Result<Box<dyn Backend>, RunError> {
        Ok(Box::new(CpuBackend::new(tissue, threading)?))
    };
    match (threads, backend.unwrap_or(scene.backend)) {
        (Some(0), _) => Ok((cpu(tissue, Threading::Parallel)?, None)),
        (Some(1), _) => Ok((cpu(tissue, Threading::Single)?, None)),
        (Some(n), _) => Ok((cpu(tissue, Threading::Threads(n))?, None)),
        (None, BackendChoice::Cpu) => Ok((cpu(tissue, Threading::Single)?, None)),
        (None, BackendChoice::CpuParallel) => Ok((cpu(tissue, Threading::Parallel)?, None)),
        (None, BackendChoice::Gpu) => Ok((Box::new(GpuBackend::new(&tissue)?), None)),
        (None, BackendChoice::Auto) => match GpuBackend::new(&tissue) {
            Ok(g) => Ok((Box::new(g), None)),
            Err(e) => Ok((
                cpu(tissue, Threading::Parallel)?,
                Some(format!("GPU backend unavailable, running on the CPU: {e}")),
            )),
        },
    }
}

/// Steps between the first two looks at [`RunOptions::stop`] (a frame may hold
/// thousands); the stretch doubles while a stretch takes less than [`STOP_CHECK_SECONDS`],
/// so that fast scenes are not cut into small batches (a GPU submits once per batch).
const STOP_CHECK_STEPS: u64 = 16;
/// Wall time a stretch of steps between two looks at [`RunOptions::stop`] aims below.
const STOP_CHECK_SECONDS: f64 = 0.05;

/// The checkpoint's file name in the output folder ([`RunOptions::checkpoint_every`]).
pub const CHECKPOINT_FILE: &str = "checkpoint.bin";

/// The open output files of a run.
struct Outputs {
    dir: PathBuf,
    frames: Option<CsvWriter>,
    surface: Option<SurfaceWriter>,
    reactions: Option<(PathBuf, std::io::BufWriter<std::fs::File>)>,
    needle: Option<crate::needle_output::NeedleCsv>,
}

fn io_error(path: &Path) -> impl FnOnce(std::io::Error) -> RunError {
    let path = path.to_path_buf();
    move |source| RunError::Io { path, source }
}

impl Outputs {
    /// Opens this run's files in `dir`: a fresh run clears the files of an earlier run; a
    /// resumed one (`resume_at`: the checkpoint's step) keeps the rows and frames of steps
    /// before it. Returns the files and the number of frames kept.
    fn create(
        scene: &Scene,
        sim: &Simulation,
        dir: &Path,
        resume_at: Option<u64>,
    ) -> Result<(Outputs, usize), RunError> {
        std::fs::create_dir_all(dir).map_err(io_error(dir))?;
        let kept = match resume_at {
            Some(step) => crate::output::keep_before(dir, step).map_err(io_error(dir))?,
            None => {
                crate::output::clear_previous_run(dir).map_err(io_error(dir))?;
                Vec::new()
            }
        };
        let frames_path = dir.join("frames.csv");
        let frames = Some(if resume_at.is_some() {
            CsvWriter::append(&frames_path).map_err(io_error(&frames_path))?
        } else {
            CsvWriter::create(&frames_path).map_err(io_error(&frames_path))?
        });
        let surface = if scene.run.surface_frames {
            // The times the frames were written with (`FrameMetrics::time`).
            let dt = sim.dt();
            let times: Vec<(f64, usize)> = kept.iter().map(|&(s, k)| (s as f64 * dt, k)).collect();
            Some(SurfaceWriter::resume(dir, &times).map_err(io_error(dir))?)
        } else {
            None
        };
        // The reactions of the held sets, one row per frame.
        let mut reactions = None;
        if !sim.boundary().held.is_empty() && resume_at.is_some() {
            let path = dir.join("reactions.csv");
            let file = std::fs::OpenOptions::new()
                .append(true)
                .open(&path)
                .map_err(io_error(&path))?;
            reactions = Some((path, std::io::BufWriter::new(file)));
        } else if !sim.boundary().held.is_empty() {
            let path = dir.join("reactions.csv");
            let mut w =
                std::io::BufWriter::new(std::fs::File::create(&path).map_err(io_error(&path))?);
            let mut header = String::from("frame,step,time_s");
            for h in &sim.boundary().held {
                for c in ["x", "y", "z"] {
                    header.push_str(&format!(",{}_f{c}_n", h.name));
                }
            }
            writeln!(w, "{header}").map_err(io_error(&path))?;
            reactions = Some((path, w));
        }
        let needle = if sim.needle().is_some() {
            Some(crate::needle_output::NeedleCsv::create(dir).map_err(io_error(dir))?)
        } else {
            None
        };
        Ok((
            Outputs {
                dir: dir.to_path_buf(),
                frames,
                surface,
                reactions,
                needle,
            },
            kept.len(),
        ))
    }

    /// Writes one frame to every file and flushes them.
    fn frame(
        &mut self,
        sim: &mut Simulation,
        m: &FrameMetrics,
        pos: &[[f32; 4]],
        rest: &[[f64; 3]],
    ) -> Result<(), RunError> {
        let dir = self.dir.clone();
        if let Some(w) = self.frames.as_mut() {
            w.row(m).map_err(io_error(&dir.join("frames.csv")))?;
        }
        if let Some(w) = self.surface.as_mut() {
            w.frame(
                m.time,
                pos,
                rest,
                sim.triangles(),
                &sim.needle_node_indices(),
            )
            .map_err(io_error(&dir.join("surface")))?;
        }
        if let Some((path, w)) = self.reactions.as_mut() {
            let r = sim.reactions()?;
            let mut row = format!("{},{},{:.6e}", m.frame, m.step, m.time);
            for f in r.iter().flat_map(|r| r.force) {
                row.push_str(&format!(",{f:.6e}"));
            }
            writeln!(w, "{row}").map_err(io_error(path))?;
            w.flush().map_err(io_error(path))?;
        }
        if let Some(w) = self.needle.as_mut() {
            let path = w.path().to_path_buf();
            w.append(sim, false).map_err(io_error(&path))?;
        }
        Ok(())
    }

    /// Writes what is left (the needle rows since the last frame) and returns every file
    /// written.
    fn finish(self, sim: &Simulation) -> Result<Vec<PathBuf>, RunError> {
        let dir = self.dir;
        let mut files = Vec::new();
        if let Some(w) = self.frames {
            files.push(w.finish().map_err(io_error(&dir.join("frames.csv")))?);
        }
        if let Some(w) = self.surface {
            files.extend(w.finish().map_err(io_error(&dir.join("surface.pvd")))?);
        }
        if let Some((path, mut w)) = self.reactions {
            w.flush().map_err(io_error(&path))?;
            files.push(path);
        }
        if let Some(mut w) = self.needle {
            let path = w.path().to_path_buf();
            w.append(sim, true).map_err(io_error(&path))?;
            files.push(path);
        }
        Ok(files)
    }
}

/// The most nodes a run probes for its stable time step when `physics.dt` is given in
/// seconds ([`time_step_warning`]).
pub const MAX_PROBED_NODES: usize = 100_000;

/// A warning when `physics.dt` is given in seconds and exceeds the largest stable step of
/// `tissue` at its initial state (the probe of `dt = "auto"`, [`Tissue::critical_dt`]):
/// a run that does not diverge (nothing loads the tissue) gives no other sign (a scene
/// with dt = 1 s ran its whole needle script between two steps without a word). The
/// probe costs about a hundred force evaluations on a CPU copy, so tissues of more than
/// [`MAX_PROBED_NODES`] nodes are not probed. `run_scene` and Python's `Simulation`
/// report it.
pub fn time_step_warning(scene: &Scene, tissue: &Tissue) -> Result<Option<String>, RunError> {
    let needlesim_core::scene::TimeStep::Seconds(dt) = scene.physics.dt else {
        return Ok(None);
    };
    if tissue.n_mesh > MAX_PROBED_NODES {
        return Ok(None);
    }
    let critical = tissue.critical_dt()?;
    Ok((dt > critical).then(|| {
        format!(
            "physics.dt = {dt} s is {:.1} times the largest stable step estimated at the \
             initial state ({critical:.3e} s, as `needlesim info` prints): the run may \
             diverge, or step past the needle's script; use dt = \"auto\"",
            dt / critical
        )
    }))
}

/// Builds and runs a scene. `progress(steps_done, steps_total)` is called after every
/// frame. A scene with a `[needle]` table also writes the needle force of every step
/// (`needle_force.csv`; the `needlesim` command line tool draws its plots from it).
///
/// Output is streamed (see [`crate::output`]): when the run stops early (a divergence,
/// a needle error, [`RunOptions::stop`]), every file is complete up to the last frame
/// (the needle rows up to the last step) before the error is returned. A run first removes the files
/// an earlier run left in its folder ([`crate::output::clear_previous_run`]).
pub fn run_scene(
    scene: &Scene,
    options: &RunOptions,
    mut progress: impl FnMut(u64, u64),
) -> Result<RunSummary, RunError> {
    let start = Instant::now();
    let checkpoint_path = options.out_dir.join(CHECKPOINT_FILE);
    if options.checkpoint_every == Some(0) {
        return Err(RunError::CheckpointEvery);
    }
    let prep = Simulation::prepare(scene)?;
    let dt = prep.tissue.step.dt as f64;
    let mut warnings = Vec::new();
    if options.resume.is_none() {
        warnings.extend(time_step_warning(scene, &prep.tissue)?);
    }
    let (backend, warning) =
        make_backend(scene, prep.tissue.clone(), options.backend, options.threads)?;
    warnings.extend(warning);
    let mut sim = match &options.resume {
        Some(c) => prep.resume(backend, c.clone())?,
        None => prep.start(backend)?,
    };
    let resume_at = options.resume.is_some().then(|| sim.steps());
    let has_needle = sim.needle().is_some();
    let total = match options.steps {
        Some(n) => n,
        None => scene.run.steps_at(sim.dt())?,
    };
    if let Some(at) = resume_at.filter(|&at| total < at) {
        return Err(RunError::ResumeBeforeCheckpoint {
            checkpoint: at,
            steps: total,
        });
    }
    let every = scene.run.output_every;
    // Held until the run returns: no other run clears or appends to this folder meanwhile.
    let _lock = if options.write_files {
        // An existing file (or device) there is no folder: "File exists" named no cause.
        if options.out_dir.exists() && !options.out_dir.is_dir() {
            return Err(RunError::Io {
                path: options.out_dir.clone(),
                source: std::io::Error::new(
                    std::io::ErrorKind::AlreadyExists,
                    "the output folder is an existing file, not a folder: give another --out",
                ),
            });
        }
        std::fs::create_dir_all(&options.out_dir).map_err(io_error(&options.out_dir))?;
        Some(
            crate::folder_lock::FolderLock::acquire(&options.out_dir).map_err(|e| match e {
                crate::folder_lock::LockError::Held { pid } => RunError::FolderInUse {
                    dir: options.out_dir.clone(),
                    pid,
                },
                crate::folder_lock::LockError::Io(e) => io_error(&options.out_dir)(e),
            })?,
        )
    } else {
        None
    };
    let (mut outputs, kept) = if options.write_files {
        let (o, kept) = Outputs::create(scene, &sim, &options.out_dir, resume_at)?;
        (Some(o), kept)
    } else {
        (None, 0)
    };
    let mut last_checkpoint = resume_at;
    let stopped = || {
        options
            .stop
            .as_ref()
            .is_some_and(|s| s.load(std::sync::atomic::Ordering::Relaxed))
    };
    let mut frames = Vec::new();
    let mut step_time = Duration::ZERO;
    let first_step = sim.steps();
    let mut done = first_step;
    let mut stretch = STOP_CHECK_STEPS;
    let mut run = || -> Result<(), RunError> {
        loop {
            let n = sim.backend().n_active();
            let mut pos = vec![[0.0f32; 4]; n];
            let mut vel = vec![[0.0f32; 4]; n];
            let mut force = vec![[0.0f32; 4]; n];
            let backend = sim.backend();
            backend.read(NodeField::Position, 0..n, &mut pos)?;
            backend.read(NodeField::Velocity, 0..n, &mut vel)?;
            backend.read(NodeField::Force, 0..n, &mut force)?;
            sim.check_read(&pos, &vel)?;
            let rest = sim.rest_positions();
            let m = FrameMetrics::measure(kept + frames.len(), done, dt, &pos, &vel, &force, &rest);
            if let Some(o) = outputs.as_mut() {
                o.frame(&mut sim, &m, &pos, &rest)?;
            }
            frames.push(m);
            if let Some(n) = options.checkpoint_every {
                if done >= last_checkpoint.map_or(n, |c| c + n) && done < total {
                    std::fs::create_dir_all(&options.out_dir)
                        .map_err(io_error(&options.out_dir))?;
                    let mut c = sim.checkpoint()?;
                    c.scene = options.scene_text.clone();
                    c.write(&checkpoint_path)?;
                    last_checkpoint = Some(done);
                }
            }
            progress(done, total);
            if done >= total {
                return Ok(());
            }
            let chunk = every.min(total - done);
            let t0 = Instant::now();
            let mut stepped = 0;
            while stepped < chunk {
                if stopped() {
                    step_time += t0.elapsed();
                    return Err(RunError::Interrupted {
                        step: done + stepped,
                        frames: kept + frames.len(),
                        out_dir: options.write_files.then(|| options.out_dir.clone()),
                        checkpoint: last_checkpoint,
                    });
                }
                let piece = stretch.min(chunk - stepped);
                let t = Instant::now();
                if let Err(e) = sim.step_n(piece) {
                    done += stepped;
                    return Err(e.into());
                }
                if piece == stretch && t.elapsed().as_secs_f64() < 0.5 * STOP_CHECK_SECONDS {
                    stretch *= 2;
                }
                stepped += piece;
            }
            sim.backend().finish();
            step_time += t0.elapsed();
            done += chunk;
        }
    };
    let outcome = run();
    let files = match outputs {
        Some(o) => o.finish(&sim),
        None => Ok(Vec::new()),
    };
    // The run's own error first: it says why the run stopped.
    outcome?;
    let files = files?;
    let nodes = sim.backend().n_active();
    Ok(RunSummary {
        backend: sim.backend().name(),
        nodes,
        steps: done - first_step,
        step_time,
        total_time: start.elapsed(),
        frames,
        files,
        warnings,
        needle: has_needle.then(|| sim.history().to_vec()),
    })
}
