//! A hand-written MATLAB level-5 MAT-file reader (the format of CWRU and MFPT files).
//!
//! Reads numeric arrays (double, single, all integer classes, logical), char arrays, structs
//! (nested, struct arrays) and cell arrays, zlib-compressed elements (`miCOMPRESSED`, MAT v7)
//! and both byte orders. Every length is checked against the bytes that remain, nesting depth
//! is bounded and decompression is capped, so hostile input gives an error, never a panic or an
//! unbounded allocation. Sparse, object and function arrays are skipped (reported as
//! [`MatValue::Unsupported`]). MAT v4 and v7.3 (HDF5) files are recognised and refused with a
//! message saying how to re-save them.
//!
//! [`directory`] lists a file's variables (name, class, dims, where they lie) from the header
//! and the head of each element alone, a compressed one decompressed only that far; then
//! [`decode_selected`] decodes just the variables an importer needs.

use std::fmt;
use std::io::{Read, Seek, SeekFrom};

/// Largest decompressed size of one `miCOMPRESSED` element (bytes).
pub const MAX_DECOMPRESSED: usize = 1 << 30;
/// Deflate cannot expand data by more than ~1032:1; anything beyond is a bomb.
const MAX_DEFLATE_RATIO: usize = 1032;
/// Deepest nesting of structs/cells accepted.
const MAX_DEPTH: usize = 32;

// Data types (miXXX).
const MI_INT8: u32 = 1;
const MI_UINT8: u32 = 2;
const MI_INT16: u32 = 3;
const MI_UINT16: u32 = 4;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_SINGLE: u32 = 7;
const MI_DOUBLE: u32 = 9;
const MI_INT64: u32 = 12;
const MI_UINT64: u32 = 13;
const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;
const MI_UTF8: u32 = 16;
const MI_UTF16: u32 = 17;
const MI_UTF32: u32 = 18;

/// Array classes (mxXXX_CLASS).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MatClass {
    Cell,
    Struct,
    Object,
    Char,
    Sparse,
    Double,
    Single,
    Int8,
    UInt8,
    Int16,
    UInt16,
    Int32,
    UInt32,
    Int64,
    UInt64,
    Function,
    Opaque,
    Unknown(u8),
}

impl MatClass {
    fn from_u8(c: u8) -> MatClass {
        use MatClass::*;
        match c {
            1 => Cell,
            2 => Struct,
            3 => Object,
            4 => Char,
            5 => Sparse,
            6 => Double,
            7 => Single,
            8 => Int8,
            9 => UInt8,
            10 => Int16,
            11 => UInt16,
            12 => Int32,
            13 => UInt32,
            14 => Int64,
            15 => UInt64,
            16 => Function,
            17 => Opaque,
            other => Unknown(other),
        }
    }

    /// MATLAB's name for the class ("double", "struct", ...).
    pub fn name(&self) -> String {
        use MatClass::*;
        match self {
            Cell => "cell".into(),
            Struct => "struct".into(),
            Object => "object".into(),
            Char => "char".into(),
            Sparse => "sparse".into(),
            Double => "double".into(),
            Single => "single".into(),
            Int8 => "int8".into(),
            UInt8 => "uint8".into(),
            Int16 => "int16".into(),
            UInt16 => "uint16".into(),
            Int32 => "int32".into(),
            UInt32 => "uint32".into(),
            Int64 => "int64".into(),
            UInt64 => "uint64".into(),
            Function => "function handle".into(),
            Opaque => "opaque".into(),
            Unknown(c) => format!("class {c}"),
        }
    }

    /// double, single or an integer class.
    pub fn is_numeric(&self) -> bool {
        use MatClass::*;
        matches!(
            self,
            Double | Single | Int8 | UInt8 | Int16 | UInt16 | Int32 | UInt32 | Int64 | UInt64
        )
    }
}

/// The value of one MAT variable (or struct field / cell element).
#[derive(Debug, Clone, PartialEq)]
pub enum MatValue {
    /// A numeric or logical array; values converted to f64, column-major.
    Numeric {
        class: MatClass,
        dims: Vec<usize>,
        real: Vec<f64>,
        /// Imaginary part of a complex array.
        imag: Option<Vec<f64>>,
        logical: bool,
    },
    /// A char array; rows joined with '\n'.
    Char { dims: Vec<usize>, text: String },
    /// A struct (array): field names and, per field, one value per element (column-major).
    Struct {
        dims: Vec<usize>,
        fields: Vec<(String, Vec<MatValue>)>,
    },
    /// A cell array, column-major.
    Cell {
        dims: Vec<usize>,
        cells: Vec<MatValue>,
    },
    /// Sparse, object, function handle...: present but not decoded.
    Unsupported { class: MatClass, dims: Vec<usize> },
}

impl MatValue {
    pub fn dims(&self) -> &[usize] {
        match self {
            MatValue::Numeric { dims, .. }
            | MatValue::Char { dims, .. }
            | MatValue::Struct { dims, .. }
            | MatValue::Cell { dims, .. }
            | MatValue::Unsupported { dims, .. } => dims,
        }
    }

    pub fn class_name(&self) -> String {
        match self {
            MatValue::Numeric { class, logical, .. } => {
                if *logical {
                    "logical".into()
                } else {
                    class.name()
                }
            }
            MatValue::Char { .. } => "char".into(),
            MatValue::Struct { .. } => "struct".into(),
            MatValue::Cell { .. } => "cell".into(),
            MatValue::Unsupported { class, .. } => class.name(),
        }
    }

    /// "243938x1 double", for messages.
    pub fn describe(&self) -> String {
        let dims: Vec<String> = self.dims().iter().map(|d| d.to_string()).collect();
        format!("{} {}", dims.join("x"), self.class_name())
    }

    /// A field of a 1x1 struct.
    pub fn field(&self, name: &str) -> Option<&MatValue> {
        match self {
            MatValue::Struct { fields, .. } => fields
                .iter()
                .find(|(n, _)| n == name)
                .and_then(|(_, v)| v.first()),
            _ => None,
        }
    }

    /// Field names of a struct (empty for other values).
    pub fn field_names(&self) -> Vec<&str> {
        match self {
            MatValue::Struct { fields, .. } => fields.iter().map(|(n, _)| n.as_str()).collect(),
            _ => Vec::new(),
        }
    }

    /// The real values of a numeric array whose dims are all 1 but one (a row or column
    /// vector, or a scalar); `None` for matrices and non-numeric values.
    pub fn as_vector(&self) -> Option<&[f64]> {
        match self {
            MatValue::Numeric { dims, real, .. }
                if dims.iter().filter(|&&d| d != 1).count() <= 1 =>
            {
                Some(real)
            }
            _ => None,
        }
    }

    /// The single real value of a numeric 1x1 array.
    pub fn as_scalar(&self) -> Option<f64> {
        match self {
            MatValue::Numeric { real, .. } if real.len() == 1 => Some(real[0]),
            _ => None,
        }
    }

    /// A metadata number in whatever class MATLAB stored it: a real 1x1 numeric or logical
    /// array of any class, a char array holding one finite number (`'25'`, `' 300 '`), or a
    /// 1x1 cell holding either. `None` for anything else.
    pub fn as_number(&self) -> Option<f64> {
        match self {
            MatValue::Numeric {
                real, imag: None, ..
            } if real.len() == 1 => Some(real[0]),
            MatValue::Char { text, .. } => {
                text.trim().parse::<f64>().ok().filter(|x| x.is_finite())
            }
            MatValue::Cell { cells, .. } if cells.len() == 1 => cells[0].as_number(),
            _ => None,
        }
    }

    /// A short text form for provenance notes: the text of a char array, the first numbers of
    /// a numeric array, else the class and shape (at most ~80 characters).
    pub fn as_text(&self) -> String {
        let text = match self {
            MatValue::Char { text, .. } => format!("{text:?}"),
            MatValue::Numeric { real, .. } if !real.is_empty() && real.len() <= 8 => {
                let v: Vec<String> = real.iter().map(|x| x.to_string()).collect();
                format!("[{}]", v.join(" "))
            }
            MatValue::Cell { cells, .. } if cells.len() == 1 => {
                format!("{{{}}}", cells[0].as_text())
            }
            other => other.describe(),
        };
        if text.chars().count() > 80 {
            let cut: String = text.chars().take(77).collect();
            format!("{cut}...")
        } else {
            text
        }
    }
}

/// One top-level variable.
#[derive(Debug, Clone, PartialEq)]
pub struct MatVar {
    pub name: String,
    pub value: MatValue,
}

/// A parsed MAT file.
#[derive(Debug, Clone, PartialEq)]
pub struct MatFile {
    /// The 116-byte descriptive text of the header ("MATLAB 5.0 MAT-file, Platform: ...").
    pub header_text: String,
    pub big_endian: bool,
    pub vars: Vec<MatVar>,
}

impl MatFile {
    pub fn get(&self, name: &str) -> Option<&MatValue> {
        self.vars.iter().find(|v| v.name == name).map(|v| &v.value)
    }

    /// "X097_DE_time (243938x1 double), X097RPM (1x1 double)", for messages (bounded: see
    /// [`list_bounded`]).
    pub fn summary(&self) -> String {
        if self.vars.is_empty() {
            return "no variables".into();
        }
        list_bounded(
            self.vars
                .iter()
                .map(|v| format!("{} ({})", shown(&v.name), v.value.describe())),
        )
    }
}

/// A parse error with the byte offset where it happened.
#[derive(Debug, Clone, PartialEq)]
pub struct MatError {
    /// Byte offset in the file (for errors inside a compressed element: the offset of that
    /// element, and `msg` says so).
    pub offset: usize,
    pub msg: String,
}

impl fmt::Display for MatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "MAT file at byte {}: {}",
            self.offset,
            bounded(&self.msg, 2000)
        )
    }
}

impl std::error::Error for MatError {}

type R<T> = Result<T, MatError>;

/// A name from the file as messages show it: control characters (terminal escapes) escaped,
/// at most 64 characters ("...(N characters)" beyond).
pub fn shown(name: &str) -> String {
    let escaped: String = name
        .chars()
        .flat_map(|c| {
            if c.is_control() {
                c.escape_default().collect::<Vec<_>>()
            } else {
                vec![c]
            }
        })
        .collect();
    let n = escaped.chars().count();
    if n <= 64 {
        return escaped;
    }
    let cut: String = escaped.chars().take(48).collect();
    format!("{cut}...({n} characters)")
}

/// `text` cut to `max` characters, saying how many were left out.
pub fn bounded(text: &str, max: usize) -> String {
    let n = text.chars().count();
    if n <= max {
        return text.to_string();
    }
    let cut: String = text.chars().take(max).collect();
    format!("{cut}... ({} more characters)", n - max)
}

/// Items joined with ", ", at most 20 of them ("... and N more").
fn list_bounded(items: impl Iterator<Item = String>) -> String {
    let mut out = Vec::new();
    let mut more = 0usize;
    for it in items {
        if out.len() < 20 {
            out.push(it);
        } else {
            more += 1;
        }
    }
    let mut s = out.join(", ");
    if more > 0 {
        s.push_str(&format!(", ... and {more} more"));
    }
    s
}

/// Refuse a second top-level variable of a name already seen: which one a reader picks would
/// be a guess (MATLAB never writes such a file).
fn check_unique<'a>(mut names: impl Iterator<Item = (&'a str, usize)>) -> R<()> {
    let mut seen = std::collections::HashMap::new();
    names.try_for_each(|(name, off)| match seen.insert(name, off) {
        Some(first) => err(
            off,
            format!(
                "two variables are named {} (the first at byte {first}); which one is meant \
                 cannot be told: re-save the file with distinct names",
                shown(name)
            ),
        ),
        None => Ok(()),
    })
}

fn err<T>(offset: usize, msg: impl Into<String>) -> R<T> {
    Err(MatError {
        offset,
        msg: msg.into(),
    })
}

/// Check the 128-byte header (`head` holds the file's first `min(128, file_len)` bytes):
/// returns the descriptive text and whether the file is big-endian; refuses MAT v4, v7.3
/// (HDF5) and damaged headers.
fn header(head: &[u8], file_len: usize) -> R<(String, bool)> {
    if file_len == 0 {
        return err(0, "the file is empty (0 bytes)");
    }
    if file_len < 128 || head.len() < 128 {
        if head.starts_with(b"MATLAB") {
            return err(
                file_len,
                format!("truncated: the 128-byte MAT header is cut short after {file_len} bytes"),
            );
        }
        return err(
            0,
            format!("not a MAT v5 file: {file_len} bytes, shorter than the 128-byte header"),
        );
    }
    let header_text = String::from_utf8_lossy(&head[..116])
        .trim_end_matches([' ', '\0'])
        .to_string();
    let big_endian = match &head[126..128] {
        b"IM" => false,
        b"MI" => true,
        _ => {
            return err(
                126,
                if head.starts_with(b"MATLAB") {
                    "bad endian indicator (expected \"IM\" or \"MI\"); the header is damaged"
                        .to_string()
                } else {
                    "not a MAT v5 file (no \"MATLAB 5.0\" header; MAT v4 files are not supported: re-save with save(..., '-v7'))".to_string()
                },
            )
        }
    };
    let c = Cursor {
        base: 0,
        big_endian,
    };
    let version = c.u16(head, 124)?;
    if version == 0x0200 || header_text.starts_with("MATLAB 7.3") {
        return err(
            124,
            "MAT v7.3 (HDF5) files are not supported; re-save with save(..., '-v7')",
        );
    }
    if version != 0x0100 {
        return err(
            124,
            format!("unknown MAT version 0x{version:04x} (expected 0x0100)"),
        );
    }
    Ok((header_text, big_endian))
}

/// Parse a whole MAT v5 file held in memory.
pub fn parse(bytes: &[u8]) -> R<MatFile> {
    let (header_text, big_endian) = header(&bytes[..bytes.len().min(128)], bytes.len())?;
    let mut vars = Vec::new();
    let mut offsets = Vec::new();
    let mut off = 128;
    while off < bytes.len() {
        if bytes.len() - off < 8 {
            check_trailing(&bytes[off..], off)?;
            break;
        }
        let (var, next) = top_element(bytes, off, 0, big_endian)?;
        offsets.extend(var.as_ref().map(|_| off));
        vars.extend(var);
        off = next;
    }
    check_unique(vars.iter().map(|v| v.name.as_str()).zip(offsets))?;
    Ok(MatFile {
        header_text,
        big_endian,
        vars,
    })
}

/// Bytes after the last element, too few for a tag: only zero padding is acceptable.
fn check_trailing(rest: &[u8], off: usize) -> R<()> {
    if rest.iter().all(|&b| b == 0) {
        return Ok(());
    }
    err(
        off,
        format!(
            "truncated: {} stray bytes where an 8-byte element tag should start",
            rest.len()
        ),
    )
}

/// Decode the top-level element whose tag starts at `buf[off]`. `base` is the file offset of
/// `buf[0]` (errors name file offsets). Returns the variable (`None` for elements that carry
/// none) and where the next element starts in `buf`.
fn top_element(
    buf: &[u8],
    off: usize,
    base: usize,
    big_endian: bool,
) -> R<(Option<MatVar>, usize)> {
    let c = Cursor { base, big_endian };
    let tag = c.tag(buf, off)?;
    if tag.small {
        // A small element at top level carries no variable; skip it.
        return Ok((None, off + 8));
    }
    let data_start = off + 8;
    let remaining = buf.len() - data_start;
    if tag.len > remaining {
        return err(
            base + off,
            format!(
                "truncated: element declares {} bytes but only {} remain (the file was cut short?)",
                tag.len, remaining
            ),
        );
    }
    let body = &buf[data_start..data_start + tag.len];
    match tag.ty {
        MI_MATRIX => {
            let cur = Cursor {
                base: base + data_start,
                big_endian,
            };
            let var = cur.matrix(body, 0, true)?;
            Ok((var, data_start + pad8(tag.len)))
        }
        MI_COMPRESSED => {
            let var = compressed_element(body, base + off, big_endian)?;
            // Compressed elements are not padded; tolerate writers that pad anyway.
            Ok((var, data_start + tag.len))
        }
        // Unknown top-level data: skip it.
        _ => Ok((None, data_start + pad8(tag.len))),
    }
}

/// Decode a `miCOMPRESSED` element's payload `body`; `at` is the element's file offset (errors
/// inside the decompressed data are reported relative to it).
fn compressed_element(body: &[u8], at: usize, big_endian: bool) -> R<Option<MatVar>> {
    let cap = MAX_DECOMPRESSED.min(body.len().saturating_mul(MAX_DEFLATE_RATIO).max(1024));
    let mut out = Vec::new();
    let mut dec = flate2::read::ZlibDecoder::new(body).take(cap as u64 + 1);
    if let Err(e) = dec.read_to_end(&mut out) {
        return err(
            at,
            format!(
                "compressed element ({} bytes) does not decompress: {e}",
                body.len()
            ),
        );
    }
    if out.len() > cap {
        return err(at, format!("compressed element expands beyond {cap} bytes; refusing (limit {MAX_DECOMPRESSED})"));
    }
    let t = compressed_matrix_tag(&out, at, big_endian)?;
    if t.len > out.len() - 8 {
        return err(
            at,
            format!("inside the compressed element: matrix declares {} bytes but {} were decompressed (truncated?)", t.len, out.len() - 8),
        );
    }
    // Offsets inside decompressed data are reported relative to the element.
    let inner = Cursor {
        base: at,
        big_endian,
    };
    inner.matrix(&out[8..8 + t.len], 0, true).or_else(|e| {
        err(
            at,
            format!(
                "inside the compressed element (at decompressed byte {}): {}",
                e.offset - at + 8,
                e.msg
            ),
        )
    })
}

/// The tag at the start of decompressed data: it must announce a matrix.
fn compressed_matrix_tag(out: &[u8], at: usize, big_endian: bool) -> R<Tag> {
    let inner = Cursor {
        base: at,
        big_endian,
    };
    let t = inner.tag(out, 0).map_err(|e| MatError {
        offset: at,
        msg: format!("inside the compressed element: {}", e.msg),
    })?;
    if t.ty != MI_MATRIX || t.small {
        return err(
            at,
            format!(
                "compressed element holds data type {} instead of a matrix",
                t.ty
            ),
        );
    }
    Ok(t)
}

/// How many bytes of an element (decompressed, for a compressed one) [`directory`] reads to
/// learn a variable's class, dimensions and name.
const HEAD_BYTES: usize = 64 * 1024;

/// One top-level variable as [`directory`] lists it: what it is and where it lies in the
/// file; its data not read.
#[derive(Debug, Clone, PartialEq)]
pub struct MatEntry {
    pub name: String,
    pub class: MatClass,
    pub dims: Vec<usize>,
    pub complex: bool,
    pub logical: bool,
    /// Stored in a zlib `miCOMPRESSED` element.
    pub compressed: bool,
    /// File offset of the element's tag.
    pub offset: u64,
    /// Bytes of the element from its tag to the next element.
    pub len: u64,
}

impl MatEntry {
    /// MATLAB's class name ("double", "logical", "struct", ...).
    pub fn class_name(&self) -> String {
        if self.logical {
            "logical".into()
        } else {
            self.class.name()
        }
    }

    /// "262144x1 double", as [`MatValue::describe`] says it.
    pub fn describe(&self) -> String {
        let dims: Vec<String> = self.dims.iter().map(|d| d.to_string()).collect();
        let complex = if self.complex { " complex" } else { "" };
        format!("{} {}{complex}", dims.join("x"), self.class_name())
    }

    /// Number of elements.
    pub fn count(&self) -> usize {
        self.dims.iter().product()
    }

    /// A real, non-logical numeric array.
    pub fn is_real_numeric(&self) -> bool {
        self.class.is_numeric() && !self.logical && !self.complex
    }

    /// All dimensions but one are 1 (a row or column vector, or a scalar).
    pub fn is_vector(&self) -> bool {
        self.dims.iter().filter(|&&d| d != 1).count() <= 1
    }
}

/// The variable directory of a MAT file: header facts and one [`MatEntry`] per variable.
#[derive(Debug, Clone, PartialEq)]
pub struct MatDirectory {
    pub header_text: String,
    pub big_endian: bool,
    pub entries: Vec<MatEntry>,
}

impl MatDirectory {
    pub fn get(&self, name: &str) -> Option<&MatEntry> {
        self.entries.iter().find(|e| e.name == name)
    }

    /// "VarName5 (262144x1 double), fs (1x1 double)", for messages.
    pub fn summary(&self) -> String {
        if self.entries.is_empty() {
            return "no variables".into();
        }
        list_bounded(
            self.entries
                .iter()
                .map(|e| format!("{} ({})", shown(&e.name), e.describe())),
        )
    }
}

/// List a MAT file's variables (name, class, dimensions, where they lie) reading only the
/// header and the first bytes of each element: a compressed element is decompressed only as
/// far as its head. Lengths are checked against the file size, so a truncated file is refused
/// here, before any data is decoded.
pub fn directory<F: Read + Seek>(file: &mut F) -> R<MatDirectory> {
    let io = |e: std::io::Error| MatError {
        offset: 0,
        msg: format!("cannot read: {e}"),
    };
    let file_len = file.seek(SeekFrom::End(0)).map_err(io)? as usize;
    file.seek(SeekFrom::Start(0)).map_err(io)?;
    let head = read_up_to(file, 128).map_err(io)?;
    let (header_text, big_endian) = header(&head, file_len)?;
    let c = Cursor {
        base: 0,
        big_endian,
    };
    let mut entries = Vec::new();
    let mut off = 128;
    while off < file_len {
        file.seek(SeekFrom::Start(off as u64)).map_err(io)?;
        let rest = read_up_to(file, 8).map_err(io)?;
        if file_len - off < 8 {
            check_trailing(&rest, off)?;
            break;
        }
        let tag = c.tag(&rest, 0).map_err(|e| MatError { offset: off, ..e })?;
        if tag.small {
            off += 8;
            continue;
        }
        let data_start = off + 8;
        if tag.len > file_len - data_start {
            return err(
                off,
                format!(
                    "truncated: element declares {} bytes but only {} remain (the file was cut short?)",
                    tag.len,
                    file_len - data_start
                ),
            );
        }
        let next = match tag.ty {
            MI_COMPRESSED => data_start + tag.len,
            _ => data_start + pad8(tag.len),
        };
        let head = match tag.ty {
            MI_MATRIX => {
                let body = read_up_to(file, tag.len.min(HEAD_BYTES)).map_err(io)?;
                let cur = Cursor {
                    base: data_start,
                    big_endian,
                };
                (!body.is_empty())
                    .then(|| cur.matrix_head(&body))
                    .transpose()?
            }
            MI_COMPRESSED => compressed_head(file, tag.len, off, big_endian)?,
            _ => None,
        };
        if let Some(h) = head {
            entries.push(MatEntry {
                name: h.name,
                class: h.class,
                dims: h.dims,
                complex: h.complex,
                logical: h.logical,
                compressed: tag.ty == MI_COMPRESSED,
                offset: off as u64,
                len: (next.min(file_len) - off) as u64,
            });
        }
        off = next;
    }
    check_unique(entries.iter().map(|e| (e.name.as_str(), e.offset as usize)))?;
    Ok(MatDirectory {
        header_text,
        big_endian,
        entries,
    })
}

/// The head of a compressed element of `len` bytes whose payload starts at the reader's
/// position: only the first [`HEAD_BYTES`] are decompressed. `None` for an empty matrix.
fn compressed_head<F: Read>(
    file: &mut F,
    len: usize,
    at: usize,
    big_endian: bool,
) -> R<Option<MatrixHead>> {
    let mut out = Vec::new();
    let mut dec = flate2::read::ZlibDecoder::new(file.take(len as u64)).take(HEAD_BYTES as u64);
    if let Err(e) = dec.read_to_end(&mut out) {
        return err(
            at,
            format!("compressed element ({len} bytes) does not decompress: {e}"),
        );
    }
    let t = compressed_matrix_tag(&out, at, big_endian)?;
    if t.len == 0 {
        return Ok(None);
    }
    let body = &out[8..out.len().min(8 + t.len)];
    let inner = Cursor {
        base: at,
        big_endian,
    };
    inner.matrix_head(body).map(Some).map_err(|e| MatError {
        offset: at,
        msg: format!(
            "inside the compressed element (at decompressed byte {}): {}",
            e.offset - at + 8,
            e.msg
        ),
    })
}

/// Read up to `n` bytes (fewer at the end of the file).
fn read_up_to<F: Read>(file: &mut F, n: usize) -> std::io::Result<Vec<u8>> {
    let mut buf = Vec::with_capacity(n);
    file.take(n as u64).read_to_end(&mut buf)?;
    Ok(buf)
}

/// Decode the variables of `dir` named in `names` (others are not read); names missing from
/// the directory are left out. Each element is read and decoded on its own, with the checks of
/// [`parse`].
pub fn decode_selected<F: Read + Seek>(
    file: &mut F,
    dir: &MatDirectory,
    names: &[&str],
) -> R<MatFile> {
    let mut vars = Vec::new();
    for e in dir
        .entries
        .iter()
        .filter(|e| names.contains(&e.name.as_str()))
    {
        let io = |err: std::io::Error| MatError {
            offset: e.offset as usize,
            msg: format!("cannot read variable {:?}: {err}", e.name),
        };
        file.seek(SeekFrom::Start(e.offset)).map_err(io)?;
        let buf = read_up_to(file, e.len as usize).map_err(io)?;
        if let (Some(v), _) = top_element(&buf, 0, e.offset as usize, dir.big_endian)? {
            vars.push(v);
        }
    }
    Ok(MatFile {
        header_text: dir.header_text.clone(),
        big_endian: dir.big_endian,
        vars,
    })
}

/// Bytes of an entry's data once decompressed (its stored length when it is not compressed),
/// learnt by inflating it into nothing: no memory is held, whatever it expands to. Capped at
/// [`MAX_DECOMPRESSED`] + 1 (decoding refuses more); a stream that does not inflate counts
/// what came out before the damage (decoding reports the damage).
pub fn inflated_len<F: Read + Seek>(file: &mut F, e: &MatEntry) -> std::io::Result<u64> {
    if !e.compressed {
        return Ok(e.len);
    }
    file.seek(SeekFrom::Start(e.offset + 8))?;
    let mut dec = flate2::read::ZlibDecoder::new(file.take(e.len.saturating_sub(8)))
        .take(MAX_DECOMPRESSED as u64 + 1);
    let mut n = 0u64;
    let mut buf = vec![0u8; 64 * 1024];
    loop {
        match dec.read(&mut buf) {
            Ok(0) | Err(_) => return Ok(n),
            Ok(k) => n += k as u64,
        }
    }
}

/// Bytes of one value of a numeric class as stored (8 for a class MATLAB stores otherwise).
pub fn class_bytes(class: MatClass) -> u64 {
    use MatClass::*;
    match class {
        Int8 | UInt8 => 1,
        Int16 | UInt16 => 2,
        Int32 | UInt32 | Single => 4,
        _ => 8,
    }
}

/// [`directory`] of a file on disk; errors name the file.
pub fn read_directory(path: &std::path::Path) -> anyhow::Result<MatDirectory> {
    let mut f = std::fs::File::open(path)
        .map_err(|e| anyhow::anyhow!("{}: cannot read: {e}", path.display()))?;
    directory(&mut std::io::BufReader::new(&mut f))
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// [`decode_selected`] on a file on disk; errors name the file.
pub fn read_selected(
    path: &std::path::Path,
    dir: &MatDirectory,
    names: &[&str],
) -> anyhow::Result<MatFile> {
    let mut f = std::fs::File::open(path)
        .map_err(|e| anyhow::anyhow!("{}: cannot read: {e}", path.display()))?;
    decode_selected(&mut f, dir, names).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

fn pad8(n: usize) -> usize {
    n.div_ceil(8) * 8
}

/// Array flags, dimensions and name of a matrix, and where its data starts in the body.
struct MatrixHead {
    class: MatClass,
    complex: bool,
    logical: bool,
    dims: Vec<usize>,
    /// Number of elements (product of `dims`, overflow-checked).
    count: usize,
    name: String,
    data_at: usize,
}

struct Tag {
    ty: u32,
    /// Payload length in bytes.
    len: usize,
    /// Small data element: payload in the 4 bytes after the 4-byte tag.
    small: bool,
}

/// Reads numbers in the file's byte order; `base` converts slice offsets into file offsets.
#[derive(Clone, Copy)]
struct Cursor {
    base: usize,
    big_endian: bool,
}

impl Cursor {
    fn bytes<'a>(&self, buf: &'a [u8], at: usize, n: usize) -> R<&'a [u8]> {
        match at.checked_add(n) {
            Some(end) if end <= buf.len() => Ok(&buf[at..end]),
            _ => err(
                self.base + at,
                format!(
                    "truncated: need {n} bytes but only {} remain",
                    buf.len().saturating_sub(at)
                ),
            ),
        }
    }

    fn u16(&self, buf: &[u8], at: usize) -> R<u16> {
        let b: [u8; 2] = self.bytes(buf, at, 2)?.try_into().unwrap();
        Ok(if self.big_endian {
            u16::from_be_bytes(b)
        } else {
            u16::from_le_bytes(b)
        })
    }

    fn u32(&self, buf: &[u8], at: usize) -> R<u32> {
        let b: [u8; 4] = self.bytes(buf, at, 4)?.try_into().unwrap();
        Ok(if self.big_endian {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        })
    }

    fn tag(&self, buf: &[u8], at: usize) -> R<Tag> {
        let first = self.u32(buf, at)?;
        let (hi, lo) = (first >> 16, first & 0xffff);
        if hi != 0 {
            // Small data element: upper half = byte count (<= 4), lower half = type.
            if hi > 4 {
                return err(
                    self.base + at,
                    format!("small data element claims {hi} bytes (at most 4 fit)"),
                );
            }
            self.bytes(buf, at, 8)?;
            return Ok(Tag {
                ty: lo,
                len: hi as usize,
                small: true,
            });
        }
        let len = self.u32(buf, at + 4)? as usize;
        Ok(Tag {
            ty: lo,
            len,
            small: false,
        })
    }

    /// Read one data element starting at `at`; returns (type, payload, offset of the next
    /// element). The payload is checked to lie inside `buf`.
    fn element<'a>(&self, buf: &'a [u8], at: usize) -> R<(u32, &'a [u8], usize)> {
        let tag = self.tag(buf, at)?;
        if tag.small {
            let data = self.bytes(buf, at + 4, tag.len)?;
            return Ok((tag.ty, data, at + 8));
        }
        let start = at + 8;
        let remaining = buf.len().saturating_sub(start);
        if tag.len > remaining {
            return err(
                self.base + at,
                format!("truncated: data element of type {} declares {} bytes but only {remaining} remain", tag.ty, tag.len),
            );
        }
        let next = (start + pad8(tag.len)).min(buf.len());
        Ok((tag.ty, &buf[start..start + tag.len], next))
    }

    /// The head of a miMATRIX body: array flags, dimensions and name, checked; the rest of
    /// `body` (the data) is not looked at, so a prefix of a large element is enough.
    fn matrix_head(&self, body: &[u8]) -> R<MatrixHead> {
        // Array flags.
        let (ty, flags, mut at) = self.element(body, 0)?;
        if ty != MI_UINT32 || flags.len() < 8 {
            return err(
                self.base,
                format!(
                    "matrix: expected array flags (uint32 x2), got type {ty} with {} bytes",
                    flags.len()
                ),
            );
        }
        let f0 = self.u32(flags, 0)?;
        let class = MatClass::from_u8((f0 & 0xff) as u8);
        let complex = f0 & 0x0800 != 0;
        let logical = f0 & 0x0200 != 0;
        // Dimensions.
        let (ty, dim_bytes, next) = self.element(body, at)?;
        if ty != MI_INT32 || dim_bytes.len() < 8 || dim_bytes.len() % 4 != 0 {
            return err(
                self.base + at,
                format!(
                    "matrix: expected dimensions (int32 x n >= 2), got type {ty} with {} bytes",
                    dim_bytes.len()
                ),
            );
        }
        let mut dims = Vec::with_capacity(dim_bytes.len() / 4);
        let mut count: usize = 1;
        for k in 0..dim_bytes.len() / 4 {
            let d = self.u32(dim_bytes, 4 * k)? as i32;
            if d < 0 {
                return err(self.base + at, format!("matrix: negative dimension {d}"));
            }
            dims.push(d as usize);
            count = match count.checked_mul(d as usize) {
                Some(c) => c,
                None => return err(self.base + at, "matrix: dimensions overflow"),
            };
        }
        at = next;
        // Name.
        let (ty, name_bytes, next) = self.element(body, at)?;
        if ty != MI_INT8 && ty != MI_UINT8 && ty != MI_UTF8 {
            return err(
                self.base + at,
                format!("matrix: expected the array name (int8), got type {ty}"),
            );
        }
        let name = String::from_utf8_lossy(name_bytes)
            .trim_end_matches('\0')
            .to_string();
        at = next;
        Ok(MatrixHead {
            class,
            complex,
            logical,
            dims,
            count,
            name,
            data_at: at,
        })
    }

    /// Parse the body of a miMATRIX element. `named` is false for struct fields and cell
    /// elements (their name is empty). Returns `None` for an empty placeholder matrix (a
    /// miMATRIX of 0 bytes, used for empty struct fields).
    fn matrix(&self, body: &[u8], depth: usize, named: bool) -> R<Option<MatVar>> {
        if depth > MAX_DEPTH {
            return err(
                self.base,
                format!("structs/cells nested deeper than {MAX_DEPTH} levels"),
            );
        }
        if body.is_empty() {
            return Ok(if named {
                None
            } else {
                Some(MatVar {
                    name: String::new(),
                    value: MatValue::Numeric {
                        class: MatClass::Double,
                        dims: vec![0, 0],
                        real: vec![],
                        imag: None,
                        logical: false,
                    },
                })
            });
        }
        let MatrixHead {
            class,
            complex,
            logical,
            dims,
            count,
            name,
            data_at,
        } = self.matrix_head(body)?;
        let mut at = data_at;
        let value = match class {
            c if c.is_numeric() => {
                let (ty, data, next) = self.element(body, at)?;
                let real = self.numbers(data, ty, self.base + at)?;
                if real.len() != count {
                    return err(
                        self.base + at,
                        format!("variable {name:?}: dimensions {dims:?} say {count} values but the data holds {}", real.len()),
                    );
                }
                let imag = if complex {
                    let (ty, data, _) = self.element(body, next)?;
                    let im = self.numbers(data, ty, self.base + next)?;
                    if im.len() != count {
                        return err(self.base + next, format!("variable {name:?}: imaginary part holds {} values, expected {count}", im.len()));
                    }
                    Some(im)
                } else {
                    None
                };
                MatValue::Numeric {
                    class: c,
                    dims,
                    real,
                    imag,
                    logical,
                }
            }
            MatClass::Char => {
                let (ty, data, _) = self.element(body, at)?;
                let units: Vec<u32> = match ty {
                    MI_UTF8 => String::from_utf8_lossy(data)
                        .chars()
                        .map(|c| c as u32)
                        .collect(),
                    MI_UTF16 | MI_UINT16 | MI_INT16 => {
                        let v = self.numbers(data, MI_UINT16, self.base + at)?;
                        let u: Vec<u16> = v.iter().map(|&x| x as u16).collect();
                        char::decode_utf16(u)
                            .map(|r| r.map_or(0xFFFD, |c| c as u32))
                            .collect()
                    }
                    _ => self
                        .numbers(data, ty, self.base + at)?
                        .iter()
                        .map(|&x| x as u32)
                        .collect(),
                };
                let rows = dims.first().copied().unwrap_or(0);
                let text = if rows <= 1 || units.len() != count {
                    units
                        .iter()
                        .map(|&u| char::from_u32(u).unwrap_or('\u{FFFD}'))
                        .collect()
                } else {
                    let cols = count / rows;
                    (0..rows)
                        .map(|r| {
                            (0..cols)
                                .map(|c| char::from_u32(units[c * rows + r]).unwrap_or('\u{FFFD}'))
                                .collect::<String>()
                        })
                        .collect::<Vec<_>>()
                        .join("\n")
                };
                MatValue::Char { dims, text }
            }
            MatClass::Struct | MatClass::Object => {
                if class == MatClass::Object {
                    // Class name element precedes the field names.
                    let (_, _, next) = self.element(body, at)?;
                    at = next;
                }
                let (ty, len_bytes, next) = self.element(body, at)?;
                if ty != MI_INT32 || len_bytes.len() != 4 {
                    return err(
                        self.base + at,
                        "struct: expected the field-name length (int32)",
                    );
                }
                let name_len = self.u32(len_bytes, 0)? as usize;
                at = next;
                let (ty, names, next) = self.element(body, at)?;
                if ty != MI_INT8 && ty != MI_UINT8 {
                    return err(
                        self.base + at,
                        format!("struct: expected field names (int8), got type {ty}"),
                    );
                }
                if name_len == 0 && !names.is_empty() {
                    return err(
                        self.base + at,
                        "struct: field-name length is 0 but names are present",
                    );
                }
                let n_fields = names.len().checked_div(name_len).unwrap_or(0);
                let field_names: Vec<String> = (0..n_fields)
                    .map(|k| {
                        String::from_utf8_lossy(&names[k * name_len..(k + 1) * name_len])
                            .trim_end_matches('\0')
                            .to_string()
                    })
                    .collect();
                at = next;
                // Each element x field needs at least an 8-byte tag: bound before allocating.
                let needed = count.checked_mul(n_fields).and_then(|n| n.checked_mul(8));
                if n_fields > 0 && needed.is_none_or(|n| n > body.len() - at.min(body.len())) {
                    return err(
                        self.base + at,
                        format!("struct {name:?}: {count} elements x {n_fields} fields cannot fit in the {} bytes left", body.len() - at.min(body.len())),
                    );
                }
                let mut fields: Vec<(String, Vec<MatValue>)> =
                    field_names.into_iter().map(|n| (n, Vec::new())).collect();
                // A struct without fields holds nothing per element, however many there are.
                for _ in 0..if n_fields == 0 { 0 } else { count } {
                    for field in fields.iter_mut() {
                        let v = self.sub_matrix(body, &mut at, depth)?;
                        field.1.push(v);
                    }
                }
                if class == MatClass::Object {
                    MatValue::Unsupported { class, dims }
                } else {
                    MatValue::Struct { dims, fields }
                }
            }
            MatClass::Cell => {
                let needed = count.checked_mul(8);
                if needed.is_none_or(|n| n > body.len() - at.min(body.len())) {
                    return err(
                        self.base + at,
                        format!("cell {name:?}: {count} elements cannot fit in the bytes left"),
                    );
                }
                // Grown as elements parse: a header's count reserves nothing.
                let mut cells = Vec::new();
                for _ in 0..count {
                    cells.push(self.sub_matrix(body, &mut at, depth)?);
                }
                MatValue::Cell { dims, cells }
            }
            other => MatValue::Unsupported { class: other, dims },
        };
        Ok(Some(MatVar { name, value }))
    }

    /// A nested miMATRIX (struct field, cell element) at `*at` inside `body`.
    fn sub_matrix(&self, body: &[u8], at: &mut usize, depth: usize) -> R<MatValue> {
        let (ty, data, next) = self.element(body, *at)?;
        if ty != MI_MATRIX {
            return err(
                self.base + *at,
                format!("expected a nested matrix (type 14), got type {ty}"),
            );
        }
        let inner = Cursor {
            base: self.base + *at + 8,
            big_endian: self.big_endian,
        };
        let v = inner.matrix(data, depth + 1, false)?;
        *at = next;
        Ok(v.expect("unnamed matrices always yield a value").value)
    }

    /// Decode a numeric data element of type `ty` to f64.
    fn numbers(&self, data: &[u8], ty: u32, offset: usize) -> R<Vec<f64>> {
        let size = match ty {
            MI_INT8 | MI_UINT8 | MI_UTF8 => 1,
            MI_INT16 | MI_UINT16 | MI_UTF16 => 2,
            MI_INT32 | MI_UINT32 | MI_SINGLE | MI_UTF32 => 4,
            MI_DOUBLE | MI_INT64 | MI_UINT64 => 8,
            _ => return err(offset, format!("unsupported numeric data type {ty}")),
        };
        if data.len() % size != 0 {
            return err(
                offset,
                format!(
                    "data of type {ty}: {} bytes is not a whole number of {size}-byte values",
                    data.len()
                ),
            );
        }
        let be = self.big_endian;
        macro_rules! conv {
            ($t:ty, $n:expr) => {
                data.chunks_exact($n)
                    .map(|c| {
                        let b: [u8; $n] = c.try_into().unwrap();
                        (if be {
                            <$t>::from_be_bytes(b)
                        } else {
                            <$t>::from_le_bytes(b)
                        }) as f64
                    })
                    .collect()
            };
        }
        Ok(match ty {
            MI_INT8 => data.iter().map(|&b| b as i8 as f64).collect(),
            MI_UINT8 | MI_UTF8 => data.iter().map(|&b| b as f64).collect(),
            MI_INT16 => conv!(i16, 2),
            MI_UINT16 | MI_UTF16 => conv!(u16, 2),
            MI_INT32 => conv!(i32, 4),
            MI_UINT32 | MI_UTF32 => conv!(u32, 4),
            MI_SINGLE => conv!(f32, 4),
            MI_DOUBLE => conv!(f64, 8),
            MI_INT64 => conv!(i64, 8),
            MI_UINT64 => conv!(u64, 8),
            _ => unreachable!(),
        })
    }
}

/// Read and parse a MAT file; errors name the file.
pub fn read(path: &std::path::Path) -> anyhow::Result<MatFile> {
    let bytes =
        std::fs::read(path).map_err(|e| anyhow::anyhow!("{}: cannot read: {e}", path.display()))?;
    parse(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// Builds MAT v5 files byte by byte for the unit tests. Little or big endian, optionally
/// wrapping each variable in a zlib `miCOMPRESSED` element. (The integration tests build their
/// files with separate code, so a shared misunderstanding cannot hide.)
#[cfg(test)]
mod writer {
    use std::io::Write;

    /// A value to write.
    #[derive(Debug, Clone)]
    pub enum W {
        /// Column-major doubles with dims.
        Double(Vec<usize>, Vec<f64>),
        /// Column-major singles with dims.
        Single(Vec<usize>, Vec<f32>),
        Int16(Vec<usize>, Vec<i16>),
        Int32(Vec<usize>, Vec<i32>),
        UInt8(Vec<usize>, Vec<u8>),
        /// A 1xN char array (UTF-16).
        Char(String),
        /// A 1x1 struct with named fields.
        Struct(Vec<(String, W)>),
    }

    /// A MAT file under construction.
    pub struct MatBuilder {
        pub big_endian: bool,
        pub out: Vec<u8>,
    }

    impl MatBuilder {
        pub fn new(big_endian: bool) -> Self {
            let mut out = Vec::new();
            let mut text =
                b"MATLAB 5.0 MAT-file, Platform: rigmon test, Created by rigmon".to_vec();
            text.resize(116, b' ');
            out.extend_from_slice(&text);
            out.extend_from_slice(&[0u8; 8]);
            if big_endian {
                out.extend_from_slice(&0x0100u16.to_be_bytes());
                out.extend_from_slice(b"MI");
            } else {
                out.extend_from_slice(&0x0100u16.to_le_bytes());
                out.extend_from_slice(b"IM");
            }
            MatBuilder { big_endian, out }
        }

        fn u32(&self, v: u32) -> [u8; 4] {
            if self.big_endian {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        }

        /// Append a top-level variable, optionally compressed.
        pub fn var(&mut self, name: &str, value: &W, compressed: bool) -> &mut Self {
            let m = self.matrix(name, value);
            if compressed {
                let mut enc =
                    flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
                enc.write_all(&m).unwrap();
                let z = enc.finish().unwrap();
                let (a, b) = (self.u32(15), self.u32(z.len() as u32));
                self.out.extend_from_slice(&a);
                self.out.extend_from_slice(&b);
                self.out.extend_from_slice(&z);
            } else {
                self.out.extend_from_slice(&m);
            }
            self
        }

        fn element(&self, ty: u32, data: &[u8]) -> Vec<u8> {
            let mut e = Vec::new();
            e.extend_from_slice(&self.u32(ty));
            e.extend_from_slice(&self.u32(data.len() as u32));
            e.extend_from_slice(data);
            while e.len() % 8 != 0 {
                e.push(0);
            }
            e
        }

        /// A full miMATRIX element (tag included).
        pub fn matrix(&self, name: &str, value: &W) -> Vec<u8> {
            let be = self.big_endian;
            macro_rules! bytes {
                ($v:expr) => {
                    $v.iter()
                        .flat_map(|x| {
                            if be {
                                x.to_be_bytes().to_vec()
                            } else {
                                x.to_le_bytes().to_vec()
                            }
                        })
                        .collect::<Vec<u8>>()
                };
            }
            let (class, dims, payload): (u32, Vec<usize>, Vec<u8>) = match value {
                W::Double(d, v) => (6, d.clone(), self.element(9, &bytes!(v))),
                W::Single(d, v) => (7, d.clone(), self.element(7, &bytes!(v))),
                W::Int16(d, v) => (10, d.clone(), self.element(3, &bytes!(v))),
                W::Int32(d, v) => (12, d.clone(), self.element(5, &bytes!(v))),
                W::UInt8(d, v) => (9, d.clone(), self.element(2, v)),
                W::Char(s) => {
                    let u: Vec<u16> = s.encode_utf16().collect();
                    (4, vec![1, u.len()], self.element(4, &bytes!(u)))
                }
                W::Struct(fields) => {
                    let name_len = fields
                        .iter()
                        .map(|(n, _)| n.len() + 1)
                        .max()
                        .unwrap_or(1)
                        .max(8);
                    let mut p = self.element(5, &self.u32(name_len as u32));
                    let mut names = Vec::new();
                    for (n, _) in fields {
                        let mut b = n.as_bytes().to_vec();
                        b.resize(name_len, 0);
                        names.extend_from_slice(&b);
                    }
                    p.extend_from_slice(&self.element(1, &names));
                    for (_, v) in fields {
                        p.extend_from_slice(&self.matrix("", v));
                    }
                    (2, vec![1, 1], p)
                }
            };
            let mut body = Vec::new();
            let mut flags = Vec::new();
            flags.extend_from_slice(&self.u32(class));
            flags.extend_from_slice(&self.u32(0));
            body.extend_from_slice(&self.element(6, &flags));
            let dims_b: Vec<u8> = dims.iter().flat_map(|&d| self.u32(d as u32)).collect();
            body.extend_from_slice(&self.element(5, &dims_b));
            body.extend_from_slice(&self.element(1, name.as_bytes()));
            body.extend_from_slice(&payload);
            self.element(14, &body)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::writer::{MatBuilder, W};
    use super::*;

    fn sample_file(be: bool, compressed: bool) -> Vec<u8> {
        let mut b = MatBuilder::new(be);
        b.var(
            "x",
            &W::Double(vec![3, 1], vec![1.5, -2.0, 3.25]),
            compressed,
        )
        .var("s", &W::Single(vec![1, 2], vec![0.5, 7.0]), compressed)
        .var("i", &W::Int16(vec![2, 2], vec![1, -2, 3, -4]), compressed)
        .var("txt", &W::Char("héllo".into()), compressed)
        .var(
            "bearing",
            &W::Struct(vec![
                ("gs".into(), W::Double(vec![2, 1], vec![0.1, 0.2])),
                ("sr".into(), W::Int32(vec![1, 1], vec![48828])),
                (
                    "inner".into(),
                    W::Struct(vec![("deep".into(), W::UInt8(vec![1, 1], vec![9]))]),
                ),
            ]),
            compressed,
        );
        b.out
    }

    fn check(f: &MatFile) {
        assert_eq!(f.get("x").unwrap().as_vector().unwrap(), &[1.5, -2.0, 3.25]);
        assert_eq!(f.get("s").unwrap().as_vector().unwrap(), &[0.5, 7.0]);
        let i = f.get("i").unwrap();
        assert_eq!(i.dims(), &[2, 2]);
        assert!(i.as_vector().is_none(), "a 2x2 matrix is not a vector");
        assert!(matches!(f.get("txt").unwrap(), MatValue::Char { text, .. } if text == "héllo"));
        let b = f.get("bearing").unwrap();
        assert_eq!(b.field_names(), ["gs", "sr", "inner"]);
        assert_eq!(b.field("gs").unwrap().as_vector().unwrap(), &[0.1, 0.2]);
        assert_eq!(b.field("sr").unwrap().as_scalar(), Some(48828.0));
        assert_eq!(
            b.field("inner").unwrap().field("deep").unwrap().as_scalar(),
            Some(9.0)
        );
    }

    #[test]
    fn reads_all_kinds_both_endians_plain_and_compressed() {
        for be in [false, true] {
            for z in [false, true] {
                let f = parse(&sample_file(be, z)).unwrap_or_else(|e| panic!("be={be} z={z}: {e}"));
                assert_eq!(f.big_endian, be);
                check(&f);
            }
        }
    }

    #[test]
    fn every_truncation_is_an_error_not_a_panic() {
        for z in [false, true] {
            let bytes = sample_file(false, z);
            for cut in 0..bytes.len() {
                // Cutting inside trailing padding of the last element may still parse; all
                // other cuts must fail cleanly.
                let _ = parse(&bytes[..cut]);
            }
            assert!(parse(&bytes[..bytes.len() - 20]).is_err());
        }
    }

    #[test]
    fn hostile_lengths_are_refused() {
        // Flip every byte of the file to 0xff one at a time: never panic.
        let bytes = sample_file(false, false);
        for k in 128..bytes.len() {
            let mut b = bytes.clone();
            b[k] = 0xff;
            let _ = parse(&b);
            b[k] = 0x7f;
            let _ = parse(&b);
        }
        // A struct claiming 2^31 x 2^31 elements.
        let mut b = MatBuilder::new(false);
        b.var(
            "s",
            &W::Struct(vec![("a".into(), W::Double(vec![1, 1], vec![1.0]))]),
            false,
        );
        let mut bytes = b.out;
        // dims element follows the flags element: tag(8)+flags(8+8) -> dims data at 128+8+16+8
        let dims_at = 128 + 8 + 16 + 8;
        bytes[dims_at..dims_at + 8]
            .copy_from_slice(&[0xff, 0xff, 0xff, 0x7f, 0xff, 0xff, 0xff, 0x7f]);
        let e = parse(&bytes).unwrap_err();
        assert!(
            e.msg.contains("cannot fit") || e.msg.contains("overflow"),
            "{e}"
        );
    }

    #[test]
    fn random_mutations_never_panic() {
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for z in [false, true] {
            for be in [false, true] {
                let base = sample_file(be, z);
                for _ in 0..1500 {
                    let mut b = base.clone();
                    for _ in 0..1 + next() % 4 {
                        let k = 120 + (next() as usize) % (b.len() - 120);
                        b[k] = next() as u8;
                    }
                    let cut = if next() % 4 == 0 {
                        (next() as usize) % b.len()
                    } else {
                        b.len()
                    };
                    let _ = parse(&b[..cut]);
                }
            }
        }
    }

    /// Found by `fuzz_mat_importer`: a struct with no fields claiming ~2^62 elements passed
    /// the size bound (0 bytes needed) and then looped over every element.
    #[test]
    fn fieldless_struct_with_huge_dims_parses_without_looping() {
        let mut b = MatBuilder::new(false);
        b.var("bearing", &W::Struct(vec![]), false);
        let mut bytes = b.out;
        let dims_at = 128 + 8 + 16 + 8;
        bytes[dims_at..dims_at + 8]
            .copy_from_slice(&[0xff, 0xff, 0xff, 0x7f, 0xff, 0xff, 0xff, 0x7f]);
        let f = parse(&bytes).unwrap();
        let v = f.get("bearing").unwrap();
        assert_eq!(v.dims(), &[0x7fff_ffff, 0x7fff_ffff]);
        assert!(v.field_names().is_empty());
    }

    #[test]
    fn metadata_numbers_in_any_class() {
        let mut b = MatBuilder::new(false);
        b.var("d", &W::Double(vec![1, 1], vec![270.0]), false)
            .var("i", &W::Int16(vec![1, 1], vec![-3]), false)
            .var("u", &W::UInt8(vec![1, 1], vec![25]), false)
            .var("c", &W::Char("100".into()), false)
            .var("s", &W::Char(" 2.5e2 ".into()), false)
            .var("t", &W::Char("270 lbs".into()), false)
            .var("n", &W::Char("NaN".into()), false)
            .var("v", &W::Double(vec![1, 2], vec![1.0, 2.0]), false);
        let f = parse(&b.out).unwrap();
        let num = |k: &str| f.get(k).unwrap().as_number();
        assert_eq!(num("d"), Some(270.0));
        assert_eq!(num("i"), Some(-3.0));
        assert_eq!(num("u"), Some(25.0));
        assert_eq!(num("c"), Some(100.0));
        assert_eq!(num("s"), Some(250.0));
        assert_eq!(num("t"), None);
        assert_eq!(num("n"), None, "NaN text is not a number");
        assert_eq!(num("v"), None, "a vector is not one number");
        assert_eq!(f.get("t").unwrap().as_text(), "\"270 lbs\"");
        assert_eq!(f.get("v").unwrap().as_text(), "[1 2]");
    }

    fn dir_of(bytes: &[u8]) -> R<MatDirectory> {
        directory(&mut std::io::Cursor::new(bytes))
    }

    #[test]
    fn the_directory_lists_what_parse_decodes_and_selected_decoding_matches() {
        for be in [false, true] {
            for z in [false, true] {
                let bytes = sample_file(be, z);
                let full = parse(&bytes).unwrap();
                let dir = dir_of(&bytes).unwrap();
                assert_eq!(dir.big_endian, be);
                assert_eq!(dir.header_text, full.header_text);
                assert_eq!(dir.summary(), full.summary(), "be={be} z={z}");
                assert!(dir.entries.iter().all(|e| e.compressed == z));
                assert_eq!(dir.get("i").unwrap().dims, [2, 2]);
                assert!(dir.get("x").unwrap().is_vector() && !dir.get("i").unwrap().is_vector());
                let sel =
                    decode_selected(&mut std::io::Cursor::new(&bytes), &dir, &["s", "bearing"])
                        .unwrap();
                let want: Vec<_> = full
                    .vars
                    .iter()
                    .filter(|v| v.name == "s" || v.name == "bearing")
                    .cloned()
                    .collect();
                assert_eq!(sel.vars, want);
            }
        }
    }

    /// The directory decompresses only an element's head: damage at the end of a compressed
    /// signal does not stop it listing the variable; decoding that variable then fails.
    #[test]
    fn the_directory_does_not_decode_data() {
        let mut x: u64 = 7;
        let noise: Vec<f64> = (0..20_000)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                (x % 1000) as f64
            })
            .collect();
        let mut b = MatBuilder::new(false);
        b.var("signal", &W::Double(vec![20_000, 1], noise), true)
            .var("fs", &W::Double(vec![1, 1], vec![51200.0]), true);
        let mut bytes = b.out;
        let dir = dir_of(&bytes).unwrap();
        let sig = dir.get("signal").unwrap().clone();
        // Damage the deflate stream well past the head.
        let at = (sig.offset + sig.len) as usize - 40;
        for k in at..at + 8 {
            bytes[k] ^= 0x5a;
        }
        let dir = dir_of(&bytes).unwrap();
        assert_eq!(dir.summary(), "signal (20000x1 double), fs (1x1 double)");
        let mut f = std::io::Cursor::new(&bytes);
        let fs = decode_selected(&mut f, &dir, &["fs"]).unwrap();
        assert_eq!(fs.get("fs").unwrap().as_scalar(), Some(51200.0));
        let e = decode_selected(&mut f, &dir, &["signal"]).unwrap_err();
        assert!(e.offset == sig.offset as usize, "{e}");
        assert!(parse(&bytes).is_err());
    }

    #[test]
    fn the_directory_refuses_truncation_and_never_panics() {
        for z in [false, true] {
            let bytes = sample_file(false, z);
            for cut in 0..bytes.len() {
                let _ = dir_of(&bytes[..cut]);
            }
            let e = dir_of(&bytes[..bytes.len() - 20]).unwrap_err();
            assert!(e.msg.contains("truncated"), "{e}");
            assert!(dir_of(b"").unwrap_err().msg.contains("empty"));
        }
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for z in [false, true] {
            for be in [false, true] {
                let base = sample_file(be, z);
                for _ in 0..1500 {
                    let mut b = base.clone();
                    for _ in 0..1 + next() % 4 {
                        let k = 120 + (next() as usize) % (b.len() - 120);
                        b[k] = next() as u8;
                    }
                    if let Ok(dir) = dir_of(&b) {
                        let names: Vec<&str> =
                            dir.entries.iter().map(|e| e.name.as_str()).collect();
                        let _ = decode_selected(&mut std::io::Cursor::new(&b), &dir, &names);
                    }
                }
            }
        }
    }

    #[test]
    fn empty_and_foreign_files() {
        assert!(parse(b"").unwrap_err().msg.contains("empty"));
        assert!(parse(b"hello").unwrap_err().msg.contains("not a MAT"));
        let mut v73 = MatBuilder::new(false).out;
        v73[124..126].copy_from_slice(&0x0200u16.to_le_bytes());
        assert!(parse(&v73).unwrap_err().msg.contains("7.3"));
    }
}
