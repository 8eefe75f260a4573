//! Pose scripts: a needle's pose as a function of time, from a start pose and a list of
//! keyframes played one after the other (move at a speed, pause, rotate about an axis
//! through a point, extract along the shaft, spin about the needle's own axis). `move` and
//! `extract` may spin the needle at the same time (`spin`, degrees per second): clinicians
//! turn a needle while pushing it to lower the insertion force.
//!
//! A hand or a robot cannot change the needle's speed in no time: the speed (and the turn
//! rate) changes at each keyframe boundary, and at the end, over a ramp of `ramp` seconds
//! centred on the boundary ([`PoseScript::with_ramp`], `needle.speed_ramp`, default
//! [`DEFAULT_RAMP`]; at most half of either keyframe it joins): one keyframe's speed falls
//! linearly while the next one's rises ([`PoseScript::pose_at`]), so the needle joins the
//! scripted pose exactly at both ends of the ramp and only the corner is rounded. (An
//! instant stop or reversal of a needle in tissue is an instant step of the viscous part
//! of the friction; measured with the per-length model on `needle_insert_extract`, the
//! force stepped by 7.3% of itself in one step when the extraction started, 2.1% with the
//! ramp.) The start at time 0 is not ramped: the needle starts outside the tissue.
//!
//! ```toml
//! [[keyframe]]
//! action = "move"
//! direction = [1.0, 0.0, 0.0]
//! speed = 0.01        # m/s
//! duration = 15.0     # s
//! [[keyframe]]
//! action = "rotate"
//! axis = [0.0, 0.0, 1.0]
//! point = [0.0, 0.05, 0.05]
//! rate = 5.0          # degrees per second
//! duration = 5.0
//! [[keyframe]]
//! action = "spin"     # about the needle's own axis, in place
//! rate = 360.0        # degrees per second (one revolution per second)
//! duration = 1.0
//! ```

use crate::needle::{unit, Needle, NeedleError};
use glam::{DQuat, DVec3};
use serde::Deserialize;
use thiserror::Error;

/// One segment of a pose script.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(tag = "action", rename_all = "snake_case", deny_unknown_fields)]
pub enum Keyframe {
    /// Translate along `direction` (normalised) at `speed` m/s for `duration` s.
    Move {
        /// Direction of travel.
        direction: [f64; 3],
        /// Speed in m/s (>= 0).
        speed: f64,
        /// Seconds.
        duration: f64,
        /// Spin about the needle's own axis at the same time, degrees per second
        /// (right-handed about the needle direction; default 0).
        #[serde(default)]
        spin: f64,
    },
    /// Hold still for `duration` s.
    Pause {
        /// Seconds.
        duration: f64,
    },
    /// Rotate about `axis` through `point` at `rate` degrees per second for `duration` s
    /// (right-handed about the normalised axis).
    Rotate {
        /// Rotation axis.
        axis: [f64; 3],
        /// A point on the axis.
        point: [f64; 3],
        /// Degrees per second.
        rate: f64,
        /// Seconds.
        duration: f64,
    },
    /// Pull back along the needle's own shaft (tip towards base) at `speed` m/s.
    Extract {
        /// Speed in m/s (>= 0).
        speed: f64,
        /// Seconds.
        duration: f64,
        /// Spin about the needle's own axis at the same time, degrees per second (default 0).
        #[serde(default)]
        spin: f64,
    },
    /// Spin in place about the needle's own axis at `rate` degrees per second for
    /// `duration` s (right-handed about the needle direction).
    Spin {
        /// Degrees per second.
        rate: f64,
        /// Seconds.
        duration: f64,
    },
}

/// A keyframe that cannot be played.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("needle keyframe {index}: {reason}")]
pub struct ScriptError {
    /// Position in the list (0-based).
    pub index: usize,
    /// What is wrong.
    pub reason: String,
}

/// Default time over which the needle's speed changes at a keyframe boundary, s: 25 mm/s
/// reversed in 50 ms is an acceleration of 1 m/s^2, within what needle insertion robots
/// and hands do.
pub const DEFAULT_RAMP: f64 = 0.05;

/// A start pose and keyframes, with the pose at the start of every keyframe precomputed.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseScript {
    keyframes: Vec<Keyframe>,
    /// `(start time, needle at that time)` per keyframe.
    starts: Vec<(f64, Needle)>,
    end: (f64, Needle),
    /// Speed ramp at the keyframe boundaries, s.
    ramp: f64,
}

/// The needle after `tau` seconds of keyframe `k` from pose `n`.
fn advance(n: &Needle, k: &Keyframe, tau: f64) -> Result<Needle, NeedleError> {
    let (b, t) = (
        DVec3::from_array(n.base()),
        DVec3::from_array(n.direction()),
    );
    let mut out = *n;
    // Turn about the needle's own axis over the keyframe so far, radians.
    let mut spun = 0.0;
    match *k {
        Keyframe::Move {
            direction,
            speed,
            spin,
            ..
        } => {
            let d = DVec3::from_array(unit(direction)?);
            out.set_pose((b + d * (speed * tau)).to_array(), t.to_array())?;
            spun = spin.to_radians() * tau;
        }
        Keyframe::Pause { .. } => {}
        Keyframe::Rotate {
            axis, point, rate, ..
        } => {
            let axis = DVec3::from_array(unit(axis)?);
            let turn = DQuat::from_axis_angle(axis, rate.to_radians() * tau);
            let point = DVec3::from_array(point);
            out.set_pose(
                (point + turn * (b - point)).to_array(),
                (turn * t).to_array(),
            )?;
            // The part of the turn about the needle's own axis (constant: the direction
            // turns about `axis`, so its component along `axis` stays).
            spun = rate.to_radians() * tau * axis.dot(t);
        }
        Keyframe::Extract { speed, spin, .. } => {
            out.set_pose((b - t * (speed * tau)).to_array(), t.to_array())?;
            spun = spin.to_radians() * tau;
        }
        Keyframe::Spin { rate, .. } => spun = rate.to_radians() * tau,
    }
    out.set_roll(n.roll() + spun)?;
    Ok(out)
}

fn duration(k: &Keyframe) -> f64 {
    match *k {
        Keyframe::Move { duration, .. }
        | Keyframe::Pause { duration }
        | Keyframe::Rotate { duration, .. }
        | Keyframe::Extract { duration, .. }
        | Keyframe::Spin { duration, .. } => duration,
    }
}

impl PoseScript {
    /// Checks the keyframes (finite values, non-negative speeds and durations, non-zero
    /// directions and axes) and precomputes the pose at every keyframe's start.
    pub fn new(start: Needle, keyframes: Vec<Keyframe>) -> Result<PoseScript, ScriptError> {
        let mut starts = Vec::with_capacity(keyframes.len());
        let (mut time, mut pose) = (0.0, start);
        for (index, k) in keyframes.iter().enumerate() {
            let err = |reason: String| ScriptError { index, reason };
            let d = duration(k);
            if !(d.is_finite() && d >= 0.0) {
                return Err(err(format!(
                    "duration must be a finite number >= 0, got {d}"
                )));
            }
            match *k {
                Keyframe::Move { speed, .. } | Keyframe::Extract { speed, .. }
                    if !(speed.is_finite() && speed >= 0.0) =>
                {
                    return Err(err(format!(
                        "speed must be a finite number >= 0, got {speed}"
                    )));
                }
                Keyframe::Move { spin, .. } | Keyframe::Extract { spin, .. }
                    if !spin.is_finite() =>
                {
                    return Err(err(format!("spin must be finite, got {spin}")));
                }
                Keyframe::Spin { rate, .. } if !rate.is_finite() => {
                    return Err(err(format!("rate must be finite, got {rate}")));
                }
                Keyframe::Rotate { rate, point, .. }
                    if !(rate.is_finite() && point.iter().all(|x| x.is_finite())) =>
                {
                    return Err(err(format!(
                        "rate and point must be finite, got {rate} and {point:?}"
                    )));
                }
                _ => {}
            }
            starts.push((time, pose));
            pose = advance(&pose, k, d).map_err(|e| err(e.to_string()))?;
            time += d;
        }
        Ok(PoseScript {
            keyframes,
            starts,
            end: (time, pose),
            ramp: DEFAULT_RAMP,
        })
    }

    /// The script with speed changes spread over `ramp` seconds at every keyframe
    /// boundary after the start (module docs); 0 changes speed within a step.
    pub fn with_ramp(mut self, ramp: f64) -> PoseScript {
        self.ramp = ramp.max(0.0);
        self
    }

    /// Total duration in seconds.
    pub fn duration(&self) -> f64 {
        self.end.0
    }

    /// The half-width of the ramp at the boundary before keyframe `i` (`i` = the number of
    /// keyframes: the end): half the ramp, but at most half of either keyframe it joins,
    /// so that no two ramps overlap; 0 at time 0.
    fn half_ramp(&self, i: usize) -> f64 {
        let d = |k: usize| self.keyframes.get(k).map_or(f64::INFINITY, duration);
        match i {
            0 => 0.0,
            _ => (0.5 * self.ramp).min(0.5 * d(i - 1)).min(0.5 * d(i)),
        }
    }

    /// The needle at time `t` (the start pose before 0, the final pose after the end),
    /// with the speed ramps at the keyframe boundaries.
    ///
    /// Within the ramp of half-width `h` about the boundary `t_b` between keyframes A and
    /// B, the speed of A falls and that of B rises linearly: with `x = t - (t_b - h)`, A
    /// has run `t_b - h - t_A + x - x^2 / (4 h)` of its time and B `x^2 / (4 h)` of its
    /// own, and the pose is B's motion applied after A's. At `x = 0` that is A's scripted
    /// pose and at `x = 2 h` B's, exactly, whatever the motions (a straight move, a turn
    /// about an axis, a spin).
    pub fn pose_at(&self, t: f64) -> Needle {
        for i in 1..=self.keyframes.len() {
            let h = self.half_ramp(i);
            let tb = self.starts.get(i).map_or(self.end.0, |s| s.0);
            if h <= 0.0 || (t - tb).abs() >= h {
                continue;
            }
            let x = t - (tb - h);
            let (ta, start_a) = self.starts[i - 1];
            let ka = &self.keyframes[i - 1];
            let in_b = x * x / (4.0 * h);
            let in_a = (tb - h - ta) + x - in_b;
            // Validated in `new`, so the poses inside the keyframes are valid.
            let after_a = advance(&start_a, ka, in_a).unwrap_or(start_a);
            return match self.keyframes.get(i) {
                Some(kb) => advance(&after_a, kb, in_b).unwrap_or(after_a),
                None => after_a,
            };
        }
        self.raw_pose_at(t)
    }

    /// The scripted pose at time `t`, without ramps.
    fn raw_pose_at(&self, t: f64) -> Needle {
        let i = self.starts.partition_point(|(s, _)| *s <= t);
        if i == 0 {
            return self.starts.first().map_or(self.end.1, |s| s.1);
        }
        let (s, pose) = self.starts[i - 1];
        let k = &self.keyframes[i - 1];
        let tau = (t - s).min(duration(k));
        // Validated in `new`, so a pose inside a keyframe is always valid.
        advance(&pose, k, tau).unwrap_or(pose)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Deserialize)]
    struct File {
        keyframe: Vec<Keyframe>,
    }

    /// The paper's experiment: 15 cm along +x, then 25 degrees about z.
    #[test]
    fn paper_script_moves_then_rotates() {
        let text = r#"
            [[keyframe]]
            action = "move"
            direction = [1.0, 0.0, 0.0]
            speed = 0.01
            duration = 15.0
            [[keyframe]]
            action = "pause"
            duration = 1.0
            [[keyframe]]
            action = "rotate"
            axis = [0.0, 0.0, 1.0]
            point = [0.05, 0.05, 0.05]
            rate = 5.0
            duration = 5.0
            [[keyframe]]
            action = "extract"
            speed = 0.02
            duration = 1.0
        "#;
        let f: File = toml::from_str(text).unwrap();
        let start = Needle::new([-0.2, 0.05, 0.05], [1.0, 0.0, 0.0], 0.1).unwrap();
        // Corners as scripted (no speed ramps; they are tested below).
        let s = PoseScript::new(start, f.keyframe).unwrap().with_ramp(0.0);
        assert_eq!(s.duration(), 22.0);
        let close = |a: [f64; 3], b: [f64; 3]| {
            (DVec3::from_array(a) - DVec3::from_array(b))
                .abs()
                .max_element()
                < 1e-12
        };
        assert!(close(s.pose_at(-1.0).tip(), [-0.1, 0.05, 0.05]));
        assert!(close(s.pose_at(7.5).tip(), [-0.025, 0.05, 0.05]));
        assert!(close(s.pose_at(15.5).tip(), [0.05, 0.05, 0.05]));
        // After the rotation the tip, which sat on the axis, has not moved and the shaft
        // points 25 degrees off x.
        let r = s.pose_at(21.0);
        assert!(close(r.tip(), [0.05, 0.05, 0.05]));
        let a = 25f64.to_radians();
        assert!(close(r.direction(), [a.cos(), a.sin(), 0.0]));
        // Extraction pulls back along the shaft by 2 cm.
        let e = s.pose_at(100.0);
        let pulled = DVec3::from_array(r.tip()) - 0.02 * DVec3::from_array(r.direction());
        assert!(close(e.tip(), pulled.to_array()));
    }

    #[test]
    fn bad_keyframes_name_their_index() {
        let start = Needle::new([0.0; 3], [1.0, 0.0, 0.0], 0.1).unwrap();
        let e = PoseScript::new(
            start,
            vec![
                Keyframe::Pause { duration: 1.0 },
                Keyframe::Move {
                    direction: [0.0; 3],
                    speed: 1.0,
                    duration: 1.0,
                    spin: 0.0,
                },
            ],
        )
        .unwrap_err();
        assert_eq!(e.index, 1);
        assert!(e.reason.contains("non-zero"), "{e}");
        let e = PoseScript::new(
            start,
            vec![Keyframe::Extract {
                speed: -1.0,
                duration: 1.0,
                spin: 0.0,
            }],
        );
        assert!(e.unwrap_err().reason.contains("speed"));
        let bad: Result<File, _> = toml::from_str("[[keyframe]]\naction = \"jump\"\n");
        assert!(bad.is_err());
    }

    fn insert_pause_extract(ramp: f64) -> PoseScript {
        let keys = vec![
            Keyframe::Move {
                direction: [1.0, 0.0, 0.0],
                speed: 0.025,
                duration: 2.0,
                spin: 0.0,
            },
            Keyframe::Pause { duration: 0.5 },
            Keyframe::Extract {
                speed: 0.025,
                duration: 2.5,
                spin: 0.0,
            },
        ];
        let start = Needle::new([0.0; 3], [1.0, 0.0, 0.0], 0.1).unwrap();
        PoseScript::new(start, keys).unwrap().with_ramp(ramp)
    }

    fn x(s: &PoseScript, t: f64) -> f64 {
        s.pose_at(t).base()[0]
    }

    /// Outside the ramps the pose is the scripted one (to rounding), inside it the speed
    /// changes linearly from one keyframe's to the next's: the velocity over each 1 ms
    /// step changes by at most the whole change times dt / ramp (plus rounding), and
    /// every keyframe's end pose is reached as scripted.
    #[test]
    fn speed_ramps_round_the_corners_and_keep_the_end_poses() {
        let (ramped, raw) = (insert_pause_extract(0.05), insert_pause_extract(0.0));
        for t in [0.0, 0.5, 1.97, 2.03, 2.25, 2.47, 2.53, 4.0, 4.97, 5.03, 6.0] {
            assert!((x(&ramped, t) - x(&raw, t)).abs() < 1e-12, "t = {t}");
        }
        // Inside a ramp: the pose lags (stop) or leads (start) the instant change.
        assert!(x(&ramped, 2.0) < x(&raw, 2.0) - 1e-6);
        let dt = 1e-3;
        let v = |t: f64| (x(&ramped, t + dt) - x(&ramped, t)) / dt;
        let mut largest = 0.0f64;
        let mut t = 1.9;
        while t < 2.7 {
            largest = largest.max((v(t + dt) - v(t)).abs());
            t += dt;
        }
        // 0.025 m/s changed over 50 ms: 0.5 mm/s per 1 ms step.
        assert!(
            largest < 0.025 * dt / 0.05 * 1.05,
            "largest velocity step {largest}"
        );
        let vr = |t: f64| (x(&raw, t + dt) - x(&raw, t)) / dt;
        assert!(
            (vr(2.49) - vr(2.51)).abs() > 0.02,
            "the raw script changes at once"
        );
    }

    /// A turn ramps too: its speed changes continuously at the stop, the direction stays
    /// a unit vector and the scripted poses hold at both ends of the ramp.
    #[test]
    fn a_turn_ramps_and_joins_the_scripted_poses() {
        let keys = vec![
            Keyframe::Rotate {
                axis: [0.0, 0.0, 1.0],
                point: [0.0; 3],
                rate: 90.0,
                duration: 1.0,
            },
            Keyframe::Pause { duration: 1.0 },
        ];
        let start = Needle::new([0.1, 0.0, 0.0], [1.0, 0.0, 0.0], 0.1).unwrap();
        let (s, raw) = (
            PoseScript::new(start, keys.clone()).unwrap(),
            PoseScript::new(start, keys).unwrap().with_ramp(0.0),
        );
        let angle = |n: Needle| {
            let d = DVec3::from_array(n.direction());
            assert!((d.length() - 1.0).abs() < 1e-12);
            d.y.atan2(d.x).to_degrees()
        };
        for t in [0.5, 0.975, 1.025, 1.5] {
            assert!(
                (angle(s.pose_at(t)) - angle(raw.pose_at(t))).abs() < 1e-9,
                "t = {t}"
            );
            let (a, b) = (s.pose_at(t).base(), raw.pose_at(t).base());
            assert!((0..3).all(|c| (a[c] - b[c]).abs() < 1e-12), "t = {t}");
        }
        // Halfway through the stop it has turned less than the full 90 degrees.
        assert!(angle(s.pose_at(1.0)) < 90.0 - 0.1);
        // The turn rate changes by at most 90 deg/s * dt / ramp per 1 ms step.
        let dt = 1e-3;
        let rate = |t: f64| (angle(s.pose_at(t + dt)) - angle(s.pose_at(t))) / dt;
        let mut largest = 0.0f64;
        let mut t = 0.95;
        while t < 1.05 {
            largest = largest.max((rate(t + dt) - rate(t)).abs());
            t += dt;
        }
        assert!(largest < 90.0 * dt / 0.05 * 1.05, "{largest}");
    }
}
