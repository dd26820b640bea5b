//! `atoll gen landscape` and the `landscape:GROWTH[:SEED]` scene source, end to end.

mod common;

use common::atoll;
use std::path::PathBuf;
use std::process::Output;

use atoll_scene::landscape::Landscape;

fn scratch(name: &str) -> PathBuf {
    common::scratch("gen", name)
}

fn stdout(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The `triangles` line `atoll info` and `atoll gen` print.
fn triangles_line(l: &Landscape) -> String {
    let e = l.estimate();
    format!("triangles          {} unique, {} instanced", e.unique_triangles, e.instanced_triangles)
}

#[test]
fn info_generates_landscape_sources() {
    let dir = scratch("info");
    let out = stdout(&atoll(&dir, &["info", "landscape:1"]));
    let l = Landscape::new(1);
    assert!(out.contains(&triangles_line(&l)), "{out}");
    assert!(out.contains(&format!("instances          {}\n", l.estimate().instances)), "{out}");
    assert!(out.contains("lights             2"), "{out}");
    let seeded = stdout(&atoll(&dir, &["info", "landscape:1:7"]));
    assert!(seeded.contains(&triangles_line(&Landscape { seed: 7, ..l })), "{seeded}");
    assert_ne!(
        out.lines().find(|l| l.starts_with("bounds")),
        seeded.lines().find(|l| l.starts_with("bounds"))
    );
}

#[test]
fn bad_landscape_sources_and_arguments_exit_2() {
    let dir = scratch("bad");
    for args in [
        &["info", "landscape:0"][..],
        &["info", "landscape:two"],
        &["render", "landscape:1:x", "--quiet"],
        &["gen", "landscape", "--growth", "0"],
        &["gen", "landscape", "--detail", "-1"],
    ] {
        let out = atoll(&dir, args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(String::from_utf8_lossy(&out.stderr).contains("error:"), "{args:?}");
    }
}

#[test]
fn gen_without_output_prints_the_estimate_only() {
    let dir = scratch("estimate");
    let out = stdout(&atoll(&dir, &["gen", "landscape", "--growth", "1000"]));
    let e = Landscape::new(1000).estimate();
    assert!(out.contains(&triangles_line(&Landscape::new(1000))), "{out}");
    assert!(out.contains(&format!("instances          {}\n", e.instances)), "{out}");
    assert!(out.contains("MiB"), "{out}");
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "no file written");
}

#[test]
fn gen_writes_pbrt_that_loads_back_with_the_same_counts() {
    let dir = scratch("write");
    let args = ["gen", "landscape", "--growth", "2", "--seed", "5", "--detail", "0.3", "-o", "land.pbrt"];
    let out = stdout(&atoll(&dir, &args));
    assert!(out.contains("land.pbrt:"), "{out}");
    let text = std::fs::read_to_string(dir.join("land.pbrt")).unwrap();
    for needle in
        ["ObjectBegin \"conifer\"", "ObjectInstance \"glass_orb\"", "LightSource \"distant\"", "WorldBegin"]
    {
        assert!(text.contains(needle), "{needle}");
    }
    let info = stdout(&atoll(&dir, &["info", "land.pbrt"]));
    let l = Landscape { growth: 2, seed: 5, detail: 0.3 };
    assert!(info.contains(&triangles_line(&l)), "{info}");
    assert!(info.contains(&format!("instances          {}\n", l.estimate().instances)), "{info}");
}

#[test]
fn renders_a_landscape_without_files() {
    let dir = scratch("render");
    let out = stdout(&atoll(
        &dir,
        &["render", "landscape:1", "--spp", "1", "--res", "32x18", "-o", "l.png", "--quiet"],
    ));
    assert!(out.contains("M samples/s"), "{out}");
    let png = std::fs::read(dir.join("l.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
}
