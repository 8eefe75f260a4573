//! What the loop measures every tick, and its percentiles.

use needlesim_needle::PunctureState;
use std::collections::VecDeque;

/// One tick's record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickRecord {
    /// Tick number.
    pub index: u64,
    /// Wall time since the loop started when the tick began, s.
    pub wall: f64,
    /// Wall time since the previous tick began, s (the period; 0 for the first tick).
    pub period: f64,
    /// Wall time the tick's work took (read pose, step, render force), s.
    pub work: f64,
    /// From the pose's sampling ([`crate::DevicePose::sampled`]) to the force handed to
    /// the device, s.
    pub latency: f64,
    /// Device position (needle base), m.
    pub device: [f64; 3],
    /// Proxy position (the simulated needle's base), m.
    pub needle: [f64; 3],
    /// Force sent to the device, N.
    pub force: [f64; 3],
    /// Force of the tissue on the needle in the tick's last step, N.
    pub tissue: [f64; 3],
    /// Depth of the tip past the first contact along the needle, m.
    pub depth: f64,
    /// Whether the tick's force was saturated at [`crate::HapticConfig::max_force`].
    pub saturated: bool,
    /// Puncture state after the tick's last step.
    pub state: PunctureState,
}

/// Percentiles of a set of durations, s.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Percentiles {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest.
    pub max: f64,
}

impl Percentiles {
    /// Nearest-rank percentiles of `values` (all zero when empty).
    pub fn of(values: impl IntoIterator<Item = f64>) -> Percentiles {
        let mut v: Vec<f64> = values.into_iter().collect();
        if v.is_empty() {
            return Percentiles::default();
        }
        v.sort_by(f64::total_cmp);
        let rank = |q: f64| v[((q * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1];
        Percentiles {
            p50: rank(0.5),
            p99: rank(0.99),
            max: v[v.len() - 1],
        }
    }
}

/// The loop's timing over the ticks kept ([`crate::HapticConfig::keep`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HapticStats {
    /// Ticks run since the start (all, not only those kept).
    pub ticks: u64,
    /// Ticks whose work ran past their deadline (the next tick started late).
    pub overruns: u64,
    /// Ticks whose force was saturated.
    pub saturated: u64,
    /// Target period, s.
    pub target: f64,
    /// Tick period (start to start), s, over the ticks kept after the first.
    pub period: Percentiles,
    /// Work per tick, s.
    pub work: Percentiles,
    /// Pose-to-force latency, s.
    pub latency: Percentiles,
}

/// The records kept (a ring) and the counters.
#[derive(Debug, Default)]
pub(crate) struct Recorder {
    pub(crate) keep: usize,
    pub(crate) records: VecDeque<TickRecord>,
    pub(crate) ticks: u64,
    pub(crate) overruns: u64,
    pub(crate) saturated: u64,
    pub(crate) target: f64,
}

impl Recorder {
    pub(crate) fn push(&mut self, r: TickRecord, overrun: bool) {
        self.ticks += 1;
        self.overruns += u64::from(overrun);
        self.saturated += u64::from(r.saturated);
        if self.keep == 0 {
            return;
        }
        if self.records.len() == self.keep {
            self.records.pop_front();
        }
        self.records.push_back(r);
    }

    pub(crate) fn stats(&self) -> HapticStats {
        let r = &self.records;
        HapticStats {
            ticks: self.ticks,
            overruns: self.overruns,
            saturated: self.saturated,
            target: self.target,
            period: Percentiles::of(r.iter().filter(|t| t.index > 0).map(|t| t.period)),
            work: Percentiles::of(r.iter().map(|t| t.work)),
            latency: Percentiles::of(r.iter().map(|t| t.latency)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_percentiles() {
        let p = Percentiles::of((1..=200).map(f64::from));
        assert_eq!((p.p50, p.p99, p.max), (100.0, 198.0, 200.0));
        let one = Percentiles::of([3.0]);
        assert_eq!((one.p50, one.p99, one.max), (3.0, 3.0, 3.0));
        assert_eq!(Percentiles::of([]), Percentiles::default());
    }
}
