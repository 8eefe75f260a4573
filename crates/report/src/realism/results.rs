//! What the realism section measured.

use super::audit::Audit;

/// The dent and the slope of one liver run.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DentSlope {
    /// Label (spacing or model).
    pub label: String,
    /// Mesh nodes.
    pub nodes: usize,
    /// Node spacing, m.
    pub spacing: f64,
    /// Tip depth past the first contact at the puncture, m.
    pub dent: f64,
    /// Force when it punctured, N.
    pub peak: f64,
    /// Slope of the axial force against depth after the puncture, N/m; `None` when the
    /// insertion ends before the fit has rows enough (more than 10 from two spacings past
    /// the puncture: a short run at a coarse spacing).
    pub slope: Option<f64>,
    /// The run's force against depth (mm, N) for the plots.
    pub curve: Vec<(f64, f64)>,
}

/// What the realism section measured.
#[derive(Debug, Clone, Default)]
pub struct Realism {
    /// Per scene: name, nodes, audit.
    pub scenes: Vec<(String, usize, Audit)>,
    /// The liver scene without friction: its audit with the flatness against the
    /// cutting force, and that force.
    pub friction_off: Option<(Audit, f64)>,
    /// Dent and slope at 0.7, 1 and 1.4 times the liver's spacing.
    pub spacing: Vec<DentSlope>,
    /// Dent and slope per model.
    pub models: Vec<DentSlope>,
    /// Insertion speed (m/s), axial force at 25 mm (N).
    pub speeds: Vec<(f64, f64)>,
    /// Spin (rev/s), axial force at 25 mm (N), friction part at 25 mm (N).
    pub spin: Vec<(f64, f64, f64)>,
    /// Spin prediction: the friction's axial share `v / sqrt(v^2 + (omega a)^2)`.
    pub spin_predicted: f64,
    /// The dent of a flat punch of the liver's contact radius on a half-space of its
    /// material at the puncture force, m.
    pub dent_half_space: f64,
    /// The energy of the node events of the liver scene's insertion.
    pub events: Option<EventEnergy>,
    /// The liver scene with viscoelastic tissue (`scenes/liver_insertion_viscoelastic.toml`).
    pub viscoelastic: Option<ViscoStudy>,
    /// Run time, s.
    pub seconds: f64,
}

/// The viscoelastic liver's speed and hold studies.
#[derive(Debug, Clone, Default)]
pub struct ViscoStudy {
    /// The Prony series, (g, tau in s) per term.
    pub series: Vec<(f64, f64)>,
    /// Insertion speed (m/s), axial force at 25 mm (N).
    pub speeds: Vec<(f64, f64)>,
    /// Holds after insertions at these speeds (m/s): the axial force when the needle
    /// stops (N), 3 s later (N), and the time constant (s) of `A + B exp(-t / T)` fitted
    /// to the force over the hold.
    pub holds: Vec<(f64, f64, f64, f64)>,
}

/// What the node events (a needle node added or removed while inside) put into the
/// tissue's motion, against the work the needle does meanwhile: for each event, the rise
/// of the tissue's kinetic energy over the 20 ms after it (its largest value minus the
/// value before the event) and the needle's work over those 20 ms (`F` times the
/// advance). Windows of the same length with no event give the background.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EventEnergy {
    /// Node events counted.
    pub events: usize,
    /// Median and largest kinetic energy rise after an event, J.
    pub rise_median: f64,
    /// Largest rise, J.
    pub rise_max: f64,
    /// Median rise over 20 ms windows without an event, J.
    pub background: f64,
    /// Median needle work over the 20 ms after an event, J.
    pub work_median: f64,
}
