//! Turns the parameter lists of `Material`, `MakeNamedMaterial`,
//! `AreaLightSource` and `LightSource` into scene values, following
//! pbrt-v4's `*::Create` functions (`materials.cpp`, `lights.cpp`) for names,
//! defaults and errors, with RGB instead of spectra.

use glam::{DMat4, DVec3, Vec3};

use crate::error::{FileLoc, SceneError};
use crate::{
    AreaEmission, CoatedConductorParams, CoatedDiffuseParams, Coating, HairParams, Light, Material, Portal,
    Rgb, TexInput, TexturedParam,
};

use super::params::{ParamList, ParamType, SpectrumParam};
use super::spectrum;
use super::textures::TexCtx;
use super::transform;
use super::WarningSink;

/// A reflectance-like spectrum as RGB; `None` (after a warning) for names we
/// cannot turn into a colour and for textures where the caller takes none
/// (texture-valued parameters go through [`TexCtx`]), so the caller uses its
/// default.
pub(super) fn reflectance_rgb(
    sp: SpectrumParam,
    what: &str,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> Option<Rgb> {
    match sp {
        SpectrumParam::Rgb(c) => Some(c),
        SpectrumParam::Constant(c) => Some(Rgb::splat(c)),
        SpectrumParam::Sampled(s) => Some(spectrum::sampled_rgb(&s)),
        SpectrumParam::Blackbody(t) => Some(spectrum::blackbody_rgb(t)),
        SpectrumParam::Named(n) => match spectrum::named_metal(&n) {
            Some(c) => Some(c),
            None => {
                w.warn(loc, format!("{what}: unknown named spectrum \"{n}\"; using the default"));
                None
            }
        },
        SpectrumParam::Texture(t) => {
            w.warn(loc, format!("{what}: texture \"{t}\" cannot be used here; using the default"));
            None
        }
    }
}

/// pbrt's roughness parameters: `uroughness`/`vroughness` default to
/// `roughness` (default `default`: 0 in pbrt-v4), remapped to GGX alpha
/// unless `remaproughness` is false. A texture-valued one is bound (one
/// `Roughness` binding when both directions read the same texture) and
/// leaves `default` in the material.
pub(super) fn alphas(
    p: &ParamList,
    what: &str,
    default: f32,
    prefix: &str,
    loc: &FileLoc,
    w: &mut WarningSink,
    tex: &mut TexCtx,
) -> Result<(f32, f32), SceneError> {
    let r = tex.float(p, &format!("{prefix}roughness"), what, loc, w)?;
    let u = tex.float(p, &format!("{prefix}uroughness"), what, loc, w)?.or(r);
    let v = tex.float(p, &format!("{prefix}vroughness"), what, loc, w)?.or(r);
    let remap = p.bool_or("remaproughness", true)?;
    // A coated conductor's two surfaces have roughnesses of their own.
    let [both, along_u, along_v] = if prefix == "conductor." {
        [
            TexturedParam::ConductorRoughness,
            TexturedParam::ConductorURoughness,
            TexturedParam::ConductorVRoughness,
        ]
    } else {
        [TexturedParam::Roughness, TexturedParam::URoughness, TexturedParam::VRoughness]
    };
    match (u, v) {
        (Some(TexInput::Texture(a)), Some(TexInput::Texture(b))) if a == b => {
            tex.bindings.push((both, a, remap))
        }
        _ => {
            for (input, param) in [(u, along_u), (v, along_v)] {
                if let Some(TexInput::Texture(t)) = input {
                    tex.bindings.push((param, t, remap));
                }
            }
        }
    }
    let alpha = |input: Option<TexInput>| {
        let r = match input {
            Some(TexInput::Value(c)) => c.x,
            _ => default,
        };
        if remap {
            Material::roughness_to_alpha(r)
        } else {
            r
        }
    };
    Ok((alpha(u), alpha(v)))
}

/// A reflectance-like parameter of the material being made: its value, or
/// `default` with a binding of `param` when a texture gives it.
#[allow(clippy::too_many_arguments)]
pub(super) fn reflectance_param(
    p: &ParamList,
    name: &str,
    param: TexturedParam,
    default: Rgb,
    what: &str,
    loc: &FileLoc,
    w: &mut WarningSink,
    tex: &mut TexCtx,
) -> Result<Rgb, SceneError> {
    Ok(match tex.spectrum(p, name, what, loc, w)? {
        Some(input) => tex.value_or_bind(input, param, default),
        None => default,
    })
}

/// A material of pbrt type `ty` (`MakeNamedMaterial` passes its `string
/// type`); texture-valued parameters become bindings in `tex`.
pub fn material(
    ty: &str,
    p: &ParamList,
    loc: &FileLoc,
    w: &mut WarningSink,
    tex: &mut TexCtx,
) -> Result<Material, SceneError> {
    let what = format!("material \"{ty}\"");
    let reflectance = TexturedParam::Reflectance;
    Ok(match ty {
        "diffuse" => Material::Diffuse {
            reflectance: reflectance_param(
                p,
                "reflectance",
                reflectance,
                Rgb::splat(0.5),
                &what,
                loc,
                w,
                tex,
            )?,
        },
        "conductor" => conductor(p, &what, 0.0, "", loc, w, tex)?,
        "dielectric" => {
            let eta = dielectric_eta(p, &what, loc, w)?;
            let (alpha_x, alpha_y) = alphas(p, &what, 0.0, "", loc, w, tex)?;
            Material::Dielectric { eta, alpha_x, alpha_y }
        }
        "interface" | "" | "none" => Material::Interface,
        "diffusetransmission" => {
            let scale = TexInput::Value(Rgb::splat(p.float_or("scale", 1.0)?));
            let default = TexInput::Value(Rgb::splat(0.25));
            let mut scaled = |name: &str, param: TexturedParam| -> Result<Rgb, SceneError> {
                let input = tex.spectrum(p, name, &what, loc, w)?.unwrap_or(default);
                let input = tex.product(input, scale);
                Ok(tex.value_or_bind(input, param, Rgb::splat(0.25)))
            };
            let reflectance = scaled("reflectance", reflectance)?;
            let transmittance = scaled("transmittance", TexturedParam::Transmittance)?;
            Material::DiffuseTransmission { reflectance, transmittance }
        }
        "thindielectric" => Material::ThinDielectric { eta: dielectric_eta(p, &what, loc, w)? },
        "coateddiffuse" => coated_diffuse(p, &what, "reflectance", (0.5, 0.0), loc, w, tex)?,
        "coatedconductor" => coated_conductor(p, &what, loc, w, tex)?,
        "hair" => hair(p, &what, loc, w, tex)?,
        "subsurface" => subsurface(p, &what, loc, w, tex)?,
        _ => match super::v3::material(ty, p, loc, w, tex)? {
            Some(m) => m,
            None => {
                p.mark_all_used();
                w.warn(
                    loc,
                    format!("material \"{ty}\" is not supported; using diffuse 0.5 (its own look is lost)"),
                );
                Material::default_diffuse()
            }
        },
    })
}

/// pbrt-v4's default subsurface interior, (σa, σs) per millimetre: whole
/// milk's measured coefficients.
const DEFAULT_SUBSURFACE: (Rgb, Rgb) = (Rgb::new(0.0011, 0.0024, 0.014), Rgb::new(2.55, 3.21, 3.77));

/// pbrt-v4's `subsurface` (`SubsurfaceMaterial::Create`). Its interior
/// comes from, in this order: a measured `name` (reduced coefficients, so
/// `g` is 0), `sigma_a` with `sigma_s`, a diffuse `reflectance` with its
/// mean free path `mfp` (1 by default; [`crate::subsurface::from_diffuse`]),
/// or pbrt's default (whole milk's coefficients). `scale` multiplies the
/// coefficients, or the mean free path; the boundary's `eta` is 1.33 and
/// its roughness 0 by default. Coefficients are constants here: a texture
/// in the place of any of them is warned about, and the default interior used.
fn subsurface(
    p: &ParamList,
    what: &str,
    loc: &FileLoc,
    w: &mut WarningSink,
    tex: &mut TexCtx,
) -> Result<Material, SceneError> {
    let mut g = phase_asymmetry(p, what, loc)?;
    let scale = coefficient_scale(p, what, loc)?;
    let eta = p.float_or("eta", 1.33)?;
    if !(eta > 0.0 && eta.is_finite()) {
        return Err(SceneError::at(loc, format!("{what}: \"eta\" {eta} must be positive")));
    }
    // A textured coefficient would vary the interior from point to point;
    // atoll's interior is one medium, so the default stands in for all.
    let coefficients = ["sigma_a", "sigma_s", "reflectance", "mfp"];
    let textured: Vec<&str> =
        coefficients.into_iter().filter(|n| p.find(n, &[ParamType::Texture]).is_some()).collect();
    if !textured.is_empty() {
        for name in coefficients {
            p.spectrum(name, true)?; // read, so that none is reported unused
        }
        w.warn(
            loc,
            format!(
                "{what}: textured {} not supported (the interior is the same everywhere); pbrt-v4's default coefficients are used",
                textured.iter().map(|n| format!("\"{n}\"")).collect::<Vec<_>>().join(", ")
            ),
        );
    }
    let mut constant = |name: &str| -> Result<Option<Rgb>, SceneError> {
        Ok(p.spectrum(name, true)?.and_then(|sp| reflectance_rgb(sp, what, loc, w)))
    };
    let name = p.string("name")?.filter(|n| !n.is_empty());
    let (sigma_a, sigma_s) = if !textured.is_empty() {
        (DEFAULT_SUBSURFACE.0 * scale, DEFAULT_SUBSURFACE.1 * scale)
    } else if let Some(name) = name {
        let Some((sigma_a, sigma_s)) = crate::scattering::measured(&name) else {
            return Err(SceneError::at(loc, format!("{what}: no measured scattering is named \"{name}\"")));
        };
        if g != 0.0 {
            w.warn(loc, format!("{what}: \"g\" {g} ignored with named coefficients (as in pbrt-v4)"));
            g = 0.0;
        }
        (sigma_a * scale, sigma_s * scale)
    } else {
        match (constant("sigma_a")?, constant("sigma_s")?) {
            (Some(sigma_a), Some(sigma_s)) => (sigma_a * scale, sigma_s * scale),
            (Some(_), None) => {
                return Err(SceneError::at(loc, format!("{what}: \"sigma_a\" given without \"sigma_s\"")))
            }
            (None, Some(_)) => {
                return Err(SceneError::at(loc, format!("{what}: \"sigma_s\" given without \"sigma_a\"")))
            }
            (None, None) => match constant("reflectance")? {
                Some(reflectance) => {
                    let mfp = constant("mfp")?.unwrap_or(Rgb::ONE).max(Rgb::ZERO) * scale;
                    crate::subsurface::from_diffuse(reflectance, mfp, eta, g)
                }
                None => (DEFAULT_SUBSURFACE.0 * scale, DEFAULT_SUBSURFACE.1 * scale),
            },
        }
    };
    let (alpha_x, alpha_y) = alphas(p, what, 0.0, "", loc, w, tex)?;
    let interior = crate::HomogeneousMedium {
        sigma_a: sigma_a.max(Rgb::ZERO),
        sigma_s: sigma_s.max(Rgb::ZERO),
        g,
        le: Rgb::ZERO,
    };
    Ok(Material::Subsurface(crate::SubsurfaceParams { eta, alpha_x, alpha_y, interior }))
}

/// pbrt-v4's `conductor` (also pbrt-v3's `metal`, whose default roughness
/// differs): `reflectance`, or `eta` and `k` (copper by default). Its
/// parameter names start with `prefix` (`coatedconductor`'s `conductor.`),
/// but for `reflectance`.
pub(super) fn conductor(
    p: &ParamList,
    what: &str,
    default_roughness: f32,
    prefix: &str,
    loc: &FileLoc,
    w: &mut WarningSink,
    tex: &mut TexCtx,
) -> Result<Material, SceneError> {
    let (eta_name, k_name) = (format!("{prefix}eta"), format!("{prefix}k"));
    let eta = p.spectrum(&eta_name, true)?;
    let k = p.spectrum(&k_name, true)?;
    let reflectance = p.has("reflectance");
    let (alpha_x, alpha_y) = alphas(p, what, default_roughness, prefix, loc, w, tex)?;
    if reflectance && (eta.is_some() || k.is_some()) {
        return Err(SceneError::at(
            loc,
            "conductor: \"reflectance\" cannot be given together with \"eta\" and \"k\"",
        ));
    }
    let (cu_eta, cu_k) = (spectrum::CU_ETA, spectrum::CU_K);
    if reflectance {
        // A textured reflectance gives k per hit the same way.
        let r = reflectance_param(p, "reflectance", TexturedParam::Reflectance, Rgb::ONE, what, loc, w, tex)?;
        return Ok(Material::Conductor {
            eta: Rgb::ONE,
            k: Material::conductor_k_from_reflectance(r),
            alpha_x,
            alpha_y,
        });
    }
    let metal = |sp: Option<SpectrumParam>, default: Rgb, name: &str, w: &mut WarningSink| match sp {
        None => default,
        Some(SpectrumParam::Named(n)) => spectrum::named_metal(&n).unwrap_or_else(|| {
            w.warn(loc, format!("{what}: unknown named spectrum \"{n}\" for \"{name}\"; using copper"));
            default
        }),
        Some(s) => reflectance_rgb(s, what, loc, w).unwrap_or(default),
    };
    // Textured `eta`/`k` (spectrum textures in pbrt-v4) bind per hit; the
    // material keeps copper's value where a texture gives one.
    let is_texture = |sp: &Option<SpectrumParam>| matches!(sp, Some(SpectrumParam::Texture(_)));
    let eta = if is_texture(&eta) {
        reflectance_param(p, &eta_name, TexturedParam::Eta, cu_eta, what, loc, w, tex)?
    } else {
        metal(eta, cu_eta, &eta_name, w)
    };
    let k = if is_texture(&k) {
        reflectance_param(p, &k_name, TexturedParam::K, cu_k, what, loc, w, tex)?
    } else {
        metal(k, cu_k, &k_name, w)
    };
    Ok(Material::Conductor { eta, k, alpha_x, alpha_y })
}

/// pbrt-v4's `coatedconductor` (defaults: `interface.roughness` 0,
/// `interface.eta` 1.5, `thickness` 0.01, `albedo` 0, `g` 0, and the
/// conductor's: copper, `conductor.roughness` 0). Its walk is pbrt's
/// default (`Material::COATED_CONDUCTOR_WALK`): other `maxdepth` or
/// `nsamples` values are warned about and not used.
fn coated_conductor(
    p: &ParamList,
    what: &str,
    loc: &FileLoc,
    w: &mut WarningSink,
    tex: &mut TexCtx,
) -> Result<Material, SceneError> {
    let Material::Conductor { eta, k, alpha_x, alpha_y } =
        conductor(p, what, 0.0, "conductor.", loc, w, tex)?
    else {
        unreachable!("conductor() makes conductors")
    };
    let mut coating = coating(p, what, "interface.", 0.0, loc, w, tex)?;
    let (max_depth, n_samples) = Material::COATED_CONDUCTOR_WALK;
    if (coating.max_depth, coating.n_samples) != (max_depth, n_samples) {
        w.warn(
            loc,
            format!(
                "{what}: \"maxdepth\" {} and \"nsamples\" {} are not supported for \"coatedconductor\"; \
                 its layers are followed with {max_depth} and {n_samples} (noise and energy of long walks differ)",
                coating.max_depth, coating.n_samples
            ),
        );
        (coating.max_depth, coating.n_samples) = (max_depth, n_samples);
    }
    if alpha_x != alpha_y || coating.alpha_x != coating.alpha_y {
        w.warn(
            loc,
            format!(
                "{what}: anisotropic roughness of \"coatedconductor\" is oriented about the shading normal \
                 alone, not along the surface's dp/du (its hits have no room for a tangent): \
                 the highlights' direction will differ"
            ),
        );
    }
    Ok(Material::CoatedConductor(CoatedConductorParams { eta, k, alpha_x, alpha_y, coating }))
}

/// pbrt-v4's `hair` (pbrt-v3's reads the same): the fibre's absorption
/// from `sigma_a`, else `reflectance` (pbrt-v3's `color`), else the melanin
/// concentrations `eumelanin` and `pheomelanin`, else eumelanin 1.3
/// (brown); `eta` 1.55, `beta_m` and `beta_n` 0.3 (clamped to [0.01, 1]),
/// `alpha` 2 degrees. `sigma_a`, `reflectance`, `eta`, `beta_m`, `beta_n`
/// and `alpha` may be textures (evaluated per hit; a reflectance becomes
/// an absorption with the hit's `beta_n`), and so may the melanin
/// concentrations (their absorptions added up per hit).
fn hair(
    p: &ParamList,
    what: &str,
    loc: &FileLoc,
    w: &mut WarningSink,
    tex: &mut TexCtx,
) -> Result<Material, SceneError> {
    let default = HairParams::pbrt_default();
    // A textured parameter keeps its default here, bound per hit.
    let mut float = |name: &str, param: TexturedParam, fallback: f32, w: &mut WarningSink| {
        let input = tex.float(p, name, what, loc, w)?;
        let textured = matches!(input, Some(TexInput::Texture(_)));
        let value = input.map(|input| tex.value_or_bind(input, param, Rgb::splat(fallback)).x);
        Ok::<_, SceneError>((value, textured))
    };
    let eta = float("eta", TexturedParam::Eta, default.eta, w)?.0.unwrap_or(default.eta);
    let beta_m = float("beta_m", TexturedParam::BetaM, default.beta_m, w)?
        .0
        .unwrap_or(default.beta_m)
        .clamp(0.01, 1.0);
    let (beta_n, beta_n_textured) = float("beta_n", TexturedParam::BetaN, default.beta_n, w)?;
    let beta_n = beta_n.unwrap_or(default.beta_n).clamp(0.01, 1.0);
    let alpha = float("alpha", TexturedParam::HairAlpha, default.alpha, w)?.0.unwrap_or(default.alpha);
    let eumelanin = tex.float(p, "eumelanin", what, loc, w)?;
    let pheomelanin = tex.float(p, "pheomelanin", what, loc, w)?;
    let sigma_a = tex.spectrum(p, "sigma_a", what, loc, w)?;
    let reflectance = match tex.spectrum(p, "reflectance", what, loc, w)? {
        Some(c) => Some(c),
        None => tex.spectrum(p, "color", what, loc, w)?,
    };
    let melanin = eumelanin.is_some() || pheomelanin.is_some();
    let given = [sigma_a.is_some(), reflectance.is_some(), melanin];
    if given.iter().filter(|&&g| g).count() > 1 {
        let used = if sigma_a.is_some() { "\"sigma_a\"" } else { "\"reflectance\"" };
        w.warn(loc, format!("{what}: more than one of \"sigma_a\", \"reflectance\" and the melanin concentrations; {used} is used, as in pbrt-v4"));
    }
    let sigma_a = match (sigma_a, reflectance) {
        // Bound per hit where textured; the default stands for it here.
        (Some(s), _) => tex.value_or_bind(s, TexturedParam::SigmaA, default.sigma_a),
        (None, Some(TexInput::Value(c))) if !beta_n_textured => {
            HairParams::sigma_a_from_reflectance(c, beta_n)
        }
        // Turned into an absorption per hit, with the hit's `beta_n` (even
        // a constant reflectance, where `beta_n` is a texture).
        (None, Some(c)) => {
            tex.bind_always(c, TexturedParam::Reflectance);
            default.sigma_a
        }
        // A textured concentration adds its absorption per hit to the
        // constant one's (pbrt-v4 takes a missing one as 0).
        (None, None) if melanin => {
            let mut concentration = |input: Option<TexInput>, param| match input {
                Some(TexInput::Value(c)) => c.x,
                Some(texture) => {
                    tex.bind_always(texture, param);
                    0.0
                }
                None => 0.0,
            };
            let eumelanin = concentration(eumelanin, TexturedParam::Eumelanin);
            let pheomelanin = concentration(pheomelanin, TexturedParam::Pheomelanin);
            HairParams::sigma_a_from_concentration(eumelanin, pheomelanin)
        }
        (None, None) => default.sigma_a,
    };
    Ok(Material::Hair(HairParams { sigma_a, eta, beta_m, beta_n, alpha }))
}

/// pbrt-v4's `coateddiffuse` (defaults: `reflectance` 0.5, `roughness` 0,
/// `thickness` 0.01, `eta` 1.5, `albedo` 0, `g` 0, `maxdepth` 10,
/// `nsamples` 1). pbrt-v3's `plastic` and `substrate` are read with it too:
/// they name the base colour `base` ("Kd") and bring their own
/// `(reflectance, roughness)` defaults.
#[allow(clippy::too_many_arguments)]
pub(super) fn coated_diffuse(
    p: &ParamList,
    what: &str,
    base: &str,
    (default_reflectance, default_roughness): (f32, f32),
    loc: &FileLoc,
    w: &mut WarningSink,
    tex: &mut TexCtx,
) -> Result<Material, SceneError> {
    let default = Rgb::splat(default_reflectance);
    let reflectance = reflectance_param(p, base, TexturedParam::Reflectance, default, what, loc, w, tex)?;
    let coating = coating(p, what, "", default_roughness, loc, w, tex)?;
    Ok(Material::CoatedDiffuse(CoatedDiffuseParams { reflectance, coating }))
}

/// The coating and medium of pbrt-v4's coated materials: the coating's
/// roughness and index named with `prefix` (`coatedconductor`'s
/// `interface.`), `thickness`, `albedo`, `g`, `maxdepth` and `nsamples`
/// (defaults: [`Coating::PBRT_DEFAULT`], roughness `default_roughness`).
fn coating(
    p: &ParamList,
    what: &str,
    prefix: &str,
    default_roughness: f32,
    loc: &FileLoc,
    w: &mut WarningSink,
    tex: &mut TexCtx,
) -> Result<Coating, SceneError> {
    let default = Coating::PBRT_DEFAULT;
    let (alpha_x, alpha_y) = alphas(p, what, default_roughness, prefix, loc, w, tex)?;
    let eta = named_dielectric_eta(p, &format!("{prefix}eta"), what, loc, w)?;
    // pbrt-v4 reads an index of 0 as 1 (no interface).
    let eta = if eta == 0.0 { 1.0 } else { eta };
    // A textured medium parameter keeps its default here, bound per hit.
    let medium = |tex: &mut TexCtx, input: Option<TexInput>, param, default: Rgb| match input {
        Some(input) => tex.value_or_bind(input, param, default),
        None => default,
    };
    let thickness = tex.float(p, "thickness", what, loc, w)?;
    let thickness = medium(tex, thickness, TexturedParam::Thickness, Rgb::splat(default.thickness)).x;
    // pbrt-v4 clamps the albedo to [0, 1] and `g` to [-1, 1] (textured
    // values are clamped where they are evaluated).
    let albedo = tex.spectrum(p, "albedo", what, loc, w)?;
    let albedo = medium(tex, albedo, TexturedParam::Albedo, default.albedo).clamp(Rgb::ZERO, Rgb::ONE);
    let g = tex.float(p, "g", what, loc, w)?;
    let g = medium(tex, g, TexturedParam::G, Rgb::splat(default.g)).x.clamp(-1.0, 1.0);
    let count = |name: &str, default: u32, min: i64| -> Result<u32, SceneError> {
        let v = p.int(name)?.unwrap_or(default as i64);
        let max = Material::COATED_MAX_COUNT as i64;
        if (min..=max).contains(&v) {
            return Ok(v as u32);
        }
        let at = p.find(name, &[ParamType::Integer]).map_or(loc, |q| &q.loc);
        Err(SceneError::at(at, format!("{what}: \"{name}\" must be between {min} and {max}, found {v}")))
    };
    let (max_depth, n_samples) =
        (count("maxdepth", default.max_depth, 0)?, count("nsamples", default.n_samples, 1)?);
    Ok(Coating { eta, alpha_x, alpha_y, thickness, albedo, g, max_depth, n_samples })
}

/// A dielectric's `eta` in any of its spellings (default 1.5).
pub(super) fn dielectric_eta(
    p: &ParamList,
    what: &str,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> Result<f32, SceneError> {
    named_dielectric_eta(p, "eta", what, loc, w)
}

/// A dielectric index given as `name` (`coatedconductor`'s
/// `interface.eta`), in any of its spellings (default 1.5).
fn named_dielectric_eta(
    p: &ParamList,
    name: &str,
    what: &str,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> Result<f32, SceneError> {
    Ok(match p.spectrum(name, true)? {
        None => 1.5,
        Some(SpectrumParam::Constant(e)) => e,
        Some(SpectrumParam::Named(n)) => spectrum::named_glass(&n).unwrap_or_else(|| {
            w.warn(loc, format!("{what}: unknown named spectrum \"{n}\" for \"{name}\"; using 1.5"));
            1.5
        }),
        Some(SpectrumParam::Sampled(s)) => {
            // pbrt disperses light with a varying eta; we take its value mid-spectrum.
            w.warn(
                loc,
                format!("{what}: spectrally varying \"{name}\" is approximated by its value at 550 nm"),
            );
            spectrum::sampled_at(&s, 550.0)
        }
        Some(other) => {
            w.warn(loc, format!("{what}: \"{name}\" given as {other:?} is not supported; using 1.5"));
            1.5
        }
    })
}

/// A light spectrum as RGB. pbrt-v4 divides every light spectrum by its
/// luminance (so `scale` alone sets brightness); for RGB values that
/// normalisation is by the colour space's white, which leaves them unchanged.
fn light_rgb(sp: SpectrumParam, what: &str, loc: &FileLoc, w: &mut WarningSink) -> Result<Rgb, SceneError> {
    let rgb = light_rgb_unchecked(sp, what, loc, w);
    // Negative light is no light: refused rather than subtracted from the image.
    if rgb.min_element() < 0.0 {
        return Err(SceneError::at(loc, format!("{what}: negative radiance {rgb:?}")));
    }
    Ok(rgb)
}

/// [`light_rgb`] before the check.
fn light_rgb_unchecked(sp: SpectrumParam, what: &str, loc: &FileLoc, w: &mut WarningSink) -> Rgb {
    let luminance_one = |c: Rgb| {
        let y = crate::luminance(c);
        if y > 0.0 {
            c / y
        } else {
            c
        }
    };
    match sp {
        SpectrumParam::Rgb(c) => c,
        SpectrumParam::Constant(c) => Rgb::splat(c),
        SpectrumParam::Blackbody(t) => spectrum::blackbody_rgb(t),
        SpectrumParam::Sampled(s) => luminance_one(spectrum::sampled_rgb(&s)),
        SpectrumParam::Named(n) => spectrum::named_illuminant(&n).unwrap_or_else(|| {
            w.warn(loc, format!("{what}: unknown named spectrum \"{n}\"; using white"));
            Rgb::ONE
        }),
        SpectrumParam::Texture(t) => {
            w.warn(loc, format!("{what}: texture \"{t}\" is not a valid light spectrum; using white"));
            Rgb::ONE
        }
    }
}

/// A light's `scale`: refused when negative, as negative radiance is.
fn light_scale(p: &ParamList, what: &str, loc: &FileLoc) -> Result<f32, SceneError> {
    let scale = p.float_or("scale", 1.0)?;
    if scale < 0.0 {
        let at = p.find("scale", &[ParamType::Float]).map_or(loc, |q| &q.loc);
        return Err(SceneError::at(at, format!("{what}: negative \"scale\" {scale}")));
    }
    Ok(scale)
}

/// A light's image `file` (beside the scene): `None`, after a warning,
/// where it cannot be read and `--allow-missing` lets the light emit
/// nothing; an error otherwise.
fn light_image(
    base_dir: &std::path::Path,
    file: &str,
    what: &str,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> Result<Option<crate::EnvironmentImage>, SceneError> {
    let image = crate::input::beside(base_dir, file)
        .map_err(crate::ImageLoadError::io(std::path::Path::new(file)))
        .and_then(|path| crate::EnvironmentImage::load(&path));
    match image {
        Ok(image) => Ok(Some(image)),
        Err(e) => {
            super::missing_file(loc, what, e.clone())?;
            w.warn(loc, format!("{what}: {e}; it emits nothing"));
            Ok(None)
        }
    }
}

/// `AreaLightSource "diffuse"`; `None` (after a warning) for other types.
pub fn area_light(
    ty: &str,
    p: &ParamList,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> Result<Option<AreaEmission>, SceneError> {
    if ty != "diffuse" {
        p.mark_all_used();
        w.warn(loc, format!("area light \"{ty}\" is not supported; shapes get no emission"));
        return Ok(None);
    }
    let what = "area light \"diffuse\"";
    p.find("nsamples", &[ParamType::Integer]);
    let l = p.spectrum("L", false)?.map(|s| light_rgb(s, what, loc, w)).transpose()?.unwrap_or(Rgb::ONE);
    let scale = light_scale(p, what, loc)?;
    let two_sided = p.bool_or("twosided", false)?;
    // An image (`filename`, read by the builder) replaces "L": the radiance
    // is `scale` times the image (pbrt-v4 refuses both; we warn).
    let radiance = if p.string("filename")?.is_some() {
        if p.spectrum("L", false)?.is_some() {
            w.warn(loc, format!("{what}: both \"L\" and \"filename\" given; the image is used"));
        }
        Rgb::splat(scale)
    } else {
        l * scale
    };
    Ok(Some(AreaEmission { radiance, two_sided }))
}

/// `LightSource`; `None` (after a warning) for unsupported types. `ctm` is
/// the light-to-world transform in effect; image file names are relative to
/// `base_dir`.
pub fn light(
    ty: &str,
    p: &ParamList,
    ctm: &DMat4,
    base_dir: &std::path::Path,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> Result<Option<Light>, SceneError> {
    let what = format!("light \"{ty}\"");
    // pbrt-v3's sample-count hint means nothing to a path tracer with light sampling.
    p.find("nsamples", &[ParamType::Integer]);
    let p3 =
        |name: &str, d: Vec3| -> Result<DVec3, SceneError> { Ok(p.point3(name)?.unwrap_or(d).as_dvec3()) };
    Ok(Some(match ty {
        "point" => {
            let i =
                p.spectrum("I", false)?.map(|s| light_rgb(s, &what, loc, w)).transpose()?.unwrap_or(Rgb::ONE);
            let scale = light_scale(p, &what, loc)?;
            let position = transform::point(ctm, p3("from", Vec3::ZERO)?).as_vec3();
            Light::Point { position, intensity: i * scale }
        }
        "spot" => {
            let i =
                p.spectrum("I", false)?.map(|s| light_rgb(s, &what, loc, w)).transpose()?.unwrap_or(Rgb::ONE);
            let scale = light_scale(p, &what, loc)?;
            let (from, to) = (p3("from", Vec3::ZERO)?, p3("to", Vec3::Z)?);
            let cone_angle = p.float_or("coneangle", 30.0)?;
            let cone_delta = p.float_or("conedelta", 5.0)?;
            if !(0.0..=180.0).contains(&cone_angle) || cone_delta < 0.0 {
                return Err(SceneError::at(
                    loc,
                    format!("{what}: \"coneangle\" must be in [0, 180] and \"conedelta\" not negative (got {cone_angle}, {cone_delta})"),
                ));
            }
            let Some(direction) = ctm.transform_vector3(to - from).try_normalize() else {
                return Err(SceneError::at(loc, format!("{what}: \"from\" and \"to\" give no direction")));
            };
            let position = transform::point(ctm, from).as_vec3();
            let mut light = Light::spot(position, direction.as_vec3(), i * scale, cone_angle, cone_delta);
            // pbrt-v4: `power` (W) sets the emitted power, replacing I's
            // brightness; 0 leaves I as it is (pbrt's "unset"), and a
            // negative power means nothing, as negative radiance.
            let power = p.float("power")?;
            if let Some(power) = power.filter(|&v| v < 0.0) {
                let at = p.find("power", &[ParamType::Float]).map_or(loc, |q| &q.loc);
                return Err(SceneError::at(at, format!("{what}: negative \"power\" {power}")));
            }
            if let (Some(power), Light::Spot { intensity, cos_falloff_start, cos_falloff_end, .. }) =
                (power.filter(|&v| v > 0.0), &mut light)
            {
                let per_unit =
                    Light::spot_solid_angle(*cos_falloff_start, *cos_falloff_end) * crate::luminance(i);
                if per_unit > 0.0 {
                    *intensity = i * (scale * power / per_unit);
                }
            }
            light
        }
        "goniometric" => {
            let i =
                p.spectrum("I", false)?.map(|s| light_rgb(s, &what, loc, w)).transpose()?.unwrap_or(Rgb::ONE);
            let scale = light_scale(p, &what, loc)?;
            let Some(file) = p.string("filename")? else {
                w.warn(loc, format!("{what}: no \"filename\" given; it emits nothing (as in pbrt-v4)"));
                return Ok(None);
            };
            let Some(image) = light_image(base_dir, &file, &what, loc, w)? else { return Ok(None) };
            if image.width != image.height {
                return Err(SceneError::at(
                    loc,
                    format!(
                        "{what}: \"{file}\" is {}x{}, not square: not an equal-area map of directions",
                        image.width, image.height
                    ),
                ));
            }
            let map = crate::IntensityMap {
                resolution: image.width,
                values: image.pixels.iter().map(|p| (p.x + p.y + p.z) / 3.0).collect(),
            };
            // pbrt-v4: `power` sets the emitted power, 4π × the map's mean × I.
            let mut intensity = i * scale;
            match p.float("power")? {
                Some(power) if power < 0.0 => {
                    let at = p.find("power", &[ParamType::Float]).map_or(loc, |q| &q.loc);
                    return Err(SceneError::at(at, format!("{what}: negative \"power\" {power}")));
                }
                Some(power) if power > 0.0 => {
                    let per_unit = 4.0 * std::f32::consts::PI * map.mean() * crate::luminance(i);
                    if per_unit > 0.0 {
                        intensity = i * (scale * power / per_unit);
                    }
                }
                _ => {}
            }
            let m = glam::DMat3::from_mat4(*ctm);
            if m.determinant() == 0.0 || !m.determinant().is_finite() {
                return Err(SceneError::at(loc, format!("{what}: the current transform is not invertible")));
            }
            Light::Goniometric {
                position: transform::point(ctm, DVec3::ZERO).as_vec3(),
                world_to_light: m.inverse().as_mat3(),
                intensity,
                map: std::sync::Arc::new(map),
            }
        }
        "projection" => {
            let scale = light_scale(p, &what, loc)?;
            let fov = p.float_or("fov", 90.0)?;
            if !(fov > 0.0 && fov < 180.0) {
                return Err(SceneError::at(
                    loc,
                    format!("{what}: \"fov\" {fov} is not between 0 and 180 degrees"),
                ));
            }
            let Some(file) = p.string("filename")? else {
                return Err(SceneError::at(
                    loc,
                    format!("{what}: \"filename\" must be given (as pbrt-v4 requires)"),
                ));
            };
            let Some(image) = light_image(base_dir, &file, &what, loc, w)? else { return Ok(None) };
            if image.pixels.iter().any(|p| !p.is_finite()) {
                return Err(SceneError::at(
                    loc,
                    format!("{what}: \"{file}\" has pixels that are not finite: not suitable as a light"),
                ));
            }
            let image = crate::ProjectionImage {
                width: image.width,
                height: image.height,
                pixels: image.pixels,
                tan_half_fov: (fov.to_radians() * 0.5).tan(),
            };
            // pbrt-v4: `power` sets the luminous power the image sends out.
            let mut intensity = scale;
            match p.float("power")? {
                Some(power) if power < 0.0 => {
                    let at = p.find("power", &[ParamType::Float]).map_or(loc, |q| &q.loc);
                    return Err(SceneError::at(at, format!("{what}: negative \"power\" {power}")));
                }
                Some(power) if power > 0.0 => {
                    let per_unit = crate::luminance(image.power());
                    if per_unit > 0.0 {
                        intensity = scale * power / per_unit;
                    }
                }
                _ => {}
            }
            let m = glam::DMat3::from_mat4(*ctm);
            if m.determinant() == 0.0 || !m.determinant().is_finite() {
                return Err(SceneError::at(loc, format!("{what}: the current transform is not invertible")));
            }
            // pbrt-v4 turns the light's y over, so that the image's top row
            // is up in the light's space.
            let flip = glam::DMat3::from_diagonal(DVec3::new(1.0, -1.0, 1.0));
            Light::Projection {
                position: transform::point(ctm, DVec3::ZERO).as_vec3(),
                world_to_light: (flip * m.inverse()).as_mat3(),
                scale: intensity,
                image: std::sync::Arc::new(image),
            }
        }
        "distant" => {
            let l =
                p.spectrum("L", false)?.map(|s| light_rgb(s, &what, loc, w)).transpose()?.unwrap_or(Rgb::ONE);
            let scale = light_scale(p, &what, loc)?;
            let (from, to) = (p3("from", Vec3::ZERO)?, p3("to", Vec3::Z)?);
            // pbrt stores the direction towards the light (from - to); ours is the way light travels.
            let Some(direction) = ctm.transform_vector3(to - from).try_normalize() else {
                return Err(SceneError::at(loc, "light \"distant\": \"from\" and \"to\" give no direction"));
            };
            Light::Distant { direction: direction.as_vec3(), radiance: l * scale }
        }
        "infinite" => {
            let l = p.spectrum("L", false)?;
            let scale = light_scale(p, &what, loc)?;
            // pbrt-v4's "illuminance": scale the light so that a surface
            // facing up (+z in the light's space) receives this illuminance
            // (luminance units; atoll renders RGB, so the light's luminance
            // stands for pbrt's photometric normalisation).
            let illuminance = p.float_or("illuminance", -1.0)?;
            let normalise = |k_e: f64| -> f32 {
                if illuminance > 0.0 && k_e > 0.0 {
                    (illuminance as f64 / k_e) as f32
                } else {
                    1.0
                }
            };
            // The portal's corners are in world space: pbrt-v4 takes them as
            // they are, whatever the light's transform.
            let portal = match p.numbers("portal", ParamType::Point3) {
                None => None,
                Some(points) if points.len() != 12 => {
                    return Err(SceneError::at(
                        loc,
                        format!("{what}: \"portal\" needs 4 points (a rectangle), got {}", points.len() / 3),
                    ));
                }
                Some(points) => {
                    let corner = |i: usize| {
                        Vec3::new(points[3 * i] as f32, points[3 * i + 1] as f32, points[3 * i + 2] as f32)
                    };
                    let portal = Portal::new([0, 1, 2, 3].map(corner));
                    Some(portal.map_err(|e| SceneError::at(loc, format!("{what}: {e}")))?)
                }
            };
            // pbrt-v3 called the environment map "mapname".
            let filename = match p.string("filename")? {
                Some(f) => Some(f),
                None => p.string("mapname")?,
            };
            if l.is_some() && filename.is_some() {
                return Err(SceneError::at(
                    loc,
                    "light \"infinite\": cannot give both \"L\" and \"filename\"",
                ));
            }
            if let Some(f) = filename {
                // The image's radiance times `scale`.
                let image = crate::input::beside(base_dir, &f)
                    .map_err(crate::ImageLoadError::io(std::path::Path::new(&f)))
                    .and_then(|path| crate::EnvironmentImage::load(&path));
                match image {
                    Ok(image) => {
                        let scale = scale * normalise(image.upper_hemisphere_illuminance());
                        let m = glam::DMat3::from_mat4(*ctm).as_mat3();
                        // Columns normalised: the light's rotation without any scale.
                        let light_to_world = glam::Mat3::from_cols(
                            m.x_axis.normalize(),
                            m.y_axis.normalize(),
                            m.z_axis.normalize(),
                        );
                        return Ok(Some(Light::Environment {
                            image: std::sync::Arc::new(image),
                            scale: Rgb::splat(scale),
                            light_to_world,
                            portal,
                        }));
                    }
                    Err(e) => {
                        super::missing_file(loc, &what, e.clone())?;
                        w.warn(loc, format!("{what}: {e}; using constant white instead"))
                    }
                }
            }
            let l = l.map(|s| light_rgb(s, &what, loc, w)).transpose()?.unwrap_or(Rgb::ONE);
            let k_e = std::f64::consts::PI * crate::luminance(l) as f64;
            Light::Infinite { radiance: l * scale * normalise(k_e), portal }
        }
        _ => {
            p.mark_all_used();
            w.warn(loc, format!("{what} is not supported; skipped (its light is missing from the image)"));
            return Ok(None);
        }
    }))
}

/// `MakeNamedMedium`, following pbrt-v4's `HomogeneousMedium::Create`,
/// `GridMedium::Create` and `RGBGridMedium::Create`: `sigma_a` and
/// `sigma_s` default to 1, both scaled by `scale`; `g` 0; a homogeneous
/// medium's `Le` (0) scaled by `Lescale`. A `uniformgrid` scales them by
/// its `density` samples, an `rgbgrid` takes them from its RGB samples
/// (see [`grid_medium`]). `None`, after a warning, for the types atoll
/// does not render (clouds, NanoVDB): the medium is a vacuum.
pub fn medium(
    name: &str,
    p: &ParamList,
    ctm: &DMat4,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> Result<Option<crate::Medium>, SceneError> {
    let what = format!("MakeNamedMedium \"{name}\"");
    let ty = p.string("type")?.unwrap_or_default();
    if !["homogeneous", "uniformgrid", "rgbgrid"].contains(&ty.as_str()) {
        p.mark_all_used();
        let ty = if ty.is_empty() { "(no type)".to_string() } else { format!("\"{ty}\"") };
        w.warn(loc, format!("{what}: medium type {ty} is not supported; it is a vacuum: the image lacks its fog, smoke or scattering"));
        return Ok(None);
    }
    let scale = coefficient_scale(p, &what, loc)?;
    let g = phase_asymmetry(p, &what, loc)?;
    if ty == "rgbgrid" {
        return rgb_grid_medium(&what, p, scale, g, ctm, loc).map(|g| Some(crate::Medium::Grid(g)));
    }
    let mut m = crate::HomogeneousMedium::pbrt_default();
    let coefficient = |name: &str, default: Rgb, w: &mut WarningSink| -> Result<Rgb, SceneError> {
        Ok(p.spectrum(name, true)?.and_then(|sp| reflectance_rgb(sp, &what, loc, w)).unwrap_or(default))
    };
    // A measured preset replaces both coefficients (pbrt-v4 warns about an
    // unknown name and reads them from the parameters then).
    let preset = if ty == "homogeneous" { p.string("preset")?.filter(|n| !n.is_empty()) } else { None };
    match preset.as_deref().map(|n| (n, crate::scattering::measured(n))) {
        Some((_, Some((sigma_a, sigma_s)))) => {
            m.sigma_a = sigma_a * scale;
            m.sigma_s = sigma_s * scale;
        }
        found => {
            if let Some((name, None)) = found {
                w.warn(loc, format!("{what}: no measured scattering is named \"{name}\"; \"sigma_a\" and \"sigma_s\" are used"));
            }
            m.sigma_a = coefficient("sigma_a", m.sigma_a, w)? * scale;
            m.sigma_s = coefficient("sigma_s", m.sigma_s, w)? * scale;
        }
    }
    m.g = g;
    let le = match p.spectrum("Le", false)? {
        Some(le) => light_rgb(le, &what, loc, w)?,
        None => Rgb::ZERO,
    };
    if ty == "uniformgrid" {
        return density_grid_medium(&what, p, m, le, ctm, loc).map(|g| Some(crate::Medium::Grid(g)));
    }
    m.le = le * p.float_or("Lescale", 1.0)?.max(0.0);
    Ok(Some(crate::Medium::Homogeneous(m)))
}

/// A medium's `scale` of its coefficients (1 by default), finite and not negative.
fn coefficient_scale(p: &ParamList, what: &str, loc: &FileLoc) -> Result<f32, SceneError> {
    let scale = p.float_or("scale", 1.0)?;
    if !(scale >= 0.0 && scale.is_finite()) {
        return Err(SceneError::at(
            loc,
            format!("{what}: \"scale\" {scale} must be finite and not negative"),
        ));
    }
    Ok(scale)
}

/// A medium's Henyey–Greenstein asymmetry `g` (0 by default), in (-1, 1).
fn phase_asymmetry(p: &ParamList, what: &str, loc: &FileLoc) -> Result<f32, SceneError> {
    let g = p.float_or("g", 0.0)?;
    if !(g > -1.0 && g < 1.0) {
        return Err(SceneError::at(loc, format!("{what}: \"g\" {g} must be between -1 and 1")));
    }
    Ok(g)
}

/// The samples per axis of a grid medium (`nx`, `ny`, `nz`, 1 each by default).
fn grid_resolution(what: &str, p: &ParamList, loc: &FileLoc) -> Result<[u32; 3], SceneError> {
    let count = |axis: &str| -> Result<u32, SceneError> {
        match p.int(axis)? {
            None => Ok(1),
            Some(n) if (1..=1 << 16).contains(&n) => Ok(n as u32),
            Some(n) => Err(SceneError::at(loc, format!("{what}: \"{axis}\" {n} must be from 1 to 65536"))),
        }
    };
    Ok([count("nx")?, count("ny")?, count("nz")?])
}

/// The values of grid parameter `name` (`per_sample` numbers for each of
/// the `resolution`'s samples), checked finite and not negative; `None`
/// where it is not given.
fn grid_values(
    what: &str,
    p: &ParamList,
    name: &str,
    ty: ParamType,
    per_sample: usize,
    resolution: [u32; 3],
    loc: &FileLoc,
) -> Result<Option<Vec<f32>>, SceneError> {
    let Some(numbers) = p.numbers(name, ty) else { return Ok(None) };
    let samples = resolution.iter().map(|&n| n as usize).product::<usize>();
    if numbers.len() != samples * per_sample {
        let [nx, ny, nz] = resolution;
        let unit = if per_sample == 3 { " RGB" } else { "" };
        return Err(SceneError::at(
            loc,
            format!(
                "{what}: \"{name}\" has {}{unit} values for {nx}x{ny}x{nz} samples",
                numbers.len() / per_sample
            ),
        ));
    }
    if let Some(v) = numbers.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
        return Err(SceneError::at(
            loc,
            format!("{what}: \"{name}\" value {v} must be finite and not negative"),
        ));
    }
    Ok(Some(numbers.iter().map(|&v| v as f32).collect()))
}

/// A grid medium's box (`p0`, `p1`, the unit cube by default) and the
/// world-to-medium transform of the space `ctm` places it in.
fn grid_placement(
    what: &str,
    p: &ParamList,
    ctm: &DMat4,
    loc: &FileLoc,
) -> Result<(Vec3, Vec3, glam::Affine3A), SceneError> {
    let lo = p.point3("p0")?.unwrap_or(Vec3::ZERO);
    let hi = p.point3("p1")?.unwrap_or(Vec3::ONE);
    if !(lo.cmplt(hi).all()) {
        return Err(SceneError::at(loc, format!("{what}: the box \"p0\" {lo} to \"p1\" {hi} is empty")));
    }
    let det = ctm.determinant();
    if det == 0.0 || !det.is_finite() {
        return Err(SceneError::at(loc, format!("{what}: the current transform is not invertible")));
    }
    Ok((lo, hi, glam::Affine3A::from_mat4(transform::to_f32(&ctm.inverse()))))
}

/// The grid medium over `resolution` samples with `values` (each a whole
/// grid: one or more numbers per sample) and `fields` reading them.
#[allow(clippy::too_many_arguments)]
fn grid_medium(
    what: &str,
    p: &ParamList,
    resolution: [u32; 3],
    values: &[Vec<f32>],
    [sigma_a, sigma_s, le]: [crate::GridField; 3],
    g: f32,
    ctm: &DMat4,
    loc: &FileLoc,
) -> Result<crate::GridMedium, SceneError> {
    let (lo, hi, world_to_medium) = grid_placement(what, p, ctm, loc)?;
    // A plane per channel: an RGB parameter's triples become three planes.
    let samples = resolution.iter().map(|&n| n as usize).product::<usize>();
    let channels: usize = values.iter().map(|v| v.len() / samples).sum();
    let mut planes = Vec::with_capacity(samples * channels);
    for v in values {
        let per = v.len() / samples;
        for k in 0..per {
            planes.extend(v.iter().skip(k).step_by(per));
        }
    }
    Ok(crate::GridMedium {
        resolution,
        channels: channels as u32,
        values: planes,
        sigma_a,
        sigma_s,
        le,
        g,
        lo,
        hi,
        world_to_medium,
    })
}

/// A `uniformgrid`: `coefficients`' σa and σs times the `density` samples,
/// emitting `le` (pbrt's `Le`, 0 by default) times `Lescale`, a grid of
/// its own where given (pbrt reads it as one value per sample), else 1.
/// A `temperature` grid emits instead a blackbody at each sample's
/// (temperature − `temperatureoffset`) × `temperaturescale` kelvin (none at
/// 100 K or below), times `Lescale`, as pbrt's `GridMedium` does; here the
/// radiance is taken at the samples and interpolated between them, where
/// pbrt interpolates the temperature.
fn density_grid_medium(
    what: &str,
    p: &ParamList,
    coefficients: crate::HomogeneousMedium,
    le: Rgb,
    ctm: &DMat4,
    loc: &FileLoc,
) -> Result<crate::GridMedium, SceneError> {
    use crate::{FieldSource, GridField};
    p.mark_all_used();
    let resolution = grid_resolution(what, p, loc)?;
    let [nx, ny, nz] = resolution;
    let density =
        grid_values(what, p, "density", ParamType::Float, 1, resolution, loc)?.ok_or_else(|| {
            SceneError::at(loc, format!("{what}: \"density\" has 0 values for {nx}x{ny}x{nz} samples"))
        })?;
    let le_scale = grid_values(what, p, "Lescale", ParamType::Float, 1, resolution, loc)?;
    let density_field = |scale| GridField { scale, source: FieldSource::Scalar(0) };
    let (sigma_a, sigma_s) = (density_field(coefficients.sigma_a), density_field(coefficients.sigma_s));
    if let Some(temperature) = grid_values(what, p, "temperature", ParamType::Float, 1, resolution, loc)? {
        if p.has("Le") {
            return Err(SceneError::at(
                loc,
                format!("{what}: both \"Le\" and \"temperature\" values were given"),
            ));
        }
        let offset = match p.float("temperatureoffset")? {
            Some(offset) => offset,
            None => p.float_or("temperaturecutoff", 0.0)?,
        };
        let scale = p.float_or("temperaturescale", 1.0)?;
        let blackbody = super::spectrum::BlackbodyTable::shared();
        let emission: Vec<f32> = (temperature.iter().enumerate())
            .flat_map(|(i, t)| {
                let le_scale = le_scale.as_ref().map_or(1.0, |s| s[i]);
                (blackbody.rgb((t - offset) * scale) * le_scale).to_array()
            })
            .collect();
        let le_field = GridField { scale: Rgb::ONE, source: FieldSource::Rgb(1) };
        return grid_medium(
            what,
            p,
            resolution,
            &[density, emission],
            [sigma_a, sigma_s, le_field],
            coefficients.g,
            ctm,
            loc,
        );
    }
    let le_field = match (&le_scale, le == Rgb::ZERO) {
        (_, true) => GridField::constant(Rgb::ZERO),
        (Some(_), false) => GridField { scale: le, source: FieldSource::Scalar(1) },
        (None, false) => GridField::constant(le),
    };
    let values: Vec<Vec<f32>> = match le_scale {
        Some(s) if le != Rgb::ZERO => vec![density, s],
        _ => vec![density],
    };
    grid_medium(what, p, resolution, &values, [sigma_a, sigma_s, le_field], coefficients.g, ctm, loc)
}

/// An `rgbgrid`: σa and σs from the RGB samples `sigma_a` and `sigma_s`
/// (at least one given; a missing one is 1), both times `scale`, and the
/// emission from the RGB samples `Le` (which need `sigma_a`) times
/// `Lescale`.
fn rgb_grid_medium(
    what: &str,
    p: &ParamList,
    scale: f32,
    g: f32,
    ctm: &DMat4,
    loc: &FileLoc,
) -> Result<crate::GridMedium, SceneError> {
    use crate::{FieldSource, GridField};
    p.mark_all_used();
    let resolution = grid_resolution(what, p, loc)?;
    let rgb = |name| grid_values(what, p, name, ParamType::Rgb, 3, resolution, loc);
    let (sigma_a, sigma_s, le) = (rgb("sigma_a")?, rgb("sigma_s")?, rgb("Le")?);
    if sigma_a.is_none() && sigma_s.is_none() {
        return Err(SceneError::at(
            loc,
            format!("{what}: an rgbgrid needs \"sigma_a\" or \"sigma_s\" values"),
        ));
    }
    if le.is_some() && sigma_a.is_none() {
        return Err(SceneError::at(
            loc,
            format!("{what}: an rgbgrid with \"Le\" values needs \"sigma_a\" values"),
        ));
    }
    let le_scale = p.float_or("Lescale", 1.0)?.max(0.0);
    let mut values = Vec::new();
    let mut field = |samples: Option<Vec<f32>>, scale: Rgb, otherwise: Rgb| match samples {
        Some(v) => {
            values.push(v);
            GridField { scale, source: FieldSource::Rgb(3 * (values.len() as u32 - 1)) }
        }
        None => GridField::constant(otherwise),
    };
    let fields = [
        field(sigma_a, Rgb::splat(scale), Rgb::splat(scale)),
        field(sigma_s, Rgb::splat(scale), Rgb::splat(scale)),
        field(le, Rgb::splat(le_scale), Rgb::ZERO),
    ];
    grid_medium(what, p, resolution, &values, fields, g, ctm, loc)
}
