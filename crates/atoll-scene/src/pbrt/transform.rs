//! pbrt-v4's transformation directives as matrices (`util/transform.cpp`).
//! Kept in f64 while the file is read so long chains of statements do not
//! accumulate f32 rounding; the scene stores f32.

use glam::{DMat3, DMat4, DVec3, DVec4, Mat4};

/// `Rotate angle x y z`: right-handed rotation by `degrees` about `axis`.
/// `None` when the axis is zero.
pub fn rotate(degrees: f64, axis: DVec3) -> Option<DMat4> {
    let a = axis.try_normalize()?;
    Some(DMat4::from_axis_angle(a, degrees.to_radians()))
}

/// Why a `LookAt` gives no camera orientation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LookAtError {
    #[error("LookAt: eye and look-at point are the same")]
    SamePoint,
    #[error("LookAt: the up vector is zero")]
    ZeroUp,
    #[error("LookAt: the up vector and the viewing direction are parallel")]
    UpParallel,
}

/// `LookAt`: the camera-from-world matrix of a camera at `eye` looking at
/// `look`, with pbrt's left-handed camera space (+x right, +y up, +z forward).
/// Errors when `up` is parallel to the viewing direction.
pub fn look_at(eye: DVec3, look: DVec3, up: DVec3) -> Result<DMat4, LookAtError> {
    let dir = (look - eye).try_normalize().ok_or(LookAtError::SamePoint)?;
    let up = up.try_normalize().ok_or(LookAtError::ZeroUp)?;
    let right = up.cross(dir).try_normalize().ok_or(LookAtError::UpParallel)?;
    let new_up = dir.cross(right);
    let world_from_camera =
        DMat4::from_cols(right.extend(0.0), new_up.extend(0.0), dir.extend(0.0), eye.extend(1.0));
    Ok(world_from_camera.inverse())
}

/// `Transform`/`ConcatTransform`: pbrt reads the 16 numbers as a row-major
/// matrix and transposes it, so the file lists the matrix column by column.
pub fn from_pbrt_numbers(m: &[f64; 16]) -> DMat4 {
    DMat4::from_cols_array(m)
}

/// True when the transform mirrors space (pbrt's `SwapsHandedness`).
pub fn swaps_handedness(m: &DMat4) -> bool {
    DMat3::from_mat4(*m).determinant() < 0.0
}

/// The f32 matrix the scene stores.
pub fn to_f32(m: &DMat4) -> Mat4 {
    m.as_mat4()
}

/// Applies `m` to a point (homogeneous divide included, as pbrt does).
pub fn point(m: &DMat4, p: DVec3) -> DVec3 {
    let h = *m * DVec4::new(p.x, p.y, p.z, 1.0);
    if h.w == 1.0 || h.w == 0.0 {
        h.truncate()
    } else {
        h.truncate() / h.w
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotate_z_maps_x_to_y() {
        let r = rotate(90.0, DVec3::Z).unwrap();
        assert!((r.transform_vector3(DVec3::X) - DVec3::Y).length() < 1e-12);
        assert!(rotate(10.0, DVec3::ZERO).is_none());
    }

    #[test]
    fn look_at_places_the_camera() {
        let cam_from_world =
            look_at(DVec3::new(0.0, 1.0, -3.9), DVec3::new(0.0, 1.0, 0.0), DVec3::Y).unwrap();
        let world_from_cam = cam_from_world.inverse();
        assert!((point(&world_from_cam, DVec3::ZERO) - DVec3::new(0.0, 1.0, -3.9)).length() < 1e-12);
        assert!((world_from_cam.transform_vector3(DVec3::Z) - DVec3::Z).length() < 1e-12);
        assert!((world_from_cam.transform_vector3(DVec3::X) - DVec3::X).length() < 1e-12);
        assert_eq!(look_at(DVec3::ZERO, DVec3::Y, DVec3::Y), Err(LookAtError::UpParallel));
        assert_eq!(look_at(DVec3::Y, DVec3::Y, DVec3::X), Err(LookAtError::SamePoint));
    }

    #[test]
    fn matrices_are_column_major_in_files() {
        let m = from_pbrt_numbers(&[1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 5., 6., 7., 1.]);
        assert_eq!(point(&m, DVec3::ZERO), DVec3::new(5.0, 6.0, 7.0));
        assert!(swaps_handedness(&DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0))));
        assert!(!swaps_handedness(&DMat4::from_scale(DVec3::new(-1.0, -1.0, 1.0))));
    }
}
