//! pbrt-v4's `measured` material: its `.bsdf` file read once per scene
//! however many materials name it ([`crate::measured`] holds the tables).

use std::path::Path;
use std::sync::Arc;

use super::params::ParamList;
use super::WarningSink;
use crate::{FileLoc, Material, MeasuredBrdf, Scene, SceneError};

/// Most measured BRDFs one scene may read: a hit names its BRDF in an f16
/// coefficient, exact for integers up to this.
pub const MAX_MEASURED: usize = 2048;

/// `Material "measured" "string filename"`: the BRDF of the file, read
/// relative to `base_dir` into `scene.measured` unless read already. A
/// missing file is an error, or with `--allow-missing` a warning and
/// pbrt's default diffuse; a malformed one is an error naming the file.
pub(super) fn measured_material(
    p: &ParamList,
    base_dir: &Path,
    scene: &mut Scene,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> Result<Material, SceneError> {
    let what = "material \"measured\"";
    let Some(file) = p.string("filename")? else {
        return Err(SceneError::at(loc, format!("{what}: \"filename\" must be given")));
    };
    if let Some(i) = scene.measured.iter().position(|m| m.filename == file) {
        return Ok(Material::Measured { brdf: i as u32 });
    }
    let bytes = crate::input::beside(base_dir, &file).and_then(|path| crate::input::read(&path));
    let bytes = match bytes {
        Ok(bytes) => bytes,
        Err(e) => {
            let e = crate::ImageLoadError::io(Path::new(&file))(e);
            super::missing_file(loc, what, e.clone())?;
            w.warn(loc, format!("{what}: {e}; using diffuse 0.5 (its measured reflection is lost)"));
            return Ok(Material::default_diffuse());
        }
    };
    let brdf = MeasuredBrdf::from_bytes(&bytes, &file)
        .map_err(|e| SceneError::at(loc, format!("{what}: {file}: {e}")))?;
    if scene.measured.len() >= MAX_MEASURED {
        return Err(SceneError::at(
            loc,
            format!("{what}: more than {MAX_MEASURED} measured BRDFs in one scene"),
        ));
    }
    scene.measured.push(Arc::new(brdf));
    Ok(Material::Measured { brdf: (scene.measured.len() - 1) as u32 })
}
