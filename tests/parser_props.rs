//! Property tests of the parsers with generated input (issue 18, item 5): scene TOML text
//! (arbitrary strings, and structured mutations of the reference scenes) and OBJ surface
//! files. Every generated input must give an error or a valid scene, and a valid scene must
//! be prepared (`Simulation::prepare`) without a panic; nothing else is asserted.

mod common;

use common::within_time;
use needlesim::core::scene::Geometry;
use needlesim::needle::Simulation;
use needlesim::{CpuBackend, Scene, Threading};
use proptest::prelude::*;
use proptest::sample::Index;
use proptest::test_runner::RngSeed;
use std::path::Path;

const INSERT_EXTRACT: &str = include_str!("../scenes/needle_insert_extract.toml");
const CUBE_SAG: &str = include_str!("../scenes/cube_sag_msm.toml");

/// The most nodes a generated scene may ask for before `prepare` is skipped: building
/// even a small fraction of the memory limit is too slow for a test.
const MAX_PREPARE_NODES: f64 = 5000.0;

/// Steps a valid scene takes on the CPU backend.
const STEPS: u64 = 3;

/// Parses `text` and, if it is a valid scene of modest size, prepares it with a small
/// memory limit, starts it on the CPU backend and takes a few steps. Returns nothing: the
/// property is that no step panics (or hangs: see [`within_time`]).
fn parse_and_prepare(text: &str, base: &Path) {
    parse_and_prepare_shown(text, base, text);
}

/// [`parse_and_prepare`], naming the input as `shown` if it hangs.
fn parse_and_prepare_shown(text: &str, base: &Path, shown: &str) {
    let text = text.to_string();
    let base = base.to_path_buf();
    within_time(shown, move || {
        let Ok(mut scene) = Scene::from_toml_str(&text, &base) else {
            return;
        };
        if !small_enough(&scene.tissue.geometry) {
            return;
        }
        // Big scenes (a needle of billions of nodes, say) fail fast with an error.
        scene.run.max_memory_gib = scene.run.max_memory_gib.min(0.05);
        let Ok(prep) = Simulation::prepare(&scene) else {
            return;
        };
        if let Ok(b) = CpuBackend::new(prep.tissue.clone(), Threading::Single) {
            if let Ok(mut sim) = prep.start(Box::new(b)) {
                let _ = sim.step_n(STEPS);
            }
        }
    });
}

/// Whether the box's node count is known to be small (surface files are judged by
/// `max_memory_gib`, whose estimate comes before any allocation).
fn small_enough(g: &Geometry) -> bool {
    match g {
        Geometry::Box(b) => match (b.spacing, b.nodes) {
            (Some(h), _) => {
                let count: f64 = (0..3)
                    .map(|i| ((b.max[i] - b.min[i]).abs() / h).floor() + 1.0)
                    .product();
                count.is_finite() && count <= MAX_PREPARE_NODES
            }
            (None, Some(n)) => n as f64 <= MAX_PREPARE_NODES,
            (None, None) => true,
        },
        Geometry::Obj(_) | Geometry::Stl(_) | Geometry::Vtk(_) => true,
    }
}

// ---------------------------------------------------------------------------------------
// Scene TOML: arbitrary text.

/// 256 cases per property from a fixed seed, so that every run tries the same inputs
/// (change [`SEED`] to explore others); no regression files are written.
fn config() -> ProptestConfig {
    ProptestConfig {
        failure_persistence: None,
        rng_seed: RngSeed::Fixed(SEED),
        ..ProptestConfig::with_cases(256)
    }
}

/// The seed of every property's generator.
const SEED: u64 = 18;

proptest! {
    #![proptest_config(config())]

    #[test]
    fn arbitrary_strings_are_an_error_or_a_scene(text in any::<String>()) {
        parse_and_prepare(&text, Path::new("."));
    }

    #[test]
    fn arbitrary_bytes_are_an_error_or_a_scene(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        parse_and_prepare(&String::from_utf8_lossy(&bytes), Path::new("."));
    }

    #[test]
    fn toml_like_text_is_an_error_or_a_scene(
        text in "(\\[[a-z.]{0,12}\\]\n|[a-z_.]{1,12} = [-+0-9.e\"a-z\\[\\], {}=]{0,20}\n){0,12}"
    ) {
        parse_and_prepare(&text, Path::new("."));
    }
}

// ---------------------------------------------------------------------------------------
// Scene TOML: structured mutations of the reference scenes.

/// Byte ranges of the numeric literals of `text` (outside strings and comments).
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut offset = 0;
    for line in text.split_inclusive('\n') {
        let b = line.as_bytes();
        let mut in_str = false;
        let mut i = 0;
        while i < b.len() {
            let c = b[i];
            if in_str {
                if c == b'"' {
                    in_str = false;
                }
                i += 1;
                continue;
            }
            match c {
                b'"' => in_str = true,
                b'#' => break,
                b'0'..=b'9' | b'-' | b'+'
                    if i > 0 && matches!(b[i - 1], b' ' | b'=' | b'[' | b',') =>
                {
                    let start = i;
                    while i < b.len()
                        && matches!(b[i], b'0'..=b'9' | b'.' | b'e' | b'E' | b'-' | b'+' | b'_')
                    {
                        i += 1;
                    }
                    if line[start..i].replace('_', "").parse::<f64>().is_ok() {
                        out.push((offset + start, offset + i));
                    }
                    continue;
                }
                _ => {}
            }
            i += 1;
        }
        offset += line.len();
    }
    out
}

/// Byte ranges of the inline arrays `[...]` that are values (after `=`), without nesting.
fn arrays(text: &str) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut offset = 0;
    for line in text.split_inclusive('\n') {
        if !line.trim_start().starts_with('[') && !line.trim_start().starts_with('#') {
            let mut from = 0;
            while let Some(s) = line[from..].find("= [") {
                let start = from + s + 2;
                match line[start..].find(']') {
                    Some(e) => {
                        out.push((offset + start, offset + start + e + 1));
                        from = start + e + 1;
                    }
                    None => break,
                }
            }
        }
        offset += line.len();
    }
    out
}

/// A TOML number (or `nan`/`inf`) chosen to hit the edges of the f64, f32 and integer
/// ranges.
fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        prop::sample::select(vec![
            "0",
            "-0",
            "0.0",
            "-0.0",
            "-1",
            "-1.5",
            "1",
            "2",
            "3",
            "1e-300",
            "-1e-300",
            "1e300",
            "-1e300",
            "1.7976931348623157e308",
            "-1.7976931348623157e308",
            "5e-324",
            "1e-45",
            "3.5e38",
            "1e-30",
            "1e30",
            "1e9",
            "4294967296",
            "18446744073709551615",
            "9223372036854775807",
            "-9223372036854775808",
            "nan",
            "+nan",
            "-nan",
            "inf",
            "+inf",
            "-inf",
            "0x7fffffffffffffff",
            "1_000_000",
        ])
        .prop_map(str::to_string),
        any::<i64>().prop_map(|i| i.to_string()),
        (-100i64..100).prop_map(|i| i.to_string()),
        any::<f64>().prop_map(toml_float),
        (-1.0f64..1.0).prop_map(toml_float),
    ]
}

/// `x` written as a TOML float.
fn toml_float(x: f64) -> String {
    if x.is_nan() {
        "nan".into()
    } else if x.is_infinite() {
        if x > 0.0 { "inf" } else { "-inf" }.into()
    } else {
        format!("{x:e}")
    }
}

/// One change to a scene's text.
#[derive(Debug, Clone)]
enum Mutation {
    ReplaceNumber(Index, String),
    DeleteLine(Index),
    DuplicateLine(Index),
    NumberToString(Index),
    ArrayToNumber(Index, String),
    NumberToArray(Index),
    SwapLines(Index, Index),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        4 => (any::<Index>(), number()).prop_map(|(i, n)| Mutation::ReplaceNumber(i, n)),
        1 => any::<Index>().prop_map(Mutation::DeleteLine),
        1 => any::<Index>().prop_map(Mutation::DuplicateLine),
        1 => any::<Index>().prop_map(Mutation::NumberToString),
        1 => (any::<Index>(), number()).prop_map(|(i, n)| Mutation::ArrayToNumber(i, n)),
        1 => any::<Index>().prop_map(Mutation::NumberToArray),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(a, b)| Mutation::SwapLines(a, b)),
    ]
}

fn replace_range(text: &str, (s, e): (usize, usize), with: &str) -> String {
    format!("{}{}{}", &text[..s], with, &text[e..])
}

fn apply(text: &str, m: &Mutation) -> String {
    let mut lines: Vec<&str> = text.split_inclusive('\n').collect();
    match m {
        Mutation::ReplaceNumber(i, n) => match numbers(text) {
            v if v.is_empty() => text.to_string(),
            v => replace_range(text, *i.get(&v), n),
        },
        Mutation::NumberToString(i) => match numbers(text) {
            v if v.is_empty() => text.to_string(),
            v => {
                let r = *i.get(&v);
                replace_range(text, r, &format!("\"{}\"", &text[r.0..r.1]))
            }
        },
        Mutation::NumberToArray(i) => match numbers(text) {
            v if v.is_empty() => text.to_string(),
            v => {
                let r = *i.get(&v);
                replace_range(text, r, &format!("[{}]", &text[r.0..r.1]))
            }
        },
        Mutation::ArrayToNumber(i, n) => match arrays(text) {
            v if v.is_empty() => text.to_string(),
            v => replace_range(text, *i.get(&v), n),
        },
        Mutation::DeleteLine(i) => {
            if !lines.is_empty() {
                lines.remove(i.index(lines.len()));
            }
            lines.concat()
        }
        Mutation::DuplicateLine(i) => {
            if !lines.is_empty() {
                let k = i.index(lines.len());
                lines.insert(k, lines[k]);
            }
            lines.concat()
        }
        Mutation::SwapLines(a, b) => {
            if !lines.is_empty() {
                let (a, b) = (a.index(lines.len()), b.index(lines.len()));
                lines.swap(a, b);
            }
            lines.concat()
        }
    }
}

fn mutated_scene() -> impl Strategy<Value = String> {
    (
        prop::sample::select(vec![INSERT_EXTRACT, CUBE_SAG]),
        prop::collection::vec(mutation(), 1..4),
    )
        .prop_map(|(base, ms)| ms.iter().fold(base.to_string(), |t, m| apply(&t, m)))
}

#[test]
fn the_mutation_helpers_find_numbers_and_arrays() {
    let n = numbers(INSERT_EXTRACT);
    let a = arrays(INSERT_EXTRACT);
    assert!(n.len() > 20, "{n:?}");
    assert!(a.len() >= 5, "{a:?}");
    for &(s, e) in &n {
        assert!(INSERT_EXTRACT[s..e].replace('_', "").parse::<f64>().is_ok());
    }
    for &(s, e) in &a {
        assert!(INSERT_EXTRACT[s..e].starts_with('[') && INSERT_EXTRACT[s..e].ends_with(']'));
    }
    // The unmutated scenes are valid and prepare.
    for text in [INSERT_EXTRACT, CUBE_SAG] {
        let scene = Scene::from_toml_str(text, Path::new(".")).unwrap();
        Simulation::prepare(&scene).unwrap();
    }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn mutated_reference_scenes_are_an_error_or_a_scene(text in mutated_scene()) {
        parse_and_prepare(&text, Path::new("."));
    }
}

// ---------------------------------------------------------------------------------------
// OBJ files.

/// An OBJ coordinate: mostly small, sometimes at the edges of f32.
fn coordinate() -> impl Strategy<Value = String> {
    prop_oneof![
        6 => (-2.0f64..2.0).prop_map(|x| format!("{x}")),
        2 => (-2i32..=2).prop_map(|x| x.to_string()),
        1 => prop::sample::select(vec![
            "nan", "NaN", "inf", "-inf", "1e30", "-1e30", "1e38", "3.5e38", "1e-30", "1e-45",
            "0", "-0", "1e300", "1.7976931348623157e308", "x", "", "1,5", "0x10", "--1",
        ])
        .prop_map(str::to_string),
        1 => any::<f32>().prop_map(|x| format!("{x:e}")),
    ]
}

/// An OBJ face index (1-based; negative is relative; 0 and out of range are invalid).
fn face_index() -> impl Strategy<Value = String> {
    prop_oneof![
        6 => (1i64..=8).prop_map(|i| i.to_string()),
        1 => (-8i64..=0).prop_map(|i| i.to_string()),
        1 => prop::sample::select(vec![
            "9", "100", "4294967295", "4294967296", "2147483648", "-2147483649",
            "18446744073709551616", "99999999999999999999", "1/1", "1//1", "1/1/1", "1/", "/1",
            "a", "1.5", "",
        ])
        .prop_map(str::to_string),
    ]
}

fn obj_line() -> impl Strategy<Value = String> {
    prop_oneof![
        5 => prop::collection::vec(coordinate(), 3..=4).prop_map(|c| format!("v {}", c.join(" "))),
        1 => prop::collection::vec(coordinate(), 0..=2).prop_map(|c| format!("v {}", c.join(" "))),
        5 => prop::collection::vec(face_index(), 3..=3).prop_map(|f| format!("f {}", f.join(" "))),
        2 => prop::collection::vec(face_index(), 0..=6).prop_map(|f| format!("f {}", f.join(" "))),
        1 => prop::collection::vec(coordinate(), 3..=3).prop_map(|c| format!("vn {}", c.join(" "))),
        1 => prop::collection::vec(coordinate(), 2..=2).prop_map(|c| format!("vt {}", c.join(" "))),
        1 => prop::sample::select(vec![
            "o a", "g b", "# comment", "", "s 1", "s off", "usemtl m", "mtllib none.mtl",
            "mtllib /dev/null", "l 1 2", "p 1", "garbage tokens here", "\\", "v", "f", "\u{0}",
            "f 1 2 3 \\", "v 1 2 3 4 5 6",
        ])
        .prop_map(str::to_string),
        1 => "[ -~]{0,30}",
    ]
}

const OCTAHEDRON: [&str; 14] = [
    "v 1 0 0", "v -1 0 0", "v 0 1 0", "v 0 -1 0", "v 0 0 1", "v 0 0 -1", "f 1 3 5", "f 3 2 5",
    "f 2 4 5", "f 4 1 5", "f 3 1 6", "f 2 3 6", "f 4 2 6", "f 1 4 6",
];

/// A closed shape's vertex and face lines: the octahedron, or a cube of quads.
fn closed_shape() -> impl Strategy<Value = (Vec<[f64; 3]>, Vec<Vec<i64>>)> {
    let octahedron = (
        common::OCTAHEDRON_VERTICES
            .map(|p| p.map(f64::from))
            .to_vec(),
        OCTAHEDRON[6..]
            .iter()
            .map(|f| f[2..].split(' ').map(|i| i.parse().unwrap()).collect())
            .collect::<Vec<Vec<i64>>>(),
    );
    let cube = (
        (0..8)
            .map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
            .collect::<Vec<_>>(),
        vec![
            vec![1, 3, 4, 2],
            vec![5, 6, 8, 7],
            vec![1, 2, 6, 5],
            vec![3, 7, 8, 4],
            vec![1, 5, 7, 3],
            vec![2, 4, 8, 6],
        ],
    );
    prop::sample::select(vec![octahedron, cube])
}

/// Mostly nothing, sometimes a list of changes.
fn rarely<T: std::fmt::Debug + Clone>(
    s: impl Strategy<Value = Vec<T>>,
) -> impl Strategy<Value = Vec<T>> {
    prop_oneof![2 => Just(Vec::new()), 1 => s]
}

/// A closed shape, perturbed: vertices moved (a little, or to an edge value), faces
/// flipped or re-indexed, the whole shell repeated (overlapping, nested or disjoint),
/// indices written relative (negative).
fn perturbed_shape() -> impl Strategy<Value = String> {
    (
        closed_shape(),
        rarely(prop::collection::vec(
            (any::<Index>(), 0usize..3, coordinate()),
            1..3,
        )),
        rarely(prop::collection::vec(any::<Index>(), 1..3)),
        rarely(prop::collection::vec((any::<Index>(), face_index()), 1..2)),
        prop::sample::select(vec![
            None,
            None,
            None,
            None,
            Some([0.0, 0.0, 0.0]),
            Some([0.5, 0.0, 0.0]),
            Some([3.0, 0.0, 0.0]),
            Some([0.0, 0.0, 1e-7]),
        ]),
        any::<bool>(),
        prop::sample::select(vec![1.0, 1.0, 1.0, 1.0, 0.5, -1.0, 1e-6, 1e6]),
    )
        .prop_map(
            |((vs, fs), moves, flips, reindex, copy, relative, factor)| {
                let mut v: Vec<[String; 3]> = vs
                    .iter()
                    .map(|p| p.map(|c| format!("{}", c * factor)))
                    .collect();
                for (at, axis, c) in moves {
                    let k = at.index(v.len());
                    v[k][axis] = c;
                }
                let mut f: Vec<Vec<String>> = fs
                    .iter()
                    .map(|f| {
                        f.iter()
                            .map(|&i| {
                                if relative {
                                    (i - 1 - vs.len() as i64).to_string()
                                } else {
                                    i.to_string()
                                }
                            })
                            .collect()
                    })
                    .collect();
                for at in flips {
                    let k = at.index(f.len());
                    f[k].reverse();
                }
                for (at, i) in reindex {
                    let k = at.index(f.len());
                    f[k][0] = i;
                }
                let mut out = String::new();
                let mut write = |v: &[[String; 3]], f: &[Vec<String>]| {
                    for p in v {
                        out.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
                    }
                    for face in f {
                        out.push_str(&format!("f {}\n", face.join(" ")));
                    }
                };
                write(&v, &f);
                if let Some(t) = copy {
                    let n = vs.len() as i64;
                    let v2: Vec<[String; 3]> = vs
                        .iter()
                        .map(|p| [0, 1, 2].map(|a| format!("{}", p[a] * factor * 0.5 + t[a])))
                        .collect();
                    let f2: Vec<Vec<String>> = fs
                        .iter()
                        .map(|f| f.iter().map(|i| (i + n).to_string()).collect())
                        .collect();
                    write(&v2, &f2);
                }
                out
            },
        )
}

/// OBJ text: random lines, the octahedron with some lines replaced, removed or added, or
/// a perturbed closed shape.
fn obj_text() -> impl Strategy<Value = String> {
    let random = prop::collection::vec(obj_line(), 0..24).prop_map(|l| l.join("\n"));
    let mutated =
        prop::collection::vec((0u8..3, any::<Index>(), obj_line()), 1..3).prop_map(|edits| {
            let mut lines: Vec<String> = OCTAHEDRON.iter().map(|s| s.to_string()).collect();
            for (kind, at, line) in edits {
                let k = at.index(lines.len() + 1);
                match kind {
                    0 if k < lines.len() => lines[k] = line,
                    1 if k < lines.len() => {
                        lines.remove(k);
                    }
                    _ => lines.insert(k, line),
                }
            }
            lines.join("\n")
        });
    prop_oneof![1 => random, 1 => mutated, 3 => perturbed_shape()]
}

/// The scene keys around the OBJ file: spacing, scale, surface mode, translation and
/// rotation; mostly values that build, sometimes values at the edges.
fn obj_keys() -> impl Strategy<Value = String> {
    let surface = prop::sample::select(vec!["resample", "vertices"]);
    let good = (
        prop::sample::select(vec!["0.25", "0.3", "0.5"]),
        surface.clone(),
        prop::sample::select(vec!["", ", rotate = { axis = [0, 0, 1], degrees = 30 }"]),
    )
        .prop_map(|(spacing, surface, rotate)| {
            format!("spacing = {spacing}, surface = \"{surface}\"{rotate}")
        });
    let edges = (
        prop::sample::select(vec!["0.25", "1", "0.1", "1e-9", "1e30", "nan"]),
        prop::sample::select(vec!["1", "0.5", "1e30", "1e-30", "1e-3", "-1", "0"]),
        surface,
        prop::sample::select(vec!["[0, 0, 0]", "[1e30, 0, 0]", "[0.5, 0, 0]"]),
        prop::sample::select(vec![
            "",
            ", rotate = { axis = [0, 0, 0], degrees = 30 }",
            ", rotate = { axis = [1e300, 1e300, 0], degrees = 1e300 }",
        ]),
    )
        .prop_map(|(spacing, scale, surface, translate, rotate)| {
            format!(
                "spacing = {spacing}, scale = {scale}, surface = \"{surface}\", \
                 translate = {translate}{rotate}"
            )
        });
    prop_oneof![3 => good, 1 => edges]
}

fn material() -> impl Strategy<Value = &'static str> {
    prop::sample::select(vec![
        "model = \"mass_spring\"\nstiffness = 1.0",
        "model = \"local_shape_matching\"\nstiffness = 20.0\nforces = \"cluster\"",
        "model = \"local_shape_matching\"\nstiffness = 20.0\nforces = \"node\"",
        "model = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3",
        "model = \"debunne_meshfree\"\nyoung_modulus = 1e4\npoisson_ratio = 0.45\ncorotated = true",
        "model = \"point_based\"\nyoung_modulus = 1e4\npoisson_ratio = 0.3",
    ])
}

fn obj_scene(keys: &str, material: &str) -> String {
    format!(
        "[tissue]\nneighbours = 6\ngeometry = {{ kind = \"obj\", path = \"fuzz.obj\", {keys} }}\n\
         [material]\n{material}\n"
    )
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn generated_obj_files_are_an_error_or_a_scene(
        obj in obj_text(),
        keys in obj_keys(),
        material in material(),
    ) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("fuzz.obj"), &obj).unwrap();
        let scene = obj_scene(&keys, material);
        parse_and_prepare_shown(&scene, dir.path(), &format!("{scene}\nfuzz.obj:\n{obj}"));
    }
}

// ---------------------------------------------------------------------------------------
// Inputs these properties found that panicked or hung, kept as regression tests.

/// Builds the OBJ scene `keys` around `obj`.
fn build_obj(obj: &str, keys: &str) {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("fuzz.obj"), obj).unwrap();
    let text = obj_scene(keys, "model = \"mass_spring\"\nstiffness = 1.0");
    let scene = Scene::from_toml_str(&text, dir.path()).unwrap();
    let _ = Simulation::prepare(&scene);
}

/// A unit cube of quads with its first vertex moved to y = -1.734..., rotated 30 degrees
/// and resampled: `geometry::resample::resample` indexed `vertex_of` out of bounds (a
/// lattice point of the outermost layer counted inside); now that layer is outside.
#[test]
fn a_rotated_distorted_cube_resamples_without_a_panic() {
    build_obj(
        "v 0 -1.7344565190404289 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 0 0 1\nv 1 0 1\nv 0 1 1\n\
         v 1 1 1\nf 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n",
        "spacing = 0.5, surface = \"resample\", rotate = { axis = [0, 0, 1], degrees = 30 }",
    );
}

/// A thin tetrahedron 200 spacings long with `surface = "vertices"` (4
/// nodes, no interior lattice point): `cell_volume::estimate` searched ever larger shells
/// of empty cells in `NodeGrid::nearest` for every sample, minutes for a 1 x 1 x 100 m body
/// (0.5 s at 20 m, 10 s at 40 m) before the "too few nodes" error; the grid now has at
/// most about two cells per node and shells are clipped to it.
#[test]
fn a_thin_tetrahedron_is_an_error_within_seconds() {
    within_time("a thin tetrahedron", || {
        build_obj(
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 100\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n",
            "spacing = 0.5, surface = \"vertices\"",
        );
    });
}
