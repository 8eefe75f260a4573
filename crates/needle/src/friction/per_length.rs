//! `model = "per_length"` (default): Coulomb friction per unit length, through a sheath
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

use serde::Deserialize;

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
            crate::config::check_magnitude(&format!("needle.friction.{name}"), v)?;
        }
        if let Some(k) = self.shear_stiffness {
            crate::config::check_magnitude("needle.friction.shear_stiffness", k)?;
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
