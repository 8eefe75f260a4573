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
    NodeSet, ObjGeometry, Physics, PointBasedParams, Prescribed, RunSettings, Scene,
    ShapeMatchingParams, SurfaceLoad, SurfaceNodes, TimeStep, Tissue, WeightKernel,
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
    pub fn obj(self, surface: ObjGeometry) -> Self {
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
            tissue: Tissue {
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

impl ObjGeometry {
    /// A surface file at `path` (relative to the scene's base directory) filled at
    /// `spacing` metres, the other keys at their defaults: `scale = 1`, resampled surface,
    /// no rotation or translation. Wrap it in [`Geometry::Obj`], [`Geometry::Stl`] or
    /// [`Geometry::Vtk`] by the file's format.
    pub fn new(path: impl Into<PathBuf>, spacing: f64) -> ObjGeometry {
        ObjGeometry {
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
        }
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
mod tests {
    use super::*;
    use crate::scene::{NodeVolumes, ShapeMatchingForces, SpringShare};
    use std::path::Path;

    fn parse(text: &str) -> Scene {
        Scene::from_toml_str(text, Path::new(".")).unwrap()
    }

    const CUBE: &str =
        "[tissue]\ngeometry = { kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], nodes = 639 }\n";

    fn cube() -> SceneBuilder {
        Scene::builder().box_with_nodes([0.0; 3], [0.1; 3], 639)
    }

    /// Only the required keys: every default is the parser's, for each model.
    #[test]
    fn defaults_are_the_parsers() {
        for (material, table) in [
            (
                Material::mass_spring(100.0),
                "model = \"mass_spring\"\nstiffness = 100.0",
            ),
            (
                Material::shape_matching(20.0),
                "model = \"local_shape_matching\"\nstiffness = 20.0",
            ),
            (
                Material::debunne(1e4, 0.3),
                "model = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3",
            ),
            (
                Material::point_based(1e4, 0.45),
                "model = \"point_based\"\nyoung_modulus = 1e4\npoisson_ratio = 0.45",
            ),
        ] {
            let built = cube().material(material).build().unwrap();
            assert_eq!(
                built,
                parse(&format!("{CUBE}[material]\n{table}\n")),
                "{table}"
            );
        }
    }

    /// Every material parameter set away from its default.
    #[test]
    fn material_setters_match_their_keys() {
        for (material, table) in [
            (
                Material::MassSpring(MassSpringParams::new(1e3)
                    .with_spring_damping(0.01)
                    .with_spring_share(SpringShare::Equal)),
                "model = \"mass_spring\"\nstiffness = 1e3\nspring_damping = 0.01\nspring_share = \"equal\"",
            ),
            (
                Material::LocalShapeMatching(ShapeMatchingParams::new(2e4)
                    .with_forces(ShapeMatchingForces::Cluster)
                    .with_rotation_iterations(5)),
                "model = \"local_shape_matching\"\nstiffness = 2e4\nforces = \"cluster\"\nrotation_iterations = 5",
            ),
            (
                Material::DebunneMeshfree(DebunneParams::new(1e7, 0.3)
                    .with_corotated(true)
                    .with_rotation_iterations(3)
                    .with_hourglass(0.05)
                    .with_node_volumes(NodeVolumes::Uniform)),
                "model = \"debunne_meshfree\"\nyoung_modulus = 1e7\npoisson_ratio = 0.3\ncorotated = true\n\
                 rotation_iterations = 3\nhourglass = 0.05\nnode_volumes = \"uniform\"",
            ),
            (
                Material::PointBased(PointBasedParams::new(1e4, 0.3)
                    .with_volume_stiffness(1e4)
                    .with_hourglass(0.0)
                    .with_node_volumes(NodeVolumes::Density)),
                "model = \"point_based\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3\nvolume_stiffness = 1e4\n\
                 hourglass = 0.0\nnode_volumes = \"density\"",
            ),
        ] {
            let built = cube().material(material).build().unwrap();
            assert_eq!(built, parse(&format!("{CUBE}[material]\n{table}\n")), "{table}");
        }
    }

    /// Every other key, with boundary tables of every kind and a needle.
    #[test]
    fn a_full_scene_matches_its_toml() {
        let built = Scene::builder()
            .name("full")
            .backend(BackendChoice::Cpu)
            .box_with_spacing([0.0; 3], [0.2, 0.1, 0.1], 0.0125)
            .density(1070.0)
            .neighbours(16)
            .weight(WeightKernel::Uniform)
            .masses(NodeMasses::Uniform)
            .material(Material::debunne(1e4, 0.3))
            .dt_auto()
            .gravity([0.0, -9.81, 0.0])
            .damping(120.0)
            .max_speed(50.0)
            .check_every(10)
            .fixed(
                FixedSelection::new(NodeSet::below(Axis::Y, 0.001))
                    .with_components(Components::of(&[Axis::Y]))
                    .with_name("floor"),
            )
            .fixed(NodeSet::in_box([0.0; 3], [0.01, 0.1, 0.1]))
            .prescribed(
                Prescribed::displacement(NodeSet::above(Axis::Y, 0.099), [0.0, -0.001, 0.0], 0.02)
                    .with_components(Components::of(&[Axis::Y, Axis::X]))
                    .with_name("plate"),
            )
            .prescribed(Prescribed::velocity(
                NodeSet::points(vec![[0.2, 0.05, 0.05]]),
                [0.1, 0.0, 0.0],
            ))
            .load(
                LoadSpec::pressure(NodeSet::sphere([0.1, 0.05, 0.05], 1.0), 20.0)
                    .with_ramp(0.1)
                    .with_name("all"),
            )
            .load(LoadSpec::traction(
                NodeSet::above(Axis::X, 0.199),
                [1.0, 0.0, 0.0],
            ))
            .stretch([1.3, 1.0, 1.0])
            .steps(5000)
            .output_every(10)
            .surface_frames(false)
            .max_memory_gib(2.0)
            .needle_toml(
                "base = [-0.105, 0.05, 0.05]\ndirection = [1.0, 0.0, 0.0]\nlength = 0.1\n\
                 [[keyframe]]\naction = \"pause\"\nduration = 1.0\n",
            )
            .build()
            .unwrap();
        let text = r#"
            name = "full"
            backend = "cpu"
            [tissue]
            geometry = { kind = "box", min = [0.0, 0.0, 0.0], max = [0.2, 0.1, 0.1], spacing = 0.0125 }
            density = 1070.0
            neighbours = 16
            weight = { kernel = "uniform" }
            masses = "uniform"
            [material]
            model = "debunne_meshfree"
            young_modulus = 1e4
            poisson_ratio = 0.3
            [physics]
            dt = "auto"
            gravity = [0.0, -9.81, 0.0]
            damping = 120.0
            max_speed = 50.0
            check_every = 10
            [[fixed]]
            name = "floor"
            axis = "y"
            below = 0.001
            components = ["y"]
            [[fixed]]
            box = { min = [0.0, 0.0, 0.0], max = [0.01, 0.1, 0.1] }
            [[prescribed]]
            name = "plate"
            axis = "y"
            above = 0.099
            components = ["x", "y"]
            displacement = [0.0, -0.001, 0.0]
            ramp = 0.02
            [[prescribed]]
            points = [[0.2, 0.05, 0.05]]
            velocity = [0.1, 0.0, 0.0]
            [[load]]
            name = "all"
            sphere = { centre = [0.1, 0.05, 0.05], radius = 1.0 }
            pressure = 20.0
            ramp = 0.1
            [[load]]
            axis = "x"
            above = 0.199
            traction = [1.0, 0.0, 0.0]
            [initial]
            stretch = [1.3, 1.0, 1.0]
            [run]
            steps = 5000
            output_every = 10
            surface_frames = false
            max_memory_gib = 2.0
            [needle]
            base = [-0.105, 0.05, 0.05]
            direction = [1.0, 0.0, 0.0]
            length = 0.1
            [[needle.keyframe]]
            action = "pause"
            duration = 1.0
        "#;
        assert_eq!(built, parse(text));
    }

    /// Surface-file geometry with every transform, relative to a base directory (the file
    /// is only read when the tissue is built).
    #[test]
    fn surface_geometry_matches_its_toml() {
        let geometry = ObjGeometry::new("cap.obj", 0.0047)
            .with_scale(0.001)
            .with_surface(SurfaceNodes::Vertices)
            .with_rotate([0.0, 0.0, 2.0], 90.0)
            .with_translate([0.5, -0.25, 1.0]);
        let table = "path = \"cap.obj\", spacing = 0.0047, scale = 0.001, surface = \"vertices\", \
                     rotate = { axis = [0.0, 0.0, 2.0], degrees = 90.0 }, translate = [0.5, -0.25, 1.0]";
        for (kind, g) in [
            ("obj", Geometry::Obj(geometry.clone())),
            ("stl", Geometry::Stl(geometry.clone())),
            ("vtk", Geometry::Vtk(geometry.clone())),
        ] {
            let built = Scene::builder()
                .geometry(g)
                .material(Material::point_based(1e4, 0.3))
                .base_dir("meshes")
                .build()
                .unwrap();
            let text = format!(
                "[tissue]\ngeometry = {{ kind = \"{kind}\", {table} }}\n[material]\n\
                 model = \"point_based\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3\n"
            );
            assert_eq!(
                built,
                Scene::from_toml_str(&text, Path::new("meshes")).unwrap()
            );
        }
        let plain = Scene::builder()
            .obj(ObjGeometry::new("ball.obj", 0.012))
            .material(Material::mass_spring(1.0))
            .build()
            .unwrap();
        assert_eq!(
            plain,
            parse(
                "[tissue]\ngeometry = { kind = \"obj\", path = \"ball.obj\", spacing = 0.012 }\n\
                 [material]\nmodel = \"mass_spring\"\nstiffness = 1.0\n"
            )
        );
    }

    /// An out-of-range value is the same typed error, naming the same key, whichever way
    /// the scene is made.
    #[test]
    fn invalid_values_give_the_parsers_error() {
        let deb =
            "[material]\nmodel = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3\n";
        let cases: Vec<(SceneBuilder, String, &str)> = vec![
            (
                cube().density(-1.0).material(Material::debunne(1e4, 0.3)),
                format!("{CUBE}density = -1.0\n{deb}"),
                "tissue.density",
            ),
            (
                cube().neighbours(3).material(Material::debunne(1e4, 0.3)),
                format!("{CUBE}neighbours = 3\n{deb}"),
                "tissue.neighbours",
            ),
            (
                cube().material(Material::point_based(1e4, 0.5)),
                format!(
                    "{CUBE}[material]\nmodel = \"point_based\"\nyoung_modulus = 1e4\npoisson_ratio = 0.5\n"
                ),
                "material.poisson_ratio",
            ),
            (
                cube().material(Material::LocalShapeMatching(ShapeMatchingParams::new(20.0).with_rotation_iterations(0))),
                format!(
                    "{CUBE}[material]\nmodel = \"local_shape_matching\"\nstiffness = 20.0\nrotation_iterations = 0\n"
                ),
                "material.rotation_iterations",
            ),
            (
                cube().material(Material::debunne(1e4, 0.3)).dt(0.0),
                format!("{CUBE}{deb}[physics]\ndt = 0.0\n"),
                "physics.dt",
            ),
            (
                Scene::builder()
                    .box_with_spacing([0.0; 3], [0.1; 3], 0.2)
                    .material(Material::debunne(1e4, 0.3)),
                format!(
                    "[tissue]\ngeometry = {{ kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], spacing = 0.2 }}\n{deb}"
                ),
                "tissue.geometry.spacing",
            ),
            (
                cube()
                    .material(Material::debunne(1e4, 0.3))
                    .fixed(NodeSet::below(Axis::X, 0.001))
                    .fixed(NodeSet::in_box([0.0; 3], [0.1, -0.1, 0.1])),
                format!(
                    "{CUBE}{deb}[[fixed]]\naxis = \"x\"\nbelow = 0.001\n[[fixed]]\nbox = {{ min = [0.0, 0.0, 0.0], max = [0.1, -0.1, 0.1] }}\n"
                ),
                "fixed[1].box.max",
            ),
            (
                cube()
                    .material(Material::debunne(1e4, 0.3))
                    .load(LoadSpec::pressure(NodeSet::sphere([0.0; 3], 1.0), f64::INFINITY)),
                format!(
                    "{CUBE}{deb}[[load]]\nsphere = {{ centre = [0.0, 0.0, 0.0], radius = 1.0 }}\npressure = inf\n"
                ),
                "load[0].pressure",
            ),
            (
                cube().material(Material::debunne(1e4, 0.3)).output_every(0),
                format!("{CUBE}{deb}[run]\noutput_every = 0\n"),
                "run.output_every",
            ),
            (
                cube().material(Material::debunne(1e4, 0.3)).duration(-1.0),
                format!("{CUBE}{deb}[run]\nduration = -1.0\n"),
                "run.duration",
            ),
            (
                cube()
                    .material(Material::debunne(1e4, 0.3))
                    .dt(1e-6)
                    .duration(1e9),
                format!("{CUBE}{deb}[physics]\ndt = 1e-6\n[run]\nduration = 1e9\n"),
                "run.duration",
            ),
        ];
        for (builder, text, key) in cases {
            let built = builder.build().unwrap_err();
            let parsed = Scene::from_toml_str(&text, Path::new(".")).unwrap_err();
            match (&built, &parsed) {
                (
                    SceneError::InvalidValue { key: a, .. },
                    SceneError::InvalidValue { key: b, .. },
                ) => assert!(a == key && b == key, "{key}: {built} / {parsed}"),
                _ => panic!("{key}: {built:?} / {parsed:?}"),
            }
            assert_eq!(built.to_string(), parsed.to_string());
        }
    }

    /// `run.duration` runs `ceil(duration / dt)` steps (a whole quotient stays whole even
    /// with dt rounded to f32, as the tissue holds it); giving both `steps` and `duration`
    /// is an error naming the table.
    #[test]
    fn run_duration_counts_steps_from_the_time_step() {
        let deb =
            "[material]\nmodel = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3\n";
        let text = format!("{CUBE}{deb}[run]\nduration = 2.0\n");
        let scene = Scene::from_toml_str(&text, Path::new(".")).unwrap();
        assert_eq!(scene.run.duration, Some(2.0));
        assert_eq!(scene.run.steps_at(1e-3).unwrap(), 2000);
        assert_eq!(scene.run.steps_at(1e-3f32 as f64).unwrap(), 2000);
        assert_eq!(scene.run.steps_at(3e-3).unwrap(), 667);
        assert_eq!(scene.run.steps_at(0.7).unwrap(), 3);
        assert!(scene.run.steps_at(0.0).is_err());
        // Without duration, the steps.
        let plain = Scene::from_toml_str(&format!("{CUBE}{deb}[run]\nsteps = 7\n"), Path::new("."));
        assert_eq!(plain.unwrap().run.steps_at(1e-3).unwrap(), 7);
        let both = format!("{CUBE}{deb}[run]\nsteps = 10\nduration = 2.0\n");
        let e = Scene::from_toml_str(&both, Path::new("."))
            .unwrap_err()
            .to_string();
        assert!(e.contains("`steps` or `duration`, not both"), "{e}");
        let built = cube()
            .material(Material::debunne(1e4, 0.3))
            .duration(0.5)
            .build()
            .unwrap();
        assert_eq!(built.run.steps_at(1e-3).unwrap(), 500);
    }

    /// What the types cannot rule out: a missing geometry or material, an empty component
    /// list, a needle table that does not parse.
    #[test]
    fn missing_and_empty_keys_are_errors_naming_them() {
        let e = Scene::builder()
            .material(Material::mass_spring(1.0))
            .build()
            .unwrap_err();
        assert!(
            matches!(&e, SceneError::Parse { message, .. } if message.contains("tissue.geometry")),
            "{e}"
        );
        let e = cube().build().unwrap_err();
        assert!(
            matches!(&e, SceneError::Parse { message, .. } if message.contains("material")),
            "{e}"
        );
        let e = cube()
            .material(Material::mass_spring(1.0))
            .fixed(
                FixedSelection::new(NodeSet::below(Axis::Y, 0.0))
                    .with_components(Components::of(&[])),
            )
            .build()
            .unwrap_err();
        assert!(
            matches!(&e, SceneError::InvalidValue { key, .. } if key == "fixed[0].components"),
            "{e}"
        );
        let e = cube()
            .material(Material::mass_spring(1.0))
            .needle_toml("base = [")
            .build()
            .unwrap_err();
        assert!(
            matches!(&e, SceneError::Parse { message, .. } if message.contains("needle")),
            "{e}"
        );
    }

    /// The constructors and setters are `const`: tables of materials can be constants.
    #[test]
    fn materials_can_be_constants() {
        const MODELS: [Material; 2] = [
            Material::LocalShapeMatching(
                ShapeMatchingParams::new(20.0).with_forces(ShapeMatchingForces::Cluster),
            ),
            Material::DebunneMeshfree(DebunneParams::new(1e4, 0.3).with_corotated(true)),
        ];
        assert!(matches!(
            MODELS[1],
            Material::DebunneMeshfree(DebunneParams {
                corotated: true,
                ..
            })
        ));
    }
}
