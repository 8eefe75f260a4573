//! Python bindings of needlesim: `needlesim.Simulation` steps a scene (TOML file or a
//! dict with the same keys) on the CPU or the GPU and hands out numpy arrays.
//!
//! Arrays are copies (float64 for positions and forces, converted exactly from the f32
//! state), so they stay valid after further steps. `step(n)` releases the interpreter
//! lock while it runs. Errors from Rust become `ValueError` (bad scene, bad argument) or
//! `RuntimeError` (divergence, device failure, needle capacity), with the Rust message.

use needlesim::core::scene::BackendChoice;
use needlesim::core::NodeSelection;
use needlesim::needle::{Checkpoint, PunctureState, SceneText, Simulation, SimulationError};
use needlesim::{make_backend, NodeField, RunError, Scene};
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::exceptions::{PyOverflowError, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

mod haptic;
mod rod;

fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A count argument (steps, threads, pixels, segments, ticks): a Python integer from 0 to
/// `max`. pyo3's own conversion raises an OverflowError that names no argument for `-1`;
/// this one says which argument and why (ValueError), or that it is not an integer
/// (TypeError).
pub(crate) fn count_arg(obj: &Bound<'_, PyAny>, name: &str, max: u64) -> PyResult<u64> {
    let too_large = || {
        PyValueError::new_err(format!(
            "`{name}` = {obj} is larger than the largest accepted, {max}"
        ))
    };
    match obj.extract::<u64>() {
        Ok(v) if v <= max => Ok(v),
        Ok(_) => Err(too_large()),
        Err(e) if e.is_instance_of::<PyOverflowError>(obj.py()) => {
            if obj.lt(0)? {
                Err(PyValueError::new_err(format!(
                    "`{name}` = {obj} is negative; it counts, so it must be 0 or more"
                )))
            } else {
                Err(too_large())
            }
        }
        Err(_) => Err(PyTypeError::new_err(format!(
            "`{name}` must be an integer, not {}",
            obj.get_type().name()?
        ))),
    }
}

/// The `threads` argument of the constructors (None: the scene's or all cores).
fn threads_arg(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Option<usize>> {
    Ok(opt_count_arg(obj, "threads", usize::MAX as u64)?.map(|t| t as usize))
}

/// An optional count argument (`None` passes through); see [`count_arg`].
pub(crate) fn opt_count_arg(
    obj: Option<&Bound<'_, PyAny>>,
    name: &str,
    max: u64,
) -> PyResult<Option<u64>> {
    match obj {
        Some(o) if !o.is_none() => count_arg(o, name, max).map(Some),
        _ => Ok(None),
    }
}

fn runtime_error(e: impl std::fmt::Display) -> PyErr {
    PyRuntimeError::new_err(e.to_string())
}

/// Bad input is a `ValueError`; everything that fails while running a `RuntimeError`.
fn run_error(e: RunError) -> PyErr {
    match e {
        RunError::Scene(_) | RunError::Threads(_) => value_error(e),
        RunError::Needle(SimulationError::Scene(_) | SimulationError::Needle(_)) => value_error(e),
        _ => runtime_error(e),
    }
}

fn sim_error(e: SimulationError) -> PyErr {
    match e {
        SimulationError::Scene(_) | SimulationError::Needle(_) | SimulationError::NoNeedle => {
            value_error(e)
        }
        _ => runtime_error(e),
    }
}

fn state_name(s: PunctureState) -> &'static str {
    match s {
        PunctureState::Outside => "outside",
        PunctureState::Touching => "touching",
        PunctureState::Inside => "inside",
    }
}

/// Deepest nesting of dicts and lists a scene may have (real scenes use 3; a dict that
/// contains itself would otherwise recurse until the stack overflows).
const MAX_SCENE_DEPTH: usize = 32;

/// A Python value as TOML, naming the dotted key of anything that has no TOML form.
fn to_toml(obj: &Bound<'_, PyAny>, key: &str) -> PyResult<toml::Value> {
    to_toml_at(obj, key, 0)
}

fn to_toml_at(obj: &Bound<'_, PyAny>, key: &str, depth: usize) -> PyResult<toml::Value> {
    if depth > MAX_SCENE_DEPTH {
        return Err(value_error(format!(
            "scene key `{key}`: nested more than {MAX_SCENE_DEPTH} levels deep (a dict or list \
             that contains itself?)"
        )));
    }
    if obj.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(obj.extract()?));
    }
    if obj.is_instance_of::<PyInt>() {
        // TOML integers are 64-bit: a larger one names its key (Python's own
        // OverflowError named none).
        return obj.extract().map(toml::Value::Integer).map_err(|_| {
            value_error(format!(
                "scene key `{key}`: {} does not fit a 64-bit integer",
                obj.str()
                    .map_or_else(|_| "the integer".into(), |s| s.to_string())
            ))
        });
    }
    if obj.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(obj.extract()?));
    }
    if obj.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(obj.extract()?));
    }
    if let Ok(d) = obj.cast::<PyDict>() {
        let mut t = toml::Table::new();
        for (k, v) in d.iter() {
            let k: String = k
                .extract()
                .map_err(|_| value_error(format!("scene key `{key}`: keys must be strings")))?;
            let sub = if key.is_empty() {
                k.clone()
            } else {
                format!("{key}.{k}")
            };
            t.insert(k, to_toml_at(&v, &sub, depth + 1)?);
        }
        return Ok(toml::Value::Table(t));
    }
    if obj.is_instance_of::<PyList>() || obj.is_instance_of::<PyTuple>() {
        let mut out = Vec::new();
        for (i, v) in obj.try_iter()?.enumerate() {
            out.push(to_toml_at(&v?, &format!("{key}[{i}]"), depth + 1)?);
        }
        return Ok(toml::Value::Array(out));
    }
    // numpy arrays and scalars: their Python form (`tolist()`: nested lists of int and
    // float, or a single int or float), so `np.int64(100)` stays an integer.
    if obj.hasattr("tolist")? && obj.hasattr("dtype")? {
        let plain = obj.call_method0("tolist")?;
        if !plain.get_type().is(obj.get_type()) {
            return to_toml_at(&plain, key, depth + 1);
        }
    }
    // Anything else float-like.
    if let Ok(f) = obj.extract::<f64>() {
        return Ok(toml::Value::Float(f));
    }
    Err(value_error(format!(
        "scene key `{key}`: cannot use a value of type {}",
        obj.get_type().name()?
    )))
}

fn backend_choice(name: Option<&str>) -> PyResult<Option<BackendChoice>> {
    name.map(|n| {
        toml::Value::String(n.to_string())
            .try_into::<BackendChoice>()
            .map_err(|_| {
                value_error(format!(
                    "unknown backend `{n}`: use \"cpu\", \"cpu-parallel\", \"gpu\" or \"auto\""
                ))
            })
    })
    .transpose()
}

/// A needle insertion simulation (or a plain tissue simulation when the scene has no
/// `[needle]` table) on the CPU or the GPU.
#[pyclass(module = "needlesim._needlesim", name = "Simulation")]
struct PySimulation {
    /// Shared with a running `HapticLoop`.
    sim: Arc<Mutex<Simulation>>,
    /// Set while a `HapticLoop` steps the simulation.
    busy: Arc<AtomicBool>,
    warnings: Vec<String>,
    masses: Vec<f64>,
    /// The mesh's neighbour rows as the scene built them (index, weight; mesh nodes x K).
    built_neighbours: (Vec<u32>, Vec<f32>, usize),
    /// The scene as TOML (checkpoints carry it).
    scene: SceneText,
    /// Steps the scene's `[run]` asks for at the simulation's time step.
    run_steps: u64,
}

impl PySimulation {
    fn build(
        scene: SceneText,
        backend: Option<&str>,
        threads: Option<usize>,
        checkpoint: Option<(Checkpoint, &std::path::Path)>,
    ) -> PyResult<Self> {
        // A scene stored in a checkpoint is named by the file in its errors.
        let parsed = match &checkpoint {
            Some((_, file)) => scene.scene_stored_in(file),
            None => scene.scene(),
        }
        .map_err(value_error)?;
        let choice = backend_choice(backend)?;
        let prep = Simulation::prepare(&parsed).map_err(sim_error)?;
        let mut warnings = match checkpoint {
            None => needlesim::time_step_warning(&parsed, &prep.tissue)
                .map_err(run_error)?
                .into_iter()
                .collect(),
            Some(_) => Vec::new(),
        };
        let (b, warning) =
            make_backend(&parsed, prep.tissue.clone(), choice, threads).map_err(run_error)?;
        warnings.extend(warning);
        let masses = prep.tissue.masses.clone();
        let nb = &prep.tissue.neighbours;
        let rows = prep.tissue.n_mesh * nb.k;
        let built_neighbours = (nb.index[..rows].to_vec(), nb.weight[..rows].to_vec(), nb.k);
        let sim = match checkpoint {
            Some((c, _)) => prep.resume(b, c),
            None => prep.start(b),
        }
        .map_err(sim_error)?;
        let run_steps = parsed.run.steps_at(sim.dt()).map_err(value_error)?;
        Ok(PySimulation {
            sim: Arc::new(Mutex::new(sim)),
            busy: Arc::default(),
            warnings,
            masses,
            built_neighbours,
            scene,
            run_steps,
        })
    }

    /// An error while a haptic loop steps the simulation.
    fn idle(&self) -> PyResult<()> {
        if self.busy.load(Ordering::Acquire) {
            return Err(runtime_error(
                "a HapticLoop is stepping this simulation: stop it first",
            ));
        }
        Ok(())
    }

    fn lock(&self) -> MutexGuard<'_, Simulation> {
        // A panic while stepping poisons the lock; the state is still readable.
        self.sim.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn field<'py>(&self, py: Python<'py>, field: NodeField) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let mut sim = self.lock();
        let b = sim.backend();
        let n = b.n_active();
        let mut bufs = read_fields(b, &[field], NodeSelection::Range(0..n), n)?;
        drop(sim);
        rows(py, bufs.swap_remove(0), 3)
    }

    /// The surface's nodes (in the order of first use by its triangles), their positions
    /// (flat, 3 per node) and the triangles as indices into that list (flat).
    fn surface_arrays(&self, py: Python<'_>) -> PyResult<(Vec<usize>, Vec<f64>, Vec<i64>)> {
        let pos = self.field(py, NodeField::Position)?;
        let pos = pos.readonly();
        let pos = pos.as_array();
        let tris = self.lock().triangles().to_vec();
        let mut map = std::collections::HashMap::new();
        let (mut nodes, mut verts) = (Vec::new(), Vec::new());
        let mut faces = Vec::with_capacity(tris.len() * 3);
        for t in &tris {
            for &v in t {
                let id = *map.entry(v).or_insert_with(|| {
                    let r = pos.row(v as usize);
                    verts.extend([r[0], r[1], r[2]]);
                    nodes.push(v as usize);
                    nodes.len() - 1
                });
                faces.push(id as i64);
            }
        }
        Ok((nodes, verts, faces))
    }
}

/// `needlesim._types.<name>(args)`: the typed results are Python classes (an enum, records
/// with numpy fields) built from what the native code hands out.
fn typed<'py>(
    py: Python<'py>,
    name: &str,
    args: impl pyo3::call::PyCallArgs<'py>,
) -> PyResult<Bound<'py, PyAny>> {
    py.import("needlesim._types")?.getattr(name)?.call1(args)
}

/// The node field named `name` in `Simulation.read`.
fn field_named(name: &str) -> PyResult<NodeField> {
    match name {
        "positions" => Ok(NodeField::Position),
        "velocities" => Ok(NodeField::Velocity),
        "forces" => Ok(NodeField::Force),
        _ => Err(value_error(format!(
            "fields: unknown field {name:?} (positions, velocities or forces)"
        ))),
    }
}

/// Neighbour index and weight rows, both (n, K).
type NeighbourRows<'py> = (Bound<'py, PyArray2<i64>>, Bound<'py, PyArray2<f32>>);

/// Vertices (m, 3) and faces (t, 3).
type Mesh<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<i64>>);

/// The xyz of node vectors as a float64 (n, 3) array (exact: every f32 is an f64).
/// `fields` of the `count` selected nodes in one transfer, each flat (3 per node) in f64.
/// A position is read with its remainder and given as their sum
/// ([`NodeField::PositionRemainder`]): f64 positions that resolve displacements far below
/// f32's spacing, wherever the body is.
fn read_fields(
    b: &mut dyn needlesim::core::Backend,
    fields: &[NodeField],
    selection: NodeSelection<'_>,
    count: usize,
) -> PyResult<Vec<Vec<f64>>> {
    let mut requests: Vec<_> = fields.iter().map(|&k| (k, selection.clone())).collect();
    let with_remainder: Vec<usize> = (0..fields.len())
        .filter(|&i| fields[i] == NodeField::Position)
        .collect();
    for _ in &with_remainder {
        requests.push((NodeField::PositionRemainder, selection.clone()));
    }
    let mut bufs = vec![vec![[0.0f32; 4]; count]; requests.len()];
    {
        let mut outs: Vec<&mut [[f32; 4]]> = bufs.iter_mut().map(|b| b.as_mut_slice()).collect();
        b.read_many(&requests, &mut outs).map_err(runtime_error)?;
    }
    let remainders = bufs.split_off(fields.len());
    let mut out: Vec<Vec<f64>> = bufs
        .iter()
        .map(|buf| {
            buf.iter()
                .flat_map(|p| [p[0] as f64, p[1] as f64, p[2] as f64])
                .collect()
        })
        .collect();
    for (&i, r) in with_remainder.iter().zip(&remainders) {
        for (x, e) in out[i]
            .iter_mut()
            .zip(r.iter().flat_map(|e| [e[0], e[1], e[2]]))
        {
            *x += e as f64;
        }
    }
    Ok(out)
}

fn rows<'py, T: numpy::Element>(
    py: Python<'py>,
    flat: Vec<T>,
    cols: usize,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let n = flat.len() / cols;
    PyArray1::from_vec(py, flat).reshape([n, cols])
}

#[pymethods]
impl PySimulation {
    /// Builds the scene in the TOML file `path`. `backend`: "cpu" (one thread),
    /// "cpu-parallel", "gpu" or "auto" (default: the scene's); `threads`: CPU threads
    /// (0 = all; implies a CPU backend).
    #[staticmethod]
    #[pyo3(signature = (path, backend=None, threads=None))]
    fn from_scene(
        path: PathBuf,
        backend: Option<&str>,
        threads: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let threads = threads_arg(threads)?;
        // Read through the checked path (size, regular file) first, for its errors.
        let scene = Scene::from_file(&path).map_err(value_error)?;
        let toml = std::fs::read_to_string(&path).map_err(value_error)?;
        let text = SceneText {
            toml,
            base_dir: scene.base_dir.clone(),
        };
        Self::build(text, backend, threads, None)
    }

    /// Builds a scene given as a dict with the keys of the TOML format (nested dicts for
    /// tables, lists for arrays and arrays of tables). Relative paths resolve against
    /// `base_dir` (default: the current directory).
    #[staticmethod]
    #[pyo3(signature = (scene, backend=None, threads=None, base_dir=None))]
    fn from_dict(
        scene: &Bound<'_, PyDict>,
        backend: Option<&str>,
        threads: Option<&Bound<'_, PyAny>>,
        base_dir: Option<PathBuf>,
    ) -> PyResult<Self> {
        let threads = threads_arg(threads)?;
        let table = to_toml(scene.as_any(), "")?;
        let toml = toml::to_string(&table).map_err(value_error)?;
        let base_dir = base_dir.unwrap_or_else(|| PathBuf::from("."));
        Self::build(SceneText { toml, base_dir }, backend, threads, None)
    }

    /// Writes the whole state (node arrays, needle nodes and undo log, puncture and
    /// friction states, clock, history, and the scene) to `path`, atomically. `load`
    /// continues from it bitwise as this simulation would on the CPU backends.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let scene = self.scene.clone();
        let sim = &self.sim;
        py.detach(|| {
            let mut s = sim.lock().unwrap_or_else(|p| p.into_inner());
            let mut c = s.checkpoint().map_err(|e| e.to_string())?;
            c.scene = Some(scene);
            c.write(&path).map_err(|e| e.to_string())
        })
        .map_err(PyRuntimeError::new_err)
    }

    /// A simulation in the state `save` wrote to `path` (built from the scene the file
    /// carries; `backend` and `threads` as in `from_scene`). A file of another format
    /// version, a truncated or altered one is a ValueError naming the problem.
    #[staticmethod]
    #[pyo3(signature = (path, backend=None, threads=None))]
    fn load(
        path: PathBuf,
        backend: Option<&str>,
        threads: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let threads = threads_arg(threads)?;
        let mut c = Checkpoint::read(&path).map_err(value_error)?;
        let scene = c
            .scene
            .take()
            .ok_or_else(|| value_error(needlesim::needle::CheckpointError::NoScene))?;
        Self::build(scene, backend, threads, Some((c, &path)))
    }

    /// Most steps `history()` keeps (None, the default: every step, 160 bytes a
    /// step). When set, the oldest steps are dropped first; `history(clear=True)` streams
    /// the record out instead.
    #[getter]
    fn get_history_limit(&self) -> Option<usize> {
        self.lock().history_limit()
    }

    #[setter]
    fn set_history_limit(&self, limit: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let limit = opt_count_arg(limit, "history_limit", usize::MAX as u64)?;
        self.lock().set_history_limit(limit.map(|l| l as usize));
        Ok(())
    }

    /// Runs `n` steps with the interpreter lock released. Every `physics.check_every`
    /// steps and at the end, every position and velocity must be finite and every free
    /// node slower than `physics.max_speed` (RuntimeError naming the step and node).
    /// Steps run in chunks of about 20 ms; between chunks pending signals are handled, so
    /// Ctrl-C raises KeyboardInterrupt with the simulation at a step boundary (the steps
    /// done so far stay done).
    #[pyo3(signature = (n=None), text_signature = "($self, n=1)")]
    fn step(&self, py: Python<'_>, n: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        let n = opt_count_arg(n, "n", u64::MAX)?.unwrap_or(1);
        self.idle()?;
        const CHUNK_SECONDS: f64 = 0.02;
        let sim = &self.sim;
        let mut done = 0u64;
        let mut chunk = 1u64;
        while done < n {
            let k = chunk.min(n - done);
            let t0 = std::time::Instant::now();
            py.detach(|| {
                let mut s = sim.lock().unwrap_or_else(|p| p.into_inner());
                s.step_n(k).map_err(|e| e.to_string())
            })
            .map_err(PyRuntimeError::new_err)?;
            done += k;
            py.check_signals()?;
            // Aim the next chunk at CHUNK_SECONDS, growing at most 4 times per chunk.
            let spent = t0.elapsed().as_secs_f64().max(1e-9);
            chunk = ((k as f64 * CHUNK_SECONDS / spent) as u64).clamp(1, 4 * k);
        }
        py.detach(|| {
            let mut s = sim.lock().unwrap_or_else(|p| p.into_inner());
            s.check().map_err(|e| e.to_string())
        })
        .map_err(PyRuntimeError::new_err)
    }

    /// Steps the scene's `[run]` table asks for: `run.steps`, or `ceil(run.duration / dt)`
    /// at this simulation's time step (so `sim.step(sim.run_steps)` runs the scene).
    #[getter]
    fn run_steps(&self) -> u64 {
        self.run_steps
    }

    /// Positions of the active nodes, shape (active_nodes, 3), float64 copy, metres: each
    /// the stored f32 position plus the integrator's remainder, so displacements far below
    /// f32's spacing (1.2e-7 m at 1 m from the origin) are resolved.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.field(py, NodeField::Position)
    }

    /// Velocities, shape (active_nodes, 3), float64 copy, m/s.
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.field(py, NodeField::Velocity)
    }

    /// Elastic forces of the last step (with friction on sliding needle nodes), shape
    /// (active_nodes, 3), float64 copy, newtons.
    #[getter]
    fn forces<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.field(py, NodeField::Force)
    }

    /// Rest positions (mesh nodes, then needle nodes), shape (active_nodes, 3), float64.
    #[getter]
    fn rest_positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let flat: Vec<f64> = self.lock().rest_positions().into_iter().flatten().collect();
        rows(py, flat, 3)
    }

    /// Surface triangles as node indices into `positions`, shape (triangles, 3), int64.
    #[getter]
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i64>>> {
        let flat: Vec<i64> = self
            .lock()
            .triangles()
            .iter()
            .flatten()
            .map(|&v| v as i64)
            .collect();
        rows(py, flat, 3)
    }

    /// The surface as its own mesh: (vertices (m, 3) float64, faces (t, 3) int64 into
    /// the vertices).
    fn surface<'py>(&self, py: Python<'py>) -> PyResult<Mesh<'py>> {
        let (_, verts, faces) = self.surface_arrays(py)?;
        Ok((rows(py, verts, 3)?, rows(py, faces, 3)?))
    }

    /// The surface as a `pyvista.PolyData` (`pip install needlesim[pyvista]`; ImportError
    /// without PyVista), with the point array "displacement" (m from rest): plot it with
    /// `mesh.plot(scalars="displacement")` or save it with `mesh.save("frame.vtp")`.
    fn surface_mesh<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let (nodes, verts, faces) = self.surface_arrays(py)?;
        let rest = self.lock().rest_positions();
        let disp: Vec<f64> = nodes
            .iter()
            .zip(verts.chunks(3))
            .flat_map(|(&i, v)| {
                let r = rest[i];
                [v[0] - r[0], v[1] - r[1], v[2] - r[2]]
            })
            .collect();
        let args = (rows(py, verts, 3)?, rows(py, faces, 3)?, rows(py, disp, 3)?);
        typed(py, "_surface_mesh", args)
    }

    /// Renders the simulation as it is now (the tissue surface lit, the needle, its
    /// nodes, the force-against-depth inset) to a PNG at `path`, offscreen on a GPU or
    /// Mesa's software Vulkan driver (RuntimeError without one; ValueError for a size
    /// outside 1..8192).
    #[pyo3(
        signature = (path, width=None, height=None),
        text_signature = "($self, path, width=800, height=600)"
    )]
    fn screenshot(
        &self,
        py: Python<'_>,
        path: PathBuf,
        width: Option<&Bound<'_, PyAny>>,
        height: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let width = opt_count_arg(width, "width", u32::MAX.into())?.unwrap_or(800) as u32;
        let height = opt_count_arg(height, "height", u32::MAX.into())?.unwrap_or(600) as u32;
        let sim = &self.sim;
        py.detach(|| {
            let mut s = sim.lock().unwrap_or_else(|p| p.into_inner());
            needlesim::view::screenshot(&mut s, &path, width, height)
        })
        .map_err(|e| match e {
            needlesim::view::ViewError::BadSize { .. } => value_error(e),
            _ => runtime_error(e),
        })
    }

    /// Puts the needle at a pose for the next step (base point and direction base ->
    /// tip, and optionally its roll about its own axis in radians: a spin); the scene's
    /// keyframes, if any, stop playing.
    #[pyo3(signature = (base, direction, roll=None))]
    fn set_pose(&self, base: [f64; 3], direction: [f64; 3], roll: Option<f64>) -> PyResult<()> {
        self.idle()?;
        let mut sim = self.lock();
        sim.set_pose(base, direction).map_err(sim_error)?;
        if let Some(r) = roll {
            sim.set_roll(r).map_err(sim_error)?;
        }
        Ok(())
    }

    /// The needle's roll about its own axis (radians), or None without a needle.
    #[getter]
    fn roll(&self) -> Option<f64> {
        self.lock().needle().map(|n| n.roll())
    }

    /// Needle tip, shape (3,), or None without a needle.
    #[getter]
    fn tip<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        let tip = self.lock().needle().map(|n| n.tip());
        tip.map(|t| PyArray1::from_vec(py, t.to_vec()))
    }

    /// Needle base point, shape (3,), or None without a needle.
    #[getter]
    fn base<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        let b = self.lock().needle().map(|n| n.base());
        b.map(|t| PyArray1::from_vec(py, t.to_vec()))
    }

    /// Needle direction (unit, base -> tip), shape (3,), or None without a needle.
    #[getter]
    fn direction<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        let d = self.lock().needle().map(|n| n.direction());
        d.map(|t| PyArray1::from_vec(py, t.to_vec()))
    }

    /// `needlesim.PunctureState`: OUTSIDE, TOUCHING or INSIDE (a str enum, equal to
    /// "outside", "touching" or "inside").
    #[getter]
    fn puncture_state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let name = state_name(self.lock().state());
        typed(py, "_puncture_state", (name,))
    }

    /// The tissue region the tip is in (a `[[region]]` name, or "tissue" for the nodes in
    /// none), or None while the tip is not inside.
    #[getter]
    fn tip_region(&self) -> Option<String> {
        let sim = self.lock();
        sim.tip_region()
            .and_then(|r| sim.region_names().get(r as usize).cloned())
    }

    /// Names of the tissue regions, "tissue" (the nodes in no `[[region]]`) first.
    #[getter]
    fn regions(&self) -> Vec<String> {
        self.lock().region_names().to_vec()
    }

    /// Force of the tissue on the needle in the last step, a `needlesim.NeedleForce`:
    /// axial (N, positive resists insertion), lateral (N), total (array (3,)), tip (N, the
    /// part of the axial force the tip's elements carry; the rest is the shaft's
    /// friction), torque (N m, the friction's torque about the needle's axis). Also a
    /// read-only mapping (`force["axial"]`).
    #[getter]
    fn needle_force<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let f = self.lock().needle_force();
        let d = PyDict::new(py);
        d.set_item("axial", f.axial)?;
        d.set_item("lateral", f.lateral)?;
        d.set_item("total", PyArray1::from_vec(py, f.total.to_vec()))?;
        d.set_item("tip", f.tip)?;
        d.set_item("torque", f.torque)?;
        typed(py, "_needle_force", (d,))
    }

    /// The force each held set (`[[fixed]]`, `[[prescribed]]`) exerts on the body, from the
    /// forces of the last step: {name: array (3,) in N}, zero in the components a set does
    /// not hold.
    fn reactions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let r = self.lock().reactions().map_err(sim_error)?;
        let d = PyDict::new(py);
        for r in r {
            d.set_item(r.name, PyArray1::from_vec(py, r.force.to_vec()))?;
        }
        Ok(d)
    }

    /// Mass of each mesh node in kg, shape (mesh_nodes,): density times its cell volume
    /// (`tissue.masses = "cell"`) or equal shares (`"uniform"`).
    #[getter]
    fn masses<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.masses.clone())
    }

    /// Neighbour lists `(index, weight)`, both of shape (nodes, K); index is int64,
    /// weight float32 and 0 marks an empty or broken slot (the mutuality rule). By
    /// default the mesh's rows as the scene built them (kept from the build, not rebuilt);
    /// `current=True`: the rows the simulation uses now, for every active node, with the
    /// needle's edits and the nodes it added.
    #[pyo3(signature = (current=false))]
    fn neighbours<'py>(&self, py: Python<'py>, current: bool) -> PyResult<NeighbourRows<'py>> {
        let (index, weight, k) = if current {
            let sim = self.lock();
            let nb = sim.editor().neighbours();
            let rows = sim.editor().n_active() * nb.k;
            (nb.index[..rows].to_vec(), nb.weight[..rows].to_vec(), nb.k)
        } else {
            self.built_neighbours.clone()
        };
        let index = index.iter().map(|&j| j as i64).collect();
        Ok((rows(py, index, k)?, rows(py, weight, k)?))
    }

    /// Several node arrays in one read (one device round trip on the GPU, where each
    /// property is one): `fields` from "positions", "velocities", "forces", for the
    /// active nodes or the listed `nodes` (in their order); a tuple of float64 arrays
    /// (n, 3).
    #[pyo3(signature = (fields=vec!["positions".to_string(), "velocities".to_string(), "forces".to_string()], nodes=None))]
    fn read<'py>(
        &self,
        py: Python<'py>,
        fields: Vec<String>,
        nodes: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyTuple>> {
        // An index beyond 64 bits is out of range like any other (pyo3's OverflowError
        // named no argument).
        let nodes: Option<Vec<i64>> = match nodes.filter(|n| !n.is_none()) {
            None => None,
            Some(n) => Some(n.extract().map_err(|e: PyErr| {
                if e.is_instance_of::<PyOverflowError>(py) {
                    value_error("nodes: an index beyond 64 bits, outside the active nodes")
                } else {
                    PyTypeError::new_err(format!("nodes: a sequence of integers: {e}"))
                }
            })?),
        };
        let kinds = fields
            .iter()
            .map(|f| field_named(f))
            .collect::<PyResult<Vec<_>>>()?;
        let mut sim = self.lock();
        let b = sim.backend();
        let n_active = b.n_active();
        let list: Option<Vec<u32>> = match nodes {
            None => None,
            Some(v) => Some(
                v.iter()
                    .map(|&i| {
                        u32::try_from(i)
                            .ok()
                            .filter(|&i| (i as usize) < n_active)
                            .ok_or_else(|| {
                                value_error(format!(
                                    "nodes: index {i} outside the {n_active} active nodes"
                                ))
                            })
                    })
                    .collect::<PyResult<_>>()?,
            ),
        };
        let count = list.as_ref().map_or(n_active, |l| l.len());
        let selection = match &list {
            Some(l) => NodeSelection::List(l),
            None => NodeSelection::Range(0..n_active),
        };
        let bufs = read_fields(b, &kinds, selection, count)?;
        drop(sim);
        let arrays = bufs
            .into_iter()
            .map(|flat| rows(py, flat, 3))
            .collect::<PyResult<Vec<_>>>()?;
        PyTuple::new(py, arrays)
    }

    /// Every step's needle record, a `needlesim.NeedleHistory` of numpy arrays: step,
    /// time, depth (m past the first contact), axial, lateral, tip (N), torque (N m),
    /// active_nodes, needle_nodes, state (a list of `PunctureState`), region (a list of
    /// str: the tissue region the tip is in, "" when not inside), and tissue_depth (m: the
    /// tip's depth in the undeformed tissue, NaN, numpy's missing value, while the tip is
    /// not in contact). Also a read-only mapping of those columns (`h["axial"]`), and
    /// `h.to_pandas()` gives a DataFrame.
    /// `clear=True` also empties the record (stream a long run to disk chunk by chunk).
    #[pyo3(signature = (clear=false))]
    fn history<'py>(&self, py: Python<'py>, clear: bool) -> PyResult<Bound<'py, PyAny>> {
        let mut sim = self.lock();
        let taken;
        let h = if clear {
            taken = sim.take_history();
            &taken[..]
        } else {
            sim.history()
        };
        let d = PyDict::new(py);
        let col = |f: &dyn Fn(&needlesim::needle::NeedleSample) -> f64| -> Vec<f64> {
            h.iter().map(f).collect()
        };
        d.set_item(
            "step",
            PyArray1::from_vec(py, h.iter().map(|s| s.step as i64).collect()),
        )?;
        d.set_item("time", PyArray1::from_vec(py, col(&|s| s.time)))?;
        d.set_item(
            "depth",
            PyArray1::from_vec(py, col(&|s| sim.depth_of(s.tip, s.direction))),
        )?;
        d.set_item("axial", PyArray1::from_vec(py, col(&|s| s.force.axial)))?;
        d.set_item("lateral", PyArray1::from_vec(py, col(&|s| s.force.lateral)))?;
        d.set_item("tip", PyArray1::from_vec(py, col(&|s| s.force.tip)))?;
        d.set_item("torque", PyArray1::from_vec(py, col(&|s| s.force.torque)))?;
        let ints = |f: &dyn Fn(&needlesim::needle::NeedleSample) -> usize| -> Vec<i64> {
            h.iter().map(|s| f(s) as i64).collect()
        };
        d.set_item(
            "active_nodes",
            PyArray1::from_vec(py, ints(&|s| s.active_nodes)),
        )?;
        d.set_item(
            "needle_nodes",
            PyArray1::from_vec(py, ints(&|s| s.needle_nodes)),
        )?;
        let states: Vec<&str> = h.iter().map(|s| state_name(s.state)).collect();
        d.set_item("state", states)?;
        let names = sim.region_names();
        let regions: Vec<&str> = h
            .iter()
            .map(|s| {
                s.region
                    .and_then(|r| names.get(r as usize))
                    .map_or("", |n| n.as_str())
            })
            .collect();
        d.set_item("region", regions)?;
        d.set_item(
            "tissue_depth",
            PyArray1::from_vec(py, col(&|s| s.tissue_depth.unwrap_or(f64::NAN))),
        )?;
        drop(sim);
        typed(py, "_needle_history", (d,))
    }

    /// Nodes simulated now (mesh nodes plus needle nodes).
    #[getter]
    fn active_nodes(&self) -> usize {
        self.lock().editor().n_active()
    }

    /// Allocated node slots (mesh nodes plus the needle's capacity).
    #[getter]
    fn capacity(&self) -> usize {
        self.lock().editor().capacity()
    }

    /// Nodes of the tissue mesh.
    #[getter]
    fn mesh_nodes(&self) -> usize {
        self.lock().editor().n_mesh()
    }

    /// Needle nodes now (Surface, Shaft and Tip nodes).
    #[getter]
    fn needle_nodes(&self) -> usize {
        self.lock().needle_nodes().len()
    }

    /// Simulated time in s.
    #[getter]
    fn time(&self) -> f64 {
        self.lock().time()
    }

    /// Steps taken.
    #[getter]
    fn steps(&self) -> u64 {
        self.lock().steps()
    }

    /// Time step in s.
    #[getter]
    fn dt(&self) -> f64 {
        self.lock().dt()
    }

    /// The backend in use, e.g. "cpu (1 thread)" or "gpu (<adapter>)".
    #[getter]
    fn backend(&self) -> String {
        self.lock().backend().name()
    }

    /// Warnings from building (for example the CPU fallback of backend "auto").
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.warnings.clone()
    }

    fn __repr__(&self) -> String {
        let mut s = self.lock();
        format!(
            "Simulation(backend={:?}, active_nodes={}, steps={}, state={:?})",
            s.backend().name(),
            s.editor().n_active(),
            s.steps(),
            state_name(s.state())
        )
    }
}

/// The GPU adapter wgpu finds, described in one line, or None without one.
#[pyfunction]
fn adapter() -> Option<String> {
    needlesim::gpu::GpuContext::new(0)
        .ok()
        .map(|c| c.describe())
}

/// The tissue models, from needlesim's registry: one dict per model with its TOML tag
/// (`model = "<tag>"` in `[material]`), short name, label and structural keys.
#[pyfunction]
fn models(py: Python<'_>) -> PyResult<Vec<Bound<'_, PyDict>>> {
    needlesim::core::models::MODELS
        .iter()
        .map(|m| {
            let d = PyDict::new(py);
            d.set_item("tag", m.tag)?;
            d.set_item("short_name", m.short_name)?;
            d.set_item("label", m.label)?;
            d.set_item("structural_keys", m.structural_keys.to_vec())?;
            Ok(d)
        })
        .collect()
}

#[pymodule]
fn _needlesim(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // A surface reader's panic becomes a ValueError naming the file: no Rust panic message
    // on stderr before it (other panics keep it).
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if !needlesim::core::geometry::panic_is_guarded() {
            default(info);
        }
    }));
    m.add_class::<PySimulation>()?;
    m.add_class::<haptic::PyHapticLoop>()?;
    m.add_class::<haptic::PySineDevice>()?;
    m.add_function(wrap_pyfunction!(adapter, m)?)?;
    m.add_function(wrap_pyfunction!(models, m)?)?;
    m.add_function(wrap_pyfunction!(rod::flexible_needle, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
