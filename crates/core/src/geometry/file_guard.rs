//! Bounds on what a surface file may make its reader allocate, checked before the reader
//! runs, and a reader panic turned into an error naming the file.
//!
//! Surface files come from segmentation tools and other people's pipelines. The readers
//! (`vtkio`, `stl_io`, `tobj`) size their buffers from the counts a file declares: a
//! 300-byte legacy VTK file declaring `POINTS 1000000000 double` made the process abort
//! on a 24 GB allocation, and inconsistent cell counts made `vtkio` panic. Here every
//! count a file declares is checked against what its bytes can hold:
//!
//! - legacy VTK: `POINTS n` needs `3 n` numbers, a cell section `KEYWORD n size` `size`
//!   numbers, `CELL_TYPES n` `n`; an ASCII number takes at least 2 bytes (a digit and a
//!   separator), a binary one the size of its type (4 bytes for cell lists);
//! - XML VTK (`.vtp`, `.vtu`): `NumberOf...` counts are bounded by the file's size times
//!   zlib's largest compression ratio (1032:1, the only compressor this build reads)
//!   over the 4 bytes of the smallest value type; parallel files (`.pvtp`, `.pvtu`, or a
//!   `<Piece Source=...>`) name other files and are refused;
//! - zlib-compressed raw appended data of XML VTK: each array's block header (block count,
//!   block size, last block size, compressed sizes) must fit the file, claim at most
//!   1032 times its compressed bytes, and every block must inflate to no more than the
//!   size its header claims, checked by inflating it here with that cap (vtkio inflates a
//!   whole block whatever the header says: a 300 KB file made it hold 690 MB), and no
//!   array may claim more than the declared points and cells need (24 bytes a point, 128
//!   a cell). The same holds for base64 appended data, decoded as VTK writes it (the
//!   header encoded on its own, then the blocks together). Inline compressed arrays are
//!   left to vtkio, which does not inflate them (it fails them on their size);
//! - binary STL: the triangle count in its header must match the file's size (84 + 50 n
//!   bytes); a file that starts with `solid` is read as ASCII.
//!
//! OBJ files are read without their material libraries (`mtllib` would open any file the
//! OBJ names, a device or a pipe included; the tissue needs no materials).

use crate::error::GeometryError;
use std::borrow::Cow;
use std::path::Path;

/// zlib's largest compression ratio (deflate's maximum, about 1032:1).
const ZLIB_MAX_RATIO: u64 = 1032;

/// The error for `path` with `message`.
fn bad(path: &Path, message: String) -> GeometryError {
    GeometryError::ObjLoad {
        path: path.to_path_buf(),
        message,
    }
}

thread_local! {
    /// Set while this thread runs a reader inside [`guarded`].
    static GUARDED: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Whether the current thread is inside a surface reader whose panic becomes a typed
/// error naming the file. A program's panic hook can stay quiet then (the `needlesim`
/// tool and the Python module do: the error says what happened); the library itself
/// installs no hook.
pub fn panic_is_guarded() -> bool {
    GUARDED.with(|g| g.get())
}

/// Runs a reader, turning a panic inside it into an error naming the file.
pub(crate) fn guarded<T>(
    path: &Path,
    read: impl FnOnce() -> Result<T, GeometryError>,
) -> Result<T, GeometryError> {
    let outer = GUARDED.with(|g| g.replace(true));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(read));
    GUARDED.with(|g| g.set(outer));
    match result {
        Ok(r) => r,
        Err(payload) => {
            let what = payload
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "no message".into());
            Err(bad(
                path,
                format!("the file is malformed (its reader failed: {what})"),
            ))
        }
    }
}

/// Checks the counts a VTK file declares against its size (module docs).
pub(crate) fn check_vtk(path: &Path, bytes: &[u8]) -> Result<(), GeometryError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if matches!(ext.as_deref(), Some("pvtp" | "pvtu" | "pvtk")) {
        return Err(bad(
            path,
            "parallel VTK files (.pvtp, .pvtu) name other files and are not read: merge the \
             pieces into one .vtp or .vtu (ParaView: Merge Blocks, then Save Data)"
                .into(),
        ));
    }
    let size = bytes.len() as u64;
    if bytes.starts_with(b"# vtk DataFile") {
        check_legacy_vtk(path, bytes, size)
    } else {
        check_xml_vtk(path, bytes, size)
    }
}

fn check_legacy_vtk(path: &Path, bytes: &[u8], size: u64) -> Result<(), GeometryError> {
    let mut lines = bytes.split(|&b| b == b'\n');
    let binary = lines
        .nth(2)
        .is_some_and(|l| l.trim_ascii().eq_ignore_ascii_case(b"BINARY"));
    for line in bytes.split(|&b| b == b'\n') {
        let Ok(text) = std::str::from_utf8(line.trim_ascii()) else {
            continue;
        };
        let words: Vec<&str> = text.split_ascii_whitespace().collect();
        let Some(&keyword) = words.first() else {
            continue;
        };
        let number = |i: usize| -> Result<u64, GeometryError> {
            words
                .get(i)
                .and_then(|w| w.parse::<u64>().ok())
                .ok_or_else(|| bad(path, format!("`{text}`: expected a count after {keyword}")))
        };
        // (values the section holds, bytes of one binary value)
        let (values, width) = match keyword.to_ascii_uppercase().as_str() {
            "POINTS" => {
                let n = number(1)?;
                let width = match words.get(2).map(|w| w.to_ascii_lowercase()) {
                    Some(t) if t == "double" || t.ends_with("long") => 8,
                    Some(t) if t == "short" || t == "unsigned_short" => 2,
                    Some(t) if t == "char" || t == "unsigned_char" || t == "bit" => 1,
                    _ => 4,
                };
                (n.saturating_mul(3), width)
            }
            "POLYGONS" | "TRIANGLE_STRIPS" | "VERTICES" | "LINES" | "CELLS" => {
                let n = number(1)?;
                let total = number(2)?;
                if total < n {
                    return Err(bad(
                        path,
                        format!("`{text}`: {n} cells cannot fit in {total} numbers"),
                    ));
                }
                (total, 4)
            }
            "CELL_TYPES" | "POINT_DATA" | "CELL_DATA" => (number(1)?, 1),
            _ => continue,
        };
        let least = if binary { width } else { 2 };
        if values.saturating_mul(least) > size {
            return Err(bad(
                path,
                format!(
                    "`{text}` declares {values} numbers, more than the file's {size} bytes \
                     can hold"
                ),
            ));
        }
    }
    Ok(())
}

fn check_xml_vtk(path: &Path, bytes: &[u8], size: u64) -> Result<(), GeometryError> {
    let text = String::from_utf8_lossy(bytes);
    if text.contains("<Piece Source") || text.contains("<Piece  Source") {
        return Err(bad(
            path,
            "its pieces are other files (a parallel VTK file): merge them into one .vtp or \
             .vtu"
                .into(),
        ));
    }
    let most = size.saturating_mul(ZLIB_MAX_RATIO) / 4;
    // Declared points and cells over every piece: the most any appended array may hold.
    let (mut points, mut cells) = (0u64, 0u64);
    for attribute in [
        "NumberOfPoints",
        "NumberOfCells",
        "NumberOfPolys",
        "NumberOfStrips",
        "NumberOfVerts",
        "NumberOfLines",
    ] {
        let pattern = format!("{attribute}=\"");
        let mut rest: &str = &text;
        while let Some(i) = rest.find(&pattern) {
            rest = &rest[i + pattern.len()..];
            let value = &rest[..rest.find('"').unwrap_or(rest.len())];
            let n: u64 = value
                .trim()
                .parse()
                .map_err(|_| bad(path, format!("{attribute}=\"{value}\" is not a count")))?;
            match attribute {
                "NumberOfPoints" => points = points.saturating_add(n),
                _ => cells = cells.saturating_add(n),
            }
            // Points have 3 components.
            let values = match attribute {
                "NumberOfPoints" => n.saturating_mul(3),
                _ => n,
            };
            if values > most {
                return Err(bad(
                    path,
                    format!(
                        "{attribute}=\"{n}\": more than a {size}-byte file can hold, even \
                         compressed"
                    ),
                ));
            }
        }
    }
    // 8-byte values: 3 per point, and up to 16 vertex indices per cell (a triangle mesh
    // has 6 per point, 3 per cell), plus a little for empty arrays' headers.
    let budget = points
        .saturating_mul(24)
        .saturating_add(cells.saturating_mul(128))
        .saturating_add(4096);
    check_appended_zlib(path, bytes, &text, budget)
}

/// The value of attribute `name` in the tag text `tag`, if present.
fn attribute<'a>(tag: &'a str, name: &str) -> Option<&'a str> {
    let pattern = format!(" {name}=\"");
    let start = tag.find(&pattern)? + pattern.len();
    let len = tag[start..].find('"')?;
    Some(&tag[start..start + len])
}

/// The zlib block headers of appended data, raw or base64 (module docs).
fn check_appended_zlib(
    path: &Path,
    bytes: &[u8],
    text: &str,
    budget: u64,
) -> Result<(), GeometryError> {
    if !text.contains("vtkZLibDataCompressor") {
        return Ok(());
    }
    let Some(tag_at) = text.find("<AppendedData") else {
        return Ok(());
    };
    let tag_end = tag_at + text[tag_at..].find('>').unwrap_or(0);
    let base64 = match attribute(&text[tag_at..tag_end], "encoding") {
        Some("raw") => false,
        Some("base64") => true,
        _ => return Ok(()),
    };
    // The data start after the `_` that follows the tag; the text before it is ASCII, so
    // its byte offset in the file is its offset in the lossy text.
    let Some(underscore) = bytes[tag_end..].iter().position(|&b| b == b'_') else {
        return Err(bad(path, "its appended data has no `_` start mark".into()));
    };
    let data = &bytes[tag_end + underscore + 1..];
    let word = if text.contains("header_type=\"UInt64\"") {
        8
    } else {
        4
    };
    let mut rest: &str = &text[..tag_at];
    while let Some(i) = rest.find("<DataArray") {
        let tag = &rest[i..i + rest[i..].find('>').unwrap_or(rest.len() - i)];
        rest = &rest[i + tag.len()..];
        if attribute(tag, "format") != Some("appended") {
            continue;
        }
        let name = attribute(tag, "Name").unwrap_or("");
        let fail = |what: String| bad(path, format!("appended array \"{name}\": {what}"));
        let offset: usize = attribute(tag, "offset")
            .and_then(|o| o.trim().parse().ok())
            .ok_or_else(|| fail("no readable offset".into()))?;
        let array = data.get(offset..).unwrap_or_default();
        let (header, blocks) = match base64 {
            false => raw_array(array, word),
            true => base64_array(array, word),
        }
        .map_err(fail)?;
        check_zlib_blocks(&header, &blocks, budget).map_err(fail)?;
    }
    Ok(())
}

/// The block header words (`[nb, nu, np, nc_1, ..., nc_nb]`) and the compressed bytes
/// after them of a raw appended array starting at `array`, `word` bytes a header word.
fn raw_array(array: &[u8], word: usize) -> Result<(Vec<u64>, Cow<'_, [u8]>), String> {
    let short = || "its compression header runs past the end of the file".to_string();
    let words = |at: usize, n: usize| -> Result<Vec<u64>, String> {
        let end = n
            .checked_mul(word)
            .and_then(|b| b.checked_add(at))
            .filter(|&e| e <= array.len())
            .ok_or_else(short)?;
        Ok(header_words(&array[at..end], word))
    };
    let blocks = words(0, 1)?[0];
    // Every block needs a compressed size in the header.
    if blocks > (array.len() / word) as u64 {
        return Err(format!(
            "its header claims {blocks} compressed blocks, more than the file holds"
        ));
    }
    let header = words(0, 3 + blocks as usize)?;
    Ok((
        header,
        Cow::Borrowed(&array[(3 + blocks as usize) * word..]),
    ))
}

/// As [`raw_array`] for base64 appended data, laid out as VTK writes it and vtkio reads
/// it: the header encoded on its own, then the compressed blocks encoded together.
fn base64_array(array: &[u8], word: usize) -> Result<(Vec<u64>, Cow<'static, [u8]>), String> {
    let chars = |bytes: u64| bytes.div_ceil(3).saturating_mul(4);
    let decode = |from: u64, bytes: u64, what: &str| -> Result<Vec<u8>, String> {
        let end = from.saturating_add(chars(bytes));
        if end > array.len() as u64 {
            return Err(format!("its {what} runs past the end of the file"));
        }
        let config = base64::STANDARD.decode_allow_trailing_bits(true);
        base64::decode_config(&array[from as usize..end as usize], config)
            .map_err(|e| format!("its {what} is not base64: {e}"))
    };
    let w = word as u64;
    let first = decode(0, w, "compression header")?;
    let blocks = header_words(first.get(..word).unwrap_or_default(), word)
        .first()
        .copied()
        .ok_or("its compression header is empty")?;
    // Every block needs a compressed size in the header: 4/3 characters a byte.
    if blocks > array.len() as u64 / w {
        return Err(format!(
            "its header claims {blocks} compressed blocks, more than the file holds"
        ));
    }
    let header_bytes = (3 + blocks) * w;
    let decoded = decode(0, header_bytes, "compression header")?;
    let header = header_words(&decoded[..header_bytes as usize], word);
    let compressed = header[3..].iter().fold(0u64, |a, &n| a.saturating_add(n));
    let data = decode(chars(header_bytes), compressed, "compressed data")?;
    Ok((header, Cow::Owned(data)))
}

/// Little-endian header words of `word` bytes.
fn header_words(bytes: &[u8], word: usize) -> Vec<u64> {
    bytes
        .chunks_exact(word)
        .map(|b| match word {
            8 => u64::from_le_bytes(b.try_into().expect("8 bytes")),
            _ => u32::from_le_bytes(b.try_into().expect("4 bytes")) as u64,
        })
        .collect()
}

/// The checks of one array's zlib blocks (module docs): `header` is `[nb, nu, np, nc_1,
/// ..., nc_nb]`, `data` the compressed blocks one after the other.
fn check_zlib_blocks(header: &[u64], data: &[u8], budget: u64) -> Result<(), String> {
    let (blocks, block, last) = (header[0], header[1], header[2]);
    let claimed_total = match blocks {
        0 => 0,
        n => (n - 1)
            .saturating_mul(block)
            .saturating_add(if last > 0 { last } else { block }),
    };
    if claimed_total > budget {
        return Err(format!(
            "its header claims {claimed_total} bytes, more than the declared points and \
             cells need ({budget})"
        ));
    }
    let (mut at, mut compressed_total) = (0usize, 0u64);
    for (k, &size) in header[3..].iter().enumerate() {
        let end = usize::try_from(size)
            .ok()
            .and_then(|s| at.checked_add(s))
            .filter(|&e| e <= data.len())
            .ok_or_else(|| format!("block {k} runs past the end of the file"))?;
        compressed_total += size;
        let claim = if k + 1 == blocks as usize && last > 0 {
            last
        } else {
            block
        };
        if claim > size.saturating_mul(ZLIB_MAX_RATIO).saturating_add(64) {
            return Err(format!(
                "block {k} claims {claim} bytes from {size} compressed, more than zlib can \
                 inflate"
            ));
        }
        // Inflate with a cap one byte past the claim.
        use std::io::Read;
        let inflated = std::io::copy(
            &mut flate2::read::ZlibDecoder::new(&data[at..end]).take(claim + 1),
            &mut std::io::sink(),
        )
        .map_err(|e| format!("block {k} does not inflate: {e}"))?;
        if inflated > claim {
            return Err(format!(
                "block {k} inflates to more than the {claim} bytes its header claims"
            ));
        }
        at = end;
    }
    if claimed_total
        > compressed_total
            .saturating_mul(ZLIB_MAX_RATIO)
            .saturating_add(64)
    {
        return Err(format!(
            "its header claims {claimed_total} bytes from {compressed_total} compressed"
        ));
    }
    Ok(())
}

/// Checks a binary STL's triangle count against the file's size; `Ok(true)` for a binary
/// file, `Ok(false)` for one to read as ASCII (it starts with `solid` and its size is not
/// that of a binary file with the count it would declare).
pub(crate) fn check_stl(path: &Path, bytes: &[u8]) -> Result<bool, GeometryError> {
    let size = bytes.len() as u64;
    let declared = (size >= 84)
        .then(|| u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as u64);
    let binary_size = declared.map(|n| 84 + 50 * n);
    if binary_size == Some(size) {
        return Ok(true);
    }
    if bytes.trim_ascii_start().starts_with(b"solid") {
        return Ok(false);
    }
    Err(bad(
        path,
        match declared {
            Some(n) => format!(
                "a binary STL declaring {n} triangles has {} bytes, this file {size}",
                84 + 50 * n
            ),
            None => format!("{size} bytes: too short for an STL file"),
        },
    ))
}
