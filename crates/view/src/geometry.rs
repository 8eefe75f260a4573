//! The vertex lists drawn for a [`Frame`], built on the CPU every frame: the tissue surface
//! with area-weighted vertex normals, the needle cylinder, the node markers and the plot
//! inset (in normalised device coordinates).

use crate::camera::Camera;
use crate::colors::{self, rgba};
use crate::frame::Frame;
use glam::Vec3;
use needlesim_needle::NodeRole;

/// One vertex of every pipeline: a position, a second vector (the normal of lit geometry,
/// the pixel offset of a marker corner) and a colour with alpha.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Vertex {
    /// Position: world space, or normalised device coordinates for overlays.
    pub position: [f32; 3],
    /// Normal (lit geometry) or pixel offset (markers).
    pub extra: [f32; 3],
    /// Colour, 0..1, with alpha.
    pub color: [f32; 4],
}

/// The tissue surface: one vertex per node (normal = sum of the cross products of its
/// triangles, so that larger triangles weigh more) and the triangle indices (triangles
/// naming a node out of range are skipped).
pub fn tissue(frame: &Frame) -> (Vec<Vertex>, Vec<u32>) {
    let n = frame.positions.len();
    let mut normals = vec![Vec3::ZERO; n];
    let mut indices = Vec::with_capacity(frame.triangles.len() * 3);
    for t in &frame.triangles {
        if t.iter().any(|&i| i as usize >= n) {
            continue;
        }
        let [a, b, c] = t.map(|i| Vec3::from(frame.positions[i as usize]));
        let face = (b - a).cross(c - a);
        if !face.is_finite() {
            continue;
        }
        for &i in t {
            normals[i as usize] += face;
        }
        indices.extend_from_slice(t);
    }
    let vertices = frame
        .positions
        .iter()
        .zip(&normals)
        .enumerate()
        .map(|(i, (&p, nrm))| Vertex {
            position: p,
            extra: nrm.normalize_or_zero().into(),
            color: rgba(
                colors::region(frame.regions.get(i).copied().unwrap_or(0)),
                colors::TISSUE_ALPHA,
            ),
        })
        .collect();
    (vertices, indices)
}

/// Sides of the needle cylinder.
const NEEDLE_SIDES: usize = 16;

/// Drawn radius of the needle: 0.6% of the scene radius, and at least 2 pixels at the
/// target's distance in an image `height` pixels high (a real 18 G needle, 1.3 mm wide,
/// would be under a pixel wide).
pub fn needle_radius(camera: &Camera, height: u32) -> f32 {
    let pixel = 2.0 * camera.distance * (crate::camera::FOV_Y * 0.5).tan() / height.max(1) as f32;
    (0.006 * camera.extent).max(2.0 * pixel)
}

/// The needle from `base` to `tip` as a lit cylinder of `radius` whose last 4 radii form
/// a cone to the tip, as a triangle list.
pub fn needle(base: [f32; 3], tip: [f32; 3], radius: f32) -> Vec<Vertex> {
    let (b, t) = (Vec3::from(base), Vec3::from(tip));
    let axis = t - b;
    let len = axis.length();
    if !(len > 0.0 && len.is_finite() && radius > 0.0) {
        return Vec::new();
    }
    let d = axis / len;
    let cone = (4.0 * radius).min(0.5 * len);
    let shoulder = t - d * cone;
    let (u, v) = d.any_orthonormal_pair();
    let color = rgba(colors::NEEDLE, 1.0);
    let ring = |k: usize| {
        let a = k as f32 / NEEDLE_SIDES as f32 * std::f32::consts::TAU;
        u * a.cos() + v * a.sin()
    };
    let vert = |p: Vec3, nrm: Vec3| Vertex {
        position: p.into(),
        extra: nrm.into(),
        color,
    };
    // The cone's normal leans towards the tip by the cone's half angle.
    let slope = radius / cone;
    let mut out = Vec::with_capacity(NEEDLE_SIDES * 12);
    for k in 0..NEEDLE_SIDES {
        let (r0, r1) = (ring(k), ring(k + 1));
        let (p0, p1) = (b + r0 * radius, b + r1 * radius);
        let (q0, q1) = (shoulder + r0 * radius, shoulder + r1 * radius);
        out.extend([
            vert(p0, r0),
            vert(p1, r1),
            vert(q1, r1),
            vert(p0, r0),
            vert(q1, r1),
            vert(q0, r0),
        ]);
        let (c0, c1) = ((r0 + d * slope).normalize(), (r1 + d * slope).normalize());
        out.extend([vert(q0, c0), vert(q1, c1), vert(t, (c0 + c1).normalize())]);
        // The flat back end.
        out.extend([vert(b, -d), vert(p1, -d), vert(p0, -d)]);
    }
    out
}

/// Side of a node marker in pixels for an image `height` pixels high (at least 7).
pub fn marker_size(height: u32) -> f32 {
    (height as f32 / 70.0).max(7.0)
}

/// The colour of a marker of `role`.
pub fn marker_color(role: NodeRole) -> [u8; 3] {
    match role {
        NodeRole::Shaft => colors::SHAFT_MARKER,
        NodeRole::Surface => colors::SURFACE_MARKER,
        NodeRole::Tip => colors::TIP_MARKER,
        NodeRole::Exit => colors::EXIT_MARKER,
    }
}

/// Camera-facing squares of `size` pixels, outlined, one per marker: shaft nodes first,
/// then the surface, exit and tip nodes, so that those stay on top.
pub fn markers(frame: &Frame, size: f32) -> Vec<Vertex> {
    let order = |r: NodeRole| match r {
        NodeRole::Shaft => 0,
        NodeRole::Surface => 1,
        NodeRole::Exit => 2,
        NodeRole::Tip => 3,
    };
    let mut sorted: Vec<_> = frame.markers.iter().collect();
    sorted.sort_by_key(|m| order(m.role));
    let mut out = Vec::with_capacity(sorted.len() * 12);
    let square = |out: &mut Vec<Vertex>, p: [f32; 3], half: f32, color: [f32; 4]| {
        let corners = [
            [-half, -half],
            [half, -half],
            [half, half],
            [-half, -half],
            [half, half],
            [-half, half],
        ];
        out.extend(corners.iter().map(|c| Vertex {
            position: p,
            extra: [c[0], c[1], 0.0],
            color,
        }));
    };
    for m in sorted {
        let half = size * 0.5;
        square(
            &mut out,
            m.position,
            half,
            rgba(colors::MARKER_OUTLINE, 1.0),
        );
        square(
            &mut out,
            m.position,
            half - (size / 7.0).max(1.0),
            rgba(marker_color(m.role), 1.0),
        );
    }
    out
}

/// The plot inset's panel in pixels, (x0, y0, x1, y1) with y down: the bottom-right
/// corner, 36% of the width and 32% of the height, 2% of the height from the edges.
pub fn plot_panel(width: u32, height: u32) -> [f32; 4] {
    let (w, h) = (width as f32, height as f32);
    let margin = (0.02 * h).round();
    let pw = (0.36 * w).round();
    let ph = (0.32 * h).round();
    [w - margin - pw, h - margin - ph, w - margin, h - margin]
}

/// The plot's axes box inside the panel, pixels (x0, y0, x1, y1), y down.
pub fn plot_axes(width: u32, height: u32) -> [f32; 4] {
    let [x0, y0, x1, y1] = plot_panel(width, height);
    let pad = (0.08 * (y1 - y0)).round().max(3.0);
    [x0 + pad, y0 + pad, x1 - pad, y1 - pad]
}

/// Width of plot lines in pixels for an image `height` pixels high (at least 2).
pub fn line_width(height: u32) -> f32 {
    (height as f32 / 300.0).max(2.0)
}

/// Builds flat 2D shapes in pixel coordinates (y down) as vertices in normalised device
/// coordinates.
struct Overlay {
    width: f32,
    height: f32,
    out: Vec<Vertex>,
}

impl Overlay {
    fn vertex(&self, x: f32, y: f32, color: [f32; 4]) -> Vertex {
        Vertex {
            position: [x / self.width * 2.0 - 1.0, 1.0 - y / self.height * 2.0, 0.0],
            extra: [0.0; 3],
            color,
        }
    }

    fn rect(&mut self, x0: f32, y0: f32, x1: f32, y1: f32, color: [f32; 4]) {
        let v = [
            self.vertex(x0, y0, color),
            self.vertex(x1, y0, color),
            self.vertex(x1, y1, color),
            self.vertex(x0, y1, color),
        ];
        self.out.extend([v[0], v[1], v[2], v[0], v[2], v[3]]);
    }

    /// A segment as a quad `w` pixels wide, extended by half that at both ends so that
    /// consecutive segments join without gaps.
    fn line(&mut self, a: [f32; 2], b: [f32; 2], w: f32, color: [f32; 4]) {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let len = dx.hypot(dy);
        let (ux, uy) = if len > 1e-6 {
            (dx / len, dy / len)
        } else {
            (1.0, 0.0)
        };
        let h = w * 0.5;
        let (ax, ay) = (a[0] - ux * h, a[1] - uy * h);
        let (bx, by) = (b[0] + ux * h, b[1] + uy * h);
        let (nx, ny) = (-uy * h, ux * h);
        let v = [
            self.vertex(ax + nx, ay + ny, color),
            self.vertex(bx + nx, by + ny, color),
            self.vertex(bx - nx, by - ny, color),
            self.vertex(ax - nx, ay - ny, color),
        ];
        self.out.extend([v[0], v[1], v[2], v[0], v[2], v[3]]);
    }
}

/// The value range drawn for `values`: from the smaller of 0 and their minimum to the
/// larger of 0 and their maximum, widened by 5% (and to at least `floor`).
fn range(values: impl Iterator<Item = f32>, floor: f32) -> (f32, f32) {
    let (mut lo, mut hi) = (0.0f32, 0.0f32);
    for v in values.filter(|v| v.is_finite()) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    if hi - lo < floor {
        hi = lo + floor;
    }
    let pad = 0.05 * (hi - lo);
    (if lo < 0.0 { lo - pad } else { lo }, hi + pad)
}

/// The force-depth plot inset: white panel, axes box, the zero-force line, the curve
/// (depth from 0 to its maximum on x, force auto-scaled on y, both ranges including 0),
/// and the latest sample as a red square. Empty curves draw the panel and axes only.
pub fn plot(frame: &Frame, width: u32, height: u32) -> Vec<Vertex> {
    let mut o = Overlay {
        width: width as f32,
        height: height as f32,
        out: Vec::new(),
    };
    let lw = line_width(height);
    let [px0, py0, px1, py1] = plot_panel(width, height);
    o.rect(px0, py0, px1, py1, rgba(colors::PLOT_PANEL, 1.0));
    let [x0, y0, x1, y1] = plot_axes(width, height);
    let pts: Vec<[f32; 2]> = frame
        .force_depth
        .iter()
        .copied()
        .filter(|p| p[0].is_finite() && p[1].is_finite())
        .collect();
    let (_, dmax) = range(pts.iter().map(|p| p[0].max(0.0)), 1e-3);
    let (fmin, fmax) = range(pts.iter().map(|p| p[1]), 1e-3);
    let sx = |d: f32| x0 + (d.max(0.0) / dmax).min(1.0) * (x1 - x0);
    let sy = |f: f32| y1 - (f - fmin) / (fmax - fmin) * (y1 - y0);
    let zero = sy(0.0);
    o.line(
        [x0, zero],
        [x1, zero],
        lw * 0.75,
        rgba(colors::PLOT_ZERO, 1.0),
    );
    let curve = rgba(colors::PLOT_CURVE, 1.0);
    for w in pts.windows(2) {
        o.line(
            [sx(w[0][0]), sy(w[0][1])],
            [sx(w[1][0]), sy(w[1][1])],
            lw,
            curve,
        );
    }
    let axes = rgba(colors::PLOT_AXES, 1.0);
    o.line([x0, y0], [x1, y0], lw * 0.75, axes);
    o.line([x1, y0], [x1, y1], lw * 0.75, axes);
    o.line([x1, y1], [x0, y1], lw * 0.75, axes);
    o.line([x0, y1], [x0, y0], lw * 0.75, axes);
    if let Some(p) = pts.last() {
        let (cx, cy) = (sx(p[0]), sy(p[1]));
        let h = lw * 1.75;
        o.rect(
            cx - h,
            cy - h,
            cx + h,
            cy + h,
            rgba(colors::PLOT_CURRENT, 1.0),
        );
    }
    o.out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_normals_are_area_weighted() {
        // Two triangles sharing node 0: a large one in the xy plane (normal +z) and a
        // small one in the xz plane (normal -y).
        let frame = Frame {
            regions: Vec::new(),
            positions: vec![
                [0.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [0.0, 2.0, 0.0],
                [0.1, 0.0, 0.0],
                [0.0, 0.0, 0.1],
            ],
            triangles: vec![[0, 1, 2], [0, 3, 4], [0, 1, 9]],
            ..Frame::default()
        };
        let (v, idx) = tissue(&frame);
        assert_eq!(idx, vec![0, 1, 2, 0, 3, 4]);
        let n = Vec3::from(v[0].extra);
        assert!((n.length() - 1.0).abs() < 1e-5);
        assert!(n.z > 0.99 && n.y < 0.0);
        assert_eq!(v[1].extra, [0.0, 0.0, 1.0]);
    }

    #[test]
    fn plot_handles_empty_and_flat_curves() {
        let mut frame = Frame::default();
        assert_eq!(plot(&frame, 100, 80).len(), 6 + 5 * 6);
        frame.force_depth = vec![[0.0, 0.0], [0.0, 0.0]];
        let v = plot(&frame, 100, 80);
        assert!(v
            .iter()
            .all(|v| v.position.iter().all(|c| c.is_finite() && c.abs() <= 1.0)));
    }
}
