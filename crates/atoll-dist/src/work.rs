//! Where a frame's rays will do their work, estimated before any device
//! holds the scene: the input of the work-balanced ring partition
//! ([`crate::spatial::partition_interleaved`]).
//!
//! In a ring every ray is traced on every part, and a part costs a ray most
//! where the ray ends: the walk down to the leaves and the triangle tests
//! around its hit (and the bounce and shadow rays leaving from there).
//! Balancing bytes alone leaves one device with what the camera looks at
//! (BENCHMARKS.md). The estimate: a low-resolution image of camera
//! rays traced against a proxy of the scene, the boxes of its pieces, and
//! the point where each ray enters its first box. The proxy needs no BLAS
//! (a scene too large for any device is too large to trace whole on the
//! host as well):
//! - each instance of an object with several instances, or of a small one,
//!   is its object's box, placed;
//! - an object with a single instance and many triangles (terrain, ground)
//!   is the boxes of runs of [`TRIANGLES_PER_BOX`] consecutive triangles,
//!   which follow its surface closely.
//!
//! Boxes that hold the ray's origin are passed through (a camera inside a
//! tree's box still sees past it). Tried and measured no better on the
//! landscape (`examples/ring_work.rs`): counting every instance box a ray
//! passes through before the surface, and adding bounce and shadow rays.

use std::sync::Arc;

use atoll_bvh::{Aabb, BuildOptions, Bvh2, BvhLayout, ByteModel, ScenePart, TraversalRay};
use atoll_render::camera::CameraRays;
use atoll_render::integrator::render_waves_observed;
use atoll_render::record::flags;
use atoll_render::{CpuDevice, Device, DeviceError, FrameContext, Queue, RenderOptions, Wave};
use atoll_scene::{ObjectId, Scene};
use glam::{UVec2, Vec2, Vec3};

use crate::partition::{Partition, PartitionError, PartitionOptions};
use crate::spatial::partition_interleaved;
use rayon::prelude::*;

/// Triangles per proxy box of a large single-instance object.
pub const TRIANGLES_PER_BOX: usize = 64;

/// Camera rays of the estimate along the image's longer side.
pub const ESTIMATE_WIDTH: u32 = 128;

/// Chunks per part of the work-balanced partition. Measured on the
/// landscape (ring of 2, CPU traversal time, `examples/ring_work.rs`):
/// one chunk per part leaves the work where the camera looks on one part;
/// more than two cost every ray more walks through more parts' chunks than
/// the balance gains.
pub const CHUNKS_PER_PART: usize = 2;

/// The ring partition for a frame of `scene` at `resolution`: `parts`
/// parts of [`CHUNKS_PER_PART`] Morton chunks each, cut so that every
/// chunk holds about equal shares of bytes (under `model`) and of the
/// [`estimate_work`] points. Errors when a part exceeds `options.budget`;
/// callers then fall back to the memory-balanced [`crate::partition()`].
pub fn partition_work_balanced(
    scene: &Scene,
    parts: usize,
    resolution: UVec2,
    model: &ByteModel,
    options: &PartitionOptions,
) -> Result<Partition, PartitionError> {
    let work = if parts > 1 { estimate_work(scene, resolution) } else { Vec::new() };
    partition_interleaved(scene, parts, CHUNKS_PER_PART, &work, model, options)
}

/// The scene's proxy: boxes and a BVH over them.
struct Proxy {
    boxes: Vec<Aabb>,
    bvh: Bvh2,
}

impl Proxy {
    fn new(scene: &Scene) -> Self {
        let mut instances_of = vec![0u32; scene.objects.len()];
        for inst in &scene.instances {
            instances_of[inst.object as usize] += 1;
        }
        let object_box: Vec<Option<Aabb>> = (0..scene.objects.len() as ObjectId)
            .into_par_iter()
            .map(|o| {
                let (lo, hi) = scene.object_bounds(o)?;
                Some(Aabb { min: lo.into(), max: hi.into() })
            })
            .collect();
        let boxes: Vec<Aabb> = scene
            .instances
            .par_iter()
            .flat_map_iter(|inst| {
                let o = inst.object as usize;
                let many_triangles = scene.object_triangles(inst.object) > 4 * TRIANGLES_PER_BOX as u64;
                if instances_of[o] == 1 && many_triangles {
                    surface_boxes(scene, inst.object, &inst.object_to_world)
                } else {
                    object_box[o].iter().map(|b| b.transformed(&inst.object_to_world)).collect()
                }
            })
            .collect();
        let bvh = Bvh2::build(&boxes, &BuildOptions::INSTANCES);
        Proxy { boxes, bvh }
    }

    /// Where `origin + t direction` first enters a box that does not hold
    /// `origin`, if it does.
    fn first_entry(&self, origin: Vec3, direction: Vec3) -> Option<Vec3> {
        let ray = TraversalRay::new(origin.into(), direction.into());
        let mut t_max = f32::INFINITY;
        let found = self.bvh.traverse::<false>(&ray, &mut t_max, |first, count, t_max| {
            let mut hit = false;
            for &i in &self.bvh.prim_order[first as usize..(first + count) as usize] {
                let b = &self.boxes[i as usize];
                let t = ray.box_entry(b.min, b.max, *t_max);
                // Entry at 0: the origin is inside (or on) the box.
                if t > 0.0 && t < *t_max {
                    *t_max = t;
                    hit = true;
                }
            }
            hit
        });
        found.then(|| origin + direction * t_max)
    }
}

/// Boxes of runs of [`TRIANGLES_PER_BOX`] triangles of `object`, in world space.
fn surface_boxes(scene: &Scene, object: ObjectId, to_world: &glam::Affine3A) -> Vec<Aabb> {
    scene.objects[object as usize]
        .meshes
        .iter()
        .flat_map(|&m| {
            let mesh = &scene.meshes[m as usize];
            mesh.indices.chunks(TRIANGLES_PER_BOX).map(move |run| {
                let corners =
                    run.iter().flatten().map(|&v| to_world.transform_point3(mesh.positions[v as usize]));
                Aabb::from_points(corners)
            })
        })
        .collect()
}

/// The ring partition whose chunks share out the work a frame of `scene`
/// at `resolution` measurably does ([`measure_work`]) as well as the bytes.
pub fn partition_work_measured(
    scene: &Arc<Scene>,
    parts: usize,
    resolution: UVec2,
    model: &ByteModel,
    options: &PartitionOptions,
) -> Result<(Partition, usize), PartitionError> {
    let work = match parts > 1 {
        true => measure_work(scene, resolution).map_err(|e| PartitionError::Measure(e.to_string()))?,
        false => Vec::new(),
    };
    Ok((partition_interleaved(scene, parts, CHUNKS_PER_PART, &work, model, options)?, work.len()))
}

/// Points where a frame of `scene` seen at `resolution` does its work,
/// measured: every hit of every path segment of one sample per pixel of
/// an [`ESTIMATE_WIDTH`]-wide image, rendered on a CPU device (host memory
/// holds what no single device of the ring can). Unlike [`estimate_work`]
/// it follows the bounces; it costs a BVH build over the whole scene.
pub fn measure_work(scene: &Arc<Scene>, resolution: UVec2) -> Result<Vec<Vec3>, DeviceError> {
    let longer = resolution.x.max(resolution.y).max(1) as f32;
    let small = (resolution.as_vec2() * (ESTIMATE_WIDTH as f32 / longer)).ceil().as_uvec2().max(UVec2::ONE);
    let options = RenderOptions { resolution: small, spp: 1, ..RenderOptions::from_scene(scene) };
    let frame = Arc::new(FrameContext::new(scene, options));
    let mut device = CpuDevice::new();
    device.prepare(scene, &ScenePart::whole(scene), &frame)?;
    let mut waves = Wave::all(&frame.options).into_iter();
    let mut points = Vec::new();
    let mut records = Vec::new();
    render_waves_observed(&mut device, false, &mut || waves.next(), &mut |d| {
        d.read_queue_into(Queue::Paths, &mut records)?;
        points.extend(records.iter().filter(|r| r.has(flags::HIT)).map(|r| Vec3::from(r.position)));
        Ok(())
    })?;
    Ok(points)
}

/// Points where a frame of `scene` seen at `resolution` will do its work:
/// the first proxy box each ray of a [`ESTIMATE_WIDTH`]-wide grid of camera
/// rays enters. Empty when no ray enters a box.
pub fn estimate_work(scene: &Scene, resolution: UVec2) -> Vec<Vec3> {
    let proxy = Proxy::new(scene);
    let longer = resolution.x.max(resolution.y).max(1) as f32;
    let grid = (resolution.as_vec2() * (ESTIMATE_WIDTH as f32 / longer)).ceil().as_uvec2().max(UVec2::ONE);
    let camera = CameraRays::new(&scene.settings.camera, resolution);
    let step = resolution.as_vec2() / grid.as_vec2();
    (0..grid.x * grid.y)
        .into_par_iter()
        .filter_map(|i| {
            let raster = (Vec2::new((i % grid.x) as f32, (i / grid.x) as f32) + 0.5) * step;
            let (origin, direction) = camera.ray(raster, Vec2::splat(0.5));
            proxy.first_entry(origin, direction)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On the landscape the estimate lands on the terrain in front of the
    /// camera: every point is within the world, below the camera's height.
    #[test]
    fn the_work_lands_on_what_the_camera_sees() {
        let scene = atoll_scene::landscape::Landscape::new(1).build();
        let points = estimate_work(&scene, UVec2::new(320, 180));
        let (lo, hi) = scene.world_bounds().unwrap();
        assert!(points.len() > 100, "{} points", points.len());
        let eye = scene.settings.camera.camera_to_world.transform_point3(Vec3::ZERO);
        for p in &points {
            assert!(p.cmpge(lo - 1e-3).all() && p.cmple(hi + 1e-3).all(), "{p} outside {lo}..{hi}");
            assert!(p.y < eye.y, "{p} above the eye {eye}");
        }
    }

    /// The measured work is the frame's hits: more points than camera rays
    /// (bounces add theirs), all on the scene, and a partition from them.
    #[test]
    fn measured_work_is_where_paths_hit() {
        let scene = Arc::new(atoll_scene::landscape::Landscape::new(1).build());
        let resolution = UVec2::new(320, 180);
        let points = measure_work(&scene, resolution).unwrap();
        let (lo, hi) = scene.world_bounds().unwrap();
        assert!(points.len() > 128 * 72, "{} hits for {} camera rays", points.len(), 128 * 72);
        assert!(points.iter().all(|p| p.cmpge(lo - 1e-2).all() && p.cmple(hi + 1e-2).all()));
        let (p, used) =
            partition_work_measured(&scene, 2, resolution, &ByteModel::CPU, &PartitionOptions::default())
                .unwrap();
        assert_eq!((p.parts.len(), used), (2, points.len()));
    }
}
