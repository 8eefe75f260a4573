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
//! - reactions: the force the supports exert on the body, `R = -sum_i (f_i + m_i g)` over a
//!   set's held components (zero in its free ones), `f_i` the forces of the last step.
//!   At rest it balances the loads and the weight.

use crate::backend::{Backend, NodeField, NodeSelection};
use crate::error::SimError;
use crate::scene::Motion;

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
        }
    }

    /// Whether the set needs work after each step (everything but a set held at rest in
    /// all components).
    fn projected(&self) -> bool {
        self.motion.is_some() || !self.kinematic
    }
}

impl Boundary {
    /// Whether the step needs this module (a projection or a load); sets held at rest in
    /// all components need nothing once their inverse mass is 0.
    pub fn acts_each_step(&self) -> bool {
        !self.loads.is_empty() || self.held.iter().any(HeldSet::projected)
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
