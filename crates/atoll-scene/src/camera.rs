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
