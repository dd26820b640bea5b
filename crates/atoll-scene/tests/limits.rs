//! Input limits of one scene load: the bytes all its files may have
//! together, the triangles its shapes may generate, and files reached
//! through symbolic links that lead out of the scene's folder.
//!
//! Budgets are given explicitly ([`with_budget`]) so that these tests do
//! not depend on, or change, the process-wide settings.

mod common;

use std::sync::Arc;
use std::time::Instant;

use atoll_scene::input::{with_budget, LoadBudget};
use atoll_scene::{load_any, LoadedScene, SceneError};
use common::{temp_dir, write};

const OPTIONS: &str = "Camera \"perspective\"\nWorldBegin\n";

const PLY: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";

/// Loads `path` with no limits (not the process-wide settings, which a
/// test here changes).
fn load(path: &std::path::Path) -> Result<LoadedScene, SceneError> {
    with_budget(Arc::new(LoadBudget::new(u64::MAX, u64::MAX)), || load_any(path))
}

fn load_with(
    budget: LoadBudget,
    path: &std::path::Path,
) -> (Result<LoadedScene, SceneError>, Arc<LoadBudget>) {
    let budget = Arc::new(budget);
    (with_budget(budget.clone(), || load_any(path)), budget)
}

#[test]
fn all_the_files_of_a_scene_share_one_byte_budget() {
    let dir = temp_dir("limits-bytes");
    write(&dir, "mesh.ply", PLY);
    write(&dir, "inc.pbrt", "Shape \"plymesh\" \"string filename\" \"mesh.ply\"\n");
    let main = write(&dir, "scene.pbrt", format!("{OPTIONS}Include \"inc.pbrt\"\nInclude \"inc.pbrt\"\n"));
    let size = |name: &str| std::fs::metadata(dir.join(name)).unwrap().len();
    // The main file, the include twice and the mesh twice.
    let total = size("scene.pbrt") + 2 * size("inc.pbrt") + 2 * size("mesh.ply");
    let (loaded, budget) = load_with(LoadBudget::new(total, u64::MAX), &main);
    assert_eq!(loaded.unwrap().scene.meshes.len(), 2);
    assert_eq!(budget.bytes(), total);
    // One byte less: the second mesh read is refused, at its plymesh statement.
    let (loaded, budget) = load_with(LoadBudget::new(total - 1, u64::MAX), &main);
    let e = loaded.unwrap_err();
    assert_eq!((e.file.as_str(), e.line), (dir.join("inc.pbrt").to_str().unwrap(), 1), "{e}");
    assert!(e.message.contains("more than the") && e.message.contains("--max-scene-bytes"), "{e}");
    assert!(budget.bytes() < total);
    // Standalone meshes count too.
    let ply = dir.join("mesh.ply");
    let (loaded, _) = load_with(LoadBudget::new(size("mesh.ply") - 1, u64::MAX), &ply);
    assert!(loaded.unwrap_err().message.contains("--max-scene-bytes"));
}

/// An Include chain that reads a tiny file exponentially many times stops
/// at the number of file reads, long before its bytes add up.
#[test]
fn file_reads_are_counted_so_include_chains_stop() {
    let dir = temp_dir("limits-files");
    write(&dir, "leaf.pbrt", "# nothing\n");
    // Level k includes level k-1 twice: 2^12 reads of the leaf.
    write(&dir, "level0.pbrt", "Include \"leaf.pbrt\"\nInclude \"leaf.pbrt\"\n");
    for k in 1..12 {
        let prev = format!("level{}.pbrt", k - 1);
        write(&dir, &format!("level{k}.pbrt"), format!("Include \"{prev}\"\nInclude \"{prev}\"\n"));
    }
    let main = write(&dir, "scene.pbrt", format!("{OPTIONS}Include \"level11.pbrt\"\n"));
    let (loaded, _) = load_with(LoadBudget::new(u64::MAX, u64::MAX).with_max_files(10_000), &main);
    assert!(loaded.is_ok(), "{:?}", loaded.err());
    let (loaded, _) = load_with(LoadBudget::new(u64::MAX, u64::MAX).with_max_files(1_000), &main);
    let e = loaded.unwrap_err();
    assert!(e.message.contains("1000 file reads"), "{e}");
    assert!(e.line > 0, "the Include that went past the limit is named: {e}");
}

#[test]
fn the_byte_budget_setting_applies_to_loads_that_start_after_it() {
    use atoll_scene::input::{max_scene_bytes, set_max_scene_bytes, DEFAULT_MAX_SCENE_BYTES};
    assert_eq!(max_scene_bytes(), DEFAULT_MAX_SCENE_BYTES);
    let dir = temp_dir("limits-setting");
    let ply = write(&dir, "mesh.ply", PLY);
    // Other tests in this file give their budgets explicitly: this one
    // alone uses the setting.
    set_max_scene_bytes(10);
    let e = load_any(&ply).unwrap_err();
    set_max_scene_bytes(DEFAULT_MAX_SCENE_BYTES);
    assert!(e.message.contains("more than the 10 one scene may read"), "{e}");
    load_any(&ply).unwrap();
}

/// A 100 × 100 grid of quads: 20,000 triangles.
fn grid_mesh(shape: &str, extra: &str) -> String {
    let n = 101;
    let p: Vec<String> = (0..n * n).map(|i| format!("{} {} 0", i % n, i / n)).collect();
    let mut idx = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = j * n + i;
            idx.extend([v, v + 1, v + n + 1, v, v + n + 1, v + n]);
        }
    }
    let idx: Vec<String> = idx.iter().map(ToString::to_string).collect();
    format!(
        "Shape \"{shape}\" {extra} \"point3 P\" [ {} ] \"integer indices\" [ {} ]\n",
        p.join(" "),
        idx.join(" ")
    )
}

#[test]
fn subdivision_past_the_triangle_budget_is_refused_before_it_starts() {
    let dir = temp_dir("limits-subdiv");
    let main =
        write(&dir, "scene.pbrt", format!("{OPTIONS}{}", grid_mesh("loopsubdiv", "\"integer levels\" 8")));
    let start = Instant::now();
    let (loaded, budget) = load_with(LoadBudget::new(u64::MAX, 1 << 28), &main);
    let e = loaded.unwrap_err();
    assert!(start.elapsed().as_secs() < 5, "refused only after {:?}", start.elapsed());
    assert_eq!(e.line, 3, "{e}");
    assert!(
        e.message.starts_with("loopsubdiv: 8 levels of subdivision of 20000 triangles: 1310720000 triangles")
            && e.message.contains("--max-generated-triangles"),
        "{e}"
    );
    assert_eq!(budget.triangles(), 0);
    // Sane levels fit, and draw on the budget.
    write(&dir, "scene.pbrt", format!("{OPTIONS}{}", grid_mesh("loopsubdiv", "\"integer levels\" 1")));
    let (loaded, budget) = load_with(LoadBudget::new(u64::MAX, 1 << 28), &main);
    assert_eq!(loaded.unwrap().scene.meshes[0].indices.len(), 80_000);
    assert_eq!(budget.triangles(), 80_000);
}

#[test]
fn the_triangle_budget_is_shared_by_every_generated_shape() {
    let dir = temp_dir("limits-shapes");
    let curved = "Shape \"bilinearmesh\" \"point3 P\" [ 0 0 0  1 0 0  0 1 0  1 1 1 ]\n";
    let flat = "Shape \"bilinearmesh\" \"point3 P\" [ 0 0 0  1 0 0  0 1 0  1 1 0 ]\n";
    let sphere = "Shape \"sphere\"\n";
    // A curved patch makes 2 × 8² triangles, a flat one 2, a sphere 2 × 64 × 31.
    let main = write(&dir, "scene.pbrt", format!("{OPTIONS}{curved}{flat}{sphere}"));
    let all = 128 + 2 + 3968;
    let (loaded, budget) = load_with(LoadBudget::new(u64::MAX, all), &main);
    assert_eq!(loaded.unwrap().scene.meshes.len(), 3);
    assert_eq!(budget.triangles(), all);
    let (loaded, _) = load_with(LoadBudget::new(u64::MAX, all - 1), &main);
    let e = loaded.unwrap_err();
    assert!(e.line == 5 && e.message.starts_with("sphere: 3968 triangles would bring"), "{e}");
    let (loaded, _) = load_with(LoadBudget::new(u64::MAX, 129), &main);
    let e = loaded.unwrap_err();
    assert!(e.line == 4 && e.message.starts_with("bilinearmesh: 1 patches: 2 triangles"), "{e}");
}

#[cfg(unix)]
#[test]
fn symbolic_links_out_of_the_scene_folder_are_refused() {
    use std::os::unix::fs::symlink;
    let root = temp_dir("limits-links");
    let (scene, outside) = (root.join("scene"), root.join("outside"));
    std::fs::create_dir_all(scene.join("meshes")).unwrap();
    std::fs::create_dir_all(&outside).unwrap();
    write(&outside, "secret.ply", PLY);
    write(&outside, "secret.pbrt", "Shape \"sphere\"\n");
    write(&scene, "meshes/mesh.ply", PLY);
    symlink(outside.join("secret.ply"), scene.join("file.ply")).unwrap();
    symlink(outside.join("secret.pbrt"), scene.join("inc.pbrt")).unwrap();
    symlink(&outside, scene.join("folder")).unwrap();
    symlink(scene.join("meshes/mesh.ply"), scene.join("inside.ply")).unwrap();
    let ply = |name: &str| format!("Shape \"plymesh\" \"string filename\" \"{name}\"\n");
    for (i, statement) in
        [ply("file.ply"), ply("folder/secret.ply"), "Include \"inc.pbrt\"\n".into()].iter().enumerate()
    {
        let main = write(&scene, &format!("scene{i}.pbrt"), format!("{OPTIONS}{statement}"));
        let e = load(&main).unwrap_err();
        assert_eq!((e.file.as_str(), e.line), (main.to_str().unwrap(), 3), "{e}");
        let target = std::fs::canonicalize(&outside).unwrap();
        assert!(
            e.message.contains("through a symbolic link")
                && e.message.contains(target.to_str().unwrap())
                && e.message.contains("--allow-outside-paths"),
            "{e}"
        );
    }
    // Links that stay inside the folder are fine, as is a folder reached
    // through a linked path to the scene itself.
    let main = write(&scene, "inside.pbrt", format!("{OPTIONS}{}", ply("inside.ply")));
    load(&main).unwrap();
    symlink(&scene, root.join("alias")).unwrap();
    load(&root.join("alias/inside.pbrt")).unwrap();
}
