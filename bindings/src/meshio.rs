//! Mesh files for `dynmesh.io`: OBJ and PLY parsed from bytes and formatted to bytes.
//!
//! Python keeps what touches the file system (reading the file, the atomic write, the
//! .mtl library and texture paths) and turns [`MeshFormatError`] `(message, line)` into
//! `MeshError(path, message, line)`; this module does the per-line and per-value work.
//!
//! Hand-written rather than a crate, because the readers must keep what `io.py` pins:
//! - OBJ: `tobj` keeps separate position and UV index lists (`single_index: false`) and
//!   triangulates, but its `LoadError` is a fieldless enum: no line, no token, where our
//!   errors name both. The reader here also keeps, as before: negative indices (relative
//!   to the lines above), `v`, `v/vt`, `v//vn` and `v/vt/vn` corners mixed in one file, UVs
//!   dropped with a note when only some corners have one, `\` continuing a line (except a
//!   comment), `#` comments anywhere, extra vertex values (colours) ignored, and the
//!   `mtllib`/`usemtl` arguments handed back for Python to resolve.
//! - PLY: `ply-rs` builds a map per record by default; the reader here is small enough to
//!   keep io.py's exact messages and their precedence: ASCII and binary little and big
//!   endian, any scalar type, ragged list properties, extra elements, ASCII errors by
//!   line, binary ones by record, truncation refused before allocating.
//!
//! Numbers are read with the standard library's `f64` parser (exact, and the
//! Eisel-Lemire algorithm that `fast-float` implements), accepting what Python's
//! `float()` accepts for ASCII digits, `_` between digits included. OBJ tokens split where
//! Python's `str.split()` splits, Unicode spaces included.
//!
//! Floats are written with their shortest round-trip digits (`ryu`) laid out as Python's
//! `repr` (`0.0001`, `1e-05`, `1e+16`, `1.0`), so a file reads back to the same float64
//! values and is byte for byte what the Python writer (`%r`) produced.
//!
//! Lines are formatted in blocks of rows, and OBJ files over 1 MB parsed in pieces, on the
//! rayon pool with the GIL released. On 2 idle cores that formats the 210k positions of
//! bench_io's frame in 24 ms instead of 47 and its faces in 24 instead of 42; the gain
//! shrinks to nothing while other jobs hold the cores.

use std::borrow::Cow;

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use rayon::prelude::*;
use rustc_hash::FxHashMap;

create_exception!(
    _core,
    MeshFormatError,
    PyValueError,
    "A mesh file that cannot be read; args are (message, 1-based line or None)."
);

/// Adds the mesh-file functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_obj, m)?)?;
    m.add_function(wrap_pyfunction!(read_ply, m)?)?;
    m.add_function(wrap_pyfunction!(format_rows, m)?)?;
    m.add_function(wrap_pyfunction!(format_obj_faces, m)?)?;
    m.add_function(wrap_pyfunction!(ply_body, m)?)?;
    m.add("MeshFormatError", m.py().get_type::<MeshFormatError>())?;
    Ok(())
}

// ------------------------------------------------------------------------- shared pieces

struct Error {
    message: String,
    line: Option<usize>,
}

type Result<T> = std::result::Result<T, Error>;

fn at_line(line: usize, message: String) -> Error {
    Error { message, line: Some(line) }
}

fn whole_file(message: String) -> Error {
    Error { message, line: None }
}

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        MeshFormatError::new_err((e.message, e.line))
    }
}

/// Whitespace as Python's `str.split()` sees it among ASCII characters, one table lookup.
fn is_space(b: u8) -> bool {
    const SPACE: [bool; 256] = {
        let mut t = [false; 256];
        let mut b = 0;
        while b < 256 {
            t[b] = b == 32 || (9 <= b && b <= 13) || (0x1c <= b && b <= 0x1f);
            b += 1;
        }
        t
    };
    SPACE[b as usize]
}

/// The whitespace-separated tokens of a line.
#[derive(Clone)]
struct Tokens<'a> {
    s: &'a str,
    i: usize,
}

impl<'a> Iterator for Tokens<'a> {
    type Item = &'a str;

    fn next(&mut self) -> Option<&'a str> {
        let b = self.s.as_bytes();
        while self.i < b.len() && is_space(b[self.i]) {
            self.i += 1;
        }
        if self.i == b.len() {
            return None;
        }
        let start = self.i;
        while self.i < b.len() && !is_space(b[self.i]) {
            self.i += 1;
        }
        Some(&self.s[start..self.i])
    }
}

fn tokens(s: &str) -> Tokens<'_> {
    Tokens { s, i: 0 }
}

fn trim(s: &str) -> &str {
    s.trim_matches(|c: char| c.is_ascii() && is_space(c as u8))
}

/// The token with Python's `_` digit separators removed, if it has valid ones.
fn without_underscores(token: &str) -> Option<String> {
    let b = token.as_bytes();
    if !b.contains(&b'_') {
        return None;
    }
    let digit = |i: Option<&u8>| i.is_some_and(u8::is_ascii_digit);
    for (i, &c) in b.iter().enumerate() {
        if c == b'_' && !(i > 0 && digit(b.get(i - 1)) && digit(b.get(i + 1))) {
            return None;
        }
    }
    Some(token.replace('_', ""))
}

/// A float as Python's `float()` reads it (nan, inf, exponents, `_` between digits).
fn parse_f64(token: &str) -> Option<f64> {
    match token.parse() {
        Ok(x) => Some(x),
        Err(_) => without_underscores(token)?.parse().ok(),
    }
}

fn parse_i64(token: &str) -> Option<i64> {
    match token.parse() {
        Ok(x) => Some(x),
        Err(_) => without_underscores(token)?.parse().ok(),
    }
}

/// An optionally signed decimal integer at `b[*i..]`, advancing `i`; None if there is none
/// (or it overflows).
fn scan_int(b: &[u8], i: &mut usize) -> Option<i64> {
    let negative = b.get(*i) == Some(&b'-');
    if negative || b.get(*i) == Some(&b'+') {
        *i += 1;
    }
    let start = *i;
    let mut v: i64 = 0;
    while let Some(&d) = b.get(*i).filter(|d| d.is_ascii_digit()) {
        v = v.checked_mul(10)?.checked_add(i64::from(d - b'0'))?;
        *i += 1;
    }
    (*i > start).then_some(if negative { -v } else { v })
}

/// Python's `repr` of a string, for error messages.
fn repr(s: &str) -> String {
    let quote = if s.contains('\'') && !s.contains('"') { '"' } else { '\'' };
    let mut out = String::with_capacity(s.len() + 2);
    out.push(quote);
    for c in s.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if c == quote => {
                out.push('\\');
                out.push(c);
            }
            c if (c as u32) < 0x20 || c as u32 == 0x7f => out.push_str(&format!("\\x{:02x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push(quote);
    out
}

/// Lays out shortest round-trip digits as Python's `repr` does: `ryu_text` is ryu's text of a
/// positive finite non-zero number (`123.45`, `0.00012`, `1e-7`, `1.5e300`).
fn push_python_layout(out: &mut Vec<u8>, ryu_text: &[u8]) {
    let mut digits = [0u8; 48];
    let (mut n, mut point, mut exp) = (0usize, None, 0i32);
    for (i, &b) in ryu_text.iter().enumerate() {
        match b {
            b'.' => point = Some(n),
            b'e' | b'E' => {
                let e = &ryu_text[i + 1..];
                let (neg, e) = if e.first() == Some(&b'-') { (true, &e[1..]) } else { (false, e) };
                exp = e.iter().fold(0i32, |a, &d| a * 10 + i32::from(d - b'0'));
                if neg {
                    exp = -exp;
                }
                break;
            }
            d => {
                digits[n] = d;
                n += 1;
            }
        }
    }
    // The value is 0.DIGITS x 10^decpt.
    let mut decpt = point.unwrap_or(n) as i32 + exp;
    let mut lo = 0;
    while lo + 1 < n && digits[lo] == b'0' {
        lo += 1;
        decpt -= 1;
    }
    let mut hi = n;
    while hi > lo + 1 && digits[hi - 1] == b'0' {
        hi -= 1;
    }
    let d = &digits[lo..hi];
    let len = d.len() as i32;
    if -4 < decpt && decpt <= 16 {
        if decpt <= 0 {
            out.extend_from_slice(b"0.");
            out.resize(out.len() + (-decpt) as usize, b'0');
            out.extend_from_slice(d);
        } else if decpt >= len {
            out.extend_from_slice(d);
            out.resize(out.len() + (decpt - len) as usize, b'0');
            out.extend_from_slice(b".0");
        } else {
            out.extend_from_slice(&d[..decpt as usize]);
            out.push(b'.');
            out.extend_from_slice(&d[decpt as usize..]);
        }
    } else {
        out.push(d[0]);
        if len > 1 {
            out.push(b'.');
            out.extend_from_slice(&d[1..]);
        }
        let e = decpt - 1;
        out.extend_from_slice(if e < 0 { b"e-" } else { b"e+" });
        if e.abs() < 10 {
            out.push(b'0');
        }
        out.extend_from_slice(itoa::Buffer::new().format(e.abs()).as_bytes());
    }
}

/// Python's `repr(x)` of a float64: shortest digits that read back to `x`.
fn push_f64(out: &mut Vec<u8>, x: f64, buf: &mut ryu::Buffer) {
    if x.is_nan() {
        out.extend_from_slice(b"nan");
        return;
    }
    if x.is_sign_negative() {
        out.push(b'-');
    }
    if x.is_infinite() {
        out.extend_from_slice(b"inf");
    } else if x == 0.0 {
        out.extend_from_slice(b"0.0");
    } else {
        let text = buf.format_finite(x.abs()).as_bytes();
        // ryu's layout is Python's but for exponents (`1e-7` for `1e-07`, `1e16` for
        // `1e+16`) and for 1e-5 <= x < 1e-4, which ryu writes as `0.0000...`.
        if text.contains(&b'e') || text.starts_with(b"0.0000") {
            push_python_layout(out, text);
        } else {
            out.extend_from_slice(text);
        }
    }
}

fn f64_text(x: f64) -> String {
    let mut out = Vec::new();
    push_f64(&mut out, x, &mut ryu::Buffer::new());
    String::from_utf8(out).expect("ascii")
}

/// Python's list repr of floats: `[0.0, nan, 1e+300]`.
fn floats_text(values: &[f64]) -> String {
    let items: Vec<String> = values.iter().map(|&x| f64_text(x)).collect();
    format!("[{}]", items.join(", "))
}

/// (positions (N, 3), faces (M, 3), uvs (K, 2) or None, uv_faces (M, 3) or None).
type MeshArrays<'py> =
    (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<i64>>, Option<Bound<'py, PyArray2<f64>>>, Option<Bound<'py, PyArray2<i64>>>);

fn mesh_arrays(py: Python<'_>, positions: Vec<f64>, faces: Vec<i64>, uv: Option<(Vec<f64>, Vec<i64>)>) -> MeshArrays<'_> {
    let rows = |v: Vec<f64>, w: usize| Array2::from_shape_vec((v.len() / w, w), v).expect("shape").into_pyarray(py);
    let tris = |v: Vec<i64>| Array2::from_shape_vec((v.len() / 3, 3), v).expect("shape").into_pyarray(py);
    let (uvs, uv_faces) = match uv {
        Some((u, f)) => (Some(rows(u, 2)), Some(tris(f))),
        None => (None, None),
    };
    (rows(positions, 3), tris(faces), uvs, uv_faces)
}

/// Fan triangulation of polygons laid end to end: corner numbers (T*3), or None when every
/// polygon is a triangle already.
fn fan(sizes: &[usize]) -> Option<Vec<usize>> {
    if sizes.iter().all(|&s| s == 3) {
        return None;
    }
    let mut out = Vec::with_capacity(3 * sizes.iter().map(|&s| s - 2).sum::<usize>());
    let mut base = 0;
    for &s in sizes {
        for k in 0..s - 2 {
            out.extend_from_slice(&[base, base + 1 + k, base + 2 + k]);
        }
        base += s;
    }
    Some(out)
}

fn polygon_note(sizes: &[usize], notes: &mut Vec<String>) {
    let polygons = sizes.iter().filter(|&&s| s > 3).count();
    if polygons > 0 {
        notes.push(format!("triangulated {polygons} polygon(s) with more than 3 corners"));
    }
}

// ------------------------------------------------------------------------- OBJ reading

struct ObjFace {
    size: usize,
    line: usize,
    v_before: usize,
    vt_before: usize,
}

#[derive(Default)]
struct Obj {
    positions: Vec<f64>,
    uvs: Vec<f64>,
    corner_v: Vec<i64>,
    corner_vt: Vec<i64>, // 0 where a corner has no UV
    faces: Vec<ObjFace>,
    corners_with_uv: usize,
    mtllibs: Vec<String>,
    materials: Vec<String>,
    bad_position: Option<(usize, [f64; 3])>,
    bad_uv: Option<(usize, [f64; 2])>,
}

impl Obj {
    fn line(&mut self, number: usize, line: &str) -> Result<()> {
        let content = match memchr::memchr(b'#', line.as_bytes()) {
            Some(i) => &line[..i],
            None => line,
        };
        let mut toks = tokens(content);
        let Some(key) = toks.next() else { return Ok(()) };
        match key {
            "v" => {
                let xyz = numbers::<3>(toks, key, 3, number)?;
                if self.bad_position.is_none() && !xyz.iter().all(|x| x.is_finite()) {
                    self.bad_position = Some((number, xyz));
                }
                self.positions.extend_from_slice(&xyz);
            }
            "vt" => {
                let uv = numbers::<2>(toks, key, 1, number)?;
                if self.bad_uv.is_none() && !uv.iter().all(|x| x.is_finite()) {
                    self.bad_uv = Some((number, uv));
                }
                self.uvs.extend_from_slice(&uv);
            }
            "f" => self.face(toks, number)?,
            "mtllib" | "usemtl" => {
                let arg = trim(&content[toks.i..]);
                if !arg.is_empty() {
                    if key == "mtllib" {
                        self.mtllibs.push(arg.to_string());
                    } else if !self.materials.iter().any(|m| m == arg) {
                        self.materials.push(arg.to_string());
                    }
                }
            }
            _ => {}
        }
        Ok(())
    }

    fn face(&mut self, toks: Tokens<'_>, number: usize) -> Result<()> {
        let (mut count, mut error) = (0, None);
        for token in toks {
            count += 1;
            if error.is_none() {
                match corner(token, number) {
                    Ok((v, vt)) => {
                        self.corner_v.push(v);
                        self.corner_vt.push(vt);
                        self.corners_with_uv += usize::from(vt != 0);
                    }
                    Err(e) => error = Some(e),
                }
            }
        }
        if count < 3 {
            return Err(at_line(number, format!("face needs at least 3 corners, found {count}")));
        }
        if let Some(e) = error {
            return Err(e);
        }
        self.faces.push(ObjFace { size: count, line: number, v_before: self.positions.len() / 3, vt_before: self.uvs.len() / 2 });
        Ok(())
    }

    /// Adds the lines of `part`, which follows `lines_before` lines of this file.
    fn append(&mut self, part: Obj, lines_before: usize) {
        let (v_before, vt_before) = (self.positions.len() / 3, self.uvs.len() / 2);
        self.bad_position = self.bad_position.or(part.bad_position.map(|(line, x)| (line + lines_before, x)));
        self.bad_uv = self.bad_uv.or(part.bad_uv.map(|(line, x)| (line + lines_before, x)));
        self.positions.extend_from_slice(&part.positions);
        self.uvs.extend_from_slice(&part.uvs);
        self.corner_v.extend_from_slice(&part.corner_v);
        self.corner_vt.extend_from_slice(&part.corner_vt);
        self.corners_with_uv += part.corners_with_uv;
        self.faces.extend(part.faces.into_iter().map(|f| ObjFace {
            line: f.line + lines_before,
            v_before: f.v_before + v_before,
            vt_before: f.vt_before + vt_before,
            ..f
        }));
        self.mtllibs.extend(part.mtllibs);
        for m in part.materials {
            if !self.materials.contains(&m) {
                self.materials.push(m);
            }
        }
    }

    /// Fan triangles of 0-based indices from OBJ ones (1-based, or negative relative to
    /// the lines above); the first bad corner is the error.
    fn triangles(&self, raw: &[i64], n: usize, what: &str, before: impl Fn(&ObjFace) -> usize) -> Result<Vec<i64>> {
        let mut out = Vec::with_capacity(3 * (raw.len() - 2 * self.faces.len()));
        let mut corners = raw.iter();
        for face in &self.faces {
            let before = before(face);
            let resolve = |r: i64| -> Result<i64> {
                let idx = if r > 0 { r - 1 } else { before as i64 + r };
                if r != 0 && idx >= 0 && idx < n as i64 {
                    return Ok(idx);
                }
                let reason = if r == 0 {
                    "is 0 (indices start at 1)".to_string()
                } else {
                    let relative = if before > 0 { format!(" or -1..-{before}") } else { String::new() };
                    format!("is out of range (1..{n}{relative})")
                };
                Err(at_line(face.line, format!("{what} index {r} {reason}")))
            };
            let mut polygon = corners.by_ref().take(face.size);
            let first = resolve(*polygon.next().expect("3 corners"))?;
            let mut previous = resolve(*polygon.next().expect("3 corners"))?;
            for &r in polygon {
                let current = resolve(r)?;
                out.extend_from_slice(&[first, previous, current]);
                previous = current;
            }
        }
        Ok(out)
    }
}

/// (vertex, uv or 0) raw indices of a face corner `v`, `v/vt`, `v//vn` or `v/vt/vn`.
fn corner(token: &str, number: usize) -> Result<(i64, i64)> {
    // Fast path for plain integers; anything else is decided by the general parse below.
    let b = token.as_bytes();
    let mut i = 0;
    if let Some(v) = scan_int(b, &mut i) {
        let mut vt = Some(0);
        if b.get(i) == Some(&b'/') {
            i += 1;
            if i < b.len() && b[i] != b'/' {
                vt = scan_int(b, &mut i);
            }
            if b.get(i) == Some(&b'/') {
                i += 1;
                if i < b.len() && scan_int(b, &mut i).is_none() {
                    vt = None;
                }
            }
        }
        if let Some(vt) = vt.filter(|_| i == b.len()) {
            return Ok((v, vt));
        }
    }
    let fields: Vec<&str> = token.split('/').collect();
    if fields.len() > 3 || fields[0].is_empty() {
        return Err(at_line(number, format!("bad face corner {}", repr(token))));
    }
    let mut numbers = [0i64; 3];
    for (n, x) in numbers.iter_mut().zip(&fields) {
        if !x.is_empty() {
            *n = parse_i64(x).ok_or_else(|| at_line(number, format!("bad index {}", repr(x))))?;
        }
    }
    Ok((numbers[0], numbers[1]))
}

/// The first `W` numbers after a keyword (at least `minimum`, missing ones 0; extra
/// values such as vertex colours are ignored).
fn numbers<const W: usize>(toks: Tokens<'_>, key: &str, minimum: usize, number: usize) -> Result<[f64; W]> {
    let mut found = [""; W];
    let mut count = 0;
    for t in toks {
        if count < W {
            found[count] = t;
        }
        count += 1;
        if count >= W && count >= minimum {
            break;
        }
    }
    if count < minimum {
        return Err(at_line(number, format!("'{key}' needs at least {minimum} numbers, found {count}")));
    }
    let mut out = [0.0; W];
    for (o, t) in out.iter_mut().zip(&found[..count.min(W)]) {
        *o = parse_f64(t).ok_or_else(|| at_line(number, format!("bad number {}", repr(t))))?;
    }
    Ok(out)
}

/// Calls `f(first line number, logical line)` with backslash continuations joined.
/// Comment lines never continue: a Windows path ending in `\` in a comment must not
/// swallow the next line.
fn logical_lines(text: &str, mut f: impl FnMut(usize, &str) -> Result<()>) -> Result<()> {
    let mut pending = String::new();
    let mut start = 0;
    let (bytes, mut at, mut number) = (text.as_bytes(), 0, 0);
    while at <= bytes.len() {
        // The pieces between newlines, as Python's text.split("\n") gives them.
        let end = memchr::memchr(b'\n', &bytes[at..]).map_or(bytes.len(), |e| at + e);
        let line = &text[at..end];
        (at, number) = (end + 1, number + 1);
        let stripped = line.trim_end_matches(|c: char| c.is_ascii() && is_space(c as u8));
        if stripped.ends_with('\\') && !trim(stripped).starts_with('#') {
            if start == 0 {
                start = number;
            }
            pending.push_str(&stripped[..stripped.len() - 1]);
            pending.push(' ');
            continue;
        }
        if start == 0 {
            f(number, line)?;
        } else {
            pending.push_str(line);
            f(start, &pending)?;
            pending.clear();
            start = 0;
        }
    }
    if start != 0 {
        f(start, &pending)?;
    }
    Ok(())
}

struct ObjMesh {
    positions: Vec<f64>,
    faces: Vec<i64>,
    uv: Option<(Vec<f64>, Vec<i64>)>,
    mtllibs: Vec<String>,
    materials: Vec<String>,
    notes: Vec<String>,
}

/// The text as Python reads it: UTF-8 with invalid bytes replaced, and every Unicode
/// whitespace character but the newline made a space, so that the ASCII tokenizer splits
/// where `str.split()` does.
fn python_text(data: &[u8]) -> Cow<'_, str> {
    match std::str::from_utf8(data) {
        Ok(text) if text.is_ascii() => Cow::Borrowed(text),
        _ => Cow::Owned(String::from_utf8_lossy(data).chars().map(|c| if c != '\n' && c.is_whitespace() { ' ' } else { c }).collect()),
    }
}

/// Below this many bytes a file is parsed in one piece.
const BYTES_PER_PIECE: usize = 1 << 20;

/// The lines of `text` as an [`Obj`]. A file without backslashes (no line continues) is cut
/// at newlines into pieces parsed on the rayon pool and joined in order: indices, line
/// numbers and the first error come out as from one pass.
fn scan_obj(text: &str) -> Result<Obj> {
    let pieces = (text.len() / BYTES_PER_PIECE).clamp(1, 4 * rayon::current_num_threads());
    if pieces == 1 || memchr::memchr(b'\\', text.as_bytes()).is_some() {
        let mut obj = Obj::default();
        logical_lines(text, |number, line| obj.line(number, line))?;
        return Ok(obj);
    }
    let bytes = text.as_bytes();
    let mut cuts = vec![0];
    for k in 1..pieces {
        let at = (k * bytes.len() / pieces).max(cuts[k - 1]);
        cuts.push(memchr::memchr(b'\n', &bytes[at..]).map_or(bytes.len(), |e| at + e + 1));
    }
    cuts.push(bytes.len());
    let parts: Vec<(Result<Obj>, usize)> = cuts
        .par_windows(2)
        .map(|w| {
            let piece = &text[w[0]..w[1]];
            let mut obj = Obj::default();
            (logical_lines(piece, |number, line| obj.line(number, line)).map(|_| obj), memchr::memchr_iter(b'\n', piece.as_bytes()).count())
        })
        .collect();
    let mut objs = Vec::with_capacity(parts.len());
    let mut lines_before = 0;
    for (part, newlines) in parts {
        objs.push((part.map_err(|e| Error { line: e.line.map(|l| l + lines_before), ..e })?, lines_before));
        lines_before += newlines;
    }
    let mut objs = objs.into_iter();
    let (mut all, _) = objs.next().expect("a piece");
    let rest: Vec<(Obj, usize)> = objs.collect();
    let total = |f: fn(&Obj) -> usize| rest.iter().map(|(o, _)| f(o)).sum::<usize>();
    all.positions.reserve(total(|o| o.positions.len()));
    all.uvs.reserve(total(|o| o.uvs.len()));
    all.corner_v.reserve(total(|o| o.corner_v.len()));
    all.corner_vt.reserve(total(|o| o.corner_vt.len()));
    all.faces.reserve(total(|o| o.faces.len()));
    for (part, lines_before) in rest {
        all.append(part, lines_before);
    }
    Ok(all)
}

fn parse_obj(data: &[u8]) -> Result<ObjMesh> {
    let text = python_text(data.strip_prefix(b"\xef\xbb\xbf").unwrap_or(data));
    let mut obj = scan_obj(&text)?;
    if let Some((line, xyz)) = obj.bad_position {
        return Err(at_line(line, format!("coordinate is not finite: {}", floats_text(&xyz))));
    }
    if let Some((line, uv)) = obj.bad_uv {
        return Err(at_line(line, format!("texture coordinate is not finite: {}", floats_text(&uv))));
    }
    if obj.faces.is_empty() {
        return Err(whole_file("no faces".into()));
    }
    let mut notes = Vec::new();
    let with_uv = obj.corners_with_uv == obj.corner_vt.len();
    if !with_uv && obj.corners_with_uv > 0 {
        notes.push("some face corners have texture coordinates and some do not; UVs dropped".into());
    }
    let sizes: Vec<usize> = obj.faces.iter().map(|f| f.size).collect();
    polygon_note(&sizes, &mut notes);
    let faces = obj.triangles(&obj.corner_v, obj.positions.len() / 3, "vertex", |f| f.v_before)?;
    let uv = if with_uv {
        let uv_faces = obj.triangles(&obj.corner_vt, obj.uvs.len() / 2, "texture", |f| f.vt_before)?;
        Some((std::mem::take(&mut obj.uvs), uv_faces))
    } else {
        None
    };
    Ok(ObjMesh { positions: obj.positions, faces, uv, mtllibs: obj.mtllibs, materials: obj.materials, notes })
}

/// (mesh arrays, mtllib arguments, usemtl names, notes).
type ObjRead<'py> = (MeshArrays<'py>, Vec<String>, Vec<String>, Vec<String>);

/// Parses an OBJ file's bytes. Returns ((positions (N, 3), faces (M, 3), uvs (K, 2) or
/// None, uv_faces (M, 3) or None), mtllib arguments, usemtl names in order of first use,
/// notes). Polygons are fan-triangulated; UVs are kept only when every corner has one.
/// Raises MeshFormatError(message, line).
#[pyfunction]
fn read_obj<'py>(py: Python<'py>, data: &[u8]) -> PyResult<ObjRead<'py>> {
    let m = py.allow_threads(|| parse_obj(data))?;
    Ok((mesh_arrays(py, m.positions, m.faces, m.uv), m.mtllibs, m.materials, m.notes))
}

// ------------------------------------------------------------------------- PLY reading

#[derive(Clone, Copy, PartialEq)]
enum Ty {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Ty {
    fn of(name: &str) -> Option<Ty> {
        Some(match name {
            "char" | "int8" => Ty::I8,
            "uchar" | "uint8" => Ty::U8,
            "short" | "int16" => Ty::I16,
            "ushort" | "uint16" => Ty::U16,
            "int" | "int32" => Ty::I32,
            "uint" | "uint32" => Ty::U32,
            "float" | "float32" => Ty::F32,
            "double" | "float64" => Ty::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Ty::I8 | Ty::U8 => 1,
            Ty::I16 | Ty::U16 => 2,
            Ty::I32 | Ty::U32 | Ty::F32 => 4,
            Ty::F64 => 8,
        }
    }

    fn is_int(self) -> bool {
        !matches!(self, Ty::F32 | Ty::F64)
    }

    /// The value at the start of `b` (at least `size` bytes); every PLY type fits f64 exactly.
    fn read(self, b: &[u8], big: bool) -> f64 {
        macro_rules! get {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().expect("size");
                if big { <$t>::from_be_bytes(a) } else { <$t>::from_le_bytes(a) }
            }};
        }
        match self {
            Ty::I8 => f64::from(b[0] as i8),
            Ty::U8 => f64::from(b[0]),
            Ty::I16 => f64::from(get!(i16, 2)),
            Ty::U16 => f64::from(get!(u16, 2)),
            Ty::I32 => f64::from(get!(i32, 4)),
            Ty::U32 => f64::from(get!(u32, 4)),
            Ty::F32 => f64::from(get!(f32, 4)),
            Ty::F64 => get!(f64, 8),
        }
    }

    /// How numpy prints a value of this type (`3`, `3.5`, `1e+20`).
    fn text(self, x: f64) -> String {
        match self {
            t if t.is_int() => format!("{}", x as i64),
            Ty::F32 if x.is_finite() && x != 0.0 => {
                let mut out = Vec::new();
                if x < 0.0 {
                    out.push(b'-');
                }
                push_python_layout(&mut out, ryu::Buffer::new().format_finite((x as f32).abs()).as_bytes());
                String::from_utf8(out).expect("ascii")
            }
            _ => f64_text(x),
        }
    }
}

struct Property {
    name: String,
    ty: Ty,
    count: Option<Ty>,
}

struct Element {
    name: String,
    count: usize,
    properties: Vec<Property>,
}

struct Header {
    format: Format,
    elements: Vec<Element>,
    comments: Vec<String>,
    body: usize,
    lines: usize,
}

#[derive(Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

/// Whitespace of Python's `str.split()` on latin-1 text (the header is decoded so).
fn is_latin1_space(b: u8) -> bool {
    is_space(b) || b == 0x85 || b == 0xa0
}

fn latin1(b: &[u8]) -> String {
    b.iter().map(|&c| c as char).collect()
}

fn parse_header(data: &[u8]) -> Result<Header> {
    let mut lines: Vec<&[u8]> = Vec::new();
    let mut pos = 0;
    loop {
        let end = data[pos..].iter().position(|&b| b == b'\n').map(|e| pos + e);
        let Some(end) = end.filter(|_| lines.len() <= 10000) else {
            return Err(whole_file("bad PLY header: no 'end_header' line".into()));
        };
        let raw = &data[pos..end];
        let s = raw.iter().position(|&b| !is_latin1_space(b)).unwrap_or(raw.len());
        let e = raw.iter().rposition(|&b| !is_latin1_space(b)).map_or(s, |i| i + 1);
        lines.push(&raw[s..e]);
        pos = end + 1;
        let text = lines[lines.len() - 1];
        if text == b"end_header" || (lines.len() == 1 && text != b"ply") {
            break;
        }
    }
    if lines[0] != b"ply" {
        return Err(at_line(1, "bad PLY header: first line is not 'ply'".into()));
    }
    let (mut format, mut elements, mut comments) = (None, Vec::<Element>::new(), Vec::new());
    for (i, line) in lines[1..lines.len() - 1].iter().enumerate() {
        let number = i + 2;
        let parts: Vec<&[u8]> = line.split(|&b| is_latin1_space(b)).filter(|t| !t.is_empty()).collect();
        let word = |k: usize| parts.get(k).map(|p| latin1(p)).unwrap_or_default();
        match parts.first().map(|p| &p[..]) {
            None | Some(b"comment") | Some(b"obj_info") => {
                let rest = line.iter().position(|&b| is_latin1_space(b)).map_or(&b""[..], |k| &line[k..]);
                let rest = &rest[rest.iter().position(|&b| !is_latin1_space(b)).unwrap_or(rest.len())..];
                comments.push(latin1(rest));
            }
            Some(b"format") if parts.len() == 3 && matches!(parts[1], b"ascii" | b"binary_little_endian" | b"binary_big_endian") => {
                format = Some(match parts[1] {
                    b"ascii" => Format::Ascii,
                    b"binary_little_endian" => Format::Little,
                    _ => Format::Big,
                });
            }
            Some(b"element") if parts.len() == 3 && parts[2].iter().all(u8::is_ascii_digit) => {
                let count = parts[2].iter().fold(0usize, |a, &d| a.saturating_mul(10).saturating_add(usize::from(d - b'0')));
                elements.push(Element { name: word(1), count, properties: Vec::new() });
            }
            Some(b"property") if !elements.is_empty() => {
                let property = match parts.len() {
                    3 => Ty::of(&word(1)).map(|ty| Property { name: word(2), ty, count: None }),
                    5 if parts[1] == b"list" => match (Ty::of(&word(2)).filter(|t| t.is_int()), Ty::of(&word(3))) {
                        (Some(count), Some(ty)) => Some(Property { name: word(4), ty, count: Some(count) }),
                        _ => None,
                    },
                    _ => None,
                };
                let joined: Vec<String> = parts.iter().map(|p| latin1(p)).collect();
                let property = property.ok_or_else(|| at_line(number, format!("bad PLY property {}", repr(&joined.join(" ")))))?;
                elements.last_mut().expect("an element").properties.push(property);
            }
            _ => return Err(at_line(number, format!("bad PLY header line {}", repr(&latin1(line))))),
        }
    }
    let format = format.ok_or_else(|| whole_file("bad PLY header: missing or unsupported 'format' line".into()))?;
    Ok(Header { format, elements, comments, body: pos, lines: lines.len() })
}

enum Values {
    Scalar(Vec<f64>),
    List(Vec<usize>, Vec<f64>),
}

struct Column {
    name: String,
    /// How values print in messages: the property's type, or float64 for ASCII.
    ty: Ty,
    values: Values,
}

struct ElementData {
    name: String,
    columns: Vec<Column>,
    /// Line number of each record (ASCII); binary records are named by number.
    lines: Option<Vec<usize>>,
}

impl ElementData {
    /// The last column of this name, as a Python dict of columns would keep.
    fn column(&self, name: &str) -> Option<&Column> {
        self.columns.iter().rev().find(|c| c.name == name)
    }

    fn scalar(&self, name: &str) -> Option<&[f64]> {
        match self.column(name).map(|c| &c.values) {
            Some(Values::Scalar(v)) => Some(v),
            _ => None,
        }
    }

    /// How to point at record `index`: its line for ASCII, its number for binary.
    fn record(&self, index: usize, what: &str) -> (String, Option<usize>) {
        match &self.lines {
            Some(lines) => (what.to_string(), Some(lines[index])),
            None => (format!("{what} {index}"), None),
        }
    }
}

fn truncated(e: &Element) -> Error {
    whole_file(format!("truncated binary PLY: data ends inside element '{}' ({} records)", e.name, e.count))
}

fn binary_element(data: &[u8], pos: &mut usize, e: &Element, big: bool) -> Result<ElementData> {
    let mut out = ElementData { name: e.name.clone(), columns: Vec::new(), lines: None };
    if e.properties.is_empty() {
        return Ok(out);
    }
    // A header may claim any count; refuse before allocating for it.
    let smallest: usize = e.properties.iter().map(|p| p.count.unwrap_or(p.ty).size()).sum();
    if smallest.saturating_mul(e.count) > data.len() - *pos {
        return Err(truncated(e));
    }
    let mut columns: Vec<Values> = e
        .properties
        .iter()
        .map(|p| match p.count {
            Some(_) => Values::List(Vec::with_capacity(e.count), Vec::with_capacity(3 * e.count)),
            None => Values::Scalar(Vec::with_capacity(e.count)),
        })
        .collect();
    let mut p = *pos;
    for r in 0..e.count {
        for (prop, column) in e.properties.iter().zip(&mut columns) {
            let size = prop.ty.size();
            match column {
                Values::Scalar(v) => {
                    let b = data.get(p..p + size).ok_or_else(|| truncated(e))?;
                    v.push(prop.ty.read(b, big));
                    p += size;
                }
                Values::List(counts, v) => {
                    let ct = prop.count.expect("list");
                    let b = data.get(p..p + ct.size()).ok_or_else(|| truncated(e))?;
                    let n = ct.read(b, big);
                    if n < 0.0 {
                        return Err(whole_file(format!("negative list length in '{}' record {r}", e.name)));
                    }
                    p += ct.size();
                    let n = n as usize;
                    let b = data.get(p..p + n * size).ok_or_else(|| truncated(e))?;
                    v.extend(b.chunks_exact(size).map(|c| prop.ty.read(c, big)));
                    counts.push(n);
                    p += n * size;
                }
            }
        }
    }
    *pos = p;
    out.columns = e.properties.iter().zip(columns).map(|(p, values)| Column { name: p.name.clone(), ty: p.ty, values }).collect();
    Ok(out)
}

/// Every non-blank line of an ASCII PLY body: (0-based line, text).
fn ascii_records(body: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    body.split(|&b| b == b'\n').enumerate().filter(|(_, l)| l.iter().any(|&b| b > 32))
}

fn ascii_element<'a>(records: &mut impl Iterator<Item = (usize, &'a [u8])>, e: &Element, first_line: usize) -> Result<ElementData> {
    let mut lines = Vec::new();
    let mut values = Vec::new();
    let mut offsets = Vec::new();
    let mut bad: Option<Error> = None;
    for (index, text) in records.by_ref().take(e.count) {
        let number = index + first_line;
        lines.push(number);
        offsets.push(values.len());
        for t in text.split(|&b| b <= 32).filter(|t| !t.is_empty()) {
            match std::str::from_utf8(t).ok().and_then(parse_f64) {
                Some(x) => values.push(x),
                None => {
                    bad.get_or_insert_with(|| at_line(number, format!("bad number {}", repr(&String::from_utf8_lossy(t)))));
                    values.push(f64::NAN);
                }
            }
        }
    }
    if lines.len() < e.count {
        return Err(whole_file(format!("PLY ends early: element '{}' needs {} lines, found {}", e.name, e.count, lines.len())));
    }
    if let Some(bad) = bad {
        return Err(bad);
    }
    offsets.push(values.len());
    let ends = &offsets[1..];
    // Property by property over all records, as the record layout is checked.
    let mut pos: Vec<usize> = offsets[..e.count].to_vec();
    let mut layout: Vec<(Vec<usize>, Vec<usize>)> = Vec::with_capacity(e.properties.len());
    for p in &e.properties {
        let mut counts = vec![1usize; e.count];
        if p.count.is_some() {
            for r in 0..e.count {
                let n = if pos[r] < ends[r] { values[pos[r]] } else { -1.0 };
                if n < 0.0 || n != n.round() {
                    return Err(at_line(lines[r], format!("bad list length in '{}'", e.name)));
                }
                counts[r] = n as usize;
                pos[r] += 1;
            }
        }
        let starts = pos.clone();
        for (q, c) in pos.iter_mut().zip(&counts) {
            *q = q.saturating_add(*c);
        }
        layout.push((counts, starts));
    }
    if let Some(r) = (0..e.count).find(|&r| pos[r] != ends[r]) {
        let (ntok, expected) = (ends[r] - offsets[r], pos[r].saturating_sub(offsets[r]));
        return Err(at_line(lines[r], format!("'{}' record has {ntok} values, expected {expected}", e.name)));
    }
    let columns = e
        .properties
        .iter()
        .zip(layout)
        .map(|(p, (counts, starts))| {
            let values = match p.count {
                Some(_) => {
                    let flat = starts.iter().zip(&counts).flat_map(|(&s, &c)| values[s..s + c].iter().copied()).collect();
                    Values::List(counts, flat)
                }
                None => Values::Scalar(starts.iter().map(|&s| values[s]).collect()),
            };
            Column { name: p.name.clone(), ty: Ty::F64, values }
        })
        .collect();
    Ok(ElementData { name: e.name.clone(), columns, lines: Some(lines) })
}

const UV_NAMES: [(&str, &str); 4] = [("u", "v"), ("s", "t"), ("texture_u", "texture_v"), ("texture_s", "texture_t")];

struct PlyMesh {
    positions: Vec<f64>,
    faces: Vec<i64>,
    uv: Option<(Vec<f64>, Vec<i64>)>,
    comments: Vec<String>,
    notes: Vec<String>,
}

fn parse_ply(data: &[u8]) -> Result<PlyMesh> {
    let header = parse_header(data)?;
    let mut elements = Vec::with_capacity(header.elements.len());
    if header.format == Format::Ascii {
        let mut records = ascii_records(&data[header.body..]);
        for e in &header.elements {
            elements.push(ascii_element(&mut records, e, header.lines + 1)?);
        }
    } else {
        let mut pos = header.body;
        for e in &header.elements {
            elements.push(binary_element(data, &mut pos, e, header.format == Format::Big)?);
        }
    }
    let find = |name: &str| elements.iter().rev().find(|e| e.name == name);
    let vertex = find("vertex").ok_or_else(|| whole_file("PLY has no 'vertex' element".into()))?;
    let mut xyz = [&[][..]; 3];
    for (k, c) in ["x", "y", "z"].into_iter().enumerate() {
        xyz[k] = vertex.scalar(c).ok_or_else(|| whole_file(format!("PLY vertex element lacks property '{c}'")))?;
    }
    let n = xyz[0].len();
    let positions: Vec<f64> = (0..n).flat_map(|i| [xyz[0][i], xyz[1][i], xyz[2][i]]).collect();
    if let Some(i) = positions.chunks_exact(3).position(|p| !p.iter().all(|x| x.is_finite())) {
        let (what, line) = vertex.record(i, "vertex");
        return Err(Error { message: format!("{what} has a coordinate that is not finite"), line });
    }

    let face = find("face");
    let column = face.and_then(|f| f.column("vertex_indices").or_else(|| f.column("vertex_index")));
    let (face, column) = match (face, column) {
        (Some(f), Some(c @ Column { values: Values::List(counts, _), .. })) if !counts.is_empty() => (f, c),
        _ => return Err(whole_file("no faces (PLY needs a 'face' element with a 'vertex_indices' list)".into())),
    };
    let Values::List(sizes, flat) = &column.values else { unreachable!("a list column") };
    if let Some(i) = sizes.iter().position(|&s| s < 3) {
        let (what, line) = face.record(i, "face");
        return Err(Error { message: format!("{what} has fewer than 3 corners"), line });
    }
    if let Some(k) = flat.iter().position(|&x| !(x >= 0.0 && x < n as f64 && x as i64 as f64 == x)) {
        let mut owner = 0;
        let mut seen = sizes[0];
        while seen <= k {
            owner += 1;
            seen += sizes[owner];
        }
        let (what, line) = face.record(owner, "face");
        let message = format!("{what}: vertex index {} is out of range (0..{})", column.ty.text(flat[k]), n as i64 - 1);
        return Err(Error { message, line });
    }
    let tris = fan(sizes);
    let corners = tris.as_ref().map_or(flat.len(), Vec::len);
    let corner = |k: usize| tris.as_ref().map_or(k, |t| t[k]);
    let mut notes = Vec::new();
    polygon_note(sizes, &mut notes);
    let faces: Vec<i64> = (0..corners).map(|k| flat[corner(k)] as i64).collect();

    let per_corner = match face.column("texcoord").map(|c| &c.values) {
        Some(Values::List(counts, uv)) if counts.iter().zip(sizes).all(|(&c, &s)| c == 2 * s) => Some(uv),
        _ => None,
    };
    let uv = if let Some(uv) = per_corner {
        Some(unique_corner_uvs(uv, (0..corners).map(corner), flat, n))
    } else {
        UV_NAMES.iter().find_map(|(u, v)| {
            let (u, v) = (vertex.scalar(u)?, vertex.scalar(v)?);
            Some((u.iter().zip(v).flat_map(|(&a, &b)| [a, b]).collect(), faces.clone()))
        })
    };
    Ok(PlyMesh { positions, faces, uv, comments: header.comments, notes })
}

/// Per-corner UVs (polygon corners laid end to end) made into a UV list in order of first
/// use and an index per triangle corner (`tris`: the polygon corner of each); equal UVs
/// (0.0 == -0.0) share one entry, NaNs never do. `corner_vertex` is each polygon corner's
/// vertex: the UV a vertex had last is tried before the table of all UVs, which most
/// corners then never touch.
fn unique_corner_uvs(uv: &[f64], tris: impl ExactSizeIterator<Item = usize>, corner_vertex: &[f64], vertices: usize) -> (Vec<f64>, Vec<i64>) {
    let key = |x: f64| if x == 0.0 { 0 } else { x.to_bits() };
    let mut seen: FxHashMap<(u64, u64), i64> = FxHashMap::default();
    let mut last: Vec<Option<((u64, u64), i64)>> = vec![None; vertices];
    let mut uvs = Vec::new();
    let mut index = Vec::with_capacity(tris.len());
    for c in tris {
        let (u, v) = (uv[2 * c], uv[2 * c + 1]);
        let next = (uvs.len() / 2) as i64;
        let i = if u.is_nan() || v.is_nan() {
            next
        } else {
            let k = (key(u), key(v));
            let cached = &mut last[corner_vertex[c] as usize];
            match *cached {
                Some((kc, i)) if kc == k => i,
                _ => {
                    let i = *seen.entry(k).or_insert(next);
                    *cached = Some((k, i));
                    i
                }
            }
        };
        if i == next {
            uvs.extend_from_slice(&[u, v]);
        }
        index.push(i);
    }
    (uvs, index)
}

/// Parses a PLY file's bytes (ASCII, binary little or big endian). Returns ((positions,
/// faces, uvs or None, uv_faces or None), header comments, notes): UVs are the faces'
/// per-corner `texcoord` lists, else per-vertex u,v (s,t, texture_u/v, texture_s/t) with
/// uv_faces equal to faces. Raises MeshFormatError(message, line).
#[pyfunction]
fn read_ply<'py>(py: Python<'py>, data: &[u8]) -> PyResult<(MeshArrays<'py>, Vec<String>, Vec<String>)> {
    let m = py.allow_threads(|| parse_ply(data))?;
    Ok((mesh_arrays(py, m.positions, m.faces, m.uv), m.comments, m.notes))
}

// ------------------------------------------------------------------------- writing

const ROWS_PER_BLOCK: usize = 16384;

/// `f(first row, end row, out)` over blocks of `rows` rows on the rayon pool, in order.
pub(crate) fn text_blocks(rows: usize, f: impl Fn(usize, usize, &mut Vec<u8>) + Sync + Send) -> Vec<Vec<u8>> {
    (0..rows.div_ceil(ROWS_PER_BLOCK))
        .into_par_iter()
        .map(|b| {
            let (lo, hi) = (b * ROWS_PER_BLOCK, ((b + 1) * ROWS_PER_BLOCK).min(rows));
            let mut out = Vec::with_capacity(64 * (hi - lo));
            f(lo, hi, &mut out);
            out
        })
        .collect()
}

/// [`text_blocks`] with the GIL released, joined into bytes.
fn format_blocks<'py>(py: Python<'py>, rows: usize, f: impl Fn(usize, usize, &mut Vec<u8>) + Sync + Send) -> PyResult<Bound<'py, PyBytes>> {
    let blocks = py.allow_threads(|| text_blocks(rows, f));
    let total = blocks.iter().map(Vec::len).sum();
    PyBytes::new_with(py, total, |buf| {
        let mut at = 0;
        for b in &blocks {
            buf[at..at + b.len()].copy_from_slice(b);
            at += b.len();
        }
        Ok(())
    })
}

/// The array's values row by row, borrowed when it is C-contiguous.
fn contiguous<'a, T: numpy::Element + Copy>(a: &'a PyReadonlyArray2<'_, T>, width: usize, what: &str) -> PyResult<Cow<'a, [T]>> {
    let v = a.as_array();
    if v.ncols() != width {
        return Err(PyValueError::new_err(format!("{what} must have shape (N, {width})")));
    }
    Ok(match a.as_slice() {
        Ok(s) => Cow::Borrowed(s),
        Err(_) => Cow::Owned(v.iter().copied().collect()),
    })
}

fn push_int(out: &mut Vec<u8>, x: i64, buf: &mut itoa::Buffer) {
    out.extend_from_slice(buf.format(x).as_bytes());
}

/// Rows `lo..hi` of `flat` (rows of `width` floats) as lines: `prefix` (if any), then the
/// row's floats as Python's repr, space-separated.
pub(crate) fn push_rows(out: &mut Vec<u8>, flat: &[f64], width: usize, prefix: &str, lo: usize, hi: usize) {
    let mut buf = ryu::Buffer::new();
    for row in flat[lo * width..hi * width].chunks_exact(width) {
        out.extend_from_slice(prefix.as_bytes());
        for (k, &x) in row.iter().enumerate() {
            if k > 0 || !prefix.is_empty() {
                out.push(b' ');
            }
            push_f64(out, x, &mut buf);
        }
        out.push(b'\n');
    }
}

/// OBJ face lines `lo..hi` of 0-based corner indices `faces` (3 per face), with `uv_faces`
/// after a slash when given.
pub(crate) fn push_obj_faces<I: Copy + Into<i64>>(out: &mut Vec<u8>, faces: &[I], uv_faces: Option<&[I]>, lo: usize, hi: usize) {
    let mut buf = itoa::Buffer::new();
    for c in 3 * lo..3 * hi {
        out.extend_from_slice(if c % 3 == 0 { b"f " } else { b" " });
        push_int(out, faces[c].into() + 1, &mut buf);
        if let Some(uv) = uv_faces {
            out.push(b'/');
            push_int(out, uv[c].into() + 1, &mut buf);
        }
        if c % 3 == 2 {
            out.push(b'\n');
        }
    }
}

/// One line per row of `values` (N, W): `prefix` (if any), then the row's floats as
/// Python's repr (shortest round trip), space-separated: `v 0.1 -2.0 1e-05`.
#[pyfunction]
fn format_rows<'py>(py: Python<'py>, values: PyReadonlyArray2<'py, f64>, prefix: &str) -> PyResult<Bound<'py, PyBytes>> {
    let width = values.as_array().ncols();
    let flat = contiguous(&values, width, "values")?;
    let rows = flat.len().checked_div(width).unwrap_or(0);
    format_blocks(py, rows, |lo, hi, out| push_rows(out, &flat, width, prefix, lo, hi))
}

/// OBJ face lines from 0-based faces (M, 3): `f 1 2 3`, or `f 1/1 2/2 3/3` with uv_faces.
#[pyfunction]
#[pyo3(signature = (faces, uv_faces=None))]
fn format_obj_faces<'py>(py: Python<'py>, faces: PyReadonlyArray2<'py, i64>, uv_faces: Option<PyReadonlyArray2<'py, i64>>) -> PyResult<Bound<'py, PyBytes>> {
    let faces = contiguous(&faces, 3, "faces")?;
    let uv_faces = uv_faces.as_ref().map(|u| contiguous(u, 3, "uv_faces")).transpose()?;
    if uv_faces.as_ref().is_some_and(|u| u.len() != faces.len()) {
        return Err(PyValueError::new_err("uv_faces and faces differ in shape"));
    }
    format_blocks(py, faces.len() / 3, |lo, hi, out| push_obj_faces(out, &faces, uv_faces.as_deref(), lo, hi))
}

/// Rows `lo..hi` of a PLY body: rows below the vertex count are vertex rows of `width`
/// doubles, the others faces as `list uchar int`, each followed by its `texcoord` (6
/// doubles) when given. ASCII rows use Python's float repr; binary is little endian. Face
/// indices must fit an i32.
pub(crate) fn push_ply_rows<I: Copy + Into<i64>>(
    out: &mut Vec<u8>,
    vertex: &[f64],
    width: usize,
    faces: &[I],
    texcoord: Option<&[f64]>,
    ascii: bool,
    lo: usize,
    hi: usize,
) {
    let rows = vertex.len().checked_div(width).unwrap_or(0);
    let (mut fbuf, mut ibuf) = (ryu::Buffer::new(), itoa::Buffer::new());
    for r in lo..hi {
        if r < rows {
            let row = &vertex[r * width..(r + 1) * width];
            if ascii {
                for (k, &x) in row.iter().enumerate() {
                    if k > 0 {
                        out.push(b' ');
                    }
                    push_f64(out, x, &mut fbuf);
                }
                out.push(b'\n');
            } else {
                row.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
            }
            continue;
        }
        let f = r - rows;
        let tc = texcoord.map(|t| &t[6 * f..6 * f + 6]);
        if ascii {
            out.push(b'3');
            for &i in &faces[3 * f..3 * f + 3] {
                out.push(b' ');
                push_int(out, i.into(), &mut ibuf);
            }
            if let Some(tc) = tc {
                out.extend_from_slice(b" 6");
                for &x in tc {
                    out.push(b' ');
                    push_f64(out, x, &mut fbuf);
                }
            }
            out.push(b'\n');
        } else {
            out.push(3);
            faces[3 * f..3 * f + 3].iter().for_each(|&i| out.extend_from_slice(&(i.into() as i32).to_le_bytes()));
            if let Some(tc) = tc {
                out.push(6);
                tc.iter().for_each(|x| out.extend_from_slice(&x.to_le_bytes()));
            }
        }
    }
}

/// The body of a PLY file after its header: vertex rows (N, W) of doubles, then faces
/// (M, 3) as `list uchar int`, each followed by its `texcoord` (M, 6) `list uchar double`
/// when given. ASCII rows use Python's float repr; binary is little endian.
#[pyfunction]
#[pyo3(signature = (vertex, faces, texcoord, ascii))]
fn ply_body<'py>(
    py: Python<'py>,
    vertex: PyReadonlyArray2<'py, f64>,
    faces: PyReadonlyArray2<'py, i64>,
    texcoord: Option<PyReadonlyArray2<'py, f64>>,
    ascii: bool,
) -> PyResult<Bound<'py, PyBytes>> {
    let width = vertex.as_array().ncols();
    let vertex = contiguous(&vertex, width, "vertex")?;
    let faces = contiguous(&faces, 3, "faces")?;
    let texcoord = texcoord.as_ref().map(|t| contiguous(t, 6, "texcoord")).transpose()?;
    if texcoord.as_ref().is_some_and(|t| t.len() != 2 * faces.len()) {
        return Err(PyValueError::new_err("texcoord needs one row per face"));
    }
    if faces.iter().any(|&i| i32::try_from(i).is_err()) {
        return Err(PyValueError::new_err("a face index does not fit PLY int"));
    }
    let rows = vertex.len().checked_div(width).unwrap_or(0);
    // Rows 0..rows are vertices, rows..rows + nf faces.
    format_blocks(py, rows + faces.len() / 3, |lo, hi, out| push_ply_rows(out, &vertex, width, &faces, texcoord.as_deref(), ascii, lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(x: f64) -> String {
        f64_text(x)
    }

    #[test]
    fn floats_are_laid_out_as_python_repr() {
        let cases = [
            (1.0, "1.0"),
            (-0.0, "-0.0"),
            (0.1, "0.1"),
            (0.0001, "0.0001"),
            (0.00001, "1e-05"),
            (1e15, "1000000000000000.0"),
            (1e16, "1e+16"),
            (123456.789, "123456.789"),
            (5e-324, "5e-324"),
            (1.7976931348623157e308, "1.7976931348623157e+308"),
            (1.5e-7, "1.5e-07"),
            (-2.0 / 3.0, "-0.6666666666666666"),
            (1e100, "1e+100"),
            (f64::INFINITY, "inf"),
        ];
        for (x, want) in cases {
            assert_eq!(text(x), want, "{x:e}");
        }
    }
}
