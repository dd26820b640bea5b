//! Anisotropic BSDFs turn with the surface's `dp/du`, as pbrt-v4's frame
//! `Frame::FromXZ(dpdu, ns)` does: a plane whose uvs are turned by an angle
//! shades, pixel for pixel, as the BSDF evaluated in the frame turned by
//! that angle (the scene is lit by a distant light and seen by an
//! orthographic camera, so every pixel is one known `f cos θ`).

mod common;

use std::sync::Arc;

use atoll_render::bsdf::Frame;
use atoll_render::material_coeffs::{bsdf_from_record, PackedMaterial};
use atoll_render::{RayRecord, RenderOptions};
use atoll_scene::texture_scenes::{anisotropic_plane_light, anisotropic_plane_scene, anisotropic_plane_view};
use atoll_scene::{Material, MeasuredBrdf, Rgb};
use bytemuck::Zeroable;
use common::{assert_finite, render_with};
use glam::{Vec2, Vec3};

/// The anisotropic GGX table of scripts/measured-scene.py.
fn anisotropic_table() -> Arc<MeasuredBrdf> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/measured-ggx-aniso.bsdf");
    let bytes = std::fs::read(path).unwrap();
    Arc::new(MeasuredBrdf::from_bytes(&bytes, "measured-ggx-aniso.bsdf").unwrap())
}

fn materials() -> Vec<(&'static str, Material)> {
    let (alpha_x, alpha_y) = (0.1, 0.4);
    vec![
        (
            "conductor",
            Material::Conductor {
                eta: Rgb::new(0.2, 0.9, 1.1),
                k: Rgb::new(3.9, 2.4, 2.2),
                alpha_x,
                alpha_y,
            },
        ),
        ("dielectric", Material::Dielectric { eta: 1.5, alpha_x, alpha_y }),
        ("measured", Material::Measured { brdf: 0 }),
    ]
}

/// `f(wo, wi) cos θi` of `material` in the frame of the surface
/// `z = a·u + b·v` (`slopes` (a, b)) where `dp/du` points at `angle` degrees
/// from +x: x along `dp/du + a z`, z the normal of that surface.
fn expected(material: &Material, brdfs: &[Arc<MeasuredBrdf>], angle: f32, slopes: Vec2) -> Rgb {
    let mut r = RayRecord::zeroed();
    PackedMaterial::pack(material).store(&mut r);
    let bsdf = bsdf_from_record(&r, brdfs).unwrap();
    let (sin, cos) = angle.to_radians().sin_cos();
    let (dpdu, dpdv) = (Vec3::new(cos, sin, slopes.x), Vec3::new(-sin, cos, slopes.y));
    let (x, z) = (dpdu.normalize(), dpdu.cross(dpdv).normalize());
    let frame = Frame { x, y: z.cross(x), z };
    let (wo, wi) = (frame.to_local(anisotropic_plane_view()), frame.to_local(anisotropic_plane_light()));
    bsdf.eval(wo, wi) * wi.z
}

#[test]
fn anisotropic_lobes_turn_with_dpdu() {
    let brdfs = vec![anisotropic_table()];
    for (name, material) in materials() {
        let along_x = expected(&material, &brdfs, 0.0, Vec2::ZERO);
        let along_y = expected(&material, &brdfs, 90.0, Vec2::ZERO);
        let luminance = |c: Rgb| c.x + c.y + c.z;
        assert!(
            (luminance(along_x) / luminance(along_y) - 1.0).abs() > 0.3,
            "{name}: turning the roughness should change the highlight ({along_x} and {along_y})"
        );
        // Bump-mapped too: the frame turns with the bumped dp/du.
        let flat = Vec2::ZERO;
        let bumps = [(0.0, flat), (30.0, flat), (90.0, flat), (200.0, flat), (30.0, Vec2::new(0.4, -0.3))];
        for (angle, slope) in bumps {
            let mut scene = anisotropic_plane_scene(material.clone(), angle, slope);
            scene.measured = brdfs.clone();
            let scene = Arc::new(scene);
            let film = render_with(&scene, RenderOptions::from_scene(&scene), Some(1));
            assert_finite(&film);
            let want = expected(&material, &brdfs, angle, slope);
            for (i, p) in film.pixels().iter().enumerate() {
                // The tangent and normal travel as f16.
                let error = (*p - want).abs().max_element() / want.max_element();
                assert!(error < 1e-2, "{name} at {angle}°, slope {slope}, pixel {i}: {p} against {want}");
            }
        }
    }
}
