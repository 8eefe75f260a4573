//! The report's needle section: the liver scene's force against depth over the published
//! band, the smoothness of the needle force for every model (median step-to-step change
//! and the share of its power above 50 Hz during the paper's rotation and the pause after
//! it), the force-depth slope at two resolutions, and the layered liver biopsy scene's
//! membranes (peak, its depth in the undeformed tissue, the drop after it) and the slope
//! in each layer.
//!
//! Published band (cited in `scenes/liver_insertion.toml`): a puncture peak of 1 to 3 N
//! and a force-depth slope after puncture of 35 to 59 N/m (J Endourol 2016,
//! doi 10.1089/end.2016.0342).

use crate::error::ReportError;
use crate::plot::{line_plot, Labels, Series};
use needlesim_core::{CpuBackend, Scene, Threading};
use needlesim_needle::{
    Keyframe, NeedleConfig, NeedleSample, PunctureState, Simulation, SimulationError,
};
use std::fmt::Write as _;
use std::path::Path;

/// Published puncture peak band, N.
pub const PEAK_BAND: (f64, f64) = (1.0, 3.0);
/// Published force-depth slope band after puncture, N/m.
pub const SLOPE_BAND: (f64, f64) = (35.0, 59.0);

/// One model's smoothness: (label, rotation step change %, pause step change %, rotation
/// power above 50 Hz %), each axial and lateral.
pub type Smoothness = (String, [f64; 2], [f64; 2], [f64; 2]);

/// What the needle section measured.
#[derive(Debug, Clone, Default)]
pub struct NeedleReport {
    /// Liver scene: nodes, puncture peak (N), slope after puncture (N/m), R^2, residual
    /// standard deviation over the mean force.
    pub liver: Option<(usize, f64, f64, f64, f64)>,
    /// Per model: (label, rotation step change %, pause step change %, rotation power
    /// above 50 Hz %, axial and lateral).
    pub smoothness: Vec<Smoothness>,
    /// Slope per resolution: (nodes, needle spacing m, slope N/m).
    pub slopes: Vec<(usize, f64, f64)>,
    /// The layered scene, one row per region the tip entered while advancing.
    pub layers: Vec<LayerRow>,
    /// Seconds of the layered scene simulated.
    pub layers_seconds: f64,
    /// The liver run's (depth mm, axial N) for the plot.
    curve: Vec<(f64, f64)>,
}

/// A region the tip entered in the layered scene (`scenes/layered_liver_biopsy.toml`).
#[derive(Debug, Clone, PartialEq)]
pub struct LayerRow {
    /// Region name.
    pub region: String,
    /// The tip's depth in the undeformed tissue when it entered, m.
    pub entered_at: f64,
    /// Entered by puncturing a membrane (the tip was denting it the step before): the
    /// largest axial force from 0.05 s after the previous entry up to this one (the
    /// puncture peak), N, and the tip's depth in the undeformed tissue there, m (0 for the
    /// entry surface). `None` for an interface without a membrane.
    pub peak: Option<(f64, f64)>,
    /// The smallest axial force within 0.05 s after entering, N.
    pub after: f64,
    /// Slope of the axial force against the tissue depth while advancing in the region,
    /// from one node spacing past the entry to half a spacing before the next entry, N/m;
    /// `None` when that span is shorter than two spacings.
    pub slope: Option<f64>,
}

fn sim_of(text: &str, base: &Path) -> Result<Simulation, ReportError> {
    sim_for(text, base, None)
}

/// The scene `text` (paths relative to `base`) and its simulation started on the CPU
/// (all threads).
pub(crate) fn start_cpu(text: &str, base: &Path) -> Result<(Scene, Simulation), ReportError> {
    let scene = Scene::from_toml_str(text, base).map_err(SimulationError::from)?;
    let prep = Simulation::prepare(&scene)?;
    let b = CpuBackend::new(prep.tissue.clone(), Threading::Parallel)
        .map_err(needlesim::runner::RunError::from)?;
    let sim = prep.start(Box::new(b))?;
    Ok((scene, sim))
}

/// The scene run for its `run.steps`, or for `seconds` if fewer.
pub(crate) fn sim_for(
    text: &str,
    base: &Path,
    seconds: Option<f64>,
) -> Result<Simulation, ReportError> {
    let (scene, mut sim) = start_cpu(text, base)?;
    let all = scene
        .run
        .steps_at(sim.dt())
        .map_err(SimulationError::from)?;
    let steps = match seconds {
        Some(t) => all.min((t / sim.dt()).ceil() as u64),
        None => all,
    };
    sim.step_n(steps)?;
    Ok(sim)
}

/// How long a scene's needle advances: the summed durations of the `move` keyframes its
/// script opens with (0 when it opens with another action or has no needle).
fn insertion_seconds(text: &str, base: &Path) -> Result<f64, ReportError> {
    let scene = Scene::from_toml_str(text, base).map_err(SimulationError::from)?;
    let Some(table) = scene.needle.as_ref() else {
        return Ok(0.0);
    };
    let needle = NeedleConfig::from_table(table).map_err(SimulationError::from)?;
    Ok(needle
        .keyframe
        .iter()
        .map_while(|k| match k {
            Keyframe::Move { duration, .. } => Some(*duration),
            _ => None,
        })
        .sum())
}

/// The rows of [`LayerRow`] from a layered run's `history` (`names` the region names,
/// `dt` the step, `spacing` the node spacing, all m and s), over the samples up to time
/// `advancing_until` (the end of the insertion).
pub fn layer_rows(
    history: &[NeedleSample],
    names: &[String],
    dt: f64,
    spacing: f64,
    advancing_until: f64,
) -> Vec<LayerRow> {
    let h: Vec<&NeedleSample> = history
        .iter()
        .filter(|s| s.time <= advancing_until)
        .collect();
    // Where the tip entered each region (the first time only).
    let mut entries: Vec<(u16, usize)> = Vec::new();
    for (k, s) in h.iter().enumerate() {
        if let Some(r) = s.region {
            if !entries.iter().any(|e| e.0 == r) {
                entries.push((r, k));
            }
        }
    }
    let depth = |k: usize| h[k].tissue_depth.unwrap_or(0.0);
    let after = (0.05 / dt).round() as usize;
    let sp = spacing;
    let mut rows = Vec::new();
    for (i, &(r, at)) in entries.iter().enumerate() {
        let from = if i == 0 { 0 } else { entries[i - 1].1 + after };
        let punctured = at > 0 && h[at - 1].state == PunctureState::Touching;
        let peak = punctured.then(|| {
            let (k, f) = (from.min(at)..=at).map(|k| (k, h[k].force.axial)).fold(
                (at, f64::NEG_INFINITY),
                |a, b| if b.1 > a.1 { b } else { a },
            );
            (f, depth(k))
        });
        let low = h[at..(at + after).min(h.len())]
            .iter()
            .map(|s| s.force.axial)
            .fold(f64::INFINITY, f64::min);
        let entered_at = depth(at);
        let (lo, hi) = (
            entered_at + sp,
            entries.get(i + 1).map_or(
                h.iter().filter_map(|s| s.tissue_depth).fold(0.0, f64::max),
                |e| depth(e.1),
            ) - 0.5 * sp,
        );
        let (x, y): (Vec<f64>, Vec<f64>) = h[at..]
            .iter()
            .filter(|s| s.region == Some(r) && s.state == PunctureState::Inside)
            .filter_map(|s| {
                let d = s.tissue_depth.filter(|d| *d >= lo && *d <= hi)?;
                Some((d, s.force.axial))
            })
            .unzip();
        let slope = (hi - lo >= 2.0 * sp && x.len() > 10).then(|| line_fit(&x, &y).0);
        rows.push(LayerRow {
            region: names
                .get(r as usize)
                .cloned()
                .unwrap_or_else(|| r.to_string()),
            entered_at,
            peak,
            after: low,
            slope,
        });
    }
    rows
}

/// Slope (per unit x), R^2 and residual standard deviation of a least-squares line.
pub fn line_fit(x: &[f64], y: &[f64]) -> (f64, f64, f64) {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let b = sxy / sxx;
    let ssr: f64 = x
        .iter()
        .zip(y)
        .map(|(a, c)| (c - my - b * (a - mx)).powi(2))
        .sum();
    let sst: f64 = y.iter().map(|c| (c - my).powi(2)).sum();
    (b, 1.0 - ssr / sst, (ssr / n).sqrt())
}

/// Median absolute step-to-step change over the mean magnitude.
pub fn step_change(v: &[f64]) -> f64 {
    let mut d: Vec<f64> = v.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    d.sort_by(f64::total_cmp);
    let mean = v.iter().map(|x| x.abs()).sum::<f64>() / v.len() as f64;
    d[d.len() / 2] / mean.max(1e-300)
}

/// Share of the power of `v` (sampled every `dt` s, its linear trend removed) above `hz`.
pub fn power_above(v: &[f64], dt: f64, hz: f64) -> f64 {
    let n = v.len();
    let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let (b, _, _) = line_fit(&x, v);
    let my = v.iter().sum::<f64>() / n as f64;
    let r: Vec<f64> = (0..n)
        .map(|i| v[i] - my - b * (i as f64 - 0.5 * (n - 1) as f64))
        .collect();
    let (mut high, mut all) = (0.0, 0.0);
    for k in 1..=n / 2 {
        let (mut re, mut im) = (0.0, 0.0);
        for (i, y) in r.iter().enumerate() {
            let a = 2.0 * std::f64::consts::PI * (k * i) as f64 / n as f64;
            re += y * a.cos();
            im -= y * a.sin();
        }
        let p = re * re + im * im;
        all += p;
        if k as f64 / (n as f64 * dt) > hz {
            high += p;
        }
    }
    if all > 0.0 {
        high / all
    } else {
        0.0
    }
}

fn pick(h: &[NeedleSample], a: f64, b: f64, f: fn(&NeedleSample) -> f64) -> Vec<f64> {
    h.iter()
        .filter(|s| s.time > a && s.time <= b)
        .map(f)
        .collect()
}

/// Runs the needle section. `full`: the liver scene at its own 5 mm spacing and the slope
/// study at 648 and 4,913 nodes; otherwise the liver scene at 10 mm and the slope study
/// with the needle spacing halved only.
pub fn run_needle(full: bool, progress: &mut dyn FnMut(&str)) -> Result<NeedleReport, ReportError> {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let read = |name: &str| {
        std::fs::read_to_string(scenes.join(name)).map_err(|source| ReportError::Io {
            path: scenes.join(name).display().to_string(),
            source,
        })
    };
    let mut rep = NeedleReport::default();
    // The liver scene.
    let mut liver = read("liver_insertion.toml")?;
    if !full {
        liver = liver.replace("spacing = 0.005 }", "spacing = 0.01 }");
    }
    let sim = sim_of(&liver, &scenes)?;
    let h = sim.history();
    let peak = h
        .iter()
        .filter(|s| s.state == PunctureState::Touching)
        .map(|s| s.force.axial)
        .fold(f64::NAN, f64::max);
    let inside: Vec<&NeedleSample> = h
        .iter()
        .filter(|s| s.state == PunctureState::Inside && s.time <= 7.0)
        .collect();
    let inside = &inside[inside.len() / 10..];
    let depth: Vec<f64> = inside
        .iter()
        .map(|s| sim.depth_of(s.tip, s.direction))
        .collect();
    let force: Vec<f64> = inside.iter().map(|s| s.force.axial).collect();
    let (slope, r2, sd) = line_fit(&depth, &force);
    let mean = force.iter().sum::<f64>() / force.len() as f64;
    let nodes = sim.editor().n_mesh();
    progress(&format!(
        "needle       liver {nodes} nodes: peak {peak:.3} N, slope {slope:.1} N/m (R^2 {r2:.3}, residual {:.1}%)",
        100.0 * sd / mean
    ));
    rep.liver = Some((nodes, peak, slope, r2, sd / mean));
    rep.curve = h
        .iter()
        .map(|s| (1e3 * sim.depth_of(s.tip, s.direction), s.force.axial))
        .collect();
    // Smoothness per model on the paper's experiment.
    for m in ["msm", "lshm", "deb", "pba"] {
        let sim = sim_of(&read(&format!("paper_insertion_{m}.toml"))?, &scenes)?;
        let h = sim.history();
        let axial: fn(&NeedleSample) -> f64 = |s| s.force.axial;
        let lateral: fn(&NeedleSample) -> f64 = |s| s.force.lateral;
        let rot = [axial, lateral].map(|f| 100.0 * step_change(&pick(h, 3.0, 4.0, f)));
        let pause = [axial, lateral].map(|f| 100.0 * step_change(&pick(h, 4.0, 4.5, f)));
        let hf =
            [axial, lateral].map(|f| 100.0 * power_above(&pick(h, 3.0, 4.0, f), sim.dt(), 50.0));
        progress(&format!(
            "needle       {m:<5} step change rotation {:.3}/{:.3}%, pause {:.3}/{:.3}%, power above 50 Hz {:.4}/{:.4}% (axial/lateral)",
            rot[0], rot[1], pause[0], pause[1], hf[0], hf[1]
        ));
        rep.smoothness.push((m.to_string(), rot, pause, hf));
    }
    // Slope against resolution, the grip given so that the tissue's modulus (and with it
    // the derived grip) does not change with the lattice.
    let base = read("needle_insert_extract.toml")?.replace(
        "friction = { coefficient = 0.3 }",
        "friction = { coefficient = 0.3, grip = 20.0 }",
    );
    let mut variants = vec![
        (base.clone(), 0.0),
        (
            base.replace("length = 0.1\n", "length = 0.1\nspacing = 0.0058\n"),
            0.0058,
        ),
    ];
    if full {
        variants.push((base.replace("nodes = 639", "nodes = 4913"), 0.0));
    }
    for (text, spacing) in variants {
        let text = text.replace("steps = 5000", "steps = 2000");
        let sim = sim_of(&text, &scenes)?;
        let rows: Vec<&NeedleSample> = sim
            .history()
            .iter()
            .filter(|s| s.state == PunctureState::Inside)
            .collect();
        let rows = &rows[rows.len() / 10..];
        let d: Vec<f64> = rows
            .iter()
            .map(|s| sim.depth_of(s.tip, s.direction))
            .collect();
        let f: Vec<f64> = rows.iter().map(|s| s.force.axial).collect();
        let (slope, _, _) = line_fit(&d, &f);
        let spacing = if spacing > 0.0 {
            spacing
        } else {
            sim.spacing()
        };
        progress(&format!(
            "needle       slope {slope:.3} N/m at {} nodes, needle spacing {spacing:.4} m",
            sim.editor().n_mesh()
        ));
        rep.slopes.push((sim.editor().n_mesh(), spacing, slope));
    }
    // The layered scene: insertion and hold (the whole run with extraction when full).
    let layered = read("layered_liver_biopsy.toml")?;
    let insertion = insertion_seconds(&layered, &scenes)?;
    let sim = sim_for(&layered, &scenes, (!full).then_some(insertion + 0.5))?;
    rep.layers = layer_rows(
        sim.history(),
        sim.region_names(),
        sim.dt(),
        sim.spacing(),
        insertion,
    );
    rep.layers_seconds = sim.time();
    for l in &rep.layers {
        progress(&format!(
            "needle       layered: {} entered at {:.2} mm, {}, {:.3} N 0.05 s later, slope {}",
            l.region,
            1e3 * l.entered_at,
            l.peak.map_or("no membrane".into(), |(f, d)| format!(
                "peak {f:.3} N at {:.2} mm",
                1e3 * d
            )),
            l.after,
            l.slope.map_or("-".into(), |s| format!("{s:.1} N/m"))
        ));
    }
    Ok(rep)
}

/// Writes `needle.csv` and `needle_force_liver.png` into `out`.
pub fn write_needle(out: &Path, r: &NeedleReport) -> std::io::Result<()> {
    let mut csv = String::from("quantity,model,nodes,value\n");
    if let Some((n, peak, slope, r2, res)) = r.liver {
        writeln!(csv, "liver_peak_n,deb,{n},{peak:e}").unwrap();
        writeln!(csv, "liver_slope_n_per_m,deb,{n},{slope:e}").unwrap();
        writeln!(csv, "liver_r2,deb,{n},{r2:e}").unwrap();
        writeln!(csv, "liver_residual_fraction,deb,{n},{res:e}").unwrap();
    }
    for (m, rot, pause, hf) in &r.smoothness {
        for (i, axis) in ["axial", "lateral"].iter().enumerate() {
            writeln!(csv, "rotation_step_change_percent_{axis},{m},,{:e}", rot[i]).unwrap();
            writeln!(csv, "pause_step_change_percent_{axis},{m},,{:e}", pause[i]).unwrap();
            writeln!(
                csv,
                "rotation_power_above_50hz_percent_{axis},{m},,{:e}",
                hf[i]
            )
            .unwrap();
        }
    }
    for (n, h, s) in &r.slopes {
        writeln!(
            csv,
            "slope_n_per_m_needle_spacing_{h:.4},lshm-cluster,{n},{s:e}"
        )
        .unwrap();
    }
    for l in &r.layers {
        let g = &l.region;
        writeln!(csv, "layer_entered_at_m,{g},,{:e}", l.entered_at).unwrap();
        if let Some((f, d)) = l.peak {
            writeln!(csv, "layer_peak_n,{g},,{f:e}").unwrap();
            writeln!(csv, "layer_peak_at_m,{g},,{d:e}").unwrap();
        }
        writeln!(csv, "layer_force_after_n,{g},,{:e}", l.after).unwrap();
        if let Some(s) = l.slope {
            writeln!(csv, "layer_slope_n_per_m,{g},,{s:e}").unwrap();
        }
    }
    std::fs::write(out.join("needle.csv"), csv)?;
    // Force against depth with the band: the peak band at the puncture depth, the slope
    // band through the force where the slope fit starts.
    let punct = r
        .curve
        .iter()
        .zip(r.curve.iter().skip(1))
        .find(|(a, b)| b.1 < a.1 - 0.2)
        .map_or(0.0, |(a, _)| a.0);
    let end = r.curve.iter().map(|p| p.0).fold(0.0, f64::max);
    let start = r
        .curve
        .iter()
        .find(|p| p.0 > punct + 0.1 * (end - punct))
        .map_or(0.0, |p| p.1);
    let x0 = punct + 0.1 * (end - punct);
    let band =
        |s: f64| -> Vec<(f64, f64)> { vec![(x0, start), (end, start + s * (end - x0) * 1e-3)] };
    line_plot(
        &out.join("needle_force_liver.png"),
        &Labels {
            title: "liver scene: needle force against depth, published band",
            x: "tip depth past first contact (mm)",
            y: "axial force (N)",
        },
        &[
            Series {
                label: "needlesim",
                colour: [200, 40, 40],
                points: r.curve.clone(),
            },
            Series {
                label: "slope 35 N/m",
                colour: [120, 120, 120],
                points: band(SLOPE_BAND.0),
            },
            Series {
                label: "slope 59 N/m",
                colour: [60, 60, 60],
                points: band(SLOPE_BAND.1),
            },
            Series {
                label: "peak 1-3 N",
                colour: [40, 90, 200],
                points: vec![(punct, PEAK_BAND.0), (punct, PEAK_BAND.1)],
            },
        ],
    )
}

/// The report's markdown section.
pub fn markdown(md: &mut String, r: &NeedleReport) {
    writeln!(md, "## Needle force\n").unwrap();
    if let Some((n, peak, slope, r2, res)) = r.liver {
        let inside = |v: f64, b: (f64, f64)| {
            if v >= b.0 && v <= b.1 {
                "inside"
            } else {
                "OUTSIDE"
            }
        };
        writeln!(md, "Liver scene (`scenes/liver_insertion.toml`, {n} nodes, 18 G needle at 5 mm/s): puncture peak {peak:.2} N ({} the published 1-3 N), slope after puncture {slope:.1} N/m ({} the published 35-59 N/m), straight line R^2 {r2:.3}, residual {:.1}% of the mean force.\n", inside(peak, PEAK_BAND), inside(slope, SLOPE_BAND), 100.0 * res).unwrap();
        writeln!(md, "![liver](needle_force_liver.png)\n").unwrap();
    }
    writeln!(md, "Smoothness on the paper's experiment (25-degree rotation 3-4 s, pause 4-4.5 s): median step-to-step change as % of the mean force, and the share of the rotation's (detrended) force power above 50 Hz.\n").unwrap();
    writeln!(md, "| model | rotation axial | rotation lateral | pause axial | pause lateral | >50 Hz axial | >50 Hz lateral |").unwrap();
    writeln!(md, "|---|---:|---:|---:|---:|---:|---:|").unwrap();
    for (m, rot, pause, hf) in &r.smoothness {
        writeln!(
            md,
            "| {m} | {:.3}% | {:.3}% | {:.3}% | {:.3}% | {:.4}% | {:.4}% |",
            rot[0], rot[1], pause[0], pause[1], hf[0], hf[1]
        )
        .unwrap();
    }
    writeln!(md, "\nForce-depth slope by resolution (insert-extract scene, grip 20 N/m given, coefficient 0.3: friction 6 N/m plus the tissue ahead of the tip):\n").unwrap();
    writeln!(
        md,
        "| tissue nodes | needle node spacing (m) | slope (N/m) |"
    )
    .unwrap();
    writeln!(md, "|---:|---:|---:|").unwrap();
    for (n, h, s) in &r.slopes {
        writeln!(md, "| {n} | {h:.4} | {s:.3} |").unwrap();
    }
    writeln!(md).unwrap();
    if !r.layers.is_empty() {
        writeln!(
            md,
            "### Layered tissue
"
        )
        .unwrap();
        writeln!(md, "`scenes/layered_liver_biopsy.toml` ({:.1} s simulated): skin 0-4.5 mm, fat to 25.5 mm, muscle to 37.5 mm, liver beyond (as the scene states); membranes at the entry surface, the fascia over the muscle and the liver capsule. Depths are the tip's in the undeformed tissue; a membrane's peak should lie within one node spacing (3 mm) of its rest depth. Slope: axial force against tissue depth while advancing in the layer.\n", r.layers_seconds).unwrap();
        writeln!(md, "| region entered | entered at (mm) | membrane peak (N) | peak at (mm) | 0.05 s after (N) | slope in layer (N/m) |").unwrap();
        writeln!(md, "|---|---:|---:|---:|---:|---:|").unwrap();
        for l in &r.layers {
            writeln!(
                md,
                "| {} | {:.2} | {} | {:.3} | {} |",
                l.region,
                1e3 * l.entered_at,
                l.peak.map_or("none | -".into(), |(f, d)| format!(
                    "{f:.3} | {:.2}",
                    1e3 * d
                )),
                l.after,
                l.slope.map_or("-".into(), |s| format!("{s:.1}"))
            )
            .unwrap();
        }
        writeln!(md).unwrap();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use needlesim_needle::NeedleForce;

    /// A synthetic record at 1 ms steps: the tip dents the entry surface (force rising to
    /// 1.98 N), enters `a` (drop to 0.1 N, then 10 N/m against depth), crosses into `b` at
    /// 8 mm without a membrane (30 N/m), dents `c`'s membrane from 15 to 16 mm (force
    /// rising to 1.4 N) and enters `c` (10 N/m).
    fn record() -> Vec<NeedleSample> {
        let mut h = Vec::new();
        let sample = |k: usize, state, region, depth: Option<f64>, f: f64| NeedleSample {
            step: k as u64,
            time: k as f64 * 1e-3,
            tip: [0.0; 3],
            direction: [1.0, 0.0, 0.0],
            force: NeedleForce {
                axial: f,
                ..Default::default()
            },
            state,
            active_nodes: 0,
            needle_nodes: 0,
            region,
            tissue_depth: depth,
        };
        let mut k = 0;
        for i in 0..100 {
            h.push(sample(
                k,
                PunctureState::Touching,
                None,
                Some(0.0),
                0.02 * i as f64,
            ));
            k += 1;
        }
        let mut d = 0.0;
        while d < 0.024 {
            let (region, f) = match d {
                d if d < 0.008 => (0, 0.1 + 10.0 * d),
                d if d < 0.016 => (1, 0.18 + 30.0 * (d - 0.008)),
                // Denting `c`'s membrane from 15 to 16 mm, then inside.
                _ => (2, 0.2 + 10.0 * (d - 0.016)),
            };
            let denting = (0.015..0.016).contains(&d);
            let (state, r, f) = match denting {
                true => (PunctureState::Touching, Some(1), 0.4 + 1000.0 * (d - 0.015)),
                false => (PunctureState::Inside, Some(region), f),
            };
            h.push(sample(k, state, r, Some(d), f));
            k += 1;
            d += 1e-5;
        }
        h
    }

    #[test]
    fn layer_rows_find_each_puncture_and_slope() {
        let names = ["a", "b", "c"].map(String::from);
        let rows = layer_rows(&record(), &names, 1e-3, 1e-3, f64::INFINITY);
        let regions: Vec<&str> = rows.iter().map(|r| r.region.as_str()).collect();
        assert_eq!(regions, ["a", "b", "c"]);
        // The entry: peak 1.98 N at depth 0; the drop to 0.1 N.
        let (f, d) = rows[0].peak.unwrap();
        assert!((f - 1.98).abs() < 1e-9 && d == 0.0, "{f} {d}");
        assert!((rows[0].after - 0.1).abs() < 1e-6);
        // No membrane between `a` and `b`.
        assert_eq!(rows[1].peak, None);
        // `c`'s membrane: the peak just before 16 mm, about 1.4 N.
        let (f, d) = rows[2].peak.unwrap();
        assert!(
            (f - 1.4).abs() < 0.02 && (d - 0.016).abs() < 2e-5,
            "{f} {d}"
        );
        // Slopes: each layer's, fitted from a spacing past its entry (exact: the record
        // is linear there).
        let slopes: Vec<f64> = rows.iter().map(|r| r.slope.unwrap()).collect();
        for (s, want) in slopes.iter().zip([10.0, 30.0, 10.0]) {
            assert!((s - want).abs() < 1e-6 * want, "{slopes:?}");
        }
    }

    #[test]
    fn the_insertion_lasts_as_long_as_the_opening_moves() {
        let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
        let text = std::fs::read_to_string(scenes.join("layered_liver_biopsy.toml")).unwrap();
        let moves = |t: &str| insertion_seconds(t, &scenes).unwrap();
        assert_eq!(moves(&text), 6.0);
        // Two opening moves add up; a pause first means no insertion.
        let split = text.replace(
            "duration = 6.0\n",
            "duration = 2.5\n\n[[needle.keyframe]]\naction = \"move\"\ndirection = [1.0, 0.0, 0.0]\nspeed = 0.02\nduration = 1.25\n",
        );
        assert_eq!(moves(&split), 3.75);
        let paused = text
            .replacen("action = \"move\"", "action = \"pause\"", 1)
            .replacen(
                "direction = [1.0, 0.0, 0.0]\nspeed = 0.01\nduration = 6.0",
                "duration = 6.0",
                1,
            );
        assert_eq!(moves(&paused), 0.0);
    }
}
