//! `atoll gen`: procedural scenes, sized up (the default) or written out as
//! PBRT-v4 text that atoll's own loader reads back to an equal scene.

use std::fmt::Display;
use std::io::{self, BufWriter, Write};
use std::path::PathBuf;
use std::time::Instant;

use atoll_scene::landscape::{Landscape, LandscapeEstimate};
use atoll_scene::{
    CoatedDiffuseParams, Coating, IntegratorSettings, Light, Material, Projection, Scene, TriangleMesh,
};
use clap::{Args, Subcommand};
use glam::{Affine3A, Mat4, Vec3};

use crate::CliError;

mod files;

#[derive(Args)]
pub struct GenArgs {
    #[command(subcommand)]
    pub scene: GenScene,
}

#[derive(Subcommand)]
pub enum GenScene {
    /// Terrain with instanced rocks, trees, glass and metal; growth g makes
    /// about g million instanced triangles. Without -o, prints its sizes only
    /// (render it without a file as the scene `landscape:GROWTH[:SEED]`).
    #[command(allow_negative_numbers = true)]
    Landscape(LandscapeArgs),
}

#[derive(Args)]
pub struct LandscapeArgs {
    /// Scale factor: terrain area, instances and instanced triangles grow linearly.
    #[arg(long, default_value_t = 1)]
    pub growth: u32,
    /// Seed of the terrain, rock shapes and placement.
    #[arg(long, default_value_t = 0)]
    pub seed: u32,
    /// Tessellation multiplier of the terrain and objects (triangles, not instances).
    #[arg(long, default_value_t = 1.0)]
    pub detail: f32,
    /// Write the scene here as PBRT-v4 text (with --files: a folder).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Write -o as a folder of files, the way production scenes come:
    /// DIR/scene.pbrt Imports geometry/tile-NNNN.pbrt, one per square tile,
    /// whose meshes are binary PLY files; the objects on a tile are baked
    /// into unique world-space meshes, one PLY per tile and material.
    #[arg(long, requires = "output")]
    pub files: bool,
    /// With --files: tiles along a side [default: about 4 million triangles a tile].
    #[arg(long, requires = "files")]
    pub tiles: Option<u32>,
    /// With --files: keep the objects as instances (ObjectBegin in
    /// scene.pbrt, ObjectInstance in the tiles) instead of baking them.
    #[arg(long, requires = "files")]
    pub instanced: bool,
    /// With --files: gzip the PLY files (.ply.gz, fastest compression).
    #[arg(long, requires = "files")]
    pub gzip: bool,
}

pub fn run(args: GenArgs) -> Result<(), CliError> {
    match args.scene {
        GenScene::Landscape(args) => landscape(args),
    }
}

/// Most `--detail` there may be.
const MAX_DETAIL: f32 = 1000.0;

fn mib(bytes: u64) -> String {
    format!("{:.1} MiB", bytes as f64 / (1024.0 * 1024.0))
}

fn landscape(args: LandscapeArgs) -> Result<(), CliError> {
    if args.growth == 0 {
        return Err(CliError::Input("--growth must be at least 1".into()));
    }
    // Detail multiplies triangle counts: past a thousand, sizes overflow
    // long before any machine could hold the result.
    if !(args.detail > 0.0 && args.detail <= MAX_DETAIL) {
        return Err(CliError::Input(format!(
            "--detail must be above 0 and at most {MAX_DETAIL}, not {}",
            args.detail
        )));
    }
    let landscape = Landscape { growth: args.growth, seed: args.seed, detail: args.detail };
    landscape.check().map_err(CliError::Input)?;
    let e: LandscapeEstimate = landscape.estimate();
    println!("landscape          growth {}, seed {}, detail {}", args.growth, args.seed, args.detail);
    println!("objects            {} ({} meshes)", e.objects, e.meshes);
    println!("instances          {}", e.instances);
    println!("triangles          {} unique, {} instanced", e.unique_triangles, e.instanced_triangles);
    println!(
        "memory estimate    {} ({} meshes + {} instance records; BVH not included)",
        mib(e.bytes),
        mib(e.geometry_bytes),
        mib(e.bytes - e.geometry_bytes)
    );
    let Some(path) = args.output else { return Ok(()) };
    let header =
        format!("atoll gen landscape --growth {} --seed {} --detail {}", args.growth, args.seed, args.detail);
    if args.files {
        let tiles = args.tiles.unwrap_or_else(|| landscape.default_tiles());
        let tiling = landscape.tiling(tiles).map_err(|e| CliError::Input(format!("--tiles: {e}")))?;
        let form = if args.instanced { "objects instanced" } else { "objects baked" };
        let ply = if args.gzip { "gzipped binary PLY" } else { "binary PLY" };
        println!("files              {tiles} x {tiles} tiles of {ply}, {form}");
        let options = files::Options { instanced: args.instanced, gzip: args.gzip };
        let start = Instant::now();
        let written = files::write(&landscape, &tiling, &path, &options, &header)?;
        written.print(&path, start.elapsed().as_secs_f64());
        return Ok(());
    }
    crate::render::check_folder(&path)?;
    crate::load::check_fits_host(&path, e.bytes)?;
    let start = Instant::now();
    let scene = landscape.build();
    let build_seconds = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let file = std::fs::File::create(&path)
        .map_err(|e| CliError::Input(format!("{}: cannot create: {e}", path.display())))?;
    let mut out = BufWriter::with_capacity(1 << 20, file);
    write_pbrt(&scene, &mut out, &header)
        .and_then(|_| out.flush())
        .map_err(|e| CliError::Runtime(format!("{}: cannot write: {e}", path.display())))?;
    let size = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    println!(
        "{}: {} generated in {:.2} s, written in {:.2} s",
        path.display(),
        mib(size),
        build_seconds,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Writes `values` as a bracketed list, a few per line (long lines are
/// awkward in editors; the loader does not care).
fn list<T: Display>(out: &mut impl Write, values: impl IntoIterator<Item = T>) -> io::Result<()> {
    write!(out, "[")?;
    for (i, v) in values.into_iter().enumerate() {
        if i % 24 == 23 {
            write!(out, "\n   ")?;
        }
        write!(out, " {v}")?;
    }
    write!(out, " ]")
}

fn vec3s<'a>(out: &mut impl Write, v: impl IntoIterator<Item = &'a Vec3>) -> io::Result<()> {
    list(out, v.into_iter().flat_map(|p| p.to_array()))
}

/// `Transform`'s 16 numbers: pbrt lists the matrix column by column.
fn matrix(out: &mut impl Write, m: &Mat4) -> io::Result<()> {
    list(out, m.to_cols_array())
}

/// `Shape "trianglemesh"` with the mesh's material (and area light and
/// orientation) in an attribute block.
fn shape(out: &mut impl Write, mesh: &TriangleMesh, world: bool) -> io::Result<()> {
    writeln!(out, "AttributeBegin")?;
    writeln!(out, "  NamedMaterial \"material_{}\"", mesh.material)?;
    // pbrt-v4 ignores area lights in object instances, so they only exist at world level.
    if let (Some(e), true) = (mesh.emission, world) {
        let c = e.radiance;
        writeln!(
            out,
            "  AreaLightSource \"diffuse\" \"rgb L\" [ {} {} {} ] \"bool twosided\" {}",
            c.x, c.y, c.z, e.two_sided
        )?;
    }
    // ReverseOrientation flips the geometric normal but also negates the
    // shading normals as they are read, so those are written negated.
    let sign = if mesh.flip_normals { -1.0 } else { 1.0 };
    if mesh.flip_normals {
        writeln!(out, "  ReverseOrientation")?;
    }
    if let Some(curves) = &mesh.curves {
        curve_shapes(out, curves)?;
        return writeln!(out, "AttributeEnd");
    }
    writeln!(out, "  # {}: {} triangles", mesh.name, mesh.triangle_count())?;
    write!(out, "  Shape \"trianglemesh\"\n    \"point3 P\" ")?;
    vec3s(out, &mesh.positions)?;
    if !mesh.normals.is_empty() {
        write!(out, "\n    \"normal N\" ")?;
        list(out, mesh.normals.iter().flat_map(|n| (*n * sign).to_array()))?;
    }
    if !mesh.uvs.is_empty() {
        write!(out, "\n    \"point2 uv\" ")?;
        list(out, mesh.uvs.iter().flat_map(|uv| uv.to_array()))?;
    }
    write!(out, "\n    \"integer indices\" ")?;
    list(out, mesh.indices.iter().flatten())?;
    writeln!(out, "\nAttributeEnd")
}

/// A curve mesh as one `Shape "curve"` per piece (`splitdepth` 0), its
/// widths and ribbon normals those at the piece's ends: the same surface,
/// though `u` now runs along each piece rather than its segment.
fn curve_shapes(out: &mut impl Write, curves: &atoll_scene::Curves) -> io::Result<()> {
    let kind = match curves.kind {
        atoll_scene::CurveKind::Flat => "flat",
        atoll_scene::CurveKind::Cylinder => "cylinder",
        atoll_scene::CurveKind::Ribbon => "ribbon",
    };
    writeln!(out, "  # {} curve pieces", curves.pieces.len())?;
    for piece in &curves.pieces {
        let [w0, w1] = piece.u.map(|u| piece.width_at(u));
        write!(out, "  Shape \"curve\" \"string type\" \"{kind}\" \"integer splitdepth\" 0 \"point3 P\" ")?;
        vec3s(out, &piece.points)?;
        write!(out, " \"float width0\" {w0} \"float width1\" {w1}")?;
        if curves.kind == atoll_scene::CurveKind::Ribbon {
            let n = piece.u.map(|u| Vec3::from(piece.ribbon_normal(u)));
            write!(out, " \"normal N\" ")?;
            vec3s(out, &n)?;
        }
        writeln!(out)?;
    }
    Ok(())
}

/// Writes material `id`; a measured one names its file as the scene did, so
/// the text reads back beside the same `.bsdf` files.
fn material(out: &mut impl Write, id: usize, m: &Material, scene: &Scene) -> io::Result<()> {
    write!(out, "MakeNamedMaterial \"material_{id}\" ")?;
    // Roughness is stored as GGX alpha already: no remapping on the way back.
    let rough = |ax: f32, ay: f32| {
        format!("\"float uroughness\" [ {ax} ] \"float vroughness\" [ {ay} ] \"bool remaproughness\" false")
    };
    let rgb = |c: Vec3| format!("[ {} {} {} ]", c.x, c.y, c.z);
    let medium = |c: &Coating| {
        format!(
            "\"float thickness\" [ {} ] \"rgb albedo\" {} \"float g\" [ {} ] \"integer maxdepth\" [ {} ] \
             \"integer nsamples\" [ {} ]",
            c.thickness,
            rgb(c.albedo),
            c.g,
            c.max_depth,
            c.n_samples
        )
    };
    match m {
        Material::Diffuse { reflectance } => {
            writeln!(out, "\"string type\" \"diffuse\" \"rgb reflectance\" {}", rgb(*reflectance))
        }
        Material::Conductor { eta, k, alpha_x, alpha_y } => writeln!(
            out,
            "\"string type\" \"conductor\" \"rgb eta\" {} \"rgb k\" {} {}",
            rgb(*eta),
            rgb(*k),
            rough(*alpha_x, *alpha_y)
        ),
        Material::Dielectric { eta, alpha_x, alpha_y } => writeln!(
            out,
            "\"string type\" \"dielectric\" \"float eta\" [ {eta} ] {}",
            rough(*alpha_x, *alpha_y)
        ),
        Material::Interface => writeln!(out, "\"string type\" \"interface\""),
        Material::DiffuseTransmission { reflectance, transmittance } => writeln!(
            out,
            "\"string type\" \"diffusetransmission\" \"rgb reflectance\" {} \"rgb transmittance\" {}",
            rgb(*reflectance),
            rgb(*transmittance)
        ),
        Material::ThinDielectric { eta } => {
            writeln!(out, "\"string type\" \"thindielectric\" \"float eta\" [ {eta} ]")
        }
        Material::CoatedDiffuse(CoatedDiffuseParams { reflectance, coating: c }) => writeln!(
            out,
            "\"string type\" \"coateddiffuse\" \"rgb reflectance\" {} {} \"float eta\" [ {} ] {}",
            rgb(*reflectance),
            rough(c.alpha_x, c.alpha_y),
            c.eta,
            medium(c),
        ),
        Material::CoatedConductor(p) => writeln!(
            out,
            "\"string type\" \"coatedconductor\" \"rgb conductor.eta\" {} \"rgb conductor.k\" {} \
             \"float conductor.uroughness\" [ {} ] \"float conductor.vroughness\" [ {} ] \
             \"float interface.uroughness\" [ {} ] \"float interface.vroughness\" [ {} ] \
             \"bool remaproughness\" false \"float interface.eta\" [ {} ] {}",
            rgb(p.eta),
            rgb(p.k),
            p.alpha_x,
            p.alpha_y,
            p.coating.alpha_x,
            p.coating.alpha_y,
            p.coating.eta,
            medium(&p.coating),
        ),
        // pbrt-v4 has no principled material: pbrt-v3's `disney` (which
        // atoll reads in either version) with its parameters, plus atoll's
        // `specular` (pbrt-v3 derives it from `eta`).
        Material::Principled(p) => writeln!(
            out,
            "\"string type\" \"disney\" \"rgb color\" {} \"float metallic\" [ {} ] \
             \"float roughness\" [ {} ] \"float specular\" [ {} ] \
             \"float speculartint\" [ {} ] \"float sheen\" [ {} ] \
             \"float sheentint\" [ {} ] \"float clearcoat\" [ {} ] \
             \"float clearcoatgloss\" [ {} ] \"float spectrans\" [ {} ] \
             \"float eta\" [ {} ]",
            rgb(p.base_color),
            p.metallic,
            p.roughness,
            p.specular,
            p.specular_tint,
            p.sheen,
            p.sheen_tint,
            p.clearcoat,
            p.clearcoat_gloss,
            p.transmission,
            p.eta
        ),
        Material::Hair(h) => writeln!(
            out,
            "\"string type\" \"hair\" \"rgb sigma_a\" {} \"float eta\" [ {} ] \"float beta_m\" [ {} ] \
             \"float beta_n\" [ {} ] \"float alpha\" [ {} ]",
            rgb(h.sigma_a),
            h.eta,
            h.beta_m,
            h.beta_n,
            h.alpha
        ),
        // Materials are written in id order, so a mix's parts come first
        // whenever they have smaller ids (as loaders make them).
        Material::Mix { materials: [a, b], amount } => writeln!(
            out,
            "\"string type\" \"mix\" \"string materials\" [ \"material_{a}\" \"material_{b}\" ] \"float amount\" [ {amount} ]"
        ),
        Material::Measured { brdf } => writeln!(
            out,
            "\"string type\" \"measured\" \"string filename\" \"{}\"",
            scene.measured[*brdf as usize].filename
        ),
        Material::Subsurface(p) => writeln!(
            out,
            "\"string type\" \"subsurface\" \"rgb sigma_a\" {} \"rgb sigma_s\" {} \"float g\" [ {} ] \"float eta\" [ {} ] {}",
            rgb(p.interior.sigma_a),
            rgb(p.interior.sigma_s),
            p.interior.g,
            p.eta,
            rough(p.alpha_x, p.alpha_y)
        ),
    }
}

/// Writes `scene` as PBRT-v4 text: options (camera, film, sampler,
/// integrator), lights, named materials, world-level meshes, object
/// definitions and their instances. An object named "world" with one
/// identity instance (what loaders make of world-level shapes) is written at
/// world level; every other object as `ObjectBegin`/`ObjectEnd` plus one
/// `Transform`/`ObjectInstance` pair per instance. Reading the text back
/// with atoll's loader gives the same meshes, objects, instances and
/// materials in the same order (materials are numbered by first use there,
/// so a scene whose meshes use them in id order keeps its ids).
pub fn write_pbrt(scene: &Scene, out: &mut impl Write, header: &str) -> io::Result<()> {
    write_prelude(scene, out, header)?;
    write_geometry(scene, out)
}

/// The start of [`write_pbrt`]'s text: options, `WorldBegin`, lights and
/// named materials (`material_ID`); geometry may follow.
fn write_prelude(scene: &Scene, out: &mut impl Write, header: &str) -> io::Result<()> {
    let s = &scene.settings;
    writeln!(out, "# {header}")?;
    // f64 on the way out and in, so the loader's inverse gives back camera_to_world.
    // pbrt has one pair of transform times per file, which the camera
    // takes where it is stated: the camera's motion's, or the first one's.
    let first_motion = s.camera.motion.as_ref().or(scene.motions.first());
    if let Some(m) = first_motion.filter(|m| m.times != [0.0, 1.0]) {
        writeln!(out, "TransformTimes {} {}", m.times[0], m.times[1])?;
    }
    let world_to_camera = s.camera.camera_to_world.as_dmat4().inverse();
    write!(out, "Transform ")?;
    list(out, world_to_camera.to_cols_array())?;
    if let Some(m) = &s.camera.motion {
        let end = glam::Mat4::from(m.end.matrix()).as_dmat4().inverse();
        write!(out, "\nActiveTransform EndTime Transform ")?;
        list(out, end.to_cols_array())?;
        write!(out, " ActiveTransform All")?;
    }
    match s.camera.projection {
        Projection::Perspective => {
            write!(out, "\nCamera \"perspective\" \"float fov\" [ {} ]", s.camera.fov_degrees)?
        }
        Projection::Orthographic => write!(out, "\nCamera \"orthographic\"")?,
        Projection::Spherical { mapping } => {
            let mapping = match mapping {
                atoll_scene::EnvLayout::EqualArea => "equalarea",
                atoll_scene::EnvLayout::LatLong => "equirectangular",
            };
            write!(out, "\nCamera \"spherical\" \"string mapping\" \"{mapping}\"")?
        }
        // A lens file is not written beside a stream: the camera is kept
        // as a pinhole through the film's centre.
        Projection::Realistic => write!(
            out,
            "\n# a realistic camera's lens system is not written back: a perspective camera stands in\n\
             Camera \"perspective\" \"float fov\" [ {} ]",
            s.camera.fov_degrees
        )?,
    }
    if let Some(window) = s.camera.screen_window {
        write!(out, " \"float screenwindow\" ")?;
        list(out, window)?;
    }
    if let Some(frame) = s.camera.frame_aspect_ratio {
        write!(out, " \"float frameaspectratio\" [ {frame} ]")?;
    }
    if s.camera.lens_radius > 0.0 {
        let c = &s.camera;
        write!(
            out,
            " \"float lensradius\" [ {} ] \"float focaldistance\" [ {} ]",
            c.lens_radius, c.focal_distance
        )?;
    }
    if s.camera.shutter != [0.0, 1.0] {
        let [open, close] = s.camera.shutter;
        write!(out, " \"float shutteropen\" [ {open} ] \"float shutterclose\" [ {close} ]")?;
    }
    let res = s.film.resolution;
    write!(
        out,
        "\nFilm \"rgb\" \"integer xresolution\" [ {} ] \"integer yresolution\" [ {} ]",
        res.x, res.y
    )?;
    if let Some(name) = &s.film.filename {
        write!(out, " \"string filename\" \"{}\"", name.replace('\\', "\\\\").replace('"', "\\\""))?;
    }
    writeln!(out, "\nSampler \"zsobol\" \"integer pixelsamples\" [ {} ]", s.spp)?;
    match s.integrator {
        IntegratorSettings::Path { max_depth } => {
            writeln!(out, "Integrator \"path\" \"integer maxdepth\" [ {max_depth} ]")?
        }
        IntegratorSettings::AmbientOcclusion { max_distance } if max_distance.is_finite() => {
            writeln!(out, "Integrator \"ambientocclusion\" \"float maxdistance\" [ {max_distance} ]")?
        }
        IntegratorSettings::AmbientOcclusion { .. } => writeln!(out, "Integrator \"ambientocclusion\"")?,
    }
    writeln!(out, "\nWorldBegin")?;
    let v = |c: Vec3| format!("[ {} {} {} ]", c.x, c.y, c.z);
    for light in &scene.lights {
        match light {
            Light::Point { position, intensity } => writeln!(
                out,
                "LightSource \"point\" \"point3 from\" {} \"rgb I\" {}",
                v(*position),
                v(*intensity)
            )?,
            Light::Distant { direction, radiance } => writeln!(
                out,
                "LightSource \"distant\" \"point3 from\" [ 0 0 0 ] \"point3 to\" {} \"rgb L\" {}",
                v(*direction),
                v(*radiance)
            )?,
            Light::Infinite { radiance, portal } => {
                writeln!(out, "LightSource \"infinite\" \"rgb L\" {}{}", v(*radiance), portal_text(portal))?
            }
            Light::Environment { image, scale, portal, .. } => {
                // The image itself is not written out: its mean stands in.
                let mean = image.pixels.iter().copied().sum::<Vec3>() / image.pixels.len().max(1) as f32;
                writeln!(
                    out,
                    "# environment image ({}x{}) written as its mean radiance",
                    image.width, image.height
                )?;
                writeln!(
                    out,
                    "LightSource \"infinite\" \"rgb L\" {}{}",
                    v(mean * *scale),
                    portal_text(portal)
                )?
            }
            Light::Goniometric { position, intensity, map, .. } => {
                // The map itself is not written out: its mean stands in.
                writeln!(
                    out,
                    "# goniometric light ({0}x{0} map) written as a point light of its mean intensity",
                    map.resolution
                )?;
                writeln!(
                    out,
                    "LightSource \"point\" \"point3 from\" {} \"rgb I\" {}",
                    v(*position),
                    v(*intensity * map.mean())
                )?
            }
            Light::Projection { position, world_to_light, scale, image } => {
                // The image is not written out: a spot light over the
                // frustum's corners, of its mean colour, stands in.
                let axis = (world_to_light.inverse() * Vec3::Z).normalize();
                let corner = (image.half_screen() * image.tan_half_fov).length();
                let cone_angle = corner.atan().to_degrees();
                let n = image.pixels.len().max(1) as f32;
                let mean = image.pixels.iter().copied().sum::<Vec3>() / n;
                writeln!(
                    out,
                    "# projection light ({}x{} image) written as a spot light of its mean colour",
                    image.width, image.height
                )?;
                writeln!(
                    out,
                    "LightSource \"spot\" \"point3 from\" {} \"point3 to\" {} \"rgb I\" {} \"float coneangle\" [ {cone_angle} ] \"float conedelta\" [ 0 ]",
                    v(*position),
                    v(*position + axis),
                    v(mean * *scale)
                )?
            }
            Light::Spot { position, direction, intensity, cos_falloff_start, cos_falloff_end } => {
                let cone_angle = cos_falloff_end.clamp(-1.0, 1.0).acos().to_degrees();
                let cone_delta = cone_angle - cos_falloff_start.clamp(-1.0, 1.0).acos().to_degrees();
                writeln!(
                    out,
                    "LightSource \"spot\" \"point3 from\" {} \"point3 to\" {} \"rgb I\" {} \"float coneangle\" [ {cone_angle} ] \"float conedelta\" [ {cone_delta} ]",
                    v(*position),
                    v(*position + *direction),
                    v(*intensity)
                )?
            }
        }
    }
    for (id, m) in scene.materials.iter().enumerate() {
        material(out, id, m, scene)?;
    }
    Ok(())
}

/// The geometry of [`write_pbrt`]'s text: world-level meshes, object
/// definitions and their instances.
fn write_geometry(scene: &Scene, out: &mut impl Write) -> io::Result<()> {
    let mut uses = vec![0usize; scene.objects.len()];
    for inst in &scene.instances {
        uses[inst.object as usize] += 1;
    }
    let mut world_level: Vec<bool> = scene.objects.iter().map(|o| o.name == "world").collect();
    for inst in &scene.instances {
        let o = inst.object as usize;
        world_level[o] &= uses[o] == 1 && inst.object_to_world == Affine3A::IDENTITY && inst.motion.is_none();
    }
    for (_, object) in scene.objects.iter().enumerate().filter(|&(o, _)| world_level[o]) {
        for &m in &object.meshes {
            shape(out, &scene.meshes[m as usize], true)?;
        }
    }
    // Names must be unique in the file: keep unique ones, number the rest.
    let names: Vec<String> = scene
        .objects
        .iter()
        .enumerate()
        .map(|(o, object)| {
            let n = &object.name;
            let unique = !n.is_empty() && scene.objects.iter().filter(|other| &other.name == n).count() == 1;
            if unique && !n.contains(['"', '\\']) {
                n.clone()
            } else {
                format!("object_{o}")
            }
        })
        .collect();
    for (o, object) in scene.objects.iter().enumerate().filter(|&(o, _)| !world_level[o]) {
        writeln!(out, "ObjectBegin \"{}\"", names[o])?;
        for &m in &object.meshes {
            shape(out, &scene.meshes[m as usize], false)?;
        }
        writeln!(out, "ObjectEnd")?;
    }
    writeln!(out, "AttributeBegin")?;
    for inst in scene.instances.iter().filter(|i| !world_level[i.object as usize]) {
        write!(out, "  Transform ")?;
        matrix(out, &Mat4::from(inst.object_to_world))?;
        if let Some(m) = inst.motion {
            write!(out, " ActiveTransform EndTime Transform ")?;
            matrix(out, &Mat4::from(scene.motions[m as usize].end.matrix()))?;
            write!(out, " ActiveTransform All")?;
        }
        writeln!(out, " ObjectInstance \"{}\"", names[inst.object as usize])?;
    }
    writeln!(out, "AttributeEnd")
}

/// An infinite light's `portal` parameter (world-space corners: lights are
/// written outside any transform), or nothing.
fn portal_text(portal: &Option<atoll_scene::Portal>) -> String {
    let Some(p) = portal else { return String::new() };
    let corners: Vec<String> = p.corners.iter().map(|c| format!("{} {} {}", c.x, c.y, c.z)).collect();
    format!(" \"point3 portal\" [ {} ]", corners.join("  "))
}

#[cfg(test)]
mod tests {
    use super::*;
    use atoll_scene::{CoatedConductorParams, PrincipledParams};

    /// Writes `scene`, reads it back with atoll's PBRT loader (no warnings
    /// allowed: every parameter written must be understood; the loader's
    /// note that a coated conductor's anisotropy turns about the normal
    /// alone is about rendering, not about the text).
    fn round_trip(scene: &Scene) -> Scene {
        let mut text = Vec::new();
        write_pbrt(scene, &mut text, "test").unwrap();
        let text = String::from_utf8(text).unwrap();
        let loaded = atoll_scene::pbrt::load_str(&text, "gen.pbrt", std::path::Path::new(".")).unwrap();
        let warnings: Vec<_> =
            loaded.warnings.iter().filter(|w| !w.message.contains("anisotropic roughness of")).collect();
        assert!(warnings.is_empty(), "{warnings:?}");
        loaded.scene
    }

    fn close(a: Vec3, b: Vec3, tolerance: f32) -> bool {
        (a - b).abs().max_element() <= tolerance * (1.0 + a.abs().max_element())
    }

    /// Counts equal, bounds within 1e-4 relative, and mesh by mesh the same
    /// vertices, materials, emission and orientation; instance by instance
    /// the same object and transform.
    fn assert_equal(a: &Scene, b: &Scene) {
        let (sa, sb) = (a.stats(), b.stats());
        assert_eq!(
            (sa.meshes, sa.objects, sa.instances, sa.unique_triangles, sa.instanced_triangles),
            (sb.meshes, sb.objects, sb.instances, sb.unique_triangles, sb.instanced_triangles)
        );
        assert_eq!(
            (sa.materials, sa.lights, sa.emissive_triangles),
            (sb.materials, sb.lights, sb.emissive_triangles)
        );
        let extent = (sa.bounds_max - sa.bounds_min).max_element();
        assert!((sa.bounds_min - sb.bounds_min).abs().max_element() <= 1e-4 * extent, "{sa:?} {sb:?}");
        assert!((sa.bounds_max - sb.bounds_max).abs().max_element() <= 1e-4 * extent, "{sa:?} {sb:?}");
        for (m, n) in a.meshes.iter().zip(&b.meshes) {
            assert_eq!((&m.indices, m.emission, m.flip_normals), (&n.indices, n.emission, n.flip_normals));
            assert_eq!(a.materials[m.material as usize], b.materials[n.material as usize]);
            assert_eq!(
                (m.positions.len(), m.normals.len(), m.uvs.len()),
                (n.positions.len(), n.normals.len(), n.uvs.len())
            );
            assert!(m.positions.iter().zip(&n.positions).all(|(p, q)| close(*p, *q, 1e-6)), "{}", m.name);
            assert!(m.normals.iter().zip(&n.normals).all(|(p, q)| close(*p, *q, 1e-5)), "{}", m.name);
        }
        for (o, p) in a.objects.iter().zip(&b.objects) {
            assert_eq!((&o.name, &o.meshes), (&p.name, &p.meshes));
        }
        for (i, j) in a.instances.iter().zip(&b.instances) {
            assert_eq!(i.object, j.object);
            assert!(i.object_to_world.abs_diff_eq(j.object_to_world, 1e-5), "{i:?} {j:?}");
            let motion = |s: &Scene, m: Option<u32>| m.map(|m| s.motions[m as usize]);
            match (motion(a, i.motion), motion(b, j.motion)) {
                (None, None) => {}
                (Some(p), Some(q)) => {
                    assert_eq!(p.times, q.times);
                    for t in [0.0, 0.3, 0.7, 1.0].map(|s| p.times[0] + s * (p.times[1] - p.times[0])) {
                        assert!(p.at(t).abs_diff_eq(q.at(t), 1e-4), "{p:?} {q:?}");
                    }
                }
                (p, q) => panic!("motions differ: {p:?} {q:?}"),
            }
        }
        let (ca, cb) = (&a.settings.camera, &b.settings.camera);
        assert!(ca.camera_to_world.abs_diff_eq(cb.camera_to_world, 1e-4), "{ca:?} {cb:?}");
        // An orthographic camera has no field of view.
        let fov =
            |c: &atoll_scene::Camera| (c.projection == Projection::Perspective).then_some(c.fov_degrees);
        assert_eq!(
            (ca.projection, fov(ca), ca.lens_radius, ca.screen_window, ca.frame_aspect_ratio),
            (cb.projection, fov(cb), cb.lens_radius, cb.screen_window, cb.frame_aspect_ratio)
        );
        let (sa, sb) = (&a.settings, &b.settings);
        assert_eq!(
            (sa.film.resolution, sa.spp, &sa.integrator),
            (sb.film.resolution, sb.spp, &sb.integrator)
        );
        for (l, m) in a.lights.iter().zip(&b.lights) {
            match (l, m) {
                (
                    Light::Distant { direction: d, radiance: r },
                    Light::Distant { direction: e, radiance: s },
                ) => {
                    assert!(close(*d, *e, 1e-6) && r == s)
                }
                _ => assert_eq!(l, m),
            }
        }
    }

    /// Curves come back as one curve per piece: the same control points,
    /// widths at the pieces' ends, ribbon normals and orientation.
    #[test]
    fn curves_round_trip_as_their_pieces() {
        let text = "LookAt 0 0 5 0 0 0 0 1 0\nCamera \"perspective\"\nWorldBegin\n\
            Shape \"curve\" \"string type\" \"cylinder\" \"point3 P\" [0 0 0 1 1 0 2 -1 0 3 0 1] \"float width0\" 0.3 \"float width1\" 0.1\n\
            ReverseOrientation\n\
            Shape \"curve\" \"string type\" \"ribbon\" \"point3 P\" [0 0 0 1 0 0 2 0 0 3 0 0] \"normal N\" [0 1 0 0 0 1] \"integer splitdepth\" 1\n";
        let scene = atoll_scene::pbrt::load_str(text, "c.pbrt", std::path::Path::new(".")).unwrap().scene;
        let back = round_trip(&scene);
        let pieces = |s: &Scene| -> Vec<(atoll_scene::CurveKind, atoll_scene::CurvePiece, bool)> {
            s.meshes
                .iter()
                .flat_map(|m| {
                    let c = m.curves.as_ref().unwrap();
                    c.pieces.iter().map(move |p| (c.kind, *p, m.flip_normals))
                })
                .collect()
        };
        let (a, b) = (pieces(&scene), pieces(&back));
        assert_eq!((a.len(), b.len()), (10, 10));
        for ((ka, pa, fa), (kb, pb, fb)) in a.iter().zip(&b) {
            assert_eq!((ka, fa), (kb, fb));
            assert!(pa.points.iter().zip(&pb.points).all(|(p, q)| close(*p, *q, 1e-6)));
            for (ua, ub) in pa.u.iter().zip(pb.u) {
                assert!((pa.width_at(*ua) - pb.width_at(ub)).abs() < 1e-6);
                let (na, nb) = (Vec3::from(pa.ribbon_normal(*ua)), Vec3::from(pb.ribbon_normal(ub)));
                assert!(*ka != atoll_scene::CurveKind::Ribbon || close(na, nb, 1e-5), "{na} {nb}");
            }
        }
    }

    #[test]
    fn landscape_round_trips_through_pbrt_text() {
        let scene = Landscape { growth: 1, seed: 3, detail: 0.5 }.build();
        let back = round_trip(&scene);
        assert_equal(&scene, &back);
        // Materials keep their ids too: the landscape's meshes use them in id order.
        assert_eq!(scene.materials, back.materials);
        assert!(scene.meshes.iter().zip(&back.meshes).all(|(m, n)| m.material == n.material));
    }

    /// A portal is written in world space and read back the same.
    #[test]
    fn infinite_light_portals_round_trip() {
        let mut scene = atoll_scene::cornell::builtin_cornell_box();
        let corners = [
            Vec3::new(0.5, 0.25, -1.0),
            Vec3::new(0.5, 1.5, -1.0),
            Vec3::new(-0.5, 1.5, -1.0),
            Vec3::new(-0.5, 0.25, -1.0),
        ];
        let portal = Some(atoll_scene::Portal::new(corners).unwrap());
        scene.lights.push(Light::Infinite { radiance: Vec3::splat(0.5), portal });
        let back = round_trip(&scene);
        assert!(back.lights.contains(&scene.lights[0]), "{:?}", back.lights);
    }

    #[test]
    fn cornell_box_round_trips_with_its_area_light() {
        let scene = atoll_scene::cornell::builtin_cornell_box();
        assert!(scene.stats().emissive_triangles > 0);
        assert_equal(&scene, &round_trip(&scene));
        // An orthographic camera with a screen window and a frame ratio.
        let mut ortho = scene.clone();
        ortho.settings.camera.projection = Projection::Orthographic;
        ortho.settings.camera.screen_window = Some([-1.25, 0.75, -1.0, 1.5]);
        ortho.settings.camera.frame_aspect_ratio = Some(1.5);
        assert_equal(&ortho, &round_trip(&ortho));
        let mut sphere = scene.clone();
        sphere.settings.camera.projection =
            Projection::Spherical { mapping: atoll_scene::EnvLayout::LatLong };
        assert_equal(&sphere, &round_trip(&sphere));
    }

    #[test]
    fn coated_materials_round_trip() {
        let mut scene = atoll_scene::cornell::builtin_cornell_box();
        let coating = Coating {
            eta: 1.33,
            alpha_x: 0.1,
            alpha_y: 0.35,
            thickness: 0.25,
            albedo: Vec3::new(0.9, 0.5, 0.1),
            g: -0.4,
            max_depth: 17,
            n_samples: 3,
        };
        scene.materials[0] =
            Material::CoatedDiffuse(CoatedDiffuseParams { reflectance: Vec3::new(0.2, 0.4, 0.6), coating });
        let (max_depth, n_samples) = Material::COATED_CONDUCTOR_WALK;
        scene.materials[1] = Material::CoatedConductor(CoatedConductorParams {
            eta: Vec3::new(0.2, 0.9, 1.1),
            k: Vec3::new(3.9, 2.5, 2.1),
            alpha_x: 0.05,
            alpha_y: 0.15,
            coating: Coating { max_depth, n_samples, ..coating },
        });
        let back = round_trip(&scene);
        assert_equal(&scene, &back);
        assert!(back.materials.contains(&scene.materials[0]));
        assert!(back.materials.contains(&scene.materials[1]));
    }

    /// pbrt-v4 has no principled material: it is written as pbrt-v3's
    /// `disney` (plus atoll's `specular`) and read back exactly, silently.
    #[test]
    fn principled_materials_round_trip_as_disney() {
        let mut scene = atoll_scene::cornell::builtin_cornell_box();
        let principled = Material::Principled(PrincipledParams {
            base_color: Vec3::new(0.8, 0.5, 0.2),
            metallic: 0.25,
            roughness: 0.3,
            specular: 0.7,
            specular_tint: 0.5,
            sheen: 0.75,
            sheen_tint: 0.25,
            clearcoat: 0.5,
            clearcoat_gloss: 0.6,
            transmission: 0.4,
            eta: 1.33,
        });
        let id = scene.meshes[0].material as usize;
        scene.materials[id] = principled.clone();
        let back = round_trip(&scene);
        assert_equal(&scene, &back);
        assert_eq!(back.materials[back.meshes[0].material as usize], principled);
    }

    #[test]
    fn mirrored_instances_and_reversed_meshes_round_trip() {
        let mut scene = Landscape { growth: 1, seed: 0, detail: 0.2 }.build();
        scene.instances.truncate(20);
        scene.instances[3].object_to_world =
            Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0)) * scene.instances[3].object_to_world;
        scene.meshes[2].flip_normals = true;
        scene.settings.integrator = IntegratorSettings::AmbientOcclusion { max_distance: 3.0 };
        scene.lights.push(Light::Point { position: Vec3::new(1.0, 2.0, 3.0), intensity: Vec3::splat(4.0) });
        assert_equal(&scene, &round_trip(&scene));
    }

    #[test]
    fn moving_instances_and_the_shutter_round_trip() {
        let mut scene = Landscape { growth: 1, seed: 0, detail: 0.2 }.build();
        scene.instances.truncate(20);
        let start = scene.instances[5].object_to_world;
        let end =
            Affine3A::from_rotation_y(1.0) * Affine3A::from_translation(Vec3::new(0.0, 2.0, 0.0)) * start;
        let motion =
            atoll_scene::Motion::new(&Mat4::from(start).as_dmat4(), &Mat4::from(end).as_dmat4(), [0.25, 2.0])
                .unwrap();
        scene.motions.push(motion);
        scene.instances[5].motion = Some(0);
        scene.settings.camera.shutter = [0.5, 1.5];
        let camera = scene.settings.camera.camera_to_world.as_dmat4();
        let camera_end = glam::DMat4::from_translation(glam::DVec3::X) * camera;
        scene.settings.camera.motion = atoll_scene::Motion::new(&camera, &camera_end, [0.25, 2.0]);
        let back = round_trip(&scene);
        assert_equal(&scene, &back);
        assert_eq!(back.settings.camera.shutter, [0.5, 1.5]);
        assert_eq!(back.motions.len(), 1);
        let (a, b) = (scene.settings.camera.motion.unwrap(), back.settings.camera.motion.unwrap());
        assert_eq!(a.times, b.times);
        assert!(a.at(1.0).abs_diff_eq(b.at(1.0), 1e-4), "{a:?} {b:?}");
    }
}
