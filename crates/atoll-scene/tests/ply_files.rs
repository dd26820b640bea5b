//! The PLY reader on files: ASCII, binary little and big endian, quads,
//! gzip; and `plymesh` shapes that use them.

mod common;

use atoll_scene::ply::read_ply;
use common::{load_world, temp_dir, write};
use glam::{Vec2, Vec3};
use std::io::Write;

const POSITIONS: [[f32; 3]; 5] =
    [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.5, 1.0]];

/// A binary PLY: 5 vertices with normals and `s t`, one quad and one
/// triangle with a ushort count and uint indices, plus a skipped property.
fn binary_ply(big_endian: bool) -> Vec<u8> {
    let fmt = if big_endian { "binary_big_endian" } else { "binary_little_endian" };
    let mut b = format!(
        "ply\nformat {fmt} 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float s\nproperty float t\n\
         element face 2\nproperty list ushort uint vertex_indices\nproperty list uchar float extra\nend_header\n"
    )
    .into_bytes();
    let f = |x: f32| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() };
    for (i, p) in POSITIONS.iter().enumerate() {
        p.iter().for_each(|&x| b.extend(f(x)));
        b.push(200);
        [0.0, 0.0, 1.0, i as f32 * 0.25, 1.0 - i as f32 * 0.25].iter().for_each(|&x| b.extend(f(x)));
    }
    let u16b = |x: u16| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() };
    let u32b = |x: u32| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() };
    b.extend(u16b(4));
    [0, 1, 2, 3].iter().for_each(|&i| b.extend(u32b(i)));
    b.push(1);
    b.extend(f(9.0));
    b.extend(u16b(3));
    [0, 1, 4].iter().for_each(|&i| b.extend(u32b(i)));
    b.push(0);
    b
}

fn check(m: &atoll_scene::ply::PlyMesh) {
    assert_eq!(m.positions, POSITIONS.map(Vec3::from).to_vec());
    assert_eq!(m.normals, vec![Vec3::Z; 5]);
    assert_eq!(m.uvs[2], Vec2::new(0.5, 0.5));
    assert_eq!(m.uvs[4], Vec2::new(1.0, 0.0));
    assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3], [0, 1, 4]]);
    assert_eq!(m.skipped_faces, 0);
}

#[test]
fn binary_little_and_big_endian() {
    let dir = temp_dir("ply-bin");
    check(&read_ply(&write(&dir, "le.ply", binary_ply(false))).unwrap());
    check(&read_ply(&write(&dir, "be.ply", binary_ply(true))).unwrap());
}

#[test]
fn ascii() {
    let dir = temp_dir("ply-ascii");
    let mut text = String::from(
        "ply\nformat ascii 1.0\ncomment made by hand\nelement vertex 5\nproperty float x\nproperty float y\n\
         property float z\nproperty uchar red\nproperty float nx\nproperty float ny\nproperty float nz\n\
         property float texture_u\nproperty float texture_v\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n",
    );
    for (i, p) in POSITIONS.iter().enumerate() {
        let uv = [i as f32 * 0.25, 1.0 - i as f32 * 0.25];
        text += &format!("{} {} {} 200 0 0 1 {} {}\n", p[0], p[1], p[2], uv[0], uv[1]);
    }
    text += "4 0 1 2 3\n3 0 1 4\n5 0 1 2 3 4\n";
    let m = read_ply(&write(&dir, "a.ply", text)).unwrap();
    assert_eq!(m.skipped_faces, 1);
    check(&atoll_scene::ply::PlyMesh { skipped_faces: 0, ..m });
}

#[test]
fn gzip_and_plymesh_shapes() {
    let dir = temp_dir("ply-gz");
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    gz.write_all(&binary_ply(true)).unwrap();
    let path = write(&dir, "mesh.ply.gz", gz.finish().unwrap());
    check(&read_ply(&path).unwrap());

    // Through the loader (the file named relative to the scene's folder):
    // positions and normals transformed, uvs kept.
    let world = "WorldBegin\nTranslate 0 0 2\nShape \"plymesh\" \"string filename\" \"mesh.ply.gz\"\n";
    let s = atoll_scene::pbrt::load_str(world, "test.pbrt", &dir).unwrap().scene;
    // Named by an absolute path, it is refused, saying how to allow it.
    let absolute = format!("Shape \"plymesh\" \"string filename\" \"{}\"", path.display());
    let e = load_world("", &absolute).unwrap_err();
    assert!(e.message.contains("--allow-outside-paths"), "{e}");
    let m = &s.meshes[0];
    assert_eq!(m.positions[4], Vec3::new(0.5, 0.5, 3.0));
    assert_eq!(m.normals[0], Vec3::Z);
    assert_eq!(m.indices.len(), 3);
    assert!(m.name.ends_with("mesh.ply.gz"));
}

#[test]
fn corrupt_files() {
    let dir = temp_dir("ply-bad");
    let full = binary_ply(false);
    for cut in [10, 100, full.len() - 30, full.len() - 1] {
        let e = read_ply(&write(&dir, "cut.ply", &full[..cut])).unwrap_err().to_string();
        assert!(e.contains("end of file") || e.contains("end_header"), "cut at {cut}: {e}");
    }
    let e = read_ply(&write(&dir, "gz.ply.gz", [0x1f, 0x8b, 1, 2, 3])).unwrap_err().to_string();
    assert!(e.contains("gzip"), "{e}");
    let e = read_ply(&write(
        &dir,
        "noxyz.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n",
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("x, y, z"), "{e}");
}
