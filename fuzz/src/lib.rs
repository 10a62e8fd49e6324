//! Fuzz targets of psr (issue 19), one module each, each with a `run(data: &[u8])` that
//! libFuzzer calls (`fuzz_targets/`, `scripts/fuzz.sh`) and that `tests/replay.rs` calls on
//! every file of the committed corpora (`corpus/<target>/`), so past findings stay fixed.
//!
//! A target fails by panicking (or by a sanitizer report): every check below is an assertion
//! about what the library promises for *any* input, never about particular values.
//!
//! * [`ply_reader`]: arbitrary bytes through every reader (PLY ASCII and both binary byte
//!   orders, PoissonRecon's ASCII and binary points, PLY meshes): an error or well-formed
//!   arrays.
//! * [`c_api`]: fuzzer-chosen sequences of C API calls on up to a few live handles, with
//!   arbitrary parameters, strides, struct sizes, buffer capacities and null pointers: no call
//!   reports an internal error (a caught panic), every handle stays usable, every mesh is
//!   closed, nothing leaks.
//! * [`reconstruct`]: small fuzzer-made clouds (duplicates, lines, planes, huge and tiny
//!   coordinates, zero and unnormalised normals, no normals) with random parameters through the
//!   Rust API: an error or a closed, consistently oriented mesh with finite vertices.

pub mod c_api;
pub mod mesh_check;
pub mod ply_reader;
pub mod reconstruct;
