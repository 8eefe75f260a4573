//! What a scene builds: node counts, neighbour statistics and the bytes of every array.

use needlesim_core::models::ArrayInfo;
use needlesim_core::neighbours::NeighbourStats;
use needlesim_core::{Scene, SceneError, Tissue};
use std::fmt;

/// Summary of a built scene.
#[derive(Debug, Clone)]
pub struct SceneInfo {
    /// Scene name.
    pub name: String,
    /// Model short name.
    pub model: &'static str,
    /// What the model cannot represent of an isotropic solid, if anything
    /// ([`needlesim_core::models::TissueModel::limitation`]).
    pub limitation: Option<&'static str>,
    /// The viscoelastic relaxation function, written out (`None`: elastic).
    pub viscoelastic: Option<String>,
    /// Mesh nodes.
    pub nodes: usize,
    /// Allocated node slots.
    pub capacity: usize,
    /// Fixed nodes.
    pub fixed: usize,
    /// Surface triangles.
    pub triangles: usize,
    /// Node bounds (min, max) in m.
    pub bounds: ([f64; 3], [f64; 3]),
    /// Origin of the frame the positions are stored in, m ([`needlesim_core::frame`]):
    /// zero for a body within about its size of the origin.
    pub frame_origin: [f64; 3],
    /// Smallest, mean and largest node mass in kg.
    pub node_masses: [f64; 3],
    /// Total mass of the mesh nodes in kg.
    pub mass: f64,
    /// Volume in m^3.
    pub volume: f64,
    /// Smallest, mean and largest node volume `V_i` in m^3 (continuum models only).
    pub node_volumes: Option<[f64; 3]>,
    /// Neighbour slots per node.
    pub k: usize,
    /// Neighbour statistics.
    pub neighbours: NeighbourStats,
    /// Every simulation array.
    pub arrays: Vec<ArrayInfo>,
}

/// `g(t) = g_inf + g_1 exp(-t / tau_1 s) + ...` and what it means for the moduli.
fn relaxation_text(p: &needlesim_core::models::viscoelastic::Prony) -> Option<String> {
    if p.is_empty() {
        return None;
    }
    let terms: Vec<String> = p
        .terms()
        .iter()
        .map(|t| format!("{} exp(-t / {} s)", t.g, t.tau))
        .collect();
    Some(format!(
        "g(t) = {:.4} + {}: the moduli are the instantaneous ones and relax to {:.4} of them",
        p.g_inf(),
        terms.join(" + "),
        p.g_inf()
    ))
}

fn min_mean_max(v: &[f64]) -> [f64; 3] {
    let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
    let min = v.iter().cloned().fold(f64::INFINITY, f64::min);
    let max = v.iter().cloned().fold(0.0, f64::max);
    [min, mean, max]
}

impl SceneInfo {
    /// Builds the scene's tissue (with its needle node slots, if it has a needle) and
    /// summarises it.
    pub fn of(scene: &Scene) -> Result<SceneInfo, SceneError> {
        use needlesim_needle::{Simulation, SimulationError};
        let prep = Simulation::prepare(scene).map_err(|e| match e {
            SimulationError::Scene(s) => s,
            other => SceneError::invalid("needle", other.to_string()),
        })?;
        Ok(Self::of_tissue(scene, &prep.tissue))
    }

    /// Summarises an already built tissue.
    pub fn of_tissue(scene: &Scene, t: &Tissue) -> SceneInfo {
        let n = t.n_mesh;
        // In world coordinates: the tissue keeps its positions in its frame.
        let rest: Vec<[f64; 3]> = t.state.positions[..n]
            .iter()
            .map(|p| t.frame.global([p[0], p[1], p[2]]))
            .collect();
        SceneInfo {
            name: scene.name.clone(),
            model: scene.material.short_name(),
            limitation: scene.material.limitation(),
            viscoelastic: relaxation_text(&scene.material.prony()),
            nodes: n,
            capacity: t.state.capacity(),
            fixed: t.n_fixed,
            triangles: t.triangles.len(),
            bounds: needlesim_core::geometry::bounds(&rest),
            frame_origin: t.frame.origin(),
            node_masses: min_mean_max(&t.masses),
            mass: t.masses.iter().sum(),
            volume: t.volume,
            node_volumes: t.shape.node_volumes(n).map(|v| {
                let v: Vec<f64> = v.iter().map(|&x| x as f64).collect();
                min_mean_max(&v)
            }),
            k: t.neighbours.k,
            neighbours: t.neighbours.stats(n),
            arrays: t.allocations(),
        }
    }

    /// Total bytes of all arrays.
    pub fn total_bytes(&self) -> usize {
        self.arrays.iter().map(|a| a.bytes).sum()
    }

    /// Bytes per allocated node (all arrays over the capacity, which includes the room
    /// kept for needle nodes): what one more node of this model and K costs.
    pub fn bytes_per_node(&self) -> f64 {
        self.total_bytes() as f64 / self.capacity.max(1) as f64
    }
}

impl fmt::Display for SceneInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (lo, hi) = self.bounds;
        writeln!(
            f,
            "scene      {}",
            if self.name.is_empty() {
                "(unnamed)"
            } else {
                &self.name
            }
        )?;
        writeln!(f, "model      {}", self.model)?;
        if let Some(l) = self.limitation {
            writeln!(f, "           note: {l}")?;
        }
        if let Some(v) = &self.viscoelastic {
            writeln!(f, "relaxation {v}")?;
        }
        writeln!(
            f,
            "nodes      {} (capacity {}, fixed {})",
            self.nodes, self.capacity, self.fixed
        )?;
        writeln!(f, "surface    {} triangles", self.triangles)?;
        writeln!(
            f,
            "bounds     [{:.4}, {:.4}, {:.4}] .. [{:.4}, {:.4}, {:.4}] m",
            lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
        )?;
        if self.frame_origin != [0.0; 3] {
            let o = self.frame_origin;
            writeln!(
                f,
                "frame      positions stored relative to [{}, {}, {}] m (far from the origin)",
                o[0], o[1], o[2]
            )?;
        }
        let [lo, mean, hi] = self.node_masses;
        writeln!(
            f,
            "volume     {:.4e} m^3, mass {:.4e} kg (node min {lo:.4e} mean {mean:.4e} max {hi:.4e} kg)",
            self.volume, self.mass
        )?;
        if let Some([min, mean, max]) = self.node_volumes {
            writeln!(
                f,
                "node volumes min {min:.4e} mean {mean:.4e} max {max:.4e} m^3"
            )?;
        }
        let s = &self.neighbours;
        writeln!(
            f,
            "neighbours K = {}: live per node min {} mean {:.2} max {}, {} broken (non-mutual) slots, min weight {:.3}",
            self.k, s.min, s.mean, s.max, s.broken, s.min_weight
        )?;
        writeln!(f, "arrays")?;
        for a in &self.arrays {
            writeln!(f, "  {:<18} {:>12} bytes", a.name, a.bytes)?;
        }
        writeln!(f, "  {:<18} {:>12} bytes", "total", self.total_bytes())?;
        write!(
            f,
            "  {:<18} {:>12.1} bytes ({} allocated nodes)",
            "per node",
            self.bytes_per_node(),
            self.capacity
        )
    }
}
