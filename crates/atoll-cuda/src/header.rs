//! Generated parts of the kernel headers: constants defined once in Rust
//! and the `static_assert`s that pin every shared struct's size and field
//! offsets to Rust's `offset_of!`.
//!
//! Each [`Block`] is text between two marker lines of a `kernels/*.cuh` file:
//!
//! ```text
//! // BEGIN GENERATED record (src/header.rs; regenerate: ATOLL_BLESS=1 cargo test -p atoll-cuda header)
//! ...generated...
//! // END GENERATED record
//! ```
//!
//! The committed headers hold the generated text (NVRTC needs no Rust at
//! run time); the test `header::tests::header_blocks_are_current` fails when
//! one is stale and rewrites them all with `ATOLL_BLESS=1`.

use std::fmt::Write;

use crate::layout::field_layout;

use atoll_render::bsdf::microfacet::SMOOTH_ALPHA;
use atoll_render::filter::{filter_kind, FilterTable, FILTER_BINS};
use atoll_render::frame::MAX_MIX_DEPTH;
use atoll_render::light_bvh::{node_flags, LightNode, NO_NODE};
use atoll_render::material_layout;
use atoll_render::record::{self, flags, MaterialKind, RayRecord, MATERIAL_COEFFS, NO_LIGHT};
use atoll_render::rng::{
    BounceDim, CAMERA_DIMENSIONS, DIMENSIONS_PER_BOUNCE, MEDIUM_DIMENSIONS, TIME_DIMENSION, WALK_DIMENSIONS,
};
use atoll_render::sampling::UNIFORM_SPHERE_PDF;
use atoll_render::spawn::{gamma, SHADOW_EPSILON};

use crate::layout::{
    image_format, mesh_flags, FieldLayout, GpuCurve, GpuImage, GpuInstance, GpuMesh, GpuObject, HitRef,
    HIT_NONE,
};
use crate::params::{
    emitter_kind, integrator_kind, light_node_layout, light_sampler_kind, projection_kind, FrameParams,
    GpuEmissionTexture, GpuEmitter, GpuMaterial, GpuMedium, SceneView, NO_EMISSION_TEXTURE,
};
use crate::work::{GpuWave, WorkFifo, WorkStatus, WORK_CLAIMS, WORK_SLOTS};

/// How to regenerate, repeated in every marker line.
pub(crate) const REGENERATE: &str =
    "src/header.rs; regenerate: ATOLL_BLESS=1 cargo test -p atoll-cuda header";

/// One generated block: `file` (in `kernels/`) holds the text of
/// `generate()` between the markers named `name`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Block {
    pub file: &'static str,
    pub name: &'static str,
    pub generate: fn() -> String,
}

/// Every generated block of the kernel headers.
pub(crate) fn blocks() -> Vec<Block> {
    vec![
        Block { file: "common.cuh", name: "constants", generate: math_constants },
        Block { file: "record.cuh", name: "record", generate: record_asserts },
        Block { file: "materials.cuh", name: "materials", generate: material_layout_constants },
        Block { file: "rng.cuh", name: "rng", generate: rng_constants },
        Block { file: "layout.cuh", name: "layout", generate: layout_asserts },
        Block { file: "params.cuh", name: "params", generate: params_asserts },
        Block { file: "bvh.cuh", name: "bvh", generate: crate::bvh::layout::header_block },
        Block { file: "lbvh.cuh", name: "lbvh", generate: crate::bvh::layout::build_header_block },
        Block { file: "noise.cuh", name: "noise", generate: noise_constants },
        Block { file: "texture.cuh", name: "texture", generate: texture_constants },
        Block { file: "layered.cuh", name: "layered", generate: layered_constants },
    ]
}

/// `static_assert`s of `name`'s size and of every field's offset and size.
pub(crate) fn struct_asserts(name: &str, size: usize, fields: &[(&str, usize, usize)]) -> String {
    let mut s = format!("static_assert(sizeof({name}) == {size}, \"{name}: size differs from Rust\");\n");
    s.push_str("#ifdef ATOLL_CHECK_LAYOUT\n");
    for (field, offset, field_size) in fields {
        let _ = writeln!(
            s,
            "static_assert(__builtin_offsetof({name}, {field}) == {offset} && sizeof({name}::{field}) == {field_size}, \
             \"{name}.{field}: offset or size differs from Rust\");"
        );
    }
    s.push_str("#endif\n");
    s
}

fn assert_struct<T>(name: &str, fields: FieldLayout) -> String {
    struct_asserts(name, std::mem::size_of::<T>(), &fields)
}

/// `inline constexpr` integer constant (`inline`: no "never referenced"
/// warnings from NVRTC for constants a kernel file does not use).
fn const_uint(ty: &str, name: &str, value: u64) -> String {
    let suffix = if ty == "unsigned int" { "u" } else { "" };
    format!("inline constexpr {ty} {name} = {value}{suffix};\n")
}

/// `constexpr float`; Rust's shortest round-trip formatting parses back to
/// the same f32.
fn const_float(name: &str, value: f32) -> String {
    format!("inline constexpr float {name} = {value:?}f;\n")
}

/// Float constants of `sampling`, `bsdf` and `std::f32::consts`.
pub(crate) fn math_constants() -> String {
    use std::f32::consts::{FRAC_1_PI, FRAC_PI_2, FRAC_PI_4, PI};
    [
        const_float("PI", PI),
        const_float("FRAC_1_PI", FRAC_1_PI),
        const_float("FRAC_PI_2", FRAC_PI_2),
        const_float("FRAC_PI_4", FRAC_PI_4),
        const_float("UNIFORM_SPHERE_PDF", UNIFORM_SPHERE_PDF),
        const_float("SMOOTH_ALPHA", SMOOTH_ALPHA),
        const_float("SHADOW_EPSILON", SHADOW_EPSILON),
        const_float("GAMMA_3", gamma(3)),
        const_float("GAMMA_6", gamma(6)),
        const_float("GAMMA_7", gamma(7)),
        const_float("ONE_MINUS_EPSILON", 1.0 - f32::EPSILON / 2.0),
    ]
    .concat()
}

/// `record` constants (flags, material kinds, `NO_LIGHT`) and the
/// `RayRecord` asserts.
pub(crate) fn record_asserts() -> String {
    let mut s = String::new();
    s += &const_uint("unsigned int", "NO_LIGHT", NO_LIGHT as u64);
    s += &const_uint("unsigned int", "MATERIAL_COEFFS", MATERIAL_COEFFS as u64);
    s += &const_uint("unsigned int", "MAX_MIX_DEPTH", MAX_MIX_DEPTH as u64);
    for (name, value) in [
        ("FLAG_SHADOW", flags::SHADOW),
        ("FLAG_OCCLUDED", flags::OCCLUDED),
        ("FLAG_HIT", flags::HIT),
        ("FLAG_SPECULAR", flags::SPECULAR),
        ("FLAG_MEDIUM_MASK", flags::MEDIUM_MASK),
    ] {
        s += &const_uint("unsigned char", name, value as u64);
    }
    s += &const_uint("unsigned int", "FLAG_MEDIUM_SHIFT", flags::MEDIUM_SHIFT as u64);
    for (name, kind) in [
        ("MATERIAL_NONE", MaterialKind::None),
        ("MATERIAL_DIFFUSE", MaterialKind::Diffuse),
        ("MATERIAL_CONDUCTOR", MaterialKind::Conductor),
        ("MATERIAL_DIELECTRIC", MaterialKind::Dielectric),
        ("MATERIAL_DIFFUSE_TRANSMISSION", MaterialKind::DiffuseTransmission),
        ("MATERIAL_THIN_DIELECTRIC", MaterialKind::ThinDielectric),
        ("MATERIAL_MIX", MaterialKind::Mix),
        ("MATERIAL_COATED_DIFFUSE", MaterialKind::CoatedDiffuse),
        ("MATERIAL_PRINCIPLED", MaterialKind::Principled),
        ("MATERIAL_COATED_CONDUCTOR", MaterialKind::CoatedConductor),
        ("MATERIAL_HAIR", MaterialKind::Hair),
        ("MATERIAL_MEASURED", MaterialKind::Measured),
        ("MATERIAL_SUBSURFACE", MaterialKind::Subsurface),
    ] {
        s += &const_uint("unsigned int", name, kind as u64);
    }
    s += &const_float("HAIR_OFFSET_FROM_NORMAL", atoll_render::bsdf::hair::OFFSET_FROM_NORMAL);
    s + &assert_struct::<RayRecord>("RayRecord", record::field_layout())
}

/// Each material kind's coefficient slots (`atoll_render::material_layout`)
/// as `COEFF_<KIND>_<PARAMETER>`, e.g. `COEFF_CONDUCTOR_ALPHA_X`, and the
/// coated conductor's walk, which has no slots, and the size of a measured
/// BRDF's header (`MeasuredBrdf::pack`).
pub(crate) fn material_layout_constants() -> String {
    let mut s = String::new();
    for layout in material_layout::LAYOUTS {
        for (param, slots) in layout.params {
            let name = format!("COEFF_{}_{param}", layout.name.to_uppercase());
            s += &const_uint("unsigned int", &name, slots.start as u64);
        }
    }
    let (max_depth, n_samples) = atoll_scene::Material::COATED_CONDUCTOR_WALK;
    s += &const_uint("unsigned int", "COATED_CONDUCTOR_MAX_DEPTH", max_depth as u64);
    s += &const_uint("unsigned int", "COATED_CONDUCTOR_N_SAMPLES", n_samples as u64);
    let header = atoll_scene::measured::PACK_HEADER_WORDS;
    s + &const_uint("unsigned int", "MEASURED_HEADER_WORDS", header as u64)
}

/// The random-number dimension layout of `rng`.
pub(crate) fn rng_constants() -> String {
    let mut s = const_uint("unsigned int", "CAMERA_DIMENSIONS", CAMERA_DIMENSIONS as u64);
    s += &const_uint("unsigned int", "DIMENSIONS_PER_BOUNCE", DIMENSIONS_PER_BOUNCE as u64);
    s += &const_uint("unsigned int", "MEDIUM_DIMENSIONS", MEDIUM_DIMENSIONS as u64);
    s += &const_uint("unsigned int", "TIME_DIMENSION", TIME_DIMENSION as u64);
    s += &const_uint("unsigned int", "WALK_DIMENSIONS", WALK_DIMENSIONS as u64);
    for (name, dim) in [
        ("BOUNCE_DIM_LIGHT_SELECT", BounceDim::LightSelect),
        ("BOUNCE_DIM_LIGHT_POSITION", BounceDim::LightPosition),
        ("BOUNCE_DIM_BSDF_LOBE", BounceDim::BsdfLobe),
        ("BOUNCE_DIM_BSDF_DIRECTION", BounceDim::BsdfDirection),
        ("BOUNCE_DIM_RUSSIAN_ROULETTE", BounceDim::RussianRoulette),
        ("BOUNCE_DIM_MATERIAL_CHOICE", BounceDim::MaterialChoice),
    ] {
        s += &const_uint("unsigned int", name, dim as u64);
    }
    s
}

/// Mesh flags, `HIT_NONE`, the pixel filter's table size and the asserts
/// of the scene-table structs.
pub(crate) fn layout_asserts() -> String {
    let mut s = const_uint("unsigned int", "HIT_NONE", HIT_NONE as u64);
    // The pixel filter's table size (params.cuh's `FilterTable` is made of it).
    s += &const_uint("unsigned int", "FILTER_BINS", FILTER_BINS as u64);
    // Entries of params.cuh's `FrameParams::media`.
    s += &const_uint("unsigned int", "MEDIA_SLOTS", crate::params::MEDIA_SLOTS as u64);
    s += &const_uint("unsigned int", "NO_GRID", crate::params::NO_GRID as u64);
    s += &const_uint("unsigned int", "GRID_FIELD_CONSTANT", crate::params::grid_field::CONSTANT as u64);
    s += &const_uint("unsigned int", "GRID_FIELD_RGB", crate::params::grid_field::RGB as u64);
    for (name, value) in [
        ("MESH_HAS_NORMALS", mesh_flags::HAS_NORMALS),
        ("MESH_FLIP_NORMALS", mesh_flags::FLIP_NORMALS),
        ("MESH_EMISSIVE", mesh_flags::EMISSIVE),
        ("MESH_HAS_UVS", mesh_flags::HAS_UVS),
        ("MESH_MEDIA_ONLY", mesh_flags::MEDIA_ONLY),
        ("MESH_CURVES", mesh_flags::CURVES),
        ("CURVE_FLAT", atoll_scene::CurveKind::Flat.code()),
        ("CURVE_CYLINDER", atoll_scene::CurveKind::Cylinder.code()),
        ("CURVE_RIBBON", atoll_scene::CurveKind::Ribbon.code()),
        ("CURVE_RECORD_MARKER", crate::bvh::CURVE_RECORD_MARKER),
        ("NO_CURVE", crate::scene::NO_CURVE),
        ("NO_MOTION", crate::layout::NO_MOTION),
        ("MESH_MEDIA_SHIFT", mesh_flags::MEDIA_SHIFT),
        ("IMAGE_RGBA8", image_format::RGBA8),
        ("IMAGE_RGBA8_SRGB", image_format::RGBA8_SRGB),
        ("IMAGE_RGBA_F32", image_format::RGBA_F32),
    ] {
        s += &const_uint("unsigned int", name, value as u64);
    }
    s += &assert_struct::<GpuMesh>("GpuMesh", GpuMesh::field_layout());
    s += &assert_struct::<GpuObject>("GpuObject", GpuObject::field_layout());
    s += &assert_struct::<GpuCurve>("GpuCurve", GpuCurve::field_layout());
    s += &assert_struct::<GpuInstance>("GpuInstance", GpuInstance::field_layout());
    s += &assert_struct::<crate::layout::GpuMotion>("GpuMotion", crate::layout::GpuMotion::field_layout());
    s += &assert_struct::<HitRef>("HitRef", HitRef::field_layout());
    s += &assert_struct::<GpuImage>("GpuImage", GpuImage::field_layout());
    s += &const_uint("unsigned int", "WORK_SLOTS", WORK_SLOTS as u64);
    s += &const_uint("unsigned int", "WORK_CLAIMS", WORK_CLAIMS as u64);
    s += &assert_struct::<GpuWave>("GpuWave", GpuWave::field_layout());
    s += &assert_struct::<WorkStatus>("WorkStatus", WorkStatus::field_layout());
    s + &assert_struct::<WorkFifo>("WorkFifo", WorkFifo::field_layout())
}

/// Texture program op codes, store modes, alpha modes and the asserts of
/// the program structs (`atoll_render::texture`).
pub(crate) fn texture_constants() -> String {
    use atoll_render::texture::{
        alpha_mode, op, projection, store, AlphaProgram, ProgramRange, TexOp, PROJECTED, TEXTURE_STACK,
    };
    let mut s = String::new();
    for (name, value) in [
        ("TEXTURE_STACK", TEXTURE_STACK as u32),
        ("TEX_CONSTANT", op::CONSTANT),
        ("TEX_IMAGE", op::IMAGE),
        ("TEX_CHECKERBOARD", op::CHECKERBOARD),
        ("TEX_SCALE", op::SCALE),
        ("TEX_MIX", op::MIX),
        ("TEX_STORE", op::STORE),
        ("TEX_PROJECT", op::PROJECT),
        ("TEX_DATA", op::DATA),
        ("TEX_FACING", op::FACING),
        ("TEX_NOISE", op::NOISE),
        ("TEX_DOTS", op::DOTS),
        ("TEX_SOLID_CHECKERBOARD", op::SOLID_CHECKERBOARD),
        ("TEX_BILERP", op::BILERP),
        ("TEX_PROJECTED", PROJECTED),
        ("PROJECT_SPHERICAL", projection::SPHERICAL),
        ("PROJECT_CYLINDRICAL", projection::CYLINDRICAL),
        ("PROJECT_PLANAR", projection::PLANAR),
        ("PROJECT_POINT", projection::POINT),
        ("BUMP_NONE", atoll_render::bump::kind::NONE),
        ("BUMP_BUMP", atoll_render::bump::kind::BUMP),
        ("BUMP_NORMAL_MAP", atoll_render::bump::kind::NORMAL_MAP),
        ("STORE_RGB", store::RGB),
        ("STORE_FLOAT", store::FLOAT),
        ("STORE_ROUGHNESS", store::ROUGHNESS),
        ("STORE_CONDUCTOR_REFLECTANCE", store::CONDUCTOR_REFLECTANCE),
        ("STORE_ASYMMETRY", store::ASYMMETRY),
        ("STORE_ALBEDO", store::ALBEDO),
        ("STORE_HAIR_ROUGHNESS", store::HAIR_ROUGHNESS),
        ("STORE_HAIR_REFLECTANCE", store::HAIR_REFLECTANCE),
        ("STORE_EUMELANIN", store::EUMELANIN),
        ("STORE_PHEOMELANIN", store::PHEOMELANIN),
        ("ALPHA_NONE", alpha_mode::NONE),
        ("ALPHA_STOCHASTIC", alpha_mode::STOCHASTIC),
        ("ALPHA_CUTOFF", alpha_mode::CUTOFF),
        ("ALPHA_TEXTURE_MASK", alpha_mode::TEXTURE_MASK),
        ("WRAP_REPEAT", atoll_scene::Wrap::Repeat as u32),
        ("WRAP_CLAMP", atoll_scene::Wrap::Clamp as u32),
        ("WRAP_BLACK", atoll_scene::Wrap::Black as u32),
        ("WRAP_MIRROR", atoll_scene::Wrap::Mirror as u32),
        ("CHANNEL_RGB", atoll_scene::Channel::Rgb as u32),
        ("CHANNEL_AVERAGE", atoll_scene::Channel::Average as u32),
        ("CHANNEL_ALPHA", atoll_scene::Channel::Alpha as u32),
        ("CHANNEL_RED", atoll_scene::Channel::Red as u32),
        ("CHANNEL_GREEN", atoll_scene::Channel::Green as u32),
        ("CHANNEL_BLUE", atoll_scene::Channel::Blue as u32),
        ("IMAGE_FILTER_SHIFT", atoll_render::texture::IMAGE_FILTER_SHIFT),
        ("IMAGE_LEVELS_SHIFT", atoll_render::texture::IMAGE_LEVELS_SHIFT),
        ("FILTER_NONE", atoll_scene::ImageFilter::None as u32),
        ("FILTER_POINT", atoll_scene::ImageFilter::Point as u32),
        ("FILTER_BILINEAR", atoll_scene::ImageFilter::Bilinear as u32),
    ] {
        s += &const_uint("unsigned int", name, value as u64);
    }
    s += &const_float("BUMP_STEP", atoll_render::bump::BUMP_STEP);
    for (name, rgb) in [
        ("EUMELANIN_SIGMA_A", atoll_scene::HairParams::EUMELANIN_SIGMA_A),
        ("PHEOMELANIN_SIGMA_A", atoll_scene::HairParams::PHEOMELANIN_SIGMA_A),
    ] {
        for (channel, value) in ["R", "G", "B"].iter().zip(rgb.to_array()) {
            s += &const_float(&format!("{name}_{channel}"), value);
        }
    }
    s += &assert_struct::<TexOp>("TexOp", field_layout!(TexOp { code, a, b, c, f }));
    s += &assert_struct::<ProgramRange>("ProgramRange", field_layout!(ProgramRange { start, len }));
    s + &assert_struct::<AlphaProgram>("AlphaProgram", field_layout!(AlphaProgram { program, mode, cutoff }))
}

/// The noise kinds, the octave cap and Perlin's permutation table
/// (`atoll_render::noise`).
pub(crate) fn noise_constants() -> String {
    use atoll_render::noise::{kind, MAX_OCTAVES, PERMUTATION};
    let mut s = String::new();
    for (name, value) in [
        ("NOISE_FBM", kind::FBM),
        ("NOISE_WRINKLED", kind::WRINKLED),
        ("NOISE_WINDY", kind::WINDY),
        ("NOISE_MARBLE", kind::MARBLE),
        ("NOISE_MAX_OCTAVES", MAX_OCTAVES),
    ] {
        s += &const_uint("unsigned int", name, value as u64);
    }
    s += "__device__ const unsigned char NOISE_PERMUTATION[256] = {\n";
    for row in PERMUTATION.chunks(16) {
        let row: Vec<String> = row.iter().map(|v| v.to_string()).collect();
        let _ = writeln!(s, "    {},", row.join(", "));
    }
    s + "};\n"
}

/// The layered BSDF's random-stream tags, seed rounding and smallest layer
/// thickness (`atoll_render::bsdf::layered`).
pub(crate) fn layered_constants() -> String {
    use atoll_render::bsdf::layered::{DIRECTION_SEED_DROP_BITS, TAG_EVAL, TAG_PDF, TAG_SAMPLE};
    let mut s = const_float("FLT_MIN_POSITIVE", f32::MIN_POSITIVE);
    s += &const_uint("unsigned int", "DIRECTION_SEED_DROP_BITS", DIRECTION_SEED_DROP_BITS as u64);
    for (name, value) in
        [("LAYERED_TAG_EVAL", TAG_EVAL), ("LAYERED_TAG_SAMPLE", TAG_SAMPLE), ("LAYERED_TAG_PDF", TAG_PDF)]
    {
        s += &const_uint("unsigned int", name, value as u64);
    }
    s
}

/// Emitter and integrator kinds and the asserts of the kernel parameters.
pub(crate) fn params_asserts() -> String {
    let mut s = const_float("PROJECTION_HITHER", atoll_scene::ProjectionImage::HITHER);
    for (name, value) in [
        ("EMITTER_POINT", emitter_kind::POINT),
        ("EMITTER_DISTANT", emitter_kind::DISTANT),
        ("EMITTER_INFINITE", emitter_kind::INFINITE),
        ("EMITTER_TRIANGLE", emitter_kind::TRIANGLE),
        ("EMITTER_SPOT", emitter_kind::SPOT),
        ("EMITTER_ENVIRONMENT", emitter_kind::ENVIRONMENT),
        ("EMITTER_GONIOMETRIC", emitter_kind::GONIOMETRIC),
        ("EMITTER_PROJECTION", emitter_kind::PROJECTION),
        ("PROJECTION_PERSPECTIVE", projection_kind::PERSPECTIVE),
        ("PROJECTION_ORTHOGRAPHIC", projection_kind::ORTHOGRAPHIC),
        ("PROJECTION_SPHERE_EQUAL_AREA", projection_kind::SPHERE_EQUAL_AREA),
        ("PROJECTION_SPHERE_LAT_LONG", projection_kind::SPHERE_LAT_LONG),
        ("PROJECTION_REALISTIC", projection_kind::REALISTIC),
        ("LENS_HEADER_WORDS", crate::params::LENS_HEADER_WORDS as u32),
        ("LENS_PUPIL_RINGS", atoll_scene::lens::PUPIL_RINGS as u32),
        ("INTEGRATOR_PATH", integrator_kind::PATH),
        ("INTEGRATOR_AMBIENT_OCCLUSION", integrator_kind::AMBIENT_OCCLUSION),
        ("LIGHT_SAMPLER_POWER", light_sampler_kind::POWER),
        ("LIGHT_SAMPLER_BVH", light_sampler_kind::BVH),
        ("LIGHT_NODE_LEAF", node_flags::LEAF),
        ("LIGHT_NODE_TWO_SIDED", node_flags::TWO_SIDED),
        ("NO_LIGHT_NODE", NO_NODE),
        ("FILTER_PIXEL", filter_kind::PIXEL),
        ("FILTER_BOX", filter_kind::BOX),
        ("FILTER_TABULATED", filter_kind::TABULATED),
    ] {
        s += &const_uint("unsigned int", name, value as u64);
    }
    s += &assert_struct::<FilterTable>(
        "FilterTable",
        field_layout!(FilterTable { kind, negative, pad, radius, weight, cdf }),
    );
    s += &assert_struct::<GpuEmitter>("GpuEmitter", GpuEmitter::field_layout());
    s += &assert_struct::<GpuMaterial>("GpuMaterial", GpuMaterial::field_layout());
    s += &assert_struct::<LightNode>("LightNode", light_node_layout());
    s += &const_uint("unsigned int", "NO_EMISSION_TEXTURE", NO_EMISSION_TEXTURE as u64);
    s += &assert_struct::<GpuEmissionTexture>("GpuEmissionTexture", GpuEmissionTexture::field_layout());
    s += &assert_struct::<GpuMedium>("GpuMedium", GpuMedium::field_layout());
    s += &assert_struct::<crate::params::GpuFootprint>(
        "GpuFootprint",
        crate::params::GpuFootprint::field_layout(),
    );
    s += &assert_struct::<FrameParams>("FrameParams", FrameParams::field_layout());
    s + &assert_struct::<SceneView>("SceneView", SceneView::field_layout())
}

/// `source` with the block `name` replaced by `text` (markers rewritten
/// too); `None` when the markers are missing or out of order.
pub(crate) fn splice_block(source: &str, name: &str, text: &str) -> Option<String> {
    let begin = format!("// BEGIN GENERATED {name} ");
    let end = format!("// END GENERATED {name}");
    let lines: Vec<&str> = source.lines().collect();
    let b = lines.iter().position(|l| l.starts_with(&begin))?;
    let e = b + lines[b..].iter().position(|l| l.trim_end() == end)?;
    let mut out = String::with_capacity(source.len() + text.len());
    for line in &lines[..b] {
        out.push_str(line);
        out.push('\n');
    }
    let _ = writeln!(out, "// BEGIN GENERATED {name} ({REGENERATE})");
    out.push_str(text);
    if !text.is_empty() && !text.ends_with('\n') {
        out.push('\n');
    }
    out.push_str(&end);
    out.push('\n');
    for line in &lines[e + 1..] {
        out.push_str(line);
        out.push('\n');
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn kernel_dir() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("kernels")
    }

    #[test]
    fn header_blocks_are_current() {
        let bless = std::env::var_os("ATOLL_BLESS").is_some_and(|v| !v.is_empty() && v != "0");
        let mut stale = Vec::new();
        for block in blocks() {
            let path = kernel_dir().join(block.file);
            let source = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            let fresh = splice_block(&source, block.name, &(block.generate)()).unwrap_or_else(|| {
                panic!("{}: no `// BEGIN/END GENERATED {}` markers", block.file, block.name)
            });
            if fresh != source {
                if bless {
                    std::fs::write(&path, fresh).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                } else {
                    stale.push(format!("{} ({})", block.file, block.name));
                }
            }
        }
        assert!(
            stale.is_empty(),
            "generated kernel header blocks are stale: {}; rewrite them with `ATOLL_BLESS=1 cargo test -p atoll-cuda \
             header` and commit the result",
            stale.join(", ")
        );
    }

    /// Every layout lists every field: consecutive, no gaps, covering the
    /// struct (all shared structs carry explicit padding fields).
    #[test]
    fn header_layouts_cover_their_structs() {
        let all: [(&str, usize, FieldLayout); 15] = [
            ("RayRecord", std::mem::size_of::<RayRecord>(), record::field_layout()),
            ("GpuMesh", std::mem::size_of::<GpuMesh>(), GpuMesh::field_layout()),
            ("GpuObject", std::mem::size_of::<GpuObject>(), GpuObject::field_layout()),
            ("GpuInstance", std::mem::size_of::<GpuInstance>(), GpuInstance::field_layout()),
            (
                "GpuMotion",
                std::mem::size_of::<crate::layout::GpuMotion>(),
                crate::layout::GpuMotion::field_layout(),
            ),
            ("HitRef", std::mem::size_of::<HitRef>(), HitRef::field_layout()),
            ("GpuWave", std::mem::size_of::<GpuWave>(), GpuWave::field_layout()),
            ("WorkStatus", std::mem::size_of::<WorkStatus>(), WorkStatus::field_layout()),
            ("WorkFifo", std::mem::size_of::<WorkFifo>(), WorkFifo::field_layout()),
            ("GpuEmitter", std::mem::size_of::<GpuEmitter>(), GpuEmitter::field_layout()),
            ("GpuMaterial", std::mem::size_of::<GpuMaterial>(), GpuMaterial::field_layout()),
            ("GpuMedium", std::mem::size_of::<GpuMedium>(), GpuMedium::field_layout()),
            (
                "GpuFootprint",
                std::mem::size_of::<crate::params::GpuFootprint>(),
                crate::params::GpuFootprint::field_layout(),
            ),
            ("FrameParams", std::mem::size_of::<FrameParams>(), FrameParams::field_layout()),
            ("SceneView", std::mem::size_of::<SceneView>(), SceneView::field_layout()),
        ];
        for (name, size, fields) in all {
            let mut end = 0;
            for (field, offset, field_size) in &fields {
                assert_eq!(*offset, end, "{name}: gap or overlap before {field}");
                end = offset + field_size;
            }
            assert_eq!(end, size, "{name}: fields do not cover the struct");
        }
    }

    #[test]
    fn header_text_forms() {
        let s = struct_asserts("A", 8, &[("x", 0, 4), ("y", 4, 4)]);
        assert!(s.starts_with("static_assert(sizeof(A) == 8,"), "{s}");
        assert!(s.contains("__builtin_offsetof(A, y) == 4 && sizeof(A::y) == 4"), "{s}");
        assert_eq!(const_float("X", 0.5), "inline constexpr float X = 0.5f;\n");
        assert_eq!(const_float("Y", 1.0), "inline constexpr float Y = 1.0f;\n");
        assert_eq!(const_uint("unsigned int", "N", 7), "inline constexpr unsigned int N = 7u;\n");
        // Every float constant parses back to the same f32.
        for line in math_constants().lines() {
            let value = line.split(" = ").nth(1).unwrap().trim_end_matches(";").trim_end_matches('f');
            let parsed: f32 = value.parse().unwrap();
            assert!(line.contains(&format!("{parsed:?}f")), "{line}");
        }
        let src = "a\n// BEGIN GENERATED x (old)\nstale\n// END GENERATED x\nb\n";
        let out = splice_block(src, "x", "new\n").unwrap();
        assert_eq!(out, format!("a\n// BEGIN GENERATED x ({REGENERATE})\nnew\n// END GENERATED x\nb\n"));
        assert_eq!(splice_block(&out, "x", "new\n").unwrap(), out, "idempotent");
        assert!(splice_block("a\n", "x", "").is_none());
    }
}
