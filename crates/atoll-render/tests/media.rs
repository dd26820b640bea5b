//! Homogeneous participating media against answers known in closed form:
//! a slab's transmittance on shadow rays, a scattering sphere that a
//! uniform sky cannot tell apart from the sky (albedo 1), and a camera
//! inside an emissive fog that sees its emission everywhere.

mod common;

use std::sync::Arc;

use atoll_render::{Film, RenderOptions};
use atoll_scene::Scene;
use common::{assert_finite, mean_and_stderr, render_with};
use glam::Vec3;

fn load(source: &str) -> Arc<Scene> {
    let loaded = atoll_scene::pbrt::load_str(source, "media.pbrt", std::path::Path::new(".")).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    Arc::new(loaded.scene)
}

fn render(scene: &Arc<Scene>) -> Film {
    let film = render_with(scene, RenderOptions::from_scene(scene), None);
    assert_finite(&film);
    film
}

/// A `trianglemesh` box from `lo` to `hi` whose normals point out (pbrt's
/// normal is `cross(p0 - p2, p1 - p2)`; the inside medium lies behind it).
fn box_mesh(lo: Vec3, hi: Vec3) -> String {
    let corner = |i: usize| {
        Vec3::new(
            if i & 1 != 0 { hi.x } else { lo.x },
            if i & 2 != 0 { hi.y } else { lo.y },
            if i & 4 != 0 { hi.z } else { lo.z },
        )
    };
    let faces = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]];
    let centre = (lo + hi) * 0.5;
    let (mut points, mut indices) = (String::new(), String::new());
    for c in 0..8 {
        let p = corner(c);
        points += &format!("{} {} {}  ", p.x, p.y, p.z);
    }
    for f in faces {
        for [a, b, c] in [[f[0], f[1], f[2]], [f[0], f[2], f[3]]] {
            let (p0, p1, p2) = (corner(a), corner(b), corner(c));
            let outwards = (p0 - p2).cross(p1 - p2).dot((p0 + p1 + p2) / 3.0 - centre) > 0.0;
            let [a, b, c] = if outwards { [a, b, c] } else { [a, c, b] };
            indices += &format!("{a} {b} {c}  ");
        }
    }
    format!(r#"Shape "trianglemesh" "point3 P" [ {points}] "integer indices" [ {indices}]"#)
}

/// Ground lit by a sun straight overhead, seen from straight above but
/// under a slab of medium 0.5 thick (1 < y < 1.5); direct light only.
fn sunlit_ground(medium: Option<&str>) -> Arc<Scene> {
    sunlit_ground_with(medium, "")
}

/// [`sunlit_ground`] with more shapes, `extra`.
fn sunlit_ground_with(medium: Option<&str>, extra: &str) -> Arc<Scene> {
    let slab = match medium {
        Some(m) => format!(
            "MakeNamedMedium \"slab\" {m}\nAttributeBegin\nMaterial \"interface\"\n\
             MediumInterface \"slab\" \"\"\n{}\nAttributeEnd",
            box_mesh(Vec3::new(-20.0, 1.0, -20.0), Vec3::new(20.0, 1.5, 20.0))
        ),
        None => String::new(),
    };
    load(&format!(
        r#"
LookAt 0 0.5 0  0 0 0  0 0 1
Camera "perspective" "float fov" [ 60 ]
Sampler "independent" "integer pixelsamples" [ 4 ]
Integrator "volpath" "integer maxdepth" [ 1 ]
Film "rgb" "integer xresolution" [ 24 ] "integer yresolution" [ 16 ]
WorldBegin
LightSource "distant" "point3 from" [ 0 1 0 ] "point3 to" [ 0 0 0 ] "rgb L" [ 1 1 1 ]
Material "diffuse" "rgb reflectance" [ 0.5 0.5 0.5 ]
Shape "trianglemesh" "point3 P" [ -20 0 -20  20 0 -20  20 0 20  -20 0 20 ] "integer indices" [ 0 2 1 0 3 2 ]
{slab}
{extra}
"#
    ))
}

/// Shadow rays through the slab reach the ground with `exp(-σt · 0.5)`
/// per channel, scattering or not (direct light only): every pixel is the
/// vacuum's times that, to rounding, whichever order the two crossings
/// are found in.
#[test]
fn a_slab_dims_sunlight_by_its_transmittance() {
    let clear = render(&sunlit_ground(None));
    let coefficients = r#""string type" "homogeneous" "rgb sigma_a" [ 0.4 1 2 ] "rgb sigma_s" [ 0.6 0 1 ] "float scale" [ 2 ]"#;
    let dimmed = render(&sunlit_ground(Some(coefficients)));
    let expected = (-Vec3::new(1.0, 1.0, 3.0) * 2.0 * 0.5).exp();
    let mut lit = 0;
    for (c, d) in clear.pixels().iter().zip(dimmed.pixels()) {
        if c.min_element() > 1e-3 {
            lit += 1;
            let ratio = d / c;
            assert!(
                (ratio - expected).abs().max_element() < 1e-4 * expected.max_element(),
                "{ratio} vs {expected}"
            );
        }
    }
    assert_eq!(lit, clear.pixels().len(), "the ground fills the view");
}

/// Every pixel of `dimmed` is `expected` times `clear`'s, to 1e-4.
fn assert_dimmed_by(clear: &Film, dimmed: &Film, expected: Vec3) {
    for (c, d) in clear.pixels().iter().zip(dimmed.pixels()) {
        let ratio = d / c;
        assert!(
            (ratio - expected).abs().max_element() < 1e-4 * expected.max_element(),
            "{ratio} vs {expected}"
        );
    }
}

/// An `interface` sheet between the slab and the sun that separates no
/// media: pbrt-v4's `volpath` lets shadow rays through it, so the ground
/// is lit as without it.
#[test]
fn an_interface_without_a_change_of_medium_lets_shadow_rays_through() {
    let coefficients = r#""string type" "homogeneous" "rgb sigma_a" [ 0.4 1 2 ] "rgb sigma_s" [ 0.6 0 1 ]"#;
    let slab = render(&sunlit_ground(Some(coefficients)));
    let sheet = r#"AttributeBegin
Material "interface"
Shape "trianglemesh" "point3 P" [ -20 2 -20  20 2 -20  20 2 20  -20 2 20 ] "integer indices" [ 0 1 2 0 2 3 ]
AttributeEnd"#;
    let sheltered = render(&sunlit_ground_with(Some(coefficients), sheet));
    for (a, b) in slab.pixels().iter().zip(sheltered.pixels()) {
        assert!(a.min_element() > 1e-3);
        assert!((a - b).abs().max_element() < 1e-5 * a.max_element(), "{a} vs {b}");
    }
}

/// A grid medium of density 1 filling the same slab with 4 samples across
/// its height (voxels 0.125 high): pbrt's samples sit at voxel centres
/// and the density falls linearly to 1/2 at the box's faces (the missing
/// neighbours count as 0), losing a quarter voxel at each face: the sun's
/// rays cross 0.5 - 0.125 / 4 of density, exactly.
#[test]
fn a_grid_slab_dims_sunlight_by_its_integral() {
    let clear = render(&sunlit_ground(None));
    let ones = vec!["1"; 2 * 4 * 2].join(" ");
    let grid = format!(
        r#""string type" "uniformgrid" "rgb sigma_a" [ 0.4 1 2 ] "rgb sigma_s" [ 0.6 0 1 ] "integer nx" 2 "integer ny" 4 "integer nz" 2 "point3 p0" [ -20 1 -20 ] "point3 p1" [ 20 1.5 20 ] "float density" [ {ones} ]"#
    );
    let dimmed = render(&sunlit_ground(Some(&grid)));
    let expected = (-Vec3::new(1.0, 1.0, 3.0) * (0.5 - 0.125 / 4.0)).exp();
    assert_dimmed_by(&clear, &dimmed, expected);
}

/// An `rgbgrid` in the same slab: σa from RGB samples (falling to half at
/// the faces, as the density grid's), σs left out, so 1 everywhere in the
/// box (pbrt's default), both times `scale`.
#[test]
fn an_rgb_grid_slab_dims_sunlight_by_its_integral() {
    let clear = render(&sunlit_ground(None));
    let samples = vec!["0.4 1 2"; 2 * 4 * 2].join("  ");
    let grid = format!(
        r#""string type" "rgbgrid" "integer nx" 2 "integer ny" 4 "integer nz" 2 "point3 p0" [ -20 1 -20 ] "point3 p1" [ 20 1.5 20 ] "rgb sigma_a" [ {samples} ] "float scale" 2"#
    );
    let dimmed = render(&sunlit_ground(Some(&grid)));
    let expected = (-(Vec3::new(0.4, 1.0, 2.0) * (0.5 - 0.125 / 4.0) + Vec3::splat(0.5)) * 2.0).exp();
    assert_dimmed_by(&clear, &dimmed, expected);
}

/// A glowing slab of grid medium that only absorbs, over black ground,
/// seen from straight above (rays within half a degree of the vertical):
/// each ray gathers ∫ T σa Le dt = Le (1 − e^(−τ)) whatever the density's
/// profile (here the faces' ramps), estimated where the ray stops in the
/// medium.
#[test]
fn a_glowing_grid_slab_shows_its_emission() {
    let ones = vec!["1"; 2 * 4 * 2].join(" ");
    assert_glowing_slab_shows(
        &format!("\"rgb Le\" [ 3 2 1 ] \"float density\" [ {ones} ]"),
        Vec3::new(3.0, 2.0, 1.0),
        false,
    );
}

/// The same slab glowing by its temperature: a blackbody at
/// (T − offset) × scale kelvin, times `Lescale`, at every sample.
#[test]
fn a_hot_grid_slab_glows_as_a_blackbody() {
    let samples = 2 * 4 * 2;
    let repeat = |v: &str| vec![v; samples].join(" ");
    let emission = format!(
        "\"float density\" [ {} ] \"float temperature\" [ {} ] \"float Lescale\" [ {} ] \
         \"float temperatureoffset\" 100 \"float temperaturescale\" 5",
        repeat("1"),
        repeat("700"),
        repeat("2")
    );
    let le = atoll_scene::pbrt::spectrum::blackbody_peak_normalised_rgb(3000.0) * 2.0;
    assert_glowing_slab_shows(&emission, le, true);
}

/// Renders the glowing slab whose grid (2 × 4 × 2 samples) has
/// `emission`'s parameters and checks that it shows `le`, constant or (if
/// `le_is_gridded`) interpolated between the samples as the density is.
fn assert_glowing_slab_shows(emission: &str, le: Vec3, le_is_gridded: bool) {
    let scene = load(&format!(
        r#"
LookAt 0 3 0  0 0 0  0 0 1
Camera "perspective" "float fov" [ 1 ]
Sampler "independent" "integer pixelsamples" [ 256 ]
Integrator "volpath" "integer maxdepth" [ 5 ]
Film "rgb" "integer xresolution" [ 8 ] "integer yresolution" [ 8 ]
WorldBegin
MakeNamedMedium "glow" "string type" "uniformgrid" "rgb sigma_a" [ 1 2 4 ] "rgb sigma_s" [ 0 0 0 ]
  "integer nx" 2 "integer ny" 4 "integer nz" 2 "point3 p0" [ -20 1 -20 ] "point3 p1" [ 20 1.5 20 ] {emission}
Material "diffuse" "rgb reflectance" [ 0 0 0 ]
Shape "trianglemesh" "point3 P" [ -20 0 -20  20 0 -20  20 0 20  -20 0 20 ] "integer indices" [ 0 2 1 0 3 2 ]
AttributeBegin
Material "interface"
MediumInterface "glow" ""
{}
AttributeEnd
"#,
        box_mesh(Vec3::new(-20.0, 1.0, -20.0), Vec3::new(20.0, 1.5, 20.0))
    ));
    let film = render(&scene);
    // Along the vertical the grid's 4 samples sit at the centres of four
    // layers; the value falls linearly to half at the faces (to 0 half a
    // layer beyond). A gridded emission falls with the density.
    let profile = |u: f32| {
        let x = u * 4.0 - 0.5;
        if x < 0.0 {
            1.0 + x
        } else if x > 3.0 {
            4.0 - x
        } else {
            1.0
        }
    };
    let sigma_a = Vec3::new(1.0, 2.0, 4.0);
    let (steps, thickness) = (100_000, 0.5);
    let (mut depth, mut expected) = (Vec3::ZERO, Vec3::ZERO);
    for i in 0..steps {
        let f = profile((i as f32 + 0.5) / steps as f32);
        let ds = thickness / steps as f32;
        let emitted = if le_is_gridded { le * f } else { le };
        expected += (-(depth + sigma_a * f * ds * 0.5)).exp() * sigma_a * f * emitted * ds;
        depth += sigma_a * f * ds;
    }
    for c in 0..3 {
        let (mean, err) = mean_and_stderr(film.pixels().iter().map(|p| p[c]));
        eprintln!("channel {c}: mean {mean} ± {err}, expected {}", expected[c]);
        let want = expected[c] as f64;
        assert!(
            (mean - want).abs() < 4.0 * err + 2e-3 * le.max_element() as f64,
            "channel {c}: {mean} ± {err} vs {want}"
        );
    }
}

/// `world` (after `WorldBegin`) in a uniform sky of radiance 1, seen from
/// 4 units away at 16×16 pixels, 64 samples, paths up to 200 vertices.
fn under_a_uniform_sky(world: &str) -> Film {
    render(&load(&format!(
        r#"
LookAt 0 0 -4  0 0 0  0 1 0
Camera "perspective" "float fov" [ 30 ]
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "volpath" "integer maxdepth" [ 200 ]
Film "rgb" "integer xresolution" [ 16 ] "integer yresolution" [ 16 ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
{world}
"#
    )))
}

/// Every channel of `film` averages 1 within four standard errors (and 0.01).
fn assert_invisible(what: &str, film: &Film) {
    for c in 0..3 {
        let (mean, err) = mean_and_stderr(film.pixels().iter().map(|p| p[c]));
        eprintln!("{what}, channel {c}: mean {mean} ± {err}");
        assert!((mean - 1.0).abs() < 4.0 * err + 0.01, "{what}, channel {c}: mean {mean} ± {err}");
    }
}

/// A sphere of medium that scatters without absorbing (albedo 1), in a
/// uniform sky of radiance 1: every path leaves it eventually, so it is
/// invisible (pixels average 1), with a forward-scattering and an
/// isotropic phase function.
#[test]
fn a_white_scattering_sphere_vanishes_in_a_uniform_sky() {
    for g in [0.0, 0.7] {
        let film = under_a_uniform_sky(&format!(
            r#"
MakeNamedMedium "cloud" "string type" "homogeneous" "rgb sigma_a" [ 0 0 0 ] "rgb sigma_s" [ 1.5 1.5 1.5 ] "float g" [ {g} ]
AttributeBegin
Material "interface"
MediumInterface "cloud" ""
Shape "sphere" "float radius" [ 1 ]
AttributeEnd
"#
        ));
        assert_invisible(&format!("g {g}"), &film);
        let worst = film.pixels().iter().map(|p| (p.y - 1.0).abs()).fold(0.0, f32::max);
        assert!(worst < 0.35, "g {g}: a pixel differs from the sky by {worst}");
    }
}

/// A box of smoke whose density varies voxel by voxel (0 to 4), albedo 1,
/// placed by a rotation: a uniform sky cannot tell it apart from itself.
/// Exercises distance sampling by inverting the grid's exact optical depth
/// and shadow rays leaving it.
#[test]
fn a_white_smoke_grid_vanishes_in_a_uniform_sky() {
    let density: Vec<String> = (0..5 * 4 * 3).map(|i| format!("{}", (i * 37 % 9) as f32 * 0.5)).collect();
    let film = under_a_uniform_sky(&format!(
        r#"
AttributeBegin
Rotate 30 0.3 1 0.2
MakeNamedMedium "smoke" "string type" "uniformgrid" "rgb sigma_a" [ 0 0 0 ] "rgb sigma_s" [ 1 1.5 2 ] "float g" [ 0.5 ]
  "integer nx" 5 "integer ny" 4 "integer nz" 3 "point3 p0" [ -0.8 -0.7 -0.6 ] "point3 p1" [ 0.8 0.7 0.6 ]
  "float density" [ {} ]
Material "interface"
MediumInterface "smoke" ""
{}
AttributeEnd
"#,
        density.join(" "),
        box_mesh(Vec3::new(-0.8, -0.7, -0.6), Vec3::new(0.8, 0.7, 0.6))
    ));
    assert_invisible("smoke", &film);
}

/// An `rgbgrid` that scatters without absorbing, each colour with its own
/// density pattern (so the channels' optical depths differ from point to
/// point): invisible in a uniform sky, as the density grid's smoke.
#[test]
fn a_white_rgb_grid_vanishes_in_a_uniform_sky() {
    let sigma_s: Vec<String> = (0..4 * 3 * 3)
        .map(|i| format!("{} {} {}", i % 4, ((i * 5) % 7) as f32 * 0.4, (i * 3 % 5) as f32 * 0.7))
        .collect();
    let film = under_a_uniform_sky(&format!(
        r#"
AttributeBegin
Rotate -20 1 0.4 0
MakeNamedMedium "tinted" "string type" "rgbgrid" "rgb sigma_a" [ {} ] "rgb sigma_s" [ {} ] "float scale" 1.5
  "integer nx" 4 "integer ny" 3 "integer nz" 3 "point3 p0" [ -0.8 -0.7 -0.6 ] "point3 p1" [ 0.8 0.7 0.6 ]
Material "interface"
MediumInterface "tinted" ""
{}
AttributeEnd
"#,
        vec!["0 0 0"; 36].join("  "),
        sigma_s.join("  "),
        box_mesh(Vec3::new(-0.8, -0.7, -0.6), Vec3::new(0.8, 0.7, 0.6))
    ));
    assert_invisible("rgb grid", &film);
}

/// A camera inside an endless emitting fog (pbrt's camera medium) sees
/// σa·Le/σt directly and the rest scattered in: Le everywhere, whatever
/// the albedo.
#[test]
fn a_camera_in_glowing_fog_sees_its_emission() {
    let scene = load(
        r#"
MakeNamedMedium "fog" "string type" "homogeneous" "rgb sigma_a" [ 0.5 0.5 0.5 ] "rgb sigma_s" [ 0.5 0.5 0.5 ] "rgb Le" [ 2 2 2 ]
MediumInterface "" "fog"
LookAt 0 0 -4  0 0 0  0 1 0
Camera "perspective" "float fov" [ 30 ]
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "volpath" "integer maxdepth" [ 200 ]
Film "rgb" "integer xresolution" [ 16 ] "integer yresolution" [ 16 ]
WorldBegin
"#,
    );
    assert_eq!(scene.settings.camera_medium, 1);
    let film = render(&scene);
    let (mean, err) = mean_and_stderr(film.pixels().iter().map(|p| p.x));
    eprintln!("fog: mean {mean} ± {err}");
    assert!((mean - 2.0).abs() < 4.0 * err + 0.01, "mean {mean} ± {err}");
}
