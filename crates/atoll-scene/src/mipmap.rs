//! MIP pyramids of image textures, made as pbrt-v4's
//! `Image::GeneratePyramid` makes them: an image whose sides are not powers
//! of two is first resized up to the next ones with pbrt's windowed-sinc
//! (Lanczos) resampling, then each level is the 2×2 box average of the one
//! below, down to a single texel. Averages are taken in linear floats, and
//! each level is stored in the image's own format (8-bit sRGB images stay
//! 8-bit sRGB), as pbrt stores them.

use rayon::prelude::*;

use crate::{Texels, TextureImage, Wrap};

/// Linear RGBA texels, row 0 at the top.
struct Level {
    width: u32,
    height: u32,
    texels: Vec<[f32; 4]>,
}

/// `image`'s MIP pyramid: its finest level where that is not the image
/// itself (an image whose sides are not powers of two is resized up
/// first), and the coarser levels, finest first. `wrap` says what lies
/// beyond the edges for the resizing. Each level's rows are made in
/// parallel.
pub struct Pyramid {
    pub resized: Option<TextureImage>,
    pub coarser: Vec<TextureImage>,
}

pub fn pyramid(image: &TextureImage, wrap: Wrap) -> Pyramid {
    let (w, h) = (image.width, image.height);
    let mut level = Level {
        width: w,
        height: h,
        texels: (0..h).into_par_iter().flat_map_iter(|y| (0..w).map(move |x| image.texel(x, y))).collect(),
    };
    let mut resized = None;
    if !w.is_power_of_two() || !h.is_power_of_two() {
        level = resize_up(&level, w.next_power_of_two(), h.next_power_of_two(), wrap);
        resized = Some(stored_like(image, 0, &level));
    }
    let count = level.width.max(level.height).ilog2();
    let mut coarser = Vec::with_capacity(count as usize);
    for i in 1..=count {
        level = downsample(&level);
        coarser.push(stored_like(image, i, &level));
    }
    Pyramid { resized, coarser }
}

/// `level` stored in `image`'s format, named after it and its `index`.
fn stored_like(image: &TextureImage, index: u32, level: &Level) -> TextureImage {
    let texels = match &image.texels {
        Texels::Rgba8 { srgb, .. } => {
            let colour = |v: f32| if *srgb { linear_to_srgb8(v) } else { linear_to_u8(v) };
            let data = level
                .texels
                .par_iter()
                .map(|&[r, g, b, a]| [colour(r), colour(g), colour(b), linear_to_u8(a)]);
            Texels::Rgba8 { srgb: *srgb, data: data.collect() }
        }
        Texels::RgbaF32(_) => Texels::RgbaF32(level.texels.clone()),
    };
    let name = format!("{} (MIP level {index})", image.name);
    TextureImage { name, width: level.width, height: level.height, texels }
}

/// The next level: each texel the mean of a 2×2 block (a side of one
/// texel averages that texel with itself).
fn downsample(level: &Level) -> Level {
    let (w, h) = (level.width, level.height);
    let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
    let at = |x: u32, y: u32| level.texels[(y.min(h - 1) * w + x.min(w - 1)) as usize];
    let texels = (0..nh)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..nw).map(move |x| {
                let (x0, y0) = (2 * x, 2 * y);
                let block = [at(x0, y0), at(x0 + 1, y0), at(x0, y0 + 1), at(x0 + 1, y0 + 1)];
                std::array::from_fn(|c| (block[0][c] + block[1][c] + block[2][c] + block[3][c]) / 4.0)
            })
        })
        .collect();
    Level { width: nw, height: nh, texels }
}

/// One output texel's four source texels and their weights.
struct Resample {
    first: i64,
    weights: [f32; 4],
}

/// pbrt's `Image::ResampleWeights`: a windowed sinc of radius 2 (tau 2)
/// over four source texels per output texel, normalised.
fn resample_weights(old: u32, new: u32) -> Vec<Resample> {
    let windowed_sinc = |x: f32| {
        let sinc = |x: f32| {
            if x == 0.0 {
                1.0
            } else {
                (std::f32::consts::PI * x).sin() / (std::f32::consts::PI * x)
            }
        };
        if x.abs() > 2.0 {
            0.0
        } else {
            sinc(x) * sinc(x / 2.0)
        }
    };
    (0..new)
        .map(|i| {
            let center = (i as f32 + 0.5) * old as f32 / new as f32;
            let first = (center - 2.0 + 0.5).floor() as i64;
            let mut weights = std::array::from_fn(|j| windowed_sinc(first as f32 + j as f32 + 0.5 - center));
            let sum: f32 = weights.iter().sum();
            weights.iter_mut().for_each(|w| *w /= sum);
            Resample { first, weights }
        })
        .collect()
}

/// pbrt's `Image::FloatResizeUp`: separable resampling to `nw` × `nh`,
/// texels beyond the edges as `wrap` says, the result clamped at zero.
fn resize_up(level: &Level, nw: u32, nh: u32, wrap: Wrap) -> Level {
    let (w, h) = (level.width as i64, level.height as i64);
    let source = |x: i64, y: i64| match (wrap.texel(x, w), wrap.texel(y, h)) {
        (Some(x), Some(y)) => level.texels[(y * w + x) as usize],
        _ => [0.0; 4],
    };
    let xs = resample_weights(level.width, nw);
    let ys = resample_weights(level.height, nh);
    // Rows of the x pass, for every source row a y weight reaches.
    let (y_lo, y_hi) = (ys[0].first, ys[ys.len() - 1].first + 4);
    let rows: Vec<Vec<[f32; 4]>> = (y_lo..y_hi)
        .into_par_iter()
        .map(|y| {
            xs.iter()
                .map(|r| {
                    let taps = std::array::from_fn::<_, 4, _>(|j| source(r.first + j as i64, y));
                    std::array::from_fn(|c| (0..4).map(|j| r.weights[j] * taps[j][c]).sum())
                })
                .collect()
        })
        .collect();
    let texels = ys
        .par_iter()
        .flat_map_iter(|r| {
            let rows = &rows;
            (0..nw as usize).map(move |x| {
                let row = |j: usize| rows[(r.first + j as i64 - y_lo) as usize][x];
                std::array::from_fn(|c| (0..4).map(|j| r.weights[j] * row(j)[c]).sum::<f32>().max(0.0))
            })
        })
        .collect();
    Level { width: nw, height: nh, texels }
}

/// pbrt's `LinearToSRGB8`.
fn linear_to_srgb8(v: f32) -> u8 {
    if v <= 0.0 {
        return 0;
    }
    if v >= 1.0 {
        return 255;
    }
    let encoded = if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
    (255.0 * encoded).round().clamp(0.0, 255.0) as u8
}

/// A linear value in [0, 1] as a byte, rounded.
fn linear_to_u8(v: f32) -> u8 {
    (255.0 * v).round().clamp(0.0, 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every level, the finest first (the image itself where not resized).
    fn levels(image: &TextureImage, wrap: Wrap) -> Vec<TextureImage> {
        let p = pyramid(image, wrap);
        std::iter::once(p.resized.unwrap_or_else(|| image.clone())).chain(p.coarser).collect()
    }

    fn image(w: u32, h: u32, texel: impl Fn(u32, u32) -> [f32; 4]) -> TextureImage {
        let texels = (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).map(|(x, y)| texel(x, y)).collect();
        TextureImage::from_linear("test", w, h, texels)
    }

    #[test]
    fn levels_halve_down_to_one_texel_averaging_blocks() {
        let img = image(8, 2, |x, y| [x as f32, y as f32, (x * y) as f32, 1.0]);
        assert!(
            pyramid(&img, Wrap::Repeat).resized.is_none(),
            "a power-of-two image is its own finest level"
        );
        let levels = levels(&img, Wrap::Repeat);
        let sizes: Vec<_> = levels.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, [(8, 2), (4, 1), (2, 1), (1, 1)]);
        // Level 1, texel 1: the block x 2..4, y 0..2.
        assert_eq!(levels[1].texel(1, 0), [2.5, 0.5, 1.25, 1.0]);
        // A side of one texel averages that texel with itself.
        assert_eq!(levels[3].texel(0, 0), [3.5, 0.5, 1.75, 1.0]);
    }

    #[test]
    fn sides_that_are_no_powers_of_two_are_resized_up_keeping_constants() {
        for wrap in [Wrap::Repeat, Wrap::Clamp, Wrap::Mirror] {
            let img = image(5, 3, |_, _| [0.25, 0.5, 1.0, 1.0]);
            let levels = levels(&img, wrap);
            assert_eq!((levels[0].width, levels[0].height), (8, 4));
            assert_eq!(levels.len(), 4);
            for l in &levels {
                for y in 0..l.height {
                    for x in 0..l.width {
                        let t = l.texel(x, y);
                        for (c, want) in [0.25, 0.5, 1.0, 1.0].into_iter().enumerate() {
                            assert!((t[c] - want).abs() < 1e-5, "{wrap:?} {x} {y}: {t:?}");
                        }
                    }
                }
            }
        }
        // Black beyond the edges darkens the border texels.
        let levels = levels(&image(3, 3, |_, _| [1.0; 4]), Wrap::Black);
        assert!(levels[0].texel(0, 0)[0] < levels[0].texel(1, 1)[0]);
    }

    #[test]
    fn resampling_weights_are_pbrts() {
        // Same size: the identity.
        for r in resample_weights(4, 4) {
            assert_eq!(r.weights.map(|w| (w * 1e6).round() / 1e6), [0.0, 1.0, 0.0, 0.0]);
        }
        // Doubling: output 0's center is 0.25 source texels in, its taps
        // start at -2 and the nearest source texels weigh most.
        let w = resample_weights(2, 4);
        assert_eq!(w[0].first, -2);
        assert!((w[0].weights.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        assert!(w[0].weights[2] > w[0].weights[3] && w[0].weights[2] > 0.5);
    }

    #[test]
    fn eight_bit_srgb_levels_stay_eight_bit_srgb() {
        let img = TextureImage {
            name: "bytes".into(),
            width: 2,
            height: 1,
            texels: Texels::Rgba8 { srgb: true, data: vec![[0, 0, 0, 255], [255, 255, 255, 255]] },
        };
        let levels = levels(&img, Wrap::Repeat);
        // The mean of black and white is linear 0.5: sRGB byte 188.
        assert_eq!(levels[1].texels, Texels::Rgba8 { srgb: true, data: vec![[188, 188, 188, 255]] });
        for v in 0..=255u8 {
            assert_eq!(linear_to_srgb8(crate::texture::srgb8_to_linear()[v as usize]), v);
        }
    }
}
