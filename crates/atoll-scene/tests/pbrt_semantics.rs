//! pbrt-v4 semantics of the loader: transforms, orientation, instancing,
//! materials, lights and warnings.

mod common;

use atoll_scene::{
    AreaEmission, CoatedConductorParams, CoatedDiffuseParams, Coating, HairParams, IntegratorSettings, Light,
    Material, PrincipledParams, Rgb, Texture, TexturedParam,
};
use common::{allowing_missing, assert_close, load_world, tri};
use glam::Vec3;

const UNIT_TRI: [[f32; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

#[test]
fn mirrored_look_at_camera() {
    let s = load_world(
        "Scale -1 1 1\nLookAt 0 1 -3.9  0 1 0  0 1 0\nCamera \"perspective\" \"float fov\" 45",
        "",
    )
    .unwrap()
    .scene;
    let c2w = s.settings.camera.camera_to_world;
    assert_close(c2w.transform_point3(Vec3::ZERO), Vec3::new(0.0, 1.0, -3.9), 1e-6);
    assert_close(c2w.transform_vector3(Vec3::Z), Vec3::Z, 1e-6);
    assert_close(c2w.transform_vector3(Vec3::Y), Vec3::Y, 1e-6);
    assert_close(c2w.transform_vector3(Vec3::X), -Vec3::X, 1e-6);
    assert!(c2w.determinant() < 0.0);
    assert_eq!(s.settings.camera.fov_degrees, 45.0);
}

/// `orthographic` and `spherical` cameras, `screenwindow` and
/// `frameaspectratio` as pbrt-v4 reads them; malformed ones are errors at
/// their statement.
#[test]
fn orthographic_cameras_and_screen_windows() {
    let camera = |text: &str| load_world(text, "").map(|l| (l.scene.settings.camera, l.warnings));
    let (c, w) = camera("Camera \"orthographic\" \"float screenwindow\" [ -2 2 -1 1.5 ]").unwrap();
    assert!(w.is_empty(), "{w:?}");
    assert_eq!(c.projection, atoll_scene::Projection::Orthographic);
    assert_eq!(c.screen_window, Some([-2.0, 2.0, -1.0, 1.5]));
    let (c, _) = camera("Camera \"perspective\" \"float fov\" 30 \"float frameaspectratio\" 0.5").unwrap();
    assert_eq!((c.projection, c.fov_degrees), (atoll_scene::Projection::Perspective, 30.0));
    assert_eq!(c.frame_aspect_ratio, Some(0.5));
    assert_eq!(c.screen_window(glam::UVec2::new(640, 480)), [-1.0, 1.0, -2.0, 2.0]);
    let (c, _) = camera("Camera \"spherical\"").unwrap();
    assert_eq!(
        c.projection,
        atoll_scene::Projection::Spherical { mapping: atoll_scene::EnvLayout::EqualArea }
    );
    let (c, _) = camera("Camera \"spherical\" \"string mapping\" \"equirectangular\"").unwrap();
    assert_eq!(c.projection, atoll_scene::Projection::Spherical { mapping: atoll_scene::EnvLayout::LatLong });
    // A camera pbrt-v4 does not have either (`realistic_cameras` tests
    // the realistic one).
    let (c, w) = camera("Camera \"fisheye\"").unwrap();
    assert_eq!(c.projection, atoll_scene::Projection::Perspective);
    assert!(w[0].message.contains("camera \"fisheye\" is not supported"), "{w:?}");
    for (text, error) in [
        (
            "Camera \"orthographic\" \"float screenwindow\" [ -1 1 -1 ]",
            "test.pbrt:1:1: Camera: \"screenwindow\" needs four values",
        ),
        ("Camera \"perspective\" \"float screenwindow\" [ 1 -1 -1 1 ]", "each minimum below its maximum"),
        ("Camera \"orthographic\" \"float frameaspectratio\" 0", "\"frameaspectratio\" 0 is not positive"),
        ("Camera \"spherical\" \"string mapping\" \"cube\"", "Camera: \"mapping\" \"cube\" is unknown"),
    ] {
        let message = camera(text).unwrap_err().to_string();
        assert!(message.contains(error), "{text}: {message}");
    }
}

#[test]
fn defaults_follow_pbrt() {
    let s = load_world("", "").unwrap().scene;
    assert_eq!(s.settings.spp, 16);
    assert_eq!(s.settings.film.resolution, glam::UVec2::new(1280, 720));
    assert_eq!(s.settings.integrator, IntegratorSettings::Path { max_depth: 5 });
    assert_eq!(s.settings.camera.fov_degrees, 90.0);
    assert!(s.objects.is_empty() && s.instances.is_empty());
    let s = load_world("Integrator \"ambientocclusion\"", "").unwrap().scene;
    assert_eq!(s.settings.integrator, IntegratorSettings::AmbientOcclusion { max_distance: f32::INFINITY });
    let loaded = load_world("Integrator \"bdpt\" \"integer maxdepth\" 3", "").unwrap();
    assert_eq!(loaded.scene.settings.integrator, IntegratorSettings::Path { max_depth: 3 });
    assert!(loaded.warnings[0].message.contains("\"bdpt\" is not supported"));
}

#[test]
fn rotate_maps_x_to_y() {
    let s = load_world("", &format!("Rotate 90 0 0 1\n{}", tri(UNIT_TRI))).unwrap().scene;
    let p = &s.meshes[0].positions;
    assert_close(p[0], Vec3::Y, 1e-6);
    assert_close(p[1], -Vec3::X, 1e-6);
    assert_close(p[2], Vec3::Z, 1e-6);
}

#[test]
fn transforms_post_multiply() {
    // Translate then Scale: the scale applies first to the shape's points.
    let s = load_world("", &format!("Translate 1 0 0\nScale 2 2 2\n{}", tri(UNIT_TRI))).unwrap().scene;
    assert_close(s.meshes[0].positions[0], Vec3::new(3.0, 0.0, 0.0), 1e-6);
    let s = load_world("", &format!("Scale 2 2 2\nTranslate 1 0 0\n{}", tri(UNIT_TRI))).unwrap().scene;
    assert_close(s.meshes[0].positions[0], Vec3::new(4.0, 0.0, 0.0), 1e-6);
}

#[test]
fn transform_matrices_are_column_major() {
    let translate = "Transform [ 1 0 0 0  0 1 0 0  0 0 1 0  5 6 7 1 ]";
    let s = load_world("", &format!("Scale 9 9 9\n{translate}\n{}", tri(UNIT_TRI))).unwrap().scene;
    assert_close(s.meshes[0].positions[0], Vec3::new(6.0, 6.0, 7.0), 1e-6);
    // ConcatTransform post-multiplies: scale first, then translate.
    let concat = "ConcatTransform [ 2 0 0 0  0 2 0 0  0 0 2 0  0 0 0 1 ]";
    let s = load_world("", &format!("Translate 1 0 0\n{concat}\n{}", tri(UNIT_TRI))).unwrap().scene;
    assert_close(s.meshes[0].positions[0], Vec3::new(3.0, 0.0, 0.0), 1e-6);
    // A shear shows the layout: column 1 (the image of y) is (1, 1, 0).
    let shear = "ConcatTransform [ 1 0 0 0  1 1 0 0  0 0 1 0  0 0 0 1 ]";
    let s = load_world("", &format!("{shear}\n{}", tri(UNIT_TRI))).unwrap().scene;
    assert_close(s.meshes[0].positions[1], Vec3::new(1.0, 1.0, 0.0), 1e-6);
}

#[test]
fn named_coordinate_systems_round_trip() {
    let world = format!(
        "Translate 1 2 3\nRotate 30 1 1 0\nCoordinateSystem \"mine\"\nIdentity\nTranslate 100 0 0\n\
         CoordSysTransform \"mine\"\n{}\nCoordSysTransform \"camera\"\n{}\nCoordSysTransform \"world\"\n{}",
        tri(UNIT_TRI),
        tri(UNIT_TRI),
        tri(UNIT_TRI)
    );
    let s = load_world("LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\"", &world).unwrap().scene;
    let expected = glam::Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0))
        * glam::Mat4::from_axis_angle(Vec3::new(1.0, 1.0, 0.0).normalize(), 30f32.to_radians());
    assert_close(s.meshes[0].positions[0], expected.transform_point3(Vec3::X), 1e-5);
    // "camera" is the camera-to-world transform: camera-space x lands next to the eye.
    assert_close(s.meshes[1].positions[0], Vec3::new(1.0, 0.0, -5.0), 1e-6);
    assert_close(s.meshes[2].positions[0], Vec3::X, 0.0);
}

#[test]
fn flip_normals_follows_handedness_and_reverse_orientation() {
    let world = format!(
        "AttributeBegin\n{t}\nAttributeEnd\n\
         AttributeBegin\nScale -1 1 1\n{t}\nAttributeEnd\n\
         AttributeBegin\nReverseOrientation\n{t}\nAttributeEnd\n\
         AttributeBegin\nReverseOrientation\nScale 1 -1 1\n{t}\nAttributeEnd\n\
         AttributeBegin\nScale -1 -1 1\n{t}\nAttributeEnd\n{t}",
        t = tri(UNIT_TRI)
    );
    let s = load_world("", &world).unwrap().scene;
    let flips: Vec<bool> = s.meshes.iter().map(|m| m.flip_normals).collect();
    assert_eq!(flips, [false, true, true, false, false, false]);
    // Under a mirror the winding reverses, and the flip restores the object-space facing.
    let n0 = s.meshes[0].geometric_normal(0);
    let n1 = s.meshes[1].geometric_normal(0);
    assert_close(n1, n0 * Vec3::new(-1.0, 1.0, 1.0), 1e-6);
}

#[test]
fn shading_normals_use_the_inverse_transpose() {
    let mesh = "Shape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"normal N\" [1 1 0 1 1 0 1 1 0] \"point2 uv\" [0 0 1 0 0 1]";
    let s = load_world("", &format!("Scale 2 1 1\n{mesh}\nReverseOrientation\n{mesh}")).unwrap().scene;
    assert_close(s.meshes[0].normals[0], Vec3::new(0.5, 1.0, 0.0).normalize(), 1e-6);
    assert_close(s.meshes[1].normals[0], -Vec3::new(0.5, 1.0, 0.0).normalize(), 1e-6);
    assert_eq!(s.meshes[0].uvs[2], glam::Vec2::new(0.0, 1.0));
}

#[test]
fn instancing_shares_meshes() {
    let world = format!(
        "AttributeBegin\nTranslate 0 0 5\nObjectBegin \"thing\"\n{t}\n{t}\nObjectEnd\nAttributeEnd\n\
         {instances}\n{t}",
        t = tri(UNIT_TRI),
        instances = (0..4)
            .map(|i| format!("AttributeBegin\nTranslate {i} 0 0\nObjectInstance \"thing\"\nAttributeEnd\n"))
            .collect::<String>()
    );
    let s = load_world("", &world).unwrap().scene;
    assert_eq!(s.meshes.len(), 3);
    assert_eq!(s.objects.len(), 2);
    // The world object comes first, with one identity instance.
    assert_eq!(s.objects[0].name, "world");
    assert_eq!(s.objects[0].meshes, vec![2]);
    assert_eq!(s.objects[1].name, "thing");
    assert_eq!(s.objects[1].meshes, vec![0, 1]);
    assert_eq!(s.instances.len(), 5);
    assert_eq!(s.instances[0].object, 0);
    for (i, inst) in s.instances[1..].iter().enumerate() {
        assert_eq!(inst.object, 1);
        assert_close(inst.object_to_world.transform_point3(Vec3::ZERO), Vec3::new(i as f32, 0.0, 0.0), 0.0);
    }
    // Object shapes keep the CTM of their definition (pbrt-v4): here Translate 0 0 5.
    assert_close(s.meshes[0].positions[0], Vec3::new(1.0, 0.0, 5.0), 0.0);
    assert_eq!(s.stats().instanced_triangles, 4 * 2 + 1);
    assert_eq!(s.stats().unique_triangles, 3);
}

#[test]
fn instances_may_precede_definitions_and_drop_area_lights() {
    let world = format!(
        "ObjectInstance \"later\"\nAttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n\
         ObjectBegin \"later\"\n{t}\nObjectEnd\n{t}\nAttributeEnd\nObjectBegin \"empty\"\nObjectEnd\nObjectInstance \"empty\"",
        t = tri(UNIT_TRI)
    );
    let loaded = load_world("", &world).unwrap();
    let s = &loaded.scene;
    assert_eq!(s.instances.len(), 2, "the empty object's instance is dropped");
    let object_mesh = &s.meshes[s.objects[1].meshes[0] as usize];
    assert_eq!(object_mesh.emission, None);
    assert!(s.meshes[1].emission.is_some());
    assert!(loaded
        .warnings
        .iter()
        .any(|w| w.message.contains("area lights are not supported in object instances")));
}

#[test]
fn materials() {
    let world = format!(
        "MakeNamedMaterial \"gold\" \"string type\" \"conductor\" \"spectrum eta\" \"metal-Au-eta\" \
         \"spectrum k\" \"metal-Au-k\" \"float roughness\" 0.25\n\
         NamedMaterial \"late\"\n{t}\n\
         Material \"conductor\" \"float uroughness\" 0.04 \"float vroughness\" 0.09 \"bool remaproughness\" false\n{t}\n\
         Material \"conductor\" \"rgb reflectance\" [0.5 0.5 0.5]\n{t}\n\
         Material \"dielectric\" \"spectrum eta\" \"glass-BK7\"\n{t}\n\
         Material \"interface\"\n{t}\nMaterial \"\"\n{t}\n\
         Material \"nonesuch\"\n{t}\n\
         NamedMaterial \"gold\"\n{t}\n\
         MakeNamedMaterial \"late\" \"string type\" \"diffuse\" \"rgb reflectance\" [0.1 0.2 0.3]\n\
         AttributeBegin\nMaterial \"dielectric\"\nAttributeEnd\n{t}",
        t = tri(UNIT_TRI)
    );
    let loaded = load_world("", &world).unwrap();
    let s = &loaded.scene;
    let m: Vec<&Material> = s.meshes.iter().map(|mesh| &s.materials[mesh.material as usize]).collect();
    assert_eq!(*m[0], Material::Diffuse { reflectance: Rgb::new(0.1, 0.2, 0.3) });
    let cu_eta = Rgb::new(0.200438, 0.924033, 1.10221);
    let cu_k = Rgb::new(3.91295, 2.45285, 2.14219);
    assert_eq!(*m[1], Material::Conductor { eta: cu_eta, k: cu_k, alpha_x: 0.04, alpha_y: 0.09 });
    let k = Material::conductor_k_from_reflectance(Rgb::splat(0.5));
    assert_eq!(*m[2], Material::Conductor { eta: Rgb::ONE, k, alpha_x: 0.0, alpha_y: 0.0 });
    assert_eq!(*m[3], Material::Dielectric { eta: 1.5168, alpha_x: 0.0, alpha_y: 0.0 });
    assert_eq!(*m[4], Material::Interface);
    assert_eq!(*m[5], Material::Interface);
    assert_eq!(*m[6], Material::default_diffuse());
    let au = (Rgb::new(0.143119, 0.374957, 1.44248), Rgb::new(3.98316, 2.38572, 1.60322));
    assert_eq!(*m[7], Material::Conductor { eta: au.0, k: au.1, alpha_x: 0.5, alpha_y: 0.5 });
    // AttributeEnd restored the named material.
    assert_eq!(s.meshes[8].material, s.meshes[7].material);
    assert!(loaded.warnings.iter().any(|w| w.message.contains("material \"nonesuch\" is not supported")));
    assert_eq!(loaded.warnings.len(), 1, "{:?}", loaded.warnings);
    // Materials are stored once however many shapes use them.
    assert_eq!(s.materials.len(), 8);
}

#[test]
fn diffuse_transmission_and_thin_dielectric() {
    let world = format!(
        "Material \"diffusetransmission\" \"rgb reflectance\" [0.2 0.4 0.6] \"float scale\" 0.5\n{t}\n\
         Material \"diffusetransmission\"\n{t}\n\
         Material \"thindielectric\" \"float eta\" 1.33\n{t}\nMaterial \"thindielectric\"\n{t}",
        t = tri(UNIT_TRI)
    );
    let loaded = load_world("", &world).unwrap();
    let s = &loaded.scene;
    let m: Vec<&Material> = s.meshes.iter().map(|mesh| &s.materials[mesh.material as usize]).collect();
    assert_eq!(
        *m[0],
        Material::DiffuseTransmission {
            reflectance: Rgb::new(0.1, 0.2, 0.3),
            transmittance: Rgb::splat(0.125)
        }
    );
    assert_eq!(
        *m[1],
        Material::DiffuseTransmission { reflectance: Rgb::splat(0.25), transmittance: Rgb::splat(0.25) }
    );
    assert_eq!(*m[2], Material::ThinDielectric { eta: 1.33 });
    assert_eq!(*m[3], Material::ThinDielectric { eta: 1.5 });
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
}

/// pbrt-v4's `coateddiffuse`: defaults, every parameter, roughness
/// remapping, and `file:line:col` errors for walk counts out of range.
#[test]
fn coated_diffuse() {
    let world = format!(
        "Material \"coateddiffuse\"\n{t}\n\
         Material \"coateddiffuse\" \"rgb reflectance\" [0.2 0.4 0.6] \"float uroughness\" 0.09 \
         \"float vroughness\" 0.25 \"float thickness\" 0.5 \"float eta\" 1.33 \"rgb albedo\" [0.9 0.8 0.7] \
         \"float g\" -0.3 \"integer maxdepth\" 32 \"integer nsamples\" 4\n{t}\n\
         Material \"coateddiffuse\" \"float roughness\" 0.2 \"bool remaproughness\" false\n{t}",
        t = tri(UNIT_TRI)
    );
    let loaded = load_world("", &world).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let s = &loaded.scene;
    let m: Vec<&Material> = s.meshes.iter().map(|mesh| &s.materials[mesh.material as usize]).collect();
    let defaults = Material::CoatedDiffuse(CoatedDiffuseParams {
        reflectance: Rgb::splat(0.5),
        coating: Coating {
            eta: 1.5,
            alpha_x: 0.0,
            alpha_y: 0.0,
            thickness: 0.01,
            albedo: Rgb::ZERO,
            g: 0.0,
            max_depth: 10,
            n_samples: 1,
        },
    });
    assert_eq!(*m[0], defaults);
    assert_eq!(
        *m[1],
        Material::CoatedDiffuse(CoatedDiffuseParams {
            reflectance: Rgb::new(0.2, 0.4, 0.6),
            coating: Coating {
                eta: 1.33,
                alpha_x: 0.3,
                alpha_y: 0.5,
                thickness: 0.5,
                albedo: Rgb::new(0.9, 0.8, 0.7),
                g: -0.3,
                max_depth: 32,
                n_samples: 4,
            },
        })
    );
    let Material::CoatedDiffuse(CoatedDiffuseParams { coating, .. }) = *m[2] else { panic!("{:?}", m[2]) };
    assert_eq!((coating.alpha_x, coating.alpha_y), (0.2, 0.2));

    // The error is at the parameter (column 26, after `Material "coateddiffuse" `).
    for bad in ["\"integer nsamples\" 0", "\"integer maxdepth\" -1", "\"integer maxdepth\" 5000"] {
        let e = load_world("", &format!("Material \"coateddiffuse\" {bad}\n{}", tri(UNIT_TRI)))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("test.pbrt:3:26: ") && e.contains("must be between"), "{e}");
    }
}

/// pbrt-v4's `coatedconductor`: copper under a smooth coating by default;
/// `conductor.*` and `interface.*` parameters each reach their own layer;
/// `reflectance` gives the conductor's index as for `conductor`; walks
/// other than pbrt's default, and anisotropic roughness (which atoll
/// cannot orient along dp/du for this material), are warned about, at the
/// statement.
#[test]
fn coated_conductor() {
    let world = format!(
        "Material \"coatedconductor\"\n{t}\n\
         Material \"coatedconductor\" \"spectrum conductor.eta\" \"metal-Au-eta\" \"spectrum conductor.k\" \"metal-Au-k\" \
         \"float conductor.uroughness\" 0.09 \"float conductor.vroughness\" 0.25 \"float interface.roughness\" 0.16 \
         \"float interface.eta\" 1.33 \"float thickness\" 0.5 \"rgb albedo\" [0.9 0.8 0.7] \"float g\" -0.3\n{t}\n\
         Material \"coatedconductor\" \"rgb reflectance\" [0.5 0.5 0.5] \"integer maxdepth\" 20\n{t}\n\
         Material \"conductor\"\n{t}",
        t = tri(UNIT_TRI)
    );
    let loaded = load_world("", &world).unwrap();
    let s = &loaded.scene;
    let m: Vec<&Material> = s.meshes.iter().map(|mesh| &s.materials[mesh.material as usize]).collect();
    let Material::CoatedConductor(copper) = *m[0] else { panic!("{:?}", m[0]) };
    let Material::Conductor { eta, k, .. } = *m[3] else { panic!("{:?}", m[3]) };
    assert_eq!((copper.eta, copper.k), (eta, k));
    assert_eq!((copper.alpha_x, copper.alpha_y), (0.0, 0.0));
    assert_eq!(copper.coating, Coating::PBRT_DEFAULT);
    assert_eq!(
        *m[1],
        Material::CoatedConductor(CoatedConductorParams {
            eta: Rgb::new(0.143119, 0.374957, 1.44248),
            k: Rgb::new(3.98316, 2.38572, 1.60322),
            alpha_x: 0.3,
            alpha_y: 0.5,
            coating: Coating {
                eta: 1.33,
                alpha_x: 0.4,
                alpha_y: 0.4,
                thickness: 0.5,
                albedo: Rgb::new(0.9, 0.8, 0.7),
                g: -0.3,
                ..Coating::PBRT_DEFAULT
            },
        })
    );
    let Material::CoatedConductor(from_reflectance) = *m[2] else { panic!("{:?}", m[2]) };
    assert_eq!(from_reflectance.eta, Rgb::ONE);
    assert_eq!(from_reflectance.k, Material::conductor_k_from_reflectance(Rgb::splat(0.5)));
    assert_eq!((from_reflectance.coating.max_depth, from_reflectance.coating.n_samples), (10, 1));
    assert_eq!(loaded.warnings.len(), 2, "{:?}", loaded.warnings);
    let anisotropic = loaded.warnings[0].to_string();
    assert!(anisotropic.starts_with("test.pbrt:5:") && anisotropic.contains("anisotropic"), "{anisotropic}");
    let warning = loaded.warnings[1].to_string();
    assert!(warning.starts_with("test.pbrt:7:") && warning.contains("\"maxdepth\" 20"), "{warning}");
}

/// pbrt-v4's `hair`: its defaults, and the absorption from `sigma_a`,
/// `reflectance` (or `color`) or the melanin concentrations, in that order
/// of precedence; roughnesses clamped to [0.01, 1]; textures bound per hit
/// for `sigma_a`, `reflectance`, `eta`, `beta_m`, `beta_n`, `alpha` and
/// the melanin concentrations (the material keeps the defaults, or the
/// constant concentration's absorption).
#[test]
fn hair() {
    let world = format!(
        "Texture \"t\" \"float\" \"constant\" \"float value\" 0.5\n\
         Material \"hair\"\n{t}\n\
         Material \"hair\" \"rgb sigma_a\" [0.1 0.2 0.3] \"float eta\" 1.4 \"float beta_m\" 0.2 \"float beta_n\" 2 \
         \"float alpha\" 3\n{t}\n\
         Material \"hair\" \"rgb reflectance\" [0.3 0.2 0.1] \"float beta_n\" 0.5\n{t}\n\
         Material \"hair\" \"rgb color\" [0.3 0.2 0.1] \"float beta_n\" 0.5\n{t}\n\
         Material \"hair\" \"float eumelanin\" 0.3 \"float pheomelanin\" 2 \"rgb sigma_a\" [1 1 1]\n{t}\n\
         Material \"hair\" \"float pheomelanin\" 2 \"texture beta_m\" \"t\" \"float beta_n\" 0.001\n{t}\n\
         Material \"hair\" \"texture eumelanin\" \"t\" \"float pheomelanin\" 0.5\n{t}\n\
         Material \"hair\" \"rgb reflectance\" [0.3 0.2 0.1] \"texture beta_n\" \"t\"\n{t}",
        t = tri(UNIT_TRI)
    );
    let loaded = load_world("", &world).unwrap();
    let s = &loaded.scene;
    let m: Vec<Material> = s.meshes.iter().map(|mesh| s.materials[mesh.material as usize].clone()).collect();
    let default = HairParams::pbrt_default();
    assert_eq!(m[0], Material::Hair(default));
    assert_eq!(default.sigma_a, Rgb::new(0.419, 0.697, 1.37) * 1.3);
    assert_eq!(
        m[1],
        Material::Hair(HairParams {
            sigma_a: Rgb::new(0.1, 0.2, 0.3),
            eta: 1.4,
            beta_m: 0.2,
            beta_n: 1.0,
            alpha: 3.0
        })
    );
    let from_colour = HairParams::sigma_a_from_reflectance(Rgb::new(0.3, 0.2, 0.1), 0.5);
    assert_eq!(m[2], Material::Hair(HairParams { sigma_a: from_colour, beta_n: 0.5, ..default }));
    assert_eq!(m[3], m[2], "pbrt-v3's \"color\" is \"reflectance\"");
    // pbrt's fit, at beta_n 0.5: sigma_a = (ln c / 5.50928)².
    assert!((from_colour.x - (0.3f32.ln() / 5.50928).powi(2)).abs() < 1e-4, "{from_colour}");
    // sigma_a wins over the concentrations (with a warning).
    let Material::Hair(given) = m[4] else { panic!("{:?}", m[4]) };
    assert_eq!(given.sigma_a, Rgb::ONE);
    let Material::Hair(red) = m[5] else { panic!("{:?}", m[5]) };
    assert_eq!(red.sigma_a, Rgb::new(0.187, 0.4, 1.05) * 2.0);
    assert_eq!((red.beta_m, red.beta_n), (0.3, 0.01), "a texture keeps the default; clamped to 0.01");
    let textured = s.meshes[5].material;
    let bound: Vec<_> =
        s.textures.bindings.iter().filter(|b| b.material == textured).map(|b| b.param).collect();
    assert_eq!(bound, vec![atoll_scene::TexturedParam::BetaM]);
    // A textured concentration adds per hit to the constant one's absorption.
    let pheomelanin = HairParams::sigma_a_from_concentration(0.0, 0.5);
    assert_eq!(m[6], Material::Hair(HairParams { sigma_a: pheomelanin, ..default }));
    let melanin = s.meshes[6].material;
    let bound: Vec<_> =
        s.textures.bindings.iter().filter(|b| b.material == melanin).map(|b| b.param).collect();
    assert_eq!(bound, vec![atoll_scene::TexturedParam::Eumelanin]);
    // A reflectance turns into an absorption per hit, after the textured beta_n.
    let per_hit = s.meshes[7].material;
    let bound: Vec<_> =
        s.textures.bindings.iter().filter(|b| b.material == per_hit).map(|b| b.param).collect();
    assert_eq!(bound, vec![atoll_scene::TexturedParam::BetaN, atoll_scene::TexturedParam::Reflectance]);
    let warnings: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("\"sigma_a\" is used"), "{warnings:?}");
}

#[test]
fn default_material_and_texture_references() {
    let world = format!(
        "{t}\nTexture \"checks\" \"spectrum\" \"checkerboard\"\nMaterial \"diffuse\" \"texture reflectance\" \"checks\"\n{t}",
        t = tri(UNIT_TRI)
    );
    let loaded = load_world("", &world).unwrap();
    let s = &loaded.scene;
    assert_eq!(s.materials[s.meshes[0].material as usize], Material::default_diffuse());
    // The textured material keeps pbrt's default as its constant; the binding overrides it.
    let textured = s.meshes[1].material;
    assert_eq!(s.materials[textured as usize], Material::default_diffuse());
    let b: Vec<_> = s.textures.bindings_of(textured).map(|b| (b.param, b.texture)).collect();
    assert_eq!(b, [(TexturedParam::Reflectance, 0)]);
    assert!(matches!(s.textures.textures[0], Texture::Checkerboard { .. }));
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
}

#[test]
fn area_lights() {
    let world = format!(
        "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 2 3] \"float scale\" 2 \"bool twosided\" true\n{t}\nAttributeEnd\n\
         {t}\nAttributeBegin\nAreaLightSource \"diffuse\" \"blackbody L\" 6500\n{t}\nAttributeEnd",
        t = tri(UNIT_TRI)
    );
    let s = load_world("", &world).unwrap().scene;
    assert_eq!(
        s.meshes[0].emission,
        Some(AreaEmission { radiance: Rgb::new(2.0, 4.0, 6.0), two_sided: true })
    );
    assert_eq!(s.meshes[1].emission, None);
    let bb = s.meshes[2].emission.unwrap().radiance;
    assert!((bb - Rgb::ONE).abs().max_element() < 0.15, "{bb}");
}

#[test]
fn light_sources() {
    let world = "AttributeBegin\nTranslate 0 5 0\nLightSource \"point\" \"rgb I\" [1 1 1] \"float scale\" 3 \"point3 from\" [1 0 0]\nAttributeEnd\n\
                 AttributeBegin\nRotate 90 1 0 0\nLightSource \"distant\" \"rgb L\" [2 2 2]\nAttributeEnd\n\
                 LightSource \"distant\" \"point3 from\" [0 10 0] \"point3 to\" [0 0 0]\n\
                 LightSource \"infinite\" \"rgb L\" [0.5 0.5 0.5] \"float scale\" 2\n\
                 LightSource \"infinite\" \"string filename\" \"sky.exr\"\n\
                 AttributeBegin\nTranslate 0 4 0\nLightSource \"spot\" \"float coneangle\" 30 \"float conedelta\" 10 \"point3 to\" [0 -1 0] \"rgb I\" [2 2 2]\nAttributeEnd\n\
                 LightSource \"spot\" \"float power\" 100";
    // Without --allow-missing, the missing map is an error where it is named.
    let e = load_world("", world).unwrap_err().to_string();
    assert!(e.starts_with("test.pbrt:13:1: light \"infinite\": ") && e.contains("sky.exr"), "{e}");
    assert!(e.contains("--allow-missing"), "{e}");
    let loaded = allowing_missing(|| load_world("", world)).unwrap();
    let l = &loaded.scene.lights;
    assert_eq!(l.len(), 7);
    assert_eq!(l[0], Light::Point { position: Vec3::new(1.0, 5.0, 0.0), intensity: Rgb::splat(3.0) });
    // Default from (0,0,0) to (0,0,1): light travels along +z; Rotate 90 about x maps +z to -y.
    let Light::Distant { direction, radiance } = l[1] else { panic!() };
    assert_close(direction, -Vec3::Y, 1e-6);
    assert_eq!(radiance, Rgb::splat(2.0));
    let Light::Distant { direction, .. } = l[2] else { panic!() };
    assert_close(direction, -Vec3::Y, 1e-6);
    assert_eq!(l[3], Light::Infinite { radiance: Rgb::ONE, portal: None });
    assert_eq!(l[4], Light::Infinite { radiance: Rgb::ONE, portal: None });
    let msgs: Vec<_> = loaded.warnings.iter().map(|w| w.message.as_str()).collect();
    assert!(msgs.iter().any(|m| m.contains("sky.exr") && m.contains("using constant white")), "{msgs:?}");
    // Spot: from (0,0,0) to (0,-1,0) under Translate 0 4 0; cone 30 degrees, falloff from 20.
    let Light::Spot { position, direction, intensity, cos_falloff_start, cos_falloff_end } = l[5] else {
        panic!()
    };
    assert_close(position, Vec3::new(0.0, 4.0, 0.0), 1e-6);
    assert_close(direction, -Vec3::Y, 1e-6);
    assert_eq!(intensity, Rgb::splat(2.0));
    assert!((cos_falloff_start - 20f32.to_radians().cos()).abs() < 1e-6);
    assert!((cos_falloff_end - 30f32.to_radians().cos()).abs() < 1e-6);
    // `power` 100 W over the default cone (30, falloff 5) of unit intensity.
    let Light::Spot { intensity, cos_falloff_start, cos_falloff_end, .. } = l[6] else { panic!() };
    let emitted = Light::spot_solid_angle(cos_falloff_start, cos_falloff_end) * intensity.x;
    assert!((emitted - 100.0).abs() < 1e-3, "{emitted} W");
    assert!(load_world("", "LightSource \"spot\" \"float coneangle\" 200").is_err());
}

/// pbrt-v4's `goniometric` light: a square image's channel average as its
/// map, placed and turned by the transform, `power` over 4π times the
/// map's mean; a map that is not square is an error, a missing one too
/// (a warning with `--allow-missing`), and no `filename` a warning.
#[test]
fn goniometric_lights() {
    let dir = std::env::temp_dir().join(format!("atoll-gonio-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    exr::prelude::write_rgb_file(dir.join("map.exr"), 2, 2, |x, y| (x as f32, y as f32, 0.5)).unwrap();
    exr::prelude::write_rgb_file(dir.join("wide.exr"), 4, 2, |_, _| (1.0, 1.0, 1.0)).unwrap();
    let load = |world: &str| {
        atoll_scene::pbrt::load_str(&format!("WorldBegin\n{world}\n"), "g.pbrt", &dir)
            .map(|l| (l.scene.lights, l.warnings))
    };
    let (lights, warnings) = load(
        "AttributeBegin\nTranslate 1 2 3\nRotate 90 0 0 1\n\
         LightSource \"goniometric\" \"string filename\" \"map.exr\" \"rgb I\" [ 2 2 2 ] \"float scale\" 3\nAttributeEnd\n\
         LightSource \"goniometric\" \"string filename\" \"map.exr\" \"float power\" 10",
    )
    .unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    let Light::Goniometric { position, world_to_light, intensity, ref map } = lights[0] else {
        panic!("{lights:?}")
    };
    assert_close(position, Vec3::new(1.0, 2.0, 3.0), 1e-6);
    assert_close(world_to_light * -Vec3::X, Vec3::Y, 1e-6);
    assert_eq!(intensity, Rgb::splat(6.0));
    assert_eq!((map.resolution, &map.values[..]), (2, &[0.5 / 3.0, 1.5 / 3.0, 1.5 / 3.0, 2.5 / 3.0][..]));
    let Light::Goniometric { intensity, ref map, .. } = lights[1] else { panic!() };
    let emitted = 4.0 * std::f32::consts::PI * map.mean() * intensity.x;
    assert!((emitted - 10.0).abs() < 1e-4, "{emitted} W");
    let e = load("LightSource \"goniometric\" \"string filename\" \"wide.exr\"").unwrap_err().to_string();
    assert!(e.starts_with("g.pbrt:2:1: light \"goniometric\": \"wide.exr\" is 4x2, not square"), "{e}");
    let e = load("LightSource \"goniometric\" \"string filename\" \"none.exr\"").unwrap_err().to_string();
    assert!(e.starts_with("g.pbrt:2:1: light \"goniometric\": ") && e.contains("none.exr"), "{e}");
    let (lights, warnings) = load("LightSource \"goniometric\"").unwrap();
    assert!(lights.is_empty() && warnings[0].message.contains("no \"filename\" given"), "{warnings:?}");
    std::fs::remove_dir_all(&dir).ok();
}

/// pbrt-v4's `projection` light: placed and aimed by the transform (its y
/// turned over, so the image's top row is the light's +y), `power` the
/// luminous power its image sends out; no `filename`, a missing image or a
/// field of view outside (0, 180) is an error at its line.
#[test]
fn projection_lights() {
    let dir = std::env::temp_dir().join(format!("atoll-projection-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    exr::prelude::write_rgb_file(dir.join("slide.exr"), 4, 2, |x, y| (x as f32, y as f32, 0.5)).unwrap();
    let load = |world: &str| {
        atoll_scene::pbrt::load_str(&format!("WorldBegin\n{world}\n"), "p.pbrt", &dir)
            .map(|l| (l.scene.lights, l.warnings))
    };
    let (lights, warnings) = load(
        "AttributeBegin\nTranslate 1 2 3\nRotate 90 0 0 1\n\
         LightSource \"projection\" \"string filename\" \"slide.exr\" \"float fov\" 45 \"float scale\" 3\nAttributeEnd\n\
         LightSource \"projection\" \"string filename\" \"slide.exr\" \"float power\" 10",
    )
    .unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    let Light::Projection { position, world_to_light, scale, ref image } = lights[0] else {
        panic!("{lights:?}")
    };
    assert_close(position, Vec3::new(1.0, 2.0, 3.0), 1e-6);
    // The transform turns light +x to world +y and light +y to world -x;
    // turned over, world +x is the light's +y.
    assert_close(world_to_light * Vec3::Y, Vec3::X, 1e-6);
    assert_close(world_to_light * Vec3::X, Vec3::Y, 1e-6);
    assert_eq!((scale, image.width, image.height), (3.0, 4, 2));
    assert!((image.tan_half_fov - 22.5f32.to_radians().tan()).abs() < 1e-6);
    // Along the axis: the window's centre, between columns 1 and 2 and rows 0 and 1.
    assert_eq!(image.towards(Vec3::new(1e-3, 1e-3, 1.0)), Some(Rgb::new(2.0, 1.0, 0.5)));
    assert_eq!(image.towards(Vec3::new(-1e-3, -1e-3, 1.0)), Some(Rgb::new(1.0, 0.0, 0.5)));
    assert_eq!(image.towards(Vec3::new(0.0, 0.0, -1.0)), None, "behind");
    assert_eq!(image.towards(Vec3::new(0.0, 0.5, 1.0)), None, "above the window");
    let Light::Projection { scale, ref image, .. } = lights[1] else { panic!() };
    let emitted = scale * atoll_scene::luminance(image.power());
    assert!((emitted - 10.0).abs() < 1e-4, "{emitted}");
    for (statement, message) in [
        ("LightSource \"projection\"", "\"filename\" must be given"),
        ("LightSource \"projection\" \"string filename\" \"none.exr\"", "none.exr"),
        ("LightSource \"projection\" \"string filename\" \"slide.exr\" \"float fov\" 180", "\"fov\" 180"),
    ] {
        let e = load(statement).unwrap_err().to_string();
        assert!(e.starts_with("p.pbrt:2:1: light \"projection\"") && e.contains(message), "{e}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// pbrt-v4's `measured` material: its `.bsdf` file read once however many
/// materials name it; a missing file (unless `--allow-missing`: then
/// diffuse, with a warning), a truncated one or no `filename` is an error
/// at the material's line.
#[test]
fn measured_materials() {
    let dir = std::env::temp_dir().join(format!("atoll-measured-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bsdf = std::fs::read(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/measured-ggx.bsdf"),
    )
    .unwrap();
    std::fs::write(dir.join("ggx.bsdf"), &bsdf).unwrap();
    std::fs::write(dir.join("cut.bsdf"), &bsdf[..bsdf.len() / 2]).unwrap();
    let load = |world: &str| atoll_scene::pbrt::load_str(&format!("WorldBegin\n{world}\n"), "m.pbrt", &dir);
    let triangle = tri([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let measured = |file: &str| format!("Material \"measured\" \"string filename\" \"{file}\"\n{triangle}\n");
    let loaded = load(&format!("{}{}", measured("ggx.bsdf"), measured("ggx.bsdf"))).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let s = &loaded.scene;
    assert_eq!(s.measured.len(), 1, "one file, read once");
    assert!(s.materials.iter().all(|m| *m == Material::Measured { brdf: 0 }), "{:?}", s.materials);
    let brdf = &s.measured[0];
    assert!(brdf.isotropic);
    assert_eq!((brdf.theta_i.len(), brdf.vndf.nx, brdf.vndf.ny, brdf.rgb.planes), (9, 32, 32, 3));
    for (file, message) in [("cut.bsdf", "cut.bsdf: field"), ("none.bsdf", "none.bsdf")] {
        let e = load(&measured(file)).unwrap_err().to_string();
        assert!(e.starts_with("m.pbrt:2:1: material \"measured\": ") && e.contains(message), "{e}");
    }
    let allowed = allowing_missing(|| load(&measured("none.bsdf"))).unwrap();
    assert_eq!(allowed.scene.materials, vec![Material::default_diffuse()]);
    assert!(
        allowed.warnings[0].message.contains("its measured reflection is lost"),
        "{:?}",
        allowed.warnings
    );
    let e = load("Material \"measured\"").unwrap_err().to_string();
    assert!(e.starts_with("m.pbrt:2:1: ") && e.contains("\"filename\" must be given"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn quadrics_and_unsupported_shapes() {
    let loaded = load_world(
        "",
        "Translate 0 2 0\nShape \"sphere\" \"float radius\" 0.5\nShape \"disk\" \"float radius\" 2\n\
         Shape \"cylinder\" \"float zmax\" 3 \"float phimax\" 180\nShape \"nurbs\"",
    )
    .unwrap();
    let s = &loaded.scene;
    assert_eq!(s.meshes.len(), 3);
    let [sphere, disk, cylinder] = [&s.meshes[0], &s.meshes[1], &s.meshes[2]];
    assert_eq!(sphere.triangle_count(), 64 * 32 * 2 - 2 * 64);
    assert!(sphere.positions.iter().all(|p| ((*p - Vec3::new(0.0, 2.0, 0.0)).length() - 0.5).abs() < 1e-5));
    assert_eq!(sphere.normals.len(), sphere.positions.len());
    // The disk lies in the plane z = 0 (moved up y by 2), radius 2.
    assert!(disk.positions.iter().all(|p| p.z == 0.0 && (p.y - 2.0).abs() <= 2.0 + 1e-5));
    assert!(disk.positions.iter().any(|p| ((*p - Vec3::new(0.0, 2.0, 0.0)).length() - 2.0).abs() < 1e-5));
    // Half a cylinder of radius 1 from z = -1 to 3, on the side of +y.
    assert!(cylinder.positions.iter().all(|p| (-1.0..=3.0).contains(&p.z) && p.y >= 2.0 - 1e-6));
    assert_eq!(cylinder.uvs.len(), cylinder.positions.len());
    let w: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(w, ["test.pbrt:7:1: unsupported shape \"nurbs\" skipped"]);
}

#[test]
fn unused_parameters_and_ignored_directives_warn() {
    let loaded = load_str_warnings(
        "Camera \"perspective\" \"float fov\" 30 \"float fovv\" 2\nPixelFilter \"gaussian\" \"float alpha\" 2\nWorldBegin\n\
         MakeNamedMedium \"fog\" \"string type\" \"nanovdb\"\nAttributeBegin\nTransformBegin\nTransformEnd\n",
    );
    let w: Vec<String> = loaded.iter().map(|w| w.to_string()).collect();
    assert_eq!(w[0], "u.pbrt:1:37: Camera \"perspective\": unused parameter \"float fovv\"");
    // pbrt-v3's Gaussian took `alpha`; pbrt-v4's takes `sigma`.
    assert!(w[1].starts_with("u.pbrt:2:") && w[1].contains("unused parameter \"float alpha\""), "{w:?}");
    assert!(
        w[2].starts_with("u.pbrt:4:1: MakeNamedMedium \"fog\": medium type \"nanovdb\" is not supported"),
        "{w:?}"
    );
    assert!(w[3].starts_with("u.pbrt:6:1: TransformBegin/End are deprecated"), "{w:?}");
    assert!(w[4].starts_with("u.pbrt:5:1: AttributeBegin has no AttributeEnd"), "{w:?}");
    assert_eq!(w.len(), 5);
}

#[test]
fn pixel_filters_take_pbrt_v4s_defaults() {
    use atoll_scene::PixelFilter;
    let filter = |text: &str| {
        let loaded = atoll_scene::pbrt::load_str(text, "f.pbrt", std::path::Path::new(".")).unwrap();
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        loaded.scene.settings.film.filter
    };
    let r = glam::Vec2::splat;
    assert_eq!(
        filter("WorldBegin"),
        PixelFilter::Gaussian { radius: r(1.5), sigma: 0.5 },
        "pbrt-v4's default"
    );
    assert_eq!(filter("PixelFilter \"box\"\nWorldBegin"), PixelFilter::PIXEL);
    assert_eq!(
        filter("PixelFilter \"gaussian\" \"float xradius\" 2 \"float sigma\" 0.7\nWorldBegin"),
        PixelFilter::Gaussian { radius: glam::Vec2::new(2.0, 1.5), sigma: 0.7 }
    );
    assert_eq!(
        filter("PixelFilter \"mitchell\" \"float B\" 0.5\nWorldBegin"),
        PixelFilter::Mitchell { radius: r(2.0), b: 0.5, c: 1.0 / 3.0 }
    );
    assert_eq!(
        filter("PixelFilter \"sinc\"\nWorldBegin"),
        PixelFilter::LanczosSinc { radius: r(4.0), tau: 3.0 }
    );
    assert_eq!(filter("PixelFilter \"triangle\"\nWorldBegin"), PixelFilter::Triangle { radius: r(2.0) });
    // Scenes not from pbrt files keep each sample in its pixel.
    assert_eq!(atoll_scene::FilmSettings::default().filter, PixelFilter::PIXEL);
    for (text, message) in [
        ("PixelFilter \"blackman\"", "f.pbrt:1:1: PixelFilter: unknown filter \"blackman\""),
        (
            "PixelFilter \"box\" \"float xradius\" 0",
            "f.pbrt:1:1: PixelFilter \"box\": radius (0, 0.5) must be in (0, 16]",
        ),
        (
            "PixelFilter \"gaussian\" \"float sigma\" -1",
            "f.pbrt:1:1: PixelFilter \"gaussian\": \"sigma\" must be positive",
        ),
        (
            "PixelFilter \"mitchell\" \"float B\" 3e38",
            "f.pbrt:1:1: PixelFilter \"mitchell\": its negative lobes cancel the rest",
        ),
        (
            "PixelFilter \"mitchell\" \"float C\" 50",
            "f.pbrt:1:1: PixelFilter \"mitchell\": its negative lobes cancel the rest",
        ),
    ] {
        let text = format!("{text}\nWorldBegin");
        let e =
            atoll_scene::pbrt::load_str(&text, "f.pbrt", std::path::Path::new(".")).unwrap_err().to_string();
        assert!(e.starts_with(message), "{e}");
    }
}

fn load_str_warnings(text: &str) -> Vec<atoll_scene::Warning> {
    atoll_scene::pbrt::load_str(text, "u.pbrt", std::path::Path::new(".")).unwrap().warnings
}

#[test]
fn transform_begin_restores_the_graphics_state() {
    let world =
        format!("TransformBegin\nTranslate 1 0 0\nMaterial \"dielectric\"\nTransformEnd\n{}", tri(UNIT_TRI));
    let s = load_world("", &world).unwrap().scene;
    assert_close(s.meshes[0].positions[0], Vec3::X, 0.0);
    assert_eq!(s.materials[s.meshes[0].material as usize], Material::default_diffuse());
}

/// `LightSource "infinite" "string filename"`: the image becomes an
/// environment light (lat-long for a 2:1 image), rotated by the CTM.
#[test]
fn infinite_light_with_an_image() {
    let dir = std::env::temp_dir().join(format!("atoll-pbrt-env-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    exr::prelude::write_rgb_file(dir.join("sky.exr"), 8, 4, |x, _| (x as f32, 1.0, 2.0)).unwrap();
    let text = "WorldBegin\nAttributeBegin\nRotate 90 1 0 0\nLightSource \"infinite\" \"string filename\" \"sky.exr\" \"float scale\" 3\nAttributeEnd\n";
    let loaded = atoll_scene::pbrt::load_str(text, "env.pbrt", &dir).unwrap();
    let Light::Environment { image, scale, light_to_world, .. } = &loaded.scene.lights[0] else {
        panic!("{:?}", loaded.scene.lights)
    };
    assert_eq!((image.width, image.height, image.layout), (8, 4, atoll_scene::EnvLayout::LatLong));
    assert_eq!(image.pixels[5], Rgb::new(5.0, 1.0, 2.0));
    assert_eq!(*scale, Rgb::splat(3.0));
    assert_close(*light_to_world * Vec3::Z, -Vec3::Y, 1e-6);
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    std::fs::remove_dir_all(&dir).ok();
}

/// pbrt-v4's `illuminance`: an infinite light is scaled so that an upward
/// (+z in light space) surface receives that illuminance: π·luminance(L)
/// for a constant one, the image's upper-hemisphere integral for a map.
#[test]
fn infinite_light_illuminance_sets_the_upward_illuminance() {
    let dir = std::env::temp_dir().join(format!("atoll-pbrt-illum-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    exr::prelude::write_rgb_file(dir.join("sky.exr"), 64, 32, |_, y| {
        if y < 16 {
            (2.0, 2.0, 2.0)
        } else {
            (9.0, 0.0, 0.0)
        }
    })
    .unwrap();
    let text = r#"WorldBegin
LightSource "infinite" "rgb L" [0.5 0.5 0.5] "float illuminance" 10 "float scale" 2
LightSource "infinite" "string filename" "sky.exr" "float illuminance" 10
"#;
    let loaded = atoll_scene::pbrt::load_str(text, "env.pbrt", &dir).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let Light::Infinite { radiance, portal: None } = loaded.scene.lights[0] else {
        panic!("{:?}", loaded.scene.lights)
    };
    // 0.5 * 2 * 10 / (π * 0.5): illuminance 2 × 10 with the scale.
    assert_close(radiance, Vec3::splat(20.0 / std::f32::consts::PI), 1e-5);
    let Light::Environment { image, scale, .. } = &loaded.scene.lights[1] else { panic!() };
    // The upper half (rows 0..16 of a lat-long map) is a uniform 2: E = 2π.
    let e = image.upper_hemisphere_illuminance() * scale.x as f64;
    assert!((e - 10.0).abs() < 0.05, "{e}");
    assert!((scale.x - 10.0 / (2.0 * std::f32::consts::PI)).abs() < 0.01, "{scale}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `loopsubdiv` is refined at load (4^levels triangles per control
/// triangle, smooth normals); `bilinearmesh` patches become triangles.
#[test]
fn loop_subdivision_and_bilinear_patches() {
    let world = "Shape \"loopsubdiv\" \"integer levels\" 2 \"point3 P\" [1 1 1 1 -1 -1 -1 1 -1 -1 -1 1] \
                 \"integer indices\" [0 1 2 0 3 1 0 2 3 1 3 2]\n\
                 Translate 0 0 5\n\
                 Shape \"bilinearmesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 1 1 1] \"point2 uv\" [0 0 1 0 0 1 1 1]";
    let loaded = load_world("", world).unwrap();
    let s = &loaded.scene;
    assert_eq!(s.meshes.len(), 2);
    let sub = &s.meshes[0];
    assert_eq!(sub.indices.len(), 4 * 16);
    assert_eq!(sub.normals.len(), sub.positions.len());
    let patch = &s.meshes[1];
    let g = atoll_scene::pbrt::subdivision::BILINEAR_GRID as usize;
    assert_eq!(patch.indices.len(), 2 * g * g, "a curved patch is sampled on a grid");
    assert_eq!(patch.uvs.len(), patch.positions.len());
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    for bad in [
        "Shape \"loopsubdiv\" \"integer levels\" 20 \"point3 P\" [0 0 0 1 0 0 0 1 0]",
        "Shape \"bilinearmesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 1 1 0 2 2 2] \"integer indices\" [0 1 2]",
        "Shape \"bilinearmesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 1 1 0] \"integer indices\" [0 1 2 7]",
    ] {
        let e = load_world("", bad).unwrap_err().to_string();
        assert!(
            e.starts_with("test.pbrt:3:") && (e.contains("loopsubdiv") || e.contains("bilinearmesh")),
            "{e}"
        );
    }
}

/// The repository's feature scene (scenes/features.pbrt, rendered on CPU and
/// GPU by scripts/gpu-check) loads without a warning.
#[test]
fn the_feature_scene_loads_cleanly() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/features.pbrt");
    let loaded = atoll_scene::pbrt::load_file(&path).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let s = &loaded.scene;
    assert!(matches!(s.lights[0], Light::Environment { .. }) && matches!(s.lights[1], Light::Spot { .. }));
    let kinds: Vec<&Material> = s.meshes.iter().map(|m| &s.materials[m.material as usize]).collect();
    assert!(matches!(kinds[1], Material::Mix { .. }));
    assert!(matches!(kinds[2], Material::ThinDielectric { .. }));
    assert!(matches!(kinds[3], Material::DiffuseTransmission { .. }));
}

/// The repository's texture scene (scenes/textures.pbrt, rendered on CPU
/// and GPU by scripts/gpu-check) loads without a warning, with its images,
/// bindings, alpha masks and emission image.
#[test]
fn the_texture_scene_loads_cleanly() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/textures.pbrt");
    let loaded = atoll_scene::pbrt::load_file(&path).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let s = &loaded.scene;
    let t = &s.textures;
    // Bricks, leaf and leaf mask as MIP pyramids (bricks made once for two
    // uses), and the sign's emission image as it is: every image is one
    // texture's, each range of images made once.
    let ranges: std::collections::BTreeSet<_> = t
        .textures
        .iter()
        .filter_map(|x| match *x {
            atoll_scene::Texture::Image { image, levels, filter, .. } => {
                Some((image, levels, filter != atoll_scene::ImageFilter::None))
            }
            _ => None,
        })
        .collect();
    let filtered = ranges.iter().filter(|r| r.2).count();
    assert_eq!((ranges.len(), filtered), (4, 3), "{ranges:?}");
    assert_eq!(t.images.len() as u32, ranges.iter().map(|r| r.1).sum::<u32>());
    assert_eq!(s.meshes.iter().filter(|m| m.alpha.is_some()).count(), 4, "three leaves and the pane");
    assert_eq!(t.emission.len(), 1, "the glowing sign");
    let params: std::collections::HashSet<_> = t.bindings.iter().map(|b| b.param).collect();
    for p in [
        atoll_scene::TexturedParam::Reflectance,
        atoll_scene::TexturedParam::Roughness,
        atoll_scene::TexturedParam::Amount,
    ] {
        assert!(params.contains(&p), "{p:?} bound");
    }
    assert!(s.materials.iter().any(|m| matches!(m, Material::CoatedDiffuse(CoatedDiffuseParams { .. }))));
    assert!(s.materials.iter().any(|m| matches!(m, Material::Principled(PrincipledParams { .. }))));
}

/// A spectrum parameter naming a file reads it as pbrt-v4 does: (wavelength,
/// value) pairs, here turned into RGB; a missing file is an error at the
/// parameter unless allowed, a malformed one always.
#[test]
fn spectra_from_files() {
    let dir = common::temp_dir("spd");
    std::fs::create_dir_all(dir.join("spds")).unwrap();
    common::write(&dir, "spds/eta.spd", "# a made-up metal\n400 1.0\n500 1.0\n550 2.0\n600 2.0\n700 3.0\n");
    common::write(&dir, "bad.spd", "400 1.0\n300 2.0\n");
    let load = |world: &str| {
        atoll_scene::pbrt::load_str(&format!("WorldBegin\n{world}\n{}", tri(UNIT_TRI)), "s.pbrt", &dir)
    };
    let m = load("Material \"conductor\" \"spectrum eta\" \"spds/eta.spd\" \"spectrum k\" \"metal-Au-k\"")
        .unwrap();
    let Material::Conductor { eta, .. } = m.scene.materials[m.scene.meshes[0].material as usize] else {
        panic!("{:?}", m.scene.materials)
    };
    // Band averages: red 600–700 nm, green 500–600, blue 400–500.
    assert!((eta - Rgb::new(2.5, 1.75, 1.0)).abs().max_element() < 0.06, "{eta}");
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);

    let e = load("Material \"conductor\" \"spectrum eta\" \"spds/gone.spd\"").unwrap_err().to_string();
    assert!(e.starts_with("s.pbrt:2:") && e.contains("gone.spd") && e.contains("--allow-missing"), "{e}");
    let allowed =
        allowing_missing(|| load("Material \"conductor\" \"spectrum eta\" \"spds/gone.spd\"")).unwrap();
    let w: Vec<String> = allowed.warnings.iter().map(|w| w.to_string()).collect();
    assert!(w.iter().any(|w| w.contains("gone.spd") && w.contains("using copper")), "{w:?}");

    let e = allowing_missing(|| load("Material \"conductor\" \"spectrum k\" \"bad.spd\"")).unwrap_err();
    assert!(e.to_string().contains("do not increase"), "{e}");

    // Lights normalise a file's spectrum to luminance 1, as pbrt-v4 does.
    common::write(&dir, "warm.spd", "400 0.5 500 1.0 600 2.0 700 3.0");
    let l = load("LightSource \"point\" \"spectrum I\" \"warm.spd\"").unwrap();
    let Light::Point { intensity, .. } = l.scene.lights[0] else { panic!() };
    assert!(
        (atoll_scene::luminance(intensity) - 1.0).abs() < 1e-4 && intensity.x > intensity.z,
        "{intensity}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// pbrt-v4's infinite-light `portal`: four corners in world space (the
/// light's transform does not move them), a rectangle; other point counts
/// and shapes are `file:line` errors.
#[test]
fn infinite_light_portals_are_read() {
    let load = |text: &str| atoll_scene::pbrt::load_str(text, "u.pbrt", std::path::Path::new("."));
    let portal = "\"point3 portal\" [ 0 0 0  1 0 0  1 1 0  0 1 0 ]";
    let loaded = load(&format!("WorldBegin\nTranslate 0 0 5\nLightSource \"infinite\" {portal}")).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let Light::Infinite { portal: Some(p), .. } = loaded.scene.lights[0] else {
        panic!("{:?}", loaded.scene.lights)
    };
    assert_eq!(
        p.corners,
        [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0)
        ]
    );
    for (bad, why) in [
        ("[ 0 0 0  1 0 0 ]", "needs 4 points"),
        ("[ 0 0 0  1 0 0  1.5 1 0  0 1 0 ]", "not a planar rectangle"),
        ("[ 0 0 0  0 0 0  0 0 0  0 0 0 ]", "coincide"),
    ] {
        let e = load(&format!("WorldBegin\nLightSource \"infinite\" \"point3 portal\" {bad}"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("u.pbrt:2:1: ") && e.contains(why), "{e}");
    }
}

/// pbrt-v4's homogeneous medium: defaults, `scale`, named media on the two
/// sides of a shape (inside behind the normal), the camera's medium (the
/// outside one where `Camera` is), and the errors.
#[test]
fn media_and_their_interfaces() {
    use atoll_scene::{HomogeneousMedium, Medium, MediumInterface};
    let loaded = atoll_scene::pbrt::load_str(
        "MakeNamedMedium \"air\" \"string type\" \"homogeneous\"\n\
         MakeNamedMedium \"ink\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [1 2 3] \"spectrum sigma_s\" [300 0.5 800 0.5] \"float scale\" 2 \"float g\" -0.3 \"rgb Le\" [1 1 0]\n\
         MediumInterface \"ink\" \"air\"\n\
         Camera \"perspective\"\nWorldBegin\n\
         MediumInterface \"ink\" \"\"\n\
         Shape \"sphere\"\n\
         MediumInterface \"air\" \"air\"\n\
         Shape \"sphere\"\n",
        "m.pbrt",
        std::path::Path::new("."),
    )
    .unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let scene = loaded.scene;
    assert_eq!(scene.media[0], Medium::Homogeneous(HomogeneousMedium::pbrt_default()));
    let Medium::Homogeneous(ink) = scene.media[1].clone() else { panic!("{:?}", scene.media) };
    assert_eq!(ink.sigma_a, Vec3::new(2.0, 4.0, 6.0));
    assert!((ink.sigma_s - Vec3::splat(1.0)).abs().max_element() < 1e-3, "{}", ink.sigma_s);
    assert_eq!((ink.g, ink.le), (-0.3, Vec3::new(1.0, 1.0, 0.0)));
    assert_eq!(scene.settings.camera_medium, 1, "the camera is in \"air\", the outside");
    assert_eq!(scene.meshes[0].media, Some(MediumInterface { inside: 2, outside: 0 }));
    assert_eq!(scene.meshes[1].media, None, "the same medium on both sides is no boundary");

    for (text, error) in [
        ("WorldBegin\nMediumInterface \"smoke\" \"\"\nShape \"sphere\"\n", "e.pbrt:2:1: MediumInterface: medium \"smoke\" is not defined"),
        ("MediumInterface \"\" \"smoke\"\nCamera \"perspective\"\nWorldBegin\n", "e.pbrt:1:1: MediumInterface: medium \"smoke\" is not defined"),
        ("WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"homogeneous\" \"float g\" 1\n", "e.pbrt:2:1: MakeNamedMedium \"m\": \"g\" 1 must be between -1 and 1"),
        ("WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"homogeneous\"\nMakeNamedMedium \"m\" \"string type\" \"homogeneous\"\n", "e.pbrt:3:1: MakeNamedMedium: medium \"m\" redefined"),
    ] {
        let e = atoll_scene::pbrt::load_str(text, "e.pbrt", std::path::Path::new(".")).unwrap_err();
        assert_eq!(e.to_string(), error);
    }
}

/// pbrt-v4's `uniformgrid`: its samples and box, placed by the transform
/// where it is defined, the density scaling σa and σs, `Le` constant or
/// times an `Lescale` grid, or a `temperature` grid's blackbody times
/// `Lescale`; wrong sample counts are errors.
#[test]
fn grid_media_read_their_samples() {
    use atoll_scene::{FieldSource, GridField, Medium};
    let loaded = atoll_scene::pbrt::load_str(
        "WorldBegin\nTranslate 1 2 3\n\
         MakeNamedMedium \"smoke\" \"string type\" \"uniformgrid\" \"integer nx\" 2 \"integer nz\" 3 \"float density\" [1 2 3 4 5 6] \"point3 p1\" [2 1 3] \"float scale\" 0.5 \"rgb Le\" [1 2 3]\n\
         MakeNamedMedium \"fire\" \"string type\" \"uniformgrid\" \"integer nx\" 2 \"float density\" [1 2] \"float Lescale\" [0.5 4] \"rgb Le\" [1 1 1]\n\
         MakeNamedMedium \"hot\" \"string type\" \"uniformgrid\" \"integer nx\" 3 \"float density\" [1 1 1] \"float temperature\" [700 1100 1200] \"float Lescale\" [1 2 3]\n  \"float temperatureoffset\" 200 \"float temperaturescale\" 4\n",
        "g.pbrt",
        std::path::Path::new("."),
    )
    .unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let Medium::Grid(g) = &loaded.scene.media[0] else { panic!("{:?}", loaded.scene.media) };
    assert_eq!(
        (g.resolution, g.channels, g.values.len(), g.lo, g.hi),
        ([2, 1, 3], 1, 6, Vec3::ZERO, Vec3::new(2.0, 1.0, 3.0))
    );
    assert_eq!(g.sigma_s, GridField { scale: Vec3::splat(0.5), source: FieldSource::Scalar(0) });
    assert_eq!(g.le, GridField::constant(Vec3::new(1.0, 2.0, 3.0)));
    assert_eq!(g.world_to_medium.transform_point3(Vec3::new(1.0, 2.0, 3.0)), Vec3::ZERO);
    let Medium::Grid(fire) = &loaded.scene.media[1] else { panic!() };
    // The density's plane, then Lescale's.
    assert_eq!((fire.channels, &fire.values[..]), (2, &[1.0, 2.0, 0.5, 4.0][..]));
    assert_eq!(fire.le, GridField { scale: Vec3::ONE, source: FieldSource::Scalar(1) });
    // A blackbody per sample at (T - 200) * 4 kelvin, times Lescale: a
    // plane per colour after the density's.
    let Medium::Grid(hot) = &loaded.scene.media[2] else { panic!() };
    assert_eq!((hot.channels, hot.le), (4, GridField { scale: Vec3::ONE, source: FieldSource::Rgb(1) }));
    for (i, (kelvin, scale)) in [(2000.0, 1.0), (3600.0, 2.0), (4000.0, 3.0)].into_iter().enumerate() {
        let want = atoll_scene::pbrt::spectrum::blackbody_peak_normalised_rgb(kelvin) * scale;
        let got = Vec3::new(hot.values[3 + i], hot.values[6 + i], hot.values[9 + i]);
        assert!((got - want).abs().max_element() < 1e-4 * want.max_element(), "{kelvin} K: {got} vs {want}");
    }
    for (text, error) in [
        (
            "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"integer nx\" 2 \"float density\" [1]\n",
            "e.pbrt:2:1: MakeNamedMedium \"m\": \"density\" has 1 values for 2x1x1 samples",
        ),
        (
            "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"integer nx\" 2 \"float density\" [1 1] \"rgb Le\" [1 1 1] \"float Lescale\" 2\n",
            "e.pbrt:2:1: MakeNamedMedium \"m\": \"Lescale\" has 1 values for 2x1x1 samples",
        ),
        (
            "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"float density\" [1] \"float temperature\" [900] \"rgb Le\" [1 1 1]\n",
            "e.pbrt:2:1: MakeNamedMedium \"m\": both \"Le\" and \"temperature\" values were given",
        ),
        (
            "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"integer nx\" 2 \"float density\" [1 1] \"float temperature\" [900]\n",
            "e.pbrt:2:1: MakeNamedMedium \"m\": \"temperature\" has 1 values for 2x1x1 samples",
        ),
        (
            "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"float density\" [-1]\n",
            "e.pbrt:2:1: MakeNamedMedium \"m\": \"density\" value -1 must be finite and not negative",
        ),
    ] {
        let e = atoll_scene::pbrt::load_str(text, "e.pbrt", std::path::Path::new(".")).unwrap_err();
        assert_eq!(e.to_string(), error);
    }
}

/// pbrt-v4's `rgbgrid`: σa, σs and Le as RGB samples (a missing σa or σs
/// is 1), `scale` on both cross sections, `Lescale` on the emission; it
/// needs σa or σs, and σa where it has Le.
#[test]
fn rgb_grid_media_read_their_samples() {
    use atoll_scene::{FieldSource, GridField, Medium};
    let loaded = atoll_scene::pbrt::load_str(
        "WorldBegin\n\
         MakeNamedMedium \"a\" \"string type\" \"rgbgrid\" \"integer nx\" 2 \"rgb sigma_s\" [1 2 3 4 5 6] \"float scale\" 2\n\
         MakeNamedMedium \"b\" \"string type\" \"rgbgrid\" \"integer ny\" 2 \"rgb sigma_a\" [1 1 1 2 2 2] \"rgb Le\" [0 1 0 0 0 1] \"float Lescale\" 3 \"float g\" 0.5\n",
        "g.pbrt",
        std::path::Path::new("."),
    )
    .unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let Medium::Grid(a) = &loaded.scene.media[0] else { panic!() };
    assert_eq!(
        (a.resolution, a.channels, &a.values[..]),
        ([2, 1, 1], 3, &[1.0, 4.0, 2.0, 5.0, 3.0, 6.0][..])
    );
    assert_eq!(a.sigma_a, GridField::constant(Vec3::splat(2.0)));
    assert_eq!(a.sigma_s, GridField { scale: Vec3::splat(2.0), source: FieldSource::Rgb(0) });
    assert_eq!(a.le, GridField::constant(Vec3::ZERO));
    let Medium::Grid(b) = &loaded.scene.media[1] else { panic!() };
    assert_eq!((b.channels, b.values.len(), b.g), (6, 12, 0.5));
    // A plane per colour: σa's three, then Le's.
    assert_eq!(&b.values[..], &[1.0, 2.0, 1.0, 2.0, 1.0, 2.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
    assert_eq!(b.sigma_a, GridField { scale: Vec3::ONE, source: FieldSource::Rgb(0) });
    assert_eq!(b.sigma_s, GridField::constant(Vec3::ONE));
    assert_eq!(b.le, GridField { scale: Vec3::splat(3.0), source: FieldSource::Rgb(3) });
    for (text, error) in [
        (
            "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"rgbgrid\"\n",
            "e.pbrt:2:1: MakeNamedMedium \"m\": an rgbgrid needs \"sigma_a\" or \"sigma_s\" values",
        ),
        (
            "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"rgbgrid\" \"rgb sigma_s\" [1 1 1] \"rgb Le\" [1 1 1]\n",
            "e.pbrt:2:1: MakeNamedMedium \"m\": an rgbgrid with \"Le\" values needs \"sigma_a\" values",
        ),
        (
            "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"rgbgrid\" \"integer nx\" 2 \"rgb sigma_s\" [1 1 1]\n",
            "e.pbrt:2:1: MakeNamedMedium \"m\": \"sigma_s\" has 1 RGB values for 2x1x1 samples",
        ),
    ] {
        let e = atoll_scene::pbrt::load_str(text, "e.pbrt", std::path::Path::new(".")).unwrap_err();
        assert_eq!(e.to_string(), error);
    }
}

/// pbrt-v4's `path` integrator skips media boundaries and sees no media
/// (its default, `volpath`, renders them): under it the media are left
/// out, with a warning where it is named.
#[test]
fn the_path_integrator_renders_no_media() {
    let text = |integrator: &str| {
        format!(
            "{integrator}MakeNamedMedium \"fog\" \"string type\" \"homogeneous\"\nMediumInterface \"\" \"fog\"\n\
             Camera \"perspective\"\nWorldBegin\nMediumInterface \"fog\" \"\"\nShape \"sphere\"\n"
        )
    };
    let load = |t: String| atoll_scene::pbrt::load_str(&t, "p.pbrt", std::path::Path::new(".")).unwrap();
    let path = load(text("Integrator \"path\"\n"));
    let w: Vec<String> = path.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(
        w,
        ["p.pbrt:1:1: integrator \"path\" renders no participating media, as in pbrt-v4; 1 media left out (\"volpath\" renders them)"]
    );
    assert!(path.scene.media.is_empty() && path.scene.meshes[0].media.is_none());
    assert_eq!(path.scene.settings.camera_medium, 0);
    for kept in [text(""), text("Integrator \"volpath\"\n")] {
        let scene = load(kept).scene;
        assert_eq!((scene.media.len(), scene.settings.camera_medium), (1, 1));
        assert!(scene.meshes[0].media.is_some());
    }
}

/// pbrt-v4's `realistic` camera: its lens file read beside the scene,
/// focused once the film (its `diagonal`, millimetres) is known; a stop
/// asked wider than the lens's is clamped with a warning; pbrt's built-in
/// aperture shapes are drawn, a missing aperture image is an error; a
/// missing lens file is an error unless allowed (a perspective camera
/// then), a malformed one always, naming the line.
#[test]
fn realistic_cameras() {
    let dir = common::temp_dir("lens");
    common::write(
        &dir,
        "singlet.dat",
        "# radius thickness eta aperture\n50 5 1.5 20\n-50 2 1 20\n0 40 1 12\n",
    );
    common::write(&dir, "bad.dat", "50 5 1.5 20\n-50 2 x 20\n");
    let load = |camera: &str| {
        atoll_scene::pbrt::load_str(
            &format!("{camera}\nFilm \"rgb\" \"float diagonal\" 24\nWorldBegin\n{}", tri(UNIT_TRI)),
            "c.pbrt",
            &dir,
        )
    };
    let loaded = load(
        "Camera \"realistic\" \"string lensfile\" \"singlet.dat\" \"float aperturediameter\" 20 \
         \"float focusdistance\" 3 \"string aperture\" \"star\"",
    )
    .unwrap();
    let camera = &loaded.scene.settings.camera;
    assert_eq!(camera.projection, atoll_scene::Projection::Realistic);
    assert_eq!(loaded.scene.settings.film.diagonal, 0.024);
    let lens = camera.lens.as_ref().unwrap();
    assert_eq!((lens.elements.len(), lens.film_diagonal), (3, 0.024));
    assert_eq!(lens.elements[2].aperture_radius, 0.006, "clamped to the stop's 12 mm");
    // Focused at 3 m: a little beyond the 50 mm focal length behind the lens.
    assert!(lens.rear_z() > 0.04 && lens.rear_z() < 0.06, "{}", lens.rear_z());
    assert!(lens.aperture.is_some(), "pbrt's built-in star");
    let warnings: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].starts_with("c.pbrt:1:1: ") && warnings[0].contains("larger than the lens's stop"));
    let e =
        load("Camera \"realistic\" \"string lensfile\" \"singlet.dat\" \"string aperture\" \"heart.png\"")
            .unwrap_err()
            .to_string();
    assert!(e.starts_with("c.pbrt:1:1: ") && e.contains("heart.png") && e.contains("--allow-missing"), "{e}");

    let e = load("Camera \"realistic\" \"string lensfile\" \"bad.dat\"").unwrap_err().to_string();
    assert!(e.starts_with("c.pbrt:1:1: ") && e.contains("bad.dat: line 2: \"x\" is not a number"), "{e}");
    let e = load("Camera \"realistic\"").unwrap_err().to_string();
    assert!(e.contains("\"lensfile\" must be given"), "{e}");
    let e = load("Camera \"realistic\" \"string lensfile\" \"singlet.dat\" \"float focusdistance\" 0.02")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("c.pbrt:1:1: ") && e.contains("too short"), "{e}");
    let missing = "Camera \"realistic\" \"string lensfile\" \"gone.dat\"";
    let e = load(missing).unwrap_err().to_string();
    assert!(e.contains("gone.dat") && e.contains("--allow-missing"), "{e}");
    let allowed = allowing_missing(|| load(missing)).unwrap();
    assert_eq!(allowed.scene.settings.camera.projection, atoll_scene::Projection::Perspective);
    std::fs::remove_dir_all(&dir).ok();
}

/// `curve` shapes become pieces of cubic Bézier segments (`2^splitdepth`
/// a segment) in the space the CTM gives: control points moved, widths
/// scaled, ribbon normals turned; their meshes' triangles are the pieces'
/// bounding proxies. Curves cannot emit, which is warned about; the size
/// check before loading counts the pieces' bytes.
#[test]
fn curves_load_as_pieces_in_world_space() {
    let world = "Translate 1 2 3\nScale 2 2 2\nRotate 90 0 0 1\n\
        AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n\
        Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 0 0 3 0 0 4 1 0 5 1 0 6 1 0] \"float width0\" 0.2 \"float width1\" 0.1 \"integer splitdepth\" 2\n\
        AttributeEnd\n\
        Shape \"curve\" \"string type\" \"ribbon\" \"point3 P\" [0 0 0 1 0 0 2 0 0 3 0 0] \"normal N\" [0 1 0 0 1 0] \"integer splitdepth\" 0\n";
    let sizes = std::sync::Arc::new(std::sync::Mutex::new(None));
    let seen = sizes.clone();
    let check: atoll_scene::input::SizeCheck = Box::new(move |s: &atoll_scene::SceneSizes| {
        *seen.lock().unwrap() = Some(*s);
        Ok(())
    });
    let budget = atoll_scene::input::LoadBudget::from_settings().with_size_check(check);
    let loaded =
        atoll_scene::input::with_budget(std::sync::Arc::new(budget), || load_world("", world)).unwrap();
    let warnings: Vec<String> = loaded.warnings.iter().map(|w| w.to_string()).collect();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(warnings[0].contains("curves cannot have its area light; dropped"), "{warnings:?}");
    let meshes = &loaded.scene.meshes;
    let (flat, ribbon) = (meshes[0].curves.as_ref().unwrap(), meshes[1].curves.as_ref().unwrap());
    assert_eq!(meshes[0].emission, None);
    assert_eq!((flat.kind, flat.pieces.len()), (atoll_scene::CurveKind::Flat, 2 * 4));
    assert_eq!((ribbon.kind, ribbon.pieces.len()), (atoll_scene::CurveKind::Ribbon, 1));
    // (1, 0, 0) in object space is (1, 2, 3) + 2 (0, 1, 0) in the world.
    assert_close(flat.pieces[0].points[0], Vec3::new(1.0, 2.0, 3.0), 1e-5);
    assert_close(flat.pieces[3].points[3], Vec3::new(1.0, 2.0 + 2.0 * 3.0, 3.0), 1e-5);
    // Widths double with the scale, running along the whole curve.
    assert!((flat.pieces[0].widths[0] - 0.4).abs() < 1e-6 && (flat.pieces[7].widths[1] - 0.2).abs() < 1e-6);
    assert!((flat.pieces[3].widths[1] - 0.3).abs() < 1e-6, "{:?}", flat.pieces[3].widths);
    assert_eq!(flat.pieces[1].u, [0.25, 0.5]);
    assert_close(ribbon.pieces[0].normals[0], Vec3::new(-1.0, 0.0, 0.0), 1e-6);
    for (mesh, curves) in [(&meshes[0], flat), (&meshes[1], ribbon)] {
        assert_eq!(mesh.indices.len(), curves.pieces.len());
        for (tri, piece) in mesh.indices.iter().zip(&curves.pieces) {
            let (lo, hi) = piece.bounds();
            assert_eq!((mesh.positions[tri[0] as usize], mesh.positions[tri[1] as usize]), (lo, hi));
        }
    }
    let sizes = sizes.lock().unwrap().expect("the size check ran");
    assert_eq!(sizes.triangles, 9);
    assert!(sizes.geometry_bytes >= flat.bytes() + ribbon.bytes(), "{sizes:?}");
}

/// Curves that cannot be made are errors at their statement: control
/// points a transform puts past the floats, and more pieces than the scene's budget of generated
/// primitives allows (drawn before they are made).
#[test]
fn bad_curves_are_errors_at_their_statement() {
    let huge = "Scale 1e30 1e30 1e30\nShape \"curve\" \"point3 P\" [0 0 0 1 0 0 1e10 0 0 3 0 0]";
    let e = load_world("", huge).unwrap_err().to_string();
    assert!(e.starts_with("test.pbrt:4:") && e.contains("non-finite"), "{e}");
    // 3 segments of 8 pieces each against a budget of 20.
    let long = "Shape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 0 0 3 0 0 4 0 0 5 0 0 6 0 0 7 0 0 8 0 0 9 0 0]";
    let budget = std::sync::Arc::new(atoll_scene::input::LoadBudget::new(u64::MAX, 20));
    let e = atoll_scene::input::with_budget(budget, || load_world("", long)).unwrap_err().to_string();
    assert!(e.starts_with("test.pbrt:3:") && e.contains("24 triangles"), "{e}");
}

/// pbrt-v4's motion blur: `ActiveTransform` picks which of the two
/// transforms directives change; a shape or instance whose two differ
/// moves between them over `TransformTimes`, and the camera's shutter says
/// when rays are traced.
#[test]
fn active_transforms_make_moving_shapes_and_instances() {
    let options =
        "TransformTimes 1 3\nCamera \"perspective\" \"float shutteropen\" 0.5 \"float shutterclose\" 2";
    let world = format!(
        "ObjectBegin \"o\"\n{still}\nObjectEnd\n\
         AttributeBegin\nTranslate 1 0 0\nActiveTransform StartTime\nTranslate 0 5 0\nActiveTransform All\n\
         {first}\nAttributeBegin\nActiveTransform EndTime\nTranslate 10 0 0\n{moving}\nAttributeEnd\n\
         ActiveTransform EndTime\nRotate 90 0 0 1\nActiveTransform All\nObjectInstance \"o\"\nAttributeEnd\n\
         {after}",
        still = tri(UNIT_TRI),
        first = tri(UNIT_TRI),
        moving = tri(UNIT_TRI),
        after = tri(UNIT_TRI),
    );
    let loaded = load_world(options, &world).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let scene = &loaded.scene;
    assert_eq!(scene.settings.camera.shutter, [0.5, 2.0]);
    assert_eq!(scene.motions.len(), 3, "{:?}", scene.motions);
    let world_point = |inst: &atoll_scene::Instance, time: f32, p: Vec3| match inst.motion {
        Some(m) => scene.motions[m as usize].at(time).transform_point3(p),
        None => inst.object_to_world.transform_point3(p),
    };
    let moving: Vec<_> = scene.instances.iter().filter(|i| i.motion.is_some()).collect();
    assert_eq!(moving.len(), 3);
    for inst in &moving {
        assert_eq!(scene.motions[inst.motion.unwrap() as usize].times, [1.0, 3.0]);
    }
    // A shape's vertices are kept in object space and the instance moves them.
    let p = Vec3::X;
    let mesh_of =
        |inst: &atoll_scene::Instance| &scene.meshes[scene.objects[inst.object as usize].meshes[0] as usize];
    for inst in &moving {
        assert_close(mesh_of(inst).positions[0], p, 0.0);
    }
    // The first moving shape: start (1, 5, 0) + p; end (1, 0, 0) + p.
    assert_close(world_point(moving[0], 0.0, p), Vec3::new(2.0, 5.0, 0.0), 1e-5);
    assert_close(world_point(moving[0], 2.0, p), Vec3::new(2.0, 2.5, 0.0), 1e-5);
    assert_close(world_point(moving[0], 3.0, p), Vec3::new(2.0, 0.0, 0.0), 1e-5);
    // The one inside the nested block: its end also moves by 10 along x.
    assert_close(world_point(moving[1], 3.0, p), Vec3::new(12.0, 0.0, 0.0), 1e-5);
    // The instance: end transform turned by 90 degrees about z, halfway by 45.
    let half = world_point(moving[2], 2.0, p);
    let r = std::f32::consts::FRAC_1_SQRT_2;
    assert_close(half, Vec3::new(1.0, 2.5, 0.0) + Vec3::new(r, r, 0.0), 1e-5);
    // After AttributeEnd nothing moves: the last shape lies in the world object.
    let world_object = scene.objects.iter().find(|o| o.name == "world").unwrap();
    assert_eq!(world_object.meshes.len(), 1);
    assert_eq!(scene.instances.len(), 4);
}

#[test]
fn moving_lights_cameras_and_area_lights_follow_pbrt() {
    let world = format!(
        "ActiveTransform EndTime\nTranslate 0 1 0\nActiveTransform All\n\
         LightSource \"point\" \"rgb I\" [1 1 1]\n\
         AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n{}\nAttributeEnd\n",
        tri(UNIT_TRI)
    );
    let err = load_world("", &world).unwrap_err();
    assert!(err.to_string().contains("area lights cannot move"), "{err}");
    assert_eq!(err.line, 9);
    // A moving camera: camera to world moves from the start's inverse to the end's.
    let camera = load_world(
        "TransformTimes 0 2\nActiveTransform StartTime\nTranslate 0 0 1\nActiveTransform All\nCamera \"perspective\"",
        "",
    )
    .unwrap();
    assert!(camera.warnings.is_empty(), "{:?}", camera.warnings);
    let cam = &camera.scene.settings.camera;
    let motion = cam.motion.expect("a moving camera");
    assert_eq!(motion.times, [0.0, 2.0]);
    assert_close(cam.camera_to_world.transform_point3(Vec3::ZERO), Vec3::new(0.0, 0.0, -1.0), 1e-6);
    assert_close(motion.at(0.0).transform_point3(Vec3::ZERO), Vec3::new(0.0, 0.0, -1.0), 1e-6);
    assert_close(motion.at(1.0).transform_point3(Vec3::ZERO), Vec3::new(0.0, 0.0, -0.5), 1e-6);
    assert_close(motion.at(2.0).transform_point3(Vec3::ZERO), Vec3::ZERO, 1e-6);
    let light = load_world("", &format!("ActiveTransform EndTime\nTranslate 0 1 0\nActiveTransform All\nLightSource \"point\" \"rgb I\" [1 1 1]\n{}", tri(UNIT_TRI))).unwrap();
    assert_eq!(light.warnings.len(), 1, "{:?}", light.warnings);
    assert!(light.warnings[0].to_string().contains("a light cannot move"));
    let err = load_world("TransformTimes 2 1", "").unwrap_err();
    assert!(err.to_string().contains("TransformTimes"), "{err}");
}

/// pbrt-v4's `subsurface`: its four ways to give the interior, `scale`,
/// and the interior each one's shapes get as the inside of their medium
/// interface (one medium per distinct interior, kept under `path`, whose
/// media pbrt-v4 drops).
#[test]
fn subsurface_materials_and_their_interiors() {
    use atoll_scene::{HomogeneousMedium, Medium, MediumInterface, SubsurfaceParams};
    let world = format!(
        "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"string preset\" \"Wholemilk\" \"float scale\" 2\n\
         Material \"subsurface\"\n{t}\n{t}\n\
         Material \"subsurface\" \"string name\" \"Skin1\" \"float scale\" 50 \"float eta\" 1.5 \"float g\" 0.3\n{t}\n\
         AttributeBegin\nMediumInterface \"\" \"fog\"\n\
         Material \"subsurface\" \"rgb sigma_a\" [0.1 0.2 0.3] \"rgb sigma_s\" [1 2 3] \"float g\" 0.5 \"float roughness\" 0.1 \"bool remaproughness\" false\n{t}\nAttributeEnd\n\
         Material \"subsurface\" \"rgb reflectance\" [0.5 0.5 0.5] \"float mfp\" 2 \"float scale\" 0.5\n{t}",
        t = tri(UNIT_TRI)
    );
    let loaded = load_world("Integrator \"path\"", &world).unwrap();
    let s = &loaded.scene;
    let params = |mesh: usize| match s.materials[s.meshes[mesh].material as usize] {
        Material::Subsurface(p) => p,
        ref other => panic!("{other:?}"),
    };
    let milk = HomogeneousMedium {
        sigma_a: Rgb::new(0.0011, 0.0024, 0.014),
        sigma_s: Rgb::new(2.55, 3.21, 3.77),
        g: 0.0,
        le: Rgb::ZERO,
    };
    assert_eq!(params(0), SubsurfaceParams { eta: 1.33, alpha_x: 0.0, alpha_y: 0.0, interior: milk });
    let skin = params(2);
    assert_eq!((skin.eta, skin.interior.g), (1.5, 0.0));
    assert_close(skin.interior.sigma_a, Rgb::new(0.032, 0.17, 0.48) * 50.0, 1e-5);
    assert_close(skin.interior.sigma_s, Rgb::new(0.74, 0.88, 1.01) * 50.0, 1e-5);
    assert!(loaded.warnings.iter().any(|w| w.message.contains("\"g\" 0.3 ignored with named coefficients")));
    let given = params(3);
    assert_eq!((given.alpha_x, given.alpha_y, given.interior.g), (0.1, 0.1, 0.5));
    assert_eq!(given.interior.sigma_s, Rgb::new(1.0, 2.0, 3.0));
    // From a diffuse reflectance: σt is 1 / (scale · mfp), the albedo high.
    let diffuse = params(4).interior;
    assert_close(diffuse.sigma_a + diffuse.sigma_s, Rgb::ONE, 1e-5);
    assert!(diffuse.sigma_s.x > 0.9 && diffuse.sigma_s.x < 1.0, "{}", diffuse.sigma_s);
    // `path` drops the fog but keeps the four interiors, each once.
    assert_eq!(s.media.len(), 4);
    let interior = |mesh: usize| match s.meshes[mesh].media {
        Some(MediumInterface { inside, outside }) => (s.media[inside as usize - 1].clone(), outside),
        None => panic!("mesh {mesh} has no interior"),
    };
    assert_eq!(interior(0), (Medium::Subsurface(milk), 0));
    assert_eq!(s.meshes[1].media, s.meshes[0].media);
    assert_ne!(s.meshes[2].media, s.meshes[0].media);
    assert!(loaded.warnings.iter().any(|w| w.message.contains("1 media left out")), "{:?}", loaded.warnings);

    // Under `volpath` the fog stays, with its preset's coefficients, and
    // is the shape's outside.
    let loaded = load_world("", &world).unwrap();
    let s = &loaded.scene;
    let Medium::Homogeneous(fog) = &s.media[0] else { panic!("{:?}", s.media[0]) };
    assert_close(fog.sigma_s, Rgb::new(2.55, 3.21, 3.77) * 2.0, 1e-5);
    assert_eq!(s.meshes[3].media.map(|m| m.outside), Some(1));
    assert_eq!(s.media.len(), 5);

    // Errors at the material's statement.
    let error = |material: &str| {
        load_world("", &format!("Material \"subsurface\" {material}\n{}", tri(UNIT_TRI)))
            .unwrap_err()
            .to_string()
    };
    assert!(error("\"string name\" \"Jam\"").contains("no measured scattering is named \"Jam\""));
    assert!(error("\"rgb sigma_a\" [1 1 1]").contains("\"sigma_a\" given without \"sigma_s\""));
    assert!(error("\"float g\" 1").contains("must be between -1 and 1"));
}

/// Subsurface interiors share the 15 media with the scene's: one too many
/// is an error at the first subsurface material, and a texture in place of
/// a coefficient is warned about (the default is used).
#[test]
fn subsurface_interiors_count_towards_the_media() {
    let fogs: String =
        (0..14).map(|i| format!("MakeNamedMedium \"fog{i}\" \"string type\" \"homogeneous\"\n")).collect();
    let subsurface =
        |i: u32| format!("Material \"subsurface\" \"float scale\" {}\n{}\n", i + 1, tri(UNIT_TRI));
    let fits = format!("{fogs}{}", subsurface(0));
    let loaded = load_world("", &fits).unwrap();
    assert_eq!(loaded.scene.media.len(), 15);
    let too_many = format!("{fogs}{}{}", subsurface(0), subsurface(1));
    let e = load_world("", &too_many).unwrap_err().to_string();
    assert!(e.contains("need more than 15 media"), "{e}");
    // `load_world` puts two lines before the world: the fogs take 14 more.
    assert!(e.starts_with("test.pbrt:17:1:"), "the first subsurface material's statement: {e}");
    let textured = format!(
        "Texture \"t\" \"spectrum\" \"constant\" \"rgb value\" [0.5 0.5 0.5]\n\
         Material \"subsurface\" \"texture sigma_a\" \"t\" \"rgb sigma_s\" [1 1 1]\n{}",
        tri(UNIT_TRI)
    );
    let loaded = load_world("", &textured).unwrap();
    assert!(
        loaded.warnings.iter().any(|w| w.message.contains("textured \"sigma_a\" not supported")),
        "{:?}",
        loaded.warnings
    );
    assert_eq!(loaded.warnings.len(), 1, "{:?}", loaded.warnings);
    let Material::Subsurface(p) = &loaded.scene.materials[loaded.scene.meshes[0].material as usize] else {
        panic!("{:?}", loaded.scene.materials)
    };
    assert_eq!(p.interior.sigma_s, Rgb::new(2.55, 3.21, 3.77));
}
