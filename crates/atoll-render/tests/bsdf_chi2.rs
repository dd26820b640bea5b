//! Chi-square goodness-of-fit tests of every rough BSDF's sampling routine
//! against its `pdf`, in the manner of pbrt-v4's `bsdfs_test.cpp` and
//! Mitsuba's `chi2` module: histogram many samples over a (θ, φ) grid of the
//! whole sphere, integrate `pdf` over each cell numerically, pool cells with
//! a low expected count, and compare with a chi-square test at significance
//! 0.01, Bonferroni-corrected over all cases of this file. Failed samples
//! (`None`) get their own cell, whose expected count is the mass the pdf does
//! not cover, so a pdf with the wrong normalisation fails too.
//!
//! Along the way every sample's `pdf` and `f` are compared with `Bsdf::pdf`
//! and `Bsdf::eval` for the same direction (all cases are rough, so a delta
//! sample is an error too).

use atoll_render::bsdf::{Bsdf, Hair, Principled};
use atoll_scene::{HairParams, MeasuredBrdf, PrincipledParams, Rgb};
use glam::{Vec2, Vec3};
use std::f64::consts::PI;

const SAMPLES: u32 = 1 << 20;
const THETA_RES: usize = 24;
const PHI_RES: usize = 2 * THETA_RES;
const MIN_EXPECTED: f64 = 5.0;
const SIGNIFICANCE: f64 = 0.01;
/// Every sample's `pdf` and `f` must match `Bsdf::pdf` and `Bsdf::eval` to
/// this relative tolerance, except for a fraction `CONSISTENCY_OUTLIERS` of
/// them, which must still be within ten times it. The outliers are f32
/// rounding amplified by the Fresnel term's infinite slope at the critical
/// angle: `eval` rebuilds the half vector from `wi`, `sample` had it exactly.
const CONSISTENCY_TOLERANCE: f32 = 1e-3;
const CONSISTENCY_OUTLIERS: f64 = 1e-5;

/// PCG32 (O'Neill), enough for tests without an RNG dependency.
struct Pcg32 {
    state: u64,
}

impl Pcg32 {
    fn new(seed: u64) -> Self {
        let mut r = Pcg32 { state: 0 };
        r.next_u32();
        r.state = r.state.wrapping_add(seed);
        r.next_u32();
        r
    }
    fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        xorshifted.rotate_right((old >> 59) as u32)
    }
    /// Uniform in [0, 1) with 24 bits, exactly representable in f32.
    fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
}

/// The chi-square distribution's CDF through the regularised lower
/// incomplete gamma function `P(a, x)` (Numerical Recipes' `gammp`: series
/// for `x < a + 1`, Lentz continued fraction for `Q` otherwise).
mod chi2 {
    fn ln_gamma(x: f64) -> f64 {
        // Lanczos approximation (g = 7, n = 9), accurate to ~1e-15.
        const C: [f64; 9] = [
            0.999_999_999_999_809_9,
            676.520_368_121_885_1,
            -1_259.139_216_722_402_8,
            771.323_428_777_653_1,
            -176.615_029_162_140_6,
            12.507_343_278_686_905,
            -0.138_571_095_265_720_12,
            9.984_369_578_019_572e-6,
            1.505_632_735_149_311_6e-7,
        ];
        let x = x - 1.0;
        let mut a = C[0];
        let t = x + 7.5;
        for (i, c) in C.iter().enumerate().skip(1) {
            a += c / (x + i as f64);
        }
        0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
    }

    /// Regularised lower incomplete gamma `P(a, x)`.
    pub fn gamma_p(a: f64, x: f64) -> f64 {
        assert!(a > 0.0 && x >= 0.0);
        if x == 0.0 {
            return 0.0;
        }
        let log_prefactor = -x + a * x.ln() - ln_gamma(a);
        if x < a + 1.0 {
            let (mut ap, mut del) = (a, 1.0 / a);
            let mut sum = del;
            for _ in 0..1000 {
                ap += 1.0;
                del *= x / ap;
                sum += del;
                if del.abs() < sum.abs() * 1e-15 {
                    break;
                }
            }
            sum * log_prefactor.exp()
        } else {
            let tiny = 1e-300;
            let mut b = x + 1.0 - a;
            let mut c = 1.0 / tiny;
            let mut d = 1.0 / b;
            let mut h = d;
            for i in 1..1000 {
                let an = -(i as f64) * (i as f64 - a);
                b += 2.0;
                d = an * d + b;
                if d.abs() < tiny {
                    d = tiny;
                }
                c = b + an / c;
                if c.abs() < tiny {
                    c = tiny;
                }
                d = 1.0 / d;
                let del = d * c;
                h *= del;
                if (del - 1.0).abs() < 1e-15 {
                    break;
                }
            }
            1.0 - log_prefactor.exp() * h
        }
    }

    /// `P[X <= x]` for a chi-square variable with `dof` degrees of freedom.
    pub fn cdf(x: f64, dof: f64) -> f64 {
        gamma_p(dof / 2.0, x / 2.0)
    }
}

#[test]
fn chi2_cdf_matches_tables() {
    // Reference values from standard chi-square tables (upper-tail critical
    // values) and closed forms (dof 2: 1 - e^{-x/2}).
    for (x, dof, p) in [
        (6.634897, 1.0, 0.99),
        (3.841459, 1.0, 0.95),
        (9.210340, 2.0, 0.99),
        (18.307038, 10.0, 0.95),
        (124.342113, 100.0, 0.95),
        (135.806723, 100.0, 0.99),
        (1.0, 2.0, 1.0 - (-0.5f64).exp()),
        (0.5, 3.0, 0.081_108_588_345_324),
    ] {
        let got = chi2::cdf(x, dof);
        assert!((got - p).abs() < 1e-6, "cdf({x}, {dof}) = {got}, want {p}");
    }
    // A wrong statistic must be rejected: far in the tail.
    assert!(1.0 - chi2::cdf(200.0, 100.0) < 1e-6);
}

fn direction(theta: f64, phi: f64) -> Vec3 {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    Vec3::new((st * cp) as f32, (st * sp) as f32, ct as f32).normalize()
}

/// Adaptive Simpson quadrature of `f` over `[a, b]` (as pbrt's
/// `AdaptiveSimpson`). The first split is forced, so at least 9 points are
/// seen before an interval is declared converged: a narrow lobe between the
/// first 5 points is not mistaken for a flat interval.
fn adaptive_simpson(f: &mut dyn FnMut(f64) -> f64, a: f64, b: f64, eps: f64, max_depth: i32) -> f64 {
    #[allow(clippy::too_many_arguments)]
    fn rec(
        f: &mut dyn FnMut(f64) -> f64,
        (a, fa): (f64, f64),
        (m, fm): (f64, f64),
        (b, fb): (f64, f64),
        whole: f64,
        eps: f64,
        depth: i32,
        forced: i32,
    ) -> f64 {
        let (lm, rm) = ((a + m) / 2.0, (m + b) / 2.0);
        let (flm, frm) = (f(lm), f(rm));
        let left = (m - a) / 6.0 * (fa + 4.0 * flm + fm);
        let right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
        let delta = left + right - whole;
        if forced <= 0 && (depth <= 0 || delta.abs() <= 15.0 * eps) {
            return left + right + delta / 15.0;
        }
        rec(f, (a, fa), (lm, flm), (m, fm), left, eps / 2.0, depth - 1, forced - 1)
            + rec(f, (m, fm), (rm, frm), (b, fb), right, eps / 2.0, depth - 1, forced - 1)
    }
    let m = (a + b) / 2.0;
    let (fa, fm, fb) = (f(a), f(m), f(b));
    let whole = (b - a) / 6.0 * (fa + 4.0 * fm + fb);
    rec(f, (a, fa), (m, fm), (b, fb), whole, eps, max_depth, 1)
}

/// ∫∫ pdf(wo, ω(θ, φ)) sin θ dφ dθ over one grid cell (nested 1-D adaptive
/// Simpson, as pbrt's `AdaptiveSimpson2D`). The θ range is inset by a hair:
/// the horizon θ = π/2 is a cell boundary where most pdfs jump, and Simpson
/// must not evaluate the upper hemisphere's value on the lower cell's edge
/// (cos(π/2) rounds to a positive f32). Cells are split into
/// [`cell_splits`]² parts first for BSDFs with very narrow lobes.
fn integrate_cell(bsdf: &Bsdf, wo: Vec3, t0: f64, t1: f64, p0: f64, p1: f64) -> f64 {
    let (t0, t1) = (t0 + 1e-7, t1 - 1e-7);
    let n = cell_splits(bsdf);
    let (dt, dp) = ((t1 - t0) / n as f64, (p1 - p0) / n as f64);
    let mut sum = 0.0;
    for i in 0..n {
        for j in 0..n {
            let (ta, pa) = (t0 + i as f64 * dt, p0 + j as f64 * dp);
            let mut outer = |theta: f64| {
                let s = theta.sin();
                let mut inner = |phi: f64| bsdf.pdf(wo, direction(theta, phi)) as f64 * s;
                adaptive_simpson(&mut inner, pa, pa + dp, 1e-7, 6)
            };
            sum += adaptive_simpson(&mut outer, ta, ta + dt, 1e-7, 6);
        }
    }
    sum
}

/// Parts per cell side for [`integrate_cell`]: Simpson's first points in a
/// 7.5° cell are about 1° apart and step over a lobe a few tenths of a
/// degree wide (GGX alpha 0.0025, GTR1 alpha near 0.001), so BSDFs with such
/// lobes are integrated on a 16× finer grid.
fn cell_splits(bsdf: &Bsdf) -> usize {
    let narrowest = match bsdf {
        Bsdf::Conductor { alpha_x, alpha_y, .. } | Bsdf::Dielectric { alpha_x, alpha_y, .. } => {
            alpha_x.min(*alpha_y)
        }
        // GGX alpha, and the clearcoat's GTR1 alpha when there is a clearcoat.
        Bsdf::Principled(p) => {
            let coat = if p.clearcoat > 0.0 { 0.1 - 0.099 * p.clearcoat_gloss } else { 1.0 };
            (p.roughness * p.roughness).min(coat)
        }
        _ => 1.0,
    };
    if narrowest < 0.02 {
        16
    } else {
        1
    }
}

struct Case {
    name: String,
    bsdf: Bsdf<'static>,
    wo: Vec3,
}

fn wo_at(theta_deg: f32, phi_deg: f32, below: bool) -> Vec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    let w = Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
    if below {
        Vec3::new(w.x, w.y, -w.z)
    } else {
        w
    }
}

/// Every case of this file (the Bonferroni correction counts them all).
fn all_cases() -> Vec<Case> {
    let mut cases = Vec::new();
    let angles = [(5.0, 30.0), (45.0, 110.0), (80.0, 250.0)];
    for &(t, p) in &angles {
        cases.push(Case {
            name: format!("diffuse wo θ={t}"),
            bsdf: Bsdf::Diffuse { reflectance: Rgb::new(0.8, 0.5, 0.2) },
            wo: wo_at(t, p, false),
        });
    }
    cases.push(Case {
        name: "diffuse wo below".into(),
        bsdf: Bsdf::Diffuse { reflectance: Rgb::splat(0.5) },
        wo: wo_at(40.0, 10.0, true),
    });
    for below in [false, true] {
        cases.push(Case {
            name: format!("diffuse transmission below={below}"),
            bsdf: Bsdf::DiffuseTransmission {
                reflectance: Rgb::new(0.3, 0.5, 0.1),
                transmittance: Rgb::new(0.6, 0.2, 0.4),
            },
            wo: wo_at(35.0, 80.0, below),
        });
    }
    // A gold-like conductor; the pdf does not depend on eta/k.
    let (eta, k) = (Rgb::new(0.18, 0.42, 1.37), Rgb::new(3.42, 2.35, 1.77));
    for (ax, ay) in [(0.1, 0.1), (0.3, 0.3), (0.7, 0.7), (0.2, 0.6)] {
        for &(t, p) in &angles {
            cases.push(Case {
                name: format!("conductor α=({ax},{ay}) wo θ={t}"),
                bsdf: Bsdf::Conductor { eta, k, alpha_x: ax, alpha_y: ay },
                wo: wo_at(t, p, false),
            });
        }
    }
    cases.push(Case {
        name: "conductor α=(0.2,0.6) wo below".into(),
        bsdf: Bsdf::Conductor { eta, k, alpha_x: 0.2, alpha_y: 0.6 },
        wo: wo_at(50.0, 70.0, true),
    });
    for eta in [1.5, 1.0 / 1.5] {
        for alpha in [0.2, 0.5] {
            for below in [false, true] {
                for &(t, p) in &angles {
                    cases.push(Case {
                        name: format!("dielectric η={eta:.3} α={alpha} wo θ={t} below={below}"),
                        bsdf: Bsdf::Dielectric { eta, alpha_x: alpha, alpha_y: alpha },
                        wo: wo_at(t, p, below),
                    });
                }
            }
        }
    }
    principled_cases(&mut cases);
    // Hair scatters over the whole sphere; its frame's x is the fibre.
    for (beta_m, beta_n) in [(0.3, 0.3), (0.15, 0.6)] {
        let params = HairParams { sigma_a: Rgb::new(0.3, 0.6, 1.2), eta: 1.55, beta_m, beta_n, alpha: 2.0 };
        for (&(t, p), below) in angles.iter().zip([false, true, false]) {
            cases.push(Case {
                name: format!("hair β=({beta_m}, {beta_n}) wo θ={t} below={below}"),
                bsdf: Bsdf::Hair(Hair::new(&params)),
                wo: wo_at(t, p, below),
            });
        }
    }
    // A measured BRDF (GGX tabulated as Dupuy and Jakob's files are),
    // sampled through its luminance and visible-normal warps.
    let [isotropic, anisotropic] = measured_ggx();
    for (&(t, p), below) in angles.iter().zip([false, false, true]) {
        for (kind, brdf) in [("isotropic", isotropic), ("anisotropic", anisotropic)] {
            cases.push(Case {
                name: format!("measured {kind} wo θ={t} below={below}"),
                bsdf: Bsdf::Measured(brdf),
                wo: wo_at(t, p, below),
            });
        }
    }
    cases
}

/// `scenes/measured-ggx.bsdf` and `measured-ggx-aniso.bsdf`
/// (scripts/measured-scene.py), read once.
fn measured_ggx() -> [&'static MeasuredBrdf; 2] {
    static BRDFS: std::sync::OnceLock<[MeasuredBrdf; 2]> = std::sync::OnceLock::new();
    let [a, b] = BRDFS.get_or_init(|| {
        ["measured-ggx.bsdf", "measured-ggx-aniso.bsdf"].map(|name| {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(name);
            MeasuredBrdf::from_bytes(&std::fs::read(path).unwrap(), name).unwrap()
        })
    });
    [a, b]
}

/// The principled BSDF: metallic 0 and 1, roughness 0.05, 0.5 and 1,
/// clearcoat, sheen, transmission from both sides, and everything at once.
fn principled_cases(cases: &mut Vec<Case>) {
    let base = PrincipledParams {
        base_color: Rgb::new(0.8, 0.5, 0.2),
        metallic: 0.0,
        roughness: 0.5,
        specular: 0.5,
        specular_tint: 0.0,
        sheen: 0.0,
        sheen_tint: 0.5,
        clearcoat: 0.0,
        clearcoat_gloss: 1.0,
        transmission: 0.0,
        eta: 1.5,
    };
    let variants = [
        ("dielectric r=0.5", PrincipledParams { ..base }),
        ("dielectric r=0.05", PrincipledParams { roughness: 0.05, ..base }),
        ("dielectric r=1", PrincipledParams { roughness: 1.0, specular_tint: 1.0, ..base }),
        ("metallic r=0.5", PrincipledParams { metallic: 1.0, ..base }),
        ("metallic r=0.05", PrincipledParams { metallic: 1.0, roughness: 0.05, ..base }),
        ("metallic r=1", PrincipledParams { metallic: 1.0, roughness: 1.0, ..base }),
        (
            "clearcoat gloss=0.5",
            PrincipledParams { clearcoat: 1.0, clearcoat_gloss: 0.5, metallic: 0.3, ..base },
        ),
        ("clearcoat gloss=1", PrincipledParams { clearcoat: 0.6, roughness: 0.3, ..base }),
        ("sheen", PrincipledParams { sheen: 1.0, roughness: 0.8, ..base }),
        ("glass r=0.3", PrincipledParams { transmission: 1.0, roughness: 0.3, ..base }),
        ("glass η=0.667 r=0.5", PrincipledParams { transmission: 1.0, eta: 1.0 / 1.5, ..base }),
        (
            "everything",
            PrincipledParams {
                metallic: 0.3,
                roughness: 0.4,
                specular: 0.8,
                specular_tint: 0.5,
                sheen: 0.5,
                clearcoat: 0.7,
                clearcoat_gloss: 0.8,
                transmission: 0.4,
                ..base
            },
        ),
    ];
    for (name, p) in variants {
        let glass = p.transmission > 0.0;
        // Mirror directions off the grid's θ boundaries (multiples of 7.5°):
        // a narrow lobe split by one is integrated less accurately.
        let angles: &[(f32, f32, bool)] = if glass {
            &[(5.0, 30.0, false), (50.0, 110.0, false), (40.0, 250.0, true), (70.0, 10.0, true)]
        } else {
            &[(5.0, 30.0, false), (40.0, 110.0, false), (80.0, 250.0, false), (50.0, 300.0, true)]
        };
        for &(t, phi, below) in angles {
            cases.push(Case {
                name: format!("principled {name} wo θ={t} below={below}"),
                bsdf: Bsdf::Principled(Principled(p)),
                wo: wo_at(t, phi, below),
            });
        }
    }
}
const CELL_THETA: f64 = PI / THETA_RES as f64;
const CELL_PHI: f64 = 2.0 * PI / PHI_RES as f64;
/// Index of the extra cell that counts failed samples.
const FAIL_CELL: usize = THETA_RES * PHI_RES;

/// Relative difference, with a floor so values near zero compare absolutely.
fn rel_diff(a: f32, b: f32) -> f32 {
    (a - b).abs() / a.abs().max(b.abs()).max(1e-4)
}

/// Draws `SAMPLES` samples of `bsdf` for `wo` and bins their directions.
/// Every sample's `pdf` and `f` are compared with `Bsdf::pdf` and
/// `Bsdf::eval` for its direction; disagreements are returned.
fn histogram(bsdf: &Bsdf, wo: Vec3, seed: u64) -> (Vec<f64>, Vec<String>) {
    let mut observed = vec![0.0f64; FAIL_CELL + 1];
    let mut rng = Pcg32::new(seed);
    let (mut worst, mut worst_sample, mut loose) = (0.0f32, None, 0u32);
    for _ in 0..SAMPLES {
        let uc = rng.next_f32();
        let u = Vec2::new(rng.next_f32(), rng.next_f32());
        let Some(s) = bsdf.sample(wo, uc, u) else {
            observed[FAIL_CELL] += 1.0;
            continue;
        };
        let (pdf, f) = (bsdf.pdf(wo, s.wi), bsdf.eval(wo, s.wi));
        let err = (0..3).map(|c| rel_diff(s.f[c], f[c])).fold(rel_diff(s.pdf, pdf), f32::max);
        let err = if s.delta { f32::INFINITY } else { err };
        loose += (err > CONSISTENCY_TOLERANCE) as u32;
        if err > worst {
            worst = err;
            worst_sample = Some((s, pdf, f));
        }
        let w = s.wi.as_dvec3();
        let theta = w.z.clamp(-1.0, 1.0).acos();
        let phi = w.y.atan2(w.x).rem_euclid(2.0 * PI);
        let ti = ((theta / CELL_THETA) as usize).min(THETA_RES - 1);
        let pi = ((phi / CELL_PHI) as usize).min(PHI_RES - 1);
        observed[ti * PHI_RES + pi] += 1.0;
    }
    let mut problems = Vec::new();
    if loose as f64 > CONSISTENCY_OUTLIERS * SAMPLES as f64 || worst > 10.0 * CONSISTENCY_TOLERANCE {
        let (s, pdf, f) = worst_sample.unwrap();
        problems.push(format!(
            "{loose} samples off by more than {CONSISTENCY_TOLERANCE}; worst ({worst:.2e}): \
             {s:?} vs pdf {pdf}, f {f}"
        ));
    }
    (observed, problems)
}

/// Chi-square test of the `observed` histogram against the counts that
/// `density`'s pdf predicts. Returns the p-value, or why the test rejects.
fn chi2_test(density: &Bsdf, wo: Vec3, observed: &[f64], significance: f64) -> Result<f64, String> {
    let n = SAMPLES as f64;
    let mut expected = vec![0.0f64; FAIL_CELL + 1];
    let mut covered = 0.0;
    for ti in 0..THETA_RES {
        for pi in 0..PHI_RES {
            let (t0, p0) = (ti as f64 * CELL_THETA, pi as f64 * CELL_PHI);
            let mass = integrate_cell(density, wo, t0, t0 + CELL_THETA, p0, p0 + CELL_PHI);
            covered += mass;
            expected[ti * PHI_RES + pi] = mass * n;
        }
    }
    if covered > 1.0 + 1e-3 {
        return Err(format!("pdf integrates to {covered} > 1"));
    }
    expected[FAIL_CELL] = ((1.0 - covered) * n).max(0.0);
    if std::env::var_os("CHI2_DEBUG").is_some() {
        // Per-θ-row totals: where a mismatch lives, at a glance.
        for ti in 0..THETA_RES {
            let o: f64 = observed[ti * PHI_RES..(ti + 1) * PHI_RES].iter().sum();
            let e: f64 = expected[ti * PHI_RES..(ti + 1) * PHI_RES].iter().sum();
            eprintln!("  row {ti}: observed {o}, expected {e:.1}");
        }
        eprintln!("  failed: observed {}, expected {:.1}", observed[FAIL_CELL], expected[FAIL_CELL]);
    }

    // Pool low-expectation cells. A sample where the pdf is zero is an error
    // unless it is a rounding-level fraction (pbrt allows 1e-5 of them).
    let (mut chsq, mut pooled_obs, mut pooled_exp, mut dof) = (0.0, 0.0, 0.0, -1i64);
    for (&o, &e) in observed.iter().zip(&expected) {
        if e == 0.0 {
            if o > n * 1e-5 {
                return Err(format!("{o} samples in a cell where the pdf is zero"));
            }
        } else if e < MIN_EXPECTED {
            pooled_obs += o;
            pooled_exp += e;
        } else {
            chsq += (o - e) * (o - e) / e;
            dof += 1;
        }
    }
    if pooled_exp > 0.0 {
        // A tiny pooled bin would make the statistic unreliable; count it as
        // if MIN_EXPECTED were expected (conservative), so only a real excess
        // of samples there rejects.
        chsq += (pooled_obs - pooled_exp).powi(2) / pooled_exp.max(MIN_EXPECTED);
        dof += 1;
    }
    if dof < 1 {
        return Ok(1.0);
    }
    let p_value = 1.0 - chi2::cdf(chsq, dof as f64);
    if p_value < significance {
        return Err(format!("chi-square {chsq:.1} with {dof} dof: p = {p_value:.3e} < {significance:.1e}"));
    }
    Ok(p_value)
}

/// Runs all cases whose name starts with `prefix`; reports every failure.
fn run_family(prefix: &str) {
    let cases = all_cases();
    let significance = SIGNIFICANCE / cases.len() as f64;
    let mut failures = Vec::new();
    let mut ran = 0;
    for (i, case) in cases.iter().enumerate().filter(|(_, c)| c.name.starts_with(prefix)) {
        ran += 1;
        let (observed, problems) = histogram(&case.bsdf, case.wo, 0x9e37_79b9 + 1000 * i as u64);
        if !problems.is_empty() {
            failures.push(format!("{}: sample disagrees with pdf/eval: {}", case.name, problems.join("; ")));
        }
        match chi2_test(&case.bsdf, case.wo, &observed, significance) {
            Ok(p) => eprintln!("{}: p = {p:.3}", case.name),
            Err(e) => failures.push(format!("{}: {e}", case.name)),
        }
    }
    assert!(ran > 0, "no case matches {prefix}");
    assert!(failures.is_empty(), "{} failure(s):\n{}", failures.len(), failures.join("\n"));
}

#[test]
fn chi2_diffuse() {
    run_family("diffuse");
}

#[test]
fn chi2_conductor() {
    run_family("conductor");
}

#[test]
fn chi2_dielectric_eta_above_one() {
    run_family("dielectric η=1.500");
}

#[test]
fn chi2_dielectric_eta_below_one() {
    run_family("dielectric η=0.667");
}

#[test]
fn chi2_principled_dielectric() {
    run_family("principled dielectric");
}

#[test]
fn chi2_principled_metallic() {
    run_family("principled metallic");
}

#[test]
fn chi2_principled_clearcoat_and_sheen() {
    run_family("principled clearcoat");
    run_family("principled sheen");
}

#[test]
fn chi2_principled_glass_and_everything() {
    run_family("principled glass");
    run_family("principled everything");
}

#[test]
fn chi2_hair() {
    run_family("hair");
}

#[test]
fn chi2_measured() {
    run_family("measured");
}

/// The test must be able to fail: samples from one BSDF checked against the
/// pdf of a slightly different one are rejected at the corrected level.
#[test]
fn chi2_rejects_slightly_wrong_pdfs() {
    let significance = SIGNIFICANCE / all_cases().len() as f64;
    let metal = |a: f32| Bsdf::Conductor { eta: Rgb::ONE, k: Rgb::ONE, alpha_x: a, alpha_y: a };
    let glass = |eta: f32| Bsdf::Dielectric { eta, alpha_x: 0.3, alpha_y: 0.3 };
    let diffuse = Bsdf::Diffuse { reflectance: Rgb::ONE };
    for (sampler, density, wo) in [
        // 5% too rough.
        (metal(0.3), metal(0.315), wo_at(30.0, 20.0, false)),
        // Wrong index: transmission lobe and Fresnel split both move.
        (glass(1.5), glass(1.45), wo_at(40.0, 0.0, false)),
        // Uniform instead of cosine-weighted: far off.
        (diffuse, metal(1.0), wo_at(0.0, 0.0, false)),
    ] {
        let (observed, _) = histogram(&sampler, wo, 1);
        let result = chi2_test(&density, wo, &observed, significance);
        assert!(result.is_err(), "{sampler:?} vs {density:?} passed: {result:?}");
        // And the right pdf passes for the same histogram.
        assert!(chi2_test(&sampler, wo, &observed, significance).is_ok());
    }
}
