//! Boundary conditions written as scenes: rollers, prescribed displacements, surface loads,
//! far-field faces and the reactions of held sets, against linear elasticity and the
//! far-field faces' own closed forms.

mod common;

use common::mean_strain;
use needlesim::core::scene::{Axis, Components, FixedSelection, LoadSpec, NodeSet, Prescribed};
use needlesim::core::NodeField;
use needlesim::needle::Simulation;
use needlesim::{make_backend, Material, Scene};
use std::path::Path;

fn run(scene: &Scene, seconds: f64) -> Simulation {
    let prep = Simulation::prepare(scene).unwrap();
    let (backend, _) = make_backend(scene, prep.tissue.clone(), None, None).unwrap();
    let mut sim = prep.start(backend).unwrap();
    let steps = (seconds / sim.dt()).ceil() as u64;
    sim.step_n(steps).unwrap();
    sim
}

/// The shipped compression scene, with Debunne and with point based animation: the top
/// plate's reaction is `E eps A` within 1% and the lateral strain `nu eps` within 2%
/// (linear elasticity; the report's stretch case measures 0.2% for both models at 729
/// nodes; these margins leave room for the scene's fixed run length, which settles to
/// about 0.1%). The bottom roller carries the same force the other way, and holds no
/// sideways force.
#[test]
fn compression_between_frictionless_plates_gives_e_and_nu() {
    let base = Scene::from_file(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cube_compression_deb.toml"),
    )
    .unwrap();
    let (e, nu, eps, area) = (1e4, 0.3, -0.002, 0.01);
    for model in ["debunne_meshfree", "point_based"] {
        let mut scene = base.clone();
        if model == "point_based" {
            scene.material = Material::point_based(e, nu);
        }
        let mut sim = run(&scene, 0.8);
        let r = sim.reactions().unwrap();
        let (bottom, top) = (&r[0], &r[1]);
        assert_eq!((bottom.name.as_str(), top.name.as_str()), ("bottom", "top"));
        let want = e * eps * area; // -0.2 N: the top plate pushes down
        eprintln!(
            "{model}: top {:?} bottom {:?} N, want {want}",
            top.force, bottom.force
        );
        assert!(
            (top.force[1] / want - 1.0).abs() < 0.01,
            "{model}: top {:?}",
            top.force
        );
        assert!(
            (bottom.force[1] / -want - 1.0).abs() < 0.01,
            "{model}: bottom {:?}",
            bottom.force
        );
        assert_eq!(
            [top.force[0], top.force[2], bottom.force[0], bottom.force[2]],
            [0.0; 4]
        );
        let (ex, ey, ez) = (
            mean_strain(&mut sim, 0),
            mean_strain(&mut sim, 1),
            mean_strain(&mut sim, 2),
        );
        eprintln!("{model}: strains {ex:e} {ey:e} {ez:e}");
        assert!((ey / eps - 1.0).abs() < 0.01, "{model}: axial strain {ey}");
        for lateral in [ex, ez] {
            assert!(
                (lateral / (-nu * eps) - 1.0).abs() < 0.02,
                "{model}: lateral strain {lateral}"
            );
        }
    }
}

/// A pressure on the top face of a block standing on a roller floor, against the same
/// block pushed by a plate: the floor's reaction balances the pressure times the face's
/// area (within 0.5%, settle tolerance), and the block shortens by `p / E` (uniaxial
/// stress, 2%).
#[test]
fn a_pressure_on_the_top_is_carried_by_the_floor() {
    let scene = Scene::builder()
        .box_with_spacing([0.0; 3], [0.1; 3], 0.0125)
        .material(Material::debunne(1e4, 0.3))
        .dt_auto()
        .damping(120.0)
        .fixed(
            FixedSelection::new(NodeSet::below(Axis::Y, 0.001))
                .with_components(Components::of(&[Axis::Y])),
        )
        .load(
            LoadSpec::pressure(NodeSet::in_box([-1.0, 0.099, -1.0], [1.0; 3]), 20.0).with_ramp(0.1),
        )
        .build()
        .unwrap();
    let mut sim = run(&scene, 0.8);
    let r = sim.reactions().unwrap();
    let want = 20.0 * 0.01;
    assert!(
        (r[0].force[1] / want - 1.0).abs() < 0.005,
        "floor {:?}",
        r[0].force
    );
    let ey = mean_strain(&mut sim, 1);
    assert!((ey / (-20.0 / 1e4) - 1.0).abs() < 0.02, "axial strain {ey}");
}

/// Bad boundary tables get an error naming the table: a set that selects nothing, a
/// displacement on a node held at rest, a load off the surface, two node sets at once,
/// an empty component list.
#[test]
fn bad_boundary_tables_name_the_table() {
    let head = "[tissue]\ngeometry = { kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], spacing = 0.025 }\n\
        [material]\nmodel = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3\n";
    let cases = [
        ("[[fixed]]\naxis = \"y\"\nbelow = -0.5\n", "fixed[0]"),
        ("[[fixed]]\nsphere = { centre = [5.0, 5.0, 5.0], radius = 0.1 }\n", "fixed[0]"),
        ("[[fixed]]\naxis = \"y\"\nbelow = 0.001\n[[prescribed]]\naxis = \"y\"\nbelow = 0.001\ndisplacement = [0.0, 0.001, 0.0]\n", "prescribed[0]"),
        ("[[load]]\nsphere = { centre = [0.05, 0.05, 0.05], radius = 0.01 }\npressure = 1.0\n", "load[0]"),
        ("[[fixed]]\naxis = \"y\"\nbelow = 0.001\nbox = { min = [0.0, 0.0, 0.0], max = [1.0, 1.0, 1.0] }\n", "exactly one node set"),
        ("[[fixed]]\naxis = \"y\"\nbelow = 0.001\ncomponents = []\n", "components"),
        ("[[prescribed]]\naxis = \"y\"\nabove = 0.09\ndisplacement = [0.0, 0.001, 0.0]\nvelocity = [0.0, 0.1, 0.0]\n", "exactly one of `displacement` and `velocity`"),
        ("[[prescribed]]\naxis = \"y\"\nabove = 0.09\ndisplacement = [0.0, nan, 0.0]\n", "prescribed[0].displacement"),
        ("[[load]]\naxis = \"y\"\nabove = 0.09\ntraction = [0.0, 1.0, 0.0]\npush = 1\n", "push"),
        ("[[fixed]]\npoints = []\n", "fixed[0].points"),
        ("[[fixed]]\naxis = \"y\"\nbelow = 0.001\nfar_field = { distance = 0.0 }\n", "fixed[0].far_field.distance"),
        ("[[fixed]]\naxis = \"y\"\nbelow = 0.001\nfar_field = { distance = inf }\n", "fixed[0].far_field.distance"),
        ("[[fixed]]\naxis = \"y\"\nbelow = 0.001\nfar_field = { radius = 0.1 }\n", "radius"),
        ("[[fixed]]\naxis = \"y\"\nbelow = 0.001\ncomponents = [\"y\"]\nfar_field = { distance = 0.1 }\n", "fixed[0].components"),
        ("[[fixed]]\nsphere = { centre = [0.05, 0.05, 0.05], radius = 0.01 }\nfar_field = { distance = 0.1 }\n", "fixed[0].far_field"),
        // Springs far too stiff for the step (1 ms): the error names the distance.
        ("[physics]\ndt = 1e-3\n[[fixed]]\naxis = \"y\"\nbelow = 0.001\nfar_field = { distance = 1e-6 }\n", "fixed[0].far_field.distance"),
    ];
    for (table, key) in cases {
        let text = format!("{head}{table}");
        let err = Scene::from_toml_str(&text, Path::new("."))
            .and_then(|s| needlesim::Tissue::from_scene(&s).map(|_| ()))
            .expect_err(table);
        assert!(err.to_string().contains(key), "{table}: {err}");
    }
}

fn far_field_block(floor: FixedSelection) -> Scene {
    Scene::builder()
        .box_with_spacing([0.0; 3], [0.05; 3], 0.0125)
        .material(Material::debunne(1e4, 0.3))
        .density(1000.0)
        .gravity([0.0, -9.81, 0.0])
        .dt_auto()
        .damping(60.0)
        .fixed(floor)
        .build()
        .unwrap()
}

/// A block standing on a far-field floor (`distance` 5 cm) sinks until the floor's springs
/// carry its weight: the reaction balances the weight (0.5%, settle tolerance) and the
/// floor moves down by `W / (K_n A)`, `K_n = 4 G / R` (2%: the plain mean of the floor's
/// nodes stands for the area-weighted one, which the springs' balance fixes exactly, and
/// the floor stays nearly flat; measured 0.3%). No sideways reaction (the tangential
/// springs see no load; 1e-6 of the weight for f32 round-off).
#[test]
fn a_far_field_floor_carries_the_weight_on_its_springs() {
    let (e, nu, rho, r, side) = (1e4, 0.3, 1000.0, 0.05, 0.05);
    let scene = far_field_block(
        FixedSelection::new(NodeSet::below(Axis::Y, 0.001))
            .with_name("floor")
            .with_far_field(r),
    );
    let mut sim = run(&scene, 1.5);
    let weight = rho * side * side * side * 9.81;
    let react = sim.reactions().unwrap();
    assert_eq!(react[0].name, "floor");
    eprintln!("reaction {:?} N, weight {weight} N", react[0].force);
    let rest = sim.rest_positions();
    let floor: Vec<usize> = (0..rest.len()).filter(|&i| rest[i][1] < 0.001).collect();
    let mut p = vec![[0.0f32; 4]; rest.len()];
    sim.backend()
        .read(NodeField::Position, 0..rest.len(), &mut p)
        .unwrap();
    let sink = floor
        .iter()
        .map(|&i| p[i][1] as f64 - rest[i][1])
        .sum::<f64>()
        / floor.len() as f64;
    let k_n = 4.0 * e / (2.0 * (1.0 + nu)) / r;
    let want = -weight / (k_n * side * side);
    eprintln!("floor moved {sink:e} m, want {want:e} m");
    assert!((sink / want - 1.0).abs() < 0.02, "{sink} vs {want}");
    assert!(
        (react[0].force[1] / weight - 1.0).abs() < 0.005,
        "{:?}",
        react[0].force
    );
    for a in [0, 2] {
        assert!(
            react[0].force[a].abs() < 1e-6 * weight,
            "{:?}",
            react[0].force
        );
    }
}

/// The mean kinetic energy of a bar between 0.2 and 0.3 s after its left end was pushed
/// 1 mm in 10 ms, its right end held rigidly or as a far-field face.
fn bar_energy_after_a_push(right: FixedSelection) -> f64 {
    // Rollers on the four sides: a column in uniaxial strain, whose waves run at c_p.
    let roller = |axis, at_min: bool| {
        let set = match at_min {
            true => NodeSet::below(axis, 0.001),
            false => NodeSet::above(axis, 0.019),
        };
        FixedSelection::new(set).with_components(Components::of(&[axis]))
    };
    let scene = Scene::builder()
        .box_with_spacing([0.0; 3], [0.2, 0.02, 0.02], 0.005)
        .material(Material::debunne(1e4, 0.3))
        .density(1000.0)
        .gravity([0.0; 3])
        .dt_auto()
        .damping(0.0)
        .prescribed(
            Prescribed::displacement(NodeSet::below(Axis::X, 0.001), [0.001, 0.0, 0.0], 0.01)
                .with_components(Components::of(&[Axis::X])),
        )
        .fixed(roller(Axis::Y, true))
        .fixed(roller(Axis::Y, false))
        .fixed(roller(Axis::Z, true))
        .fixed(roller(Axis::Z, false))
        .fixed(right)
        .build()
        .unwrap();
    let prep = Simulation::prepare(&scene).unwrap();
    let (backend, _) = make_backend(&scene, prep.tissue.clone(), None, None).unwrap();
    let mut sim = prep.start(backend).unwrap();
    let n = sim.rest_positions().len();
    let masses = prep_masses(&scene);
    let (mut sum, mut count) = (0.0, 0);
    while sim.time() < 0.3 {
        sim.step().unwrap();
        if sim.time() > 0.2 {
            let mut v = vec![[0.0f32; 4]; n];
            sim.backend()
                .read(NodeField::Velocity, 0..n, &mut v)
                .unwrap();
            sum += v
                .iter()
                .zip(&masses)
                .map(|(v, m)| 0.5 * m * (0..3).map(|a| (v[a] as f64).powi(2)).sum::<f64>())
                .sum::<f64>();
            count += 1;
        }
    }
    sum / count as f64
}

fn prep_masses(scene: &Scene) -> Vec<f64> {
    needlesim::Tissue::from_scene(scene).unwrap().masses
}

/// A step wave sent down a column in uniaxial strain (rollers on its sides, so it runs at
/// `c_p` = 3.7 m/s and crosses the 20 cm five times by the end of the measurement) is
/// reflected by a held end and keeps ringing; a far-field end, whose normal dashpot is
/// the P wave's impedance `rho c_p`, passes it out. What stays: the lattice's dispersion
/// (the dashpot matches the continuum's impedance, not the lattice's at short
/// wavelengths), the weak springs' reflection of the lowest frequencies (`distance` 1 m),
/// and the column creeping onto those springs under the pushed end. Measured (CPU, dev
/// machine, 2026-11-27): 8.6% of the held end's kinetic energy; bound 15%.
#[test]
fn a_far_field_end_lets_a_wave_out() {
    let end = || FixedSelection::new(NodeSet::above(Axis::X, 0.199));
    let held = bar_energy_after_a_push(end());
    let far = bar_energy_after_a_push(end().with_far_field(1.0));
    eprintln!("kinetic energy 0.2-0.3 s: held end {held:e} J, far-field end {far:e} J");
    assert!(
        held > 0.0 && far < 0.15 * held,
        "held {held:e}, far {far:e}"
    );
}
