// What the wavefront kernels are launched with: the frame's parameters
// (camera, options, light and material tables) and the scene tables' device
// pointers. Mirrors `atoll_cuda::params`; the generated block asserts every
// offset and size against the Rust structs and defines their constants.
#pragma once

#include "layout.cuh"

/// Mirror of `params::GpuEmitter` (80 bytes), one `lights::Emitter`. By
/// `kind` (`EMITTER_*`): point: `p[0..3]` position, `radiance` intensity;
/// distant: `p[0..3]` direction of travel; infinite: `radiance` only;
/// triangle: `p` the three world-space vertices, `normal`, `area`,
/// `two_sided`, `error` the corners' error bound along the normal.
struct GpuEmitter {
    unsigned int kind;
    unsigned int two_sided;
    float area;
    unsigned int table;
    float p[9];
    float normal[3];
    float radiance[3];
    float error;
    // Infinite and environment emitters: 1 + their portal's offset in
    // `environment_tables` (portal.cuh), 0 for none.
    unsigned int portal;
};

/// Mirror of `atoll_render::light_bvh::LightNode` (80 bytes).
struct LightNode {
    float min[3];
    float phi;
    float max[3];
    float cos_theta_o;
    float w[3];
    float cos_theta_e;
    float sin_theta_o;
    float radius;
    unsigned int child_or_light;
    unsigned int parent;
    unsigned int flags;
    unsigned int pad[3];
};

/// Mirror of `params::GpuMaterial` (48 bytes): a `PackedMaterial`, f16 bits.
struct __align__(16) GpuMaterial {
    unsigned short coeffs[16];
    unsigned int kind;
    unsigned int pad[3];
};

/// Mirror of `params::GpuEmissionTexture` (32 bytes): a triangle
/// emitter's corner uvs and its program in `texture_ops`.
struct GpuEmissionTexture {
    float uv[6];
    unsigned int start, len;
};

/// Mirror of `filter::FilterTable`: the pixel filter's sampling tables
/// (camera.cuh samples them).
struct FilterTable {
    unsigned int kind;
    unsigned int negative[2];
    unsigned int pad;
    float radius[2];
    float weight[2];
    float cdf[2 * FILTER_BINS];
};

/// Mirror of `params::GpuFootprint` (144 bytes): the camera's smallest
/// one-pixel differentials (`atoll_render::footprint::CameraFootprint`),
/// matrices row-major, x's then y's.
struct GpuFootprint {
    float camera_position[3];
    float spp_scale;
    float camera_from_world[9];
    float world_from_camera[9];
    float min_position[6];
    float min_direction[6];
    float pad[2];
};

/// Mirror of `params::GpuMedium`: a medium's coefficients (a grid's field
/// scales), its grid's place (`grid_first` NO_GRID: the same coefficients
/// everywhere) and where its fields come from (GRID_FIELD_CONSTANT, a
/// channel, or a channel | GRID_FIELD_RGB).
struct GpuMedium {
    float sigma_a[3];
    float sigma_s[3];
    float le[3];
    float g;
    unsigned int grid_first;
    unsigned int grid_resolution[3];
    float world_to_lattice[12];
    unsigned int grid_plane;
    unsigned int grid_fields[3];
    /// 1 for a subsurface material's interior (walked without light sampling).
    unsigned int subsurface;
};

/// Mirror of `params::FrameParams`: everything shading needs, identical on
/// every device (`atoll_render::FrameContext` flattened).
struct FrameParams {
    // CameraRays (camera.rs): row-major 3x4 camera-to-world, screen window.
    float camera_to_world[12];
    float window_min[2];
    float window_max[2];
    float raster_size[2];
    float lens_radius;
    float focal_distance;
    unsigned int projection;
    /// 1 when the camera moves: camera_motion places it at each path's time.
    unsigned int camera_moves;
    // RenderOptions.
    unsigned int resolution[2];
    unsigned int seed;
    unsigned int integrator;
    unsigned int max_depth;
    float ao_max_distance;
    unsigned int russian_roulette;
    // Table sizes.
    unsigned int light_count;
    unsigned int infinite_count;
    unsigned int triangle_key_count;
    unsigned int material_count;
    unsigned int light_sampler;
    // LightSet: emitters, pmf (light_count), cdf (light_count + 1), infinite
    // light indices, sorted (instance << 32 | mesh) keys and their base
    // light indices; the packed materials.
    const GpuEmitter* emitters;
    const float* light_pmf;
    const float* light_cdf;
    const unsigned int* infinite_lights;
    const unsigned long long* triangle_keys;
    const unsigned int* triangle_bases;
    const GpuMaterial* materials;
    /// The environment emitters' tables (see environment.cuh).
    const float* environment_tables;
    /// Texture programs (`TexOp`s, texture.cuh); materials name theirs.
    const void* texture_ops;
    /// `AlphaProgram` per scene mesh; null when no mesh has alpha.
    const void* mesh_alpha;
    /// sRGB byte to linear float.
    const float* srgb_to_linear;
    /// `GpuEmissionTexture` per textured triangle emitter (`GpuEmitter::table`).
    const void* emission_textures;
    /// The scene's texture images and their texels (texture.cuh).
    const GpuImage* images;
    const unsigned int* texels;
    // The BVH light sampler (light_bvh.cuh): its nodes, the leaf of each
    // emitter, and the lights at infinity chosen apart from the tree.
    const LightNode* light_nodes;
    const unsigned int* light_leaf;
    const unsigned int* unbounded_lights;
    unsigned int light_node_count;
    unsigned int unbounded_count;
    FilterTable filter;
    // MediumTable (medium.rs): homogeneous media by MediumIndex, 0 the vacuum.
    unsigned int media_count;
    unsigned int camera_medium;
    float shadow_reach;
    unsigned int media_pad;
    const float* media_grids;
    // The measured BRDFs (measured.cuh): per BRDF the bits of its tables'
    // offset in this array, then the tables. Null for none.
    const float* measured;
    // A realistic camera's lens (params.rs `pack_lens`; lens.cuh); null for
    // other cameras.
    const float* lens;
    GpuMedium media[MEDIA_SLOTS];
    /// A moving camera's camera-to-world motion.
    GpuMotion camera_motion;
    /// What textures need to estimate a hit's footprint (footprint.cuh).
    GpuFootprint footprint;
};

/// Mirror of `params::SceneView`: device pointers of the GPU scene tables
/// (crate docs in lib.rs describe them) and their sizes.
struct SceneView {
    const float* vertices;
    const float* normals;
    const unsigned int* triangles;
    const unsigned int* triangle_mesh;
    const GpuMesh* meshes;
    const GpuInstance* instances;
    /// u, v per vertex (meshes with MESH_HAS_UVS).
    const float* uvs;
    /// Per triangle, the curve piece its proxy stands for (NO_CURVE for triangles).
    const unsigned int* curve_of;
    /// The curve pieces (MESH_CURVES meshes).
    const GpuCurve* curves;
    /// Moving instances' motions (GpuInstance::motion).
    const GpuMotion* motions;
    unsigned int triangle_count;
    unsigned int mesh_count;
    unsigned int instance_count;
    unsigned int vertex_count;
};

// BEGIN GENERATED params (src/header.rs; regenerate: ATOLL_BLESS=1 cargo test -p atoll-cuda header)
inline constexpr float PROJECTION_HITHER = 0.001f;
inline constexpr unsigned int EMITTER_POINT = 0u;
inline constexpr unsigned int EMITTER_DISTANT = 1u;
inline constexpr unsigned int EMITTER_INFINITE = 2u;
inline constexpr unsigned int EMITTER_TRIANGLE = 3u;
inline constexpr unsigned int EMITTER_SPOT = 4u;
inline constexpr unsigned int EMITTER_ENVIRONMENT = 5u;
inline constexpr unsigned int EMITTER_GONIOMETRIC = 6u;
inline constexpr unsigned int EMITTER_PROJECTION = 7u;
inline constexpr unsigned int PROJECTION_PERSPECTIVE = 0u;
inline constexpr unsigned int PROJECTION_ORTHOGRAPHIC = 1u;
inline constexpr unsigned int PROJECTION_SPHERE_EQUAL_AREA = 2u;
inline constexpr unsigned int PROJECTION_SPHERE_LAT_LONG = 3u;
inline constexpr unsigned int PROJECTION_REALISTIC = 4u;
inline constexpr unsigned int LENS_HEADER_WORDS = 6u;
inline constexpr unsigned int LENS_PUPIL_RINGS = 64u;
inline constexpr unsigned int INTEGRATOR_PATH = 0u;
inline constexpr unsigned int INTEGRATOR_AMBIENT_OCCLUSION = 1u;
inline constexpr unsigned int LIGHT_SAMPLER_POWER = 0u;
inline constexpr unsigned int LIGHT_SAMPLER_BVH = 1u;
inline constexpr unsigned int LIGHT_NODE_LEAF = 1u;
inline constexpr unsigned int LIGHT_NODE_TWO_SIDED = 2u;
inline constexpr unsigned int NO_LIGHT_NODE = 4294967295u;
inline constexpr unsigned int FILTER_PIXEL = 0u;
inline constexpr unsigned int FILTER_BOX = 1u;
inline constexpr unsigned int FILTER_TABULATED = 2u;
static_assert(sizeof(FilterTable) == 288, "FilterTable: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(FilterTable, kind) == 0 && sizeof(FilterTable::kind) == 4, "FilterTable.kind: offset or size differs from Rust");
static_assert(__builtin_offsetof(FilterTable, negative) == 4 && sizeof(FilterTable::negative) == 8, "FilterTable.negative: offset or size differs from Rust");
static_assert(__builtin_offsetof(FilterTable, pad) == 12 && sizeof(FilterTable::pad) == 4, "FilterTable.pad: offset or size differs from Rust");
static_assert(__builtin_offsetof(FilterTable, radius) == 16 && sizeof(FilterTable::radius) == 8, "FilterTable.radius: offset or size differs from Rust");
static_assert(__builtin_offsetof(FilterTable, weight) == 24 && sizeof(FilterTable::weight) == 8, "FilterTable.weight: offset or size differs from Rust");
static_assert(__builtin_offsetof(FilterTable, cdf) == 32 && sizeof(FilterTable::cdf) == 256, "FilterTable.cdf: offset or size differs from Rust");
#endif
static_assert(sizeof(GpuEmitter) == 84, "GpuEmitter: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(GpuEmitter, kind) == 0 && sizeof(GpuEmitter::kind) == 4, "GpuEmitter.kind: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuEmitter, two_sided) == 4 && sizeof(GpuEmitter::two_sided) == 4, "GpuEmitter.two_sided: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuEmitter, area) == 8 && sizeof(GpuEmitter::area) == 4, "GpuEmitter.area: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuEmitter, table) == 12 && sizeof(GpuEmitter::table) == 4, "GpuEmitter.table: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuEmitter, p) == 16 && sizeof(GpuEmitter::p) == 36, "GpuEmitter.p: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuEmitter, normal) == 52 && sizeof(GpuEmitter::normal) == 12, "GpuEmitter.normal: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuEmitter, radiance) == 64 && sizeof(GpuEmitter::radiance) == 12, "GpuEmitter.radiance: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuEmitter, error) == 76 && sizeof(GpuEmitter::error) == 4, "GpuEmitter.error: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuEmitter, portal) == 80 && sizeof(GpuEmitter::portal) == 4, "GpuEmitter.portal: offset or size differs from Rust");
#endif
static_assert(sizeof(GpuMaterial) == 48, "GpuMaterial: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(GpuMaterial, coeffs) == 0 && sizeof(GpuMaterial::coeffs) == 32, "GpuMaterial.coeffs: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMaterial, kind) == 32 && sizeof(GpuMaterial::kind) == 4, "GpuMaterial.kind: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMaterial, pad) == 36 && sizeof(GpuMaterial::pad) == 12, "GpuMaterial.pad: offset or size differs from Rust");
#endif
static_assert(sizeof(LightNode) == 80, "LightNode: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(LightNode, min) == 0 && sizeof(LightNode::min) == 12, "LightNode.min: offset or size differs from Rust");
static_assert(__builtin_offsetof(LightNode, phi) == 12 && sizeof(LightNode::phi) == 4, "LightNode.phi: offset or size differs from Rust");
static_assert(__builtin_offsetof(LightNode, max) == 16 && sizeof(LightNode::max) == 12, "LightNode.max: offset or size differs from Rust");
static_assert(__builtin_offsetof(LightNode, cos_theta_o) == 28 && sizeof(LightNode::cos_theta_o) == 4, "LightNode.cos_theta_o: offset or size differs from Rust");
static_assert(__builtin_offsetof(LightNode, w) == 32 && sizeof(LightNode::w) == 12, "LightNode.w: offset or size differs from Rust");
static_assert(__builtin_offsetof(LightNode, cos_theta_e) == 44 && sizeof(LightNode::cos_theta_e) == 4, "LightNode.cos_theta_e: offset or size differs from Rust");
static_assert(__builtin_offsetof(LightNode, sin_theta_o) == 48 && sizeof(LightNode::sin_theta_o) == 4, "LightNode.sin_theta_o: offset or size differs from Rust");
static_assert(__builtin_offsetof(LightNode, radius) == 52 && sizeof(LightNode::radius) == 4, "LightNode.radius: offset or size differs from Rust");
static_assert(__builtin_offsetof(LightNode, child_or_light) == 56 && sizeof(LightNode::child_or_light) == 4, "LightNode.child_or_light: offset or size differs from Rust");
static_assert(__builtin_offsetof(LightNode, parent) == 60 && sizeof(LightNode::parent) == 4, "LightNode.parent: offset or size differs from Rust");
static_assert(__builtin_offsetof(LightNode, flags) == 64 && sizeof(LightNode::flags) == 4, "LightNode.flags: offset or size differs from Rust");
static_assert(__builtin_offsetof(LightNode, pad) == 68 && sizeof(LightNode::pad) == 12, "LightNode.pad: offset or size differs from Rust");
#endif
inline constexpr unsigned int NO_EMISSION_TEXTURE = 4294967295u;
static_assert(sizeof(GpuEmissionTexture) == 32, "GpuEmissionTexture: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(GpuEmissionTexture, uv) == 0 && sizeof(GpuEmissionTexture::uv) == 24, "GpuEmissionTexture.uv: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuEmissionTexture, start) == 24 && sizeof(GpuEmissionTexture::start) == 4, "GpuEmissionTexture.start: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuEmissionTexture, len) == 28 && sizeof(GpuEmissionTexture::len) == 4, "GpuEmissionTexture.len: offset or size differs from Rust");
#endif
static_assert(sizeof(GpuMedium) == 124, "GpuMedium: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(GpuMedium, sigma_a) == 0 && sizeof(GpuMedium::sigma_a) == 12, "GpuMedium.sigma_a: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMedium, sigma_s) == 12 && sizeof(GpuMedium::sigma_s) == 12, "GpuMedium.sigma_s: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMedium, le) == 24 && sizeof(GpuMedium::le) == 12, "GpuMedium.le: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMedium, g) == 36 && sizeof(GpuMedium::g) == 4, "GpuMedium.g: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMedium, grid_first) == 40 && sizeof(GpuMedium::grid_first) == 4, "GpuMedium.grid_first: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMedium, grid_resolution) == 44 && sizeof(GpuMedium::grid_resolution) == 12, "GpuMedium.grid_resolution: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMedium, world_to_lattice) == 56 && sizeof(GpuMedium::world_to_lattice) == 48, "GpuMedium.world_to_lattice: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMedium, grid_plane) == 104 && sizeof(GpuMedium::grid_plane) == 4, "GpuMedium.grid_plane: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMedium, grid_fields) == 108 && sizeof(GpuMedium::grid_fields) == 12, "GpuMedium.grid_fields: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuMedium, subsurface) == 120 && sizeof(GpuMedium::subsurface) == 4, "GpuMedium.subsurface: offset or size differs from Rust");
#endif
static_assert(sizeof(GpuFootprint) == 144, "GpuFootprint: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(GpuFootprint, camera_position) == 0 && sizeof(GpuFootprint::camera_position) == 12, "GpuFootprint.camera_position: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuFootprint, spp_scale) == 12 && sizeof(GpuFootprint::spp_scale) == 4, "GpuFootprint.spp_scale: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuFootprint, camera_from_world) == 16 && sizeof(GpuFootprint::camera_from_world) == 36, "GpuFootprint.camera_from_world: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuFootprint, world_from_camera) == 52 && sizeof(GpuFootprint::world_from_camera) == 36, "GpuFootprint.world_from_camera: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuFootprint, min_position) == 88 && sizeof(GpuFootprint::min_position) == 24, "GpuFootprint.min_position: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuFootprint, min_direction) == 112 && sizeof(GpuFootprint::min_direction) == 24, "GpuFootprint.min_direction: offset or size differs from Rust");
static_assert(__builtin_offsetof(GpuFootprint, pad) == 136 && sizeof(GpuFootprint::pad) == 8, "GpuFootprint.pad: offset or size differs from Rust");
#endif
static_assert(sizeof(FrameParams) == 2912, "FrameParams: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(FrameParams, camera_to_world) == 0 && sizeof(FrameParams::camera_to_world) == 48, "FrameParams.camera_to_world: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, window_min) == 48 && sizeof(FrameParams::window_min) == 8, "FrameParams.window_min: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, window_max) == 56 && sizeof(FrameParams::window_max) == 8, "FrameParams.window_max: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, raster_size) == 64 && sizeof(FrameParams::raster_size) == 8, "FrameParams.raster_size: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, lens_radius) == 72 && sizeof(FrameParams::lens_radius) == 4, "FrameParams.lens_radius: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, focal_distance) == 76 && sizeof(FrameParams::focal_distance) == 4, "FrameParams.focal_distance: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, projection) == 80 && sizeof(FrameParams::projection) == 4, "FrameParams.projection: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, camera_moves) == 84 && sizeof(FrameParams::camera_moves) == 4, "FrameParams.camera_moves: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, resolution) == 88 && sizeof(FrameParams::resolution) == 8, "FrameParams.resolution: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, seed) == 96 && sizeof(FrameParams::seed) == 4, "FrameParams.seed: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, integrator) == 100 && sizeof(FrameParams::integrator) == 4, "FrameParams.integrator: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, max_depth) == 104 && sizeof(FrameParams::max_depth) == 4, "FrameParams.max_depth: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, ao_max_distance) == 108 && sizeof(FrameParams::ao_max_distance) == 4, "FrameParams.ao_max_distance: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, russian_roulette) == 112 && sizeof(FrameParams::russian_roulette) == 4, "FrameParams.russian_roulette: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, light_count) == 116 && sizeof(FrameParams::light_count) == 4, "FrameParams.light_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, infinite_count) == 120 && sizeof(FrameParams::infinite_count) == 4, "FrameParams.infinite_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, triangle_key_count) == 124 && sizeof(FrameParams::triangle_key_count) == 4, "FrameParams.triangle_key_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, material_count) == 128 && sizeof(FrameParams::material_count) == 4, "FrameParams.material_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, light_sampler) == 132 && sizeof(FrameParams::light_sampler) == 4, "FrameParams.light_sampler: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, emitters) == 136 && sizeof(FrameParams::emitters) == 8, "FrameParams.emitters: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, light_pmf) == 144 && sizeof(FrameParams::light_pmf) == 8, "FrameParams.light_pmf: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, light_cdf) == 152 && sizeof(FrameParams::light_cdf) == 8, "FrameParams.light_cdf: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, infinite_lights) == 160 && sizeof(FrameParams::infinite_lights) == 8, "FrameParams.infinite_lights: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, triangle_keys) == 168 && sizeof(FrameParams::triangle_keys) == 8, "FrameParams.triangle_keys: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, triangle_bases) == 176 && sizeof(FrameParams::triangle_bases) == 8, "FrameParams.triangle_bases: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, materials) == 184 && sizeof(FrameParams::materials) == 8, "FrameParams.materials: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, environment_tables) == 192 && sizeof(FrameParams::environment_tables) == 8, "FrameParams.environment_tables: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, texture_ops) == 200 && sizeof(FrameParams::texture_ops) == 8, "FrameParams.texture_ops: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, mesh_alpha) == 208 && sizeof(FrameParams::mesh_alpha) == 8, "FrameParams.mesh_alpha: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, srgb_to_linear) == 216 && sizeof(FrameParams::srgb_to_linear) == 8, "FrameParams.srgb_to_linear: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, emission_textures) == 224 && sizeof(FrameParams::emission_textures) == 8, "FrameParams.emission_textures: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, images) == 232 && sizeof(FrameParams::images) == 8, "FrameParams.images: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, texels) == 240 && sizeof(FrameParams::texels) == 8, "FrameParams.texels: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, light_nodes) == 248 && sizeof(FrameParams::light_nodes) == 8, "FrameParams.light_nodes: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, light_leaf) == 256 && sizeof(FrameParams::light_leaf) == 8, "FrameParams.light_leaf: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, unbounded_lights) == 264 && sizeof(FrameParams::unbounded_lights) == 8, "FrameParams.unbounded_lights: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, light_node_count) == 272 && sizeof(FrameParams::light_node_count) == 4, "FrameParams.light_node_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, unbounded_count) == 276 && sizeof(FrameParams::unbounded_count) == 4, "FrameParams.unbounded_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, filter) == 280 && sizeof(FrameParams::filter) == 288, "FrameParams.filter: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, media_count) == 568 && sizeof(FrameParams::media_count) == 4, "FrameParams.media_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, camera_medium) == 572 && sizeof(FrameParams::camera_medium) == 4, "FrameParams.camera_medium: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, shadow_reach) == 576 && sizeof(FrameParams::shadow_reach) == 4, "FrameParams.shadow_reach: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, media_pad) == 580 && sizeof(FrameParams::media_pad) == 4, "FrameParams.media_pad: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, media_grids) == 584 && sizeof(FrameParams::media_grids) == 8, "FrameParams.media_grids: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, measured) == 592 && sizeof(FrameParams::measured) == 8, "FrameParams.measured: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, lens) == 600 && sizeof(FrameParams::lens) == 8, "FrameParams.lens: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, media) == 608 && sizeof(FrameParams::media) == 1984, "FrameParams.media: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, camera_motion) == 2592 && sizeof(FrameParams::camera_motion) == 176, "FrameParams.camera_motion: offset or size differs from Rust");
static_assert(__builtin_offsetof(FrameParams, footprint) == 2768 && sizeof(FrameParams::footprint) == 144, "FrameParams.footprint: offset or size differs from Rust");
#endif
static_assert(sizeof(SceneView) == 96, "SceneView: size differs from Rust");
#ifdef ATOLL_CHECK_LAYOUT
static_assert(__builtin_offsetof(SceneView, vertices) == 0 && sizeof(SceneView::vertices) == 8, "SceneView.vertices: offset or size differs from Rust");
static_assert(__builtin_offsetof(SceneView, normals) == 8 && sizeof(SceneView::normals) == 8, "SceneView.normals: offset or size differs from Rust");
static_assert(__builtin_offsetof(SceneView, triangles) == 16 && sizeof(SceneView::triangles) == 8, "SceneView.triangles: offset or size differs from Rust");
static_assert(__builtin_offsetof(SceneView, triangle_mesh) == 24 && sizeof(SceneView::triangle_mesh) == 8, "SceneView.triangle_mesh: offset or size differs from Rust");
static_assert(__builtin_offsetof(SceneView, meshes) == 32 && sizeof(SceneView::meshes) == 8, "SceneView.meshes: offset or size differs from Rust");
static_assert(__builtin_offsetof(SceneView, instances) == 40 && sizeof(SceneView::instances) == 8, "SceneView.instances: offset or size differs from Rust");
static_assert(__builtin_offsetof(SceneView, uvs) == 48 && sizeof(SceneView::uvs) == 8, "SceneView.uvs: offset or size differs from Rust");
static_assert(__builtin_offsetof(SceneView, curve_of) == 56 && sizeof(SceneView::curve_of) == 8, "SceneView.curve_of: offset or size differs from Rust");
static_assert(__builtin_offsetof(SceneView, curves) == 64 && sizeof(SceneView::curves) == 8, "SceneView.curves: offset or size differs from Rust");
static_assert(__builtin_offsetof(SceneView, motions) == 72 && sizeof(SceneView::motions) == 8, "SceneView.motions: offset or size differs from Rust");
static_assert(__builtin_offsetof(SceneView, triangle_count) == 80 && sizeof(SceneView::triangle_count) == 4, "SceneView.triangle_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(SceneView, mesh_count) == 84 && sizeof(SceneView::mesh_count) == 4, "SceneView.mesh_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(SceneView, instance_count) == 88 && sizeof(SceneView::instance_count) == 4, "SceneView.instance_count: offset or size differs from Rust");
static_assert(__builtin_offsetof(SceneView, vertex_count) == 92 && sizeof(SceneView::vertex_count) == 4, "SceneView.vertex_count: offset or size differs from Rust");
#endif
// END GENERATED params
