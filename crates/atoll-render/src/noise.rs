//! pbrt-v4's solid noise and the textures made of it: Perlin's gradient
//! noise (his improved noise, with his permutation table, as pbrt uses it),
//! fractional Brownian motion, turbulence (`wrinkled`), `windy`, `marble`
//! and polka `dots`. The GPU port is `kernels/noise.cuh`, operation for
//! operation; its copy of [`PERMUTATION`] is generated from this one.
//!
//! atoll traces no ray differentials, so the sums take every octave a
//! texture asks for. pbrt-v4 stops where an octave is finer than a pixel
//! (replacing turbulence's dropped octaves by their mean, 0.2); a pixel's
//! many samples average those octaves out here instead.

use glam::{Vec2, Vec3};

/// Ken Perlin's permutation of 0..=255 (the table pbrt-v4 uses), which
/// picks each lattice point's gradient.
pub const PERMUTATION: [u8; 256] = [
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30, 69, 142, 8, 99,
    37, 240, 21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219, 203, 117, 35, 11, 32,
    57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175, 74, 165, 71, 134, 139, 48, 27,
    166, 77, 146, 158, 231, 83, 111, 229, 122, 60, 211, 133, 230, 220, 105, 92, 41, 55, 46, 245, 40, 244,
    102, 143, 54, 65, 25, 63, 161, 1, 216, 80, 73, 209, 76, 132, 187, 208, 89, 18, 169, 200, 196, 135, 130,
    116, 188, 159, 86, 164, 100, 109, 198, 173, 186, 3, 64, 52, 217, 226, 250, 124, 123, 5, 202, 38, 147,
    118, 126, 255, 82, 85, 212, 207, 206, 59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213, 119,
    248, 152, 2, 44, 154, 163, 70, 221, 153, 101, 155, 167, 43, 172, 9, 129, 22, 39, 253, 19, 98, 108, 110,
    79, 113, 224, 232, 178, 185, 112, 104, 218, 246, 97, 228, 251, 34, 242, 193, 238, 210, 144, 12, 191, 179,
    162, 241, 81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157, 184, 84, 204, 176,
    115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93, 222, 114, 67, 29, 24, 72, 243, 141, 128, 195, 78,
    66, 215, 61, 156, 180,
];

/// Most octaves a sum takes (more are summed as this many).
pub const MAX_OCTAVES: u32 = atoll_scene::Noise::MAX_OCTAVES;

/// The kinds of noise texture (`TexOp::a` of a noise op).
pub mod kind {
    /// `fbm`: the sum of `octaves` octaves of noise.
    pub const FBM: u32 = 0;
    /// `wrinkled`: turbulence, the sum of the octaves' absolute values.
    pub const WRINKLED: u32 = 1;
    /// `windy`: coarse fBm (wind strength) times finer fBm (wave height).
    pub const WINDY: u32 = 2;
    /// `marble`: a colour spline indexed by a sine perturbed by fBm.
    pub const MARBLE: u32 = 3;
}

/// The gradient of lattice point (x, y, z) (each in 0..=256) dotted with
/// the offset `d` from it.
fn gradient(x: i32, y: i32, z: i32, d: Vec3) -> f32 {
    let p = |i: i32| PERMUTATION[(i & 255) as usize] as i32;
    let h = p(p(p(x) + y) + z) & 15;
    let u = if h < 8 || h == 12 || h == 13 { d.x } else { d.y };
    let v = if h < 4 || h == 12 || h == 13 { d.y } else { d.z };
    (if h & 1 != 0 { -u } else { u }) + (if h & 2 != 0 { -v } else { v })
}

/// Perlin's quintic fade `6t^5 - 15t^4 + 10t^3`, in pbrt's order of operations.
fn fade(t: f32) -> f32 {
    let t3 = t * t * t;
    let t4 = t3 * t;
    let t5 = t4 * t;
    6.0 * t5 - 15.0 * t4 + 10.0 * t3
}

fn lerp(t: f32, a: f32, b: f32) -> f32 {
    (1.0 - t) * a + t * b
}

/// Gradient noise at `p`: 0 at every lattice point, within about ±1.
pub fn noise(p: Vec3) -> f32 {
    // Coordinates wrap at 2^30 so that the cell index fits an i32.
    let wrap = |v: f32| v % (1u32 << 30) as f32;
    let (x, y, z) = (wrap(p.x), wrap(p.y), wrap(p.z));
    let (fx, fy, fz) = (x.floor(), y.floor(), z.floor());
    let d = Vec3::new(x - fx, y - fy, z - fz);
    let (ix, iy, iz) = ((fx as i32) & 255, (fy as i32) & 255, (fz as i32) & 255);
    let w = |dx: i32, dy: i32, dz: i32| {
        let offset = Vec3::new(d.x - dx as f32, d.y - dy as f32, d.z - dz as f32);
        gradient(ix + dx, iy + dy, iz + dz, offset)
    };
    let (wx, wy, wz) = (fade(d.x), fade(d.y), fade(d.z));
    let x00 = lerp(wx, w(0, 0, 0), w(1, 0, 0));
    let x10 = lerp(wx, w(0, 1, 0), w(1, 1, 0));
    let x01 = lerp(wx, w(0, 0, 1), w(1, 0, 1));
    let x11 = lerp(wx, w(0, 1, 1), w(1, 1, 1));
    lerp(wz, lerp(wy, x00, x10), lerp(wy, x01, x11))
}

/// Noise in the plane z = 0.5 (pbrt's two-argument `Noise`).
fn noise2(x: f32, y: f32) -> f32 {
    noise(Vec3::new(x, y, 0.5))
}

/// How many octaves a noise sum keeps where the point moves by `len2`
/// (squared) from pixel to pixel: pbrt-v4's antialiasing, fewer octaves
/// the wider the footprint (all of them for none), the last in part.
fn octaves_for(len2: f32, octaves: u32) -> f32 {
    let len2 = if len2.is_nan() { 0.0 } else { len2 };
    (-1.0 - len2.log2() / 2.0).clamp(0.0, octaves.min(MAX_OCTAVES) as f32)
}

/// pbrt's `SmoothStep(x, 0.3, 0.7)`: how much of a partial octave is kept.
fn partial_weight(x: f32) -> f32 {
    let t = ((x - 0.3) / 0.4).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Fractional Brownian motion: `sum_i omega^i noise(1.99^i p)` over
/// `octaves`, as many as a footprint of `len2` (see [`octaves_for`]) keeps.
pub fn fbm(p: Vec3, len2: f32, omega: f32, octaves: u32) -> f32 {
    let n = octaves_for(len2, octaves);
    let whole = n.floor();
    let (mut sum, mut lambda, mut o) = (0.0, 1.0, 1.0);
    for _ in 0..whole as u32 {
        sum += o * noise(lambda * p);
        lambda *= 1.99;
        o *= omega;
    }
    // The partial octave, where there is one (its noise costs as much as
    // a whole one's).
    match partial_weight(n - whole) {
        0.0 => sum,
        w => sum + o * w * noise(lambda * p),
    }
}

/// Turbulence: fBm of the absolute noise, plus pbrt's allowance for the
/// octaves past the last kept (0.2 times each one's weight).
pub fn turbulence(p: Vec3, len2: f32, omega: f32, octaves: u32) -> f32 {
    let octaves = octaves.min(MAX_OCTAVES);
    let n = octaves_for(len2, octaves);
    let whole = n.floor();
    let (mut sum, mut lambda, mut o) = (0.0, 1.0, 1.0);
    for _ in 0..whole as u32 {
        sum += o * noise(lambda * p).abs();
        lambda *= 1.99;
        o *= omega;
    }
    sum += match partial_weight(n - whole) {
        0.0 => o * 0.2,
        w => o * ((1.0 - w) * 0.2 + w * noise(lambda * p).abs()),
    };
    for _ in whole as u32..octaves {
        sum += o * 0.2;
        o *= omega;
    }
    sum
}

/// pbrt's `windy`: `|fbm(p / 10, 0.5, 3)| * fbm(p, 0.5, 6)`.
pub fn windy(p: Vec3, len2: f32) -> f32 {
    fbm(0.1 * p, 0.01 * len2, 0.5, 3).abs() * fbm(p, len2, 0.5, 6)
}

/// The control points of pbrt's marble spline.
const MARBLE_COLORS: [[f32; 3]; 9] = [
    [0.58, 0.58, 0.6],
    [0.58, 0.58, 0.6],
    [0.58, 0.58, 0.6],
    [0.5, 0.5, 0.5],
    [0.6, 0.59, 0.58],
    [0.58, 0.58, 0.6],
    [0.58, 0.58, 0.6],
    [0.2, 0.2, 0.33],
    [0.58, 0.58, 0.6],
];

/// pbrt's `marble` at `p` (scaled by `scale`): the cubic Bézier segment of
/// [`MARBLE_COLORS`] picked by `0.5 + 0.5 sin(p.y + variation fbm(p))`, times 1.5.
pub fn marble(p: Vec3, len2: f32, omega: f32, octaves: u32, scale: f32, variation: f32) -> Vec3 {
    let p = p * scale;
    let m = p.y + variation * fbm(p, scale * scale * len2, omega, octaves);
    let t = 0.5 + 0.5 * m.sin();
    const SEGMENTS: usize = MARBLE_COLORS.len() - 3;
    let first = ((t * SEGMENTS as f32).floor().max(0.0) as usize).min(SEGMENTS - 1);
    let t = t * SEGMENTS as f32 - first as f32;
    let c = |i: usize| Vec3::from_array(MARBLE_COLORS[first + i]);
    // De Casteljau's evaluation of the segment's four points.
    let (a, b, d) = (c(0).lerp(c(1), t), c(1).lerp(c(2), t), c(2).lerp(c(3), t));
    let (a, b) = (a.lerp(b, t), b.lerp(d, t));
    1.5 * a.lerp(b, t)
}

/// Whether (s, t) lies in one of pbrt's polka dots: each unit cell around
/// an integer point has a dot where noise there is positive, of radius
/// 0.35, its centre shifted by noise.
pub fn inside_polka_dot(st: Vec2) -> bool {
    let (s_cell, t_cell) = ((st.x + 0.5).floor(), (st.y + 0.5).floor());
    if noise2(s_cell + 0.5, t_cell + 0.5) <= 0.0 {
        return false;
    }
    const RADIUS: f32 = 0.35;
    const MAX_SHIFT: f32 = 0.5 - RADIUS;
    let s_center = s_cell + MAX_SHIFT * noise2(s_cell + 1.5, t_cell + 2.8);
    let t_center = t_cell + MAX_SHIFT * noise2(s_cell + 4.5, t_cell + 9.8);
    (st - Vec2::new(s_center, t_center)).length_squared() < RADIUS * RADIUS
}

/// The value of noise texture `kind` at `p` (texture space), where `p`
/// moves by at most `sqrt(len2)` from pixel to pixel (0: unknown, all
/// octaves): `octaves`, `omega` (pbrt's `roughness`), and marble's `scale`
/// and `variation`.
pub fn evaluate(kind: u32, p: Vec3, len2: f32, octaves: u32, omega: f32, scale: f32, variation: f32) -> Vec3 {
    match kind {
        kind::FBM => Vec3::splat(fbm(p, len2, omega, octaves)),
        kind::WRINKLED => Vec3::splat(turbulence(p, len2, omega, octaves)),
        kind::WINDY => Vec3::splat(windy(p, len2)),
        _ => marble(p, len2, omega, octaves, scale, variation),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn points(n: usize) -> impl Iterator<Item = Vec3> {
        let mut state = 0x2545_f491_u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32
        };
        (0..n).map(move |_| Vec3::new(next(), next(), next()) * 40.0 - 20.0)
    }

    #[test]
    fn noise_vanishes_on_the_lattice_and_stays_bounded() {
        for p in points(2000) {
            assert_eq!(noise(p.floor()), 0.0, "{p}");
            let n = noise(p);
            assert!(n.abs() <= 1.05, "noise({p}) = {n}");
        }
        // Not constant: it has a spread of values off the lattice.
        let values: Vec<f32> = points(2000).map(noise).collect();
        let mean = values.iter().sum::<f32>() / values.len() as f32;
        let spread = values.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / values.len() as f32;
        assert!(mean.abs() < 0.03 && spread > 0.02, "mean {mean}, variance {spread}");
    }

    #[test]
    fn noise_is_continuous_and_periodic_over_256_cells() {
        for p in points(500) {
            let step = Vec3::splat(1e-3);
            assert!((noise(p) - noise(p + step)).abs() < 0.02, "{p}");
            let shifted = p + Vec3::new(256.0, -512.0, 768.0);
            assert!((noise(p) - noise(shifted)).abs() < 1e-3, "{p}");
        }
    }

    #[test]
    fn octave_sums_follow_their_definitions() {
        for p in points(200) {
            assert_eq!(fbm(p, 0.0, 0.5, 1), noise(p));
            let two = noise(p) + 0.3 * noise(1.99 * p);
            assert!((fbm(p, 0.0, 0.3, 2) - two).abs() < 1e-6);
            let wrinkled = noise(p).abs() + 0.5 * 0.2;
            assert!((turbulence(p, 0.0, 0.5, 1) - wrinkled).abs() < 1e-6);
            assert!(turbulence(p, 0.0, 0.5, 8) >= 0.0);
            assert_eq!(windy(p, 0.0), fbm(0.1 * p, 0.0, 0.5, 3).abs() * fbm(p, 0.0, 0.5, 6));
            // More octaves than the cap sum no further.
            assert_eq!(fbm(p, 0.0, 0.5, 1000), fbm(p, 0.0, 0.5, MAX_OCTAVES));
        }
    }

    /// A wide footprint keeps fewer octaves, as pbrt-v4's antialiased
    /// FBm does: `clamp(-1 - log2(len2) / 2, 0, octaves)` of them, the
    /// last faded in between 0.3 and 0.7 of it.
    #[test]
    fn wide_footprints_keep_fewer_octaves() {
        for p in points(100) {
            // len2 = 2^-8: 3 whole octaves and none in part.
            let three = fbm(p, 0.0, 0.5, 3);
            assert_eq!(fbm(p, 2f32.powi(-8), 0.5, 8), three + 0.0 * noise(1.99f32.powi(3) * p));
            // 3.5 octaves: half of the fourth (smoothstep(0.5) = 0.5).
            let half = three + 0.125 * 0.5 * noise(1.99f32.powi(3) * p);
            assert!((fbm(p, 2f32.powi(-9), 0.5, 8) - half).abs() < 1e-6);
            // Turbulence keeps 0.2 for each octave dropped.
            let t = turbulence(p, 2f32.powi(-8), 0.5, 5);
            let kept: f32 = (0..3).map(|i| 0.5f32.powi(i) * noise(1.99f32.powi(i) * p).abs()).sum();
            assert!((t - (kept + 0.2 * (0.125 + 0.125 + 0.0625))).abs() < 1e-5, "{t}");
            // A footprint wider than the noise keeps nothing of fBm.
            assert_eq!(fbm(p, 4.0, 0.5, 8), 0.0);
        }
    }

    #[test]
    fn marble_stays_within_its_palette() {
        let (lo, hi) = (1.5 * Vec3::new(0.2, 0.2, 0.33), 1.5 * Vec3::new(0.6, 0.59, 0.6));
        let mut dark = 0;
        for p in points(2000) {
            let c = marble(p, 0.0, 0.5, 8, 1.0, 0.2);
            assert!(c.cmpge(lo - 1e-5).all() && c.cmple(hi + 1e-5).all(), "{c}");
            dark += (c.x < 0.7) as usize;
        }
        // The dark vein (0.2, 0.2, 0.33) shows up, but on a minority of points.
        assert!((20..1000).contains(&dark), "{dark} dark points of 2000");
    }

    #[test]
    fn polka_dots_cover_about_a_fifth_of_the_plane() {
        // Dots of radius 0.35 in about half the cells: about 0.5 * pi * 0.35^2.
        let n = 200_000;
        let mut inside = 0;
        let mut state = 12345u32;
        for _ in 0..n {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let s = (state >> 8) as f32 / (1 << 24) as f32 * 50.0;
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let t = (state >> 8) as f32 / (1 << 24) as f32 * 50.0;
            inside += inside_polka_dot(Vec2::new(s, t)) as usize;
        }
        let share = inside as f32 / n as f32;
        assert!((0.12..0.28).contains(&share), "{share}");
        // A dot is a disc: its centre cell's point is inside when it is.
        assert!(!inside_polka_dot(Vec2::new(0.5, 0.5)) || inside_polka_dot(Vec2::new(0.49, 0.5)));
    }
}
