//! Neighbour lists: K slots per node, a `u32` index and an `f32` weight per slot, stored
//! row-major (`index[i * K + s]`).
//!
//! Construction: the K nearest nodes of every node (uniform-grid search, ties broken by the
//! smaller index so the result is deterministic), weights from the scene's kernel (its
//! length from the median neighbour distance, [`kernel_length`]), then the
//! paper's mutuality rule (section 5.1 and its footnote): a pair that is not in both lists
//! gets weight 0 in the list that holds it. A weight of 0 marks an empty or broken slot;
//! every model skips such slots, so a mutual pair always acts on both of its nodes.
//!
//! The k-nearest search is a hand-written uniform grid rather than a spatial-index crate
//! (a k-d tree such as kiddo or rstar): those order equidistant candidates arbitrarily or
//! by index, and the point-symmetric tie-break of `closer` is what keeps lattice
//! neighbourhoods symmetric (see there).

use crate::scene::WeightKernel;
use glam::DVec3;

/// Fewest live neighbours (non-zero weight) a mesh node must keep. With none it feels no
/// elastic force and leaves the body; [`crate::tissue::Tissue::from_cloud`] refuses such a
/// scene. One or two live neighbours hold a node loosely (a pendulum on its springs, a
/// rank-deficient moment matrix, which the continuum models pseudo-invert); the tips of a
/// coarse surface kept with `surface = "vertices"` and `neighbours = 6` have one.
pub const MIN_LIVE_NEIGHBOURS: usize = 1;

/// A node with fewer than [`MIN_LIVE_NEIGHBOURS`] live neighbours.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoorNode {
    /// The node.
    pub node: usize,
    /// Its live slots (non-zero weight).
    pub live: usize,
    /// Its slots whose neighbour lists it back (live, or zero only by the kernel's support
    /// or f32 rounding).
    pub mutual: usize,
}

/// Neighbour rows of all allocated nodes.
#[derive(Debug, Clone, PartialEq)]
pub struct Neighbours {
    /// Slots per node.
    pub k: usize,
    /// Neighbour index per slot (`capacity * k`).
    pub index: Vec<u32>,
    /// Weight per slot; 0 marks an empty or broken slot (`capacity * k`).
    pub weight: Vec<f32>,
}

/// Summary of the neighbour lists.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeighbourStats {
    /// Fewest non-zero slots of a node.
    pub min: usize,
    /// Most non-zero slots of a node.
    pub max: usize,
    /// Mean non-zero slots per node.
    pub mean: f64,
    /// Slots with zero weight (non-mutual pairs dropped).
    pub broken: usize,
    /// Smallest non-zero weight.
    pub min_weight: f32,
}

impl Neighbours {
    /// Builds K-nearest neighbour lists with weights and the mutuality rule for `points`,
    /// with rows for `capacity >= points.len()` nodes (extra rows empty).
    pub fn build(
        points: &[[f64; 3]],
        k: usize,
        kernel: WeightKernel,
        capacity: usize,
    ) -> Neighbours {
        let n = points.len();
        assert!(k < n, "need more nodes than neighbours per node");
        let grid = UniformGrid::new(points, k);
        let mut index = vec![0u32; capacity * k];
        let mut dist = vec![0f64; n * k];
        let mut scratch = Vec::new();
        for i in 0..n {
            grid.k_nearest(points, points[i], k, Some(i), &mut scratch);
            for (s, &(d2, j)) in scratch.iter().enumerate() {
                index[i * k + s] = j;
                dist[i * k + s] = d2.sqrt();
            }
        }
        let dk: Vec<f64> = (0..n)
            .map(|i| kernel_length(&mut dist[i * k..(i + 1) * k].to_vec()))
            .collect();
        let mut weight = vec![0f32; capacity * k];
        for i in 0..n {
            for s in 0..k {
                let j = index[i * k + s] as usize;
                let mutual = index[j * k..(j + 1) * k].contains(&(i as u32));
                if mutual {
                    weight[i * k + s] = kernel_weight(kernel, dist[i * k + s], dk[i], dk[j]) as f32;
                }
            }
        }
        Neighbours { k, index, weight }
    }

    /// The slots of node `i`: `(indices, weights)`.
    #[inline(always)]
    pub fn row(&self, i: usize) -> (&[u32], &[f32]) {
        (
            &self.index[i * self.k..(i + 1) * self.k],
            &self.weight[i * self.k..(i + 1) * self.k],
        )
    }

    /// The live slots of node `i` (weight not 0): `(slot, neighbour, weight)`, `slot` the
    /// index into the flat `capacity * K` arrays.
    #[inline(always)]
    pub fn live(&self, i: usize) -> impl Iterator<Item = (usize, usize, f32)> + '_ {
        (i * self.k..(i + 1) * self.k).filter_map(move |slot| {
            let w = self.weight[slot];
            (w != 0.0).then(|| (slot, self.index[slot] as usize, w))
        })
    }

    /// Statistics over the first `n` nodes.
    pub fn stats(&self, n: usize) -> NeighbourStats {
        let mut st = NeighbourStats {
            min: usize::MAX,
            max: 0,
            mean: 0.0,
            broken: 0,
            min_weight: f32::INFINITY,
        };
        for i in 0..n {
            let (_, w) = self.row(i);
            let live = w.iter().filter(|&&x| x != 0.0).count();
            st.min = st.min.min(live);
            st.max = st.max.max(live);
            st.mean += live as f64;
            st.broken += self.k - live;
            for &x in w {
                if x != 0.0 {
                    st.min_weight = st.min_weight.min(x);
                }
            }
        }
        st.mean /= n.max(1) as f64;
        st
    }

    /// The first of the first `n` nodes with fewer than `min` live slots.
    pub fn first_poor(&self, n: usize, min: usize) -> Option<PoorNode> {
        let node = (0..n).find(|&i| self.live(i).count() < min)?;
        let (idx, _) = self.row(node);
        let mutual = idx
            .iter()
            .filter(|&&j| {
                let j = j as usize;
                j < n && j != node && self.row(j).0.contains(&(node as u32))
            })
            .count();
        Some(PoorNode {
            node,
            live: self.live(node).count(),
            mutual,
        })
    }

    /// Checks the invariant every model relies on: for the first `n` nodes, every non-zero
    /// slot `i -> j` has a non-zero slot `j -> i` with the same weight. Returns the first
    /// offending pair.
    pub fn check_mutual(&self, n: usize) -> Result<(), (usize, usize)> {
        for i in 0..n {
            let (idx, w) = self.row(i);
            for s in 0..self.k {
                if w[s] == 0.0 {
                    continue;
                }
                let j = idx[s] as usize;
                if j >= n {
                    return Err((i, j));
                }
                let (jidx, jw) = self.row(j);
                let back = (0..self.k).any(|r| jidx[r] as usize == i && jw[r] == w[s]);
                if !back {
                    return Err((i, j));
                }
            }
        }
        Ok(())
    }
}

/// A node's kernel length from the distances to its K nearest nodes (any order; sorted in
/// place): the distance of the `ceil(K/2)`-th nearest, the median.
///
/// In the interior of a cubic lattice of spacing h with K = 16 or 18 this is `sqrt(2) h`, the
/// same as the K-th distance. At a free surface the K nearest reach deeper into the body
/// (a face node has 13 nodes within `sqrt(2) h`, an edge node 9), so the K-th distance
/// grows to `sqrt(3) h` or `2 h` and gave surface pairs wider kernels, larger weights and a
/// stiffer surface layer (a mass-spring cube of 5^3 nodes with every spring counted fully,
/// under uniform strain: 2.21 times the unbounded lattice with the K-th distance, 1.67
/// with the median); the median stays at `sqrt(2) h`.
pub fn kernel_length(distances: &mut [f64]) -> f64 {
    if distances.is_empty() {
        return 0.0;
    }
    distances.sort_by(f64::total_cmp);
    distances[(distances.len() - 1) / 2]
}

/// Weight of a pair at distance `r` whose nodes have kernel lengths `dki`, `dkj`
/// ([`kernel_length`]). Symmetric in `(i, j)`, 1 at `r = 0`.
pub fn kernel_weight(kernel: WeightKernel, r: f64, dki: f64, dkj: f64) -> f64 {
    match kernel {
        WeightKernel::Uniform => 1.0,
        WeightKernel::Poly6 { support } => {
            let h = support * 0.5 * (dki + dkj);
            let q = (r / h).min(1.0);
            (1.0 - q * q).powi(3)
        }
    }
}

/// A uniform grid over a point set for nearest-neighbour queries.
#[derive(Debug, Clone)]
pub struct UniformGrid {
    origin: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    /// Start of each cell's run in `items` (`cells + 1` entries).
    start: Vec<u32>,
    /// Point indices sorted by cell.
    items: Vec<u32>,
}

impl UniformGrid {
    /// A grid whose cells hold about `k / 4` points each on average.
    pub fn new(points: &[[f64; 3]], k: usize) -> UniformGrid {
        let (lo, hi) = crate::geometry::bounds(points);
        let ext: [f64; 3] = std::array::from_fn(|a| (hi[a] - lo[a]).max(0.0));
        let scale = ext.iter().cloned().fold(0.0, f64::max).max(1e-12);
        // Guard flat sets: give every axis at least a 1e-3 share of the largest extent.
        let vol: f64 = ext.iter().map(|e| e.max(1e-3 * scale)).product();
        let per_cell = (k as f64 / 4.0).max(1.0);
        let cell = (vol * per_cell / points.len().max(1) as f64)
            .cbrt()
            .max(1e-12);
        let dims: [usize; 3] =
            std::array::from_fn(|a| ((ext[a] / cell).floor() as usize + 1).min(1 << 20));
        let n_cells = dims[0] * dims[1] * dims[2];
        let mut grid = UniformGrid {
            origin: lo,
            cell,
            dims,
            start: vec![0; n_cells + 1],
            items: vec![0; points.len()],
        };
        let cells: Vec<usize> = points
            .iter()
            .map(|p| grid.cell_index(grid.cell_of(*p)))
            .collect();
        for &c in &cells {
            grid.start[c + 1] += 1;
        }
        for c in 0..n_cells {
            grid.start[c + 1] += grid.start[c];
        }
        let mut fill = grid.start.clone();
        for (i, &c) in cells.iter().enumerate() {
            grid.items[fill[c] as usize] = i as u32;
            fill[c] += 1;
        }
        grid
    }

    fn cell_of(&self, p: [f64; 3]) -> [usize; 3] {
        std::array::from_fn(|a| {
            let c = ((p[a] - self.origin[a]) / self.cell).floor();
            (c.max(0.0) as usize).min(self.dims[a] - 1)
        })
    }

    fn cell_index(&self, c: [usize; 3]) -> usize {
        c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])
    }

    /// The `k` nearest points to `p` (excluding index `exclude`), as `(squared distance,
    /// index)` sorted by distance, ties broken as described at `closer`, written to
    /// `out`.
    pub fn k_nearest(
        &self,
        points: &[[f64; 3]],
        p: [f64; 3],
        k: usize,
        exclude: Option<usize>,
        out: &mut Vec<(f64, u32)>,
    ) {
        out.clear();
        let home = self.cell_of(p);
        let max_ring = self.dims.iter().max().copied().unwrap_or(1);
        for ring in 0..=max_ring {
            self.visit_ring(home, ring, |idx| {
                if Some(idx as usize) == exclude {
                    return;
                }
                let d2 = DVec3::from(points[idx as usize]).distance_squared(DVec3::from(p));
                insert_sorted(out, k, (d2, idx), |a, b| closer(points, p, a, b));
            });
            // Every point in ring r+1 or beyond is at least r * cell away from p.
            if out.len() == k {
                let reach = ring as f64 * self.cell;
                if out[k - 1].0 <= reach * reach {
                    break;
                }
            }
        }
    }

    fn visit_ring(&self, home: [usize; 3], ring: usize, mut f: impl FnMut(u32)) {
        let r = ring as isize;
        let lo: [isize; 3] = std::array::from_fn(|a| (home[a] as isize - r).max(0));
        let hi: [isize; 3] =
            std::array::from_fn(|a| (home[a] as isize + r).min(self.dims[a] as isize - 1));
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let on_shell = (x - home[0] as isize).abs() == r
                        || (y - home[1] as isize).abs() == r
                        || (z - home[2] as isize).abs() == r;
                    if !on_shell {
                        continue;
                    }
                    let c = self.cell_index([x as usize, y as usize, z as usize]);
                    for &idx in &self.items[self.start[c] as usize..self.start[c + 1] as usize] {
                        f(idx);
                    }
                }
            }
        }
    }
}

/// Whether candidate `a` (squared distance, index) comes before `b` as a neighbour of
/// `p`. Squared distances within a relative 1e-9 are a tie (lattice offsets of equal
/// length differ in the last bits after subtraction). Ties are broken by direction, in a
/// point-symmetric way: offsets `e` and `-e` are ranked next to each other (by the
/// canonical direction, the one of the two whose first non-zero component is positive),
/// `+e` first, then by index (coincident points). So when the K-th distance cuts through a
/// shell of equidistant lattice neighbours, every interior node keeps the same offsets,
/// and keeps them in `+e, -e` pairs: the mutuality rule then leaves the neighbourhood
/// point-symmetric with no direction missing on one side only. (Breaking ties by index
/// instead keeps the lower-index side, and the mutuality rule then removes a whole
/// diagonal direction on a cubic lattice.)
fn closer(points: &[[f64; 3]], p: [f64; 3], a: &(f64, u32), b: &(f64, u32)) -> bool {
    let scale = a.0.max(b.0);
    if (a.0 - b.0).abs() > 1e-9 * scale {
        return a.0 < b.0;
    }
    let tol = 1e-6 * scale.sqrt();
    let canonical = |i: u32| -> (DVec3, bool) {
        let d = DVec3::from(points[i as usize]) - DVec3::from(p);
        match d.to_array().into_iter().find(|c| c.abs() > tol) {
            Some(c) if c < 0.0 => (-d, true),
            _ => (d, false),
        }
    };
    let (ca, na) = canonical(a.1);
    let (cb, nb) = canonical(b.1);
    for axis in 0..3 {
        if (ca[axis] - cb[axis]).abs() > tol {
            return ca[axis] < cb[axis];
        }
    }
    if na != nb {
        return !na;
    }
    a.1 < b.1
}

fn insert_sorted(
    out: &mut Vec<(f64, u32)>,
    k: usize,
    item: (f64, u32),
    less: impl Fn(&(f64, u32), &(f64, u32)) -> bool,
) {
    if out.len() == k {
        if !less(&item, &out[k - 1]) {
            return;
        }
        out.pop();
    }
    let pos = out.iter().position(|x| less(&item, x)).unwrap_or(out.len());
    out.insert(pos, item);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pseudo_random_points(n: usize, seed: u64) -> Vec<[f64; 3]> {
        let mut s = seed;
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n)
            .map(|_| [next(), next() * 0.5, next() * 2.0])
            .collect()
    }

    #[test]
    fn grid_knn_matches_brute_force() {
        let pts = pseudo_random_points(500, 7);
        let grid = UniformGrid::new(&pts, 16);
        let mut out = Vec::new();
        for i in (0..pts.len()).step_by(7) {
            grid.k_nearest(&pts, pts[i], 16, Some(i), &mut out);
            let mut brute: Vec<(f64, u32)> = (0..pts.len())
                .filter(|&j| j != i)
                .map(|j| {
                    (
                        DVec3::from(pts[j]).distance_squared(DVec3::from(pts[i])),
                        j as u32,
                    )
                })
                .collect();
            brute.sort_by(|a, b| {
                if closer(&pts, pts[i], a, b) {
                    std::cmp::Ordering::Less
                } else {
                    std::cmp::Ordering::Greater
                }
            });
            brute.truncate(16);
            assert_eq!(out, brute, "node {i}");
        }
    }

    /// On a cubic lattice with K = 16 the kernel length is `sqrt(2) a` for interior, face
    /// and edge nodes alike (the K-th distance is `sqrt(3) a` or more at the surface).
    #[test]
    fn kernel_length_is_not_inflated_at_the_surface() {
        let a = 0.01;
        let pts: Vec<[f64; 3]> = (0..216)
            .map(|i| {
                [
                    (i % 6) as f64 * a,
                    ((i / 6) % 6) as f64 * a,
                    (i / 36) as f64 * a,
                ]
            })
            .collect();
        let grid = UniformGrid::new(&pts, 16);
        let mut out = Vec::new();
        // Interior (2, 2, 2), face (0, 2, 2), edge (0, 0, 2).
        for (i, kth_min) in [(2 + 12 + 72, 1.0), (12 + 72, 1.7), (72, 1.7)] {
            grid.k_nearest(&pts, pts[i], 16, Some(i), &mut out);
            let mut d: Vec<f64> = out.iter().map(|&(d2, _)| d2.sqrt()).collect();
            assert!(d[15] >= kth_min * a, "node {i}: K-th {}", d[15]);
            let l = kernel_length(&mut d);
            assert!((l / (2f64.sqrt() * a) - 1.0).abs() < 1e-12, "node {i}: {l}");
        }
    }

    /// A point 1.7 spacings off the corner of a lattice is nobody's neighbour with K = 6;
    /// zeroing a mutual pair's weights leaves it mutual but not live.
    #[test]
    fn poor_nodes_are_found_with_their_mutual_count() {
        let mut pts: Vec<[f64; 3]> = (0..27)
            .map(|i| [(i % 3) as f64, ((i / 3) % 3) as f64, (i / 9) as f64])
            .collect();
        let nb = Neighbours::build(&pts, 6, WeightKernel::default(), 27);
        assert_eq!(nb.first_poor(27, MIN_LIVE_NEIGHBOURS), None);
        pts.push([-1.0, -1.0, -1.0]);
        let nb = Neighbours::build(&pts, 6, WeightKernel::default(), 28);
        let poor = nb.first_poor(28, MIN_LIVE_NEIGHBOURS).unwrap();
        assert_eq!((poor.node, poor.live, poor.mutual), (27, 0, 0));
        let mut nb = Neighbours::build(&pts[..27], 6, WeightKernel::default(), 27);
        for slot in 0..6 {
            let j = nb.index[slot] as usize;
            nb.weight[slot] = 0.0;
            for s in j * 6..(j + 1) * 6 {
                if nb.index[s] == 0 {
                    nb.weight[s] = 0.0;
                }
            }
        }
        let poor = nb.first_poor(27, MIN_LIVE_NEIGHBOURS).unwrap();
        assert_eq!((poor.node, poor.live), (0, 0));
        assert!(poor.mutual >= 3, "{poor:?}");
    }

    #[test]
    fn lists_are_mutual_with_symmetric_positive_weights() {
        let pts = pseudo_random_points(300, 3);
        let nb = Neighbours::build(&pts, 12, WeightKernel::default(), 310);
        nb.check_mutual(300).unwrap();
        let st = nb.stats(300);
        assert!(st.min_weight > 0.0 && st.mean > 6.0, "{st:?}");
        // Extra capacity rows are empty.
        assert!(nb.weight[300 * 12..].iter().all(|&w| w == 0.0));
    }
}
