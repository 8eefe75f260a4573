//! The needle's output file `needle_force.csv`: one row per step, streamed (rows are
//! flushed at every frame once the tip has touched the tissue, and at the end). Its plots
//! against depth and time are drawn from it by the `needlesim` command line tool (crate
//! `needlesim-report`, `needle_plots`).

use needlesim_needle::{PunctureState, Simulation};
use std::io::Write;
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

fn state_name(s: PunctureState) -> &'static str {
    match s {
        PunctureState::Outside => "outside",
        PunctureState::Touching => "touching",
        PunctureState::Inside => "inside",
    }
}

/// Streams `needle_force.csv`: [`NeedleCsv::append`] writes the steps recorded since its
/// last call and flushes them.
pub struct NeedleCsv {
    path: PathBuf,
    out: std::io::BufWriter<std::fs::File>,
    /// Step of the last row written.
    written: Option<u64>,
}

impl NeedleCsv {
    /// Creates `dir/needle_force.csv` with its header.
    pub fn create(dir: &Path) -> std::io::Result<NeedleCsv> {
        let path = dir.join("needle_force.csv");
        let mut out = std::io::BufWriter::new(std::fs::File::create(&path)?);
        writeln!(out, "{NEEDLE_CSV_HEADER}")?;
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
            writeln!(
                self.out,
                "{},{:.6e},{:.6e},{:.6e},{:.6e},{},{},{},{},{},{:.6e},{:.6e}",
                s.step,
                s.time,
                sim.depth_of(s.tip, s.direction),
                s.force.axial,
                s.force.lateral,
                state_name(s.state),
                s.active_nodes,
                s.needle_nodes,
                s.region
                    .and_then(|r| sim.region_names().get(r as usize))
                    .map_or("", |n| n.as_str()),
                s.tissue_depth.map_or(String::new(), |d| format!("{d:.6e}")),
                s.force.tip,
                s.force.torque,
            )?;
        }
        self.written = sim.history().last().map(|s| s.step).or(self.written);
        self.out.flush()
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }
}
