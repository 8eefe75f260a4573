//! The report's realism section: whether the needle force comes from the tissue and not
//! from the node bookkeeping, measured the way `shared/tools/force_audit.py` measures it
//! (the definitions of [`audit`], which this module reproduces), on every shipped needle
//! scene and on studies of the liver scene:
//!
//! - **events**: steps whose force changes by more than 5% of the local force that are not
//!   within 20 ms of a puncture (jumps), the RMS of the part of the force above about
//!   50 Hz over 20 ms windows (buzz), the median step change while the needle is held and
//!   while it moves, axial force below zero while advancing, and the largest single-step
//!   change within 50 ms after each reversal;
//! - **friction off**: the liver scene with friction coefficient 0, whose force should be
//!   the cutting force between its puncture and the end of the insertion;
//! - **spacing** and **models**: the dent (tip depth past the first contact when the
//!   entry punctures) and the slope of force against depth after it, at 0.7, 1 and 1.4
//!   times the liver scene's spacing, and for co-rotated Debunne, point based animation,
//!   shape matching and mass-spring with the calibration `k = C E h`
//!   (`needlesim_core::calibration`), all with the liver's E and nu;
//! - **speed**: the force at 25 mm for insertions at 2, 5, 10 and 20 mm/s (the tissue is
//!   elastic: it should not depend on speed);
//! - **spin**: the force at 25 mm while the needle turns one revolution per second about
//!   its axis, against the Coulomb prediction for friction on a helical path
//!   ([`needlesim_needle::sheath`]).
//!
//! The local force of the audit is a centred moving mean of `|F|` over 50 ms with zero
//! padding at the ends of the series (numpy's `convolve(..., "same")`), floored at 10% of
//! the largest `|F|`; a series that ends with the needle inside and a force on it reads a
//! buzz of about 40% in its last 10 ms from that padding alone. The tables give the buzz
//! with and without the series' last 20 ms.

use crate::error::ReportError;
use crate::needle::{line_fit, sim_for, start_cpu};
use crate::plot::{line_plot, Labels, Series};
use needlesim_core::Scene;
use needlesim_needle::{NeedleSample, PunctureState, Simulation, SimulationError};
use std::fmt::Write as _;
use std::path::Path;

/// The needle scenes the section audits, by file name.
pub const SCENES: [&str; 8] = [
    "liver_insertion",
    "layered_liver_biopsy",
    "phantom_insertion",
    "needle_insert_extract",
    "paper_insertion_lshm",
    "paper_insertion_deb",
    "paper_insertion_pba",
    "paper_insertion_msm",
];

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

fn median(mut v: Vec<f64>) -> Option<f64> {
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
        flatness,
    }
}

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
    /// Slope of the axial force against depth after the puncture, N/m.
    pub slope: f64,
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
    /// Run time, s.
    pub seconds: f64,
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

/// Runs the liver scene `table` for `seconds`, recording the tissue's kinetic energy at
/// every step (from the positions' inverse mass and the velocities), and measures the
/// node events ([`EventEnergy`]).
fn event_energy(table: &toml::Table, seconds: f64) -> Result<EventEnergy, ReportError> {
    let (_, mut sim) = start(table)?;
    let steps = (seconds / sim.dt()).ceil() as usize;
    let mut energy = Vec::with_capacity(steps);
    let (mut p, mut v) = (Vec::new(), Vec::new());
    for _ in 0..steps {
        sim.step()?;
        let n = sim.editor().n_active();
        p.resize(n, [0.0f32; 4]);
        v.resize(n, [0.0f32; 4]);
        let backend = sim.backend();
        backend
            .read(needlesim_core::NodeField::Position, 0..n, &mut p)
            .map_err(SimulationError::from)?;
        backend
            .read(needlesim_core::NodeField::Velocity, 0..n, &mut v)
            .map_err(SimulationError::from)?;
        let e: f64 = p
            .iter()
            .zip(&v)
            .filter(|(x, _)| x[3] > 0.0)
            .map(|(x, u)| {
                let v2: f64 = u[..3].iter().map(|c| (*c as f64).powi(2)).sum();
                0.5 * v2 / x[3] as f64
            })
            .sum();
        energy.push(e);
    }
    let h = sim.history();
    let r = rows(&sim);
    let window = (0.02 / sim.dt()).round() as usize;
    let first = r.iter().position(|x| x.state == PunctureState::Inside);
    let Some(first) = first else {
        return Ok(EventEnergy::default());
    };
    let start = first + window;
    let mut rises = Vec::new();
    let mut works = Vec::new();
    let mut quiet = Vec::new();
    let rise = |k: usize| {
        let top = energy[k..(k + window).min(energy.len())]
            .iter()
            .cloned()
            .fold(0.0, f64::max);
        top - energy[k - 1]
    };
    let mut k = start.max(1);
    while k + window < h.len() {
        let event = (k..k + window).find(|&i| h[i].needle_nodes != h[i - 1].needle_nodes);
        match event {
            Some(e) if e + window < h.len() => {
                rises.push(rise(e));
                works.push(
                    (e..e + window)
                        .map(|i| r[i].force * (r[i + 1].depth - r[i].depth))
                        .sum::<f64>(),
                );
                k = e + window;
            }
            Some(_) => break,
            None => {
                quiet.push(rise(k));
                k += window;
            }
        }
    }
    let med = |v: &[f64]| median(v.to_vec()).unwrap_or(f64::NAN);
    Ok(EventEnergy {
        events: rises.len(),
        rise_median: med(&rises),
        rise_max: rises.iter().cloned().fold(0.0, f64::max),
        background: med(&quiet),
        work_median: med(&works),
    })
}

fn scene_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

fn read_scene(name: &str) -> Result<toml::Table, ReportError> {
    let path = scene_dir().join(format!("{name}.toml"));
    let text = std::fs::read_to_string(&path).map_err(|source| ReportError::Io {
        path: path.display().to_string(),
        source,
    })?;
    text.parse::<toml::Table>()
        .map_err(|e| ReportError::Scene(format!("{}: {e}", path.display())))
}

/// Moves the liver scene's fixed set (`above` along x) onto the last lattice plane at
/// spacing `h`: a spacing that does not divide the block leaves that plane short of the
/// face, and the scene's `above = 0.0799` would then hold no node.
fn hold_far_face(table: &mut toml::Table, h: f64) {
    let geometry = &table["tissue"]["geometry"];
    let coord = |key: &str| geometry[key].as_array().expect("box corner")[0].as_float();
    let (lo, hi) = (coord("min").expect("min"), coord("max").expect("max"));
    let last = lo + ((hi - lo) / h + 1e-9).floor() * h;
    set(table, "fixed.0.above", (last - 0.1 * h).into());
}

/// Sets the dotted key `key` of `table` (every part but the last must exist; the part
/// after an array's name is an index into it).
fn set(table: &mut toml::Table, key: &str, value: toml::Value) {
    fn walk(t: &mut toml::Table, parts: &[&str], value: toml::Value, key: &str) {
        if let [last] = parts {
            t.insert(last.to_string(), value);
            return;
        }
        match t.get_mut(parts[0]) {
            Some(toml::Value::Table(inner)) => walk(inner, &parts[1..], value, key),
            Some(toml::Value::Array(a)) => {
                let i: usize = parts[1]
                    .parse()
                    .unwrap_or_else(|_| panic!("index in {key}"));
                let inner = a[i]
                    .as_table_mut()
                    .unwrap_or_else(|| panic!("{key}: not a table"));
                walk(inner, &parts[2..], value, key)
            }
            _ => panic!("scene has no {} (key {key})", parts[0]),
        }
    }
    let parts: Vec<&str> = key.split('.').collect();
    walk(table, &parts, value, key);
}

/// The scene `table` and its simulation started on the CPU (all threads).
fn start(table: &toml::Table) -> Result<(Scene, Simulation), ReportError> {
    let text = toml::to_string(table).map_err(|e| ReportError::Scene(e.to_string()))?;
    start_cpu(&text, &scene_dir())
}

/// Runs the scene `table` on the CPU (all threads) for its run length or `seconds`.
fn run(table: &toml::Table, seconds: Option<f64>) -> Result<Simulation, ReportError> {
    let text = toml::to_string(table).map_err(|e| ReportError::Scene(e.to_string()))?;
    sim_for(&text, &scene_dir(), seconds)
}

/// The first move keyframe's speed (m/s) and duration (s) of a scene.
fn first_move(table: &toml::Table) -> (f64, f64) {
    let k = table["needle"]["keyframe"][0]
        .as_table()
        .expect("a keyframe");
    let f = |key: &str| k[key].as_float().expect("a number");
    (f("speed"), f("duration"))
}

/// Dent, peak and slope of a liver run: the dent and peak at the last Touching row, the
/// slope fitted to the inside rows while advancing from two spacings past the puncture
/// (the tear and the shaft's first node past) to the end of the insertion.
fn dent_slope(sim: &Simulation, label: String, insertion: f64) -> DentSlope {
    let r = rows(sim);
    let last_touch = r.iter().rposition(|x| x.state == PunctureState::Touching);
    let (dent, peak) = last_touch.map_or((f64::NAN, f64::NAN), |i| (r[i].depth, r[i].force));
    let from = dent + 2.0 * sim.spacing();
    let (x, y): (Vec<f64>, Vec<f64>) = r
        .iter()
        .filter(|x| x.state == PunctureState::Inside && x.time <= insertion && x.depth >= from)
        .map(|x| (x.depth, x.force))
        .unzip();
    let slope = if x.len() > 10 {
        line_fit(&x, &y).0
    } else {
        f64::NAN
    };
    DentSlope {
        label,
        nodes: sim.editor().n_mesh(),
        spacing: sim.spacing(),
        dent,
        peak,
        slope,
        curve: r
            .iter()
            .filter(|x| x.time <= insertion)
            .map(|x| (1e3 * x.depth, x.force))
            .collect(),
    }
}

/// The axial force (N) when the tip first passed `depth` (m).
fn force_at(sim: &Simulation, depth: f64) -> f64 {
    rows(sim)
        .iter()
        .find(|x| x.depth >= depth && x.state == PunctureState::Inside)
        .map_or(f64::NAN, |x| x.force)
}

/// Runs the section. `full`: every scene as shipped and the studies at the liver scene's
/// own 5 mm spacing; otherwise (CI) the liver studies at 10 mm, the layered scene left
/// out and the other scenes as shipped.
pub fn run_realism(full: bool, progress: &mut dyn FnMut(&str)) -> Result<Realism, ReportError> {
    let start = std::time::Instant::now();
    let mut rep = Realism::default();
    let mut liver = read_scene("liver_insertion")?;
    let base_h = if full { 0.005 } else { 0.01 };
    set(&mut liver, "tissue.geometry.spacing", base_h.into());
    for name in SCENES {
        if !full && name == "layered_liver_biopsy" {
            continue;
        }
        let table = match name {
            "liver_insertion" => liver.clone(),
            _ => read_scene(name)?,
        };
        let sim = run(&table, None)?;
        let a = audit(&rows(&sim), None);
        progress(&format!(
            "realism      {name}: {} jumps, buzz {:.2}% ({:.2}% before the last 20 ms), {:.2}% of rows over 2%, held {} (still {}, rotating {}), moving {}",
            a.jumps,
            a.buzz_max,
            a.buzz_max_body,
            100.0 * a.buzz_share,
            a.held.map_or("-".into(), |x| format!("{x:.4}%")),
            a.still.map_or("-".into(), |x| format!("{x:.4}%")),
            a.rotating.map_or("-".into(), |x| format!("{x:.4}%")),
            a.moving.map_or("-".into(), |x| format!("{x:.4}%")),
        ));
        rep.scenes
            .push((name.to_string(), sim.editor().n_mesh(), a));
    }
    let (speed, duration) = first_move(&liver);
    let insertion = duration + 1.0; // the first contact comes after about a second
                                    // Friction off: the cutting force alone.
    let cutting = liver["needle"]["cutting"].as_float().expect("cutting");
    let mut off = liver.clone();
    set(&mut off, "needle.friction.coefficient", 0.0.into());
    let sim = run(&off, Some(insertion))?;
    let a = audit(&rows(&sim), Some(cutting));
    progress(&format!(
        "realism      liver, friction off: within {:.2}% of the cutting force {cutting} N, {} jumps",
        a.flatness.unwrap_or(f64::NAN),
        a.jumps
    ));
    rep.friction_off = Some((a, cutting));
    // Spacing.
    for factor in [0.7, 1.0, 1.4] {
        let mut t = liver.clone();
        set(&mut t, "tissue.geometry.spacing", (base_h * factor).into());
        hold_far_face(&mut t, base_h * factor);
        let sim = run(&t, Some(duration))?;
        let ds = dent_slope(&sim, format!("{factor} x spacing"), duration);
        progress(&format!(
            "realism      liver at {:.4} m: dent {:.2} mm at {:.3} N, slope {:.1} N/m",
            base_h * factor,
            1e3 * ds.dent,
            ds.peak,
            ds.slope
        ));
        rep.spacing.push(ds);
    }
    // Models with the liver's E and nu.
    let young = liver["material"]["young_modulus"].as_float().expect("E");
    let nu = liver["material"]["poisson_ratio"].as_float().expect("nu");
    let k = liver["tissue"]
        .get("neighbours")
        .and_then(|v| v.as_integer())
        .unwrap_or(18) as usize;
    let cal = needlesim_core::calibration::calibration(k)
        .map_err(|e| ReportError::Scene(e.to_string()))?;
    for model in [
        "debunne_corotated",
        "point_based",
        "local_shape_matching",
        "mass_spring",
    ] {
        let mut t = liver.clone();
        let mut mat = toml::Table::new();
        match model {
            "debunne_corotated" => mat = liver["material"].as_table().expect("material").clone(),
            "point_based" => {
                mat.insert("model".into(), "point_based".into());
                mat.insert("young_modulus".into(), young.into());
                mat.insert("poisson_ratio".into(), nu.into());
                mat.insert("hourglass".into(), 4.0.into());
            }
            "local_shape_matching" => {
                mat.insert("model".into(), "local_shape_matching".into());
                mat.insert("forces".into(), "cluster".into());
                mat.insert(
                    "stiffness".into(),
                    (cal.shape_matching_cluster * young * base_h).into(),
                );
            }
            _ => {
                mat.insert("model".into(), "mass_spring".into());
                mat.insert(
                    "stiffness".into(),
                    (cal.mass_spring * young * base_h).into(),
                );
            }
        }
        t.insert("material".into(), mat.into());
        let sim = run(&t, Some(duration))?;
        let ds = dent_slope(&sim, model.to_string(), duration);
        progress(&format!(
            "realism      liver, {model}: dent {:.2} mm at {:.3} N, slope {:.1} N/m",
            1e3 * ds.dent,
            ds.peak,
            ds.slope
        ));
        rep.models.push(ds);
    }
    let contact = liver["needle"]["contact_radius"]
        .as_float()
        .expect("contact_radius");
    let fp = liver["needle"]["puncture_force"]
        .as_float()
        .expect("puncture_force");
    rep.dent_half_space = fp * needlesim_needle::sheath::punch_compliance(young, nu, contact);
    // Speed: the tip reaches 25 mm at every speed.
    let travel = speed * duration;
    let speeds: &[f64] = if full {
        &[0.002, 0.005, 0.01, 0.02]
    } else {
        &[0.005, 0.02]
    };
    for &v in speeds {
        let mut t = liver.clone();
        set(&mut t, "needle.keyframe.0.speed", v.into());
        set(&mut t, "needle.keyframe.0.duration", (travel / v).into());
        let sim = run(&t, Some(travel / v))?;
        let f = force_at(&sim, 0.025);
        progress(&format!(
            "realism      liver at {:.0} mm/s: {f:.3} N at 25 mm",
            1e3 * v
        ));
        rep.speeds.push((v, f));
    }
    // The node events' energy, on the liver at the section's spacing.
    let ev = event_energy(&liver, duration)?;
    progress(&format!(
        "realism      liver node events: {} events, kinetic energy rise median {:.2e} J (largest {:.2e} J, without events {:.2e} J), needle work over the same 20 ms {:.2e} J",
        ev.events, ev.rise_median, ev.rise_max, ev.background, ev.work_median
    ));
    rep.events = Some(ev);
    // Spin at one revolution per second while inserting.
    let radius = liver["needle"]["radius"].as_float().expect("radius");
    let omega = 2.0 * std::f64::consts::PI;
    rep.spin_predicted = speed / speed.hypot(omega * radius);
    for rev in [0.0, 1.0] {
        let mut t = liver.clone();
        set(&mut t, "needle.keyframe.0.spin", (360.0 * rev).into());
        let sim = run(&t, Some(duration))?;
        let f = force_at(&sim, 0.025);
        let friction: f64 = sim
            .history()
            .iter()
            .zip(rows(&sim))
            .find(|(_, r)| r.depth >= 0.025 && r.state == PunctureState::Inside)
            .map_or(f64::NAN, |(s, _)| s.force.axial - s.force.tip);
        progress(&format!(
            "realism      liver spinning {rev} rev/s: {f:.3} N at 25 mm (friction {friction:.3} N)"
        ));
        rep.spin.push((rev, f, friction));
    }
    rep.seconds = start.elapsed().as_secs_f64();
    Ok(rep)
}

fn pct(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.3}"))
}

/// Writes `realism.csv`, `realism_spacing.png` and `realism_models.png` into `out`.
pub fn write_realism(out: &Path, r: &Realism) -> std::io::Result<()> {
    let mut csv = String::from("study,case,quantity,value\n");
    for (name, nodes, a) in &r.scenes {
        let mut row = |q: &str, v: f64| writeln!(csv, "scene,{name},{q},{v:e}").unwrap();
        row("nodes", *nodes as f64);
        row("jumps", a.jumps as f64);
        row("buzz_max_percent", a.buzz_max);
        row("buzz_max_before_last_20ms_percent", a.buzz_max_body);
        row("buzz_share_over_2_percent", a.buzz_share);
        row("median_step_held_percent", a.held.unwrap_or(f64::NAN));
        row("median_step_still_percent", a.still.unwrap_or(f64::NAN));
        row(
            "median_step_rotating_percent",
            a.rotating.unwrap_or(f64::NAN),
        );
        row("median_step_moving_percent", a.moving.unwrap_or(f64::NAN));
        row("negative_while_advancing_rows", a.negative_advancing as f64);
        row("reversal_max_step_percent", a.reversal.unwrap_or(f64::NAN));
    }
    if let Some((a, c)) = &r.friction_off {
        writeln!(csv, "friction_off,liver,cutting_n,{c:e}").unwrap();
        writeln!(
            csv,
            "friction_off,liver,max_deviation_percent,{:e}",
            a.flatness.unwrap_or(f64::NAN)
        )
        .unwrap();
    }
    if let Some(e) = &r.events {
        for (q, x) in [
            ("events", e.events as f64),
            ("kinetic_rise_median_j", e.rise_median),
            ("kinetic_rise_max_j", e.rise_max),
            ("kinetic_rise_without_events_j", e.background),
            ("needle_work_median_j", e.work_median),
        ] {
            writeln!(csv, "node_events,liver,{q},{x:e}").unwrap();
        }
    }
    for (study, v) in [("spacing", &r.spacing), ("model", &r.models)] {
        for d in v {
            for (q, x) in [
                ("nodes", d.nodes as f64),
                ("spacing_m", d.spacing),
                ("dent_m", d.dent),
                ("peak_n", d.peak),
                ("slope_n_per_m", d.slope),
            ] {
                writeln!(csv, "{study},{},{q},{x:e}", d.label).unwrap();
            }
        }
    }
    for (v, f) in &r.speeds {
        writeln!(csv, "speed,{v},force_at_25mm_n,{f:e}").unwrap();
    }
    for (rev, f, fr) in &r.spin {
        writeln!(csv, "spin,{rev},force_at_25mm_n,{f:e}").unwrap();
        writeln!(csv, "spin,{rev},friction_at_25mm_n,{fr:e}").unwrap();
    }
    std::fs::write(out.join("realism.csv"), csv)?;
    let colours = [[200, 40, 40], [40, 90, 200], [40, 150, 60], [150, 90, 20]];
    for (file, title, v) in [
        (
            "realism_spacing.png",
            "liver scene: force against depth at three spacings",
            &r.spacing,
        ),
        (
            "realism_models.png",
            "liver scene: force against depth, four tissue models",
            &r.models,
        ),
    ] {
        let series: Vec<Series> = v
            .iter()
            .zip(colours)
            .map(|(d, colour)| Series {
                label: &d.label,
                colour,
                points: d.curve.clone(),
            })
            .collect();
        line_plot(
            &out.join(file),
            &Labels {
                title,
                x: "tip depth past first contact (mm)",
                y: "axial force (N)",
            },
            &series,
        )?;
    }
    Ok(())
}

/// Runs the section alone ([`run_realism`]) and writes it into `out` (created):
/// `realism.md` besides the files of [`write_realism`].
pub fn run_and_write(
    full: bool,
    out: &Path,
    progress: &mut dyn FnMut(&str),
) -> Result<Realism, ReportError> {
    let r = run_realism(full, progress)?;
    let io = |source| ReportError::Io {
        path: out.display().to_string(),
        source,
    };
    std::fs::create_dir_all(out).map_err(io)?;
    write_realism(out, &r).map_err(io)?;
    let mut md = String::from("# needlesim: needle force realism\n");
    markdown(&mut md, &r);
    std::fs::write(out.join("realism.md"), md).map_err(io)?;
    Ok(r)
}

/// Spread of `x` as (max - min) / mean, %.
fn spread(x: impl Iterator<Item = f64> + Clone) -> f64 {
    let (lo, hi) = x
        .clone()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    let n = x.clone().count() as f64;
    let mean = x.sum::<f64>() / n;
    100.0 * (hi - lo) / mean
}

/// Appends the section to the report's markdown.
pub fn markdown(md: &mut String, r: &Realism) {
    writeln!(md, "\n## Needle force realism\n").unwrap();
    writeln!(
        md,
        "Figures of `shared/tools/force_audit.py` (jumps: steps changing by more than 5% of the local force, inside and not within 20 ms of a puncture; buzz: RMS above about 50 Hz over 20 ms over the local force; held/moving: median step change, the held rows split into the needle still and turning at constant depth; negative: rows advancing with F < 0; reversal: largest step within 50 ms after a reversal over the force there). The audit's zero padding reads a buzz of about 40% in the last 10 ms of a series that ends with a force on the needle: the buzz is given with and without the last 20 ms. {:.0} s on this machine.\n",
        r.seconds
    )
    .unwrap();
    writeln!(
        md,
        "| scene | nodes | jumps | buzz max % (before last 20 ms) | rows buzz > 2% | held % (still / rotating) | moving % | negative | reversal % |"
    )
    .unwrap();
    writeln!(md, "|---|---:|---:|---:|---:|---:|---:|---:|---:|").unwrap();
    for (name, nodes, a) in &r.scenes {
        writeln!(
            md,
            "| {name} | {nodes} | {} | {:.2} ({:.2}) | {:.2}% | {} ({} / {}) | {} | {} | {} |",
            a.jumps,
            a.buzz_max,
            a.buzz_max_body,
            100.0 * a.buzz_share,
            pct(a.held),
            pct(a.still),
            pct(a.rotating),
            pct(a.moving),
            a.negative_advancing,
            pct(a.reversal)
        )
        .unwrap();
    }
    if let Some((a, c)) = &r.friction_off {
        writeln!(
            md,
            "\nFriction off (liver scene, coefficient 0): the axial force stays within {:.2}% of the cutting force {c} N between the puncture (20 ms after) and the end of the insertion; {} jumps.\n",
            a.flatness.unwrap_or(f64::NAN),
            a.jumps
        )
        .unwrap();
    }
    if let Some(e) = &r.events {
        writeln!(
            md,
            "\nNode events (liver scene, insertion): {} additions and removals while inside. The tissue's kinetic energy rises by {:.2e} J (median; largest {:.2e} J) over the 20 ms after an event, against {:.2e} J over 20 ms windows without one, while the needle does {:.2e} J of work in those 20 ms: an event puts {:.2}% of that work (median) into motion. (The elastic energy of the models is not computed, so the budget's elastic side is not reported.)\n",
            e.events,
            e.rise_median,
            e.rise_max,
            e.background,
            e.work_median,
            100.0 * e.rise_median / e.work_median
        )
        .unwrap();
    }
    for (title, v) in [("Spacing", &r.spacing), ("Tissue model", &r.models)] {
        writeln!(md, "\n{title} study, liver scene (insertion only):\n").unwrap();
        writeln!(
            md,
            "| case | nodes | spacing mm | dent mm | force at puncture N | slope N/m |"
        )
        .unwrap();
        writeln!(md, "|---|---:|---:|---:|---:|---:|").unwrap();
        for d in v.iter() {
            writeln!(
                md,
                "| {} | {} | {:.2} | {:.2} | {:.3} | {:.1} |",
                d.label,
                d.nodes,
                1e3 * d.spacing,
                1e3 * d.dent,
                d.peak,
                d.slope
            )
            .unwrap();
        }
        if !v.is_empty() {
            writeln!(
                md,
                "\nSpread (max - min over mean): dent {:.1}%, slope {:.1}%.",
                spread(v.iter().map(|d| d.dent)),
                spread(v.iter().map(|d| d.slope))
            )
            .unwrap();
        }
    }
    writeln!(
        md,
        "\nA rigid flat punch of the contact radius on a half-space of the liver's material dents {:.2} mm at the puncture force (Sneddon 1965; the 8 cm block held on its far face is stiffer).",
        1e3 * r.dent_half_space
    )
    .unwrap();
    if !r.speeds.is_empty() {
        writeln!(
            md,
            "\nSpeed (elastic tissue: the force should not depend on it):\n"
        )
        .unwrap();
        writeln!(md, "| speed mm/s | force at 25 mm N |").unwrap();
        writeln!(md, "|---:|---:|").unwrap();
        for (v, f) in &r.speeds {
            writeln!(md, "| {:.0} | {f:.3} |", 1e3 * v).unwrap();
        }
    }
    if let [(_, f0, fr0), (_, f1, fr1)] = r.spin[..] {
        writeln!(
            md,
            "\nSpin (one revolution per second while inserting): axial force at 25 mm {f0:.3} N -> {f1:.3} N ({:+.1}%), friction {fr0:.3} N -> {fr1:.3} N ({:+.1}%; Coulomb friction on the helical path predicts x{:.3}, {:+.1}%). Measured: rotating the needle lowers the insertion force (Abolhassani, Patel and Moallem, Med Eng Phys 29:413, 2007, a survey of the experiments; Lin and Huang, IEEE TBME 67:3195, 2020, gelatin: the cutting force falls as the rotation speed rises). The model lowers the shaft's friction only, by the share the circumferential sliding takes; a cutting force that falls with rotation, which those gelatin tests measure, is not modelled, and no data set with the friction's share at a given ratio of surface to axial speed was found to compare the number with.",
            100.0 * (f1 / f0 - 1.0),
            100.0 * (fr1 / fr0 - 1.0),
            r.spin_predicted,
            100.0 * (r.spin_predicted - 1.0)
        )
        .unwrap();
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
