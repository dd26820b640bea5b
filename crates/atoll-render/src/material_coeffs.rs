//! Materials reduced to the compact f16 coefficients a hit carries in the
//! ray record, and the BSDF rebuilt from them on the shading device.

use atoll_scene::{CoatedDiffuseParams, Material, PrincipledParams};
use half::f16;

use crate::bsdf::{Bsdf, CoatedDiffuse, Principled};
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
                c[..3].copy_from_slice(&reflectance.to_array());
                MaterialKind::Diffuse
            }
            Material::Conductor { eta, k, alpha_x, alpha_y } => {
                c[..3].copy_from_slice(&eta.to_array());
                c[3..6].copy_from_slice(&k.to_array());
                c[6] = alpha_x;
                c[7] = alpha_y;
                MaterialKind::Conductor
            }
            Material::Dielectric { eta, alpha_x, alpha_y } => {
                c[0] = eta;
                c[1] = alpha_x;
                c[2] = alpha_y;
                MaterialKind::Dielectric
            }
            Material::Interface => MaterialKind::None,
            Material::DiffuseTransmission { reflectance, transmittance } => {
                c[..3].copy_from_slice(&reflectance.to_array());
                c[3..6].copy_from_slice(&transmittance.to_array());
                MaterialKind::DiffuseTransmission
            }
            Material::ThinDielectric { eta } => {
                c[0] = eta;
                MaterialKind::ThinDielectric
            }
            Material::Mix { materials, amount } => {
                mix = Some((materials, amount));
                MaterialKind::Mix
            }
            Material::CoatedDiffuse(p) => {
                // Reflectance and roughness first, where per-hit textures
                // overwrite them (`MaterialKind::CoatedDiffuse` has the layout).
                c[..3].copy_from_slice(&p.reflectance.to_array());
                c[3] = p.alpha_x;
                c[4] = p.alpha_y;
                c[5] = p.eta;
                c[6] = p.thickness;
                c[7..10].copy_from_slice(&p.albedo.to_array());
                c[10] = p.g;
                c[11] = p.max_depth.min(Material::COATED_MAX_COUNT) as f32;
                c[12] = p.n_samples.min(Material::COATED_MAX_COUNT) as f32;
                MaterialKind::CoatedDiffuse
            }
            Material::Principled(p) => {
                // Base colour, metallic and roughness first: per-hit textures
                // overwrite them (`MaterialKind::Principled` has the layout).
                c[..3].copy_from_slice(&p.base_color.to_array());
                c[3..13].copy_from_slice(&[
                    p.metallic,
                    p.roughness,
                    p.specular,
                    p.specular_tint,
                    p.sheen,
                    p.sheen_tint,
                    p.clearcoat,
                    p.clearcoat_gloss,
                    p.transmission,
                    p.eta,
                ]);
                MaterialKind::Principled
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

/// The BSDF of a record's hit; `None` for pass-through surfaces and misses.
pub fn bsdf_from_record(r: &RayRecord) -> Option<Bsdf> {
    match r.material_kind() {
        MaterialKind::None | MaterialKind::Mix => None,
        MaterialKind::Diffuse => Some(Bsdf::Diffuse { reflectance: r.coeff3(0) }),
        MaterialKind::Conductor => Some(Bsdf::Conductor {
            eta: r.coeff3(0),
            k: r.coeff3(3),
            alpha_x: r.coeff(6),
            alpha_y: r.coeff(7),
        }),
        MaterialKind::Dielectric => {
            Some(Bsdf::Dielectric { eta: r.coeff(0), alpha_x: r.coeff(1), alpha_y: r.coeff(2) })
        }
        MaterialKind::DiffuseTransmission => {
            Some(Bsdf::DiffuseTransmission { reflectance: r.coeff3(0), transmittance: r.coeff3(3) })
        }
        MaterialKind::ThinDielectric => Some(Bsdf::ThinDielectric { eta: r.coeff(0) }),
        MaterialKind::CoatedDiffuse => Some(Bsdf::CoatedDiffuse(CoatedDiffuse(CoatedDiffuseParams {
            reflectance: r.coeff3(0),
            alpha_x: r.coeff(3),
            alpha_y: r.coeff(4),
            eta: r.coeff(5),
            thickness: r.coeff(6),
            albedo: r.coeff3(7),
            g: r.coeff(10),
            max_depth: r.coeff(11) as u32,
            n_samples: r.coeff(12) as u32,
        }))),
        MaterialKind::Principled => Some(Bsdf::Principled(Principled(PrincipledParams {
            base_color: r.coeff3(0),
            metallic: r.coeff(3),
            roughness: r.coeff(4),
            specular: r.coeff(5),
            specular_tint: r.coeff(6),
            sheen: r.coeff(7),
            sheen_tint: r.coeff(8),
            clearcoat: r.coeff(9),
            clearcoat_gloss: r.coeff(10),
            transmission: r.coeff(11),
            eta: r.coeff(12),
        }))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use atoll_scene::Rgb;
    use bytemuck::Zeroable;

    /// Per-hit textures overwrite reflectance and roughness in place, so a
    /// coated diffuse keeps them where `MaterialKind::CoatedDiffuse` says.
    #[test]
    fn coated_diffuse_layout() {
        let m = Material::CoatedDiffuse(CoatedDiffuseParams {
            reflectance: Rgb::new(0.25, 0.5, 0.75),
            eta: 1.25,
            alpha_x: 0.125,
            alpha_y: 0.375,
            thickness: 2.0,
            albedo: Rgb::new(0.5, 0.625, 0.875),
            g: -0.25,
            max_depth: 2048,
            n_samples: 4000,
        });
        let p = PackedMaterial::pack(&m);
        let c: Vec<f32> = p.coeffs.iter().map(|h| h.to_f32()).collect();
        let expected =
            [0.25, 0.5, 0.75, 0.125, 0.375, 1.25, 2.0, 0.5, 0.625, 0.875, -0.25, 2048.0, 2048.0, 0.0];
        assert_eq!(&c[..14], &expected, "counts beyond COATED_MAX_COUNT are clamped");
        assert!(c[14..].iter().all(|&x| x == 0.0));
        assert_eq!(p.kind, MaterialKind::CoatedDiffuse);
    }

    #[test]
    fn round_trip_through_record() {
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
                eta: 1.5,
                alpha_x: 0.25,
                alpha_y: 0.5,
                thickness: 0.125,
                albedo: Rgb::new(0.5, 0.25, 0.0),
                g: -0.5,
                max_depth: 10,
                n_samples: 3,
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
        ];
        for m in &materials {
            let mut r = RayRecord::zeroed();
            PackedMaterial::pack(m).store(&mut r);
            let b = bsdf_from_record(&r).unwrap();
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
                Bsdf::CoatedDiffuse(c) => Material::CoatedDiffuse(c.0),
                Bsdf::Principled(p) => Material::Principled(p.0),
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
                | (Material::Principled(_), Material::Principled(_)) => assert_eq!(m, &back),
                _ => panic!("kind changed: {m:?} -> {back:?}"),
            }
        }
        let mut r = RayRecord::zeroed();
        PackedMaterial::pack(&Material::Interface).store(&mut r);
        assert!(bsdf_from_record(&r).is_none());
    }
}
