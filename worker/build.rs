//! Bakes libtorch's lib directory into the worker's binaries and tests as an rpath: link
//! arguments do not pass from the trainer's build script to its dependents
//! (`build-support/libtorch_rpath.rs`).
include!("../build-support/libtorch_rpath.rs");
