//! Scenes for testing textures on every device.
//!
//! [`cutout_scene`]'s image is known from geometry alone: a white ground lit
//! by a distant light through a screen of stripes. The screen is
//! either one quad whose alpha mask cuts the stripes out ([`Screen::AlphaMask`])
//! or the solid stripes as separate quads ([`Screen::Strips`]); both must
//! render the same image, shadows and all.
//!
//! The mask is a 2×1 image (alpha 0, 1), repeated, read bilinearly with a
//! cutoff of 0.5: with `u = x` on the screen it is solid where
//! `frac(x) ∈ [0.5, 1)` and a hole where `frac(x) ∈ [0, 0.5)`.

use glam::{Affine3A, Mat4, Vec2, Vec3};

use crate::{
    AlphaMode, Camera, Channel, Instance, IntegratorSettings, Light, Material, MeshAlpha, Object, Rgb, Scene,
    Texture, TextureBinding, TextureImage, TexturedParam, TriangleMesh, UvMapping, Wrap,
};

/// How the screen's stripes are made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Screen {
    /// One quad with an alpha mask.
    AlphaMask,
    /// Quads where the mask is solid.
    Strips,
}

/// Half the width of the ground and the screen.
const EXTENT: f32 = 4.0;
/// Height of the screen above the ground (z = 0).
const SCREEN_HEIGHT: f32 = 1.0;

fn quad(x0: f32, x1: f32, y0: f32, y1: f32, z: f32, material: u32) -> TriangleMesh {
    let positions =
        vec![Vec3::new(x0, y0, z), Vec3::new(x1, y0, z), Vec3::new(x1, y1, z), Vec3::new(x0, y1, z)];
    let uvs = positions.iter().map(|p| Vec2::new(p.x, p.y)).collect();
    TriangleMesh {
        name: "quad".into(),
        positions,
        uvs,
        indices: vec![[0, 1, 2], [0, 2, 3]],
        material,
        ..Default::default()
    }
}

/// The scene, seen from `eye` (above the screen sees it and the ground
/// through its holes; below it sees only the ground and the shadow).
/// The ground is textured with a checkerboard of two whites (0.8 and 0.6
/// reflectance, 1-unit squares), and the screen is a `mix` of two materials
/// chosen by a checkerboard texture, which exercises textured parameters.
pub fn cutout_scene(screen: Screen, eye: Vec3) -> Scene {
    let mut scene = Scene::default();
    let ground_material = scene.add_material(Material::Diffuse { reflectance: Rgb::splat(0.5) });
    // The screen: dark grey or dark red in a checkerboard, a `mix` whose
    // amount is a texture (0 or 1: the choice is exact on every device).
    let dark = scene.add_material(Material::Diffuse { reflectance: Rgb::splat(0.05) });
    let red = scene.add_material(Material::Diffuse { reflectance: Rgb::new(0.3, 0.02, 0.02) });
    let screen_material = scene.add_material(Material::Mix { materials: [dark, red], amount: 0.5 });
    let squares = scene.textures.add(Texture::Checkerboard {
        mapping: UvMapping { su: 0.5, sv: 0.5, du: 0.0, dv: 0.0 }.into(),
        tex: [crate::TexInput::Value(Rgb::ZERO), crate::TexInput::Value(Rgb::ONE)],
    });
    scene.textures.bind(TextureBinding {
        material: screen_material,
        param: TexturedParam::Amount,
        texture: squares,
        remap_roughness: false,
    });
    let checker = scene.textures.add(Texture::Checkerboard {
        mapping: UvMapping::default().into(),
        tex: [crate::TexInput::Value(Rgb::splat(0.8)), crate::TexInput::Value(Rgb::splat(0.6))],
    });
    scene.textures.bind(TextureBinding {
        material: ground_material,
        param: TexturedParam::Reflectance,
        texture: checker,
        remap_roughness: false,
    });
    let mut meshes = vec![quad(-EXTENT, EXTENT, -EXTENT, EXTENT, 0.0, ground_material)];
    match screen {
        Screen::AlphaMask => {
            let image = scene.textures.add_image(TextureImage::from_linear(
                "stripes",
                2,
                1,
                vec![[1.0, 1.0, 1.0, 0.0], [1.0, 1.0, 1.0, 1.0]],
            ));
            let mask = scene.textures.add(Texture::Image {
                image,
                mapping: UvMapping::default().into(),
                wrap: Wrap::Repeat,
                channel: Channel::Alpha,
                scale: 1.0,
                invert: false,
                filter: crate::ImageFilter::None,
                levels: 1,
            });
            let mut q = quad(-EXTENT, EXTENT, -EXTENT, EXTENT, SCREEN_HEIGHT, screen_material);
            q.alpha = Some(MeshAlpha { texture: mask, mode: AlphaMode::Cutoff(0.5) });
            meshes.push(q);
        }
        Screen::Strips => {
            let mut x = -EXTENT;
            while x < EXTENT {
                meshes.push(quad(x + 0.5, x + 1.0, -EXTENT, EXTENT, SCREEN_HEIGHT, screen_material));
                x += 1.0;
            }
        }
    }
    let ids = meshes.into_iter().map(|m| scene.add_mesh(m)).collect();
    let object = scene.add_object(Object { name: "world".into(), meshes: ids });
    scene.instances.push(Instance::new(object, Affine3A::IDENTITY));
    // Slightly off vertical so the shadow is displaced from the screen.
    scene
        .lights
        .push(Light::Distant { direction: Vec3::new(0.3, 0.0, -1.0).normalize(), radiance: Rgb::splat(3.0) });
    let target = Vec3::new(eye.x, eye.y, 0.0) + Vec3::new(0.0, 0.3, 0.0);
    scene.settings.camera = Camera {
        camera_to_world: crate::framing::look_at(eye, target, Vec3::Y).unwrap_or(Mat4::IDENTITY),
        fov_degrees: 60.0,
        ..Camera::default()
    };
    scene.settings.integrator = IntegratorSettings::Path { max_depth: 3 };
    scene.settings.film.resolution = glam::UVec2::new(64, 64);
    scene.settings.spp = 4;
    scene
}

/// A floor under a 2×2 square area light facing down (radiance 1, scaled
/// by `emission` when given: an emission texture over the light's uvs
/// (0,0)–(1,1)), seen from `eye` looking at `target`.
pub fn textured_light_scene(emission: Option<Texture>, eye: Vec3, target: Vec3) -> Scene {
    let mut scene = Scene::default();
    let material = scene.add_material(Material::Diffuse { reflectance: Rgb::splat(0.5) });
    let floor = scene.add_mesh(quad(-6.0, 6.0, -6.0, 6.0, 0.0, material));
    let mut light = quad(-1.0, 1.0, -1.0, 1.0, 2.0, material);
    // Facing down, uvs (0,0)–(1,1) across it.
    light.indices = vec![[0, 2, 1], [0, 3, 2]];
    light.uvs = vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)];
    light.emission = Some(crate::AreaEmission { radiance: Rgb::ONE, two_sided: false });
    let light = scene.add_mesh(light);
    if let Some(t) = emission {
        let t = scene.textures.add(t);
        scene.textures.bind_emission(light, t);
    }
    let object = scene.add_object(Object { name: "world".into(), meshes: vec![floor, light] });
    scene.instances.push(Instance::new(object, Affine3A::IDENTITY));
    scene.settings.camera = Camera {
        camera_to_world: crate::framing::look_at(eye, target, Vec3::Y).unwrap_or(Mat4::IDENTITY),
        fov_degrees: 50.0,
        ..Camera::default()
    };
    scene.settings.film.resolution = glam::UVec2::new(48, 48);
    scene.settings.spp = 16;
    scene.settings.integrator = IntegratorSettings::Path { max_depth: 2 };
    scene
}

/// How [`bent_plane_scene`]'s plane gets its tilted normal.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bend {
    /// A flat plane bump-mapped by a ramp of displacement `d = u / 2`.
    Bump,
    /// A flat plane with a normal map of the same tilt.
    NormalMap,
    /// The plane itself tilted: the displaced surface the bump stands for.
    Tilted,
}

/// The normal every [`Bend`] gives the plane: the surface `z = (x + 1) / 4`
/// over x ∈ [-1, 1], on which `u = (x + 1) / 2`.
pub fn bent_plane_normal() -> Vec3 {
    Vec3::new(-0.25, 0.0, 1.0).normalize()
}

/// A 2×2 diffuse plane (reflectance 0.5) facing +z under a distant light
/// from `(1, 0.5, 2)` (radiance 1), seen from above, its normal tilted by
/// `bend`: every pixel on it is `0.5 / π · max(0, n · l)`, whichever way
/// the tilt comes (direct light only).
pub fn bent_plane_scene(bend: Bend) -> Scene {
    let mut scene = Scene::default();
    let material = scene.add_material(Material::Diffuse { reflectance: Rgb::splat(0.5) });
    let mut plane = quad(-1.0, 1.0, -1.0, 1.0, 0.0, material);
    plane.uvs = plane.positions.iter().map(|p| Vec2::new((p.x + 1.0) / 2.0, (p.y + 1.0) / 2.0)).collect();
    let ramp = |texel: &dyn Fn(f32) -> [f32; 4]| {
        // 64 texels across u, bilinear: exact for a linear ramp between texel centres.
        let texels = (0..64).map(|i| texel((i as f32 + 0.5) / 64.0)).collect();
        TextureImage::from_linear("ramp", 64, 1, texels)
    };
    let image = |scene: &mut Scene, image: TextureImage| {
        let image = scene.textures.add_image(image);
        scene.textures.add(Texture::Image {
            image,
            mapping: UvMapping::default().into(),
            wrap: Wrap::Clamp,
            channel: Channel::Rgb,
            scale: 1.0,
            invert: false,
            filter: crate::ImageFilter::None,
            levels: 1,
        })
    };
    let bound = |scene: &mut Scene, param, texture| {
        scene.textures.bind(TextureBinding { material, param, texture, remap_roughness: false })
    };
    match bend {
        Bend::Bump => {
            let t = image(&mut scene, ramp(&|u| [u / 2.0; 4]));
            bound(&mut scene, TexturedParam::Displacement, t);
        }
        Bend::NormalMap => {
            let n = bent_plane_normal();
            let c = (n + Vec3::ONE) / 2.0;
            let t = image(&mut scene, ramp(&|_| [c.x, c.y, c.z, 1.0]));
            bound(&mut scene, TexturedParam::NormalMap, t);
        }
        Bend::Tilted => {
            for p in &mut plane.positions {
                p.z = (p.x + 1.0) / 4.0;
            }
        }
    }
    let plane = scene.add_mesh(plane);
    let object = scene.add_object(Object { name: "world".into(), meshes: vec![plane] });
    scene.instances.push(Instance::new(object, Affine3A::IDENTITY));
    scene
        .lights
        .push(Light::Distant { direction: -Vec3::new(1.0, 0.5, 2.0).normalize(), radiance: Rgb::ONE });
    scene.settings.camera = Camera {
        camera_to_world: crate::framing::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, Vec3::Y)
            .unwrap_or(Mat4::IDENTITY),
        fov_degrees: 20.0,
        ..Camera::default()
    };
    scene.settings.film.resolution = glam::UVec2::new(16, 16);
    scene.settings.spp = 1;
    scene.settings.integrator = IntegratorSettings::Path { max_depth: 1 };
    scene
}

/// The direction the camera of [`anisotropic_plane_scene`] looks from (unit,
/// from the plane towards the camera).
pub fn anisotropic_plane_view() -> Vec3 {
    Vec3::new(0.0, -1.0, 1.0).normalize()
}

/// The direction towards the distant light of [`anisotropic_plane_scene`]
/// (unit): off the mirror direction of the view, so that the highlight
/// depends on how the roughness is oriented.
pub fn anisotropic_plane_light() -> Vec3 {
    let (theta, phi) = (40f32.to_radians(), 115f32.to_radians());
    Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
}

/// The plane z = 0 of `material`, its uvs turned so that `dp/du` points
/// along `(cos a, sin a, 0)` for `a = u_angle_degrees`, seen by an
/// orthographic camera from [`anisotropic_plane_view`] and lit by a distant
/// light of radiance 1 from [`anisotropic_plane_light`], direct light only:
/// every pixel is `f(wo, wi) cos θi` of the BSDF in the frame whose x is
/// `dp/du`, whatever the material. Non-zero `bump_slopes` (a, b) bump-map
/// the plane by the displacement `a·u + b·v`, which tilts the shading
/// normal and `dp/du` (pbrt's `BumpMap`) as the surface `z = a·u + b·v`
/// would have them.
pub fn anisotropic_plane_scene(material: Material, u_angle_degrees: f32, bump_slopes: Vec2) -> Scene {
    let mut scene = Scene::default();
    let material = scene.add_material(material);
    let mut plane = quad(-2.0, 2.0, -2.0, 2.0, 0.0, material);
    let (sin, cos) = u_angle_degrees.to_radians().sin_cos();
    plane.uvs =
        plane.positions.iter().map(|p| Vec2::new(cos * p.x + sin * p.y, -sin * p.x + cos * p.y)).collect();
    if bump_slopes != Vec2::ZERO {
        // bilerp's corners (v00, v10, v01, v11) make a·u + b·v: linear
        // everywhere, past [0, 1] too.
        let corner = |v: f32| crate::TexInput::Value(Rgb::splat(v));
        let (a, b) = (bump_slopes.x, bump_slopes.y);
        let ramp = scene.textures.add(Texture::Bilerp {
            mapping: crate::TexMapping::default(),
            corners: [corner(0.0), corner(a), corner(b), corner(a + b)],
        });
        scene.textures.bind(TextureBinding {
            material,
            param: TexturedParam::Displacement,
            texture: ramp,
            remap_roughness: false,
        });
    }
    let plane = scene.add_mesh(plane);
    let object = scene.add_object(Object { name: "world".into(), meshes: vec![plane] });
    scene.instances.push(Instance::new(object, Affine3A::IDENTITY));
    scene.lights.push(Light::Distant { direction: -anisotropic_plane_light(), radiance: Rgb::ONE });
    scene.settings.camera = Camera {
        camera_to_world: crate::framing::look_at(anisotropic_plane_view() * 4.0, Vec3::ZERO, Vec3::Z)
            .unwrap_or(Mat4::IDENTITY),
        projection: crate::Projection::Orthographic,
        screen_window: Some([-1.0, 1.0, -1.0, 1.0]),
        ..Camera::default()
    };
    scene.settings.film.resolution = glam::UVec2::new(8, 8);
    scene.settings.spp = 1;
    scene.settings.integrator = IntegratorSettings::Path { max_depth: 1 };
    scene
}
