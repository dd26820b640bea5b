//! `atoll render --mpi`: every process `mpirun` started renders the frame
//! on its own devices (`--device` or `--devices`, which may differ per
//! rank with mpirun's `A : B` syntax), with its own copy of the scene.
//! Rank 0 hands out the waves as devices free up (nodes of unequal speed
//! finish together), sums the films, writes the image and prints every
//! rank's devices.
//!
//! Every step that can fail on one rank is followed by a vote, so that the
//! others stop with it instead of waiting for it forever.

use std::sync::Arc;

use atoll_bvh::{part_bytes, ByteModel, ScenePart};
use atoll_cuda::error::fmt_bytes;
use atoll_dist::placement::widest_model;
use atoll_dist::placement::{scene_budget, Sharing};
use atoll_dist::ranks::{RankRing, Ranks};
use atoll_dist::{
    min_parts, render_multi_with, Layout, MultiFrame, MultiOutput, Partition, RingPeers, Shared,
};
use atoll_render::{Device, RenderOptions};
use atoll_scene::Scene;

use crate::load::LoadReport;
use crate::multi::{self, DeviceList, DeviceSpec};
use crate::render::{
    gpu_wavefronts, load_frame, multi_args, open_device, print_summary, progress_bar, set_waves_for_devices,
    Frame, RenderArgs, Run,
};
use crate::CliError;

pub fn run(args: RenderArgs) -> Result<(), CliError> {
    let ranks = Ranks::init().map_err(|e| CliError::Runtime(format!("--mpi: {e}")))?;
    let result = render_on_ranks(&ranks, args);
    // On a failure rank 0 knows every rank's reason (`together`): it says
    // it first, then every rank stops with its exit code. mpirun stops the
    // job at the first process that exits with an error, so a rank leaving
    // before rank 0 has spoken could silence it.
    let code = match &result {
        Ok(()) => None,
        Err(CliError::Input(_)) => Some(2),
        Err(CliError::Runtime(_)) => Some(1),
        Err(CliError::Reported(code)) => Some(*code),
        Err(CliError::Internal(_)) => Some(70),
    };
    if let (true, Err(CliError::Input(message) | CliError::Runtime(message) | CliError::Internal(message))) =
        (ranks.is_root(), &result)
    {
        eprintln!("error: {message}");
    }
    ranks.wait_for_all();
    code.map_or(Ok(()), |code| Err(CliError::Reported(code)))
}

fn render_on_ranks(ranks: &Ranks, mut args: RenderArgs) -> Result<(), CliError> {
    let rank = ranks.rank();
    // `auto` and `cuda:local` take the GPU of this rank's place on its node.
    args.device.local_rank = ranks.local_rank();
    let Frame { scene, mut options, output, load } =
        together(ranks, load_frame(&args, None), "load the scene")?;
    let RankDevices { mut devices, layout, description } =
        together(ranks, rank_devices(ranks.is_root(), &args, &scene, &mut options), "open their devices")?;
    let ring = together(ranks, rank_ring(ranks, &args, &scene, &options, &mut devices), "plan rings")?;
    // (Every rank votes, whether it adds wavefronts or not.)
    let one_device = args.devices.as_ref().is_none_or(|d| d.0.len() == 1);
    let more = match ring.is_none() && one_device {
        true => add_wavefronts(&args, &scene, &options, &mut devices),
        false => Ok(()),
    };
    together(ranks, more, "open more wavefronts")?;
    // Ranks with several devices placing the scene themselves: rank 0's
    // own view, written by `multi::place_on`.
    let places_itself = args.devices.as_ref().is_some_and(|d| d.0.len() > 1) && ring.is_none();
    let ownership = match (ranks.is_root(), places_itself, &args.ownership) {
        (true, false, Some(path)) => {
            multi::write_ownership(&scene, &options, ring.as_ref().map(|(_, p)| p), path)
        }
        _ => Ok(()),
    };
    together(ranks, ownership, "write the ownership view")?;
    let layout = match &ring {
        Some((rings, partition)) => {
            let place = rings[0].place();
            Layout::Ring {
                parts: vec![partition.parts[place.member].clone()],
                islands: rings.len(),
                order: place.order,
            }
        }
        None => layout,
    };
    let links: Vec<&(dyn RingPeers + Sync)> = match &ring {
        Some((rings, _)) => rings.iter().map(|r| r as &(dyn RingPeers + Sync)).collect(),
        None => Vec::new(),
    };
    if ranks.is_root() {
        eprintln!("{} ranks; rank 0: {description}", ranks.size());
    }

    let handout = ranks.waves();
    let mut bar = progress_bar(args.quiet || !ranks.is_root());
    let frame = MultiFrame {
        layout: &layout,
        transport: args.ring_transport,
        warmup: args.warmup,
        shared: Some(Shared { handout: &handout, rings: &links }),
    };
    let rendered = render_multi_with(&mut devices, &scene, options.clone(), &frame, &mut |done, total| {
        bar.update(done, total)
    })
    .map_err(|e| CliError::Runtime(e.to_string()));
    bar.finish_and_clear();
    let mut out = together(ranks, rendered, "render their share")?;

    let summing = std::time::Instant::now();
    ranks.sum_films(&mut out.film);
    tracing::info!("films summed over MPI in {:.4} s", summing.elapsed().as_secs_f64());
    let rows = ranks.gather_text(&rank_rows(rank, &out));
    let rays: u64 = out.devices.iter().map(|d| d.stats.rays_traced + d.stats.shadow_rays_traced).sum();
    let rays = ranks.sum(rays);
    let devices_in_all = ranks.sum(out.devices.len() as u64);
    // The frame lasts until the last rank is done (they start together).
    let render_seconds = ranks.max(out.render_seconds);
    let run = Run {
        load: LoadReport { seconds: ranks.max(load.seconds), ..load },
        prepare_seconds: ranks.max(out.prepare_seconds),
        upload_seconds: 0.0,
        bvh_build_seconds: 0.0,
        render_seconds,
        samples_per_second: out.film.pixel_count() as f64 * out.film.spp as f64 / render_seconds.max(1e-9),
        rays_per_second: rays as f64 / render_seconds.max(1e-9),
    };
    if !ranks.is_root() {
        return Ok(());
    }
    crate::render::write_image(&out.film, &output)?;
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
    root: bool,
    args: &RenderArgs,
    scene: &Arc<Scene>,
    options: &mut RenderOptions,
) -> Result<RankDevices, CliError> {
    match &args.devices {
        Some(DeviceList(specs)) if specs.len() > 1 && rings_of_ranks(args) => {
            // Every device holds this rank's part of the rings (`rank_ring`).
            set_waves_for_devices(args, specs, options);
            let devices = multi::open_devices(specs, args.device.device_memory, args.threads)?;
            let description = format!("{} devices", devices.len());
            Ok(RankDevices { devices, layout: Layout::Replicate, description })
        }
        Some(DeviceList(specs)) if specs.len() > 1 => {
            set_waves_for_devices(args, specs, options);
            // Rank 0 alone writes the ownership view.
            let several = multi::MultiArgs {
                ownership: args.ownership.as_deref().filter(|_| root),
                ..multi_args(args, specs)
            };
            let devices = multi::open_devices(specs, args.device.device_memory, args.threads)?;
            let multi::Placed { devices, layout, .. } = multi::place_on(devices, scene, options, &several)?;
            let description = format!("{} devices", devices.len());
            Ok(RankDevices { devices, layout, description })
        }
        Some(DeviceList(specs)) => {
            set_waves_for_devices(args, specs, options);
            let devices = multi::open_devices(specs, args.device.device_memory, args.threads)?;
            let description = devices[0].name();
            Ok(RankDevices { devices, layout: Layout::Replicate, description })
        }
        None => {
            let selected = open_device(args, scene, options)?;
            Ok(RankDevices {
                devices: vec![selected.device],
                layout: Layout::Replicate,
                description: selected.description,
            })
        }
    }
}

/// A GPU rank holding the whole scene renders with the further wavefronts
/// `--streams` asks for, sharing its copy.
fn add_wavefronts(
    args: &RenderArgs,
    scene: &Arc<Scene>,
    options: &RenderOptions,
    devices: &mut Vec<Box<dyn Device>>,
) -> Result<(), CliError> {
    let more = gpu_wavefronts(devices[0].as_ref(), args, scene, options)?;
    devices.extend(more);
    Ok(())
}

/// Whether `--ring-ranks` asks for rings of ranks (of 2 or more).
fn rings_of_ranks(args: &RenderArgs) -> bool {
    args.ring_ranks.is_some_and(|k| k > 1)
}

/// The rings of ranks this rank belongs to and the partition of their
/// parts, when `--ring-ranks` asks for rings or the scene does not fit the
/// smallest rank's device (`None`: every rank holds the whole scene, or
/// plans its own `--devices`). Without `--ring-ranks`, rings of ranks need
/// one device per rank (`--device`, or one listed in `--devices`). Every
/// device of a rank holds the rank's part, and GPUs add the wavefronts
/// `--streams` asks for; each of them is the member of a ring of its own
/// over the same ranks (islands; as many as every rank has). Every rank
/// calls it at the same point (collectives inside).
fn rank_ring(
    ranks: &Ranks,
    args: &RenderArgs,
    scene: &Arc<Scene>,
    options: &RenderOptions,
    devices: &mut Vec<Box<dyn Device>>,
) -> Result<Option<(Vec<RankRing>, Partition)>, CliError> {
    // What every rank must agree on, gathered first (collectives), so that
    // every rank then plans the same rings. Ranks with `--devices` plan
    // their own: they only say so.
    let alone = args.devices.as_ref().is_none_or(|d| d.0.len() == 1) || rings_of_ranks(args);
    // A device with memory of its own (a GPU) plans with the GPU byte model.
    let gpu = devices.iter().any(|d| d.free_memory().is_some());
    // (Devices of one GPU share its copy of the part.)
    let budget = match alone {
        true => scene_budget(devices, scene, args.device.device_memory, options, Sharing::Scene),
        false => None,
    };
    let (smallest, _) = ranks.extremes(budget.unwrap_or(u64::MAX));
    let [gpus, planning_alone] = ranks.sums([gpu as u64, alone as u64]);
    let cpus = ranks.size() as u64 - gpus;
    let kinds: Vec<DeviceSpec> = [(cpus > 0, DeviceSpec::Cpu), (gpus > 0, DeviceSpec::Cuda(0))]
        .into_iter()
        .filter_map(|(present, kind)| present.then_some(kind))
        .collect();
    let model = byte_model(&kinds);
    let whole = part_bytes(scene, &ScenePart::whole(scene), &model);
    let scenes = ranks.extremes(whole);
    let asked = ranks.extremes(args.ring_ranks.map_or(0, u64::from));

    if scenes.0 != scenes.1 {
        return Err(CliError::Input(
            "the ranks loaded different scenes: every rank needs the same one".into(),
        ));
    }
    if asked.0 != asked.1 {
        return Err(CliError::Input("--ring-ranks differs between ranks: every rank needs the same".into()));
    }
    let n = ranks.size();
    if planning_alone < n as u64 {
        // Some rank plans its own devices: no rings of ranks.
        return match asked.1 {
            0 | 1 => Ok(None),
            _ => Err(CliError::Input("--ring-ranks: rings of ranks need one device on every rank".into())),
        };
    }
    let budget = (smallest != u64::MAX).then_some(smallest);
    let k = match (asked.0 as usize, budget) {
        (0, None) => 1,
        (0, Some(b)) if whole <= b => 1,
        // The fewest parts that fit, made a divisor of the ranks.
        (0, Some(b)) => min_parts(scene, &model, b, n)
            .and_then(|k| (k..=n).find(|d| n.is_multiple_of(*d)))
            .ok_or_else(|| {
            CliError::Runtime(format!(
                "the scene ({}) does not fit {n} ranks whose smallest device holds {}",
                fmt_bytes(whole),
                fmt_bytes(b)
            ))
        })?,
        (k, _) if !n.is_multiple_of(k) => {
            return Err(CliError::Input(format!("--ring-ranks {k}: must divide the {n} ranks")));
        }
        (k, _) => k,
    };
    if k == 1 {
        return Ok(None);
    }
    let (partition, kind) = atoll_dist::placement::partition_ring(
        scene,
        k,
        &model,
        budget,
        options.resolution,
        args.partitioning,
        None,
    )
    .map_err(|e| CliError::Runtime(e.to_string()))?;
    let islands = ring_wavefronts(ranks, args, scene, options, &partition.parts[ranks.rank() % k], devices)?;
    let mut rings =
        ranks.rings(k, args.ring_order, islands).expect("k divides the ranks: every rank is in a ring");
    let wanted = args.ring_transport != Some(atoll_dist::Transport::Host);
    // (In the same order on every rank: joining a ring's link is collective.)
    let transports: Vec<Result<&str, String>> = rings
        .iter_mut()
        .zip(devices.iter_mut())
        .map(|(ring, device)| ring.connect_devices(device.as_mut(), wanted))
        .collect();
    if ranks.is_root() {
        match transports.iter().find(|t| t.is_err()).unwrap_or(&transports[0]) {
            Ok(name) => eprintln!("ring transport: {name}, device to device"),
            Err(why) => eprintln!("note: ring queues go through host memory: {why}"),
        }
        let sizes: Vec<String> = partition.bytes.iter().map(|&b| fmt_bytes(b)).collect();
        eprintln!("partition: {kind}");
        let islands = multi::islands_text(n / k * islands);
        eprintln!("strategy: rings of {k} ranks ({islands}); parts {}", sizes.join(", "));
    }
    Ok(Some((rings, partition)))
}

/// Adds beside this rank's devices (each holding `part`) the further
/// wavefronts `--streams` asks for, and keeps as many devices as every
/// rank has: the islands of its rings. A collective; a rank that cannot
/// open them fails every rank.
fn ring_wavefronts(
    ranks: &Ranks,
    args: &RenderArgs,
    scene: &Scene,
    options: &RenderOptions,
    part: &ScenePart,
    devices: &mut Vec<Box<dyn Device>>,
) -> Result<usize, CliError> {
    let more: Result<Vec<Box<dyn Device>>, _> = devices.iter().try_fold(Vec::new(), |mut more, device| {
        more.extend(atoll_dist::placement::more_wavefronts_beside(
            device.as_ref(),
            args.waves.streams(),
            part_bytes(scene, part, &device.byte_model()),
            options,
            args.device.device_memory,
        )?);
        Ok::<_, atoll_render::DeviceError>(more)
    });
    let mine = more.as_ref().map_or(0, |m| (devices.len() + m.len()) as u64);
    let (fewest, _) = ranks.extremes(mine);
    match more {
        Err(e) => Err(CliError::Runtime(e.to_string())),
        Ok(_) if fewest == 0 => Err(CliError::Runtime("another rank could not open its wavefronts".into())),
        Ok(more) => {
            devices.extend(more);
            devices.truncate(fewest as usize);
            Ok(fewest as usize)
        }
    }
}

/// This rank's rows of the device table, each led by the rank.
fn rank_rows(rank: usize, out: &MultiOutput) -> String {
    multi::device_rows(out).lines().map(|row| format!("{rank:>4}  {row}\n")).collect()
}

/// `result` if every rank got that far, else an error on every rank (a
/// collective: every rank calls it at the same point). Rank 0's error
/// gives every failed rank's own message (only rank 0 speaks, see `run`).
/// It is an input error (exit 2) when any rank's was.
fn together<T>(ranks: &Ranks, result: Result<T, CliError>, what: &str) -> Result<T, CliError> {
    let input = matches!(result, Err(CliError::Input(_)));
    let [failed, inputs] = ranks.sums([result.is_err() as u64, input as u64]);
    if failed == 0 {
        return result;
    }
    let mine = match &result {
        Ok(_) => String::new(),
        Err(CliError::Input(message) | CliError::Runtime(message) | CliError::Internal(message)) => {
            message.clone()
        }
        Err(CliError::Reported(code)) => format!("failed (exit code {code})"),
    };
    let all = ranks.gather_text(&mine);
    let message = if ranks.is_root() {
        // The same failure on several ranks is said once, with their ranks.
        let mut failures: Vec<(Vec<usize>, &str)> = Vec::new();
        for (r, m) in all.iter().enumerate().filter(|(_, m)| !m.is_empty()) {
            match failures.iter_mut().find(|(_, seen)| *seen == m) {
                Some((ranks, _)) => ranks.push(r),
                None => failures.push((vec![r], m)),
            }
        }
        let lines: Vec<String> = failures
            .iter()
            .map(|(rs, m)| {
                let rs: Vec<String> = rs.iter().map(usize::to_string).collect();
                format!("rank {}: {m}", rs.join(", "))
            })
            .collect();
        format!("{failed} of {} ranks could not {what}:\n  {}", ranks.size(), lines.join("\n  "))
    } else {
        // Rank 0 says it for all (see `run`).
        String::new()
    };
    Err(if inputs > 0 { CliError::Input(message) } else { CliError::Runtime(message) })
}

/// The byte model partitioning uses: the widest of the device kinds
/// present, so that every device can hold any part (for ranks, which plan
/// from the kinds every rank has before opening devices).
fn byte_model(specs: &[DeviceSpec]) -> ByteModel {
    let cpu = specs.contains(&DeviceSpec::Cpu).then_some(ByteModel::CPU);
    let gpu = specs.iter().any(|s| s.ordinal().is_some()).then(atoll_cuda::scene::byte_model);
    widest_model(cpu.into_iter().chain(gpu))
}
