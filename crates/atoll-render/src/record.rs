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
//!
//! The record has two 64-byte halves: the ray and path state (up to and
//! including `instance`), and the hit (from `position` on). The hit half
//! means something only while [`flags::HIT`] is set: stages that make a new
//! segment or a shadow ray may leave it as it was (the GPU writes only the
//! ray half, which saves a third of shading's memory traffic), so nothing
//! may read it from a record that closest-hit tracing has not hit.

use atoll_scene::{MediumIndex, MediumInterface};
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
    pub const SHADOW: u8 = 1 << 0;
    /// Set by any-hit tracing of a shadow ray that is blocked.
    pub const OCCLUDED: u8 = 1 << 1;
    /// Set by closest-hit tracing when the ray hit something (fields below are valid).
    pub const HIT: u8 = 1 << 2;
    /// The direction was sampled from a delta lobe (or is a camera ray): an
    /// emitter found along it is counted without MIS.
    pub const SPECULAR: u8 = 1 << 3;
    /// The top four bits: the medium a path segment travels through
    /// ([`atoll_scene::MediumIndex`], 0 the vacuum; [`RayRecord::medium`]).
    pub const MEDIUM_SHIFT: u32 = 4;
    /// The bits [`MEDIUM_SHIFT`] points at.
    pub const MEDIUM_MASK: u8 = 0xf0;
}

/// Which material model the coefficients describe ([`RayRecord::material`]);
/// which coefficient holds which parameter is [`crate::material_layout`]'s
/// module of the kind's name.
#[repr(u16)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaterialKind {
    /// No scattering surface (pass-through, or a miss).
    None = 0,
    Diffuse = 1,
    Conductor = 2,
    Dielectric = 3,
    DiffuseTransmission = 4,
    ThinDielectric = 5,
    /// Material tables only, never in a record: a `mix` resolved to one of
    /// its materials when the hit is written ([`crate::FrameContext::material_at`]).
    Mix = 6,
    CoatedDiffuse = 7,
    Principled = 8,
    CoatedConductor = 9,
    Hair = 10,
    Measured = 11,
    /// A dielectric boundary around a scattering interior (the scene's
    /// subsurface material); the interior is the inside medium of the
    /// hit's interface.
    Subsurface = 12,
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
            7 => MaterialKind::CoatedDiffuse,
            8 => MaterialKind::Principled,
            9 => MaterialKind::CoatedConductor,
            10 => MaterialKind::Hair,
            11 => MaterialKind::Measured,
            12 => MaterialKind::Subsurface,
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
    pub flags: u8,
    /// Path state: the product of η² over the refractions so far (pbrt-v4's
    /// `etaScale`), which Russian roulette takes out of the throughput so
    /// that radiance scaling at refractions does not end paths; packed by
    /// [`pack_eta_scale`] (0 is 1, so camera paths need not set it). Beside
    /// the flags because the GPU's hit writer rewrites this word anyway.
    pub eta_scale: u8,
    // --- the hit (written by closest-hit tracing) ---
    /// Global light index when the hit surface emits, else [`NO_LIGHT`].
    pub light: u32,
    /// Instance that was hit (for ownership/debug views).
    pub instance: u32,
    pub position: [f32; 3],
    /// For a hit on a textured emitter: the emission texture's value at the
    /// hit, packed by [`pack_rgb9e5`] (the emitter's radiance is scaled by
    /// it when shading); 0 otherwise.
    pub emission_scale: u32,
    /// Geometric normal, oriented by pbrt's rule (not towards the ray).
    pub geometric_normal: [f16; 3],
    /// [`MaterialKind`] in the low byte; in the high byte, where the hit
    /// surface separates two media, their [`atoll_scene::MediumIndex`]es
    /// (inside in the top four bits, outside below; [`RayRecord::hit_media`]).
    pub material: u16,
    pub shading_normal: [f16; 3],
    /// How far `position` may lie off the surface along the geometric
    /// normal (its floating-point error bound), as bfloat16 bits rounded
    /// up ([`crate::spawn::pack_error`]); rays leave the hit past it.
    pub position_error: u16,
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
    assert!(std::mem::offset_of!(RayRecord, position_error) == 94);
    assert!(std::mem::offset_of!(RayRecord, coeffs) == 96);
    assert!(std::mem::offset_of!(RayRecord, eta_scale) == 55);
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
        f!(eta_scale),
        f!(light),
        f!(instance),
        f!(position),
        f!(emission_scale),
        f!(geometric_normal),
        f!(material),
        f!(shading_normal),
        f!(position_error),
        f!(coeffs),
    ]
}

/// Mantissa bits of [`pack_rgb9e5`]'s channels.
const RGB9E5_MANTISSA: i32 = 9;
/// Exponent bias of [`pack_rgb9e5`].
const RGB9E5_BIAS: i32 = 15;

/// Packs a non-negative colour as RGB9E5 (three 9-bit mantissas sharing a
/// 5-bit exponent, as `EXT_texture_shared_exponent`): 4 bytes, about 0.2%
/// precision relative to the largest channel, range up to 65408. Pure bit
/// arithmetic (no `log2`), so `kernels/texture.cuh` packs the same bits.
pub fn pack_rgb9e5(v: Vec3) -> u32 {
    let max_value = 511.0 / 512.0 * 65536.0;
    let c = |x: f32| if x > 0.0 { x.min(max_value) } else { 0.0 };
    let (r, g, b) = (c(v.x), c(v.y), c(v.z));
    let max_c = r.max(g).max(b);
    if max_c < f32::MIN_POSITIVE {
        return 0;
    }
    // floor(log2(max_c)) from the exponent bits (max_c is normal here).
    let floor_log2 = ((max_c.to_bits() >> 23) & 0xff) as i32 - 127;
    let mut exp_shared = floor_log2.max(-RGB9E5_BIAS - 1) + 1 + RGB9E5_BIAS;
    let scale = |e: i32| f32::from_bits(((127 - (e - RGB9E5_BIAS - RGB9E5_MANTISSA)) as u32) << 23);
    let mut inv_denom = scale(exp_shared);
    if (max_c * inv_denom + 0.5).floor() >= 512.0 {
        exp_shared += 1;
        inv_denom = scale(exp_shared);
    }
    let m = |x: f32| ((x * inv_denom + 0.5).floor() as u32).min(511);
    m(r) | m(g) << 9 | m(b) << 18 | (exp_shared as u32) << 27
}

/// The colour of [`pack_rgb9e5`] bits.
pub fn unpack_rgb9e5(bits: u32) -> Vec3 {
    let e = (bits >> 27) as i32 - RGB9E5_BIAS - RGB9E5_MANTISSA;
    let scale = f32::from_bits(((127 + e) as u32) << 23);
    Vec3::new((bits & 511) as f32, (bits >> 9 & 511) as f32, (bits >> 18 & 511) as f32) * scale
}

/// Packs a positive scale factor into 8 bits, a tiny float: a 5-bit
/// exponent (two's complement, 2^-15 to 2^15) and 3 mantissa bits, rounded
/// to nearest with integer arithmetic only, so `kernels/record.cuh` packs
/// the same bits. 1 packs to 0. Values beyond the range are clamped: Russian
/// roulette stays unbiased with any value, so 6% precision is plenty.
pub fn pack_eta_scale(v: f32) -> u8 {
    const MIN: f32 = 1.0 / 32768.0;
    const MAX: f32 = 32768.0 * 1.875;
    let v = if v >= MIN { v.min(MAX) } else { MIN };
    let bits = v.to_bits();
    // Round the mantissa to 3 bits; a carry steps the exponent up.
    let rounded = (bits + (1 << 19)) >> 20;
    let exponent = ((rounded >> 3) & 0xff) as i32 - 127;
    let (exponent, mantissa) = if exponent > 15 { (15, 7) } else { (exponent, rounded & 7) };
    (((exponent & 31) as u32) << 3 | mantissa) as u8
}

/// The value [`pack_eta_scale`] packed.
pub fn unpack_eta_scale(code: u8) -> f32 {
    // Sign-extend the 5-bit exponent.
    let exponent = ((code as i8) >> 3) as i32;
    let mantissa = (code & 7) as u32;
    f32::from_bits(((exponent + 127) as u32) << 23 | mantissa << 20)
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
    pub fn has(&self, flag: u8) -> bool {
        self.flags & flag != 0
    }
    pub fn geometric_normal(&self) -> Vec3 {
        from_f16x3(self.geometric_normal)
    }
    pub fn shading_normal(&self) -> Vec3 {
        from_f16x3(self.shading_normal)
    }
    pub fn material_kind(&self) -> MaterialKind {
        MaterialKind::from_u16(self.material & 0xff)
    }
    /// The medium this segment travels through.
    pub fn medium(&self) -> MediumIndex {
        self.flags >> flags::MEDIUM_SHIFT
    }
    /// Puts the segment in medium `m`.
    pub fn set_medium(&mut self, m: MediumIndex) {
        self.flags = (self.flags & !flags::MEDIUM_MASK) | (m << flags::MEDIUM_SHIFT);
    }
    /// The media on either side of the hit surface, where they differ.
    pub fn hit_media(&self) -> Option<MediumInterface> {
        let byte = (self.material >> 8) as u8;
        MediumInterface::transition(byte >> 4, byte & 0xf)
    }
    /// Records the hit surface's media (after its material kind is stored).
    pub fn set_hit_media(&mut self, media: Option<MediumInterface>) {
        let byte = media.map_or(0, |m| (m.inside << 4 | m.outside) as u16);
        self.material = (self.material & 0xff) | byte << 8;
    }
    /// A shadow ray's optical depth through media so far, per channel: it
    /// reaches the light with `exp(-depth)` of its radiance. Kept in the
    /// hit half's `position`, which shadow rays never use otherwise.
    pub fn optical_depth(&self) -> Vec3 {
        Vec3::from(self.position)
    }
    pub fn coeff(&self, i: usize) -> f32 {
        self.coeffs[i].to_f32()
    }
    pub fn coeff3(&self, i: usize) -> Vec3 {
        Vec3::new(self.coeff(i), self.coeff(i + 1), self.coeff(i + 2))
    }
    /// [`Self::position_error`] as a float.
    pub fn position_error(&self) -> f32 {
        crate::spawn::unpack_error(self.position_error)
    }
    pub fn eta_scale(&self) -> f32 {
        unpack_eta_scale(self.eta_scale)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rgb9e5_round_trips_within_its_precision() {
        assert_eq!(pack_rgb9e5(Vec3::ZERO), 0);
        assert_eq!(unpack_rgb9e5(pack_rgb9e5(Vec3::ONE)), Vec3::ONE);
        for v in [
            Vec3::new(0.25, 0.5, 2.0),
            Vec3::new(1e-3, 7.0, 300.0),
            Vec3::new(0.999, 0.0, 0.001),
            Vec3::splat(65000.0),
        ] {
            let back = unpack_rgb9e5(pack_rgb9e5(v));
            let tol = v.max_element() / 256.0;
            assert!((back - v).abs().max_element() <= tol, "{v} -> {back}");
        }
        // Negative and NaN channels become 0; huge ones saturate.
        let back = unpack_rgb9e5(pack_rgb9e5(Vec3::new(-1.0, f32::NAN, 1e9)));
        assert_eq!(back, Vec3::new(0.0, 0.0, 511.0 / 512.0 * 65536.0));
    }

    #[test]
    fn eta_scale_packs_within_its_precision() {
        assert_eq!(pack_eta_scale(1.0), 0);
        assert_eq!(unpack_eta_scale(0), 1.0);
        for v in [2.25f32, 1.0 / 2.25, 1.5 * 1.5 * 1.33 * 1.33, 0.01, 300.0, 1.9999] {
            let back = unpack_eta_scale(pack_eta_scale(v));
            assert!((back / v - 1.0).abs() <= 1.0 / 16.0, "{v} -> {back}");
        }
        assert_eq!(unpack_eta_scale(pack_eta_scale(1e9)), 32768.0 * 1.875);
        assert_eq!(unpack_eta_scale(pack_eta_scale(0.0)), 1.0 / 32768.0);
        for code in 0..=255u8 {
            if code >> 3 != 16 {
                assert_eq!(pack_eta_scale(unpack_eta_scale(code)), code, "code {code}");
            }
        }
    }

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
