//! pbrt-v3 scenes: v3 materials mapped to atoll's with one warning each,
//! `Texture` statements recorded, `mix`, v3 spellings of types, Booleans,
//! films, cameras and lights, and skipped curves counted.

mod common;

use atoll_scene::pbrt::load_str;
use atoll_scene::{Light, Material, Rgb};
use common::assert_close;
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
        "Material \"disney\" \"rgb color\" [0.2 0.4 0.6] \"float metallic\" 1 \"float roughness\" 0.5",
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
    assert_eq!(*m[1], diffuse([0.4, 0.4, 0.4]));
    assert_eq!(*m[2], diffuse([0.3, 0.2, 0.1]));
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
    let k = Material::conductor_k_from_reflectance(Rgb::new(0.2, 0.4, 0.6));
    assert_eq!(*m[10], Material::Conductor { eta: Rgb::ONE, k, alpha_x: 0.25, alpha_y: 0.25 });
    assert_eq!(*m[11], diffuse([0.3, 0.2, 0.1]));
    // v3 metal defaults: copper, roughness 0.01 remapped to alpha 0.1.
    let Material::Conductor { alpha_x, eta, .. } = m[12] else { panic!("{:?}", m[12]) };
    assert!((alpha_x - 0.1).abs() < 1e-6 && (eta.x - 0.200438).abs() < 1e-6);
    assert_eq!(*m[13], Material::Dielectric { eta: 1.5, alpha_x: 0.01, alpha_y: 0.04 });

    // One warning per mapped material, at its Material statement (line 7 + 4 per block).
    let mapped: Vec<_> = loaded.warnings.iter().filter(|w| w.message.contains("material \"")).collect();
    let lines: Vec<u32> = mapped.iter().map(|w| w.line).collect();
    let expected: Vec<u32> = (0..materials.len() as u32).map(|i| 8 + 4 * i).collect();
    assert_eq!(lines, expected, "{mapped:#?}");
    assert!(mapped[0]
        .message
        .starts_with("pbrt-v3 material \"matte\" is not supported; read as \"diffuse\""));
    assert!(mapped[1].message.contains("specular layer dropped"), "{}", mapped[1]);
    assert!(mapped[11].message.starts_with("material \"hair\" is not supported"), "{}", mapped[11]);
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
    assert_eq!(st.camera.fov_degrees, 45.0);
    let w: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    assert!(
        w.iter().any(|w| w.starts_with("v3.pbrt:2:1: Camera: \"frameaspectratio\" is not supported")),
        "{w:#?}"
    );
    assert!(w.iter().any(|w| w.contains("WorldEnd is pbrt-v3 syntax")), "{w:#?}");
    assert!(w.iter().any(|w| w.contains("type 'point' is pbrt-v3 syntax")), "{w:#?}");
}

#[test]
fn textures_are_recorded_and_warned_about_once() {
    let text = "WorldBegin\n\
        Texture \"wood\" \"color\" \"imagemap\" \"string filename\" \"textures/wood.png\" \"bool trilinear\" \"true\"\n\
        Texture \"bump\" \"float\" \"imagemap\" \"string filename\" \"textures/bump.png\"\n\
        Texture \"checks\" \"spectrum\" \"checkerboard\" \"float uscale\" 4\n\
        Material \"matte\" \"texture Kd\" \"wood\"\n"
        .to_string()
        + TRI;
    let loaded = load_str(&text, "t.pbrt", Path::new("/scenes")).unwrap();
    let names: Vec<_> = loaded.textures.iter().map(|t| (t.name.as_str(), t.class.as_str())).collect();
    assert_eq!(names, [("wood", "imagemap"), ("bump", "imagemap"), ("checks", "checkerboard")]);
    assert_eq!(loaded.textures[0].filename.as_deref(), Some(Path::new("/scenes/textures/wood.png")));
    assert_eq!(loaded.textures[2].filename, None);
    let w: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(w.iter().filter(|w| w.contains("textures are not rendered yet")).count(), 1, "{w:#?}");
    assert!(w[0].starts_with("t.pbrt:2:1: texture \"wood\" recorded"), "{w:#?}");
    // The material parameter that uses a texture keeps its default, with a warning at the material.
    assert!(w
        .iter()
        .any(|w| w.starts_with("t.pbrt:5:1:") && w.contains("texture \"wood\" replaced by the default")));
    assert_eq!(loaded.scene.materials[0], Material::Diffuse { reflectance: Rgb::splat(0.5) });
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
fn curves_are_skipped_once_then_counted() {
    let curve =
        "Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 1 1 0 0 1 0] \"float width\" 0.1 \"string type\" \"flat\"";
    let tri = TRI.replace("\"point P\"", "\"point3 P\"");
    let text = format!("WorldBegin\n{tri}\n{curve}\n{curve}\n{curve}\nShape \"disk\"\n");
    let loaded = load_str(&text, "c.pbrt", Path::new(".")).unwrap();
    assert_eq!(loaded.scene.meshes.len(), 1);
    let w: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(
        w,
        [
            "c.pbrt:3:1: unsupported shape \"curve\" skipped",
            "c.pbrt:6:1: unsupported shape \"disk\" skipped",
            "c.pbrt:3:1: 3 unsupported \"curve\" shapes skipped in all (the first is here)"
        ]
    );
}

#[test]
fn v3_lights() {
    let text = "WorldBegin\n\
        LightSource \"infinite\" \"string mapname\" \"sky.exr\" \"integer nsamples\" 4\n\
        LightSource \"distant\" \"blackbody L\" [5500 2] \"point from\" [0 1 0] \"point to\" [0 0 0]\n";
    let loaded = load_str(text, "l.pbrt", Path::new(".")).unwrap();
    let l = &loaded.scene.lights;
    assert_eq!(l[0], Light::Infinite { radiance: Rgb::ONE });
    let Light::Distant { direction, radiance } = l[1] else { panic!("{:?}", l[1]) };
    assert_close(direction, -glam::Vec3::Y, 1e-6);
    // v3's (temperature, scale) blackbody: the colour of 5500 K at luminance 2.
    let lum = 0.2126 * radiance.x + 0.7152 * radiance.y + 0.0722 * radiance.z;
    assert!((lum - 2.0).abs() < 0.05 && radiance.x > radiance.z, "{radiance}");
    let w: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    // A missing map: a warning naming it, constant white instead.
    assert!(w[0].contains("sky.exr") && w[0].contains("using constant white"), "{w:#?}");
    assert!(!w.iter().any(|w| w.contains("unused parameter")), "{w:#?}");
}
