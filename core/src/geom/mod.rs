//! Geometry kernels every stage shares: the [`mesh::Mesh`] value and its vector helpers, the
//! position [`grid`] (input units to grid units), welding of coincident positions, the input
//! [`limits`], the quadric error metric, counting-sort [`bins`], and the closest-point queries
//! of a triangle surface ([`bvh`] for single queries, [`closest`] for walks of nearby ones).

pub mod mesh;
pub mod bins;
pub mod weld;
pub mod limits;
pub mod grid;
pub mod quadric;
pub mod bvh;
pub mod closest;
#[cfg(test)]
pub(crate) mod testmesh;
