//! The scene model of atoll and everything that produces one: the loaders
//! (PBRT v4 and v3, OBJ/MTL, glTF 2.0, PLY, OFF; [`load_any`] picks one by
//! extension), default framing for files without a camera, the built-in
//! Cornell box and procedural scenes (the benchmark [`landscape`]).
//!
//! A [`Scene`] is two-level: [`Object`]s are groups of [`TriangleMesh`]es, and
//! [`Instance`]s place objects in the world with an affine transform. Geometry
//! outside any `ObjectBegin` block lives in world space in the *world object*,
//! which has exactly one identity instance. Instancing never copies a mesh.

pub mod camera;
pub mod cornell;
pub mod curve;
pub mod environment;
pub mod error;
pub mod framing;
pub mod gltf;
pub mod input;
pub mod landscape;
pub mod lens;
pub mod light;
pub mod load;
pub mod material;
pub mod measured;
pub mod medium;
pub mod mesh;
pub mod mipmap;
pub mod motion;
pub mod obj;
pub mod off;
pub mod pbrt;
pub mod ply;
pub mod ply_write;
pub mod procedural;
pub mod progress;
pub mod scattering;
pub mod scene;
pub mod subsurface;
pub mod tensor;
pub mod texture;
pub mod texture_scenes;

pub use camera::{
    Camera, FilmSettings, IntegratorSettings, LightSampler, PixelFilter, Projection, RenderSettings, Sensor,
};
pub use curve::{CurveKind, CurvePiece, Curves};
pub use environment::{EnvLayout, EnvironmentImage};
pub use error::{FileLoc, SceneError, Warning};
pub use light::{AreaEmission, IntensityMap, Light, Portal, ProjectionImage};
pub use load::{load_any, LoadedScene};
pub use material::{
    CoatedConductorParams, CoatedDiffuseParams, Coating, HairParams, Material, MaterialId, MeasuredId,
    PrincipledParams, SubsurfaceParams,
};
pub use measured::MeasuredBrdf;
pub use medium::{
    FieldSource, GridField, GridMedium, HomogeneousMedium, Medium, MediumIndex, MediumInterface, MAX_MEDIA,
    VACUUM,
};
pub use mesh::{MeshError, MeshId, TriangleMesh};
pub use motion::{Decomposed, Motion};
pub use scene::{Instance, Object, ObjectId, Scene, SceneSizes, SceneStats};
pub use texture::{
    AlphaMode, Channel, ColorEncoding, ImageCache, ImageFilter, ImageId, ImageLoadError, MeshAlpha, Noise,
    TexInput, TexMapping, Texels, Texture, TextureBinding, TextureId, TextureImage, TexturedParam, Textures,
    UvMapping, Wrap,
};

/// Linear-sRGB colour triple (radiance, reflectance, ...).
pub type Rgb = glam::Vec3;

/// Luminance (Y) of a linear-sRGB colour (Rec. 709 weights).
pub fn luminance(c: Rgb) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}
