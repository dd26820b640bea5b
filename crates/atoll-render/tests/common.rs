//! Helpers shared by the renderer's integration tests.
#![allow(dead_code)]

use std::path::PathBuf;
use std::sync::Arc;

use atoll_render::{render, CpuDevice, Film, RenderOptions};
use atoll_scene::Scene;

/// `../shared/scenes/<rel>` from the repository root.
pub fn shared_scene(rel: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes").join(rel)
}

pub fn render_with(scene: &Arc<Scene>, options: RenderOptions, threads: Option<usize>) -> Film {
    let mut device = CpuDevice::new();
    if let Some(t) = threads {
        device = device.with_threads(t).unwrap();
    }
    render(&mut device, scene, options, &mut |_, _| {}).unwrap().film
}

pub fn assert_finite(film: &Film) {
    for (i, p) in film.pixels().iter().enumerate() {
        assert!(p.is_finite() && p.min_element() >= 0.0, "pixel {i} is {p}");
    }
}

/// Mean and standard error of one channel's per-pixel values.
pub fn mean_and_stderr(values: impl Iterator<Item = f32>) -> (f64, f64) {
    let v: Vec<f64> = values.map(|x| x as f64).collect();
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// A UV sphere of radius 1 with smooth normals, `rings` × `segments` quads.
pub fn uv_sphere(material: u32, rings: u32, segments: u32) -> atoll_scene::TriangleMesh {
    use glam::Vec3;
    let mut positions = Vec::new();
    for i in 0..=rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = 2.0 * std::f32::consts::PI * j as f32 / segments as f32;
            positions.push(Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()));
        }
    }
    let mut indices = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let a = i * segments + j;
            let b = i * segments + (j + 1) % segments;
            let (c, d) = (a + segments, b + segments);
            indices.push([a, c, b]);
            indices.push([b, c, d]);
        }
    }
    let normals = positions.clone();
    atoll_scene::TriangleMesh {
        name: "sphere".into(),
        positions,
        normals,
        indices,
        material,
        ..Default::default()
    }
}

/// A pbrt scene: the plane z = 0 (uv (0,0)–(1,1) over x, y in [-10, 10])
/// seen from above at `size`² pixels and `spp`, diffuse with the spectrum
/// texture "reflectance" that `textures` defines, under a uniform white
/// sky, so that every pixel converges to the filtered reflectance it sees
/// (direct light only). `filter` is the `PixelFilter` statement.
pub fn sky_lit_plane(size: u32, spp: u32, filter: &str, textures: &str) -> String {
    format!(
        r#"
LookAt 0 0 4  0 0 0  0 1 0
Camera "perspective" "float fov" [ 40 ]
Sampler "independent" "integer pixelsamples" [ {spp} ]
Integrator "path" "integer maxdepth" [ 1 ]
Film "rgb" "integer xresolution" [ {size} ] "integer yresolution" [ {size} ]
{filter}
WorldBegin
LightSource "infinite" "rgb L" [ 1 1 1 ]
{textures}
Material "diffuse" "texture reflectance" "reflectance"
Shape "trianglemesh" "point3 P" [ -10 -10 0  10 -10 0  10 10 0  -10 10 0 ]
  "integer indices" [ 0 1 2  0 2 3 ] "point2 uv" [ 0 0  1 0  1 1  0 1 ]
"#
    )
}

/// Renders the [`sky_lit_plane`] scene `source` and returns its film with
/// what each pixel should converge to: `reflectance` (of a point of the
/// plane) under the scene's pixel filter, integrated over a grid of
/// offsets around the pixel's centre through the scene's own camera.
pub fn render_against(
    source: &str,
    reflectance: &dyn Fn(glam::Vec3) -> glam::Vec3,
) -> (Film, Vec<glam::Vec3>) {
    use glam::{Vec2, Vec3};
    let loaded = atoll_scene::pbrt::load_str(source, "plane.pbrt", std::path::Path::new(".")).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let scene = Arc::new(loaded.scene);
    let options = RenderOptions::from_scene(&scene);
    let film = render_with(&scene, options.clone(), None);
    // Filters with negative lobes may leave pixels below 0.
    assert!(film.pixels().iter().all(|p| p.is_finite()));
    let camera = atoll_render::camera::CameraRays::new(&scene.settings.camera, options.resolution);
    let filter = options.filter;
    let r = filter.radius();
    // 16 points a pixel: edges within the filter's reach come out sharp.
    let grid = (2.0 * r.max_element() * 16.0).ceil() as u32;
    let offsets: Vec<(Vec2, f32)> = (0..grid * grid)
        .map(|k| {
            let t = (Vec2::new((k % grid) as f32, (k / grid) as f32) + 0.5) / grid as f32;
            let o = (2.0 * t - 1.0) * r;
            (o, filter.along(0, o.x) * filter.along(1, o.y))
        })
        .collect();
    let total: f32 = offsets.iter().map(|(_, w)| w).sum();
    let width = options.resolution.x;
    let want = (0..options.pixel_count())
        .map(|i| {
            let centre = Vec2::new((i % width) as f32, (i / width) as f32) + 0.5;
            let sum: Vec3 = offsets
                .iter()
                .map(|&(o, w)| {
                    let (origin, d) = camera.ray(centre + o, Vec2::ZERO);
                    w * reflectance(origin - d * (origin.z / d.z))
                })
                .sum();
            sum / total
        })
        .collect();
    (film, want)
}

/// Every pixel of `film` within `median` of `want` at the median and
/// `p99` at the 99th percentile (largest channel error), and `want` not flat.
pub fn assert_pixels_match(what: &str, film: &Film, want: &[glam::Vec3], median: f32, p99: f32) {
    let mut errors: Vec<f32> =
        film.pixels().iter().zip(want).map(|(got, want)| (*got - *want).abs().max_element()).collect();
    let values: Vec<f32> = want.iter().map(|v| v.x).collect();
    let mean = values.iter().sum::<f32>() / values.len() as f32;
    let spread = (values.iter().map(|v| (v - mean).powi(2)).sum::<f32>() / values.len() as f32).sqrt();
    assert!(spread > 0.01, "{what}: the reflectance hardly varies over the image ({spread})");
    errors.sort_by(f32::total_cmp);
    let (m, p) = (errors[errors.len() / 2], errors[errors.len() * 99 / 100]);
    assert!(m < median && p < p99, "{what}: pixel errors median {m}, p99 {p}");
}

/// xorshift64*, enough for tests without an RNG dependency.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_f32(&mut self) -> f32 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 40) as f32 * (1.0 / 16_777_216.0)
    }

    pub fn vec2(&mut self) -> glam::Vec2 {
        glam::Vec2::new(self.next_f32(), self.next_f32())
    }
}
