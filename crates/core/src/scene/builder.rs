//! A typed builder for [`Scene`]s, for code that makes scenes (tests, benches, the report)
//! instead of writing TOML. TOML stays the file format: [`SceneBuilder::build`] gives the
//! same [`Scene`] as parsing the equivalent TOML, with the same defaults for every key
//! left out and the same checks ([`Scene::validate`]), so an out-of-range value is the
//! same [`SceneError::InvalidValue`] naming the same dotted key.
//!
//! ```
//! use needlesim_core::scene::{Axis, NodeSet};
//! use needlesim_core::{Material, Scene};
//! let scene = Scene::builder()
//!     .box_with_nodes([0.0; 3], [0.1, 0.1, 0.1], 639)
//!     .material(Material::shape_matching(20.0))
//!     .dt(1e-3)
//!     .gravity([0.0, -9.81, 0.0])
//!     .damping(5.0)
//!     .fixed(NodeSet::below(Axis::X, 0.001))
//!     .build()?;
//! let text = r#"
//!     [tissue]
//!     geometry = { kind = "box", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], nodes = 639 }
//!     [material]
//!     model = "local_shape_matching"
//!     stiffness = 20.0
//!     [physics]
//!     dt = 1e-3
//!     gravity = [0.0, -9.81, 0.0]
//!     damping = 5.0
//!     [[fixed]]
//!     axis = "x"
//!     below = 0.001
//! "#;
//! assert_eq!(scene, Scene::from_toml_str(text, std::path::Path::new("."))?);
//! # Ok::<(), needlesim_core::SceneError>(())
//! ```
//!
//! Two things the TOML parser rejects cannot be said in the builder's types, or are
//! checked by [`SceneBuilder::build`] with an error of its own: a scene without geometry or
//! material ([`SceneError::Parse`] naming the missing key, as a TOML file without them),
//! and a `components` list that holds no axis ([`SceneError::InvalidValue`] naming
//! `fixed[i].components` or `prescribed[i].components`; the parser's error for `[]` is a
//! [`SceneError::Parse`]).

use crate::error::SceneError;
use crate::scene::{
    default_density, Axis, AxisRotation, BackendChoice, BoxGeometry, Components, DebunneParams,
    FixedSelection, Geometry, Initial, LoadSpec, MassSpringParams, Material, Motion, NodeMasses,
    NodeSet, Physics, PointBasedParams, Prescribed, RunSettings, Scene, ShapeMatchingParams,
    SurfaceGeometry, SurfaceLoad, SurfaceNodes, TimeStep, TissueSpec, WeightKernel,
    DEFAULT_NEIGHBOURS,
};
use std::path::PathBuf;

/// Where builder errors say the scene came from ([`SceneError::Parse`]'s `origin`).
pub const BUILDER_ORIGIN: &str = "<builder>";

impl Scene {
    /// A builder with every key at its TOML default; give it at least a geometry and a
    /// material. Relative paths resolve against `.` unless [`SceneBuilder::base_dir`] says
    /// otherwise.
    pub fn builder() -> SceneBuilder {
        SceneBuilder::default()
    }
}

/// Builds a [`Scene`] key by key (see the [module docs](self)). Every method sets one key
/// (or adds one `[[fixed]]`, `[[prescribed]]` or `[[load]]` table) and returns the builder.
#[derive(Debug, Clone)]
pub struct SceneBuilder {
    name: String,
    backend: BackendChoice,
    geometry: Option<Geometry>,
    density: f64,
    neighbours: usize,
    weight: WeightKernel,
    masses: NodeMasses,
    material: Option<Material>,
    physics: Physics,
    fixed: Vec<FixedSelection>,
    prescribed: Vec<Prescribed>,
    load: Vec<LoadSpec>,
    initial: Initial,
    run: RunSettings,
    needle: Option<toml::Table>,
    needle_error: Option<String>,
    base_dir: PathBuf,
}

impl Default for SceneBuilder {
    fn default() -> Self {
        SceneBuilder {
            name: String::new(),
            backend: BackendChoice::default(),
            geometry: None,
            density: default_density(),
            neighbours: DEFAULT_NEIGHBOURS,
            weight: WeightKernel::default(),
            masses: NodeMasses::default(),
            material: None,
            physics: Physics::default(),
            fixed: Vec::new(),
            prescribed: Vec::new(),
            load: Vec::new(),
            initial: Initial::default(),
            run: RunSettings::default(),
            needle: None,
            needle_error: None,
            base_dir: PathBuf::from("."),
        }
    }
}

impl SceneBuilder {
    /// `name`: free text shown by the CLI.
    pub fn name(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }

    /// `backend` (default `cpu-parallel`).
    pub fn backend(mut self, backend: BackendChoice) -> Self {
        self.backend = backend;
        self
    }

    /// The directory relative paths (surface files) resolve against; default `.`.
    pub fn base_dir(mut self, dir: impl Into<PathBuf>) -> Self {
        self.base_dir = dir.into();
        self
    }

    /// `tissue.geometry`, any kind.
    pub fn geometry(mut self, geometry: Geometry) -> Self {
        self.geometry = Some(geometry);
        self
    }

    /// `tissue.geometry = { kind = "box", min, max, nodes }`: a box lattice of about
    /// `nodes` nodes.
    pub fn box_with_nodes(self, min: [f64; 3], max: [f64; 3], nodes: usize) -> Self {
        self.geometry(Geometry::box_with_nodes(min, max, nodes))
    }

    /// `tissue.geometry = { kind = "box", min, max, spacing }`: a box lattice of the given
    /// spacing in metres.
    pub fn box_with_spacing(self, min: [f64; 3], max: [f64; 3], spacing: f64) -> Self {
        self.geometry(Geometry::box_with_spacing(min, max, spacing))
    }

    /// `tissue.geometry = { kind = "obj", .. }`: a Wavefront OBJ surface filled with nodes.
    pub fn obj(self, surface: SurfaceGeometry) -> Self {
        self.geometry(Geometry::Obj(surface))
    }

    /// `tissue.density` in kg/m^3 (default 1000).
    pub fn density(mut self, density: f64) -> Self {
        self.density = density;
        self
    }

    /// `tissue.neighbours`: neighbour slots per node (default [`DEFAULT_NEIGHBOURS`]).
    pub fn neighbours(mut self, neighbours: usize) -> Self {
        self.neighbours = neighbours;
        self
    }

    /// `tissue.weight`: the weight kernel of a neighbour pair (default poly6, support 2).
    pub fn weight(mut self, weight: WeightKernel) -> Self {
        self.weight = weight;
        self
    }

    /// `tissue.masses`: how the mass is shared by the nodes (default `cell`).
    pub fn masses(mut self, masses: NodeMasses) -> Self {
        self.masses = masses;
        self
    }

    /// `[material]`: the tissue model and its parameters.
    pub fn material(mut self, material: Material) -> Self {
        self.material = Some(material);
        self
    }

    /// `physics.dt` in seconds (default 1e-3).
    pub fn dt(self, seconds: f64) -> Self {
        self.time_step(TimeStep::Seconds(seconds))
    }

    /// `physics.dt = "auto"`.
    pub fn dt_auto(self) -> Self {
        self.time_step(TimeStep::Auto)
    }

    /// `physics.dt`, either form.
    pub fn time_step(mut self, dt: TimeStep) -> Self {
        self.physics.dt = dt;
        self
    }

    /// `physics.gravity` in m/s^2 (default none).
    pub fn gravity(mut self, gravity: [f64; 3]) -> Self {
        self.physics.gravity = gravity;
        self
    }

    /// `physics.damping`: mass-proportional velocity damping in 1/s (default 0).
    pub fn damping(mut self, damping: f64) -> Self {
        self.physics.damping = damping;
        self
    }

    /// `physics.max_speed`: the divergence guard's speed in m/s (default 100).
    pub fn max_speed(mut self, max_speed: f64) -> Self {
        self.physics.max_speed = max_speed;
        self
    }

    /// `physics.check_every`: steps between divergence checks of a needle simulation
    /// (default 100).
    pub fn check_every(mut self, steps: u64) -> Self {
        self.physics.check_every = steps;
        self
    }

    /// Adds a `[[fixed]]` table: a node set held at rest (a bare [`NodeSet`] holds all
    /// three components).
    pub fn fixed(mut self, fixed: impl Into<FixedSelection>) -> Self {
        self.fixed.push(fixed.into());
        self
    }

    /// Adds a `[[prescribed]]` table: a node set moved by a prescribed motion.
    pub fn prescribed(mut self, prescribed: Prescribed) -> Self {
        self.prescribed.push(prescribed);
        self
    }

    /// Adds a `[[load]]` table: a surface load.
    pub fn load(mut self, load: LoadSpec) -> Self {
        self.load.push(load);
        self
    }

    /// `initial.stretch`: scale factors along x, y, z of the initial shape (default
    /// `[1, 1, 1]`).
    pub fn stretch(mut self, stretch: [f64; 3]) -> Self {
        self.initial.stretch = stretch;
        self
    }

    /// `run.steps` (default 1000); clears `run.duration`.
    pub fn steps(mut self, steps: u64) -> Self {
        self.run.steps = steps;
        self.run.duration = None;
        self
    }

    /// `run.duration`, simulated seconds to run instead of `run.steps`
    /// ([`crate::scene::RunSettings::steps_at`]).
    pub fn duration(mut self, seconds: f64) -> Self {
        self.run.duration = Some(seconds);
        self
    }

    /// `run.output_every` (default 50).
    pub fn output_every(mut self, steps: u64) -> Self {
        self.run.output_every = steps;
        self
    }

    /// `run.surface_frames` (default true).
    pub fn surface_frames(mut self, write: bool) -> Self {
        self.run.surface_frames = write;
        self
    }

    /// `run.max_memory_gib` (default 8).
    pub fn max_memory_gib(mut self, gib: f64) -> Self {
        self.run.max_memory_gib = gib;
        self
    }

    /// `[needle]`, as the TOML table `needlesim-needle` reads (this crate knows nothing of
    /// the needle).
    pub fn needle(mut self, table: toml::Table) -> Self {
        self.needle = Some(table);
        self.needle_error = None;
        self
    }

    /// `[needle]` from the TOML text of its table body (keyframes as `[[keyframe]]`). A
    /// syntax error is reported by [`Self::build`] as a [`SceneError::Parse`] naming
    /// `needle`.
    pub fn needle_toml(mut self, text: &str) -> Self {
        match text.parse::<toml::Table>() {
            Ok(t) => {
                self.needle = Some(t);
                self.needle_error = None;
            }
            Err(e) => {
                self.needle = None;
                self.needle_error = Some(e.to_string().trim_end().replace('\n', " "));
            }
        }
        self
    }

    /// The scene, checked by [`Scene::validate`] as a parsed one is.
    ///
    /// # Errors
    ///
    /// [`SceneError::Parse`] (origin [`BUILDER_ORIGIN`]) without a geometry or a material,
    /// or when the [`Self::needle_toml`] text did not parse; [`SceneError::InvalidValue`]
    /// naming the dotted key of a value out of range, or of an empty `components` list.
    pub fn build(self) -> Result<Scene, SceneError> {
        let parse = |message: String| SceneError::Parse {
            origin: BUILDER_ORIGIN.to_string(),
            message,
        };
        if let Some(e) = self.needle_error {
            return Err(parse(format!("`needle`: {e}")));
        }
        let geometry = self
            .geometry
            .ok_or_else(|| parse("missing field `tissue.geometry`".into()))?;
        let material = self
            .material
            .ok_or_else(|| parse("missing field `material`".into()))?;
        let empty = |c: &Components| c.0 == [false; 3];
        for (i, f) in self.fixed.iter().enumerate() {
            if empty(&f.components) {
                return Err(SceneError::invalid(
                    format!("fixed[{i}].components"),
                    "is empty: list the axes held",
                ));
            }
        }
        for (i, p) in self.prescribed.iter().enumerate() {
            if empty(&p.components) {
                return Err(SceneError::invalid(
                    format!("prescribed[{i}].components"),
                    "is empty: list the axes prescribed",
                ));
            }
        }
        let scene = Scene {
            name: self.name,
            backend: self.backend,
            tissue: TissueSpec {
                geometry,
                density: self.density,
                neighbours: self.neighbours,
                weight: self.weight,
                masses: self.masses,
            },
            material,
            physics: self.physics,
            fixed: self.fixed,
            prescribed: self.prescribed,
            load: self.load,
            region: Vec::new(),
            initial: self.initial,
            run: self.run,
            needle: self.needle,
            base_dir: self.base_dir,
        };
        scene.validate()?;
        Ok(scene)
    }
}

impl Geometry {
    /// `{ kind = "box", min, max, nodes }`.
    pub const fn box_with_nodes(min: [f64; 3], max: [f64; 3], nodes: usize) -> Geometry {
        Geometry::Box(BoxGeometry {
            min,
            max,
            spacing: None,
            nodes: Some(nodes),
        })
    }

    /// `{ kind = "box", min, max, spacing }`.
    pub const fn box_with_spacing(min: [f64; 3], max: [f64; 3], spacing: f64) -> Geometry {
        Geometry::Box(BoxGeometry {
            min,
            max,
            spacing: Some(spacing),
            nodes: None,
        })
    }
}

impl SurfaceGeometry {
    /// A surface file at `path` (relative to the scene's base directory) filled at
    /// `spacing` metres, the other keys at their defaults: `scale = 1`, resampled surface,
    /// no rotation or translation. Wrap it in [`Geometry::Obj`], [`Geometry::Stl`] or
    /// [`Geometry::Vtk`] by the file's format.
    pub fn new(path: impl Into<PathBuf>, spacing: f64) -> SurfaceGeometry {
        SurfaceGeometry {
            path: path.into(),
            spacing,
            scale: 1.0,
            surface: SurfaceNodes::default(),
            rotate: None,
            translate: [0.0; 3],
        }
    }

    /// `scale`: factor applied to the file's coordinates.
    pub fn with_scale(mut self, scale: f64) -> Self {
        self.scale = scale;
        self
    }

    /// `surface`: where the surface nodes come from.
    pub fn with_surface(mut self, surface: SurfaceNodes) -> Self {
        self.surface = surface;
        self
    }

    /// `rotate = { axis, degrees }`, applied after `scale`.
    pub fn with_rotate(mut self, axis: [f64; 3], degrees: f64) -> Self {
        self.rotate = Some(AxisRotation { axis, degrees });
        self
    }

    /// `translate` in metres, applied last.
    pub fn with_translate(mut self, translate: [f64; 3]) -> Self {
        self.translate = translate;
        self
    }
}

impl NodeSet {
    /// `axis` with `below`: every node at or below `value` along `axis`.
    pub const fn below(axis: Axis, value: f64) -> NodeSet {
        NodeSet::Plane {
            axis,
            below: Some(value),
            above: None,
        }
    }

    /// `axis` with `above`: every node at or above `value` along `axis`.
    pub const fn above(axis: Axis, value: f64) -> NodeSet {
        NodeSet::Plane {
            axis,
            below: None,
            above: Some(value),
        }
    }

    /// `box = { min, max }`: every node inside the box, faces included.
    pub const fn in_box(min: [f64; 3], max: [f64; 3]) -> NodeSet {
        NodeSet::Box { min, max }
    }

    /// `sphere = { centre, radius }`: every node within `radius` of `centre`.
    pub const fn sphere(centre: [f64; 3], radius: f64) -> NodeSet {
        NodeSet::Sphere { centre, radius }
    }

    /// `points = [..]`: the node nearest to each point.
    pub fn points(points: impl Into<Vec<[f64; 3]>>) -> NodeSet {
        NodeSet::Points(points.into())
    }
}

impl Components {
    /// The listed axes (`components = ["y"]` is `Components::of(&[Axis::Y])`); a repeated
    /// axis counts once.
    pub const fn of(axes: &[Axis]) -> Components {
        let mut c = [false; 3];
        let mut i = 0;
        while i < axes.len() {
            let a = match axes[i] {
                Axis::X => 0,
                Axis::Y => 1,
                Axis::Z => 2,
            };
            c[a] = true;
            i += 1;
        }
        Components(c)
    }
}

impl FixedSelection {
    /// The node set held in all three components, unnamed.
    pub fn new(nodes: NodeSet) -> FixedSelection {
        FixedSelection {
            nodes,
            components: Components::default(),
            name: None,
            far_field: None,
        }
    }

    /// `far_field = { distance }`: a cut face supported by the tissue beyond it, `distance`
    /// m from the loads inside ([`crate::boundary`]).
    pub fn with_far_field(mut self, distance: f64) -> Self {
        self.far_field = Some(crate::scene::FarFieldSpec { distance });
        self
    }

    /// `components`: hold only these.
    pub fn with_components(mut self, components: Components) -> Self {
        self.components = components;
        self
    }

    /// `name` in the reaction output.
    pub fn with_name(mut self, name: impl Into<String>) -> Self {
        self.name = Some(name.into());
        self
    }
}

impl From<NodeSet> for FixedSelection {
    fn from(nodes: NodeSet) -> FixedSelection {
        FixedSelection::new(nodes)
    }
}

impl Prescribed {
    /// `displacement` in metres reached linearly over `ramp` seconds, all components.
    pub fn displacement(nodes: NodeSet, displacement: [f64; 3], ramp: f64) -> Prescribed {
        Prescribed {
            nodes,
            components: Components::default(),
            motion: Motion::Displacement { displacement, ramp },
            name: None,
        }
    }

    /// `velocity` in m/s from the start, all components.
    pub fn velocity(nodes: NodeSet, velocity: [f64; 3]) -> Prescribed {
        Prescribed {
            nodes,
            components: Components::default(),
            motion: Motion::Velocity { velocity },
            name: None,
        }
    }

    /// `components`: prescribe only these.
    pub fn with_components(mut self, components: Components) -> Self {
        self.components = components;
        self
    }

    /// `name` in the reaction output.
    pub fn with_name(mut self, name: impl Into<String>) -> Self {
        self.name = Some(name.into());
        self
    }
}

impl LoadSpec {
    /// `pressure` in Pa along the inward normal, no ramp.
    pub fn pressure(nodes: NodeSet, pressure: f64) -> LoadSpec {
        LoadSpec {
            nodes,
            load: SurfaceLoad::Pressure(pressure),
            ramp: 0.0,
            name: None,
        }
    }

    /// `traction` in Pa in a fixed direction, no ramp.
    pub fn traction(nodes: NodeSet, traction: [f64; 3]) -> LoadSpec {
        LoadSpec {
            nodes,
            load: SurfaceLoad::Traction(traction),
            ramp: 0.0,
            name: None,
        }
    }

    /// `ramp`: seconds over which the load rises linearly.
    pub fn with_ramp(mut self, ramp: f64) -> Self {
        self.ramp = ramp;
        self
    }

    /// `name` (for errors).
    pub fn with_name(mut self, name: impl Into<String>) -> Self {
        self.name = Some(name.into());
        self
    }
}

impl Material {
    /// `model = "mass_spring"` with spring `stiffness` in N/m, the other keys at their
    /// defaults ([`MassSpringParams::new`]).
    pub const fn mass_spring(stiffness: f64) -> Material {
        Material::MassSpring(MassSpringParams::new(stiffness))
    }

    /// `model = "local_shape_matching"` with restoring `stiffness` in N/m, the other keys
    /// at their defaults ([`ShapeMatchingParams::new`]).
    pub const fn shape_matching(stiffness: f64) -> Material {
        Material::LocalShapeMatching(ShapeMatchingParams::new(stiffness))
    }

    /// `model = "debunne_meshfree"` with Young's modulus in Pa and the Poisson ratio, the
    /// other keys at their defaults ([`DebunneParams::new`]).
    pub const fn debunne(young_modulus: f64, poisson_ratio: f64) -> Material {
        Material::DebunneMeshfree(DebunneParams::new(young_modulus, poisson_ratio))
    }

    /// `model = "point_based"` with Young's modulus in Pa and the Poisson ratio, the other
    /// keys at their defaults ([`PointBasedParams::new`]).
    pub const fn point_based(young_modulus: f64, poisson_ratio: f64) -> Material {
        Material::PointBased(PointBasedParams::new(young_modulus, poisson_ratio))
    }
}

#[cfg(test)]
mod tests;
