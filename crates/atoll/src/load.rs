//! Scene loading for every subcommand: a file of any supported format (chosen
//! by extension, see `atoll_scene::load_any`), or the built-in Cornell box.

use std::path::Path;

use atoll_scene::Scene;

use crate::CliError;

/// Loads `path` (or the built-in Cornell box for `None`). Warnings have
/// already been printed by the loader through `tracing`.
pub fn load_scene(path: Option<&Path>) -> Result<Scene, CliError> {
    let Some(path) = path else {
        return Ok(atoll_scene::cornell::builtin_cornell_box());
    };
    atoll_scene::load_any(path).map(|l| l.scene).map_err(|e| CliError::Input(e.to_string()))
}
