//! Runs PBRT directives against pbrt-v4's graphics state and builds the
//! [`Scene`] (`BasicSceneBuilder` in pbrt-v4's `scene.cpp`).
//!
//! The rules that matter for geometry, as pbrt-v4 has them:
//! - Transform directives post-multiply the CTM (`ctm = ctm * T`).
//! - A shape's vertices go through the CTM in effect at its `Shape`, inside
//!   `ObjectBegin` too; an `ObjectInstance` places the object with the CTM in
//!   effect at the instance. World shapes are stored in world space in the
//!   world object (object 0, one identity instance).
//! - `flip_normals` = `ReverseOrientation` XOR "the CTM swaps handedness";
//!   shading normals go through the inverse transpose and are negated under
//!   `ReverseOrientation`.
//! - Named materials and object instances are resolved at the end, so they
//!   may be used before they are defined.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Affine3A, DMat4, DVec3};

use crate::error::{FileLoc, SceneError};
use crate::input::LoadPhase;
use crate::{
    AlphaMode, AreaEmission, Instance, IntegratorSettings, LightSampler, Material, MaterialId, MeshAlpha,
    MeshId, Object, Rgb, Scene, TexInput, Texture, TextureBinding, TextureId, TexturedParam,
};

use super::ahead::{Included, Next, Source};
use super::params::{Param, ParamList, ParamType};
use super::parser::{Directive, EntityKind, Parser, RawParam, Statement};
use super::pending::{PendingShape, ShapePlace};
use super::shapes::{self, ShapeSource};
use super::textures::{NamedTextures, TexCtx, TextureSite};
use super::tokenizer::Tokenizer;
use super::{entities, spectrum, transform, LoadedScene, WarningSink};

/// Which material the graphics state refers to.
#[derive(Clone, Debug)]
enum MaterialRef {
    /// None set yet: pbrt's default diffuse 0.5.
    Default,
    /// Index into `Builder::anonymous` (a `Material` directive).
    Anonymous(usize),
    /// `NamedMaterial`, resolved when a shape uses it (or at the end).
    Named(String, FileLoc),
}

/// Which of pbrt's two motion-blur transforms the transform directives change.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ActiveTransform {
    All,
    Start,
    End,
}

/// pbrt's `GraphicsState`: what `AttributeBegin` saves and `AttributeEnd` restores.
#[derive(Clone, Debug)]
struct GraphicsState {
    /// The current transform: at the start of the motion, and at its end
    /// (the same where nothing moves).
    ctm: DMat4,
    ctm_end: DMat4,
    active: ActiveTransform,
    reverse_orientation: bool,
    material: MaterialRef,
    area_light: Option<AreaEmission>,
    /// The area light's emission image (`filename`), as a texture.
    area_light_texture: Option<crate::TextureId>,
    shape_attributes: Vec<Param>,
    light_attributes: Vec<Param>,
    material_attributes: Vec<Param>,
    /// `MediumInterface`'s inside and outside medium names ("" is vacuum)
    /// and where it was given.
    media: (String, String, Option<FileLoc>),
}

impl Default for GraphicsState {
    fn default() -> Self {
        GraphicsState {
            ctm: DMat4::IDENTITY,
            ctm_end: DMat4::IDENTITY,
            active: ActiveTransform::All,
            reverse_orientation: false,
            material: MaterialRef::Default,
            area_light: None,
            area_light_texture: None,
            shape_attributes: Vec::new(),
            light_attributes: Vec::new(),
            material_attributes: Vec::new(),
            media: Default::default(),
        }
    }
}

/// Why a graphics state was pushed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Block {
    Attribute,
    Object,
}

/// An `ObjectBegin` definition.
struct ObjectDef {
    name: String,
    meshes: Vec<MeshId>,
}

/// A material waiting for its id until a shape uses it.
struct MaterialSlot {
    material: Material,
    /// Its texture bindings: (parameter, texture, remap roughness).
    bindings: Vec<(TexturedParam, TextureId, bool)>,
    id: Option<MaterialId>,
}

impl MaterialSlot {
    /// The material's id, adding it and its bindings to `scene` on first use.
    fn id(&mut self, scene: &mut Scene) -> MaterialId {
        if let Some(id) = self.id {
            return id;
        }
        let material = scene.add_material(self.material.clone());
        for &(param, texture, remap_roughness) in &self.bindings {
            scene.textures.bind(TextureBinding { material, param, texture, remap_roughness });
        }
        self.id = Some(material);
        material
    }
}

/// Loader state for one scene.
pub struct Builder {
    base_dir: PathBuf,
    scene: Scene,
    warnings: WarningSink,
    gs: GraphicsState,
    pushed: Vec<(GraphicsState, Block, FileLoc)>,
    /// `CoordinateSystem`s: both transforms of the motion.
    named_coordinate_systems: HashMap<String, (DMat4, DMat4)>,
    /// `TransformTimes`: when the start and end transforms hold.
    transform_times: [f32; 2],
    in_world: bool,
    /// Open files, innermost last, each read ahead ([`super::ahead`]).
    sources: Vec<Source>,
    anonymous: Vec<MaterialSlot>,
    named_materials: HashMap<String, MaterialSlot>,
    default_material: Option<MaterialId>,
    /// Meshes whose `NamedMaterial` was not defined yet when they were created.
    pending_materials: Vec<(MeshId, String, FileLoc)>,
    /// The first subsurface material's place, for an error in giving the
    /// subsurface materials their interiors.
    subsurface_at: Option<FileLoc>,
    /// Shapes whose triangles are made at the end, in parallel.
    pending_shapes: Vec<PendingShape>,
    world_meshes: Vec<MeshId>,
    objects: Vec<ObjectDef>,
    object_names: HashMap<String, usize>,
    active_object: Option<usize>,
    /// `ObjectInstance`s: the object, the transforms at the motion's start
    /// and end, and where.
    instance_uses: Vec<(String, DMat4, DMat4, FileLoc)>,
    warned_transform_begin: bool,
    /// Named float and spectrum textures, and the decoded images.
    textures: NamedTextures,
    /// Unsupported shape types: how many were skipped, and where the first was.
    skipped_shapes: Vec<(String, u64, FileLoc)>,
    /// pbrt-v3 spellings already warned about.
    v3_spellings_warned: std::collections::HashSet<String>,
    /// `MakeNamedMedium`s by name, as indices into the scene's media.
    named_media: HashMap<String, crate::MediumIndex>,
    /// The `Camera`'s outside medium name and where, resolved at the end.
    camera_medium: Option<(String, FileLoc)>,
    /// An `Integrator` that renders no media in pbrt-v4 (`path`,
    /// `ambientocclusion`, ...): its name and where.
    ignores_media: Option<(String, FileLoc)>,
    /// A `realistic` camera's lens, focused once the film is known (at
    /// `WorldBegin`).
    pending_lens: Option<PendingLens>,
}

/// A `realistic` camera's parameters until its film's size is known.
struct PendingLens {
    /// The lens file's numbers.
    values: Vec<f32>,
    file: String,
    aperture_diameter: f32,
    aperture: Option<crate::lens::ApertureImage>,
    focus_distance: f32,
    loc: FileLoc,
}

impl Builder {
    /// A builder resolving relative file names against `base_dir`.
    pub fn new(base_dir: &Path) -> Self {
        let mut scene = Scene::default();
        // pbrt-v4's default sampler takes 16 samples per pixel, its default
        // filter is a Gaussian.
        scene.settings.spp = 16;
        scene.settings.film.filter = crate::PixelFilter::PBRT_DEFAULT;
        Builder {
            base_dir: base_dir.to_path_buf(),
            scene,
            warnings: WarningSink::default(),
            gs: GraphicsState::default(),
            pushed: Vec::new(),
            named_coordinate_systems: HashMap::new(),
            transform_times: [0.0, 1.0],
            in_world: false,
            sources: Vec::new(),
            anonymous: Vec::new(),
            named_materials: HashMap::new(),
            default_material: None,
            pending_materials: Vec::new(),
            subsurface_at: None,
            pending_shapes: Vec::new(),
            world_meshes: Vec::new(),
            objects: Vec::new(),
            object_names: HashMap::new(),
            active_object: None,
            instance_uses: Vec::new(),
            warned_transform_begin: false,
            textures: NamedTextures::default(),
            skipped_shapes: Vec::new(),
            v3_spellings_warned: Default::default(),
            named_media: HashMap::new(),
            pending_lens: None,
            camera_medium: None,
            ignores_media: None,
        }
    }

    /// Parses `bytes` (the main file, called `name`) and everything it includes.
    pub fn load(
        mut self,
        bytes: Vec<u8>,
        name: &str,
        canonical: Option<PathBuf>,
    ) -> Result<LoadedScene, SceneError> {
        self.sources.push(Source::live(Parser::new(Tokenizer::new(name, bytes)?), canonical));
        let mut last_loc = FileLoc::whole_file(name);
        while let Some(source) = self.sources.last_mut() {
            match source.next(&self.base_dir)? {
                Some(Next::Directive(d)) => {
                    last_loc = d.loc.clone();
                    self.directive(d)?;
                }
                Some(Next::Include(d, file)) => {
                    last_loc = d.loc.clone();
                    self.include(d, file.take()?)?;
                }
                None => {
                    self.sources.pop();
                }
            }
        }
        self.check_sizes(&FileLoc::whole_file(name))?;
        self.finish(&last_loc)
    }

    /// Runs the load's size check ([`crate::input::LoadBudget::with_size_check`])
    /// on the sizes the scene will have, before any mesh file is read: a
    /// scene that cannot fit is refused without reading it. Not fitting is
    /// not bad input: the error is of kind out-of-memory.
    fn check_sizes(&self, main: &FileLoc) -> Result<(), SceneError> {
        if !crate::input::on_budget(|b| b.has_size_check()) {
            return Ok(());
        }
        let objects = self.objects.len() as u64 + 1;
        let instances = self.instance_uses.len() as u64 + 1;
        let sizes = super::pending::sizes(&self.pending_shapes, objects, instances);
        crate::input::on_budget(|b| b.check_sizes(&sizes)).map_err(|why| {
            let cause = std::io::Error::new(std::io::ErrorKind::OutOfMemory, why.clone());
            SceneError::caused_by(main, why, cause)
        })
    }

    fn warn(&mut self, loc: &FileLoc, msg: impl Into<String>) {
        self.warnings.warn(loc, msg);
    }

    fn require_world(&self, what: &str, loc: &FileLoc) -> Result<(), SceneError> {
        if self.in_world {
            Ok(())
        } else {
            Err(SceneError::at(loc, format!("{what} is not allowed before WorldBegin")))
        }
    }

    fn require_options(&self, what: &str, loc: &FileLoc) -> Result<(), SceneError> {
        if self.in_world {
            Err(SceneError::at(
                loc,
                format!("{what} is not allowed after WorldBegin (it is a rendering option)"),
            ))
        } else {
            Ok(())
        }
    }

    /// Applies a transform directive to the active transforms: `ctm = ctm
    /// * m` (or `ctm = m`).
    fn transform(&mut self, m: DMat4, replace: bool) {
        let apply = |ctm: &mut DMat4| *ctm = if replace { m } else { *ctm * m };
        if self.gs.active != ActiveTransform::End {
            apply(&mut self.gs.ctm);
        }
        if self.gs.active != ActiveTransform::Start {
            apply(&mut self.gs.ctm_end);
        }
    }

    /// Whether the two transforms differ: what is made now moves.
    fn ctm_moves(&self) -> bool {
        self.gs.ctm != self.gs.ctm_end
    }

    /// Warns that `what` keeps still at the start transform where the
    /// current transform moves (as pbrt-v4 does for lights, media and
    /// textures).
    fn warn_if_moving(&mut self, what: &str, loc: &FileLoc) {
        if self.ctm_moves() {
            self.warn(loc, format!("{what} cannot move (as in pbrt-v4); the start transform is used"));
        }
    }

    fn params(&mut self, raw: Vec<RawParam>) -> Result<ParamList, SceneError> {
        let warnings = &mut self.warnings;
        let seen = &mut self.v3_spellings_warned;
        // pbrt-v3 files use the same spellings millions of times: warn once each.
        let mut p = ParamList::new(raw, &mut |loc, msg| {
            if seen.insert(msg.clone()) {
                warnings.warn(loc, format!("{msg} (reported once)"));
            }
        })?;
        p.read_spectrum_strings(|param, name| read_spectrum_file(&self.base_dir, param, name))?;
        Ok(p)
    }

    /// Warns about every parameter the directive did not look up.
    fn warn_unused(&mut self, p: &ParamList, what: &str) {
        let unused: Vec<_> = p.unused().map(|u| (u.loc.clone(), u.decl.clone())).collect();
        for (loc, decl) in unused {
            self.warn(&loc, format!("{what}: unused parameter \"{decl}\""));
        }
    }

    fn directive(&mut self, d: Directive) -> Result<(), SceneError> {
        let loc = d.loc;
        use Statement as S;
        match d.statement {
            S::Include(_) | S::Import(_) => unreachable!("files are included as they are read ahead"),
            S::WorldBegin => {
                self.require_options("WorldBegin", &loc)?;
                self.focus_lens()?;
                self.in_world = true;
                self.gs.ctm = DMat4::IDENTITY;
                self.gs.ctm_end = DMat4::IDENTITY;
                self.gs.active = ActiveTransform::All;
                self.named_coordinate_systems.insert("world".into(), (DMat4::IDENTITY, DMat4::IDENTITY));
            }
            S::WorldEnd => self.warn(&loc, "WorldEnd is pbrt-v3 syntax; ignored"),
            S::AttributeBegin => {
                self.require_world("AttributeBegin", &loc)?;
                self.pushed.push((self.gs.clone(), Block::Attribute, loc));
            }
            S::AttributeEnd => {
                self.require_world("AttributeEnd", &loc)?;
                self.pop_attributes("AttributeEnd", &loc)?;
            }
            S::TransformBegin => {
                // pbrt-v4 runs these as AttributeBegin/End (but also allows them
                // before WorldBegin, as pbrt-v3 scenes use them there).
                if !self.warned_transform_begin {
                    self.warned_transform_begin = true;
                    self.warn(
                        &loc,
                        "TransformBegin/End are deprecated; treated as AttributeBegin/End (as pbrt-v4 does)",
                    );
                }
                self.pushed.push((self.gs.clone(), Block::Attribute, loc));
            }
            S::TransformEnd => self.pop_attributes("TransformEnd", &loc)?,
            S::ObjectBegin(name) => self.object_begin(name, loc)?,
            S::ObjectEnd => self.object_end(&loc)?,
            S::ObjectInstance(name) => {
                self.require_world("ObjectInstance", &loc)?;
                if self.active_object.is_some() {
                    return Err(SceneError::at(
                        &loc,
                        "ObjectInstance is not allowed inside ObjectBegin/ObjectEnd",
                    ));
                }
                self.instance_uses.push((name, self.gs.ctm, self.gs.ctm_end, loc));
            }
            S::Identity => self.transform(DMat4::IDENTITY, true),
            S::Translate(v) => self.transform(DMat4::from_translation(DVec3::from(v)), false),
            S::Scale(v) => self.transform(DMat4::from_scale(DVec3::from(v)), false),
            S::Rotate([angle, x, y, z]) => match transform::rotate(angle, DVec3::new(x, y, z)) {
                Some(r) => self.transform(r, false),
                None => self.warn(&loc, "Rotate about a zero axis; ignored"),
            },
            S::LookAt(v) => {
                let [e, l, u] = [0, 3, 6].map(|i| DVec3::new(v[i], v[i + 1], v[i + 2]));
                match transform::look_at(e, l, u) {
                    Ok(m) => self.transform(m, false),
                    Err(msg) => self.warn(&loc, format!("{msg}; ignored")),
                }
            }
            S::Transform(m) => self.transform(transform::from_pbrt_numbers(&m), true),
            S::ConcatTransform(m) => self.transform(transform::from_pbrt_numbers(&m), false),
            S::CoordinateSystem(name) => {
                self.named_coordinate_systems.insert(name, (self.gs.ctm, self.gs.ctm_end));
            }
            S::CoordSysTransform(name) => match self.named_coordinate_systems.get(&name) {
                Some(&(start, end)) => (self.gs.ctm, self.gs.ctm_end) = (start, end),
                None => self.warn(&loc, format!("unknown coordinate system \"{name}\"; ignored")),
            },
            S::ActiveTransform(which) => {
                self.gs.active = match which.as_str() {
                    "All" => ActiveTransform::All,
                    "StartTime" => ActiveTransform::Start,
                    "EndTime" => ActiveTransform::End,
                    _ => {
                        return Err(SceneError::at(
                            &loc,
                            format!("ActiveTransform: expected All, StartTime or EndTime, found '{which}'"),
                        ))
                    }
                };
            }
            S::TransformTimes([start, end]) => {
                self.require_options("TransformTimes", &loc)?;
                if !(start.is_finite() && end.is_finite() && start <= end) {
                    return Err(SceneError::at(
                        &loc,
                        format!(
                            "TransformTimes: the end time {end} must not be before the start time {start}"
                        ),
                    ));
                }
                self.transform_times = [start as f32, end as f32];
            }
            S::ReverseOrientation => {
                self.require_world("ReverseOrientation", &loc)?;
                self.gs.reverse_orientation = !self.gs.reverse_orientation;
            }
            S::NamedMaterial(name) => {
                self.require_world("NamedMaterial", &loc)?;
                self.gs.material = MaterialRef::Named(name, loc);
            }
            S::ColorSpace(name) => {
                if name != "srgb" {
                    self.warn(&loc, format!("color space \"{name}\" is not supported; using sRGB"));
                }
            }
            S::Option(name, _) => self.warn(&loc, format!("Option \"{name}\" is not supported; ignored")),
            S::MediumInterface(inside, outside) => self.gs.media = (inside, outside, Some(loc)),
            S::Texture { name, ty, class, params } => self.texture(name, &ty, &class, params, &loc)?,
            S::Entity { kind, name, params } => self.entity(kind, name, params, loc)?,
        }
        Ok(())
    }

    fn pop_attributes(&mut self, what: &str, loc: &FileLoc) -> Result<(), SceneError> {
        match self.pushed.pop() {
            None => Err(SceneError::at(loc, format!("{what} without a matching AttributeBegin"))),
            Some((_, Block::Object, open)) => Err(SceneError::at(
                loc,
                format!("{what} inside the object definition opened at {open} (missing ObjectEnd)"),
            )),
            Some((gs, Block::Attribute, _)) => {
                self.gs = gs;
                Ok(())
            }
        }
    }

    /// `Include` or `Import` of a file read ahead: its directives come next.
    fn include(&mut self, d: Directive, included: Included) -> Result<(), SceneError> {
        if matches!(d.statement, Statement::Import(_)) {
            self.require_world("Import", &d.loc)?;
        }
        let canonical = &included.source.canonical;
        if let Some(i) = self.sources.iter().position(|s| s.canonical.is_some() && s.canonical == *canonical)
        {
            let chain: Vec<&str> = self.sources[i..].iter().map(|s| &*s.file).collect();
            return Err(SceneError::at(
                &d.loc,
                format!("cyclic Include: {} -> {}", chain.join(" -> "), included.source.file),
            ));
        }
        self.sources.push(included.source);
        Ok(())
    }

    fn object_begin(&mut self, name: String, loc: FileLoc) -> Result<(), SceneError> {
        self.require_world("ObjectBegin", &loc)?;
        if let Some(active) = self.active_object {
            let open = &self.objects[active].name;
            return Err(SceneError::at(
                &loc,
                format!("ObjectBegin inside the definition of object \"{open}\""),
            ));
        }
        if self.object_names.contains_key(&name) {
            return Err(SceneError::at(&loc, format!("object \"{name}\" is defined twice")));
        }
        self.pushed.push((self.gs.clone(), Block::Object, loc));
        self.object_names.insert(name.clone(), self.objects.len());
        self.active_object = Some(self.objects.len());
        self.objects.push(ObjectDef { name, meshes: Vec::new() });
        Ok(())
    }

    fn object_end(&mut self, loc: &FileLoc) -> Result<(), SceneError> {
        self.require_world("ObjectEnd", loc)?;
        if self.active_object.is_none() {
            return Err(SceneError::at(loc, "ObjectEnd without a matching ObjectBegin"));
        }
        match self.pushed.pop() {
            Some((gs, Block::Object, _)) => {
                self.gs = gs;
                self.active_object = None;
                Ok(())
            }
            Some((_, Block::Attribute, open)) => Err(SceneError::at(
                loc,
                format!("ObjectEnd while the AttributeBegin at {open} is still open"),
            )),
            None => Err(SceneError::at(loc, "ObjectEnd without a matching ObjectBegin")),
        }
    }

    fn entity(
        &mut self,
        kind: EntityKind,
        name: String,
        raw: Vec<RawParam>,
        loc: FileLoc,
    ) -> Result<(), SceneError> {
        use EntityKind as E;
        let keyword = kind.keyword();
        match kind {
            E::Camera | E::Film | E::Sampler | E::Integrator | E::PixelFilter | E::Accelerator => {
                self.require_options(keyword, &loc)?
            }
            E::Shape | E::Material | E::MakeNamedMaterial | E::LightSource | E::AreaLightSource => {
                self.require_world(keyword, &loc)?
            }
            E::MakeNamedMedium | E::Attribute => {}
        }
        if kind == E::Attribute {
            return self.attribute(&name, raw, &loc);
        }
        let mut p = self.params(raw)?;
        match kind {
            E::Shape => p = p.with_defaults(&self.gs.shape_attributes),
            E::LightSource | E::AreaLightSource => p = p.with_defaults(&self.gs.light_attributes),
            E::Material | E::MakeNamedMaterial => p = p.with_defaults(&self.gs.material_attributes),
            _ => {}
        }
        if kind == E::LightSource {
            self.warn_if_moving("a light", &loc);
        }
        let w = &mut self.warnings;
        match kind {
            E::Shape if !shapes::SUPPORTED.contains(&name.as_str()) => {
                p.mark_all_used();
                self.skip_shape(&name, &loc);
            }
            E::Shape => {
                if let Some(source) = shapes::shape_source(&name, &p, &loc, &self.base_dir, w)? {
                    let alpha = self.shape_alpha(&name, &p, &loc)?;
                    self.add_shape(source, alpha, &loc)?;
                }
            }
            E::Material if name == "mix" => {
                let slot = self.mix(&p, "Material \"mix\"", &loc)?;
                self.anonymous.push(slot);
                self.gs.material = MaterialRef::Anonymous(self.anonymous.len() - 1);
            }
            E::Material => {
                let slot = self.material(&name, &p, &loc)?;
                self.anonymous.push(slot);
                self.gs.material = MaterialRef::Anonymous(self.anonymous.len() - 1);
            }
            E::MakeNamedMaterial => {
                let Some(ty) = p.string("type")? else {
                    return Err(SceneError::at(
                        &loc,
                        format!("named material \"{name}\": \"string type\" is missing"),
                    ));
                };
                if self.named_materials.contains_key(&name) {
                    return Err(SceneError::at(&loc, format!("named material \"{name}\" is defined twice")));
                }
                let slot = if ty == "mix" {
                    self.mix(&p, &format!("mix \"{name}\""), &loc)?
                } else {
                    self.material(&ty, &p, &loc)?
                };
                self.named_materials.insert(name.clone(), slot);
            }
            E::LightSource => {
                if let Some(light) = entities::light(&name, &p, &self.gs.ctm, &self.base_dir, &loc, w)? {
                    self.scene.lights.push(light);
                }
            }
            E::AreaLightSource => {
                self.gs.area_light = entities::area_light(&name, &p, &loc, w)?;
                self.gs.area_light_texture = None;
                if let (Some(_), Some(file)) = (self.gs.area_light, p.string("filename")?) {
                    match self.textures.emission_image(&file, &self.base_dir, &mut self.scene.textures) {
                        Ok(t) => self.gs.area_light_texture = Some(t),
                        Err(e) => {
                            super::missing_file(&loc, "area light image", e.clone())?;
                            w.warn(&loc, format!("area light image: {e}; emitting \"scale\" uniformly"))
                        }
                    }
                }
            }
            E::Camera => self.camera(&name, &p, &loc)?,
            E::Film => {
                let res = |v: Option<i64>, d: u32| -> Result<u64, SceneError> {
                    match v {
                        None => Ok(d as u64),
                        Some(r) if r > 0 => Ok(r as u64),
                        Some(r) => {
                            Err(SceneError::at(&loc, format!("Film: resolution {r} must be positive")))
                        }
                    }
                };
                let d = self.scene.settings.film.resolution;
                let x = res(p.int("xresolution")?, d.x)?;
                let y = res(p.int("yresolution")?, d.y)?;
                self.scene.settings.film.resolution = crate::FilmSettings::check_resolution(x, y)
                    .map_err(|e| SceneError::at(&loc, format!("Film: {e}")))?;
                self.scene.settings.film.filename = p.string("filename")?;
                self.film_response(&p, &loc)?;
            }
            E::Sampler => {
                if let Some(n) = p.int("pixelsamples")? {
                    let Some(spp) = u32::try_from(n).ok().filter(|&n| n > 0) else {
                        return Err(SceneError::at(
                            &loc,
                            format!("Sampler: pixelsamples {n} must be from 1 to {}", u32::MAX),
                        ));
                    };
                    self.scene.settings.spp = spp;
                }
            }
            E::Integrator => self.integrator(&name, &p, &loc)?,
            E::PixelFilter => self.pixel_filter(&name, &p, &loc)?,
            E::Accelerator => p.mark_all_used(),
            E::MakeNamedMedium => self.medium(&name, &p, &loc)?,
            E::Attribute => unreachable!("handled above"),
        }
        self.warn_unused(&p, &format!("{keyword} \"{name}\""));
        Ok(())
    }

    /// Skips a shape type atoll cannot tessellate. The first of each type is
    /// warned about where it is; the rest are counted (the Moana island has
    /// millions of curves) and summed up at the end.
    fn skip_shape(&mut self, ty: &str, loc: &FileLoc) {
        match self.skipped_shapes.iter_mut().find(|(t, _, _)| t == ty) {
            Some((_, n, _)) => *n += 1,
            None => {
                self.skipped_shapes.push((ty.to_string(), 1, loc.clone()));
                self.warn(loc, format!("unsupported shape \"{ty}\" skipped"));
            }
        }
    }

    /// A `mix` of two named materials (pbrt-v4's `string materials`,
    /// pbrt-v3's `namedmaterial1/2`), both added to the scene now. A name
    /// not defined before the mix becomes diffuse 0.5, with a warning.
    fn mix(&mut self, p: &ParamList, what: &str, loc: &FileLoc) -> Result<MaterialSlot, SceneError> {
        // pbrt-v4's `amount` may be a float texture: bound per hit.
        let mut bindings = Vec::new();
        if p.find("amount", &[ParamType::Texture]).is_some() {
            let tex = TexCtx::new(&self.textures, &mut self.scene.textures);
            if let Some(TexInput::Texture(t)) = tex.float(p, "amount", what, loc, &mut self.warnings)? {
                bindings.push((TexturedParam::Amount, t, false));
            }
        }
        let (first, second, amount) = super::v3::mix_parts(p, loc, &mut self.warnings)?;
        let mut id = |name: &str| -> MaterialId {
            match self.named_materials.get_mut(name) {
                Some(slot) => slot.id(&mut self.scene),
                None => {
                    let msg =
                        format!("{what}: material \"{name}\" is not defined before it; using diffuse 0.5");
                    self.warnings.warn(loc, msg);
                    self.scene.add_material(Material::default_diffuse())
                }
            }
        };
        let materials = [id(&first), id(&second)];
        Ok(MaterialSlot { material: Material::Mix { materials, amount }, bindings, id: None })
    }

    /// `Texture "name" "float"|"spectrum"|"color" "class" params` (see [`super::textures`]).
    fn texture(
        &mut self,
        name: String,
        ty: &str,
        class: &str,
        raw: Vec<RawParam>,
        loc: &FileLoc,
    ) -> Result<(), SceneError> {
        self.require_world("Texture", loc)?;
        let p = self.params(raw)?;
        self.warn_if_moving("a texture's space", loc);
        let store = &mut self.scene.textures;
        let site = TextureSite { base_dir: &self.base_dir, world_from_texture: self.gs.ctm };
        self.textures.define(name.clone(), ty, class, &p, &site, store, loc, &mut self.warnings)?;
        self.warn_unused(&p, &format!("Texture \"{name}\""));
        Ok(())
    }

    /// A material of pbrt type `ty` with the bindings of its texture-valued
    /// parameters, its bump map (`displacement`, pbrt-v3's `bumpmap`) and
    /// its normal map (`normalmap`, an image read linearly).
    fn material(&mut self, ty: &str, p: &ParamList, loc: &FileLoc) -> Result<MaterialSlot, SceneError> {
        let what = format!("Material \"{ty}\"");
        let measured = match ty {
            "measured" => Some(super::measured::measured_material(
                p,
                &self.base_dir,
                &mut self.scene,
                loc,
                &mut self.warnings,
            )?),
            _ => None,
        };
        let mut tex = TexCtx::new(&self.textures, &mut self.scene.textures);
        let material = match measured {
            Some(m) => m,
            None => entities::material(ty, p, loc, &mut self.warnings, &mut tex)?,
        };
        if matches!(material, crate::Material::Subsurface(_)) {
            self.subsurface_at.get_or_insert_with(|| loc.clone());
        }
        let bump =
            if p.find("displacement", &[ParamType::Texture]).is_some() { "displacement" } else { "bumpmap" };
        let displacement = tex.float(p, bump, &what, loc, &mut self.warnings)?;
        let mut bindings = tex.bindings;
        // A constant displacement moves nothing pbrt's bump mapping sees.
        p.find("displacement", &[ParamType::Float]);
        let normal_map = match p.string("normalmap")? {
            None => None,
            Some(file) => match self.textures.normal_map(&file, &self.base_dir, &mut self.scene.textures) {
                Ok(t) => Some(t),
                Err(e) => {
                    super::missing_file(loc, &format!("{what}: normal map"), e.clone())?;
                    self.warnings
                        .warn(loc, format!("{what}: normal map: {e}; the shading normal is not bent"));
                    None
                }
            },
        };
        match (normal_map, displacement) {
            (Some(t), other) => {
                if other.is_some() {
                    self.warnings.warn(
                        loc,
                        format!("{what}: both a normal map and a displacement; the normal map is used"),
                    );
                }
                bindings.push((TexturedParam::NormalMap, t, false));
            }
            (None, Some(TexInput::Texture(t))) => bindings.push((TexturedParam::Displacement, t, false)),
            (None, _) => {}
        }
        Ok(MaterialSlot { material, bindings, id: None })
    }

    /// A shape's `alpha` (pbrt-v4's `float alpha` or `texture alpha`): a
    /// stochastic mask, `None` for the default of 1. A mesh without uvs
    /// reads a textured mask with pbrt's per-triangle default uvs (the
    /// renderer's convention), so none are generated here.
    fn shape_alpha(
        &mut self,
        ty: &str,
        p: &ParamList,
        loc: &FileLoc,
    ) -> Result<Option<MeshAlpha>, SceneError> {
        // pbrt-v3's separate shadow mask: pbrt-v4 (and atoll) cut shadow rays with `alpha` too.
        p.find("shadowalpha", &[ParamType::Texture, ParamType::Float]);
        let tex = TexCtx::new(&self.textures, &mut self.scene.textures);
        let what = format!("shape \"{ty}\"");
        let texture = match tex.float(p, "alpha", &what, loc, &mut self.warnings)? {
            None => return Ok(None),
            Some(TexInput::Value(a)) if a.x >= 1.0 => return Ok(None),
            Some(TexInput::Value(a)) => self.scene.textures.add(Texture::Constant(Rgb::splat(a.x.max(0.0)))),
            Some(TexInput::Texture(t)) => t,
        };
        Ok(Some(MeshAlpha { texture, mode: AlphaMode::Stochastic }))
    }

    /// `Attribute "shape"|"light"|"material" params`: defaults for later directives.
    fn attribute(&mut self, target: &str, raw: Vec<RawParam>, loc: &FileLoc) -> Result<(), SceneError> {
        let p = self.params(raw)?;
        p.mark_all_used();
        // The latest Attribute wins: put its parameters first.
        let params = p.into_params();
        match target {
            "shape" => self.gs.shape_attributes.splice(0..0, params),
            "light" => self.gs.light_attributes.splice(0..0, params),
            "material" => self.gs.material_attributes.splice(0..0, params),
            "medium" | "texture" => {
                self.warn(loc, format!("Attribute \"{target}\": {target}s are not supported; ignored"));
                return Ok(());
            }
            _ => {
                return Err(SceneError::at(
                    loc,
                    format!("unknown Attribute target \"{target}\" (expected shape, light, material, medium or texture)"),
                ))
            }
        };
        Ok(())
    }

    fn camera(&mut self, name: &str, p: &ParamList, loc: &FileLoc) -> Result<(), SceneError> {
        let det = self.gs.ctm.determinant();
        if det == 0.0 || !det.is_finite() {
            return Err(SceneError::at(loc, "Camera: the current transform is not invertible"));
        }
        let world_from_camera = self.gs.ctm.inverse();
        let world_from_camera_end = self.gs.ctm_end.inverse();
        let motion = if self.ctm_moves() {
            let motion = crate::Motion::new(&world_from_camera, &world_from_camera_end, self.transform_times);
            if motion.is_none() {
                return Err(SceneError::at(loc, "Camera: the end transform is not invertible"));
            }
            motion
        } else {
            None
        };
        self.named_coordinate_systems.insert("camera".into(), (world_from_camera, world_from_camera_end));
        self.pending_lens = None;
        let (_, outside, at) = &self.gs.media;
        if !outside.is_empty() {
            self.camera_medium = Some((outside.clone(), at.clone().unwrap_or_else(|| loc.clone())));
        }
        let projection = match name {
            "perspective" => crate::Projection::Perspective,
            "orthographic" => crate::Projection::Orthographic,
            "spherical" => {
                let mapping = match p.string("mapping")?.as_deref() {
                    None | Some("equalarea") => crate::EnvLayout::EqualArea,
                    Some("equirectangular") => crate::EnvLayout::LatLong,
                    Some(other) => {
                        return Err(SceneError::at(
                            loc,
                            format!(
                                "Camera: \"mapping\" \"{other}\" is unknown (expected \"equalarea\" or \"equirectangular\")"
                            ),
                        ))
                    }
                };
                crate::Projection::Spherical { mapping }
            }
            "realistic" => {
                if !self.realistic_camera(p, loc)? {
                    return self.camera("perspective", p, loc);
                }
                crate::Projection::Realistic
            }
            _ => {
                p.mark_all_used();
                self.warn(loc, format!("camera \"{name}\" is not supported; using a perspective camera"));
                let cam = &mut self.scene.settings.camera;
                *cam = crate::Camera {
                    camera_to_world: transform::to_f32(&world_from_camera),
                    motion,
                    ..Default::default()
                };
                return Ok(());
            }
        };
        let fov = p.float_or("fov", 90.0)?;
        if projection == crate::Projection::Perspective && !(fov > 0.0 && fov < 180.0) {
            return Err(SceneError::at(
                loc,
                format!("Camera: \"fov\" {fov} is not between 0 and 180 degrees"),
            ));
        }
        let frame_aspect_ratio = p.float("frameaspectratio")?;
        if let Some(frame) = frame_aspect_ratio.filter(|f| !(*f > 0.0 && f.is_finite())) {
            return Err(SceneError::at(loc, format!("Camera: \"frameaspectratio\" {frame} is not positive")));
        }
        let screen_window = match p.numbers("screenwindow", ParamType::Float) {
            None => None,
            Some(&[x0, x1, y0, y1]) if x0 < x1 && y0 < y1 => Some([x0, x1, y0, y1].map(|v| v as f32)),
            Some(w) => {
                return Err(SceneError::at(
                    loc,
                    format!(
                        "Camera: \"screenwindow\" needs four values (x min, x max, y min, y max) \
                         with each minimum below its maximum, got {w:?}"
                    ),
                ))
            }
        };
        let cam = &mut self.scene.settings.camera;
        *cam = crate::Camera {
            camera_to_world: transform::to_f32(&world_from_camera),
            projection,
            fov_degrees: fov,
            screen_window,
            frame_aspect_ratio,
            motion,
            ..Default::default()
        };
        cam.lens_radius = p.float_or("lensradius", 0.0)?;
        cam.focal_distance = p.float_or("focaldistance", 1e6)?;
        // The film's exposure, over which what moves is blurred.
        let (open, close) = (p.float_or("shutteropen", 0.0)?, p.float_or("shutterclose", 1.0)?);
        if close < open {
            return Err(SceneError::at(
                loc,
                format!("Camera: \"shutterclose\" {close} is before \"shutteropen\" {open}"),
            ));
        }
        self.scene.settings.film.sensor.exposure_time = close - open;
        self.scene.settings.camera.shutter = [open, close];
        Ok(())
    }

    /// A `realistic` camera's lens file and parameters (pbrt-v4's
    /// defaults: a 1 mm aperture focused at 10 m), kept until `WorldBegin`
    /// knows the film. `false` where the lens file is missing and
    /// `--allow-missing` makes the camera a perspective one.
    fn realistic_camera(&mut self, p: &ParamList, loc: &FileLoc) -> Result<bool, SceneError> {
        let what = "Camera \"realistic\"";
        let Some(file) = p.string("lensfile")? else {
            return Err(SceneError::at(loc, format!("{what}: \"lensfile\" must be given")));
        };
        let aperture_diameter = p.float_or("aperturediameter", 1.0)?;
        let focus_distance = p.float_or("focusdistance", 10.0)?;
        let aperture = match p.string("aperture")? {
            None => None,
            Some(name) => self.aperture_image(&name, what, loc)?,
        };
        let text = crate::input::beside(&self.base_dir, &file).and_then(|path| crate::input::read(&path));
        let text = match text {
            Ok(bytes) => String::from_utf8_lossy(&bytes).into_owned(),
            Err(e) => {
                let e = crate::ImageLoadError::io(Path::new(&file))(e);
                super::missing_file(loc, what, e.clone())?;
                self.warn(loc, format!("{what}: {e}; using a perspective camera"));
                return Ok(false);
            }
        };
        let values = crate::lens::parse_lens_file(&text)
            .map_err(|e| SceneError::at(loc, format!("{what}: {file}: {e}")))?;
        self.pending_lens =
            Some(PendingLens { values, file, aperture_diameter, aperture, focus_distance, loc: loc.clone() });
        Ok(true)
    }

    /// A realistic camera's `aperture`: one of pbrt-v4's built-in shapes or
    /// an image file beside the scene (its RGB averaged). A missing file is
    /// an error unless allowed (the stop then stays round).
    fn aperture_image(
        &mut self,
        name: &str,
        what: &str,
        loc: &FileLoc,
    ) -> Result<Option<crate::lens::ApertureImage>, SceneError> {
        if let Some(image) = crate::lens::ApertureImage::builtin(name) {
            return Ok(Some(image));
        }
        let image = crate::input::beside(&self.base_dir, name)
            .map_err(crate::ImageLoadError::io(Path::new(name)))
            .and_then(|path| crate::EnvironmentImage::load(&path));
        match image {
            Ok(image) => {
                let values = image.pixels.iter().map(|p| (p.x + p.y + p.z) / 3.0).collect();
                Ok(Some(crate::lens::ApertureImage::from_rows(image.width, image.height, values)))
            }
            Err(e) => {
                super::missing_file(loc, what, e.clone())?;
                self.warn(loc, format!("{what}: {e}; the stop stays round"));
                Ok(None)
            }
        }
    }

    /// Focuses a `realistic` camera's lens for the film (its diagonal), and
    /// bounds its exit pupils.
    fn focus_lens(&mut self) -> Result<(), SceneError> {
        let Some(l) = self.pending_lens.take() else { return Ok(()) };
        let diagonal = self.scene.settings.film.diagonal;
        let what = "Camera \"realistic\"";
        let (lens, warning) = crate::lens::LensSystem::new(
            &l.values,
            l.aperture_diameter,
            l.aperture,
            l.focus_distance,
            diagonal,
        )
        .map_err(|e| SceneError::at(&l.loc, format!("{what}: {}: {e}", l.file)))?;
        if let Some(w) = warning {
            self.warn(&l.loc, format!("{what}: {w}"));
        }
        self.scene.settings.camera.lens = Some(std::sync::Arc::new(lens));
        Ok(())
    }

    /// `PixelFilter "name"`: pbrt-v4's filters with its default radii and
    /// parameters; an unknown one is an error, as in pbrt-v4.
    fn pixel_filter(&mut self, name: &str, p: &ParamList, loc: &FileLoc) -> Result<(), SceneError> {
        use crate::PixelFilter as F;
        let default_radius = match name {
            "box" => 0.5,
            "gaussian" => 1.5,
            "mitchell" | "triangle" => 2.0,
            "sinc" => 4.0,
            _ => {
                return Err(SceneError::at(
                    loc,
                    format!("PixelFilter: unknown filter \"{name}\" (expected box, gaussian, mitchell, sinc or triangle)"),
                ))
            }
        };
        let radius =
            glam::Vec2::new(p.float_or("xradius", default_radius)?, p.float_or("yradius", default_radius)?);
        // A sample lands at most this far from its pixel: more would be no
        // pixel filter but a blur.
        const MAX_RADIUS: f32 = 16.0;
        if !(radius.min_element() > 0.0 && radius.max_element() <= MAX_RADIUS) {
            return Err(SceneError::at(
                loc,
                format!(
                    "PixelFilter \"{name}\": radius ({}, {}) must be in (0, {MAX_RADIUS}]",
                    radius.x, radius.y
                ),
            ));
        }
        let positive = |what: &str, v: f32| {
            if v > 0.0 && v.is_finite() {
                Ok(v)
            } else {
                Err(SceneError::at(
                    loc,
                    format!("PixelFilter \"{name}\": \"{what}\" must be positive, found {v}"),
                ))
            }
        };
        let filter = match name {
            "box" => F::Box { radius },
            "gaussian" => F::Gaussian { radius, sigma: positive("sigma", p.float_or("sigma", 0.5)?)? },
            "mitchell" => {
                F::Mitchell { radius, b: p.float_or("B", 1.0 / 3.0)?, c: p.float_or("C", 1.0 / 3.0)? }
            }
            "sinc" => F::LanczosSinc { radius, tau: positive("tau", p.float_or("tau", 3.0)?)? },
            _ => F::Triangle { radius },
        };
        // Negative lobes may not outweigh the rest: pixels are divided by
        // the filter's integral.
        for axis in 0..2 {
            let (signed, magnitude) = (0..256)
                .map(|i| filter.along(axis, (i as f32 + 0.5) / 256.0 * radius[axis]))
                .fold((0.0, 0.0), |(s, m), v| (s + v, m + v.abs()));
            // (Written so that a NaN, from parameters too large to evaluate, fails too.)
            if signed.partial_cmp(&(0.1 * magnitude)) != Some(std::cmp::Ordering::Greater) {
                return Err(SceneError::at(
                    loc,
                    format!("PixelFilter \"{name}\": its negative lobes cancel the rest (integral {signed:.3} of magnitude {magnitude:.3} along an axis)"),
                ));
            }
        }
        self.scene.settings.film.filter = filter;
        Ok(())
    }

    /// The `Film`'s crop window and pixel sensor (pbrt-v4's `RGBFilm` and
    /// `PixelSensor` parameters; pbrt-v3's `scale`).
    fn film_response(&mut self, p: &ParamList, loc: &FileLoc) -> Result<(), SceneError> {
        let film = &mut self.scene.settings.film;
        let bad = |msg: String| SceneError::at(loc, format!("Film: {msg}"));
        let r = film.resolution.as_vec2();
        film.crop_window = match (p.numbers("cropwindow", ParamType::Float), p.ints("pixelbounds")) {
            (Some(c), _) if c.len() != 4 => {
                return Err(bad(format!("\"cropwindow\" needs 4 values, got {}", c.len())))
            }
            (Some(c), _) => Some([c[0], c[1], c[2], c[3]].map(|v| v as f32)),
            (None, Some(b)) if b.len() != 4 => {
                return Err(bad(format!("\"pixelbounds\" needs 4 values, got {}", b.len())))
            }
            (None, Some(b)) => {
                Some([b[0] as f32 / r.x, b[1] as f32 / r.x, b[2] as f32 / r.y, b[3] as f32 / r.y])
            }
            (None, None) => None,
        };
        if let Some([x0, x1, y0, y1]) = film.crop_window {
            let inside = |a: f32, b: f32| (0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b) && a < b;
            let (lo, hi) = film.pixel_bounds();
            if !inside(x0, x1) || !inside(y0, y1) || lo.x >= hi.x || lo.y >= hi.y {
                return Err(bad(format!(
                    "the crop window [{x0} {x1} {y0} {y1}] covers no pixel of the image"
                )));
            }
        }
        let sensor = &mut film.sensor;
        sensor.iso = p.float_or("iso", 100.0)?;
        sensor.scale = p.float_or("scale", 1.0)?;
        let kelvin = p.float_or("whitebalance", 0.0)?;
        if !(sensor.iso > 0.0 && sensor.scale > 0.0 && kelvin >= 0.0) {
            return Err(bad("\"iso\" and \"scale\" must be positive, \"whitebalance\" not negative".into()));
        }
        sensor.white_balance = (kelvin > 0.0).then_some(kelvin);
        if let Some(name) = p.string("sensor")?.filter(|n| n != "cie1931") {
            self.warnings.warn(loc, format!("Film: sensor \"{name}\" is not supported; using \"cie1931\""));
        }
        if !(4000.0..=25000.0).contains(&kelvin) && kelvin > 0.0 {
            self.warnings.warn(
                loc,
                format!(
                    "Film: white balance {kelvin} K is outside the daylight locus (4000 to 25000 K); clamped"
                ),
            );
        }
        if let Some(m) = p.float("maxcomponentvalue")?.filter(|m| m.is_finite()) {
            self.warnings.warn(
                loc,
                format!(
                    "Film: \"maxcomponentvalue\" {m} is not supported yet; bright samples are not clamped"
                ),
            );
        }
        // What only changes how pbrt stores its image.
        p.find("savefp16", &[ParamType::Bool]);
        let diagonal = p.float_or("diagonal", 35.0)?;
        if !(diagonal > 0.0 && diagonal.is_finite()) {
            return Err(SceneError::at(loc, format!("Film: \"diagonal\" {diagonal} mm is not positive")));
        }
        self.scene.settings.film.diagonal = diagonal / 1000.0;
        Ok(())
    }

    fn integrator(&mut self, name: &str, p: &ParamList, loc: &FileLoc) -> Result<(), SceneError> {
        // pbrt-v4's integrators that follow rays through media; the others
        // skip medium boundaries and see no media (its default is `volpath`).
        let with_media = ["volpath", "simplevolpath", "bdpt", "mlt"];
        self.ignores_media = (!with_media.contains(&name)).then(|| (name.to_string(), loc.clone()));
        self.scene.settings.light_sampler = match p.string("lightsampler")?.as_deref() {
            None | Some("bvh") => LightSampler::Bvh,
            Some("power") => LightSampler::Power,
            Some(other) => {
                self.warn(
                    loc,
                    format!("Integrator: lightsampler \"{other}\" is not supported; using \"bvh\""),
                );
                LightSampler::Bvh
            }
        };
        self.scene.settings.integrator = if name == "ambientocclusion" {
            let max_distance = p.float_or("maxdistance", f32::INFINITY)?;
            IntegratorSettings::AmbientOcclusion { max_distance }
        } else {
            let depth = p.int("maxdepth")?.unwrap_or(5);
            let Ok(depth) = u32::try_from(depth) else {
                return Err(SceneError::at(
                    loc,
                    format!("Integrator: maxdepth {depth} must be from 0 to {}", u32::MAX),
                ));
            };
            if name != "path" && name != "volpath" {
                p.mark_all_used();
                self.warn(loc, format!("integrator \"{name}\" is not supported; rendering with \"path\""));
            }
            IntegratorSettings::Path { max_depth: depth }
        };
        Ok(())
    }

    /// The material id for the current graphics state (`None`: a named
    /// material not defined yet).
    fn current_material(&mut self) -> Option<MaterialId> {
        let scene = &mut self.scene;
        match &self.gs.material {
            MaterialRef::Default => Some(
                *self.default_material.get_or_insert_with(|| scene.add_material(Material::default_diffuse())),
            ),
            MaterialRef::Anonymous(i) => Some(self.anonymous[*i].id(scene)),
            MaterialRef::Named(name, _) => Some(self.named_materials.get_mut(name)?.id(scene)),
        }
    }

    /// Records a shape for the world or the object being defined, with the
    /// graphics state's transform, material and emission; its triangles are
    /// made at the end ([`Builder::add_pending_shapes`]).
    fn add_shape(
        &mut self,
        source: ShapeSource,
        alpha: Option<MeshAlpha>,
        loc: &FileLoc,
    ) -> Result<(), SceneError> {
        if let ShapeSource::Mesh(m) = &source {
            if m.indices.is_empty() {
                self.warn(loc, format!("shape \"{}\" has no triangles; skipped", m.name));
                return Ok(());
            }
        }
        let (inside, outside, at) = &self.gs.media;
        let at = at.as_ref().unwrap_or(loc);
        let media = crate::MediumInterface::transition(
            self.medium_index(inside, at)?,
            self.medium_index(outside, at)?,
        );
        let mut emission = self.gs.area_light;
        if emission.is_some() && self.active_object.is_some() {
            self.warn(
                loc,
                "area lights are not supported in object instances (as in pbrt-v4); emission dropped",
            );
            emission = None;
        }
        let mut motion = None;
        if self.ctm_moves() {
            if emission.is_some() {
                return Err(SceneError::at(loc, "area lights cannot move (as in pbrt-v4)"));
            }
            if self.active_object.is_some() {
                self.warn(loc, "shapes cannot move inside ObjectBegin here; the start transform is used");
            } else {
                motion = Some((self.gs.ctm, self.gs.ctm_end));
            }
        }
        let material = self.current_material();
        let named_material = match (&self.gs.material, material) {
            (MaterialRef::Named(name, at), None) => Some((name.clone(), at.clone())),
            _ => None,
        };
        let place = ShapePlace {
            loc: loc.clone(),
            ctm: if motion.is_some() { DMat4::IDENTITY } else { self.gs.ctm },
            reverse_orientation: self.gs.reverse_orientation,
            material,
            named_material,
            emission_texture: emission.and(self.gs.area_light_texture),
            emission,
            alpha,
            media,
            object: self.active_object,
            motion,
        };
        self.pending_shapes.push(PendingShape { source, place });
        Ok(())
    }

    /// Under an integrator that renders no media, as pbrt-v4's do not: the
    /// media are dropped (warned about where the integrator is named).
    fn drop_media_unless_rendered(&mut self) {
        let Some((name, loc)) = self.ignores_media.take() else { return };
        if self.scene.media.is_empty() {
            return;
        }
        self.warn(
            &loc,
            format!(
                "integrator \"{name}\" renders no participating media, as in pbrt-v4; {} media left out (\"volpath\" renders them)",
                self.scene.media.len()
            ),
        );
        self.scene.media.clear();
        self.scene.settings.camera_medium = crate::VACUUM;
        for mesh in &mut self.scene.meshes {
            mesh.media = None;
        }
    }

    /// The index of the medium `name` ("" is the vacuum).
    fn medium_index(&self, name: &str, loc: &FileLoc) -> Result<crate::MediumIndex, SceneError> {
        if name.is_empty() {
            return Ok(crate::VACUUM);
        }
        self.named_media
            .get(name)
            .copied()
            .ok_or_else(|| SceneError::at(loc, format!("MediumInterface: medium \"{name}\" is not defined")))
    }

    /// `MakeNamedMedium`: a homogeneous medium joins the scene; the other
    /// types are warned about once each and become the vacuum.
    fn medium(&mut self, name: &str, p: &ParamList, loc: &FileLoc) -> Result<(), SceneError> {
        self.warn_if_moving("a medium", loc);
        let medium = entities::medium(name, p, &self.gs.ctm, loc, &mut self.warnings)?;
        let index = match medium {
            None => crate::VACUUM,
            Some(medium) => {
                if self.scene.media.len() == crate::MAX_MEDIA {
                    return Err(SceneError::at(
                        loc,
                        format!("MakeNamedMedium \"{name}\": more than {} media", crate::MAX_MEDIA),
                    ));
                }
                self.scene.media.push(medium);
                self.scene.media.len() as crate::MediumIndex
            }
        };
        // pbrt-v4 refuses a second definition too.
        if self.named_media.insert(name.to_string(), index).is_some() {
            return Err(SceneError::at(loc, format!("MakeNamedMedium: medium \"{name}\" redefined")));
        }
        Ok(())
    }

    /// Makes the pending shapes (in parallel) and adds their meshes in the
    /// order of their directives.
    fn add_pending_shapes(&mut self) -> Result<(), SceneError> {
        for made in super::pending::make_all(std::mem::take(&mut self.pending_shapes))? {
            let place = made.place;
            for warning in made.warnings {
                self.warn(&place.loc, warning);
            }
            let Some(mesh) = made.mesh else { continue };
            let id = self.scene.add_mesh(mesh);
            if let Some(texture) = place.emission_texture {
                self.scene.textures.bind_emission(id, texture);
            }
            if let Some((name, at)) = place.named_material {
                self.pending_materials.push((id, name, at));
            }
            match (place.object, place.motion) {
                (Some(o), _) => self.objects[o].meshes.push(id),
                (None, Some((start, end))) => {
                    let object = self.scene.add_object(Object { name: String::new(), meshes: vec![id] });
                    self.place_instance(object, &start, &end, &place.loc);
                }
                (None, None) => self.world_meshes.push(id),
            }
        }
        Ok(())
    }

    /// Places `object` with the transforms at the motion's start and end
    /// (moving where they differ).
    fn place_instance(&mut self, object: crate::ObjectId, start: &DMat4, end: &DMat4, loc: &FileLoc) {
        let object_to_world = Affine3A::from_mat4(transform::to_f32(start));
        let mut instance = Instance::new(object, object_to_world);
        if start != end {
            match crate::Motion::new(start, end, self.transform_times) {
                Some(motion) => {
                    instance.motion = Some(self.scene.motions.len() as u32);
                    self.scene.motions.push(motion);
                }
                None => self.warn(loc, "a motion's transform is singular; the start transform is used"),
            }
        }
        self.scene.instances.push(instance);
    }

    /// End of input: close open blocks, resolve names, assemble objects and instances.
    fn finish(mut self, last: &FileLoc) -> Result<LoadedScene, SceneError> {
        if !self.in_world {
            return Err(SceneError::at(last, "end of file before WorldBegin"));
        }
        for (_, block, open) in std::mem::take(&mut self.pushed).into_iter().rev() {
            let what = if block == Block::Object {
                "ObjectBegin has no ObjectEnd"
            } else {
                "AttributeBegin has no AttributeEnd"
            };
            self.warn(&open, format!("{what} at the end of the file"));
        }
        for (ty, n, first) in std::mem::take(&mut self.skipped_shapes) {
            if n > 1 {
                self.warn(
                    &first,
                    format!("{n} unsupported \"{ty}\" shapes skipped in all (the first is here)"),
                );
            }
        }
        crate::input::on_budget(|b| b.end_phase(LoadPhase::Text));
        if let Some((name, loc)) = self.camera_medium.take() {
            self.scene.settings.camera_medium = self.medium_index(&name, &loc)?;
        }
        self.add_pending_shapes()?;
        self.drop_media_unless_rendered();
        crate::input::on_budget(|b| b.end_phase(LoadPhase::Meshes));
        for (mesh, name, loc) in std::mem::take(&mut self.pending_materials) {
            let Some(slot) = self.named_materials.get_mut(&name) else {
                return Err(SceneError::at(
                    &loc,
                    format!("NamedMaterial: material \"{name}\" is not defined"),
                ));
            };
            let id = slot.id(&mut self.scene);
            self.scene.meshes[mesh as usize].material = id;
        }
        // After the media are dropped or kept: pbrt-v4's `path` renders
        // subsurface scattering, though it renders no media.
        if let Some(at) = self.subsurface_at.take() {
            self.scene.attach_subsurface_interiors().map_err(|e| SceneError::at(&at, e))?;
        }
        if !self.world_meshes.is_empty() {
            let id = self
                .scene
                .add_object(Object { name: "world".into(), meshes: std::mem::take(&mut self.world_meshes) });
            self.scene.instances.push(Instance::new(id, Affine3A::IDENTITY));
        }
        let mut ids = Vec::with_capacity(self.objects.len());
        for def in std::mem::take(&mut self.objects) {
            ids.push(self.scene.add_object(Object { name: def.name, meshes: def.meshes }));
        }
        for (name, start, end, loc) in std::mem::take(&mut self.instance_uses) {
            let Some(&i) = self.object_names.get(&name) else {
                return Err(SceneError::at(
                    &loc,
                    format!("ObjectInstance: object \"{name}\" is not defined"),
                ));
            };
            // pbrt-v4 drops instances of empty objects.
            if !self.scene.objects[ids[i] as usize].meshes.is_empty() {
                self.place_instance(ids[i], &start, &end, &loc);
            }
        }
        Ok(LoadedScene { scene: self.scene, warnings: self.warnings.list })
    }
}

/// The numbers of the spectrum file `name` that `param` names, if it names
/// one ([`spectrum::names_a_file`]); `None` also for a file that cannot be
/// read under `--allow-missing` (the parameter then falls back, warned).
fn read_spectrum_file(base_dir: &Path, param: &Param, name: &str) -> Result<Option<Vec<f64>>, SceneError> {
    if !spectrum::names_a_file(name) {
        return Ok(None);
    }
    let what = format!("parameter \"{}\": spectrum file '{name}'", param.decl);
    let text = crate::input::beside(base_dir, name).and_then(|path| crate::input::read(&path));
    let text = match text {
        Ok(bytes) => String::from_utf8_lossy(&bytes).into_owned(),
        Err(e) => {
            super::missing_file(&param.loc, &what, e)?;
            return Ok(None);
        }
    };
    spectrum::parse_spd(&text).map(Some).map_err(|why| SceneError::at(&param.loc, format!("{what}: {why}")))
}
