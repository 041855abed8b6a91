//! The PLY reader: ASCII and binary little and big endian, any scalar type, ragged list
//! properties, extra elements, ASCII errors by line, binary ones by record, truncation
//! refused before allocating.
//!
//! Hand-written rather than `ply-rs`, which builds a map per record by default: the reader
//! here is small enough to keep the exact messages of the former Python reader and their
//! precedence.

use rustc_hash::FxHashMap;

use crate::error::{at_line, whole_file, FormatError, Result};
use crate::polygons::{fan, polygon_note};
use crate::python_repr::{f64_text, push_python_layout, repr};
use crate::tokens::{is_space, parse_f64};

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

fn truncated(e: &Element) -> FormatError {
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
    let mut bad: Option<FormatError> = None;
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

/// The per-vertex UV property pairs, in the order they are looked for.
const UV_NAMES: [(&str, &str); 4] = [("u", "v"), ("s", "t"), ("texture_u", "texture_v"), ("texture_s", "texture_t")];

/// A mesh read from a PLY file.
#[derive(Debug, Clone, PartialEq)]
pub struct PlyMesh {
    /// Positions, 3 per vertex.
    pub positions: Vec<f64>,
    /// Triangles of 0-based indices into `positions` (3 per face), polygons fan-triangulated.
    pub faces: Vec<i64>,
    /// UVs (2 per entry) and their triangles (3 indices per face, face for face with
    /// `faces`): the faces' per-corner `texcoord` lists, else per-vertex u,v (s,t,
    /// texture_u/v, texture_s/t) with triangles equal to `faces`.
    pub uv: Option<(Vec<f64>, Vec<i64>)>,
    /// The header's `comment` and `obj_info` lines, without their keyword.
    pub comments: Vec<String>,
    /// What the reader changed for the user to hear of (polygons triangulated).
    pub notes: Vec<String>,
}

/// Reads a PLY file's bytes (ASCII, binary little or big endian). The mesh is the last
/// `vertex` element's x, y, z and the last `face` element's `vertex_indices` (or
/// `vertex_index`) lists; other elements and properties are read and left.
///
/// Errors: a bad header line, a bad number or record length (ASCII, by line), a truncated
/// body, a missing vertex element or coordinate, a non-finite coordinate, a face of fewer
/// than 3 corners or an index out of range (ASCII by line, binary by record number), or no
/// faces.
pub fn read_ply(data: &[u8]) -> Result<PlyMesh> {
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
        return Err(FormatError { message: format!("{what} has a coordinate that is not finite"), line });
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
        return Err(FormatError { message: format!("{what} has fewer than 3 corners"), line });
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
        return Err(FormatError { message, line });
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

#[cfg(test)]
mod tests {
    use super::*;

    fn binary_triangle(indices: [i32; 3]) -> Vec<u8> {
        let mut data = b"ply\nformat binary_little_endian 1.0\ncomment made by hand\nelement vertex 3\n\
            property float x\nproperty float y\nproperty float z\nelement face 1\n\
            property list uchar int vertex_indices\nend_header\n"
            .to_vec();
        for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.5, 2.0]] {
            p.iter().for_each(|x| data.extend_from_slice(&x.to_le_bytes()));
        }
        data.push(3);
        indices.iter().for_each(|i| data.extend_from_slice(&i.to_le_bytes()));
        data
    }

    #[test]
    fn binary_little_endian_triangle() {
        let m = read_ply(&binary_triangle([0, 1, 2])).unwrap();
        assert_eq!(m.positions, [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.5, 2.0]);
        assert_eq!(m.faces, [0, 1, 2]);
        assert_eq!(m.uv, None);
        assert_eq!(m.comments, ["made by hand"]);
    }

    #[test]
    fn binary_errors_name_the_record() {
        let e = read_ply(&binary_triangle([0, 1, 3])).unwrap_err();
        assert_eq!(e, FormatError { message: "face 0: vertex index 3 is out of range (0..2)".into(), line: None });
        let mut short = binary_triangle([0, 1, 2]);
        short.truncate(short.len() - 2);
        let e = read_ply(&short).unwrap_err();
        assert_eq!(e.message, "truncated binary PLY: data ends inside element 'face' (1 records)");
    }

    #[test]
    fn ascii_per_vertex_uvs_and_errors_by_line() {
        let header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\n\
            property double s\nproperty double t\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
        let m = read_ply(format!("{header}0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n3 0 1 2\n").as_bytes()).unwrap();
        assert_eq!(m.uv, Some((vec![0.0, 0.0, 1.0, 0.0, 0.0, 1.0], vec![0, 1, 2])));
        let e = read_ply(format!("{header}0 0 0 0 0\n1 0 0 1 0\n0 1 0 0\n3 0 1 2\n").as_bytes()).unwrap_err();
        assert_eq!(e, FormatError { message: "'vertex' record has 4 values, expected 5".into(), line: Some(14) });
    }
}
