//! Interior sampling of a closed surface, keeping the surface's own vertices as nodes
//! (`surface = "vertices"`; the default resamples them, [`super::resample`]).
//!
//! The surface vertices become nodes; the inside is filled with a cubic lattice of spacing
//! `h` (centred on the surface's bounding box). A lattice point is kept when it lies
//! inside ([`super::ray_columns`]) and at least `h / 2` from the surface, so no interior
//! node crowds a surface vertex. Node cell volumes come from [`super::cell_volume`].

use super::lattice::Lattice;
use super::obj::Surface;
use super::ray_columns::ColumnCrossings;
use super::triangle_bins::TriangleBins;
use super::NodeCloud;
use glam::DVec3;

/// Surface vertices plus the interior lattice points.
pub fn fill_lattice(surface: &Surface, h: f64) -> NodeCloud {
    let lattice = Lattice::covering(&surface.vertices, h, 0);
    let tris: Vec<[[f64; 3]; 3]> = surface
        .triangles
        .iter()
        .map(|t| t.map(|i| surface.vertices[i as usize]))
        .collect();
    let inside = ColumnCrossings::inside_grid(&tris, lattice.origin, h, lattice.dims);
    let bins = TriangleBins::new(tris, h);
    let mut positions = surface.vertices.clone();
    let [nx, ny, nz] = lattice.dims;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = lattice.point([i, j, k]);
                if inside[i + nx * (j + ny * k)] && bins.distance_capped(p, 0.5 * h) >= 0.5 * h {
                    positions.push(p);
                }
            }
        }
    }
    let node_volumes =
        super::cell_volume::estimate(&positions, bins.triangles(), &lattice, surface.volume);
    NodeCloud {
        positions,
        triangles: surface.triangles.clone(),
        volume: surface.volume,
        node_volumes,
        spacing: h,
    }
}

/// Generalised winding number of `p` with respect to a closed triangle surface: 1 inside,
/// 0 outside.
pub fn winding_number(p: [f64; 3], triangles: &[[[f64; 3]; 3]]) -> f64 {
    let p = DVec3::from(p);
    let mut total = 0.0;
    for t in triangles {
        let a = DVec3::from(t[0]) - p;
        let b = DVec3::from(t[1]) - p;
        let c = DVec3::from(t[2]) - p;
        let (la, lb, lc) = (a.length(), b.length(), c.length());
        let num = a.dot(b.cross(c));
        let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
        total += 2.0 * num.atan2(den);
    }
    total / (4.0 * std::f64::consts::PI)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::box_lattice::BoxLattice;
    use crate::geometry::triangle_bins::distance_to_triangles;

    #[test]
    fn winding_number_is_one_inside_zero_outside() {
        let c = BoxLattice::with_spacing([0.0; 3], [1.0; 3], 0.5).cloud();
        let tris = c.triangle_corners();
        assert!((winding_number([0.3, 0.4, 0.6], &tris) - 1.0).abs() < 1e-9);
        assert!(winding_number([1.3, 0.4, 0.6], &tris).abs() < 1e-9);
        assert!((distance_to_triangles([0.5, 0.5, 0.9], &tris) - 0.1).abs() < 1e-12);
    }
}
