//! Moving a ring's queues from device to device without the host, for the
//! device kinds that can (GPUs writing into each other's memory). The
//! strategy orders the steps on the host; what a step does on the devices
//! (copies, events) stays inside the device crate.
//!
//! Per ring step, on every member's thread:
//! 1. [`DirectRing::open`]: the member makes room for the queue it will
//!    receive and marks that its earlier work is queued;
//! 2. a barrier of the ring's members (the strategy's);
//! 3. [`DirectRing::send`]: the member's queue goes into its successor's
//!    room, after the successor's earlier work;
//! 4. once the predecessor has sent (the strategy says so through its own
//!    channel), [`DirectRing::accept`] makes what arrived the member's queue.
//!
//! None of these waits for the devices: each is queued work, ordered on the
//! devices themselves.

use crate::device::{Device, DeviceError, Queue};
use crate::film::Film;

/// A direct transport a device kind offers ([`Device::direct_transport`]).
pub trait DirectTransport: Send + Sync {
    /// What it is, for messages.
    fn name(&self) -> &'static str;

    /// Connects `ring` (member i sends to member i + 1, the last to the
    /// first): direct access between its devices, what sending needs on
    /// each. Fails when a member is not a device of this transport's kind.
    fn connect(&self, ring: &mut [Box<dyn Device>]) -> Result<Box<dyn DirectRing>, DeviceError>;
}

/// One connected ring ([`DirectTransport::connect`]); `member` is a
/// device's place in it, `step` counts the ring's hand-overs from 0.
pub trait DirectRing: Send + Sync {
    /// Step part 1: room for the incoming `queue`, and a mark that the
    /// member's earlier work is queued.
    fn open(
        &self,
        member: usize,
        device: &mut dyn Device,
        queue: Queue,
        step: usize,
    ) -> Result<(), DeviceError>;

    /// Step part 2, after every member opened: sends the member's `queue`
    /// into its successor's room.
    fn send(
        &self,
        member: usize,
        device: &mut dyn Device,
        queue: Queue,
        step: usize,
    ) -> Result<(), DeviceError>;

    /// Step part 3, after the predecessor sent: what it sent becomes the
    /// member's `queue`.
    fn accept(
        &self,
        member: usize,
        device: &mut dyn Device,
        queue: Queue,
        step: usize,
    ) -> Result<(), DeviceError>;

    /// Ray-record bytes `device` sent over the frame (counted where the
    /// sending happens: the host may never learn the queue lengths).
    fn bytes_sent(&self, device: &mut dyn Device) -> Result<u64, DeviceError>;
}

/// A transport between devices of different processes (NCCL for GPUs),
/// for rings whose members are processes with one device each
/// ([`Device::process_transport`]). The ring's first process makes an id
/// ([`ProcessTransport::new_id`]) that reaches the others over the
/// caller's own channel (MPI); then every process joins with it.
pub trait ProcessTransport: Send + Sync {
    /// What it is, for messages.
    fn name(&self) -> &'static str;

    /// A new id for one ring's link.
    fn new_id(&self) -> Result<Vec<u8>, DeviceError>;

    /// Joins the link of `size` processes that `id` names, as `rank`, with
    /// `device`. Every process of the ring calls it at once.
    fn connect(
        &self,
        device: &mut dyn Device,
        id: &[u8],
        rank: usize,
        size: usize,
    ) -> Result<Box<dyn ProcessLink>, DeviceError>;
}

/// One process's link into its ring, or into the ranks' film sum
/// ([`ProcessTransport::connect`]).
pub trait ProcessLink: Send {
    /// One ring step: the first `sending` records of `device`'s `queue` go
    /// to rank `next`, and `receiving` records from rank `prev` become the
    /// queue (the caller swapped the counts). May return before they are
    /// there: the device's later work waits for them.
    fn exchange(
        &self,
        device: &mut dyn Device,
        queue: Queue,
        sending: (usize, usize),
        receiving: (usize, usize),
    ) -> Result<(), DeviceError>;

    /// Sums every process's `film` into the film of the process that is
    /// rank `root` of the link, through `device` (the others' films are
    /// left as they were). Collective: every process of the link calls it
    /// at once, with films of one size.
    fn sum_film(&self, device: &mut dyn Device, film: &mut Film, root: usize) -> Result<(), DeviceError>;
}
