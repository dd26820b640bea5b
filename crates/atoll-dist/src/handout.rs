//! Where the waves of a frame come from: a counter in this process, or one
//! shared with other processes (ranks started by `mpirun`, see
//! `crate::ranks`), so that every device of every process takes the next
//! wave as soon as it is free: the dynamic load balancing of Jaroš et al.
//! 2021, across nodes as well as across the devices of one node.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::Instant;

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
    /// The frame has `waves` waves; `pacing` says how this process's
    /// workers take them.
    fn begin(&self, waves: usize, pacing: Pacing);
    /// The next wave for worker `taker` of this process to render, `None`
    /// when all are taken or it should take no more ([`Pace`]).
    fn next(&self, taker: usize) -> Option<usize>;
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

/// How fast a taker of waves (a process and its workers) renders: one
/// worker's seconds per wave, measured since the frame began.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Speed {
    /// Seconds one worker takes per wave.
    pub seconds_per_wave: f64,
    /// Workers (devices or rings) taking waves.
    pub workers: usize,
}

impl Speed {
    /// From `taken` waves over `seconds` by `workers`; `None` before the
    /// first wave is done (nothing to go by).
    pub fn measured(taken: usize, seconds: f64, workers: usize) -> Option<Speed> {
        (taken > 0 && workers > 0)
            .then(|| Speed { seconds_per_wave: seconds * workers as f64 / taken as f64, workers })
    }

    /// How fast a taker goes and how long it still needs for the waves it
    /// holds, from `taken` waves over `seconds` by `workers`: judged on the
    /// waves it has rendered (those taken less the `in_flight` ones its
    /// merging devices may still hold), else on `warmed` (its warm-up).
    pub fn judged(
        taken: usize,
        in_flight: usize,
        seconds: f64,
        workers: usize,
        warmed: Option<Speed>,
    ) -> (Option<Speed>, f64) {
        let speed = Speed::measured(taken.saturating_sub(in_flight), seconds, workers).or(warmed);
        let backlog =
            speed.map_or(0.0, |s| taken as f64 * s.seconds_per_wave / s.workers.max(1) as f64 - seconds);
        (speed, backlog.max(0.0))
    }

    /// Waves all its workers render per second.
    pub fn waves_per_second(&self) -> f64 {
        self.workers as f64 / self.seconds_per_wave.max(1e-9)
    }
}

/// Takers whose time per wave is within this factor of the fastest's are
/// never refused ([`Pace::allows`]).
const SIMILAR: f64 = 2.0;

/// Who may take another wave as a frame runs out. A taker whose next wave
/// would still be rendering when the others have finished all the rest
/// only makes the frame wait for it, so it is refused and takes no more (a
/// CPU rank beside a GPU's, taking a handful of waves, made the frame much
/// longer than the GPU's alone: BENCHMARKS.md). Only
/// takers still taking count as the others, and a taker is never refused
/// when none of them is measured yet, nor when it is about as fast as the
/// fastest of them: so the last takers left always get the remaining waves.
#[derive(Clone, Debug, Default)]
pub struct Pace {
    speeds: Vec<Option<Speed>>,
    /// Per taker, seconds until it is done with the waves it holds.
    backlogs: Vec<f64>,
    refused: Vec<bool>,
}

impl Pace {
    /// No taker measured yet.
    pub fn new(takers: usize) -> Self {
        Pace { speeds: vec![None; takers], backlogs: vec![0.0; takers], refused: vec![false; takers] }
    }

    /// `taker`'s latest speed, and how long it will take to render the
    /// waves it holds.
    pub fn report(&mut self, taker: usize, speed: Option<Speed>, backlog_seconds: f64) {
        if let (Some(slot), Some(backlog)) = (self.speeds.get_mut(taker), self.backlogs.get_mut(taker)) {
            *slot = speed.or(*slot);
            *backlog = backlog_seconds.max(0.0);
        }
    }

    /// Whether `taker` may take one of the `remaining` waves; once refused,
    /// it is refused for the rest of the frame.
    pub fn allows(&mut self, taker: usize, remaining: usize) -> bool {
        if self.refused.get(taker).copied().unwrap_or(false) {
            return false;
        }
        let Some(Some(mine)) = self.speeds.get(taker).copied() else { return true };
        let others: Vec<Speed> = (0..self.speeds.len())
            .filter(|&t| t != taker && !self.refused[t])
            .filter_map(|t| self.speeds[t])
            .collect();
        let fastest = others.iter().map(|s| s.seconds_per_wave).fold(f64::INFINITY, f64::min);
        // Within twice the fastest's time per wave, never: among devices
        // of about one speed the estimates' noise would refuse the wrong
        // ones, and the frame's last waves, cut in four, even them out.
        if others.is_empty() || mine.seconds_per_wave <= SIMILAR * fastest {
            return true;
        }
        // When the others still taking would be done with the rest, and
        // when this taker would be, with one more wave after those it holds.
        let rate: f64 = others.iter().map(Speed::waves_per_second).sum();
        let others_done = remaining.saturating_sub(1) as f64 / rate;
        let allowed = self.backlogs[taker] + mine.seconds_per_wave <= others_done;
        self.refused[taker] = !allowed;
        allowed
    }
}

/// How a process's workers take a frame's waves, for judging their speed
/// from the waves they took ([`Speed`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Pacing {
    /// Waves a worker holds at once: merging wave-fronts, a device takes
    /// the next wave when its queue has room, long before the last is done,
    /// so the waves taken run ahead of those rendered by this many.
    pub in_flight: usize,
    /// Per worker, its speed measured on the frame's first sample
    /// (`--warmup`), until it has rendered waves of the frame itself.
    pub warmed: Vec<Option<Speed>>,
}

impl Pacing {
    /// The workers together, as one taker: the waves they hold, and their
    /// speed from the warm-up (one worker's seconds per wave at their
    /// combined rate).
    pub fn together(&self) -> (usize, Option<Speed>) {
        let workers = self.warmed.len();
        let rate: Option<f64> = self.warmed.iter().map(|s| s.map(|s| s.waves_per_second())).sum();
        let warmed =
            rate.filter(|&r| r > 0.0).map(|r| Speed { seconds_per_wave: workers as f64 / r, workers });
        (self.in_flight * workers, warmed)
    }
}

/// The waves of a frame rendered by this process alone, each worker
/// paced ([`Pace`]): a device much slower than the others stops taking
/// waves near the end instead of making the frame wait for its last one.
#[derive(Debug, Default)]
pub struct LocalHandout {
    waves: AtomicUsize,
    next: AtomicUsize,
    paced: Mutex<Paced>,
}

/// The workers' takes and pace, behind one lock (a take per wave).
#[derive(Debug)]
struct Paced {
    pace: Pace,
    taken: Vec<usize>,
    pacing: Pacing,
    started: Instant,
}

impl Default for Paced {
    fn default() -> Self {
        Paced { pace: Pace::default(), taken: Vec::new(), pacing: Pacing::default(), started: Instant::now() }
    }
}

impl WaveHandout for LocalHandout {
    fn join(&self, me: Joining) -> Result<Joined, DeviceError> {
        Ok(Joined { workers: me.workers, wave_size: me.wave_size })
    }

    fn begin(&self, waves: usize, pacing: Pacing) {
        self.waves.store(waves, Ordering::Relaxed);
        self.next.store(0, Ordering::Relaxed);
        let workers = pacing.warmed.len();
        *self.paced.lock().unwrap_or_else(|p| p.into_inner()) =
            Paced { pace: Pace::new(workers), taken: vec![0; workers], pacing, started: Instant::now() };
    }

    fn next(&self, taker: usize) -> Option<usize> {
        let waves = self.waves.load(Ordering::Relaxed);
        let mut paced = self.paced.lock().unwrap_or_else(|p| p.into_inner());
        let Paced { pace, taken, pacing, started } = &mut *paced;
        if let Some(&mine) = taken.get(taker) {
            let seconds = started.elapsed().as_secs_f64();
            let warmed = pacing.warmed.get(taker).copied().flatten();
            let (speed, backlog) = Speed::judged(mine, pacing.in_flight, seconds, 1, warmed);
            pace.report(taker, speed, backlog);
        }
        let i = self.next.load(Ordering::Relaxed);
        if i >= waves || !pace.allows(taker, waves - i) {
            return None;
        }
        self.next.store(i + 1, Ordering::Relaxed);
        if let Some(mine) = taken.get_mut(taker) {
            *mine += 1;
        }
        Some(i)
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
        handout.begin(5, Pacing::default());
        let taken: Vec<_> = std::iter::from_fn(|| handout.next(0)).collect();
        assert_eq!(taken, vec![0, 1, 2, 3, 4]);
        assert_eq!(handout.next(1), None);
        assert_eq!(handout.taken(), 5);
        handout.begin(2, Pacing::default());
        assert_eq!(handout.taken(), 0);
        assert_eq!((handout.next(0), handout.next(0), handout.next(0)), (Some(0), Some(1), None));
    }

    #[test]
    fn a_device_too_slow_for_one_wave_is_refused_from_the_start() {
        // Worker 0 renders a wave in 1 ms, worker 1 in 300 ms (measured on
        // the warm-up); 100 waves: worker 0 alone is done in 0.1 s.
        let handout = LocalHandout::default();
        let fast = Speed { seconds_per_wave: 0.001, workers: 1 };
        let slow = Speed { seconds_per_wave: 0.3, workers: 1 };
        handout.begin(100, Pacing { in_flight: 1, warmed: vec![Some(fast), Some(slow)] });
        assert_eq!(handout.next(0), Some(0));
        assert_eq!(handout.next(1), None, "its one wave would outlast the whole frame");
        let rest: Vec<_> = std::iter::from_fn(|| handout.next(0)).collect();
        assert_eq!(rest.len(), 99, "every other wave goes to worker 0");
        // Together they are one taker going at their combined rate.
        let (held, together) = Pacing { in_flight: 2, warmed: vec![Some(fast), Some(slow)] }.together();
        let together = together.unwrap();
        assert_eq!((held, together.workers), (4, 2));
        assert!((together.waves_per_second() - (1000.0 + 1.0 / 0.3)).abs() < 1e-6);
        assert_eq!(Pacing { in_flight: 1, warmed: vec![Some(fast), None] }.together().1, None);
    }

    #[test]
    fn a_slow_taker_is_refused_only_when_the_others_would_finish_first() {
        // A GPU process (3 workers, 10 ms a wave each: 300 waves/s) and a
        // CPU process (1 worker, 90 ms a wave).
        let gpu = Speed::measured(30, 0.1, 3).unwrap();
        let cpu = Speed::measured(1, 0.09, 1).unwrap();
        assert!((gpu.seconds_per_wave - 0.01).abs() < 1e-12 && (cpu.seconds_per_wave - 0.09).abs() < 1e-12);
        let mut pace = Pace::new(2);
        assert!(pace.allows(1, 1) && pace.allows(0, 1), "not measured yet: never refused");
        pace.report(0, Some(gpu), 0.0);
        pace.report(1, Some(cpu), 0.0);
        // 100 waves left: the GPU needs 0.33 s for them, the CPU 0.09 s for one.
        assert!(pace.allows(1, 100));
        // Not when it still holds 0.3 s of waves.
        pace.report(1, Some(cpu), 0.3);
        let mut holding = pace.clone();
        assert!(!holding.allows(1, 100));
        // A report without a measure keeps the last speed.
        pace.report(1, None, 0.0);
        // 20 left: the GPU is done in 0.063 s, before the CPU's wave.
        assert!(!pace.allows(1, 20));
        assert!(!pace.allows(1, 100), "refused for the rest of the frame");
        // The fastest always gets one, to the last.
        assert!(pace.allows(0, 1) && pace.allows(0, 20));
        // Equal takers, or nearly, are never refused.
        let mut equal = Pace::new(3);
        (0..3).for_each(|t| equal.report(t, Some(cpu), 0.0));
        equal.report(2, Speed::measured(1, 0.17, 1), 0.5);
        assert!((0..3).all(|t| equal.allows(t, 1)));
        assert_eq!(Speed::measured(0, 1.0, 2), None);
        // 5 taken, 2 of them maybe still held: 3 rendered in 0.3 s, so
        // 0.1 s a wave and 0.2 s of the 5 still to go.
        let (speed, backlog) = Speed::judged(5, 2, 0.3, 1, None);
        assert!((speed.unwrap().seconds_per_wave - 0.1).abs() < 1e-12 && (backlog - 0.2).abs() < 1e-12);
        // Nothing rendered yet: the warm-up's speed.
        assert_eq!(Speed::judged(2, 2, 0.3, 1, Some(cpu)).0, Some(cpu));
    }

    /// Takers of nearly equal, changing speeds ask as they free up, each
    /// refused when it looks slower: every wave must still be taken.
    #[test]
    fn every_wave_is_taken_whoever_is_refused() {
        for seed in 0..200u64 {
            let mut random = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
            let mut next_random = move || {
                random ^= random << 13;
                random ^= random >> 7;
                random ^= random << 17;
                (random % 1000) as f64 / 1000.0
            };
            let takers = 2 + (seed % 4) as usize;
            let waves = 10 + (seed % 50) as usize;
            let base: Vec<f64> = (0..takers).map(|_| 0.01 + 0.1 * next_random()).collect();
            let mut pace = Pace::new(takers);
            let (mut free_at, mut taken, mut done) =
                (vec![0.0f64; takers], vec![0usize; takers], vec![false; takers]);
            let mut handed = 0;
            while handed < waves && done.iter().any(|d| !d) {
                // The next free taker asks, with its speed so far (noisy).
                let t = (0..takers)
                    .filter(|&t| !done[t])
                    .min_by(|&a, &b| free_at[a].total_cmp(&free_at[b]))
                    .unwrap();
                let speed = Speed::measured(taken[t], free_at[t] * (0.8 + 0.4 * next_random()), 1);
                pace.report(t, speed, base[t] * next_random());
                if pace.allows(t, waves - handed) {
                    handed += 1;
                    taken[t] += 1;
                    free_at[t] += base[t];
                } else {
                    done[t] = true;
                }
            }
            assert_eq!(handed, waves, "seed {seed}: waves left untaken");
        }
    }
}
