//! `[run]`: how long to run and what to write.

use crate::error::SceneError;
use crate::validate::positive_finite;
use serde::Deserialize;

/// Run length and output.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(try_from = "RunToml")]
pub struct RunSettings {
    /// Steps to run (`steps`, default 1000), unless `duration` is given.
    pub steps: u64,
    /// Simulated seconds to run instead of `steps` (`duration`): [`RunSettings::steps_at`]
    /// turns it into steps with the time step the tissue was built with, so that a
    /// `dt = "auto"` scene runs as long whatever its stiffness.
    pub duration: Option<f64>,
    /// Write a frame (CSV row and surface mesh) every this many steps.
    #[serde(default = "default_output_every")]
    pub output_every: u64,
    /// Write the surface mesh of every frame (VTK XML PolyData plus a .pvd time series).
    #[serde(default = "yes")]
    pub surface_frames: bool,
    /// Largest estimated memory in GiB a scene may need (`max_memory_gib`, default 8):
    /// the node count is estimated from the geometry (and the needle) before anything is
    /// allocated ([`crate::geometry::memory`]), and a scene above it is an error naming
    /// the key that asked for the nodes. Raise it for large runs.
    #[serde(default = "default_max_memory_gib")]
    pub max_memory_gib: f64,
}

/// Default of `run.max_memory_gib`: a fixed 8 GiB (physical memory cannot be asked for
/// portably); raise it in the scene for larger runs.
pub const DEFAULT_MAX_MEMORY_GIB: f64 = 8.0;

fn default_max_memory_gib() -> f64 {
    DEFAULT_MAX_MEMORY_GIB
}

fn default_steps() -> u64 {
    1000
}

/// The `[run]` table as written: `steps` and `duration` both optional, not both given.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RunToml {
    steps: Option<u64>,
    duration: Option<f64>,
    #[serde(default = "default_output_every")]
    output_every: u64,
    #[serde(default = "yes")]
    surface_frames: bool,
    #[serde(default = "default_max_memory_gib")]
    max_memory_gib: f64,
}

impl TryFrom<RunToml> for RunSettings {
    type Error = String;
    fn try_from(r: RunToml) -> Result<RunSettings, String> {
        if r.steps.is_some() && r.duration.is_some() {
            return Err("run: give `steps` or `duration`, not both".into());
        }
        Ok(RunSettings {
            steps: r.steps.unwrap_or_else(default_steps),
            duration: r.duration,
            output_every: r.output_every,
            surface_frames: r.surface_frames,
            max_memory_gib: r.max_memory_gib,
        })
    }
}

/// Most steps `run.duration` may ask for (about 30 years of 1 kHz stepping): more is
/// a unit mistake, not a run.
pub const MAX_RUN_STEPS: f64 = 1e12;

impl RunSettings {
    /// Steps to run with time step `dt` (s): `ceil(duration / dt)` when `duration` is given
    /// (a quotient within 1e-6 of a whole number counts as that number, so 2 s at 1 ms
    /// is 2000 steps even with `dt` rounded to f32), else `steps`.
    pub fn steps_at(&self, dt: f64) -> Result<u64, SceneError> {
        let Some(duration) = self.duration else {
            return Ok(self.steps);
        };
        let n = duration / dt;
        if !(n.is_finite() && n <= MAX_RUN_STEPS) {
            return Err(SceneError::invalid(
                "run.duration",
                format!(
                    "{duration} s at dt = {dt:e} s is {n:e} steps, more than {MAX_RUN_STEPS:e}"
                ),
            ));
        }
        let whole = n.round();
        Ok(if (n - whole).abs() <= 1e-6 * whole.max(1.0) {
            whole as u64
        } else {
            n.ceil() as u64
        })
    }
}
fn default_output_every() -> u64 {
    50
}
fn yes() -> bool {
    true
}

impl Default for RunSettings {
    fn default() -> Self {
        RunSettings {
            steps: default_steps(),
            duration: None,
            output_every: default_output_every(),
            surface_frames: true,
            max_memory_gib: default_max_memory_gib(),
        }
    }
}

impl RunSettings {
    /// Checks the `[run]` table's values (`dt` the fixed time step, if any, for the
    /// step count of `duration`).
    pub fn validate(&self, dt: Option<f64>) -> Result<(), SceneError> {
        positive_finite("run.max_memory_gib", self.max_memory_gib)?;
        if let Some(d) = self.duration {
            positive_finite("run.duration", d)?;
            if let Some(dt) = dt {
                self.steps_at(dt)?;
            }
        }
        if self.output_every == 0 {
            return Err(SceneError::invalid(
                "run.output_every",
                "must be at least 1",
            ));
        }
        Ok(())
    }
}
