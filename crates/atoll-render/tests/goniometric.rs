//! Goniometric lights: a point light whose intensity follows an equal-area
//! map of directions, here one that lights only the half-space -x of the
//! light, seen on a floor from above.

mod common;

use std::sync::Arc;

use atoll_render::RenderOptions;
use atoll_scene::{IntensityMap, Light, Rgb};
use common::render_with;
use glam::Vec3;

/// A grey floor (albedo 0.5) 4 × 4 units seen straight down by an
/// orthographic camera, direct light only.
const FLOOR: &str = r#"LookAt 0 5 0  0 0 0  0 0 1
Camera "orthographic" "float screenwindow" [ -2 2 -2 2 ]
Film "rgb" "integer xresolution" [ 32 ] "integer yresolution" [ 32 ]
PixelFilter "box"
Sampler "independent" "integer pixelsamples" [ 256 ]
Integrator "path" "integer maxdepth" [ 1 ]
WorldBegin
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
Shape "trianglemesh" "point3 P" [ -2 0 -2  2 0 -2  2 0 2  -2 0 2 ] "integer indices" [ 0 1 2 0 2 3 ]
"#;

#[test]
fn a_goniometric_light_shines_where_its_map_does() {
    let mut scene =
        atoll_scene::pbrt::load_str(FLOOR, "floor.pbrt", std::path::Path::new(".")).unwrap().scene;
    // The equal-area square's left half holds the directions with x < 0.
    let n = 16;
    let values = (0..n * n).map(|i| if i % n < n / 2 { 1.0 } else { 0.0 }).collect();
    let height = 1.0;
    scene.lights.push(Light::Goniometric {
        position: Vec3::new(0.0, height, 0.0),
        world_to_light: glam::Mat3::IDENTITY,
        intensity: Rgb::splat(2.0),
        map: Arc::new(IntensityMap { resolution: n, values }),
    });
    let scene = Arc::new(scene);
    let film = render_with(&scene, RenderOptions::from_scene(&scene), Some(2));
    let pixels = film.pixels();
    // Looking down with +z up the image, camera +x is world +x.
    let mut lit = 0;
    for py in 0..32u32 {
        for px in 0..32u32 {
            let value = pixels[(py * 32 + px) as usize].x as f64;
            let centre = |p: u32| -2.0 + (p as f64 + 0.5) / 8.0;
            let world = Vec3::new(centre(px) as f32, 0.0, centre(31 - py) as f32);
            let x = world.x as f64;
            if x.abs() < 0.25 {
                continue; // the pixels the map's edge crosses
            }
            let r2 = x * x + (world.z as f64).powi(2) + height as f64 * height as f64;
            let expected =
                if x < 0.0 { 0.5 / std::f64::consts::PI * 2.0 * height as f64 / r2.powf(1.5) } else { 0.0 };
            if expected > 0.0 {
                lit += 1;
                // The pixel's mean over 256 samples, against its centre's value.
                assert!((value / expected - 1.0).abs() < 0.015, "({x}, {}): {value} vs {expected}", world.z);
            } else {
                assert_eq!(value, 0.0, "({x}, {}) is behind the map's edge", world.z);
            }
        }
    }
    assert!(lit > 400, "{lit} lit pixels compared");
}
