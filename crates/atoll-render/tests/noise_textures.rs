//! pbrt-v4's noise textures (`fbm`, `wrinkled`, `windy`, `marble`) and
//! polka `dots` through the whole pipeline: a pbrt scene's `Texture`
//! statements drive a diffuse plane's reflectance under a uniform white
//! sky, where every pixel converges to the reflectance it sees. Each
//! pixel is checked against the texture functions of `atoll_render::noise`
//! averaged over the pixel's footprint on the plane (`common::render_against`),
//! so the mapping, the texture's transform and the texture program are
//! what is tested.

mod common;

use atoll_render::noise;
use common::{assert_pixels_match, render_against, sky_lit_plane};
use glam::{Vec2, Vec3};

/// Renders `textures` (defining the spectrum texture "reflectance") on the
/// sky-lit plane and compares every pixel with `expected` over its footprint.
fn check(what: &str, textures: &str, expected: impl Fn(Vec3) -> Vec3) {
    let source = sky_lit_plane(24, 512, "PixelFilter \"box\"", textures);
    let (film, want) = render_against(&source, &expected);
    assert_pixels_match(what, &film, &want, 0.015, 0.06);
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
