//! Bump and normal maps against the surface they stand for: a flat plane
//! bump-mapped by a ramp of displacement, or given a normal map of the same
//! tilt, shades as the tilted plane itself does (pbrt-v4's `BumpMap` and
//! `NormalMap`), under a distant light where every pixel is known.

mod common;

use std::sync::Arc;

use atoll_render::RenderOptions;
use atoll_scene::texture_scenes::{bent_plane_normal, bent_plane_scene, Bend};
use common::{assert_finite, render_with};
use glam::Vec3;

fn render(bend: Bend) -> Vec<Vec3> {
    let scene = Arc::new(bent_plane_scene(bend));
    let film = render_with(&scene, RenderOptions::from_scene(&scene), None);
    assert_finite(&film);
    film.pixels()
}

#[test]
fn bumps_and_normal_maps_shade_as_the_tilted_surface() {
    let light = Vec3::new(1.0, 0.5, 2.0).normalize();
    let expected = 0.5 / std::f32::consts::PI * bent_plane_normal().dot(light);
    let flat = 0.5 / std::f32::consts::PI * Vec3::Z.dot(light);
    for bend in [Bend::Tilted, Bend::Bump, Bend::NormalMap] {
        for (i, p) in render(bend).iter().enumerate() {
            // Normals travel as f16: a few parts in ten thousand.
            assert!((p.x - expected).abs() < 2e-3 * expected, "{bend:?}, pixel {i}: {p} against {expected}");
        }
    }
    assert!((expected - flat).abs() > 0.05 * flat, "the tilt shows");
}
