//! Deterministic random numbers from (seed, pixel, sample, dimension).
//!
//! No generator state lives in threads or devices: every random number is a
//! hash of where it is used, so any device, thread count or partition
//! produces the same image. The hash is PCG's output permutation
//! (Jarzynski & Olano 2020, "Hash Functions for GPU Rendering"), chained;
//! the CUDA kernels implement the same integer arithmetic.

/// Dimensions used by camera ray generation (pixel jitter x/y, lens u/v).
pub const CAMERA_DIMENSIONS: u32 = 4;
/// Dimensions reserved per bounce; see [`BounceDim`].
pub const DIMENSIONS_PER_BOUNCE: u32 = 8;

/// Offsets of each random decision within a bounce's block of dimensions.
#[derive(Clone, Copy, Debug)]
#[repr(u32)]
pub enum BounceDim {
    LightSelect = 0,
    LightPosition = 1, // and 2
    BsdfLobe = 3,
    BsdfDirection = 4, // and 5
    RussianRoulette = 6,
    /// Which material of a `mix` the hit takes (written with the hit).
    MaterialChoice = 7,
}

/// Where the media's dimensions start (hashed with the segment's origin):
/// apart from every bounce's, so that media leave every other decision's
/// numbers as they were.
pub const MEDIUM_DIMENSIONS: u32 = 1 << 24;

/// Where the dimensions of decisions inside a subsurface medium start
/// (hashed with where they are made): a walk there takes many steps within
/// one path vertex, so its numbers cannot come from the vertex's block.
pub const WALK_DIMENSIONS: u32 = 1 << 25;

/// The dimension of a path's time within the shutter (motion blur): one
/// below the media's, apart from every bounce's.
pub const TIME_DIMENSION: u32 = MEDIUM_DIMENSIONS - 1;

/// One round of the PCG hash.
#[inline]
pub fn pcg_hash(x: u32) -> u32 {
    let state = x.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28).wrapping_add(4))) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// `start` hashed with a path segment's origin and throughput: what tells
/// apart the segments of one path vertex. Both are what shading is given,
/// so every device has their bits (where a segment ends is computed, and
/// may round differently). The throughput matters where a walk scatters
/// again so close to where it was that the origin rounds to the same
/// point: every step changes the throughput (by its weight and its
/// roulette's), so the walk still draws new numbers.
#[inline]
pub fn segment_key(start: u32, origin: [f32; 3], beta: [f32; 3]) -> u32 {
    origin.iter().chain(&beta).fold(start, |h, c| pcg_hash(h ^ c.to_bits()))
}

/// Where a path's random numbers come from.
#[derive(Clone, Copy, Debug)]
pub struct SampleStream {
    key: u32,
}

impl SampleStream {
    pub fn new(seed: u32, pixel: u32, sample: u32) -> Self {
        SampleStream { key: pcg_hash(sample ^ pcg_hash(pixel ^ pcg_hash(seed))) }
    }

    /// Uniform float in [0, 1) for `dimension`.
    #[inline]
    pub fn get(&self, dimension: u32) -> f32 {
        let h = pcg_hash(self.key ^ pcg_hash(dimension.wrapping_add(0x9e37_79b9)));
        // 24 random bits: exactly representable, never rounds up to 1.0.
        (h >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Uniform float for decision `dim` of bounce `depth`.
    #[inline]
    pub fn bounce(&self, depth: u32, dim: BounceDim, offset: u32) -> f32 {
        self.get(CAMERA_DIMENSIONS + depth * DIMENSIONS_PER_BOUNCE + dim as u32 + offset)
    }

    /// Uniform float for where a segment leaving vertex `depth` from
    /// `origin` with throughput `beta` scatters in a medium. The segment is
    /// hashed in because several segments may leave one vertex (crossing
    /// boundaries of media is no vertex, nor is a step of a subsurface
    /// walk): each needs a number of its own ([`segment_key`]).
    #[inline]
    pub fn medium_distance(&self, depth: u32, origin: [f32; 3], beta: [f32; 3]) -> f32 {
        self.get(segment_key(MEDIUM_DIMENSIONS + depth, origin, beta))
    }

    /// Uniform float for decision `dim` where a segment of a walk through
    /// a subsurface medium ends (a step, or the walk's exit) within path
    /// vertex `depth`; the segment leaves `origin` with throughput `beta`
    /// ([`segment_key`]). Each segment ends in one step or one exit.
    #[inline]
    pub fn walk(&self, depth: u32, origin: [f32; 3], beta: [f32; 3], dim: BounceDim, offset: u32) -> f32 {
        let start = WALK_DIMENSIONS + depth * DIMENSIONS_PER_BOUNCE + dim as u32 + offset;
        self.get(segment_key(start, origin, beta))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_mean_and_range() {
        let mut sum = 0.0f64;
        let n = 100_000;
        for i in 0..n {
            let s = SampleStream::new(7, i, i / 3);
            let x = s.get(i % 17);
            assert!((0.0..1.0).contains(&x));
            sum += x as f64;
        }
        let mean = sum / n as f64;
        assert!((mean - 0.5).abs() < 0.005, "mean {mean}");
    }

    #[test]
    fn dimensions_are_decorrelated() {
        // Correlation between consecutive dimensions should be ~0.
        let n = 50_000;
        let (mut sxy, mut sx, mut sy, mut sxx, mut syy) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
        for i in 0..n {
            let s = SampleStream::new(1, i, 0);
            let (x, y) = (s.get(0) as f64, s.get(1) as f64);
            sxy += x * y;
            sx += x;
            sy += y;
            sxx += x * x;
            syy += y * y;
        }
        let n = n as f64;
        let cov = sxy / n - sx / n * sy / n;
        let corr = cov / ((sxx / n - (sx / n).powi(2)) * (syy / n - (sy / n).powi(2))).sqrt();
        assert!(corr.abs() < 0.02, "correlation {corr}");
    }
}
