//! The wavefront kernels compile cleanly with NVRTC (no GPU needed): no
//! warnings, every kernel the device launches present, no register spills.
//! Skips when NVRTC cannot be loaded (set LD_LIBRARY_PATH to its directory);
//! `ATOLL_REQUIRE_NVRTC=1` turns the skip into a failure.

use atoll_cuda::compile::{compile_with_cache, CompileOptions};

fn nvrtc_or_skip() -> bool {
    if atoll_cuda::error::nvrtc_present() {
        return true;
    }
    let required = std::env::var("ATOLL_REQUIRE_NVRTC").is_ok_and(|v| v == "1");
    assert!(!required, "ATOLL_REQUIRE_NVRTC=1 but libnvrtc cannot be loaded (LD_LIBRARY_PATH?)");
    eprintln!("skipped: NVRTC not found (set LD_LIBRARY_PATH; ATOLL_REQUIRE_NVRTC=1 makes this fail)");
    false
}

/// Compiles `file` for sm_90 with ptxas' report; returns (PTX, log).
fn compile(file: &str, extra: &[&str]) -> (String, String) {
    let mut ptx_options = CompileOptions::ptx((9, 0));
    ptx_options.extra = extra
        .iter()
        .map(|s| s.to_string())
        .chain([atoll_cuda::compile::LAYOUT_CHECK_OPTION.to_string()])
        .collect();
    let ptx = compile_with_cache(file, &ptx_options, None).unwrap_or_else(|e| panic!("{e}"));
    let mut cubin_options = CompileOptions::cubin((9, 0));
    cubin_options.extra = extra.iter().map(|s| s.to_string()).chain(["-Xptxas=-v".to_string()]).collect();
    let cubin = compile_with_cache(file, &cubin_options, None).unwrap_or_else(|e| panic!("{e}"));
    (String::from_utf8(ptx.image).unwrap(), ptx.log + &cubin.log)
}

fn check(file: &str, kernels: &[&str], extra: &[&str]) {
    let (ptx, log) = compile(file, extra);
    for kernel in kernels {
        assert!(ptx.contains(&format!(".entry {kernel}(")), "{file}: no kernel {kernel} in the PTX");
    }
    assert!(!log.contains("warning"), "{file} {extra:?}: NVRTC warnings:\n{log}");
    // Every "N bytes spill stores" of the report must be 0.
    for line in log.lines().filter(|l| l.contains("spill stores")) {
        assert!(line.contains(" 0 bytes spill stores"), "{file} {extra:?}: register spills:\n{log}");
    }
    eprintln!("{file} {extra:?}:\n{log}");
}

#[test]
fn wavefront_kernels_compile_without_warnings_or_spills() {
    if !nvrtc_or_skip() {
        return;
    }
    let kernels = [
        "push_work",
        "refill_claim",
        "refill_generate",
        "surface",
        "shade",
        "resolve_shadows",
        "reset_queue_counts",
    ];
    check("wavefront.cu", &kernels, &[]);
    // What the equality tests compile (tests/gpu_stages.rs).
    check("wavefront.cu", &kernels, &["--fmad=false"]);
}

#[test]
fn test_kernels_compile_without_warnings() {
    if !nvrtc_or_skip() {
        return;
    }
    check("test_bsdf.cu", &["test_bsdf", "test_rng", "test_lights", "test_light_lookup"], &["--fmad=false"]);
}

/// Registers ptxas reports for `kernel` in a compile log.
fn registers(log: &str, kernel: &str) -> u32 {
    let entry = format!("Compiling entry function '{kernel}'");
    let mut lines = log.lines().skip_while(|l| !l.contains(&entry));
    let used = lines
        .find(|l| l.contains("Used "))
        .unwrap_or_else(|| panic!("no register report for {kernel}:\n{log}"));
    let words: Vec<&str> = used.split_whitespace().collect();
    let at = words.iter().position(|w| *w == "Used").unwrap();
    words[at + 1].parse().unwrap()
}

/// The shade kernel a scene without coated, principled, hair or measured
/// materials, anisotropic roughness or emission textures gets (src/device.rs `shade_features`) keeps the register count
/// it had before those materials existed (the bound below): their code would
/// otherwise halve every scene's occupancy. Specialised for one of them,
/// it still compiles cleanly.
#[test]
fn specialised_shade_kernels_keep_their_registers() {
    if !nvrtc_or_skip() {
        return;
    }
    let none = [
        "-DATOLL_WITH_COATED=0",
        "-DATOLL_WITH_PRINCIPLED=0",
        "-DATOLL_WITH_HAIR=0",
        "-DATOLL_WITH_MEASURED=0",
        "-DATOLL_WITH_EMISSION_TEXTURES=0",
        "-DATOLL_WITH_TANGENTS=0",
        "-DATOLL_WITH_MEDIA=0",
    ];
    let (_, log) = compile("wavefront.cu", &none);
    let plain = registers(&log, "shade");
    // Anisotropic conductors or dielectrics: the frame's tangent read.
    let (_, log) = compile("wavefront.cu", &[&none[..5], &none[6..]].concat());
    let plain_anisotropic = registers(&log, "shade");
    let grey_grids = "-DATOLL_WITH_RGB_MEDIA=0";
    let (_, log) = compile("wavefront.cu", &[&none[..6], &[grey_grids]].concat());
    let plain_in_media = registers(&log, "shade");
    let (_, log) = compile("wavefront.cu", &none[..6]);
    let plain_in_rgb_media = registers(&log, "shade");
    let (_, log) = compile("wavefront.cu", &[]);
    let everything = registers(&log, "shade");
    // The material kinds' specialisations, compared without media (their
    // own specialisation, whose walks through grids add registers of their own).
    let no_media = "-DATOLL_WITH_MEDIA=0";
    let (_, log) = compile("wavefront.cu", &[no_media]);
    let all = registers(&log, "shade");
    let (_, log) = compile("wavefront.cu", &["-DATOLL_WITH_COATED_CONDUCTOR=0", no_media]);
    let no_coated_conductor = registers(&log, "shade");
    let (_, log) = compile("wavefront.cu", &["-DATOLL_WITH_HAIR=0", no_media]);
    let no_hair = registers(&log, "shade");
    let (_, log) = compile("wavefront.cu", &[&none[..3], &[none[4], no_media]].concat());
    let measured_only = registers(&log, "shade");
    eprintln!(
        "shade registers: plain materials {plain} ({plain_anisotropic} anisotropic), every material {all}, \
         all but coated conductors {no_coated_conductor}, all but hair {no_hair}, measured among plain ones \
         {measured_only}; with media: plain materials {plain_in_media} ({plain_in_rgb_media} with RGB grids), \
         every material {everything}"
    );
    assert!(plain <= 104, "shade without coated/principled uses {plain} registers");
    assert!(
        plain_anisotropic <= 104,
        "shade with anisotropic plain materials uses {plain_anisotropic} registers"
    );
    // Registers are allocated in eights: past 128, a 128-thread block no
    // longer fits four times into an SM's 64K registers.
    assert!(
        plain_in_media <= 128,
        "shade with grey media and plain materials uses {plain_in_media} registers"
    );
    assert!(plain < all, "specialisation must drop registers ({plain} vs {all})");
    // Measured BRDFs' warps are calls (kernels/measured.cuh), which measured
    // faster than inlining them at 2 registers more than 128.
    assert!(measured_only <= 136, "shade with measured and plain materials uses {measured_only} registers");
    assert!(no_coated_conductor <= all, "leaving coated conductors out must not add registers");
    check("wavefront.cu", &["shade"], &["-DATOLL_WITH_COATED=0"]);
    check("wavefront.cu", &["shade"], &["-DATOLL_WITH_COATED_CONDUCTOR=0"]);
    check("wavefront.cu", &["shade"], &["-DATOLL_WITH_PRINCIPLED=0"]);
    check("wavefront.cu", &["shade"], &["-DATOLL_WITH_HAIR=0"]);
    check("wavefront.cu", &["shade"], &["-DATOLL_WITH_MEASURED=0"]);
    check("wavefront.cu", &["shade"], &["-DATOLL_WITH_EMISSION_TEXTURES=0"]);
    check("wavefront.cu", &["shade"], &["-DATOLL_WITH_TANGENTS=0"]);
    check("wavefront.cu", &["shade"], &["-DATOLL_WITH_MEDIA=0"]);
    check("wavefront.cu", &["shade"], &[grey_grids]);
}

/// Every specialisation of the trace module compiles cleanly (the alpha
/// kernels are launched only for scenes with alpha masks), and the plain
/// ones keep the registers they had before textures existed (src/trace.rs
/// `TraceFeatures`).
#[test]
fn trace_specialisations_compile_and_plain_ones_stay_lean() {
    if !nvrtc_or_skip() {
        return;
    }
    let kernels = ["trace_closest_pt_exact", "trace_any_pt_exact", "trace_closest_ptcw_woop"];
    let mut plain = (0, 0);
    for alpha in [0, 1] {
        for textures in [0, 1] {
            let defines =
                [format!("-DATOLL_TRACE_ALPHA={alpha}"), format!("-DATOLL_WITH_TEXTURES={textures}")];
            let defines: Vec<&str> = defines.iter().map(String::as_str).collect();
            let (ptx, log) = compile("trace.cu", &defines);
            for kernel in kernels {
                assert!(ptx.contains(&format!(".entry {kernel}(")), "{defines:?}: no kernel {kernel}");
            }
            assert!(!log.contains("warning"), "{defines:?}: NVRTC warnings:\n{log}");
            let regs = (registers(&log, "trace_closest_pt_exact"), registers(&log, "trace_any_pt_exact"));
            eprintln!("{defines:?}: closest {} any {} registers", regs.0, regs.1);
            if alpha == 0 && textures == 0 {
                plain = regs;
            }
        }
    }
    assert!(plain.0 <= 72 && plain.1 <= 64, "plain trace kernels: {plain:?} registers");
    // The shared scene's counting prepass variant, and its globals the host sets.
    let (ptx, log) = compile("trace.cu", &["-DATOLL_COUNT_ACCESSES=1", "-DATOLL_WITH_TEXTURES=1"]);
    assert!(!log.contains("warning"), "counting: NVRTC warnings:\n{log}");
    for global in ["atoll_access_counts", "atoll_window_base", "atoll_window_bytes", "atoll_chunk_bytes"] {
        assert!(ptx.contains(global), "counting module without {global}");
    }
    assert!(ptx.contains("atom.global.add.u64"), "counting kernels add to the counters");
}
