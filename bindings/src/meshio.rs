//! Mesh files for `dynmesh.io`: OBJ and PLY parsed from bytes and formatted to bytes.
//!
//! Python keeps what touches the file system (reading the file, the atomic write, the
//! .mtl library and texture paths) and turns [`MeshFormatError`] `(message, line)` into
//! `MeshError(path, message, line)`; this module does the per-line and per-value work.
//!
//! Hand-written rather than a crate, because the readers must keep what `python/dynmesh/io/meshio.py` and
//! the tests pin:
//! - OBJ: `tobj` keeps separate position and UV index lists (`single_index: false`) and
//!   triangulates, but its `LoadError` is a fieldless enum: no line, no token, where our
//!   errors name both. The reader here also keeps, as before: negative indices (relative
//!   to the lines above), `v`, `v/vt`, `v//vn` and `v/vt/vn` corners mixed in one file, UVs
//!   dropped with a note when only some corners have one, `\` continuing a line (except a
//!   comment), `#` comments anywhere, extra vertex values (colours) ignored, and the
//!   `mtllib`/`usemtl` arguments handed back for Python to resolve.
//! - PLY: `ply-rs` builds a map per record by default; the reader here is small enough to
//!   keep the exact messages and their precedence: ASCII and binary little and big
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
use numpy::PyUntypedArrayMethods;
use numpy::{IntoPyArray, PyArray2, PyReadonlyArray2};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use rayon::prelude::*;

create_exception!(
    _core,
    MeshFormatError,
    PyValueError,
    "A mesh file that cannot be read; args are (message, 1-based line or None)."
);

/// Adds the mesh-file functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(crate::obj::read_obj, m)?)?;
    m.add_function(wrap_pyfunction!(crate::ply::read_ply, m)?)?;
    m.add_function(wrap_pyfunction!(format_rows, m)?)?;
    m.add_function(wrap_pyfunction!(format_obj_faces, m)?)?;
    m.add_function(wrap_pyfunction!(ply_body, m)?)?;
    m.add("MeshFormatError", m.py().get_type::<MeshFormatError>())?;
    Ok(())
}

// ------------------------------------------------------------------------- shared pieces

pub(crate) struct Error {
    pub(crate) message: String,
    pub(crate) line: Option<usize>,
}

pub(crate) type Result<T> = std::result::Result<T, Error>;

pub(crate) fn at_line(line: usize, message: String) -> Error {
    Error { message, line: Some(line) }
}

pub(crate) fn whole_file(message: String) -> Error {
    Error { message, line: None }
}

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        MeshFormatError::new_err((e.message, e.line))
    }
}

/// Whitespace as Python's `str.split()` sees it among ASCII characters, one table lookup.
pub(crate) fn is_space(b: u8) -> bool {
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
pub(crate) struct Tokens<'a> {
    s: &'a str,
    pub(crate) i: usize,
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

pub(crate) fn tokens(s: &str) -> Tokens<'_> {
    Tokens { s, i: 0 }
}

pub(crate) fn trim(s: &str) -> &str {
    s.trim_matches(|c: char| c.is_ascii() && is_space(c as u8))
}

/// The token with Python's `_` digit separators removed, if it has valid ones.
pub(crate) fn without_underscores(token: &str) -> Option<String> {
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
pub(crate) fn parse_f64(token: &str) -> Option<f64> {
    match token.parse() {
        Ok(x) => Some(x),
        Err(_) => without_underscores(token)?.parse().ok(),
    }
}

pub(crate) fn parse_i64(token: &str) -> Option<i64> {
    match token.parse() {
        Ok(x) => Some(x),
        Err(_) => without_underscores(token)?.parse().ok(),
    }
}

/// An optionally signed decimal integer at `b[*i..]`, advancing `i`; None if there is none
/// (or it overflows).
pub(crate) fn scan_int(b: &[u8], i: &mut usize) -> Option<i64> {
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
pub(crate) fn repr(s: &str) -> String {
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
pub(crate) fn push_python_layout(out: &mut Vec<u8>, ryu_text: &[u8]) {
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
pub(crate) fn push_f64(out: &mut Vec<u8>, x: f64, buf: &mut ryu::Buffer) {
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

pub(crate) fn f64_text(x: f64) -> String {
    let mut out = Vec::new();
    push_f64(&mut out, x, &mut ryu::Buffer::new());
    String::from_utf8(out).expect("ascii")
}

/// Python's list repr of floats: `[0.0, nan, 1e+300]`.
pub(crate) fn floats_text(values: &[f64]) -> String {
    let items: Vec<String> = values.iter().map(|&x| f64_text(x)).collect();
    format!("[{}]", items.join(", "))
}

/// (positions (N, 3), faces (M, 3), uvs (K, 2) or None, uv_faces (M, 3) or None).
pub(crate) type MeshArrays<'py> =
    (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<i64>>, Option<Bound<'py, PyArray2<f64>>>, Option<Bound<'py, PyArray2<i64>>>);

pub(crate) fn mesh_arrays(py: Python<'_>, positions: Vec<f64>, faces: Vec<i64>, uv: Option<(Vec<f64>, Vec<i64>)>) -> MeshArrays<'_> {
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
pub(crate) fn fan(sizes: &[usize]) -> Option<Vec<usize>> {
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

pub(crate) fn polygon_note(sizes: &[usize], notes: &mut Vec<String>) {
    let polygons = sizes.iter().filter(|&&s| s > 3).count();
    if polygons > 0 {
        notes.push(format!("triangulated {polygons} polygon(s) with more than 3 corners"));
    }
}

// ------------------------------------------------------------------------- OBJ reading

// ------------------------------------------------------------------------- writing

pub(crate) const ROWS_PER_BLOCK: usize = 16384;

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
pub(crate) fn format_blocks<'py>(py: Python<'py>, rows: usize, f: impl Fn(usize, usize, &mut Vec<u8>) + Sync + Send) -> PyResult<Bound<'py, PyBytes>> {
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
pub(crate) fn contiguous<'a, T: numpy::Element + Copy>(a: &'a PyReadonlyArray2<'_, T>, width: usize, what: &str) -> PyResult<Cow<'a, [T]>> {
    let v = a.as_array();
    if v.ncols() != width {
        return Err(PyValueError::new_err(format!("{what} must have shape (N, {width})")));
    }
    // A Fortran-ordered array is contiguous too, but not row by row: only C order is borrowed.
    Ok(match a.as_slice().ok().filter(|_| a.is_c_contiguous()) {
        Some(s) => Cow::Borrowed(s),
        None => Cow::Owned(v.iter().copied().collect()),
    })
}

pub(crate) fn push_int(out: &mut Vec<u8>, x: i64, buf: &mut itoa::Buffer) {
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
pub(crate) fn format_rows<'py>(py: Python<'py>, values: PyReadonlyArray2<'py, f64>, prefix: &str) -> PyResult<Bound<'py, PyBytes>> {
    let width = values.as_array().ncols();
    let flat = contiguous(&values, width, "values")?;
    let rows = flat.len().checked_div(width).unwrap_or(0);
    format_blocks(py, rows, |lo, hi, out| push_rows(out, &flat, width, prefix, lo, hi))
}

/// OBJ face lines from 0-based faces (M, 3): `f 1 2 3`, or `f 1/1 2/2 3/3` with uv_faces.
#[pyfunction]
#[pyo3(signature = (faces, uv_faces=None))]
pub(crate) fn format_obj_faces<'py>(py: Python<'py>, faces: PyReadonlyArray2<'py, i64>, uv_faces: Option<PyReadonlyArray2<'py, i64>>) -> PyResult<Bound<'py, PyBytes>> {
    let faces = contiguous(&faces, 3, "faces")?;
    let uv_faces = uv_faces.as_ref().map(|u| contiguous(u, 3, "uv_faces")).transpose()?;
    if uv_faces.as_ref().is_some_and(|u| u.len() != faces.len()) {
        return Err(PyValueError::new_err("uv_faces and faces differ in shape"));
    }
    format_blocks(py, faces.len() / 3, |lo, hi, out| push_obj_faces(out, &faces, uv_faces.as_deref(), lo, hi))
}

/// A PLY body to write: vertex rows of `width` doubles, triangles, and per face its `texcoord`
/// (6 doubles) when given, in ASCII or binary.
pub(crate) struct PlyBody<'a, I> {
    pub vertex: &'a [f64],
    pub width: usize,
    pub faces: &'a [I],
    pub texcoord: Option<&'a [f64]>,
    pub ascii: bool,
}

/// Rows `lo..hi` of a PLY body: rows below the vertex count are vertex rows of `width`
/// doubles, the others faces as `list uchar int`, each followed by its `texcoord` (6
/// doubles) when given. ASCII rows use Python's float repr; binary is little endian. Face
/// indices must fit an i32.
pub(crate) fn push_ply_rows<I: Copy + Into<i64>>(out: &mut Vec<u8>, body: &PlyBody<'_, I>, lo: usize, hi: usize) {
    let PlyBody { vertex, width, faces, texcoord, ascii } = *body;
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
pub(crate) fn ply_body<'py>(
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
    let body = PlyBody { vertex: &vertex, width, faces: &faces, texcoord: texcoord.as_deref(), ascii };
    format_blocks(py, rows + faces.len() / 3, |lo, hi, out| push_ply_rows(out, &body, lo, hi))
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
