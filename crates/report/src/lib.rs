//! # needlesim-report
//!
//! The accuracy and stability report of [`needlesim`] (`needlesim report`):
//! reference cases with known answers run per model, resolution, time step and backend
//! ([`cases`]), the stable time step map ([`stable_dt`](mod@stable_dt)) and the extreme cases
//! ([`extreme`]). Writes `accuracy.csv`, `timing.csv`, `stable_dt.csv`, `extreme.csv`,
//! `work_precision_<case>.png`, `error_vs_nodes.png`, `stable_dt.png` and `report.md` into
//! one directory.
//!
//! It also holds the PNG line plots ([`plot`](mod@plot), drawn with `plotters` and an embedded
//! DejaVu Sans font) and the needle force plots of a run ([`needle_plots`]), which the
//! `needlesim` command line tool draws from the `needle_force.csv` a run writes. None of
//! this is part of the `needlesim` library, so that it and the Python module stay free of
//! the plotting dependencies.

#![warn(missing_docs)]

pub mod cases;
pub mod constants;
pub mod effective;
pub mod error;
pub mod extreme;
pub mod fem;
pub mod needle;
pub mod needle_plots;
pub mod plot;
pub mod realism;
pub mod stable_dt;

use crate::plot::{plot, Axes, Labels, Series};
use cases::{run_case, CaseId, CaseResult, ModelId, RunSpec};
pub use error::ReportError;
use extreme::{run_extreme, ExtremeCase, ExtremeResult, ExtremeSize, Outcome};
use needlesim_core::scene::BackendChoice;
use stable_dt::{stable_dt, StableDt};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How much to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReportSize {
    /// Two coarse resolutions, short bisections, few cycles: a few minutes; what the test
    /// command runs.
    Reduced,
    /// Cube cases from 125 to 15,625 nodes, beam cases from 496 to 12,221, 1000
    /// insert/extract cycles (about 16 min on 2 cores).
    Full,
}

/// What the report runs and where it writes.
#[derive(Debug, Clone)]
pub struct ReportOptions {
    /// Output directory (created).
    pub out: PathBuf,
    /// Size.
    pub size: ReportSize,
    /// Backends whose time per step is measured for every case run (the accuracy runs
    /// themselves use all CPU threads).
    pub timing_backends: Vec<BackendChoice>,
    /// Whether to run the needle force realism section (about 24 min of the full size on
    /// 2 cores); without it report.md points to `needlesim report --realism`, which runs
    /// that section alone.
    pub realism: bool,
}

/// Seconds per step of one case run on one backend.
#[derive(Debug, Clone)]
pub struct Timing {
    /// Index into [`ReportSummary::accuracy`].
    pub run: usize,
    /// Backend name.
    pub backend: String,
    /// Seconds per step (mean of a short run after one warm-up step).
    pub seconds_per_step: f64,
}

/// Everything the report measured.
#[derive(Debug, Clone)]
pub struct ReportSummary {
    /// Reference case runs.
    pub accuracy: Vec<CaseResult>,
    /// Time per step per backend.
    pub timing: Vec<Timing>,
    /// Stable step map.
    pub stable: Vec<StableDt>,
    /// Extreme cases.
    pub extreme: Vec<ExtremeResult>,
    /// The needle section.
    pub needle: needle::NeedleReport,
    /// The needle force realism section, unless [`ReportOptions::realism`] left it out.
    pub realism: Option<realism::Realism>,
    /// The elastic constants each model shows.
    pub effective: Vec<effective::Effective>,
    /// Wall time of the whole report.
    pub elapsed: Duration,
}

struct Plan {
    /// Resolution levels of the cube cases (stretch, indentation).
    levels: Vec<usize>,
    /// Resolution levels of the beam cases (cantilever, frequency).
    beam_levels: Vec<usize>,
    static_fraction: f64,
    frequency_fractions: Vec<f64>,
    stable_side: usize,
    stable_scales: Vec<f64>,
    stable_steps: u64,
    stable_iterations: usize,
    extreme: ExtremeSize,
    timing_steps: u64,
}

fn plan(size: ReportSize) -> Plan {
    match size {
        ReportSize::Reduced => Plan {
            levels: vec![0, 1],
            beam_levels: vec![0, 1],
            static_fraction: 0.5,
            frequency_fractions: vec![0.8, 0.4],
            stable_side: 5,
            stable_scales: vec![1.0, 1000.0],
            stable_steps: 400,
            stable_iterations: 4,
            extreme: ExtremeSize {
                cube_side: 5,
                needle_spacing: 0.05,
                cycles: 5,
            },
            timing_steps: 10,
        },
        ReportSize::Full => Plan {
            levels: vec![0, 1, 2, 3, 4, 5],
            beam_levels: vec![1, 2, 3, 4, 5],
            static_fraction: 0.5,
            frequency_fractions: vec![0.8, 0.3],
            stable_side: 7,
            stable_scales: vec![1.0, 10.0, 100.0, 1000.0],
            stable_steps: 3000,
            stable_iterations: 7,
            extreme: ExtremeSize {
                cube_side: 7,
                needle_spacing: 0.025,
                cycles: 1000,
            },
            timing_steps: 50,
        },
    }
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> ReportError + '_ {
    move |source| ReportError::Io {
        path: path.display().to_string(),
        source,
    }
}

/// Seconds per step of the case's tissue on `backend` (the case's initial state, no
/// constraints), or None when the backend is unavailable.
fn time_per_step(case: CaseId, model: ModelId, spec: &RunSpec, steps: u64) -> Option<f64> {
    let mut b = cases::case_backend(case, model, spec).ok()?;
    b.step(1);
    b.finish();
    let t = Instant::now();
    b.step(steps);
    b.finish();
    Some(t.elapsed().as_secs_f64() / steps as f64)
}

/// Runs the report and writes its files; `progress` gets one line per finished run.
pub fn run_report(
    options: &ReportOptions,
    mut progress: impl FnMut(&str),
) -> Result<ReportSummary, ReportError> {
    let start = Instant::now();
    let p = plan(options.size);
    std::fs::create_dir_all(&options.out).map_err(io(&options.out))?;
    let mut accuracy = Vec::new();
    let mut timing = Vec::new();
    for case in CaseId::ALL {
        let fractions = if case == CaseId::Frequency {
            p.frequency_fractions.clone()
        } else {
            vec![p.static_fraction]
        };
        for model in ModelId::ALL {
            let levels = match case {
                CaseId::Cantilever | CaseId::Frequency => &p.beam_levels,
                _ => &p.levels,
            };
            for &level in levels {
                for &dt_fraction in &fractions {
                    let spec = RunSpec {
                        level,
                        dt_fraction,
                        backend: BackendChoice::CpuParallel,
                    };
                    let r = run_case(case, model, &spec)?;
                    progress(&format!(
                        "{:<12} {:<14} {:>6} nodes dt {:.2e} s ({:.1}x crit): error {:>7.3}%  {} steps {:.2} s{}",
                        case.label(),
                        model.label(),
                        r.nodes,
                        r.dt,
                        dt_fraction,
                        100.0 * r.error,
                        r.steps,
                        r.wall.as_secs_f64(),
                        if r.converged { "" } else { "  (not converged)" }
                    ));
                    let run = accuracy.len();
                    accuracy.push(r);
                    if dt_fraction == fractions[0] {
                        for &choice in &options.timing_backends {
                            let spec = RunSpec {
                                backend: choice,
                                ..spec
                            };
                            if let Some(s) = time_per_step(case, model, &spec, p.timing_steps) {
                                timing.push(Timing {
                                    run,
                                    backend: backend_label(choice).into(),
                                    seconds_per_step: s,
                                });
                            }
                        }
                    }
                }
            }
        }
    }
    let mut stable = Vec::new();
    for model in ModelId::ALL {
        for &scale in &p.stable_scales {
            let s = stable_dt(
                model,
                scale,
                p.stable_side,
                p.stable_steps,
                p.stable_iterations,
            )?;
            progress(&format!(
                "stable dt    {:<14} stiffness x{:<6} estimate {:.3e} s, bisection {:.3e} s ({:.2}x)",
                model.label(),
                scale,
                s.estimate,
                s.measured,
                s.measured / s.estimate
            ));
            stable.push(s);
        }
    }
    let mut extreme = Vec::new();
    for case in ExtremeCase::ALL {
        for model in ModelId::ALL {
            let r = run_extreme(case, model, &p.extreme)?;
            progress(&format!(
                "extreme      {:<14} {:<32} {}: {}{}",
                model.label(),
                case.label(),
                r.outcome.word(),
                r.detail,
                match &r.outcome {
                    Outcome::Diverged(m) | Outcome::Failed(m) => format!(" ({m})"),
                    _ => String::new(),
                }
            ));
            extreme.push(r);
        }
    }
    let needle = needle::run_needle(options.size == ReportSize::Full, &mut progress)?;
    let realism = if options.realism {
        Some(realism::run_realism(
            options.size == ReportSize::Full,
            &mut progress,
        )?)
    } else {
        None
    };
    let effective = effective::run(13)?;
    for r in &effective {
        progress(&format!(
            "effective    {:<14} E {:.2} kPa, nu {:.3}, anisotropy {:.3}",
            r.model.label(),
            r.young / 1e3,
            r.poisson,
            r.anisotropy
        ));
    }
    let summary = ReportSummary {
        accuracy,
        timing,
        stable,
        extreme,
        needle,
        realism,
        effective,
        elapsed: start.elapsed(),
    };
    write_all(options, &summary)?;
    Ok(summary)
}

fn backend_label(choice: BackendChoice) -> &'static str {
    match choice {
        BackendChoice::Cpu => "cpu",
        BackendChoice::CpuParallel => "cpu-parallel",
        BackendChoice::Gpu => "gpu",
        BackendChoice::Auto => "auto",
    }
}

fn write(path: &Path, text: &str) -> Result<(), ReportError> {
    std::fs::write(path, text).map_err(io(path))
}

fn write_all(options: &ReportOptions, s: &ReportSummary) -> Result<(), ReportError> {
    let out = &options.out;
    let mut csv = String::from(
        "case,model,nodes,spacing_m,dt_s,dt_fraction,steps,wall_s,measured,reference,error,secondary_error,converged\n",
    );
    for r in &s.accuracy {
        writeln!(
            csv,
            "{},{},{},{:e},{:e},{},{},{:.4},{:e},{:e},{:e},{:e},{}",
            r.case.label(),
            r.model.label(),
            r.nodes,
            r.spacing,
            r.dt,
            r.dt_fraction,
            r.steps,
            r.wall.as_secs_f64(),
            r.measured,
            r.reference,
            r.error,
            r.secondary,
            r.converged
        )
        .unwrap();
    }
    write(&out.join("accuracy.csv"), &csv)?;
    let mut csv =
        String::from("case,model,nodes,steps,backend,seconds_per_step,projected_wall_s\n");
    for t in &s.timing {
        let r = &s.accuracy[t.run];
        writeln!(
            csv,
            "{},{},{},{},{},{:e},{:.4}",
            r.case.label(),
            r.model.label(),
            r.nodes,
            r.steps,
            t.backend,
            t.seconds_per_step,
            t.seconds_per_step * r.steps as f64
        )
        .unwrap();
    }
    write(&out.join("timing.csv"), &csv)?;
    let mut csv =
        String::from("model,stiffness_scale,nodes,estimate_s,bisection_s,ratio,bracket\n");
    for r in &s.stable {
        writeln!(
            csv,
            "{},{},{},{:e},{:e},{:.3},{:.3}",
            r.model.label(),
            r.stiffness_scale,
            r.nodes,
            r.estimate,
            r.measured,
            r.measured / r.estimate,
            r.bracket
        )
        .unwrap();
    }
    write(&out.join("stable_dt.csv"), &csv)?;
    let mut csv = String::from("case,model,outcome,steps,detail\n");
    for r in &s.extreme {
        let msg = match &r.outcome {
            Outcome::Diverged(m) | Outcome::Failed(m) => format!("{} {m}", r.detail),
            _ => r.detail.clone(),
        };
        writeln!(
            csv,
            "\"{}\",{},{},{},\"{}\"",
            r.case.label(),
            r.model.label(),
            r.outcome.word(),
            r.steps,
            msg.trim().replace('"', "'")
        )
        .unwrap();
    }
    write(&out.join("extreme.csv"), &csv)?;
    write(&out.join("effective.csv"), &effective::csv(&s.effective))?;
    plots(out, s)?;
    needle::write_needle(out, &s.needle).map_err(io(out))?;
    if let Some(r) = &s.realism {
        realism::write_realism(out, r).map_err(io(out))?;
    }
    write(&out.join("report.md"), &markdown(options, s))
}

/// A log-log plot with point markers.
fn log_plot(
    path: &Path,
    title: &str,
    x: &str,
    y: &str,
    series: &[Series],
) -> Result<(), ReportError> {
    let axes = Axes {
        log_x: true,
        log_y: true,
        markers: true,
    };
    plot(path, &Labels { title, x, y }, axes, series).map_err(io(path))
}

fn plots(out: &Path, s: &ReportSummary) -> Result<(), ReportError> {
    for case in CaseId::ALL {
        let path = out.join(format!("work_precision_{}.png", case.label()));
        let series: Vec<Series> = ModelId::ALL
            .iter()
            .map(|&m| {
                let mut pts: Vec<(f64, f64)> = s
                    .accuracy
                    .iter()
                    .filter(|r| r.case == case && r.model == m)
                    .map(|r| (r.wall.as_secs_f64(), r.error))
                    .collect();
                pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                Series {
                    label: m.label(),
                    colour: m.colour(),
                    points: pts,
                }
            })
            .collect();
        let title = format!("{}: {}", case.label(), case.error_meaning());
        log_plot(
            &path,
            &title,
            "wall time of the run, s (all CPU threads)",
            "relative error",
            &series,
        )?;
    }
    let path = out.join("error_vs_nodes.png");
    let mut series = Vec::new();
    for &m in &ModelId::ALL {
        for (case, dash) in [(CaseId::Cantilever, 0u8), (CaseId::Indentation, 1)] {
            let mut pts: Vec<(f64, f64)> = s
                .accuracy
                .iter()
                .filter(|r| r.case == case && r.model == m)
                .map(|r| (r.nodes as f64, r.error))
                .collect();
            pts.sort_by(|a, b| a.0.total_cmp(&b.0));
            let c = m.colour();
            series.push(Series {
                label: if dash == 0 { m.label() } else { "" },
                colour: if dash == 0 {
                    c
                } else {
                    c.map(|v| ((v as u16 + 255) / 2) as u8)
                },
                points: pts,
            });
        }
    }
    series.retain(|s| !s.points.is_empty());
    log_plot(
        &path,
        "error against nodes: cantilever (dark), indentation (light)",
        "nodes",
        "relative error",
        &series,
    )?;
    let path = out.join("stable_dt.png");
    let mut series = Vec::new();
    for &m in &ModelId::ALL {
        let pts = |f: &dyn Fn(&StableDt) -> f64| -> Vec<(f64, f64)> {
            s.stable
                .iter()
                .filter(|r| r.model == m)
                .map(|r| (r.stiffness_scale, f(r)))
                .collect()
        };
        series.push(Series {
            label: m.label(),
            colour: m.colour(),
            points: pts(&|r| r.measured),
        });
        let c = m.colour();
        series.push(Series {
            label: "",
            colour: c.map(|v| ((v as u16 + 255) / 2) as u8),
            points: pts(&|r| r.estimate),
        });
    }
    log_plot(
        &path,
        "largest stable dt: bisection (dark), estimate (light)",
        "stiffness / default",
        "dt, s",
        &series,
    )
}

/// The runs of `model` in `case` from coarsest to finest (frequency: at the smallest step
/// fraction run).
pub fn runs_by_resolution(s: &ReportSummary, case: CaseId, model: ModelId) -> Vec<&CaseResult> {
    let runs: Vec<&CaseResult> = s
        .accuracy
        .iter()
        .filter(|r| r.case == case && r.model == model)
        .collect();
    let fraction = runs
        .iter()
        .map(|r| r.dt_fraction)
        .fold(f64::INFINITY, f64::min);
    let mut runs: Vec<&CaseResult> = runs
        .into_iter()
        .filter(|r| r.dt_fraction == fraction)
        .collect();
    runs.sort_by_key(|r| r.nodes);
    runs
}

fn convergence_table(md: &mut String, s: &ReportSummary) {
    writeln!(md, "## Does the error fall with resolution?\n").unwrap();
    writeln!(
        md,
        "Errors from the coarsest to the finest resolution (frequency: at the smaller step fraction). \
         `falls`: every run settled and each error is below the one before, or both are below the reference's own accuracy \
         (stretch {:.1}%, other cases {:.0}%; `CaseId::reference_accuracy`).\n",
        100.0 * CaseId::Stretch.reference_accuracy(),
        100.0 * CaseId::Indentation.reference_accuracy()
    )
    .unwrap();
    writeln!(md, "| case | model | errors, % | falls |").unwrap();
    writeln!(md, "|---|---|---|:---:|").unwrap();
    for case in CaseId::ALL {
        for model in ModelId::ALL {
            let runs = runs_by_resolution(s, case, model);
            if runs.is_empty() {
                continue;
            }
            // A run that did not settle has no error to compare: it never counts as falling.
            let e: Vec<f64> = runs
                .iter()
                .map(|r| if r.converged { r.error } else { f64::NAN })
                .collect();
            let list: Vec<String> = runs
                .iter()
                .map(|r| match (r.error.is_finite(), r.converged) {
                    (true, true) => format!("{:.2}", 100.0 * r.error),
                    (true, false) => format!("{:.2} (not settled)", 100.0 * r.error),
                    _ => "n/a".into(),
                })
                .collect();
            writeln!(
                md,
                "| {} | {} | {} | {} |",
                case.label(),
                model.label(),
                list.join(", "),
                if case.error_falls(&e) { "yes" } else { "no" }
            )
            .unwrap();
        }
    }
    writeln!(md).unwrap();
}

fn markdown(options: &ReportOptions, s: &ReportSummary) -> String {
    let mut md = String::new();
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1);
    writeln!(md, "# needlesim accuracy and stability report\n").unwrap();
    let cal = needlesim_core::calibration::calibration(cases::NEIGHBOURS)
        .expect("the report's K is calibrated");
    writeln!(
        md,
        "Size: {:?}. Run time {:.0} s on this machine ({threads} CPU threads). Produced by `needlesim report{}`.\n",
        options.size,
        s.elapsed.as_secs_f64(),
        if options.size == ReportSize::Full { " --full" } else { "" }
    )
    .unwrap();
    writeln!(
        md,
        "Material of every reference case: E = {} Pa, nu = {}, rho = {} kg/m^3. Mass-spring and shape matching \
         take their stiffness from E by `k = C E h` (`needlesim_core::calibration`, K = {}: C = {} msm, {} lshm-node, {} lshm-cluster). \
         Every case uses K = {} neighbours.\n",
        cases::YOUNG,
        cases::POISSON,
        cases::DENSITY,
        cal.neighbours,
        cal.mass_spring,
        cal.shape_matching_node,
        cal.shape_matching_cluster,
        cases::NEIGHBOURS
    )
    .unwrap();
    writeln!(
        md,
        "C implied by the stretch case at each resolution (`C * E eps / stress`; the shipped C \
         is its limit for h -> 0, extrapolated from 21^3 and 25^3 nodes):\n"
    )
    .unwrap();
    writeln!(md, "| model | nodes | implied C |").unwrap();
    writeln!(md, "|---|---:|---:|").unwrap();
    for r in s.accuracy.iter().filter(|r| r.case == CaseId::Stretch) {
        let c = match r.model {
            ModelId::Msm => cal.mass_spring,
            ModelId::LshmNode => cal.shape_matching_node,
            ModelId::LshmCluster => cal.shape_matching_cluster,
            _ => continue,
        };
        writeln!(
            md,
            "| {} | {} | {:.4} |",
            r.model.label(),
            r.nodes,
            c * r.reference / r.measured
        )
        .unwrap();
    }
    writeln!(md).unwrap();
    convergence_table(&mut md, s);
    writeln!(md, "## Error against resolution\n").unwrap();
    writeln!(
        md,
        "Relative error of each case's main quantity (static cases at 0.5 x the estimated critical step, \
         relaxed until the quantity changes by less than 1e-3 over 1/omega_slow; frequency at every step \
         fraction listed; n/a: no oscillation found, the paper's shape matching forces need damping that \
         overdamps the beam). Secondary errors: cantilever vs Euler-Bernoulli, frequency vs Euler-Bernoulli, stretch lateral strain vs nu, \
         indentation displacement field (rms over the punch depth).\n"
    )
    .unwrap();
    for case in CaseId::ALL {
        writeln!(md, "### {} ({})\n", case.label(), case.error_meaning()).unwrap();
        writeln!(
            md,
            "| model | nodes | dt, s | steps | wall, s | error | secondary | converged |"
        )
        .unwrap();
        writeln!(md, "|---|---:|---:|---:|---:|---:|---:|:---:|").unwrap();
        for r in s.accuracy.iter().filter(|r| r.case == case) {
            writeln!(
                md,
                "| {} | {} | {:.2e} | {} | {:.2} | {} | {} | {} |",
                r.model.label(),
                r.nodes,
                r.dt,
                r.steps,
                r.wall.as_secs_f64(),
                if r.error.is_finite() {
                    format!("{:.2}%", 100.0 * r.error)
                } else {
                    "n/a".into()
                },
                if r.secondary.is_finite() {
                    format!("{:.2}%", 100.0 * r.secondary)
                } else {
                    "-".into()
                },
                if r.converged { "yes" } else { "no" }
            )
            .unwrap();
        }
        writeln!(md, "\n![{0}](work_precision_{0}.png)\n", case.label()).unwrap();
    }
    if !s.timing.is_empty() {
        writeln!(md, "## Time per step by backend\n").unwrap();
        writeln!(md, "Mean over a short run of each case's tissue (`timing.csv` has every run and the projected wall time, steps x time per step).\n").unwrap();
        writeln!(md, "| case | model | nodes | backend | ms per step |").unwrap();
        writeln!(md, "|---|---|---:|---|---:|").unwrap();
        for t in &s.timing {
            let r = &s.accuracy[t.run];
            if r.case == CaseId::Cantilever {
                writeln!(
                    md,
                    "| {} | {} | {} | {} | {:.3} |",
                    r.case.label(),
                    r.model.label(),
                    r.nodes,
                    t.backend,
                    1e3 * t.seconds_per_step
                )
                .unwrap();
            }
        }
        writeln!(md).unwrap();
    }
    writeln!(md, "## Stable time step\n").unwrap();
    writeln!(md, "Free cube, undamped, 0.1 mm random perturbation; bisection of the largest step that stays bounded against the estimate 2/sqrt(lambda_max) (`needlesim_core::stability`).\n").unwrap();
    writeln!(
        md,
        "| model | stiffness | nodes | estimate, s | bisection, s | ratio |"
    )
    .unwrap();
    writeln!(md, "|---|---:|---:|---:|---:|---:|").unwrap();
    for r in &s.stable {
        writeln!(
            md,
            "| {} | x{} | {} | {:.3e} | {:.3e} | {:.2} (+-{:.0}%) |",
            r.model.label(),
            r.stiffness_scale,
            r.nodes,
            r.estimate,
            r.measured,
            r.measured / r.estimate,
            50.0 * r.bracket
        )
        .unwrap();
    }
    writeln!(md, "\n![stable dt](stable_dt.png)\n").unwrap();
    writeln!(md, "## Extreme cases\n").unwrap();
    writeln!(md, "stable: bounded and right by the case's criterion; degraded: bounded but wrong; diverged: stopped by the divergence guard with a typed error naming step and node (never NaN in the output). Details in `extreme.csv`.\n").unwrap();
    write!(md, "| case |").unwrap();
    for m in ModelId::ALL {
        write!(md, " {} |", m.label()).unwrap();
    }
    writeln!(md).unwrap();
    writeln!(md, "|---|{}", ":---:|".repeat(ModelId::ALL.len())).unwrap();
    for case in ExtremeCase::ALL {
        write!(md, "| {} |", case.label()).unwrap();
        for m in ModelId::ALL {
            let w = s
                .extreme
                .iter()
                .find(|r| r.case == case && r.model == m)
                .map(|r| r.outcome.word())
                .unwrap_or("-");
            write!(md, " {w} |").unwrap();
        }
        writeln!(md).unwrap();
    }
    effective::markdown(&mut md, &s.effective);
    needle::markdown(&mut md, &s.needle);
    match &s.realism {
        Some(r) => realism::markdown(&mut md, r),
        None => writeln!(
            md,
            "\n## Needle force realism\n\nNot part of this run: `needlesim report --realism` runs it alone (realism.md)."
        )
        .unwrap(),
    }
    md
}
