//! Camera, film and the render settings a scene file carries.

use glam::{Mat4, UVec2};

/// pbrt-style perspective camera. Camera space is left-handed: +x right,
/// +y up, +z forward (pbrt-v4's convention).
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Camera space to world space (the inverse of the CTM at `Camera`).
    pub camera_to_world: Mat4,
    /// Field of view in degrees, spanning the shorter image axis (pbrt's rule).
    pub fov_degrees: f32,
    /// Thin-lens aperture radius; 0 is a pinhole.
    pub lens_radius: f32,
    /// Distance to the plane in focus (used only when `lens_radius > 0`).
    pub focal_distance: f32,
}

impl Default for Camera {
    fn default() -> Self {
        Camera { camera_to_world: Mat4::IDENTITY, fov_degrees: 90.0, lens_radius: 0.0, focal_distance: 1e6 }
    }
}

/// Image size and output.
#[derive(Clone, Debug, PartialEq)]
pub struct FilmSettings {
    pub resolution: UVec2,
    /// Output file named by the scene (`Film "string filename"`).
    pub filename: Option<String>,
}

impl FilmSettings {
    /// Most pixels a frame may have: its film alone is 12 bytes a pixel,
    /// and every device keeps one (16384 × 16384 is 3 GiB).
    pub const MAX_PIXELS: u64 = 1 << 28;

    /// Refuses a resolution of no pixels or of more than [`Self::MAX_PIXELS`].
    pub fn check_resolution(x: u64, y: u64) -> Result<UVec2, String> {
        if x == 0 || y == 0 {
            return Err(format!("resolution {x}x{y}: must be at least 1x1"));
        }
        match x.checked_mul(y) {
            Some(pixels) if pixels <= Self::MAX_PIXELS => Ok(UVec2::new(x as u32, y as u32)),
            _ => {
                Err(format!("resolution {x}x{y}: more than the {} pixels a frame may have", Self::MAX_PIXELS))
            }
        }
    }
}

/// Width and height of the tiles paths are generated in (a warp's 32).
pub const PIXEL_TILE: [u32; 2] = [8, 4];

/// The pixel (row-major index) at place `ordinal` of the order a frame's
/// camera paths are made in: bands of [`PIXEL_TILE`] rows top to bottom,
/// each cut into tiles left to right (the last band and the last tile of a
/// band smaller where the frame does not divide), a tile's pixels row by
/// row. 32 consecutive paths then cover an 8×4 tile rather than a strip of
/// one row, so a warp's camera rays are coherent. A bijection of
/// `0..x * y` for every resolution.
pub fn tile_order_pixel(ordinal: u32, resolution: UVec2) -> u32 {
    let [tile_w, tile_h] = PIXEL_TILE.map(u64::from);
    let (res_x, res_y, i) = (u64::from(resolution.x), u64::from(resolution.y), u64::from(ordinal));
    let y0 = i / (res_x * tile_h) * tile_h;
    let h = tile_h.min(res_y - y0);
    let j = i - y0 * res_x;
    let x0 = j / (tile_w * h) * tile_w;
    let w = tile_w.min(res_x - x0);
    let k = j - x0 * h;
    ((y0 + k / w) * res_x + x0 + k % w) as u32
}

impl Default for FilmSettings {
    fn default() -> Self {
        // pbrt-v4's defaults.
        FilmSettings { resolution: UVec2::new(1280, 720), filename: None }
    }
}

/// Which light transport algorithm to run.
#[derive(Clone, Debug, PartialEq)]
pub enum IntegratorSettings {
    /// Unidirectional path tracing with next-event estimation and MIS.
    Path { max_depth: u32 },
    /// Ambient occlusion: the fraction of the cosine-weighted hemisphere that
    /// is unoccluded within `max_distance` (pbrt's `ambientocclusion`).
    AmbientOcclusion { max_distance: f32 },
}

impl Default for IntegratorSettings {
    fn default() -> Self {
        IntegratorSettings::Path { max_depth: 5 }
    }
}

impl std::fmt::Display for IntegratorSettings {
    /// As reports print it: `path, max depth 5`, `ambient occlusion, max distance 2`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            IntegratorSettings::Path { max_depth } => write!(f, "path, max depth {max_depth}"),
            IntegratorSettings::AmbientOcclusion { max_distance } => {
                write!(f, "ambient occlusion, max distance {max_distance}")
            }
        }
    }
}

/// How next-event estimation picks a light (pbrt-v4's `lightsampler`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LightSampler {
    /// In proportion to each light's power, the same everywhere.
    Power,
    /// By each light's estimated contribution at the shading point, from a
    /// BVH over the lights' bounds (pbrt-v4's default).
    #[default]
    Bvh,
}

/// Everything about *how* to render that the scene file can say.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderSettings {
    pub camera: Camera,
    pub film: FilmSettings,
    /// Samples per pixel (`Sampler "integer pixelsamples"`).
    pub spp: u32,
    pub integrator: IntegratorSettings,
    /// `Integrator "string lightsampler"`.
    pub light_sampler: LightSampler,
}

#[cfg(test)]
mod tile_order_tests {
    use super::*;

    #[test]
    fn tile_order_is_a_bijection_for_every_shape() {
        for (x, y) in [(1, 1), (1, 7), (7, 1), (8, 4), (9, 5), (16, 8), (33, 17), (640, 360), (1921, 1081)] {
            let res = UVec2::new(x, y);
            let mut seen = vec![false; (x * y) as usize];
            for i in 0..x * y {
                let p = tile_order_pixel(i, res) as usize;
                assert!(p < seen.len() && !seen[p], "{x}x{y}: ordinal {i} gives pixel {p} again or outside");
                seen[p] = true;
            }
        }
    }

    #[test]
    fn warps_cover_tiles() {
        let res = UVec2::new(20, 9);
        let at = |i| {
            let p = tile_order_pixel(i, res);
            (p % res.x, p / res.x)
        };
        // The first tile, row by row, then the next tile to its right.
        assert_eq!(
            (0..10).map(at).collect::<Vec<_>>()[..9],
            [(0, 0), (1, 0), (2, 0), (3, 0), (4, 0), (5, 0), (6, 0), (7, 0), (0, 1)]
        );
        assert_eq!(at(31), (7, 3));
        assert_eq!(at(32), (8, 0));
        // The band's last tile is 4 wide; the last band is 1 row high.
        assert_eq!(at(64), (16, 0));
        assert_eq!(at(68), (16, 1));
        assert_eq!(at(20 * 8), (0, 8));
        assert_eq!(at(20 * 9 - 1), (19, 8));
    }
}
