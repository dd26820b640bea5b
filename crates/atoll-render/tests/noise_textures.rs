//! pbrt-v4's noise textures (`fbm`, `wrinkled`, `windy`, `marble`) and
//! polka `dots` through the whole pipeline: a pbrt scene's `Texture`
//! statements drive a diffuse plane's reflectance under a uniform white
//! sky, where every pixel converges to the reflectance it sees. Each
//! pixel is checked against the texture functions of `atoll_render::noise`
//! averaged over the pixel's footprint on the plane (found through the
//! scene's own camera), so the mapping, the texture's transform and the
//! texture program are what is tested.

mod common;

use std::path::Path;
use std::sync::Arc;

use atoll_render::camera::CameraRays;
use atoll_render::noise;
use atoll_render::RenderOptions;
use common::{assert_finite, render_with};
use glam::{UVec2, Vec2, Vec3};

const SIZE: u32 = 24;

/// The plane z = 0 (uv (0,0)–(1,1) over x, y in [-10, 10]) seen from above,
/// its reflectance the spectrum texture `reflectance` defined by `textures`.
fn scene(textures: &str) -> String {
    format!(
        r#"
LookAt 0 0 4  0 0 0  0 1 0
Camera "perspective" "float fov" [ 40 ]
Sampler "independent" "integer pixelsamples" [ 512 ]
Integrator "path" "integer maxdepth" [ 1 ]
Film "rgb" "integer xresolution" [ {SIZE} ] "integer yresolution" [ {SIZE} ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
{textures}
Material "diffuse" "texture reflectance" "reflectance"
Shape "trianglemesh" "point3 P" [ -10 -10 0  10 -10 0  10 10 0  -10 10 0 ]
  "integer indices" [ 0 1 2  0 2 3 ] "point2 uv" [ 0 0  1 0  1 1  0 1 ]
"#
    )
}

/// Renders `textures` and compares every pixel with `expected` (the
/// reflectance at a point of the plane) averaged over the pixel.
fn check(what: &str, textures: &str, expected: impl Fn(Vec3) -> Vec3) {
    let source = scene(textures);
    let loaded = atoll_scene::pbrt::load_str(&source, "noise.pbrt", Path::new(".")).unwrap();
    assert!(loaded.warnings.is_empty(), "{what}: {:?}", loaded.warnings);
    let scene = Arc::new(loaded.scene);
    let options = RenderOptions::from_scene(&scene);
    assert_eq!(options.resolution, UVec2::splat(SIZE));
    let film = render_with(&scene, options, None);
    assert_finite(&film);
    let camera = CameraRays::new(&scene.settings.camera, UVec2::splat(SIZE));
    const SUB: u32 = 6;
    let mut errors = Vec::new();
    let mut values = Vec::new();
    for (i, pixel) in film.pixels().iter().enumerate() {
        let (x, y) = ((i as u32 % SIZE) as f32, (i as u32 / SIZE) as f32);
        let mut sum = Vec3::ZERO;
        for k in 0..SUB * SUB {
            let offset = (Vec2::new((k % SUB) as f32, (k / SUB) as f32) + 0.5) / SUB as f32;
            let (o, d) = camera.ray(Vec2::new(x, y) + offset, Vec2::ZERO);
            sum += expected(o - d * (o.z / d.z));
        }
        let want = sum / (SUB * SUB) as f32;
        values.push(want.x);
        errors.push((*pixel - want).abs().max_element());
    }
    let mean = values.iter().sum::<f32>() / values.len() as f32;
    let spread = (values.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / values.len() as f32).sqrt();
    assert!(spread > 0.01, "{what}: the texture hardly varies over the image ({spread})");
    errors.sort_by(f32::total_cmp);
    let median = errors[errors.len() / 2];
    let p99 = errors[errors.len() * 99 / 100];
    assert!(median < 0.015 && p99 < 0.06, "{what}: pixel errors median {median}, p99 {p99}");
}

/// The reflectance a float texture `f` gives through `scale` by 0.5 (no negative reflectance).
fn half(f: f32) -> Vec3 {
    Vec3::splat(0.5 * f.max(0.0))
}

#[test]
fn fbm_wrinkled_and_windy_drive_reflectance() {
    let scaled =
        "Texture \"reflectance\" \"spectrum\" \"scale\" \"rgb tex\" [ 0.5 0.5 0.5 ] \"texture scale\" \"f\"";
    // Scaled by 2 at the statement: the texture reads p / 2.
    check(
        "fbm",
        &format!("AttributeBegin\nScale 2 2 2\nTexture \"f\" \"float\" \"fbm\" \"integer octaves\" 5\nAttributeEnd\n{scaled}"),
        |p| half(noise::fbm(p / 2.0, 0.5, 5)),
    );
    check(
        "wrinkled",
        &format!("Texture \"f\" \"float\" \"wrinkled\" \"float roughness\" 0.4\n{scaled}"),
        |p| half(noise::turbulence(p, 0.4, 8)),
    );
    check(
        "windy",
        &format!(
            "AttributeBegin\nTranslate 3 -1 0\nScale 0.25 0.25 0.25\nTexture \"f\" \"float\" \"windy\"\nAttributeEnd\n{scaled}"
        ),
        |p| half(noise::windy(4.0 * (p - Vec3::new(3.0, -1.0, 0.0)))),
    );
}

#[test]
fn marble_and_dots_drive_reflectance() {
    check(
        "marble",
        "Texture \"reflectance\" \"spectrum\" \"marble\" \"float scale\" 2 \"float variation\" 0.5",
        |p| noise::marble(p, 0.5, 8, 2.0, 0.5),
    );
    // uv spans 20 units: 40 cells of (s, t) per uv unit are half-unit cells.
    check(
        "dots",
        "Texture \"reflectance\" \"spectrum\" \"dots\" \"float uscale\" 40 \"float vscale\" 40 \
           \"rgb inside\" [ 0.9 0.2 0.1 ] \"rgb outside\" [ 0.1 0.3 0.8 ]",
        |p| {
            let st = (Vec2::new(p.x, p.y) + 10.0) / 20.0 * 40.0;
            if noise::inside_polka_dot(st) {
                Vec3::new(0.9, 0.2, 0.1)
            } else {
                Vec3::new(0.1, 0.3, 0.8)
            }
        },
    );
}
