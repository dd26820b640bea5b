//! Kernel sources and their compilation by NVRTC at run time.
//!
//! Every `kernels/*.cu` / `*.cuh` file but the test kernels is compiled
//! into the binary ([`KERNEL_FILES`]), so the binary needs no source tree
//! and no CUDA toolkit at build time. NVRTC (cudarc 0.19) takes no
//! in-memory headers, so `#include "x.cuh"` is resolved here by splicing the
//! header's text in ([`splice`]), once per file, with `#line` markers so
//! NVRTC's messages still name the original file and line.
//!
//! Setting `ATOLL_KERNEL_DIR` to a kernels directory makes the sources be
//! read from there instead: kernels can be edited and rerun on a GPU
//! machine that has no Rust toolchain.

use std::borrow::Cow;
use std::collections::HashSet;
use std::ffi::{CStr, CString};

use cudarc::nvrtc::{result as nvrtc, sys as nvrtc_sys};

use crate::error::{require_nvrtc, CudaError};
use crate::kernel_cache::{Fnv1a64, KernelCache};

/// Every kernel source file but the test kernels (`TEST_KERNEL_FILES`), by
/// file name. A file is added here when it is added to `kernels/` (a line
/// per file; `include_str!` fails the build while the file does not exist,
/// so lines are added with their files).
pub const KERNEL_FILES: &[(&str, &str)] = &[
    ("access_count.cuh", include_str!("../kernels/access_count.cuh")),
    ("bsdf.cuh", include_str!("../kernels/bsdf.cuh")),
    ("bvh.cuh", include_str!("../kernels/bvh.cuh")),
    ("bump.cuh", include_str!("../kernels/bump.cuh")),
    ("camera.cuh", include_str!("../kernels/camera.cuh")),
    ("common.cuh", include_str!("../kernels/common.cuh")),
    ("curve.cuh", include_str!("../kernels/curve.cuh")),
    ("environment.cuh", include_str!("../kernels/environment.cuh")),
    ("footprint.cuh", include_str!("../kernels/footprint.cuh")),
    ("layout.cuh", include_str!("../kernels/layout.cuh")),
    ("layered.cuh", include_str!("../kernels/layered.cuh")),
    ("lens.cuh", include_str!("../kernels/lens.cuh")),
    ("lbvh.cu", include_str!("../kernels/lbvh.cu")),
    ("lbvh.cuh", include_str!("../kernels/lbvh.cuh")),
    ("light_bvh.cuh", include_str!("../kernels/light_bvh.cuh")),
    ("lights.cuh", include_str!("../kernels/lights.cuh")),
    ("materials.cuh", include_str!("../kernels/materials.cuh")),
    ("noise.cuh", include_str!("../kernels/noise.cuh")),
    ("surface.cuh", include_str!("../kernels/surface.cuh")),
    ("params.cuh", include_str!("../kernels/params.cuh")),
    ("principled.cuh", include_str!("../kernels/principled.cuh")),
    ("hair.cuh", include_str!("../kernels/hair.cuh")),
    ("measured.cuh", include_str!("../kernels/measured.cuh")),
    ("media.cuh", include_str!("../kernels/media.cuh")),
    ("motion.cuh", include_str!("../kernels/motion.cuh")),
    ("record.cuh", include_str!("../kernels/record.cuh")),
    ("rng.cuh", include_str!("../kernels/rng.cuh")),
    ("peer.cu", include_str!("../kernels/peer.cu")),
    ("portal.cuh", include_str!("../kernels/portal.cuh")),
    ("sampling.cuh", include_str!("../kernels/sampling.cuh")),
    ("spawn.cuh", include_str!("../kernels/spawn.cuh")),
    ("selftest.cu", include_str!("../kernels/selftest.cu")),
    ("sort.cu", include_str!("../kernels/sort.cu")),
    ("texture.cuh", include_str!("../kernels/texture.cuh")),
    ("trace.cu", include_str!("../kernels/trace.cu")),
    ("traverse.cuh", include_str!("../kernels/traverse.cuh")),
    ("wide.cuh", include_str!("../kernels/wide.cuh")),
    ("treelet.cu", include_str!("../kernels/treelet.cu")),
    ("wavefront.cu", include_str!("../kernels/wavefront.cu")),
];

/// Kernel files only tests launch (device functions wrapped one by one for
/// comparison with the CPU; reads through a chunk window). They are part of the registry with the
/// `testing` feature, which atoll-cuda's own tests turn on (so the NVRTC
/// compile tests still check them), and left out of the library otherwise:
/// a feature rather than `tests/`, because they include `kernels/` headers
/// and are compiled and loaded exactly like the production kernels.
#[cfg(any(test, feature = "testing"))]
const TEST_KERNEL_FILES: &[(&str, &str)] = &[
    ("test_bsdf.cu", include_str!("../kernels/test_bsdf.cu")),
    ("test_window.cu", include_str!("../kernels/test_window.cu")),
];
#[cfg(not(any(test, feature = "testing")))]
const TEST_KERNEL_FILES: &[(&str, &str)] = &[];

/// Every registered kernel file: [`KERNEL_FILES`], then the test kernels.
fn registry() -> impl Iterator<Item = &'static (&'static str, &'static str)> {
    KERNEL_FILES.iter().chain(TEST_KERNEL_FILES)
}

/// The text of kernel file `name`: from `$ATOLL_KERNEL_DIR` when set (and
/// the file exists there), else the copy built into the binary.
pub(crate) fn kernel_source(name: &str) -> Option<Cow<'static, str>> {
    if let Some(dir) = std::env::var_os("ATOLL_KERNEL_DIR").filter(|d| !d.is_empty()) {
        if let Ok(text) = std::fs::read_to_string(std::path::Path::new(&dir).join(name)) {
            return Some(Cow::Owned(text));
        }
    }
    registry().find(|(n, _)| *n == name).map(|(_, text)| Cow::Borrowed(*text))
}

/// The `.cu` files of the registry (the compilable units).
pub fn compilation_units() -> impl Iterator<Item = &'static str> {
    registry().map(|(name, _)| *name).filter(|name| name.ends_with(".cu"))
}

/// `file` with every `#include "x"` replaced by x's text (recursively), each
/// file at most once (a second include of it becomes a comment, which also
/// makes include cycles harmless). `lookup` maps a file name to its text.
/// `#include <...>` is left alone: kernels must not use system headers
/// (NVRTC on CI has none), and NVRTC reports it if they do.
pub(crate) fn splice_with(
    file: &str,
    lookup: &dyn Fn(&str) -> Option<Cow<'static, str>>,
) -> Result<String, CudaError> {
    let text = lookup(file).ok_or_else(|| CudaError::UnknownKernelFile { file: file.to_string() })?;
    let mut out = String::with_capacity(text.len() * 2);
    let mut seen = HashSet::new();
    seen.insert(file.to_string());
    splice_into(file, &text, lookup, &mut seen, &mut out)?;
    Ok(out)
}

/// [`splice_with`] over the registry ([`kernel_source`]).
pub fn splice(file: &str) -> Result<String, CudaError> {
    splice_with(file, &kernel_source)
}

fn splice_into(
    file: &str,
    text: &str,
    lookup: &dyn Fn(&str) -> Option<Cow<'static, str>>,
    seen: &mut HashSet<String>,
    out: &mut String,
) -> Result<(), CudaError> {
    out.push_str(&format!("#line 1 \"{file}\"\n"));
    for (index, line) in text.lines().enumerate() {
        let trimmed = line.trim();
        if trimmed == "#pragma once" {
            // Splicing already includes each file once; NVRTC would warn
            // about `#pragma once` in what it sees as the main file.
            out.push_str("// #pragma once (handled by atoll's splicer)\n");
            continue;
        }
        let Some(include) = quoted_include(trimmed) else {
            out.push_str(line);
            out.push('\n');
            continue;
        };
        if seen.insert(include.to_string()) {
            let included = lookup(include).ok_or_else(|| CudaError::MissingInclude {
                file: file.to_string(),
                include: include.to_string(),
            })?;
            splice_into(include, &included, lookup, seen, out)?;
            // Back in this file: the next line is line index + 2.
            out.push_str(&format!("#line {} \"{file}\"\n", index + 2));
        } else {
            out.push_str(&format!("// #include \"{include}\" (already included)\n"));
        }
    }
    Ok(())
}

/// `x.cuh` for a line `#include "x.cuh"` (spaces allowed after `#`).
fn quoted_include(line: &str) -> Option<&str> {
    let rest = line.strip_prefix('#')?.trim_start().strip_prefix("include")?.trim_start();
    let rest = rest.strip_prefix('"')?;
    let end = rest.find('"')?;
    Some(&rest[..end])
}

/// The NVRTC option that turns on the per-field offset asserts of the
/// generated header blocks (`src/header.rs`).
///
/// `__builtin_offsetof` is accepted by the NVRTC of CUDA 13.5 (the PyPI
/// wheel CI compiles with) but not by CUDA 13.0's (seen on the H200
/// machines), so field offsets are checked where CI compiles every kernel
/// and skipped in run-time compiles; struct sizes are always checked.
pub const LAYOUT_CHECK_OPTION: &str = "-DATOLL_CHECK_LAYOUT";

/// What NVRTC produces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Output {
    /// PTX for a virtual architecture (`compute_XY`); the driver JIT-compiles it.
    Ptx,
    /// Machine code for one real architecture (`sm_XY`): no JIT at load, and
    /// loads even when NVRTC is newer than the driver's PTX support.
    Cubin,
}

/// How to compile a kernel file.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct CompileOptions {
    /// Compute capability (major, minor), e.g. (9, 0) for H100/H200.
    pub arch: (u32, u32),
    pub output: Output,
    /// `--use_fast_math` (approximate transcendentals, flush denormals).
    /// Passed as a raw option: cudarc's `use_fast_math` field only sets `--fmad`.
    pub fast_math: bool,
    /// `-lineinfo`: source lines in profiles (ncu, compute-sanitizer) at no run-time cost.
    pub line_info: bool,
    /// Further raw NVRTC options, e.g. `-Xptxas=-v` or `-DNAME=1`.
    pub extra: Vec<String>,
}

impl CompileOptions {
    /// Machine code for compute capability `arch`, with line info.
    pub fn cubin(arch: (u32, u32)) -> Self {
        CompileOptions { arch, output: Output::Cubin, fast_math: false, line_info: true, extra: Vec::new() }
    }

    /// PTX for compute capability `arch`, with line info.
    pub fn ptx(arch: (u32, u32)) -> Self {
        CompileOptions { output: Output::Ptx, ..Self::cubin(arch) }
    }

    /// The option strings handed to NVRTC.
    pub(crate) fn nvrtc_options(&self) -> Vec<String> {
        let (major, minor) = self.arch;
        let prefix = match self.output {
            Output::Ptx => "compute",
            Output::Cubin => "sm",
        };
        let mut options =
            vec![format!("--gpu-architecture={prefix}_{major}{minor}"), "-std=c++17".to_string()];
        if self.fast_math {
            options.push("--use_fast_math".into());
        }
        if self.line_info {
            options.push("-lineinfo".into());
        }
        options.extend(self.extra.iter().cloned());
        options
    }

    /// The file extension of the output: `ptx` or `cubin`.
    pub(crate) fn extension(&self) -> &'static str {
        match self.output {
            Output::Ptx => "ptx",
            Output::Cubin => "cubin",
        }
    }
}

/// A compiled kernel file.
#[derive(Clone, Debug)]
pub struct Compiled {
    /// PTX text (without a trailing NUL) or CUBIN bytes, per [`Output`].
    pub image: Vec<u8>,
    /// NVRTC's log (warnings, `-Xptxas=-v` reports); empty when `cached`.
    pub log: String,
    /// Whether it came from the disk cache.
    pub cached: bool,
}

/// NVRTC's version as (major, minor).
pub(crate) fn nvrtc_version() -> Result<(i32, i32), CudaError> {
    require_nvrtc()?;
    let (mut major, mut minor) = (0, 0);
    // SAFETY: NVRTC is loadable (checked above); the pointers are valid for the call.
    let status = unsafe { nvrtc_sys::nvrtcVersion(&mut major, &mut minor) };
    status.result().map_err(|nvrtc| CudaError::Compile {
        file: "(nvrtcVersion)".into(),
        nvrtc,
        log: String::new(),
    })?;
    Ok((major, minor))
}

/// The cache key of `source` compiled with `options` by NVRTC `version`.
pub(crate) fn cache_key(source: &str, options: &CompileOptions, version: (i32, i32)) -> u64 {
    let mut h = Fnv1a64::new();
    h.field(b"atoll kernel v1");
    h.field(source.as_bytes());
    for option in options.nvrtc_options() {
        h.field(option.as_bytes());
    }
    h.field(options.extension().as_bytes());
    h.field(&version.0.to_le_bytes()).field(&version.1.to_le_bytes());
    h.finish()
}

/// Compiles kernel file `file` (spliced), through the disk cache of the
/// environment ([`crate::kernel_cache::default_dir`]).
pub(crate) fn compile(file: &str, options: &CompileOptions) -> Result<Compiled, CudaError> {
    compile_with_cache(file, options, KernelCache::from_env().as_ref())
}

/// [`compile`] with an explicit cache (`None`: always compile).
pub fn compile_with_cache(
    file: &str,
    options: &CompileOptions,
    cache: Option<&KernelCache>,
) -> Result<Compiled, CudaError> {
    compile_source(file, &splice(file)?, options, cache)
}

/// Compiles already spliced `source`, named `name` in NVRTC's messages.
pub fn compile_source(
    name: &str,
    source: &str,
    options: &CompileOptions,
    cache: Option<&KernelCache>,
) -> Result<Compiled, CudaError> {
    let file = name;
    let version = nvrtc_version()?;
    let key = cache_key(source, options, version);
    if let Some(image) = cache.and_then(|c| c.get(key, options.extension())) {
        tracing::debug!("kernel cache hit: {file} ({key:016x})");
        return Ok(Compiled { image, log: String::new(), cached: true });
    }
    let start = std::time::Instant::now();
    let (image, log) = nvrtc_compile(file, source, &options.nvrtc_options(), options.output)?;
    tracing::info!("compiled {file} in {:.2} s", start.elapsed().as_secs_f64());
    if let Some(cache) = cache {
        cache.put(key, options.extension(), &image);
    }
    Ok(Compiled { image, log, cached: false })
}

/// Destroys an NVRTC program however compilation ends.
struct Program(nvrtc_sys::nvrtcProgram);

impl Drop for Program {
    fn drop(&mut self) {
        // SAFETY: the handle came from `create_program` and is destroyed once, here.
        let _ = unsafe { nvrtc::destroy_program(self.0) };
    }
}

/// One NVRTC compilation through the raw API (the safe wrapper returns
/// neither CUBIN nor the log of a successful compile, and unwraps
/// internally): (image, log).
fn nvrtc_compile(
    file: &str,
    source: &str,
    options: &[String],
    output: Output,
) -> Result<(Vec<u8>, String), CudaError> {
    require_nvrtc()?;
    let fail = |nvrtc, log: String| CudaError::Compile { file: file.to_string(), nvrtc, log };
    let no_nul = |what: &str| CudaError::Usage(format!("{file}: {what} contains a NUL byte"));
    let c_source = CString::new(source).map_err(|_| no_nul("the source"))?;
    let c_name = CString::new(file).map_err(|_| no_nul("the file name"))?;
    if options.iter().any(|o| o.contains('\0')) {
        return Err(no_nul("an option"));
    }
    let program =
        Program(nvrtc::create_program(&c_source, Some(&c_name)).map_err(|e| fail(e, String::new()))?);
    // SAFETY: `program` is live until dropped at the end of this function;
    // the options contain no NUL (checked above), so cudarc's CString
    // conversion inside cannot panic.
    let compiled = unsafe { nvrtc::compile_program(program.0, options) };
    // SAFETY: as above; the log is NUL-terminated by NVRTC.
    let log = unsafe { nvrtc::get_program_log(program.0) }
        .map(|raw| {
            let bytes: Vec<u8> = raw.iter().map(|&c| c as u8).take_while(|&b| b != 0).collect();
            String::from_utf8_lossy(&bytes).into_owned()
        })
        .unwrap_or_default();
    if let Err(e) = compiled {
        return Err(fail(e, log));
    }
    let image = match output {
        Output::Ptx => {
            // SAFETY: compiled successfully; `program` is live.
            let raw = unsafe { nvrtc::get_ptx(program.0) }.map_err(|e| fail(e, log.clone()))?;
            // SAFETY: NVRTC's PTX is NUL-terminated within `raw`.
            let text = unsafe { CStr::from_ptr(raw.as_ptr()) };
            text.to_bytes().to_vec()
        }
        Output::Cubin => {
            let mut size = 0usize;
            // SAFETY: compiled successfully; `size` is valid for the call.
            unsafe { nvrtc_sys::nvrtcGetCUBINSize(program.0, &mut size) }
                .result()
                .map_err(|e| fail(e, log.clone()))?;
            let mut bytes = vec![0u8; size];
            // SAFETY: `bytes` holds exactly the size NVRTC reported.
            unsafe { nvrtc_sys::nvrtcGetCUBIN(program.0, bytes.as_mut_ptr().cast()) }
                .result()
                .map_err(|e| fail(e, log.clone()))?;
            bytes
        }
    };
    Ok((image, log))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn files(list: &'static [(&'static str, &'static str)]) -> impl Fn(&str) -> Option<Cow<'static, str>> {
        move |name| list.iter().find(|(n, _)| *n == name).map(|(_, t)| Cow::Borrowed(*t))
    }

    #[test]
    fn include_forms() {
        assert_eq!(quoted_include("#include \"a.cuh\""), Some("a.cuh"));
        assert_eq!(quoted_include("#  include   \"b.cuh\" // why"), Some("b.cuh"));
        assert_eq!(quoted_include("#include <cuda_fp16.h>"), None);
        assert_eq!(quoted_include("// #include \"c.cuh\""), None);
    }

    #[test]
    fn splices_recursively_once_per_file_with_line_markers() {
        const FILES: &[(&str, &str)] = &[
            ("main.cu", "#include \"a.cuh\"\n#include \"b.cuh\"\nint main_line;\n"),
            ("a.cuh", "#pragma once\n#include \"b.cuh\"\nint a;\n"),
            ("b.cuh", "#include \"a.cuh\"\nint b;\n"),
        ];
        let out = splice_with("main.cu", &files(FILES)).unwrap();
        assert_eq!(out.matches("int a;").count(), 1);
        assert_eq!(out.matches("int b;").count(), 1);
        // b comes first (a includes it before declaring a), main last.
        let (pa, pb, pm) =
            (out.find("int a;").unwrap(), out.find("int b;").unwrap(), out.find("int main_line").unwrap());
        assert!(pb < pa && pa < pm, "{out}");
        assert!(out.contains("#line 1 \"b.cuh\""));
        // After a's text, main resumes at its line 2.
        assert!(out.contains("#line 2 \"main.cu\""), "{out}");
        assert!(!out.lines().any(|l| l.trim() == "#pragma once"));
    }

    #[test]
    fn missing_include_and_unknown_file_are_errors() {
        const FILES: &[(&str, &str)] = &[("main.cu", "#include \"nope.cuh\"\n")];
        match splice_with("main.cu", &files(FILES)) {
            Err(CudaError::MissingInclude { file, include }) => {
                assert_eq!((file.as_str(), include.as_str()), ("main.cu", "nope.cuh"))
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(splice_with("other.cu", &files(FILES)), Err(CudaError::UnknownKernelFile { .. })));
    }

    #[test]
    fn registry_files_splice() {
        for (name, _) in registry() {
            splice(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        assert!(compilation_units().any(|n| n == "selftest.cu"));
        assert!(compilation_units().any(|n| n == "test_bsdf.cu"));
    }

    #[test]
    fn options_and_cache_keys() {
        let cubin = CompileOptions::cubin((9, 0));
        assert_eq!(cubin.nvrtc_options(), ["--gpu-architecture=sm_90", "-std=c++17", "-lineinfo"]);
        let mut ptx = CompileOptions::ptx((8, 6));
        ptx.fast_math = true;
        assert_eq!(
            ptx.nvrtc_options(),
            ["--gpu-architecture=compute_86", "-std=c++17", "--use_fast_math", "-lineinfo"]
        );
        let key = cache_key("src", &cubin, (13, 0));
        assert_eq!(key, cache_key("src", &cubin, (13, 0)), "deterministic");
        assert_ne!(key, cache_key("src2", &cubin, (13, 0)));
        assert_ne!(key, cache_key("src", &CompileOptions::ptx((9, 0)), (13, 0)));
        assert_ne!(key, cache_key("src", &CompileOptions::cubin((8, 9)), (13, 0)));
        assert_ne!(key, cache_key("src", &cubin, (13, 1)));
        let mut fast = cubin.clone();
        fast.fast_math = true;
        assert_ne!(key, cache_key("src", &fast, (13, 0)));
    }
}
