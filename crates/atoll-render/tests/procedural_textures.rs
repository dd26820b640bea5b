//! pbrt-v4's procedural textures (`fbm`, `wrinkled`, `windy`, `marble`,
//! polka `dots`, `bilerp`, 3D `checkerboard`) through the whole pipeline: a
//! pbrt scene's `Texture` statements drive a diffuse plane's reflectance
//! under a uniform white sky, where every pixel converges to the
//! reflectance it sees. Each pixel is checked against the texture's
//! function (`atoll_render::noise` for the noise) averaged over the
//! pixel's footprint on the plane (`common::render_against`), so the
//! mapping, the texture's transform and the texture program are what is
//! tested. (The render drops the octaves finer than a sample's footprint,
//! and filters the checkerboard over it, as pbrt-v4 does; averaged over a
//! pixel, what they add is within the tolerances.)

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
        |p| half(noise::fbm(p / 2.0, 0.0, 0.5, 5)),
    );
    check(
        "wrinkled",
        &format!("Texture \"f\" \"float\" \"wrinkled\" \"float roughness\" 0.4\n{scaled}"),
        |p| half(noise::turbulence(p, 0.0, 0.4, 8)),
    );
    check(
        "windy",
        &format!(
            "AttributeBegin\nTranslate 3 -1 0\nScale 0.25 0.25 0.25\nTexture \"f\" \"float\" \"windy\"\nAttributeEnd\n{scaled}"
        ),
        |p| half(noise::windy(4.0 * (p - Vec3::new(3.0, -1.0, 0.0)), 0.0)),
    );
}

#[test]
fn marble_and_dots_drive_reflectance() {
    check(
        "marble",
        "Texture \"reflectance\" \"spectrum\" \"marble\" \"float scale\" 2 \"float variation\" 0.5",
        |p| noise::marble(p, 0.0, 0.5, 8, 2.0, 0.5),
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

#[test]
fn bilerp_and_solid_checkerboards_drive_reflectance() {
    // (s, t) = 4 uv - 1.5 spans about [0.2, 0.8] over the view.
    check(
        "bilerp",
        "Texture \"reflectance\" \"spectrum\" \"bilerp\" \"float uscale\" 4 \"float vscale\" 4 \
           \"float udelta\" -1.5 \"float vdelta\" -1.5 \"rgb v00\" [ 0.9 0.1 0.1 ] \"rgb v10\" [ 0.1 0.9 0.1 ] \
           \"rgb v01\" [ 0.1 0.1 0.9 ] \"rgb v11\" [ 0.9 0.9 0.9 ]",
        |p| {
            let st = (Vec2::new(p.x, p.y) + 10.0) / 20.0 * 4.0 - 1.5;
            let (s, t) = (st.x, st.y);
            let corner = |r: f32, g: f32, b: f32| Vec3::new(r, g, b);
            (1.0 - s) * (1.0 - t) * corner(0.9, 0.1, 0.1)
                + s * (1.0 - t) * corner(0.1, 0.9, 0.1)
                + (1.0 - s) * t * corner(0.1, 0.1, 0.9)
                + s * t * corner(0.9, 0.9, 0.9)
        },
    );
    // Cells of 0.4 units, the plane through the middle of a layer of them.
    check(
        "solid checkerboard",
        "AttributeBegin\nTranslate 0 0 0.5\nScale 0.4 0.4 0.4\n\
         Texture \"reflectance\" \"spectrum\" \"checkerboard\" \"integer dimension\" 3 \
           \"rgb tex1\" [ 0.8 0.8 0.8 ] \"rgb tex2\" [ 0.2 0.2 0.2 ]\nAttributeEnd",
        |p| {
            let q = (p - Vec3::new(0.0, 0.0, 0.5)) / 0.4;
            let even = (q.x.floor() + q.y.floor() + q.z.floor()).rem_euclid(2.0) == 0.0;
            Vec3::splat(if even { 0.8 } else { 0.2 })
        },
    );
}
