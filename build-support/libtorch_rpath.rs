// Makes the trainer's tests and the worker's binaries and tests find libtorch at run time
// (`trainer/build.rs` and `worker/build.rs` include this file, so plain comments) without any environment
// variable: asks the same python that tch's build asks (the torch==2.13.0 venv that
// `scripts/setup.sh` installs) for libtorch's lib directory and bakes it in as an rpath.
// It also forces `libtorch_cuda` to be linked even though no symbol of it is referenced,
// because otherwise `--as-needed` drops it and `Device::Cuda` never becomes available.
//
// This file is self-contained on purpose: another crate that links tch (tests, coordinator)
// can copy it verbatim as its own `build.rs`.

use std::env;
use std::path::{Path, PathBuf};
use std::process::Command;

const PRINT_LIB_DIR: &str =
    "import torch, os; print(os.path.join(os.path.dirname(torch.__file__), 'lib'))";

fn main() {
    for var in [
        "LIBTORCH",
        "LIBTORCH_USE_PYTORCH",
        "VIRTUAL_ENV",
        "PATH",
        "GAITSWEEP_CACHE",
    ] {
        println!("cargo:rerun-if-env-changed={var}");
    }
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=../build-support/libtorch_rpath.rs");
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("linux") {
        return;
    }
    let lib_dir = match libtorch_lib_dir() {
        Some(dir) => dir,
        None => panic!(
            "libtorch not found: run `source scripts/setup.sh` (installs torch==2.13.0 into \
             ~/.cache/gaitsweep/venv once and exports LIBTORCH_USE_PYTORCH=1), then build again"
        ),
    };
    println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib_dir.display());
    if lib_dir.join("libtorch_cuda.so").exists() {
        println!("cargo:rustc-link-search=native={}", lib_dir.display());
        println!("cargo:rustc-link-arg=-Wl,--no-as-needed");
        println!("cargo:rustc-link-arg=-ltorch_cuda");
        println!("cargo:rustc-link-arg=-Wl,--as-needed");
    }
}

/// The lib directory of the libtorch that tch links: `$LIBTORCH/lib` when set, otherwise the
/// torch package of the active python (tch's rule: `python` inside a venv, else `python3`),
/// otherwise the project's cached venv.
fn libtorch_lib_dir() -> Option<PathBuf> {
    if let Ok(root) = env::var("LIBTORCH") {
        let dir = Path::new(&root).join("lib");
        if dir.join("libtorch_cpu.so").exists() {
            return Some(dir);
        }
    }
    let active = if env::var_os("VIRTUAL_ENV").is_some() {
        "python"
    } else {
        "python3"
    };
    let cache = env::var_os("GAITSWEEP_CACHE")
        .map(PathBuf::from)
        .or_else(|| env::var_os("HOME").map(|h| Path::new(&h).join(".cache/gaitsweep")));
    let mut candidates = vec![PathBuf::from(active)];
    if let Some(cache) = cache {
        candidates.push(cache.join("venv/bin/python"));
    }
    candidates.into_iter().find_map(|python| {
        let out = Command::new(&python)
            .arg("-c")
            .arg(PRINT_LIB_DIR)
            .output()
            .ok()?;
        if !out.status.success() {
            return None;
        }
        let dir = PathBuf::from(String::from_utf8_lossy(&out.stdout).trim());
        dir.join("libtorch_cpu.so").exists().then_some(dir)
    })
}
