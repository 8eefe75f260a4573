//! Tissue geometry: the rest positions of the nodes and the closed triangulated surface
//! that bounds them (used for output and, later, for needle contact).
//!
//! Two sources: a box filled with a cubic lattice ([`box_lattice`]) and a closed surface
//! file (OBJ, STL or VTK, [`obj`]) resampled at the scene's spacing ([`resample`]) or keeping
//! its own vertices ([`sampling`]), its inside filled with a cubic lattice.

pub mod box_lattice;
pub mod cell_volume;
mod file_guard;
pub mod lattice;
pub mod memory;
pub mod obj;
pub mod ray_columns;
pub mod resample;
pub mod sampling;
pub mod shapes;
pub mod triangle_bins;
pub use triangle_bins::segment_triangle;

use crate::error::SceneError;
use crate::scene::{Geometry, Scene, SurfaceNodes};
pub use file_guard::panic_is_guarded;
use glam::{DMat3, DVec3};
pub use memory::{check_memory, MemoryEstimate, MeshEstimate};

/// The largest lattice a surface may be sampled on (the box limit of 50 million nodes).
pub const MAX_LATTICE_POINTS: f64 = 5.0e7;

/// Rough bytes per node of a simulation (state, 18 neighbours, model arrays: a continuum
/// model's are about 530), for the size estimate in errors.
const BYTES_PER_NODE: f64 = 550.0;

/// Rest positions of the nodes and the surface triangles over them.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeCloud {
    /// Rest positions in metres.
    pub positions: Vec<[f64; 3]>,
    /// Surface triangles (node indices), counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    /// Volume enclosed by the surface in m^3.
    pub volume: f64,
    /// Volume of each node's cell (the part of the body nearer to it than to any other
    /// node) in m^3; they add up to `volume`. The continuum models integrate their energy
    /// with these weights.
    pub node_volumes: Vec<f64>,
    /// Spacing of the lattice the nodes were placed on (or that fills the surface) in
    /// metres; an interior node's cell is `spacing^3`.
    pub spacing: f64,
}

impl NodeCloud {
    /// Axis-aligned bounds `(min, max)` of the nodes.
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        bounds(&self.positions)
    }

    /// The surface triangles as corner coordinates.
    pub fn triangle_corners(&self) -> Vec<[[f64; 3]; 3]> {
        self.triangles
            .iter()
            .map(|t| t.map(|i| self.positions[i as usize]))
            .collect()
    }
}

/// Axis-aligned bounds of a point set (`(+inf, -inf)` when empty).
pub fn bounds(points: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (lo, hi)
}

/// Builds the node cloud that a scene's geometry describes, with no memory estimate (see
/// [`build_checked`]).
pub fn build(geometry: &Geometry, base_dir: &std::path::Path) -> Result<NodeCloud, SceneError> {
    build_with(geometry, base_dir, &mut |_| Ok(()))
}

/// Builds the node cloud of `scene` after checking its memory estimate, with
/// `extra_nodes` more node slots asked for by `extra_key` ([`check_memory`]): a box is
/// checked before anything is allocated, a surface file once it is read and before it is
/// sampled.
pub fn build_checked(
    scene: &Scene,
    extra_nodes: f64,
    extra_key: &str,
) -> Result<NodeCloud, SceneError> {
    build_with(&scene.tissue.geometry, &scene.base_dir, &mut |mesh| {
        check_memory(scene, &mesh, extra_nodes, extra_key).map(|_| ())
    })
}

/// A soft-tissue body larger than this (m) after `scale` most likely has the wrong
/// `scale`; memory errors then name `scale` rather than `spacing`.
const LIKELY_WRONG_SCALE_M: f64 = 10.0;

fn build_with(
    geometry: &Geometry,
    base_dir: &std::path::Path,
    check: &mut dyn FnMut(MeshEstimate) -> Result<(), SceneError>,
) -> Result<NodeCloud, SceneError> {
    match geometry {
        Geometry::Box(crate::scene::BoxGeometry {
            min,
            max,
            spacing,
            nodes,
        }) => {
            let side = (0..3).map(|a| max[a] - min[a]).fold(0.0, f64::max);
            check_length("tissue.geometry.max", "the box's longest side", side)?;
            let (count, key, what) = match (spacing, nodes) {
                (Some(h), _) => (
                    (0..3)
                        .map(|a| (((max[a] - min[a]) / h + 1e-9).floor() + 1.0).max(2.0))
                        .product(),
                    "tissue.geometry.spacing",
                    format!("a box of {} at spacing {h} m", extent(*min, *max)),
                ),
                (None, Some(n)) => (
                    // `with_node_count` lands within 3% of the target.
                    1.03 * *n as f64,
                    "tissue.geometry.nodes",
                    format!("a box of {n} nodes"),
                ),
                (None, None) => (0.0, "tissue.geometry", String::new()),
            };
            check(MeshEstimate {
                nodes: count,
                lattice_points: 0.0,
                key,
                what,
            })?;
            let lattice = match (spacing, nodes) {
                (Some(h), _) => box_lattice::BoxLattice::with_spacing(*min, *max, *h),
                (None, Some(n)) => {
                    let l = box_lattice::BoxLattice::with_node_count(*min, *max, *n);
                    // A box thinner than the spacing its count implies cannot keep two
                    // nodes across its thin side at that count.
                    if l.len() > 2 * *n {
                        return Err(SceneError::invalid(
                            "tissue.geometry.nodes",
                            format!(
                                "{n} nodes cannot fill this box: its thinnest side needs a \
                                 spacing of at most {:e} m, which takes at least {} nodes; \
                                 give more nodes or a `spacing`",
                                l.spacing,
                                l.len()
                            ),
                        ));
                    }
                    l
                }
                (None, None) => {
                    return Err(SceneError::invalid(
                        "tissue.geometry",
                        "a box needs `spacing` or `nodes`",
                    ))
                }
            };
            check_length(
                if spacing.is_some() {
                    "tissue.geometry.spacing"
                } else {
                    "tissue.geometry.nodes"
                },
                "the spacing",
                lattice.spacing,
            )?;
            check_f32_resolution(
                *min,
                *max,
                lattice.spacing,
                "tissue.geometry.min",
                "move the body near the origin",
                if spacing.is_some() {
                    "tissue.geometry.spacing"
                } else {
                    "tissue.geometry.nodes"
                },
            )?;
            Ok(lattice.cloud())
        }
        Geometry::Obj(g) | Geometry::Stl(g) | Geometry::Vtk(g) => {
            let full = if g.path.is_absolute() {
                g.path.clone()
            } else {
                base_dir.join(&g.path)
            };
            crate::scene::check_input_file(
                &full,
                crate::scene::MAX_SURFACE_FILE_BYTES,
                "tissue.geometry.path",
            )?;
            let mut surface = match geometry {
                Geometry::Stl(_) => obj::load_closed_stl(&full, g.scale)?,
                Geometry::Vtk(_) => obj::load_closed_vtk(&full, g.scale)?,
                _ => obj::load_closed_surface(&full, g.scale)?,
            };
            // The body's size after `scale`, then the spacing, then its size in spacings
            // (a rotation changes it by sqrt(3) at most), then after `translate` its
            // distance from the origin in spacings: each names the key to change.
            let (lo, hi) = bounds(&surface.vertices);
            let size = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
            check_length(
                "tissue.geometry.scale",
                &format!("the body's size after `scale` = {:e}", g.scale),
                size,
            )?;
            check_length("tissue.geometry.spacing", "the spacing", g.spacing)?;
            let half = 0.5 * size;
            check_f32_resolution(
                [-half; 3],
                [half; 3],
                g.spacing,
                "tissue.geometry.spacing",
                "use a coarser spacing",
                "tissue.geometry.spacing",
            )?;
            // A rotation keeps the orientation and the volume of the surface.
            let m = g
                .rotate
                .map(|r| DMat3::from_cols_array_2d(&r.matrix()).transpose());
            for v in &mut surface.vertices {
                let r = match m {
                    Some(m) => m * DVec3::from(*v),
                    None => DVec3::from(*v),
                };
                *v = (r + DVec3::from(g.translate)).into();
            }
            let (lo, hi) = bounds(&surface.vertices);
            check_f32_resolution(
                lo,
                hi,
                g.spacing,
                "tissue.geometry.translate",
                "move the body near the origin",
                "tissue.geometry.spacing",
            )?;
            let points = lattice::Lattice::count(lo, hi, g.spacing, 2);
            let h = g.spacing;
            // Interior nodes fill the volume at one per h^3; resampled surface nodes sit
            // one per lattice cube the surface crosses, fewer than 3 area / h^2.
            let surface_nodes = match g.surface {
                SurfaceNodes::Resample => 3.0 * surface_area(&surface) / (h * h),
                SurfaceNodes::Vertices => surface.vertices.len() as f64,
            };
            let largest = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
            let key = if g.scale != 1.0 && largest > LIKELY_WRONG_SCALE_M {
                "tissue.geometry.scale"
            } else {
                "tissue.geometry.spacing"
            };
            check(MeshEstimate {
                nodes: surface.volume / (h * h * h) + surface_nodes,
                lattice_points: points,
                key,
                what: format!(
                    "a surface of {} and {:.3e} m^3 after `scale` = {} at spacing {h} m",
                    extent(lo, hi),
                    surface.volume,
                    g.scale
                ),
            })?;
            if points > MAX_LATTICE_POINTS {
                let size: Vec<String> = (0..3).map(|a| format!("{:.3e}", hi[a] - lo[a])).collect();
                return Err(SceneError::invalid(
                    "tissue.geometry.spacing",
                    format!(
                        "the surface measures [{}] m after `scale` = {}; at spacing {} m that \
                         is a lattice of {points:.3e} points (about {:.1} GiB), more than the \
                         {MAX_LATTICE_POINTS:.0e} supported: check `scale` (0.001 for a file \
                         in millimetres) and `spacing`",
                        size.join(", "),
                        g.scale,
                        g.spacing,
                        points * BYTES_PER_NODE / (1u64 << 30) as f64,
                    ),
                ));
            }
            check_shells(&surface, g.spacing, &full)?;
            match g.surface {
                SurfaceNodes::Resample => Ok(resample::resample(&surface, g.spacing, &full)?),
                SurfaceNodes::Vertices => Ok(sampling::fill_lattice(&surface, g.spacing)),
            }
        }
    }
}

/// An error naming `tissue.geometry.path` when the surface's shells overlap, one passes
/// through itself or one is inside out outside any other: vertical rays one spacing apart
/// find a winding number other than 0 or 1 ([`ColumnCrossings::first_bad_winding`]).
/// Such a surface would count the shared volume twice (or negatively) and give nodes
/// that belong to no consistent body. A cavity (an inside-out shell within another) is
/// fine; overlaps thinner than the spacing can be missed.
fn check_shells(surface: &obj::Surface, h: f64, path: &std::path::Path) -> Result<(), SceneError> {
    let lattice = lattice::Lattice::covering(&surface.vertices, h, 0);
    let tris: Vec<[[f64; 3]; 3]> = surface
        .triangles
        .iter()
        .map(|t| t.map(|i| surface.vertices[i as usize]))
        .collect();
    let origin = [lattice.origin[0], lattice.origin[1]];
    let columns =
        ray_columns::ColumnCrossings::build(&tris, origin, h, lattice.dims[0], lattice.dims[1]);
    let Some((p, winding)) = columns.first_bad_winding(origin, h) else {
        return Ok(());
    };
    let what = if winding > 1 {
        "shells overlap or the surface passes through itself (a point inside two of them)"
    } else {
        "a shell is inside out (its normals point inwards) and lies inside no other shell"
    };
    Err(SceneError::invalid(
        "tissue.geometry.path",
        format!(
            "{}: {what}: the winding number at ({:.4e}, {:.4e}, {:.4e}) m is {winding}, not 0 \
             or 1; merge the shells into one closed surface (a boolean union) or fix their \
             orientation",
            path.display(),
            p[0],
            p[1],
            p[2]
        ),
    ))
}

/// The extent `hi - lo` in words, `[x, y, z] m`.
fn extent(lo: [f64; 3], hi: [f64; 3]) -> String {
    let e: Vec<String> = (0..3).map(|a| format!("{:.3e}", hi[a] - lo[a])).collect();
    format!("[{}] m", e.join(", "))
}

/// Total area of a surface's triangles in m^2.
fn surface_area(surface: &obj::Surface) -> f64 {
    surface
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| surface.vertices[i as usize]);
            let [a, b, c] = [a, b, c].map(DVec3::from);
            0.5 * (b - a).cross(c - a).length()
        })
        .sum()
}

/// Shortest and longest length (m) a body or a spacing may have. Positions, node volumes
/// (`spacing^3`) and masses are stored in f32 and multiplied by densities and moduli;
/// within these bounds `spacing^3` stays within 1e-27 to 1e18 m^3, at least 1e11 from
/// either end of the f32 range, and the bounds are orders of magnitude beyond anything a
/// continuum model of tissue describes (molecules to planets). A surface scaled by 1e30
/// or 1e-30 is refused here instead of running on rounded or overflowing numbers.
pub const LENGTH_RANGE_M: (f64, f64) = (1e-9, 1e6);

/// An error naming `key` when `length` (described by `what`) lies outside
/// [`LENGTH_RANGE_M`].
fn check_length(key: &str, what: &str, length: f64) -> Result<(), SceneError> {
    let (lo, hi) = LENGTH_RANGE_M;
    if (lo..=hi).contains(&length) {
        return Ok(());
    }
    Err(SceneError::invalid(
        key,
        format!(
            "{what} is {length:.3e} m, outside the {lo:e} to {hi:e} m that f32 positions, \
             volumes and masses can carry"
        ),
    ))
}

/// Node coordinates at most this many spacings from the origin: positions are stored in
/// f32 (relative rounding 6e-8), so a node there is placed within 0.6% of a spacing.
pub const MAX_COORDINATE_SPACINGS: f64 = 1e5;

/// An error naming `key` and saying `cure` when the body between `lo` and `hi` lies so far
/// from the origin (or is so large) that f32 positions cannot resolve spacing `h`.
fn check_f32_resolution(
    lo: [f64; 3],
    hi: [f64; 3],
    h: f64,
    key: &str,
    cure: &str,
    spacing_key: &str,
) -> Result<(), SceneError> {
    let far = lo.iter().chain(&hi).fold(0.0f64, |m, c| m.max(c.abs()));
    if far.is_finite() && far <= MAX_COORDINATE_SPACINGS * h {
        return Ok(());
    }
    // The body itself spans too many spacings (a thin box given many nodes): no
    // placement helps, the spacing must grow.
    let size = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f64, f64::max);
    if size.is_finite() && size > 0.5 * MAX_COORDINATE_SPACINGS * h {
        return Err(SceneError::invalid(
            spacing_key,
            format!(
                "the body spans {size:.3e} m, {:.1e} spacings ({h:e} m): positions are stored \
                 in f32 and could not tell neighbouring nodes apart across it; use a coarser \
                 spacing (fewer nodes)",
                size / h
            ),
        ));
    }
    Err(SceneError::invalid(
        key,
        format!(
            "the body reaches {far:.3e} m from the origin, more than {MAX_COORDINATE_SPACINGS:.0e} \
             spacings ({h:e} m): positions are stored in f32 and could not tell neighbouring \
             nodes apart; {cure}"
        ),
    ))
}

/// Area vector of every node on the surface: `sum over its triangles of area * normal / 3`
/// (outward), zero for nodes not on the surface. Its length is the node's share of the
/// surface area. `positions` holds at least every triangle vertex.
pub fn vertex_area_vectors(positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> Vec<[f64; 3]> {
    let mut out = vec![[0.0; 3]; positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|v| DVec3::from(positions[v as usize]));
        // cross / 2 is the area vector of the triangle; a third goes to each corner.
        let n = (b - a).cross(c - a) / 6.0;
        for v in t {
            out[*v as usize] = (DVec3::from(out[*v as usize]) + n).into();
        }
    }
    out
}

/// Signed volume enclosed by a closed, outward-oriented triangle surface (divergence
/// theorem).
pub fn signed_volume(vertices: &[[f64; 3]], triangles: &[[u32; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| DVec3::from(vertices[v as usize]));
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}
