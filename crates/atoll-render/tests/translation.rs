//! A scene renders the same anywhere in space: every shared scene and the
//! feature scene, moved with its camera by 10, 1e3 and 1e5 units, gives
//! the image it gives at the origin (within noise), and surfaces lit at
//! grazing angles by a small area light get the light they should.

mod common;

use std::path::Path;
use std::sync::Arc;

use atoll_render::{Film, RenderOptions};
use atoll_scene::Scene;
use common::{assert_finite, mean_and_stderr, render_with, shared_scene};
use glam::{UVec2, Vec3};

const OFFSETS: [f32; 3] = [10.0, 1e3, 1e5];

/// `text` (a pbrt-v4 scene) with its world and camera moved by `offset`:
/// the camera's transform gains a translation by `-offset` (the world
/// seen from `offset` further along) and the world one by `offset`, so
/// every shape and light is built at its moved position.
fn moved(text: &str, offset: Vec3) -> String {
    let (x, y, z) = (offset.x, offset.y, offset.z);
    let camera = text.find("\nCamera").expect("a Camera directive");
    let world = text.find("WorldBegin").expect("WorldBegin") + "WorldBegin".len();
    format!(
        "{}\nTranslate {} {} {}{}\nTranslate {x} {y} {z}\n{}",
        &text[..camera],
        -x,
        -y,
        -z,
        &text[camera..world],
        &text[world..]
    )
}

fn load(text: &str, dir: &Path) -> Arc<Scene> {
    Arc::new(atoll_scene::pbrt::load_str(text, "moved.pbrt", dir).expect("scene loads").scene)
}

fn options(scene: &Scene, spp: u32) -> RenderOptions {
    let mut o = RenderOptions::from_scene(scene);
    o.resolution = UVec2::new(48, 48);
    o.spp = spp;
    o.seed = 7;
    o
}

/// Channel means of `moved` agree with `origin`'s, over the whole image
/// and over each of 4×4 blocks, within the noise of their per-pixel
/// differences (plus 1% for geometry that rounding moves at large offsets).
fn assert_same_image(label: &str, origin: &Film, moved: &Film) {
    assert_finite(moved);
    let width = origin.resolution.x as usize;
    let height = origin.resolution.y as usize;
    let (origin, moved) = (origin.pixels(), moved.pixels());
    for c in 0..3 {
        for block in 0..17 {
            // Block 16 is the whole image.
            let in_block = |i: usize| {
                let (x, y) = (i % width, i / width);
                block == 16 || (x * 4 / width + 4 * (y * 4 / height)) == block
            };
            let pairs = origin.iter().zip(&moved).enumerate().filter(|(i, _)| in_block(*i));
            let diff: Vec<f32> = pairs.clone().map(|(_, (a, b))| a[c] - b[c]).collect();
            let (mean_diff, err) = mean_and_stderr(diff.into_iter());
            let (mean, _) = mean_and_stderr(pairs.map(|(_, (a, _))| a[c]));
            assert!(
                mean_diff.abs() <= 5.0 * err + 0.01 * mean + 1e-4,
                "{label}: channel {c} block {block}: mean {mean}, moved differs by {mean_diff} ± {err}"
            );
        }
    }
}

fn check_scene_file(path: &Path, spp: u32) {
    let text = std::fs::read_to_string(path).unwrap();
    let dir = path.parent().unwrap();
    let scene = load(&text, dir);
    let origin = render_with(&scene, options(&scene, spp), None);
    assert_finite(&origin);
    for offset in OFFSETS {
        // Horizontal moves at every offset; a move with a vertical part
        // only up to 1e3: the specular box's light hangs 1 mm under its
        // ceiling, and from about 3e4 up floats are farther apart than
        // that, so light and ceiling round to one plane (a limit of the
        // scene's numbers, not of the renderer).
        let mut directions = vec![Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.6, 0.0, -0.8) * 0.99];
        if offset <= 1e3 {
            directions.push(Vec3::new(0.3, -0.9, 0.2));
        }
        for axis in directions {
            let scene = load(&moved(&text, axis * offset), dir);
            let image = render_with(&scene, options(&scene, spp), None);
            assert_same_image(&format!("{} moved by {}", path.display(), axis * offset), &origin, &image);
        }
    }
}

#[test]
fn diffuse_cornell_box_renders_the_same_anywhere() {
    check_scene_file(&shared_scene("cbox/diffuse/scene.pbrt"), 16);
}

#[test]
fn specular_cornell_box_renders_the_same_anywhere() {
    check_scene_file(&shared_scene("cbox/spec/scene.pbrt"), 16);
}

#[test]
fn feature_scene_renders_the_same_anywhere() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/features.pbrt");
    check_scene_file(&path, 16);
}

/// A small downward light just above a large floor, seen from straight
/// above: most of the floor is lit at grazing angles. Direct light only.
const GRAZING: &str = r#"
LookAt 0 6 0  0 0 0  0 0 1
Camera "perspective" "float fov" [ 60 ]
Film "rgb" "integer xresolution" [ 48 ] "integer yresolution" [ 48 ]
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "path" "integer maxdepth" [ 1 ]
WorldBegin
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
Shape "trianglemesh" "point3 P" [ -10 0 -10  10 0 -10  10 0 10  -10 0 10 ] "integer indices" [ 0 2 1 0 3 2 ]
AttributeBegin
AreaLightSource "diffuse" "rgb L" [ 40 40 40 ]
Material "diffuse" "rgb reflectance" [ 0 0 0 ]
Shape "trianglemesh" "point3 P" [ -0.25 0.05 -0.25  0.25 0.05 -0.25  0.25 0.05 0.25  -0.25 0.05 0.25 ] "integer indices" [ 0 1 2 0 2 3 ]
AttributeEnd
"#;

/// Irradiance at floor point `x` (y = 0) from the GRAZING light, by a
/// fine midpoint rule over the light.
fn grazing_irradiance(x: Vec3) -> f64 {
    let (n, half, h, radiance) = (200, 0.25f64, 0.05f64, 40.0f64);
    let cell = 2.0 * half / n as f64;
    let mut e = 0.0;
    for i in 0..n {
        for j in 0..n {
            let q = (-half + (i as f64 + 0.5) * cell, -half + (j as f64 + 0.5) * cell);
            let d = (q.0 - x.x as f64, h, q.1 - x.z as f64);
            let r2 = d.0 * d.0 + d.1 * d.1 + d.2 * d.2;
            // cos at the receiver (normal +y) and at the light (normal -y) are both h / r.
            e += radiance * (h * h / r2) / r2 * cell * cell;
        }
    }
    e
}

/// The floor around the light (beyond its footprint, where every
/// receiver sees it within a few degrees of grazing) has the radiance
/// albedo/π · E, at the origin and moved far away.
#[test]
fn grazing_receivers_near_an_area_light_are_lit() {
    let dir = Path::new(".");
    let scene = load(GRAZING, dir);
    let origin = render_with(&scene, options(&scene, 64), None);
    // Pixel centres to floor points: the camera looks down -y with +z up
    // the image; its half-width at the floor is 6 tan(30°).
    let half = 6.0 * (30f32.to_radians()).tan();
    let floor_point = |px: usize, py: usize| {
        let sx = ((px as f32 + 0.5) / 48.0) * 2.0 - 1.0;
        let sy = ((py as f32 + 0.5) / 48.0) * 2.0 - 1.0;
        (sx * half, sy * half)
    };
    // Ring of pixels 0.6 to 2 units from the light's centre.
    let ring: Vec<usize> = (0..48 * 48)
        .filter(|&i| {
            let (u, v) = floor_point(i % 48, i / 48);
            let r = (u * u + v * v).sqrt();
            (0.6..2.0).contains(&r)
        })
        .collect();
    // The exact value depends only on the distance to the light's centre
    // up to its square shape; average the four mirror images of each pixel.
    let expected: f64 = ring
        .iter()
        .map(|&i| {
            let (u, v) = floor_point(i % 48, i / 48);
            let e = [(u, v), (-u, v), (u, -v), (-u, -v)]
                .iter()
                .map(|&(a, b)| grazing_irradiance(Vec3::new(a, 0.0, b)))
                .sum::<f64>()
                / 4.0;
            0.5 / std::f64::consts::PI * e
        })
        .sum::<f64>()
        / ring.len() as f64;
    let measure = |film: &Film| mean_and_stderr(ring.iter().map(|&i| film.pixels()[i].x));
    let (got, err) = measure(&origin);
    assert!(
        (got - expected).abs() <= 4.0 * err + 0.02 * expected,
        "grazing floor at the origin: {got} ± {err}, expected {expected}"
    );
    for offset in OFFSETS {
        let scene = load(&moved(GRAZING, Vec3::new(offset, 0.0, -offset)), dir);
        let film = render_with(&scene, options(&scene, 64), None);
        let (moved_mean, moved_err) = measure(&film);
        assert!(
            (moved_mean - expected).abs() <= 4.0 * moved_err + 0.03 * expected,
            "grazing floor moved by {offset}: {moved_mean} ± {moved_err}, expected {expected}"
        );
    }
}
