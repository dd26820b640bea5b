//! Scene loading for every subcommand: a file of any supported format (chosen
//! by extension, see `atoll_scene::load_any`), a generated scene named
//! `landscape:GROWTH[:SEED]`, or the built-in Cornell box.

use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

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
    guarded(path, || {
        atoll_scene::load_any(path).map(|l| l.scene).map_err(|e| {
            // A file larger than the memory there is did not fit; it is not wrong.
            if atoll_scene::input::is_out_of_memory(&e) {
                CliError::Runtime(e.to_string())
            } else {
                CliError::Input(e.to_string())
            }
        })
    })
}

/// Panics seen while [`guarded`] runs: silenced, their message and place
/// kept for the error that reports them.
static QUIET_PANICS: AtomicUsize = AtomicUsize::new(0);
static LAST_PANIC: Mutex<Option<String>> = Mutex::new(None);

/// Installs the panic hook [`guarded`] relies on: while a guarded load
/// runs (on any thread), a panic prints nothing and is remembered; at
/// other times panics print as usual.
pub fn install_panic_hook() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        if QUIET_PANICS.load(Ordering::SeqCst) == 0 {
            return default(info);
        }
        let message = match (info.payload().downcast_ref::<&str>(), info.payload().downcast_ref::<String>()) {
            (Some(s), _) => s.to_string(),
            (_, Some(s)) => s.clone(),
            _ => "a panic".to_string(),
        };
        let place = info.location().map_or(String::new(), |l| format!(" at {}:{}", l.file(), l.line()));
        LAST_PANIC.lock().unwrap_or_else(|e| e.into_inner()).get_or_insert(format!("{message}{place}"));
    }));
}

/// Runs `load` (reading `path`); a panic in it, which no input should
/// cause and which the loaders try hard not to, becomes an internal error
/// naming the file instead of a crash with a backtrace notice.
pub fn guarded<T>(path: &Path, load: impl FnOnce() -> Result<T, CliError>) -> Result<T, CliError> {
    QUIET_PANICS.fetch_add(1, Ordering::SeqCst);
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(load));
    QUIET_PANICS.fetch_sub(1, Ordering::SeqCst);
    let last = LAST_PANIC.lock().unwrap_or_else(|e| e.into_inner()).take();
    result.unwrap_or_else(|_| {
        let what = last.unwrap_or_else(|| "a panic".into());
        Err(CliError::Internal(format!(
            "internal error while reading {}: {what} (please report)",
            path.display()
        )))
    })
}

/// Refuses, before building, a generated scene whose meshes alone would
/// take more host memory than the OS has available.
pub(crate) fn check_fits_host(source: &Path, bytes: u64) -> Result<(), CliError> {
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
    fn a_panic_while_loading_is_an_internal_error_naming_the_file() {
        install_panic_hook();
        let e =
            guarded(Path::new("scenes/broken.gltf"), || -> Result<(), CliError> { panic!("index 7 of 3") });
        let Err(CliError::Internal(message)) = e else { panic!("not an internal error") };
        assert!(
            message.starts_with("internal error while reading scenes/broken.gltf: index 7 of 3 at "),
            "{message}"
        );
        assert!(message.contains("load.rs:") && message.ends_with("(please report)"), "{message}");
        // Errors and results pass through untouched.
        assert!(matches!(
            guarded(Path::new("x"), || Err::<(), _>(CliError::Input("bad".into()))),
            Err(CliError::Input(_))
        ));
        assert_eq!(guarded(Path::new("x"), || Ok(7)).ok(), Some(7));
    }

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
