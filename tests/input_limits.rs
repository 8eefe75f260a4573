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
    for part in ["1.581e7 nodes", "GiB", "run.max_memory_gib", "spacing 0.004"] {
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
    assert!(msg.contains("nodes") && msg.contains("run.max_memory_gib"), "{msg}");
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
