//! Lights as the renderer samples them: one flat table of every emitter
//! (point, distant, infinite and each emissive triangle in world space),
//! chosen by the frame's [`LightSampler`]: in proportion to power, or by a
//! BVH over the lights ([`crate::light_bvh`]) that weighs each by what it
//! can contribute at the shading point. The tables are small and
//! replicated on every device, so any device can do next-event estimation
//! and MIS for any path.

use atoll_scene::{luminance, Light, LightSampler, Portal, Rgb, Scene};
use glam::{Vec2, Vec3};

use std::sync::Arc;

use atoll_scene::TextureImage;

use crate::environment::EnvironmentSampler;
use crate::light_bvh::{LightBounds, LightBvh};
use crate::portal::{split_strategy, PortalFrame};
use crate::record::{pack_rgb9e5, unpack_rgb9e5};
use crate::sampling::{sample_uniform_sphere, sample_uniform_triangle, UNIFORM_SPHERE_PDF};
use crate::spawn;
use crate::texture::{self, ProgramRange, TexOp};

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
    /// With a `portal` of [`LightSet::portals`], only through it.
    Infinite {
        radiance: Rgb,
        portal: Option<u32>,
    },
    /// Image-based environment `index` of [`LightSet::environments`]; with
    /// a `portal`, only through it.
    Environment {
        index: u32,
        portal: Option<u32>,
    },
    /// `direction` is the cone's unit axis; see [`Light::Spot`].
    Spot {
        position: Vec3,
        direction: Vec3,
        intensity: Rgb,
        cos_falloff_start: f32,
        cos_falloff_end: f32,
    },
    Triangle {
        p: [Vec3; 3],
        normal: Vec3,
        area: f32,
        radiance: Rgb,
        two_sided: bool,
        /// Emission texture scaling `radiance` across the triangle.
        texture: Option<EmissionTexture>,
        /// Error bound along `normal` of the world-space corners (the
        /// instance transform's rounding), added to a sampled point's own.
        corner_error: f32,
    },
    /// A point whose intensity is scaled by map `map` of
    /// [`LightSet::intensity_maps`] towards `world_to_light × w`; see
    /// [`Light::Goniometric`].
    Goniometric {
        position: Vec3,
        world_to_light: glam::Mat3,
        intensity: Rgb,
        map: u32,
    },
    /// A point projecting image `image` of [`LightSet::projection_images`]
    /// towards `world_to_light × w`, times `scale`; see [`Light::Projection`].
    Projection {
        position: Vec3,
        world_to_light: glam::Mat3,
        scale: f32,
        image: u32,
    },
}

/// A triangle emitter's texture: its corners' uvs and its program in
/// [`LightSet::emission_ops`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmissionTexture {
    pub uv: [Vec2; 3],
    pub program: ProgramRange,
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
    /// For lights at a finite distance, the sampled point (with its
    /// surface normal, zero for point lights, and error bound) that a
    /// shadow ray aims at ([`spawn::spawn_ray_to`]).
    pub target: spawn::SurfacePoint,
}

/// All emitters of a scene and how next-event estimation picks one.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    pub emitters: Vec<Emitter>,
    pub sampler: LightSampler,
    /// [`LightSampler::Bvh`]: the tree over the emitters at a finite
    /// distance (empty under [`LightSampler::Power`]).
    pub bvh: LightBvh,
    /// [`LightSampler::Bvh`]: lights at infinity (distant, infinite,
    /// environment), chosen uniformly before the tree is asked.
    unbounded: Vec<u32>,
    /// Power selection probability per emitter.
    pmf: Vec<f32>,
    /// Cumulative distribution (len = emitters + 1, last = 1).
    cdf: Vec<f32>,
    /// Emissive (instance, mesh) pairs as sorted [`triangle_key`]s; the
    /// CUDA kernels binary-search the same table.
    triangle_keys: Vec<u64>,
    /// First emitter index of the pair `triangle_keys[i]`.
    triangle_bases: Vec<u32>,
    /// Indices of infinite lights (a path that escapes sees all of them).
    infinite: Vec<u32>,
    /// The image-based environments, by [`Emitter::Environment`] index.
    pub environments: Vec<EnvironmentSampler>,
    /// The goniometric lights' intensity maps, by their emitters' `map`.
    pub intensity_maps: Vec<Arc<atoll_scene::IntensityMap>>,
    /// The projection lights' images, by their emitters' `image`.
    pub projection_images: Vec<Arc<atoll_scene::ProjectionImage>>,
    /// The infinite lights' portals, by their emitters' `portal` index.
    pub portals: Vec<PortalFrame>,
    /// Programs of emission textures ([`EmissionTexture::program`]).
    pub emission_ops: Vec<TexOp>,
    /// The scene's texture images (shared), which those programs read.
    pub images: Vec<Arc<TextureImage>>,
}

/// The key of an (instance, mesh) pair in [`LightSet`]'s sorted triangle
/// table: `instance << 32 | mesh`.
#[inline]
pub fn triangle_key(instance: u32, mesh: u32) -> u64 {
    (instance as u64) << 32 | mesh as u64
}

/// pbrt's `SmoothStep(x, a, b)`: 0 below `a`, 1 above `b`, a cubic between
/// (a step at `a` when `a == b`). The GPU's `smooth_step` mirrors it.
pub fn smooth_step(x: f32, a: f32, b: f32) -> f32 {
    if a == b {
        return if x < a { 0.0 } else { 1.0 };
    }
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// A light at infinity: no point to aim a shadow ray at.
const AT_INFINITY: spawn::SurfacePoint =
    spawn::SurfacePoint { p: Vec3::ZERO, normal: Vec3::ZERO, error: 0.0 };

/// A point light's position: exact, on no surface.
fn point_target(p: Vec3) -> spawn::SurfacePoint {
    spawn::SurfacePoint { p, normal: Vec3::ZERO, error: 0.0 }
}

/// Lights at infinity, which have no bounds ([`LightSampler::Bvh`]
/// chooses among them apart from its tree).
fn is_unbounded(e: &Emitter) -> bool {
    matches!(e, Emitter::Distant { .. } | Emitter::Infinite { .. } | Emitter::Environment { .. })
}

/// The bounds of an emitter at a finite distance whose power is `phi`
/// (pbrt-v4's `Bounds` of its lights); `None` for lights at infinity.
fn light_bounds(e: &Emitter, phi: f32) -> Option<LightBounds> {
    let whole_sphere = |position: Vec3| LightBounds {
        min: position,
        max: position,
        w: Vec3::Z,
        phi,
        cos_theta_o: -1.0,
        cos_theta_e: 0.0,
        two_sided: false,
    };
    match *e {
        // A projection light's frustum is left unbounded: what lies outside
        // it only costs a shadow ray of zero radiance.
        Emitter::Point { position, .. }
        | Emitter::Goniometric { position, .. }
        | Emitter::Projection { position, .. } => Some(whole_sphere(position)),
        Emitter::Spot { position, direction, cos_falloff_start, cos_falloff_end, .. } => {
            // Light leaves within the falloff cone; the full cone is the
            // start angle plus what the falloff band adds.
            let theta_e = cos_falloff_end.clamp(-1.0, 1.0).acos() - cos_falloff_start.clamp(-1.0, 1.0).acos();
            Some(LightBounds {
                w: direction,
                cos_theta_o: cos_falloff_start,
                cos_theta_e: theta_e.cos(),
                ..whole_sphere(position)
            })
        }
        Emitter::Triangle { p, normal, two_sided, .. } => Some(LightBounds {
            min: p[0].min(p[1]).min(p[2]),
            max: p[0].max(p[1]).max(p[2]),
            w: normal,
            phi,
            cos_theta_o: 1.0,
            cos_theta_e: 0.0,
            two_sided,
        }),
        Emitter::Distant { .. } | Emitter::Infinite { .. } | Emitter::Environment { .. } => None,
    }
}

impl LightSet {
    pub fn new(scene: &Scene, sampler: LightSampler) -> Self {
        let (lo, hi) = scene.world_bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
        let scene_radius = 0.5 * (hi - lo).length().max(1e-3);
        let mut set = LightSet { sampler, ..Default::default() };
        let mut triangle_base = Vec::new();
        for light in &scene.lights {
            let emitter = match *light {
                Light::Point { position, intensity } => Emitter::Point { position, intensity },
                Light::Distant { direction, radiance } => {
                    Emitter::Distant { direction: direction.normalize(), radiance }
                }
                Light::Infinite { radiance, portal } => {
                    Emitter::Infinite { radiance, portal: set.add_portal(portal) }
                }
                Light::Spot { position, direction, intensity, cos_falloff_start, cos_falloff_end } => {
                    Emitter::Spot { position, direction, intensity, cos_falloff_start, cos_falloff_end }
                }
                Light::Goniometric { position, world_to_light, intensity, ref map } => {
                    set.intensity_maps.push(map.clone());
                    let map = set.intensity_maps.len() as u32 - 1;
                    Emitter::Goniometric { position, world_to_light, intensity, map }
                }
                Light::Projection { position, world_to_light, scale, ref image } => {
                    set.projection_images.push(image.clone());
                    let image = set.projection_images.len() as u32 - 1;
                    Emitter::Projection { position, world_to_light, scale, image }
                }
                Light::Environment { ref image, scale, light_to_world, portal } => {
                    set.environments.push(EnvironmentSampler::new(image.clone(), scale, light_to_world));
                    let index = set.environments.len() as u32 - 1;
                    Emitter::Environment { index, portal: set.add_portal(portal) }
                }
            };
            set.emitters.push(emitter);
        }
        // Emission texture programs per textured emissive mesh.
        let mut mesh_programs = std::collections::HashMap::new();
        for &(mesh, texture) in &scene.textures.emission {
            if scene.meshes.get(mesh as usize).is_none_or(|m| m.emission.is_none()) {
                continue;
            }
            let start = set.emission_ops.len() as u32;
            match texture::compile_texture(scene, texture, &mut set.emission_ops) {
                Ok(()) => {
                    let len = set.emission_ops.len() as u32 - start;
                    mesh_programs.insert(mesh, ProgramRange { start, len });
                }
                Err(e) => {
                    set.emission_ops.truncate(start as usize);
                    tracing::warn!("mesh {mesh}: emission texture: {e}; emitting its constant radiance");
                }
            }
        }
        if !mesh_programs.is_empty() {
            set.images = scene.textures.images.clone();
        }
        for (instance_id, instance) in scene.instances.iter().enumerate() {
            for &mesh_id in &scene.objects[instance.object as usize].meshes {
                let mesh = &scene.meshes[mesh_id as usize];
                let Some(emission) = mesh.emission else { continue };
                if instance.motion.is_some() {
                    // pbrt-v4 refuses moving area lights; the loaders make none.
                    tracing::warn!(
                        "mesh {mesh_id}: an emitter cannot move; it emits from its start position"
                    );
                }
                let program = mesh_programs.get(&mesh_id).copied();
                triangle_base.push((triangle_key(instance_id as u32, mesh_id), set.emitters.len() as u32));
                let normal_to_world = instance.normal_to_world();
                let to_world = &instance.object_to_world;
                for t in 0..mesh.triangle_count() {
                    let corners = mesh.triangle(t);
                    let p = corners.map(|v| to_world.transform_point3(v));
                    let area = 0.5 * (p[0] - p[2]).cross(p[1] - p[2]).length();
                    // Oriented exactly like the geometric normal of a hit
                    // (see the CPU device's `write_hit`), so one-sidedness
                    // agrees between light sampling and emitter hits even
                    // under mirroring instance transforms.
                    let n = normal_to_world * mesh.geometric_normal(t);
                    let texture = program.map(|program| EmissionTexture {
                        // pbrt's default parameterisation without uvs, as for other textures.
                        uv: if mesh.uvs.is_empty() {
                            [Vec2::ZERO, Vec2::X, Vec2::ONE]
                        } else {
                            mesh.indices[t].map(|i| mesh.uvs[i as usize])
                        },
                        program,
                    });
                    let normal = n.normalize_or_zero();
                    let corner_error = corners
                        .iter()
                        .map(|&v| {
                            spawn::error_along(normal, spawn::transformed_error(to_world, v, Vec3::ZERO))
                        })
                        .fold(0.0, f32::max);
                    set.emitters.push(Emitter::Triangle {
                        p,
                        normal,
                        area,
                        radiance: emission.radiance,
                        two_sided: emission.two_sided,
                        texture,
                        corner_error,
                    });
                }
            }
        }
        let power: Vec<f32> = set
            .emitters
            .iter()
            .map(|e| match *e {
                Emitter::Point { intensity, .. } => 4.0 * std::f32::consts::PI * luminance(intensity),
                Emitter::Goniometric { intensity, map, .. } => {
                    4.0 * std::f32::consts::PI
                        * luminance(intensity)
                        * set.intensity_maps[map as usize].mean()
                }
                Emitter::Projection { scale, image, .. } => {
                    scale * luminance(set.projection_images[image as usize].power())
                }
                Emitter::Spot { intensity, cos_falloff_start, cos_falloff_end, .. } => {
                    Light::spot_solid_angle(cos_falloff_start, cos_falloff_end) * luminance(intensity)
                }
                Emitter::Distant { radiance, .. } => {
                    std::f32::consts::PI * scene_radius * scene_radius * luminance(radiance)
                }
                Emitter::Infinite { radiance, .. } => {
                    4.0 * std::f32::consts::PI.powi(2) * scene_radius * scene_radius * luminance(radiance)
                }
                Emitter::Environment { index, .. } => {
                    4.0 * std::f32::consts::PI.powi(2)
                        * scene_radius
                        * scene_radius
                        * set.environments[index as usize].mean_luminance
                }
                Emitter::Triangle { area, radiance, two_sided, texture, .. } => {
                    let sides = if two_sided { 2.0 } else { 1.0 };
                    // A textured triangle's power: the texture's mean over
                    // its centroid and edge midpoints (selection only needs
                    // to be roughly proportional).
                    let mean = texture.map_or(Rgb::ONE, |t| {
                        let points = [[1.0 / 3.0; 3], [0.5, 0.5, 0.0], [0.0, 0.5, 0.5], [0.5, 0.0, 0.5]];
                        points.iter().map(|&b| set.texture_value(&t, b)).sum::<Rgb>() / points.len() as f32
                    });
                    std::f32::consts::PI * sides * area * luminance(radiance * mean)
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
        // Sorted for binary search. A mesh listed twice in one object keeps
        // its last base (stable sort, last of each run), as a map insert would.
        triangle_base.sort_by_key(|&(key, _)| key);
        for (i, &(key, base)) in triangle_base.iter().enumerate() {
            if triangle_base.get(i + 1).is_some_and(|next| next.0 == key) {
                continue;
            }
            set.triangle_keys.push(key);
            set.triangle_bases.push(base);
        }
        set.infinite = (0..set.emitters.len() as u32)
            .filter(|&i| {
                matches!(set.emitters[i as usize], Emitter::Infinite { .. } | Emitter::Environment { .. })
            })
            .collect();
        if sampler == LightSampler::Bvh {
            let mut bounded = Vec::new();
            // `is_unbounded` alone decides, as `selection_pmf` (and the
            // kernels' emitter-kind test) will.
            for (i, (e, &phi)) in set.emitters.iter().zip(&power).enumerate() {
                if is_unbounded(e) {
                    set.unbounded.push(i as u32);
                } else if let Some(b) = light_bounds(e, phi) {
                    bounded.push((i as u32, b));
                }
            }
            set.bvh = LightBvh::build(&bounded, set.emitters.len());
        }
        set
    }

    /// [`LightSampler::Bvh`]: the probability of choosing a light at
    /// infinity rather than asking the tree (pbrt-v4's: each light at
    /// infinity counts as much as the whole tree).
    pub fn unbounded_probability(&self) -> f32 {
        let n = self.unbounded.len() as f32;
        let tree = if self.bvh.is_empty() { 0.0 } else { 1.0 };
        if n == 0.0 {
            0.0
        } else {
            n / (n + tree)
        }
    }

    /// [`LightSampler::Bvh`]: the lights at infinity, in the order
    /// selection numbers map to them.
    pub fn unbounded_lights(&self) -> &[u32] {
        &self.unbounded
    }

    pub fn is_empty(&self) -> bool {
        self.emitters.is_empty()
    }

    /// Global light index of triangle `triangle` of `mesh` in `instance`, if it emits.
    pub fn triangle_light(&self, instance: u32, mesh: u32, triangle: u32) -> Option<u32> {
        let i = self.triangle_keys.binary_search(&triangle_key(instance, mesh)).ok()?;
        Some(self.triangle_bases[i] + triangle)
    }

    /// The sorted [`triangle_key`]s of the emissive (instance, mesh) pairs.
    pub fn triangle_keys(&self) -> &[u64] {
        &self.triangle_keys
    }

    /// First global light index of each pair of [`Self::triangle_keys`].
    pub fn triangle_bases(&self) -> &[u32] {
        &self.triangle_bases
    }

    /// Selection probability of every emitter.
    pub fn pmfs(&self) -> &[f32] {
        &self.pmf
    }

    /// Cumulative selection distribution: `emitters + 1` entries, the last
    /// exactly 1, non-decreasing ([`Self::select`] searches it).
    pub fn cdf(&self) -> &[f32] {
        &self.cdf
    }

    /// Indices of the infinite (environment) lights.
    pub fn infinite_lights(&self) -> &[u32] {
        &self.infinite
    }

    /// Probability of choosing emitter `index`.
    pub fn pmf(&self, index: u32) -> f32 {
        self.pmf[index as usize]
    }

    /// Picks an emitter for shading point `p` with `u` in [0,1): (index,
    /// probability).
    pub fn select(&self, p: Vec3, u: f32) -> Option<(u32, f32)> {
        match self.sampler {
            LightSampler::Power => self.select_by_power(u),
            LightSampler::Bvh => {
                let p_unbounded = self.unbounded_probability();
                if u < p_unbounded {
                    let n = self.unbounded.len();
                    let k = (((u / p_unbounded) * n as f32) as usize).min(n - 1);
                    return Some((self.unbounded[k], p_unbounded / n as f32));
                }
                let u = ((u - p_unbounded) / (1.0 - p_unbounded)).min(1.0 - f32::EPSILON / 2.0);
                let (index, pmf) = self.bvh.sample(p, u)?;
                Some((index, (1.0 - p_unbounded) * pmf))
            }
        }
    }

    /// The probability that [`Self::select`] at `p` picks emitter `index`.
    pub fn selection_pmf(&self, p: Vec3, index: u32) -> f32 {
        match self.sampler {
            LightSampler::Power => self.pmf[index as usize],
            LightSampler::Bvh => {
                if is_unbounded(&self.emitters[index as usize]) {
                    self.unbounded_probability() / self.unbounded.len() as f32
                } else {
                    (1.0 - self.unbounded_probability()) * self.bvh.pmf(p, index)
                }
            }
        }
    }

    /// [`LightSampler::Power`]'s choice: `u` in [0,1) through the cdf.
    pub fn select_by_power(&self, u: f32) -> Option<(u32, f32)> {
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
        let (index, pmf) = self.select(p, u_select)?;
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
                    target: point_target(position),
                })
            }
            Emitter::Distant { direction, radiance } => Some(LightSample {
                wi: -direction,
                distance: f32::INFINITY,
                radiance,
                pdf: pmf,
                delta: true,
                target: AT_INFINITY,
            }),
            Emitter::Infinite { portal: Some(_), .. } | Emitter::Environment { .. } => {
                let (wi, radiance, pdf) = match self.emitters[index as usize] {
                    Emitter::Environment { index, portal: None } => {
                        self.environments[index as usize].sample(u)?
                    }
                    _ => self.sample_through_portal(p, index, u)?,
                };
                Some(LightSample {
                    wi,
                    distance: f32::INFINITY,
                    radiance,
                    pdf: pmf * pdf,
                    delta: false,
                    target: AT_INFINITY,
                })
            }
            Emitter::Goniometric { position, world_to_light, intensity, map } => {
                let d = position - p;
                let dist2 = d.length_squared();
                let distance = dist2.sqrt();
                let wi = d / distance;
                let towards = (world_to_light * -wi).try_normalize()?;
                let scale = self.intensity_maps[map as usize].towards(towards);
                if scale <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    wi,
                    distance,
                    radiance: intensity * (scale / dist2),
                    pdf: pmf,
                    delta: true,
                    target: point_target(position),
                })
            }
            Emitter::Projection { position, world_to_light, scale, image } => {
                let d = position - p;
                let dist2 = d.length_squared();
                let distance = dist2.sqrt();
                let wi = d / distance;
                let rgb = self.projection_images[image as usize].towards(world_to_light * -wi)?;
                let radiance = rgb.max(Rgb::ZERO) * (scale / dist2);
                if radiance == Rgb::ZERO {
                    return None;
                }
                Some(LightSample {
                    wi,
                    distance,
                    radiance,
                    pdf: pmf,
                    delta: true,
                    target: point_target(position),
                })
            }
            Emitter::Spot { position, direction, intensity, cos_falloff_start, cos_falloff_end } => {
                let d = position - p;
                let dist2 = d.length_squared();
                let distance = dist2.sqrt();
                let wi = d / distance;
                let falloff = smooth_step(direction.dot(-wi), cos_falloff_end, cos_falloff_start);
                if falloff <= 0.0 {
                    return None;
                }
                Some(LightSample {
                    wi,
                    distance,
                    radiance: intensity * (falloff / dist2),
                    pdf: pmf,
                    delta: true,
                    target: point_target(position),
                })
            }
            Emitter::Infinite { radiance, portal: None } => Some(LightSample {
                wi: sample_uniform_sphere(u),
                distance: f32::INFINITY,
                radiance,
                pdf: pmf * UNIFORM_SPHERE_PDF,
                delta: false,
                target: AT_INFINITY,
            }),
            Emitter::Triangle { p: tri, normal, area, radiance, two_sided, texture, corner_error } => {
                let b = sample_uniform_triangle(u);
                let q = tri[0] * b[0] + tri[1] * b[1] + tri[2] * b[2];
                // pbrt's bound for a sampled point: γ₆ Σ |bᵢ pᵢ|, plus the corners' own.
                let error =
                    spawn::error_along(normal, spawn::gamma(6) * spawn::barycentric_magnitude(tri, b))
                        + corner_error;
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
                let radiance = match texture {
                    Some(t) => radiance * self.texture_value(&t, b),
                    None => radiance,
                };
                Some(LightSample {
                    wi,
                    distance,
                    radiance,
                    pdf,
                    delta: false,
                    target: spawn::SurfacePoint { p: q, normal, error },
                })
            }
        }
    }

    /// Radiance leaving emissive triangle `index` towards direction `w`
    /// (pointing away from the surface), for a hit whose record carries
    /// `emission_scale` (see [`LightSet::emission_scale`]).
    pub fn emitted(&self, index: u32, w: Vec3, emission_scale: u32) -> Rgb {
        match self.emitters[index as usize] {
            Emitter::Triangle { normal, radiance, two_sided, texture, .. } => {
                if !(two_sided || normal.dot(w) > 0.0) {
                    Rgb::ZERO
                } else if texture.is_some() {
                    radiance * unpack_rgb9e5(emission_scale)
                } else {
                    radiance
                }
            }
            _ => Rgb::ZERO,
        }
    }

    /// What a hit at barycentrics `(b1, b2)` of emissive triangle `index`
    /// stores in [`crate::RayRecord::emission_scale`]: its emission texture's
    /// value, packed; 0 for untextured emitters.
    pub fn emission_scale(&self, index: u32, b1: f32, b2: f32) -> u32 {
        match self.emitters[index as usize] {
            Emitter::Triangle { texture: Some(t), .. } => {
                pack_rgb9e5(self.texture_value(&t, [1.0 - b1 - b2, b1, b2]))
            }
            _ => 0,
        }
    }

    /// An emission texture's value at barycentrics `b`.
    fn texture_value(&self, t: &EmissionTexture, b: [f32; 3]) -> Rgb {
        let uv = t.uv[0] * b[0] + t.uv[1] * b[1] + t.uv[2] * b[2];
        let ops = &self.emission_ops[t.program.start as usize..(t.program.start + t.program.len) as usize];
        // An area light's image is looked up by uv (pbrt's `DiffuseAreaLight`):
        // no 3D mapping needs the point.
        let at = texture::TexPoint::uv(uv);
        texture::run_program(ops, &self.images, at, &mut [half::f16::ZERO; crate::record::MATERIAL_COEFFS])
    }

    /// Solid-angle pdf (with selection) that [`LightSet::sample`] at `p`
    /// picks the point at `distance` along `wi` on emissive triangle `index`
    /// — the light-sampling side of MIS when a BSDF-sampled ray from `p`
    /// hits an emitter.
    pub fn pdf_triangle(&self, p: Vec3, index: u32, wi: Vec3, distance: f32) -> f32 {
        match self.emitters[index as usize] {
            Emitter::Triangle { normal, area, .. } => {
                let cos = normal.dot(wi).abs();
                if cos == 0.0 || area == 0.0 {
                    0.0
                } else {
                    self.selection_pmf(p, index) * distance * distance / (cos * area)
                }
            }
            _ => 0.0,
        }
    }

    /// Radiance of infinite light `index` along a ray leaving the scene
    /// from `origin` in the unit direction `w` (through its portal, if it
    /// has one).
    pub fn environment_radiance(&self, index: u32, origin: Vec3, w: Vec3) -> Rgb {
        let (radiance, portal) = match self.emitters[index as usize] {
            Emitter::Infinite { radiance, portal } => (radiance, portal),
            Emitter::Environment { index, portal } => (self.environments[index as usize].radiance(w), portal),
            _ => return Rgb::ZERO,
        };
        match portal {
            Some(k) if !self.portals[k as usize].passes(origin, w) => Rgb::ZERO,
            _ => radiance,
        }
    }

    /// Solid-angle pdf (with selection) that light sampling at `p` picks
    /// direction `w` from infinite light `index`.
    pub fn pdf_environment(&self, p: Vec3, index: u32, w: Vec3) -> f32 {
        self.selection_pmf(p, index) * self.environment_direction_pdf(p, index, w)
    }

    /// The density of infinite light `index`'s direction sampling at `p`:
    /// its own (the image's, or uniform), or with a portal the even
    /// mixture of that and the portal's ([`crate::portal`]).
    fn environment_direction_pdf(&self, p: Vec3, index: u32, w: Vec3) -> f32 {
        let (own, portal) = match self.emitters[index as usize] {
            Emitter::Environment { index, portal } => (self.environments[index as usize].pdf(w), portal),
            Emitter::Infinite { portal, .. } => (UNIFORM_SPHERE_PDF, portal),
            _ => return 0.0,
        };
        match portal {
            Some(k) => 0.5 * own + 0.5 * self.portals[k as usize].pdf(p, w),
            None => own,
        }
    }

    /// A direction from `p` for infinite light `index`, which has a portal:
    /// by the light's own sampling or towards a point of the portal
    /// ([`crate::portal::split_strategy`]); its radiance (zero unless
    /// through the portal) and the mixture's density.
    fn sample_through_portal(&self, p: Vec3, index: u32, u: Vec2) -> Option<(Vec3, Rgb, f32)> {
        let (through_portal, u) = split_strategy(u);
        let wi = match self.emitters[index as usize] {
            Emitter::Infinite { portal: Some(k), .. } | Emitter::Environment { portal: Some(k), .. }
                if through_portal =>
            {
                self.portals[k as usize].sample(p, u)?.0
            }
            Emitter::Environment { index, .. } => self.environments[index as usize].sample(u)?.0,
            _ => sample_uniform_sphere(u),
        };
        let pdf = self.environment_direction_pdf(p, index, wi);
        (pdf > 0.0).then(|| (wi, self.environment_radiance(index, p, wi), pdf))
    }

    /// Adds `portal` to [`Self::portals`]; its index.
    fn add_portal(&mut self, portal: Option<Portal>) -> Option<u32> {
        let portal = portal?;
        self.portals.push(PortalFrame::new(&portal));
        Some(self.portals.len() as u32 - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use atoll_scene::{AreaEmission, Instance, Material, Object, TriangleMesh};
    use glam::Affine3A;

    /// A scene with one emissive square of side `side` at height `h`, facing down.
    fn square_light(side: f32, h: f32, radiance: Rgb) -> Scene {
        let s = side / 2.0;
        let mut scene = Scene::default();
        scene.add_material(Material::default_diffuse());
        let mesh = scene.add_mesh(TriangleMesh {
            positions: vec![
                Vec3::new(-s, h, -s),
                Vec3::new(s, h, -s),
                Vec3::new(s, h, s),
                Vec3::new(-s, h, s),
            ],
            // Same winding as the Cornell box light: pbrt's rule makes it face -y.
            indices: vec![[0, 1, 2], [0, 2, 3]],
            emission: Some(AreaEmission { radiance, two_sided: false }),
            ..Default::default()
        });
        let object = scene.add_object(Object { name: "light".into(), meshes: vec![mesh] });
        scene.instances.push(Instance::new(object, Affine3A::IDENTITY));
        scene
    }

    /// Irradiance at a point under the centre of an a×b rectangle at height
    /// h, parallel to the receiver: π L · 4 · F(corner, a/2, b/2).
    fn rectangle_irradiance(a: f64, b: f64, h: f64, radiance: f64) -> f64 {
        let corner = |a: f64, b: f64| {
            let (ra, rb) = ((a * a + h * h).sqrt(), (b * b + h * h).sqrt());
            (a / ra * (b / ra).atan() + b / rb * (a / rb).atan()) / (2.0 * std::f64::consts::PI)
        };
        std::f64::consts::PI * radiance * 4.0 * corner(a / 2.0, b / 2.0)
    }

    #[test]
    fn light_sampling_estimates_irradiance_of_a_square() {
        let (side, h, l) = (0.5f32, 0.8f32, 3.0f32);
        let set = LightSet::new(&square_light(side, h, Rgb::splat(l)), LightSampler::Power);
        assert_eq!(set.emitters.len(), 2);
        let n = 200_000;
        let mut sum = 0.0f64;
        for i in 0..n {
            let s = crate::rng::SampleStream::new(1, i, 0);
            if let Some(ls) = set.sample(Vec3::ZERO, s.get(0), Vec2::new(s.get(1), s.get(2))) {
                sum += (ls.radiance.x * ls.wi.y.max(0.0) / ls.pdf) as f64;
            }
        }
        let estimate = sum / n as f64;
        let exact = rectangle_irradiance(side as f64, side as f64, h as f64, l as f64);
        assert!((estimate - exact).abs() < 0.01 * exact, "estimate {estimate}, exact {exact}");
    }

    #[test]
    fn sample_pdf_matches_hit_pdf_and_back_faces_are_dark() {
        let set = LightSet::new(&square_light(1.0, 1.0, Rgb::ONE), LightSampler::Power);
        let p = Vec3::new(0.1, 0.0, -0.2);
        for i in 0..100 {
            let s = crate::rng::SampleStream::new(2, i, 0);
            let ls = set.sample(p, s.get(0), Vec2::new(s.get(1), s.get(2))).unwrap();
            // Which triangle was chosen is recorded by the selection; both
            // have equal power, so recompute via either.
            let (index, _) = set.select_by_power(s.get(0)).unwrap();
            let pdf = set.pdf_triangle(p, index, ls.wi, ls.distance);
            assert!((pdf - ls.pdf).abs() < 1e-4 * pdf, "{pdf} vs {}", ls.pdf);
            assert_eq!(set.emitted(index, -ls.wi, 0), Rgb::ONE);
            assert_eq!(set.emitted(index, ls.wi, 0), Rgb::ZERO);
        }
        // From above, the one-sided light cannot be sampled.
        assert!(set.sample(Vec3::new(0.0, 2.0, 0.0), 0.3, Vec2::new(0.2, 0.4)).is_none());
    }

    /// pbrt transforms an instance's normals with the inverse transpose, so a
    /// mirrored instance of a downward-facing light still faces down (the
    /// world-space cross product of its mirrored vertices would point up).
    #[test]
    fn mirrored_instance_keeps_its_emitting_side() {
        let mut scene = square_light(1.0, 1.0, Rgb::ONE);
        scene.instances[0].object_to_world = Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0));
        let set = LightSet::new(&scene, LightSampler::Power);
        assert!(set.sample(Vec3::ZERO, 0.3, Vec2::new(0.2, 0.4)).is_some());
        assert!(set.sample(Vec3::new(0.0, 2.0, 0.0), 0.3, Vec2::new(0.2, 0.4)).is_none());
    }

    #[test]
    fn selection_is_proportional_to_power() {
        let mut scene = square_light(1.0, 1.0, Rgb::ONE);
        scene.lights.push(Light::Point {
            position: Vec3::ZERO,
            intensity: Rgb::splat(1.0 / (4.0 * std::f32::consts::PI)),
        });
        let set = LightSet::new(&scene, LightSampler::Power);
        // Point: 4π · I = 1. Square: π · area · L = π. Two triangles of π/2.
        let total = 1.0 + std::f32::consts::PI;
        assert!((set.pmf(0) - 1.0 / total).abs() < 1e-6);
        assert!((set.pmf(1) - 0.5 * std::f32::consts::PI / total).abs() < 1e-6);
        let n = 100_000;
        let picked_point =
            (0..n).filter(|&i| set.select_by_power((i as f32 + 0.5) / n as f32).unwrap().0 == 0).count();
        assert!((picked_point as f32 / n as f32 - 1.0 / total).abs() < 1e-3);
    }

    #[test]
    fn triangle_lights_are_found_through_sorted_keys() {
        // A plain instance, two instances of the light object, and an object
        // listing a new emissive mesh before the light mesh (so its keys are
        // produced out of order and must be sorted).
        let mut scene = square_light(1.0, 1.0, Rgb::ONE);
        let light_mesh = 0;
        let plain = scene.add_mesh(TriangleMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            indices: vec![[0, 1, 2]],
            ..Default::default()
        });
        let lamp = scene.add_mesh(TriangleMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            indices: vec![[0, 1, 2]],
            emission: Some(AreaEmission { radiance: Rgb::ONE, two_sided: true }),
            ..Default::default()
        });
        let light_object = scene.instances[0].object;
        let plain_object = scene.add_object(Object { name: "plain".into(), meshes: vec![plain] });
        let mixed = scene.add_object(Object { name: "mixed".into(), meshes: vec![lamp, light_mesh] });
        scene.instances.insert(0, Instance::new(plain_object, Affine3A::IDENTITY));
        scene
            .instances
            .push(Instance::new(light_object, Affine3A::from_translation(Vec3::new(3.0, 0.0, 0.0))));
        scene.instances.push(Instance::new(mixed, Affine3A::IDENTITY));
        let set = LightSet::new(&scene, LightSampler::Power);
        // Instance 1: 2 triangles, instance 2: 2, instance 3: lamp 1 then light 2.
        assert_eq!(set.emitters.len(), 7);
        let keys = [triangle_key(1, 0), triangle_key(2, 0), triangle_key(3, 0), triangle_key(3, lamp)];
        assert_eq!(set.triangle_keys(), &keys);
        assert_eq!(set.triangle_bases(), &[0, 2, 5, 4]);
        assert_eq!(set.triangle_light(1, 0, 1), Some(1));
        assert_eq!(set.triangle_light(2, 0, 0), Some(2));
        assert_eq!(set.triangle_light(3, lamp, 0), Some(4));
        assert_eq!(set.triangle_light(3, light_mesh, 1), Some(6));
        assert_eq!(set.triangle_light(0, plain, 0), None);
        assert_eq!(set.triangle_light(4, 0, 0), None);
        // The second instance's triangles are the translated copies.
        match set.emitters[2] {
            Emitter::Triangle { p, .. } => assert_eq!(p[0].x, -0.5 + 3.0),
            other => panic!("{other:?}"),
        }
        assert_eq!(set.cdf().len(), 8);
        assert_eq!(set.pmfs().len(), 7);
    }

    /// A spot light: full intensity inside the inner cone, pbrt's
    /// smoothstep across the falloff band, nothing outside; chosen by power.
    #[test]
    fn spot_light_cone_and_power() {
        let mut scene = Scene::default();
        let axis = Vec3::new(0.0, -1.0, 0.0);
        scene.lights.push(Light::spot(Vec3::new(0.0, 2.0, 0.0), axis, Rgb::splat(8.0), 30.0, 10.0));
        scene.lights.push(Light::Point { position: Vec3::new(5.0, 5.0, 5.0), intensity: Rgb::splat(8.0) });
        let set = LightSet::new(&scene, LightSampler::Power);
        let spot_pmf = set.pmf(0);
        // Power: a spot of cone 30 (falloff from 20) against a point light of equal intensity.
        let (start, end) = (20f32.to_radians().cos(), 30f32.to_radians().cos());
        let expected = Light::spot_solid_angle(start, end)
            / (Light::spot_solid_angle(start, end) + 4.0 * std::f32::consts::PI);
        assert!((spot_pmf - expected).abs() < 1e-6, "{spot_pmf} vs {expected}");
        // Selection number 0 picks the spot light.
        let at = |angle_deg: f32| {
            let a = angle_deg.to_radians();
            Vec3::new(0.0, 2.0, 0.0) + Vec3::new(a.sin(), -a.cos(), 0.0) * 2.0
        };
        let inside = set.sample(at(10.0), 0.0, Vec2::ZERO).expect("inside the cone");
        assert!(inside.delta && (inside.pdf - spot_pmf).abs() < 1e-7);
        assert!((inside.radiance - Rgb::splat(2.0)).abs().max_element() < 1e-5, "{:?}", inside.radiance);
        assert!((inside.distance - 2.0).abs() < 1e-5);
        let band = set.sample(at(25.0), 0.0, Vec2::ZERO).expect("in the falloff band");
        let cos = 25f32.to_radians().cos();
        let t = (cos - end) / (start - end);
        let falloff = t * t * (3.0 - 2.0 * t);
        assert!((band.radiance.x - 2.0 * falloff).abs() < 1e-4, "{} vs {}", band.radiance.x, 2.0 * falloff);
        assert!(band.radiance.x > 0.0 && band.radiance.x < 2.0);
        assert!(set.sample(at(31.0), 0.0, Vec2::ZERO).is_none(), "outside the cone");
        assert!(set.sample(Vec3::new(0.0, 3.0, 0.0), 0.0, Vec2::ZERO).is_none(), "behind the light");
        assert_eq!(smooth_step(0.5, 0.5, 0.5), 1.0);
        assert_eq!(smooth_step(0.4, 0.5, 0.5), 0.0);
    }
}
