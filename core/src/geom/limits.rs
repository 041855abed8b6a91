//! The inputs the encoder accepts: bounds that keep its time and memory near-linear and
//! within a few gigabytes on any frame, each refused with a message that says which.
//!
//! Memory: the encoder holds about 2 KB per input face (a 510,720-face sphere peaked at
//! 1.06 GB), so [`MAX_INPUT_FACES`] keeps a frame under about 2.5 GB. Time: quadric
//! decimation re-keys every edge around the surviving vertex of each collapse, so its cost
//! grows with the sum of squared vertex valences; a fan of 30,000 faces around one vertex
//! took minutes. [`MAX_VALENCE_SQUARES_PER_FACE`] allows every real mesh (about 18 per face
//! for valence 6, and the poles of a UV sphere) and refuses such fans.

use crate::error::InputError;
use crate::geom::mesh::Mesh;

/// Most vertices of an input frame, before coincident ones are merged.
pub const MAX_INPUT_VERTICES: usize = 1 << 22;
/// Most faces of an input frame.
pub const MAX_INPUT_FACES: usize = 1 << 20;
/// The sum over vertices of their valence squared may be at most this many per face, plus
/// [`VALENCE_SQUARES_FLOOR`].
pub const MAX_VALENCE_SQUARES_PER_FACE: u64 = 64;
pub const VALENCE_SQUARES_FLOOR: u64 = 1 << 22;

/// Refuses a frame beyond the size limits (checked before any work on it).
pub fn check_size(mesh: &Mesh) -> Result<(), InputError> {
    if mesh.positions.len() > MAX_INPUT_VERTICES {
        return Err(InputError(format!("{} vertices exceed the limit of {MAX_INPUT_VERTICES} per frame", mesh.positions.len())));
    }
    if mesh.faces.len() > MAX_INPUT_FACES {
        return Err(InputError(format!("{} faces exceed the limit of {MAX_INPUT_FACES} per frame", mesh.faces.len())));
    }
    Ok(())
}

/// Refuses a (welded) frame whose faces crowd around a few vertices.
pub fn check_valence(mesh: &Mesh) -> Result<(), InputError> {
    let mut valence = vec![0u64; mesh.positions.len()];
    for &v in mesh.faces.iter().flatten() {
        valence[v as usize] += 1;
    }
    let squares: u64 = valence.iter().map(|d| d * d).sum();
    let allowed = MAX_VALENCE_SQUARES_PER_FACE * mesh.faces.len() as u64 + VALENCE_SQUARES_FLOOR;
    if squares > allowed {
        let (v, most) = valence.iter().enumerate().max_by_key(|&(_, d)| *d).expect("a mesh with faces");
        return Err(InputError(format!(
            "too many faces share a few vertices (vertex {v} is in {most} faces; the sum of squared vertex valences, \
             {squares}, exceeds the limit of {MAX_VALENCE_SQUARES_PER_FACE} per face + {VALENCE_SQUARES_FLOOR})"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fan_around_one_vertex_is_refused_and_a_grid_is_not() {
        let n = 5000u32;
        let fan = Mesh::new((0..n + 2).map(|i| [i as f64, (i % 2) as f64, 0.0]).collect(), (0..n).map(|i| [0, i + 1, i + 2]).collect());
        let e = check_valence(&fan).unwrap_err();
        assert!(e.0.contains("vertex 0 is in 5000 faces"), "{}", e.0);
        let k = 200u32;
        let grid = Mesh::new(
            (0..k * k).map(|i| [(i % k) as f64, (i / k) as f64, 0.0]).collect(),
            (0..(k - 1) * (k - 1)).flat_map(|c| {
                let v = c / (k - 1) * k + c % (k - 1);
                [[v, v + 1, v + k + 1], [v, v + k + 1, v + k]]
            }).collect(),
        );
        assert!(check_valence(&grid).is_ok());
    }

    #[test]
    fn sizes_beyond_the_limits_are_refused_naming_the_limit() {
        let m = Mesh::new(vec![[0.0; 3]; MAX_INPUT_VERTICES + 1], vec![[0, 1, 2]]);
        assert!(check_size(&m).unwrap_err().0.contains(&MAX_INPUT_VERTICES.to_string()));
        let m = Mesh::new(vec![[0.0; 3]; 3], vec![[0, 1, 2]; MAX_INPUT_FACES + 1]);
        assert!(check_size(&m).unwrap_err().0.contains("faces exceed"));
    }
}
