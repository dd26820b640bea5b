//! What a frame is rendered with: options from the command line and scene,
//! and the context every device holds a copy of (camera, lights, materials).

use atoll_scene::{IntegratorSettings, Scene};
use glam::UVec2;

use crate::camera::CameraRays;
use crate::lights::LightSet;
use crate::material_coeffs::PackedMaterial;

/// How to render a frame.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    pub resolution: UVec2,
    pub spp: u32,
    pub integrator: IntegratorSettings,
    /// Mixed into every random number; different seeds give independent images.
    pub seed: u32,
    /// Russian roulette after the second bounce (pbrt-v4's rule). Unbiased
    /// either way; off gives the fixed-length paths benchmarks ask for.
    pub russian_roulette: bool,
    /// Paths in flight per wave. Memory is `wave_size * 128 B` per queue.
    pub wave_size: u32,
    /// Wave-front merging: start the next wave's camera paths in the slots
    /// that finished paths free, so late bounces do not run on nearly empty
    /// queues. Off renders one wave at a time (each pixel at most once per
    /// queue). Either way each path's random numbers depend only on its
    /// pixel and sample; only the order of film additions changes.
    pub merge_waves: bool,
}

impl RenderOptions {
    /// The scene's own settings.
    pub fn from_scene(scene: &Scene) -> Self {
        let s = &scene.settings;
        RenderOptions {
            resolution: s.film.resolution,
            spp: s.spp.max(1),
            integrator: s.integrator.clone(),
            seed: 0,
            russian_roulette: true,
            wave_size: 1 << 18,
            merge_waves: true,
        }
    }

    pub fn pixel_count(&self) -> u32 {
        self.resolution.x * self.resolution.y
    }
}

/// Everything shading needs, identical on every device.
#[derive(Clone, Debug)]
pub struct FrameContext {
    pub options: RenderOptions,
    pub camera: CameraRays,
    pub lights: LightSet,
    /// Scene materials packed for the ray record, by material id.
    pub materials: Vec<PackedMaterial>,
}

impl FrameContext {
    pub fn new(scene: &Scene, options: RenderOptions) -> Self {
        FrameContext {
            camera: CameraRays::new(&scene.settings.camera, options.resolution),
            lights: LightSet::new(scene),
            materials: scene.materials.iter().map(PackedMaterial::pack).collect(),
            options,
        }
    }

    pub fn max_depth(&self) -> u32 {
        match self.options.integrator {
            IntegratorSettings::Path { max_depth } => max_depth,
            IntegratorSettings::AmbientOcclusion { .. } => 0,
        }
    }
}

/// A batch of camera paths: one sample for a contiguous range of pixels.
/// Within a wave each pixel appears at most once, so film updates of a wave
/// never collide and their order cannot change the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Wave {
    pub sample: u32,
    pub first_pixel: u32,
    pub pixel_count: u32,
}

impl Wave {
    /// All waves of a frame, in the order they are rendered: sample-major,
    /// so an interrupted render has a uniform number of samples per pixel.
    pub fn all(options: &RenderOptions) -> Vec<Wave> {
        let pixels = options.pixel_count();
        let per_wave = options.wave_size.max(1).min(pixels.max(1));
        (0..options.spp)
            .flat_map(|sample| {
                (0..pixels.div_ceil(per_wave)).map(move |w| Wave {
                    sample,
                    first_pixel: w * per_wave,
                    pixel_count: per_wave.min(pixels - w * per_wave),
                })
            })
            .collect()
    }
}
