//! OBJ/MTL, glTF (JSON with external or data-URI buffers, and GLB), PLY and
//! OFF through `load_any`, on files written here with known contents; bad
//! files give errors with locations, never panics.

mod common;

use atoll_scene::{
    load_any, AlphaMode, AreaEmission, Channel, Light, Material, PrincipledParams, Rgb, TexInput, Texels,
    Texture, TexturedParam, UvMapping, Wrap,
};
use common::{assert_close, gltf_bin, temp_dir, write};
use glam::{UVec2, Vec3};
use serde_json::json;

const OBJ: &str = "# a quad, a lamp triangle and a glass triangle
mtllib scene.mtl
o quad
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
usemtl red
f 1/1/1 2/2/1 3/3/1 4/4/1
o lamp
usemtl light
f 1 2 3
usemtl chrome
f 2 3 4
usemtl glass
f -4 -3 -1
";

const MTL: &str = "newmtl red\nKd 0.8 0.1 0.1\nKs 0.9 0.9 0.9\nNs 10\nmap_Kd tex\\red.png\n\
newmtl chrome\nKd 0.05 0.05 0.05\nKs 0.9 0.8 0.7\nNs 898\n\
newmtl glass\nillum 7\nNi 1.45\nd 0.2\n\
newmtl light\nKd 0 0 0\nKe 5 4 3\n";

#[test]
fn obj_with_mtl() {
    let dir = temp_dir("obj");
    write(&dir, "scene.mtl", MTL);
    let loaded = load_any(&write(&dir, "scene.obj", OBJ)).unwrap();
    let s = &loaded.scene;
    assert_eq!((s.objects.len(), s.instances.len(), s.meshes.len()), (1, 1, 4));
    assert_eq!(s.instances[0].object_to_world, glam::Affine3A::IDENTITY);
    let quad = &s.meshes[0];
    assert_eq!((quad.name.as_str(), quad.triangle_count()), ("quad", 2));
    assert_eq!((quad.normals.len(), quad.uvs.len()), (quad.positions.len(), quad.positions.len()));
    assert!(quad.geometric_normal(0).z > 0.0, "counter-clockwise faces face +z");
    let mat = |i: usize| &s.materials[s.meshes[i].material as usize];
    assert_eq!(*mat(0), Material::Diffuse { reflectance: Rgb::new(0.8, 0.1, 0.1) });
    assert_eq!(*mat(1), Material::Diffuse { reflectance: Rgb::ZERO });
    assert_eq!(
        s.meshes[1].emission,
        Some(AreaEmission { radiance: Rgb::new(5.0, 4.0, 3.0), two_sided: false })
    );
    let k = Material::conductor_k_from_reflectance(Rgb::new(0.9, 0.8, 0.7));
    let alpha = (2.0f32 / 900.0).sqrt();
    assert_eq!(*mat(2), Material::Conductor { eta: Rgb::ONE, k, alpha_x: alpha, alpha_y: alpha });
    assert_eq!(*mat(3), Material::Dielectric { eta: 1.45, alpha_x: 0.0, alpha_y: 0.0 });
    // Negative indices count back from the last vertex: -4 -3 -1 are 1 2 4.
    assert_eq!(s.meshes[3].triangle(0), [Vec3::ZERO, Vec3::X, Vec3::Y]);
    // `map_Kd tex\red.png` names no file here: warned about, the material keeps Kd.
    assert!(s.textures.images.is_empty() && s.textures.bindings.is_empty());
    let w: Vec<&str> = loaded.warnings.iter().map(|w| w.message.as_str()).collect();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].starts_with("material 'red': map_Kd: ") && w[0].contains("tex/red.png"), "{w:?}");
    // Emissive meshes light the scene: no default sky or sun.
    assert!(s.lights.is_empty());
    assert_eq!(s.settings.film.resolution, UVec2::new(1024, 768));
}

#[test]
fn obj_without_its_mtl_warns_and_uses_the_default() {
    let dir = temp_dir("obj-nomtl");
    let path = write(&dir, "scene.obj", OBJ);
    let loaded = load_any(&path).unwrap();
    let w = &loaded.warnings;
    assert_eq!(w.len(), 1, "{w:?}");
    assert_eq!(
        w[0].to_string(),
        format!(
            "{}: material library 'scene.mtl' cannot be read: No such file or directory (os error 2); its materials use the default diffuse",
            path.display()
        )
    );
    assert!(loaded.scene.materials.iter().all(|m| *m == Material::default_diffuse()));
    assert_eq!(loaded.scene.materials.len(), 1);
    // No light in the file: the default sky and sun.
    assert_eq!(loaded.scene.lights, atoll_scene::framing::default_lights());
}

/// The MTL spec lets colours give one value for all channels; tobj panicked
/// on fewer than three (found by the property tests).
#[test]
fn mtl_colours_with_one_value_or_none() {
    let dir = temp_dir("mtl-short");
    write(&dir, "scene.mtl", "newmtl red\nKd 0.25\n");
    let loaded = load_any(&write(
        &dir,
        "scene.obj",
        "mtllib scene.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n",
    ))
    .unwrap();
    assert_eq!(loaded.scene.materials, [Material::Diffuse { reflectance: Rgb::splat(0.25) }]);
    for bad in ["Kd", "Kd 0.25 0.5"] {
        write(&dir, "scene.mtl", format!("newmtl red\n{bad}\n"));
        let loaded = load_any(&dir.join("scene.obj")).unwrap();
        let w = loaded.warnings.iter().map(ToString::to_string).collect::<Vec<_>>().join("\n");
        assert!(w.contains("material library 'scene.mtl'"), "{bad}: {w}");
    }
}

#[test]
fn bad_obj_files_are_errors_with_lines() {
    let dir = temp_dir("obj-bad");
    let cases = [
        ("v 0 0 0\nv 1 0 zero\n", 2, "bad vertex position"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0\n", 4, "bad normal"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 3\nf 1 2 9\n", 6, "face uses vertex 9 but only 3 are defined"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 x\n", 5, "bad face"),
        // A file cut off in the middle of a number.
        (&OBJ[..OBJ.find("v 1 1 0").unwrap() + 4], 6, "bad vertex position"),
    ];
    for (text, line, msg) in cases {
        let path = write(&dir, "bad.obj", text);
        let e = load_any(&path).unwrap_err();
        assert_eq!((e.line, e.file.as_str()), (line, path.to_str().unwrap()), "{e}");
        assert!(e.message.contains(msg), "{e}");
    }
    let e = load_any(&write(&dir, "points.obj", "v 0 0 0\nv 1 0 0\np 1 2\n")).unwrap_err();
    assert!(e.message.contains("no triangles"), "{e}");
}

/// A glTF scene exercising instancing, materials, camera and lights.
fn gltf_json(buffer_uri: Option<String>) -> serde_json::Value {
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let vec3 = |view: u32, n: u32, max: [f32; 3]| json!({"bufferView": view, "componentType": 5126, "count": n, "type": "VEC3", "min": [0, 0, 0], "max": max});
    let mut buffer = json!({"byteLength": gltf_bin().len()});
    if let Some(uri) = buffer_uri {
        buffer["uri"] = json!(uri);
    }
    json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior",
                           "KHR_materials_emissive_strength", "KHR_texture_transform", "KHR_materials_clearcoat"],
        "scene": 0,
        "scenes": [{"nodes": [0, 3, 4, 5, 6, 7, 8]}],
        "nodes": [
            {"name": "root", "translation": [10, 0, 0], "children": [1, 2]},
            {"mesh": 0, "rotation": [0, 0, s, s]},
            {"mesh": 0, "scale": [2, 2, 2]},
            {"mesh": 1, "translation": [0, 5, 0]},
            {"mesh": 2},
            {"camera": 0, "translation": [0, 1, 10]},
            {"translation": [0, 3, 0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"extensions": {"KHR_lights_punctual": {"light": 1}}},
            {"rotation": [-s, 0, 0, s], "extensions": {"KHR_lights_punctual": {"light": 2}}}
        ],
        "meshes": [
            {"name": "tri", "primitives": [
                {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3, "material": 0},
                {"attributes": {"POSITION": 4}, "mode": 5, "material": 1}]},
            {"name": "glass", "primitives": [{"attributes": {"POSITION": 0}, "indices": 3, "material": 2}]},
            {"name": "lamp", "primitives": [{"attributes": {"POSITION": 0}, "material": 3}]}
        ],
        "materials": [
            {"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.2, 0.1, 0.5], "metallicFactor": 0,
                                      "baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform":
                                          {"offset": [0.5, 0.25], "scale": [2, 4]}}}},
             "alphaMode": "MASK", "alphaCutoff": 0.3},
            {"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.8, 0.5, 1], "metallicFactor": 1, "roughnessFactor": 0.5},
             "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 0.5, "clearcoatRoughnessFactor": 0.1}}},
            {"pbrMetallicRoughness": {"roughnessFactor": 0, "metallicFactor": 0},
             "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1}, "KHR_materials_ior": {"ior": 1.33}}},
            {"emissiveFactor": [1, 0.5, 0.25], "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4}}}
        ],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"wrapS": 33648, "wrapT": 33648}],
        "images": [{"uri": "tex/wood%20dark.png"}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "aspectRatio": 1.5, "znear": 0.1}}],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "color": [1, 1, 1], "intensity": 10},
            {"type": "spot", "intensity": 5, "spot": {}},
            {"type": "directional", "color": [1, 0.9, 0.8], "intensity": 2}]}},
        "accessors": [
            vec3(0, 3, [1., 1., 0.]),
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 3, "type": "SCALAR"},
            vec3(4, 4, [1., 1., 0.])
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 36},
            {"buffer": 0, "byteOffset": 72, "byteLength": 24},
            {"buffer": 0, "byteOffset": 96, "byteLength": 6},
            {"buffer": 0, "byteOffset": 104, "byteLength": 48}
        ],
        "buffers": [buffer]
    })
}

/// A binary glTF of `json` with `bin` as its BIN chunk.
fn glb(json: &serde_json::Value, bin: &[u8]) -> Vec<u8> {
    common::glb(&serde_json::to_vec(json).unwrap(), bin)
}

fn base64(bytes: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            s.push(if i <= c.len() { A[(n >> (18 - 6 * i) & 63) as usize] as char } else { '=' });
        }
    }
    s
}

#[test]
fn gltf_scene_in_all_three_packagings() {
    let dir = temp_dir("gltf");
    write(&dir, "scene.bin", gltf_bin());
    // The base colour image: 2x1, sRGB, alpha 1 and 0.4.
    std::fs::create_dir_all(dir.join("tex")).unwrap();
    let image = image::RgbaImage::from_raw(2, 1, vec![255, 128, 0, 255, 0, 64, 255, 102]).unwrap();
    image.save(dir.join("tex/wood dark.png")).unwrap();
    let external = write(&dir, "external.gltf", gltf_json(Some("scene.bin".into())).to_string());
    let data_uri = format!("data:application/octet-stream;base64,{}", base64(&gltf_bin()));
    let embedded = write(&dir, "embedded.gltf", gltf_json(Some(data_uri)).to_string());
    let binary = write(&dir, "binary.glb", glb(&gltf_json(None), &gltf_bin()));
    for path in [&external, &embedded, &binary] {
        let loaded = load_any(path).unwrap_or_else(|e| panic!("{e}"));
        check_gltf_scene(&loaded);
    }
    // Without its image the material keeps its factors (after a warning), and
    // the constant alpha 0.5 passes the 0.3 cutoff: no mask.
    std::fs::remove_file(dir.join("tex/wood dark.png")).unwrap();
    let loaded = load_any(&external).unwrap();
    let s = &loaded.scene;
    assert!(s.textures.images.is_empty() && s.textures.bindings.is_empty());
    assert!(s.meshes.iter().all(|m| m.alpha.is_none()));
    let w: Vec<&str> = loaded.warnings.iter().map(|w| w.message.as_str()).collect();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].starts_with("image 0 ('tex/wood%20dark.png') cannot be read: "), "{w:?}");
}

fn check_gltf_scene(loaded: &atoll_scene::LoadedScene) {
    let s = &loaded.scene;
    // Mesh "tri" is used by two nodes but stored once.
    assert_eq!((s.objects.len(), s.meshes.len(), s.instances.len()), (3, 4, 4));
    assert_eq!(s.objects[0].meshes.len(), 2);
    assert_eq!(s.meshes[1].indices, [[0, 1, 2], [2, 1, 3]], "triangle strip");
    assert_eq!((s.instances[0].object, s.instances[1].object), (0, 0));
    let p = |i: usize, v: Vec3| s.instances[i].object_to_world.transform_point3(v);
    assert_close(p(0, Vec3::X), Vec3::new(10.0, 1.0, 0.0), 1e-5);
    assert_close(p(1, Vec3::X), Vec3::new(12.0, 0.0, 0.0), 1e-5);
    assert_close(p(2, Vec3::ZERO), Vec3::new(0.0, 5.0, 0.0), 1e-6);
    let tri = &s.meshes[0];
    assert_eq!((tri.normals.len(), tri.uvs.len(), tri.flip_normals), (3, 3, false));
    assert!(tri.geometric_normal(0).z > 0.0, "glTF front faces are counter-clockwise");
    let m = |mesh: usize| &s.materials[s.meshes[mesh].material as usize];
    // (base colour, metallic, roughness), (clearcoat, gloss), (transmission, ior).
    let principled = |(base, metallic, roughness): (Rgb, f32, f32), coat: (f32, f32), glass: (f32, f32)| {
        Material::Principled(PrincipledParams {
            base_color: base,
            metallic,
            roughness,
            specular: Material::specular_from_eta(glass.1),
            specular_tint: 0.0,
            sheen: 0.0,
            sheen_tint: 0.0,
            clearcoat: coat.0,
            clearcoat_gloss: coat.1,
            transmission: glass.0,
            eta: glass.1,
        })
    };
    let (no_coat, no_glass) = ((0.0, 1.0), (0.0, 1.5));
    assert_eq!(*m(0), principled((Rgb::new(0.8, 0.2, 0.1), 0.0, 1.0), no_coat, no_glass));
    // Clearcoat roughness r = 0.1: the gloss whose GTR1 alpha (0.1 - 0.099 gloss) is r².
    let coat = (0.5, (0.1f32 - 0.1 * 0.1) / 0.099);
    assert_eq!(*m(1), principled((Rgb::new(0.9, 0.8, 0.5), 1.0, 0.5), coat, no_glass));
    assert_eq!(*m(2), principled((Rgb::ONE, 0.0, 0.0), no_coat, (1.0, 1.33)));
    // The lamp has no material: glTF's default, white metal of roughness 1.
    assert_eq!(*m(3), principled((Rgb::ONE, 1.0, 1.0), no_coat, no_glass));
    // The base colour texture: the sRGB image, times the factor, bound to the
    // reflectance, mirrored, offset and scaled with v flipped.
    let t = &s.textures;
    assert_eq!(t.images.len(), 1);
    let img = &t.images[0];
    assert_eq!((img.width, img.height), (2, 1));
    let Texels::Rgba8 { srgb: true, data } = &img.texels else { panic!("{:?}", img.texels) };
    assert_eq!(data, &[[255, 128, 0, 255], [0, 64, 255, 102]]);
    let bound: Vec<_> = t.bindings_of(s.meshes[0].material).collect();
    assert_eq!(bound.len(), 1);
    assert_eq!((bound[0].param, bound[0].remap_roughness), (TexturedParam::Reflectance, false));
    let Texture::Scale { tex: TexInput::Texture(image), scale } = t.textures[bound[0].texture as usize]
    else {
        panic!("{:?}", t.textures)
    };
    assert_eq!(scale, TexInput::Value(Rgb::new(0.8, 0.2, 0.1)));
    let mapping = UvMapping { su: 2.0, sv: -4.0, du: 0.5, dv: 0.75 };
    let node = |channel: Channel, scale: f32| Texture::Image {
        image: 0,
        mapping: mapping.into(),
        wrap: Wrap::Mirror,
        channel,
        scale,
        invert: false,
        filter: atoll_scene::ImageFilter::None,
        levels: 1,
    };
    assert_eq!(t.textures[image as usize], node(Channel::Rgb, 1.0));
    // MASK: the image's alpha times the factor's (0.5) against the cutoff, on both
    // primitives of the material and no other mesh.
    let alpha = s.meshes[0].alpha.expect("a mask");
    assert_eq!(alpha.mode, AlphaMode::Cutoff(0.3));
    assert_eq!(t.textures[alpha.texture as usize], node(Channel::Alpha, 0.5));
    assert!(s.meshes[1..].iter().all(|m| m.alpha.is_none()));
    assert_eq!(
        s.meshes[3].emission,
        Some(AreaEmission { radiance: Rgb::new(4.0, 2.0, 1.0), two_sided: false })
    );
    assert_eq!(s.meshes[3].indices, [[0, 1, 2]], "non-indexed");
    // Camera at (0, 1, 10) looking down -Z, aspect 1.5: fov = yfov on a landscape image.
    let cam = &s.settings.camera;
    assert_close(cam.camera_to_world.transform_point3(Vec3::ZERO), Vec3::new(0.0, 1.0, 10.0), 1e-6);
    assert_close(cam.camera_to_world.transform_vector3(Vec3::Z), -Vec3::Z, 1e-6);
    assert_close(cam.camera_to_world.transform_vector3(Vec3::X), Vec3::X, 1e-6);
    assert!((cam.fov_degrees - 0.8f32.to_degrees()).abs() < 1e-4);
    assert_eq!(s.settings.film.resolution, UVec2::new(1024, 683));
    assert_eq!(s.lights.len(), 3);
    assert_eq!(s.lights[0], Light::Point { position: Vec3::new(0.0, 3.0, 0.0), intensity: Rgb::splat(10.0) });
    // glTF's default cone: inner 0, outer π/4.
    let Light::Spot { intensity, cos_falloff_start, cos_falloff_end, .. } = s.lights[1] else {
        panic!("{:?}", s.lights[1])
    };
    assert_eq!(intensity, Rgb::splat(5.0));
    assert!(
        (cos_falloff_start - 1.0).abs() < 1e-6 && (cos_falloff_end - 45f32.to_radians().cos()).abs() < 1e-6
    );
    let Light::Distant { direction, radiance } = s.lights[2] else { panic!("{:?}", s.lights[2]) };
    assert_close(direction, -Vec3::Y, 1e-6);
    assert_close(radiance, Rgb::new(2.0, 1.8, 1.6), 1e-6);
    assert_eq!(img.name, "tex/wood%20dark.png");
    let w: Vec<&str> = loaded.warnings.iter().map(|w| w.message.as_str()).collect();
    assert!(w.is_empty(), "{w:?}");
}

#[test]
fn broken_gltf_files_are_errors() {
    let dir = temp_dir("gltf-bad");
    let good = glb(&gltf_json(None), &gltf_bin());
    for cut in [10, 30, good.len() - 20] {
        let e = load_any(&write(&dir, "cut.glb", &good[..cut])).unwrap_err();
        assert_eq!(e.line, 0, "{e}");
    }
    write(&dir, "short.bin", &gltf_bin()[..100]);
    let e =
        load_any(&write(&dir, "short.gltf", gltf_json(Some("short.bin".into())).to_string())).unwrap_err();
    assert!(e.message.contains("has 100 bytes but the file says 152"), "{e}");
    let text = gltf_json(Some("scene.bin".into())).to_string();
    let e = load_any(&write(&dir, "cut.gltf", &text[..text.len() / 2])).unwrap_err();
    assert!(e.line >= 1 && e.message.starts_with("bad glTF JSON"), "{e}");
    // Positions declared as 2D would make the gltf crate panic; we refuse them.
    let mut j = gltf_json(Some("scene.bin".into()));
    j["accessors"][0]["type"] = json!("VEC2");
    write(&dir, "scene.bin", gltf_bin());
    let e = load_any(&write(&dir, "vec2.gltf", j.to_string())).unwrap_err();
    assert!(e.message.contains("POSITION accessor 0: unexpected type Vec2"), "{e}");
    // A node that is its own descendant.
    let mut j = gltf_json(Some("scene.bin".into()));
    j["nodes"][1]["children"] = json!([0]);
    let e = load_any(&write(&dir, "cycle.gltf", j.to_string())).unwrap_err();
    assert!(e.message.contains("cycle"), "{e}");
}

/// An orthographic glTF camera: half-width and half-height as the screen
/// window, an image of their aspect ratio; a zero size is an error.
#[test]
fn gltf_orthographic_camera() {
    let dir = temp_dir("gltf-ortho");
    write(&dir, "scene.bin", gltf_bin());
    let mut j = gltf_json(Some("scene.bin".into()));
    j["cameras"][0] =
        json!({"type": "orthographic", "orthographic": {"xmag": 3, "ymag": 1.5, "znear": 0, "zfar": 50}});
    let s = load_any(&write(&dir, "ortho.gltf", j.to_string())).unwrap().scene;
    let cam = &s.settings.camera;
    assert_eq!(cam.projection, atoll_scene::Projection::Orthographic);
    assert_eq!(cam.screen_window, Some([-3.0, 3.0, -1.5, 1.5]));
    assert_eq!(s.settings.film.resolution, UVec2::new(1024, 512));
    assert_close(cam.camera_to_world.transform_vector3(Vec3::Z), -Vec3::Z, 1e-6);
    j["cameras"][0]["orthographic"]["ymag"] = json!(0);
    let e = load_any(&write(&dir, "flat.gltf", j.to_string())).unwrap_err();
    assert!(e.message.contains("camera 0: orthographic xmag 3 and ymag 0 must be nonzero"), "{e}");
}

/// Files the gltf crate panicked on (found by the property tests): refused
/// with what is wrong, not with "the glTF reader failed".
#[test]
fn gltf_files_the_gltf_crate_trusts_are_checked() {
    let dir = temp_dir("gltf-trusted");
    write(&dir, "scene.bin", gltf_bin());
    let mut short = glb(&gltf_json(None), &gltf_bin());
    short[8..12].copy_from_slice(&0u32.to_le_bytes());
    let e = load_any(&write(&dir, "short.glb", &short)).unwrap_err();
    assert!(e.message.contains("bad GLB header: a total length of 0 bytes"), "{e}");
    let cases = [
        ("/meshes/0/primitives/0/attributes/POSITION", json!(99), "POSITION accessor 99 does not exist"),
        ("/images/0", json!({"name": "no source"}), "images[0] has neither a uri nor a bufferView"),
        ("/images/0", json!({"bufferView": 0}), "images[0] has a bufferView but no mimeType"),
    ];
    for (pointer, value, expected) in cases {
        let mut j = gltf_json(Some("scene.bin".into()));
        *j.pointer_mut(pointer).unwrap() = value;
        let e = load_any(&write(&dir, "bad.gltf", j.to_string())).unwrap_err();
        assert!(e.message.contains(expected), "{pointer}: {e}");
    }
}

/// tobj's index arithmetic overflowed on far out-of-range uv and normal
/// indices (found by the property tests).
#[test]
fn obj_indices_far_out_of_range_are_errors() {
    let dir = temp_dir("obj-far");
    for (face, kind) in [("1/-2147483648/1", "texture coordinate"), ("1/1/9223372036854775807", "normal")] {
        let obj = format!("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf {face} 2/1/1 3/1/1\n");
        let e = load_any(&write(&dir, "far.obj", obj)).unwrap_err();
        assert_eq!((e.line, e.message.contains(kind)), (6, true), "{e}");
    }
}

#[test]
fn standalone_ply_and_off_are_framed() {
    let dir = temp_dir("ply");
    let ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
               element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n2 0 0\n2 1 0\n0 1 0\n4 0 1 2 3\n";
    let off = "OFF\n4 1 0\n0 0 0\n2 0 0\n2 1 0\n0 1 0\n4 0 1 2 3\n";
    for path in [write(&dir, "quad.ply", ply), write(&dir, "quad.off", off)] {
        let loaded = load_any(&path).unwrap();
        let s = &loaded.scene;
        assert_eq!((s.meshes.len(), s.meshes[0].triangle_count(), s.instances.len()), (1, 2, 1));
        assert_eq!(s.materials, [Material::default_diffuse()]);
        assert_eq!(s.lights, atoll_scene::framing::default_lights());
        assert_eq!((s.settings.spp, s.settings.film.resolution), (64, UVec2::new(1024, 768)));
        assert_eq!(s.settings.integrator, atoll_scene::IntegratorSettings::Path { max_depth: 8 });
        let eye = s.settings.camera.camera_to_world.transform_point3(Vec3::ZERO);
        let forward = s.settings.camera.camera_to_world.transform_vector3(Vec3::Z);
        assert_close(forward, (Vec3::new(1.0, 0.5, 0.0) - eye).normalize(), 1e-5);
    }
    let e = load_any(&write(&dir, "bad.off", "OFF\n4 1 0\n0 0 0\n2 0 0\n")).unwrap_err();
    assert!(e.message.contains("truncated"), "{e}");
    let e = load_any(&write(&dir, "scene.fbx", "")).unwrap_err();
    assert!(e.message.contains("unknown scene format"), "{e}");
}
