//! The PBRT-v4 scene loader.
//!
//! Loading goes in three steps, as in pbrt-v4: [`tokenizer`] and [`parser`]
//! turn text into directives with a location each (syntax only); [`builder`]
//! runs them against the graphics state (transforms, materials, area lights,
//! object definitions) and produces a [`crate::Scene`]; [`params`],
//! [`entities`] and [`shapes`] turn parameter lists into typed values,
//! materials, lights and meshes. Every error is a [`SceneError`] that points at
//! a file, line and column; everything ignored or approximated is a
//! [`Warning`], also emitted with `tracing::warn!`.
//!
//! Textures ([`textures`]) fill [`crate::Scene::textures`]: `Texture`
//! statements become texture nodes, texture-valued material parameters
//! become bindings, and a shape's `alpha` a mask on its mesh.
//!
//! pbrt-v3 files load too: v3 type spellings (`point`, `color`, Booleans as
//! strings), v3 texture parameters (`gamma`, `scale`'s `tex1`/`tex2`), v3
//! materials mapped by [`v3`], `mix` resolved to its first material,
//! `WorldEnd`, `Film "image"`, two-value `blackbody`, the infinite light's
//! `mapname`; what cannot be honoured is warned about.

mod ahead;
pub mod builder;
pub mod curves;
pub mod entities;
mod fluorescent;
mod measured;
pub mod params;
pub mod parser;
mod pending;
pub mod quadrics;
pub mod shapes;
pub mod spectrum;
pub mod subdivision;
pub mod textures;
pub mod tokenizer;
pub mod transform;
pub mod v3;

use std::path::{Path, PathBuf};

use crate::error::{FileLoc, SceneError, Warning};
pub use crate::load::LoadedScene;

/// Loads a `.pbrt` (or `.pbrt.gz`) file. Relative paths inside it (`Include`,
/// `plymesh` file names) resolve against the file's directory, as pbrt-v4 does.
pub fn load_file(path: &Path) -> Result<LoadedScene, SceneError> {
    crate::input::scene_load(|| load_path(path))
}

fn load_path(path: &Path) -> Result<LoadedScene, SceneError> {
    let name = path.display().to_string();
    let bytes = read_scene_file(path)
        .map_err(|e| SceneError::caused_by(&FileLoc::whole_file(name.as_str()), e.to_string(), e))?;
    let base_dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let canonical = path.canonicalize().ok();
    builder::Builder::new(&base_dir).load(bytes, &name, canonical)
}

/// Loads scene text. `name` is used in messages; relative paths resolve
/// against `base_dir`.
pub fn load_str(text: &str, name: &str, base_dir: &Path) -> Result<LoadedScene, SceneError> {
    crate::input::scene_load(|| builder::Builder::new(base_dir).load(text.as_bytes().to_vec(), name, None))
}

/// Why a scene file's bytes could not be had; the caller says which file.
#[derive(Debug, thiserror::Error)]
enum ReadSceneError {
    #[error("cannot read scene file: {0}")]
    Read(#[source] std::io::Error),
    #[error("bad gzip data: {0}")]
    Gzip(#[source] std::io::Error),
}

/// Reads a scene file, decompressing `.gz` files.
fn read_scene_file(path: &Path) -> Result<Vec<u8>, ReadSceneError> {
    let bytes = crate::input::read(path).map_err(ReadSceneError::Read)?;
    if path.extension().is_some_and(|e| e == "gz") {
        return crate::input::gunzip(&bytes).map_err(ReadSceneError::Gzip);
    }
    Ok(bytes)
}

/// A file the scene names at `loc` could not be had (`error`): an error
/// naming `what` needs it, unless [`crate::input::allow_missing_files`],
/// when the caller goes on with its stand-in and its warning. The error
/// keeps `error` as its cause (a file too large to read did not fit; it is
/// not wrong).
pub(crate) fn missing_file<E>(loc: &FileLoc, what: &str, error: E) -> Result<(), SceneError>
where
    E: std::error::Error + Send + Sync + 'static,
{
    if crate::input::missing_files_allowed() {
        return Ok(());
    }
    let message = format!("{what}: {error} (--allow-missing renders without it)");
    Err(SceneError::caused_by(loc, message, error))
}

/// Collects warnings and emits each with `tracing::warn!`.
#[derive(Debug, Default)]
pub struct WarningSink {
    /// The warnings so far.
    pub list: Vec<Warning>,
}

impl WarningSink {
    /// Records a warning at `loc`.
    pub fn warn(&mut self, loc: &FileLoc, message: impl Into<String>) {
        let w = Warning::at(loc, message);
        tracing::warn!("{w}");
        self.list.push(w);
    }
}
