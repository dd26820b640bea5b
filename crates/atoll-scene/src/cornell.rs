//! The built-in Cornell box: the shared `cbox/diffuse` scene with every
//! `plymesh` written inline as a `trianglemesh` (same vertices, bit for bit,
//! and same indices), so it needs no files. It goes through the PBRT loader
//! like any other scene.

use std::path::Path;

use crate::Scene;

/// PBRT-v4 text of the built-in Cornell box: the shared diffuse box with
/// its meshes inline (512x512, path tracing to depth 15; no output file
/// name, so the caller picks one). It asks for 64 spp instead of the shared
/// file's 4096 so that `atoll` with no arguments finishes in seconds.
pub const CORNELL_BOX_PBRT: &str = r#"Scale -1 1 1
LookAt 0 1 -3.9  0 1 0  0 1 0
Camera "perspective" "float fov" [ 39.3077 ]
Film "rgb" "integer xresolution" [ 512 ] "integer yresolution" [ 512 ]
PixelFilter "box"
Sampler "independent" "integer pixelsamples" [ 64 ]
Integrator "path" "integer maxdepth" [ 15 ]
WorldBegin
MakeNamedMaterial "white" "string type" [ "diffuse" ] "rgb reflectance" [ 0.725 0.71 0.68 ]
MakeNamedMaterial "red" "string type" [ "diffuse" ] "rgb reflectance" [ 0.63 0.065 0.05 ]
MakeNamedMaterial "green" "string type" [ "diffuse" ] "rgb reflectance" [ 0.14 0.45 0.091 ]
MakeNamedMaterial "glass" "string type" [ "dielectric" ] "float eta" [ 1.5 ]
MakeNamedMaterial "mirror" "string type" [ "conductor" ] "rgb reflectance" [ 1 1 1 ] "float roughness" [ 0 ]
AttributeBegin
 NamedMaterial "white"
 Shape "trianglemesh"
  "point3 P" [ -1 0 -1 -1 0 1 1 0 1 1 0 -1 ]
  "integer indices" [ 0 1 2 0 2 3 ]
AttributeEnd
AttributeBegin
 NamedMaterial "white"
 Shape "trianglemesh"
  "point3 P" [ -1 2 -1 1 2 -1 1 2 1 -1 2 1 ]
  "integer indices" [ 0 1 2 0 2 3 ]
AttributeEnd
AttributeBegin
 NamedMaterial "white"
 Shape "trianglemesh"
  "point3 P" [ -1 0 1 -1 2 1 1 2 1 1 0 1 ]
  "integer indices" [ 0 1 2 0 2 3 ]
AttributeEnd
AttributeBegin
 NamedMaterial "red"
 Shape "trianglemesh"
  "point3 P" [ -1 0 -1 -1 2 -1 -1 2 1 -1 0 1 ]
  "integer indices" [ 0 1 2 0 2 3 ]
AttributeEnd
AttributeBegin
 NamedMaterial "green"
 Shape "trianglemesh"
  "point3 P" [ 1 0 -1 1 0 1 1 2 1 1 2 -1 ]
  "integer indices" [ 0 1 2 0 2 3 ]
AttributeEnd
AttributeBegin
 AreaLightSource "diffuse" "rgb L" [ 17 12 4 ]
 Material "diffuse" "rgb reflectance" [ 0 0 0 ]
 Shape "trianglemesh"
  "point3 P" [ -0.25 1.999 -0.25 0.25 1.999 -0.25 0.25 1.999 0.25 -0.25 1.999 0.25 ]
  "integer indices" [ 0 1 2 0 2 3 ]
AttributeEnd
AttributeBegin
 NamedMaterial "white"
 Shape "trianglemesh"
  "point3 P" [ -0.71451384 0 0.12069826 -0.5093017 0 0.6845138 -0.71451384 1.2 0.12069826 -0.5093017 1.2 0.6845138 -0.15069826 0 -0.08451383 0.05451383 0 0.47930175 -0.15069826 1.2 -0.08451383 0.05451383 1.2 0.47930175 ]
  "integer indices" [ 0 1 3 0 3 2 4 6 7 4 7 5 0 4 5 0 5 1 2 3 7 2 7 6 0 2 6 0 6 4 1 5 7 1 7 3 ]
AttributeEnd
AttributeBegin
 NamedMaterial "white"
 Shape "trianglemesh"
  "point3 P" [ 0.15738815 0 -0.678022 -0.028022053 0 -0.107388146 0.15738815 0.6 -0.678022 -0.028022053 0.6 -0.107388146 0.72802204 0 -0.49261186 0.54261184 0 0.078022055 0.72802204 0.6 -0.49261186 0.54261184 0.6 0.078022055 ]
  "integer indices" [ 0 1 3 0 3 2 4 6 7 4 7 5 0 4 5 0 5 1 2 3 7 2 7 6 0 2 6 0 6 4 1 5 7 1 7 3 ]
AttributeEnd
"#;

/// The built-in Cornell box as a [`Scene`].
pub fn builtin_cornell_box() -> Scene {
    crate::pbrt::load_str(CORNELL_BOX_PBRT, "<builtin cornell box>", Path::new("."))
        .expect("the built-in Cornell box is valid PBRT")
        .scene
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loads_without_warnings() {
        let loaded = crate::pbrt::load_str(CORNELL_BOX_PBRT, "cbox", Path::new(".")).unwrap();
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        let s = loaded.scene;
        assert_eq!(s.stats().unique_triangles, 36);
        assert_eq!(s.settings.film.resolution, glam::UVec2::new(512, 512));
        assert_eq!(s.settings.film.filename, None);
        assert_eq!(s.settings.spp, 64);
        assert_eq!(s.emissive_triangle_count(), 2);
    }
}
