//! The realism section written out: `realism.csv`, its plots and the markdown.

use super::results::Realism;
use crate::plot::{line_plot, Labels, Series};
use std::fmt::Write as _;
use std::path::Path;

fn pct(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.3}"))
}

/// Writes `realism.csv`, `realism_spacing.png` and `realism_models.png` into `out`.
pub fn write_realism(out: &Path, r: &Realism) -> std::io::Result<()> {
    let mut csv = String::from("study,case,quantity,value\n");
    for (name, nodes, a) in &r.scenes {
        // A quantity the run has none of (no hold, no reversal) is an empty value, which
        // CSV readers take as missing, not NaN.
        let mut row = |q: &str, v: Option<f64>| {
            let v = v.map_or(String::new(), |v| format!("{v:e}"));
            writeln!(csv, "scene,{name},{q},{v}").unwrap()
        };
        row("nodes", Some(*nodes as f64));
        row("jumps", Some(a.jumps as f64));
        row("buzz_max_percent", Some(a.buzz_max));
        row("buzz_max_before_last_20ms_percent", Some(a.buzz_max_body));
        row("buzz_share_over_2_percent", Some(a.buzz_share));
        row("median_step_held_percent", a.held);
        row("median_step_still_percent", a.still);
        row("median_step_rotating_percent", a.rotating);
        row("median_step_moving_percent", a.moving);
        row(
            "negative_while_advancing_rows",
            Some(a.negative_advancing as f64),
        );
        row("reversal_max_step_percent", a.reversal);
        row("material_point_max_step_withdrawing_mm", a.material_step);
    }
    if let Some((a, c)) = &r.friction_off {
        writeln!(csv, "friction_off,liver,cutting_n,{c:e}").unwrap();
        let flat = a.flatness.map_or(String::new(), |x| format!("{x:e}"));
        writeln!(csv, "friction_off,liver,max_deviation_percent,{flat}").unwrap();
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
                ("nodes", Some(d.nodes as f64)),
                ("spacing_m", Some(d.spacing)),
                ("dent_m", Some(d.dent)),
                ("peak_n", Some(d.peak)),
                ("slope_n_per_m", d.slope),
            ] {
                // No slope is an empty value (missing to a CSV reader), not NaN.
                let x = x.map_or(String::new(), |x| format!("{x:e}"));
                writeln!(csv, "{study},{},{q},{x}", d.label).unwrap();
            }
        }
    }
    for (v, f) in &r.speeds {
        writeln!(csv, "speed,{v},force_at_25mm_n,{f:e}").unwrap();
    }
    if let Some(v) = &r.viscoelastic {
        for (speed, f) in &v.speeds {
            writeln!(csv, "viscoelastic_speed,{speed},force_at_25mm_n,{f:e}").unwrap();
        }
        for (speed, start, end, tau) in &v.holds {
            writeln!(csv, "viscoelastic_hold,{speed},force_at_stop_n,{start:e}").unwrap();
            writeln!(csv, "viscoelastic_hold,{speed},force_after_3s_n,{end:e}").unwrap();
            writeln!(csv, "viscoelastic_hold,{speed},time_constant_s,{tau:e}").unwrap();
        }
    }
    for (rev, f, fr) in &r.spin {
        writeln!(csv, "spin,{rev},force_at_25mm_n,{f:e}").unwrap();
        writeln!(csv, "spin,{rev},friction_at_25mm_n,{fr:e}").unwrap();
    }
    std::fs::write(out.join("realism.csv"), csv)?;
    // One colour per curve (the model study has five; a fifth curve was dropped from the
    // plot while there were four colours and a zip), reused past the fifth.
    let colours = [
        [200, 40, 40],
        [40, 90, 200],
        [40, 150, 60],
        [150, 90, 20],
        [120, 40, 160],
    ];
    for (file, title, v) in [
        (
            "realism_spacing.png",
            "liver scene: force against depth at three spacings",
            &r.spacing,
        ),
        (
            "realism_models.png",
            "liver scene: force against depth, five tissue models",
            &r.models,
        ),
    ] {
        let series: Vec<Series> = v
            .iter()
            .zip(colours.iter().cycle())
            .map(|(d, &colour)| Series {
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
        "Figures of `shared/tools/force_audit.py` (jumps: steps changing by more than 5% of the local force, inside and not within 20 ms of a puncture; buzz: RMS above about 50 Hz over 20 ms over the local force; held/moving: median step change, the held rows split into the needle still and turning at constant depth; negative: rows advancing with F < 0; reversal: largest step within 50 ms after a reversal over the force there; material point step: the largest step of the tip's depth in the undeformed tissue between two withdrawing rows, which should follow the needle's travel across node removals). The audit's zero padding reads a buzz of about 40% in the last 10 ms of a series that ends with a force on the needle: the buzz is given with and without the last 20 ms. {:.0} s on this machine.\n",
        r.seconds
    )
    .unwrap();
    writeln!(
        md,
        "| scene | nodes | jumps | buzz max % (before last 20 ms) | rows buzz > 2% | held % (still / rotating) | moving % | negative | reversal % | material point step mm |"
    )
    .unwrap();
    writeln!(md, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|").unwrap();
    for (name, nodes, a) in &r.scenes {
        writeln!(
            md,
            "| {name} | {nodes} | {} | {:.2} ({:.2}) | {:.2}% | {} ({} / {}) | {} | {} | {} | {} |",
            a.jumps,
            a.buzz_max,
            a.buzz_max_body,
            100.0 * a.buzz_share,
            pct(a.held),
            pct(a.still),
            pct(a.rotating),
            pct(a.moving),
            a.negative_advancing,
            pct(a.reversal),
            a.material_step
                .map_or("-".to_string(), |x| format!("{x:.3}"))
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
                "| {} | {} | {:.2} | {:.2} | {:.3} | {} |",
                d.label,
                d.nodes,
                1e3 * d.spacing,
                1e3 * d.dent,
                d.peak,
                d.slope.map_or("n/a".into(), |s| format!("{s:.1}"))
            )
            .unwrap();
        }
        if !v.is_empty() {
            writeln!(
                md,
                "\nSpread (max - min over mean): dent {:.1}%, slope {}.",
                spread(v.iter().map(|d| d.dent)),
                match v.iter().filter(|d| d.slope.is_some()).count() {
                    n if n == v.len() =>
                        format!("{:.1}%", spread(v.iter().filter_map(|d| d.slope))),
                    n if n >= 2 => format!(
                        "{:.1}% over the {n} cases with a slope (n/a: the insertion ends within \
                         two spacings of the puncture)",
                        spread(v.iter().filter_map(|d| d.slope))
                    ),
                    _ => "n/a (the insertion ends within two spacings of the puncture)".into(),
                }
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
    if let Some(v) = &r.viscoelastic {
        let series: Vec<String> = v
            .series
            .iter()
            .map(|(g, tau)| format!("g {g} at tau {tau} s"))
            .collect();
        writeln!(
            md,
            "\nViscoelastic tissue (the liver with the Prony series of `scenes/liver_insertion_viscoelastic.toml`: {}; the grip of the cut on the shaft relaxes with the age of the cut):\n",
            series.join(", ")
        )
        .unwrap();
        writeln!(md, "| speed mm/s | force at 25 mm N | elastic N |").unwrap();
        writeln!(md, "|---:|---:|---:|").unwrap();
        for (speed, f) in &v.speeds {
            let elastic = r
                .speeds
                .iter()
                .find(|(s, _)| s == speed)
                .map_or("-".to_string(), |(_, e)| format!("{e:.3}"));
            writeln!(md, "| {:.0} | {f:.3} | {elastic} |", 1e3 * speed).unwrap();
        }
        writeln!(md, "\n| held after mm/s | force at the stop N | after 3 s N | change | fitted time constant s |").unwrap();
        writeln!(md, "|---:|---:|---:|---:|---:|").unwrap();
        for (speed, start, end, tau) in &v.holds {
            writeln!(
                md,
                "| {:.0} | {start:.3} | {end:.3} | {:+.1}% | {tau:.2} |",
                1e3 * speed,
                100.0 * (end / start - 1.0)
            )
            .unwrap();
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
