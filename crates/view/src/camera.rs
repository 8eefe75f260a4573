//! An orbit camera: it looks at a target from a yaw, pitch and distance, with +z up.
//! [`Camera::frame`] picks a three-quarter view from above, on the side the needle comes
//! from, that holds the tissue and the needle.

use crate::frame::Frame;
use glam::{Mat4, Vec3};

/// Vertical field of view, radians (35 degrees).
pub const FOV_Y: f32 = 35.0 * std::f32::consts::PI / 180.0;

/// A perspective camera orbiting a target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// The point looked at, m.
    pub target: Vec3,
    /// Angle of the camera about +z from +x, radians.
    pub yaw: f32,
    /// Elevation of the camera above the xy plane, radians (kept within +-89 degrees).
    pub pitch: f32,
    /// Distance from the target, m.
    pub distance: f32,
    /// Radius of the scene around the target, m (sets the clipping planes and the needle's
    /// drawn thickness).
    pub extent: f32,
}

/// Where the target appears, normalised device coordinates: a little left of and above
/// the centre, away from the plot inset in the bottom-right corner.
pub const SHIFT: [f32; 2] = [-0.08, 0.06];

/// Largest pitch magnitude, radians.
const MAX_PITCH: f32 = 89.0 * std::f32::consts::PI / 180.0;

impl Camera {
    /// Frames the bounding box of `frame` (tissue and needle): the target is its centre,
    /// the view comes from 28 degrees above, turned 65 degrees about +z from the side the
    /// needle enters (looking straight along the needle would hide it), far enough that
    /// the box's bounding sphere fits the vertical field of view.
    pub fn frame(frame: &Frame) -> Camera {
        let (lo, hi) = frame.bounds().unwrap_or(([-1.0; 3], [1.0; 3]));
        let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
        let target = (lo + hi) * 0.5;
        let extent = ((hi - lo).length() * 0.5).max(1e-6);
        let back = frame
            .needle
            .map(|(b, t)| Vec3::from(b) - Vec3::from(t))
            .filter(|d| d.x.hypot(d.y) > 1e-3 * d.length())
            .map(|d| d.y.atan2(d.x))
            .unwrap_or(-std::f32::consts::FRAC_PI_2);
        Camera {
            target,
            yaw: back + 65f32.to_radians(),
            pitch: 28f32.to_radians(),
            distance: extent / (FOV_Y * 0.5).sin() * 1.1,
            extent,
        }
    }

    /// The camera position, m.
    pub fn eye(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        self.target + self.distance * Vec3::new(cp * cy, cp * sy, sp)
    }

    /// World to clip space (wgpu's depth range 0..1) for an image of `aspect` = width /
    /// height, the target at [`SHIFT`]. A narrow image widens the view so that the horizontal field is at least the
    /// vertical one.
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        let aspect = aspect.max(1e-3);
        let fov = if aspect < 1.0 {
            2.0 * ((FOV_Y * 0.5).tan() / aspect).atan()
        } else {
            FOV_Y
        };
        let near = (self.distance - 2.0 * self.extent).max(self.distance * 0.01);
        let far = self.distance + 2.0 * self.extent;
        let view = glam::camera::rh::view::look_at_mat4(self.eye(), self.target, Vec3::Z);
        let shift = Mat4::from_translation(Vec3::new(SHIFT[0], SHIFT[1], 0.0));
        shift * glam::camera::rh::proj::directx::perspective(fov, aspect, near, far) * view
    }

    /// Turns the camera by `yaw` and `pitch` radians (pitch clamped to +-89 degrees).
    pub fn orbit(&mut self, yaw: f32, pitch: f32) {
        self.yaw = (self.yaw + yaw).rem_euclid(std::f32::consts::TAU);
        self.pitch = (self.pitch + pitch).clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// Multiplies the distance by `factor` (kept between 0.05 and 20 scene radii).
    pub fn zoom(&mut self, factor: f32) {
        self.distance = (self.distance * factor).clamp(0.05 * self.extent, 20.0 * self.extent);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_puts_the_target_at_the_shift_and_the_box_in_view() {
        let frame = Frame {
            regions: Vec::new(),
            positions: vec![[0.0, 0.0, 0.0], [0.2, 0.2, 0.2], [0.2, 0.0, 0.0]],
            triangles: vec![[0, 1, 2]],
            needle: Some(([-0.2, 0.1, 0.1], [0.0, 0.1, 0.1])),
            ..Frame::default()
        };
        let c = Camera::frame(&frame);
        let p = c.view_proj(1.5) * c.target.extend(1.0);
        assert!((p.x / p.w - SHIFT[0]).abs() < 1e-5 && (p.y / p.w - SHIFT[1]).abs() < 1e-5);
        assert!(p.z / p.w > 0.0 && p.z / p.w < 1.0);
        // Looking from the entry side (-x) and from above.
        let eye = c.eye();
        assert!(eye.x < c.target.x && eye.z > c.target.z);
        // Every corner of the box is inside the view.
        let vp = c.view_proj(1.5);
        for &x in &[-0.2f32, 0.2] {
            for &y in &[0.0f32, 0.2] {
                for &z in &[0.0f32, 0.2] {
                    let q = vp * Vec3::new(x, y, z).extend(1.0);
                    assert!((q.x / q.w).abs() <= 1.0 && (q.y / q.w).abs() <= 1.0);
                    assert!(q.z / q.w > 0.0 && q.z / q.w < 1.0);
                }
            }
        }
    }
}
