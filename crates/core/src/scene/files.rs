//! Limits on the files a scene reads.

use crate::error::SceneError;
use std::path::Path;

/// Largest scene file read, bytes (scenes are a few kB).
pub const MAX_SCENE_FILE_BYTES: u64 = 16 << 20;

/// Largest surface file read, bytes (a 10-million-triangle binary STL is 500 MB).
pub const MAX_SURFACE_FILE_BYTES: u64 = 2 << 30;

/// An error naming `key` if `path` is not a regular file or holds more than `max` bytes: a device
/// (`/dev/zero`), a pipe or a folder would be read until memory runs out, or fail later
/// with a less clear message.
pub fn check_input_file(path: &Path, max: u64, key: &str) -> Result<(), SceneError> {
    // A file that cannot be inspected (missing, no permission) is left to its reader,
    // whose error names the file in its own terms.
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(());
    };
    if !meta.is_file() {
        return Err(SceneError::invalid(
            key,
            format!("{} is not a regular file", path.display()),
        ));
    }
    if meta.len() > max {
        return Err(SceneError::invalid(
            key,
            format!(
                "{} holds {} bytes, more than the {max} read",
                path.display(),
                meta.len()
            ),
        ));
    }
    Ok(())
}
