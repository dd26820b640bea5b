//! `atoll info`.

use std::path::PathBuf;
use std::time::Instant;

use atoll_bvh::SceneBvh;
use clap::Args;

use crate::load::load_scene;
use crate::CliError;

#[derive(Args)]
pub struct InfoArgs {
    /// Scene file (.pbrt, .obj, .gltf/.glb, .ply, .off) or a generated `landscape:GROWTH[:SEED]`;
    /// the built-in Cornell box when omitted.
    pub scene: Option<PathBuf>,
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
    println!("instances          {}", s.instances);
    println!("triangles          {} unique, {} instanced", s.unique_triangles, s.instanced_triangles);
    println!("emissive triangles {}", s.emissive_triangles);
    println!("lights             {} (plus area lights)", s.lights);
    println!("materials          {}", s.materials);
    println!("textures           {} ({} images, {})", s.textures, s.texture_images, mib(s.texture_bytes));
    println!("bounds             {:?} .. {:?}", s.bounds_min.to_array(), s.bounds_max.to_array());
    let r = &scene.settings;
    println!(
        "render settings    {}x{}, {} spp, {:?}",
        r.film.resolution.x, r.film.resolution.y, r.spp, r.integrator
    );
    let bvh: SceneBvh = SceneBvh::build(&scene);
    let b = bvh.stats();
    let bvh_bytes = b.bytes as u64;
    println!("geometry memory    {}", mib(s.geometry_bytes));
    println!("BVH memory         {}", mib(bvh_bytes));
    println!("texture memory     {}", mib(s.texture_bytes));
    println!(
        "memory estimate    {} (geometry + BVH + textures)",
        mib(s.geometry_bytes + bvh_bytes + s.texture_bytes)
    );
    println!(
        "BVH build          {:.1} ms ({} BLAS over {} triangles, TLAS over {} instances)",
        b.build_ms, b.blas_count, b.triangles, b.instances
    );
    for (level, l) in [("BLAS (all)", &b.blas), ("TLAS", &b.tlas)] {
        println!(
            "{level:<18} {} nodes, {} leaves, max depth {}, SAH cost {:.2}, {}",
            l.nodes,
            l.leaves,
            l.max_depth,
            l.sah_cost,
            mib(l.bytes as u64)
        );
    }
    Ok(())
}
