//! The README and the user guide (`docs/`) checked against the code, so that they cannot
//! drift: the annotated scene example against the scene file it annotates, every complete
//! scene snippet parsed by the scene loader, every key the scene parser accepts named in
//! the reference, the history record's size the guide quotes against the type, and every
//! relative link and picture against the files. (The Python snippets run in
//! `scripts/doc_snippets.py`.)

use needlesim::needle::NeedleSample;
use needlesim::Scene;
use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(root().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// The guide's chapters and the README, as `(path relative to the root, text)`.
fn documents() -> Vec<(String, String)> {
    let mut out = vec![("README.md".to_string(), read("README.md"))];
    let mut chapters: Vec<PathBuf> = std::fs::read_dir(root().join("docs/guide"))
        .expect("docs/guide")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    chapters.sort();
    for p in chapters {
        let rel = p.strip_prefix(root()).unwrap().display().to_string();
        out.push((rel.clone(), read(&rel)));
    }
    out.push(("docs/SUMMARY.md".to_string(), read("docs/SUMMARY.md")));
    out
}

/// The fenced code blocks of `text` whose info string is `lang`.
fn blocks(text: &str, lang: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut current: Option<String> = None;
    for line in text.lines() {
        let fence = line.trim_start().strip_prefix("```");
        match (&mut current, fence) {
            (None, Some(info)) if info.trim() == lang => current = Some(String::new()),
            (Some(_), Some(_)) => out.push(current.take().unwrap()),
            (Some(body), None) => {
                body.push_str(line);
                body.push('\n');
            }
            _ => {}
        }
    }
    out
}

/// Every key path of `file` is in `example` with the same value (tables recursively,
/// arrays element by element).
fn assert_contains(example: &toml::Value, file: &toml::Value, path: &str) {
    match (example, file) {
        (toml::Value::Table(e), toml::Value::Table(f)) => {
            for (k, v) in f {
                let sub = format!("{path}.{k}");
                let e = e
                    .get(k)
                    .unwrap_or_else(|| panic!("the example lacks {sub}"));
                assert_contains(e, v, &sub);
            }
        }
        (toml::Value::Array(e), toml::Value::Array(f)) if f.iter().any(|v| v.is_table()) => {
            assert_eq!(e.len(), f.len(), "{path}: array lengths");
            for (i, (e, f)) in e.iter().zip(f).enumerate() {
                assert_contains(e, f, &format!("{path}[{i}]"));
            }
        }
        _ => assert_eq!(example, file, "{path}: the example and the file differ"),
    }
}

/// The scene reference's annotated example is `scenes/cube_sag_lshm.toml` with comments
/// and defaults written out: it loads, and it sets every key the file sets to the file's
/// value (the README once showed `neighbours = 18` for a file that has 16).
#[test]
fn the_annotated_example_is_the_scene_file_it_names() {
    let guide = read("docs/guide/scenes.md");
    let example = blocks(&guide, "toml")
        .into_iter()
        .next()
        .expect("a toml block in the scene reference");
    Scene::from_toml_str(&example, &root().join("scenes"))
        .unwrap_or_else(|e| panic!("the annotated example does not load: {e}"));
    let example: toml::Value = toml::from_str(&example).unwrap();
    let file: toml::Value = toml::from_str(&read("scenes/cube_sag_lshm.toml")).unwrap();
    assert_contains(&example, &file, "");
}

/// Every complete scene shown in the README and the guide (a block with `name =` and a
/// `[tissue]` table) loads.
#[test]
fn every_complete_scene_snippet_loads() {
    let mut checked = 0;
    for (doc, text) in documents() {
        for block in blocks(&text, "toml") {
            let complete = block.lines().any(|l| l.starts_with("name ="))
                && block.lines().any(|l| l.trim() == "[tissue]");
            if complete {
                Scene::from_toml_str(&block, &root().join("scenes"))
                    .unwrap_or_else(|e| panic!("{doc}: a scene snippet does not load: {e}"));
                checked += 1;
            }
        }
    }
    assert!(checked >= 1, "no complete scene snippet found");
}

/// The output chapter quotes the bytes the needle history keeps per step.
#[test]
fn the_history_record_size_in_the_guide_is_the_types() {
    let text = read("docs/guide/output.md");
    let at = text
        .find(" bytes a step")
        .expect("the output chapter gives the record's size");
    let digits: String = text[..at]
        .chars()
        .rev()
        .take_while(|c| c.is_ascii_digit())
        .collect::<Vec<_>>()
        .into_iter()
        .rev()
        .collect();
    let quoted: usize = digits.parse().expect("a number before ' bytes a step'");
    assert_eq!(quoted, std::mem::size_of::<NeedleSample>());
}

/// Every relative link and picture in the README, the guide and its summary names a file
/// that exists.
#[test]
fn every_relative_link_names_a_file() {
    let mut checked = 0;
    for (doc, text) in documents() {
        let dir = root().join(&doc).parent().unwrap().to_path_buf();
        let mut rest = text.as_str();
        while let Some(i) = rest.find("](") {
            rest = &rest[i + 2..];
            let Some(end) = rest.find(')') else { break };
            let target = &rest[..end];
            rest = &rest[end..];
            if target.contains("://") || target.starts_with('#') || target.contains(' ') {
                continue;
            }
            let file = target.split('#').next().unwrap();
            assert!(
                dir.join(file).exists(),
                "{doc}: the link ({target}) names no file"
            );
            checked += 1;
        }
    }
    assert!(checked > 10, "{checked} links");
}

/// The keys a scene table accepts, from the parser itself: a key it does not know gets an
/// error listing the ones it does (serde's `unknown field`, and the needle's own parser
/// in the same form). `table` is a scene with `bogus = 1` placed in the table under test.
fn accepted_keys(table: &str) -> Vec<String> {
    // The needle's tables are read when a simulation is prepared.
    let e = match Scene::from_toml_str(table, Path::new(".")) {
        Ok(scene) => match needlesim::needle::Simulation::prepare(&scene) {
            Ok(_) => panic!("a bogus key was accepted in:\n{table}"),
            Err(e) => e.to_string(),
        },
        Err(e) => e.to_string(),
    };
    let list = e
        .split_once("unknown field `bogus`, expected ")
        .unwrap_or_else(|| panic!("no key list in `{e}` for:\n{table}"))
        .1;
    // The needle's parser ends with " in `<table>`".
    let list = list.split(" in `").next().unwrap_or(list);
    list.split('`')
        .skip(1)
        .step_by(2)
        .map(str::to_string)
        .collect()
}

/// A needle that the needle tables under test can be added to.
const NEEDLE: &str = "base = [-0.11, 0.05, 0.05]\ndirection = [1.0, 0.0, 0.0]\nlength = 0.1\n";

/// Whether `word` stands in `text` as a word of its own (not inside a longer name).
fn has_word(text: &str, word: &str) -> bool {
    let part = |c: char| c.is_ascii_alphanumeric() || c == '_';
    text.match_indices(word).any(|(i, _)| {
        let before = text[..i].chars().next_back();
        let after = text[i + word.len()..].chars().next();
        !before.is_some_and(part) && !after.is_some_and(part)
    })
}

/// Every key each scene table accepts is named in the scene reference, the needle chapter
/// or the layers chapter (a key line, a table header or a word of a comment): the key
/// lists come from the parser, so a key added to the types without a word in the guide
/// fails here.
#[test]
fn every_key_the_scene_types_accept_is_in_the_reference() {
    let guide = [
        "docs/guide/scenes.md",
        "docs/guide/needle.md",
        "docs/guide/layers.md",
    ]
    .map(read)
    .join("\n");
    let box_geometry =
        "geometry = { kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], nodes = 100 }";
    let base = |tissue_extra: &str, material: &str, rest: &str| {
        format!("[tissue]\n{box_geometry}\n{tissue_extra}\n[material]\n{material}\n{rest}")
    };
    let msm = "model = \"mass_spring\"\nstiffness = 1.0";
    let mut tables: Vec<(String, String)> = vec![
        ("top level".into(), format!("bogus = 1\n{}", base("", msm, ""))),
        ("tissue".into(), base("bogus = 1", msm, "")),
        (
            "tissue.weight".into(),
            base("weight = { kernel = \"poly6\", bogus = 1 }", msm, ""),
        ),
        ("physics".into(), base("", msm, "[physics]\nbogus = 1\n")),
        ("run".into(), base("", msm, "[run]\nbogus = 1\n")),
        ("initial".into(), base("", msm, "[initial]\nbogus = 1\n")),
        (
            "fixed".into(),
            base("", msm, "[[fixed]]\naxis = \"x\"\nbelow = 0.01\nbogus = 1\n"),
        ),
        (
            "prescribed".into(),
            base("", msm, "[[prescribed]]\naxis = \"x\"\nbelow = 0.01\nbogus = 1\n"),
        ),
        (
            "load".into(),
            base("", msm, "[[load]]\naxis = \"x\"\nbelow = 0.01\nbogus = 1\n"),
        ),
        (
            "region".into(),
            base(
                "",
                msm,
                "[[region]]\nname = \"a\"\ngeometry = { kind = \"box\", min = [0.0, 0.0, 0.0], max = [0.05, 0.1, 0.1] }\nbogus = 1\n",
            ),
        ),
        ("needle".into(), base("", msm, &format!("[needle]\n{NEEDLE}bogus = 1\n"))),
        (
            "needle.friction".into(),
            base(
                "",
                msm,
                &format!("[needle]\n{NEEDLE}friction = {{ coefficient = 0.3, bogus = 1 }}\n"),
            ),
        ),
        (
            "needle.friction (paper)".into(),
            base(
                "",
                msm,
                &format!("[needle]\n{NEEDLE}friction = {{ model = \"paper\", bogus = 1 }}\n"),
            ),
        ),
        (
            "needle.thresholds".into(),
            base(
                "",
                msm,
                &format!("[needle]\n{NEEDLE}thresholds = {{ puncture = 80.0, bogus = 1 }}\n"),
            ),
        ),
        (
            "needle.keyframe".into(),
            base(
                "",
                msm,
                &format!(
                    "[needle]\n{NEEDLE}[[needle.keyframe]]\naction = \"move\"\nduration = 1.0\nbogus = 1\n"
                ),
            ),
        ),
    ];
    for kind in ["box", "obj", "stl", "vtk"] {
        tables.push((
            format!("tissue.geometry ({kind})"),
            format!("[tissue]\ngeometry = {{ kind = \"{kind}\", bogus = 1 }}\n[material]\n{msm}\n"),
        ));
    }
    for m in needlesim::core::models::MODELS {
        tables.push((
            format!("material ({})", m.tag),
            base("", &format!("model = \"{}\"\nbogus = 1", m.tag), ""),
        ));
    }
    let mut missing = Vec::new();
    for (name, table) in &tables {
        for key in accepted_keys(table) {
            if !has_word(&guide, &key) {
                missing.push(format!("{name}: {key}"));
            }
        }
    }
    assert!(
        missing.is_empty(),
        "accepted by the parser, not in the guide's reference:\n{}",
        missing.join("\n")
    );
}
