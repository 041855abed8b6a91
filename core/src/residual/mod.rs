//! The residual of every frame: the base mesh is subdivided ([`subdivide`]), each subdivided
//! vertex is fitted to the input along its local frame ([`displace`]), the displacements go
//! through the lifting wavelet ([`transform`]), are quantized per level of detail
//! ([`quantize`]) and entropy coded ([`coefcoder`]).

pub mod subdivide;
pub mod displace;
pub mod transform;
pub mod quantize;
pub mod coefcoder;
