//! Checkpoints: the whole state of a [`Simulation`](crate::Simulation) in one versioned
//! file. A run restored from one continues bitwise as if it had not stopped on the CPU
//! backends (the GPU backend restores the same bytes; its own rounding differs from the
//! CPU's, not from itself).
//!
//! The state: every node array of the backend (all slots: an inactive slot keeps the bytes
//! the undo log puts back when a node is removed), every shape array (static ones and the
//! per-step ones such as warm-start rotations), the node editor (neighbour rows, shape
//! mirror, rest positions, undo log), the needle (pose, last pose, whether its script still
//! drives it), the puncture phase, the needle nodes and their friction states, the split
//! surface triangles and their grid, the clock and the history.
//!
//! File layout: the magic `NEEDLESIM-CHECKPOINT\n`, the format version (u32, little
//! endian), the payload length (u64), the payload's CRC-32 (IEEE, `crc32fast`; u32), then
//! the payload in the postcard encoding. Another version, another magic, a short or altered file
//! are typed errors ([`CheckpointError`]).
//!
//! A checkpoint does not rebuild a tissue: it is restored onto one prepared from the same
//! scene ([`Prepared::resume`](crate::Prepared::resume)), which a fingerprint of the scene
//! parts that shape the state checks (the run settings, the backend and the name may
//! change). It can carry the scene's TOML text ([`Checkpoint::scene`]) so that a file alone
//! is enough to resume (the Python `Simulation.load`).

use crate::node_editor::EditorSnapshot;
use crate::state::NeedleState;
use needlesim_core::math::Vec4;
use needlesim_core::Scene;
use serde::{Deserialize, Serialize};
use std::io::Write as _;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// First bytes of a checkpoint file.
pub const MAGIC: &[u8] = b"NEEDLESIM-CHECKPOINT\n";
/// Format version this build writes and reads. Raised whenever the payload changes (12:
/// the neo-Hookean and point based materials carry a `viscosity` (the fingerprint's
/// material text changed), point based animation's node rows hold it where they held
/// alpha mu, and the fingerprint hashes the `[[region]]` list (a region's own material
/// fills the node rows a checkpoint restores); 11:
/// the tip's element carries its pushing share and that share's handover after an edit,
/// `FrontElement::free` and [`crate::sheath::FreeFade`], and the contact patch the touched
/// point's place against its mean, `Patch::offset`; 10:
/// the continuum models' moment rows carry the integration correction, 66 floats per
/// node instead of 48; 9: the continuum models' moment rows and first passes carry the hourglass control's
/// quadratic fit, 48 and 28 floats per node instead of 9 and 12; 8: the scene fingerprint
/// hashes `[[fixed]]` with its `far_field` key, so a version 7 file is refused as a
/// version rather than as another scene).
pub const FORMAT_VERSION: u32 = 12;
const HEADER: usize = MAGIC.len() + 4 + 8 + 4;

/// Why a checkpoint cannot be written, read or restored.
#[derive(Debug, Error)]
pub enum CheckpointError {
    /// The file cannot be read or written.
    #[error("checkpoint {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file does not start with [`MAGIC`].
    #[error("{path} is not a needlesim checkpoint")]
    NotACheckpoint {
        /// The file.
        path: PathBuf,
    },
    /// The file was written by a build with another format version.
    #[error(
        "checkpoint {path} has format version {found}; this build reads version {expected} \
         (resume with the needlesim version that wrote it, or start the run again)"
    )]
    Version {
        /// The file.
        path: PathBuf,
        /// Version in the file.
        found: u32,
        /// Version this build reads.
        expected: u32,
    },
    /// The file is shorter than its header says (an interrupted copy or write).
    #[error("checkpoint {path} is truncated: {got} of {expected} bytes")]
    Truncated {
        /// The file.
        path: PathBuf,
        /// Bytes present.
        got: u64,
        /// Bytes the header announces.
        expected: u64,
    },
    /// The payload does not match its hash or does not decode.
    #[error("checkpoint {} is corrupt: {reason}", shown(path))]
    Corrupt {
        /// The file (empty when restored from memory).
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The checkpoint was taken with a scene that differs from the one given.
    #[error(
        "the checkpoint was taken with another scene: its `{part}` differs (resume with the \
         scene the checkpoint was written from; only `run`, `backend` and `name` may change)"
    )]
    SceneMismatch {
        /// The scene part that differs (`tissue`, `material`, `needle`, ...).
        part: String,
    },
    /// The checkpoint carries no scene text and none was given.
    #[error("the checkpoint carries no scene; give the scene it was taken with")]
    NoScene,
    /// The state holds a value that is not finite (a diverged run): it is neither written
    /// nor restored.
    #[error(
        "checkpoint {path}: node {node}'s {field} is not finite ({value:?}): the state \
         diverged; a checkpoint of it would resume a broken run"
    )]
    NonFinite {
        /// The file (empty when taken in memory).
        path: PathBuf,
        /// The first node found.
        node: usize,
        /// `position` or `velocity`.
        field: &'static str,
        /// The value (x, y, z).
        value: [f32; 3],
    },
}

/// A checkpoint's path for a message: "(taken in memory)" when it has none.
fn shown(path: &Path) -> String {
    match path.as_os_str().is_empty() {
        true => "(taken in memory)".into(),
        false => path.display().to_string(),
    }
}

/// The scene a checkpoint can carry: its TOML text and the folder relative paths resolve
/// against.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneText {
    /// The scene as TOML.
    pub toml: String,
    /// The scene file's folder.
    pub base_dir: PathBuf,
}

impl SceneText {
    /// Parses and validates the scene.
    pub fn scene(&self) -> Result<Scene, needlesim_core::SceneError> {
        Scene::from_toml_str(&self.toml, &self.base_dir)
    }

    /// [`SceneText::scene`], its errors naming the checkpoint file it came from.
    pub fn scene_stored_in(&self, checkpoint: &Path) -> Result<Scene, needlesim_core::SceneError> {
        Scene::from_toml_str_named(
            &self.toml,
            &format!("stored in {}", checkpoint.display()),
            &self.base_dir,
        )
    }
}

/// The backend's arrays.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct BackendSnapshot {
    pub n_active: usize,
    pub steps: u64,
    /// Positions as the backend stores them, in the tissue's frame
    /// (`NodeField::StoredPosition`; the world's for a body near the origin).
    pub positions: Vec<Vec4>,
    pub velocities: Vec<Vec4>,
    pub forces: Vec<Vec4>,
    /// The integrator's position remainders (format version 5 on).
    pub position_remainders: Vec<Vec4>,
    /// Every shape array, in [`needlesim_core::models::ShapeInfo::bytes`] order.
    pub shape: Vec<Vec<u8>>,
}

/// The needle simulation's own state and clock.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct SimSnapshot {
    pub state: NeedleState,
    /// Whether the scene's script still drives the needle.
    pub scripted: bool,
    pub time: f64,
    pub steps: u64,
}

/// The whole state of a simulation. Take one with
/// [`Simulation::checkpoint`](crate::Simulation::checkpoint), write it with
/// [`Checkpoint::write`], read it with [`Checkpoint::read`], restore it with
/// [`Prepared::resume`](crate::Prepared::resume).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Checkpoint {
    /// The scene, if the writer attached it (a checkpoint restores onto a tissue prepared
    /// from the same scene; with it, the file alone is enough).
    pub scene: Option<SceneText>,
    pub(crate) fingerprint: Vec<(String, u32)>,
    pub(crate) backend: BackendSnapshot,
    pub(crate) editor: EditorSnapshot,
    pub(crate) sim: SimSnapshot,
    /// The file it was read from (empty when taken in memory), for errors found while
    /// restoring it.
    #[serde(skip)]
    pub(crate) source: PathBuf,
}

impl Checkpoint {
    /// Simulated time at the checkpoint, s.
    pub fn time(&self) -> f64 {
        self.sim.time
    }

    /// Steps taken at the checkpoint.
    pub fn steps(&self) -> u64 {
        self.sim.steps
    }

    /// The file's bytes (header and payload).
    pub fn to_bytes(&self) -> Vec<u8> {
        let payload = postcard::to_stdvec(self).expect("in-memory serialisation cannot fail");
        let mut out = Vec::with_capacity(HEADER + payload.len());
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
        out.extend_from_slice(&payload);
        out
    }

    /// The first active node whose position or velocity is not finite.
    fn check_finite(&self, path: &Path) -> Result<(), CheckpointError> {
        let b = &self.backend;
        let n = [&b.positions, &b.velocities, &b.position_remainders]
            .iter()
            .fold(b.n_active, |n, a| n.min(a.len()));
        for (field, rows) in [
            ("position", &b.positions),
            ("velocity", &b.velocities),
            ("position remainder", &b.position_remainders),
        ] {
            if let Some((node, v)) = rows[..n]
                .iter()
                .enumerate()
                .find(|(_, v)| !v[..3].iter().all(|x| x.is_finite()))
            {
                return Err(CheckpointError::NonFinite {
                    path: path.to_path_buf(),
                    node,
                    field,
                    value: [v[0], v[1], v[2]],
                });
            }
        }
        Ok(())
    }

    /// Decodes a file's bytes; `path` names the file in errors.
    pub fn from_bytes(bytes: &[u8], path: &Path) -> Result<Checkpoint, CheckpointError> {
        let path = path.to_path_buf();
        if bytes.len() < MAGIC.len() || &bytes[..MAGIC.len()] != MAGIC {
            return Err(CheckpointError::NotACheckpoint { path });
        }
        if bytes.len() < HEADER {
            return Err(CheckpointError::Truncated {
                path,
                got: bytes.len() as u64,
                expected: HEADER as u64,
            });
        }
        let word = |at: usize, n: usize| {
            let mut b = [0u8; 8];
            b[..n].copy_from_slice(&bytes[at..at + n]);
            u64::from_le_bytes(b)
        };
        let version = word(MAGIC.len(), 4) as u32;
        if version != FORMAT_VERSION {
            return Err(CheckpointError::Version {
                path,
                found: version,
                expected: FORMAT_VERSION,
            });
        }
        let len = word(MAGIC.len() + 4, 8);
        let crc = word(MAGIC.len() + 12, 4) as u32;
        let expected = (HEADER as u64).saturating_add(len);
        if (bytes.len() as u64) < expected {
            return Err(CheckpointError::Truncated {
                path,
                got: bytes.len() as u64,
                expected,
            });
        }
        if (bytes.len() as u64) > expected {
            return Err(CheckpointError::Corrupt {
                path,
                reason: format!("{} bytes past the payload", bytes.len() as u64 - expected),
            });
        }
        let payload = &bytes[HEADER..];
        if crc32fast::hash(payload) != crc {
            return Err(CheckpointError::Corrupt {
                path,
                reason: "the payload does not match its CRC-32".into(),
            });
        }
        let mut c: Checkpoint =
            postcard::from_bytes(payload).map_err(|e| CheckpointError::Corrupt {
                path: path.clone(),
                reason: e.to_string(),
            })?;
        c.check_finite(&path)?;
        c.source = path;
        Ok(c)
    }

    /// Writes the checkpoint to `path` atomically (a `.partial` file renamed over it), so
    /// that an interruption leaves the previous checkpoint intact. Refuses a state that
    /// is not finite, and a `path` (or its `.partial`) that exists and is not a regular
    /// file: a checkpoint never replaces a device, a pipe or a folder.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<(), CheckpointError> {
        let path = path.as_ref();
        self.check_finite(path)?;
        let io = |source| CheckpointError::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(".partial");
        let tmp = PathBuf::from(tmp);
        for p in [path, tmp.as_path()] {
            match std::fs::symlink_metadata(p) {
                Ok(m) if !m.file_type().is_file() => {
                    return Err(io(std::io::Error::new(
                        std::io::ErrorKind::InvalidInput,
                        format!("{} exists and is not a regular file", p.display()),
                    )));
                }
                _ => {}
            }
        }
        {
            let mut f = std::fs::File::create(&tmp).map_err(io)?;
            f.write_all(&self.to_bytes()).map_err(io)?;
            f.sync_all().map_err(io)?;
        }
        std::fs::rename(&tmp, path).map_err(io)
    }

    /// Reads a checkpoint file.
    pub fn read(path: impl AsRef<Path>) -> Result<Checkpoint, CheckpointError> {
        let path = path.as_ref();
        needlesim_core::scene::check_input_file(path, u64::MAX, "checkpoint").map_err(|e| {
            // The reason alone: the file is no scene key ("scene key `checkpoint`" misled).
            let reason = match e {
                needlesim_core::SceneError::InvalidValue { reason, .. } => reason,
                other => other.to_string(),
            };
            CheckpointError::Io {
                path: path.to_path_buf(),
                source: std::io::Error::new(std::io::ErrorKind::InvalidInput, reason),
            }
        })?;
        let bytes = std::fs::read(path).map_err(|source| CheckpointError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Checkpoint::from_bytes(&bytes, path)
    }
}

/// The scene parts that shape a simulation's state, each hashed (CRC-32: stable across
/// Rust releases, unlike std's hashers): a checkpoint restores only onto a tissue prepared
/// from a scene with the same parts. `nodes` hashes the built node
/// positions and inverse masses, so that a changed surface file is caught too.
pub(crate) fn fingerprint(scene: &Scene, positions: &[Vec4]) -> Vec<(String, u32)> {
    // Debug output of floats is exact (shortest round-trip form), so equal text is equal
    // values.
    let parts: [(&str, String); 9] = [
        ("tissue", format!("{:?}", scene.tissue)),
        ("material", format!("{:?}", scene.material)),
        ("region", format!("{:?}", scene.region)),
        ("physics", format!("{:?}", scene.physics)),
        ("fixed", format!("{:?}", scene.fixed)),
        ("prescribed", format!("{:?}", scene.prescribed)),
        ("load", format!("{:?}", scene.load)),
        ("initial", format!("{:?}", scene.initial)),
        ("needle", format!("{:?}", scene.needle)),
    ];
    let mut out: Vec<(String, u32)> = parts
        .into_iter()
        .map(|(k, v)| (k.to_string(), crc32fast::hash(v.as_bytes())))
        .collect();
    out.push((
        "nodes".to_string(),
        crc32fast::hash(bytemuck::cast_slice(positions)),
    ));
    out
}
