//! Extreme cases, each run for every model through the same [`Simulation`] a user runs:
//! the engine's divergence guard (`physics.max_speed`, `physics.check_every`) decides
//! "diverged"; a run that stays bounded is "stable" or "degraded" by a stated criterion.
//!
//! Tissue cases use a free 10 cm cube with velocity damping 10/s, run 1.5 s (the slowest
//! mode rings down to below 1e-3); recovery is judged by the shape residual
//! `r = rms |x - xc - R (X - Xc)| / L` after the best-fit rotation R: stable when
//! `r < 2%`, degraded otherwise (for example an inverted cube that stays inverted). Needle
//! cases use the paper's experiment (20 cm cube, needle along +x at 5 cm/s).

use super::cases::ModelId;
use crate::constants::{CUBE, NEIGHBOURS, YOUNG};
use crate::error::ReportError;
use needlesim::runner::make_backend;
use needlesim_core::glam::{Mat3, Quat};
use needlesim_core::models::mueller2016_rotation::extract_rotation;
use needlesim_core::scene::{Axis, NodeSet, TimeStep};
use needlesim_core::{NodeField, Scene, SceneError, SimError};
use needlesim_needle::{PunctureState, Simulation, SimulationError};

/// The cases.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExtremeCase {
    /// The cube twisted 90 degrees about y (top against bottom) and released.
    Twist90,
    /// The cube squashed to 10% of its height and released.
    Squash10,
    /// 1000 times the default stiffness, released from a 10% stretch, at dt = 1 ms.
    Stiff1000,
    /// The same at `dt = "auto"`.
    Stiff1000Auto,
    /// A time step 10 times the automatic one, released from a 10% stretch.
    Dt10x,
    /// The needle moved 5 cm in one step while 8 cm inside.
    NeedleJerk,
    /// The paper's experiment: 15 cm in, then 25 degrees about z.
    NeedleRotation,
    /// Insert 3 cm and extract, repeated.
    Cycles,
}

impl ExtremeCase {
    /// Every case.
    pub const ALL: [ExtremeCase; 8] = [
        ExtremeCase::Twist90,
        ExtremeCase::Squash10,
        ExtremeCase::Stiff1000,
        ExtremeCase::Stiff1000Auto,
        ExtremeCase::Dt10x,
        ExtremeCase::NeedleJerk,
        ExtremeCase::NeedleRotation,
        ExtremeCase::Cycles,
    ];

    /// Short label.
    pub fn label(self) -> &'static str {
        match self {
            ExtremeCase::Twist90 => "twist 90 deg released",
            ExtremeCase::Squash10 => "squash to 10% released",
            ExtremeCase::Stiff1000 => "stiffness x1000, dt 1 ms",
            ExtremeCase::Stiff1000Auto => "stiffness x1000, dt auto",
            ExtremeCase::Dt10x => "dt 10x the auto step",
            ExtremeCase::NeedleJerk => "needle jerked 5 cm in one step",
            ExtremeCase::NeedleRotation => "needle rotated 25 deg inside",
            ExtremeCase::Cycles => "insert/extract cycles",
        }
    }
}

/// How a case ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Outcome {
    /// Bounded and right by the case's criterion.
    Stable,
    /// Bounded but wrong by the case's criterion.
    Degraded,
    /// Stopped by the divergence guard (the message names step and node).
    Diverged(String),
    /// Stopped by another error (a bug or a limit; never expected).
    Failed(String),
}

impl Outcome {
    /// Stable when the case's criterion holds, degraded otherwise.
    fn judge(ok: bool) -> Outcome {
        if ok {
            Outcome::Stable
        } else {
            Outcome::Degraded
        }
    }

    /// One word.
    pub fn word(&self) -> &'static str {
        match self {
            Outcome::Stable => "stable",
            Outcome::Degraded => "degraded",
            Outcome::Diverged(_) => "diverged",
            Outcome::Failed(_) => "failed",
        }
    }
}

/// One case for one model.
#[derive(Debug, Clone)]
pub struct ExtremeResult {
    /// The case.
    pub case: ExtremeCase,
    /// The model.
    pub model: ModelId,
    /// Outcome.
    pub outcome: Outcome,
    /// The measurement behind it.
    pub detail: String,
    /// Steps run.
    pub steps: u64,
}

/// Sizes of the extreme runs.
#[derive(Debug, Clone, Copy)]
pub struct ExtremeSize {
    /// Lattice points per side of the tissue cube.
    pub cube_side: usize,
    /// Lattice spacing of the needle scenes' 20 cm cube, m.
    pub needle_spacing: f64,
    /// Insert/extract cycles.
    pub cycles: usize,
}

fn outcome_of(e: SimulationError) -> Outcome {
    match e {
        SimulationError::Sim(s @ (SimError::Diverged { .. } | SimError::Runaway { .. })) => {
            Outcome::Diverged(s.to_string())
        }
        other => Outcome::Failed(other.to_string()),
    }
}

fn start(
    scene: &Scene,
    prepare: impl FnOnce(&mut needlesim_core::Tissue),
) -> Result<Simulation, SimulationError> {
    let mut prep = Simulation::prepare(scene)?;
    prepare(&mut prep.tissue);
    let backend = make_backend(scene, prep.tissue.clone(), None, None)
        .map_err(|e| {
            SimulationError::Scene(needlesim_core::SceneError::invalid(
                "backend",
                e.to_string(),
            ))
        })?
        .0;
    prep.start(backend)
}

fn cube_scene(
    model: ModelId,
    side: usize,
    scale: f64,
    dt: TimeStep,
    stretch: f64,
) -> Result<Scene, SceneError> {
    let h = CUBE / (side - 1) as f64;
    let young = YOUNG * scale;
    Scene::builder()
        .neighbours(NEIGHBOURS)
        .box_with_spacing([0.0; 3], [CUBE; 3], h)
        .material(model.material(young, h))
        .time_step(dt)
        .damping(10.0 + model.damping_floor(young, h))
        .check_every(50)
        .stretch([stretch, 1.0, 1.0])
        .build()
}

/// Shape residual after the best-fit rotation, over the cube side.
fn shape_residual(sim: &mut Simulation, rest: &[[f64; 3]]) -> Result<f64, SimulationError> {
    let n = rest.len();
    let mut p = vec![[0.0f32; 4]; n];
    sim.backend().read(NodeField::Position, 0..n, &mut p)?;
    let mean = |f: &dyn Fn(usize) -> [f64; 3]| -> [f64; 3] {
        let mut m = [0.0; 3];
        for i in 0..n {
            let v = f(i);
            for a in 0..3 {
                m[a] += v[a] / n as f64;
            }
        }
        m
    };
    let xc = mean(&|i| [p[i][0] as f64, p[i][1] as f64, p[i][2] as f64]);
    let rc = mean(&|i| rest[i]);
    let mut a = [[0.0f64; 3]; 3];
    for i in 0..n {
        for r in 0..3 {
            for c in 0..3 {
                a[r][c] += (p[i][r] as f64 - xc[r]) * (rest[i][c] - rc[c]);
            }
        }
    }
    let norm = a
        .iter()
        .flatten()
        .map(|v| v * v)
        .sum::<f64>()
        .sqrt()
        .max(1e-300);
    let a32: [[f32; 3]; 3] =
        std::array::from_fn(|r| std::array::from_fn(|c| (a[r][c] / norm) as f32));
    // Start from the identity and iterate to convergence (a 180-degree error still moves).
    let a32 = Mat3::from_cols_array_2d(&a32).transpose();
    let q = extract_rotation(&a32, Quat::IDENTITY, 200);
    let rot = Mat3::from_quat(q).transpose().to_cols_array_2d();
    let mut sum = 0.0;
    for i in 0..n {
        for r in 0..3 {
            let target: f64 = (0..3)
                .map(|c| rot[r][c] as f64 * (rest[i][c] - rc[c]))
                .sum();
            sum += (p[i][r] as f64 - xc[r] - target).powi(2);
        }
    }
    Ok((sum / n as f64).sqrt() / CUBE)
}

fn tissue_case(
    case: ExtremeCase,
    model: ModelId,
    size: &ExtremeSize,
) -> Result<(Outcome, String, u64), SimulationError> {
    let side = size.cube_side;
    let (scale, stretch) = match case {
        ExtremeCase::Stiff1000 | ExtremeCase::Stiff1000Auto => (1000.0, 1.1),
        ExtremeCase::Dt10x => (1.0, 1.1),
        _ => (1.0, 1.0),
    };
    let dt = match case {
        ExtremeCase::Stiff1000 => TimeStep::Seconds(1e-3),
        ExtremeCase::Dt10x => {
            let auto = cube_scene(model, side, scale, TimeStep::Auto, stretch)?;
            let t = needlesim_core::Tissue::from_scene(&auto)?;
            TimeStep::Seconds(10.0 * t.step.dt as f64)
        }
        _ => TimeStep::Auto,
    };
    let scene = cube_scene(model, side, scale, dt, stretch)?;
    let c = 0.5 * CUBE;
    let mut sim = start(&scene, |t| {
        for p in t.state.positions[..t.state.n_active].iter_mut() {
            let (x, y, z) = (p[0] as f64 - c, p[1] as f64 - c, p[2] as f64 - c);
            match case {
                ExtremeCase::Twist90 => {
                    let th = std::f64::consts::FRAC_PI_2 * (y / CUBE);
                    p[0] = (c + x * th.cos() - z * th.sin()) as f32;
                    p[2] = (c + x * th.sin() + z * th.cos()) as f32;
                }
                ExtremeCase::Squash10 => p[1] = (c + 0.1 * y) as f32,
                _ => {}
            }
        }
    })?;
    // The reference shape is the rest shape (the prepared positions carry the initial
    // stretch).
    let rest = sim.rest_positions();
    let steps = (1.5 / sim.dt()).ceil() as u64;
    if let Err(e) = sim.step_n(steps).and_then(|_| sim.check()) {
        let s = sim.steps();
        return Ok((outcome_of(e), format!("dt {:.2e} s", sim.dt()), s));
    }
    let r = shape_residual(&mut sim, &rest)?;
    let outcome = Outcome::judge(r < 0.02);
    Ok((
        outcome,
        format!("shape residual {:.2}% (dt {:.2e} s)", 100.0 * r, sim.dt()),
        steps,
    ))
}

/// The paper's needle (`[needle]`, read by `needlesim-needle`): 15 cm in along +x at
/// 5 cm/s, turned 25 degrees about z, held.
const PAPER_NEEDLE: &str = "base = [-0.22, 0.1013, 0.0987]\ndirection = [1.0, 0.0, 0.0]\nlength = 0.2\n\
    friction = { coefficient = 0.3 }\ncutting = 0.2\n\
    [[keyframe]]\naction = \"move\"\ndirection = [1.0, 0.0, 0.0]\nspeed = 0.05\nduration = 3.0\n\
    [[keyframe]]\naction = \"rotate\"\naxis = [0.0, 0.0, 1.0]\npoint = [0.0, 0.1013, 0.0987]\nrate = 25.0\nduration = 1.0\n\
    [[keyframe]]\naction = \"pause\"\nduration = 0.5\n";

/// The paper's experiment with the report's model and spacing.
fn paper_scene(model: ModelId, h: f64) -> Result<Scene, SceneError> {
    let young = YOUNG;
    Scene::builder()
        .neighbours(NEIGHBOURS)
        .box_with_spacing([0.0; 3], [0.2; 3], h)
        .material(model.material(young, h))
        .dt(1e-3)
        .damping(4.0 + model.damping_floor(young, h))
        .check_every(50)
        .fixed(NodeSet::above(Axis::X, 0.199))
        .needle_toml(PAPER_NEEDLE)
        .build()
}

fn needle_case(
    case: ExtremeCase,
    model: ModelId,
    size: &ExtremeSize,
) -> Result<(Outcome, String, u64), SimulationError> {
    let h = size.needle_spacing;
    let mut sim = start(&paper_scene(model, h)?, |_| {})?;
    let rest = sim.rest_positions();
    let n_mesh = rest.len();
    let run = |sim: &mut Simulation, n: u64| sim.step_n(n);
    macro_rules! guard {
        ($e:expr) => {
            if let Err(e) = $e {
                let s = sim.steps();
                return Ok((outcome_of(e), String::new(), s));
            }
        };
    }
    match case {
        ExtremeCase::NeedleRotation => {
            guard!(run(&mut sim, 4500));
            let hist = sim.history();
            let rot: Vec<f64> = hist
                .iter()
                .filter(|s| s.time > 3.0 && s.time <= 4.0)
                .map(|s| s.force.axial)
                .collect();
            let jumps = rot.windows(2).map(|w| (w[1] - w[0]).abs()).sum::<f64>()
                / (rot.len().max(2) - 1) as f64;
            let level = rot.iter().map(|f| f.abs()).sum::<f64>() / rot.len().max(1) as f64;
            let ratio = jumps / (level + 0.01);
            let outcome = Outcome::judge(ratio < 0.5);
            Ok((
                outcome,
                format!(
                    "mean |axial| {level:.3} N, mean step-to-step change {:.0}% of it",
                    100.0 * ratio
                ),
                sim.steps(),
            ))
        }
        ExtremeCase::NeedleJerk => {
            guard!(run(&mut sim, 2000));
            let before = sim
                .history()
                .iter()
                .map(|s| s.force.axial.abs())
                .fold(0.0, f64::max);
            let n = *sim.needle().expect("needle scene");
            let d = n.direction();
            let b = n.base();
            guard!(sim.set_pose(std::array::from_fn(|a| b[a] + 0.05 * d[a]), d));
            guard!(run(&mut sim, 300));
            let after = sim.needle_force().axial.abs();
            let outcome = Outcome::judge(
                after <= 10.0 * before.max(1e-3) && sim.state() == PunctureState::Inside,
            );
            Ok((
                outcome,
                format!("|axial| {after:.3} N 0.3 s after the jerk, max {before:.3} N before"),
                sim.steps(),
            ))
        }
        _ => {
            sim.set_record(false);
            let n = *sim.needle().expect("needle scene");
            let d = n.direction();
            let b0 = n.base();
            let tip0 = n.tip();
            // Tip from 1 cm outside (x = -0.01) to 3 cm deep and back, 80 steps each way.
            let shift = -0.01 - tip0[0];
            let pose = |s: f64| -> [f64; 3] { std::array::from_fn(|a| b0[a] + (shift + s) * d[a]) };
            let mut max_nodes = 0;
            for _ in 0..size.cycles {
                for k in 0..160 {
                    let s = if k < 80 {
                        0.04 * k as f64 / 80.0
                    } else {
                        0.04 * (160 - k) as f64 / 80.0
                    };
                    guard!(sim.set_pose(pose(s), d));
                    guard!(sim.step());
                    max_nodes = max_nodes.max(sim.needle_nodes().len());
                }
            }
            guard!(run(&mut sim, 500));
            let active = sim.backend().n_active();
            let mut p = vec![[0.0f32; 4]; n_mesh];
            guard!(sim
                .backend()
                .read(NodeField::Position, 0..n_mesh, &mut p)
                .map_err(SimulationError::from));
            let drift = p
                .iter()
                .zip(&rest)
                .map(|(p, r)| {
                    (0..3)
                        .map(|a| (p[a] as f64 - r[a]).powi(2))
                        .sum::<f64>()
                        .sqrt()
                })
                .fold(0.0, f64::max);
            let outcome = Outcome::judge(
                active == n_mesh && drift < 0.1 * h && sim.state() == PunctureState::Outside,
            );
            Ok((
                outcome,
                format!(
                    "{} cycles (up to {max_nodes} needle nodes): {} nodes after ({} mesh), largest drift from rest {:.2} mm",
                    size.cycles,
                    active,
                    n_mesh,
                    1e3 * drift
                ),
                sim.steps(),
            ))
        }
    }
}

/// Runs one extreme case for one model.
pub fn run_extreme(
    case: ExtremeCase,
    model: ModelId,
    size: &ExtremeSize,
) -> Result<ExtremeResult, ReportError> {
    let r = match case {
        ExtremeCase::NeedleJerk | ExtremeCase::NeedleRotation | ExtremeCase::Cycles => {
            needle_case(case, model, size)
        }
        _ => tissue_case(case, model, size),
    };
    let (outcome, detail, steps) = match r {
        Ok(v) => v,
        Err(e) => (outcome_of(e), String::new(), 0),
    };
    Ok(ExtremeResult {
        case,
        model,
        outcome,
        detail,
        steps,
    })
}
