//! Waves handed out by image region, for the shared strategy: worker `w`
//! takes first the waves whose first pixel lies in its stripe (the
//! `stripe_of[w]`-th of N equal stripes of the image: workers on one GPU
//! share its stripe), in order, so each device keeps rendering the same
//! part of the image (as the stripes of Jaroš et al. 2021) and reads the
//! same part of the scene: the prepass's counts then say which device
//! reads a chunk most, and the chunks it owns serve most of its reads. A
//! worker whose stripe is done takes the last wave of the stripe with the
//! most waves left (work stealing), so uneven stripes still finish
//! together.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use atoll_render::{DeviceError, Wave};

use crate::handout::{Joined, Joining, Pacing, WaveHandout};

/// Hands out a frame's waves by stripe ([`crate::stripes`]).
#[derive(Debug)]
pub struct StripeHandout {
    /// Per stripe, the indices of its waves not yet taken.
    stripes: Mutex<Vec<VecDeque<usize>>>,
    /// Per worker, its stripe.
    stripe_of: Vec<usize>,
    /// Whether a worker whose stripe is done takes others' waves.
    steal: bool,
    taken: AtomicUsize,
}

/// The stripes `stripe_of` names (one per distinct value, numbered from 0).
fn stripe_count(stripe_of: &[usize]) -> usize {
    stripe_of.iter().max().map_or(1, |&s| s + 1)
}

/// The stripe (of `count` over `pixels` pixels) that pixel `pixel` lies in.
fn stripe_of_pixel(pixel: u32, pixels: u32, count: usize) -> usize {
    ((pixel as u64 * count as u64 / pixels.max(1) as u64) as usize).min(count - 1)
}

/// `waves` with every wave that spans a stripe boundary cut there, so
/// that each stripe holds an equal share of every sample's pixels: a wave
/// belongs to the stripe of its first pixel, and frames whose waves are
/// large against a stripe would otherwise give one stripe much more work
/// than another, leaving the last big waves of the busier one to finish
/// while the other GPU waits (BENCHMARKS.md: short frames). Order is kept.
fn cut_at_stripes(waves: &[Wave], pixels: u32, stripe_of: &[usize]) -> Vec<Wave> {
    let count = stripe_count(stripe_of);
    // The first pixel of each stripe after the first.
    let starts: Vec<u32> =
        (1..count).map(|s| (s as u64 * pixels as u64).div_ceil(count as u64) as u32).collect();
    let mut out = Vec::with_capacity(waves.len() + count);
    for w in waves {
        let end = w.first_pixel + w.pixel_count;
        let mut first = w.first_pixel;
        for &cut in starts.iter().filter(|&&c| c > w.first_pixel && c < end) {
            out.push(Wave { sample: w.sample, first_pixel: first, pixel_count: cut - first });
            first = cut;
        }
        out.push(Wave { sample: w.sample, first_pixel: first, pixel_count: end - first });
    }
    out
}

impl StripeHandout {
    /// `waves` of an image of `pixels` pixels cut at the stripes'
    /// boundaries ([`cut_at_stripes`], so every stripe has the same
    /// pixels), and the handout of the cut waves, whose indices it hands
    /// out: worker `w` takes from stripe `stripe_of[w]` first (one stripe
    /// per distinct value, numbered from 0).
    pub fn cut(waves: &[Wave], pixels: u32, stripe_of: &[usize]) -> (Vec<Wave>, Self) {
        let waves = cut_at_stripes(waves, pixels, stripe_of);
        let handout = Self::new(&waves, pixels, stripe_of);
        (waves, handout)
    }

    /// `waves` dealt to stripes as they are (each to the stripe of its first pixel).
    fn new(waves: &[Wave], pixels: u32, stripe_of: &[usize]) -> Self {
        let count = stripe_count(stripe_of);
        let mut stripes = vec![VecDeque::new(); count];
        for (i, wave) in waves.iter().enumerate() {
            stripes[stripe_of_pixel(wave.first_pixel, pixels, count)].push_back(i);
        }
        StripeHandout {
            stripes: Mutex::new(stripes),
            stripe_of: stripe_of.to_vec(),
            steal: true,
            taken: AtomicUsize::new(0),
        }
    }

    /// Every worker renders its own stripe and no other (the prepass:
    /// each device's counts are then its stripe's, whatever the timing).
    pub fn without_stealing(mut self) -> Self {
        self.steal = false;
        self
    }
}

impl WaveHandout for StripeHandout {
    fn join(&self, me: Joining) -> Result<Joined, DeviceError> {
        Ok(Joined { workers: me.workers, wave_size: me.wave_size })
    }

    fn begin(&self, _waves: usize, _pacing: Pacing) {}

    fn next(&self, taker: usize) -> Option<usize> {
        let mut stripes = self.stripes.lock().unwrap_or_else(|p| p.into_inner());
        let own = self.stripe_of.get(taker).and_then(|&s| stripes.get_mut(s)).and_then(VecDeque::pop_front);
        let wave = own.or_else(|| {
            let fullest = stripes.iter_mut().filter(|_| self.steal).max_by_key(|s| s.len())?;
            fullest.pop_back()
        })?;
        self.taken.fetch_add(1, Ordering::Relaxed);
        Some(wave)
    }

    fn taken(&self) -> usize {
        self.taken.load(Ordering::Relaxed)
    }

    fn end(&self) {}
}

#[cfg(test)]
mod tests {
    use super::*;

    fn waves(n: u32, per: u32, samples: u32) -> Vec<Wave> {
        (0..samples)
            .flat_map(|sample| (0..n).map(move |i| Wave { sample, first_pixel: i * per, pixel_count: per }))
            .collect()
    }

    #[test]
    fn workers_take_their_stripes_in_order_then_steal_from_the_fullest() {
        // 8 waves per sample over 2 samples, 2 workers: worker 0's stripe is
        // waves 0..4 of each sample, worker 1's 4..8.
        let w = waves(8, 100, 2);
        let h = StripeHandout::new(&w, 800, &[0, 1]);
        assert_eq!(h.next(0), Some(0));
        assert_eq!(h.next(1), Some(4));
        assert_eq!(h.next(1), Some(5));
        // Worker 0 alone takes the rest of its stripe, then steals worker 1's last.
        let mine: Vec<usize> = (0..5).filter_map(|_| h.next(0)).collect();
        assert_eq!(mine, vec![1, 2, 3, 8, 9]);
        let mut rest: Vec<usize> = std::iter::from_fn(|| h.next(0)).collect();
        rest.sort_unstable();
        assert_eq!(rest, vec![6, 7, 10, 11, 12, 13, 14, 15]);
        assert_eq!(h.next(1), None);
        assert_eq!(h.taken(), 16);
    }

    #[test]
    fn cutting_at_stripes_gives_each_stripe_the_same_pixels_of_each_sample() {
        // A frame of 1000 pixels in waves of 600 (600 + 400 per sample), as
        // short frames on large GPUs cut it, over 2 and 3 stripes.
        let w = waves(2, 600, 3)
            .into_iter()
            .map(|w| Wave { pixel_count: w.pixel_count.min(1000 - w.first_pixel), ..w })
            .collect::<Vec<_>>();
        for stripe_of in [vec![0, 1], vec![0, 1, 2, 0]] {
            let count = stripe_count(&stripe_of);
            let cut = cut_at_stripes(&w, 1000, &stripe_of);
            let mut covered = vec![vec![0u32; 1000]; 3];
            let mut per_stripe = vec![vec![0u32; count]; 3];
            for c in &cut {
                let stripe = stripe_of_pixel(c.first_pixel, 1000, count);
                assert!(c.pixel_count > 0);
                for p in c.first_pixel..c.first_pixel + c.pixel_count {
                    covered[c.sample as usize][p as usize] += 1;
                    assert_eq!(stripe_of_pixel(p, 1000, count), stripe, "{c:?} spans a stripe boundary");
                }
                per_stripe[c.sample as usize][stripe] += c.pixel_count;
            }
            assert!(covered.iter().flatten().all(|&n| n == 1), "every pixel of every sample once");
            for shares in &per_stripe {
                let (min, max) = (shares.iter().min().unwrap(), shares.iter().max().unwrap());
                assert!(max - min <= 1, "{count} stripes: {shares:?}");
            }
            // Sample-major order is kept.
            assert!(cut
                .windows(2)
                .all(|p| (p[0].sample, p[0].first_pixel) < (p[1].sample, p[1].first_pixel)));
        }
        // Waves inside one stripe are left as they are.
        let small = waves(10, 100, 1);
        assert_eq!(cut_at_stripes(&small, 1000, &[0, 1]), small);
    }

    #[test]
    fn every_wave_is_handed_out_once() {
        let w = waves(10, 37, 3);
        let h = StripeHandout::new(&w, 370, &[0, 1, 2]);
        let mut seen = vec![0; w.len()];
        let mut worker = 0;
        while let Some(i) = h.next(worker % 3) {
            seen[i] += 1;
            worker += 1;
        }
        assert!(seen.iter().all(|&n| n == 1), "{seen:?}");
    }

    #[test]
    fn without_stealing_each_worker_takes_its_stripe_only() {
        let w = waves(4, 100, 1);
        let h = StripeHandout::new(&w, 400, &[0, 1]).without_stealing();
        assert_eq!((h.next(0), h.next(0), h.next(0)), (Some(0), Some(1), None));
        assert_eq!((h.next(1), h.next(1), h.next(1)), (Some(2), Some(3), None));
    }

    #[test]
    fn workers_on_one_gpu_share_its_stripe() {
        // Workers 0 and 2 on GPU 0, 1 on GPU 1: two stripes.
        let w = waves(4, 100, 1);
        let h = StripeHandout::new(&w, 400, &[0, 1, 0]);
        assert_eq!((h.next(2), h.next(0), h.next(1), h.next(2)), (Some(0), Some(1), Some(2), Some(3)));
        assert_eq!(h.next(0), None);
    }
}
