//! The frame a backend stores positions in: the world translated by a per-body origin, so
//! that a body far from the world's origin keeps the position resolution it would have
//! near it (issue 41, item 2).
//!
//! # Why
//!
//! Positions are f32. Their spacing grows with the distance from the origin: 7.5e-9 m at
//! 0.1 m, 1.2e-7 m at 1 m. The integrator's compensated sum ([`crate::integrator`])
//! loses no increment, but the forces see the stored f32 position, so the same body
//! deformed less precisely the farther it sat from the origin. Measured on the dev machine
//! before this frame (`tests/precision.rs`, a 10 cm cube sagging about 3 mm): placed 1 m
//! from the origin, its displacement field differed from the one at the origin by up to
//! 6.3e-5 of the sag, and for a 23 um sag the spacing at 1 m alone is 0.5% of it.
//!
//! Every force of every model depends only on differences of positions and differences
//! of rest positions (`x_j - x_i`, `X_j - X_i`), never on a position itself, so the
//! positions and the rest positions may live in a translated frame: the tissue builds
//! both in it ([`crate::tissue::Tissue::frame`]), from the f64 node cloud, rounding once.
//!
//! # The origin
//!
//! With `G` the smallest power of two at least the body's largest extent and `c` the
//! centre of its bounds, each axis's origin is `round(c / G) G` when `|c| > G`, and 0
//! otherwise. So:
//! - a body within about its own size of the origin keeps the world frame (every shipped
//!   scene does: their results are bitwise those of before);
//! - in the frame every coordinate is within `1.5 G` of zero, so the spacing is at most
//!   `2^-23 x 1.5 G` whatever the placement;
//! - the origin is a multiple of `G`, so moving a body by a multiple of `G` (1 m is one
//!   for any body up to 1 m) gives it the same frame coordinates up to the rounding of
//!   its world rest positions;
//! - a world f32 position near the body, minus the origin, is exact in f32 (both are
//!   multiples of the world position's unit in the last place, and the difference is
//!   smaller than the position), so a body starts exactly at its rest shape.
//!
//! # What a backend shows
//!
//! The backends convert at their interface ([`crate::backend::Backend`]): a position read
//! is the world position rounded to f32, the position remainder read is the rest of the
//! world position (`world = position + remainder` to about 2^-48 of its distance from
//! the world's origin, 3.6e-15 m at 1 m); a position written is a world position, a
//! remainder written is added to it. In the world frame (origin 0) every conversion is
//! the identity, bit for bit. [`crate::backend::NodeField::StoredPosition`] and
//! `StoredRemainder` give the stored values unconverted, for checkpoints.

use crate::math::Vec4;

/// A translation of the world by a per-body origin (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PositionFrame {
    origin: [f64; 3],
}

impl PositionFrame {
    /// The world frame (origin 0).
    pub const WORLD: PositionFrame = PositionFrame { origin: [0.0; 3] };

    /// The frame for a body whose nodes are at `positions` (world, metres; module docs).
    /// The world frame for no node, a single point or non-finite positions.
    pub fn for_body(positions: &[[f64; 3]]) -> PositionFrame {
        let (lo, hi) = crate::geometry::bounds(positions);
        let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        if !(extent > 0.0 && extent.is_finite()) || (0..3).any(|a| !lo[a].is_finite()) {
            return PositionFrame::WORLD;
        }
        let g = 2f64.powi(extent.log2().ceil() as i32);
        let origin = [0, 1, 2].map(|a| {
            let c = 0.5 * (lo[a] + hi[a]);
            if c.abs() > g {
                (c / g).round() * g
            } else {
                0.0
            }
        });
        PositionFrame { origin }
    }

    /// A world point (f64) in this frame, rounded to f32 once.
    #[inline]
    pub fn local(&self, world: [f64; 3]) -> [f32; 3] {
        let o = self.origin;
        [0, 1, 2].map(|a| (world[a] - o[a]) as f32)
    }

    /// A point of this frame in world coordinates (f64, exact for an f32 point).
    #[inline]
    pub fn global(&self, local: [f32; 3]) -> [f64; 3] {
        let o = self.origin;
        [0, 1, 2].map(|a| local[a] as f64 + o[a])
    }

    /// The frame's origin in world coordinates, metres.
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    /// Whether this is the world frame (every conversion is the identity).
    pub fn is_world(&self) -> bool {
        self.origin == [0.0; 3]
    }

    /// A world position (xyz; w kept) in this frame.
    #[inline]
    pub fn to_frame(&self, world: Vec4) -> Vec4 {
        let q = self.local([world[0] as f64, world[1] as f64, world[2] as f64]);
        [q[0], q[1], q[2], world[3]]
    }

    /// A stored position (xyz; w kept) in world coordinates, rounded to f32.
    #[inline]
    pub fn to_world(&self, stored: Vec4) -> Vec4 {
        let w = self.global([stored[0], stored[1], stored[2]]);
        [w[0] as f32, w[1] as f32, w[2] as f32, stored[3]]
    }

    /// The world position's part below f32 resolution: what [`PositionFrame::to_world`]
    /// rounded off `stored`, plus the stored remainder (w kept from `remainder`).
    #[inline]
    pub fn world_remainder(&self, stored: Vec4, remainder: Vec4) -> Vec4 {
        let o = self.origin;
        let part = |a: usize| {
            let exact = stored[a] as f64 + o[a];
            ((exact - exact as f32 as f64) + remainder[a] as f64) as f32
        };
        [part(0), part(1), part(2), remainder[3]]
    }

    /// Stored positions, read into `out`, as a read of world positions gives them
    /// ([`PositionFrame::to_world`]; nothing to do in the world frame).
    pub fn positions_to_world(&self, out: &mut [Vec4]) {
        if !self.is_world() {
            out.iter_mut().for_each(|p| *p = self.to_world(*p));
        }
    }

    /// Stored remainders, read into `out`, as a read of world remainders gives them, from
    /// the stored positions `stored` of the same nodes ([`PositionFrame::world_remainder`];
    /// nothing to do in the world frame).
    pub fn remainders_to_world(&self, out: &mut [Vec4], stored: &[Vec4]) {
        if !self.is_world() {
            for (r, p) in out.iter_mut().zip(stored) {
                *r = self.world_remainder(*p, *r);
            }
        }
    }

    /// [`PositionFrame::to_frame`] on every element (nothing to do in the world frame).
    pub fn slice_to_frame(&self, data: &mut [Vec4]) {
        if !self.is_world() {
            data.iter_mut().for_each(|p| *p = self.to_frame(*p));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(shift: f64) -> Vec<[f64; 3]> {
        (0..27)
            .map(|i| [i % 3, (i / 3) % 3, i / 9].map(|k| shift + 0.05 * k as f64))
            .collect()
    }

    #[test]
    fn a_body_near_the_origin_keeps_the_world_frame() {
        assert!(PositionFrame::for_body(&cube(0.0)).is_world());
        assert!(PositionFrame::for_body(&cube(-0.05)).is_world());
        assert!(PositionFrame::for_body(&[]).is_world());
        assert!(PositionFrame::for_body(&cube(0.0)[..1]).is_world());
        let mut bad = cube(0.0);
        bad[3][1] = f64::NAN;
        assert!(PositionFrame::for_body(&bad).is_world());
    }

    #[test]
    fn a_body_1_m_away_gets_the_same_coordinates_as_at_the_origin() {
        // The 0.1 m cube: G = 0.125; at 1 m its centre 1.05 rounds to 8 G = 1 m.
        let far = cube(1.0);
        let frame = PositionFrame::for_body(&far);
        assert_eq!(frame.origin(), [1.0; 3]);
        for (p, q) in far.iter().zip(cube(0.0)) {
            let s = frame.local(*p);
            assert_eq!(s, q.map(|c| c as f32), "the same f32 coordinates");
            let w = frame.global(s);
            assert!((0..3).all(|a| (w[a] - p[a]).abs() < 1e-8), "round trip");
        }
    }

    #[test]
    fn the_remainder_carries_what_the_world_position_rounds_off() {
        let frame = PositionFrame {
            origin: [1.0, -2.0, 0.0],
        };
        let stored = [1.234_567e-3, 3.3e-2, 0.1, 0.5];
        let remainder = [1e-12, -2e-12, 3e-12, 0.0];
        let w = frame.to_world(stored);
        let r = frame.world_remainder(stored, remainder);
        for a in 0..3 {
            let exact = stored[a] as f64 + frame.origin[a] + remainder[a] as f64;
            let got = w[a] as f64 + r[a] as f64;
            // The world remainder is an f32 of up to half the world spacing (6e-8 m at
            // 1 m), so it resolves 2^-24 of that: 3.6e-15 m.
            assert!(
                (got - exact).abs() < 4e-15,
                "axis {a}: {got} against {exact}"
            );
        }
        // In the world frame both are the identity.
        assert_eq!(PositionFrame::WORLD.to_world(stored), stored);
        assert_eq!(
            PositionFrame::WORLD.world_remainder(stored, remainder),
            remainder
        );
        assert_eq!(PositionFrame::WORLD.to_frame(stored), stored);
    }
}
