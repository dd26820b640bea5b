//! Infinite-light portals (pbrt-v4's `portal`): the environment shines in
//! only through the rectangle, and sampling through it finds the light
//! that a room lets in through a window far more often than sampling the
//! whole sky does.

mod common;

use std::sync::Arc;

use atoll_render::RenderOptions;
use atoll_scene::Scene;
use common::{mean_and_stderr, render_with};

/// A closed room (2 × 2 × 2, diffuse grey) whose ceiling has a square
/// window, under a uniform sky of radiance 1; seen from inside. With
/// `portal`, the sky's portal is the window (pbrt's frame z pointing out
/// of the room).
fn room(portal: bool, spp: u32) -> Arc<Scene> {
    let portal =
        if portal { r#""point3 portal" [ -0.3 2 -0.3  0.3 2 -0.3  0.3 2 0.3  -0.3 2 0.3 ]"# } else { "" };
    let source = format!(
        r#"
LookAt 0 1 -0.9  0 0.5 0.5  0 1 0
Camera "perspective" "float fov" [ 70 ]
Sampler "independent" "integer pixelsamples" [ {spp} ]
Integrator "path" "integer maxdepth" [ 3 ]
Film "rgb" "integer xresolution" [ 32 ] "integer yresolution" [ 32 ]
PixelFilter "box" "float xradius" [ 0.5 ] "float yradius" [ 0.5 ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ] {portal}
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
# Floor and walls, facing in.
Shape "trianglemesh" "point3 P" [ -1 0 -1  1 0 -1  1 0 1  -1 0 1 ] "integer indices" [ 0 1 2 0 2 3 ]
Shape "trianglemesh" "point3 P" [ -1 0 -1  -1 2 -1  -1 2 1  -1 0 1 ] "integer indices" [ 0 1 2 0 2 3 ]
Shape "trianglemesh" "point3 P" [ 1 0 -1  1 2 -1  1 2 1  1 0 1 ] "integer indices" [ 0 1 2 0 2 3 ]
Shape "trianglemesh" "point3 P" [ -1 0 -1  1 0 -1  1 2 -1  -1 2 -1 ] "integer indices" [ 0 1 2 0 2 3 ]
Shape "trianglemesh" "point3 P" [ -1 0 1  1 0 1  1 2 1  -1 2 1 ] "integer indices" [ 0 1 2 0 2 3 ]
# The ceiling around the window [-0.3, 0.3]².
Shape "trianglemesh" "point3 P" [ -1 2 -1  1 2 -1  1 2 -0.3  -1 2 -0.3 ] "integer indices" [ 0 1 2 0 2 3 ]
Shape "trianglemesh" "point3 P" [ -1 2 0.3  1 2 0.3  1 2 1  -1 2 1 ] "integer indices" [ 0 1 2 0 2 3 ]
Shape "trianglemesh" "point3 P" [ -1 2 -0.3  -0.3 2 -0.3  -0.3 2 0.3  -1 2 0.3 ] "integer indices" [ 0 1 2 0 2 3 ]
Shape "trianglemesh" "point3 P" [ 0.3 2 -0.3  1 2 -0.3  1 2 0.3  0.3 2 0.3 ] "integer indices" [ 0 1 2 0 2 3 ]
"#
    );
    let loaded = atoll_scene::pbrt::load_str(&source, "room.pbrt", std::path::Path::new(".")).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    Arc::new(loaded.scene)
}

/// The red channel of `scene` rendered with `seed`.
fn render(scene: &Arc<Scene>, seed: u32) -> Vec<f32> {
    let film = render_with(scene, RenderOptions { seed, ..RenderOptions::from_scene(scene) }, None);
    film.pixels().iter().map(|p| p.x).collect()
}

/// The room renders the same with and without the portal (the window is
/// its only opening, so the same light comes in), and with far less
/// noise: two independent renders of each differ less with the portal.
#[test]
fn a_window_portal_renders_the_room_alike_with_less_noise() {
    let spp = 16;
    let (with_portal, without) = (room(true, spp), room(false, spp));
    let [a, b] = [1, 2].map(|seed| render(&with_portal, seed));
    let [c, d] = [1, 2].map(|seed| render(&without, seed));
    let spread = |x: &[f32], y: &[f32]| {
        x.iter().zip(y).map(|(p, q)| ((p - q) as f64).powi(2)).sum::<f64>() / x.len() as f64
    };
    let (with_portal, without) = (spread(&a, &b), spread(&c, &d));
    eprintln!("pixel noise with the portal {with_portal}, without {without}");
    assert!(with_portal < 0.5 * without, "pixel noise with the portal {with_portal}, without {without}");
    let (m_portal, e_portal) = mean_and_stderr(a.iter().chain(&b).copied());
    let (m_sky, e_sky) = mean_and_stderr(c.iter().chain(&d).copied());
    let err = (e_portal.powi(2) + e_sky.powi(2)).sqrt();
    assert!(
        (m_portal - m_sky).abs() < 4.0 * err + 1e-3,
        "mean {m_portal} ± {e_portal} against {m_sky} ± {e_sky}"
    );
    assert!(m_portal > 0.01, "the room is lit: {m_portal}");
}

/// pbrt-v4's portal lights only through the rectangle: with no room at
/// all, the camera sees the sky through the portal and black beside it,
/// and nothing from in front of the portal.
#[test]
fn the_sky_is_seen_only_through_the_portal() {
    let source = |eye: &str| {
        format!(
            r#"
LookAt {eye}  0 2 0  0 0 1
Camera "perspective" "float fov" [ 90 ]
Sampler "independent" "integer pixelsamples" [ 4 ]
Film "rgb" "integer xresolution" [ 16 ] "integer yresolution" [ 16 ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ] "point3 portal" [ -0.3 2 -0.3  0.3 2 -0.3  0.3 2 0.3  -0.3 2 0.3 ]
"#
        )
    };
    let film = |eye: &str| {
        let loaded =
            atoll_scene::pbrt::load_str(&source(eye), "sky.pbrt", std::path::Path::new(".")).unwrap();
        let scene = Arc::new(loaded.scene);
        render_with(&scene, RenderOptions::from_scene(&scene), None)
    };
    // From below, looking up: the window fills the middle of the image.
    let below = film("0 1 0");
    let px = |x: usize, y: usize| below.pixels()[y * 16 + x].x;
    assert!((px(8, 8) - 1.0).abs() < 1e-5 && (px(7, 7) - 1.0).abs() < 1e-5, "{} {}", px(8, 8), px(7, 7));
    assert_eq!((px(0, 0), px(15, 15), px(0, 8)), (0.0, 0.0, 0.0));
    // From above (in front of the portal): nothing.
    let above = film("0 3 0.001");
    assert!(above.pixels().iter().all(|p| p.x == 0.0));
}
