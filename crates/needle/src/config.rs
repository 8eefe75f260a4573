//! The scene's `[needle]` table.
//!
//! ```toml
//! [needle]
//! base = [-0.17, 0.05, 0.05]     # start pose: base point, direction base -> tip
//! direction = [1.0, 0.0, 0.0]
//! length = 0.15                  # m
//! spacing = 0.01                 # node-adding threshold h, m (default: the mesh spacing)
//! tip_refresh = 0.1              # Tip node neighbours refreshed every tip_refresh * h
//! radius = 0.000635             # m, default an 18 G needle (1.27 mm outer diameter)
//! cutting = 0.5                  # N, at the tip while it advances into uncut tissue
//! thresholds = { puncture = 80.0, release = 95.0 }   # cone angle, degrees
//! puncture_force = 2.0           # N: puncture by force instead of the cone angle
//! contact_radius = 0.003         # m, the surface that carries the tip's load before
//!                                # puncture (default: the needle radius)
//! point_length = 0.0039         # m: length of the needle's point; a membrane that gave
//!                                # lets go of its load, and the cutting force builds up,
//!                                # while the point passes (default: an 18-degree bevel,
//!                                # diameter / tan 18 deg)
//! tear_time = 0.015              # s: a membrane that gave lets go of its load within
//!                                # this time at most (default 15 ms)
//! speed_ramp = 0.05              # s: the needle's speed changes over this time at each
//!                                # keyframe boundary (default 50 ms; 0: within a step)
//! friction = { coefficient = 0.3, grip = 40.0 }      # per unit length (default model)
//! # friction = { model = "paper", static_threshold = 0.02, dynamic = 0.3, viscous = 0.5 }
//!
//! [[needle.keyframe]]
//! action = "move"
//! direction = [1.0, 0.0, 0.0]
//! speed = 0.05
//! duration = 3.0
//! ```
//!
//! Without keyframes the needle stays where it is put ([`crate::Simulation::set_pose`]).

use crate::friction::FrictionModel;
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
    /// Needle radius in m (default 0.635 mm, an 18 G needle). It sets the grip of the
    /// tissue on the shaft when `friction.grip` is not given; it must be below half the
    /// node spacing (the tissue the shaft pushes aside is below the node resolution).
    #[serde(default = "default_radius")]
    pub radius: f64,
    /// Cutting force in N at the tip while it advances into tissue it has not cut yet
    /// (default 0: no cutting force). Per-length friction model only.
    #[serde(default)]
    pub cutting: f64,
    /// Cone angle thresholds (the release threshold applies with either puncture rule).
    #[serde(default)]
    pub thresholds: Thresholds,
    /// Puncture by force: the surface is punctured when the axial force of the dented
    /// surface on the tip exceeds this many N (instead of the cone angle rule).
    #[serde(default)]
    pub puncture_force: Option<f64>,
    /// Radius of the surface that carries the tip's load before puncture, m (per-length
    /// model, [`crate::sheath`]): the needle's own radius (the default) on a bare surface,
    /// more where a capsule or skin under tension spreads the load. With the tissue's
    /// modulus it sets the dent: a rigid flat punch of this radius on a half-space.
    #[serde(default)]
    pub contact_radius: Option<f64>,
    /// Length of the needle's point (its bevel), m (per-length model, [`crate::sheath`]):
    /// a membrane that gave lets go of its load while the point passes through it (the
    /// hole opens to the shaft's diameter), and the cutting force builds up over it when
    /// the tip starts cutting (and lets go over it when the tip is pulled back). Default:
    /// an 18-degree bevel (a Quincke-type spinal or biopsy point),
    /// `2 radius / tan(18 deg)`, 3.9 mm for an 18 G needle.
    #[serde(default)]
    pub point_length: Option<f64>,
    /// Time within which a membrane that gave lets go of the load it carried beyond the
    /// cutting force, s (per-length model; default 15 ms, [`crate::sheath::Tear`]).
    #[serde(default)]
    pub tear_time: Option<f64>,
    /// Time over which the scripted speed changes at each keyframe boundary, s (default
    /// [`crate::script::DEFAULT_RAMP`]; 0 changes it within one step).
    #[serde(default)]
    pub speed_ramp: Option<f64>,
    /// Stick-slip friction (read from the `friction` table by [`FrictionModel::from_value`]).
    #[serde(skip)]
    pub friction: FrictionModel,
    /// Pose script played from time 0.
    #[serde(default)]
    pub keyframe: Vec<Keyframe>,
}

/// What a region's membrane (its boundary, met by the crack front from another region)
/// does to the needle tip.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Membrane {
    /// No membrane: the tip cuts on into the region with the region's cutting force.
    None,
    /// The tip dents the membrane (the crack front sticks to it) until its axial force on
    /// the tissue exceeds this many N, then punctures it.
    Force(f64),
    /// Never punctured (bone, a hard capsule): the tip pushes the region ahead of it and
    /// the force is the region's contact force.
    Impenetrable,
}

/// The needle's parameters in one tissue region, from its `[[region]]` table's `needle`
/// table; what is not given is the `[needle]` table's.
///
/// ```toml
/// [[region]]
/// name = "ligament"
/// # ...
/// needle = { puncture_force = 4.0, cutting = 0.6, friction = { coefficient = 0.3, grip = 120.0 } }
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionNeedle {
    /// Friction per unit length in the region (the grip is resolved against the region's
    /// material when not given).
    pub friction: FrictionModel,
    /// Cutting force at the tip while it cuts the region, N.
    pub cutting: f64,
    /// The region's membrane.
    pub membrane: Membrane,
    /// Radius of the surface that carries the tip's load while it dents the region's
    /// membrane, m (`contact_radius`, by default the `[needle]` table's).
    pub contact_radius: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RegionNeedleKeys {
    #[serde(default)]
    puncture_force: Option<f64>,
    #[serde(default)]
    impenetrable: bool,
    #[serde(default)]
    cutting: Option<f64>,
    #[serde(default)]
    contact_radius: Option<f64>,
    #[serde(default)]
    friction: Option<toml::Value>,
}

fn default_tip_refresh() -> f64 {
    0.1
}

/// Length of an 18-degree bevel on a needle of radius `radius`: `2 radius / tan 18 deg`
/// (m).
pub fn default_point_length(radius: f64) -> f64 {
    2.0 * radius / 18f64.to_radians().tan()
}

/// An 18 G needle: 1.27 mm outer diameter.
pub const RADIUS_18G: f64 = 0.635e-3;

fn default_radius() -> f64 {
    RADIUS_18G
}

impl NeedleConfig {
    /// Reads and validates the `[needle]` table.
    pub fn from_table(table: &toml::Table) -> Result<NeedleConfig, SceneError> {
        let mut table = table.clone();
        let friction = table.remove("friction");
        // Each keyframe on its own, so that an error names its index (serde's said "in
        // `keyframe`" for a wrong type in any of them).
        let keyframes = match table.remove("keyframe") {
            None => Vec::new(),
            Some(toml::Value::Array(items)) => items
                .into_iter()
                .enumerate()
                .map(|(i, item)| {
                    item.try_into().map_err(|e: toml::de::Error| {
                        SceneError::invalid(
                            format!("needle.keyframe[{i}]"),
                            e.to_string().trim_end().replace('\n', " "),
                        )
                    })
                })
                .collect::<Result<Vec<Keyframe>, SceneError>>()?,
            Some(other) => {
                return Err(SceneError::invalid(
                    "needle.keyframe",
                    format!(
                        "must be an array of tables ([[needle.keyframe]]), got a {}",
                        other.type_str()
                    ),
                ))
            }
        };
        let mut c: NeedleConfig =
            toml::Value::Table(table)
                .try_into()
                .map_err(|e: toml::de::Error| SceneError::Parse {
                    origin: "[needle]".into(),
                    message: e.to_string().trim_end().replace('\n', " "),
                })?;
        c.keyframe = keyframes;
        if let Some(f) = friction {
            c.friction = FrictionModel::from_value(&f)
                .map_err(|(key, why)| SceneError::invalid(key, why))?;
        }
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
        if !(self.radius.is_finite() && self.radius >= MIN_RADIUS) {
            return Err(SceneError::invalid(
                "needle.radius",
                format!(
                    "must be a finite number of at least 1e-6 m (1 um), got {:e}",
                    self.radius
                ),
            ));
        }
        for (key, v) in [
            ("needle.radius", Some(self.radius)),
            ("needle.length", Some(self.length)),
            ("needle.cutting", Some(self.cutting)),
            ("needle.spacing", self.spacing),
            ("needle.puncture_force", self.puncture_force),
            ("needle.contact_radius", self.contact_radius),
            ("needle.point_length", self.point_length),
            ("needle.tear_time", self.tear_time),
            ("needle.speed_ramp", self.speed_ramp),
        ] {
            if let Some(v) = v {
                check_magnitude(key, v).map_err(|(k, why)| SceneError::invalid(k, why))?;
            }
        }
        if !(self.cutting.is_finite() && self.cutting >= 0.0) {
            return Err(SceneError::invalid(
                "needle.cutting",
                format!("must be a finite number >= 0 (N), got {}", self.cutting),
            ));
        }
        if let Some(f) = self.puncture_force {
            if !(f.is_finite() && f > 0.0) {
                return Err(SceneError::invalid(
                    "needle.puncture_force",
                    format!("must be a finite number > 0 (N), got {f}"),
                ));
            }
        }
        for (key, v) in [
            ("needle.contact_radius", self.contact_radius),
            ("needle.point_length", self.point_length),
            ("needle.tear_time", self.tear_time),
        ] {
            if let Some(v) = v {
                if !(v.is_finite() && v > 0.0) {
                    return Err(SceneError::invalid(
                        key,
                        format!("must be a finite number > 0, got {v}"),
                    ));
                }
            }
        }
        if let Some(r) = self.speed_ramp {
            if !(r.is_finite() && r >= 0.0) {
                return Err(SceneError::invalid(
                    "needle.speed_ramp",
                    format!("must be a finite number >= 0 (s), got {r}"),
                ));
            }
        }
        if self.cutting > 0.0 && matches!(self.friction, FrictionModel::Paper(_)) {
            return Err(SceneError::invalid(
                "needle.cutting",
                "needs the per-length friction model (the paper's model has no cutting force)",
            ));
        }
        self.thresholds
            .validate()
            .map_err(|e| SceneError::invalid("needle.thresholds", e))?;
        match &self.friction {
            FrictionModel::PerLength(p) => p.validate(),
            FrictionModel::Paper(p) => p.validate(),
        }
        .map_err(|(key, why)| SceneError::invalid(key, why))?;
        self.script()
            .map_err(|e| SceneError::invalid(format!("needle.keyframe[{}]", e.index), e.reason))?;
        Ok(())
    }

    /// Contact radius before puncture (m): `contact_radius`, or the needle's radius.
    pub fn contact_radius(&self) -> f64 {
        self.contact_radius.unwrap_or(self.radius)
    }

    /// Tear time (s): `tear_time`, or 15 ms.
    pub fn tear_time(&self) -> f64 {
        self.tear_time.unwrap_or(0.015)
    }

    /// Point length (m): `point_length`, or that of an 18-degree bevel.
    pub fn point_length(&self) -> f64 {
        self.point_length
            .unwrap_or_else(|| default_point_length(self.radius))
    }

    /// The needle's parameters in region `name` from its `needle` table (`None`: the
    /// `[needle]` table's, with no membrane). Errors name `region[name].needle.<key>`.
    pub fn region(
        &self,
        name: &str,
        table: Option<&toml::Table>,
    ) -> Result<RegionNeedle, SceneError> {
        let key = format!("region[{name}].needle");
        let mut out = RegionNeedle {
            friction: self.friction,
            cutting: self.cutting,
            membrane: Membrane::None,
            contact_radius: self.contact_radius(),
        };
        let Some(table) = table else {
            return Ok(out);
        };
        let k: RegionNeedleKeys =
            toml::Value::Table(table.clone())
                .try_into()
                .map_err(|e: toml::de::Error| {
                    SceneError::invalid(&key, e.to_string().trim_end().replace('\n', " "))
                })?;
        if let Some(f) = k.friction {
            if !matches!(self.friction, FrictionModel::PerLength(_)) {
                return Err(SceneError::invalid(
                    format!("{key}.friction"),
                    "friction per region needs the per-length model in [needle]",
                ));
            }
            out.friction = FrictionModel::from_value(&f)
                .map_err(|(k2, why)| SceneError::invalid(k2.replacen("needle", &key, 1), why))?;
            match &out.friction {
                FrictionModel::PerLength(p) => p.validate(),
                FrictionModel::Paper(p) => p.validate(),
            }
            .map_err(|(k2, why)| SceneError::invalid(k2.replacen("needle", &key, 1), why))?;
            if !matches!(out.friction, FrictionModel::PerLength(_)) {
                return Err(SceneError::invalid(
                    format!("{key}.friction.model"),
                    "a region's friction must be the per-length model",
                ));
            }
        }
        for (name, v) in [
            ("contact_radius", k.contact_radius),
            ("cutting", k.cutting),
            ("puncture_force", k.puncture_force),
        ] {
            if let Some(v) = v {
                check_magnitude(&format!("{key}.{name}"), v)
                    .map_err(|(k, why)| SceneError::invalid(k, why))?;
            }
        }
        if let Some(r) = k.contact_radius {
            if !(r.is_finite() && r > 0.0) {
                return Err(SceneError::invalid(
                    format!("{key}.contact_radius"),
                    format!("must be a finite number > 0 (m), got {r}"),
                ));
            }
            out.contact_radius = r;
        }
        if let Some(c) = k.cutting {
            if !(c.is_finite() && c >= 0.0) {
                return Err(SceneError::invalid(
                    format!("{key}.cutting"),
                    format!("must be a finite number >= 0 (N), got {c}"),
                ));
            }
            out.cutting = c;
        }
        out.membrane = match (k.puncture_force, k.impenetrable) {
            (Some(_), true) => {
                return Err(SceneError::invalid(
                    format!("{key}.impenetrable"),
                    "an impenetrable region has no puncture force: give one of the two",
                ))
            }
            (Some(f), false) if !(f.is_finite() && f > 0.0) => {
                return Err(SceneError::invalid(
                    format!("{key}.puncture_force"),
                    format!("must be a finite number > 0 (N), got {f}"),
                ))
            }
            (Some(f), false) => Membrane::Force(f),
            (None, true) => Membrane::Impenetrable,
            (None, false) => Membrane::None,
        };
        let layered = out.membrane != Membrane::None || out.cutting > 0.0;
        if layered && !matches!(out.friction, FrictionModel::PerLength(_)) {
            return Err(SceneError::invalid(
                key,
                "membranes and cutting need the per-length friction model (the paper's model \
                 has no crack front)",
            ));
        }
        Ok(out)
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
        let ramp = self.speed_ramp.unwrap_or(crate::script::DEFAULT_RAMP);
        PoseScript::new(start, self.keyframe.clone()).map(|s| Some(s.with_ramp(ramp)))
    }

    /// Needle node slots for node spacing `h`: one per spacing along the whole needle,
    /// plus the Surface node, the Tip node and one spare for the step in which a node is
    /// added before the Tip node is re-added.
    pub fn node_slots(&self, h: f64) -> usize {
        // (+1: the exit node of a needle pushed through the far surface.)
        ((self.length / h).ceil() as usize).saturating_add(4)
    }

    /// Checks the radius against the node spacing `h`: the shaft must be thinner than
    /// half a spacing, since the tissue it pushes aside is modelled below the node
    /// resolution (the grip of the friction model).
    pub fn check_radius(&self, h: f64) -> Result<(), SceneError> {
        if self.radius >= 0.5 * h {
            return Err(SceneError::invalid(
                "needle.radius",
                format!(
                    "{} m is not below half the node spacing h = {h} m: the friction model \
                     treats the tissue the shaft pushes aside as below the node resolution; \
                     use a coarser `needle.spacing` or a thinner needle",
                    self.radius
                ),
            ));
        }
        Ok(())
    }
}

/// The largest magnitude a needle parameter may have (a force in N, a length in m, a time
/// in s, a coefficient): beyond it a value is a units mistake, and the needle's forces go
/// into f32 arrays (1e308 N of cutting force ran into a non-finite tissue). The same bound
/// as the needle's base ([`crate::NeedleError::FarBase`]).
pub const MAX_MAGNITUDE: f64 = 1e30;

/// The thinnest needle, m: 1 um (microneedles are tens of micrometres across). Below it the
/// cutting element's stiffness `F_c / a` and the sheath's logarithm lose the cutting force
/// (a radius of 1e-18 m inserted with no cutting force at all).
pub const MIN_RADIUS: f64 = 1e-6;

/// Refuses a parameter whose magnitude exceeds [`MAX_MAGNITUDE`] (0 passes).
pub(crate) fn check_magnitude(key: &str, v: f64) -> Result<(), (String, String)> {
    if v.abs() > MAX_MAGNITUDE {
        return Err((
            key.to_string(),
            format!("{v:e} is beyond the 1e30 a needle parameter may reach (a units mistake?)"),
        ));
    }
    Ok(())
}
