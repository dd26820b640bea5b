//! Pixel filters as pbrt-v4 applies them: a camera sample's offset from
//! its pixel's centre is drawn in proportion to the filter's magnitude, and
//! the sample counts only for its own pixel, weighted by the filter's sign
//! (times the ratio that keeps the expected weight 1). Positive filters
//! (box, Gaussian, triangle) thus weight every sample 1, and a pixel is
//! still the mean of its samples.
//!
//! Every filter is a product of one function per axis, so each axis is
//! sampled on its own from a table of [`FILTER_BINS`] bins over
//! `[0, radius]` (the other half by symmetry), uniform within a bin: the
//! filter rendered is this tabulated one, a close approximation. The GPU
//! reads the same [`FilterTable`] (a part of its frame parameters) and
//! samples it with the same operations (`kernels/camera.cuh`).

use atoll_scene::PixelFilter;
use bytemuck::{Pod, Zeroable};
use glam::Vec2;

/// Bins of a filter table per axis, over `[0, radius]`.
pub const FILTER_BINS: usize = 32;

/// How [`FilterTable`] places samples ([`FilterTable::kind`]).
pub mod filter_kind {
    /// The pixel's own square: raster = pixel + u (atoll's default).
    pub const PIXEL: u32 = 0;
    /// A box of another radius: uniform within it.
    pub const BOX: u32 = 1;
    /// Sampled from the tables.
    pub const TABULATED: u32 = 2;
}

/// A pixel filter prepared for sampling (the GPU reads the same bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct FilterTable {
    /// [`filter_kind`].
    pub kind: u32,
    /// Per axis, bit `i`: bin `i` holds negative filter values.
    pub negative: [u32; 2],
    pub pad: u32,
    pub radius: [f32; 2],
    /// Per axis, the magnitude of a sample's weight: the integral of the
    /// filter's magnitude over the integral of the filter (1 without
    /// negative lobes).
    pub weight: [f32; 2],
    /// Per axis (x's bins, then y's), the cumulative distribution of the
    /// bins' magnitudes at the end of each bin (the last one 1).
    pub cdf: [f32; 2 * FILTER_BINS],
}

impl Default for FilterTable {
    fn default() -> Self {
        FilterTable::new(&PixelFilter::PIXEL)
    }
}

impl FilterTable {
    pub fn new(filter: &PixelFilter) -> Self {
        let radius = filter.radius();
        let mut table = FilterTable {
            kind: filter_kind::TABULATED,
            negative: [0; 2],
            pad: 0,
            radius: radius.to_array(),
            weight: [1.0; 2],
            cdf: [0.0; 2 * FILTER_BINS],
        };
        if let PixelFilter::Box { .. } = filter {
            table.kind = if *filter == PixelFilter::PIXEL { filter_kind::PIXEL } else { filter_kind::BOX };
            return table;
        }
        for axis in 0..2 {
            // Each bin's mean of the filter, from a few points inside it.
            const POINTS: usize = 8;
            let step = radius[axis] / FILTER_BINS as f32;
            let bins: Vec<f32> = (0..FILTER_BINS)
                .map(|i| {
                    let x = |k: usize| (i as f32 + (k as f32 + 0.5) / POINTS as f32) * step;
                    (0..POINTS).map(|k| filter.along(axis, x(k))).sum::<f32>() / POINTS as f32
                })
                .collect();
            let magnitude: f32 = bins.iter().map(|v| v.abs()).sum();
            let signed: f32 = bins.iter().sum();
            let mut running = 0.0;
            for (i, v) in bins.iter().enumerate() {
                running += v.abs();
                table.cdf[axis * FILTER_BINS + i] = running / magnitude;
                if *v < 0.0 {
                    table.negative[axis] |= 1 << i;
                }
            }
            table.cdf[axis * FILTER_BINS + FILTER_BINS - 1] = 1.0;
            table.weight[axis] = magnitude / signed;
        }
        table
    }

    /// The raster position of a sample of pixel `(x, y)` from the uniform
    /// numbers `u`, and its weight.
    pub fn sample(&self, pixel: Vec2, u: Vec2) -> (Vec2, f32) {
        match self.kind {
            filter_kind::PIXEL => (pixel + u, 1.0),
            filter_kind::BOX => {
                let r = Vec2::from(self.radius);
                (pixel + 0.5 + (2.0 * u - 1.0) * r, 1.0)
            }
            _ => {
                let (x, wx) = self.sample_axis(0, u.x);
                let (y, wy) = self.sample_axis(1, u.y);
                (pixel + 0.5 + Vec2::new(x, y), wx * wy)
            }
        }
    }

    /// An offset along `axis` and its weight: the side from `u`'s first
    /// half or second, the bin by the cumulative distribution, uniform in it.
    fn sample_axis(&self, axis: usize, u: f32) -> (f32, f32) {
        let (side, u) = if u < 0.5 { (-1.0, u * 2.0) } else { (1.0, u * 2.0 - 1.0) };
        let ends = &self.cdf[axis * FILTER_BINS..(axis + 1) * FILTER_BINS];
        // The first bin ending past u (a binary search; the last ends at 1 > u).
        let (mut lo, mut hi) = (0usize, FILTER_BINS - 1);
        while lo < hi {
            let mid = (lo + hi) / 2;
            if ends[mid] <= u {
                lo = mid + 1;
            } else {
                hi = mid;
            }
        }
        let start = if lo == 0 { 0.0 } else { ends[lo - 1] };
        let width = ends[lo] - start;
        let within = if width > 0.0 { ((u - start) / width).min(1.0) } else { 0.5 };
        let x = (lo as f32 + within) * (self.radius[axis] / FILTER_BINS as f32);
        let weight = if self.negative[axis] >> lo & 1 != 0 { -self.weight[axis] } else { self.weight[axis] };
        (side * x, weight)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    fn filters() -> [PixelFilter; 5] {
        [
            PixelFilter::Box { radius: Vec2::new(1.0, 0.75) },
            PixelFilter::PBRT_DEFAULT,
            PixelFilter::Mitchell { radius: Vec2::splat(2.0), b: 1.0 / 3.0, c: 1.0 / 3.0 },
            PixelFilter::LanczosSinc { radius: Vec2::splat(4.0), tau: 3.0 },
            PixelFilter::Triangle { radius: Vec2::new(2.0, 1.0) },
        ]
    }

    #[test]
    fn the_pixel_filter_keeps_samples_in_their_pixel() {
        let t = FilterTable::new(&PixelFilter::PIXEL);
        assert_eq!(t.sample(Vec2::new(3.0, 4.0), Vec2::new(0.25, 0.75)), (Vec2::new(3.25, 4.75), 1.0));
    }

    /// Over a fine grid of u, the weighted samples of each axis integrate
    /// the filter: their histogram of offsets, times the weights, follows
    /// the filter's shape normalised to integral 1, and the weights average 1.
    #[test]
    fn weighted_samples_follow_the_filter() {
        for filter in filters() {
            let t = FilterTable::new(&filter);
            let r = filter.radius();
            const N: usize = 200_000;
            const CELLS: usize = 16;
            for axis in 0..2 {
                // The other axis stays at u = 0.5: its weight is divided out.
                let other = t.sample_axis(1 - axis, 0.5).1 as f64;
                let mut hist = [0.0f64; CELLS];
                let mut weight_sum = 0.0f64;
                for i in 0..N {
                    let mut u = Vec2::splat(0.5);
                    u[axis] = (i as f32 + 0.5) / N as f32;
                    let (p, w) = t.sample(Vec2::ZERO, u);
                    let offset = p[axis] - 0.5;
                    assert!(offset.abs() <= r[axis] + 1e-4, "{filter:?}: {offset} outside the radius");
                    weight_sum += w as f64 / other;
                    let cell = ((offset / r[axis] + 1.0) / 2.0 * CELLS as f32) as usize;
                    hist[cell.min(CELLS - 1)] += w as f64 / other;
                }
                let mean = weight_sum / N as f64;
                assert!((mean - 1.0).abs() < 2e-3, "{filter:?} axis {axis}: weights average {mean}");
                // The filter's own share of each cell, by fine quadrature.
                let share = |c: usize| {
                    let a = (c as f32 / CELLS as f32 * 2.0 - 1.0) * r[axis];
                    let h = 2.0 * r[axis] / CELLS as f32;
                    (0..64).map(|k| filter.along(axis, a + (k as f32 + 0.5) / 64.0 * h)).sum::<f32>() * h
                        / 64.0
                };
                let total: f32 = (0..CELLS).map(share).sum();
                for (c, got) in hist.iter().enumerate() {
                    let got = got / N as f64;
                    let want = (share(c) / total) as f64;
                    assert!(
                        (got - want).abs() < 5e-3,
                        "{filter:?} axis {axis} cell {c}: {got} against {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn only_filters_with_negative_lobes_weight_samples_differently() {
        for filter in filters() {
            let t = FilterTable::new(&filter);
            let negative = matches!(filter, PixelFilter::Mitchell { .. } | PixelFilter::LanczosSinc { .. });
            assert_eq!(t.negative != [0, 0], negative, "{filter:?}");
            assert_eq!(t.weight.iter().any(|&w| w > 1.0), negative, "{filter:?}: {:?}", t.weight);
        }
    }
}
