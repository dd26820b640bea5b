//! The ring strategy (ray queue cycling, Wald et al. 2023): each device
//! of a ring holds one scene part; every queue visits every member to be
//! traced, then is shaded where its cycle ends. Several rings (islands)
//! share a frame's waves. Members of one process link through channels
//! ([`RingLink`]); members that are processes link through MPI
//! (`crate::ranks::RankRing`), both behind [`RingPeers`].

use std::cell::Cell;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use atoll_render::{Device, DeviceError, DirectRing, Queue, RayRecord, Wave};

use crate::handout::WaveHandout;
use crate::layout::RingOrder;
use crate::render::{on_device_threads, DeviceReport, RunShape};
use crate::transport::{read_for_sending, Handover};
use crate::vote::Vote;

/// Why a ring cannot go on.
#[derive(Debug, thiserror::Error)]
pub enum RingError {
    /// A neighbour's thread or process is gone (it panicked or failed):
    /// the frame cannot finish.
    #[error("the {0} member of the ring stopped")]
    NeighbourGone(&'static str),
}

/// A ring member's neighbours: where its queues go, where the next ones
/// come from, and with whom it decides when the frame is done. Devices of
/// one process link through channels ([`RingLink`]); a ring whose members
/// are processes links through MPI (`crate::ranks::RankRing`).
pub trait RingPeers {
    /// The ring, and this member's place in it.
    fn place(&self) -> RingPlace;
    /// Blocks until every member has voted; true when any voted true. Also
    /// how long this member waited.
    fn any(&self, mine: bool) -> (bool, Duration);
    /// Sends `device`'s `queue` to the next member and puts the previous
    /// member's in its place. An error means a neighbour is gone: the frame
    /// cannot finish.
    fn pass(&self, device: &mut dyn Device, queue: Queue, report: &mut DeviceReport)
        -> Result<(), RingError>;
}

/// A ring member's place: its ring, and where in it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RingPlace {
    /// Members of the ring.
    pub size: usize,
    /// This member's place in the ring (the scene part it holds).
    pub member: usize,
    /// Which of several rings this is (islands).
    pub island: usize,
    /// Where the ring's queues are made and shaded.
    pub order: RingOrder,
}

/// Traces `queue` with `trace` on this device, passing it on between
/// traces: after `size` traces every queue of the ring has visited every
/// member once. With [`RingOrder::Spread`] it is then shaded (or resolved)
/// where it is, not sent home: any member can shade any hit (the record
/// carries it, materials and lights are on every device, films are summed
/// at the end), and a ring of K sends K - 1 times per trace instead of K
/// (for K = 2, half the traffic); with
/// [`RingOrder::Home`] it goes on to where it was made. A closest hit
/// found earlier shortens `t_max`, so later members only report nearer
/// hits; shadow rays found occluded are skipped by the later members.
fn cycle(
    link: &dyn RingPeers,
    device: &mut dyn Device,
    queue: Queue,
    trace: fn(&mut dyn Device) -> Result<(), DeviceError>,
    report: &mut DeviceReport,
) -> Result<(), RingError> {
    let RingPlace { size, order, .. } = link.place();
    for i in 0..size {
        stage(device, report, trace);
        if i + 1 == size && order != RingOrder::Home {
            break;
        }
        link.pass(device, queue, report)?;
    }
    Ok(())
}

/// A device's connections to its ring neighbours.
pub(crate) struct RingLink<'a> {
    pub(crate) size: usize,
    pub(crate) member: usize,
    /// The ring's direct transport; `None`: through the host.
    pub(crate) direct: Option<&'a dyn DirectRing>,
    pub(crate) to_next: mpsc::Sender<Handover>,
    pub(crate) from_prev: mpsc::Receiver<Handover>,
    /// Steps taken.
    pub(crate) steps: Cell<usize>,
    /// The last queue that came in through the host, its allocation kept
    /// for the next one going out.
    pub(crate) spare: Cell<Vec<RayRecord>>,
    pub(crate) vote: &'a Vote,
    pub(crate) order: RingOrder,
}

impl RingPeers for RingLink<'_> {
    fn place(&self) -> RingPlace {
        RingPlace { size: self.size, member: self.member, island: 0, order: self.order }
    }

    fn any(&self, mine: bool) -> (bool, Duration) {
        self.vote.any(mine)
    }

    fn pass(
        &self,
        device: &mut dyn Device,
        queue: Queue,
        report: &mut DeviceReport,
    ) -> Result<(), RingError> {
        let step = self.steps.get();
        self.steps.set(step + 1);
        let handover = match self.direct {
            None => {
                // Into the allocation of the queue that came in last.
                let mut records = self.spare.take();
                read_for_sending(device, queue, &mut records, report);
                Handover::Records(records)
            }
            Some(direct) => {
                self.send_direct(direct, device, queue, step, report);
                Handover::Copied
            }
        };
        let waited = Instant::now();
        self.to_next.send(handover).map_err(|_| RingError::NeighbourGone("next"))?;
        let incoming = self.from_prev.recv().map_err(|_| RingError::NeighbourGone("previous"))?;
        report.wait_seconds += waited.elapsed().as_secs_f64();
        match incoming {
            Handover::Records(records) => {
                let written = device.write_queue(queue, &records);
                report.keep(written, ());
                self.spare.replace(records);
            }
            Handover::Copied => {
                let accepted = match self.direct {
                    Some(direct) => direct.accept(self.member, device, queue, step),
                    None => Err(DeviceError::Unsupported {
                        device: device.name(),
                        what: "records sent directly to a member linked through the host".into(),
                    }),
                };
                report.keep(accepted, ());
            }
        }
        Ok(())
    }
}

impl RingLink<'_> {
    /// Opens this member's step, waits until every member has, and queues
    /// the send of `queue` to the successor ([`atoll_render::transport`]).
    /// Nothing here waits for the devices. Errors are kept in the report;
    /// the ring keeps stepping.
    fn send_direct(
        &self,
        direct: &dyn DirectRing,
        device: &mut dyn Device,
        queue: Queue,
        step: usize,
        report: &mut DeviceReport,
    ) {
        let opened = direct.open(self.member, device, queue, step);
        report.wait_seconds += self.vote.any(false).1.as_secs_f64();
        let sending = Instant::now();
        let sent = opened.and_then(|()| direct.send(self.member, device, queue, step));
        report.send_seconds += sending.elapsed().as_secs_f64();
        report.keep(sent, ());
    }
}

/// Renders `waves` on this process's devices, each a member of its own
/// ring of processes (`links[d]` is device d's), on a thread each: the
/// rings are islands of the same ranks, taking waves as workers 0, 1, …
pub(crate) fn run_members(
    devices: &mut [Box<dyn Device>],
    waves: &[Wave],
    shape: RunShape,
    links: &[&(dyn RingPeers + Sync)],
    handout: &dyn WaveHandout,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<DeviceReport>, DeviceError> {
    let reports = on_device_threads(devices, handout, waves.len(), progress, &|d, device, taken| {
        let link = links[d];
        let RingPlace { island, member, .. } = link.place();
        let mut report = DeviceReport { name: device.name(), island, member, ..Default::default() };
        let take = || handout.next(d).and_then(|i| waves.get(i));
        ring_loop(device, link, shape.merge, &take, taken, &mut report);
        report
    });
    Ok(reports)
}

/// One ring member's frame: queue waves as this member runs out of work
/// (or, merging, as its pending work runs low) and bounce in step with the
/// others until no member of the ring has paths or work left.
pub(crate) fn ring_loop<'w>(
    device: &mut dyn Device,
    link: &dyn RingPeers,
    merge: bool,
    take: &dyn Fn() -> Option<&'w Wave>,
    taken: &dyn Fn(),
    report: &mut DeviceReport,
) {
    loop {
        // A device that failed takes no more work but keeps stepping (with
        // empty queues) so that the others are not left waiting for it.
        let makes_queues = link.place().order == RingOrder::Spread || link.place().member == 0;
        if makes_queues && report.error.is_none() {
            let busy = has_paths(device, report);
            if !busy || (merge && report.keep(device.wants_work(), false)) {
                if let Some(wave) = take() {
                    stage(device, report, |d| d.queue_work(wave));
                    report.waves += 1;
                    taken();
                }
            }
        }
        let (any, waited): (bool, Duration) = link.any(has_paths(device, report));
        report.wait_seconds += waited.as_secs_f64();
        if !any {
            return;
        }
        stage(device, report, |d| d.refill());
        let traced = cycle(link, device, Queue::Paths, |d| d.trace_paths(), report).and_then(|()| {
            stage(device, report, |d| d.shade());
            cycle(link, device, Queue::Shadows, |d| d.trace_shadows(), report)
        });
        if let Err(message) = traced {
            // Only when a neighbour's thread is gone (it panicked): the
            // frame cannot finish; its panic is reported by the caller.
            tracing::error!("{}: {message}", device.name());
            return;
        }
        stage(device, report, |d| d.resolve_shadows());
    }
}

/// Runs `f` on a member's device unless it failed before; a failure is
/// kept in `report`.
fn stage(
    device: &mut dyn Device,
    report: &mut DeviceReport,
    f: impl FnOnce(&mut dyn Device) -> Result<(), DeviceError>,
) {
    if report.error.is_none() {
        let result = f(device);
        report.keep(result, ());
    }
}

/// Whether a member still has paths: never once it failed.
fn has_paths(device: &dyn Device, report: &mut DeviceReport) -> bool {
    report.error.is_none() && report.keep(device.has_paths(), false)
}
