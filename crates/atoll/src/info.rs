//! `atoll info`.

use std::path::PathBuf;
use std::time::Instant;

use std::sync::Arc;

use atoll_bvh::SceneBvh;
use atoll_cuda::error::fmt_bytes;
use atoll_dist::SharedSpec;
use atoll_render::RenderOptions;
use atoll_scene::Scene;
use clap::Args;

use crate::load::load_scene;
use crate::multi::DeviceSpec;
use crate::CliError;

#[derive(Args)]
pub struct InfoArgs {
    /// Scene file (.pbrt, .obj, .gltf/.glb, .ply, .off) or a generated `landscape:GROWTH[:SEED]`;
    /// the built-in Cornell box when omitted.
    pub scene: Option<PathBuf>,
    /// Also run the shared strategy's prepass (one sample per pixel of the
    /// scene's frame, reads counted per chunk) and print how concentrated
    /// the reads are: the share the hottest 1%, 5%, 10%… of the data take.
    #[arg(long)]
    pub prepass: bool,
    /// Devices of the prepass (as `atoll render --devices`; default: the CPU).
    #[arg(long, value_parser = crate::multi::parse_devices, requires = "prepass")]
    pub devices: Option<crate::multi::DeviceList>,
    /// Chunk size of the prepass, e.g. 2M.
    #[arg(long, value_parser = crate::device::parse_size, value_name = "SIZE", requires = "prepass")]
    pub chunk_size: Option<u64>,
}

fn mib(bytes: u64) -> String {
    format!("{:.2} MiB", bytes as f64 / (1024.0 * 1024.0))
}

pub fn run(args: InfoArgs) -> Result<(), CliError> {
    let start = Instant::now();
    let scene = load_scene(args.scene.as_deref())?;
    let load_seconds = start.elapsed().as_secs_f64();
    let s = scene.stats();
    let name = args.scene.as_ref().map_or("built-in Cornell box".into(), |p| p.display().to_string());
    println!("scene              {name} (loaded in {load_seconds:.3} s)");
    println!("meshes             {}", s.meshes);
    println!("objects            {}", s.objects);
    let moving = scene.instances.iter().filter(|i| i.motion.is_some()).count();
    match (moving, scene.settings.camera.motion.is_some()) {
        (0, false) => println!("instances          {}", s.instances),
        (_, camera) => println!(
            "instances          {} ({moving} moving over the shutter {:?}{})",
            s.instances,
            scene.settings.camera.shutter,
            if camera { "; the camera moves too" } else { "" }
        ),
    }
    println!("triangles          {} unique, {} instanced", s.unique_triangles, s.instanced_triangles);
    if s.curve_pieces > 0 {
        println!(
            "curve pieces       {} unique (counted among the triangles: one proxy each)",
            s.curve_pieces
        );
    }
    println!("emissive triangles {}", s.emissive_triangles);
    println!("lights             {} (plus area lights)", s.lights);
    println!("materials          {}", s.materials);
    println!(
        "textures           {} ({} images, MIP levels counted, {})",
        s.textures,
        s.texture_images,
        mib(s.texture_bytes)
    );
    let interiors = match s.subsurface_interiors {
        0 => String::new(),
        n => format!(", {n} of them subsurface interiors"),
    };
    println!("media              {} ({}{interiors})", s.media, mib(s.media_bytes));
    println!("bounds             {:?} .. {:?}", s.bounds_min.to_array(), s.bounds_max.to_array());
    let r = &scene.settings;
    println!(
        "render settings    {}x{}, {} spp, {}",
        r.film.resolution.x, r.film.resolution.y, r.spp, r.integrator
    );
    let bvh: SceneBvh = SceneBvh::build(&scene);
    let b = bvh.stats();
    let bvh_bytes = b.bytes as u64;
    println!("geometry memory    {}", mib(s.geometry_bytes));
    println!("BVH memory         {}", mib(bvh_bytes));
    println!("texture memory     {}", mib(s.texture_bytes));
    println!("media memory       {}", mib(s.media_bytes));
    println!(
        "memory estimate    {} (geometry + BVH + textures and media)",
        mib(s.geometry_bytes + bvh_bytes + s.texture_bytes + s.media_bytes)
    );
    println!(
        "BVH build          {:.1} ms ({} BLAS over {} triangles, TLAS over {} instances)",
        b.build_ms, b.blas_count, b.triangles, b.instances
    );
    let levels = [("BLAS (all)", &b.blas), ("TLAS", &b.tlas)];
    for (level, l) in levels {
        println!(
            "{level:<18} {} nodes, {} leaves, max depth {}, SAH cost {:.2}, {}",
            l.nodes,
            l.leaves,
            l.max_depth,
            l.sah_cost,
            mib(l.bytes as u64)
        );
    }
    if args.prepass {
        print_prepass(&scene, &args)?;
    }
    Ok(())
}

/// The hottest shares of the data the access-concentration curve reports.
const HOTTEST: [f64; 7] = [0.01, 0.02, 0.05, 0.10, 0.25, 0.50, 1.0];

/// Runs the prepass and prints the access-concentration curve (Jaroš et
/// al. 2021, Figure 4) and the placement it leads to.
fn print_prepass(scene: &Scene, args: &InfoArgs) -> Result<(), CliError> {
    let specs = args.devices.as_ref().map_or_else(|| vec![DeviceSpec::Cpu], |l| l.0.clone());
    let mut devices = crate::multi::open_devices(&specs, None, None)?;
    let scene = Arc::new(scene.clone());
    let options = RenderOptions::from_scene(&scene);
    let default = SharedSpec::default();
    let spec = SharedSpec { chunk_bytes: args.chunk_size.unwrap_or(default.chunk_bytes), ..default };
    let report = atoll_dist::shared::prepass(&mut devices, &scene, options.clone(), &spec)
        .map_err(|e| CliError::Runtime(e.to_string()))?;
    let chunks = report.layout.chunk_count();
    let reads: u64 = report.counts.iter().flatten().sum();
    let unread = (0..chunks).filter(|&c| report.counts.iter().all(|d| d[c] == 0));
    let unread_bytes: u64 = unread.map(|c| report.layout.chunk_len(c)).sum();
    println!(
        "prepass            {}x{}, 1 spp on {} device(s) in {:.3} s: {reads} reads of {} in {chunks} chunks of {}",
        options.resolution.x,
        options.resolution.y,
        devices.len(),
        report.prepass_seconds,
        fmt_bytes(report.layout.bytes()),
        fmt_bytes(report.layout.chunk_bytes),
    );
    let curve = report.concentration(&HOTTEST);
    let points: Vec<String> = HOTTEST
        .iter()
        .zip(&curve)
        .map(|(f, share)| format!("{:.0}%: {:.1}%", f * 100.0, share * 100.0))
        .collect();
    println!("hottest data       {} of reads", points.join(", "));
    println!(
        "never read         {:.1}% of the data",
        100.0 * unread_bytes as f64 / report.layout.bytes().max(1) as f64
    );
    Ok(())
}
