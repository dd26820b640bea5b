//! One entry point for every scene format: [`load_any`] picks the loader by
//! the file's extension, and every loader returns a [`LoadedScene`].
//!
//! | extension | loader | camera, lights, settings |
//! |---|---|---|
//! | `.pbrt`, `.pbrt.gz` | [`crate::pbrt`] (v4, and v3 with warnings) | from the file |
//! | `.obj` (+ `.mtl`) | [`crate::obj`] | [`crate::framing`] defaults |
//! | `.gltf`, `.glb` | [`crate::gltf`] (glTF 2.0) | the file's first perspective camera and its punctual lights; otherwise [`crate::framing`] |
//! | `.ply`, `.ply.gz` | [`crate::ply`], one mesh | [`crate::framing`] defaults |
//! | `.off` | [`crate::off`], one mesh | [`crate::framing`] defaults |

use std::path::Path;

use glam::Affine3A;

use crate::error::{FileLoc, SceneError, Warning};
use crate::pbrt::WarningSink;
use crate::{Instance, Material, Object, Scene, TriangleMesh};

/// A loaded scene with everything the loader had to warn about.
#[derive(Clone, Debug, Default)]
pub struct LoadedScene {
    /// The scene.
    pub scene: Scene,
    /// Everything ignored or approximated, in file order.
    pub warnings: Vec<Warning>,
}

/// The scene formats [`load_any`] knows, by extension.
pub const SUPPORTED_EXTENSIONS: &str = ".pbrt, .pbrt.gz, .obj, .gltf, .glb, .ply, .ply.gz, .off";

/// Loads a scene file of any supported format (see the module docs), chosen
/// by its extension (case-insensitive).
pub fn load_any(path: &Path) -> Result<LoadedScene, SceneError> {
    let loaded = crate::input::scene_load(|| load_by_extension(path))?;
    check_finite(&loaded.scene, &FileLoc::whole_file(path.display().to_string()))?;
    Ok(loaded)
}

/// Refuses a scene whose camera or instances have infinite or NaN
/// transforms, or whose geometry lies beyond f32's range once placed
/// (finite numbers can multiply past it): rays and bounding boxes of
/// infinities break every later step.
fn check_finite(scene: &Scene, loc: &FileLoc) -> Result<(), SceneError> {
    if !scene.settings.camera.camera_to_world.is_finite() {
        return Err(SceneError::at(loc, "the camera's transform is infinite or NaN (numbers too large?)"));
    }
    if let Some(i) = scene.instances.iter().position(|i| !i.object_to_world.is_finite()) {
        return Err(SceneError::at(
            loc,
            format!("instance {i} has an infinite or NaN transform (numbers too large?)"),
        ));
    }
    match scene.world_bounds() {
        Some((lo, hi)) if !(lo.is_finite() && hi.is_finite()) => Err(SceneError::at(
            loc,
            format!("the geometry reaches beyond f32's range once placed (bounds {lo} to {hi})"),
        )),
        _ => Ok(()),
    }
}

fn load_by_extension(path: &Path) -> Result<LoadedScene, SceneError> {
    let name = path.display().to_string();
    let lower = path.file_name().map(|f| f.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let has = |ext: &str| lower.ends_with(ext);
    if has(".pbrt") || has(".pbrt.gz") {
        crate::pbrt::load_file(path)
    } else if has(".obj") {
        crate::obj::load_obj(path)
    } else if has(".gltf") || has(".glb") {
        crate::gltf::load_gltf(path)
    } else if has(".ply") || has(".ply.gz") {
        load_ply(path)
    } else if has(".off") {
        load_off(path)
    } else {
        Err(SceneError::at(
            &FileLoc::whole_file(name),
            format!("unknown scene format (expected one of {SUPPORTED_EXTENSIONS})"),
        ))
    }
}

/// Loads a standalone PLY mesh (`atoll render model.ply`): one mesh with the
/// default diffuse material, framed by [`crate::framing`].
pub fn load_ply(path: &Path) -> Result<LoadedScene, SceneError> {
    crate::input::scene_load(|| load_ply_file(path))
}

fn load_ply_file(path: &Path) -> Result<LoadedScene, SceneError> {
    let loc = FileLoc::whole_file(path.display().to_string());
    let m = crate::ply::read_ply(path).map_err(|e| match e {
        crate::ply::PlyError::Io { source, .. } => {
            SceneError::caused_by(&loc, format!("cannot read: {source}"), source)
        }
        crate::ply::PlyError::Invalid(msg) => SceneError::at(&loc, format!("bad PLY file: {msg}")),
    })?;
    let mut w = WarningSink::default();
    if m.skipped_faces > 0 {
        w.warn(&loc, format!("{} faces that are neither triangles nor quads skipped", m.skipped_faces));
    }
    let mesh = TriangleMesh {
        name: file_name(path),
        positions: m.positions,
        normals: m.normals,
        uvs: m.uvs,
        indices: m.indices,
        ..Default::default()
    };
    single_mesh_scene(mesh, &loc, w)
}

/// Loads a standalone OFF mesh (Geomview's Object File Format, used by CGAL's
/// data sets): one mesh with the default diffuse material, framed.
pub fn load_off(path: &Path) -> Result<LoadedScene, SceneError> {
    crate::input::scene_load(|| load_off_file(path))
}

fn load_off_file(path: &Path) -> Result<LoadedScene, SceneError> {
    let loc = FileLoc::whole_file(path.display().to_string());
    let bytes =
        crate::input::read(path).map_err(|e| SceneError::caused_by(&loc, format!("cannot read: {e}"), e))?;
    let m = crate::off::parse_off(&bytes).map_err(|e| SceneError::at(&e.loc(&loc.file), e.message))?;
    let mut w = WarningSink::default();
    if m.degenerate_faces > 0 {
        w.warn(&loc, format!("{} faces with fewer than 3 vertices skipped", m.degenerate_faces));
    }
    let mesh = TriangleMesh {
        name: file_name(path),
        positions: m.positions,
        normals: m.normals,
        indices: m.indices,
        ..Default::default()
    };
    single_mesh_scene(mesh, &loc, w)
}

/// The file name of `path` (for mesh names).
pub(crate) fn file_name(path: &Path) -> String {
    path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_else(|| path.display().to_string())
}

/// A scene of one mesh in the world object with pbrt's default material.
fn single_mesh_scene(
    mut mesh: TriangleMesh,
    loc: &FileLoc,
    w: WarningSink,
) -> Result<LoadedScene, SceneError> {
    if mesh.indices.is_empty() {
        let n = mesh.positions.len();
        return Err(SceneError::at(
            loc,
            format!("no triangles to render ({n} vertices and no faces: a point cloud?)"),
        ));
    }
    mesh.validate().map_err(|m| SceneError::caused_by(loc, m.to_string(), m))?;
    let mut scene = Scene::default();
    mesh.material = scene.add_material(Material::default_diffuse());
    let id = scene.add_mesh(mesh);
    let mut loaded = LoadedScene { scene, warnings: w.list };
    add_world_object(&mut loaded.scene, vec![id]);
    crate::framing::frame_scene(&mut loaded.scene, true);
    Ok(loaded)
}

/// Puts `meshes` (in world space) into one object with an identity instance.
pub(crate) fn add_world_object(scene: &mut Scene, meshes: Vec<crate::MeshId>) {
    if meshes.is_empty() {
        return;
    }
    let object = scene.add_object(Object { name: "world".into(), meshes });
    scene.instances.push(Instance::new(object, Affine3A::IDENTITY));
}
