//! The OBJ reader: positions, per-corner UV indices kept apart from the position indices,
//! polygons fan-triangulated, `mtllib`/`usemtl` arguments handed back for the caller to
//! resolve (material libraries and texture paths are file-system work, `dynmesh.io`'s).
//!
//! Hand-written rather than `tobj`: `tobj` keeps separate position and UV index lists
//! (`single_index: false`) and triangulates, but its `LoadError` is a fieldless enum, no
//! line and no token, where these errors name both. The reader also keeps what
//! `python/dynmesh/io/meshio.py` and the tests pin: negative indices (relative to the lines
//! above), `v`, `v/vt`, `v//vn` and `v/vt/vn` corners mixed in one file, UVs dropped with a
//! note when only some corners have one, `\` continuing a line (except a comment), `#`
//! comments anywhere, extra vertex values (colours) ignored.
//!
//! Files over 1 MB are parsed in pieces on the rayon pool; the result, line numbers and
//! first error included, is what one pass gives.

use std::borrow::Cow;

use rayon::prelude::*;

use crate::error::{at_line, whole_file, FormatError, Result};
use crate::polygons::polygon_note;
use crate::python_repr::{floats_text, repr};
use crate::tokens::{is_space, parse_f64, parse_i64, scan_int, tokens, trim, Tokens};

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

/// A mesh read from an OBJ file.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjMesh {
    /// Positions, 3 per vertex.
    pub positions: Vec<f64>,
    /// Triangles of 0-based indices into `positions` (3 per face), polygons fan-triangulated.
    pub faces: Vec<i64>,
    /// UVs (2 per entry) and their triangles (3 indices per face, face for face with
    /// `faces`), when every face corner has a UV.
    pub uv: Option<(Vec<f64>, Vec<i64>)>,
    /// The arguments of the `mtllib` lines, in order.
    pub mtllibs: Vec<String>,
    /// The `usemtl` names, in order of first use.
    pub materials: Vec<String>,
    /// What the reader changed for the user to hear of (UVs dropped, polygons triangulated).
    pub notes: Vec<String>,
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
        objs.push((part.map_err(|e| FormatError { line: e.line.map(|l| l + lines_before), ..e })?, lines_before));
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

/// Reads an OBJ file's bytes (UTF-8 with an optional BOM; invalid bytes read as Python's
/// `errors="replace"` reads them). Polygons are fan-triangulated; UVs are kept only when
/// every corner has one.
///
/// Errors: the first malformed line (a bad number, index or corner, a face of fewer than 3
/// corners, an index out of range), a non-finite coordinate, or a file without faces.
pub fn read_obj(data: &[u8]) -> Result<ObjMesh> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangle_with_uvs_keeps_its_own_uv_indices() {
        let text = b"mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvt 0.5 0.5\nusemtl skin\nf 1/4 2/2 3/3\n";
        let m = read_obj(text).unwrap();
        assert_eq!(m.positions, [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
        assert_eq!(m.faces, [0, 1, 2]);
        let (uvs, uv_faces) = m.uv.unwrap();
        assert_eq!(uvs, [0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.5, 0.5]);
        assert_eq!(uv_faces, [3, 1, 2]);
        assert_eq!((m.mtllibs, m.materials), (vec!["a.mtl".to_string()], vec!["skin".to_string()]));
        assert!(m.notes.is_empty());
    }

    #[test]
    fn quad_is_fanned_and_relative_indices_resolve() {
        let m = read_obj(b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf -4 -3 -2 -1\n").unwrap();
        assert_eq!(m.faces, [0, 1, 2, 0, 2, 3]);
        assert_eq!(m.uv, None);
        assert_eq!(m.notes, ["triangulated 1 polygon(s) with more than 3 corners"]);
    }

    #[test]
    fn malformed_faces_name_their_line_and_token() {
        let e = read_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\n# a comment\nf 1 x 3\n").unwrap_err();
        assert_eq!(e, FormatError { message: "bad index 'x'".into(), line: Some(5) });
        let e = read_obj(b"v 0 0 0\nf 1 1\n").unwrap_err();
        assert_eq!(e, FormatError { message: "face needs at least 3 corners, found 2".into(), line: Some(2) });
        let e = read_obj(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").unwrap_err();
        assert_eq!(e, FormatError { message: "vertex index 4 is out of range (1..3 or -1..-3)".into(), line: Some(4) });
        assert_eq!(read_obj(b"v 0 0 0\n").unwrap_err(), FormatError { message: "no faces".into(), line: None });
    }
}
