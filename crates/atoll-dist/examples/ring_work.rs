//! Experiment: how much traversal work a ring of two parts costs against
//! one whole-scene BVH, per partition and per choice of which part traces a
//! ray first, on the landscape. CPU traversal time stands in for work: a
//! device's time is its share of first traces plus the second traces of
//! the other's rays (shortened by the first hit; occluded shadow rays not
//! traced again). Rays: one per pixel, a cosine bounce from each hit and a
//! shadow ray to the sun.
//!
//! `cargo run --release -p atoll-dist --example ring_work -- GROWTH [WIDTH]`
//!
//! Partitions: `greedy` (memory-balanced, [`atoll_dist::partition()`]),
//! `chunksC` (C Morton chunks per part by bytes), `workC` (by bytes and the
//! reference's own hit points: the best a work estimate could do), `proxyC`
//! (by bytes and [`atoll_dist::work::estimate_work`]). Orders: `alternate`
//! (as the ring does: each ray starts where it was shaded), `prev-hit` (on
//! the part holding the surface it leaves), `oracle` (on the part holding
//! its hit). `CHUNKS=1,2,4` picks the chunk counts, `WORK_STRIDE=N` thins
//! the reference's points, `NO_PLAIN=1` skips `chunksC`. BENCHMARKS.md has
//! the results; GPU measurements disagreed with them.

use std::time::Instant;

use atoll_bvh::{ByteModel, Hit, Ray, SceneBvh};
use atoll_dist::{partition, spatial::partition_interleaved, Partition, PartitionOptions};
use atoll_render::camera::CameraRays;
use atoll_render::rng::pcg_hash;
use atoll_render::sampling::sample_cosine_hemisphere;
use atoll_scene::landscape::Landscape;
use atoll_scene::{Light, Scene};
use glam::{UVec2, Vec2, Vec3};
use rayon::prelude::*;

/// A uniform number in [0, 1) from `x` (for the bounce directions).
fn u01(x: u32) -> f32 {
    (pcg_hash(x) >> 8) as f32 / (1u32 << 24) as f32
}

struct RaySet {
    name: &'static str,
    rays: Vec<Ray>,
    /// Part that holds the surface the ray leaves (None: camera).
    from: Vec<Option<(u32, u32, u32)>>,
    shadow: bool,
}

fn geometric_normal(scene: &Scene, hit: &Hit) -> Vec3 {
    let mesh = &scene.meshes[hit.mesh as usize];
    let [a, b, c] = mesh.indices[hit.triangle as usize];
    let xf = scene.instances[hit.instance as usize].object_to_world;
    let p = |i: u32| xf.transform_point3(mesh.positions[i as usize]);
    (p(b) - p(a)).cross(p(c) - p(a)).normalize()
}

fn frame(n: Vec3) -> (Vec3, Vec3) {
    let t = if n.x.abs() > 0.9 { Vec3::Y } else { Vec3::X };
    let t = n.cross(t).normalize();
    (t, n.cross(t))
}

fn time<T: Send>(f: impl FnOnce() -> T) -> (T, f64) {
    let start = Instant::now();
    let out = f();
    (out, start.elapsed().as_secs_f64())
}

fn trace(bvh: &SceneBvh, rays: &[Ray], shadow: bool) -> (Vec<Option<Hit>>, f64) {
    (0..3).map(|_| trace_once(bvh, rays, shadow)).min_by(|a, b| a.1.total_cmp(&b.1)).unwrap()
}

fn trace_once(bvh: &SceneBvh, rays: &[Ray], shadow: bool) -> (Vec<Option<Hit>>, f64) {
    time(|| {
        rays.par_iter()
            .with_min_len(256)
            .map(|r| {
                if shadow {
                    bvh.occluded(r).then_some(Hit {
                        t: 0.0,
                        u: 0.0,
                        v: 0.0,
                        instance: 0,
                        mesh: 0,
                        triangle: 0,
                    })
                } else {
                    bvh.intersect(r)
                }
            })
            .collect()
    })
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let growth: u32 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(10);
    let width: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(480);
    let scene = Landscape::new(growth).build();
    let res = UVec2::new(width, width * 9 / 16);
    let cam = CameraRays::new(&scene.settings.camera, res);
    let sun = scene
        .lights
        .iter()
        .find_map(|l| match l {
            Light::Distant { direction, .. } => Some(-*direction),
            _ => None,
        })
        .unwrap_or(Vec3::Y);
    let full = SceneBvh::build(&scene);

    // Primary rays, one bounce, shadow rays from both.
    let mut sets = Vec::new();
    let primary: Vec<Ray> = (0..res.x * res.y)
        .map(|i| {
            let px = Vec2::new((i % res.x) as f32 + 0.5, (i / res.x) as f32 + 0.5);
            let (o, d) = cam.ray(px, Vec2::ZERO);
            Ray { origin: o, direction: d, t_max: f32::INFINITY, time: 0.0 }
        })
        .collect();
    let (hits0, _) = trace(&full, &primary, false);
    sets.push(RaySet {
        name: "primary",
        from: vec![None; primary.len()],
        rays: primary.clone(),
        shadow: false,
    });
    let mut bounce = Vec::new();
    let mut bounce_from = Vec::new();
    let mut shadow = Vec::new();
    let mut shadow_from = Vec::new();
    for (i, (r, h)) in primary.iter().zip(&hits0).enumerate() {
        let Some(h) = h else { continue };
        let mut n = geometric_normal(&scene, h);
        if n.dot(r.direction) > 0.0 {
            n = -n;
        }
        let p = r.origin + r.direction * h.t + n * 1e-3;
        let (t, b) = frame(n);
        let l = sample_cosine_hemisphere(Vec2::new(u01(2 * i as u32), u01(2 * i as u32 + 1)));
        let d = t * l.x + b * l.y + n * l.z;
        bounce.push(Ray { origin: p, direction: d, t_max: f32::INFINITY, time: 0.0 });
        bounce_from.push(Some((h.instance, h.mesh, h.triangle)));
        if n.dot(sun) > 0.0 {
            shadow.push(Ray { origin: p, direction: sun, t_max: f32::INFINITY, time: 0.0 });
            shadow_from.push(Some((h.instance, h.mesh, h.triangle)));
        }
    }
    sets.push(RaySet { name: "bounce", rays: bounce, from: bounce_from, shadow: false });
    sets.push(RaySet { name: "shadow", rays: shadow, from: shadow_from, shadow: true });

    // Reference: the whole scene.
    let mut full_hits = Vec::new();
    let mut t_full = 0.0;
    for set in &sets {
        let best = trace(&full, &set.rays, set.shadow);
        println!("full {:8} {:7} rays {:.4} s", set.name, set.rays.len(), best.1);
        t_full += best.1;
        full_hits.push(best.0);
    }
    println!("full total {t_full:.4} s (replicate on 2: {:.4})", t_full / 2.0);

    let model = ByteModel::CPU;
    let options = PartitionOptions::default();
    let mut partitions: Vec<(String, Partition)> = Vec::new();
    partitions.push(("greedy".into(), partition(&scene, 2, &model, &options).unwrap()));
    // Where rays work: primary and bounce hits of the reference.
    let mut work = Vec::new();
    for (set, hits) in sets.iter().zip(&full_hits).take(2) {
        for (r, h) in set.rays.iter().zip(hits) {
            if let Some(h) = h {
                work.push(r.origin + r.direction * h.t);
            }
        }
    }
    let stride = std::env::var("WORK_STRIDE").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
    let work: Vec<Vec3> = work.into_iter().step_by(stride).collect();
    let chunks: Vec<usize> = std::env::var("CHUNKS")
        .unwrap_or("1,4,16,64,256".into())
        .split(',')
        .map(|c| c.parse().unwrap())
        .collect();
    let proxy = atoll_dist::work::estimate_work(&scene, res);
    println!("proxy work points: {}", proxy.len());
    for c in chunks.clone() {
        let p = partition_interleaved(&scene, 2, c, &proxy, &model, &options).unwrap();
        partitions.push((format!("proxy{c}"), p));
    }
    for c in chunks {
        if std::env::var("NO_PLAIN").is_err() {
            let p = partition_interleaved(&scene, 2, c, &[], &model, &options).unwrap();
            partitions.push((format!("chunks{c}"), p));
        }
        let p = partition_interleaved(&scene, 2, c, &work, &model, &options).unwrap();
        partitions.push((format!("work{c}"), p));
    }

    for (name, part) in &partitions {
        let bvhs: Vec<SceneBvh> = part.parts.iter().map(|p| SceneBvh::build_part(&scene, p)).collect();
        for order in ["alternate", "prev-hit", "oracle"] {
            let mut device = [0.0f64; 2];
            for (s, set) in sets.iter().enumerate() {
                let first: Vec<usize> = (0..set.rays.len())
                    .map(|i| match order {
                        "alternate" => (i + s) % 2,
                        "prev-hit" => match set.from[i] {
                            Some((inst, mesh, tri)) => part.owner(inst, mesh, tri).unwrap_or(0),
                            None => i % 2,
                        },
                        _ => match full_hits[s][i] {
                            Some(h) if !set.shadow => part.owner(h.instance, h.mesh, h.triangle).unwrap_or(0),
                            _ => match set.from[i] {
                                Some((inst, mesh, tri)) => part.owner(inst, mesh, tri).unwrap_or(0),
                                None => i % 2,
                            },
                        },
                    })
                    .collect();
                for d in 0..2 {
                    let idx: Vec<usize> = (0..set.rays.len()).filter(|&i| first[i] == d).collect();
                    let rays: Vec<Ray> = idx.iter().map(|&i| set.rays[i]).collect();
                    let (h1, t1) = trace(&bvhs[d], &rays, set.shadow);
                    device[d] += t1;
                    let second: Vec<Ray> = rays
                        .iter()
                        .zip(&h1)
                        .filter(|(_, h)| !(set.shadow && h.is_some()))
                        .map(|(r, h)| Ray { t_max: h.map_or(r.t_max, |h| h.t), ..*r })
                        .collect();
                    let (_, t2) = trace(&bvhs[1 - d], &second, set.shadow);
                    device[1 - d] += t2;
                }
            }
            let worst = device[0].max(device[1]);
            println!(
                "{name:10} {:?} {order:9} devices {:.4} {:.4} s  work {:.2}x  ring/replicate {:.2}",
                part.bytes,
                device[0],
                device[1],
                (device[0] + device[1]) / t_full,
                (t_full / 2.0) / worst
            );
        }
    }
}
