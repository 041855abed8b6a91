//! PLY bodies written as the former Python writer wrote them (ASCII rows with `%r` floats,
//! or binary little endian), and the header of a PLY of positions and faces alone (what a
//! decoded frame without UVs is).

use crate::blocks::{push_int, text_blocks};
use crate::python_repr::push_f64;

/// A PLY body to write: vertex rows of `width` doubles, triangles, and per face its
/// `texcoord` (6 doubles) when given, in ASCII or binary.
pub struct PlyBody<'a, I> {
    /// Vertex rows laid end to end, `width` doubles each.
    pub vertex: &'a [f64],
    /// Doubles per vertex row (x, y, z and any further properties the header declares).
    pub width: usize,
    /// 0-based triangles, 3 indices per face.
    pub faces: &'a [I],
    /// Per face, its corners' u, v (6 doubles), or None.
    pub texcoord: Option<&'a [f64]>,
    /// ASCII rows rather than binary little endian.
    pub ascii: bool,
}

/// The body of a PLY file after its header: vertex rows of doubles, then faces as `list
/// uchar int`, each followed by its `texcoord` as `list uchar double` when given. ASCII rows
/// use Python's float repr; binary is little endian. Returns the bytes in blocks to be laid
/// end to end.
///
/// Errors: `texcoord` without 6 doubles per face, or a face index that does not fit an i32.
pub fn ply_body<I: Copy + Into<i64> + Sync>(body: &PlyBody<'_, I>) -> Result<Vec<Vec<u8>>, &'static str> {
    if body.texcoord.is_some_and(|t| t.len() != 2 * body.faces.len()) {
        return Err("texcoord needs one row per face");
    }
    if body.faces.iter().any(|&i| i32::try_from(i.into()).is_err()) {
        return Err("a face index does not fit PLY int");
    }
    Ok(ply_rows(body))
}

/// [`ply_body`] of a body already checked.
pub(crate) fn ply_rows<I: Copy + Into<i64> + Sync>(body: &PlyBody<'_, I>) -> Vec<Vec<u8>> {
    let rows = body.vertex.len().checked_div(body.width).unwrap_or(0);
    // Rows 0..rows are vertices, rows..rows + nf faces.
    text_blocks(rows + body.faces.len() / 3, |lo, hi, out| push_ply_rows(out, body, lo, hi))
}

/// The header `dynmesh.io` writes for a binary PLY of `vertices` positions (doubles) and
/// `faces` triangles.
pub(crate) fn positions_header(vertices: usize, faces: usize) -> String {
    format!(
        "ply\nformat binary_little_endian 1.0\ncomment written by dynmesh\nelement vertex {vertices}\n\
         property double x\nproperty double y\nproperty double z\nelement face {faces}\n\
         property list uchar int vertex_indices\nend_header\n"
    )
}

/// Rows `lo..hi` of a PLY body: rows below the vertex count are vertex rows of `width`
/// doubles, the others faces as `list uchar int`, each followed by its `texcoord` (6
/// doubles) when given. ASCII rows use Python's float repr; binary is little endian. Face
/// indices must fit an i32.
fn push_ply_rows<I: Copy + Into<i64>>(out: &mut Vec<u8>, body: &PlyBody<'_, I>, lo: usize, hi: usize) {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bodies_read_back_and_bad_input_is_refused() {
        let vertex = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let faces = [0i64, 1, 2];
        let ascii = PlyBody { vertex: &vertex, width: 3, faces: &faces, texcoord: None, ascii: true };
        assert_eq!(ply_body(&ascii).unwrap().concat(), b"0.0 0.0 0.0\n1.0 0.0 0.0\n0.0 1.0 0.0\n3 0 1 2\n");
        let binary = PlyBody { ascii: false, ..ascii };
        let mut file = positions_header(3, 1).into_bytes();
        file.extend(ply_body(&binary).unwrap().concat());
        let m = crate::ply::read_ply(&file).unwrap();
        assert_eq!((m.positions, m.faces), (vertex.to_vec(), faces.to_vec()));
        let texcoord = [0.0; 5];
        assert_eq!(ply_body(&PlyBody { texcoord: Some(&texcoord), ..binary }).err(), Some("texcoord needs one row per face"));
        let big = [0i64, 1, 1 << 31];
        assert_eq!(ply_body(&PlyBody { faces: &big, ..binary }).err(), Some("a face index does not fit PLY int"));
    }
}
