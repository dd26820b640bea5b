//! Camera, film and the render settings a scene file carries.

use glam::{Mat3, Mat4, UVec2, Vec3};

/// pbrt-style camera (perspective, orthographic or spherical). Camera
/// space is left-handed: +x right, +y up, +z forward (pbrt-v4's convention).
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Camera space to world space (the inverse of the CTM at `Camera`).
    pub camera_to_world: Mat4,
    pub projection: Projection,
    /// Field of view in degrees, spanning the shorter side of the screen
    /// window (pbrt's rule); perspective cameras only.
    pub fov_degrees: f32,
    /// Thin-lens aperture radius; 0 is a pinhole.
    pub lens_radius: f32,
    /// Distance to the plane in focus (used only when `lens_radius > 0`).
    pub focal_distance: f32,
    /// pbrt's `screenwindow`: (x min, x max, y min, y max) of the image on
    /// the screen, before a perspective camera's fov scales it. `None`: from
    /// the frame's aspect ratio ([`Camera::screen_window`]).
    pub screen_window: Option<[f32; 4]>,
    /// pbrt's `frameaspectratio`; `None`: the image's width over its height.
    pub frame_aspect_ratio: Option<f32>,
    /// The lens system of a [`Projection::Realistic`] camera, focused.
    pub lens: Option<std::sync::Arc<crate::lens::LensSystem>>,
    /// pbrt's `shutteropen` and `shutterclose`: the times rays are traced
    /// at, spread evenly over them (what moves is blurred over them).
    pub shutter: [f32; 2],
    /// A moving camera's camera-to-world motion (`camera_to_world` is then
    /// its start).
    pub motion: Option<crate::Motion>,
}

/// How camera space maps onto the screen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Projection {
    /// Rays fan out from the origin through the screen at z = 1, scaled by
    /// the field of view.
    #[default]
    Perspective,
    /// Parallel rays along +z, leaving from the screen window at z = 0 (its
    /// units are camera-space lengths).
    Orthographic,
    /// Every direction from the origin: the image is the sphere of
    /// directions laid out by `mapping` (pbrt's `spherical` camera; its
    /// pole is camera +y).
    Spherical { mapping: crate::EnvLayout },
    /// pbrt-v4's `realistic` camera: rays from the physical film through
    /// the lens system [`Camera::lens`] (its own ray generation:
    /// [`crate::lens::LensSystem::ray`]).
    Realistic,
}

impl Projection {
    /// The camera-space pinhole ray (origin, direction; not normalised)
    /// through point `screen` of the camera's window: at z = 1 for a
    /// perspective camera (its window scaled by tan(fov/2)), at z = 0 for
    /// an orthographic one, and for a spherical one the direction at
    /// (u, v) = (x, −y) of its mapping, pole up (pbrt-v4's swap of y and z).
    pub fn camera_ray(self, screen: glam::Vec2) -> (Vec3, Vec3) {
        match self {
            Projection::Perspective => (Vec3::ZERO, screen.extend(1.0)),
            Projection::Orthographic => (screen.extend(0.0), Vec3::Z),
            // Only its film point: the lens makes the ray.
            Projection::Realistic => (screen.extend(0.0), Vec3::Z),
            Projection::Spherical { mapping } => {
                let uv = glam::Vec2::new(screen.x, -screen.y);
                let uv = match mapping {
                    crate::EnvLayout::EqualArea => crate::environment::wrap_equal_area_square(uv),
                    crate::EnvLayout::LatLong => uv,
                };
                let d = mapping.direction(uv);
                (Vec3::ZERO, Vec3::new(d.x, d.z, d.y))
            }
        }
    }
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            camera_to_world: Mat4::IDENTITY,
            projection: Projection::Perspective,
            fov_degrees: 90.0,
            lens_radius: 0.0,
            focal_distance: 1e6,
            screen_window: None,
            frame_aspect_ratio: None,
            lens: None,
            shutter: [0.0, 1.0],
            motion: None,
        }
    }
}

impl Camera {
    /// The time of a ray whose uniform sample is `u` ∈ [0, 1).
    pub fn time(&self, u: f32) -> f32 {
        let [open, close] = self.shutter;
        open + (close - open) * u
    }
}

impl Camera {
    /// The screen window of an image of `resolution` as pbrt-v4 makes it:
    /// the shorter side spans [-1, 1] and the other keeps the frame's
    /// aspect ratio, unless `screenwindow` gives it. (x min, x max, y min,
    /// y max).
    /// A spherical camera's window is its square of directions, as
    /// (u, −v): [0, 1] × [−1, 0] (so that a crop cuts it as it cuts the
    /// others; see [`Projection::camera_ray`]).
    pub fn screen_window(&self, resolution: UVec2) -> [f32; 4] {
        if let Projection::Spherical { .. } = self.projection {
            return [0.0, 1.0, -1.0, 0.0];
        }
        if let Some(window) = self.screen_window {
            return window;
        }
        let frame = self.frame_aspect_ratio.unwrap_or(resolution.x as f32 / resolution.y as f32);
        if frame > 1.0 {
            [-frame, frame, -1.0, 1.0]
        } else {
            [-1.0, 1.0, -1.0 / frame, 1.0 / frame]
        }
    }
}

/// Image size and output.
#[derive(Clone, Debug, PartialEq)]
pub struct FilmSettings {
    pub resolution: UVec2,
    /// Output file named by the scene (`Film "string filename"`).
    pub filename: Option<String>,
    /// The part of the image rendered, pbrt's `cropwindow`: (x min, x max,
    /// y min, y max) as fractions of the image, y down. `None`: all of it.
    pub crop_window: Option<[f32; 4]>,
    /// How the film turns radiance into pixel values.
    pub sensor: Sensor,
    /// How samples around a pixel make its value.
    pub filter: PixelFilter,
    /// The physical film's diagonal in metres (pbrt's `diagonal`, given in
    /// millimetres): a realistic camera's film size.
    pub diagonal: f32,
}

/// pbrt-v4's pixel filters. Each is a product of one function per axis,
/// nonzero within `radius` pixels of the pixel's centre; `Mitchell` and
/// `LanczosSinc` have negative lobes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PixelFilter {
    /// 1 within the radius (0.5: the pixel's own square).
    Box { radius: glam::Vec2 },
    /// A Gaussian of standard deviation `sigma`, less its value at the
    /// radius (radius 1.5, sigma 0.5).
    Gaussian { radius: glam::Vec2, sigma: f32 },
    /// Mitchell and Netravali's cubic of parameters B and C over the
    /// radius (radius 2, B = C = 1/3).
    Mitchell { radius: glam::Vec2, b: f32, c: f32 },
    /// `sinc(x) sinc(x / tau)` within the radius (radius 4, tau 3).
    LanczosSinc { radius: glam::Vec2, tau: f32 },
    /// A tent falling to 0 at the radius (radius 2).
    Triangle { radius: glam::Vec2 },
}

impl PixelFilter {
    /// The pixel's own square: every sample lands in its pixel, weighted alike.
    pub const PIXEL: PixelFilter = PixelFilter::Box { radius: glam::Vec2::splat(0.5) };

    /// pbrt-v4's default filter (its `gaussian`).
    pub const PBRT_DEFAULT: PixelFilter =
        PixelFilter::Gaussian { radius: glam::Vec2::splat(1.5), sigma: 0.5 };

    pub fn radius(&self) -> glam::Vec2 {
        match *self {
            PixelFilter::Box { radius }
            | PixelFilter::Gaussian { radius, .. }
            | PixelFilter::Mitchell { radius, .. }
            | PixelFilter::LanczosSinc { radius, .. }
            | PixelFilter::Triangle { radius } => radius,
        }
    }

    /// The filter's factor along `axis` (0: x, 1: y) at offset `x` pixels
    /// from the pixel's centre (pbrt-v4's definitions).
    pub fn along(&self, axis: usize, x: f32) -> f32 {
        let r = self.radius()[axis];
        if x.abs() > r {
            return 0.0;
        }
        match *self {
            PixelFilter::Box { .. } => 1.0,
            PixelFilter::Gaussian { sigma, .. } => (gaussian(x, sigma) - gaussian(r, sigma)).max(0.0),
            PixelFilter::Mitchell { b, c, .. } => mitchell(2.0 * x / r, b, c),
            PixelFilter::LanczosSinc { tau, .. } => sinc(x) * sinc(x / tau),
            PixelFilter::Triangle { .. } => (r - x.abs()).max(0.0),
        }
    }
}

impl Default for PixelFilter {
    fn default() -> Self {
        PixelFilter::PIXEL
    }
}

fn gaussian(x: f32, sigma: f32) -> f32 {
    (-(x * x) / (2.0 * sigma * sigma)).exp() / (std::f32::consts::TAU * sigma * sigma).sqrt()
}

/// Mitchell and Netravali's cubic on [-2, 2].
fn mitchell(x: f32, b: f32, c: f32) -> f32 {
    let x = x.abs();
    let (x2, x3) = (x * x, x * x * x);
    if x <= 1.0 {
        ((12.0 - 9.0 * b - 6.0 * c) * x3 + (-18.0 + 12.0 * b + 6.0 * c) * x2 + (6.0 - 2.0 * b)) / 6.0
    } else if x <= 2.0 {
        ((-b - 6.0 * c) * x3 + (6.0 * b + 30.0 * c) * x2 + (-12.0 * b - 48.0 * c) * x + (8.0 * b + 24.0 * c))
            / 6.0
    } else {
        0.0
    }
}

fn sinc(x: f32) -> f32 {
    if x.abs() < 1e-5 {
        return 1.0;
    }
    let px = std::f32::consts::PI * x;
    px.sin() / px
}

/// pbrt-v4's pixel sensor for its default `cie1931` sensor: radiance times
/// the imaging ratio (exposure time × ISO / 100), white balanced from a
/// daylight illuminant of `white_balance` kelvin to the colour space's
/// white (D65), and pbrt-v3's film `scale`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sensor {
    /// `iso` (100).
    pub iso: f32,
    /// The camera's `shutterclose` − `shutteropen` (1).
    pub exposure_time: f32,
    /// `whitebalance`; `None` (pbrt's 0) leaves colours as they are.
    pub white_balance: Option<f32>,
    /// pbrt-v3's `Film "float scale"` (1).
    pub scale: f32,
}

impl Default for Sensor {
    fn default() -> Self {
        Sensor { iso: 100.0, exposure_time: 1.0, white_balance: None, scale: 1.0 }
    }
}

/// Linear sRGB to CIE XYZ (D65 white).
const XYZ_FROM_SRGB: Mat3 = Mat3::from_cols(
    Vec3::new(0.412_456_4, 0.212_672_9, 0.019_333_9),
    Vec3::new(0.357_576_1, 0.715_152_2, 0.119_192),
    Vec3::new(0.180_437_5, 0.072_175, 0.950_304_1),
);

/// The Bradford cone response (LMS from XYZ), as pbrt-v4's white balance.
const LMS_FROM_XYZ: Mat3 = Mat3::from_cols(
    Vec3::new(0.8951, -0.7502, 0.0389),
    Vec3::new(0.2664, 1.7135, -0.0685),
    Vec3::new(-0.1614, 0.0367, 1.0296),
);

/// sRGB's white, D65, as a chromaticity.
const D65_XY: [f32; 2] = [0.3127, 0.3290];

/// The chromaticity of CIE daylight at `kelvin` (the daylight locus, defined
/// from 4000 to 25000 K; clamped there).
pub fn daylight_xy(kelvin: f32) -> [f32; 2] {
    let t = kelvin.clamp(4000.0, 25000.0) as f64;
    let x = if t <= 7000.0 {
        -4.6070e9 / (t * t * t) + 2.9678e6 / (t * t) + 0.09911e3 / t + 0.244063
    } else {
        -2.0064e9 / (t * t * t) + 1.9018e6 / (t * t) + 0.24748e3 / t + 0.237040
    };
    let y = -3.0 * x * x + 2.870 * x - 0.275;
    [x as f32, y as f32]
}

/// Linear sRGB of CIE daylight at `kelvin`, at luminance 1 (pbrt-v4's
/// named daylight illuminants, normalised as it normalises light spectra).
pub fn daylight_rgb(kelvin: f32) -> Vec3 {
    XYZ_FROM_SRGB.inverse() * white_xyz(daylight_xy(kelvin))
}

/// XYZ of the white of chromaticity `xy` at luminance 1.
fn white_xyz([x, y]: [f32; 2]) -> Vec3 {
    Vec3::new(x / y, 1.0, (1.0 - x - y) / y)
}

impl Sensor {
    /// The linear map from rendered radiance (linear sRGB) to pixel values.
    pub fn response(&self) -> Mat3 {
        let ratio = self.exposure_time * self.iso / 100.0 * self.scale;
        let balance = match self.white_balance {
            None => Mat3::IDENTITY,
            Some(kelvin) => {
                let (src, dst) =
                    (LMS_FROM_XYZ * white_xyz(daylight_xy(kelvin)), LMS_FROM_XYZ * white_xyz(D65_XY));
                let lms = Mat3::from_diagonal(dst / src);
                XYZ_FROM_SRGB.inverse() * LMS_FROM_XYZ.inverse() * lms * LMS_FROM_XYZ * XYZ_FROM_SRGB
            }
        };
        balance * ratio
    }
}

impl FilmSettings {
    /// Most pixels a frame may have: its film alone is 12 bytes a pixel,
    /// and every device keeps one (16384 × 16384 is 3 GiB).
    pub const MAX_PIXELS: u64 = 1 << 28;

    /// The pixels the crop window covers, pbrt-v4's pixel bounds: from
    /// (⌈x min · width⌉, ⌈y min · height⌉) up to, not including,
    /// (⌈x max · width⌉, ⌈y max · height⌉); all of them without a crop.
    pub fn pixel_bounds(&self) -> (UVec2, UVec2) {
        let Some([x0, x1, y0, y1]) = self.crop_window else { return (UVec2::ZERO, self.resolution) };
        let r = self.resolution.as_vec2();
        let at = |fx: f32, fy: f32| UVec2::new((fx * r.x).ceil() as u32, (fy * r.y).ceil() as u32);
        (at(x0, y0), at(x1, y1).min(self.resolution))
    }

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
        // pbrt-v4's defaults, but for the filter: scenes from pbrt files get
        // pbrt-v4's Gaussian (`PixelFilter::PBRT_DEFAULT`), others the pixel's square.
        FilmSettings {
            resolution: UVec2::new(1280, 720),
            filename: None,
            crop_window: None,
            sensor: Sensor::default(),
            filter: PixelFilter::PIXEL,
            diagonal: 0.035,
        }
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
    /// The medium the camera sits in (pbrt's outside medium where the
    /// `Camera` statement is).
    pub camera_medium: crate::MediumIndex,
}

#[cfg(test)]
mod tests {
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

    /// Linear sRGB of the white of chromaticity `xy` at luminance 1.
    fn srgb_white(xy: [f32; 2]) -> Vec3 {
        XYZ_FROM_SRGB.inverse() * white_xyz(xy)
    }

    #[test]
    fn the_sensor_scales_by_exposure_and_iso_and_balances_whites() {
        assert_eq!(Sensor::default().response(), Mat3::IDENTITY);
        let bright = Sensor { iso: 400.0, exposure_time: 0.5, scale: 1.5, ..Default::default() };
        assert!((bright.response() - Mat3::from_diagonal(Vec3::splat(3.0)))
            .abs()
            .to_cols_array()
            .iter()
            .all(|d| *d < 1e-6));
        // D65 is sRGB's white: the daylight locus passes close to it.
        let d65 = srgb_white(daylight_xy(6504.0));
        assert!((d65 - Vec3::ONE).abs().max_element() < 0.01, "{d65}");
        // Balanced for a warm daylight, its white comes out neutral.
        for kelvin in [4500.0, 5000.0, 9000.0] {
            let white = srgb_white(daylight_xy(kelvin));
            let out = Sensor { white_balance: Some(kelvin), ..Default::default() }.response() * white;
            assert!((out / out.y - Vec3::ONE).abs().max_element() < 1e-3, "{kelvin} K: {white} -> {out}");
            assert!(white.x > 1.02 * white.z || kelvin > 6504.0, "{kelvin} K is warm: {white}");
        }
    }

    #[test]
    fn crop_windows_cover_pbrts_pixel_bounds() {
        let film =
            |crop| FilmSettings { resolution: UVec2::new(100, 50), crop_window: crop, ..Default::default() };
        assert_eq!(film(None).pixel_bounds(), (UVec2::ZERO, UVec2::new(100, 50)));
        // pbrt-v4: ⌈fraction × size⌉ at both ends.
        let (lo, hi) = film(Some([0.255, 0.5, 0.1, 1.0])).pixel_bounds();
        assert_eq!((lo, hi), (UVec2::new(26, 5), UVec2::new(50, 50)));
    }
}
