//! Handing over the elastic forces a node edit changes, over a time instead of in one
//! step (issue 39, item 1).
//!
//! Removing a needle node replays its addition's undo log (paper section 5.2): the rows of
//! its neighbours, and of the neighbours' dropped partners, get their old entries back.
//! The tissue has deformed since the addition, so the restored pairs do not find the
//! strain they left: at the same positions, the elastic forces of the nodes in those rows
//! change in one step. Measured on `layered_liver_biopsy.toml` (CPU, 2026-11-26): when
//! the last Shaft node is removed at the skin on the way out, the Surface node's axial
//! elastic force goes from 0.258 to 0.393 N in one step, the tissue round it rings, and
//! the needle force jumps four times in the next 2 ms; `liver_insertion.toml` has its one
//! jump there too.
//!
//! What is handed over: for every node `j` whose force the step's edits changed, the
//! difference
//!
//! ```text
//! r_j = f_j(x; rows before the step's edits) - f_j(x; rows after them)
//! ```
//!
//! at the same positions `x`. The reach of an edit is every node whose row it changed and
//! the nodes in that row before and after ([`NodeEditor::reach_since`](crate::NodeEditor::reach_since)).
//! The forces before a removal are evaluated just before it; those before an addition by
//! putting the rows and static shape information it changed back on the backend for one
//! partial evaluation ([`NodeEditor::forces_before`](crate::NodeEditor::forces_before)),
//! so a node keeps the force it had at the start of the step whatever the order of the
//! step's edits. Slots an edit freed or took are left out (the node there is another one,
//! placed in equilibrium by [`settle`](crate::simulation)). The difference is added to
//! the node's elastic force and fades out,
//!
//! ```text
//! f_j(t) = f_j(x(t); rows after) + w(t) r_j,   w = 1 - S((t - t_e) / T),  S(s) = s^2 (3 - 2 s)
//! ```
//!
//! so the force on every node is continuous at the event (`w = 1`) and reaches the new
//! rows' force with a continuous rate (`S` is C1) after `T`. `T` is per event: 40 ms for
//! a node event, less for a Tip refresh (below). A second event before the first is
//! done adds its own difference to what is left of the first (`w r_j`) and starts again
//! with the longer of its own `T` and what the first had left, so the force stays
//! continuous whatever the events' spacing.
//!
//! Why a time and which one: the change is the discretisation's (the tissue round a
//! removed node is the same material before and after); what a user must not feel is its
//! being made at once. Spread over many periods of the tissue's nodal vibration, the
//! tissue follows it in near-equilibrium (an adiabatic change: almost no kinetic energy
//! is left behind), so nothing rings. The nodal vibration of the shipped tissues is near
//! 470 Hz (issue 39's ringing, a 2.1 ms period); `T` = [`HANDOVER_TIME`] = 40 ms is 19 of
//! those periods, and under a quarter of the time between Shaft node events at the
//! fastest shipped speed (20 mm/s over a 3.35 mm spacing: 170 ms). A needle held still
//! still gets its handover done (it runs on time, not on travel).
//!
//! Which edits: the steps that add or remove a Surface, Shaft or Exit node (one event per
//! node spacing of travel), the Tip node's refreshes, and the Tip node's last removal on
//! the way out and its return (below). A step that lifts the Tip node to edit the shaft
//! behind it is a Shaft event; one that drops a Tip node the tissue carried ahead of the
//! tip is not handed over. A refresh (every tenth of a spacing of cut, a few steps apart
//! at speed) hands over within the time the tip takes at its speed to cut the distance
//! to the next one, at most `T` ([`refresh_handover_time`]): one refresh's fade is
//! mostly over before the next starts, so refreshes do not pile up into a standing force
//! on the tissue at the tip (a 40 ms handover of every refresh would sum tens of them).
//! No event cuts short what is left of a running handover: the new one lasts at least
//! as long. Until 2026-11-27 refreshes were not handed over: the refreshed Tip node was
//! placed in equilibrium, but the change of its neighbours' rows came in one step, and
//! on `liver_insertion.toml` a refresh moved the shaft's friction by up to 50 mN within
//! 3 ms (a tenth of the force there) and rang, the run's largest buzz (2.29% of the local
//! force). Handed over, the largest high-pass excursion in the 20 ms after a refresh fell
//! from 11 mN (median over the refreshes; 25 mN the largest) to 3.9 mN (4.3). With
//! `force_audit.py` (CPU, dev machine, 2026-11-27) the largest buzz outside the 20 ms
//! after a puncture went from 2.29% to 1.59% on the liver and 5.56% to 3.22% on
//! `layered_liver_biopsy.toml` (with the warm starts kept, below), and stayed where it
//! was on `needle_insert_extract.toml` (4.68%, 4.76%: the reversal's zero crossing) and
//! `phantom_insertion.toml` (3.47%, 3.80%: its puncture's release at the audit's 20
//! ms); no jump appeared. Handing refreshes over first made the GPU and CPU runs of the
//! layered test (`tests/layers.rs`) drift three steps apart at their events: each handover evaluates
//! forces locally twice more, and the GPU backend, which evaluates every node, refined
//! co-rotated Debunne's warm-start rotations at every such evaluation; local
//! evaluations now leave those as they were on every backend
//! (`needlesim_core::Backend::compute_forces_on`), and the two runs keep the same events
//! at every step.
//! The Tip node taken off for good while the needle is pulled back (behind the crack
//! front; it is put on again only when the needle advances) is handed over like a Shaft
//! node: it happens once per withdrawal, and without it the Shaft node behind it jerked
//! back at 52 mm/s and the needle force rose 19 mN within 1 ms (`liver_insertion.toml`,
//! first removal on the way out, CPU, 2026-11-27). Its return when the needle advances
//! again behind the crack front is handed over too (once per re-insertion; it also starts
//! without a share of the shaft's friction, `Simulation::finish_inside`): without, on a
//! liver re-insertion the Shaft node behind it slid at 0.45 m/s and the force rang at
//! about 280 Hz for 20 ms (`tests/needle.rs`, `advancing_again_after_a_withdrawal_is_smooth`).
//! The first Tip node after a puncture is not: handed over, the shipped scenes' buzz rose
//! (layered 6.1% to 11.1%, phantom 3.0% to 3.6%; CPU, 2026-11-27).
//!
//! Measured with `needlesim run` and `force_audit.py` (CPU, dev machine, 2026-11-26),
//! before and after: `layered_liver_biopsy.toml` 6 jumps to 1, largest buzz 16.8% to
//! 13.9%, share of rows above 2% buzz 3.6% to 2.5%; `liver_insertion.toml` 1 jump to 0,
//! share above 2% 0.6% to 0.2%; `needle_insert_extract.toml` share above 2% 3.2% to
//! 2.5%; the friction-free liver still 0.00% from its cutting force.
//!
//! Cost: a partial force evaluation with a read before every removal (Tip refreshes
//! included: whether a Shaft edit follows in the same step is not known yet), one more
//! with the additions put back when the step added nodes, and one after the edits; on
//! the GPU each is a full force pass and a readback (its `compute_forces_on` evaluates
//! every node, and leaves co-rotated Debunne's warm-start rotations as they were, as
//! the CPU's does). A Tip refresh pays the two after its removal too. While a handover
//! runs, the forces of its nodes (a few dozen) are read with the needle nodes' forces in the
//! step's existing readback and written back; only after the needle has left the tissue
//! does it read back on its own (`tests/needle.rs` counts the readbacks per step).
//!
//! Only the needle's default per-length friction model uses it: with the paper's friction
//! model the simulation reproduces the paper's method as published.

use serde::{Deserialize, Serialize};

/// How long a node edit's change of the elastic forces takes to hand over, s (module
/// docs).
pub const HANDOVER_TIME: f64 = 0.04;

/// How long a step that only refreshed the Tip node hands its change over, s: the time
/// the tip takes at its speed (`advance` m in a step of `dt` s) to cut the `refresh`
/// distance to the next refresh, at most [`HANDOVER_TIME`] and at least one step (module
/// docs: the fade of one refresh is over before the next begins, so refreshes never sum
/// into a standing force).
pub fn refresh_handover_time(refresh: f64, advance: f64, dt: f64) -> f64 {
    let to_next = match advance > 0.0 {
        true => refresh / advance * dt,
        false => HANDOVER_TIME,
    };
    to_next.clamp(dt.min(HANDOVER_TIME), HANDOVER_TIME)
}

/// The share left `elapsed` seconds into a handover lasting `duration`: `1 - S(s)`, `S(s) =
/// s^2 (3 - 2 s)`, `s = elapsed / duration` clamped to `[0, 1]` (1 at the event, 0 once
/// done, continuous with a continuous rate).
pub fn fade(elapsed: f64, duration: f64) -> f64 {
    let s = (elapsed / duration).clamp(0.0, 1.0);
    1.0 - s * s * (3.0 - 2.0 * s)
}

/// The part of the elastic forces node edits changed that is still being handed over.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Handover {
    /// Nodes, sorted, each once.
    pub nodes: Vec<u32>,
    /// The difference `r_j` (force before less force after) at `started`, N.
    pub forces: Vec<[f64; 3]>,
    /// Simulated time of the event, s.
    pub started: f64,
    /// Time to hand over, s.
    pub duration: f64,
}

impl Handover {
    /// The share of `r_j` still applied at time `now` (1 at the event, 0 once done).
    pub fn weight(&self, now: f64) -> f64 {
        fade(now - self.started, self.duration)
    }

    /// Whether nothing is left to hand over at time `now`.
    pub fn done(&self, now: f64) -> bool {
        self.weight(now) == 0.0
    }

    /// A new handover at time `now` of the differences `forces` on `nodes` (sorted, each
    /// once), with what is left of `previous` added.
    pub fn start(
        previous: Option<&Handover>,
        now: f64,
        nodes: &[u32],
        forces: &[[f64; 3]],
        duration: f64,
    ) -> Handover {
        let mut merged: Vec<(u32, [f64; 3])> =
            nodes.iter().copied().zip(forces.iter().copied()).collect();
        if let Some(p) = previous {
            let w = p.weight(now);
            if w > 0.0 {
                for (&j, r) in p.nodes.iter().zip(&p.forces) {
                    let left = r.map(|x| w * x);
                    match merged.binary_search_by_key(&j, |e| e.0) {
                        Ok(k) => {
                            for (a, b) in merged[k].1.iter_mut().zip(left) {
                                *a += b;
                            }
                        }
                        Err(k) => merged.insert(k, (j, left)),
                    }
                }
            }
        }
        Handover {
            nodes: merged.iter().map(|e| e.0).collect(),
            forces: merged.iter().map(|e| e.1).collect(),
            started: now,
            duration,
        }
    }

    /// Leaves out the nodes at index `n` and above (slots a removal freed: a node added
    /// there later is another node).
    pub fn keep_below(&mut self, n: usize) {
        let end = self.nodes.partition_point(|&j| (j as usize) < n);
        self.nodes.truncate(end);
        self.forces.truncate(end);
    }

    /// The forces to add at time `now`, node by node.
    pub fn at(&self, now: f64) -> Vec<[f64; 3]> {
        let w = self.weight(now);
        self.forces.iter().map(|r| r.map(|x| w * x)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_refresh_hands_over_before_the_next_one() {
        // 0.47 mm between refreshes: at 5 mm/s (0.274 ms steps) the next one is 94 ms
        // away and the handover takes the full 40 ms; at 20 mm/s with 1 ms steps, 23.5 ms.
        let dt = 2.74e-4;
        assert_eq!(refresh_handover_time(4.7e-4, 0.005 * dt, dt), HANDOVER_TIME);
        let t = refresh_handover_time(4.7e-4, 0.02 * 1e-3, 1e-3);
        assert!((t - 0.0235).abs() < 1e-12, "{t}");
        // Faster than a refresh a step: one step; standing still (no refresh is due):
        // the full time.
        assert_eq!(refresh_handover_time(4.7e-4, 1e-3, 1e-3), 1e-3);
        assert_eq!(refresh_handover_time(4.7e-4, 0.0, 1e-3), HANDOVER_TIME);
    }

    #[test]
    fn weight_falls_smoothly_from_one_to_zero() {
        let h = Handover::start(None, 1.0, &[3], &[[2.0, 0.0, 0.0]], 0.04);
        assert_eq!(h.weight(1.0), 1.0);
        assert!((h.weight(1.02) - 0.5).abs() < 1e-12);
        assert_eq!(h.weight(1.04), 0.0);
        assert!(h.done(1.05) && !h.done(1.039));
        // C1: the slope vanishes at both ends (a finite difference over 1e-6 of the span).
        let e = 0.04e-6;
        assert!((1.0 - h.weight(1.0 + e)) < 1e-9);
        assert!(h.weight(1.04 - e) < 1e-9);
    }

    #[test]
    fn a_second_event_adds_what_is_left_of_the_first_and_the_force_stays_continuous() {
        let a = Handover::start(
            None,
            0.0,
            &[1, 5],
            &[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]],
            0.04,
        );
        // Half way through: w = 0.5.
        let b = Handover::start(
            Some(&a),
            0.02,
            &[2, 5],
            &[[0.0, 0.0, 4.0], [0.0, 1.0, 0.0]],
            0.04,
        );
        assert_eq!(b.nodes, vec![1, 2, 5]);
        assert_eq!(
            b.forces,
            vec![[0.5, 0.0, 0.0], [0.0, 0.0, 4.0], [0.0, 2.0, 0.0]]
        );
        // Just before the second event the first applied 0.5 r; at it the second applies
        // that plus its own difference (which the rows' change took away at once).
        assert_eq!(b.at(0.02)[0], a.at(0.02)[0]);
    }

    #[test]
    fn freed_slots_are_left_out() {
        let mut h = Handover::start(None, 0.0, &[1, 7, 9], &[[1.0; 3]; 3], 0.04);
        h.keep_below(8);
        assert_eq!(h.nodes, vec![1, 7]);
        assert_eq!(h.forces.len(), 2);
    }
}
