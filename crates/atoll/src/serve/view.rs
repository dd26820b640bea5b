//! The viewer's camera: orbit about a point in front of the camera, pan,
//! and dolly towards it, starting from the scene's own camera and keeping
//! its field of view, lens and handedness (pbrt scenes often mirror the
//! camera with `Scale -1 1 1`). An orthographic camera sees the same
//! picture from any distance, so its dolly zooms: it scales the screen
//! window.

use atoll_scene::{Camera, Projection};
use glam::{Mat4, Quat, UVec2, Vec3};

/// A camera looking at `target` from `distance` away along `-forward`.
#[derive(Clone, Debug, PartialEq)]
pub struct Orbit {
    template: Camera,
    target: Vec3,
    distance: f32,
    /// Unit view direction.
    forward: Vec3,
    /// What orbiting keeps up: the scene camera's up.
    up: Vec3,
    /// +1 for pbrt's left-handed camera space, -1 where the scene mirrors it.
    handedness: f32,
    /// An orthographic view's screen window relative to the scene's: the
    /// product of its dollies' scales (1 for other projections).
    zoom: f32,
}

/// One change of the view, as the page sends it. Angles in radians;
/// pans in fractions of the view's height; dolly as a power of e (positive
/// moves closer).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Move {
    pub yaw: f32,
    pub pitch: f32,
    pub pan_x: f32,
    pub pan_y: f32,
    pub dolly: f32,
}

/// How close orbiting may come to looking straight up or down.
const POLE_MARGIN: f32 = 0.02;

impl Orbit {
    /// The orbit of `camera` rendering `resolution` pixels, about the point
    /// in front of it at the depth of the scene's centre (`bounds`), or half
    /// the scene's size away when the centre is behind it.
    pub fn new(camera: &Camera, resolution: UVec2, bounds: Option<(Vec3, Vec3)>) -> Orbit {
        let m = camera.camera_to_world;
        let eye = m.transform_point3(Vec3::ZERO);
        let forward = m.transform_vector3(Vec3::Z).normalize_or(Vec3::Z);
        let up = m.transform_vector3(Vec3::Y).normalize_or(Vec3::Y);
        let right = m.transform_vector3(Vec3::X);
        let handedness = if right.dot(up.cross(forward)) < 0.0 { -1.0 } else { 1.0 };
        let (centre, size) =
            bounds.map_or((eye + forward, 1.0), |(lo, hi)| ((lo + hi) * 0.5, (hi - lo).length()));
        let depth = (centre - eye).dot(forward);
        let distance = if depth > 1e-3 * size.max(1e-6) { depth } else { (0.5 * size).max(1e-3) };
        let mut template = camera.clone();
        if template.projection == Projection::Orthographic {
            // The window resolved once, so that zooming scales what was seen.
            template.screen_window = Some(camera.screen_window(resolution));
        }
        Orbit { template, target: eye + forward * distance, distance, forward, up, handedness, zoom: 1.0 }
    }

    /// Whether dollies zoom (scale the screen window) instead of moving.
    fn zooms(&self) -> bool {
        self.template.projection == Projection::Orthographic
    }

    /// The view after `step`.
    pub fn moved(&self, step: Move) -> Orbit {
        let mut next = self.clone();
        // Yaw about the kept up; pitch about the camera's right, stopping
        // short of the poles.
        let yawed = Quat::from_axis_angle(self.up, step.yaw) * self.forward;
        let elevation = yawed.dot(self.up).clamp(-1.0, 1.0).asin();
        let limit = std::f32::consts::FRAC_PI_2 - POLE_MARGIN;
        let pitch = (elevation + step.pitch).clamp(-limit, limit) - elevation;
        let right = self.up.cross(yawed).normalize_or(Vec3::X);
        next.forward = (Quat::from_axis_angle(right, -pitch) * yawed).normalize();
        // Pans scale with the visible height at the target.
        let height = match self.template.screen_window {
            Some([_, _, y0, y1]) if self.zooms() => (y1 - y0) * self.zoom,
            _ => 2.0 * self.distance * (0.5 * self.template.fov_degrees.to_radians()).tan(),
        };
        let (right, up) = self.basis();
        next.target += (right * step.pan_x + up * step.pan_y) * height;
        if self.zooms() {
            next.zoom = (self.zoom * (-step.dolly).exp()).max(1e-6);
        } else {
            next.distance = (self.distance * (-step.dolly).exp()).max(1e-4);
        }
        next
    }

    /// The camera's right and up for the current view.
    fn basis(&self) -> (Vec3, Vec3) {
        let right = self.up.cross(self.forward).normalize_or(Vec3::X);
        (right, self.forward.cross(right))
    }

    /// The camera of this view.
    pub fn camera(&self) -> Camera {
        let (right, up) = self.basis();
        let eye = self.target - self.forward * self.distance;
        let camera_to_world = Mat4::from_cols(
            (right * self.handedness).extend(0.0),
            up.extend(0.0),
            self.forward.extend(0.0),
            eye.extend(1.0),
        );
        let screen_window = match self.template.screen_window {
            Some([x0, x1, y0, y1]) if self.zooms() => {
                let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
                let z = 0.5 * self.zoom;
                Some([cx - z * (x1 - x0), cx + z * (x1 - x0), cy - z * (y1 - y0), cy + z * (y1 - y0)])
            }
            window => window,
        };
        // A view moved by hand stays where it is put: a moving camera's motion is dropped.
        Camera { camera_to_world, screen_window, motion: None, ..self.template.clone() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn look_at(eye: Vec3, target: Vec3, mirrored: bool) -> Camera {
        let forward = (target - eye).normalize();
        let right = Vec3::Y.cross(forward).normalize();
        let up = forward.cross(right);
        let sign = if mirrored { -1.0 } else { 1.0 };
        let m =
            Mat4::from_cols((right * sign).extend(0.0), up.extend(0.0), forward.extend(0.0), eye.extend(1.0));
        Camera { camera_to_world: m, fov_degrees: 40.0, ..Camera::default() }
    }

    fn close(a: Mat4, b: Mat4) -> bool {
        a.abs_diff_eq(b, 1e-4)
    }

    const RES: UVec2 = UVec2::new(320, 240);

    /// An orthographic view zooms instead of moving: dolly scales the
    /// screen window about its centre, and pans follow the window's height.
    #[test]
    fn orthographic_dollies_zoom() {
        let camera = Camera {
            projection: Projection::Orthographic,
            ..look_at(Vec3::new(0.0, 0.0, -4.0), Vec3::ZERO, false)
        };
        let orbit = Orbit::new(&camera, RES, Some((Vec3::splat(-1.0), Vec3::splat(1.0))));
        assert_eq!(orbit.camera().screen_window, Some([-4.0 / 3.0, 4.0 / 3.0, -1.0, 1.0]));
        let closer = orbit.moved(Move { dolly: 2.0_f32.ln(), ..Move::default() });
        assert_eq!(closer.distance, orbit.distance);
        let [x0, x1, y0, y1] = closer.camera().screen_window.unwrap();
        assert!((x1 - x0 - 4.0 / 3.0).abs() < 1e-5 && (y1 - y0 - 1.0).abs() < 1e-5, "{x0} {x1} {y0} {y1}");
        assert!((x0 + x1).abs() < 1e-6 && (y0 + y1).abs() < 1e-6);
        let panned = closer.moved(Move { pan_y: 0.5, ..Move::default() });
        assert!((panned.target.y - 0.5).abs() < 1e-5, "half of a window 1 high: {}", panned.target);
    }

    #[test]
    fn no_move_keeps_the_scene_camera_mirrored_or_not() {
        let bounds = Some((Vec3::splat(-1.0), Vec3::splat(1.0)));
        for mirrored in [false, true] {
            let camera = look_at(Vec3::new(0.0, 1.0, -5.0), Vec3::ZERO, mirrored);
            let orbit = Orbit::new(&camera, RES, bounds);
            assert!(close(orbit.camera().camera_to_world, camera.camera_to_world), "mirrored {mirrored}");
            assert!(close(orbit.moved(Move::default()).camera().camera_to_world, camera.camera_to_world));
        }
    }

    #[test]
    fn orbiting_keeps_the_target_and_distance_and_stops_at_the_poles() {
        let camera = look_at(Vec3::new(0.0, 0.0, -4.0), Vec3::ZERO, false);
        let orbit = Orbit::new(&camera, RES, Some((Vec3::splat(-1.0), Vec3::splat(1.0))));
        let quarter = orbit.moved(Move { yaw: std::f32::consts::FRAC_PI_2, ..Move::default() });
        let eye = quarter.camera().camera_to_world.transform_point3(Vec3::ZERO);
        assert!((eye.length() - 4.0).abs() < 1e-4, "{eye}");
        assert!(eye.z.abs() < 1e-4 && eye.x.abs() > 3.9, "a quarter turn about +y: {eye}");
        let over = orbit.moved(Move { pitch: 10.0, ..Move::default() });
        let up = over.forward.dot(Vec3::Y).abs();
        assert!(up < 1.0 && up > 0.99, "stops short of straight up: {up}");
        let m = over.camera().camera_to_world;
        assert!(m.x_axis.truncate().is_normalized() && m.y_axis.truncate().is_normalized());
    }

    #[test]
    fn pans_move_the_target_and_dollies_the_distance() {
        let camera = look_at(Vec3::new(0.0, 0.0, -4.0), Vec3::ZERO, false);
        let orbit = Orbit::new(&camera, RES, Some((Vec3::splat(-1.0), Vec3::splat(1.0))));
        let panned = orbit.moved(Move { pan_x: 0.5, ..Move::default() });
        assert!(panned.target.x.abs() > 0.1 && panned.target.y.abs() < 1e-5, "{}", panned.target);
        assert_eq!(panned.distance, orbit.distance);
        let closer = orbit.moved(Move { dolly: 1.0, ..Move::default() });
        assert!((closer.distance - 4.0 / std::f32::consts::E).abs() < 1e-4);
        assert_eq!(closer.target, orbit.target);
    }

    #[test]
    fn a_centre_behind_the_camera_orbits_half_the_scene_away() {
        let camera = look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::new(0.0, 0.0, 10.0), false);
        let orbit = Orbit::new(&camera, RES, Some((Vec3::splat(-1.0), Vec3::splat(1.0))));
        assert!((orbit.distance - Vec3::splat(2.0).length() * 0.5).abs() < 1e-5);
    }
}
