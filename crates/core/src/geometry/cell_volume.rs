//! Cell volumes of a node set inside a closed surface: for each node, the volume of the
//! part of the body nearer to it than to any other node (its Voronoi cell clipped to the
//! body), estimated by sub-sampling.
//!
//! Every lattice spacing `h` is divided into `SUBDIVISION` sub-points along each axis;
//! every sub-point inside the surface ([`super::ray_columns`]) adds `(h / s)^3` to its
//! nearest node. A node that no sub-point reaches (a surface vertex at a sharp tip) gets
//! one sub-cell, so that no node is massless. The estimates are finally scaled to add up
//! to the enclosed volume, which removes the O(h / s) sampling error of the total.

use super::lattice::Lattice;
use super::ray_columns::ColumnCrossings;

/// Sub-points per lattice spacing along each axis (even, so that no sub-point falls on
/// the mid-plane between two lattice points).
pub const SUBDIVISION: usize = 4;

/// Cell volume of every node of `nodes`, scaled to add up to `total_volume`.
/// `triangles` are the surface triangles as corner coordinates; the sub-points fill the
/// cubes of side `h` centred on the points of `lattice`.
pub fn estimate(
    nodes: &[[f64; 3]],
    triangles: &[[[f64; 3]; 3]],
    lattice: &Lattice,
    total_volume: f64,
) -> Vec<f64> {
    let grid = NodeGrid::new(nodes, lattice.spacing);
    let s = SUBDIVISION;
    let h = lattice.spacing;
    let sub = h / s as f64;
    let origin: [f64; 3] = std::array::from_fn(|a| lattice.origin[a] - 0.5 * h + 0.5 * sub);
    let [nx, ny, nz] = lattice.dims.map(|n| n * s);
    let columns = ColumnCrossings::build(triangles, [origin[0], origin[1]], sub, nx, ny);
    let mut count = vec![0u64; nodes.len()];
    for j in 0..ny {
        for i in 0..nx {
            for (k, inside) in columns
                .inside_column(i, j, origin[2], sub, nz)
                .into_iter()
                .enumerate()
            {
                if inside {
                    let p = [i as f64, j as f64, k as f64];
                    let p: [f64; 3] = std::array::from_fn(|a| origin[a] + p[a] * sub);
                    if let Some(n) = grid.nearest(nodes, p) {
                        count[n] += 1;
                    }
                }
            }
        }
    }
    for c in &mut count {
        *c = (*c).max(1);
    }
    let sampled: f64 = count.iter().map(|&c| c as f64).sum::<f64>() * sub.powi(3);
    let scale = if sampled > 0.0 {
        total_volume / sampled
    } else {
        0.0
    };
    count
        .iter()
        .map(|&c| c as f64 * sub.powi(3) * scale)
        .collect()
}

/// Nodes binned in cubes of side `h`, for nearest-node queries.
struct NodeGrid {
    lo: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    bins: Vec<Vec<u32>>,
}

impl NodeGrid {
    /// Cells of side `cell`, widened so that there are at most about two cells per node:
    /// a body far larger than its nodes' spacing (a thin spike of a surface with few
    /// vertices) would otherwise make every query walk a vast empty grid.
    fn new(nodes: &[[f64; 3]], cell: f64) -> NodeGrid {
        let (lo, hi) = super::bounds(nodes);
        let cells = (0..3)
            .map(|a| ((hi[a] - lo[a]) / cell).max(0.0) + 1.0)
            .product::<f64>();
        let most = 2.0 * nodes.len().max(4) as f64;
        let cell = if cells > most {
            cell * (cells / most).cbrt()
        } else {
            cell
        };
        let dims: [usize; 3] =
            std::array::from_fn(|a| ((hi[a] - lo[a]) / cell).floor().max(0.0) as usize + 1);
        let mut bins = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        let mut grid = NodeGrid {
            lo,
            cell,
            dims,
            bins: Vec::new(),
        };
        for (n, p) in nodes.iter().enumerate() {
            let c = grid.cell_of(*p);
            bins[grid.flat(c)].push(n as u32);
        }
        grid.bins = bins;
        grid
    }

    fn cell_of(&self, p: [f64; 3]) -> [i64; 3] {
        std::array::from_fn(|a| {
            (((p[a] - self.lo[a]) / self.cell).floor() as i64).clamp(0, self.dims[a] as i64 - 1)
        })
    }

    fn flat(&self, c: [i64; 3]) -> usize {
        c[0] as usize + self.dims[0] * (c[1] as usize + self.dims[1] * c[2] as usize)
    }

    /// Index of the node nearest to `p` (the lowest index on a tie), searching shells of
    /// cells outwards until no closer node can remain.
    fn nearest(&self, nodes: &[[f64; 3]], p: [f64; 3]) -> Option<usize> {
        let c = self.cell_of(p);
        let max_r = *self.dims.iter().max()? as i64;
        let mut best: Option<(f64, usize)> = None;
        for r in 0..=max_r {
            if let Some((d2, _)) = best {
                // Every node in shell r is at least (r - 1) cells away from p.
                let gap = (r - 1).max(0) as f64 * self.cell;
                if gap * gap > d2 {
                    break;
                }
            }
            // The shell's offsets, clipped to the grid (a long thin grid is not walked
            // through its whole cube of offsets).
            let span = |a: usize| (-r).max(-c[a])..=r.min(self.dims[a] as i64 - 1 - c[a]);
            for dz in span(2) {
                for dy in span(1) {
                    let full_row = dz.abs() == r || dy.abs() == r;
                    for dx in span(0) {
                        if !full_row && dx.abs() != r {
                            continue;
                        }
                        let q = [c[0] + dx, c[1] + dy, c[2] + dz];
                        for &n in &self.bins[self.flat(q)] {
                            let d2 = glam::DVec3::from(nodes[n as usize])
                                .distance_squared(glam::DVec3::from(p));
                            let better = match best {
                                None => true,
                                Some((bd, bn)) => d2 < bd || (d2 == bd && (n as usize) < bn),
                            };
                            if better {
                                best = Some((d2, n as usize));
                            }
                        }
                    }
                }
            }
        }
        best.map(|b| b.1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::box_lattice::BoxLattice;

    /// On a box whose nodes are a lattice aligned with the sampling lattice the estimate
    /// reproduces the exact cells (h^3, halved on each face) to sampling accuracy.
    #[test]
    fn lattice_nodes_in_a_box_get_the_trapezoid_cells() {
        let l = BoxLattice::with_spacing([0.0; 3], [0.04, 0.03, 0.05], 0.01);
        let c = l.cloud();
        let tris = c.triangle_corners();
        let lattice = Lattice {
            origin: [0.0; 3],
            dims: l.dims,
            spacing: 0.01,
        };
        let v = estimate(&c.positions, &tris, &lattice, c.volume);
        let total: f64 = v.iter().sum();
        assert!((total - c.volume).abs() < 1e-12 * c.volume);
        // No sub-point lies on a face or on a mid-plane between two nodes (even
        // subdivision), so each cell is exact.
        for (n, (got, want)) in v.iter().zip(&c.node_volumes).enumerate() {
            assert!(
                (got - want).abs() < 1e-9 * want,
                "node {n}: {got} vs {want}"
            );
        }
    }
}
