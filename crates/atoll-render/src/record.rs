//! The one ray record every device and every strategy moves around.
//!
//! A record is a path segment (or a shadow ray) plus, after tracing, the full
//! description of its closest hit: position, normals and the material already
//! reduced to compact f16 coefficients. That is what lets a hit found on one
//! device be shaded on another (ray queue cycling, Wald et al. 2023): the
//! shading device never needs the mesh that was hit.
//!
//! The layout is fixed (`#[repr(C)]`, 128 bytes, checked below) because the
//! CUDA kernels mirror it in a header generated from these offsets.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use half::f16;

/// Number of f16 material coefficients carried by a hit.
pub const MATERIAL_COEFFS: usize = 16;
/// `RayRecord::light` value meaning "the hit surface does not emit".
pub const NO_LIGHT: u32 = u32::MAX;

/// Bit flags in [`RayRecord::flags`].
pub mod flags {
    /// The record is a shadow/AO ray: trace asks "occluded?", not "closest hit".
    pub const SHADOW: u16 = 1 << 0;
    /// Set by any-hit tracing of a shadow ray that is blocked.
    pub const OCCLUDED: u16 = 1 << 1;
    /// Set by closest-hit tracing when the ray hit something (fields below are valid).
    pub const HIT: u16 = 1 << 2;
    /// The direction was sampled from a delta lobe (or is a camera ray): an
    /// emitter found along it is counted without MIS.
    pub const SPECULAR: u16 = 1 << 3;
}

/// Which material model the coefficients describe ([`RayRecord::material`]).
#[repr(u16)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaterialKind {
    /// No scattering surface (pass-through, or a miss).
    None = 0,
    /// coeffs[0..3] reflectance.
    Diffuse = 1,
    /// coeffs[0..3] eta, [3..6] k, [6] alpha_x, [7] alpha_y.
    Conductor = 2,
    /// coeffs[0] eta, [1] alpha_x, [2] alpha_y.
    Dielectric = 3,
    /// coeffs[0..3] reflectance, [3..6] transmittance.
    DiffuseTransmission = 4,
    /// coeffs[0] eta.
    ThinDielectric = 5,
    /// Material tables only, never in a record: a `mix` resolved to one of
    /// its materials when the hit is written ([`crate::FrameContext::material_at`]).
    Mix = 6,
}

impl MaterialKind {
    pub fn from_u16(v: u16) -> MaterialKind {
        match v {
            1 => MaterialKind::Diffuse,
            2 => MaterialKind::Conductor,
            3 => MaterialKind::Dielectric,
            4 => MaterialKind::DiffuseTransmission,
            5 => MaterialKind::ThinDielectric,
            6 => MaterialKind::Mix,
            _ => MaterialKind::None,
        }
    }
}

/// A path vertex / shadow ray and its hit. 128 bytes, two per cache line pair.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct RayRecord {
    // --- the ray (traced) ---
    pub origin: [f32; 3],
    /// Ray extent; closest-hit tracing shrinks it to the hit distance, so
    /// tracing the same record against several scene parts keeps the nearest.
    pub t_max: f32,
    /// Not normalised necessarily; shading normalises.
    pub direction: [f32; 3],
    /// Linear pixel index `y * width + x`.
    pub pixel: u32,
    // --- path state (read by shading) ---
    /// Path throughput; for shadow rays the radiance to add if unoccluded.
    pub throughput: [f32; 3],
    /// Sample index of this path within its pixel.
    pub sample: u32,
    /// Solid-angle pdf with which `direction` was sampled (for MIS at emitters).
    pub bsdf_pdf: f32,
    /// Number of scattering events before this segment (camera ray: 0).
    pub depth: u16,
    /// [`flags`].
    pub flags: u16,
    // --- the hit (written by closest-hit tracing) ---
    /// Global light index when the hit surface emits, else [`NO_LIGHT`].
    pub light: u32,
    /// Instance that was hit (for ownership/debug views).
    pub instance: u32,
    pub position: [f32; 3],
    /// Reserved; keeps the f16 block aligned.
    pub reserved: u32,
    /// Geometric normal, oriented by pbrt's rule (not towards the ray).
    pub geometric_normal: [f16; 3],
    /// [`MaterialKind`] as u16.
    pub material: u16,
    pub shading_normal: [f16; 3],
    /// Reserved.
    pub reserved2: u16,
    pub coeffs: [f16; MATERIAL_COEFFS],
}

// The CUDA header mirrors these numbers; change both together.
const _: () = {
    assert!(std::mem::size_of::<RayRecord>() == 128);
    assert!(std::mem::offset_of!(RayRecord, t_max) == 12);
    assert!(std::mem::offset_of!(RayRecord, pixel) == 28);
    assert!(std::mem::offset_of!(RayRecord, throughput) == 32);
    assert!(std::mem::offset_of!(RayRecord, bsdf_pdf) == 48);
    assert!(std::mem::offset_of!(RayRecord, flags) == 54);
    assert!(std::mem::offset_of!(RayRecord, light) == 56);
    assert!(std::mem::offset_of!(RayRecord, position) == 64);
    assert!(std::mem::offset_of!(RayRecord, geometric_normal) == 80);
    assert!(std::mem::offset_of!(RayRecord, shading_normal) == 88);
    assert!(std::mem::offset_of!(RayRecord, coeffs) == 96);
};

/// `(name, offset, size)` of every field, for generating the CUDA header's
/// `static_assert`s and for tests.
pub fn field_layout() -> Vec<(&'static str, usize, usize)> {
    macro_rules! f {
        ($name:ident) => {{
            let r = RayRecord::zeroed();
            (stringify!($name), std::mem::offset_of!(RayRecord, $name), std::mem::size_of_val(&r.$name))
        }};
    }
    vec![
        f!(origin),
        f!(t_max),
        f!(direction),
        f!(pixel),
        f!(throughput),
        f!(sample),
        f!(bsdf_pdf),
        f!(depth),
        f!(flags),
        f!(light),
        f!(instance),
        f!(position),
        f!(reserved),
        f!(geometric_normal),
        f!(material),
        f!(shading_normal),
        f!(reserved2),
        f!(coeffs),
    ]
}

pub(crate) fn to_f16x3(v: Vec3) -> [f16; 3] {
    [f16::from_f32(v.x), f16::from_f32(v.y), f16::from_f32(v.z)]
}

pub(crate) fn from_f16x3(v: [f16; 3]) -> Vec3 {
    Vec3::new(v[0].to_f32(), v[1].to_f32(), v[2].to_f32())
}

impl RayRecord {
    pub fn origin(&self) -> Vec3 {
        Vec3::from(self.origin)
    }
    pub fn direction(&self) -> Vec3 {
        Vec3::from(self.direction)
    }
    pub fn throughput(&self) -> Vec3 {
        Vec3::from(self.throughput)
    }
    pub fn has(&self, flag: u16) -> bool {
        self.flags & flag != 0
    }
    pub fn geometric_normal(&self) -> Vec3 {
        from_f16x3(self.geometric_normal)
    }
    pub fn shading_normal(&self) -> Vec3 {
        from_f16x3(self.shading_normal)
    }
    pub fn material_kind(&self) -> MaterialKind {
        MaterialKind::from_u16(self.material)
    }
    pub fn coeff(&self, i: usize) -> f32 {
        self.coeffs[i].to_f32()
    }
    pub fn coeff3(&self, i: usize) -> Vec3 {
        Vec3::new(self.coeff(i), self.coeff(i + 1), self.coeff(i + 2))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_has_no_gaps_and_fills_128_bytes() {
        let fields = field_layout();
        let mut end = 0;
        for (name, offset, size) in &fields {
            assert_eq!(*offset, end, "gap or overlap before {name}");
            end = offset + size;
        }
        assert_eq!(end, std::mem::size_of::<RayRecord>());
    }
}
