//! Friction between the needle shaft and the needle nodes (paper section 5.3, after
//! Karnopp 1985), in two models.
//!
//! With `t` the unit shaft direction (base to tip) and `f` the elastic tissue force on a
//! node, the axial part is `a = f . t` (eq. 3) and the normal part `f_N = f - a t`
//! (eq. 4). The shaft holds every node on its line (bilateral); friction acts along it.
//!
//! Two laws, each in its own module with its keys and checks: [`per_length`] (the
//! default) and [`paper`]; [`FrictionModel`] reads the `friction` table and picks one.

mod axial;
pub mod paper;
pub mod per_length;

pub use axial::{split, FrictionState};
pub use paper::{paper_dynamic_friction, paper_next_state, PaperFriction};
pub use per_length::{grip_from_modulus, PerLengthFriction, DEFAULT_SHEATH_VISCOSITY};

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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

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
