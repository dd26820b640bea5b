//! pbrt `Texture` statements and texture-valued parameters, following
//! pbrt-v4's `textures.cpp` for names and defaults (pbrt-v3's spellings too).
//!
//! | class | parameters (default) |
//! |---|---|
//! | `imagemap` | `filename`, `wrap` (repeat), `scale` (1), `invert` (false), `encoding` (sRGB for 8-bit files; pbrt-v3: `bool gamma`), `filter` (bilinear; pbrt-v3: `bool trilinear`, false meaning EWA): a MIP pyramid the hit's footprint picks levels from, EWA filtered trilinearly; `maxanisotropy` ignored |
//! | `checkerboard` | `tex1` (1), `tex2` (0); `dimension` 2 (a 2D mapping) or 3 (the point in the texture's space) |
//! | `bilerp` | `v00` (0), `v01` (1), `v10` (0), `v11` (1) over a 2D mapping |
//! | `constant` | `value` (1) |
//! | `scale` | `tex` (1) × `scale` (1); pbrt-v3: `tex1` × `tex2` |
//! | `mix` | `tex1` (0), `tex2` (1), `amount` (0.5, a float texture) |
//! | `directionmix` | `tex1` (0), `tex2` (1), `dir` (0 1 0, in the texture's space): `tex1` times `\|n · dir\|`, `tex2` the rest |
//! | `fbm`, `wrinkled` | `octaves` (8, at most 32), `roughness` (0.5) |
//! | `windy` | none |
//! | `marble` | `octaves` (8), `roughness` (0.5), `scale` (1), `variation` (0.2) |
//! | `dots` | `inside` (1), `outside` (0); 2D mappings |
//!
//! The noise textures (`fbm`, `wrinkled`, `windy`, `marble`) read the hit
//! point in the space of the `Texture` statement. `imagemap`,
//! `checkerboard` and `dots` take pbrt-v4's 2D mappings: `uv`
//! (`uscale`, `vscale`, `udelta`, `vdelta`), and `spherical`,
//! `cylindrical` and `planar` (`v1`, `v2`, `udelta`, `vdelta`) of the hit
//! point in the space of the `Texture` statement. Other classes (`ptex`,
//! `uv`) are warned about and replaced
//! by a constant (0.5 grey, or 1 for float textures), as is an image that
//! cannot be read under `--allow-missing` (without it, an error as in pbrt-v4).
//!
//! Float and spectrum textures have separate namespaces, as in pbrt. A
//! texture parameter names a texture defined earlier in the file (pbrt-v4
//! also creates textures in file order).
//!
//! Materials read their texture-valued parameters through [`TexCtx`], which
//! collects the bindings of the material being made; the builder attaches
//! them to the material's id.

use std::collections::HashMap;
use std::path::Path;

use crate::error::{FileLoc, SceneError};
use crate::{
    ColorEncoding, ImageCache, ImageFilter, ImageLoadError, Noise, Rgb, TexInput, TexMapping, Texture,
    TextureId, TexturedParam, Textures, UvMapping, Wrap,
};

use super::entities::reflectance_rgb;
use super::params::{FloatOrTexture, ParamList, ParamType, SpectrumParam};
use super::WarningSink;

/// Where a `Texture` statement is: the folder its files are named from,
/// and the transform current there (3D mappings work in its space).
pub struct TextureSite<'a> {
    pub base_dir: &'a Path,
    pub world_from_texture: glam::DMat4,
}

/// pbrt's two texture types.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TexKind {
    Float,
    Spectrum,
}

impl TexKind {
    fn name(self) -> &'static str {
        match self {
            TexKind::Float => "float",
            TexKind::Spectrum => "spectrum",
        }
    }

    /// What replaces a texture that cannot be made.
    fn fallback(self) -> Rgb {
        match self {
            TexKind::Float => Rgb::ONE,
            TexKind::Spectrum => Rgb::splat(0.5),
        }
    }
}

/// pbrt texture classes atoll has no texture for.
const UNSUPPORTED: &[&str] = &["ptex", "uv"];

/// The named textures of a scene being loaded, and its image cache.
#[derive(Debug, Default)]
pub struct NamedTextures {
    float: HashMap<String, TextureId>,
    spectrum: HashMap<String, TextureId>,
    images: ImageCache,
}

impl NamedTextures {
    /// Runs `Texture "name" "ty" "class" params`, adding the texture to
    /// `store`. Image files resolve against `base_dir`.
    #[allow(clippy::too_many_arguments)]
    pub fn define(
        &mut self,
        name: String,
        ty: &str,
        class: &str,
        p: &ParamList,
        site: &TextureSite,
        store: &mut Textures,
        loc: &FileLoc,
        w: &mut WarningSink,
    ) -> Result<(), SceneError> {
        let kind = match ty {
            "float" => TexKind::Float,
            // pbrt-v3 wrote `color`.
            "spectrum" | "color" | "rgb" => TexKind::Spectrum,
            _ => {
                return Err(SceneError::at(
                    loc,
                    format!("Texture \"{name}\": type must be \"float\" or \"spectrum\", found \"{ty}\""),
                ))
            }
        };
        let what = format!("texture \"{name}\"");
        let id = match self.make(kind, class, p, site, store, &what, loc, w)? {
            Ok(texture) => store.add(texture),
            Err(reason) => {
                p.mark_all_used();
                w.warn(loc, format!("{what}: {reason}; using a constant"));
                store.add(Texture::Constant(kind.fallback()))
            }
        };
        let names = match kind {
            TexKind::Float => &mut self.float,
            TexKind::Spectrum => &mut self.spectrum,
        };
        // pbrt-v4 rejects a second definition; pbrt-v3 let the later one win, which we follow.
        if names.insert(name, id).is_some() {
            w.warn(loc, format!("{what} is defined again; the later definition is used from here on"));
        }
        Ok(())
    }

    /// The texture node for `class`, or (the outer `Ok`) why it is replaced
    /// by a constant. Errors are malformed parameters.
    #[allow(clippy::too_many_arguments)]
    fn make(
        &mut self,
        kind: TexKind,
        class: &str,
        p: &ParamList,
        site: &TextureSite,
        store: &mut Textures,
        what: &str,
        loc: &FileLoc,
        w: &mut WarningSink,
    ) -> Result<Result<Texture, String>, SceneError> {
        let input = |name: &str, k: TexKind, default: f32, w: &mut WarningSink| {
            self.input(p, name, k, Rgb::splat(default), what, loc, w)
        };
        Ok(Ok(match class {
            // A value only (as in pbrt): no texture may stand for it.
            "constant" => Texture::Constant(match kind {
                TexKind::Float => Rgb::splat(p.float_or("value", 1.0)?),
                TexKind::Spectrum => p
                    .spectrum("value", true)?
                    .and_then(|sp| reflectance_rgb(sp, what, loc, w))
                    .unwrap_or(Rgb::ONE),
            }),
            "scale" => {
                // pbrt-v3's ScaleTexture multiplies `tex1` by `tex2`.
                let (tex, scale) = if !p.has("tex") && (p.has("tex1") || p.has("tex2")) {
                    (input("tex1", kind, 1.0, w)?, input("tex2", kind, 1.0, w)?)
                } else {
                    (input("tex", kind, 1.0, w)?, input("scale", TexKind::Float, 1.0, w)?)
                };
                match (tex, scale) {
                    (TexInput::Value(a), TexInput::Value(b)) => Texture::Constant(a * b),
                    _ => Texture::Scale { tex, scale },
                }
            }
            "mix" => Texture::Mix {
                tex: [input("tex1", kind, 0.0, w)?, input("tex2", kind, 1.0, w)?],
                amount: input("amount", TexKind::Float, 0.5, w)?,
            },
            // pbrt-v4: `|n · dir|` of `tex1` and the rest of `tex2`, `dir`
            // in the texture's space.
            "directionmix" => {
                let dir = match p.numbers("dir", ParamType::Vector3) {
                    None => glam::DVec3::Y,
                    Some([x, y, z]) => glam::DVec3::new(*x, *y, *z),
                    Some(v) => {
                        return Err(SceneError::at(
                            loc,
                            format!("{what}: \"dir\" needs 3 values, got {}", v.len()),
                        ))
                    }
                };
                let direction = site.world_from_texture.transform_vector3(dir).normalize_or_zero().as_vec3();
                if direction == glam::Vec3::ZERO {
                    return Err(SceneError::at(loc, format!("{what}: \"dir\" is no direction")));
                }
                let facing = store.add(Texture::Facing { direction });
                Texture::Mix {
                    tex: [input("tex2", kind, 1.0, w)?, input("tex1", kind, 0.0, w)?],
                    amount: TexInput::Texture(facing),
                }
            }
            "checkerboard" => {
                p.find("aamode", &[ParamType::String]); // pbrt-v3's antialiasing choice
                let tex = [input("tex1", kind, 1.0, w)?, input("tex2", kind, 0.0, w)?];
                match p.int("dimension")?.unwrap_or(2) {
                    2 => Texture::Checkerboard { mapping: tex_mapping(p, site, what, loc, w)?, tex },
                    3 => Texture::SolidCheckerboard { texture_from_world: texture_from_world(site), tex },
                    d => {
                        return Err(SceneError::at(
                            loc,
                            format!("{what}: \"dimension\" must be 2 or 3, found {d}"),
                        ))
                    }
                }
            }
            "bilerp" => {
                let mapping = tex_mapping(p, site, what, loc, w)?;
                let corners = [
                    input("v00", kind, 0.0, w)?,
                    input("v10", kind, 0.0, w)?,
                    input("v01", kind, 1.0, w)?,
                    input("v11", kind, 1.0, w)?,
                ];
                Texture::Bilerp { mapping, corners }
            }
            "fbm" | "wrinkled" | "windy" | "marble" => Texture::Noise {
                noise: noise(class, p, what, loc, w)?,
                texture_from_world: texture_from_world(site),
            },
            "dots" => {
                let mapping = tex_mapping(p, site, what, loc, w)?;
                Texture::Dots {
                    mapping,
                    tex: [input("inside", kind, 1.0, w)?, input("outside", kind, 0.0, w)?],
                }
            }
            "imagemap" => return self.image(kind, p, site, store, what, loc, w),
            c if UNSUPPORTED.contains(&c) => return Ok(Err(format!("class \"{c}\" is not supported"))),
            c => return Ok(Err(format!("unknown texture class \"{c}\""))),
        }))
    }

    /// `imagemap`: the image decoded once per file and encoding.
    #[allow(clippy::too_many_arguments)]
    fn image(
        &mut self,
        kind: TexKind,
        p: &ParamList,
        site: &TextureSite,
        store: &mut Textures,
        what: &str,
        loc: &FileLoc,
        w: &mut WarningSink,
    ) -> Result<Result<Texture, String>, SceneError> {
        // pbrt-v4's `filter`; pbrt-v3 asked for trilinear filtering with a
        // bool (its other filter was EWA).
        let filter = match (p.string("filter")?, p.bool("trilinear")?) {
            (Some(f), _) => ImageFilter::parse(&f).ok_or_else(|| {
                SceneError::at(
                    loc,
                    format!("{what}: unknown filter \"{f}\" (expected point, bilinear, trilinear or ewa)"),
                )
            })?,
            (None, Some(true)) => ImageFilter::Trilinear,
            (None, Some(false)) => ImageFilter::Ewa,
            (None, None) => ImageFilter::Bilinear,
        };
        if filter == ImageFilter::Ewa {
            w.warn(loc, format!("{what}: filter \"ewa\" is approximated by trilinear filtering (pbrt-v4's EWA is sharper along the footprint's short axis)"));
        }
        p.find("maxanisotropy", &[ParamType::Float]);
        let wrap = match p.string("wrap")? {
            None => Wrap::Repeat,
            Some(s) if s == "octahedralsphere" => {
                w.warn(
                    loc,
                    format!("{what}: wrap mode \"octahedralsphere\" is not supported; using \"clamp\""),
                );
                Wrap::Clamp
            }
            Some(s) => Wrap::parse(&s).ok_or_else(|| {
                SceneError::at(
                    loc,
                    format!("{what}: unknown wrap mode \"{s}\" (expected repeat, black, clamp or mirror)"),
                )
            })?,
        };
        let scale = p.float_or("scale", 1.0)?;
        let invert = p.bool_or("invert", false)?;
        // pbrt-v4's `encoding`; pbrt-v3's `gamma` says whether the sRGB curve applies.
        let encoding = match (p.string("encoding")?, p.bool("gamma")?) {
            (Some(e), _) => ColorEncoding::parse(&e).ok_or_else(|| {
                SceneError::at(
                    loc,
                    format!("{what}: unknown encoding \"{e}\" (expected sRGB, linear or \"gamma G\")"),
                )
            })?,
            (None, Some(false)) => ColorEncoding::Linear,
            (None, _) => ColorEncoding::Srgb,
        };
        let mapping = tex_mapping(p, site, what, loc, w)?;
        let Some(file) = p.string("filename")? else {
            return Ok(Err("no \"string filename\" given".into()));
        };
        let image = crate::input::beside(site.base_dir, &file)
            .map_err(ImageLoadError::io(Path::new(&file)))
            .and_then(|path| self.images.load_levels(store, &path, encoding, Some(wrap)));
        let (image, levels) = match image {
            Ok(id) => id,
            Err(e) => {
                super::missing_file(loc, what, e.clone())?;
                return Ok(Err(e.to_string()));
            }
        };
        let channel = match kind {
            TexKind::Float => crate::Channel::Average,
            TexKind::Spectrum => crate::Channel::Rgb,
        };
        Ok(Ok(Texture::Image { image, mapping, wrap, channel, scale, invert, filter, levels }))
    }

    /// An area light's `filename`: the image as an RGB texture (sRGB for
    /// 8-bit files, clamped at the edges as pbrt-v4's `DiffuseAreaLight`
    /// reads it), through the scene's image cache.
    pub fn emission_image(
        &mut self,
        file: &str,
        base_dir: &Path,
        store: &mut Textures,
    ) -> Result<TextureId, ImageLoadError> {
        self.rgb_image(file, base_dir, store, ColorEncoding::Srgb, Wrap::Clamp)
    }

    /// A material's `normalmap`: the image read linearly (pbrt-v4 reads
    /// normal maps so), repeated, through the scene's image cache.
    pub fn normal_map(
        &mut self,
        file: &str,
        base_dir: &Path,
        store: &mut Textures,
    ) -> Result<TextureId, ImageLoadError> {
        self.rgb_image(file, base_dir, store, ColorEncoding::Linear, Wrap::Repeat)
    }

    /// Image `file` as an RGB texture over the surface's uv.
    fn rgb_image(
        &mut self,
        file: &str,
        base_dir: &Path,
        store: &mut Textures,
        encoding: ColorEncoding,
        wrap: Wrap,
    ) -> Result<TextureId, ImageLoadError> {
        let path = crate::input::beside(base_dir, file).map_err(ImageLoadError::io(Path::new(file)))?;
        let image = self.images.load(store, &path, encoding)?;
        Ok(store.add(Texture::Image {
            image,
            mapping: UvMapping::default().into(),
            wrap,
            channel: crate::Channel::Rgb,
            scale: 1.0,
            invert: false,
            filter: ImageFilter::None,
            levels: 1,
        }))
    }

    /// The texture called `name` of `kind`; `None` after a warning when
    /// there is none.
    fn lookup(
        &self,
        name: &str,
        kind: TexKind,
        param: &str,
        what: &str,
        loc: &FileLoc,
        w: &mut WarningSink,
    ) -> Option<TextureId> {
        let (own, other) = match kind {
            TexKind::Float => (&self.float, &self.spectrum),
            TexKind::Spectrum => (&self.spectrum, &self.float),
        };
        if let Some(&id) = own.get(name) {
            return Some(id);
        }
        let why = if other.contains_key(name) {
            format!("\"{name}\" is not a {} texture", kind.name())
        } else {
            format!("{} texture \"{name}\" is not defined before this line", kind.name())
        };
        w.warn(loc, format!("{what}: {why}; \"{param}\" uses its default"));
        None
    }

    /// A texture parameter of `kind`: a value or a named texture; `default`
    /// when absent or unusable.
    #[allow(clippy::too_many_arguments)]
    fn input(
        &self,
        p: &ParamList,
        name: &str,
        kind: TexKind,
        default: Rgb,
        what: &str,
        loc: &FileLoc,
        w: &mut WarningSink,
    ) -> Result<TexInput, SceneError> {
        Ok(self.optional_input(p, name, kind, what, loc, w)?.unwrap_or(TexInput::Value(default)))
    }

    /// As [`NamedTextures::input`], `None` when absent or unusable.
    fn optional_input(
        &self,
        p: &ParamList,
        name: &str,
        kind: TexKind,
        what: &str,
        loc: &FileLoc,
        w: &mut WarningSink,
    ) -> Result<Option<TexInput>, SceneError> {
        let named =
            |t: &str, w: &mut WarningSink| self.lookup(t, kind, name, what, loc, w).map(TexInput::Texture);
        Ok(match kind {
            TexKind::Float => match p.float_or_texture(name)? {
                None => None,
                Some(FloatOrTexture::Value(v)) => Some(TexInput::Value(Rgb::splat(v))),
                Some(FloatOrTexture::Texture(t)) => named(&t, w),
            },
            TexKind::Spectrum => match p.spectrum(name, true)? {
                None => None,
                Some(SpectrumParam::Texture(t)) => named(&t, w),
                Some(sp) => reflectance_rgb(sp, what, loc, w).map(TexInput::Value),
            },
        })
    }
}

/// The map from world space into the space of the `Texture` statement at `site`.
fn texture_from_world(site: &TextureSite) -> glam::Affine3A {
    glam::Affine3A::from_mat4(site.world_from_texture.inverse().as_mat4())
}

/// The noise texture of `class` (`fbm`, `wrinkled`, `windy` or `marble`)
/// with pbrt-v4's parameters and defaults.
fn noise(
    class: &str,
    p: &ParamList,
    what: &str,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> Result<Noise, SceneError> {
    if class == "windy" {
        return Ok(Noise::Windy);
    }
    let octaves = match p.int("octaves")?.unwrap_or(8) {
        n if n < 0 => {
            return Err(SceneError::at(loc, format!("{what}: \"octaves\" must not be negative, found {n}")))
        }
        n if n as u64 > Noise::MAX_OCTAVES as u64 => {
            w.warn(loc, format!("{what}: {n} octaves; summing the first {}", Noise::MAX_OCTAVES));
            Noise::MAX_OCTAVES
        }
        n => n as u32,
    };
    let omega = p.float_or("roughness", 0.5)?;
    Ok(match class {
        "fbm" => Noise::Fbm { octaves, omega },
        "wrinkled" => Noise::Wrinkled { octaves, omega },
        _ => Noise::Marble {
            octaves,
            omega,
            scale: p.float_or("scale", 1.0)?,
            variation: p.float_or("variation", 0.2)?,
        },
    })
}

/// pbrt-v4's 2D texture mapping (`TextureMapping2D::Create`): `uv`
/// (`uscale`, `vscale`, `udelta`, `vdelta`), or `spherical`, `cylindrical`
/// or `planar` (`v1`, `v2`, `udelta`, `vdelta`) of the hit point in the
/// texture's space (that of the `Texture` statement at `site`).
fn tex_mapping(
    p: &ParamList,
    site: &TextureSite,
    what: &str,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> Result<TexMapping, SceneError> {
    let texture_from_world = texture_from_world(site);
    let (du, dv) = (p.float_or("udelta", 0.0)?, p.float_or("vdelta", 0.0)?);
    Ok(match p.string("mapping")?.as_deref() {
        None | Some("uv") => TexMapping::Uv(UvMapping {
            su: p.float_or("uscale", 1.0)?,
            sv: p.float_or("vscale", 1.0)?,
            du,
            dv,
        }),
        Some("spherical") => TexMapping::Spherical { texture_from_world },
        Some("cylindrical") => TexMapping::Cylindrical { texture_from_world },
        Some("planar") => {
            let axis = |name: &str, default: glam::Vec3| -> Result<glam::Vec3, SceneError> {
                Ok(match p.numbers(name, ParamType::Vector3) {
                    Some([x, y, z]) => glam::DVec3::new(*x, *y, *z).as_vec3(),
                    Some(v) => {
                        return Err(SceneError::at(
                            loc,
                            format!("{what}: \"{name}\" needs 3 values, got {}", v.len()),
                        ))
                    }
                    None => default,
                })
            };
            let (vs, vt) = (axis("v1", glam::Vec3::X)?, axis("v2", glam::Vec3::Y)?);
            TexMapping::Planar { texture_from_world, vs, vt, ds: du, dt: dv }
        }
        // pbrt-v4 reports an unknown mapping and uses `uv`.
        Some(m) => {
            w.warn(loc, format!("{what}: unknown mapping \"{m}\"; using \"uv\""));
            TexMapping::Uv(UvMapping {
                su: p.float_or("uscale", 1.0)?,
                sv: p.float_or("vscale", 1.0)?,
                du,
                dv,
            })
        }
    })
}

/// Texture access while a material is made: looks up its texture-valued
/// parameters and collects its bindings.
pub struct TexCtx<'a> {
    named: &'a NamedTextures,
    store: &'a mut Textures,
    /// The bindings of the material being made: (parameter, texture, remap roughness).
    pub bindings: Vec<(TexturedParam, TextureId, bool)>,
}

impl<'a> TexCtx<'a> {
    pub fn new(named: &'a NamedTextures, store: &'a mut Textures) -> Self {
        TexCtx { named, store, bindings: Vec::new() }
    }

    /// A spectrum parameter (`rgb`, `spectrum`, `blackbody`, `float` or
    /// `texture`); `None` when absent or unusable (after a warning).
    pub fn spectrum(
        &self,
        p: &ParamList,
        name: &str,
        what: &str,
        loc: &FileLoc,
        w: &mut WarningSink,
    ) -> Result<Option<TexInput>, SceneError> {
        self.named.optional_input(p, name, TexKind::Spectrum, what, loc, w)
    }

    /// A float parameter (`float` or `texture`); `None` when absent or unusable.
    pub fn float(
        &self,
        p: &ParamList,
        name: &str,
        what: &str,
        loc: &FileLoc,
        w: &mut WarningSink,
    ) -> Result<Option<TexInput>, SceneError> {
        self.named.optional_input(p, name, TexKind::Float, what, loc, w)
    }

    /// Binds `param` to `input` per hit even where it is a constant (which
    /// becomes a constant texture): for a parameter derived per hit from
    /// others that are textures.
    pub fn bind_always(&mut self, input: TexInput, param: TexturedParam) {
        let texture = match input {
            TexInput::Value(v) => self.store.add(crate::Texture::Constant(v)),
            TexInput::Texture(t) => t,
        };
        self.bindings.push((param, texture, false));
    }

    /// The material's constant for `input`: the value itself, or for a
    /// texture `default` (what the material keeps) with a binding of `param`.
    pub fn value_or_bind(&mut self, input: TexInput, param: TexturedParam, default: Rgb) -> Rgb {
        match input {
            TexInput::Value(v) => v,
            TexInput::Texture(t) => {
                self.bindings.push((param, t, false));
                default
            }
        }
    }

    /// The product of two inputs: a value when both are, else a `Scale` node.
    pub fn product(&mut self, a: TexInput, b: TexInput) -> TexInput {
        match (a, b) {
            (TexInput::Value(x), TexInput::Value(y)) => TexInput::Value(x * y),
            (t, TexInput::Value(v)) | (TexInput::Value(v), t) if v == Rgb::ONE => t,
            _ => TexInput::Texture(self.store.add(Texture::Scale { tex: a, scale: b })),
        }
    }
}
