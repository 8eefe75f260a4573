//! Wavefront OBJ, STL (binary or ASCII, read with `stl_io`) and VTK (legacy `.vtk`, XML
//! `.vtp` poly data or `.vtu` unstructured grids of surface cells, read with `vtkio`)
//! import of a closed tissue surface.
//!
//! Polygons are triangulated, all objects of the file are merged, vertices at bit-identical
//! positions are welded (files that repeat a vertex per face become connected), and
//! vertices used by no triangle are dropped. The result must be a closed, manifold,
//! consistently oriented surface enclosing a positive volume; anything else is a
//! [`GeometryError`] that names the file and the offending triangle or edge.

use super::file_guard;
use crate::error::{GeometryError, SceneError};
use glam::DVec3;
use std::collections::HashMap;
use std::path::Path;

/// A closed triangle surface.
#[derive(Debug, Clone, PartialEq)]
pub struct Surface {
    /// Vertex positions in metres.
    pub vertices: Vec<[f64; 3]>,
    /// Triangles, counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Enclosed volume in m^3 (positive).
    pub volume: f64,
}

/// Loads an OBJ file, scales its coordinates and checks that it bounds a volume.
pub fn load_closed_surface(path: &Path, scale: f64) -> Result<Surface, SceneError> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let load = |message: String| GeometryError::ObjLoad {
        path: path.to_path_buf(),
        message,
    };
    let bytes = std::fs::read(path).map_err(|e| load(e.to_string()))?;
    let text = file_guard::obj_text(path, &bytes)?;
    // Without the material libraries: `mtllib` could name any file, a device or a pipe
    // included, and the tissue needs no materials (file_guard module docs).
    let (models, _materials) = file_guard::guarded(path, || {
        tobj::load_obj_buf(&mut text.as_bytes(), &options, |_| {
            Ok((Vec::new(), HashMap::new()))
        })
        .map_err(|e| load(e.to_string()))
    })?;
    let mut raw_vertices: Vec<[f64; 3]> = Vec::new();
    let mut raw_triangles: Vec<[u32; 3]> = Vec::new();
    for model in &models {
        let mesh = &model.mesh;
        let offset = raw_vertices.len() as u32;
        for (i, p) in mesh.positions.chunks_exact(3).enumerate() {
            let v = scaled_vertex(
                path,
                raw_vertices.len() + i,
                [p[0] as f64, p[1] as f64, p[2] as f64],
                scale,
            )?;
            raw_vertices.push(v);
        }
        for t in mesh.indices.chunks_exact(3) {
            raw_triangles.push([t[0] + offset, t[1] + offset, t[2] + offset]);
        }
    }
    from_triangles(path, &raw_vertices, &raw_triangles).map_err(Into::into)
}

/// Largest coordinate a surface vertex may have after `scale`, m. The geometry's own
/// checks name `scale` for any body too large for f32 positions (about 1e6 m and up);
/// they compute areas and volumes, products of two and three coordinates, which overflow
/// f64 past about 1e100 m: a vertex near 1e298 m was reported as a degenerate triangle.
/// Beyond 1e30 m the vertex itself is named.
const MAX_COORDINATE: f64 = 1e30;

/// A file vertex `p` times `scale`, or the error naming vertex `index` if not finite or
/// beyond [`MAX_COORDINATE`].
fn scaled_vertex(
    path: &Path,
    index: usize,
    p: [f64; 3],
    scale: f64,
) -> Result<[f64; 3], GeometryError> {
    let v = p.map(|c| c * scale);
    if !v.iter().all(|c| c.is_finite()) {
        return Err(GeometryError::NonFiniteVertex {
            path: path.to_path_buf(),
            vertex: index,
        });
    }
    // Far beyond any body, where the surface's areas and volumes overflow: the units
    // are wrong ([`MAX_COORDINATE`]).
    if v.iter().any(|c| c.abs() > MAX_COORDINATE) {
        return Err(GeometryError::ObjLoad {
            path: path.to_path_buf(),
            message: format!(
                "vertex {index} is at {v:?} m, beyond {MAX_COORDINATE:e} m from the origin: \
                 check the file's units and the geometry's `scale`"
            ),
        });
    }
    Ok(v)
}

/// Loads a binary or ASCII STL file, scales its coordinates and checks that it bounds a
/// volume. STL stores each triangle's corners on their own: corners at bit-identical
/// positions are welded, so a surface is closed only if its file repeats shared corners
/// exactly (as exporters do).
pub fn load_closed_stl(path: &Path, scale: f64) -> Result<Surface, SceneError> {
    let load = |message: String| GeometryError::ObjLoad {
        path: path.to_path_buf(),
        message,
    };
    let mut bytes = std::fs::read(path).map_err(|e| load(e.to_string()))?;
    // `stl_io` takes a file whose first line starts with "solid " for ASCII: a binary
    // file whose free-text header starts so has it blanked, an ASCII one whose `solid`
    // line has no name gets one (it was read as binary).
    if file_guard::check_stl(path, &bytes)? {
        if bytes.starts_with(b"solid") {
            bytes[..5].copy_from_slice(b"     ");
        }
    } else {
        // The `solid` keyword in any case, after a byte order mark and blanks.
        let start = bytes.len() - file_guard::stl_text_start(&bytes).len();
        bytes.splice(..start + 5, *b"solid ").for_each(drop);
    }
    let mesh = file_guard::guarded(path, || {
        stl_io::read_stl(&mut std::io::Cursor::new(&bytes)).map_err(|e| load(e.to_string()))
    })?;
    let mut vertices = Vec::with_capacity(mesh.vertices.len());
    for (i, v) in mesh.vertices.iter().enumerate() {
        vertices.push(scaled_vertex(
            path,
            i,
            [v[0] as f64, v[1] as f64, v[2] as f64],
            scale,
        )?);
    }
    let triangles: Vec<[u32; 3]> = mesh
        .faces
        .iter()
        .map(|f| f.vertices.map(|i| i as u32))
        .collect();
    from_triangles(path, &vertices, &triangles).map_err(Into::into)
}

/// Loads a VTK surface (legacy `.vtk`, or XML `.vtp` / `.vtu`; the extension says which),
/// scales it and checks that it bounds a volume. Poly data contributes its polygons and
/// triangle strips; an unstructured grid its triangles, quads and polygons (volume cells
/// are not a surface). Polygons are split into fans.
pub fn load_closed_vtk(path: &Path, scale: f64) -> Result<Surface, SceneError> {
    use vtkio::model::{CellType, DataSet};
    let load = |message: String| GeometryError::ObjLoad {
        path: path.to_path_buf(),
        message,
    };
    let bytes = std::fs::read(path).map_err(|e| load(e.to_string()))?;
    file_guard::check_vtk(path, &bytes)?;
    // The bytes just checked, not the file again (it may have changed since).
    let vtk = file_guard::guarded(path, || {
        if file_guard::is_xml(&bytes) {
            let xml = file_guard::xml_for_reader(&bytes);
            vtkio::Vtk::parse_xml(&xml[..])
        } else {
            vtkio::Vtk::parse_legacy_be(&bytes[..])
        }
        .map_err(|e| load(e.to_string()))
    })?;
    let mut vertices: Vec<[f64; 3]> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    // Appends a piece's points and its cells (`(vertex lists, is a strip)`).
    let mut add =
        |points: vtkio::IOBuffer, cells: Vec<(Vec<u64>, bool)>| -> Result<(), GeometryError> {
            let coords: Vec<f64> = points
                .cast_into::<f64>()
                .ok_or_else(|| load("points are not numbers".into()))?;
            let offset = vertices.len();
            let count = coords.len() / 3;
            for (i, p) in coords.chunks_exact(3).enumerate() {
                vertices.push(scaled_vertex(path, offset + i, [p[0], p[1], p[2]], scale)?);
            }
            for (cell, strip) in cells {
                if let Some(&bad) = cell.iter().find(|&&v| v as usize >= count) {
                    return Err(load(format!(
                        "a cell uses point {bad}, but the piece has {count} points"
                    )));
                }
                let c: Vec<u32> = cell.iter().map(|&v| (v as usize + offset) as u32).collect();
                for k in 2..c.len() {
                    triangles.push(match (strip, k % 2) {
                        (true, 0) => [c[k - 2], c[k - 1], c[k]],
                        (true, _) => [c[k - 1], c[k - 2], c[k]],
                        (false, _) => [c[0], c[k - 1], c[k]],
                    });
                }
            }
            Ok(())
        };
    // vtkio asserts that a legacy cell list holds the counts its header gave: guarded,
    // so that a file whose counts disagree is an error naming it (tests/reader_props.rs).
    let split = |v: vtkio::model::VertexNumbers| -> Result<Vec<Vec<u64>>, GeometryError> {
        file_guard::guarded(path, || {
            let (connectivity, offsets) = v.into_xml();
            let mut start = 0usize;
            Ok(offsets
                .iter()
                .map(|&end| {
                    let end = (end as usize).min(connectivity.len());
                    let cell = connectivity[start.min(end)..end].to_vec();
                    start = end;
                    cell
                })
                .collect())
        })
    };
    match vtk.data {
        DataSet::PolyData { pieces, .. } => {
            for piece in pieces {
                let p = file_guard::guarded(path, || {
                    piece
                        .into_loaded_piece_data(Some(path))
                        .map_err(|e| load(e.to_string()))
                })?;
                let mut cells: Vec<(Vec<u64>, bool)> = Vec::new();
                if let Some(polys) = p.polys {
                    cells.extend(split(polys)?.into_iter().map(|c| (c, false)));
                }
                if let Some(strips) = p.strips {
                    cells.extend(split(strips)?.into_iter().map(|c| (c, true)));
                }
                add(p.points, cells)?;
            }
        }
        DataSet::UnstructuredGrid { pieces, .. } => {
            for piece in pieces {
                let p = file_guard::guarded(path, || {
                    piece
                        .into_loaded_piece_data(Some(path))
                        .map_err(|e| load(e.to_string()))
                })?;
                let types = p.cells.types.clone();
                let cells = split(p.cells.cell_verts)?
                    .into_iter()
                    .zip(types)
                    .filter_map(|(c, t)| match t {
                        CellType::Triangle | CellType::Quad | CellType::Polygon => Some((c, false)),
                        CellType::TriangleStrip => Some((c, true)),
                        _ => None,
                    })
                    .collect();
                add(p.points, cells)?;
            }
        }
        _ => {
            return Err(load(
                "holds no surface: give poly data or an unstructured grid of triangles, quads \
                 or polygons"
                    .into(),
            )
            .into())
        }
    }
    if triangles.is_empty() {
        return Err(load(
            "holds no surface cells (triangles, quads, polygons or strips); a volume mesh must \
             be given as its boundary surface"
                .into(),
        )
        .into());
    }
    from_triangles(path, &vertices, &triangles).map_err(Into::into)
}

/// Welds, compacts and checks a triangle soup. `path` only names the source in errors.
pub fn from_triangles(
    path: &Path,
    vertices: &[[f64; 3]],
    triangles: &[[u32; 3]],
) -> Result<Surface, GeometryError> {
    if triangles.is_empty() {
        return Err(GeometryError::Empty {
            path: path.to_path_buf(),
        });
    }
    // Weld bit-identical positions and keep only referenced vertices, in first-use order.
    let mut by_bits: HashMap<[u64; 3], u32> = HashMap::new();
    let mut remap: Vec<Option<u32>> = vec![None; vertices.len()];
    let mut out_vertices = Vec::new();
    let mut out_triangles = Vec::with_capacity(triangles.len());
    for t in triangles {
        let mut nt = [0u32; 3];
        for (c, &vi) in t.iter().enumerate() {
            let vi = vi as usize;
            nt[c] = match remap[vi] {
                Some(n) => n,
                None => {
                    let p = vertices[vi];
                    let key = p.map(|x| (x + 0.0).to_bits());
                    let n = *by_bits.entry(key).or_insert_with(|| {
                        out_vertices.push(p);
                        (out_vertices.len() - 1) as u32
                    });
                    remap[vi] = Some(n);
                    n
                }
            };
        }
        out_triangles.push(nt);
    }
    let (lo, hi) = super::bounds(&out_vertices);
    let diag2 = (DVec3::from(hi) - DVec3::from(lo)).length_squared();
    for (ti, t) in out_triangles.iter().enumerate() {
        let [a, b, c] = t.map(|i| DVec3::from(out_vertices[i as usize]));
        let area2 = (b - a).cross(c - a).length_squared();
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || area2 <= 1e-24 * diag2 * diag2 {
            return Err(GeometryError::DegenerateTriangle {
                path: path.to_path_buf(),
                triangle: ti,
            });
        }
    }
    check_closed_manifold(path, out_vertices.len(), &out_triangles)?;
    let volume = super::signed_volume(&out_vertices, &out_triangles);
    if volume <= 0.0 {
        return Err(GeometryError::NonPositiveVolume {
            path: path.to_path_buf(),
            volume,
        });
    }
    Ok(Surface {
        vertices: out_vertices,
        triangles: out_triangles,
        volume,
    })
}

/// Checks that every edge is shared by exactly two triangles that traverse it in opposite
/// directions (closed, manifold along edges, consistently oriented).
pub fn check_closed_manifold(
    path: &Path,
    n_vertices: usize,
    triangles: &[[u32; 3]],
) -> Result<(), GeometryError> {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(triangles.len() * 3);
    for t in triangles {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            debug_assert!((a as usize) < n_vertices && (b as usize) < n_vertices);
            let count = directed.entry((a, b)).or_insert(0);
            *count += 1;
            if *count > 1 {
                return Err(GeometryError::NonManifold {
                    path: path.to_path_buf(),
                    a,
                    b,
                });
            }
        }
    }
    let mut edges: Vec<&(u32, u32)> = directed.keys().collect();
    edges.sort_unstable();
    for &&(a, b) in &edges {
        if !directed.contains_key(&(b, a)) {
            return Err(GeometryError::OpenSurface {
                path: path.to_path_buf(),
                a: a.min(b),
                b: a.max(b),
            });
        }
    }
    Ok(())
}
