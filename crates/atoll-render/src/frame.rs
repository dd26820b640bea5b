//! What a frame is rendered with: options from the command line and scene,
//! and the context every device holds a copy of (camera, lights, materials).

use std::sync::Arc;

use atoll_scene::{FilmSettings, IntegratorSettings, LightSampler, PixelFilter, Scene, TextureImage};
use glam::{Mat3, UVec2};

use crate::camera::CameraRays;
use crate::filter::FilterTable;
use crate::lights::LightSet;
use crate::material_coeffs::PackedMaterial;
use crate::medium::MediumTable;
use crate::record::RayRecord;
use crate::record::MATERIAL_COEFFS;
use crate::rng::{BounceDim, SampleStream};
use crate::texture::{run_program, TexPoint, TextureTables};

/// Most nested `mix` materials a hit resolves.
pub const MAX_MIX_DEPTH: u32 = 8;

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
    /// How next-event estimation picks a light.
    pub light_sampler: LightSampler,
    /// Paths in flight per wave. Memory is `wave_size * 128 B` per queue.
    pub wave_size: u32,
    /// Wave-front merging: start the next wave's camera paths in the slots
    /// that finished paths free, so late bounces do not run on nearly empty
    /// queues. Off renders one wave at a time (each pixel at most once per
    /// queue). Either way each path's random numbers depend only on its
    /// pixel and sample; only the order of film additions changes.
    pub merge_waves: bool,
    /// The part of the scene's image that `resolution` covers, as fractions
    /// of it (x min, x max, y min, y max; y down): pbrt's crop window, cut
    /// at pixel boundaries. `None`: the whole image.
    pub crop: Option<[f32; 4]>,
    /// What the film's sensor does to radiance (exposure, ISO, white
    /// balance): applied to the image when it is written, not while
    /// rendering, so devices and strategies never see it.
    pub film_response: Mat3,
    /// How camera samples spread around their pixel ([`crate::filter`]).
    pub filter: PixelFilter,
}

/// Paths in flight per wave on a CPU device (GPUs take more: the CUDA
/// device's own default).
pub const DEFAULT_WAVE_SIZE: u32 = 1 << 18;

impl RenderOptions {
    /// The scene's own settings.
    pub fn from_scene(scene: &Scene) -> Self {
        let s = &scene.settings;
        let (resolution, crop) = image_of(&s.film);
        RenderOptions {
            resolution,
            crop,
            film_response: s.film.sensor.response(),
            filter: s.film.filter,
            spp: s.spp.max(1),
            integrator: s.integrator.clone(),
            seed: 0,
            russian_roulette: true,
            light_sampler: s.light_sampler,
            wave_size: DEFAULT_WAVE_SIZE,
            merge_waves: true,
        }
    }

    /// Renders `film`'s image (its crop window of its resolution), keeping
    /// everything else.
    pub fn set_image(&mut self, film: &FilmSettings) {
        (self.resolution, self.crop) = image_of(film);
    }

    pub fn pixel_count(&self) -> u32 {
        self.resolution.x * self.resolution.y
    }

    /// Records a device's path queue holds for this frame: the wave size,
    /// or the whole image when that is smaller (at least one).
    pub fn queue_capacity(&self) -> u32 {
        self.wave_size.min(self.pixel_count()).max(1)
    }
}

/// The pixels `film` renders and, where cropped, which part of its image
/// they are.
fn image_of(film: &FilmSettings) -> (UVec2, Option<[f32; 4]>) {
    let (lo, hi) = film.pixel_bounds();
    if film.crop_window.is_none() {
        return (film.resolution, None);
    }
    let r = film.resolution.as_vec2();
    (hi - lo, Some([lo.x as f32 / r.x, hi.x as f32 / r.x, lo.y as f32 / r.y, hi.y as f32 / r.y]))
}

/// Everything shading needs, identical on every device.
#[derive(Clone, Debug)]
pub struct FrameContext {
    pub options: RenderOptions,
    pub camera: CameraRays,
    /// What textures need to estimate a hit's footprint.
    pub footprint: crate::footprint::CameraFootprint,
    /// The pixel filter, prepared for sampling camera rays.
    pub filter: FilterTable,
    pub lights: LightSet,
    /// Scene materials packed for the ray record, by material id.
    pub materials: Vec<PackedMaterial>,
    /// Textured material parameters and alpha masks as programs.
    pub textures: TextureTables,
    /// The scene's texture images (shared), which the programs read.
    pub images: Vec<Arc<TextureImage>>,
    /// Participating media and the camera's.
    pub media: MediumTable,
    /// The scene's measured BRDFs (shared), which measured surfaces read.
    pub measured: Vec<Arc<atoll_scene::MeasuredBrdf>>,
    /// The camera's shutter where something in the scene moves; `None`
    /// where nothing does (rays then need no time).
    pub shutter: Option<[f32; 2]>,
}

impl FrameContext {
    pub fn new(scene: &Scene, options: RenderOptions) -> Self {
        let materials: Vec<PackedMaterial> = scene.materials.iter().map(PackedMaterial::pack).collect();
        let kinds: Vec<_> = materials.iter().map(|m| m.kind).collect();
        let camera = CameraRays::for_options(&scene.settings.camera, &options);
        FrameContext {
            footprint: crate::footprint::CameraFootprint::new(&camera, options.spp),
            camera,
            filter: FilterTable::new(&options.filter),
            lights: LightSet::new(scene, options.light_sampler),
            textures: TextureTables::new(scene, &kinds),
            images: scene.textures.images.clone(),
            media: MediumTable::new(scene),
            measured: scene.measured.clone(),
            shutter: (!scene.motions.is_empty() || scene.settings.camera.motion.is_some())
                .then_some(scene.settings.camera.shutter),
            materials,
            options,
        }
    }

    /// When path vertex `r`'s rays are traced: a time of the shutter drawn
    /// from its sample, so every segment of a path (and its shadow rays)
    /// sees the scene at one moment, as in pbrt.
    pub fn ray_time(&self, r: &RayRecord) -> f32 {
        self.path_time(r.pixel, r.sample)
    }

    /// The time of sample `sample` of pixel `pixel`'s path ([`Self::ray_time`]).
    pub fn path_time(&self, pixel: u32, sample: u32) -> f32 {
        let Some([open, close]) = self.shutter else { return 0.0 };
        let u = SampleStream::new(self.options.seed, pixel, sample).get(crate::rng::TIME_DIMENSION);
        open + (close - open) * u
    }

    /// The material a hit of path vertex `r` takes on a surface of material
    /// `id`: the material itself, or for a `mix` one of its two, chosen with
    /// the vertex's [`BounceDim::MaterialChoice`] number (nested mixes reuse
    /// what is left of it, rescaled). The GPU's `write_surface` mirrors it.
    /// Returns the chosen material's id with it (its textures apply). A
    /// mix whose amount is a texture evaluates it at the hit `at` (computed
    /// only then).
    pub fn material_at(&self, id: u32, r: &RayRecord, at: impl Fn() -> TexPoint) -> (u32, &PackedMaterial) {
        let mut id = id;
        let mut m = &self.materials[id as usize];
        if m.mix.is_none() {
            return (id, m);
        }
        let mut u = SampleStream::new(self.options.seed, r.pixel, r.sample).bounce(
            r.depth as u32,
            BounceDim::MaterialChoice,
            0,
        );
        // Bounded: a mix that (indirectly) contains itself stops somewhere.
        for _ in 0..MAX_MIX_DEPTH {
            let Some(([first, second], amount)) = m.mix else { break };
            let program = self.textures.mix_amount[id as usize];
            let amount = if program.is_empty() {
                amount
            } else {
                let ops = &self.textures.ops[program.start as usize..(program.start + program.len) as usize];
                let value = run_program(ops, &self.images, at(), &mut [half::f16::ZERO; MATERIAL_COEFFS]).x;
                value.clamp(0.0, 1.0)
            };
            if u < amount {
                id = second;
                u /= amount;
            } else {
                id = first;
                u = (u - amount) / (1.0 - amount);
            }
            m = &self.materials[id as usize];
        }
        (id, m)
    }

    pub fn max_depth(&self) -> u32 {
        match self.options.integrator {
            IntegratorSettings::Path { max_depth } => max_depth,
            IntegratorSettings::AmbientOcclusion { .. } => 0,
        }
    }
}

/// A batch of camera paths: one sample for a contiguous range of pixels
/// in the order camera paths are made (`first_pixel` and `pixel_count`
/// count places in that order: [`atoll_scene::camera::tile_order_pixel`]).
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material_layout::diffuse;
    use atoll_scene::{Material, Rgb};
    use bytemuck::Zeroable;

    /// A mix picks its second material with probability `amount`, nested
    /// mixes multiply, and the choice is a function of the path vertex.
    #[test]
    fn mixes_choose_by_amount_deterministically() {
        let mut scene = atoll_scene::cornell::builtin_cornell_box();
        let a = scene.add_material(Material::Diffuse { reflectance: Rgb::splat(0.1) });
        let b = scene.add_material(Material::Diffuse { reflectance: Rgb::splat(0.2) });
        let c = scene.add_material(Material::Diffuse { reflectance: Rgb::splat(0.3) });
        let ab = scene.add_material(Material::Mix { materials: [a, b], amount: 0.25 });
        let abc = scene.add_material(Material::Mix { materials: [ab, c], amount: 0.5 });
        let frame = FrameContext::new(&scene, RenderOptions::from_scene(&scene));
        let mut counts = std::collections::HashMap::new();
        let n = 40_000;
        for i in 0..n {
            let mut r = RayRecord::zeroed();
            (r.pixel, r.sample, r.depth) = (i, i % 7, (i % 3) as u16);
            let chosen =
                frame.material_at(abc, &r, TexPoint::default).1.coeffs[diffuse::REFLECTANCE].to_f32();
            assert_eq!(
                frame.material_at(abc, &r, TexPoint::default).1.coeffs[diffuse::REFLECTANCE].to_f32(),
                chosen,
                "deterministic"
            );
            *counts.entry((chosen * 10.0).round() as u32).or_insert(0u32) += 1;
        }
        // c half the time; of the other half, b a quarter.
        for (key, expected) in [(1, 0.375), (2, 0.125), (3, 0.5)] {
            let share = counts[&key] as f64 / n as f64;
            assert!((share - expected).abs() < 0.01, "material {key}: {share} vs {expected}");
        }
        // A textured amount chooses by the texture at the hit: a checkerboard
        // of 0 and 1 picks the first material on even squares, the second on odd.
        let checker = scene.textures.add(atoll_scene::Texture::Checkerboard {
            mapping: atoll_scene::UvMapping::default().into(),
            tex: [atoll_scene::TexInput::Value(Rgb::ZERO), atoll_scene::TexInput::Value(Rgb::ONE)],
        });
        let textured = scene.add_material(Material::Mix { materials: [a, b], amount: 0.5 });
        scene.textures.bind(atoll_scene::TextureBinding {
            material: textured,
            param: atoll_scene::TexturedParam::Amount,
            texture: checker,
            remap_roughness: false,
        });
        let frame = FrameContext::new(&scene, RenderOptions::from_scene(&scene));
        for i in 0..200 {
            let mut r = RayRecord::zeroed();
            (r.pixel, r.sample) = (i, 3);
            assert_eq!(frame.material_at(textured, &r, || TexPoint::uv(glam::Vec2::new(0.5, 0.5))).0, a);
            assert_eq!(frame.material_at(textured, &r, || TexPoint::uv(glam::Vec2::new(1.5, 0.5))).0, b);
        }
        // A plain material is itself.
        assert_eq!(
            frame.material_at(a, &RayRecord::zeroed(), TexPoint::default),
            (a, &frame.materials[a as usize])
        );
    }
}
