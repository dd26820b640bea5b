//! Shadow rays through the boundaries of media. A shadow ray starts with
//! the optical depth of its first medium over its whole length
//! (`stages::shade`); each boundary it crosses at `t` then adds the depth
//! of the medium after it over the rest of the ray, less that of the
//! medium before it: for homogeneous media `(σt after − σt before) ·
//! (t_max − t)`. The sum is the integral of σt along the ray whatever
//! order traversal finds the crossings in, and it adds up across the parts
//! of a ring. (A grid's density outside its medium's boundary counts only
//! where the ray is in that medium: the crossings take it out again.)

use std::cell::Cell;

use atoll_bvh::HitFilter;
use atoll_scene::MeshId;
use glam::{Vec3, Vec3A};

use crate::frame::FrameContext;
use crate::record::RayRecord;
use crate::texture::SceneTextures;

/// The hit filter of one shadow ray: alpha masks as for any ray, and
/// surfaces that only bound media let it through, adding to its depth.
pub struct ShadowFilter<'a> {
    textures: &'a SceneTextures<'a>,
    frame: &'a FrameContext,
    /// The world ray and its extent.
    origin: Vec3,
    dir: Vec3,
    t_max: f32,
    depth: Cell<Vec3>,
}

impl<'a> ShadowFilter<'a> {
    pub fn new(textures: &'a SceneTextures<'a>, frame: &'a FrameContext, r: &RayRecord) -> Self {
        ShadowFilter {
            textures,
            frame,
            origin: r.origin(),
            dir: r.direction(),
            t_max: r.t_max,
            depth: Cell::new(r.optical_depth()),
        }
    }

    /// The optical depth with every crossing found so far.
    pub fn optical_depth(&self) -> Vec3 {
        self.depth.get()
    }
}

impl HitFilter for ShadowFilter<'_> {
    fn filters(&self, mesh: MeshId) -> bool {
        self.textures.filters(mesh) || self.textures.scene.bounds_media_only(mesh)
    }

    fn keeps(&self, mesh: MeshId, triangle: u32, u: f32, v: f32, t: f32, origin: Vec3A, dir: Vec3A) -> bool {
        if !self.textures.keeps(mesh, triangle, u, v, t, origin, dir) {
            return false;
        }
        if !self.textures.scene.bounds_media_only(mesh) {
            return true;
        }
        let m = &self.textures.scene.meshes[mesh as usize];
        // Without a transition the media on both sides are the ray's: no change.
        let Some(media) = m.media else { return false };
        // The normal the hit writer orients (towards the interpolated
        // normal where there is one), in object space: its side of the ray
        // is the same in world space.
        let mut n = m.geometric_normal(triangle as usize);
        if !m.normals.is_empty() {
            let [i0, i1, i2] = m.indices[triangle as usize].map(|i| i as usize);
            let ns = m.normals[i0] * (1.0 - u - v) + m.normals[i1] * u + m.normals[i2] * v;
            if ns.dot(n) < 0.0 {
                n = -n;
            }
        }
        let cos = Vec3::from(dir).dot(n);
        let (before, after) = (media.towards(-cos), media.towards(cos));
        let rest = |m| self.frame.media.optical_depth(m, self.origin, self.dir, t, self.t_max);
        self.depth.set(self.depth.get() + rest(after) - rest(before));
        false
    }
}
