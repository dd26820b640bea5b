//! Materials reduced to the compact f16 coefficients a hit carries in the
//! ray record, and the BSDF rebuilt from them on the shading device.

use atoll_scene::Material;
use half::f16;

use crate::bsdf::Bsdf;
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
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use atoll_scene::Rgb;
    use bytemuck::Zeroable;

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
                | (Material::ThinDielectric { .. }, Material::ThinDielectric { .. }) => assert_eq!(m, &back),
                _ => panic!("kind changed: {m:?} -> {back:?}"),
            }
        }
        let mut r = RayRecord::zeroed();
        PackedMaterial::pack(&Material::Interface).store(&mut r);
        assert!(bsdf_from_record(&r).is_none());
    }
}
