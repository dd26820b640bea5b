//! pbrt-v4's `CoatedDiffuseBxDF` and `CoatedConductorBxDF`
//! (`LayeredBxDF<DielectricBxDF, DiffuseBxDF | ConductorBxDF, true>`): a
//! dielectric coating over a Lambertian or conductor base, with an optional
//! homogeneous medium between them, evaluated by following light through
//! the layers with a random walk (Guo et al. 2018, "Position-free Monte Carlo
//! simulation for arbitrary layered BSDFs", in pbrt's form).
//!
//! `eval`, `sample` and `pdf` are themselves Monte Carlo estimates, as in
//! pbrt: `eval` is unbiased for the layered BSDF (up to `max_depth`), the
//! weight `f |cos| / pdf` of a sample is an unbiased estimate of the BSDF's
//! value over its density, and `pdf` is only an approximation (the
//! transmission–reflection–transmission paths, mixed with a uniform density)
//! for multiple importance sampling. Integrators therefore use `pdf` rather
//! than the sample's density for MIS ([`super::Bsdf::sampled_pdf_is_proportional`]).
//!
//! Each estimate's random numbers come from a hash of its arguments (pbrt
//! hashes them too), so the same query gives the same value on every call
//! and every device; the CUDA port (`kernels/layered.cuh`) does the same
//! integer arithmetic. Directions are hashed rounded to about 1e-4 (see
//! [`DIRECTION_SEED_DROP_BITS`]) so that an ulp of difference between
//! devices rarely changes the walk. pbrt also mixes in the render's seed;
//! here the estimates do not depend on it.
//!
//! The structure is two-sided (a `wo` below the surface is mirrored above),
//! the medium's extinction coefficient is 1 so `thickness` is its optical
//! depth, and a walk ends after `max_depth` events or by Russian roulette
//! once its weight is small.
//!
//! Two departures from pbrt's code, both fixes: `eval`'s MIS weights for
//! leaving through the coating compare densities of the same variable (see
//! [`Coated::eval`]; pbrt's make its `f` disagree with its
//! `Sample_f` under rough coatings), and `sample` carries the walk's weight
//! rather than its `f` and density separately, which underflow f32 on long
//! walks (see [`Coated::sample`]).

use atoll_scene::{CoatedConductorParams, CoatedDiffuseParams, Coating, Rgb};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

use super::dielectric::{self, Lobes, Mode};
use super::microfacet::TrowbridgeReitz;
use super::{same_hemisphere, Bsdf, BsdfSample};
use crate::rng::pcg_hash;
use crate::sampling::{henyey_greenstein, power_heuristic, sample_exponential, sample_henyey_greenstein};

/// A coated surface: its [`Coating`] (fields through `Deref`) over a base.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coated {
    pub coating: Coating,
    pub base: CoatedBase,
}

/// What lies under a [`Coated`] surface's coating.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CoatedBase {
    /// Lambertian (pbrt's `coateddiffuse`).
    Diffuse { reflectance: Rgb },
    /// A conductor whose index `eta + i k` is relative to the outside, as a
    /// scene gives it (pbrt's `coatedconductor`); [`Coated::base`] makes it
    /// relative to the coating.
    Conductor { eta: Rgb, k: Rgb, alpha_x: f32, alpha_y: f32 },
}

impl Coated {
    pub fn diffuse(p: CoatedDiffuseParams) -> Self {
        Coated { coating: p.coating, base: CoatedBase::Diffuse { reflectance: p.reflectance } }
    }

    pub fn conductor(p: CoatedConductorParams) -> Self {
        let CoatedConductorParams { eta, k, alpha_x, alpha_y, coating } = p;
        Coated { coating, base: CoatedBase::Conductor { eta, k, alpha_x, alpha_y } }
    }
}

impl std::ops::Deref for Coated {
    type Target = Coating;
    fn deref(&self) -> &Coating {
        &self.coating
    }
}

impl std::ops::DerefMut for Coated {
    fn deref_mut(&mut self) -> &mut Coating {
        &mut self.coating
    }
}

/// Domain tags that keep the three estimates' random streams apart (the
/// CUDA header has them from here).
pub const TAG_EVAL: u32 = 0x6576_616c;
/// See [`TAG_EVAL`].
pub const TAG_SAMPLE: u32 = 0x736d_706c;
/// See [`TAG_EVAL`].
pub const TAG_PDF: u32 = 0x7064_6621;

/// Low mantissa bits of a direction component that do not reach the seed.
pub const DIRECTION_SEED_DROP_BITS: u32 = 10;

/// A direction component's bits rounded to a multiple of
/// 2^[`DIRECTION_SEED_DROP_BITS`] ulps (about 1e-4 relative). Directions
/// computed on two devices can differ by an ulp or two (`sinf`, FMA), and
/// an exact hash would then start unrelated walks; rounded, the seeds
/// differ only for the few values near a rounding boundary.
#[inline]
fn seed_bits(x: f32) -> u32 {
    let half = 1u32 << (DIRECTION_SEED_DROP_BITS - 1);
    x.to_bits().wrapping_add(half) & !((1u32 << DIRECTION_SEED_DROP_BITS) - 1)
}

/// The random numbers of one estimate: a PCG32 (RXS-M-XS) stream whose
/// state starts at a hash of the estimate's arguments.
struct WalkRng {
    state: u32,
}

impl WalkRng {
    /// Seeds from `tag`, the rounded bits of the directions `dirs` and the
    /// exact bits of `words`, hashed in order.
    fn new(tag: u32, dirs: &[Vec3], words: &[f32]) -> Self {
        let dir_bits = dirs.iter().flat_map(|d| [d.x, d.y, d.z]).map(seed_bits);
        let bits = dir_bits.chain(words.iter().map(|w| w.to_bits()));
        WalkRng { state: bits.fold(pcg_hash(tag), |h, b| pcg_hash(h ^ b)) }
    }

    /// Uniform in `[0, 1)` with 24 bits (never rounds to 1, like pbrt's
    /// `min(u, OneMinusEpsilon)`). `pcg_hash` is one LCG step and the
    /// output permutation, so hashing the state and then stepping it is
    /// exactly the PCG32 RXS-M-XS generator.
    fn next(&mut self) -> f32 {
        let out = pcg_hash(self.state);
        self.state = self.state.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
        (out >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    fn next2(&mut self) -> Vec2 {
        let x = self.next();
        Vec2::new(x, self.next())
    }
}

/// pbrt's `LayeredBxDF::Tr`: transmittance through optical depth `dz` along
/// `w`; 1 for a zero-thickness layer.
#[inline]
fn tr(dz: f32, w: Vec3) -> f32 {
    if dz.abs() <= f32::MIN_POSITIVE {
        1.0
    } else {
        (-(dz / w.z).abs()).exp()
    }
}

/// A sample usable as a step of the walk (pbrt: `!bs || !bs->f || bs->pdf
/// == 0 || bs->wi.z == 0` rejects it).
#[inline]
fn usable(s: Option<BsdfSample>) -> Option<BsdfSample> {
    s.filter(|s| s.f != Rgb::ZERO && s.pdf > 0.0 && s.wi.z != 0.0)
}

impl Coated {
    fn coat(&self) -> TrowbridgeReitz {
        TrowbridgeReitz::new(self.alpha_x, self.alpha_y)
    }

    /// The base's BSDF inside the coating: pbrt-v4 divides a conductor's
    /// index by the coating's.
    fn base(&self) -> Bsdf<'static> {
        match self.base {
            CoatedBase::Diffuse { reflectance } => Bsdf::Diffuse { reflectance },
            CoatedBase::Conductor { eta, k, alpha_x, alpha_y } => {
                Bsdf::Conductor { eta: eta / self.eta, k: k / self.eta, alpha_x, alpha_y }
            }
        }
    }

    /// The base reflects only specularly (a smooth conductor): walks take
    /// no next-event estimates there, as pbrt's `IsSpecular` tests.
    fn base_is_specular(&self) -> bool {
        match self.base {
            CoatedBase::Diffuse { .. } => false,
            CoatedBase::Conductor { alpha_x, alpha_y, .. } => {
                TrowbridgeReitz::new(alpha_x, alpha_y).effectively_smooth()
            }
        }
    }

    /// pbrt clamps the thickness away from zero so the layer boundaries differ.
    fn thickness(&self) -> f32 {
        self.thickness.max(f32::MIN_POSITIVE)
    }

    /// The medium scatters (pbrt's `if (albedo)`).
    fn scatters(&self) -> bool {
        self.albedo != Rgb::ZERO
    }

    /// pbrt's flags: specular only when the coating is smooth and nothing
    /// below it scatters diffusely or glossily (a black diffuse base or a
    /// smooth conductor, in an absorbing medium).
    pub fn is_delta(&self) -> bool {
        let base_is_delta = match self.base {
            CoatedBase::Diffuse { reflectance } => reflectance == Rgb::ZERO,
            CoatedBase::Conductor { .. } => self.base_is_specular(),
        };
        self.coat().effectively_smooth() && base_is_delta && !self.scatters()
    }

    /// The coating's BSDF in `mode`.
    fn coat_eval(&self, wo: Vec3, wi: Vec3, mode: Mode) -> Rgb {
        dielectric::eval_with(self.eta, self.coat(), wo, wi, mode)
    }

    fn coat_pdf(&self, wo: Vec3, wi: Vec3, lobes: Lobes) -> f32 {
        dielectric::pdf_with(self.eta, self.coat(), wo, wi, lobes)
    }

    fn coat_sample(&self, wo: Vec3, uc: f32, u: Vec2, mode: Mode, lobes: Lobes) -> Option<BsdfSample> {
        usable(dielectric::sample_with(self.eta, self.coat(), wo, uc, u, mode, lobes))
    }

    /// Stochastic estimate of `f(wo, wi)` (pbrt's `LayeredBxDF::f`): the
    /// coating's own reflection plus `n_samples` random walks that enter
    /// through the coating, bounce between base and coating, and are joined
    /// to `wi` by next-event estimation through the coating at every vertex.
    ///
    /// Each vertex leaves towards `wi` in two ways, combined by MIS: through
    /// the internal direction presampled from `wi` (`wis`), and through the
    /// direction the walk samples next. Both weights compare the densities
    /// of the same internal direction. pbrt weighs the second with the
    /// coating's density of `wi` given that direction (`exitInterface.PDF(-w,
    /// wi)`), a density of another variable, so its weights do not sum to one
    /// and its `f` disagrees with its `Sample_f` under rough coatings
    /// (pbrt-v4 issue #187); here it is the density `wis` has for it.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        // Two-sided: mirror a query from below.
        let (wo, wi) = if wo.z < 0.0 { (-wo, -wi) } else { (wo, wi) };
        // The base is opaque: light never leaves through it, so only
        // reflection is nonzero (pbrt finds no transmission through it).
        if !same_hemisphere(wo, wi) {
            return Rgb::ZERO;
        }
        let thickness = self.thickness();
        let coat_specular = self.coat().effectively_smooth();
        let base = self.base();
        let base_specular = self.base_is_specular();
        let n = self.n_samples.max(1);
        let mut f = self.coat_eval(wo, wi, Mode::Radiance) * n as f32;
        let mut rng = WalkRng::new(TAG_EVAL, &[wo, wi], &[]);
        for _ in 0..n {
            // Enter through the coating, and presample the way out to wi
            // (followed backwards, hence importance mode).
            let uc = rng.next();
            let Some(wos) = self.coat_sample(wo, uc, rng.next2(), Mode::Radiance, Lobes::Transmission) else {
                continue;
            };
            let uc = rng.next();
            let Some(wis) = self.coat_sample(wi, uc, rng.next2(), Mode::Importance, Lobes::Transmission)
            else {
                continue;
            };
            let mut beta = wos.f * wos.wi.z.abs() / wos.pdf;
            let mut z = thickness;
            let mut w = wos.wi;
            for depth in 0..self.max_depth {
                if depth > 3 && beta.max_element() < 0.25 {
                    let q = (1.0 - beta.max_element()).max(0.0);
                    if rng.next() < q {
                        break;
                    }
                    beta /= 1.0 - q;
                }
                if !self.scatters() {
                    // Straight to the other boundary through an absorber.
                    z = if z == thickness { 0.0 } else { thickness };
                    beta *= tr(thickness, w);
                } else {
                    let dz = sample_exponential(rng.next(), 1.0 / w.z.abs());
                    let zp = if w.z > 0.0 { z + dz } else { z - dz };
                    if zp == z {
                        continue;
                    }
                    if 0.0 < zp && zp < thickness {
                        // Scattering in the medium: connect to the presampled
                        // exit direction, then continue along the phase function.
                        let phase = henyey_greenstein((-w).dot(-wis.wi), self.g);
                        let wt = if coat_specular { 1.0 } else { power_heuristic(wis.pdf, phase) };
                        f += beta * self.albedo * phase * wt * tr(zp - thickness, wis.wi) * wis.f / wis.pdf;
                        let (wp, p) = sample_henyey_greenstein(-w, self.g, rng.next2());
                        if p == 0.0 || wp.z == 0.0 {
                            continue;
                        }
                        // The phase function is sampled exactly (its value
                        // equals its density), so only the albedo remains.
                        beta *= self.albedo;
                        w = wp;
                        z = zp;
                        // Heading up, towards the exit: connect through the coating.
                        if z < thickness && w.z > 0.0 && !coat_specular {
                            let f_exit = self.coat_eval(-w, wi, Mode::Radiance);
                            if f_exit != Rgb::ZERO {
                                // The density of sampling -w as `wis` (see above).
                                let exit_pdf = self.coat_pdf(wi, -w, Lobes::Transmission);
                                let wt = power_heuristic(p, exit_pdf);
                                f += beta * tr(zp - thickness, wp) * f_exit * wt;
                            }
                        }
                        continue;
                    }
                    z = zp.clamp(0.0, thickness);
                }
                if z == thickness {
                    // Back at the coating from below: reflect inside.
                    let uc = rng.next();
                    let Some(bs) = self.coat_sample(-w, uc, rng.next2(), Mode::Radiance, Lobes::Reflection)
                    else {
                        break;
                    };
                    beta *= bs.f * bs.wi.z.abs() / bs.pdf;
                    w = bs.wi;
                } else {
                    // At the base: next-event estimation along the presampled
                    // exit direction (a specular base reflects no other
                    // direction), then a bounce.
                    if !base_specular {
                        let wt =
                            if coat_specular { 1.0 } else { power_heuristic(wis.pdf, base.pdf(-w, -wis.wi)) };
                        f += beta
                            * base.eval(-w, -wis.wi)
                            * wis.wi.z.abs()
                            * wt
                            * tr(thickness, wis.wi)
                            * wis.f
                            / wis.pdf;
                    }
                    let uc = rng.next();
                    let u = rng.next2();
                    let Some(bs) = usable(base.sample(-w, uc, u)) else {
                        break;
                    };
                    beta *= bs.f * bs.wi.z.abs() / bs.pdf;
                    w = bs.wi;
                    if !coat_specular {
                        // The bounce's own direction, if it leaves towards wi.
                        let f_exit = self.coat_eval(-w, wi, Mode::Radiance);
                        if f_exit != Rgb::ZERO {
                            // The density of sampling -w as `wis` (see above);
                            // a specular bounce is the only way there.
                            let wt = if base_specular {
                                1.0
                            } else {
                                power_heuristic(bs.pdf, self.coat_pdf(wi, -w, Lobes::Transmission))
                            };
                            f += beta * tr(thickness, bs.wi) * f_exit * wt;
                        }
                    }
                }
            }
        }
        f / n as f32
    }

    /// Samples a direction by following one walk until it leaves through
    /// the coating (pbrt's `LayeredBxDF::Sample_f`). `f |cos| / pdf` is the
    /// walk's weight, an unbiased estimate; `pdf` is only proportional to the
    /// density of `wi` ([`super::Bsdf::sampled_pdf_is_proportional`]).
    ///
    /// pbrt multiplies up the whole path's `f` and density separately; both
    /// underflow f32 on long walks (a lossless layer can take hundreds of
    /// steps), so here the walk carries their ratio `beta` and the sample
    /// reports the last step's density, with `f` scaled to match.
    pub fn sample(&self, wo: Vec3, uc: f32, u: Vec2) -> Option<BsdfSample> {
        let flip = wo.z < 0.0;
        let wo = if flip { -wo } else { wo };
        let flip_w = |w: Vec3| if flip { -w } else { w };
        // Reflection at the coating ends the walk at once.
        let bs = self.coat_sample(wo, uc, u, Mode::Radiance, Lobes::All)?;
        if !bs.transmission {
            return Some(BsdfSample { wi: flip_w(bs.wi), ..bs });
        }
        let thickness = self.thickness();
        let mut w = bs.wi;
        let mut specular_path = bs.delta;
        let mut rng = WalkRng::new(TAG_SAMPLE, &[wo], &[uc, u.x, u.y]);
        let mut beta = bs.f * bs.wi.z.abs() / bs.pdf;
        let mut z = thickness;
        for depth in 0..self.max_depth {
            // Russian roulette; surviving walks weigh 1 / (1 - q) more
            // (pbrt divides the path density by it).
            let rr_beta = beta.max_element();
            if depth > 3 && rr_beta < 0.25 {
                let q = (1.0 - rr_beta).max(0.0);
                if rng.next() < q {
                    return None;
                }
                beta /= 1.0 - q;
            }
            if w.z == 0.0 {
                return None;
            }
            if self.scatters() {
                let dz = sample_exponential(rng.next(), 1.0 / w.z.abs());
                let zp = if w.z > 0.0 { z + dz } else { z - dz };
                if zp == z {
                    return None;
                }
                if 0.0 < zp && zp < thickness {
                    let (wp, p) = sample_henyey_greenstein(-w, self.g, rng.next2());
                    if p == 0.0 || wp.z == 0.0 {
                        return None;
                    }
                    // Sampled exactly: the phase function's value over its
                    // density is 1, only the albedo remains.
                    beta *= self.albedo;
                    specular_path = false;
                    w = wp;
                    z = zp;
                    continue;
                }
                z = zp.clamp(0.0, thickness);
            } else {
                z = if z == thickness { 0.0 } else { thickness };
                beta *= tr(thickness, w);
            }
            let uc = rng.next();
            let u = rng.next2();
            let bs = if z == 0.0 {
                usable(self.base().sample(-w, uc, u))
            } else {
                self.coat_sample(-w, uc, u, Mode::Radiance, Lobes::All)
            }?;
            specular_path &= bs.delta;
            w = bs.wi;
            if bs.transmission {
                // Out through the coating (the base never transmits).
                let transmission = !same_hemisphere(wo, w);
                let f = beta * bs.f;
                return Some(BsdfSample {
                    f,
                    wi: flip_w(w),
                    pdf: bs.pdf,
                    eta: 1.0,
                    delta: specular_path,
                    transmission,
                });
            }
            beta *= bs.f * bs.wi.z.abs() / bs.pdf;
        }
        None
    }

    /// pbrt's approximate density for MIS (`LayeredBxDF::PDF`): the
    /// coating's reflection plus an estimate of the paths that refract in,
    /// reflect once at the base and refract out, mixed with a uniform
    /// density (10%) so it is never zero where the BSDF is not.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let (wo, wi) = if wo.z < 0.0 { (-wo, -wi) } else { (wo, wi) };
        let mut rng = WalkRng::new(TAG_PDF, &[wi, wo], &[]);
        let n = self.n_samples.max(1);
        let mut pdf_sum = 0.0;
        // Transmission pairs: the base is opaque, no walk gets through.
        if same_hemisphere(wo, wi) {
            let coat_specular = self.coat().effectively_smooth();
            let base = self.base();
            pdf_sum += n as f32 * self.coat_pdf(wo, wi, Lobes::Reflection);
            for _ in 0..n {
                let uc = rng.next();
                let wos = self.coat_sample(wo, uc, rng.next2(), Mode::Radiance, Lobes::Transmission);
                let uc = rng.next();
                let wis = self.coat_sample(wi, uc, rng.next2(), Mode::Importance, Lobes::Transmission);
                let (Some(wos), Some(wis)) = (wos, wis) else { continue };
                if coat_specular {
                    pdf_sum += base.pdf(-wos.wi, -wis.wi);
                    continue;
                }
                // Rough coating: MIS between sampling the base from the way
                // in and the coating from the base's bounce (the only way
                // for a specular base).
                let uc = rng.next();
                let Some(rs) = usable(base.sample(-wos.wi, uc, rng.next2())) else { continue };
                if self.base_is_specular() {
                    pdf_sum += self.coat_pdf(-rs.wi, wi, Lobes::All);
                    continue;
                }
                let r_pdf = base.pdf(-wos.wi, -wis.wi);
                pdf_sum += power_heuristic(wis.pdf, r_pdf) * r_pdf;
                let t_pdf = self.coat_pdf(-rs.wi, wi, Lobes::All);
                pdf_sum += power_heuristic(rs.pdf, t_pdf) * t_pdf;
            }
        }
        // pbrt's Lerp(0.9, 1 / 4π, estimate).
        0.1 * (1.0 / (4.0 * PI)) + 0.9 * (pdf_sum / n as f32)
    }
}
