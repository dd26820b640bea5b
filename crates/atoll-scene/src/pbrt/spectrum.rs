//! The spectral values a PBRT file can name, reduced to what atoll renders
//! with: linear sRGB triples and (for dielectrics) one index of refraction.
//! pbrt-v4 renders spectrally; these are the RGB approximations we use instead.

use glam::Vec3;

/// Copper's index of refraction (`metal-Cu-eta`), pbrt-v4's default conductor.
pub const CU_ETA: Vec3 = Vec3::new(0.200438, 0.924033, 1.10221);
/// Copper's absorption coefficient (`metal-Cu-k`).
pub const CU_K: Vec3 = Vec3::new(3.91295, 2.45285, 2.14219);

/// RGB approximations of pbrt-v4's named metal spectra (`metal-Cu-eta`, ...).
pub fn named_metal(name: &str) -> Option<Vec3> {
    Some(match name {
        "metal-Cu-eta" => CU_ETA,
        "metal-Cu-k" => CU_K,
        "metal-Au-eta" => Vec3::new(0.143119, 0.374957, 1.44248),
        "metal-Au-k" => Vec3::new(3.98316, 2.38572, 1.60322),
        "metal-Ag-eta" => Vec3::new(0.155265, 0.116723, 0.138342),
        "metal-Ag-k" => Vec3::new(4.82835, 3.12225, 2.14696),
        "metal-Al-eta" => Vec3::new(1.65746, 0.880369, 0.521229),
        "metal-Al-k" => Vec3::new(9.22387, 6.26952, 4.837),
        _ => return None,
    })
}

/// Index of refraction at the d line (587.6 nm) of pbrt-v4's named glasses
/// (`glass-F5`, `-F10`, `-F11` are Schott SF5, SF10, SF11 there).
pub fn named_glass(name: &str) -> Option<f32> {
    Some(match name {
        "glass-BK7" => 1.5168,
        "glass-BAF10" => 1.6700,
        "glass-FK51A" => 1.4866,
        "glass-LASF9" => 1.8503,
        "glass-F5" => 1.6727,
        "glass-F10" => 1.7283,
        "glass-F11" => 1.7847,
        _ => return None,
    })
}

/// Named illuminants: pbrt normalises light spectra to unit luminance, and
/// D65 is the white point of sRGB, so it becomes RGB white; A is a
/// blackbody at 2856 K, D50 and ACES's D60 daylight at 5003 K and 6000 K;
/// `stdillum-F1` to `-F12` the CIE fluorescent tables.
pub fn named_illuminant(name: &str) -> Option<Vec3> {
    match name {
        "stdillum-D65" => Some(Vec3::ONE),
        "stdillum-A" => Some(blackbody_rgb(2856.0)),
        "stdillum-D50" => Some(crate::camera::daylight_rgb(5003.0)),
        "illum-acesD60" => Some(crate::camera::daylight_rgb(6000.0)),
        _ => {
            let n: usize = name.strip_prefix("stdillum-F")?.parse().ok()?;
            let table = super::fluorescent::FLUORESCENT.get(n.checked_sub(1)?)?;
            Some(emission_rgb(|l| tabulated(table, l)))
        }
    }
}

/// A fluorescent table's value at `nm`, linear between its samples and
/// zero outside them (pbrt's piecewise-linear spectra).
fn tabulated(table: &[f32], nm: f64) -> f64 {
    use super::fluorescent::{FIRST_NM, STEP_NM};
    let x = (nm - FIRST_NM) / STEP_NM;
    let i = x.floor();
    if i < 0.0 || i as usize + 1 >= table.len() {
        return if x == (table.len() - 1) as f64 { table[table.len() - 1] as f64 } else { 0.0 };
    }
    let (a, b) = (table[i as usize] as f64, table[i as usize + 1] as f64);
    a + (x - i) * (b - a)
}

/// Whether `name` is a spectrum this module knows by name.
pub fn is_named(name: &str) -> bool {
    named_metal(name).is_some() || named_glass(name).is_some() || named_illuminant(name).is_some()
}

/// Whether a spectrum parameter's string names a file rather than one of
/// pbrt-v4's named spectra: pbrt reads any name it does not know as a
/// file, but atoll knows fewer names than pbrt, so only a string that
/// looks like a path (pbrt's names have neither dots nor slashes) is read
/// as one; other unknown names fall back to a default with a warning.
pub fn names_a_file(name: &str) -> bool {
    !is_named(name) && name.contains(['.', '/', '\\'])
}

/// The numbers of a pbrt spectrum file (`.spd`): (wavelength in nm, value)
/// pairs separated by white space, `#` starting a comment to the end of
/// the line, wavelengths increasing (pbrt-v4's `PiecewiseLinearSpectrum::Read`).
pub fn parse_spd(text: &str) -> Result<Vec<f64>, String> {
    let mut numbers = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let data = line.split('#').next().unwrap_or("");
        for word in data.split_whitespace() {
            let x: f64 = word.parse().map_err(|_| format!("line {}: \"{word}\" is not a number", i + 1))?;
            if !x.is_finite() {
                return Err(format!("line {}: {word} is not finite", i + 1));
            }
            numbers.push(x);
        }
    }
    if numbers.is_empty() {
        return Err("no (wavelength, value) pairs".into());
    }
    if numbers.len() % 2 != 0 {
        return Err(format!("{} numbers: not (wavelength, value) pairs", numbers.len()));
    }
    if let Some(w) =
        numbers.chunks_exact(2).map(|c| c[0]).collect::<Vec<_>>().windows(2).find(|w| w[1] <= w[0])
    {
        return Err(format!("wavelengths do not increase ({} then {})", w[0], w[1]));
    }
    Ok(numbers)
}

/// Value of a piecewise-linear spectrum at `lambda` (clamped at the ends).
pub fn sampled_at(pairs: &[(f32, f32)], lambda: f32) -> f32 {
    match pairs {
        [] => 0.0,
        [(_, v)] => *v,
        _ => {
            let i = pairs.partition_point(|&(l, _)| l < lambda);
            if i == 0 {
                return pairs[0].1;
            }
            if i == pairs.len() {
                return pairs[pairs.len() - 1].1;
            }
            let ((l0, v0), (l1, v1)) = (pairs[i - 1], pairs[i]);
            let t = if l1 > l0 { (lambda - l0) / (l1 - l0) } else { 0.0 };
            v0 + t * (v1 - v0)
        }
    }
}

/// A crude RGB for a sampled reflectance-like spectrum: its averages over the
/// blue (400–500 nm), green (500–600 nm) and red (600–700 nm) bands. Exact
/// for constant spectra, which is what scenes mostly give this way.
pub fn sampled_rgb(pairs: &[(f32, f32)]) -> Vec3 {
    let band = |lo: f32| (0..10).map(|i| sampled_at(pairs, lo + 5.0 + 10.0 * i as f32)).sum::<f32>() / 10.0;
    Vec3::new(band(600.0), band(500.0), band(400.0))
}

/// The linear-sRGB colour of a reflectance spectrum sampled at
/// `wavelengths` (nm, increasing; piecewise linear between them and constant
/// past the ends, as pbrt reads tabulated spectra), as weights: the colour of
/// values `v` is `Σ weights[k] · v[k]`. The spectrum's XYZ under an
/// equal-energy light becomes sRGB divided channel by channel by the sRGB of
/// a perfect reflector's, so that a constant spectrum `c` is exactly `(c, c,
/// c)` (white stays white, as it does in pbrt-v4's RGB film). Tables of
/// many spectra on one set of wavelengths (measured BRDFs) convert with one
/// dot product each.
pub fn reflectance_rgb_weights(wavelengths: &[f32]) -> Vec<Vec3> {
    let n = wavelengths.len();
    let to_rgb = |[x, y, z]: [f64; 3]| {
        glam::DVec3::new(
            3.2404542 * x - 1.5371385 * y - 0.4985314 * z,
            -0.9692660 * x + 1.8760108 * y + 0.0415560 * z,
            0.0556434 * x - 0.2040259 * y + 1.0572252 * z,
        )
    };
    // The spectrum that is 1 at sample `k` and 0 at the others.
    let hat = |k: usize| {
        let pairs: Vec<(f32, f32)> =
            wavelengths.iter().enumerate().map(|(i, &l)| (l, if i == k { 1.0 } else { 0.0 })).collect();
        move |l: f64| sampled_at(&pairs, l as f32) as f64
    };
    let rgb: Vec<glam::DVec3> = (0..n).map(|k| to_rgb(emission_xyz(hat(k)))).collect();
    let white: glam::DVec3 = rgb.iter().sum();
    rgb.iter().map(|c| (*c / white).as_vec3()).collect()
}

/// Planck's law at `nm` nanometres and `kelvin`, up to a constant factor.
fn planck(nm: f64, kelvin: f64) -> f64 {
    let lm = nm * 1e-9;
    1.0 / (lm.powi(5) * ((0.014387769 / (lm * kelvin)).exp() - 1.0))
}

/// Linear-sRGB colour of a blackbody at `kelvin`, normalised to luminance 1
/// (pbrt-v4 divides light spectra by their luminance, so only the colour of a
/// blackbody matters; `scale` sets the brightness).
pub fn blackbody_rgb(kelvin: f32) -> Vec3 {
    if kelvin <= 0.0 {
        return Vec3::ZERO;
    }
    let t = kelvin as f64;
    emission_rgb(|l| planck(l, t))
}

/// Linear-sRGB radiance of pbrt-v4's `BlackbodySpectrum` at `kelvin`: the
/// spectrum scaled to 1 at its peak, not normalised to a luminance (what
/// a grid medium's `temperature` emits). Its luminance is
/// ∫ B ȳ dλ / ∫ ȳ dλ, as pbrt's sensor counts it.
pub fn blackbody_peak_normalised_rgb(kelvin: f32) -> Vec3 {
    if kelvin <= 0.0 {
        return Vec3::ZERO;
    }
    let t = kelvin as f64;
    // Wien's displacement law: where the spectrum peaks.
    let peak = planck(2.8977721e6 / t, t);
    static Y_OF_ONE: std::sync::OnceLock<f64> = std::sync::OnceLock::new();
    let y_of_one = *Y_OF_ONE.get_or_init(|| emission_xyz(|_| 1.0)[1]);
    let xyz = emission_xyz(|l| planck(l, t));
    xyz_to_unit_luminance_rgb(xyz) * (xyz[1] / peak / y_of_one) as f32
}

/// A blackbody's [`blackbody_peak_normalised_rgb`] by table: grids of
/// temperature samples convert millions of values, each an integral over
/// the spectrum otherwise.
pub struct BlackbodyTable {
    rgb: Vec<Vec3>,
}

impl BlackbodyTable {
    /// The table's span: below it pbrt's grid emits nothing; above it
    /// the colour is computed directly.
    const LOWEST: f32 = 100.0;
    const HIGHEST: f32 = 1e5;
    const ENTRIES: usize = 4096;

    /// The table, built once per process (4096 spectral integrals).
    pub fn shared() -> &'static BlackbodyTable {
        static TABLE: std::sync::OnceLock<BlackbodyTable> = std::sync::OnceLock::new();
        TABLE.get_or_init(BlackbodyTable::new)
    }

    pub fn new() -> Self {
        let rgb =
            (0..Self::ENTRIES).map(|i| blackbody_peak_normalised_rgb(Self::kelvin_at(i as f32))).collect();
        BlackbodyTable { rgb }
    }

    /// The temperature of entry `i` (or between entries): evenly spaced in
    /// log temperature, where the colour varies smoothly.
    fn kelvin_at(i: f32) -> f32 {
        let span = (Self::HIGHEST / Self::LOWEST).ln();
        Self::LOWEST * (span * i / (Self::ENTRIES - 1) as f32).exp()
    }

    /// The radiance at `kelvin` (linear between entries).
    pub fn rgb(&self, kelvin: f32) -> Vec3 {
        // Also NaN: no light.
        if kelvin.is_nan() || kelvin < Self::LOWEST {
            return Vec3::ZERO;
        }
        if kelvin >= Self::HIGHEST {
            return blackbody_peak_normalised_rgb(kelvin);
        }
        let span = (Self::HIGHEST / Self::LOWEST).ln();
        let x = (kelvin / Self::LOWEST).ln() / span * (Self::ENTRIES - 1) as f32;
        let i = (x as usize).min(Self::ENTRIES - 2);
        let f = x - i as f32;
        self.rgb[i] * (1.0 - f) + self.rgb[i + 1] * f
    }
}

impl Default for BlackbodyTable {
    fn default() -> Self {
        Self::new()
    }
}

/// CIE 1931 XYZ sums of the emission spectrum `spd` (of the wavelength in
/// nm): integrated at 1 nm steps against the analytic fit of Wyman, Sloan
/// and Shirley (2013) from 360 to 830 nm.
fn emission_xyz(spd: impl Fn(f64) -> f64) -> [f64; 3] {
    let g = |x: f64, mu: f64, s1: f64, s2: f64| {
        let s = if x < mu { s1 } else { s2 };
        (-(x - mu) * (x - mu) / (2.0 * s * s)).exp()
    };
    let (mut x, mut y, mut z) = (0.0, 0.0, 0.0);
    for i in 0..=470 {
        let l = 360.0 + i as f64;
        let b = spd(l);
        x += b
            * (1.056 * g(l, 599.8, 37.9, 31.0) + 0.362 * g(l, 442.0, 16.0, 26.7)
                - 0.065 * g(l, 501.1, 20.4, 26.2));
        y += b * (0.821 * g(l, 568.8, 46.9, 40.5) + 0.286 * g(l, 530.9, 16.3, 31.1));
        z += b * (1.217 * g(l, 437.0, 11.8, 36.0) + 0.681 * g(l, 459.0, 26.0, 13.8));
    }
    [x, y, z]
}

/// Linear-sRGB colour of the emission spectrum `spd` (of the wavelength in
/// nm), normalised to luminance 1 ([`emission_xyz`]'s integrals).
fn emission_rgb(spd: impl Fn(f64) -> f64) -> Vec3 {
    xyz_to_unit_luminance_rgb(emission_xyz(spd))
}

/// Linear sRGB of the colour of XYZ sums, normalised to luminance 1
/// (negative channels clipped).
fn xyz_to_unit_luminance_rgb([x, y, z]: [f64; 3]) -> Vec3 {
    if y <= 0.0 || !y.is_finite() {
        return Vec3::ZERO;
    }
    let (x, z) = (x / y, z / y);
    let rgb = Vec3::new(
        (3.2404542 * x - 1.5371385 - 0.4985314 * z) as f32,
        (-0.9692660 * x + 1.8760108 + 0.0415560 * z) as f32,
        (0.0556434 * x - 0.2040259 + 1.0572252 * z) as f32,
    );
    rgb.max(Vec3::ZERO)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampled_spectra() {
        let s = [(400.0, 1.0), (500.0, 2.0), (700.0, 4.0)];
        assert_eq!(sampled_at(&s, 300.0), 1.0);
        assert_eq!(sampled_at(&s, 450.0), 1.5);
        assert_eq!(sampled_at(&s, 600.0), 3.0);
        assert_eq!(sampled_at(&s, 800.0), 4.0);
        assert!((sampled_rgb(&[(300.0, 0.5), (800.0, 0.5)]) - Vec3::splat(0.5)).abs().max_element() < 1e-6);
    }

    /// pbrt's peak-normalised blackbody: the colour of the luminance-1
    /// blackbody, with the luminance of a spectrum that is 1 at its peak
    /// (checked against a plain sum of Planck's law times ȳ where no colour
    /// channel is clipped at 0, and against the table).
    #[test]
    fn peak_normalised_blackbodies() {
        let luminance = |c: Vec3| c.dot(Vec3::new(0.2126, 0.7152, 0.0722));
        // Wyman, Sloan and Shirley's two-lobe fit of ȳ.
        let lobe = |l: f64, mu: f64, s1: f64, s2: f64| {
            (-0.5 * ((l - mu) / if l < mu { s1 } else { s2 }).powi(2)).exp()
        };
        let y_bar = |l: f64| 0.821 * lobe(l, 568.8, 46.9, 40.5) + 0.286 * lobe(l, 530.9, 16.3, 31.1);
        let table = BlackbodyTable::new();
        for kelvin in [2000.0f32, 3000.0, 5000.0, 6500.0, 12000.0] {
            let c = blackbody_peak_normalised_rgb(kelvin);
            let colour = blackbody_rgb(kelvin);
            assert!(
                (c.normalize() - colour.normalize()).abs().max_element() < 1e-5,
                "{kelvin}: {c} {colour}"
            );
            let t = kelvin as f64;
            let peak = planck(2.8977721e6 / t, t);
            let (mut num, mut den) = (0.0, 0.0);
            for nm in 360..=830 {
                num += planck(nm as f64, t) / peak * y_bar(nm as f64);
                den += y_bar(nm as f64);
            }
            let expected = (num / den) as f32;
            assert!(
                (luminance(c) / expected - 1.0).abs() < 2e-3,
                "{kelvin} K: {} vs {expected}",
                luminance(c)
            );
            assert!((table.rgb(kelvin) - c).abs().max_element() <= 1e-4 * c.max_element() + 1e-9, "{kelvin}");
        }
        // Nothing at or below 100 K; a star's heat beyond the table.
        assert_eq!(table.rgb(100.0 - 1e-3), Vec3::ZERO);
        assert_eq!(table.rgb(2e5), blackbody_peak_normalised_rgb(2e5));
        assert!(luminance(blackbody_peak_normalised_rgb(5200.0)) > 0.8);
        assert!(luminance(blackbody_peak_normalised_rgb(1000.0)) < 1e-3);
    }

    #[test]
    fn spectrum_files() {
        let text = "# copper, k\n400 2.1  # violet\n500 2.5\n\n600 3.0 700 3.6\n";
        assert_eq!(parse_spd(text).unwrap(), [400.0, 2.1, 500.0, 2.5, 600.0, 3.0, 700.0, 3.6]);
        assert!(parse_spd("400 1 500").unwrap_err().contains("3 numbers"));
        assert!(parse_spd("500 1 400 2").unwrap_err().contains("do not increase"));
        assert!(parse_spd("400 x").unwrap_err().contains("line 1"));
        assert!(parse_spd("# nothing\n").is_err());
        assert!(names_a_file("spds/cu.spd") && names_a_file("k.spd"));
        assert!(!names_a_file("metal-Cu-eta") && !names_a_file("metal-CuZn-eta"));
    }

    #[test]
    fn named_illuminants_have_unit_luminance_and_their_colour() {
        let luminance = |c: Vec3| c.dot(Vec3::new(0.2126, 0.7152, 0.0722));
        let [a, d50, d60, d65] = ["stdillum-A", "stdillum-D50", "illum-acesD60", "stdillum-D65"]
            .map(|n| named_illuminant(n).unwrap());
        for c in [a, d50, d60, d65] {
            assert!((luminance(c) - 1.0).abs() < 2e-3, "{c}");
        }
        // Warmer the lower the temperature: red over blue falls from A to D65.
        let warmth = |c: Vec3| c.x / c.z;
        assert!(
            warmth(a) > warmth(d50) && warmth(d50) > warmth(d60) && warmth(d60) > warmth(d65),
            "{a} {d50} {d60}"
        );
        assert!(warmth(a) > 3.0, "{a}");
        // The daylight locus at D65's temperature is sRGB's white.
        assert!((crate::camera::daylight_rgb(6504.0) - Vec3::ONE).abs().max_element() < 0.01);
        assert!(named_illuminant("stdillum-F0").is_none() && named_illuminant("stdillum-F13").is_none());
    }

    /// The fluorescent illuminants have unit luminance and, back in CIE
    /// 1931 xy, the chromaticities the CIE publishes for them (CIE 15:2004,
    /// table T.8), within the analytic colour-matching fit's error.
    #[test]
    fn fluorescent_illuminants_have_their_chromaticities() {
        let published = [
            (0.3131, 0.3373),
            (0.3721, 0.3751),
            (0.4091, 0.3941),
            (0.4402, 0.4031),
            (0.3138, 0.3452),
            (0.3779, 0.3882),
            (0.3129, 0.3292),
            (0.3458, 0.3586),
            (0.3741, 0.3727),
            (0.3458, 0.3588),
            (0.3805, 0.3769),
            (0.4370, 0.4042),
        ];
        for (i, (x, y)) in published.into_iter().enumerate() {
            let c = named_illuminant(&format!("stdillum-F{}", i + 1)).unwrap();
            let xyz = Vec3::new(
                Vec3::new(0.4124, 0.3576, 0.1805).dot(c),
                Vec3::new(0.2126, 0.7152, 0.0722).dot(c),
                Vec3::new(0.0193, 0.1192, 0.9505).dot(c),
            );
            assert!((xyz.y - 1.0).abs() < 2e-3, "F{}: {c}", i + 1);
            let (cx, cy) = (xyz.x / xyz.element_sum(), xyz.y / xyz.element_sum());
            assert!(
                (cx - x).abs() < 0.004 && (cy - y).abs() < 0.004,
                "F{}: ({cx}, {cy}) against ({x}, {y})",
                i + 1
            );
        }
    }

    #[test]
    fn blackbody_colours() {
        // Near the sRGB white point, roughly white; warm light is red-heavy.
        let d65ish = blackbody_rgb(6504.0);
        assert!((d65ish - Vec3::ONE).abs().max_element() < 0.15, "{d65ish}");
        let warm = blackbody_rgb(2700.0);
        assert!(warm.x > warm.y && warm.y > warm.z, "{warm}");
        let lum = crate::luminance(warm);
        assert!((lum - 1.0).abs() < 0.02, "{lum}");
    }
}
