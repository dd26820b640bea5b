//! A binary little-endian PLY writer for triangle meshes: positions,
//! optional normals, and faces as `vertex_indices` lists (uchar count, uint
//! indices), the layout pbrt-v4's `plymesh` and [`crate::ply`] read.
//!
//! [`PlyWriter`] streams: the header takes the counts up front, then
//! vertices and faces go out one at a time, so a mesh assembled on the fly
//! (baked instances) never has to exist in memory.

use std::io::{self, Write};

use glam::Vec3;

use crate::TriangleMesh;

/// Bytes gathered before they are handed to the writer: large writes keep
/// a compressing or unbuffered writer fast.
const CHUNK: usize = 1 << 20;

/// Writes one PLY file: [`PlyWriter::new`] writes the header, then exactly
/// the announced vertices and faces follow, and [`PlyWriter::finish`]
/// checks the counts and flushes.
pub struct PlyWriter<W: Write> {
    out: W,
    buf: Vec<u8>,
    normals: bool,
    vertices_left: u64,
    faces_left: u64,
}

impl<W: Write> PlyWriter<W> {
    /// Writes the header of a mesh of `vertices` vertices (with normals when
    /// `normals`) and `faces` triangles. `comment` goes in a comment line.
    pub fn new(mut out: W, vertices: u64, faces: u64, normals: bool, comment: &str) -> io::Result<Self> {
        // Indices are written as 32-bit unsigned integers (and callers
        // count vertices in them).
        if vertices > u32::MAX as u64 {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("{vertices} vertices: more than 32-bit indices can address"),
            ));
        }
        let mut header = format!(
            "ply\nformat binary_little_endian 1.0\ncomment {}\nelement vertex {vertices}\n\
             property float x\nproperty float y\nproperty float z\n",
            comment.replace('\n', " ")
        );
        if normals {
            header.push_str("property float nx\nproperty float ny\nproperty float nz\n");
        }
        header.push_str(&format!(
            "element face {faces}\nproperty list uchar uint vertex_indices\nend_header\n"
        ));
        out.write_all(header.as_bytes())?;
        Ok(PlyWriter {
            out,
            buf: Vec::with_capacity(CHUNK + 64),
            normals,
            vertices_left: vertices,
            faces_left: faces,
        })
    }

    fn spill(&mut self) -> io::Result<()> {
        if self.buf.len() >= CHUNK {
            self.out.write_all(&self.buf)?;
            self.buf.clear();
        }
        Ok(())
    }

    /// The next vertex; `normal` is ignored when the header has no normals.
    pub fn vertex(&mut self, position: Vec3, normal: Vec3) -> io::Result<()> {
        if self.vertices_left == 0 {
            return Err(mismatch("more vertices than the header announced"));
        }
        self.vertices_left -= 1;
        for v in position.to_array() {
            self.buf.extend_from_slice(&v.to_le_bytes());
        }
        if self.normals {
            for v in normal.to_array() {
                self.buf.extend_from_slice(&v.to_le_bytes());
            }
        }
        self.spill()
    }

    /// The next triangle; every vertex must have been written before.
    pub fn face(&mut self, indices: [u32; 3]) -> io::Result<()> {
        if self.vertices_left > 0 {
            return Err(mismatch("a face before all vertices"));
        }
        if self.faces_left == 0 {
            return Err(mismatch("more faces than the header announced"));
        }
        self.faces_left -= 1;
        self.buf.push(3);
        for i in indices {
            self.buf.extend_from_slice(&i.to_le_bytes());
        }
        self.spill()
    }

    /// Writes what is left and flushes; an error if fewer vertices or faces
    /// came than announced. Returns the writer.
    pub fn finish(mut self) -> io::Result<W> {
        if self.vertices_left > 0 || self.faces_left > 0 {
            return Err(mismatch("fewer vertices or faces than the header announced"));
        }
        self.out.write_all(&self.buf)?;
        self.out.flush()?;
        Ok(self.out)
    }
}

fn mismatch(what: &str) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, format!("PLY writer: {what}"))
}

/// Writes `mesh` (positions, normals if it has them, triangles) as one
/// binary PLY file; `comment` goes in the header. Returns the writer.
pub fn write_ply<W: Write>(mesh: &TriangleMesh, out: W, comment: &str) -> io::Result<W> {
    let normals = !mesh.normals.is_empty();
    let mut ply =
        PlyWriter::new(out, mesh.positions.len() as u64, mesh.indices.len() as u64, normals, comment)?;
    for (i, &p) in mesh.positions.iter().enumerate() {
        ply.vertex(p, mesh.normals.get(i).copied().unwrap_or(Vec3::ZERO))?;
    }
    for &t in &mesh.indices {
        ply.face(t)?;
    }
    ply.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mesh(normals: bool) -> TriangleMesh {
        TriangleMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(1.0, 1.0, -2.5)],
            normals: if normals { vec![Vec3::Z, Vec3::Z, Vec3::X, Vec3::Y] } else { Vec::new() },
            indices: vec![[0, 1, 2], [2, 1, 3]],
            ..Default::default()
        }
    }

    #[test]
    fn reads_back_with_and_without_normals() {
        for normals in [true, false] {
            let m = mesh(normals);
            let bytes = write_ply(&m, Vec::new(), "test").unwrap();
            let back = crate::ply::parse_ply(&bytes).unwrap();
            assert_eq!((back.positions, back.normals, back.indices), (m.positions, m.normals, m.indices));
            let size = 4 * (12 + 12 * normals as usize) + 2 * 13;
            assert!(bytes.ends_with(&[3, 2, 0, 0, 0, 1, 0, 0, 0, 3, 0, 0, 0]), "{bytes:?}");
            assert!(bytes.len() > size && String::from_utf8_lossy(&bytes).contains("end_header\n"));
        }
    }

    #[test]
    fn counts_must_match_the_header() {
        let mut ply = PlyWriter::new(Vec::new(), 1, 1, false, "").unwrap();
        assert!(ply.face([0, 0, 0]).is_err());
        ply.vertex(Vec3::ZERO, Vec3::ZERO).unwrap();
        assert!(ply.vertex(Vec3::ZERO, Vec3::ZERO).is_err());
        let ply = PlyWriter::new(Vec::new(), 1, 1, false, "").unwrap();
        assert!(ply.finish().is_err());
        assert!(PlyWriter::new(Vec::new(), 1 << 33, 1, false, "").is_err());
    }
}
