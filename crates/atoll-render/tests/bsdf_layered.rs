//! The coated diffuse and coated conductor BSDFs (pbrt-v4's stochastic
//! `LayeredBxDF`).
//!
//! Its `eval`, `sample` and `pdf` are Monte Carlo estimates, so the usual
//! chi-square test of sample counts against `pdf` does not apply: pbrt's
//! layered `pdf` is an approximation for MIS, not the density of `sample`'s
//! directions, and a sample's `pdf` is the density of the random walk that
//! made it. What must hold, and is tested here:
//! - sampling and evaluation estimate the same BSDF: per cell of a grid over
//!   the hemisphere, the mean sample weight `f |cos| / pdf` landing in the
//!   cell equals the integral of `eval |cos|` over it (a z-test against both
//!   estimates' standard errors);
//! - the physics: with a smooth coating over a white base (or a smooth
//!   conductor) the directional albedo equals the closed form of light
//!   bouncing in an absorbing slab;
//!   a non-absorbing medium loses nothing; a black base leaves exactly the
//!   coating's Fresnel reflection;
//! - reciprocity in expectation (independent estimates come from perturbing
//!   the directions by an ulp, which reseeds the walk's hash);
//! - the `pdf` pbrt defines, exactly where it is deterministic (smooth
//!   coating), and positive everywhere (so MIS stays unbiased);
//! - a white furnace render: MIS with the proportional sample density.

mod common;

use std::f64::consts::PI;
use std::sync::Arc;

use atoll_render::bsdf::layered::DIRECTION_SEED_DROP_BITS;
use atoll_render::bsdf::{fr_complex_rgb, fr_dielectric, refract, Bsdf, Coated};
use atoll_render::sampling::{sample_cosine_hemisphere, sample_uniform_sphere};
use atoll_render::RenderOptions;
use atoll_scene::{
    Camera, CoatedConductorParams, CoatedDiffuseParams, Coating, Instance, IntegratorSettings, Light,
    Material, Object, Rgb, Scene, TriangleMesh,
};
use common::{assert_finite, mean_and_stderr, render_with, Rng};
use glam::{Affine3A, UVec2, Vec2, Vec3};

/// pbrt's default coating (index 1.5, walks of 10 events) with these
/// roughnesses and medium.
fn coating((alpha_x, alpha_y): (f32, f32), thickness: f32, albedo: Rgb, g: f32) -> Coating {
    Coating { alpha_x, alpha_y, thickness, albedo, g, ..Coating::PBRT_DEFAULT }
}

fn coated(reflectance: Rgb, alpha: (f32, f32), thickness: f32, albedo: Rgb, g: f32) -> Coated {
    Coated::diffuse(CoatedDiffuseParams { reflectance, coating: coating(alpha, thickness, albedo, g) })
}

/// Gold's index (relative to air) at the RGB primaries.
const GOLD: (Rgb, Rgb) = (Rgb::new(0.143, 0.374, 1.442), Rgb::new(3.983, 2.385, 1.603));

/// A gold conductor of roughness `base_alpha` under a coating.
fn coated_gold(base_alpha: (f32, f32), coating: Coating) -> Coated {
    Coated::conductor(CoatedConductorParams {
        eta: GOLD.0,
        k: GOLD.1,
        alpha_x: base_alpha.0,
        alpha_y: base_alpha.1,
        coating,
    })
}

fn wo_at(theta_deg: f32, phi_deg: f32) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// Running mean and variance of a per-channel estimate.
#[derive(Clone, Copy, Default)]
struct Moments {
    n: f64,
    sum: [f64; 3],
    sum2: [f64; 3],
}

impl Moments {
    fn add(&mut self, v: Rgb) {
        self.n += 1.0;
        for c in 0..3 {
            let x = v[c] as f64;
            self.sum[c] += x;
            self.sum2[c] += x * x;
        }
    }
    /// Adds `count` zeros (samples that contributed nothing).
    fn pad_to(&mut self, count: f64) {
        self.n = count;
    }
    fn mean(&self, c: usize) -> f64 {
        self.sum[c] / self.n
    }
    fn stderr(&self, c: usize) -> f64 {
        let m = self.mean(c);
        ((self.sum2[c] / self.n - m * m).max(0.0) / (self.n - 1.0)).sqrt()
    }
}

/// Directional albedo `E[f |cos| / pdf]` from `sample`, delta samples
/// included, with its standard error per channel.
fn sampled_albedo(c: &Coated, wo: Vec3, n: u32, rng: &mut Rng) -> Moments {
    let bsdf = Bsdf::Coated(*c);
    let mut m = Moments::default();
    for _ in 0..n {
        let uc = rng.next_f32();
        let w = bsdf.sample(wo, uc, rng.vec2()).map_or(Rgb::ZERO, |s| s.f * s.wi.z.abs() / s.pdf);
        m.add(w);
    }
    m
}

/// `∫ eval |cos| dω` over `wo`'s hemisphere by cosine-weighted sampling
/// (the non-delta part of the albedo), with its standard error.
fn evaluated_albedo(c: &Coated, wo: Vec3, n: u32, rng: &mut Rng) -> Moments {
    let mut m = Moments::default();
    for _ in 0..n {
        let mut wi = sample_cosine_hemisphere(rng.vec2());
        wi.z = wi.z.copysign(wo.z);
        m.add(c.eval(wo, wi) * std::f32::consts::PI);
    }
    m
}

/// `∫₀¹ f(μ) dμ` by the midpoint rule in f64.
fn integrate(f: impl Fn(f64) -> f64) -> f64 {
    let n = 20_000;
    (0..n).map(|i| f((i as f64 + 0.5) / n as f64)).sum::<f64>() / n as f64
}

/// Albedo of a smooth coating (index `eta`) over a white Lambertian base,
/// with an absorbing layer of optical depth `t` between them, for light
/// arriving at `cos θ = mu_o`: the coating reflects `R(μo)`; the rest
/// crosses the layer at the refracted angle, is scattered diffusely by the
/// base, crosses the layer again (`e^{-t/μ}`) and leaves with probability
/// `1 - R_inside(μ)` or is mirrored back down to the base, a geometric series.
fn slab_albedo(eta: f32, t: f64, mu_o: f32) -> f64 {
    let r_out = fr_dielectric(mu_o, eta) as f64;
    let (refracted, _) = refract(Vec3::new((1.0 - mu_o * mu_o).sqrt(), 0.0, mu_o), Vec3::Z, eta).unwrap();
    let mu_t = refracted.z.abs() as f64;
    let r_in = |mu: f64| fr_dielectric(-(mu as f32), eta) as f64;
    let escape = integrate(|mu| 2.0 * mu * (-t / mu).exp() * (1.0 - r_in(mu)));
    let back = integrate(|mu| 2.0 * mu * (-2.0 * t / mu).exp() * r_in(mu));
    r_out + (1.0 - r_out) * (-t / mu_t).exp() * escape / (1.0 - back)
}

#[test]
fn smooth_coat_over_white_base_matches_the_slab_series() {
    let mut rng = Rng(0x5eed_0001);
    for thickness in [0.0f32, 0.05, 0.4] {
        let mut c = coated(Rgb::ONE, (0.0, 0.0), thickness, Rgb::ZERO, 0.0);
        // Deep enough that truncation loses < 1e-9 (0.6 of the light goes
        // back down at each visit of the coating).
        c.max_depth = 100;
        for theta in [0.0f32, 40.0, 75.0] {
            let wo = wo_at(theta, 20.0);
            let expected = slab_albedo(1.5, thickness as f64, wo.z);
            let s = sampled_albedo(&c, wo, 100_000, &mut rng);
            // eval misses the coating's specular reflection: add it back.
            let e = evaluated_albedo(&c, wo, 20_000, &mut rng);
            let r = fr_dielectric(wo.z, 1.5) as f64;
            for ch in 0..3 {
                let (ms, es) = (s.mean(ch), s.stderr(ch));
                assert!(
                    (ms - expected).abs() < 5.0 * es + 1e-4,
                    "t={thickness} θ={theta}: sampled albedo {ms} ± {es}, expected {expected}"
                );
                let (me, ee) = (e.mean(ch) + r, e.stderr(ch));
                assert!(
                    (me - expected).abs() < 5.0 * ee + 1e-4,
                    "t={thickness} θ={theta}: evaluated albedo {me} ± {ee}, expected {expected}"
                );
            }
        }
    }
    // The closed form itself: no absorption keeps all the light.
    assert!((slab_albedo(1.5, 0.0, 0.7) - 1.0).abs() < 1e-4);
}

/// A smooth conductor under a smooth coating and an absorbing layer: the
/// coating reflects `R(μo)`; the rest refracts to `μt`, crosses the layer
/// (`T = e^{-t/μt}`), is mirrored by the conductor (`Fc(μt)`, its index
/// divided by the coating's), crosses back, and leaves with `1 - R_in(μt)`
/// or is mirrored down again: `R + (1 - R) T² Fc (1 - R_in) / (1 - R_in T² Fc)`,
/// per channel. Every event is specular, so the BSDF is a delta.
#[test]
fn smooth_coat_over_smooth_conductor_matches_the_mirror_series() {
    let mut rng = Rng(0x5eed_0006);
    for thickness in [0.0f32, 0.1, 0.5] {
        let c = coated_gold(
            (0.0, 0.0),
            Coating { max_depth: 100, ..coating((0.0, 0.0), thickness, Rgb::ZERO, 0.0) },
        );
        assert!(Bsdf::Coated(c).is_delta());
        for theta in [0.0f32, 40.0, 75.0] {
            let wo = wo_at(theta, 20.0);
            let r = fr_dielectric(wo.z, 1.5) as f64;
            let (inside, _) = refract(wo, Vec3::Z, 1.5).unwrap();
            let mu_t = inside.z.abs();
            let r_in = fr_dielectric(-mu_t, 1.5) as f64;
            let t2 = (-2.0 * thickness as f64 / mu_t as f64).exp();
            let fc = fr_complex_rgb(mu_t, GOLD.0 / 1.5, GOLD.1 / 1.5);
            let s = sampled_albedo(&c, wo, 40_000, &mut rng);
            for ch in 0..3 {
                let round = t2 * fc[ch] as f64;
                let expected = r + (1.0 - r) * round * (1.0 - r_in) / (1.0 - r_in * round);
                let (m, e) = (s.mean(ch), s.stderr(ch));
                assert!(
                    (m - expected).abs() < 5.0 * e + 1e-4,
                    "t={thickness} θ={theta} channel {ch}: sampled albedo {m} ± {e}, expected {expected}"
                );
            }
        }
    }
}

/// pbrt's flags for a coated conductor: a delta only when the coating and
/// the conductor are smooth and the medium does not scatter.
#[test]
fn coated_conductor_is_a_delta_only_when_every_layer_is() {
    let smooth = coating((0.0, 0.0), 0.01, Rgb::ZERO, 0.0);
    assert!(Bsdf::Coated(coated_gold((0.0, 0.0), smooth)).is_delta());
    assert!(!Bsdf::Coated(coated_gold((0.1, 0.1), smooth)).is_delta());
    assert!(!Bsdf::Coated(coated_gold((0.0, 0.0), coating((0.1, 0.1), 0.01, Rgb::ZERO, 0.0))).is_delta());
    assert!(
        !Bsdf::Coated(coated_gold((0.0, 0.0), coating((0.0, 0.0), 0.01, Rgb::splat(0.5), 0.0))).is_delta()
    );
}

/// A scattering medium that absorbs nothing over a white base loses no
/// energy under a smooth coating: every walk's weight is exactly 1, however
/// long (hundreds of steps: the weight must not underflow). A rough coating
/// loses what single-scattering GGX loses at each of the many internal
/// visits, and creates none. A grey medium absorbs.
#[test]
fn energy_is_conserved_with_a_scattering_medium() {
    let mut rng = Rng(0x5eed_0002);
    for (alpha, g) in [((0.0, 0.0), 0.0), ((0.0, 0.0), 0.6), ((0.3, 0.3), -0.4), ((0.1, 0.5), 0.2)] {
        let mut c = coated(Rgb::ONE, alpha, 0.5, Rgb::ONE, g);
        c.max_depth = 200;
        for theta in [10.0f32, 60.0] {
            let wo = wo_at(theta, 130.0);
            let s = sampled_albedo(&c, wo, 40_000, &mut rng);
            let (m, e) = (s.mean(0), s.stderr(0));
            if alpha.0 == 0.0 {
                assert!((m - 1.0).abs() < 1e-5, "{c:?} θ={theta}: albedo {m} ± {e}");
            } else {
                assert!(m < 1.0 + 5.0 * e && m > 0.5, "{c:?} θ={theta}: albedo {m} ± {e}");
            }
        }
        let grey = Coated { coating: Coating { albedo: Rgb::splat(0.5), ..c.coating }, ..c };
        let s = sampled_albedo(&grey, wo_at(30.0, 0.0), 20_000, &mut rng);
        assert!(s.mean(0) < 0.95, "{grey:?}: albedo {}", s.mean(0));
    }
}

/// A black base in an absorbing layer under a smooth coating is just the
/// coating's specular reflection: `eval` is zero, and the sampled weight
/// (1 for the reflection, nothing for light that enters) averages to the
/// Fresnel reflectance. Under a rough coating `eval` is the rough
/// dielectric's reflection.
#[test]
fn black_base_leaves_the_coating_alone() {
    let smooth = coated(Rgb::ZERO, (0.0, 0.0), 0.01, Rgb::ZERO, 0.0);
    assert!(Bsdf::Coated(smooth).is_delta());
    assert!(!Bsdf::Coated(coated(Rgb::splat(0.1), (0.0, 0.0), 0.01, Rgb::ZERO, 0.0)).is_delta());
    assert!(!Bsdf::Coated(coated(Rgb::ZERO, (0.0, 0.0), 0.01, Rgb::splat(0.1), 0.0)).is_delta());
    let bsdf = Bsdf::Coated(smooth);
    let mut rng = Rng(3);
    for theta in [0.0f32, 30.0, 60.0, 85.0] {
        for below in [false, true] {
            let mut wo = wo_at(theta, 75.0);
            if below {
                wo.z = -wo.z;
            }
            let n = 10_000;
            let mut sum = 0.0f64;
            for i in 0..n {
                let uc = (i as f32 + 0.5) / n as f32;
                if let Some(s) = bsdf.sample(wo, uc, rng.vec2()) {
                    assert!(s.delta && !s.transmission, "{s:?}");
                    assert_eq!(s.wi, Vec3::new(-wo.x, -wo.y, wo.z));
                    sum += (s.f.x * s.wi.z.abs() / s.pdf) as f64;
                }
            }
            let r = fr_dielectric(wo.z.abs(), 1.5) as f64;
            assert!((sum / n as f64 - r).abs() < 2e-4, "θ={theta}: {} vs Fresnel {r}", sum / n as f64);
            let wi = sample_uniform_sphere(rng.vec2());
            assert_eq!(bsdf.eval(wo, wi), Rgb::ZERO);
        }
    }
    let rough = coated(Rgb::ZERO, (0.3, 0.15), 0.01, Rgb::ZERO, 0.0);
    let dielectric = Bsdf::Dielectric { eta: 1.5, alpha_x: 0.3, alpha_y: 0.15 };
    let mut nonzero = 0;
    for _ in 0..2000 {
        let wo = sample_uniform_sphere(rng.vec2());
        let mut wi = sample_uniform_sphere(rng.vec2());
        wi.z = wi.z.abs().copysign(wo.z);
        let (a, b) = (Bsdf::Coated(rough).eval(wo, wi), dielectric.eval(wo, wi));
        // Seen from below, the two-sided coating is the one seen from above.
        let b = if wo.z < 0.0 { dielectric.eval(-wo, -wi) } else { b };
        assert_eq!(a, b, "wo={wo} wi={wi}");
        nonzero += (a.x > 0.0) as u32;
    }
    assert!(nonzero > 1000);
}

/// Per cell of a (cos θ, φ) grid over `wo`'s hemisphere: the mean of
/// `f |cos| / pdf` over samples landing in it (delta samples left out:
/// `eval` excludes them) against `∫ eval |cos| dω` over it, by stratified
/// uniform points. Returns the largest |z| score over cells and the
/// total of both over the hemisphere.
fn compare_sample_with_eval(c: &Coated, wo: Vec3, seed: u64) -> (f64, f64, f64) {
    const COS_RES: usize = 6;
    const PHI_RES: usize = 8;
    const SAMPLES: u32 = 150_000;
    const POINTS_PER_CELL: u32 = 600;
    let cells = COS_RES * PHI_RES;
    let bsdf = Bsdf::Coated(*c);
    let side = wo.z.signum();
    let cell_of = |w: Vec3| {
        let ci = ((w.z.abs() * COS_RES as f32) as usize).min(COS_RES - 1);
        let phi = (w.y.atan2(w.x) as f64).rem_euclid(2.0 * PI);
        let pi = ((phi / (2.0 * PI) * PHI_RES as f64) as usize).min(PHI_RES - 1);
        ci * PHI_RES + pi
    };
    let mut rng = Rng(seed);
    let mut sampled = vec![Moments::default(); cells];
    for _ in 0..SAMPLES {
        let uc = rng.next_f32();
        let Some(s) = bsdf.sample(wo, uc, rng.vec2()) else { continue };
        if s.delta {
            continue;
        }
        assert!(s.wi.z * side > 0.0, "{s:?}: the base is opaque");
        sampled[cell_of(s.wi)].add(s.f * s.wi.z.abs() / s.pdf);
    }
    // Each cell covers 2π / cells of solid angle (uniform in cos θ and φ).
    let area = 2.0 * PI / cells as f64;
    let mut worst: f64 = 0.0;
    let (mut total_s, mut total_e) = (0.0, 0.0);
    for (cell, s) in sampled.iter_mut().enumerate() {
        s.pad_to(SAMPLES as f64);
        let (ci, pi) = (cell / PHI_RES, cell % PHI_RES);
        let mut e = Moments::default();
        for _ in 0..POINTS_PER_CELL {
            let u = rng.vec2();
            let cos = (ci as f32 + u.x) / COS_RES as f32;
            let phi = (pi as f32 + u.y) / PHI_RES as f32 * 2.0 * std::f32::consts::PI;
            let sin = (1.0 - cos * cos).max(0.0).sqrt();
            let wi = Vec3::new(sin * phi.cos(), sin * phi.sin(), cos * side);
            e.add(c.eval(wo, wi) * cos * area as f32);
        }
        for ch in 0..3 {
            let (a, b) = (s.mean(ch), e.mean(ch));
            let err = (s.stderr(ch).powi(2) + e.stderr(ch).powi(2)).sqrt();
            if err > 0.0 {
                worst = worst.max((a - b).abs() / err);
            } else {
                assert_eq!(a, b, "cell {cell}");
            }
        }
        total_s += s.mean(0);
        total_e += e.mean(0);
    }
    (worst, total_s, total_e)
}

#[test]
fn sampling_and_evaluation_estimate_the_same_bsdf() {
    let cases = [
        coated(Rgb::new(0.8, 0.4, 0.1), (0.0, 0.0), 0.01, Rgb::ZERO, 0.0),
        coated(Rgb::new(0.8, 0.4, 0.1), (0.2, 0.2), 0.01, Rgb::ZERO, 0.0),
        coated(Rgb::new(0.5, 0.9, 0.3), (0.5, 0.15), 0.1, Rgb::ZERO, 0.0),
        coated(Rgb::splat(0.7), (0.0, 0.0), 0.3, Rgb::new(0.9, 0.5, 0.2), 0.5),
        coated(Rgb::splat(0.7), (0.3, 0.3), 0.3, Rgb::new(0.9, 0.5, 0.2), -0.3),
        // Conductor bases: rough under smooth, rough under rough, and with
        // a medium (a smooth one under a rough coating is tested apart).
        coated_gold((0.3, 0.15), coating((0.0, 0.0), 0.01, Rgb::ZERO, 0.0)),
        coated_gold((0.2, 0.2), coating((0.4, 0.1), 0.01, Rgb::ZERO, 0.0)),
        coated_gold((0.3, 0.3), coating((0.1, 0.2), 0.3, Rgb::new(0.9, 0.5, 0.2), 0.4)),
    ];
    let mut failures = Vec::new();
    let mut seed = 100;
    for c in &cases {
        for wo in [wo_at(10.0, 30.0), wo_at(55.0, 200.0), wo_at(80.0, 300.0), -wo_at(35.0, 100.0)] {
            seed += 1;
            let (worst, s, e) = compare_sample_with_eval(c, wo, seed);
            // 48 cells × 3 channels × 32 cases ≈ 4600 z scores: 5σ is a
            // false alarm once in ~400 runs of the file.
            if worst > 5.0 {
                failures.push(format!("{c:?} wo={wo}: worst z {worst:.2} (totals {s:.4} vs {e:.4})"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A smooth conductor under a rough coating: light leaves only by the
/// walk's connections through the coating after each mirror bounce (no
/// MIS), so `eval`'s estimates are heavy-tailed and per-cell z scores mean
/// little. The albedo from sampling and from evaluating must still agree.
#[test]
fn specular_base_under_a_rough_coating_samples_what_it_evaluates() {
    let mut rng = Rng(0x5eed_0007);
    for (alpha, thickness) in [(0.25, 0.1), (0.5, 0.01)] {
        let c = coated_gold((0.0, 0.0), coating((alpha, alpha), thickness, Rgb::ZERO, 0.0));
        for wo in [wo_at(10.0, 30.0), wo_at(55.0, 200.0), -wo_at(35.0, 100.0)] {
            let s = sampled_albedo(&c, wo, 100_000, &mut rng);
            let e = evaluated_albedo(&c, wo, 400_000, &mut rng);
            for ch in 0..3 {
                let (a, b) = (s.mean(ch), e.mean(ch));
                assert!(
                    (a - b).abs() < 0.02 * a,
                    "α={alpha} wo={wo} channel {ch}: sampled {a}, evaluated {b}"
                );
            }
        }
    }
}

/// `E[eval(wo, wi)] ≈ E[eval(wi, wo)]`: each estimate is averaged over
/// directions perturbed by ~1e-4..1e-3 (which reseeds the walk).
#[test]
fn evaluation_is_reciprocal_in_expectation() {
    let mut rng = Rng(0x5eed_0004);
    let cases = [
        coated(Rgb::new(0.8, 0.4, 0.1), (0.25, 0.25), 0.1, Rgb::ZERO, 0.0),
        coated(Rgb::splat(0.6), (0.1, 0.4), 0.4, Rgb::splat(0.8), 0.3),
        coated(Rgb::splat(0.6), (0.0, 0.0), 0.4, Rgb::splat(0.8), -0.3),
    ];
    for mut c in cases {
        c.max_depth = 100;
        for _ in 0..4 {
            let wo = sample_uniform_sphere(rng.vec2());
            let mut wi = sample_uniform_sphere(rng.vec2());
            wi.z = wi.z.abs().copysign(wo.z);
            let estimate = |a: Vec3, b: Vec3| {
                let mut m = Moments::default();
                for k in 0..4000u32 {
                    // Three bits of k per component, above the bits the
                    // seed rounds off (a nudge of at most ~1e-3): 4000
                    // distinct seeds.
                    let nudge = |v: Vec3, first: u32| {
                        let bits = |x: f32, j: u32| {
                            let flip = ((k >> (3 * (first + j))) & 7) << DIRECTION_SEED_DROP_BITS;
                            f32::from_bits(x.to_bits() ^ flip)
                        };
                        Vec3::new(bits(v.x, 0), bits(v.y, 1), bits(v.z, 2))
                    };
                    m.add(c.eval(nudge(a, 0), nudge(b, 3)));
                }
                m
            };
            let (f, r) = (estimate(wo, wi), estimate(wi, wo));
            for ch in 0..3 {
                let err = (f.stderr(ch).powi(2) + r.stderr(ch).powi(2)).sqrt();
                let d = (f.mean(ch) - r.mean(ch)).abs();
                assert!(
                    d < 5.0 * err + 1e-6,
                    "{c:?} wo={wo} wi={wi}: {} vs {} ± {err}",
                    f.mean(ch),
                    r.mean(ch)
                );
            }
        }
    }
}

/// With a smooth coating the walk's way in and out are refractions, so
/// pbrt's pdf is deterministic: 10% uniform plus 90% the base's cosine
/// density of the refracted `wi`. Rough coatings: positive and finite
/// everywhere (MIS needs it wherever `f` is), the same for a query from
/// below (two-sided), repeatable.
#[test]
fn pdf_is_pbrts_mis_density() {
    let mut rng = Rng(0x5eed_0005);
    let uniform = 0.1 / (4.0 * std::f32::consts::PI);
    let close = |a: f32, b: f32| (a - b).abs() <= 1e-5 * b;
    let smooth = Bsdf::Coated(coated(Rgb::splat(0.5), (0.0, 0.0), 0.01, Rgb::ZERO, 0.0));
    for _ in 0..1000 {
        let wo = sample_uniform_sphere(rng.vec2());
        let mut wi = sample_uniform_sphere(rng.vec2());
        wi.z = wi.z.abs().copysign(wo.z);
        // Refracted into the coating from above (a query from below is mirrored).
        let inside = refract(Vec3::new(wi.x, wi.y, wi.z.abs()), Vec3::Z, 1.5).unwrap().0;
        let expected = uniform + 0.9 * inside.z.abs() / std::f32::consts::PI;
        let got = smooth.pdf(wo, wi);
        assert!(close(got, expected), "wo={wo} wi={wi}: {got} vs {expected}");
        // Across the surface: only the uniform part.
        assert!(close(smooth.pdf(wo, Vec3::new(wi.x, wi.y, -wi.z)), uniform));
    }
    for c in [
        coated(Rgb::splat(0.5), (0.3, 0.3), 0.01, Rgb::ZERO, 0.0),
        coated(Rgb::splat(0.9), (0.05, 0.6), 0.3, Rgb::splat(0.5), 0.4),
        coated_gold((0.0, 0.0), coating((0.3, 0.3), 0.01, Rgb::ZERO, 0.0)),
        coated_gold((0.2, 0.3), coating((0.3, 0.3), 0.01, Rgb::ZERO, 0.0)),
    ] {
        let bsdf = Bsdf::Coated(c);
        let mut sum = 0.0f64;
        for _ in 0..4000 {
            let wo = sample_uniform_sphere(rng.vec2());
            let mut wi = sample_uniform_sphere(rng.vec2());
            wi.z = wi.z.abs().copysign(wo.z);
            let p = bsdf.pdf(wo, wi);
            assert!(p.is_finite() && p >= uniform * (1.0 - 1e-5), "{c:?} wo={wo} wi={wi}: {p}");
            assert_eq!(p, bsdf.pdf(wo, wi));
            assert_eq!(p, bsdf.pdf(-wo, -wi));
            sum += p as f64;
        }
        // Not a normalised density: pbrt adds the coating's reflection-only
        // density (mass ~1) to the estimate of the paths through the base
        // (mass ~1), so it integrates to about 2 over the hemisphere.
        // Less over a conductor, whose walks mostly leave at angles the
        // coating reflects back (total internal reflection).
        let mass = sum / 4000.0 * 2.0 * PI;
        assert!((1.0..2.5).contains(&mass), "{c:?}: {mass}");
    }
}

/// Same inputs, same estimates; different inputs, different walks.
#[test]
fn estimates_are_deterministic_hashes_of_their_inputs() {
    let c = coated(Rgb::splat(0.6), (0.2, 0.2), 0.3, Rgb::splat(0.7), 0.2);
    let bsdf = Bsdf::Coated(c);
    let (wo, wi) = (wo_at(30.0, 10.0), wo_at(50.0, 200.0));
    assert_eq!(bsdf.eval(wo, wi), bsdf.eval(wo, wi));
    assert_eq!(bsdf.sample(wo, 0.7, Vec2::new(0.3, 0.9)), bsdf.sample(wo, 0.7, Vec2::new(0.3, 0.9)));
    let distinct: std::collections::HashSet<u32> =
        (0..50).map(|k| bsdf.eval(wo, wi + Vec3::splat(k as f32 * 1e-3)).x.to_bits()).collect();
    assert!(distinct.len() > 40, "{} distinct values of 50", distinct.len());
    // An ulp of difference (two devices' rounding) keeps the walk: the
    // value changes by rounding, not by a new random walk.
    let nudged =
        |v: Vec3| Vec3::new(f32::from_bits(v.x.to_bits() + 1), v.y, f32::from_bits(v.z.to_bits() - 1));
    let (a, b) = (bsdf.eval(wo, wi), bsdf.eval(nudged(wo), nudged(wi)));
    assert!((a - b).abs().max_element() <= 1e-4 * a.max_element(), "{a} vs {b}");
    assert!(bsdf.sampled_pdf_is_proportional());
    assert!(!Bsdf::Diffuse { reflectance: Rgb::ONE }.sampled_pdf_is_proportional());
}

/// A UV sphere of radius 1 with smooth normals.
fn sphere(material: u32) -> TriangleMesh {
    common::uv_sphere(material, 32, 64)
}

/// A coated white sphere that absorbs nothing (smooth coating, no
/// absorbing layer) under a uniform sky of radiance 1 is invisible: every
/// pixel is 1. The path integrator's MIS must weigh BSDF samples with the
/// layered `pdf` (not the walk's density) for the two strategies to sum up.
#[test]
fn lossless_coated_sphere_under_uniform_sky_is_invisible() {
    let material = Material::CoatedDiffuse(CoatedDiffuseParams {
        reflectance: Rgb::ONE,
        coating: Coating { max_depth: 100, ..coating((0.0, 0.0), 0.0, Rgb::ZERO, 0.0) },
    });
    let mut scene = Scene { materials: vec![material], ..Default::default() };
    let mesh = scene.add_mesh(sphere(0));
    let object = scene.add_object(Object { name: "world".into(), meshes: vec![mesh] });
    scene.instances.push(Instance::new(object, Affine3A::IDENTITY));
    scene.settings.camera = Camera {
        camera_to_world: glam::camera::lh::view::look_at_mat4(Vec3::new(0.0, 0.0, -3.0), Vec3::ZERO, Vec3::Y)
            .inverse(),
        fov_degrees: 50.0,
        ..Camera::default()
    };
    scene.lights.push(Light::Infinite { radiance: Rgb::ONE, portal: None });
    let options = RenderOptions {
        resolution: UVec2::new(24, 24),
        spp: 48,
        integrator: IntegratorSettings::Path { max_depth: 8 },
        seed: 5,
        russian_roulette: true,
        light_sampler: Default::default(),
        wave_size: 1 << 16,
        merge_waves: true,
        crop: None,
        film_response: glam::Mat3::IDENTITY,
        filter: atoll_scene::PixelFilter::PIXEL,
    };
    let film = render_with(&Arc::new(scene), options, None);
    assert_finite(&film);
    for c in 0..3 {
        let (mean, err) = mean_and_stderr(film.pixels().iter().map(|p| p[c]));
        assert!((mean - 1.0).abs() < 4.0 * err + 3e-3, "channel {c}: mean {mean} ± {err}");
    }
}
