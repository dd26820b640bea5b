//! pbrt-v3 materials (and pbrt-v4 ones atoll lacks) mapped to the closest
//! material atoll has, with one warning each that names the mapping. The
//! Moana island and most older scenes are pbrt-v3 files.
//!
//! | material | becomes | from |
//! |---|---|---|
//! | `matte` | `Diffuse` | `Kd` (0.5); Oren–Nayar `sigma` ignored |
//! | `plastic`, `substrate` | `CoatedDiffuse` (as pbrt-v4's upgrade; a `plastic` with `Ks` 0 is `Diffuse`) | `Kd` (0.25, 0.5), `roughness` or `uroughness`/`vroughness` (0.1), `remaproughness`; `Ks` dropped (the coating's Fresnel sets the specular) |
//! | `uber`, `kdsubsurface` | `Diffuse` | `Kd` (v3 defaults); the specular layer, subsurface dropped |
//! | `translucent` | `DiffuseTransmission` | `Kd` × `reflect`, `Kd` × `transmit` (0.25, 0.5, 0.5); the glossy lobe dropped |
//! | `metal` | `Conductor` | `eta`, `k` (copper), `roughness` (0.01) or `uroughness`/`vroughness`, `remaproughness` |
//! | `glass` | `Dielectric` | `eta` or `index` (1.5), `uroughness`/`vroughness` (0); `Kr`/`Kt` tints ignored |
//! | `mirror` | smooth `Conductor` | reflectance `Kr` (0.9) |
//! | `disney` | `Principled`, without a warning unless something is dropped ([`disney`]) | all but `scatterdistance`, `thin` (with `flatness`, `difftrans`) and `anisotropic` |
//! | `fourier` | `Diffuse` 0.5 | the measured BSDF file is ignored |
//!
//! `hair` is read as pbrt-v4's (the same parameters, `color` for `reflectance`).
//!
//! `mix` names two named materials ([`mix_parts`]); the builder makes a `Material::Mix` of them.
//!
//! Textures given for the colours above (`Kd`, `Kr`, and the
//! roughnesses) are bound to the mapped material's `Reflectance` (and
//! `Transmittance`, roughness); `translucent`'s products become `Scale`
//! textures. Bump maps are ignored (the builder warns once).

use crate::error::{FileLoc, SceneError};
use crate::{Material, PrincipledParams, Rgb, TexInput, TexturedParam};

use super::entities::{alphas, reflectance_param};
use super::params::{FloatOrTexture, ParamList, ParamType, SpectrumParam};
use super::parser::ParamValues;
use super::textures::TexCtx;
use super::WarningSink;

/// The material for `ty` when it is one of the names above; `None` otherwise.
pub fn material(
    ty: &str,
    p: &ParamList,
    loc: &FileLoc,
    w: &mut WarningSink,
    tex: &mut TexCtx,
) -> Result<Option<Material>, SceneError> {
    let what = format!("material \"{ty}\"");
    // A colour parameter bound to the mapped material's reflectance when textured.
    let rgb = |name: &str, default: f32, w: &mut WarningSink, tex: &mut TexCtx| -> Result<Rgb, SceneError> {
        let reflectance = TexturedParam::Reflectance;
        reflectance_param(p, name, reflectance, Rgb::splat(default), &what, loc, w, tex)
    };
    let (material, how) = match ty {
        "matte" => {
            let kd = rgb("Kd", 0.5, w, tex)?;
            let sigma = match p.float_or_texture("sigma")? {
                Some(FloatOrTexture::Value(s)) if s != 0.0 => " (Oren-Nayar sigma ignored)",
                Some(FloatOrTexture::Texture(_)) => " (Oren-Nayar sigma ignored)",
                _ => "",
            };
            (Material::Diffuse { reflectance: kd }, format!("read as \"diffuse\" with its \"Kd\"{sigma}"))
        }
        "translucent" => {
            // pbrt-v3's TranslucentMaterial: Kd (0.25) split by reflect and transmit (0.5 each).
            let mut input = |name: &str, default: f32| -> Result<TexInput, SceneError> {
                Ok(tex.spectrum(p, name, &what, loc, w)?.unwrap_or(TexInput::Value(Rgb::splat(default))))
            };
            let (kd, reflect, transmit) =
                (input("Kd", 0.25)?, input("reflect", 0.5)?, input("transmit", 0.5)?);
            let (r, t) = (tex.product(kd, reflect), tex.product(kd, transmit));
            let reflectance = tex.value_or_bind(r, TexturedParam::Reflectance, Rgb::splat(0.125));
            let transmittance = tex.value_or_bind(t, TexturedParam::Transmittance, Rgb::splat(0.125));
            (
                Material::DiffuseTransmission { reflectance, transmittance },
                "read as \"diffusetransmission\" (Kd × reflect, Kd × transmit; the glossy Ks lobe dropped)"
                    .into(),
            )
        }
        "plastic" | "substrate" if !(ty == "plastic" && specular_is_black(p)?) => {
            // pbrt-v3's Kd default differs; both default to roughness 0.1.
            let kd = if ty == "plastic" { 0.25 } else { 0.5 };
            let m = super::entities::coated_diffuse(p, &what, "Kd", (kd, 0.1), loc, w, tex)?;
            (m, "read as \"coateddiffuse\" with \"Kd\" as its reflectance (\"Ks\" dropped)".to_string())
        }
        "plastic" | "substrate" | "uber" | "kdsubsurface" => {
            // pbrt-v3's defaults for Kd.
            let default = if matches!(ty, "plastic" | "uber") { 0.25 } else { 0.5 };
            let kd = rgb("Kd", default, w, tex)?;
            let dropped = match ty {
                "kdsubsurface" => "subsurface scattering dropped",
                _ => "specular layer dropped",
            };
            (
                Material::Diffuse { reflectance: kd },
                format!("approximated by \"diffuse\" with its \"Kd\" ({dropped})"),
            )
        }
        "metal" => {
            // The copper defaults, eta/k spellings and roughness rules are pbrt-v4's
            // conductor's, except v3's default roughness of 0.01.
            let conductor = super::entities::conductor(p, &what, 0.01, "", loc, w, tex)?;
            (conductor, "read as \"conductor\"".to_string())
        }
        "glass" => {
            let eta = match p.float("index")? {
                Some(i) => i,
                None => super::entities::dielectric_eta(p, &what, loc, w)?,
            };
            let (alpha_x, alpha_y) = alphas(p, &what, 0.0, "", loc, w, tex)?;
            let tinted = [p.spectrum("Kr", true)?, p.spectrum("Kt", true)?].iter().flatten().count() > 0;
            let note = if tinted { " (\"Kr\"/\"Kt\" tints ignored)" } else { "" };
            (Material::Dielectric { eta, alpha_x, alpha_y }, format!("read as \"dielectric\"{note}"))
        }
        "mirror" => {
            let kr = rgb("Kr", 0.9, w, tex)?;
            let k = Material::conductor_k_from_reflectance(kr);
            let m = Material::Conductor { eta: Rgb::ONE, k, alpha_x: 0.0, alpha_y: 0.0 };
            (m, "read as a smooth \"conductor\" with reflectance \"Kr\"".to_string())
        }
        "disney" => return disney(p, &what, loc, w, tex).map(Some),
        "fourier" => {
            (Material::default_diffuse(), "approximated by diffuse 0.5 (measured BSDF ignored)".into())
        }
        _ => return Ok(None),
    };
    // One warning covers every parameter the mapping does not use.
    p.mark_all_used();
    w.warn(loc, format!("pbrt-v3 material \"{ty}\" is not supported; {how}"));
    Ok(Some(material))
}

/// pbrt-v3's `Ks` given as a constant zero: a plastic without its specular
/// layer, which pbrt-v4's upgrade turns into `diffuse`.
fn specular_is_black(p: &ParamList) -> Result<bool, SceneError> {
    Ok(match p.spectrum("Ks", true)? {
        Some(SpectrumParam::Constant(c)) => c == 0.0,
        Some(SpectrumParam::Rgb(c)) => c == Rgb::ZERO,
        _ => false,
    })
}

/// pbrt-v3's `disney` as atoll's principled material, with the parameters
/// and defaults of pbrt-v3's `CreateDisneyMaterial`: `color` (0.5),
/// `metallic` (0), `eta` (1.5), `roughness` (0.5), `speculartint` (0),
/// `sheen` (0), `sheentint` (0.5), `clearcoat` (0), `clearcoatgloss` (1),
/// `spectrans` (0), plus atoll's `specular`, which pbrt-v3 derives from
/// `eta` ([`Material::specular_from_eta`], the default) and atoll's writer
/// gives. `color`, `metallic` and `roughness` may be textures (bound).
/// One warning names what atoll does not model: subsurface scattering
/// (`scatterdistance`), the thin-surface mode (`thin`, with `flatness` and
/// `difftrans`), anisotropy, textures of the other parameters and weights
/// outside [0, 1] (clamped); without any, the material loads silently.
pub fn disney(
    p: &ParamList,
    what: &str,
    loc: &FileLoc,
    w: &mut WarningSink,
    tex: &mut TexCtx,
) -> Result<Material, SceneError> {
    let mut dropped: Vec<String> = Vec::new();
    let base_color =
        reflectance_param(p, "color", TexturedParam::Reflectance, Rgb::splat(0.5), what, loc, w, tex)?;
    // A float parameter: its value, or for a texture the default and a
    // binding of `bind` (or a note that the texture is ignored).
    let mut float = |name: &str, default: f32, bind: Option<TexturedParam>, w: &mut WarningSink| {
        let v = match tex.float(p, name, what, loc, w)? {
            None => default,
            Some(TexInput::Value(v)) => v.x,
            Some(TexInput::Texture(t)) => {
                match bind {
                    // Principled roughness is perceptual: no remapping.
                    Some(param) => tex.bindings.push((param, t, false)),
                    None => dropped.push(format!("the \"{name}\" texture (using {default})")),
                }
                default
            }
        };
        Ok::<f32, SceneError>(v)
    };
    let metallic = float("metallic", 0.0, Some(TexturedParam::Metallic), w)?;
    let roughness = float("roughness", 0.5, Some(TexturedParam::Roughness), w)?;
    let eta = float("eta", 1.5, None, w)?;
    let specular_tint = float("speculartint", 0.0, Some(TexturedParam::SpecularTint), w)?;
    let sheen = float("sheen", 0.0, Some(TexturedParam::Sheen), w)?;
    let sheen_tint = float("sheentint", 0.5, Some(TexturedParam::SheenTint), w)?;
    let clearcoat = float("clearcoat", 0.0, Some(TexturedParam::Clearcoat), w)?;
    let clearcoat_gloss = float("clearcoatgloss", 1.0, Some(TexturedParam::ClearcoatGloss), w)?;
    let transmission = float("spectrans", 0.0, Some(TexturedParam::Transmission), w)?;
    let anisotropic = float("anisotropic", 0.0, None, w)?;
    if !(eta.is_finite() && eta > 0.0) {
        return Err(SceneError::at(loc, format!("{what}: \"eta\" must be positive, not {eta}")));
    }
    let specular = p.float("specular")?.unwrap_or_else(|| Material::specular_from_eta(eta));
    if !(specular.is_finite() && specular >= 0.0) {
        return Err(SceneError::at(loc, format!("{what}: \"specular\" must be 0 or more, not {specular}")));
    }
    if anisotropic != 0.0 {
        dropped.push("anisotropy".into());
    }
    let subsurface = match p.spectrum("scatterdistance", true)? {
        None => false,
        Some(SpectrumParam::Rgb(c)) => c != Rgb::ZERO,
        Some(SpectrumParam::Constant(c)) => c != 0.0,
        Some(_) => true,
    };
    if subsurface {
        dropped.push("subsurface scattering (\"scatterdistance\")".into());
    }
    if p.bool_or("thin", false)? {
        dropped.push("the thin-surface mode (read as a solid)".into());
    }
    // Only the thin-surface mode reads these.
    p.find("flatness", &[ParamType::Float, ParamType::Texture]);
    p.find("difftrans", &[ParamType::Float, ParamType::Texture]);
    let mut unit = |name: &str, v: f32| {
        if !(0.0..=1.0).contains(&v) {
            dropped.push(format!("\"{name}\" {v} outside [0, 1] (clamped)"));
        }
        v.clamp(0.0, 1.0)
    };
    let m = Material::Principled(PrincipledParams {
        base_color,
        metallic: unit("metallic", metallic),
        roughness: unit("roughness", roughness),
        specular,
        specular_tint: unit("speculartint", specular_tint),
        sheen: unit("sheen", sheen),
        sheen_tint: unit("sheentint", sheen_tint),
        clearcoat: unit("clearcoat", clearcoat),
        clearcoat_gloss: unit("clearcoatgloss", clearcoat_gloss),
        transmission: unit("spectrans", transmission),
        eta,
    });
    if !dropped.is_empty() {
        w.warn(
            loc,
            format!(
                "pbrt-v3 material \"disney\" is read as atoll's principled material without {}",
                dropped.join(", ")
            ),
        );
    }
    Ok(m)
}

/// The first material of a `mix`: pbrt-v4's `string materials` or pbrt-v3's
/// `string namedmaterial1` (the rest of the mix is not used).
pub fn mix_parts(
    p: &ParamList,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> Result<(String, String, f32), SceneError> {
    let v4 = p.find("materials", &[ParamType::String]).and_then(|m| match &m.values {
        ParamValues::Strings(s) if s.len() == 2 => Some((s[0].clone(), s[1].clone())),
        _ => None,
    });
    let (first, second) = match v4 {
        Some(names) => names,
        None => match (p.string("namedmaterial1")?, p.string("namedmaterial2")?) {
            (Some(a), Some(b)) => (a, b),
            _ => {
                return Err(SceneError::at(
                    loc,
                    "material \"mix\": \"string materials\" with two names (or \"namedmaterial1\" and \"namedmaterial2\") must be given",
                ))
            }
        },
    };
    // pbrt-v4's amount is a float; pbrt-v3's a spectrum (its mean is taken).
    // A float texture is the builder's to bind (`amount` then stays 0.5).
    let amount = match p.spectrum("amount", true)? {
        None | Some(SpectrumParam::Texture(_)) => 0.5,
        Some(SpectrumParam::Constant(a)) => a,
        Some(SpectrumParam::Rgb(c)) => {
            if c.max_element() - c.min_element() > 1e-6 {
                w.warn(loc, "material \"mix\": a coloured \"amount\" is replaced by its mean");
            }
            (c.x + c.y + c.z) / 3.0
        }
        Some(_) => {
            w.warn(loc, "material \"mix\": this \"amount\" (a spectrum) is replaced by 0.5");
            0.5
        }
    };
    p.mark_all_used();
    Ok((first, second, amount.clamp(0.0, 1.0)))
}
