//! Friction between the needle shaft and the needle nodes (paper section 5.3, after
//! Karnopp 1985), in two models.
//!
//! With `t` the unit shaft direction (base to tip) and `f` the elastic tissue force on a
//! node, the axial part is `a = f . t` (eq. 3) and the normal part `f_N = f - a t`
//! (eq. 4). The shaft holds every node on its line (bilateral); friction acts along it.
//!
//! # `model = "per_length"` (default): Coulomb friction per unit length, through a sheath
//!
//! Okamura, Simone and O'Leary 2004 (IEEE TBME 51(10)) split the insertion force into the
//! capsule's stiffness before puncture, friction along the inserted shaft and a cutting
//! force at the tip. Here each needle node carries the shaft length `l` it represents (half
//! the way to its neighbours along the shaft, the first node from the entry, the last to
//! the tip) and the normal load on that length:
//!
//! `N = q l + |f_N|`
//!
//! `q` (N/m) is the grip of the tissue that the shaft pushes aside, `|f_N|` the net normal
//! force of the tissue on the node (the shaft pressed sideways, as in a rotation). The
//! kinetic limit is `K = mu_k N`, the static limit `S = mu_s N`, and a slipping node also
//! feels `c l w` (viscous friction per unit length, `w` the relative axial speed). The
//! total friction then grows with the inserted length and does not depend on how many
//! nodes share it.
//!
//! The grip is sub-grid: an 18 G needle (radius 0.635 mm) is far thinner than any node
//! spacing, so the tissue it pushes aside is not resolved by nodes. By default `q` comes
//! from the tissue's Young's modulus: the bevel cuts a slit as wide as the needle, and a
//! slit of half-width `a` held open into the shaft's circle of radius `a` needs the contact
//! pressure `p = E / (2 (1 - nu^2))` (plane-strain opening of a pressurised crack,
//! Sneddon 1946: semi-minor axis `2 p a (1 - nu^2) / E`), so `q = 2 pi a p`. This is linear
//! elasticity at strains of order one, an estimate of the order of the grip; measured
//! friction is matched by giving `grip` (or the coefficient) explicitly.
//!
//! The node's axial motion against the needle goes through the sheath of tissue around
//! the shaft ([`crate::sheath`]): an elastic shear element with a Kelvin-Voigt dashpot,
//! in series with a Coulomb slider whose cap is `mu N` (`mu_s N` until the node first
//! slips when a static coefficient above the kinetic one is given, then `mu_k N`, plus the
//! viscous term). Its state is the force itself, so it cannot chatter; it reverses over
//! the pre-sliding length; the friction opposes the relative sliding velocity including a
//! spin of the needle about its axis. The cutting force `F_c` acts on the node at the
//! crack front while the tip advances into tissue it has not cut (never pulling it back).

//! # `model = "paper"`: equation 2 as written
//!
//! Stick: the node moves rigidly with the needle, and slips when `|a|` exceeds the static
//! threshold. Slip: `f_df = (k_vf w + k_df sign(w) |f_N|) t` with `w = (v_needle - v_node)
//! . t`; it sticks again when `|w|` falls below the stick speed while `|a|` is within the
//! threshold. The paper's viscous term, taken literally, is proportional to the node's own
//! axial velocity and would push a node further along the way it already moves; we apply it
//! to the relative velocity like the Coulomb term, so both dissipate (tested). This is the
//! model whose explicit `sign(w)` flips from step to step near zero relative speed; it is
//! kept to reproduce the paper.

use glam::DVec3;
use serde::Deserialize;

/// Friction state of one needle node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum FrictionState {
    /// Moves with the needle (static friction).
    #[default]
    Stick,
    /// Slides along the shaft (dynamic friction).
    Slip,
}

/// The friction model of the `[needle]` table's `friction` key.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FrictionModel {
    /// `model = "per_length"` (default): Coulomb friction per unit length of shaft, solved
    /// implicitly (no chatter).
    PerLength(PerLengthFriction),
    /// `model = "paper"`: the paper's equation 2, explicit.
    Paper(PaperFriction),
}

impl Default for FrictionModel {
    fn default() -> Self {
        FrictionModel::PerLength(PerLengthFriction::default())
    }
}

/// Parameters of the per-length model.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PerLengthFriction {
    /// Kinetic Coulomb coefficient `mu_k` (dimensionless), default 0.3.
    #[serde(default = "default_coefficient")]
    pub coefficient: f64,
    /// Static coefficient `mu_s >= mu_k`; default: equal to `coefficient`.
    #[serde(default)]
    pub static_coefficient: Option<f64>,
    /// Normal load per unit length of the tissue gripping the shaft, N/m. Default: from
    /// the tissue's Young's modulus and the needle radius, `pi a E / (1 - nu^2)`.
    #[serde(default)]
    pub grip: Option<f64>,
    /// Viscous friction per unit length and unit relative speed, N s/m^2 (default 0).
    #[serde(default)]
    pub viscous: f64,
    /// Shear stiffness per unit length of the tissue sheath around the shaft, N/m^2: how
    /// much relative motion it takes the friction to build up (default: from the
    /// tissue's modulus, `2 pi G / ln(h / 2a)`, [`crate::sheath`]).
    #[serde(default)]
    pub shear_stiffness: Option<f64>,
    /// Shear viscosity of the tissue in the sheath, Pa s (default
    /// [`DEFAULT_SHEATH_VISCOSITY`]): a Kelvin-Voigt dashpot beside the sheath's
    /// stiffness, `2 pi eta / ln(h / 2a)` per unit length, that damps the needle nodes'
    /// motion against the needle while the sheath holds; it carries nothing in steady
    /// sliding ([`crate::sheath`]).
    #[serde(default)]
    pub sheath_viscosity: Option<f64>,
}

/// Default shear viscosity of the sheath's tissue, Pa s (module docs of
/// [`crate::sheath`]).
pub const DEFAULT_SHEATH_VISCOSITY: f64 = 2.0;

fn default_coefficient() -> f64 {
    0.3
}

impl Default for PerLengthFriction {
    fn default() -> Self {
        PerLengthFriction {
            coefficient: default_coefficient(),
            static_coefficient: None,
            grip: None,
            viscous: 0.0,
            shear_stiffness: None,
            sheath_viscosity: None,
        }
    }
}

impl PerLengthFriction {
    /// The static coefficient (the kinetic one when not given).
    pub fn static_coefficient(&self) -> f64 {
        self.static_coefficient.unwrap_or(self.coefficient)
    }

    /// Checks that every value is finite and non-negative and `mu_s >= mu_k`.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let mut values = vec![("coefficient", self.coefficient), ("viscous", self.viscous)];
        if let Some(g) = self.grip {
            values.push(("grip", g));
        }
        if let Some(e) = self.sheath_viscosity {
            values.push(("sheath_viscosity", e));
        }
        if let Some(k) = self.shear_stiffness {
            if !(k.is_finite() && k > 0.0) {
                return Err((
                    "needle.friction.shear_stiffness".into(),
                    format!("must be a finite number > 0 (N/m^2), got {k}"),
                ));
            }
        }
        if let Some(s) = self.static_coefficient {
            values.push(("static_coefficient", s));
        }
        for (name, v) in values {
            if !(v.is_finite() && v >= 0.0) {
                return Err((
                    format!("needle.friction.{name}"),
                    format!("must be a finite number >= 0, got {v}"),
                ));
            }
        }
        if self.static_coefficient() < self.coefficient {
            return Err((
                "needle.friction.static_coefficient".into(),
                format!(
                    "must be >= coefficient ({}), got {}",
                    self.coefficient,
                    self.static_coefficient()
                ),
            ));
        }
        Ok(())
    }
}

/// Grip per unit length (N/m) of a tissue of Young's modulus `young` (Pa) and Poisson
/// ratio `nu` on a shaft of radius `radius` (m): `pi a E / (1 - nu^2)` (module docs).
pub fn grip_from_modulus(young: f64, nu: f64, radius: f64) -> f64 {
    std::f64::consts::PI * radius * young / (1.0 - nu * nu)
}

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
        }
        if !(self.stick_speed.is_finite() && self.stick_speed > 0.0) {
            return Err((
                "needle.friction.stick_speed".into(),
                format!("must be a finite number > 0, got {}", self.stick_speed),
            ));
        }
        Ok(())
    }
}

impl FrictionModel {
    /// Reads the `friction` table: `model = "per_length"` (default) or `"paper"`, and
    /// that model's keys.
    pub fn from_value(value: &toml::Value) -> Result<FrictionModel, (String, String)> {
        let key = |k: &str| format!("needle.friction.{k}");
        let Some(table) = value.as_table() else {
            return Err((
                "needle.friction".into(),
                format!("must be a table, got {value}"),
            ));
        };
        let mut table = table.clone();
        let model = match table.remove("model") {
            None => "per_length".to_string(),
            Some(toml::Value::String(s)) => s,
            Some(v) => return Err((key("model"), format!("must be a string, got {v}"))),
        };
        let parse_err = |e: toml::de::Error| {
            let msg = e.to_string().trim_end().replace('\n', " ");
            (format!("needle.friction (model = \"{model}\")"), msg)
        };
        let m = match model.as_str() {
            "per_length" => {
                let p: PerLengthFriction =
                    toml::Value::Table(table).try_into().map_err(parse_err)?;
                p.validate()?;
                FrictionModel::PerLength(p)
            }
            "paper" => {
                let p: PaperFriction = toml::Value::Table(table).try_into().map_err(parse_err)?;
                p.validate()?;
                FrictionModel::Paper(p)
            }
            other => {
                return Err((
                    key("model"),
                    format!("must be \"per_length\" or \"paper\", got \"{other}\""),
                ))
            }
        };
        Ok(m)
    }
}

/// Axial component `f . t` and normal part `f - (f . t) t` of a force (eqs. 3 and 4).
pub fn split(f: [f64; 3], t: [f64; 3]) -> (f64, [f64; 3]) {
    let (p, n) = split_v(DVec3::from_array(f), DVec3::from_array(t));
    (p, n.to_array())
}

fn split_v(f: DVec3, t: DVec3) -> (f64, DVec3) {
    let p = f.dot(t);
    (p, f - t * p)
}

/// The needle's axial velocity relative to the node, `(v_needle - v_node) . t`.
fn relative_axial(v_node: [f64; 3], v_needle: [f64; 3], t: DVec3) -> f64 {
    (DVec3::from_array(v_needle) - DVec3::from_array(v_node)).dot(t)
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

#[cfg(test)]
mod tests {
    use super::*;

    const P: PaperFriction = PaperFriction {
        static_threshold: 0.5,
        dynamic: 0.3,
        viscous: 2.0,
        stick_speed: 1e-3,
    };

    #[test]
    fn paper_node_slips_above_the_threshold_and_sticks_when_slow() {
        let t = [1.0, 0.0, 0.0];
        let v = [0.01, 0.0, 0.0];
        let st = |s, f, vn| paper_next_state(s, f, vn, v, t, &P);
        // Large normal force, small axial force: still sticks.
        assert_eq!(
            st(FrictionState::Stick, [0.4, 5.0, 0.0], v),
            FrictionState::Stick
        );
        assert_eq!(
            st(FrictionState::Stick, [-0.6, 0.0, 0.0], v),
            FrictionState::Slip
        );
        assert_eq!(
            st(FrictionState::Slip, [0.0; 3], [0.0; 3]),
            FrictionState::Slip
        );
        let slow = [0.0095, 0.0, 0.0];
        assert_eq!(
            st(FrictionState::Slip, [0.0; 3], slow),
            FrictionState::Stick
        );
        // Slow, but pulled harder than the static threshold: keeps slipping.
        assert_eq!(
            st(FrictionState::Slip, [0.6, 0.0, 0.0], slow),
            FrictionState::Slip
        );
        assert_eq!(
            st(FrictionState::Slip, [0.3, 0.0, 0.0], slow),
            FrictionState::Stick
        );
    }

    #[test]
    fn paper_dynamic_friction_drags_along_the_needle_and_dissipates() {
        let t = [0.6, 0.8, 0.0];
        let mut s = 5u64;
        let mut r = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for _ in 0..200 {
            let f = [r(), r(), r()];
            let (vn, vd) = ([r(), r(), r()], [r(), r(), r()]);
            let fd = paper_dynamic_friction(f, vn, vd, t, &P);
            let (along, normal) = split(fd, t);
            let v = DVec3::from_array;
            assert!(v(normal).length() < 1e-12);
            assert!(v(fd).dot(v(vn) - v(vd)) <= 1e-15);
            let w = (v(vd) - v(vn)).dot(v(t));
            let fnorm = v(split(f, t).1).length();
            assert!((along.abs() - (P.viscous * w.abs() + P.dynamic * fnorm)).abs() < 1e-12);
        }
        let fd = paper_dynamic_friction([0.0, 0.0, 1.0], [0.0; 3], [0.06, 0.08, 0.0], t, &P);
        assert!(DVec3::from_array(fd).dot(DVec3::from_array(t)) > 0.0);
    }

    #[test]
    fn per_length_config_and_errors_name_the_key() {
        let v: toml::Value = toml::from_str("coefficient = 0.4\ngrip = 50.0").unwrap();
        let m = FrictionModel::from_value(&v).unwrap();
        let FrictionModel::PerLength(p) = m else {
            panic!("{m:?}")
        };
        assert_eq!(
            (p.coefficient, p.grip, p.static_coefficient()),
            (0.4, Some(50.0), 0.4)
        );
        let v: toml::Value =
            toml::from_str("model = \"paper\"\nstatic_threshold = 0.01\ndynamic = 0.2").unwrap();
        assert!(matches!(
            FrictionModel::from_value(&v),
            Ok(FrictionModel::Paper(_))
        ));
        for (text, key) in [
            ("grip = -1.0", "needle.friction.grip"),
            ("coefficient = nan", "needle.friction.coefficient"),
            (
                "coefficient = 0.4\nstatic_coefficient = 0.2",
                "needle.friction.static_coefficient",
            ),
            ("model = \"coulomb\"", "needle.friction.model"),
            (
                "static_threshold = 0.01",
                "needle.friction (model = \"per_length\")",
            ),
        ] {
            let v: toml::Value = toml::from_str(text).unwrap();
            let (k, why) = FrictionModel::from_value(&v).unwrap_err();
            assert_eq!(k, key, "{text}: {why}");
        }
        // Liver-like tissue, 18 G: pi * 0.635 mm * 5 kPa / (1 - 0.45^2) = 12.5 N/m.
        assert!((grip_from_modulus(5e3, 0.45, 0.635e-3) - 12.507).abs() < 1e-3);
    }
}
