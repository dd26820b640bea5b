//! Scene loading for every subcommand: a file by extension, or the built-in Cornell box.

use std::path::Path;

use atoll_scene::Scene;

use crate::CliError;

/// Loads `path` (or the built-in Cornell box for `None`). Warnings have
/// already been printed by the loader through `tracing`.
pub fn load_scene(path: Option<&Path>) -> Result<Scene, CliError> {
    let Some(path) = path else {
        return Ok(atoll_scene::cornell::builtin_cornell_box());
    };
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    match ext.as_str() {
        "pbrt" => {
            atoll_scene::pbrt::load_file(path).map(|l| l.scene).map_err(|e| CliError::Input(e.to_string()))
        }
        _ => Err(CliError::Input(format!("{}: unknown scene format (expected .pbrt)", path.display()))),
    }
}
