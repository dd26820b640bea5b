//! A reader for ASCII OFF meshes (Geomview's Object File Format), the format
//! of CGAL's and many geometry-processing data sets.
//!
//! Header keyword `[ST][C][N][4][n]OFF`, optionally followed on the same line
//! by the counts `vertices faces edges`; then one vertex per line (`x y z`,
//! then normals when the keyword has `N`; colours and texture coordinates are
//! ignored), then one face per line (`n i0 .. i(n-1)`, optional colour after).
//! Polygons are split into triangle fans. `#` starts a comment. Binary OFF
//! and the `4`/`n` (4D, n-D) variants are refused with a clear message.

use glam::Vec3;

use crate::error::FileLoc;

/// The triangles of an OFF file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OffMesh {
    pub positions: Vec<Vec3>,
    /// Per-vertex normals (`NOFF`); empty otherwise.
    pub normals: Vec<Vec3>,
    pub indices: Vec<[u32; 3]>,
    /// Faces with fewer than three vertices, skipped.
    pub degenerate_faces: usize,
}

/// Why an OFF file could not be read, at a line (0: the whole file).
#[derive(Clone, Debug, PartialEq)]
pub struct OffError {
    pub line: u32,
    pub message: String,
}

impl OffError {
    /// The error's location in `file`.
    pub fn loc(&self, file: &str) -> FileLoc {
        if self.line == 0 {
            FileLoc::whole_file(file)
        } else {
            FileLoc::new(file, self.line, 1)
        }
    }
}

/// Non-empty lines with comments removed, numbered from 1.
fn content_lines(text: &str) -> impl Iterator<Item = (u32, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i as u32 + 1, l.split('#').next().unwrap_or("").trim()))
        .filter(|(_, l)| !l.is_empty())
}

/// Parses the bytes of an ASCII OFF file.
pub fn parse_off(bytes: &[u8]) -> Result<OffMesh, OffError> {
    let err = |line: u32, message: String| Err(OffError { line, message });
    let Ok(text) = std::str::from_utf8(bytes) else {
        return err(0, "not a text OFF file (binary OFF is not supported)".into());
    };
    let mut lines = content_lines(text);
    let Some((first_line, header)) = lines.next() else { return err(0, "empty file".into()) };
    let mut words = header.split_whitespace();
    let keyword = words.next().unwrap_or("");
    let Some(prefix) = keyword.strip_suffix("OFF") else {
        return err(first_line, format!("not an OFF file: expected the keyword OFF, found '{keyword}'"));
    };
    if prefix.contains('4') || prefix.contains('n') {
        return err(first_line, format!("'{keyword}': 4D and n-dimensional OFF files are not supported"));
    }
    let has_normals = prefix.contains('N');
    let mut rest: Vec<&str> = words.collect();
    if rest.first() == Some(&"BINARY") {
        return err(first_line, "binary OFF is not supported".into());
    }
    let mut counts_line = first_line;
    if rest.is_empty() {
        let Some((n, l)) = lines.next() else {
            return err(first_line, "missing vertex and face counts".into());
        };
        counts_line = n;
        rest = l.split_whitespace().collect();
    }
    let count = |i: usize| -> Result<usize, OffError> {
        rest.get(i).and_then(|s| s.parse().ok()).ok_or_else(|| OffError {
            line: counts_line,
            message: "expected the counts 'vertices faces edges'".into(),
        })
    };
    let (nv, nf) = (count(0)?, count(1)?);
    // Counts come from the header: a vertex takes at least 6 bytes ("0 0 0\n"),
    // a face at least 8 ("3 0 1 2\n"). Claims the file cannot hold are
    // refused before anything is allocated for them.
    let (most_vertices, most_faces) = (bytes.len() / 6, bytes.len() / 8);
    if nv > most_vertices || nf > most_faces {
        return err(
            counts_line,
            format!(
                "the header claims {nv} vertices and {nf} faces, more than the file's {} bytes can hold (truncated?)",
                bytes.len()
            ),
        );
    }
    let mut m = OffMesh { positions: Vec::with_capacity(nv), ..Default::default() };
    let expected = if has_normals { 6 } else { 3 };
    for _ in 0..nv {
        let Some((n, l)) = lines.next() else {
            return err(0, format!("truncated: {} of {nv} vertices", m.positions.len()));
        };
        let v: Vec<f32> = l.split_whitespace().take(expected).map_while(|s| s.parse().ok()).collect();
        if v.len() < expected {
            return err(n, format!("expected {expected} numbers for a vertex, found '{l}'"));
        }
        if v.iter().any(|x| !x.is_finite()) {
            return err(n, format!("vertex '{l}': numbers beyond f32's range, infinite or NaN"));
        }
        m.positions.push(Vec3::new(v[0], v[1], v[2]));
        if has_normals {
            m.normals.push(Vec3::new(v[3], v[4], v[5]));
        }
    }
    for f in 0..nf {
        let Some((n, l)) = lines.next() else {
            return err(0, format!("truncated: {f} of {nf} faces"));
        };
        let mut words = l.split_whitespace();
        let k: usize = words
            .next()
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| OffError { line: n, message: format!("expected a vertex count, found '{l}'") })?;
        // At most one index per two characters of the line, whatever `k` claims.
        let mut face = Vec::with_capacity(k.min(l.len() / 2 + 1));
        for w in words.take(k) {
            match w.parse::<u32>() {
                Ok(i) if (i as usize) < nv => face.push(i),
                _ => return err(n, format!("bad vertex index '{w}' ({nv} vertices)")),
            }
        }
        if face.len() < k {
            return err(n, format!("face says {k} vertices but lists {}", face.len()));
        }
        if k < 3 {
            m.degenerate_faces += 1;
            continue;
        }
        for i in 1..k - 1 {
            m.indices.push([face[0], face[i], face[i + 1]]);
        }
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quads_comments_and_normals() {
        let m = parse_off(b"OFF # a square\n4 2 0\n\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3 255 0 0\n2 0 1\n")
            .unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.degenerate_faces, 1);
        let m = parse_off(b"NOFF 3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n").unwrap();
        assert_eq!(m.normals, vec![Vec3::Z; 3]);
    }

    #[test]
    fn errors_point_at_lines() {
        let e = parse_off(b"OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n").unwrap_err();
        assert_eq!(e.line, 4);
        let e = parse_off(b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n").unwrap_err();
        assert_eq!((e.line, e.message.contains("bad vertex index '7'")), (6, true));
        let e = parse_off(b"OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").unwrap_err();
        assert!(e.message.contains("truncated"), "{e:?}");
        assert!(parse_off(b"PLY\n").unwrap_err().message.contains("not an OFF file"));
        // Counts no file this size could hold, and a face claiming trillions
        // of corners: refused, nothing allocated for them.
        for header in ["OFF\n4000000000 1 0\n", "OFF\n3 1000000000000000000 0\n"] {
            let e = parse_off(format!("{header}0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").as_bytes()).unwrap_err();
            assert!(e.message.contains("more than the file"), "{header}: {}", e.message);
        }
        let e = parse_off(b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4000000000000 0 1 2\n").unwrap_err();
        assert!(e.message.contains("lists 3"), "{}", e.message);
    }
}
