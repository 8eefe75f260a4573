//! Which surface triangle a moving needle tip crosses: an exact segment-triangle test
//! (Moller and Trumbore 1997, two-sided, edges included) behind a uniform grid of triangle
//! bounding boxes, so a query costs the triangles near the segment, not all of them.
//!
//! The grid is built from vertex positions once and inflated by a `margin`: it stays valid
//! while no vertex has moved further than the margin since the build (the caller rebuilds
//! it, or grows the margin, when that may no longer hold). Queries read vertex positions
//! through a closure, so a GPU caller can fetch only the candidates' vertices.

/// A crossing of the segment `p0 -> p1` through a triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceHit {
    /// Triangle index.
    pub triangle: u32,
    /// Fraction along the segment, in [0, 1].
    pub t: f64,
    /// Barycentric coordinates of the hit (weights of the three corners).
    pub barycentric: [f64; 3],
    /// The hit point.
    pub point: [f64; 3],
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Where the segment `p0 -> p1` crosses triangle `(a, b, c)`: `(t, [w_a, w_b, w_c])`, or
/// `None` (also for a segment in the triangle's plane or a degenerate triangle). Edges and
/// corners count as inside up to a relative 1e-12.
pub fn segment_triangle(
    p0: [f64; 3],
    p1: [f64; 3],
    a: [f64; 3],
    b: [f64; 3],
    c: [f64; 3],
) -> Option<(f64, [f64; 3])> {
    const EPS: f64 = 1e-12;
    let d = sub(p1, p0);
    let e1 = sub(b, a);
    let e2 = sub(c, a);
    let h = cross(d, e2);
    let det = dot(e1, h);
    let scale = (dot(d, d) * dot(e1, e1) * dot(e2, e2)).sqrt();
    if det.abs() <= EPS * scale {
        return None;
    }
    let inv = 1.0 / det;
    let s = sub(p0, a);
    let u = inv * dot(s, h);
    if !(-EPS..=1.0 + EPS).contains(&u) {
        return None;
    }
    let q = cross(s, e1);
    let v = inv * dot(d, q);
    if v < -EPS || u + v > 1.0 + EPS {
        return None;
    }
    let t = inv * dot(e2, q);
    if !(-EPS..=1.0 + EPS).contains(&t) {
        return None;
    }
    Some((t.clamp(0.0, 1.0), [1.0 - u - v, u, v]))
}

/// Uniform grid of inflated triangle bounding boxes.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct TriangleGrid {
    origin: [f64; 3],
    cell: f64,
    dims: [usize; 3],
    /// Triangle ids per cell (flattened `x + dims.x (y + dims.y z)`).
    cells: Vec<Vec<u32>>,
    margin: f64,
}

impl TriangleGrid {
    /// Builds the grid over `triangles` with vertex positions `positions`, every box
    /// inflated by `margin` metres. The cell size is the mean triangle edge length (at most
    /// 64 cells along the largest side).
    pub fn build(positions: &[[f64; 3]], triangles: &[[u32; 3]], margin: f64) -> TriangleGrid {
        let margin = margin.max(0.0);
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        let mut edge_sum = 0.0;
        for t in triangles {
            let p = t.map(|v| positions[v as usize]);
            for q in p {
                for a in 0..3 {
                    lo[a] = lo[a].min(q[a] - margin);
                    hi[a] = hi[a].max(q[a] + margin);
                }
            }
            edge_sum += (0..3)
                .map(|e| dot(sub(p[e], p[(e + 1) % 3]), sub(p[e], p[(e + 1) % 3])).sqrt())
                .sum::<f64>();
        }
        if triangles.is_empty() {
            return TriangleGrid {
                origin: [0.0; 3],
                cell: 1.0,
                dims: [1; 3],
                cells: vec![Vec::new()],
                margin,
            };
        }
        let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        // The mean edge length, but at most 64 cells along the largest side.
        let cell = (edge_sum / (3 * triangles.len()) as f64)
            .max(extent / 64.0)
            .max(1e-9);
        let dims: [usize; 3] =
            std::array::from_fn(|a| (((hi[a] - lo[a]) / cell).floor() as usize + 1).max(1));
        let mut grid = TriangleGrid {
            origin: lo,
            cell,
            dims,
            cells: vec![Vec::new(); dims[0] * dims[1] * dims[2]],
            margin,
        };
        for (i, t) in triangles.iter().enumerate() {
            grid.insert(i as u32, t.map(|v| positions[v as usize]));
        }
        grid
    }

    /// The margin the grid was built with.
    pub fn margin(&self) -> f64 {
        self.margin
    }

    fn cell_of(&self, p: [f64; 3]) -> [usize; 3] {
        std::array::from_fn(|a| {
            let c = ((p[a] - self.origin[a]) / self.cell).floor();
            (c.max(0.0) as usize).min(self.dims[a] - 1)
        })
    }

    fn for_cells(&self, lo: [f64; 3], hi: [f64; 3], mut f: impl FnMut(usize)) {
        let (a, b) = (self.cell_of(lo), self.cell_of(hi));
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    f(x + self.dims[0] * (y + self.dims[1] * z));
                }
            }
        }
    }

    /// Adds triangle `id` with corners `p` (inflated by the margin).
    pub fn insert(&mut self, id: u32, p: [[f64; 3]; 3]) {
        let m = self.margin;
        let lo = std::array::from_fn(|a| p[0][a].min(p[1][a]).min(p[2][a]) - m);
        let hi = std::array::from_fn(|a| p[0][a].max(p[1][a]).max(p[2][a]) + m);
        let mut cells = Vec::new();
        self.for_cells(lo, hi, |c| cells.push(c));
        for c in cells {
            self.cells[c].push(id);
        }
    }

    /// Removes triangle `id` from every cell (used when a triangle is split or restored).
    pub fn remove(&mut self, id: u32) {
        for c in &mut self.cells {
            c.retain(|&t| t != id);
        }
    }

    /// Triangle ids whose inflated boxes share a cell with the segment's bounding box,
    /// each once, in increasing order.
    pub fn candidates(&self, p0: [f64; 3], p1: [f64; 3]) -> Vec<u32> {
        let lo = std::array::from_fn(|a| p0[a].min(p1[a]));
        let hi = std::array::from_fn(|a| p0[a].max(p1[a]));
        let mut out = Vec::new();
        self.for_cells(lo, hi, |c| out.extend_from_slice(&self.cells[c]));
        out.sort_unstable();
        out.dedup();
        out
    }

    /// The first crossing along `p0 -> p1` (smallest t, then smallest triangle id) among
    /// the candidates; `corners(id)` gives a triangle's current corner positions.
    pub fn first_hit(
        &self,
        p0: [f64; 3],
        p1: [f64; 3],
        corners: impl Fn(u32) -> [[f64; 3]; 3],
    ) -> Option<SurfaceHit> {
        let mut best: Option<SurfaceHit> = None;
        for id in self.candidates(p0, p1) {
            let [a, b, c] = corners(id);
            if let Some((t, w)) = segment_triangle(p0, p1, a, b, c) {
                if best.is_none_or(|h| t < h.t) {
                    best = Some(SurfaceHit {
                        triangle: id,
                        t,
                        barycentric: w,
                        point: std::array::from_fn(|k| w[0] * a[k] + w[1] * b[k] + w[2] * c[k]),
                    });
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use needlesim_core::geometry::box_lattice::BoxLattice;

    #[test]
    fn segment_through_a_triangle_and_past_it() {
        let (a, b, c) = ([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        let (t, w) = segment_triangle([0.25, 0.25, -1.0], [0.25, 0.25, 1.0], a, b, c).unwrap();
        assert!(
            (t - 0.5).abs() < 1e-15 && (w[1] - 0.25).abs() < 1e-15 && (w[2] - 0.25).abs() < 1e-15
        );
        // Stops short, misses beside, lies in the plane.
        assert!(segment_triangle([0.25, 0.25, -1.0], [0.25, 0.25, -0.1], a, b, c).is_none());
        assert!(segment_triangle([0.8, 0.8, -1.0], [0.8, 0.8, 1.0], a, b, c).is_none());
        assert!(segment_triangle([-1.0, 0.2, 0.0], [2.0, 0.2, 0.0], a, b, c).is_none());
        // A corner counts.
        assert!(segment_triangle([1.0, 0.0, -1.0], [1.0, 0.0, 1.0], a, b, c).is_some());
    }

    /// Grid queries give the same first hit as testing every triangle, for random segments
    /// around a box surface (704 triangles).
    #[test]
    fn grid_matches_brute_force() {
        let cloud = BoxLattice::with_node_count([0.0; 3], [0.1; 3], 639).cloud();
        let (pos, tris) = (&cloud.positions, &cloud.triangles);
        let grid = TriangleGrid::build(pos, tris, 0.0);
        let corners = |id: u32| tris[id as usize].map(|v| pos[v as usize]);
        let mut s = 99u64;
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut hits = 0;
        for _ in 0..500 {
            let p0: [f64; 3] = std::array::from_fn(|_| -0.02 + 0.14 * next());
            let p1: [f64; 3] = std::array::from_fn(|a| p0[a] + 0.03 * (next() - 0.5));
            let brute = (0..tris.len() as u32)
                .filter_map(|id| {
                    let [a, b, c] = corners(id);
                    segment_triangle(p0, p1, a, b, c).map(|(t, _)| (t, id))
                })
                .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            let fast = grid.first_hit(p0, p1, corners).map(|h| (h.t, h.triangle));
            assert_eq!(fast, brute, "segment {p0:?} -> {p1:?}");
            hits += fast.is_some() as usize;
            // Few candidates: the broad phase does its job.
            assert!(grid.candidates(p0, p1).len() < tris.len() / 4);
        }
        assert!(hits > 20, "only {hits} segments crossed the surface");
    }

    #[test]
    fn split_triangles_are_found_after_insert_and_not_after_remove() {
        let cloud = BoxLattice::with_node_count([0.0; 3], [0.1; 3], 639).cloud();
        let (pos, tris) = (&cloud.positions, &cloud.triangles);
        let mut grid = TriangleGrid::build(pos, tris, 1e-3);
        let corners = |id: u32| tris[id as usize].map(|v| pos[v as usize]);
        // A segment through the x = 0.1 face.
        let (p0, p1) = ([0.12, 0.031, 0.047], [0.08, 0.031, 0.047]);
        let hit = grid.first_hit(p0, p1, corners).unwrap();
        assert!((hit.point[0] - 0.1).abs() < 1e-12);
        grid.remove(hit.triangle);
        let again = grid.first_hit(p0, p1, corners);
        assert!(again.is_none_or(|h| h.triangle != hit.triangle));
        grid.insert(hit.triangle, corners(hit.triangle));
        assert_eq!(grid.first_hit(p0, p1, corners), Some(hit));
    }
}
