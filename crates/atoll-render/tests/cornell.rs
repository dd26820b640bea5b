//! The shared Cornell boxes: plausible, noise-consistent, deterministic images.

mod common;

use std::sync::Arc;

use atoll_render::RenderOptions;
use atoll_scene::Scene;
use common::{assert_finite, mean_and_stderr, render_with, shared_scene};
use glam::{UVec2, Vec3};

fn load(rel: &str) -> Arc<Scene> {
    Arc::new(atoll_scene::pbrt::load_file(&shared_scene(rel)).expect("shared scene loads").scene)
}

fn small(scene: &Scene, spp: u32, seed: u32) -> RenderOptions {
    let mut o = RenderOptions::from_scene(scene);
    o.resolution = UVec2::new(48, 48);
    o.spp = spp;
    o.seed = seed;
    o
}

/// Mean radiance per channel agrees between independent seeds within noise,
/// and no pixel is NaN, infinite or negative.
fn seeds_agree(rel: &str) {
    let scene = load(rel);
    let a = render_with(&scene, small(&scene, 16, 1), None);
    let b = render_with(&scene, small(&scene, 16, 2), None);
    assert_finite(&a);
    assert_finite(&b);
    for c in 0..3 {
        // Per-pixel differences of two independent renders have mean 0; their
        // spread gives the noise level without counting image content.
        let diff = a.pixels().iter().zip(b.pixels()).map(|(p, q)| p[c] - q[c]).collect::<Vec<_>>();
        let (mean_diff, err) = mean_and_stderr(diff.into_iter());
        assert!(mean_diff.abs() < 4.0 * err + 1e-4, "{rel} channel {c}: seeds differ by {mean_diff} ± {err}");
        let (mean, _) = mean_and_stderr(a.pixels().iter().map(|p| p[c]));
        assert!(mean > 0.05, "{rel} channel {c} is nearly black: {mean}");
    }
}

#[test]
fn diffuse_box_is_noise_consistent() {
    seeds_agree("cbox/diffuse/scene.pbrt");
}

#[test]
fn specular_box_is_noise_consistent() {
    seeds_agree("cbox/spec/scene.pbrt");
}

/// Pixels that see only the (black, one-sided, downward-facing) light show
/// its radiance exactly: (17, 12, 4).
#[test]
fn light_is_seen_at_its_radiance() {
    let scene = load("cbox/diffuse/scene.pbrt");
    let film = render_with(&scene, small(&scene, 4, 0), None);
    let light = Vec3::new(17.0, 12.0, 4.0);
    let exact = film.pixels().iter().filter(|p| (**p - light).abs().max_element() < 1e-4).count();
    assert!(exact >= 4, "{exact} pixels show the light's radiance");
}

/// The same image for 1 thread and for several.
#[test]
fn thread_count_does_not_change_pixels() {
    let scene = load("cbox/spec/scene.pbrt");
    let mut options = small(&scene, 4, 7);
    options.wave_size = 1000; // several waves, partial last one
    let one = render_with(&scene, options.clone(), Some(1));
    let many = render_with(&scene, options, Some(3));
    assert_eq!(one, many);
}

/// The built-in Cornell box is the shared diffuse scene.
#[test]
fn builtin_box_renders_like_the_shared_file() {
    let file = load("cbox/diffuse/scene.pbrt");
    let builtin = Arc::new(atoll_scene::cornell::builtin_cornell_box());
    let options = small(&file, 2, 5);
    assert_eq!(render_with(&file, options.clone(), None), render_with(&builtin, options, None));
}
