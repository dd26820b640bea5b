//! pbrt-v4's infinite-light portals (`PortalImageInfiniteLight`): the
//! environment shines in only through a rectangle, and a ray sees it only
//! if it leaves through the rectangle from its back (pbrt's `Le` and
//! `ImageBounds`, reproduced here in pbrt's own terms: a direction's
//! rectified image coordinates and the bounds of the portal's corners).
//!
//! Sampling is atoll's own, not pbrt's windowed image distribution: with
//! equal probability the light's own direction sampling (the image's
//! importance, or the uniform sphere) or a uniform point on the rectangle,
//! combined as one mixture density. Either finds what the other misses: a
//! sun seen through a window, a window's patch of an evenly lit sky.

use atoll_scene::Portal;
use glam::{Vec2, Vec3};
use std::f32::consts::{FRAC_PI_2, PI};

/// A portal in the form the light set uses: pbrt's frame (x along the
/// corners 0 → 3, y along 0 → 1, z their cross product, the side the
/// environment is on) and the rectangle's corner, edges and area.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PortalFrame {
    pub corner: Vec3,
    /// Corner 2, the bounds' other end (pbrt's `portal[2]`).
    pub far_corner: Vec3,
    /// Corner 1 − corner 0 and corner 3 − corner 0.
    pub edge_u: Vec3,
    pub edge_v: Vec3,
    pub x: Vec3,
    pub y: Vec3,
    pub z: Vec3,
    pub area: f32,
}

impl PortalFrame {
    pub fn new(portal: &Portal) -> Self {
        let [p0, p1, p2, p3] = portal.corners;
        let (edge_u, edge_v) = (p1 - p0, p3 - p0);
        let (x, y) = (edge_v.normalize(), edge_u.normalize());
        PortalFrame {
            corner: p0,
            far_corner: p2,
            edge_u,
            edge_v,
            x,
            y,
            z: x.cross(y),
            area: edge_u.length() * edge_v.length(),
        }
    }

    /// pbrt's `ImageFromRender`: the rectified image coordinates of the
    /// unit direction `w`; `None` for directions not towards the +z side.
    pub fn image_uv(&self, w: Vec3) -> Option<Vec2> {
        let (x, y, z) = (w.dot(self.x), w.dot(self.y), w.dot(self.z));
        if z <= 0.0 {
            return None;
        }
        let to_unit = |a: f32| ((a + FRAC_PI_2) / PI).clamp(0.0, 1.0);
        Some(Vec2::new(to_unit(x.atan2(z)), to_unit(y.atan2(z))))
    }

    /// pbrt's `Le` test: the ray from `origin` along the unit direction `w`
    /// leaves through the portal.
    pub fn passes(&self, origin: Vec3, w: Vec3) -> bool {
        let Some(uv) = self.image_uv(w) else { return false };
        let corner_uv = |c: Vec3| self.image_uv((c - origin).normalize());
        let (Some(a), Some(b)) = (corner_uv(self.corner), corner_uv(self.far_corner)) else { return false };
        uv.cmpge(a.min(b)).all() && uv.cmple(a.max(b)).all()
    }

    /// A direction from `origin` towards a uniform point `u` of the
    /// rectangle, with its solid-angle density; `None` from in front of it.
    pub fn sample(&self, origin: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        let d = self.corner + u.x * self.edge_u + u.y * self.edge_v - origin;
        let dist2 = d.length_squared();
        let w = d / dist2.sqrt();
        let cos = w.dot(self.z);
        (cos > 0.0 && dist2 > 0.0).then(|| (w, dist2 / (self.area * cos)))
    }

    /// The density [`Self::sample`] has for the unit direction `w` from
    /// `origin`: zero unless the ray crosses the rectangle from its back.
    pub fn pdf(&self, origin: Vec3, w: Vec3) -> f32 {
        let cos = w.dot(self.z);
        let t = (self.corner - origin).dot(self.z) / cos;
        if !(cos > 0.0 && t > 0.0) {
            return 0.0;
        }
        let q = origin + t * w - self.corner;
        let a = q.dot(self.edge_u) / self.edge_u.length_squared();
        let b = q.dot(self.edge_v) / self.edge_v.length_squared();
        if !((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b)) {
            return 0.0;
        }
        t * t / (self.area * cos)
    }
}

/// How a portal light picks between its two strategies: `u.x` below one
/// half takes the light's own direction sampling, the rest the portal,
/// each with `u.x` stretched back over [0, 1).
pub fn split_strategy(u: Vec2) -> (bool, Vec2) {
    match u.x < 0.5 {
        true => (false, Vec2::new(u.x * 2.0, u.y)),
        false => (true, Vec2::new(u.x * 2.0 - 1.0, u.y)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit window in the plane z = 1 of world space, the environment
    /// beyond it (+z).
    fn window() -> PortalFrame {
        // Corners 0 → 3 along +x and 0 → 1 along +y: z = x × y = +z.
        let corners = [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
            Vec3::new(1.0, 1.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
        ];
        PortalFrame::new(&Portal::new(corners).unwrap())
    }

    /// A ray passes exactly when it crosses the rectangle from behind;
    /// sampled directions pass, and their density is what `pdf` says.
    #[test]
    fn rays_through_the_window_pass_and_sampling_matches_its_density() {
        let w = window();
        assert_eq!(w.z, Vec3::Z);
        let o = Vec3::new(0.3, 0.6, 0.0);
        assert!(w.passes(o, (Vec3::new(0.5, 0.5, 1.0) - o).normalize()));
        assert!(!w.passes(o, (Vec3::new(1.5, 0.5, 1.0) - o).normalize()));
        assert!(!w.passes(o, -Vec3::Z));
        // From in front of the window nothing passes or is sampled.
        let front = Vec3::new(0.5, 0.5, 2.0);
        assert!(!w.passes(front, -Vec3::Z) && w.sample(front, Vec2::splat(0.5)).is_none());
        let mut total = 0.0f64;
        let n = 64;
        for i in 0..n {
            for j in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                let (dir, pdf) = w.sample(o, u).unwrap();
                assert!(w.passes(o, dir), "{u}");
                let back = w.pdf(o, dir);
                assert!((back - pdf).abs() <= 1e-4 * pdf, "{u}: {back} vs {pdf}");
                total += 1.0 / pdf as f64;
            }
        }
        // The mean of 1 / pdf is the window's solid angle from `o`; a
        // square of side 1 at distance 1 subtends 0.5 sr or so, seen from
        // inside its footprint.
        let solid_angle = total / (n * n) as f64;
        assert!((0.4..0.8).contains(&solid_angle), "{solid_angle}");
    }

    /// Corners that make no rectangle are refused.
    #[test]
    fn portals_must_be_rectangles() {
        let skew = [Vec3::ZERO, Vec3::Y, Vec3::new(1.0, 1.5, 0.0), Vec3::X];
        assert!(Portal::new(skew).is_err());
        assert!(Portal::new([Vec3::ZERO; 4]).is_err());
    }

    #[test]
    fn strategies_split_the_first_number() {
        assert_eq!(split_strategy(Vec2::new(0.25, 0.7)), (false, Vec2::new(0.5, 0.7)));
        assert_eq!(split_strategy(Vec2::new(0.75, 0.7)), (true, Vec2::new(0.5, 0.7)));
    }
}
