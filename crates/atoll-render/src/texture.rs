//! Textures at hit points: the scene's texture trees ([`atoll_scene::Textures`])
//! flattened into small stack programs that the CPU (here) and the GPU
//! (`kernels/texture.cuh`, a line-by-line port) run alike.
//!
//! A material with textured parameters gets one program: each bound texture
//! is evaluated and *stored* into the record's material coefficients after
//! the material was packed, so the hit carries the textured values to
//! whichever device shades it (one ray record). A mesh with an alpha mask
//! gets a program that leaves the alpha on the stack; traversal runs it for
//! candidate hits ([`AlphaFilter`]) so cut-out geometry neither blocks
//! shadow rays nor is found by closest-hit rays.
//!
//! Images are looked up with pbrt-v4's texel addressing: `(s, t)` →
//! `(s * width - 0.5, (1 - t) * height - 0.5)`, row 0 at the top of the
//! picture; filtered ones in the MIP level the hit's footprint picks
//! ([`crate::footprint`]), as pbrt-v4's `MIPMap::Filter` picks it. The 2D
//! checkerboard is box-filtered over the footprint and bump maps step by
//! it, as in pbrt-v4; the noise textures and the 3D checkerboard are
//! still evaluated at the point alone.

use std::sync::Arc;

use atoll_bvh::HitFilter;
#[cfg(test)]
use atoll_scene::Rgb;
use atoll_scene::{
    AlphaMode, Channel, ImageFilter, ImageId, Material, Noise, Scene, TexInput, TexMapping, Texture,
    TextureBinding, TextureId, TextureImage, TexturedParam, Wrap,
};
use bytemuck::{Pod, Zeroable};
use glam::{Vec2, Vec3, Vec3A};
use half::f16;

use crate::bump::kind as bump;
use crate::material_layout::{conductor, hair};
use crate::noise;
use crate::record::{MaterialKind, MATERIAL_COEFFS};
use crate::rng::pcg_hash;

/// Most values a texture program keeps on its stack (deeper texture trees
/// are refused when flattening).
pub const TEXTURE_STACK: usize = 8;

/// Op codes of [`TexOp::code`].
pub mod op {
    /// Push `f[0..3]`.
    pub const CONSTANT: u32 = 0;
    /// Push an image lookup: `a` image, `b` = wrap | channel << 8 | invert << 16,
    /// `c` the scale (f32 bits), `f` the uv mapping (su, sv, du, dv).
    pub const IMAGE: u32 = 1;
    /// Pop `second`, `first`; push `first` where `floor(s) + floor(t)` is
    /// even, else `second`; `f` the uv mapping.
    pub const CHECKERBOARD: u32 = 2;
    /// Pop two, push their product.
    pub const SCALE: u32 = 3;
    /// Pop `amount`, `second`, `first`; push `lerp(first, second, amount.x)`.
    pub const MIX: u32 = 4;
    /// Pop a value and store it into coefficients `a ..` as [`super::store`] `b` says.
    pub const STORE: u32 = 5;
    /// Push `(s, t, 0)`, the hit point's coordinates under a 3D mapping:
    /// `a` is the [`super::projection`] kind, `f` and the `f` of the two
    /// [`DATA`] ops after it the three rows of its 3×4 matrix.
    pub const PROJECT: u32 = 6;
    /// Rows of a [`PROJECT`]'s matrix; nothing when run.
    pub const DATA: u32 = 7;
    /// Push `|n · f[0..3]|` (all three channels), `n` the hit's geometric
    /// normal: pbrt's `directionmix` amount.
    pub const FACING: u32 = 8;
    /// Pop the texture-space point `q` (an [`op::PROJECT`] of kind
    /// [`super::projection::POINT`]); push noise texture `a`
    /// ([`crate::noise::kind`]) at it: `b` octaves, `f` = (omega, scale,
    /// variation, 0).
    pub const NOISE: u32 = 9;
    /// Pop `second`, `first`; push `first` inside pbrt's polka dots of
    /// (s, t), else `second`; `f` the uv mapping (as [`CHECKERBOARD`]).
    pub const DOTS: u32 = 10;
    /// Pop the texture-space point `q` (a [`super::projection::POINT`]),
    /// `second`, `first`; push `first` where `floor(q.x) + floor(q.y) +
    /// floor(q.z)` is even, else `second`.
    pub const SOLID_CHECKERBOARD: u32 = 11;
    /// Pop the corners v11, v01, v10, v00; push their bilinear blend at
    /// (s, t); `f` the uv mapping (as [`CHECKERBOARD`]).
    pub const BILERP: u32 = 12;
}

/// Where a texture program runs: the hit's texture coordinates, its point
/// (for 3D mappings) and its unit geometric normal (for `directionmix`),
/// and its footprint: how the point and the uv change from one pixel to
/// the next in x and y (pbrt-v4's `dpdx`, `dudx`, ...; zero where no
/// footprint is known, which picks the finest MIP level).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TexPoint {
    pub uv: Vec2,
    pub position: Vec3,
    pub normal: Vec3,
    pub footprint: Footprint,
}

/// pbrt-v4's `dpdx`, `dpdy`, and the uv's `(dudx, dvdx)`, `(dudy, dvdy)`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Footprint {
    pub dpdx: Vec3,
    pub dpdy: Vec3,
    pub duvdx: Vec2,
    pub duvdy: Vec2,
}

impl TexPoint {
    /// Texture coordinates alone (emission images, tests): no point, no normal.
    pub fn uv(uv: Vec2) -> Self {
        TexPoint { uv, ..Default::default() }
    }
}

/// The kinds of [`op::PROJECT`], pbrt-v4's 3D texture mappings of the hit
/// point `p`: `q` is the matrix times `(p, 1)`.
pub mod projection {
    /// `(θ / π, φ / 2π)` of the direction to `q`.
    pub const SPHERICAL: u32 = 0;
    /// `((π + atan2(q.y, q.x)) / 2π, q.z)`.
    pub const CYLINDRICAL: u32 = 1;
    /// `(q.x, q.y)`: the rows hold the planar mapping's `vs`, `vt`, `ds`, `dt`.
    pub const PLANAR: u32 = 2;
    /// `q` itself, a point for the noise textures.
    pub const POINT: u32 = 3;
}

/// Where an [`op::IMAGE`]'s `b` holds its [`atoll_scene::ImageFilter`]
/// (3 bits) and its number of MIP levels (6 bits; its images are `a`
/// onwards).
pub const IMAGE_FILTER_SHIFT: u32 = 17;
pub const IMAGE_LEVELS_SHIFT: u32 = 25;

/// Set in `b` of an [`op::IMAGE`], [`op::CHECKERBOARD`], [`op::DOTS`] or
/// [`op::BILERP`]: it pops its
/// `(s, t)` from the stack (an [`op::PROJECT`]) instead of mapping the
/// hit's `uv`.
pub const PROJECTED: u32 = 1 << 24;

/// How [`op::STORE`] writes a value into the material coefficients.
pub mod store {
    /// Three coefficients: the colour.
    pub const RGB: u32 = 0;
    /// One coefficient: the first channel.
    pub const FLOAT: u32 = 1;
    /// One coefficient: `sqrt(x)`, pbrt's `RoughnessToAlpha` (remapped roughness).
    pub const ROUGHNESS: u32 = 2;
    /// A conductor's eta and k (the slot is eta's): `eta = 1` and the `k`
    /// that gives reflectance `x` at normal incidence (pbrt-v4's conductor
    /// `reflectance`).
    pub const CONDUCTOR_REFLECTANCE: u32 = 3;
    /// One coefficient: the first channel clamped to [-1, 1] (a phase
    /// function's asymmetry `g`, negative for back-scattering media).
    pub const ASYMMETRY: u32 = 4;
    /// Three coefficients: the colour clamped to [0, 1] (a medium's
    /// single-scattering albedo, as pbrt-v4 clamps it).
    pub const ALBEDO: u32 = 5;
    /// One coefficient: the first channel clamped to [0.01, 1] (a hair
    /// fibre's roughness, as pbrt-v4 clamps it).
    pub const HAIR_ROUGHNESS: u32 = 6;
    /// Three coefficients (the slot is a hair fibre's `sigma_a`): the
    /// absorption that gives the colour, clamped to [0, 1], as a
    /// reflectance at the fibre's `beta_n` (already in its slot).
    pub const HAIR_REFLECTANCE: u32 = 7;
    /// Three coefficients (a hair fibre's `sigma_a`): the absorption of the
    /// first channel's concentration of eumelanin added to theirs.
    pub const EUMELANIN: u32 = 8;
    /// The same for pheomelanin.
    pub const PHEOMELANIN: u32 = 9;
}

/// One instruction of a texture program (32 bytes; the GPU reads the same bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct TexOp {
    pub code: u32,
    pub a: u32,
    pub b: u32,
    pub c: u32,
    pub f: [f32; 4],
}

/// A run of [`TexOp`]s in [`TextureTables::ops`]; `len == 0`: none.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq, Eq)]
pub struct ProgramRange {
    pub start: u32,
    pub len: u32,
}

impl ProgramRange {
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// `AlphaProgram::mode` values.
pub mod alpha_mode {
    /// No alpha: the mesh is solid.
    pub const NONE: u32 = 0;
    /// Kept with probability alpha (pbrt).
    pub const STOCHASTIC: u32 = 1;
    /// Kept where alpha ≥ the cutoff (glTF `MASK`).
    pub const CUTOFF: u32 = 2;
    /// The bits above that name the texture's test.
    pub const TEXTURE_MASK: u32 = 0xff;
}

/// A mesh's alpha test (16 bytes, mirrored by the GPU).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct AlphaProgram {
    pub program: ProgramRange,
    /// [`alpha_mode`].
    pub mode: u32,
    pub cutoff: f32,
}

/// The texture programs of a frame: per material and per mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TextureTables {
    pub ops: Vec<TexOp>,
    /// By material id: the program storing its textured parameters.
    pub materials: Vec<ProgramRange>,
    /// By material id: for a `mix` with a textured amount, the program
    /// leaving the amount on the stack.
    pub mix_amount: Vec<ProgramRange>,
    /// By scene mesh id; empty when no mesh has alpha.
    pub mesh_alpha: Vec<AlphaProgram>,
    /// By material id: the program of its bump or normal map ([`crate::bump`]),
    /// leaving the displacement or the tangent-space normal on the stack.
    pub shading_normals: Vec<ShadingNormalProgram>,
}

/// A material's bump or normal map: its [`crate::bump::kind`] and program.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq, Eq)]
pub struct ShadingNormalProgram {
    pub kind: u32,
    pub program: ProgramRange,
}

impl TextureTables {
    /// Flattens the scene's texture bindings and alpha masks. Bindings a
    /// material kind has no coefficient for, and texture trees deeper than
    /// [`TEXTURE_STACK`], are dropped with a warning.
    pub fn new(scene: &Scene, kinds: &[MaterialKind]) -> Self {
        let textures = &scene.textures;
        let mut tables = TextureTables {
            materials: vec![ProgramRange::default(); kinds.len()],
            mix_amount: vec![ProgramRange::default(); kinds.len()],
            shading_normals: vec![ShadingNormalProgram::default(); kinds.len()],
            ..Default::default()
        };
        for (id, kind) in kinds.iter().enumerate() {
            if *kind == MaterialKind::Mix {
                let amount = textures.bindings_of(id as u32).find(|b| b.param == TexturedParam::Amount);
                if let Some(b) = amount {
                    let start = tables.ops.len() as u32;
                    match compile(scene, b.texture, &mut tables.ops, 0, 0) {
                        Ok(()) => {
                            tables.mix_amount[id] =
                                ProgramRange { start, len: tables.ops.len() as u32 - start }
                        }
                        Err(e) => {
                            tables.ops.truncate(start as usize);
                            tracing::warn!("material {id}: texture for \"amount\": {e}; ignored");
                        }
                    }
                }
                continue;
            }
            let bends = |b: &&TextureBinding| {
                matches!(b.param, TexturedParam::Displacement | TexturedParam::NormalMap)
            };
            if let Some(b) = textures.bindings_of(id as u32).find(bends) {
                let start = tables.ops.len() as u32;
                match compile(scene, b.texture, &mut tables.ops, 0, 0) {
                    Ok(()) => {
                        let kind =
                            if b.param == TexturedParam::NormalMap { bump::NORMAL_MAP } else { bump::BUMP };
                        let program = ProgramRange { start, len: tables.ops.len() as u32 - start };
                        tables.shading_normals[id] = ShadingNormalProgram { kind, program };
                    }
                    Err(e) => {
                        tables.ops.truncate(start as usize);
                        tracing::warn!(
                            "material {id}: texture for \"{}\": {e}; ignored",
                            b.param.pbrt_name()
                        );
                    }
                }
            }
            let start = tables.ops.len() as u32;
            for binding in textures.bindings_of(id as u32).filter(|b| !bends(b)) {
                let targets = store_targets(*kind, binding.param, binding.remap_roughness);
                if targets.is_empty() {
                    tracing::warn!(
                        "material {id}: a {:?} material has no parameter \"{}\" to texture; ignored",
                        kind,
                        binding.param.pbrt_name()
                    );
                    continue;
                }
                let mut program = Vec::new();
                if let Err(e) = compile(scene, binding.texture, &mut program, 0, 0) {
                    tracing::warn!(
                        "material {id}: texture for \"{}\": {e}; ignored",
                        binding.param.pbrt_name()
                    );
                    continue;
                }
                // One evaluation, stored as often as the parameter has slots
                // (roughness drives both alphas): duplicate the value first.
                for (i, (slot, how)) in targets.iter().enumerate() {
                    if i + 1 < targets.len() {
                        tables.ops.extend_from_slice(&program);
                    } else {
                        tables.ops.append(&mut program);
                    }
                    tables.ops.push(TexOp { code: op::STORE, a: *slot, b: *how, ..Default::default() });
                }
            }
            tables.materials[id] = ProgramRange { start, len: tables.ops.len() as u32 - start };
        }
        if (0..scene.meshes.len() as u32).any(|m| scene.filters_hits(m)) {
            tables.mesh_alpha = scene
                .meshes
                .iter()
                .enumerate()
                .map(|(id, mesh)| {
                    let solid = AlphaProgram::default();
                    let Some(alpha) = mesh.alpha else { return solid };
                    let start = tables.ops.len() as u32;
                    let mut program = Vec::new();
                    if let Err(e) = compile(scene, alpha.texture, &mut program, 0, 0) {
                        tracing::warn!("mesh {id} ({}): alpha texture: {e}; the mesh is solid", mesh.name);
                        return solid;
                    }
                    tables.ops.append(&mut program);
                    let program = ProgramRange { start, len: tables.ops.len() as u32 - start };
                    match alpha.mode {
                        AlphaMode::Stochastic => {
                            AlphaProgram { program, mode: alpha_mode::STOCHASTIC, cutoff: 0.0 }
                        }
                        AlphaMode::Cutoff(c) => AlphaProgram { program, mode: alpha_mode::CUTOFF, cutoff: c },
                    }
                })
                .collect();
        }
        tables
    }

    /// The alpha test of scene mesh `mesh`, if it has one.
    #[inline]
    pub fn alpha_of(&self, mesh: u32) -> Option<&AlphaProgram> {
        self.mesh_alpha.get(mesh as usize).filter(|a| a.mode != alpha_mode::NONE)
    }

    pub fn has_alpha(&self) -> bool {
        !self.mesh_alpha.is_empty()
    }

    /// Bytes the GPU holds for these tables (images not included).
    pub fn bytes(&self) -> u64 {
        (self.ops.len() * std::mem::size_of::<TexOp>()
            + (self.materials.len() + self.mix_amount.len()) * 8
            + self.mesh_alpha.len() * std::mem::size_of::<AlphaProgram>()) as u64
    }
}

/// Why a texture tree has no program.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TextureCompileError {
    #[error("texture tree needs more than {} stack values", TEXTURE_STACK)]
    StackTooDeep,
    #[error("textures nested more than {} deep (a cycle?)", MAX_TEXTURE_NESTING)]
    NestedTooDeep,
    #[error("texture {0} does not exist")]
    NoTexture(TextureId),
    #[error("image {0} does not exist")]
    NoImage(ImageId),
}

/// Appends the program of texture `id` (leaving its value on the stack)
/// to `out`; errors name what is wrong with the texture tree.
pub fn compile_texture(
    scene: &Scene,
    id: TextureId,
    out: &mut Vec<TexOp>,
) -> Result<(), TextureCompileError> {
    compile(scene, id, out, 0, 0)
}

/// Most nested textures a tree may have (stops reference cycles).
const MAX_TEXTURE_NESTING: usize = 64;

/// Appends the postfix program of texture `id` (children first) to `out`.
/// `depth` is the stack depth before it runs, `nesting` how many textures
/// enclose it.
fn compile(
    scene: &Scene,
    id: TextureId,
    out: &mut Vec<TexOp>,
    depth: usize,
    nesting: usize,
) -> Result<(), TextureCompileError> {
    if depth >= TEXTURE_STACK {
        return Err(TextureCompileError::StackTooDeep);
    }
    if nesting > MAX_TEXTURE_NESTING {
        return Err(TextureCompileError::NestedTooDeep);
    }
    let textures = &scene.textures;
    let texture = textures.textures.get(id as usize).ok_or(TextureCompileError::NoTexture(id))?;
    let input = |out: &mut Vec<TexOp>, input: &TexInput, depth: usize| match *input {
        TexInput::Value(_) if depth >= TEXTURE_STACK => Err(TextureCompileError::StackTooDeep),
        TexInput::Value(v) => {
            out.push(constant(v));
            Ok(())
        }
        TexInput::Texture(t) => compile(scene, t, out, depth, nesting + 1),
    };
    match texture {
        Texture::Constant(v) => out.push(constant(*v)),
        Texture::Facing { direction } => {
            out.push(TexOp { code: op::FACING, f: direction.extend(0.0).to_array(), ..Default::default() })
        }
        Texture::Image { image, mapping, wrap, channel, scale, invert, filter, levels } => {
            let last = (*image as usize).saturating_add(*levels as usize);
            if last > textures.images.len() || !(1..64).contains(levels) {
                return Err(TextureCompileError::NoImage(*image));
            }
            let (f, projected) = mapping_ops(mapping, out, depth)?;
            let filtering = (*filter as u32) << IMAGE_FILTER_SHIFT | levels << IMAGE_LEVELS_SHIFT;
            out.push(TexOp {
                code: op::IMAGE,
                a: *image,
                b: *wrap as u32 | (*channel as u32) << 8 | (*invert as u32) << 16 | projected | filtering,
                c: scale.to_bits(),
                f,
            })
        }
        // Two inputs chosen between by the (s, t) of a 2D mapping.
        Texture::Checkerboard { mapping, tex } | Texture::Dots { mapping, tex } => {
            let code = if matches!(texture, Texture::Dots { .. }) { op::DOTS } else { op::CHECKERBOARD };
            input(out, &tex[0], depth)?;
            input(out, &tex[1], depth + 1)?;
            let (f, projected) = mapping_ops(mapping, out, depth + 2)?;
            out.push(TexOp { code, b: projected, f, ..Default::default() });
        }
        Texture::SolidCheckerboard { texture_from_world, tex } => {
            input(out, &tex[0], depth)?;
            input(out, &tex[1], depth + 1)?;
            project_ops(projection::POINT, rows_of(texture_from_world), out, depth + 2)?;
            out.push(TexOp { code: op::SOLID_CHECKERBOARD, ..Default::default() });
        }
        Texture::Bilerp { mapping, corners } => {
            for (i, corner) in corners.iter().enumerate() {
                input(out, corner, depth + i)?;
            }
            let (f, projected) = mapping_ops(mapping, out, depth + 4)?;
            out.push(TexOp { code: op::BILERP, b: projected, f, ..Default::default() });
        }
        Texture::Noise { noise, texture_from_world } => {
            project_ops(projection::POINT, rows_of(texture_from_world), out, depth)?;
            let (kind, octaves, omega, scale, variation) = match *noise {
                Noise::Fbm { octaves, omega } => (noise::kind::FBM, octaves, omega, 1.0, 0.0),
                Noise::Wrinkled { octaves, omega } => (noise::kind::WRINKLED, octaves, omega, 1.0, 0.0),
                Noise::Windy => (noise::kind::WINDY, 0, 0.5, 1.0, 0.0),
                Noise::Marble { octaves, omega, scale, variation } => {
                    (noise::kind::MARBLE, octaves, omega, scale, variation)
                }
            };
            out.push(TexOp {
                code: op::NOISE,
                a: kind,
                b: octaves,
                f: [omega, scale, variation, 0.0],
                ..Default::default()
            });
        }
        Texture::Scale { tex, scale } => {
            input(out, tex, depth)?;
            input(out, scale, depth + 1)?;
            out.push(TexOp { code: op::SCALE, ..Default::default() });
        }
        Texture::Mix { tex, amount } => {
            input(out, &tex[0], depth)?;
            input(out, &tex[1], depth + 1)?;
            input(out, amount, depth + 2)?;
            out.push(TexOp { code: op::MIX, ..Default::default() });
        }
    }
    Ok(())
}

fn constant(v: Vec3) -> TexOp {
    TexOp { code: op::CONSTANT, f: [v.x, v.y, v.z, 0.0], ..Default::default() }
}

/// The uv mapping words of an op reading `mapping`, and its [`PROJECTED`]
/// flag; a 3D mapping first appends its [`op::PROJECT`] (run at stack
/// depth `depth`) to `out`, and the op then maps `(s, t)` unchanged.
fn mapping_ops(
    mapping: &TexMapping,
    out: &mut Vec<TexOp>,
    depth: usize,
) -> Result<([f32; 4], u32), TextureCompileError> {
    let (kind, rows) = match *mapping {
        TexMapping::Uv(m) => return Ok(([m.su, m.sv, m.du, m.dv], 0)),
        TexMapping::Spherical { texture_from_world } => (projection::SPHERICAL, rows_of(&texture_from_world)),
        TexMapping::Cylindrical { texture_from_world } => {
            (projection::CYLINDRICAL, rows_of(&texture_from_world))
        }
        TexMapping::Planar { texture_from_world, vs, vt, ds, dt } => {
            // s = ds + vs · (M p + c): one affine row per coordinate.
            let m = glam::Mat3::from(texture_from_world.matrix3);
            let c = Vec3::from(texture_from_world.translation);
            let row = |v: Vec3, d: f32| (m.transpose() * v).extend(d + v.dot(c)).to_array();
            (projection::PLANAR, [row(vs, ds), row(vt, dt), [0.0; 4]])
        }
    };
    project_ops(kind, rows, out, depth)?;
    Ok(([1.0, 1.0, 0.0, 0.0], PROJECTED))
}

/// Appends an [`op::PROJECT`] of `kind` with the matrix `rows` (run at
/// stack depth `depth`, where it pushes one value) and its [`op::DATA`].
fn project_ops(
    kind: u32,
    rows: [[f32; 4]; 3],
    out: &mut Vec<TexOp>,
    depth: usize,
) -> Result<(), TextureCompileError> {
    if depth >= TEXTURE_STACK {
        return Err(TextureCompileError::StackTooDeep);
    }
    out.push(TexOp { code: op::PROJECT, a: kind, f: rows[0], ..Default::default() });
    out.extend(rows[1..].iter().map(|&f| TexOp { code: op::DATA, f, ..Default::default() }));
    Ok(())
}

/// The three rows of an affine map as a 3×4 matrix.
fn rows_of(a: &glam::Affine3A) -> [[f32; 4]; 3] {
    let m = glam::Mat3::from(a.matrix3);
    let c = Vec3::from(a.translation);
    [0, 1, 2].map(|r| m.row(r).extend(c[r]).to_array())
}

/// What the [`op::PROJECT`] at `ops[k]` pushes for the hit point
/// `position`: `(s, t, 0)`, or the point itself for [`projection::POINT`];
/// and the derivatives in x and y over `footprint` of `(s, t)` (pbrt-v4's
/// `TextureMapping2D::Map`; none for a point) and of the point in the
/// texture's space (its `TextureMapping3D::Map`).
fn project(ops: &[TexOp], k: usize, position: Vec3, footprint: &Footprint) -> (Vec3, [Vec2; 2], [Vec3; 2]) {
    use std::f32::consts::{PI, TAU};
    let row = |i: usize| glam::Vec4::from_array(ops[k + i].f);
    let p = position.extend(1.0);
    let q = Vec3::new(row(0).dot(p), row(1).dot(p), row(2).dot(p));
    // The footprint in the texture's space.
    let linear =
        |d: Vec3| Vec3::new(row(0).truncate().dot(d), row(1).truncate().dot(d), row(2).truncate().dot(d));
    let (dqdx, dqdy) = (linear(footprint.dpdx), linear(footprint.dpdy));
    let along = |dsdq: Vec3, dtdq: Vec3| {
        [Vec2::new(dsdq.dot(dqdx), dtdq.dot(dqdx)), Vec2::new(dsdq.dot(dqdy), dtdq.dot(dqdy))]
    };
    let x2y2 = q.x * q.x + q.y * q.y;
    let (value, st_derivatives) = match ops[k].a {
        projection::SPHERICAL => {
            let d = q.normalize_or_zero();
            let theta = d.z.clamp(-1.0, 1.0).acos();
            let phi = d.y.atan2(d.x);
            let phi = if phi < 0.0 { phi + TAU } else { phi };
            let r = x2y2.sqrt();
            let dsdq = Vec3::new(-q.y, q.x, 0.0) / (2.0 * PI * x2y2);
            let dtdq = Vec3::new(q.x * q.z / r, q.y * q.z / r, -r) / (PI * (x2y2 + q.z * q.z));
            // As pbrt-v4 has them (its `dsdp` is φ's; a footprint's width
            // takes the largest of the four, whichever is whose).
            (Vec3::new(theta * std::f32::consts::FRAC_1_PI, phi / TAU, 0.0), finite(along(dsdq, dtdq)))
        }
        projection::CYLINDRICAL => {
            let dsdq = Vec3::new(-q.y, q.x, 0.0) / (2.0 * PI * x2y2);
            let st = Vec3::new((PI + q.y.atan2(q.x)) / TAU, q.z, 0.0);
            (st, finite(along(dsdq, Vec3::Z)))
        }
        projection::POINT => (q, [Vec2::ZERO; 2]),
        _ => (Vec3::new(q.x, q.y, 0.0), along(Vec3::X, Vec3::Y)),
    };
    (value, st_derivatives, [dqdx, dqdy])
}

/// Derivatives with NaN or infinite parts (on a mapping's axis) as zero.
fn finite(d: [Vec2; 2]) -> [Vec2; 2] {
    d.map(|v| if v.is_finite() { v } else { Vec2::ZERO })
}

/// Where a textured parameter goes in the coefficients of a material kind
/// ([`crate::material_layout`]): `(first coefficient, store mode)` per store.
pub fn store_targets(kind: MaterialKind, param: TexturedParam, remap: bool) -> Vec<(u32, u32)> {
    use crate::material_layout::{
        coated_conductor as cc, coated_diffuse as coated, conductor, dielectric, diffuse,
        diffuse_transmission, principled, subsurface,
    };
    use MaterialKind as K;
    use TexturedParam as P;
    let roughness = if remap { store::ROUGHNESS } else { store::FLOAT };
    let to = |slots: &[usize], how: u32| slots.iter().map(|&slot| (slot as u32, how)).collect();
    match (kind, param) {
        (K::Diffuse, P::Reflectance) => to(&[diffuse::REFLECTANCE], store::RGB),
        (K::DiffuseTransmission, P::Reflectance) => to(&[diffuse_transmission::REFLECTANCE], store::RGB),
        (K::DiffuseTransmission, P::Transmittance) => to(&[diffuse_transmission::TRANSMITTANCE], store::RGB),
        (K::Conductor, P::Reflectance) => to(&[conductor::ETA], store::CONDUCTOR_REFLECTANCE),
        (K::Conductor, P::Eta) => to(&[conductor::ETA], store::RGB),
        (K::Conductor, P::K) => to(&[conductor::K], store::RGB),
        (K::Conductor, P::Roughness) => to(&[conductor::ALPHA_X, conductor::ALPHA_Y], roughness),
        (K::Conductor, P::URoughness) => to(&[conductor::ALPHA_X], roughness),
        (K::Conductor, P::VRoughness) => to(&[conductor::ALPHA_Y], roughness),
        (K::Dielectric, P::Roughness) => to(&[dielectric::ALPHA_X, dielectric::ALPHA_Y], roughness),
        (K::Dielectric, P::URoughness) => to(&[dielectric::ALPHA_X], roughness),
        (K::Dielectric, P::VRoughness) => to(&[dielectric::ALPHA_Y], roughness),
        (K::Subsurface, P::Roughness) => to(&[subsurface::ALPHA_X, subsurface::ALPHA_Y], roughness),
        (K::Subsurface, P::URoughness) => to(&[subsurface::ALPHA_X], roughness),
        (K::Subsurface, P::VRoughness) => to(&[subsurface::ALPHA_Y], roughness),
        (K::CoatedDiffuse, P::Reflectance) => to(&[coated::REFLECTANCE], store::RGB),
        (K::CoatedDiffuse, P::Roughness) => to(&[coated::ALPHA_X, coated::ALPHA_Y], roughness),
        (K::CoatedDiffuse, P::URoughness) => to(&[coated::ALPHA_X], roughness),
        (K::CoatedDiffuse, P::VRoughness) => to(&[coated::ALPHA_Y], roughness),
        (K::CoatedDiffuse, P::Thickness) => to(&[coated::THICKNESS], store::FLOAT),
        (K::CoatedDiffuse, P::Albedo) => to(&[coated::ALBEDO], store::ALBEDO),
        (K::CoatedDiffuse, P::G) => to(&[coated::G], store::ASYMMETRY),
        (K::CoatedConductor, P::Reflectance) => to(&[cc::ETA], store::CONDUCTOR_REFLECTANCE),
        (K::CoatedConductor, P::Eta) => to(&[cc::ETA], store::RGB),
        (K::CoatedConductor, P::K) => to(&[cc::K], store::RGB),
        (K::CoatedConductor, P::ConductorRoughness) => {
            to(&[cc::CONDUCTOR_ALPHA_X, cc::CONDUCTOR_ALPHA_Y], roughness)
        }
        (K::CoatedConductor, P::ConductorURoughness) => to(&[cc::CONDUCTOR_ALPHA_X], roughness),
        (K::CoatedConductor, P::ConductorVRoughness) => to(&[cc::CONDUCTOR_ALPHA_Y], roughness),
        (K::CoatedConductor, P::Roughness) => to(&[cc::INTERFACE_ALPHA_X, cc::INTERFACE_ALPHA_Y], roughness),
        (K::CoatedConductor, P::URoughness) => to(&[cc::INTERFACE_ALPHA_X], roughness),
        (K::CoatedConductor, P::VRoughness) => to(&[cc::INTERFACE_ALPHA_Y], roughness),
        (K::CoatedConductor, P::Thickness) => to(&[cc::THICKNESS], store::FLOAT),
        (K::CoatedConductor, P::Albedo) => to(&[cc::ALBEDO], store::ALBEDO),
        (K::CoatedConductor, P::G) => to(&[cc::G], store::ASYMMETRY),
        // Base colour, metallic, and perceptual roughness (never remapped:
        // the principled BSDF squares it itself).
        (K::Principled, P::Reflectance) => to(&[principled::BASE_COLOR], store::RGB),
        (K::Principled, P::Metallic) => to(&[principled::METALLIC], store::FLOAT),
        (K::Principled, P::Roughness) => to(&[principled::ROUGHNESS], store::FLOAT),
        (K::Principled, P::SpecularTint) => to(&[principled::SPECULAR_TINT], store::FLOAT),
        (K::Principled, P::Sheen) => to(&[principled::SHEEN], store::FLOAT),
        (K::Principled, P::SheenTint) => to(&[principled::SHEEN_TINT], store::FLOAT),
        (K::Principled, P::Clearcoat) => to(&[principled::CLEARCOAT], store::FLOAT),
        (K::Principled, P::ClearcoatGloss) => to(&[principled::CLEARCOAT_GLOSS], store::FLOAT),
        (K::Principled, P::Transmission) => to(&[principled::TRANSMISSION], store::FLOAT),
        (K::Hair, P::SigmaA) => to(&[hair::SIGMA_A], store::RGB),
        (K::Hair, P::Reflectance) => to(&[hair::SIGMA_A], store::HAIR_REFLECTANCE),
        (K::Hair, P::Eta) => to(&[hair::ETA], store::FLOAT),
        (K::Hair, P::BetaM) => to(&[hair::BETA_M], store::HAIR_ROUGHNESS),
        (K::Hair, P::BetaN) => to(&[hair::BETA_N], store::HAIR_ROUGHNESS),
        (K::Hair, P::HairAlpha) => to(&[hair::ALPHA], store::FLOAT),
        (K::Hair, P::Eumelanin) => to(&[hair::SIGMA_A], store::EUMELANIN),
        (K::Hair, P::Pheomelanin) => to(&[hair::SIGMA_A], store::PHEOMELANIN),
        _ => Vec::new(),
    }
}

/// Texture coordinates of a hit at barycentrics `(b1, b2)` of a triangle
/// whose corners have `uvs` (`None`: pbrt's default per-triangle
/// parameterisation (0,0), (1,0), (1,1)).
#[inline]
pub fn hit_uv(uvs: Option<[Vec2; 3]>, b1: f32, b2: f32) -> Vec2 {
    let b0 = 1.0 - b1 - b2;
    match uvs {
        Some([a, b, c]) => a * b0 + b * b1 + c * b2,
        None => Vec2::new(b1 + b2, b2),
    }
}

/// Runs `ops` at hit `at`: stores go into `coeffs`; returns what is left
/// on top of the stack (an alpha program's alpha).
pub fn run_program(
    ops: &[TexOp],
    images: &[Arc<TextureImage>],
    at: TexPoint,
    coeffs: &mut [f16; MATERIAL_COEFFS],
) -> Vec3 {
    let TexPoint { uv, position, normal, footprint } = at;
    let mut stack = [Vec3::ZERO; TEXTURE_STACK];
    let mut sp = 0usize;
    // The (s, t) and point derivatives of the last projection (its
    // consumer follows it).
    let mut projected_derivatives = [Vec2::ZERO; 2];
    let mut point_derivatives = [Vec3::ZERO; 2];
    // An op's (s, t) before its own mapping: projected ones pop theirs.
    let coords = |o: &TexOp, stack: &[Vec3], sp: &mut usize| {
        if o.b & PROJECTED == 0 {
            return uv;
        }
        *sp -= 1;
        stack[*sp].truncate()
    };
    // Their derivatives in x and y.
    let derivatives = |o: &TexOp, projected: [Vec2; 2]| {
        if o.b & PROJECTED == 0 {
            [footprint.duvdx, footprint.duvdy]
        } else {
            projected
        }
    };
    for (k, o) in ops.iter().enumerate() {
        match o.code {
            op::CONSTANT => {
                stack[sp] = Vec3::new(o.f[0], o.f[1], o.f[2]);
                sp += 1;
            }
            op::PROJECT => {
                (stack[sp], projected_derivatives, point_derivatives) = project(ops, k, position, &footprint);
                sp += 1;
            }
            op::NOISE => {
                let [omega, scale, variation, _] = o.f;
                let len2 = point_derivatives[0].length_squared().max(point_derivatives[1].length_squared());
                stack[sp - 1] = noise::evaluate(o.a, stack[sp - 1], len2, o.b, omega, scale, variation);
            }
            op::SOLID_CHECKERBOARD => {
                sp -= 2;
                let q = stack[sp + 1];
                // pbrt-v4's 3D checkerboard, box-filtered over the footprint.
                let [dx, dy] = point_derivatives;
                let checks = |i: usize| filtered_checks(q[i], 1.5 * dx[i].abs().max(dy[i].abs()));
                let w = 0.5 - 0.5 * checks(0) * checks(1) * checks(2);
                if w != 0.0 {
                    stack[sp - 1] = stack[sp - 1] * (1.0 - w) + stack[sp] * w;
                }
            }
            op::BILERP => {
                let st = apply_mapping(o.f, coords(o, &stack, &mut sp));
                sp -= 3;
                let [v00, v10, v01, v11] = [stack[sp - 1], stack[sp], stack[sp + 1], stack[sp + 2]];
                let (s, t) = (st.x, st.y);
                stack[sp - 1] =
                    (1.0 - s) * (1.0 - t) * v00 + s * (1.0 - t) * v10 + (1.0 - s) * t * v01 + s * t * v11;
            }
            op::DOTS => {
                let st = coords(o, &stack, &mut sp);
                let inside = noise::inside_polka_dot(apply_mapping(o.f, st));
                sp -= 1;
                if !inside {
                    stack[sp - 1] = stack[sp];
                }
            }
            op::FACING => {
                stack[sp] = Vec3::splat(normal.dot(Vec3::new(o.f[0], o.f[1], o.f[2])).abs());
                sp += 1;
            }
            op::IMAGE => {
                let st = coords(o, &stack, &mut sp);
                stack[sp] = image_lookup(o, images, st, derivatives(o, projected_derivatives));
                sp += 1;
            }
            op::CHECKERBOARD => {
                let [dx, dy] = derivatives(o, projected_derivatives);
                let st = apply_mapping(o.f, coords(o, &stack, &mut sp));
                sp -= 1;
                // pbrt-v4's checkerboard box-filtered over the footprint: the
                // weight of `second` (above `first`); an even cell is 0.
                let radius = |i: usize| 1.5 * (o.f[i] * dx[i]).abs().max((o.f[i] * dy[i]).abs());
                let w = 0.5 - filtered_checks(st.x, radius(0)) * filtered_checks(st.y, radius(1)) / 2.0;
                if w != 0.0 {
                    stack[sp - 1] = stack[sp - 1] * (1.0 - w) + stack[sp] * w;
                }
            }
            op::SCALE => {
                sp -= 1;
                stack[sp - 1] *= stack[sp];
            }
            op::MIX => {
                sp -= 2;
                let amount = stack[sp + 1].x;
                stack[sp - 1] = stack[sp - 1] * (1.0 - amount) + stack[sp] * amount;
            }
            op::STORE => {
                sp -= 1;
                store_value(stack[sp], o.a as usize, o.b, coeffs);
            }
            _ => {}
        }
    }
    if sp > 0 {
        stack[sp - 1]
    } else {
        Vec3::ZERO
    }
}

fn store_value(v: Vec3, slot: usize, how: u32, coeffs: &mut [f16; MATERIAL_COEFFS]) {
    if how == store::ASYMMETRY {
        coeffs[slot] = f16::from_f32(v.x.clamp(-1.0, 1.0));
        return;
    }
    if how == store::HAIR_ROUGHNESS {
        coeffs[slot] = f16::from_f32(v.x.clamp(0.01, 1.0));
        return;
    }
    let v = v.max(Vec3::ZERO);
    let v = if how == store::ALBEDO { v.min(Vec3::ONE) } else { v };
    match how {
        store::RGB | store::ALBEDO => {
            for (i, c) in v.to_array().into_iter().enumerate() {
                coeffs[slot + i] = f16::from_f32(c);
            }
        }
        store::FLOAT => coeffs[slot] = f16::from_f32(v.x),
        store::ROUGHNESS => coeffs[slot] = f16::from_f32(v.x.sqrt()),
        store::HAIR_REFLECTANCE => {
            // `slot` is the fibre's sigma_a; beta_n lies where its layout puts it.
            let beta_n = coeffs[slot + hair::BETA_N - hair::SIGMA_A].to_f32();
            let sigma_a = atoll_scene::HairParams::sigma_a_from_reflectance(v.min(Vec3::ONE), beta_n);
            for (i, c) in sigma_a.to_array().into_iter().enumerate() {
                coeffs[slot + i] = f16::from_f32(c);
            }
        }
        store::EUMELANIN | store::PHEOMELANIN => {
            let pigment = if how == store::EUMELANIN {
                atoll_scene::HairParams::EUMELANIN_SIGMA_A
            } else {
                atoll_scene::HairParams::PHEOMELANIN_SIGMA_A
            };
            for (i, c) in (pigment * v.x).to_array().into_iter().enumerate() {
                coeffs[slot + i] = f16::from_f32(coeffs[slot + i].to_f32() + c);
            }
        }
        store::CONDUCTOR_REFLECTANCE => {
            // `slot` is the conductor's eta; k lies where its layout puts it.
            let k_slot = slot + conductor::K - conductor::ETA;
            let k = Material::conductor_k_from_reflectance(v);
            for i in 0..3 {
                coeffs[slot + i] = f16::ONE;
                coeffs[k_slot + i] = f16::from_f32(k[i]);
            }
        }
        _ => {}
    }
}

/// pbrt-v4's 1D checkerboard (+1 on even cells, −1 on odd ones) averaged
/// over a triangle filter of radius `r` about `x` (`bf` in its
/// `Checkerboard`); exact where the filter stays in one cell.
fn filtered_checks(x: f32, r: f32) -> f32 {
    if (x - r).floor() == (x + r).floor() {
        return 1.0 - 2.0 * ((x.floor() as i32) & 1) as f32;
    }
    // The integral of the 1D checkerboard.
    let d = |x: f32| {
        let y = x / 2.0 - (x / 2.0).floor() - 0.5;
        x / 2.0 + y * (1.0 - 2.0 * y.abs())
    };
    (d(x + r) - 2.0 * d(x) + d(x - r)) / (r * r)
}

#[inline]
fn apply_mapping(f: [f32; 4], uv: Vec2) -> Vec2 {
    Vec2::new(f[0] * uv.x + f[2], f[1] * uv.y + f[3])
}

/// An [`op::IMAGE`]'s lookup at `uv` (before its mapping), whose
/// derivatives in x and y are `duv`: pbrt-v4's `MIPMap::Filter` for
/// filtered images, bilinear in the image itself otherwise.
fn image_lookup(o: &TexOp, images: &[Arc<TextureImage>], uv: Vec2, duv: [Vec2; 2]) -> Vec3 {
    let wrap = o.b & 0xff;
    let channel = (o.b >> 8) & 0xff;
    let invert = (o.b >> 16) & 1 != 0;
    let filter = (o.b >> IMAGE_FILTER_SHIFT) & 0x7;
    let levels = (o.b >> IMAGE_LEVELS_SHIFT) & 0x3f;
    let scale = f32::from_bits(o.c);
    let st = apply_mapping(o.f, uv);
    let [dx, dy] = duv.map(|d| Vec2::new(o.f[0] * d.x, o.f[1] * d.y));
    let level = |l: u32| &*images[(o.a + l) as usize];
    let px = match filter {
        f if f == ImageFilter::None as u32 => bilerp(level(0), st, wrap),
        _ => {
            let width = 2.0 * dx.abs().max(dy.abs()).max_element();
            let n = levels as f32;
            let lod = n - 1.0 + width.max(1e-8).log2();
            if lod >= n - 1.0 {
                texel(level(levels - 1), 0, 0, wrap)
            } else {
                let i = lod.floor().max(0.0) as u32;
                match filter {
                    f if f == ImageFilter::Point as u32 => {
                        let image = level(i);
                        let x = (st.x * image.width as f32 - 0.5).round();
                        let y = ((1.0 - st.y) * image.height as f32 - 0.5).round();
                        texel(image, x.clamp(-1e8, 1e8) as i32, y.clamp(-1e8, 1e8) as i32, wrap)
                    }
                    f if f == ImageFilter::Bilinear as u32 || i == 0 => bilerp(level(i), st, wrap),
                    _ => {
                        let (a, b) = (bilerp(level(i), st, wrap), bilerp(level(i + 1), st, wrap));
                        let t = lod - i as f32;
                        std::array::from_fn(|c| (1.0 - t) * a[c] + t * b[c])
                    }
                }
            }
        }
    };
    let v = channel_value(px, channel) * scale;
    if invert {
        (Vec3::ONE - v).max(Vec3::ZERO)
    } else {
        v.max(Vec3::ZERO)
    }
}

/// Texel `(x, y)` of `image` under wrap mode `wrap` (black outside for
/// [`Wrap::Black`]).
fn texel(image: &TextureImage, x: i32, y: i32, wrap: u32) -> [f32; 4] {
    match (wrap_coord(x, image.width as i32, wrap), wrap_coord(y, image.height as i32, wrap)) {
        (Some(x), Some(y)) => image.texel(x as u32, y as u32),
        _ => [0.0; 4],
    }
}

/// Bilinear lookup of `image` at `st`, pbrt-v4's texel addressing.
fn bilerp(image: &TextureImage, st: Vec2, wrap: u32) -> [f32; 4] {
    let (w, h) = (image.width as i32, image.height as i32);
    let x = st.x * w as f32 - 0.5;
    let y = (1.0 - st.y) * h as f32 - 0.5;
    let (xf, yf) = (x.floor(), y.floor());
    let (dx, dy) = (x - xf, y - yf);
    // Far outside the image every wrap mode is periodic or constant:
    // clamping keeps the integer conversion in range.
    let (x0, y0) = (xf.clamp(-1e8, 1e8) as i32, yf.clamp(-1e8, 1e8) as i32);
    let t = |x, y| texel(image, x, y, wrap);
    let (t00, t10, t01, t11) = (t(x0, y0), t(x0 + 1, y0), t(x0, y0 + 1), t(x0 + 1, y0 + 1));
    std::array::from_fn(|c| {
        ((1.0 - dx) * t00[c] + dx * t10[c]) * (1.0 - dy) + ((1.0 - dx) * t01[c] + dx * t11[c]) * dy
    })
}

/// The texel a coordinate addresses under a wrap mode; `None`: black.
#[inline]
fn wrap_coord(i: i32, n: i32, wrap: u32) -> Option<i32> {
    Wrap::texel_of(wrap, i as i64, n as i64).map(|i| i as i32)
}

fn channel_value(px: [f32; 4], channel: u32) -> Vec3 {
    let [r, g, b, a] = px;
    match channel {
        c if c == Channel::Average as u32 => Vec3::splat((r + g + b) * (1.0 / 3.0)),
        c if c == Channel::Alpha as u32 => Vec3::splat(a),
        c if c == Channel::Red as u32 => Vec3::splat(r),
        c if c == Channel::Green as u32 => Vec3::splat(g),
        c if c == Channel::Blue as u32 => Vec3::splat(b),
        _ => Vec3::new(r, g, b),
    }
}

/// The uniform number deciding a stochastic alpha test: a hash of the ray
/// (as traversal sees it, in the space of the triangle) and the hit
/// distance, so every device decides alike and stacked cut-outs along one
/// ray decide independently. `kernels/texture.cuh` mirrors it.
pub fn alpha_hash(origin: Vec3A, dir: Vec3A, t: f32) -> f32 {
    let words = [origin.x, origin.y, origin.z, dir.x, dir.y, dir.z, t];
    let mut h = 0x9e37_79b9u32;
    for w in words {
        h = pcg_hash(h ^ w.to_bits());
    }
    (h >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// Whether an alpha value keeps a hit.
#[inline]
pub fn alpha_keeps(program: &AlphaProgram, alpha: f32, origin: Vec3A, dir: Vec3A, t: f32) -> bool {
    match program.mode & alpha_mode::TEXTURE_MASK {
        alpha_mode::CUTOFF => alpha >= program.cutoff,
        alpha_mode::STOCHASTIC => {
            // pbrt-v4's rule: alpha >= 1 always hits, <= 0 never.
            alpha >= 1.0 || (alpha > 0.0 && alpha_hash(origin, dir, t) < alpha)
        }
        _ => true,
    }
}

/// Textured parameters and alpha masks of a scene, for the CPU device: the
/// texture tables with the scene's images and meshes.
pub struct SceneTextures<'a> {
    pub scene: &'a Scene,
    pub tables: &'a TextureTables,
}

impl SceneTextures<'_> {
    /// Texture coordinates on triangle `triangle` of scene mesh `mesh`.
    pub fn uv(&self, mesh: u32, triangle: u32, b1: f32, b2: f32) -> Vec2 {
        let mesh = &self.scene.meshes[mesh as usize];
        let uvs =
            (!mesh.uvs.is_empty()).then(|| mesh.indices[triangle as usize].map(|i| mesh.uvs[i as usize]));
        hit_uv(uvs, b1, b2)
    }

    /// The corner uvs of triangle `triangle` of scene mesh `mesh` (pbrt's
    /// defaults where it has none).
    pub fn corner_uvs(&self, mesh: u32, triangle: u32) -> [Vec2; 3] {
        let mesh = &self.scene.meshes[mesh as usize];
        match mesh.uvs.is_empty() {
            true => [Vec2::ZERO, Vec2::X, Vec2::ONE],
            false => mesh.indices[triangle as usize].map(|i| mesh.uvs[i as usize]),
        }
    }

    /// The shading normal and `dpdu` of `surface` (whose footprint
    /// `footprint` makes, if it is needed) with material `id`'s bump or
    /// normal map; the surface's own where it has none.
    pub fn shading_geometry(
        &self,
        id: u32,
        surface: &crate::bump::SurfaceAt,
        footprint: impl FnOnce() -> Footprint,
    ) -> crate::bump::Bent {
        let bend = self.tables.shading_normals[id as usize];
        if bend.kind == bump::NONE {
            return crate::bump::Bent { normal: surface.ns, dpdu: surface.dpdu };
        }
        let footprint = footprint();
        let ops = self.ops(bend.program);
        let duv = [footprint.duvdx, footprint.duvdy];
        crate::bump::bent_normal(bend.kind, surface, duv, |uv, p| {
            let at = TexPoint { uv, position: p, normal: surface.ng, footprint };
            run_program(ops, &self.scene.textures.images, at, &mut [f16::ZERO; MATERIAL_COEFFS])
        })
    }

    /// Overwrites the textured coefficients of material `id` at hit `at`.
    pub fn apply(&self, id: u32, at: TexPoint, coeffs: &mut [f16; MATERIAL_COEFFS]) {
        let range = self.tables.materials[id as usize];
        if !range.is_empty() {
            run_program(self.ops(range), &self.scene.textures.images, at, coeffs);
        }
    }

    fn ops(&self, r: ProgramRange) -> &[TexOp] {
        &self.tables.ops[r.start as usize..(r.start + r.len) as usize]
    }
}

impl HitFilter for SceneTextures<'_> {
    fn filters(&self, mesh: u32) -> bool {
        self.tables.alpha_of(mesh).is_some()
    }

    fn keeps(&self, mesh: u32, triangle: u32, u: f32, v: f32, t: f32, origin: Vec3A, dir: Vec3A) -> bool {
        let Some(program) = self.tables.alpha_of(mesh) else { return true };
        let uv = self.uv(mesh, triangle, u, v);
        let mut scratch = [f16::ZERO; MATERIAL_COEFFS];
        // The point where traversal sees the hit: world space, except inside
        // instances (object space there; pbrt's 3D mappings take the world's).
        // No normal: a `directionmix` in an alpha mask takes its second texture.
        // No footprint either: pbrt-v4 tests alpha at the finest level.
        let at = TexPoint { uv, position: Vec3::from(origin + dir * t), ..Default::default() };
        let alpha = run_program(self.ops(program.program), &self.scene.textures.images, at, &mut scratch).x;
        alpha_keeps(program, alpha, origin, dir, t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material_layout::diffuse;
    use atoll_scene::{MeshAlpha, TextureBinding};

    /// (s, t) under a 3D mapping at `position`, through the ops it compiles to.
    fn projected(mapping: TexMapping, position: Vec3) -> Vec2 {
        let mut ops = Vec::new();
        let (f, flag) = mapping_ops(&mapping, &mut ops, 0).unwrap();
        assert_eq!((f, flag, ops.len()), ([1.0, 1.0, 0.0, 0.0], PROJECTED, 3));
        assert_eq!(ops.iter().map(|o| o.code).collect::<Vec<_>>(), [op::PROJECT, op::DATA, op::DATA]);
        project(&ops, 0, position, &Footprint::default()).0.truncate()
    }

    /// pbrt-v4's spherical, cylindrical and planar mappings, in the
    /// texture's space (`texture_from_world`, here a shift by -1 in x).
    #[test]
    fn projections_follow_pbrt() {
        use std::f32::consts::PI;
        let texture_from_world = glam::Affine3A::from_translation(Vec3::new(-1.0, 0.0, 0.0));
        let close = |a: Vec2, b: Vec2| (a - b).abs().max_element() < 1e-6;
        let sphere = |p: Vec3| projected(TexMapping::Spherical { texture_from_world }, p);
        assert!(close(sphere(Vec3::new(1.0, 0.0, 2.0)), Vec2::new(0.0, 0.0)), "+z: θ = 0");
        assert!(close(sphere(Vec3::new(3.0, 0.0, 0.0)), Vec2::new(0.5, 0.0)), "+x: θ = π/2, φ = 0");
        assert!(close(sphere(Vec3::new(1.0, 5.0, 0.0)), Vec2::new(0.5, 0.25)), "+y: φ = π/2");
        assert!(close(sphere(Vec3::new(1.0, -5.0, 0.0)), Vec2::new(0.5, 0.75)), "-y: φ = 3π/2");
        let cylinder = |p: Vec3| projected(TexMapping::Cylindrical { texture_from_world }, p);
        assert!(close(cylinder(Vec3::new(2.0, 0.0, 5.0)), Vec2::new(0.5, 5.0)), "+x: (π + 0) / 2π");
        assert!(close(cylinder(Vec3::new(1.0, 1.0, -1.0)), Vec2::new((PI + PI / 2.0) / (2.0 * PI), -1.0)));
        let planar = |p: Vec3| {
            let (vs, vt) = (Vec3::new(0.0, 0.0, 2.0), Vec3::new(0.0, 1.0, 0.0));
            projected(TexMapping::Planar { texture_from_world, vs, vt, ds: 0.25, dt: -1.0 }, p)
        };
        assert!(close(planar(Vec3::new(7.0, 3.0, 0.5)), Vec2::new(0.25 + 1.0, -1.0 + 3.0)));
    }

    /// `directionmix`: the facing amount `|n · dir|` mixes the second
    /// texture into the first (a Mix over [tex2, tex1]).
    #[test]
    fn facing_reads_the_normal() {
        let mut scene = Scene::default();
        let facing = scene.textures.add(Texture::Facing { direction: Vec3::Z });
        scene.textures.add(Texture::Mix {
            tex: [TexInput::Value(Rgb::splat(0.2)), TexInput::Value(Rgb::splat(0.8))],
            amount: TexInput::Texture(facing),
        });
        let mut ops = Vec::new();
        compile_texture(&scene, 1, &mut ops).unwrap();
        let at = |normal: Vec3| {
            let at = TexPoint { normal, ..TexPoint::default() };
            run_program(&ops, &[], at, &mut [f16::ZERO; MATERIAL_COEFFS]).x
        };
        assert_eq!(at(Vec3::Z), 0.8);
        assert_eq!(at(-Vec3::Z), 0.8, "either side");
        assert_eq!(at(Vec3::X), 0.2);
        assert!((at(Vec3::new(0.6, 0.0, 0.8)) - (0.2 * 0.2 + 0.8 * 0.8)).abs() < 1e-6);
    }

    /// A tree whose values would push past the stack is refused when
    /// compiled (not overflowing where it runs): each `bilerp` holds four
    /// values, nested in the last corner of the next.
    #[test]
    fn values_past_the_stack_are_refused() {
        let mut scene = Scene::default();
        let corner = |v: f32| TexInput::Value(Rgb::splat(v));
        let mapping = TexMapping::default();
        let mut last = scene.textures.add(Texture::Constant(Rgb::ONE));
        let mut results = Vec::new();
        for _ in 0..3 {
            last = scene.textures.add(Texture::Bilerp {
                mapping,
                corners: [corner(0.0), corner(0.5), corner(1.0), TexInput::Texture(last)],
            });
            results.push(compile_texture(&scene, last, &mut Vec::new()));
        }
        // Depths 4 and 7 fit eight values; a third level needs 10.
        assert!(results[0].is_ok() && results[1].is_ok(), "{results:?}");
        assert_eq!(results[2], Err(TextureCompileError::StackTooDeep));
    }

    /// A projected checkerboard takes its squares from the point, not the
    /// surface's uv, and keeps its inputs' order on the stack.
    #[test]
    fn projected_checkerboards_read_the_point() {
        let mut scene = Scene::default();
        let texture_from_world = glam::Affine3A::IDENTITY;
        let (vs, vt) = (Vec3::X, Vec3::Y);
        scene.textures.add(Texture::Checkerboard {
            mapping: TexMapping::Planar { texture_from_world, vs, vt, ds: 0.0, dt: 0.0 },
            tex: [TexInput::Value(Rgb::splat(0.2)), TexInput::Value(Rgb::splat(0.8))],
        });
        let mut ops = Vec::new();
        compile_texture(&scene, 0, &mut ops).unwrap();
        let at = |p: Vec3| {
            run_program(
                &ops,
                &[],
                TexPoint { position: p, ..TexPoint::uv(Vec2::splat(0.5)) },
                &mut [f16::ZERO; MATERIAL_COEFFS],
            )
            .x
        };
        assert_eq!(at(Vec3::new(0.5, 0.5, 9.0)), 0.2);
        assert_eq!(at(Vec3::new(1.5, 0.5, 9.0)), 0.8);
        assert_eq!(at(Vec3::new(-0.5, 0.5, 0.0)), 0.8);
    }

    fn image(texels: Vec<[f32; 4]>, w: u32, h: u32) -> Arc<TextureImage> {
        Arc::new(TextureImage::from_linear("t", w, h, texels))
    }

    fn image_op(wrap: Wrap, channel: Channel, scale: f32, invert: bool) -> TexOp {
        TexOp {
            code: op::IMAGE,
            a: 0,
            b: wrap as u32 | (channel as u32) << 8 | (invert as u32) << 16,
            c: scale.to_bits(),
            f: [1.0, 1.0, 0.0, 0.0],
        }
    }

    fn eval(ops: &[TexOp], images: &[Arc<TextureImage>], uv: Vec2) -> Vec3 {
        run_program(ops, images, TexPoint::uv(uv), &mut [f16::ZERO; MATERIAL_COEFFS])
    }

    /// A filtered image picks the MIP level pbrt-v4 picks for the
    /// footprint: `n - 1 + log2(2 · widest derivative)` for an image of `n`
    /// levels, the coarsest past the last, blended between two for
    /// trilinear filtering.
    #[test]
    fn footprints_pick_mip_levels_as_pbrt() {
        // An 8×8 image of x + 10 y: levels 8, 4, 2 and 1 texels wide.
        let base =
            image((0..64).map(|i| [(i % 8) as f32 + 10.0 * (i / 8) as f32, 0.0, 0.0, 1.0]).collect(), 8, 8);
        let mut textures = atoll_scene::Textures::default();
        let (first, levels) = textures.add_pyramid(&base, Wrap::Repeat);
        assert_eq!((first, levels), (0, 4));
        let images = textures.images;
        let op = |filter: ImageFilter| TexOp {
            b: image_op(Wrap::Repeat, Channel::Red, 1.0, false).b
                | (filter as u32) << IMAGE_FILTER_SHIFT
                | levels << IMAGE_LEVELS_SHIFT,
            ..image_op(Wrap::Repeat, Channel::Red, 1.0, false)
        };
        let uv = Vec2::new(0.3, 0.6);
        let at = |d: f32| TexPoint {
            uv,
            footprint: Footprint {
                duvdx: Vec2::new(d, 0.0),
                duvdy: Vec2::new(0.0, d / 2.0),
                ..Default::default()
            },
            ..Default::default()
        };
        let run = |f: ImageFilter, d: f32| {
            run_program(&[op(f)], &images, at(d), &mut [f16::ZERO; MATERIAL_COEFFS]).x
        };
        let level = |l: usize, uv: Vec2| bilerp(&images[l], uv, Wrap::Repeat as u32)[0];
        // Width 2/16 = 1/8: level 3 + log2(1/8) = 0; 1/4: level 1.
        assert_eq!(run(ImageFilter::Bilinear, 1.0 / 16.0), level(0, uv));
        assert_eq!(run(ImageFilter::Bilinear, 1.0 / 8.0), level(1, uv));
        // Past the last level: the one texel, the image's mean.
        assert_eq!(run(ImageFilter::Bilinear, 0.5), 38.5);
        // Trilinear: a third of the way from level 1 to 2.
        let d = 2f32.powf(1.0 / 3.0) / 8.0;
        let blend = level(1, uv) + (level(2, uv) - level(1, uv)) * (1.0 / 3.0);
        assert!((run(ImageFilter::Trilinear, d) - blend).abs() < 1e-4);
        // No footprint, or no filter: the finest level, bilinearly.
        assert_eq!(run(ImageFilter::Trilinear, 0.0), level(0, uv));
        assert_eq!(eval(&[image_op(Wrap::Repeat, Channel::Red, 1.0, false)], &images, uv).x, level(0, uv));
        // Point: level 1's nearest texel (x 1, row 1 from the top).
        assert_eq!(run(ImageFilter::Point, 1.0 / 8.0), images[1].texel(1, 1)[0]);
    }

    /// pbrt-v4's filtered checkerboard is the ±1 checks averaged under a
    /// triangle filter of the footprint's radius (checked by quadrature).
    #[test]
    fn checkerboards_are_box_filtered_over_the_footprint() {
        let checks = |x: f32| if (x.floor() as i32) & 1 == 0 { 1.0 } else { -1.0 };
        for (x, r) in [(0.3f32, 0.5f32), (1.9, 0.25), (-0.6, 1.7), (2.5, 4.0), (0.99, 0.02)] {
            let n = 20_000;
            let (mut sum, mut weights) = (0.0f64, 0.0f64);
            for i in 0..n {
                let t = -r + 2.0 * r * (i as f32 + 0.5) / n as f32;
                let w = (1.0 - (t / r).abs()) as f64;
                sum += w * checks(x + t);
                weights += w;
            }
            let got = filtered_checks(x, r) as f64;
            assert!((got - sum / weights).abs() < 2e-3, "x {x} r {r}: {got} against {}", sum / weights);
        }
        // Within one cell: the cell's sign, as without a footprint.
        assert_eq!(
            (filtered_checks(0.5, 0.1), filtered_checks(1.5, 0.1), filtered_checks(-0.5, 0.0)),
            (1.0, -1.0, -1.0)
        );
    }

    /// Texel centres return the texel; halfway between two, their mean;
    /// row 0 is the top of the image (t = 1).
    #[test]
    fn bilinear_lookups_follow_pbrt_addressing() {
        let img = image(vec![[0.0, 0.0, 0.0, 1.0], [1.0, 0.5, 0.25, 0.0], [0.2; 4], [0.4; 4]], 2, 2);
        let images = [img];
        let o = [image_op(Wrap::Clamp, Channel::Rgb, 1.0, false)];
        assert_eq!(eval(&o, &images, Vec2::new(0.75, 0.75)), Vec3::new(1.0, 0.5, 0.25));
        assert_eq!(eval(&o, &images, Vec2::new(0.25, 0.25)), Vec3::splat(0.2));
        let mid = eval(&o, &images, Vec2::new(0.5, 0.75));
        assert!(mid.abs_diff_eq(Vec3::new(0.5, 0.25, 0.125), 1e-6), "{mid}");
        // Channels, scale and invert.
        let alpha = [image_op(Wrap::Clamp, Channel::Alpha, 1.0, false)];
        assert_eq!(eval(&alpha, &images, Vec2::new(0.25, 0.75)), Vec3::ONE);
        let avg = [image_op(Wrap::Clamp, Channel::Average, 2.0, true)];
        let v = eval(&avg, &images, Vec2::new(0.75, 0.75));
        assert!(v.abs_diff_eq(Vec3::splat(0.0), 1e-6), "1 - 2 * mean(1, .5, .25) clamps to 0: {v}");
        let green = [image_op(Wrap::Clamp, Channel::Green, 1.0, false)];
        assert_eq!(eval(&green, &images, Vec2::new(0.75, 0.75)), Vec3::splat(0.5));
    }

    #[test]
    fn wrap_modes_address_outside_the_image() {
        assert_eq!(wrap_coord(-1, 4, Wrap::Repeat as u32), Some(3));
        assert_eq!(wrap_coord(9, 4, Wrap::Repeat as u32), Some(1));
        assert_eq!(wrap_coord(-3, 4, Wrap::Clamp as u32), Some(0));
        assert_eq!(wrap_coord(7, 4, Wrap::Clamp as u32), Some(3));
        assert_eq!(wrap_coord(4, 4, Wrap::Black as u32), None);
        assert_eq!(wrap_coord(4, 4, Wrap::Mirror as u32), Some(3));
        assert_eq!(wrap_coord(-1, 4, Wrap::Mirror as u32), Some(0));
        assert_eq!(wrap_coord(8, 4, Wrap::Mirror as u32), Some(0));
        let images = [image(vec![[1.0; 4]], 1, 1)];
        let black = [image_op(Wrap::Black, Channel::Rgb, 1.0, false)];
        assert_eq!(eval(&black, &images, Vec2::new(0.5, 0.5)), Vec3::ONE);
        assert_eq!(eval(&black, &images, Vec2::new(1.5, 0.5)), Vec3::ZERO);
    }

    /// Programs from texture trees: checkerboard of a constant and a
    /// scaled mix, stored into a material's coefficients.
    #[test]
    fn texture_trees_compile_to_programs_that_store_parameters() {
        let mut scene = Scene::default();
        let m = scene.add_material(Material::Diffuse { reflectance: Rgb::splat(0.5) });
        let c = scene.add_material(Material::Conductor {
            eta: Rgb::ONE,
            k: Rgb::ONE,
            alpha_x: 0.0,
            alpha_y: 0.0,
        });
        let t = &mut scene.textures;
        let mix = t.add(Texture::Mix {
            tex: [TexInput::Value(Rgb::splat(0.2)), TexInput::Value(Rgb::splat(0.6))],
            amount: TexInput::Value(Rgb::splat(0.25)),
        });
        let scaled = t.add(Texture::Scale {
            tex: TexInput::Texture(mix),
            scale: TexInput::Value(Rgb::new(1.0, 0.5, 2.0)),
        });
        let checker = t.add(Texture::Checkerboard {
            mapping: atoll_scene::UvMapping { su: 2.0, sv: 2.0, du: 0.0, dv: 0.0 }.into(),
            tex: [TexInput::Value(Rgb::splat(0.9)), TexInput::Texture(scaled)],
        });
        t.bind(TextureBinding {
            material: m,
            param: TexturedParam::Reflectance,
            texture: checker,
            remap_roughness: false,
        });
        let rough = t.add(Texture::Constant(Rgb::splat(0.25)));
        t.bind(TextureBinding {
            material: c,
            param: TexturedParam::Roughness,
            texture: rough,
            remap_roughness: true,
        });
        t.bind(TextureBinding {
            material: c,
            param: TexturedParam::Reflectance,
            texture: rough,
            remap_roughness: false,
        });
        // Not a diffuse parameter: dropped.
        t.bind(TextureBinding {
            material: m,
            param: TexturedParam::Transmittance,
            texture: rough,
            remap_roughness: false,
        });
        let kinds = [MaterialKind::Diffuse, MaterialKind::Conductor];
        let tables = TextureTables::new(&scene, &kinds);
        let st = SceneTextures { scene: &scene, tables: &tables };
        let coeffs_at = |id: u32, uv: Vec2| {
            let mut c = [f16::ZERO; MATERIAL_COEFFS];
            st.apply(id, TexPoint::uv(uv), &mut c);
            c.map(f16::to_f32)
        };
        let reflectance = diffuse::REFLECTANCE..diffuse::REFLECTANCE + 3;
        // (0.1, 0.1) → st (0.2, 0.2): even square, 0.9.
        let even = coeffs_at(m, Vec2::new(0.1, 0.1));
        assert_eq!(even[reflectance.clone()], [f16::from_f32(0.9).to_f32(); 3]);
        // (0.6, 0.1) → odd: (0.75 * 0.2 + 0.25 * 0.6) * (1, 0.5, 2) = 0.3 * ...
        let odd = coeffs_at(m, Vec2::new(0.6, 0.1));
        for (got, want) in odd[reflectance].iter().zip([0.3, 0.15, 0.6]) {
            assert!((got - want).abs() < 1e-3, "{odd:?}");
        }
        let metal = coeffs_at(c, Vec2::ZERO);
        assert_eq!(metal[conductor::ALPHA_X], 0.5, "sqrt of roughness 0.25");
        assert_eq!(metal[conductor::ALPHA_Y], 0.5);
        assert_eq!(metal[conductor::ETA..conductor::ETA + 3], [1.0; 3], "eta 1 for a reflectance");
        let k = Material::conductor_k_from_reflectance(Rgb::splat(0.25)).x;
        assert!((metal[conductor::K] - k).abs() < 1e-2 * k, "{metal:?}");
        assert!(!tables.has_alpha());
    }

    /// Stochastic alpha keeps a share `alpha` of hits, decided by the ray.
    #[test]
    fn stochastic_alpha_keeps_its_share_of_hits() {
        let mut scene = Scene::default();
        let material = scene.add_material(Material::default_diffuse());
        let half = scene.textures.add(Texture::Constant(Rgb::splat(0.3)));
        let mesh = scene.add_mesh(atoll_scene::TriangleMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            indices: vec![[0, 1, 2]],
            material,
            alpha: Some(MeshAlpha { texture: half, mode: AlphaMode::Stochastic }),
            ..Default::default()
        });
        let tables = TextureTables::new(&scene, &[MaterialKind::Diffuse]);
        let st = SceneTextures { scene: &scene, tables: &tables };
        assert!(st.filters(mesh));
        let n = 20_000;
        let kept = (0..n)
            .filter(|&i| {
                let o = Vec3A::new(i as f32 * 1e-3, 0.1, -1.0);
                st.keeps(mesh, 0, 0.2, 0.2, 1.0, o, Vec3A::Z)
            })
            .count();
        let share = kept as f64 / n as f64;
        assert!((share - 0.3).abs() < 0.015, "{share}");
        let o = Vec3A::new(0.5, 0.1, -1.0);
        assert_eq!(
            st.keeps(mesh, 0, 0.2, 0.2, 1.0, o, Vec3A::Z),
            st.keeps(mesh, 0, 0.2, 0.2, 1.0, o, Vec3A::Z)
        );
    }
}

#[cfg(test)]
mod binding_tests {
    use super::*;
    use crate::material_coeffs::PackedMaterial;
    use atoll_scene::{
        CoatedConductorParams, CoatedDiffuseParams, Coating, PrincipledParams, Rgb, TextureBinding,
    };

    /// A parameter bound to a constant texture of value `v` packs like the
    /// material with that parameter set to `v`: every store target is the
    /// coefficient the material layout gives the parameter.
    #[test]
    fn constant_textures_store_like_material_values() {
        let principled = Material::Principled(PrincipledParams {
            base_color: Rgb::splat(0.5),
            metallic: 0.0,
            roughness: 0.5,
            specular: 0.5,
            specular_tint: 0.0,
            sheen: 0.0,
            sheen_tint: 0.5,
            clearcoat: 0.0,
            clearcoat_gloss: 1.0,
            transmission: 0.0,
            eta: 1.5,
        });
        let coating = Coating::PBRT_DEFAULT;
        let coated = Material::CoatedDiffuse(CoatedDiffuseParams { reflectance: Rgb::splat(0.5), coating });
        let coated_metal = Material::CoatedConductor(CoatedConductorParams {
            eta: Rgb::ONE,
            k: Rgb::ONE,
            alpha_x: 0.0,
            alpha_y: 0.0,
            coating,
        });
        let v = Rgb::new(0.25, 0.375, 0.625);
        let s = v.x;
        use TexturedParam as P;
        // (material, parameter, texture value, the material with the value set)
        let set = |m: &Material, f: &dyn Fn(&mut Material)| {
            let mut m = m.clone();
            f(&mut m);
            m
        };
        macro_rules! field {
            ($m:expr, $variant:ident, $field:ident, $value:expr) => {
                set(&$m, &|m| {
                    if let Material::$variant { $field, .. } = m {
                        *$field = $value;
                    }
                })
            };
        }
        // The same for materials whose parameters are a struct.
        macro_rules! params_field {
            ($m:expr, $variant:ident, $($field:ident).+, $value:expr) => {
                set(&$m, &|m| {
                    if let Material::$variant(p) = m {
                        p.$($field).+ = $value;
                    }
                })
            };
        }
        let conductor = Material::Conductor { eta: Rgb::ONE, k: Rgb::ONE, alpha_x: 0.0, alpha_y: 0.0 };
        let cases: Vec<(Material, P, Rgb, Material)> = vec![
            (Material::default_diffuse(), P::Reflectance, v, Material::Diffuse { reflectance: v }),
            (conductor.clone(), P::Eta, v, field!(conductor, Conductor, eta, v)),
            (conductor.clone(), P::K, v, field!(conductor, Conductor, k, v)),
            (conductor.clone(), P::Roughness, Rgb::splat(s), {
                let m = field!(conductor, Conductor, alpha_x, s);
                field!(m, Conductor, alpha_y, s)
            }),
            (
                Material::DiffuseTransmission { reflectance: Rgb::ONE, transmittance: Rgb::ONE },
                P::Transmittance,
                v,
                Material::DiffuseTransmission { reflectance: Rgb::ONE, transmittance: v },
            ),
            (coated.clone(), P::Reflectance, v, params_field!(coated, CoatedDiffuse, reflectance, v)),
            (coated.clone(), P::Albedo, v, params_field!(coated, CoatedDiffuse, coating.albedo, v)),
            (
                coated.clone(),
                P::Thickness,
                Rgb::splat(s),
                params_field!(coated, CoatedDiffuse, coating.thickness, s),
            ),
            (coated.clone(), P::G, Rgb::splat(s), params_field!(coated, CoatedDiffuse, coating.g, s)),
            // Back-scattering media keep their sign; pbrt's clamps hold.
            (coated.clone(), P::G, Rgb::splat(-0.5), params_field!(coated, CoatedDiffuse, coating.g, -0.5)),
            (coated.clone(), P::G, Rgb::splat(-3.0), params_field!(coated, CoatedDiffuse, coating.g, -1.0)),
            (
                coated.clone(),
                P::Albedo,
                Rgb::new(0.5, 1.5, -2.0),
                params_field!(coated, CoatedDiffuse, coating.albedo, Rgb::new(0.5, 1.0, 0.0)),
            ),
            (coated_metal.clone(), P::Eta, v, params_field!(coated_metal, CoatedConductor, eta, v)),
            (coated_metal.clone(), P::K, v, params_field!(coated_metal, CoatedConductor, k, v)),
            (coated_metal.clone(), P::Reflectance, v, {
                let m = params_field!(coated_metal, CoatedConductor, eta, Rgb::ONE);
                params_field!(m, CoatedConductor, k, Material::conductor_k_from_reflectance(v))
            }),
            (coated_metal.clone(), P::ConductorURoughness, Rgb::splat(s), {
                params_field!(coated_metal, CoatedConductor, alpha_x, s)
            }),
            (coated_metal.clone(), P::ConductorRoughness, Rgb::splat(s), {
                let m = params_field!(coated_metal, CoatedConductor, alpha_x, s);
                params_field!(m, CoatedConductor, alpha_y, s)
            }),
            (coated_metal.clone(), P::VRoughness, Rgb::splat(s), {
                params_field!(coated_metal, CoatedConductor, coating.alpha_y, s)
            }),
            (
                coated_metal.clone(),
                P::Albedo,
                v,
                params_field!(coated_metal, CoatedConductor, coating.albedo, v),
            ),
            (
                coated_metal.clone(),
                P::G,
                Rgb::splat(s),
                params_field!(coated_metal, CoatedConductor, coating.g, s),
            ),
            (principled.clone(), P::Reflectance, v, params_field!(principled, Principled, base_color, v)),
            (
                principled.clone(),
                P::Metallic,
                Rgb::splat(s),
                params_field!(principled, Principled, metallic, s),
            ),
            (
                principled.clone(),
                P::Roughness,
                Rgb::splat(s),
                params_field!(principled, Principled, roughness, s),
            ),
            (
                principled.clone(),
                P::SpecularTint,
                Rgb::splat(s),
                params_field!(principled, Principled, specular_tint, s),
            ),
            (principled.clone(), P::Sheen, Rgb::splat(s), params_field!(principled, Principled, sheen, s)),
            (
                principled.clone(),
                P::SheenTint,
                Rgb::splat(s),
                params_field!(principled, Principled, sheen_tint, s),
            ),
            (
                principled.clone(),
                P::Clearcoat,
                Rgb::splat(s),
                params_field!(principled, Principled, clearcoat, s),
            ),
            (
                principled.clone(),
                P::ClearcoatGloss,
                Rgb::splat(s),
                params_field!(principled, Principled, clearcoat_gloss, s),
            ),
            (
                principled.clone(),
                P::Transmission,
                Rgb::splat(s),
                params_field!(principled, Principled, transmission, s),
            ),
        ];
        for (base, param, value, expected) in cases {
            let mut scene = Scene::default();
            let m = scene.add_material(base.clone());
            let t = scene.textures.add(Texture::Constant(value));
            scene.textures.bind(TextureBinding { material: m, param, texture: t, remap_roughness: false });
            let packed = PackedMaterial::pack(&base);
            let tables = TextureTables::new(&scene, &[packed.kind]);
            assert!(!tables.materials[0].is_empty(), "{param:?} on {base:?} was dropped");
            let mut coeffs = packed.coeffs;
            SceneTextures { scene: &scene, tables: &tables }.apply(m, TexPoint::default(), &mut coeffs);
            assert_eq!(coeffs, PackedMaterial::pack(&expected).coeffs, "{param:?} on {base:?}");
        }
    }
}
