//! Bakes libtorch's lib directory into the trainer's test binaries as an rpath (shared
//! with the worker: `build-support/libtorch_rpath.rs`).
include!("../build-support/libtorch_rpath.rs");
