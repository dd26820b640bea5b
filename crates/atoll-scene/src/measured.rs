//! pbrt-v4's `measured` material data: the tabulated BRDFs of Dupuy and
//! Jakob (2018, "An Adaptive Parameterization for Efficient Material
//! Acquisition and Rendering"), read from their `.bsdf` tensor files
//! ([`crate::tensor`]), with the 2D warps (pbrt's `PiecewiseLinear2D`) that
//! evaluate, sample and invert them.
//!
//! A file holds, over the unit square of a microfacet normal or of a sample:
//! the normal distribution `ndf`, the projected area `sigma` (both of one
//! direction), and, for each tabulated incident direction (`phi_i`,
//! `theta_i`), the visible-normal distribution `vndf`, the `luminance` that
//! importance-samples it, and the reflectance `spectra` at the points a
//! uniform grid of samples maps to. atoll renders in RGB: the spectra become
//! three planes of linear sRGB when the file is read
//! ([`crate::pbrt::spectrum::reflectance_rgb_weights`]).
//!
//! The BSDF that reads these tables is `atoll_render::bsdf::measured`; the
//! GPU's is `kernels/measured.cuh`, over [`MeasuredBrdf::pack`]'s words.

use crate::tensor::{TensorFile, TensorType};

/// pbrt's `OneMinusEpsilon`: the largest f32 below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// A piecewise-bilinear density over the unit square, tabulated on `nx` ×
/// `ny` points per slice, a slice for each tabulated incident direction
/// (or one, for the tables of one direction: `ndf`, `sigma`). pbrt-v4's
/// `PiecewiseLinear2D`, with its conditioning parameters (the incident
/// direction) looked up once per BSDF query by [`IncidentLookup`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Warp2d {
    pub nx: u32,
    pub ny: u32,
    /// Planes per slice: 1, or 3 for the RGB reflectance (one per channel).
    pub planes: u32,
    /// `planes × ny × nx` values per slice, x fastest.
    pub data: Vec<f32>,
    /// `ny` per slice; empty for a table that is only evaluated.
    pub marginal_cdf: Vec<f32>,
    /// `ny × nx` per slice; empty for a table that is only evaluated.
    pub conditional_cdf: Vec<f32>,
    /// What [`Warp2d::evaluate`] multiplies the interpolated data by: the
    /// cells per unit area, `(nx − 1)(ny − 1)`, for a normalised density;
    /// 1 for a table of plain values.
    pub density_scale: f32,
}

/// Where tables conditioned on the incident direction are read: the four
/// slices around it (`phi` fastest) and the interpolation weights of `phi`
/// (`[0]`, `[1]`) and `theta` (`[2]`, `[3]`). pbrt-v4's `param_weight` and
/// `slice_offset`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IncidentLookup {
    pub slices: [u32; 4],
    pub weights: [f32; 4],
}

impl IncidentLookup {
    /// The lookup of a table with one slice.
    pub const SINGLE: IncidentLookup = IncidentLookup { slices: [0; 4], weights: [1.0, 0.0, 1.0, 0.0] };

    /// The value at element `i` of the slices of `slice_len` elements in
    /// `data`, interpolated: over `phi` first, then `theta`, as pbrt's
    /// recursive `lookup`.
    #[inline]
    pub fn lookup(&self, data: &[f32], i: u32, slice_len: u32) -> f32 {
        let v = |c: usize| data[(self.slices[c] * slice_len + i) as usize];
        let [p0, p1, t0, t1] = self.weights;
        let near = v(0) * p0 + v(1) * p1;
        let far = v(2) * p0 + v(3) * p1;
        near * t0 + far * t1
    }
}

/// pbrt's `FindInterval`: the largest `i` in `[0, size − 2]` with
/// `pred(i)` (`pred` true then false over the indices), else 0.
#[inline]
pub fn find_interval(size: u32, pred: impl Fn(u32) -> bool) -> u32 {
    let (mut first, mut len) = (1u32, size.saturating_sub(2));
    while len > 0 {
        let half = len >> 1;
        let middle = first + half;
        if pred(middle) {
            first = middle + 1;
            len -= half + 1;
        } else {
            len = half;
        }
    }
    first.saturating_sub(1).min(size.saturating_sub(2))
}

/// pbrt's `SafeSqrt`.
#[inline]
fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

impl Warp2d {
    /// A table of `slices` slices of `planes × ny × nx` values, from `data`.
    /// `sampled` builds the CDFs and normalises each slice to a density
    /// over the unit square (pbrt's `normalize` and `build_cdf`, which it
    /// always sets together); otherwise values are kept as they are.
    pub fn new(data: &[f32], nx: u32, ny: u32, planes: u32, sampled: bool) -> Warp2d {
        let (x, y) = (nx as usize, ny as usize);
        let n = x * y;
        let mut warp =
            Warp2d { nx, ny, planes, data: data.to_vec(), density_scale: 1.0, ..Default::default() };
        if !sampled {
            return warp;
        }
        assert_eq!(planes, 1, "a sampled table has one plane");
        warp.density_scale = ((nx - 1) * (ny - 1)) as f32;
        warp.marginal_cdf = vec![0.0; data.len() / x];
        warp.conditional_cdf = vec![0.0; data.len()];
        for ((values, conditional), marginal) in warp
            .data
            .chunks_exact_mut(n)
            .zip(warp.conditional_cdf.chunks_exact_mut(n))
            .zip(warp.marginal_cdf.chunks_exact_mut(y))
        {
            for (row, cdf) in values.chunks_exact(x).zip(conditional.chunks_exact_mut(x)) {
                let mut sum = 0.0f64;
                for i in 0..x - 1 {
                    sum += 0.5 * (row[i] as f64 + row[i + 1] as f64);
                    cdf[i + 1] = sum as f32;
                }
            }
            let mut sum = 0.0f64;
            for j in 0..y - 1 {
                sum += 0.5 * (conditional[(j + 1) * x - 1] as f64 + conditional[(j + 2) * x - 1] as f64);
                marginal[j + 1] = sum as f32;
            }
            let normalisation = 1.0 / marginal[y - 1];
            conditional.iter_mut().for_each(|v| *v *= normalisation);
            marginal.iter_mut().for_each(|v| *v *= normalisation);
            values.iter_mut().for_each(|v| *v *= normalisation);
        }
        warp
    }

    /// Elements of one slice of [`Warp2d::data`].
    fn slice_len(&self) -> u32 {
        self.planes * self.nx * self.ny
    }

    /// pbrt's `PiecewiseLinear2D::Evaluate`: the bilinearly interpolated
    /// value of plane `plane` at `pos` in the unit square.
    pub fn evaluate(&self, pos: glam::Vec2, at: &IncidentLookup, plane: u32) -> f32 {
        let (nx, ny) = (self.nx, self.ny);
        let pos = pos * glam::Vec2::new((nx - 1) as f32, (ny - 1) as f32);
        let (ix, iy) = ((pos.x as u32).min(nx - 2), (pos.y as u32).min(ny - 2));
        let (w1x, w1y) = (pos.x - ix as f32, pos.y - iy as f32);
        let (w0x, w0y) = (1.0 - w1x, 1.0 - w1y);
        let i = plane * nx * ny + ix + iy * nx;
        let len = self.slice_len();
        let v = |o: u32| at.lookup(&self.data, i + o, len);
        let (v00, v10, v01, v11) = (v(0), v(1), v(nx), v(nx + 1));
        (w0y * (w0x * v00 + w1x * v10) + w1y * (w0x * v01 + w1x * v11)) * self.density_scale
    }

    /// pbrt's `PiecewiseLinear2D::Sample`: the point of the unit square
    /// that the uniform `u` maps to, and the density there.
    pub fn sample(&self, u: glam::Vec2, at: &IncidentLookup) -> (glam::Vec2, f32) {
        let (nx, ny) = (self.nx, self.ny);
        let clamp = |v: f32| v.clamp(1.0 - ONE_MINUS_EPSILON, ONE_MINUS_EPSILON);
        let (mut ux, mut uy) = (clamp(u.x), clamp(u.y));
        let slice = nx * ny;

        // The row, from the marginal CDF.
        let marginal = |i: u32| at.lookup(&self.marginal_cdf, i, ny);
        let row = find_interval(ny, |i| marginal(i) < uy);
        uy -= marginal(row);
        let mut offset = row * nx;
        let r0 = at.lookup(&self.conditional_cdf, offset + nx - 1, slice);
        let r1 = at.lookup(&self.conditional_cdf, offset + 2 * nx - 1, slice);
        let is_const = (r0 - r1).abs() < 1e-4 * (r0 + r1);
        uy = if is_const { 2.0 * uy } else { r0 - safe_sqrt(r0 * r0 - 2.0 * uy * (r0 - r1)) };
        uy /= if is_const { r0 + r1 } else { r0 - r1 };

        // The column, from the conditional CDF between the two rows.
        ux *= (1.0 - uy) * r0 + uy * r1;
        let conditional = |i: u32| {
            let v0 = at.lookup(&self.conditional_cdf, offset + i, slice);
            let v1 = at.lookup(&self.conditional_cdf, offset + nx + i, slice);
            (1.0 - uy) * v0 + uy * v1
        };
        let col = find_interval(nx, |i| conditional(i) < ux);
        ux -= conditional(col);
        offset += col;

        let v = |o: u32| at.lookup(&self.data, offset + o, slice);
        let (v00, v10, v01, v11) = (v(0), v(1), v(nx), v(nx + 1));
        let c0 = (1.0 - uy) * v00 + uy * v01;
        let c1 = (1.0 - uy) * v10 + uy * v11;
        let is_const = (c0 - c1).abs() < 1e-4 * (c0 + c1);
        ux = if is_const { 2.0 * ux } else { c0 - safe_sqrt(c0 * c0 - 2.0 * ux * (c0 - c1)) };
        ux /= if is_const { c0 + c1 } else { c0 - c1 };

        let p = glam::Vec2::new((col as f32 + ux) / (nx - 1) as f32, (row as f32 + uy) / (ny - 1) as f32);
        (p, ((1.0 - ux) * c0 + ux * c1) * self.density_scale)
    }

    /// pbrt's `PiecewiseLinear2D::Invert`: the uniform sample that
    /// [`Warp2d::sample`] maps to `p`, and the density at `p`.
    pub fn invert(&self, p: glam::Vec2, at: &IncidentLookup) -> (glam::Vec2, f32) {
        let (nx, ny) = (self.nx, self.ny);
        let slice = nx * ny;
        let scaled = p * glam::Vec2::new((nx - 1) as f32, (ny - 1) as f32);
        let (ix, iy) = ((scaled.x as u32).min(nx - 2), (scaled.y as u32).min(ny - 2));
        let (mut sx, mut sy) = (scaled.x - ix as f32, scaled.y - iy as f32);
        let offset = ix + iy * nx;

        // The x component.
        let v = |o: u32| at.lookup(&self.data, offset + o, slice);
        let (v00, v10, v01, v11) = (v(0), v(1), v(nx), v(nx + 1));
        let (w1x, w1y) = (sx, sy);
        let (w0x, w0y) = (1.0 - w1x, 1.0 - w1y);
        let c0 = w0y * v00 + w1y * v01;
        let c1 = w0y * v10 + w1y * v11;
        let pdf = w0x * c0 + w1x * c1;
        sx *= c0 + 0.5 * sx * (c1 - c0);
        let v0 = at.lookup(&self.conditional_cdf, offset, slice);
        let v1 = at.lookup(&self.conditional_cdf, offset + nx, slice);
        sx += (1.0 - sy) * v0 + sy * v1;
        let row = iy * nx;
        let r0 = at.lookup(&self.conditional_cdf, row + nx - 1, slice);
        let r1 = at.lookup(&self.conditional_cdf, row + 2 * nx - 1, slice);
        sx /= (1.0 - sy) * r0 + sy * r1;

        // The y component.
        sy *= r0 + 0.5 * sy * (r1 - r0);
        sy += at.lookup(&self.marginal_cdf, iy, ny);
        (glam::Vec2::new(sx, sy), pdf * self.density_scale)
    }
}

/// A measured BRDF, ready to render: pbrt-v4's `MeasuredBxDFData` in RGB.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeasuredBrdf {
    /// The file as the scene named it (what `atoll gen` writes back).
    pub filename: String,
    /// Whether the tables hold one azimuth of incidence (`phi_i` has at
    /// most two entries): normals are then relative to the incident azimuth.
    pub isotropic: bool,
    /// The tabulated incident azimuths and elevations, in radians.
    pub phi_i: Vec<f32>,
    pub theta_i: Vec<f32>,
    /// Distribution of normals, over `u_wm`: plain values.
    pub ndf: Warp2d,
    /// Projected microfacet area, over `u_wo`: plain values.
    pub sigma: Warp2d,
    /// Distribution of visible normals per incident direction: sampled.
    pub vndf: Warp2d,
    /// Luminance of the reflectance over the sample square: sampled.
    pub luminance: Warp2d,
    /// Reflectance over the sample square, three planes of linear sRGB.
    pub rgb: Warp2d,
}

impl MeasuredBrdf {
    /// Reads a measured BRDF from the bytes of a `.bsdf` file (named
    /// `filename` in the scene), checking its structure as pbrt-v4 does.
    pub fn from_bytes(bytes: &[u8], filename: &str) -> Result<MeasuredBrdf, String> {
        let file = TensorFile::parse(bytes)?;
        let f32_field = |name: &str, ndim: usize| -> Result<(Vec<usize>, Vec<f32>), String> {
            let field = file.field(name)?;
            if field.shape.len() != ndim {
                return Err(format!("field \"{name}\" has {} dimensions, not {ndim}", field.shape.len()));
            }
            let values = field.f32s().ok_or_else(|| format!("field \"{name}\" is not float32"))?;
            if let Some(bad) = values.iter().find(|v| !v.is_finite()) {
                return Err(format!("field \"{name}\" holds {bad}"));
            }
            Ok((field.shape.clone(), values))
        };
        let (_, theta_i) = f32_field("theta_i", 1)?;
        let (_, phi_i) = f32_field("phi_i", 1)?;
        let (_, wavelengths) = f32_field("wavelengths", 1)?;
        let (ndf_shape, ndf) = f32_field("ndf", 2)?;
        let (sigma_shape, sigma) = f32_field("sigma", 2)?;
        let (vndf_shape, vndf) = f32_field("vndf", 4)?;
        let (lum_shape, luminance) = f32_field("luminance", 4)?;
        let (spectra_shape, spectra) = f32_field("spectra", 5)?;
        for (name, ty) in [("description", TensorType::UInt8), ("jacobian", TensorType::UInt8)] {
            if file.field(name)?.dtype != ty {
                return Err(format!("field \"{name}\" is not uint8"));
            }
        }
        let (n_phi, n_theta) = (phi_i.len(), theta_i.len());
        let structure = |ok: bool, what: &str| {
            if ok {
                Ok(())
            } else {
                Err(format!("invalid BRDF file structure: {what}"))
            }
        };
        structure(
            n_phi >= 1 && n_theta >= 1 && !wavelengths.is_empty(),
            "empty phi_i, theta_i or wavelengths",
        )?;
        structure(vndf_shape[..2] == [n_phi, n_theta], "vndf is not phi_i × theta_i × y × x")?;
        structure(lum_shape[..2] == [n_phi, n_theta], "luminance is not phi_i × theta_i × y × x")?;
        structure(lum_shape[2] == lum_shape[3], "luminance is not square")?;
        structure(
            spectra_shape[..3] == [n_phi, n_theta, wavelengths.len()],
            "spectra is not phi_i × theta_i × wavelengths × y × x",
        )?;
        structure(spectra_shape[3..] == lum_shape[2..], "spectra and luminance differ in size")?;
        structure(file.field("jacobian")?.shape == [1], "jacobian is not one value")?;
        for (name, shape) in [
            ("ndf", &ndf_shape[..]),
            ("sigma", &sigma_shape[..]),
            ("vndf", &vndf_shape[2..]),
            ("luminance", &lum_shape[2..]),
        ] {
            structure(
                shape.iter().all(|&s| (2..=1 << 16).contains(&s)),
                &format!("{name} needs 2 to 65536 points a side"),
            )?;
        }
        structure(
            theta_i.windows(2).all(|w| w[0] < w[1]) && phi_i.windows(2).all(|w| w[0] < w[1]),
            "phi_i or theta_i do not increase",
        )?;
        let non_negative = |v: &[f32]| v.iter().all(|&x| x >= 0.0);
        structure(non_negative(&vndf) && non_negative(&luminance), "negative vndf or luminance densities")?;
        let isotropic = n_phi <= 2;
        if !isotropic {
            let reduction = (2.0 * std::f32::consts::PI / (phi_i[n_phi - 1] - phi_i[0])).round();
            if reduction != 1.0 {
                return Err(format!("reduction {reduction} (!= 1) not supported"));
            }
        }

        // The spectra, one dot product per point, into RGB planes.
        let weights = crate::pbrt::spectrum::reflectance_rgb_weights(&wavelengths);
        let n = spectra_shape[3] * spectra_shape[4];
        let mut rgb = vec![0.0f32; n_phi * n_theta * 3 * n];
        for (slice, out) in spectra.chunks_exact(wavelengths.len() * n).zip(rgb.chunks_exact_mut(3 * n)) {
            for i in 0..n {
                let c: glam::Vec3 =
                    weights.iter().enumerate().map(|(k, w)| *w * slice[k * n + i].max(0.0)).sum();
                for (ch, v) in c.to_array().into_iter().enumerate() {
                    out[ch * n + i] = v;
                }
            }
        }
        let size = |s: &[usize]| (s[s.len() - 1] as u32, s[s.len() - 2] as u32);
        let warp = |data: &[f32], shape: &[usize], planes, sampled| {
            let (nx, ny) = size(shape);
            Warp2d::new(data, nx, ny, planes, sampled)
        };
        let brdf = MeasuredBrdf {
            filename: filename.to_string(),
            isotropic,
            phi_i,
            theta_i,
            ndf: warp(&ndf, &ndf_shape, 1, false),
            sigma: warp(&sigma, &sigma_shape, 1, false),
            vndf: warp(&vndf, &vndf_shape, 1, true),
            luminance: warp(&luminance, &lum_shape, 1, true),
            rgb: warp(&rgb, &spectra_shape, 3, false),
        };
        let degenerate = |w: &Warp2d| w.marginal_cdf.iter().any(|v| !v.is_finite());
        structure(
            !degenerate(&brdf.vndf) && !degenerate(&brdf.luminance),
            "a vndf or luminance slice is all zero",
        )?;
        Ok(brdf)
    }

    /// The slices and weights of the incident direction at azimuth `phi`
    /// and elevation `theta` (pbrt's parameter lookup of `phi_i`, `theta_i`).
    pub fn incident(&self, phi: f32, theta: f32) -> IncidentLookup {
        let axis = |values: &[f32], x: f32| -> (u32, u32, f32, f32) {
            let n = values.len() as u32;
            if n == 1 {
                return (0, 0, 1.0, 0.0);
            }
            let i = find_interval(n, |k| values[k as usize] <= x);
            let (p0, p1) = (values[i as usize], values[i as usize + 1]);
            let w1 = ((x - p0) / (p1 - p0)).clamp(0.0, 1.0);
            (i, i + 1, 1.0 - w1, w1)
        };
        let (p0, p1, wp0, wp1) = axis(&self.phi_i, phi);
        let (t0, t1, wt0, wt1) = axis(&self.theta_i, theta);
        let n_theta = self.theta_i.len() as u32;
        let slice = |p: u32, t: u32| p * n_theta + t;
        IncidentLookup {
            slices: [slice(p0, t0), slice(p1, t0), slice(p0, t1), slice(p1, t1)],
            weights: [wp0, wp1, wt0, wt1],
        }
    }

    /// Bytes of the tables.
    pub fn bytes(&self) -> u64 {
        let warps = [&self.ndf, &self.sigma, &self.vndf, &self.luminance, &self.rgb];
        let floats: usize =
            warps.iter().map(|w| w.data.len() + w.marginal_cdf.len() + w.conditional_cdf.len()).sum();
        4 * (floats + self.phi_i.len() + self.theta_i.len()) as u64
    }

    /// The tables as one run of 32-bit words for the GPU
    /// (`kernels/measured.cuh`): a header of [`PACK_HEADER_WORDS`] —
    /// isotropic, `phi_i` count, `theta_i` count, their offsets, then per
    /// table (ndf, sigma, vndf, luminance, rgb) `nx`, `ny`, and the offsets
    /// of its data, marginal and conditional CDFs — then the arrays. Offsets
    /// count words from the header's start; integers are stored as their
    /// bits.
    pub fn pack(&self) -> Vec<f32> {
        let warps = [&self.ndf, &self.sigma, &self.vndf, &self.luminance, &self.rgb];
        let mut header: Vec<u32> =
            vec![self.isotropic as u32, self.phi_i.len() as u32, self.theta_i.len() as u32];
        let mut body: Vec<f32> = Vec::new();
        let mut place = |values: &[f32]| {
            let at = PACK_HEADER_WORDS as u32 + body.len() as u32;
            body.extend_from_slice(values);
            at
        };
        header.push(place(&self.phi_i));
        header.push(place(&self.theta_i));
        for w in warps {
            header.extend([w.nx, w.ny, place(&w.data), place(&w.marginal_cdf), place(&w.conditional_cdf)]);
        }
        assert_eq!(header.len(), PACK_HEADER_WORDS);
        header.into_iter().map(f32::from_bits).chain(body).collect()
    }
}

/// Words of [`MeasuredBrdf::pack`]'s header.
pub const PACK_HEADER_WORDS: usize = 5 + 5 * 5;

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    #[test]
    fn find_interval_brackets() {
        let v = [0.0f32, 1.0, 2.0, 4.0];
        let at = |x: f32| find_interval(4, |i| v[i as usize] <= x);
        assert_eq!([at(-1.0), at(0.5), at(1.0), at(3.0), at(9.0)], [0, 0, 1, 2, 2]);
    }

    /// A density conditioned on two parameters, of two and three values:
    /// sampling then inverting gives the sample back, the density sampling
    /// reports is the one evaluation gives, and each slice integrates to 1.
    #[test]
    fn warps_sample_invert_and_evaluate_alike() {
        let (nx, ny) = (5u32, 4u32);
        let slices = 2 * 3;
        let data: Vec<f32> = (0..slices * nx * ny)
            .map(|i| {
                let (s, x, y) = (i / (nx * ny), i % nx, (i / nx) % ny);
                0.2 + (x as f32 * 0.7 + y as f32 * 0.3 + s as f32).sin().abs()
            })
            .collect();
        let warp = Warp2d::new(&data, nx, ny, 1, true);
        let brdf = MeasuredBrdf { phi_i: vec![0.0, 1.0], theta_i: vec![0.0, 0.5, 1.0], ..Default::default() };
        for (phi, theta) in [(0.0, 0.0), (0.3, 0.7), (1.0, 0.25)] {
            let at = brdf.incident(phi, theta);
            let mut mass = 0.0;
            let steps = 200;
            for i in 0..steps {
                for j in 0..steps {
                    let p = Vec2::new((i as f32 + 0.5) / steps as f32, (j as f32 + 0.5) / steps as f32);
                    mass += warp.evaluate(p, &at, 0) / (steps * steps) as f32;
                }
            }
            assert!((mass - 1.0).abs() < 1e-3, "slice ({phi}, {theta}) integrates to {mass}");
            for u in
                [Vec2::new(0.1, 0.2), Vec2::new(0.5, 0.5), Vec2::new(0.93, 0.07), Vec2::new(0.999, 0.999)]
            {
                let (p, pdf) = warp.sample(u, &at);
                let (back, pdf_back) = warp.invert(p, &at);
                assert!((back - u).abs().max_element() < 1e-4, "{u} → {p} → {back}");
                assert!((pdf - pdf_back).abs() < 1e-4 * pdf, "{pdf} vs {pdf_back}");
                assert!((pdf - warp.evaluate(p, &at, 0)).abs() < 1e-4 * pdf);
            }
        }
    }

    /// A file whose densities are negative, whose fields have the wrong
    /// type or whose tables disagree in size, or that lacks a field, is
    /// refused with what is wrong.
    #[test]
    fn malformed_files_are_refused() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/measured-ggx.bsdf");
        let bytes = std::fs::read(path).unwrap();
        assert!(MeasuredBrdf::from_bytes(&bytes, "ggx.bsdf").is_ok());
        let file = TensorFile::parse(&bytes).unwrap();
        let read = |f: &TensorFile| {
            let fields: Vec<_> =
                f.fields.iter().map(|(n, v)| (n.as_str(), v.dtype, &v.shape[..], &v.bytes[..])).collect();
            MeasuredBrdf::from_bytes(&TensorFile::write(&fields), "ggx.bsdf").unwrap_err()
        };
        let edited = |name: &str, edit: &dyn Fn(&mut crate::tensor::TensorField)| {
            let mut f = file.clone();
            edit(f.fields.get_mut(name).unwrap());
            read(&f)
        };
        let negative = edited("vndf", &|v| v.bytes[..4].copy_from_slice(&(-1.0f32).to_le_bytes()));
        assert!(negative.contains("negative"), "{negative}");
        let wrong_type = edited("theta_i", &|v| v.dtype = TensorType::Int32);
        assert!(wrong_type.contains("\"theta_i\" is not float32"), "{wrong_type}");
        let smaller = edited("luminance", &|v| {
            v.shape[3] -= 1;
            v.bytes.truncate(v.shape.iter().product::<usize>() * 4);
        });
        assert!(smaller.contains("invalid BRDF file structure"), "{smaller}");
        let mut without = file.clone();
        without.fields.remove("spectra");
        assert!(read(&without).contains("no \"spectra\" field"));
    }

    /// A constant reflectance spectrum is that grey exactly, and a spectrum
    /// rising towards red is reddest.
    #[test]
    fn reflectance_spectra_become_rgb() {
        let wavelengths = [380.0, 450.0, 520.0, 600.0, 700.0, 780.0];
        let weights = crate::pbrt::spectrum::reflectance_rgb_weights(&wavelengths);
        let rgb = |v: &[f32]| -> glam::Vec3 { weights.iter().zip(v).map(|(w, v)| *w * *v).sum() };
        assert!((rgb(&[0.4; 6]) - glam::Vec3::splat(0.4)).abs().max_element() < 1e-6);
        let red = rgb(&[0.1, 0.1, 0.2, 0.6, 0.9, 0.9]);
        assert!(red.x > red.y && red.y > red.z, "{red}");
    }
}
