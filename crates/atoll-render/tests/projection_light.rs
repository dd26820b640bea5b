//! Projection lights: a slide projector beside the camera, both looking at
//! a white wall through the same frustum, shows the camera the slide
//! upright and unmirrored, each pixel as bright as the inverse-square law
//! and the wall's slant make it.

mod common;

use std::sync::Arc;

use atoll_render::RenderOptions;
use common::render_with;

/// The slide's 4 × 2 pixels: red counts columns, green rows.
fn slide(x: u32, y: u32) -> [f32; 3] {
    [0.25 + x as f32 / 3.0, 0.5 + y as f32, 0.25]
}

#[test]
fn a_projector_beside_the_camera_shows_its_slide() {
    let dir = std::env::temp_dir().join(format!("atoll-projection-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    exr::prelude::write_rgb_file(dir.join("slide.exr"), 4, 2, |x, y| {
        let [r, g, b] = slide(x as u32, y as u32);
        (r, g, b)
    })
    .unwrap();
    // Camera and projector share the transform and the 60-degree field of
    // view across the shorter side; the wall is 5 units away, white.
    let text = r#"LookAt 0 0 0  0 0 1  0 1 0
Camera "perspective" "float fov" [ 60 ]
Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 32 ]
PixelFilter "box"
Sampler "independent" "integer pixelsamples" [ 16 ]
Integrator "path" "integer maxdepth" [ 1 ]
WorldBegin
LookAt 0 0 0  0 0 1  0 1 0
LightSource "projection" "string filename" "slide.exr" "float fov" [ 60 ] "float scale" [ 40 ]
Material "diffuse" "rgb reflectance" [ 1 1 1 ]
Shape "trianglemesh" "point3 P" [ -20 -20 5  20 -20 5  20 20 5  -20 20 5 ] "integer indices" [ 0 1 2 0 2 3 ]
"#;
    let loaded = atoll_scene::pbrt::load_str(text, "projector.pbrt", &dir).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let scene = Arc::new(loaded.scene);
    let film = render_with(&scene, RenderOptions::from_scene(&scene), Some(2));
    let pixels = film.pixels();
    let tan = (30.0f64).to_radians().tan();
    for py in 0..32u32 {
        for px in 0..64u32 {
            // The pixel centre's direction, and the wall's irradiance there:
            // I cos θ / r² with r = 5 / cos θ; white diffuse: radiance E / π.
            let sx = (-2.0 + 4.0 * (px as f64 + 0.5) / 64.0) * tan;
            let sy = (1.0 - 2.0 * (py as f64 + 0.5) / 32.0) * tan;
            let cos = 1.0 / (sx * sx + sy * sy + 1.0).sqrt();
            let falloff = 40.0 * cos.powi(3) / 25.0 / std::f64::consts::PI;
            let rgb = slide(px / 16, py / 16);
            let got = pixels[(py * 64 + px) as usize].to_array();
            for c in 0..3 {
                let expect = rgb[c] as f64 * falloff;
                // Within the pixel cos³θ varies by under 2%.
                assert!(
                    (got[c] as f64 - expect).abs() <= 0.02 * expect,
                    "pixel ({px}, {py}) channel {c}: {} against {expect}",
                    got[c]
                );
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}
