//! Every kernel file compiles with NVRTC (no GPU needed, only libnvrtc).
//!
//! Skipped with a message when NVRTC cannot be loaded, unless
//! `ATOLL_REQUIRE_NVRTC=1` (CI sets it: scripts/test.sh installs NVRTC),
//! which turns the skip into a failure.

use atoll_cuda::compile::{
    compilation_units, compile_source, compile_with_cache, splice, CompileOptions, Output, KERNEL_FILES,
};
use atoll_cuda::error::nvrtc_present;
use atoll_cuda::kernel_cache::KernelCache;
use atoll_cuda::CudaError;

/// Hopper (H100/H200): the GPUs atoll is measured on.
const ARCH: (u32, u32) = (9, 0);

fn nvrtc_or_skip(test: &str) -> bool {
    if nvrtc_present() {
        return true;
    }
    if std::env::var("ATOLL_REQUIRE_NVRTC").is_ok_and(|v| v == "1") {
        panic!("{test}: ATOLL_REQUIRE_NVRTC=1 but libnvrtc cannot be loaded (LD_LIBRARY_PATH?)");
    }
    eprintln!(
        "{test}: skipped, NVRTC not found (set LD_LIBRARY_PATH; ATOLL_REQUIRE_NVRTC=1 makes this fail)"
    );
    false
}

#[test]
fn every_kernel_file_compiles_to_ptx_for_compute_90() {
    if !nvrtc_or_skip("ptx") {
        return;
    }
    let mut failures = Vec::new();
    for file in compilation_units() {
        let mut options = CompileOptions::ptx(ARCH);
        options.extra.push(atoll_cuda::compile::LAYOUT_CHECK_OPTION.into());
        match compile_with_cache(file, &options, None) {
            Ok(compiled) => {
                let ptx = String::from_utf8(compiled.image).expect("PTX is text");
                assert!(ptx.contains(".target sm_90"), "{file}: unexpected PTX target");
                assert!(ptx.contains(".entry"), "{file}: no kernel entry point");
                if !compiled.log.trim().is_empty() {
                    eprintln!("{file}: NVRTC warnings:\n{}", compiled.log);
                }
            }
            Err(e) => failures.push(format!("{file}: {e}")),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// SASS for sm_90 with ptxas's register and spill report, printed per
/// kernel (`cargo test -p atoll-cuda --test nvrtc -- --nocapture`).
#[test]
fn every_kernel_file_compiles_to_sm_90_cubin_with_register_report() {
    if !nvrtc_or_skip("cubin") {
        return;
    }
    let mut failures = Vec::new();
    for file in compilation_units() {
        let mut options = CompileOptions::cubin(ARCH);
        options.extra.push("-Xptxas=-v".into());
        options.extra.push(atoll_cuda::compile::LAYOUT_CHECK_OPTION.into());
        match compile_with_cache(file, &options, None) {
            Ok(compiled) => {
                // ELF magic: machine code, not PTX.
                assert_eq!(&compiled.image[..4], b"\x7fELF", "{file}: not a CUBIN");
                for line in compiled
                    .log
                    .lines()
                    .filter(|l| l.contains("entry function") || l.contains("Used") || l.contains("spill"))
                {
                    println!("{file}: {}", line.trim());
                }
            }
            Err(e) => failures.push(format!("{file}: {e}")),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn every_header_is_included_by_some_unit() {
    // A header no .cu includes would never be compiled, hence never checked.
    let spliced: Vec<String> = compilation_units().map(|f| splice(f).unwrap()).collect();
    for (name, _) in KERNEL_FILES.iter().filter(|(n, _)| n.ends_with(".cuh")) {
        let marker = format!("#line 1 \"{name}\"");
        assert!(spliced.iter().any(|s| s.contains(&marker)), "{name} is included by no .cu file");
    }
}

#[test]
fn disk_cache_hits_on_the_second_compile() {
    if !nvrtc_or_skip("cache") {
        return;
    }
    let dir = std::env::temp_dir().join(format!("atoll-nvrtc-cache-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let cache = KernelCache::new(&dir);
    let options = CompileOptions::cubin(ARCH);
    let first = compile_with_cache("selftest.cu", &options, Some(&cache)).unwrap();
    assert!(!first.cached);
    let second = compile_with_cache("selftest.cu", &options, Some(&cache)).unwrap();
    assert!(second.cached);
    assert_eq!(first.image, second.image);
    // Other options: another entry.
    let ptx =
        compile_with_cache("selftest.cu", &CompileOptions { output: Output::Ptx, ..options }, Some(&cache));
    assert!(!ptx.unwrap().cached);
    // A corrupt entry is recompiled, not fatal.
    for entry in std::fs::read_dir(&dir).unwrap() {
        std::fs::write(entry.unwrap().path(), b"garbage").unwrap();
    }
    let again = compile_with_cache("selftest.cu", &CompileOptions::cubin(ARCH), Some(&cache)).unwrap();
    assert!(!again.cached);
    assert_eq!(again.image, first.image);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn compile_errors_carry_the_file_and_log() {
    if !nvrtc_or_skip("errors") {
        return;
    }
    let source = "#line 1 \"broken.cu\"\nextern \"C\" __global__ void k() { undefined_thing(); }\n";
    match compile_source("broken.cu", source, &CompileOptions::ptx(ARCH), None) {
        Err(CudaError::Compile { file, log, .. }) => {
            assert_eq!(file, "broken.cu");
            assert!(log.contains("broken.cu(1)") && log.contains("undefined_thing"), "{log}");
        }
        other => panic!("expected a compile error, got {other:?}"),
    }
}

/// The modules a frame compiles hold only their kernels: the wavefront
/// file's shading and bookkeeping halves, and one traversal loop of the
/// trace file per module (its four kernels), so that a frame compiles only
/// what it launches.
#[test]
fn frame_modules_hold_only_their_kernels() {
    if !nvrtc_or_skip("frame modules") {
        return;
    }
    let entries = |file: &str, define: &str| -> Vec<String> {
        let mut options = CompileOptions::ptx(ARCH);
        options.extra.push(define.into());
        let compiled =
            compile_with_cache(file, &options, None).unwrap_or_else(|e| panic!("{file} {define}: {e}"));
        let ptx = String::from_utf8(compiled.image).expect("PTX is text");
        let mut names: Vec<String> = ptx
            .lines()
            .filter_map(|l| l.split(".entry ").nth(1))
            .map(|rest| rest.trim_end_matches(['(', ' ']).to_string())
            .collect();
        names.sort();
        names
    };
    assert_eq!(entries("wavefront.cu", "-DATOLL_WAVEFRONT_KERNELS=1"), ["shade", "surface"]);
    assert_eq!(
        entries("wavefront.cu", "-DATOLL_WAVEFRONT_KERNELS=2"),
        ["push_work", "refill_claim", "refill_generate", "reset_queue_counts", "resolve_shadows"]
    );
    let mut all = Vec::new();
    for (bit, name) in ["ww", "pt", "sp", "ptsp", "cw", "ptcw"].iter().enumerate() {
        let mine = entries("trace.cu", &format!("-DATOLL_TRACE_LOOPS={}", 1 << bit));
        let expected: Vec<String> = ["any", "closest"]
            .iter()
            .flat_map(|q| ["exact", "woop"].map(|t| format!("trace_{q}_{name}_{t}")))
            .collect();
        assert_eq!(mine, expected, "loop {name}");
        all.extend(mine);
    }
    all.sort();
    assert_eq!(entries("trace.cu", "-DATOLL_TRACE_LOOPS=63"), all, "every loop's kernels, once");
}

/// The trace module with every feature a frame or BVH may switch on
/// (`TraceFeatures`: alpha masks, media boundaries, textures, access
/// counting, record bases, curves, moving instances) compiles, every loop
/// in it.
#[test]
fn trace_module_compiles_with_every_feature() {
    if !nvrtc_or_skip("trace features") {
        return;
    }
    // RGB grids, then grey grids alone (their own walk).
    for rgb in ["-DATOLL_WITH_RGB_MEDIA=1", "-DATOLL_WITH_RGB_MEDIA=0"] {
        let mut options = CompileOptions::ptx(ARCH);
        options.extra.extend(
            [
                "-DATOLL_TRACE_LOOPS=63",
                "-DATOLL_TRACE_ALPHA=1",
                "-DATOLL_TRACE_MEDIA=1",
                rgb,
                "-DATOLL_WITH_TEXTURES=1",
                "-DATOLL_COUNT_ACCESSES=1",
                "-DATOLL_TRI_BASES=1",
                "-DATOLL_TRACE_CURVES=1",
                "-DATOLL_TRACE_MOTION=1",
                atoll_cuda::compile::LAYOUT_CHECK_OPTION,
            ]
            .map(String::from),
        );
        let compiled =
            compile_with_cache("trace.cu", &options, None).unwrap_or_else(|e| panic!("trace.cu {rgb}: {e}"));
        let ptx = String::from_utf8(compiled.image).expect("PTX is text");
        assert_eq!(ptx.matches(".entry ").count(), 24, "six loops, two queries, two tests");
    }
}
