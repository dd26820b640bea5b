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
    /// Every process sharing the frame calls this once, prepared or not
    /// (`ready`), with its own workers (devices replicating, or rings):
    /// all their workers together, which sets the size of the waves, or an
    /// error when another process could not prepare (each process then
    /// stops instead of waiting for the others forever).
    fn join(&self, ready: bool, workers: usize) -> Result<usize, DeviceError>;
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

/// The waves of a frame rendered by this process alone.
#[derive(Debug, Default)]
pub struct LocalHandout {
    waves: AtomicUsize,
    next: AtomicUsize,
}

impl WaveHandout for LocalHandout {
    fn join(&self, _ready: bool, workers: usize) -> Result<usize, DeviceError> {
        Ok(workers)
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
        assert_eq!(handout.join(true, 3).unwrap(), 3);
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
