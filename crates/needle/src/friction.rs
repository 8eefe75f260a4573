//! Stick-slip friction between the needle shaft and a needle node (paper section 5.3, after
//! Karnopp 1985).
//!
//! With `t` the unit shaft direction (base to tip) and `f` the elastic tissue force on the
//! node, the axial part is `f_p = (f . t) t` (eq. 3) and the normal part `f_N = f - f_p`
//! (eq. 4).
//!
//! - Stick: the node moves rigidly with the needle. It starts to slip when `|f_p|` exceeds
//!   the static threshold.
//! - Slip: the node is projected onto the shaft and receives the dynamic friction force
//!   `f_df = (k_vf w + k_df sign(w) |f_N|) t` with `w = (v_needle - v_node) . t`, the
//!   needle's axial speed relative to the node. It sticks again when `|w|` falls below the
//!   stick speed while `|f_p|` is within the static threshold.
//!
//! Sign convention: the paper's equation 2 reads `k_vf v_i^p + k_df sign(v_needle^p -
//! v_i^p) |f_N| t`. Its Coulomb term is the one above: it drags the node the way the needle
//! moves relative to it. Its viscous term, taken literally, is proportional to the node's
//! own axial velocity and would push a node further along the way it already moves (energy
//! in, not out); we apply it to the relative velocity `w` like the Coulomb term, so that
//! both terms dissipate: `f_df . (v_node - v_needle) <= 0` always (tested).

use serde::Deserialize;

/// Friction state of one needle node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FrictionState {
    /// Moves with the needle (static friction).
    #[default]
    Stick,
    /// Slides along the shaft (dynamic friction).
    Slip,
}

/// Friction parameters.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionParams {
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

impl Default for FrictionParams {
    /// 0.01 N static threshold, Coulomb coefficient 0.2, 0.1 N s/m viscous, stick below
    /// 0.1 mm/s: values of the order of the shipped scenes' node forces, not measured
    /// tissue constants.
    fn default() -> Self {
        FrictionParams {
            static_threshold: 0.01,
            dynamic: 0.2,
            viscous: 0.1,
            stick_speed: default_stick_speed(),
        }
    }
}

impl FrictionParams {
    /// Checks that every value is finite and non-negative (the stick speed positive).
    pub fn validate(&self) -> Result<(), String> {
        let values = [
            ("static_threshold", self.static_threshold),
            ("dynamic", self.dynamic),
            ("viscous", self.viscous),
        ];
        for (name, v) in values {
            if !(v.is_finite() && v >= 0.0) {
                return Err(format!(
                    "friction.{name} must be a finite number >= 0, got {v}"
                ));
            }
        }
        if !(self.stick_speed.is_finite() && self.stick_speed > 0.0) {
            return Err(format!(
                "friction.stick_speed must be a finite number > 0, got {}",
                self.stick_speed
            ));
        }
        Ok(())
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Axial component `f . t` and normal part `f - (f . t) t` of a force (eqs. 3 and 4).
pub fn split(f: [f64; 3], t: [f64; 3]) -> (f64, [f64; 3]) {
    let p = dot(f, t);
    (p, std::array::from_fn(|a| f[a] - p * t[a]))
}

/// The state after this step: a sticking node slips when its axial elastic force exceeds
/// the threshold; a slipping node sticks when the relative axial speed is below the stick
/// speed and the axial force is within the threshold (Karnopp's band: a node whose force
/// would make it slip again at once keeps slipping, so the state does not chatter from
/// step to step).
pub fn next_state(
    state: FrictionState,
    elastic: [f64; 3],
    v_node: [f64; 3],
    v_needle: [f64; 3],
    t: [f64; 3],
    p: &FrictionParams,
) -> FrictionState {
    match state {
        FrictionState::Stick if split(elastic, t).0.abs() > p.static_threshold => {
            FrictionState::Slip
        }
        FrictionState::Slip
            if dot(sub(v_needle, v_node), t).abs() < p.stick_speed
                && split(elastic, t).0.abs() <= p.static_threshold =>
        {
            FrictionState::Stick
        }
        s => s,
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Dynamic friction force on a slipping node, along the shaft.
pub fn dynamic_friction(
    elastic: [f64; 3],
    v_node: [f64; 3],
    v_needle: [f64; 3],
    t: [f64; 3],
    p: &FrictionParams,
) -> [f64; 3] {
    let w = dot(sub(v_needle, v_node), t);
    let normal = split(elastic, t).1;
    let coulomb = if w == 0.0 { 0.0 } else { w.signum() } * p.dynamic * dot(normal, normal).sqrt();
    let m = p.viscous * w + coulomb;
    t.map(|x| m * x)
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: FrictionParams = FrictionParams {
        static_threshold: 0.5,
        dynamic: 0.3,
        viscous: 2.0,
        stick_speed: 1e-3,
    };

    #[test]
    fn sticking_node_slips_above_the_threshold_and_sticks_when_slow() {
        let t = [1.0, 0.0, 0.0];
        let v = [0.01, 0.0, 0.0];
        // Large normal force, small axial force: still sticks.
        assert_eq!(
            next_state(FrictionState::Stick, [0.4, 5.0, 0.0], v, v, t, &P),
            FrictionState::Stick
        );
        assert_eq!(
            next_state(FrictionState::Stick, [-0.6, 0.0, 0.0], v, v, t, &P),
            FrictionState::Slip
        );
        assert_eq!(
            next_state(FrictionState::Slip, [0.0; 3], [0.0; 3], v, t, &P),
            FrictionState::Slip
        );
        assert_eq!(
            next_state(FrictionState::Slip, [0.0; 3], [0.0095, 0.0, 0.0], v, t, &P),
            FrictionState::Stick
        );
        // Slow, but pulled harder than the static threshold: keeps slipping (no chatter).
        assert_eq!(
            next_state(
                FrictionState::Slip,
                [0.6, 0.0, 0.0],
                [0.0095, 0.0, 0.0],
                v,
                t,
                &P
            ),
            FrictionState::Slip
        );
        assert_eq!(
            next_state(
                FrictionState::Slip,
                [0.3, 0.0, 0.0],
                [0.0095, 0.0, 0.0],
                v,
                t,
                &P
            ),
            FrictionState::Stick
        );
    }

    #[test]
    fn dynamic_friction_drags_along_the_needle_and_dissipates() {
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
            let fd = dynamic_friction(f, vn, vd, t, &P);
            // Along the shaft, dissipative, with the magnitude of the law.
            let (along, normal) = split(fd, t);
            assert!(dot(normal, normal).sqrt() < 1e-12);
            assert!(dot(fd, sub(vn, vd)) <= 1e-15);
            let w = dot(sub(vd, vn), t);
            let fnorm = dot(split(f, t).1, split(f, t).1).sqrt();
            assert!((along.abs() - (P.viscous * w.abs() + P.dynamic * fnorm)).abs() < 1e-12);
        }
        // A needle pushed in (+t) relative to the node drags the node inwards.
        let fd = dynamic_friction([0.0, 0.0, 1.0], [0.0; 3], [0.06, 0.08, 0.0], t, &P);
        assert!(dot(fd, t) > 0.0);
    }
}
