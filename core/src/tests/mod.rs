//! Tests of whole streams that reach into the stages (once integration tests in `core/tests`):
//! the conformance vectors, damaged streams, and streams crafted past the CRC.

mod conformance;
mod damaged;
mod hostile;
