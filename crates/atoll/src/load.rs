//! Scene loading for every subcommand: a file of any supported format (chosen
//! by extension, see `atoll_scene::load_any`), a generated scene named
//! `landscape:GROWTH[:SEED]`, or the built-in Cornell box.

use std::path::Path;

use atoll_scene::landscape::Landscape;
use atoll_scene::Scene;

use crate::CliError;

/// The prefix that names a generated landscape instead of a file.
const LANDSCAPE: &str = "landscape:";

/// Loads `path` (or the built-in Cornell box for `None`). Warnings have
/// already been printed by the loader through `tracing`.
pub fn load_scene(path: Option<&Path>) -> Result<Scene, CliError> {
    let Some(path) = path else {
        return Ok(atoll_scene::cornell::builtin_cornell_box());
    };
    if let Some(landscape) = path.to_str().and_then(parse_landscape) {
        let landscape = landscape?;
        landscape.check().map_err(|m| CliError::Input(format!("{}: {m}", path.display())))?;
        check_fits_host(path, landscape.estimate().bytes)?;
        return Ok(landscape.build());
    }
    atoll_scene::load_any(path).map(|l| l.scene).map_err(|e| CliError::Input(e.to_string()))
}

/// Refuses, before building, a generated scene whose meshes alone would
/// take more host memory than the OS has available.
fn check_fits_host(source: &Path, bytes: u64) -> Result<(), CliError> {
    match atoll_dist::placement::host_memory_available() {
        Some(available) if bytes > available => Err(CliError::Runtime(format!(
            "{}: its meshes need {bytes} bytes of host memory, {available} are available",
            source.display()
        ))),
        _ => Ok(()),
    }
}

/// `landscape:GROWTH[:SEED]` as a [`Landscape`] (detail 1); `None` when
/// `source` does not start with `landscape:`, an error when the rest is wrong.
pub fn parse_landscape(source: &str) -> Option<Result<Landscape, CliError>> {
    let rest = source.strip_prefix(LANDSCAPE)?;
    let bad = |what: &str| CliError::Input(format!("{source}: {what} (expected landscape:GROWTH[:SEED])"));
    let mut parts = rest.split(':');
    let growth = match parts.next().map(str::parse::<u32>) {
        Some(Ok(g)) if g > 0 => g,
        _ => return Some(Err(bad("the growth must be a positive integer"))),
    };
    let seed = match parts.next().map(str::parse::<u32>) {
        None => 0,
        Some(Ok(s)) => s,
        Some(Err(_)) => return Some(Err(bad("the seed must be a non-negative integer"))),
    };
    if parts.next().is_some() {
        return Some(Err(bad("too many fields")));
    }
    Some(Ok(Landscape { growth, seed, ..Default::default() }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn landscape_sources_parse() {
        let l = parse_landscape("landscape:4").unwrap().ok().unwrap();
        assert_eq!((l.growth, l.seed, l.detail), (4, 0, 1.0));
        let l = parse_landscape("landscape:100:7").unwrap().ok().unwrap();
        assert_eq!((l.growth, l.seed), (100, 7));
        assert!(parse_landscape("scene.pbrt").is_none());
        for bad in ["landscape:", "landscape:0", "landscape:x", "landscape:2:-1", "landscape:2:3:4"] {
            assert!(matches!(parse_landscape(bad), Some(Err(CliError::Input(_)))), "{bad}");
        }
    }
}
