//! cargo fuzz target: see `dynmesh::fuzzing::refresh` for the input layout and the checks.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| dynmesh::fuzzing::refresh(data));
