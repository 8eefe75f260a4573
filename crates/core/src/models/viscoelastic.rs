//! Viscoelastic continuum tissue: a generalized Maxwell (Prony series) relaxation of the
//! stress, `viscoelastic = [{ g = 0.3, tau = 0.5 }, ...]` in the `[material]` table of the
//! continuum models (Debunne, co-rotated Debunne, point based animation, neo-Hookean).
//!
//! # The law
//!
//! Quasi-linear viscoelasticity (Fung; in the form of Simo 1987 and of Abaqus' Prony
//! series): the stress is the hereditary integral of the instantaneous elastic stress
//! `S_0` (the model's own elastic law with the scene's moduli, which are therefore the
//! *instantaneous* ones) against the normalised relaxation function
//!
//! `g(t) = g_inf + sum_i g_i exp(-t / tau_i)`,  `g_inf = 1 - sum_i g_i`,
//!
//! `S(t) = int_0^t g(t - s) dS_0/ds ds = g_inf S_0(t) + sum_i h_i(t)`,
//! `h_i(t) = g_i int_0^t exp(-(t - s) / tau_i) dS_0/ds ds`.
//!
//! Young's modulus relaxes as `E(t) = E g(t)`, from `E` at once to `E g_inf` after long
//! holds; the same function scales both Lame constants, so the Poisson ratio does not
//! change with time and a uniaxial test relaxes exactly as `g(t)`. `S` is the stress
//! measure each model's energy is written in, in the material frame where the recursion
//! is objective: the small-strain stress of Debunne's model (for the co-rotated variant,
//! of `R^T F - I`, pushed forward by `R`), the second Piola-Kirchhoff stress of point
//! based animation and of the neo-Hookean model (pushed forward by `F`). The hourglass
//! control and point based animation's volume term stay elastic (they stabilise, they
//! are not tissue).
//!
//! # The update
//!
//! With `S_0` linear in time over each step (exact for the explicit step, which sees the
//! stress only at its ends), the integral over a step is closed form
//! (Taylor, Pister and Goudreau 1970; Simo and Hughes 1998, section 10.3):
//!
//! `h_i(n+1) = a_i h_i(n) + b_i (S_0(n+1) - S_0(n))`,
//! `a_i = exp(-dt / tau_i)`,  `b_i = g_i (tau_i / dt) (1 - a_i)`.
//!
//! `a_i` lies in (0, 1) for every `dt / tau_i`, so the recursion is stable for any step:
//! a `tau` far below `dt` relaxes its term within the step, one far above it holds it.
//! The state per node is `S_0(n)` and the `h_i(n)` (six floats each, symmetric); the
//! force pass writes the next state beside the committed one and the integration commits
//! it, so extra force evaluations within a step (a needle settling, a stability probe)
//! do not advance the relaxation.
//!
//! The state is allocated only for a material with terms; an elastic scene's arrays and
//! arithmetic are those of before (bitwise).

use crate::error::SceneError;
use glam::Mat3;

/// Most Prony terms a material may have (the kernels' fixed loop bound).
pub const MAX_PRONY_TERMS: usize = 4;

/// Floats of the viscous state per node and term (one symmetric tensor).
pub const SYM: usize = 6;

/// One term of the series: its share `g` of the instantaneous modulus that relaxes, with
/// time constant `tau`.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PronyTerm {
    /// Share of the instantaneous modulus that relaxes with this term, in [0, 1).
    pub g: f64,
    /// Relaxation time in s, positive and finite.
    pub tau: f64,
}

/// A Prony series of at most [`MAX_PRONY_TERMS`] terms (empty: elastic). It reads and
/// writes as a TOML array of `{ g, tau }` tables; a longer array is kept to be refused by
/// [`Prony::validate`] with the key's name.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Prony {
    terms: [PronyTerm; MAX_PRONY_TERMS],
    len: usize,
    /// Terms the input had (more than [`MAX_PRONY_TERMS`] is an error).
    requested: usize,
}

impl Prony {
    /// No terms: an elastic material (the default).
    pub const fn elastic() -> Prony {
        Prony {
            terms: [PronyTerm { g: 0.0, tau: 0.0 }; MAX_PRONY_TERMS],
            len: 0,
            requested: 0,
        }
    }

    /// The series of two terms, in a constant.
    pub const fn new_const(terms: [PronyTerm; 2]) -> Prony {
        let mut p = Prony::elastic();
        p.terms[0] = terms[0];
        p.terms[1] = terms[1];
        p.len = 2;
        p.requested = 2;
        p
    }

    /// The series of `terms` (more than [`MAX_PRONY_TERMS`] fails [`Prony::validate`]).
    pub fn new(terms: &[PronyTerm]) -> Prony {
        let mut p = Prony {
            requested: terms.len(),
            len: terms.len().min(MAX_PRONY_TERMS),
            ..Prony::default()
        };
        p.terms[..p.len].copy_from_slice(&terms[..p.len]);
        p
    }

    /// The terms.
    pub fn terms(&self) -> &[PronyTerm] {
        &self.terms[..self.len]
    }

    /// No terms: an elastic material.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// `g_inf = 1 - sum g_i`: the long-term share of the instantaneous modulus.
    pub fn g_inf(&self) -> f64 {
        1.0 - self.terms().iter().map(|t| t.g).sum::<f64>()
    }

    /// The normalised relaxation function `g(t) = E(t) / E`.
    pub fn relaxation(&self, t: f64) -> f64 {
        self.g_inf()
            + self
                .terms()
                .iter()
                .map(|p| p.g * (-t / p.tau).exp())
                .sum::<f64>()
    }

    /// Floats of viscous state per node: `S_0` and one tensor per term.
    pub fn state_floats(&self) -> usize {
        if self.is_empty() {
            0
        } else {
            SYM * (1 + self.len)
        }
    }

    /// Checks the series; errors name `{key}.viscoelastic`.
    pub fn validate(&self, key: &str) -> Result<(), SceneError> {
        let key = format!("{key}.viscoelastic");
        if self.requested > MAX_PRONY_TERMS {
            return Err(SceneError::invalid(
                key,
                format!(
                    "at most {MAX_PRONY_TERMS} terms (the kernels' fixed bound), got {}",
                    self.requested
                ),
            ));
        }
        for (i, t) in self.terms().iter().enumerate() {
            if !(t.g.is_finite() && (0.0..1.0).contains(&t.g)) {
                return Err(SceneError::invalid(
                    format!("{key}[{i}].g"),
                    format!(
                        "must lie in [0, 1) (a share of the instantaneous modulus), got {}",
                        t.g
                    ),
                ));
            }
            if !(t.tau.is_finite() && t.tau > 0.0 && (t.tau as f32) > 0.0) {
                return Err(SceneError::invalid(
                    format!("{key}[{i}].tau"),
                    format!("must be a positive finite time in s, got {}", t.tau),
                ));
            }
        }
        let sum: f64 = self.terms().iter().map(|t| t.g).sum();
        if sum >= 1.0 {
            return Err(SceneError::invalid(
                key,
                format!(
                    "the shares g must sum to less than 1 (the long-term modulus E (1 - sum g) \
                     must stay positive), got {sum}"
                ),
            ));
        }
        Ok(())
    }

    /// The update coefficients of a step `dt` (module docs), in the f32 the kernels use.
    pub fn coefficients(&self, dt: f64) -> ViscoCoefficients {
        let mut c = ViscoCoefficients {
            g_inf: self.g_inf() as f32,
            a: [0.0; MAX_PRONY_TERMS],
            b: [0.0; MAX_PRONY_TERMS],
            len: self.len,
        };
        for (i, t) in self.terms().iter().enumerate() {
            let x = dt / t.tau;
            let a = (-x).exp();
            c.a[i] = a as f32;
            // (1 - exp(-x)) / x without cancellation for small x.
            c.b[i] = (t.g * -(-x).exp_m1() / x) as f32;
        }
        c
    }
}

impl serde::Serialize for Prony {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.terms().serialize(s)
    }
}

impl<'de> serde::Deserialize<'de> for Prony {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Prony, D::Error> {
        let terms = Vec::<PronyTerm>::deserialize(d)?;
        Ok(Prony::new(&terms))
    }
}

/// Bytes per node of the viscoelastic state of `p` (committed and next rows; 0 when
/// elastic), for the memory estimate.
pub fn visco_bytes(p: &Prony) -> f64 {
    if p.is_empty() {
        0.0
    } else {
        (2 * 4 * SYM * (1 + MAX_PRONY_TERMS)) as f64
    }
}

/// The per-step constants of [`Prony::coefficients`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViscoCoefficients {
    /// `1 - sum g_i`.
    pub g_inf: f32,
    /// `exp(-dt / tau_i)`.
    pub a: [f32; MAX_PRONY_TERMS],
    /// `g_i (tau_i / dt) (1 - a_i)`.
    pub b: [f32; MAX_PRONY_TERMS],
    /// Terms in use.
    pub len: usize,
}

/// The symmetric part of `m` as `[xx, yy, zz, xy, yz, zx]`.
#[inline]
pub fn to_sym(m: &Mat3) -> [f32; SYM] {
    let (c0, c1, c2) = (m.x_axis, m.y_axis, m.z_axis);
    [
        c0.x,
        c1.y,
        c2.z,
        0.5 * (c1.x + c0.y),
        0.5 * (c2.y + c1.z),
        0.5 * (c0.z + c2.x),
    ]
}

/// The symmetric matrix of `[xx, yy, zz, xy, yz, zx]`.
#[inline]
pub fn from_sym(s: &[f32]) -> Mat3 {
    Mat3::from_cols_array(&[s[0], s[3], s[5], s[3], s[1], s[4], s[5], s[4], s[2]])
}

/// One step of the recursion for one node: from its committed state `prev`
/// (`[S_0(n), h_1(n), ...]`) and its new elastic stress `s0`, writes `[S_0(n+1),
/// h_1(n+1), ...]` into `next` and returns the viscoelastic stress
/// `g_inf S_0(n+1) + sum h_i(n+1)`.
#[inline]
pub fn relax(s0: &Mat3, prev: &[f32], next: &mut [f32], c: &ViscoCoefficients) -> Mat3 {
    let s = to_sym(s0);
    let mut total = [0.0f32; SYM];
    for k in 0..SYM {
        total[k] = c.g_inf * s[k];
    }
    for i in 0..c.len {
        let at = SYM * (i + 1);
        for k in 0..SYM {
            let h = c.a[i] * prev[at + k] + c.b[i] * (s[k] - prev[k]);
            next[at + k] = h;
            total[k] += h;
        }
    }
    next[..SYM].copy_from_slice(&s);
    from_sym(&total)
}

/// The closed forms the tests and the report check against: the response of the series
/// to a strain ramped linearly from 0 at `t = 0` to its full value at `t = ramp` (then
/// held), as a fraction of the instantaneous elastic response to the full strain:
/// `(1 / ramp) int_0^min(t, ramp) g(t - s) ds`. `ramp = 0` is a step: `g(t)`.
pub fn ramp_response(p: &Prony, t: f64, ramp: f64) -> f64 {
    if ramp <= 0.0 {
        return p.relaxation(t);
    }
    let end = t.min(ramp);
    // int_0^end g(t - s) ds = g_inf end + sum g_i tau_i (exp(-(t - end)/tau) - exp(-t/tau)).
    let mut v = p.g_inf() * end;
    for term in p.terms() {
        v += term.g * term.tau * ((-(t - end) / term.tau).exp() - (-t / term.tau).exp());
    }
    v / ramp
}

/// The complex modulus of the series at angular frequency `omega`, as a fraction of the
/// instantaneous modulus: `(E', E'')`, `E*/E = g_inf + sum g_i i w tau_i / (1 + i w tau_i)`.
/// The loss angle is `atan(E'' / E')`.
pub fn complex_modulus(p: &Prony, omega: f64) -> (f64, f64) {
    let mut re = p.g_inf();
    let mut im = 0.0;
    for t in p.terms() {
        let x = omega * t.tau;
        re += t.g * x * x / (1.0 + x * x);
        im += t.g * x / (1.0 + x * x);
    }
    (re, im)
}

/// The creep compliance of a one-term series (the standard linear solid) under a stress
/// step, as a multiple of the instantaneous compliance `1 / E`:
/// `J(t) E = 1 / g_inf - (1 / g_inf - 1) exp(-t g_inf / tau)` (the retardation time is
/// `tau / g_inf`). `None` for any other number of terms (their compliance needs the roots
/// of a polynomial).
pub fn creep_compliance(p: &Prony, t: f64) -> Option<f64> {
    let [term] = p.terms() else { return None };
    let g_inf = p.g_inf();
    Some(1.0 / g_inf - (1.0 / g_inf - 1.0) * (-t * g_inf / term.tau).exp())
}

/// The creep of a one-term series under a stress ramped linearly from 0 at `t = 0` to
/// its full value at `t = ramp` (then held), as a multiple of the instantaneous strain
/// of the full stress: `(1 / ramp) int_0^min(t, ramp) J(t - s) E ds` with
/// [`creep_compliance`]; `ramp = 0` is a step. `None` unless the series has one term.
pub fn creep_ramp_response(p: &Prony, t: f64, ramp: f64) -> Option<f64> {
    let [term] = p.terms() else { return None };
    if ramp <= 0.0 {
        return creep_compliance(p, t);
    }
    let g_inf = p.g_inf();
    let tau_c = term.tau / g_inf;
    let end = t.min(ramp);
    let v = end / g_inf
        - (1.0 / g_inf - 1.0) * tau_c * ((-(t - end) / tau_c).exp() - (-t / tau_c).exp());
    Some(v / ramp)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series() -> Prony {
        Prony::new(&[
            PronyTerm { g: 0.3, tau: 0.05 },
            PronyTerm { g: 0.2, tau: 1.0 },
        ])
    }

    /// The recursion at one material point reproduces the closed form of a ramp and hold
    /// for steps from far below to far above the time constants (stable for any
    /// dt / tau), within f32 round-off (1e-5 of the instantaneous stress).
    #[test]
    fn the_recursion_is_exact_for_a_ramp_and_hold_at_any_step() {
        let p = series();
        for dt in [1e-4, 1e-3, 0.02, 0.5] {
            let c = p.coefficients(dt);
            let (mut prev, mut next) = (
                vec![0.0f32; p.state_floats()],
                vec![0.0f32; p.state_floats()],
            );
            let ramp_steps = 10usize;
            let ramp = ramp_steps as f64 * dt;
            for n in 1..=2000usize {
                let t = n as f64 * dt;
                let strain = (t / ramp).min(1.0) as f32;
                let s = relax(
                    &Mat3::from_diagonal(glam::Vec3::new(strain, 0.0, 0.0)),
                    &prev,
                    &mut next,
                    &c,
                );
                std::mem::swap(&mut prev, &mut next);
                let want = ramp_response(&p, t, ramp);
                assert!(
                    (s.x_axis.x as f64 - want).abs() < 1e-5,
                    "dt {dt}, t {t}: {} against {want}",
                    s.x_axis.x
                );
            }
        }
    }

    #[test]
    fn bad_series_are_typed_errors_naming_the_key() {
        let bad = |terms: &[PronyTerm]| {
            Prony::new(terms)
                .validate("material")
                .unwrap_err()
                .to_string()
        };
        let t = |g, tau| PronyTerm { g, tau };
        assert!(bad(&[t(1.0, 1.0)]).contains("material.viscoelastic[0].g"));
        assert!(bad(&[t(-0.1, 1.0)]).contains("material.viscoelastic[0].g"));
        assert!(bad(&[t(0.2, 1.0), t(0.2, 0.0)]).contains("material.viscoelastic[1].tau"));
        assert!(bad(&[t(0.2, f64::INFINITY)]).contains("[0].tau"));
        assert!(bad(&[t(0.6, 1.0), t(0.5, 2.0)]).contains("sum"));
        assert!(bad(&[t(0.1, 1.0); 5]).contains("at most 4"));
        assert!(Prony::new(&[t(0.5, 1.0), t(0.4, 0.1)])
            .validate("m")
            .is_ok());
    }

    /// The closed forms agree with each other: a ramp of length -> 0 is the step, the
    /// complex modulus tends to g_inf and 1 at low and high frequency, and the creep
    /// compliance starts at 1 and ends at 1 / g_inf.
    #[test]
    fn closed_forms_are_consistent() {
        let p = series();
        for t in [0.01, 0.1, 1.0, 3.0] {
            assert!((ramp_response(&p, t, 1e-9) - p.relaxation(t)).abs() < 1e-6);
        }
        let (lo, _) = complex_modulus(&p, 1e-6);
        let (hi, _) = complex_modulus(&p, 1e6);
        assert!((lo - 0.5).abs() < 1e-5 && (hi - 1.0).abs() < 1e-5);
        let one = Prony::new(&[PronyTerm { g: 0.4, tau: 0.5 }]);
        assert!((creep_compliance(&one, 0.0).unwrap() - 1.0).abs() < 1e-12);
        assert!((creep_compliance(&one, 1e3).unwrap() - 1.0 / 0.6).abs() < 1e-9);
        assert!(creep_compliance(&p, 1.0).is_none());
        for t in [0.3, 1.0, 5.0] {
            let a = creep_ramp_response(&one, t, 1e-9).unwrap();
            assert!((a - creep_compliance(&one, t).unwrap()).abs() < 1e-6);
        }
        // Halfway up a short ramp the strain is about half the instantaneous one.
        assert!((creep_ramp_response(&one, 0.05, 0.1).unwrap() - 0.5).abs() < 0.02);
    }
}
