//! Geometry on solids other than a box: surface resampling, lumped masses that add up to
//! density times volume, and a stable step that follows the spacing.

use needlesim::core::geometry::{self, obj::Surface, resample, shapes};
use needlesim::core::scene::{Geometry, NodeMasses, SurfaceGeometry, SurfaceNodes};
use needlesim::{Material, Scene, Tissue};
use std::fmt::Write as _;
use std::path::Path;

const DEB: Material = Material::debunne(1e4, 0.3);

fn write_obj(path: &Path, s: &Surface) {
    let mut text = String::new();
    for v in &s.vertices {
        writeln!(text, "v {:.17e} {:.17e} {:.17e}", v[0], v[1], v[2]).unwrap();
    }
    for t in &s.triangles {
        writeln!(text, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
    }
    std::fs::write(path, text).unwrap();
}

fn write_ascii_stl(path: &Path, s: &Surface) {
    let mut text = String::from("solid s\n");
    for t in &s.triangles {
        text.push_str(" facet normal 0 0 0\n  outer loop\n");
        for &v in t {
            let p = s.vertices[v as usize];
            writeln!(
                text,
                "   vertex {:e} {:e} {:e}",
                p[0] as f32, p[1] as f32, p[2] as f32
            )
            .unwrap();
        }
        text.push_str("  endloop\n endfacet\n");
    }
    text.push_str("endsolid s\n");
    std::fs::write(path, text).unwrap();
}

fn write_legacy_vtk(path: &Path, s: &Surface) {
    let mut text = format!(
        "# vtk DataFile Version 3.0\nball\nASCII\nDATASET POLYDATA\nPOINTS {} double\n",
        s.vertices.len()
    );
    for v in &s.vertices {
        writeln!(text, "{:.17e} {:.17e} {:.17e}", v[0], v[1], v[2]).unwrap();
    }
    writeln!(
        text,
        "POLYGONS {} {}",
        s.triangles.len(),
        4 * s.triangles.len()
    )
    .unwrap();
    for t in &s.triangles {
        writeln!(text, "3 {} {} {}", t[0], t[1], t[2]).unwrap();
    }
    std::fs::write(path, text).unwrap();
}

/// An XML unstructured grid of the surface's triangles (`cell_type` 5), or of anything
/// else with the same connectivity (10: tetrahedra, to test the error).
fn write_vtu(path: &Path, s: &Surface, cell_type: u8) {
    let join = |v: Vec<String>| v.join(" ");
    let points = join(
        s.vertices
            .iter()
            .flatten()
            .map(|c| format!("{c:.17e}"))
            .collect(),
    );
    let conn = join(
        s.triangles
            .iter()
            .flatten()
            .map(|c| c.to_string())
            .collect(),
    );
    let offsets = join(
        (1..=s.triangles.len())
            .map(|k| (3 * k).to_string())
            .collect(),
    );
    let types = join(vec![cell_type.to_string(); s.triangles.len()]);
    let text = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n\
         <Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n\
         <Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">{points}</DataArray></Points>\n\
         <Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">{conn}</DataArray>\n\
         <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">{offsets}</DataArray>\n\
         <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">{types}</DataArray>\n</Cells>\n\
         </Piece>\n</UnstructuredGrid>\n</VTKFile>\n",
        s.vertices.len(),
        s.triangles.len()
    );
    std::fs::write(path, text).unwrap();
}

fn scene(geometry: Geometry, masses: NodeMasses, dir: &Path) -> Scene {
    Scene::builder()
        .density(1070.0)
        .masses(masses)
        .geometry(geometry)
        .material(DEB)
        .base_dir(dir)
        .build()
        .unwrap()
}

/// Every geometry kind, with both mass rules: the node masses add up to density times
/// the enclosed volume (f64 sums: 1e-9 relative), and each free node's inverse mass in
/// the state is its own (f32: 1e-6 relative).
#[test]
fn total_mass_is_density_times_volume_for_every_geometry_kind() {
    let dir = tempfile::tempdir().unwrap();
    let ball = shapes::icosphere([0.01, 0.02, 0.03], 0.04, 3);
    write_obj(&dir.path().join("ball.obj"), &ball);
    write_ascii_stl(&dir.path().join("ball.stl"), &ball);
    write_legacy_vtk(&dir.path().join("ball.vtk"), &ball);
    write_vtu(&dir.path().join("ball.vtu"), &ball, 5);
    let (lo, hi) = ([0.0; 3], [0.05, 0.03, 0.04]);
    let kinds = [
        ("box, spacing", Geometry::box_with_spacing(lo, hi, 0.01)),
        ("box, nodes", Geometry::box_with_nodes(lo, hi, 300)),
        (
            "obj ball.obj",
            Geometry::Obj(SurfaceGeometry::new("ball.obj", 0.012)),
        ),
        (
            "obj ball.obj, surface vertices",
            Geometry::Obj(
                SurfaceGeometry::new("ball.obj", 0.012).with_surface(SurfaceNodes::Vertices),
            ),
        ),
        (
            "stl ball.stl",
            Geometry::Stl(SurfaceGeometry::new("ball.stl", 0.012)),
        ),
        (
            "vtk ball.vtk",
            Geometry::Vtk(SurfaceGeometry::new("ball.vtk", 0.012)),
        ),
        (
            "vtk ball.vtu",
            Geometry::Vtk(SurfaceGeometry::new("ball.vtu", 0.012)),
        ),
    ];
    for (kind, geometry) in &kinds {
        for (masses, rule) in [("cell", NodeMasses::Cell), ("uniform", NodeMasses::Uniform)] {
            let s = scene(geometry.clone(), rule, dir.path());
            let t = Tissue::from_scene(&s).unwrap_or_else(|e| panic!("{kind}: {e}"));
            let total: f64 = t.masses.iter().sum();
            let want = 1070.0 * t.volume;
            assert!(
                (total / want - 1.0).abs() < 1e-9,
                "{kind} {masses}: {total} kg vs {want} kg"
            );
            for (i, p) in t.state.positions[..t.n_mesh].iter().enumerate() {
                let m = 1.0 / p[3] as f64;
                assert!(
                    (m / t.masses[i] - 1.0).abs() < 1e-6,
                    "{kind} {masses}: node {i}"
                );
            }
            if kind.contains("ball") {
                // The file's volume, not the resampled surface's (STL stores f32).
                assert!((t.volume / ball.volume - 1.0).abs() < 1e-6, "{kind}");
            }
            if kind.contains("ball.vt") && masses == "cell" {
                // VTK files give the same nodes as the OBJ of the same surface (tobj reads
                // f32, vtkio f64: positions agree to f32 rounding, 1e-8 m here).
                let obj = scene(kinds[2].1.clone(), rule, dir.path());
                let o = Tissue::from_scene(&obj).unwrap();
                assert_eq!(o.n_mesh, t.n_mesh, "{kind}");
                for (a, b) in o.state.positions.iter().zip(&t.state.positions) {
                    assert!(
                        (0..3).all(|c| (a[c] - b[c]).abs() < 1e-8),
                        "{kind}: {a:?} {b:?}"
                    );
                    assert!((a[3] / b[3] - 1.0).abs() < 1e-4, "{kind}: {a:?} {b:?}");
                }
            }
        }
    }
    // A box corner node stands for an eighth of an interior cell, an edge node a quarter.
    let s = scene(kinds[0].1.clone(), NodeMasses::Cell, dir.path());
    let t = Tissue::from_scene(&s).unwrap();
    let interior = 1070.0 * 0.01f64.powi(3);
    assert!((t.masses[0] / interior - 0.125).abs() < 1e-9);
    assert!((t.masses[1] / interior - 0.25).abs() < 1e-9);
    assert!((t.node_mass / interior - 1.0).abs() < 1e-12);
}

/// A sphere's resampled node count depends on the spacing, not on the file: 320 or 81,920
/// triangles give counts within 5% of each other and within 25% of a cube of the same
/// volume at the same spacing. The new surface is closed and outward, its vertices lie
/// within a spacing of the sphere, and it encloses the sphere's volume to 5% (a polyhedron
/// inscribed at a fifth of the radius).
#[test]
fn resampled_node_count_follows_the_spacing_not_the_triangle_count() {
    let r = 0.05;
    let h = r / 5.0;
    let mut counts = Vec::new();
    for subdivisions in [2, 6] {
        let s = shapes::icosphere([0.0; 3], r, subdivisions);
        let c = resample::resample(&s, h, Path::new("sphere")).unwrap();
        geometry::obj::check_closed_manifold(Path::new("sphere"), c.positions.len(), &c.triangles)
            .unwrap();
        let enclosed = geometry::signed_volume(&c.positions, &c.triangles);
        assert!(
            (enclosed / s.volume - 1.0).abs() < 0.05,
            "{enclosed} vs {}",
            s.volume
        );
        let n_surface = *c.triangles.iter().flatten().max().unwrap() as usize + 1;
        for p in &c.positions[..n_surface] {
            let d = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            assert!(
                (d - r).abs() < h,
                "surface node {p:?} is {d} m from the centre"
            );
        }
        for p in &c.positions[n_surface..] {
            let d = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            assert!(d < r - 0.45 * h, "interior node {p:?} too near the surface");
        }
        counts.push(c.positions.len() as f64);
    }
    assert!((counts[1] / counts[0] - 1.0).abs() < 0.05, "{counts:?}");
    let side = (4.0 / 3.0 * std::f64::consts::PI).cbrt() * r;
    let cube = (side / h + 1.0).powi(3);
    for c in &counts {
        assert!(
            (c / cube - 1.0).abs() < 0.25,
            "{c} nodes vs {cube} for a cube"
        );
    }
}

/// The explicit step of an elastic body scales with its node spacing: halving the spacing
/// of a resampled sphere halves the estimated critical step, within 25% (surface nodes
/// sit at varying depths in their cells, so the ratio is not exact).
#[test]
fn the_stable_step_follows_the_spacing_on_a_sphere() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(
        Geometry::box_with_spacing([0.0; 3], [0.1; 3], 0.02),
        NodeMasses::Cell,
        dir.path(),
    );
    let ball = shapes::icosphere([0.0; 3], 0.05, 4);
    let mut dts = Vec::new();
    for h in [0.0125, 0.00625] {
        let cloud = resample::resample(&ball, h, Path::new("ball")).unwrap();
        let t = Tissue::from_cloud(&s, cloud, 0).unwrap();
        let mut b = needlesim::CpuBackend::new(t, needlesim::Threading::Parallel).unwrap();
        let est = needlesim::core::stability::max_eigenvalue(&mut b, 40).unwrap();
        dts.push(est.critical_dt);
    }
    let ratio = dts[0] / dts[1];
    assert!((1.5..=2.5).contains(&ratio), "critical steps {dts:?}");
}

/// VTK files that hold no closed surface are rejected with the reason: volume cells only,
/// an open surface, a cell that uses a missing point, a file that is not VTK.
#[test]
fn bad_vtk_files_are_rejected_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ball = shapes::icosphere([0.0; 3], 0.04, 1);
    write_vtu(&d.join("tets.vtu"), &ball, 10);
    let mut open = ball.clone();
    open.triangles.pop();
    write_legacy_vtk(&d.join("open.vtk"), &open);
    let mut missing = ball.clone();
    missing.triangles[0][0] = 9999;
    write_legacy_vtk(&d.join("missing.vtk"), &missing);
    std::fs::write(d.join("garbage.vtk"), "not a vtk file\n").unwrap();
    for (file, reason) in [
        ("tets.vtu", "no surface cells"),
        ("open.vtk", "open"),
        ("missing.vtk", "point 9999"),
        ("garbage.vtk", "cannot load"),
        ("absent.vtp", "cannot load"),
    ] {
        let err = Scene::builder()
            .geometry(Geometry::Vtk(SurfaceGeometry::new(file, 0.01)))
            .material(DEB)
            .base_dir(d)
            .build()
            .and_then(|s| Tissue::from_scene(&s).map(|_| ()))
            .expect_err(file);
        let msg = err.to_string();
        assert!(msg.contains(reason) && msg.contains(file), "{file}: {msg}");
    }
}

/// A millimetre mesh read without `scale = 0.001` asks for a lattice a billion times too
/// large: the size check names the key and suggests the scale, before allocating.
#[test]
fn a_unit_mistake_is_caught_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    write_obj(
        &dir.path().join("mm.obj"),
        &shapes::icosphere([0.0; 3], 50.0, 2),
    );
    let scene = Scene::builder()
        .obj(SurfaceGeometry::new("mm.obj", 0.005))
        .material(DEB)
        .base_dir(dir.path())
        .build()
        .unwrap();
    let err = Tissue::from_scene(&scene).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("tissue.geometry.spacing") && msg.contains("scale"),
        "{msg}"
    );
}

/// `rotate` and `translate` move a surface file rigidly (after `scale`). A shift alone
/// shifts every node (same count, positions within 1e-9 m: f64, on a spacing that puts
/// no lattice point on the surface). A capsule along y (the
/// file in millimetres) turned 90 degrees about z and shifted lies where the turned file
/// lies: its nodes' bounds are inside the turned file's bounds and within a quarter
/// spacing of them (resampled vertices sit on the surface; the lattice is anchored at
/// the new bounds, so the nodes themselves differ), and the total mass is unchanged
/// (1e-9 relative: the enclosed volume is). Bad transforms are errors naming their key.
#[test]
fn surface_files_can_be_rotated_and_translated() {
    let dir = tempfile::tempdir().unwrap();
    let capsule = shapes::capsule([0.0; 3], 100.0, 20.0, 48, 12);
    write_obj(&dir.path().join("cap.obj"), &capsule);
    // Not a divisor of the radius: no lattice point lies exactly on the surface, where
    // the shifted lattice's rounding could flip an inside test.
    let h = 0.0047;
    let base = SurfaceGeometry::new("cap.obj", h).with_scale(0.001);
    let obj = |g: SurfaceGeometry| scene(Geometry::Obj(g), NodeMasses::Cell, dir.path());
    let plain = obj(base.clone());
    let shifted = obj(base.clone().with_translate([0.5, -0.25, 1.0]));
    let moved = obj(base
        .clone()
        .with_rotate([0.0, 0.0, 2.0], 90.0)
        .with_translate([0.5, -0.25, 1.0]));
    let cloud = |s: &Scene| geometry::build(&s.tissue.geometry, dir.path()).unwrap();
    let (a, b) = (cloud(&plain), cloud(&shifted));
    assert_eq!(a.positions.len(), b.positions.len());
    for (p, q) in a.positions.iter().zip(&b.positions) {
        let t = [0.5, -0.25, 1.0];
        assert!(
            (0..3).all(|k| (p[k] + t[k] - q[k]).abs() < 1e-9),
            "{p:?} {q:?}"
        );
    }
    // The file spans x, z in [-20, 20] mm and y in [0, 100] mm; (x, y, z) -> (-y, x, z) + t.
    let expect_lo = [-0.1 + 0.5, -0.02 - 0.25, -0.02 + 1.0];
    let expect_hi = [0.5, 0.02 - 0.25, 0.02 + 1.0];
    let (lo, hi) = geometry::bounds(&cloud(&moved).positions);
    for a in 0..3 {
        let inside = lo[a] > expect_lo[a] - 1e-9 && hi[a] < expect_hi[a] + 1e-9;
        let near = lo[a] < expect_lo[a] + 0.25 * h && hi[a] > expect_hi[a] - 0.25 * h;
        assert!(
            inside && near,
            "axis {a}: [{}, {}] vs [{}, {}]",
            lo[a],
            hi[a],
            expect_lo[a],
            expect_hi[a]
        );
    }
    let mass = |s: &Scene| Tissue::from_scene(s).unwrap().masses.iter().sum::<f64>();
    let (m0, m1) = (mass(&plain), mass(&moved));
    assert!((m1 / m0 - 1.0).abs() < 1e-9, "{m0} vs {m1}");
    for (bad, geometry, key) in [
        (
            "rotate = { axis = [0.0, 0.0, 0.0], degrees = 90.0 }",
            base.clone().with_rotate([0.0; 3], 90.0),
            "tissue.geometry.rotate.axis",
        ),
        (
            "rotate = { axis = [0.0, 1.0, 0.0], degrees = inf }",
            base.clone().with_rotate([0.0, 1.0, 0.0], f64::INFINITY),
            "tissue.geometry.rotate.degrees",
        ),
        (
            "translate = [0.0, nan, 0.0]",
            base.clone().with_translate([0.0, f64::NAN, 0.0]),
            "tissue.geometry.translate",
        ),
        (
            "translate = [1e6, 0.0, 0.0]",
            base.clone().with_translate([1e6, 0.0, 0.0]),
            "tissue.geometry.translate",
        ),
    ] {
        let err = Scene::builder()
            .obj(geometry)
            .material(DEB)
            .base_dir(dir.path())
            .build()
            .map_err(|e| e.to_string())
            .and_then(|s| {
                Tissue::from_scene(&s)
                    .map(|_| ())
                    .map_err(|e| e.to_string())
            })
            .unwrap_err();
        assert!(err.contains(key), "{bad}: {err}");
    }
}
