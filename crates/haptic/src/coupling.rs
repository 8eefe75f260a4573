//! Virtual coupling (Colgate, Stanley and Brown 1995; Adams and Hannaford 1999): the
//! simulated needle is a proxy of mass `m`, tied to the device by a spring-damper and
//! pushed by the tissue,
//!
//! `m dv/dt = K (x_d - x) + B (v_d - v) - C v + F_tissue`,
//!
//! where `x_d, v_d` are the device's position and velocity, `C` damps the proxy against
//! the ground and `F_tissue` is the force of the tissue on the needle. The device is sent
//! the coupling's reaction `F_device = K (x - x_d) + B (v - v_d)`: at rest it equals the
//! tissue force. The spring, both dampers and the proxy mass are integrated implicitly
//! (backward Euler in `v`, then `x += T v`), so the proxy itself is stable for any
//! positive parameters; the tissue force enters explicitly, from the last step.
//!
//! Passivity of the rendered spring-damper sampled at period `T` (Colgate and Schenkel
//! 1997) asks the device for physical damping `b > K T / 2 + B`
//! ([`VirtualCoupling::min_device_damping`]).

use glam::DVec3;

/// Parameters of the virtual coupling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VirtualCoupling {
    /// Spring stiffness `K` between device and needle, N/m.
    pub stiffness: f64,
    /// Damping `B` on the device-needle relative velocity, N s/m (rendered).
    pub damping: f64,
    /// Mass `m` of the needle proxy, kg.
    pub proxy_mass: f64,
    /// Damping `C` of the proxy against the ground, N s/m (felt only through the spring:
    /// a drag of `C v` at steady speed `v`).
    pub proxy_damping: f64,
}

impl Default for VirtualCoupling {
    /// `K` = 300 N/m (below the 0.9-1.3 N/mm a Touch/Omni-class device renders and far
    /// below the 14.5 N/mm of a Force Dimension omega.3), `B` = 0, a 2 g proxy and `C`
    /// critical for the spring, `2 sqrt(K m)` = 1.55 N s/m (a drag of 0.015 N at 1 cm/s).
    /// At 1 kHz the passivity bound asks for 0.15 N s/m of device damping. The tissue
    /// force enters explicitly: the proxy is stable while the needle's stiffness in the
    /// tissue stays below `4 m / T^2` (8 kN/m at the defaults and 1 kHz).
    fn default() -> Self {
        let (k, m) = (300.0, 0.002);
        VirtualCoupling {
            stiffness: k,
            damping: 0.0,
            proxy_mass: m,
            proxy_damping: VirtualCoupling::critical_damping(k, m),
        }
    }
}

impl VirtualCoupling {
    /// The proxy damping that makes the spring `stiffness` on a proxy of mass `mass`
    /// critically damped, `2 sqrt(K m)`, N s/m.
    pub fn critical_damping(stiffness: f64, mass: f64) -> f64 {
        2.0 * (stiffness * mass).sqrt()
    }

    /// The device damping, N s/m, above which the rendered coupling is passive at period
    /// `period` s: `K T / 2 + B`.
    pub fn min_device_damping(&self, period: f64) -> f64 {
        0.5 * self.stiffness * period + self.damping
    }

    /// A parameter that is not finite, negative, or (mass, stiffness) zero: its name and
    /// value.
    pub fn invalid(&self) -> Option<(&'static str, f64)> {
        let checks = [
            ("stiffness", self.stiffness, true),
            ("damping", self.damping, false),
            ("proxy_mass", self.proxy_mass, true),
            ("proxy_damping", self.proxy_damping, false),
        ];
        checks
            .into_iter()
            .find(|&(_, v, positive)| !v.is_finite() || v < 0.0 || (positive && v == 0.0))
            .map(|(name, v, _)| (name, v))
    }
}

/// The needle proxy: the needle base's position and velocity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Proxy {
    /// Position, m.
    pub position: DVec3,
    /// Velocity, m/s.
    pub velocity: DVec3,
}

impl Proxy {
    /// A proxy at rest at `position`.
    pub fn at_rest(position: DVec3) -> Proxy {
        Proxy {
            position,
            velocity: DVec3::ZERO,
        }
    }

    /// Advances the proxy by `dt` under the coupling to a device at `device` moving at
    /// `device_velocity` and the tissue force `tissue` (N, on the needle); returns the
    /// force to send to the device, N.
    pub fn advance(
        &mut self,
        c: &VirtualCoupling,
        device: DVec3,
        device_velocity: DVec3,
        tissue: DVec3,
        dt: f64,
    ) -> DVec3 {
        let (k, b, m, cg) = (c.stiffness, c.damping, c.proxy_mass, c.proxy_damping);
        // Backward Euler in v with x_new = x + dt v_new:
        // m (v' - v) = dt [K (x_d - x - dt v') + B (v_d - v') - C v' + F].
        let rhs =
            m * self.velocity + dt * (k * (device - self.position) + b * device_velocity + tissue);
        self.velocity = rhs / (m + dt * (b + cg) + dt * dt * k);
        self.position += dt * self.velocity;
        self.device_force(c, device, device_velocity)
    }

    /// The coupling's force on the device, N: `K (x - x_d) + B (v - v_d)`.
    pub fn device_force(
        &self,
        c: &VirtualCoupling,
        device: DVec3,
        device_velocity: DVec3,
    ) -> DVec3 {
        c.stiffness * (self.position - device) + c.damping * (self.velocity - device_velocity)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A held device and a constant tissue force: the proxy settles where the spring
    /// carries the whole force, and the device feels exactly the tissue force.
    #[test]
    fn at_rest_the_device_feels_the_tissue_force() {
        let c = VirtualCoupling::default();
        let mut p = Proxy::at_rest(DVec3::ZERO);
        let tissue = DVec3::new(-1.5, 0.2, 0.0);
        let mut f = DVec3::ZERO;
        for _ in 0..5000 {
            f = p.advance(&c, DVec3::ZERO, DVec3::ZERO, tissue, 1e-3);
        }
        // Critically damped at 387 rad/s: after 5 s only rounding is left.
        assert!((f - tissue).length() < 1e-9, "{f} against {tissue}");
        assert!((p.position - tissue / c.stiffness).length() < 1e-12);
    }

    /// Stiff parameters far past the explicit limit (`sqrt(K/m) dt` = 100) stay bounded:
    /// the implicit update is unconditionally stable for the spring and dampers.
    #[test]
    fn a_stiff_coupling_does_not_blow_up() {
        let c = VirtualCoupling {
            stiffness: 1e5,
            damping: 0.0,
            proxy_mass: 1e-5,
            proxy_damping: 0.0,
        };
        let mut p = Proxy::at_rest(DVec3::new(0.01, 0.0, 0.0));
        for _ in 0..1000 {
            p.advance(&c, DVec3::ZERO, DVec3::ZERO, DVec3::ZERO, 1e-3);
        }
        assert!(p.position.length() <= 0.01, "{}", p.position);
    }

    /// Following a device at constant speed, the proxy lags by the drag `C v / K`.
    #[test]
    fn the_proxy_lags_by_its_drag() {
        let c = VirtualCoupling::default();
        let mut p = Proxy::at_rest(DVec3::ZERO);
        let v = DVec3::new(0.02, 0.0, 0.0);
        let mut f = DVec3::ZERO;
        let dt = 1e-3;
        for i in 1..=4000 {
            f = p.advance(&c, v * (i as f64 * dt), v, DVec3::ZERO, dt);
        }
        let drag = c.proxy_damping * v;
        // The implicit update lags by one more step of motion: K v dt = 6e-3 N.
        assert!(
            (-f - drag).length() < c.stiffness * v.length() * dt * 1.01,
            "{f}"
        );
    }

    #[test]
    fn invalid_parameters_are_named() {
        let mut c = VirtualCoupling::default();
        assert_eq!(c.invalid(), None);
        c.proxy_mass = 0.0;
        assert_eq!(c.invalid(), Some(("proxy_mass", 0.0)));
        c.proxy_mass = 0.01;
        c.damping = f64::NAN;
        assert!(matches!(c.invalid(), Some(("damping", v)) if v.is_nan()));
        assert!((VirtualCoupling::default().min_device_damping(1e-3) - 0.15).abs() < 1e-12);
    }
}
