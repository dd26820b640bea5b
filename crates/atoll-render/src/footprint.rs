//! How much of a texture one pixel covers at a hit: pbrt-v4's texture
//! footprint for rays without differentials. Once per frame the camera's
//! smallest one-pixel change of ray origin and direction is found
//! ([`CameraFootprint::new`], pbrt's `FindMinimumDifferentials`); at a hit,
//! rays shifted by those changes are met with the hit's tangent plane,
//! giving how the point moves from pixel to pixel
//! ([`CameraFootprint::dp_dxy`], pbrt's `Camera::Approximate_dp_dxy`),
//! and from that how its uv move ([`uv_footprint`]). Image textures pick
//! their MIP level from it. pbrt-v4 uses the camera ray's own
//! differentials at first hits and this estimate after; atoll uses the
//! estimate at every hit (the ray record has no room for differentials).
//! `kernels/footprint.cuh` mirrors it.

use glam::{Mat3, Vec2, Vec3};

use crate::camera::CameraRays;

/// The camera's smallest differentials and the transforms the estimate
/// works in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraFootprint {
    /// The camera's position and the linear parts of its transforms.
    pub camera_position: Vec3,
    pub camera_from_world: Mat3,
    pub world_from_camera: Mat3,
    /// In camera space: a one-pixel step in x and in y of a ray's origin.
    pub min_position: [Vec3; 2],
    /// In a ray's own frame (its direction +z): the same of its direction.
    pub min_direction: [Vec3; 2],
    /// pbrt-v4's `max(1/8, 1/sqrt(spp))`: more samples a pixel, each a
    /// narrower footprint.
    pub spp_scale: f32,
}

impl CameraFootprint {
    /// pbrt-v4's `FindMinimumDifferentials`: over 512 points of the film's
    /// diagonal, the shortest one-pixel change of origin and of direction.
    pub fn new(camera: &CameraRays, spp: u32) -> Self {
        let world_from_camera = Mat3::from_mat4(camera.camera_to_world());
        let camera_from_world = world_from_camera.inverse();
        let (mut min_position, mut min_direction) = ([Vec3::INFINITY; 2], [Vec3::INFINITY; 2]);
        const POINTS: u32 = 512;
        for i in 0..POINTS {
            let raster = camera.raster_size() * (i as f32 / (POINTS - 1) as f32);
            let Some((origin, direction, shifted)) = differentials(camera, raster) else { continue };
            let (x, y, z) = frame_from_z(direction);
            let local = |v: Vec3| Vec3::new(v.dot(x), v.dot(y), v.dot(z));
            for (k, (o, d)) in shifted.into_iter().enumerate() {
                let dp = camera_from_world * (o - origin);
                if dp.length() < min_position[k].length() {
                    min_position[k] = dp;
                }
                let dd = local(d.normalize()).normalize() - local(direction);
                if dd.length() < min_direction[k].length() {
                    min_direction[k] = dd;
                }
            }
        }
        let finite = |v: [Vec3; 2]| v.map(|v| if v.is_finite() { v } else { Vec3::ZERO });
        CameraFootprint {
            camera_position: camera.camera_to_world().w_axis.truncate(),
            camera_from_world,
            world_from_camera,
            min_position: finite(min_position),
            min_direction: finite(min_direction),
            spp_scale: (1.0 / (spp.max(1) as f32).sqrt()).max(0.125),
        }
    }

    /// pbrt-v4's `Approximate_dp_dxy`: how the hit point `p` (world space;
    /// `n` its surface normal) moves from one pixel to the next in x and y.
    pub fn dp_dxy(&self, p: Vec3, n: Vec3) -> (Vec3, Vec3) {
        let p_camera = self.camera_from_world * (p - self.camera_position);
        let down_z = rotate_from_to(p_camera.normalize(), Vec3::Z);
        let (p_down, n_down) = (down_z * p_camera, down_z * (self.camera_from_world * n));
        let d = n_down.z * p_down.z;
        let meet = |k: usize| {
            let (o, dir) = (self.min_position[k], Vec3::Z + self.min_direction[k]);
            let t = -(n_down.dot(o) - d) / n_down.dot(dir);
            o + t * dir
        };
        let back = |v: Vec3| self.spp_scale * (self.world_from_camera * (down_z.transpose() * v));
        (back(meet(0) - p_down), back(meet(1) - p_down))
    }
}

/// A camera ray through `raster` (the lens's centre) and the rays one pixel
/// on in x and in y, as pbrt-v4 makes differentials: exactly for the
/// perspective and orthographic cameras, by a twentieth of a pixel and
/// extrapolated for the others (`CameraBase::GenerateRayDifferential`).
/// `None` where the lens blocks the ray.
fn differentials(camera: &CameraRays, raster: Vec2) -> Option<(Vec3, Vec3, [Ray; 2])> {
    let centre = Vec2::splat(0.5);
    let ray = |at: Vec2| {
        let r = camera.weighted_ray(at, centre);
        (r.weight > 0.0).then_some((r.origin, r.direction))
    };
    let (origin, direction) = ray(raster)?;
    let exact = matches!(
        camera.projection(),
        atoll_scene::Projection::Perspective | atoll_scene::Projection::Orthographic
    );
    let shifted = |step: Vec2| -> Option<Ray> {
        if exact {
            return ray(raster + step);
        }
        [0.05f32, -0.05].into_iter().find_map(|eps| {
            let (o, d) = ray(raster + step * eps)?;
            Some((origin + (o - origin) / eps, direction + (d - direction) / eps))
        })
    };
    Some((origin, direction, [shifted(Vec2::X)?, shifted(Vec2::Y)?]))
}

/// A ray's origin and direction.
type Ray = (Vec3, Vec3);

/// pbrt-v4's `Frame::FromZ` (its `CoordinateSystem`): axes x and y about `z`.
fn frame_from_z(z: Vec3) -> (Vec3, Vec3, Vec3) {
    let sign = 1f32.copysign(z.z);
    let a = -1.0 / (sign + z.z);
    let b = z.x * z.y * a;
    let x = Vec3::new(1.0 + sign * z.x * z.x * a, sign * b, -sign * z.x);
    let y = Vec3::new(b, sign + z.y * z.y * a, -z.y);
    (x, y, z)
}

/// pbrt-v4's `RotateFromTo`: the rotation (two reflections) taking unit
/// vector `from` to `to`.
fn rotate_from_to(from: Vec3, to: Vec3) -> Mat3 {
    let refl = if from.x.abs() < 0.72 && to.x.abs() < 0.72 {
        Vec3::X
    } else if from.y.abs() < 0.72 && to.y.abs() < 0.72 {
        Vec3::Y
    } else {
        Vec3::Z
    };
    let (u, v) = (refl - from, refl - to);
    let (uu, vv, uv) = (u.dot(u), v.dot(v), u.dot(v));
    // Row i, column j: δij − 2/uu uᵢuⱼ − 2/vv vᵢvⱼ + 4 uv/(uu vv) vᵢuⱼ.
    let column = |j: usize| {
        Vec3::from_array(std::array::from_fn(|i| {
            let delta = if i == j { 1.0 } else { 0.0 };
            delta - 2.0 / uu * u[i] * u[j] - 2.0 / vv * v[i] * v[j] + 4.0 * uv / (uu * vv) * v[i] * u[j]
        }))
    };
    Mat3::from_cols(column(0), column(1), column(2))
}

/// `a·b − c·d` with the rounding of `c·d` recovered (pbrt's
/// `DifferenceOfProducts`).
fn difference_of_products(a: f32, b: f32, c: f32, d: f32) -> f32 {
    let cd = c * d;
    let error = (-c).mul_add(d, cd);
    a.mul_add(b, -cd) + error
}

/// pbrt-v4's `SurfaceInteraction::ComputeDifferentials` after `dpdx` and
/// `dpdy`: the uv's changes `(dudx, dvdx)` and `(dudy, dvdy)` by least
/// squares over the surface's `dpdu` and `dpdv`, clamped to ±1e8 (zero
/// where not finite).
pub fn uv_footprint(dpdx: Vec3, dpdy: Vec3, dpdu: Vec3, dpdv: Vec3) -> (Vec2, Vec2) {
    let (ata00, ata01, ata11) = (dpdu.dot(dpdu), dpdu.dot(dpdv), dpdv.dot(dpdv));
    let inv_det = 1.0 / difference_of_products(ata00, ata11, ata01, ata01);
    let inv_det = if inv_det.is_finite() { inv_det } else { 0.0 };
    let solve = |d: Vec3| {
        let (atb0, atb1) = (dpdu.dot(d), dpdv.dot(d));
        let du = difference_of_products(ata11, atb0, ata01, atb1) * inv_det;
        let dv = difference_of_products(ata00, atb1, ata01, atb0) * inv_det;
        let clamp = |x: f32| if x.is_finite() { x.clamp(-1e8, 1e8) } else { 0.0 };
        Vec2::new(clamp(du), clamp(dv))
    };
    (solve(dpdx), solve(dpdy))
}

#[cfg(test)]
mod tests {
    use super::*;
    use atoll_scene::Camera;

    /// A pinhole camera at the origin looking down +z at a wall facing it.
    fn camera(fov: f32, width: u32) -> CameraRays {
        let camera = Camera { fov_degrees: fov, camera_to_world: glam::Mat4::IDENTITY, ..Camera::default() };
        CameraRays::new(&camera, glam::UVec2::new(width, width))
    }

    #[test]
    fn a_wall_facing_the_camera_moves_one_pixel_per_pixel() {
        let (fov, width, distance) = (30.0f32, 512, 3.0);
        let f = CameraFootprint::new(&camera(fov, width), 1);
        // The smallest pixel (at the film's corners, pbrt's choice) is a
        // few percent narrower than the centre's 2 tan(15°)/512 at unit
        // distance; the estimate applies it at the hit.
        let pixel = 2.0 * (fov.to_radians() / 2.0).tan() / width as f32;
        let (dpdx, dpdy) = f.dp_dxy(Vec3::new(0.0, 0.0, distance), -Vec3::Z);
        for d in [dpdx, dpdy] {
            let ratio = d.length() / (pixel * distance);
            assert!((0.85..=1.0).contains(&ratio), "{d}: {ratio}");
            assert!(d.z.abs() < 1e-5 * d.length(), "in the wall: {d}");
        }
        // Twice as far, twice as wide; more samples a pixel, narrower.
        let (far, _) = f.dp_dxy(Vec3::new(0.0, 0.0, 2.0 * distance), -Vec3::Z);
        assert!((far.length() / dpdx.length() - 2.0).abs() < 1e-3);
        let f16 = CameraFootprint::new(&camera(fov, width), 16);
        assert!(
            (f16.dp_dxy(Vec3::new(0.0, 0.0, distance), -Vec3::Z).0.length() / dpdx.length() - 0.25).abs()
                < 1e-4
        );
        // A grazing wall stretches the footprint.
        let tilted = Vec3::new(0.0, -1.0, -0.2).normalize();
        let (gx, gy) = f.dp_dxy(Vec3::new(0.0, 0.0, distance), tilted);
        assert!(gx.length().max(gy.length()) > 3.0 * dpdx.length());
    }

    #[test]
    fn uv_footprints_solve_for_the_surface_parametrisation() {
        // u along x at 2 units a texture, v along y at 4.
        let (dpdu, dpdv) = (Vec3::X * 2.0, Vec3::Y * 4.0);
        let (dx, dy) = uv_footprint(Vec3::new(0.1, 0.0, 0.0), Vec3::new(0.0, 0.2, 0.0), dpdu, dpdv);
        assert!((dx - Vec2::new(0.05, 0.0)).length() < 1e-7 && (dy - Vec2::new(0.0, 0.05)).length() < 1e-7);
        // A degenerate parametrisation gives no footprint.
        assert_eq!(uv_footprint(Vec3::X, Vec3::Y, Vec3::ZERO, Vec3::Y), (Vec2::ZERO, Vec2::ZERO));
    }

    #[test]
    fn rotations_take_from_to_to() {
        for from in [Vec3::X, Vec3::new(0.3, -0.8, 0.52).normalize(), -Vec3::Z, Vec3::Z] {
            let r = rotate_from_to(from, Vec3::Z);
            assert!((r * from - Vec3::Z).length() < 1e-5, "{from}");
            assert!((r.determinant() - 1.0).abs() < 1e-5);
        }
        let (x, y, z) = frame_from_z(Vec3::new(0.3, -0.8, 0.52).normalize());
        assert!(x.dot(y).abs() < 1e-6 && x.dot(z).abs() < 1e-6 && (x.cross(y) - z).length() < 1e-5);
    }
}
