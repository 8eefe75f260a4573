//! The rigid straight needle: base `b`, unit direction `t` (base to tip), length `L`, tip
//! `b + L t`, and its roll: the angle it has turned about its own axis (spin), which moves
//! the shaft's surface past the tissue around it (the friction sees it,
//! [`crate::sheath`]) but not the shaft's line.

use glam::DVec3;
use thiserror::Error;

/// A needle pose or parameter that cannot be simulated.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum NeedleError {
    /// A coordinate is NaN or infinite.
    #[error("needle {what} must be finite, got {value:?}")]
    NonFinite {
        /// Which quantity.
        what: &'static str,
        /// Its value.
        value: [f64; 3],
    },
    /// The direction has (almost) zero length.
    #[error("needle direction must be non-zero, got {0:?}")]
    ZeroDirection([f64; 3]),
    /// The length is not positive.
    #[error("needle length must be a finite number > 0, got {0}")]
    BadLength(f64),
    /// The roll angle is not finite.
    #[error("needle roll must be a finite angle in radians, got {0}")]
    BadRoll(f64),
    /// The base lies beyond [`MAX_BASE_DISTANCE`] of the origin.
    #[error(
        "needle base must lie within {MAX_BASE_DISTANCE:e} m of the origin (the tissue's \
         positions are f32), got {0:?}"
    )]
    FarBase([f64; 3]),
}

/// The farthest a needle's base may be from the origin, m: the tissue is stored in f32,
/// and a base at 1e300 m overflowed the contact's sweep to infinity, where its checks
/// (the move across the body in one step) compared NaN and let the pose through.
pub const MAX_BASE_DISTANCE: f64 = 1e30;

/// `base` as a point, or the error naming it if not finite or too far.
fn base_point(base: [f64; 3]) -> Result<DVec3, NeedleError> {
    let b = finite("base", base)?;
    if b.abs().max_element() > MAX_BASE_DISTANCE {
        return Err(NeedleError::FarBase(base));
    }
    Ok(b)
}

/// A rigid straight needle.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Needle {
    base: DVec3,
    direction: DVec3,
    length: f64,
    /// Angle turned about its own axis since the start, radians (right-handed about the
    /// direction).
    roll: f64,
}

fn finite(what: &'static str, v: [f64; 3]) -> Result<DVec3, NeedleError> {
    let d = DVec3::from_array(v);
    if d.is_finite() {
        Ok(d)
    } else {
        Err(NeedleError::NonFinite { what, value: v })
    }
}

/// `v / |v|`, or an error for a zero or non-finite vector.
pub fn unit(v: [f64; 3]) -> Result<[f64; 3], NeedleError> {
    let d = finite("direction", v)?;
    // Scaled by the largest component first, so that neither [1e300, 0, 0] (whose norm
    // overflows) nor [1e-200, 0, 0] (whose squares underflow) normalises to zero.
    let m = d.abs().max_element();
    if m == 0.0 {
        return Err(NeedleError::ZeroDirection(v));
    }
    let w = d / m;
    Ok((w / w.length()).to_array())
}

impl Needle {
    /// A needle from its base, a direction (normalised here) and its length in metres.
    pub fn new(base: [f64; 3], direction: [f64; 3], length: f64) -> Result<Needle, NeedleError> {
        let base = base_point(base)?;
        if !(length.is_finite() && length > 0.0) {
            return Err(NeedleError::BadLength(length));
        }
        Ok(Needle {
            base,
            direction: DVec3::from_array(unit(direction)?),
            length,
            roll: 0.0,
        })
    }

    /// Base point.
    pub fn base(&self) -> [f64; 3] {
        self.base.to_array()
    }

    /// Unit direction from base to tip.
    pub fn direction(&self) -> [f64; 3] {
        self.direction.to_array()
    }

    /// Length in metres.
    pub fn length(&self) -> f64 {
        self.length
    }

    /// Tip point `b + L t`.
    pub fn tip(&self) -> [f64; 3] {
        (self.base + self.direction * self.length).to_array()
    }

    /// Angle the needle has turned about its own axis, radians (right-handed about the
    /// direction); 0 at the start pose.
    pub fn roll(&self) -> f64 {
        self.roll
    }

    /// Sets the roll angle (radians), leaving the shaft's line where it is.
    pub fn set_roll(&mut self, roll: f64) -> Result<(), NeedleError> {
        if !roll.is_finite() {
            return Err(NeedleError::BadRoll(roll));
        }
        self.roll = roll;
        Ok(())
    }

    /// Moves the needle to a new pose (same length and roll).
    pub fn set_pose(&mut self, base: [f64; 3], direction: [f64; 3]) -> Result<(), NeedleError> {
        let base = base_point(base)?;
        self.direction = DVec3::from_array(unit(direction)?);
        self.base = base;
        Ok(())
    }

    /// Splits `p - b` into the distance along the shaft's line (not clamped to the shaft)
    /// and the perpendicular offset.
    pub fn project(&self, p: [f64; 3]) -> (f64, [f64; 3]) {
        let d = DVec3::from_array(p) - self.base;
        let s = d.dot(self.direction);
        (s, (d - self.direction * s).to_array())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_base_beyond_f32s_range_is_an_error() {
        let mut n = Needle::new([0.0, 1.0, 0.0], [2.0, 0.0, 0.0], 0.15).unwrap();
        let far = [1e300, 0.0513, 0.0487];
        assert_eq!(
            n.set_pose(far, [1.0, 0.0, 0.0]),
            Err(NeedleError::FarBase(far))
        );
        assert!(Needle::new(far, [1.0, 0.0, 0.0], 0.1).is_err());
        assert!(n.set_pose([1e29, 0.0, 0.0], [1.0, 0.0, 0.0]).is_ok());
    }

    #[test]
    fn tip_projection_and_bad_poses() {
        let mut n = Needle::new([0.0, 1.0, 0.0], [2.0, 0.0, 0.0], 0.15).unwrap();
        assert_eq!(n.tip(), [0.15, 1.0, 0.0]);
        let (s, r) = n.project([0.05, 1.02, 0.0]);
        assert!((s - 0.05).abs() < 1e-15 && (r[1] - 0.02).abs() < 1e-15);
        assert_eq!(
            n.set_pose([0.0; 3], [0.0; 3]),
            Err(NeedleError::ZeroDirection([0.0; 3]))
        );
        assert!(matches!(
            n.set_pose([f64::NAN, 0.0, 0.0], [1.0, 0.0, 0.0]),
            Err(NeedleError::NonFinite { what: "base", .. })
        ));
        assert_eq!(
            n.tip(),
            [0.15, 1.0, 0.0],
            "a refused pose leaves the needle as it was"
        );
        assert_eq!(
            Needle::new([0.0; 3], [1.0, 0.0, 0.0], -1.0),
            Err(NeedleError::BadLength(-1.0))
        );
    }
}
