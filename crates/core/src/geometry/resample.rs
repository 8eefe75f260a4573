//! Resampling a closed surface to nodes about one spacing apart.
//!
//! A cubic lattice of spacing `h` covers the surface's bounds with a margin; its points
//! are classified inside or outside ([`super::ray_columns`]). The new surface is the
//! lattice's dual contour ("surface nets", Gibson 1998): one vertex in every lattice cube
//! whose corners are not all on one side, placed at the mean of the points where the
//! cube's edges cross the input surface and then moved to the closest point of the input
//! surface, as long as that stays in the cube (a tenth of a spacing from its faces, so no
//! two vertices meet where the surface grazes a lattice point); one quad, split in two triangles, across every lattice edge that changes side.
//! Vertices end up on the input surface, about `h` apart, whatever the input's own
//! triangle count, and the triangles stay what the needle punctures and splits.
//!
//! Where the surface has features thinner than `h`, a cube's inside (or outside) corners
//! can fall apart into pieces, which would make the contour non-manifold. Such cubes have
//! their outside corners counted as inside for the contour (repeated until none is left);
//! this thickens sub-spacing features to one spacing and nothing else. The result is
//! checked like an input file (closed, manifold, consistently oriented).
//!
//! Interior nodes are the lattice points inside the input surface and at least `h / 2`
//! from it, as in [`super::sampling`].

use super::obj::Surface;
use super::ray_columns::ColumnCrossings;
use super::triangle_bins::TriangleBins;
use super::NodeCloud;
use crate::error::GeometryError;
use glam::DVec3;
use std::path::Path;

/// The resampled surface and interior nodes of `surface` at spacing `h`. `path` names the
/// source in errors.
pub fn resample(surface: &Surface, h: f64, path: &Path) -> Result<NodeCloud, GeometryError> {
    let tris: Vec<[[f64; 3]; 3]> = surface
        .triangles
        .iter()
        .map(|t| t.map(|i| surface.vertices[i as usize]))
        .collect();
    let lattice = super::lattice::Lattice::covering(&surface.vertices, h, 2);
    let dims = lattice.dims;
    let [nx, ny, nz] = dims;
    let inside = ColumnCrossings::inside_grid(&tris, lattice.origin, h, dims);
    let bins = TriangleBins::new(tris, h);
    let mut topo = regularise(&inside, dims);
    // The lattice has two layers of margin around the vertices, so its outermost layer is
    // outside; a ray crossing counted wrongly (a grazing hit on a distorted mesh) must not
    // put a point there, or the quads below would reach past the lattice.
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                if i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1 {
                    topo[i + nx * (j + ny * k)] = false;
                }
            }
        }
    }

    // One vertex per mixed cube, at the mean edge crossing projected onto the surface.
    let cube_index = |i: usize, j: usize, k: usize| i + (nx - 1) * (j + (ny - 1) * k);
    let mut vertex_of = vec![u32::MAX; (nx - 1) * (ny - 1) * (nz - 1)];
    let mut positions: Vec<[f64; 3]> = Vec::new();
    for k in 0..nz - 1 {
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let corner = |c: usize| [i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1)];
                let mask = (0..8).fold(0u8, |m, c| {
                    let [a, b, d] = corner(c);
                    m | (topo[a + nx * (b + ny * d)] as u8) << c
                });
                if mask == 0 || mask == 255 {
                    continue;
                }
                let mut sum = [0.0; 3];
                let mut count = 0.0;
                for &(c0, c1) in CUBE_EDGES.iter() {
                    if (mask >> c0 & 1) == (mask >> c1 & 1) {
                        continue;
                    }
                    let a = lattice.point(corner(c0));
                    let b = lattice.point(corner(c1));
                    let s = bins.first_crossing(a, b).unwrap_or(0.5);
                    for x in 0..3 {
                        sum[x] += a[x] + s * (b[x] - a[x]);
                    }
                    count += 1.0;
                }
                let mean = sum.map(|s| s / count);
                let on_surface = bins.closest(mean, 2.0 * h).map_or(mean, |(x, _)| x);
                // Kept inside its cube, CUBE_MARGIN from the faces, so that no two
                // vertices meet where the surface touches a lattice point.
                let lo = lattice.point([i, j, k]);
                let v: [f64; 3] = std::array::from_fn(|a| {
                    on_surface[a].clamp(lo[a] + CUBE_MARGIN * h, lo[a] + (1.0 - CUBE_MARGIN) * h)
                });
                vertex_of[cube_index(i, j, k)] = positions.len() as u32;
                positions.push(v);
            }
        }
    }

    // A quad across every lattice edge that changes side, counter-clockwise from outside.
    // Such an edge never lies in the outermost layer (never turned inside), so its four
    // cubes exist.
    let mut triangles = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let p = [i, j, k];
                let here = topo[i + nx * (j + ny * k)];
                for a in 0..3 {
                    let mut q = p;
                    q[a] += 1;
                    if q[a] >= dims[a] {
                        continue;
                    }
                    let there = topo[q[0] + nx * (q[1] + ny * q[2])];
                    if here == there {
                        continue;
                    }
                    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
                    let cube = |db: usize, dc: usize| {
                        let mut m = p;
                        m[b] -= db;
                        m[c] -= dc;
                        vertex_of[cube_index(m[0], m[1], m[2])]
                    };
                    // Counter-clockwise about +a; the normal points from inside to outside.
                    let mut quad = [cube(0, 0), cube(1, 0), cube(1, 1), cube(0, 1)];
                    if !here {
                        quad.reverse();
                    }
                    let x = |v: u32| DVec3::from(positions[v as usize]);
                    let d02 = x(quad[0]).distance_squared(x(quad[2]));
                    let d13 = x(quad[1]).distance_squared(x(quad[3]));
                    if d02 <= d13 {
                        triangles.push([quad[0], quad[1], quad[2]]);
                        triangles.push([quad[0], quad[2], quad[3]]);
                    } else {
                        triangles.push([quad[1], quad[2], quad[3]]);
                        triangles.push([quad[1], quad[3], quad[0]]);
                    }
                }
            }
        }
    }
    if triangles.is_empty() {
        return Err(GeometryError::TooThin {
            path: path.to_path_buf(),
            spacing: h,
        });
    }
    super::obj::check_closed_manifold(path, positions.len(), &triangles)?;

    // Interior nodes: lattice points inside, at least h / 2 from the input surface.
    let n_surface = positions.len();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                if inside[i + nx * (j + ny * k)] {
                    let p = lattice.point([i, j, k]);
                    if bins.distance_capped(p, 0.5 * h) >= 0.5 * h {
                        positions.push(p);
                    }
                }
            }
        }
    }
    let node_volumes =
        super::cell_volume::estimate(&positions, bins.triangles(), &lattice, surface.volume);
    debug_assert!(n_surface <= positions.len());
    Ok(NodeCloud {
        positions,
        triangles,
        volume: surface.volume,
        node_volumes,
        spacing: h,
    })
}

/// How far (in spacings) a surface vertex stays from the faces of its lattice cube: two
/// vertices are at least twice this apart.
const CUBE_MARGIN: f64 = 0.1;

/// The twelve edges of a cube, as pairs of corner numbers `x + 2 y + 4 z`.
const CUBE_EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// Whether the inside corners of a cube (bit `c` of `mask` for corner `c`) and its outside
/// corners each form one piece along the cube's edges.
fn simple(mask: u8) -> bool {
    let pieces = |side: u8| {
        let members: Vec<usize> = (0..8).filter(|&c| (mask >> c & 1) == side).collect();
        let mut piece: [usize; 8] = std::array::from_fn(|c| c);
        fn find(p: &mut [usize; 8], c: usize) -> usize {
            let mut r = c;
            while p[r] != r {
                r = p[r];
            }
            p[c] = r;
            r
        }
        for &(a, b) in CUBE_EDGES.iter() {
            if (mask >> a & 1) == side && (mask >> b & 1) == side {
                let (ra, rb) = (find(&mut piece, a), find(&mut piece, b));
                piece[ra] = rb;
            }
        }
        let mut roots: Vec<usize> = members.iter().map(|&c| find(&mut piece, c)).collect();
        roots.sort_unstable();
        roots.dedup();
        roots.len()
    };
    pieces(1) <= 1 && pieces(0) <= 1
}

/// The inside flags with every non-simple cube's outside corners turned inside, until all
/// cubes are simple. Points on the outermost layer are never turned (the grid's margin
/// keeps them clear of the surface).
fn regularise(inside: &[bool], dims: [usize; 3]) -> Vec<bool> {
    let [nx, ny, nz] = dims;
    let table: Vec<bool> = (0..=255u8).map(simple).collect();
    let mut topo = inside.to_vec();
    let border = |p: [usize; 3]| (0..3).any(|a| p[a] == 0 || p[a] == dims[a] - 1);
    loop {
        let mut changed = false;
        for k in 0..nz - 1 {
            for j in 0..ny - 1 {
                for i in 0..nx - 1 {
                    let corner = |c: usize| [i + (c & 1), j + (c >> 1 & 1), k + (c >> 2 & 1)];
                    let flat = |p: [usize; 3]| p[0] + nx * (p[1] + ny * p[2]);
                    let mask = (0..8).fold(0u8, |m, c| m | (topo[flat(corner(c))] as u8) << c);
                    if table[mask as usize] {
                        continue;
                    }
                    for c in 0..8 {
                        let p = corner(c);
                        if !topo[flat(p)] && !border(p) {
                            topo[flat(p)] = true;
                            changed = true;
                        }
                    }
                }
            }
        }
        if !changed {
            return topo;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simple_cubes() {
        assert!(simple(0) && simple(255));
        assert!(simple(0b0000_0001)); // one corner
        assert!(simple(0b0000_0011)); // one edge
        assert!(simple(0b0000_1111)); // one face
        assert!(!simple(0b0000_1001)); // two corners of a face diagonal
        assert!(!simple(0b1000_0001)); // two corners of the body diagonal
        assert!(!simple(!0b1000_0001)); // six corners, outside split
    }
}
