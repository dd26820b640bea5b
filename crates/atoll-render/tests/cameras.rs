//! Cameras render what their projection shows: an orthographic camera sees
//! a shape the same size at any distance, within its screen window.

mod common;

use std::sync::Arc;

use atoll_render::RenderOptions;
use common::render_with;

/// Two glowing unit squares, one 2 units away on the left and one 50 units
/// away on the right, seen by an orthographic camera whose screen window
/// spans 4 × 2 units (16 pixels per unit, so the squares' edges fall on
/// pixel edges).
const SQUARES: &str = r#"LookAt 0 0 0  0 0 1  0 1 0
Camera "orthographic" "float screenwindow" [ -2 2 -1 1 ]
Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 32 ]
PixelFilter "box"
Sampler "independent" "integer pixelsamples" [ 4 ]
Integrator "path" "integer maxdepth" [ 1 ]
WorldBegin
AttributeBegin
 AreaLightSource "diffuse" "rgb L" [ 1 1 1 ] "bool twosided" true
 Shape "bilinearmesh" "point3 P" [ -1.5 -0.5 2  -0.5 -0.5 2  -1.5 0.5 2  -0.5 0.5 2 ]
 Shape "bilinearmesh" "point3 P" [ 0.5 -0.5 50  1.5 -0.5 50  0.5 0.5 50  1.5 0.5 50 ]
AttributeEnd
"#;

#[test]
fn orthographic_views_keep_sizes_at_any_distance() {
    let scene = Arc::new(
        atoll_scene::pbrt::load_str(SQUARES, "squares.pbrt", std::path::Path::new(".")).unwrap().scene,
    );
    let film = render_with(&scene, RenderOptions::from_scene(&scene), Some(2));
    let pixels = film.pixels();
    let lit = |x: u32, y: u32| pixels[(y * 64 + x) as usize].x;
    // Each square covers 16 × 16 pixels exactly, and nothing else glows.
    for (name, columns) in [("near", 8..24), ("far", 40..56)] {
        let inside: f32 =
            columns.clone().flat_map(|x| (8..24).map(move |y| (x, y))).map(|(x, y)| lit(x, y)).sum();
        assert_eq!(inside, 256.0, "the {name} square's pixels");
    }
    let total: f32 = pixels.iter().map(|p| p.x).sum();
    assert_eq!(total, 512.0, "light outside the squares");
    // Perspective would shrink the far square to a few pixels.
    let mut perspective = (*scene).clone();
    perspective.settings.camera.projection = atoll_scene::Projection::Perspective;
    perspective.settings.camera.screen_window = None;
    let perspective = Arc::new(perspective);
    let film = render_with(&perspective, RenderOptions::from_scene(&perspective), Some(2));
    let right: f32 = film.pixels().iter().enumerate().filter(|(i, _)| i % 64 >= 32).map(|(_, p)| p.x).sum();
    assert!(right < 5.0, "a perspective view's far square covers {right} pixels");
}

/// A spherical camera about 2 units from a glowing ball of radius 1,
/// which covers 2π(1 − cos α) sr (sin α = 1 / distance): an equal-area
/// image gives every pixel the same solid angle, so the ball fills that
/// share of 4π of it; an equirectangular one gives its rows sin θ of it.
#[test]
fn spherical_images_cover_the_solid_angle_of_what_they_see() {
    let distance = (0.3f64 * 0.3 + 0.2 * 0.2 + 2.0 * 2.0).sqrt();
    let solid_angle = std::f64::consts::TAU * (1.0 - (1.0 - 1.0 / (distance * distance)).sqrt());
    for (mapping, size) in [("equalarea", (96, 96)), ("equirectangular", (192, 96))] {
        let text = format!(
            r#"LookAt 0 0 0  0 0 1  0 1 0
Camera "spherical" "string mapping" "{mapping}"
Film "rgb" "integer xresolution" [ {} ] "integer yresolution" [ {} ]
PixelFilter "box"
Sampler "independent" "integer pixelsamples" [ 16 ]
Integrator "path" "integer maxdepth" [ 1 ]
WorldBegin
AttributeBegin
 AreaLightSource "diffuse" "rgb L" [ 1 1 1 ]
 Translate 0.3 -0.2 2
 Shape "sphere" "float radius" 1
AttributeEnd
"#,
            size.0, size.1
        );
        let scene = Arc::new(
            atoll_scene::pbrt::load_str(&text, "ball.pbrt", std::path::Path::new(".")).unwrap().scene,
        );
        let film = render_with(&scene, RenderOptions::from_scene(&scene), Some(2));
        let (w, h) = (size.0 as usize, size.1 as usize);
        let seen: f64 = film
            .pixels()
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let pixel_solid_angle = if mapping == "equalarea" {
                    4.0 * std::f64::consts::PI / (w * h) as f64
                } else {
                    let theta = std::f64::consts::PI * ((i / w) as f64 + 0.5) / h as f64;
                    2.0 * std::f64::consts::PI.powi(2) * theta.sin() / (w * h) as f64
                };
                p.x as f64 * pixel_solid_angle
            })
            .sum();
        // The tessellated ball's outline is a little inside the sphere's.
        assert!((seen / solid_angle - 1.0).abs() < 0.005, "{mapping}: {seen} sr, expected {solid_angle}");
    }
}

/// pbrt-v4's realistic camera under a sky of radiance 1: every pixel is the
/// film's irradiance through the lens, ∫ cos⁴θ / z² over the rear element's
/// points that rays get through by. Its centre pixel matches that integral
/// summed on a fine grid over the whole rear element (no exit-pupil bounds,
/// no sampling); the corners are darker (vignetting) and the image is
/// symmetric about its centre.
#[test]
fn a_realistic_cameras_pixels_are_its_lens_irradiance() {
    let scene_with = |camera: &str, film: &str| {
        let source = format!(
            "LookAt 0 0 0  0 0 1  0 1 0\n{camera}\n\
             Film \"rgb\" \"integer xresolution\" [ 9 ] \"integer yresolution\" [ 9 ] \"float diagonal\" 35 {film}\n\
             PixelFilter \"box\"\nSampler \"independent\" \"integer pixelsamples\" [ 4096 ]\n\
             Integrator \"path\" \"integer maxdepth\" [ 1 ]\nWorldBegin\nLightSource \"infinite\" \"rgb L\" [ 1 1 1 ]\n"
        );
        let dir = std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes"));
        Arc::new(atoll_scene::pbrt::load_str(&source, "lens.pbrt", dir).unwrap().scene)
    };
    let camera =
        "Camera \"realistic\" \"string lensfile\" \"singlet-50mm.dat\" \"float aperturediameter\" 8 \
                  \"float focusdistance\" 2";
    let realistic = scene_with(camera, "");
    let pinhole = scene_with("Camera \"perspective\"", "");
    let render = |scene: &Arc<atoll_scene::Scene>, spp: u32| {
        render_with(scene, RenderOptions { spp, ..RenderOptions::from_scene(scene) }, None).pixels()
    };
    let (lens_image, sky) = (render(&realistic, 4096), render(&pinhole, 1));
    // The sky's radiance as the film records it.
    let radiance = sky[40].x;
    assert!(sky.iter().all(|p| (p.x - radiance).abs() < 1e-4 * radiance));
    let at = |x: usize, y: usize| lens_image[y * 9 + x].x / radiance;

    let lens = realistic.settings.camera.lens.as_ref().unwrap();
    let (rear_z, extent, n) = (lens.rear_z(), 1.5 * lens.elements.last().unwrap().aperture_radius, 400);
    let cell = 2.0 * extent / n as f32;
    let mut integral = 0.0f64;
    for i in 0..n {
        for j in 0..n {
            let q =
                glam::Vec3::new(-extent + (i as f32 + 0.5) * cell, -extent + (j as f32 + 0.5) * cell, rear_z);
            if lens.trace_from_film(glam::Vec3::ZERO, q).is_some() {
                let cos = q.normalize().z;
                integral += (cos.powi(4) / (rear_z * rear_z) * cell * cell) as f64;
            }
        }
    }
    // The centre pixel alone (a crop window), at 2^18 samples: noise near 0.1%.
    let centre_only = scene_with(camera, "\"float cropwindow\" [ 0.4 0.5 0.4 0.5 ]");
    let centre = render(&centre_only, 1 << 18)[0].x as f64 / radiance as f64;
    assert!((centre / integral - 1.0).abs() < 0.01, "centre pixel {centre}, integral {integral}");
    assert!(
        (at(4, 4) as f64 / centre - 1.0).abs() < 0.03,
        "the whole image's centre {} against {centre}",
        at(4, 4)
    );
    for (x, y) in [(0, 0), (8, 0), (0, 8), (8, 8)] {
        assert!(at(x, y) < 0.9 * at(4, 4), "corner ({x}, {y}) {} against the centre {}", at(x, y), at(4, 4));
        assert!((at(x, y) / at(0, 0) - 1.0).abs() < 0.05, "corners differ: {} and {}", at(x, y), at(0, 0));
    }
}
