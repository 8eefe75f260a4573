//! Bad scene files and bad OBJ files give typed errors that name the problem.

mod common;

use needlesim::{GeometryError, Scene, SceneError, Tissue};
use std::path::Path;

const GOOD: &str = r#"
[tissue]
geometry = { kind = "box", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], spacing = 0.02 }
[material]
model = "mass_spring"
stiffness = 100.0
[physics]
dt = 1e-3
"#;

/// Parses `text` and builds its tissue; returns the error message.
fn error_of(text: &str, base: &Path) -> (SceneError, String) {
    let r = Scene::from_toml_str(text, base).and_then(|s| Tissue::from_scene(&s).map(|_| ()));
    let e = r.expect_err("scene should be rejected");
    let msg = e.to_string();
    (e, msg)
}

#[test]
fn the_reference_scene_is_valid() {
    let s = Scene::from_toml_str(GOOD, Path::new(".")).unwrap();
    assert_eq!(Tissue::from_scene(&s).unwrap().n_mesh, 216);
}

#[test]
fn bad_scenes_name_the_key() {
    // (edit applied to GOOD, text that the message must contain)
    let cases: Vec<(String, &str)> = vec![
        (
            GOOD.replace("[physics]", "[physics]\nstep_size = 2.0"),
            "step_size",
        ),
        (
            GOOD.replace("stiffness = 100.0", "stifness = 100.0"),
            "stifness",
        ),
        (
            GOOD.replace("stiffness = 100.0", "stiffness = -5.0"),
            "material.stiffness",
        ),
        (
            GOOD.replace("stiffness = 100.0", "stiffness = \"stiff\""),
            "stiffness",
        ),
        (GOOD.replace("dt = 1e-3", "dt = 0.0"), "physics.dt"),
        (GOOD.replace("dt = 1e-3", "dt = \"fast\""), "physics.dt"),
        (
            GOOD.replace("dt = 1e-3", "dt = 1e-3\nmax_speed = -1.0"),
            "physics.max_speed",
        ),
        (
            GOOD.replace("dt = 1e-3", "dt = 1e-3\ncheck_every = 0"),
            "physics.check_every",
        ),
        (
            GOOD.replace(
                "model = \"mass_spring\"\nstiffness = 100.0",
                "model = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.5",
            ),
            "material.poisson_ratio",
        ),
        (
            GOOD.replace(
                "model = \"mass_spring\"\nstiffness = 100.0",
                "model = \"point_based\"\nyoung_modulus = -1e4\npoisson_ratio = 0.3",
            ),
            "material.young_modulus",
        ),
        (
            GOOD.replace(
                "model = \"mass_spring\"\nstiffness = 100.0",
                "model = \"point_based\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3\nhourglass = -1.0",
            ),
            "material.hourglass",
        ),
        (
            GOOD.replace(
                "model = \"mass_spring\"\nstiffness = 100.0",
                "model = \"point_based\"\nyoung_modulus = 1e4",
            ),
            "poisson_ratio",
        ),
        (
            GOOD.replace("mass_spring", "finite_elements"),
            "finite_elements",
        ),
        (
            GOOD.replace("[tissue]", "[tissue]\nneighbours = 0"),
            "tissue.neighbours",
        ),
        // One neighbour used to pass: the body fell apart without a warning.
        (
            GOOD.replace("[tissue]", "[tissue]\nneighbours = 1"),
            "tissue.neighbours",
        ),
        (
            GOOD.replace("[tissue]", "[tissue]\nneighbours = 5"),
            "tissue.neighbours",
        ),
        (
            GOOD.replace("[tissue]", "[tissue]\ndensity = nan"),
            "tissue.density",
        ),
        (
            GOOD.replace("max = [0.1, 0.1, 0.1]", "max = [0.1, -0.1, 0.1]"),
            "tissue.geometry.max",
        ),
        (
            GOOD.replace("spacing = 0.02", "spacing = 0.02, nodes = 100"),
            "tissue.geometry",
        ),
        (
            GOOD.replace("spacing = 0.02", "spacing = 0.5"),
            "tissue.geometry.spacing",
        ),
        (
            GOOD.replace("kind = \"box\"", "kind = \"sphere\""),
            "sphere",
        ),
        (
            format!("{GOOD}\n[[fixed]]\naxis = \"y\"\nbelow = -1.0\n"),
            "fixed[0]",
        ),
        (
            format!("{GOOD}\n[[fixed]]\naxis = \"y\"\nbelow = 0.0\nabove = 0.1\n"),
            "fixed[0]",
        ),
        (
            format!("{GOOD}\n[[fixed]]\naxis = \"w\"\nbelow = 0.0\n"),
            "w",
        ),
        (
            format!("{GOOD}\n[initial]\nstretch = [1.0, 0.0, 1.0]\n"),
            "initial.stretch",
        ),
        (
            format!("{GOOD}\n[run]\noutput_every = 0\n"),
            "run.output_every",
        ),
        (
            GOOD.replace(
                "[tissue]",
                "[tissue]\nweight = { kernel = \"poly6\", support = 0.5 }",
            ),
            "tissue.weight.support",
        ),
        (
            GOOD.replace("[material]\nmodel = \"mass_spring\"\nstiffness = 100.0", ""),
            "material",
        ),
        (
            GOOD.replace("[tissue]", "[tissue]\nneighbours = 40")
                .replace("spacing = 0.02", "spacing = 0.05"),
            "40",
        ),
        ("this is = not toml [".to_string(), "scene <string>"),
    ];
    for (text, needle) in &cases {
        let (_, msg) = error_of(text, Path::new("."));
        assert!(
            msg.contains(needle),
            "message `{msg}` should name `{needle}`"
        );
    }
    assert!(cases.len() >= 8);
}

fn write_obj(dir: &Path, name: &str, body: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, body).unwrap();
    p
}

fn obj_scene(obj: &str) -> String {
    format!(
        "[tissue]\nneighbours = 6\ngeometry = {{ kind = \"obj\", path = \"{obj}\", spacing = 0.25 }}\n[material]\nmodel = \"mass_spring\"\nstiffness = 1.0\n"
    )
}

/// A unit octahedron written as OBJ, optionally with one face changed.
fn octahedron(faces: &[&str]) -> String {
    let mut s = String::from("v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n");
    for f in faces {
        s.push_str(f);
        s.push('\n');
    }
    s
}

const OCTA_FACES: [&str; 8] = [
    "f 1 3 5", "f 3 2 5", "f 2 4 5", "f 4 1 5", "f 3 1 6", "f 2 3 6", "f 4 2 6", "f 1 4 6",
];

#[test]
fn a_closed_obj_is_filled_with_nodes() {
    let dir = tempfile::tempdir().unwrap();
    write_obj(dir.path(), "octa.obj", &octahedron(&OCTA_FACES));
    let h = 0.25;
    for surface in ["vertices", "resample"] {
        let text = obj_scene("octa.obj").replace(
            "spacing = 0.25 }",
            &format!("spacing = {h}, surface = \"{surface}\" }}"),
        );
        let scene = Scene::from_toml_str(&text, dir.path()).unwrap();
        let t = Tissue::from_scene(&scene).unwrap();
        // Volume of the octahedron |x|+|y|+|z| <= 1 is 4/3.
        assert!((t.volume - 4.0 / 3.0).abs() < 1e-9, "volume {}", t.volume);
        // The surface nodes are the triangles' corners, the interior nodes follow.
        let n_surface = t.triangles.iter().flatten().max().unwrap() + 1;
        let l1 = |p: &[f32; 4]| p[0].abs() + p[1].abs() + p[2].abs();
        if surface == "vertices" {
            assert_eq!(n_surface, 6);
        } else {
            // About one spacing apart over the surface (area 4 sqrt(3) = 6.9): some
            // dozens, each on the surface or kept inside its lattice cube (within a
            // spacing of it).
            assert!((40..400).contains(&n_surface), "{n_surface} surface nodes");
            for p in &t.state.positions[..n_surface as usize] {
                assert!(
                    (l1(p) - 1.0).abs() < 3f32.sqrt() * h as f32,
                    "{p:?} off the surface"
                );
            }
        }
        assert!(
            t.n_mesh > n_surface as usize,
            "interior nodes were added: {}",
            t.n_mesh
        );
        for p in &t.state.positions[n_surface as usize..t.n_mesh] {
            // At least h / 2 from the surface: l1 <= 1 - sqrt(3) h / 2.
            assert!(
                l1(p) < 1.0 - 0.85 * h as f32,
                "interior node {p:?} too close or outside"
            );
        }
        t.neighbours.check_mutual(t.n_mesh).unwrap();
        // A continuum model gets the nodes' cells (sub-sampled): they add up to the
        // enclosed volume, none is negative, and each of the six tips (the surface
        // vertices, whose cells are thin cones) gets less than the largest interior cell
        // (h^3 = 0.0156).
        let deb = text.replace(
            "model = \"mass_spring\"\nstiffness = 1.0",
            "model = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3",
        );
        let t = Tissue::from_scene(&Scene::from_toml_str(&deb, dir.path()).unwrap()).unwrap();
        let v = t.shape.node_volumes(t.n_mesh).unwrap();
        let total: f64 = v.iter().map(|&x| x as f64).sum();
        assert!(
            (total - 4.0 / 3.0).abs() < 1e-5,
            "cell volumes add up to {total}"
        );
        assert!(v.iter().all(|&x| x > 0.0));
        if surface == "vertices" {
            let largest = v[6..].iter().cloned().fold(0.0f32, f32::max);
            assert!(v[..6].iter().all(|&x| x < largest), "{v:?}");
        }
    }
}

#[test]
fn bad_obj_files_are_rejected_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut open = OCTA_FACES.to_vec();
    open.pop();
    let mut flipped = OCTA_FACES.to_vec();
    flipped[0] = "f 1 5 3";
    let inside_out: Vec<String> = OCTA_FACES
        .iter()
        .map(|f| {
            let v: Vec<&str> = f.split_whitespace().collect();
            format!("f {} {} {}", v[1], v[3], v[2])
        })
        .collect();
    let inside_out: Vec<&str> = inside_out.iter().map(|s| s.as_str()).collect();
    let mut extra = OCTA_FACES.to_vec();
    extra.push("f 1 3 5");
    let mut degenerate = OCTA_FACES.to_vec();
    degenerate.push("f 1 1 2");
    type Case = (
        &'static str,
        String,
        fn(&GeometryError) -> bool,
        &'static str,
    );
    let cases: Vec<Case> = vec![
        (
            "open.obj",
            octahedron(&open),
            |e| matches!(e, GeometryError::OpenSurface { .. }),
            "open",
        ),
        (
            "flipped.obj",
            octahedron(&flipped),
            |e| {
                matches!(
                    e,
                    GeometryError::NonManifold { .. } | GeometryError::OpenSurface { .. }
                )
            },
            "edge",
        ),
        (
            "inside_out.obj",
            octahedron(&inside_out),
            |e| matches!(e, GeometryError::NonPositiveVolume { .. }),
            "inside out",
        ),
        (
            "extra.obj",
            octahedron(&extra),
            |e| matches!(e, GeometryError::NonManifold { .. }),
            "not manifold",
        ),
        (
            "degenerate.obj",
            octahedron(&degenerate),
            |e| matches!(e, GeometryError::DegenerateTriangle { .. }),
            "degenerate",
        ),
        (
            "empty.obj",
            "# nothing here\nv 0 0 0\n".into(),
            |e| matches!(e, GeometryError::Empty { .. }),
            "no triangles",
        ),
        (
            "out_of_range.obj",
            octahedron(&["f 1 2 99"]),
            |e| matches!(e, GeometryError::ObjLoad { .. }),
            "cannot load",
        ),
        (
            "garbage.obj",
            "v 1 zero 0\nf 1 2 3\n".into(),
            |e| matches!(e, GeometryError::ObjLoad { .. }),
            "cannot load",
        ),
    ];
    for (name, body, is_expected, text) in cases {
        write_obj(d, name, &body);
        let (err, msg) = error_of(&obj_scene(name), d);
        match &err {
            SceneError::Geometry(g) => assert!(is_expected(g), "{name}: unexpected {g:?}"),
            other => panic!("{name}: expected a geometry error, got {other:?}"),
        }
        assert!(
            msg.contains(name) && msg.contains(text),
            "{name}: message `{msg}`"
        );
    }
    let (err, msg) = error_of(&obj_scene("missing.obj"), d);
    assert!(
        matches!(err, SceneError::Geometry(GeometryError::ObjLoad { .. }))
            && msg.contains("missing.obj"),
        "{msg}"
    );
}

/// A `[needle]` table with a bad value names the key; the capacity error names the fix.
#[test]
fn bad_needle_tables_name_the_key() {
    use needlesim::needle::{Simulation, SimulationError};
    let needle =
        "[needle]\nbase = [-0.05, 0.05, 0.05]\ndirection = [1.0, 0.0, 0.0]\nlength = 0.04\n";
    let with = |edit: &str| format!("{GOOD}{needle}{edit}");
    let cases: Vec<(String, &str)> = vec![
        (with("colour = \"red\"\n"), "colour"),
        (with("").replace("length = 0.04", "length = -1.0"), "needle length"),
        (with("").replace("direction = [1.0, 0.0, 0.0]", "direction = [0.0, 0.0, 0.0]"), "direction"),
        (with("spacing = 0.0\n"), "needle.spacing"),
        (with("thresholds = { puncture = 100.0, release = 95.0 }\n"), "needle.thresholds"),
        (with("friction = { static_threshold = -1.0, dynamic = 0.2 }\n"), "needle.friction"),
        (
            with("friction = { model = \"paper\", static_threshold = -1.0, dynamic = 0.2 }\n"),
            "needle.friction.static_threshold",
        ),
        (with("friction = { grip = -5.0 }\n"), "needle.friction.grip"),
        (with("friction = { grip = inf }\n"), "needle.friction.grip"),
        (with("friction = { coefficient = nan }\n"), "needle.friction.coefficient"),
        (with("friction = { viscous = -1.0 }\n"), "needle.friction.viscous"),
        (with("friction = { model = \"stiction\" }\n"), "needle.friction.model"),
        (with("radius = -0.001\n"), "needle.radius"),
        (with("radius = nan\n"), "needle.radius"),
        (with("radius = 0.0\n"), "needle.radius"),
        // 2 cm lattice: a 1.2 cm radius is not below half the spacing.
        (with("radius = 0.012\n"), "needle.radius"),
        (with("cutting = -0.5\n"), "needle.cutting"),
        (with("cutting = inf\n"), "needle.cutting"),
        (with("puncture_force = 0.0\n"), "needle.puncture_force"),
        (with("puncture_force = -2.0\n"), "needle.puncture_force"),
        (with("puncture_force = nan\n"), "needle.puncture_force"),
        (
            with("cutting = 0.5\nfriction = { model = \"paper\", static_threshold = 0.01, dynamic = 0.2 }\n"),
            "needle.cutting",
        ),
        (
            with("[[needle.keyframe]]\naction = \"move\"\ndirection = [1.0, 0.0, 0.0]\nspeed = -1.0\nduration = 1.0\n"),
            "needle.keyframe[0]",
        ),
        (
            with("[[needle.keyframe]]\naction = \"jump\"\nduration = 1.0\n"),
            "jump",
        ),
        // The sheath's and the tip's keys (crates/needle sheath.rs).
        (with("contact_radius = 0.0\n"), "needle.contact_radius"),
        (with("contact_radius = nan\n"), "needle.contact_radius"),
        (with("point_length = -0.001\n"), "needle.point_length"),
        (with("point_length = inf\n"), "needle.point_length"),
        (with("tear_time = -0.01\n"), "needle.tear_time"),
        (with("tear_time = nan\n"), "needle.tear_time"),
        (with("speed_ramp = -0.05\n"), "needle.speed_ramp"),
        (with("speed_ramp = inf\n"), "needle.speed_ramp"),
        (with("friction = { shear_stiffness = -1.0 }\n"), "needle.friction.shear_stiffness"),
        (with("friction = { shear_stiffness = nan }\n"), "needle.friction.shear_stiffness"),
        (with("friction = { sheath_viscosity = -2.0 }\n"), "needle.friction.sheath_viscosity"),
        (with("friction = { sheath_viscosity = inf }\n"), "needle.friction.sheath_viscosity"),
        (
            with("[[needle.keyframe]]\naction = \"move\"\ndirection = [1.0, 0.0, 0.0]\nspeed = 0.01\nduration = 1.0\nspin = nan\n"),
            "needle.keyframe[0]",
        ),
        (
            with("[[needle.keyframe]]\naction = \"extract\"\nspeed = 0.01\nduration = 1.0\nspin = inf\n"),
            "needle.keyframe[0]",
        ),
    ];
    for (text, key) in cases {
        let r = Scene::from_toml_str(&text, Path::new("."))
            .map_err(SimulationError::from)
            .and_then(|s| Simulation::prepare(&s).map(|_| ()));
        let msg = r.expect_err(key).to_string();
        assert!(msg.contains(key), "`{key}` not in: {msg}");
    }
    // A needle longer than its node slots allow: a 4 cm needle with 2 cm spacing has
    // 5 slots; pushing it 10 cm (the needle moves past its own length) runs out.
    let text = with(
        "spacing = 0.01\n[[needle.keyframe]]\naction = \"move\"\ndirection = [1.0, 0.0, 0.0]\nspeed = 0.1\nduration = 2.0\n",
    )
    .replace("[physics]\ndt = 1e-3", "[physics]\ndt = 1e-3\ndamping = 5.0");
    let scene = Scene::from_toml_str(&text, Path::new(".")).unwrap();
    let prep = Simulation::prepare(&scene).unwrap();
    let b = needlesim::CpuBackend::new(prep.tissue.clone(), needlesim::Threading::Single).unwrap();
    let mut sim = prep.start(Box::new(b)).unwrap();
    let e = sim.step_n(2000).expect_err("capacity reached");
    assert!(
        matches!(e, SimulationError::Edit { .. }) && e.to_string().contains("capacity reached"),
        "{e}"
    );
}

/// The unit octahedron's faces as corner coordinates (1-based OBJ indices above).
fn octa_triangles(faces: &[&str]) -> Vec<[[f32; 3]; 3]> {
    let v = common::OCTAHEDRON_VERTICES;
    faces
        .iter()
        .map(|f| {
            let i: Vec<usize> = f
                .split_whitespace()
                .skip(1)
                .map(|x| x.parse().unwrap())
                .collect();
            [v[i[0] - 1], v[i[1] - 1], v[i[2] - 1]]
        })
        .collect()
}

/// ASCII STL text of `triangles` (normals left zero: readers recompute them).
fn ascii_stl(triangles: &[[[f32; 3]; 3]]) -> String {
    let mut s = String::from("solid octa\n");
    for t in triangles {
        s.push_str("facet normal 0 0 0\nouter loop\n");
        for p in t {
            s.push_str(&format!("vertex {} {} {}\n", p[0], p[1], p[2]));
        }
        s.push_str("endloop\nendfacet\n");
    }
    s.push_str("endsolid octa\n");
    s
}

/// Binary STL bytes of `triangles`: 80-byte header, count, then 50 bytes per triangle.
fn binary_stl(triangles: &[[[f32; 3]; 3]]) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
    for t in triangles {
        b.extend_from_slice(&[0u8; 12]);
        for p in t {
            for c in p {
                b.extend_from_slice(&c.to_le_bytes());
            }
        }
        b.extend_from_slice(&[0u8; 2]);
    }
    b
}

/// The octahedron as ASCII and as binary STL, written in millimetres and read with
/// `scale = 0.001`: both enclose the OBJ's 4/3 m^3 and get nodes inside; an open STL, an
/// inside-out one, a garbled one and a missing one are typed errors naming the file.
#[test]
fn stl_surfaces_ascii_and_binary_load_like_obj_and_bad_ones_are_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mm: Vec<[[f32; 3]; 3]> = octa_triangles(&OCTA_FACES)
        .iter()
        .map(|t| t.map(|p| p.map(|c| c * 1000.0)))
        .collect();
    std::fs::write(d.join("octa_ascii.stl"), ascii_stl(&mm)).unwrap();
    std::fs::write(d.join("octa_binary.stl"), binary_stl(&mm)).unwrap();
    let stl_scene = |file: &str| {
        obj_scene(file).replace(
            &format!("kind = \"obj\", path = \"{file}\", spacing = 0.25"),
            &format!("kind = \"stl\", path = \"{file}\", spacing = 0.25, scale = 0.001"),
        )
    };
    for file in ["octa_ascii.stl", "octa_binary.stl"] {
        let scene = Scene::from_toml_str(&stl_scene(file), d).unwrap();
        let t = Tissue::from_scene(&scene).unwrap_or_else(|e| panic!("{file}: {e}"));
        // f32 corners scaled in f64: the volume to 1e-9 relative.
        assert!(
            (t.volume - 4.0 / 3.0).abs() < 1e-9 * 4.0 / 3.0,
            "{file}: {}",
            t.volume
        );
        assert!(t.n_mesh > 6, "{file}: {} nodes", t.n_mesh);
        t.neighbours.check_mutual(t.n_mesh).unwrap();
    }
    let mut open = OCTA_FACES.to_vec();
    open.pop();
    std::fs::write(d.join("open.stl"), binary_stl(&octa_triangles(&open))).unwrap();
    let inside_out: Vec<[[f32; 3]; 3]> = octa_triangles(&OCTA_FACES)
        .iter()
        .map(|t| [t[0], t[2], t[1]])
        .collect();
    std::fs::write(d.join("inside_out.stl"), ascii_stl(&inside_out)).unwrap();
    std::fs::write(d.join("garbage.stl"), b"solid x\nfacet nonsense\n").unwrap();
    for (file, want) in [
        ("open.stl", "surface is open"),
        ("inside_out.stl", "volume"),
        ("garbage.stl", "cannot load surface file"),
        ("missing.stl", "cannot load surface file"),
    ] {
        let scene = Scene::from_toml_str(&stl_scene(file), d).unwrap();
        let e = Tissue::from_scene(&scene).unwrap_err().to_string();
        assert!(e.contains(want) && e.contains(file), "{file}: {e}");
    }
}
