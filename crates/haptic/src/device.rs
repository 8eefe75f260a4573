//! The device side of the loop: what the loop reads at the start of a tick (a pose) and
//! writes at its end (a force).
//!
//! A real device plugs in by implementing [`Device`] over its driver, called from the
//! loop's own thread: Force Dimension's SDK (`dhdGetPosition`, `dhdSetForce`), chai3d's
//! `cGenericHapticDevice` (`getPosition`, `setForce`), or OpenHaptics HD
//! (`hdGetDoublev(HD_CURRENT_POSITION)`, `hdSetDoublev(HD_CURRENT_FORCE)` between
//! `hdBeginFrame`/`hdEndFrame`). A driver that runs its own servo thread (OpenHaptics'
//! scheduler) instead writes each pose into a [`DeviceHandle`] and reads the force back
//! from it; the loop then uses the matching [`SharedDevice`]. Convert units and frames in
//! the implementation: the loop works in metres and newtons, in the scene's frame.

use needlesim_needle::Needle;
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// One tick of the loop, as the device sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tick {
    /// Tick number, from 0.
    pub index: u64,
    /// Scheduled time of the tick since the loop started, s (`index * period`): the
    /// simulated time the tick advances to.
    pub time: f64,
    /// Wall time since the loop started, s, when the tick began.
    pub wall: f64,
}

/// The pose of the device's needle: where its base (the hub held by the device) is and
/// where it points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DevicePose {
    /// Position of the needle's base, m.
    pub position: [f64; 3],
    /// Direction base to tip (normalised by the simulation).
    pub direction: [f64; 3],
    /// When the pose was sampled: the loop's pose-to-force latency runs from here.
    pub sampled: Instant,
}

impl DevicePose {
    /// A pose sampled now.
    pub fn now(position: [f64; 3], direction: [f64; 3]) -> DevicePose {
        DevicePose {
            position,
            direction,
            sampled: Instant::now(),
        }
    }
}

/// A device's failure, with its message (the loop stops and sends zero force).
#[derive(Debug, thiserror::Error)]
#[error("haptic device: {0}")]
pub struct DeviceError(pub String);

/// A haptic device read and written by the loop's thread once a tick.
pub trait Device: Send {
    /// The pose at the start of tick `tick`.
    fn pose(&mut self, tick: &Tick) -> Result<DevicePose, DeviceError>;
    /// Sends the force to render, N, at the end of tick `tick` (zero when the loop
    /// stops).
    fn render(&mut self, force: [f64; 3], tick: &Tick) -> Result<(), DeviceError>;
}

impl<D: Device + ?Sized> Device for Box<D> {
    fn pose(&mut self, tick: &Tick) -> Result<DevicePose, DeviceError> {
        (**self).pose(tick)
    }

    fn render(&mut self, force: [f64; 3], tick: &Tick) -> Result<(), DeviceError> {
        (**self).render(force, tick)
    }
}

/// What a [`DeviceHandle`] and its [`SharedDevice`] share.
#[derive(Debug)]
struct Slot {
    pose: DevicePose,
    force: [f64; 3],
    tick: Option<u64>,
}

/// A device whose pose is set from another thread through a [`DeviceHandle`] (a driver's
/// own servo thread, a Python thread, a network receiver); the loop reads the latest pose.
#[derive(Debug)]
pub struct SharedDevice {
    slot: Arc<Mutex<Slot>>,
}

/// The writer's side of a [`SharedDevice`]: set poses, read the rendered force.
#[derive(Debug, Clone)]
pub struct DeviceHandle {
    slot: Arc<Mutex<Slot>>,
}

impl SharedDevice {
    /// A shared device starting at `position`, `direction`, and its handle.
    pub fn new(position: [f64; 3], direction: [f64; 3]) -> (SharedDevice, DeviceHandle) {
        let slot = Arc::new(Mutex::new(Slot {
            pose: DevicePose::now(position, direction),
            force: [0.0; 3],
            tick: None,
        }));
        (SharedDevice { slot: slot.clone() }, DeviceHandle { slot })
    }
}

fn lock(slot: &Mutex<Slot>) -> std::sync::MutexGuard<'_, Slot> {
    // The slot holds plain values: a panic elsewhere leaves them consistent.
    slot.lock().unwrap_or_else(|p| p.into_inner())
}

impl DeviceHandle {
    /// Sets the device pose, stamped now.
    pub fn set_pose(&self, position: [f64; 3], direction: [f64; 3]) {
        lock(&self.slot).pose = DevicePose::now(position, direction);
    }

    /// The last force rendered, N, and the tick that rendered it (`None` before the
    /// first).
    pub fn force(&self) -> ([f64; 3], Option<u64>) {
        let s = lock(&self.slot);
        (s.force, s.tick)
    }
}

impl Device for SharedDevice {
    fn pose(&mut self, _tick: &Tick) -> Result<DevicePose, DeviceError> {
        Ok(lock(&self.slot).pose)
    }

    fn render(&mut self, force: [f64; 3], tick: &Tick) -> Result<(), DeviceError> {
        let mut s = lock(&self.slot);
        s.force = force;
        s.tick = Some(tick.index);
        Ok(())
    }
}

/// Which clock a simulated device follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Clock {
    /// The tick's scheduled time ([`Tick::time`]): the same poses at every run, whatever
    /// the loop's timing (tests).
    Scheduled,
    /// Wall time ([`Tick::wall`]): what a hand on a real device does while the loop runs
    /// late.
    Wall,
}

/// A simulated device: a sinusoidal insertion along a fixed direction,
/// `x(t) = start + d A (1 - cos(2 pi f t)) / 2`, in to depth `A` and back out every
/// `1 / f` seconds. It records nothing; the loop's tick records hold its poses and forces.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SineDevice {
    /// Base position at `t = 0`, m.
    pub start: [f64; 3],
    /// Unit insertion direction (also the needle direction).
    pub direction: [f64; 3],
    /// Stroke `A`, m.
    pub amplitude: f64,
    /// Strokes per second `f`, Hz.
    pub frequency: f64,
    /// The clock it follows.
    pub clock: Clock,
}

impl SineDevice {
    /// A sinusoidal insertion of `needle` from where it is, along itself.
    pub fn along(needle: &Needle, amplitude: f64, frequency: f64, clock: Clock) -> SineDevice {
        SineDevice {
            start: needle.base(),
            direction: needle.direction(),
            amplitude,
            frequency,
            clock,
        }
    }

    /// The base position at time `t`, s.
    pub fn position_at(&self, t: f64) -> [f64; 3] {
        let s =
            0.5 * self.amplitude * (1.0 - (2.0 * std::f64::consts::PI * self.frequency * t).cos());
        std::array::from_fn(|i| self.start[i] + self.direction[i] * s)
    }
}

impl Device for SineDevice {
    fn pose(&mut self, tick: &Tick) -> Result<DevicePose, DeviceError> {
        let t = match self.clock {
            Clock::Scheduled => tick.time,
            Clock::Wall => tick.wall,
        };
        Ok(DevicePose::now(self.position_at(t), self.direction))
    }

    fn render(&mut self, _force: [f64; 3], _tick: &Tick) -> Result<(), DeviceError> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shared_device_passes_poses_and_forces() {
        let (mut dev, handle) = SharedDevice::new([0.0; 3], [1.0, 0.0, 0.0]);
        handle.set_pose([0.1, 0.2, 0.3], [0.0, 1.0, 0.0]);
        let tick = Tick {
            index: 7,
            time: 0.007,
            wall: 0.0071,
        };
        let p = dev.pose(&tick).unwrap();
        assert_eq!(
            (p.position, p.direction),
            ([0.1, 0.2, 0.3], [0.0, 1.0, 0.0])
        );
        assert_eq!(handle.force(), ([0.0; 3], None));
        dev.render([1.0, -2.0, 0.5], &tick).unwrap();
        assert_eq!(handle.force(), ([1.0, -2.0, 0.5], Some(7)));
    }

    #[test]
    fn the_sine_device_goes_in_and_comes_back() {
        let d = SineDevice {
            start: [-0.03, 0.0, 0.0],
            direction: [1.0, 0.0, 0.0],
            amplitude: 0.04,
            frequency: 0.25,
            clock: Clock::Scheduled,
        };
        assert_eq!(d.position_at(0.0), [-0.03, 0.0, 0.0]);
        assert!((d.position_at(2.0)[0] - 0.01).abs() < 1e-15);
        assert!((d.position_at(4.0)[0] + 0.03).abs() < 1e-15);
    }
}
