//! The cubic lattices that interior sampling, resampling and cell volumes lay over a
//! surface.

/// A cubic lattice of spacing `h` over a point set's bounds, centred on them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lattice {
    /// Position of lattice point (0, 0, 0).
    pub origin: [f64; 3],
    /// Points along each axis.
    pub dims: [usize; 3],
    /// Spacing in metres.
    pub spacing: f64,
}

impl Lattice {
    /// The lattice of spacing `h` whose points cover the bounds of `points` (centred on
    /// them), plus `margin` more points on every side.
    pub fn covering(points: &[[f64; 3]], h: f64, margin: usize) -> Lattice {
        let (lo, hi) = super::bounds(points);
        // A tolerance of 1e-9 spacings keeps an extent of exactly n spacings at n + 1
        // points (a lattice plane on both bounds), as for boxes.
        let inner: [usize; 3] =
            std::array::from_fn(|a| ((hi[a] - lo[a]) / h + 1e-9).floor() as usize + 1);
        Lattice {
            origin: std::array::from_fn(|a| {
                lo[a] + 0.5 * ((hi[a] - lo[a]) - (inner[a] - 1) as f64 * h) - margin as f64 * h
            }),
            dims: inner.map(|n| n + 2 * margin),
            spacing: h,
        }
    }

    /// Lattice points a surface with these bounds would need at spacing `h` (before
    /// building it, to reject absurd sizes).
    pub fn count(lo: [f64; 3], hi: [f64; 3], h: f64, margin: usize) -> f64 {
        (0..3)
            .map(|a| ((hi[a] - lo[a]) / h + 1e-9).floor() + 1.0 + 2.0 * margin as f64)
            .product()
    }

    /// Position of point `(i, j, k)`.
    pub fn point(&self, p: [usize; 3]) -> [f64; 3] {
        std::array::from_fn(|a| self.origin[a] + p[a] as f64 * self.spacing)
    }
}
