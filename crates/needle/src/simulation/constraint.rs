//! Needle node constraints (paper section 5.4): a node held rigidly on the needle (the
//! pinned Exit node while Touching the far surface; with the paper's friction model also a
//! sticking node and the pinned Surface node) moves with it, its velocity the needle's at
//! its axial coordinate; every other needle node is projected onto the shaft and keeps only
//! its own axial velocity relative to the needle. With the per-length model the axial
//! motion is the sheath's business ([`crate::sheath`]): no node is held axially.

use super::{at, vec4, xyz, Simulation};
use crate::friction::FrictionState;
use crate::needle::Needle;
use crate::nodes::{NeedleNode, NodeRole};
use crate::state::Passage;
use glam::DVec3;
use needlesim_core::{NodeField, SimError};

impl Simulation {
    /// Whether the per-length friction model's sheath couples the needle nodes axially
    /// ([`crate::sheath`]); else the paper's model holds sticking nodes rigidly.
    pub(super) fn sheathed(&self) -> bool {
        self.params.per_length().is_some()
    }

    /// Whether node `n` is held rigidly on the needle this step.
    pub(super) fn kinematic(&self, n: &NeedleNode) -> bool {
        self.pinned(n)
            || (!self.sheathed() && (n.friction == FrictionState::Stick || n.role == NodeRole::Tip))
    }

    /// The Exit node while Touching the far surface, and with the paper's friction model
    /// the Surface node while Touching the entry: pinned to the tip in every direction.
    /// (With the per-length model the entry's load goes into the contact patch.)
    pub(super) fn pinned(&self, n: &NeedleNode) -> bool {
        (n.role == NodeRole::Surface && self.state.phase == Passage::Touching && !self.sheathed())
            || (n.role == NodeRole::Exit && self.state.phase == Passage::ExitTouching)
    }

    /// The divergence guard on the sliding needle nodes, whose positions `p` and
    /// velocities `v` are read back every step anyway: a node flung along the shaft (an
    /// unstable friction or contact force acts on these light nodes first) stops the run
    /// at once with [`SimError::Diverged`] or [`SimError::Runaway`], instead of at the
    /// next `physics.check_every` step after rows of huge forces were recorded.
    fn guard_sliding(&self, p: &[[f32; 4]], v: &[[f32; 4]]) -> Result<(), SimError> {
        let step = self.stepper.steps();
        let n0 = self.editor.n_mesh();
        let limit = self.stepper.max_speed();
        for (k, node) in self.state.nodes.iter().enumerate() {
            if self.kinematic(node) {
                continue;
            }
            let node = n0 + k;
            for (x, field) in [(p[k], "position"), (v[k], "velocity")] {
                if !x[..3].iter().all(|c| c.is_finite()) {
                    return Err(SimError::Diverged { step, node, field });
                }
            }
            let speed = xyz(v[k]).length();
            if speed > limit {
                return Err(SimError::Runaway {
                    step,
                    node,
                    speed,
                    limit,
                });
            }
        }
        Ok(())
    }

    /// Puts sticking nodes on the needle and slipping nodes onto the shaft.
    pub(super) fn constrain(&mut self, prev: &Needle, now: &Needle) -> Result<(), SimError> {
        let m = self.state.nodes.len();
        self.state.velocities.clear();
        if m == 0 {
            return Ok(());
        }
        let n0 = self.editor.n_mesh();
        let mut v = vec![[0.0f32; 4]; m];
        // Only sliding nodes need their own state; sticking ones follow the needle. The
        // positions (and, without node edits, the velocities) come from the contact
        // update when it read them this step; else both are read in one readback.
        let mut p = std::mem::take(&mut self.state.positions);
        let known = std::mem::take(&mut self.state.read_velocities);
        if self.state.nodes.iter().any(|n| !self.kinematic(n)) {
            if p.len() != m {
                if let Some((pi, vi)) = self.take_integrated() {
                    (p, v) = (pi, vi);
                } else {
                    p = vec![[0.0f32; 4]; m];
                    self.backend.read_many(
                        &[
                            (NodeField::Position, (n0..n0 + m).into()),
                            (NodeField::Velocity, (n0..n0 + m).into()),
                        ],
                        &mut [&mut p, &mut v],
                    )?;
                }
            } else if known.len() == m {
                v = known;
            } else {
                self.backend.read(NodeField::Velocity, n0..n0 + m, &mut v)?;
            }
        } else {
            p = vec![[0.0f32; 4]; m];
        }
        self.guard_sliding(&p, &v)?;
        let (t, base) = (DVec3::from(now.direction()), DVec3::from(now.base()));
        for k in 0..m {
            let node = self.state.nodes[k];
            if self.kinematic(&node) {
                let x = at(now, node.s);
                let vn = self.needle_velocity(prev, now, node.s);
                p[k] = vec4(x, 0.0);
                v[k] = vec4(vn, 0.0);
            } else {
                let s = (xyz(p[k]) - base).dot(t);
                let x = at(now, s);
                let vn = self.needle_velocity(prev, now, s);
                let own = xyz(v[k]).dot(t) - vn.dot(t);
                p[k] = vec4(x, self.inv_mass_of(&node));
                v[k] = vec4(vn + t * own, 0.0);
            }
        }
        self.backend.write(NodeField::Position, n0, &p)?;
        self.backend.write(NodeField::Velocity, n0, &v)?;
        self.state.velocities = v;
        self.state.positions = p;
        Ok(())
    }
}
