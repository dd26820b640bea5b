//! The tensor files of Mitsuba and pbrt-v4 (`.bsdf`: measured BRDFs): a
//! 12-byte `tensor_file\0` magic, version 1.0, and named n-dimensional
//! arrays, each with a type, a shape and an offset to its little-endian
//! data. Written by hand: the format is a few dozen lines and no crate reads
//! it.

use std::collections::HashMap;

/// The element types a field may have (the format's type codes 1 to 11).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TensorType {
    UInt8,
    Int8,
    UInt16,
    Int16,
    UInt32,
    Int32,
    UInt64,
    Int64,
    Float16,
    Float32,
    Float64,
}

impl TensorType {
    fn from_code(code: u8) -> Option<TensorType> {
        use TensorType::*;
        Some(match code {
            1 => UInt8,
            2 => Int8,
            3 => UInt16,
            4 => Int16,
            5 => UInt32,
            6 => Int32,
            7 => UInt64,
            8 => Int64,
            9 => Float16,
            10 => Float32,
            11 => Float64,
            _ => return None,
        })
    }

    /// Bytes per element.
    pub fn size(self) -> usize {
        use TensorType::*;
        match self {
            UInt8 | Int8 => 1,
            UInt16 | Int16 | Float16 => 2,
            UInt32 | Int32 | Float32 => 4,
            UInt64 | Int64 | Float64 => 8,
        }
    }
}

/// One named array of a tensor file.
#[derive(Clone, Debug, PartialEq)]
pub struct TensorField {
    pub dtype: TensorType,
    /// Size along each dimension, outermost first.
    pub shape: Vec<usize>,
    /// The raw little-endian elements.
    pub bytes: Vec<u8>,
}

impl TensorField {
    /// The elements as f32, for a `Float32` field.
    pub fn f32s(&self) -> Option<Vec<f32>> {
        (self.dtype == TensorType::Float32).then(|| {
            self.bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
        })
    }
}

/// A whole tensor file: its fields by name.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TensorFile {
    pub fields: HashMap<String, TensorField>,
}

/// The magic the format starts with.
const MAGIC: &[u8; 12] = b"tensor_file\0";

impl TensorFile {
    /// Parses a tensor file's bytes; the error says what is wrong.
    pub fn parse(bytes: &[u8]) -> Result<TensorFile, String> {
        let mut at = Reader { bytes, pos: 0 };
        if at.take(12)? != MAGIC {
            return Err("not a tensor file (no \"tensor_file\" header)".into());
        }
        let version = at.take(2)?;
        if version != [1, 0] {
            return Err(format!("tensor file version {}.{}, only 1.0 is known", version[0], version[1]));
        }
        let count = at.u32()?;
        let mut fields = HashMap::new();
        for _ in 0..count {
            let name_len = at.u16()? as usize;
            let name = String::from_utf8_lossy(at.take(name_len)?).into_owned();
            let ndim = at.u16()? as usize;
            let code = at.take(1)?[0];
            let dtype = TensorType::from_code(code)
                .ok_or_else(|| format!("field \"{name}\": unknown element type {code}"))?;
            let offset = at.u64()?;
            let shape = (0..ndim).map(|_| at.u64().map(|s| s as usize)).collect::<Result<Vec<_>, _>>()?;
            let len = shape
                .iter()
                .try_fold(dtype.size(), |n, &s| n.checked_mul(s))
                .ok_or_else(|| format!("field \"{name}\": shape {shape:?} is too large"))?;
            let data = usize::try_from(offset)
                .ok()
                .and_then(|start| Some(start..start.checked_add(len)?))
                .and_then(|range| bytes.get(range))
                .ok_or_else(|| {
                    format!("field \"{name}\": {len} bytes at offset {offset} run past the file's end (truncated?)")
                })?;
            fields.insert(name, TensorField { dtype, shape, bytes: data.to_vec() });
        }
        Ok(TensorFile { fields })
    }

    /// The field `name`, or an error naming it.
    pub fn field(&self, name: &str) -> Result<&TensorField, String> {
        self.fields.get(name).ok_or_else(|| format!("no \"{name}\" field"))
    }

    /// Serialises `fields` (in the given order) as a tensor file: what
    /// tests and generators write.
    pub fn write(fields: &[(&str, TensorType, &[usize], &[u8])]) -> Vec<u8> {
        let mut out = MAGIC.to_vec();
        out.extend_from_slice(&[1, 0]);
        out.extend_from_slice(&(fields.len() as u32).to_le_bytes());
        let header: usize =
            fields.iter().map(|(name, _, shape, _)| 2 + name.len() + 2 + 1 + 8 + 8 * shape.len()).sum();
        let mut offset = out.len() + header;
        for (name, dtype, shape, data) in fields {
            out.extend_from_slice(&(name.len() as u16).to_le_bytes());
            out.extend_from_slice(name.as_bytes());
            out.extend_from_slice(&(shape.len() as u16).to_le_bytes());
            out.push(*dtype as u8 + 1);
            out.extend_from_slice(&(offset as u64).to_le_bytes());
            for &s in *shape {
                out.extend_from_slice(&(s as u64).to_le_bytes());
            }
            offset += data.len();
        }
        for (_, _, _, data) in fields {
            out.extend_from_slice(data);
        }
        out
    }
}

/// A cursor over the header.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end =
            end.ok_or_else(|| format!("the header ends early at byte {} (truncated?)", self.bytes.len()))?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn u16(&mut self) -> Result<u16, String> {
        Ok(u16::from_le_bytes(self.take(2)?.try_into().expect("two bytes")))
    }

    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("four bytes")))
    }

    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("eight bytes")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_errors() {
        let values: Vec<u8> =
            [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0].iter().flat_map(|v| v.to_le_bytes()).collect();
        let bytes = TensorFile::write(&[
            ("a", TensorType::Float32, &[2, 3], &values),
            ("b", TensorType::UInt8, &[1], &[7]),
        ]);
        let file = TensorFile::parse(&bytes).unwrap();
        let a = file.field("a").unwrap();
        assert_eq!(a.shape, vec![2, 3]);
        assert_eq!(a.f32s().unwrap(), vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        assert_eq!(file.field("b").unwrap().bytes, vec![7]);
        assert!(file.field("b").unwrap().f32s().is_none());
        assert!(file.field("c").unwrap_err().contains("no \"c\" field"));

        let truncated = TensorFile::parse(&bytes[..bytes.len() - 3]).unwrap_err();
        assert!(truncated.contains("past the file's end"), "{truncated}");
        assert!(TensorFile::parse(&bytes[..20]).unwrap_err().contains("header ends early"));
        assert!(TensorFile::parse(b"not a tensor file at all").unwrap_err().contains("not a tensor file"));
        let mut wrong_version = bytes.clone();
        wrong_version[12] = 2;
        assert!(TensorFile::parse(&wrong_version).unwrap_err().contains("version 2.0"));
    }
}
