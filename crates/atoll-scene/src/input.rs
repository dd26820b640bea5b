//! Reading the files a scene names, as untrusted input: only regular files
//! (a device such as `/dev/zero`, a pipe or a folder is refused by its type,
//! never read), at most [`MAX_FILE_BYTES`] each and [`max_scene_bytes`] for
//! all the files of one scene together, and gzip data inflated to at most
//! [`MAX_INFLATION`] times its size; the files a scene file names are
//! confined to its folder ([`beside`]), symbolic links included, unless the
//! user allows more ([`allow_outside_paths`]). Shapes that loaders generate
//! (subdivision surfaces, tessellated patches) draw on a budget of
//! [`max_generated_triangles`] for one scene. Loaders read through here.
//!
//! Both budgets belong to one scene load ([`LoadBudget`]): the loaders'
//! entry points run in [`scene_load`], and everything read or generated on
//! that thread until it returns counts against the same budget.

use std::cell::RefCell;
use std::io::{self, Read};
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

/// Whether files a scene names may lie outside its folder.
static OUTSIDE_PATHS: AtomicBool = AtomicBool::new(false);

/// Lets scenes name files outside their folder, absolute paths included
/// (`--allow-outside-paths`): for scenes from trusted sources only.
pub fn allow_outside_paths(allow: bool) {
    OUTSIDE_PATHS.store(allow, Ordering::Relaxed);
}

/// Whether scenes may name files that cannot be read.
static MISSING_FILES: AtomicBool = AtomicBool::new(false);

/// Lets scenes loaded from now on name files (images, environment maps,
/// spectra) that cannot be read, each replaced by a stand-in with a
/// warning (`--allow-missing`). Without it such a file is an error, as in
/// pbrt-v4. One load can say otherwise ([`LoadBudget::allowing_missing_files`]).
pub fn allow_missing_files(allow: bool) {
    MISSING_FILES.store(allow, Ordering::Relaxed);
}

/// Whether the scene load under way may name files that cannot be read.
pub fn missing_files_allowed() -> bool {
    on_budget(|b| b.missing_files_allowed)
}

/// The file `name` that a scene file in folder `base` names: `base/name`,
/// refused (unless [`allow_outside_paths`]) when `name` is absolute, a
/// `file:` URI, climbs out of `base` with `..`, or leads out of it through
/// a symbolic link (a file or a folder inside `base` that links outside).
pub fn beside(base: &Path, name: &str) -> io::Result<PathBuf> {
    if OUTSIDE_PATHS.load(Ordering::Relaxed) {
        return Ok(base.join(name.strip_prefix("file://").unwrap_or(name)));
    }
    let refuse = |why: &str| {
        io::Error::new(
            io::ErrorKind::PermissionDenied,
            format!("'{name}' {why}: refused outside the scene's folder (--allow-outside-paths allows it)"),
        )
    };
    if name.starts_with("file:") {
        return Err(refuse("is a file: URI"));
    }
    let mut depth = 0usize;
    for component in Path::new(name).components() {
        match component {
            Component::Prefix(_) | Component::RootDir => return Err(refuse("is an absolute path")),
            Component::ParentDir if depth == 0 => return Err(refuse("climbs out of the scene's folder")),
            Component::ParentDir => depth -= 1,
            Component::CurDir => {}
            Component::Normal(_) => depth += 1,
        }
    }
    let path = base.join(name);
    // Where links lead is only known on the disk: a name that does not
    // resolve (a missing file) reads nothing, and fails when it is read.
    if let (Ok(real), Ok(real_base)) = (path.canonicalize(), base.canonicalize()) {
        if !real.starts_with(&real_base) {
            return Err(refuse(&format!("leads to '{}' through a symbolic link", real.display())));
        }
    }
    Ok(path)
}

/// Most bytes one scene file may have (a Moana island mesh file is well
/// under this).
pub const MAX_FILE_BYTES: u64 = 64 << 30;

/// Most a gzip file may inflate to, as a multiple of its size: text and
/// meshes inflate some 3–10×; gzip bombs by a thousand and more.
pub const MAX_INFLATION: u64 = 100;

/// Default of [`max_scene_bytes`]: 256 GiB. The budget is there to stop a
/// scene that reads without end (an `Include` or mesh file named again and
/// again), not to judge memory (a mesh file's bytes are dropped once
/// parsed), so it sits far above real scenes: the largest public
/// production scene, Disney's Moana island, is some 50 GiB of pbrt files;
/// four times the per-file cap.
pub const DEFAULT_MAX_SCENE_BYTES: u64 = 256 << 30;

/// Default of [`max_generated_triangles`]: 2^28 (268 million). Generating
/// takes far more memory per triangle than storing one (subdivision keeps
/// every edge's neighbours), some 160 bytes, so this is about 40 GiB at the
/// peak; `loopsubdiv` level 6 of a 20,000-triangle control mesh (82 million
/// triangles) fits, level 7 (328 million) does not.
pub const DEFAULT_MAX_GENERATED_TRIANGLES: u64 = 1 << 28;

static MAX_SCENE_BYTES: AtomicU64 = AtomicU64::new(DEFAULT_MAX_SCENE_BYTES);
static MAX_GENERATED_TRIANGLES: AtomicU64 = AtomicU64::new(DEFAULT_MAX_GENERATED_TRIANGLES);

/// Sets how many bytes all the files of one scene may have together
/// (`--max-scene-bytes`); loads that start later use it.
pub fn set_max_scene_bytes(bytes: u64) {
    MAX_SCENE_BYTES.store(bytes, Ordering::Relaxed);
}

/// How many bytes all the files of one scene may have together.
pub fn max_scene_bytes() -> u64 {
    MAX_SCENE_BYTES.load(Ordering::Relaxed)
}

/// Sets how many triangles the shapes of one scene may generate
/// (`--max-generated-triangles`); loads that start later use it.
pub fn set_max_generated_triangles(triangles: u64) {
    MAX_GENERATED_TRIANGLES.store(triangles, Ordering::Relaxed);
}

/// How many triangles the shapes of one scene may generate (subdivision,
/// tessellation); triangles read from files are bounded by the bytes.
pub fn max_generated_triangles() -> u64 {
    MAX_GENERATED_TRIANGLES.load(Ordering::Relaxed)
}

/// What one scene load may still read and generate, and whether it may name
/// files that cannot be read. Shared (an `Arc` of
/// atomics) so that threads loading parts of one scene draw on one budget:
/// give a worker the loader's [`current_budget`] through [`with_budget`].
pub struct LoadBudget {
    max_bytes: u64,
    bytes: AtomicU64,
    max_triangles: u64,
    triangles: AtomicU64,
    max_files: u64,
    files: AtomicU64,
    /// Progress, for reports: triangles of the meshes made so far, and
    /// nanoseconds threads spent reading files (summed over threads).
    triangles_loaded: AtomicU64,
    read_nanos: AtomicU64,
    /// When the budget was made, and the nanoseconds after it at which the
    /// loader finished each [`LoadPhase`] (0: not reached, or no such phase).
    started: std::time::Instant,
    phase_ends: [AtomicU64; 2],
    /// What the scene's sizes, known before its meshes are read, must pass.
    size_check: Option<SizeCheck>,
    /// See [`allow_missing_files`].
    missing_files_allowed: bool,
}

/// The phases of a load, in order, for loaders that read a scene's text
/// first and its meshes after (PBRT); what follows the last is assembling
/// the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoadPhase {
    /// The scene's text (its included files and textures with it).
    Text = 0,
    /// The mesh files, read and decoded in parallel.
    Meshes = 1,
}

/// A check of a scene's [`crate::SceneSizes`] before its meshes are read:
/// `Err(why)` when the scene cannot fit where it is going.
pub type SizeCheck = Box<dyn Fn(&crate::SceneSizes) -> Result<(), String> + Send + Sync>;

impl std::fmt::Debug for LoadBudget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LoadBudget")
            .field("bytes", &self.bytes())
            .field("files", &self.files())
            .field("triangles", &self.triangles())
            .field("size_check", &self.size_check.is_some())
            .finish_non_exhaustive()
    }
}

/// Most files (counting each time one is read) one scene may read: far
/// more than production scenes have (thousands), and a stop for Include
/// chains that read tiny files exponentially many times, which the byte
/// budget would let run for hours.
pub const MAX_SCENE_FILES: u64 = 1_000_000;

impl LoadBudget {
    /// A budget of `max_bytes` bytes read and `max_triangles` generated.
    pub fn new(max_bytes: u64, max_triangles: u64) -> Self {
        LoadBudget {
            max_bytes,
            bytes: AtomicU64::new(0),
            max_triangles,
            triangles: AtomicU64::new(0),
            max_files: MAX_SCENE_FILES,
            files: AtomicU64::new(0),
            triangles_loaded: AtomicU64::new(0),
            read_nanos: AtomicU64::new(0),
            started: std::time::Instant::now(),
            phase_ends: Default::default(),
            size_check: None,
            missing_files_allowed: false,
        }
    }

    /// Notes that the loader has finished `phase`, now.
    pub fn end_phase(&self, phase: LoadPhase) {
        let nanos = self.started.elapsed().as_nanos().clamp(1, u64::MAX as u128) as u64;
        self.phase_ends[phase as usize].store(nanos, Ordering::Relaxed);
    }

    /// Seconds after the budget was made at which `phase` ended, for
    /// loaders that have it.
    pub fn phase_end(&self, phase: LoadPhase) -> Option<f64> {
        let nanos = self.phase_ends[phase as usize].load(Ordering::Relaxed);
        (nanos > 0).then_some(nanos as f64 * 1e-9)
    }

    /// The same budget, with a check of the scene's sizes that loaders run
    /// before they read its meshes ([`LoadBudget::check_sizes`]).
    pub fn with_size_check(self, check: SizeCheck) -> Self {
        LoadBudget { size_check: Some(check), ..self }
    }

    /// Whether there is a size check (estimating sizes costs file reads).
    pub fn has_size_check(&self) -> bool {
        self.size_check.is_some()
    }

    /// Runs the size check, if any: `Err(why)` when the scene cannot fit.
    pub fn check_sizes(&self, sizes: &crate::SceneSizes) -> Result<(), String> {
        self.size_check.as_ref().map_or(Ok(()), |check| check(sizes))
    }

    /// The same budget allowing at most `max_files` file reads.
    pub fn with_max_files(self, max_files: u64) -> Self {
        LoadBudget { max_files, ..self }
    }

    /// The same budget, its load letting the scene name files that cannot
    /// be read (or not).
    pub fn allowing_missing_files(self, allow: bool) -> Self {
        LoadBudget { missing_files_allowed: allow, ..self }
    }

    /// A budget with the limits set now ([`max_scene_bytes`],
    /// [`max_generated_triangles`], [`allow_missing_files`]).
    pub fn from_settings() -> Self {
        LoadBudget::new(max_scene_bytes(), max_generated_triangles())
            .allowing_missing_files(MISSING_FILES.load(Ordering::Relaxed))
    }

    /// Bytes read so far.
    pub fn bytes(&self) -> u64 {
        self.bytes.load(Ordering::Relaxed)
    }

    /// Triangles generated so far.
    pub fn triangles(&self) -> u64 {
        self.triangles.load(Ordering::Relaxed)
    }

    /// Files read so far (each read counted).
    pub fn files(&self) -> u64 {
        self.files.load(Ordering::Relaxed)
    }

    /// Triangles of the meshes made so far (read or generated).
    pub fn triangles_loaded(&self) -> u64 {
        self.triangles_loaded.load(Ordering::Relaxed)
    }

    /// Counts `n` triangles of a mesh made.
    pub fn count_loaded_triangles(&self, n: u64) {
        self.triangles_loaded.fetch_add(n, Ordering::Relaxed);
    }

    /// Seconds threads spent reading files, summed over threads.
    pub fn read_seconds(&self) -> f64 {
        self.read_nanos.load(Ordering::Relaxed) as f64 * 1e-9
    }

    /// Adds `n` to `used`, refusing (and leaving it as it was) when the
    /// sum would pass `max`; returns the sum it refused.
    fn draw(used: &AtomicU64, n: u64, max: u64) -> Result<(), u64> {
        used.fetch_update(Ordering::Relaxed, Ordering::Relaxed, |u| u.checked_add(n).filter(|&t| t <= max))
            .map(drop)
            .map_err(|u| u.saturating_add(n))
    }

    /// Counts a file of `n` bytes; refused past the scene's byte budget or
    /// its number of file reads.
    pub fn read_bytes(&self, n: u64) -> io::Result<()> {
        Self::draw(&self.files, 1, self.max_files).map_err(|_| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "more than the {} file reads one scene may make (files included over and over?)",
                    self.max_files
                ),
            )
        })?;
        Self::draw(&self.bytes, n, self.max_bytes).map_err(|total| {
            io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "its {n} bytes would bring the scene's files to {total} bytes, more than the {} one scene may read (--max-scene-bytes)",
                    self.max_bytes
                ),
            )
        })
    }

    /// Counts `n` generated triangles; refused past the scene's budget,
    /// with a message saying so (the caller says where and what).
    pub fn generate_triangles(&self, n: u64) -> Result<(), String> {
        Self::draw(&self.triangles, n, self.max_triangles).map_err(|total| {
            format!(
                "{n} triangles would bring the triangles generated for the scene to {total}, more than the {} allowed (--max-generated-triangles)",
                self.max_triangles
            )
        })
    }
}

thread_local! {
    /// The budget of the scene load under way on this thread.
    static CURRENT: RefCell<Option<Arc<LoadBudget>>> = const { RefCell::new(None) };
}

/// The budget of the scene load under way on this thread, if any.
pub fn current_budget() -> Option<Arc<LoadBudget>> {
    CURRENT.with(|c| c.borrow().clone())
}

/// Runs `f` with `budget` as this thread's scene budget (restored after,
/// even if `f` panics).
pub fn with_budget<T>(budget: Arc<LoadBudget>, f: impl FnOnce() -> T) -> T {
    struct Restore(Option<Arc<LoadBudget>>);
    impl Drop for Restore {
        fn drop(&mut self) {
            CURRENT.with(|c| *c.borrow_mut() = self.0.take());
        }
    }
    let _restore = Restore(CURRENT.with(|c| c.borrow_mut().replace(budget)));
    f()
}

/// Runs the scene load `load` with a budget: the one already under way on
/// this thread (a loader calling another), else a fresh one from the
/// settings. Every loader's entry point runs in it.
pub fn scene_load<T>(load: impl FnOnce() -> T) -> T {
    match current_budget() {
        Some(_) => load(),
        None => with_budget(Arc::new(LoadBudget::from_settings()), load),
    }
}

/// Runs `f` on the current scene's budget, or outside any load (a file
/// read on its own) on a fresh one with the settings' limits.
pub fn on_budget<T>(f: impl FnOnce(&LoadBudget) -> T) -> T {
    match current_budget() {
        Some(b) => f(&b),
        None => f(&LoadBudget::from_settings()),
    }
}

/// Refuses what is not a regular file of at most [`MAX_FILE_BYTES`]
/// (symbolic links are followed to what they name), or one that would take
/// the scene past its byte budget, and counts it there; returns its length.
/// Call it once per file read (other readers, such as image decoders, read
/// the file after it).
pub fn check_regular(path: &Path) -> io::Result<u64> {
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        let kind = if meta.is_dir() { "a folder" } else { "not a regular file (a device or a pipe)" };
        return Err(io::Error::new(io::ErrorKind::InvalidInput, format!("is {kind}")));
    }
    if meta.len() > MAX_FILE_BYTES {
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("has {} bytes, more than the {MAX_FILE_BYTES} a scene file may have", meta.len()),
        ));
    }
    on_budget(|b| b.read_bytes(meta.len()))?;
    Ok(meta.len())
}

/// The bytes of the regular file `path` ([`check_regular`]), read no
/// further than the size it had when checked (a file growing while read
/// is cut there).
pub fn read(path: &Path) -> io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    read_into(path, &mut bytes)?;
    Ok(bytes)
}

/// [`read`] into `bytes` (cleared first), reusing its memory: fresh memory
/// costs the kernel a page clear per 4 KiB, as much as the read itself.
pub fn read_into(path: &Path, bytes: &mut Vec<u8>) -> io::Result<()> {
    let len = check_regular(path)?;
    bytes.clear();
    // A file may be larger than the memory there is (a sparse file of
    // 60 GiB takes no disk): an error of kind `OutOfMemory`, not an abort.
    bytes.try_reserve_exact(len as usize).map_err(|_| {
        io::Error::new(
            io::ErrorKind::OutOfMemory,
            format!("has {len} bytes, more than this process can allocate"),
        )
    })?;
    let start = std::time::Instant::now();
    std::fs::File::open(path)?.take(len).read_to_end(bytes)?;
    let nanos = start.elapsed().as_nanos() as u64;
    on_budget(|b| b.read_nanos.fetch_add(nanos, Ordering::Relaxed));
    Ok(())
}

/// Whether `error` or any error beneath it is an I/O error of kind
/// `OutOfMemory`: the input did not fit, rather than being wrong.
pub fn is_out_of_memory(error: &(dyn std::error::Error + 'static)) -> bool {
    let mut next = Some(error);
    while let Some(e) = next {
        if e.downcast_ref::<io::Error>().is_some_and(|io| io.kind() == io::ErrorKind::OutOfMemory) {
            return true;
        }
        next = e.source();
    }
    false
}

/// `compressed` gzip data inflated, at most [`MAX_INFLATION`] times its size.
pub fn gunzip(compressed: &[u8]) -> io::Result<Vec<u8>> {
    let limit = (compressed.len() as u64).saturating_mul(MAX_INFLATION).max(1 << 20);
    let mut out = Vec::new();
    flate2::read::MultiGzDecoder::new(compressed).take(limit + 1).read_to_end(&mut out)?;
    if out.len() as u64 > limit {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("inflates past {limit} bytes, {MAX_INFLATION} times its size (a gzip bomb?)"),
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_files_stay_in_the_scene_folder() {
        let base = Path::new("/scenes/island");
        assert_eq!(beside(base, "geometry/tree.ply").unwrap(), base.join("geometry/tree.ply"));
        assert_eq!(beside(base, "a/../b.ply").unwrap(), base.join("a/../b.ply"));
        for bad in ["../../../etc/passwd", "/etc/passwd", "file:///etc/passwd", "a/../../b", "./../x"] {
            let e = beside(base, bad).unwrap_err();
            assert_eq!(e.kind(), io::ErrorKind::PermissionDenied, "{bad}");
            assert!(e.to_string().contains("--allow-outside-paths"), "{e}");
        }
    }

    #[test]
    fn devices_folders_and_bombs_are_refused_without_reading_them() {
        for path in ["/dev/zero", "/dev/null", "/"] {
            if Path::new(path).exists() {
                let e = read(Path::new(path)).unwrap_err();
                assert_eq!(e.kind(), io::ErrorKind::InvalidInput, "{path}: {e}");
            }
        }
        // 64 MiB of zeros compress to some 64 KiB: over a hundred times.
        use std::io::Write;
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        gz.write_all(&vec![0u8; 64 << 20]).unwrap();
        let bomb = gz.finish().unwrap();
        let e = gunzip(&bomb).unwrap_err();
        assert!(e.to_string().contains("gzip bomb"), "{e}");
        // Ordinary data inflates fine.
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        gz.write_all(b"Shape \"sphere\"\n").unwrap();
        assert_eq!(gunzip(&gz.finish().unwrap()).unwrap(), b"Shape \"sphere\"\n");
    }
}
