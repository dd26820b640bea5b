//! pbrt-v3 materials (and pbrt-v4 ones atoll lacks) mapped to the closest
//! material atoll has, with one warning each that names the mapping. The
//! Moana island and most older scenes are pbrt-v3 files.
//!
//! | material | becomes | from |
//! |---|---|---|
//! | `matte` | `Diffuse` | `Kd` (0.5); Oren–Nayar `sigma` ignored |
//! | `plastic`, `substrate`, `uber`, `kdsubsurface` | `Diffuse` | `Kd` (v3 defaults); the specular layer, subsurface dropped |
//! | `translucent` | `DiffuseTransmission` | `Kd` × `reflect`, `Kd` × `transmit` (0.25, 0.5, 0.5); the glossy lobe dropped |
//! | `metal` | `Conductor` | `eta`, `k` (copper), `roughness` (0.01) or `uroughness`/`vroughness`, `remaproughness` |
//! | `glass` | `Dielectric` | `eta` or `index` (1.5), `uroughness`/`vroughness` (0); `Kr`/`Kt` tints ignored |
//! | `mirror` | smooth `Conductor` | reflectance `Kr` (0.9) |
//! | `disney` | like glTF: `Dielectric` if `spectrans` ≥ 0.5, `Conductor` if `metallic` ≥ 0.5, else `Diffuse` | `color` (0.5), `roughness` (0.5) |
//! | `hair` | `Diffuse` | `color` (0.5) |
//! | `fourier` | `Diffuse` 0.5 | the measured BSDF file is ignored |
//!
//! `mix` names two named materials ([`mix_parts`]); the builder makes a `Material::Mix` of them.
//! `Texture` statements are recorded ([`texture`]), not rendered yet.

use std::path::Path;

use crate::error::{FileLoc, SceneError};
use crate::{Material, Rgb, TextureRef};

use super::entities::{alphas, reflectance_rgb};
use super::params::{FloatOrTexture, ParamList, ParamType, SpectrumParam};
use super::parser::ParamValues;
use super::WarningSink;

/// The material for `ty` when it is one of the names above; `None` otherwise.
pub fn material(
    ty: &str,
    p: &ParamList,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> Result<Option<Material>, SceneError> {
    let what = format!("material \"{ty}\"");
    let rgb = |name: &str, default: f32, w: &mut WarningSink| -> Result<Rgb, SceneError> {
        let v = p.spectrum(name, true)?.and_then(|s| reflectance_rgb(s, &what, loc, w));
        Ok(v.unwrap_or(Rgb::splat(default)))
    };
    let (material, how) = match ty {
        "matte" => {
            let kd = rgb("Kd", 0.5, w)?;
            let sigma = match p.float_or_texture("sigma")? {
                Some(FloatOrTexture::Value(s)) if s != 0.0 => " (Oren-Nayar sigma ignored)",
                Some(FloatOrTexture::Texture(_)) => " (Oren-Nayar sigma ignored)",
                _ => "",
            };
            (Material::Diffuse { reflectance: kd }, format!("read as \"diffuse\" with its \"Kd\"{sigma}"))
        }
        "translucent" => {
            // pbrt-v3's TranslucentMaterial: Kd (0.25) split by reflect and transmit (0.5 each).
            let kd = rgb("Kd", 0.25, w)?;
            let (reflect, transmit) = (rgb("reflect", 0.5, w)?, rgb("transmit", 0.5, w)?);
            (
                Material::DiffuseTransmission { reflectance: kd * reflect, transmittance: kd * transmit },
                "read as \"diffusetransmission\" (Kd × reflect, Kd × transmit; the glossy Ks lobe dropped)"
                    .into(),
            )
        }
        "plastic" | "substrate" | "uber" | "kdsubsurface" => {
            // pbrt-v3's defaults for Kd.
            let default = if matches!(ty, "plastic" | "uber") { 0.25 } else { 0.5 };
            let kd = rgb("Kd", default, w)?;
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
            let conductor = super::entities::conductor(p, &what, 0.01, loc, w)?;
            (conductor, "read as \"conductor\"".to_string())
        }
        "glass" => {
            let eta = match p.float("index")? {
                Some(i) => i,
                None => super::entities::dielectric_eta(p, &what, loc, w)?,
            };
            let (alpha_x, alpha_y) = alphas(p, &what, 0.0, loc, w)?;
            let tinted = [p.spectrum("Kr", true)?, p.spectrum("Kt", true)?].iter().flatten().count() > 0;
            let note = if tinted { " (\"Kr\"/\"Kt\" tints ignored)" } else { "" };
            (Material::Dielectric { eta, alpha_x, alpha_y }, format!("read as \"dielectric\"{note}"))
        }
        "mirror" => {
            let kr = rgb("Kr", 0.9, w)?;
            let k = Material::conductor_k_from_reflectance(kr);
            let m = Material::Conductor { eta: Rgb::ONE, k, alpha_x: 0.0, alpha_y: 0.0 };
            (m, "read as a smooth \"conductor\" with reflectance \"Kr\"".to_string())
        }
        "disney" => {
            let color = rgb("color", 0.5, w)?;
            let roughness = p.float_or("roughness", 0.5)?.clamp(0.0, 1.0);
            let alpha = roughness * roughness;
            let m = if p.float_or("spectrans", 0.0)? >= 0.5 {
                Material::Dielectric { eta: p.float_or("eta", 1.5)?, alpha_x: alpha, alpha_y: alpha }
            } else if p.float_or("metallic", 0.0)? >= 0.5 {
                let k = Material::conductor_k_from_reflectance(color);
                Material::Conductor { eta: Rgb::ONE, k, alpha_x: alpha, alpha_y: alpha }
            } else {
                Material::Diffuse { reflectance: color }
            };
            (m, "approximated by a diffuse, conductor or dielectric material (principled material not available yet)".into())
        }
        "hair" => {
            let color = rgb("color", 0.5, w)?;
            (
                Material::Diffuse { reflectance: color },
                "approximated by \"diffuse\" with its \"color\"".into(),
            )
        }
        "fourier" => {
            (Material::default_diffuse(), "approximated by diffuse 0.5 (measured BSDF ignored)".into())
        }
        _ => return Ok(None),
    };
    // One warning covers every parameter the mapping does not use.
    p.mark_all_used();
    let version = if matches!(ty, "hair") { "" } else { "pbrt-v3 " };
    w.warn(loc, format!("{version}material \"{ty}\" is not supported; {how}"));
    Ok(Some(material))
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
    let amount = match p.spectrum("amount", true)? {
        None => 0.5,
        Some(SpectrumParam::Constant(a)) => a,
        Some(SpectrumParam::Rgb(c)) => {
            if c.max_element() - c.min_element() > 1e-6 {
                w.warn(loc, "material \"mix\": a coloured \"amount\" is replaced by its mean");
            }
            (c.x + c.y + c.z) / 3.0
        }
        Some(_) => {
            w.warn(loc, "material \"mix\": this \"amount\" (a texture or spectrum) is replaced by 0.5");
            0.5
        }
    };
    p.mark_all_used();
    Ok((first, second, amount.clamp(0.0, 1.0)))
}

/// The record of `Texture "name" "ty" "class" params` (pbrt-v3 also wrote
/// `color` for `spectrum`); its image file resolves against `base_dir`.
pub fn texture(
    name: String,
    ty: &str,
    class: String,
    p: &ParamList,
    base_dir: &Path,
    loc: &FileLoc,
) -> Result<TextureRef, SceneError> {
    if !matches!(ty, "float" | "spectrum" | "color" | "rgb") {
        return Err(SceneError::at(
            loc,
            format!("Texture \"{name}\": type must be \"float\" or \"spectrum\", found \"{ty}\""),
        ));
    }
    let filename = p.string("filename")?.map(|f| base_dir.join(f));
    // Texture parameters are the texture step's business.
    p.mark_all_used();
    Ok(TextureRef { name, class, filename, uses: Vec::new() })
}
