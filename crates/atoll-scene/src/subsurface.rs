//! Subsurface scattering on the scene side: the interiors of
//! [`Material::Subsurface`] surfaces, and pbrt-v4's conversion of a
//! subsurface material's diffuse `reflectance` and mean free path into
//! scattering coefficients.
//!
//! atoll renders a subsurface material as what it models: a dielectric
//! boundary around a scattering medium, walked by the path tracer. pbrt-v4
//! instead approximates the walk by a tabulated diffusion profile
//! (photon beam diffusion, Habel et al. 2013). Its parameters mean the same
//! here; only `reflectance` is defined through that profile, so it is
//! converted with the same model, as pbrt-v4 converts it.

use crate::{
    HomogeneousMedium, Material, MaterialId, Medium, MediumIndex, MediumInterface, Rgb, Scene, VACUUM,
};

impl Scene {
    /// Gives every mesh whose material is (or mixes in) a subsurface
    /// material that material's interior: one [`Medium::Subsurface`] per
    /// distinct interior, made the inside of the mesh's medium interface;
    /// its outside stays the medium the shape had outside (the vacuum where
    /// it had no interface). An error names the medium limit when the
    /// interiors do not fit beside the scene's media.
    pub fn attach_subsurface_interiors(&mut self) -> Result<(), String> {
        let mut interiors: Vec<(HomogeneousMedium, MediumIndex)> = Vec::new();
        let mut by_material: Vec<Option<MediumIndex>> = vec![None; self.materials.len()];
        for (id, slot) in by_material.iter_mut().enumerate() {
            let Some(interior) = subsurface_interior(&self.materials, id as MaterialId, 0) else { continue };
            let index = match interiors.iter().find(|(m, _)| *m == interior) {
                Some(&(_, index)) => index,
                None => {
                    if self.media.len() == crate::MAX_MEDIA {
                        return Err(format!(
                            "subsurface materials and media need more than {} media between them",
                            crate::MAX_MEDIA
                        ));
                    }
                    self.media.push(Medium::Subsurface(interior));
                    let index = self.media.len() as MediumIndex;
                    interiors.push((interior, index));
                    index
                }
            };
            *slot = Some(index);
        }
        for mesh in &mut self.meshes {
            if let Some(Some(inside)) = by_material.get(mesh.material as usize) {
                let outside = mesh.media.map_or(VACUUM, |m| m.outside);
                mesh.media = MediumInterface::transition(*inside, outside);
            }
        }
        Ok(())
    }
}

/// The interior of material `id` where it is a subsurface material or a
/// mix holding one (the first found).
fn subsurface_interior(materials: &[Material], id: MaterialId, depth: u32) -> Option<HomogeneousMedium> {
    match materials.get(id as usize)? {
        Material::Subsurface(p) => Some(p.interior),
        Material::Mix { materials: pair, .. } if depth < 16 => {
            pair.iter().find_map(|&m| subsurface_interior(materials, m, depth + 1))
        }
        _ => None,
    }
}

/// pbrt-v4's `SubsurfaceFromDiffuse`: the absorption and scattering
/// coefficients (σa, σs) of a medium whose photon-beam-diffusion profile
/// under a boundary of index `eta`, with Henyey–Greenstein asymmetry `g`,
/// reflects `reflectance` in all, with mean free path `mfp` (1 / σt), per
/// channel.
pub fn from_diffuse(reflectance: Rgb, mfp: Rgb, eta: f32, g: f32) -> (Rgb, Rgb) {
    let table = EffectiveAlbedo::new(eta as f64, g as f64);
    let mut sigma_a = Rgb::ZERO;
    let mut sigma_s = Rgb::ZERO;
    for c in 0..3 {
        let rho = table.albedo_for(reflectance[c].clamp(0.0, 1.0) as f64) as f32;
        let mfp = mfp[c].max(0.0);
        sigma_s[c] = rho / mfp;
        sigma_a[c] = (1.0 - rho) / mfp;
    }
    (sigma_a, sigma_s)
}

/// Albedos and the diffuse reflectance (pbrt's `rhoEff`) of a half-space
/// of unit extinction with each, under the photon-beam-diffusion model.
struct EffectiveAlbedo {
    albedo: Vec<f64>,
    reflectance: Vec<f64>,
}

impl EffectiveAlbedo {
    /// pbrt-v4's `ComputeBeamDiffusionBSSRDF` discretisation: 100 albedos,
    /// denser towards 1, and 64 radii growing by 1.2 from 0.0025 mean free
    /// paths; the radial profile is integrated as a Catmull–Rom spline.
    fn new(eta: f64, g: f64) -> Self {
        const ALBEDOS: usize = 100;
        const RADII: usize = 64;
        let mut radii = vec![0.0, 2.5e-3];
        while radii.len() < RADII {
            radii.push(radii[radii.len() - 1] * 1.2);
        }
        let albedo: Vec<f64> = (0..ALBEDOS)
            .map(|i| (1.0 - (-8.0 * i as f64 / (ALBEDOS - 1) as f64).exp()) / (1.0 - (-8.0f64).exp()))
            .collect();
        let reflectance = albedo
            .iter()
            .map(|&rho| {
                let profile: Vec<f64> = radii
                    .iter()
                    .map(|&r| {
                        2.0 * std::f64::consts::PI
                            * r
                            * (single_scattering(rho, 1.0 - rho, g, eta, r)
                                + multiple_scattering(rho, 1.0 - rho, g, eta, r))
                    })
                    .collect();
                integrate_catmull_rom(&radii, &profile)
            })
            .collect();
        EffectiveAlbedo { albedo, reflectance }
    }

    /// The albedo whose reflectance is `target` (the spline inverted).
    fn albedo_for(&self, target: f64) -> f64 {
        invert_catmull_rom(&self.albedo, &self.reflectance, target)
    }
}

/// pbrt's polynomial fits of the first two Fresnel moments,
/// ∫ Fr(cos θ, η) cosᵏ θ d(cos θ) (d'Eon and Irving 2011).
fn fresnel_moment1(eta: f64) -> f64 {
    let (e2, e3, e4, e5) = (eta * eta, eta.powi(3), eta.powi(4), eta.powi(5));
    if eta < 1.0 {
        0.45966 - 1.73965 * eta + 3.37668 * e2 - 3.904945 * e3 + 2.49277 * e4 - 0.68441 * e5
    } else {
        -4.61686 + 11.1136 * eta - 10.4646 * e2 + 5.11455 * e3 - 1.27198 * e4 + 0.12746 * e5
    }
}

fn fresnel_moment2(eta: f64) -> f64 {
    let (e2, e3, e4, e5) = (eta * eta, eta.powi(3), eta.powi(4), eta.powi(5));
    if eta < 1.0 {
        0.27614 - 0.87350 * eta + 1.12077 * e2 - 0.65095 * e3 + 0.07883 * e4 + 0.04860 * e5
    } else {
        let (r, r2, r3) = (1.0 / eta, 1.0 / e2, 1.0 / e3);
        -547.033 + 45.3087 * r3 - 218.725 * r2 + 458.843 * r + 404.557 * eta - 189.519 * e2 + 54.9327 * e3
            - 9.00603 * e4
            + 0.63942 * e5
    }
}

/// Unpolarised Fresnel reflectance of a dielectric of relative index
/// `eta` for light arriving at `cos_i` (negative: from inside).
fn fresnel_dielectric(cos_i: f64, eta: f64) -> f64 {
    let (cos_i, eta) = if cos_i < 0.0 { (-cos_i, 1.0 / eta) } else { (cos_i, eta) };
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    (parallel * parallel + perpendicular * perpendicular) / 2.0
}

fn henyey_greenstein(cos: f64, g: f64) -> f64 {
    let denom = 1.0 + g * g + 2.0 * g * cos;
    (1.0 - g * g) / (4.0 * std::f64::consts::PI * denom * denom.max(0.0).sqrt())
}

/// The depth `i`-th of `n` stratified samples of an exponential of rate `a` reaches.
fn exponential_quantile(i: usize, n: usize, a: f64) -> f64 {
    -(1.0 - (i as f64 + 0.5) / n as f64).ln() / a
}

const BEAM_SAMPLES: usize = 100;

/// Multiple scattering at distance `r` from where a beam enters: the
/// classical dipole with Grosjean's diffusion coefficient, integrated
/// over the depths the beam's first collisions reach (pbrt-v4's
/// `BeamDiffusionMS`).
fn multiple_scattering(sigma_s: f64, sigma_a: f64, g: f64, eta: f64, r: f64) -> f64 {
    use std::f64::consts::PI;
    let sigmap_s = sigma_s * (1.0 - g);
    let sigmap_t = sigma_a + sigmap_s;
    let rhop = sigmap_s / sigmap_t;
    let d_g = (2.0 * sigma_a + sigmap_s) / (3.0 * sigmap_t * sigmap_t);
    let sigma_tr = (sigma_a / d_g).max(0.0).sqrt();
    let (fm1, fm2) = (fresnel_moment1(eta), fresnel_moment2(eta));
    let ze = -2.0 * d_g * (1.0 + 3.0 * fm2) / (1.0 - 2.0 * fm1);
    let (c_phi, c_e) = (0.25 * (1.0 - 2.0 * fm1), 0.5 * (1.0 - 3.0 * fm2));
    let mut sum = 0.0;
    for i in 0..BEAM_SAMPLES {
        let zr = exponential_quantile(i, BEAM_SAMPLES, sigmap_t);
        let zv = -zr + 2.0 * ze;
        let dr = (r * r + zr * zr).sqrt();
        let dv = (r * r + zv * zv).sqrt();
        let (er, ev) = ((-sigma_tr * dr).exp(), (-sigma_tr * dv).exp());
        let phi = (er / dr - ev / dv) / (4.0 * PI * d_g);
        let e_dn = (zr * (1.0 + sigma_tr * dr) * er / dr.powi(3)
            - zv * (1.0 + sigma_tr * dv) * ev / dv.powi(3))
            / (4.0 * PI);
        let kappa = 1.0 - (-2.0 * sigmap_t * (dr + zr)).exp();
        sum += kappa * rhop * rhop * (phi * c_phi + e_dn * c_e);
    }
    sum / BEAM_SAMPLES as f64
}

/// Single scattering at distance `r` from where a beam enters, over the
/// depths from which light can leave below the critical angle (pbrt-v4's
/// `BeamDiffusionSS`).
fn single_scattering(sigma_s: f64, sigma_a: f64, g: f64, eta: f64, r: f64) -> f64 {
    let sigma_t = sigma_a + sigma_s;
    let rho = sigma_s / sigma_t;
    let t_crit = r * (eta * eta - 1.0).max(0.0).sqrt();
    let mut sum = 0.0;
    for i in 0..BEAM_SAMPLES {
        let t = t_crit + exponential_quantile(i, BEAM_SAMPLES, sigma_t);
        let d = (r * r + t * t).sqrt();
        let cos_o = t / d;
        sum += rho * (-sigma_t * (d + t_crit)).exp() / (d * d)
            * henyey_greenstein(cos_o, g)
            * (1.0 - fresnel_dielectric(-cos_o, eta))
            * cos_o.abs();
    }
    sum / BEAM_SAMPLES as f64
}

/// The slopes a Catmull–Rom spline through `(x, f)` has at the ends of
/// interval `i`, scaled to the interval's width.
fn catmull_rom_slopes(x: &[f64], f: &[f64], i: usize) -> (f64, f64) {
    let width = x[i + 1] - x[i];
    let d0 = if i > 0 { width * (f[i + 1] - f[i - 1]) / (x[i + 1] - x[i - 1]) } else { f[i + 1] - f[i] };
    let d1 = if i + 2 < x.len() { width * (f[i + 2] - f[i]) / (x[i + 2] - x[i]) } else { f[i + 1] - f[i] };
    (d0, d1)
}

/// The integral of the Catmull–Rom spline through `(x, f)` over `x`'s range.
fn integrate_catmull_rom(x: &[f64], f: &[f64]) -> f64 {
    (0..x.len() - 1)
        .map(|i| {
            let (d0, d1) = catmull_rom_slopes(x, f, i);
            ((d0 - d1) / 12.0 + (f[i] + f[i + 1]) / 2.0) * (x[i + 1] - x[i])
        })
        .sum()
}

/// The `x` where the Catmull–Rom spline through `(x, f)`, increasing,
/// reaches `target` (clamped to the ends), by Newton–bisection.
fn invert_catmull_rom(x: &[f64], f: &[f64], target: f64) -> f64 {
    let n = x.len();
    // NaN falls to the first end.
    if target.is_nan() || target <= f[0] {
        return x[0];
    }
    if target >= f[n - 1] {
        return x[n - 1];
    }
    let i = f.partition_point(|&v| v <= target).clamp(1, n - 1) - 1;
    let (f0, f1) = (f[i], f[i + 1]);
    let (d0, d1) = catmull_rom_slopes(x, f, i);
    let (mut a, mut b, mut t) = (0.0f64, 1.0f64, 0.5f64);
    for _ in 0..100 {
        if !(t >= a && t <= b) {
            t = 0.5 * (a + b);
        }
        let (t2, t3) = (t * t, t * t * t);
        let value = (2.0 * t3 - 3.0 * t2 + 1.0) * f0
            + (-2.0 * t3 + 3.0 * t2) * f1
            + (t3 - 2.0 * t2 + t) * d0
            + (t3 - t2) * d1;
        let slope = (6.0 * t2 - 6.0 * t) * f0
            + (-6.0 * t2 + 6.0 * t) * f1
            + (3.0 * t2 - 4.0 * t + 1.0) * d0
            + (3.0 * t2 - 2.0 * t) * d1;
        if (value - target).abs() < 1e-9 || b - a < 1e-9 {
            break;
        }
        if value < target {
            a = t;
        } else {
            b = t;
        }
        t -= (value - target) / slope;
    }
    x[i] + t * (x[i + 1] - x[i])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn catmull_rom_integrates_and_inverts_a_line_exactly() {
        let x: Vec<f64> = (0..10).map(|i| (i as f64).powf(1.3)).collect();
        let f: Vec<f64> = x.iter().map(|v| 2.0 * v + 1.0).collect();
        let end = x[9];
        assert!((integrate_catmull_rom(&x, &f) - (end * end + end)).abs() < 1e-9);
        for target in [1.5, 4.0, 12.25] {
            let at = invert_catmull_rom(&x, &f, target);
            assert!((2.0 * at + 1.0 - target).abs() < 1e-6, "{target}: {at}");
        }
        assert_eq!(invert_catmull_rom(&x, &f, -3.0), x[0]);
        assert_eq!(invert_catmull_rom(&x, &f, 1e9), end);
    }

    #[test]
    fn effective_albedo_rises_from_zero_to_about_one() {
        let table = EffectiveAlbedo::new(1.33, 0.0);
        assert_eq!(table.reflectance[0], 0.0);
        assert!(table.reflectance.windows(2).all(|w| w[1] > w[0]), "{:?}", table.reflectance);
        // Nothing is absorbed at albedo 1: the diffusion model gives back
        // about all the light (it is an approximation, a little over).
        let top = *table.reflectance.last().unwrap();
        assert!((top - 1.0).abs() < 0.05, "{top}");
    }

    #[test]
    fn from_diffuse_reproduces_its_reflectance() {
        let (eta, g) = (1.33, 0.0);
        let table = EffectiveAlbedo::new(eta, g);
        let reflectance = Rgb::new(0.2, 0.5, 0.8);
        let mfp = Rgb::new(1.0, 0.5, 2.0);
        let (sigma_a, sigma_s) = from_diffuse(reflectance, mfp, eta as f32, g as f32);
        for c in 0..3 {
            // Unit mean free path per channel: σt = 1 / mfp.
            assert!(((sigma_a[c] + sigma_s[c]) * mfp[c] - 1.0).abs() < 1e-5);
            let rho = (sigma_s[c] * mfp[c]) as f64;
            let i = table.albedo.partition_point(|&a| a <= rho) - 1;
            let t = (rho - table.albedo[i]) / (table.albedo[i + 1] - table.albedo[i]);
            let back = table.reflectance[i] * (1.0 - t) + table.reflectance[i + 1] * t;
            assert!((back - reflectance[c] as f64).abs() < 0.01, "{c}: {back}");
        }
        // More reflectance asks for more scattering.
        assert!(sigma_s.x * mfp.x < sigma_s.y * mfp.y && sigma_s.y * mfp.y < sigma_s.z * mfp.z);
    }
}
