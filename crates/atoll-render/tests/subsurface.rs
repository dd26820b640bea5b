//! Subsurface scattering (pbrt-v4's `subsurface` material, walked as the
//! medium it models) against answers known in closed form: a white
//! interior in a uniform sky is invisible, at any roughness of its
//! boundary, any phase function and even a path depth of 1, since entry
//! and exit count as one bounce; absorption only darkens it, by colour.

mod common;

use std::sync::Arc;

use atoll_render::{Film, RenderOptions};
use common::{assert_finite, mean_and_stderr, render_with};

/// Renders, at 16×16 pixels and `spp` samples with paths of `max_depth`,
/// the world `world` seen from 4 units before `at` (on -z) with a field of
/// view of `fov` degrees.
fn render(at: f64, fov: u32, spp: u32, max_depth: u32, world: &str) -> Film {
    let source = format!(
        r#"
LookAt {at} 0 -4  {at} 0 0  0 1 0
Camera "perspective" "float fov" [ {fov} ]
Sampler "independent" "integer pixelsamples" [ {spp} ]
Integrator "volpath" "integer maxdepth" [ {max_depth} ]
Film "rgb" "integer xresolution" [ 16 ] "integer yresolution" [ 16 ]
WorldBegin
{world}
"#
    );
    let loaded = atoll_scene::pbrt::load_str(&source, "subsurface.pbrt", std::path::Path::new(".")).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let scene = Arc::new(loaded.scene);
    let film = render_with(&scene, RenderOptions::from_scene(&scene), None);
    assert_finite(&film);
    film
}

/// A unit sphere of `material` seen from 4 units away in a uniform sky of
/// radiance 1, at 16×16 pixels and 64 samples, paths of `max_depth`.
fn sphere_in_the_sky(material: &str, max_depth: u32) -> Film {
    let world = format!(
        r#"LightSource "infinite" "rgb L" [ 1 1 1 ]
Material "subsurface" {material}
Shape "sphere" "float radius" [ 1 ]"#
    );
    render(0.0, 30, 64, max_depth, &world)
}

/// Per channel: the mean over the pixels the sphere covers (the middle
/// 8×8) and its standard error.
fn middle(film: &Film) -> [(f64, f64); 3] {
    let pixels = film.pixels();
    [0, 1, 2].map(|c| {
        mean_and_stderr(
            (4..12).flat_map(|y| (4..12).map(move |x| (x, y))).map(|(x, y)| pixels[y * 16 + x][c]),
        )
    })
}

#[test]
fn a_white_interior_vanishes_in_a_uniform_sky() {
    let cases = [
        (r#""rgb sigma_a" [ 0 0 0 ] "rgb sigma_s" [ 4 4 4 ]"#, 1),
        (r#""rgb sigma_a" [ 0 0 0 ] "rgb sigma_s" [ 1 2 8 ] "float g" [ 0.6 ] "float eta" [ 1.5 ]"#, 3),
        (r#""string name" "Spectralon" "float scale" [ 0.5 ]"#, 1),
    ];
    for (material, depth) in cases {
        let film = sphere_in_the_sky(material, depth);
        for (c, (mean, err)) in middle(&film).into_iter().enumerate() {
            eprintln!("{material}, channel {c}: {mean} ± {err}");
            assert!((mean - 1.0).abs() < 4.0 * err + 0.01, "{material}, channel {c}: {mean} ± {err}");
        }
    }
}

/// A rough boundary loses what single-scattering microfacets lose, at the
/// entry only (the exit lobe lets all out): a few percent, never more light.
#[test]
fn a_rough_boundary_loses_only_its_microfacet_share() {
    let film =
        sphere_in_the_sky(r#""rgb sigma_a" [ 0 0 0 ] "rgb sigma_s" [ 3 3 3 ] "float roughness" [ 0.3 ]"#, 2);
    for (c, (mean, err)) in middle(&film).into_iter().enumerate() {
        assert!(mean < 1.0 + 4.0 * err && mean > 0.93, "channel {c}: {mean} ± {err}");
    }
}

#[test]
fn absorption_darkens_by_colour() {
    let white = middle(&sphere_in_the_sky(r#""rgb sigma_a" [ 0 0 0 ] "rgb sigma_s" [ 4 4 4 ]"#, 5));
    let tinted = middle(&sphere_in_the_sky(r#""rgb sigma_a" [ 0.02 0.2 2 ] "rgb sigma_s" [ 4 4 4 ]"#, 5));
    let ketchup = middle(&sphere_in_the_sky(r#""string name" "Ketchup" "float scale" [ 10 ]"#, 5));
    let [r, g, b] = tinted.map(|(m, _)| m);
    assert!(r < white[0].0 && r > g && g > b, "{r} {g} {b}");
    // The Fresnel reflection of the boundary stays: even a black interior
    // is not black.
    assert!(b > 0.02, "{b}");
    let [r, g, b] = ketchup.map(|(m, _)| m);
    assert!(r > 1.5 * g && r > 1.5 * b, "ketchup: {r} {g} {b}");
}

/// Light goes through a thin subsurface slab, where a diffuse one of the
/// same reflectance lets none through; lit from behind by a distant
/// light, seen from the front.
#[test]
fn light_shines_through_a_thin_slab() {
    let slab = |material: &str| {
        let world = format!(
            r#"LightSource "distant" "point3 from" [ 0 0 1 ] "point3 to" [ 0 0 0 ] "rgb L" [ 3 3 3 ]
Material {material}
AttributeBegin
Scale 2 2 0.05
Shape "trianglemesh" "integer indices" [ 0 1 3  0 3 2  4 6 7  4 7 5  0 4 5  0 5 1  2 3 7  2 7 6  0 2 6  0 6 4  1 5 7  1 7 3 ]
  "point3 P" [ -1 -1 -1  1 -1 -1  -1 1 -1  1 1 -1  -1 -1 1  1 -1 1  -1 1 1  1 1 1 ]
AttributeEnd"#
        );
        render(0.0, 20, 32, 5, &world)
    };
    let through = middle(&slab(r#""subsurface" "rgb sigma_a" [ 0.1 0.1 0.1 ] "rgb sigma_s" [ 20 20 20 ]"#));
    let diffuse = middle(&slab(r#""diffuse" "rgb reflectance" [ 0.8 0.8 0.8 ]"#));
    for c in 0..3 {
        assert_eq!(diffuse[c].0, 0.0);
        assert!(through[c].0 > 0.1, "channel {c}: {:?}", through[c]);
    }
}

/// Far from the origin, where many of a dense interior's steps are
/// shorter than the spacing of floats there and end where they began, a
/// walk still draws new numbers at each step (they come from the
/// segment's throughput too), so it ends, and the white interior stays
/// close to invisible.
#[test]
fn walks_far_from_the_origin_end() {
    let world = r#"LightSource "infinite" "rgb L" [ 1 1 1 ]
Translate 100000 0 0
Material "subsurface" "rgb sigma_a" [ 0 0 0 ] "rgb sigma_s" [ 16 16 16 ]
Shape "sphere" "float radius" [ 1 ]"#;
    let film = render(100_000.0, 30, 16, 3, world);
    for (c, (mean, err)) in middle(&film).into_iter().enumerate() {
        assert!(mean > 0.85 && mean < 1.05 + 4.0 * err, "channel {c}: {mean} ± {err}");
    }
}
