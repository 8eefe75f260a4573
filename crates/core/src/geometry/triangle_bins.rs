//! Triangles binned in cubes, for closest-point and distance queries near a surface.
//!
//! Each triangle is listed in every cube its bounding box overlaps. A query searches
//! shells of cubes around the point's cube outwards and stops once no unsearched cube can
//! hold a closer triangle, so a point near the surface costs the few triangles around it.

use glam::DVec3;

/// Triangles binned in cubes of side `cell`.
#[derive(Debug, Clone)]
pub struct TriangleBins {
    triangles: Vec<[[f64; 3]; 3]>,
    lo: [f64; 3],
    cell: f64,
    dims: [i64; 3],
    bins: Vec<Vec<u32>>,
}

impl TriangleBins {
    /// Bins `triangles` (corner coordinates) in cubes of side `cell` over their bounds.
    pub fn new(triangles: Vec<[[f64; 3]; 3]>, cell: f64) -> TriangleBins {
        let corners: Vec<[f64; 3]> = triangles.iter().flatten().copied().collect();
        let (lo, hi) = super::bounds(&corners);
        let dims: [i64; 3] =
            std::array::from_fn(|a| ((hi[a] - lo[a]) / cell).floor().max(0.0) as i64 + 1);
        let mut bins = vec![Vec::new(); (dims[0] * dims[1] * dims[2]) as usize];
        let mut out = TriangleBins {
            triangles,
            lo,
            cell,
            dims,
            bins: Vec::new(),
        };
        for (n, t) in out.triangles.iter().enumerate() {
            let (tlo, thi) = super::bounds(t);
            let a = out.cell_of(tlo);
            let b = out.cell_of(thi);
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    for x in a[0]..=b[0] {
                        bins[out.flat([x, y, z])].push(n as u32);
                    }
                }
            }
        }
        out.bins = bins;
        out
    }

    /// The binned triangles.
    pub fn triangles(&self) -> &[[[f64; 3]; 3]] {
        &self.triangles
    }

    fn cell_of(&self, p: [f64; 3]) -> [i64; 3] {
        std::array::from_fn(|a| ((p[a] - self.lo[a]) / self.cell).floor() as i64)
    }

    fn flat(&self, c: [i64; 3]) -> usize {
        (c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])) as usize
    }

    /// The closest surface point to `p` and its distance, if one lies within `max_distance`
    /// (pass infinity for any).
    pub fn closest(&self, p: [f64; 3], max_distance: f64) -> Option<([f64; 3], f64)> {
        let c = self.cell_of(p);
        // Chebyshev distance in cubes from c to the grid.
        let outside = (0..3)
            .map(|a| (-c[a]).max(c[a] - (self.dims[a] - 1)).max(0))
            .max()
            .unwrap_or(0);
        let far = outside + self.dims.iter().max().copied().unwrap_or(0);
        let mut best: Option<([f64; 3], f64)> = None;
        for r in outside..=far {
            // Every cube of shell r is at least (r - 1) cubes away from p.
            let gap = (r - 1).max(0) as f64 * self.cell;
            let bound = best.map_or(max_distance, |b| b.1.min(max_distance));
            if gap > bound {
                break;
            }
            for z in c[2] - r..=c[2] + r {
                for y in c[1] - r..=c[1] + r {
                    for x in c[0] - r..=c[0] + r {
                        let q = [x, y, z];
                        if (0..3).all(|a| (q[a] - c[a]).abs() != r)
                            || (0..3).any(|a| q[a] < 0 || q[a] >= self.dims[a])
                        {
                            continue;
                        }
                        for &t in &self.bins[self.flat(q)] {
                            let x = closest_point_on_triangle(p, &self.triangles[t as usize]);
                            let d = DVec3::from(x).distance(DVec3::from(p));
                            if best.is_none_or(|b| d < b.1) {
                                best = Some((x, d));
                            }
                        }
                    }
                }
            }
        }
        best.filter(|b| b.1 <= max_distance)
    }

    /// Distance from `p` to the surface, or `cap` if it is farther than `cap`.
    pub fn distance_capped(&self, p: [f64; 3], cap: f64) -> f64 {
        self.closest(p, cap).map_or(cap, |b| b.1)
    }

    /// Where the segment `a -> b` first crosses a triangle, as the fraction of the way
    /// from `a` (the segment should be no longer than a cube).
    pub fn first_crossing(&self, a: [f64; 3], b: [f64; 3]) -> Option<f64> {
        let ca = self.cell_of(a);
        let cb = self.cell_of(b);
        let mut best: Option<f64> = None;
        let mut seen = std::collections::HashSet::new();
        for z in ca[2].min(cb[2])..=ca[2].max(cb[2]) {
            for y in ca[1].min(cb[1])..=ca[1].max(cb[1]) {
                for x in ca[0].min(cb[0])..=ca[0].max(cb[0]) {
                    let q = [x, y, z];
                    if (0..3).any(|a| q[a] < 0 || q[a] >= self.dims[a]) {
                        continue;
                    }
                    for &t in &self.bins[self.flat(q)] {
                        if !seen.insert(t) {
                            continue;
                        }
                        if let Some((s, _)) =
                            segment_triangle(a, b, self.triangles[t as usize], 0.0)
                        {
                            if best.is_none_or(|b| s < b) {
                                best = Some(s);
                            }
                        }
                    }
                }
            }
        }
        best
    }
}

/// Where the segment `p0 -> p1` crosses triangle `t = [a, b, c]` (Moeller and Trumbore
/// 1997): `(s, [w_a, w_b, w_c])` with the segment fraction `s` in `[0, 1]` and the hit's
/// barycentric weights, or `None` (also for a segment in the triangle's plane or a
/// degenerate triangle). Edges and corners count as inside up to the relative tolerance
/// `eps` (0: exactly; the needle uses 1e-12 so that a segment through a shared edge or
/// vertex crosses every triangle around it, which parry's triangle ray cast does not).
pub fn segment_triangle(
    p0: [f64; 3],
    p1: [f64; 3],
    t: [[f64; 3]; 3],
    eps: f64,
) -> Option<(f64, [f64; 3])> {
    let [a, b, c] = t.map(DVec3::from_array);
    let p0 = DVec3::from_array(p0);
    let d = DVec3::from_array(p1) - p0;
    let e1 = b - a;
    let e2 = c - a;
    let h = d.cross(e2);
    let det = e1.dot(h);
    if det == 0.0 {
        return None;
    }
    if eps > 0.0 {
        let scale = (d.length_squared() * e1.length_squared() * e2.length_squared()).sqrt();
        if det.abs() <= eps * scale {
            return None;
        }
    }
    let inv = 1.0 / det;
    let s = p0 - a;
    let u = inv * s.dot(h);
    if !(-eps..=1.0 + eps).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = inv * d.dot(q);
    if v < -eps || u + v > 1.0 + eps {
        return None;
    }
    let f = inv * e2.dot(q);
    if !(-eps..=1.0 + eps).contains(&f) {
        return None;
    }
    Some((f.clamp(0.0, 1.0), [1.0 - u - v, u, v]))
}

/// Distance from `p` to the nearest point of any triangle.
pub fn distance_to_triangles(p: [f64; 3], triangles: &[[[f64; 3]; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| DVec3::from(p).distance(closest_point_on_triangle(p, t).into()))
        .fold(f64::INFINITY, f64::min)
}

/// Closest point of triangle `t` to `p` (Voronoi regions of vertices, edges and face).
pub fn closest_point_on_triangle(p: [f64; 3], t: &[[f64; 3]; 3]) -> [f64; 3] {
    let p = DVec3::from(p);
    let [a, b, c] = t.map(DVec3::from);
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a.into();
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b.into();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v).into();
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c.into();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w).into();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w).into();
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    (a + (ab * v + ac * w)).into()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::box_lattice::BoxLattice;

    /// Binned queries agree with the brute-force distance over all triangles, near and far.
    #[test]
    fn binned_distance_matches_brute_force() {
        let c = BoxLattice::with_spacing([0.0; 3], [0.04, 0.03, 0.05], 0.01).cloud();
        let tris = c.triangle_corners();
        let bins = TriangleBins::new(tris.clone(), 0.007);
        let mut x = 0.123_f64;
        for _ in 0..300 {
            let mut r = || {
                x = (x * 97.31 + 0.371).fract();
                x * 0.1 - 0.03
            };
            let p = [r(), r(), r()];
            let want = distance_to_triangles(p, &tris);
            let got = bins.closest(p, f64::INFINITY).unwrap().1;
            assert!((got - want).abs() < 1e-15, "{p:?}: {got} vs {want}");
            assert_eq!(bins.distance_capped(p, 0.004), want.min(0.004));
        }
        let s = bins
            .first_crossing([0.02, 0.015, -0.01], [0.02, 0.015, 0.01])
            .unwrap();
        assert!((s - 0.5).abs() < 1e-12);
        assert!(bins
            .first_crossing([0.02, 0.015, 0.01], [0.02, 0.015, 0.02])
            .is_none());
    }
}
