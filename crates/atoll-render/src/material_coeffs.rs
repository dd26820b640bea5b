//! Materials reduced to the compact f16 coefficients a hit carries in the
//! ray record, and the BSDF rebuilt from them on the shading device.

use std::sync::Arc;

use atoll_scene::{Coating, HairParams, Material, MeasuredBrdf, PrincipledParams, Rgb};
use glam::Vec3;
use half::f16;

use crate::bsdf::{Bsdf, Coated, CoatedBase, Frame, Hair, Principled};
use crate::material_layout::{
    coated_conductor, coated_diffuse, conductor, dielectric, diffuse, diffuse_transmission, hair, measured,
    principled, subsurface, tangent_slot, thin_dielectric,
};
use crate::record::{MaterialKind, RayRecord, MATERIAL_COEFFS};

/// A material as it travels in a [`RayRecord`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PackedMaterial {
    pub kind: MaterialKind,
    pub coeffs: [f16; MATERIAL_COEFFS],
    /// For [`MaterialKind::Mix`]: the two material ids and the probability
    /// of the second.
    pub mix: Option<([u32; 2], f32)>,
}

impl PackedMaterial {
    /// Packs a scene material (values rounded to f16).
    pub fn pack(material: &Material) -> Self {
        let mut c = [0f32; MATERIAL_COEFFS];
        let mut mix = None;
        let kind = match *material {
            Material::Diffuse { reflectance } => {
                put3(&mut c, diffuse::REFLECTANCE, reflectance);
                MaterialKind::Diffuse
            }
            Material::Conductor { eta, k, alpha_x, alpha_y } => {
                put3(&mut c, conductor::ETA, eta);
                put3(&mut c, conductor::K, k);
                c[conductor::ALPHA_X] = alpha_x;
                c[conductor::ALPHA_Y] = alpha_y;
                MaterialKind::Conductor
            }
            Material::Dielectric { eta, alpha_x, alpha_y } => {
                c[dielectric::ETA] = eta;
                c[dielectric::ALPHA_X] = alpha_x;
                c[dielectric::ALPHA_Y] = alpha_y;
                MaterialKind::Dielectric
            }
            Material::Interface => MaterialKind::None,
            Material::DiffuseTransmission { reflectance, transmittance } => {
                put3(&mut c, diffuse_transmission::REFLECTANCE, reflectance);
                put3(&mut c, diffuse_transmission::TRANSMITTANCE, transmittance);
                MaterialKind::DiffuseTransmission
            }
            Material::ThinDielectric { eta } => {
                c[thin_dielectric::ETA] = eta;
                MaterialKind::ThinDielectric
            }
            Material::Mix { materials, amount } => {
                mix = Some((materials, amount));
                MaterialKind::Mix
            }
            Material::CoatedDiffuse(p) => {
                use coated_diffuse as slot;
                let coating = p.coating;
                put3(&mut c, slot::REFLECTANCE, p.reflectance);
                put_coating(
                    &mut c,
                    &coating,
                    [slot::ALPHA_X, slot::ALPHA_Y, slot::ETA, slot::THICKNESS],
                    slot::ALBEDO,
                    slot::G,
                );
                c[slot::MAX_DEPTH] = coating.max_depth.min(Material::COATED_MAX_COUNT) as f32;
                c[slot::N_SAMPLES] = coating.n_samples.min(Material::COATED_MAX_COUNT) as f32;
                MaterialKind::CoatedDiffuse
            }
            Material::CoatedConductor(p) => {
                use coated_conductor as slot;
                put3(&mut c, slot::ETA, p.eta);
                put3(&mut c, slot::K, p.k);
                c[slot::CONDUCTOR_ALPHA_X] = p.alpha_x;
                c[slot::CONDUCTOR_ALPHA_Y] = p.alpha_y;
                let scalars =
                    [slot::INTERFACE_ALPHA_X, slot::INTERFACE_ALPHA_Y, slot::INTERFACE_ETA, slot::THICKNESS];
                put_coating(&mut c, &p.coating, scalars, slot::ALBEDO, slot::G);
                MaterialKind::CoatedConductor
            }
            Material::Principled(p) => {
                put3(&mut c, principled::BASE_COLOR, p.base_color);
                c[principled::METALLIC] = p.metallic;
                c[principled::ROUGHNESS] = p.roughness;
                c[principled::SPECULAR] = p.specular;
                c[principled::SPECULAR_TINT] = p.specular_tint;
                c[principled::SHEEN] = p.sheen;
                c[principled::SHEEN_TINT] = p.sheen_tint;
                c[principled::CLEARCOAT] = p.clearcoat;
                c[principled::CLEARCOAT_GLOSS] = p.clearcoat_gloss;
                c[principled::TRANSMISSION] = p.transmission;
                c[principled::ETA] = p.eta;
                MaterialKind::Principled
            }
            Material::Hair(p) => {
                put3(&mut c, hair::SIGMA_A, p.sigma_a);
                c[hair::ETA] = p.eta;
                c[hair::BETA_M] = p.beta_m;
                c[hair::BETA_N] = p.beta_n;
                c[hair::ALPHA] = p.alpha;
                c[hair::OFFSET] = crate::bsdf::hair::OFFSET_FROM_NORMAL;
                MaterialKind::Hair
            }
            Material::Measured { brdf } => {
                c[measured::BRDF] = brdf as f32;
                MaterialKind::Measured
            }
            Material::Subsurface(p) => {
                c[subsurface::ETA] = p.eta;
                c[subsurface::ALPHA_X] = p.alpha_x;
                c[subsurface::ALPHA_Y] = p.alpha_y;
                c[subsurface::EXIT_NORMALISATION] = crate::bsdf::fresnel::diffuse_transmittance(p.eta);
                MaterialKind::Subsurface
            }
        };
        PackedMaterial { kind, coeffs: c.map(f16::from_f32), mix }
    }

    /// Writes the material into a record's hit fields.
    pub fn store(&self, record: &mut RayRecord) {
        record.material = self.kind as u16;
        record.coeffs = self.coeffs;
    }
}

/// The BSDF of a record's hit, reading the frame's measured BRDFs `brdfs`;
/// `None` for pass-through surfaces and misses.
pub fn bsdf_from_record<'a>(r: &RayRecord, brdfs: &'a [Arc<MeasuredBrdf>]) -> Option<Bsdf<'a>> {
    match r.material_kind() {
        MaterialKind::None | MaterialKind::Mix => None,
        MaterialKind::Diffuse => Some(Bsdf::Diffuse { reflectance: r.coeff3(diffuse::REFLECTANCE) }),
        MaterialKind::Conductor => Some(Bsdf::Conductor {
            eta: r.coeff3(conductor::ETA),
            k: r.coeff3(conductor::K),
            alpha_x: r.coeff(conductor::ALPHA_X),
            alpha_y: r.coeff(conductor::ALPHA_Y),
        }),
        MaterialKind::Dielectric => Some(Bsdf::Dielectric {
            eta: r.coeff(dielectric::ETA),
            alpha_x: r.coeff(dielectric::ALPHA_X),
            alpha_y: r.coeff(dielectric::ALPHA_Y),
        }),
        MaterialKind::DiffuseTransmission => Some(Bsdf::DiffuseTransmission {
            reflectance: r.coeff3(diffuse_transmission::REFLECTANCE),
            transmittance: r.coeff3(diffuse_transmission::TRANSMITTANCE),
        }),
        MaterialKind::ThinDielectric => Some(Bsdf::ThinDielectric { eta: r.coeff(thin_dielectric::ETA) }),
        MaterialKind::CoatedDiffuse => {
            use coated_diffuse as slot;
            let scalars = [slot::ALPHA_X, slot::ALPHA_Y, slot::ETA, slot::THICKNESS];
            let walk = (r.coeff(slot::MAX_DEPTH) as u32, r.coeff(slot::N_SAMPLES) as u32);
            let coating = coating_from_record(r, scalars, slot::ALBEDO, slot::G, walk);
            Some(Bsdf::Coated(Coated {
                coating,
                base: CoatedBase::Diffuse { reflectance: r.coeff3(slot::REFLECTANCE) },
            }))
        }
        MaterialKind::CoatedConductor => {
            use coated_conductor as slot;
            let scalars =
                [slot::INTERFACE_ALPHA_X, slot::INTERFACE_ALPHA_Y, slot::INTERFACE_ETA, slot::THICKNESS];
            let coating =
                coating_from_record(r, scalars, slot::ALBEDO, slot::G, Material::COATED_CONDUCTOR_WALK);
            let base = CoatedBase::Conductor {
                eta: r.coeff3(slot::ETA),
                k: r.coeff3(slot::K),
                alpha_x: r.coeff(slot::CONDUCTOR_ALPHA_X),
                alpha_y: r.coeff(slot::CONDUCTOR_ALPHA_Y),
            };
            Some(Bsdf::Coated(Coated { coating, base }))
        }
        MaterialKind::Principled => Some(Bsdf::Principled(Principled(PrincipledParams {
            base_color: r.coeff3(principled::BASE_COLOR),
            metallic: r.coeff(principled::METALLIC),
            roughness: r.coeff(principled::ROUGHNESS),
            specular: r.coeff(principled::SPECULAR),
            specular_tint: r.coeff(principled::SPECULAR_TINT),
            sheen: r.coeff(principled::SHEEN),
            sheen_tint: r.coeff(principled::SHEEN_TINT),
            clearcoat: r.coeff(principled::CLEARCOAT),
            clearcoat_gloss: r.coeff(principled::CLEARCOAT_GLOSS),
            transmission: r.coeff(principled::TRANSMISSION),
            eta: r.coeff(principled::ETA),
        }))),
        MaterialKind::Hair => Some(Bsdf::Hair(
            Hair::new(&HairParams {
                sigma_a: r.coeff3(hair::SIGMA_A),
                eta: r.coeff(hair::ETA),
                beta_m: r.coeff(hair::BETA_M),
                beta_n: r.coeff(hair::BETA_N),
                alpha: r.coeff(hair::ALPHA),
            })
            .with_offset(r.coeff(hair::OFFSET)),
        )),
        MaterialKind::Measured => brdfs.get(r.coeff(measured::BRDF) as usize).map(|m| Bsdf::Measured(m)),
        // Where paths enter; where they leave, shading takes the exit lobe
        // instead (`stages::shade`).
        MaterialKind::Subsurface => Some(Bsdf::Dielectric {
            eta: r.coeff(subsurface::ETA),
            alpha_x: r.coeff(subsurface::ALPHA_X),
            alpha_y: r.coeff(subsurface::ALPHA_Y),
        }),
    }
}

/// The local shading frame of a record's hit: about the shading normal,
/// with x along the surface's `dpdu` where the hit carries it
/// ([`store_tangent`]; pbrt's `Frame::FromXZ(dpdu, ns)`), else the
/// normal's own basis ([`Frame::from_z`]).
pub fn shading_frame(r: &RayRecord) -> Frame {
    let n = r.shading_normal().normalize_or_zero();
    match tangent_slot(r.material_kind()) {
        Some(slot) => Frame::from_xz(r.coeff3(slot), n),
        None => Frame::from_z(n),
    }
}

/// Whether a hit on material `kind` with (textured) coefficients `coeffs`
/// needs the surface's `dpdu` for its frame: always for hair (its axis) and
/// measured BRDFs (their azimuth), and where the roughness is anisotropic
/// for the others that have room for it ([`tangent_slot`]). Isotropic
/// lobes do not turn about the normal, so their hits skip the partials.
pub fn wants_tangent(kind: MaterialKind, coeffs: &[f16; MATERIAL_COEFFS]) -> bool {
    let anisotropic = |x: usize, y: usize| coeffs[x] != coeffs[y];
    match kind {
        MaterialKind::Hair | MaterialKind::Measured => true,
        MaterialKind::Conductor => anisotropic(conductor::ALPHA_X, conductor::ALPHA_Y),
        MaterialKind::Dielectric => anisotropic(dielectric::ALPHA_X, dielectric::ALPHA_Y),
        MaterialKind::Subsurface => anisotropic(subsurface::ALPHA_X, subsurface::ALPHA_Y),
        MaterialKind::CoatedDiffuse => anisotropic(coated_diffuse::ALPHA_X, coated_diffuse::ALPHA_Y),
        _ => false,
    }
}

/// Writes the surface's `dpdu` (pbrt's shading `dpdu`: after bump mapping,
/// see [`crate::bump::Bent`]), normalised, into the hit's tangent slot
/// where [`wants_tangent`]; the slots stay zero otherwise, which
/// [`shading_frame`] reads as "no tangent".
pub fn store_tangent(kind: MaterialKind, coeffs: &mut [f16; MATERIAL_COEFFS], dpdu: Vec3) {
    if let Some(slot) = tangent_slot(kind).filter(|_| wants_tangent(kind, coeffs)) {
        let unit = dpdu.normalize_or_zero();
        for (c, v) in coeffs[slot..slot + 3].iter_mut().zip(unit.to_array()) {
            *c = f16::from_f32(v);
        }
    }
}

/// Writes a hair hit's offset across the fibre into its coefficients
/// (nothing for other kinds): `-1 + 2v` from the hit's `v` ([`hair_offset_at`]).
pub fn store_hair_offset(kind: MaterialKind, coeffs: &mut [f16; MATERIAL_COEFFS], offset: f32) {
    if kind == MaterialKind::Hair {
        coeffs[hair::OFFSET] = f16::from_f32(offset);
    }
}

/// The offset across a hair fibre at a hit of `v`: pbrt's `-1 + 2v`
/// ([`store_hair_offset`]).
pub fn hair_offset_at(v: f32) -> f32 {
    (-1.0 + 2.0 * v).clamp(-1.0, 1.0)
}

/// Writes a colour into the three coefficients from `slot`.
fn put3(c: &mut [f32; MATERIAL_COEFFS], slot: usize, v: Rgb) {
    c[slot..slot + 3].copy_from_slice(&v.to_array());
}

/// Writes a coating's alphas, index and thickness into the slots
/// `scalars` (in that order), its albedo and `g` into theirs; the walk's
/// counts are the kind's own business.
fn put_coating(
    c: &mut [f32; MATERIAL_COEFFS],
    coating: &Coating,
    scalars: [usize; 4],
    albedo: usize,
    g: usize,
) {
    let [alpha_x, alpha_y, eta, thickness] = scalars;
    c[alpha_x] = coating.alpha_x;
    c[alpha_y] = coating.alpha_y;
    c[eta] = coating.eta;
    c[thickness] = coating.thickness;
    put3(c, albedo, coating.albedo);
    c[g] = coating.g;
}

/// The coating [`put_coating`] wrote, with the walk `(max_depth, n_samples)`.
fn coating_from_record(
    r: &RayRecord,
    scalars: [usize; 4],
    albedo: usize,
    g: usize,
    walk: (u32, u32),
) -> Coating {
    let [alpha_x, alpha_y, eta, thickness] = scalars.map(|slot| r.coeff(slot));
    Coating {
        eta,
        alpha_x,
        alpha_y,
        thickness,
        albedo: r.coeff3(albedo),
        g: r.coeff(g),
        max_depth: walk.0,
        n_samples: walk.1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use atoll_scene::{CoatedConductorParams, CoatedDiffuseParams, Rgb};
    use bytemuck::Zeroable;

    /// Counts beyond `COATED_MAX_COUNT` are clamped (f16 holds integers
    /// exactly only up to 2048); every parameter lands in its named slot.
    #[test]
    fn coated_diffuse_packs_into_its_layout() {
        use coated_diffuse as slot;
        let m = Material::CoatedDiffuse(CoatedDiffuseParams {
            reflectance: Rgb::new(0.25, 0.5, 0.75),
            coating: Coating {
                eta: 1.25,
                alpha_x: 0.125,
                alpha_y: 0.375,
                thickness: 2.0,
                albedo: Rgb::new(0.5, 0.625, 0.875),
                g: -0.25,
                max_depth: 2048,
                n_samples: 4000,
            },
        });
        let p = PackedMaterial::pack(&m);
        assert_eq!(p.kind, MaterialKind::CoatedDiffuse);
        let c = p.coeffs.map(f16::to_f32);
        let rgb = |at: usize| [c[at], c[at + 1], c[at + 2]];
        assert_eq!(rgb(slot::REFLECTANCE), [0.25, 0.5, 0.75]);
        assert_eq!([c[slot::ALPHA_X], c[slot::ALPHA_Y], c[slot::ETA]], [0.125, 0.375, 1.25]);
        assert_eq!([c[slot::THICKNESS], c[slot::G]], [2.0, -0.25]);
        assert_eq!(rgb(slot::ALBEDO), [0.5, 0.625, 0.875]);
        assert_eq!([c[slot::MAX_DEPTH], c[slot::N_SAMPLES]], [2048.0; 2], "counts are clamped");
    }

    #[test]
    fn round_trip_through_record() {
        let coating = Coating {
            eta: 1.5,
            alpha_x: 0.25,
            alpha_y: 0.5,
            thickness: 0.125,
            albedo: Rgb::new(0.5, 0.25, 0.0),
            g: -0.5,
            max_depth: 0,
            n_samples: 0,
        };
        let materials = [
            Material::Diffuse { reflectance: Rgb::new(0.725, 0.71, 0.68) },
            Material::Conductor {
                eta: Rgb::new(0.2, 0.92, 1.1),
                k: Rgb::new(3.9, 2.45, 2.14),
                alpha_x: 0.1,
                alpha_y: 0.3,
            },
            Material::Dielectric { eta: 1.5, alpha_x: 0.0, alpha_y: 0.0 },
            Material::DiffuseTransmission {
                reflectance: Rgb::new(0.25, 0.5, 0.125),
                transmittance: Rgb::splat(0.75),
            },
            Material::ThinDielectric { eta: 1.25 },
            Material::CoatedDiffuse(CoatedDiffuseParams {
                reflectance: Rgb::new(0.25, 0.5, 0.125),
                coating: Coating { max_depth: 10, n_samples: 3, ..coating },
            }),
            Material::CoatedConductor(CoatedConductorParams {
                eta: Rgb::new(0.25, 0.5, 1.5),
                k: Rgb::new(3.5, 2.5, 2.0),
                alpha_x: 0.0625,
                alpha_y: 0.125,
                coating: Coating { max_depth: 10, n_samples: 1, ..coating },
            }),
            Material::Principled(PrincipledParams {
                base_color: Rgb::new(0.25, 0.5, 0.75),
                metallic: 0.125,
                roughness: 0.375,
                specular: 0.5,
                specular_tint: 0.25,
                sheen: 0.0625,
                sheen_tint: 0.5,
                clearcoat: 1.0,
                clearcoat_gloss: 0.875,
                transmission: 0.75,
                eta: 1.5,
            }),
            Material::Hair(HairParams {
                sigma_a: Rgb::new(0.25, 0.5, 1.25),
                eta: 1.5,
                beta_m: 0.25,
                beta_n: 0.375,
                alpha: 2.0,
            }),
            Material::Measured { brdf: 1 },
        ];
        let brdfs = [Arc::new(MeasuredBrdf::default()), Arc::new(MeasuredBrdf::default())];
        for m in &materials {
            let mut r = RayRecord::zeroed();
            PackedMaterial::pack(m).store(&mut r);
            let b = bsdf_from_record(&r, &brdfs).unwrap();
            let back = match b {
                Bsdf::Diffuse { reflectance } => Material::Diffuse { reflectance },
                Bsdf::Conductor { eta, k, alpha_x, alpha_y } => {
                    Material::Conductor { eta, k, alpha_x, alpha_y }
                }
                Bsdf::Dielectric { eta, alpha_x, alpha_y } => Material::Dielectric { eta, alpha_x, alpha_y },
                Bsdf::DiffuseTransmission { reflectance, transmittance } => {
                    Material::DiffuseTransmission { reflectance, transmittance }
                }
                Bsdf::ThinDielectric { eta } => Material::ThinDielectric { eta },
                Bsdf::Coated(Coated { coating, base: CoatedBase::Diffuse { reflectance } }) => {
                    Material::CoatedDiffuse(CoatedDiffuseParams { reflectance, coating })
                }
                Bsdf::Coated(Coated {
                    coating,
                    base: CoatedBase::Conductor { eta, k, alpha_x, alpha_y },
                }) => Material::CoatedConductor(CoatedConductorParams { eta, k, alpha_x, alpha_y, coating }),
                Bsdf::Principled(p) => Material::Principled(p.0),
                Bsdf::Hair(h) => Material::Hair(h.params),
                Bsdf::Measured(brdf) => Material::Measured {
                    brdf: brdfs.iter().position(|b| std::ptr::eq(&**b, brdf)).unwrap() as u32,
                },
            };
            // f16 keeps ~3 significant digits.
            let close = |a: f32, b: f32| (a - b).abs() <= 1e-3 * a.abs().max(1.0);
            match (m, &back) {
                (Material::Diffuse { reflectance: a }, Material::Diffuse { reflectance: b }) => {
                    assert!(a.to_array().iter().zip(b.to_array()).all(|(x, y)| close(*x, y)))
                }
                (
                    Material::Conductor { k: a, alpha_y: ay, .. },
                    Material::Conductor { k: b, alpha_y: by, .. },
                ) => {
                    assert!(a.to_array().iter().zip(b.to_array()).all(|(x, y)| close(*x, y)));
                    assert!(close(*ay, *by));
                }
                (Material::Dielectric { eta: a, .. }, Material::Dielectric { eta: b, .. }) => {
                    assert_eq!(a, b)
                }
                // Values exact in f16: the round trip is exact.
                (Material::DiffuseTransmission { .. }, Material::DiffuseTransmission { .. })
                | (Material::ThinDielectric { .. }, Material::ThinDielectric { .. })
                | (Material::CoatedDiffuse(_), Material::CoatedDiffuse(_))
                | (Material::CoatedConductor(_), Material::CoatedConductor(_))
                | (Material::Principled(_), Material::Principled(_))
                | (Material::Hair(_), Material::Hair(_))
                | (Material::Measured { .. }, Material::Measured { .. }) => assert_eq!(m, &back),
                _ => panic!("kind changed: {m:?} -> {back:?}"),
            }
        }
        let mut r = RayRecord::zeroed();
        PackedMaterial::pack(&Material::Interface).store(&mut r);
        assert!(bsdf_from_record(&r, &brdfs).is_none());
    }
}
