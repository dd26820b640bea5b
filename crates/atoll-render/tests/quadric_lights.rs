//! pbrt's quadrics as area lights, against their analytic irradiance: a
//! diffuse ground under a downward-facing `disk` light (pbrt-v4's disk
//! faces +z; `ReverseOrientation` turns it to face the ground), seen from
//! the side through a narrow lens, so that the pixels at the image's
//! centre see the ground point under the disk's centre.

mod common;

use std::path::Path;
use std::sync::Arc;

use atoll_render::RenderOptions;
use common::{assert_finite, mean_and_stderr, render_with};
use glam::UVec2;

/// A disk of `radius` R at `height` h radiating L straight down gives the
/// point below its centre the irradiance E = π L R² / (h² + R²); a diffuse
/// ground of reflectance ρ then leaves with radiance ρ E / π.
fn expected_radiance(l: f64, radius: f64, height: f64, reflectance: f64) -> f64 {
    reflectance * l * radius * radius / (height * height + radius * radius)
}

fn scene(shape: &str) -> String {
    format!(
        r#"
LookAt 3 0 0.8  0 0 0  0 0 1
Camera "perspective" "float fov" [ 2 ]
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "path" "integer maxdepth" [ 1 ]
WorldBegin
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
Shape "trianglemesh" "point3 P" [ -20 -20 0  20 -20 0  20 20 0  -20 20 0 ] "integer indices" [ 0 1 2 0 2 3 ]
AttributeBegin
AreaLightSource "diffuse" "rgb L" [ 4 4 4 ]
Material "diffuse" "rgb reflectance" [ 0 0 0 ]
{shape}
AttributeEnd
"#
    )
}

/// The mean of the image's central 4×4 pixels (red), with its standard error.
fn centre_radiance(source: &str) -> (f64, f64) {
    let scene = Arc::new(atoll_scene::pbrt::load_str(source, "disk.pbrt", Path::new(".")).unwrap().scene);
    let mut o = RenderOptions::from_scene(&scene);
    o.resolution = UVec2::new(16, 16);
    o.spp = 1024;
    let film = render_with(&scene, o, None);
    assert_finite(&film);
    let pixels = film.pixels();
    mean_and_stderr((6..10).flat_map(|y| (6..10).map(move |x| y * 16 + x)).map(|i| pixels[i].x))
}

fn assert_near(what: &str, (mean, err): (f64, f64), expected: f64) {
    // The tessellated disk's area is 0.04% short of πR².
    let allowed = 4.0 * err + 0.01 * expected;
    assert!((mean - expected).abs() < allowed, "{what}: {mean} ± {err}, expected {expected}");
}

#[test]
fn a_disk_light_gives_its_analytic_irradiance() {
    let expected = expected_radiance(4.0, 0.5, 1.0, 0.5);
    let below = "Translate 0 0 1\nReverseOrientation\nShape \"disk\" \"float radius\" [ 0.5 ]";
    assert_near("disk facing down", centre_radiance(&scene(below)), expected);
    // The same disk given as its height, turned over by a rotation.
    let rotated = "Rotate 180 1 0 0\nShape \"disk\" \"float radius\" [ 0.5 ] \"float height\" [ -1 ]";
    assert_near("disk rotated", centre_radiance(&scene(rotated)), expected);
    // Facing up, it lights nothing below it.
    let up = "Translate 0 0 1\nShape \"disk\" \"float radius\" [ 0.5 ]";
    let (dark, _) = centre_radiance(&scene(up));
    assert!(dark < 1e-6, "a disk facing away lights the ground: {dark}");
}

#[test]
fn an_annulus_light_gives_the_difference_of_two_disks() {
    // Irradiance is additive over the emitter's area: the ring between
    // radii 0.3 and 0.6 gives the 0.6 disk's less the 0.3 disk's.
    let expected = expected_radiance(4.0, 0.6, 1.0, 0.5) - expected_radiance(4.0, 0.3, 1.0, 0.5);
    let ring = "Translate 0 0 1\nReverseOrientation\nShape \"disk\" \"float radius\" [ 0.6 ] \"float innerradius\" [ 0.3 ]";
    assert_near("annulus", centre_radiance(&scene(ring)), expected);
}
