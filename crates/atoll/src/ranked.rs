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
use atoll_dist::ranks::{FilmLink, RankRing, Ranks};
use atoll_dist::{
    min_parts, render_multi_with, Layout, MultiFrame, MultiOutput, Partition, RingPeers, Shared,
};
use atoll_render::{Device, RenderOptions};
use atoll_scene::Scene;
use glam::UVec2;

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
    let films = link_films(ranks, &args, devices[0].as_mut(), options.resolution);
    // Ranks with several devices placing the scene themselves: rank 0's
    // own view, written by `multi::place_on`.
    let places_itself = args.devices.as_ref().is_some_and(|d| d.0.len() > 1) && ring.is_none();
    let ownership = match (ranks.is_root(), places_itself, &args.ownership) {
        (true, false, Some(path)) => {
            multi::write_ownership(&scene, &options, ring.as_ref().map(|r| &r.partition), path)
        }
        _ => Ok(()),
    };
    together(ranks, ownership, "write the ownership view")?;
    let layout = match &ring {
        Some(RankRings { rings, parts, .. }) => {
            Layout::Ring { parts: parts.clone(), islands: rings.len() / parts.len(), order: args.ring_order }
        }
        None => layout,
    };
    let links: Vec<&(dyn RingPeers + Sync)> = match &ring {
        Some(RankRings { rings, .. }) => rings.iter().map(|r| r as &(dyn RingPeers + Sync)).collect(),
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
    let summed = ranks.sum_films(&mut out.film, films.as_ref().map(|link| (link, devices[0].as_mut())));
    together(ranks, summed.map_err(|e| CliError::Runtime(e.to_string())), "sum their films")?;
    let over = films.as_ref().map_or("MPI", |link| link.name());
    tracing::info!("films summed over {over} in {:.4} s", summing.elapsed().as_secs_f64());
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
    crate::render::write_image(&out.film, &options, &output)?;
    print!("rank  {}", multi::device_table_header());
    print!("{}", rows.concat());
    let on = format!("{} ranks ({devices_in_all} devices)", ranks.size());
    print_summary(&output, &options, &on, run);
    Ok(())
}

/// Collective: the ranks' link for summing films device to device, where
/// every rank's first device offers one and `--film-transport` does not
/// say host. Rank 0 says which way films go when its device could link.
fn link_films(
    ranks: &Ranks,
    args: &RenderArgs,
    first: &mut dyn Device,
    resolution: UVec2,
) -> Option<FilmLink> {
    let could = first.process_transport().is_some();
    let link = ranks.link_films(first, args.film_transport != Some(atoll_dist::Transport::Host), resolution);
    if ranks.is_root() && could {
        match &link {
            Ok(link) => eprintln!("films: summed over {}, device to device", link.name()),
            Err(why) => eprintln!("note: films are summed through host memory: {why}"),
        }
    }
    link.ok()
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

/// This rank's members of rings of ranks, and the parts they hold.
struct RankRings {
    /// Island by island, this rank's members of each (see [`Ranks::rings`]).
    rings: Vec<RankRing>,
    /// The rings' partition: every member's part.
    partition: Partition,
    /// The parts this rank's members hold, in member order.
    parts: Vec<ScenePart>,
}

/// The rings of ranks this rank belongs to and the partition of their
/// parts, when `--ring-ranks` asks for rings or the scene does not fit the
/// smallest rank's device (`None`: every rank holds the whole scene, or
/// plans its own `--devices`). Without `--ring-ranks`, rings of ranks need
/// one device per rank (`--device`, or one listed in `--devices`). With it,
/// a rank's `--devices` split the rank's share of the scene (two-level
/// rings: a queue visits a rank's devices, then the next rank's) in
/// groups of `--ring-size` (default: the fewest that fit), its further
/// groups and the wavefronts `--streams` adds to GPUs each the member of a
/// ring of its own over the same ranks (islands; as many as every rank
/// has). Every rank calls it at the same point (collectives inside).
fn rank_ring(
    ranks: &Ranks,
    args: &RenderArgs,
    scene: &Arc<Scene>,
    options: &RenderOptions,
    devices: &mut Vec<Box<dyn Device>>,
) -> Result<Option<RankRings>, CliError> {
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
    // Devices per rank, and the `--ring-size` every rank asked for.
    let (fewest_devices, _) = ranks.extremes(devices.len() as u64);
    let sizes = ranks.extremes(args.ring_size.unwrap_or(0) as u64);

    if scenes.0 != scenes.1 {
        return Err(CliError::Input(
            "the ranks loaded different scenes: every rank needs the same one".into(),
        ));
    }
    if asked.0 != asked.1 {
        return Err(CliError::Input("--ring-ranks differs between ranks: every rank needs the same".into()));
    }
    if sizes.0 != sizes.1 {
        return Err(CliError::Input("--ring-size differs between ranks: every rank needs the same".into()));
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
    // Rings of ranks use a rank's further devices only when asked.
    let per_rank_devices = if rings_of_ranks(args) { fewest_devices as usize } else { 1 };
    let fits = |most: usize| match budget {
        None => Some(1),
        Some(b) if whole <= b => Some(1),
        Some(b) => min_parts(scene, &model, b, most),
    };
    let shape = RingShape::choose(
        n,
        per_rank_devices,
        (asked.0 as usize, sizes.0 as usize),
        fits(n * per_rank_devices),
    )
    .map_err(|e| match (e, budget) {
        (RingShapeError::Input(message), _) => CliError::Input(message),
        (RingShapeError::DoesNotFit, b) => CliError::Runtime(format!(
            "the scene ({}) does not fit {n} ranks whose smallest device holds {}",
            fmt_bytes(whole),
            fmt_bytes(b.unwrap_or(0))
        )),
    })?;
    let RingShape { ranks: k, per_rank } = shape;
    if k * per_rank == 1 {
        return Ok(None);
    }
    let (partition, kind) = atoll_dist::placement::partition_ring(
        scene,
        k * per_rank,
        &model,
        budget,
        options.resolution,
        args.partitioning,
        None,
    )
    .map_err(|e| CliError::Runtime(e.to_string()))?;
    let first = ranks.rank() % k * per_rank;
    let parts = partition.parts[first..first + per_rank].to_vec();
    let islands = ring_wavefronts(ranks, args, scene, options, &parts, devices)?;
    let mut rings = ranks
        .rings(k, per_rank, args.ring_order, islands)
        .expect("k divides the ranks: every rank is in a ring");
    let wanted = args.ring_transport != Some(atoll_dist::Transport::Host);
    // (In the same order on every rank: joining a ring's link is collective.)
    let transports: Vec<Result<&str, String>> = rings
        .chunks_mut(per_rank)
        .zip(devices.chunks_mut(per_rank))
        .map(|(members, devices)| RankRing::connect_devices(members, devices, wanted))
        .collect();
    if ranks.is_root() {
        match transports.iter().find(|t| t.is_err()).unwrap_or(&transports[0]) {
            Ok(name) => eprintln!("ring transport: {name}, device to device"),
            Err(why) => eprintln!("note: ring queues go through host memory: {why}"),
        }
        let sizes: Vec<String> = partition.bytes.iter().map(|&b| fmt_bytes(b)).collect();
        eprintln!("partition: {kind}");
        let islands = multi::islands_text(n / k * islands);
        let members = match per_rank {
            1 => String::new(),
            d => format!(" × {d} devices"),
        };
        eprintln!("strategy: rings of {k} ranks{members} ({islands}); parts {}", sizes.join(", "));
    }
    Ok(Some(RankRings { rings, partition, parts }))
}

/// How rings of ranks are made: ranks per ring, and members (devices) per
/// rank, each holding one part.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct RingShape {
    ranks: usize,
    per_rank: usize,
}

#[derive(Debug, PartialEq, Eq)]
enum RingShapeError {
    Input(String),
    DoesNotFit,
}

impl RingShape {
    /// The rings for `n` ranks with `devices` each (the fewest any rank
    /// has), given `--ring-ranks` and `--ring-size` (`asked`, 0 where not
    /// given) and the fewest parts that fit a device (`None`: none fits):
    /// what was asked, else the fewest parts that fit, made a divisor of
    /// the ranks, then of the devices (every rank of a ring in it, every
    /// member of a rank holding one part).
    fn choose(
        n: usize,
        devices: usize,
        (asked_ranks, asked_size): (usize, usize),
        fewest_parts: Option<usize>,
    ) -> Result<RingShape, RingShapeError> {
        if asked_ranks > 1 && !n.is_multiple_of(asked_ranks) {
            return Err(RingShapeError::Input(format!(
                "--ring-ranks {asked_ranks}: must divide the {n} ranks"
            )));
        }
        if asked_size > devices {
            return Err(RingShapeError::Input(format!(
                "--ring-size {asked_size}: more than the {devices} devices of a rank"
            )));
        }
        let ranks = match (asked_ranks, fewest_parts) {
            (0, None) => return Err(RingShapeError::DoesNotFit),
            (0, Some(fewest)) => {
                (fewest.min(n)..=n).find(|k| n.is_multiple_of(*k)).ok_or(RingShapeError::DoesNotFit)?
            }
            (k, _) => k,
        };
        // Asked-for rings that do not fit fail when their parts are placed.
        let per_rank = match (asked_size, fewest_parts) {
            (0, None) => devices,
            (0, Some(fewest)) => {
                (1..=devices).find(|d| ranks * d >= fewest && devices.is_multiple_of(*d)).unwrap_or(devices)
            }
            (d, _) => d,
        };
        match ranks * per_rank >= fewest_parts.unwrap_or(usize::MAX) || asked_ranks > 0 {
            true => Ok(RingShape { ranks, per_rank }),
            false => Err(RingShapeError::DoesNotFit),
        }
    }
}

/// Groups this rank's devices (device i holding `parts[i mod D]`) into
/// islands of D, adding beside each device the further wavefronts
/// `--streams` asks for, island by island, and keeps as many islands as
/// every rank has. A collective; a rank that cannot open them fails every
/// rank. Returns the islands.
fn ring_wavefronts(
    ranks: &Ranks,
    args: &RenderArgs,
    scene: &Scene,
    options: &RenderOptions,
    parts: &[ScenePart],
    devices: &mut Vec<Box<dyn Device>>,
) -> Result<usize, CliError> {
    let per_rank = parts.len();
    let more: Result<Vec<Vec<Box<dyn Device>>>, _> = devices
        .iter()
        .enumerate()
        .map(|(i, device)| {
            atoll_dist::placement::more_wavefronts_beside(
                device.as_ref(),
                args.waves.streams(),
                part_bytes(scene, &parts[i % per_rank], &device.byte_model()),
                options,
                args.device.device_memory,
            )
        })
        .collect();
    let grouped = more.map(|more| islands_of(std::mem::take(devices), more, per_rank));
    let mine = grouped.as_ref().map_or(0, |g| (g.len() / per_rank) as u64);
    let (fewest, _) = ranks.extremes(mine);
    match grouped {
        Err(e) => Err(CliError::Runtime(e.to_string())),
        Ok(_) if fewest == 0 => Err(CliError::Runtime("another rank could not open its wavefronts".into())),
        Ok(mut grouped) => {
            grouped.truncate(fewest as usize * per_rank);
            *devices = grouped;
            Ok(fewest as usize)
        }
    }
}

/// `devices` in islands of `per_rank` (device i is member i mod
/// `per_rank` of island i / `per_rank`), each device followed by its
/// further wavefronts `more[i]` (islands of their own): island by island,
/// as many as the device with fewest wavefronts of each group allows; the
/// devices of an incomplete last group are left out.
fn islands_of<T>(devices: Vec<T>, more: Vec<Vec<T>>, per_rank: usize) -> Vec<T> {
    let mut out = Vec::new();
    let mut pairs = devices.into_iter().zip(more).peekable();
    while pairs.peek().is_some() {
        let mut group: Vec<(T, Vec<T>)> = pairs.by_ref().take(per_rank).collect();
        if group.len() < per_rank {
            break;
        }
        let extra = group.iter().map(|(_, m)| m.len()).min().unwrap_or(0);
        let mut columns: Vec<std::vec::IntoIter<T>> = Vec::with_capacity(per_rank);
        for (device, mut more) in group.drain(..) {
            more.truncate(extra);
            out.push(device);
            columns.push(more.into_iter());
        }
        for _ in 0..extra {
            out.extend(columns.iter_mut().map(|c| c.next().expect("as many as `extra`")));
        }
    }
    out
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

#[cfg(test)]
mod tests {
    use super::*;

    fn shape(ranks: usize, per_rank: usize) -> Result<RingShape, RingShapeError> {
        Ok(RingShape { ranks, per_rank })
    }

    /// Rings take the fewest ranks whose parts fit, then the fewest of a
    /// rank's devices; what was asked for is kept, and what cannot be is
    /// refused.
    #[test]
    fn rings_of_ranks_take_the_fewest_members_that_fit() {
        // A scene that fits one device: no ring.
        assert_eq!(RingShape::choose(4, 2, (0, 0), Some(1)), shape(1, 1));
        // Three parts over four ranks: rings of four (a divisor).
        assert_eq!(RingShape::choose(4, 1, (0, 0), Some(3)), shape(4, 1));
        // More parts than ranks: every rank, and its devices split its part.
        assert_eq!(RingShape::choose(2, 4, (0, 0), Some(3)), shape(2, 2));
        assert_eq!(RingShape::choose(2, 4, (0, 0), Some(5)), shape(2, 4));
        // Asked for: rings of 2 ranks, each rank's part fitting one device
        // (the other devices are islands), or split as asked.
        assert_eq!(RingShape::choose(4, 2, (2, 0), Some(1)), shape(2, 1));
        assert_eq!(RingShape::choose(4, 2, (2, 2), Some(1)), shape(2, 2));
        assert_eq!(RingShape::choose(4, 2, (2, 0), Some(4)), shape(2, 2));
        // Asked for and not fitting: left to fail where the parts go.
        assert_eq!(RingShape::choose(2, 1, (1, 0), None), shape(1, 1));
        // Refused.
        assert_eq!(RingShape::choose(2, 2, (0, 0), None), Err(RingShapeError::DoesNotFit));
        assert_eq!(RingShape::choose(2, 2, (0, 0), Some(5)), Err(RingShapeError::DoesNotFit));
        assert!(
            matches!(RingShape::choose(3, 1, (2, 0), Some(1)), Err(RingShapeError::Input(m)) if m.contains("must divide the 3 ranks"))
        );
        assert!(
            matches!(RingShape::choose(2, 2, (2, 3), Some(1)), Err(RingShapeError::Input(m)) if m.contains("more than the 2 devices"))
        );
    }

    /// Islands of a rank's devices: each group of `per_rank` devices, then
    /// their wavefronts, one island of them at a time; uneven wavefronts
    /// are cut to the fewest of their group, and a partial group is left out.
    #[test]
    fn wavefronts_form_islands_of_whole_groups() {
        let more = |n: usize, of: &str| (1..=n).map(|k| format!("{of}.{k}")).collect::<Vec<_>>();
        let devices = vec!["a".to_string(), "b".into(), "c".into(), "d".into(), "e".into()];
        let wavefronts = vec![more(2, "a"), more(1, "b"), more(2, "c"), more(2, "d"), more(2, "e")];
        let islands = islands_of(devices, wavefronts, 2);
        assert_eq!(islands, ["a", "b", "a.1", "b.1", "c", "d", "c.1", "d.1", "c.2", "d.2"]);
        let one = islands_of(vec![1, 2], vec![vec![10], vec![20, 21]], 1);
        assert_eq!(one, [1, 10, 2, 20, 21]);
    }
}
