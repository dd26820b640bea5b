//! The measured BRDF against the closed form it was tabulated from:
//! `scenes/measured-ggx.bsdf` (scripts/measured-scene.py) holds isotropic
//! GGX of alpha 0.3 with a reflectance rising from 0.2 at 400 nm to 0.9 at
//! 700 nm, tabulated so that `f = F D(wm) G1(wo) / (4 cos θo cos θi)`;
//! `scenes/measured-ggx-aniso.bsdf` anisotropic GGX of alphas 0.15 (x) and
//! 0.45 (y) and reflectance 0.7, tabulated over incident azimuths.

use atoll_render::bsdf::Bsdf;
use atoll_scene::pbrt::spectrum::reflectance_rgb_weights;
use atoll_scene::{MeasuredBrdf, Rgb};
use glam::Vec3;
use std::f32::consts::PI;

const ALPHA: f32 = 0.3;
const ANISO_ALPHAS: (f32, f32) = (0.15, 0.45);

fn read(name: &str) -> MeasuredBrdf {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name);
    MeasuredBrdf::from_bytes(&std::fs::read(path).unwrap(), name).unwrap()
}

fn brdf() -> MeasuredBrdf {
    read("measured-ggx.bsdf")
}

/// GGX's `D` of the unit normal `m` with alphas `(ax, ay)`.
fn ggx_d_aniso(m: Vec3, (ax, ay): (f32, f32)) -> f32 {
    let e = (m.x / ax).powi(2) + (m.y / ay).powi(2) + m.z * m.z;
    1.0 / (PI * ax * ay * e * e)
}

fn ggx_d(cos: f32) -> f32 {
    ggx_d_aniso(Vec3::new((1.0 - cos * cos).max(0.0).sqrt(), 0.0, cos), (ALPHA, ALPHA))
}

/// Smith's `G1` of the unit direction `w` for GGX with alphas `(ax, ay)`.
fn smith_g1_aniso(w: Vec3, (ax, ay): (f32, f32)) -> f32 {
    let tan2 = (w.x * w.x * ax * ax + w.y * w.y * ay * ay) / (w.z * w.z);
    2.0 / (1.0 + (1.0 + tan2).sqrt())
}

fn smith_g1(cos: f32) -> f32 {
    smith_g1_aniso(Vec3::new((1.0 - cos * cos).max(0.0).sqrt(), 0.0, cos), (ALPHA, ALPHA))
}

fn direction(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// The file's reflectance spectrum as linear sRGB.
fn reflectance() -> Rgb {
    let wavelengths: Vec<f32> = (0..8).map(|i| 400.0 + 50.0 * i as f32).collect();
    let f = |l: f32| (0.2 + 0.7 * (l - 400.0) / 300.0).clamp(0.2, 0.9);
    reflectance_rgb_weights(&wavelengths).iter().zip(&wavelengths).map(|(w, &l)| *w * f(l)).sum()
}

/// `eval` matches the closed form to the tables' interpolation error, for
/// incidences on and between the tabulated elevations and either side of
/// the surface, and is zero across it.
#[test]
fn measured_ggx_evaluates_as_its_closed_form() {
    let m = brdf();
    let bsdf = Bsdf::Measured(&m);
    let colour = reflectance();
    assert!(colour.x > colour.y && colour.y > colour.z, "a reddish reflectance: {colour}");
    let mut worst = 0.0f32;
    for (to, po) in [(0.0, 0.0), (20.0, 40.0), (35.0, 200.0), (55.0, 300.0), (70.0, 10.0)] {
        for (ti, pi) in [(0.0, 0.0), (15.0, 90.0), (30.0, 210.0), (45.0, 20.0), (60.0, 135.0), (75.0, 250.0)]
        {
            let (wo, wi) = (direction(to, po), direction(ti, pi));
            let wm = (wo + wi).normalize();
            let expected = colour * (ggx_d(wm.z) * smith_g1(wo.z) / (4.0 * wo.z * wi.z));
            if expected.y < 1e-3 {
                continue;
            }
            for flip in [1.0, -1.0] {
                let f = bsdf.eval(wo * flip, wi * flip);
                let error = ((f - expected) / expected).abs().max_element();
                assert!(error < 0.01, "wo {wo} wi {wi}: {f} vs {expected}");
                worst = worst.max(error);
            }
            assert_eq!(bsdf.eval(wo, -wi), Rgb::ZERO);
            assert_eq!(bsdf.pdf(wo, -wi), 0.0);
        }
    }
    eprintln!("worst relative error {worst:.4}");
}

/// The directional albedo by sampling equals the closed form's integral
/// (F times the visible normals whose reflections stay above the surface),
/// which checks `sample`'s weights as a whole.
#[test]
fn measured_ggx_albedo_matches_the_closed_form() {
    let m = brdf();
    let bsdf = Bsdf::Measured(&m);
    for theta in [10.0f32, 45.0, 70.0] {
        let wo = direction(theta, 30.0);
        let n = 400;
        let (mut sampled, mut exact) = (Rgb::ZERO, 0.0f64);
        for i in 0..n {
            for j in 0..n {
                let u = glam::Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                if let Some(s) = bsdf.sample(wo, 0.5, u) {
                    sampled += s.f * (s.wi.z.abs() / s.pdf);
                }
                // ∫ f cos dwi over the hemisphere, in (cos θi, φi) cells.
                let wi = Vec3::new(
                    (1.0 - u.x * u.x).sqrt() * (2.0 * PI * u.y).cos(),
                    (1.0 - u.x * u.x).sqrt() * (2.0 * PI * u.y).sin(),
                    u.x,
                );
                let wm = (wo + wi).normalize();
                exact += (ggx_d(wm.z) * smith_g1(wo.z) / (4.0 * wo.z)) as f64 * 2.0 * PI as f64;
            }
        }
        let sampled = sampled / (n * n) as f32;
        let exact = reflectance() * (exact / (n * n) as f64) as f32;
        let error = ((sampled - exact) / exact).abs().max_element();
        eprintln!("θo {theta}: sampled albedo {sampled} vs {exact}");
        assert!(error < 0.01, "θo {theta}: sampled albedo {sampled} vs {exact}");
    }
}

/// The anisotropic file: `eval` follows the azimuth of both directions (its
/// tables are conditioned on the incident azimuth, its normals absolute),
/// within the coarser tables' interpolation error.
#[test]
fn anisotropic_measured_ggx_evaluates_as_its_closed_form() {
    let m = read("measured-ggx-aniso.bsdf");
    assert!(!m.isotropic);
    let bsdf = Bsdf::Measured(&m);
    let mut worst = 0.0f32;
    for (to, po) in [(10.0, 20.0), (35.0, 100.0), (50.0, 200.0), (65.0, 290.0)] {
        for (ti, pi) in [(15.0, 190.0), (30.0, 300.0), (45.0, 40.0), (60.0, 110.0)] {
            let (wo, wi) = (direction(to, po), direction(ti, pi));
            let wm = (wo + wi).normalize();
            let expected =
                0.7 * ggx_d_aniso(wm, ANISO_ALPHAS) * smith_g1_aniso(wo, ANISO_ALPHAS) / (4.0 * wo.z * wi.z);
            if expected < 1e-2 {
                continue;
            }
            let f = bsdf.eval(wo, wi);
            let error = ((f - Rgb::splat(expected)) / expected).abs().max_element();
            assert!(error < 0.05, "wo {wo} wi {wi}: {f} vs {expected}");
            worst = worst.max(error);
        }
    }
    eprintln!("worst relative error {worst:.4}");
    // Turned a quarter about the normal, a normal tilted along x (alpha
    // 0.15) becomes one tilted along y (alpha 0.45): many times likelier.
    let (wo, wi) = (direction(0.0, 0.0), direction(40.0, 0.0));
    let turned = |w: Vec3| Vec3::new(-w.y, w.x, w.z);
    let (along_x, along_y) = (bsdf.eval(wo, wi).x, bsdf.eval(turned(wo), turned(wi)).x);
    assert!(along_y > 10.0 * along_x, "tilted along x {along_x}, along y {along_y}");
}
