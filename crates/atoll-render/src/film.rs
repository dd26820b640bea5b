//! The film: per-pixel radiance sums with a one-pixel box filter, and image output.

use std::path::{Path, PathBuf};

use glam::{UVec2, Vec3};
use rayon::prelude::*;

/// Radiance sums over the samples taken so far (box filter: each sample
/// lands in exactly the pixel it was generated for).
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub resolution: UVec2,
    /// Row-major, `resolution.x * resolution.y` entries.
    pub sum: Vec<Vec3>,
    /// Samples per pixel accumulated in `sum`.
    pub spp: u32,
}

/// Errors writing an image. `path` is the file asked for (not the
/// temporary one written first); the message repeats the wrapped error's.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: unsupported image extension (use .exr or .png)")]
    UnknownFormat { path: String },
    /// The `exr` crate could not write the image.
    #[error("{path}: {source}")]
    Exr {
        path: String,
        #[source]
        source: exr::error::Error,
    },
    /// The `image` crate could not write the PNG.
    #[error("{path}: {source}")]
    Png {
        path: String,
        #[source]
        source: image::ImageError,
    },
    /// No temporary file could be made beside the target (a folder that
    /// does not exist or cannot be written).
    #[error("{path}: cannot write beside it: {source}")]
    Temporary {
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// The finished image could not replace the target.
    #[error("{path}: {source}")]
    Rename {
        path: String,
        #[source]
        source: std::io::Error,
    },
}

/// Why a format writer failed, before the path is known to the message.
enum WriteFailure {
    Exr(exr::error::Error),
    Png(image::ImageError),
}

/// The folder `path` is in (`.` for a bare name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// A new file `PREFIXxxxxxx.EXT` in `dir` for an image: a temporary file
/// (removed unless kept) with the permissions of any file the user creates
/// (0666 less the umask; temporary files default to 0600, which would
/// leave the image readable by its owner alone).
fn image_file_in(dir: &Path, prefix: &str, ext: &str) -> std::io::Result<tempfile::NamedTempFile> {
    let suffix = format!(".{ext}");
    let mut builder = tempfile::Builder::new();
    builder.prefix(prefix).suffix(&suffix);
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    builder.tempfile_in(dir)
}

impl Film {
    pub fn new(resolution: UVec2) -> Self {
        Film { resolution, sum: vec![Vec3::ZERO; (resolution.x * resolution.y) as usize], spp: 0 }
    }

    pub fn pixel_count(&self) -> usize {
        self.sum.len()
    }

    /// Adds `radiance` to pixel `pixel` (linear index).
    #[inline]
    pub fn add(&mut self, pixel: u32, radiance: Vec3) {
        self.sum[pixel as usize] += radiance;
    }

    /// Adds another film's sums (same resolution) — merging devices.
    pub fn merge(&mut self, other: &Film) {
        assert_eq!(self.resolution, other.resolution, "films of different sizes");
        // In parallel: a 4K film is 25 million additions.
        self.sum.par_iter_mut().zip(other.sum.par_iter()).for_each(|(a, b)| *a += *b);
    }

    /// The film as a sensor of linear `response` records it (every pixel's
    /// sum mapped through it): exposure and white balance.
    pub fn responded(&self, response: glam::Mat3) -> Film {
        let sum = self.sum.par_iter().map(|s| response * *s).collect();
        Film { sum, ..*self }
    }

    /// Mean radiance per pixel (sum / spp).
    pub fn pixels(&self) -> Vec<Vec3> {
        let scale = if self.spp > 0 { 1.0 / self.spp as f32 } else { 0.0 };
        self.sum.iter().map(|s| *s * scale).collect()
    }

    /// Mean over all pixels per channel (tests and summaries).
    pub fn mean(&self) -> Vec3 {
        let total: glam::DVec3 = self.pixels().iter().map(|p| p.as_dvec3()).sum();
        (total / self.pixel_count().max(1) as f64).as_vec3()
    }

    /// Writes the image; the format follows the extension (`.exr` linear
    /// float, `.png` sRGB 8-bit). The file is written to a temporary file
    /// of a unique name next to the target and renamed over it, so an
    /// existing image is never left truncated by a failed write, and no
    /// other file is touched: the temporary file is removed on every
    /// failure, a panic's unwinding included.
    pub fn write(&self, path: &Path) -> Result<(), ImageError> {
        let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
        let display = path.display().to_string();
        let ext = match ext.as_deref() {
            Some(e @ ("exr" | "png")) => e.to_string(),
            _ => return Err(ImageError::UnknownFormat { path: display }),
        };
        let tmp = image_file_in(folder_of(path), ".atoll-", &ext)
            .map_err(|source| ImageError::Temporary { path: display.clone(), source })?;
        self.write_as(tmp.path(), &ext, &display)?;
        tmp.persist(path).map(drop).map_err(|e| ImageError::Rename { path: display, source: e.error })
    }

    /// Writes the image to `file` in format `ext` (`exr`, else PNG); errors
    /// name `display`, the image the user asked for.
    fn write_as(&self, file: &Path, ext: &str, display: &str) -> Result<(), ImageError> {
        let written = if ext == "exr" { self.write_exr(file) } else { self.write_png(file) };
        written.map_err(|failure| match failure {
            WriteFailure::Exr(source) => ImageError::Exr { path: display.to_string(), source },
            WriteFailure::Png(source) => ImageError::Png { path: display.to_string(), source },
        })
    }

    /// Writes the image under a new name when [`Film::write`] to `path`
    /// failed (a folder gone or full, the target replaced by a folder), so
    /// that the render is not lost: `NAME-XXXXXX.EXT` beside `path`, else in
    /// the temporary folder. Returns where it went.
    pub fn write_fallback(&self, path: &Path) -> Result<PathBuf, ImageError> {
        let display = path.display().to_string();
        let ext = match path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref() {
            Some("exr") => "exr",
            _ => "png",
        };
        let stem = path.file_stem().map_or("atoll".into(), |s| s.to_string_lossy().into_owned());
        let mut last = None;
        for dir in [folder_of(path).to_path_buf(), std::env::temp_dir()] {
            let made = image_file_in(&dir, &format!("{stem}-"), ext)
                .map_err(|source| ImageError::Temporary { path: display.clone(), source });
            let tmp = match made {
                Ok(tmp) => tmp,
                Err(e) => {
                    last = Some(e);
                    continue;
                }
            };
            match self.write_as(tmp.path(), ext, &display) {
                Ok(()) => {
                    return tmp
                        .keep()
                        .map(|(_, kept)| kept)
                        .map_err(|e| ImageError::Rename { path: display, source: e.error })
                }
                Err(e) => last = Some(e),
            }
        }
        Err(last.expect("two folders were tried"))
    }

    fn write_exr(&self, path: &Path) -> Result<(), WriteFailure> {
        let pixels = self.pixels();
        let width = self.resolution.x as usize;
        exr::prelude::write_rgb_file(path, width, self.resolution.y as usize, |x, y| {
            let p = pixels[y * width + x];
            (p.x, p.y, p.z)
        })
        .map_err(WriteFailure::Exr)
    }

    fn write_png(&self, path: &Path) -> Result<(), WriteFailure> {
        let bytes: Vec<u8> = self
            .pixels()
            .iter()
            .flat_map(|p| [p.x, p.y, p.z])
            .map(|c| (linear_to_srgb(c) * 255.0 + 0.5) as u8)
            .collect();
        image::save_buffer_with_format(
            path,
            &bytes,
            self.resolution.x,
            self.resolution.y,
            image::ColorType::Rgb8,
            image::ImageFormat::Png,
        )
        .map_err(WriteFailure::Png)
    }
}

/// sRGB transfer function with clamping to [0, 1] (NaN → 0).
pub fn linear_to_srgb(c: f32) -> f32 {
    let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_endpoints() {
        assert_eq!(linear_to_srgb(0.0), 0.0);
        assert!((linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
        assert!((linear_to_srgb(0.5) - 0.7354).abs() < 1e-3);
        assert_eq!(linear_to_srgb(f32::NAN), 0.0);
    }

    #[test]
    fn exr_round_trip_and_failed_write_keeps_old_file() {
        let dir = std::env::temp_dir().join(format!("atoll-film-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut film = Film::new(UVec2::new(3, 2));
        film.add(4, Vec3::new(1.5, 2.0, 0.25));
        film.spp = 1;
        let path = dir.join("a.exr");
        film.write(&path).unwrap();
        let img = exr::prelude::read_first_rgba_layer_from_file(
            &path,
            |res, _| vec![[0f32; 3]; res.width() * res.height()],
            |px: &mut Vec<[f32; 3]>, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                px[pos.y() * 3 + pos.x()] = [r, g, b]
            },
        )
        .unwrap();
        assert_eq!(img.layer_data.channel_data.pixels[4], [1.5, 2.0, 0.25]);
        let bad = dir.join("b.tga");
        assert!(matches!(film.write(&bad), Err(ImageError::UnknownFormat { .. })));
        // A directory that does not exist: the I/O error is kept as the source.
        let nowhere = dir.join("no-such-dir").join("c.png");
        let err = film.write(&nowhere).unwrap_err();
        assert!(matches!(err, ImageError::Temporary { .. }), "{err:?}");
        assert!(err.to_string().starts_with(&nowhere.display().to_string()), "{err}");
        assert!(std::error::Error::source(&err).is_some_and(|s| s.is::<std::io::Error>()));
        // A user's files beside the target, whatever their names, are left
        // alone; the target is replaced whole; nothing temporary remains.
        let theirs = dir.join("a.partial.exr");
        std::fs::write(&theirs, b"mine").unwrap();
        film.write(&path).unwrap();
        assert_eq!(std::fs::read(&theirs).unwrap(), b"mine");
        let names: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(names.iter().all(|n| !n.starts_with(".atoll-")), "{names:?}");
        // A failing write (a target that is a folder) leaves the folder and
        // no temporary file.
        let folder = dir.join("d.png");
        std::fs::create_dir(&folder).unwrap();
        assert!(film.write(&folder).is_err());
        assert!(folder.is_dir());
        let names: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(names.iter().all(|n| !n.starts_with(".atoll-")), "{names:?}");
        std::fs::remove_dir_all(&dir).ok();
    }

    /// Images get the permissions of any file the user creates, not a
    /// temporary file's owner-only ones.
    #[cfg(unix)]
    #[test]
    fn written_images_have_the_permissions_of_new_files() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        let plain = dir.path().join("plain");
        std::fs::write(&plain, b"x").unwrap();
        let mut film = Film::new(UVec2::new(2, 2));
        film.spp = 1;
        for name in ["a.png", "a.exr"] {
            let path = dir.path().join(name);
            film.write(&path).unwrap();
            assert_eq!(mode(&path), mode(&plain), "{name}");
        }
        std::fs::create_dir(dir.path().join("b.png")).unwrap();
        let saved = film.write_fallback(&dir.path().join("b.png")).unwrap();
        assert_eq!(mode(&saved), mode(&plain));
    }

    #[test]
    fn a_failed_write_falls_back_beside_the_target_or_to_the_temporary_folder() {
        let dir = tempfile::tempdir().unwrap();
        let mut film = Film::new(UVec2::new(2, 2));
        film.add(1, Vec3::ONE);
        film.spp = 1;
        // The target became a folder: the image goes beside it, new name.
        let folder = dir.path().join("out.png");
        std::fs::create_dir(&folder).unwrap();
        assert!(film.write(&folder).is_err());
        let saved = film.write_fallback(&folder).unwrap();
        assert_eq!(saved.parent(), Some(dir.path()));
        let name = saved.file_name().unwrap().to_string_lossy().into_owned();
        assert!(name.starts_with("out-") && name.ends_with(".png"), "{name}");
        assert_eq!(&std::fs::read(&saved).unwrap()[1..4], b"PNG");
        assert!(folder.is_dir(), "the folder is left alone");
        // The folder is gone: the image goes to the temporary folder.
        let gone = dir.path().join("gone").join("render.exr");
        assert!(film.write(&gone).is_err());
        let saved = film.write_fallback(&gone).unwrap();
        assert_eq!(saved.parent(), Some(std::env::temp_dir().as_path()));
        assert!(saved.file_name().unwrap().to_string_lossy().starts_with("render-"));
        assert_eq!(&std::fs::read(&saved).unwrap()[..4], &[0x76, 0x2f, 0x31, 0x01], "an EXR");
        std::fs::remove_file(saved).unwrap();
    }
}
