//! Polygons of either reader made triangles: OBJ and PLY faces may have any number of
//! corners, the codec takes triangles.

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

/// The note a reader hands back when it triangulated polygons, so that the user learns
/// the file was not all triangles.
pub(crate) fn polygon_note(sizes: &[usize], notes: &mut Vec<String>) {
    let polygons = sizes.iter().filter(|&&s| s > 3).count();
    if polygons > 0 {
        notes.push(format!("triangulated {polygons} polygon(s) with more than 3 corners"));
    }
}
