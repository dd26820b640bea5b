//! The fast path for binary PLY bodies, which is how large meshes come:
//! vertex rows (fixed size) decoded in parallel blocks straight into the
//! mesh's arrays, and faces decoded in parallel where every face is a
//! triangle (checked row by row), else in one pass specialised to the
//! layout. It gives the mesh the general reader in the parent module gives;
//! layouts it does not cover (lists besides the face indices, float
//! indices, faces before vertices) and every file with an error go to that
//! reader, whose messages say what is wrong.

use std::sync::atomic::{AtomicBool, Ordering};

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::{Element, Format, Header, PlyMesh, PropKind, Scalar, VertexLayout};

/// Fewest rows one parallel task decodes: a task costs about as much as
/// some thousands of rows.
const MIN_ROWS: usize = 1 << 14;

/// The mesh of a binary body, or `None` where the general reader must
/// decide (an unusual layout, or anything wrong with the file).
pub(super) fn read(header: &Header, body: &[u8]) -> Option<PlyMesh> {
    let big_endian = match header.format {
        Format::Ascii => return None,
        Format::BinaryLe => false,
        Format::BinaryBe => true,
    };
    let mut mesh = PlyMesh::default();
    let (mut vertices, mut faces_seen) = (None, false);
    let mut at = 0usize;
    for e in &header.elements {
        let rest = body.get(at..)?;
        match e.name.as_str() {
            "vertex" if vertices.is_none() && !faces_seen => {
                let rows = FixedRows::new(e, rest, big_endian)?;
                read_vertices(e, &rows, &mut mesh)?;
                vertices = Some(e.count);
                at += rows.bytes();
            }
            "face" if !faces_seen => {
                faces_seen = true;
                let layout = FaceLayout::new(e, big_endian)?;
                at += layout.read(e.count, vertices?, rest, &mut mesh)?;
            }
            "vertex" | "face" => return None,
            _ => at += FixedRows::new(e, rest, big_endian)?.bytes(),
        }
    }
    vertices?;
    Some(mesh)
}

/// Reads scalar `ty` at byte `at` of `b` as the general reader's `f64`
/// would become an `f32` (integers convert exactly either way).
#[inline(always)]
fn scalar_f32(ty: Scalar, b: &[u8], at: usize, be: bool) -> f32 {
    match ty {
        Scalar::I8 => b[at] as i8 as f32,
        Scalar::U8 => b[at] as f32,
        Scalar::I16 => i16::from_le_bytes(bytes(b, at, be)) as f32,
        Scalar::U16 => u16::from_le_bytes(bytes(b, at, be)) as f32,
        Scalar::I32 => i32::from_le_bytes(bytes(b, at, be)) as f32,
        Scalar::U32 => u32::from_le_bytes(bytes(b, at, be)) as f32,
        Scalar::F32 => f32::from_le_bytes(bytes(b, at, be)),
        Scalar::F64 => f64::from_le_bytes(bytes(b, at, be)) as f32,
    }
}

/// Reads integer scalar `ty` at byte `at` of `b`; `None` for float types.
#[inline(always)]
fn scalar_int(ty: Scalar, b: &[u8], at: usize, be: bool) -> Option<i64> {
    Some(match ty {
        Scalar::I8 => b[at] as i8 as i64,
        Scalar::U8 => b[at] as i64,
        Scalar::I16 => i16::from_le_bytes(bytes(b, at, be)) as i64,
        Scalar::U16 => u16::from_le_bytes(bytes(b, at, be)) as i64,
        Scalar::I32 => i32::from_le_bytes(bytes(b, at, be)) as i64,
        Scalar::U32 => u32::from_le_bytes(bytes(b, at, be)) as i64,
        Scalar::F32 | Scalar::F64 => return None,
    })
}

/// The little-endian `f32` at byte `at` of `row`.
#[inline(always)]
fn f32_le(row: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(row[at..at + 4].try_into().expect("4 bytes"))
}

/// The little-endian `u32` at byte `at` of `row`.
#[inline(always)]
fn u32_le(row: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(row[at..at + 4].try_into().expect("4 bytes"))
}

/// `N` bytes at `at`, in little-endian order.
#[inline(always)]
fn bytes<const N: usize>(b: &[u8], at: usize, be: bool) -> [u8; N] {
    let mut a: [u8; N] = b[at..at + N].try_into().expect("N bytes");
    if be {
        a.reverse();
    }
    a
}

/// An element whose rows are all scalars: every row has the same size.
struct FixedRows<'a> {
    rows: &'a [u8],
    row_size: usize,
    /// Each property's type and offset in the row.
    props: Vec<(Scalar, usize)>,
    big_endian: bool,
}

impl<'a> FixedRows<'a> {
    /// `None` when a property is a list or the rows pass the end of `body`.
    fn new(e: &Element, body: &'a [u8], big_endian: bool) -> Option<Self> {
        let mut props = Vec::with_capacity(e.props.len());
        let mut row_size = 0;
        for p in &e.props {
            let PropKind::Scalar(ty) = p.kind else { return None };
            props.push((ty, row_size));
            row_size += ty.size();
        }
        let bytes = e.count.checked_mul(row_size)?;
        Some(FixedRows { rows: body.get(..bytes)?, row_size, props, big_endian })
    }

    fn bytes(&self) -> usize {
        self.rows.len()
    }

    /// The offsets of properties `ks` where each is a little-endian `f32`:
    /// the layout of nearly every mesh, decoded without a type per value.
    fn f32_le_offsets<const N: usize>(&self, ks: [usize; N]) -> Option<[usize; N]> {
        let all = !self.big_endian && ks.iter().all(|&k| self.props[k].0 == Scalar::F32);
        all.then(|| ks.map(|k| self.props[k].1))
    }

    /// A reader of property `k` of row `i` as an `f32`.
    fn column(&self, k: usize) -> impl Fn(usize) -> f32 + Sync + '_ {
        let (ty, offset) = self.props[k];
        move |i| scalar_f32(ty, self.rows, i * self.row_size + offset, self.big_endian)
    }
}

fn read_vertices(e: &Element, rows: &FixedRows, mesh: &mut PlyMesh) -> Option<()> {
    let layout = VertexLayout::new(e);
    let column = |k: Option<usize>| k.map(|k| rows.column(k));
    let vec3 = |ks: [Option<usize>; 3]| -> Option<Vec<Vec3>> {
        let ks = [ks[0]?, ks[1]?, ks[2]?];
        if let Some([x, y, z]) = rows.f32_le_offsets(ks) {
            return Some(
                rows.rows
                    .par_chunks_exact(rows.row_size)
                    .with_min_len(MIN_ROWS)
                    .map(|row| Vec3::new(f32_le(row, x), f32_le(row, y), f32_le(row, z)))
                    .collect(),
            );
        }
        let [x, y, z] = ks.map(|k| rows.column(k));
        Some(
            (0..e.count)
                .into_par_iter()
                .with_min_len(MIN_ROWS)
                .map(|i| Vec3::new(x(i), y(i), z(i)))
                .collect(),
        )
    };
    mesh.positions = vec3(layout.pos)?;
    mesh.normals = vec3(layout.normal).unwrap_or_default();
    if let [Some(u), Some(v)] = layout.uv.map(column) {
        mesh.uvs =
            (0..e.count).into_par_iter().with_min_len(MIN_ROWS).map(|i| Vec2::new(u(i), v(i))).collect();
    }
    Some(())
}

/// Where a face row's vertex index list is: scalars before and after it
/// (skipped), the list's count and item types.
struct FaceLayout {
    before: usize,
    after: usize,
    count: Scalar,
    item: Scalar,
    big_endian: bool,
}

impl FaceLayout {
    /// `None` unless the row is scalars around one integer index list.
    fn new(e: &Element, big_endian: bool) -> Option<Self> {
        let (mut before, mut after, mut list) = (0, 0, None);
        for p in &e.props {
            match p.kind {
                PropKind::List { count, item }
                    if list.is_none() && (p.name == "vertex_indices" || p.name == "vertex_index") =>
                {
                    list = Some((count, item))
                }
                PropKind::List { .. } => return None,
                PropKind::Scalar(ty) if list.is_none() => before += ty.size(),
                PropKind::Scalar(ty) => after += ty.size(),
            }
        }
        let (count, item) = list?;
        if matches!(count, Scalar::F32 | Scalar::F64) || matches!(item, Scalar::F32 | Scalar::F64) {
            return None;
        }
        Some(FaceLayout { before, after, count, item, big_endian })
    }

    /// Reads `faces` rows from the start of `body` into `mesh.indices`;
    /// the bytes they took, or `None` for anything the general reader
    /// should look at (an index out of range, a short body).
    fn read(&self, faces: usize, vertices: usize, body: &[u8], mesh: &mut PlyMesh) -> Option<usize> {
        if let Some((indices, bytes)) = self.triangles(faces, vertices, body) {
            mesh.indices = indices;
            return Some(bytes);
        }
        self.any_faces(faces, vertices, body, mesh)
    }

    /// In parallel, if every face is a triangle: rows are then all
    /// `triangle_row` bytes, which each row's count confirms.
    fn triangles(&self, faces: usize, vertices: usize, body: &[u8]) -> Option<(Vec<[u32; 3]>, usize)> {
        let row = self.before + self.count.size() + 3 * self.item.size() + self.after;
        let bytes = faces.checked_mul(row)?;
        let rows = body.get(..bytes)?;
        let (be, item) = (self.big_endian, self.item.size());
        // An indexed collect writes straight into the vector (collecting
        // `Option`s would gather pieces and copy them); a row that breaks
        // the assumption raises the flag instead.
        let broken = AtomicBool::new(false);
        if let Some(limit) = self.u8_count_32_bit_items(vertices) {
            // The layout of nearly every mesh, without a type per value.
            let at = self.before + 1;
            let indices = rows
                .par_chunks_exact(row)
                .with_min_len(MIN_ROWS)
                .map(|r| {
                    let t = [u32_le(r, at), u32_le(r, at + 4), u32_le(r, at + 8)];
                    if r[self.before] != 3 || t.iter().any(|&v| u64::from(v) >= limit) {
                        broken.store(true, Ordering::Relaxed);
                    }
                    t
                })
                .collect();
            return (!broken.into_inner()).then_some((indices, bytes));
        }
        let indices: Vec<[u32; 3]> = (0..faces)
            .into_par_iter()
            .with_min_len(MIN_ROWS)
            .map(|f| {
                let at = f * row + self.before;
                let index = |k: usize| {
                    let v = scalar_int(self.item, rows, at + self.count.size() + k * item, be)?;
                    (0..vertices as i64).contains(&v).then_some(v as u32)
                };
                let triangle = match scalar_int(self.count, rows, at, be) {
                    Some(3) => index(0).zip(index(1)).zip(index(2)).map(|((a, b), c)| [a, b, c]),
                    _ => None,
                };
                triangle.unwrap_or_else(|| {
                    broken.store(true, Ordering::Relaxed);
                    [0; 3]
                })
            })
            .collect();
        if broken.into_inner() {
            return None;
        }
        Some((indices, bytes))
    }

    /// For little-endian rows with a `u8` count and 32-bit indices, the
    /// bound every index must be below: the vertex count, and for signed
    /// indices read as unsigned, 2^31 (negatives come out above it).
    fn u8_count_32_bit_items(&self, vertices: usize) -> Option<u64> {
        let type_limit = match self.item {
            Scalar::U32 => 1u64 << 32,
            Scalar::I32 => 1u64 << 31,
            _ => return None,
        };
        (!self.big_endian && self.count == Scalar::U8).then(|| type_limit.min(vertices as u64))
    }

    /// One pass over rows of any length: triangles, quads split in two,
    /// other faces skipped and counted (as the general reader does).
    fn any_faces(&self, faces: usize, vertices: usize, body: &[u8], mesh: &mut PlyMesh) -> Option<usize> {
        let be = self.big_endian;
        let (count_size, item_size) = (self.count.size(), self.item.size());
        // Every row takes at least its count: the body bounds the allocation.
        mesh.indices = Vec::with_capacity(faces.min(body.len() / count_size.max(1)));
        let mut at = 0usize;
        let mut face = [0u32; 4];
        for _ in 0..faces {
            at += self.before;
            let n = usize::try_from(scalar_int(self.count, body.get(..at + count_size)?, at, be)?).ok()?;
            at += count_size;
            let items = body.get(at..at.checked_add(n.checked_mul(item_size)?)?)?;
            for (k, item) in items.chunks_exact(item_size).enumerate() {
                let v = scalar_int(self.item, item, 0, be)?;
                if !(0..vertices as i64).contains(&v) {
                    return None;
                }
                if let Some(slot) = face.get_mut(k) {
                    *slot = v as u32;
                }
            }
            match n {
                3 => mesh.indices.push([face[0], face[1], face[2]]),
                4 => mesh.indices.extend([[face[0], face[1], face[2]], [face[0], face[2], face[3]]]),
                _ => mesh.skipped_faces += 1,
            }
            at += items.len() + self.after;
        }
        (at <= body.len()).then_some(at)
    }
}
