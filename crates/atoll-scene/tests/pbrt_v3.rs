//! pbrt-v3 scenes: v3 materials mapped to atoll's with one warning each,
//! textures bound to the mapped materials, `mix`, v3 spellings of types, Booleans,
//! films, cameras and lights, and skipped curves counted.

mod common;

use atoll_scene::pbrt::load_str;
use atoll_scene::texture::srgb8_to_linear;
use atoll_scene::{
    Channel, CoatedDiffuseParams, Coating, HairParams, Light, Material, PrincipledParams, Rgb, TexInput,
    Texture, TexturedParam,
};
use common::{allowing_missing, assert_close};
use std::path::Path;

const TRI: &str = "Shape \"trianglemesh\" \"point P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]";

/// A pbrt-v3 scene with one triangle per material statement in `materials`.
fn v3_scene(materials: &[&str]) -> String {
    let mut s = String::from(
        "LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [45] \"float frameaspectratio\" [1.5]\n\
         Film \"image\" \"integer xresolution\" [400] \"integer yresolution\" [300] \"string filename\" \"v3.exr\"\n\
         Sampler \"halton\" \"integer pixelsamples\" [8]\nIntegrator \"path\" \"integer maxdepth\" [6]\nWorldBegin\n",
    );
    for m in materials {
        s += &format!("AttributeBegin\n{m}\n{TRI}\nAttributeEnd\n");
    }
    s + "WorldEnd\n"
}

#[test]
fn every_v3_material_maps_with_one_warning_naming_its_line() {
    let materials = [
        "Material \"matte\" \"color Kd\" [0.1 0.2 0.3]",
        "Material \"plastic\" \"rgb Kd\" [0.4 0.4 0.4] \"rgb Ks\" [0.5 0.5 0.5] \"float roughness\" 0.1",
        "Material \"substrate\" \"rgb Kd\" [0.3 0.2 0.1] \"float uroughness\" 0.2",
        "Material \"uber\" \"rgb Kd\" [0.6 0.5 0.4] \"rgb Kr\" [0.1 0.1 0.1] \"rgb opacity\" [1 1 1]",
        "Material \"translucent\" \"rgb Kd\" [0.7 0.7 0.7] \"rgb reflect\" [0.5 0.5 0.5]",
        "Material \"metal\" \"spectrum eta\" \"metal-Au-eta\" \"spectrum k\" \"metal-Au-k\" \"float roughness\" 0.04",
        "Material \"glass\" \"float index\" 1.33",
        "Material \"mirror\" \"rgb Kr\" [0.8 0.8 0.8]",
        "Material \"fourier\" \"string bsdffile\" \"paint.bsdf\"",
        "Material \"kdsubsurface\" \"rgb Kd\" [0.9 0.8 0.7] \"float mfp\" 1",
        "Material \"disney\" \"rgb color\" [0.2 0.4 0.6] \"float metallic\" 1 \"float roughness\" 0.5 \"float anisotropic\" 0.3",
        "Material \"hair\" \"rgb color\" [0.3 0.2 0.1]",
        "Material \"metal\"",
        "Material \"glass\" \"bool remaproughness\" \"false\" \"float uroughness\" 0.01 \"float vroughness\" 0.04",
    ];
    let text = v3_scene(&materials);
    let loaded = load_str(&text, "v3.pbrt", Path::new(".")).unwrap();
    let s = &loaded.scene;
    let m: Vec<&Material> = s.meshes.iter().map(|mesh| &s.materials[mesh.material as usize]).collect();
    assert_eq!(m.len(), materials.len());
    let diffuse = |r: [f32; 3]| Material::Diffuse { reflectance: Rgb::from(r) };
    assert_eq!(*m[0], diffuse([0.1, 0.2, 0.3]));
    // plastic and substrate: coateddiffuse, as pbrt-v4's upgrade does, with v3's defaults.
    let coated = |r: [f32; 3], ax: f32, ay: f32| {
        Material::CoatedDiffuse(CoatedDiffuseParams {
            reflectance: Rgb::from(r),
            coating: Coating {
                alpha_x: Material::roughness_to_alpha(ax),
                alpha_y: Material::roughness_to_alpha(ay),
                ..Coating::PBRT_DEFAULT
            },
        })
    };
    assert_eq!(*m[1], coated([0.4, 0.4, 0.4], 0.1, 0.1));
    assert_eq!(*m[2], coated([0.3, 0.2, 0.1], 0.2, 0.1));
    assert_eq!(*m[3], diffuse([0.6, 0.5, 0.4]));
    assert_eq!(
        *m[4],
        Material::DiffuseTransmission { reflectance: Rgb::splat(0.35), transmittance: Rgb::splat(0.35) }
    );
    let au = (Rgb::new(0.143119, 0.374957, 1.44248), Rgb::new(3.98316, 2.38572, 1.60322));
    assert_eq!(*m[5], Material::Conductor { eta: au.0, k: au.1, alpha_x: 0.2, alpha_y: 0.2 });
    assert_eq!(*m[6], Material::Dielectric { eta: 1.33, alpha_x: 0.0, alpha_y: 0.0 });
    let k = Material::conductor_k_from_reflectance(Rgb::splat(0.8));
    assert_eq!(*m[7], Material::Conductor { eta: Rgb::ONE, k, alpha_x: 0.0, alpha_y: 0.0 });
    assert_eq!(*m[8], Material::default_diffuse());
    assert_eq!(*m[9], diffuse([0.9, 0.8, 0.7]));
    // disney: principled with pbrt-v3's defaults; the anisotropy is what it warns about.
    let principled = Material::Principled(PrincipledParams {
        base_color: Rgb::new(0.2, 0.4, 0.6),
        metallic: 1.0,
        roughness: 0.5,
        specular: Material::specular_from_eta(1.5),
        specular_tint: 0.0,
        sheen: 0.0,
        sheen_tint: 0.5,
        clearcoat: 0.0,
        clearcoat_gloss: 1.0,
        transmission: 0.0,
        eta: 1.5,
    });
    assert_eq!(*m[10], principled);
    // hair is pbrt-v4's, its `color` the reflectance it is fitted to.
    let sigma_a = HairParams::sigma_a_from_reflectance(Rgb::new(0.3, 0.2, 0.1), 0.3);
    assert_eq!(*m[11], Material::Hair(HairParams { sigma_a, ..HairParams::pbrt_default() }));
    // v3 metal defaults: copper, roughness 0.01 remapped to alpha 0.1.
    let Material::Conductor { alpha_x, eta, .. } = m[12] else { panic!("{:?}", m[12]) };
    assert!((alpha_x - 0.1).abs() < 1e-6 && (eta.x - 0.200438).abs() < 1e-6);
    assert_eq!(*m[13], Material::Dielectric { eta: 1.5, alpha_x: 0.01, alpha_y: 0.04 });

    // One warning per mapped material (all but hair), at its Material
    // statement (line 7 + 4 per block).
    let mapped: Vec<_> = loaded.warnings.iter().filter(|w| w.message.contains("material \"")).collect();
    let lines: Vec<u32> = mapped.iter().map(|w| w.line).collect();
    let expected: Vec<u32> = (0..materials.len() as u32).filter(|&i| i != 11).map(|i| 8 + 4 * i).collect();
    assert_eq!(lines, expected, "{mapped:#?}");
    assert!(mapped[0]
        .message
        .starts_with("pbrt-v3 material \"matte\" is not supported; read as \"diffuse\""));
    assert!(mapped[1].message.contains("read as \"coateddiffuse\""), "{}", mapped[1]);
    assert!(mapped[3].message.contains("specular layer dropped"), "{}", mapped[3]);
    assert!(mapped[10].message.ends_with("principled material without anisotropy"), "{}", mapped[10]);
    // The mapping's warning covers the parameters it does not use.
    assert!(
        !loaded.warnings.iter().any(|w| w.message.contains("unused parameter")),
        "{:#?}",
        loaded.warnings
    );
    // v3 type spellings are reported once each, not once per use.
    let point = loaded.warnings.iter().filter(|w| w.message.contains("type 'point'")).count();
    assert_eq!(point, 1);
}

#[test]
fn v3_options_film_camera_and_booleans() {
    let loaded = load_str(&v3_scene(&["Material \"matte\""]), "v3.pbrt", Path::new(".")).unwrap();
    let st = &loaded.scene.settings;
    assert_eq!((st.film.resolution.x, st.film.resolution.y, st.spp), (400, 300, 8));
    assert_eq!(st.film.filename.as_deref(), Some("v3.exr"));
    assert_eq!((st.camera.fov_degrees, st.camera.frame_aspect_ratio), (45.0, Some(1.5)));
    let w: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    assert!(w.iter().any(|w| w.contains("WorldEnd is pbrt-v3 syntax")), "{w:#?}");
    assert!(w.iter().any(|w| w.contains("type 'point' is pbrt-v3 syntax")), "{w:#?}");
}

#[test]
fn v3_textures_bind_to_the_mapped_materials() {
    let dir = common::temp_dir("v3-textures");
    std::fs::create_dir_all(dir.join("textures")).unwrap();
    image::RgbImage::from_pixel(2, 2, image::Rgb([255, 128, 0])).save(dir.join("textures/wood.png")).unwrap();
    let text = "WorldBegin\n\
        Texture \"wood\" \"color\" \"imagemap\" \"string filename\" \"textures/wood.png\" \"bool trilinear\" \"true\"\n\
        Texture \"raw\" \"color\" \"imagemap\" \"string filename\" \"textures/wood.png\" \"bool gamma\" \"false\"\n\
        Texture \"bump\" \"float\" \"imagemap\" \"string filename\" \"textures/bump.png\"\n\
        Texture \"tint\" \"color\" \"scale\" \"texture tex1\" \"wood\" \"color tex2\" [0.5 0.5 0.5]\n\
        Material \"matte\" \"texture Kd\" \"wood\" \"texture bumpmap\" \"bump\"\n"
        .to_string()
        + TRI
        + "\nMaterial \"translucent\" \"texture Kd\" \"tint\" \"color transmit\" [0.25 0.25 0.25]\n"
        + TRI
        + "\nMaterial \"plastic\" \"texture Kd\" \"raw\" \"texture bumpmap\" \"bump\"\n"
        + TRI;
    // bump.png is missing: an error, unless allowed (it would be ignored anyway).
    assert!(load_str(&text, "t.pbrt", &dir).unwrap_err().to_string().starts_with("t.pbrt:4:1: "));
    let loaded = allowing_missing(|| load_str(&text, "t.pbrt", &dir)).unwrap();
    let s = &loaded.scene;
    let t = &s.textures;
    // One file, decoded once per encoding: sRGB by default (pbrt-v3's
    // `gamma` for PNG), linear for "raw"; each a MIP pyramid of 2 levels.
    assert_eq!(t.images.len(), 4);
    assert_eq!(t.images[0].texel(1, 1), [1.0, srgb8_to_linear()[128], 0.0, 1.0]);
    assert_eq!(t.images[2].texel(0, 0)[1], 128.0 / 255.0);
    assert!(matches!(t.textures[0], Texture::Image { image: 0, channel: Channel::Rgb, levels: 2, .. }));
    assert!(matches!(t.textures[1], Texture::Image { image: 2, levels: 2, .. }));
    // The missing bump map became a float constant 1 (allowed missing): a
    // displacement that bends nothing, bound as pbrt-v3's `bumpmap`.
    assert_eq!(t.textures[2], Texture::Constant(Rgb::ONE));
    assert_eq!(
        t.textures[3],
        Texture::Scale { tex: TexInput::Texture(0), scale: TexInput::Value(Rgb::splat(0.5)) }
    );
    let bindings = |mesh: usize| -> Vec<(TexturedParam, u32)> {
        t.bindings_of(s.meshes[mesh].material).map(|b| (b.param, b.texture)).collect()
    };
    assert_eq!(bindings(0), [(TexturedParam::Reflectance, 0), (TexturedParam::Displacement, 2)]);
    assert_eq!(
        s.materials[s.meshes[0].material as usize],
        Material::Diffuse { reflectance: Rgb::splat(0.5) }
    );
    // translucent: Kd × reflect (0.5 default) and Kd × transmit, as Scale nodes over "tint".
    assert_eq!(bindings(1), [(TexturedParam::Reflectance, 4), (TexturedParam::Transmittance, 5)]);
    assert_eq!(
        t.textures[4],
        Texture::Scale { tex: TexInput::Texture(3), scale: TexInput::Value(Rgb::splat(0.5)) }
    );
    assert_eq!(
        t.textures[5],
        Texture::Scale { tex: TexInput::Texture(3), scale: TexInput::Value(Rgb::splat(0.25)) }
    );
    assert_eq!(bindings(2), [(TexturedParam::Reflectance, 1), (TexturedParam::Displacement, 2)]);
    let w: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    let missing = w.iter().find(|w| w.contains("bump.png")).expect("a warning for the missing file");
    assert!(
        missing.starts_with("t.pbrt:4:1: texture \"bump\": ") && missing.ends_with("; using a constant"),
        "{w:#?}"
    );
    assert!(!w.iter().any(|w| w.contains("unused") || w.contains("trilinear")), "{w:#?}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn mix_materials_name_their_two_parts() {
    let text = "WorldBegin\n\
        MakeNamedMaterial \"red\" \"string type\" \"matte\" \"rgb Kd\" [0.8 0.1 0.1]\n\
        MakeNamedMaterial \"chrome\" \"string type\" \"mirror\"\n\
        MakeNamedMaterial \"blend\" \"string type\" \"mix\" \"string namedmaterial1\" \"red\" \
        \"string namedmaterial2\" \"chrome\" \"rgb amount\" [0.5 0.5 0.5]\n\
        NamedMaterial \"blend\"\n"
        .to_string()
        + TRI
        + "\nMaterial \"mix\" \"string materials\" [\"chrome\" \"red\"] \"float amount\" 0.3\n"
        + TRI
        + "\nMaterial \"mix\" \"string materials\" [\"red\" \"nowhere\"]\n"
        + TRI;
    let loaded = load_str(&text, "m.pbrt", Path::new(".")).unwrap();
    let s = &loaded.scene;
    let material = |mesh: usize| &s.materials[s.meshes[mesh].material as usize];
    let Material::Mix { materials: [red, chrome], amount } = *material(0) else {
        panic!("{:?}", material(0))
    };
    assert_eq!(amount, 0.5);
    assert_eq!(s.materials[red as usize], Material::Diffuse { reflectance: Rgb::new(0.8, 0.1, 0.1) });
    assert!(matches!(s.materials[chrome as usize], Material::Conductor { .. }));
    assert_eq!(*material(1), Material::Mix { materials: [chrome, red], amount: 0.3 });
    let Material::Mix { materials: [_, missing], .. } = *material(2) else { panic!() };
    assert_eq!(s.materials[missing as usize], Material::default_diffuse());
    let w: Vec<String> =
        loaded.warnings.iter().filter(|w| w.message.contains("mix")).map(|w| w.to_string()).collect();
    assert_eq!(
        w,
        ["m.pbrt:9:1: Material \"mix\": material \"nowhere\" is not defined before it; using diffuse 0.5"]
    );
}

#[test]
fn unsupported_shapes_are_skipped_once_then_counted_and_curves_made() {
    let curve =
        "Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 1 1 0 0 1 0] \"float width\" 0.1 \"string type\" \"flat\"";
    let tri = TRI.replace("\"point P\"", "\"point3 P\"");
    let odd = "Shape \"hyperboloid\"";
    let text = format!("WorldBegin\n{tri}\n{odd}\n{odd}\n{odd}\n{curve}\n{curve}\n");
    let loaded = load_str(&text, "c.pbrt", Path::new(".")).unwrap();
    assert_eq!(loaded.scene.meshes.len(), 3, "the triangle and two curves");
    let w: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(w.len(), 2, "curves are no longer warned about: {w:#?}");
    assert_eq!(w[0], "c.pbrt:3:1: unsupported shape \"hyperboloid\" skipped");
    assert_eq!(w[1], "c.pbrt:3:1: 3 unsupported \"hyperboloid\" shapes skipped in all (the first is here)");
    assert!(loaded.scene.meshes[1].curves.is_some() && loaded.scene.meshes[2].curves.is_some());
}

#[test]
fn v3_lights() {
    let text = "WorldBegin\n\
        LightSource \"infinite\" \"string mapname\" \"sky.exr\" \"integer nsamples\" 4\n\
        LightSource \"distant\" \"blackbody L\" [5500 2] \"point from\" [0 1 0] \"point to\" [0 0 0]\n";
    assert!(load_str(text, "l.pbrt", Path::new(".")).unwrap_err().to_string().contains("sky.exr"));
    let loaded = allowing_missing(|| load_str(text, "l.pbrt", Path::new("."))).unwrap();
    let l = &loaded.scene.lights;
    assert_eq!(l[0], Light::Infinite { radiance: Rgb::ONE, portal: None });
    let Light::Distant { direction, radiance } = l[1] else { panic!("{:?}", l[1]) };
    assert_close(direction, -glam::Vec3::Y, 1e-6);
    // v3's (temperature, scale) blackbody: the colour of 5500 K at luminance 2.
    let lum = 0.2126 * radiance.x + 0.7152 * radiance.y + 0.0722 * radiance.z;
    assert!((lum - 2.0).abs() < 0.05 && radiance.x > radiance.z, "{radiance}");
    let w: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    // A missing map allowed: a warning naming it, constant white instead.
    assert!(w[0].contains("sky.exr") && w[0].contains("using constant white"), "{w:#?}");
    assert!(!w.iter().any(|w| w.contains("unused parameter")), "{w:#?}");
}

/// pbrt-v3's `disney`: every parameter read into the principled material
/// (silently when nothing is dropped), `color`/`metallic`/`roughness`
/// textures bound (roughness not remapped), what atoll does not model named
/// in one warning, and a bad `eta` an error at its line.
#[test]
fn disney_reads_as_the_principled_material() {
    let dir = common::temp_dir("v3-disney");
    image::RgbImage::from_pixel(2, 2, image::Rgb([255, 128, 0])).save(dir.join("mr.png")).unwrap();
    let full = "Material \"disney\" \"rgb color\" [0.8 0.5 0.2] \"float metallic\" 0.25 \"float eta\" 1.33 \
                \"float roughness\" 0.3 \"float speculartint\" 0.5 \"float sheen\" 0.75 \"float sheentint\" 0.25 \
                \"float clearcoat\" 0.5 \"float clearcoatgloss\" 0.6 \"float spectrans\" 0.4 \
                \"float flatness\" 0.2 \"float difftrans\" 0.5";
    let textured = "Texture \"m\" \"float\" \"imagemap\" \"string filename\" \"mr.png\"\n\
                    Texture \"c\" \"color\" \"imagemap\" \"string filename\" \"mr.png\"\n\
                    Material \"disney\" \"texture color\" \"c\" \"texture metallic\" \"m\" \"texture roughness\" \"m\" \
                    \"float specular\" 0.7";
    let dropped = "Material \"disney\" \"bool thin\" \"true\" \"rgb scatterdistance\" [1 1 1] \
                   \"texture sheen\" \"m\" \"float clearcoat\" 2";
    let loaded = load_str(&v3_scene(&[full, textured, dropped]), "d.pbrt", &dir).unwrap();
    let s = &loaded.scene;
    let m: Vec<&Material> = s.meshes.iter().map(|mesh| &s.materials[mesh.material as usize]).collect();
    let expected = Material::Principled(PrincipledParams {
        base_color: Rgb::new(0.8, 0.5, 0.2),
        metallic: 0.25,
        roughness: 0.3,
        specular: Material::specular_from_eta(1.33),
        specular_tint: 0.5,
        sheen: 0.75,
        sheen_tint: 0.25,
        clearcoat: 0.5,
        clearcoat_gloss: 0.6,
        transmission: 0.4,
        eta: 1.33,
    });
    assert_eq!(*m[0], expected);
    assert!((Material::specular_from_eta(1.5) - 0.5).abs() < 1e-6);
    let Material::Principled(PrincipledParams { base_color, metallic, roughness, specular, .. }) = *m[1]
    else {
        panic!("{:?}", m[1])
    };
    assert_eq!((base_color, metallic, roughness, specular), (Rgb::splat(0.5), 0.0, 0.5, 0.7));
    let bound: Vec<(TexturedParam, bool)> =
        s.textures.bindings_of(s.meshes[1].material).map(|b| (b.param, b.remap_roughness)).collect();
    assert_eq!(
        bound,
        [
            (TexturedParam::Reflectance, false),
            (TexturedParam::Metallic, false),
            (TexturedParam::Roughness, false)
        ]
    );
    let Material::Principled(PrincipledParams { clearcoat, sheen, .. }) = *m[2] else { panic!("{:?}", m[2]) };
    assert_eq!((clearcoat, sheen), (1.0, 0.0));
    // A textured sheen is bound (its default stays in the material).
    let bound: Vec<TexturedParam> = s.textures.bindings_of(s.meshes[2].material).map(|b| b.param).collect();
    assert_eq!(bound, [TexturedParam::Sheen]);
    let disney: Vec<String> =
        loaded.warnings.iter().filter(|w| w.message.contains("disney")).map(|w| w.to_string()).collect();
    assert_eq!(disney.len(), 1, "{disney:#?}");
    for part in ["subsurface scattering", "thin-surface mode", "\"clearcoat\" 2 outside"] {
        assert!(disney[0].contains(part), "{part}: {}", disney[0]);
    }
    assert!(disney[0].starts_with("d.pbrt:18:1: "), "{}", disney[0]);
    assert!(!loaded.warnings.iter().any(|w| w.message.contains("unused")), "{:#?}", loaded.warnings);
    let e = load_str(&v3_scene(&["Material \"disney\" \"float eta\" 0"]), "e.pbrt", &dir).unwrap_err();
    assert!((e.line, e.message.contains("\"eta\" must be positive")) == (8, true), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}
