//! Output files: per-frame metrics as CSV, and the tissue surface of every frame as VTK XML
//! PolyData (`.vtp`, ASCII) with a ParaView collection (`surface.pvd`) that orders the
//! frames in time. Point data: displacement from rest in metres.
//!
//! Everything is streamed: each CSV row is flushed as it is written and `surface.pvd` is
//! rewritten (write, then rename) after every frame, so a run that stops early, however it
//! stops, leaves readable files up to its last frame.
//!
//! The `.vtp` frames are written here rather than with vtkio's writer (vtkio is a
//! dependency for reading surfaces): `tests/outputs_read.rs` reads every frame back with
//! vtkio, which is an independent check only while vtkio did not also write them (meshio,
//! the other light reader, does not read `.vtp`); and ASCII frames stay readable by eye.
//! `frames.csv` and `reactions.csv` hold numbers and validated set names only and are
//! written directly; `needle_force.csv` carries region names and uses the `csv` crate
//! ([`crate::needle_output`]).

use crate::frame::FrameMetrics;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Writes `frames.csv`.
pub struct CsvWriter {
    path: PathBuf,
    out: BufWriter<File>,
}

/// Column names of `frames.csv`.
pub const CSV_HEADER: &str =
    "frame,step,time_s,kinetic_energy_j,max_displacement_m,mean_displacement_m,max_speed_m_s,max_force_n";

impl CsvWriter {
    /// Creates the file and writes the header.
    pub fn create(path: &Path) -> std::io::Result<CsvWriter> {
        let mut out = BufWriter::new(File::create(path)?);
        writeln!(out, "{CSV_HEADER}")?;
        Ok(CsvWriter {
            path: path.to_path_buf(),
            out,
        })
    }

    /// Opens an existing file to append rows (a resumed run).
    pub fn append(path: &Path) -> std::io::Result<CsvWriter> {
        let file = std::fs::OpenOptions::new().append(true).open(path)?;
        Ok(CsvWriter {
            path: path.to_path_buf(),
            out: BufWriter::new(file),
        })
    }

    /// Appends one frame and flushes it to the file.
    pub fn row(&mut self, m: &FrameMetrics) -> std::io::Result<()> {
        writeln!(
            self.out,
            "{},{},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e}",
            m.frame,
            m.step,
            m.time,
            m.kinetic_energy,
            m.max_displacement,
            m.mean_displacement,
            m.max_speed,
            m.max_force
        )?;
        self.out.flush()
    }

    /// Flushes and returns the path.
    pub fn finish(mut self) -> std::io::Result<PathBuf> {
        self.out.flush()?;
        Ok(self.path)
    }
}

/// Writes `surface/surface_NNNNN.vtp` per frame and `surface.pvd` beside the `surface`
/// folder. Each frame holds the surface triangles of that frame (a needle splits one) and,
/// as vertex cells, the needle nodes, with the point data `displacement` and `needle`
/// (1 on needle nodes).
pub struct SurfaceWriter {
    dir: PathBuf,
    frames: Vec<(f64, String)>,
}

impl SurfaceWriter {
    /// Creates the `surface` folder.
    pub fn new(out_dir: &Path) -> std::io::Result<SurfaceWriter> {
        std::fs::create_dir_all(out_dir.join("surface"))?;
        Ok(SurfaceWriter {
            dir: out_dir.to_path_buf(),
            frames: Vec::new(),
        })
    }

    /// Continues a series whose first frames are `kept`, `(time, frame)` each (a resumed
    /// run; the index is rewritten at the next frame). Only frames whose file is on disk
    /// are listed: a run that wrote no surface frames before its checkpoint (they were
    /// switched off) leaves none to list.
    pub fn resume(out_dir: &Path, kept: &[(f64, usize)]) -> std::io::Result<SurfaceWriter> {
        let mut w = SurfaceWriter::new(out_dir)?;
        w.frames = kept
            .iter()
            .map(|&(t, k)| (t, frame_name(k)))
            .filter(|(_, name)| out_dir.join(name).is_file())
            .collect();
        Ok(w)
    }

    /// Writes one frame: `triangles` and `vertices` are node indices into `pos` and `rest`.
    pub fn frame(
        &mut self,
        time: f64,
        pos: &[[f32; 4]],
        rest: &[[f64; 3]],
        triangles: &[[u32; 3]],
        vertices: &[u32],
    ) -> std::io::Result<()> {
        let mut map = std::collections::HashMap::new();
        let mut points: Vec<u32> = Vec::new();
        let mut local = |i: u32| -> u32 {
            *map.entry(i).or_insert_with(|| {
                points.push(i);
                (points.len() - 1) as u32
            })
        };
        let tris: Vec<[u32; 3]> = triangles.iter().map(|t| t.map(&mut local)).collect();
        let verts: Vec<u32> = vertices.iter().map(|&v| local(v)).collect();
        let needle: std::collections::HashSet<u32> = vertices.iter().copied().collect();
        let name = frame_name(self.frames.len());
        let mut out = BufWriter::new(File::create(self.dir.join(&name))?);
        writeln!(out, r#"<?xml version="1.0"?>"#)?;
        writeln!(
            out,
            r#"<VTKFile type="PolyData" version="0.1" byte_order="LittleEndian">"#
        )?;
        writeln!(out, "<PolyData>")?;
        writeln!(
            out,
            r#"<Piece NumberOfPoints="{}" NumberOfVerts="{}" NumberOfLines="0" NumberOfStrips="0" NumberOfPolys="{}">"#,
            points.len(),
            verts.len(),
            tris.len()
        )?;
        writeln!(
            out,
            r#"<Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">"#
        )?;
        for &i in &points {
            let p = pos[i as usize];
            writeln!(out, "{} {} {}", p[0], p[1], p[2])?;
        }
        writeln!(out, "</DataArray></Points>")?;
        writeln!(
            out,
            r#"<PointData Vectors="displacement" Scalars="needle">"#
        )?;
        writeln!(
            out,
            r#"<DataArray type="Float32" Name="displacement" NumberOfComponents="3" format="ascii">"#
        )?;
        for &i in &points {
            let (p, r) = (pos[i as usize], rest[i as usize]);
            writeln!(
                out,
                "{} {} {}",
                (p[0] as f64 - r[0]) as f32,
                (p[1] as f64 - r[1]) as f32,
                (p[2] as f64 - r[2]) as f32
            )?;
        }
        writeln!(out, "</DataArray>")?;
        writeln!(
            out,
            r#"<DataArray type="UInt8" Name="needle" format="ascii">"#
        )?;
        for i in &points {
            write!(out, "{} ", needle.contains(i) as u8)?;
        }
        writeln!(out, "\n</DataArray></PointData>")?;
        let cells = |out: &mut BufWriter<File>, tag: &str, conn: &[u32], per: usize| {
            writeln!(out, "<{tag}>")?;
            writeln!(
                out,
                r#"<DataArray type="Int32" Name="connectivity" format="ascii">"#
            )?;
            for c in conn.chunks(per) {
                for v in c {
                    write!(out, "{v} ")?;
                }
                writeln!(out)?;
            }
            writeln!(out, "</DataArray>")?;
            writeln!(
                out,
                r#"<DataArray type="Int32" Name="offsets" format="ascii">"#
            )?;
            for k in 1..=conn.len() / per {
                write!(out, "{} ", per * k)?;
            }
            writeln!(out, "\n</DataArray>\n</{tag}>")
        };
        // No <Verts> section without vertices: an empty cell array is valid VTK, but vtkio
        // (a reader users have, tests/outputs_read.rs) fails on it.
        if !verts.is_empty() {
            cells(&mut out, "Verts", &verts, 1)?;
        }
        let flat: Vec<u32> = tris.iter().flatten().copied().collect();
        cells(&mut out, "Polys", &flat, 3)?;
        writeln!(out, "</Piece>\n</PolyData>\n</VTKFile>")?;
        out.flush()?;
        self.frames.push((time, name));
        self.write_index()
    }

    /// Rewrites `surface.pvd` with every frame so far: written beside it, then renamed over
    /// it, so that the index on disk is always complete.
    fn write_index(&self) -> std::io::Result<()> {
        let pvd = self.dir.join("surface.pvd");
        let partial = self.dir.join("surface.pvd.partial");
        let mut out = BufWriter::new(File::create(&partial)?);
        writeln!(out, r#"<?xml version="1.0"?>"#)?;
        writeln!(
            out,
            r#"<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">"#
        )?;
        writeln!(out, "<Collection>")?;
        for (t, name) in &self.frames {
            writeln!(
                out,
                r#"<DataSet timestep="{t}" group="" part="0" file="{name}"/>"#
            )?;
        }
        writeln!(out, "</Collection>\n</VTKFile>")?;
        out.flush()?;
        drop(out);
        std::fs::rename(&partial, &pvd)
    }

    /// Returns every path written (the index is already up to date).
    pub fn finish(self) -> std::io::Result<Vec<PathBuf>> {
        let pvd = self.dir.join("surface.pvd");
        let mut files = vec![pvd];
        files.extend(self.frames.iter().map(|(_, n)| self.dir.join(n)));
        Ok(files)
    }
}

fn frame_name(frame: usize) -> String {
    format!("surface/surface_{frame:05}.vtp")
}

/// Prepares `out_dir` for a run resumed at step `at`: `frames.csv` and `reactions.csv`
/// keep their rows of earlier steps (each file rewritten beside itself, then renamed over
/// it), surface frames after those rows are removed, and `needle_force.csv` is left for
/// the resumed run to rewrite from its history. Returns `(step, frame)` of the frames
/// kept.
pub fn keep_before(out_dir: &Path, at: u64) -> std::io::Result<Vec<(u64, usize)>> {
    let invalid = |path: &Path, line: &str| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("{}: unreadable row `{line}`", path.display()),
        )
    };
    let mut kept = Vec::new();
    for name in ["frames.csv", "reactions.csv"] {
        let path = out_dir.join(name);
        let text = match std::fs::read_to_string(&path) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound && name == "reactions.csv" => {
                continue
            }
            other => other?,
        };
        let mut out = String::new();
        for (k, line) in text.lines().enumerate() {
            if k == 0 {
                out.push_str(line);
                out.push('\n');
                continue;
            }
            // Columns: frame, step, time.
            let cols: Vec<&str> = line.splitn(4, ',').collect();
            let parse = || -> Option<(usize, u64)> {
                Some((cols.first()?.parse().ok()?, cols.get(1)?.parse().ok()?))
            };
            let (frame, step) = parse().ok_or_else(|| invalid(&path, line))?;
            if step < at {
                out.push_str(line);
                out.push('\n');
                if name == "frames.csv" {
                    kept.push((step, frame));
                }
            }
        }
        let partial = out_dir.join(format!("{name}.partial"));
        std::fs::write(&partial, out)?;
        std::fs::rename(&partial, &path)?;
    }
    let frames = out_dir.join("surface");
    if let Ok(entries) = std::fs::read_dir(&frames) {
        for entry in entries {
            let name = entry?.file_name();
            let name = name.to_string_lossy();
            let number = name
                .strip_prefix("surface_")
                .and_then(|n| n.strip_suffix(".vtp"))
                .and_then(|n| n.parse::<usize>().ok());
            if number.is_some_and(|k| k >= kept.len()) {
                std::fs::remove_file(frames.join(name.as_ref()))?;
            }
        }
    }
    Ok(kept)
}

/// The files a run writes into its output folder, removed before a fresh run writes
/// there, so that no frame of an earlier run is mistaken for one of this run. Only
/// these names are touched; anything else in the folder stays.
pub fn clear_previous_run(out_dir: &Path) -> std::io::Result<()> {
    let remove = |p: PathBuf| match std::fs::remove_file(&p) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e),
        _ => Ok(()),
    };
    for name in [
        "frames.csv",
        "reactions.csv",
        "needle_force.csv",
        "needle_force.png",
        "needle_force_time.png",
        "surface.pvd",
        "surface.pvd.partial",
        "checkpoint.bin",
        "checkpoint.bin.partial",
    ] {
        remove(out_dir.join(name))?;
    }
    let frames = out_dir.join("surface");
    if let Ok(entries) = std::fs::read_dir(&frames) {
        for entry in entries {
            let name = entry?.file_name();
            let name = name.to_string_lossy();
            if name.starts_with("surface_") && name.ends_with(".vtp") {
                remove(frames.join(name.as_ref()))?;
            }
        }
    }
    Ok(())
}
