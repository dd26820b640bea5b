//! Property tests: random mutations of valid scene files never make a
//! loader panic, and every error names one of the files it was given, at a
//! line that file has.
//!
//! Each property starts from small valid files (a PBRT scene with an
//! `Include` and a PLY mesh; ASCII and binary PLY of both byte orders; OFF;
//! OBJ with its MTL; glTF with its buffer, and GLB) and applies a few
//! mutations: bit flips, insertions of tokens that break parsers (`1e400`,
//! `-0`, `4294967296`, `nan`, quotes, brackets, ...), numbers replaced by
//! such values, deletions, truncations, duplicated spans, swapped lines and
//! 32-bit values written over binary data. A panic anywhere, even one a
//! loader catches itself, fails the property.
//!
//! The runs are deterministic (a fixed seed, so CI does not turn red at
//! random); `PROPTEST_RNG_SEED=<n>` explores other mutations and
//! `PROPTEST_CASES=<n>` runs more of them. Failures are not persisted to
//! files: each one found becomes a plain unit test beside the code it
//! fixed, with its minimal input.

mod common;

use std::cell::Cell;
use std::path::{Path, PathBuf};
use std::sync::Once;

use atoll_scene::load_any;
use atoll_scene::pbrt::parser::Parser;
use atoll_scene::pbrt::tokenizer::{TokenKind, Tokenizer};
use common::{gltf_bin, temp_dir};
use proptest::prelude::*;
use proptest::sample::Index;
use proptest::test_runner::{RngSeed, TestCaseError};

/// Cases per property, unless `PROPTEST_CASES` says otherwise: the whole
/// suite stays well under a minute in a debug build on two cores.
const CASES: u32 = 2048;

fn config() -> ProptestConfig {
    let defaults = ProptestConfig::default();
    let cases = std::env::var("PROPTEST_CASES").ok().and_then(|c| c.parse().ok()).unwrap_or(CASES);
    let rng_seed = match std::env::var_os("PROPTEST_RNG_SEED") {
        Some(_) => defaults.rng_seed,
        None => RngSeed::Fixed(0x5eed_a7011),
    };
    ProptestConfig { cases, rng_seed, failure_persistence: None, ..defaults }
}

// ---------------------------------------------------------------------------
// Mutations

/// Values that break number parsing, range checks and index arithmetic.
const NUMBERS: &[&str] = &[
    "1e400",
    "-1e400",
    "1e-400",
    "-0",
    "0",
    "-1",
    "1",
    "2",
    "3",
    "8",
    "16",
    "255",
    "256",
    "65535",
    "65536",
    "1000",
    "1e9",
    "2147483647",
    "2147483648",
    "-2147483648",
    "-2147483649",
    "4294967295",
    "4294967296",
    "9007199254740993",
    "18446744073709551616",
    "99999999999999999999999",
    "3.5e38",
    "1e38",
    "0.5",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "infinity",
    "0x10",
    "1.2.3",
    "--1",
];

/// Text that breaks tokenizers and line structure.
const TOKENS: &[&str] = &[
    "\"",
    "[",
    "]",
    "{",
    "}",
    "#",
    "\n",
    "\r\n",
    "\r",
    "\\",
    "\0",
    " ",
    "\t",
    "/",
    "//",
    "\u{feff}",
    "\u{fffd}",
    "é",
    ",",
    ":",
    "null",
    "true",
    "false",
    "-",
    ".",
    "..",
    "../",
    "/etc/passwd",
    "file:///etc/passwd",
];

/// Format keywords worth inserting anywhere.
const KEYWORDS: &[&str] = &[
    "WorldBegin\n",
    "AttributeBegin\n",
    "AttributeEnd\n",
    "ObjectBegin \"o\"\n",
    "ObjectEnd\n",
    "ObjectInstance \"o\"\n",
    "Include \"scene.pbrt\"\n",
    "Include \"inc.pbrt\"\n",
    "Import \"inc.pbrt\"\n",
    "Shape \"loopsubdiv\" \"integer levels\" 8 ",
    "\"integer indices\" [ 0 1 2 ] ",
    "\"point3 P\" [ 0 0 0 ] ",
    "\"rgb reflectance\" [ -1 0 0 ] ",
    "\"float scale\" -1 ",
    "\"blackbody L\" [ 0 1 ] ",
    "element vertex 4294967295\n",
    "element face 1000000000000\n",
    "element edge 4000000000\n",
    "property list uint uint vertex_indices\n",
    "property list uchar float vertex_indices\n",
    "property double x\n",
    "end_header\n",
    "format binary_big_endian 1.0\n",
    "4294967295 0 1 2\n",
    "f 0 0 0\n",
    "f -10 1 2\n",
    "f 1/1/1 2//2 3/3\n",
    "v nan inf 1e400\n",
    "vt 1e400 -0\n",
    "usemtl \n",
    "mtllib scene.mtl\n",
    "mtllib ../x.mtl\n",
    "newmtl red\n",
    "map_Kd -s 1e400 nan missing.png\n",
    "\"bufferView\": 99,",
    "\"byteOffset\": 4294967295,",
    "\"byteStride\": 1,",
    "\"count\": 4294967295,",
    "\"componentType\": 5121,",
    "\"type\": \"MAT4\",",
    "\"mode\": 6,",
    "\"uri\": \"data:application/octet-stream;base64,AAAA\",",
    "\"children\": [0],",
    "\"sparse\": {\"count\": 1, \"indices\": {\"bufferView\": 0, \"componentType\": 5125}, \"values\": {\"bufferView\": 0}},",
];

/// One change to a file's bytes; positions are drawn relative to the
/// file's length when the mutation is applied.
#[derive(Clone, Debug)]
enum Mutation {
    FlipBit(Index, u8),
    SetByte(Index, u8),
    Insert(Index, &'static str),
    /// Replaces the n-th number of the text.
    ReplaceNumber(Index, &'static str),
    Delete(Index, usize),
    Truncate(Index),
    /// Copies `len` bytes at the first index to the second.
    Duplicate(Index, usize, Index),
    SwapLines(Index, Index),
    /// Writes the value's little-endian bytes over the data there.
    WriteU32(Index, u32),
}

fn any_token() -> impl Strategy<Value = &'static str> {
    prop_oneof![prop::sample::select(NUMBERS), prop::sample::select(TOKENS), prop::sample::select(KEYWORDS),]
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let words = [0u32, 1, 2, 3, 0xff, 0x100, 0xffff, 0x7fff_ffff, 0x8000_0000, 0xffff_fffe, 0xffff_ffff];
    prop_oneof![
        2 => (any::<Index>(), 0u8..8).prop_map(|(i, b)| Mutation::FlipBit(i, b)),
        1 => (any::<Index>(), any::<u8>()).prop_map(|(i, b)| Mutation::SetByte(i, b)),
        3 => (any::<Index>(), any_token()).prop_map(|(i, t)| Mutation::Insert(i, t)),
        4 => (any::<Index>(), prop::sample::select(NUMBERS)).prop_map(|(i, t)| Mutation::ReplaceNumber(i, t)),
        2 => (any::<Index>(), 1usize..32).prop_map(|(i, n)| Mutation::Delete(i, n)),
        1 => any::<Index>().prop_map(Mutation::Truncate),
        1 => (any::<Index>(), 1usize..200, any::<Index>()).prop_map(|(i, n, j)| Mutation::Duplicate(i, n, j)),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(i, j)| Mutation::SwapLines(i, j)),
        2 => (any::<Index>(), prop::sample::select(words.to_vec())).prop_map(|(i, v)| Mutation::WriteU32(i, v)),
    ]
}

fn mutations() -> impl Strategy<Value = Vec<Mutation>> {
    prop::collection::vec(mutation(), 1..4)
}

/// Byte ranges of the numbers in `bytes` (runs of digits, signs, dots and
/// exponents that hold a digit).
fn number_spans(bytes: &[u8]) -> Vec<(usize, usize)> {
    let part = |b: u8| b.is_ascii_digit() || matches!(b, b'.' | b'-' | b'+' | b'e' | b'E');
    let mut spans = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        if part(bytes[i]) && (i == 0 || !bytes[i - 1].is_ascii_alphabetic()) {
            let start = i;
            while i < bytes.len() && part(bytes[i]) {
                i += 1;
            }
            if bytes[start..i].iter().any(u8::is_ascii_digit) {
                spans.push((start, i));
            }
        } else {
            i += 1;
        }
    }
    spans
}

fn apply(bytes: &mut Vec<u8>, m: &Mutation) {
    let len = bytes.len();
    match *m {
        Mutation::FlipBit(i, bit) if len > 0 => bytes[i.index(len)] ^= 1 << bit,
        Mutation::SetByte(i, b) if len > 0 => bytes[i.index(len)] = b,
        Mutation::Insert(i, t) => {
            let at = i.index(len + 1);
            bytes.splice(at..at, t.bytes());
        }
        Mutation::ReplaceNumber(i, t) => {
            let spans = number_spans(bytes);
            if !spans.is_empty() {
                let (a, b) = spans[i.index(spans.len())];
                bytes.splice(a..b, t.bytes());
            }
        }
        Mutation::Delete(i, n) if len > 0 => {
            let at = i.index(len);
            bytes.drain(at..(at + n).min(len));
        }
        Mutation::Truncate(i) => bytes.truncate(i.index(len + 1)),
        Mutation::Duplicate(i, n, j) if len > 0 => {
            let at = i.index(len);
            let copy = bytes[at..(at + n).min(len)].to_vec();
            let to = j.index(len + 1);
            bytes.splice(to..to, copy);
        }
        Mutation::SwapLines(i, j) => {
            let mut lines: Vec<Vec<u8>> = bytes.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
            let n = lines.len();
            lines.swap(i.index(n), j.index(n));
            *bytes = lines.join(&b'\n');
        }
        Mutation::WriteU32(i, v) if len > 0 => {
            let at = i.index(len);
            for (k, b) in v.to_le_bytes().into_iter().enumerate() {
                if let Some(slot) = bytes.get_mut(at + k) {
                    *slot = b;
                }
            }
        }
        _ => {}
    }
}

fn mutated(seed: &[u8], ms: &[Mutation]) -> Vec<u8> {
    let mut bytes = seed.to_vec();
    for m in ms {
        apply(&mut bytes, m);
    }
    bytes
}

// ---------------------------------------------------------------------------
// Checking a load

thread_local! {
    /// Panics on this thread since the last [`no_panic`] began.
    static PANICS: Cell<u32> = const { Cell::new(0) };
}

/// Runs `f`, failing the case on any panic on this thread, including one
/// caught (and turned into an error) inside the code under test.
fn no_panic<T>(f: impl FnOnce() -> T) -> Result<T, TestCaseError> {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            PANICS.with(|p| p.set(p.get() + 1));
            previous(info);
        }));
    });
    PANICS.with(|p| p.set(0));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    let panics = PANICS.with(Cell::get);
    match result {
        Err(e) => {
            let msg = e
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            Err(TestCaseError::fail(format!("panicked: {msg}")))
        }
        Ok(_) if panics > 0 => {
            Err(TestCaseError::fail(format!("{panics} panic(s) caught inside the loader")))
        }
        Ok(v) => Ok(v),
    }
}

/// A folder with the files of one case.
struct Case {
    dir: PathBuf,
    names: Vec<&'static str>,
}

impl Case {
    /// The case folder for `tag`: one per property and thread, emptied of
    /// the last case's files (cases only ever write the same few names).
    fn new(tag: &str) -> Self {
        thread_local! {
            static DIRS: std::cell::RefCell<Vec<(String, PathBuf)>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        let dir = DIRS.with(|d| {
            let mut d = d.borrow_mut();
            match d.iter().find(|(t, _)| t == tag) {
                Some((_, dir)) => dir.clone(),
                None => {
                    let dir = temp_dir(tag);
                    d.push((tag.to_string(), dir.clone()));
                    dir
                }
            }
        });
        for entry in std::fs::read_dir(&dir).unwrap() {
            std::fs::remove_file(entry.unwrap().path()).unwrap();
        }
        Case { dir, names: Vec::new() }
    }

    fn write(&mut self, name: &'static str, bytes: &[u8]) {
        std::fs::write(self.dir.join(name), bytes).unwrap();
        if !self.names.contains(&name) {
            self.names.push(name);
        }
    }

    /// Loads `main` with [`load_any`]: it must not panic, and an error must
    /// name one of the case's files and a line that file has.
    fn load(&self, main: &str) -> Result<(), TestCaseError> {
        let result = no_panic(|| load_any(&self.dir.join(main)))?;
        let Err(e) = result else { return Ok(()) };
        let Some(name) = self.names.iter().find(|n| Path::new(&e.file) == self.dir.join(n)) else {
            return Err(TestCaseError::fail(format!("the error names none of the scene's files: {e}")));
        };
        prop_assert!(!e.message.is_empty(), "empty message: {e}");
        if e.line > 0 {
            let text = std::fs::read(self.dir.join(name)).unwrap();
            let lines = text.iter().filter(|&&b| b == b'\n').count() + 1;
            prop_assert!(e.line as usize <= lines, "{e}: the file has {lines} lines");
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------
// Seeds: small valid files

const PBRT_SCENE: &str = r#"# A small scene using most of what the loader reads.
LookAt 0 1 -5  0 0 0  0 1 0
Camera "perspective" "float fov" [ 45 ]
Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" [ 48 ] "string filename" "out.exr"
Sampler "independent" "integer pixelsamples" [ 4 ]
Integrator "path" "integer maxdepth" [ 5 ]
WorldBegin
LightSource "infinite" "rgb L" [ 0.2 0.3 0.4 ] "float scale" 1
LightSource "point" "point3 from" [ 0 4 0 ] "blackbody I" 5500
LightSource "spot" "point3 from" [ 0 4 0 ] "point3 to" [ 0 0 0 ] "float coneangle" 30 "rgb I" [ 1 1 1 ]
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [ 4 4 4 ] "float scale" 2
  Translate 0 3 0
  Shape "bilinearmesh" "point3 P" [ -1 0 -1  1 0 -1  -1 0 1  1 0.5 1 ]
AttributeEnd
MakeNamedMaterial "red" "string type" "diffuse" "rgb reflectance" [ 0.8 0.1 0.1 ]
Texture "checks" "spectrum" "checkerboard" "float uscale" 4 "float vscale" 4 "rgb tex1" [ 1 1 1 ] "rgb tex2" [ 0 0 0 ]
Material "coateddiffuse" "texture reflectance" "checks" "float roughness" 0.1
Include "inc.pbrt"
ObjectBegin "thing"
  NamedMaterial "red"
  Shape "sphere" "float radius" 0.5
  Shape "loopsubdiv" "integer levels" 2 "point3 P" [ 0 0 0  1 0 0  0 1 0  0 0 1 ]
    "integer indices" [ 0 1 2  0 3 1  0 2 3  1 3 2 ]
ObjectEnd
ObjectInstance "thing"
Translate 2 0 0
Rotate 30 0 1 0
Scale 1 2 1
ObjectInstance "thing"
"#;

const PBRT_INCLUDE: &str = r#"AttributeBegin
  Material "conductor" "spectrum eta" "metal-Cu-eta" "spectrum k" "metal-Cu-k" "float roughness" 0.2
  Shape "trianglemesh" "point3 P" [ -5 0 -5  5 0 -5  5 0 5  -5 0 5 ] "integer indices" [ 0 1 2  0 2 3 ]
    "point2 uv" [ 0 0  1 0  1 1  0 1 ] "normal N" [ 0 1 0  0 1 0  0 1 0  0 1 0 ]
  Material "dielectric" "float eta" 1.5
  Shape "plymesh" "string filename" "mesh.ply"
AttributeEnd
"#;

const PLY_ASCII: &str = "ply\nformat ascii 1.0\ncomment a quad and a triangle\nelement vertex 5\n\
property float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
property float u\nproperty float v\nelement face 2\nproperty list uchar int vertex_indices\n\
element edge 1\nproperty int a\nproperty int b\nend_header\n\
0 0 0 0 0 1 0 0\n1 0 0 0 0 1 1 0\n1 1 0 0 0 1 1 1\n0 1 0 0 0 1 0 1\n0.5 2 0 0 0 1 0.5 2\n\
4 0 1 2 3\n3 3 2 4\n0 1\n";

/// A binary PLY: four vertices with double uvs, one quad, an extra per-face int.
fn ply_binary(big_endian: bool) -> Vec<u8> {
    let fmt = if big_endian { "binary_big_endian" } else { "binary_little_endian" };
    let mut b = format!(
        "ply\nformat {fmt} 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
         property double u\nproperty double v\nelement face 1\nproperty list uchar uint vertex_indices\n\
         property int flags\nend_header\n"
    )
    .into_bytes();
    let f32b = |x: f32| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() };
    let f64b = |x: f64| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() };
    let u32b = |x: u32| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() };
    for (p, uv) in [
        ([0., 0., 0.], [0., 0.]),
        ([1., 0., 0.], [1., 0.]),
        ([1., 1., 0.], [1., 1.]),
        ([0., 1., 0.], [0., 1.]),
    ] {
        p.iter().for_each(|&x: &f32| b.extend(f32b(x)));
        uv.iter().for_each(|&x: &f64| b.extend(f64b(x)));
    }
    b.push(4);
    [0, 1, 2, 3].iter().for_each(|&i| b.extend(u32b(i)));
    b.extend(u32b(7));
    b
}

const OFF: &str = "OFF # a square and a triangle\n5 3 0\n\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0.5 2 0\n\
4 0 1 2 3 255 0 0\n3 3 2 4\n2 0 1\n";

const NOFF: &str = "NOFF 3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n";

const OBJ: &str = "# two objects and a group\nmtllib scene.mtl\no quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nusemtl red\nf 1/1/1 2/2/1 3/3/1 4/4/1\no tri\nv 0 0 1\nv 1 0 1\n\
v 0 1 1\nusemtl glass\nf -3 -2 -1\ng lamp\nusemtl lamp\nf 5 6 7\ns 1\nl 1 2\n";

const MTL: &str =
    "newmtl red\nKd 0.8 0.1 0.1\nKs 0.1 0.1 0.1\nNs 10\nd 0.5\nmap_Kd -s 2 2 -clamp on missing.png\n\
newmtl glass\nillum 7\nNi 1.5\nNs 300\nnewmtl lamp\nKd 0 0 0\nKe 4 4 4\nTr 0.25\n";

/// A glTF scene with instancing, materials, a camera and lights; the
/// buffer is `uri` (`None`: the GLB chunk).
fn gltf_json(uri: Option<&str>) -> String {
    let buffer = match uri {
        Some(uri) => format!(r#"{{"byteLength": 152, "uri": "{uri}"}}"#),
        None => r#"{"byteLength": 152}"#.to_string(),
    };
    format!(
        r#"{{
"asset": {{"version": "2.0"}},
"extensionsUsed": ["KHR_lights_punctual", "KHR_materials_ior", "KHR_materials_emissive_strength", "KHR_texture_transform"],
"scene": 0,
"scenes": [{{"nodes": [0, 3, 4, 5, 6]}}],
"nodes": [
  {{"name": "root", "translation": [10, 0, 0], "children": [1, 2]}},
  {{"mesh": 0, "rotation": [0, 0, 0.7071, 0.7071]}},
  {{"mesh": 0, "scale": [2, 2, 2]}},
  {{"mesh": 1, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 5, 0, 1]}},
  {{"camera": 0, "translation": [0, 1, 10]}},
  {{"translation": [0, 3, 0], "extensions": {{"KHR_lights_punctual": {{"light": 0}}}}}},
  {{"rotation": [-0.7071, 0, 0, 0.7071], "extensions": {{"KHR_lights_punctual": {{"light": 1}}}}}}
],
"meshes": [
  {{"name": "tri", "primitives": [
    {{"attributes": {{"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}}, "indices": 3, "material": 0}},
    {{"attributes": {{"POSITION": 4}}, "mode": 5, "material": 1}}]}},
  {{"name": "lamp", "primitives": [{{"attributes": {{"POSITION": 0}}, "material": 2}}]}}
],
"materials": [
  {{"pbrMetallicRoughness": {{"baseColorFactor": [0.8, 0.2, 0.1, 0.5], "metallicFactor": 0,
     "baseColorTexture": {{"index": 0, "extensions": {{"KHR_texture_transform": {{"offset": [0.5, 0.25], "scale": [2, 4]}}}}}}}},
   "alphaMode": "MASK", "alphaCutoff": 0.3}},
  {{"pbrMetallicRoughness": {{"metallicFactor": 1, "roughnessFactor": 0.5}},
   "extensions": {{"KHR_materials_ior": {{"ior": 1.33}}}}}},
  {{"emissiveFactor": [1, 0.5, 0.25], "extensions": {{"KHR_materials_emissive_strength": {{"emissiveStrength": 4}}}}}}
],
"textures": [{{"source": 0, "sampler": 0}}],
"samplers": [{{"wrapS": 33648, "wrapT": 33071}}],
"images": [{{"uri": "missing%20image.png"}}],
"cameras": [{{"type": "perspective", "perspective": {{"yfov": 0.8, "aspectRatio": 1.5, "znear": 0.1}}}}],
"extensions": {{"KHR_lights_punctual": {{"lights": [
  {{"type": "spot", "color": [1, 1, 1], "intensity": 10, "spot": {{"innerConeAngle": 0.2, "outerConeAngle": 0.5}}}},
  {{"type": "directional", "intensity": 2}}]}}}},
"accessors": [
  {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
  {{"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"}},
  {{"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC2"}},
  {{"bufferView": 3, "componentType": 5123, "count": 3, "type": "SCALAR"}},
  {{"bufferView": 4, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}}
],
"bufferViews": [
  {{"buffer": 0, "byteOffset": 0, "byteLength": 36}},
  {{"buffer": 0, "byteOffset": 36, "byteLength": 36, "byteStride": 12}},
  {{"buffer": 0, "byteOffset": 72, "byteLength": 24}},
  {{"buffer": 0, "byteOffset": 96, "byteLength": 6}},
  {{"buffer": 0, "byteOffset": 104, "byteLength": 48}}
],
"buffers": [{buffer}]
}}"#
    )
}

/// A GLB of `json` with `bin` as its BIN chunk.
fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    common::glb(json.as_bytes(), bin)
}

/// Every seed loads as it is: a property over broken seeds would test little.
#[test]
fn the_seeds_are_valid() {
    let mut c = Case::new("props-seeds");
    c.write("scene.pbrt", PBRT_SCENE.as_bytes());
    c.write("inc.pbrt", PBRT_INCLUDE.as_bytes());
    c.write("mesh.ply", PLY_ASCII.as_bytes());
    c.write("le.ply", &ply_binary(false));
    c.write("be.ply", &ply_binary(true));
    c.write("mesh.off", OFF.as_bytes());
    c.write("n.off", NOFF.as_bytes());
    c.write("scene.obj", OBJ.as_bytes());
    c.write("scene.mtl", MTL.as_bytes());
    c.write("scene.gltf", gltf_json(Some("scene.bin")).as_bytes());
    c.write("scene.bin", &gltf_bin());
    c.write("scene.glb", &glb(&gltf_json(None), &gltf_bin()));
    for main in [
        "scene.pbrt",
        "mesh.ply",
        "le.ply",
        "be.ply",
        "mesh.off",
        "n.off",
        "scene.obj",
        "scene.gltf",
        "scene.glb",
    ] {
        let loaded = load_any(&c.dir.join(main)).unwrap_or_else(|e| panic!("{main}: {e}"));
        assert!(!loaded.scene.meshes.is_empty(), "{main}");
    }
}

// ---------------------------------------------------------------------------
// Properties

proptest! {
    #![proptest_config(config())]

    /// Tokens stay inside the text on character boundaries, in order, and
    /// every token consumes input (so tokenizing ends).
    #[test]
    fn tokenizer_never_panics(ms in mutations()) {
        let bytes = mutated(PBRT_SCENE.as_bytes(), &ms);
        let limit = bytes.len() + 1;
        no_panic(|| -> Result<(), TestCaseError> {
            let mut t = match Tokenizer::new("t.pbrt", bytes) {
                Ok(t) => t,
                Err(e) => {
                    prop_assert_eq!(e.file.as_str(), "t.pbrt");
                    return Ok(());
                }
            };
            let (mut count, mut last) = (0, (1, 0));
            loop {
                match t.next_token() {
                    Ok(None) => return Ok(()),
                    Err(e) => {
                        prop_assert_eq!(e.file.as_str(), "t.pbrt");
                        prop_assert!(e.line >= 1 && e.col >= 1, "{}", e);
                        return Ok(());
                    }
                    Ok(Some(tok)) => {
                        count += 1;
                        prop_assert!(count <= limit, "more tokens than bytes");
                        prop_assert!((tok.line, tok.col) > last, "token at {}:{} after {:?}", tok.line, tok.col, last);
                        last = (tok.line, tok.col);
                        let _ = t.text(&tok);
                        if let TokenKind::Str { .. } = tok.kind {
                            let _ = t.string(&tok);
                        }
                    }
                }
            }
        })??;
    }

    /// The parser reads directives until the end or an error at a location
    /// in its file.
    #[test]
    fn parser_never_panics(ms in mutations()) {
        let bytes = mutated(PBRT_SCENE.as_bytes(), &ms);
        let lines = bytes.iter().filter(|&&b| b == b'\n').count() + 1;
        let limit = bytes.len() + 1;
        no_panic(|| -> Result<(), TestCaseError> {
            let Ok(t) = Tokenizer::new("p.pbrt", bytes) else { return Ok(()) };
            let mut p = Parser::new(t);
            for _ in 0..limit {
                match p.next_directive() {
                    Ok(Some(_)) => {}
                    Ok(None) => return Ok(()),
                    Err(e) => {
                        prop_assert_eq!(e.file.as_str(), "p.pbrt");
                        prop_assert!(e.line >= 1 && e.line as usize <= lines, "{}", e);
                        return Ok(());
                    }
                }
            }
            Err(TestCaseError::fail("more directives than bytes"))
        })??;
    }

    /// A PBRT scene with an Include and a PLY mesh, one of the three files mutated.
    #[test]
    fn pbrt_scenes_never_panic(file in 0..3usize, ms in mutations()) {
        let mut seeds = [PBRT_SCENE.as_bytes(), PBRT_INCLUDE.as_bytes(), PLY_ASCII.as_bytes()].map(<[u8]>::to_vec);
        seeds[file] = mutated(&seeds[file], &ms);
        let mut c = Case::new("props-pbrt");
        for (name, bytes) in ["scene.pbrt", "inc.pbrt", "mesh.ply"].into_iter().zip(&seeds) {
            c.write(name, bytes);
        }
        c.load("scene.pbrt")?;
    }

    /// ASCII and binary PLY of both byte orders.
    #[test]
    fn ply_never_panics(seed in 0..3usize, ms in mutations()) {
        let seed = match seed {
            0 => PLY_ASCII.as_bytes().to_vec(),
            1 => ply_binary(false),
            _ => ply_binary(true),
        };
        let mut c = Case::new("props-ply");
        c.write("mesh.ply", &mutated(&seed, &ms));
        c.load("mesh.ply")?;
    }

    #[test]
    fn off_never_panics(noff in any::<bool>(), ms in mutations()) {
        let seed = if noff { NOFF } else { OFF };
        let mut c = Case::new("props-off");
        c.write("mesh.off", &mutated(seed.as_bytes(), &ms));
        c.load("mesh.off")?;
    }

    /// OBJ with its MTL, one of the two mutated.
    #[test]
    fn obj_never_panics(mtl in any::<bool>(), ms in mutations()) {
        let mut c = Case::new("props-obj");
        let (obj, lib) = if mtl {
            (OBJ.as_bytes().to_vec(), mutated(MTL.as_bytes(), &ms))
        } else {
            (mutated(OBJ.as_bytes(), &ms), MTL.as_bytes().to_vec())
        };
        c.write("scene.obj", &obj);
        c.write("scene.mtl", &lib);
        c.load("scene.obj")?;
    }

    /// glTF JSON with an external buffer, one of the two mutated.
    #[test]
    fn gltf_never_panics(bin in any::<bool>(), ms in mutations()) {
        let mut c = Case::new("props-gltf");
        let (json, buffer) = if bin {
            (gltf_json(Some("scene.bin")).into_bytes(), mutated(&gltf_bin(), &ms))
        } else {
            (mutated(gltf_json(Some("scene.bin")).as_bytes(), &ms), gltf_bin())
        };
        c.write("scene.gltf", &json);
        c.write("scene.bin", &buffer);
        c.load("scene.gltf")?;
    }

    #[test]
    fn glb_never_panics(ms in mutations()) {
        let mut c = Case::new("props-glb");
        c.write("scene.glb", &mutated(&glb(&gltf_json(None), &gltf_bin()), &ms));
        c.load("scene.glb")?;
    }
}
