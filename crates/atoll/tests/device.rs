//! `--device` and `--device-memory` end to end, and `atoll compare`.

mod common;

use common::atoll;
use std::path::PathBuf;
use std::process::Output;

fn scratch(name: &str) -> PathBuf {
    common::scratch("device", name)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn has_cuda_driver() -> bool {
    atoll_cuda::error::driver_present()
}

#[test]
fn cuda_without_a_driver_exits_1_with_a_clear_message() {
    if has_cuda_driver() {
        eprintln!("skipped: this machine has a CUDA driver");
        return;
    }
    let dir = scratch("nodriver");
    for device in ["cuda", "cuda:0", "cuda:3"] {
        let out =
            atoll(&dir, &["render", "--device", device, "--spp", "1", "--res", "8x8", "-q", "-o", "x.png"]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{device}: {err}");
        assert!(err.contains("no CUDA driver (libcuda.so.1) found"), "{device}: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!dir.join("x.png").exists());
    }
    let out = atoll(&dir, &["bench", "--device", "cuda", "--no-traversal", "--spp", "1"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
}

#[test]
fn auto_falls_back_to_the_cpu_and_says_why() {
    if has_cuda_driver() {
        eprintln!("skipped: this machine has a CUDA driver");
        return;
    }
    let dir = scratch("auto");
    let out = atoll(&dir, &["render", "--spp", "1", "--res", "8x8", "-q", "-o", "x.exr"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("device: cpu") && err.contains("no CUDA driver"), "{err}");
    assert_eq!(err.lines().count(), 1, "one line of explanation: {err}");
}

#[test]
fn bad_device_flags_exit_2() {
    let dir = scratch("flags");
    for args in
        [["--device", "tpu"], ["--device", "cuda:x"], ["--device-memory", "lots"], ["--device-memory", "0"]]
    {
        let out = atoll(&dir, &["render", args[0], args[1], "-q"]);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
    }
}

#[test]
fn memory_budget_too_small_is_a_clear_error() {
    let dir = scratch("budget");
    let out = atoll(
        &dir,
        &["render", "--device", "cpu", "--device-memory", "1K", "--spp", "1", "--res", "8x8", "-q"],
    );
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("budget"), "{}", stderr(&out));
}

#[test]
fn compare_reports_means_and_enforces_a_limit() {
    let dir = scratch("compare");
    for (seed, name) in [("0", "a.exr"), ("1", "b.exr")] {
        let out = atoll(
            &dir,
            &["render", "--device", "cpu", "--spp", "4", "--res", "24x24", "--seed", seed, "-q", "-o", name],
        );
        assert!(out.status.success(), "{}", stderr(&out));
    }
    let same = atoll(&dir, &["compare", "a.exr", "a.exr", "--max-mean-diff", "0"]);
    assert!(same.status.success(), "{}", stderr(&same));
    let stdout = String::from_utf8_lossy(&same.stdout);
    assert!(stdout.contains("mean difference   0.000% 0.000% 0.000%"), "{stdout}");
    // Different seeds at 4 spp differ by noise: loose limit passes, zero fails.
    let loose = atoll(&dir, &["compare", "a.exr", "b.exr", "--max-mean-diff", "10"]);
    assert!(loose.status.success(), "{}", stderr(&loose));
    let strict = atoll(&dir, &["compare", "a.exr", "b.exr", "--max-mean-diff", "0"]);
    assert_eq!(strict.status.code(), Some(1));
    let missing = atoll(&dir, &["compare", "a.exr", "nope.exr"]);
    assert_eq!(missing.status.code(), Some(2));
}
