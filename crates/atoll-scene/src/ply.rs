//! A PLY reader for triangle meshes: ASCII and binary (little or big endian),
//! optionally gzip-compressed (`.ply.gz`, recognised by its magic bytes).
//!
//! Reads vertex positions `x y z`, optional normals `nx ny nz` and texture
//! coordinates (`u v`, `s t`, `texture_u texture_v` or `texture_s texture_t`),
//! and faces from the list property `vertex_indices` (or `vertex_index`).
//! Quads are split into two triangles; other properties and elements are
//! skipped. Faces with other vertex counts are skipped and counted (pbrt-v4
//! ignores them too).

mod fast;

use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

/// The triangle mesh in a PLY file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlyMesh {
    pub positions: Vec<Vec3>,
    /// Per-vertex normals; empty when the file has none.
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates; empty when the file has none.
    pub uvs: Vec<Vec2>,
    pub indices: Vec<[u32; 3]>,
    /// Faces that were neither triangles nor quads, and so were skipped.
    pub skipped_faces: usize,
}

/// Why a PLY file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum PlyError {
    #[error("cannot read '{}': {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    /// The file is not a valid PLY mesh; the message says where and why.
    #[error("{0}")]
    Invalid(String),
}

fn invalid<T>(msg: impl Into<String>) -> Result<T, PlyError> {
    Err(PlyError::Invalid(msg.into()))
}

/// Reads a PLY (or gzip-compressed PLY) file.
pub fn read_ply(path: &Path) -> Result<PlyMesh, PlyError> {
    thread_local! {
        /// The bytes of the last file this thread read, whose memory the
        /// next read reuses (scenes read hundreds of mesh files).
        static BYTES: std::cell::RefCell<Vec<u8>> = const { std::cell::RefCell::new(Vec::new()) };
    }
    /// Larger buffers are not kept: one huge file must not hold its
    /// memory for good.
    const KEPT_BYTES: usize = 1 << 30;
    let mut bytes = BYTES.with(|b| std::mem::take(&mut *b.borrow_mut()));
    let read = crate::input::read_into(path, &mut bytes);
    let mesh = read
        .map_err(|source| PlyError::Io { path: path.to_path_buf(), source })
        .and_then(|()| parse_ply(&bytes));
    if bytes.capacity() <= KEPT_BYTES {
        BYTES.with(|b| *b.borrow_mut() = bytes);
    }
    mesh
}

/// What a PLY file's header says of its mesh, for estimates made before
/// the file is read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PlySizes {
    pub vertices: u64,
    /// Faces (each at least one triangle).
    pub faces: u64,
    pub normals: bool,
    pub uvs: bool,
}

/// The sizes in `path`'s header (gzip-compressed or not), read from its
/// first bytes; `None` when they cannot be had (a file that is missing, not
/// regular, or not PLY): reading the whole file then says why.
pub fn peek_sizes(path: &Path) -> Option<PlySizes> {
    use std::io::Read;
    /// Headers are a few hundred bytes; one this long is not believed.
    const MOST: u64 = 64 << 10;
    let meta = std::fs::metadata(path).ok()?;
    if !meta.is_file() {
        return None;
    }
    use std::io::Seek;
    let mut file = std::fs::File::open(path).ok()?;
    let mut start = Vec::new();
    let mut magic = [0u8; 2];
    let gz = file.read_exact(&mut magic).is_ok() && magic == [0x1f, 0x8b];
    file.rewind().ok()?;
    if gz {
        flate2::read::GzDecoder::new(file).take(MOST).read_to_end(&mut start).ok()?;
    } else {
        file.take(MOST).read_to_end(&mut start).ok()?;
    }
    let header = parse_header(&start).ok()?;
    // Counts are believed only where the file could hold them (gzip data
    // inflates at most so much): a header claiming billions of rows in a
    // small file is for the full read to refuse, as bad input.
    let most = if gz { meta.len().saturating_mul(crate::input::MAX_INFLATION) } else { meta.len() };
    check_counts(&header, usize::try_from(most).unwrap_or(usize::MAX)).ok()?;
    let vertex = header.elements.iter().find(|e| e.name == "vertex")?;
    let layout = VertexLayout::new(vertex);
    let faces = header.elements.iter().find(|e| e.name == "face").map_or(0, |e| e.count);
    Some(PlySizes {
        vertices: vertex.count as u64,
        faces: faces as u64,
        normals: layout.normal.iter().all(Option::is_some),
        uvs: layout.uv.iter().all(Option::is_some),
    })
}

/// Parses the bytes of a PLY file (gzip-compressed or not).
pub fn parse_ply(bytes: &[u8]) -> Result<PlyMesh, PlyError> {
    if bytes.starts_with(&[0x1f, 0x8b]) {
        let out =
            crate::input::gunzip(bytes).map_err(|e| PlyError::Invalid(format!("bad gzip data: {e}")))?;
        return parse_uncompressed(&out);
    }
    parse_uncompressed(bytes)
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Ascii,
    BinaryLe,
    BinaryBe,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

#[derive(Clone, Debug)]
enum PropKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    kind: PropKind,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

struct Header {
    format: Format,
    elements: Vec<Element>,
    body_start: usize,
}

fn parse_header(bytes: &[u8]) -> Result<Header, PlyError> {
    if !bytes.starts_with(b"ply") {
        return invalid("not a PLY file (it does not start with 'ply')");
    }
    let mut pos = 0;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    for line_no in 1.. {
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return invalid("truncated header: no 'end_header' line");
        };
        let line = String::from_utf8_lossy(&bytes[pos..pos + len]).trim_end_matches('\r').to_string();
        pos += len + 1;
        let words: Vec<&str> = line.split_whitespace().collect();
        let bad = |what: &str| invalid(format!("header line {line_no}: {what}: '{line}'"));
        match words.as_slice() {
            ["ply"] if line_no == 1 => {}
            ["end_header"] => break,
            ["comment", ..] | ["obj_info", ..] | [] => {}
            ["format", f, _version] => {
                format = Some(match *f {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::BinaryLe,
                    "binary_big_endian" => Format::BinaryBe,
                    _ => return bad("unknown format"),
                });
            }
            ["element", name, count] => {
                let Ok(count) = count.parse::<usize>() else { return bad("bad element count") };
                elements.push(Element { name: name.to_string(), count, props: Vec::new() });
            }
            ["property", "list", count, item, name] => {
                let (Some(count), Some(item)) = (Scalar::parse(count), Scalar::parse(item)) else {
                    return bad("unknown list property type");
                };
                let Some(e) = elements.last_mut() else { return bad("property before any element") };
                e.props.push(Property { name: name.to_string(), kind: PropKind::List { count, item } });
            }
            ["property", ty, name] => {
                let Some(ty) = Scalar::parse(ty) else { return bad("unknown property type") };
                let Some(e) = elements.last_mut() else { return bad("property before any element") };
                e.props.push(Property { name: name.to_string(), kind: PropKind::Scalar(ty) });
            }
            _ => return bad("cannot parse"),
        }
    }
    let Some(format) = format else { return invalid("header has no 'format' line") };
    Ok(Header { format, elements, body_start: pos })
}

/// Why the next value of a body could not be read.
#[derive(Debug, thiserror::Error)]
enum ValueError {
    #[error("unexpected end of file at byte {0}")]
    EndAt(usize),
    #[error("unexpected end of file")]
    End,
    #[error("bad number '{0}'")]
    BadNumber(String),
}

/// Reads scalar values from the body in file order.
trait Values {
    fn next(&mut self, ty: Scalar) -> Result<f64, ValueError>;
}

struct Binary<'a> {
    bytes: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl Values for Binary<'_> {
    fn next(&mut self, ty: Scalar) -> Result<f64, ValueError> {
        let n = ty.size();
        let Some(src) = self.bytes.get(self.pos..self.pos + n) else {
            return Err(ValueError::EndAt(self.bytes.len()));
        };
        self.pos += n;
        let mut b = [0u8; 8];
        b[..n].copy_from_slice(src);
        if self.big_endian {
            b[..n].reverse();
        }
        Ok(match ty {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Scalar::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Scalar::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Scalar::F64 => f64::from_le_bytes(b),
        })
    }
}

struct Ascii<'a> {
    words: std::str::SplitAsciiWhitespace<'a>,
}

impl Values for Ascii<'_> {
    fn next(&mut self, _ty: Scalar) -> Result<f64, ValueError> {
        let w = self.words.next().ok_or(ValueError::End)?;
        w.parse::<f64>().map_err(|_| ValueError::BadNumber(w.to_string()))
    }
}

/// Where each vertex attribute is among an element's properties.
#[derive(Default)]
struct VertexLayout {
    pos: [Option<usize>; 3],
    normal: [Option<usize>; 3],
    uv: [Option<usize>; 2],
}

impl VertexLayout {
    fn new(e: &Element) -> Self {
        let find = |names: &[&str]| {
            e.props
                .iter()
                .position(|p| names.contains(&p.name.as_str()) && matches!(p.kind, PropKind::Scalar(_)))
        };
        VertexLayout {
            pos: [find(&["x"]), find(&["y"]), find(&["z"])],
            normal: [find(&["nx"]), find(&["ny"]), find(&["nz"])],
            uv: [find(&["u", "s", "texture_u", "texture_s"]), find(&["v", "t", "texture_v", "texture_t"])],
        }
    }
}

fn parse_uncompressed(bytes: &[u8]) -> Result<PlyMesh, PlyError> {
    let header = parse_header(bytes)?;
    let body = &bytes[header.body_start..];
    match header.format {
        Format::Ascii => {
            let text = String::from_utf8_lossy(body);
            read_body(&header, &mut Ascii { words: text.split_ascii_whitespace() }, body.len())
        }
        f => match fast::read(&header, body) {
            Some(mesh) => Ok(mesh),
            None => read_body(
                &header,
                &mut Binary { bytes: body, pos: 0, big_endian: f == Format::BinaryBe },
                body.len(),
            ),
        },
    }
}

/// Refuses element counts the body cannot hold: every row takes at least
/// its scalars' bytes (and a list's length) in binary, and one character a
/// property in ASCII. Counts of 10^18 are refused before anything is read;
/// an element without properties takes no bytes, and is not read at all.
fn check_counts(header: &Header, body_len: usize) -> Result<(), PlyError> {
    let mut least = 0u64;
    for e in &header.elements {
        let row: u64 = match header.format {
            Format::Ascii => e.props.len() as u64,
            _ => e
                .props
                .iter()
                .map(|p| match p.kind {
                    PropKind::Scalar(ty) | PropKind::List { count: ty, .. } => ty.size() as u64,
                })
                .sum(),
        };
        least = least.saturating_add((e.count as u64).saturating_mul(row));
        if least > body_len as u64 {
            return invalid(format!(
                "element '{}' claims {} rows, more than the file's {body_len} bytes of data can hold (truncated?)",
                e.name, e.count
            ));
        }
    }
    Ok(())
}

fn read_body(header: &Header, src: &mut dyn Values, body_len: usize) -> Result<PlyMesh, PlyError> {
    check_counts(header, body_len)?;
    let mut mesh = PlyMesh::default();
    // Face index lists, flattened: (start, len) into `face_items`.
    let mut faces: Vec<(usize, usize)> = Vec::new();
    let mut face_items: Vec<i64> = Vec::new();
    let mut vertex_count = None;
    let mut row = Vec::new();
    for e in &header.elements {
        let is_vertex = e.name == "vertex";
        let is_face = e.name == "face";
        let layout = VertexLayout::new(e);
        if is_vertex {
            if layout.pos.iter().any(Option::is_none) {
                return invalid("element 'vertex' lacks one of the properties x, y, z");
            }
            vertex_count = Some(e.count);
            // Never trust a header count for an allocation: every property
            // takes at least one byte, so the file bounds the real count.
            let cap = e.count.min(body_len / e.props.len().max(1));
            mesh.positions.reserve(cap);
            if layout.normal.iter().all(Option::is_some) {
                mesh.normals.reserve(cap);
            }
            if layout.uv.iter().all(Option::is_some) {
                mesh.uvs.reserve(cap);
            }
        }
        let index_prop = e.props.iter().position(|p| {
            matches!(p.kind, PropKind::List { .. })
                && (p.name == "vertex_indices" || p.name == "vertex_index")
        });
        if is_face && index_prop.is_none() {
            return invalid("element 'face' has no list property 'vertex_indices'");
        }
        // Rows of an element without properties hold nothing: a count of
        // billions would only spin here.
        let rows = if e.props.is_empty() { 0 } else { e.count };
        for i in 0..rows {
            let at = |m: &dyn std::fmt::Display| {
                PlyError::Invalid(format!("element '{}' {i} of {}: {m}", e.name, e.count))
            };
            row.clear();
            for (pi, p) in e.props.iter().enumerate() {
                match p.kind {
                    PropKind::Scalar(ty) => row.push(src.next(ty).map_err(|err| at(&err))?),
                    PropKind::List { count, item } => {
                        let n = src.next(count).map_err(|err| at(&err))?;
                        if n < 0.0 || n.fract() != 0.0 {
                            return Err(at(&format_args!("bad list length {n}")));
                        }
                        let keep = is_face && Some(pi) == index_prop;
                        let start = face_items.len();
                        for _ in 0..n as usize {
                            let v = src.next(item).map_err(|err| at(&err))?;
                            if keep {
                                // A fraction (or NaN) would be cut to some other vertex.
                                if v.fract() != 0.0 {
                                    return Err(at(&format_args!("vertex index {v} is not an integer")));
                                }
                                face_items.push(v as i64);
                            }
                        }
                        if keep {
                            faces.push((start, n as usize));
                        }
                        row.push(f64::NAN);
                    }
                }
            }
            if is_vertex {
                let get = |k: Option<usize>| row[k.unwrap()] as f32;
                mesh.positions.push(Vec3::new(get(layout.pos[0]), get(layout.pos[1]), get(layout.pos[2])));
                if layout.normal.iter().all(Option::is_some) {
                    mesh.normals.push(Vec3::new(
                        get(layout.normal[0]),
                        get(layout.normal[1]),
                        get(layout.normal[2]),
                    ));
                }
                if layout.uv.iter().all(Option::is_some) {
                    mesh.uvs.push(Vec2::new(get(layout.uv[0]), get(layout.uv[1])));
                }
            }
        }
    }
    let Some(nv) = vertex_count else { return invalid("no 'vertex' element") };
    mesh.indices.reserve(faces.len());
    for (f, &(start, len)) in faces.iter().enumerate() {
        let face = &face_items[start..start + len];
        if let Some(&bad) = face.iter().find(|&&v| v < 0 || v as usize >= nv) {
            return invalid(format!("face {f} uses vertex index {bad}, out of range for {nv} vertices"));
        }
        let v = |k: usize| face[k] as u32;
        match face.len() {
            3 => mesh.indices.push([v(0), v(1), v(2)]),
            4 => {
                mesh.indices.push([v(0), v(1), v(2)]);
                mesh.indices.push([v(0), v(2), v(3)]);
            }
            _ => mesh.skipped_faces += 1,
        }
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn binary(big_endian: bool) -> Vec<u8> {
        let fmt = if big_endian { "binary_big_endian" } else { "binary_little_endian" };
        let mut b = format!(
            "ply\nformat {fmt} 1.0\ncomment test\nelement vertex 4\nproperty float x\nproperty float y\n\
             property float z\nproperty double u\nproperty double v\nelement face 1\n\
             property list uchar uint vertex_indices\nproperty int face_indices\nend_header\n"
        )
        .into_bytes();
        let f32b = |x: f32| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() };
        let f64b = |x: f64| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() };
        for (p, uv) in [
            ([0.0, 0.0, 0.0], [0.0, 0.0]),
            ([1.0, 0.0, 0.0], [1.0, 0.0]),
            ([1.0, 1.0, 0.0], [1.0, 1.0]),
            ([0.0, 1.0, 0.0], [0.0, 1.0]),
        ] {
            p.iter().for_each(|&x| b.extend(f32b(x)));
            uv.iter().for_each(|&x| b.extend(f64b(x)));
        }
        b.push(4);
        for i in [0u32, 1, 2, 3] {
            b.extend(if big_endian { i.to_be_bytes() } else { i.to_le_bytes() });
        }
        b.extend(if big_endian { 7i32.to_be_bytes() } else { 7i32.to_le_bytes() });
        b
    }

    #[test]
    fn binary_both_endians_with_quads_and_extra_properties() {
        for be in [false, true] {
            let m = parse_ply(&binary(be)).unwrap();
            assert_eq!(m.positions[2], Vec3::new(1.0, 1.0, 0.0));
            assert_eq!(m.uvs[3], Vec2::new(0.0, 1.0));
            assert!(m.normals.is_empty());
            assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3]]);
        }
    }

    #[test]
    fn ascii_with_normals_and_crlf() {
        let text = "ply\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty float x\r\nproperty float y\r\n\
                    property float z\r\nproperty float nx\r\nproperty float ny\r\nproperty float nz\r\n\
                    element edge 1\r\nproperty int a\r\nproperty int b\r\n\
                    element face 2\r\nproperty list uchar int vertex_index\r\nend_header\r\n\
                    0 0 0 0 0 1\r\n1 0 0 0 0 1\r\n0 1 -2.5e-1 0 0 1\r\n0 1\r\n3 0 1 2\r\n2 0 1\r\n";
        let m = parse_ply(text.as_bytes()).unwrap();
        assert_eq!(m.positions[2], Vec3::new(0.0, 1.0, -0.25));
        assert_eq!(m.normals, vec![Vec3::Z; 3]);
        assert_eq!(m.indices, vec![[0, 1, 2]]);
        assert_eq!(m.skipped_faces, 1);
    }

    #[test]
    fn errors() {
        let mut truncated = binary(false);
        truncated.truncate(truncated.len() - 6);
        let e = parse_ply(&truncated).unwrap_err().to_string();
        assert!(e.contains("unexpected end of file") && e.contains("'face'"), "{e}");
        let mut bad_index = binary(false);
        let n = bad_index.len();
        bad_index[n - 8..n - 4].copy_from_slice(&9u32.to_le_bytes());
        let e = parse_ply(&bad_index).unwrap_err().to_string();
        assert!(e.contains("out of range"), "{e}");
        assert!(parse_ply(b"PLY\n").is_err());
        assert!(parse_ply(b"ply\nformat ascii 1.0\nelement vertex 1\n")
            .unwrap_err()
            .to_string()
            .contains("end_header"));
        let e = read_ply(Path::new("/nonexistent/x.ply")).unwrap_err();
        assert!(matches!(e, PlyError::Io { .. }));
    }

    #[test]
    fn elements_without_properties_and_fractional_indices() {
        // Nothing to read per row: an enormous count must not spin.
        let header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                      property float z\nelement nothing 18446744073709551615\nelement face 1\n\
                      property list uchar float vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
        let m = parse_ply(format!("{header}3 0 1 2\n").as_bytes()).unwrap();
        assert_eq!(m.indices, vec![[0, 1, 2]]);
        for bad in ["3 0 1 1.5\n", "3 0 nan 2\n"] {
            let e = parse_ply(format!("{header}{bad}").as_bytes()).unwrap_err().to_string();
            assert!(e.contains("is not an integer") && e.contains("'face' 0"), "{e}");
        }
    }

    /// A binary PLY of `quads` quads in a strip, with normals as doubles,
    /// an extra vertex property, and faces as triangles, quads or
    /// pentagons by `shape` (0, 1, 2 cycling).
    fn strip(big_endian: bool, quads: u32, mixed: bool, index: &str) -> Vec<u8> {
        let fmt = if big_endian { "binary_big_endian" } else { "binary_little_endian" };
        let vertices = 2 * (quads + 1);
        let faces = if mixed { quads } else { 2 * quads };
        let mut b = format!(
            "ply\nformat {fmt} 1.0\nelement vertex {vertices}\nproperty float x\nproperty short quality\n\
             property float y\nproperty float z\nproperty double nx\nproperty double ny\nproperty double nz\n\
             element face {faces}\nproperty uchar flags\nproperty list uchar {index} vertex_indices\n\
             property float area\nend_header\n"
        )
        .into_bytes();
        let put = |b: &mut Vec<u8>, le: &[u8]| {
            let mut v = le.to_vec();
            if big_endian {
                v.reverse();
            }
            b.extend(v);
        };
        for i in 0..=quads {
            for y in 0..2 {
                put(&mut b, &(i as f32 * 0.5).to_le_bytes());
                put(&mut b, &(-7i16).to_le_bytes());
                put(&mut b, &(y as f32).to_le_bytes());
                put(&mut b, &(0.1f32 * i as f32).to_le_bytes());
                for n in [0.0f64, 0.6, 0.8] {
                    put(&mut b, &n.to_le_bytes());
                }
            }
        }
        let idx = |b: &mut Vec<u8>, v: u32| match index {
            "ushort" => put(b, &(v as u16).to_le_bytes()),
            _ => put(b, &v.to_le_bytes()),
        };
        for q in 0..quads {
            let a = 2 * q;
            let face = |b: &mut Vec<u8>, vs: &[u32]| {
                b.push(1);
                b.push(vs.len() as u8);
                vs.iter().for_each(|&v| idx(b, v));
                put(b, &1.5f32.to_le_bytes());
            };
            if !mixed {
                face(&mut b, &[a, a + 2, a + 1]);
                face(&mut b, &[a + 1, a + 2, a + 3]);
            } else {
                match q % 3 {
                    0 => face(&mut b, &[a, a + 2, a + 1]),
                    1 => face(&mut b, &[a, a + 2, a + 3, a + 1]),
                    _ => face(&mut b, &[a, a + 2, a + 3, a + 1, a]),
                }
            }
        }
        b
    }

    /// The general reader alone, as the fast path must match it.
    fn general(bytes: &[u8]) -> Result<PlyMesh, PlyError> {
        let header = parse_header(bytes)?;
        let body = &bytes[header.body_start..];
        let big_endian = header.format == Format::BinaryBe;
        read_body(&header, &mut Binary { bytes: body, pos: 0, big_endian }, body.len())
    }

    #[test]
    fn the_fast_binary_path_gives_the_general_readers_mesh() {
        for be in [false, true] {
            for mixed in [false, true] {
                for index in ["uint", "int", "ushort"] {
                    for quads in [1, 5, 40_000] {
                        let bytes = strip(be, quads, mixed, index);
                        let header = parse_header(&bytes).unwrap();
                        let fast = fast::read(&header, &bytes[header.body_start..]).expect("fast path");
                        let general = general(&bytes).unwrap();
                        assert_eq!(fast, general, "be {be}, mixed {mixed}, {index}, {quads} quads");
                        assert!(fast.normals.len() == fast.positions.len() && fast.uvs.is_empty());
                        if mixed {
                            assert_eq!(fast.skipped_faces, quads as usize / 3);
                        } else {
                            assert_eq!(fast.indices.len(), 2 * quads as usize);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn the_fast_binary_path_leaves_errors_to_the_general_reader() {
        let good = strip(false, 100, false, "uint");
        let header = parse_header(&good).unwrap();
        let body = header.body_start;
        // An index out of range (the last face's last index), a short body.
        let mut bad_index = good.clone();
        let n = bad_index.len();
        bad_index[n - 8..n - 4].copy_from_slice(&999u32.to_le_bytes());
        let truncated = &good[..good.len() - 3];
        for bad in [&bad_index[..], truncated] {
            assert!(fast::read(&header, &bad[body..]).is_none());
            let e = parse_ply(bad).unwrap_err().to_string();
            assert_eq!(e, general(bad).unwrap_err().to_string());
        }
        assert!(parse_ply(&bad_index).unwrap_err().to_string().contains("out of range"));
        // A negative signed index, which read unsigned is merely large.
        let mut negative = strip(false, 100, false, "int");
        let n = negative.len();
        negative[n - 8..n - 4].copy_from_slice(&(-1i32).to_le_bytes());
        let signed = parse_header(&negative).unwrap();
        assert!(fast::read(&signed, &negative[signed.body_start..]).is_none());
        assert_eq!(
            parse_ply(&negative).unwrap_err().to_string(),
            general(&negative).unwrap_err().to_string()
        );
    }

    #[test]
    fn sizes_come_from_the_header_alone() {
        use std::io::Write;
        let dir = std::env::temp_dir().join(format!("atoll-ply-peek-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let bytes = strip(false, 1000, false, "uint");
        let (plain, gz) = (dir.join("a.ply"), dir.join("a.ply.gz"));
        std::fs::write(&plain, &bytes).unwrap();
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        e.write_all(&bytes).unwrap();
        std::fs::write(&gz, e.finish().unwrap()).unwrap();
        let want = PlySizes { vertices: 2002, faces: 2000, normals: true, uvs: false };
        assert_eq!(peek_sizes(&plain), Some(want));
        assert_eq!(peek_sizes(&gz), Some(want));
        assert_eq!(peek_sizes(&dir.join("missing.ply")), None);
        assert_eq!(peek_sizes(&dir), None);
        // More rows than the file could hold: not believed.
        std::fs::write(&plain, &bytes[..bytes.len() / 2]).unwrap();
        assert_eq!(peek_sizes(&plain), None);
        let text = String::from_utf8_lossy(&bytes[..200])
            .replace("element vertex 2002", "element vertex 4000000000");
        std::fs::write(&plain, text.as_bytes()).unwrap();
        assert_eq!(peek_sizes(&plain), None);
        std::fs::write(&plain, b"not a ply").unwrap();
        assert_eq!(peek_sizes(&plain), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn gzip() {
        use std::io::Write;
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        gz.write_all(&binary(false)).unwrap();
        let m = parse_ply(&gz.finish().unwrap()).unwrap();
        assert_eq!(m.indices.len(), 2);
    }
}
