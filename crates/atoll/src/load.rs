//! Scene loading for every subcommand: a file of any supported format (chosen
//! by extension, see `atoll_scene::load_any`), a generated scene named
//! `landscape:GROWTH[:SEED]`, or the built-in Cornell box.

use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use atoll_scene::input::{LoadBudget, LoadPhase, SizeCheck};
use atoll_scene::landscape::Landscape;
use atoll_scene::Scene;

use crate::CliError;

/// The prefix that names a generated landscape instead of a file.
const LANDSCAPE: &str = "landscape:";

/// What loading a scene took and read, for the closing line.
#[derive(Clone, Copy, Debug, Default)]
pub struct LoadReport {
    pub seconds: f64,
    /// Files read (each read counted) and their bytes.
    pub files: u64,
    pub bytes: u64,
    /// Seconds threads spent reading files, summed over threads; the rest
    /// of the load is parsing and making meshes.
    pub read_seconds: f64,
    /// Triangles of the scene's meshes.
    pub triangles: u64,
    /// Wall-clock seconds of the scene's text and of its mesh files, for
    /// loaders that read one before the other; the rest of `seconds` is
    /// assembling the scene.
    pub phases: Option<(f64, f64)>,
}

impl std::fmt::Display for LoadReport {
    /// `load 2.10 s (text 0.05 s, meshes 1.90 s, scene 0.15 s): 12 files,
    /// 3.40 GB (2.1 GB/s), read 0.80 s over threads, 120.0 M triangles`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "load {:.2} s", self.seconds)?;
        if let Some((text, meshes)) = self.phases {
            let scene = (self.seconds - text - meshes).max(0.0);
            write!(f, " (text {text:.2} s, meshes {meshes:.2} s, scene {scene:.2} s)")?;
        }
        if self.files > 0 {
            let gb = self.bytes as f64 / 1e9;
            write!(
                f,
                ": {} files, {gb:.2} GB ({:.2} GB/s), read {:.2} s over threads",
                self.files,
                gb / self.seconds.max(1e-9),
                self.read_seconds
            )?;
        }
        write!(f, ", {:.1} M triangles", self.triangles as f64 / 1e6)
    }
}

/// Loads `path` (or the built-in Cornell box for `None`). Warnings have
/// already been printed by the loader through `tracing`.
pub fn load_scene(path: Option<&Path>) -> Result<Scene, CliError> {
    load_scene_reporting(path, true, None).map(|(scene, _)| scene)
}

/// [`load_scene`], showing what it reads as it goes (unless `quiet`) and
/// reporting it; a file scene's sizes pass `size_check` before its meshes
/// are read.
pub fn load_scene_reporting(
    path: Option<&Path>,
    quiet: bool,
    size_check: Option<SizeCheck>,
) -> Result<(Scene, LoadReport), CliError> {
    let start = std::time::Instant::now();
    let mut budget = LoadBudget::from_settings();
    if let Some(check) = size_check {
        budget = budget.with_size_check(check);
    }
    let budget = Arc::new(budget);
    let done = AtomicBool::new(false);
    let scene = std::thread::scope(|s| {
        if !quiet {
            s.spawn(|| show_progress(&budget, &done, start));
        }
        let scene = atoll_scene::input::with_budget(budget.clone(), || load_unreported(path));
        done.store(true, Ordering::Relaxed);
        scene
    })?;
    let report = LoadReport {
        seconds: start.elapsed().as_secs_f64(),
        files: budget.files(),
        bytes: budget.bytes(),
        read_seconds: budget.read_seconds(),
        triangles: scene.meshes.iter().map(|m| m.indices.len() as u64).sum(),
        phases: budget
            .phase_end(LoadPhase::Text)
            .zip(budget.phase_end(LoadPhase::Meshes))
            .map(|(text, meshes)| (text, meshes - text)),
    };
    Ok((scene, report))
}

/// A spinner with the files, bytes and triangles read so far and their
/// rates, until `done`; shown only for loads that last.
fn show_progress(budget: &LoadBudget, done: &AtomicBool, start: std::time::Instant) {
    let tick = std::time::Duration::from_millis(100);
    let mut bar = None;
    while !done.load(Ordering::Relaxed) {
        std::thread::sleep(tick);
        let seconds = start.elapsed().as_secs_f64();
        if seconds < 1.0 {
            continue;
        }
        let bar = bar.get_or_insert_with(|| {
            let bar = indicatif::ProgressBar::new_spinner();
            bar.set_style(
                indicatif::ProgressStyle::with_template("{spinner} loading [{elapsed_precise}] {msg}")
                    .expect("valid template"),
            );
            bar
        });
        let (gb, triangles) = (budget.bytes() as f64 / 1e9, budget.triangles_loaded() as f64 / 1e6);
        bar.set_message(format!(
            "{} files, {gb:.2} GB ({:.2} GB/s), {triangles:.1} M triangles ({:.1} M/s)",
            budget.files(),
            gb / seconds,
            triangles / seconds
        ));
        bar.tick();
    }
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
}

fn load_unreported(path: Option<&Path>) -> Result<Scene, CliError> {
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
