//! The scene model of atoll and everything that produces one: the PBRT loader,
//! the PLY reader, the built-in Cornell box and (later) procedural scenes.
//!
//! A [`Scene`] is two-level: [`Object`]s are groups of [`TriangleMesh`]es, and
//! [`Instance`]s place objects in the world with an affine transform. Geometry
//! outside any `ObjectBegin` block lives in world space in the *world object*,
//! which has exactly one identity instance. Instancing never copies a mesh.

pub mod camera;
pub mod cornell;
pub mod error;
pub mod light;
pub mod material;
pub mod mesh;
pub mod pbrt;
pub mod ply;
pub mod procedural;
pub mod scene;

pub use camera::{Camera, FilmSettings, IntegratorSettings, RenderSettings};
pub use error::{FileLoc, SceneError, Warning};
pub use light::{AreaEmission, Light};
pub use material::{Material, MaterialId};
pub use mesh::{MeshId, TriangleMesh};
pub use pbrt::LoadedScene;
pub use scene::{Instance, Object, ObjectId, Scene, SceneStats};

/// Linear-sRGB colour triple (radiance, reflectance, ...).
pub type Rgb = glam::Vec3;
