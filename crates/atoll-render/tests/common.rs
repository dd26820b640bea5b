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
