//! The fixed-rate loop: a thread that, every period `T`, reads the device pose, steps the
//! simulation `T / dt` steps with the needle at the proxy's pose, advances the proxy
//! under the coupling and the tissue force ([`crate::coupling`]), and sends the coupling
//! force to the device (low-passed and saturated if asked).
//!
//! Timing: each tick starts at its deadline (sleep, then a spin for the last
//! [`HapticConfig::spin`]); a tick whose work runs past the next deadline is an overrun,
//! and the next tick starts at once, without bursts to catch up: the simulated time then
//! falls behind wall time.

use crate::coupling::{Proxy, VirtualCoupling};
use crate::device::{Device, DeviceError, Tick};
use crate::lowpass::LowPass;
use crate::stats::{HapticStats, Recorder, TickRecord};
use glam::DVec3;
use needlesim_needle::{Simulation, SimulationError};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The loop's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HapticConfig {
    /// Ticks per second (default 1000); the period must be a whole number of the
    /// scene's time steps.
    pub rate: f64,
    /// The virtual coupling between device and needle.
    pub coupling: VirtualCoupling,
    /// Cutoff of the first-order low-pass on the device force, Hz (`None`, the default:
    /// no filter).
    pub lowpass: Option<f64>,
    /// Largest force magnitude sent to the device, N (default 10; set your device's
    /// peak force). Larger forces are scaled down to it and counted
    /// ([`HapticStats::saturated`]).
    pub max_force: f64,
    /// Time before each deadline spent spinning instead of sleeping (default 1 ms: at
    /// 1 kHz the loop's thread busy-waits and keeps a core). A sleeping thread wakes up
    /// late on a loaded machine: on this project's 2-core test machine the 648-node
    /// loop's p99 period was 2.0-2.8 ms with 200 us of spin and 1.06-1.27 ms with 1 ms
    /// (`examples/loop_bench.rs`). Lower it to give the core back.
    pub spin: Duration,
    /// Tick records kept for [`HapticLoop::records`] and the percentiles (default 65536,
    /// about a minute at 1 kHz; a ring, oldest dropped).
    pub keep: usize,
    /// Stop by itself after this many ticks (`None`, the default: run until
    /// [`HapticLoop::stop`]).
    pub max_ticks: Option<u64>,
}

impl Default for HapticConfig {
    fn default() -> Self {
        HapticConfig {
            rate: 1000.0,
            coupling: VirtualCoupling::default(),
            lowpass: None,
            max_force: 10.0,
            spin: Duration::from_millis(1),
            keep: 1 << 16,
            max_ticks: None,
        }
    }
}

/// `v` for a message: plainly between 1e-4 and 1e6, in e-notation beyond (1e-300 Hz was
/// printed with 300 digits).
fn readable(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-4..1e6).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

/// Why the loop did not start or stopped.
#[derive(Debug, thiserror::Error)]
pub enum HapticError {
    /// The period is not a whole number of time steps.
    #[error(
        "a haptic rate of {} Hz (period {} s) is not a whole number of the scene's time steps of {} s",
        readable(*rate), readable(*period), readable(*dt)
    )]
    Rate {
        /// Ticks per second asked for.
        rate: f64,
        /// Its period, s.
        period: f64,
        /// The scene's time step, s.
        dt: f64,
    },
    /// A setting is out of range.
    #[error("haptic setting `{name}` = {} is out of range ({expected})", readable(*value))]
    Setting {
        /// The setting.
        name: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
    /// The scene has no needle.
    #[error("the scene has no [needle]: there is nothing for the device to hold")]
    NoNeedle,
    /// The device's pose is not usable.
    #[error("tick {tick}: the device pose is not finite (position {position:?}, direction {direction:?})")]
    Pose {
        /// Tick number.
        tick: u64,
        /// The position read.
        position: [f64; 3],
        /// The direction read.
        direction: [f64; 3],
    },
    /// The simulation failed (diverged, bad pose...).
    #[error("tick {tick}: {source}")]
    Simulation {
        /// Tick number.
        tick: u64,
        /// What failed.
        #[source]
        source: SimulationError,
    },
    /// The device failed.
    #[error("tick {tick}: {source}")]
    Device {
        /// Tick number.
        tick: u64,
        /// What failed.
        #[source]
        source: DeviceError,
    },
    /// The loop's thread panicked.
    #[error("the haptic loop's thread panicked: {0}")]
    Panicked(String),
}

/// Owner of the simulation the loop steps: the simulation itself, or one shared with
/// other threads behind a mutex (locked once per tick, briefly; a reader holding the lock
/// delays the tick).
pub trait Plant: Send + 'static {
    /// Calls `f` with the simulation.
    fn with<R>(&mut self, f: impl FnOnce(&mut Simulation) -> R) -> R;
}

impl Plant for Simulation {
    fn with<R>(&mut self, f: impl FnOnce(&mut Simulation) -> R) -> R {
        f(self)
    }
}

impl Plant for Arc<Mutex<Simulation>> {
    fn with<R>(&mut self, f: impl FnOnce(&mut Simulation) -> R) -> R {
        f(&mut self.lock().unwrap_or_else(|p| p.into_inner()))
    }
}

/// What the loop's thread and its handle share.
#[derive(Debug, Default)]
struct Shared {
    stop: AtomicBool,
    recorder: Mutex<Recorder>,
    latest: Mutex<Option<TickRecord>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// What [`HapticLoop::stop`] hands back.
pub struct Stopped<P> {
    /// The simulation (as stepped up to the last tick).
    pub plant: P,
    /// The timing over the ticks kept.
    pub stats: HapticStats,
    /// The tick records kept, oldest first.
    pub records: Vec<TickRecord>,
    /// Why the loop stopped by itself, if it failed.
    pub error: Option<HapticError>,
}

/// A haptic loop running on its own thread.
pub struct HapticLoop<P: Plant> {
    thread: Option<JoinHandle<(P, Option<HapticError>)>>,
    shared: Arc<Shared>,
}

/// The loop's constants, checked.
#[derive(Debug, Clone, Copy)]
struct Timing {
    period: f64,
    steps: u64,
}

/// The lowest tick rate the loop accepts, Hz.
pub const MIN_RATE: f64 = 1.0;

/// The most scene time steps one tick may run: `stop` waits for the tick in progress.
pub const MAX_TICK_STEPS: u64 = 100_000;

fn check(config: &HapticConfig, dt: f64) -> Result<Timing, HapticError> {
    let setting = |name, value, expected| HapticError::Setting {
        name,
        value,
        expected,
    };
    if !(config.rate.is_finite() && config.rate >= MIN_RATE) {
        return Err(setting(
            "rate",
            config.rate,
            "at least 1 Hz (a haptic loop ticks hundreds to thousands of times a second; \
             a slower one ran a tick of millions of steps that nothing could stop)",
        ));
    }
    if let Some((name, value)) = config.coupling.invalid() {
        return Err(setting(
            name,
            value,
            "finite and not negative; mass and stiffness above 0",
        ));
    }
    if let Some(fc) = config.lowpass {
        if !(fc.is_finite() && fc > 0.0) {
            return Err(setting("lowpass", fc, "a positive cutoff in Hz"));
        }
    }
    if !(config.max_force.is_finite() && config.max_force > 0.0) {
        return Err(setting(
            "max_force",
            config.max_force,
            "a positive force in N",
        ));
    }
    let period = 1.0 / config.rate;
    let steps = (period / dt).round();
    if steps < 1.0 || (steps * dt - period).abs() > 1e-6 * period {
        return Err(HapticError::Rate {
            rate: config.rate,
            period,
            dt,
        });
    }
    if steps > MAX_TICK_STEPS as f64 {
        return Err(setting(
            "rate",
            config.rate,
            "a tick of at most 100,000 scene time steps (a lower rate or a smaller dt \
             makes each tick a run that `stop` cannot interrupt)",
        ));
    }
    Ok(Timing {
        period,
        steps: steps as u64,
    })
}

impl<P: Plant> HapticLoop<P> {
    /// Starts the loop on a new thread: the proxy starts at rest at the needle's base,
    /// and the scene's script, if any, stops playing at the first tick.
    pub fn start<D: Device + 'static>(
        mut plant: P,
        device: D,
        config: HapticConfig,
    ) -> Result<HapticLoop<P>, HapticError> {
        let (dt, base) = plant.with(|s| (s.dt(), s.needle().map(|n| n.base())));
        let timing = check(&config, dt)?;
        let base = base.ok_or(HapticError::NoNeedle)?;
        let shared = Arc::new(Shared::default());
        {
            let mut r = lock(&shared.recorder);
            r.keep = config.keep;
            r.target = timing.period;
        }
        let s = shared.clone();
        let thread = std::thread::Builder::new()
            .name("needlesim-haptic".into())
            .spawn(move || {
                let mut device = device;
                let error = run(
                    &mut plant,
                    &mut device,
                    &config,
                    timing,
                    DVec3::from(base),
                    &s,
                )
                .err();
                (plant, error)
            })
            .map_err(|e| HapticError::Panicked(e.to_string()))?;
        Ok(HapticLoop {
            thread: Some(thread),
            shared,
        })
    }

    /// The last tick's record (`None` before the first tick).
    pub fn latest(&self) -> Option<TickRecord> {
        *lock(&self.shared.latest)
    }

    /// Timing so far.
    pub fn stats(&self) -> HapticStats {
        lock(&self.shared.recorder).stats()
    }

    /// The tick records kept so far, oldest first.
    pub fn records(&self) -> Vec<TickRecord> {
        lock(&self.shared.recorder)
            .records
            .iter()
            .copied()
            .collect()
    }

    /// Whether the loop's thread is still ticking.
    pub fn running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }

    /// Stops the loop (after its current tick, sending zero force) and hands back the
    /// simulation, the timing and the error that stopped it, if any.
    pub fn stop(mut self) -> Result<Stopped<P>, HapticError> {
        self.shared.stop.store(true, Ordering::Relaxed);
        self.join_thread()
    }

    /// Waits until the loop stops by itself ([`HapticConfig::max_ticks`] or an error).
    pub fn join(mut self) -> Result<Stopped<P>, HapticError> {
        self.join_thread()
    }

    fn join_thread(&mut self) -> Result<Stopped<P>, HapticError> {
        let thread = self.thread.take().expect("joined once");
        let (plant, error) = thread.join().map_err(|p| {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            HapticError::Panicked(msg)
        })?;
        Ok(Stopped {
            plant,
            stats: self.stats(),
            records: self.records(),
            error,
        })
    }
}

impl<P: Plant> Drop for HapticLoop<P> {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Sleeps, then spins, until `deadline`.
fn wait_until(deadline: Instant, spin: Duration) {
    loop {
        let now = Instant::now();
        if now >= deadline {
            return;
        }
        let left = deadline - now;
        if left > spin {
            std::thread::sleep(left - spin);
        } else {
            std::hint::spin_loop();
        }
    }
}

/// `f` scaled down to magnitude `max` when larger, and whether it was.
fn saturate(f: DVec3, max: f64) -> (DVec3, bool) {
    let n = f.length();
    if n > max {
        (f * (max / n), true)
    } else {
        (f, false)
    }
}

/// The loop body; on return the device has been sent zero force.
fn run<P: Plant, D: Device>(
    plant: &mut P,
    device: &mut D,
    config: &HapticConfig,
    timing: Timing,
    base: DVec3,
    shared: &Shared,
) -> Result<(), HapticError> {
    let start = Instant::now();
    let mut proxy = Proxy::at_rest(base);
    let mut lowpass = config.lowpass.map(|fc| LowPass::new(fc, timing.period));
    let mut next = start;
    let mut last_start: Option<Instant> = None;
    let mut last_device: Option<DVec3> = None;
    let mut tick = Tick {
        index: 0,
        time: 0.0,
        wall: 0.0,
    };
    let result = loop {
        if shared.stop.load(Ordering::Relaxed) || config.max_ticks.is_some_and(|m| tick.index >= m)
        {
            break Ok(());
        }
        wait_until(next, config.spin);
        let t0 = Instant::now();
        tick.time = tick.index as f64 * timing.period;
        tick.wall = (t0 - start).as_secs_f64();
        let pose = match device.pose(&tick) {
            Ok(p) => p,
            Err(source) => {
                break Err(HapticError::Device {
                    tick: tick.index,
                    source,
                })
            }
        };
        let finite = pose
            .position
            .iter()
            .chain(&pose.direction)
            .all(|v| v.is_finite());
        if !finite {
            break Err(HapticError::Pose {
                tick: tick.index,
                position: pose.position,
                direction: pose.direction,
            });
        }
        let xd = DVec3::from(pose.position);
        let vd = last_device.map_or(DVec3::ZERO, |p| (xd - p) / timing.period);
        last_device = Some(xd);
        // The needle steps at the proxy's pose (where the last tick left it), then the
        // proxy answers this step's tissue force.
        let stepped = plant.with(|s| -> Result<_, SimulationError> {
            s.set_pose(proxy.position.into(), pose.direction)?;
            s.step_n(timing.steps)?;
            let n = s.needle().expect("checked at start");
            let depth = s.depth_of(n.tip(), n.direction());
            Ok((DVec3::from(s.needle_force().total), depth, s.state()))
        });
        let (tissue, depth, state) = match stepped {
            Ok(v) => v,
            Err(source) => {
                break Err(HapticError::Simulation {
                    tick: tick.index,
                    source,
                })
            }
        };
        let coupling = proxy.advance(&config.coupling, xd, vd, tissue, timing.period);
        let filtered = match lowpass.as_mut() {
            Some(f) => DVec3::from(f.apply(coupling.into())),
            None => coupling,
        };
        let (force, saturated) = saturate(filtered, config.max_force);
        if let Err(source) = device.render(force.into(), &tick) {
            break Err(HapticError::Device {
                tick: tick.index,
                source,
            });
        }
        let done = Instant::now();
        let record = TickRecord {
            index: tick.index,
            wall: tick.wall,
            period: last_start.map_or(0.0, |l| (t0 - l).as_secs_f64()),
            work: (done - t0).as_secs_f64(),
            latency: done.saturating_duration_since(pose.sampled).as_secs_f64(),
            device: pose.position,
            needle: proxy.position.into(),
            force: force.into(),
            tissue: tissue.into(),
            depth,
            saturated,
            state,
        };
        last_start = Some(t0);
        next += Duration::from_secs_f64(timing.period);
        let overrun = done > next;
        if overrun {
            next = done;
        }
        lock(&shared.recorder).push(record, overrun);
        *lock(&shared.latest) = Some(record);
        tick.index += 1;
    };
    // Whatever stopped the loop, the device must not keep the last force.
    let _ = device.render([0.0; 3], &tick);
    result
}
