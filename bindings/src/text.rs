//! The text of mesh files, for the readers (`obj.rs`, `ply.rs`) and the writers
//! (`meshio.rs`): the error a reader reports (message and line, [`MeshFormatError`] in
//! Python), tokens split where Python's `str.split()` splits, numbers read as Python's
//! `float()` and `int()` read them and written as its `repr` writes them, and the arrays a
//! reader hands back.
//!
//! Numbers are read with the standard library's `f64` parser (exact, and the
//! Eisel-Lemire algorithm that `fast-float` implements), accepting what Python's
//! `float()` accepts for ASCII digits, `_` between digits included. OBJ tokens split where
//! Python's `str.split()` splits, Unicode spaces included.
//!
//! Floats are written with their shortest round-trip digits (`ryu`) laid out as Python's
//! `repr` (`0.0001`, `1e-05`, `1e+16`, `1.0`), so a file reads back to the same float64
//! values and is byte for byte what the Python writer (`%r`) produced.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2};
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

create_exception!(
    _core,
    MeshFormatError,
    PyValueError,
    "A mesh file that cannot be read; args are (message, 1-based line or None)."
);

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
