//! The needle's output file `needle_force.csv`: one row per step, streamed (rows are
//! flushed at every frame once the tip has touched the tissue, and at the end). Its plots
//! against depth and time are drawn from it by the `needlesim` command line tool (crate
//! `needlesim-report`, `needle_plots`).

use needlesim_needle::{PunctureState, Simulation};
use std::path::{Path, PathBuf};

/// Column names of `needle_force.csv`. `depth_m` is the tip's distance past the point
/// where it first touched the surface, along the needle (negative before contact, from the
/// start tip if it never touched); `axial_force_n` is positive when the tissue resists
/// insertion and negative when it resists extraction. `state` is `touching` also while
/// the tip dents an inner membrane; `region` is the tissue region the tip is in (empty
/// while it is not inside); `tissue_depth_m` is the depth of the tip in the undeformed
/// tissue ([`Simulation::tissue_depth`]: 0 while denting the entry surface, empty while
/// not in contact), which differs from `depth_m` by the dents and the tissue dragged
/// along. `tip_force_n` is the part of the axial force the tip's elements carry (the
/// contact before puncture, the cutting and tearing at the crack front; the rest is the
/// shaft's friction), `torque_nm` the friction's torque about the needle's axis (right-handed
/// about its direction, resisting a spin).
pub const NEEDLE_CSV_HEADER: &str = "step,time_s,depth_m,axial_force_n,lateral_force_n,state,\
active_nodes,needle_nodes,region,tissue_depth_m,tip_force_n,torque_nm";

/// One row of `needle_force.csv`, the columns of [`NEEDLE_CSV_HEADER`] in order. Written
/// and read with the `csv` crate (RFC 4180 quoting: a region name with a comma or a quote
/// round-trips); [`read_needle_csv`] reads a file back.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NeedleRow {
    /// Step number.
    pub step: u64,
    /// Simulated time, s.
    #[serde(serialize_with = "seven_digits")]
    pub time_s: f64,
    /// Tip depth past first contact along the needle, m.
    #[serde(serialize_with = "seven_digits")]
    pub depth_m: f64,
    /// Axial force, N (positive: the tissue resists insertion).
    #[serde(serialize_with = "seven_digits")]
    pub axial_force_n: f64,
    /// Lateral force, N.
    #[serde(serialize_with = "seven_digits")]
    pub lateral_force_n: f64,
    /// `outside`, `touching` or `inside`.
    pub state: String,
    /// Simulated nodes.
    pub active_nodes: usize,
    /// Nodes on the needle.
    pub needle_nodes: usize,
    /// The region the tip is in, empty while it is not inside.
    pub region: String,
    /// Tip depth in the undeformed tissue, m; empty (`None`) while not in contact.
    #[serde(serialize_with = "seven_digits_or_empty")]
    pub tissue_depth_m: Option<f64>,
    /// The tip elements' share of the axial force, N.
    #[serde(serialize_with = "seven_digits")]
    pub tip_force_n: f64,
    /// Friction torque about the needle's axis, N m.
    #[serde(serialize_with = "seven_digits")]
    pub torque_nm: f64,
}

fn state_name(s: PunctureState) -> &'static str {
    match s {
        PunctureState::Outside => "outside",
        PunctureState::Touching => "touching",
        PunctureState::Inside => "inside",
    }
}

/// Writes `x` with 7 significant digits (`{:.6e}`), the resolution the file has always
/// had: the forces come from f32 node arrays, and full f64 text would double the file.
fn seven_digits<S: serde::Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&format!("{x:.6e}"))
}

/// [`seven_digits`], or an empty field for `None`.
fn seven_digits_or_empty<S: serde::Serializer>(x: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
    match x {
        Some(x) => seven_digits(x, s),
        None => s.serialize_none(),
    }
}

/// Streams `needle_force.csv`: [`NeedleCsv::append`] writes the steps recorded since its
/// last call and flushes them.
pub struct NeedleCsv {
    path: PathBuf,
    out: csv::Writer<std::fs::File>,
    /// Step of the last row written.
    written: Option<u64>,
}

impl NeedleCsv {
    /// Creates `dir/needle_force.csv` with its header.
    pub fn create(dir: &Path) -> std::io::Result<NeedleCsv> {
        let path = dir.join("needle_force.csv");
        let mut out = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(std::fs::File::create(&path)?);
        out.write_record(NEEDLE_CSV_HEADER.split(','))?;
        out.flush()?;
        Ok(NeedleCsv {
            path,
            out,
            written: None,
        })
    }

    /// Writes the rows of the steps `sim` recorded since the last call, and flushes.
    /// Depth is measured from the first contact point, which is known only once the tip
    /// has touched: until then rows are held back, unless `last` (the run is ending; the
    /// depth then counts from the start tip, as documented for a needle that never
    /// touched).
    pub fn append(&mut self, sim: &Simulation, last: bool) -> std::io::Result<()> {
        if sim.entry_point().is_none() && !last {
            return Ok(());
        }
        // Steps increase along the history: the new rows follow the last one written.
        let h = sim.history();
        let from = h.partition_point(|s| self.written.is_some_and(|w| s.step <= w));
        for s in &h[from..] {
            let region = s
                .region
                .and_then(|r| sim.region_names().get(r as usize))
                .map_or("", |n| n.as_str());
            self.out.serialize(NeedleRow {
                step: s.step,
                time_s: s.time,
                depth_m: sim.depth_of(s.tip, s.direction),
                axial_force_n: s.force.axial,
                lateral_force_n: s.force.lateral,
                state: state_name(s.state).to_string(),
                active_nodes: s.active_nodes,
                needle_nodes: s.needle_nodes,
                region: region.to_string(),
                tissue_depth_m: s.tissue_depth,
                tip_force_n: s.force.tip,
                torque_nm: s.force.torque,
            })?;
        }
        self.written = sim.history().last().map(|s| s.step).or(self.written);
        self.out.flush()
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// The rows of the `needle_force.csv` at `path`, checking its header; errors name the
/// file and the line.
pub fn read_needle_csv(path: &Path) -> Result<Vec<NeedleRow>, String> {
    let file = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    parse_needle_csv(file, &path.display().to_string())
}

/// The rows of a `needle_force.csv` read from `input`; `name` names it in errors.
pub fn parse_needle_csv(input: impl std::io::Read, name: &str) -> Result<Vec<NeedleRow>, String> {
    let mut r = csv::Reader::from_reader(input);
    let header = r.headers().map_err(|e| format!("{name}: {e}"))?;
    if !header.iter().eq(NEEDLE_CSV_HEADER.split(',')) {
        return Err(format!(
            "{name}: not a needle_force.csv (unexpected header)"
        ));
    }
    r.deserialize()
        .map(|row| row.map_err(|e| format!("{name}: {e}")))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The header constant and the row type name the same columns in the same order.
    #[test]
    fn the_header_is_the_row_type() {
        let mut w = csv::Writer::from_writer(Vec::new());
        w.serialize(NeedleRow {
            step: 1,
            time_s: 0.0,
            depth_m: 0.0,
            axial_force_n: 0.0,
            lateral_force_n: 0.0,
            state: "outside".into(),
            active_nodes: 0,
            needle_nodes: 0,
            region: String::new(),
            tissue_depth_m: None,
            tip_force_n: 0.0,
            torque_nm: 0.0,
        })
        .unwrap();
        let text = String::from_utf8(w.into_inner().unwrap()).unwrap();
        assert_eq!(text.lines().next(), Some(NEEDLE_CSV_HEADER));
    }

    /// Numbers are written with 7 significant digits and read back as those.
    #[test]
    fn seven_digits_round_trip() {
        let row = NeedleRow {
            step: 3,
            time_s: 0.123456789,
            depth_m: -1.5e-9,
            axial_force_n: 0.0,
            lateral_force_n: 0.0,
            state: "inside".into(),
            active_nodes: 0,
            needle_nodes: 0,
            region: "a, \"b\"".into(),
            tissue_depth_m: Some(2.0),
            tip_force_n: 0.0,
            torque_nm: 0.0,
        };
        let mut w = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(Vec::new());
        w.serialize(&row).unwrap();
        let text = String::from_utf8(w.into_inner().unwrap()).unwrap();
        assert!(text.starts_with("3,1.234568e-1,-1.500000e-9,"), "{text}");
        let back =
            &parse_needle_csv(format!("{NEEDLE_CSV_HEADER}\n{text}").as_bytes(), "x").unwrap()[0];
        assert_eq!(back.time_s, 0.1234568);
        assert_eq!(
            (back.region.as_str(), back.tissue_depth_m),
            ("a, \"b\"", Some(2.0))
        );
    }
}
