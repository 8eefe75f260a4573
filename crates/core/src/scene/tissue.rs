//! `[tissue]`: geometry, density, masses and neighbourhoods.

use super::tagged::de_tagged;
use crate::error::SceneError;
use crate::validate::{finite, positive_finite};
use serde::Deserialize;
use std::path::PathBuf;

/// Tissue geometry and discretisation.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TissueSpec {
    /// Where the nodes come from.
    #[serde(deserialize_with = "de_geometry")]
    pub geometry: Geometry,
    /// Mass density in kg/m^3; the total mass `density * volume` is shared by the nodes as
    /// `masses` says.
    #[serde(default = "default_density")]
    pub density: f64,
    /// Neighbour slots per node (K). Default 18: the first two shells of a cubic lattice
    /// (6 face neighbours, 12 face diagonals). The paper's 16 cuts the second shell, and
    /// as every node keeps the same 10 diagonals the lattice models become anisotropic
    /// ([`crate::calibration`]).
    #[serde(default = "default_neighbours")]
    pub neighbours: usize,
    /// Weight kernel of a neighbour pair.
    #[serde(default, deserialize_with = "de_weight")]
    pub weight: WeightKernel,
    /// How the mass is shared by the nodes (`masses`, default `"cell"`).
    #[serde(default)]
    pub masses: NodeMasses,
}

/// How the body's mass `density * volume` is shared by its nodes.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum NodeMasses {
    /// Each node carries `density * V_i`, `V_i` its cell volume (the part of the body
    /// nearer to it than to any other node; on a box lattice `h^3`, halved on each face).
    /// The lumped mass of the same cells the continuum models integrate over: gravity
    /// loads each part of the body by its volume, whatever the node layout.
    #[default]
    Cell,
    /// Every node `density * volume / n` (the paper's; surface and corner nodes are too
    /// heavy for the volume they stand for, by 8 at a box corner).
    Uniform,
}

pub(crate) fn default_density() -> f64 {
    1000.0
}
/// Fewest neighbours per node a scene may ask for. With K nearest neighbours a body of n
/// nodes has at least `K n / 2` pairs; a 3D framework needs `3n - 6` bars to be rigid
/// (Maxwell's count), so K below 6 leaves every spring network floppy and gives the
/// continuum models moment matrices that are singular at the surface. `neighbours = 1`
/// used to be accepted, and the body fell apart without a word.
pub const MIN_NEIGHBOURS: usize = 6;

/// Default of `tissue.neighbours`.
pub const DEFAULT_NEIGHBOURS: usize = 18;

fn default_neighbours() -> usize {
    DEFAULT_NEIGHBOURS
}

/// The source of the tissue nodes, chosen by the key `kind`.
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// `kind = "box"`.
    Box(BoxGeometry),
    /// `kind = "obj"`.
    Obj(SurfaceGeometry),
    /// `kind = "stl"`: a closed binary or ASCII STL surface, with the same keys and checks
    /// as `obj`.
    Stl(SurfaceGeometry),
    /// `kind = "vtk"`: a closed surface in a VTK file (legacy `.vtk`, XML `.vtp` or `.vtu`,
    /// told by the extension), with the same keys and checks as `obj`.
    Vtk(SurfaceGeometry),
}

/// An axis-aligned box filled with a cubic lattice. Give either `spacing` or a target node
/// count `nodes`; with `nodes`, the lattice spacing is uniform and the lattice may fall
/// short of `max` by less than one spacing along some axes (it stays centred).
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BoxGeometry {
    /// Lower corner.
    pub min: [f64; 3],
    /// Upper corner.
    pub max: [f64; 3],
    /// Lattice spacing in metres.
    pub spacing: Option<f64>,
    /// Target node count (the result is within a few percent).
    pub nodes: Option<usize>,
}

/// A closed triangulated surface (Wavefront OBJ; STL with `kind = "stl"`; VTK with
/// `kind = "vtk"`). By default
/// the surface is resampled to nodes about `spacing` apart and the inside is filled with a
/// cubic lattice of that spacing, so the node count follows the spacing and the volume,
/// not the file's triangle count.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SurfaceGeometry {
    /// Path to the surface file, relative to the scene file.
    pub path: PathBuf,
    /// Node spacing in metres (after scaling).
    pub spacing: f64,
    /// Factor applied to the file's coordinates (e.g. 0.001 for millimetres).
    #[serde(default = "one")]
    pub scale: f64,
    /// Where the surface nodes come from (`surface`, default `"resample"`).
    #[serde(default)]
    pub surface: SurfaceNodes,
    /// Rotation applied after `scale`, about an axis through the origin (`rotate`).
    #[serde(default)]
    pub rotate: Option<AxisRotation>,
    /// Translation in metres applied last (`translate`, default none).
    #[serde(default)]
    pub translate: [f64; 3],
}

/// A right-handed rotation by `degrees` about `axis` (any length but zero).
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AxisRotation {
    /// Rotation axis.
    pub axis: [f64; 3],
    /// Angle in degrees.
    pub degrees: f64,
}

impl AxisRotation {
    /// The rotation matrix (Rodrigues' formula), rows first.
    pub fn matrix(&self) -> [[f64; 3]; 3] {
        let axis = glam::DVec3::from(self.axis);
        let [x, y, z] = (axis / axis.length()).to_array();
        let (s, c) = self.degrees.to_radians().sin_cos();
        let t = 1.0 - c;
        [
            [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
            [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
            [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
        ]
    }
}

/// The surface nodes of a surface-file geometry.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum SurfaceNodes {
    /// A new surface with vertices about one spacing apart on the file's surface (its
    /// dual contour on the node lattice, [`crate::geometry::resample`]); the file's
    /// triangle count does not matter.
    #[default]
    Resample,
    /// Every vertex of the file is a node and its triangles are the surface: for a mesh
    /// already made at the node spacing. A file finer than the spacing gives many more
    /// nodes than its volume needs, and crowded surface nodes shrink the stable step.
    Vertices,
}

pub(crate) fn one() -> f64 {
    1.0
}

/// Weight of a neighbour pair as a function of its rest distance, chosen by the key
/// `kernel`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WeightKernel {
    /// `kernel = "uniform"`: every neighbour weighs 1 (the paper's plain averages).
    Uniform,
    /// `kernel = "poly6"`: `w = (1 - r^2/h^2)^3` with `h = support * (d(i) + d(j)) / 2`,
    /// where `d` is a node's median distance to its K nearest neighbours
    /// ([`crate::neighbours::kernel_length`]; inside a cubic lattice of spacing `a` with
    /// K = 16 or 18, `sqrt(2) a`). A mutual pair farther
    /// apart than `h` gets weight 0, like a broken pair (with the default `support = 2`, a
    /// pair more than twice the median neighbour distance apart).
    Poly6 {
        /// Support radius in units of the median neighbour distance (default 2).
        support: f64,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Poly6Params {
    #[serde(default = "default_support")]
    support: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NoParams {}

fn default_support() -> f64 {
    2.0
}

impl Default for WeightKernel {
    fn default() -> Self {
        WeightKernel::Poly6 {
            support: default_support(),
        }
    }
}

fn de_geometry<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Geometry, D::Error> {
    de_tagged(d, "tissue.geometry", "kind", |name, v| match name {
        "box" => Some(v.try_into().map(Geometry::Box)),
        "obj" => Some(v.try_into().map(Geometry::Obj)),
        "stl" => Some(v.try_into().map(Geometry::Stl)),
        "vtk" => Some(v.try_into().map(Geometry::Vtk)),
        _ => None,
    })
}

fn de_weight<'de, D: serde::Deserializer<'de>>(d: D) -> Result<WeightKernel, D::Error> {
    de_tagged(d, "tissue.weight", "kernel", |name, v| match name {
        "uniform" => Some(v.try_into::<NoParams>().map(|_| WeightKernel::Uniform)),
        "poly6" => Some(
            v.try_into::<Poly6Params>()
                .map(|p| WeightKernel::Poly6 { support: p.support }),
        ),
        _ => None,
    })
}

impl TissueSpec {
    /// Checks the `[tissue]` table's values.
    pub fn validate(&self) -> Result<(), SceneError> {
        let t = self;
        positive_finite("tissue.density", t.density)?;
        if !(MIN_NEIGHBOURS..=64).contains(&t.neighbours) {
            return Err(SceneError::invalid(
                "tissue.neighbours",
                format!(
                    "must be between {MIN_NEIGHBOURS} and 64, got {} ({})",
                    t.neighbours,
                    if t.neighbours < MIN_NEIGHBOURS {
                        "fewer neighbours cannot hold a 3D body together"
                    } else {
                        "the kernels' neighbour rows hold at most 64"
                    }
                ),
            ));
        }
        if let WeightKernel::Poly6 { support } = t.weight {
            if !(support.is_finite() && support > 1.0) {
                return Err(SceneError::invalid(
                    "tissue.weight.support",
                    format!("must be a finite number > 1, got {support}"),
                ));
            }
        }
        match &t.geometry {
            Geometry::Box(BoxGeometry {
                min,
                max,
                spacing,
                nodes,
            }) => {
                for a in 0..3 {
                    finite("tissue.geometry.min", min[a])?;
                    finite("tissue.geometry.max", max[a])?;
                    if max[a] <= min[a] {
                        return Err(SceneError::invalid(
                            "tissue.geometry.max",
                            format!(
                                "must exceed min along every axis (axis {a}: {} <= {})",
                                max[a], min[a]
                            ),
                        ));
                    }
                }
                match (spacing, nodes) {
                    (Some(h), None) => {
                        positive_finite("tissue.geometry.spacing", *h)?;
                        let shortest = (0..3).map(|a| max[a] - min[a]).fold(f64::MAX, f64::min);
                        if *h > shortest {
                            return Err(SceneError::invalid(
                                "tissue.geometry.spacing",
                                format!(
                                    "{h} m is larger than the box's shortest side {shortest} m"
                                ),
                            ));
                        }
                        let count: f64 = (0..3)
                            .map(|a| ((max[a] - min[a]) / h).floor() + 1.0)
                            .product();
                        if count > 5.0e7 {
                            return Err(SceneError::invalid(
                                "tissue.geometry.spacing",
                                format!("{h} m gives {count:.0} nodes, more than the 50 million supported"),
                            ));
                        }
                    }
                    (None, Some(n)) => {
                        if *n < 8 || *n > 50_000_000 {
                            return Err(SceneError::invalid(
                                "tissue.geometry.nodes",
                                format!("must be between 8 and 50000000, got {n}"),
                            ));
                        }
                    }
                    _ => {
                        return Err(SceneError::invalid(
                            "tissue.geometry",
                            "a box needs exactly one of `spacing` and `nodes`",
                        ))
                    }
                }
            }
            Geometry::Obj(g) | Geometry::Stl(g) | Geometry::Vtk(g) => {
                // The lattice size is checked against the surface's bounds when the
                // geometry is built.
                positive_finite("tissue.geometry.spacing", g.spacing)?;
                positive_finite("tissue.geometry.scale", g.scale)?;
                for c in g.translate {
                    finite("tissue.geometry.translate", c)?;
                }
                if let Some(r) = g.rotate {
                    finite("tissue.geometry.rotate.degrees", r.degrees)?;
                    let length = glam::DVec3::from(r.axis).length();
                    if !(length.is_finite() && length > 0.0) {
                        return Err(SceneError::invalid(
                            "tissue.geometry.rotate.axis",
                            format!("must be a finite non-zero vector, got {:?}", r.axis),
                        ));
                    }
                }
            }
        }
        Ok(())
    }
}
