//! `Shape` directives as triangle meshes in object space (before the CTM):
//! `trianglemesh`, `plymesh`, `loopsubdiv`, `bilinearmesh`, the quadrics
//! `sphere`, `disk` and `cylinder` (tessellated, [`super::quadrics`]) and
//! `curve` (pieces of cubic Bézier curves, [`super::curves`]). Other pbrt
//! shapes are skipped with a warning.
//! Checks follow pbrt-v4's `Triangle::CreateMesh`.

use std::path::Path;

use glam::{Vec2, Vec3};

use crate::error::{FileLoc, SceneError};
use crate::ply;

use super::params::ParamList;
use super::quadrics;
use super::WarningSink;

/// A shape's triangles in object space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShapeMesh {
    /// For messages and `atoll info`: the PLY file name or the shape type.
    pub name: String,
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<Vec2>,
    pub indices: Vec<[u32; 3]>,
    /// A curve's pieces ([`crate::TriangleMesh::curves`]); the triangles
    /// are their proxies.
    pub curves: Option<crate::curve::Curves>,
}

/// The shape types [`shape_mesh`] turns into triangles.
pub const SUPPORTED: &[&str] =
    &["trianglemesh", "plymesh", "sphere", "disk", "cylinder", "curve", "loopsubdiv", "bilinearmesh"];

/// Where a shape's triangles come from: made from the directive's
/// parameters, or a PLY file read later ([`ShapeSource::mesh`]), in
/// parallel with the scene's other files.
#[derive(Clone, Debug)]
pub enum ShapeSource {
    Mesh(ShapeMesh),
    Ply {
        path: std::path::PathBuf,
        /// As the scene names it, for messages and the mesh's name.
        filename: String,
    },
}

impl ShapeSource {
    /// The shape's triangles in object space, with what to warn about.
    pub fn mesh(self, loc: &FileLoc) -> Result<(ShapeMesh, Option<String>), SceneError> {
        match self {
            ShapeSource::Mesh(mesh) => Ok((mesh, None)),
            ShapeSource::Ply { path, filename } => read_ply_mesh(&path, filename, loc),
        }
    }
}

/// Where the triangles of `Shape "ty" params` come from; `None` (after a
/// warning) for shapes we skip.
pub fn shape_source(
    ty: &str,
    p: &ParamList,
    loc: &FileLoc,
    base_dir: &Path,
    w: &mut WarningSink,
) -> Result<Option<ShapeSource>, SceneError> {
    if ty == "plymesh" {
        return ply_source(p, loc, base_dir).map(Some);
    }
    made_mesh(ty, p, loc, w).map(|m| m.map(ShapeSource::Mesh))
}

/// The mesh of a shape made from its parameters.
fn made_mesh(
    ty: &str,
    p: &ParamList,
    loc: &FileLoc,
    w: &mut WarningSink,
) -> Result<Option<ShapeMesh>, SceneError> {
    match ty {
        "trianglemesh" => triangle_mesh(p, loc, w).map(Some),
        "loopsubdiv" => {
            let levels = p.int("levels")?.unwrap_or(3);
            if !(0..=8).contains(&levels) {
                return Err(SceneError::at(
                    loc,
                    format!("loopsubdiv: \"levels\" must be 0 to 8 (got {levels})"),
                ));
            }
            let control = triangle_mesh(p, loc, w)?;
            let n = control.indices.len() as u64;
            let triangles = 4u64.checked_pow(levels as u32).and_then(|f| f.checked_mul(n));
            let what = format!("loopsubdiv: {levels} levels of subdivision of {n} triangles");
            generate(&what, triangles, loc)?;
            Ok(Some(super::subdivision::loop_subdivide(&control.positions, &control.indices, levels as u32)))
        }
        "bilinearmesh" => bilinear(p, loc, w).map(Some),
        "sphere" => {
            let radius = p.float_or("radius", 1.0)?;
            let (zmin, zmax) = (p.float_or("zmin", -radius)?, p.float_or("zmax", radius)?);
            let phimax = p.float_or("phimax", 360.0)?;
            tessellated("sphere", quadrics::sphere(radius, zmin, zmax, phimax), loc)
        }
        "disk" => {
            let (height, radius) = (p.float_or("height", 0.0)?, p.float_or("radius", 1.0)?);
            let (inner, phimax) = (p.float_or("innerradius", 0.0)?, p.float_or("phimax", 360.0)?);
            tessellated("disk", quadrics::disk(height, radius, inner, phimax), loc)
        }
        "cylinder" => {
            let radius = p.float_or("radius", 1.0)?;
            let (zmin, zmax) = (p.float_or("zmin", -1.0)?, p.float_or("zmax", 1.0)?);
            let phimax = p.float_or("phimax", 360.0)?;
            tessellated("cylinder", quadrics::cylinder(radius, zmin, zmax, phimax), loc)
        }
        "curve" => super::curves::curve(p, loc).map(Some),
        _ => {
            p.mark_all_used();
            w.warn(loc, format!("unsupported shape \"{ty}\" skipped"));
            Ok(None)
        }
    }
}

/// A tessellated quadric, its few thousand triangles at most drawn
/// from the scene's budget (made first: they take less memory than the check).
fn tessellated(what: &str, mesh: ShapeMesh, loc: &FileLoc) -> Result<Option<ShapeMesh>, SceneError> {
    generate(what, Some(mesh.indices.len() as u64), loc)?;
    Ok(Some(mesh))
}

/// Draws the `triangles` a shape is about to generate from the scene's
/// budget ([`crate::input::max_generated_triangles`]), before anything is
/// allocated for them; `None` is a count past `u64`. A mesh's vertices are
/// addressed with 32 bits, so no more triangles than that either.
pub(super) fn generate(what: &str, triangles: Option<u64>, loc: &FileLoc) -> Result<(), SceneError> {
    let Some(t) = triangles.filter(|&t| t <= u32::MAX as u64) else {
        let count = triangles.map_or("more than 2^64".into(), |t| t.to_string());
        return Err(SceneError::at(
            loc,
            format!("{what}: {count} triangles, more than one mesh can hold (2^32 - 1)"),
        ));
    };
    // Past the budget the scene does not fit (exit 1), as for memory.
    crate::input::on_budget(|b| b.generate_triangles(t)).map_err(|m| {
        let why = format!("{what}: {m}");
        let memory = std::io::Error::new(std::io::ErrorKind::OutOfMemory, why.clone());
        SceneError::caused_by(loc, why, memory)
    })
}

fn triangle_mesh(p: &ParamList, loc: &FileLoc, w: &mut WarningSink) -> Result<ShapeMesh, SceneError> {
    let positions = p.point3s("P").unwrap_or_default();
    if positions.is_empty() {
        return Err(SceneError::at(loc, "trianglemesh: vertex positions \"point3 P\" must be given"));
    }
    let n = positions.len();
    let mut flat: Vec<f64> = match p.ints("indices") {
        Some(i) => i.to_vec(),
        None if n == 3 => vec![0.0, 1.0, 2.0],
        None => return Err(SceneError::at(
            loc,
            "trianglemesh: vertex \"integer indices\" must be given (unless there are exactly 3 vertices)",
        )),
    };
    let excess = flat.len() % 3;
    if excess > 0 {
        w.warn(
            loc,
            format!("trianglemesh: {} indices are not a multiple of 3; the excess is discarded", flat.len()),
        );
        flat.truncate(flat.len() - excess);
    }
    if let Some(bad) = flat.iter().find(|&&i| i < 0.0 || i as usize >= n) {
        return Err(SceneError::at(
            loc,
            format!("trianglemesh: vertex index {bad} out of range ({n} \"P\" values were given)"),
        ));
    }
    let indices = flat.chunks_exact(3).map(|c| [c[0] as u32, c[1] as u32, c[2] as u32]).collect();
    let mut normals = p.normals("N").unwrap_or_default();
    if !normals.is_empty() && normals.len() != n {
        w.warn(
            loc,
            format!("trianglemesh: {} normals \"N\" for {n} vertices; discarding them", normals.len()),
        );
        normals.clear();
    }
    let mut uvs = p.point2s("uv").or_else(|| p.point2s("st")).unwrap_or_default();
    if !uvs.is_empty() && uvs.len() != n {
        w.warn(loc, format!("trianglemesh: {} \"uv\"s for {n} vertices; discarding them", uvs.len()));
        uvs.clear();
    }
    Ok(ShapeMesh { name: "trianglemesh".into(), positions, normals, uvs, indices, ..Default::default() })
}

/// `bilinearmesh`: `P`, `indices` (four per patch; all of `P` as one patch
/// when there are exactly four and no indices), optional `N` and `uv`.
fn bilinear(p: &ParamList, loc: &FileLoc, w: &mut WarningSink) -> Result<ShapeMesh, SceneError> {
    let positions = p.point3s("P").unwrap_or_default();
    let n = positions.len();
    let flat: Vec<f64> = match p.ints("indices") {
        Some(i) => i.to_vec(),
        None if n == 4 => vec![0.0, 1.0, 2.0, 3.0],
        None => {
            return Err(SceneError::at(
                loc,
                "bilinearmesh: \"integer indices\" must be given (unless there are exactly 4 vertices)",
            ))
        }
    };
    if !flat.len().is_multiple_of(4) || flat.is_empty() {
        return Err(SceneError::at(
            loc,
            format!("bilinearmesh: {} indices are not a positive multiple of 4", flat.len()),
        ));
    }
    if let Some(bad) = flat.iter().find(|&&i| i < 0.0 || i as usize >= n) {
        return Err(SceneError::at(
            loc,
            format!("bilinearmesh: vertex index {bad} out of range ({n} \"P\" values)"),
        ));
    }
    let patches: Vec<[u32; 4]> =
        flat.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]].map(|i| i as u32)).collect();
    let mut normals = p.normals("N").unwrap_or_default();
    if !normals.is_empty() && normals.len() != n {
        w.warn(
            loc,
            format!("bilinearmesh: {} normals \"N\" for {n} vertices; discarding them", normals.len()),
        );
        normals.clear();
    }
    let mut uvs = p.point2s("uv").unwrap_or_default();
    if !uvs.is_empty() && uvs.len() != n {
        w.warn(loc, format!("bilinearmesh: {} \"uv\"s for {n} vertices; discarding them", uvs.len()));
        uvs.clear();
    }
    let triangles = super::subdivision::bilinear_triangles(&positions, &patches);
    generate(&format!("bilinearmesh: {} patches", patches.len()), Some(triangles), loc)?;
    Ok(super::subdivision::bilinear_mesh(&positions, &normals, &uvs, &patches))
}

fn ply_source(p: &ParamList, loc: &FileLoc, base_dir: &Path) -> Result<ShapeSource, SceneError> {
    let Some(filename) = p.string("filename")? else {
        return Err(SceneError::at(loc, "plymesh: \"string filename\" must be given"));
    };
    let path = crate::input::beside(base_dir, &filename)
        .map_err(|e| SceneError::at(loc, format!("plymesh: {e}")))?;
    Ok(ShapeSource::Ply { path, filename })
}

fn read_ply_mesh(
    path: &Path,
    filename: String,
    loc: &FileLoc,
) -> Result<(ShapeMesh, Option<String>), SceneError> {
    let m = ply::read_ply(path).map_err(|e| match e {
        ply::PlyError::Io { source, .. } => SceneError::caused_by(
            loc,
            format!("plymesh: cannot read PLY file '{}': {source}", path.display()),
            source,
        ),
        ply::PlyError::Invalid(msg) => {
            SceneError::at(loc, format!("plymesh: bad PLY file '{}': {msg}", path.display()))
        }
    })?;
    let warning = (m.skipped_faces > 0).then(|| {
        format!(
            "plymesh '{filename}': {} faces that are neither triangles nor quads skipped",
            m.skipped_faces
        )
    });
    let mesh = ShapeMesh {
        name: filename,
        positions: m.positions,
        normals: m.normals,
        uvs: m.uvs,
        indices: m.indices,
        curves: None,
    };
    Ok((mesh, warning))
}
