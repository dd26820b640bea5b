//! pbrt-v4's `realistic` camera: a lens system of spherical elements and an
//! aperture stop, traced from the film (Kolb et al. 1995, as in pbrt-v4's
//! `RealisticCamera`).
//!
//! Lens space has the film at z = 0 and the elements towards −z: the rear
//! element, nearest the film, last in the list. Camera space flips z (the
//! scene lies towards +z). Lengths are metres; the lens file gives
//! millimetres.
//!
//! What is computed once, when the scene is loaded: the film distance that
//! focuses the lens at the focus distance (from its thick-lens
//! approximation), and per ring of film radius the bounds of the exit
//! pupil, the part of the rear element that rays from the film get through
//! the whole system by. Rays are then sampled over those bounds only.

use glam::{Vec2, Vec3};

/// One interface of the lens system, as a row of the lens file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LensElement {
    /// Radius of the spherical interface (metres; positive: its centre lies
    /// towards the film, 0: the aperture stop).
    pub curvature_radius: f32,
    /// Distance to the next interface towards the film (for the last, to
    /// the film itself: set by focusing).
    pub thickness: f32,
    /// Index of refraction on the film side of the interface (0 or 1: air).
    pub eta: f32,
    pub aperture_radius: f32,
}

impl LensElement {
    fn is_stop(&self) -> bool {
        self.curvature_radius == 0.0
    }
}

/// Bounds of the exit pupil on the rear element's plane, for film points on
/// the +x axis (rotated about z for others): (min x, min y, max x, max y);
/// min > max where no ray gets through.
pub type PupilBounds = [f32; 4];

/// Exit-pupil rings over the film's radius (pbrt-v4's count).
pub const PUPIL_RINGS: usize = 64;

/// Rear-element points tried per ring when bounding its exit pupil: fewer
/// than pbrt-v4's 2^20, since rings are widened by the samples' spacing and
/// sampling beyond the pupil only adds noise, never bias.
const PUPIL_SAMPLES: usize = 1 << 16;

/// A focused lens system with its exit pupils.
#[derive(Clone, Debug, PartialEq)]
pub struct LensSystem {
    /// From the front (scene side) to the rear (film side).
    pub elements: Vec<LensElement>,
    /// The film's diagonal (metres): the pupils' rings span half of it.
    pub film_diagonal: f32,
    /// [`PUPIL_RINGS`] bounds, from the film's centre outwards.
    pub pupils: Vec<PupilBounds>,
    /// The stop's shape where it is not round (pbrt-v4's `aperture`).
    pub aperture: Option<ApertureImage>,
}

/// A stop's shape and transmission over the square the stop's circle fits
/// in: pbrt-v4's aperture image, one channel, its mean scaled to π/4 (a
/// round stop's share of the square) so that every shape passes the light
/// of the round stop.
#[derive(Clone, Debug, PartialEq)]
pub struct ApertureImage {
    pub width: u32,
    pub height: u32,
    /// Row 0 at the stop's −y edge, as pbrt-v4 has it after `FlipY`.
    pub values: Vec<f32>,
}

/// Size of pbrt-v4's built-in aperture shapes.
const BUILTIN_APERTURE_SIZE: u32 = 256;

impl ApertureImage {
    /// pbrt-v4's built-in shapes by name (`gaussian`, `square`, `pentagon`,
    /// `star`), or `None` for another name (an image file).
    pub fn builtin(name: &str) -> Option<ApertureImage> {
        let n = BUILTIN_APERTURE_SIZE;
        let at = |x: u32, y: u32| {
            Vec2::new(-1.0 + 2.0 * (x as f32 + 0.5) / n as f32, -1.0 + 2.0 * (y as f32 + 0.5) / n as f32)
        };
        let image = |f: &dyn Fn(Vec2, u32, u32) -> f32| {
            let values =
                (0..n).flat_map(|y| (0..n).map(move |x| (x, y))).map(|(x, y)| f(at(x, y), x, y)).collect();
            ApertureImage::from_rows(n, n, values)
        };
        let pentagon = || {
            let (c1, c2) = ((5f32.sqrt() - 1.0) / 4.0, (5f32.sqrt() + 1.0) / 4.0);
            let (s1, s2) = ((10.0 + 2.0 * 5f32.sqrt()).sqrt() / 4.0, (10.0 - 2.0 * 5f32.sqrt()).sqrt() / 4.0);
            [
                Vec2::new(0.0, 1.0),
                Vec2::new(s1, c1),
                Vec2::new(s2, -c2),
                Vec2::new(-s2, -c2),
                Vec2::new(-s1, c1),
            ]
            .map(|v| v * 0.8)
            .to_vec()
        };
        let star = || {
            let inner = 72f32.to_radians().cos() / 36f32.to_radians().cos();
            let mut v: Vec<Vec2> = (0..10)
                .map(|i| {
                    let r = if i % 2 == 1 { 1.0 } else { inner };
                    let a = std::f32::consts::PI * i as f32 / 5.0;
                    Vec2::new(r * a.cos(), r * a.sin())
                })
                .collect();
            v.reverse();
            v
        };
        match name {
            "gaussian" => Some(image(&|p, _, _| ((-p.length_squared()).exp() - (-1f32).exp()).max(0.0))),
            "square" => {
                let inside = |i: u32| i >= n / 4 && i < 3 * n / 4;
                Some(image(&|_, x, y| if inside(x) && inside(y) { 4.0 } else { 0.0 }))
            }
            "pentagon" => {
                let v = pentagon();
                Some(image(&|p, _, _| if winding_number(&v, p) != 0 { 1.0 } else { 0.0 }))
            }
            "star" => {
                let v = star();
                Some(image(&|p, _, _| if winding_number(&v, p) != 0 { 1.0 } else { 0.0 }))
            }
            _ => None,
        }
    }

    /// The aperture of an image whose rows run from `values`' first (top of
    /// a file; −y of a built-in shape) on: turned over and scaled as
    /// pbrt-v4 does. An image of no light stays dark.
    pub fn from_rows(width: u32, height: u32, values: Vec<f32>) -> ApertureImage {
        let mut flipped: Vec<f32> = values.chunks(width as usize).rev().flatten().copied().collect();
        let mean = flipped.iter().map(|&v| v as f64).sum::<f64>() / flipped.len().max(1) as f64;
        if mean > 0.0 {
            let scale = (std::f64::consts::FRAC_PI_4 / mean) as f32;
            flipped.iter_mut().for_each(|v| *v *= scale);
        }
        ApertureImage { width, height, values: flipped }
    }

    /// The bilinear value at `uv` (pbrt-v4's `BilerpChannel` with black
    /// outside the image).
    pub fn bilerp(&self, uv: Vec2) -> f32 {
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        let (xi, yi) = (x.floor(), y.floor());
        let (dx, dy) = (x - xi, y - yi);
        let texel = |x: f32, y: f32| {
            if x < 0.0 || y < 0.0 || x >= self.width as f32 || y >= self.height as f32 {
                0.0
            } else {
                self.values[y as usize * self.width as usize + x as usize]
            }
        };
        (1.0 - dx) * (1.0 - dy) * texel(xi, yi)
            + dx * (1.0 - dy) * texel(xi + 1.0, yi)
            + (1.0 - dx) * dy * texel(xi, yi + 1.0)
            + dx * dy * texel(xi + 1.0, yi + 1.0)
    }
}

/// The winding number of polygon `v` about `p` (pbrt-v4's rasteriser of
/// its built-in aperture shapes).
fn winding_number(v: &[Vec2], p: Vec2) -> i32 {
    let mut winding = 0;
    for i in 0..v.len() {
        let (a, b) = (v[i], v[(i + 1) % v.len()]);
        let e = (p.x - a.x) * (b.y - a.y) - (p.y - a.y) * (b.x - a.x);
        if a.y <= p.y {
            if b.y > p.y && e > 0.0 {
                winding += 1;
            }
        } else if b.y <= p.y && e < 0.0 {
            winding -= 1;
        }
    }
    winding
}

/// A camera-space ray out of the lens and its weight (pbrt-v4's
/// `cos⁴θ / (pdf z²)`: the film's irradiance estimate).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LensRay {
    pub origin: Vec3,
    pub direction: Vec3,
    pub weight: f32,
}

/// Reads a lens file: numbers separated by white space, `#` comments to
/// the end of the line, four per element (radius, thickness, index,
/// aperture diameter, in millimetres but for the index). Errors name the
/// line (`line N: what is wrong`).
pub fn parse_lens_file(text: &str) -> Result<Vec<f32>, String> {
    let mut values = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        for word in line.split_whitespace() {
            let v: f32 = word.parse().map_err(|_| format!("line {}: \"{word}\" is not a number", i + 1))?;
            if !v.is_finite() {
                return Err(format!("line {}: \"{word}\" is not finite", i + 1));
            }
            values.push(v);
        }
    }
    if values.is_empty() {
        return Err("no lens elements".into());
    }
    if values.len() % 4 != 0 {
        return Err(format!(
            "{} values: a lens element needs four (radius, thickness, eta, aperture)",
            values.len()
        ));
    }
    Ok(values)
}

impl LensSystem {
    /// The lens of `values` ([`parse_lens_file`]) with its stop opened to
    /// `aperture_diameter` millimetres (at most the stop's own, which a
    /// larger value is clamped to, with the warning returned) and shaped by
    /// `aperture` (round where `None`), focused at `focus_distance` metres,
    /// for a film of diagonal `film_diagonal` metres.
    pub fn new(
        values: &[f32],
        aperture_diameter: f32,
        aperture: Option<ApertureImage>,
        focus_distance: f32,
        film_diagonal: f32,
    ) -> Result<(LensSystem, Option<String>), String> {
        let mut warning = None;
        let mut elements = Vec::with_capacity(values.len() / 4);
        for row in values.chunks_exact(4) {
            let (radius, thickness, eta, diameter) = (row[0], row[1], row[2], row[3]);
            let mut diameter = diameter / 1000.0;
            if radius == 0.0 {
                let wanted = aperture_diameter / 1000.0;
                if wanted > diameter {
                    warning = Some(format!(
                        "\"aperturediameter\" {aperture_diameter} mm is larger than the lens's stop ({} mm); \
                         using the stop's",
                        diameter * 1000.0
                    ));
                } else {
                    diameter = wanted;
                }
            }
            if !positive(diameter) || thickness < 0.0 || eta < 0.0 {
                return Err(format!(
                    "element {}: aperture {diameter} m, thickness {} m and eta {eta} must be positive",
                    elements.len() + 1,
                    thickness / 1000.0
                ));
            }
            elements.push(LensElement {
                curvature_radius: radius / 1000.0,
                thickness: thickness / 1000.0,
                eta,
                aperture_radius: diameter / 2.0,
            });
        }
        if !positive(focus_distance) || !positive(film_diagonal) {
            return Err(format!(
                "\"focusdistance\" {focus_distance} and the film's diagonal {film_diagonal} must be positive"
            ));
        }
        let mut lens = LensSystem { elements, film_diagonal, pupils: Vec::new(), aperture };
        let film_distance = lens.focused_film_distance(focus_distance)?;
        lens.elements.last_mut().expect("at least one element").thickness = film_distance;
        lens.pupils = (0..PUPIL_RINGS)
            .map(|i| {
                let r = |i: usize| i as f32 / PUPIL_RINGS as f32 * film_diagonal / 2.0;
                lens.bound_exit_pupil(r(i), r(i + 1))
            })
            .collect();
        Ok((lens, warning))
    }

    /// The rear element's distance from the film.
    pub fn rear_z(&self) -> f32 {
        self.elements.last().map_or(0.0, |e| e.thickness)
    }

    /// The front element's distance from the film.
    pub fn front_z(&self) -> f32 {
        self.elements.iter().map(|e| e.thickness).sum()
    }

    fn rear_radius(&self) -> f32 {
        self.elements.last().map_or(0.0, |e| e.aperture_radius)
    }

    /// The camera-space ray from film point `origin` along `direction`
    /// after the whole system, and the stop's transmission where it has an
    /// aperture image (pbrt-v4's `TraceLensesFromFilm`); `None` where an
    /// element or the stop blocks it or it reflects totally.
    pub fn trace_from_film(&self, origin: Vec3, direction: Vec3) -> Option<(Vec3, Vec3, f32)> {
        let flip = Vec3::new(1.0, 1.0, -1.0);
        let (mut o, mut d) = (origin * flip, direction * flip);
        let (mut z, mut weight) = (0.0, 1.0);
        for (i, element) in self.elements.iter().enumerate().rev() {
            z -= element.thickness;
            let (t, n) = intersect_element(element, z, o, d)?;
            let hit = o + d * t;
            let radius = element.aperture_radius;
            match &self.aperture {
                Some(image) if element.is_stop() => {
                    weight = image.bilerp((hit.truncate() / radius + Vec2::ONE) / 2.0);
                    if weight == 0.0 {
                        return None;
                    }
                }
                _ if hit.x * hit.x + hit.y * hit.y > radius * radius => return None,
                _ => {}
            }
            o = hit;
            if !element.is_stop() {
                // Into the medium in front of this interface.
                let eta_t = match i {
                    0 => 1.0,
                    _ => medium_eta(self.elements[i - 1].eta),
                };
                d = refract(-d.normalize(), n, eta_t / medium_eta(element.eta))?;
            }
        }
        Some((o * flip, d * flip, weight))
    }

    /// The camera-space ray from scene point `origin` along `direction`
    /// through the system towards the film (pbrt-v4's
    /// `TraceLensesFromScene`), or `None` where it is blocked.
    pub fn trace_from_scene(&self, origin: Vec3, direction: Vec3) -> Option<(Vec3, Vec3)> {
        let flip = Vec3::new(1.0, 1.0, -1.0);
        let (mut o, mut d) = (origin * flip, direction * flip);
        let mut z = -self.front_z();
        for (i, element) in self.elements.iter().enumerate() {
            let (t, n) = intersect_element(element, z, o, d)?;
            let hit = o + d * t;
            if hit.x * hit.x + hit.y * hit.y > element.aperture_radius * element.aperture_radius {
                return None;
            }
            o = hit;
            if !element.is_stop() {
                let eta_i = match i {
                    0 => 1.0,
                    _ => medium_eta(self.elements[i - 1].eta),
                };
                d = refract(-d.normalize(), n, medium_eta(element.eta) / eta_i)?;
            }
            z += element.thickness;
        }
        Some((o * flip, d * flip))
    }

    /// The thick-lens approximation's principal planes `p` and focal points
    /// `f` (camera-space z): index 0 on the film side, 1 on the scene side.
    pub fn cardinal_points(&self) -> Result<([f32; 2], [f32; 2]), String> {
        // Rays parallel to the axis, a little off it.
        let x = 0.001 * self.film_diagonal;
        let blocked =
            || "no ray parallel to the axis gets through the lens (is the aperture stop tiny?)".to_string();
        let from_scene = (Vec3::new(x, 0.0, self.front_z() + 1.0), Vec3::NEG_Z);
        let (o, d) = self.trace_from_scene(from_scene.0, from_scene.1).ok_or_else(blocked)?;
        let (p0, f0) = cardinal(from_scene.0, o, d);
        let from_film = (Vec3::new(x, 0.0, self.rear_z() - 1.0), Vec3::Z);
        let (o, d, _) = self.trace_from_film(from_film.0, from_film.1).ok_or_else(blocked)?;
        let (p1, f1) = cardinal(from_film.0, o, d);
        Ok(([p0, p1], [f0, f1]))
    }

    /// The rear element's distance from the film that focuses the system at
    /// `focus_distance` (pbrt-v4's `FocusThickLens`).
    fn focused_film_distance(&self, focus_distance: f32) -> Result<f32, String> {
        let (p, f) = self.cardinal_points()?;
        let focal_length = f[0] - p[0];
        let z = -focus_distance;
        let c = (p[1] - z - p[0]) * (p[1] - z - 4.0 * focal_length - p[0]);
        if !positive(c) {
            return Err(format!(
                "\"focusdistance\" {focus_distance} is too short for this lens (focal length {focal_length} m)"
            ));
        }
        let delta = 0.5 * (p[1] - z + p[0] - c.sqrt());
        Ok(self.rear_z() + delta)
    }

    /// Bounds of the rear-element points that rays from the film between
    /// radii `r0` and `r1` on +x get through the system by (pbrt-v4's
    /// `BoundExitPupil`), widened by twice the samples' spacing.
    fn bound_exit_pupil(&self, r0: f32, r1: f32) -> PupilBounds {
        let extent = 1.5 * self.rear_radius();
        let mut bounds = [f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY];
        let inside = |b: &PupilBounds, p: Vec2| p.x >= b[0] && p.y >= b[1] && p.x <= b[2] && p.y <= b[3];
        for i in 0..PUPIL_SAMPLES {
            let film = Vec3::new(r0 + (i as f32 + 0.5) / PUPIL_SAMPLES as f32 * (r1 - r0), 0.0, 0.0);
            let u = Vec2::new(radical_inverse(2, i as u64), radical_inverse(3, i as u64));
            let rear = (u * 2.0 - Vec2::ONE) * extent;
            if !inside(&bounds, rear)
                && self.trace_from_film(film, rear.extend(self.rear_z()) - film).is_some()
            {
                bounds = [
                    bounds[0].min(rear.x),
                    bounds[1].min(rear.y),
                    bounds[2].max(rear.x),
                    bounds[3].max(rear.y),
                ];
            }
        }
        if bounds[0] > bounds[2] {
            return bounds;
        }
        let pad = 2.0 * (2.0 * extent * std::f32::consts::SQRT_2) / (PUPIL_SAMPLES as f32).sqrt();
        [bounds[0] - pad, bounds[1] - pad, bounds[2] + pad, bounds[3] + pad]
    }

    /// The ray from camera-space film point `film` (z = 0) through the
    /// exit pupil at `u` and out of the lens, and its weight; `None` where
    /// the lens blocks it.
    pub fn ray(&self, film: Vec2, u: Vec2) -> Option<LensRay> {
        let r = film.length();
        let ring = ((r / (self.film_diagonal / 2.0) * PUPIL_RINGS as f32) as usize).min(PUPIL_RINGS - 1);
        let b = self.pupils[ring];
        if !(b[0] < b[2] && b[1] < b[3]) {
            return None;
        }
        let lens = Vec2::new(b[0] + u.x * (b[2] - b[0]), b[1] + u.y * (b[3] - b[1]));
        let pdf = 1.0 / ((b[2] - b[0]) * (b[3] - b[1]));
        // The bounds are for film points on +x: turned to the film point's angle.
        let (sin, cos) = if r != 0.0 { (film.y / r, film.x / r) } else { (0.0, 1.0) };
        let pupil = Vec3::new(cos * lens.x - sin * lens.y, sin * lens.x + cos * lens.y, self.rear_z());
        let film = film.extend(0.0);
        let (origin, direction, transmission) = self.trace_from_film(film, pupil - film)?;
        let cos_theta = (pupil - film).normalize().z;
        let weight = transmission * cos_theta.powi(4) / (pdf * self.rear_z() * self.rear_z());
        Some(LensRay { origin, direction: direction.normalize(), weight })
    }

    /// The physical film's half extents (metres) for an image of aspect
    /// `height / width`, its diagonal [`LensSystem::film_diagonal`].
    pub fn film_half_extent(&self, aspect: f32) -> Vec2 {
        let x = (self.film_diagonal * self.film_diagonal / (1.0 + aspect * aspect)).sqrt();
        Vec2::new(x, aspect * x) / 2.0
    }
}

/// `x > 0` (false for NaN).
fn positive(x: f32) -> bool {
    x > 0.0
}

/// An element's medium index: 0 in a lens file means air.
fn medium_eta(eta: f32) -> f32 {
    if eta == 0.0 {
        1.0
    } else {
        eta
    }
}

/// The principal plane and focal point (camera-space z) of a ray parallel
/// to the axis entering at `entry` and leaving from `o` along `d`.
fn cardinal(entry: Vec3, o: Vec3, d: Vec3) -> (f32, f32) {
    let focal = -(o + d * (-o.x / d.x)).z;
    let principal = -(o + d * ((entry.x - o.x) / d.x)).z;
    (principal, focal)
}

/// Where the lens-space ray (`o`, `d`) meets `element` whose vertex lies at
/// `z`: its parameter and the normal facing the ray (pbrt-v4's
/// `IntersectSphericalElement`, or the stop's plane).
fn intersect_element(element: &LensElement, z: f32, o: Vec3, d: Vec3) -> Option<(f32, Vec3)> {
    if element.is_stop() {
        let t = (z - o.z) / d.z;
        return (t >= 0.0).then_some((t, Vec3::Z));
    }
    let radius = element.curvature_radius;
    let oc = o - Vec3::new(0.0, 0.0, z + radius);
    let (a, b, c) = (d.length_squared(), 2.0 * d.dot(oc), oc.length_squared() - radius * radius);
    let discriminant = b * b - 4.0 * a * c;
    if discriminant < 0.0 {
        return None;
    }
    // The numerically stable pair of roots.
    let root = discriminant.sqrt();
    let q = if b < 0.0 { -0.5 * (b - root) } else { -0.5 * (b + root) };
    let (t0, t1) = (q / a, c / q);
    let (t0, t1) = (t0.min(t1), t0.max(t1));
    let closer = (d.z > 0.0) ^ (radius < 0.0);
    let t = if closer { t0 } else { t1 };
    if t.is_nan() || t < 0.0 {
        return None;
    }
    let n = (oc + d * t).normalize();
    Some((t, if n.dot(-d) < 0.0 { -n } else { n }))
}

/// `wi` (unit, on the side of `n`) refracted through the interface of
/// relative index `eta` (transmitted over incident), or `None` on total
/// internal reflection.
fn refract(wi: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = n.dot(wi);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(-wi / eta + n * (cos_i / eta - cos_t))
}

/// The radical inverse of `i` in prime `base` (Halton's sequence).
fn radical_inverse(base: u64, mut i: u64) -> f32 {
    let (mut reversed, mut inv_base_n) = (0u64, 1.0f64);
    while i > 0 {
        reversed = reversed * base + i % base;
        inv_base_n /= base as f64;
        i /= base;
    }
    ((reversed as f64 * inv_base_n) as f32).min(1.0 - f32::EPSILON / 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A single biconvex lens (radii ±50 mm, 5 mm thick, index 1.5) and a
    /// stop behind it.
    fn biconvex(aperture_mm: f32) -> Vec<f32> {
        vec![50.0, 5.0, 1.5, 20.0, -50.0, 2.0, 1.0, 20.0, 0.0, 30.0, 1.0, aperture_mm]
    }

    /// The lensmaker's equation for a thick lens: 1/f = (n−1)(1/R1 − 1/R2 +
    /// (n−1) d / (n R1 R2)).
    #[test]
    fn the_thick_lens_focal_length_is_the_lensmakers() {
        let (lens, _) = LensSystem::new(&biconvex(10.0), 10.0, None, 10.0, 0.035).unwrap();
        let (p, f) = lens.cardinal_points().unwrap();
        let (n, r1, r2, d) = (1.5f32, 0.05f32, -0.05f32, 0.005f32);
        let expected = 1.0 / ((n - 1.0) * (1.0 / r1 - 1.0 / r2 + (n - 1.0) * d / (n * r1 * r2)));
        let focal = f[0] - p[0];
        assert!((focal - expected).abs() < 2e-3 * expected, "{focal} against {expected}");
        // Symmetric lens: the same on both sides.
        assert!(((f[1] - p[1]).abs() - expected).abs() < 2e-3 * expected, "{p:?} {f:?}");
    }

    /// Focused at 2 m, rays from the film's centre through any part of the
    /// pupil meet again on the axis near 2 m in front of the lens (the thick
    /// lens approximation's focus; a 2 mm stop keeps the singlet's
    /// spherical aberration small); focused elsewhere, they do not.
    #[test]
    fn rays_from_the_film_centre_converge_at_the_focus_distance() {
        let spread = |focus: f32| {
            let (lens, _) = LensSystem::new(&biconvex(2.0), 2.0, None, focus, 0.035).unwrap();
            let mut crossings = Vec::new();
            for i in 0..64 {
                let u = Vec2::new(radical_inverse(2, i), radical_inverse(3, i));
                if let Some(ray) = lens.ray(Vec2::ZERO, u) {
                    // Where the ray crosses the plane through the axis it
                    // spans with +z (it leaves off the axis, heading back).
                    let radial = ray.origin.truncate().normalize_or_zero();
                    let (h, dh) = (ray.origin.truncate().dot(radial), ray.direction.truncate().dot(radial));
                    if dh != 0.0 && h.abs() > 1e-4 {
                        crossings.push(ray.origin.z + ray.direction.z * (-h / dh));
                    }
                }
            }
            assert!(crossings.len() > 32, "{} rays got through", crossings.len());
            crossings
        };
        let at_2m = spread(2.0);
        for z in &at_2m {
            assert!((z - 2.0).abs() < 0.05, "crosses the axis at {z}");
        }
        assert!(spread(5.0).iter().all(|z| (z - 2.0).abs() > 0.5));
    }

    /// Every ray that gets through the lens leaves its rear through the
    /// pupil bounds of its ring: sampling rays over the whole rear element
    /// finds none outside.
    #[test]
    fn exit_pupils_hold_every_ray_that_gets_through() {
        let (lens, _) = LensSystem::new(&biconvex(8.0), 8.0, None, 3.0, 0.035).unwrap();
        let extent = lens.rear_radius() * 1.5;
        for ring in [0, 20, 50] {
            let film = Vec3::new((ring as f32 + 0.5) / PUPIL_RINGS as f32 * 0.0175, 0.0, 0.0);
            let b = lens.pupils[ring];
            let mut through = 0;
            for i in 0..20000u64 {
                let u = Vec2::new(radical_inverse(5, i), radical_inverse(7, i));
                let rear = (u * 2.0 - Vec2::ONE) * extent;
                if lens.trace_from_film(film, rear.extend(lens.rear_z()) - film).is_some() {
                    through += 1;
                    assert!(
                        rear.x >= b[0] && rear.y >= b[1] && rear.x <= b[2] && rear.y <= b[3],
                        "{rear} outside {b:?}"
                    );
                }
            }
            assert!(through > 100, "ring {ring}: {through}");
        }
    }

    /// pbrt-v4's built-in shapes keep the round stop's light on average
    /// (their mean is π/4) and pass light only where the shape is.
    #[test]
    fn aperture_shapes_keep_the_round_stops_light() {
        for name in ["gaussian", "square", "pentagon", "star"] {
            let image = ApertureImage::builtin(name).unwrap();
            let mean = image.values.iter().map(|&v| v as f64).sum::<f64>() / image.values.len() as f64;
            assert!((mean - std::f64::consts::FRAC_PI_4).abs() < 1e-5, "{name}: {mean}");
        }
        assert!(ApertureImage::builtin("heart.png").is_none());
        let square = ApertureImage::builtin("square").unwrap();
        // The square covers the middle half of the stop's square on each axis.
        assert!(square.bilerp(Vec2::splat(0.5)) > 0.0 && square.bilerp(Vec2::new(0.7, 0.7)) > 0.0);
        assert_eq!(square.bilerp(Vec2::new(0.5, 0.1)), 0.0);
        let star = ApertureImage::builtin("star").unwrap();
        assert!(star.bilerp(Vec2::splat(0.5)) > 0.0);
        // Its notch between two points (at 0°, the points at ±36°), inside a
        // round stop; a point, further out.
        assert_eq!(star.bilerp((Vec2::new(0.7, 0.0) + Vec2::ONE) / 2.0), 0.0);
        let point = Vec2::new(0.7 * 36f32.to_radians().cos(), 0.7 * 36f32.to_radians().sin());
        assert!(star.bilerp((point + Vec2::ONE) / 2.0) > 0.0);
        // Through a lens: the weight follows the shape, and the sampled
        // rays' mean weight is the round stop's.
        let shaped = |aperture| LensSystem::new(&biconvex(8.0), 8.0, aperture, 3.0, 0.035).unwrap().0;
        let mean_weight = |lens: &LensSystem| {
            let n = 1 << 16;
            (0..n as u64)
                .filter_map(|i| lens.ray(Vec2::ZERO, Vec2::new(radical_inverse(2, i), radical_inverse(3, i))))
                .map(|r| r.weight as f64)
                .sum::<f64>()
                / n as f64
        };
        let (round, square) =
            (mean_weight(&shaped(None)), mean_weight(&shaped(ApertureImage::builtin("square"))));
        assert!((square / round - 1.0).abs() < 0.02, "square {square} against round {round}");
    }

    #[test]
    fn lens_files_are_checked() {
        assert_eq!(
            parse_lens_file("# r t eta ap\n50 5 1.5 20 # front\n").unwrap(),
            vec![50.0, 5.0, 1.5, 20.0]
        );
        assert_eq!(
            parse_lens_file("50 5 1.5\n").unwrap_err(),
            "3 values: a lens element needs four (radius, thickness, eta, aperture)"
        );
        assert_eq!(parse_lens_file("50 5\n1.5 x\n").unwrap_err(), "line 2: \"x\" is not a number");
        assert!(parse_lens_file("# nothing\n").is_err());
        // A stop asked wider than it is stays as it is, with a warning.
        let (lens, warning) = LensSystem::new(&biconvex(8.0), 30.0, None, 3.0, 0.035).unwrap();
        assert!(warning.unwrap().contains("larger than the lens's stop"));
        assert_eq!(lens.elements[2].aperture_radius, 0.004);
        assert!(LensSystem::new(&biconvex(8.0), 8.0, None, 0.01, 0.035).unwrap_err().contains("too short"));
    }
}
