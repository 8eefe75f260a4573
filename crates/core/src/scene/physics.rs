//! `[physics]` (time step, gravity, damping, divergence guard) and `[initial]`.

use crate::error::SceneError;
use crate::validate::{finite, non_negative_finite, positive_finite};
use serde::Deserialize;

/// Time stepping parameters.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Physics {
    /// Time step: seconds, or `"auto"` for half the critical time step estimated from the
    /// model at the initial state ([`crate::stability`]).
    #[serde(default = "default_dt")]
    pub dt: TimeStep,
    /// Gravity in m/s^2.
    #[serde(default)]
    pub gravity: [f64; 3],
    /// Mass-proportional velocity damping c in 1/s: `v <- (v + dt a) / (1 + dt c)`.
    #[serde(default)]
    pub damping: f64,
    /// Divergence guard: a free node faster than this (m/s), or any non-finite position or
    /// velocity, stops the run with an error naming the step and the node. An unstable
    /// explicit step grows geometrically, so the bound is crossed within a few steps of
    /// the instability becoming visible; tissue speeds are far below the default 100 m/s.
    #[serde(default = "default_max_speed")]
    pub max_speed: f64,
    /// Steps between two divergence checks of a needle simulation (each reads every
    /// node back from the GPU); runs also check at every output frame, and the needle
    /// nodes sliding on the shaft (read back every step anyway) are checked every step.
    #[serde(default = "default_check_every")]
    pub check_every: u64,
}

fn default_dt() -> TimeStep {
    TimeStep::Seconds(1e-3)
}

/// A time step in seconds or chosen by the engine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TimeStep {
    /// This many seconds.
    Seconds(f64),
    /// [`AUTO_DT_SAFETY`] times the critical time step estimated from the model.
    Auto,
}

/// The fraction of the estimated critical time step that `dt = "auto"` uses. The estimate
/// is made at the initial state; a half leaves room for the stiffening of large
/// deformations (the divergence guard catches what it does not).
pub const AUTO_DT_SAFETY: f64 = 0.5;

impl<'de> Deserialize<'de> for TimeStep {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        match toml::Value::deserialize(d)? {
            toml::Value::Float(f) => Ok(TimeStep::Seconds(f)),
            toml::Value::Integer(i) => Ok(TimeStep::Seconds(i as f64)),
            toml::Value::String(s) if s == "auto" => Ok(TimeStep::Auto),
            other => Err(D::Error::custom(format!(
                "`physics.dt` must be a number of seconds or \"auto\", got {other}"
            ))),
        }
    }
}
fn default_max_speed() -> f64 {
    100.0
}
fn default_check_every() -> u64 {
    100
}

impl Default for Physics {
    fn default() -> Self {
        Physics {
            dt: default_dt(),
            gravity: [0.0; 3],
            damping: 0.0,
            max_speed: default_max_speed(),
            check_every: default_check_every(),
        }
    }
}

impl Physics {
    /// Checks the `[physics]` table's values.
    pub fn validate(&self) -> Result<(), SceneError> {
        let p = self;
        if let TimeStep::Seconds(dt) = p.dt {
            positive_finite("physics.dt", dt)?;
        }
        for g in p.gravity {
            finite("physics.gravity", g)?;
        }
        non_negative_finite("physics.damping", p.damping)?;
        positive_finite("physics.max_speed", p.max_speed)?;
        if p.check_every == 0 {
            return Err(SceneError::invalid(
                "physics.check_every",
                "must be at least 1",
            ));
        }
        Ok(())
    }
}

/// Initial deformation of the rest shape.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Initial {
    /// Scale factors along x, y, z about the centroid of the free nodes' rest positions
    /// (`[1.3, 1, 1]` stretches by 30% along x). Fixed nodes are not moved.
    #[serde(default = "unit_stretch")]
    pub stretch: [f64; 3],
}

fn unit_stretch() -> [f64; 3] {
    [1.0; 3]
}

impl Default for Initial {
    fn default() -> Self {
        Initial {
            stretch: unit_stretch(),
        }
    }
}

impl Initial {
    /// Checks the `[initial]` table's values.
    pub fn validate(&self) -> Result<(), SceneError> {
        for s in self.stretch {
            positive_finite("initial.stretch", s)?;
        }
        Ok(())
    }
}
