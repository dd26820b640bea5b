//! Motion blur: an instance moving between two transforms while the
//! shutter is open, as pbrt-v4's `AnimatedTransform` moves it.
//!
//! Each transform is split into translation, rotation and scale (a
//! symmetric matrix, by polar decomposition; Shoemake & Duff 1992), and a
//! time between the two keys interpolates the three apart: translation and
//! scale linearly, rotation along the shorter great arc. Interpolating the
//! matrices themselves would shear and shrink a turning object.

use glam::{Affine3A, DMat3, DMat4, DQuat, Mat3, Quat, Vec3};

/// A transform as translation · rotation · scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decomposed {
    pub translation: Vec3,
    /// A unit quaternion.
    pub rotation: Quat,
    /// Symmetric; negative where the transform mirrors.
    pub scale: Mat3,
}

impl Decomposed {
    /// Splits affine `m` (its bottom row is ignored); `None` where it is
    /// singular or not finite.
    pub fn new(m: &DMat4) -> Option<Self> {
        let linear = DMat3::from_mat4(*m);
        let det = linear.determinant();
        if !det.is_finite() || det == 0.0 {
            return None;
        }
        // Polar decomposition: average the matrix with its inverse
        // transpose until it stops changing; the limit is the rotation.
        let mut r = linear;
        for _ in 0..100 {
            let next = (r + r.transpose().inverse()) * 0.5;
            let change = (0..3).map(|i| (next.row(i) - r.row(i)).abs().element_sum()).fold(0.0, f64::max);
            r = next;
            if change <= 1e-12 {
                break;
            }
        }
        // A mirroring transform gives an improper rotation: move the sign
        // into the scale, so that the rotation has a quaternion.
        if r.determinant() < 0.0 {
            r = -r;
        }
        let scale = r.transpose() * linear;
        let rotation = DQuat::from_mat3(&r).normalize();
        let d = Decomposed {
            translation: m.w_axis.truncate().as_vec3(),
            rotation: rotation.as_quat(),
            scale: scale.as_mat3(),
        };
        d.matrix().is_finite().then_some(d)
    }

    /// The transform it came from.
    pub fn matrix(&self) -> Affine3A {
        let linear = Mat3::from_quat(self.rotation) * self.scale;
        Affine3A::from_mat3_translation(linear, self.translation)
    }
}

/// Two keyed transforms of an instance (pbrt's `ActiveTransform StartTime`
/// and `EndTime`) and their times (`TransformTimes`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    pub start: Decomposed,
    /// Its rotation is on the start's side of the sphere of quaternions,
    /// so that interpolation takes the shorter way round.
    pub end: Decomposed,
    pub times: [f32; 2],
}

impl Motion {
    /// The motion from `start` to `end` over `times`; `None` where either
    /// transform is singular.
    pub fn new(start: &DMat4, end: &DMat4, times: [f32; 2]) -> Option<Self> {
        let start = Decomposed::new(start)?;
        let mut end = Decomposed::new(end)?;
        if start.rotation.dot(end.rotation) < 0.0 {
            end.rotation = -end.rotation;
        }
        Some(Motion { start, end, times })
    }

    /// Where between the keys `time` lies: 0 at or before the start's time,
    /// 1 at or after the end's.
    pub fn key(&self, time: f32) -> f32 {
        let [t0, t1] = self.times;
        if time <= t0 {
            0.0
        } else if time >= t1 {
            1.0
        } else {
            (time - t0) / (t1 - t0)
        }
    }

    /// The transform a fraction `s` of the way from start to end.
    pub fn interpolate(&self, s: f32) -> Decomposed {
        let (a, b) = (&self.start, &self.end);
        Decomposed {
            translation: a.translation.lerp(b.translation, s),
            rotation: slerp(a.rotation, b.rotation, s),
            scale: a.scale * (1.0 - s) + b.scale * s,
        }
    }

    /// Object to world at `time`.
    pub fn at(&self, time: f32) -> Affine3A {
        self.interpolate(self.key(time)).matrix()
    }

    /// The angle the rotation turns through from start to end (radians).
    fn turn(&self) -> f32 {
        2.0 * self.start.rotation.dot(self.end.rotation).clamp(-1.0, 1.0).acos()
    }

    /// A box holding the object box `lo`..`hi` wherever the motion takes it.
    ///
    /// The box is moved to evenly spaced keys and the results joined; a
    /// corner's path between two neighbouring keys strays from the straight
    /// line between them by at most h²/8 · max |p''| (h the keys' spacing),
    /// and |p''| ≤ θ² |S x| + 2θ |ΔS x| for a turn θ and a scale changing
    /// by ΔS, so the joined box grows by that much.
    pub fn bounds(&self, lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
        const STEPS: u32 = 32;
        let corners: Vec<Vec3> = (0..8)
            .map(|k| Vec3::select(glam::BVec3::new(k & 1 != 0, k & 2 != 0, k & 4 != 0), hi, lo))
            .collect();
        let (mut min, mut max) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for step in 0..=STEPS {
            let m = self.interpolate(step as f32 / STEPS as f32).matrix();
            for &c in &corners {
                let p = m.transform_point3(c);
                min = min.min(p);
                max = max.max(p);
            }
        }
        let theta = self.turn();
        let ds = self.end.scale - self.start.scale;
        let bend = corners
            .iter()
            .map(|&c| {
                let sx = (self.start.scale * c).length().max((self.end.scale * c).length());
                theta * theta * sx + 2.0 * theta * (ds * c).length()
            })
            .fold(0.0, f32::max);
        let h = 1.0 / STEPS as f32;
        // The bound, and a relative margin for the rounding of the keys' transforms.
        let pad =
            h * h / 8.0 * bend + (max - min).max_element().max(max.abs().max(min.abs()).max_element()) * 1e-6;
        (min - Vec3::splat(pad), max + Vec3::splat(pad))
    }
}

/// Spherical interpolation of unit quaternions on the same side of the
/// sphere (pbrt-v4's `Slerp`: nearly equal ones are interpolated linearly).
pub fn slerp(a: Quat, b: Quat, s: f32) -> Quat {
    let cos_theta = a.dot(b);
    if cos_theta > 0.9995 {
        return (a * (1.0 - s) + b * s).normalize();
    }
    let theta = cos_theta.clamp(-1.0, 1.0).acos();
    let perpendicular = (b - a * cos_theta).normalize();
    a * (theta * s).cos() + perpendicular * (theta * s).sin()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn close(a: Affine3A, b: Affine3A, tol: f32) -> bool {
        a.to_cols_array().iter().zip(b.to_cols_array()).all(|(x, y)| (x - y).abs() <= tol)
    }

    fn sample_transform(angle: f64, axis: DVec3, scale: DVec3, translation: DVec3) -> DMat4 {
        DMat4::from_translation(translation)
            * DMat4::from_axis_angle(axis.normalize(), angle)
            * DMat4::from_scale(scale)
    }

    #[test]
    fn decomposition_gives_back_its_transform() {
        for (angle, scale) in
            [(0.3, DVec3::new(1.0, 2.0, 0.5)), (2.9, DVec3::new(-1.0, 1.0, 1.0)), (0.0, DVec3::splat(3.0))]
        {
            let m = sample_transform(angle, DVec3::new(1.0, 2.0, -0.5), scale, DVec3::new(4.0, -2.0, 7.0))
                * DMat4::from_cols_array(&[
                    1.0, 0.2, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.1, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
                ]);
            let d = Decomposed::new(&m).unwrap();
            assert!((d.rotation.length() - 1.0).abs() < 1e-5);
            let s = d.scale;
            assert!((s - s.transpose()).to_cols_array().iter().all(|x| x.abs() < 1e-5), "{s:?}");
            assert!(close(d.matrix(), Affine3A::from_mat4(m.as_mat4()), 1e-5), "{angle}");
        }
        assert!(Decomposed::new(&DMat4::from_scale(DVec3::new(1.0, 0.0, 1.0))).is_none());
    }

    #[test]
    fn keys_are_met_and_clamped_and_rotation_turns_evenly() {
        let start = sample_transform(0.0, DVec3::Z, DVec3::ONE, DVec3::ZERO);
        let end = sample_transform(std::f64::consts::FRAC_PI_2, DVec3::Z, DVec3::splat(2.0), DVec3::X * 10.0);
        let m = Motion::new(&start, &end, [1.0, 3.0]).unwrap();
        assert!(close(m.at(0.0), Affine3A::IDENTITY, 1e-6));
        assert!(close(m.at(1.0), Affine3A::IDENTITY, 1e-6));
        assert!(close(m.at(5.0), Affine3A::from_mat4(end.as_mat4()), 1e-5));
        // Half way: 45 degrees, scale 1.5, translation 5.
        let half = m.at(2.0);
        let p = half.transform_point3(Vec3::X);
        let r = 1.5 * std::f32::consts::FRAC_1_SQRT_2;
        assert!((p - Vec3::new(5.0 + r, r, 0.0)).length() < 1e-5, "{p}");
        // The length of a rotated vector does not dip (no shrinking).
        for k in 0..=10 {
            let s = k as f32 / 10.0;
            let v = m.interpolate(s).matrix().transform_vector3(Vec3::X);
            assert!((v.length() - (1.0 + s)).abs() < 1e-5);
        }
    }

    #[test]
    fn rotation_takes_the_short_way_round() {
        // +0.1 and -0.1 radians (written as 2π - 0.1) meet at no turn, not at π.
        let start = sample_transform(0.1, DVec3::Y, DVec3::ONE, DVec3::ZERO);
        let end = sample_transform(std::f64::consts::TAU - 0.1, DVec3::Y, DVec3::ONE, DVec3::ZERO);
        let m = Motion::new(&start, &end, [0.0, 1.0]).unwrap();
        assert!(close(m.at(0.5), Affine3A::IDENTITY, 1e-5), "{:?}", m.at(0.5));
        assert!((m.turn() - 0.2).abs() < 1e-4);
    }

    #[test]
    fn bounds_hold_the_box_at_every_time() {
        let start = sample_transform(0.2, DVec3::new(1.0, 1.0, 0.0), DVec3::new(1.0, 2.0, 1.0), DVec3::ZERO);
        let end = sample_transform(3.0, DVec3::new(0.0, 1.0, 1.0), DVec3::new(0.5, 1.0, 3.0), DVec3::Y * 4.0);
        let m = Motion::new(&start, &end, [0.0, 1.0]).unwrap();
        let (lo, hi) = (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(2.0, 1.0, 3.0));
        let (min, max) = m.bounds(lo, hi);
        let mut seen_min = Vec3::INFINITY;
        for k in 0..=4000 {
            let t = m.at(k as f32 / 4000.0);
            for c in 0..8 {
                let corner = Vec3::select(glam::BVec3::new(c & 1 != 0, c & 2 != 0, c & 4 != 0), hi, lo);
                let p = t.transform_point3(corner);
                assert!(p.cmpge(min).all() && p.cmple(max).all(), "{p} outside {min}..{max}");
                seen_min = seen_min.min(p);
            }
        }
        // Conservative, but not wildly so.
        assert!((seen_min - min).max_element() < 0.5, "{seen_min} vs {min}");
    }
}
