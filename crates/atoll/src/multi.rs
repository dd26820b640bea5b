//! `--devices`, `--strategy` and `--ownership`: rendering on many devices
//! in one process (atoll-dist), and the per-device table printed after.

use std::path::Path;
use std::sync::Arc;

use atoll_cuda::device::CudaDevice;
use atoll_cuda::error::fmt_bytes;
use atoll_dist::partition::GPU_INSTANCE_COST;
pub use atoll_dist::placement::Partitioning;
use atoll_dist::placement::{place, PlacementError, PlacementRequest};
use atoll_dist::{
    render_multi, render_multi_warmed, Layout, MultiOutput, Partition, Plan, RingOrder, Strategy, Transport,
};
use atoll_render::{CpuDevice, Device, RenderOptions};
use atoll_scene::Scene;

use crate::CliError;

/// One entry of `--devices`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeviceSpec {
    Cpu,
    Cuda(usize),
    /// `cuda:I/P`: a part of GPU I split into P groups of multiprocessors,
    /// each listing the next part ([`atoll_cuda::Gpu::open_partition`]);
    /// `cuda:I[J/P]` (the label atoll prints) names part J itself, e.g.
    /// for processes sharing a GPU under mpirun.
    CudaPart {
        ordinal: usize,
        parts: usize,
        index: Option<usize>,
    },
}

impl DeviceSpec {
    /// The GPU this names, if any.
    pub fn ordinal(&self) -> Option<usize> {
        match *self {
            DeviceSpec::Cpu => None,
            DeviceSpec::Cuda(ordinal) | DeviceSpec::CudaPart { ordinal, .. } => Some(ordinal),
        }
    }
}

/// The parsed `--devices` list (a newtype: clap would take a bare `Vec`
/// for a repeated flag).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceList(pub Vec<DeviceSpec>);

/// Parses `--devices`: comma-separated `cpu`, `cpu:N` (N CPU devices
/// sharing the cores), `cuda:I` (GPU I). A GPU listed twice is two devices
/// sharing it (its time and memory): a ring's or replica's total work
/// measured on one GPU, and the multi-device paths tested without two.
pub fn parse_devices(s: &str) -> Result<DeviceList, String> {
    let mut devices = Vec::new();
    for item in s.split(',').map(|i| i.trim().to_ascii_lowercase()) {
        let bad = || {
            format!(
                "{item:?} in {s:?}: expected cpu, cpu:N (N CPU devices), cuda:I, cuda:I/P (the next part of P) or cuda:I[J/P] (part J of P)"
            )
        };
        match item.split_once(':') {
            None if item == "cpu" => devices.push(DeviceSpec::Cpu),
            None if item == "cuda" => devices.push(DeviceSpec::Cuda(0)),
            Some(("cpu", n)) => {
                let n: usize = n.parse().map_err(|_| bad())?;
                if n == 0 || n > 64 {
                    return Err(format!("{item:?}: between 1 and 64 CPU devices"));
                }
                devices.extend(std::iter::repeat_n(DeviceSpec::Cpu, n));
            }
            Some(("cuda", i)) => match i.split_once('/') {
                None => devices.push(DeviceSpec::Cuda(i.parse().map_err(|_| bad())?)),
                Some((i, p)) => {
                    // `I/P`, or `I[J/P]`: part J named.
                    let (i, index, p) = match (i.split_once('['), p.strip_suffix(']')) {
                        (Some((i, j)), Some(p)) => (i, Some(j.parse::<usize>().map_err(|_| bad())?), p),
                        (None, None) => (i, None, p),
                        _ => return Err(bad()),
                    };
                    let ordinal = i.parse().map_err(|_| bad())?;
                    let parts: usize = p.parse().map_err(|_| bad())?;
                    if !(2..=16).contains(&parts) {
                        return Err(format!("{item:?}: a GPU splits into 2 to 16 parts"));
                    }
                    if index.is_some_and(|j| j >= parts) {
                        return Err(format!("{item:?}: parts of {parts} are numbered 0 to {}", parts - 1));
                    }
                    devices.push(DeviceSpec::CudaPart { ordinal, parts, index });
                }
            },
            _ => return Err(bad()),
        }
    }
    if devices.is_empty() {
        return Err("--devices: no devices listed".into());
    }
    Ok(DeviceList(devices))
}

/// The devices, created (GPUs opened) but not prepared.
pub fn open_devices(
    specs: &[DeviceSpec],
    budget: Option<u64>,
    threads: Option<usize>,
) -> Result<Vec<Box<dyn Device>>, CliError> {
    let start = std::time::Instant::now();
    let mut devices: Vec<Box<dyn Device>> = Vec::new();
    let mut cpus = 0;
    for spec in specs {
        match *spec {
            DeviceSpec::Cpu => {
                let mut d = CpuDevice::new().with_name(format!("cpu:{cpus}"));
                cpus += 1;
                if let Some(t) = threads {
                    d = d.with_threads(t.max(1)).map_err(|e| CliError::Runtime(e.to_string()))?;
                }
                if let Some(b) = budget {
                    d = d.with_memory_budget(b);
                }
                devices.push(Box::new(d));
            }
            DeviceSpec::Cuda(_) | DeviceSpec::CudaPart { .. } => {
                let ordinal = spec.ordinal().expect("a GPU");
                let gpu = match *spec {
                    DeviceSpec::CudaPart { parts, index: Some(index), .. } => {
                        atoll_cuda::Gpu::open_partition(ordinal, parts, index)
                    }
                    DeviceSpec::CudaPart { parts, index: None, .. } => {
                        // The next part of this GPU: one per earlier `cuda:I/P` of it.
                        let index = specs[..devices.len()]
                            .iter()
                            .filter(|s| matches!(s, DeviceSpec::CudaPart { ordinal: o, .. } if *o == ordinal))
                            .count();
                        if index >= parts {
                            return Err(CliError::Input(format!(
                                "cuda:{ordinal}/{parts} is listed more than {parts} times"
                            )));
                        }
                        atoll_cuda::Gpu::open_partition(ordinal, parts, index)
                    }
                    _ => atoll_cuda::Gpu::open(ordinal),
                }
                .map_err(|e| CliError::Runtime(e.to_string()))?;
                let mut d = CudaDevice::on(gpu);
                // Devices sharing a GPU prepare at once: each checks its plan
                // against its share of the free memory, not all of it.
                let sharing = specs.iter().filter(|s| s.ordinal() == Some(ordinal)).count() as u64;
                let share = (sharing > 1).then(|| d.gpu().free_memory().ok().map(|f| f / sharing)).flatten();
                if let Some(b) = budget.into_iter().chain(share).min() {
                    d = d.with_memory_budget(b);
                }
                devices.push(Box::new(d));
            }
        }
    }
    tracing::info!("opened {} devices in {:.2} s", devices.len(), start.elapsed().as_secs_f64());
    Ok(devices)
}

/// What `atoll render` hands to the multi-device path.
pub struct MultiArgs<'a> {
    pub specs: &'a [DeviceSpec],
    pub strategy: Strategy,
    pub budget: Option<u64>,
    pub ownership: Option<&'a Path>,
    /// How ring queues move (`None`: the fastest the devices allow).
    pub transport: Option<Transport>,
    /// How a ring's scene parts are made.
    pub partitioning: Partitioning,
    /// Wavefronts per GPU (`--streams`): when replicating, per GPU listed
    /// once; on a ring, copies of the ring as more islands.
    pub streams: usize,
    /// Render the frame's first sample untimed first, on the prepared devices.
    pub warmup: bool,
    /// Where a ring's queues start and end their cycles.
    pub ring_order: RingOrder,
    /// Devices per ring (`--ring-size`), the rest of the devices forming
    /// more islands; `None`: the fewest the budget allows.
    pub ring_size: Option<usize>,
    /// How `--strategy shared` cuts and places the scene.
    pub shared: atoll_dist::SharedSpec,
}

/// Plans, partitions and renders `scene` on the listed devices; prints the
/// choice before.
pub fn render(
    devices: Vec<Box<dyn Device>>,
    scene: &Arc<Scene>,
    options: RenderOptions,
    args: &MultiArgs,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<MultiOutput, CliError> {
    let Placed { mut devices, layout, .. } = place_on(devices, scene, &options, args)?;
    let render = if args.warmup { render_multi_warmed } else { render_multi };
    render(&mut devices, scene, options, &layout, args.transport, progress)
        .map_err(|e| CliError::Runtime(e.to_string()))
}

/// Devices with the scene placed on them.
pub struct Placed {
    pub devices: Vec<Box<dyn Device>>,
    pub layout: Layout,
    /// A ring's parts, for the ownership view.
    pub partition: Option<Partition>,
}

/// Places `scene` on `devices`, opened from the listed ones (atoll-dist
/// decides the strategy, partition and further wavefronts), and prints the
/// choice.
pub fn place_on(
    mut devices: Vec<Box<dyn Device>>,
    scene: &Arc<Scene>,
    options: &RenderOptions,
    args: &MultiArgs,
) -> Result<Placed, CliError> {
    let mut gpus: Vec<usize> =
        args.specs.iter().filter_map(|d| if let DeviceSpec::Cuda(i) = d { Some(*i) } else { None }).collect();
    gpus.sort_unstable();
    for shared in gpus.chunk_by(|a, b| a == b).filter(|c| c.len() > 1) {
        eprintln!("note: {} devices share cuda:{} (its time and memory)", shared.len(), shared[0]);
    }
    for spec in args.specs {
        if let DeviceSpec::CudaPart { ordinal, parts, .. } = *spec {
            eprintln!("note: cuda:{ordinal} split into {parts} parts (multiprocessors apart; memory and its bandwidth shared)");
            break;
        }
    }
    // More wavefronts beside each GPU listed once, and each GPU part.
    let may_add_wavefronts = args
        .specs
        .iter()
        .map(|spec| match *spec {
            DeviceSpec::Cpu => false,
            DeviceSpec::CudaPart { .. } => true,
            DeviceSpec::Cuda(_) => args.specs.iter().filter(|s| *s == spec).count() == 1,
        })
        .collect();
    let request = PlacementRequest {
        strategy: args.strategy,
        ring_size: args.ring_size,
        budget: args.budget,
        partitioning: args.partitioning,
        ring_order: args.ring_order,
        streams: args.streams,
        may_add_wavefronts,
        shared: args.shared,
    };
    let start = std::time::Instant::now();
    let placement = place(&mut devices, scene, options, &request).map_err(|e| match e {
        PlacementError::Request(message) => CliError::Input(message),
        other => CliError::Runtime(other.to_string()),
    })?;
    tracing::info!("placed the scene in {:.2} s", start.elapsed().as_secs_f64());
    if let Some((_, kind)) = &placement.partition {
        eprintln!("partition: {kind}");
    }
    let partition = placement.partition.as_ref().map(|(p, _)| p);
    eprintln!("{}", describe(&placement.plan, &placement.layout, partition, args.specs.len()));
    if matches!(placement.layout, Layout::Ring { order: RingOrder::Home, .. }) {
        eprintln!("ring order: member 0 makes and shades every queue");
    }
    if let Some(path) = args.ownership {
        write_ownership(scene, options, partition, path)?;
    }
    for note in &placement.notes {
        eprintln!("note: {note}");
    }
    Ok(Placed { devices, layout: placement.layout, partition: placement.partition.map(|(p, _)| p) })
}

/// One line saying what was chosen and why (islands as `layout` has
/// them, wavefronts sharing a GPU's part included).
fn describe(plan: &Plan, layout: &Layout, partition: Option<&Partition>, devices: usize) -> String {
    match (plan, layout, partition) {
        (Plan::Ring { k, .. }, Layout::Ring { islands, .. }, Some(p)) => {
            let sizes: Vec<String> = p.bytes.iter().map(|&b| fmt_bytes(b)).collect();
            format!(
                "strategy: ring of {k} ({}) on {devices} devices; parts {}",
                islands_text(*islands),
                sizes.join(", ")
            )
        }
        (Plan::Shared, ..) => format!("strategy: shared scene memory on {devices} devices"),
        _ => format!("strategy: replicate on {devices} devices"),
    }
}

/// `1 island`, `3 islands`.
pub fn islands_text(islands: usize) -> String {
    format!("{islands} island{}", if islands == 1 { "" } else { "s" })
}

/// The false-colour view: by part (ring) or everything device 0's colour (replicate).
pub fn write_ownership(
    scene: &Scene,
    options: &RenderOptions,
    partition: Option<&Partition>,
    path: &Path,
) -> Result<(), CliError> {
    let owner = |instance: u32, mesh: u32, triangle: u32| match partition {
        Some(p) => p.owner(instance, mesh, triangle),
        None => Some(0),
    };
    let film = atoll_dist::ownership::ownership_view(scene, options, &owner);
    // False colours: no sensor response.
    let plain = RenderOptions { film_response: glam::Mat3::IDENTITY, ..options.clone() };
    crate::render::write_image(&film, &plain, path)?;
    eprintln!("ownership view: {}", path.display());
    Ok(())
}

/// The per-device table printed after a multi-device render. Busy: the
/// device's own work (CPU: inside its stages; GPU: its kernels, timed on
/// the GPU); idle: the rest of its time in the frame, waiting for ring
/// neighbours, for the host or for work; wait and send: host time blocked
/// on neighbours and spent sending queues.
pub fn device_table(out: &MultiOutput) -> String {
    device_table_header().to_string() + &device_rows(out)
}

/// The device table's first line.
pub fn device_table_header() -> &'static str {
    "device       ring  member  scene mem   frame mem   waves   rays (M)  shadow (M)  busy s   idle s   wait s   send s  sent\n"
}

/// The device table's rows, one per device.
pub fn device_rows(out: &MultiOutput) -> String {
    let mut s = String::new();
    for d in &out.devices {
        s += &format!(
            "{:<12} {:>4}  {:>6}  {:>9}  {:>10}  {:>6}  {:>9.2}  {:>10.2}  {:>6.3}  {:>7.3}  {:>7.3}  {:>6.3}  {}\n",
            d.name,
            d.island,
            d.member,
            fmt_bytes(d.prepare.scene_bytes),
            fmt_bytes(d.prepare.frame_bytes),
            d.waves,
            d.stats.rays_traced as f64 / 1e6,
            d.stats.shadow_rays_traced as f64 / 1e6,
            d.stats.busy_seconds,
            (d.wall_seconds - d.stats.busy_seconds).max(0.0),
            d.wait_seconds,
            d.send_seconds,
            fmt_bytes(d.bytes_sent),
        );
    }
    s
}

/// Where `--strategy shared` put the chunks: the prepass, then per device
/// what it holds (replicated, owned), reads elsewhere (remote, host) and
/// the share of its prepass reads its own memory serves.
pub fn shared_table(out: &MultiOutput) -> String {
    let Some(report) = &out.shared else { return String::new() };
    let layout = &report.layout;
    let chunks = layout.chunk_count();
    let replicated = report.replicated_chunks();
    let mut s = format!(
        "shared: {} in {chunks} chunks of {}; {replicated} replicated ({:.1}%); prepass {:.3} s\n",
        fmt_bytes(layout.bytes()),
        fmt_bytes(layout.chunk_bytes),
        100.0 * replicated as f64 / chunks.max(1) as f64,
        report.prepass_seconds
    );
    s += "device       replicated      owned     remote       host  prepass reads (M)  local reads\n";
    let rows = report.residency.iter().zip(&report.local_reads).zip(&report.counts).zip(&out.devices);
    for (((r, local), counts), device) in rows {
        s += &format!(
            "{:<12} {:>10} {:>10} {:>10} {:>10}  {:>17.2}  {:>10.1}%\n",
            device.name,
            fmt_bytes(r.replicated),
            fmt_bytes(r.owned),
            fmt_bytes(r.remote),
            fmt_bytes(r.host),
            counts.iter().sum::<u64>() as f64 / 1e6,
            100.0 * local
        );
    }
    s
}

/// Parses `--partition`.
pub fn parse_partitioning(s: &str) -> Result<Partitioning, String> {
    match s.trim().to_ascii_lowercase().as_str() {
        "auto" => Ok(Partitioning::Auto),
        "work" => Ok(Partitioning::Work),
        "measured" => Ok(Partitioning::Measured),
        "spatial" => Ok(Partitioning::Spatial),
        "memory" => Ok(Partitioning::Memory),
        "cost" => Ok(Partitioning::Cost(GPU_INSTANCE_COST)),
        other => match other.strip_prefix("cost=").map(str::parse::<u64>) {
            Some(Ok(bytes)) => Ok(Partitioning::Cost(bytes)),
            _ => Err(format!(
                "{s:?}: expected auto, cost, cost=BYTES (per instance), work, measured, spatial or memory"
            )),
        },
    }
}

/// Parses `--ring-order`.
pub fn parse_ring_order(s: &str) -> Result<RingOrder, String> {
    match s.trim().to_ascii_lowercase().as_str() {
        "spread" => Ok(RingOrder::Spread),
        "home" => Ok(RingOrder::Home),
        _ => Err(format!("{s:?}: expected spread or home")),
    }
}

/// Parses `--ring-transport`.
pub fn parse_transport(s: &str) -> Result<Transport, String> {
    match s.trim().to_ascii_lowercase().as_str() {
        "host" => Ok(Transport::Host),
        "peer" => Ok(Transport::Peer),
        _ => Err(format!("{s:?}: expected host or peer")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_lists() {
        assert_eq!(parse_devices("cpu:3"), Ok(DeviceList(vec![DeviceSpec::Cpu; 3])));
        assert_eq!(
            parse_devices("cuda:0,cuda:1"),
            Ok(DeviceList(vec![DeviceSpec::Cuda(0), DeviceSpec::Cuda(1)]))
        );
        assert_eq!(parse_devices("cpu, cuda:1"), Ok(DeviceList(vec![DeviceSpec::Cpu, DeviceSpec::Cuda(1)])));
        assert_eq!(parse_devices("cuda:0,cuda:0"), Ok(DeviceList(vec![DeviceSpec::Cuda(0); 2])));
        let half = DeviceSpec::CudaPart { ordinal: 1, parts: 2, index: None };
        assert_eq!(parse_devices("cuda:1/2,cuda:1/2"), Ok(DeviceList(vec![half; 2])));
        let second = DeviceSpec::CudaPart { ordinal: 0, parts: 4, index: Some(1) };
        assert_eq!(parse_devices("cuda:0[1/4]"), Ok(DeviceList(vec![second])));
        assert!(parse_devices("cuda:0[4/4]").is_err() && parse_devices("cuda:0[1/4").is_err());
        assert!(parse_devices("cuda:0/1").is_err() && parse_devices("cuda:0/x").is_err());
        assert!(parse_devices("cpu:0").is_err());
        assert!(parse_devices("tpu:1").is_err());
        assert!(parse_devices("").is_err());
    }

    #[test]
    fn ring_orders() {
        assert_eq!(parse_ring_order("home"), Ok(RingOrder::Home));
        assert_eq!(parse_ring_order(" Spread "), Ok(RingOrder::Spread));
        assert!(parse_ring_order("first").is_err());
    }
}
