//! `needlesim.HapticLoop` and `needlesim.SineDevice`: the haptic loop of
//! `needlesim::haptic` on its own thread, stepping a `Simulation` shared with Python.

use crate::{runtime_error, value_error, PySimulation};
use needlesim::haptic::{
    Clock, Device, DeviceHandle, HapticConfig, HapticLoop, HapticStats, SharedDevice, SineDevice,
    TickRecord, VirtualCoupling,
};
use needlesim::needle::Simulation;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

type Shared = Arc<Mutex<Simulation>>;

/// A simulated device for `HapticLoop(device=...)`: a sinusoidal insertion from `start`
/// along `direction`, `amplitude` m deep, `frequency` strokes per second, following the
/// ticks' schedule (`clock="scheduled"`, reproducible) or wall time (`"wall"`).
#[pyclass(module = "needlesim._needlesim", name = "SineDevice", frozen)]
#[derive(Clone)]
pub(crate) struct PySineDevice(SineDevice);

#[pymethods]
impl PySineDevice {
    #[new]
    #[pyo3(signature = (start, direction, amplitude, frequency, clock="scheduled"))]
    fn new(
        start: [f64; 3],
        direction: [f64; 3],
        amplitude: f64,
        frequency: f64,
        clock: &str,
    ) -> PyResult<Self> {
        let clock = match clock {
            "scheduled" => Clock::Scheduled,
            "wall" => Clock::Wall,
            other => {
                return Err(value_error(format!(
                    "clock must be \"scheduled\" or \"wall\", not {other:?}"
                )))
            }
        };
        let finite = start
            .iter()
            .chain(&direction)
            .chain([&amplitude, &frequency]);
        if !finite.into_iter().all(|v| v.is_finite()) {
            return Err(value_error(
                "SineDevice: start, direction, amplitude and frequency must be finite",
            ));
        }
        needlesim::needle::needle::unit(direction)
            .map_err(|e| value_error(format!("SineDevice: {e}")))?;
        Ok(PySineDevice(SineDevice {
            start,
            direction,
            amplitude,
            frequency,
            clock,
        }))
    }

    /// The base position at time `t` s.
    fn position_at<'py>(&self, py: Python<'py>, t: f64) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.0.position_at(t).to_vec())
    }
}

/// The simulation's haptic loop: steps `sim` on a thread of its own at `rate` ticks per
/// second with the needle tied to a device by a virtual coupling (spring `stiffness`
/// N/m, damping `damping` N s/m, a proxy of `proxy_mass` kg damped by `proxy_damping`
/// N s/m, default critical), and sends it the coupling force, low-passed at `lowpass` Hz
/// if given and capped at `max_force` N. The device is `device` (a `SineDevice`) or, by
/// default, poses set with `set_device` from Python. While the loop runs, `sim.step` and
/// `sim.set_pose` raise RuntimeError; reading `sim` briefly blocks the loop's tick.
///
/// Every method takes the object shared (the class is frozen, its state behind short
/// locks): while one thread waits in `join()`, a device thread can set the pose, read the
/// force and stop the loop (with a mutable borrow held for the wait, every such call
/// raised "Already borrowed").
#[pyclass(module = "needlesim._needlesim", name = "HapticLoop", frozen)]
pub(crate) struct PyHapticLoop {
    haptic: Mutex<Option<HapticLoop<Shared>>>,
    handle: Option<DeviceHandle>,
    busy: Arc<AtomicBool>,
    /// What the loop measured once stopped, and the error it stopped on.
    finished: Mutex<Option<Finished>>,
}

/// A stopped loop's stats, records and error.
type Finished = (HapticStats, Vec<TickRecord>, Option<String>);

/// Locks a mutex, a poisoned one included (its data is a plain value, still consistent).
fn locked<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

fn record<'py>(py: Python<'py>, r: &TickRecord) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("tick", r.index)?;
    d.set_item("wall", r.wall)?;
    d.set_item("period", r.period)?;
    d.set_item("work", r.work)?;
    d.set_item("latency", r.latency)?;
    d.set_item("device", PyArray1::from_vec(py, r.device.to_vec()))?;
    d.set_item("needle", PyArray1::from_vec(py, r.needle.to_vec()))?;
    d.set_item("force", PyArray1::from_vec(py, r.force.to_vec()))?;
    d.set_item("tissue", PyArray1::from_vec(py, r.tissue.to_vec()))?;
    d.set_item("depth", r.depth)?;
    d.set_item("saturated", r.saturated)?;
    d.set_item("state", crate::state_name(r.state))?;
    Ok(d)
}

fn stats_dict<'py>(
    py: Python<'py>,
    s: &needlesim::haptic::HapticStats,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("ticks", s.ticks)?;
    d.set_item("overruns", s.overruns)?;
    d.set_item("saturated", s.saturated)?;
    d.set_item("target", s.target)?;
    for (name, p) in [
        ("period", s.period),
        ("work", s.work),
        ("latency", s.latency),
    ] {
        d.set_item(format!("{name}_p50"), p.p50)?;
        d.set_item(format!("{name}_p99"), p.p99)?;
        d.set_item(format!("{name}_max"), p.max)?;
    }
    Ok(d)
}

impl PyHapticLoop {
    fn last(&self) -> Option<TickRecord> {
        if let Some(h) = locked(&self.haptic).as_ref() {
            return h.latest();
        }
        locked(&self.finished)
            .as_ref()
            .and_then(|(_, r, _)| r.last().copied())
    }

    /// The stats of the stopped loop as a dict, or its error.
    fn finished_stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        match locked(&self.finished).as_ref() {
            Some((_, _, Some(e))) => Err(runtime_error(e.clone())),
            Some((s, _, None)) => stats_dict(py, s),
            None => Err(runtime_error("the haptic loop failed to stop")),
        }
    }
}

#[pymethods]
impl PyHapticLoop {
    #[new]
    #[pyo3(signature = (sim, rate=1000.0, stiffness=None, damping=None, proxy_mass=None, proxy_damping=None, lowpass=None, max_force=10.0, max_ticks=None, device=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        sim: &PySimulation,
        rate: f64,
        stiffness: Option<f64>,
        damping: Option<f64>,
        proxy_mass: Option<f64>,
        proxy_damping: Option<f64>,
        lowpass: Option<f64>,
        max_force: f64,
        max_ticks: Option<&Bound<'_, PyAny>>,
        device: Option<PyRef<PySineDevice>>,
    ) -> PyResult<Self> {
        let max_ticks = crate::opt_count_arg(max_ticks, "max_ticks", u64::MAX)?;
        let d = VirtualCoupling::default();
        let k = stiffness.unwrap_or(d.stiffness);
        let m = proxy_mass.unwrap_or(d.proxy_mass);
        let coupling = VirtualCoupling {
            stiffness: k,
            damping: damping.unwrap_or(d.damping),
            proxy_mass: m,
            // Critical for the spring unless given (the default's rule; a negative K or m
            // is named by the loop's check, not made NaN here).
            proxy_damping: proxy_damping
                .unwrap_or_else(|| VirtualCoupling::critical_damping(k.abs(), m.abs())),
        };
        let config = HapticConfig {
            rate,
            coupling,
            lowpass,
            max_force,
            max_ticks,
            ..HapticConfig::default()
        };
        if sim.busy.swap(true, Ordering::AcqRel) {
            return Err(runtime_error(
                "another haptic loop is stepping this simulation",
            ));
        }
        let start = |device: Box<dyn Device>| HapticLoop::start(sim.sim.clone(), device, config);
        let (started, handle) = match device {
            Some(s) => (start(Box::new(s.0)), None),
            None => {
                let (base, dir) = {
                    let s = sim.lock();
                    let n = s
                        .needle()
                        .ok_or_else(|| value_error("the scene has no [needle]"));
                    match n {
                        Ok(n) => (n.base(), n.direction()),
                        Err(e) => {
                            sim.busy.store(false, Ordering::Release);
                            return Err(e);
                        }
                    }
                };
                let (dev, handle) = SharedDevice::new(base, dir);
                (start(Box::new(dev)), Some(handle))
            }
        };
        match started {
            Ok(haptic) => Ok(PyHapticLoop {
                haptic: Mutex::new(Some(haptic)),
                handle,
                busy: sim.busy.clone(),
                finished: Mutex::new(None),
            }),
            Err(e) => {
                sim.busy.store(false, Ordering::Release);
                Err(value_error(e))
            }
        }
    }

    /// Sets the device pose (needle base position, m, and direction) for the next tick;
    /// only for the default shared device.
    fn set_device(&self, position: [f64; 3], direction: [f64; 3]) -> PyResult<()> {
        let h = self
            .handle
            .as_ref()
            .ok_or_else(|| value_error("set_device needs the default device (device=None)"))?;
        // Checked here, where the caller can be told, not on the loop's thread (a NaN
        // stopped the loop and surfaced only from `stop()`).
        if !position.iter().all(|c| c.is_finite()) {
            return Err(value_error(format!(
                "set_device: position must be finite, got {position:?}"
            )));
        }
        needlesim::needle::needle::unit(direction)
            .map_err(|e| value_error(format!("set_device: {e}")))?;
        h.set_pose(position, direction);
        Ok(())
    }

    /// The force sent to the device in the last tick, N, shape (3,).
    #[getter]
    fn force<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let f = self.last().map_or([0.0; 3], |r| r.force);
        Ok(PyArray1::from_vec(py, f.to_vec()))
    }

    /// The last tick's record as a dict (None before the first tick).
    fn latest<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        self.last().map(|r| record(py, &r)).transpose()
    }

    /// Whether the loop's thread is still ticking.
    #[getter]
    fn running(&self) -> bool {
        locked(&self.haptic).as_ref().is_some_and(|h| h.running())
    }

    /// Timing so far: ticks, overruns, saturated, target (s) and p50/p99/max of the tick
    /// period, the work per tick and the pose-to-force latency (s).
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        if let Some(h) = locked(&self.haptic).as_ref() {
            return stats_dict(py, &h.stats());
        }
        match locked(&self.finished).as_ref() {
            Some((s, _, _)) => stats_dict(py, s),
            None => Err(runtime_error("the haptic loop failed to stop")),
        }
    }

    /// The tick records kept (the last 65536), as numpy arrays: tick, wall, period, work,
    /// latency, depth (n,), device, needle, force, tissue (n, 3), saturated (bool list)
    /// and state (str list).
    fn records<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let live = locked(&self.haptic).as_ref().map(|h| h.records());
        match live {
            Some(r) => records_dict(py, &r),
            None => match locked(&self.finished).as_ref() {
                Some((_, r, _)) => records_dict(py, r),
                None => Err(runtime_error("the haptic loop failed to stop")),
            },
        }
    }

    /// Stops the loop (zero force sent last), waiting for its thread (without the
    /// interpreter lock), and returns its stats; raises RuntimeError if the loop had
    /// stopped on an error (divergence, device), naming it. The records stay readable.
    fn stop<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        // Taken out under a short lock: the other methods stay usable while it stops.
        let haptic = locked(&self.haptic)
            .take()
            .ok_or_else(|| runtime_error("the haptic loop was stopped already"))?;
        let stopped = py.detach(|| haptic.stop());
        self.busy.store(false, Ordering::Release);
        let stopped = match stopped {
            Ok(s) => s,
            Err(e) => {
                // Recorded, so that a thread waiting in `join()` ends with the same error.
                let message = e.to_string();
                *locked(&self.finished) =
                    Some((HapticStats::default(), Vec::new(), Some(message.clone())));
                return Err(runtime_error(message));
            }
        };
        *locked(&self.finished) = Some((
            stopped.stats,
            stopped.records,
            stopped.error.map(|e| e.to_string()),
        ));
        self.finished_stats(py)
    }

    /// Waits (without the interpreter lock, handling Ctrl-C every 50 ms) until the loop
    /// stops by itself after `max_ticks` ticks or another thread stops it, then returns
    /// like `stop`. Other threads may call every method meanwhile.
    fn join<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        while self.running() {
            py.detach(|| std::thread::sleep(Duration::from_millis(50)));
            py.check_signals()?;
        }
        if locked(&self.haptic).is_some() {
            return self.stop(py);
        }
        // Stopped by another thread (or while this one waited for the lock).
        loop {
            if locked(&self.finished).is_some() {
                return self.finished_stats(py);
            }
            py.detach(|| std::thread::sleep(Duration::from_millis(5)));
            py.check_signals()?;
        }
    }
}

impl Drop for PyHapticLoop {
    fn drop(&mut self) {
        let taken = self
            .haptic
            .get_mut()
            .unwrap_or_else(|e| e.into_inner())
            .take();
        if let Some(h) = taken {
            let _ = h.stop();
            self.busy.store(false, Ordering::Release);
        }
    }
}

fn records_dict<'py>(py: Python<'py>, r: &[TickRecord]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let col = |f: fn(&TickRecord) -> f64| PyArray1::from_vec(py, r.iter().map(f).collect());
    d.set_item(
        "tick",
        PyArray1::from_vec(py, r.iter().map(|t| t.index).collect()),
    )?;
    d.set_item("wall", col(|t| t.wall))?;
    d.set_item("period", col(|t| t.period))?;
    d.set_item("work", col(|t| t.work))?;
    d.set_item("latency", col(|t| t.latency))?;
    d.set_item("depth", col(|t| t.depth))?;
    let xyz = |f: fn(&TickRecord) -> [f64; 3]| {
        crate::rows(py, r.iter().flat_map(f).collect::<Vec<f64>>(), 3)
    };
    d.set_item("device", xyz(|t| t.device)?)?;
    d.set_item("needle", xyz(|t| t.needle)?)?;
    d.set_item("force", xyz(|t| t.force)?)?;
    d.set_item("tissue", xyz(|t| t.tissue)?)?;
    d.set_item(
        "saturated",
        r.iter().map(|t| t.saturated).collect::<Vec<_>>(),
    )?;
    d.set_item(
        "state",
        r.iter()
            .map(|t| crate::state_name(t.state))
            .collect::<Vec<_>>(),
    )?;
    Ok(d)
}
