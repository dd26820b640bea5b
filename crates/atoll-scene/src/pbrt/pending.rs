//! Shapes whose triangles are made once the scene's text is read: PLY
//! files are then read, and every mesh is transformed and checked, in
//! parallel; the meshes join the scene in the order of their `Shape`
//! directives, so the scene equals the one a serial load gives, whatever
//! the thread count.

use glam::{DMat3, DMat4, DVec3};
use rayon::prelude::*;

use crate::error::{FileLoc, SceneError};
use crate::SceneSizes;
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
    pub media: Option<crate::MediumInterface>,
    /// The object being defined, `None` for the world.
    pub object: Option<usize>,
    /// A moving shape's transforms at the motion's start and end; its
    /// triangles are then made in object space (`ctm` is the identity), as
    /// pbrt-v4 makes an animated shape's.
    pub motion: Option<(DMat4, DMat4)>,
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

/// The sizes of the scene the pending shapes make, in `objects` objects
/// with `instances` instances, before anything is read: PLY files from
/// their headers ([`crate::ply::peek_sizes`]; one that cannot be peeked
/// counts nothing, and its read says why later).
pub(super) fn sizes(pending: &[PendingShape], objects: u64, instances: u64) -> SceneSizes {
    let mut s = SceneSizes { objects, instances, ..Default::default() };
    let mut per_object: std::collections::HashMap<Option<usize>, u64> = Default::default();
    for p in pending {
        if let ShapeSource::Mesh(m) = &p.source {
            s.geometry_bytes = s.geometry_bytes.saturating_add(m.curves.as_ref().map_or(0, |c| c.bytes()));
        }
        let (vertices, triangles, normals, uvs) = match &p.source {
            ShapeSource::Mesh(m) => {
                (m.positions.len() as u64, m.indices.len() as u64, !m.normals.is_empty(), !m.uvs.is_empty())
            }
            ShapeSource::Ply { path, .. } => match crate::ply::peek_sizes(path) {
                Some(ply) => (ply.vertices, ply.faces, ply.normals, ply.uvs),
                None => continue,
            },
        };
        // Saturating: sizes are estimates, and a file's claims are not trusted.
        let per_vertex = 12 + 12 * u64::from(normals) + 8 * u64::from(uvs);
        s.vertices = s.vertices.saturating_add(vertices);
        s.triangles = s.triangles.saturating_add(triangles);
        let bytes = vertices.saturating_mul(per_vertex).saturating_add(triangles.saturating_mul(12));
        s.geometry_bytes = s.geometry_bytes.saturating_add(bytes);
        let object = per_object.entry(p.place.object).or_default();
        *object = object.saturating_add(triangles);
    }
    s.largest_object_triangles = per_object.into_values().max().unwrap_or(0);
    s
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
        if let Some(curves) = shape.curves {
            return curve_mesh(shape.name, curves, place, warnings);
        }
        let normal_matrix = DMat3::from_mat4(ctm).inverse().transpose();
        let unit = |n: DVec3| {
            let n = n.normalize_or_zero().as_vec3();
            if reverse {
                -n
            } else {
                n
            }
        };
        // In place: the arrays are the shape's own (PLY files are read into
        // fresh ones), and a second copy costs as much as the transform.
        let (mut positions, mut normals) = (shape.positions, shape.normals);
        // The identity moves no point (x·1 + 0 is exact): baked geometry
        // skips the pass.
        if ctm != DMat4::IDENTITY {
            positions.par_iter_mut().with_min_len(MIN_VERTICES).for_each(|p| {
                *p = transform::point(&ctm, p.as_dvec3()).as_vec3();
            });
        }
        if ctm == DMat4::IDENTITY {
            // The identity's normal matrix moves no normal either (a NaN or
            // infinite one becomes zero both ways): normalised alone.
            normals.par_iter_mut().with_min_len(MIN_VERTICES).for_each(|n| *n = unit(n.as_dvec3()));
        } else {
            normals
                .par_iter_mut()
                .with_min_len(MIN_VERTICES)
                .for_each(|n| *n = unit(normal_matrix * n.as_dvec3()));
        }
        let indices = shape.indices;
        let mesh = TriangleMesh {
            name: shape.name,
            positions,
            normals,
            uvs: shape.uvs,
            indices,
            material: place.material.unwrap_or(0),
            emission: place.emission,
            flip_normals: reverse ^ transform::swaps_handedness(&ctm),
            alpha: place.alpha,
            media: place.media,
            curves: None,
        };
        mesh.validate()
            .map_err(|m| SceneError::caused_by(&place.loc, format!("shape \"{}\": {m}", mesh.name), m))?;
        crate::input::on_budget(|b| b.count_loaded_triangles(mesh.indices.len() as u64));
        Ok(MadeShape { place, mesh: Some(mesh), warnings })
    }
}

/// The mesh of a curve shape: its pieces through the CTM
/// ([`crate::curve::Curves::transform`], in f64 as triangles are) and
/// their proxy triangles. Curves do not emit, cut holes or bound media (pbrt-v4's
/// curves cannot be sampled as lights either): those are warned about and
/// dropped.
fn curve_mesh(
    name: String,
    mut curves: crate::curve::Curves,
    mut place: ShapePlace,
    mut warnings: Vec<String>,
) -> Result<MadeShape, SceneError> {
    let ctm = place.ctm;
    let linear = DMat3::from_mat4(ctm);
    let normal_matrix = linear.inverse().transpose();
    let scale = linear.determinant().abs().cbrt() as f32;
    curves.transform(
        |p| transform::point(&ctm, p.as_dvec3()).as_vec3(),
        |n| (normal_matrix * n.as_dvec3()).as_vec3(),
        scale,
    );
    let mut dropped = Vec::new();
    if place.emission.take().is_some() {
        place.emission_texture = None;
        dropped.push("its area light");
    }
    if place.alpha.take().is_some() {
        dropped.push("its alpha");
    }
    if place.media.take().is_some() {
        dropped.push("its medium interface");
    }
    if !dropped.is_empty() {
        warnings.push(format!("curves cannot have {}; dropped", dropped.join(" or ")));
    }
    let (positions, indices) = curves.proxy_triangles();
    let mesh = TriangleMesh {
        name,
        positions,
        indices,
        material: place.material.unwrap_or(0),
        flip_normals: place.reverse_orientation ^ transform::swaps_handedness(&ctm),
        curves: Some(curves),
        ..Default::default()
    };
    // Non-finite control points or widths make non-finite proxies.
    mesh.validate()
        .map_err(|m| SceneError::caused_by(&place.loc, format!("shape \"{}\": {m}", mesh.name), m))?;
    crate::input::on_budget(|b| b.count_loaded_triangles(mesh.indices.len() as u64));
    Ok(MadeShape { place, mesh: Some(mesh), warnings })
}
