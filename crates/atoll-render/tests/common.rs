//! Helpers shared by the renderer's integration tests.
#![allow(dead_code)]

use std::path::PathBuf;
use std::sync::Arc;

use atoll_render::{render, CpuDevice, Film, RenderOptions};
use atoll_scene::Scene;

/// `../shared/scenes/<rel>` from the repository root.
pub fn shared_scene(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes").join(rel)
}

pub fn render_with(scene: &Arc<Scene>, options: RenderOptions, threads: Option<usize>) -> Film {
    let mut device = CpuDevice::new();
    if let Some(t) = threads {
        device = device.with_threads(t).unwrap();
    }
    render(&mut device, scene, options, &mut |_, _| {}).unwrap().film
}

pub fn assert_finite(film: &Film) {
    for (i, p) in film.pixels().iter().enumerate() {
        assert!(p.is_finite() && p.min_element() >= 0.0, "pixel {i} is {p}");
    }
}

/// Mean and standard error of one channel's per-pixel values.
pub fn mean_and_stderr(values: impl Iterator<Item = f32>) -> (f64, f64) {
    let v: Vec<f64> = values.map(|x| x as f64).collect();
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// A UV sphere of radius 1 with smooth normals, `rings` × `segments` quads.
pub fn uv_sphere(material: u32, rings: u32, segments: u32) -> atoll_scene::TriangleMesh {
    use glam::Vec3;
    let mut positions = Vec::new();
    for i in 0..=rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = 2.0 * std::f32::consts::PI * j as f32 / segments as f32;
            positions.push(Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()));
        }
    }
    let mut indices = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let a = i * segments + j;
            let b = i * segments + (j + 1) % segments;
            let (c, d) = (a + segments, b + segments);
            indices.push([a, c, b]);
            indices.push([b, c, d]);
        }
    }
    let normals = positions.clone();
    atoll_scene::TriangleMesh {
        name: "sphere".into(),
        positions,
        normals,
        indices,
        material,
        ..Default::default()
    }
}
