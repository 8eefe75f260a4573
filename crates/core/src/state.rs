//! Node state in structure-of-arrays form, one `[f32; 4]` per vector, the same bytes on the
//! CPU and the GPU.
//!
//! Arrays are allocated once at `capacity = n_mesh + n_needle_max` nodes; only the first
//! `n_active` are simulated. The w lane of a position holds the node's inverse mass
//! (0 for a fixed node, which never moves); the w lanes of velocities and forces are 0.

use crate::math::Vec4;

/// Positions, velocities and forces of all allocated nodes.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeState {
    /// Nodes simulated (the first `n_active` of the arrays).
    pub n_active: usize,
    /// Positions in metres; w = inverse mass in 1/kg (0 = fixed).
    pub positions: Vec<Vec4>,
    /// Velocities in m/s.
    pub velocities: Vec<Vec4>,
    /// Elastic forces of the last force evaluation, in newtons.
    pub forces: Vec<Vec4>,
    /// The part of each position below f32 resolution, in metres (w = 0): the
    /// integrator's compensated sum ([`crate::integrator`]).
    pub position_remainders: Vec<Vec4>,
}

impl NodeState {
    /// State with `capacity` slots of which the first `positions.len()` are active and at
    /// rest.
    pub fn new(positions: Vec<Vec4>, capacity: usize) -> NodeState {
        let n = positions.len();
        assert!(capacity >= n);
        let mut p = positions;
        p.resize(capacity, [0.0; 4]);
        NodeState {
            n_active: n,
            positions: p,
            velocities: vec![[0.0; 4]; capacity],
            forces: vec![[0.0; 4]; capacity],
            position_remainders: vec![[0.0; 4]; capacity],
        }
    }

    /// Allocated node slots.
    pub fn capacity(&self) -> usize {
        self.positions.len()
    }

    /// Kinetic energy `sum m |v|^2 / 2` of the active free nodes, in joules.
    pub fn kinetic_energy(&self) -> f64 {
        (0..self.n_active)
            .filter(|&i| self.positions[i][3] > 0.0)
            .map(|i| {
                let v = self.velocities[i];
                let m = 1.0 / self.positions[i][3] as f64;
                0.5 * m
                    * (v[0] as f64 * v[0] as f64
                        + v[1] as f64 * v[1] as f64
                        + v[2] as f64 * v[2] as f64)
            })
            .sum()
    }
}
