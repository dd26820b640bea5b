//! Textures from the loaders: pbrt-v4 `Texture` classes and their
//! parameters, material bindings, shape alpha, what is warned about and
//! replaced, and OBJ/MTL maps. (pbrt-v3 textures: `pbrt_v3.rs`; the OBJ
//! spider's real textures: `real_models.rs`.)

mod common;

use std::path::Path;

use atoll_scene::pbrt::{load_str, LoadedScene};
use atoll_scene::texture::srgb8_to_linear;
use atoll_scene::{
    load_any, AlphaMode, Channel, CoatedDiffuseParams, ImageFilter, Material, MeshAlpha, Rgb, TexInput,
    TexMapping, Texels, Texture, TexturedParam, UvMapping, Wrap,
};
use common::{allowing_missing, temp_dir, write};

const TRI: &str = "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"point2 uv\" [0 0 1 0 1 1]";

/// Loads a world block (`WorldBegin` is line 1) from a file in `dir`.
fn load(dir: &Path, world: &str) -> LoadedScene {
    load_str(&format!("WorldBegin\n{world}\n"), "t.pbrt", dir).unwrap_or_else(|e| panic!("{e}"))
}

fn warnings(l: &LoadedScene) -> Vec<String> {
    l.warnings.iter().map(|w| w.to_string()).collect()
}

/// A 2×1 PNG: an orange and a half-transparent blue texel.
fn png(dir: &Path, name: &str) {
    let mut img = image::RgbaImage::new(2, 1);
    img.put_pixel(0, 0, image::Rgba([255, 128, 0, 255]));
    img.put_pixel(1, 0, image::Rgba([0, 0, 255, 128]));
    img.save(dir.join(name)).unwrap();
}

/// The (parameter, texture) bindings of mesh `mesh`'s material.
fn bindings(l: &LoadedScene, mesh: usize) -> Vec<(TexturedParam, u32, bool)> {
    let s = &l.scene;
    s.textures.bindings_of(s.meshes[mesh].material).map(|b| (b.param, b.texture, b.remap_roughness)).collect()
}

#[test]
fn texture_classes_with_values_and_nested_textures() {
    let dir = temp_dir("tex-classes");
    png(&dir, "g.png");
    let l = load(
        &dir,
        "Texture \"grid\" \"spectrum\" \"imagemap\" \"string filename\" \"g.png\" \"string wrap\" \"clamp\" \
           \"float scale\" 2 \"bool invert\" true \"string encoding\" \"linear\" \"string filter\" \"trilinear\" \
           \"float uscale\" 2 \"float vscale\" 3 \"float udelta\" 0.5 \"float vdelta\" 0.25\n\
         Texture \"grey\" \"float\" \"imagemap\" \"string filename\" \"g.png\" \"string encoding\" \"gamma 2\"\n\
         Texture \"c\" \"spectrum\" \"constant\" \"rgb value\" [0.1 0.2 0.3]\n\
         Texture \"f\" \"float\" \"constant\" \"float value\" 0.25\n\
         Texture \"checks\" \"spectrum\" \"checkerboard\" \"texture tex1\" \"grid\" \"rgb tex2\" [0 0 1] \"float uscale\" 8\n\
         Texture \"scaled\" \"spectrum\" \"scale\" \"texture tex\" \"checks\" \"texture scale\" \"f\"\n\
         Texture \"folded\" \"spectrum\" \"scale\" \"rgb tex\" [1 2 3] \"float scale\" 0.5\n\
         Texture \"mixed\" \"spectrum\" \"mix\" \"texture tex1\" \"c\" \"texture tex2\" \"scaled\" \"texture amount\" \"grey\"\n\
         Texture \"fmix\" \"float\" \"mix\"\n\
         Texture \"srgb\" \"spectrum\" \"imagemap\" \"string filename\" \"g.png\"",
    );
    assert!(l.warnings.is_empty(), "{:#?}", warnings(&l));
    let t = &l.scene.textures;
    let mapping = UvMapping { su: 2.0, sv: 3.0, du: 0.5, dv: 0.25 };
    assert_eq!(
        t.textures[0],
        Texture::Image {
            image: 0,
            mapping: mapping.into(),
            wrap: Wrap::Clamp,
            channel: Channel::Rgb,
            scale: 2.0,
            invert: true,
            filter: ImageFilter::Trilinear,
            levels: 2,
        }
    );
    // A float image texture reads the colour's mean; "gamma 2" needs its own (float) decoding.
    let Texture::Image { image: 2, channel: Channel::Average, wrap: Wrap::Repeat, .. } = t.textures[1] else {
        panic!("{:?}", t.textures[1])
    };
    assert_eq!(t.images[0].texel(0, 0), [1.0, 128.0 / 255.0, 0.0, 1.0]);
    // Images 0 and 1 are the first one's MIP pyramid, 2 and 3 the second's.
    assert_eq!(t.images[2].texel(0, 0), [1.0, (128.0f32 / 255.0).powi(2), 0.0, 1.0]);
    assert!(matches!(t.images[2].texels, Texels::RgbaF32(_)));
    assert_eq!(t.textures[2], Texture::Constant(Rgb::new(0.1, 0.2, 0.3)));
    assert_eq!(t.textures[3], Texture::Constant(Rgb::splat(0.25)));
    let mapping = UvMapping { su: 8.0, ..UvMapping::default() };
    assert_eq!(
        t.textures[4],
        Texture::Checkerboard {
            mapping: mapping.into(),
            tex: [TexInput::Texture(0), TexInput::Value(Rgb::Z)]
        }
    );
    assert_eq!(t.textures[5], Texture::Scale { tex: TexInput::Texture(4), scale: TexInput::Texture(3) });
    // Two values fold into a constant.
    assert_eq!(t.textures[6], Texture::Constant(Rgb::new(0.5, 1.0, 1.5)));
    assert_eq!(
        t.textures[7],
        Texture::Mix { tex: [TexInput::Texture(2), TexInput::Texture(5)], amount: TexInput::Texture(1) }
    );
    // pbrt-v4's mix defaults: tex1 0, tex2 1, amount 0.5.
    assert_eq!(
        t.textures[8],
        Texture::Mix {
            tex: [TexInput::Value(Rgb::ZERO), TexInput::Value(Rgb::ONE)],
            amount: TexInput::Value(Rgb::splat(0.5))
        }
    );
    // The third use of g.png is sRGB-decoded (the 8-bit default), the first
    // linear: 3 pyramids of 2 levels in all.
    let Texture::Image { image: 4, .. } = t.textures[9] else { panic!("{:?}", t.textures[9]) };
    assert_eq!(t.images.len(), 6);
    assert_eq!(t.images[4].texel(0, 0)[1], srgb8_to_linear()[128]);
    assert!(t.bindings.is_empty());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn material_parameters_bind_textures() {
    let dir = temp_dir("tex-bind");
    let l = load(
        &dir,
        &format!(
            "Texture \"c\" \"spectrum\" \"checkerboard\"\n\
             Texture \"r\" \"float\" \"checkerboard\" \"float tex1\" 0.5 \"float tex2\" 0.1\n\
             Material \"diffuse\" \"texture reflectance\" \"c\"\n{TRI}\n\
             Material \"conductor\" \"texture reflectance\" \"c\" \"texture roughness\" \"r\"\n{TRI}\n\
             Material \"conductor\" \"texture uroughness\" \"r\" \"float vroughness\" 0.09 \"bool remaproughness\" false\n{TRI}\n\
             Material \"dielectric\" \"texture roughness\" \"r\" \"float uroughness\" 0.09\n{TRI}\n\
             Material \"diffusetransmission\" \"texture reflectance\" \"c\" \"rgb transmittance\" [0.1 0.2 0.3] \"float scale\" 2\n{TRI}\n\
             MakeNamedMaterial \"shared\" \"string type\" \"diffuse\" \"texture reflectance\" \"c\"\n\
             MakeNamedMaterial \"unused\" \"string type\" \"diffuse\" \"texture reflectance\" \"c\"\n\
             NamedMaterial \"shared\"\n{TRI}\n{TRI}"
        ),
    );
    assert!(l.warnings.is_empty(), "{:#?}", warnings(&l));
    let s = &l.scene;
    let m = |i: usize| &s.materials[s.meshes[i].material as usize];
    use TexturedParam as P;
    // The materials keep pbrt's defaults where a texture overrides them.
    assert_eq!(bindings(&l, 0), [(P::Reflectance, 0, false)]);
    assert_eq!(*m(0), Material::default_diffuse());
    // Both roughnesses from one texture: one binding, remapped (pbrt's default).
    assert_eq!(bindings(&l, 1), [(P::Roughness, 1, true), (P::Reflectance, 0, false)]);
    let k = Material::conductor_k_from_reflectance(Rgb::ONE);
    assert_eq!(*m(1), Material::Conductor { eta: Rgb::ONE, k, alpha_x: 0.0, alpha_y: 0.0 });
    assert_eq!(bindings(&l, 2), [(P::URoughness, 1, false)]);
    let Material::Conductor { alpha_x, alpha_y, .. } = *m(2) else { panic!("{:?}", m(2)) };
    assert_eq!((alpha_x, alpha_y), (0.0, 0.09));
    // uroughness is a value, vroughness falls back to the roughness texture.
    assert_eq!(bindings(&l, 3), [(P::VRoughness, 1, true)]);
    assert_eq!(*m(3), Material::Dielectric { eta: 1.5, alpha_x: 0.3, alpha_y: 0.0 });
    // diffusetransmission's scale multiplies the texture (a Scale node) and the value.
    assert_eq!(bindings(&l, 4), [(P::Reflectance, 2, false)]);
    assert_eq!(
        s.textures.textures[2],
        Texture::Scale { tex: TexInput::Texture(0), scale: TexInput::Value(Rgb::splat(2.0)) }
    );
    assert_eq!(
        *m(4),
        Material::DiffuseTransmission {
            reflectance: Rgb::splat(0.25),
            transmittance: Rgb::new(0.2, 0.4, 0.6)
        }
    );
    // A named material used twice is one material with one binding; the unused one has none.
    assert_eq!(s.meshes[5].material, s.meshes[6].material);
    assert_eq!(bindings(&l, 5), [(P::Reflectance, 0, false)]);
    assert_eq!(s.textures.bindings.len(), 7);
    std::fs::remove_dir_all(&dir).ok();
}

/// As in pbrt-v4, an image that cannot be read stops the load at the
/// texture that names it (file, line and column), missing or corrupt.
#[test]
fn unreadable_images_are_errors_without_allow_missing() {
    let dir = temp_dir("tex-missing");
    write(&dir, "corrupt.png", b"not a png");
    for (file, why) in [("nowhere.png", "nowhere.png"), ("corrupt.png", "corrupt.png")] {
        let text =
            format!("WorldBegin\nTexture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"{file}\"\n");
        let e = load_str(&text, "t.pbrt", &dir).unwrap_err().to_string();
        assert!(e.starts_with("t.pbrt:2:1: texture \"t\": ") && e.contains(why), "{e}");
        assert!(e.contains("--allow-missing"), "{e}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn unreadable_and_unsupported_textures_warn_and_fall_back_to_constants() {
    let dir = temp_dir("tex-bad");
    write(&dir, "corrupt.png", b"not a png");
    let l = allowing_missing(|| {
        load(
            &dir,
            &format!(
                "Texture \"missing\" \"spectrum\" \"imagemap\" \"string filename\" \"nowhere.png\"\n\
             Texture \"corrupt\" \"float\" \"imagemap\" \"string filename\" \"corrupt.png\"\n\
             Texture \"ptexed\" \"spectrum\" \"ptex\" \"string filename\" \"x.ptx\"\n\
             Texture \"sphere\" \"spectrum\" \"checkerboard\" \"string mapping\" \"spherical\"\n\
             Texture \"uvs\" \"float\" \"uv\"\n\
             Material \"diffuse\" \"texture reflectance\" \"undefined\"\n{TRI}\n\
             Material \"diffuse\" \"texture reflectance\" \"corrupt\"\n{TRI}\n\
             Texture \"missing\" \"spectrum\" \"constant\"\n\
             Material \"diffuse\" \"texture reflectance\" \"missing\"\n{TRI}"
            ),
        )
    });
    let w = warnings(&l);
    let at = |line: u32, text: &str| {
        assert!(
            w.iter().any(|w| w.starts_with(&format!("t.pbrt:{line}:1: ")) && w.contains(text)),
            "{text}: {w:#?}"
        )
    };
    at(2, "texture \"missing\": ");
    at(2, "nowhere.png");
    at(3, "texture \"corrupt\": ");
    at(4, "texture \"ptexed\": class \"ptex\" is not supported; using a constant");
    at(6, "texture \"uvs\": class \"uv\" is not supported; using a constant");
    at(7, "spectrum texture \"undefined\" is not defined before this line; \"reflectance\" uses its default");
    at(9, "\"corrupt\" is not a spectrum texture");
    at(11, "texture \"missing\" is defined again");
    assert!(w.iter().all(|w| w.ends_with("using a constant") || !w.contains("png")), "{w:#?}");
    assert_eq!(w.len(), 7, "{w:#?}");
    let t = &l.scene.textures;
    assert!(t.images.is_empty());
    let grey = Texture::Constant(Rgb::splat(0.5));
    let one = Texture::Constant(Rgb::ONE);
    assert_eq!(t.textures[..3], [grey.clone(), one.clone(), grey]);
    // The spherical mapping is pbrt-v4's, in the texture's space (here the world's).
    let Texture::Checkerboard { mapping: TexMapping::Spherical { texture_from_world }, .. } = t.textures[3]
    else {
        panic!("{:?}", t.textures[3])
    };
    assert_eq!(texture_from_world, glam::Affine3A::IDENTITY);
    assert_eq!(t.textures[4], one);
    assert!(bindings(&l, 0).is_empty() && bindings(&l, 1).is_empty());
    // The later definition is the one used after it.
    assert_eq!(bindings(&l, 2), [(TexturedParam::Reflectance, 5, false)]);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_texture_parameters_are_errors() {
    let dir = temp_dir("tex-err");
    for (world, message) in [
        (
            "Texture \"a\" \"spectrum\" \"imagemap\" \"string filename\" \"x.png\" \"string wrap\" \"spiral\"",
            "t.pbrt:2:1: texture \"a\": unknown wrap mode \"spiral\"",
        ),
        (
            "Texture \"a\" \"spectrum\" \"imagemap\" \"string filename\" \"x.png\" \"string encoding\" \"log\"",
            "t.pbrt:2:1: texture \"a\": unknown encoding \"log\"",
        ),
        ("Texture \"a\" \"normal\" \"constant\"", "t.pbrt:2:1: Texture \"a\": type must be \"float\" or \"spectrum\""),
        (
            "Texture \"a\" \"float\" \"checkerboard\" \"integer dimension\" 4",
            "t.pbrt:2:1: texture \"a\": \"dimension\" must be 2 or 3, found 4",
        ),
        (
            "Texture \"a\" \"float\" \"fbm\" \"integer octaves\" -1",
            "t.pbrt:2:1: texture \"a\": \"octaves\" must not be negative, found -1",
        ),
    ] {
        let e = load_str(&format!("WorldBegin\n{world}\n"), "t.pbrt", &dir).unwrap_err();
        assert!(e.to_string().starts_with(message), "{e}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn shape_alpha_constant_and_textured() {
    let dir = temp_dir("tex-alpha");
    let l = load(
        &dir,
        &format!(
            "Texture \"mask\" \"float\" \"checkerboard\"\n\
             Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"float alpha\" 0.5\n\
             Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"float alpha\" 1\n\
             Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"texture alpha\" \"mask\"\n\
             AttributeBegin\nAttribute \"shape\" \"float alpha\" 0\n{TRI}\nAttributeEnd\n\
             Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"texture alpha\" \"nomask\"\n{TRI}"
        ),
    );
    let s = &l.scene;
    let t = &s.textures.textures;
    let stochastic = |texture| Some(MeshAlpha { texture, mode: AlphaMode::Stochastic });
    assert_eq!(s.meshes[0].alpha, stochastic(1));
    assert_eq!(t[1], Texture::Constant(Rgb::splat(0.5)));
    assert_eq!(s.meshes[1].alpha, None, "alpha 1 is pbrt's default: no mask");
    // A mesh without uvs keeps none: the renderer reads pbrt's per-triangle defaults.
    assert_eq!(s.meshes[2].alpha, stochastic(0));
    assert!(s.meshes[2].uvs.is_empty());
    assert_eq!(s.meshes[3].alpha, stochastic(2));
    assert_eq!(t[2], Texture::Constant(Rgb::ZERO));
    assert_eq!((s.meshes[4].alpha, s.meshes[5].alpha), (None, None));
    let w = warnings(&l);
    assert_eq!(w.len(), 1, "{w:#?}");
    assert!(
        w[0].starts_with("t.pbrt:10:1: shape \"trianglemesh\": float texture \"nomask\" is not defined"),
        "{w:#?}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn obj_map_kd_map_d_and_dissolve() {
    let dir = temp_dir("tex-obj");
    png(&dir, "leaf.png");
    image::RgbImage::from_pixel(2, 2, image::Rgb([10, 20, 30])).save(dir.join("wall.png")).unwrap();
    image::GrayImage::from_pixel(2, 2, image::Luma([200])).save(dir.join("mask.png")).unwrap();
    write(
        &dir,
        "m.mtl",
        "newmtl leaf\nKd 1 1 1\nmap_Kd leaf.png\n\
         newmtl fence\nKd 0.5 0.5 0.5\nmap_Kd -s 2 2 1 -o 0.5 0 -clamp on .\\wall.png\nmap_d mask.png\n\
         newmtl veil\nKd 0.8 0.8 0.8\nd 0.25\n\
         newmtl chrome\nKd 0.1 0.1 0.1\nKs 0.9 0.9 0.9\nNs 900\nmap_Kd wall.png\n",
    );
    let obj = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n\
               o a\nusemtl leaf\nf 1/1 2/2 3/3\no b\nusemtl fence\nf 1/1 2/2 3/3\n\
               o c\nusemtl veil\nf 1 2 3\no d\nusemtl chrome\nf 1/1 2/2 3/3\n";
    let l = load_any(&write(&dir, "m.obj", obj)).unwrap_or_else(|e| panic!("{e}"));
    let s = &l.scene;
    let t = &s.textures;
    // leaf.png (sRGB), wall.png (sRGB, once for two materials), mask.png (linear).
    assert_eq!(t.images.len(), 3);
    assert!(matches!(t.images[2].texels, Texels::Rgba8 { srgb: false, .. }));
    // leaf: Kd 1 binds the image itself; its alpha channel cuts the mesh.
    let leaf = &s.meshes[0];
    assert_eq!(bindings(&l, 0), [(TexturedParam::Reflectance, 0, false)]);
    assert_eq!(
        t.textures[0],
        Texture::Image {
            image: 0,
            mapping: UvMapping::default().into(),
            wrap: Wrap::Repeat,
            channel: Channel::Rgb,
            scale: 1.0,
            invert: false,
            filter: ImageFilter::None,
            levels: 1,
        }
    );
    let Some(MeshAlpha { texture, mode: AlphaMode::Cutoff(c) }) = leaf.alpha else {
        panic!("{:?}", leaf.alpha)
    };
    assert_eq!(c, 0.5);
    assert!(matches!(t.textures[texture as usize], Texture::Image { image: 0, channel: Channel::Alpha, .. }));
    // fence: Kd × map_Kd with its options; map_d, a grey image, cuts by its mean.
    let [(TexturedParam::Reflectance, scaled, false)] = bindings(&l, 1)[..] else {
        panic!("{:?}", bindings(&l, 1))
    };
    let Texture::Scale { tex: TexInput::Texture(wall), scale } = t.textures[scaled as usize] else {
        panic!()
    };
    assert_eq!(scale, TexInput::Value(Rgb::splat(0.5)));
    let mapping = UvMapping { su: 2.0, sv: 2.0, du: 0.5, dv: 0.0 };
    let Texture::Image { image: 1, mapping: m, wrap: Wrap::Clamp, channel: Channel::Rgb, .. } =
        t.textures[wall as usize]
    else {
        panic!("{:?}", t.textures[wall as usize])
    };
    assert_eq!(m, mapping.into());
    let fence = s.meshes[1].alpha.unwrap();
    assert_eq!(fence.mode, AlphaMode::Cutoff(0.5));
    assert!(matches!(
        t.textures[fence.texture as usize],
        Texture::Image { image: 2, channel: Channel::Average, .. }
    ));
    // veil: d 0.25 is a stochastic constant alpha, and no uvs are needed for it.
    let veil = s.meshes[2].alpha.unwrap();
    assert_eq!(veil.mode, AlphaMode::Stochastic);
    assert_eq!(t.textures[veil.texture as usize], Texture::Constant(Rgb::splat(0.25)));
    // chrome became a conductor: its map_Kd is ignored with a warning.
    assert!(matches!(s.materials[s.meshes[3].material as usize], Material::Conductor { .. }));
    assert!(bindings(&l, 3).is_empty());
    let w = warnings(&l);
    assert_eq!(w.len(), 1, "{w:#?}");
    assert!(w[0].contains("material 'chrome': map_Kd is ignored"), "{w:#?}");
    // At the line that defines the material, in its library.
    assert!(w[0].contains("m.mtl:11:1"), "{w:#?}");
    std::fs::remove_dir_all(&dir).ok();
}

/// An area light's `filename` scales its emission by the image (sRGB,
/// clamped, times `scale`); a missing image is an error, or with
/// `--allow-missing` warns and emits `scale`.
#[test]
fn area_light_images_bind_emission_textures() {
    let dir = temp_dir("tex-emission");
    png(&dir, "e.png");
    let world = format!(
        "AttributeBegin\nAreaLightSource \"diffuse\" \"string filename\" \"e.png\" \"float scale\" 2\n{TRI}\nAttributeEnd\n\
         AttributeBegin\nAreaLightSource \"diffuse\" \"string filename\" \"nope.png\" \"rgb L\" [1 1 1]\n{TRI}\nAttributeEnd\n{TRI}"
    );
    let e = load_str(&format!("WorldBegin\n{world}\n"), "t.pbrt", &dir).unwrap_err().to_string();
    assert!(e.starts_with("t.pbrt:7:1: area light image: ") && e.contains("nope.png"), "{e}");
    let l = allowing_missing(|| load(&dir, &world));
    let s = &l.scene;
    assert_eq!(s.meshes[0].emission.map(|e| e.radiance), Some(Rgb::splat(2.0)));
    let t = s.textures.emission_of(0).expect("first light is textured");
    match &s.textures.textures[t as usize] {
        Texture::Image { image, wrap, channel, scale, .. } => {
            assert_eq!((*wrap, *channel, *scale), (Wrap::Clamp, Channel::Rgb, 1.0));
            let img = &s.textures.images[*image as usize];
            assert_eq!(img.texel(0, 0), [1.0, srgb8_to_linear()[128], 0.0, 1.0]);
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(s.textures.emission_of(1), None);
    assert_eq!(s.textures.emission_of(2), None);
    let w = warnings(&l).join("\n");
    assert!(w.contains("t.pbrt:7") && w.contains("nope.png"), "{w}");
    assert!(w.contains("both \"L\" and \"filename\""), "{w}");
}

/// coateddiffuse's medium parameters may be textures too: bound per hit,
/// the material keeping pbrt's defaults.
#[test]
fn coated_diffuse_medium_textures_are_bound() {
    let dir = temp_dir("tex-coated");
    let l = load(
        &dir,
        &format!(
            "Texture \"f\" \"float\" \"constant\" \"float value\" 0.3\n\
             Texture \"c\" \"spectrum\" \"constant\" \"rgb value\" [0.9 0.5 0.1]\n\
             Material \"coateddiffuse\" \"texture thickness\" \"f\" \"texture albedo\" \"c\" \"texture g\" \"f\"\n{TRI}"
        ),
    );
    let mut bound: Vec<TexturedParam> = bindings(&l, 0).into_iter().map(|(p, _, _)| p).collect();
    bound.sort_by_key(|p| *p as u32);
    assert_eq!(bound, [TexturedParam::Thickness, TexturedParam::Albedo, TexturedParam::G]);
    let Material::CoatedDiffuse(CoatedDiffuseParams { coating: c, .. }) =
        l.scene.materials[l.scene.meshes[0].material as usize]
    else {
        panic!()
    };
    assert_eq!((c.thickness, c.albedo, c.g), (0.01, Rgb::ZERO, 0.0));
    assert!(l.warnings.is_empty(), "{:?}", warnings(&l));
}

/// A conductor's `eta` and `k` may be spectrum textures (pbrt-v4): bound
/// per hit, copper's values kept in the material.
#[test]
fn conductor_eta_and_k_textures_are_bound() {
    let dir = temp_dir("tex-conductor");
    let l = load(
        &dir,
        &format!(
            "Texture \"e\" \"spectrum\" \"constant\" \"rgb value\" [0.2 0.9 1.1]\n\
             Material \"conductor\" \"texture eta\" \"e\" \"texture k\" \"e\"\n{TRI}"
        ),
    );
    let bound: Vec<TexturedParam> = bindings(&l, 0).into_iter().map(|(p, _, _)| p).collect();
    assert_eq!(bound, [TexturedParam::Eta, TexturedParam::K]);
    assert!(l.warnings.is_empty(), "{:?}", warnings(&l));
}

/// A `mix` material's `amount` may be a float texture (pbrt-v4): bound to
/// the mix, chosen per hit; the constant stays 0.5.
#[test]
fn mix_amount_textures_are_bound() {
    let dir = temp_dir("tex-mix");
    let l = load(
        &dir,
        &format!(
            "Texture \"f\" \"float\" \"checkerboard\" \"float tex1\" 0 \"float tex2\" 1\n\
             MakeNamedMaterial \"a\" \"string type\" \"diffuse\"\n\
             MakeNamedMaterial \"b\" \"string type\" \"conductor\"\n\
             Material \"mix\" \"string materials\" [\"a\" \"b\"] \"texture amount\" \"f\"\n{TRI}"
        ),
    );
    let bound: Vec<TexturedParam> = bindings(&l, 0).into_iter().map(|(p, _, _)| p).collect();
    assert_eq!(bound, [TexturedParam::Amount]);
    let Material::Mix { amount, .. } = l.scene.materials[l.scene.meshes[0].material as usize] else {
        panic!()
    };
    assert_eq!(amount, 0.5);
    assert!(l.warnings.is_empty(), "{:?}", warnings(&l));
}

/// pbrt-v4's planar mapping: `v1`, `v2`, `udelta`, `vdelta`, in the space
/// of the transform current at the `Texture` statement.
#[test]
fn planar_mappings_take_the_textures_transform() {
    let dir = temp_dir("tex-planar");
    let l = load(
        &dir,
        "AttributeBegin\nTranslate 1 2 3\n\
         Texture \"p\" \"float\" \"checkerboard\" \"string mapping\" \"planar\" \"vector3 v1\" [0 0 2] \"float udelta\" 0.5\n\
         AttributeEnd\n\
         Texture \"c\" \"float\" \"checkerboard\" \"string mapping\" \"cylindrical\"",
    );
    assert!(warnings(&l).is_empty(), "{:?}", warnings(&l));
    let t = &l.scene.textures.textures;
    let Texture::Checkerboard { mapping: TexMapping::Planar { texture_from_world, vs, vt, ds, dt }, .. } =
        t[0]
    else {
        panic!("{:?}", t[0])
    };
    assert_eq!(texture_from_world, glam::Affine3A::from_translation(glam::Vec3::new(-1.0, -2.0, -3.0)));
    assert_eq!((vs, vt, ds, dt), (glam::Vec3::new(0.0, 0.0, 2.0), glam::Vec3::Y, 0.5, 0.0));
    let Texture::Checkerboard { mapping: TexMapping::Cylindrical { texture_from_world }, .. } = t[1] else {
        panic!("{:?}", t[1])
    };
    assert_eq!(texture_from_world, glam::Affine3A::IDENTITY);
    std::fs::remove_dir_all(&dir).ok();
}

/// A material's `displacement` texture (pbrt-v3's `bumpmap`) and its
/// `normalmap` image (read linearly) bind to it; a missing normal map is an
/// error unless allowed.
#[test]
fn bump_and_normal_maps_bind_to_their_materials() {
    let dir = temp_dir("tex-bump");
    png(&dir, "n.png");
    let l = load(
        &dir,
        &format!(
            "Texture \"d\" \"float\" \"checkerboard\"\n\
             Material \"diffuse\" \"texture displacement\" \"d\"\n{TRI}\n\
             Material \"conductor\" \"string normalmap\" \"n.png\"\n{TRI}"
        ),
    );
    assert!(warnings(&l).is_empty(), "{:?}", warnings(&l));
    let s = &l.scene;
    let bound = |mesh: usize| -> Vec<(TexturedParam, u32)> {
        s.textures.bindings_of(s.meshes[mesh].material).map(|b| (b.param, b.texture)).collect()
    };
    assert_eq!(bound(0), [(TexturedParam::Displacement, 0)]);
    assert_eq!(bound(1), [(TexturedParam::NormalMap, 1)]);
    // Linear: the texel's 8-bit value over 255, no sRGB curve.
    assert_eq!(s.textures.images[0].texel(0, 0)[1], 128.0 / 255.0);
    let world = format!("Material \"diffuse\" \"string normalmap\" \"gone.png\"\n{TRI}");
    let e = load_str(&format!("WorldBegin\n{world}\n"), "t.pbrt", &dir).unwrap_err().to_string();
    assert!(e.starts_with("t.pbrt:2:1: Material \"diffuse\": normal map: ") && e.contains("gone.png"), "{e}");
    let l = allowing_missing(|| load(&dir, &world));
    assert!(warnings(&l)[0].contains("the shading normal is not bent"), "{:?}", warnings(&l));
    std::fs::remove_dir_all(&dir).ok();
}

/// pbrt-v4's `directionmix`: `tex1` where the normal is along `dir` (in the
/// texture's space), `tex2` across it: a mix of [tex2, tex1] by `|n · dir|`.
#[test]
fn direction_mixes_mix_by_the_facing_amount() {
    let dir = temp_dir("tex-dirmix");
    let l = load(
        &dir,
        "AttributeBegin\nRotate 90 1 0 0\n\
         Texture \"d\" \"spectrum\" \"directionmix\" \"rgb tex1\" [1 0 0] \"rgb tex2\" [0 0 1] \"vector3 dir\" [0 1 0]\n\
         AttributeEnd",
    );
    assert!(warnings(&l).is_empty(), "{:?}", warnings(&l));
    let t = &l.scene.textures.textures;
    let Texture::Facing { direction } = t[0] else { panic!("{:?}", t[0]) };
    assert!((direction - glam::Vec3::Z).length() < 1e-6, "Rotate 90 about x turns +y to +z: {direction}");
    assert_eq!(
        t[1],
        Texture::Mix {
            tex: [TexInput::Value(Rgb::new(0.0, 0.0, 1.0)), TexInput::Value(Rgb::new(1.0, 0.0, 0.0))],
            amount: TexInput::Texture(0),
        }
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn noise_textures_take_pbrts_parameters_and_defaults() {
    use atoll_scene::Noise;
    let dir = temp_dir("tex-noise");
    let l = load(
        &dir,
        "Texture \"f\" \"float\" \"fbm\"\n\
         Texture \"w\" \"float\" \"wrinkled\" \"integer octaves\" 4 \"float roughness\" 0.7\n\
         AttributeBegin\nTranslate 1 2 3\n\
         Texture \"wind\" \"float\" \"windy\"\n\
         Texture \"m\" \"spectrum\" \"marble\" \"float scale\" 3 \"float variation\" 0.5\n\
         AttributeEnd\n\
         Texture \"d\" \"spectrum\" \"dots\" \"texture inside\" \"m\" \"float uscale\" 4\n\
         Texture \"many\" \"float\" \"fbm\" \"integer octaves\" 100",
    );
    let w = warnings(&l);
    assert_eq!(w.len(), 1, "{w:#?}");
    assert!(w[0].starts_with("t.pbrt:10:1: texture \"many\": 100 octaves; summing the first 32"), "{w:#?}");
    let t = &l.scene.textures.textures;
    let identity = glam::Affine3A::IDENTITY;
    let shifted = glam::Affine3A::from_translation(glam::Vec3::new(-1.0, -2.0, -3.0));
    let noise = |i: usize| match t[i] {
        Texture::Noise { noise, texture_from_world } => (noise, texture_from_world),
        ref other => panic!("texture {i}: {other:?}"),
    };
    assert_eq!(noise(0), (Noise::Fbm { octaves: 8, omega: 0.5 }, identity));
    assert_eq!(noise(1), (Noise::Wrinkled { octaves: 4, omega: 0.7 }, identity));
    // The noise textures read the point in the space of their statement.
    assert_eq!(noise(2), (Noise::Windy, shifted));
    assert_eq!(noise(3), (Noise::Marble { octaves: 8, omega: 0.5, scale: 3.0, variation: 0.5 }, shifted));
    assert_eq!(
        t[4],
        Texture::Dots {
            mapping: TexMapping::Uv(UvMapping { su: 4.0, sv: 1.0, du: 0.0, dv: 0.0 }),
            tex: [TexInput::Texture(3), TexInput::Value(Rgb::ZERO)],
        }
    );
    assert_eq!(noise(5).0, Noise::Fbm { octaves: 32, omega: 0.5 });
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bilerp_and_solid_checkerboards_take_pbrts_parameters() {
    let dir = temp_dir("tex-bilerp");
    let l = load(
        &dir,
        "Texture \"b\" \"spectrum\" \"bilerp\" \"rgb v00\" [1 0 0] \"rgb v11\" [0 0 1] \"float uscale\" 2\n\
         Texture \"f\" \"float\" \"bilerp\"\n\
         AttributeBegin\nScale 2 2 2\n\
         Texture \"c\" \"float\" \"checkerboard\" \"integer dimension\" 3 \"float tex2\" 0.25\n\
         AttributeEnd",
    );
    assert!(warnings(&l).is_empty(), "{:?}", warnings(&l));
    let t = &l.scene.textures.textures;
    let v = |r: f32, g: f32, b: f32| TexInput::Value(Rgb::new(r, g, b));
    assert_eq!(
        t[0],
        Texture::Bilerp {
            mapping: TexMapping::Uv(UvMapping { su: 2.0, sv: 1.0, du: 0.0, dv: 0.0 }),
            // v00, v10, v01, v11 (pbrt's defaults 0, 0, 1, 1 where not given).
            corners: [v(1.0, 0.0, 0.0), v(0.0, 0.0, 0.0), v(1.0, 1.0, 1.0), v(0.0, 0.0, 1.0)],
        }
    );
    let Texture::Bilerp { corners, .. } = t[1] else { panic!("{:?}", t[1]) };
    assert_eq!(corners, [v(0.0, 0.0, 0.0), v(0.0, 0.0, 0.0), v(1.0, 1.0, 1.0), v(1.0, 1.0, 1.0)]);
    assert_eq!(
        t[2],
        Texture::SolidCheckerboard {
            texture_from_world: glam::Affine3A::from_scale(glam::Vec3::splat(0.5)),
            tex: [v(1.0, 1.0, 1.0), v(0.25, 0.25, 0.25)],
        }
    );
    std::fs::remove_dir_all(&dir).ok();
}
