//! Lights as the renderer samples them: one flat table of every emitter
//! (point, distant, infinite and each emissive triangle in world space),
//! chosen in proportion to power. The table is small and replicated on every
//! device, so any device can do next-event estimation and MIS for any path.

use std::collections::HashMap;

use atoll_scene::{Light, Rgb, Scene};
use glam::{Vec2, Vec3};

use crate::sampling::{sample_uniform_sphere, sample_uniform_triangle, UNIFORM_SPHERE_PDF};

/// One emitter in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Emitter {
    Point {
        position: Vec3,
        intensity: Rgb,
    },
    /// `direction` is where the light travels.
    Distant {
        direction: Vec3,
        radiance: Rgb,
    },
    Infinite {
        radiance: Rgb,
    },
    Triangle {
        p: [Vec3; 3],
        normal: Vec3,
        area: f32,
        radiance: Rgb,
        two_sided: bool,
    },
}

/// A light sample as seen from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub wi: Vec3,
    /// Distance to the sampled point (infinite for distant/environment).
    pub distance: f32,
    /// Incident radiance (for point lights: intensity / distance²).
    pub radiance: Rgb,
    /// Solid-angle pdf including the light selection probability; for delta
    /// lights the selection probability alone.
    pub pdf: f32,
    pub delta: bool,
}

/// All emitters of a scene with a power-proportional selection distribution.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    pub emitters: Vec<Emitter>,
    /// Selection probability per emitter.
    pmf: Vec<f32>,
    /// Cumulative distribution (len = emitters + 1, last = 1).
    cdf: Vec<f32>,
    /// First emitter index of each emissive (instance, mesh) pair.
    triangle_base: HashMap<(u32, u32), u32>,
    /// Indices of infinite lights (a path that escapes sees all of them).
    infinite: Vec<u32>,
}

fn luminance(c: Rgb) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

impl LightSet {
    pub fn new(scene: &Scene) -> Self {
        let (lo, hi) = scene.world_bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let scene_radius = 0.5 * (hi - lo).length().max(1e-3);
        let mut set = LightSet::default();
        for light in &scene.lights {
            set.emitters.push(match *light {
                Light::Point { position, intensity } => Emitter::Point { position, intensity },
                Light::Distant { direction, radiance } => {
                    Emitter::Distant { direction: direction.normalize(), radiance }
                }
                Light::Infinite { radiance } => Emitter::Infinite { radiance },
            });
        }
        for (instance_id, instance) in scene.instances.iter().enumerate() {
            for &mesh_id in &scene.objects[instance.object as usize].meshes {
                let mesh = &scene.meshes[mesh_id as usize];
                let Some(emission) = mesh.emission else { continue };
                set.triangle_base.insert((instance_id as u32, mesh_id), set.emitters.len() as u32);
                for t in 0..mesh.triangle_count() {
                    let p = mesh.triangle(t).map(|v| instance.object_to_world.transform_point3(v));
                    // pbrt's orientation rule, evaluated in world space: the
                    // transform's handedness flips the cross product.
                    let mut n = (p[0] - p[2]).cross(p[1] - p[2]);
                    let area = 0.5 * n.length();
                    if mesh.flip_normals {
                        n = -n;
                    }
                    set.emitters.push(Emitter::Triangle {
                        p,
                        normal: n.normalize_or_zero(),
                        area,
                        radiance: emission.radiance,
                        two_sided: emission.two_sided,
                    });
                }
            }
        }
        let power: Vec<f32> = set
            .emitters
            .iter()
            .map(|e| match *e {
                Emitter::Point { intensity, .. } => 4.0 * std::f32::consts::PI * luminance(intensity),
                Emitter::Distant { radiance, .. } => {
                    std::f32::consts::PI * scene_radius * scene_radius * luminance(radiance)
                }
                Emitter::Infinite { radiance } => {
                    4.0 * std::f32::consts::PI.powi(2) * scene_radius * scene_radius * luminance(radiance)
                }
                Emitter::Triangle { area, radiance, two_sided, .. } => {
                    let sides = if two_sided { 2.0 } else { 1.0 };
                    std::f32::consts::PI * sides * area * luminance(radiance)
                }
            })
            .map(|p| if p.is_finite() { p.max(0.0) } else { 0.0 })
            .collect();
        let total: f64 = power.iter().map(|&p| p as f64).sum();
        set.pmf = if total > 0.0 {
            power.iter().map(|&p| (p as f64 / total) as f32).collect()
        } else {
            vec![1.0 / set.emitters.len().max(1) as f32; set.emitters.len()]
        };
        set.cdf = std::iter::once(0.0)
            .chain(set.pmf.iter().scan(0.0f64, |acc, &p| {
                *acc += p as f64;
                Some(*acc as f32)
            }))
            .collect();
        if let Some(last) = set.cdf.last_mut() {
            *last = 1.0;
        }
        set.infinite = (0..set.emitters.len() as u32)
            .filter(|&i| matches!(set.emitters[i as usize], Emitter::Infinite { .. }))
            .collect();
        set
    }

    pub fn is_empty(&self) -> bool {
        self.emitters.is_empty()
    }

    /// Global light index of triangle `triangle` of `mesh` in `instance`, if it emits.
    pub fn triangle_light(&self, instance: u32, mesh: u32, triangle: u32) -> Option<u32> {
        self.triangle_base.get(&(instance, mesh)).map(|base| base + triangle)
    }

    /// Indices of the infinite (environment) lights.
    pub fn infinite_lights(&self) -> &[u32] {
        &self.infinite
    }

    /// Probability of choosing emitter `index`.
    pub fn pmf(&self, index: u32) -> f32 {
        self.pmf[index as usize]
    }

    /// Picks an emitter with `u` in [0,1): (index, probability).
    pub fn select(&self, u: f32) -> Option<(u32, f32)> {
        if self.emitters.is_empty() {
            return None;
        }
        // First cdf entry > u, minus one; skips zero-probability emitters.
        let i = self.cdf.partition_point(|&c| c <= u).saturating_sub(1).min(self.emitters.len() - 1);
        Some((i as u32, self.pmf[i]))
    }

    /// Samples incident light at `p` with selection number `u_select` and
    /// position numbers `u`. `None` when the chosen light cannot contribute.
    pub fn sample(&self, p: Vec3, u_select: f32, u: Vec2) -> Option<LightSample> {
        let (index, pmf) = self.select(u_select)?;
        if pmf <= 0.0 {
            return None;
        }
        match self.emitters[index as usize] {
            Emitter::Point { position, intensity } => {
                let d = position - p;
                let dist2 = d.length_squared();
                let distance = dist2.sqrt();
                Some(LightSample {
                    wi: d / distance,
                    distance,
                    radiance: intensity / dist2,
                    pdf: pmf,
                    delta: true,
                })
            }
            Emitter::Distant { direction, radiance } => {
                Some(LightSample { wi: -direction, distance: f32::INFINITY, radiance, pdf: pmf, delta: true })
            }
            Emitter::Infinite { radiance } => Some(LightSample {
                wi: sample_uniform_sphere(u),
                distance: f32::INFINITY,
                radiance,
                pdf: pmf * UNIFORM_SPHERE_PDF,
                delta: false,
            }),
            Emitter::Triangle { p: tri, normal, area, radiance, two_sided } => {
                let b = sample_uniform_triangle(u);
                let q = tri[0] * b[0] + tri[1] * b[1] + tri[2] * b[2];
                let d = q - p;
                let dist2 = d.length_squared();
                if dist2 == 0.0 || area == 0.0 {
                    return None;
                }
                let distance = dist2.sqrt();
                let wi = d / distance;
                let cos_light = normal.dot(-wi);
                if cos_light == 0.0 || (!two_sided && cos_light < 0.0) {
                    return None;
                }
                let pdf = pmf * dist2 / (cos_light.abs() * area);
                Some(LightSample { wi, distance, radiance, pdf, delta: false })
            }
        }
    }

    /// Radiance leaving emissive triangle `index` towards direction `w`
    /// (pointing away from the surface).
    pub fn emitted(&self, index: u32, w: Vec3) -> Rgb {
        match self.emitters[index as usize] {
            Emitter::Triangle { normal, radiance, two_sided, .. } => {
                if two_sided || normal.dot(w) > 0.0 {
                    radiance
                } else {
                    Rgb::ZERO
                }
            }
            _ => Rgb::ZERO,
        }
    }

    /// Solid-angle pdf (with selection) that [`LightSet::sample`] picks the
    /// point at `distance` along `wi` on emissive triangle `index` — the
    /// light-sampling side of MIS when a BSDF-sampled ray hits an emitter.
    pub fn pdf_triangle(&self, index: u32, wi: Vec3, distance: f32) -> f32 {
        match self.emitters[index as usize] {
            Emitter::Triangle { normal, area, .. } => {
                let cos = normal.dot(wi).abs();
                if cos == 0.0 || area == 0.0 {
                    0.0
                } else {
                    self.pmf[index as usize] * distance * distance / (cos * area)
                }
            }
            _ => 0.0,
        }
    }

    /// Radiance of infinite light `index` along a ray leaving the scene in direction `w`.
    pub fn environment_radiance(&self, index: u32, _w: Vec3) -> Rgb {
        match self.emitters[index as usize] {
            Emitter::Infinite { radiance } => radiance,
            _ => Rgb::ZERO,
        }
    }

    /// Solid-angle pdf (with selection) that light sampling picks direction
    /// `w` from infinite light `index`.
    pub fn pdf_environment(&self, index: u32, _w: Vec3) -> f32 {
        self.pmf[index as usize] * UNIFORM_SPHERE_PDF
    }
}
