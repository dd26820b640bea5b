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
