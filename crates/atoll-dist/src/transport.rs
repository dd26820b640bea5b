//! How a ring's queues move from member to member: through the host
//! (`read_queue` / `write_queue`, any device) or directly between devices
//! that offer a [`DirectTransport`](atoll_render::DirectTransport) (GPU
//! peer copies).

use std::time::Instant;

use atoll_render::{Device, DeviceError, DirectRing, Queue, RayRecord};

use crate::render::DeviceReport;

/// How queues move around a ring.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    /// `read_queue` / `write_queue` through host memory: works for every device.
    Host,
    /// Device to device ([`atoll_render::DirectTransport`]: CUDA peer
    /// copies, NVLink where available): every member a device offering it.
    Peer,
}

/// What passes from a ring member to the next at each step.
pub(crate) enum Handover {
    /// The records themselves, through the host (any device kind).
    Records(Vec<RayRecord>),
    /// The records are on their way device to device ([`DirectRing`]):
    /// the receiver accepts them.
    Copied,
}

/// The transport for `devices`: `wanted`, or when `None` the fastest that
/// works (direct when every device offers the same direct transport, else
/// the host).
pub(crate) fn choose_transport(
    devices: &[Box<dyn Device>],
    wanted: Option<Transport>,
) -> Result<Transport, DeviceError> {
    let kinds: Vec<Option<&'static str>> =
        devices.iter().map(|d| d.direct_transport().map(|t| t.name())).collect();
    let direct = kinds.first().copied().flatten().is_some() && kinds.windows(2).all(|w| w[0] == w[1]);
    match (direct, wanted) {
        (_, Some(Transport::Host)) => Ok(Transport::Host),
        (true, _) => Ok(Transport::Peer),
        (false, Some(Transport::Peer)) => Err(DeviceError::Other {
            device: "devices".into(),
            message: "direct copies need every device of the ring to offer the same direct transport (all CUDA GPUs)"
                .into(),
        }),
        (false, None) => Ok(Transport::Host),
    }
}

/// Connects each ring of `ring` consecutive devices through their direct
/// transport (see [`choose_transport`]).
pub(crate) fn connect_rings(
    devices: &mut [Box<dyn Device>],
    ring: usize,
) -> Result<Vec<Box<dyn DirectRing>>, DeviceError> {
    devices
        .chunks_mut(ring)
        .map(|members| {
            let transport = members[0].direct_transport().ok_or_else(|| DeviceError::Unsupported {
                device: members[0].name(),
                what: "direct queue transport".into(),
            })?;
            transport.connect(members)
        })
        .collect()
}

/// The host transport's send side: `device`'s `queue` read into `records`
/// (their allocation reused), timed and counted in `report`. A failed
/// read sends nothing, so that the ring still steps; the failure is kept.
pub(crate) fn read_for_sending(
    device: &dyn Device,
    queue: Queue,
    records: &mut Vec<RayRecord>,
    report: &mut DeviceReport,
) {
    let sending = Instant::now();
    if let Err(e) = device.read_queue_into(queue, records) {
        records.clear();
        report.fail(e);
    }
    report.send_seconds += sending.elapsed().as_secs_f64();
    report.bytes_sent += std::mem::size_of_val(records.as_slice()) as u64;
}
