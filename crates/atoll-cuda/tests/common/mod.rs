//! Shared by the GPU tests (`tests/gpu_*.rs`): open GPU 0 or skip.
//!
//! Without a usable GPU a test prints why and returns, so `cargo test`
//! passes on machines without one; `ATOLL_REQUIRE_GPU=1` (scripts/gpu-check
//! sets it) turns the skip into a failure.

#![allow(dead_code)]

use std::sync::Arc;

use atoll_cuda::Gpu;

/// GPU 0, or `None` after printing why the test is skipped.
pub fn gpu_or_skip(test: &str) -> Option<Arc<Gpu>> {
    match Gpu::open(0) {
        Ok(gpu) => Some(gpu),
        Err(e) => {
            if std::env::var("ATOLL_REQUIRE_GPU").is_ok_and(|v| v == "1") {
                panic!("{test}: ATOLL_REQUIRE_GPU=1 but no usable GPU: {e}");
            }
            eprintln!("{test}: skipped, no usable GPU ({e})");
            None
        }
    }
}
