//! The surface side of the puncture state machine (paper section 5): the states, the
//! 1-to-3 split of the touched triangle around the Surface node and its exact reversal,
//! and the cone angle that decides puncture and release while Touching.
//!
//! While Touching, the three edges from the Surface node to the old triangle's corners make
//! angles with the shaft direction pointing from tip to base. Pushing in closes that cone:
//! when the mean angle drops below the puncture threshold (default 80 degrees) the surface
//! is punctured; pulling back opens it: above the release threshold (default 95 degrees)
//! the Surface node is removed and the triangle restored.

use glam::DVec3;
use serde::Deserialize;

/// Where the needle tip is relative to the tissue.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum PunctureState {
    /// Not in contact.
    #[default]
    Outside,
    /// Pressing on the surface through the Surface node, not punctured.
    Touching,
    /// Through the surface.
    Inside,
}

/// Angle thresholds in degrees.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Thresholds {
    /// Puncture when the mean cone angle falls below this (default 80).
    #[serde(default = "default_puncture")]
    pub puncture: f64,
    /// Release (back to Outside) when the mean cone angle rises above this (default 95).
    #[serde(default = "default_release")]
    pub release: f64,
}

fn default_puncture() -> f64 {
    80.0
}
fn default_release() -> f64 {
    95.0
}

impl Default for Thresholds {
    fn default() -> Self {
        Thresholds {
            puncture: default_puncture(),
            release: default_release(),
        }
    }
}

/// What a Touching needle does this step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TouchingOutcome {
    /// Stays Touching.
    Stay,
    /// Punctures: Touching -> Inside.
    Puncture,
    /// Lets go: Touching -> Outside.
    Release,
}

impl Thresholds {
    /// Checks `0 < puncture < release < 180`.
    pub fn validate(&self) -> Result<(), String> {
        let ok = self.puncture.is_finite()
            && self.release.is_finite()
            && 0.0 < self.puncture
            && self.puncture < self.release
            && self.release < 180.0;
        if ok {
            Ok(())
        } else {
            Err(format!(
                "need 0 < puncture < release < 180 degrees, got puncture {} and release {}",
                self.puncture, self.release
            ))
        }
    }

    /// The outcome for a mean cone angle in degrees.
    pub fn touching(&self, mean_angle: f64) -> TouchingOutcome {
        if mean_angle < self.puncture {
            TouchingOutcome::Puncture
        } else if mean_angle > self.release {
            TouchingOutcome::Release
        } else {
            TouchingOutcome::Stay
        }
    }
}

/// Mean angle in degrees between the edges `surface node -> corner` and `-direction` (the
/// shaft from tip to base, `direction` being base to tip, unit length).
pub fn mean_cone_angle(surface_node: [f64; 3], corners: [[f64; 3]; 3], direction: [f64; 3]) -> f64 {
    let (s, t) = (
        DVec3::from_array(surface_node),
        DVec3::from_array(direction),
    );
    corners
        .iter()
        .map(|c| {
            let e = DVec3::from_array(*c) - s;
            let cos = -e.dot(t) / e.length();
            cos.clamp(-1.0, 1.0).acos().to_degrees()
        })
        .sum::<f64>()
        / 3.0
}

/// What a split changed, to undo it exactly.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Split {
    /// The split triangle's index (now holding the first of the three).
    pub triangle: usize,
    /// Its corners before the split.
    pub original: [u32; 3],
    /// Length of the triangle list before the split (the other two were appended there).
    pub appended_at: usize,
}

/// Replaces triangle `id` `[a, b, c]` by `[a, b, s]` in place and appends `[b, c, s]` and
/// `[c, a, s]` (same winding, so the surface stays outward oriented).
pub fn split_triangle(triangles: &mut Vec<[u32; 3]>, id: usize, s: u32) -> Split {
    let [a, b, c] = triangles[id];
    let split = Split {
        triangle: id,
        original: [a, b, c],
        appended_at: triangles.len(),
    };
    triangles[id] = [a, b, s];
    triangles.push([b, c, s]);
    triangles.push([c, a, s]);
    split
}

/// Undoes [`split_triangle`]: the list is bitwise what it was before the split. Splits
/// must be undone in reverse order (the state machine has at most one at a time).
pub fn restore_triangle(triangles: &mut Vec<[u32; 3]>, split: &Split) {
    debug_assert_eq!(
        triangles.len(),
        split.appended_at + 2,
        "splits undone out of order"
    );
    triangles.truncate(split.appended_at);
    triangles[split.triangle] = split.original;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pushing_closes_the_cone_and_pulling_opens_it() {
        // Flat triangle in z = 0 around the origin, needle pointing down (-z).
        let corners = [
            [0.01, 0.0, 0.0],
            [-0.005, 0.0087, 0.0],
            [-0.005, -0.0087, 0.0],
        ];
        let down = [0.0, 0.0, -1.0];
        let th = Thresholds::default();
        let at = |depth: f64| mean_cone_angle([0.0, 0.0, -depth], corners, down);
        assert!((at(0.0) - 90.0).abs() < 1e-9);
        assert_eq!(th.touching(at(0.0)), TouchingOutcome::Stay);
        // The corners are 1 cm away: the cone passes 80 degrees at 1 cm * tan(10 deg).
        let d80 = 0.01 * 10f64.to_radians().tan();
        assert_eq!(th.touching(at(0.9 * d80)), TouchingOutcome::Stay);
        assert_eq!(th.touching(at(1.1 * d80)), TouchingOutcome::Puncture);
        let d95 = 0.01 * 5f64.to_radians().tan();
        assert_eq!(th.touching(at(-0.9 * d95)), TouchingOutcome::Stay);
        assert_eq!(th.touching(at(-1.1 * d95)), TouchingOutcome::Release);
        assert!(Thresholds {
            puncture: 95.0,
            release: 80.0
        }
        .validate()
        .is_err());
        assert!(th.validate().is_ok());
    }

    #[test]
    fn split_then_restore_is_bitwise_exact() {
        let original: Vec<[u32; 3]> = vec![[0, 1, 2], [2, 1, 3], [3, 1, 4]];
        let mut t = original.clone();
        let s = split_triangle(&mut t, 1, 9);
        assert_eq!(
            t,
            vec![[0, 1, 2], [2, 1, 9], [3, 1, 4], [1, 3, 9], [3, 2, 9]]
        );
        restore_triangle(&mut t, &s);
        assert_eq!(t, original);
    }
}
