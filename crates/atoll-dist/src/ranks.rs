//! Processes started by `mpirun` rendering one frame together (the `mpi`
//! feature): one process per node, or per GPU, each rendering on its own
//! devices with its own copy of the scene. MPI (Open MPI on Debian) carries
//! all of it, with no protocol of our own: point-to-point messages hand out
//! the waves from rank 0 ([`RankWaves`]), collectives decide together
//! whether everybody is ready, and sum the films at the end.
//!
//! Device threads ask for waves themselves, so MPI must allow calls from
//! any thread (`MPI_THREAD_MULTIPLE`; Open MPI 4.1 gives it).

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use atoll_render::{DeviceError, Film};
use mpi::collective::SystemOperation;
use mpi::datatype::PartitionMut;
use mpi::environment::Universe;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Threading;

use crate::handout::WaveHandout;

/// Tag of a request for a wave (rank ≠ 0 to rank 0).
const TAKE: i32 = 701;
/// Tag of the answer: a wave index, or −1 when none is left.
const GIVE: i32 = 702;

/// How long a waiting rank sleeps between looks at the network. Blocking
/// MPI calls spin on a core in Open MPI; ranks sharing a machine (tests,
/// one rank per GPU) would take it from the devices. Waves last
/// milliseconds, so 0.2 ms of latency costs nothing.
const POLL: Duration = Duration::from_micros(200);

/// This process's place among the processes `mpirun` started. Dropping it
/// finalises MPI.
pub struct Ranks {
    world: SimpleCommunicator,
    _universe: Universe,
}

impl Ranks {
    /// Initialises MPI (once per process), asking for calls from any thread.
    pub fn init() -> Result<Ranks, String> {
        let (universe, threading) = mpi::initialize_with_threading(Threading::Multiple)
            .ok_or("MPI was initialised already in this process")?;
        if threading < Threading::Multiple {
            return Err(format!(
                "the MPI library allows calls from {threading:?} threads; atoll's device threads need Multiple"
            ));
        }
        Ok(Ranks { world: universe.world(), _universe: universe })
    }

    /// This process's rank (0 writes the image).
    pub fn rank(&self) -> usize {
        self.world.rank() as usize
    }

    /// Processes in all.
    pub fn size(&self) -> usize {
        self.world.size() as usize
    }

    /// Rank 0: hands out waves, gathers films, writes the image.
    pub fn is_root(&self) -> bool {
        self.world.rank() == 0
    }

    /// Collective: how many processes `failed` (so that when one cannot go
    /// on, the others stop too instead of waiting for it).
    pub fn failures(&self, failed: bool) -> usize {
        self.sum(failed as u64) as usize
    }

    /// Collective: the sum of every process's `value`.
    pub fn sum(&self, value: u64) -> u64 {
        self.sums([value])[0]
    }

    /// Collective: the sums of every process's `values`, element by element.
    pub fn sums<const N: usize>(&self, values: [u64; N]) -> [u64; N] {
        let mut totals = [0u64; N];
        self.world.all_reduce_into(&values[..], &mut totals[..], SystemOperation::sum());
        totals
    }

    /// Collective: the largest of every process's `value`.
    pub fn max(&self, value: f64) -> f64 {
        let mut largest = 0f64;
        self.world.all_reduce_into(&value, &mut largest, SystemOperation::max());
        largest
    }

    /// Collective: every process's film summed into rank 0's (the others'
    /// are left as they were).
    pub fn sum_films(&self, film: &mut Film) {
        let root = self.world.process_at_rank(0);
        let mine: &mut [f32] = bytemuck_floats(&mut film.sum);
        if self.is_root() {
            let local = mine.to_vec();
            root.reduce_into_root(&local[..], mine, SystemOperation::sum());
        } else {
            root.reduce_into(&mine[..], SystemOperation::sum());
        }
    }

    /// Collective: every process's `text`, in rank order, on rank 0 (empty
    /// elsewhere).
    pub fn gather_text(&self, text: &str) -> Vec<String> {
        // Each text goes with one more byte: Open MPI reads the address of
        // an empty buffer (Rust's dangling 0x1) as MPI_IN_PLACE.
        let mine: Vec<u8> = text.bytes().chain([0]).collect();
        let root = self.world.process_at_rank(0);
        let length = mine.len() as i32;
        if !self.is_root() {
            root.gather_into(&length);
            root.gather_varcount_into(&mine[..]);
            return Vec::new();
        }
        let mut lengths = vec![0i32; self.size()];
        root.gather_into_root(&length, &mut lengths[..]);
        let offsets: Vec<i32> =
            lengths.iter().scan(0, |at, &n| Some(std::mem::replace(at, *at + n))).collect();
        let mut bytes = vec![0u8; lengths.iter().sum::<i32>() as usize];
        let mut partition = PartitionMut::new(&mut bytes[..], &lengths[..], &offsets[..]);
        root.gather_varcount_into_root(&mine[..], &mut partition);
        offsets
            .iter()
            .zip(&lengths)
            .map(|(&at, &n)| String::from_utf8_lossy(&bytes[at as usize..(at + n - 1) as usize]).into_owned())
            .collect()
    }

    /// Collective: returns when every process has called it, sleeping
    /// while it waits (see [`POLL`]).
    pub fn wait_for_all(&self) {
        sleeping_barrier(&self.world);
    }

    /// The waves of the next frame, shared by every process.
    pub fn waves(&self) -> RankWaves {
        RankWaves {
            rank: self.rank(),
            size: self.size(),
            waves: Arc::new(AtomicUsize::new(0)),
            next: Arc::new(AtomicUsize::new(0)),
            taken_here: AtomicUsize::new(0),
            asking: Mutex::new(()),
            exhausted: AtomicBool::new(false),
            server: Mutex::new(None),
        }
    }
}

/// A film's sums as plain floats, as MPI sums them.
fn bytemuck_floats(sums: &mut [glam::Vec3]) -> &mut [f32] {
    // Vec3 is three f32 without padding (glam's scalar layout).
    bytemuck::cast_slice_mut(sums)
}

/// A frame's waves handed out by rank 0 to every process's devices, each
/// as soon as it asks: rank 0's devices take from its counter directly, the
/// other ranks' send a request and wait for the answer (one at a time per
/// rank). A thread on rank 0 answers the requests until every other rank
/// has been told that none are left.
pub struct RankWaves {
    rank: usize,
    size: usize,
    waves: Arc<AtomicUsize>,
    /// Rank 0: the next wave to hand out.
    next: Arc<AtomicUsize>,
    /// Waves this process's devices took.
    taken_here: AtomicUsize,
    /// Other ranks: one request in flight, so answers come back in order.
    asking: Mutex<()>,
    /// Other ranks: rank 0 said none are left.
    exhausted: AtomicBool,
    /// Rank 0: the thread answering the others.
    server: Mutex<Option<JoinHandle<()>>>,
}

impl RankWaves {
    /// Rank ≠ 0: asks rank 0 for the next wave.
    fn ask(&self) -> Option<usize> {
        let _one_at_a_time = self.asking.lock().unwrap_or_else(|p| p.into_inner());
        if self.exhausted.load(Ordering::Acquire) {
            return None;
        }
        let world = SimpleCommunicator::world();
        let root = world.process_at_rank(0);
        root.send_with_tag(&(self.rank as i32), TAKE);
        let answer = loop {
            if let Some((message, _)) = root.immediate_matched_probe_with_tag(GIVE) {
                break message.matched_receive::<i64>().0;
            }
            std::thread::sleep(POLL);
        };
        if answer < 0 {
            self.exhausted.store(true, Ordering::Release);
            return None;
        }
        Some(answer as usize)
    }
}

/// Rank 0's answering thread: one answer per request, until each of the
/// other `ranks - 1` has been told that no wave is left.
fn serve(next: Arc<AtomicUsize>, waves: Arc<AtomicUsize>, ranks: usize) {
    let world = SimpleCommunicator::world();
    let mut told_done = 0;
    while told_done + 1 < ranks {
        let Some((message, status)) = world.any_process().immediate_matched_probe_with_tag(TAKE) else {
            std::thread::sleep(POLL);
            continue;
        };
        let _asker: i32 = message.matched_receive().0;
        let i = next.fetch_add(1, Ordering::Relaxed);
        let answer = if i < waves.load(Ordering::Relaxed) { i as i64 } else { -1 };
        told_done += (answer < 0) as usize;
        world.process_at_rank(status.source_rank()).send_with_tag(&answer, GIVE);
    }
}

impl WaveHandout for RankWaves {
    fn join(&self, ready: bool, workers: usize) -> Result<usize, DeviceError> {
        let world = SimpleCommunicator::world();
        let mine = [(!ready) as u64, workers as u64];
        let mut all = [0u64; 2];
        world.all_reduce_into(&mine[..], &mut all[..], SystemOperation::sum());
        match all {
            [0, workers] => Ok(workers as usize),
            [failed, _] => Err(DeviceError::Other {
                device: "ranks".into(),
                message: format!("{failed} of {} ranks could not prepare their devices", self.size),
            }),
        }
    }

    fn begin(&self, waves: usize) {
        self.waves.store(waves, Ordering::Relaxed);
        self.next.store(0, Ordering::Relaxed);
        self.taken_here.store(0, Ordering::Relaxed);
        self.exhausted.store(false, Ordering::Relaxed);
        if self.rank == 0 && self.size > 1 {
            let (next, waves, ranks) = (self.next.clone(), self.waves.clone(), self.size);
            *self.server.lock().unwrap_or_else(|p| p.into_inner()) =
                Some(std::thread::spawn(move || serve(next, waves, ranks)));
        }
        // Nobody asks before rank 0 has reset its counter and listens.
        SimpleCommunicator::world().barrier();
    }

    fn next(&self) -> Option<usize> {
        let wave = if self.rank == 0 {
            let i = self.next.fetch_add(1, Ordering::Relaxed);
            (i < self.waves.load(Ordering::Relaxed)).then_some(i)
        } else {
            self.ask()
        };
        if wave.is_some() {
            self.taken_here.fetch_add(1, Ordering::Relaxed);
        }
        wave
    }

    fn taken(&self) -> usize {
        let counter = if self.rank == 0 { &self.next } else { &self.taken_here };
        counter.load(Ordering::Relaxed).min(self.waves.load(Ordering::Relaxed))
    }

    fn end(&self) {
        // A rank whose devices all failed may never have been told that
        // the waves are gone; rank 0 waits for that. What it takes here is
        // lost, but the frame is refused anyway.
        if self.rank != 0 {
            while self.ask().is_some() {}
        }
        if let Some(server) = self.server.lock().unwrap_or_else(|p| p.into_inner()).take() {
            server.join().expect("the wave server panicked");
        }
        sleeping_barrier(&SimpleCommunicator::world());
    }
}

/// A barrier that sleeps between looks instead of spinning (see [`POLL`]).
fn sleeping_barrier(world: &SimpleCommunicator) {
    let mut barrier = world.immediate_barrier();
    loop {
        match barrier.test() {
            Ok(_) => return,
            Err(pending) => barrier = pending,
        }
        std::thread::sleep(POLL);
    }
}
