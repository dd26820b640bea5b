//! `--devices`, `--strategy`, `--device-memory` per device and
//! `--ownership` end to end, on CPU devices: a budget that forces the scene
//! apart makes `auto` pick a ring (or islands of rings), and the image is
//! the one a single device renders.

mod common;

use common::atoll;
use std::path::{Path, PathBuf};
use std::process::Output;

use atoll_bvh::{part_bytes, ByteModel, ScenePart};

fn scratch(name: &str) -> PathBuf {
    common::scratch("multi", name)
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The built-in Cornell box's bytes on a CPU device.
fn cornell_bytes() -> u64 {
    let scene = atoll_scene::cornell::builtin_cornell_box();
    part_bytes(&scene, &ScenePart::whole(&scene), &ByteModel::CPU)
}

const RENDER: [&str; 6] = ["render", "--spp", "4", "--res", "48x48", "-q"];

fn render(dir: &Path, extra: &[&str], output: &str) -> Output {
    let args: Vec<&str> = RENDER.iter().copied().chain(extra.iter().copied()).chain(["-o", output]).collect();
    atoll(dir, &args)
}

/// Same image as the single CPU device within 0.05% in every channel mean.
fn assert_same_as_single(dir: &Path, image: &str) {
    let out = atoll(dir, &["compare", "single.exr", image, "--max-mean-diff", "0.05"]);
    assert!(out.status.success(), "{image}: {}{}", text(&out.stdout), text(&out.stderr));
}

#[test]
fn a_budget_that_splits_the_scene_gives_rings_and_the_same_image() {
    let dir = scratch("ring");
    let single = render(&dir, &["--device", "cpu"], "single.exr");
    assert!(single.status.success(), "{}", text(&single.stderr));
    let whole = cornell_bytes();

    // 40% of the scene per device: three parts are needed.
    let budget = format!("{}", whole * 2 / 5);
    let out = render(&dir, &["--devices", "cpu:3", "--device-memory", &budget], "ring.exr");
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("strategy: ring of 3 (1 island)"), "{stderr}");
    for name in ["cpu:0", "cpu:1", "cpu:2"] {
        assert!(stdout.lines().any(|l| l.starts_with(name)), "table row for {name}: {stdout}");
    }
    assert_same_as_single(&dir, "ring.exr");

    // 60% per device on four devices: rings of two, two islands.
    let budget = format!("{}", whole * 3 / 5);
    let out = render(
        &dir,
        &["--devices", "cpu:4", "--device-memory", &budget, "--ownership", "own.png"],
        "islands.exr",
    );
    let stderr = text(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("strategy: ring of 2 (2 islands)"), "{stderr}");
    assert!(dir.join("own.png").exists());
    assert_same_as_single(&dir, "islands.exr");

    // No budget: the scene fits every device, so auto replicates.
    let out = render(&dir, &["--devices", "cpu:2"], "replicate.exr");
    assert!(text(&out.stderr).contains("strategy: replicate on 2 devices"), "{}", text(&out.stderr));
    assert_same_as_single(&dir, "replicate.exr");

    // Forced ring without a budget: one ring over all devices, queues through the host.
    let out =
        render(&dir, &["--devices", "cpu:2", "--strategy", "ring", "--ring-transport", "host"], "forced.exr");
    assert!(text(&out.stderr).contains("strategy: ring of 2 (1 island)"), "{}", text(&out.stderr));
    assert_same_as_single(&dir, "forced.exr");

    // A ring size chosen: rings of 2 on four devices, two islands, every
    // queue made and shaded on member 0.
    let args = ["--devices", "cpu:4", "--strategy", "ring", "--ring-size", "2", "--ring-order", "home"];
    let out = render(&dir, &args, "sized.exr");
    let stderr = text(&out.stderr);
    assert!(stderr.contains("strategy: ring of 2 (2 islands)") && stderr.contains("ring order"), "{stderr}");
    assert_same_as_single(&dir, "sized.exr");
}

#[test]
fn shared_scene_memory_renders_the_single_image_and_reports_its_placement() {
    let dir = scratch("shared");
    let single = render(&dir, &["--device", "cpu"], "single.exr");
    assert!(single.status.success(), "{}", text(&single.stderr));
    // Nothing replicated: every device owns half the chunks and reads the others'.
    let args =
        ["--devices", "cpu:2", "--strategy", "shared", "--chunk-size", "512", "--replicate-fraction", "0"];
    let out = render(&dir, &args, "shared.exr");
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("strategy: shared scene memory on 2 devices"), "{stderr}");
    assert!(stdout.contains("0 replicated (0.0%)"), "{stdout}");
    let rows: Vec<&str> =
        stdout.lines().skip_while(|l| !l.starts_with("shared:")).filter(|l| l.starts_with("cpu:")).collect();
    assert_eq!(rows.len(), 2, "{stdout}");
    for row in rows {
        // Device, then replicated, owned, remote and host as number and
        // unit, then prepass reads and the share of local reads.
        let cols: Vec<&str> = row.split_whitespace().collect();
        assert_eq!(cols.len(), 11, "{row}");
        assert!(cols[9].parse::<f64>().unwrap() > 0.0, "every device counted reads: {row}");
        assert_eq!(cols[1], "0", "nothing replicated: {row}");
        assert!(cols[3] != "0" && cols[5] != "0", "every device owns and reads remote chunks: {row}");
        assert_eq!(cols[7], "0", "nothing in host memory: {row}");
    }
    assert_same_as_single(&dir, "shared.exr");

    let out = atoll(&dir, &["info", "--prepass", "--devices", "cpu:2", "--chunk-size", "1K"]);
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(stdout.contains("prepass") && stdout.contains("hottest data       1%:"), "{stdout}");
    // Chunks so small that their counters would outgrow the scene: refused, nothing written.
    let args =
        ["render", "landscape:8", "--res", "8x8", "--spp", "1", "--devices", "cpu:2", "--strategy", "shared"];
    let tiny = atoll(&dir, &[&args[..], &["--chunk-size", "1", "-o", "tiny.png"]].concat());
    assert_eq!(tiny.status.code(), Some(1), "{}", text(&tiny.stderr));
    assert!(text(&tiny.stderr).contains("use a chunk size of at least"), "{}", text(&tiny.stderr));
    assert!(!dir.join("tiny.png").exists());
    let bad =
        atoll(&dir, &["render", "--devices", "cpu:2", "--strategy", "shared", "--replicate-fraction", "2"]);
    assert_eq!(bad.status.code(), Some(2), "{}", text(&bad.stderr));
}

#[test]
fn scenes_that_cannot_fit_and_bad_flags_are_clear_errors() {
    let dir = scratch("errors");
    // Too small for any partition over 2 devices: exit 1 before rendering, nothing written.
    let out = render(&dir, &["--devices", "cpu:2", "--device-memory", "1K"], "x.exr");
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("does not fit"), "{}", text(&out.stderr));
    assert!(!dir.join("x.exr").exists());
    // Replicate forced under a budget the whole scene exceeds.
    let budget = format!("{}", cornell_bytes() / 2);
    let out =
        render(&dir, &["--devices", "cpu:2", "--device-memory", &budget, "--strategy", "replicate"], "x.exr");
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stderr));
    for args in [
        vec!["--devices", "tpu:1"],
        vec!["--devices", "cpu:0"],
        vec!["--strategy", "ring"],
        vec!["--devices", "cpu:2", "--strategy", "scatter"],
        vec!["--devices", "cpu:2", "--device", "cpu"],
        vec!["--devices", "cpu:2", "--ring-transport", "pigeon"],
        vec!["--devices", "cpu:2", "--ring-order", "random"],
        vec!["--devices", "cpu:2", "--strategy", "ring", "--ring-size", "3"],
        vec!["--devices", "cpu:2", "--ring-size", "2"],
        vec!["--devices", "cuda:0/1"],
    ] {
        let out = render(&dir, &args, "x.exr");
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", text(&out.stderr));
        assert!(!text(&out.stderr).contains("panicked"), "{}", text(&out.stderr));
    }
}
