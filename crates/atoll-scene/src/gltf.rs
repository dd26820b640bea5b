//! glTF 2.0 scenes (`.gltf` with external or data-URI buffers, and `.glb`),
//! read with the `gltf` crate.
//!
//! - **Instancing**: each glTF mesh referenced by a node becomes one atoll
//!   [`Object`] made of its triangle primitives; each node that references a
//!   mesh becomes one [`Instance`] with the node's world transform. A mesh
//!   referenced by many nodes is stored once. Triangle strips and fans are
//!   converted to triangles; points and lines are skipped with a warning.
//! - **Coordinates** stay as they are (right-handed, +Y up); atoll has no
//!   fixed up axis. glTF's front faces wind counter-clockwise, which is the
//!   side atoll's geometric normal points to, so `flip_normals` is false.
//! - **Materials** become [`Material::Principled`] ([`convert_material`]):
//!   `baseColorFactor`, `metallicFactor`, `roughnessFactor` (perceptual, as
//!   the principled roughness), `KHR_materials_ior` (default 1.5) as `eta` and,
//!   with `KHR_materials_specular`'s factors, as `specular` (glTF's dielectric
//!   reflectance `((ior - 1) / (ior + 1))² · specularFactor ·
//!   specularColorFactor`, its colour's luminance); `KHR_materials_transmission`
//!   as `transmission` (a refracting solid: glTF without `KHR_materials_volume`
//!   means a thin wall, which atoll does not model); `KHR_materials_clearcoat`
//!   (its roughness² as the coat's GTR1 alpha) and `KHR_materials_sheen` (the
//!   colour's largest channel, untinted) read from the raw extension JSON,
//!   which the `gltf` crate does not parse. Specular-glossiness materials use
//!   their diffuse factor and texture, `1 - glossiness` and the specular
//!   factor's luminance. Primitives without a material get glTF's default
//!   material (white, metallic 1, roughness 1), as viewers do.
//! - **Textures** go into [`crate::Scene::textures`]: `baseColorTexture`
//!   (sRGB, times `baseColorFactor` through a `Scale` node) bound to
//!   `Reflectance`; `metallicRoughnessTexture` (linear) as two image textures
//!   of the same image, blue scaled by `metallicFactor` bound to `Metallic`,
//!   green by `roughnessFactor` to `Roughness`. Images are decoded from the
//!   file's buffers, data URIs or files (16-bit sRGB images at 8 bits), once
//!   per colour encoding; samplers' wrap modes map to [`Wrap`] (u's when u
//!   and v differ); `KHR_texture_transform`'s offset and scale join the
//!   `v` flip into the [`UvMapping`] (rotation is ignored). `TEXCOORD_0`
//!   gives the meshes' uvs. What is not read (normal and
//!   extension textures, textures on other texture coordinates, ...) is
//!   named in one warning a file; an image that cannot be read leaves its
//!   material with the factors, after a warning.
//! - **Alpha**: `MASK` cuts the primitive where the base colour's alpha
//!   (texture × factor) is below `alphaCutoff` (default 0.5); `BLEND` is
//!   rendered as stochastic coverage (alpha is the probability that a ray
//!   hits), which converges to the blend for a single layer.
//! - **Emission**: `emissiveFactor × KHR_materials_emissive_strength`, when
//!   non-zero, is a one-sided area light on the primitive's mesh, scaled
//!   across it by `emissiveTexture` (sRGB) when there is one.
//! - **Camera**: the first perspective camera met walking the scene's nodes
//!   (see [`camera_to_world`] and [`camera_fov_and_resolution`]); without one,
//!   [`crate::framing`] frames the model.
//! - **Lights** (`KHR_lights_punctual`): point → `Light::Point` (candela =
//!   W/sr here, used as is), directional → `Light::Distant` (lux used as its
//!   radiance), spot → `Light::Spot` (cone angles as pbrt's coneangle/conedelta).
//!   Without punctual lights the default sky and sun of [`crate::framing`]
//!   are added, even when some materials are emissive (in glTF content those
//!   are screens and LEDs, not what lights the scene).

use std::collections::{BTreeSet, HashMap};
use std::path::Path;
use std::sync::Arc;

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::json::validation::Checked;
use ::gltf::khr_lights_punctual::Kind as LightKind;
use ::gltf::mesh::Mode;
use glam::{Affine3A, Mat4, UVec2, Vec2, Vec3, Vec4};

use crate::error::{FileLoc, SceneError};
use crate::pbrt::WarningSink;
use crate::{
    luminance, AlphaMode, AreaEmission, Camera, Channel, ImageId, ImageLoadError, Instance, Light,
    LoadedScene, Material, MaterialId, MeshAlpha, Object, ObjectId, PrincipledParams, Rgb, TexInput, Texels,
    Texture, TextureBinding, TextureImage, TexturedParam, TriangleMesh, UvMapping, Wrap,
};

/// Loads a `.gltf` or `.glb` file; external buffers resolve against its directory.
pub fn load_gltf(path: &Path) -> Result<LoadedScene, SceneError> {
    crate::input::scene_load(|| {
        let name = path.display().to_string();
        let bytes = crate::input::read(path).map_err(|e| {
            SceneError::caused_by(&FileLoc::whole_file(name.as_str()), format!("cannot read: {e}"), e)
        })?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        load_gltf_bytes(&bytes, &name, &base)
    })
}

/// Loads glTF from memory (`name` for messages; external files resolve against `base`).
pub fn load_gltf_bytes(bytes: &[u8], name: &str, base: &Path) -> Result<LoadedScene, SceneError> {
    let whole = FileLoc::whole_file(name);
    // We check every accessor before the gltf crate reads it (it panics on
    // some malformed files); this catch is the last line of defence so that
    // a bad file is an error, never a crash.
    let load = || crate::input::scene_load(|| convert(bytes, name, base));
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(load)) {
        Ok(result) => result,
        Err(_) => Err(SceneError::at(&whole, "malformed glTF: the glTF reader failed on this file")),
    }
}

/// State of one glTF load.
struct Loader<'a> {
    doc: &'a ::gltf::Document,
    buffers: Vec<::gltf::buffer::Data>,
    base: &'a Path,
    loc: FileLoc,
    out: LoadedScene,
    w: WarningSink,
    /// glTF material index (`None`: the default material) → atoll material
    /// and the alpha mask of the primitives that use it.
    materials: HashMap<Option<usize>, (MaterialId, Option<MeshAlpha>)>,
    /// glTF material index → its emissive texture, if any.
    emission_textures: HashMap<Option<usize>, Option<u32>>,
    /// (glTF image index, sRGB) → the decoded image (`None`: unreadable).
    images: HashMap<(usize, bool), Option<ImageId>>,
    /// What the file uses that atoll ignores, named in one warning.
    ignored: BTreeSet<&'static str>,
    /// glTF mesh index → atoll object (`None`: the mesh has no triangles).
    objects: HashMap<usize, Option<ObjectId>>,
    /// The first camera: its node's world transform and its projection.
    camera: Option<(Mat4, GltfProjection)>,
}

/// A glTF camera's projection, as the file gives it.
enum GltfProjection {
    /// Vertical field of view in radians and the aspect ratio, if given.
    Perspective { yfov: f32, aspect: Option<f32> },
    /// Half the view's width and height in camera-space units.
    Orthographic { xmag: f32, ymag: f32 },
}

/// Parses, reads the buffers, converts.
fn convert(bytes: &[u8], name: &str, base: &Path) -> Result<LoadedScene, SceneError> {
    let loc = FileLoc::whole_file(name);
    // The gltf crate trusts a few things it does not check (and panics on
    // them): those are checked here, before and after parsing.
    check_glb_length(bytes).map_err(|m| SceneError::at(&loc, m))?;
    let raw = ::gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| parse_error(e, bytes, name))?;
    let json = raw.document.into_json();
    check_unvalidated(&json).map_err(|m| SceneError::at(&loc, m))?;
    let document = ::gltf::Document::from_json(json).map_err(|e| parse_error(e, bytes, name))?;
    let gltf = ::gltf::Gltf { document, blob: raw.blob };
    let buffers = read_buffers(&gltf.document, gltf.blob.clone(), base, &loc)?;
    let mut loader = Loader {
        doc: &gltf.document,
        buffers,
        base,
        loc,
        out: LoadedScene::default(),
        w: WarningSink::default(),
        materials: HashMap::new(),
        emission_textures: HashMap::new(),
        images: HashMap::new(),
        ignored: BTreeSet::new(),
        objects: HashMap::new(),
        camera: None,
    };
    loader.walk_nodes()?;
    loader.finish()
}

impl<'a> Loader<'a> {
    /// Visits every node of the scene to show with its world transform.
    fn walk_nodes(&mut self) -> Result<(), SceneError> {
        let doc = self.doc;
        let node_count = doc.as_json().nodes.len();
        let roots: Vec<::gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
            Some(scene) => scene.nodes().collect(),
            None => {
                if node_count > 0 {
                    self.w.warn(&self.loc, "the file has no scene; showing every root node");
                }
                let mut is_child = vec![false; node_count];
                doc.nodes().flat_map(|n| n.children()).for_each(|c| is_child[c.index()] = true);
                doc.nodes().filter(|n| !is_child[n.index()]).collect()
            }
        };
        let mut stack: Vec<_> = roots.into_iter().rev().map(|n| (n, Mat4::IDENTITY, 0)).collect();
        while let Some((node, parent, depth)) = stack.pop() {
            // A path longer than the node count repeats a node: the hierarchy has a cycle.
            if depth > node_count {
                return Err(SceneError::at(
                    &self.loc,
                    format!("the node hierarchy has a cycle (through node {})", node.index()),
                ));
            }
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            self.node(&node, world)?;
            stack
                .extend(node.children().collect::<Vec<_>>().into_iter().rev().map(|c| (c, world, depth + 1)));
        }
        Ok(())
    }

    fn node(&mut self, node: &::gltf::Node<'a>, world: Mat4) -> Result<(), SceneError> {
        if let Some(mesh) = node.mesh() {
            if let Some(object) = self.object(&mesh)? {
                self.out.scene.instances.push(Instance::new(object, Affine3A::from_mat4(world)));
            }
        }
        if let Some(cam) = node.camera() {
            if self.camera.is_none() {
                let projection = match cam.projection() {
                    ::gltf::camera::Projection::Perspective(p) => {
                        let yfov = p.yfov();
                        if !(yfov > 0.0 && yfov < std::f32::consts::PI) {
                            return Err(SceneError::at(
                                &self.loc,
                                format!(
                                    "camera {}: yfov {yfov} is not between 0 and pi radians",
                                    cam.index()
                                ),
                            ));
                        }
                        GltfProjection::Perspective { yfov, aspect: p.aspect_ratio() }
                    }
                    ::gltf::camera::Projection::Orthographic(o) => {
                        let (xmag, ymag) = (o.xmag().abs(), o.ymag().abs());
                        if !(xmag > 0.0 && ymag > 0.0 && xmag.is_finite() && ymag.is_finite()) {
                            return Err(SceneError::at(
                                &self.loc,
                                format!(
                                    "camera {}: orthographic xmag {} and ymag {} must be nonzero",
                                    cam.index(),
                                    o.xmag(),
                                    o.ymag()
                                ),
                            ));
                        }
                        GltfProjection::Orthographic { xmag, ymag }
                    }
                };
                self.camera = Some((world, projection));
            }
        }
        if let Some(light) = node.light() {
            let rgb = Rgb::from(light.color()) * light.intensity();
            let position = world.transform_point3(Vec3::ZERO);
            let direction = world.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Z);
            let light = match light.kind() {
                LightKind::Point => Light::Point { position, intensity: rgb },
                LightKind::Directional => Light::Distant { direction, radiance: rgb },
                LightKind::Spot { inner_cone_angle, outer_cone_angle } => {
                    // glTF's cone angles are radians from the axis; its
                    // suggested falloff is quadratic in cos θ between them,
                    // pbrt's (used here) a smoothstep: equal at both ends.
                    let outer = outer_cone_angle.to_degrees();
                    let inner = inner_cone_angle.to_degrees().min(outer);
                    Light::spot(position, direction, rgb, outer, outer - inner)
                }
            };
            self.out.scene.lights.push(light);
        }
        Ok(())
    }

    /// The object for glTF mesh `mesh`, built on first use.
    fn object(&mut self, mesh: &::gltf::Mesh<'a>) -> Result<Option<ObjectId>, SceneError> {
        if let Some(&o) = self.objects.get(&mesh.index()) {
            return Ok(o);
        }
        let mesh_name = mesh.name().map(String::from).unwrap_or_else(|| format!("mesh {}", mesh.index()));
        let mut meshes = Vec::new();
        for prim in mesh.primitives() {
            let what = format!("{mesh_name}, primitive {}", prim.index());
            if let Some(m) = self.primitive(&prim, &what)? {
                let emits = m.emission.is_some();
                let id = self.out.scene.add_mesh(m);
                // emissiveTexture scales the emissive factor across the mesh.
                if let Some(texture) = emits.then(|| self.emission_texture(&prim.material())).flatten() {
                    self.out.scene.textures.bind_emission(id, texture);
                }
                meshes.push(id);
            }
        }
        let object =
            (!meshes.is_empty()).then(|| self.out.scene.add_object(Object { name: mesh_name, meshes }));
        self.objects.insert(mesh.index(), object);
        Ok(object)
    }

    /// The triangles of one primitive; `None` (after a warning) for points and lines.
    fn primitive(
        &mut self,
        prim: &::gltf::Primitive<'a>,
        what: &str,
    ) -> Result<Option<TriangleMesh>, SceneError> {
        let mode = prim.mode();
        if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            self.w.warn(&self.loc, format!("{what}: {mode:?} primitives are not supported; skipped"));
            return Ok(None);
        }
        let loc = self.loc.clone();
        let err = |m: String| SceneError::at(&loc, format!("{what}: {m}"));
        let accessor = |e: AccessorError| SceneError::caused_by(&loc, format!("{what}: {e}"), e);
        let buffers = &self.buffers;
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| d.0.as_slice()));
        let Some(pos) = prim.get(&::gltf::Semantic::Positions) else {
            return Err(err("no POSITION attribute".into()));
        };
        check_accessor(self.doc, &pos, "POSITION", &[Dimensions::Vec3], &[DataType::F32])
            .map_err(accessor)?;
        let positions: Vec<Vec3> =
            reader.read_positions().ok_or_else(|| err(out_of_range("POSITION")))?.map(Vec3::from).collect();
        let n = positions.len();
        let mut normals = Vec::new();
        if let Some(acc) = prim.get(&::gltf::Semantic::Normals) {
            check_accessor(self.doc, &acc, "NORMAL", &[Dimensions::Vec3], &[DataType::F32])
                .map_err(accessor)?;
            normals =
                reader.read_normals().ok_or_else(|| err(out_of_range("NORMAL")))?.map(Vec3::from).collect();
        }
        let mut uvs = Vec::new();
        if let Some(acc) = prim.get(&::gltf::Semantic::TexCoords(0)) {
            let types = [DataType::F32, DataType::U8, DataType::U16];
            check_accessor(self.doc, &acc, "TEXCOORD_0", &[Dimensions::Vec2], &types).map_err(accessor)?;
            let read = reader.read_tex_coords(0).ok_or_else(|| err(out_of_range("TEXCOORD_0")))?;
            uvs = read.into_f32().map(Vec2::from).collect();
        }
        let flat: Vec<u32> = match prim.indices() {
            Some(acc) => {
                let types = [DataType::U8, DataType::U16, DataType::U32];
                check_accessor(self.doc, &acc, "indices", &[Dimensions::Scalar], &types).map_err(accessor)?;
                reader.read_indices().ok_or_else(|| err(out_of_range("indices")))?.into_u32().collect()
            }
            None => (0..n as u32).collect(),
        };
        for (attr, len) in [("NORMAL", normals.len()), ("TEXCOORD_0", uvs.len())] {
            if len != 0 && len != n {
                return Err(err(format!("{len} {attr} values for {n} positions")));
            }
        }
        let indices = triangles(mode, &flat);
        if prim.morph_targets().next().is_some() {
            self.w.warn(&self.loc, format!("{what}: morph targets are not supported; using the base shape"));
        }
        let (material, alpha) = self.material(&prim.material());
        let emission = emission(&prim.material()).map_err(|e| SceneError::at(&self.loc, e))?;
        let mesh = TriangleMesh {
            name: what.to_string(),
            positions,
            normals,
            uvs,
            indices,
            material,
            emission,
            flip_normals: false,
            alpha,
            curves: None,
            media: None,
        };
        mesh.validate().map_err(|m| SceneError::caused_by(&loc, format!("{what}: {m}"), m))?;
        Ok(Some(mesh))
    }

    /// The atoll material for a glTF material, added with its texture
    /// bindings on first use, and the alpha mask of its primitives.
    fn material(&mut self, m: &::gltf::Material<'a>) -> (MaterialId, Option<MeshAlpha>) {
        if let Some(&known) = self.materials.get(&m.index()) {
            return known;
        }
        let id = self.out.scene.add_material(convert_material(m));
        let pbr = m.pbr_metallic_roughness();
        let sg = m.pbr_specular_glossiness();
        let (factor, color_info) = match &sg {
            Some(sg) => (Vec4::from(sg.diffuse_factor()), sg.diffuse_texture()),
            None => (Vec4::from(pbr.base_color_factor()), pbr.base_color_texture()),
        };
        // Base colour: the sRGB image times the factor.
        let color = color_info.and_then(|info| self.image_texture(&info, true));
        if let Some((image, mapping, wrap)) = color {
            let tex = self.add_texture(image_node(image, mapping, wrap, Channel::Rgb, 1.0));
            let rgb = factor.truncate();
            let tex = if rgb == Rgb::ONE {
                tex
            } else {
                self.add_texture(Texture::Scale { tex: TexInput::Texture(tex), scale: TexInput::Value(rgb) })
            };
            self.bind(id, TexturedParam::Reflectance, tex);
        }
        // Metalness in blue, roughness in green of one linear image, times the factors.
        let mr = pbr.metallic_roughness_texture().filter(|_| sg.is_none());
        if let Some((image, mapping, wrap)) = mr.and_then(|info| self.image_texture(&info, false)) {
            let metallic =
                self.add_texture(image_node(image, mapping, wrap, Channel::Blue, pbr.metallic_factor()));
            self.bind(id, TexturedParam::Metallic, metallic);
            let roughness =
                self.add_texture(image_node(image, mapping, wrap, Channel::Green, pbr.roughness_factor()));
            self.bind(id, TexturedParam::Roughness, roughness);
        }
        let alpha = self.alpha(m, factor.w, color);
        self.note_ignored(m);
        self.materials.insert(m.index(), (id, alpha));
        (id, alpha)
    }

    /// The texture of `m`'s `emissiveTexture` (sRGB), added on first use.
    fn emission_texture(&mut self, m: &::gltf::Material<'a>) -> Option<u32> {
        if let Some(&known) = self.emission_textures.get(&m.index()) {
            return known;
        }
        let texture = m.emissive_texture().and_then(|info| self.image_texture(&info, true)).map(
            |(image, mapping, wrap)| self.add_texture(image_node(image, mapping, wrap, Channel::Rgb, 1.0)),
        );
        self.emission_textures.insert(m.index(), texture);
        texture
    }

    fn add_texture(&mut self, texture: Texture) -> u32 {
        self.out.scene.textures.add(texture)
    }

    /// Binds `texture` to `param` of `material`; the principled roughness is
    /// perceptual, as glTF's, so nothing is remapped.
    fn bind(&mut self, material: MaterialId, param: TexturedParam, texture: u32) {
        self.out.scene.textures.bind(TextureBinding { material, param, texture, remap_roughness: false });
    }

    /// The image, uv mapping and wrap mode of a texture reference; `None`
    /// (noted) for one atoll cannot use.
    fn image_texture(
        &mut self,
        info: &::gltf::texture::Info<'a>,
        srgb: bool,
    ) -> Option<(ImageId, UvMapping, Wrap)> {
        let transform = info.texture_transform();
        let tex_coord = transform.as_ref().and_then(|t| t.tex_coord()).unwrap_or(info.tex_coord());
        if tex_coord != 0 {
            self.ignored.insert("textures on TEXCOORD_1 and beyond");
            return None;
        }
        let texture = info.texture();
        let image = self.image(&texture.source(), srgb)?;
        let sampler = texture.sampler();
        let (wrap, wrap_t) = (wrap_mode(sampler.wrap_s()), wrap_mode(sampler.wrap_t()));
        if wrap != wrap_t {
            self.ignored.insert("v wrap modes that differ from u's (u's is used)");
        }
        let mapping = match transform {
            Some(t) => {
                if t.rotation() != 0.0 {
                    self.ignored.insert("texture rotations (KHR_texture_transform)");
                }
                uv_mapping(t.offset(), t.scale())
            }
            None => UvMapping::FLIP_V,
        };
        Some((image, mapping, wrap))
    }

    /// glTF image `image` decoded (once per encoding); `None` after a
    /// warning when it cannot be read.
    fn image(&mut self, image: &::gltf::Image<'a>, srgb: bool) -> Option<ImageId> {
        if let Some(&known) = self.images.get(&(image.index(), srgb)) {
            return known;
        }
        let name = match image.source() {
            ::gltf::image::Source::Uri { uri, .. } if !uri.starts_with("data:") => uri.to_string(),
            _ => image.name().map(String::from).unwrap_or_else(|| format!("image {}", image.index())),
        };
        let decoded = match image.source() {
            ::gltf::image::Source::Uri { uri, .. } if !uri.starts_with("data:") => {
                let path = Path::new(uri);
                // Read here, not by the gltf crate: only regular files in the
                // model's folder, and a file too big for memory is an error.
                percent_decode(uri)
                    .ok_or_else(|| {
                        std::io::Error::new(
                            std::io::ErrorKind::InvalidInput,
                            "bad URI (percent escapes that are not UTF-8)",
                        )
                    })
                    .and_then(|decoded| crate::input::read(&crate::input::beside(self.base, &decoded)?))
                    .map_err(ImageLoadError::io(path))
                    .and_then(|bytes| decode_image(&bytes).map_err(ImageLoadError::decode(path)))
            }
            _ => ::gltf::image::Data::from_source(image.source(), Some(self.base), &self.buffers)
                .map_err(|e| ImageLoadError::Gltf(Arc::new(e))),
        }
        .and_then(|data| texture_image(&name, data, srgb));
        let id = match decoded {
            Ok(t) => Some(self.out.scene.textures.add_image(t)),
            Err(e) => {
                self.w.warn(
                    &self.loc,
                    format!(
                        "image {} ('{name}') cannot be read: {e}; its materials use their factors",
                        image.index()
                    ),
                );
                None
            }
        };
        self.images.insert((image.index(), srgb), id);
        id
    }

    /// The alpha mask of `m`'s primitives: the base colour's alpha (texture
    /// × factor) against the cutoff for `MASK`, as a hit probability for
    /// `BLEND`; `None` when opaque.
    fn alpha(
        &mut self,
        m: &::gltf::Material<'a>,
        factor: f32,
        color: Option<(ImageId, UvMapping, Wrap)>,
    ) -> Option<MeshAlpha> {
        let mode = match m.alpha_mode() {
            ::gltf::material::AlphaMode::Opaque => return None,
            ::gltf::material::AlphaMode::Mask => AlphaMode::Cutoff(m.alpha_cutoff().unwrap_or(0.5)),
            ::gltf::material::AlphaMode::Blend => AlphaMode::Stochastic,
        };
        let images = &self.out.scene.textures.images;
        let texture = match color.filter(|&(image, ..)| images[image as usize].has_alpha()) {
            Some((image, mapping, wrap)) => image_node(image, mapping, wrap, Channel::Alpha, factor),
            None => {
                // A constant alpha: the surface is whole or gone.
                let solid = match mode {
                    AlphaMode::Cutoff(cutoff) => factor >= cutoff,
                    AlphaMode::Stochastic => factor >= 1.0,
                };
                if solid {
                    return None;
                }
                Texture::Constant(Rgb::splat(factor.max(0.0)))
            }
        };
        Some(MeshAlpha { texture: self.add_texture(texture), mode })
    }

    /// Notes what of `m` atoll does not read.
    fn note_ignored(&mut self, m: &::gltf::Material<'a>) {
        let ext_texture = |name: &str, keys: &[&str]| {
            m.extension_value(name).is_some_and(|v| keys.iter().any(|k| v.get(*k).is_some()))
        };
        let notes = [
            (m.normal_texture().is_some(), "normal maps"),
            (m.unlit(), "KHR_materials_unlit (shaded as lit)"),
            (m.volume().is_some(), "KHR_materials_volume (transmission is a refracting solid without absorption)"),
            (
                m.pbr_specular_glossiness().is_some_and(|sg| sg.specular_glossiness_texture().is_some())
                    || m.transmission().is_some_and(|t| t.transmission_texture().is_some())
                    || m.specular()
                        .is_some_and(|s| s.specular_texture().is_some() || s.specular_color_texture().is_some())
                    || ext_texture(CLEARCOAT, &["clearcoatTexture", "clearcoatRoughnessTexture"])
                    || ext_texture(SHEEN, &["sheenColorTexture", "sheenRoughnessTexture"]),
                "specular-glossiness, transmission, specular, clearcoat and sheen textures (factors are used)",
            ),
            (ext_texture(CLEARCOAT, &["clearcoatNormalTexture"]), "clearcoat normal maps"),
        ];
        for (used, what) in notes {
            if used {
                self.ignored.insert(what);
            }
        }
    }

    fn finish(mut self) -> Result<LoadedScene, SceneError> {
        let doc = self.doc;
        if !self.ignored.is_empty() {
            let list: Vec<&str> = self.ignored.iter().copied().collect();
            self.w.warn(&self.loc, format!("not supported, ignored: {}", list.join("; ")));
        }
        if doc.skins().next().is_some() || doc.animations().next().is_some() {
            self.w.warn(
                &self.loc,
                "skins and animations are not supported; showing the static node transforms",
            );
        }
        let mut scene = std::mem::take(&mut self.out.scene);
        if scene.instances.is_empty() {
            return Err(SceneError::at(
                &self.loc,
                "no triangles to render (points and lines are not supported)",
            ));
        }
        // Emissive glTF materials are screens and LEDs rather than the scene's
        // lighting: without punctual lights, the default sky and sun are added.
        let punctual_lights = !scene.lights.is_empty();
        match self.camera.take() {
            Some((world, projection)) => {
                let camera_to_world = camera_to_world(world);
                let (camera, resolution) = match projection {
                    GltfProjection::Perspective { yfov, aspect } => {
                        let (fov_degrees, resolution) = camera_fov_and_resolution(yfov, aspect);
                        (Camera { camera_to_world, fov_degrees, ..Default::default() }, resolution)
                    }
                    GltfProjection::Orthographic { xmag, ymag } => {
                        let camera = Camera {
                            camera_to_world,
                            projection: crate::Projection::Orthographic,
                            screen_window: Some([-xmag, xmag, -ymag, ymag]),
                            ..Default::default()
                        };
                        (camera, image_resolution(Some(xmag / ymag)))
                    }
                };
                scene.settings.camera = camera;
                crate::framing::frame_scene(&mut scene, false);
                scene.settings.film.resolution = resolution;
            }
            None => crate::framing::frame_scene(&mut scene, true),
        }
        if !punctual_lights {
            scene.lights = crate::framing::default_lights();
        }
        self.out.scene = scene;
        self.out.warnings = self.w.list;
        Ok(self.out)
    }
}

/// atoll's camera-to-world for a glTF camera node with world transform
/// `node_world`. glTF cameras look down their local -Z with +Y up and +X to
/// the right (right-handed); atoll's camera space has +Z forward, +Y up, +X
/// right. So camera_to_world = node_world × diag(1, 1, -1): it sends our
/// forward (+Z) to glTF's forward (-Z) and keeps right and up. The node's
/// scale is removed (it must not change the field of view).
pub fn camera_to_world(node_world: Mat4) -> Mat4 {
    let axis = |v: Vec4| v.truncate().normalize_or_zero().extend(0.0);
    Mat4::from_cols(
        axis(node_world.x_axis),
        axis(node_world.y_axis),
        -axis(node_world.z_axis),
        node_world.w_axis,
    )
}

/// The field of view (atoll's: spanning the shorter image axis, degrees) and
/// resolution for a glTF perspective camera. The longer side is 1024 pixels
/// with the camera's aspect ratio, or [`crate::framing::RESOLUTION`] without
/// one. glTF's `yfov` is vertical: on a portrait image the shorter axis is
/// the horizontal one, whose angle is `2 atan(tan(yfov / 2) · width / height)`.
pub fn camera_fov_and_resolution(yfov: f32, aspect: Option<f32>) -> (f32, UVec2) {
    let resolution = image_resolution(aspect);
    let (w, h) = (resolution.x as f32, resolution.y as f32);
    let fov = if w >= h { yfov } else { 2.0 * ((yfov * 0.5).tan() * w / h).atan() };
    (fov.to_degrees(), resolution)
}

/// An image 1024 pixels on its longer side with the aspect ratio (width
/// over height) `aspect`, or the default framing's size.
fn image_resolution(aspect: Option<f32>) -> UVec2 {
    match aspect.filter(|a| a.is_finite() && *a > 0.0) {
        Some(a) if a >= 1.0 => UVec2::new(1024, ((1024.0 / a).round() as u32).max(1)),
        Some(a) => UVec2::new(((1024.0 * a).round() as u32).max(1), 1024),
        None => crate::framing::RESOLUTION,
    }
}

/// The raw JSON of these extensions is read (the `gltf` crate does not
/// parse them).
const CLEARCOAT: &str = "KHR_materials_clearcoat";
const SHEEN: &str = "KHR_materials_sheen";

/// The principled material of a glTF material's factors (rules in the module docs).
pub fn convert_material(m: &::gltf::Material) -> Material {
    let ior = m.ior().filter(|e| e.is_finite() && *e > 0.0).unwrap_or(1.5);
    let unit = |x: f32| x.clamp(0.0, 1.0);
    let (base_color, metallic, roughness, specular) = match m.pbr_specular_glossiness() {
        Some(sg) => {
            let specular = luminance(Rgb::from(sg.specular_factor())) / 0.08;
            (Vec4::from(sg.diffuse_factor()).truncate(), 0.0, 1.0 - sg.glossiness_factor(), specular)
        }
        None => {
            let pbr = m.pbr_metallic_roughness();
            let scale = m
                .specular()
                .map_or(1.0, |s| s.specular_factor() * luminance(Rgb::from(s.specular_color_factor())));
            let base = Vec4::from(pbr.base_color_factor()).truncate();
            (base, pbr.metallic_factor(), pbr.roughness_factor(), scale * Material::specular_from_eta(ior))
        }
    };
    let number = |ext: &str, key: &str, default: f32| {
        m.extension_value(ext)
            .and_then(|v| v.get(key))
            .and_then(serde_json::Value::as_f64)
            .map_or(default, |x| x as f32)
    };
    // glTF's coat is GGX of roughness r (alpha r²); Disney's is GTR1 of alpha
    // lerp(gloss, 0.1, 0.001): the gloss whose alpha is r², within that range.
    let coat_roughness = number(CLEARCOAT, "clearcoatRoughnessFactor", 0.0);
    let clearcoat_gloss = unit((0.1 - coat_roughness * coat_roughness) / 0.099);
    let sheen_color = m
        .extension_value(SHEEN)
        .and_then(|v| v.get("sheenColorFactor"))
        .and_then(serde_json::Value::as_array)
        .map_or(0.0, |c| c.iter().filter_map(serde_json::Value::as_f64).fold(0.0, f64::max) as f32);
    Material::Principled(PrincipledParams {
        base_color: base_color.clamp(Rgb::ZERO, Rgb::ONE),
        metallic: unit(metallic),
        roughness: unit(roughness),
        specular: specular.max(0.0),
        specular_tint: 0.0,
        sheen: unit(sheen_color),
        sheen_tint: 0.0,
        clearcoat: unit(number(CLEARCOAT, "clearcoatFactor", 0.0)),
        clearcoat_gloss,
        transmission: unit(m.transmission().map_or(0.0, |t| t.transmission_factor())),
        eta: ior,
    })
}

/// An image texture node with no inversion.
fn image_node(image: ImageId, mapping: UvMapping, wrap: Wrap, channel: Channel, scale: f32) -> Texture {
    Texture::Image {
        image,
        mapping: mapping.into(),
        wrap,
        channel,
        scale,
        invert: false,
        filter: crate::ImageFilter::None,
        levels: 1,
    }
}

fn wrap_mode(m: ::gltf::texture::WrappingMode) -> Wrap {
    match m {
        ::gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
        ::gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
        ::gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
    }
}

/// `KHR_texture_transform`'s `uv · scale + offset` (glTF's uv, `v` down),
/// then atoll's `v` up: `s = sx u + ox`, `t = 1 - (sy v + oy)`. Offset 0
/// and scale 1 give [`UvMapping::FLIP_V`].
fn uv_mapping(offset: [f32; 2], scale: [f32; 2]) -> UvMapping {
    UvMapping { su: scale[0], sv: -scale[1], du: offset[0], dv: 1.0 - offset[1] }
}

/// Grey, grey-alpha, RGB or RGBA values of one texel as RGBA (`one`: opaque).
fn rgba<T: Copy>(v: &[T], one: T) -> [T; 4] {
    match v.len() {
        1 => [v[0], v[0], v[0], one],
        2 => [v[0], v[0], v[0], v[1]],
        3 => [v[0], v[1], v[2], one],
        _ => [v[0], v[1], v[2], v[3]],
    }
}

/// A decoded glTF image as a [`TextureImage`]: 8-bit images stay 8-bit
/// (sRGB when `srgb`); grey ones are spread over RGB (with grey-alpha's
/// alpha); 16-bit ones become linear floats, or 8-bit when sRGB; float ones
/// stay linear floats.
pub fn texture_image(
    name: &str,
    data: ::gltf::image::Data,
    srgb: bool,
) -> Result<TextureImage, ImageLoadError> {
    use ::gltf::image::Format as F;
    let (width, height) = (data.width, data.height);
    let px = &data.pixels;
    let channels = match data.format {
        F::R8 | F::R16 => 1,
        F::R8G8 | F::R16G16 => 2,
        F::R8G8B8 | F::R16G16B16 | F::R32G32B32FLOAT => 3,
        F::R8G8B8A8 | F::R16G16B16A16 | F::R32G32B32A32FLOAT => 4,
    };
    let texels = match data.format {
        F::R8 | F::R8G8 | F::R8G8B8 | F::R8G8B8A8 => {
            Texels::Rgba8 { srgb, data: px.chunks_exact(channels).map(|c| rgba(c, 255)).collect() }
        }
        F::R16 | F::R16G16 | F::R16G16B16 | F::R16G16B16A16 => {
            let words: Vec<f32> =
                px.chunks_exact(2).map(|b| u16::from_ne_bytes([b[0], b[1]]) as f32 / 65535.0).collect();
            let texels = words.chunks_exact(channels).map(|c| rgba(c, 1.0));
            if srgb {
                let byte = |v: f32| (v * 255.0).round() as u8;
                Texels::Rgba8 { srgb, data: texels.map(|t| t.map(byte)).collect() }
            } else {
                Texels::RgbaF32(texels.collect())
            }
        }
        F::R32G32B32FLOAT | F::R32G32B32A32FLOAT => {
            let floats: Vec<f32> =
                px.chunks_exact(4).map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])).collect();
            Texels::RgbaF32(floats.chunks_exact(channels).map(|c| rgba(c, 1.0)).collect())
        }
    };
    let count = match &texels {
        Texels::Rgba8 { data, .. } => data.len(),
        Texels::RgbaF32(data) => data.len(),
    };
    if width == 0 || height == 0 || count != (width * height) as usize {
        return Err(ImageLoadError::TexelCount { width, height, texels: count });
    }
    Ok(TextureImage { name: name.to_string(), width, height, texels })
}

/// `emissiveFactor × emissive_strength` as a one-sided area light.
fn emission(m: &::gltf::Material) -> Result<Option<AreaEmission>, String> {
    let radiance = Rgb::from(m.emissive_factor()) * m.emissive_strength().unwrap_or(1.0);
    AreaEmission::one_sided(radiance).map_err(|e| match m.index() {
        Some(i) => format!("material {i}: {e}"),
        None => format!("the default material: {e}"),
    })
}

/// Triangles from a primitive's indices (strips and fans converted; an
/// incomplete last triangle dropped).
fn triangles(mode: Mode, idx: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::TriangleStrip => {
            (0..idx.len().saturating_sub(2))
                .map(|i| {
                    if i % 2 == 0 {
                        [idx[i], idx[i + 1], idx[i + 2]]
                    } else {
                        [idx[i + 1], idx[i], idx[i + 2]]
                    }
                })
                .collect()
        }
        Mode::TriangleFan => (1..idx.len().saturating_sub(1)).map(|i| [idx[0], idx[i], idx[i + 1]]).collect(),
        _ => idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
    }
}

fn out_of_range(attr: &str) -> String {
    format!("the {attr} accessor has no data or reaches past its buffer")
}

/// An accessor that [`check_accessor`] refuses: `attr` is the attribute
/// it feeds (`POSITION`, `indices`, ...), `index` the accessor's index.
#[derive(Debug, thiserror::Error)]
enum AccessorError {
    #[error("{attr} accessor {index}: unexpected type {dims:?} of {ty:?}")]
    Type { attr: &'static str, index: usize, dims: Dimensions, ty: DataType },
    #[error("{attr} accessor {index}: count is 0")]
    Empty { attr: &'static str, index: usize },
    #[error("{attr} accessor {index}: byte stride {stride} is smaller than an element ({size} bytes)")]
    Stride { attr: &'static str, index: usize, stride: usize, size: usize },
    #[error("{attr} accessor {index}: sparse storage with no entries or non-integer indices")]
    Sparse { attr: &'static str, index: usize },
    #[error("{attr} accessor {index}: its {count} elements do not lie within its buffer view and buffer")]
    Bounds { attr: &'static str, index: usize, count: usize },
}

/// Checks what the gltf crate's reader assumes without checking (it panics
/// otherwise): the element type, a non-zero count, a stride no smaller than
/// an element, and integer sparse indices.
fn check_accessor(
    doc: &::gltf::Document,
    acc: &::gltf::Accessor,
    attr: &'static str,
    dims: &[Dimensions],
    types: &[DataType],
) -> Result<(), AccessorError> {
    let index = acc.index();
    if !dims.contains(&acc.dimensions()) || !types.contains(&acc.data_type()) {
        return Err(AccessorError::Type { attr, index, dims: acc.dimensions(), ty: acc.data_type() });
    }
    if acc.count() == 0 {
        return Err(AccessorError::Empty { attr, index });
    }
    if let Some(view) = acc.view() {
        let stride = view.stride().unwrap_or(acc.size());
        if stride < acc.size() {
            return Err(AccessorError::Stride { attr, index, stride, size: acc.size() });
        }
        // The reader adds and multiplies these unchecked: offsets near 2^64
        // or counts of 2^62 overflow there; checked here.
        let last = (acc.count() - 1).checked_mul(stride).and_then(|b| b.checked_add(acc.offset()));
        let in_view = last.and_then(|b| b.checked_add(acc.size())).is_some_and(|end| end <= view.length());
        let in_buffer =
            view.offset().checked_add(view.length()).is_some_and(|end| end <= view.buffer().length());
        if !(in_view && in_buffer) {
            return Err(AccessorError::Bounds { attr, index, count: acc.count() });
        }
    }
    if let Some(sparse) = doc.as_json().accessors.get(acc.index()).and_then(|a| a.sparse.as_ref()) {
        use ::gltf::json::accessor::ComponentType as C;
        let int_indices = matches!(sparse.indices.component_type, Checked::Valid(t) if matches!(t.0, C::U8 | C::U16 | C::U32));
        if sparse.count.0 == 0 || !int_indices {
            return Err(AccessorError::Sparse { attr, index });
        }
    }
    Ok(())
}

/// Reads every buffer: the GLB's binary chunk, data URIs, external files.
/// Refuses a GLB whose header gives a total length shorter than the header
/// itself (the gltf crate subtracts without checking).
fn check_glb_length(bytes: &[u8]) -> Result<(), String> {
    let Some(length) = bytes.strip_prefix(b"glTF").and_then(|h| h.get(4..8)) else { return Ok(()) };
    let length = u32::from_le_bytes(length.try_into().expect("four bytes"));
    if length < 12 {
        return Err(format!("bad GLB header: a total length of {length} bytes is shorter than the header"));
    }
    Ok(())
}

/// What the gltf crate's validation and accessors index or unwrap without
/// checking, checked on the parsed JSON before validation: every POSITION
/// accessor exists, and every image has a `uri` or a `bufferView` with a
/// `mimeType` (as the glTF spec requires).
fn check_unvalidated(json: &::gltf::json::Root) -> Result<(), String> {
    let n = json.accessors.len();
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let position = prim.attributes.get(&Checked::Valid(::gltf::json::mesh::Semantic::Positions));
            if let Some(i) = position.map(|i| i.value()).filter(|&i| i >= n) {
                return Err(format!(
                    "invalid glTF: meshes[{m}].primitives[{p}]: POSITION accessor {i} does not exist ({n} accessors)"
                ));
            }
        }
    }
    for (i, image) in json.images.iter().enumerate() {
        let why = match (&image.uri, &image.buffer_view, &image.mime_type) {
            (None, None, _) => "has neither a uri nor a bufferView",
            (_, Some(_), None) => "has a bufferView but no mimeType",
            _ => continue,
        };
        return Err(format!("invalid glTF: images[{i}] {why}"));
    }
    Ok(())
}

fn read_buffers(
    doc: &::gltf::Document,
    mut blob: Option<Vec<u8>>,
    base: &Path,
    loc: &FileLoc,
) -> Result<Vec<::gltf::buffer::Data>, SceneError> {
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let what = match buffer.source() {
            ::gltf::buffer::Source::Bin => "the GLB binary chunk".to_string(),
            ::gltf::buffer::Source::Uri(uri) if uri.starts_with("data:") => {
                format!("buffer {} (data URI)", buffer.index())
            }
            ::gltf::buffer::Source::Uri(uri) => {
                // Read here, not by the gltf crate (which unwraps its
                // percent-decoding and reads any file whole): only a
                // regular file in the model's folder, and a file too big
                // for memory is an error.
                let Some(decoded) = percent_decode(uri) else {
                    return Err(SceneError::at(loc, format!("buffer {}: bad URI '{uri}'", buffer.index())));
                };
                let mut bytes = crate::input::beside(base, &decoded)
                    .and_then(|path| crate::input::read(&path))
                    .map_err(|e| SceneError::caused_by(loc, format!("cannot read buffer '{uri}': {e}"), e))?;
                // As the gltf crate does: buffers padded to 4 bytes.
                bytes.resize(bytes.len().next_multiple_of(4), 0);
                out.push(check_length(
                    ::gltf::buffer::Data(bytes),
                    &buffer,
                    &format!("buffer '{uri}'"),
                    loc,
                )?);
                continue;
            }
        };
        let data = ::gltf::buffer::Data::from_source_and_blob(buffer.source(), Some(base), &mut blob)
            .map_err(|e| SceneError::at(loc, format!("cannot read {what}: {e}")))?;
        out.push(check_length(data, &buffer, &what, loc)?);
    }
    Ok(out)
}

/// `data` if it holds the `byteLength` its buffer claims.
fn check_length(
    data: ::gltf::buffer::Data,
    buffer: &::gltf::Buffer,
    what: &str,
    loc: &FileLoc,
) -> Result<::gltf::buffer::Data, SceneError> {
    if data.len() < buffer.length() {
        return Err(SceneError::at(
            loc,
            format!("{what} has {} bytes but the file says {} (truncated?)", data.len(), buffer.length()),
        ));
    }
    Ok(data)
}

/// An encoded image (PNG, JPEG, ...: its bytes say which) as glTF's
/// decoded image, decoded under the image crate's default memory limits.
fn decode_image(bytes: &[u8]) -> Result<::gltf::image::Data, image::ImageError> {
    use ::gltf::image::Format as F;
    use image::DynamicImage as D;
    let image = image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format()?.decode()?;
    let (width, height) = (image.width(), image.height());
    let words = |w: &[u16]| w.iter().flat_map(|v| v.to_ne_bytes()).collect();
    let floats = |f: &[f32]| f.iter().flat_map(|v| v.to_ne_bytes()).collect();
    let (format, pixels) = match image {
        D::ImageLuma8(i) => (F::R8, i.into_raw()),
        D::ImageLumaA8(i) => (F::R8G8, i.into_raw()),
        D::ImageRgb8(i) => (F::R8G8B8, i.into_raw()),
        D::ImageLuma16(i) => (F::R16, words(&i)),
        D::ImageLumaA16(i) => (F::R16G16, words(&i)),
        D::ImageRgb16(i) => (F::R16G16B16, words(&i)),
        D::ImageRgba16(i) => (F::R16G16B16A16, words(&i)),
        D::ImageRgb32F(i) => (F::R32G32B32FLOAT, floats(&i)),
        D::ImageRgba32F(i) => (F::R32G32B32A32FLOAT, floats(&i)),
        other => (F::R8G8B8A8, other.into_rgba8().into_raw()),
    };
    Ok(::gltf::image::Data { pixels, format, width, height })
}

/// Decodes `%XX` escapes of a relative URI; `None` when they are malformed or not UTF-8.
fn percent_decode(uri: &str) -> Option<String> {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// A `SceneError` for a file the gltf crate could not parse or validate.
fn parse_error(e: ::gltf::Error, bytes: &[u8], name: &str) -> SceneError {
    let whole = FileLoc::whole_file(name);
    if let Some(v) = gltf1_version(bytes) {
        return SceneError::at(
            &whole,
            format!("glTF {v} is not supported, only glTF 2.0 (convert the file, e.g. with gltf-pipeline or Blender)"),
        );
    }
    match e {
        // JSON syntax errors know their line (of the JSON text, which is the file for .gltf).
        ::gltf::Error::Deserialize(j) if !bytes.starts_with(b"glTF") && j.line() > 0 => SceneError::at(
            &FileLoc::new(name, j.line() as u32, j.column() as u32),
            format!("bad glTF JSON: {j}"),
        ),
        ::gltf::Error::Validation(list) => {
            let shown: Vec<String> = list.iter().take(3).map(|(p, e)| format!("{p}: {e}")).collect();
            let more = if list.len() > 3 { format!(" (and {} more)", list.len() - 3) } else { String::new() };
            let required = list.iter().find(|(p, _)| p.as_str().starts_with("extensionsRequired"));
            match required {
                Some((p, _)) => {
                    SceneError::at(&whole, format!("the file requires an extension atoll cannot read: {p}"))
                }
                None => SceneError::at(&whole, format!("invalid glTF: {}{more}", shown.join("; "))),
            }
        }
        other => SceneError::at(&whole, format!("cannot read glTF: {other}")),
    }
}

/// `Some(version)` when the bytes are a glTF 1.x file (JSON or binary).
fn gltf1_version(bytes: &[u8]) -> Option<String> {
    if let Some(header) = bytes.strip_prefix(b"glTF") {
        let v = u32::from_le_bytes(header.get(..4)?.try_into().ok()?);
        return (v == 1).then(|| "1.0 (binary)".into());
    }
    let json: serde_json::Value = serde_json::from_slice(bytes).ok()?;
    let v = &json["asset"]["version"];
    let v = v.as_str().map(String::from).or_else(|| v.as_f64().map(|f| f.to_string()))?;
    v.starts_with('1').then_some(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_looks_down_negative_z() {
        let world = Mat4::from_translation(Vec3::new(0.5, 0.5, 3.0)) * Mat4::from_scale(Vec3::splat(2.0));
        let m = camera_to_world(world);
        assert!((m.transform_vector3(Vec3::Z) + Vec3::Z).length() < 1e-6);
        assert!((m.transform_vector3(Vec3::X) - Vec3::X).length() < 1e-6);
        assert!((m.transform_point3(Vec3::ZERO) - Vec3::new(0.5, 0.5, 3.0)).length() < 1e-6);
    }

    #[test]
    fn fov_spans_the_shorter_axis() {
        let (fov, res) = camera_fov_and_resolution(0.5, Some(2.0));
        assert_eq!(res, UVec2::new(1024, 512));
        assert!((fov - 0.5f32.to_degrees()).abs() < 1e-4);
        let (fov, res) = camera_fov_and_resolution(0.5, Some(0.5));
        assert_eq!(res, UVec2::new(512, 1024));
        let expected = 2.0 * (0.25f32.tan() * 0.5).atan();
        assert!((fov - expected.to_degrees()).abs() < 1e-4);
        assert_eq!(camera_fov_and_resolution(0.5, None).1, crate::framing::RESOLUTION);
    }

    #[test]
    fn texture_transform_joins_the_v_flip() {
        assert_eq!(uv_mapping([0.0, 0.0], [1.0, 1.0]), UvMapping::FLIP_V);
        // glTF uv (0.25, 0.5) → (0.25 · 2 + 0.5, 0.5 · 4 + 0.25) = (1, 2.25) → atoll t = 1 - 2.25.
        let m = uv_mapping([0.5, 0.25], [2.0, 4.0]);
        assert_eq!((m.su * 0.25 + m.du, m.sv * 0.5 + m.dv), (1.0, -1.25));
    }

    #[test]
    fn decoded_images_become_rgba_texels() {
        use ::gltf::image::{Data, Format};
        let image = |format, pixels: Vec<u8>| Data { pixels, format, width: 2, height: 1 };
        // Grey, grey-alpha, RGB: spread to RGBA, 8-bit stays 8-bit.
        let t = texture_image("g", image(Format::R8, vec![10, 20]), true).unwrap();
        assert_eq!(t.texels, Texels::Rgba8 { srgb: true, data: vec![[10, 10, 10, 255], [20, 20, 20, 255]] });
        let t = texture_image("ga", image(Format::R8G8, vec![10, 1, 20, 2]), false).unwrap();
        assert_eq!(t.texels, Texels::Rgba8 { srgb: false, data: vec![[10, 10, 10, 1], [20, 20, 20, 2]] });
        let t = texture_image("rgb", image(Format::R8G8B8, vec![1, 2, 3, 4, 5, 6]), true).unwrap();
        assert_eq!(t.texels, Texels::Rgba8 { srgb: true, data: vec![[1, 2, 3, 255], [4, 5, 6, 255]] });
        // 16-bit: linear floats, or 8-bit when sRGB.
        let words: Vec<u8> = [0u16, 65535].iter().flat_map(|w| w.to_ne_bytes()).collect();
        let t = texture_image("r16", image(Format::R16, words.clone()), false).unwrap();
        assert_eq!(t.texels, Texels::RgbaF32(vec![[0.0, 0.0, 0.0, 1.0], [1.0, 1.0, 1.0, 1.0]]));
        let t = texture_image("r16", image(Format::R16, words), true).unwrap();
        assert_eq!(t.texels, Texels::Rgba8 { srgb: true, data: vec![[0, 0, 0, 255], [255, 255, 255, 255]] });
        // Too few pixels for the size is an error, not a short image.
        assert!(texture_image("short", image(Format::R8, vec![1]), true).is_err());
    }

    #[test]
    fn strips_and_fans() {
        assert_eq!(triangles(Mode::TriangleStrip, &[0, 1, 2, 3]), vec![[0, 1, 2], [2, 1, 3]]);
        assert_eq!(triangles(Mode::TriangleFan, &[0, 1, 2, 3]), vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(triangles(Mode::Triangles, &[0, 1, 2, 3]), vec![[0, 1, 2]]);
        assert_eq!(percent_decode("a%20b.bin").as_deref(), Some("a b.bin"));
        assert_eq!(percent_decode("a%FF.bin"), None);
    }
}
