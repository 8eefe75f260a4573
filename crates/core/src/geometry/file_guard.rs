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
//!   bytes); a file that starts with `solid` (any case, after a byte order mark) is read
//!   as ASCII.
//!
//! A fuzzing pass (about 5,400 damaged and crafted files, issue 45) found ways past the
//! first version of these checks, each now closed and tested (`tests/hostile_inputs.rs`):
//! a legacy file not starting with its header line, or with a count on the line of
//! another keyword, skipped or missed the checks; attribute counts (`SCALARS`,
//! `LOOKUP_TABLE`, `COLOR_SCALARS`, `TEXTURE_COORDINATES`, `FIELD` arrays) were not
//! checked; XML attributes in single quotes or spaced round their `=` were not seen; a
//! file without `header_type` was checked with 4-byte words and read with 8. The reader
//! is given the checked bytes (not the file again), with VTK's default `header_type`
//! written in and raw appended data re-encoded as base64 ([`xml_for_reader`]).
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
    if is_xml(bytes) {
        check_xml_vtk(path, bytes, size)
    } else {
        check_legacy_vtk(path, vtk_body(bytes), size)
    }
}

/// `bytes` from its first line on: without a UTF-8 byte order mark and blank space before
/// it, which the readers skip. (A legacy file that began with a newline went to the XML
/// check, so none of its counts were checked, and vtkio then allocated 24 GB.)
fn vtk_body(bytes: &[u8]) -> &[u8] {
    bytes
        .strip_prefix(b"\xEF\xBB\xBF")
        .unwrap_or(bytes)
        .trim_ascii_start()
}

/// An ASCII legacy cell list (`words` from just after its header `what`: `n` cells in
/// `total` numbers, over `points` points) read as its reader will: each cell a vertex
/// count and that many point numbers. A count that disagrees with the cells, a negative
/// or non-integer number or a point beyond the file's was "holds no surface cells" or a
/// failed assertion inside the reader; here it names the cell.
fn check_ascii_cells(
    path: &Path,
    words: &[&str],
    n: u64,
    total: u64,
    points: u64,
    what: &str,
) -> Result<(), GeometryError> {
    let fail = |m: String| bad(path, format!("`{what}`: {m}"));
    let number = |at: usize, cell: u64| -> Result<u64, GeometryError> {
        let w = words
            .get(at)
            .ok_or_else(|| fail(format!("the file ends in cell {cell} of {n}")))?;
        w.parse::<u64>().map_err(|_| {
            fail(format!(
                "cell {cell} holds `{w}` where a non-negative whole number is needed"
            ))
        })
    };
    let mut at = 0usize;
    for cell in 0..n {
        let k = number(at, cell)?;
        if k > total {
            return Err(fail(format!("cell {cell} claims {k} vertices")));
        }
        for v in 0..k as usize {
            let p = number(at + 1 + v, cell)?;
            if p >= points {
                return Err(fail(format!(
                    "cell {cell} uses point {p}, but the file has {points} points"
                )));
            }
        }
        at += 1 + k as usize;
    }
    if at as u64 != total {
        return Err(fail(format!(
            "its {n} cells hold {at} numbers, not the {total} the header says"
        )));
    }
    Ok(())
}

/// Whether a VTK file is XML (`.vtp`, `.vtu`) rather than legacy, by its content.
pub(crate) fn is_xml(bytes: &[u8]) -> bool {
    vtk_body(bytes).starts_with(b"<")
}

/// The bytes vtkio is given for an XML VTK file: `bytes`, with `header_type="UInt32"`
/// added to the `VTKFile` tag when it has none. That is VTK's default for the block
/// headers of compressed data (files of format version 0.1 have no attribute), but
/// vtkio assumes UInt64: such a file failed with a size mismatch, and the compression
/// check, which read 4-byte words, could be passed by a header vtkio read otherwise.
///
/// Raw appended data is handed over re-encoded as base64 ([`raw_appended_as_base64`]).
pub(crate) fn xml_for_reader(bytes: &[u8]) -> Cow<'_, [u8]> {
    let Some((at, _, tag)) = first_tag(bytes, b"<VTKFile") else {
        return Cow::Borrowed(bytes);
    };
    // Pieces without points (VTK writes `<Piece NumberOfPoints="0" .../>` for an empty
    // block) are left out: vtkio's reader panicked on them. [`check_xml_vtk`] has refused
    // a piece that declares points and has none.
    let pieces = pieces(bytes);
    if pieces.iter().any(|p| !p.has_points) {
        let mut kept = Vec::with_capacity(bytes.len());
        let mut from = 0;
        for p in pieces.iter().filter(|p| !p.has_points) {
            kept.extend_from_slice(&bytes[from..p.range.start]);
            from = p.range.end;
        }
        kept.extend_from_slice(&bytes[from..]);
        return Cow::Owned(xml_for_reader(&kept).into_owned());
    }
    let patched: Cow<'_, [u8]> = if attribute(&tag, "header_type").is_some() {
        Cow::Borrowed(bytes)
    } else {
        let insert = at + b"<VTKFile".len();
        let mut out = Vec::with_capacity(bytes.len() + 24);
        out.extend_from_slice(&bytes[..insert]);
        out.extend_from_slice(b" header_type=\"UInt32\"");
        out.extend_from_slice(&bytes[insert..]);
        Cow::Owned(out)
    };
    let word = header_word(bytes);
    let compressed = attribute(&tag, "compressor").is_some_and(|c| !c.is_empty());
    match raw_appended_as_base64(&patched, word, compressed) {
        Some(b) => Cow::Owned(b),
        None => patched,
    }
}

/// The file with its raw appended data re-encoded as base64, laid out as VTK writes
/// base64 appended data (an uncompressed array's size word and bytes encoded together; a
/// compressed array's block header encoded on its own, then its blocks), with every
/// appended array's `offset` moved to its place in the encoded text. vtkio's XML reader
/// takes raw appended bytes as text and fails at the first `<`, `>` or `&` among them,
/// so a raw-appended file as ParaView and VTK write it (their default) could not be read.
/// `None` when the file has no raw appended data or its arrays cannot be delimited (the
/// reader then gets it as it is).
fn raw_appended_as_base64(bytes: &[u8], word: usize, compressed: bool) -> Option<Vec<u8>> {
    let (tag_at, tag_end, tag) = first_tag(bytes, b"<AppendedData")?;
    if attribute(&tag, "encoding") != Some("raw") {
        return None;
    }
    let data_at = tag_end + bytes[tag_end..].iter().position(|&b| b == b'_')? + 1;
    let close = b"</AppendedData>";
    let data_end = bytes
        .windows(close.len())
        .rposition(|w| w == close)
        .filter(|&e| e >= data_at)?;
    let data = &bytes[data_at..data_end];
    let number = |at: usize| -> Option<usize> {
        let w = data.get(at..at.checked_add(word)?)?;
        let v = match word {
            8 => u64::from_le_bytes(w.try_into().ok()?),
            _ => u32::from_le_bytes(w.try_into().ok()?) as u64,
        };
        usize::try_from(v).ok()
    };
    // Appended DataArray tags before the data: (offset value's byte range, offset).
    let head = &bytes[..tag_at];
    let mut arrays: Vec<(std::ops::Range<usize>, usize)> = Vec::new();
    let mut from = 0;
    while let Some(i) = find(&head[from..], b"<DataArray") {
        let start = from + i;
        let end = start + head[start..].iter().position(|&b| b == b'>')?;
        from = end;
        let text = std::str::from_utf8(&head[start..end]).ok()?;
        if attribute(text, "format") != Some("appended") {
            continue;
        }
        let value = attribute(text, "offset")?;
        let offset: usize = value.trim().parse().ok()?;
        // The value's place in the file: attribute() returned a slice of `text`.
        let at = start + (value.as_ptr() as usize - text.as_ptr() as usize);
        arrays.push((at..at + value.len(), offset));
    }
    let mut offsets: Vec<usize> = arrays.iter().map(|a| a.1).collect();
    offsets.sort_unstable();
    offsets.dedup();
    let mut encoded = String::new();
    let mut moved = std::collections::HashMap::new();
    for &o in &offsets {
        let (header_len, body_len) = if compressed {
            let blocks = number(o)?;
            let header_len = blocks.checked_add(3)?.checked_mul(word)?;
            let mut body = 0usize;
            for k in 0..blocks {
                body = body.checked_add(number(o + (3 + k) * word)?)?;
            }
            (header_len, body)
        } else {
            (word, number(o)?)
        };
        let end = o.checked_add(header_len)?.checked_add(body_len)?;
        let array = data.get(o..end)?;
        moved.insert(o, encoded.len());
        if compressed {
            encoded.push_str(&base64::encode(&array[..header_len]));
            encoded.push_str(&base64::encode(&array[header_len..]));
        } else {
            encoded.push_str(&base64::encode(array));
        }
    }
    arrays.sort_by_key(|a| a.0.start);
    let mut out = Vec::with_capacity(tag_at + encoded.len() + 64);
    let mut copied = 0;
    for (range, offset) in &arrays {
        out.extend_from_slice(&bytes[copied..range.start]);
        out.extend_from_slice(moved[offset].to_string().as_bytes());
        copied = range.end;
    }
    out.extend_from_slice(&bytes[copied..tag_at]);
    out.extend_from_slice(b"<AppendedData encoding=\"base64\">\n_");
    out.extend_from_slice(encoded.as_bytes());
    out.extend_from_slice(b"\n");
    out.extend_from_slice(&bytes[data_end..]);
    Some(out)
}

/// The first tag that `open` starts (`b"<VTKFile"`) in `bytes`: where it starts, where
/// its `>` is (the file's end without one), and its text. Positions are in the bytes, not
/// in a lossily decoded text (longer wherever the file is not UTF-8: its offsets indexed
/// past the end of the bytes).
fn first_tag(bytes: &[u8], open: &[u8]) -> Option<(usize, usize, String)> {
    let at = find(bytes, open)?;
    let end = bytes[at..]
        .iter()
        .position(|&b| b == b'>')
        .map_or(bytes.len(), |e| at + e);
    Some((
        at,
        end,
        String::from_utf8_lossy(&bytes[at..end]).into_owned(),
    ))
}

/// Bytes of a compression header word as vtkio reads the file after [`xml_for_reader`]:
/// 8 for `header_type="UInt64"`, else 4 (VTK's default).
fn header_word(bytes: &[u8]) -> usize {
    match first_tag(bytes, b"<VTKFile") {
        Some((_, _, tag)) if attribute(&tag, "header_type") == Some("UInt64") => 8,
        _ => 4,
    }
}

/// The first position of `needle` in `haystack`.
fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

/// An XML VTK `<Piece>` element: its byte range in the file, its tag text, and whether it
/// holds points (a `<Points>` element and a declared `NumberOfPoints` that is not 0).
struct PieceSpan {
    range: std::ops::Range<usize>,
    tag: String,
    has_points: bool,
    has_points_element: bool,
}

/// `bytes` with the text of every XML comment (`<!-- ... -->`) blanked out, so that a tag
/// in a comment is not taken for one (positions unchanged).
fn without_comments(bytes: &[u8]) -> Cow<'_, [u8]> {
    let Some(first) = find(bytes, b"<!--") else {
        return Cow::Borrowed(bytes);
    };
    let mut out = bytes.to_vec();
    let mut from = first;
    while let Some(i) = find(&out[from..], b"<!--") {
        let at = from + i;
        let end = find(&out[at + 4..], b"-->").map_or(out.len(), |e| at + 4 + e + 3);
        out[at..end].iter_mut().for_each(|b| *b = b' ');
        from = end;
        if from >= out.len() {
            break;
        }
    }
    Cow::Owned(out)
}

/// The `<Piece>` elements before any appended data (raw appended bytes may hold
/// anything), comments left out.
fn pieces(bytes: &[u8]) -> Vec<PieceSpan> {
    let end = find(bytes, b"<AppendedData").unwrap_or(bytes.len());
    let view = without_comments(&bytes[..end]);
    let bytes = &view[..];
    let is_name_end =
        |b: Option<&u8>| b.is_none_or(|b| b.is_ascii_whitespace() || b"/>".contains(b));
    // The end of the element from `from`: past `</Piece` and blanks up to its `>`.
    let close = |from: usize| -> usize {
        let mut at = from;
        while let Some(i) = find(&bytes[at..], b"</Piece") {
            let tail = at + i + b"</Piece".len();
            let rest = bytes[tail..].iter().position(|b| !b.is_ascii_whitespace());
            if let Some(r) = rest.filter(|&r| bytes[tail + r] == b'>') {
                return tail + r + 1;
            }
            at = tail;
        }
        bytes.len()
    };
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(i) = find(&bytes[from..], b"<Piece") {
        let at = from + i;
        from = at + b"<Piece".len();
        if !is_name_end(bytes.get(from)) {
            continue;
        }
        let Some(gt) = bytes[from..].iter().position(|&b| b == b'>') else {
            break;
        };
        let tag_end = from + gt;
        let tag = String::from_utf8_lossy(&bytes[at..tag_end]).into_owned();
        let (body, stop) = if bytes[tag_end - 1] == b'/' {
            (&bytes[tag_end..tag_end], tag_end + 1)
        } else {
            let stop = close(tag_end);
            (&bytes[tag_end..stop], stop)
        };
        let has_points_element = body
            .windows(b"<Points".len() + 1)
            .any(|w| w.starts_with(b"<Points") && is_name_end(w.last()));
        let declared_zero =
            attribute(&tag, "NumberOfPoints").is_some_and(|n| n.trim().parse::<u64>() == Ok(0));
        out.push(PieceSpan {
            range: at..stop,
            tag,
            has_points: has_points_element && !declared_zero,
            has_points_element,
        });
        from = stop;
    }
    out
}

/// Bytes of one binary value of the VTK data type named `t` (4 for a name it does not
/// know: the smallest bound that still counts a float).
fn type_width(t: &str) -> u64 {
    match t.to_ascii_lowercase().as_str() {
        "double" | "long" | "unsigned_long" | "vtkidtype" | "vtktypeint64" | "vtktypeuint64" => 8,
        "short" | "unsigned_short" | "vtktypeint16" | "vtktypeuint16" => 2,
        "char" | "unsigned_char" | "bit" | "vtktypeint8" | "vtktypeuint8" => 1,
        _ => 4,
    }
}

/// Whether `t` names a VTK data type (a field array's header ends with one).
fn is_type_name(t: &str) -> bool {
    matches!(
        t.to_ascii_lowercase().as_str(),
        "bit"
            | "char"
            | "unsigned_char"
            | "short"
            | "unsigned_short"
            | "int"
            | "unsigned_int"
            | "long"
            | "unsigned_long"
            | "float"
            | "double"
            | "vtkidtype"
    )
}

/// The legacy checks. `body` starts at the file's first line; the keywords are read as
/// vtkio reads them, as a stream of words (`DATASET POLYDATA POINTS 5 float` on one line
/// is valid), from the fourth line on (the second is free text). Every count that sizes
/// an allocation is bounded by what the file's `size` bytes can hold: points, cell lists
/// and cell types; the point and cell data counts; and the attributes' own counts, each
/// times the data count before it (`SCALARS` components, at most 4 by the format;
/// `COLOR_SCALARS` values; `TEXTURE_COORDINATES` dimension, at most 3; a
/// `LOOKUP_TABLE`'s size; a `FIELD`'s array count and each array's components times
/// tuples). Each of those made vtkio abort on a 5 to 64 GB allocation.
fn check_legacy_vtk(path: &Path, body: &[u8], size: u64) -> Result<(), GeometryError> {
    let mut lines = body.split(|&b| b == b'\n');
    let binary = lines
        .nth(2)
        .is_some_and(|l| l.trim_ascii().eq_ignore_ascii_case(b"BINARY"));
    let rest_at = {
        let mut at = 0;
        for _ in 0..3 {
            match body[at..].iter().position(|&b| b == b'\n') {
                Some(i) => at += i + 1,
                None => return Ok(()),
            }
        }
        at
    };
    let words: Vec<&str> = body[rest_at..]
        .split(|b| b.is_ascii_whitespace())
        .filter(|w| !w.is_empty())
        .filter_map(|w| std::str::from_utf8(w).ok())
        .collect();
    let least = |width: u64| if binary { width } else { 2 };
    let fits = |values: u64, width: u64, what: String| -> Result<(), GeometryError> {
        if values.saturating_mul(least(width)) > size {
            return Err(bad(
                path,
                format!("`{what}` declares {values} numbers, more than the file's {size} bytes can hold"),
            ));
        }
        Ok(())
    };
    let count = |i: usize, keyword: &str| -> Result<u64, GeometryError> {
        words
            .get(i)
            .and_then(|w| w.parse::<u64>().ok())
            .ok_or_else(|| bad(path, format!("expected a count after {keyword}")))
    };
    let phrase = |from: usize, n: usize| words[from..(from + n).min(words.len())].join(" ");
    // Values per point or cell data item follow from the last POINT_DATA / CELL_DATA.
    let mut data_count = 0u64;
    let mut points = 0u64;
    // Where a `LOOKUP_TABLE` right after a SCALARS header names a table (no size).
    let mut scalars_end = usize::MAX;
    for (i, &word) in words.iter().enumerate() {
        let keyword = word.to_ascii_uppercase();
        match keyword.as_str() {
            "POINTS" => {
                let n = count(i + 1, word)?;
                points = n;
                let width = words.get(i + 2).map_or(4, |t| type_width(t));
                fits(n.saturating_mul(3), width, phrase(i, 3))?;
            }
            "POLYGONS" | "TRIANGLE_STRIPS" | "VERTICES" | "LINES" | "CELLS" => {
                let (n, total) = (count(i + 1, word)?, count(i + 2, word)?);
                if words
                    .get(i + 3)
                    .is_some_and(|w| w.eq_ignore_ascii_case("OFFSETS"))
                {
                    return Err(bad(
                        path,
                        "it uses the legacy VTK 5.1 cell layout (OFFSETS and CONNECTIVITY), \
                         which this reader does not read: save it as legacy VTK 4.2 or as .vtp"
                            .into(),
                    ));
                }
                if total < n {
                    return Err(bad(
                        path,
                        format!(
                            "`{}`: {n} cells cannot fit in {total} numbers",
                            phrase(i, 3)
                        ),
                    ));
                }
                fits(total, 4, phrase(i, 3))?;
                if !binary {
                    check_ascii_cells(path, &words[i + 3..], n, total, points, &phrase(i, 3))?;
                }
            }
            "CELL_TYPES" => fits(count(i + 1, word)?, 4, phrase(i, 2))?,
            "POINT_DATA" | "CELL_DATA" => {
                data_count = count(i + 1, word)?;
                fits(data_count, 1, phrase(i, 2))?;
            }
            "SCALARS" => {
                // SCALARS name type [components]
                let components = words.get(i + 3).and_then(|w| w.parse::<u64>().ok());
                if let Some(c) = components {
                    if !(1..=4).contains(&c) {
                        return Err(bad(
                            path,
                            format!("`{}`: scalars have 1 to 4 components", phrase(i, 4)),
                        ));
                    }
                }
                let width = words.get(i + 2).map_or(4, |t| type_width(t));
                fits(
                    data_count.saturating_mul(components.unwrap_or(1)),
                    width,
                    phrase(i, 4),
                )?;
                scalars_end = i + 3 + usize::from(components.is_some());
            }
            "LOOKUP_TABLE" if i != scalars_end => {
                // A table's definition: LOOKUP_TABLE name size, 4 values an entry.
                let n = count(i + 2, word)?;
                fits(n.saturating_mul(4), 1, phrase(i, 3))?;
            }
            "COLOR_SCALARS" => {
                let n = count(i + 2, word)?;
                fits(data_count.saturating_mul(n), 1, phrase(i, 3))?;
            }
            "TEXTURE_COORDINATES" => {
                let dim = count(i + 2, word)?;
                if !(1..=3).contains(&dim) {
                    return Err(bad(
                        path,
                        format!(
                            "`{}`: texture coordinates have 1 to 3 dimensions",
                            phrase(i, 4)
                        ),
                    ));
                }
                let width = words.get(i + 3).map_or(4, |t| type_width(t));
                fits(data_count.saturating_mul(dim), width, phrase(i, 4))?;
            }
            "FIELD" => {
                // FIELD name arrays: each array takes a header line of 4 words at least.
                let n = count(i + 2, word)?;
                fits(n.saturating_mul(4), 1, phrase(i, 3))?;
            }
            _ => {
                // A field array's header: name components tuples type.
                let header = (
                    words.get(i + 1).and_then(|w| w.parse::<u64>().ok()),
                    words.get(i + 2).and_then(|w| w.parse::<u64>().ok()),
                    words.get(i + 3),
                );
                if let (Some(c), Some(t), Some(ty)) = header {
                    if is_type_name(ty) && word.parse::<f64>().is_err() {
                        fits(c.saturating_mul(t), type_width(ty), phrase(i, 4))?;
                    }
                }
            }
        }
    }
    Ok(())
}

/// The most points, and the most cells, a surface file may declare: 2^25 (33.5 million;
/// 0.8 GB of coordinates, far beyond any organ surface, whose meshes have up to a few
/// million). Within the other bounds a 4 MB `.vtp` declaring 170 million points could
/// hold a zlib stream that vtkio inflated to 3 GB before it failed.
pub const MAX_SURFACE_ITEMS: u64 = 1 << 25;

fn check_xml_vtk(path: &Path, bytes: &[u8], size: u64) -> Result<(), GeometryError> {
    let text = String::from_utf8_lossy(bytes);
    let spans = pieces(bytes);
    if spans.iter().any(|p| attribute(&p.tag, "Source").is_some()) {
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
    for tag in spans.iter().map(|p| p.tag.as_str()) {
        for name in [
            "NumberOfPoints",
            "NumberOfCells",
            "NumberOfPolys",
            "NumberOfStrips",
            "NumberOfVerts",
            "NumberOfLines",
        ] {
            let Some(value) = attribute(tag, name) else {
                continue;
            };
            let n: u64 = value
                .trim()
                .parse()
                .map_err(|_| bad(path, format!("{name}=\"{value}\" is not a count")))?;
            match name {
                "NumberOfPoints" => points = points.saturating_add(n),
                _ => cells = cells.saturating_add(n),
            }
            // Points have 3 components.
            let values = match name {
                "NumberOfPoints" => n.saturating_mul(3),
                _ => n,
            };
            if values > most {
                return Err(bad(
                    path,
                    format!(
                        "{name}=\"{n}\": more than a {size}-byte file can hold, even \
                         compressed"
                    ),
                ));
            }
        }
    }
    if points > MAX_SURFACE_ITEMS || cells > MAX_SURFACE_ITEMS {
        return Err(bad(
            path,
            format!(
                "it declares {points} points and {cells} cells, more than the \
                 {MAX_SURFACE_ITEMS} a surface may have: decimate the surface (it needs only \
                 to resolve the node spacing)"
            ),
        ));
    }
    // 8-byte values: 3 per point, and up to 16 vertex indices per cell (a triangle mesh
    // has 6 per point, 3 per cell), plus a little for empty arrays' headers.
    let budget = points
        .saturating_mul(24)
        .saturating_add(cells.saturating_mul(128))
        .saturating_add(4096);
    check_appended_zlib(path, bytes, &text, budget)?;
    for (k, p) in spans.iter().enumerate() {
        let declared = attribute(&p.tag, "NumberOfPoints").map(str::trim);
        if !p.has_points_element && declared.is_some_and(|n| n.parse::<u64>() != Ok(0)) {
            return Err(bad(
                path,
                format!(
                    "piece {k} declares NumberOfPoints=\"{}\" but has no <Points> element",
                    declared.unwrap_or_default()
                ),
            ));
        }
    }
    if spans.iter().all(|p| !p.has_points) {
        return Err(bad(
            path,
            if spans.is_empty() {
                "it has no <Piece> element: no surface".into()
            } else {
                format!("none of its {} pieces has points: no surface", spans.len())
            },
        ));
    }
    Ok(())
}

/// The value of attribute `name` in the tag text `tag`, if present: `name="value"` or
/// `name='value'`, with blanks allowed around the `=` (an attribute in single quotes or
/// spaced out was not seen, and the compression check let a zlib bomb through).
fn attribute<'a>(tag: &'a str, name: &str) -> Option<&'a str> {
    let mut from = 0;
    while let Some(i) = tag[from..].find(name) {
        let at = from + i;
        from = at + name.len();
        let before = tag[..at].chars().next_back();
        if !before.is_some_and(char::is_whitespace) {
            continue;
        }
        let rest = tag[from..].trim_start();
        let Some(rest) = rest.strip_prefix('=') else {
            continue;
        };
        let rest = rest.trim_start();
        let Some(quote) = rest.chars().next().filter(|c| *c == '"' || *c == '\'') else {
            continue;
        };
        let value = &rest[1..];
        let len = value.find(quote)?;
        return Some(&value[..len]);
    }
    None
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
    let Some((tag_at, tag_end, tag)) = first_tag(bytes, b"<AppendedData") else {
        return Ok(());
    };
    let base64 = match attribute(&tag, "encoding") {
        Some("raw") => false,
        Some("base64") => true,
        Some(other) => {
            return Err(bad(
                path,
                format!("its appended data has encoding \"{other}\" (raw or base64)"),
            ))
        }
        None => return Ok(()),
    };
    let Some(underscore) = bytes[tag_end..].iter().position(|&b| b == b'_') else {
        return Err(bad(path, "its appended data has no `_` start mark".into()));
    };
    let data = &bytes[tag_end + underscore + 1..];
    let word = header_word(bytes);
    let head = String::from_utf8_lossy(&bytes[..tag_at]);
    let mut rest: &str = &head;
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
    let header = header_words(
        decoded
            .get(..header_bytes as usize)
            .ok_or("its compression header is shorter than its block count needs")?,
        word,
    );
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
    if stl_text_start(bytes)
        .get(..5)
        .is_some_and(|w| w.eq_ignore_ascii_case(b"solid"))
    {
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

/// An STL file from where its text starts: after a UTF-8 byte order mark and blank space
/// (an ASCII file beginning with a byte order mark, or with `SOLID` in capitals, was
/// taken for a binary one and refused for its size).
pub(crate) fn stl_text_start(bytes: &[u8]) -> &[u8] {
    vtk_body(bytes)
}

/// An OBJ file's text as its reader should see it: UTF-8 (an error naming the first bad
/// byte otherwise; the reader said only "read error"), without a byte order mark (its
/// first line was dropped, and the faces then used a vertex that was not there), and with
/// lines ended by a lone carriage return (classic Mac) split as lines (the reader saw one
/// line and reported a colour).
pub(crate) fn obj_text<'a>(path: &Path, bytes: &'a [u8]) -> Result<Cow<'a, str>, GeometryError> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let text = std::str::from_utf8(bytes).map_err(|e| {
        bad(
            path,
            format!(
                "the file is not UTF-8 text (byte {} is not): an OBJ file is text",
                e.valid_up_to()
            ),
        )
    })?;
    Ok(if text.contains('\r') {
        Cow::Owned(text.replace("\r\n", "\n").replace('\r', "\n"))
    } else {
        Cow::Borrowed(text)
    })
}
