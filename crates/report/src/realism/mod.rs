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
//!   neo-Hookean, shape matching and mass-spring with the calibration `k = C E h`
//!   (`needlesim_core::calibration`), all with the liver's E and nu;
//! - **speed**: the force at 25 mm for insertions at 2, 5, 10 and 20 mm/s (the tissue is
//!   elastic: it should not depend on speed);
//! - **viscoelastic**: the same speeds with the Prony series of
//!   `scenes/liver_insertion_viscoelastic.toml` (the force rises with speed), and a 3 s
//!   hold after the slowest and the fastest insertion (the force relaxes; the time
//!   constant of one exponential fitted to it);
//! - **spin**: the force at 25 mm while the needle turns one revolution per second about
//!   its axis, against the Coulomb prediction for friction on a helical path
//!   ([`needlesim_needle::sheath`]).
//!
//! The local force of the audit is a centred moving mean of `|F|` over 50 ms with zero
//! padding at the ends of the series (numpy's `convolve(..., "same")`), floored at 10% of
//! the largest `|F|`; a series that ends with the needle inside and a force on it reads a
//! buzz of about 40% in its last 10 ms from that padding alone. The tables give the buzz
//! with and without the series' last 20 ms.

mod audit;
mod results;
mod write;

use audit::median;
pub use audit::{audit, rows, Audit, Row};
pub use results::{DentSlope, EventEnergy, Realism, ViscoStudy};
pub use write::{markdown, write_realism};

use crate::error::ReportError;
use crate::needle::{line_fit, sim_for, start_cpu};
use needlesim_core::Scene;
use needlesim_needle::{PunctureState, Simulation, SimulationError};
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
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
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

/// A fitted slope for the progress lines and the report, or why there is none.
pub(crate) fn slope_text(slope: Option<f64>) -> String {
    slope.map_or(
        "n/a (the insertion ends within two spacings of the puncture)".into(),
        |s| format!("{s:.1} N/m"),
    )
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
    let slope = (x.len() > 10).then(|| line_fit(&x, &y).0);
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

/// The liver scene `liver` with the Prony series of
/// `scenes/liver_insertion_viscoelastic.toml`: the force at 25 mm at each of `speeds`
/// (m/s, the tip travelling `travel`), and a 3 s hold after the insertion at the slowest
/// and the fastest of them.
fn viscoelastic_study(
    liver: &toml::Table,
    speeds: &[f64],
    travel: f64,
    progress: &mut dyn FnMut(&str),
) -> Result<ViscoStudy, ReportError> {
    let visco = read_scene("liver_insertion_viscoelastic")?;
    let terms = visco["material"]["viscoelastic"].clone();
    let mut base = liver.clone();
    set(&mut base, "material.viscoelastic", terms.clone());
    let mut study = ViscoStudy {
        series: terms
            .as_array()
            .expect("an array of terms")
            .iter()
            .map(|t| {
                (
                    t["g"].as_float().expect("g"),
                    t["tau"].as_float().expect("tau"),
                )
            })
            .collect(),
        ..ViscoStudy::default()
    };
    for &v in speeds {
        let mut t = base.clone();
        set(&mut t, "needle.keyframe.0.speed", v.into());
        set(&mut t, "needle.keyframe.0.duration", (travel / v).into());
        set(&mut t, "run.duration", (travel / v + 0.5).into());
        let sim = run(&t, Some(travel / v))?;
        let f = force_at(&sim, 0.025);
        progress(&format!(
            "realism      viscoelastic liver at {:.0} mm/s: {f:.3} N at 25 mm",
            1e3 * v
        ));
        study.speeds.push((v, f));
    }
    const HOLD: f64 = 3.0;
    let (lo, hi) = (speeds[0], speeds[speeds.len() - 1]);
    for v in [lo, hi] {
        let mut t = base.clone();
        set(&mut t, "needle.keyframe.0.speed", v.into());
        set(&mut t, "needle.keyframe.0.duration", (travel / v).into());
        set(&mut t, "needle.keyframe.1.duration", HOLD.into());
        let stop = travel / v;
        // The scene's own run is shorter than a slow insertion and its hold.
        set(&mut t, "run.duration", (stop + HOLD + 0.5).into());
        let sim = run(&t, Some(stop + HOLD))?;
        // The hold from 50 ms after the stop (the speed ramp's end) to its end.
        let held: Vec<(f64, f64)> = rows(&sim)
            .iter()
            .filter(|r| r.time >= stop + 0.05 && r.time <= stop + HOLD)
            .map(|r| (r.time - stop, r.force))
            .collect();
        let (Some(first), Some(last)) = (held.first(), held.last()) else {
            return Err(ReportError::Scene(
                "the viscoelastic hold recorded nothing".into(),
            ));
        };
        let tau = exponential_time_constant(&held);
        progress(&format!(
            "realism      viscoelastic liver held 3 s after {:.0} mm/s: {:.3} N -> {:.3} N ({:.1}%), fitted time constant {tau:.2} s",
            1e3 * v,
            first.1,
            last.1,
            100.0 * (last.1 / first.1 - 1.0)
        ));
        study.holds.push((v, first.1, last.1, tau));
    }
    Ok(study)
}

/// The time constant `T` of `A + B exp(-t / T)` fitted by least squares to the points
/// `(t, y)`: for each `T` the best `A` and `B` are linear; `T` is found by a golden
/// section search on `ln T` over 0.01 to 100 s.
fn exponential_time_constant(points: &[(f64, f64)]) -> f64 {
    let cost = |ln_t: f64| {
        let tau = ln_t.exp();
        let (mut n, mut se, mut see, mut sy, mut sey) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for &(t, y) in points {
            let e = (-t / tau).exp();
            n += 1.0;
            se += e;
            see += e * e;
            sy += y;
            sey += e * y;
        }
        let det = n * see - se * se;
        if det.abs() < 1e-300 {
            return f64::INFINITY;
        }
        let b = (n * sey - se * sy) / det;
        let a = (sy - b * se) / n;
        points
            .iter()
            .map(|&(t, y)| (a + b * (-t / tau).exp() - y).powi(2))
            .sum::<f64>()
    };
    let (mut lo, mut hi) = (0.01f64.ln(), 100f64.ln());
    let r = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..100 {
        let (a, b) = (hi - r * (hi - lo), lo + r * (hi - lo));
        if cost(a) < cost(b) {
            hi = b;
        } else {
            lo = a;
        }
    }
    (0.5 * (lo + hi)).exp()
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
            "realism      liver at {:.4} m: dent {:.2} mm at {:.3} N, slope {}",
            base_h * factor,
            1e3 * ds.dent,
            ds.peak,
            slope_text(ds.slope)
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
        "neo_hookean",
        "local_shape_matching",
        "mass_spring",
    ] {
        let mut t = liver.clone();
        let mut mat = toml::Table::new();
        match model {
            "debunne_corotated" => mat = liver["material"].as_table().expect("material").clone(),
            "point_based" | "neo_hookean" => {
                mat.insert("model".into(), model.into());
                mat.insert("young_modulus".into(), young.into());
                mat.insert("poisson_ratio".into(), nu.into());
                // The same tissue loss as the scene's (the continuum models all take the
                // Kelvin-Voigt viscosity).
                if let Some(eta) = liver["material"].get("viscosity") {
                    mat.insert("viscosity".into(), eta.clone());
                }
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
            "realism      liver, {model}: dent {:.2} mm at {:.3} N, slope {}",
            1e3 * ds.dent,
            ds.peak,
            slope_text(ds.slope)
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
    // Viscoelastic tissue: the same speeds, and holds.
    rep.viscoelastic = Some(viscoelastic_study(&liver, speeds, travel, progress)?);
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

#[cfg(test)]
mod tests {
    use super::results::{DentSlope, Realism};

    /// A spacing case whose insertion ends before the slope fit has rows (a short run at a
    /// coarse spacing, as in CI's reduced report) reads "n/a" in the markdown and is an
    /// empty value in the CSV, never NaN; the spread is over the cases with a slope.
    #[test]
    fn a_missing_slope_is_n_a_not_nan() {
        let case = |label: &str, slope| DentSlope {
            label: label.into(),
            nodes: 100,
            spacing: 0.01,
            dent: 0.007,
            peak: 1.0,
            slope,
            curve: vec![(0.0, 0.0), (1.0, 0.1)],
        };
        let r = Realism {
            spacing: vec![
                case("0.7 x spacing", Some(44.0)),
                case("1 x spacing", Some(45.5)),
                case("1.4 x spacing", None),
            ],
            ..Realism::default()
        };
        let mut md = String::new();
        super::markdown(&mut md, &r);
        assert!(md.contains("| n/a |") && !md.contains("NaN"), "{md}");
        assert!(md.contains("over the 2 cases with a slope"), "{md}");
        let dir = tempfile::tempdir().unwrap();
        super::write_realism(dir.path(), &r).unwrap();
        let csv = std::fs::read_to_string(dir.path().join("realism.csv")).unwrap();
        assert!(!csv.contains("NaN"), "{csv}");
        assert!(
            csv.contains("spacing,1.4 x spacing,slope_n_per_m,\n"),
            "{csv}"
        );
        assert!(super::slope_text(None).starts_with("n/a"));
    }

    /// The fitted time constant of a clean `A + B exp(-t / T)` is `T` (within 1e-4), and
    /// 3 s of record resolve a constant longer than the record.
    #[test]
    fn one_exponential_fit_recovers_its_time_constant() {
        for tau in [0.3, 1.86, 5.0] {
            let points: Vec<(f64, f64)> = (0..300)
                .map(|i| {
                    let t = 0.05 + 0.01 * i as f64;
                    (t, 0.9 + 0.4 * (-t / tau).exp())
                })
                .collect();
            let got = super::exponential_time_constant(&points);
            assert!((got / tau - 1.0).abs() < 1e-4, "{got} against {tau}");
        }
    }
}
