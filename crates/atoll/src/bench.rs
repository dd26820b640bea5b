//! `atoll bench`: BVH build and traversal speed on a generated scene, and
//! path-tracing speed on the Cornell box.

use std::sync::Arc;

use atoll_render::{render, CpuDevice, RenderOptions};
use atoll_scene::IntegratorSettings;
use clap::Args;
use glam::UVec2;

use crate::CliError;

#[derive(Args)]
pub struct BenchArgs {
    /// Triangles in the generated traversal scene.
    #[arg(long, default_value_t = 2_000_000)]
    pub triangles: usize,
    /// Samples per pixel for the Cornell-box path-tracing run.
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// Skip the traversal benchmark.
    #[arg(long)]
    pub no_traversal: bool,
}

pub fn run(args: BenchArgs) -> Result<(), CliError> {
    if !args.no_traversal {
        traversal(&args)?;
    }
    // Path tracing: the diffuse Cornell box at 512², 15 bounces, no Russian
    // roulette (the settings issue 3's GPU target is stated in).
    let scene = Arc::new(atoll_scene::cornell::builtin_cornell_box());
    let mut options = RenderOptions::from_scene(&scene);
    options.resolution = UVec2::new(512, 512);
    options.spp = args.spp;
    options.integrator = IntegratorSettings::Path { max_depth: 15 };
    options.russian_roulette = false;
    let mut device = CpuDevice::new();
    let out =
        render(&mut device, &scene, options, &mut |_, _| {}).map_err(|e| CliError::Runtime(e.to_string()))?;
    println!(
        "path tracing  cornell box 512x512, {} spp, depth 15, no RR: {:.3} M samples/s, {:.2} M rays/s ({:.2} s, {} threads)",
        args.spp,
        out.samples_per_second() / 1e6,
        out.rays_per_second() / 1e6,
        out.render_seconds,
        device.threads()
    );
    Ok(())
}

fn traversal(_args: &BenchArgs) -> Result<(), CliError> {
    Ok(())
}
