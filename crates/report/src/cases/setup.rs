//! A case's tissue, time step and backend, the relaxation that settles the static cases,
//! and the helpers the cases share.

use super::ids::{CaseId, CaseResult, ModelId, RunSpec};
use crate::constants::*;
use crate::error::ReportError;
use needlesim::runner::{make_backend, RunError};
use needlesim_core::backend::check_bounded;
use needlesim_core::integrator::StepParams;
use needlesim_core::scene::{Axis, LoadSpec, NodeSet};
use needlesim_core::stability::max_eigenvalue;
use needlesim_core::{
    Backend, CpuBackend, Material, NodeField, Scene, SceneBuilder, Threading, Tissue,
};
use std::path::Path;
use std::time::{Duration, Instant};

pub(super) struct Setup {
    pub(super) dt: f64,
    pub(super) scene: Scene,
    pub(super) tissue: Tissue,
    pub(super) rest: Vec<[f64; 3]>,
    pub(super) h: f64,
}

/// A box of lattice spacing `h` from the origin to `max`, under gravity `gravity` along -y.
pub(super) fn scene(
    max: [f64; 3],
    h: f64,
    material: Material,
    gravity: f64,
    damping: f64,
) -> SceneBuilder {
    Scene::builder()
        .density(DENSITY)
        .neighbours(NEIGHBOURS)
        .box_with_spacing([0.0; 3], max, h)
        .material(material)
        .dt(1e-3)
        .gravity([0.0, -gravity, 0.0])
        .damping(damping)
        .max_speed(100.0)
}

/// Builds the case's tissue at `dt_fraction` of its critical step (estimated on the CPU at
/// the rest state, with the fixed nodes of the case already fixed).
pub(super) fn setup(case: CaseId, model: ModelId, spec: &RunSpec) -> Result<Setup, ReportError> {
    let prepare: fn(&mut Tissue, &[[f64; 3]], f64) = match case {
        CaseId::Cantilever => |_, _, _| {},
        CaseId::Frequency => prepare_frequency,
        CaseId::Stretch => prepare_stretch,
        CaseId::Indentation => prepare_indentation,
        CaseId::Sphere | CaseId::Column => |_, _, _| {},
    };
    let n = case.points_per_side(spec.level);
    let (max, h) = match case {
        CaseId::Cantilever | CaseId::Frequency => {
            let h = BEAM_WIDTH / (n - 1) as f64;
            ([BEAM_LENGTH, BEAM_WIDTH, BEAM_WIDTH], h)
        }
        CaseId::Sphere => ([CUBE; 3], SPHERE_RADIUS / n as f64),
        CaseId::Column => ([CUBE; 3], COLUMN_RADIUS / n as f64),
        _ => ([CUBE; 3], CUBE / (n - 1) as f64),
    };
    let material = model.material(YOUNG, h);
    let floor = model.damping_floor(YOUNG, h);
    // Fixed below a quarter spacing along an axis: the lattice's first layer.
    let clamp = |axis| Some(NodeSet::below(axis, 0.25 * h));
    let (gravity, damping, fixed) = match case {
        CaseId::Cantilever => (
            beam_gravity(),
            (2.0 * beam_omega()).max(floor),
            clamp(Axis::X),
        ),
        CaseId::Frequency => (0.0, floor, clamp(Axis::X)),
        CaseId::Stretch => (0.0, (2.0 * cube_omega(false)).max(floor), None),
        CaseId::Indentation => (0.0, (2.0 * cube_omega(true)).max(floor), clamp(Axis::Y)),
        // Free, under a pressure on its whole surface.
        CaseId::Sphere => (0.0, (2.0 * cube_omega(true)).max(floor), None),
        // The resampled bottom face's nodes lie on y = 0 (they are projected onto the
        // input surface); interior nodes are at least h / 2 inside it.
        CaseId::Column => (
            COLUMN_GRAVITY,
            (2.0 * cube_omega(true)).max(floor),
            clamp(Axis::Y),
        ),
    };
    let mut scene = scene(max, h, material, gravity, damping);
    if let Some(set) = fixed {
        scene = scene.fixed(set);
    }
    if case == CaseId::Sphere {
        scene = scene.load(LoadSpec::pressure(
            NodeSet::sphere([0.0; 3], 1.0),
            SPHERE_PRESSURE,
        ));
    }
    let scene = scene.build().expect("report scenes are valid");
    let mut tissue = match case {
        // The scene's box only carries the spacing; the nodes come from the sphere.
        CaseId::Sphere => {
            let r = SPHERE_RADIUS;
            let surface =
                needlesim_core::geometry::shapes::capsule([0.0, -r, 0.0], 2.0 * r, r, 96, 48);
            let cloud =
                needlesim_core::geometry::resample::resample(&surface, h, Path::new("sphere"))
                    .map_err(|e| RunError::from(needlesim_core::SceneError::from(e)))?;
            Tissue::from_cloud(&scene, cloud, 0)
        }
        CaseId::Column => {
            let surface = needlesim_core::geometry::shapes::cylinder(
                [0.0; 3],
                COLUMN_HEIGHT,
                COLUMN_RADIUS,
                192,
            );
            let cloud =
                needlesim_core::geometry::resample::resample(&surface, h, Path::new("column"))
                    .map_err(|e| RunError::from(needlesim_core::SceneError::from(e)))?;
            Tissue::from_cloud(&scene, cloud, 0)
        }
        _ => Tissue::from_scene(&scene),
    }
    .map_err(RunError::from)?;
    let rest: Vec<[f64; 3]> = tissue.state.positions[..tissue.state.n_active]
        .iter()
        .map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
        .collect();
    prepare(&mut tissue, &rest, h);
    let mut probe = CpuBackend::new(tissue.clone(), Threading::Parallel).map_err(RunError::from)?;
    let critical = max_eigenvalue(&mut probe, 40)?.critical_dt;
    let dt = spec.dt_fraction * critical;
    tissue.step = StepParams::new(dt, &scene.physics);
    Ok(Setup {
        dt,
        scene,
        tissue,
        rest,
        h,
    })
}

/// The backend holding the case's initial state (the report times steps on it).
pub fn case_backend(
    case: CaseId,
    model: ModelId,
    spec: &RunSpec,
) -> Result<Box<dyn Backend>, ReportError> {
    let s = setup(case, model, spec)?;
    backend_of(&s, spec)
}

pub(super) fn backend_of(s: &Setup, spec: &RunSpec) -> Result<Box<dyn Backend>, ReportError> {
    Ok(make_backend(&s.scene, s.tissue.clone(), Some(spec.backend), None)?.0)
}

/// Second moment of the beam's square section, m^4.
pub(super) fn beam_inertia() -> f64 {
    BEAM_WIDTH.powi(4) / 12.0
}

/// Euler-Bernoulli first bending frequency of the cantilever, rad/s.
pub fn beam_omega() -> f64 {
    let a = BEAM_WIDTH * BEAM_WIDTH;
    1.875104f64.powi(2) * (YOUNG * beam_inertia() / (DENSITY * a * BEAM_LENGTH.powi(4))).sqrt()
}

/// The gravity that gives the Euler-Bernoulli tip deflection [`BEAM_DEFLECTION`], m/s^2.
pub fn beam_gravity() -> f64 {
    let a = BEAM_WIDTH * BEAM_WIDTH;
    BEAM_DEFLECTION * 8.0 * YOUNG * beam_inertia() / (DENSITY * a * BEAM_LENGTH.powi(4))
}

/// Timoshenko tip deflection of the cantilever under its weight (bending plus shear with
/// the rectangle's shear coefficient `kappa = 10 (1 + nu) / (12 + 11 nu)`), m.
pub fn beam_deflection_timoshenko() -> f64 {
    let a = BEAM_WIDTH * BEAM_WIDTH;
    let q = DENSITY * a * beam_gravity();
    let g = YOUNG / (2.0 * (1.0 + POISSON));
    let kappa = 10.0 * (1.0 + POISSON) / (12.0 + 11.0 * POISSON);
    BEAM_DEFLECTION + q * BEAM_LENGTH * BEAM_LENGTH / (2.0 * kappa * g * a)
}

/// A slow mode of the cube cases, rad/s: a quarter shear wave over the height with the
/// bottom fixed, half of one for the free cube.
pub(super) fn cube_omega(fixed_bottom: bool) -> f64 {
    let cs = (YOUNG / (2.0 * (1.0 + POISSON)) / DENSITY).sqrt();
    let f = if fixed_bottom { 0.5 } else { 1.0 };
    f * std::f64::consts::PI * cs / CUBE
}

/// One step of a relaxation with what the case adds to it (the stretch case's rollers,
/// the sphere case's pressure).
pub(super) type Constraint<'a> = &'a mut dyn FnMut(&mut dyn Backend) -> Result<(), ReportError>;

/// Runs the backend until `quantity` settles (module docs); `constrain`, when given,
/// runs each step in place of the plain one. Returns (quantity, steps, wall, converged).
pub(super) fn relax(
    b: &mut dyn Backend,
    dt: f64,
    omega: f64,
    mut quantity: impl FnMut(&mut dyn Backend) -> Result<f64, ReportError>,
    mut constrain: Option<Constraint<'_>>,
) -> Result<(f64, u64, Duration, bool), ReportError> {
    let tau = 1.0 / omega;
    let chunk = ((0.25 * tau / dt).ceil() as u64).max(1);
    let max_steps = (40.0 * tau / dt).ceil() as u64;
    let start = Instant::now();
    let mut history: Vec<f64> = Vec::new();
    let mut steps = 0;
    while steps < max_steps {
        match constrain.as_mut() {
            Some(c) => {
                for _ in 0..chunk {
                    c(b)?;
                }
            }
            None => b.step(chunk),
        }
        steps += chunk;
        check_bounded(b, 100.0)?;
        let q = quantity(b)?;
        history.push(q);
        // Settled: the quantity moved by less than REL_TOL over each of the last two
        // windows of length tau (4 checks each).
        let k = history.len();
        if k > 8 {
            let moved = |a: f64, b: f64| (a - b).abs() < REL_TOL * q.abs();
            if moved(q, history[k - 5]) && moved(history[k - 5], history[k - 9]) {
                b.finish();
                return Ok((q, steps, start.elapsed(), true));
            }
        }
    }
    b.finish();
    let q = *history.last().unwrap_or(&f64::NAN);
    Ok((q, steps, start.elapsed(), false))
}

pub(super) fn read_all(
    b: &mut dyn Backend,
    field: NodeField,
) -> Result<Vec<[f32; 4]>, ReportError> {
    let n = b.n_active();
    let mut out = vec![[0.0; 4]; n];
    b.read(field, 0..n, &mut out)?;
    Ok(out)
}

/// Mean y displacement of the listed nodes.
pub(super) fn mean_dy(
    b: &mut dyn Backend,
    nodes: &[u32],
    rest: &[[f64; 3]],
) -> Result<f64, ReportError> {
    let mut out = vec![[0.0; 4]; nodes.len()];
    b.read_nodes(NodeField::Position, nodes, &mut out)?;
    Ok(nodes
        .iter()
        .zip(&out)
        .map(|(&i, p)| p[1] as f64 - rest[i as usize][1])
        .sum::<f64>()
        / nodes.len() as f64)
}

pub(super) fn tip_nodes(rest: &[[f64; 3]], h: f64) -> Vec<u32> {
    (0..rest.len() as u32)
        .filter(|&i| rest[i as usize][0] > BEAM_LENGTH - 0.25 * h)
        .collect()
}

pub(super) fn result(
    case: CaseId,
    model: ModelId,
    s: &Setup,
    spec: &RunSpec,
    run: (f64, u64, Duration, bool),
    reference: f64,
    secondary: f64,
) -> CaseResult {
    let (measured, steps, wall, converged) = run;
    CaseResult {
        case,
        model,
        nodes: s.rest.len(),
        spacing: s.h,
        dt: s.dt,
        dt_fraction: spec.dt_fraction,
        steps,
        wall,
        measured,
        reference,
        error: (measured / reference - 1.0).abs(),
        secondary,
        converged,
    }
}

pub(super) fn prepare_frequency(t: &mut Tissue, rest: &[[f64; 3]], _: f64) {
    for (p, r) in t.state.positions.iter_mut().zip(rest) {
        if p[3] > 0.0 {
            p[1] = (r[1] - BEAM_DEFLECTION * beam_shape(r[0])) as f32;
        }
    }
}

/// Euler-Bernoulli static shape under uniform load, 1 at the tip.
pub(super) fn beam_shape(x: f64) -> f64 {
    let l = BEAM_LENGTH;
    x * x * (6.0 * l * l - 4.0 * l * x + x * x) / (3.0 * l.powi(4))
}

pub(super) fn prepare_stretch(t: &mut Tissue, rest: &[[f64; 3]], _: f64) {
    for (p, r) in t.state.positions.iter_mut().zip(rest) {
        p[2] = (r[2] * (1.0 + STRETCH)) as f32;
    }
}

pub(super) fn prepare_indentation(t: &mut Tissue, rest: &[[f64; 3]], h: f64) {
    for i in punch_nodes(rest, h) {
        let p = &mut t.state.positions[i];
        p[1] = (rest[i][1] - PUNCH_DEPTH) as f32;
        p[3] = 0.0;
    }
}

pub(super) fn punch_nodes(rest: &[[f64; 3]], h: f64) -> Vec<usize> {
    (0..rest.len())
        .filter(|&i| {
            let r = rest[i];
            let within = |v: f64| (v - 0.5 * CUBE).abs() <= PUNCH_HALF_WIDTH * (1.0 + 1e-6);
            r[1] > CUBE - 0.25 * h && within(r[0]) && within(r[2])
        })
        .collect()
}

/// Least-squares strain along `axis` over the free nodes.
pub(super) fn fitted_strain(p: &[[f32; 4]], rest: &[[f64; 3]], axis: usize) -> f64 {
    let n = rest.len() as f64;
    let (mx, mr) = rest.iter().zip(p).fold((0.0, 0.0), |(a, b), (r, p)| {
        (a + p[axis] as f64 / n, b + r[axis] / n)
    });
    let (num, den) = rest.iter().zip(p).fold((0.0, 0.0), |(a, b), (r, p)| {
        let d = r[axis] - mr;
        (a + (p[axis] as f64 - mx) * d, b + d * d)
    });
    num / den - 1.0
}
