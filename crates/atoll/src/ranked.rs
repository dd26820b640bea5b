//! `atoll render --mpi`: every process `mpirun` started renders the frame
//! on its own devices (`--device` or `--devices`, which may differ per
//! rank with mpirun's `A : B` syntax), with its own copy of the scene.
//! Rank 0 hands out the waves as devices free up (nodes of unequal speed
//! finish together), sums the films, writes the image and prints every
//! rank's devices.
//!
//! Every step that can fail on one rank is followed by a vote, so that the
//! others stop with it instead of waiting for it forever.

use atoll_dist::ranks::Ranks;
use atoll_dist::{render_multi_with, Layout, MultiOutput};
use atoll_render::Device;

use crate::multi::{self, DeviceList};
use crate::render::{
    load_frame, multi_args, open_device, print_summary, progress_bar, set_waves_for_devices, Frame,
    RenderArgs, Run,
};
use crate::CliError;

pub fn run(args: RenderArgs) -> Result<(), CliError> {
    let ranks = Ranks::init().map_err(|e| CliError::Runtime(format!("--mpi: {e}")))?;
    let rank = ranks.rank();
    let Frame { scene, mut options, output, load_seconds } =
        together(&ranks, load_frame(&args), "load the scene")?;
    let RankDevices { mut devices, layout, description } =
        together(&ranks, rank_devices(&args, &scene, &mut options), "open their devices")?;
    if ranks.is_root() {
        eprintln!("{} ranks; rank 0: {description}", ranks.size());
    }

    let handout = ranks.waves();
    let bar = progress_bar(args.quiet || !ranks.is_root());
    let rendered = render_multi_with(
        &mut devices,
        &scene,
        options.clone(),
        &layout,
        args.ring_transport,
        args.warmup,
        Some(&handout),
        &mut |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        },
    )
    .map_err(|e| CliError::Runtime(e.to_string()));
    bar.finish_and_clear();
    let mut out = together(&ranks, rendered, "render their share")?;

    ranks.sum_films(&mut out.film);
    let rows = ranks.gather_text(&rank_rows(rank, &out));
    let rays: u64 = out.devices.iter().map(|d| d.stats.rays_traced + d.stats.shadow_rays_traced).sum();
    let rays = ranks.sum(rays);
    let devices_in_all = ranks.sum(out.devices.len() as u64);
    // The frame lasts until the last rank is done (they start together).
    let render_seconds = ranks.max(out.render_seconds);
    let run = Run {
        load_seconds: ranks.max(load_seconds),
        prepare_seconds: ranks.max(out.prepare_seconds),
        render_seconds,
        samples_per_second: out.film.pixel_count() as f64 * out.film.spp as f64 / render_seconds.max(1e-9),
        rays_per_second: rays as f64 / render_seconds.max(1e-9),
    };
    if !ranks.is_root() {
        return Ok(());
    }
    out.film.write(&output).map_err(|e| CliError::Runtime(e.to_string()))?;
    print!("rank  {}", multi::device_table_header());
    print!("{}", rows.concat());
    let on = format!("{} ranks ({devices_in_all} devices)", ranks.size());
    print_summary(&output, &options, &on, run);
    Ok(())
}

/// This rank's devices, how they share the scene, and a line about them.
struct RankDevices {
    devices: Vec<Box<dyn Device>>,
    layout: Layout,
    description: String,
}

fn rank_devices(
    args: &RenderArgs,
    scene: &std::sync::Arc<atoll_scene::Scene>,
    options: &mut atoll_render::RenderOptions,
) -> Result<RankDevices, CliError> {
    if let Some(DeviceList(specs)) = &args.devices {
        set_waves_for_devices(args, specs, options);
        let (devices, layout) = multi::setup(scene, options, &multi_args(args, specs))?;
        let description = format!("{} devices", devices.len());
        return Ok(RankDevices { devices, layout, description });
    }
    let (selected, more) = open_device(args, scene, options)?;
    let description = match more.len() {
        0 => selected.description.clone(),
        n => format!("{} x {} wavefronts", selected.description, n + 1),
    };
    let mut devices = vec![selected.device];
    devices.extend(more);
    Ok(RankDevices { devices, layout: Layout::Replicate, description })
}

/// This rank's rows of the device table, each led by the rank.
fn rank_rows(rank: usize, out: &MultiOutput) -> String {
    multi::device_rows(out).lines().map(|row| format!("{rank:>4}  {row}\n")).collect()
}

/// `result` if every rank got that far, else an error on every rank (a
/// collective: every rank calls it at the same point). Rank 0's error
/// gives every failed rank's own message: mpirun stops the job as soon as
/// one process exits with an error, so the others might not get to print
/// theirs. It is an input error (exit 2) when any rank's was.
fn together<T>(ranks: &Ranks, result: Result<T, CliError>, what: &str) -> Result<T, CliError> {
    let input = matches!(result, Err(CliError::Input(_)));
    let [failed, inputs] = ranks.sums([result.is_err() as u64, input as u64]);
    if failed == 0 {
        return result;
    }
    let rank = ranks.rank();
    let mine = match &result {
        Ok(_) => String::new(),
        Err(CliError::Input(message) | CliError::Runtime(message)) => format!("rank {rank}: {message}"),
    };
    let all = ranks.gather_text(&mine);
    let message = if ranks.is_root() {
        let failures: Vec<&str> = all.iter().map(String::as_str).filter(|m| !m.is_empty()).collect();
        format!("{failed} of {} ranks could not {what}:\n  {}", ranks.size(), failures.join("\n  "))
    } else if result.is_err() {
        mine
    } else {
        format!("rank {rank}: stopping: {failed} rank(s) could not {what}")
    };
    Err(if inputs > 0 { CliError::Input(message) } else { CliError::Runtime(message) })
}
