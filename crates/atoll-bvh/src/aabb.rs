//! Axis-aligned bounding boxes.

use glam::{Affine3A, Vec3, Vec3A};

/// An axis-aligned box. The empty box has `min = +inf, max = -inf`, so that
/// growing it by anything gives that thing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Vec3A,
    /// Largest corner.
    pub max: Vec3A,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The box containing nothing.
    pub const EMPTY: Aabb = Aabb { min: Vec3A::INFINITY, max: Vec3A::NEG_INFINITY };

    /// The box of a set of points (`EMPTY` for none).
    pub fn from_points(points: impl IntoIterator<Item = Vec3>) -> Self {
        points.into_iter().fold(Self::EMPTY, |b, p| b.grow_point(p.into()))
    }

    /// This box grown to contain `p`.
    #[inline]
    pub fn grow_point(self, p: Vec3A) -> Self {
        Aabb { min: self.min.min(p), max: self.max.max(p) }
    }

    /// The union of two boxes.
    #[inline]
    pub fn union(self, other: Aabb) -> Self {
        Aabb { min: self.min.min(other.min), max: self.max.max(other.max) }
    }

    /// True for the empty box (or any box with `min > max` on some axis).
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    /// Twice the centre: cheaper than the centre and as good for binning.
    #[inline]
    pub fn centroid2(&self) -> Vec3A {
        self.min + self.max
    }

    /// Surface area; 0 for the empty box (SAH weights must not go negative or NaN).
    #[inline]
    pub fn area(&self) -> f32 {
        let e = (self.max - self.min).max(Vec3A::ZERO);
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// The box of this box's eight corners moved by `m`.
    pub fn transformed(&self, m: &Affine3A) -> Self {
        if self.is_empty() {
            return *self;
        }
        // Arvo's method: each output axis is the sum over input axes of the
        // smaller and larger of (matrix entry * min, matrix entry * max).
        let mut lo = m.translation;
        let mut hi = m.translation;
        for (axis, col) in [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis].into_iter().enumerate() {
            let a = col * self.min[axis];
            let b = col * self.max[axis];
            lo += a.min(b);
            hi += a.max(b);
        }
        Aabb { min: lo, max: hi }
    }

    /// True when `other` lies inside this box (used by tests and debug checks).
    pub fn contains(&self, other: &Aabb) -> bool {
        other.is_empty() || (self.min.cmple(other.min).all() && other.max.cmple(self.max).all())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    #[test]
    fn transformed_box_contains_transformed_corners() {
        let b = Aabb::from_points([Vec3::new(-1.0, 0.5, 2.0), Vec3::new(3.0, 1.0, 2.5)]);
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, 0.5, 1.0),
            Quat::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 0.7),
            Vec3::new(5.0, -1.0, 0.0),
        );
        let t = b.transformed(&m);
        for i in 0..8 {
            let c = Vec3A::select(glam::BVec3A::new(i & 1 != 0, i & 2 != 0, i & 4 != 0), b.max, b.min);
            let p = m.transform_point3a(c);
            assert!(t.min.cmple(p + 1e-5).all() && p.cmple(t.max + 1e-5).all(), "{p} outside {t:?}");
        }
        assert_eq!(b.area(), 2.0 * (4.0 * 0.5 + 0.5 * 0.5 + 0.5 * 4.0));
        assert_eq!(Aabb::EMPTY.area(), 0.0);
        assert!(Aabb::EMPTY.transformed(&m).is_empty());
    }
}
