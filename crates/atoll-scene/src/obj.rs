//! Wavefront OBJ + MTL scenes, read with `tobj` (polygons triangulated as
//! fans, one index per vertex).
//!
//! Every OBJ model (an `o`/`g` group, split further where `usemtl` changes)
//! becomes one mesh, in world space, in the world object with its one
//! identity instance. Camera, settings and lights come from
//! [`crate::framing`] since OBJ has none.
//!
//! MTL materials map to atoll's as follows ([`mtl_material`]):
//! - `illum` 4, 6, 7 or 9 (the refracting models): `Dielectric` with
//!   `eta = Ni` (1.5 when `Ni` ≤ 1).
//! - Specular-dominated (`max(Ks) ≥ 0.5`, `Ns ≥ 200` and `max(Ks) > max(Kd)`):
//!   `Conductor` with `eta = 1` and `k` giving reflectance `Ks`, GGX alpha
//!   `sqrt(2 / (Ns + 2))` (the Phong exponent's Beckmann equivalent). A
//!   strong `Ks` with a low `Ns` is a broad highlight that Lambert shows
//!   better than a rough metal, so those stay diffuse.
//! - Otherwise `Diffuse` with `Kd` (0.5 grey when absent).
//! - `Ke` (emission) becomes a one-sided `AreaEmission` on the meshes.
//!
//! Textures ([`mtl_textures`]; images decoded once per file):
//! - `map_Kd` (sRGB) times `Kd`, as the MTL spec says, bound to a diffuse
//!   material's reflectance (warned about and ignored on the others).
//! - `map_d` cuts the meshes: solid where the map is at least 0.5
//!   (`AlphaMode::Cutoff`), reading the image's alpha when it has a
//!   non-opaque one, else the mean of its colour (linear), or the channel
//!   `-imfchan` names. Without `map_d`, a `map_Kd` with a non-opaque alpha
//!   channel cuts the same way (what viewers and Blender do with such
//!   images). Otherwise `d` (or `1 - Tr`) below 1 makes a stochastic alpha
//!   of that constant, pbrt's shape `alpha`; `d 0` is taken for an
//!   exporter's mistake and ignored.
//! - Map options `-s` and `-o` become the uv mapping (`uv * s + o`, as
//!   three.js and Blender read them), `-clamp on` clamps; others are ignored.
//! - `vt` v = 0 is the bottom of the image, as in pbrt: no flip.
//! - Bump and normal maps are warned about and ignored.
//!
//! A mesh without `vt` reads its textures at pbrt's default per-triangle uvs.

use std::cell::RefCell;
use std::collections::HashMap;
use std::io::{BufRead, Read};
use std::path::Path;

use glam::{Vec2, Vec3};

use crate::error::{FileLoc, SceneError};
use crate::load::add_world_object;
use crate::pbrt::WarningSink;
use crate::{
    AlphaMode, AreaEmission, Channel, ColorEncoding, ImageCache, LoadedScene, Material, MaterialId,
    MeshAlpha, Rgb, TexInput, Texture, TextureBinding, TexturedParam, TriangleMesh, UvMapping, Wrap,
};

/// Loads an OBJ file and the MTL files it names (relative to its directory).
pub fn load_obj(path: &Path) -> Result<LoadedScene, SceneError> {
    crate::input::scene_load(|| {
        let name = path.display().to_string();
        let whole = FileLoc::whole_file(name.as_str());
        let bytes = crate::input::read(path)
            .map_err(|e| SceneError::caused_by(&whole, format!("cannot read: {e}"), e))?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        load_obj_bytes(&bytes, &name, &dir)
    })
}

/// Loads OBJ text (`name` for messages; MTL files resolve against `dir`).
pub fn load_obj_bytes(bytes: &[u8], name: &str, dir: &Path) -> Result<LoadedScene, SceneError> {
    crate::input::scene_load(|| obj_scene(bytes, name, dir))
}

fn obj_scene(bytes: &[u8], name: &str, dir: &Path) -> Result<LoadedScene, SceneError> {
    let whole = FileLoc::whole_file(name);
    let mut w = WarningSink::default();
    let (text, lossy) = decode_text(bytes);
    if lossy {
        w.warn(
            &whole,
            "the file is not valid UTF-8 (an 8-bit encoding?); the bytes that are not were replaced",
        );
    }
    // MTL files are decoded the same way, so material names written with the
    // same 8-bit encoding still match.
    let libs: RefCell<Vec<(String, Option<String>)>> = RefCell::new(Vec::new());
    // Where each material is defined (its `newmtl` line), for its warnings.
    let material_lines: RefCell<HashMap<String, FileLoc>> = RefCell::new(HashMap::new());
    let loader = |mtl: &Path| {
        let (read, shown) = match crate::input::beside(dir, &mtl.to_string_lossy()) {
            Ok(path) => (crate::input::read(&path), path.display().to_string()),
            Err(e) => (Err(e), mtl.display().to_string()),
        };
        let (result, why) = match read {
            Ok(b) => {
                let text = decode_text(&b).0;
                let shown: std::sync::Arc<str> = shown.into();
                for (i, line) in text.lines().enumerate() {
                    if let Some(("newmtl", name)) = line.trim().split_once(char::is_whitespace) {
                        let at = FileLoc::new(shown.clone(), i as u32 + 1, 1);
                        material_lines.borrow_mut().entry(name.trim().to_string()).or_insert(at);
                    }
                }
                let result = mtl_for_tobj(&text).and_then(|t| tobj::load_mtl_buf(&mut t.as_bytes()));
                let why = result.as_ref().err().map(|e| e.to_string());
                (result, why)
            }
            // Why it could not be read (refused, missing, too big) is said below.
            Err(e) => (Err(tobj::LoadError::OpenFileFailed), Some(format!("cannot be read: {e}"))),
        };
        libs.borrow_mut().push((mtl.display().to_string(), why));
        result
    };
    let options =
        tobj::LoadOptions { single_index: true, triangulate: true, ignore_points: true, ignore_lines: true };
    // tobj's index arithmetic overflows on far out-of-range `vt` and `vn`
    // indices (a panic, or wrapped into the wrong vertex): refused first.
    if let Some((line, msg)) = find_bad_index(text.as_bytes()) {
        return Err(SceneError::at(&FileLoc::new(name, line, 1), msg));
    }
    let mut reader = LineCounter { data: text.as_bytes(), pos: 0, newlines: 0 };
    let (models, materials) = match tobj::load_obj_buf(&mut reader, &options, loader) {
        Ok(r) => r,
        Err(e) => return Err(obj_error(e, text.as_bytes(), reader.current_line(), name)),
    };
    for (lib, why) in libs.into_inner() {
        if let Some(why) = why {
            w.warn(&whole, format!("material library '{lib}' {why}; its materials use the default diffuse"));
        }
    }
    if let Some((n, first)) = short_faces(&text) {
        let at = FileLoc::new(name, first, 1);
        w.warn(
            &at,
            format!("{n} faces with fewer than 3 vertices skipped (the first is here; a truncated file?)"),
        );
    }
    // tobj reports a missing library again as the materials' error; it was warned about above.
    let materials = materials.unwrap_or_default();

    let mut loaded = LoadedScene::default();
    let mut images = ImageCache::default();
    let mut ids: HashMap<Option<usize>, (MaterialId, Option<MeshAlpha>)> = HashMap::new();
    let mut meshes = Vec::new();
    for model in models {
        let m = &model.mesh;
        if m.indices.is_empty() {
            w.warn(&whole, format!("object '{}' has no faces (points or lines only); skipped", model.name));
            continue;
        }
        // An unknown `usemtl` name leaves no material id: those share the default.
        let mat = model.mesh.material_id.and_then(|i| materials.get(i));
        let key = mat.and(model.mesh.material_id);
        let defined = |mtl: &tobj::Material| material_lines.borrow().get(&mtl.name).cloned();
        let (material, alpha) = *ids.entry(key).or_insert_with(|| match mat {
            Some(mtl) => {
                let at = defined(mtl).unwrap_or_else(|| whole.clone());
                add_mtl_material(mtl, &mut loaded, &mut images, dir, &at, &mut w)
            }
            None => (loaded.scene.add_material(Material::default_diffuse()), None),
        });
        let mut mesh = TriangleMesh {
            name: model.name.clone(),
            positions: m.positions.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect(),
            normals: m.normals.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect(),
            uvs: m.texcoords.chunks_exact(2).map(|c| Vec2::new(c[0], c[1])).collect(),
            indices: m.indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            material,
            emission: mat
                .map(mtl_emission)
                .transpose()
                .map_err(|e| SceneError::at(&mat.and_then(defined).unwrap_or_else(|| whole.clone()), e))?
                .flatten(),
            flip_normals: false,
            alpha,
            curves: None,
            media: None,
        };
        // Faces mixing vertices with and without normals (or uvs) leave them partial: drop them.
        if mesh.normals.len() != mesh.positions.len() {
            mesh.normals.clear();
        }
        if mesh.uvs.len() != mesh.positions.len() {
            mesh.uvs.clear();
        }
        mesh.validate()
            .map_err(|m| SceneError::caused_by(&whole, format!("object '{}': {m}", model.name), m))?;
        meshes.push(loaded.scene.add_mesh(mesh));
    }
    if meshes.is_empty() {
        return Err(SceneError::at(&whole, "no triangles to render (points and lines are not supported)"));
    }
    add_world_object(&mut loaded.scene, meshes);
    crate::framing::frame_scene(&mut loaded.scene, true);
    loaded.warnings = w.list;
    Ok(loaded)
}

/// Text of an OBJ or MTL file: UTF-16 when it starts with a byte-order mark,
/// else UTF-8 (BOM dropped) with invalid bytes replaced. The flag says
/// whether anything was replaced.
fn decode_text(bytes: &[u8]) -> (std::borrow::Cow<'_, str>, bool) {
    let utf16 = |be: bool| {
        let units = bytes[2..].chunks_exact(2).map(|c| {
            if be {
                u16::from_be_bytes([c[0], c[1]])
            } else {
                u16::from_le_bytes([c[0], c[1]])
            }
        });
        let text: String =
            char::decode_utf16(units).map(|c| c.unwrap_or(char::REPLACEMENT_CHARACTER)).collect();
        (std::borrow::Cow::Owned(text), false)
    };
    match bytes {
        [0xfe, 0xff, ..] => utf16(true),
        [0xff, 0xfe, ..] => utf16(false),
        _ => {
            let b = bytes.strip_prefix(&[0xef, 0xbb, 0xbf]).unwrap_or(bytes);
            let text = String::from_utf8_lossy(b);
            let lossy = matches!(text, std::borrow::Cow::Owned(_));
            (text, lossy)
        }
    }
}

/// MTL text as tobj reads it. The MTL spec lets a colour statement (`Ka`,
/// `Kd`, `Ks`, `Ke`) give one value for all three channels; tobj takes
/// exactly three and panics on fewer, so one value is written out three
/// times, and none or two (a malformed line) is a parse error.
fn mtl_for_tobj(text: &str) -> Result<std::borrow::Cow<'_, str>, tobj::LoadError> {
    fn colour(line: &str) -> Option<(&str, Vec<&str>)> {
        let mut words = line.split_whitespace();
        let keyword = words.next().filter(|k| matches!(*k, "Ka" | "Kd" | "Ks" | "Ke"))?;
        Some((keyword, words.collect()))
    }
    let mut lines = text.lines().map(colour);
    if lines.all(|c| c.is_none_or(|(_, values)| values.len() >= 3)) {
        return Ok(std::borrow::Cow::Borrowed(text));
    }
    let mut out = String::with_capacity(text.len() + 64);
    for line in text.lines() {
        match colour(line) {
            Some((keyword, values)) if values.len() < 3 => {
                let [v] = values[..] else { return Err(tobj::LoadError::MaterialParseError) };
                out.push_str(&format!("{keyword} {v} {v} {v}"));
            }
            _ => out.push_str(line),
        }
        out.push('\n');
    }
    Ok(std::borrow::Cow::Owned(out))
}

/// Adds the atoll material for an MTL material with its textures; returns
/// its id and the alpha mask of the meshes that use it.
fn add_mtl_material(
    mtl: &tobj::Material,
    loaded: &mut LoadedScene,
    images: &mut ImageCache,
    dir: &Path,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> (MaterialId, Option<MeshAlpha>) {
    let material = mtl_material(mtl);
    let diffuse = matches!(material, Material::Diffuse { .. });
    let id = loaded.scene.add_material(material);
    let t = mtl_textures(mtl, diffuse, &mut loaded.scene.textures, images, dir, loc, w);
    if let Some(texture) = t.reflectance {
        loaded.scene.textures.bind(TextureBinding {
            material: id,
            param: TexturedParam::Reflectance,
            texture,
            remap_roughness: false,
        });
    }
    (id, t.alpha)
}

/// The textures of one MTL material (rules in the module docs).
struct MtlTextures {
    /// `map_Kd` × `Kd`, for the material's reflectance.
    reflectance: Option<crate::TextureId>,
    alpha: Option<MeshAlpha>,
}

/// A texture map statement: the file and the options atoll reads.
#[derive(Debug, PartialEq)]
struct MapSpec {
    file: String,
    mapping: UvMapping,
    wrap: Wrap,
    channel: Option<Channel>,
}

/// Parses `[-option values...] file` of a `map_*` statement (tobj keeps
/// the whole line). The file name may contain spaces.
fn parse_map(spec: &str) -> MapSpec {
    let mut words = spec.split_whitespace().peekable();
    let mut m =
        MapSpec { file: String::new(), mapping: UvMapping::default(), wrap: Wrap::Repeat, channel: None };
    let mut rest: Vec<&str> = Vec::new();
    while let Some(word) = words.next() {
        if !rest.is_empty() || !word.starts_with('-') {
            rest.push(word);
            continue;
        }
        // Up to three numbers (`-s`, `-o`, `-t`), else the option's fixed argument count.
        let mut numbers = |max: usize| -> Vec<f32> {
            let mut v = Vec::new();
            while v.len() < max {
                match words.peek().and_then(|x| x.parse::<f32>().ok()) {
                    Some(x) => {
                        v.push(x);
                        words.next();
                    }
                    None => break,
                }
            }
            v
        };
        match word {
            "-s" => {
                let v = numbers(3);
                m.mapping.su = v.first().copied().unwrap_or(1.0);
                m.mapping.sv = v.get(1).copied().unwrap_or(m.mapping.su);
            }
            "-o" => {
                let v = numbers(3);
                m.mapping.du = v.first().copied().unwrap_or(0.0);
                m.mapping.dv = v.get(1).copied().unwrap_or(0.0);
            }
            "-t" => {
                numbers(3);
            }
            "-mm" => {
                numbers(2);
            }
            "-clamp" => m.wrap = if words.next() == Some("on") { Wrap::Clamp } else { Wrap::Repeat },
            "-imfchan" => {
                m.channel = match words.next() {
                    Some("r") => Some(Channel::Red),
                    Some("g") => Some(Channel::Green),
                    Some("b") => Some(Channel::Blue),
                    Some("m") => Some(Channel::Alpha),
                    Some("l") => Some(Channel::Average),
                    _ => None,
                }
            }
            // -blendu, -blendv, -cc, -bm, -boost, -texres, -type: one argument each.
            _ => {
                words.next();
            }
        }
    }
    // Exporters on Windows write `.\tex.jpg`.
    m.file = rest.join(" ").replace('\\', "/");
    m
}

impl MapSpec {
    /// The image texture reading `channel` of `image` with this map's options.
    fn texture(&self, image: crate::ImageId, channel: Channel) -> Texture {
        Texture::Image {
            image,
            mapping: self.mapping.into(),
            wrap: self.wrap,
            channel,
            scale: 1.0,
            invert: false,
            filter: crate::ImageFilter::None,
            levels: 1,
        }
    }
}

/// The textures of `mtl` (rules in the module docs); `diffuse` says whether
/// its atoll material takes a reflectance texture.
fn mtl_textures(
    mtl: &tobj::Material,
    diffuse: bool,
    textures: &mut crate::Textures,
    images: &mut ImageCache,
    dir: &Path,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> MtlTextures {
    let what = format!("material '{}'", mtl.name);
    let spec = |m: &Option<String>| m.as_deref().map(str::trim).filter(|t| !t.is_empty()).map(parse_map);
    // The map's image, or `None` after a warning when it cannot be read.
    let mut load = |map: &MapSpec, keyword: &str, encoding, textures: &mut crate::Textures| {
        crate::input::beside(dir, &map.file)
            .map_err(crate::ImageLoadError::io(Path::new(&map.file)))
            .and_then(|path| images.load(textures, &path, encoding))
            .map_err(|e| w.warn(loc, format!("{what}: {keyword}: {e}; ignored")))
            .ok()
    };
    let mut out = MtlTextures { reflectance: None, alpha: None };
    let mut kd_alpha = None;
    if let Some(map) = spec(&mtl.diffuse_texture) {
        if let Some(image) = load(&map, "map_Kd", ColorEncoding::Srgb, textures) {
            let tex = textures.add(map.texture(image, Channel::Rgb));
            let kd = mtl.diffuse.map(Rgb::from).unwrap_or(Rgb::ONE);
            out.reflectance = Some(if kd == Rgb::ONE {
                tex
            } else {
                textures.add(Texture::Scale { tex: TexInput::Texture(tex), scale: TexInput::Value(kd) })
            });
            if textures.images[image as usize].has_alpha() {
                kd_alpha = Some(map.texture(image, Channel::Alpha));
            }
        }
    }
    let cutout = |texture| Some(MeshAlpha { texture, mode: AlphaMode::Cutoff(0.5) });
    if let Some(map) = spec(&mtl.dissolve_texture) {
        // A mask is data, not colour: read linearly.
        if let Some(image) = load(&map, "map_d", ColorEncoding::Linear, textures) {
            let alpha =
                if textures.images[image as usize].has_alpha() { Channel::Alpha } else { Channel::Average };
            out.alpha = cutout(textures.add(map.texture(image, map.channel.unwrap_or(alpha))));
        }
    } else if let Some(texture) = kd_alpha {
        out.alpha = cutout(textures.add(texture));
    }
    if out.reflectance.is_some() && !diffuse {
        w.warn(loc, format!("{what}: map_Kd is ignored (it colours diffuse materials only)"));
        out.reflectance = None;
    }
    // `d` is opacity; `Tr` its complement, written by some exporters instead.
    let tr = mtl.unknown_param.get("Tr").and_then(|t| t.trim().parse::<f32>().ok());
    match mtl.dissolve.or(tr.map(|t| 1.0 - t)) {
        Some(d) if d < 1.0 && out.alpha.is_none() && !is_refractive(mtl) => {
            if d > 0.0 {
                let texture = textures.add(Texture::Constant(Rgb::splat(d)));
                out.alpha = Some(MeshAlpha { texture, mode: AlphaMode::Stochastic });
            } else {
                w.warn(
                    loc,
                    format!(
                        "{what}: d 0 (fully transparent) is taken for an exporter's mistake; rendered opaque"
                    ),
                );
            }
        }
        _ => {}
    }
    if spec(&mtl.normal_texture).is_some() {
        w.warn(loc, format!("{what}: bump and normal maps are not supported; ignored"));
    }
    out
}

fn is_refractive(mtl: &tobj::Material) -> bool {
    matches!(mtl.illumination_model, Some(4 | 6 | 7 | 9))
}

/// The atoll material for an MTL material (rules in the module docs).
pub fn mtl_material(mtl: &tobj::Material) -> Material {
    let kd = mtl.diffuse.map(Rgb::from).unwrap_or(Rgb::splat(0.5));
    let ks = mtl.specular.map(Rgb::from).unwrap_or(Rgb::ZERO);
    let ns = mtl.shininess.unwrap_or(0.0);
    let phong_alpha = (2.0 / (ns.max(0.0) + 2.0)).sqrt();
    if is_refractive(mtl) {
        let eta = mtl.optical_density.filter(|&n| n > 1.0).unwrap_or(1.5);
        // Refracting MTL materials are smooth unless Ns says otherwise; a
        // missing Ns is not a hint of roughness.
        let alpha = if mtl.shininess.is_some() && ns < 200.0 { phong_alpha } else { 0.0 };
        return Material::Dielectric { eta, alpha_x: alpha, alpha_y: alpha };
    }
    if ks.max_element() >= 0.5 && ns >= 200.0 && ks.max_element() > kd.max_element() {
        let k = Material::conductor_k_from_reflectance(ks);
        return Material::Conductor { eta: Rgb::ONE, k, alpha_x: phong_alpha, alpha_y: phong_alpha };
    }
    Material::Diffuse { reflectance: kd }
}

/// `Ke` as an area light, when non-zero.
fn mtl_emission(mtl: &tobj::Material) -> Result<Option<AreaEmission>, String> {
    let Some(ke) = mtl.emissive else { return Ok(None) };
    AreaEmission::one_sided(Rgb::from(ke)).map_err(|e| format!("material '{}': Ke: {e}", mtl.name))
}

/// A `SceneError` for a tobj failure. Errors about one line point at it
/// (`line` is the line tobj was reading); index errors are only detected
/// when a group ends, so the offending face is searched for instead.
fn obj_error(e: tobj::LoadError, bytes: &[u8], line: u32, name: &str) -> SceneError {
    use tobj::LoadError as E;
    let what = match e {
        E::PositionParseError => "bad vertex position 'v'",
        E::NormalParseError => "bad normal 'vn'",
        E::TexcoordParseError => "bad texture coordinate 'vt'",
        E::FaceParseError => "bad face 'f'",
        E::MaterialParseError => "bad 'usemtl' (no material name)",
        E::ColorParseError => "bad vertex colour",
        E::ScalingByZeroError => "vertex 'w' is zero",
        E::InvalidObjectName => "bad object name",
        E::FaceVertexOutOfBounds
        | E::FaceNormalOutOfBounds
        | E::FaceTexCoordOutOfBounds
        | E::InvalidPolygon => {
            let (at, msg) = find_bad_index(bytes).unwrap_or((0, format!("bad face: {e}")));
            return SceneError::at(&FileLoc::new(name, at, 1), msg);
        }
        other => return SceneError::at(&FileLoc::whole_file(name), format!("cannot load OBJ: {other}")),
    };
    SceneError::at(&FileLoc::new(name, line.max(1), 1), what)
}

/// The first face line whose `v`/`vt`/`vn` index is out of range (OBJ
/// indices count from 1; negative ones count back from the last defined).
fn find_bad_index(bytes: &[u8]) -> Option<(u32, String)> {
    let text = String::from_utf8_lossy(bytes);
    let mut counts = [0i64; 3];
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => counts[0] += 1,
            Some("vt") => counts[1] += 1,
            Some("vn") => counts[2] += 1,
            Some("f") => {
                if words.clone().next().is_none() {
                    return Some((i as u32 + 1, "face without vertices".into()));
                }
                for vertex in words {
                    for (slot, s) in vertex.split('/').enumerate().take(3) {
                        let Ok(idx) = s.parse::<i64>() else { continue };
                        let n = counts[slot];
                        let resolved = if idx < 0 { n + idx + 1 } else { idx };
                        if resolved < 1 || resolved > n {
                            let kind = ["vertex", "texture coordinate", "normal"][slot];
                            let msg = format!("face uses {kind} {idx} but only {n} are defined before it");
                            return Some((i as u32 + 1, msg));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    None
}

/// How many `f` lines have one or two vertices (tobj drops them as points
/// and lines), and the first one's line.
fn short_faces(text: &str) -> Option<(usize, u32)> {
    let mut found = None;
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() == Some("f") && matches!(words.count(), 1 | 2) {
            let (n, _) = found.get_or_insert((0, i as u32 + 1));
            *n += 1;
        }
    }
    found
}

/// Reads a byte slice for tobj, counting the lines it consumed, so a parse
/// error can name the line tobj was reading.
struct LineCounter<'a> {
    data: &'a [u8],
    pos: usize,
    newlines: u32,
}

impl LineCounter<'_> {
    /// The line tobj read last (from 1).
    fn current_line(&self) -> u32 {
        let ended = self.pos > 0 && self.data[self.pos - 1] == b'\n';
        self.newlines + u32::from(!ended)
    }
}

impl Read for LineCounter<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = buf.len().min(self.data.len() - self.pos);
        buf[..n].copy_from_slice(&self.data[self.pos..self.pos + n]);
        self.consume(n);
        Ok(n)
    }
}

impl BufRead for LineCounter<'_> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        Ok(&self.data[self.pos..])
    }

    fn consume(&mut self, amt: usize) {
        let end = (self.pos + amt).min(self.data.len());
        self.newlines += self.data[self.pos..end].iter().filter(|&&b| b == b'\n').count() as u32;
        self.pos = end;
    }
}
