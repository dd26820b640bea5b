//! Processes started by `mpirun` rendering one frame together (the `mpi`
//! feature): one process per node, or per GPU, each rendering on its own
//! devices with its own copy of the scene. A program using atoll as a
//! library hands it a communicator of its own instead of the world
//! ([`Ranks::with_communicator`], then [`Ranks::render`]). MPI (Open MPI on Debian) carries
//! all of it, with no protocol of our own: point-to-point messages hand out
//! the waves from rank 0 ([`RankWaves`]), collectives decide together
//! whether everybody is ready, and sum the films at the end.
//!
//! Device threads ask for waves themselves, so MPI must allow calls from
//! any thread (`MPI_THREAD_MULTIPLE`; Open MPI 4.1 gives it).

use std::mem::size_of;
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use atoll_render::{Device, DeviceError, Film, ProcessLink, Queue, RayRecord, RenderOptions};
use atoll_scene::Scene;
use bytemuck::Zeroable;
use glam::UVec2;
use mpi::collective::SystemOperation;
use mpi::datatype::PartitionMut;
use mpi::environment::Universe;
use mpi::topology::{Color, SimpleCommunicator};
use mpi::traits::*;
use mpi::Threading;

use crate::handout::{Joined, Joining, Pace, Pacing, Speed, WaveHandout};
use crate::layout::Layout;
use crate::render::{render_multi_with, DeviceReport, MultiFrame, MultiOutput, Shared};
use crate::ring::{RingError, RingPeers, RingPlace};
use crate::transport::read_for_sending;
use crate::vote::Vote;
use crate::RingOrder;

/// Tag of a request for a wave (rank ≠ 0 to rank 0).
const TAKE: i32 = 701;
/// Tag of the answer: a wave index, or −1 when none is left.
const GIVE: i32 = 702;

/// How long a waiting rank sleeps between looks at the network. Blocking
/// MPI calls spin on a core in Open MPI; ranks sharing a machine (tests,
/// one rank per GPU) would take it from the devices. Waves last
/// milliseconds, so 0.2 ms of latency costs nothing.
const POLL: Duration = Duration::from_micros(200);

/// Why MPI could not be set up for atoll.
#[derive(Debug, thiserror::Error)]
pub enum MpiInitError {
    /// MPI was initialised already in this process.
    #[error("MPI was initialised already in this process")]
    AlreadyInitialised,
    /// A caller's communicator was given before MPI was initialised.
    #[error("MPI is not initialised: initialise it before handing atoll a communicator")]
    NotInitialised,
    /// The library grants less than calls from any thread.
    #[error("the MPI library allows calls from {0} threads; atoll's device threads need Multiple")]
    Threading(String),
}

/// This process's place among the processes rendering together: all that
/// `mpirun` started ([`Ranks::init`]), or those of a caller's communicator
/// ([`Ranks::with_communicator`]).
pub struct Ranks {
    /// The ranks' own communicator (MPI_COMM_WORLD, or a duplicate of the
    /// caller's, so that atoll's messages never meet the caller's).
    world: Arc<AnyThread>,
    /// This process's place among those of its node.
    local_rank: usize,
    /// When atoll initialised MPI: dropping it finalises MPI.
    _universe: Option<Universe>,
}

impl Ranks {
    /// Initialises MPI (once per process), asking for calls from any
    /// thread; every process `mpirun` started renders.
    pub fn init() -> Result<Ranks, MpiInitError> {
        let (universe, threading) =
            mpi::initialize_with_threading(Threading::Multiple).ok_or(MpiInitError::AlreadyInitialised)?;
        if threading < Threading::Multiple {
            return Err(MpiInitError::Threading(format!("{threading:?}")));
        }
        Ok(Ranks::over(universe.world(), Some(universe)))
    }

    /// The processes of `comm`, a communicator of a program that uses
    /// atoll as a library and initialised MPI itself (with calls from any
    /// thread): they render together, the others not at all. Every process
    /// of `comm` calls it (it duplicates `comm`). The caller keeps MPI and
    /// finalises it after dropping the ranks.
    pub fn with_communicator(comm: &impl Communicator) -> Result<Ranks, MpiInitError> {
        if !mpi::environment::is_initialized() {
            return Err(MpiInitError::NotInitialised);
        }
        let threading = mpi::environment::threading_support();
        if threading < Threading::Multiple {
            return Err(MpiInitError::Threading(format!("{threading:?}")));
        }
        Ok(Ranks::over(comm.duplicate(), None))
    }

    fn over(comm: SimpleCommunicator, universe: Option<Universe>) -> Ranks {
        // The processes that share this one's memory: its node.
        let local_rank = comm.split_shared(comm.rank()).rank() as usize;
        Ranks { world: Arc::new(AnyThread(comm)), local_rank, _universe: universe }
    }

    /// Renders one frame with every rank, each on its `devices` holding
    /// the whole scene as `layout` places it on them (replicate or shared
    /// scene memory; rings of ranks are planned by the caller, see
    /// [`render_multi_with`]): rank 0 hands out the waves as devices free
    /// up. Returns, on rank 0, every rank's film summed; elsewhere the
    /// rank's own share. A collective; a rank that fails fails every rank.
    pub fn render(
        &self,
        devices: &mut [Box<dyn Device>],
        scene: &Arc<Scene>,
        options: RenderOptions,
        layout: &Layout,
    ) -> Result<MultiOutput, DeviceError> {
        let handout = self.waves();
        let frame = MultiFrame {
            layout,
            transport: None,
            warmup: false,
            shared: Some(Shared { handout: &handout, rings: &[] }),
        };
        let films = match devices.first_mut() {
            Some(first) => self.link_films(first.as_mut(), true, options.resolution).ok(),
            None => None,
        };
        let mut out = render_multi_with(devices, scene, options, &frame, &mut |_, _| {})?;
        self.sum_films(&mut out.film, films.as_ref().zip(devices.first_mut().map(|d| d.as_mut())))?;
        Ok(out)
    }

    /// This process's place among the processes of its node (which GPU
    /// it takes, one per rank).
    pub fn local_rank(&self) -> usize {
        self.local_rank
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

    /// Collective: the smallest and the largest of every process's `value`.
    pub fn extremes(&self, value: u64) -> (u64, u64) {
        let mut largest = [0u64; 2];
        // One reduction: the largest of the complements is the smallest.
        self.world.all_reduce_into(&[!value, value][..], &mut largest[..], SystemOperation::max());
        (!largest[0], largest[1])
    }

    /// Collective: the largest of every process's `value`.
    pub fn max(&self, value: f64) -> f64 {
        let mut largest = 0f64;
        self.world.all_reduce_into(&value, &mut largest, SystemOperation::max());
        largest
    }

    /// Collective: rank 0's `bytes` on every process (an NCCL
    /// communicator's unique id, say).
    pub fn broadcast(&self, bytes: &mut [u8]) {
        self.world.process_at_rank(0).broadcast_into(bytes);
    }

    /// Collective: links every rank's `device` (its first) for summing
    /// films device to device, where every rank's offers the same process
    /// transport (NCCL between GPUs) and `wanted` (false where films were
    /// asked to go through the host); else why not, and films are summed
    /// over MPI.
    /// The link's first sum, of a film of `resolution`, is done here: NCCL
    /// makes its connections on a communicator's first collective, which
    /// would otherwise fall in the frame.
    pub fn link_films(
        &self,
        device: &mut dyn Device,
        wanted: bool,
        resolution: UVec2,
    ) -> Result<FilmLink, String> {
        let joiners = vec![(&mut *device, self.rank(), self.size())];
        let (name, mut links) = join_process_links(&self.world, joiners, self.is_root(), wanted)?;
        let link = FilmLink { name, link: links.pop().expect("one link per joining device") };
        let mut blank = Film::new(resolution);
        let warmed = link.link.sum_film(device, &mut blank, 0).map_err(|e| e.to_string());
        let mut all = 0u8;
        self.world.all_reduce_into(&u8::from(warmed.is_ok()), &mut all, SystemOperation::min());
        joined_together(warmed, all == 1)?;
        Ok(link)
    }

    /// Collective: every process's film summed into rank 0's (the others'
    /// are left as they were), over `link` through its device where given
    /// (every rank must give one then), else over MPI.
    pub fn sum_films<'d>(
        &self,
        film: &mut Film,
        link: Option<(&FilmLink, &mut (dyn Device + 'd))>,
    ) -> Result<(), DeviceError> {
        match link {
            Some((link, device)) => link.link.sum_film(device, film, 0),
            None => {
                self.sum_films_over_mpi(film);
                Ok(())
            }
        }
    }

    fn sum_films_over_mpi(&self, film: &mut Film) {
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

    /// Collective: rings of `size` consecutive ranks, each rank holding
    /// `per_rank` consecutive members (its devices; the ring is
    /// `size * per_rank` long, and a queue visits a rank's members before
    /// it goes on to the next rank's, as barney's two-level exchange
    /// does). Rank r is the `r mod size`-th rank of ring `r / size`, its
    /// device d member `(r mod size) * per_rank + d`. There are `islands`
    /// rings over the same ranks, one per wavefront each device renders
    /// with. Returned island by island, a rank's members in order: the
    /// order of `Layout::Ring`'s devices. Queues move between members as
    /// MPI messages, each island on a communicator of its own. `None` for
    /// the ranks past the last whole ring. Every rank must ask for the
    /// same rings.
    pub fn rings(
        &self,
        size: usize,
        per_rank: usize,
        order: RingOrder,
        islands: usize,
    ) -> Option<Vec<RankRing>> {
        let rank = self.rank();
        let (size, per_rank, islands) = (size.max(1), per_rank.max(1), islands.max(1));
        let ring = rank / size;
        let whole = ring < self.size() / size;
        let color = if whole { Color::with_value(ring as i32) } else { Color::undefined() };
        let comm = self.world.split_by_color(color)?;
        let mut rings = Vec::with_capacity(islands * per_rank);
        for k in 0..islands {
            // A communicator per island: the islands' steps reuse tags.
            let steps = Arc::new(AnyThread(comm.duplicate()));
            let here = Arc::new(Vote::new(per_rank));
            for d in 0..per_rank {
                rings.push(RankRing {
                    comm: steps.clone(),
                    // (Collectives on one communicator must not overlap:
                    // each member votes on its own.)
                    votes: AnyThread(comm.duplicate()),
                    here: here.clone(),
                    per_rank,
                    place: RingPlace {
                        size: size * per_rank,
                        member: (rank % size) * per_rank + d,
                        island: ring * islands + k,
                        order,
                    },
                    steps: AtomicI32::new(0),
                    outgoing: Mutex::default(),
                    incoming: Mutex::default(),
                    link: None,
                });
            }
        }
        Some(rings)
    }

    /// The waves of the next frame, shared by every process.
    pub fn waves(&self) -> RankWaves {
        RankWaves {
            comm: self.world.clone(),
            rank: self.rank(),
            size: self.size(),
            counter: Arc::new(Counter::default()),
            workers: AtomicUsize::new(0),
            started: Mutex::new(Instant::now()),
            pacing: Mutex::new(Pacing::default()),
            taken_here: AtomicUsize::new(0),
            asking: Mutex::new(()),
            exhausted: AtomicBool::new(false),
            server: Mutex::new(None),
        }
    }
}

/// The ranks' link for summing their films device to device
/// ([`Ranks::link_films`]).
pub struct FilmLink {
    name: &'static str,
    link: Box<dyn ProcessLink>,
}

impl FilmLink {
    /// The transport's name (NCCL).
    pub fn name(&self) -> &'static str {
        self.name
    }
}

/// One member's links to the other members of its ring of ranks (see
/// [`Ranks::rings`]): queues go to the next member as MPI messages (or
/// device to device, [`RankRing::connect_devices`]), each member polling
/// for the previous one's while its own is on the way; the end-of-frame
/// vote is taken among a rank's members, then all-reduced over the ranks.
/// A ring is stepped by one device thread at a time, but islands step on
/// threads of their own, so its state is behind locks.
pub struct RankRing {
    /// The island's communicator, shared by a rank's members: queues and
    /// counts.
    comm: Arc<AnyThread>,
    /// This member's own duplicate of it: the end-of-frame votes.
    votes: AnyThread,
    /// The vote among this rank's members of the island, taken first.
    here: Arc<Vote>,
    /// Members per rank.
    per_rank: usize,
    place: RingPlace,
    /// Steps taken: each one's messages carry its tag, so that a step's
    /// queue is never taken for another's.
    steps: AtomicI32,
    /// The queue going out and the one coming in, kept from step to step.
    outgoing: Mutex<Vec<RayRecord>>,
    incoming: Mutex<Vec<RayRecord>>,
    /// Where every member's device offers it, the devices' own link
    /// ([`RankRing::connect_devices`]): records then go device to device,
    /// and MPI carries only their counts.
    link: Option<Mutex<Box<dyn ProcessLink>>>,
}

/// A communicator that any thread may use: [`Ranks::init`] makes sure MPI
/// allows calls from every thread (`MPI_THREAD_MULTIPLE`).
struct AnyThread(SimpleCommunicator);

// SAFETY: the handle names a communicator of an MPI library initialised
// with MPI_THREAD_MULTIPLE (`Ranks::init` refuses less), which makes calls
// on it from any thread, at once, safe.
unsafe impl Send for AnyThread {}
// SAFETY: as for Send.
unsafe impl Sync for AnyThread {}

impl std::ops::Deref for AnyThread {
    type Target = SimpleCommunicator;
    fn deref(&self) -> &SimpleCommunicator {
        &self.0
    }
}

impl RankRing {
    /// Collective over the ring: where every member's device offers the
    /// same kind of process transport (NCCL between GPUs), member 0 makes
    /// the link's id, the other ranks receive it over the ring's
    /// communicator, and every member joins it; queues then move device to
    /// device. `members` are this rank's members of one island and
    /// `devices` theirs, in order. Returns the transport's name, or why not
    /// (queues then stay MPI messages through the host).
    /// Every rank calls it, with `wanted` false where the host transport
    /// was asked for (then no member connects).
    pub fn connect_devices(
        members: &mut [RankRing],
        devices: &mut [Box<dyn Device>],
        wanted: bool,
    ) -> Result<&'static str, String> {
        let Some(first) = members.first() else { return Err("no members on this rank".into()) };
        let comm = first.comm.clone();
        let makes_id = members.iter().any(|m| m.place.member == 0);
        let joiners = members
            .iter()
            .zip(devices.iter_mut())
            .map(|(m, d)| (d.as_mut(), m.place.member, m.place.size))
            .collect();
        let (name, links) = join_process_links(&comm, joiners, makes_id, wanted)?;
        for (member, link) in members.iter_mut().zip(links) {
            member.link = Some(Mutex::new(link));
        }
        Ok(name)
    }

    /// Where this member's step goes and comes from: the ranks (in the
    /// ring's communicator) of its successor and predecessor, and the tag
    /// of `step`'s messages to the successor and from the predecessor.
    fn route(&self, step: i32) -> Route {
        route(self.place, self.per_rank, step)
    }

    /// Tells the successor how many records come, and learns how many come
    /// from the predecessor.
    fn swap_counts(&self, sending: usize, route: &Route) -> usize {
        let (next, prev) = (self.comm.process_at_rank(route.next), self.comm.process_at_rank(route.prev));
        let mine = sending as u64;
        let mut theirs = 0u64;
        mpi::request::scope(|scope| {
            let sent = next.immediate_send_with_tag(scope, &mine, route.sent_tag);
            let received = prev.immediate_receive_into_with_tag(scope, &mut theirs, route.received_tag);
            sleep_until_done(received);
            sleep_until_done(sent);
        });
        theirs as usize
    }
}

/// A ring step's messages (see [`route`]).
#[derive(Debug, PartialEq, Eq)]
struct Route {
    /// The successor's and predecessor's ranks in the ring's communicator.
    next: i32,
    prev: i32,
    /// The successor's member index, and the predecessor's (the link's ranks).
    next_member: usize,
    prev_member: usize,
    /// Tags of the message sent and of the one received.
    sent_tag: i32,
    received_tag: i32,
}

/// Step `step`'s route for the member at `place` of a ring holding
/// `per_rank` members on each rank: a member's messages are tagged with
/// the step and the receiver's place on its rank, so that a rank's
/// members never take each other's.
fn route(place: RingPlace, per_rank: usize, step: i32) -> Route {
    let (next, prev) = neighbours(place);
    let tag = |member: usize| step * per_rank as i32 + (member % per_rank) as i32;
    Route {
        next: (next / per_rank) as i32,
        prev: (prev / per_rank) as i32,
        next_member: next,
        prev_member: prev,
        sent_tag: tag(next),
        received_tag: tag(place.member),
    }
}

/// `place`'s successor and predecessor: every step, member m sends to the
/// first and receives from the second.
fn neighbours(place: RingPlace) -> (usize, usize) {
    let RingPlace { size, member, .. } = place;
    ((member + 1) % size, (member + size - 1) % size)
}

/// This process's links of one kind, one per joining device.
type ProcessLinks = Vec<Box<dyn ProcessLink>>;

/// Collective over `comm`: where every process's joining devices offer
/// the same kind of process transport (NCCL between GPUs), the process
/// that `makes_id` (`comm`'s rank 0) makes the link's id, the others
/// receive it over `comm`, and every device joins as its place of a link
/// of the size given, a process's devices at once on threads of their own
/// (joining waits for every member). Returns the transport's name and
/// the links, or why not. Every process calls it, with `wanted` false
/// where the host transport was asked for (then none connects).
fn join_process_links<'b>(
    comm: &SimpleCommunicator,
    joiners: Vec<(&mut (dyn Device + 'b), usize, usize)>,
    makes_id: bool,
    wanted: bool,
) -> Result<(&'static str, ProcessLinks), String> {
    let transports: Vec<_> = joiners.iter().map(|(d, ..)| d.process_transport().filter(|_| wanted)).collect();
    let mut all = [0u8; 2];
    let mine = [u8::from(!wanted), u8::from(transports.iter().any(Option::is_none))];
    comm.all_reduce_into(&mine[..], &mut all[..], SystemOperation::max());
    let agreed = transport_vote(all);
    let transports: Option<Vec<_>> = transports.into_iter().collect();
    let Some(transports) = transports.filter(|t| agreed.is_ok() && !t.is_empty()) else {
        return Err(agreed.err().unwrap_or("this rank has no device transport").into());
    };
    let name = transports[0].name();
    // The id's length first (0: the first process could not make one).
    let root = comm.process_at_rank(0);
    let mut id = if makes_id { transports[0].new_id().unwrap_or_default() } else { Vec::new() };
    let mut len = id.len() as u64;
    root.broadcast_into(&mut len);
    if len == 0 {
        return Err("the first rank could not make an NCCL id".into());
    }
    id.resize(len as usize, 0);
    root.broadcast_into(&mut id[..]);
    let id = &id;
    let joined: Vec<Result<Box<dyn ProcessLink>, String>> = std::thread::scope(|scope| {
        let joining: Vec<_> = joiners
            .into_iter()
            .zip(&transports)
            .map(|((device, place, size), transport)| {
                scope.spawn(move || transport.connect(device, id, place, size))
            })
            .collect();
        joining
            .into_iter()
            .map(|h| h.join().expect("joining NCCL panicked").map_err(|e| e.to_string()))
            .collect()
    });
    let mut all = 0u8;
    comm.all_reduce_into(&u8::from(joined.iter().all(Result::is_ok)), &mut all, SystemOperation::min());
    let links: Result<Vec<_>, String> =
        joined.into_iter().map(|link| joined_together(link, all == 1)).collect();
    Ok((name, links?))
}

/// Whether a ring's members link their devices, from the largest of
/// every member's [asked for the host transport, has no device
/// transport]: only when no member says either; else why not.
fn transport_vote(largest: [u8; 2]) -> Result<(), &'static str> {
    match largest {
        [0, 0] => Ok(()),
        [1, _] => Err("the host transport was asked for"),
        _ => Err("not every rank has a GPU with NCCL"),
    }
}

/// A member's link once every member tried to join: kept only when all
/// joined (`everyone`), so that no member steps over a link its
/// neighbour lacks; this member's own failure is said first.
fn joined_together<L>(mine: Result<L, String>, everyone: bool) -> Result<L, String> {
    match (mine, everyone) {
        (Ok(link), true) => Ok(link),
        (Err(e), _) => Err(e),
        (Ok(_), false) => Err("another rank could not join NCCL".into()),
    }
}

/// An empty queue still goes as one byte: Open MPI reads the address of an
/// empty buffer (Rust's dangling 0x1) as MPI_IN_PLACE.
const EMPTY_QUEUE: [u8; 1] = [0];

impl RingPeers for RankRing {
    fn place(&self) -> RingPlace {
        self.place
    }

    fn any(&self, mine: bool) -> (bool, Duration) {
        let start = Instant::now();
        // This rank's members agree first, then each asks the others' (all
        // of a rank's members carry the same vote).
        let (mine, mut any) = (self.here.any(mine).0 as u8, 0u8);
        mpi::request::scope(|scope| {
            let vote = self.votes.immediate_all_reduce_into(scope, &mine, &mut any, SystemOperation::max());
            sleep_until_done(vote);
        });
        (any != 0, start.elapsed())
    }

    fn pass(
        &self,
        device: &mut dyn Device,
        queue: Queue,
        report: &mut DeviceReport,
    ) -> Result<(), RingError> {
        let step = self.steps.load(Ordering::Relaxed);
        // (Every step's tags are the step's members' places: see `route`.)
        self.steps.store((step + 1) % (RING_TAGS / self.per_rank as i32), Ordering::Relaxed);
        let route = self.route(step);
        if let Some(link) = &self.link {
            let link = link.lock().unwrap_or_else(|p| p.into_inner());
            // A member whose device failed sends nothing but still steps.
            let sending = report.keep(device.queue_len(queue), 0);
            let waited = Instant::now();
            let receiving = self.swap_counts(sending, &route);
            let exchanged =
                link.exchange(device, queue, (sending, route.next_member), (receiving, route.prev_member));
            report.keep(exchanged, ());
            report.wait_seconds += waited.elapsed().as_secs_f64();
            report.bytes_sent += (sending * size_of::<RayRecord>()) as u64;
            return Ok(());
        }
        let mut outgoing = self.outgoing.lock().unwrap_or_else(|p| p.into_inner());
        let mut incoming = self.incoming.lock().unwrap_or_else(|p| p.into_inner());
        read_for_sending(device, queue, &mut outgoing, report);
        let bytes: &[u8] = if outgoing.is_empty() { &EMPTY_QUEUE } else { bytemuck::cast_slice(&outgoing) };
        let next = self.comm.process_at_rank(route.next);
        let prev = self.comm.process_at_rank(route.prev);
        let waited = Instant::now();
        mpi::request::scope(|scope| {
            let sent = next.immediate_send_with_tag(scope, bytes, route.sent_tag);
            let mut backoff = Backoff::new();
            let (message, status) = loop {
                if let Some(probed) = prev.immediate_matched_probe_with_tag(route.received_tag) {
                    break probed;
                }
                backoff.wait();
            };
            // Received straight into the records (their allocation kept
            // from step to step); one byte is an empty queue.
            let length = status.count(u8::equivalent_datatype()) as usize;
            incoming.resize(length / size_of::<RayRecord>(), RayRecord::zeroed());
            match incoming.is_empty() {
                true => drop(message.matched_receive_into(&mut [0u8][..])),
                false => drop(
                    message.matched_receive_into(bytemuck::cast_slice_mut::<RayRecord, u8>(&mut incoming)),
                ),
            }
            sleep_until_done(sent);
        });
        report.wait_seconds += waited.elapsed().as_secs_f64();
        let written = device.write_queue(queue, &incoming);
        report.keep(written, ());
        Ok(())
    }
}

/// Tags of ring steps, reused in turn (MPI guarantees tags up to 32767).
const RING_TAGS: i32 = 1 << 14;

/// Waits for `request`, looking at it as [`Backoff`] says.
fn sleep_until_done<'a, D: ?Sized, S: mpi::request::Scope<'a>>(mut request: mpi::request::Request<'a, D, S>) {
    let mut backoff = Backoff::new();
    loop {
        match request.test() {
            Ok(_) => return,
            Err(pending) => request = pending,
        }
        backoff.wait();
    }
}

/// How a rank waits between looks at the network: yielding its core for
/// the first [`Backoff::SPIN`] (a ring step's counts and votes come within
/// microseconds, and every one of them holds a GPU idle), then sleeping,
/// twice as long each time, up to [`POLL`].
struct Backoff {
    started: Instant,
    sleep: Duration,
}

impl Backoff {
    const SPIN: Duration = Duration::from_micros(50);

    fn new() -> Backoff {
        Backoff { started: Instant::now(), sleep: Duration::from_micros(10) }
    }

    fn wait(&mut self) {
        if self.started.elapsed() < Self::SPIN {
            std::thread::yield_now();
            return;
        }
        std::thread::sleep(self.sleep);
        self.sleep = (self.sleep * 2).min(POLL);
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
/// has been told that none are left for it. Each request says how fast its
/// rank renders, so that near the end a rank too slow to finish another
/// wave before the others finish the rest is told to stop ([`Pace`]).
pub struct RankWaves {
    comm: Arc<AnyThread>,
    rank: usize,
    size: usize,
    /// Rank 0: the waves, and who may take them.
    counter: Arc<Counter>,
    /// This process's workers (devices or rings taking waves).
    workers: AtomicUsize,
    /// When this frame's waves began.
    started: Mutex<Instant>,
    /// How this process takes waves (for its speed).
    pacing: Mutex<Pacing>,
    /// Waves this process's devices took.
    taken_here: AtomicUsize,
    /// Other ranks: one request in flight, so answers come back in order.
    asking: Mutex<()>,
    /// No more waves for this rank.
    exhausted: AtomicBool,
    /// Rank 0: the thread answering the others.
    server: Mutex<Option<JoinHandle<()>>>,
}

/// Rank 0's count of a frame's waves.
#[derive(Default)]
struct Counter {
    waves: AtomicUsize,
    next: AtomicUsize,
    pace: Mutex<Pace>,
}

impl Counter {
    /// The next wave for `rank`, going at `speed` with `backlog` seconds of
    /// waves in hand; `None` when all are taken or `rank` should take no more.
    fn take(&self, rank: usize, (speed, backlog): (Option<Speed>, f64)) -> Option<usize> {
        let waves = self.waves.load(Ordering::Relaxed);
        let mut pace = self.pace.lock().unwrap_or_else(|p| p.into_inner());
        // (A refusal is final: the rank is told none are left.)
        pace.report(rank, speed, backlog);
        let remaining = waves.saturating_sub(self.next.load(Ordering::Relaxed));
        if remaining == 0 || !pace.allows(rank, remaining) {
            return None;
        }
        let i = self.next.fetch_add(1, Ordering::Relaxed);
        (i < waves).then_some(i)
    }
}

impl RankWaves {
    /// How fast this process renders, and the seconds it still needs for
    /// the waves it holds ([`Speed::judged`]).
    fn speed(&self) -> (Option<Speed>, f64) {
        let seconds = self.started.lock().unwrap_or_else(|p| p.into_inner()).elapsed().as_secs_f64();
        // The process's workers as one taker.
        let (in_flight, warmed) = self.pacing.lock().unwrap_or_else(|p| p.into_inner()).together();
        let taken = self.taken_here.load(Ordering::Relaxed);
        Speed::judged(taken, in_flight, seconds, self.workers.load(Ordering::Relaxed), warmed)
    }

    /// Rank ≠ 0: asks rank 0 for the next wave, saying how fast this rank goes.
    fn ask(&self) -> Option<usize> {
        let _one_at_a_time = self.asking.lock().unwrap_or_else(|p| p.into_inner());
        if self.exhausted.load(Ordering::Acquire) {
            return None;
        }
        let root = self.comm.process_at_rank(0);
        let request = match self.speed() {
            (Some(speed), backlog) => [speed.seconds_per_wave, speed.workers as f64, backlog],
            (None, _) => [-1.0, 0.0, 0.0],
        };
        root.send_with_tag(&request[..], TAKE);
        let mut backoff = Backoff::new();
        let answer = loop {
            if let Some((message, _)) = root.immediate_matched_probe_with_tag(GIVE) {
                break message.matched_receive::<i64>().0;
            }
            backoff.wait();
        };
        if answer < 0 {
            self.exhausted.store(true, Ordering::Release);
            return None;
        }
        Some(answer as usize)
    }
}

/// Rank 0's answering thread: one answer per request, until each of the
/// other `ranks - 1` has been told that no wave is left for it.
fn serve(counter: Arc<Counter>, ranks: usize, world: Arc<AnyThread>) {
    let mut told_done = 0;
    while told_done + 1 < ranks {
        let Some(probed) = world.any_process().immediate_matched_probe_with_tag(TAKE) else {
            std::thread::sleep(POLL);
            continue;
        };
        let (request, status) = probed.matched_receive_vec::<f64>();
        let speed = match request[..] {
            [seconds_per_wave, workers, backlog] if seconds_per_wave > 0.0 => {
                (Some(Speed { seconds_per_wave, workers: workers as usize }), backlog)
            }
            _ => (None, 0.0),
        };
        let asker = status.source_rank();
        let answer = counter.take(asker as usize, speed).map_or(-1, |i| i as i64);
        told_done += (answer < 0) as usize;
        world.process_at_rank(asker).send_with_tag(&answer, GIVE);
    }
}

impl WaveHandout for RankWaves {
    fn join(&self, me: Joining) -> Result<Joined, DeviceError> {
        let world = &self.comm;
        let sums = [(!me.ready) as u64, me.workers as u64];
        let mut summed = [0u64; 2];
        world.all_reduce_into(&sums[..], &mut summed[..], SystemOperation::sum());
        // Smallest values as the largest of their complements.
        let maxima = [!(me.wave_size as u64), me.samples, !me.samples];
        let mut largest = [0u64; 3];
        world.all_reduce_into(&maxima[..], &mut largest[..], SystemOperation::max());
        let [failed, workers] = summed;
        let (wave_size, samples) = (!largest[0] as u32, (!largest[2], largest[1]));
        let error = |message: String| Err(DeviceError::Other { device: "ranks".into(), message });
        if failed > 0 {
            return error(format!("{failed} of {} ranks could not prepare their devices", self.size));
        }
        if samples.0 != samples.1 {
            return error(format!(
                "the ranks render different frames ({} to {} samples): every rank needs the same resolution and spp",
                samples.0, samples.1
            ));
        }
        self.workers.store(me.workers, Ordering::Relaxed);
        Ok(Joined { workers: workers as usize, wave_size })
    }

    fn begin(&self, waves: usize, pacing: Pacing) {
        *self.pacing.lock().unwrap_or_else(|p| p.into_inner()) = pacing;
        let counter = &self.counter;
        counter.waves.store(waves, Ordering::Relaxed);
        counter.next.store(0, Ordering::Relaxed);
        *counter.pace.lock().unwrap_or_else(|p| p.into_inner()) = Pace::new(self.size);
        self.taken_here.store(0, Ordering::Relaxed);
        self.exhausted.store(false, Ordering::Relaxed);
        if self.rank == 0 && self.size > 1 {
            let (counter, ranks, comm) = (self.counter.clone(), self.size, self.comm.clone());
            *self.server.lock().unwrap_or_else(|p| p.into_inner()) =
                Some(std::thread::spawn(move || serve(counter, ranks, comm)));
        }
        // Nobody asks before rank 0 has reset its counter and listens.
        self.comm.barrier();
        *self.started.lock().unwrap_or_else(|p| p.into_inner()) = Instant::now();
    }

    /// (Ranks are paced as wholes: `_taker` does not matter.)
    fn next(&self, _taker: usize) -> Option<usize> {
        let wave = if self.rank == 0 {
            // Once refused, rank 0's devices take no more either.
            let wave = match self.exhausted.load(Ordering::Acquire) {
                true => None,
                false => self.counter.take(0, self.speed()),
            };
            self.exhausted.store(wave.is_none(), Ordering::Release);
            wave
        } else {
            self.ask()
        };
        if wave.is_some() {
            self.taken_here.fetch_add(1, Ordering::Relaxed);
        }
        wave
    }

    fn taken(&self) -> usize {
        let counter = if self.rank == 0 { &self.counter.next } else { &self.taken_here };
        counter.load(Ordering::Relaxed).min(self.counter.waves.load(Ordering::Relaxed))
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
        sleeping_barrier(&self.comm);
    }
}

/// A barrier that sleeps between looks instead of spinning (see [`POLL`]).
fn sleeping_barrier(world: &SimpleCommunicator) {
    sleep_until_done(world.immediate_barrier());
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each member's send is the receive of the member after it, so every
    /// step's messages pair up, in rings of any size; a ring of one talks
    /// to itself.
    #[test]
    fn every_send_meets_its_receive() {
        for size in 1..=5 {
            let place = |member| RingPlace { size, member, island: 0, order: RingOrder::Spread };
            for member in 0..size {
                let (next, prev) = neighbours(place(member));
                assert_eq!(neighbours(place(next)).1, member, "{member} of {size}");
                assert_eq!(neighbours(place(prev)).0, member, "{member} of {size}");
            }
        }
    }

    /// In rings of ranks holding several members each, a member's message
    /// goes to the rank holding its successor, with the tag that member
    /// waits for; a rank's members wait for different tags, and a queue
    /// visits a rank's members before it crosses to the next rank.
    #[test]
    fn every_message_reaches_the_member_that_waits_for_it() {
        for (ranks, per_rank) in [(1, 1), (2, 1), (1, 3), (2, 2), (3, 2), (2, 4)] {
            let size = ranks * per_rank;
            let place = |member| RingPlace { size, member, island: 0, order: RingOrder::Spread };
            for step in [0, 1, RING_TAGS / per_rank as i32 - 1] {
                for member in 0..size {
                    let mine = route(place(member), per_rank, step);
                    let theirs = route(place(mine.next_member), per_rank, step);
                    assert_eq!(mine.next, (mine.next_member / per_rank) as i32);
                    assert_eq!(theirs.prev_member, member);
                    assert_eq!(theirs.prev, (member / per_rank) as i32, "{member} of {ranks}×{per_rank}");
                    assert_eq!(theirs.received_tag, mine.sent_tag, "{member} of {ranks}×{per_rank}");
                    assert!((0..RING_TAGS).contains(&mine.sent_tag));
                    // Crossing ranks only from a rank's last member.
                    let crosses = mine.next != (member / per_rank) as i32;
                    assert_eq!(crosses, ranks > 1 && member % per_rank == per_rank - 1);
                }
                let on_rank_0: Vec<i32> =
                    (0..per_rank).map(|m| route(place(m), per_rank, step).received_tag).collect();
                let mut distinct = on_rank_0.clone();
                distinct.dedup();
                assert_eq!(distinct, on_rank_0);
            }
        }
    }

    /// Devices link only when every member can and wants to; the host
    /// being asked for is said before a missing GPU.
    #[test]
    fn the_ring_links_devices_only_when_every_member_can() {
        assert_eq!(transport_vote([0, 0]), Ok(()));
        assert_eq!(transport_vote([1, 0]), Err("the host transport was asked for"));
        assert_eq!(transport_vote([1, 1]), Err("the host transport was asked for"));
        assert_eq!(transport_vote([0, 1]), Err("not every rank has a GPU with NCCL"));
    }

    #[test]
    fn a_link_stands_only_when_every_member_joined() {
        assert_eq!(joined_together(Ok(7), true), Ok(7));
        assert_eq!(joined_together(Ok(7), false), Err("another rank could not join NCCL".into()));
        assert_eq!(joined_together::<u8>(Err("mine".into()), false), Err("mine".into()));
    }
}
