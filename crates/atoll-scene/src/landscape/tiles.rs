//! The landscape cut into square tiles, for writing it out as files one
//! piece at a time (`atoll gen landscape --files`): the terrain of a tile
//! and the placements standing on it, without building the whole scene.
//!
//! Tiles follow the terrain's grid lines, so neighbouring tiles share their
//! border vertices bit for bit (no cracks), and all tiles together hold
//! exactly the triangles and instances of [`Landscape::build`].

use glam::{Affine3A, Vec3};

use super::{materials, object_meshes, triangle_count, Landscape, Terrain, GOLD, GROUND, KINDS};
use crate::{MaterialId, Scene, TriangleMesh};

/// Names of the landscape's materials by id (for file names).
pub const MATERIAL_NAMES: [&str; GOLD as usize + 1] =
    ["ground", "rock", "bark", "needles", "leaves", "glass", "gold"];

/// Most tiles along a side: beyond that, files get small and many.
pub const MAX_TILES: u32 = 256;

/// Instanced triangles per tile that [`Landscape::default_tiles`] aims at:
/// a few million, so a tile's files are tens of megabytes.
const TILE_TRIANGLES: f64 = 4e6;

/// One instance: which object (kind) it places, and where.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// Index into [`Tiling::objects`].
    pub object: usize,
    pub object_to_world: Affine3A,
}

/// A landscape cut into `tiles × tiles` square tiles, from
/// [`Landscape::tiling`]. Holds the object meshes and every placement
/// (tens of bytes per instance), never the terrain or baked geometry.
pub struct Tiling {
    terrain: Terrain,
    tiles: u32,
    objects: [Vec<TriangleMesh>; KINDS.len()],
    /// Placements by tile, `ty * tiles + tx`, in the order `build` makes them.
    placements: Vec<Vec<Placement>>,
}

impl Landscape {
    /// Tiles along a side so that each tile holds about four million
    /// instanced triangles (at least one tile, at most one per terrain quad).
    pub fn default_tiles(&self) -> u32 {
        let tiles = (self.estimate().instanced_triangles as f64 / TILE_TRIANGLES).sqrt().ceil() as u32;
        tiles.clamp(1, Terrain::new(self).quads.min(MAX_TILES))
    }

    /// The scene of [`Landscape::build`] without its geometry: materials
    /// (same ids), camera, film, sampler, integrator and lights.
    pub fn without_geometry(&self) -> Scene {
        let mut scene = Scene { materials: materials(), ..Default::default() };
        self.set_view(&mut scene, &Terrain::new(self));
        scene
    }

    /// Cuts the landscape into `tiles × tiles` tiles: refused unless
    /// `1 ≤ tiles ≤` the terrain's quads along a side (and [`MAX_TILES`]).
    /// Expects a landscape that passes [`Landscape::check`].
    pub fn tiling(&self, tiles: u32) -> Result<Tiling, String> {
        let terrain = Terrain::new(self);
        let most = terrain.quads.min(MAX_TILES);
        if !(1..=most).contains(&tiles) {
            return Err(format!(
                "{tiles} tiles along a side: there may be 1 to {most} (the terrain has {} quads along a side)",
                terrain.quads
            ));
        }
        let objects = object_meshes(self.tessellation(self.growth()), self.seed);
        let n = self.instance_count(&objects.each_ref().map(|m| triangle_count(m)));
        let mut tiling =
            Tiling { terrain, tiles, objects, placements: vec![Vec::new(); (tiles * tiles) as usize] };
        let mut buckets = std::mem::take(&mut tiling.placements);
        for (object, object_to_world) in self.placements(&tiling.terrain, n) {
            let at = object_to_world.translation;
            let tile = tiling.tile_of(at.z) * tiles + tiling.tile_of(at.x);
            buckets[tile as usize].push(Placement { object: object as usize, object_to_world });
        }
        tiling.placements = buckets;
        Ok(tiling)
    }
}

impl Tiling {
    /// Tiles along a side.
    pub fn tiles(&self) -> u32 {
        self.tiles
    }

    /// The objects instances place, by [`Placement::object`]: each object's
    /// name and meshes (in object space, with their materials).
    pub fn objects(&self) -> impl Iterator<Item = (&'static str, &[TriangleMesh])> {
        KINDS.iter().zip(&self.objects).map(|(k, m)| (k.name, m.as_slice()))
    }

    /// The material of the terrain.
    pub fn terrain_material(&self) -> MaterialId {
        GROUND
    }

    /// The placements on tile `(tx, ty)`: those whose origin lies over the
    /// tile's terrain quads (an instance may reach over the tile's border).
    pub fn placements(&self, tx: u32, ty: u32) -> &[Placement] {
        &self.placements[(ty * self.tiles + tx) as usize]
    }

    /// Terrain quads `[first, end)` of tile column (or row) `t`.
    fn span(&self, t: u32) -> (u32, u32) {
        let at = |t: u32| (t as u64 * self.terrain.quads as u64 / self.tiles as u64) as u32;
        (at(t), at(t + 1))
    }

    /// The tile column (or row) over which coordinate `v` lies: the one
    /// whose span holds the quad that [`Terrain::surface_height`] uses.
    fn tile_of(&self, v: f32) -> u32 {
        let t = &self.terrain;
        let u = ((v + t.half) / t.step).clamp(0.0, t.quads as f32);
        let quad = (u.floor() as u32).min(t.quads - 1) as u64;
        // The largest tile whose first quad, t * quads / tiles, is <= quad.
        (((quad + 1) * self.tiles as u64 - 1) / t.quads as u64) as u32
    }

    /// The terrain of tile `(tx, ty)`: the quads of its span with the
    /// vertices, normals and winding of the whole terrain's mesh, bit for bit.
    pub fn terrain(&self, tx: u32, ty: u32) -> TriangleMesh {
        let t = &self.terrain;
        let ((i0, i1), (j0, j1)) = (self.span(tx), self.span(ty));
        // Heights one vertex beyond the tile where the terrain goes on:
        // the normals' central differences reach that far.
        let (a0, a1, b0, b1) =
            (i0.saturating_sub(1), (i1 + 1).min(t.quads), j0.saturating_sub(1), (j1 + 1).min(t.quads));
        let width = (a1 - a0 + 1) as usize;
        let heights: Vec<f32> =
            (b0..=b1).flat_map(|j| (a0..=a1).map(move |i| t.vertex_height(i, j))).collect();
        let h = |i: u32, j: u32| heights[(j - b0) as usize * width + (i - a0) as usize];
        let row = (i1 - i0 + 1) as usize;
        let mut positions = Vec::with_capacity(row * (j1 - j0 + 1) as usize);
        let mut normals = Vec::with_capacity(positions.capacity());
        for j in j0..=j1 {
            for i in i0..=i1 {
                positions.push(Vec3::new(t.coord(i), h(i, j), t.coord(j)));
                // One-sided differences at the terrain's border, as the whole mesh has them.
                let (il, ir, jl, jr) =
                    (i.saturating_sub(1), (i + 1).min(t.quads), j.saturating_sub(1), (j + 1).min(t.quads));
                let dx = (h(ir, j) - h(il, j)) / ((ir - il) as f32 * t.step);
                let dz = (h(i, jr) - h(i, jl)) / ((jr - jl) as f32 * t.step);
                normals.push(Vec3::new(-dx, 1.0, -dz).normalize());
            }
        }
        let row = row as u32;
        let mut indices = Vec::with_capacity(2 * ((i1 - i0) * (j1 - j0)) as usize);
        for j in 0..j1 - j0 {
            for i in 0..i1 - i0 {
                let a = j * row + i;
                let (b, c, d) = (a + 1, a + row, a + row + 1);
                // Wound so the geometric normal points up (+y), as the whole mesh.
                indices.extend([[a, c, b], [b, c, d]]);
            }
        }
        TriangleMesh {
            name: format!("terrain tile ({tx}, {ty})"),
            positions,
            normals,
            indices,
            material: GROUND,
            ..Default::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn landscape() -> Landscape {
        Landscape { growth: 2, seed: 5, detail: 0.3 }
    }

    /// Every tile vertex is the whole terrain's vertex at the same grid
    /// point, position and normal bit for bit, and the tiles' triangles
    /// add up to the whole terrain's.
    #[test]
    fn terrain_tiles_are_cut_from_the_whole_terrain() {
        let l = landscape();
        let whole = Terrain::new(&l).mesh();
        let tiling = l.tiling(3).unwrap();
        let row = tiling.terrain.quads + 1;
        let mut triangles = 0;
        for (tx, ty) in (0..3).flat_map(|ty| (0..3).map(move |tx| (tx, ty))) {
            let tile = tiling.terrain(tx, ty);
            let ((i0, i1), (j0, j1)) = (tiling.span(tx), tiling.span(ty));
            assert!(i1 > i0 && j1 > j0);
            let mut v = 0;
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let w = (j * row + i) as usize;
                    assert_eq!(tile.positions[v].to_array(), whole.positions[w].to_array());
                    assert_eq!(tile.normals[v].to_array(), whole.normals[w].to_array());
                    v += 1;
                }
            }
            assert_eq!(v, tile.positions.len());
            // Winding: geometric normals point up.
            assert!((0..tile.triangle_count()).all(|t| tile.geometric_normal(t).y > 0.0));
            triangles += tile.triangle_count();
        }
        assert_eq!(triangles, whole.triangle_count());
    }

    /// The tiles' placements are the built scene's instances, each over its
    /// own tile.
    #[test]
    fn placements_are_the_instances_bucketed_by_tile() {
        let l = landscape();
        let scene = l.build();
        let tiling = l.tiling(4).unwrap();
        let mut all: Vec<Placement> = Vec::new();
        for ty in 0..4 {
            for tx in 0..4 {
                let (x0, x1) = tiling.span(tx);
                let (z0, z1) = tiling.span(ty);
                let t = &tiling.terrain;
                for p in tiling.placements(tx, ty) {
                    let at = p.object_to_world.translation;
                    assert!(at.x >= t.coord(x0) - 1e-3 && at.x <= t.coord(x1) + 1e-3, "{at} tile {tx}");
                    assert!(at.z >= t.coord(z0) - 1e-3 && at.z <= t.coord(z1) + 1e-3, "{at} tile {ty}");
                }
                all.extend(tiling.placements(tx, ty));
            }
        }
        // The scene's instance 0 is the terrain; objects follow in kind order.
        assert_eq!(all.len(), scene.instances.len() - 1);
        assert!(all.len() > 100);
        for i in &scene.instances[1..] {
            let found = all
                .iter()
                .any(|p| p.object + 1 == i.object as usize && p.object_to_world == i.object_to_world);
            assert!(found, "{i:?}");
        }
        let names: Vec<&str> = tiling.objects().map(|(n, _)| n).collect();
        assert_eq!(names, scene.objects[1..].iter().map(|o| o.name.as_str()).collect::<Vec<_>>());
    }

    #[test]
    fn tile_counts_are_checked() {
        let l = landscape();
        let quads = Terrain::new(&l).quads;
        assert!(l.tiling(0).is_err());
        assert!(l.tiling(quads + 1).is_err());
        assert_eq!(l.tiling(quads).unwrap().tiles(), quads);
        assert_eq!(Landscape::new(1).default_tiles(), 1);
        assert_eq!(Landscape::new(300).default_tiles(), 9);
    }

    #[test]
    fn without_geometry_has_the_views_and_materials_of_build() {
        let l = landscape();
        let (bare, full) = (l.without_geometry(), l.build());
        assert_eq!((bare.materials, bare.lights), (full.materials, full.lights));
        assert_eq!(bare.settings.camera.camera_to_world, full.settings.camera.camera_to_world);
        assert_eq!(MATERIAL_NAMES.len(), materials().len());
    }
}
