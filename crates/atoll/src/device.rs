//! `--device` and `--device-memory`: which device renders, and its budget.
//!
//! `auto` (the default) takes the first CUDA GPU when a driver, a GPU and
//! NVRTC are all there, else the CPU, and says on stderr which and why.
//! Naming `cuda` on a machine without them is an error (exit 1), never a panic.

use atoll_cuda::device::CudaDevice;
use atoll_cuda::error::{fmt_bytes, CudaError};
use atoll_render::{CpuDevice, Device};
use clap::Args;

use crate::CliError;

/// Which device to render on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DeviceChoice {
    /// CUDA GPU 0 when usable, else the CPU.
    #[default]
    Auto,
    Cpu,
    /// CUDA GPU with this ordinal (`cuda` is `cuda:0`).
    Cuda(usize),
    /// Under `--mpi`, the GPU of this rank's place among the ranks of its
    /// node (`cuda:local`): node rank r takes GPU r mod the GPUs there.
    CudaLocal,
}

/// Parses `auto`, `cpu`, `cuda`, `cuda:N` or `cuda:local`.
pub fn parse_device(s: &str) -> Result<DeviceChoice, String> {
    match s.trim().to_ascii_lowercase().as_str() {
        "auto" => Ok(DeviceChoice::Auto),
        "cpu" => Ok(DeviceChoice::Cpu),
        "cuda" | "gpu" => Ok(DeviceChoice::Cuda(0)),
        "cuda:local" => Ok(DeviceChoice::CudaLocal),
        other => other
            .strip_prefix("cuda:")
            .and_then(|n| n.parse().ok())
            .map(DeviceChoice::Cuda)
            .ok_or_else(|| format!("{s:?}: expected auto, cpu, cuda, cuda:N or cuda:local")),
    }
}

/// Parses a byte size: a number with an optional binary unit (`K`, `M`,
/// `G`, `T`, also written `KiB`/`KB`, …): `8G`, `512M`, `1.5G`, `4096`.
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number.parse().map_err(|_| format!("{s:?}: expected a size such as 8G or 512M"))?;
    let shift = match unit.trim().to_ascii_uppercase().trim_end_matches("IB").trim_end_matches('B') {
        "" => 0,
        "K" => 10,
        "M" => 20,
        "G" => 30,
        "T" => 40,
        _ => return Err(format!("{s:?}: unknown unit {unit:?} (use K, M, G or T)")),
    };
    let bytes = value * (1u64 << shift) as f64;
    if !(1.0..=u64::MAX as f64).contains(&bytes) {
        return Err(format!("{s:?}: size must be at least 1 byte"));
    }
    Ok(bytes as u64)
}

/// The device flags shared by `render` and `bench`.
#[derive(Args, Clone, Debug, Default)]
pub struct DeviceArgs {
    /// Device: auto (a CUDA GPU when one is usable, else the CPU), cpu,
    /// cuda, cuda:N, or with --mpi cuda:local (one GPU per rank of a node:
    /// its r-th rank takes GPU r mod the GPUs there; what auto takes under
    /// --mpi too).
    #[arg(long, default_value = "auto", value_parser = parse_device)]
    pub device: DeviceChoice,
    /// Memory budget of the device, e.g. 8G or 512M (default: what the device has).
    #[arg(long, value_parser = parse_size, value_name = "SIZE")]
    pub device_memory: Option<u64>,
    /// This process's place among the processes of its node (`--mpi`
    /// sets it; 0 otherwise): which GPU `auto` and `cuda:local` take.
    #[arg(skip)]
    pub local_rank: usize,
}

/// The device to render on, with what to tell the user about it.
pub struct Selected {
    pub device: Box<dyn Device>,
    /// e.g. `cuda:0 (NVIDIA H200, 139.8 GiB)` or `cpu (16 threads)`.
    pub description: String,
    /// The GPU behind a CUDA device (benchmarks use it directly).
    pub gpu: Option<std::sync::Arc<atoll_cuda::Gpu>>,
}

fn cpu(args: &DeviceArgs, threads: Option<usize>) -> Result<Selected, CliError> {
    let mut device = CpuDevice::new();
    if let Some(threads) = threads {
        device = device.with_threads(threads.max(1)).map_err(|e| CliError::Runtime(e.to_string()))?;
    }
    if let Some(bytes) = args.device_memory {
        device = device.with_memory_budget(bytes);
    }
    let description = format!("cpu ({} threads)", device.threads());
    Ok(Selected { device: Box::new(device), description, gpu: None })
}

fn cuda(args: &DeviceArgs, ordinal: usize) -> Result<Selected, CudaError> {
    let mut device = CudaDevice::new(ordinal)?;
    if let Some(bytes) = args.device_memory {
        device = device.with_memory_budget(bytes);
    }
    let gpu = device.gpu();
    let description = format!("{} ({}, {})", gpu.label(), gpu.name, fmt_bytes(gpu.total_memory));
    let gpu = Some(gpu.clone());
    Ok(Selected { device: Box::new(device), description, gpu })
}

/// The device `args` ask for; `threads` applies to the CPU device only.
pub fn select(args: &DeviceArgs, threads: Option<usize>) -> Result<Selected, CliError> {
    match args.device {
        DeviceChoice::Cpu => cpu(args, threads),
        DeviceChoice::Cuda(ordinal) => {
            if threads.is_some() {
                eprintln!("note: --threads applies to the CPU device only");
            }
            cuda(args, ordinal).map_err(|e| CliError::Runtime(e.to_string()))
        }
        DeviceChoice::CudaLocal => local_gpu(args)
            .and_then(|ordinal| cuda(args, ordinal))
            .map_err(|e| CliError::Runtime(format!("cuda:local: {e}"))),
        DeviceChoice::Auto => match local_gpu(args).and_then(|ordinal| cuda(args, ordinal)) {
            Ok(selected) => {
                eprintln!("device: {} (auto: CUDA driver and GPU found)", selected.description);
                Ok(selected)
            }
            Err(reason) => {
                let selected = cpu(args, threads)?;
                eprintln!("device: {} (auto: {})", selected.description, short_reason(&reason));
                Ok(selected)
            }
        },
    }
}

/// The GPU of this process's place on its node ([`DeviceArgs::local_rank`]).
fn local_gpu(args: &DeviceArgs) -> Result<usize, CudaError> {
    match atoll_cuda::gpu::device_count()? {
        0 => Err(CudaError::NoGpu),
        gpus => Ok(args.local_rank % gpus),
    }
}

/// Why `auto` fell back to the CPU, in a few words.
fn short_reason(e: &CudaError) -> String {
    match e {
        CudaError::NoDriver => "no CUDA driver (libcuda.so.1) found".into(),
        CudaError::NoNvrtc => "CUDA driver found but no NVRTC library (libnvrtc.so.13)".into(),
        CudaError::NoGpu => "CUDA driver found but no GPU".into(),
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_names() {
        assert_eq!(parse_device("auto"), Ok(DeviceChoice::Auto));
        assert_eq!(parse_device("CPU"), Ok(DeviceChoice::Cpu));
        assert_eq!(parse_device("cuda"), Ok(DeviceChoice::Cuda(0)));
        assert_eq!(parse_device("cuda:3"), Ok(DeviceChoice::Cuda(3)));
        assert_eq!(parse_device("cuda:Local"), Ok(DeviceChoice::CudaLocal));
        assert!(parse_device("cuda:x").is_err());
        assert!(parse_device("metal").is_err());
    }

    #[test]
    fn sizes() {
        assert_eq!(parse_size("8G"), Ok(8 << 30));
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("512MiB"), Ok(512 << 20));
        assert_eq!(parse_size("64kb"), Ok(64 << 10));
        assert_eq!(parse_size("1.5G"), Ok(3 << 29));
        assert_eq!(parse_size("4096"), Ok(4096));
        assert!(parse_size("0").is_err());
        assert!(parse_size("12X").is_err());
        assert!(parse_size("G").is_err());
    }

    #[test]
    fn auto_without_a_driver_picks_the_cpu() {
        if atoll_cuda::error::driver_present() {
            return;
        }
        let selected = select(&DeviceArgs::default(), Some(1)).unwrap();
        assert!(selected.description.starts_with("cpu"), "{}", selected.description);
        for device in [DeviceChoice::Cuda(0), DeviceChoice::CudaLocal] {
            let cuda = DeviceArgs { device, ..Default::default() };
            match select(&cuda, None) {
                Err(CliError::Runtime(message)) => assert!(message.contains("no CUDA driver"), "{message}"),
                _ => panic!("{device:?} without a driver must be an error"),
            }
        }
    }
}
