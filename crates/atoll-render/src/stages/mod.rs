//! The integrator's stages as functions of one record. Devices map them over
//! their queues (the CPU device with rayon); the CUDA kernels of the same
//! names implement the same arithmetic.

pub mod generate;
pub mod shade;

use glam::Vec3;

/// Moves a ray origin off a surface along the geometric normal, to the side
/// `w` leaves from, so the new ray does not re-hit its own surface. The
/// offset scales with the coordinates' magnitude (float spacing grows with it).
#[inline]
pub fn offset_origin(p: Vec3, ng: Vec3, w: Vec3) -> Vec3 {
    let eps = 1e-4 * (1.0 + p.abs().max_element());
    let n = if ng.dot(w) < 0.0 { -ng } else { ng };
    p + n * eps
}
