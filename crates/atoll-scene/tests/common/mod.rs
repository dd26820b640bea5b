//! Helpers shared by the integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};

use atoll_scene::pbrt::{load_str, LoadedScene};
use atoll_scene::SceneError;

/// A fresh, empty directory under the system temp dir.
pub fn temp_dir(tag: &str) -> PathBuf {
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().subsec_nanos();
    let dir = std::env::temp_dir().join(format!("atoll-scene-{tag}-{}-{n}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes `contents` to `dir/name` and returns the path.
pub fn write(dir: &Path, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    path
}

/// The shared test scenes (`/work/shared/scenes` next to the repository).
pub fn shared_scene(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes").join(rel)
}

/// Loads a world-block fragment (options first, then `WorldBegin` and `world`).
pub fn load_world(options: &str, world: &str) -> Result<LoadedScene, SceneError> {
    load_str(&format!("{options}\nWorldBegin\n{world}\n"), "test.pbrt", Path::new("."))
}

/// Runs the scene load `load` letting the scene name files that cannot be
/// read (`--allow-missing`), without touching the process-wide setting
/// that other tests' loads read.
#[allow(dead_code)]
pub fn allowing_missing<T>(load: impl FnOnce() -> T) -> T {
    let budget = atoll_scene::input::LoadBudget::from_settings().allowing_missing_files(true);
    atoll_scene::input::with_budget(std::sync::Arc::new(budget), load)
}

/// A one-triangle mesh statement with the given vertices.
pub fn tri(p: [[f32; 3]; 3]) -> String {
    let v: Vec<String> = p.iter().flatten().map(|x| x.to_string()).collect();
    format!("Shape \"trianglemesh\" \"point3 P\" [ {} ] \"integer indices\" [ 0 1 2 ]", v.join(" "))
}

/// Asserts two vectors agree to `eps`.
pub fn assert_close(a: glam::Vec3, b: glam::Vec3, eps: f32) {
    assert!((a - b).abs().max_element() <= eps, "{a} != {b}");
}

/// A binary glTF (GLB) of JSON text `json` with `bin` as its BIN chunk.
pub fn glb(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let mut j = json.to_vec();
    j.resize(j.len().next_multiple_of(4), b' ');
    let mut b = bin.to_vec();
    b.resize(b.len().next_multiple_of(4), 0);
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = b"glTF".to_vec();
    for x in [2u32, total as u32, j.len() as u32, 0x4E4F534A] {
        out.extend(x.to_le_bytes());
    }
    out.extend(j);
    out.extend((b.len() as u32).to_le_bytes());
    out.extend(0x004E4942u32.to_le_bytes());
    out.extend(b);
    out
}

/// Little-endian bytes of f32s.
pub fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// The binary buffer of the tests' glTF scenes: a triangle (positions,
/// normals, uvs, u16 indices) and a 4-vertex triangle strip (152 bytes).
pub fn gltf_bin() -> Vec<u8> {
    let mut b = f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0.]);
    b.extend(f32s(&[0., 0., 1., 0., 0., 1., 0., 0., 1.]));
    b.extend(f32s(&[0., 0., 1., 0., 0., 1.]));
    b.extend([0u16, 1, 2, 0].iter().flat_map(|i| i.to_le_bytes()));
    b.extend(f32s(&[0., 0., 0., 1., 0., 0., 0., 1., 0., 1., 1., 0.]));
    b
}
