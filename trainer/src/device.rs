//! The training device and libtorch's threads.

use crate::{Error, Result};

/// Parses `cpu`, `cuda` or `cuda:N`; refuses CUDA where libtorch sees no GPU.
pub fn parse_device(s: &str) -> Result<tch::Device> {
    let dev = match s {
        "cpu" => tch::Device::Cpu,
        "cuda" => tch::Device::Cuda(0),
        _ => match s.strip_prefix("cuda:").and_then(|n| n.parse().ok()) {
            Some(n) => tch::Device::Cuda(n),
            None => {
                return Err(Error::Config(format!(
                    "unknown device {s:?} (cpu, cuda, cuda:N)"
                )))
            }
        },
    };
    if let tch::Device::Cuda(n) = dev {
        let have = tch::Cuda::device_count();
        if n as i64 >= have {
            return Err(Error::Config(format!(
                "device {s} requested but libtorch sees {have} CUDA devices"
            )));
        }
    }
    Ok(dev)
}

/// libtorch threads when none are asked for. One: the simulation's rayon threads run
/// between the learner's calls, and OpenMP barriers with as many threads as cores collapse
/// as soon as anything else runs (measured 1.0 s vs 6.5 s per epoch, BENCHMARKS.md).
pub const DEFAULT_TORCH_THREADS: usize = 1;

/// Sets libtorch's intra-op threads (default [`DEFAULT_TORCH_THREADS`]).
pub fn configure_threads(threads: Option<usize>) {
    tch::set_num_threads(threads.unwrap_or(DEFAULT_TORCH_THREADS).max(1) as i32);
}
