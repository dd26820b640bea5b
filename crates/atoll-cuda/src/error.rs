//! The crate's one error type. Every failure of the CUDA stack (missing
//! libraries, no GPU, driver calls, kernel compilation, memory) becomes a
//! [`CudaError`] with enough context to act on; nothing here panics.
//!
//! cudarc loads `libcuda` and `libnvrtc` lazily and *panics* when they are
//! missing, so every entry point checks [`driver_present`] /
//! [`nvrtc_present`] before the first call into them.

use cudarc::driver::DriverError;
use cudarc::nvrtc::result::NvrtcError;

/// Everything that can go wrong on the CUDA side.
#[derive(Debug, thiserror::Error)]
pub enum CudaError {
    #[error("no CUDA driver (libcuda.so.1) found: install the NVIDIA driver or use --device cpu")]
    NoDriver,
    #[error(
        "no NVRTC library (libnvrtc.so.13) found: install the CUDA 13 toolkit or add its lib64 \
         directory to LD_LIBRARY_PATH"
    )]
    NoNvrtc,
    #[error("no CUDA GPU found (the driver reports none)")]
    NoGpu,
    #[error("CUDA GPU {ordinal} does not exist: this machine has {count} (cuda:0 .. cuda:{last})", last = count.saturating_sub(1))]
    BadOrdinal { ordinal: usize, count: usize },
    /// A driver call failed; `context` says what was being done.
    #[error("{context}: {source}")]
    Driver {
        context: String,
        #[source]
        source: DriverError,
    },
    #[error("kernel file {file:?} is not in the kernel registry (compile::KERNEL_FILES)")]
    UnknownKernelFile { file: String },
    #[error("{file}: #include \"{include}\" names no file of the kernel registry")]
    MissingInclude { file: String, include: String },
    /// NVRTC rejected a kernel file; `log` is its full diagnostic output.
    #[error("compiling {file} with NVRTC failed ({nvrtc:?}):\n{log}")]
    Compile { file: String, nvrtc: NvrtcError, log: String },
    /// The device cannot hold what was asked of it; detected before allocating.
    #[error(
        "{device}: needs {} but only {} is available (memory budget {}, free on the GPU {}); {what}",
        fmt_bytes(*needed), fmt_bytes(*budget.min(free)), fmt_bytes(*budget), fmt_bytes(*free)
    )]
    OutOfMemory { device: String, what: String, needed: u64, budget: u64, free: u64 },
    /// A GPU would map another's memory (a chunk window) but the hardware
    /// gives it no direct (peer) access: the caller falls back to a
    /// strategy that needs none.
    #[error("{reader} has no peer access to {owner}: it cannot read chunks that {owner} holds")]
    NoPeerAccess { reader: String, owner: String },
    /// A device used in a way its API does not allow (e.g. a stage before `prepare`).
    #[error("{0}")]
    Usage(String),
}

impl CudaError {
    /// Wraps a driver error with what was being done.
    pub(crate) fn driver(context: impl Into<String>) -> impl FnOnce(DriverError) -> CudaError {
        let context = context.into();
        move |source| CudaError::Driver { context, source }
    }
}

/// Bytes in a human unit (`1.50 GiB`), for messages.
pub fn fmt_bytes(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.2} {}", UNITS[unit])
    }
}

/// Whether the CUDA driver library can be loaded. Calling any driver
/// function without it makes cudarc panic.
pub fn driver_present() -> bool {
    // SAFETY: only tries `dlopen` on cudarc's candidate names; no symbol is called.
    unsafe { cudarc::driver::sys::is_culib_present() }
}

/// Whether NVRTC can be loaded (see [`driver_present`] for why this matters).
pub fn nvrtc_present() -> bool {
    // SAFETY: as in `driver_present`.
    unsafe { cudarc::nvrtc::sys::is_culib_present() }
}

/// `Err(NoDriver)` unless the driver library loads.
pub(crate) fn require_driver() -> Result<(), CudaError> {
    if driver_present() {
        Ok(())
    } else {
        Err(CudaError::NoDriver)
    }
}

/// `Err(NoNvrtc)` unless NVRTC loads.
pub(crate) fn require_nvrtc() -> Result<(), CudaError> {
    if nvrtc_present() {
        Ok(())
    } else {
        Err(CudaError::NoNvrtc)
    }
}

impl CudaError {
    /// The render crate's error for device `device` (memory errors keep their numbers).
    pub(crate) fn into_device_error(self, device: &str) -> atoll_render::DeviceError {
        match self {
            CudaError::OutOfMemory { needed, budget, free, .. } => atoll_render::DeviceError::OutOfMemory {
                device: device.to_string(),
                needed,
                budget: budget.min(free),
            },
            other => atoll_render::DeviceError::Backend {
                device: device.to_string(),
                what: other.to_string(),
                source: Box::new(other),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_are_actionable() {
        assert!(CudaError::NoDriver.to_string().contains("libcuda.so.1"));
        let e = CudaError::BadOrdinal { ordinal: 3, count: 2 };
        assert_eq!(e.to_string(), "CUDA GPU 3 does not exist: this machine has 2 (cuda:0 .. cuda:1)");
        let e = CudaError::OutOfMemory {
            device: "cuda:0".into(),
            what: "scene tables 1.00 GiB".into(),
            needed: 3 << 30,
            budget: 2 << 30,
            free: 70 << 30,
        };
        let text = e.to_string();
        assert!(text.contains("needs 3.00 GiB") && text.contains("only 2.00 GiB"), "{text}");
    }

    #[test]
    fn byte_units() {
        assert_eq!(fmt_bytes(12), "12 B");
        assert_eq!(fmt_bytes(1536), "1.50 KiB");
        assert_eq!(fmt_bytes(8 << 30), "8.00 GiB");
    }
}
