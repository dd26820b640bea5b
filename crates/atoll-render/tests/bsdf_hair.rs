//! The hair BSDF (pbrt-v4's `HairBxDF`) and hair on curves.
//!
//! What must hold, after pbrt-v4's own hair tests:
//! - a fibre that absorbs nothing reflects and transmits all light (white
//!   furnace), for any roughness and direction;
//! - without absorption every sample's weight `f |cos| / pdf` is 1, since
//!   the lobes are sampled in proportion to their attenuations;
//! - `pdf` integrates to 1 over the sphere, and sampling estimates the same
//!   integral as uniform directions do, with absorption;
//! - the reflection lobe mirrors `wo` about the surface normal, which is
//!   how atoll's offset `h` across the fibre is defined;
//! - rendered: a white fibre under a uniform sky is as bright as the sky
//!   (the tangent frame, the offset and the integrator together).

mod common;

use std::f32::consts::PI;
use std::sync::Arc;

use atoll_render::bsdf::{Bsdf, Hair};
use atoll_render::sampling::sample_uniform_sphere;
use atoll_render::RenderOptions;
use atoll_scene::{HairParams, Rgb};
use common::{assert_finite, mean_and_stderr, render_with, Rng};
use glam::Vec3;

fn hair(sigma_a: Rgb, beta_m: f32, beta_n: f32, alpha: f32) -> Hair {
    Hair::new(&HairParams { sigma_a, eta: 1.55, beta_m, beta_n, alpha })
}

const BETAS: [f32; 5] = [0.1, 0.3, 0.5, 0.7, 0.9];

/// ∫ f |cos θ_i| dω_i over uniform directions, averaged over uniform `wo`:
/// 1 for a fibre that absorbs nothing.
#[test]
fn white_furnace_with_uniform_directions() {
    let mut rng = Rng(0x1234_5678_9abc_def1);
    for beta_m in BETAS {
        for beta_n in BETAS {
            let h = hair(Rgb::ZERO, beta_m, beta_n, 2.0);
            let n = 60_000;
            let mut sum = 0.0f64;
            for _ in 0..n {
                let wo = sample_uniform_sphere(rng.vec2());
                let wi = sample_uniform_sphere(rng.vec2());
                sum += (h.eval(wo, wi).y * wi.z.abs()) as f64 * (4.0 * std::f64::consts::PI);
            }
            let albedo = sum / n as f64;
            assert!((0.95..1.05).contains(&albedo), "beta_m {beta_m}, beta_n {beta_n}: albedo {albedo}");
        }
    }
}

/// Without absorption `pdf` equals `f |cos|` exactly (the lobes'
/// attenuations sum to 1 and are their selection weights).
#[test]
fn samples_weigh_one_without_absorption() {
    let mut rng = Rng(0x0bad_cafe_1234_5678);
    for beta_m in BETAS {
        for beta_n in BETAS {
            let h = Bsdf::Hair(hair(Rgb::ZERO, beta_m, beta_n, 2.0));
            for _ in 0..2_000 {
                let wo = sample_uniform_sphere(rng.vec2());
                let Some(s) = h.sample(wo, rng.next_f32(), rng.vec2()) else { continue };
                let weight = s.f * s.wi.z.abs() / s.pdf;
                for c in 0..3 {
                    assert!(
                        (weight[c] - 1.0).abs() < 2e-3,
                        "beta_m {beta_m}, beta_n {beta_n}, wo {wo}: weight {weight} ({s:?})"
                    );
                }
            }
        }
    }
}

/// `pdf` is a density over the whole sphere.
#[test]
fn pdf_integrates_to_one() {
    let mut rng = Rng(0x5eed_0000_0000_0001);
    for (beta_m, beta_n) in [(0.2, 0.2), (0.3, 0.6), (0.8, 0.3)] {
        let h = hair(Rgb::new(0.4, 0.8, 1.6), beta_m, beta_n, 3.0);
        for _ in 0..4 {
            let wo = sample_uniform_sphere(rng.vec2());
            let n = 200_000;
            let sum: f64 = (0..n).map(|_| h.pdf(wo, sample_uniform_sphere(rng.vec2())) as f64).sum::<f64>();
            let integral = sum / n as f64 * 4.0 * std::f64::consts::PI;
            assert!((integral - 1.0).abs() < 0.04, "beta ({beta_m}, {beta_n}), wo {wo}: ∫pdf = {integral}");
        }
    }
}

/// With absorption, importance sampling and uniform sampling estimate the
/// same directional albedo.
#[test]
fn sampling_and_evaluation_agree_with_absorption() {
    let mut rng = Rng(0xfeed_beef_0000_0042);
    for (beta_m, beta_n) in [(0.2, 0.3), (0.5, 0.5), (0.3, 0.9)] {
        let h = Bsdf::Hair(hair(Rgb::new(0.2, 0.6, 1.4), beta_m, beta_n, 2.0));
        for k in 0..3 {
            let wo = sample_uniform_sphere(rng.vec2());
            let n = 200_000;
            let (mut sampled, mut uniform) = (Vec3::ZERO.as_dvec3(), Vec3::ZERO.as_dvec3());
            for _ in 0..n {
                if let Some(s) = h.sample(wo, rng.next_f32(), rng.vec2()) {
                    sampled += (s.f * s.wi.z.abs() / s.pdf).as_dvec3();
                }
                let wi = sample_uniform_sphere(rng.vec2());
                uniform += (h.eval(wo, wi) * wi.z.abs() * (4.0 * PI)).as_dvec3();
            }
            let (sampled, uniform) = (sampled / n as f64, uniform / n as f64);
            for c in 0..3 {
                let rel = (sampled[c] - uniform[c]).abs() / uniform[c];
                assert!(
                    rel < 0.05,
                    "beta ({beta_m}, {beta_n}) wo #{k}: sampled {sampled}, uniform {uniform}"
                );
            }
        }
    }
}

/// `h` is the sine of the azimuth from the normal (+z) to `wo` about the
/// axis (+x): 0 facing the fibre, ±1 at its silhouettes.
#[test]
fn offset_is_the_sine_of_the_azimuth_from_the_normal() {
    for gamma in [-1.4f32, -0.6, 0.0, 0.3, 1.2] {
        for theta in [-0.8f32, 0.0, 0.5] {
            let wo = Vec3::new(theta.sin(), -theta.cos() * gamma.sin(), theta.cos() * gamma.cos());
            assert!((Hair::offset(wo) - gamma.sin()).abs() < 1e-5, "gamma {gamma}, theta {theta}");
        }
    }
    assert_eq!(Hair::offset(Vec3::X), 0.0);
}

/// A surface's own offset (pbrt's `-1 + 2v`) is used as is, and means
/// what the normal's does: the fibre with offset `h` given equals (times
/// the cosine, and in pdf) the fibre that takes it from the normal, with
/// `wo` and `wi` turned together about the axis.
#[test]
fn a_given_offset_is_the_normals_turned_about_the_axis() {
    let params =
        HairParams { sigma_a: Rgb::new(0.3, 0.7, 1.5), eta: 1.55, beta_m: 0.3, beta_n: 0.4, alpha: 2.0 };
    let from_normal = Hair::new(&params);
    let mut rng = Rng(0xabcd_ef01_2345_6789);
    for _ in 0..200 {
        let (wo, wi) = (sample_uniform_sphere(rng.vec2()), sample_uniform_sphere(rng.vec2()));
        let given = from_normal.with_offset(Hair::offset(wo));
        // Turning both about x keeps their azimuths apart and wo's offset.
        let turn = glam::Quat::from_rotation_x(1.0 + 4.0 * rng.next_f32());
        // f is divided by the cosine to the normal, which the turn changes.
        let (a, b) =
            (from_normal.eval(wo, wi) * wi.z.abs(), given.eval(turn * wo, turn * wi) * (turn * wi).z.abs());
        assert!((a - b).abs().max_element() <= 1e-3 * a.max_element().max(1e-3), "{a} vs {b}");
        let (pa, pb) = (from_normal.pdf(wo, wi), given.pdf(turn * wo, turn * wi));
        assert!((pa - pb).abs() <= 1e-3 * pa.max(1e-3), "{pa} vs {pb}");
    }
}

/// The reflection lobe (R) of a smooth, untilted, opaque fibre peaks at
/// the mirror image of `wo` about the normal: its azimuth mirrored about
/// the normal's, its longitudinal angle negated.
#[test]
fn reflection_peaks_at_the_mirror_direction() {
    // Opaque: only R is left.
    let h = hair(Rgb::splat(50.0), 0.1, 0.1, 0.0);
    for gamma in [-0.9f32, -0.3, 0.2, 0.7] {
        let theta = 0.4f32;
        // wo's azimuth is π/2 + gamma (the normal's is π/2).
        let phi_o = PI / 2.0 + gamma;
        let wo = Vec3::new(theta.sin(), theta.cos() * phi_o.cos(), theta.cos() * phi_o.sin());
        let at = |phi: f32| {
            let wi = Vec3::new(-theta.sin(), theta.cos() * phi.cos(), theta.cos() * phi.sin());
            h.eval(wo, wi).y
        };
        let mirror = PI / 2.0 - gamma;
        let peak = at(mirror);
        for off in [-0.3f32, -0.1, 0.1, 0.3] {
            assert!(
                at(mirror + off) < peak,
                "gamma {gamma}: f at mirror {peak}, at +{off}: {}",
                at(mirror + off)
            );
        }
        // The wrong sign of h would put the peak at phi_o + 2 gamma instead.
        let wrong = phi_o + 2.0 * gamma + PI;
        assert!(gamma.abs() < 0.25 || at(wrong) < 0.5 * peak, "gamma {gamma}");
    }
}

/// A scene of one white fibre (pbrt's `cylinder` curve under the `hair`
/// material) before a uniform sky.
fn white_fibre_scene() -> atoll_scene::Scene {
    let source = r#"
LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" [ 30 ]
Sampler "independent" "integer pixelsamples" [ 256 ]
Integrator "path" "integer maxdepth" [ 64 ]
Film "rgb" "integer xresolution" [ 24 ] "integer yresolution" [ 24 ]
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
Material "hair" "rgb sigma_a" [ 0 0 0 ] "float beta_m" [ 0.3 ] "float beta_n" [ 0.3 ]
Shape "curve" "string type" "cylinder" "point3 P" [ -1 -0.8 0  -0.3 0.2 0.4  0.3 -0.2 -0.4  1 0.8 0 ]
  "float width" [ 0.5 ] "integer splitdepth" [ 4 ]
"#;
    let loaded = atoll_scene::pbrt::load_str(source, "fibre.pbrt", std::path::Path::new(".")).unwrap();
    assert!(loaded.warnings.iter().all(|w| !w.message.contains("hair")), "{:?}", loaded.warnings);
    loaded.scene
}

/// Every pixel the fibre covers is as bright as the sky, as the white
/// furnace demands: the hair frame, its offset and sampling work together
/// through the integrator (NEE, MIS, transmission to both sides).
#[test]
fn white_fibre_under_a_uniform_sky_is_invisible() {
    let scene = Arc::new(white_fibre_scene());
    let film = render_with(&scene, RenderOptions::from_scene(&scene), None);
    assert_finite(&film);
    let (mean, err) = mean_and_stderr(film.pixels().iter().map(|p| p.y));
    assert!((mean - 1.0).abs() < 4.0 * err + 0.01, "mean {mean} ± {err}");
    // Any pixel that sees the fibre agrees too (no dark or bright spots).
    for (i, p) in film.pixels().iter().enumerate() {
        assert!((p.y - 1.0).abs() < 0.25, "pixel {i}: {p}");
    }
}

/// The hits of straight-down rays at `origins` on the scene of pbrt text
/// `source`, traced on the CPU device.
fn hits_from_above(source: &str, origins: &[[f32; 3]]) -> Vec<atoll_render::RayRecord> {
    use atoll_render::stages::generate::camera_record;
    use atoll_render::{CpuDevice, Device, FrameContext, Queue};
    let scene = Arc::new(
        atoll_scene::pbrt::load_str(source, "fibres.pbrt", std::path::Path::new(".")).unwrap().scene,
    );
    let frame = Arc::new(FrameContext::new(&scene, RenderOptions::from_scene(&scene)));
    let mut cpu = CpuDevice::new();
    cpu.prepare(&scene, &atoll_bvh::ScenePart::whole(&scene), &frame).unwrap();
    let rays: Vec<_> = origins
        .iter()
        .map(|&origin| {
            let mut r = camera_record(&frame, 0, 0);
            r.origin = origin;
            r.direction = [0.0, 0.0, -1.0];
            r
        })
        .collect();
    cpu.write_queue(Queue::Paths, &rays).unwrap();
    cpu.trace_paths().unwrap();
    cpu.read_queue(Queue::Paths).unwrap()
}

/// Textured hair parameters (`sigma_a`, `eta`, `beta_m`, `beta_n`,
/// `alpha`) reach the hit's coefficients, the roughnesses clamped to
/// [0.01, 1] as pbrt-v4 clamps them; a textured `reflectance` becomes the
/// absorption at the hit's (textured) `beta_n`; textured melanin adds its
/// absorption.
#[test]
fn textured_hair_parameters_reach_the_hit() {
    use atoll_render::material_layout::hair;
    let source = r#"
LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective"
WorldBegin
Texture "absorption" "spectrum" "constant" "rgb value" [ 0.5 1.5 2.5 ]
Texture "index" "float" "constant" "float value" 1.7
Texture "rough" "float" "constant" "float value" 3
Texture "smooth" "float" "constant" "float value" 0.001
Texture "tilt" "float" "constant" "float value" 4
Material "hair" "texture sigma_a" "absorption" "texture eta" "index" "texture beta_m" "rough"
  "texture beta_n" "smooth" "texture alpha" "tilt"
Shape "curve" "string type" "cylinder" "point3 P" [ -1 0 0  -0.3 0 0  0.3 0 0  1 0 0 ] "float width" [ 0.5 ]
"#;
    let hits = hits_from_above(source, &[[0.3, 0.05, 5.0]]);
    let h = &hits[0];
    assert_eq!(h.material_kind(), atoll_render::record::MaterialKind::Hair);
    assert!((h.coeff3(hair::SIGMA_A) - Vec3::new(0.5, 1.5, 2.5)).abs().max_element() < 2e-3);
    let close = |slot: usize, want: f32| (h.coeff(slot) - want).abs() < 2e-3 * want.max(1.0);
    assert!(close(hair::ETA, 1.7) && close(hair::ALPHA, 4.0), "{:?}", h.coeffs);
    assert_eq!((h.coeff(hair::BETA_M), h.coeff(hair::BETA_N)), (1.0, half::f16::from_f32(0.01).to_f32()));

    // A textured reflectance becomes the absorption at the hit's beta_n.
    let source = source
        .replace("\"texture sigma_a\" \"absorption\"", "\"texture reflectance\" \"colour\"")
        .replace("\"texture beta_n\" \"smooth\"", "\"texture beta_n\" \"half\"");
    let source = source.replace(
        "Material \"hair\"",
        "Texture \"colour\" \"spectrum\" \"constant\" \"rgb value\" [ 0.6 0.3 0.1 ]\n\
         Texture \"half\" \"float\" \"constant\" \"float value\" 0.5\nMaterial \"hair\"",
    );
    let h = &hits_from_above(&source, &[[0.3, 0.05, 5.0]])[0];
    let want = HairParams::sigma_a_from_reflectance(Rgb::new(0.6, 0.3, 0.1), 0.5);
    assert!((h.coeff3(hair::SIGMA_A) - want).abs().max_element() < 2e-3 * want.max_element(), "{want}");

    // A textured eumelanin concentration adds its absorption to the constant pheomelanin's.
    let source = source.replace(
        "\"texture reflectance\" \"colour\"",
        "\"texture eumelanin\" \"half\" \"float pheomelanin\" 2",
    );
    let h = &hits_from_above(&source, &[[0.3, 0.05, 5.0]])[0];
    let want = HairParams::sigma_a_from_concentration(0.5, 2.0);
    assert!((h.coeff3(hair::SIGMA_A) - want).abs().max_element() < 2e-3 * want.max_element(), "{want}");
}

/// Hair hits carry the fibre's axis and offset, `-1 + 2v` as pbrt reads
/// it, on ribbons and cylinder curves alike.
#[test]
fn hits_carry_the_fibres_axis_and_offset() {
    use atoll_render::material_layout::hair;
    let source = r#"
LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective"
WorldBegin
Material "hair"
Shape "curve" "string type" "ribbon" "point3 P" [ -1 0 0  -0.3 0 0  0.3 0 0  1 0 0 ]
  "normal N" [ 0 0 1  0 0 1 ] "float width" [ 0.5 ]
Shape "curve" "string type" "cylinder" "point3 P" [ -1 1 0  -0.3 1 0  0.3 1 0  1 1 0 ] "float width" [ 0.5 ]
"#;
    // Straight down onto the ribbon at y = 0.1, and onto the cylinder 0.05 off its axis.
    let hits = hits_from_above(source, &[[0.3, 0.1, 5.0], [0.3, 1.05, 5.0]]);
    for h in &hits {
        assert_eq!(h.material_kind(), atoll_render::record::MaterialKind::Hair);
        let axis = h.coeff3(hair::TANGENT);
        assert!((axis.x.abs() - 1.0).abs() < 1e-3, "the fibre runs along x: {axis}");
    }
    // The ribbon's v runs from its +y edge (0) to its -y edge (1): y = 0.1
    // is v = 0.3, h = -0.4.
    let ribbon = hits[0].coeff(hair::OFFSET);
    assert!((ribbon + 0.4).abs() < 2e-3, "ribbon offset {ribbon}");
    // The cylinder's v runs the same way across its width of 0.5.
    let cylinder = hits[1].coeff(hair::OFFSET);
    assert!((cylinder + 0.2).abs() < 2e-3, "cylinder offset {cylinder}");
}
