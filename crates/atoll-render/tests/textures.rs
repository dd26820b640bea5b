//! Textures and alpha cut-outs in whole renders: a screen cut by an alpha
//! mask must render exactly like the same screen built from solid strips
//! (`atoll_scene::texture_scenes`), from above (closest-hit rays pass the holes)
//! and from below (shadow rays pass them: the shadow has the holes).

mod common;

use std::sync::Arc;

use atoll_render::{Film, RenderOptions};
use atoll_scene::texture_scenes::{cutout_scene, Screen};
use common::{assert_finite, render_with};
use glam::Vec3;

fn render(screen: Screen, eye: Vec3) -> Film {
    let scene = Arc::new(cutout_scene(screen, eye));
    let options = RenderOptions::from_scene(&scene);
    let film = render_with(&scene, options, None);
    assert_finite(&film);
    film
}

/// Fraction of pixels that differ by more than `tol` (relative), and the
/// fraction of pixels brighter than `lit`.
fn compare(a: &Film, b: &Film, tol: f32, lit: f32) -> (f64, f64) {
    let (pa, pb) = (a.pixels(), b.pixels());
    assert_eq!(pa.len(), pb.len());
    let differ =
        pa.iter().zip(&pb).filter(|(x, y)| (**x - **y).abs().max_element() > tol * x.max_element().max(0.05));
    let bright = pa.iter().filter(|p| p.x > lit).count();
    (differ.count() as f64 / pa.len() as f64, bright as f64 / pa.len() as f64)
}

#[test]
fn an_alpha_cut_screen_casts_the_shadow_of_its_strips() {
    let eye = Vec3::new(0.0, 0.0, 0.6);
    let masked = render(Screen::AlphaMask, eye);
    let strips = render(Screen::Strips, eye);
    let (differ, lit) = compare(&masked, &strips, 1e-4, 0.2);
    // Samples whose shadow ray meets a stripe edge may round either way.
    assert!(differ < 0.01, "{:.2}% of pixels differ", differ * 100.0);
    // Half the ground is in the light: the holes let it through.
    assert!((0.3..0.7).contains(&lit), "lit fraction {lit}");
}

#[test]
fn closest_hits_pass_through_alpha_holes() {
    let eye = Vec3::new(0.0, 0.0, 3.0);
    let masked = render(Screen::AlphaMask, eye);
    let strips = render(Screen::Strips, eye);
    let (differ, lit) = compare(&masked, &strips, 1e-4, 0.2);
    assert!(differ < 0.01, "{:.2}% of pixels differ", differ * 100.0);
    // The dark screen covers about half the view, lit ground shows through the rest.
    assert!((0.2..0.7).contains(&lit), "lit fraction {lit}");
}

fn lit_floor(texture: Option<atoll_scene::Texture>, eye: Vec3, target: Vec3) -> Arc<atoll_scene::Scene> {
    Arc::new(atoll_scene::texture_scenes::textured_light_scene(texture, eye, target))
}

fn mean_of(scene: &Arc<atoll_scene::Scene>) -> f32 {
    let film = render_with(scene, RenderOptions::from_scene(scene), None);
    assert_finite(&film);
    film.mean().x
}

/// Light sampling and emitter hits both apply an emission texture: a
/// constant 0.5 halves the floor's light, a fine checkerboard of 0 and 2
/// leaves its average unchanged, and the light seen directly shows the
/// checkerboard's two values.
#[test]
fn emission_textures_scale_light_sampling_and_emitter_hits() {
    use atoll_scene::{Rgb, TexInput, Texture, UvMapping};
    let (eye, target) = (Vec3::new(0.0, -3.0, 0.8), Vec3::new(0.0, 0.0, 0.0));
    let plain = mean_of(&lit_floor(None, eye, target));
    let half = mean_of(&lit_floor(Some(Texture::Constant(Rgb::splat(0.5))), eye, target));
    assert!((half / plain - 0.5).abs() < 0.01, "half-scaled light: {half} vs {plain}");
    let checker = Texture::Checkerboard {
        mapping: UvMapping { su: 16.0, sv: 16.0, du: 0.0, dv: 0.0 }.into(),
        tex: [TexInput::Value(Rgb::ZERO), TexInput::Value(Rgb::splat(2.0))],
    };
    let checkered = mean_of(&lit_floor(Some(checker.clone()), eye, target));
    assert!((checkered / plain - 1.0).abs() < 0.03, "checkered light: {checkered} vs {plain}");
    // Looking straight up at the light: pixels are 0 or 2 (edges mixed).
    let scene = lit_floor(Some(checker), Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.01, 2.0));
    let film = render_with(&scene, RenderOptions::from_scene(&scene), None);
    let pixels = film.pixels();
    let dark = pixels.iter().filter(|p| p.x < 0.05).count() as f64 / pixels.len() as f64;
    let bright = pixels.iter().filter(|p| (p.x - 2.0).abs() < 0.05).count() as f64 / pixels.len() as f64;
    assert!(dark > 0.2 && bright > 0.2, "dark {dark}, bright {bright}");
}
