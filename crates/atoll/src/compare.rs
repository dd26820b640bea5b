//! `atoll compare A.exr B.exr`: how far two renders of the same scene are
//! apart (CPU against GPU, before against after a change).
//!
//! Two renders with different random numbers differ by Monte Carlo noise
//! per pixel, so the mean per channel is the robust check; per-pixel
//! relative errors show where they differ. `--max-mean-diff` makes it a test.

use std::path::{Path, PathBuf};

use clap::Args;

use crate::CliError;

#[derive(Args)]
pub struct CompareArgs {
    /// Reference image (.exr).
    pub a: PathBuf,
    /// Image to compare with it (.exr, same size).
    pub b: PathBuf,
    /// Exit 1 when a channel's mean differs by more than this fraction (e.g. 0.02).
    #[arg(long, value_parser = parse_fraction_limit)]
    pub max_mean_diff: Option<f64>,
}

/// A limit a gate can fail: finite and not negative (`nan` or `inf` would
/// pass any two images).
fn parse_fraction_limit(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(f) if f.is_finite() && f >= 0.0 => Ok(f),
        _ => Err(format!("{s:?}: expected a finite fraction of 0 or more")),
    }
}

/// Linear RGB pixels of an EXR and its size.
fn read_exr(path: &Path) -> Result<(usize, usize, Vec<[f32; 3]>), CliError> {
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), vec![[0f32; 3]; res.width() * res.height()]),
        |(w, px): &mut (usize, Vec<[f32; 3]>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = [r, g, b]
        },
    )
    .map_err(|e| CliError::Input(format!("{}: {e}", path.display())))?;
    let size = image.layer_data.size;
    Ok((size.width(), size.height(), image.layer_data.channel_data.pixels.1))
}

/// What `compare` measures.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    pub mean_a: [f64; 3],
    pub mean_b: [f64; 3],
    /// Per channel `|mean_b - mean_a| / mean_a`.
    pub mean_diff: [f64; 3],
    /// Per-pixel relative error `|b - a| / (|a| + 0.01)` (channel average):
    /// mean, median, 99th percentile, max.
    pub pixel_error: [f64; 4],
    pub rmse: f64,
}

/// Compares two images of equal size.
pub fn compare(a: &[[f32; 3]], b: &[[f32; 3]]) -> Comparison {
    let n = a.len().max(1) as f64;
    let mut mean_a = [0.0; 3];
    let mut mean_b = [0.0; 3];
    let mut squared = 0.0;
    let mut errors = Vec::with_capacity(a.len());
    for (pa, pb) in a.iter().zip(b) {
        let mut e = 0.0;
        for c in 0..3 {
            let (x, y) = (pa[c] as f64, pb[c] as f64);
            mean_a[c] += x / n;
            mean_b[c] += y / n;
            squared += (y - x) * (y - x) / (3.0 * n);
            // The offset keeps black pixels from dominating with huge ratios.
            e += (y - x).abs() / (x.abs() + 0.01) / 3.0;
        }
        errors.push(e);
    }
    errors.sort_by(f64::total_cmp);
    let at = |q: f64| errors.get(((errors.len() as f64 - 1.0) * q).round() as usize).copied().unwrap_or(0.0);
    let mean_diff = std::array::from_fn(|c| (mean_b[c] - mean_a[c]).abs() / mean_a[c].abs().max(1e-12));
    Comparison {
        mean_a,
        mean_b,
        mean_diff,
        pixel_error: [errors.iter().sum::<f64>() / n, at(0.5), at(0.99), at(1.0)],
        rmse: squared.sqrt(),
    }
}

pub fn run(args: CompareArgs) -> Result<(), CliError> {
    let (wa, ha, a) = read_exr(&args.a)?;
    let (wb, hb, b) = read_exr(&args.b)?;
    if (wa, ha) != (wb, hb) {
        return Err(CliError::Input(format!("image sizes differ: {wa}x{ha} and {wb}x{hb}")));
    }
    let c = compare(&a, &b);
    let rgb = |v: [f64; 3]| format!("{:.5} {:.5} {:.5}", v[0], v[1], v[2]);
    println!("mean A            {}", rgb(c.mean_a));
    println!("mean B            {}", rgb(c.mean_b));
    println!(
        "mean difference   {:.3}% {:.3}% {:.3}%",
        100.0 * c.mean_diff[0],
        100.0 * c.mean_diff[1],
        100.0 * c.mean_diff[2]
    );
    let [mean, median, p99, max] = c.pixel_error;
    println!("pixel rel. error  mean {mean:.4}, median {median:.4}, p99 {p99:.4}, max {max:.4}");
    println!("rmse              {:.6}", c.rmse);
    if let Some(limit) = args.max_mean_diff {
        let worst = c.mean_diff.iter().copied().fold(0.0, f64::max);
        // NaN means compare as failures.
        if worst.is_nan() || worst > limit {
            return Err(CliError::Runtime(format!(
                "mean differs by {:.3}% (more than {:.3}%)",
                100.0 * worst,
                100.0 * limit
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_images_have_no_error() {
        let a = vec![[0.5, 0.25, 1.0], [0.0, 2.0, 0.1]];
        let c = compare(&a, &a);
        assert_eq!(c.mean_diff, [0.0; 3]);
        assert_eq!(c.pixel_error, [0.0; 4]);
        assert_eq!(c.rmse, 0.0);
        assert!((c.mean_a[1] - 1.125).abs() < 1e-12);
    }

    #[test]
    fn scaled_image_differs_by_the_scale() {
        let a = vec![[1.0, 1.0, 1.0]; 4];
        let b = vec![[1.1, 1.1, 1.1]; 4];
        let c = compare(&a, &b);
        assert!(c.mean_diff.iter().all(|d| (d - 0.1).abs() < 1e-6), "{c:?}");
        assert!((c.pixel_error[1] - 0.1 / 1.01).abs() < 1e-6);
    }
}
