//! The hash that names a decoded frame's exact values: `dynmesh decode --hash` prints it and
//! the conformance manifest (`tests/vectors`) lists it, so every decoder can check its
//! output against the reference bit for bit.

use sha2::{Digest, Sha256};

use dynmesh::Mesh;

/// The lowercase hex SHA-256 of `mesh`'s positions as little-endian float64, then its faces
/// as little-endian uint32: `dynmesh.conformance.frame_hash`.
pub fn frame_hash(mesh: &Mesh) -> String {
    let mut h = Sha256::new();
    mesh.positions.iter().flatten().for_each(|x| h.update(x.to_le_bytes()));
    mesh.faces.iter().flatten().for_each(|i| h.update(i.to_le_bytes()));
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}
