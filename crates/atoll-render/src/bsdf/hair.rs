//! pbrt-v4's `HairBxDF`: the hair scattering model of Chiang et al. 2016
//! ("A practical and controllable hair and fur model for production path
//! tracing"), a dielectric cylinder with an absorbing interior whose
//! cuticle scales tilt the lobes. Light leaves after `p` internal paths:
//! reflection (R, `p` = 0), transmission (TT, 1), one internal reflection
//! (TRT, 2) and the rest summed (`p` = [`P_MAX`]). Each lobe is a product
//! of a longitudinal term `Mp` (d'Eon et al. 2011), an attenuation `Ap`
//! (Fresnel and absorption) and an azimuthal term `Np` (a trimmed logistic).
//!
//! The frame is the hair's: local x is the fibre's axis (the surface's
//! `dpdu`), z the surface normal, so `sin θ = w.x` and `φ = atan2(w.z,
//! w.y)`. pbrt takes the offset `h` across the fibre from the surface's `v`
//! coordinate (`-1 + 2v`), and so do atoll's hits. Without one
//! ([`OFFSET_FROM_NORMAL`], what [`Hair::new`] gives) `h` is where `wo`
//! meets the normal of a round fibre, the sine of the azimuth between the
//! normal and `wo` ([`Hair::offset`]): what `v` stands for on pbrt's
//! ray-facing curves.

use atoll_scene::{HairParams, Rgb};
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_1_PI, PI};

use super::{fr_dielectric, same_hemisphere, BsdfSample};

/// The last lobe: `p` = `P_MAX` sums every longer path through the fibre.
pub const P_MAX: usize = 3;

/// [`Hair::given_offset`] meaning "from the normal" ([`Hair::offset`]):
/// outside [-1, 1], and exact in f16.
pub const OFFSET_FROM_NORMAL: f32 = 2.0;

/// A hair fibre's BSDF with its per-lobe constants worked out.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hair {
    pub params: HairParams,
    /// The offset `h` across the fibre as the surface gives it (pbrt's
    /// `-1 + 2v`), or [`OFFSET_FROM_NORMAL`] where none is given.
    pub given_offset: f32,
    /// Longitudinal variance of each lobe.
    v: [f32; P_MAX + 1],
    /// Logistic scale of the azimuthal lobes.
    s: f32,
    /// `sin(2^k α)` and `cos(2^k α)` for the scale tilts of the lobes.
    sin_2k_alpha: [f32; 3],
    cos_2k_alpha: [f32; 3],
}

/// What every evaluation needs of `wo`: its angles, the offset `h`, the
/// refracted azimuth, and the lobes' attenuations and selection weights.
struct Outgoing {
    sin_theta_o: f32,
    cos_theta_o: f32,
    phi_o: f32,
    gamma_o: f32,
    gamma_t: f32,
    ap: [Rgb; P_MAX + 1],
    ap_pdf: [f32; P_MAX + 1],
}

fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

fn safe_asin(x: f32) -> f32 {
    x.clamp(-1.0, 1.0).asin()
}

/// The modified Bessel function of the first kind `I0`, by its series
/// `Σ (x²/4)^i / (i!)²` summed until the terms no longer count. pbrt stops
/// at ten terms, which near x = 12 (where [`log_bessel_i0`] turns to the
/// asymptotic form) is several percent low: `Mp`, and so `f` and `pdf`,
/// came out short of the density `sample` draws from.
pub fn bessel_i0(x: f32) -> f32 {
    let quarter_x2 = x * x * 0.25;
    let (mut term, mut sum) = (1.0f32, 1.0f32);
    for i in 1..BESSEL_TERMS {
        term *= quarter_x2 / (i * i) as f32;
        sum += term;
        if term < sum * 1e-8 {
            break;
        }
    }
    sum
}

/// The most series terms [`bessel_i0`] adds: enough for x up to 12.
const BESSEL_TERMS: u32 = 40;

/// `ln I0(x)`: above 12 by the asymptotic expansion `e^x / sqrt(2πx)
/// (1 + 1/(8x) + 9/(128x²) + 225/(3072x³))`, within 1e-5. pbrt adds half
/// of the first correction only (`ln` of it should be about `1/(8x)`),
/// which leaves narrow lobes up to half a percent short of unit mass.
pub fn log_bessel_i0(x: f32) -> f32 {
    if x > 12.0 {
        let r = 1.0 / x;
        let series = r * (1.0 / 8.0 + r * (9.0 / 128.0 + r * (225.0 / 3072.0)));
        x - 0.5 * (2.0 * PI * x).ln() + series.ln_1p()
    } else {
        bessel_i0(x).ln()
    }
}

/// The longitudinal scattering function of variance `v` (d'Eon et al.
/// 2011), in log space for narrow lobes where `I0` and `sinh` overflow.
fn mp(cos_theta_i: f32, cos_theta_o: f32, sin_theta_i: f32, sin_theta_o: f32, v: f32) -> f32 {
    let a = cos_theta_i * cos_theta_o / v;
    let b = sin_theta_i * sin_theta_o / v;
    if v <= 0.1 {
        (log_bessel_i0(a) - b - 1.0 / v + std::f32::consts::LN_2 + (1.0 / (2.0 * v)).ln()).exp()
    } else {
        ((-b).exp() * bessel_i0(a)) / ((1.0 / v).sinh() * 2.0 * v)
    }
}

/// The azimuth a path of `p` internal segments leaves at, relative to the
/// incident one.
fn phi(p: usize, gamma_o: f32, gamma_t: f32) -> f32 {
    2.0 * p as f32 * gamma_t - 2.0 * gamma_o + p as f32 * PI
}

fn logistic(x: f32, s: f32) -> f32 {
    let e = (-x.abs() / s).exp();
    e / (s * (1.0 + e) * (1.0 + e))
}

fn logistic_cdf(x: f32, s: f32) -> f32 {
    1.0 / (1.0 + (-x / s).exp())
}

/// The logistic of scale `s` restricted to [-π, π] and renormalised.
fn trimmed_logistic(x: f32, s: f32) -> f32 {
    logistic(x, s) / (logistic_cdf(PI, s) - logistic_cdf(-PI, s))
}

/// Inverts [`trimmed_logistic`]'s distribution at `u`: `s ln(c / (1 - c))`
/// for the logistic's CDF value `c`. `c` and `1 - c` are each made from the
/// end they are near (the logistic is symmetric, `1 - cdf(π) = cdf(-π)`),
/// where pbrt's `1 / c - 1` loses digits as `u` nears 1.
fn sample_trimmed_logistic(u: f32, s: f32) -> f32 {
    let (lo, hi) = (logistic_cdf(-PI, s), logistic_cdf(PI, s));
    let span = hi - lo;
    let (below, above) = (lo + u * span, lo + (1.0 - u) * span);
    (s * (below / above).ln()).clamp(-PI, PI)
}

/// The azimuthal scattering function of lobe `p` at azimuth difference `phi`.
fn np(phi_diff: f32, p: usize, s: f32, gamma_o: f32, gamma_t: f32) -> f32 {
    let mut dphi = phi_diff - phi(p, gamma_o, gamma_t);
    // Into [-π, π].
    while dphi > PI {
        dphi -= 2.0 * PI;
    }
    while dphi < -PI {
        dphi += 2.0 * PI;
    }
    trimmed_logistic(dphi, s)
}

impl Hair {
    /// pbrt's `HairBxDF` constructor: the lobes' longitudinal variances from
    /// `beta_m` (TT half, TRT and beyond four times R's), the azimuthal
    /// scale from `beta_n`, the tilts from `alpha`.
    pub fn new(params: &HairParams) -> Hair {
        let bm = params.beta_m;
        let v0 = (0.726 * bm + 0.812 * bm * bm + 3.7 * bm.powi(20)).powi(2);
        let v = [v0, 0.25 * v0, 4.0 * v0, 4.0 * v0];
        let bn = params.beta_n;
        let sqrt_pi_over_8 = 0.626_657_07;
        let s = sqrt_pi_over_8 * (0.265 * bn + 1.194 * bn * bn + 5.372 * bn.powi(22));
        let mut sin_2k_alpha = [params.alpha.to_radians().sin(), 0.0, 0.0];
        let mut cos_2k_alpha = [safe_sqrt(1.0 - sin_2k_alpha[0] * sin_2k_alpha[0]), 0.0, 0.0];
        for i in 1..3 {
            sin_2k_alpha[i] = 2.0 * cos_2k_alpha[i - 1] * sin_2k_alpha[i - 1];
            cos_2k_alpha[i] =
                cos_2k_alpha[i - 1] * cos_2k_alpha[i - 1] - sin_2k_alpha[i - 1] * sin_2k_alpha[i - 1];
        }
        Hair { params: *params, given_offset: OFFSET_FROM_NORMAL, v, s, sin_2k_alpha, cos_2k_alpha }
    }

    /// The fibre with the offset its surface gives (see [`Hair::given_offset`]).
    pub fn with_offset(self, given_offset: f32) -> Hair {
        Hair { given_offset, ..self }
    }

    /// The offset `h` in [-1, 1] across the fibre where `wo` (local) meets
    /// it: the sine of the azimuth from the normal (+z) to `wo`, as on a
    /// round fibre whose normal at the hit is the surface's. 0 for `wo`
    /// along the axis.
    pub fn offset(wo: Vec3) -> f32 {
        let r = (wo.y * wo.y + wo.z * wo.z).sqrt();
        if r > 0.0 {
            (-wo.y / r).clamp(-1.0, 1.0)
        } else {
            0.0
        }
    }

    /// `sin θ_o` and `|cos θ_o|` of lobe `p`, tilted by its scales: R by
    /// -2α, TT by α, TRT by 4α (pbrt's signs).
    fn tilted(&self, p: usize, sin_theta_o: f32, cos_theta_o: f32) -> (f32, f32) {
        let (s, c) = (self.sin_2k_alpha, self.cos_2k_alpha);
        let (sin_p, cos_p) = match p {
            0 => (sin_theta_o * c[1] - cos_theta_o * s[1], cos_theta_o * c[1] + sin_theta_o * s[1]),
            1 => (sin_theta_o * c[0] + cos_theta_o * s[0], cos_theta_o * c[0] - sin_theta_o * s[0]),
            2 => (sin_theta_o * c[2] + cos_theta_o * s[2], cos_theta_o * c[2] - sin_theta_o * s[2]),
            _ => (sin_theta_o, cos_theta_o),
        };
        (sin_p, cos_p.abs())
    }

    fn outgoing(&self, wo: Vec3) -> Outgoing {
        let h = if self.given_offset.abs() <= 1.0 { self.given_offset } else { Hair::offset(wo) };
        let sin_theta_o = wo.x;
        let cos_theta_o = safe_sqrt(1.0 - sin_theta_o * sin_theta_o);
        let phi_o = wo.z.atan2(wo.y);
        let gamma_o = safe_asin(h);
        // The refracted ray's longitudinal and azimuthal angles (Bravais).
        let sin_theta_t = sin_theta_o / self.params.eta;
        let cos_theta_t = safe_sqrt(1.0 - sin_theta_t * sin_theta_t);
        let etap = safe_sqrt(self.params.eta * self.params.eta - sin_theta_o * sin_theta_o) / cos_theta_o;
        let sin_gamma_t = h / etap;
        let cos_gamma_t = safe_sqrt(1.0 - sin_gamma_t * sin_gamma_t);
        let gamma_t = safe_asin(sin_gamma_t);
        // Transmittance of one crossing of the fibre.
        let path = 2.0 * cos_gamma_t / cos_theta_t;
        let t = Rgb::new(
            (-self.params.sigma_a.x * path).exp(),
            (-self.params.sigma_a.y * path).exp(),
            (-self.params.sigma_a.z * path).exp(),
        );
        // Attenuations: Fresnel at the entry, absorption, internal reflections.
        let f = fr_dielectric(cos_theta_o * safe_sqrt(1.0 - h * h), self.params.eta);
        let mut ap = [Rgb::ZERO; P_MAX + 1];
        ap[0] = Rgb::splat(f);
        ap[1] = t * ((1.0 - f) * (1.0 - f));
        for p in 2..P_MAX {
            ap[p] = ap[p - 1] * t * f;
        }
        let tf = t * f;
        let rest = Rgb::ONE - tf;
        ap[P_MAX] = Rgb::new(
            if rest.x != 0.0 { ap[P_MAX - 1].x * tf.x / rest.x } else { 0.0 },
            if rest.y != 0.0 { ap[P_MAX - 1].y * tf.y / rest.y } else { 0.0 },
            if rest.z != 0.0 { ap[P_MAX - 1].z * tf.z / rest.z } else { 0.0 },
        );
        // Lobes are chosen by their mean attenuation over the channels.
        let mean = |c: Rgb| (c.x + c.y + c.z) * (1.0 / 3.0);
        let total: f32 = ap.iter().map(|&a| mean(a)).sum();
        let ap_pdf = ap.map(|a| if total > 0.0 { mean(a) / total } else { 0.0 });
        Outgoing { sin_theta_o, cos_theta_o, phi_o, gamma_o, gamma_t, ap, ap_pdf }
    }

    /// `Σ_p weight(p) Mp Np` for `wi` (sines, cosines and the azimuth
    /// difference `dphi` from `wo`), plus the isotropic last lobe: the BSDF
    /// times `|cos θ_i|` with `weight = ap`, the pdf with `ap_pdf`.
    fn lobes<T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>>(
        &self,
        o: &Outgoing,
        (sin_theta_i, cos_theta_i): (f32, f32),
        dphi: f32,
        weight: [T; P_MAX + 1],
        zero: T,
    ) -> T {
        let mut sum = zero;
        for (p, &w) in weight.iter().enumerate().take(P_MAX) {
            let (sin_p, cos_p) = self.tilted(p, o.sin_theta_o, o.cos_theta_o);
            let m = mp(cos_theta_i, cos_p, sin_theta_i, sin_p, self.v[p]);
            sum = sum + w * (m * np(dphi, p, self.s, o.gamma_o, o.gamma_t));
        }
        let m = mp(cos_theta_i, o.cos_theta_o, sin_theta_i, o.sin_theta_o, self.v[P_MAX]);
        sum + weight[P_MAX] * (m * (0.5 * FRAC_1_PI))
    }

    /// The incident direction's sine, cosine and azimuth difference from `wo`.
    fn incident(o: &Outgoing, wi: Vec3) -> ((f32, f32), f32) {
        let sin_theta_i = wi.x;
        ((sin_theta_i, safe_sqrt(1.0 - sin_theta_i * sin_theta_i)), wi.z.atan2(wi.y) - o.phi_o)
    }

    /// BSDF value without the cosine (pbrt divides the lobes by `|cos θ_i|`
    /// with respect to the normal, which the integrator multiplies back).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        let o = self.outgoing(wo);
        let (angles, dphi) = Hair::incident(&o, wi);
        let f = self.lobes(&o, angles, dphi, o.ap, Rgb::ZERO);
        let cos = wi.z.abs();
        if cos > 0.0 {
            f / cos
        } else {
            f
        }
    }

    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let o = self.outgoing(wo);
        let (angles, dphi) = Hair::incident(&o, wi);
        self.lobes(&o, angles, dphi, o.ap_pdf, 0.0)
    }

    /// pbrt's `Sample_f`: a lobe by `uc` (then reused, rescaled, for the
    /// azimuth), `θ_i` from its `Mp` by `u`, `φ_i` from its `Np`.
    pub fn sample(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<BsdfSample> {
        let o = self.outgoing(wo);
        // Pick a lobe and rescale uc into it (pbrt's `SampleDiscrete`).
        let mut p = 0;
        let mut start = 0.0;
        while p < P_MAX && uc >= start + o.ap_pdf[p] {
            start += o.ap_pdf[p];
            p += 1;
        }
        if o.ap_pdf[p] <= 0.0 {
            return None;
        }
        let uc = ((uc - start) / o.ap_pdf[p]).clamp(0.0, 1.0 - f32::EPSILON / 2.0);
        let (sin_p, cos_p) = self.tilted(p, o.sin_theta_o, o.cos_theta_o);
        // θ_i about the mirror of the tilted θ_o (d'Eon et al.'s sampling).
        let v = self.v[p];
        let cos_theta = 1.0 + v * (u.x.max(1e-5) + (1.0 - u.x) * (-2.0 / v).exp()).ln();
        let sin_theta = safe_sqrt(1.0 - cos_theta * cos_theta);
        let cos_phi = (2.0 * PI * u.y).cos();
        let sin_theta_i = -cos_theta * sin_p + sin_theta * cos_phi * cos_p;
        let cos_theta_i = safe_sqrt(1.0 - sin_theta_i * sin_theta_i);
        let dphi = if p < P_MAX {
            phi(p, o.gamma_o, o.gamma_t) + sample_trimmed_logistic(uc, self.s)
        } else {
            2.0 * PI * uc
        };
        let phi_i = o.phi_o + dphi;
        let wi = Vec3::new(sin_theta_i, cos_theta_i * phi_i.cos(), cos_theta_i * phi_i.sin());
        let pdf = self.lobes(&o, (sin_theta_i, cos_theta_i), dphi, o.ap_pdf, 0.0);
        let f = self.eval(wo, wi);
        let transmission = !same_hemisphere(wo, wi);
        Some(BsdfSample { f, wi, pdf, eta: 1.0, delta: false, transmission })
    }
}
