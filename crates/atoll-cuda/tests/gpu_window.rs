//! Chunk windows (src/window.rs) on real GPUs: chunks on the device, on a
//! peer GPU and in host memory, written from the host, read back through
//! each GPU's range and by kernels (kernels/test_window.cu), moved by
//! `replace`; and the speed of random reads through a window. Ignored
//! unless asked for (`--include-ignored`); skipped without a GPU unless
//! `ATOLL_REQUIRE_GPU=1` (see tests/common). The two-GPU tests say so and
//! return on a machine with one.

mod common;

use std::sync::Arc;

use atoll_cuda::gpu::launch_1d;
use atoll_cuda::{device_count, ChunkWindow, CudaError, Gpu};
use atoll_render::{ChunkHome, ChunkPlacement, Residency};
use cudarc::driver::{LaunchConfig, PushKernelArg};

use common::gpu_or_skip;
use ChunkHome::{Device, Host, Replicated};

/// Held by every test of this file: some measure the GPU's free memory,
/// which another test allocating beside them would move.
fn exclusive() -> std::sync::MutexGuard<'static, ()> {
    static GPU_MEMORY: std::sync::Mutex<()> = std::sync::Mutex::new(());
    GPU_MEMORY.lock().unwrap_or_else(|e| e.into_inner())
}

/// GPUs 0 and 1, or `None` after saying why the test is skipped.
fn two_gpus(test: &str) -> Option<Vec<Arc<Gpu>>> {
    let first = gpu_or_skip(test)?;
    let count = device_count().unwrap_or(0);
    if count < 2 {
        eprintln!("{test}: skipped, needs 2 GPUs (this machine has {count})");
        return None;
    }
    Some(vec![first, Gpu::open(1).unwrap()])
}

fn placement(homes: &[ChunkHome]) -> ChunkPlacement {
    ChunkPlacement { homes: homes.to_vec() }
}

/// Word `i` of the test pattern: distinct in every chunk.
fn word(i: u64, seed: u32) -> u32 {
    (i as u32).wrapping_mul(2_654_435_761).wrapping_add(seed)
}

/// The pattern for `bytes` bytes, as bytes.
fn pattern(bytes: u64, seed: u32) -> Vec<u8> {
    (0..bytes / 4).flat_map(|i| word(i, seed).to_le_bytes()).collect()
}

fn sum_words(bytes: &[u8]) -> u64 {
    bytes.chunks_exact(4).fold(0u64, |s, w| s.wrapping_add(u32::from_le_bytes(w.try_into().unwrap()) as u64))
}

/// The sum of the window's words, computed by a kernel on GPU `g` reading
/// through its range.
fn kernel_sum(window: &ChunkWindow, gpus: &[Arc<Gpu>], g: usize) -> u64 {
    let gpu = &gpus[g];
    let f = gpu.function("test_window.cu", "window_sum").unwrap();
    let mut sum = gpu.stream.alloc_zeros::<u64>(1).unwrap();
    let (base, words) = (window.base(g), window.bytes() / 4);
    let mut launch = gpu.stream.launch_builder(&f);
    launch.arg(&base).arg(&words).arg(&mut sum);
    let config = LaunchConfig {
        grid_dim: (gpu.multiprocessors * 4, 1, 1),
        block_dim: (256, 1, 1),
        shared_mem_bytes: 0,
    };
    // SAFETY: matches window_sum(const unsigned*, unsigned long long n, unsigned long long*);
    // `base` is GPU g's range of the window, `words` 4-byte words long, mapped for it.
    unsafe { launch.launch(config) }.unwrap();
    gpu.stream.clone_dtoh(&sum).unwrap()[0]
}

/// Words `indices` of the window, gathered by a kernel on GPU `g`.
fn kernel_gather(window: &ChunkWindow, gpus: &[Arc<Gpu>], g: usize, indices: &[u64]) -> Vec<u32> {
    let gpu = &gpus[g];
    let f = gpu.function("test_window.cu", "window_gather").unwrap();
    assert!(indices.iter().all(|&i| i < window.bytes() / 4));
    let idx = gpu.stream.clone_htod(indices).unwrap();
    let n = indices.len() as u32;
    let mut out = gpu.stream.alloc_zeros::<u32>(indices.len()).unwrap();
    let base = window.base(g);
    let mut launch = gpu.stream.launch_builder(&f);
    launch.arg(&base).arg(&idx).arg(&n).arg(&mut out);
    // SAFETY: matches window_gather(const unsigned*, const unsigned long long*, unsigned n,
    // unsigned*); every index is a word of the window (asserted above), `out` holds n.
    unsafe { launch.launch(launch_1d(n, 128)) }.unwrap();
    gpu.stream.clone_dtoh(&out).unwrap()
}

/// Word indices spread over every chunk, chunk boundaries included.
fn probe_indices(window: &ChunkWindow) -> Vec<u64> {
    let words_per_chunk = window.chunk_bytes() / 4;
    let chunks = window.bytes() / window.chunk_bytes();
    (0..chunks)
        .flat_map(|c| [0, 1, words_per_chunk / 3, words_per_chunk - 1].map(|w| c * words_per_chunk + w))
        .collect()
}

/// Checks that every GPU sees `expected` through its range: host reads,
/// a kernel's sum and a kernel's gather.
fn check_contents(window: &ChunkWindow, gpus: &[Arc<Gpu>], expected: &[u8]) {
    let indices = probe_indices(window);
    let want: Vec<u32> = indices
        .iter()
        .map(|&i| u32::from_le_bytes(expected[i as usize * 4..i as usize * 4 + 4].try_into().unwrap()))
        .collect();
    for g in 0..gpus.len() {
        assert!(window.read(g, 0, window.bytes()).unwrap() == expected, "GPU {g}: read back differs");
        assert_eq!(kernel_sum(window, gpus, g), sum_words(expected), "GPU {g}: kernel sum");
        assert_eq!(kernel_gather(window, gpus, g, &indices), want, "GPU {g}: kernel gather");
    }
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn one_gpu_reads_device_and_host_chunks() {
    let _memory = exclusive();
    let Some(gpu) = gpu_or_skip("window on one GPU") else { return };
    let gpus = vec![gpu];
    let chunk = ChunkWindow::chunk_bytes_for(&gpus, 1).unwrap();
    println!("chunk granularity: {chunk} bytes");
    let p = placement(&[Device(0), Host, Host, Device(0), Host]);
    let window = ChunkWindow::new(&gpus, 1, &p, &[]).unwrap();
    assert_eq!((window.chunk_bytes(), window.bytes()), (chunk, 5 * chunk));
    assert_eq!(
        window.residency(0),
        Residency { replicated: 0, owned: 2 * chunk, remote: 0, host: 3 * chunk }
    );
    assert_eq!(window.memory().host, 3 * chunk);

    let mut data = pattern(window.bytes(), 7);
    window.write(0, &data).unwrap();
    check_contents(&window, &gpus, &data);

    // A small write across the boundary of a device and a host chunk.
    let patch = [0xABu8; 10];
    let at = 2 * chunk - 3;
    window.write(at, &patch).unwrap();
    data[at as usize..at as usize + 10].copy_from_slice(&patch);
    assert_eq!(window.read(0, at - 5, 20).unwrap(), data[at as usize - 5..at as usize + 15]);
    check_contents(&window, &gpus, &data);

    assert!(matches!(window.write(window.bytes() - 2, &[0; 4]), Err(CudaError::Usage(_))));
    assert!(matches!(window.read(0, u64::MAX, 2), Err(CudaError::Usage(_))));
    assert!(matches!(window.read(1, 0, 4), Err(CudaError::Usage(_))));
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn one_gpu_replace_keeps_contents_and_base() {
    let _memory = exclusive();
    let Some(gpu) = gpu_or_skip("window replace on one GPU") else { return };
    let gpus = vec![gpu];
    let mut window =
        ChunkWindow::new(&gpus, 1, &placement(&[Device(0), Host, Device(0), Host]), &[]).unwrap();
    let base = window.base(0);
    let data = pattern(window.bytes(), 11);
    window.write(0, &data).unwrap();
    for homes in [[Host, Host, Device(0), Device(0)], [Replicated, Device(0), Host, Replicated], [Host; 4]] {
        window.replace(&placement(&homes), &[]).unwrap();
        assert_eq!(window.base(0), base, "replace keeps the base address");
        assert_eq!(window.placement().homes, homes);
        check_contents(&window, &gpus, &data);
    }
    // A placement of another length is refused and changes nothing.
    assert!(matches!(window.replace(&placement(&[Host]), &[]), Err(CudaError::Usage(_))));
    check_contents(&window, &gpus, &data);
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn budgets_refuse_before_allocating() {
    let _memory = exclusive();
    let Some(gpu) = gpu_or_skip("window budgets") else { return };
    let gpus = vec![gpu];
    let chunk = ChunkWindow::chunk_bytes_for(&gpus, 1).unwrap();
    let p = placement(&[Device(0), Device(0), Host]);
    let memory = ChunkWindow::check_memory(&gpus, 1, &p, &[Some(2 * chunk)]).unwrap();
    assert_eq!(memory.gpus[0].owned, 2 * chunk);
    let refused = ChunkWindow::new(&gpus, 1, &p, &[Some(2 * chunk - 1)]);
    assert!(matches!(refused, Err(CudaError::OutOfMemory { needed, .. }) if needed == 2 * chunk));
    // More than the GPU has: refused from its free memory, with no budget.
    let chunks = (gpus[0].total_memory / chunk + 1) as usize;
    let huge = placement(&vec![Device(0); chunks]);
    let e = ChunkWindow::check_memory(&gpus, 1, &huge, &[]).unwrap_err();
    println!("{e}");
    assert!(matches!(e, CudaError::OutOfMemory { .. }));
    // A replacement is checked too, and leaves the window as it was.
    let mut window = ChunkWindow::new(&gpus, 1, &p, &[]).unwrap();
    let data = pattern(window.bytes(), 3);
    window.write(0, &data).unwrap();
    let all_local = placement(&[Device(0); 3]);
    assert!(matches!(window.replace(&all_local, &[Some(2 * chunk)]), Err(CudaError::OutOfMemory { .. })));
    assert_eq!(window.placement(), &p);
    check_contents(&window, &gpus, &data);
    window.replace(&all_local, &[Some(3 * chunk)]).unwrap();
    check_contents(&window, &gpus, &data);
}

/// Physical memory goes back when the window drops, and when `replace`
/// moves chunks off the GPU.
#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn dropping_and_moving_chunks_frees_their_memory() {
    let _memory = exclusive();
    let Some(gpu) = gpu_or_skip("window memory") else { return };
    let gpus = vec![gpu.clone()];
    const BYTES: u64 = 512 << 20;
    let chunk = ChunkWindow::chunk_bytes_for(&gpus, 1).unwrap();
    let chunks = (BYTES / chunk) as usize;
    // What the driver keeps for itself may move by a page or two.
    let slack = 8 << 20;
    let before = gpu.free_memory().unwrap();
    let mut window = ChunkWindow::new(&gpus, chunk, &placement(&vec![Device(0); chunks]), &[]).unwrap();
    let with = gpu.free_memory().unwrap();
    assert!(before - with >= BYTES, "{before} free before, {with} with the window");
    window.replace(&placement(&vec![Host; chunks]), &[]).unwrap();
    let moved = gpu.free_memory().unwrap();
    assert!(moved + slack >= before, "{before} free before, {moved} with every chunk in host memory");
    window.replace(&placement(&vec![Device(0); chunks]), &[]).unwrap();
    drop(window);
    let after = gpu.free_memory().unwrap();
    assert!(after + slack >= before, "{before} free before, {after} after");
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn two_gpus_read_peer_replicated_and_host_chunks() {
    let _memory = exclusive();
    let Some(gpus) = two_gpus("window on two GPUs") else { return };
    let p = placement(&[Replicated, Device(1), Device(0), Host, Device(1), Replicated]);
    let window = ChunkWindow::new(&gpus, 1, &p, &[]).unwrap();
    let chunk = window.chunk_bytes();
    assert_eq!(
        window.residency(0),
        Residency { replicated: 2 * chunk, owned: chunk, remote: 2 * chunk, host: chunk }
    );
    assert_eq!(
        window.residency(1),
        Residency { replicated: 2 * chunk, owned: 2 * chunk, remote: chunk, host: chunk }
    );
    let mut data = pattern(window.bytes(), 5);
    window.write(0, &data).unwrap();
    check_contents(&window, &gpus, &data);

    // A write into a replicated chunk reaches both replicas.
    let at = 5 * chunk + 100;
    let patch: Vec<u8> = (0..64).collect();
    window.write(at, &patch).unwrap();
    data[at as usize..at as usize + 64].copy_from_slice(&patch);
    for g in 0..2 {
        assert_eq!(window.read(g, at, 64).unwrap(), patch, "GPU {g}'s replica");
    }
    check_contents(&window, &gpus, &data);
}

#[test]
#[ignore = "needs a CUDA GPU (scripts/gpu-check runs these with --include-ignored)"]
fn two_gpus_replace_keeps_contents() {
    let _memory = exclusive();
    let Some(gpus) = two_gpus("window replace on two GPUs") else { return };
    let start = [Replicated, Device(1), Device(0), Host, Device(1), Replicated];
    let mut window = ChunkWindow::new(&gpus, 1, &placement(&start), &[]).unwrap();
    let bases = [window.base(0), window.base(1)];
    let data = pattern(window.bytes(), 9);
    window.write(0, &data).unwrap();
    let steps = [
        [Device(1), Replicated, Host, Device(0), Device(0), Device(1)],
        [Host; 6],
        [Replicated; 6],
        [Device(0), Device(1), Device(0), Device(1), Device(0), Device(1)],
    ];
    for homes in steps {
        window.replace(&placement(&homes), &[]).unwrap();
        assert_eq!([window.base(0), window.base(1)], bases, "replace keeps the base addresses");
        check_contents(&window, &gpus, &data);
    }
}

/// Whether chunk `c` goes elsewhere when `percent` % of the chunks do
/// (rounded), spread evenly.
fn moved(c: usize, percent: usize) -> bool {
    (c + 1) * percent / 100 > c * percent / 100
}

/// Blocks × threads × dependent reads of the random-read measurements, as
/// GPU.md's measurement of peer reads through plain allocations (2112 blocks
/// × 256 threads × 64 steps on 132 multiprocessors).
const STEPS: u32 = 64;
const THREADS_PER_BLOCK: u32 = 256;

fn read_blocks(gpu: &Gpu) -> u32 {
    gpu.multiprocessors * 16
}

/// Fills `bytes` at device address `base` on `gpu` with a pattern, then
/// times dependent random 32-byte reads of it: the median of five runs
/// after a warm-up, in G reads/s. `bytes` is a power of two.
fn random_read_rate(gpu: &Arc<Gpu>, base: u64, bytes: u64) -> f64 {
    assert!(bytes.is_power_of_two());
    let fill = gpu.function("test_window.cu", "window_fill").unwrap();
    let random_reads = gpu.function("test_window.cu", "window_random_reads").unwrap();
    let blocks = read_blocks(gpu);
    let threads = blocks * THREADS_PER_BLOCK;
    let mut out = gpu.stream.alloc_zeros::<u32>(threads as usize).unwrap();
    let (words, seed) = (bytes / 4, 1u32);
    let mut launch = gpu.stream.launch_builder(&fill);
    launch.arg(&base).arg(&words).arg(&seed);
    let config = LaunchConfig {
        grid_dim: (gpu.multiprocessors * 8, 1, 1),
        block_dim: (256, 1, 1),
        shared_mem_bytes: 0,
    };
    // SAFETY: matches window_fill(unsigned*, unsigned long long n, unsigned); `base` holds
    // `words` words, writable by this GPU (the callers' contract).
    unsafe { launch.launch(config) }.unwrap();
    let mask = (bytes / 32 - 1) as u32;
    let mut times = Vec::new();
    for run in 0..6 {
        let mut timer = gpu.start_timer().unwrap();
        let mut launch = gpu.stream.launch_builder(&random_reads);
        launch.arg(&base).arg(&mask).arg(&STEPS).arg(&mut out);
        let config = LaunchConfig {
            grid_dim: (blocks, 1, 1),
            block_dim: (THREADS_PER_BLOCK, 1, 1),
            shared_mem_bytes: 0,
        };
        // SAFETY: matches window_random_reads(const uint4*, unsigned mask, unsigned steps,
        // unsigned*); `base` holds mask + 1 blocks of 32 bytes, `out` one word per thread.
        unsafe { launch.launch(config) }.unwrap();
        timer.stop(gpu).unwrap();
        let ms = timer.elapsed_ms().unwrap() as f64;
        // The first run warms up.
        if run > 0 {
            times.push(ms);
        }
    }
    times.sort_by(f64::total_cmp);
    threads as f64 * STEPS as f64 / (times[times.len() / 2] * 1e-3) / 1e9
}

/// Dependent random 32-byte reads on GPU 0 through windows of 4 GiB with
/// 0, 10, 50 and 100 % of the chunks on GPU 1 (with two GPUs) or in host
/// memory: G reads/s.
#[test]
#[ignore = "a measurement on a CUDA GPU: run it by name with --include-ignored --nocapture"]
fn window_read_speed() {
    let _memory = exclusive();
    let Some(first) = gpu_or_skip("window read speed") else { return };
    let count = device_count().unwrap_or(0);
    let gpus = if count >= 2 { vec![first, Gpu::open(1).unwrap()] } else { vec![first] };
    let gpu = gpus[0].clone();
    const TABLE: u64 = 4 << 30;
    const CHUNK: u64 = 32 << 20;
    let chunks = (TABLE / CHUNK) as usize;
    let mut configs = vec![("local".to_string(), vec![Device(0); chunks])];
    for percent in [10, 50, 100] {
        let homes = |elsewhere: ChunkHome| {
            (0..chunks).map(|c| if moved(c, percent) { elsewhere } else { Device(0) }).collect()
        };
        if gpus.len() >= 2 {
            configs.push((format!("{percent}% on GPU 1"), homes(Device(1))));
        }
        configs.push((format!("{percent}% in host memory"), homes(Host)));
    }
    if gpus.len() < 2 {
        println!("one GPU: no peer configurations");
    }
    println!(
        "{} ({}), {} GiB window in chunks of {} MiB, {} blocks × {THREADS_PER_BLOCK} threads × {STEPS} dependent reads of 32 B",
        gpu.name,
        gpu.label(),
        TABLE >> 30,
        CHUNK >> 20,
        read_blocks(&gpu)
    );
    println!("{:<22} {:>10} {:>10} {:>8} {:>10}", "chunks", "G reads/s", "GB/s", "× local", "setup ms");
    let mut local = None;
    for (name, homes) in configs {
        let setup = std::time::Instant::now();
        let window = ChunkWindow::new(&gpus, CHUNK, &ChunkPlacement { homes }, &[]).unwrap();
        let setup_ms = setup.elapsed().as_secs_f64() * 1e3;
        let greads = random_read_rate(&gpu, window.base(0), window.bytes());
        let local_rate = *local.get_or_insert(greads);
        println!(
            "{name:<22} {greads:>10.2} {:>10.1} {:>8.2} {setup_ms:>10.0}",
            greads * 32.0,
            greads / local_rate
        );
    }
}

/// Pinned host memory from `cuMemHostAlloc`, mapped into the device's
/// address space: the plain alternative to a window's host chunks.
struct MappedHost {
    host: *mut std::ffi::c_void,
    device: u64,
}

impl MappedHost {
    fn new(gpu: &Gpu, bytes: u64) -> MappedHost {
        use cudarc::driver::sys;
        gpu.ctx.bind_to_thread().unwrap();
        let mut host = std::ptr::null_mut();
        let mut device = 0;
        // SAFETY: out-parameters of the allocation and its device address; freed in `Drop`.
        unsafe {
            sys::cuMemHostAlloc(&mut host, bytes as usize, sys::CU_MEMHOSTALLOC_DEVICEMAP).result().unwrap();
            sys::cuMemHostGetDevicePointer_v2(&mut device, host, 0).result().unwrap();
        }
        MappedHost { host, device }
    }
}

impl Drop for MappedHost {
    fn drop(&mut self) {
        // SAFETY: allocated by cuMemHostAlloc; every kernel using it was waited for.
        unsafe { cudarc::driver::sys::cuMemFreeHost(self.host) };
    }
}

/// Random reads of host memory by size, through a window of host chunks
/// and through plain mapped pinned memory: where host reads fall off a
/// cliff as the memory read grows (address translation on the way to the
/// host), and whether windows change it.
#[test]
#[ignore = "a measurement on a CUDA GPU: run it by name with --include-ignored --nocapture"]
fn host_read_speed_by_size() {
    let _memory = exclusive();
    let Some(gpu) = gpu_or_skip("host read speed") else { return };
    let gpus = vec![gpu.clone()];
    println!("{} ({}): dependent random 32-byte reads of host memory", gpu.name, gpu.label());
    println!("{:>10} {:>16} {:>16}", "MiB", "window G reads/s", "mapped G reads/s");
    for bytes in [64u64 << 20, 256 << 20, 512 << 20, 1 << 30, 2 << 30] {
        const CHUNK: u64 = 32 << 20;
        let homes = vec![Host; (bytes / CHUNK) as usize];
        let window = ChunkWindow::new(&gpus, CHUNK, &ChunkPlacement { homes }, &[]).unwrap();
        let through_window = random_read_rate(&gpu, window.base(0), bytes);
        drop(window);
        let mapped = MappedHost::new(&gpu, bytes);
        let plain = random_read_rate(&gpu, mapped.device, bytes);
        gpu.stream.synchronize().unwrap();
        drop(mapped);
        println!("{:>10} {through_window:>16.3} {plain:>16.3}", bytes >> 20);
    }
}
