//! The README and the user guide (`docs/`) checked against the code, so that they cannot
//! drift: the annotated scene example against the scene file it annotates, every complete
//! scene snippet parsed by the scene loader, the history record's size the guide quotes
//! against the type, and every relative link and picture against the files.

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
