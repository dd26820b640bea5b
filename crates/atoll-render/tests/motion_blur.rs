//! Motion blur: a black bar sliding in front of a glowing wall darkens each
//! pixel by the share of the shutter time it covers the pixel, which is
//! known exactly.

mod common;

use std::sync::Arc;

use atoll_render::RenderOptions;
use common::render_with;

/// An orthographic camera looking along +z at a glowing wall (z = 10)
/// through a 10 × 2 unit window (0.1 units per pixel, pixel column `c`
/// centred on x = -4 + 0.1 (c + 0.5)). A black bar 1 unit wide (x in
/// [-0.5, 0.5] at the start) at z = 5 slides 4 units along +x between the
/// transform times 0 and 1.
fn sliding_bar(shutter: [f32; 2]) -> String {
    bar_scene(shutter, "", "ActiveTransform EndTime\n Translate 4 0 0\n ActiveTransform All")
}

/// The bar standing still and the camera sliding 4 units along -x instead
/// (the camera transform's end moves the world by +4 relative to it).
fn sliding_camera(shutter: [f32; 2]) -> String {
    bar_scene(shutter, "ActiveTransform EndTime\nTranslate 4 0 0\nActiveTransform All", "")
}

/// The scene of [`sliding_bar`], `camera_motion` given to the camera's
/// transform and `bar_motion` to the bar's.
fn bar_scene(shutter: [f32; 2], camera_motion: &str, bar_motion: &str) -> String {
    format!(
        r#"LookAt 0 0 0  0 0 1  0 1 0
{camera_motion}
Camera "orthographic" "float screenwindow" [ -4 6 -1 1 ] "float shutteropen" {} "float shutterclose" {}
Film "rgb" "integer xresolution" [ 100 ] "integer yresolution" [ 20 ]
PixelFilter "box"
Sampler "independent" "integer pixelsamples" [ 256 ]
Integrator "path" "integer maxdepth" [ 1 ]
WorldBegin
AttributeBegin
 AreaLightSource "diffuse" "rgb L" [ 1 1 1 ] "bool twosided" true
 Shape "bilinearmesh" "point3 P" [ -20 -20 10  20 -20 10  -20 20 10  20 20 10 ]
AttributeEnd
AttributeBegin
 Material "diffuse" "rgb reflectance" [ 0 0 0 ]
 {bar_motion}
 Shape "bilinearmesh" "point3 P" [ -0.5 -5 5  0.5 -5 5  -0.5 5 5  0.5 5 5 ]
AttributeEnd
"#,
        shutter[0], shutter[1]
    )
}

/// The mean of pixel column `c` (over its 20 rows) of `scene`.
fn render_columns(text: &str) -> Vec<f64> {
    let loaded = atoll_scene::pbrt::load_str(text, "bar.pbrt", std::path::Path::new("."));
    let scene = Arc::new(loaded.unwrap().scene);
    assert_eq!(scene.motions.len() + scene.settings.camera.motion.iter().count(), 1);
    let film = render_with(&scene, RenderOptions::from_scene(&scene), Some(2));
    let pixels = film.pixels();
    (0..100).map(|c| (0..20).map(|y| pixels[y * 100 + c].x as f64).sum::<f64>() / 20.0).collect()
}

/// The share of the time `[open, close]` during which the bar covers x.
fn covered(x: f64, [open, close]: [f64; 2]) -> f64 {
    // The bar's centre is at 4 s for s = clamp(t, 0, 1): covered while
    // |x - 4 s| <= 0.5, i.e. s in [(x - 0.5) / 4, (x + 0.5) / 4].
    let steps = 200_000;
    let hits = (0..steps)
        .filter(|&k| {
            let t = open + (close - open) * (k as f64 + 0.5) / steps as f64;
            (x - 4.0 * t.clamp(0.0, 1.0)).abs() <= 0.5
        })
        .count();
    hits as f64 / steps as f64
}

#[test]
fn a_sliding_bar_darkens_pixels_by_the_time_it_covers_them() {
    for shutter in [[0.0, 1.0], [0.0, 2.0], [0.25, 0.75]] {
        let columns = render_columns(&sliding_bar(shutter));
        for (c, &value) in columns.iter().enumerate() {
            let x = -4.0 + 0.1 * (c as f64 + 0.5);
            // The box filter averages the pixel's width: away from the
            // kinks of the coverage, that is the value at its centre.
            let expect = 1.0 - covered(x, shutter.map(f64::from));
            // Coverage bends where the bar's edges are at the shutter's and
            // the motion's ends.
            let near_kink = [0.0, 1.0, shutter[0].min(1.0), shutter[1].min(1.0)]
                .iter()
                .flat_map(|&s| [4.0 * s as f64 - 0.5, 4.0 * s as f64 + 0.5])
                .any(|k| (x - k).abs() < 0.1);
            if near_kink {
                continue;
            }
            // 5120 samples per column: a binomial standard error below 0.007.
            assert!(
                (value - expect).abs() < 0.035,
                "shutter {shutter:?}, x = {x:.2}: {value} against {expect}"
            );
        }
    }
}

#[test]
fn a_sliding_camera_sees_what_a_sliding_bar_shows() {
    for shutter in [[0.0, 1.0], [0.0, 2.0]] {
        let bar = render_columns(&sliding_bar(shutter));
        let camera = render_columns(&sliding_camera(shutter));
        // The same paths at the same times see the same relative scene:
        // equal but for the rounding of the two transforms.
        for (c, (a, b)) in bar.iter().zip(&camera).enumerate() {
            assert!((a - b).abs() < 0.02, "shutter {shutter:?}, column {c}: bar {a}, camera {b}");
        }
    }
}
