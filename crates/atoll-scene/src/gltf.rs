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
//! - **Materials** (metallic-roughness) are approximated until atoll has a
//!   principled material (one warning a file): `KHR_materials_transmission`
//!   ≥ 0.5 → `Dielectric` (eta = `KHR_materials_ior`, default 1.5);
//!   metallic ≥ 0.5 → `Conductor` with eta 1 and the `k` whose normal
//!   reflectance is the base colour; otherwise `Diffuse` with the base
//!   colour. Alpha is roughness² (glTF's GGX convention). Specular-glossiness
//!   materials use their diffuse factor. Primitives without a material get
//!   glTF's default material (white, metallic 1, roughness 1), as viewers do.
//! - **Emission**: `emissiveFactor × KHR_materials_emissive_strength`, when
//!   non-zero, is a one-sided area light on the primitive's mesh.
//! - **Camera**: the first perspective camera met walking the scene's nodes
//!   (see [`camera_to_world`] and [`camera_fov_and_resolution`]); without one,
//!   [`crate::framing`] frames the model.
//! - **Lights** (`KHR_lights_punctual`): point → `Light::Point` (candela =
//!   W/sr here, used as is), directional → `Light::Distant` (lux used as its
//!   radiance), spot → `Light::Spot` (cone angles as pbrt's coneangle/conedelta).
//!   Without punctual lights the default sky and sun of [`crate::framing`]
//!   are added, even when some materials are emissive (in glTF content those
//!   are screens and LEDs, not what lights the scene).
//! - **Textures** are recorded in [`LoadedScene::textures`], not rendered yet.

use std::collections::HashMap;
use std::path::Path;

use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::json::validation::Checked;
use ::gltf::khr_lights_punctual::Kind as LightKind;
use ::gltf::mesh::Mode;
use glam::{Affine3A, Mat4, UVec2, Vec2, Vec3, Vec4};

use crate::error::{FileLoc, SceneError};
use crate::load::TextureRef;
use crate::pbrt::WarningSink;
use crate::{
    AreaEmission, Camera, Instance, Light, LoadedScene, Material, MaterialId, Object, ObjectId, Rgb,
    TriangleMesh,
};

/// Loads a `.gltf` or `.glb` file; external buffers resolve against its directory.
pub fn load_gltf(path: &Path) -> Result<LoadedScene, SceneError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path)
        .map_err(|e| SceneError::at(&FileLoc::whole_file(name.as_str()), format!("cannot read: {e}")))?;
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    load_gltf_bytes(&bytes, &name, &base)
}

/// Loads glTF from memory (`name` for messages; external files resolve against `base`).
pub fn load_gltf_bytes(bytes: &[u8], name: &str, base: &Path) -> Result<LoadedScene, SceneError> {
    let whole = FileLoc::whole_file(name);
    // We check every accessor before the gltf crate reads it (it panics on
    // some malformed files); this catch is the last line of defence so that
    // a bad file is an error, never a crash.
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| convert(bytes, name, base))) {
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
    /// glTF material index (`None`: the default material) → atoll material.
    materials: HashMap<Option<usize>, MaterialId>,
    /// glTF mesh index → atoll object (`None`: the mesh has no triangles).
    objects: HashMap<usize, Option<ObjectId>>,
    /// The first perspective camera: node world transform, yfov, aspect ratio.
    camera: Option<(Mat4, f32, Option<f32>)>,
}

/// Parses, reads the buffers, converts.
fn convert(bytes: &[u8], name: &str, base: &Path) -> Result<LoadedScene, SceneError> {
    let loc = FileLoc::whole_file(name);
    let gltf = ::gltf::Gltf::from_slice(bytes).map_err(|e| parse_error(e, bytes, name))?;
    let buffers = read_buffers(&gltf.document, gltf.blob.clone(), base, &loc)?;
    let mut loader = Loader {
        doc: &gltf.document,
        buffers,
        base,
        loc,
        out: LoadedScene::default(),
        w: WarningSink::default(),
        materials: HashMap::new(),
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
                self.out
                    .scene
                    .instances
                    .push(Instance { object, object_to_world: Affine3A::from_mat4(world) });
            }
        }
        if let Some(cam) = node.camera() {
            match cam.projection() {
                ::gltf::camera::Projection::Perspective(p) if self.camera.is_none() => {
                    self.camera = Some((world, p.yfov(), p.aspect_ratio()))
                }
                ::gltf::camera::Projection::Perspective(_) => {}
                ::gltf::camera::Projection::Orthographic(_) => self.w.warn(
                    &self.loc,
                    format!("orthographic camera {} is not supported; skipped", cam.index()),
                ),
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
                meshes.push(self.out.scene.add_mesh(m));
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
        let buffers = &self.buffers;
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| d.0.as_slice()));
        let Some(pos) = prim.get(&::gltf::Semantic::Positions) else {
            return Err(err("no POSITION attribute".into()));
        };
        check_accessor(self.doc, &pos, "POSITION", &[Dimensions::Vec3], &[DataType::F32]).map_err(err)?;
        let positions: Vec<Vec3> =
            reader.read_positions().ok_or_else(|| err(out_of_range("POSITION")))?.map(Vec3::from).collect();
        let n = positions.len();
        let mut normals = Vec::new();
        if let Some(acc) = prim.get(&::gltf::Semantic::Normals) {
            check_accessor(self.doc, &acc, "NORMAL", &[Dimensions::Vec3], &[DataType::F32]).map_err(err)?;
            normals =
                reader.read_normals().ok_or_else(|| err(out_of_range("NORMAL")))?.map(Vec3::from).collect();
        }
        let mut uvs = Vec::new();
        if let Some(acc) = prim.get(&::gltf::Semantic::TexCoords(0)) {
            let types = [DataType::F32, DataType::U8, DataType::U16];
            check_accessor(self.doc, &acc, "TEXCOORD_0", &[Dimensions::Vec2], &types).map_err(err)?;
            let read = reader.read_tex_coords(0).ok_or_else(|| err(out_of_range("TEXCOORD_0")))?;
            uvs = read.into_f32().map(Vec2::from).collect();
        }
        let flat: Vec<u32> = match prim.indices() {
            Some(acc) => {
                let types = [DataType::U8, DataType::U16, DataType::U32];
                check_accessor(self.doc, &acc, "indices", &[Dimensions::Scalar], &types).map_err(err)?;
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
        let material = self.material(&prim.material());
        let emission = emission(&prim.material());
        let mesh = TriangleMesh {
            name: what.to_string(),
            positions,
            normals,
            uvs,
            indices,
            material,
            emission,
            flip_normals: false,
        };
        mesh.validate().map_err(err)?;
        Ok(Some(mesh))
    }

    /// The atoll material for a glTF material, added on first use.
    fn material(&mut self, m: &::gltf::Material<'a>) -> MaterialId {
        if let Some(&id) = self.materials.get(&m.index()) {
            return id;
        }
        let id = self.out.scene.add_material(convert_material(m));
        self.materials.insert(m.index(), id);
        let pbr = m.pbr_metallic_roughness();
        let textures = [
            (pbr.base_color_texture().map(|t| t.texture()), "reflectance"),
            (m.emissive_texture().map(|t| t.texture()), "emission"),
            (m.normal_texture().map(|t| t.texture()), "normalmap"),
            (pbr.metallic_roughness_texture().map(|t| t.texture()), "roughness"),
        ];
        for (tex, parameter) in textures {
            if let Some(tex) = tex {
                self.record_texture(&tex.source(), id, parameter);
            }
        }
        id
    }

    fn record_texture(&mut self, image: &::gltf::Image<'a>, id: MaterialId, parameter: &str) {
        let (name, filename) = match image.source() {
            ::gltf::image::Source::Uri { uri, .. } if !uri.starts_with("data:") => {
                let file = percent_decode(uri).map(|f| self.base.join(f));
                (image.name().unwrap_or(uri).to_string(), file)
            }
            _ => (image.name().map(String::from).unwrap_or_else(|| format!("image {}", image.index())), None),
        };
        let use_ = (id, parameter.to_string());
        match self.out.textures.iter_mut().find(|t| t.name == name && t.filename == filename) {
            Some(t) => t.uses.push(use_),
            None => {
                self.out.textures.push(TextureRef { name, class: "image".into(), filename, uses: vec![use_] })
            }
        }
    }

    fn finish(mut self) -> Result<LoadedScene, SceneError> {
        let doc = self.doc;
        if doc.materials().next().is_some() {
            self.w.warn(
                &self.loc,
                "glTF materials are approximated (diffuse, conductor or dielectric) until atoll has a principled material",
            );
        }
        if !self.out.textures.is_empty() {
            let n = self.out.textures.len();
            self.w.warn(
                &self.loc,
                format!("{n} textures recorded but not rendered yet; materials use their factors"),
            );
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
            Some((world, yfov, aspect)) => {
                let (fov_degrees, resolution) = camera_fov_and_resolution(yfov, aspect);
                scene.settings.camera =
                    Camera { camera_to_world: camera_to_world(world), fov_degrees, ..Default::default() };
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
    let resolution = match aspect.filter(|a| a.is_finite() && *a > 0.0) {
        Some(a) if a >= 1.0 => UVec2::new(1024, ((1024.0 / a).round() as u32).max(1)),
        Some(a) => UVec2::new(((1024.0 * a).round() as u32).max(1), 1024),
        None => crate::framing::RESOLUTION,
    };
    let (w, h) = (resolution.x as f32, resolution.y as f32);
    let fov = if w >= h { yfov } else { 2.0 * ((yfov * 0.5).tan() * w / h).atan() };
    (fov.to_degrees(), resolution)
}

/// The approximated material (rules in the module docs).
fn convert_material(m: &::gltf::Material) -> Material {
    if let Some(sg) = m.pbr_specular_glossiness() {
        return Material::Diffuse { reflectance: Vec4::from(sg.diffuse_factor()).truncate() };
    }
    let pbr = m.pbr_metallic_roughness();
    let base = Vec4::from(pbr.base_color_factor()).truncate();
    let roughness = pbr.roughness_factor().clamp(0.0, 1.0);
    let alpha = roughness * roughness;
    if m.transmission().is_some_and(|t| t.transmission_factor() >= 0.5) {
        let eta = m.ior().filter(|&e| e > 0.0).unwrap_or(1.5);
        return Material::Dielectric { eta, alpha_x: alpha, alpha_y: alpha };
    }
    if pbr.metallic_factor() >= 0.5 {
        let k = Material::conductor_k_from_reflectance(base);
        return Material::Conductor { eta: Rgb::ONE, k, alpha_x: alpha, alpha_y: alpha };
    }
    Material::Diffuse { reflectance: base }
}

/// `emissiveFactor × emissive_strength` as a one-sided area light.
fn emission(m: &::gltf::Material) -> Option<AreaEmission> {
    let radiance = Rgb::from(m.emissive_factor()) * m.emissive_strength().unwrap_or(1.0);
    (radiance.max_element() > 0.0).then_some(AreaEmission { radiance, two_sided: false })
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

/// Checks what the gltf crate's reader assumes without checking (it panics
/// otherwise): the element type, a non-zero count, a stride no smaller than
/// an element, and integer sparse indices.
fn check_accessor(
    doc: &::gltf::Document,
    acc: &::gltf::Accessor,
    what: &str,
    dims: &[Dimensions],
    types: &[DataType],
) -> Result<(), String> {
    let bad = |m: String| Err(format!("{what} accessor {}: {m}", acc.index()));
    if !dims.contains(&acc.dimensions()) || !types.contains(&acc.data_type()) {
        return bad(format!("unexpected type {:?} of {:?}", acc.dimensions(), acc.data_type()));
    }
    if acc.count() == 0 {
        return bad("count is 0".into());
    }
    if let Some(stride) = acc.view().and_then(|v| v.stride()) {
        if stride < acc.size() {
            return bad(format!("byte stride {stride} is smaller than an element ({} bytes)", acc.size()));
        }
    }
    if let Some(sparse) = doc.as_json().accessors.get(acc.index()).and_then(|a| a.sparse.as_ref()) {
        use ::gltf::json::accessor::ComponentType as C;
        let int_indices = matches!(sparse.indices.component_type, Checked::Valid(t) if matches!(t.0, C::U8 | C::U16 | C::U32));
        if sparse.count.0 == 0 || !int_indices {
            return bad("sparse storage with no entries or non-integer indices".into());
        }
    }
    Ok(())
}

/// Reads every buffer: the GLB's binary chunk, data URIs, external files.
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
                // The gltf crate unwraps its percent-decoding: refuse what it cannot decode.
                if percent_decode(uri).is_none() {
                    return Err(SceneError::at(loc, format!("buffer {}: bad URI '{uri}'", buffer.index())));
                }
                format!("buffer '{uri}'")
            }
        };
        let data = ::gltf::buffer::Data::from_source_and_blob(buffer.source(), Some(base), &mut blob)
            .map_err(|e| SceneError::at(loc, format!("cannot read {what}: {e}")))?;
        if data.len() < buffer.length() {
            return Err(SceneError::at(
                loc,
                format!("{what} has {} bytes but the file says {} (truncated?)", data.len(), buffer.length()),
            ));
        }
        out.push(data);
    }
    Ok(out)
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
    fn strips_and_fans() {
        assert_eq!(triangles(Mode::TriangleStrip, &[0, 1, 2, 3]), vec![[0, 1, 2], [2, 1, 3]]);
        assert_eq!(triangles(Mode::TriangleFan, &[0, 1, 2, 3]), vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(triangles(Mode::Triangles, &[0, 1, 2, 3]), vec![[0, 1, 2]]);
        assert_eq!(percent_decode("a%20b.bin").as_deref(), Some("a b.bin"));
        assert_eq!(percent_decode("a%FF.bin"), None);
    }
}
