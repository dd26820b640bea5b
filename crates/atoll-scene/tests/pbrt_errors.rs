//! Malformed scenes give a `SceneError` that names the file, line and
//! column and says what is wrong; nothing panics.

mod common;

use std::path::Path;

use atoll_scene::cornell::CORNELL_BOX_PBRT;
use atoll_scene::pbrt::{load_file, load_str};
use common::{temp_dir, write};

/// Loads `text` written as `scene.pbrt` in a fresh directory and returns the
/// error's Display, checking it starts with `path:line:`.
fn error_at(tag: &str, text: &str, line: u32) -> String {
    let dir = temp_dir(tag);
    let path = write(&dir, "scene.pbrt", text);
    error_in(&path, &path, line)
}

/// Loads `main` and checks the error points at `file`:`line`.
fn error_in(main: &Path, file: &Path, line: u32) -> String {
    let e = load_file(main).expect_err("the scene should not load").to_string();
    let prefix = format!("{}:{line}:", file.display());
    assert!(e.starts_with(&prefix), "expected '{prefix}...', got '{e}'");
    e
}

const OPTIONS: &str = "Camera \"perspective\"\nWorldBegin\n";

#[test]
fn truncated_files() {
    let e = error_at("trunc", &format!("{OPTIONS}Shape \"trianglemesh\" \"point3 P\" [ 1 2"), 3);
    assert!(e.contains("unexpected end of file") && e.contains("missing ']'"), "{e}");
    let e = error_at("trunc2", &format!("{OPTIONS}Translate 1 2"), 3);
    assert!(e.contains("unexpected end of file"), "{e}");
    let e = error_at("unterminated", &format!("{OPTIONS}NamedMaterial \"white\nShape \"sphere\""), 3);
    assert!(e.contains("unterminated string"), "{e}");
    let e = error_at("noworld", "Camera \"perspective\"\n", 1);
    assert!(e.contains("end of file before WorldBegin"), "{e}");
}

#[test]
fn bad_numbers_and_parameters() {
    let e = error_at("number", "Camera \"perspective\" \"float fov\" [ 3x.5 ]\nWorldBegin\n", 1);
    assert!(e.ends_with(":1:36: bad number '3x.5'"), "{e}");
    let e = error_at("count", &format!("{OPTIONS}AreaLightSource \"diffuse\" \"rgb L\" [ 1 2 ]\n"), 3);
    assert!(e.contains("\"rgb L\": 2 values given, not a multiple of 3"), "{e}");
    let e = error_at("type", "Camera \"perspective\" \"float fov\" \"wide\"\nWorldBegin\n", 1);
    assert!(e.contains("\"float fov\": expected numbers, found a string"), "{e}");
    let e = error_at("unknowndirective", &format!("{OPTIONS}Foo 1 2\n"), 3);
    assert!(e.ends_with(":3:1: unknown directive 'Foo'"), "{e}");
}

#[test]
fn missing_and_broken_ply_files() {
    let e = error_at("noply", &format!("{OPTIONS}Shape \"plymesh\" \"string filename\" \"nope.ply\"\n"), 3);
    assert!(e.contains("nope.ply") && e.contains("cannot read PLY file"), "{e}");

    let dir = temp_dir("badply");
    let header =
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                  property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let mut body: Vec<u8> = header.as_bytes().to_vec();
    for x in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        body.extend(x.to_le_bytes());
    }
    body.push(3);
    write(&dir, "truncated.ply", &body[..body.len() - 2]);
    for i in [0i32, 1, 7] {
        body.extend(i.to_le_bytes());
    }
    write(&dir, "badindex.ply", &body);
    let scene = write(
        &dir,
        "a.pbrt",
        format!("{OPTIONS}\nShape \"plymesh\" \"string filename\" \"truncated.ply\"\n"),
    );
    let e = error_in(&scene, &scene, 4);
    // Too short for the rows its header claims: refused before reading them.
    assert!(
        e.contains("truncated.ply") && e.contains("more than the file's 35 bytes of data can hold"),
        "{e}"
    );
    let scene =
        write(&dir, "b.pbrt", format!("{OPTIONS}Shape \"plymesh\" \"string filename\" \"badindex.ply\"\n"));
    let e = error_in(&scene, &scene, 3);
    assert!(e.contains("badindex.ply") && e.contains("vertex index 7, out of range for 3 vertices"), "{e}");
}

#[test]
fn trianglemesh_index_out_of_range() {
    let e = error_at(
        "triindex",
        &format!(
            "{OPTIONS}Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 3]"
        ),
        3,
    );
    assert!(e.contains("vertex index 3 out of range"), "{e}");
}

#[test]
fn unknown_names() {
    let e = error_at("namedmat", &format!("{OPTIONS}NamedMaterial \"nope\"\nShape \"sphere\"\n"), 3);
    assert!(e.ends_with(":3:1: NamedMaterial: material \"nope\" is not defined"), "{e}");
    let e = error_at("instance", &format!("{OPTIONS}ObjectInstance \"nope\"\n"), 3);
    assert!(e.contains("object \"nope\" is not defined"), "{e}");
    let e = error_at("attrend", &format!("{OPTIONS}AttributeBegin\nAttributeEnd\nAttributeEnd\n"), 5);
    assert!(e.contains("AttributeEnd without a matching AttributeBegin"), "{e}");
    let e = error_at("objend", &format!("{OPTIONS}ObjectBegin \"a\"\nAttributeEnd\n"), 4);
    assert!(e.contains("missing ObjectEnd"), "{e}");
    let e = error_at("order", &format!("{OPTIONS}Camera \"perspective\"\n"), 3);
    assert!(e.contains("not allowed after WorldBegin"), "{e}");
    let e = error_at("order2", "Shape \"sphere\"\nWorldBegin\n", 1);
    assert!(e.contains("not allowed before WorldBegin"), "{e}");
}

#[test]
fn includes() {
    let dir = temp_dir("include");
    let a = write(&dir, "a.pbrt", format!("{OPTIONS}Include \"b.pbrt\"\n"));
    let b = write(&dir, "b.pbrt", "Include \"a.pbrt\"\n");
    let e = error_in(&a, &b, 1);
    assert!(e.contains("cyclic Include") && e.contains("a.pbrt -> ") && e.contains("b.pbrt -> "), "{e}");

    let c = write(&dir, "c.pbrt", format!("{OPTIONS}\nInclude \"missing.pbrt\"\n"));
    let e = error_in(&c, &c, 4);
    assert!(e.contains("cannot read included file") && e.contains("missing.pbrt"), "{e}");

    // Errors inside an included file point into that file.
    let d = write(&dir, "d.pbrt", format!("{OPTIONS}Include \"e.pbrt\"\n"));
    let inc = write(&dir, "e.pbrt", "# comment\n  Bar\n");
    let e = error_in(&d, &inc, 2);
    assert!(e.ends_with(":2:3: unknown directive 'Bar'"), "{e}");
}

#[test]
fn includes_that_work() {
    let dir = temp_dir("include-ok");
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    // Paths in included files resolve against the main file's directory (pbrt-v4).
    let main =
        write(&dir, "main.pbrt", "Include \"sub/options.pbrt\"\nWorldBegin\nImport \"sub/geometry.pbrt\"\n");
    write(&dir, "sub/options.pbrt", "Film \"rgb\" \"integer xresolution\" 64 \"integer yresolution\" 32\n");
    write(&dir, "sub/geometry.pbrt", "Shape \"plymesh\" \"string filename\" \"sub/quad.ply\"\n");
    write(
        &dir,
        "sub/quad.ply",
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n",
    );
    let loaded = load_file(&main).unwrap();
    assert_eq!(loaded.scene.settings.film.resolution, glam::UVec2::new(64, 32));
    assert_eq!(loaded.scene.meshes[0].indices, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(loaded.scene.meshes[0].name, "sub/quad.ply");
}

#[test]
fn missing_main_file() {
    let e = load_file(Path::new("/nonexistent/scene.pbrt")).unwrap_err();
    assert!(e.to_string().starts_with("/nonexistent/scene.pbrt: cannot read scene file"), "{e}");
    // The I/O error is kept underneath the message.
    let mut cause = std::error::Error::source(&e);
    while let Some(c) = cause {
        if let Some(io) = c.downcast_ref::<std::io::Error>() {
            assert_eq!(io.kind(), std::io::ErrorKind::NotFound);
            return;
        }
        cause = c.source();
    }
    panic!("no io::Error in the source chain of {e:?}");
}

/// Every prefix of a valid scene either loads or fails with a located error.
#[test]
fn truncation_never_panics() {
    let text = CORNELL_BOX_PBRT;
    for end in (0..text.len()).filter(|&i| text.is_char_boundary(i)) {
        if let Err(e) = load_str(&text[..end], "cbox", Path::new(".")) {
            assert!(e.to_string().starts_with("cbox:"), "{e}");
        }
    }
}

/// Negative colours, spectra and light scales are refused where they are
/// written (pbrt-v4 refuses negative RGB values; a negative scale would
/// make a light subtract from the image).
#[test]
fn negative_colours_and_light_scales() {
    let cases = [
        ("Material \"diffuse\" \"rgb reflectance\" [ -1 0 0 ]", "\"rgb reflectance\": negative value -1"),
        ("Material \"diffuse\" \"float reflectance\" -0.5", "\"float reflectance\": negative value -0.5"),
        ("Material \"coateddiffuse\" \"rgb albedo\" [ 0.5 -0.1 0.5 ]", "\"rgb albedo\": negative value -0.1"),
        ("Material \"conductor\" \"spectrum k\" [ 400 1 700 -2 ]", "\"spectrum k\": negative value -2"),
        ("Material \"dielectric\" \"float eta\" -1.5", "\"float eta\": negative value -1.5"),
        ("MakeNamedMaterial \"m\" \"string type\" \"matte\" \"color Kd\" [ 0 0 -1 ]", "negative value -1"),
        ("LightSource \"point\" \"float scale\" -1", "light \"point\": negative \"scale\" -1"),
        ("LightSource \"distant\" \"float scale\" -2", "light \"distant\": negative \"scale\" -2"),
        ("LightSource \"infinite\" \"rgb L\" [ 1 1 1 ] \"float scale\" -1", "negative \"scale\""),
        ("LightSource \"spot\" \"blackbody I\" [ 5500 -1 ]", "\"blackbody I\": negative value -1"),
        ("AreaLightSource \"diffuse\" \"float scale\" -3", "area light \"diffuse\": negative \"scale\" -3"),
        ("LightSource \"spot\" \"float power\" -5", "light \"spot\": negative \"power\" -5"),
    ];
    for (i, (statement, expected)) in cases.into_iter().enumerate() {
        let e = error_at(&format!("negative{i}"), &format!("{OPTIONS}\n{statement}\n"), 4);
        assert!(e.contains(expected), "{statement}: {e}");
    }
    // Zero is no light and black, not an error.
    // A spot's power of 0 is pbrt-v4's "unset": its intensity stays.
    let ok = "LightSource \"point\" \"float scale\" 0\nMaterial \"diffuse\" \"rgb reflectance\" [ 0 0 0 ]\n\
              LightSource \"spot\" \"float power\" 0";
    load_str(&format!("{OPTIONS}{ok}\n"), "zero", Path::new(".")).unwrap();
}
