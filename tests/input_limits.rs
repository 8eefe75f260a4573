//! Input at the limits: scenes that would need more memory than allowed, bodies too far
//! from the origin or too large or small for f32 positions, nodes left without live
//! neighbours, and overlapping surface shells all give typed errors naming the key,
//! before anything large is allocated and never a panic.

use needlesim::{Scene, SceneError, Tissue};
use std::path::Path;

/// A box scene with `geometry` (the inline table's keys) and `extra` appended.
fn box_scene(geometry: &str, extra: &str) -> String {
    format!(
        "[tissue]\ngeometry = {{ kind = \"box\", {geometry} }}\n[material]\n\
         model = \"local_shape_matching\"\nstiffness = 20.0\n{extra}"
    )
}

/// Parses `text` (paths relative to `base`) and builds its tissue.
fn build(text: &str, base: &Path) -> Result<Tissue, SceneError> {
    Tissue::from_scene(&Scene::from_toml_str(text, base)?)
}

/// The key and the message of the error building `text` gives.
fn key_and_message(text: &str, base: &Path) -> (String, String) {
    match build(text, base) {
        Ok(t) => panic!("accepted, {} nodes: {text}", t.n_mesh),
        Err(e) => {
            let msg = e.to_string();
            match e {
                SceneError::InvalidValue { key, .. } => (key, msg),
                other => panic!("not an invalid value: {other}"),
            }
        }
    }
}

/// A box of 1.6e7 nodes (under the 5e7 supported) needs about 11 GiB: refused before the
/// lattice is built, naming the spacing, the node count, the bytes and the override.
#[test]
fn a_box_beyond_the_memory_limit_names_the_spacing_and_the_override() {
    let text = box_scene("min = [0, 0, 0], max = [1, 1, 1], spacing = 0.004", "");
    let (key, msg) = key_and_message(&text, Path::new("."));
    assert_eq!(key, "tissue.geometry.spacing", "{msg}");
    for part in [
        "1.581e7 nodes",
        "GiB",
        "run.max_memory_gib",
        "spacing 0.004",
        "choose a coarser",
    ] {
        assert!(msg.contains(part), "{part:?} missing: {msg}");
    }
    // The estimate itself, without building anything, with a larger limit.
    let scene = Scene::from_toml_str(
        &box_scene(
            "min = [0, 0, 0], max = [1, 1, 1], spacing = 0.004",
            "[run]\nmax_memory_gib = 64.0\n",
        ),
        Path::new("."),
    )
    .unwrap();
    let est = needlesim::core::geometry::check_memory(
        &scene,
        &needlesim::core::geometry::MeshEstimate::built(251usize.pow(3)),
        0.0,
        "needle.length",
    )
    .unwrap();
    assert!(est.bytes > 8.0 * (1u64 << 30) as f64 && est.bytes < est.limit);
}

/// `run.max_memory_gib` is the limit: a small box passes by default and fails under a
/// tiny limit; a bad value names the key.
#[test]
fn the_memory_limit_is_the_scenes_override() {
    let geometry = "min = [0, 0, 0], max = [0.1, 0.1, 0.1], spacing = 0.01";
    assert_eq!(
        build(&box_scene(geometry, ""), Path::new("."))
            .unwrap()
            .n_mesh,
        1331
    );
    let tiny = box_scene(geometry, "[run]\nmax_memory_gib = 1e-4\n");
    let (key, msg) = key_and_message(&tiny, Path::new("."));
    assert_eq!(key, "tissue.geometry.spacing", "{msg}");
    assert!(msg.contains("0.0001 GiB"), "{msg}");
    for bad in ["0.0", "-1.0", "nan", "inf"] {
        let text = box_scene(geometry, &format!("[run]\nmax_memory_gib = {bad}\n"));
        let (key, msg) = key_and_message(&text, Path::new("."));
        assert_eq!(key, "run.max_memory_gib", "{msg}");
    }
}

/// Nodes that would fit with the default 18 neighbours but not with 64: the error names
/// `tissue.neighbours`.
#[test]
fn many_neighbours_beyond_the_limit_name_tissue_neighbours() {
    let text = box_scene(
        "min = [0, 0, 0], max = [0.1, 0.1, 0.1], spacing = 0.01",
        "[run]\nmax_memory_gib = 0.001\n",
    )
    .replace("[tissue]\n", "[tissue]\nneighbours = 64\n");
    let (key, msg) = key_and_message(&text, Path::new("."));
    assert_eq!(key, "tissue.neighbours", "{msg}");
    assert!(msg.contains("64 neighbours"), "{msg}");
}

/// A surface file scaled by 200 (a 20 m ball at a 1 cm spacing: 5e8 nodes) is refused
/// once the file is read, before the lattice is built, naming `scale`.
#[test]
fn a_surface_scaled_to_billions_of_nodes_names_the_scale() {
    let text = "[tissue]\ngeometry = { kind = \"obj\", path = \"meshes/sphere.obj\", \
                spacing = 0.01, scale = 200.0 }\n[material]\nmodel = \"mass_spring\"\n\
                stiffness = 100.0\n";
    let (key, msg) = key_and_message(text, Path::new("scenes"));
    assert_eq!(key, "tissue.geometry.scale", "{msg}");
    assert!(
        msg.contains("nodes") && msg.contains("run.max_memory_gib"),
        "{msg}"
    );
    // The same ball at its own size builds.
    let ok = text.replace(", scale = 200.0", "");
    assert!(build(&ok, Path::new("scenes")).unwrap().n_mesh > 500);
}

/// Spare node slots (the needle's) enter the estimate; even `usize::MAX` of them is an
/// error naming the needle, not an overflow or an abort.
#[test]
fn spare_node_slots_enter_the_estimate() {
    let scene = Scene::from_toml_str(
        &box_scene("min = [0, 0, 0], max = [0.1, 0.1, 0.1], spacing = 0.02", ""),
        Path::new("."),
    )
    .unwrap();
    assert!(Tissue::from_scene_with_capacity(&scene, 100).is_ok());
    for extra in [50_000_000, usize::MAX] {
        match Tissue::from_scene_with_capacity(&scene, extra) {
            Err(SceneError::InvalidValue { key, reason }) => {
                assert_eq!(key, "needle.length", "{reason}");
                assert!(reason.contains("node slots"), "{reason}");
            }
            other => panic!("{extra} slots: {:?}", other.map(|t| t.n_mesh)),
        }
    }
}

/// An OBJ of axis-aligned cubes (`(corner, side)` each, one closed shell per cube),
/// outward oriented.
fn cubes_obj(cubes: &[([f64; 3], f64)]) -> String {
    let mut s = String::new();
    for (c, (o, a)) in cubes.iter().enumerate() {
        for k in 0..8 {
            let (x, y, z) = (k & 1, k >> 1 & 1, k >> 2 & 1);
            // Corners in the order 1 (0,0,0), 2 (1,0,0), 3 (1,1,0), 4 (0,1,0), then z = 1.
            let (x, y) = [(0, 0), (1, 0), (1, 1), (0, 1)][x + 2 * y];
            s += &format!(
                "v {} {} {}\n",
                o[0] + x as f64 * a,
                o[1] + y as f64 * a,
                o[2] + z as f64 * a
            );
        }
        let b = 8 * c;
        for f in [
            [1, 3, 2],
            [1, 4, 3],
            [5, 6, 7],
            [5, 7, 8],
            [1, 2, 6],
            [1, 6, 5],
            [4, 8, 7],
            [4, 7, 3],
            [1, 5, 8],
            [1, 8, 4],
            [2, 3, 7],
            [2, 7, 6],
        ] {
            s += &format!("f {} {} {}\n", b + f[0], b + f[1], b + f[2]);
        }
    }
    s
}

/// A surface-file scene for `path` with the geometry's extra keys and `neighbours`.
fn surface_scene(path: &str, keys: &str, neighbours: usize) -> String {
    format!(
        "[tissue]\nneighbours = {neighbours}\ngeometry = {{ kind = \"obj\", path = \"{path}\", \
         {keys} }}\n[material]\nmodel = \"mass_spring\"\nstiffness = 100.0\n"
    )
}

/// A 1 m cube of 8 vertices kept as nodes (`surface = "vertices"`) at a 0.1 m spacing:
/// each corner is 0.17 m from the nearest interior node, whose 6 nearest are all at 0.1 or
/// 0.14 m, so with 6 neighbours no node lists a corner back. It used to build with 8
/// detached corners; now it is an error naming the node, where it is and its live count.
#[test]
fn a_node_without_live_neighbours_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("cube.obj"), cubes_obj(&[([0.0; 3], 1.0)])).unwrap();
    let vertices = "spacing = 0.1, surface = \"vertices\"";
    let (key, msg) = key_and_message(&surface_scene("cube.obj", vertices, 6), dir.path());
    assert_eq!(key, "tissue.geometry.spacing", "{msg}");
    for part in [
        "node 0 at (0.0000e0, 0.0000e0, 0.0000e0) m",
        "0 live neighbours",
    ] {
        assert!(msg.contains(part), "{part:?} missing: {msg}");
    }
    // With the default 18 neighbours, or resampled, every node keeps live neighbours.
    for (keys, k) in [(vertices, 18), ("spacing = 0.1", 6)] {
        let t = build(&surface_scene("cube.obj", keys, k), dir.path()).unwrap();
        assert!(t.neighbours.stats(t.n_mesh).min >= 1, "{keys}, {k}");
    }
}

/// The shipped 10 cm ball (`scenes/meshes/sphere.obj`) scaled by 1e30 or 1e-30, with
/// the spacing as given or scaled along: the body is then 1e29 m or 1e-31 m across, far
/// outside what f32 positions, volumes and masses can carry. Each is an error naming
/// `scale`, never a panic or a run with meaningless rounding.
#[test]
fn absurd_surface_scales_name_the_scale() {
    for (scale, spacing) in [(1e30, 0.01), (1e30, 1e28), (1e-30, 0.01), (1e-30, 1e-32)] {
        let text = surface_scene(
            "meshes/sphere.obj",
            &format!("spacing = {spacing:e}, scale = {scale:e}"),
            16,
        );
        let r = std::panic::catch_unwind(|| key_and_message(&text, Path::new("scenes")));
        let (key, msg) = r.unwrap_or_else(|_| panic!("scale {scale}, spacing {spacing}"));
        assert_eq!(
            key, "tissue.geometry.scale",
            "scale {scale}, spacing {spacing}: {msg}"
        );
    }
}

/// Boxes and spacings outside 1e-9 to 1e6 m name the key: the box's side, its spacing or
/// its node count (a tiny box of many nodes), and the scaled-along surface's spacing.
#[test]
fn lengths_beyond_f32_name_the_key() {
    let cases = [
        (
            "min = [0, 0, 0], max = [1e7, 1, 1], nodes = 639",
            "tissue.geometry.max",
        ),
        (
            "min = [0, 0, 0], max = [1e-8, 1e-8, 1e-8], spacing = 1e-10",
            "tissue.geometry.spacing",
        ),
        (
            "min = [0, 0, 0], max = [1e-8, 1e-8, 1e-8], nodes = 10000",
            "tissue.geometry.nodes",
        ),
    ];
    for (geometry, want) in cases {
        let (key, msg) = key_and_message(&box_scene(geometry, ""), Path::new("."));
        assert_eq!(key, want, "{geometry}: {msg}");
        assert!(msg.contains("f32"), "{msg}");
    }
    let text = surface_scene("meshes/sphere.obj", "spacing = 1e-10", 16);
    let (key, msg) = key_and_message(&text, Path::new("scenes"));
    assert_eq!(key, "tissue.geometry.spacing", "{msg}");
}

/// Two cubes in one OBJ overlapping (by half along x, or one inside the other), or a
/// smaller one inside out beside the first (total volume still positive), are refused naming `tissue.geometry.path`, the winding number and
/// where; two disjoint cubes, and a cube with an inside-out cube as a cavity, build.
#[test]
fn overlapping_or_inverted_shells_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = |name: &str, obj: String, surface: &str| {
        std::fs::write(dir.path().join(name), obj).unwrap();
        surface_scene(name, &format!("spacing = 0.1, surface = \"{surface}\""), 18)
    };
    // Swaps two corners of every face of the shells after the first: inside out.
    let invert_later = |obj: String| -> String {
        let mut faces = 0;
        obj.lines()
            .map(|l| {
                if let Some(f) = l.strip_prefix("f ") {
                    faces += 1;
                    if faces > 12 {
                        let v: Vec<&str> = f.split(' ').collect();
                        return format!("f {} {} {}\n", v[0], v[2], v[1]);
                    }
                }
                format!("{l}\n")
            })
            .collect()
    };
    for surface in ["resample", "vertices"] {
        let bad = [
            (
                "half.obj",
                cubes_obj(&[([0.0; 3], 1.0), ([0.5, 0.2, 0.1], 1.0)]),
                "2",
            ),
            (
                "nested.obj",
                cubes_obj(&[([0.0; 3], 1.0), ([0.3; 3], 0.4)]),
                "2",
            ),
            (
                "inverted.obj",
                invert_later(cubes_obj(&[([0.0; 3], 1.0), ([2.0, 0.0, 0.0], 0.5)])),
                "-1",
            ),
        ];
        for (name, obj, winding) in bad {
            let (key, msg) = key_and_message(&scene(name, obj, surface), dir.path());
            assert_eq!(key, "tissue.geometry.path", "{name}: {msg}");
            assert!(
                msg.contains(name) && msg.contains(&format!("is {winding}, not 0 or 1")),
                "{name}: {msg}"
            );
        }
        let good = [
            (
                "apart.obj",
                cubes_obj(&[([0.0; 3], 1.0), ([1.5, 0.2, 0.1], 1.0)]),
            ),
            (
                "cavity.obj",
                invert_later(cubes_obj(&[([0.0; 3], 1.0), ([0.3; 3], 0.4)])),
            ),
        ];
        for (name, obj) in good {
            let t = build(&scene(name, obj, surface), dir.path()).unwrap();
            let want = if name == "apart.obj" {
                2.0
            } else {
                1.0 - 0.064
            };
            // OBJ coordinates are read as f32.
            assert!((t.volume - want).abs() < 1e-6, "{name}: {}", t.volume);
        }
    }
}
