//! `model = "paper"`: the paper's equation 2 as written.
//!
//! Stick: the node moves rigidly with the needle, and slips when `|a|` exceeds the static
//! threshold. Slip: `f_df = (k_vf w + k_df sign(w) |f_N|) t` with `w = (v_needle - v_node)
//! . t`; it sticks again when `|w|` falls below the stick speed while `|a|` is within the
//! threshold. The paper's viscous term, taken literally, is proportional to the node's own
//! axial velocity and would push a node further along the way it already moves; we apply it
//! to the relative velocity like the Coulomb term, so both dissipate (tested). This is the
//! model whose explicit `sign(w)` flips from step to step near zero relative speed; it is
//! kept to reproduce the paper.

use super::axial::{relative_axial, split, split_v, FrictionState};
use glam::DVec3;
use serde::Deserialize;

/// Parameters of the paper's equation 2.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PaperFriction {
    /// Axial elastic force in N above which a sticking node slips.
    pub static_threshold: f64,
    /// Coulomb coefficient k_df (dimensionless), times the normal force.
    pub dynamic: f64,
    /// Viscous coefficient k_vf in N s/m, times the relative axial speed.
    #[serde(default)]
    pub viscous: f64,
    /// Relative axial speed in m/s below which a slipping node sticks again.
    #[serde(default = "default_stick_speed")]
    pub stick_speed: f64,
}

fn default_stick_speed() -> f64 {
    1e-4
}

impl Default for PaperFriction {
    /// 0.01 N static threshold, Coulomb coefficient 0.2, 0.1 N s/m viscous, stick below
    /// 0.1 mm/s: values of the order of the paper scenes' node forces, not measured
    /// tissue constants.
    fn default() -> Self {
        PaperFriction {
            static_threshold: 0.01,
            dynamic: 0.2,
            viscous: 0.1,
            stick_speed: default_stick_speed(),
        }
    }
}

impl PaperFriction {
    /// Checks that every value is finite and non-negative (the stick speed positive).
    pub fn validate(&self) -> Result<(), (String, String)> {
        let values = [
            ("static_threshold", self.static_threshold),
            ("dynamic", self.dynamic),
            ("viscous", self.viscous),
        ];
        for (name, v) in values {
            if !(v.is_finite() && v >= 0.0) {
                return Err((
                    format!("needle.friction.{name}"),
                    format!("must be a finite number >= 0, got {v}"),
                ));
            }
            crate::config::check_magnitude(&format!("needle.friction.{name}"), v)?;
        }
        crate::config::check_magnitude("needle.friction.stick_speed", self.stick_speed)?;
        if !(self.stick_speed.is_finite() && self.stick_speed > 0.0) {
            return Err((
                "needle.friction.stick_speed".into(),
                format!("must be a finite number > 0, got {}", self.stick_speed),
            ));
        }
        Ok(())
    }
}

/// The paper model's state after this step: a sticking node slips when its axial elastic
/// force exceeds the threshold; a slipping node sticks when the relative axial speed is
/// below the stick speed and the axial force is within the threshold.
pub fn paper_next_state(
    state: FrictionState,
    elastic: [f64; 3],
    v_node: [f64; 3],
    v_needle: [f64; 3],
    t: [f64; 3],
    p: &PaperFriction,
) -> FrictionState {
    match state {
        FrictionState::Stick if split(elastic, t).0.abs() > p.static_threshold => {
            FrictionState::Slip
        }
        FrictionState::Slip
            if relative_axial(v_node, v_needle, DVec3::from_array(t)).abs() < p.stick_speed
                && split(elastic, t).0.abs() <= p.static_threshold =>
        {
            FrictionState::Stick
        }
        s => s,
    }
}

/// The paper model's dynamic friction force on a slipping node, along the shaft.
pub fn paper_dynamic_friction(
    elastic: [f64; 3],
    v_node: [f64; 3],
    v_needle: [f64; 3],
    t: [f64; 3],
    p: &PaperFriction,
) -> [f64; 3] {
    let t = DVec3::from_array(t);
    let w = relative_axial(v_node, v_needle, t);
    let normal = split_v(DVec3::from_array(elastic), t).1;
    let coulomb = if w == 0.0 { 0.0 } else { w.signum() } * p.dynamic * normal.length();
    let m = p.viscous * w + coulomb;
    (t * m).to_array()
}
