//! The needle force plots of a run: `needle_force.png` (force against depth past first
//! contact), `needle_force_time.png` (force against time) and, when the tip entered the
//! tissue, `needle_force_tissue_depth.png` (force against the tip's depth in the
//! undeformed tissue, where membranes lie at their rest depths), drawn from the
//! `needle_force.csv` that [`needlesim::run_scene`] writes for a scene with a needle. The `needlesim run` command
//! draws them when the run ends, however it ends (the CSV is complete up to the last
//! step then).

use crate::plot::{line_plot, Labels, Series};
use needlesim::needle_output::parse_needle_csv;
use std::path::{Path, PathBuf};

/// The force plot files, by name, in a run's output folder (the third only when the
/// tip entered the tissue).
pub const NEEDLE_PLOT_FILES: [&str; 3] = [
    "needle_force.png",
    "needle_force_time.png",
    "needle_force_tissue_depth.png",
];

/// The rows of `needle_force.csv`: time (s), depth (m), axial and lateral force (N), the
/// tissue depth (m, NaN where the CSV has none), and the row indices where the tip entered
/// a new region (a puncture: the region column changes to another non-empty name).
fn parse(text: &str) -> Result<(Vec<[f64; 5]>, Vec<usize>), String> {
    let table = parse_needle_csv(text.as_bytes(), "needle_force.csv")?;
    let mut rows = Vec::new();
    let mut punctures = Vec::new();
    let mut region = String::new();
    for (k, r) in table.into_iter().enumerate() {
        rows.push([
            r.time_s,
            r.depth_m,
            r.axial_force_n,
            r.lateral_force_n,
            r.tissue_depth_m.unwrap_or(f64::NAN),
        ]);
        if !r.region.is_empty() && r.region != region {
            punctures.push(k);
        }
        if !r.region.is_empty() || r.state == "outside" {
            region = r.region;
        }
    }
    Ok((rows, punctures))
}

/// Vertical marks at `x(row)` for the puncture rows, spanning the force range.
fn marks(rows: &[[f64; 5]], punctures: &[usize], x: &dyn Fn(&[f64; 5]) -> f64) -> Vec<(f64, f64)> {
    let (lo, hi) = rows.iter().fold((0.0f64, 0.0f64), |(a, b), r| {
        (a.min(r[2]).min(r[3]), b.max(r[2]).max(r[3]))
    });
    punctures
        .iter()
        .flat_map(|&k| {
            let x = x(&rows[k]);
            [(x, lo), (x, hi), (f64::NAN, f64::NAN)]
        })
        .collect()
}

/// Draws both needle force plots into `dir` from `dir/needle_force.csv`; returns their
/// paths.
pub fn needle_plots(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let csv = dir.join("needle_force.csv");
    let (rows, punctures) = parse(&std::fs::read_to_string(&csv)?).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("{}: {e}", csv.display()),
        )
    })?;
    let series = |x: &dyn Fn(&[f64; 5]) -> f64| -> [Series<'static>; 3] {
        [
            Series {
                label: "puncture (tip enters a region)",
                colour: [150, 150, 150],
                points: marks(&rows, &punctures, x),
            },
            Series {
                label: "axial",
                colour: [200, 40, 40],
                points: rows.iter().map(|r| (x(r), r[2])).collect(),
            },
            Series {
                label: "lateral",
                colour: [40, 90, 200],
                points: rows.iter().map(|r| (x(r), r[3])).collect(),
            },
        ]
    };
    let by_depth = dir.join(NEEDLE_PLOT_FILES[0]);
    line_plot(
        &by_depth,
        &Labels {
            title: "needle force against depth",
            x: "tip depth past first contact (mm)",
            y: "force on needle (N)",
        },
        &series(&|r| r[1] * 1e3),
    )?;
    let by_time = dir.join(NEEDLE_PLOT_FILES[1]);
    line_plot(
        &by_time,
        &Labels {
            title: "needle force against time",
            x: "time (s)",
            y: "force on needle (N)",
        },
        &series(&|r| r[0]),
    )?;
    let mut files = vec![by_depth, by_time];
    if rows.iter().any(|r| r[4].is_finite()) {
        let by_tissue = dir.join(NEEDLE_PLOT_FILES[2]);
        line_plot(
            &by_tissue,
            &Labels {
                title: "needle force against depth in the undeformed tissue",
                x: "tip depth in the tissue at rest, past the entry point (mm)",
                y: "force on needle (N)",
            },
            &series(&|r| r[4] * 1e3),
        )?;
        files.push(by_tissue);
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;
    use needlesim::needle_output::NEEDLE_CSV_HEADER;

    /// A region name with a comma and quotes is one quoted field (RFC 4180).
    #[test]
    fn a_quoted_region_name_is_one_column() {
        let csv = format!(
            "{NEEDLE_CSV_HEADER}\n0,0,0,1,0,inside,3,4,\"skin, \"\"outer\"\"\",,0,0\n\
             1,1e-3,1e-5,1,0,inside,3,4,fat,1e-5,0,0\n"
        );
        let (rows, punctures) = parse(&csv).unwrap();
        assert_eq!((rows.len(), punctures), (2, vec![0, 1]));
        let table = parse_needle_csv(csv.as_bytes(), "x").unwrap();
        assert_eq!(table[0].region, "skin, \"outer\"");
        assert_eq!(table[0].tissue_depth_m, None);
    }

    #[test]
    fn draws_the_plots_from_the_csv() {
        let dir = tempfile::tempdir().unwrap();
        let mut csv = format!("{NEEDLE_CSV_HEADER}\n");
        for k in 0..200 {
            let t = k as f64 * 1e-3;
            csv.push_str(&format!(
                "{k},{t:.6e},{:.6e},{:.6e},{:.6e},inside,3,4,{},{},0.0,0.0\n",
                t * 0.01 - 1e-4,
                (t * 30.0).sin(),
                0.1 * t,
                if k < 100 { "skin" } else { "fat" },
                if k < 50 {
                    String::new()
                } else {
                    format!("{:.6e}", t * 0.005)
                }
            ));
        }
        let (rows, punctures) = parse(&csv).unwrap();
        assert_eq!((rows.len(), punctures), (200, vec![0, 100]));
        assert!(rows[49][4].is_nan() && (rows[100][4] - 0.5e-3).abs() < 1e-12);
        std::fs::write(dir.path().join("needle_force.csv"), &csv).unwrap();
        let files = needle_plots(dir.path()).unwrap();
        assert_eq!(files.len(), 3);
        for f in files {
            assert!(
                std::fs::metadata(&f).unwrap().len() > 5000,
                "{}",
                f.display()
            );
        }
        // Without a tissue depth (the tip never inside) the third plot is not drawn.
        let none: String = csv
            .lines()
            .map(|l| {
                if l.starts_with("step") {
                    return format!("{l}\n");
                }
                // Blank the tissue_depth_m column (the tenth).
                let mut f: Vec<&str> = l.split(',').collect();
                f[9] = "";
                format!("{}\n", f.join(","))
            })
            .collect();
        std::fs::write(dir.path().join("needle_force.csv"), none).unwrap();
        assert_eq!(needle_plots(dir.path()).unwrap().len(), 2);
        std::fs::write(dir.path().join("needle_force.csv"), "a,b\n1,2\n").unwrap();
        let e = needle_plots(dir.path()).unwrap_err();
        assert!(e.to_string().contains("unexpected header"), "{e}");
    }
}
