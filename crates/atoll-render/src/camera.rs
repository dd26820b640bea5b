//! Camera rays (pbrt-v4's perspective and orthographic cameras with a thin
//! lens, and its spherical camera).

use std::sync::Arc;

use atoll_scene::lens::LensSystem;
use atoll_scene::{Camera, Motion, Projection};
use glam::{Mat4, UVec2, Vec2, Vec3};

use crate::sampling::sample_uniform_disk_concentric;

/// A camera prepared for a given image size.
#[derive(Clone, Debug)]
pub struct CameraRays {
    camera_to_world: Mat4,
    projection: Projection,
    /// The screen window in camera space: x/y at z = 1 for a perspective
    /// camera (pbrt's screen scaled by tan(fov/2)), at z = 0 for an
    /// orthographic one; for a spherical camera, (u, -v) of the image's
    /// square of directions (so that a crop cuts it as it cuts the others).
    window_min: Vec2,
    window_max: Vec2,
    resolution: Vec2,
    lens_radius: f32,
    focal_distance: f32,
    /// A realistic camera's lens; its window is then the physical film
    /// (metres, centred on the axis).
    lens: Option<Arc<LensSystem>>,
    /// A moving camera's motion (`camera_to_world` is its start) and the
    /// shutter its rays' times span.
    motion: Option<Motion>,
    shutter: [f32; 2],
}

/// A camera ray in world space: origin, unit direction, and the weight the
/// camera gives it (1 but for a realistic camera's lens; 0 for a ray the
/// lens blocks, which then has no extent).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraRay {
    pub origin: Vec3,
    pub direction: Vec3,
    pub weight: f32,
}

impl CameraRays {
    pub fn new(camera: &Camera, resolution: UVec2) -> Self {
        let [x0, x1, y0, y1] = camera.screen_window(resolution);
        let (mut window_min, mut window_max) = (Vec2::new(x0, y0), Vec2::new(x1, y1));
        let lens = camera.lens.clone().filter(|_| camera.projection == Projection::Realistic);
        if let Some(lens) = &lens {
            let half = lens.film_half_extent(resolution.y as f32 / resolution.x as f32);
            (window_min, window_max) = (-half, half);
        }
        let scale = match camera.projection {
            Projection::Perspective => (camera.fov_degrees.to_radians() * 0.5).tan(),
            _ => 1.0,
        };
        CameraRays {
            camera_to_world: camera.camera_to_world,
            projection: camera.projection,
            window_min: window_min * scale,
            window_max: window_max * scale,
            resolution: resolution.as_vec2(),
            // pbrt-v4's spherical camera has no lens.
            lens_radius: match camera.projection {
                Projection::Spherical { .. } => 0.0,
                _ => camera.lens_radius,
            },
            focal_distance: camera.focal_distance,
            lens,
            motion: camera.motion,
            shutter: camera.shutter,
        }
    }

    /// The camera for a frame rendered with `options`: its image, or the
    /// part of the scene's image its crop window covers (the window of
    /// screen space that part spans; raster positions count from its corner).
    pub fn for_options(camera: &Camera, options: &crate::RenderOptions) -> Self {
        let Some([x0, x1, y0, y1]) = options.crop else { return CameraRays::new(camera, options.resolution) };
        // The whole image's size (the crop is cut at its pixel boundaries).
        let r = options.resolution.as_vec2();
        let whole = Vec2::new(r.x / (x1 - x0), r.y / (y1 - y0)).round().as_uvec2();
        let mut rays = CameraRays::new(camera, whole.max(glam::UVec2::ONE));
        let (lo, hi) = (rays.window_min, rays.window_max);
        let size = hi - lo;
        // Raster y runs down from the window's top (its maximum y).
        rays.window_min = Vec2::new(lo.x + x0 * size.x, hi.y - y1 * size.y);
        rays.window_max = Vec2::new(lo.x + x1 * size.x, hi.y - y0 * size.y);
        rays.resolution = r;
        rays
    }

    /// Camera space to world space (at the start of a moving camera's motion).
    pub fn camera_to_world(&self) -> Mat4 {
        self.camera_to_world
    }

    /// A moving camera's motion and the shutter (`None` for a still one).
    pub fn motion(&self) -> Option<(&Motion, [f32; 2])> {
        self.motion.as_ref().map(|m| (m, self.shutter))
    }

    pub fn projection(&self) -> Projection {
        self.projection
    }

    /// Screen window in camera space (x/y at z = 1, at z = 0 for an
    /// orthographic camera, (u, −v) for a spherical one): (min, max).
    pub fn window(&self) -> (Vec2, Vec2) {
        (self.window_min, self.window_max)
    }

    /// Image size in pixels, as floats (what [`Self::ray`] divides by).
    pub fn raster_size(&self) -> Vec2 {
        self.resolution
    }

    /// Thin-lens aperture radius (0: pinhole) and focal distance.
    pub fn lens(&self) -> (f32, f32) {
        (self.lens_radius, self.focal_distance)
    }

    /// A realistic camera's lens system.
    pub fn lens_system(&self) -> Option<&Arc<LensSystem>> {
        self.lens.as_ref()
    }

    /// World-space ray through raster position `raster` (pixels, y down),
    /// with lens sample `u_lens`. Returns (origin, unit direction); see
    /// [`Self::weighted_ray`] for the weight a realistic camera gives it.
    pub fn ray(&self, raster: Vec2, u_lens: Vec2) -> (Vec3, Vec3) {
        let r = self.weighted_ray(raster, u_lens);
        (r.origin, r.direction)
    }

    /// World-space ray through raster position `raster` (pixels, y down),
    /// with lens sample `u_lens`, and its weight (of a moving camera, at
    /// the start of its motion).
    pub fn weighted_ray(&self, raster: Vec2, u_lens: Vec2) -> CameraRay {
        self.weighted_ray_from(self.camera_to_world, raster, u_lens)
    }

    /// [`Self::weighted_ray`] at `time` (where a moving camera is then).
    pub fn weighted_ray_at(&self, raster: Vec2, u_lens: Vec2, time: f32) -> CameraRay {
        match &self.motion {
            Some(m) => self.weighted_ray_from(Mat4::from(m.at(time)), raster, u_lens),
            None => self.weighted_ray(raster, u_lens),
        }
    }

    fn weighted_ray_from(&self, camera_to_world: Mat4, raster: Vec2, u_lens: Vec2) -> CameraRay {
        let t = raster / self.resolution;
        // Raster y grows downwards, camera y upwards.
        let x = self.window_min.x + t.x * (self.window_max.x - self.window_min.x);
        let y = self.window_max.y - t.y * (self.window_max.y - self.window_min.y);
        if let Some(lens) = &self.lens {
            // The lens turns the image over: the film point is opposite.
            return match lens.ray(Vec2::new(-x, -y), u_lens) {
                Some(r) => CameraRay {
                    origin: camera_to_world.transform_point3(r.origin),
                    direction: camera_to_world.transform_vector3(r.direction).normalize(),
                    weight: r.weight,
                },
                None => CameraRay {
                    origin: camera_to_world.transform_point3(Vec3::ZERO),
                    direction: camera_to_world.transform_vector3(Vec3::Z).normalize(),
                    weight: 0.0,
                },
            };
        }
        let (mut origin, mut dir) = self.projection.camera_ray(Vec2::new(x, y));
        if self.lens_radius > 0.0 {
            // The point in focus along the pinhole ray; pbrt-v4's
            // orthographic camera, too, moves the origin to the lens sample
            // itself (not beside the ray's own origin).
            let lens = self.lens_radius * sample_uniform_disk_concentric(u_lens);
            let focus = origin + dir * self.focal_distance;
            origin = Vec3::new(lens.x, lens.y, 0.0);
            dir = focus - origin;
        }
        let o = camera_to_world.transform_point3(origin);
        let d = camera_to_world.transform_vector3(dir).normalize();
        CameraRay { origin: o, direction: d, weight: 1.0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cropped frame's pixel traces the ray of the same pixel of the whole
    /// image.
    #[test]
    fn a_crop_traces_the_whole_images_rays() {
        let camera = Camera {
            camera_to_world: Mat4::from_rotation_translation(
                glam::Quat::from_rotation_y(0.3),
                Vec3::new(1.0, 2.0, -3.0),
            ),
            fov_degrees: 40.0,
            ..Camera::default()
        };
        let mut scene = atoll_scene::Scene::default();
        scene.settings.camera = camera.clone();
        scene.settings.film.resolution = glam::UVec2::new(64, 48);
        let whole = crate::RenderOptions::from_scene(&scene);
        scene.settings.film.crop_window = Some([0.25, 0.75, 0.5, 1.0]);
        let cropped = crate::RenderOptions::from_scene(&scene);
        assert_eq!(
            (cropped.resolution, cropped.crop),
            (glam::UVec2::new(32, 24), Some([0.25, 0.75, 0.5, 1.0]))
        );
        let (full, part) =
            (CameraRays::for_options(&camera, &whole), CameraRays::for_options(&camera, &cropped));
        for raster in [Vec2::new(0.5, 0.5), Vec2::new(31.9, 0.1), Vec2::new(10.25, 23.5)] {
            let (o1, d1) = full.ray(raster + Vec2::new(16.0, 24.0), Vec2::ZERO);
            let (o2, d2) = part.ray(raster, Vec2::ZERO);
            assert!(o1.distance(o2) < 1e-5 && d1.distance(d2) < 1e-5, "{raster}: {d1} against {d2}");
        }
    }

    /// An orthographic camera's rays are parallel to its +z and leave from
    /// the screen window, which pbrt makes from the frame's aspect ratio
    /// unless `screenwindow` gives it; a thin lens focuses them on the
    /// plane at the focal distance.
    #[test]
    fn orthographic_rays_are_parallel_and_leave_the_screen_window() {
        let turn =
            Mat4::from_rotation_translation(glam::Quat::from_rotation_x(0.4), Vec3::new(3.0, -1.0, 2.0));
        let forward = turn.transform_vector3(Vec3::Z);
        let mut camera =
            Camera { camera_to_world: turn, projection: Projection::Orthographic, ..Camera::default() };
        let rays = CameraRays::new(&camera, UVec2::new(200, 100));
        assert_eq!(rays.window(), (Vec2::new(-2.0, -1.0), Vec2::new(2.0, 1.0)), "the aspect ratio's frame");
        for (raster, local) in [
            (Vec2::new(0.0, 0.0), Vec2::new(-2.0, 1.0)),
            (Vec2::new(200.0, 100.0), Vec2::new(2.0, -1.0)),
            (Vec2::new(100.0, 50.0), Vec2::ZERO),
        ] {
            let (o, d) = rays.ray(raster, Vec2::new(0.7, 0.2));
            assert!(d.abs_diff_eq(forward, 1e-6), "{d}");
            let expected = turn.transform_point3(local.extend(0.0));
            assert!(o.abs_diff_eq(expected, 1e-5), "{raster}: {o} against {expected}");
        }
        // A screen window of its own; tall images keep the window.
        camera.screen_window = Some([-0.5, 1.5, 0.0, 4.0]);
        let rays = CameraRays::new(&camera, UVec2::new(10, 40));
        assert_eq!(rays.window(), (Vec2::new(-0.5, 0.0), Vec2::new(1.5, 4.0)));
        // Through a lens, rays of one raster position meet at the focal plane.
        camera.lens_radius = 0.3;
        camera.focal_distance = 5.0;
        let rays = CameraRays::new(&camera, UVec2::new(10, 40));
        let raster = Vec2::new(7.5, 12.5);
        let focus = turn.transform_point3(Vec3::new(-0.5 + 0.75 * 2.0, 4.0 - 12.5 / 40.0 * 4.0, 5.0));
        for u in [Vec2::new(0.1, 0.9), Vec2::new(0.6, 0.3)] {
            let (o, d) = rays.ray(raster, u);
            let t = (focus - o).dot(d);
            assert!((o + t * d).abs_diff_eq(focus, 1e-4), "lens sample {u}");
        }
    }

    /// A perspective camera's screen window is the frame's, or the one
    /// given, scaled by tan(fov / 2).
    #[test]
    fn perspective_screen_windows_scale_with_the_field_of_view() {
        let tan = (30.0f32).to_radians().tan();
        // Within an ulp or two: tan is not correctly rounded everywhere.
        let is = |rays: &CameraRays, (lo, hi): (Vec2, Vec2)| {
            let (min, max) = rays.window();
            assert!(min.abs_diff_eq(lo * tan, 1e-6) && max.abs_diff_eq(hi * tan, 1e-6), "{min} {max}");
        };
        let mut camera = Camera { fov_degrees: 60.0, ..Camera::default() };
        is(&CameraRays::new(&camera, UVec2::new(100, 200)), (Vec2::new(-1.0, -2.0), Vec2::new(1.0, 2.0)));
        camera.frame_aspect_ratio = Some(2.0);
        is(&CameraRays::new(&camera, UVec2::new(100, 200)), (Vec2::new(-2.0, -1.0), Vec2::new(2.0, 1.0)));
        camera.screen_window = Some([0.0, 1.0, -1.0, 0.0]);
        let rays = CameraRays::new(&camera, UVec2::new(100, 200));
        is(&rays, (Vec2::new(0.0, -1.0), Vec2::new(1.0, 0.0)));
        // The window's corner pixel looks along its corner.
        let (_, d) = rays.ray(Vec2::new(100.0, 200.0), Vec2::ZERO);
        assert!(d.abs_diff_eq(Vec3::new(tan, -tan, 1.0).normalize(), 1e-6), "{d}");
    }

    /// A spherical camera sees every direction from its origin, pole up:
    /// equirectangular rows run from +y down to -y, its centre looks along
    /// -x; the equal-area square's centre is the pole, its corners the
    /// other pole, and border samples past its edge fold back onto the sphere.
    #[test]
    fn spherical_rays_cover_the_sphere_pole_up() {
        let turn =
            Mat4::from_rotation_translation(glam::Quat::from_rotation_y(0.7), Vec3::new(1.0, 2.0, 3.0));
        let sphere = |mapping| Camera {
            camera_to_world: turn,
            projection: Projection::Spherical { mapping },
            ..Camera::default()
        };
        let world = |v: Vec3| turn.transform_vector3(v);
        let rays = CameraRays::new(&sphere(atoll_scene::EnvLayout::LatLong), UVec2::new(200, 100));
        for (raster, expected) in [
            (Vec2::new(100.0, 0.0), Vec3::Y),
            (Vec2::new(37.0, 100.0), -Vec3::Y),
            (Vec2::new(100.0, 50.0), -Vec3::X),
            (Vec2::new(50.0, 50.0), Vec3::Z),
        ] {
            let (o, d) = rays.ray(raster, Vec2::ZERO);
            assert!(o.abs_diff_eq(Vec3::new(1.0, 2.0, 3.0), 1e-6));
            assert!(d.abs_diff_eq(world(expected), 1e-5), "{raster}: {d}");
        }
        // A lens changes nothing.
        let rays = CameraRays::new(
            &Camera { lens_radius: 0.5, ..sphere(atoll_scene::EnvLayout::EqualArea) },
            UVec2::new(64, 64),
        );
        assert!(rays.ray(Vec2::new(32.0, 32.0), Vec2::ZERO).1.abs_diff_eq(world(Vec3::Y), 1e-6));
        assert!(rays.ray(Vec2::new(0.0, 64.0), Vec2::ZERO).1.abs_diff_eq(world(-Vec3::Y), 1e-6));
        // Just past the left edge is just inside it, mirrored top to bottom.
        let (_, outside) = rays.ray(Vec2::new(-0.5, 10.0), Vec2::ZERO);
        let (_, inside) = rays.ray(Vec2::new(0.5, 54.0), Vec2::ZERO);
        assert!(outside.abs_diff_eq(inside, 1e-5), "{outside} vs {inside}");
    }
}
