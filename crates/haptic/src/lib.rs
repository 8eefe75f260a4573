//! A haptic loop around a needle insertion simulation: a thread stepping the simulation
//! at a fixed rate (1 kHz by default) with the needle tied to a device by a virtual
//! coupling, returning the force to render each tick, with its timing measured.
//!
//! ```no_run
//! # fn demo(sim: needlesim_needle::Simulation) -> Result<(), needlesim_haptic::HapticError> {
//! use needlesim_haptic::{HapticConfig, HapticLoop, SharedDevice};
//! let (device, handle) = SharedDevice::new([-0.22, 0.1, 0.1], [1.0, 0.0, 0.0]);
//! let haptic = HapticLoop::start(sim, device, HapticConfig::default())?;
//! handle.set_pose([-0.21, 0.1, 0.1], [1.0, 0.0, 0.0]); // from the device's thread
//! let (force, _tick) = handle.force();
//! let stopped = haptic.stop()?;
//! println!("p99 tick period {:.3} ms", stopped.stats.period.p99 * 1e3);
//! # Ok(()) }
//! ```

#![warn(missing_docs)]

pub mod coupling;
pub mod device;
pub mod haptic_loop;
pub mod lowpass;
pub mod stats;

pub use coupling::{Proxy, VirtualCoupling};
pub use device::{
    Clock, Device, DeviceError, DeviceHandle, DevicePose, SharedDevice, SineDevice, Tick,
};
pub use haptic_loop::{HapticConfig, HapticError, HapticLoop, Plant, Stopped};
pub use lowpass::LowPass;
pub use stats::{HapticStats, Percentiles, TickRecord};
