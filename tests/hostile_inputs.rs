//! Hostile inputs (issue 45): surface files whose declared counts their bytes cannot hold,
//! parallel VTK files, OBJ material libraries that name devices or pipes, thread counts
//! far beyond any machine, held sets that conflict or whose names would corrupt the
//! reaction CSV, and checkpoints of a diverged state or over something that is not a
//! regular file. Each case failed before (a panic, an abort on a huge allocation, a hang,
//! or a silent wrong result) and is now a typed error naming the file, key or set.

mod common;

use common::{OCTAHEDRON_TRIANGLES, OCTAHEDRON_VERTICES};
use needlesim::{Scene, Tissue};
use std::path::Path;
use std::time::{Duration, Instant};

/// A scene whose tissue is the surface file `file` (of `kind`) in `dir`.
fn surface_scene(kind: &str, file: &str) -> String {
    format!(
        "[tissue]\nneighbours = 6\ngeometry = {{ kind = \"{kind}\", path = \"{file}\", spacing = 0.25 }}\n\
         [material]\nmodel = \"mass_spring\"\nstiffness = 1.0\n"
    )
}

/// The error building the tissue of `kind` file `file` in `dir`, within 10 s.
fn surface_error(dir: &Path, kind: &str, file: &str) -> String {
    let start = Instant::now();
    let e = match Scene::from_toml_str(&surface_scene(kind, file), dir)
        .and_then(|scene| Tissue::from_scene(&scene))
    {
        Ok(_) => panic!("{file}: accepted"),
        Err(e) => e.to_string(),
    };
    assert!(
        start.elapsed() < Duration::from_secs(10),
        "{file}: {:?} to fail",
        start.elapsed()
    );
    assert!(
        e.contains(file),
        "{file}: the error does not name the file: {e}"
    );
    e
}

const OCTA_POINTS: &str = "1 0 0\n-1 0 0\n0 1 0\n0 -1 0\n0 0 1\n0 0 -1\n";

/// Legacy VTK poly data of the unit octahedron with `points` and `polygons` headers
/// replaced as given.
fn legacy_vtk(points_header: &str, polygons_header: &str) -> String {
    format!(
        "# vtk DataFile Version 3.0\noctahedron\nASCII\nDATASET POLYDATA\n{points_header}\n{OCTA_POINTS}\
         {polygons_header}\n3 0 2 4\n3 2 1 4\n3 1 3 4\n3 3 0 4\n3 2 0 5\n3 1 2 5\n3 3 1 5\n3 0 3 5\n"
    )
}

#[test]
fn vtk_files_declaring_more_than_their_bytes_hold_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The good file loads (the checks let a real file through).
    std::fs::write(
        d.join("good.vtk"),
        legacy_vtk("POINTS 6 float", "POLYGONS 8 32"),
    )
    .unwrap();
    let scene = Scene::from_toml_str(&surface_scene("vtk", "good.vtk"), d).unwrap();
    let t = Tissue::from_scene(&scene).unwrap();
    assert!((t.volume - 4.0 / 3.0).abs() < 1e-6, "{}", t.volume);
    // A billion points in a 300-byte file: an abort on a 24 GB allocation before.
    std::fs::write(
        d.join("huge_points.vtk"),
        legacy_vtk("POINTS 1000000000 double", "POLYGONS 8 32"),
    )
    .unwrap();
    let e = surface_error(d, "vtk", "huge_points.vtk");
    assert!(e.contains("POINTS 1000000000"), "{e}");
    // Cell counts that disagree with the header: a panic in the reader before.
    std::fs::write(
        d.join("cells.vtk"),
        legacy_vtk("POINTS 6 float", "POLYGONS 8 9000000000"),
    )
    .unwrap();
    let e = surface_error(d, "vtk", "cells.vtk");
    assert!(e.contains("POLYGONS"), "{e}");
    std::fs::write(
        d.join("few.vtk"),
        legacy_vtk("POINTS 6 float", "POLYGONS 8 5"),
    )
    .unwrap();
    surface_error(d, "vtk", "few.vtk");
    // XML with a huge declared point count.
    std::fs::write(
        d.join("huge.vtp"),
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"0.1\">\n<PolyData>\n\
         <Piece NumberOfPoints=\"4000000000\" NumberOfPolys=\"1\">\n</Piece>\n</PolyData>\n</VTKFile>\n",
    )
    .unwrap();
    let e = surface_error(d, "vtk", "huge.vtp");
    assert!(e.contains("NumberOfPoints"), "{e}");
    // A parallel file whose piece is itself: a stack overflow before.
    std::fs::write(
        d.join("self.pvtp"),
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"PPolyData\" version=\"0.1\">\n<PPolyData>\n\
         <Piece Source=\"self.pvtp\"/>\n</PPolyData>\n</VTKFile>\n",
    )
    .unwrap();
    let e = surface_error(d, "vtk", "self.pvtp");
    assert!(e.contains("parallel"), "{e}");
    std::fs::copy(d.join("self.pvtp"), d.join("disguised.vtp")).unwrap();
    let e = surface_error(d, "vtk", "disguised.vtp");
    assert!(e.contains("other files"), "{e}");
}

/// What a fuzzing pass over the readers found (about 5,400 damaged or crafted files, on
/// the dev machine): each was a panic, an abort on a 5 to 64 GB allocation, or a zlib
/// bomb inflated to 2 GB before it failed; each is now a typed error naming the file and
/// the cause, while the valid variants load.
#[test]
fn fuzzed_vtk_files_are_typed_errors() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let octa = legacy_vtk("POINTS 6 float", "POLYGONS 8 32");
    let cases: Vec<(&str, String, &str)> = vec![
        // The legacy checks were skipped for a file not starting with its header line.
        (
            "newline.vtk",
            format!(
                "\n{}",
                legacy_vtk("POINTS 1000000000 double", "POLYGONS 8 32")
            ),
            "POINTS 1000000000",
        ),
        (
            "bom.vtk",
            format!(
                "\u{feff}{}",
                legacy_vtk("POINTS 1000000000 double", "POLYGONS 8 32")
            ),
            "POINTS 1000000000",
        ),
        // ... and read only the first word of a line.
        (
            "same_line.vtk",
            octa.replace(
                "DATASET POLYDATA\nPOINTS 6 float",
                "DATASET POLYDATA POINTS 1000000000 double",
            ),
            "POINTS 1000000000",
        ),
        // Attribute counts were not checked at all.
        (
            "scalars.vtk",
            format!("{octa}POINT_DATA 6\nSCALARS s float 1000000000\n"),
            "1 to 4 components",
        ),
        (
            "lookup.vtk",
            format!("{octa}POINT_DATA 6\nLOOKUP_TABLE t 1000000000\n"),
            "LOOKUP_TABLE t 1000000000",
        ),
        (
            "colours.vtk",
            format!("{octa}POINT_DATA 6\nCOLOR_SCALARS c 1000000000\n"),
            "COLOR_SCALARS",
        ),
        (
            "texture.vtk",
            format!("{octa}POINT_DATA 6\nTEXTURE_COORDINATES t 1000000000 float\n"),
            "1 to 3 dimensions",
        ),
        (
            "field_arrays.vtk",
            format!("{octa}POINT_DATA 6\nFIELD f 1000000000\n"),
            "FIELD f 1000000000",
        ),
        // 100000 x 100000 wraps in the reader's u32 product: a 5.6 GB allocation.
        (
            "field_dims.vtk",
            format!("{octa}POINT_DATA 6\nFIELD f 1\nfoo 100000 100000 float\n0 0 0\n"),
            "foo 100000 100000 float",
        ),
        // Cell lists that disagree with their header ("holds no surface cells" or a
        // failed assertion inside the reader before).
        ("negative.vtk", octa.replace("3 0 2 4", "3 0 2 -1"), "`-1`"),
        (
            "short.vtk",
            legacy_vtk("POINTS 6 float", "POLYGONS 8 30"),
            "hold 32 numbers, not the 30",
        ),
        (
            "beyond.vtk",
            octa.replace("3 0 2 4", "3 0 2 6"),
            "uses point 6",
        ),
        (
            "v51.vtk",
            octa.replace("POLYGONS 8 32\n", "POLYGONS 9 24\nOFFSETS vtktypeint64\n"),
            "5.1",
        ),
    ];
    for (file, text, says) in &cases {
        std::fs::write(d.join(file), text).unwrap();
        let e = surface_error(d, "vtk", file);
        assert!(e.contains(says), "{file}: {e}");
    }
    // The same octahedron with a byte order mark or a blank line first still loads.
    for (file, text) in [
        ("bom_ok.vtk", format!("\u{feff}{octa}")),
        ("blank_ok.vtk", format!("\n\n{octa}")),
    ] {
        std::fs::write(d.join(file), text).unwrap();
        let scene = Scene::from_toml_str(&surface_scene("vtk", file), d).unwrap();
        let t = Tissue::from_scene(&scene).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!((t.volume - 4.0 / 3.0).abs() < 1e-6, "{file}: {}", t.volume);
    }
}

/// XML VTK: offsets taken in the lossily decoded text indexed past the bytes (a panic), a
/// base64 header shorter than its block count (a panic), and the zlib check passed by
/// an `encoding` in single quotes or with blanks round its `=`, or by a file without
/// `header_type` (vtkio read 8-byte header words where the check read 4; VTK's default is
/// 4, which vtkio is now given); and a valid file without `header_type` loads.
#[test]
fn fuzzed_vtp_files_are_typed_errors_and_the_vtk_default_header_loads() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut lossy = vec![0xffu8; 8];
    lossy.extend_from_slice(b" vtkZLibDataCompressor <AppendedData encoding=\"raw\">_");
    std::fs::write(d.join("lossy.vtp"), &lossy).unwrap();
    surface_error(d, "vtk", "lossy.vtp");
    let short = "<VTKFile compressor=\"vtkZLibDataCompressor\"><DataArray format=\"appended\" \
                 offset=\"0\"/><AppendedData encoding=\"base64\">_AAAAAAAAAAAAAA==</AppendedData></VTKFile>";
    std::fs::write(d.join("short.vtp"), short).unwrap();
    let e = surface_error(d, "vtk", "short.vtp");
    assert!(e.contains("shorter than its block count"), "{e}");
    // 30 MB of zeros in one zlib block whose header claims 3,000 bytes.
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    z.write_all(&vec![0u8; 30 << 20]).unwrap();
    let block = z.finish().unwrap();
    let bomb = |encoding: &str, header_type: &str| {
        let mut f = format!(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" \
             compressor=\"vtkZLibDataCompressor\"{header_type}>\n<PolyData>\n<Piece \
             NumberOfPoints=\"250\" NumberOfPolys=\"0\">\n<Points><DataArray type=\"Float32\" \
             NumberOfComponents=\"3\" format=\"appended\" offset=\"0\"/></Points>\n</Piece>\n\
             </PolyData>\n<AppendedData {encoding}>\n_"
        )
        .into_bytes();
        for w in [1u32, 3000, 3000, block.len() as u32] {
            f.extend_from_slice(&w.to_le_bytes());
        }
        f.extend_from_slice(&block);
        f.extend_from_slice(b"\n</AppendedData>\n</VTKFile>\n");
        f
    };
    for (file, encoding, header_type) in [
        ("quotes.vtp", "encoding='raw'", " header_type=\"UInt32\""),
        (
            "spaced.vtp",
            "encoding = \"raw\"",
            " header_type=\"UInt32\"",
        ),
        ("default.vtp", "encoding=\"raw\"", ""),
    ] {
        std::fs::write(d.join(file), bomb(encoding, header_type)).unwrap();
        let e = surface_error(d, "vtk", file);
        assert!(
            e.contains("inflates to more than the 3000 bytes"),
            "{file}: {e}"
        );
    }
    // The octahedron as inline base64 binary arrays with 4-byte headers and no
    // `header_type` (a size mismatch before).
    let valid = "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\">\n<PolyData>\n\
        <Piece NumberOfPoints=\"6\" NumberOfPolys=\"8\">\n<Points><DataArray type=\"Float32\" \
        NumberOfComponents=\"3\" format=\"binary\">SAAAAAAAgD8AAAAAAAAAAAAAgL8AAAAAAAAAAAAAAAAAAIA/AAAAAAAAAAAAAIC/AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAACAvw==</DataArray></Points>\n\
        <Polys><DataArray type=\"Int32\" Name=\"connectivity\" format=\"binary\">YAAAAAAAAAACAAAABAAAAAIAAAABAAAABAAAAAEAAAADAAAABAAAAAMAAAAAAAAABAAAAAIAAAAAAAAABQAAAAEAAAACAAAABQAAAAMAAAABAAAABQAAAAAAAAADAAAABQAAAA==</DataArray>\n\
        <DataArray type=\"Int32\" Name=\"offsets\" format=\"binary\">IAAAAAMAAAAGAAAACQAAAAwAAAAPAAAAEgAAABUAAAAYAAAA</DataArray></Polys>\n\
        </Piece>\n</PolyData>\n</VTKFile>\n";
    std::fs::write(d.join("octa.vtp"), valid).unwrap();
    let scene = Scene::from_toml_str(&surface_scene("vtk", "octa.vtp"), d).unwrap();
    let t = Tissue::from_scene(&scene).unwrap_or_else(|e| panic!("{e}"));
    assert!((t.volume - 4.0 / 3.0).abs() < 1e-6, "{}", t.volume);

    // Pieces without points: vtkio's reader panicked on any (the message was a caught
    // `Option::unwrap()`). An empty piece, as VTK writes an empty block, is left out; one
    // that declares points and has none, or a file with no points at all, is named.
    let piece_at = valid.find("<Piece").unwrap();
    let with = |extra: &str| format!("{}{extra}{}", &valid[..piece_at], &valid[piece_at..]);
    let empty = "<Piece NumberOfPoints=\"0\" NumberOfPolys=\"0\"/>\n";
    std::fs::write(d.join("empty_first.vtp"), with(&empty.repeat(1000))).unwrap();
    let scene = Scene::from_toml_str(&surface_scene("vtk", "empty_first.vtp"), d).unwrap();
    let t = Tissue::from_scene(&scene).unwrap_or_else(|e| panic!("{e}"));
    assert!((t.volume - 4.0 / 3.0).abs() < 1e-6, "{}", t.volume);
    let only_empty = |n: usize| {
        let end = valid.find("</Piece>").unwrap() + "</Piece>".len();
        format!("{}{}{}", &valid[..piece_at], empty.repeat(n), &valid[end..])
    };
    std::fs::write(d.join("all_empty.vtp"), only_empty(3)).unwrap();
    let e = surface_error(d, "vtk", "all_empty.vtp");
    assert!(e.contains("none of its 3 pieces has points"), "{e}");
    std::fs::write(d.join("no_piece.vtp"), only_empty(0)).unwrap();
    let e = surface_error(d, "vtk", "no_piece.vtp");
    assert!(e.contains("no <Piece> element"), "{e}");
    // Empty pieces as other writers put them, and tags in comments, load (the fourth
    // fuzzing pass: a close tag with a blank ran the cut to the end of the file, a piece
    // with an empty `<Points>` and `NumberOfPoints="0"` reached vtkio, a comment's
    // `<Piece>` was taken for one).
    for (name, extra) in [
        ("spaced_close.vtp", "<Piece NumberOfPoints=\"0\"></Piece >\n"),
        (
            "empty_points.vtp",
            "<Piece NumberOfPoints=\"0\" NumberOfPolys=\"0\"><Points></Points><Polys></Polys></Piece>\n",
        ),
        ("zeros.vtp", "<Piece NumberOfPoints=\"00\"/>\n"),
        ("comment.vtp", "<!-- <Piece NumberOfPoints=\"8\"/> <Piece> -->\n"),
    ] {
        std::fs::write(d.join(name), with(extra)).unwrap();
        let scene = Scene::from_toml_str(&surface_scene("vtk", name), d).unwrap();
        let t = Tissue::from_scene(&scene).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!((t.volume - 4.0 / 3.0).abs() < 1e-6, "{name}: {}", t.volume);
    }
    let hollow = "<Piece NumberOfPoints=\"4\" NumberOfPolys=\"0\"></Piece>\n";
    std::fs::write(d.join("hollow.vtp"), with(hollow)).unwrap();
    let e = surface_error(d, "vtk", "hollow.vtp");
    assert!(
        e.contains("piece 0 declares NumberOfPoints=\"4\" but has no <Points>"),
        "{e}"
    );
}

/// Raw appended data, the default of VTK's and ParaView's writers: vtkio's XML reader
/// failed at the first `<`, `>` or `&` byte among the data ("EndEventMismatch"); the file
/// is now handed to it re-encoded as base64. The octahedron's coordinates are scaled to
/// 2^-7 so that every one holds a `<` byte (0x3C); uncompressed, and zlib-compressed (the
/// compressed arrays' other layout, at the first level whose stream holds a `<` if any).
#[test]
fn raw_appended_vtp_files_with_markup_bytes_load() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let points: Vec<u8> = OCTAHEDRON_VERTICES
        .iter()
        .flatten()
        .flat_map(|x| (x / 128.0).to_le_bytes())
        .collect();
    assert!(points.contains(&b'<'));
    let conn: Vec<u8> = OCTAHEDRON_TRIANGLES
        .iter()
        .flatten()
        .flat_map(|&v| (v as i32).to_le_bytes())
        .collect();
    let offsets: Vec<u8> = (1..=8i32).flat_map(|k| (3 * k).to_le_bytes()).collect();
    for compressed in [false, true] {
        let encode = |data: &[u8]| -> Vec<u8> {
            if !compressed {
                return [(data.len() as u32).to_le_bytes().to_vec(), data.to_vec()].concat();
            }
            let z = (1..=9)
                .map(|level| {
                    let mut e = flate2::write::ZlibEncoder::new(
                        Vec::new(),
                        flate2::Compression::new(level),
                    );
                    e.write_all(data).unwrap();
                    e.finish().unwrap()
                })
                .find(|z| z.contains(&b'<'))
                .unwrap_or_else(|| {
                    let mut e = flate2::write::ZlibEncoder::new(Vec::new(), Default::default());
                    e.write_all(data).unwrap();
                    e.finish().unwrap()
                });
            let n = data.len() as u32;
            let mut out = Vec::new();
            for w in [1, n, n, z.len() as u32] {
                out.extend(w.to_le_bytes());
            }
            [out, z].concat()
        };
        let arrays = [encode(&points), encode(&conn), encode(&offsets)];
        let (o1, o2) = (arrays[0].len(), arrays[0].len() + arrays[1].len());
        let compressor = if compressed {
            " compressor=\"vtkZLibDataCompressor\""
        } else {
            ""
        };
        let mut f = format!(
            "<?xml version=\"1.0\"?>\n<VTKFile type=\"PolyData\" version=\"1.0\" \
             byte_order=\"LittleEndian\" header_type=\"UInt32\"{compressor}>\n<PolyData>\n\
             <Piece NumberOfPoints=\"6\" NumberOfPolys=\"8\">\n<Points><DataArray \
             type=\"Float32\" NumberOfComponents=\"3\" format=\"appended\" offset=\"0\"/>\
             </Points>\n<Polys><DataArray type=\"Int32\" Name=\"connectivity\" \
             format=\"appended\" offset=\"{o1}\"/>\n<DataArray type=\"Int32\" \
             Name=\"offsets\" format=\"appended\" offset=\"{o2}\"/></Polys>\n</Piece>\n\
             </PolyData>\n<AppendedData encoding=\"raw\">\n   _"
        )
        .into_bytes();
        for a in arrays {
            f.extend(a);
        }
        f.extend(b"\n  </AppendedData>\n</VTKFile>\n");
        let file = if compressed { "zlib.vtp" } else { "plain.vtp" };
        std::fs::write(d.join(file), f).unwrap();
        let scene = Scene::from_toml_str(
            &surface_scene("vtk", file).replace("spacing = 0.25", "spacing = 0.25, scale = 128.0"),
            d,
        )
        .unwrap();
        let t = Tissue::from_scene(&scene).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!((t.volume - 4.0 / 3.0).abs() < 1e-5, "{file}: {}", t.volume);
    }
}

/// OBJ and STL text that the readers misread: a byte order mark (an OBJ dropped its first
/// vertex; an STL was taken for binary), lone carriage returns ending the lines (one
/// line, "color parse error"), `SOLID` in capitals, and bytes that are not UTF-8 ("read
/// error"). The first three load; the last names the byte.
#[test]
fn surface_text_with_a_byte_order_mark_or_old_line_ends_loads() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut obj = String::new();
    for p in OCTAHEDRON_VERTICES {
        obj.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    for t in OCTAHEDRON_TRIANGLES {
        obj.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    let mut stl = String::from("SOLID octa\n");
    for f in OCTAHEDRON_TRIANGLES {
        stl.push_str("facet normal 0 0 0\nouter loop\n");
        for i in f {
            let p = OCTAHEDRON_VERTICES[i as usize];
            stl.push_str(&format!("vertex {} {} {}\n", p[0], p[1], p[2]));
        }
        stl.push_str("endloop\nendfacet\n");
    }
    stl.push_str("endsolid\n");
    for (file, kind, text) in [
        ("bom.obj", "obj", format!("\u{feff}{obj}")),
        ("mac.obj", "obj", obj.replace('\n', "\r")),
        (
            "bom.stl",
            "stl",
            format!("\u{feff}{}", stl.replacen("SOLID", "solid", 1)),
        ),
        ("upper.stl", "stl", stl.clone()),
    ] {
        std::fs::write(d.join(file), text).unwrap();
        let scene = Scene::from_toml_str(&surface_scene(kind, file), d).unwrap();
        let t = Tissue::from_scene(&scene).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!((t.volume - 4.0 / 3.0).abs() < 1e-6, "{file}: {}", t.volume);
    }
    let mut bad = obj.into_bytes();
    bad.extend_from_slice(b"g \xff\xfe\n");
    std::fs::write(d.join("latin.obj"), bad).unwrap();
    let e = surface_error(d, "obj", "latin.obj");
    assert!(e.contains("not UTF-8"), "{e}");
}

#[test]
fn stl_counts_are_checked_and_an_unnamed_ascii_solid_loads() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A binary header declaring 4 billion triangles in 134 bytes.
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&u32::MAX.to_le_bytes());
    b.extend_from_slice(&[0u8; 50]);
    std::fs::write(d.join("huge.stl"), &b).unwrap();
    let e = surface_error(d, "stl", "huge.stl");
    assert!(e.contains("4294967295 triangles"), "{e}");
    // A valid ASCII STL whose `solid` line has no name (read as binary before).
    let mut s = String::from("solid\n");
    for f in OCTAHEDRON_TRIANGLES {
        s.push_str("facet normal 0 0 0\nouter loop\n");
        for i in f {
            let p = OCTAHEDRON_VERTICES[i as usize];
            s.push_str(&format!("vertex {} {} {}\n", p[0], p[1], p[2]));
        }
        s.push_str("endloop\nendfacet\n");
    }
    s.push_str("endsolid\n");
    std::fs::write(d.join("unnamed.stl"), s).unwrap();
    let scene = Scene::from_toml_str(&surface_scene("stl", "unnamed.stl"), d).unwrap();
    let t = Tissue::from_scene(&scene).unwrap_or_else(|e| panic!("{e}"));
    assert!((t.volume - 4.0 / 3.0).abs() < 1e-6, "{}", t.volume);
}

/// An OBJ whose `mtllib` names a FIFO (a hang before: the reader opened it) or a device
/// loads without reading its materials.
#[cfg(unix)]
#[test]
fn obj_material_libraries_are_not_opened() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fifo = d.join("materials.mtl");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    assert!(made.is_ok_and(|s| s.success()), "mkfifo");
    let faces = "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n";
    let body = |lib: &str| {
        format!("mtllib {lib}\nv 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\nusemtl a\n{faces}")
    };
    std::fs::write(d.join("fifo.obj"), body("materials.mtl")).unwrap();
    std::fs::write(d.join("device.obj"), body("/dev/zero")).unwrap();
    for file in ["fifo.obj", "device.obj"] {
        let start = Instant::now();
        let scene = Scene::from_toml_str(&surface_scene("obj", file), d).unwrap();
        let t = Tissue::from_scene(&scene).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!((t.volume - 4.0 / 3.0).abs() < 1e-6, "{file}: {}", t.volume);
        assert!(start.elapsed() < Duration::from_secs(10), "{file}");
    }
}

/// Thread counts far beyond any machine are errors before a pool is built (5,000 made
/// rayon panic or the process abort; 100,000 took a minute to fail).
#[test]
fn thread_counts_beyond_the_maximum_are_errors() {
    use needlesim::{CpuBackend, Threading};
    let scene = Scene::from_toml_str(
        "[tissue]\ngeometry = { kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], spacing = 0.05 }\n\
         [material]\nmodel = \"mass_spring\"\nstiffness = 100.0\n[physics]\ndt = 1e-3\n",
        Path::new("."),
    )
    .unwrap();
    let tissue = Tissue::from_scene(&scene).unwrap();
    for n in [0, 5000, 100_000] {
        let start = Instant::now();
        let e = CpuBackend::new(tissue.clone(), Threading::Threads(n))
            .err()
            .unwrap_or_else(|| panic!("{n} threads accepted"))
            .to_string();
        assert!(e.contains(&n.to_string()) && e.contains("1024"), "{e}");
        assert!(start.elapsed() < Duration::from_secs(1));
    }
    assert!(CpuBackend::new(tissue, Threading::Threads(2)).is_ok());
}

const HELD: &str = "[tissue]\ngeometry = { kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], spacing = 0.05 }\n\
                    [material]\nmodel = \"mass_spring\"\nstiffness = 100.0\n[physics]\ndt = 1e-3\n";

/// The error of `HELD` plus `extra`, from the scene or its tissue.
fn held_error(extra: &str) -> String {
    let text = format!("{HELD}{extra}");
    match Scene::from_toml_str(&text, Path::new(".")) {
        Err(e) => e.to_string(),
        Ok(s) => match Tissue::from_scene(&s) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("accepted:\n{extra}"),
        },
    }
}

#[test]
fn conflicting_or_badly_named_held_sets_are_errors() {
    // Two prescribed sets moving the same nodes apart (the later silently won).
    let e = held_error(
        "[[prescribed]]\naxis = \"y\"\nabove = 0.099\ndisplacement = [0.0, -0.001, 0.0]\n\
         [[prescribed]]\naxis = \"y\"\nabove = 0.099\ndisplacement = [0.0, 0.001, 0.0]\n",
    );
    assert!(
        e.contains("prescribed[1]") && e.contains("prescribed[0]"),
        "{e}"
    );
    // Different components of the same nodes are two motions, allowed.
    let text = format!(
        "{HELD}[[prescribed]]\naxis = \"y\"\nabove = 0.099\ncomponents = [\"y\"]\ndisplacement = [0.0, -0.001, 0.0]\n\
         [[prescribed]]\naxis = \"y\"\nabove = 0.099\ncomponents = [\"x\"]\ndisplacement = [0.001, 0.0, 0.0]\n"
    );
    Tissue::from_scene(&Scene::from_toml_str(&text, Path::new(".")).unwrap()).unwrap();
    // A component held at rest by a fixed set and moved by a prescribed one (the motion
    // won, and both sets reported its reaction).
    let e = held_error(
        "[[fixed]]\naxis = \"y\"\nabove = 0.099\ncomponents = [\"y\"]\n\
         [[prescribed]]\naxis = \"y\"\nabove = 0.099\ncomponents = [\"y\"]\ndisplacement = [0.0, 0.001, 0.0]\n",
    );
    assert!(
        e.contains("prescribed[0]") && e.contains("in y, which fixed[0] holds"),
        "{e}"
    );
    // Held in x, moved in y: allowed.
    let text = format!(
        "{HELD}[[fixed]]\naxis = \"y\"\nabove = 0.099\ncomponents = [\"x\"]\n\
         [[prescribed]]\naxis = \"y\"\nabove = 0.099\ncomponents = [\"y\"]\ndisplacement = [0.0, 0.001, 0.0]\n"
    );
    Tissue::from_scene(&Scene::from_toml_str(&text, Path::new(".")).unwrap()).unwrap();
    // Names that would corrupt reactions.csv or act on a terminal, and duplicates
    // (defaults included).
    for (name, key) in [
        ("a,b", "fixed[0].name"),
        ("line\nbreak", "fixed[0].name"),
        ("quote\"d", "fixed[0].name"),
        ("", "fixed[0].name"),
        ("nul\0byte", "fixed[0].name"),
        ("line\u{2028}separator", "fixed[0].name"),
        ("\u{1b}[2Jclear", "fixed[0].name"),
    ] {
        let quoted = toml::Value::String(name.to_string()).to_string();
        let e = held_error(&format!(
            "[[fixed]]\naxis = \"x\"\nbelow = 0.001\nname = {quoted}\n"
        ));
        assert!(e.contains(key), "{name:?}: {e}");
    }
    let e = held_error(
        "[[fixed]]\naxis = \"x\"\nbelow = 0.001\nname = \"clamp\"\n\
         [[prescribed]]\naxis = \"x\"\nabove = 0.099\ndisplacement = [0.001, 0.0, 0.0]\nname = \"clamp\"\n",
    );
    assert!(
        e.contains("prescribed[0].name") && e.contains("fixed[0].name"),
        "{e}"
    );
    let e = held_error(
        "[[fixed]]\naxis = \"x\"\nbelow = 0.001\n\
         [[fixed]]\naxis = \"x\"\nabove = 0.099\nname = \"fixed0\"\n",
    );
    assert!(e.contains("fixed[1].name"), "{e}");
    // An emoji sequence joins its emoji with U+200D: a name, not a hidden character.
    let text = format!(
        "{HELD}[[fixed]]\naxis = \"x\"\nbelow = 0.001\nname = \"\u{1F468}\u{200D}\u{1F469}\u{200D}\u{1F467}\"\n"
    );
    Tissue::from_scene(&Scene::from_toml_str(&text, Path::new(".")).unwrap()).unwrap();
    // The scene's own name is printed by `info`: an escape sequence in it cleared the
    // terminal.
    let text = format!("name = \"\\u001b[2J\"\n{HELD}");
    let e = Scene::from_toml_str(&text, Path::new("."))
        .unwrap_err()
        .to_string();
    assert!(e.contains("name") && e.contains("'\\u{1b}'"), "{e}");
}

/// A vertex near 1e298 m (a double in a VTK file) is named as a units problem (it was
/// reported as a degenerate triangle, products of its coordinates overflowing).
#[test]
fn a_vertex_beyond_any_body_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let far = legacy_vtk("POINTS 6 double", "POLYGONS 8 32").replacen("1 0 0\n", "1e298 0 0\n", 1);
    std::fs::write(d.join("far.vtk"), far).unwrap();
    let e = surface_error(d, "vtk", "far.vtk");
    assert!(e.contains("vertex 0") && e.contains("scale"), "{e}");
}

/// A box given by `nodes` keeps its extent on every axis (a 1 m rod of 1 x 1 cm with 639
/// nodes covered 31% of its volume), and a count too small for a thin box is an error
/// naming `nodes`.
#[test]
fn node_count_boxes_keep_their_extent_or_name_the_count() {
    let scene = |max: &str, n: usize| {
        format!(
            "[tissue]\ngeometry = {{ kind = \"box\", min = [0.0, 0.0, 0.0], max = {max}, nodes = {n} }}\n\
             [material]\nmodel = \"mass_spring\"\nstiffness = 100.0\n[physics]\ndt = 1e-3\n"
        )
    };
    let t = Tissue::from_scene(
        &Scene::from_toml_str(&scene("[1.0, 0.01, 0.01]", 639), Path::new(".")).unwrap(),
    )
    .unwrap();
    assert!(t.volume > 0.95 * 1e-4 * 0.5, "volume {}", t.volume);
    let mut hi = [f64::MIN; 3];
    let mut lo = [f64::MAX; 3];
    for p in &t.state.positions[..t.n_mesh] {
        for a in 0..3 {
            hi[a] = hi[a].max(p[a] as f64);
            lo[a] = lo[a].min(p[a] as f64);
        }
    }
    assert!(hi[0] - lo[0] > 0.95, "the rod spans {} m", hi[0] - lo[0]);
    let e = match Scene::from_toml_str(&scene("[0.2, 0.2, 0.001]", 50), Path::new("."))
        .and_then(|s| Tissue::from_scene(&s))
    {
        Ok(t) => panic!("accepted with {} nodes", t.n_mesh),
        Err(e) => e.to_string(),
    };
    assert!(e.contains("tissue.geometry.nodes"), "{e}");
}

/// A box at the origin spanning more f32-resolvable spacings than positions allow is told
/// to coarsen its spacing, naming the spacing key (it was told to "move the body near the
/// origin", where it already was); a small box far away is still told to move.
#[test]
fn too_fine_a_spacing_is_named_as_the_cause_not_the_placement() {
    let error = |geometry: &str| {
        let text = format!(
            "[tissue]\ngeometry = {{ kind = \"box\", {geometry} }}\n\
             [material]\nmodel = \"mass_spring\"\nstiffness = 100.0\n[physics]\ndt = 1e-3\n"
        );
        match Scene::from_toml_str(&text, Path::new(".")).and_then(|s| Tissue::from_scene(&s)) {
            Ok(t) => panic!("accepted with {} nodes", t.n_mesh),
            Err(e) => e.to_string(),
        }
    };
    let e = error("min = [0.0, 0.0, 0.0], max = [1.0, 1e-5, 1e-5], spacing = 5e-6");
    assert!(
        e.contains("tissue.geometry.spacing") && e.contains("coarser spacing"),
        "{e}"
    );
    assert!(!e.contains("near the origin"), "{e}");
    let e = error("min = [1e4, 0.0, 0.0], max = [10000.01, 0.01, 0.01], spacing = 0.001");
    assert!(
        e.contains("tissue.geometry.min") && e.contains("near the origin"),
        "{e}"
    );
}

/// A 3-vector key with more than three elements is refused, naming the key (serde's
/// fixed-size arrays read the first three and dropped the rest, so gravity with a string
/// and a table after its three numbers was accepted).
#[test]
fn vectors_with_extra_elements_are_refused() {
    for (extra, key) in [
        (
            "[physics]\ngravity = [0.0, -9.81, 0.0, \"junk\"]\n",
            "physics.gravity",
        ),
        (
            "[initial]\nstretch = [1.0, 1.0, 1.0, 99.0]\n",
            "initial.stretch",
        ),
        (
            "[[prescribed]]\naxis = \"y\"\nabove = 0.099\ndisplacement = [0.0, 0.001, 0.0, 0.0]\n",
            "displacement",
        ),
    ] {
        let text = format!("{}{extra}", HELD.replace("[physics]\ndt = 1e-3\n", ""));
        let e = Scene::from_toml_str(&text, Path::new("."))
            .unwrap_err()
            .to_string();
        assert!(e.contains(key) && e.contains("elements"), "{key}: {e}");
    }
    // Too few in a keyframe: the whole path (serde's message named only the keyframe).
    let base = include_str!("../scenes/needle_insert_extract.toml");
    let text = base.replacen(
        "action = \"move\"\ndirection = [1.0, 0.0, 0.0]",
        "action = \"move\"\ndirection = [1.0, 0.0]",
        1,
    );
    assert_ne!(text, base);
    let e = Scene::from_toml_str(&text, Path::new("scenes"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("needle.keyframe[0].direction"), "{e}");
}

/// Needle parameters of absurd size are named (1e308 N of cutting force ran into a
/// non-finite tissue; a radius of 1e-18 m lost the cutting force), and a region's own
/// density is named when it gives a mass f32 cannot hold (the message named
/// `tissue.density`).
#[test]
fn needle_parameters_beyond_any_scale_and_region_densities_are_named() {
    let base = include_str!("../scenes/needle_insert_extract.toml");
    for (from, to, key) in [
        ("cutting = 0.05", "cutting = 1e308", "needle.cutting"),
        ("radius = 0.000635", "radius = 1e-18", "needle.radius"),
        (
            "friction = { coefficient = 0.3 }",
            "friction = { coefficient = 0.3, sheath_viscosity = 1e300 }",
            "needle.friction.sheath_viscosity",
        ),
        (
            "cutting = 0.05",
            "cutting = 0.05\ncontact_radius = 1e40",
            "needle.contact_radius",
        ),
        // A wrong type in a keyframe names its index (it said "in `keyframe`").
        (
            "action = \"pause\"\nduration = 0.5",
            "action = \"pause\"\nduration = \"long\"",
            "needle.keyframe[1]",
        ),
    ] {
        let text = base.replacen(from, to, 1);
        assert_ne!(text, base, "{from}");
        let e = match Scene::from_toml_str(&text, Path::new("scenes")) {
            Err(e) => e.to_string(),
            Ok(s) => match needlesim::needle::Simulation::prepare(&s) {
                Err(e) => e.to_string(),
                Ok(_) => panic!("{to}: accepted"),
            },
        };
        assert!(e.contains(key), "{to}: {e}");
    }
    let text = format!(
        "{HELD}[[region]]\nname = \"heavy\"\ngeometry = {{ kind = \"box\", min = [0.0, 0.0, 0.0], \
         max = [0.1, 0.1, 0.05] }}\ndensity = 1e308\nmaterial = {{ stiffness = 100.0 }}\n"
    );
    let e = held_error(&text[HELD.len()..]);
    assert!(e.contains("region[heavy].density"), "{e}");
}
