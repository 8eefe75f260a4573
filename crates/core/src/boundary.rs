//! Boundary conditions on node sets, applied around the backend's step:
//!
//! - held sets (`[[fixed]]`, `[[prescribed]]`): a set held in all three components at rest
//!   has inverse mass 0 and never moves; any other (a roller, a prescribed displacement)
//!   has its held components of position and velocity set to `x0 + u(t)` and `u'(t)` after
//!   every integration, so the next force evaluation sees the constraint satisfied (a
//!   projection, exact for the explicit step);
//! - surface loads (`[[load]]`): `f_i = s(t) * traction * |A_i|` or `-s(t) * p * A_i` added
//!   to the forces before the integration, `A_i` the node's outward area vector at rest
//!   over the loaded triangles (a third of each) and `s` the ramp;
//! - far-field faces (`[[fixed]]` with `far_field = { distance = R }`): see below;
//! - reactions: the force the supports exert on the body, `R = -sum_i (f_i + m_i g)` over a
//!   set's held components (zero in its free ones), `f_i` the forces of the last step.
//!   At rest it balances the loads and the weight. A far-field face's reaction is the sum
//!   of its springs' and dashpots' forces at the current state.
//!
//! # Far-field faces
//!
//! A scene that cuts a block out of a body (the abdominal wall around a biopsy site) and
//! holds the cut faces rigidly reflects every wave that reaches them: the block rings at
//! its own standing modes, which the body it was cut from does not have (the energy would
//! travel on and spread). Measured on `scenes/layered_liver_biopsy.toml` (side faces
//! 15 mm from the needle, held): after the skin gives at 2.8 N, the 4.5 mm skin rings at
//! about 95 Hz, `c_s / 4 w` for its half-width `w`, for more than 50 ms.
//!
//! A far-field face lets its surface nodes move, each tied to its rest position by
//! springs and dashpots per unit area, normal (`n`) and tangential to the face:
//!
//! `f_i = -A_i [ (rho c_p v_n + K_n u_n) n + rho c_s v_t + K_t u_t ]`
//!
//! `A_i` the node's share of the face's area, `u` its displacement, `v` its velocity, and
//! `rho`, `c_p = sqrt((lambda + 2 G) / rho)`, `c_s = sqrt(G / rho)` those of the node's
//! region. The dashpots are Lysmer and Kuhlemeyer's (1969, J Eng Mech Div ASCE
//! 95(EM4):859-877): the impedances of plane P and S waves, so a wave that meets the face
//! head-on leaves the block instead of coming back. The springs carry the static load
//! that the tissue beyond carries: for the exterior of a sphere of radius `R`, a uniform
//! radial displacement `u` needs the traction `4 G u / R` (Lame: `u_r = u R^2 / r^2`,
//! `sigma_rr = 2 G du_r/dr` for this divergence-free field) and a rotation of its surface
//! `3 G u / R` (`u_phi = u R^2 / r^2`, `tau = G r d(u_phi / r)/dr`), so `K_n = 4 G / R`,
//! `K_t = 3 G / R` with
//! `R = distance`, the distance from the loads inside to the face. These are the
//! viscous-spring boundaries of geomechanics; a larger `distance` is a softer support, and
//! the static response tends to a held face as it shrinks. Below the corner frequency
//! `K / (rho c)` the face reflects like a spring; above it, it absorbs.
//!
//! The dashpot is taken implicitly with the integrator's own step
//! ([`crate::integrator`]): with `v*` the velocity the step would reach without it and `d`
//! the damping factor, the force `-c d v* / (1 + d dt c / m)` makes the update exactly
//! `v' = d v* / (1 + d dt c / m)` in each direction, stable for any `c` (explicitly, the
//! skin's edge nodes had `dt c / m` near 1.5). The springs are explicit:
//! [`Boundary::check_far_field`] refuses a step at which a spring alone would be near its
//! stability limit. Host side (a read and a write of the face's rows per step on any
//! backend). Limits: a node that another set holds in all components gets no far-field
//! force; a node on two far-field faces (an edge where two meet) is solved face by face,
//! so its dashpots compound there (stable, somewhat more damped than one solve of both);
//! a node a roller also holds gets the far-field force in its held component too, which
//! the projection then removes, and the roller's reaction counts it. Tested against closed forms in `tests/boundary.rs`: a block on a far-field
//! floor sinks by `W / (K_n A)` (0.3%) with the weight as its reaction, and a step wave
//! down a column leaves 8.6% of the kinetic energy a held end keeps.
//!
//! The shipped layered scene keeps its held sides. With far-field sides at the needle's
//! 15 mm the skin's ring went (CPU, 2026-11-27), and the skin's dent at its puncture
//! came to 9.3 mm of travel against 7.3 mm held and 9.4 mm for a block twice as wide
//! (held 30 mm away): nearer the wider body, as it should. But the fat then rode along
//! the needle (the tip's material point 1.1 mm deep after 11 mm of travel, 1.6 s), and
//! where it sprang forward ahead of the tip the cutting element let go and pushed again
//! (the tip's force 0.31 to 0.15 N and back within 1 ms): 9.8% of buzz and 3 jumps,
//! against 6.1% and none with held sides. What is left to mend is the tip's contact in a
//! layer that moves with the needle, not the boundary (the needle chapter).

use crate::backend::{Backend, NodeField, NodeSelection};
use crate::error::{SceneError, SimError};
use crate::integrator::StepParams;
use crate::scene::Motion;
use glam::DVec3;

/// A node set whose displacement is held in some components.
#[derive(Debug, Clone, PartialEq)]
pub struct HeldSet {
    /// Name in the reaction output.
    pub name: String,
    /// Node indices, sorted.
    pub nodes: Vec<u32>,
    /// The components held.
    pub components: [bool; 3],
    /// The prescribed motion (none: held at rest).
    pub motion: Option<Motion>,
    /// Whether its nodes have inverse mass 0 (all components held): the integrator leaves
    /// them where they are put.
    pub kinematic: bool,
    rest: Vec<[f64; 3]>,
    masses: Vec<f64>,
    /// The springs and dashpots of a far-field face (none: held rigidly).
    far: Option<FarField>,
}

/// The springs and dashpots of a far-field face, per node of a [`HeldSet`] (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct FarField {
    /// The key of the scene's table, for errors (`fixed[i].far_field.distance`).
    pub key: String,
    /// Unit outward normal of each node's share of the face.
    pub normals: Vec<[f64; 3]>,
    /// Normal and tangential dashpot of each node, `A rho c_p` and `A rho c_s`, N s/m.
    pub dashpots: Vec<[f64; 2]>,
    /// Normal and tangential spring of each node, `A K_n` and `A K_t`, N/m.
    pub springs: Vec<[f64; 2]>,
}

/// The node's share of a far-field face's area (`area`, m^2), its material (`young`,
/// `nu`, `density`) and the face's `distance`: the dashpots and springs of the module docs.
pub fn far_field_coefficients(
    area: f64,
    (young, nu): (f64, f64),
    density: f64,
    distance: f64,
) -> ([f64; 2], [f64; 2]) {
    let g = young / (2.0 * (1.0 + nu));
    let m = young * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu));
    (
        [area * (density * m).sqrt(), area * (density * g).sqrt()],
        [area * 4.0 * g / distance, area * 3.0 * g / distance],
    )
}

/// A surface load on some nodes.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadSet {
    /// Name (for errors).
    pub name: String,
    /// Node indices, sorted.
    pub nodes: Vec<u32>,
    /// Each node's force at the full load, N.
    pub forces: Vec<[f64; 3]>,
    /// Ramp time, s.
    pub ramp: f64,
}

/// The force the supports of one held set exert on the body.
#[derive(Debug, Clone, PartialEq)]
pub struct Reaction {
    /// The set's name.
    pub name: String,
    /// Force in N (zero in the components the set does not hold).
    pub force: [f64; 3],
}

/// Every boundary condition of a tissue.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Boundary {
    /// Held sets, `[[fixed]]` first, then `[[prescribed]]`.
    pub held: Vec<HeldSet>,
    /// Surface loads.
    pub loads: Vec<LoadSet>,
}

impl HeldSet {
    /// A held set of `nodes` with their rest positions and masses.
    pub fn new(
        name: String,
        nodes: Vec<u32>,
        components: [bool; 3],
        motion: Option<Motion>,
        rest: &[[f64; 3]],
        masses: &[f64],
    ) -> HeldSet {
        HeldSet {
            kinematic: components == [true; 3],
            rest: nodes.iter().map(|&i| rest[i as usize]).collect(),
            masses: nodes.iter().map(|&i| masses[i as usize]).collect(),
            name,
            nodes,
            components,
            motion,
            far: None,
        }
    }

    /// A far-field face: `nodes` (its surface nodes) supported by the springs and dashpots
    /// of `far`, one entry per node.
    pub fn far_field(
        name: String,
        nodes: Vec<u32>,
        far: FarField,
        rest: &[[f64; 3]],
        masses: &[f64],
    ) -> HeldSet {
        let mut set = HeldSet::new(name, nodes, [true; 3], None, rest, masses);
        set.kinematic = false;
        set.far = Some(far);
        set
    }

    /// The springs and dashpots of a far-field face.
    pub fn far(&self) -> Option<&FarField> {
        self.far.as_ref()
    }

    /// Whether the set needs work after each step (everything but a set held at rest in
    /// all components).
    fn projected(&self) -> bool {
        self.far.is_none() && (self.motion.is_some() || !self.kinematic)
    }

    /// The far-field springs' force on node `k` displaced by `u` from its rest position.
    fn far_spring(&self, f: &FarField, k: usize, u: DVec3) -> DVec3 {
        let (un, ut) = normal_tangent(DVec3::from(f.normals[k]), u);
        let [kn, kt] = f.springs[k];
        -kn * un - kt * ut
    }

    /// The force of the far-field springs and dashpots on node `k` of `s` (the dashpots
    /// explicit: the reaction after the step).
    fn far_force(&self, f: &FarField, k: usize, s: &FarRead) -> DVec3 {
        let (vn, vt) = normal_tangent(DVec3::from(f.normals[k]), s.velocity[k]);
        let [cn, ct] = f.dashpots[k];
        self.far_spring(f, k, s.position[k] - DVec3::from(self.rest[k])) - cn * vn - ct * vt
    }

    /// The set's nodes as the backend has them, in one read: world positions to the
    /// remainder, velocities, inverse masses, and with `forces` the forces.
    fn read_far(&self, b: &mut dyn Backend, forces: bool) -> Result<FarRead, SimError> {
        let n = self.nodes.len();
        let (mut x, mut r) = (vec![[0.0f32; 4]; n], vec![[0.0f32; 4]; n]);
        let mut v = vec![[0.0f32; 4]; n];
        let mut f = vec![[0.0f32; 4]; if forces { n } else { 0 }];
        let list = NodeSelection::List(&self.nodes);
        let mut requests = vec![
            (NodeField::Position, list.clone()),
            (NodeField::PositionRemainder, list.clone()),
            (NodeField::Velocity, list.clone()),
        ];
        let mut outs: Vec<&mut [[f32; 4]]> = vec![&mut x, &mut r, &mut v];
        if forces {
            requests.push((NodeField::Force, list));
            outs.push(&mut f);
        }
        b.read_many(&requests, &mut outs)?;
        let f64s = |p: &[f32; 4]| DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        Ok(FarRead {
            position: x.iter().zip(&r).map(|(x, r)| f64s(x) + f64s(r)).collect(),
            velocity: v.iter().map(f64s).collect(),
            inv_mass: x.iter().map(|x| x[3] as f64).collect(),
            force: f,
        })
    }
}

/// A far-field set's nodes as read back ([`HeldSet::read_far`]).
struct FarRead {
    /// World positions, f32 value plus remainder.
    position: Vec<DVec3>,
    velocity: Vec<DVec3>,
    inv_mass: Vec<f64>,
    /// Forces (empty unless asked for).
    force: Vec<[f32; 4]>,
}

/// The parts of `a` along the unit normal `n` and across it.
fn normal_tangent(n: DVec3, a: DVec3) -> (DVec3, DVec3) {
    let an = a.dot(n) * n;
    (an, a - an)
}

impl Boundary {
    /// Whether the step needs this module (a projection or a load); sets held at rest in
    /// all components need nothing once their inverse mass is 0.
    pub fn acts_each_step(&self) -> bool {
        !self.loads.is_empty() || self.held.iter().any(|h| h.projected() || h.far.is_some())
    }

    /// The highest frequency of a far-field spring on its node alone, `sqrt(k / m)`
    /// (rad/s; 0 without far-field faces).
    pub fn far_field_frequency(&self) -> f64 {
        self.held
            .iter()
            .filter_map(|h| h.far.as_ref().map(|f| (f, h)))
            .flat_map(|(f, h)| f.springs.iter().zip(&h.masses))
            .map(|(k, m)| (k[0].max(k[1]) / m).sqrt())
            .fold(0.0, f64::max)
    }

    /// Checks that the far-field springs are stable at the time step `dt`: each spring
    /// alone (`sqrt(k / m)`, both directions) is at most a quarter of the explicit limit,
    /// `dt sqrt(k / m) <= 0.5` (`dt = "auto"` takes at most that step). The error names
    /// the face's `distance`.
    pub fn check_far_field(&self, dt: f64) -> Result<(), SceneError> {
        for h in &self.held {
            let Some(f) = &h.far else { continue };
            let worst = f
                .springs
                .iter()
                .zip(&h.masses)
                .map(|(k, m)| k[0].max(k[1]) / m)
                .fold(0.0, f64::max);
            if dt * worst.sqrt() > 0.5 * (1.0 + 1e-6) {
                return Err(SceneError::invalid(
                    f.key.clone(),
                    format!(
                        "makes the face's springs too stiff for the time step {dt:e} s (a \
                         node's spring frequency times the step is {:.2}, at most 0.5): give a \
                         larger distance or a shorter step",
                        dt * worst.sqrt()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Adds the far-field faces' spring and dashpot forces to the forces (call after
    /// [`Boundary::apply_loads`], right before `integrate` with the parameters `p`); the
    /// dashpots are implicit with the step (module docs).
    pub fn apply_far_field(&self, b: &mut dyn Backend, p: &StepParams) -> Result<(), SimError> {
        let (dt, d) = (p.dt as f64, p.damping_factor as f64);
        let g = DVec3::from(p.gravity.map(|g| g as f64));
        for h in &self.held {
            let Some(far) = &h.far else { continue };
            let s = h.read_far(b, true)?;
            let mut f = s.force.clone();
            for k in 0..h.nodes.len() {
                let w = s.inv_mass[k];
                // A node another set holds in all components does not move: no force (it
                // would only bias that set's reaction).
                if w == 0.0 {
                    continue;
                }
                let force = DVec3::new(f[k][0] as f64, f[k][1] as f64, f[k][2] as f64);
                let spring = h.far_spring(far, k, s.position[k] - DVec3::from(h.rest[k]));
                // The velocity the step would reach without the dashpots (zero at rest,
                // where the springs balance the rest).
                let v_star = s.velocity[k] + dt * ((force + spring) * w + g);
                let (vn, vt) = normal_tangent(DVec3::from(far.normals[k]), v_star);
                let [cn, ct] = far.dashpots[k];
                let implicit = |c: f64| c * d / (1.0 + d * dt * c * w);
                let add = spring - implicit(cn) * vn - implicit(ct) * vt;
                for a in 0..3 {
                    f[k][a] = (force[a] + add[a]) as f32;
                }
            }
            write_scattered(b, NodeField::Force, &h.nodes, &f)?;
        }
        Ok(())
    }

    /// Adds the loads at time `t` to the forces (call between `compute_forces` and
    /// `integrate`).
    pub fn apply_loads(&self, b: &mut dyn Backend, t: f64) -> Result<(), SimError> {
        for l in &self.loads {
            let s = if l.ramp > 0.0 {
                (t / l.ramp).min(1.0)
            } else {
                1.0
            };
            let mut f = vec![[0.0f32; 4]; l.nodes.len()];
            b.read_nodes(NodeField::Force, &l.nodes, &mut f)?;
            for (f, add) in f.iter_mut().zip(&l.forces) {
                for a in 0..3 {
                    f[a] = (f[a] as f64 + s * add[a]) as f32;
                }
            }
            write_scattered(b, NodeField::Force, &l.nodes, &f)?;
        }
        Ok(())
    }

    /// Sets the held components of position and velocity to their values at time `t`
    /// (call after `integrate`, with the time the step reached).
    ///
    /// A held component is written as the backend stores positions
    /// ([`NodeField::StoredPosition`], in its frame, [`crate::frame`]): its f32 value and
    /// the remainder below it, and the free components of the same node keep theirs. So a
    /// prescribed position is exact to the body's own f32 spacing (the forces see it) and
    /// below, wherever the body is. (Writing world f32 positions was off by up to half a
    /// world spacing, 3.7e-9 m at 0.1 m from the origin and 6e-8 m at 1 m, and cleared the
    /// free components' remainders.)
    pub fn project(&self, b: &mut dyn Backend, t: f64) -> Result<(), SimError> {
        let origin = b.position_frame().origin();
        for h in self.held.iter().filter(|h| h.projected()) {
            let u = h.motion.map_or([0.0; 3], |m| m.displacement(t));
            let v = h.motion.map_or([0.0; 3], |m| m.velocity(t));
            let n = h.nodes.len();
            let mut p = vec![[0.0f32; 4]; n];
            let mut vel = vec![[0.0f32; 4]; n];
            let mut rem = vec![[0.0f32; 4]; n];
            let list = NodeSelection::List(&h.nodes);
            b.read_many(
                &[
                    (NodeField::StoredPosition, list.clone()),
                    (NodeField::Velocity, list.clone()),
                    (NodeField::StoredRemainder, list),
                ],
                &mut [&mut p, &mut vel, &mut rem],
            )?;
            for k in 0..n {
                for a in (0..3).filter(|&a| h.components[a]) {
                    let x = h.rest[k][a] + u[a] - origin[a];
                    p[k][a] = x as f32;
                    rem[k][a] = (x - p[k][a] as f64) as f32;
                    vel[k][a] = v[a] as f32;
                }
            }
            write_scattered(b, NodeField::StoredPosition, &h.nodes, &p)?;
            write_scattered(b, NodeField::StoredRemainder, &h.nodes, &rem)?;
            write_scattered(b, NodeField::Velocity, &h.nodes, &vel)?;
        }
        Ok(())
    }

    /// The reaction of every held set from the forces of the last step.
    pub fn reactions(
        &self,
        b: &mut dyn Backend,
        gravity: [f64; 3],
    ) -> Result<Vec<Reaction>, SimError> {
        let mut out = Vec::with_capacity(self.held.len());
        for h in &self.held {
            if let Some(far) = &h.far {
                let s = h.read_far(b, false)?;
                let r: DVec3 = (0..h.nodes.len())
                    .filter(|&k| s.inv_mass[k] != 0.0)
                    .map(|k| h.far_force(far, k, &s))
                    .sum();
                out.push(Reaction {
                    name: h.name.clone(),
                    force: r.to_array(),
                });
                continue;
            }
            let mut f = vec![[0.0f32; 4]; h.nodes.len()];
            b.read_nodes(NodeField::Force, &h.nodes, &mut f)?;
            let mut r = [0.0; 3];
            for (f, m) in f.iter().zip(&h.masses) {
                for a in (0..3).filter(|&a| h.components[a]) {
                    r[a] -= f[a] as f64 + m * gravity[a];
                }
            }
            out.push(Reaction {
                name: h.name.clone(),
                force: r,
            });
        }
        Ok(out)
    }
}

/// Writes `data[k]` to node `nodes[k]` (sorted), one transfer per run of consecutive
/// indices.
pub fn write_scattered(
    b: &mut dyn Backend,
    field: NodeField,
    nodes: &[u32],
    data: &[[f32; 4]],
) -> Result<(), SimError> {
    let mut start = 0;
    while start < nodes.len() {
        let mut end = start + 1;
        while end < nodes.len() && nodes[end] == nodes[end - 1] + 1 {
            end += 1;
        }
        b.write(field, nodes[start] as usize, &data[start..end])?;
        start = end;
    }
    Ok(())
}
