//! Textures as the scene describes them: decoded images, the procedural and
//! combining textures pbrt-v4 names (`imagemap`, `checkerboard`, `constant`,
//! `scale`, `mix`), their bindings to material parameters, and alpha masks
//! that cut geometry.
//!
//! Every texture evaluates to an RGB triple; a *float* texture is one whose
//! value has three equal channels (an image read as float averages its
//! colour channels, or reads one channel, see [`Channel`]). The renderer
//! (`atoll_render::texture`) flattens these trees into one program that the
//! CPU and the GPU both run.

use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use crate::{MaterialId, MeshId, Rgb};

/// Index of a texture in [`Textures::textures`].
pub type TextureId = u32;
/// Index of an image in [`Textures::images`].
pub type ImageId = u32;

/// Texel storage. 8-bit files stay 8-bit (a quarter of float storage, which
/// matters for film assets with gigabytes of textures); HDR and EXR files keep
/// floats.
#[derive(Clone, Debug, PartialEq)]
pub enum Texels {
    /// RGBA bytes; `srgb` says the colour channels are sRGB-encoded (alpha
    /// never is), decoded through [`srgb8_to_linear`].
    Rgba8 { srgb: bool, data: Vec<[u8; 4]> },
    /// Linear RGBA floats.
    RgbaF32(Vec<[f32; 4]>),
}

/// A decoded image, row 0 at the top of the picture (as files store it).
#[derive(Clone, Debug, PartialEq)]
pub struct TextureImage {
    /// The file it came from, or a name given by the loader, for messages.
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub texels: Texels,
}

/// Why an image (a texture or an environment map) could not be had.
///
/// Cheap to clone (wrapped errors are shared), so that [`ImageCache`] can
/// hand the same failure to every texture naming the file. Each message
/// names the file and already says what the wrapped error says; the wrapped
/// error is also the [`std::error::Error::source`].
#[derive(Clone, Debug)]
pub enum ImageLoadError {
    /// The file could not be opened or read.
    Io { path: PathBuf, source: Arc<std::io::Error> },
    /// The `image` crate could not decode the file.
    Decode { path: PathBuf, source: Arc<image::ImageError> },
    /// The `exr` crate could not read the file.
    Exr { path: PathBuf, source: Arc<exr::error::Error> },
    /// glTF could not produce an image's pixels (a bad URI or buffer view,
    /// an embedded image that does not decode).
    Gltf(Arc<::gltf::Error>),
    /// Environment maps are read from EXR and PNG files only.
    EnvironmentFormat { path: PathBuf },
    /// The image has no pixels.
    Empty { path: PathBuf },
    /// A float texel is infinite or NaN.
    NonFiniteTexel { path: PathBuf, x: u32, y: u32 },
    /// An environment pixel is negative, infinite or NaN.
    BadEnvironmentPixel { path: PathBuf, x: u32, y: u32 },
    /// Decoded pixel data that does not fill the image's size.
    TexelCount { width: u32, height: u32, texels: usize },
}

impl ImageLoadError {
    pub(crate) fn io(path: &Path) -> impl FnOnce(std::io::Error) -> Self + '_ {
        |e| ImageLoadError::Io { path: path.to_path_buf(), source: Arc::new(e) }
    }

    pub(crate) fn decode(path: &Path) -> impl FnOnce(image::ImageError) -> Self + '_ {
        |e| ImageLoadError::Decode { path: path.to_path_buf(), source: Arc::new(e) }
    }

    pub(crate) fn exr(path: &Path) -> impl FnOnce(exr::error::Error) -> Self + '_ {
        |e| ImageLoadError::Exr { path: path.to_path_buf(), source: Arc::new(e) }
    }
}

impl fmt::Display for ImageLoadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use ImageLoadError as E;
        match self {
            E::Io { path, source } => write!(f, "{}: {source}", path.display()),
            E::Decode { path, source } => write!(f, "{}: {source}", path.display()),
            E::Exr { path, source } => write!(f, "{}: {source}", path.display()),
            E::Gltf(source) => write!(f, "{source}"),
            E::EnvironmentFormat { path } => {
                write!(f, "{}: environment images must be .exr or .png", path.display())
            }
            E::Empty { path } => write!(f, "{}: the image is empty", path.display()),
            E::NonFiniteTexel { path, x, y } => {
                write!(f, "{}: texel ({x}, {y}) is not finite", path.display())
            }
            E::BadEnvironmentPixel { path, x, y } => {
                write!(f, "{}: pixel ({x}, {y}) is negative or not finite", path.display())
            }
            E::TexelCount { width, height, texels } => {
                write!(f, "{width}x{height} pixels but {texels} texels decoded")
            }
        }
    }
}

// By hand rather than derived: the source must be the wrapped error itself
// (so callers can downcast it), not the `Arc` that makes this type cloneable.
impl std::error::Error for ImageLoadError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        use ImageLoadError as E;
        match self {
            E::Io { source, .. } => Some(&**source),
            E::Decode { source, .. } => Some(&**source),
            E::Exr { source, .. } => Some(&**source),
            E::Gltf(source) => Some(&**source),
            _ => None,
        }
    }
}

/// The 256 linear values of the sRGB-encoded bytes. One table for CPU and
/// GPU (it is uploaded), so both decode a texel to the same float.
pub fn srgb8_to_linear() -> &'static [f32; 256] {
    static TABLE: OnceLock<[f32; 256]> = OnceLock::new();
    TABLE.get_or_init(|| {
        std::array::from_fn(|i| {
            let c = i as f64 / 255.0;
            (if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }) as f32
        })
    })
}

impl TextureImage {
    /// A linear float image (tests and procedural content).
    pub fn from_linear(name: &str, width: u32, height: u32, texels: Vec<[f32; 4]>) -> Self {
        assert_eq!(texels.len(), (width * height) as usize);
        TextureImage { name: name.into(), width, height, texels: Texels::RgbaF32(texels) }
    }

    /// Decodes an image file: EXR (floats), Radiance HDR (floats), PNG,
    /// JPEG, TGA and BMP (8-bit, sRGB unless `srgb` is false: pbrt's
    /// `encoding "linear"`). 16-bit PNGs are kept as floats.
    pub fn decode(path: &Path, srgb: bool) -> Result<Self, ImageLoadError> {
        crate::input::check_regular(path).map_err(ImageLoadError::io(path))?;
        let name = path.display().to_string();
        let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
        let (width, height, texels) = if ext.as_deref() == Some("exr") {
            let img = exr::prelude::read_first_rgba_layer_from_file(
                path,
                |res, _| (res.width(), vec![[0f32; 4]; res.width() * res.height()]),
                |(w, px): &mut (usize, Vec<[f32; 4]>), pos, (r, g, b, a): (f32, f32, f32, f32)| {
                    px[pos.y() * *w + pos.x()] = [r, g, b, a]
                },
            )
            .map_err(ImageLoadError::exr(path))?;
            let size = img.layer_data.size;
            (size.width() as u32, size.height() as u32, Texels::RgbaF32(img.layer_data.channel_data.pixels.1))
        } else {
            let img = image::ImageReader::open(path)
                .map_err(ImageLoadError::io(path))?
                .with_guessed_format()
                .map_err(ImageLoadError::io(path))?
                .decode()
                .map_err(ImageLoadError::decode(path))?;
            let (w, h) = (img.width(), img.height());
            use image::ColorType as C;
            let float = !matches!(img.color(), C::L8 | C::La8 | C::Rgb8 | C::Rgba8);
            if float {
                let hdr = matches!(img.color(), C::Rgb32F | C::Rgba32F);
                let decode = |c: f32| if hdr || !srgb { c } else { srgb8_to_linear_f32(c) };
                let data = img
                    .to_rgba32f()
                    .pixels()
                    .map(|p| [decode(p[0]), decode(p[1]), decode(p[2]), p[3]])
                    .collect();
                (w, h, Texels::RgbaF32(data))
            } else {
                (w, h, Texels::Rgba8 { srgb, data: img.to_rgba8().pixels().map(|p| p.0).collect() })
            }
        };
        if width == 0 || height == 0 {
            return Err(ImageLoadError::Empty { path: path.to_path_buf() });
        }
        if let Texels::RgbaF32(px) = &texels {
            if let Some(bad) = px.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
                let (x, y) = (bad as u32 % width, bad as u32 / width);
                return Err(ImageLoadError::NonFiniteTexel { path: path.to_path_buf(), x, y });
            }
        }
        Ok(TextureImage { name, width, height, texels })
    }

    /// Linear RGBA of texel `(x, y)` (in range).
    #[inline]
    pub fn texel(&self, x: u32, y: u32) -> [f32; 4] {
        let i = (y * self.width + x) as usize;
        match &self.texels {
            Texels::Rgba8 { srgb, data } => {
                let [r, g, b, a] = data[i];
                let table = srgb8_to_linear();
                let c = |v: u8| if *srgb { table[v as usize] } else { v as f32 * (1.0 / 255.0) };
                [c(r), c(g), c(b), a as f32 * (1.0 / 255.0)]
            }
            Texels::RgbaF32(data) => data[i],
        }
    }

    /// Bytes of texel storage.
    pub fn memory_bytes(&self) -> u64 {
        match &self.texels {
            Texels::Rgba8 { data, .. } => data.len() as u64 * 4,
            Texels::RgbaF32(data) => data.len() as u64 * 16,
        }
    }
}

/// How an image file's 8- and 16-bit colour values map to linear ones
/// (pbrt-v4's `encoding` of image textures). Float files (EXR, HDR) are
/// linear whatever is asked.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum ColorEncoding {
    /// The sRGB curve (what 8-bit files default to).
    #[default]
    Srgb,
    Linear,
    /// `value^gamma` (pbrt-v4's `"gamma 2.2"`).
    Gamma(f32),
}

impl ColorEncoding {
    /// pbrt-v4's spellings: `sRGB`, `linear`, `gamma G` (case-insensitive).
    pub fn parse(s: &str) -> Option<ColorEncoding> {
        let lower = s.trim().to_ascii_lowercase();
        match lower.as_str() {
            "srgb" => Some(ColorEncoding::Srgb),
            "linear" => Some(ColorEncoding::Linear),
            _ => {
                let g: f32 = lower.strip_prefix("gamma")?.trim().parse().ok()?;
                (g.is_finite() && g > 0.0).then_some(ColorEncoding::Gamma(g))
            }
        }
    }

    /// A hashable identity (for caches keyed by encoding).
    fn key(self) -> (u8, u32) {
        match self {
            ColorEncoding::Srgb => (0, 0),
            ColorEncoding::Linear => (1, 0),
            ColorEncoding::Gamma(g) => (2, g.to_bits()),
        }
    }
}

impl TextureImage {
    /// [`TextureImage::decode`] with any [`ColorEncoding`]. A gamma curve
    /// has no 8-bit table, so such images are kept as floats.
    pub fn decode_encoded(path: &Path, encoding: ColorEncoding) -> Result<Self, ImageLoadError> {
        let gamma = match encoding {
            ColorEncoding::Srgb => return Self::decode(path, true),
            ColorEncoding::Linear => return Self::decode(path, false),
            ColorEncoding::Gamma(g) => g,
        };
        let mut image = Self::decode(path, false)?;
        let ext = path.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
        if matches!(ext.as_deref(), Some("exr" | "hdr")) {
            return Ok(image);
        }
        let curve = |c: f32| c.powf(gamma);
        let data = match &image.texels {
            Texels::Rgba8 { data, .. } => data
                .iter()
                .map(|p| {
                    let c = |v: u8| curve(v as f32 * (1.0 / 255.0));
                    [c(p[0]), c(p[1]), c(p[2]), p[3] as f32 * (1.0 / 255.0)]
                })
                .collect(),
            Texels::RgbaF32(data) => {
                data.iter().map(|p| [curve(p[0]), curve(p[1]), curve(p[2]), p[3]]).collect()
            }
        };
        image.texels = Texels::RgbaF32(data);
        Ok(image)
    }

    /// Whether any texel is less than fully opaque: an alpha channel that
    /// carries a mask (an opaque one says nothing).
    pub fn has_alpha(&self) -> bool {
        match &self.texels {
            Texels::Rgba8 { data, .. } => data.iter().any(|p| p[3] < 255),
            Texels::RgbaF32(data) => data.iter().any(|p| p[3] < 1.0),
        }
    }
}

/// Decodes each image file once per scene (per encoding), whichever
/// textures and loaders name it: keyed by canonical path and encoding.
/// Failures are remembered too, so a missing file is looked for once. An
/// image is added to the scene once as it is and once per wrap mode as a
/// MIP pyramid ([`crate::mipmap`]), as textures ask.
#[derive(Debug, Default)]
pub struct ImageCache {
    decoded: HashMap<ImageKey, Result<Arc<TextureImage>, ImageLoadError>>,
    /// Added images: the first and how many (a pyramid's levels), by file,
    /// encoding and the pyramid's wrap mode (`None`: the image as it is).
    added: HashMap<(ImageKey, Option<Wrap>), (ImageId, u32)>,
}

/// An image file (canonical path) and its encoding ([`ColorEncoding::key`]).
type ImageKey = (PathBuf, (u8, u32));

impl ImageCache {
    /// The image of `path` in `textures`, decoded and added on first use.
    pub fn load(
        &mut self,
        textures: &mut Textures,
        path: &Path,
        encoding: ColorEncoding,
    ) -> Result<ImageId, ImageLoadError> {
        self.load_levels(textures, path, encoding, None).map(|(first, _)| first)
    }

    /// The image of `path` in `textures` as it is (`pyramid_wrap` `None`),
    /// or its MIP pyramid under that wrap mode: the first image and how
    /// many follow it.
    pub fn load_levels(
        &mut self,
        textures: &mut Textures,
        path: &Path,
        encoding: ColorEncoding,
        pyramid_wrap: Option<Wrap>,
    ) -> Result<(ImageId, u32), ImageLoadError> {
        // A path that does not resolve is its own key; decoding then reports why.
        let canonical = path.canonicalize().unwrap_or_else(|_| path.to_path_buf());
        let key = (canonical, encoding.key());
        let decoded = self
            .decoded
            .entry(key.clone())
            .or_insert_with(|| TextureImage::decode_encoded(path, encoding).map(Arc::new))
            .clone()?;
        let added = self.added.entry((key, pyramid_wrap)).or_insert_with(|| match pyramid_wrap {
            None => (textures.add_shared_image(decoded), 1),
            Some(wrap) => textures.add_pyramid(&decoded, wrap),
        });
        Ok(*added)
    }
}

/// The sRGB curve for a 16-bit channel already scaled to [0, 1].
fn srgb8_to_linear_f32(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// What an image lookup outside [0, 1) does (pbrt-v4's `wrap`; glTF's
/// samplers add mirrored repeat).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[repr(u32)]
pub enum Wrap {
    #[default]
    Repeat = 0,
    Clamp = 1,
    /// Outside the image is black (and transparent).
    Black = 2,
    Mirror = 3,
}

impl Wrap {
    /// The texel that coordinate `i` of a side of `n` texels addresses;
    /// `None`: black.
    #[inline]
    pub fn texel(self, i: i64, n: i64) -> Option<i64> {
        if (0..n).contains(&i) {
            return Some(i);
        }
        match self {
            Wrap::Clamp => Some(i.clamp(0, n - 1)),
            Wrap::Black => None,
            Wrap::Mirror => {
                let period = i.rem_euclid(2 * n);
                Some(if period < n { period } else { 2 * n - 1 - period })
            }
            Wrap::Repeat => Some(i.rem_euclid(n)),
        }
    }

    /// [`Wrap::texel`] for a mode given as its number (the texture
    /// programs'); unknown numbers repeat.
    #[inline]
    pub fn texel_of(mode: u32, i: i64, n: i64) -> Option<i64> {
        let wrap = [Wrap::Repeat, Wrap::Clamp, Wrap::Black, Wrap::Mirror]
            .into_iter()
            .find(|w| *w as u32 == mode)
            .unwrap_or(Wrap::Repeat);
        wrap.texel(i, n)
    }

    /// pbrt-v4's names (`octahedralsphere` is not supported).
    pub fn parse(s: &str) -> Option<Wrap> {
        Some(match s {
            "repeat" => Wrap::Repeat,
            "clamp" => Wrap::Clamp,
            "black" => Wrap::Black,
            "mirror" => Wrap::Mirror,
            _ => return None,
        })
    }
}

/// pbrt-v4's image texture `filter`: how a lookup averages the texels a
/// pixel's footprint covers, through the image's MIP pyramid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(u32)]
pub enum ImageFilter {
    /// The image itself, bilinearly, whatever the footprint: area lights'
    /// images and normal maps, which pbrt-v4 reads so, and the textures of
    /// glTF and OBJ files.
    #[default]
    None = 0,
    /// The nearest texel of the level the footprint picks.
    Point = 1,
    /// Bilinear in the level the footprint picks (pbrt-v4's default).
    Bilinear = 2,
    /// Bilinear in the two levels about the footprint, blended.
    Trilinear = 3,
    /// pbrt-v4's elliptically weighted average (filtered trilinearly here).
    Ewa = 4,
}

impl ImageFilter {
    /// pbrt-v4's names.
    pub fn parse(s: &str) -> Option<ImageFilter> {
        Some(match s {
            "point" => ImageFilter::Point,
            "bilinear" => ImageFilter::Bilinear,
            "trilinear" => ImageFilter::Trilinear,
            "ewa" | "EWA" => ImageFilter::Ewa,
            _ => return None,
        })
    }
}

/// Which value of a texel an image texture returns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[repr(u32)]
pub enum Channel {
    /// The colour.
    #[default]
    Rgb = 0,
    /// The mean of the colour channels, in all three (a float texture).
    Average = 1,
    /// Alpha, in all three (cut-out masks of OBJ's `map_d` and glTF's base colour).
    Alpha = 2,
    /// One colour channel (0 red, 1 green, 2 blue) in all three: glTF packs
    /// roughness in green and metalness in blue of one image.
    Red = 3,
    Green = 4,
    Blue = 5,
}

/// pbrt's `uv` texture mapping: `s = su * u + du`, `t = sv * v + dv`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvMapping {
    pub su: f32,
    pub sv: f32,
    pub du: f32,
    pub dv: f32,
}

impl Default for UvMapping {
    fn default() -> Self {
        UvMapping { su: 1.0, sv: 1.0, du: 0.0, dv: 0.0 }
    }
}

impl UvMapping {
    /// glTF and most real-time formats put `v = 0` at the top of the image;
    /// pbrt (and atoll's image lookup) at the bottom.
    pub const FLIP_V: UvMapping = UvMapping { su: 1.0, sv: -1.0, du: 0.0, dv: 1.0 };
}

/// How a texture finds its (s, t) at a hit: pbrt-v4's 2D texture mappings.
/// The 3D ones map the hit point `p` (world space) through
/// `texture_from_world`, the inverse of the transform current at the
/// `Texture` statement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TexMapping {
    /// The surface's (u, v), scaled and offset.
    Uv(UvMapping),
    /// `(θ / π, φ / 2π)` of the direction to `q = texture_from_world(p)`
    /// (θ from +z, φ about z from +x).
    Spherical { texture_from_world: glam::Affine3A },
    /// `((π + atan2(q.y, q.x)) / 2π, q.z)`.
    Cylindrical { texture_from_world: glam::Affine3A },
    /// `(ds + vs · q, dt + vt · q)`.
    Planar { texture_from_world: glam::Affine3A, vs: glam::Vec3, vt: glam::Vec3, ds: f32, dt: f32 },
}

impl Default for TexMapping {
    fn default() -> Self {
        TexMapping::Uv(UvMapping::default())
    }
}

impl From<UvMapping> for TexMapping {
    fn from(m: UvMapping) -> Self {
        TexMapping::Uv(m)
    }
}

/// Which of pbrt-v4's noise textures, with its parameters (`omega` is
/// pbrt's `roughness`, the weight of each octave relative to the last).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Noise {
    Fbm { octaves: u32, omega: f32 },
    Wrinkled { octaves: u32, omega: f32 },
    Windy,
    Marble { octaves: u32, omega: f32, scale: f32, variation: f32 },
}

impl Noise {
    /// Most octaves a noise texture sums: past this an octave's weight is
    /// below 2^-32 of the first at pbrt's default roughness, and its
    /// frequency runs towards overflow.
    pub const MAX_OCTAVES: u32 = 32;
}

/// A texture input that is either a value or another texture (pbrt lets
/// most texture parameters be either).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TexInput {
    Value(Rgb),
    Texture(TextureId),
}

/// A texture node.
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    Constant(Rgb),
    /// `v = scale * lookup(image, mapping(uv))`, then `max(0, 1 - v)` when
    /// `invert` (pbrt-v4's order). The lookup is bilinear in `image` for
    /// [`ImageFilter::None`]; otherwise `image` is the first of `levels`
    /// MIP levels that `filter` picks from by the hit's footprint.
    Image {
        image: ImageId,
        mapping: TexMapping,
        wrap: Wrap,
        channel: Channel,
        scale: f32,
        invert: bool,
        filter: ImageFilter,
        levels: u32,
    },
    /// `tex[0]` where `floor(s) + floor(t)` is even, else `tex[1]`.
    Checkerboard {
        mapping: TexMapping,
        tex: [TexInput; 2],
    },
    /// `|n · direction|` in all three channels, `n` the hit's geometric
    /// normal: pbrt-v4's `directionmix` is a [`Texture::Mix`] by it.
    Facing {
        direction: glam::Vec3,
    },
    /// pbrt-v4's solid noise textures of the point `texture_from_world(p)`:
    /// `fbm`, `wrinkled`, `windy` and `marble` (`atoll_render::noise`).
    Noise {
        noise: Noise,
        texture_from_world: glam::Affine3A,
    },
    /// pbrt's 3D checkerboard: `tex[0]` where `floor(q.x) + floor(q.y) +
    /// floor(q.z)` is even, `q = texture_from_world(p)`, else `tex[1]`.
    SolidCheckerboard {
        texture_from_world: glam::Affine3A,
        tex: [TexInput; 2],
    },
    /// pbrt's `bilerp`: the bilinear blend of `corners` (v00, v10, v01,
    /// v11) over (s, t).
    Bilerp {
        mapping: TexMapping,
        corners: [TexInput; 4],
    },
    /// pbrt's polka dots: `tex[0]` inside the dots of the (s, t) plane,
    /// `tex[1]` outside.
    Dots {
        mapping: TexMapping,
        tex: [TexInput; 2],
    },
    /// The product of both inputs.
    Scale {
        tex: TexInput,
        scale: TexInput,
    },
    /// `(1 - amount) * tex[0] + amount * tex[1]`, `amount` read as a float
    /// (its first channel).
    Mix {
        tex: [TexInput; 2],
        amount: TexInput,
    },
}

/// A material parameter a texture can drive. Each material kind reads the
/// ones it has; the renderer maps them to record coefficients.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TexturedParam {
    /// Diffuse / diffuse-transmission / conductor reflectance, principled base colour.
    Reflectance,
    /// Diffuse-transmission transmittance.
    Transmittance,
    /// Both roughnesses (pbrt's `roughness`), before `remaproughness`.
    Roughness,
    URoughness,
    VRoughness,
    /// A coated conductor's conductor roughnesses (`conductor.roughness`
    /// and the like; its coating's are [`TexturedParam::Roughness`] and
    /// the like).
    ConductorRoughness,
    ConductorURoughness,
    ConductorVRoughness,
    /// Principled metalness.
    Metallic,
    /// A `mix` material's probability of its second material (read as a
    /// float: the first channel).
    Amount,
    /// Conductor's complex index of refraction (spectrum textures); a hair
    /// fibre's index (a float texture).
    Eta,
    K,
    /// Coated materials: the medium's thickness, albedo and asymmetry `g`.
    Thickness,
    Albedo,
    G,
    /// pbrt's bump map: a float texture of displacement along the shading
    /// normal, which bends the normal (the surface stays where it is).
    Displacement,
    /// pbrt's normal map: an RGB image of tangent-space normals (`2 c - 1`
    /// in the frame of the surface's dpdu and shading normal).
    NormalMap,
    /// Principled weights (pbrt-v3 `disney` names in [`TexturedParam::pbrt_name`]).
    SpecularTint,
    Sheen,
    SheenTint,
    Clearcoat,
    ClearcoatGloss,
    Transmission,
    /// A hair fibre's absorption coefficient.
    SigmaA,
    /// A hair fibre's longitudinal and azimuthal roughness (clamped to
    /// [0.01, 1] where evaluated, as pbrt-v4 does).
    BetaM,
    BetaN,
    /// A hair fibre's scale tilt (degrees).
    HairAlpha,
    /// A hair fibre's concentrations of eumelanin and pheomelanin, whose
    /// absorptions add up to its `sigma_a` where evaluated.
    Eumelanin,
    Pheomelanin,
}

impl TexturedParam {
    /// pbrt-v4's parameter name.
    pub fn pbrt_name(self) -> &'static str {
        match self {
            TexturedParam::Reflectance => "reflectance",
            TexturedParam::Transmittance => "transmittance",
            TexturedParam::Roughness => "roughness",
            TexturedParam::URoughness => "uroughness",
            TexturedParam::VRoughness => "vroughness",
            TexturedParam::ConductorRoughness => "conductor.roughness",
            TexturedParam::ConductorURoughness => "conductor.uroughness",
            TexturedParam::ConductorVRoughness => "conductor.vroughness",
            TexturedParam::Metallic => "metallic",
            TexturedParam::Amount => "amount",
            TexturedParam::Displacement => "displacement",
            TexturedParam::NormalMap => "normalmap",
            TexturedParam::Eta => "eta",
            TexturedParam::K => "k",
            TexturedParam::Thickness => "thickness",
            TexturedParam::Albedo => "albedo",
            TexturedParam::G => "g",
            TexturedParam::SpecularTint => "speculartint",
            TexturedParam::Sheen => "sheen",
            TexturedParam::SheenTint => "sheentint",
            TexturedParam::Clearcoat => "clearcoat",
            TexturedParam::ClearcoatGloss => "clearcoatgloss",
            TexturedParam::Transmission => "spectrans",
            TexturedParam::SigmaA => "sigma_a",
            TexturedParam::BetaM => "beta_m",
            TexturedParam::BetaN => "beta_n",
            TexturedParam::HairAlpha => "alpha",
            TexturedParam::Eumelanin => "eumelanin",
            TexturedParam::Pheomelanin => "pheomelanin",
        }
    }
}

/// "This material's `param` comes from `texture`."
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureBinding {
    pub material: MaterialId,
    pub param: TexturedParam,
    pub texture: TextureId,
    /// pbrt's `remaproughness` for roughness parameters: the texture gives
    /// perceptual roughness, the material wants GGX alpha (`sqrt`).
    pub remap_roughness: bool,
}

/// How a shape's alpha cuts it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    /// pbrt: alpha 0 is a hole, 1 solid, values between let a ray through
    /// with probability `1 - alpha` (decided by a hash of the ray, so every
    /// device decides alike).
    Stochastic,
    /// glTF `MASK` / OBJ: solid where alpha ≥ the cutoff, a hole elsewhere.
    Cutoff(f32),
}

/// A shape's alpha mask.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshAlpha {
    pub texture: TextureId,
    pub mode: AlphaMode,
}

/// All textures of a scene.
#[derive(Clone, Debug, Default)]
pub struct Textures {
    /// Shared (`Arc`): the renderer's light table keeps the images emission
    /// textures read without copying texels.
    pub images: Vec<Arc<TextureImage>>,
    pub textures: Vec<Texture>,
    pub bindings: Vec<TextureBinding>,
    /// Meshes whose area emission is scaled by a texture (pbrt's area light
    /// `filename`, glTF's `emissiveTexture`): `(mesh, texture)`.
    pub emission: Vec<(MeshId, TextureId)>,
}

impl Textures {
    pub fn add_image(&mut self, image: TextureImage) -> ImageId {
        self.add_shared_image(Arc::new(image))
    }

    pub fn add_shared_image(&mut self, image: Arc<TextureImage>) -> ImageId {
        self.images.push(image);
        (self.images.len() - 1) as ImageId
    }

    /// Adds `image`'s MIP pyramid under `wrap` ([`crate::mipmap`]): its
    /// first level and how many there are (consecutive). A level equal to
    /// the image (sides that are powers of two) shares its texels.
    pub fn add_pyramid(&mut self, image: &Arc<TextureImage>, wrap: Wrap) -> (ImageId, u32) {
        let pyramid = crate::mipmap::pyramid(image, wrap);
        let first = self.images.len() as ImageId;
        self.images.push(pyramid.resized.map_or_else(|| image.clone(), Arc::new));
        self.images.extend(pyramid.coarser.into_iter().map(Arc::new));
        (first, self.images.len() as u32 - first)
    }

    pub fn add(&mut self, texture: Texture) -> TextureId {
        self.textures.push(texture);
        (self.textures.len() - 1) as TextureId
    }

    /// Binds `texture` to a material parameter, replacing an earlier binding
    /// of the same parameter.
    pub fn bind(&mut self, binding: TextureBinding) {
        self.bindings.retain(|b| !(b.material == binding.material && b.param == binding.param));
        self.bindings.push(binding);
    }

    /// Scales `mesh`'s area emission by `texture` (replacing an earlier one).
    pub fn bind_emission(&mut self, mesh: MeshId, texture: TextureId) {
        self.emission.retain(|(m, _)| *m != mesh);
        self.emission.push((mesh, texture));
    }

    /// The texture scaling `mesh`'s emission, if any.
    pub fn emission_of(&self, mesh: MeshId) -> Option<TextureId> {
        self.emission.iter().find(|(m, _)| *m == mesh).map(|(_, t)| *t)
    }

    /// The bindings of one material.
    pub fn bindings_of(&self, material: MaterialId) -> impl Iterator<Item = &TextureBinding> {
        self.bindings.iter().filter(move |b| b.material == material)
    }

    /// Bytes of image texels (what dominates texture memory).
    pub fn memory_bytes(&self) -> u64 {
        self.images.iter().map(|i| i.memory_bytes()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.textures.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_table_matches_the_curve() {
        let t = srgb8_to_linear();
        assert_eq!(t[0], 0.0);
        assert_eq!(t[255], 1.0);
        assert!((t[128] - 0.2158605).abs() < 1e-6, "{}", t[128]);
        assert!(t.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn decoding_reads_png_texels_and_reports_bad_files() {
        let dir = std::env::temp_dir().join(format!("atoll-tex-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.png");
        let mut img = image::RgbaImage::new(2, 1);
        img.put_pixel(0, 0, image::Rgba([255, 128, 0, 255]));
        img.put_pixel(1, 0, image::Rgba([0, 0, 255, 0]));
        img.save(&path).unwrap();
        let t = TextureImage::decode(&path, true).unwrap();
        assert_eq!((t.width, t.height, t.memory_bytes()), (2, 1, 8));
        assert_eq!(t.texel(0, 0), [1.0, srgb8_to_linear()[128], 0.0, 1.0]);
        assert_eq!(t.texel(1, 0), [0.0, 0.0, 1.0, 0.0]);
        let linear = TextureImage::decode(&path, false).unwrap();
        assert_eq!(linear.texel(0, 0)[1], 128.0 / 255.0);
        std::fs::write(dir.join("bad.png"), b"not a png").unwrap();
        let err = TextureImage::decode(&dir.join("bad.png"), true).unwrap_err();
        assert!(err.to_string().contains("bad.png"), "{err}");
        // The decoder's own error stays reachable underneath.
        let source = std::error::Error::source(&err).expect("a source");
        assert!(source.downcast_ref::<image::ImageError>().is_some(), "{err:?}");
        let missing = TextureImage::decode(&dir.join("missing.png"), true).unwrap_err();
        assert!(
            matches!(&missing, ImageLoadError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound)
        );
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn encodings_parse_and_decode_once_per_file() {
        assert_eq!(ColorEncoding::parse("sRGB"), Some(ColorEncoding::Srgb));
        assert_eq!(ColorEncoding::parse("linear"), Some(ColorEncoding::Linear));
        assert_eq!(ColorEncoding::parse("gamma 2.2"), Some(ColorEncoding::Gamma(2.2)));
        assert_eq!(ColorEncoding::parse("gamma -1"), None);
        assert_eq!(ColorEncoding::parse("log"), None);
        let dir = std::env::temp_dir().join(format!("atoll-tex-enc-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("g.png");
        image::RgbaImage::from_pixel(1, 1, image::Rgba([128, 255, 0, 255])).save(&path).unwrap();
        let g = TextureImage::decode_encoded(&path, ColorEncoding::Gamma(2.0)).unwrap();
        assert_eq!(g.texel(0, 0), [(128.0f32 / 255.0).powi(2), 1.0, 0.0, 1.0]);
        assert!(!g.has_alpha());
        let mut textures = Textures::default();
        let mut cache = ImageCache::default();
        let a = cache.load(&mut textures, &path, ColorEncoding::Srgb).unwrap();
        // The same file by another spelling of its path is the same image.
        let b = cache.load(&mut textures, &dir.join(".").join("g.png"), ColorEncoding::Srgb).unwrap();
        let c = cache.load(&mut textures, &path, ColorEncoding::Linear).unwrap();
        assert_eq!((a, b, c, textures.images.len()), (0, 0, 1, 2));
        let missing = cache.load(&mut textures, &dir.join("none.png"), ColorEncoding::Srgb).unwrap_err();
        // Remembered: the second request gets the same failure without looking again.
        let again = cache.load(&mut textures, &dir.join("none.png"), ColorEncoding::Srgb).unwrap_err();
        assert_eq!(missing.to_string(), again.to_string());
        assert!(missing.to_string().contains("none.png"), "{missing}");
        assert_eq!(textures.images.len(), 2);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn rebinding_a_parameter_replaces_it() {
        let mut t = Textures::default();
        let a = t.add(Texture::Constant(Rgb::ONE));
        let b = t.add(Texture::Constant(Rgb::ZERO));
        let bind = |texture| TextureBinding {
            material: 3,
            param: TexturedParam::Reflectance,
            texture,
            remap_roughness: false,
        };
        t.bind(bind(a));
        t.bind(bind(b));
        assert_eq!(t.bindings_of(3).map(|b| b.texture).collect::<Vec<_>>(), [b]);
    }
}
