//! What one picture shows, copied out of a simulation (or built by hand): node positions,
//! surface triangles, the needle pose, the needle node markers and the force-depth curve.

use crate::ViewError;
use needlesim_core::NodeField;
use needlesim_needle::{NodeRole, PunctureState, Simulation};

/// Most points of the force-depth curve kept in a frame; longer histories are thinned
/// evenly (the latest sample is always kept).
pub const MAX_PLOT_POINTS: usize = 4096;

/// A needle node to mark.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Marker {
    /// Position, m.
    pub position: [f32; 3],
    /// Its role (sets the colour).
    pub role: NodeRole,
}

/// Everything one picture needs, independent of the simulation.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Frame {
    /// Positions of the active nodes, m.
    pub positions: Vec<[f32; 3]>,
    /// Surface triangles, as indices into `positions` (out-of-range ones are skipped).
    pub triangles: Vec<[u32; 3]>,
    /// The tissue region of each position (colours of [`crate::colors::region`]); region 0
    /// for the positions past its end (empty: one tissue).
    pub regions: Vec<u16>,
    /// The needle as (base, tip), m, if the scene has one.
    pub needle: Option<([f32; 3], [f32; 3])>,
    /// The needle nodes.
    pub markers: Vec<Marker>,
    /// The force-depth curve: (tip depth past the entry point, m; axial force, N), oldest
    /// first.
    pub force_depth: Vec<[f32; 2]>,
    /// Simulated time, s.
    pub time: f64,
    /// The puncture state, if the scene has a needle.
    pub state: Option<PunctureState>,
}

impl Frame {
    /// Copies the current state of `sim`: positions of its active nodes (one read from
    /// the backend), its surface triangles, needle pose and nodes, and its needle history
    /// as force against depth ([`Simulation::depth_of`]), thinned to [`MAX_PLOT_POINTS`].
    pub fn gather(sim: &mut Simulation) -> Result<Frame, ViewError> {
        let n = sim.backend().n_active();
        let mut raw = vec![[0.0f32; 4]; n];
        sim.backend().read(NodeField::Position, 0..n, &mut raw)?;
        let positions: Vec<[f32; 3]> = raw.iter().map(|p| [p[0], p[1], p[2]]).collect();
        let markers = sim
            .needle_nodes()
            .iter()
            .filter_map(|node| {
                positions.get(node.index as usize).map(|&p| Marker {
                    position: p,
                    role: node.role,
                })
            })
            .collect();
        // Mesh nodes, then the needle nodes (a split surface triangle names the Surface
        // node), each with its region.
        let mut regions = sim.node_regions().to_vec();
        regions.resize(sim.editor().n_mesh(), 0);
        regions.extend(sim.needle_nodes().iter().map(|node| node.region));
        let needle = sim.needle().map(|nd| (f32x3(nd.base()), f32x3(nd.tip())));
        let history = sim.history();
        let stride = history.len().div_ceil(MAX_PLOT_POINTS).max(1);
        let mut force_depth: Vec<[f32; 2]> = history
            .iter()
            .step_by(stride)
            .map(|s| {
                [
                    sim.depth_of(s.tip, s.direction) as f32,
                    s.force.axial as f32,
                ]
            })
            .collect();
        if let Some(last) = history.last() {
            if !(history.len() - 1).is_multiple_of(stride) {
                force_depth.push([
                    sim.depth_of(last.tip, last.direction) as f32,
                    last.force.axial as f32,
                ]);
            }
        }
        Ok(Frame {
            regions,
            positions,
            triangles: sim.triangles().to_vec(),
            needle,
            markers,
            force_depth,
            time: sim.time(),
            state: sim.needle().map(|_| sim.state()),
        })
    }

    /// The axis-aligned box of the nodes that triangles use and of the needle, as
    /// (min, max); `None` when there is nothing to draw.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        let mut any = false;
        let mut add = |p: [f32; 3]| {
            if p.iter().all(|c| c.is_finite()) {
                any = true;
                for k in 0..3 {
                    lo[k] = lo[k].min(p[k]);
                    hi[k] = hi[k].max(p[k]);
                }
            }
        };
        for t in &self.triangles {
            for &i in t {
                if let Some(&p) = self.positions.get(i as usize) {
                    add(p);
                }
            }
        }
        if self.triangles.is_empty() {
            self.positions.iter().for_each(|&p| add(p));
        }
        if let Some((b, t)) = self.needle {
            add(b);
            add(t);
        }
        any.then_some((lo, hi))
    }
}

fn f32x3(p: [f64; 3]) -> [f32; 3] {
    [p[0] as f32, p[1] as f32, p[2] as f32]
}
