//! The force audit of `shared/tools/force_audit.py`, reproduced: jumps, buzz, held and
//! moving step changes, negative force while advancing, reversal steps and flatness.

use needlesim_needle::{NeedleSample, PunctureState, Simulation};

/// One step of a force history as the audit reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Row {
    /// Simulated time, s.
    pub time: f64,
    /// Tip depth past the first contact point along the needle, m.
    pub depth: f64,
    /// Axial force, N.
    pub force: f64,
    /// Puncture state.
    pub state: PunctureState,
    /// Region the tip is in.
    pub region: Option<u16>,
    /// Needle direction.
    pub direction: [f64; 3],
    /// Depth of the tip's material point in the undeformed tissue, m (inside only).
    pub tissue_depth: Option<f64>,
}

/// The rows of a simulation's history.
pub fn rows(sim: &Simulation) -> Vec<Row> {
    sim.history()
        .iter()
        .map(|s: &NeedleSample| Row {
            time: s.time,
            depth: sim.depth_of(s.tip, s.direction),
            force: s.force.axial,
            state: s.state,
            region: s.region,
            direction: s.direction,
            tissue_depth: s.tissue_depth,
        })
        .collect()
}

/// The audit's figures of one force history.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Audit {
    /// Rows.
    pub rows: usize,
    /// Punctures (entering Inside, or a new region while inside).
    pub punctures: usize,
    /// Steps changing by more than 5% of the local force, inside and not within 20 ms of a
    /// puncture.
    pub jumps: usize,
    /// Largest buzz (RMS above about 50 Hz over 20 ms, over the local force), %.
    pub buzz_max: f64,
    /// The same without the series' last 20 ms, %.
    pub buzz_max_body: f64,
    /// Share of the inside rows (not near a puncture) whose buzz is above 2%.
    pub buzz_share: f64,
    /// Median step change over the local force while the needle is held, % (`None`
    /// without held rows).
    pub held: Option<f64>,
    /// The held rows split: the needle still (a pause), %.
    pub still: Option<f64>,
    /// ... and turning about a point at constant depth (the paper scenes' rotation), %.
    pub rotating: Option<f64>,
    /// The same while it moves.
    pub moving: Option<f64>,
    /// Inside rows advancing with a negative axial force.
    pub negative_advancing: usize,
    /// Largest single-step change within 50 ms after a reversal from advancing to
    /// withdrawing, over the force at the reversal (floored at 10% of the largest), %
    /// (`None` without a reversal).
    pub reversal: Option<f64>,
    /// Largest step of the tip's material depth between two withdrawing inside rows, mm
    /// (issue 39: it should follow the needle, also across node removals; `None` without
    /// such rows).
    pub material_step: Option<f64>,
    /// With a cutting force given: the largest deviation from it over the inside,
    /// advancing rows not near a puncture, % (meaningful for a run without friction).
    pub flatness: Option<f64>,
}

/// numpy's `convolve(x, ones(w) / w, "same")`.
fn movmean(x: &[f64], w: usize) -> Vec<f64> {
    let n = x.len();
    let w = w.max(1);
    let mut prefix = vec![0.0; n + 1];
    for i in 0..n {
        prefix[i + 1] = prefix[i] + x[i];
    }
    let off = (w - 1) / 2;
    (0..n)
        .map(|i| {
            // Full convolution index i + off covers x[i + off - (w - 1) ..= i + off].
            let hi = (i + off).min(n - 1);
            let lo = (i + off).saturating_sub(w - 1);
            (prefix[hi + 1] - prefix[lo]) / w as f64
        })
        .collect()
}

pub(super) fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    })
}

/// The figures of `rows` (module docs; the definitions of `force_audit.py`), with the
/// flatness against `cutting` when given.
pub fn audit(rows: &[Row], cutting: Option<f64>) -> Audit {
    let n = rows.len();
    if n < 2 {
        return Audit {
            rows: n,
            ..Default::default()
        };
    }
    let t: Vec<f64> = rows.iter().map(|r| r.time).collect();
    let f: Vec<f64> = rows.iter().map(|r| r.force).collect();
    let d: Vec<f64> = rows.iter().map(|r| r.depth).collect();
    let mut dts: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    dts.sort_by(f64::total_cmp);
    let dt = dts[dts.len() / 2];
    let inside: Vec<bool> = rows
        .iter()
        .map(|r| r.state == PunctureState::Inside)
        .collect();
    let punct: Vec<f64> = (1..n)
        .filter(|&i| inside[i] && (!inside[i - 1] || rows[i].region != rows[i - 1].region))
        .map(|i| t[i])
        .collect();
    let near: Vec<bool> = t
        .iter()
        .map(|x| punct.iter().any(|p| (x - p).abs() < 0.02))
        .collect();
    let fmax = f.iter().fold(0.0f64, |a, x| a.max(x.abs())).max(1e-12);
    let abs: Vec<f64> = f.iter().map(|x| x.abs()).collect();
    let m: Vec<f64> = movmean(&abs, (0.05 / dt).round() as usize)
        .into_iter()
        .map(|x| x.max(0.1 * fmax))
        .collect();
    let df: Vec<f64> = (0..n)
        .map(|i| {
            if i + 1 < n {
                (f[i + 1] - f[i]).abs()
            } else {
                0.0
            }
        })
        .collect();
    let ok: Vec<bool> = (0..n).map(|i| inside[i] && !near[i]).collect();
    let jumps = (0..n).filter(|&i| ok[i] && df[i] > 0.05 * m[i]).count();
    let w20 = (0.02 / dt).round() as usize;
    let smooth = movmean(&f, w20);
    let sq: Vec<f64> = f
        .iter()
        .zip(&smooth)
        .map(|(a, b)| (a - b).powi(2))
        .collect();
    let hf: Vec<f64> = movmean(&sq, w20)
        .into_iter()
        .zip(&m)
        .map(|(x, m)| x.max(0.0).sqrt() / m)
        .collect();
    let end = t[n - 1] - 0.02;
    let okv: Vec<usize> = (0..n).filter(|&i| ok[i]).collect();
    let buzz_max = okv.iter().map(|&i| hf[i]).fold(0.0, f64::max);
    let buzz_max_body = okv
        .iter()
        .filter(|&&i| t[i] < end)
        .map(|&i| hf[i])
        .fold(0.0, f64::max);
    let buzz_share = match okv.len() {
        0 => 0.0,
        k => okv.iter().filter(|&&i| hf[i] > 0.02).count() as f64 / k as f64,
    };
    let dd: Vec<f64> = (0..n)
        .map(|i| if i + 1 < n { d[i + 1] - d[i] } else { 0.0 })
        .collect();
    // Turning: the needle's direction changes over the step (the paper scenes' rotation
    // about the entry point keeps the depth, which the shared audit counts as held).
    let turning: Vec<bool> = (0..n)
        .map(|i| {
            i + 1 < n
                && (0..3).any(|c| (rows[i + 1].direction[c] - rows[i].direction[c]).abs() > 1e-12)
        })
        .collect();
    let held: Vec<usize> = (0..n)
        .filter(|&i| inside[i] && dd[i].abs() < 1e-9)
        .collect();
    let still: Vec<usize> = held.iter().copied().filter(|&i| !turning[i]).collect();
    let rotating: Vec<usize> = held.iter().copied().filter(|&i| turning[i]).collect();
    let moving: Vec<usize> = (0..n)
        .filter(|&i| inside[i] && dd[i].abs() >= 1e-9)
        .collect();
    let med = |ix: &[usize]| median(ix.iter().map(|&i| 100.0 * df[i] / m[i]).collect());
    let negative_advancing = (0..n)
        .filter(|&i| inside[i] && dd[i] > 1e-9 && f[i] < 0.0)
        .count();
    // Reversals: a withdrawing step whose last moving step before it advanced.
    let mut reversal: Option<f64> = None;
    let mut last_dir = 0i8;
    for i in 0..n {
        let dir = if dd[i] > 1e-9 {
            1
        } else if dd[i] < -1e-9 {
            -1
        } else {
            0
        };
        if dir == -1 && last_dir == 1 && inside[i] {
            let level = f[i].abs().max(0.1 * fmax);
            let steps = (0.05 / dt).round() as usize;
            let worst = (i.saturating_sub(1)..(i + steps).min(n - 1))
                .map(|k| df[k])
                .fold(0.0, f64::max);
            reversal = Some(reversal.unwrap_or(0.0).max(100.0 * worst / level));
        }
        if dir != 0 {
            last_dir = dir;
        }
    }
    let material_step = (1..n)
        .filter(|&i| inside[i - 1] && inside[i] && dd[i - 1] < -1e-9)
        .filter_map(|i| Some(1e3 * (rows[i].tissue_depth? - rows[i - 1].tissue_depth?).abs()))
        .reduce(f64::max);
    let flatness = cutting.and_then(|c| {
        let sel: Vec<usize> = (0..n)
            .filter(|&i| inside[i] && dd[i] > 1e-9 && !near[i])
            .collect();
        (!sel.is_empty()).then(|| {
            sel.iter()
                .map(|&i| 100.0 * (f[i] - c).abs() / c)
                .fold(0.0, f64::max)
        })
    });
    Audit {
        rows: n,
        punctures: punct.len(),
        jumps,
        buzz_max: 100.0 * buzz_max,
        buzz_max_body: 100.0 * buzz_max_body,
        buzz_share,
        held: med(&held),
        still: med(&still),
        rotating: med(&rotating),
        moving: med(&moving),
        negative_advancing,
        reversal,
        material_step,
        flatness,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(time: f64, depth: f64, force: f64) -> Row {
        Row {
            time,
            depth,
            force,
            state: PunctureState::Inside,
            region: Some(0),
            direction: [1.0, 0.0, 0.0],
            tissue_depth: Some(depth),
        }
    }

    #[test]
    fn movmean_is_numpys_same_convolution() {
        // numpy: np.convolve([1, 2, 3, 4, 5], np.ones(3) / 3, "same") = [1, 2, 3, 4, 3]
        let m = movmean(&[1.0, 2.0, 3.0, 4.0, 5.0], 3);
        let want = [1.0, 2.0, 3.0, 4.0, 3.0];
        assert!(
            m.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-12),
            "{m:?}"
        );
        // Even windows lean as numpy's do: [1, 3, 5, 7, 9] with ones(4) / 4 gives
        // [1, 2.25, 4, 6, 5.25].
        let m = movmean(&[1.0, 3.0, 5.0, 7.0, 9.0], 4);
        let want = [1.0, 2.25, 4.0, 6.0, 5.25];
        assert!(
            m.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-12),
            "{m:?}"
        );
    }

    #[test]
    fn audit_counts_a_jump_and_a_reversal_step() {
        // 1 kHz, advancing at 1 mm/s with a 1 N force, one 10% step at 0.5 s, then
        // withdrawing from 1 s with the force turning over 1 s (2 mN a step: under 5% of
        // the local force, floored at a tenth of the largest, everywhere).
        let mut rows = Vec::new();
        for i in 0..2000 {
            let t = i as f64 * 1e-3;
            let (d, f) = if t < 1.0 {
                (1e-3 * t, if t < 0.5 { 1.0 } else { 1.1 })
            } else {
                (1e-3 * (2.0 - t), 1.1 - 2.0 * (t - 1.0))
            };
            rows.push(row(t, d, f));
        }
        let a = audit(&rows, Some(1.0));
        assert_eq!(a.jumps, 1, "{a:?}");
        assert_eq!(a.negative_advancing, 0);
        // 2 mN a step over a force of 1.1 N at the reversal.
        let r = a.reversal.expect("a reversal");
        assert!((r - 100.0 * 0.002 / 1.1).abs() < 0.01, "{r}");
        // Advancing at 1.0 then 1.1 N: 10% off the cutting force 1 N.
        assert!((a.flatness.unwrap() - 10.0).abs() < 1e-9);
        // The material point follows the tip back, 1 um a step ...
        let m = a.material_step.expect("withdrawing rows");
        assert!((m - 1e-3).abs() < 1e-9, "{m}");
        // ... until it jumps back by 0.5 mm at 1.5 s (an advancing step does not count).
        for r in rows.iter_mut().filter(|r| r.time >= 1.5) {
            r.tissue_depth = r.tissue_depth.map(|x| x + 5e-4);
        }
        let m = audit(&rows, None).material_step.unwrap();
        assert!((m - 0.499).abs() < 1e-9, "{m}");
    }

    #[test]
    fn audit_splits_held_rows_into_still_and_turning() {
        // Held at 1 mm for 1 s with the force creeping by 0.1% a step, turning about the
        // entry for the first half (the direction changes, the depth does not), still for
        // the second with the force constant.
        let mut rows = Vec::new();
        for i in 0..1000 {
            let t = i as f64 * 1e-3;
            let mut r = row(t, 1e-3, 1.0);
            if t < 0.5 {
                let a = 0.01 * t;
                r.direction = [a.cos(), a.sin(), 0.0];
                r.force = 1.0 + 1e-3 * i as f64;
            } else {
                r.force = 1.5;
            }
            rows.push(r);
        }
        let a = audit(&rows, None);
        let (still, rotating) = (a.still.unwrap(), a.rotating.unwrap());
        assert!(still < 1e-9, "{still}");
        assert!(rotating > 0.05 && rotating < 0.1, "{rotating}");
    }
}
