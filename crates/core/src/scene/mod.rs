//! Scene description, read from TOML.
//!
//! A scene says what tissue to build (geometry, material model, density, neighbours),
//! how to step it (time step, gravity, damping, fixed nodes, initial deformation) and what
//! to write. Every table rejects unknown keys, and [`Scene::validate`] rejects values out
//! of range with an error that names the dotted key. Lengths are metres, masses kilograms,
//! times seconds.
//!
//! ```toml
//! [tissue]
//! density = 1000.0
//! neighbours = 18
//! geometry = { kind = "box", min = [0.0, 0.0, 0.0], max = [0.1, 0.1, 0.1], nodes = 639 }
//!
//! [material]
//! model = "local_shape_matching"
//! stiffness = 20.0
//!
//! [physics]
//! dt = 1e-3
//! gravity = [0.0, -9.81, 0.0]
//! damping = 5.0
//!
//! [[fixed]]
//! axis = "x"
//! below = 0.001
//! ```

pub mod builder;
mod files;
mod material;
mod physics;
mod region;
mod run;
mod selection;
mod tagged;
mod tissue;

pub use crate::models::debunne_meshfree::DebunneParams;
pub use crate::models::local_shape_matching::{ShapeMatchingForces, ShapeMatchingParams};
pub use crate::models::mass_spring::{MassSpringParams, SpringShare};
pub use crate::models::mls::{lame, NodeVolumes};
pub use crate::models::neo_hookean::NeoHookeanParams;
pub use crate::models::point_based::PointBasedParams;
pub use crate::models::Material;
pub use files::{check_input_file, MAX_SCENE_FILE_BYTES, MAX_SURFACE_FILE_BYTES};
pub(crate) use material::MaterialTable;
pub use physics::{Initial, Physics, TimeStep, AUTO_DT_SAFETY};
pub use region::{RegionGeometry, RegionSpec, RegionSurface};
pub use run::{RunSettings, DEFAULT_MAX_MEMORY_GIB, MAX_RUN_STEPS};
pub use selection::{
    Axis, Components, FarFieldSpec, FixedSelection, LoadSpec, Motion, NodeSet, Prescribed,
    SurfaceLoad,
};
pub(crate) use tissue::default_density;
pub use tissue::{
    AxisRotation, BoxGeometry, Geometry, NodeMasses, SurfaceGeometry, SurfaceNodes, TissueSpec,
    WeightKernel, DEFAULT_NEIGHBOURS, MIN_NEIGHBOURS,
};

/// The `[tissue]` table under its former name.
#[deprecated(note = "renamed TissueSpec (the runtime tissue is needlesim_core::Tissue)")]
pub type Tissue = TissueSpec;

/// The surface-file geometry under its former name (it serves OBJ, STL and VTK files).
#[deprecated(note = "renamed SurfaceGeometry")]
pub type ObjGeometry = SurfaceGeometry;

use crate::error::SceneError;
use material::de_material;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// A complete scene.
#[derive(Debug, Clone, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Free text shown by the CLI.
    #[serde(default)]
    pub name: String,
    /// Which backend runs the scene.
    #[serde(default)]
    pub backend: BackendChoice,
    /// The tissue: geometry, density and neighbourhoods.
    pub tissue: TissueSpec,
    /// The material model and its parameters.
    #[serde(deserialize_with = "de_material")]
    pub material: Material,
    /// Time step, gravity and damping.
    #[serde(default)]
    pub physics: Physics,
    /// Node sets held at rest (`[[fixed]]`), in all or some components.
    #[serde(default)]
    pub fixed: Vec<FixedSelection>,
    /// Node sets moved by a prescribed displacement (`[[prescribed]]`).
    #[serde(default)]
    pub prescribed: Vec<Prescribed>,
    /// Surface loads (`[[load]]`).
    #[serde(default)]
    pub load: Vec<LoadSpec>,
    /// Tissue regions with their own material (`[[region]]`, checked and resolved by
    /// `regions::classify` when the tissue is built).
    #[serde(default)]
    pub region: Vec<RegionSpec>,
    /// Initial deformation applied to the rest shape at the start.
    #[serde(default)]
    pub initial: Initial,
    /// How long to run and what to write.
    #[serde(default)]
    pub run: RunSettings,
    /// The needle (table `[needle]`), read and validated by `needlesim-needle`; this crate
    /// keeps it as raw TOML so that it knows nothing of the needle. A scene without it has
    /// no needle and allocates no needle node slots.
    #[serde(default)]
    pub needle: Option<toml::Table>,
    /// Directory that relative paths in the scene are resolved against (the scene file's
    /// directory); not read from the file.
    #[serde(skip)]
    pub base_dir: PathBuf,
}

/// Which backend steps the tissue.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "kebab-case")]
pub enum BackendChoice {
    /// One CPU thread.
    Cpu,
    /// All CPU threads (rayon); the default.
    #[default]
    CpuParallel,
    /// The wgpu compute backend; an error if no GPU adapter is found.
    Gpu,
    /// The GPU when an adapter is found, else all CPU threads (with a warning).
    Auto,
}

/// Keys whose value is a 3-vector wherever they appear in a scene.
const VECTOR_KEYS: &[&str] = &[
    "gravity",
    "stretch",
    "min",
    "max",
    "translate",
    "axis",
    "base",
    "direction",
    "point",
    "centre",
    "displacement",
    "velocity",
];

/// Refuses a 3-vector key given other than three elements, naming its whole path: serde's
/// fixed-size arrays read the first three and drop the rest, so `gravity = [0, -9.81, 0,
/// "junk"]` was accepted, and too few were refused without the key's name inside a
/// keyframe.
fn check_vector_lengths(table: &toml::Table, path: &str) -> Result<(), SceneError> {
    for (key, value) in table {
        let here = if path.is_empty() {
            key.clone()
        } else {
            format!("{path}.{key}")
        };
        match value {
            toml::Value::Array(a) if VECTOR_KEYS.contains(&key.as_str()) && a.len() != 3 => {
                return Err(SceneError::invalid(
                    here,
                    format!("has {} elements: a vector has three, [x, y, z]", a.len()),
                ));
            }
            toml::Value::Array(a) => {
                for (i, item) in a.iter().enumerate() {
                    if let toml::Value::Table(t) = item {
                        check_vector_lengths(t, &format!("{here}[{i}]"))?;
                    }
                }
            }
            toml::Value::Table(t) => check_vector_lengths(t, &here)?,
            _ => {}
        }
    }
    Ok(())
}

/// The first character of `text` that a name must not hold because it acts on a terminal
/// or a file instead of being seen: a control character (escape, NUL, carriage return ...),
/// a Unicode line or paragraph separator, a bidirectional override, isolate or mark, or a
/// zero-width space or byte-order mark. (The zero-width joiners, U+200C and U+200D, are
/// part of emoji sequences and of several scripts: they pass.) A scene name with `ESC [2J` cleared the terminal of
/// `needlesim info`; a set name with NUL reached the `reactions.csv` header.
pub fn hidden_character(text: &str) -> Option<char> {
    text.chars().find(|&c| {
        c.is_control()
            || matches!(
                c,
                '\u{2028}' | '\u{2029}' | '\u{200B}' | '\u{200E}' | '\u{200F}' | '\u{202A}'..='\u{202E}'
                    | '\u{2066}'..='\u{2069}' | '\u{FEFF}'
            )
    })
}

impl Scene {
    /// Parses and validates a scene from TOML text. Relative paths resolve against
    /// `base_dir`.
    pub fn from_toml_str(text: &str, base_dir: &Path) -> Result<Scene, SceneError> {
        Self::parse(text, "<string>", base_dir)
    }

    /// [`Scene::from_toml_str`], its parse errors naming `origin` (where the text came
    /// from) instead of `<string>`.
    pub fn from_toml_str_named(
        text: &str,
        origin: &str,
        base_dir: &Path,
    ) -> Result<Scene, SceneError> {
        Self::parse(text, origin, base_dir)
    }

    /// Reads, parses and validates a scene file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Scene, SceneError> {
        let path = path.as_ref();
        check_input_file(path, MAX_SCENE_FILE_BYTES, "scene file")?;
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let base = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        Self::parse(&text, &path.display().to_string(), &base)
    }

    fn parse(text: &str, origin: &str, base_dir: &Path) -> Result<Scene, SceneError> {
        let mut scene: Scene = toml::from_str(text).map_err(|e| SceneError::Parse {
            origin: origin.to_string(),
            message: e.to_string().trim_end().to_string(),
        })?;
        scene.base_dir = base_dir.to_path_buf();
        if let Ok(doc) = text.parse::<toml::Table>() {
            check_vector_lengths(&doc, "")?;
        }
        scene.validate()?;
        Ok(scene)
    }

    /// The names of the held sets as `reactions.csv` and Python's `reactions()` give them,
    /// `[[fixed]]` first then `[[prescribed]]`, each with its key: the `name` given, or
    /// `fixed<i>` / `prescribed<i>`.
    pub fn held_set_names(&self) -> Vec<(String, String)> {
        let fixed = self.fixed.iter().enumerate().map(|(i, f)| {
            let name = f.name.clone().unwrap_or_else(|| format!("fixed{i}"));
            (format!("fixed[{i}].name"), name)
        });
        let prescribed = self.prescribed.iter().enumerate().map(|(i, p)| {
            let name = p.name.clone().unwrap_or_else(|| format!("prescribed{i}"));
            (format!("prescribed[{i}].name"), name)
        });
        fixed.chain(prescribed).collect()
    }

    /// Held set names are column prefixes of `reactions.csv` and keys of a dict: each is
    /// a non-empty name without separators, quotes, brackets or line breaks, and no two
    /// are the same (with the defaults `fixed<i>` / `prescribed<i>` counted).
    fn validate_set_names(&self) -> Result<(), SceneError> {
        let names = self.held_set_names();
        for (k, (key, name)) in names.iter().enumerate() {
            if name.trim().is_empty()
                || name.trim() != name
                || name.contains([',', ';', '"', '\'', '[', ']'])
                || hidden_character(name).is_some()
            {
                return Err(SceneError::invalid(
                    key.clone(),
                    format!(
                        "must be a non-empty name without commas, semicolons, quotes, \
                         brackets, control characters (tabs, line breaks ...), invisible \
                         Unicode characters or surrounding spaces, got {name:?}"
                    ),
                ));
            }
            if let Some((other, _)) = names[..k].iter().find(|(_, n)| n == name) {
                return Err(SceneError::invalid(
                    key.clone(),
                    format!("`{name}` is also the name of {other}: each held set needs its own"),
                ));
            }
        }
        Ok(())
    }

    /// Checks every value's range, table by table. Called by the parsers; call it again
    /// after editing a scene in code.
    pub fn validate(&self) -> Result<(), SceneError> {
        if let Some(c) = hidden_character(&self.name) {
            return Err(SceneError::invalid(
                "name",
                format!(
                    "holds the character {c:?}, which a terminal or a file would act on \
                     instead of showing: the name is printed and written to outputs"
                ),
            ));
        }
        self.tissue.validate()?;
        self.material.validate("material")?;
        self.physics.validate()?;
        for (i, f) in self.fixed.iter().enumerate() {
            f.validate(&format!("fixed[{i}]"))?;
        }
        for (i, p) in self.prescribed.iter().enumerate() {
            p.validate(&format!("prescribed[{i}]"))?;
        }
        for (i, l) in self.load.iter().enumerate() {
            l.validate(&format!("load[{i}]"))?;
        }
        self.validate_set_names()?;
        self.initial.validate()?;
        let dt = match self.physics.dt {
            TimeStep::Seconds(dt) => Some(dt),
            TimeStep::Auto => None,
        };
        self.run.validate(dt)
    }
}
