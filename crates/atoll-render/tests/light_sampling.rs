//! The BVH light sampler against selection by power: a small area light,
//! a point light and a spot over a ground under a bright sky (the sky's
//! power grows with the scene's size; the ground is kept small enough that
//! selection by power still picks the spot often enough to converge). Both are unbiased, so their images agree
//! within noise (which also checks that MIS at emitter hits uses the same
//! selection probability that light sampling did); the BVH sampler is far
//! less noisy under the small light.

mod common;

use std::path::Path;
use std::sync::Arc;

use atoll_render::RenderOptions;
use atoll_scene::{LightSampler, Scene};
use common::{assert_finite, mean_and_stderr, render_with};
use glam::UVec2;

const SCENE: &str = r#"
LookAt 0 4 -6  0 0 0  0 1 0
Camera "perspective" "float fov" [ 50 ]
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "path" "integer maxdepth" [ 3 ]
WorldBegin
LightSource "infinite" "rgb L" [ 0.3 0.3 0.3 ]
LightSource "point" "point3 from" [ -2 1 1 ] "rgb I" [ 10 10 10 ]
LightSource "spot" "point3 from" [ 2 2 0 ] "point3 to" [ 2 0 0 ] "rgb I" [ 40 30 20 ] "float coneangle" 30
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
Shape "trianglemesh" "point3 P" [ -5 0 -5  5 0 -5  5 0 5  -5 0 5 ] "integer indices" [ 0 2 1 0 3 2 ]
AttributeBegin
AreaLightSource "diffuse" "rgb L" [ 20 20 20 ]
Material "diffuse" "rgb reflectance" [ 0 0 0 ]
Shape "trianglemesh" "point3 P" [ -0.25 1 -0.25  0.25 1 -0.25  0.25 1 0.25  -0.25 1 0.25 ] "integer indices" [ 0 1 2 0 2 3 ]
AttributeEnd
"#;

fn render(scene: &Arc<Scene>, sampler: LightSampler, seed: u32) -> Vec<glam::Vec3> {
    let mut o = RenderOptions::from_scene(scene);
    o.resolution = UVec2::new(40, 40);
    o.spp = 32;
    o.seed = seed;
    o.light_sampler = sampler;
    let film = render_with(scene, o, None);
    assert_finite(&film);
    film.pixels()
}

/// Every channel's mean agrees between two renders within 4σ of their
/// per-pixel differences.
fn assert_same_means(a: &[glam::Vec3], b: &[glam::Vec3]) {
    for c in 0..3 {
        let (mean_diff, err) = mean_and_stderr(a.iter().zip(b).map(|(p, q)| p[c] - q[c]));
        assert!(mean_diff.abs() < 4.0 * err + 1e-4, "channel {c}: samplers differ by {mean_diff} ± {err}");
    }
}

#[test]
fn bvh_and_power_selection_agree_and_bvh_is_less_noisy_near_a_small_light() {
    let scene = Arc::new(atoll_scene::pbrt::load_str(SCENE, "lights.pbrt", Path::new(".")).unwrap().scene);
    let bvh = render(&scene, LightSampler::Bvh, 1);
    let power = render(&scene, LightSampler::Power, 2);
    assert_same_means(&bvh, &power);
    // Noise: two renders of each sampler with different seeds; the spread
    // of their differences over the pool of light under the small light.
    let bvh2 = render(&scene, LightSampler::Bvh, 3);
    let power2 = render(&scene, LightSampler::Power, 4);
    let brightest = bvh.iter().map(|p| p.x).fold(0.0f32, f32::max);
    let pool: Vec<usize> =
        (0..bvh.len()).filter(|&i| 0.5 * (bvh[i].x + bvh2[i].x) > 0.2 * brightest).collect();
    assert!(pool.len() > 20, "the light's pool has {} pixels", pool.len());
    let spread = |a: &[glam::Vec3], b: &[glam::Vec3]| {
        let d: Vec<f64> = pool.iter().map(|&i| (a[i].x - b[i].x) as f64).collect();
        (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt()
    };
    let (noise_bvh, noise_power) = (spread(&bvh, &bvh2), spread(&power, &power2));
    assert!(noise_bvh < 0.6 * noise_power, "pool noise: bvh {noise_bvh}, power {noise_power}");
}

/// Thousands of emissive triangles (five emissive spheres): the tree is
/// deep, and the BVH sampler's image still agrees with selection by power.
#[test]
fn thousands_of_emissive_triangles_agree_between_samplers() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/many-lights.pbrt");
    let scene = Arc::new(atoll_scene::pbrt::load_file(&path).unwrap().scene);
    let frame = atoll_render::FrameContext::new(&scene, RenderOptions::from_scene(&scene));
    let bounded = frame.lights.emitters.len() - frame.lights.unbounded_lights().len();
    assert!(bounded > 10_000, "{bounded} emissive triangles");
    assert_eq!(frame.lights.bvh.nodes.len(), 2 * bounded - 1);
    let bvh = render(&scene, LightSampler::Bvh, 5);
    let power = render(&scene, LightSampler::Power, 6);
    assert_same_means(&bvh, &power);
}
