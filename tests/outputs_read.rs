//! The output files read back by readers that are not our writers (issue 44): every
//! surface frame (`surface/surface_NNNNN.vtp`, written by needlesim's own XML writer) by
//! vtkio, and `surface.pvd` against the frames on disk. The CSV files are read with pandas
//! by `scripts/check_outputs.py` in `scripts/test`.

use needlesim::{run_scene, RunOptions, Scene};
use std::path::Path;
use vtkio::model::DataSet;

#[test]
fn surface_frames_read_back_with_vtkio() {
    let scene = Scene::from_toml_str(
        include_str!("../scenes/needle_insert_extract.toml"),
        Path::new("scenes"),
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut options = RunOptions::new(dir.path());
    options.steps = Some(1500);
    options.threads = Some(1);
    run_scene(&scene, &options, |_, _| {}).unwrap();
    let pvd = std::fs::read_to_string(dir.path().join("surface.pvd")).unwrap();
    let files: Vec<&str> = pvd
        .split("file=\"")
        .skip(1)
        .map(|s| &s[..s.find('"').unwrap()])
        .collect();
    // Frames every `output_every` (100) steps, from step 0: 16 for 1,500 steps.
    assert_eq!(files.len(), 16, "{pvd}");
    let mut sizes = Vec::new();
    for f in files {
        let path = dir.path().join(f);
        let vtk = vtkio::Vtk::import(&path).unwrap_or_else(|e| panic!("{f}: {e}"));
        let DataSet::PolyData { pieces, .. } = vtk.data else {
            panic!("{f}: not poly data");
        };
        assert_eq!(pieces.len(), 1, "{f}");
        let piece = pieces
            .into_iter()
            .next()
            .unwrap()
            .into_loaded_piece_data(Some(&path))
            .unwrap();
        let points: Vec<f64> = piece.points.cast_into().expect("numeric points");
        let n = points.len() / 3;
        assert!(
            n > 100 && points.iter().all(|x| x.is_finite()),
            "{f}: {n} points"
        );
        let (connectivity, offsets) = piece.polys.expect("polygons").into_xml();
        assert!(!offsets.is_empty(), "{f}: no polygons");
        assert!(
            connectivity.iter().all(|&v| (v as usize) < n),
            "{f}: a polygon names a point beyond {n}"
        );
        let mut start = 0;
        for &end in &offsets {
            assert_eq!(end - start, 3, "{f}: triangles only");
            start = end;
        }
        let displacement = piece
            .data
            .point
            .iter()
            .find_map(|a| match a {
                vtkio::model::Attribute::DataArray(d) if d.name == "displacement" => {
                    d.data.clone().cast_into::<f64>()
                }
                _ => None,
            })
            .expect("a displacement array");
        assert_eq!(displacement.len(), 3 * n, "{f}");
        sizes.push((n, offsets.len()));
    }
    // The needle splits surface triangles while it is in: the frames are not all alike,
    // and the first is the undisturbed surface.
    assert!(sizes.iter().any(|s| *s != sizes[0]), "{sizes:?}");
}
