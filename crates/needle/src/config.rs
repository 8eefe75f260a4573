//! The scene's `[needle]` table.
//!
//! ```toml
//! [needle]
//! base = [-0.17, 0.05, 0.05]     # start pose: base point, direction base -> tip
//! direction = [1.0, 0.0, 0.0]
//! length = 0.15                  # m
//! spacing = 0.01                 # node-adding threshold h, m (default: the mesh spacing)
//! tip_refresh = 0.1              # Tip node neighbours refreshed every tip_refresh * h
//! thresholds = { puncture = 80.0, release = 95.0 }   # degrees
//! friction = { static_threshold = 0.02, dynamic = 0.3, viscous = 0.5 }
//!
//! [[needle.keyframe]]
//! action = "move"
//! direction = [1.0, 0.0, 0.0]
//! speed = 0.05
//! duration = 3.0
//! ```
//!
//! Without keyframes the needle stays where it is put ([`crate::Simulation::set_pose`]).

use crate::friction::FrictionParams;
use crate::needle::Needle;
use crate::puncture::Thresholds;
use crate::script::{Keyframe, PoseScript};
use needlesim_core::SceneError;
use serde::Deserialize;

/// The needle part of a scene.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NeedleConfig {
    /// Base point of the start pose, m.
    pub base: [f64; 3],
    /// Direction base -> tip of the start pose (normalised).
    pub direction: [f64; 3],
    /// Needle length, m.
    pub length: f64,
    /// Node-adding threshold h in m: a node is added along the shaft for every h of
    /// insertion. Default: the mesh's node spacing `(volume / nodes)^(1/3)`.
    #[serde(default)]
    pub spacing: Option<f64>,
    /// Fraction of h after which the Tip node's neighbours are refreshed (paper: 1/10).
    #[serde(default = "default_tip_refresh")]
    pub tip_refresh: f64,
    /// Cone angle thresholds.
    #[serde(default)]
    pub thresholds: Thresholds,
    /// Stick-slip friction.
    #[serde(default)]
    pub friction: FrictionParams,
    /// Pose script played from time 0.
    #[serde(default)]
    pub keyframe: Vec<Keyframe>,
}

fn default_tip_refresh() -> f64 {
    0.1
}

impl NeedleConfig {
    /// Reads and validates the `[needle]` table.
    pub fn from_table(table: &toml::Table) -> Result<NeedleConfig, SceneError> {
        let c: NeedleConfig =
            toml::Value::Table(table.clone())
                .try_into()
                .map_err(|e: toml::de::Error| SceneError::Parse {
                    origin: "[needle]".into(),
                    message: e.to_string().trim_end().replace('\n', " "),
                })?;
        c.validate()?;
        Ok(c)
    }

    /// Checks every value; errors name the key.
    pub fn validate(&self) -> Result<(), SceneError> {
        self.start().map_err(|e| {
            SceneError::invalid(
                "needle.base / needle.direction / needle.length",
                e.to_string(),
            )
        })?;
        if let Some(h) = self.spacing {
            if !(h.is_finite() && h > 0.0) {
                return Err(SceneError::invalid(
                    "needle.spacing",
                    format!("must be a finite number > 0, got {h}"),
                ));
            }
        }
        if !(self.tip_refresh.is_finite() && self.tip_refresh > 0.0 && self.tip_refresh <= 1.0) {
            return Err(SceneError::invalid(
                "needle.tip_refresh",
                format!("must be in (0, 1], got {}", self.tip_refresh),
            ));
        }
        self.thresholds
            .validate()
            .map_err(|e| SceneError::invalid("needle.thresholds", e))?;
        self.friction
            .validate()
            .map_err(|e| SceneError::invalid("needle.friction", e))?;
        self.script()
            .map_err(|e| SceneError::invalid(format!("needle.keyframe[{}]", e.index), e.reason))?;
        Ok(())
    }

    /// The start pose.
    pub fn start(&self) -> Result<Needle, crate::NeedleError> {
        Needle::new(self.base, self.direction, self.length)
    }

    /// The pose script, or `None` without keyframes.
    pub fn script(&self) -> Result<Option<PoseScript>, crate::script::ScriptError> {
        if self.keyframe.is_empty() {
            return Ok(None);
        }
        let start = self.start().map_err(|e| crate::script::ScriptError {
            index: 0,
            reason: e.to_string(),
        })?;
        PoseScript::new(start, self.keyframe.clone()).map(Some)
    }

    /// Needle node slots for node spacing `h`: one per spacing along the whole needle,
    /// plus the Surface node, the Tip node and one spare for the step in which a node is
    /// added before the Tip node is re-added.
    pub fn node_slots(&self, h: f64) -> usize {
        (self.length / h).ceil() as usize + 3
    }
}
