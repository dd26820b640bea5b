//! MIP-mapped image textures: a wall facing the camera, lit head-on by a
//! distant light (no noise but the pixels' own), textured with a
//! checkerboard of one-texel cells. Seen from afar, many texels to a
//! pixel, pbrt-v4's filtered lookup reads a level where the cells have
//! averaged to grey, so every pixel is the same; the unfiltered lookup
//! only gets there by averaging samples. Close up, the finest level is
//! read.

mod common;

use std::sync::Arc;

use atoll_render::RenderOptions;
use atoll_scene::{ImageFilter, Scene, Texture};
use common::render_with;

/// The wall with the checkerboard repeated `repeat` times across it, as
/// loaded (its image texture filtered bilinearly, pbrt-v4's default).
fn wall(repeat: f32) -> Scene {
    let dir = std::env::temp_dir().join(format!("atoll-mip-{}-{repeat}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    exr::prelude::write_rgb_file(dir.join("checks.exr"), 256, 256, |x, y| {
        let v = ((x + y) % 2) as f32;
        (v, v, v)
    })
    .unwrap();
    let text = format!(
        r#"LookAt 0 0 0  0 0 1  0 1 0
Camera "perspective" "float fov" [ 60 ]
Film "rgb" "integer xresolution" [ 48 ] "integer yresolution" [ 48 ]
PixelFilter "box"
Sampler "independent" "integer pixelsamples" [ 16 ]
Integrator "path" "integer maxdepth" [ 1 ]
WorldBegin
LightSource "distant" "point3 from" [ 0 0 0 ] "point3 to" [ 0 0 1 ] "rgb L" [ 3.14159265 3.14159265 3.14159265 ]
Texture "checks" "spectrum" "imagemap" "string filename" "checks.exr" "float uscale" [ {repeat} ] "float vscale" [ {repeat} ]
Material "diffuse" "texture reflectance" "checks"
Shape "trianglemesh" "point3 P" [ -20 -20 5  20 -20 5  20 20 5  -20 20 5 ]
  "point2 uv" [ 0 0  1 0  1 1  0 1 ] "integer indices" [ 0 1 2 0 2 3 ]
"#
    );
    let loaded = atoll_scene::pbrt::load_str(&text, "wall.pbrt", &dir).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    loaded.scene
}

/// The same wall with the image read unfiltered (its finest level).
fn unfiltered(mut scene: Scene) -> Scene {
    for t in &mut scene.textures.textures {
        if let Texture::Image { filter, levels, .. } = t {
            (*filter, *levels) = (ImageFilter::None, 1);
        }
    }
    scene
}

/// Mean and standard deviation of the pixels' red channel.
fn stats(scene: Scene) -> (f64, f64) {
    let scene = Arc::new(scene);
    let film = render_with(&scene, RenderOptions::from_scene(&scene), Some(2));
    let v: Vec<f64> = film.pixels().iter().map(|p| p.x as f64).collect();
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64;
    (mean, var.sqrt())
}

#[test]
fn distant_textures_are_filtered_and_near_ones_stay_sharp() {
    // From afar: 64 repeats of 256 cells over 40 units, about 37 cells to
    // a pixel's width.
    let (mean, spread) = stats(wall(64.0));
    let (raw_mean, raw_spread) = stats(unfiltered(wall(64.0)));
    // Both are grey on average; the filtered pixels all but exactly.
    assert!((mean - 0.5).abs() < 0.01, "{mean}");
    assert!((raw_mean - 0.5).abs() < 0.03, "{raw_mean}");
    assert!(spread < 0.01, "filtered: {spread}");
    assert!(raw_spread > 5.0 * spread && raw_spread > 0.03, "unfiltered: {raw_spread}, filtered {spread}");
    // Close up (a cell over five pixels) the finest level is read: the
    // bilinear blend of black and white cells, 0.5 ± 0.5 (1 − 2x)(1 − 2y)
    // over a cell, whose spread is 1/6 (a coarser level would be flat).
    let (near_mean, near_spread) = stats(wall(0.25));
    assert!((near_mean - 0.5).abs() < 0.05, "{near_mean}");
    assert!((near_spread - 1.0 / 6.0).abs() < 0.02, "{near_spread}");
}
