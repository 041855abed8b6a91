//! Kernels the benchmark examples time (`core/examples/kernel_timings.rs`,
//! `library_comparison.rs`), behind the cargo feature `internals`: not part of the API, and
//! free to change with the stages they come from.

pub use crate::base::decimate::decimate;
pub use crate::base::refit::refit_base;
pub use crate::geom::bvh::Bvh;
pub use crate::geom::mesh::{self, normalize, scale};
pub use crate::residual::displace::{fit_displacements, local_frames};
pub use crate::residual::subdivide::{subdivide, Scheme};
