//! The `atoll` binary end to end: outputs, exit codes and error messages.

mod common;

use common::atoll;
use std::path::PathBuf;
use std::process::Output;

fn scratch(name: &str) -> PathBuf {
    common::scratch("cli", name)
}

fn shared(rel: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes").join(rel).display().to_string()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn renders_builtin_box_to_default_png() {
    let dir = scratch("default");
    let out = atoll(&dir, &["render", "--spp", "1", "--res", "24x16", "--quiet"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("M samples/s") && stdout.contains("M rays/s"), "summary line: {stdout}");
    let png = std::fs::read(dir.join("atoll.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
}

#[test]
fn writes_linear_exr_with_the_light_radiance() {
    let dir = scratch("exr");
    let scene = shared("cbox/diffuse/scene.pbrt");
    let out = atoll(&dir, &["render", &scene, "--spp", "2", "--res", "32x32", "-o", "out.exr", "--quiet"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let image = exr::prelude::read_first_rgba_layer_from_file(
        dir.join("out.exr"),
        |res, _| (res.width(), Vec::<[f32; 3]>::with_capacity(res.width() * res.height())),
        |(_, px): &mut (usize, Vec<[f32; 3]>), _pos, (r, g, b, _a): (f32, f32, f32, f32)| px.push([r, g, b]),
    )
    .unwrap();
    let pixels = &image.layer_data.channel_data.pixels.1;
    assert_eq!(pixels.len(), 32 * 32);
    // The brightest pixels look straight at the light: exactly its radiance.
    let max_red = pixels.iter().map(|p| p[0]).fold(0.0, f32::max);
    assert_eq!(max_red, 17.0);
}

#[test]
fn info_reports_counts() {
    let dir = scratch("info");
    let out = atoll(&dir, &["info", &shared("cbox/spec/scene.pbrt")]);
    assert!(out.status.success(), "{}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("20504 unique"), "{stdout}");
    assert!(stdout.contains("SAH cost"), "{stdout}");
    assert!(!stdout.contains("curve pieces"), "{stdout}");
    // Curves: 210 strands of one segment, 8 pieces each, beside the ground's 2 triangles.
    let hair = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes/hair.pbrt");
    let out = atoll(&dir, &["info", &hair.display().to_string()]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("triangles          1682 unique"), "{stdout}");
    assert!(stdout.contains("curve pieces       1680 unique"), "{stdout}");
    assert!(!stdout.contains("moving"), "{stdout}");
    // Motion blur: the ball, the box and the ring's six cubes move.
    let motion = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes/motion.pbrt");
    let out = atoll(&dir, &["info", &motion.display().to_string()]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("instances          9 (8 moving over the shutter [0.0, 1.0])"), "{stdout}");
    // Each distinct subsurface material has an interior of its own.
    let subsurface = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes/subsurface.pbrt");
    let out = atoll(&dir, &["info", &subsurface.display().to_string()]);
    assert!(out.status.success() && stderr(&out).is_empty(), "{}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("media              4 (0.00 MiB, 4 of them subsurface interiors)"), "{stdout}");
}

/// Output into a pipe whose reader is gone (`atoll info … | head -1`)
/// ends atoll as it ends Unix tools, by SIGPIPE, with no panic message.
#[cfg(unix)]
#[test]
fn a_closed_stdout_ends_quietly() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::{Command, Stdio};
    let dir = scratch("pipe");
    let mut child = Command::new(env!("CARGO_BIN_EXE_atoll"))
        .args(["info", &shared("cbox/spec/scene.pbrt")])
        .current_dir(&dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("atoll runs");
    // The reader goes before atoll has loaded the scene and printed.
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.signal(), Some(libc::SIGPIPE), "{:?}: {}", out.status, stderr(&out));
    assert!(!stderr(&out).contains("panicked"), "{}", stderr(&out));
}

/// Textures count in `atoll info`; an image that cannot be read is an
/// error at its line (exit 2), as in pbrt-v4, and with `--allow-missing` a
/// warning there (the texture becomes a constant).
#[test]
fn info_reports_textures_and_warns_about_unreadable_images() {
    let dir = scratch("info-textures");
    exr::prelude::write_rgba_file(dir.join("wood.exr"), 4, 2, |_, _| (0.8f32, 0.4f32, 0.2f32, 1.0f32))
        .unwrap();
    let scene = "WorldBegin\n\
                 Texture \"wood\" \"spectrum\" \"imagemap\" \"string filename\" \"wood.exr\"\n\
                 Texture \"gone\" \"float\" \"imagemap\" \"string filename\" \"gone.png\"\n\
                 Material \"conductor\" \"texture reflectance\" \"wood\" \"texture roughness\" \"gone\"\n\
                 Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n";
    std::fs::write(dir.join("t.pbrt"), scene).unwrap();
    let out = atoll(&dir, &["info", "t.pbrt"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("t.pbrt:3:1: texture \"gone\": ") && err.contains("--allow-missing"), "{err}");
    let out = atoll(&dir, &["info", "t.pbrt", "--allow-missing"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    // The 4×2 image and its MIP levels, 2×1 and 1×1.
    assert!(stdout.contains("textures           2 (3 images, MIP levels counted, 0.00 MiB)"), "{stdout}");
    assert!(stdout.contains("(geometry + BVH + textures and media)"), "{stdout}");
    assert!(stdout.contains("media              0 (0.00 MiB)"), "{stdout}");
    let err = stderr(&out);
    assert!(err.contains("t.pbrt:3:1: texture \"gone\": ") && err.contains("gone.png"), "{err}");
    assert!(err.contains("; using a constant"), "{err}");
    // Not a terminal: no colour codes in the warnings.
    assert!(!err.contains('\u{1b}'), "{err:?}");
    // The integrator as words, not a Rust value.
    assert!(stdout.contains("spp, path, max depth"), "{stdout}");
}

/// Each malformed scene: exit code 2, a `file:line:` message, no panic, and
/// an image already at the output path left untouched.
#[test]
fn malformed_scenes_exit_2_with_location() {
    let dir = scratch("malformed");
    let cases: &[(&str, &str, &str)] = &[
        (
            "truncated.pbrt",
            "WorldBegin\nShape \"trianglemesh\" \"point3 P\" [ 0 0 0 1 0",
            "truncated.pbrt:2:",
        ),
        (
            "badnumber.pbrt",
            "Camera \"perspective\"\n  \"float fov\" [ 3x.5 ]\nWorldBegin\n",
            "badnumber.pbrt:2:",
        ),
        (
            "missingply.pbrt",
            "WorldBegin\n\nShape \"plymesh\" \"string filename\" \"nope.ply\"\n",
            "missingply.pbrt:3:",
        ),
        ("unknownmat.pbrt", "WorldBegin\nNamedMaterial \"gold\"\nShape \"sphere\"\n", "unknownmat.pbrt:2:"),
        // Files outside the scene's folder are refused (without --allow-outside-paths).
        ("outside.pbrt", "WorldBegin\nInclude \"/etc/hostname\"\n", "outside.pbrt:2:"),
        // Devices are refused by their type, never read (they would not end).
        ("devzero.pbrt", "WorldBegin\nInclude \"/dev/zero\"\n", "devzero.pbrt:2:"),
        (
            "devzeroply.pbrt",
            "WorldBegin\nShape \"plymesh\" \"string filename\" \"/dev/zero\"\n",
            "devzeroply.pbrt:2:",
        ),
        // Physically meaningless parameters.
        ("fov0.pbrt", "Camera \"perspective\" \"float fov\" 0\nWorldBegin\n", "fov0.pbrt:1:"),
        ("fov180.pbrt", "Camera \"perspective\" \"float fov\" 180\nWorldBegin\n", "fov180.pbrt:1:"),
        ("darklight.pbrt", "WorldBegin\nLightSource \"point\" \"rgb I\" [ -1 1 1 ]\n", "darklight.pbrt:2:"),
        (
            "coldlight.pbrt",
            "WorldBegin\nLightSource \"point\" \"blackbody I\" [ -100 ]\n",
            "coldlight.pbrt:2:",
        ),
        // Numbers past f32's range would be infinities in the camera, lights and BVH.
        (
            "hugefov.pbrt",
            "Camera \"perspective\"\n  \"float fov\" [ 1e400 ]\nWorldBegin\n",
            "hugefov.pbrt:2:",
        ),
        (
            "hugelight.pbrt",
            "WorldBegin\nAreaLightSource \"diffuse\" \"rgb L\" [ 1e39 1 1 ]\nShape \"sphere\"\n",
            "hugelight.pbrt:2:",
        ),
        ("cycle_a.pbrt", "WorldBegin\nInclude \"cycle_b.pbrt\"\n", "cycle_b.pbrt:1:"),
    ];
    std::fs::write(dir.join("cycle_b.pbrt"), "Include \"cycle_a.pbrt\"\n").unwrap();
    std::fs::write(dir.join("keep.png"), b"precious").unwrap();
    for (file, text, location) in cases {
        std::fs::write(dir.join(file), text).unwrap();
        let out = atoll(&dir, &["render", file, "-o", "keep.png", "--spp", "1", "--quiet"]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{file}: {err}");
        assert!(err.contains(location), "{file}: expected {location} in {err}");
        assert!(!err.contains("panicked"), "{file}: {err}");
        assert_eq!(std::fs::read(dir.join("keep.png")).unwrap(), b"precious");
    }
}

#[test]
fn bad_arguments_exit_2() {
    let dir = scratch("args");
    let out = atoll(&dir, &["render", "--res", "0x5"]);
    assert_eq!(out.status.code(), Some(2));
    let out = atoll(&dir, &["render", "-o", "image.tga"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("image.tga"));
    let out = atoll(&dir, &["render", "scene.xyz"]);
    assert_eq!(out.status.code(), Some(2));
    let out = atoll(&dir, &["render", "--light-sampler", "uniform"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("unknown light sampler \"uniform\""), "{}", stderr(&out)); // Numbers that make no sense, and sizes past what a frame may hold.
    for args in [
        &["render", "--spp", "0"][..],
        &["render", "--res", "65536x65536"],
        &["render", "--res", "92682x46341"],
        &["render", "--threads", "100000"],
        &["render", "--threads", "0"],
        &["render", "--ao", "nan"],
        &["render", "--ao", "0"],
        &["render", "--ao", "-1"],
    ] {
        let out = atoll(&dir, args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(!stderr(&out).contains("panicked"), "{args:?}: {}", stderr(&out));
    }
    // A generated scene past what 32-bit vertex indices address: refused
    // before anything is estimated or built.
    let out = atoll(&dir, &["info", "landscape:4294967295"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("landscape:4294967295: growth 4294967295"), "{}", stderr(&out));
    assert!(stderr(&out).contains("32-bit indices"), "{}", stderr(&out));
    let out = atoll(&dir, &["gen", "landscape", "--detail", "150"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("tessellates objects"), "{}", stderr(&out));
    // A gate that cannot fail is refused.
    for limit in ["nan", "inf", "-0.1"] {
        let out = atoll(&dir, &["compare", "a.exr", "b.exr", "--max-mean-diff", limit]);
        assert_eq!(out.status.code(), Some(2), "{limit}: {}", stderr(&out));
    }
    // An output that cannot be written is refused before loading, naming it.
    let out = atoll(&dir, &["render", "-o", "no-such-folder/x.png"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("no-such-folder") && stderr(&out).contains("does not exist"),
        "{}",
        stderr(&out)
    );
    std::fs::create_dir_all(dir.join("folder.png")).unwrap();
    let out = atoll(&dir, &["render", "-o", "folder.png"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("is a folder"), "{}", stderr(&out));
}

/// The scene limits are set on the command line, sizes with units.
#[test]
fn scene_limits_from_the_command_line() {
    let dir = scratch("limits");
    std::fs::write(dir.join("ball.pbrt"), "WorldBegin\nShape \"sphere\"\n").unwrap();
    let out = atoll(&dir, &["info", "ball.pbrt", "--max-scene-bytes", "10"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("more than the 10 one scene may read"), "{}", stderr(&out));
    // Past the triangle budget the scene does not fit, as for memory.
    let out = atoll(&dir, &["info", "ball.pbrt", "--max-generated-triangles", "100"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).starts_with("error: ball.pbrt:2:1: sphere: 3968 triangles"), "{}", stderr(&out));
    let out =
        atoll(&dir, &["--max-scene-bytes", "1K", "--max-generated-triangles", "4000", "info", "ball.pbrt"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    for bad in
        [&["--max-scene-bytes", "0"][..], &["--max-scene-bytes", "12X"], &["--max-generated-triangles", "0"]]
    {
        let out = atoll(&dir, &[&["info", "ball.pbrt"][..], bad].concat());
        assert_eq!(out.status.code(), Some(2), "{bad:?}: {}", stderr(&out));
    }
}

/// glTF buffers outside the model's folder are refused, naming the URI,
/// unless the user allows it.
#[test]
fn gltf_buffers_outside_the_model_folder_are_refused() {
    let dir = scratch("gltf-outside");
    for uri in ["../../../etc/hostname", "/etc/hostname", "file:///etc/hostname"] {
        let gltf = format!(
            r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"uri":"{uri}","byteLength":4}}],"scenes":[{{"nodes":[]}}]}}"#
        );
        std::fs::write(dir.join("m.gltf"), gltf).unwrap();
        let out = atoll(&dir, &["info", "m.gltf"]);
        assert_eq!(out.status.code(), Some(2), "{uri}: {}", stderr(&out));
        assert!(
            stderr(&out).contains(uri) && stderr(&out).contains("--allow-outside-paths"),
            "{}",
            stderr(&out)
        );
        let allowed = atoll(&dir, &["info", "m.gltf", "--allow-outside-paths"]);
        assert!(!stderr(&allowed).contains("--allow-outside-paths"), "{uri}: {}", stderr(&allowed));
    }
}

/// Rendering touches no file but its output: a user's file named like a
/// temporary one is left as it was.
#[test]
fn a_render_touches_only_its_output() {
    let dir = scratch("only-output");
    std::fs::write(dir.join("out.partial.png"), b"mine").unwrap();
    let out = atoll(&dir, &["render", "--spp", "1", "--res", "16x16", "-q", "-o", "out.png"]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(std::fs::read(dir.join("out.partial.png")).unwrap(), b"mine");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["out.partial.png", "out.png"]);
}

#[test]
fn a_generated_scene_that_cannot_fit_is_refused_before_it_is_built() {
    let dir = scratch("refused_early");
    // Some 60 GB for the CPU device: built, it would take minutes and more
    // memory than a test machine has. Refused from its sizes, it takes none.
    let out =
        atoll(&dir, &["render", "landscape:9000", "--device", "cpu", "--device-memory", "4G", "-o", "x.png"]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("landscape:9000: does not fit cpu") && err.contains("estimated before building it"),
        "{err}"
    );
    assert!(!dir.join("x.png").exists());
    // One that fits renders.
    let out = atoll(
        &dir,
        &["render", "landscape:1", "--device", "cpu", "--spp", "1", "--res", "16x9", "-o", "y.png"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
}

/// `atoll bench SCENE` traces the scene's own rays and writes them out
/// for other ray tracers: as many primary rays as `--res` asks, one shadow
/// and one diffuse ray per primary hit, and every instanced triangle once;
/// the report's hit counts are those rays'. A missing scene is an input
/// error.
#[test]
fn bench_traces_a_scene_and_exports_its_rays() {
    let dir = scratch("bench-scene");
    let out =
        atoll(&dir, &["bench", "landscape:1", "--device", "cpu", "--res", "40x30", "--export", "rays", "-q"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let report = String::from_utf8_lossy(&out.stdout).into_owned();
    let floats = |name: &str| std::fs::metadata(dir.join("rays").join(name)).unwrap().len() / 4;
    assert_eq!(floats("primary.f32"), 40 * 30 * 7);
    let row = |batch: &str| -> (u64, u64) {
        let line =
            report.lines().find(|l| l.starts_with(batch)).unwrap_or_else(|| panic!("{batch}: {report}"));
        let fields: Vec<u64> = line.split_whitespace().skip(2).take(2).map(|f| f.parse().unwrap()).collect();
        (fields[0], fields[1])
    };
    let (rays, primary_hits) = row("primary");
    assert_eq!(rays, 40 * 30, "{report}");
    assert!(primary_hits > 0 && primary_hits <= rays, "{report}");
    for batch in ["shadow", "diffuse"] {
        assert_eq!(row(batch).0, primary_hits, "{report}");
        assert_eq!(floats(&format!("{batch}.f32")), primary_hits * 7);
    }
    let info = atoll(&dir, &["info", "landscape:1"]);
    let info = String::from_utf8_lossy(&info.stdout).into_owned();
    let instanced: u64 = info
        .lines()
        .find_map(|l| l.strip_prefix("triangles")?.split(" unique, ").nth(1)?.split(' ').next()?.parse().ok())
        .unwrap_or_else(|| panic!("{info}"));
    assert_eq!(floats("triangles.f32"), instanced * 9);

    let out = atoll(&dir, &["bench", "missing.pbrt", "--device", "cpu"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("missing.pbrt"), "{}", stderr(&out));
}

/// A negative number is read as the value it is and refused by its
/// argument's range, naming the argument, with exit code 2 (not taken for
/// an unknown flag).
#[test]
fn negative_numbers_are_refused_by_their_argument() {
    let dir = scratch("negative");
    for (args, flag) in [
        (&["render", "--spp", "-1"][..], "--spp"),
        (&["render", "--max-depth", "-2"][..], "--max-depth"),
        (&["bench", "--spp", "-3"][..], "--spp"),
        (&["serve", "--spp", "-1"][..], "--spp"),
    ] {
        let out = atoll(&dir, args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        let err = stderr(&out);
        assert!(err.contains(&format!("invalid value '{}' for '{flag}", args[2])), "{args:?}: {err}");
    }
}

/// pbrt-v4's film parameters: a crop window renders that part of the image
/// (pbrt's pixel bounds, written at their size), and the sensor's ISO
/// scales what the pixels record.
#[test]
fn film_crop_windows_and_sensor_response() {
    let dir = scratch("film");
    let source = PathBuf::from(shared("cbox/diffuse/scene.pbrt"));
    for entry in std::fs::read_dir(source.parent().unwrap()).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, dir.join(path.file_name().unwrap())).unwrap();
    }
    let text = std::fs::read_to_string(&source).unwrap();
    let film_line = text.lines().find(|l| l.starts_with("Film")).unwrap();
    let render = |name: &str, film: &str| {
        std::fs::write(dir.join(format!("{name}.pbrt")), text.replace(film_line, film)).unwrap();
        let (scene, image) = (format!("{name}.pbrt"), format!("{name}.exr"));
        let out = atoll(&dir, &["render", &scene, "--spp", "64", "--device", "cpu", "-o", &image, "--quiet"]);
        assert!(out.status.success(), "{}", stderr(&out));
        common::read_exr(&dir.join(image))
    };
    let size = "Film \"rgb\" \"integer xresolution\" 32 \"integer yresolution\" 32";
    let whole = render("whole", size);
    let crop = "\"float cropwindow\" [0.25 0.75 0.5 1]";
    let part = render("part", &format!("{size} {crop}"));
    let brighter = render("brighter", &format!("{size} {crop} \"float iso\" 200"));
    assert_eq!(part.len(), 16 * 16, "the crop's pixels only");
    // The same pixels and samples, recorded twice as brightly.
    for (a, b) in part.iter().zip(&brighter) {
        assert!((0..3).all(|c| (2.0 * a[c] - b[c]).abs() <= 1e-5 * b[c].abs().max(1.0)), "{a:?} {b:?}");
    }
    // The crop shows what that part of the whole image shows (other
    // samples: the means agree within noise).
    let region: Vec<[f32; 3]> =
        (16..32).flat_map(|y| (8..24).map(move |x| y * 32 + x)).map(|i| whole[i]).collect();
    let mean = |px: &[[f32; 3]]| px.iter().map(|p| p[0] + p[1] + p[2]).sum::<f32>() / px.len() as f32;
    let (a, b) = (mean(&region), mean(&part));
    assert!((a - b).abs() < 0.05 * a, "the crop's mean {b} against its region's {a}");
    // Its left column is the region's left column, not the image's.
    let left = |px: &[[f32; 3]], stride: usize| (0..16).map(|y| px[y * stride][0]).sum::<f32>();
    assert!((left(&part, 16) - left(&region, 16)).abs() < 0.2 * left(&region, 16));
}

/// The repository's pbrt-v4 feature scene (quadrics, curves, 3D mappings,
/// directionmix, a bump map) loads with no warning and renders a finite,
/// lit image.
#[test]
fn the_pbrt_v4_feature_scene_renders() {
    let dir = scratch("pbrt-v4");
    let scene = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes/pbrt-v4.pbrt");
    let scene = scene.display().to_string();
    let args = ["render", &scene, "--spp", "2", "--res", "40x30", "--device", "cpu", "-o", "v4.exr", "-q"];
    let out = atoll(&dir, &args);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert_eq!(err.lines().filter(|l| l.contains("WARN")).count(), 0, "{err}");
    let image = common::read_exr(&dir.join("v4.exr"));
    assert!(image.iter().all(|p| p.iter().all(|c| c.is_finite() && *c >= 0.0)));
    assert!(image.iter().map(|p| p[0] + p[1] + p[2]).sum::<f32>() / image.len() as f32 > 0.05, "lit");
}
