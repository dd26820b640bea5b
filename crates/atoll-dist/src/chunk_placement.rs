//! Where a shared scene's chunks go, from the prepass's access counts:
//! Algorithm 1 of Jaroš et al. 2021, with a host tier for chunks that fit
//! no device.
//!
//! Chunks are taken hottest first (most reads over all devices; ties by
//! chunk index, so the result is deterministic). The hottest `N_dup` are
//! replicated on every device; every other chunk that was read goes to
//! the device that read it most with room left (the next most, and so on),
//! else to host memory; chunks never read are dealt round robin over the
//! devices with room, else to host memory. As in the paper, every device
//! gets about the same bytes: "room" is first a device's even share of
//! the chunks not replicated, then (when every share is full) its budget.

use atoll_render::{ChunkHome, ChunkLayout, ChunkPlacement};

/// What [`place_chunks`] plans with.
#[derive(Clone, Debug)]
pub struct ChunkBudget {
    /// Per device, bytes of chunks it may hold (`None`: no limit).
    pub devices: Vec<Option<u64>>,
    /// Bytes of chunks host memory may hold when the devices are full
    /// (`None`: no host tier; `Some(u64::MAX)`: no limit).
    pub host: Option<u64>,
}

/// How many chunks to replicate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Replication {
    /// The paper's `N_dup = (G_free − S_scene / N_devices) / C_size`: as
    /// many as leave every device room for an even share of the rest.
    Auto,
    /// This fraction of the chunks (at most what the budgets allow):
    /// `--replicate-fraction`, for measuring.
    Fraction(f64),
}

/// Why no placement exists.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
#[allow(missing_docs)]
pub enum ChunkPlacementError {
    /// More chunk bytes than the devices' budgets and the host tier hold.
    #[error(
        "the scene's {scene} bytes in chunks of {chunk_bytes} do not fit the devices' {devices} bytes and {host} bytes of host memory"
    )]
    DoesNotFit { scene: u64, chunk_bytes: u64, devices: u64, host: u64 },
    /// Counts of another shape than the layout and devices.
    #[error("access counts for {got} devices and {chunks_got} chunks, expected {devices} and {chunks}")]
    Counts { got: usize, devices: usize, chunks_got: usize, chunks: usize },
}

/// The first placement, before anything was counted: chunk `c` on device
/// `c mod N` while devices have room (devices without room skipped), the
/// rest in host memory.
pub fn initial_placement(
    layout: &ChunkLayout,
    budget: &ChunkBudget,
) -> Result<ChunkPlacement, ChunkPlacementError> {
    let zero = vec![vec![0; layout.chunk_count()]; budget.devices.len()];
    place_chunks(layout, &zero, budget, Replication::Fraction(0.0))
}

/// Algorithm 1 over `counts[device][chunk]`.
pub fn place_chunks(
    layout: &ChunkLayout,
    counts: &[Vec<u64>],
    budget: &ChunkBudget,
    replication: Replication,
) -> Result<ChunkPlacement, ChunkPlacementError> {
    let chunks = layout.chunk_count();
    let devices = budget.devices.len();
    if counts.len() != devices || counts.iter().any(|c| c.len() != chunks) {
        return Err(ChunkPlacementError::Counts {
            got: counts.len(),
            devices,
            chunks_got: counts.first().map_or(0, Vec::len),
            chunks,
        });
    }
    let scene = layout.bytes();
    let room_total = budget.devices.iter().try_fold(0u64, |sum, b| b.map(|b| sum.saturating_add(b)));
    let host_room = budget.host.unwrap_or(0);
    let does_not_fit = || ChunkPlacementError::DoesNotFit {
        scene,
        chunk_bytes: layout.chunk_bytes,
        devices: room_total.unwrap_or(u64::MAX),
        host: host_room,
    };
    // Refused before any placing when the bytes alone cannot fit.
    if room_total.is_some_and(|room| scene > room.saturating_add(host_room)) {
        return Err(does_not_fit());
    }
    let total: Vec<u64> = (0..chunks).map(|c| counts.iter().map(|d| d[c]).sum()).collect();
    let mut order: Vec<usize> = (0..chunks).collect();
    // Hottest first, ties by index: deterministic.
    order.sort_by(|&a, &b| total[b].cmp(&total[a]).then(a.cmp(&b)));
    let n_dup = replicated_chunks(layout, budget, replication, &order, &total);

    let mut room: Vec<u64> = budget.devices.iter().map(|b| b.unwrap_or(u64::MAX)).collect();
    let mut homes = vec![ChunkHome::Host; chunks];
    for &c in &order[..n_dup] {
        homes[c] = ChunkHome::Replicated;
        for r in &mut room {
            *r -= layout.chunk_len(c);
        }
    }
    let rest: u64 = order[n_dup..].iter().map(|&c| layout.chunk_len(c)).sum();
    let mut share = even_shares(&room, rest, layout.chunk_bytes);
    // The first of `candidates` with room in its share, else in its budget.
    let mut take = |c: usize, candidates: &mut dyn Iterator<Item = usize>| -> Option<usize> {
        let len = layout.chunk_len(c);
        let candidates: Vec<usize> = candidates.collect();
        let d = candidates
            .iter()
            .copied()
            .find(|&d| share[d] >= len && room[d] >= len)
            .or_else(|| candidates.iter().copied().find(|&d| room[d] >= len))?;
        room[d] -= len;
        share[d] = share[d].saturating_sub(len);
        homes[c] = ChunkHome::Device(d as u32);
        Some(d)
    };
    // Read chunks: to their most frequent reader with room.
    let mut readers: Vec<usize> = (0..devices).collect();
    for &c in order[n_dup..].iter().take_while(|&&c| total[c] > 0) {
        readers.sort_by(|&a, &b| counts[b][c].cmp(&counts[a][c]).then(a.cmp(&b)));
        take(c, &mut readers.iter().copied());
    }
    // Chunks never read: round robin over the devices with room.
    let mut next = 0;
    for &c in order[n_dup..].iter().skip_while(|&&c| total[c] > 0) {
        if let Some(d) = take(c, &mut (0..devices).map(|i| (next + i) % devices)) {
            next = d + 1;
        }
    }
    let on_host: u64 =
        (0..chunks).filter(|&c| homes[c] == ChunkHome::Host).map(|c| layout.chunk_len(c)).sum();
    if on_host > host_room {
        return Err(does_not_fit());
    }
    Ok(ChunkPlacement { homes })
}

/// Per device, its even share of `bytes` to hold within `room` (devices
/// with less room than an even share hold what they can, the others
/// share the rest), plus one chunk for rounding to whole chunks.
fn even_shares(room: &[u64], bytes: u64, chunk_bytes: u64) -> Vec<u64> {
    let mut by_room: Vec<usize> = (0..room.len()).collect();
    by_room.sort_by_key(|&d| (room[d], d));
    let mut share = vec![0; room.len()];
    let mut left = bytes;
    for (i, &d) in by_room.iter().enumerate() {
        let even = left.div_ceil((room.len() - i) as u64);
        let held = even.min(room[d]);
        share[d] = held.saturating_add(chunk_bytes).min(room[d]);
        left -= held;
    }
    share
}

/// How many of the hottest chunks (`order`) to replicate: as `replication`
/// asks, never more than leaves every device room for its even share of
/// the chunks not replicated (those the devices can hold at all), and
/// never a chunk nobody read.
fn replicated_chunks(
    layout: &ChunkLayout,
    budget: &ChunkBudget,
    replication: Replication,
    order: &[usize],
    total: &[u64],
) -> usize {
    let read = order.iter().take_while(|&&c| total[c] > 0).count();
    let devices = budget.devices.len().max(1) as u64;
    let Some(smallest) = budget.devices.iter().map(|b| b.unwrap_or(u64::MAX)).min() else { return 0 };
    let scene = layout.bytes();
    // What must stay on the devices (the rest may go to the host).
    let on_devices =
        budget.devices.iter().map(|b| b.unwrap_or(u64::MAX)).fold(0u64, u64::saturating_add).min(scene);
    let fits = |n: usize| {
        let replicated: u64 = order[..n].iter().map(|&c| layout.chunk_len(c)).sum();
        let rest = on_devices.saturating_sub(replicated);
        replicated.saturating_add(rest.div_ceil(devices)) <= smallest
    };
    let wanted = match replication {
        Replication::Auto => {
            // N_dup = (G_free − S / N) / C.
            let spare = smallest.saturating_sub(on_devices.div_ceil(devices));
            (spare / layout.chunk_bytes) as usize
        }
        Replication::Fraction(f) => (f.clamp(0.0, 1.0) * layout.chunk_count() as f64).round() as usize,
    };
    let mut n = wanted.min(read);
    while n > 0 && !fits(n) {
        n -= 1;
    }
    n
}

/// Share of all reads that the hottest `fraction` of the scene's bytes
/// take, per fraction asked (the paper's Figure 4), counting the reads of
/// a chunk only partly in that fraction in proportion; 0 where nothing
/// was read.
pub fn access_concentration(layout: &ChunkLayout, counts: &[Vec<u64>], fractions: &[f64]) -> Vec<f64> {
    let chunks = layout.chunk_count();
    let total: Vec<u64> =
        (0..chunks).map(|c| counts.iter().map(|d| d.get(c).copied().unwrap_or(0)).sum()).collect();
    let mut order: Vec<usize> = (0..chunks).collect();
    order.sort_by(|&a, &b| total[b].cmp(&total[a]).then(a.cmp(&b)));
    let all: u64 = total.iter().sum();
    let bytes = layout.bytes().max(1) as f64;
    fractions
        .iter()
        .map(|&f| {
            // Reads spread evenly within a chunk: the last one counts in part.
            let (mut left, mut reads) = (f * bytes, 0.0);
            for &c in &order {
                if left <= 0.0 {
                    break;
                }
                let len = layout.chunk_len(c) as f64;
                reads += total[c] as f64 * (left / len).min(1.0);
                left -= len;
            }
            if all == 0 {
                0.0
            } else {
                reads / all as f64
            }
        })
        .collect()
}

/// Share of device reads that its own memory serves under `placement`
/// (from the prepass's counts), per device.
pub fn local_read_share(placement: &ChunkPlacement, counts: &[Vec<u64>]) -> Vec<f64> {
    counts
        .iter()
        .enumerate()
        .map(|(d, reads)| {
            let all: u64 = reads.iter().sum();
            let local: u64 =
                reads.iter().enumerate().filter(|&(c, _)| placement.is_local(c, d)).map(|(_, &n)| n).sum();
            if all == 0 {
                1.0
            } else {
                local as f64 / all as f64
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` chunks of 100 bytes (the last one `last` bytes).
    fn layout(n: u64, last: u64) -> ChunkLayout {
        ChunkLayout::new(100, 1, [("t".to_string(), (n - 1) * 100 + last)])
    }

    fn budget(devices: &[Option<u64>], host: bool) -> ChunkBudget {
        ChunkBudget { devices: devices.to_vec(), host: host.then_some(u64::MAX) }
    }

    /// Per device, bytes held; host bytes; every chunk placed once.
    fn check(layout: &ChunkLayout, p: &ChunkPlacement, budget: &ChunkBudget) -> (Vec<u64>, u64) {
        assert_eq!(p.homes.len(), layout.chunk_count());
        let held: Vec<u64> = (0..budget.devices.len()).map(|d| p.residency(layout, d).local()).collect();
        for (d, (&h, b)) in held.iter().zip(&budget.devices).enumerate() {
            assert!(h <= b.unwrap_or(u64::MAX), "device {d} holds {h} over its budget {b:?}");
        }
        let host = p.residency(layout, 0).host;
        // Every byte once: replicated counted once, owned once, host once.
        let replicated = p.residency(layout, 0).replicated;
        let owned: u64 = (0..budget.devices.len()).map(|d| p.residency(layout, d).owned).sum();
        assert_eq!(replicated + owned + host, layout.bytes());
        (held, host)
    }

    #[test]
    fn hottest_are_replicated_and_the_rest_goes_to_its_main_reader() {
        let l = layout(10, 100);
        // Chunk 9 hottest, then 8; chunk 0..4 read mostly by device 1, 5..7 by device 0.
        let counts =
            vec![vec![1, 1, 1, 1, 1, 20, 20, 20, 300, 500], vec![10, 11, 12, 13, 14, 0, 0, 0, 0, 500]];
        let b = budget(&[Some(700), Some(700)], false);
        // N_dup = (700 − 1000 / 2) / 100 = 2.
        let p = place_chunks(&l, &counts, &b, Replication::Auto).unwrap();
        check(&l, &p, &b);
        assert_eq!(p.homes[9], ChunkHome::Replicated);
        assert_eq!(p.homes[8], ChunkHome::Replicated);
        for c in 0..5 {
            assert_eq!(p.homes[c], ChunkHome::Device(1), "chunk {c}");
        }
        for c in 5..8 {
            assert_eq!(p.homes[c], ChunkHome::Device(0), "chunk {c}");
        }
        let local = local_read_share(&p, &counts);
        assert_eq!(local[1], 1.0);
        assert!(local[0] > 0.99 && local[0] < 1.0);
    }

    #[test]
    fn a_full_reader_passes_chunks_to_the_next_and_then_to_the_host() {
        let l = layout(6, 40);
        // Device 0 reads everything; it can hold 2 chunks, device 1 two more.
        let counts = vec![vec![5, 4, 3, 2, 1, 0], vec![0, 0, 0, 0, 1, 0]];
        let b = budget(&[Some(200), Some(200)], true);
        let p = place_chunks(&l, &counts, &b, Replication::Fraction(0.0)).unwrap();
        let (held, host) = check(&l, &p, &b);
        assert_eq!(&p.homes[..2], &[ChunkHome::Device(0), ChunkHome::Device(0)]);
        assert_eq!(&p.homes[2..4], &[ChunkHome::Device(1), ChunkHome::Device(1)]);
        // The coldest stay in host memory.
        assert_eq!(&p.homes[4..], &[ChunkHome::Host, ChunkHome::Host]);
        assert_eq!((held, host), (vec![200, 200], 140));
        // Without the host tier, or with too little host memory, it is
        // refused, not over-committed.
        let no_host = budget(&[Some(200), Some(200)], false);
        assert!(matches!(
            place_chunks(&l, &counts, &no_host, Replication::Auto),
            Err(ChunkPlacementError::DoesNotFit { scene: 540, chunk_bytes: 100, devices: 400, host: 0 })
        ));
        let small_host = ChunkBudget { host: Some(100), ..no_host.clone() };
        assert!(matches!(
            place_chunks(&l, &counts, &small_host, Replication::Auto),
            Err(ChunkPlacementError::DoesNotFit { host: 100, .. })
        ));
        let enough = ChunkBudget { host: Some(140), ..no_host };
        assert_eq!(place_chunks(&l, &counts, &enough, Replication::Fraction(0.0)).unwrap(), p);
    }

    #[test]
    fn unread_chunks_are_dealt_round_robin_and_ties_are_deterministic() {
        let l = layout(8, 100);
        let counts = vec![vec![0u64; 8]; 3];
        let b = budget(&[None, None, None], false);
        let p = place_chunks(&l, &counts, &b, Replication::Auto).unwrap();
        check(&l, &p, &b);
        let homes: Vec<ChunkHome> = (0..8).map(|c| ChunkHome::Device(c % 3)).collect();
        assert_eq!(p.homes, homes);
        assert_eq!(initial_placement(&l, &b).unwrap(), p);
        // Equal counts on two devices: the lower index wins, until its
        // even share is full; every time the same.
        let tied = vec![vec![1u64; 8], vec![1u64; 8], vec![0u64; 8]];
        let b = budget(&[Some(800), Some(800), Some(800)], false);
        let first = place_chunks(&l, &tied, &b, Replication::Fraction(0.0)).unwrap();
        let owners: Vec<ChunkHome> = [0, 0, 0, 1, 1, 1, 2, 2].map(ChunkHome::Device).to_vec();
        assert_eq!(first.homes, owners);
        assert_eq!(place_chunks(&l, &tied, &b, Replication::Fraction(0.0)).unwrap(), first);
    }

    #[test]
    fn replication_stays_within_every_budget() {
        let l = layout(20, 100);
        let counts: Vec<Vec<u64>> = (0..2).map(|d| (0..20).map(|c| 100 - c as u64 + d).collect()).collect();
        // 2000 bytes over 2 devices of 1200: at most 4 replicated (4·100 + 1600/2 = 1200).
        let b = budget(&[Some(1200), Some(1300)], false);
        for fraction in [0.0, 0.1, 0.2, 0.5, 1.0] {
            let p = place_chunks(&l, &counts, &b, Replication::Fraction(fraction)).unwrap();
            check(&l, &p, &b);
            let replicated = p.homes.iter().filter(|h| **h == ChunkHome::Replicated).count();
            assert_eq!(replicated, ((fraction * 20.0).round() as usize).min(4), "fraction {fraction}");
        }
        let auto = place_chunks(&l, &counts, &b, Replication::Auto).unwrap();
        assert_eq!(auto.homes.iter().filter(|h| **h == ChunkHome::Replicated).count(), 2);
        // Unlimited devices replicate everything read when asked to.
        let free = budget(&[None, None], false);
        let all = place_chunks(&l, &counts, &free, Replication::Fraction(1.0)).unwrap();
        assert!(all.homes.iter().all(|h| *h == ChunkHome::Replicated));
        // Counts of the wrong shape are an error, not a panic.
        assert!(place_chunks(&l, &counts[..1], &free, Replication::Auto).is_err());
    }

    #[test]
    fn devices_hold_even_shares_where_they_can() {
        // 1000 bytes over rooms of 200, 1000, 1000: 200, then 400 each.
        assert_eq!(even_shares(&[200, 1000, 1000], 1000, 100), vec![200, 500, 500]);
        assert_eq!(even_shares(&[u64::MAX, u64::MAX], 1000, 100), vec![600, 600]);
        // One device reads everything, nothing is replicated: it still
        // holds only its share when the others have room.
        let l = layout(10, 100);
        let counts = vec![vec![9u64; 10], vec![0u64; 10]];
        let b = budget(&[None, None], false);
        let p = place_chunks(&l, &counts, &b, Replication::Fraction(0.0)).unwrap();
        let (held, _) = check(&l, &p, &b);
        assert!(held[0] <= 600 && held[1] >= 400, "{held:?}");
    }

    #[test]
    fn concentration_curve_accumulates_hottest_bytes_first() {
        let l = layout(10, 100);
        let counts = vec![vec![70, 10, 10, 5, 5, 0, 0, 0, 0, 0]];
        let curve = access_concentration(&l, &counts, &[0.0, 0.05, 0.1, 0.2, 0.5, 1.0]);
        assert_eq!(curve, vec![0.0, 0.35, 0.7, 0.8, 1.0, 1.0]);
    }
}
