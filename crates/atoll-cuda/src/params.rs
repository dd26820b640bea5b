//! What the wavefront kernels (`kernels/wavefront.cu`) are launched with:
//! [`FrameParams`], the frame's [`FrameContext`] flattened into one
//! `#[repr(C)]` struct of values and device pointers (camera, options, the
//! light tables, the packed materials), and [`SceneView`], the device
//! pointers of a [`GpuScene`]'s tables. `kernels/params.cuh` mirrors every
//! struct here; its `static_assert`s are generated from `FieldLayout`s by
//! `src/header.rs`.
//!
//! [`FrameTables`] is the host side of the light and material tables (a pure
//! function of the frame, tested without a GPU); [`FrameParamsHost`] uploads
//! them and owns the device buffers the pointers in its [`FrameParams`]
//! point into.

use std::sync::Arc;

use atoll_render::camera::CameraRays;
use atoll_render::environment::EnvironmentSampler;
use atoll_render::filter::FilterTable;
#[cfg(test)]
use atoll_render::light_bvh::LightNode;
use atoll_render::lights::Emitter;
use atoll_render::material_coeffs::PackedMaterial;
use atoll_render::material_layout;
use atoll_render::portal::PortalFrame;
use atoll_render::record::MATERIAL_COEFFS;
use atoll_render::texture::{ProgramRange, ShadingNormalProgram};
use atoll_render::FrameContext;
use atoll_scene::{EnvLayout, IntegratorSettings, LightSampler, Projection};
use bytemuck::{Pod, Zeroable};
use cudarc::driver::{CudaSlice, DevicePtr, DeviceRepr, ValidAsZeroBits};

use crate::error::CudaError;
use crate::gpu::{upload, Gpu};
use crate::layout::GpuMotion;
#[cfg(test)]
use crate::layout::{field_layout, FieldLayout};
use crate::scene::GpuScene;

/// [`GpuEmitter::kind`] values, one per [`Emitter`] variant.
pub(crate) mod emitter_kind {
    pub(crate) const POINT: u32 = 0;
    pub(crate) const DISTANT: u32 = 1;
    pub(crate) const INFINITE: u32 = 2;
    pub(crate) const TRIANGLE: u32 = 3;
    pub(crate) const SPOT: u32 = 4;
    pub(crate) const ENVIRONMENT: u32 = 5;
    pub(crate) const GONIOMETRIC: u32 = 6;
    pub(crate) const PROJECTION: u32 = 7;
}

/// [`GpuEmitter::table`] of a triangle emitter without an emission texture.
pub(crate) const NO_EMISSION_TEXTURE: u32 = u32::MAX;

/// A textured triangle emitter's corner uvs and its program in
/// [`FrameParams::texture_ops`] (32 bytes; `lights::EmissionTexture`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub(crate) struct GpuEmissionTexture {
    pub uv: [f32; 6],
    pub start: u32,
    pub len: u32,
}

impl GpuEmissionTexture {
    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuEmissionTexture { uv, start, len })
    }
}

/// A medium's coefficients (`atoll_render::medium::MediumCoeffs`: a grid
/// medium's field scales) and its grid's place and fields
/// (`atoll_render::density_grid::DensityGrid`), 124 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuMedium {
    pub sigma_a: [f32; 3],
    pub sigma_s: [f32; 3],
    pub le: [f32; 3],
    pub g: f32,
    /// First value in [`FrameParams::media_grids`], or [`NO_GRID`] (the
    /// same coefficients everywhere).
    pub grid_first: u32,
    pub grid_resolution: [u32; 3],
    /// World to the grid's sample lattice, row-major 3×4.
    pub world_to_lattice: [f32; 12],
    /// Samples per channel: channel `k` of the grid starts `k` planes
    /// after `grid_first`.
    pub grid_plane: u32,
    /// Where σa, σs and Le come from ([`grid_field`]).
    pub grid_fields: [u32; 3],
    /// 1 for a subsurface material's interior
    /// (`atoll_render::medium::MediumCoeffs::subsurface`), else 0.
    pub subsurface: u32,
}

/// [`GpuMedium::grid_first`] of a medium without a grid.
pub(crate) const NO_GRID: u32 = u32::MAX;

/// [`GpuMedium::grid_fields`]: a field's [`FieldSource`] as one word.
pub(crate) mod grid_field {
    use atoll_scene::FieldSource;

    /// 1 everywhere in the box.
    pub(crate) const CONSTANT: u32 = u32::MAX;
    /// With a channel: it and the next two are red, green and blue.
    pub(crate) const RGB: u32 = 1 << 16;

    pub(crate) fn encode(source: FieldSource) -> u32 {
        match source {
            FieldSource::Constant => CONSTANT,
            FieldSource::Scalar(k) => k,
            FieldSource::Rgb(k) => k | RGB,
        }
    }
}

/// `atoll_render::footprint::CameraFootprint` on the device (144 bytes;
/// matrices row-major).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuFootprint {
    pub camera_position: [f32; 3],
    pub spp_scale: f32,
    pub camera_from_world: [f32; 9],
    pub world_from_camera: [f32; 9],
    /// x's then y's.
    pub min_position: [f32; 6],
    pub min_direction: [f32; 6],
    pub pad: [f32; 2],
}

impl GpuFootprint {
    pub(crate) fn new(f: &atoll_render::footprint::CameraFootprint) -> Self {
        let rows = |m: glam::Mat3| m.transpose().to_cols_array();
        let pair = |v: [glam::Vec3; 2]| {
            let mut out = [0.0; 6];
            out[..3].copy_from_slice(&v[0].to_array());
            out[3..].copy_from_slice(&v[1].to_array());
            out
        };
        GpuFootprint {
            camera_position: f.camera_position.to_array(),
            spp_scale: f.spp_scale,
            camera_from_world: rows(f.camera_from_world),
            world_from_camera: rows(f.world_from_camera),
            min_position: pair(f.min_position),
            min_direction: pair(f.min_direction),
            pad: [0.0; 2],
        }
    }

    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuFootprint {
            camera_position,
            spp_scale,
            camera_from_world,
            world_from_camera,
            min_position,
            min_direction,
            pad
        })
    }
}

impl GpuMedium {
    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuMedium {
            sigma_a,
            sigma_s,
            le,
            g,
            grid_first,
            grid_resolution,
            world_to_lattice,
            grid_plane,
            grid_fields,
            subsurface
        })
    }
}

/// Media a frame can hold: the vacuum and [`atoll_scene::MAX_MEDIA`].
pub const MEDIA_SLOTS: usize = atoll_scene::MAX_MEDIA + 1;

/// [`FrameParams::light_sampler`] values, one per [`LightSampler`] variant.
pub(crate) mod light_sampler_kind {
    pub(crate) const POWER: u32 = 0;
    pub(crate) const BVH: u32 = 1;
}

/// The layout of the BVH light sampler's nodes, which the kernels mirror.
#[cfg(test)]
pub(crate) fn light_node_layout() -> FieldLayout {
    field_layout!(LightNode {
        min,
        phi,
        max,
        cos_theta_o,
        w,
        cos_theta_e,
        sin_theta_o,
        radius,
        child_or_light,
        parent,
        flags,
        pad
    })
}

/// [`FrameParams::integrator`] values, one per [`IntegratorSettings`] variant.
/// `FrameParams::projection`: how camera rays leave (`atoll_scene::Projection`).
pub(crate) mod projection_kind {
    pub(crate) const PERSPECTIVE: u32 = 0;
    pub(crate) const ORTHOGRAPHIC: u32 = 1;
    pub(crate) const SPHERE_EQUAL_AREA: u32 = 2;
    pub(crate) const SPHERE_LAT_LONG: u32 = 3;
    pub(crate) const REALISTIC: u32 = 4;
}

pub(crate) mod integrator_kind {
    pub(crate) const PATH: u32 = 0;
    pub(crate) const AMBIENT_OCCLUSION: u32 = 1;
}

/// One [`Emitter`] on the device (80 bytes). By `kind`: point: `p[0..3]`
/// position, `radiance` intensity; distant: `p[0..3]` the direction light
/// travels, `radiance`; infinite: `radiance`; triangle: `p` the three
/// world-space vertices, `normal`, `area`, `radiance`, `two_sided`; spot:
/// `p[0..3]` position, `p[3..6]` axis, `p[6]` cos_falloff_start, `p[7]`
/// cos_falloff_end, `radiance` intensity; environment: `p` the
/// light-to-world rotation's columns, `normal` (width, height, layout: 0
/// equal-area, 1 lat-long) as floats, `area` the sum of its selection
/// weights, `table` its offset in [`FrameParams::environment_tables`];
/// a triangle's `table` indexes [`FrameParams::emission_textures`]
/// ([`NO_EMISSION_TEXTURE`]: untextured); goniometric: `p` the
/// world-to-light matrix's columns, `normal` the position, `radiance`
/// intensity, `area` the map's resolution as a float and `table` the
/// offset of its values in [`FrameParams::environment_tables`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub(crate) struct GpuEmitter {
    /// [`emitter_kind`].
    pub kind: u32,
    /// 1 when a triangle emits on both sides.
    pub two_sided: u32,
    pub area: f32,
    /// Environment emitters: offset of their tables (see `kernels/environment.cuh`).
    pub table: u32,
    pub p: [f32; 9],
    pub normal: [f32; 3],
    pub radiance: [f32; 3],
    /// Triangles: the corners' error bound along the normal (`Emitter::Triangle::corner_error`).
    pub error: f32,
    /// Infinite and environment emitters with a portal: 1 + the offset of
    /// its [`portal_words`] in [`FrameParams::environment_tables`]; 0: none.
    pub portal: u32,
}

/// Floats of a portal in the environment tables (`kernels/portal.cuh`).
pub(crate) const PORTAL_WORDS: usize = 22;

/// A portal's floats for the kernels: its corner, far corner, two edges,
/// frame x, y, z (three each) and area, as `atoll_render::portal::PortalFrame`.
pub(crate) fn portal_words(f: &PortalFrame) -> [f32; PORTAL_WORDS] {
    let mut w = [0.0; PORTAL_WORDS];
    for (k, v) in [f.corner, f.far_corner, f.edge_u, f.edge_v, f.x, f.y, f.z].iter().enumerate() {
        w[3 * k..3 * k + 3].copy_from_slice(&v.to_array());
    }
    w[21] = f.area;
    w
}

impl GpuEmitter {
    /// The device form of `e`.
    pub(crate) fn new(e: &Emitter) -> Self {
        let mut g = GpuEmitter::zeroed();
        match *e {
            Emitter::Point { position, intensity } => {
                g.kind = emitter_kind::POINT;
                g.p[..3].copy_from_slice(&position.to_array());
                g.radiance = intensity.to_array();
            }
            Emitter::Distant { direction, radiance } => {
                g.kind = emitter_kind::DISTANT;
                g.p[..3].copy_from_slice(&direction.to_array());
                g.radiance = radiance.to_array();
            }
            Emitter::Infinite { radiance, .. } => {
                g.kind = emitter_kind::INFINITE;
                g.radiance = radiance.to_array();
            }
            Emitter::Environment { .. } | Emitter::Goniometric { .. } | Emitter::Projection { .. } => {
                unreachable!("emitters with tables are built by FrameTables::build")
            }
            Emitter::Spot { position, direction, intensity, cos_falloff_start, cos_falloff_end } => {
                g.kind = emitter_kind::SPOT;
                g.p[..3].copy_from_slice(&position.to_array());
                g.p[3..6].copy_from_slice(&direction.to_array());
                g.p[6] = cos_falloff_start;
                g.p[7] = cos_falloff_end;
                g.radiance = intensity.to_array();
            }
            Emitter::Triangle { p, normal, area, radiance, two_sided, corner_error, .. } => {
                g.kind = emitter_kind::TRIANGLE;
                // FrameTables::build points textured triangles at their texture.
                g.table = NO_EMISSION_TEXTURE;
                for (k, v) in p.iter().enumerate() {
                    g.p[3 * k..3 * k + 3].copy_from_slice(&v.to_array());
                }
                g.normal = normal.to_array();
                g.area = area;
                g.radiance = radiance.to_array();
                g.two_sided = two_sided as u32;
                g.error = corner_error;
            }
        }
        g
    }

    /// The device form of an environment emitter whose tables start at
    /// `table` in [`FrameParams::environment_tables`].
    pub(crate) fn environment(env: &EnvironmentSampler, table: u32) -> Self {
        let mut g = GpuEmitter::zeroed();
        g.kind = emitter_kind::ENVIRONMENT;
        g.p = env.light_to_world.to_cols_array();
        let layout = match env.image.layout {
            atoll_scene::EnvLayout::EqualArea => 0.0,
            atoll_scene::EnvLayout::LatLong => 1.0,
        };
        g.normal = [env.image.width as f32, env.image.height as f32, layout];
        g.area = env.func_sum;
        g.table = table;
        g
    }

    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuEmitter { kind, two_sided, area, table, p, normal, radiance, error, portal })
    }
}

/// A [`PackedMaterial`] on the device (48 bytes, 16-aligned in the table
/// so the kernels copy the coefficients as two 16-byte words).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub(crate) struct GpuMaterial {
    /// f16 bit patterns, as in [`atoll_render::RayRecord::coeffs`].
    pub coeffs: [u16; MATERIAL_COEFFS],
    /// [`atoll_render::record::MaterialKind`] as u32.
    pub kind: u32,
    pub pad: [u32; 3],
}

/// A material's bump or normal map in one word: its kind in the top two
/// bits, its program's start in the next 22, its length in the low 8 (0:
/// none). A program that does not fit (none compiled so far comes near)
/// is dropped with a warning: the GPU then shades without it.
pub(crate) fn bend_word(bend: ShadingNormalProgram) -> u32 {
    let ShadingNormalProgram { kind, program } = bend;
    if kind == 0 {
        return 0;
    }
    if program.len >= 1 << 8 || program.start >= 1 << 22 || kind >= 4 {
        tracing::warn!(
            "a bump or normal map program ({program:?}) is too long for the GPU's material words; ignored"
        );
        return 0;
    }
    kind << 30 | program.start << 8 | program.len
}

impl GpuMaterial {
    /// For a `mix`, `pad` holds its two material ids and the probability of
    /// the second (f32 bits), and its coefficients at `mix::AMOUNT_PROGRAM`
    /// the start and length of its amount's texture program (`mix_amount`); otherwise
    /// `pad` holds the start and length of its texture program (`textures`)
    /// and its bump or normal map (`bend`, [`bend_word`]): see `write_surface`.
    pub(crate) fn new(
        m: &PackedMaterial,
        textures: ProgramRange,
        mix_amount: ProgramRange,
        bend: ShadingNormalProgram,
    ) -> Self {
        let mut coeffs = m.coeffs.map(|c| c.to_bits());
        let pad = match m.mix {
            Some(([a, b], amount)) => {
                let words = [mix_amount.start, mix_amount.len];
                let slot = material_layout::mix::AMOUNT_PROGRAM;
                coeffs[slot..slot + 4].copy_from_slice(bytemuck::cast_slice(&words));
                [a, b, amount.to_bits()]
            }
            None => [textures.start, textures.len, bend_word(bend)],
        };
        GpuMaterial { coeffs, kind: m.kind as u32, pad }
    }

    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(GpuMaterial { coeffs, kind, pad })
    }
}

/// Everything shading needs, identical on every device: the
/// [`FrameContext`] flattened. Pointers are device addresses
/// (0 until uploaded: see [`FrameParamsHost`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct FrameParams {
    /// `CameraRays` camera-to-world, row-major 3×4 (`m[r*4 + c]`).
    pub camera_to_world: [f32; 12],
    pub window_min: [f32; 2],
    pub window_max: [f32; 2],
    /// Image size as floats (what camera rays divide raster positions by).
    pub raster_size: [f32; 2],
    pub lens_radius: f32,
    pub focal_distance: f32,
    /// [`projection_kind`].
    pub projection: u32,
    /// 1 when the camera moves: `camera_motion` places it at each path's time.
    pub camera_moves: u32,
    pub resolution: [u32; 2],
    pub seed: u32,
    /// [`integrator_kind`].
    pub integrator: u32,
    /// Path integrator's maximum depth (0 for ambient occlusion).
    pub max_depth: u32,
    /// Ambient occlusion's ray length (0 for the path integrator).
    pub ao_max_distance: f32,
    /// 1 when Russian roulette is on.
    pub russian_roulette: u32,
    /// Entries of `emitters` and `light_pmf` (`light_cdf` has one more).
    pub light_count: u32,
    pub infinite_count: u32,
    pub triangle_key_count: u32,
    pub material_count: u32,
    /// [`light_sampler_kind`].
    pub light_sampler: u32,
    /// `GpuEmitter[light_count]`.
    pub emitters: u64,
    /// `f32[light_count]`: selection probability per emitter.
    pub light_pmf: u64,
    /// `f32[light_count + 1]`: cumulative distribution, last entry 1.
    pub light_cdf: u64,
    /// `u32[infinite_count]`: indices of the infinite lights.
    pub infinite_lights: u64,
    /// `u64[triangle_key_count]`: sorted `instance << 32 | mesh` keys.
    pub triangle_keys: u64,
    /// `u32[triangle_key_count]`: first light index per key.
    pub triangle_bases: u64,
    /// `GpuMaterial[material_count]`, by scene material id.
    pub materials: u64,
    /// `f32[]`: the environment emitters' tables.
    pub environment_tables: u64,
    /// `TexOp[]`: texture programs (`atoll_render::texture`); materials
    /// name theirs in `GpuMaterial::pad`.
    pub texture_ops: u64,
    /// `AlphaProgram[]` by scene mesh id; 0 when no mesh has alpha.
    pub mesh_alpha: u64,
    /// `f32[256]`: sRGB byte to linear (`atoll_scene::srgb8_to_linear`).
    pub srgb_to_linear: u64,
    /// `GpuEmissionTexture[]`, by triangle emitters' `table`.
    pub emission_textures: u64,
    /// The scene's `GpuImage`s and their `u32` texels (from the `GpuScene`).
    pub images: u64,
    pub texels: u64,
    /// `LightNode[light_node_count]`: the BVH light sampler's tree.
    pub light_nodes: u64,
    /// `u32[light_count]`: the leaf of each emitter (`light_bvh::NO_NODE` outside the tree).
    pub light_leaf: u64,
    /// `u32[unbounded_count]`: the lights at infinity, chosen apart from the tree.
    pub unbounded_lights: u64,
    pub light_node_count: u32,
    pub unbounded_count: u32,
    /// The pixel filter's sampling tables (`atoll_render::filter`).
    pub filter: FilterTable,
    /// Entries of `media` in use (1, the vacuum, when the scene has none).
    pub media_count: u32,
    /// The medium camera rays start in.
    pub camera_medium: u32,
    /// `MediumTable::shadow_reach`.
    pub shadow_reach: f32,
    pub media_pad: u32,
    /// `f32[]`: every grid medium's density samples, one after another.
    pub media_grids: u64,
    /// `f32[]`: the measured BRDFs ([`FrameTables::measured`]); 0 for none.
    pub measured: u64,
    /// `f32[]`: a realistic camera's lens ([`pack_lens`]); 0 for none.
    pub lens: u64,
    /// By `MediumIndex`; entry 0 is the vacuum.
    pub media: [GpuMedium; MEDIA_SLOTS],
    /// A moving camera's camera-to-world motion (with `camera_moves`).
    pub camera_motion: GpuMotion,
    /// What textures need to estimate a hit's footprint.
    pub footprint: GpuFootprint,
}

impl FrameParams {
    /// The values of `frame` (table pointers left 0; table counts set).
    pub(crate) fn from_frame(frame: &FrameContext) -> Self {
        let (integrator, max_depth, ao_max_distance) = match frame.options.integrator {
            IntegratorSettings::Path { max_depth } => (integrator_kind::PATH, max_depth, 0.0),
            IntegratorSettings::AmbientOcclusion { max_distance } => {
                (integrator_kind::AMBIENT_OCCLUSION, 0, max_distance)
            }
        };
        let lights = &frame.lights;
        let mut params = FrameParams {
            resolution: frame.options.resolution.to_array(),
            seed: frame.options.seed,
            integrator,
            max_depth,
            ao_max_distance,
            russian_roulette: frame.options.russian_roulette as u32,
            light_count: lights.emitters.len() as u32,
            infinite_count: lights.infinite_lights().len() as u32,
            triangle_key_count: lights.triangle_keys().len() as u32,
            material_count: frame.materials.len() as u32,
            light_sampler: match frame.options.light_sampler {
                LightSampler::Power => light_sampler_kind::POWER,
                LightSampler::Bvh => light_sampler_kind::BVH,
            },
            light_node_count: lights.bvh.nodes.len() as u32,
            unbounded_count: lights.unbounded_lights().len() as u32,
            filter: frame.filter,
            media_count: frame.media.media.len() as u32,
            camera_medium: frame.media.camera as u32,
            shadow_reach: frame.media.shadow_reach,
            ..Zeroable::zeroed()
        };
        let mut first = 0;
        let grid_starts: Vec<u32> = (frame.media.grids.iter())
            .map(|g| {
                first += g.values.len() as u32;
                first - g.values.len() as u32
            })
            .collect();
        for (slot, m) in params.media.iter_mut().zip(&frame.media.media) {
            *slot = GpuMedium {
                sigma_a: m.sigma_a.to_array(),
                sigma_s: m.sigma_s.to_array(),
                le: m.le.to_array(),
                g: m.g,
                grid_first: NO_GRID,
                subsurface: m.subsurface as u32,
                ..Zeroable::zeroed()
            };
            if let Some(g) = m.grid {
                let grid = &frame.media.grids[g as usize];
                slot.grid_first = grid_starts[g as usize];
                slot.grid_resolution = grid.resolution;
                slot.grid_plane = grid.resolution.iter().product();
                slot.grid_fields = grid.fields.map(|f| grid_field::encode(f.source));
                let m = glam::Mat4::from(grid.world_to_lattice);
                for (r, row) in slot.world_to_lattice.chunks_exact_mut(4).enumerate() {
                    row.copy_from_slice(&m.row(r).to_array());
                }
            }
        }
        params.set_camera(&frame.camera);
        params.footprint = GpuFootprint::new(&frame.footprint);
        params
    }

    /// Camera rays leave from `camera`.
    pub(crate) fn set_camera(&mut self, camera: &CameraRays) {
        let m = camera.camera_to_world();
        for r in 0..3 {
            self.camera_to_world[r * 4..r * 4 + 4].copy_from_slice(&m.row(r).to_array());
        }
        let (window_min, window_max) = camera.window();
        (self.window_min, self.window_max) = (window_min.to_array(), window_max.to_array());
        self.raster_size = camera.raster_size().to_array();
        (self.lens_radius, self.focal_distance) = camera.lens();
        (self.camera_moves, self.camera_motion) = match camera.motion() {
            Some((motion, shutter)) => {
                (1, GpuMotion::new(motion, shutter, (glam::Vec3::ZERO, glam::Vec3::ZERO)))
            }
            None => (0, GpuMotion::default()),
        };
        self.projection = match camera.projection() {
            Projection::Perspective => projection_kind::PERSPECTIVE,
            Projection::Orthographic => projection_kind::ORTHOGRAPHIC,
            Projection::Spherical { mapping: EnvLayout::EqualArea } => projection_kind::SPHERE_EQUAL_AREA,
            Projection::Spherical { mapping: EnvLayout::LatLong } => projection_kind::SPHERE_LAT_LONG,
            Projection::Realistic => projection_kind::REALISTIC,
        };
    }

    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(FrameParams {
            camera_to_world,
            window_min,
            window_max,
            raster_size,
            lens_radius,
            focal_distance,
            projection,
            camera_moves,
            resolution,
            seed,
            integrator,
            max_depth,
            ao_max_distance,
            russian_roulette,
            light_count,
            infinite_count,
            triangle_key_count,
            material_count,
            light_sampler,
            emitters,
            light_pmf,
            light_cdf,
            infinite_lights,
            triangle_keys,
            triangle_bases,
            materials,
            environment_tables,
            texture_ops,
            mesh_alpha,
            srgb_to_linear,
            emission_textures,
            images,
            texels,
            light_nodes,
            light_leaf,
            unbounded_lights,
            light_node_count,
            unbounded_count,
            filter,
            media_count,
            camera_medium,
            shadow_reach,
            media_pad,
            media_grids,
            measured,
            lens,
            media,
            camera_motion,
            footprint,
        })
    }
}

/// Device pointers of a [`GpuScene`]'s tables and their sizes (88 bytes);
/// the crate docs describe the tables.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct SceneView {
    /// `f32[3 * vertex_count]`.
    pub vertices: u64,
    /// `f32[3 * vertex_count]` (meaningful for meshes with `HAS_NORMALS`).
    pub normals: u64,
    /// `u32[3 * triangle_count]`, absolute vertex indices.
    pub triangles: u64,
    /// `u32[triangle_count]`: index into `meshes`.
    pub triangle_mesh: u64,
    /// `GpuMesh[mesh_count]`.
    pub meshes: u64,
    /// `GpuInstance[instance_count]`.
    pub instances: u64,
    /// `f32[2 * vertex_count]` (meaningful for meshes with `HAS_UVS`).
    pub uvs: u64,
    /// `u32[triangle_count]`: the curve piece a proxy triangle stands for
    /// (`NO_CURVE` elsewhere); one placeholder without curves.
    pub curve_of: u64,
    /// `GpuCurve[..]`: the pieces.
    pub curves: u64,
    /// `GpuMotion[..]`: moving instances' motions; one placeholder where
    /// nothing moves.
    pub motions: u64,
    pub triangle_count: u32,
    pub mesh_count: u32,
    pub instance_count: u32,
    pub vertex_count: u32,
}

impl SceneView {
    /// The view of `scene`'s device tables.
    pub fn of(scene: &GpuScene) -> Self {
        let stream = &scene.gpu.stream;
        SceneView {
            vertices: scene.vertices.device_ptr(stream).0,
            normals: scene.normals.device_ptr(stream).0,
            triangles: scene.triangles.device_ptr(stream).0,
            triangle_mesh: scene.triangle_mesh.device_ptr(stream).0,
            meshes: scene.meshes.device_ptr(stream).0,
            instances: scene.instances.device_ptr(stream).0,
            uvs: scene.uvs.device_ptr(stream).0,
            curve_of: scene.curve_of.device_ptr(stream).0,
            curves: scene.curves.device_ptr(stream).0,
            motions: scene.motions.device_ptr(stream).0,
            triangle_count: scene.counts.triangles as u32,
            mesh_count: scene.counts.meshes as u32,
            instance_count: scene.counts.instances as u32,
            vertex_count: scene.counts.vertices as u32,
        }
    }

    #[cfg(test)]
    pub(crate) fn field_layout() -> FieldLayout {
        field_layout!(SceneView {
            vertices,
            normals,
            triangles,
            triangle_mesh,
            meshes,
            instances,
            uvs,
            curve_of,
            curves,
            motions,
            triangle_count,
            mesh_count,
            instance_count,
            vertex_count,
        })
    }
}

// SAFETY (all ten): plain-old-data `#[repr(C)]` structs (Pod), so any bit
// pattern, including all zeros, is a valid value and they can be copied to
// and from the device byte for byte.
unsafe impl DeviceRepr for GpuEmitter {}
unsafe impl ValidAsZeroBits for GpuEmitter {}
unsafe impl DeviceRepr for GpuMaterial {}
unsafe impl ValidAsZeroBits for GpuMaterial {}
unsafe impl DeviceRepr for FrameParams {}
unsafe impl ValidAsZeroBits for FrameParams {}
unsafe impl DeviceRepr for SceneView {}
unsafe impl DeviceRepr for GpuEmissionTexture {}
unsafe impl ValidAsZeroBits for GpuEmissionTexture {}
unsafe impl ValidAsZeroBits for SceneView {}

const _: () = {
    assert!(std::mem::size_of::<GpuEmitter>() == 84);
    assert!(std::mem::size_of::<GpuMaterial>() == 48);
    assert!(std::mem::size_of::<GpuMedium>() == 124);
    assert!(
        std::mem::size_of::<FrameParams>()
            == 280
                + std::mem::size_of::<atoll_render::filter::FilterTable>()
                + 40
                + std::mem::size_of::<GpuMedium>() * MEDIA_SLOTS
                + std::mem::size_of::<GpuMotion>()
                + std::mem::size_of::<GpuFootprint>()
    );
    assert!(std::mem::size_of::<GpuFootprint>() == 144);
    assert!(std::mem::offset_of!(FrameParams, emitters) == 136);
    assert!(std::mem::size_of::<SceneView>() == 96);
};

/// The frame's light and material tables in host memory, exactly as they
/// go to the device.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct FrameTables {
    pub emitters: Vec<GpuEmitter>,
    pub light_pmf: Vec<f32>,
    pub light_cdf: Vec<f32>,
    pub infinite_lights: Vec<u32>,
    pub triangle_keys: Vec<u64>,
    pub triangle_bases: Vec<u32>,
    pub materials: Vec<GpuMaterial>,
    pub environment_tables: Vec<f32>,
    /// `TexOp`s and `AlphaProgram`s as u32 words (the structs belong to
    /// atoll-render, so they travel as plain words).
    pub texture_ops: Vec<u32>,
    pub mesh_alpha: Vec<u32>,
    pub srgb_to_linear: Vec<f32>,
    pub emission_textures: Vec<GpuEmissionTexture>,
    /// The BVH light sampler's nodes as u32 words (the struct belongs to
    /// atoll-render), each emitter's leaf, and the lights at infinity.
    pub light_nodes: Vec<u32>,
    pub light_leaf: Vec<u32>,
    pub unbounded_lights: Vec<u32>,
    /// The measured BRDFs: one word per BRDF, the bits of the offset of its
    /// tables ([`atoll_scene::MeasuredBrdf::pack`]) in this array, then the
    /// tables one after another.
    pub measured: Vec<f32>,
    /// A realistic camera's lens ([`pack_lens`]); empty for other cameras.
    pub lens: Vec<f32>,
}

/// Words of [`pack_lens`]'s header: element count, pupil count (as u32
/// bits), the film's diagonal, the rear element's distance from it, and the
/// aperture image's width and height (u32 bits; 0 for a round stop).
pub const LENS_HEADER_WORDS: usize = 6;

/// A realistic camera's lens as `FrameParams::lens` points to it: the
/// header ([`LENS_HEADER_WORDS`]), each element's radius, thickness, index
/// and aperture radius front to rear, each ring's exit-pupil bounds, then
/// the aperture image's values row by row.
pub fn pack_lens(lens: &atoll_scene::lens::LensSystem) -> Vec<f32> {
    let count = |n: usize| f32::from_bits(n as u32);
    let (width, height) = lens.aperture.as_ref().map_or((0, 0), |a| (a.width as usize, a.height as usize));
    let mut words = vec![
        count(lens.elements.len()),
        count(lens.pupils.len()),
        lens.film_diagonal,
        lens.rear_z(),
        count(width),
        count(height),
    ];
    for e in &lens.elements {
        words.extend([e.curvature_radius, e.thickness, e.eta, e.aperture_radius]);
    }
    words.extend(lens.pupils.iter().flatten());
    if let Some(aperture) = &lens.aperture {
        words.extend(&aperture.values);
    }
    words
}

/// [`FrameTables::measured`] of `brdfs`: what `FrameParams::measured`
/// points to.
pub fn pack_measured(brdfs: &[Arc<atoll_scene::MeasuredBrdf>]) -> Vec<f32> {
    let mut words = vec![0.0f32; brdfs.len()];
    for (i, brdf) in brdfs.iter().enumerate() {
        words[i] = f32::from_bits(words.len() as u32);
        words.extend(brdf.pack());
    }
    words
}

/// Appends `portal`'s words to `tables`; the emitter's `portal` field for it.
fn push_portal(tables: &mut Vec<f32>, portal: &PortalFrame) -> u32 {
    let offset = tables.len() as u32;
    tables.extend(portal_words(portal));
    offset + 1
}

impl FrameTables {
    pub(crate) fn build(frame: &FrameContext) -> Self {
        let lights = &frame.lights;
        let mut environment_tables = Vec::new();
        // Emission programs follow the material and alpha programs in one table.
        let emission_base = frame.textures.ops.len() as u32;
        let mut emission_textures = Vec::new();
        let emitters = lights
            .emitters
            .iter()
            .map(|e| match *e {
                Emitter::Environment { index, portal } => {
                    let env = &lights.environments[index as usize];
                    let mut g = GpuEmitter::environment(env, env.tables(&mut environment_tables));
                    g.portal = portal
                        .map_or(0, |k| push_portal(&mut environment_tables, &lights.portals[k as usize]));
                    g
                }
                Emitter::Goniometric { position, world_to_light, intensity, map } => {
                    let map = &lights.intensity_maps[map as usize];
                    let mut g = GpuEmitter::zeroed();
                    g.kind = emitter_kind::GONIOMETRIC;
                    g.p = world_to_light.to_cols_array();
                    g.normal = position.to_array();
                    g.radiance = intensity.to_array();
                    g.area = map.resolution as f32;
                    g.table = environment_tables.len() as u32;
                    environment_tables.extend_from_slice(&map.values);
                    g
                }
                Emitter::Projection { position, world_to_light, scale, image } => {
                    // The table: width, height, then the pixels' r, g, b by rows from the top.
                    let image = &lights.projection_images[image as usize];
                    let mut g = GpuEmitter::zeroed();
                    g.kind = emitter_kind::PROJECTION;
                    g.p = world_to_light.to_cols_array();
                    g.normal = position.to_array();
                    g.radiance = [scale, image.tan_half_fov, 0.0];
                    g.table = environment_tables.len() as u32;
                    environment_tables.extend_from_slice(&[image.width as f32, image.height as f32]);
                    environment_tables.extend(image.pixels.iter().flat_map(|p| p.to_array()));
                    g
                }
                Emitter::Infinite { portal: Some(k), .. } => {
                    let mut g = GpuEmitter::new(e);
                    g.portal = push_portal(&mut environment_tables, &lights.portals[k as usize]);
                    g
                }
                Emitter::Triangle { texture: Some(t), .. } => {
                    let mut g = GpuEmitter::new(e);
                    g.table = emission_textures.len() as u32;
                    emission_textures.push(GpuEmissionTexture {
                        uv: [t.uv[0].x, t.uv[0].y, t.uv[1].x, t.uv[1].y, t.uv[2].x, t.uv[2].y],
                        start: emission_base + t.program.start,
                        len: t.program.len,
                    });
                    g
                }
                _ => GpuEmitter::new(e),
            })
            .collect();
        FrameTables {
            emitters,
            environment_tables,
            light_pmf: lights.pmfs().to_vec(),
            light_cdf: lights.cdf().to_vec(),
            infinite_lights: lights.infinite_lights().to_vec(),
            triangle_keys: lights.triangle_keys().to_vec(),
            triangle_bases: lights.triangle_bases().to_vec(),
            materials: frame
                .materials
                .iter()
                .zip(frame.textures.materials.iter().zip(&frame.textures.mix_amount))
                .zip(&frame.textures.shading_normals)
                .map(|((m, (t, amount)), bend)| GpuMaterial::new(m, *t, *amount, *bend))
                .collect(),
            texture_ops: bytemuck::cast_slice(&frame.textures.ops)
                .iter()
                .chain(bytemuck::cast_slice(&lights.emission_ops))
                .copied()
                .collect(),
            emission_textures,
            mesh_alpha: bytemuck::cast_slice(&frame.textures.mesh_alpha).to_vec(),
            srgb_to_linear: atoll_scene::texture::srgb8_to_linear().to_vec(),
            measured: pack_measured(&frame.measured),
            lens: frame.camera.lens_system().map(|lens| pack_lens(lens)).unwrap_or_default(),
            light_nodes: bytemuck::cast_slice(&lights.bvh.nodes).to_vec(),
            light_leaf: lights.bvh.leaf_of.clone(),
            unbounded_lights: lights.unbounded_lights().to_vec(),
        }
    }

    /// Device bytes of the tables plus the parameter block (empty tables
    /// still take one element).
    pub(crate) fn bytes(&self) -> u64 {
        fn b<T>(v: &[T]) -> u64 {
            (v.len().max(1) * std::mem::size_of::<T>()) as u64
        }
        b(&self.emitters)
            + b(&self.light_pmf)
            + b(&self.light_cdf)
            + b(&self.infinite_lights)
            + b(&self.triangle_keys)
            + b(&self.triangle_bases)
            + b(&self.materials)
            + b(&self.environment_tables)
            + b(&self.texture_ops)
            + b(&self.mesh_alpha)
            + b(&self.srgb_to_linear)
            + b(&self.emission_textures)
            + b(&self.light_nodes)
            + b(&self.light_leaf)
            + b(&self.unbounded_lights)
            + b(&self.lens)
            + std::mem::size_of::<FrameParams>() as u64
    }
}

/// [`FrameParams`] resident on a GPU: the parameter block itself
/// ([`Self::device`], what the kernels' `const FrameParams*` takes) and the
/// tables it points into, kept alive as long as this value.
pub struct FrameParamsHost {
    /// The values, with the device pointers filled in.
    pub params: FrameParams,
    /// One `FrameParams` on the device.
    pub device: CudaSlice<FrameParams>,
    emitters: CudaSlice<GpuEmitter>,
    light_pmf: CudaSlice<f32>,
    light_cdf: CudaSlice<f32>,
    infinite_lights: CudaSlice<u32>,
    triangle_keys: CudaSlice<u64>,
    triangle_bases: CudaSlice<u32>,
    materials: CudaSlice<GpuMaterial>,
    environment_tables: CudaSlice<f32>,
    texture_ops: CudaSlice<u32>,
    mesh_alpha: CudaSlice<u32>,
    srgb_to_linear: CudaSlice<f32>,
    emission_textures: CudaSlice<GpuEmissionTexture>,
    light_nodes: CudaSlice<u32>,
    light_leaf: CudaSlice<u32>,
    unbounded_lights: CudaSlice<u32>,
    media_grids: CudaSlice<f32>,
    measured: CudaSlice<f32>,
    lens: CudaSlice<f32>,
}

impl FrameParamsHost {
    /// Uploads `frame`'s light and material tables and the parameter block,
    /// for a scene without texture images.
    pub fn new(gpu: &Arc<Gpu>, frame: &FrameContext) -> Result<Self, CudaError> {
        Self::for_scene(gpu, frame, None)
    }

    /// [`FrameParamsHost::new`] whose textures read `scene`'s images.
    pub(crate) fn for_scene(
        gpu: &Arc<Gpu>,
        frame: &FrameContext,
        scene: Option<&GpuScene>,
    ) -> Result<Self, CudaError> {
        let t = FrameTables::build(frame);
        let emitters = upload(gpu, &t.emitters, "emitters")?;
        let light_pmf = upload(gpu, &t.light_pmf, "light pmf")?;
        let light_cdf = upload(gpu, &t.light_cdf, "light cdf")?;
        let infinite_lights = upload(gpu, &t.infinite_lights, "infinite lights")?;
        let triangle_keys = upload(gpu, &t.triangle_keys, "triangle light keys")?;
        let triangle_bases = upload(gpu, &t.triangle_bases, "triangle light bases")?;
        let materials = upload(gpu, &t.materials, "materials")?;
        let environment_tables = upload(gpu, &t.environment_tables, "environment tables")?;
        let texture_ops = upload(gpu, &t.texture_ops, "texture programs")?;
        let mesh_alpha = upload(gpu, &t.mesh_alpha, "alpha masks")?;
        let srgb_to_linear = upload(gpu, &t.srgb_to_linear, "sRGB table")?;
        let emission_textures = upload(gpu, &t.emission_textures, "emission textures")?;
        let light_nodes = upload(gpu, &t.light_nodes, "light BVH")?;
        let light_leaf = upload(gpu, &t.light_leaf, "light BVH leaves")?;
        let unbounded_lights = upload(gpu, &t.unbounded_lights, "lights at infinity")?;
        let grid_values: Vec<f32> = frame.media.grids.iter().flat_map(|g| g.values.iter().copied()).collect();
        let media_grids = upload(gpu, &grid_values, "media grids")?;
        let measured = upload(gpu, &t.measured, "measured BRDFs")?;
        let lens = upload(gpu, &t.lens, "camera lens")?;
        let stream = &gpu.stream;
        let mut params = FrameParams::from_frame(frame);
        params.emitters = emitters.device_ptr(stream).0;
        params.light_pmf = light_pmf.device_ptr(stream).0;
        params.light_cdf = light_cdf.device_ptr(stream).0;
        params.infinite_lights = infinite_lights.device_ptr(stream).0;
        params.triangle_keys = triangle_keys.device_ptr(stream).0;
        params.triangle_bases = triangle_bases.device_ptr(stream).0;
        params.materials = materials.device_ptr(stream).0;
        params.environment_tables = environment_tables.device_ptr(stream).0;
        params.texture_ops = texture_ops.device_ptr(stream).0;
        // Null tells traversal that no mesh has alpha (it skips the test).
        params.mesh_alpha = if t.mesh_alpha.is_empty() { 0 } else { mesh_alpha.device_ptr(stream).0 };
        params.srgb_to_linear = srgb_to_linear.device_ptr(stream).0;
        params.emission_textures = emission_textures.device_ptr(stream).0;
        params.light_nodes = light_nodes.device_ptr(stream).0;
        params.light_leaf = light_leaf.device_ptr(stream).0;
        params.unbounded_lights = unbounded_lights.device_ptr(stream).0;
        params.media_grids = media_grids.device_ptr(stream).0;
        params.measured = if t.measured.is_empty() { 0 } else { measured.device_ptr(stream).0 };
        params.lens = if t.lens.is_empty() { 0 } else { lens.device_ptr(stream).0 };
        if let Some(scene) = scene {
            params.images = scene.images.device_ptr(stream).0;
            params.texels = scene.texels.device_ptr(stream).0;
        }
        let device = upload(gpu, &[params], "frame parameters")?;
        Ok(FrameParamsHost {
            params,
            device,
            emitters,
            light_pmf,
            light_cdf,
            infinite_lights,
            triangle_keys,
            triangle_bases,
            materials,
            environment_tables,
            texture_ops,
            mesh_alpha,
            srgb_to_linear,
            emission_textures,
            light_nodes,
            light_leaf,
            unbounded_lights,
            media_grids,
            measured,
            lens,
        })
    }

    /// Device bytes held (tables and parameter block).
    pub(crate) fn bytes(&self) -> u64 {
        (self.device.num_bytes()
            + self.emitters.num_bytes()
            + self.light_pmf.num_bytes()
            + self.light_cdf.num_bytes()
            + self.infinite_lights.num_bytes()
            + self.triangle_keys.num_bytes()
            + self.triangle_bases.num_bytes()
            + self.materials.num_bytes()
            + self.environment_tables.num_bytes()
            + self.texture_ops.num_bytes()
            + self.mesh_alpha.num_bytes()
            + self.srgb_to_linear.num_bytes()
            + self.emission_textures.num_bytes()
            + self.light_nodes.num_bytes()
            + self.light_leaf.num_bytes()
            + self.unbounded_lights.num_bytes()
            + self.media_grids.num_bytes()
            + self.measured.num_bytes()
            + self.lens.num_bytes()) as u64
    }
}

#[cfg(test)]
mod tests;
