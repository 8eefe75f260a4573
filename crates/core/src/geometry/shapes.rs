//! Closed triangle surfaces of simple solids, for tests, reference cases and examples:
//! a sphere (subdivided icosahedron), a capsule (cylinder with hemispherical caps) and a
//! cylinder with flat ends.

use super::obj::Surface;
use glam::DVec3;

/// A sphere of `radius` about `centre`: an icosahedron whose triangles are split in four
/// `subdivisions` times, every new vertex pushed onto the sphere (`20 * 4^s` triangles).
pub fn icosphere(centre: [f64; 3], radius: f64, subdivisions: u32) -> Surface {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<[f64; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let unit = |p: [f64; 3]| {
        let p = DVec3::from(p);
        (p / p.length()).into()
    };
    v.iter_mut().for_each(|p| *p = unit(*p));
    for _ in 0..subdivisions {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(f.len() * 4);
        let mut midpoint = |a: u32, b: u32, v: &mut Vec<[f64; 3]>| -> u32 {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (v[a as usize], v[b as usize]);
                v.push(unit(std::array::from_fn(|i| 0.5 * (p[i] + q[i]))));
                (v.len() - 1) as u32
            })
        };
        for [a, b, c] in f {
            let ab = midpoint(a, b, &mut v);
            let bc = midpoint(b, c, &mut v);
            let ca = midpoint(c, a, &mut v);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    let vertices: Vec<[f64; 3]> = v
        .iter()
        .map(|p| std::array::from_fn(|i| centre[i] + radius * p[i]))
        .collect();
    let volume = super::signed_volume(&vertices, &f);
    Surface {
        vertices,
        triangles: f,
        volume,
    }
}

/// A capsule along y from `base` (the bottom pole) to `base + length` (the top pole):
/// a cylinder of `radius` with hemispherical caps, `segments` vertices around and
/// `rings` rings per cap (the cylinder gets as many rings as keep its quads about
/// square).
pub fn capsule(base: [f64; 3], length: f64, radius: f64, segments: usize, rings: usize) -> Surface {
    let segments = segments.max(3);
    let rings = rings.max(1);
    let bottom = base[1] + radius;
    let top = base[1] + length - radius;
    let mut levels: Vec<(f64, f64)> = Vec::new();
    for i in 1..=rings {
        let a = std::f64::consts::FRAC_PI_2 * i as f64 / rings as f64;
        levels.push((bottom - radius * a.cos(), radius * a.sin()));
    }
    let arc = 2.0 * std::f64::consts::PI * radius / segments as f64;
    let body = (((top - bottom) / arc).round() as usize).max(1);
    for i in 1..body {
        levels.push((bottom + (top - bottom) * i as f64 / body as f64, radius));
    }
    for i in (1..=rings).rev() {
        let a = std::f64::consts::FRAC_PI_2 * i as f64 / rings as f64;
        levels.push((top + radius * a.cos(), radius * a.sin()));
    }
    revolve(base, length, &levels, segments)
}

/// A solid cylinder along y from `base` (the centre of its bottom face) to
/// `base + height`, flat ends: `segments` vertices around, rings on the end faces and the
/// side about as far apart as the vertices of a ring.
pub fn cylinder(base: [f64; 3], height: f64, radius: f64, segments: usize) -> Surface {
    let segments = segments.max(3);
    let arc = 2.0 * std::f64::consts::PI * radius / segments as f64;
    let caps = ((radius / arc).round() as usize).max(1);
    let body = ((height / arc).round() as usize).max(1);
    let mut levels: Vec<(f64, f64)> = Vec::new();
    for i in 1..=caps {
        levels.push((base[1], radius * i as f64 / caps as f64));
    }
    for i in 1..body {
        levels.push((base[1] + height * i as f64 / body as f64, radius));
    }
    for i in (1..=caps).rev() {
        levels.push((base[1] + height, radius * i as f64 / caps as f64));
    }
    revolve(base, height, &levels, segments)
}

/// The closed surface of revolution about the y axis through `base` with poles at `base`
/// and `base + length` and the rings `levels` (height, radius) between them, bottom to
/// top, `segments` vertices per ring.
fn revolve(base: [f64; 3], length: f64, levels: &[(f64, f64)], segments: usize) -> Surface {
    let mut vertices = vec![base];
    for &(y, r) in levels {
        for k in 0..segments {
            let a = 2.0 * std::f64::consts::PI * k as f64 / segments as f64;
            vertices.push([base[0] + r * a.cos(), y, base[2] - r * a.sin()]);
        }
    }
    vertices.push([base[0], base[1] + length, base[2]]);
    let s = segments as u32;
    let last = vertices.len() as u32 - 1;
    let mut triangles = Vec::new();
    // Around +y a ring runs from x to -z; triangles are counter-clockwise from outside.
    for k in 0..s {
        triangles.push([0, 1 + (k + 1) % s, 1 + k]);
    }
    for l in 0..levels.len() as u32 - 1 {
        let (a, b) = (1 + l * s, 1 + (l + 1) * s);
        for k in 0..s {
            let k1 = (k + 1) % s;
            triangles.push([a + k, b + k1, b + k]);
            triangles.push([a + k, a + k1, b + k1]);
        }
    }
    let top_ring = 1 + (levels.len() as u32 - 1) * s;
    for k in 0..s {
        triangles.push([last, top_ring + k, top_ring + (k + 1) % s]);
    }
    let volume = super::signed_volume(&vertices, &triangles);
    Surface {
        vertices,
        triangles,
        volume,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// All are closed and outward, and their volumes approach the solids' from below.
    #[test]
    fn shapes_are_closed_outward_and_near_their_volume() {
        let p = std::path::Path::new("shape");
        let s = icosphere([0.0; 3], 0.05, 4);
        crate::geometry::obj::check_closed_manifold(p, s.vertices.len(), &s.triangles).unwrap();
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 0.05f64.powi(3);
        assert!(
            s.volume < exact && s.volume > 0.99 * exact,
            "{} vs {exact}",
            s.volume
        );
        let c = capsule([0.0; 3], 0.1, 0.02, 48, 12);
        crate::geometry::obj::check_closed_manifold(p, c.vertices.len(), &c.triangles).unwrap();
        let exact = std::f64::consts::PI * 0.02f64.powi(2) * (0.1 - 0.04)
            + 4.0 / 3.0 * std::f64::consts::PI * 0.02f64.powi(3);
        assert!(
            c.volume < exact && c.volume > 0.99 * exact,
            "{} vs {exact}",
            c.volume
        );
        let c = cylinder([0.0; 3], 0.1, 0.025, 64);
        crate::geometry::obj::check_closed_manifold(p, c.vertices.len(), &c.triangles).unwrap();
        let exact = std::f64::consts::PI * 0.025f64.powi(2) * 0.1;
        assert!(
            c.volume < exact && c.volume > 0.99 * exact,
            "{} vs {exact}",
            c.volume
        );
    }
}
