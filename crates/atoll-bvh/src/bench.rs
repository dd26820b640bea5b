//! The traversal benchmark behind `atoll bench` (after tinybvh's speedtest):
//! build speed and quality, then Mrays/s for three deterministic ray batches
//! from the scene camera, every layout validated by its hit counts.
//!
//! - primary: one ray per pixel through the pinhole, closest hit;
//! - shadow: from each primary hit, a cosine-distributed direction with
//!   `t_max` a fraction of the scene diagonal (ambient occlusion), any hit;
//! - diffuse: from each primary hit, another cosine direction, closest hit.
//!
//! [`export_bench_data`] writes the same triangles and rays for
//! `scripts/bench-embree.py`.

use std::fmt;
use std::io;
use std::path::Path;
use std::time::Instant;

use atoll_scene::camera::tile_order_pixel;
use atoll_scene::Scene;
use glam::{UVec2, Vec3};
use rayon::prelude::*;

use crate::{Bvh2, Bvh4Cpu, BvhLayout, Hit, Ray, SceneBvh, SceneBvhStats, ScenePart};

/// What to measure and how often.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchOptions {
    /// Primary rays per axis; `None` takes the scene's film resolution.
    pub resolution: Option<UVec2>,
    /// Timed runs per batch, after one untimed warm-up; the median is reported.
    pub runs: usize,
    /// Timed builds per layout; the median is reported.
    pub builds: usize,
    /// Thread counts to trace with; 0 means one per core.
    pub threads: Vec<usize>,
    /// Shadow-ray length as a fraction of the scene's bounding-box diagonal.
    pub shadow_fraction: f32,
}

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions { resolution: None, runs: 5, builds: 3, threads: vec![0], shadow_fraction: 0.05 }
    }
}

/// Build speed and size of one layout.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildResult {
    /// [`BvhLayout::NAME`] of the layout built.
    pub layout: &'static str,
    /// Median wall-clock build time.
    pub build_ms: f64,
    /// Triangles built (each stored triangle once) per second, in millions.
    pub mtris_per_s: f64,
    /// Sizes and quality of the last build.
    pub stats: SceneBvhStats,
}

/// One timed traversal: a batch, a layout, a thread count.
#[derive(Clone, Debug, PartialEq)]
pub struct Measurement {
    /// [`BvhLayout::NAME`] of the layout traced.
    pub layout: &'static str,
    /// Threads actually used.
    pub threads: usize,
    /// Rays per second (median run), in millions.
    pub mrays_per_s: f64,
    /// Rays that hit (closest-hit batches) or were occluded (shadow).
    pub hits: usize,
}

/// All measurements of one ray batch.
#[derive(Clone, Debug, PartialEq)]
pub struct BatchResult {
    /// `primary`, `shadow` or `diffuse`.
    pub name: &'static str,
    /// `intersect` or `occluded`.
    pub query: &'static str,
    /// Rays in the batch.
    pub rays: usize,
    /// One per layout and thread count.
    pub measurements: Vec<Measurement>,
}

impl BatchResult {
    /// Whether every layout and thread count found the same number of hits.
    pub fn hits_agree(&self) -> bool {
        self.measurements.windows(2).all(|w| w[0].hits == w[1].hits)
    }
}

/// Everything [`run_traversal_bench`] measured; `Display` prints it as tables.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchReport {
    /// Triangles as rays see them (instanced).
    pub triangles: u64,
    /// Instances in the scene.
    pub instances: usize,
    /// Primary rays per axis.
    pub resolution: UVec2,
    /// One per layout.
    pub builds: Vec<BuildResult>,
    /// Primary, shadow and diffuse.
    pub batches: Vec<BatchResult>,
}

/// The three ray batches.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RayBatches {
    /// One per pixel, row by row from the top left.
    pub primary: Vec<Ray>,
    /// One per primary hit (occlusion queries).
    pub shadow: Vec<Ray>,
    /// One per primary hit (closest-hit queries).
    pub diffuse: Vec<Ray>,
}

/// Builds every layout, generates the ray batches and times them.
pub fn run_traversal_bench(scene: &Scene, opts: &BenchOptions) -> BenchReport {
    let stats = scene.stats();
    let resolution = opts.resolution.unwrap_or(scene.settings.film.resolution);
    let (build4, bvh4) = timed_build::<Bvh4Cpu>(scene, opts.builds);
    let (build2, bvh2) = timed_build::<Bvh2>(scene, opts.builds);
    let rays = generate_rays(scene, &bvh4, opts);
    let batches = [
        ("primary", false, &rays.primary),
        ("shadow", true, &rays.shadow),
        ("diffuse", false, &rays.diffuse),
    ];
    let batches = batches
        .into_iter()
        .map(|(name, any, rays)| {
            let mut measurements = Vec::new();
            for &threads in &opts.threads {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
                measurements.push(time_batch(&pool, &bvh4, rays, any, opts.runs));
                measurements.push(time_batch(&pool, &bvh2, rays, any, opts.runs));
            }
            BatchResult {
                name,
                query: if any { "occluded" } else { "intersect" },
                rays: rays.len(),
                measurements,
            }
        })
        .collect();
    BenchReport {
        triangles: stats.instanced_triangles,
        instances: stats.instances,
        resolution,
        builds: vec![build4, build2],
        batches,
    }
}

/// Builds `builds` times (at least once) and keeps the last BVH.
fn timed_build<L: BvhLayout>(scene: &Scene, builds: usize) -> (BuildResult, SceneBvh<L>) {
    let mut times = Vec::new();
    let whole = ScenePart::whole(scene);
    let mut bvh = SceneBvh::<L>::build_layout(scene, &whole);
    times.push(bvh.stats().build_ms);
    for _ in 1..builds {
        bvh = SceneBvh::<L>::build_layout(scene, &whole);
        times.push(bvh.stats().build_ms);
    }
    let build_ms = median(times);
    let stats = bvh.stats();
    let mtris_per_s = stats.triangles as f64 / build_ms / 1e3;
    (BuildResult { layout: L::NAME, build_ms, mtris_per_s, stats }, bvh)
}

/// Median time of `runs` traversals of the batch (after a warm-up) on `pool`.
fn time_batch<L: BvhLayout>(
    pool: &rayon::ThreadPool,
    bvh: &SceneBvh<L>,
    rays: &[Ray],
    any: bool,
    runs: usize,
) -> Measurement {
    // Chunks of 1024 rays: few enough tasks for rayon's overhead to vanish,
    // enough for load balance.
    let trace = || -> usize {
        pool.install(|| {
            rays.par_chunks(1024)
                .map(|c| {
                    if any {
                        c.iter().filter(|r| bvh.occluded(r)).count()
                    } else {
                        c.iter().filter(|r| bvh.intersect(r).is_some()).count()
                    }
                })
                .sum()
        })
    };
    let hits = trace();
    let times: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            let start = Instant::now();
            std::hint::black_box(trace());
            start.elapsed().as_secs_f64()
        })
        .collect();
    let mrays_per_s = rays.len() as f64 / median(times) / 1e6;
    Measurement { layout: L::NAME, threads: pool.current_num_threads(), mrays_per_s, hits }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Generates the three batches: primary rays through the scene camera, and
/// from each primary hit one shadow and one diffuse ray. Deterministic: the
/// random numbers hash (pixel, dimension).
pub fn generate_rays<L: BvhLayout>(scene: &Scene, bvh: &SceneBvh<L>, opts: &BenchOptions) -> RayBatches {
    let resolution = opts.resolution.unwrap_or(scene.settings.film.resolution);
    let primary = camera_rays(scene, resolution);
    let diagonal = scene.world_bounds().map_or(1.0, |(lo, hi)| (hi - lo).length());
    let hits: Vec<(u32, Ray, Hit)> = primary
        .par_iter()
        .enumerate()
        .filter_map(|(i, r)| bvh.intersect(r).map(|h| (tile_order_pixel(i as u32, resolution), *r, h)))
        .collect();
    let secondary = |dimension: u32, t_max: f32| -> Vec<Ray> {
        hits.par_iter()
            .map(|&(pixel, ray, hit)| {
                let (point, normal) = surface(scene, &ray, &hit);
                // Offset along the normal, well above float error at these
                // coordinates, so the ray does not hit its own triangle.
                let origin = point + normal * (1e-5 * diagonal);
                let u = [hash01(pixel, dimension), hash01(pixel, dimension + 1)];
                Ray { origin, direction: cosine_direction(normal, u), t_max, time: 0.0 }
            })
            .collect()
    };
    RayBatches {
        shadow: secondary(0, opts.shadow_fraction * diagonal),
        diffuse: secondary(2, f32::INFINITY),
        primary,
    }
}

/// One ray per pixel centre through the scene's camera as a pinhole (over
/// its screen window, [`atoll_scene::Projection::camera_ray`]). The rays
/// come in the order the renderer makes camera paths in (8×4 tiles,
/// [`tile_order_pixel`]).
fn camera_rays(scene: &Scene, resolution: UVec2) -> Vec<Ray> {
    let cam = &scene.settings.camera;
    let scale = match cam.projection {
        atoll_scene::Projection::Perspective => (cam.fov_degrees.to_radians() * 0.5).tan(),
        _ => 1.0,
    };
    let [x0, x1, y0, y1] = cam.screen_window(resolution).map(|v| v * scale);
    let size = resolution.as_vec2();
    (0..resolution.x * resolution.y)
        .into_par_iter()
        .map(|i| {
            let pixel = tile_order_pixel(i, resolution);
            let (px, py) = ((pixel % resolution.x) as f32 + 0.5, (pixel / resolution.x) as f32 + 0.5);
            let (x, y) = (x0 + px / size.x * (x1 - x0), y1 - py / size.y * (y1 - y0));
            let (origin, local) = cam.projection.camera_ray(glam::Vec2::new(x, y));
            let origin = cam.camera_to_world.transform_point3(origin);
            let direction = cam.camera_to_world.transform_vector3(local).normalize();
            Ray { origin, direction, t_max: f32::INFINITY, time: 0.0 }
        })
        .collect()
}

/// World-space hit point and unit geometric normal facing the ray's origin.
fn surface(scene: &Scene, ray: &Ray, hit: &Hit) -> (Vec3, Vec3) {
    let m = scene.instances[hit.instance as usize].object_to_world;
    let [p0, p1, p2] = scene.meshes[hit.mesh as usize].triangle(hit.triangle as usize);
    let [p0, p1, p2] = [p0, p1, p2].map(|p| m.transform_point3(p));
    let n = (p1 - p0).cross(p2 - p0).normalize_or(Vec3::Y);
    let n = if n.dot(ray.direction) > 0.0 { -n } else { n };
    (ray.origin + hit.t * ray.direction, n)
}

/// Cosine-distributed unit direction around `n` (Malley's method in the
/// branchless orthonormal basis of Duff et al. 2017).
fn cosine_direction(n: Vec3, u: [f32; 2]) -> Vec3 {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let s = Vec3::new(b, sign + n.y * n.y * a, -n.y);
    let r = u[0].sqrt();
    let phi = std::f32::consts::TAU * u[1];
    (t * (r * phi.cos()) + s * (r * phi.sin()) + n * (1.0 - u[0]).max(0.0).sqrt()).normalize()
}

/// Uniform in [0, 1) from (pixel, dimension): PCG's output hash of both.
fn hash01(pixel: u32, dimension: u32) -> f32 {
    let mut x = pixel.wrapping_mul(0x9e37_79b9) ^ dimension.wrapping_mul(0x85eb_ca6b);
    for _ in 0..2 {
        let state = x.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
        let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
        x = (word >> 22) ^ word;
    }
    (x >> 8) as f32 / (1u32 << 24) as f32
}

/// Writes, as little-endian f32: `triangles.f32` (every instanced triangle
/// in world space, N x 9: p0, p1, p2; curves, which are no triangles, are
/// left out) and `primary.f32`, `shadow.f32`, `diffuse.f32` (M x 7:
/// origin, direction, t_max).
pub fn export_bench_data(scene: &Scene, opts: &BenchOptions, dir: &Path) -> io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let mut triangles: Vec<[Vec3; 3]> = Vec::new();
    for inst in &scene.instances {
        for &m in &scene.objects[inst.object as usize].meshes {
            let mesh = &scene.meshes[m as usize];
            if mesh.curves.is_some() {
                continue;
            }
            triangles.extend(
                (0..mesh.triangle_count())
                    .map(|t| mesh.triangle(t).map(|p| inst.object_to_world.transform_point3(p))),
            );
        }
    }
    write_f32(&dir.join("triangles.f32"), bytemuck::cast_slice(&triangles))?;
    let rays = generate_rays(scene, &SceneBvh::build(scene), opts);
    for (name, batch) in [("primary", &rays.primary), ("shadow", &rays.shadow), ("diffuse", &rays.diffuse)] {
        // Seven numbers a ray: bench rays are all at time 0, which is left out.
        let values: Vec<f32> = batch
            .iter()
            .flat_map(|r| {
                [r.origin.x, r.origin.y, r.origin.z, r.direction.x, r.direction.y, r.direction.z, r.t_max]
            })
            .collect();
        write_f32(&dir.join(format!("{name}.f32")), &values)?;
    }
    Ok(())
}

fn write_f32(path: &Path, values: &[f32]) -> io::Result<()> {
    let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(path, bytes)
}

impl BenchReport {
    /// The report as JSON (for scripts: `scripts/bench-embree.py` reads it).
    pub fn to_json(&self) -> String {
        let builds: Vec<String> = self
            .builds
            .iter()
            .map(|b| {
                let s = &b.stats;
                format!(
                    r#"{{"layout": "{}", "build_ms": {:.3}, "mtris_per_s": {:.3}, "triangles": {}, "blas_sah": {:.3}, "bytes": {}}}"#,
                    b.layout, b.build_ms, b.mtris_per_s, s.triangles, s.blas.sah_cost, s.bytes
                )
            })
            .collect();
        let batches: Vec<String> = self
            .batches
            .iter()
            .map(|b| {
                let m: Vec<String> = b
                    .measurements
                    .iter()
                    .map(|m| {
                        format!(
                            r#"{{"layout": "{}", "threads": {}, "mrays_per_s": {:.4}, "hits": {}}}"#,
                            m.layout, m.threads, m.mrays_per_s, m.hits
                        )
                    })
                    .collect();
                format!(
                    r#"{{"name": "{}", "query": "{}", "rays": {}, "measurements": [{}]}}"#,
                    b.name,
                    b.query,
                    b.rays,
                    m.join(", ")
                )
            })
            .collect();
        format!(
            "{{\"triangles\": {}, \"instances\": {}, \"builds\": [{}],\n \"batches\": [\n  {}\n ]}}\n",
            self.triangles,
            self.instances,
            builds.join(", "),
            batches.join(",\n  ")
        )
    }
}

impl fmt::Display for BenchReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = self.resolution;
        writeln!(
            f,
            "{} triangles, {} instances, {}x{} primary rays",
            self.triangles, self.instances, r.x, r.y
        )?;
        writeln!(
            f,
            "{:<8} {:>9} {:>8} {:>9} {:>9} {:>9} {:>6} {:>8}",
            "layout", "build ms", "Mtris/s", "triangles", "nodes", "TLAS SAH", "SAH", "MiB"
        )?;
        for b in &self.builds {
            let s = &b.stats;
            writeln!(
                f,
                "{:<8} {:>9.1} {:>8.2} {:>9} {:>9} {:>9.1} {:>6.1} {:>8.1}",
                b.layout,
                b.build_ms,
                b.mtris_per_s,
                s.triangles,
                s.blas.nodes + s.tlas.nodes,
                s.tlas.sah_cost,
                s.blas.sah_cost,
                s.bytes as f64 / (1 << 20) as f64
            )?;
        }
        write!(f, "{:<8} {:<9} {:>8} {:>8}", "batch", "query", "rays", "hits")?;
        for m in self.batches.first().map_or(&[][..], |b| &b.measurements[..]) {
            write!(f, " {:>13}", format!("{} {}t", m.layout, m.threads))?;
        }
        writeln!(f, "   (Mrays/s)")?;
        for b in &self.batches {
            let hits = b.measurements.first().map_or(0, |m| m.hits);
            write!(f, "{:<8} {:<9} {:>8} {:>8}", b.name, b.query, b.rays, hits)?;
            for m in &b.measurements {
                write!(f, " {:>13.2}", m.mrays_per_s)?;
            }
            writeln!(f, "{}", if b.hits_agree() { "" } else { "   HIT COUNTS DIFFER" })?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bench_runs_and_layouts_agree() {
        let scene = atoll_scene::procedural::bench_scene(5_000);
        let opts = BenchOptions {
            resolution: Some(UVec2::new(48, 32)),
            runs: 1,
            builds: 1,
            threads: vec![1, 2],
            ..Default::default()
        };
        let report = run_traversal_bench(&scene, &opts);
        assert_eq!(report.batches[0].rays, 48 * 32);
        let primary_hits = report.batches[0].measurements[0].hits;
        assert!(primary_hits > 48 * 32 / 2, "the camera looks at the terrain");
        for b in &report.batches {
            assert!(b.hits_agree(), "{report}");
            assert_eq!(b.measurements.len(), 4);
            assert!(b.measurements.iter().all(|m| m.mrays_per_s > 0.0));
        }
        // Secondary rays start at primary hits; some are occluded, some escape.
        let shadow = &report.batches[1];
        assert_eq!(shadow.rays, primary_hits);
        assert!(0 < shadow.measurements[0].hits && shadow.measurements[0].hits < shadow.rays);
        assert!(report.to_string().contains("diffuse"));
        assert!(report.to_json().contains(r#""name": "shadow""#));
    }

    #[test]
    fn cosine_directions_are_in_the_hemisphere() {
        for (i, n) in [Vec3::Z, -Vec3::Z, Vec3::new(0.3, -0.9, 0.1).normalize()].into_iter().enumerate() {
            let mean: Vec3 = (0..4096)
                .map(|p| {
                    let d = cosine_direction(n, [hash01(p, i as u32), hash01(p, 7)]);
                    assert!((d.length() - 1.0).abs() < 1e-4 && d.dot(n) >= 0.0);
                    d
                })
                .sum::<Vec3>()
                / 4096.0;
            // E[cos] of a cosine distribution is 2/3.
            assert!((mean.dot(n) - 2.0 / 3.0).abs() < 0.02, "{}", mean.dot(n));
        }
    }

    #[test]
    fn export_writes_triangles_and_rays() {
        let scene = atoll_scene::procedural::bench_scene(2_000);
        let dir = std::env::temp_dir().join(format!("atoll-bench-export-{}", std::process::id()));
        let opts = BenchOptions { resolution: Some(UVec2::new(16, 16)), ..Default::default() };
        export_bench_data(&scene, &opts, &dir).unwrap();
        let len = |name: &str| std::fs::metadata(dir.join(name)).unwrap().len();
        assert_eq!(len("triangles.f32"), scene.stats().instanced_triangles * 36);
        assert_eq!(len("primary.f32"), 16 * 16 * 28);
        assert_eq!(len("shadow.f32"), len("diffuse.f32"));
        std::fs::remove_dir_all(dir).unwrap();
    }
}
