//! Scene description, read from TOML.
//!
//! A scene says what tissue to build (geometry, material model, density, neighbours),
//! how to step it (time step, gravity, damping, fixed nodes, initial deformation) and what
//! to write. Every table rejects unknown keys, and [`Scene::validate`] rejects values out
//! of range with an error that names the dotted key. Lengths are metres, masses kilograms,
//! times seconds.
//!
//! ```toml
//! [tissue]
//! density = 1000.0
//! neighbours = 18
//! geometry = { kind = "box", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], nodes = 639 }
//!
//! [material]
//! model = "local_shape_matching"
//! stiffness = 20.0
//!
//! [physics]
//! dt = 1e-3
//! gravity = [0.0, -9.81, 0.0]
//! damping = 5.0
//!
//! [[fixed]]
//! axis = "x"
//! below = 0.001
//! ```

use crate::error::SceneError;
use crate::validate::{finite, non_negative_finite, positive_finite};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// One `[[region]]` table.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    /// Unique name (errors, CSV and Python name regions by it).
    pub name: String,
    /// Where the region is.
    #[serde(deserialize_with = "de_region_geometry")]
    pub geometry: RegionGeometry,
    /// Mass density in kg/m^3 (default: `tissue.density`).
    #[serde(default)]
    pub density: Option<f64>,
    /// The region's material parameters, for the scene's model (required).
    #[serde(default)]
    pub material: Option<toml::Table>,
    /// The needle's parameters in this region (read by `needlesim-needle`).
    #[serde(default)]
    pub needle: Option<toml::Table>,
}

/// The shape of a region.
#[derive(Debug, Clone, PartialEq)]
pub enum RegionGeometry {
    /// `kind = "box"`: an axis-aligned box, faces included.
    Box {
        /// Lower corner, m.
        min: [f64; 3],
        /// Upper corner, m.
        max: [f64; 3],
    },
    /// `kind = "obj"`, `"stl"` or `"vtk"`: the inside of a closed surface file.
    Surface(RegionSurface),
}

/// A closed surface file bounding a region.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RegionSurface {
    /// `obj`, `stl` or `vtk` (set from `kind`).
    #[serde(skip)]
    pub kind: String,
    /// Path, relative to the scene file.
    pub path: PathBuf,
    /// Factor on the file's coordinates.
    #[serde(default = "one")]
    pub scale: f64,
    /// Rotation after `scale`.
    #[serde(default)]
    pub rotate: Option<AxisRotation>,
    /// Translation in m, applied last.
    #[serde(default)]
    pub translate: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RegionBoxKeys {
    min: [f64; 3],
    max: [f64; 3],
}

fn de_region_geometry<'de, D: serde::Deserializer<'de>>(d: D) -> Result<RegionGeometry, D::Error> {
    use serde::de::Error;
    let mut t = toml::Table::deserialize(d)?;
    let kind = match t.remove("kind") {
        Some(toml::Value::String(s)) => s,
        _ => {
            return Err(D::Error::custom(
                "`region.geometry` needs `kind` = \"box\", \"obj\", \"stl\" or \"vtk\"",
            ))
        }
    };
    let msg = |e: toml::de::Error| {
        D::Error::custom(format!(
            "`region.geometry` (kind = \"{kind}\"): {}",
            e.to_string().trim_end().replace('\n', " ")
        ))
    };
    match kind.as_str() {
        "box" => {
            let b: RegionBoxKeys = toml::Value::Table(t).try_into().map_err(msg)?;
            Ok(RegionGeometry::Box {
                min: b.min,
                max: b.max,
            })
        }
        "obj" | "stl" | "vtk" => {
            let mut s: RegionSurface = toml::Value::Table(t).try_into().map_err(msg)?;
            s.kind = kind;
            Ok(RegionGeometry::Surface(s))
        }
        other => Err(D::Error::custom(format!(
            "`region.geometry.kind`: unknown variant `{other}` (box, obj, stl or vtk)"
        ))),
    }
}

/// A complete scene.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Free text shown by the CLI.
    #[serde(default)]
    pub name: String,
    /// Which backend runs the scene.
    #[serde(default)]
    pub backend: BackendChoice,
    /// The tissue: geometry, density and neighbourhoods.
    pub tissue: Tissue,
    /// The material model and its parameters.
    #[serde(deserialize_with = "de_material")]
    pub material: Material,
    /// Time step, gravity and damping.
    #[serde(default)]
    pub physics: Physics,
    /// Node sets held at rest (`[[fixed]]`), in all or some components.
    #[serde(default)]
    pub fixed: Vec<FixedSelection>,
    /// Node sets moved by a prescribed displacement (`[[prescribed]]`).
    #[serde(default)]
    pub prescribed: Vec<Prescribed>,
    /// Surface loads (`[[load]]`).
    #[serde(default)]
    pub load: Vec<LoadSpec>,
    /// Tissue regions with their own material (`[[region]]`, checked and resolved by
    /// `regions::classify` when the tissue is built).
    #[serde(default)]
    pub region: Vec<RegionSpec>,
    /// Initial deformation applied to the rest shape at the start.
    #[serde(default)]
    pub initial: Initial,
    /// How long to run and what to write.
    #[serde(default)]
    pub run: RunSettings,
    /// The needle (table `[needle]`), read and validated by `needlesim-needle`; this crate
    /// keeps it as raw TOML so that it knows nothing of the needle. A scene without it has
    /// no needle and allocates no needle node slots.
    #[serde(default)]
    pub needle: Option<toml::Table>,
    /// Directory that relative paths in the scene are resolved against (the scene file's
    /// directory); not read from the file.
    #[serde(skip)]
    pub base_dir: PathBuf,
}

/// Which backend steps the tissue.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "kebab-case")]
pub enum BackendChoice {
    /// One CPU thread.
    Cpu,
    /// All CPU threads (rayon); the default.
    #[default]
    CpuParallel,
    /// The wgpu compute backend; an error if no GPU adapter is found.
    Gpu,
    /// The GPU when an adapter is found, else all CPU threads (with a warning).
    Auto,
}

/// Tissue geometry and discretisation.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Tissue {
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
    Obj(ObjGeometry),
    /// `kind = "stl"`: a closed binary or ASCII STL surface, with the same keys and checks
    /// as `obj`.
    Stl(ObjGeometry),
    /// `kind = "vtk"`: a closed surface in a VTK file (legacy `.vtk`, XML `.vtp` or `.vtu`,
    /// told by the extension), with the same keys and checks as `obj`.
    Vtk(ObjGeometry),
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
pub struct ObjGeometry {
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

fn one() -> f64 {
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

pub use crate::models::debunne_meshfree::DebunneParams;
pub use crate::models::local_shape_matching::{ShapeMatchingForces, ShapeMatchingParams};
pub use crate::models::mass_spring::{MassSpringParams, SpringShare};
pub use crate::models::mls::{lame, NodeVolumes};
pub use crate::models::point_based::PointBasedParams;
pub use crate::models::Material;

/// Time stepping parameters.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Physics {
    /// Time step: seconds, or `"auto"` for half the critical time step estimated from the
    /// model at the initial state ([`crate::stability`]).
    #[serde(default = "default_dt")]
    pub dt: TimeStep,
    /// Gravity in m/s^2.
    #[serde(default)]
    pub gravity: [f64; 3],
    /// Mass-proportional velocity damping c in 1/s: `v <- (v + dt a) / (1 + dt c)`.
    #[serde(default)]
    pub damping: f64,
    /// Divergence guard: a free node faster than this (m/s), or any non-finite position or
    /// velocity, stops the run with an error naming the step and the node. An unstable
    /// explicit step grows geometrically, so the bound is crossed within a few steps of
    /// the instability becoming visible; tissue speeds are far below the default 100 m/s.
    #[serde(default = "default_max_speed")]
    pub max_speed: f64,
    /// Steps between two divergence checks of a needle simulation (each reads every
    /// node back from the GPU); runs also check at every output frame, and the needle
    /// nodes sliding on the shaft (read back every step anyway) are checked every step.
    #[serde(default = "default_check_every")]
    pub check_every: u64,
}

fn default_dt() -> TimeStep {
    TimeStep::Seconds(1e-3)
}

/// A time step in seconds or chosen by the engine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TimeStep {
    /// This many seconds.
    Seconds(f64),
    /// [`AUTO_DT_SAFETY`] times the critical time step estimated from the model.
    Auto,
}

/// The fraction of the estimated critical time step that `dt = "auto"` uses. The estimate
/// is made at the initial state; a half leaves room for the stiffening of large
/// deformations (the divergence guard catches what it does not).
pub const AUTO_DT_SAFETY: f64 = 0.5;

impl<'de> Deserialize<'de> for TimeStep {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        match toml::Value::deserialize(d)? {
            toml::Value::Float(f) => Ok(TimeStep::Seconds(f)),
            toml::Value::Integer(i) => Ok(TimeStep::Seconds(i as f64)),
            toml::Value::String(s) if s == "auto" => Ok(TimeStep::Auto),
            other => Err(D::Error::custom(format!(
                "`physics.dt` must be a number of seconds or \"auto\", got {other}"
            ))),
        }
    }
}
fn default_max_speed() -> f64 {
    100.0
}
fn default_check_every() -> u64 {
    100
}

impl Default for Physics {
    fn default() -> Self {
        Physics {
            dt: default_dt(),
            gravity: [0.0; 3],
            damping: 0.0,
            max_speed: default_max_speed(),
            check_every: default_check_every(),
        }
    }
}

/// An axis of the scene frame.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Axis {
    /// x
    X,
    /// y
    Y,
    /// z
    Z,
}

impl Axis {
    /// 0, 1 or 2.
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
}

/// A set of nodes, chosen by their rest positions. In a scene table it is given by
/// exactly one of these keys (next to the table's own keys):
///
/// - `axis` with `below` or `above`: every node at or below (above) that coordinate;
/// - `box = { min = [..], max = [..] }`: every node inside the box (faces included);
/// - `sphere = { centre = [..], radius = r }`: every node within `r` of the centre;
/// - `points = [[x, y, z], ...]`: the node nearest to each point.
///
/// A set that selects no node is an error naming the table.
#[derive(Debug, Clone, PartialEq)]
pub enum NodeSet {
    /// Nodes on one side of a plane normal to an axis.
    Plane {
        /// The axis the plane is normal to.
        axis: Axis,
        /// Nodes at or below this coordinate, else at or above `above`.
        below: Option<f64>,
        /// Nodes at or above this coordinate.
        above: Option<f64>,
    },
    /// Nodes inside an axis-aligned box.
    Box {
        /// Lower corner.
        min: [f64; 3],
        /// Upper corner.
        max: [f64; 3],
    },
    /// Nodes inside a sphere.
    Sphere {
        /// Centre.
        centre: [f64; 3],
        /// Radius in m.
        radius: f64,
    },
    /// The node nearest to each point.
    Points(Vec<[f64; 3]>),
}

impl NodeSet {
    /// Indices of the selected nodes among `rest` (sorted, each once).
    pub fn select(&self, rest: &[[f64; 3]]) -> Vec<u32> {
        let mut out: Vec<u32> = match self {
            NodeSet::Points(points) => points
                .iter()
                .filter_map(|q| {
                    (0..rest.len()).min_by(|&a, &b| {
                        let d = |i: usize| {
                            glam::DVec3::from(rest[i]).distance_squared(glam::DVec3::from(*q))
                        };
                        d(a).total_cmp(&d(b))
                    })
                })
                .map(|i| i as u32)
                .collect(),
            _ => (0..rest.len() as u32)
                .filter(|&i| self.contains(rest[i as usize]))
                .collect(),
        };
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Whether a rest position lies in the set's region (`points` sets contain no region:
    /// false).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        match self {
            NodeSet::Plane { axis, below, above } => {
                let c = p[axis.index()];
                match (below, above) {
                    (Some(b), _) => c <= *b,
                    (None, Some(a)) => c >= *a,
                    (None, None) => false,
                }
            }
            NodeSet::Box { min, max } => (0..3).all(|a| p[a] >= min[a] && p[a] <= max[a]),
            NodeSet::Sphere { centre, radius } => {
                glam::DVec3::from(p).distance_squared(glam::DVec3::from(*centre)) <= radius * radius
            }
            NodeSet::Points(_) => false,
        }
    }

    fn validate(&self, key: &str) -> Result<(), SceneError> {
        match self {
            NodeSet::Plane { below, above, .. } => match (below, above) {
                (Some(v), None) | (None, Some(v)) => finite(key, *v),
                _ => Err(SceneError::invalid(
                    key,
                    "give exactly one of `below` and `above` with `axis`",
                )),
            },
            NodeSet::Box { min, max } => {
                for a in 0..3 {
                    finite(&format!("{key}.box.min"), min[a])?;
                    finite(&format!("{key}.box.max"), max[a])?;
                    if max[a] < min[a] {
                        return Err(SceneError::invalid(
                            format!("{key}.box.max"),
                            format!("must not be below min (axis {a}: {} < {})", max[a], min[a]),
                        ));
                    }
                }
                Ok(())
            }
            NodeSet::Sphere { centre, radius } => {
                for c in centre {
                    finite(&format!("{key}.sphere.centre"), *c)?;
                }
                positive_finite(&format!("{key}.sphere.radius"), *radius)
            }
            NodeSet::Points(points) => {
                if points.is_empty() {
                    return Err(SceneError::invalid(format!("{key}.points"), "is empty"));
                }
                for c in points.iter().flatten() {
                    finite(&format!("{key}.points"), *c)?;
                }
                Ok(())
            }
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BoxKeys {
    min: [f64; 3],
    max: [f64; 3],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SphereKeys {
    centre: [f64; 3],
    radius: f64,
}

/// Takes the node-set keys out of a boundary table; the rest is the table's own.
fn take_node_set(t: &mut toml::Table) -> Result<NodeSet, String> {
    let picked: Vec<&str> = ["axis", "box", "sphere", "points"]
        .into_iter()
        .filter(|k| t.contains_key(*k))
        .collect();
    if picked.len() != 1 {
        return Err(format!(
            "give exactly one node set: `axis` (with `below` or `above`), `box`, `sphere` or `points`{}",
            if picked.is_empty() {
                String::new()
            } else {
                format!(" (got {})", picked.join(", "))
            }
        ));
    }
    fn e(k: &'static str) -> impl Fn(toml::de::Error) -> String {
        move |e| format!("`{k}`: {}", e.to_string().trim_end())
    }
    let num = |v: Option<toml::Value>, k: &'static str| -> Result<Option<f64>, String> {
        v.map(|v| v.try_into::<f64>().map_err(e(k))).transpose()
    };
    Ok(match picked[0] {
        "axis" => NodeSet::Plane {
            axis: t
                .remove("axis")
                .expect("present")
                .try_into()
                .map_err(e("axis"))?,
            below: num(t.remove("below"), "below")?,
            above: num(t.remove("above"), "above")?,
        },
        "box" => {
            let b: BoxKeys = t
                .remove("box")
                .expect("present")
                .try_into()
                .map_err(e("box"))?;
            NodeSet::Box {
                min: b.min,
                max: b.max,
            }
        }
        "sphere" => {
            let b: SphereKeys = t
                .remove("sphere")
                .expect("present")
                .try_into()
                .map_err(e("sphere"))?;
            NodeSet::Sphere {
                centre: b.centre,
                radius: b.radius,
            }
        }
        _ => NodeSet::Points(
            t.remove("points")
                .expect("present")
                .try_into()
                .map_err(e("points"))?,
        ),
    })
}

/// Deserialises a boundary table: its node set, then the rest into `T`.
fn de_with_node_set<'de, D, T>(d: D) -> Result<(NodeSet, T), D::Error>
where
    D: serde::Deserializer<'de>,
    T: serde::de::DeserializeOwned,
{
    use serde::de::Error;
    let mut t = toml::Table::deserialize(d)?;
    let set = take_node_set(&mut t).map_err(D::Error::custom)?;
    let rest = toml::Value::Table(t)
        .try_into()
        .map_err(|e: toml::de::Error| {
            D::Error::custom(e.to_string().trim_end().replace('\n', " "))
        })?;
    Ok((set, rest))
}

/// Which displacement components a constraint holds: a list of axes (`["y"]` is a roller
/// along y, free to slide in x and z). Default: all three.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Components(pub [bool; 3]);

impl Default for Components {
    fn default() -> Self {
        Components([true; 3])
    }
}

impl Components {
    /// Whether all three are held.
    pub fn all(&self) -> bool {
        self.0 == [true; 3]
    }
}

impl<'de> Deserialize<'de> for Components {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let axes = Vec::<Axis>::deserialize(d)?;
        if axes.is_empty() {
            return Err(D::Error::custom(
                "`components` is empty: list the axes held, e.g. [\"y\"]",
            ));
        }
        let mut c = [false; 3];
        for a in axes {
            if c[a.index()] {
                return Err(D::Error::custom(format!("`components` lists {a:?} twice")));
            }
            c[a.index()] = true;
        }
        Ok(Components(c))
    }
}

/// `[[fixed]]`: a node set held at its rest position, in every component or (with
/// `components`) only in some: `components = ["y"]` on a bottom face is a frictionless
/// floor (roller).
#[derive(Debug, Clone, PartialEq)]
pub struct FixedSelection {
    /// The nodes.
    pub nodes: NodeSet,
    /// The components held (default all).
    pub components: Components,
    /// Name in the reaction output (default `fixed<i>`).
    pub name: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FixedKeys {
    #[serde(default)]
    components: Components,
    name: Option<String>,
}

impl<'de> Deserialize<'de> for FixedSelection {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let (nodes, k): (NodeSet, FixedKeys) = de_with_node_set(d)?;
        Ok(FixedSelection {
            nodes,
            components: k.components,
            name: k.name,
        })
    }
}

impl FixedSelection {
    /// Whether a rest position is in the set's region.
    pub fn contains(&self, p: [f64; 3]) -> bool {
        self.nodes.contains(p)
    }
}

/// `[[prescribed]]`: a node set moved by a prescribed displacement, in every component or
/// only in `components` (the others move freely: a frictionless plate). Give
/// `displacement` (m, reached linearly over `ramp` seconds, then held) or `velocity`
/// (m/s, from the start).
#[derive(Debug, Clone, PartialEq)]
pub struct Prescribed {
    /// The nodes.
    pub nodes: NodeSet,
    /// The components prescribed (default all).
    pub components: Components,
    /// How they move.
    pub motion: Motion,
    /// Name in the reaction output (default `prescribed<i>`).
    pub name: Option<String>,
}

/// A prescribed motion of a node set, as a displacement from the rest position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Motion {
    /// `u(t) = displacement * min(t / ramp, 1)` (`ramp = 0`: from the first step).
    Displacement {
        /// Final displacement, m.
        displacement: [f64; 3],
        /// Ramp time, s.
        ramp: f64,
    },
    /// `u(t) = velocity * t`.
    Velocity {
        /// Velocity, m/s.
        velocity: [f64; 3],
    },
}

impl Motion {
    /// Displacement at time `t`.
    pub fn displacement(&self, t: f64) -> [f64; 3] {
        match *self {
            Motion::Displacement { displacement, ramp } => {
                let s = if ramp > 0.0 {
                    (t / ramp).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                displacement.map(|u| u * s)
            }
            Motion::Velocity { velocity } => velocity.map(|v| v * t),
        }
    }

    /// Velocity at time `t` (the ramp's slope while it rises).
    pub fn velocity(&self, t: f64) -> [f64; 3] {
        match *self {
            Motion::Displacement { displacement, ramp } => {
                if ramp > 0.0 && t < ramp {
                    displacement.map(|u| u / ramp)
                } else {
                    [0.0; 3]
                }
            }
            Motion::Velocity { velocity } => velocity,
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PrescribedKeys {
    #[serde(default)]
    components: Components,
    displacement: Option<[f64; 3]>,
    velocity: Option<[f64; 3]>,
    #[serde(default)]
    ramp: f64,
    name: Option<String>,
}

impl<'de> Deserialize<'de> for Prescribed {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let (nodes, k): (NodeSet, PrescribedKeys) = de_with_node_set(d)?;
        let motion = match (k.displacement, k.velocity) {
            (Some(displacement), None) => Motion::Displacement {
                displacement,
                ramp: k.ramp,
            },
            (None, Some(velocity)) if k.ramp == 0.0 => Motion::Velocity { velocity },
            (None, Some(_)) => {
                return Err(D::Error::custom(
                    "`ramp` goes with `displacement`, not `velocity`",
                ))
            }
            _ => {
                return Err(D::Error::custom(
                    "give exactly one of `displacement` and `velocity`",
                ))
            }
        };
        Ok(Prescribed {
            nodes,
            components: k.components,
            motion,
            name: k.name,
        })
    }
}

/// `[[load]]`: a surface load on the part of the surface a node set covers (the triangles
/// whose three corners it selects), reached linearly over `ramp` seconds. Give `traction`
/// (a force per area, Pa, in a fixed direction) or `pressure` (Pa, along the inward
/// normal). Each corner takes a third of each loaded triangle's load, on the rest shape
/// (small deformations: the load does not follow the surface as it turns).
#[derive(Debug, Clone, PartialEq)]
pub struct LoadSpec {
    /// The nodes (those on the surface take the load).
    pub nodes: NodeSet,
    /// The load.
    pub load: SurfaceLoad,
    /// Ramp time, s.
    pub ramp: f64,
    /// Name (for errors).
    pub name: Option<String>,
}

/// A load per unit surface area.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SurfaceLoad {
    /// Force per area, Pa.
    Traction([f64; 3]),
    /// Pressure, Pa (positive pushes inward).
    Pressure(f64),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LoadKeys {
    traction: Option<[f64; 3]>,
    pressure: Option<f64>,
    #[serde(default)]
    ramp: f64,
    name: Option<String>,
}

impl<'de> Deserialize<'de> for LoadSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let (nodes, k): (NodeSet, LoadKeys) = de_with_node_set(d)?;
        let load = match (k.traction, k.pressure) {
            (Some(t), None) => SurfaceLoad::Traction(t),
            (None, Some(p)) => SurfaceLoad::Pressure(p),
            _ => {
                return Err(D::Error::custom(
                    "give exactly one of `traction` and `pressure`",
                ))
            }
        };
        Ok(LoadSpec {
            nodes,
            load,
            ramp: k.ramp,
            name: k.name,
        })
    }
}

/// Initial deformation of the rest shape.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Initial {
    /// Scale factors along x, y, z about the centroid of the free nodes' rest positions
    /// (`[1.3, 1, 1]` stretches by 30% along x). Fixed nodes are not moved.
    #[serde(default = "unit_stretch")]
    pub stretch: [f64; 3],
}

fn unit_stretch() -> [f64; 3] {
    [1.0; 3]
}

impl Default for Initial {
    fn default() -> Self {
        Initial {
            stretch: unit_stretch(),
        }
    }
}

/// Run length and output.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
#[serde(try_from = "RunToml")]
pub struct RunSettings {
    /// Steps to run (`steps`, default 1000), unless `duration` is given.
    pub steps: u64,
    /// Simulated seconds to run instead of `steps` (`duration`): [`RunSettings::steps_at`]
    /// turns it into steps with the time step the tissue was built with, so that a
    /// `dt = "auto"` scene runs as long whatever its stiffness.
    pub duration: Option<f64>,
    /// Write a frame (CSV row and surface mesh) every this many steps.
    #[serde(default = "default_output_every")]
    pub output_every: u64,
    /// Write the surface mesh of every frame (VTK XML PolyData plus a .pvd time series).
    #[serde(default = "yes")]
    pub surface_frames: bool,
    /// Largest estimated memory in GiB a scene may need (`max_memory_gib`, default 8):
    /// the node count is estimated from the geometry (and the needle) before anything is
    /// allocated ([`crate::geometry::memory`]), and a scene above it is an error naming
    /// the key that asked for the nodes. Raise it for large runs.
    #[serde(default = "default_max_memory_gib")]
    pub max_memory_gib: f64,
}

/// Default of `run.max_memory_gib`: a fixed 8 GiB (physical memory cannot be asked for
/// portably); raise it in the scene for larger runs.
pub const DEFAULT_MAX_MEMORY_GIB: f64 = 8.0;

fn default_max_memory_gib() -> f64 {
    DEFAULT_MAX_MEMORY_GIB
}

fn default_steps() -> u64 {
    1000
}

/// The `[run]` table as written: `steps` and `duration` both optional, not both given.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RunToml {
    steps: Option<u64>,
    duration: Option<f64>,
    #[serde(default = "default_output_every")]
    output_every: u64,
    #[serde(default = "yes")]
    surface_frames: bool,
    #[serde(default = "default_max_memory_gib")]
    max_memory_gib: f64,
}

impl TryFrom<RunToml> for RunSettings {
    type Error = String;
    fn try_from(r: RunToml) -> Result<RunSettings, String> {
        if r.steps.is_some() && r.duration.is_some() {
            return Err("run: give `steps` or `duration`, not both".into());
        }
        Ok(RunSettings {
            steps: r.steps.unwrap_or_else(default_steps),
            duration: r.duration,
            output_every: r.output_every,
            surface_frames: r.surface_frames,
            max_memory_gib: r.max_memory_gib,
        })
    }
}

/// Most steps `run.duration` may ask for (about 30 years of 1 kHz stepping): more is
/// a unit mistake, not a run.
pub const MAX_RUN_STEPS: f64 = 1e12;

impl RunSettings {
    /// Steps to run with time step `dt` (s): `ceil(duration / dt)` when `duration` is given
    /// (a quotient within 1e-6 of a whole number counts as that number, so 2 s at 1 ms
    /// is 2000 steps even with `dt` rounded to f32), else `steps`.
    pub fn steps_at(&self, dt: f64) -> Result<u64, SceneError> {
        let Some(duration) = self.duration else {
            return Ok(self.steps);
        };
        let n = duration / dt;
        if !(n.is_finite() && n <= MAX_RUN_STEPS) {
            return Err(SceneError::invalid(
                "run.duration",
                format!(
                    "{duration} s at dt = {dt:e} s is {n:e} steps, more than {MAX_RUN_STEPS:e}"
                ),
            ));
        }
        let whole = n.round();
        Ok(if (n - whole).abs() <= 1e-6 * whole.max(1.0) {
            whole as u64
        } else {
            n.ceil() as u64
        })
    }
}
fn default_output_every() -> u64 {
    50
}
fn yes() -> bool {
    true
}

impl Default for RunSettings {
    fn default() -> Self {
        RunSettings {
            steps: default_steps(),
            duration: None,
            output_every: default_output_every(),
            surface_frames: true,
            max_memory_gib: default_max_memory_gib(),
        }
    }
}

/// Deserialises a table whose key `tag` selects the variant; the rest of the table is
/// read by `pick(variant_name, rest)`. Errors name the table, the variant and the key.
fn de_tagged<'de, D, T>(
    d: D,
    table: &str,
    tag: &str,
    pick: impl FnOnce(&str, toml::Value) -> Option<Result<T, toml::de::Error>>,
) -> Result<T, D::Error>
where
    D: serde::Deserializer<'de>,
{
    use serde::de::Error;
    let mut t = toml::Table::deserialize(d)?;
    let name = match t.remove(tag) {
        Some(toml::Value::String(s)) => s,
        Some(other) => {
            return Err(D::Error::custom(format!(
                "`{table}.{tag}` must be a string, got {other}"
            )))
        }
        None => return Err(D::Error::custom(format!("`{table}` needs the key `{tag}`"))),
    };
    match pick(&name, toml::Value::Table(t)) {
        Some(r) => r.map_err(|e| {
            D::Error::custom(format!(
                "`{table}` ({tag} = \"{name}\"): {}",
                e.to_string().trim_end().replace('\n', " ")
            ))
        }),
        None => Err(D::Error::custom(format!(
            "`{table}.{tag}`: unknown variant `{name}`"
        ))),
    }
}

/// A material table with its `model` key, deserialised ([`crate::regions`]).
pub(crate) struct MaterialTable(pub Material);

impl<'de> Deserialize<'de> for MaterialTable {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        de_material(d).map(MaterialTable)
    }
}

fn de_material<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Material, D::Error> {
    de_tagged(d, "material", "model", Material::from_tagged)
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

/// Largest scene file read, bytes (scenes are a few kB).
pub const MAX_SCENE_FILE_BYTES: u64 = 16 << 20;

/// Largest surface file read, bytes (a 10-million-triangle binary STL is 500 MB).
pub const MAX_SURFACE_FILE_BYTES: u64 = 2 << 30;

/// An error naming `key` if `path` is not a regular file or holds more than `max` bytes: a device
/// (`/dev/zero`), a pipe or a folder would be read until memory runs out, or fail later
/// with a less clear message.
pub fn check_input_file(path: &Path, max: u64, key: &str) -> Result<(), SceneError> {
    // A file that cannot be inspected (missing, no permission) is left to its reader,
    // whose error names the file in its own terms.
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(());
    };
    if !meta.is_file() {
        return Err(SceneError::invalid(
            key,
            format!("{} is not a regular file", path.display()),
        ));
    }
    if meta.len() > max {
        return Err(SceneError::invalid(
            key,
            format!(
                "{} holds {} bytes, more than the {max} read",
                path.display(),
                meta.len()
            ),
        ));
    }
    Ok(())
}

impl Scene {
    /// Parses and validates a scene from TOML text. Relative paths resolve against
    /// `base_dir`.
    pub fn from_toml_str(text: &str, base_dir: &Path) -> Result<Scene, SceneError> {
        Self::parse(text, "<string>", base_dir)
    }

    /// Reads, parses and validates a scene file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Scene, SceneError> {
        let path = path.as_ref();
        check_input_file(path, MAX_SCENE_FILE_BYTES, "scene file")?;
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let base = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        Self::parse(&text, &path.display().to_string(), &base)
    }

    fn parse(text: &str, origin: &str, base_dir: &Path) -> Result<Scene, SceneError> {
        let mut scene: Scene = toml::from_str(text).map_err(|e| SceneError::Parse {
            origin: origin.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        scene.base_dir = base_dir.to_path_buf();
        scene.validate()?;
        Ok(scene)
    }

    /// Checks every value's range. Called by the parsers; call it again after editing a
    /// scene in code.
    pub fn validate(&self) -> Result<(), SceneError> {
        let t = &self.tissue;
        positive_finite("tissue.density", t.density)?;
        if !(MIN_NEIGHBOURS..=64).contains(&t.neighbours) {
            return Err(SceneError::invalid(
                "tissue.neighbours",
                format!(
                    "must be between {MIN_NEIGHBOURS} and 64, got {} (fewer neighbours cannot \
                     hold a 3D body together)",
                    t.neighbours
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
        self.material.validate("material")?;
        let p = &self.physics;
        if let TimeStep::Seconds(dt) = p.dt {
            positive_finite("physics.dt", dt)?;
        }
        for g in p.gravity {
            finite("physics.gravity", g)?;
        }
        non_negative_finite("physics.damping", p.damping)?;
        positive_finite("physics.max_speed", p.max_speed)?;
        if p.check_every == 0 {
            return Err(SceneError::invalid(
                "physics.check_every",
                "must be at least 1",
            ));
        }
        for (i, f) in self.fixed.iter().enumerate() {
            f.nodes.validate(&format!("fixed[{i}]"))?;
        }
        for (i, p) in self.prescribed.iter().enumerate() {
            let key = format!("prescribed[{i}]");
            p.nodes.validate(&key)?;
            match p.motion {
                Motion::Displacement { displacement, ramp } => {
                    for u in displacement {
                        finite(&format!("{key}.displacement"), u)?;
                    }
                    non_negative_finite(&format!("{key}.ramp"), ramp)?;
                }
                Motion::Velocity { velocity } => {
                    for v in velocity {
                        finite(&format!("{key}.velocity"), v)?;
                    }
                }
            }
        }
        for (i, l) in self.load.iter().enumerate() {
            let key = format!("load[{i}]");
            l.nodes.validate(&key)?;
            match l.load {
                SurfaceLoad::Traction(t) => {
                    for c in t {
                        finite(&format!("{key}.traction"), c)?;
                    }
                }
                SurfaceLoad::Pressure(p) => finite(&format!("{key}.pressure"), p)?,
            }
            non_negative_finite(&format!("{key}.ramp"), l.ramp)?;
        }
        for s in self.initial.stretch {
            positive_finite("initial.stretch", s)?;
        }
        positive_finite("run.max_memory_gib", self.run.max_memory_gib)?;
        if let Some(d) = self.run.duration {
            positive_finite("run.duration", d)?;
            if let TimeStep::Seconds(dt) = self.physics.dt {
                self.run.steps_at(dt)?;
            }
        }
        if self.run.output_every == 0 {
            return Err(SceneError::invalid(
                "run.output_every",
                "must be at least 1",
            ));
        }
        Ok(())
    }
}
