//! Parameter sweeps on local cores: a scene run once per variant, a variant being a set of
//! overrides of the scene's keys (dotted paths into its TOML, `material.stiffness`,
//! `needle.keyframe.0.speed`), each run on one CPU thread so that `jobs` runs use `jobs`
//! cores once. A variant that fails keeps its typed error; the others complete.

use crate::start_simulation;
use needlesim_core::scene::BackendChoice;
use needlesim_core::Scene;
use needlesim_needle::NeedleSample;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Why a sweep could not start, or a variant failed.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    /// A `--vary` argument is not `key=v1,v2,...`.
    #[error("`{0}` is not KEY=V1,V2,... (a dotted scene key and comma-separated values)")]
    Vary(String),
    /// A dotted key does not name a value of the scene.
    #[error("scene key `{key}`: {problem}")]
    Key {
        /// The dotted key.
        key: String,
        /// What is wrong.
        problem: String,
    },
    /// The scene text is not TOML.
    #[error("the scene is not TOML: {0}")]
    Toml(String),
    /// The variant's scene or run failed.
    #[error("{0}")]
    Run(String),
    /// The sweep was stopped ([`sweep_each`]'s `stop`) before this variant finished.
    #[error("interrupted before it finished")]
    Interrupted,
}

/// One override: a dotted key and its value.
pub type Override = (String, toml::Value);

/// A TOML value from a command line word: a TOML literal (`1e4`, `true`, `[1, 2]`,
/// `"text"`), else the word as a string.
pub fn parse_value(word: &str) -> toml::Value {
    toml::from_str::<toml::Table>(&format!("v = {word}"))
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(word.to_string()))
}

/// `key=v1,v2,...` as the key and its values.
pub fn parse_vary(spec: &str) -> Result<(String, Vec<toml::Value>), SweepError> {
    let (key, values) = spec
        .split_once('=')
        .ok_or_else(|| SweepError::Vary(spec.into()))?;
    let key = key.trim();
    if key.is_empty() || values.trim().is_empty() {
        return Err(SweepError::Vary(spec.into()));
    }
    let words = split_values(values).map_err(|problem| SweepError::Key {
        key: key.to_string(),
        problem,
    })?;
    Ok((
        key.to_string(),
        words.iter().map(|v| parse_value(v.trim())).collect(),
    ))
}

/// `text` cut to its first 60 characters, for a message (a value list can be long).
fn shortened(text: &str) -> String {
    match text.char_indices().nth(60) {
        Some((at, _)) => format!("{}...", &text[..at]),
        None => text.to_string(),
    }
}

/// The comma-separated values of a `--vary`, commas inside brackets, braces or quotes
/// kept (`[-0.11,0.05,0.05],[-0.11,0.04,0.05]` is two arrays; it was six fragments, each
/// taken as a string); an unclosed bracket or quote is an error.
fn split_values(values: &str) -> Result<Vec<&str>, String> {
    let (mut out, mut start, mut depth) = (Vec::new(), 0usize, 0i64);
    let mut quote: Option<char> = None;
    let mut escaped = false;
    for (i, c) in values.char_indices() {
        if let Some(q) = quote {
            if escaped {
                escaped = false;
            } else if c == '\\' && q == '"' {
                escaped = true;
            } else if c == q {
                quote = None;
            }
            continue;
        }
        match c {
            '"' | '\'' => quote = Some(c),
            '[' | '{' => depth += 1,
            ']' | '}' => {
                depth -= 1;
                if depth < 0 {
                    return Err(format!(
                        "value {} (`{}`) closes a bracket it never opened",
                        out.len(),
                        shortened(&values[start..=i])
                    ));
                }
            }
            ',' if depth == 0 => {
                out.push(&values[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    if quote.is_some() || depth != 0 {
        return Err(format!(
            "value {} (`{}`) leaves a quote or bracket open",
            out.len(),
            shortened(&values[start..])
        ));
    }
    out.push(&values[start..]);
    Ok(out)
}

/// Parses every `--vary` argument ([`parse_vary`]); a key given twice is an error (its
/// values would have made two columns of one key, the later one overriding the earlier).
pub fn parse_vary_all(specs: &[String]) -> Result<Vec<(String, Vec<toml::Value>)>, SweepError> {
    let mut out: Vec<(String, Vec<toml::Value>)> = Vec::with_capacity(specs.len());
    for spec in specs {
        let (key, values) = parse_vary(spec)?;
        if out.iter().any(|(k, _)| *k == key) {
            return Err(SweepError::Key {
                key,
                problem: "is varied twice: give all its values in one --vary KEY=V1,V2,...".into(),
            });
        }
        out.push((key, values));
    }
    Ok(out)
}

/// Every combination of the keys' values (the first key varies slowest).
pub fn grid(vary: &[(String, Vec<toml::Value>)]) -> Vec<Vec<Override>> {
    vary.iter().fold(vec![Vec::new()], |acc, (key, values)| {
        acc.iter()
            .flat_map(|prefix| {
                values.iter().map(move |v| {
                    let mut o = prefix.clone();
                    o.push((key.clone(), v.clone()));
                    o
                })
            })
            .collect()
    })
}

/// The scene text with the overrides set. A key must name an existing table path; its
/// last part may be new (an optional key). Numeric parts index arrays of tables.
pub fn apply(text: &str, overrides: &[Override]) -> Result<String, SweepError> {
    let mut doc: toml::Value = toml::from_str::<toml::Table>(text)
        .map(toml::Value::Table)
        .map_err(|e| SweepError::Toml(e.to_string()))?;
    for (key, value) in overrides {
        let err = |problem: &str| SweepError::Key {
            key: key.clone(),
            problem: problem.into(),
        };
        let parts: Vec<&str> = key.split('.').collect();
        let (last, path) = parts.split_last().ok_or_else(|| err("empty"))?;
        let mut at = &mut doc;
        for p in path {
            at = match at {
                toml::Value::Table(t) => t.get_mut(*p).ok_or_else(|| err(&format!("no `{p}`")))?,
                toml::Value::Array(a) => {
                    let i: usize = p
                        .parse()
                        .map_err(|_| err(&format!("`{p}` is not an index")))?;
                    let n = a.len();
                    a.get_mut(i)
                        .ok_or_else(|| err(&format!("index {i} past the {n} entries")))?
                }
                _ => return Err(err(&format!("`{p}` is inside a plain value"))),
            };
        }
        match at {
            toml::Value::Table(t) => {
                t.insert(last.to_string(), value.clone());
            }
            toml::Value::Array(a) => {
                let i: usize = last
                    .parse()
                    .map_err(|_| err("the last part must be an index"))?;
                let n = a.len();
                *a.get_mut(i)
                    .ok_or_else(|| err(&format!("index {i} past the {n} entries")))? =
                    value.clone();
            }
            _ => return Err(err("its parent is a plain value")),
        }
    }
    toml::to_string(&doc).map_err(|e| SweepError::Toml(e.to_string()))
}

/// What one variant's run recorded.
#[derive(Debug, Clone, PartialEq)]
pub struct VariantRun {
    /// The needle's record, every step.
    pub samples: Vec<NeedleSample>,
    /// Each sample's tip depth past the entry point along the needle, m
    /// ([`needlesim_needle::Simulation::depth_of`], as in `needle_force.csv`).
    pub depths: Vec<f64>,
}

/// Runs the scene `text` (relative paths from `base_dir`) for `steps` steps (the scene's
/// `run.steps` when `None`) on one CPU thread and returns the needle's record.
pub fn run_variant(
    text: &str,
    base_dir: &Path,
    steps: Option<u64>,
) -> Result<VariantRun, SweepError> {
    run_variant_until(text, base_dir, steps, None)
}

/// Steps between two looks at the stop flag of a variant run.
const STOP_CHECK_STEPS: u64 = 256;

/// [`run_variant`], ending early with [`SweepError::Interrupted`] once `stop` is set.
fn run_variant_until(
    text: &str,
    base_dir: &Path,
    steps: Option<u64>,
    stop: Option<&AtomicBool>,
) -> Result<VariantRun, SweepError> {
    let stopped = || stop.is_some_and(|s| s.load(Ordering::Relaxed));
    let run = || -> Result<Option<VariantRun>, Box<dyn std::error::Error>> {
        let scene = Scene::from_toml_str(text, base_dir)?;
        let (mut sim, _) = start_simulation(&scene, Some(BackendChoice::Cpu), None)?;
        let steps = match steps {
            Some(n) => n,
            None => scene.run.steps_at(sim.dt())?,
        };
        let mut done = 0;
        while done < steps {
            if stopped() {
                return Ok(None);
            }
            let n = STOP_CHECK_STEPS.min(steps - done);
            sim.step_n(n)?;
            done += n;
        }
        sim.check()?;
        let samples = sim.take_history();
        let depths = samples
            .iter()
            .map(|s| sim.depth_of(s.tip, s.direction))
            .collect();
        Ok(Some(VariantRun { samples, depths }))
    };
    match run() {
        Ok(Some(r)) => Ok(r),
        Ok(None) => Err(SweepError::Interrupted),
        Err(e) => Err(SweepError::Run(e.to_string())),
    }
}

/// Runs every variant of `text` on `jobs` threads (at least 1), one CPU thread each;
/// results in the variants' order.
pub fn sweep(
    text: &str,
    base_dir: &Path,
    variants: &[Vec<Override>],
    steps: Option<u64>,
    jobs: usize,
) -> Vec<Result<VariantRun, SweepError>> {
    let mut results: Vec<Option<Result<VariantRun, SweepError>>> =
        variants.iter().map(|_| None).collect();
    sweep_each(text, base_dir, variants, steps, jobs, None, |i, r| {
        results[i] = Some(r)
    });
    results
        .into_iter()
        .map(|r| r.unwrap_or_else(|| Err(SweepError::Run("not run (a worker panicked)".into()))))
        .collect()
}

/// Runs every variant of `text` on `jobs` threads (at least 1), one CPU thread each, and
/// hands each result to `done` on the calling thread as soon as it is there (in the order
/// the variants finish), so that a caller can write it out at once: a sweep stopped or
/// killed keeps what finished. Once `stop` is set no variant starts and the running ones
/// end with [`SweepError::Interrupted`] within a few hundred steps.
///
/// The pool is `jobs` scoped threads taking the next variant from a shared counter, not
/// rayon's: variants start in the order given (rayon's work stealing splits the list and
/// starts its halves at once, so a sweep stopped early would have started variants from
/// the middle of the grid), and results reach the calling thread while the workers run
/// (rayon's `install` blocks the caller, which would need a thread of its own to drain
/// them). Each variant runs one CPU thread, so the pools do not nest.
pub fn sweep_each(
    text: &str,
    base_dir: &Path,
    variants: &[Vec<Override>],
    steps: Option<u64>,
    jobs: usize,
    stop: Option<&AtomicBool>,
    mut done: impl FnMut(usize, Result<VariantRun, SweepError>),
) {
    let next = AtomicUsize::new(0);
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::scope(|s| {
        for _ in 0..jobs.max(1).min(variants.len().max(1)) {
            let tx = tx.clone();
            let next = &next;
            s.spawn(move || loop {
                if stop.is_some_and(|s| s.load(Ordering::Relaxed)) {
                    break;
                }
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(v) = variants.get(i) else { break };
                let r = apply(text, v).and_then(|t| run_variant_until(&t, base_dir, steps, stop));
                if tx.send((i, r)).is_err() {
                    break;
                }
            });
        }
        drop(tx);
        for (i, r) in rx {
            done(i, r);
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_keys_and_grids() {
        assert_eq!(parse_value("1e4"), toml::Value::Float(1e4));
        assert_eq!(parse_value("3"), toml::Value::Integer(3));
        assert_eq!(parse_value("cpu"), toml::Value::String("cpu".into()));
        let (k, v) = parse_vary("material.stiffness=10,20.5").unwrap();
        assert_eq!((k.as_str(), v.len()), ("material.stiffness", 2));
        assert!(matches!(
            parse_vary("material.stiffness"),
            Err(SweepError::Vary(_))
        ));
        let g = grid(&[
            ("a".into(), vec![parse_value("1"), parse_value("2")]),
            (
                "b".into(),
                vec![parse_value("x"), parse_value("y"), parse_value("z")],
            ),
        ]);
        assert_eq!(g.len(), 6);
        assert_eq!(
            g[1],
            vec![
                ("a".into(), parse_value("1")),
                ("b".into(), parse_value("y"))
            ]
        );
    }

    #[test]
    fn overrides_reach_tables_and_arrays_of_tables_and_name_bad_keys() {
        let text = "[material]\nstiffness = 20.0\n[[needle.keyframe]]\nspeed = 0.05\n";
        let out = apply(
            text,
            &[
                ("material.stiffness".into(), parse_value("30")),
                ("needle.keyframe.0.speed".into(), parse_value("0.01")),
            ],
        )
        .unwrap();
        let t: toml::Table = toml::from_str(&out).unwrap();
        assert_eq!(t["material"]["stiffness"].as_integer(), Some(30));
        assert_eq!(t["needle"]["keyframe"][0]["speed"].as_float(), Some(0.01));
        let e = apply(text, &[("materal.stiffness".into(), parse_value("1"))]).unwrap_err();
        assert!(e.to_string().contains("no `materal`"), "{e}");
        let e = apply(
            text,
            &[("needle.keyframe.3.speed".into(), parse_value("1"))],
        )
        .unwrap_err();
        assert!(e.to_string().contains("index 3 past the 1 entries"), "{e}");
    }
}

#[cfg(test)]
mod vary_tests {
    use super::*;

    #[test]
    fn commas_inside_arrays_and_strings_do_not_split_values() {
        let (key, v) = parse_vary("needle.base=[-0.11,0.05,0.05], [-0.11,0.04,0.05]").unwrap();
        assert_eq!(key, "needle.base");
        assert_eq!(v.len(), 2);
        assert_eq!(v[1], parse_value("[-0.11, 0.04, 0.05]"));
        let (_, v) = parse_vary("name=\"a, b\",'c,d',e").unwrap();
        assert_eq!(
            v,
            vec![
                toml::Value::String("a, b".into()),
                toml::Value::String("c,d".into()),
                toml::Value::String("e".into())
            ]
        );
        assert!(parse_vary("x=[1,2").is_err());
        assert!(parse_vary("x=1]").is_err());
        assert!(parse_vary("x=\"open").is_err());
        // The message names the value, not the whole list (7 kB for 1,000 values).
        let long: Vec<String> = (0..1000).map(|i| format!("{i}.0")).collect();
        let mut values = long.clone();
        values[778] = "[5777.0".into();
        let e = parse_vary(&format!("x={}", values.join(",")))
            .unwrap_err()
            .to_string();
        assert!(e.contains("value 778 (`[5777.0") && e.len() < 400, "{e}");
        let e = parse_vary("x=1,2,3]").unwrap_err().to_string();
        assert!(e.contains("value 2 (`3]`)"), "{e}");
    }
}
