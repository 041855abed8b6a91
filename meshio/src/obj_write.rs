//! OBJ lines written as the former Python writer wrote them (`%r` floats, 1-based indices),
//! byte for byte: `dynmesh.io` writes the header and material lines, these the rows.

use crate::blocks::{push_int, text_blocks};
use crate::python_repr::push_f64;

/// One line per row of `flat` (rows of `width` floats; a width of 0 gives no line): `prefix`
/// (if not empty), then the row's floats as Python's repr (shortest round trip),
/// space-separated: `v 0.1 -2.0 1e-05`. Returns the text in blocks to be laid end to end.
pub fn format_rows(flat: &[f64], width: usize, prefix: &str) -> Vec<Vec<u8>> {
    let rows = flat.len().checked_div(width).unwrap_or(0);
    text_blocks(rows, |lo, hi, out| push_rows(out, flat, width, prefix, lo, hi))
}

/// OBJ face lines of 0-based triangles `faces` (3 indices per face): `f 1 2 3`, or
/// `f 1/1 2/2 3/3` with `uv_faces` (3 per face as well). Returns the text in blocks to be
/// laid end to end.
///
/// Errors: `uv_faces` of another length than `faces`.
pub fn format_obj_faces<I: Copy + Into<i64> + Sync>(faces: &[I], uv_faces: Option<&[I]>) -> Result<Vec<Vec<u8>>, &'static str> {
    if uv_faces.is_some_and(|u| u.len() != faces.len()) {
        return Err("uv_faces and faces differ in shape");
    }
    Ok(text_blocks(faces.len() / 3, |lo, hi, out| push_obj_faces(out, faces, uv_faces, lo, hi)))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_and_faces_are_written_as_python_wrote_them() {
        assert_eq!(format_rows(&[0.1, -2.0, 1e-5, 3.0, 0.0, 1e16], 3, "v").concat(), b"v 0.1 -2.0 1e-05\nv 3.0 0.0 1e+16\n");
        assert_eq!(format_rows(&[0.5, 0.25], 2, "").concat(), b"0.5 0.25\n");
        assert_eq!(format_obj_faces(&[0i64, 1, 2], Some(&[2, 1, 0])).unwrap().concat(), b"f 1/3 2/2 3/1\n");
        assert_eq!(format_obj_faces(&[0i64, 1, 2], Some(&[])).err(), Some("uv_faces and faces differ in shape"));
    }
}
