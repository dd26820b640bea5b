//! The false-colour ownership view (the ray-queue-cycling paper's Figure 1):
//! every surface coloured by the device that holds it, lightly shaded by
//! the angle to the camera so that shapes stay readable.

use atoll_bvh::{Ray, SceneBvh};
use atoll_render::stages::generate::camera_record;
use atoll_render::{Film, FrameContext, RenderOptions};
use atoll_scene::Scene;
use glam::Vec3;
use rayon::prelude::*;

/// Distinct colours for up to 8 owners (then repeating), linear RGB.
const PALETTE: [[f32; 3]; 8] = [
    [0.90, 0.20, 0.15],
    [0.15, 0.45, 0.90],
    [0.20, 0.75, 0.25],
    [0.95, 0.75, 0.10],
    [0.60, 0.25, 0.80],
    [0.10, 0.80, 0.80],
    [0.95, 0.45, 0.70],
    [0.55, 0.55, 0.55],
];

/// The colour of owner `index`.
pub fn owner_colour(index: usize) -> Vec3 {
    Vec3::from_array(PALETTE[index % PALETTE.len()])
}

/// One camera ray per pixel (the frame's sample 0); a surface owned by nobody is white, background
/// black. `owner(instance, mesh, triangle)` names the device holding a
/// triangle of the scene.
pub fn ownership_view(
    scene: &Scene,
    options: &RenderOptions,
    owner: &(dyn Fn(u32, u32, u32) -> Option<usize> + Sync),
) -> Film {
    let frame = FrameContext::new(scene, options.clone());
    ownership_view_of(scene, &frame, &SceneBvh::build(scene), owner)
}

/// [`ownership_view`] of `frame`'s camera and image over `bvh`, a BVH of
/// the whole scene (kept by a caller drawing many views).
pub fn ownership_view_of(
    scene: &Scene,
    frame: &FrameContext,
    bvh: &SceneBvh,
    owner: &(dyn Fn(u32, u32, u32) -> Option<usize> + Sync),
) -> Film {
    let options = &frame.options;
    let colours: Vec<Vec3> = (0..options.pixel_count())
        .into_par_iter()
        .map(|pixel| {
            let r = camera_record(frame, pixel, 0);
            let ray = Ray { origin: r.origin(), direction: r.direction(), t_max: r.t_max, time: 0.0 };
            let Some(hit) = bvh.intersect(&ray) else { return Vec3::ZERO };
            let instance = &scene.instances[hit.instance as usize];
            let mesh = &scene.meshes[hit.mesh as usize];
            let n = (instance.normal_to_world() * mesh.geometric_normal(hit.triangle as usize))
                .normalize_or_zero();
            let facing = n.dot(ray.direction.normalize_or_zero()).abs();
            let base = owner(hit.instance, hit.mesh, hit.triangle).map_or(Vec3::ONE, owner_colour);
            base * (0.35 + 0.65 * facing)
        })
        .collect();
    let mut film = Film::new(options.resolution);
    for (pixel, c) in colours.into_iter().enumerate() {
        film.add(pixel as u32, c);
    }
    film.spp = 1;
    film
}

#[cfg(test)]
mod tests {
    use super::*;
    use atoll_scene::cornell::builtin_cornell_box;

    #[test]
    fn every_visible_surface_takes_its_owners_colour() {
        let scene = builtin_cornell_box();
        let mut options = RenderOptions::from_scene(&scene);
        options.resolution = glam::UVec2::new(32, 32);
        // Owner = mesh index modulo 2: both colours must appear, and nothing else.
        let film = ownership_view(&scene, &options, &|_, mesh, _| Some(mesh as usize % 2));
        let (a, b) = (owner_colour(0), owner_colour(1));
        let mut seen = [false; 2];
        for p in film.pixels() {
            if p == Vec3::ZERO {
                continue;
            }
            // A shaded palette colour: proportional to one of the two.
            let along = |c: Vec3| (p / p.length()).dot(c / c.length()) > 0.9999;
            match (along(a), along(b)) {
                (true, false) => seen[0] = true,
                (false, true) => seen[1] = true,
                _ => panic!("pixel {p} is not an owner colour"),
            }
        }
        assert_eq!(seen, [true, true]);
    }
}
