//! Small valid inputs of every format the suite mutates: each renders (exit
//! 0) as it is, so any failure of a mutation is the mutation's doing.

use std::io::Write;

/// The PBRT scene, one statement a line (mutations address lines; the
/// location a message must give is `scene.pbrt:<index + 1>:`).
pub const PBRT: &[&str] = &[
    "# hostile-suite template",
    "LookAt 0 0 5  0 0 0  0 1 0",
    "Camera \"perspective\" \"float fov\" [ 45 ]",
    "Film \"rgb\" \"integer xresolution\" [ 16 ] \"integer yresolution\" [ 16 ] \"string filename\" \"film.png\"",
    "Sampler \"independent\" \"integer pixelsamples\" [ 1 ]",
    "Integrator \"volpath\" \"integer maxdepth\" [ 3 ]",
    "WorldBegin",
    "LightSource \"point\" \"rgb I\" [ 10 10 10 ] \"point3 from\" [ 0 0 4 ]",
    "LightSource \"infinite\" \"blackbody L\" [ 6500 ] \"float scale\" [ 0.1 ]",
    "AttributeBegin",
    "  AreaLightSource \"diffuse\" \"rgb L\" [ 4 4 4 ]",
    "  Shape \"trianglemesh\" \"point3 P\" [ -1 1 2  1 1 2  1 1.5 2 ] \"integer indices\" [ 0 1 2 ]",
    "AttributeEnd",
    "Texture \"checks\" \"spectrum\" \"checkerboard\" \"float uscale\" [ 4 ] \"float vscale\" [ 4 ]",
    "Material \"diffuse\" \"texture reflectance\" \"checks\"",
    "Shape \"trianglemesh\" \"point3 P\" [ -1 -1 0  1 -1 0  1 1 0  -1 1 0 ] \"integer indices\" [ 0 1 2  0 2 3 ] \"point2 uv\" [ 0 0 1 0 1 1 0 1 ]",
    "Material \"conductor\" \"float roughness\" [ 0.2 ]",
    "Shape \"sphere\" \"float radius\" [ 0.5 ]",
];

/// The template's text, lines joined.
pub fn pbrt() -> String {
    join(PBRT.iter().copied())
}

/// Lines joined with newlines (and one at the end).
pub fn join<'a>(lines: impl IntoIterator<Item = &'a str>) -> String {
    lines.into_iter().flat_map(|l| [l, "\n"]).collect()
}

/// A scene around one `statement` (after `WorldBegin`, on line 8), with a
/// light so that it renders: `scene.pbrt:8:` is where the statement is.
pub fn pbrt_with(statement: &str) -> String {
    join([
        "LookAt 0 0 5  0 0 0  0 1 0",
        "Camera \"perspective\" \"float fov\" [ 45 ]",
        "Sampler \"independent\" \"integer pixelsamples\" [ 1 ]",
        "WorldBegin",
        "LightSource \"point\" \"rgb I\" [ 10 10 10 ] \"point3 from\" [ 0 0 4 ]",
        "Shape \"trianglemesh\" \"point3 P\" [ -1 -1 0  1 -1 0  1 1 0 ]",
        "Material \"diffuse\"",
        statement,
    ])
}

/// Line of [`pbrt_with`]'s statement.
pub const STATEMENT_LINE: usize = 8;

pub const PLY_ASCII: &str = "ply\nformat ascii 1.0\ncomment hostile-suite\nelement vertex 4\n\
property float x\nproperty float y\nproperty float z\nproperty float u\nproperty float v\n\
element face 2\nproperty list uchar int vertex_indices\nend_header\n\
-1 -1 0 0 0\n1 -1 0 1 0\n1 1 0 1 1\n-1 1 0 0 1\n3 0 1 2\n3 0 2 3\n";

/// The binary header (little endian, or big); the body follows it.
pub fn ply_binary_header(big_endian: bool, vertices: &str, faces: &str) -> String {
    let format = if big_endian { "binary_big_endian" } else { "binary_little_endian" };
    format!(
        "ply\nformat {format} 1.0\nelement vertex {vertices}\nproperty float x\nproperty float y\n\
         property float z\nelement face {faces}\nproperty list uchar uint vertex_indices\nend_header\n"
    )
}

/// A square of two triangles as binary PLY.
pub fn ply_binary(big_endian: bool) -> Vec<u8> {
    let mut b = ply_binary_header(big_endian, "4", "2").into_bytes();
    let f = |x: f32| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() };
    let u = |x: u32| if big_endian { x.to_be_bytes() } else { x.to_le_bytes() };
    for p in [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0f32]] {
        p.iter().for_each(|&x| b.extend(f(x)));
    }
    for tri in [[0, 1, 2], [0, 2, 3u32]] {
        b.push(3);
        tri.iter().for_each(|&i| b.extend(u(i)));
    }
    b
}

pub const OFF: &str = "OFF\n# hostile-suite\n4 2 0\n-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n3 0 1 2\n3 0 2 3\n";

pub const OBJ: &str = "# hostile-suite\nmtllib model.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n\
vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nusemtl red\nf 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n";

pub const MTL: &str = "newmtl red\nKd 0.8 0.1 0.1\nmap_Kd tex.png\nnewmtl glow\nKe 1 1 1\n";

/// A glTF buffer: a triangle's positions (36 bytes), uvs (24) and u16
/// indices (6, padded to 8).
pub fn gltf_bin() -> Vec<u8> {
    let mut b = Vec::new();
    for x in [-1.0f32, -1.0, 0.0, 1.0, -1.0, 0.0, 0.0, 1.0, 0.0] {
        b.extend(x.to_le_bytes());
    }
    for x in [0.0f32, 0.0, 1.0, 0.0, 0.5, 1.0] {
        b.extend(x.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0] {
        b.extend(i.to_le_bytes());
    }
    b
}

/// The glTF document; `BUFFER_URI` stands for the buffer's URI (mutations
/// replace its pieces by text).
pub const GLTF: &str = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0,1]}],
"nodes":[{"mesh":0},{"camera":0,"translation":[0,0,3]}],
"cameras":[{"type":"perspective","perspective":{"yfov":0.8,"znear":0.01,"aspectRatio":1.0}}],
"meshes":[{"primitives":[{"attributes":{"POSITION":0,"TEXCOORD_0":1},"indices":2,"material":0}]}],
"materials":[{"pbrMetallicRoughness":{"baseColorFactor":[0.8,0.8,0.8,1],"baseColorTexture":{"index":0}},"emissiveFactor":[0.1,0.1,0.1]}],
"textures":[{"source":0}],
"images":[{"uri":"tex.png"}],
"buffers":[{"uri":"BUFFER_URI","byteLength":68}],
"bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":24},{"buffer":0,"byteOffset":60,"byteLength":6}],
"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[-1,-1,0],"max":[1,1,0]},
{"bufferView":1,"componentType":5126,"count":3,"type":"VEC2"},
{"bufferView":2,"componentType":5123,"count":3,"type":"SCALAR"}]}
"#;

/// The glTF document with its buffer in `model.bin`.
pub fn gltf() -> String {
    GLTF.replace("BUFFER_URI", "model.bin")
}

/// The glTF document with its buffer in a base64 data URI.
pub fn gltf_data_uri() -> String {
    GLTF.replace("BUFFER_URI", &format!("data:application/octet-stream;base64,{}", base64(&gltf_bin())))
}

/// A GLB: the document (buffer without URI) and the buffer as its binary chunk.
pub fn glb() -> Vec<u8> {
    let mut json = GLTF.replace("\"uri\":\"BUFFER_URI\",", "").into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let bin = gltf_bin();
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut b = Vec::new();
    b.extend(b"glTF");
    b.extend(2u32.to_le_bytes());
    b.extend((total as u32).to_le_bytes());
    b.extend((json.len() as u32).to_le_bytes());
    b.extend(b"JSON");
    b.extend(json);
    b.extend((bin.len() as u32).to_le_bytes());
    b.extend(b"BIN\0");
    b.extend(bin);
    b
}

fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for i in 0..4 {
            if i <= c.len() {
                s.push(A[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A `width`×`height` 8-bit RGB PNG of a gradient, encoded by hand (zlib
/// and CRC from flate2) so that the suite needs no image encoder.
pub fn png(width: u32, height: u32) -> Vec<u8> {
    let mut raw = Vec::new();
    for y in 0..height {
        raw.push(0); // filter: none
        for x in 0..width {
            raw.extend([(x * 255 / width.max(1)) as u8, (y * 255 / height.max(1)) as u8, 128]);
        }
    }
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    z.write_all(&raw).unwrap();
    png_with(width, height, &z.finish().unwrap())
}

/// A PNG of the given header size around the zlib stream `idat` (any bytes).
pub fn png_with(width: u32, height: u32, idat: &[u8]) -> Vec<u8> {
    let mut b = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend(width.to_be_bytes());
    ihdr.extend(height.to_be_bytes());
    ihdr.extend([8, 2, 0, 0, 0]); // 8-bit RGB, deflate, no filter, no interlace
    chunk(&mut b, b"IHDR", &ihdr);
    chunk(&mut b, b"IDAT", idat);
    chunk(&mut b, b"IEND", &[]);
    b
}

fn chunk(out: &mut Vec<u8>, kind: &[u8; 4], data: &[u8]) {
    out.extend((data.len() as u32).to_be_bytes());
    let mut crc = flate2::Crc::new();
    crc.update(kind);
    crc.update(data);
    out.extend(kind);
    out.extend(data);
    out.extend(crc.sum().to_be_bytes());
}

/// A 2×2 PFM (little endian floats).
pub fn pfm() -> Vec<u8> {
    let mut b = b"PF\n2 2\n-1.0\n".to_vec();
    for _ in 0..12 {
        b.extend(0.5f32.to_le_bytes());
    }
    b
}

/// A 4×4 EXR, written through the exr crate into `dir` and read back.
pub fn exr(dir: &std::path::Path) -> Vec<u8> {
    let path = dir.join("template.exr");
    exr::prelude::write_rgb_file(&path, 4, 4, |x, y| (x as f32 / 4.0, y as f32 / 4.0, 0.5f32)).unwrap();
    std::fs::read(&path).unwrap()
}

/// `bytes` gzip-compressed.
pub fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    gz.write_all(bytes).unwrap();
    gz.finish().unwrap()
}

/// A gzip bomb: `prefix` then `mib` MiB of `fill` bytes, compressed
/// (some 1000 times smaller than it inflates).
pub fn gzip_bomb(prefix: &[u8], fill: u8, mib: usize) -> Vec<u8> {
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    gz.write_all(prefix).unwrap();
    let block = vec![fill; 1 << 20];
    for _ in 0..mib {
        gz.write_all(&block).unwrap();
    }
    gz.finish().unwrap()
}

/// A `n`×`n` grid of quads as a PBRT trianglemesh statement (2n² triangles).
pub fn grid_mesh(n: usize, shape: &str) -> String {
    let mut s = format!("Shape \"{shape}\" \"point3 P\" [");
    for y in 0..=n {
        for x in 0..=n {
            s.push_str(&format!(" {} {} 0", x as f32 / n as f32 - 0.5, y as f32 / n as f32 - 0.5));
        }
    }
    s.push_str(" ] \"integer indices\" [");
    let v = |x: usize, y: usize| y * (n + 1) + x;
    for y in 0..n {
        for x in 0..n {
            let (a, b, c, d) = (v(x, y), v(x + 1, y), v(x + 1, y + 1), v(x, y + 1));
            s.push_str(&format!(" {a} {b} {c} {a} {c} {d}"));
        }
    }
    s.push_str(" ]");
    s
}
