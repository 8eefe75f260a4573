//! The builder against the TOML parser, and its errors.

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
    let geometry = SurfaceGeometry::new("cap.obj", 0.0047)
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
        .obj(SurfaceGeometry::new("ball.obj", 0.012))
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
            (SceneError::InvalidValue { key: a, .. }, SceneError::InvalidValue { key: b, .. }) => {
                assert!(a == key && b == key, "{key}: {built} / {parsed}")
            }
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
            FixedSelection::new(NodeSet::below(Axis::Y, 0.0)).with_components(Components::of(&[])),
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
