//! Where the waves of a frame come from: a counter in this process, or one
//! shared with other processes (ranks started by `mpirun`, see
//! `crate::ranks`), so that every device of every process takes the next
//! wave as soon as it is free: the dynamic load balancing of Jaroš et al.
//! 2021, across nodes as well as across the devices of one node.

use std::sync::atomic::{AtomicUsize, Ordering};

use atoll_render::DeviceError;

/// Hands out the indices of a frame's waves, each once, to whoever asks
/// first. The calls come in this order, once per frame: [`join`], then
/// (unless it failed) [`begin`], any number of [`next`] from the device
/// threads, then [`end`].
///
/// [`join`]: WaveHandout::join
/// [`begin`]: WaveHandout::begin
/// [`next`]: WaveHandout::next
/// [`end`]: WaveHandout::end
pub trait WaveHandout: Sync {
    /// Every process sharing the frame calls this once, prepared or not:
    /// what they agree on, from which each cuts the same list of waves; an
    /// error when another process could not prepare or renders another
    /// frame (each process then stops instead of waiting for the others
    /// forever).
    fn join(&self, me: Joining) -> Result<Joined, DeviceError>;
    /// The frame has `waves` waves.
    fn begin(&self, waves: usize);
    /// The next wave to render, `None` when all are taken.
    fn next(&self) -> Option<usize>;
    /// Waves taken so far: by every process where this one hands them out,
    /// else by this one (for progress bars).
    fn taken(&self) -> usize;
    /// This process has rendered all it took; returns when every process has.
    fn end(&self);
}

/// What a process brings to a frame it shares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Joining {
    /// Its devices are prepared.
    pub ready: bool,
    /// What takes waves: devices replicating, or rings.
    pub workers: usize,
    /// The most pixels its devices take per wave.
    pub wave_size: u32,
    /// Pixels times samples per pixel of its frame.
    pub samples: u64,
}

/// What the processes sharing a frame agreed on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Joined {
    /// Every process's workers: the waves are cut for all of them.
    pub workers: usize,
    /// The smallest wave size of any process (a GPU's devices take several
    /// small waves at once when they merge wave-fronts).
    pub wave_size: u32,
}

/// The waves of a frame rendered by this process alone.
#[derive(Debug, Default)]
pub struct LocalHandout {
    waves: AtomicUsize,
    next: AtomicUsize,
}

impl WaveHandout for LocalHandout {
    fn join(&self, me: Joining) -> Result<Joined, DeviceError> {
        Ok(Joined { workers: me.workers, wave_size: me.wave_size })
    }

    fn begin(&self, waves: usize) {
        self.waves.store(waves, Ordering::Relaxed);
        self.next.store(0, Ordering::Relaxed);
    }

    fn next(&self) -> Option<usize> {
        let i = self.next.fetch_add(1, Ordering::Relaxed);
        (i < self.waves.load(Ordering::Relaxed)).then_some(i)
    }

    fn taken(&self) -> usize {
        self.next.load(Ordering::Relaxed).min(self.waves.load(Ordering::Relaxed))
    }

    fn end(&self) {}
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn local_handout_gives_every_wave_once_then_none() {
        let handout = LocalHandout::default();
        let me = Joining { ready: true, workers: 3, wave_size: 4096, samples: 64 };
        assert_eq!(handout.join(me).unwrap(), Joined { workers: 3, wave_size: 4096 });
        handout.begin(5);
        let taken: Vec<_> = std::iter::from_fn(|| handout.next()).collect();
        assert_eq!(taken, vec![0, 1, 2, 3, 4]);
        assert_eq!(handout.next(), None);
        assert_eq!(handout.taken(), 5);
        handout.begin(2);
        assert_eq!(handout.taken(), 0);
        assert_eq!((handout.next(), handout.next(), handout.next()), (Some(0), Some(1), None));
    }
}
