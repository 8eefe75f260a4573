//! A flexible needle shaft: a chain of rigid segments joined by elastic hinges, solved
//! quasi-statically (issue 43, the paper's future work).
//!
//! The paper (section 7) proposes to model a flexible needle "as a chain of small rigid
//! needles". This module is that chain, as the rigid finite element method builds it
//! (Wittbrodt, Adamiec-Wojcik and Wojciech, *Dynamics of Flexible Multibody Systems:
//! Rigid Finite Element Method*, Springer 2006): the shaft of length `L` is cut into `N`
//! elements of length `l = L / N`; each element's flexibility is lumped into a hinge at its
//! middle, `s_k = (k + 1/2) l`, and rigid links join the hinges (a half link from the
//! clamped base to the first hinge, a half link from the last hinge to the tip). A hinge
//! turns the links after it by a rotation vector `theta_k`, taken in the frame of the link
//! before it, against the stiffness
//!
//! `K = diag(E I / l, E I / l, G J / l)`,  `I = pi (D^4 - d^4) / 64`,  `J = 2 I`,
//! `G = E / (2 (1 + nu))`,
//!
//! (bending about the two axes across the needle, torsion about its axis `z`), with `D`
//! and `d` the tube's outer and inner diameters.
//!
//! # Equilibrium
//!
//! A needle's own dynamics would set the time step if it were integrated explicitly with
//! the tissue: a 10 cm 22 G steel cantilever has its first bending mode near 57 Hz, but
//! its axial one near 12 kHz and a 20-element chain's highest bending mode near 20 kHz,
//! far above what the tissue's step resolves. So its shape is solved quasi-statically
//! (the "must not limit the tissue's time step"): for given loads the hinge
//! rotations are those for which every hinge's spring carries the moment of all the loads
//! beyond it about the hinge,
//!
//! `K theta_k = Q_k^T M_k(theta)`,  `M_k = sum_{s_j > s_k} (x(s_j) - p_k) x F_j + T_j
//!   + int_{s_k}^{L} (x(s) - p_k) x q ds`,
//!
//! with `Q_k` the orientation of the link before hinge `k`, `p_k` the hinge's position,
//! `F_j`, `T_j` point forces and moments at arc lengths `s_j`, and `q` a load per length.
//! The loads are dead (their directions stay put while the needle bends), and the lever
//! arms are taken on the deformed needle: large deflections are geometrically exact up
//! to the discretisation. The fixed point is found by Picard iteration on the moments,
//! under-relaxed when a step would grow the change (module tests: 3 to 4 iterations in
//! the linear range, 16 for a tip load `P L^2 / (E I) = 1`).
//!
//! # Accuracy (tests below; references that are not this code)
//!
//! Placing each hinge at its element's middle makes the chain exact to second order:
//!
//! - a tip force `P` deflects the tip by `P L^3 / (3 E I) (1 - 1 / (4 N^2))` (the
//!   Euler-Bernoulli cantilever, less 0.06% with 20 elements; measured -0.063%);
//! - a load `q` per length by `q L^4 / (8 E I) (1 - 1 / (2 N^2))` (0.13% with 20;
//!   measured -0.125%);
//! - a tip torque twists the tip by `T L / (G J)`, exactly;
//! - a tip force with `P L^2 / (E I) = 1` bends the tip 0.30172 L across and 0.05643 L
//!   back, the elastica of Bisshopp and Drucker (Q. Appl. Math. 3, 272-275, 1945); with
//!   100 elements the chain gives 0.301713 and 0.056433.
//!
//! What this module does not do yet: carry the needle nodes, friction and cutting of the
//! simulation along the bent centre line, and a bevel tip's asymmetric cutting force
//! (the items 2 to 5). The rigid needle is what [`crate::Simulation`] uses.

/// The vector and rotation types of this module's API (glam's, re-exported so that a
/// caller needs no glam dependency of its own).
pub use glam::{DQuat, DVec3};
use thiserror::Error;

/// Young's modulus of the stainless steel of hypodermic tubing (AISI 304), Pa.
pub const STEEL_YOUNG_MODULUS: f64 = 193e9;
/// Poisson's ratio of the same steel.
pub const STEEL_POISSON_RATIO: f64 = 0.29;

/// Most hinges a shaft may have (the solve is `O(N^2)` per iteration).
pub const MAX_SEGMENTS: usize = 1000;

/// Iterations of the equilibrium solve before it gives up.
const MAX_ITERATIONS: usize = 500;

/// Relative change of the hinge rotations at which the solve stops.
const TOLERANCE: f64 = 1e-12;

/// A bad shaft description or a load it cannot carry: the message names the key.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum RodError {
    /// A parameter outside its physical range.
    #[error("invalid flexible needle: {key}: {message}")]
    Invalid {
        /// The parameter's name.
        key: &'static str,
        /// What is wrong with its value.
        message: String,
    },
    /// A load that is not finite or lies off the shaft.
    #[error("invalid load on the flexible needle: {0}")]
    Load(String),
    /// The equilibrium iteration did not settle (a load far past the elastic range of
    /// a tube this thin). The solve follows the branch that starts straight: an axial
    /// compression above the buckling load with nothing across it returns the straight,
    /// unstable, equilibrium, not a buckled one.
    #[error(
        "the flexible needle found no equilibrium within {MAX_ITERATIONS} iterations (last \
         relative change {change:.3e}): the loads bend it past what the solve follows"
    )]
    NoEquilibrium {
        /// The last relative change of the hinge rotations.
        change: f64,
    },
}

/// The needle's tube: material, cross-section, length and discretisation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShaftSpec {
    /// Length from the clamped base to the tip, m.
    pub length: f64,
    /// Outer diameter, m (22 G: 0.718 mm; 18 G: 1.27 mm).
    pub outer_diameter: f64,
    /// Inner diameter (the lumen), m; 0 for a solid rod (a stylet in place).
    pub inner_diameter: f64,
    /// Young's modulus, Pa (stainless steel about 193 GPa, nitinol about 40-75 GPa).
    pub young_modulus: f64,
    /// Poisson's ratio (for the shear modulus of torsion).
    pub poisson_ratio: f64,
    /// Number of elements (hinges).
    pub segments: usize,
}

impl ShaftSpec {
    /// A steel tube of the given length and diameters, with `segments` elements.
    pub fn steel(length: f64, outer_diameter: f64, inner_diameter: f64, segments: usize) -> Self {
        ShaftSpec {
            length,
            outer_diameter,
            inner_diameter,
            young_modulus: STEEL_YOUNG_MODULUS,
            poisson_ratio: STEEL_POISSON_RATIO,
            segments,
        }
    }

    /// Checks every parameter; the error names the first bad one.
    pub fn validate(&self) -> Result<(), RodError> {
        let bad = |key, message: String| Err(RodError::Invalid { key, message });
        let positive = |x: f64| x.is_finite() && x > 0.0;
        if !positive(self.length) {
            return bad(
                "length",
                format!("must be a positive length in m, got {}", self.length),
            );
        }
        if !positive(self.outer_diameter) || self.outer_diameter > 0.01 {
            return bad(
                "outer_diameter",
                format!(
                    "must lie in (0, 0.01] m (a needle, 10 mm at most), got {}",
                    self.outer_diameter
                ),
            );
        }
        if !(self.inner_diameter.is_finite()
            && self.inner_diameter >= 0.0
            && self.inner_diameter < self.outer_diameter)
        {
            return bad(
                "inner_diameter",
                format!(
                    "must lie in [0, outer_diameter = {}) m, got {}",
                    self.outer_diameter, self.inner_diameter
                ),
            );
        }
        if !positive(self.young_modulus) {
            return bad(
                "young_modulus",
                format!(
                    "must be a positive modulus in Pa, got {}",
                    self.young_modulus
                ),
            );
        }
        if !(self.poisson_ratio.is_finite()
            && self.poisson_ratio > -1.0
            && self.poisson_ratio < 0.5)
        {
            return bad(
                "poisson_ratio",
                format!("must lie in (-1, 0.5), got {}", self.poisson_ratio),
            );
        }
        if self.segments == 0 || self.segments > MAX_SEGMENTS {
            return bad(
                "segments",
                format!("must lie in [1, {MAX_SEGMENTS}], got {}", self.segments),
            );
        }
        Ok(())
    }

    /// Second moment of area of the tube's cross-section, m^4.
    pub fn second_moment(&self) -> f64 {
        std::f64::consts::PI / 64.0 * (self.outer_diameter.powi(4) - self.inner_diameter.powi(4))
    }

    /// Bending stiffness `E I`, N m^2.
    pub fn bending_stiffness(&self) -> f64 {
        self.young_modulus * self.second_moment()
    }

    /// Torsional stiffness `G J`, N m^2 (`J = 2 I` for a circular tube).
    pub fn torsional_stiffness(&self) -> f64 {
        self.young_modulus / (2.0 * (1.0 + self.poisson_ratio)) * 2.0 * self.second_moment()
    }

    /// Element length `l = L / N`, m.
    pub fn element(&self) -> f64 {
        self.length / self.segments as f64
    }
}

/// A point load on the shaft: a force and a moment at arc length `s` from the base.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointLoad {
    /// Arc length from the base, m, in `[0, length]`.
    pub s: f64,
    /// Force, N, in the world frame.
    pub force: DVec3,
    /// Moment, N m, in the world frame.
    pub moment: DVec3,
}

/// The loads on the shaft.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Loads {
    /// Point forces and moments.
    pub points: Vec<PointLoad>,
    /// A uniform force per length along the whole shaft, N/m (its weight, a lateral
    /// tissue pressure), in the world frame.
    pub per_length: DVec3,
}

/// The shaft's equilibrium shape.
#[derive(Debug, Clone, PartialEq)]
pub struct ShaftShape {
    /// The hinge rotations (rotation vectors in the frame of the link before each).
    pub rotations: Vec<DVec3>,
    /// The centre line: the base, every hinge, the tip (`N + 2` points).
    pub points: Vec<DVec3>,
    /// The orientation of each link (`N + 1`: the base half link first); the needle's
    /// axis is each one's local `z`.
    pub frames: Vec<DQuat>,
    /// Iterations the solve took.
    pub iterations: usize,
}

impl ShaftShape {
    /// The tip's position.
    pub fn tip(&self) -> DVec3 {
        *self.points.last().expect("a shape has a tip")
    }

    /// The tip's orientation (its local `z` is the needle's direction at the tip).
    pub fn tip_frame(&self) -> DQuat {
        *self.frames.last().expect("a shape has a frame")
    }

    /// The point at arc length `s` (clamped to the shaft).
    pub fn point_at(&self, s: f64, spec: &ShaftSpec) -> DVec3 {
        let (link, from, along) = link_of(s, spec);
        self.points[link] + self.frames[link] * DVec3::Z * (along - from)
    }
}

/// The link holding arc length `s` (0: the base half link; `k + 1`: the link after hinge
/// `k`), the arc length where it starts, and `s` clamped to the shaft.
fn link_of(s: f64, spec: &ShaftSpec) -> (usize, f64, f64) {
    let l = spec.element();
    let s = s.clamp(0.0, spec.length);
    if s <= 0.5 * l {
        return (0, 0.0, s);
    }
    let k = (((s - 0.5 * l) / l).floor() as usize).min(spec.segments - 1);
    (k + 1, (k as f64 + 0.5) * l, s)
}

/// The centre line and link frames for hinge rotations `theta`, from the base at `base`
/// with orientation `q0`.
fn shape(spec: &ShaftSpec, base: DVec3, q0: DQuat, theta: &[DVec3]) -> (Vec<DVec3>, Vec<DQuat>) {
    let l = spec.element();
    let mut points = Vec::with_capacity(theta.len() + 2);
    let mut frames = Vec::with_capacity(theta.len() + 1);
    points.push(base);
    frames.push(q0);
    let mut x = base + q0 * DVec3::Z * (0.5 * l);
    let mut q = q0;
    for (k, t) in theta.iter().enumerate() {
        points.push(x);
        q = (q * DQuat::from_scaled_axis(*t)).normalize();
        frames.push(q);
        let length = if k + 1 == theta.len() { 0.5 * l } else { l };
        x += q * DVec3::Z * length;
    }
    points.push(x);
    (points, frames)
}

/// `int_a^b (p + u d - c) x q du` over a straight link from `p` along unit `d`, with the
/// arc length `u` from the link's start: the moment about `c` of a load `q` per length.
fn link_moment(p: DVec3, d: DVec3, a: f64, b: f64, c: DVec3, q: DVec3) -> DVec3 {
    let r = p - c;
    (r * (b - a) + d * (0.5 * (b * b - a * a))).cross(q)
}

/// The equilibrium shape of the shaft clamped at `base` with orientation `orientation`
/// (local `z` along the needle) under `loads`. Zero loads give the straight needle.
pub fn solve(
    spec: &ShaftSpec,
    base: DVec3,
    orientation: DQuat,
    loads: &Loads,
) -> Result<ShaftShape, RodError> {
    spec.validate()?;
    for (i, p) in loads.points.iter().enumerate() {
        if !(p.s.is_finite() && (0.0..=spec.length).contains(&p.s)) {
            return Err(RodError::Load(format!(
                "point load {i}: s = {} m is not on the shaft [0, {}]",
                p.s, spec.length
            )));
        }
        if !(p.force.is_finite() && p.moment.is_finite()) {
            return Err(RodError::Load(format!("point load {i} is not finite")));
        }
    }
    if !loads.per_length.is_finite() {
        return Err(RodError::Load("the load per length is not finite".into()));
    }
    let n = spec.segments;
    let l = spec.element();
    let (ei, gj) = (spec.bending_stiffness(), spec.torsional_stiffness());
    let compliance = DVec3::new(l / ei, l / ei, l / gj);
    let q0 = orientation.normalize();
    let mut theta = vec![DVec3::ZERO; n];
    let mut relax = 1.0f64;
    let mut last_change = f64::INFINITY;
    for iteration in 1..=MAX_ITERATIONS {
        let (points, frames) = shape(spec, base, q0, &theta);
        // Where each point load sits on the bent needle this iteration.
        let at: Vec<DVec3> = loads
            .points
            .iter()
            .map(|p| {
                let (link, from, s) = link_of(p.s, spec);
                points[link] + frames[link] * DVec3::Z * (s - from)
            })
            .collect();
        let mut next = Vec::with_capacity(n);
        for k in 0..n {
            let (sk, pk) = ((k as f64 + 0.5) * l, points[k + 1]);
            let mut m = DVec3::ZERO;
            for (p, x) in loads.points.iter().zip(&at).filter(|(p, _)| p.s > sk) {
                m += (*x - pk).cross(p.force) + p.moment;
            }
            if loads.per_length != DVec3::ZERO {
                for j in k + 1..=n {
                    let length = if j == n { 0.5 * l } else { l };
                    let d = frames[j] * DVec3::Z;
                    m += link_moment(points[j], d, 0.0, length, pk, loads.per_length);
                }
            }
            // The spring's moment in the frame of the link before the hinge.
            next.push(compliance * (frames[k].inverse() * m));
        }
        // Rotations beyond f64 (a load of 1e300 N, a tube of 1e-300 m): no equilibrium
        // (the NaN they gave passed the size test below as 0 and came back as a shape).
        if !next.iter().all(|t| t.is_finite()) {
            return Err(RodError::NoEquilibrium {
                change: f64::INFINITY,
            });
        }
        let size = next.iter().map(|t| t.length()).fold(0.0f64, f64::max);
        let change = theta
            .iter()
            .zip(&next)
            .map(|(a, b)| (*b - *a).length())
            .fold(0.0f64, f64::max);
        if change <= TOLERANCE * size.max(1e-300) || size == 0.0 {
            let (points, frames) = shape(spec, base, q0, &next);
            if !points.iter().all(|p| p.is_finite()) {
                return Err(RodError::NoEquilibrium {
                    change: f64::INFINITY,
                });
            }
            return Ok(ShaftShape {
                rotations: next,
                points,
                frames,
                iterations: iteration,
            });
        }
        // A Picard step that grows the change is halved until it no longer does.
        if change > last_change {
            relax = (relax * 0.5).max(1.0 / 64.0);
        }
        last_change = change;
        for (t, u) in theta.iter_mut().zip(&next) {
            *t += relax * (*u - *t);
        }
    }
    Err(RodError::NoEquilibrium {
        change: last_change,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 22 G steel needle (0.718 mm outer, 0.413 mm inner diameter), 10 cm.
    fn needle(segments: usize) -> ShaftSpec {
        ShaftSpec::steel(0.1, 0.718e-3, 0.413e-3, segments)
    }

    fn tip_load(force: DVec3) -> Loads {
        Loads {
            points: vec![PointLoad {
                s: 0.1,
                force,
                moment: DVec3::ZERO,
            }],
            per_length: DVec3::ZERO,
        }
    }

    /// Euler-Bernoulli cantilever, tip force: `P L^3 / (3 E I)`. A load of 1 mN bends
    /// the 22 G needle by about 0.1% of its length (the linear range); the chain's own
    /// error is `1 / (4 N^2)` (module docs), so 20 elements are within 0.1%.
    #[test]
    fn a_tip_force_bends_the_cantilever_as_euler_bernoulli() {
        let spec = needle(20);
        let p = 1e-3;
        let s = solve(&spec, DVec3::ZERO, DQuat::IDENTITY, &tip_load(DVec3::X * p)).unwrap();
        let exact = p * spec.length.powi(3) / (3.0 * spec.bending_stiffness());
        let got = s.tip().x;
        assert!((got / exact - 1.0).abs() < 0.01, "{got} vs {exact}");
        // The discretisation error as derived.
        let chain = exact * (1.0 - 1.0 / (4.0 * 400.0));
        assert!((got / chain - 1.0).abs() < 2e-3, "{got} vs {chain}");
        // The tip's slope: P L^2 / (2 E I).
        let slope = p * spec.length.powi(2) / (2.0 * spec.bending_stiffness());
        let d = s.tip_frame() * DVec3::Z;
        assert!((d.x / slope - 1.0).abs() < 0.01, "{} vs {slope}", d.x);
    }

    /// Euler-Bernoulli cantilever, uniform load: `q L^4 / (8 E I)`.
    #[test]
    fn a_uniform_load_bends_the_cantilever_as_euler_bernoulli() {
        let spec = needle(20);
        let q = 1e-2;
        let loads = Loads {
            points: Vec::new(),
            per_length: DVec3::new(0.0, -q, 0.0),
        };
        let s = solve(&spec, DVec3::ZERO, DQuat::IDENTITY, &loads).unwrap();
        let exact = q * spec.length.powi(4) / (8.0 * spec.bending_stiffness());
        let got = -s.tip().y;
        assert!((got / exact - 1.0).abs() < 0.01, "{got} vs {exact}");
    }

    /// A tip torque twists the tip by `T L / (G J)`.
    #[test]
    fn a_tip_torque_twists_by_t_l_over_g_j() {
        let spec = needle(10);
        let t = 1e-3;
        let loads = Loads {
            points: vec![PointLoad {
                s: spec.length,
                force: DVec3::ZERO,
                moment: DVec3::Z * t,
            }],
            per_length: DVec3::ZERO,
        };
        let s = solve(&spec, DVec3::ZERO, DQuat::IDENTITY, &loads).unwrap();
        let (axis, angle) = s.tip_frame().to_axis_angle();
        let exact = t * spec.length / spec.torsional_stiffness();
        assert!((axis.z - 1.0).abs() < 1e-9 && (angle / exact - 1.0).abs() < 1e-9);
        assert!(s.tip().distance(DVec3::Z * spec.length) < 1e-12);
    }

    /// Large deflection: with `P L^2 / (E I) = 1` the elastica's tip moves 0.30172 L
    /// across and 0.05643 L back (Bisshopp and Drucker 1945, their table).
    #[test]
    fn a_large_tip_force_follows_the_elastica() {
        let spec = needle(100);
        let p = spec.bending_stiffness() / spec.length.powi(2);
        let s = solve(&spec, DVec3::ZERO, DQuat::IDENTITY, &tip_load(DVec3::X * p)).unwrap();
        let (across, back) = (s.tip().x / spec.length, 1.0 - s.tip().z / spec.length);
        assert!((across / 0.30172 - 1.0).abs() < 0.01, "across {across}");
        assert!((back / 0.05643 - 1.0).abs() < 0.01, "back {back}");
        assert!(s.iterations < MAX_ITERATIONS);
    }

    /// The base pose carries the shape: a rotated and moved base gives the same shape,
    /// rotated and moved, for loads rotated with it.
    #[test]
    fn the_shape_follows_the_base_pose() {
        let spec = needle(20);
        let q = DQuat::from_scaled_axis(DVec3::new(0.3, -1.1, 0.4));
        let x0 = DVec3::new(0.01, -0.02, 0.5);
        let f = DVec3::new(2e-3, -1e-3, 5e-4);
        let a = solve(&spec, DVec3::ZERO, DQuat::IDENTITY, &tip_load(f)).unwrap();
        let b = solve(&spec, x0, q, &tip_load(q * f)).unwrap();
        for (pa, pb) in a.points.iter().zip(&b.points) {
            assert!((x0 + q * *pa).distance(*pb) < 1e-12, "{pa} {pb}");
        }
        assert!(b.point_at(spec.length, &spec).distance(b.tip()) < 1e-15);
        assert!(b.point_at(0.0, &spec).distance(x0) < 1e-15);
    }

    #[test]
    fn bad_specs_and_loads_are_errors_naming_the_key() {
        let good = needle(10);
        let cases: [(&str, ShaftSpec); 7] = [
            (
                "length",
                ShaftSpec {
                    length: -1.0,
                    ..good
                },
            ),
            (
                "outer_diameter",
                ShaftSpec {
                    outer_diameter: 0.0,
                    ..good
                },
            ),
            (
                "outer_diameter",
                ShaftSpec {
                    outer_diameter: 0.5,
                    ..good
                },
            ),
            (
                "inner_diameter",
                ShaftSpec {
                    inner_diameter: 1e-3,
                    ..good
                },
            ),
            (
                "young_modulus",
                ShaftSpec {
                    young_modulus: f64::NAN,
                    ..good
                },
            ),
            (
                "poisson_ratio",
                ShaftSpec {
                    poisson_ratio: 0.5,
                    ..good
                },
            ),
            (
                "segments",
                ShaftSpec {
                    segments: 0,
                    ..good
                },
            ),
        ];
        for (key, spec) in cases {
            let e = solve(&spec, DVec3::ZERO, DQuat::IDENTITY, &Loads::default()).unwrap_err();
            assert!(
                matches!(e, RodError::Invalid { key: k, .. } if k == key),
                "{key}: {e}"
            );
        }
        let off = Loads {
            points: vec![PointLoad {
                s: 0.2,
                force: DVec3::X,
                moment: DVec3::ZERO,
            }],
            per_length: DVec3::ZERO,
        };
        let e = solve(&good, DVec3::ZERO, DQuat::IDENTITY, &off).unwrap_err();
        assert!(e.to_string().contains("not on the shaft"), "{e}");
        let nan = tip_load(DVec3::new(f64::NAN, 0.0, 0.0));
        assert!(solve(&good, DVec3::ZERO, DQuat::IDENTITY, &nan).is_err());
        // A load far past the elastic range (a kilonewton on a 22 G needle) finds no
        // equilibrium rather than a wrong one.
        let e = solve(
            &good,
            DVec3::ZERO,
            DQuat::IDENTITY,
            &tip_load(DVec3::X * 1e3),
        );
        assert!(matches!(e, Err(RodError::NoEquilibrium { .. })), "{e:?}");
        // Beyond f64: the rotations were NaN and came back as a shape.
        let e = solve(
            &needle(20),
            DVec3::ZERO,
            DQuat::IDENTITY,
            &tip_load(DVec3::X * 1e300),
        );
        assert!(matches!(e, Err(RodError::NoEquilibrium { .. })), "{e:?}");
    }
}
