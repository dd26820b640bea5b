//! Shading a traced path record: emission, next-event estimation with MIS,
//! BSDF sampling and Russian roulette (pbrt-v4's PathIntegrator, one vertex
//! at a time), and the ambient-occlusion variant.
//!
//! A segment through a medium first decides whether it scatters on the way
//! ([`crate::medium`]); a scattering point is a vertex like a surface's,
//! with the phase function for its BSDF (pbrt-v4's VolPathIntegrator for
//! homogeneous media). Shadow rays carry the optical depth of the medium
//! they start in; traversal adds that of the media boundaries they cross.
//!
//! A subsurface material is a dielectric boundary around a medium of its
//! own. A path refracted in walks that medium (no light sampling: the
//! boundary blocks it) until the walk reaches the boundary, where the light
//! leaves by pbrt-v4's normalised Fresnel lobe, as from pbrt's BSSRDF
//! probe point. Entry and exit count as one bounce, as in pbrt-v4.

use atoll_scene::IntegratorSettings;
use glam::{Vec2, Vec3};

use crate::bsdf::fresnel::fr_dielectric;
use crate::bsdf::Frame;
use crate::frame::FrameContext;
use crate::material_coeffs::{bsdf_from_record, shading_frame};
use crate::material_layout::subsurface;
use crate::medium::{MediumCoeffs, Segment};
use crate::record::{flags, pack_eta_scale, MaterialKind, RayRecord, NO_LIGHT};
use crate::rng::{BounceDim, SampleStream};
use crate::sampling::{
    henyey_greenstein, power_heuristic, sample_cosine_hemisphere, sample_henyey_greenstein,
};
use crate::spawn::{self, SurfacePoint};
use atoll_scene::MediumIndex;

/// What shading one record produces.
#[derive(Clone, Copy, Debug, Default)]
pub struct ShadeOutcome {
    /// Radiance to add to the record's pixel now (emission found by this segment).
    pub emitted: Vec3,
    /// A shadow ray carrying the radiance it adds if unoccluded.
    pub shadow: Option<RayRecord>,
    /// The path's next segment.
    pub next: Option<RayRecord>,
}

/// Shades `r` with the frame's integrator.
pub fn shade(ctx: &FrameContext, r: &RayRecord) -> ShadeOutcome {
    match ctx.options.integrator {
        IntegratorSettings::Path { max_depth } => shade_path(ctx, r, max_depth),
        IntegratorSettings::AmbientOcclusion { max_distance } => {
            shade_ambient_occlusion(ctx, r, max_distance)
        }
    }
}

/// A new segment of the same path leaving the hit `at` in unit direction
/// `w`, from just past the hit's error bound.
fn continuation(r: &RayRecord, at: &SurfacePoint, w: Vec3) -> RayRecord {
    let mut next = *r;
    next.origin = spawn::offset_ray_origin(at.p, at.error, at.normal, w).to_array();
    next.direction = w.to_array();
    next.t_max = f32::INFINITY;
    next.flags &= !flags::HIT;
    next.light = NO_LIGHT;
    next
}

/// A shadow ray from the hit `at` that adds `radiance` to the pixel if
/// unoccluded: towards `target` when the light is at a finite distance
/// (`SpawnRayTo`, neither end's surface can occlude it), else along `w`
/// up to `t_max`. `None` when the two ends coincide.
fn shadow_ray(
    r: &RayRecord,
    at: &SurfacePoint,
    target: Option<&SurfacePoint>,
    w: Vec3,
    t_max: f32,
    radiance: Vec3,
) -> Option<RayRecord> {
    let mut s = *r;
    match target {
        Some(target) => {
            let ray = spawn::spawn_ray_to(*at, *target)?;
            s.origin = ray.origin.to_array();
            s.direction = ray.direction.to_array();
            s.t_max = ray.t_max;
        }
        None => {
            s.origin = spawn::offset_ray_origin(at.p, at.error, at.normal, w).to_array();
            s.direction = w.to_array();
            s.t_max = t_max;
        }
    }
    s.light = NO_LIGHT;
    s.throughput = radiance.to_array();
    s.flags = flags::SHADOW;
    // No optical depth unless it starts in a medium (`start_in_medium`).
    s.position = [0.0; 3];
    Some(s)
}

/// With media in the scene: a shadow ray leaving in medium `medium` starts
/// with that medium's optical depth over its whole length (traversal adds
/// the change at each boundary it crosses), and one towards a light at
/// infinity ends past the scene, so that its depth is finite.
fn start_in_medium(ctx: &FrameContext, s: &mut RayRecord, medium: MediumIndex) {
    if !ctx.media.any() {
        return;
    }
    if s.t_max == f32::INFINITY {
        s.t_max = ctx.media.shadow_reach / s.direction().length();
    }
    s.position = ctx.media.optical_depth(medium, s.origin(), s.direction(), 0.0, s.t_max).to_array();
}

/// Russian roulette from the second bounce on (pbrt-v4's `depth > 1`), on
/// the throughput without the radiance scaling of refractions, which
/// would otherwise end most paths inside glass. Its magnitude: a pixel
/// filter's negative lobes make some throughputs negative. `u` is the
/// vertex's uniform number for it. `None` when the path ends.
fn russian_roulette(ctx: &FrameContext, u: f32, depth: u32, beta: Vec3, eta_scale: f32) -> Option<Vec3> {
    let mut beta = beta;
    if ctx.options.russian_roulette && depth >= 1 {
        let max = (beta * eta_scale).abs().max_element();
        if max < 1.0 {
            let q = (1.0 - max).max(0.0);
            if u < q {
                return None;
            }
            beta /= 1.0 - q;
        }
    }
    beta.is_finite().then_some(beta)
}

/// The least probability with which a walk through a subsurface medium
/// ends at each step: in a medium that absorbs nothing, the walk could
/// otherwise go on as long as its boundary lets it (for ever in an open
/// mesh). Survivors are weighted up, so the image stays unbiased.
pub const WALK_END: f32 = 1.0 / 256.0;

/// Russian roulette at a step of a subsurface walk: as
/// [`russian_roulette`] at any depth, and at least [`WALK_END`].
fn walk_roulette(ctx: &FrameContext, u: f32, beta: Vec3, eta_scale: f32) -> Option<Vec3> {
    let q = if ctx.options.russian_roulette {
        (1.0 - (beta * eta_scale).abs().max_element()).max(WALK_END)
    } else {
        WALK_END
    };
    if u < q {
        return None;
    }
    let beta = beta / (1.0 - q);
    beta.is_finite().then_some(beta)
}

/// The shaded hit of `r` as a ray end: position, geometric normal, error.
fn hit_point(r: &RayRecord) -> SurfacePoint {
    SurfacePoint {
        p: Vec3::from(r.position),
        normal: r.geometric_normal().normalize_or_zero(),
        error: r.position_error(),
    }
}

fn shade_path(ctx: &FrameContext, r: &RayRecord, max_depth: u32) -> ShadeOutcome {
    let lights = &ctx.lights;
    let mut beta = r.throughput();
    let dir = r.direction();
    let specular = r.has(flags::SPECULAR);
    let mut out = ShadeOutcome::default();
    let medium = r.medium();

    // Through a medium: its emission along the segment, then where (and
    // whether) the segment scatters before its end.
    if medium != atoll_scene::VACUUM {
        let m = ctx.media.get(medium);
        let t_max = if r.has(flags::HIT) { r.t_max } else { f32::INFINITY };
        let rng = SampleStream::new(ctx.options.seed, r.pixel, r.sample);
        let u = rng.medium_distance(r.depth as u32, r.origin, r.throughput);
        let segment = ctx.media.sample_segment(medium, r.origin(), dir, t_max, u, beta);
        out.emitted += beta * segment.emitted;
        match segment.end {
            Segment::Scatter { t, weight } => {
                let p = r.origin() + dir.normalize() * t;
                return scatter_in_medium(ctx, r, m, p, beta * weight, max_depth, out);
            }
            Segment::Pass { weight } => beta *= weight,
        }
        if beta == Vec3::ZERO {
            return out;
        }
    }

    // Escaped: environment lights, MIS-weighted against light sampling.
    // Light selection may depend on where the path was (the BVH sampler):
    // the previous vertex is where this segment started.
    let from = r.origin();
    if !r.has(flags::HIT) {
        for &i in lights.infinite_lights() {
            let le = lights.environment_radiance(i, from, dir);
            let w = if specular {
                1.0
            } else {
                power_heuristic(r.bsdf_pdf, lights.pdf_environment(from, i, dir))
            };
            out.emitted += beta * le * w;
        }
        return out;
    }

    // Emission of the surface hit, MIS-weighted against light sampling.
    if r.light != NO_LIGHT {
        let le = lights.emitted(r.light, -dir, r.emission_scale);
        if le != Vec3::ZERO {
            let w = if specular {
                1.0
            } else {
                power_heuristic(r.bsdf_pdf, lights.pdf_triangle(from, r.light, dir, r.t_max))
            };
            out.emitted += beta * le * w;
        }
    }

    let at = hit_point(r);
    let p = at.p;
    let media = r.hit_media();
    let subsurface_entry = r.material_kind() == MaterialKind::Subsurface;
    if let Some(m) =
        media.filter(|m| subsurface_entry && m.inside == medium && ctx.media.get(medium).subsurface)
    {
        return leave_subsurface(ctx, r, &at, m.outside, beta, out);
    }
    // The medium on the side a direction leaves the surface into; a
    // subsurface boundary's inside is its interior, whichever way its
    // normal points.
    let medium_towards = |w: Vec3| match media {
        Some(m) if subsurface_entry => {
            if w.dot(at.normal) * dir.dot(at.normal) > 0.0 {
                m.inside
            } else {
                medium
            }
        }
        Some(m) => m.towards(w.dot(at.normal)),
        None => medium,
    };
    let Some(bsdf) = bsdf_from_record(r, &ctx.measured) else {
        // A surface that only bounds a medium: continue straight through.
        let mut next = continuation(r, &at, dir);
        next.throughput = beta.to_array();
        next.set_medium(medium_towards(dir));
        out.next = Some(next);
        return out;
    };
    let depth = r.depth as u32;
    if depth >= max_depth {
        return out;
    }
    let frame = shading_frame(r);
    let wo = frame.to_local(-dir);
    if wo.z == 0.0 {
        return out;
    }
    let rng = SampleStream::new(ctx.options.seed, r.pixel, r.sample);

    // Next-event estimation.
    if !bsdf.is_delta() {
        let u_light = Vec2::new(
            rng.bounce(depth, BounceDim::LightPosition, 0),
            rng.bounce(depth, BounceDim::LightPosition, 1),
        );
        if let Some(ls) = lights.sample(p, rng.bounce(depth, BounceDim::LightSelect, 0), u_light) {
            let wi = frame.to_local(ls.wi);
            let f = bsdf.eval(wo, wi) * wi.z.abs();
            if ls.pdf > 0.0 && f != Vec3::ZERO && ls.radiance != Vec3::ZERO {
                let w = if ls.delta { 1.0 } else { power_heuristic(ls.pdf, bsdf.pdf(wo, wi)) };
                let contribution = beta * f * ls.radiance * (w / ls.pdf);
                let target = ls.distance.is_finite().then_some(&ls.target);
                out.shadow = shadow_ray(r, &at, target, ls.wi, f32::INFINITY, contribution).map(|mut s| {
                    start_in_medium(ctx, &mut s, medium_towards(ls.wi));
                    s
                });
            }
        }
    }

    // Sample the BSDF for the next segment.
    let u_dir = Vec2::new(
        rng.bounce(depth, BounceDim::BsdfDirection, 0),
        rng.bounce(depth, BounceDim::BsdfDirection, 1),
    );
    let Some(bs) = bsdf.sample(wo, rng.bounce(depth, BounceDim::BsdfLobe, 0), u_dir) else {
        return out;
    };
    if bs.pdf <= 0.0 || bs.f == Vec3::ZERO {
        return out;
    }
    let beta = beta * bs.f * (bs.wi.z.abs() / bs.pdf);
    let mut eta_scale = r.eta_scale();
    if bs.transmission {
        eta_scale *= bs.eta * bs.eta;
    }
    let u_roulette = rng.bounce(depth, BounceDim::RussianRoulette, 0);
    let Some(beta) = russian_roulette(ctx, u_roulette, depth, beta, eta_scale) else {
        return out;
    };
    let wi = frame.from_local(bs.wi).normalize();
    let mut next = continuation(r, &at, wi);
    next.throughput = beta.to_array();
    next.eta_scale = pack_eta_scale(eta_scale);
    // A stochastic BSDF's sample density is only proportional to the real
    // one; MIS at the next vertex needs its `pdf` (pbrt's `pdfIsProportional`).
    // Specular samples skip MIS, so their probability is kept as it is.
    let proportional = bsdf.sampled_pdf_is_proportional() && !bs.delta;
    next.bsdf_pdf = if proportional { bsdf.pdf(wo, bs.wi) } else { bs.pdf };
    next.depth += 1;
    next.flags = if bs.delta { flags::SPECULAR } else { 0 };
    next.set_medium(medium_towards(wi));
    out.next = Some(next);
    out
}

/// A path vertex where the segment `r` scatters in medium `m`, at `p`,
/// with throughput `beta` (the segment's weight included): next-event
/// estimation and a new direction, both with the Henyey–Greenstein phase
/// function, which samples itself exactly.
fn scatter_in_medium(
    ctx: &FrameContext,
    r: &RayRecord,
    m: &MediumCoeffs,
    p: Vec3,
    beta: Vec3,
    max_depth: u32,
    mut out: ShadeOutcome,
) -> ShadeOutcome {
    if m.subsurface {
        return walk_subsurface(ctx, r, m, p, beta, out);
    }
    let depth = r.depth as u32;
    if depth >= max_depth {
        return out;
    }
    let wo = -r.direction().normalize();
    let at = SurfacePoint { p, normal: Vec3::ZERO, error: 0.0 };
    let rng = SampleStream::new(ctx.options.seed, r.pixel, r.sample);
    let u_light = Vec2::new(
        rng.bounce(depth, BounceDim::LightPosition, 0),
        rng.bounce(depth, BounceDim::LightPosition, 1),
    );
    if let Some(ls) = ctx.lights.sample(p, rng.bounce(depth, BounceDim::LightSelect, 0), u_light) {
        let phase = henyey_greenstein(wo.dot(ls.wi), m.g);
        if ls.pdf > 0.0 && phase > 0.0 && ls.radiance != Vec3::ZERO {
            let w = if ls.delta { 1.0 } else { power_heuristic(ls.pdf, phase) };
            let contribution = beta * ls.radiance * (phase * w / ls.pdf);
            let target = ls.distance.is_finite().then_some(&ls.target);
            out.shadow = shadow_ray(r, &at, target, ls.wi, f32::INFINITY, contribution).map(|mut s| {
                start_in_medium(ctx, &mut s, r.medium());
                s
            });
        }
    }
    let u_dir = Vec2::new(
        rng.bounce(depth, BounceDim::BsdfDirection, 0),
        rng.bounce(depth, BounceDim::BsdfDirection, 1),
    );
    let (wi, pdf) = sample_henyey_greenstein(wo, m.g, u_dir);
    let u_roulette = rng.bounce(depth, BounceDim::RussianRoulette, 0);
    let Some(beta) = russian_roulette(ctx, u_roulette, depth, beta, r.eta_scale()) else {
        return out;
    };
    let mut next = scattered(r, p, wi, beta, pdf);
    next.depth += 1;
    out.next = Some(next);
    out
}

/// The segment after `r` scatters at `p` in its medium towards `wi`
/// (sampled with density `pdf`), with throughput `beta`.
fn scattered(r: &RayRecord, p: Vec3, wi: Vec3, beta: Vec3, pdf: f32) -> RayRecord {
    let mut next = continuation(r, &SurfacePoint { p, normal: Vec3::ZERO, error: 0.0 }, wi);
    next.throughput = beta.to_array();
    next.bsdf_pdf = pdf;
    next.flags = 0;
    next.set_medium(r.medium());
    next
}

/// A step of a walk through subsurface medium `m`: the segment `r`
/// scatters at `p` with throughput `beta`. The walk is part of one path
/// vertex, so the depth stays and its numbers come from the segment
/// ([`SampleStream::walk`]); it samples no light and ends by
/// [`walk_roulette`] or at the boundary.
fn walk_subsurface(
    ctx: &FrameContext,
    r: &RayRecord,
    m: &MediumCoeffs,
    p: Vec3,
    beta: Vec3,
    mut out: ShadeOutcome,
) -> ShadeOutcome {
    let depth = r.depth as u32;
    let (origin, throughput) = (r.origin, r.throughput);
    let rng = SampleStream::new(ctx.options.seed, r.pixel, r.sample);
    let wo = -r.direction().normalize();
    let u_dir = Vec2::new(
        rng.walk(depth, origin, throughput, BounceDim::BsdfDirection, 0),
        rng.walk(depth, origin, throughput, BounceDim::BsdfDirection, 1),
    );
    let (wi, pdf) = sample_henyey_greenstein(wo, m.g, u_dir);
    let u_roulette = rng.walk(depth, origin, throughput, BounceDim::RussianRoulette, 0);
    let Some(beta) = walk_roulette(ctx, u_roulette, beta, r.eta_scale()) else {
        return out;
    };
    out.next = Some(scattered(r, p, wi, beta, pdf));
    out
}

/// Where a subsurface walk reaches its boundary `at`, from inside, with
/// throughput `beta`: the light leaves into `outside` by pbrt-v4's
/// `NormalizedFresnelBxDF`, cosine-weighted less what the boundary
/// reflects and normalised to let all of it out (the walk accounted for
/// the interior), and the radiance scaling of the entry's refraction is
/// undone (pbrt's η² in radiance mode). It samples a light and a new
/// direction with numbers from the walk's last segment, at the entry's
/// depth, which the depth limit was checked against.
fn leave_subsurface(
    ctx: &FrameContext,
    r: &RayRecord,
    at: &SurfacePoint,
    outside: MediumIndex,
    beta: Vec3,
    mut out: ShadeOutcome,
) -> ShadeOutcome {
    use std::f32::consts::PI;
    let eta = r.coeff(subsurface::ETA);
    let normalisation = r.coeff(subsurface::EXIT_NORMALISATION);
    let lets_out = |cos: f32| (1.0 - fr_dielectric(cos, eta)) / normalisation;
    // The side the walk was heading for, and the lobe's frame on it.
    let dir = r.direction();
    let n_out = if at.normal.dot(dir) < 0.0 { -at.normal } else { at.normal };
    let ns = r.shading_normal().normalize_or_zero();
    let ns = if ns == Vec3::ZERO {
        n_out
    } else if ns.dot(n_out) < 0.0 {
        -ns
    } else {
        ns
    };
    let beta = beta * (eta * eta);
    let eta_scale = r.eta_scale() / (eta * eta);
    let depth = r.depth as u32;
    let (origin, throughput) = (r.origin, r.throughput);
    let rng = SampleStream::new(ctx.options.seed, r.pixel, r.sample);
    let u_light = Vec2::new(
        rng.walk(depth, origin, throughput, BounceDim::LightPosition, 0),
        rng.walk(depth, origin, throughput, BounceDim::LightPosition, 1),
    );
    if let Some(ls) =
        ctx.lights.sample(at.p, rng.walk(depth, origin, throughput, BounceDim::LightSelect, 0), u_light)
    {
        let cos = ls.wi.dot(ns);
        if cos > 0.0 && ls.wi.dot(n_out) > 0.0 && ls.pdf > 0.0 && ls.radiance != Vec3::ZERO {
            let pdf = cos / PI;
            let w = if ls.delta { 1.0 } else { power_heuristic(ls.pdf, pdf) };
            let contribution = beta * ls.radiance * (lets_out(cos) * pdf * w / ls.pdf);
            let target = ls.distance.is_finite().then_some(&ls.target);
            out.shadow = shadow_ray(r, at, target, ls.wi, f32::INFINITY, contribution).map(|mut s| {
                start_in_medium(ctx, &mut s, outside);
                s
            });
        }
    }
    let u_dir = Vec2::new(
        rng.walk(depth, origin, throughput, BounceDim::BsdfDirection, 0),
        rng.walk(depth, origin, throughput, BounceDim::BsdfDirection, 1),
    );
    let local = sample_cosine_hemisphere(u_dir);
    let wi = Frame::from_z(ns).from_local(local).normalize();
    if local.z <= 0.0 || wi.dot(n_out) <= 0.0 {
        return out;
    }
    // f cos / pdf: the cosine and π cancel.
    let beta = beta * lets_out(local.z);
    let u_roulette = rng.walk(depth, origin, throughput, BounceDim::RussianRoulette, 0);
    let Some(beta) = russian_roulette(ctx, u_roulette, depth, beta, eta_scale) else {
        return out;
    };
    let mut next = continuation(r, at, wi);
    next.throughput = beta.to_array();
    next.eta_scale = pack_eta_scale(eta_scale);
    next.bsdf_pdf = local.z / PI;
    next.flags = 0;
    next.set_medium(outside);
    out.next = Some(next);
    out
}

/// pbrt-v4's `ambientocclusion` with cosine sampling: each unoccluded
/// direction contributes exactly 1 (cos / (π · cos/π)).
fn shade_ambient_occlusion(ctx: &FrameContext, r: &RayRecord, max_distance: f32) -> ShadeOutcome {
    let mut out = ShadeOutcome::default();
    if !r.has(flags::HIT) {
        return out;
    }
    let at = hit_point(r);
    let dir = r.direction();
    if bsdf_from_record(r, &ctx.measured).is_none() {
        out.next = Some(continuation(r, &at, dir));
        return out;
    }
    let ng = if at.normal.dot(dir) > 0.0 { -at.normal } else { at.normal };
    let rng = SampleStream::new(ctx.options.seed, r.pixel, r.sample);
    let u = Vec2::new(rng.bounce(0, BounceDim::BsdfDirection, 0), rng.bounce(0, BounceDim::BsdfDirection, 1));
    let w = Frame::from_z(ng).from_local(sample_cosine_hemisphere(u)).normalize();
    out.shadow = shadow_ray(r, &at, None, w, max_distance, Vec3::ONE);
    out
}
