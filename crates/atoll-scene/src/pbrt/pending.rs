//! Shapes whose triangles are made once the scene's text is read: PLY
//! files are then read, and every mesh is transformed and checked, in
//! parallel; the meshes join the scene in the order of their `Shape`
//! directives, so the scene equals the one a serial load gives, whatever
//! the thread count.

use glam::{DMat3, DMat4};
use rayon::prelude::*;

use crate::error::{FileLoc, SceneError};
use crate::{AreaEmission, MaterialId, MeshAlpha, TextureId, TriangleMesh};

use super::shapes::ShapeSource;
use super::transform;

/// Fewest vertices one parallel task transforms.
const MIN_VERTICES: usize = 1 << 14;

/// A `Shape` directive, with what the graphics state said of it then.
pub(super) struct PendingShape {
    pub source: ShapeSource,
    pub place: ShapePlace,
}

/// Everything about a pending shape but its triangles.
pub(super) struct ShapePlace {
    pub loc: FileLoc,
    pub ctm: DMat4,
    pub reverse_orientation: bool,
    /// `None`: a `NamedMaterial` not defined yet ([`ShapePlace::named_material`]).
    pub material: Option<MaterialId>,
    pub named_material: Option<(String, FileLoc)>,
    pub emission: Option<AreaEmission>,
    pub emission_texture: Option<TextureId>,
    pub alpha: Option<MeshAlpha>,
    /// The object being defined, `None` for the world.
    pub object: Option<usize>,
}

/// A pending shape made: its mesh (`None` when it has no triangles) and
/// what to warn about, in order.
pub(super) struct MadeShape {
    pub place: ShapePlace,
    pub mesh: Option<TriangleMesh>,
    pub warnings: Vec<String>,
}

/// Makes every pending shape, in parallel (reads count against the scene
/// load's budget on every thread); the first error in directive order
/// wins, so errors do not depend on timing either.
pub(super) fn make_all(pending: Vec<PendingShape>) -> Result<Vec<MadeShape>, SceneError> {
    let budget = crate::input::current_budget();
    pending
        .into_par_iter()
        .map(|p| match &budget {
            Some(b) => crate::input::with_budget(b.clone(), || p.make()),
            None => p.make(),
        })
        .collect::<Vec<_>>()
        .into_iter()
        .collect()
}

impl PendingShape {
    fn make(self) -> Result<MadeShape, SceneError> {
        let PendingShape { source, place } = self;
        let (shape, warning) = source.mesh(&place.loc)?;
        let mut warnings: Vec<String> = warning.into_iter().collect();
        if shape.indices.is_empty() {
            warnings.push(format!("shape \"{}\" has no triangles; skipped", shape.name));
            return Ok(MadeShape { place, mesh: None, warnings });
        }
        let ctm = place.ctm;
        let reverse = place.reverse_orientation;
        let positions = shape
            .positions
            .par_iter()
            .with_min_len(MIN_VERTICES)
            .map(|p| transform::point(&ctm, p.as_dvec3()).as_vec3())
            .collect();
        let normal_matrix = DMat3::from_mat4(ctm).inverse().transpose();
        let normals = shape
            .normals
            .par_iter()
            .with_min_len(MIN_VERTICES)
            .map(|n| {
                let n = (normal_matrix * n.as_dvec3()).normalize_or_zero().as_vec3();
                if reverse {
                    -n
                } else {
                    n
                }
            })
            .collect();
        let mesh = TriangleMesh {
            name: shape.name,
            positions,
            normals,
            uvs: shape.uvs,
            indices: shape.indices,
            material: place.material.unwrap_or(0),
            emission: place.emission,
            flip_normals: reverse ^ transform::swaps_handedness(&ctm),
            alpha: place.alpha,
        };
        mesh.validate()
            .map_err(|m| SceneError::caused_by(&place.loc, format!("shape \"{}\": {m}", mesh.name), m))?;
        crate::input::on_budget(|b| b.count_loaded_triangles(mesh.indices.len() as u64));
        Ok(MadeShape { place, mesh: Some(mesh), warnings })
    }
}
