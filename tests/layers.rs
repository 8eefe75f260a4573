//! Layered tissue (`[[region]]`): per-region materials against the series-spring
//! solution, a needle puncturing each layer's membrane in turn and extracted with every
//! array restored bitwise (each model, two cycles), the GPU against the CPU on the layered
//! needle, an impenetrable layer, and bad region input.

mod common;

use common::{cpu_sim, gpu_sim, same_states_force_difference};
use needlesim::core::regions::BASE_REGION;
use needlesim::needle::{NeedleSample, PunctureState, Simulation, SimulationError};
use needlesim::{Backend, CpuBackend, NodeField, Scene, SimError, Threading, Tissue};
use std::path::Path;

/// A 32 x 16 x 16 mm block, nodes `h` = 4 mm apart, held on its far face (x = 32 mm), in
/// three layers along x: `outer` 0-8 mm, `middle` 8-16 mm, `deep` 16-32 mm. The
/// membranes sit between node planes: 10 mm (middle) and 18 mm (deep).
const H: f64 = 0.004;

/// The needle's grip in `outer`, `middle` and `deep`, N/m (friction limits of 6, 24 and
/// 12 N/m of shaft with the coefficient 0.3).
const GRIP: [f64; 3] = [20.0, 80.0, 40.0];

/// Material tables of the base material and the three layers, for a model.
fn materials(model: &str) -> (String, [String; 3]) {
    let (base, layer) = match model {
        // Spring stiffness about E h, the continuum models' moduli at h = 4 mm.
        "mass_spring" => (
            "model = \"mass_spring\"\nstiffness = 80.0",
            ["stiffness = 120.0", "stiffness = 32.0", "stiffness = 80.0"],
        ),
        "local_shape_matching" => (
            "model = \"local_shape_matching\"\nstiffness = 40.0\nforces = \"cluster\"",
            ["stiffness = 60.0", "stiffness = 15.0", "stiffness = 40.0"],
        ),
        "point_based" => (
            "model = \"point_based\"\nyoung_modulus = 20000.0\npoisson_ratio = 0.3",
            [
                "young_modulus = 30000.0, poisson_ratio = 0.3",
                "young_modulus = 8000.0, poisson_ratio = 0.3",
                "young_modulus = 20000.0, poisson_ratio = 0.3",
            ],
        ),
        "neo_hookean" => (
            "model = \"neo_hookean\"\nyoung_modulus = 20000.0\npoisson_ratio = 0.3",
            [
                "young_modulus = 30000.0, poisson_ratio = 0.3",
                "young_modulus = 8000.0, poisson_ratio = 0.3",
                "young_modulus = 20000.0, poisson_ratio = 0.3",
            ],
        ),
        _ => (
            "model = \"debunne_meshfree\"\nyoung_modulus = 20000.0\npoisson_ratio = 0.3\ncorotated = true",
            [
                "young_modulus = 30000.0, poisson_ratio = 0.3",
                "young_modulus = 8000.0, poisson_ratio = 0.3",
                "young_modulus = 20000.0, poisson_ratio = 0.3",
            ],
        ),
    };
    (base.to_string(), layer.map(String::from))
}

/// The layered block with a needle inserted along +x through the middle of the entry
/// face to 26 mm at 20 mm/s, held, and pulled out; `membranes` the puncture forces of
/// `outer`, `middle` and `deep` (as TOML values, `""` for none). Every membrane carries
/// the tip's load on a contact of one node spacing's radius (`contact_radius`: a punch
/// of 4 mm dents the 8 kPa middle layer 5.7 mm at 0.4 N, the others about 2 mm), so that
/// the dents stay within the 8 mm layers.
fn layered(model: &str, membranes: [&str; 3]) -> String {
    layered_with(model, membranes, GRIP)
}

/// [`layered`] with the needle's grip in each layer, N/m.
fn layered_with(model: &str, membranes: [&str; 3], grip: [f64; 3]) -> String {
    let (base, layer) = materials(model);
    let names = ["outer", "middle", "deep"];
    let spans = [(-0.001, 0.008), (0.008, 0.016), (0.016, 0.033)];
    let mut regions = String::new();
    for k in 0..3 {
        let membrane = match membranes[k] {
            "" => String::new(),
            "impenetrable" => "impenetrable = true, ".into(),
            f => format!("puncture_force = {f}, "),
        };
        regions.push_str(&format!(
            "[[region]]\nname = \"{}\"\ngeometry = {{ kind = \"box\", min = [{}, -0.001, -0.001], max = [{}, 0.017, 0.017] }}\n\
             material = {{ {} }}\nneedle = {{ {membrane}cutting = {}, contact_radius = {H}, friction = {{ coefficient = 0.3, grip = {} }} }}\n\n",
            names[k],
            spans[k].0,
            spans[k].1,
            layer[k],
            [0.2, 0.05, 0.1][k],
            grip[k],
        ));
    }
    format!(
        "[tissue]\ndensity = 1000.0\ngeometry = {{ kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.032, 0.016, 0.016], spacing = {H} }}\n\n\
         [material]\n{base}\n\n[physics]\ndt = 2e-4\ndamping = 6.0\n\n[[fixed]]\naxis = \"x\"\nabove = 0.0319\n\n\
         {regions}\
         [needle]\nbase = [-0.103, 0.0081, 0.0079]\ndirection = [1.0, 0.0, 0.0]\nlength = 0.1\nradius = 0.0005\ncontact_radius = {H}\n\
         friction = {{ coefficient = 0.3, grip = 20.0 }}\n\n\
         [[needle.keyframe]]\naction = \"move\"\ndirection = [1.0, 0.0, 0.0]\nspeed = 0.02\nduration = 1.6\n\n\
         [[needle.keyframe]]\naction = \"pause\"\nduration = 0.2\n\n\
         [[needle.keyframe]]\naction = \"extract\"\nspeed = 0.02\nduration = 1.7\n"
    )
}

fn scene(text: &str) -> Scene {
    Scene::from_toml_str(text, Path::new(".")).unwrap()
}

/// Where the tip first entered each region while advancing: `(region name, depth m,
/// history index)`.
fn entries(sim: &Simulation) -> Vec<(String, f64, usize)> {
    let mut out: Vec<(String, f64, usize)> = Vec::new();
    for (k, s) in sim.history().iter().enumerate() {
        if let Some(r) = s.region {
            let name = &sim.region_names()[r as usize];
            if out.last().is_none_or(|e| &e.0 != name) && !out.iter().any(|e| &e.0 == name) {
                out.push((name.clone(), sim.depth_of(s.tip, s.direction), k));
            }
        }
    }
    out
}

/// Co-rotated Debunne: the tip punctures `outer` (the entry surface), then dents and
/// punctures the membranes of `middle` and `deep` in that order. Against the tip's depth
/// in the undeformed tissue (`tissue_depth`), each membrane's force peak lies within one
/// node spacing of its rest depth (10 and 18 mm, midway between node planes) and is
/// followed by a drop to less than 60 % of the peak within 0.05 s; the tip region is
/// reported back out to `outer`; after full extraction every neighbour row, shape array
/// (the per-node materials included) and surface triangle is bitwise as at the start.
/// (Against tip travel the peaks come later by the dents, 4 to 6 mm here: see the
/// guide's layered tissue chapter, docs/guide/layers.md.)
#[test]
fn the_needle_punctures_each_layer_in_turn_and_extraction_restores_every_array() {
    let layered_scene = scene(&layered("debunne_meshfree", ["0.5", "0.4", "0.4"]));
    let mut sim = cpu_sim(&layered_scene);
    assert!(
        sim.editor().shape().node_material().is_some(),
        "three materials need per-node rows"
    );
    let (nb, shape, tri) = (
        sim.editor().neighbours().clone(),
        sim.editor().shape().clone(),
        sim.triangles().to_vec(),
    );
    let steps = (sim.script_duration() / sim.dt()).round() as u64 + 50;
    sim.step_n(steps).unwrap();
    let e = entries(&sim);
    let names: Vec<&str> = e.iter().map(|e| e.0.as_str()).collect();
    assert_eq!(names, ["outer", "middle", "deep"], "{e:?}");
    let h = sim.history();
    let after = (0.05 / sim.dt()).round() as usize;
    for (k, (name, _, at)) in e.iter().enumerate().skip(1) {
        let membrane = [0.0, 0.010, 0.018][k];
        // The peak between the previous puncture and this one.
        let from = e[k - 1].2;
        let (peak_at, peak) = (from..*at)
            .map(|i| (i, h[i].force.axial))
            .fold((from, f64::MIN), |a, b| if b.1 > a.1 { b } else { a });
        let depth = h[peak_at].tissue_depth.expect("inside: a tissue depth");
        let low = h[*at..*at + after]
            .iter()
            .map(|s| s.force.axial)
            .fold(f64::MAX, f64::min);
        eprintln!(
            "{name}: peak {peak:.3} N at tissue depth {:.2} mm (membrane {:.0} mm, travel {:.2} mm), \
             then down to {low:.3} N",
            depth * 1e3,
            membrane * 1e3,
            sim.depth_of(h[peak_at].tip, h[peak_at].direction) * 1e3
        );
        assert!((depth - membrane).abs() < H, "{name}: peak at {depth} m");
        // The membrane's load beyond the cutting force goes (the friction stays): a
        // drop of at least 80% of it within 0.05 s (the tear takes 30 ms).
        let (membrane_force, cutting) = [(0.0, 0.0), (0.4, 0.05), (0.4, 0.1)][k];
        assert!(
            peak - low > 0.8 * (membrane_force - cutting),
            "{name}: no drop after the peak {peak} ({low})"
        );
        assert!(
            h[peak_at].state == PunctureState::Touching,
            "{name}: denting at the peak"
        );
    }
    // Pulled back, the tip is reported in the layers it passes.
    let back: Vec<Option<u16>> = h
        .iter()
        .filter(|s| s.time > 1.6 && s.region.is_some())
        .map(|s| s.region)
        .collect();
    assert_eq!(
        back.last().copied().flatten(),
        sim.region_names()
            .iter()
            .position(|n| n == "outer")
            .map(|r| r as u16)
    );
    assert_eq!(sim.state(), PunctureState::Outside);
    assert_eq!(sim.needle_nodes().len(), 0);
    assert!(sim.editor().neighbours() == &nb, "neighbour rows differ");
    assert!(sim.editor().shape() == &shape, "shape arrays differ");
    assert_eq!(sim.triangles(), &tri[..]);
}

/// An impenetrable `middle` layer (a bone, a hard capsule): the tip never enters it or
/// anything past it, and the force keeps rising as the needle presses on (over the last
/// 6 mm of travel).
#[test]
fn an_impenetrable_layer_stops_the_tip() {
    let text = layered("debunne_meshfree", ["0.5", "impenetrable", "0.4"]);
    let mut sim = cpu_sim(&scene(&text));
    // To 14 mm of travel: the entry dent is about 6 mm, the membrane 10 mm deep. (Pressed
    // further, the crushed tissue diverges: see the next test.)
    sim.step_n((1.05 / sim.dt()) as u64).unwrap();
    let h = sim.history();
    let outer = sim
        .region_names()
        .iter()
        .position(|n| n == "outer")
        .unwrap() as u16;
    assert!(h
        .iter()
        .all(|s| s.region.is_none() || s.region == Some(outer)));
    assert_eq!(
        sim.state(),
        PunctureState::Touching,
        "pressing on the layer"
    );
    let n = h.len();
    let (before, last) = (
        h[n - 1 - (0.3 / sim.dt()) as usize].force.axial,
        h[n - 1].force.axial,
    );
    eprintln!("impenetrable: force {before:.3} N, 6 mm of travel later {last:.3} N");
    assert!(last > before + 0.1, "{before} {last}");
}

/// Pressed on an impenetrable layer for the whole insertion (soft layers, 10 mm of press
/// and more), the run either completes or stops with the divergence guard's error: a
/// diverging run is not reported as needle nodes lost (before, a shaft node flung 0.3 m
/// ahead of the tip stopped it with `NodesLost`).
#[test]
fn a_run_diverging_against_an_impenetrable_layer_says_so() {
    let text = layered("debunne_meshfree", ["0.5", "impenetrable", "0.4"]);
    let mut sim = cpu_sim(&scene(&text));
    match sim.step_n((1.6 / sim.dt()) as u64) {
        Ok(()) => assert_eq!(sim.state(), PunctureState::Touching),
        Err(SimulationError::Sim(SimError::Diverged { .. } | SimError::Runaway { .. })) => {}
        Err(e) => panic!("expected a divergence error, got: {e}"),
    }
}

/// Two layers in series under a prescribed end displacement, relaxed: the mean strain
/// of each layer is inversely proportional to its modulus (equal force through both,
/// `eps_1 / eps_2 = E_2 / E_1`), within 15% (nodal quadrature at 4 nodes per layer, and
/// the lateral contraction the held ends restrain); uniform material gives equal strains.
#[test]
fn layers_in_series_share_the_force() {
    let run = |stiff: &str| {
        let text = format!(
            "[tissue]\ndensity = 1000.0\ngeometry = {{ kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.032, 0.008, 0.008], spacing = {H} }}\n\
             [material]\nmodel = \"debunne_meshfree\"\nyoung_modulus = 10000.0\npoisson_ratio = 0.0\n\
             [physics]\ndt = 2e-4\ndamping = 60.0\n\
             [[fixed]]\naxis = \"x\"\nbelow = 0.0001\n\
             [[prescribed]]\naxis = \"x\"\nabove = 0.0319\ndisplacement = [0.0016, 0.0, 0.0]\nramp = 0.05\n\
             [[region]]\nname = \"soft\"\ngeometry = {{ kind = \"box\", min = [0.0, -0.001, -0.001], max = [0.016, 0.009, 0.009] }}\n\
             material = {{ young_modulus = {stiff}, poisson_ratio = 0.0 }}\n"
        );
        let scene = Scene::from_toml_str(&text, Path::new(".")).unwrap();
        let tissue = Tissue::from_scene(&scene).unwrap();
        let rest: Vec<[f32; 4]> = tissue.state.positions.clone();
        let n = tissue.n_mesh;
        let prep = Simulation::prepare(&scene).unwrap();
        let b = CpuBackend::new(prep.tissue.clone(), Threading::Single).unwrap();
        let mut sim = prep.start(Box::new(b)).unwrap();
        sim.step_n(3000).unwrap();
        let mut x = vec![[0.0f32; 4]; n];
        sim.backend()
            .read(NodeField::Position, 0..n, &mut x)
            .unwrap();
        // Mean x displacement of the node planes at x = 16 mm (the interface) and 32 mm.
        let mean_u = |plane: f32| {
            let sel: Vec<usize> = (0..n)
                .filter(|&i| (rest[i][0] - plane).abs() < 1e-4)
                .collect();
            sel.iter()
                .map(|&i| (x[i][0] - rest[i][0]) as f64)
                .sum::<f64>()
                / sel.len() as f64
        };
        let (mid, end) = (mean_u(0.016), mean_u(0.032));
        (mid / 0.016, (end - mid) / 0.016)
    };
    let (soft, stiff) = run("2500.0");
    let ratio = soft / stiff;
    eprintln!("strains: soft {soft:.4}, stiff {stiff:.4}, ratio {ratio:.2} (expected 4)");
    assert!((ratio / 4.0 - 1.0).abs() < 0.15, "ratio {ratio}");
    let (a, b) = run("10000.0");
    assert!((a / b - 1.0).abs() < 0.05, "uniform material: {a} {b}");
}

fn error_of(text: &str) -> String {
    let e = match Scene::from_toml_str(text, Path::new(".")) {
        Err(e) => e.to_string(),
        Ok(scene) => match Simulation::prepare(&scene) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("accepted:\n{text}"),
        },
    };
    e
}

/// Bad region input: typed errors that name the region and the key.
#[test]
fn bad_regions_are_errors_naming_the_region_and_key() {
    let ok = layered("debunne_meshfree", ["1.0", "0.5", "0.5"]);
    assert!(Simulation::prepare(&scene(&ok)).is_ok());
    let cases: Vec<(String, &str)> = vec![
        (
            ok.replace("min = [0.008, -0.001", "min = [0.004, -0.001"),
            "region[middle].geometry",
        ),
        (
            ok.replace(
                "material = { young_modulus = 8000.0, poisson_ratio = 0.3 }\n",
                "",
            ),
            "region[middle].material",
        ),
        (
            ok.replace(
                "puncture_force = 0.5, cutting = 0.05",
                "puncture_force = 0.0, cutting = 0.05",
            ),
            "region[middle].needle.puncture_force",
        ),
        (
            ok.replace(
                "puncture_force = 0.5, cutting = 0.05",
                "puncture_force = -2.0, cutting = 0.05",
            ),
            "region[middle].needle.puncture_force",
        ),
        (
            ok.replace(
                "puncture_force = 0.5, cutting = 0.05",
                "puncture_force = 1.0, impenetrable = true, cutting = 0.05",
            ),
            "region[middle].needle.impenetrable",
        ),
        (
            ok.replace("cutting = 0.05,", "cutting = -0.05,"),
            "region[middle].needle.cutting",
        ),
        (
            ok.replace(
                "young_modulus = 8000.0, poisson_ratio = 0.3",
                "young_modulus = -8000.0, poisson_ratio = 0.3",
            ),
            "region[middle].material.young_modulus",
        ),
        (
            ok.replace(
                "young_modulus = 8000.0, poisson_ratio = 0.3",
                "model = \"mass_spring\", stiffness = 3.0",
            ),
            "region[middle].material.model",
        ),
        (
            ok.replace(
                "young_modulus = 8000.0, poisson_ratio = 0.3",
                "young_modulus = 8000.0, poisson_ratio = 0.3, corotated = false",
            ),
            "region[middle].material.corotated",
        ),
        (
            ok.replace("name = \"deep\"", "name = \"middle\""),
            "region[2].name",
        ),
        (
            ok.replace("name = \"deep\"", &format!("name = \"{BASE_REGION}\"")),
            "region[2].name",
        ),
        (
            ok.replace("min = [0.016, -0.001", "min = [0.0405, -0.001")
                .replace("max = [0.033, 0.017", "max = [0.05, 0.017"),
            "region[deep].geometry",
        ),
        (
            ok.replace(
                "puncture_force = 0.5, cutting = 0.05",
                "puncture_forse = 0.5",
            ),
            "region[middle].needle",
        ),
        (
            ok.replace(
                "cutting = 0.05, contact_radius = 0.004",
                "cutting = 0.05, contact_radius = -0.004",
            ),
            "region[middle].needle.contact_radius",
        ),
    ];
    for (text, key) in cases {
        let e = error_of(&text);
        assert!(
            e.contains(key),
            "expected an error naming `{key}`, got: {e}"
        );
    }
}

/// One material in every region (same parameters): no per-node rows are allocated, and
/// the run is bitwise the run without regions.
#[test]
fn regions_of_one_material_allocate_nothing_and_change_nothing() {
    let plain = "[tissue]\ndensity = 1000.0\ngeometry = { kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.016, 0.016, 0.016], spacing = 0.004 }\n\
                 [material]\nmodel = \"mass_spring\"\nstiffness = 40.0\n[physics]\ndt = 1e-4\ngravity = [0.0, -9.81, 0.0]\ndamping = 5.0\n\
                 [[fixed]]\naxis = \"y\"\nbelow = 0.0001\n";
    let with = format!(
        "{plain}[[region]]\nname = \"top\"\ngeometry = {{ kind = \"box\", min = [0.0, 0.008, 0.0], max = [0.016, 0.016, 0.016] }}\nmaterial = {{ stiffness = 40.0 }}\n"
    );
    let run = |text: &str| {
        let t = Tissue::from_scene(&Scene::from_toml_str(text, Path::new(".")).unwrap()).unwrap();
        assert!(t.shape.node_material().is_none());
        let mut b = CpuBackend::new(t, Threading::Single).unwrap();
        b.step(200);
        b.check_finite().unwrap();
        let bits: Vec<[u32; 4]> = b
            .tissue()
            .state
            .positions
            .iter()
            .map(|p| p.map(f32::to_bits))
            .collect();
        bits
    };
    assert_eq!(run(plain), run(&with));
}

/// Every model.
const ALL_MODELS: [&str; 5] = [
    "mass_spring",
    "local_shape_matching",
    "point_based",
    "debunne_meshfree",
    "neo_hookean",
];

/// Every model, two insert / hold / extract cycles through the three layers (membranes of
/// 0.2, 0.15 and 0.15 N, dents below about one node spacing for every model): in each
/// cycle the tip enters `outer`, `middle` and `deep` in that order, each inner membrane
/// punctured at a tissue depth within one node spacing of its rest depth; after each
/// cycle every neighbour row, shape array (per-node materials included) and surface
/// triangle is bitwise as at the start.
#[test]
fn every_model_restores_every_array_after_each_cycle_through_the_layers() {
    for model in ALL_MODELS {
        let text = layered(model, ["0.2", "0.15", "0.15"]);
        // A second cycle after a 0.1 s pause outside.
        let (_, cycle) = text.split_once("[[needle.keyframe]]").unwrap();
        let text = format!(
            "{text}\n[[needle.keyframe]]\naction = \"pause\"\nduration = 0.1\n\n[[needle.keyframe]]{cycle}"
        );
        let mut sim = cpu_sim(&scene(&text));
        let (nb, shape, tri) = (
            sim.editor().neighbours().clone(),
            sim.editor().shape().clone(),
            sim.triangles().to_vec(),
        );
        let cycle_steps = ((1.6 + 0.2 + 1.7 + 0.1) / sim.dt()).round() as u64;
        for k in 1..=2 {
            sim.step_n(cycle_steps).unwrap();
            let e = entries(&sim);
            let names: Vec<&str> = e.iter().map(|e| e.0.as_str()).collect();
            assert_eq!(
                names,
                ["outer", "middle", "deep"],
                "{model}, cycle {k}: {e:?}"
            );
            let h = sim.history();
            for (m, (name, _, at)) in e.iter().enumerate().skip(1) {
                let depth = h[at - 1].tissue_depth.expect("inside: a tissue depth");
                let membrane = [0.0, 0.010, 0.018][m];
                assert!(
                    (depth - membrane).abs() < H,
                    "{model}, cycle {k}: {name} punctured at a tissue depth of {depth} m"
                );
            }
            assert_eq!(sim.state(), PunctureState::Outside, "{model}, cycle {k}");
            assert_eq!(sim.needle_nodes().len(), 0);
            assert!(
                sim.editor().neighbours() == &nb,
                "{model}, cycle {k}: neighbour rows"
            );
            assert!(
                sim.editor().shape() == &shape,
                "{model}, cycle {k}: shape arrays"
            );
            assert_eq!(sim.triangles(), &tri[..], "{model}, cycle {k}: triangles");
            sim.take_history();
        }
    }
}

/// The layered needle (co-rotated Debunne, three materials, three membranes) on the GPU
/// and on the CPU through insertion, hold and extraction: the same punctures, the same
/// sequences of tip regions, puncture states and needle node counts (each change within
/// two steps of the other run's), and the axial force within 1% of the
/// largest force at every step (the margin as in `tests/needle.rs`: f32 rounding may move
/// a node's switch between sticking and slipping by a step).
#[test]
fn gpu_and_cpu_agree_on_the_layered_needle() {
    let scene = scene(&layered("debunne_meshfree", ["0.5", "0.4", "0.4"]));
    let Some(mut g) = gpu_sim(&scene) else { return };
    let mut c = cpu_sim(&scene);
    let steps = (c.script_duration() / c.dt()).round() as u64 + 50;
    g.step_n(steps).unwrap();
    c.step_n(steps).unwrap();
    let (hg, hc) = (g.history(), c.history());
    let names =
        |sim: &Simulation| -> Vec<String> { entries(sim).into_iter().map(|e| e.0).collect() };
    assert_eq!(names(&c), ["outer", "middle", "deep"]);
    assert_eq!(names(&g), names(&c));
    // The tip's region at every step: the same sequence of regions, each change within
    // two steps on both (a change is a threshold on the tip's material depth, which f32
    // rounding moves: measured 1.2e-7 m apart on a 9.6 mm depth, one step apart).
    let changes = |h: &[NeedleSample]| -> Vec<(usize, Option<u16>)> {
        (1..h.len())
            .filter(|&i| h[i].region != h[i - 1].region)
            .map(|i| (i, h[i].region))
            .collect()
    };
    let (cg, cc) = (changes(hg), changes(hc));
    assert_eq!(cg.len(), cc.len(), "region changes: GPU {cg:?}, CPU {cc:?}");
    for (a, b) in cg.iter().zip(&cc) {
        assert!(a.1 == b.1 && a.0.abs_diff(b.0) <= 2, "GPU {a:?}, CPU {b:?}");
    }
    let (scale, per_step) = same_states_force_difference(hg, hc, f64::INFINITY);
    eprintln!("layered: force scale {scale:.3} N; largest difference {per_step:.2e} of it");
    assert!(per_step < 0.01, "{per_step}");
}

/// A 60 x 16 x 16 mm block of one material (co-rotated Debunne, `young` Pa), held on its
/// far face, in three layers along x that differ only by the needle's grip (N/m): `outer`
/// 0-10 mm, `middle` 10-26 mm, `deep` 26-60 mm (boundaries midway between node planes);
/// the needle enters by a 0.3 N puncture and goes 56 mm in at 20 mm/s; no inner membranes.
fn slope_scene(young: f64, dt: f64, grip: [f64; 3]) -> String {
    let names = ["outer", "middle", "deep"];
    let spans = [(-0.001, 0.010), (0.010, 0.026), (0.026, 0.061)];
    let mut regions = String::new();
    for k in 0..3 {
        regions.push_str(&format!(
            "[[region]]\nname = \"{}\"\ngeometry = {{ kind = \"box\", min = [{}, -0.001, -0.001], max = [{}, 0.017, 0.017] }}\n\
             material = {{ young_modulus = {young}, poisson_ratio = 0.3 }}\n\
             needle = {{ cutting = 0.05, friction = {{ coefficient = 0.3, grip = {} }} }}\n\n",
            names[k], spans[k].0, spans[k].1, grip[k],
        ));
    }
    format!(
        "[tissue]\ndensity = 1000.0\ngeometry = {{ kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.060, 0.016, 0.016], spacing = {H} }}\n\n\
         [material]\nmodel = \"debunne_meshfree\"\nyoung_modulus = {young}\npoisson_ratio = 0.3\ncorotated = true\n\n\
         [physics]\ndt = {dt}\ndamping = 6.0\n\n[[fixed]]\naxis = \"x\"\nabove = 0.0599\n\n\
         {regions}\
         [needle]\nbase = [-0.103, 0.0081, 0.0079]\ndirection = [1.0, 0.0, 0.0]\nlength = 0.1\nradius = 0.0005\npuncture_force = 0.3\n\
         friction = {{ coefficient = 0.3, grip = 20.0 }}\n\n\
         [[needle.keyframe]]\naction = \"move\"\ndirection = [1.0, 0.0, 0.0]\nspeed = 0.02\nduration = 2.8\n"
    )
}

/// Least-squares slope of `(x, y)` points.
fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    sxy / sxx
}

/// The friction slope changes at each layer as the layer's friction per length: with
/// Coulomb friction per unit length (Okamura et al. 2004), the force on a needle advancing
/// through a layer grows with the tip's depth by `mu q` of that layer (the shaft length in
/// it grows, every other term is constant), here 6, 24 and 12 N/m. The tissue is stiff
/// (100 kPa) so that the shaft nodes slip rather than drag the tissue along: the slope of
/// the axial force against the tip's depth in the undeformed tissue, fitted in each
/// layer from h / 4 past its interface (the region hysteresis) to h / 8 before the next
/// (`deep` to 50 mm, the needle stops at 52), is within 15% of `mu q`. (Measured: 6.75,
/// 24.4 and 12.1 N/m with the default hourglass control, 2026-11-27; 6.4, 24.2 and 11.9
/// with the first-order control at 0.1 before it. The `outer` window starts a spacing
/// (4 mm) in, after the entry dent has relaxed, and is the farthest off (6.46 N/m since
/// 2026-11-28: the needle enters 0.14 mm from a node, and until the contact patch counted
/// such a pair as overlapping cells, `needle::sheath::patch_compliance`, the contact there
/// was too stiff and its dent small; with the deeper dent a window from 3 mm read 7.21):
/// what is left of the dent's relaxation there depends on how stiff a node is against its neighbours, 8.5 N/m with
/// the quadratic control at 0.1, 6.6 to 6.8 at 4 to 32. In a soft block held close
/// behind the needle the slope is mostly elastic drag, not friction: see the guide's
/// layered tissue chapter.)
#[test]
fn the_friction_slope_changes_at_each_layer_as_its_friction_per_length() {
    let mut sim = cpu_sim(&scene(&slope_scene(1e5, 2e-4, GRIP)));
    let steps = (sim.script_duration() / sim.dt()).round() as u64;
    sim.step_n(steps).unwrap();
    let names: Vec<String> = entries(&sim).into_iter().map(|e| e.0).collect();
    assert_eq!(names, ["outer", "middle", "deep"]);
    let h = sim.history();
    let windows = [(0.004, 0.0095), (0.011, 0.0255), (0.027, 0.05)];
    for (k, (lo, hi)) in windows.into_iter().enumerate() {
        let points: Vec<(f64, f64)> = h
            .iter()
            .filter(|s| s.state == PunctureState::Inside)
            .filter_map(|s| {
                let d = s.tissue_depth.filter(|d| *d > lo && *d < hi)?;
                Some((d, s.force.axial))
            })
            .collect();
        assert!(points.len() > 1000, "window {k}: {} samples", points.len());
        let (measured, expected) = (slope(&points), 0.3 * GRIP[k]);
        eprintln!("layer {k}: slope {measured:.2} N/m (mu q = {expected:.1})");
        assert!(
            (measured / expected - 1.0).abs() < 0.15,
            "layer {k}: slope {measured} N/m, mu q = {expected}"
        );
    }
}

/// A node added where the grip falls tenfold (`middle` 60 N/m of shaft, `deep` 6 N/m, in
/// [`slope_scene`]) takes from the shaft's friction field more than its own tissue holds;
/// what is above its cap is let go over the handover time, not in one step
/// (`NeedleNode::carried`). From the first grip change on, no step changes the axial
/// force by more than 3% of the local force (the mean |force| over 50 ms, at least a
/// tenth of the largest, as `shared/tools/force_audit.py` counts; it counts a jump at 5%).
/// Measured (CPU, 2026-11-27): 1.95% with the fade, at a node event inside `middle`;
/// 11.8% without it, at the first `deep` node (and 4.1% where the grip rises); 1.99%
/// with the default hourglass control that came after. The excess goes: the slope in
/// `deep` is its own `mu q` within 15% (measured 6.10 N/m, and 6.60 with the default
/// hourglass control; 9.38 with an excess that never fades).
#[test]
fn node_additions_where_the_grip_falls_leave_the_force_continuous() {
    let mut sim = cpu_sim(&scene(&slope_scene(1e5, 2e-4, [20.0, 200.0, 20.0])));
    let steps = (sim.script_duration() / sim.dt()).round() as u64;
    sim.step_n(steps).unwrap();
    let h = sim.history();
    let entered = h
        .iter()
        .position(|s| s.state == PunctureState::Inside)
        .expect("the needle goes in");
    let f: Vec<f64> = h.iter().map(|s| s.force.axial).collect();
    let peak = f.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let w = (0.025 / sim.dt()) as usize;
    // From h / 8 before the first grip change on (the entry's recoil is the first
    // layer's, a 0.3 N puncture into a 4 mm lattice, and not what this test is about).
    let start = h
        .iter()
        .position(|s| s.tissue_depth.is_some_and(|d| d > 0.0095))
        .expect("the tip reaches `middle`");
    assert!(start > entered);
    let mut worst = (0.0f64, 0);
    for k in start..f.len() - 1 {
        let (a, b) = (k.saturating_sub(w), (k + w).min(f.len()));
        let local = f[a..b].iter().map(|x| x.abs()).sum::<f64>() / (b - a) as f64;
        let step = (f[k + 1] - f[k]).abs() / local.max(0.1 * peak);
        if step > worst.0 {
            worst = (step, k);
        }
    }
    let at = h[worst.1].tissue_depth.unwrap_or(f64::NAN);
    eprintln!(
        "largest step {:.2}% of the local force at tissue depth {:.1} mm",
        100.0 * worst.0,
        1e3 * at
    );
    assert!(
        worst.0 < 0.03,
        "a step of {:.2}% at {at} m",
        100.0 * worst.0
    );
    // And the excess does fade: the slope in `deep` (from 1 mm past its interface,
    // h / 4 past the hysteresis, to 50 mm) is its own friction per length, 6 N/m, within
    // 15%, not the 60 N/m of `middle` it came from.
    let points: Vec<(f64, f64)> = h
        .iter()
        .filter(|s| s.state == PunctureState::Inside)
        .filter_map(|s| {
            let d = s.tissue_depth.filter(|d| *d > 0.027 && *d < 0.05)?;
            Some((d, s.force.axial))
        })
        .collect();
    let deep = slope(&points);
    eprintln!("deep slope {deep:.2} N/m (mu q = 6)");
    assert!((deep / 6.0 - 1.0).abs() < 0.15, "deep slope {deep} N/m");
}

/// A region bounded by a closed surface file: the octahedron `|x| + |y| + |z| < 1`,
/// scaled to 3 cm and moved to the middle of a 10 cm cube, over an 11^3-node lattice.
/// Every node farther than 1e-9 m from its faces is in the region exactly when it is
/// inside the octahedron (the clustered winding number, `geometry::sampling::FastWinding`,
/// against the closed form).
#[test]
fn a_region_bounded_by_a_surface_file_holds_the_nodes_inside_it() {
    let dir = tempfile::tempdir().unwrap();
    let mut obj = String::new();
    for p in common::OCTAHEDRON_VERTICES {
        obj.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    for t in common::OCTAHEDRON_TRIANGLES {
        obj.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    std::fs::write(dir.path().join("octa.obj"), obj).unwrap();
    let scene = Scene::from_toml_str(
        "[tissue]\ngeometry = { kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], \
         spacing = 0.01 }\n[material]\nmodel = \"mass_spring\"\nstiffness = 100.0\n\
         [[region]]\nname = \"core\"\ngeometry = { kind = \"obj\", path = \"octa.obj\", \
         scale = 0.03, translate = [0.05, 0.05, 0.05] }\nmaterial = { stiffness = 200.0 }\n",
        dir.path(),
    )
    .unwrap();
    let t = Tissue::from_scene(&scene).unwrap();
    let core = t.regions.names.iter().position(|n| n == "core").unwrap() as u16;
    let (mut inside, mut checked) = (0, 0);
    for (i, p) in t.state.positions[..t.n_mesh].iter().enumerate() {
        let l1: f64 = (0..3).map(|a| (p[a] as f64 - 0.05).abs()).sum();
        if (l1 - 0.03).abs() < 1e-9 {
            continue;
        }
        checked += 1;
        assert_eq!(
            t.regions.of_node[i] == core,
            l1 < 0.03,
            "node {i} at {p:?} (|x - c|_1 = {l1})"
        );
        inside += usize::from(l1 < 0.03);
    }
    assert!(
        inside >= 19 && checked > 1200,
        "{inside} inside of {checked}"
    );
}
