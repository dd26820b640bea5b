//! `atoll gen landscape --files`: the landscape as a folder of files, the
//! way production scenes arrive (pbrt-v4's Moana island), to benchmark
//! loading them:
//!
//! ```text
//! DIR/scene.pbrt                       options, lights, materials, one Import per tile
//! DIR/geometry/tile-NNNN.pbrt          a tile's shapes (and, --instanced, its instances)
//! DIR/geometry/tile-NNNN-ground.ply    the tile's terrain
//! DIR/geometry/tile-NNNN-MAT[-flat].ply   its objects baked, one per material
//!                                      (-flat: the meshes without normals)
//! DIR/geometry/object-NAME-M.ply       --instanced: the objects' meshes
//! ```
//!
//! File names inside the scene are relative to DIR, the scene file's
//! folder, however deep the file naming them: atoll and pbrt-v4 both
//! resolve them against the main scene file's folder.
//!
//! Tiles are written in parallel, each by one worker from its own terrain
//! and placements, baked meshes streamed vertex by vertex: memory stays a
//! few tiles' worth at any growth, and every file's bytes depend only on
//! (growth, seed, detail, tiles) and the options.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use atoll_scene::landscape::{Landscape, Placement, Tiling, MATERIAL_NAMES};
use atoll_scene::ply_write::{write_ply, PlyWriter};
use atoll_scene::{MaterialId, TriangleMesh};
use flate2::write::GzEncoder;
use glam::{Mat4, Vec3};
use rayon::prelude::*;

use super::{mib, write_prelude};
use crate::CliError;

/// How the folder is written.
pub struct Options {
    /// Objects as `ObjectBegin`/`ObjectInstance` instead of baked meshes.
    pub instanced: bool,
    /// PLY files gzip-compressed (`.ply.gz`).
    pub gzip: bool,
}

/// What was written.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Written {
    pub files: u64,
    pub bytes: u64,
    /// Triangles stored in the files (each instanced object counted once).
    pub unique_triangles: u64,
}

impl Written {
    fn add(self, other: Written) -> Written {
        Written {
            files: self.files + other.files,
            bytes: self.bytes + other.bytes,
            unique_triangles: self.unique_triangles + other.unique_triangles,
        }
    }

    /// The summary line, for writing that took `seconds`.
    pub fn print(&self, dir: &Path, seconds: f64) {
        println!(
            "{}: {} files, {} ({} bytes), {} unique triangles, written in {seconds:.2} s ({:.0} MB/s)",
            dir.display(),
            self.files,
            mib(self.bytes),
            self.bytes,
            self.unique_triangles,
            self.bytes as f64 / 1e6 / seconds.max(1e-3)
        );
    }
}

/// Writes `landscape`, cut as `tiling`, into the folder `dir` (made if
/// missing; files of the same names are replaced, others left alone).
/// `header` is the first comment of scene.pbrt.
pub fn write(
    landscape: &Landscape,
    tiling: &Tiling,
    dir: &Path,
    options: &Options,
    header: &str,
) -> Result<Written, CliError> {
    let tiles = tiling.tiles();
    make_folders(dir)?;
    let out = Out { dir, gzip: options.gzip };
    let groups = Group::all(tiling);
    let mut written = if options.instanced { write_objects(tiling, &out)? } else { Written::default() };
    let per_tile = (0..tiles * tiles)
        .into_par_iter()
        .map(|t| write_tile(tiling, &groups, &out, options.instanced, t, header))
        .collect::<Result<Vec<_>, _>>()?;
    written = per_tile.into_iter().fold(written, Written::add);
    // Last, so that a folder whose writing failed has no scene to load.
    Ok(written.add(write_scene(landscape, tiling, &out, options.instanced, header)?))
}

fn make_folders(dir: &Path) -> Result<(), CliError> {
    if dir.exists() && !dir.is_dir() {
        return Err(CliError::Input(format!("{}: is not a folder (--files writes a folder)", dir.display())));
    }
    let geometry = dir.join("geometry");
    std::fs::create_dir_all(&geometry)
        .map_err(|e| CliError::Runtime(format!("{}: cannot make the folder: {e}", geometry.display())))
}

/// Where files go, and whether PLY files are compressed.
struct Out<'a> {
    dir: &'a Path,
    gzip: bool,
}

impl Out<'_> {
    /// The name of PLY file `stem` relative to the scene's folder.
    fn ply_name(&self, stem: &str) -> String {
        format!("geometry/{stem}.ply{}", if self.gzip { ".gz" } else { "" })
    }

    /// Writes the file `name` (relative to the folder) with `fill`; its size.
    fn file(
        &self,
        name: &str,
        gzip: bool,
        fill: impl FnOnce(&mut Sink) -> io::Result<()>,
    ) -> Result<u64, CliError> {
        let path = self.dir.join(name);
        let failed = |e: io::Error| CliError::Runtime(format!("{}: cannot write: {e}", path.display()));
        let file = BufWriter::with_capacity(1 << 20, File::create(&path).map_err(failed)?);
        // Level 1: compressing must not be what limits a benchmark's writing.
        let mut sink = if gzip {
            Sink::Gzip(GzEncoder::new(file, flate2::Compression::fast()))
        } else {
            Sink::Plain(file)
        };
        fill(&mut sink).and_then(|_| sink.finish()).map_err(failed)?;
        Ok(std::fs::metadata(&path).map_err(failed)?.len())
    }

    /// Writes `mesh` as PLY file `stem`.
    fn mesh(&self, stem: &str, mesh: &TriangleMesh, comment: &str) -> Result<(String, Written), CliError> {
        let name = self.ply_name(stem);
        let bytes = self.file(&name, self.gzip, |sink| write_ply(mesh, sink, comment).map(|_| ()))?;
        Ok((name, Written { files: 1, bytes, unique_triangles: mesh.triangle_count() as u64 }))
    }

    /// Writes the text file `name`.
    fn text(&self, name: &str, text: &str) -> Result<Written, CliError> {
        let bytes = self.file(name, false, |sink| sink.write_all(text.as_bytes()))?;
        Ok(Written { files: 1, bytes, ..Default::default() })
    }
}

/// A file being written, compressed or not.
enum Sink {
    Plain(BufWriter<File>),
    Gzip(GzEncoder<BufWriter<File>>),
}

impl Sink {
    /// Ends the gzip stream and flushes: errors a drop would swallow.
    fn finish(self) -> io::Result<()> {
        let mut file = match self {
            Sink::Plain(file) => file,
            Sink::Gzip(gz) => gz.finish()?,
        };
        file.flush()
    }
}

impl Write for Sink {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        match self {
            Sink::Plain(w) => w.write(buf),
            Sink::Gzip(w) => w.write(buf),
        }
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        match self {
            Sink::Plain(w) => w.write_all(buf),
            Sink::Gzip(w) => w.write_all(buf),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        match self {
            Sink::Plain(w) => w.flush(),
            Sink::Gzip(w) => w.flush(),
        }
    }
}

/// Object meshes baked into one PLY file per tile: those of one material,
/// with normals or without (a PLY file's vertices all have the same properties).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Group {
    material: MaterialId,
    normals: bool,
}

impl Group {
    fn of(mesh: &TriangleMesh) -> Group {
        Group { material: mesh.material, normals: !mesh.normals.is_empty() }
    }

    /// The groups of the tiling's object meshes, in material order.
    fn all(tiling: &Tiling) -> Vec<Group> {
        let mut groups: Vec<Group> =
            tiling.objects().flat_map(|(_, meshes)| meshes.iter().map(Group::of)).collect();
        groups.sort();
        groups.dedup();
        groups
    }

    fn suffix(&self) -> String {
        let name = MATERIAL_NAMES.get(self.material as usize).copied().unwrap_or("material");
        format!("{name}{}", if self.normals { "" } else { "-flat" })
    }
}

/// `Shape "plymesh"` with its material, in an attribute block.
fn plymesh(text: &mut String, material: MaterialId, name: &str, triangles: u64) {
    text.push_str(&format!(
        "AttributeBegin\n  NamedMaterial \"material_{material}\"\n  # {triangles} triangles\n  \
         Shape \"plymesh\" \"string filename\" [ \"{name}\" ]\nAttributeEnd\n"
    ));
}

/// Writes tile `t`: its terrain, its objects baked (or its instances in
/// the tile's text), and the tile's scene file.
fn write_tile(
    tiling: &Tiling,
    groups: &[Group],
    out: &Out,
    instanced: bool,
    t: u32,
    header: &str,
) -> Result<Written, CliError> {
    let k = tiling.tiles();
    let (tx, ty) = (t % k, t / k);
    let stem = format!("tile-{t:04}");
    let comment = format!("{header}: tile {t} ({tx}, {ty}) of {k} x {k}");
    let mut text = format!("# {comment}\n");
    let terrain = tiling.terrain(tx, ty);
    let (name, mut written) = out.mesh(&format!("{stem}-ground"), &terrain, &comment)?;
    plymesh(&mut text, tiling.terrain_material(), &name, written.unique_triangles);
    drop(terrain);
    let placements = tiling.placements(tx, ty);
    if instanced {
        instances(&mut text, tiling, placements);
    } else {
        for &group in groups {
            let Some((name, baked)) = bake(tiling, placements, group, out, &stem, &comment)? else {
                continue;
            };
            plymesh(&mut text, group.material, &name, baked.unique_triangles);
            written = written.add(baked);
        }
    }
    Ok(written.add(out.text(&format!("geometry/{stem}.pbrt"), &text)?))
}

/// One `Transform`/`ObjectInstance` pair per placement (the matrix
/// column by column, as pbrt lists it).
fn instances(text: &mut String, tiling: &Tiling, placements: &[Placement]) {
    let names: Vec<&str> = tiling.objects().map(|(name, _)| name).collect();
    text.push_str("AttributeBegin\n");
    for p in placements {
        let m = Mat4::from(p.object_to_world).to_cols_array().map(|v| v.to_string()).join(" ");
        text.push_str(&format!("  Transform [ {m} ] ObjectInstance \"{}\"\n", names[p.object]));
    }
    text.push_str("AttributeEnd\n");
}

/// The meshes of `group` that the placements put on the tile.
fn group_meshes<'a>(
    tiling: &'a Tiling,
    placements: &'a [Placement],
    group: Group,
) -> impl Iterator<Item = (&'a Placement, &'a TriangleMesh)> + 'a {
    let objects: Vec<&[TriangleMesh]> = tiling.objects().map(|(_, meshes)| meshes).collect();
    placements.iter().flat_map(move |p| {
        objects[p.object].iter().filter(move |m| Group::of(m) == group).map(move |m| (p, m))
    })
}

/// Writes the tile's meshes of `group` in world space as one PLY file
/// (none when the tile has none): vertices streamed instance by instance,
/// then the faces, so no baked mesh is ever held. Its name, and what was written.
fn bake(
    tiling: &Tiling,
    placements: &[Placement],
    group: Group,
    out: &Out,
    stem: &str,
    comment: &str,
) -> Result<Option<(String, Written)>, CliError> {
    let meshes = || group_meshes(tiling, placements, group);
    let vertices: u64 = meshes().map(|(_, m)| m.positions.len() as u64).sum();
    let faces: u64 = meshes().map(|(_, m)| m.triangle_count() as u64).sum();
    if faces == 0 {
        return Ok(None);
    }
    let name = out.ply_name(&format!("{stem}-{}", group.suffix()));
    let bytes = out.file(&name, out.gzip, |sink| {
        let mut ply = PlyWriter::new(sink, vertices, faces, group.normals, comment)?;
        for (p, mesh) in meshes() {
            let m = p.object_to_world;
            // Normals go by the inverse transpose (exact for any scale).
            let normal_matrix = m.matrix3.inverse().transpose();
            for (i, &position) in mesh.positions.iter().enumerate() {
                let n = mesh.normals.get(i).map_or(Vec3::ZERO, |&n| (normal_matrix * n).normalize_or_zero());
                ply.vertex(m.transform_point3(position), n)?;
            }
        }
        let mut first = 0u32;
        for (p, mesh) in meshes() {
            // A mirroring transform turns the winding around; swapping two
            // corners keeps the geometric normal facing where it did.
            let mirrored = p.object_to_world.matrix3.determinant() < 0.0;
            for &[a, b, c] in &mesh.indices {
                let [a, b, c] = [a + first, b + first, c + first];
                ply.face(if mirrored { [a, c, b] } else { [a, b, c] })?;
            }
            first += mesh.positions.len() as u32;
        }
        ply.finish().map(|_| ())
    })?;
    Ok(Some((name, Written { files: 1, bytes, unique_triangles: faces })))
}

/// `--instanced`: each object mesh as its own PLY file.
fn write_objects(tiling: &Tiling, out: &Out) -> Result<Written, CliError> {
    let mut written = Written::default();
    for (name, meshes) in tiling.objects() {
        for (i, mesh) in meshes.iter().enumerate() {
            let (_, w) = out.mesh(&object_stem(name, i), mesh, name)?;
            written = written.add(w);
        }
    }
    Ok(written)
}

fn object_stem(object: &str, mesh: usize) -> String {
    format!("object-{object}-{mesh}")
}

/// scene.pbrt: what `write_pbrt` writes before the geometry, the object
/// definitions when instanced, then one `Import` per tile.
fn write_scene(
    landscape: &Landscape,
    tiling: &Tiling,
    out: &Out,
    instanced: bool,
    header: &str,
) -> Result<Written, CliError> {
    let mut bytes = Vec::new();
    write_prelude(&landscape.without_geometry(), &mut bytes, header)
        .map_err(|e| CliError::Runtime(format!("scene.pbrt: {e}")))?;
    let mut text = String::from_utf8_lossy(&bytes).into_owned();
    if instanced {
        for (name, meshes) in tiling.objects() {
            text.push_str(&format!("ObjectBegin \"{name}\"\n"));
            for (i, mesh) in meshes.iter().enumerate() {
                plymesh(
                    &mut text,
                    mesh.material,
                    &out.ply_name(&object_stem(name, i)),
                    mesh.triangle_count() as u64,
                );
            }
            text.push_str("ObjectEnd\n");
        }
    }
    let k = tiling.tiles();
    text.push_str(&format!("# {k} x {k} tiles\n"));
    for t in 0..k * k {
        text.push_str(&format!("Import \"geometry/tile-{t:04}.pbrt\"\n"));
    }
    out.text("scene.pbrt", &text)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    use atoll_scene::{Material, Scene};

    fn landscape() -> Landscape {
        Landscape { growth: 2, seed: 7, detail: 0.3 }
    }

    fn write_to(dir: &Path, instanced: bool, gzip: bool) -> Written {
        let tiling = landscape().tiling(3).unwrap();
        write(&landscape(), &tiling, dir, &Options { instanced, gzip }, "test").unwrap()
    }

    /// Loads the folder's scene with atoll's loader: no warnings allowed.
    fn load(dir: &Path) -> Scene {
        let loaded = atoll_scene::load_any(&dir.join("scene.pbrt")).unwrap();
        assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
        loaded.scene
    }

    /// Instanced triangles by the landscape's material ids (the loader
    /// numbers materials by first use, so they are matched by value).
    fn per_material(scene: &Scene) -> Vec<u64> {
        let reference: Vec<Material> = landscape().without_geometry().materials;
        let mut counts = vec![0; reference.len()];
        for inst in &scene.instances {
            for &m in &scene.objects[inst.object as usize].meshes {
                let mesh = &scene.meshes[m as usize];
                let material = &scene.materials[mesh.material as usize];
                counts[reference.iter().position(|r| r == material).unwrap()] += mesh.triangle_count() as u64;
            }
        }
        counts
    }

    /// Every file under `dir`, by name, with its bytes.
    fn files(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
        let mut all = Vec::new();
        for sub in [dir.to_path_buf(), dir.join("geometry")] {
            for entry in std::fs::read_dir(&sub).unwrap() {
                let path = entry.unwrap().path();
                if path.is_file() {
                    let bytes = std::fs::read(&path).unwrap();
                    all.push((path.strip_prefix(dir).unwrap().to_path_buf(), bytes));
                }
            }
        }
        all.sort();
        all
    }

    /// The bounds of every vertex placed in the world (`Scene::stats`
    /// bounds transformed object boxes, looser than baked vertices').
    fn vertex_bounds(scene: &Scene) -> (Vec3, Vec3) {
        let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for inst in &scene.instances {
            for &m in &scene.objects[inst.object as usize].meshes {
                for &p in &scene.meshes[m as usize].positions {
                    let p = inst.object_to_world.transform_point3(p);
                    (lo, hi) = (lo.min(p), hi.max(p));
                }
            }
        }
        (lo, hi)
    }

    /// Same triangle count, bounds, materials and view as the procedural
    /// scene; `written` tells the truth about the folder.
    fn assert_like_procedural(scene: &Scene, dir: &Path, written: Written) {
        let procedural = landscape().build();
        let (a, b) = (scene.stats(), procedural.stats());
        assert_eq!(a.instanced_triangles, landscape().estimate().instanced_triangles);
        assert_eq!(a.instanced_triangles, b.instanced_triangles);
        let ((lo, hi), (rlo, rhi)) = (vertex_bounds(scene), vertex_bounds(&procedural));
        let extent = (rhi - rlo).max_element();
        assert!((lo - rlo).abs().max_element() <= 1e-6 * extent, "{lo} {hi} {rlo} {rhi}");
        assert!((hi - rhi).abs().max_element() <= 1e-6 * extent, "{lo} {hi} {rlo} {rhi}");
        assert_eq!(per_material(scene), per_material(&procedural));
        assert_eq!(a.unique_triangles, written.unique_triangles);
        let (cam, reference) = (&scene.settings.camera, &procedural.settings.camera);
        assert!(cam.camera_to_world.abs_diff_eq(reference.camera_to_world, 1e-4));
        assert_eq!(scene.lights.len(), procedural.lights.len());
        let on_disk = files(dir);
        assert_eq!(written.files, on_disk.len() as u64);
        assert_eq!(written.bytes, on_disk.iter().map(|(_, b)| b.len() as u64).sum::<u64>());
    }

    #[test]
    fn baked_folder_loads_as_the_procedural_scene() {
        let dir = tempfile::tempdir().unwrap();
        let written = write_to(dir.path(), false, false);
        let scene = load(dir.path());
        assert_like_procedural(&scene, dir.path(), written);
        // Baked: one world object, every triangle unique.
        assert_eq!(scene.instances.len(), 1);
        assert_eq!(written.unique_triangles, landscape().estimate().instanced_triangles);
        let imports = std::fs::read_to_string(dir.path().join("scene.pbrt")).unwrap();
        assert_eq!(imports.matches("Import \"geometry/tile-").count(), 9);
        assert_baked_as_placed(&scene);
    }

    /// Each baked mesh is its tile's placements' object meshes of its group,
    /// one after the other: positions placed, normals turned as vectors
    /// (instances scale uniformly) and unit length, the same corners in the
    /// same order (so the same winding).
    fn assert_baked_as_placed(scene: &Scene) {
        let tiling = landscape().tiling(3).unwrap();
        let mut baked = 0;
        for mesh in &scene.meshes {
            let name = mesh.name.strip_prefix("geometry/tile-").unwrap().strip_suffix(".ply").unwrap();
            let (t, suffix) = name.split_once('-').unwrap();
            let t: u32 = t.parse().unwrap();
            let Some(&group) = Group::all(&tiling).iter().find(|g| g.suffix() == suffix) else {
                assert_eq!(suffix, "ground");
                continue;
            };
            let (mut positions, mut normals, mut indices) = (Vec::new(), Vec::new(), Vec::new());
            for (p, m) in group_meshes(&tiling, tiling.placements(t % 3, t / 3), group) {
                let first = positions.len() as u32;
                let to_world = Mat4::from(p.object_to_world);
                positions.extend(m.positions.iter().map(|&q| to_world.transform_point3(q)));
                normals.extend(m.normals.iter().map(|&n| to_world.transform_vector3(n).normalize()));
                indices.extend(m.indices.iter().map(|t| t.map(|i| i + first)));
            }
            assert_eq!(indices, mesh.indices, "{}", mesh.name);
            assert_eq!(positions.len(), mesh.positions.len());
            let close = |a: &[Vec3], b: &[Vec3], e: f32| a.iter().zip(b).all(|(p, q)| p.abs_diff_eq(*q, e));
            assert!(close(&positions, &mesh.positions, 1e-4), "{}", mesh.name);
            assert_eq!(normals.len(), mesh.normals.len());
            assert!(close(&normals, &mesh.normals, 1e-5), "{}", mesh.name);
            baked += 1;
        }
        assert!(baked >= 9 * 4, "{baked} baked meshes");
    }

    #[test]
    fn gzip_folder_loads_to_the_same_triangles() {
        let (plain, gzip) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
        let plain_written = write_to(plain.path(), false, false);
        let written = write_to(gzip.path(), false, true);
        assert!(written.bytes < plain_written.bytes);
        let scene = load(gzip.path());
        assert_like_procedural(&scene, gzip.path(), written);
        let plain = load(plain.path());
        assert_eq!(scene.meshes.len(), plain.meshes.len());
        for (m, n) in scene.meshes.iter().zip(&plain.meshes) {
            assert_eq!((&m.positions, &m.normals, &m.indices), (&n.positions, &n.normals, &n.indices));
        }
        let names = files(gzip.path());
        assert!(names.iter().filter(|(p, _)| p.to_string_lossy().ends_with(".ply.gz")).count() >= 9);
        assert!(!names.iter().any(|(p, _)| p.to_string_lossy().ends_with(".ply")));
    }

    #[test]
    fn writing_twice_gives_the_same_bytes() {
        for (instanced, gzip) in [(false, false), (true, true)] {
            let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
            assert_eq!(write_to(a.path(), instanced, gzip), write_to(b.path(), instanced, gzip));
            let (fa, fb) = (files(a.path()), files(b.path()));
            assert!(fa.len() > 10);
            assert!(fa == fb, "{instanced} {gzip}");
        }
    }

    #[test]
    fn instanced_folder_loads_with_the_same_instanced_triangles() {
        let dir = tempfile::tempdir().unwrap();
        let written = write_to(dir.path(), true, false);
        let scene = load(dir.path());
        assert_like_procedural(&scene, dir.path(), written);
        let e = landscape().estimate();
        let s = scene.stats();
        assert_eq!((s.unique_triangles, s.instances as u64), (e.unique_triangles, e.instances));
        // The objects as build makes them: their names and triangles.
        let procedural = landscape().build();
        for o in &procedural.objects[1..] {
            let back = scene.objects.iter().position(|p| p.name == o.name).unwrap();
            let id = procedural.objects.iter().position(|p| p.name == o.name).unwrap();
            assert_eq!(scene.object_triangles(back as u32), procedural.object_triangles(id as u32));
        }
    }

    #[test]
    fn bad_outputs_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("file");
        std::fs::write(&file, "x").unwrap();
        let (l, options) = (landscape(), Options { instanced: false, gzip: false });
        let tiling = l.tiling(2).unwrap();
        assert!(matches!(write(&l, &tiling, &file, &options, ""), Err(CliError::Input(_))));
        // A folder beneath a file cannot be made.
        assert!(matches!(write(&l, &tiling, &file.join("sub"), &options, ""), Err(CliError::Runtime(_))));
        assert!(!dir.path().join("scene.pbrt").exists());
    }
}
