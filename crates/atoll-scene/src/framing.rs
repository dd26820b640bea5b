//! Defaults for files that say nothing about how to render them (OBJ, PLY,
//! OFF, and glTF files without a camera or lights): a camera that frames the
//! world bounds, render settings, and a sky with a sun.
//!
//! The choices, and why:
//! - **Camera**: looks at the centre of the world bounds from the direction
//!   [`VIEW_DIRECTION`] (right, a little above and in front, for a +Y-up
//!   model), with a 40° field of view. The distance puts the bounding sphere
//!   at 80% of the view's shorter axis, so the model fills about that much
//!   whatever its shape. +Y is taken as up because OBJ, PLY and glTF content
//!   almost always is (glTF requires it). The camera is not mirrored: world
//!   +X appears on the right when looking down -Z, as in any viewer of these
//!   formats (pbrt's `LookAt` would mirror a right-handed scene).
//! - **Settings**: 1024×768, 64 samples per pixel, path depth 8: enough
//!   bounces for glass and metal, cheap enough for a first look.
//! - **Lights** (only when the file has none, emissive surfaces included): a
//!   uniform sky of radiance [`SKY_RADIANCE`] lights every side so no part of
//!   the model is black, and a distant "sun" of radiance [`SUN_RADIANCE`]
//!   from the camera's upper left adds shadows and shading, so shapes read.

use glam::{Mat4, UVec2, Vec3};

use crate::{Camera, IntegratorSettings, Light, RenderSettings, Rgb, Scene};

/// The direction from the model's centre towards the default camera.
pub const VIEW_DIRECTION: Vec3 = Vec3::new(1.0, 0.6, 1.5);
/// Field of view of the default camera, in degrees (spans the shorter axis).
pub const FOV_DEGREES: f32 = 40.0;
/// Share of the view's shorter axis the bounding sphere covers.
pub const FILL: f32 = 0.8;
/// Default image size.
pub const RESOLUTION: UVec2 = UVec2::new(1024, 768);
/// Default samples per pixel.
pub const SPP: u32 = 64;
/// Default maximum path depth.
pub const MAX_DEPTH: u32 = 8;
/// Radiance of the default sky.
pub const SKY_RADIANCE: f32 = 1.0;
/// Radiance of the default sun (irradiance on a surface facing it).
pub const SUN_RADIANCE: f32 = 3.0;
/// Where the default sun is, seen from the model (unnormalised): above, to
/// the left of the default camera and towards it.
pub const SUN_FROM: Vec3 = Vec3::new(-1.0, 2.3, 1.75);

/// The render settings for files that have none.
pub fn default_settings() -> RenderSettings {
    RenderSettings {
        camera: Camera { fov_degrees: FOV_DEGREES, ..Default::default() },
        film: crate::FilmSettings { resolution: RESOLUTION, ..Default::default() },
        spp: SPP,
        integrator: IntegratorSettings::Path { max_depth: MAX_DEPTH },
        light_sampler: Default::default(),
        camera_medium: crate::VACUUM,
    }
}

/// Camera-to-world for a camera at `eye` looking at `target` with `up` as
/// the world's up, in atoll's camera space (+x right on the image, +y up,
/// +z forward) without mirroring the image. `None` when `eye == target` or
/// the view direction is parallel to `up`.
pub fn look_at(eye: Vec3, target: Vec3, up: Vec3) -> Option<Mat4> {
    let forward = (target - eye).try_normalize()?;
    // In a right-handed world, forward × up points to the viewer's right.
    let right = forward.cross(up).try_normalize()?;
    let true_up = right.cross(forward);
    Some(Mat4::from_cols(right.extend(0.0), true_up.extend(0.0), forward.extend(0.0), eye.extend(1.0)))
}

/// A camera that frames the box `bounds` (see the module docs); the default
/// camera for an empty scene.
pub fn framing_camera(bounds: Option<(Vec3, Vec3)>) -> Camera {
    let mut camera = Camera { fov_degrees: FOV_DEGREES, ..Default::default() };
    let Some((lo, hi)) = bounds else { return camera };
    let centre = (lo + hi) * 0.5;
    // A flat or point-like model still needs a positive distance.
    let radius = ((hi - lo).length() * 0.5).max(1e-3 * centre.abs().max_element()).max(1e-6);
    let half_angle = (FOV_DEGREES * 0.5 * FILL).to_radians();
    let distance = radius / half_angle.sin();
    let eye = centre + VIEW_DIRECTION.normalize() * distance;
    if let Some(m) = look_at(eye, centre, Vec3::Y) {
        camera.camera_to_world = m;
    }
    camera
}

/// The default sky and sun (see the module docs).
pub fn default_lights() -> Vec<Light> {
    vec![
        Light::Infinite { radiance: Rgb::splat(SKY_RADIANCE), portal: None },
        Light::Distant { direction: -SUN_FROM.normalize(), radiance: Rgb::splat(SUN_RADIANCE) },
    ]
}

/// Gives a scene from a file without render settings the defaults: settings,
/// a framing camera when `frame_camera` (otherwise the camera is kept), and
/// the sky and sun when the scene has no light at all.
pub fn frame_scene(scene: &mut Scene, frame_camera: bool) {
    let camera =
        if frame_camera { framing_camera(scene.world_bounds()) } else { scene.settings.camera.clone() };
    scene.settings = RenderSettings { camera, ..default_settings() };
    let emissive = scene.meshes.iter().any(|m| m.emission.is_some());
    if scene.lights.is_empty() && !emissive {
        scene.lights = default_lights();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn framing_camera_looks_at_the_centre_and_fits_the_model() {
        let (lo, hi) = (Vec3::new(-1.0, 0.0, -2.0), Vec3::new(3.0, 2.0, 2.0));
        let cam = framing_camera(Some((lo, hi)));
        let eye = cam.camera_to_world.transform_point3(Vec3::ZERO);
        let forward = cam.camera_to_world.transform_vector3(Vec3::Z);
        let centre = Vec3::new(1.0, 1.0, 0.0);
        assert!((forward - (centre - eye).normalize()).length() < 1e-5);
        assert!((eye - centre).normalize().dot(VIEW_DIRECTION.normalize()) > 0.9999);
        // The bounding sphere subtends 80% of the 40° field of view.
        let radius = (hi - lo).length() * 0.5;
        let subtended = 2.0 * (radius / (eye - centre).length()).asin().to_degrees();
        assert!((subtended - FILL * FOV_DEGREES).abs() < 1e-3, "{subtended}");
        // Not mirrored: camera +x is the viewer's right, camera +y world up.
        let right = cam.camera_to_world.transform_vector3(Vec3::X);
        let up = cam.camera_to_world.transform_vector3(Vec3::Y);
        assert!(right.cross(up).dot(-forward) > 0.99, "right × up must point back at the viewer");
        assert!(up.y > 0.0);
    }

    #[test]
    fn look_at_down_negative_z_keeps_x_to_the_right() {
        let m = look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y).unwrap();
        assert!((m.transform_vector3(Vec3::X) - Vec3::X).length() < 1e-6);
        assert!((m.transform_vector3(Vec3::Y) - Vec3::Y).length() < 1e-6);
        assert!((m.transform_vector3(Vec3::Z) + Vec3::Z).length() < 1e-6);
        assert!(look_at(Vec3::ZERO, Vec3::Y, Vec3::Y).is_none());
    }

    #[test]
    fn frame_scene_adds_lights_only_to_dark_scenes() {
        let mut s = Scene::default();
        frame_scene(&mut s, true);
        assert_eq!(s.lights, default_lights());
        assert_eq!((s.settings.spp, s.settings.film.resolution), (SPP, RESOLUTION));
        assert_eq!(s.settings.integrator, IntegratorSettings::Path { max_depth: MAX_DEPTH });
        let mut lit = Scene::default();
        lit.lights.push(Light::Point { position: Vec3::ZERO, intensity: Rgb::ONE });
        frame_scene(&mut lit, true);
        assert_eq!(lit.lights.len(), 1);
    }
}
