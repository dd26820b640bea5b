//! Triangle meshes: what the renderer traces, curves included (a mesh of
//! curves holds one proxy triangle per piece, [`crate::curve`]).

use glam::{Vec2, Vec3};

use crate::{AreaEmission, MaterialId};

/// Index of a mesh in [`crate::Scene::meshes`].
pub type MeshId = u32;

/// What [`TriangleMesh::validate`] found wrong. Loaders put the mesh's
/// name and the file's location in front.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MeshError {
    #[error("{normals} normals for {positions} positions")]
    NormalCount { normals: usize, positions: usize },
    #[error("{uvs} uvs for {positions} positions")]
    UvCount { uvs: usize, positions: usize },
    #[error("triangle {triangle} uses vertex {vertex} but the mesh has {vertices} vertices")]
    VertexOutOfRange { triangle: usize, vertex: u32, vertices: usize },
    #[error("non-finite vertex position {position}")]
    NonFinitePosition { position: Vec3 },
}

/// An indexed triangle mesh in the space of the object that owns it.
#[derive(Clone, Debug, Default)]
pub struct TriangleMesh {
    /// Where it came from (file name or "trianglemesh"), for messages and `atoll info`.
    pub name: String,
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals; empty when the mesh has none.
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates; empty when the mesh has none.
    pub uvs: Vec<Vec2>,
    pub indices: Vec<[u32; 3]>,
    pub material: MaterialId,
    /// Diffuse area emission (pbrt's `AreaLightSource "diffuse"`), if any.
    pub emission: Option<AreaEmission>,
    /// Flip the geometric normal: pbrt's `ReverseOrientation` XOR "the
    /// transform in effect swaps handedness". The geometric normal is
    /// `normalize(cross(p0 - p2, p1 - p2))`, negated when this is set
    /// (pbrt-v4's convention, which decides which side a one-sided light emits on).
    pub flip_normals: bool,
    /// Alpha mask cutting holes into the surface (pbrt's shape `alpha`,
    /// glTF `MASK`, OBJ `map_d`); needs `uvs` unless the texture is constant.
    pub alpha: Option<crate::MeshAlpha>,
    /// The media on either side, where they differ (pbrt's
    /// `MediumInterface`): a ray crossing the surface changes medium.
    pub media: Option<crate::MediumInterface>,
    /// A mesh of curves: triangle `i` is the proxy of piece `i`
    /// ([`crate::curve::Curves::proxy_triangles`]), which traversal
    /// intersects instead of the triangle. Such a mesh has no normals, uvs,
    /// alpha, media or emission.
    pub curves: Option<crate::curve::Curves>,
}

impl TriangleMesh {
    /// Whether traversal must ask about each candidate hit on this mesh
    /// for the mesh's own sake: it has an alpha mask. (A surface that
    /// only bounds media is asked about too, for shadow rays to cross it:
    /// that depends on its material, [`crate::Scene::filters_hits`]. Any
    /// other surface between media stops shadow rays like any surface.)
    pub fn filters_hits(&self) -> bool {
        self.alpha.is_some()
    }

    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }

    /// The three corner positions of triangle `t`.
    #[inline]
    pub fn triangle(&self, t: usize) -> [Vec3; 3] {
        let [a, b, c] = self.indices[t];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }

    /// Unnormalised geometric normal of triangle `t` following pbrt-v4's
    /// orientation rule (see [`TriangleMesh::flip_normals`]).
    #[inline]
    pub fn geometric_normal(&self, t: usize) -> Vec3 {
        let [p0, p1, p2] = self.triangle(t);
        let n = (p0 - p2).cross(p1 - p2);
        if self.flip_normals {
            -n
        } else {
            n
        }
    }

    /// Bytes this mesh occupies in memory (positions, normals, uvs, indices).
    pub fn memory_bytes(&self) -> u64 {
        (self.positions.len() * 12 + self.normals.len() * 12 + self.uvs.len() * 8 + self.indices.len() * 12)
            as u64
            + self.curves.as_ref().map_or(0, |c| c.bytes())
    }

    /// Checks indices and attribute lengths; returns the first problem.
    pub fn validate(&self) -> Result<(), MeshError> {
        let positions = self.positions.len();
        if !self.normals.is_empty() && self.normals.len() != positions {
            return Err(MeshError::NormalCount { normals: self.normals.len(), positions });
        }
        if !self.uvs.is_empty() && self.uvs.len() != positions {
            return Err(MeshError::UvCount { uvs: self.uvs.len(), positions });
        }
        for (triangle, tri) in self.indices.iter().enumerate() {
            if let Some(&vertex) = tri.iter().find(|&&i| i as usize >= positions) {
                return Err(MeshError::VertexOutOfRange { triangle, vertex, vertices: positions });
            }
        }
        if let Some(&position) = self.positions.iter().find(|p| !p.is_finite()) {
            return Err(MeshError::NonFinitePosition { position });
        }
        Ok(())
    }
}
