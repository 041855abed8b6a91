//! cargo fuzz target: see `dynmesh::fuzzing::coef` for the input layout and the checks.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| dynmesh::fuzzing::coef(data));
