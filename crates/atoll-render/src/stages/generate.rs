//! Camera rays for a wave.

use bytemuck::Zeroable;
use glam::{UVec2, Vec2};

use crate::frame::FrameContext;
use crate::record::{flags, RayRecord};
use crate::rng::SampleStream;

/// The camera path record for `pixel`, sample `sample`.
pub fn camera_record(ctx: &FrameContext, pixel: u32, sample: u32) -> RayRecord {
    let res: UVec2 = ctx.options.resolution;
    let rng = SampleStream::new(ctx.options.seed, pixel, sample);
    // The pixel filter places the sample and weights it (`filter`).
    let corner = Vec2::new((pixel % res.x) as f32, (pixel / res.x) as f32);
    let (raster, weight) = ctx.filter.sample(corner, Vec2::new(rng.get(0), rng.get(1)));
    let time = ctx.path_time(pixel, sample);
    let ray = ctx.camera.weighted_ray_at(raster, Vec2::new(rng.get(2), rng.get(3)), time);
    let mut r = RayRecord::zeroed();
    r.origin = ray.origin.to_array();
    r.direction = ray.direction.to_array();
    // A ray the lens blocks still counts as a sample, of nothing.
    r.t_max = if ray.weight == 0.0 { 0.0 } else { f32::INFINITY };
    r.pixel = pixel;
    r.sample = sample;
    r.throughput = [weight * ray.weight; 3];
    // Emitters seen directly count in full, like after a specular bounce.
    r.flags = flags::SPECULAR;
    r.set_medium(ctx.media.camera);
    r
}
