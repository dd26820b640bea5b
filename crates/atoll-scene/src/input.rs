//! Reading the files a scene names, as untrusted input: only regular files
//! (a device such as `/dev/zero`, a pipe or a folder is refused by its type,
//! never read), at most [`MAX_FILE_BYTES`] each, and gzip data inflated to
//! at most [`MAX_INFLATION`] times its size; the files a scene file names
//! are confined to its folder ([`beside`]) unless the user allows more
//! ([`allow_outside_paths`]). Loaders read through here.

use std::io::{self, Read};
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

/// Whether files a scene names may lie outside its folder.
static OUTSIDE_PATHS: AtomicBool = AtomicBool::new(false);

/// Lets scenes name files outside their folder, absolute paths included
/// (`--allow-outside-paths`): for scenes from trusted sources only.
pub fn allow_outside_paths(allow: bool) {
    OUTSIDE_PATHS.store(allow, Ordering::Relaxed);
}

/// The file `name` that a scene file in folder `base` names: `base/name`,
/// refused (unless [`allow_outside_paths`]) when `name` is absolute, a
/// `file:` URI, or climbs out of `base` with `..` (checked on the names,
/// not by following links).
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
    Ok(base.join(name))
}

/// Most bytes one scene file may have (a Moana island mesh file is well
/// under this).
pub const MAX_FILE_BYTES: u64 = 64 << 30;

/// Most a gzip file may inflate to, as a multiple of its size: text and
/// meshes inflate some 3–10×; gzip bombs by a thousand and more.
pub const MAX_INFLATION: u64 = 100;

/// Refuses what is not a regular file of at most [`MAX_FILE_BYTES`]
/// (symbolic links are followed to what they name); returns its length.
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
    Ok(meta.len())
}

/// The bytes of the regular file `path` ([`check_regular`]), read no
/// further than the size it had when checked (a file growing while read
/// is cut there).
pub fn read(path: &Path) -> io::Result<Vec<u8>> {
    let len = check_regular(path)?;
    let mut bytes = Vec::new();
    // A file may be larger than the memory there is (a sparse file of
    // 60 GiB takes no disk): an error of kind `OutOfMemory`, not an abort.
    bytes.try_reserve_exact(len as usize).map_err(|_| {
        io::Error::new(
            io::ErrorKind::OutOfMemory,
            format!("has {len} bytes, more than this process can allocate"),
        )
    })?;
    std::fs::File::open(path)?.take(len).read_to_end(&mut bytes)?;
    Ok(bytes)
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
