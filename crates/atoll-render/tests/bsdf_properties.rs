//! Physical properties of the BSDFs: Helmholtz reciprocity (and pbrt's
//! non-symmetric relation for radiance-mode transmission), energy
//! conservation of the albedo estimate, the Fresnel equations and the law of
//! refraction.

mod common;

use common::Rng;

use atoll_render::bsdf::{fr_complex, fr_dielectric, refract, Bsdf, Principled};
use atoll_render::sampling::sample_uniform_sphere;
use atoll_scene::{Material, PrincipledParams, Rgb};
use glam::{Vec2, Vec3};

fn gold() -> (Rgb, Rgb) {
    (Rgb::new(0.18, 0.42, 1.37), Rgb::new(3.42, 2.35, 1.77))
}

/// The rough BSDFs the properties are checked on.
fn rough_bsdfs() -> Vec<Bsdf<'static>> {
    let (eta, k) = gold();
    let mut v = vec![Bsdf::Diffuse { reflectance: Rgb::new(0.9, 0.5, 0.1) }];
    for (ax, ay) in [(0.1, 0.1), (0.3, 0.3), (0.7, 0.7), (0.2, 0.6)] {
        v.push(Bsdf::Conductor { eta, k, alpha_x: ax, alpha_y: ay });
    }
    for eta in [1.5, 1.0 / 1.5] {
        for (ax, ay) in [(0.2, 0.2), (0.5, 0.5), (0.1, 0.4)] {
            v.push(Bsdf::Dielectric { eta, alpha_x: ax, alpha_y: ay });
        }
    }
    v
}

fn rel_close(a: Rgb, b: Rgb, rel: f32) -> bool {
    (a - b).abs().max_element() <= rel * a.abs().max(b.abs()).max_element() + 1e-6
}

#[test]
fn reflection_is_reciprocal() {
    let mut rng = Rng(0x1234_5678_9abc_def1);
    for bsdf in rough_bsdfs() {
        let mut nonzero = 0;
        for _ in 0..20_000 {
            let wo = sample_uniform_sphere(rng.vec2());
            let mut wi = sample_uniform_sphere(rng.vec2());
            // Reflection pairs only: put wi on wo's side.
            wi.z = wi.z.abs().copysign(wo.z);
            let (a, b) = (bsdf.eval(wo, wi), bsdf.eval(wi, wo));
            assert!(rel_close(a, b, 1e-3), "{bsdf:?} wo={wo} wi={wi}: {a} vs {b}");
            nonzero += (a.max_element() > 0.0) as u32;
        }
        assert!(nonzero > 1000, "{bsdf:?}: only {nonzero} nonzero values");
    }
}

/// Radiance-mode transmission is not symmetric: with `etap` the relative
/// index seen from `wo` (eta above, 1/eta below), `f(wi, wo) = etap² f(wo, wi)`
/// (pbrt-v4 §9.5.2: `f(wo, wi) / η_o² = f(wi, wo) / η_i²`). The
/// importance-mode value `etap² f(wo, wi)` is symmetric.
#[test]
fn transmission_obeys_the_eta_squared_relation() {
    let mut rng = Rng(0x0fed_cba9_8765_4321);
    for bsdf in rough_bsdfs() {
        let Bsdf::Dielectric { eta, .. } = bsdf else { continue };
        let mut nonzero = 0;
        for _ in 0..20_000 {
            let wo = sample_uniform_sphere(rng.vec2());
            let mut wi = sample_uniform_sphere(rng.vec2());
            wi.z = -wi.z.abs().copysign(wo.z);
            let etap = if wo.z > 0.0 { eta } else { 1.0 / eta };
            let (a, b) = (bsdf.eval(wo, wi), bsdf.eval(wi, wo));
            // Skip pairs within ~1° of grazing on the optically thinner side
            // of their microfacet: the Fresnel term's slope is infinite at
            // the critical angle, so f32 rounding in the two half-vector
            // computations shows up as large relative differences there.
            let wm = (wi * etap + wo).normalize();
            if wo.dot(wm).abs().min(wi.dot(wm).abs()) < 0.02 {
                continue;
            }
            assert!(rel_close(b, a * etap * etap, 1e-3), "{bsdf:?} wo={wo} wi={wi}: {a} vs {b}");
            nonzero += (a.max_element() > 0.0) as u32;
        }
        assert!(nonzero > 1000, "{bsdf:?}: only {nonzero} nonzero values");
    }
}

/// Monte Carlo albedo `E[f |cos θ_i| / pdf]` for `wo`, per channel. With
/// `importance`, transmission samples are multiplied back by `eta²`, undoing
/// the radiance-mode `1 / etap²` (pbrt's `TransportMode::Importance`).
/// Returns the mean and the largest single-sample weight.
fn albedo(bsdf: &Bsdf, wo: Vec3, n: u32, importance: bool, rng: &mut Rng) -> (Rgb, f32) {
    let (mut sum, mut max) = (Rgb::ZERO, 0.0f32);
    for _ in 0..n {
        let uc = rng.next_f32();
        if let Some(s) = bsdf.sample(wo, uc, rng.vec2()) {
            let mut w = s.f * s.wi.z.abs() / s.pdf;
            if importance && s.transmission {
                w *= s.eta * s.eta;
            }
            sum += w;
            max = max.max(w.max_element());
        }
    }
    (sum / n as f32, max)
}

fn wo_angles() -> Vec<Vec3> {
    let mut v = Vec::new();
    for deg in [0.0f32, 30.0, 60.0, 85.0] {
        let t = deg.to_radians();
        let w = Vec3::new(t.sin() * 0.8, t.sin() * 0.6, t.cos());
        v.push(w);
        v.push(Vec3::new(w.x, w.y, -w.z));
    }
    v
}

#[test]
fn albedo_never_exceeds_one() {
    let mut rng = Rng(42);
    for bsdf in rough_bsdfs() {
        for wo in wo_angles() {
            // Dielectrics in importance mode: radiance mode legitimately
            // exceeds 1 going from glass to air (radiance is scaled by η²).
            let importance = matches!(bsdf, Bsdf::Dielectric { .. });
            let (a, max) = albedo(&bsdf, wo, 20_000, importance, &mut rng);
            // Each weight is G/G1 ≤ 1 times Fresnel for the microfacet models
            // and the reflectance for diffuse: the mean is ≤ 1 without noise.
            assert!(max <= 1.0 + 1e-3, "{bsdf:?} wo={wo}: a sample weight {max} > 1");
            assert!(a.max_element() <= 1.0 + 1e-3, "{bsdf:?} wo={wo}: albedo {a}");
        }
    }
}

/// Diffuse transmission: reciprocal on both sides, its albedo is R + T per
/// channel from either side, and a sample lands on the far side with the
/// probability its lobe weight says.
#[test]
fn diffuse_transmission_albedo_is_reflectance_plus_transmittance() {
    let (r, t) = (Rgb::new(0.3, 0.5, 0.1), Rgb::new(0.6, 0.2, 0.4));
    let bsdf = Bsdf::DiffuseTransmission { reflectance: r, transmittance: t };
    let mut rng = Rng(11);
    for wo in wo_angles() {
        let (a, _) = albedo(&bsdf, wo, 40_000, false, &mut rng);
        assert!((a - (r + t)).abs().max_element() < 0.01, "wo={wo}: {a} vs {}", r + t);
        let wi = rng.vec2();
        let wi = Vec3::new(wi.x - 0.5, wi.y - 0.5, -0.6 * wo.z.signum()).normalize();
        assert_eq!(bsdf.eval(wo, wi), bsdf.eval(wi, wo));
        assert_eq!(bsdf.eval(wo, wi), t / std::f32::consts::PI);
        let crossing = (0..4000).filter(|_| {
            let uc = rng.next_f32();
            bsdf.sample(wo, uc, rng.vec2()).unwrap().transmission
        });
        let share = crossing.count() as f32 / 4000.0;
        assert!((share - 0.6 / 1.1).abs() < 0.03, "transmitted share {share}");
    }
}

/// A thin dielectric loses nothing (R + T = 1: every sample weighs 1), and
/// reflects more than one interface: at normal incidence, η = 1.5, 0.04 for
/// the interface and 0.04 + 0.96² 0.04 / (1 - 0.04²) ≈ 0.0769 for the slab.
#[test]
fn thin_dielectric_conserves_energy() {
    let bsdf = Bsdf::ThinDielectric { eta: 1.5 };
    assert!(bsdf.is_delta());
    let mut rng = Rng(5);
    for wo in wo_angles() {
        let (a, max) = albedo(&bsdf, wo, 2_000, false, &mut rng);
        assert!((a - Rgb::ONE).abs().max_element() < 1e-4 && max <= 1.0 + 1e-5, "wo={wo}: {a}");
        let s = bsdf.sample(wo, 0.99, rng.vec2()).unwrap();
        assert!(s.transmission && (s.wi + wo).length() < 1e-6, "straight through");
    }
    let normal = Vec3::Z;
    let reflected = bsdf.sample(normal, 0.0, Vec2::ZERO).unwrap();
    assert!(!reflected.transmission && (reflected.pdf - 0.076_923).abs() < 1e-4, "{}", reflected.pdf);
}

#[test]
fn diffuse_albedo_is_its_reflectance() {
    let r = Rgb::new(0.9, 0.5, 0.1);
    let bsdf = Bsdf::Diffuse { reflectance: r };
    let mut rng = Rng(7);
    for wo in wo_angles() {
        let (a, _) = albedo(&bsdf, wo, 5_000, false, &mut rng);
        assert!((a - r).abs().max_element() < 1e-4, "wo={wo}: {a}");
    }
}

/// A conductor with a huge extinction coefficient is a nearly perfect mirror;
/// pbrt's `reflectance` parameterisation (eta 1, k from r) reproduces r at
/// normal incidence.
#[test]
fn smooth_conductor_albedo() {
    let mut rng = Rng(8);
    let perfect = Bsdf::Conductor { eta: Rgb::ONE, k: Rgb::splat(1000.0), alpha_x: 0.0, alpha_y: 0.0 };
    assert!(perfect.is_delta());
    for wo in wo_angles() {
        let (a, _) = albedo(&perfect, wo, 100, false, &mut rng);
        assert!(a.min_element() > 0.995 && a.max_element() <= 1.0, "wo={wo}: {a}");
    }
    let r = Rgb::new(0.9, 0.6, 0.2);
    let k = Material::conductor_k_from_reflectance(r);
    let tinted = Bsdf::Conductor { eta: Rgb::ONE, k, alpha_x: 0.0, alpha_y: 0.0 };
    let (a, _) = albedo(&tinted, Vec3::Z, 10, false, &mut rng);
    assert!((a - r).abs().max_element() < 1e-3, "{a} vs {r}");
    // A rough near-perfect conductor loses only the energy of single
    // scattering's missing multiple bounces: little at low roughness.
    let rough = Bsdf::Conductor { eta: Rgb::ONE, k: Rgb::splat(1000.0), alpha_x: 0.1, alpha_y: 0.1 };
    let (a, _) = albedo(&rough, Vec3::new(0.0, 0.5, 0.866), 20_000, false, &mut rng);
    assert!(a.min_element() > 0.97 && a.max_element() <= 1.0, "{a}");
}

/// Smooth dielectric: reflection and transmission probabilities are R and
/// 1 − R; each importance-mode weight is exactly 1 (so the albedo is 1), and
/// radiance-mode transmission weights are 1 / etap².
#[test]
fn smooth_dielectric_conserves_energy() {
    for eta in [1.5f32, 1.0 / 1.5, 2.4] {
        let bsdf = Bsdf::Dielectric { eta, alpha_x: 0.0, alpha_y: 0.0 };
        assert!(bsdf.is_delta());
        let mut rng = Rng(9);
        for i in 0..200 {
            let wo = sample_uniform_sphere(rng.vec2());
            let r = fr_dielectric(wo.z, eta);
            let refl = bsdf.sample(wo, 0.0, Vec2::ZERO).unwrap();
            assert!(refl.delta && !refl.transmission);
            assert!((refl.pdf - r).abs() < 1e-6, "{eta} {wo}: {} vs {r}", refl.pdf);
            assert!((refl.wi - Vec3::new(-wo.x, -wo.y, wo.z)).length() < 1e-6);
            match bsdf.sample(wo, 0.999_999, Vec2::ZERO) {
                Some(t) if t.transmission => {
                    assert!((refl.pdf + t.pdf - 1.0).abs() < 1e-6, "{}+{}", refl.pdf, t.pdf);
                    let etap = if wo.z > 0.0 { eta } else { 1.0 / eta };
                    assert_eq!(t.eta, etap);
                    let radiance = t.f.x * t.wi.z.abs() / t.pdf;
                    assert!((radiance * etap * etap - 1.0).abs() < 1e-4, "{i}: {radiance}");
                    assert!(t.wi.z * wo.z < 0.0);
                }
                // Total internal reflection: reflection is certain.
                _ => assert!((refl.pdf - 1.0).abs() < 1e-6 && r == 1.0),
            }
            let w = refl.f.x * refl.wi.z.abs() / refl.pdf;
            assert!((w - 1.0).abs() < 1e-4, "{w}");
        }
        let mut rng = Rng(10);
        for wo in wo_angles() {
            let (a, _) = albedo(&bsdf, wo, 2_000, true, &mut rng);
            assert!((a - Rgb::ONE).abs().max_element() < 1e-4, "{eta} {wo}: {a}");
        }
    }
}

/// The rough dielectric in importance mode loses little energy at low
/// roughness (single-scattering GGX), and none is created.
#[test]
fn rough_dielectric_albedo_is_close_to_one_when_nearly_smooth() {
    let mut rng = Rng(11);
    let bsdf = Bsdf::Dielectric { eta: 1.5, alpha_x: 0.05, alpha_y: 0.05 };
    for wo in [Vec3::Z, -Vec3::Z, Vec3::new(0.5, 0.0, 0.866)] {
        let (a, _) = albedo(&bsdf, wo, 20_000, true, &mut rng);
        assert!(a.min_element() > 0.97 && a.max_element() <= 1.0 + 1e-3, "{wo}: {a}");
    }
}

#[test]
fn fresnel_dielectric_limits() {
    for eta in [1.33f32, 1.5, 2.4, 1.0 / 1.5] {
        let f0 = ((eta - 1.0) / (eta + 1.0)).powi(2);
        assert!((fr_dielectric(1.0, eta) - f0).abs() < 1e-6, "{eta}");
        // Seen from the other side, normal incidence gives the same value.
        assert!((fr_dielectric(-1.0, eta) - f0).abs() < 1e-6, "{eta}");
        assert!(fr_dielectric(1e-4, eta) > 0.99, "{eta}");
        assert!(fr_dielectric(0.0, eta) == 1.0, "{eta}");
        // Grazing reflects more than near-normal incidence.
        assert!(fr_dielectric(0.2, eta) > fr_dielectric(0.9, eta), "{eta}");
    }
    assert_eq!(fr_dielectric(1.0, 1.0), 0.0);
    // Total internal reflection beyond the critical angle sin θc = 1/1.5.
    let cos_c = (1.0f32 - 1.0 / 2.25).sqrt();
    // From inside glass (negative cosine with eta 1.5), or from outside with
    // the inverted index: the same interface.
    assert_eq!(fr_dielectric(-(cos_c - 1e-3), 1.5), 1.0);
    assert_eq!(fr_dielectric(cos_c - 1e-3, 1.0 / 1.5), 1.0);
    assert!(fr_dielectric(-(cos_c + 1e-2), 1.5) < 1.0);
    assert!(fr_dielectric(-0.99, 1.5) < 0.05);
}

#[test]
fn fresnel_complex_limits() {
    for eta in [1.33f32, 1.5, 2.4, 0.5] {
        for i in 0..=100 {
            let c = i as f32 / 100.0;
            let (a, b) = (fr_complex(c, eta, 0.0), fr_dielectric(c, eta));
            assert!((a - b).abs() < 1e-5, "eta {eta} cos {c}: {a} vs {b}");
        }
    }
    // Normal incidence: ((n-1)² + k²) / ((n+1)² + k²).
    let (n, k) = (0.18f32, 3.42f32);
    let f0 = ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
    assert!((fr_complex(1.0, n, k) - f0).abs() < 1e-5);
    assert!(fr_complex(0.5, 1.0, 1e4) > 0.999);
    assert!(fr_complex(0.0, n, k) > 0.999);
    // pbrt's reflectance → k mapping hits the requested value at normal incidence.
    for r in [0.04f32, 0.5, 0.95] {
        let k = Material::conductor_k_from_reflectance(Rgb::splat(r)).x;
        assert!((fr_complex(1.0, 1.0, k) - r).abs() < 1e-4, "{r}");
    }
}

#[test]
fn refraction_follows_snell() {
    let mut rng = Rng(12);
    for eta in [1.5f32, 1.0 / 1.5] {
        for _ in 0..2000 {
            let wo = sample_uniform_sphere(rng.vec2());
            let (eta_o, eta_i) = if wo.z > 0.0 { (1.0, eta) } else { (eta, 1.0) };
            let sin_o = (1.0 - wo.z * wo.z).max(0.0).sqrt();
            match refract(wo, Vec3::Z, eta) {
                Some((wi, etap)) => {
                    assert!((wi.length() - 1.0).abs() < 1e-5);
                    assert!(wi.z * wo.z < 0.0 || wo.z == 0.0);
                    assert!((etap - eta_i / eta_o).abs() < 1e-6);
                    let sin_i = (1.0 - wi.z * wi.z).max(0.0).sqrt();
                    assert!((eta_o * sin_o - eta_i * sin_i).abs() < 1e-4, "{wo} {wi}");
                    // In the plane of incidence, on the far side of the normal.
                    assert!(wo.x * wi.x + wo.y * wi.y <= 1e-6);
                    // Reversible (away from grazing, where it is ill-conditioned).
                    if wi.z.abs().min(wo.z.abs()) > 0.02 {
                        let (back, _) = refract(wi, Vec3::Z, eta).unwrap();
                        assert!((back - wo).length() < 1e-4, "{wo} {back}");
                    }
                }
                None => assert!(eta_o * sin_o > eta_i, "no TIR expected for {wo}"),
            }
        }
    }
}

/// A principled surface with the given weights (specular 0.5, eta 1.5,
/// sheen tint 0.5, gloss 1 unless set after).
fn principled(base: Rgb, metallic: f32, roughness: f32, transmission: f32) -> Principled {
    Principled(PrincipledParams {
        base_color: base,
        metallic,
        roughness,
        specular: 0.5,
        specular_tint: 0.0,
        sheen: 0.0,
        sheen_tint: 0.5,
        clearcoat: 0.0,
        clearcoat_gloss: 1.0,
        transmission,
        eta: 1.5,
    })
}

/// Principled parameter sets covering every lobe, rough and smooth.
fn principled_set(base: Rgb) -> Vec<Principled> {
    let mut v = Vec::new();
    for metallic in [0.0, 0.5, 1.0] {
        for roughness in [0.0, 0.05, 0.3, 0.5, 1.0] {
            v.push(principled(base, metallic, roughness, 0.0));
        }
    }
    for transmission in [0.5, 1.0] {
        for roughness in [0.0, 0.2, 0.6] {
            v.push(principled(base, 0.0, roughness, transmission));
        }
    }
    let p = principled(base, 0.0, 1.0, 0.0);
    v.push(Principled(PrincipledParams { sheen: 1.0, sheen_tint: 0.0, ..p.0 }));
    v.push(Principled(PrincipledParams { sheen: 1.0, specular: 1.0, ..principled(base, 0.0, 0.0, 0.0).0 }));
    v.push(Principled(PrincipledParams { specular: 0.0, ..p.0 }));
    v.push(Principled(PrincipledParams { specular: 1.0, specular_tint: 1.0, roughness: 0.2, ..p.0 }));
    for (metallic, roughness) in [(1.0, 0.0), (1.0, 0.3), (0.0, 1.0), (0.0, 0.05)] {
        for gloss in [0.0, 1.0] {
            let p = principled(base, metallic, roughness, 0.0);
            v.push(Principled(PrincipledParams { clearcoat: 1.0, clearcoat_gloss: gloss, ..p.0 }));
        }
    }
    v.push(Principled(PrincipledParams {
        metallic: 0.3,
        roughness: 0.4,
        specular: 0.8,
        specular_tint: 0.5,
        sheen: 0.5,
        clearcoat: 0.7,
        clearcoat_gloss: 0.8,
        transmission: 0.4,
        ..principled(base, 0.0, 0.0, 0.0).0
    }));
    v
}

/// Reflection pairs of every principled lobe (diffuse with its energy
/// normalisation, specular, glass reflection, sheen, clearcoat) are
/// symmetric; transmission obeys the `etap²` relation of radiance mode.
#[test]
fn principled_is_reciprocal() {
    let mut rng = Rng(0x5eed_1234_abcd_0001);
    for p in principled_set(Rgb::new(0.9, 0.4, 0.1)) {
        let bsdf = Bsdf::Principled(p);
        let (mut reflected, mut transmitted) = (0, 0);
        for _ in 0..20_000 {
            let wo = sample_uniform_sphere(rng.vec2());
            let wi = sample_uniform_sphere(rng.vec2());
            let (a, b) = (bsdf.eval(wo, wi), bsdf.eval(wi, wo));
            if wo.z * wi.z > 0.0 {
                assert!(rel_close(a, b, 1e-3), "{p:?} wo={wo} wi={wi}: {a} vs {b}");
                reflected += (a.max_element() > 0.0) as u32;
            } else {
                let etap = if wo.z > 0.0 { p.eta } else { 1.0 / p.eta };
                // Away from the critical angle, as for the dielectric.
                let wm = (wi * etap + wo).normalize();
                if wo.dot(wm).abs().min(wi.dot(wm).abs()) < 0.02 {
                    continue;
                }
                assert!(rel_close(b, a * etap * etap, 1e-3), "{p:?} wo={wo} wi={wi}: {a} vs {b}");
                transmitted += (a.max_element() > 0.0) as u32;
            }
        }
        assert!(bsdf.is_delta() || reflected > 1000, "{p:?}: only {reflected} nonzero reflection values");
        assert!(p.transmission == 0.0 || p.roughness == 0.0 || transmitted > 1000, "{p:?}: {transmitted}");
    }
}

/// White principled surfaces never reflect (and transmit, in importance
/// mode) more than they receive, at any angle, with every lobe: the
/// Monte Carlo albedo stays below 1 up to three standard errors.
#[test]
fn principled_white_albedo_never_exceeds_one() {
    let mut rng = Rng(0x00a1_bed0);
    let n = 20_000;
    let mut most = (0.0f32, None);
    for p in principled_set(Rgb::ONE) {
        let bsdf = Bsdf::Principled(p);
        for wo in wo_angles() {
            let (mut sum, mut sum2) = (Rgb::ZERO, Rgb::ZERO);
            for _ in 0..n {
                let uc = rng.next_f32();
                if let Some(s) = bsdf.sample(wo, uc, rng.vec2()) {
                    let mut w = s.f * s.wi.z.abs() / s.pdf;
                    if s.transmission {
                        w *= s.eta * s.eta;
                    }
                    sum += w;
                    sum2 += w * w;
                }
            }
            let mean = sum / n as f32;
            let stderr = ((sum2 / n as f32 - mean * mean).max(Rgb::ZERO) / n as f32).map(f32::sqrt);
            let excess = (mean - Rgb::ONE - 3.0 * stderr).max_element();
            assert!(excess <= 1e-3, "{p:?} wo={wo}: albedo {mean} ± {stderr}");
            if mean.max_element() > most.0 {
                most = (mean.max_element(), Some((p, wo)));
            }
        }
    }
    // The tests are not vacuous: some white surfaces are close to 1 (the smooth metal is 1).
    assert!(most.0 > 0.99, "{most:?}");
}

/// Metallic 1, roughness → 0 is a mirror whose reflectance is Schlick's
/// from the base colour: the base colour at normal incidence, white at
/// grazing. Just above the delta threshold the rough lobe reflects about
/// the same.
#[test]
fn smooth_principled_metal_is_a_mirror_of_its_base_colour() {
    let base = Rgb::new(0.9, 0.6, 0.2);
    for roughness in [0.0, 0.01] {
        let bsdf = Bsdf::Principled(principled(base, 1.0, roughness, 0.0));
        assert!(bsdf.is_delta());
        for wo in wo_angles() {
            let s = bsdf.sample(wo, 0.5, Vec2::new(0.3, 0.7)).unwrap();
            assert!(s.delta && !s.transmission && s.pdf == 1.0);
            assert!((s.wi - Vec3::new(-wo.x, -wo.y, wo.z)).length() < 1e-6);
            let schlick = base + (Rgb::ONE - base) * (1.0 - wo.z.abs()).powi(5);
            let weight = s.f * s.wi.z.abs() / s.pdf;
            assert!((weight - schlick).abs().max_element() < 1e-5, "{wo}: {weight} vs {schlick}");
            assert_eq!((bsdf.eval(wo, s.wi), bsdf.pdf(wo, s.wi)), (Rgb::ZERO, 0.0));
        }
    }
    let mut rng = Rng(13);
    let nearly = Bsdf::Principled(principled(base, 1.0, 0.05, 0.0));
    assert!(!nearly.is_delta());
    let (a, _) = albedo(&nearly, Vec3::Z, 20_000, false, &mut rng);
    assert!((a - base).abs().max_element() < 0.01, "{a} vs {base}");
    // With a clearcoat there is a glossy lobe to light-sample.
    let coated = Principled(PrincipledParams { clearcoat: 1.0, ..principled(base, 1.0, 0.0, 0.0).0 });
    assert!(!Bsdf::Principled(coated).is_delta());
}

/// Smooth principled glass of white base colour is the smooth dielectric:
/// reflection with probability R, refraction with 1 − R, weights 1 in
/// importance mode; a coloured base tints transmission by its square root.
#[test]
fn smooth_principled_glass_is_the_dielectric() {
    for eta in [1.5f32, 1.0 / 1.5] {
        let p = Principled(PrincipledParams { eta, ..principled(Rgb::ONE, 0.0, 0.0, 1.0).0 });
        let glass = Bsdf::Principled(p);
        assert!(glass.is_delta());
        let tinted =
            Bsdf::Principled(Principled(PrincipledParams { base_color: Rgb::new(0.25, 1.0, 0.64), ..p.0 }));
        let mut rng = Rng(14);
        for _ in 0..200 {
            let wo = sample_uniform_sphere(rng.vec2());
            let r = fr_dielectric(wo.z, eta);
            let refl = glass.sample(wo, 0.0, Vec2::ZERO).unwrap();
            assert!(refl.delta && !refl.transmission && (refl.pdf - r).abs() < 1e-5, "{wo}: {refl:?}");
            if let Some(t) = glass.sample(wo, 0.999_999, Vec2::ZERO).filter(|t| t.transmission) {
                assert!((refl.pdf + t.pdf - 1.0).abs() < 1e-5);
                let w = t.f * t.wi.z.abs() / t.pdf * t.eta * t.eta;
                assert!((w - Rgb::ONE).abs().max_element() < 1e-4, "{w}");
                let s = tinted.sample(wo, 0.999_999, Vec2::ZERO).unwrap();
                let wt = s.f * s.wi.z.abs() / s.pdf * s.eta * s.eta;
                assert!((wt - Rgb::new(0.5, 1.0, 0.8)).abs().max_element() < 1e-4, "{wt}");
            }
        }
    }
}
