//! Host side of `kernels/sort.cu`: an exclusive prefix sum over u32 and an
//! LSD radix sort of (u32 key, u32 value) pairs, 8 bits per pass, for the
//! LBVH build.
//!
//! A radix pass: each tile of [`SORT_TILE`] pairs counts its digits
//! (`radix_histogram`, digit-major: `hist[digit * tiles + tile]`), one
//! exclusive scan over that table gives every (digit, tile) its output
//! offset, and `radix_scatter` writes each tile's pairs there in input
//! order within a digit (stable). `reference_pass` is the same algorithm
//! on the host, tested against a stable sort.

use cudarc::driver::sys::CUdeviceptr;
use cudarc::driver::{CudaFunction, CudaSlice, DevicePtr, DevicePtrMut, LaunchConfig, PushKernelArg};

use crate::error::CudaError;
use crate::gpu::Gpu;

/// Threads per block of the sort and scan kernels.
const THREADS: u32 = 256;
/// Pairs per radix tile (SORT_TILE in sort.cu).
pub(crate) const SORT_TILE: u32 = 4096;
/// Elements per scan tile (SCAN_TILE in sort.cu).
pub(crate) const SCAN_TILE: u32 = 2048;
pub(super) const FILE: &str = "sort.cu";

/// One radix pass: the 8 bits at `shift` of the key, or of the segment of
/// the value (a primitive index) when `from_segment`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SortPass {
    pub shift: u32,
    pub from_segment: bool,
}

/// Passes that order 30-bit Morton codes by (segment, code): four over the
/// code, then as many over the segment id as its bits need (none for one segment).
pub fn morton_passes(segments: u32) -> Vec<SortPass> {
    let mut passes: Vec<SortPass> = (0..4).map(|k| SortPass { shift: 8 * k, from_segment: false }).collect();
    let mut shift = 0;
    while shift < 32 && (segments.saturating_sub(1) >> shift) != 0 {
        passes.push(SortPass { shift, from_segment: true });
        shift += 8;
    }
    passes
}

/// A scan of `n` elements over buffers of `len` with scratch for `capacity`.
fn check_scan_len(n: u32, len: usize, capacity: u32) -> Result<(), CudaError> {
    if n > capacity || n as usize > len {
        return Err(CudaError::Usage(format!("scan of {n} elements exceeds its buffers")));
    }
    Ok(())
}

fn radix_tiles(n: u32) -> u32 {
    n.div_ceil(SORT_TILE).max(1)
}

/// Device scratch of the scan and the sort for up to `n` elements.
pub struct SortScratch {
    hist: CudaSlice<u32>,
    tile_sums: CudaSlice<u32>,
    /// `[0]`: the total of the last scan.
    pub total: CudaSlice<u32>,
    capacity: u32,
}

impl SortScratch {
    /// Scratch for sorting `n` pairs and scanning up to `scan_n` elements.
    pub fn new(gpu: &Gpu, n: u32, scan_n: u32) -> Result<Self, CudaError> {
        let alloc = |len: u64| {
            gpu.stream
                .alloc_zeros::<u32>(len.max(1) as usize)
                .map_err(CudaError::driver(format!("{}: allocating sort scratch", gpu.label())))
        };
        let hist_len = 256 * radix_tiles(n) as u64;
        let scan_len = hist_len.max(scan_n as u64);
        Ok(SortScratch {
            hist: alloc(hist_len)?,
            tile_sums: alloc(scan_len.div_ceil(SCAN_TILE as u64))?,
            total: alloc(1)?,
            capacity: scan_len as u32,
        })
    }

    /// Device bytes [`SortScratch::new`] allocates.
    pub(crate) fn bytes(n: u32, scan_n: u32) -> u64 {
        let hist_len = 256 * radix_tiles(n) as u64;
        let scan_len = hist_len.max(scan_n as u64);
        4 * (hist_len.max(1) + scan_len.div_ceil(SCAN_TILE as u64).max(1) + 1)
    }
}

/// The sort and scan kernels, loaded once per build.
pub struct SortKernels {
    scan_reduce: CudaFunction,
    scan_tile_sums: CudaFunction,
    scan_downsweep: CudaFunction,
    histogram: CudaFunction,
    scatter: CudaFunction,
}

fn grid(blocks: u32, shared: u32) -> LaunchConfig {
    LaunchConfig { grid_dim: (blocks.max(1), 1, 1), block_dim: (THREADS, 1, 1), shared_mem_bytes: shared }
}

impl SortKernels {
    pub fn load(gpu: &Gpu) -> Result<Self, CudaError> {
        Ok(SortKernels {
            scan_reduce: gpu.function(FILE, "scan_reduce")?,
            scan_tile_sums: gpu.function(FILE, "scan_tile_sums")?,
            scan_downsweep: gpu.function(FILE, "scan_downsweep")?,
            histogram: gpu.function(FILE, "radix_histogram")?,
            scatter: gpu.function(FILE, "radix_scatter")?,
        })
    }

    /// Exclusive prefix sum of `data[..n]` in place; the total goes to
    /// `scratch.total[0]`. `n` must not exceed the scratch's capacity.
    pub fn scan_in_place(
        &self,
        gpu: &Gpu,
        data: &mut CudaSlice<u32>,
        n: u32,
        scratch: &mut SortScratch,
    ) -> Result<(), CudaError> {
        check_scan_len(n, data.len(), scratch.capacity)?;
        let (ptr, _write) = data.device_ptr_mut(&gpu.stream);
        self.scan_pointers(gpu, ptr, ptr, n, &mut scratch.tile_sums, &mut scratch.total)
    }

    /// Exclusive prefix sum of `input[..n]` into `output[..n]` (the input
    /// stays); the total goes to `scratch.total[0]`.
    pub fn scan(
        &self,
        gpu: &Gpu,
        input: &CudaSlice<u32>,
        output: &mut CudaSlice<u32>,
        n: u32,
        scratch: &mut SortScratch,
    ) -> Result<(), CudaError> {
        check_scan_len(n, input.len().min(output.len()), scratch.capacity)?;
        let (src, _read) = input.device_ptr(&gpu.stream);
        let (dst, _write) = output.device_ptr_mut(&gpu.stream);
        self.scan_pointers(gpu, src, dst, n, &mut scratch.tile_sums, &mut scratch.total)
    }

    /// The scan's three launches from `input` to `output` (the same
    /// buffer for a scan in place: each block reads its tile before it
    /// writes it), both of at least `n` elements.
    fn scan_pointers(
        &self,
        gpu: &Gpu,
        input: CUdeviceptr,
        output: CUdeviceptr,
        n: u32,
        tile_sums: &mut CudaSlice<u32>,
        total: &mut CudaSlice<u32>,
    ) -> Result<(), CudaError> {
        let tiles = n.div_ceil(SCAN_TILE).max(1);
        let err = |k: &str| CudaError::driver(format!("{}: launching {k}", gpu.label()));
        let mut launch = gpu.stream.launch_builder(&self.scan_reduce);
        launch.arg(&input).arg(&n).arg(&mut *tile_sums);
        // SAFETY: matches `scan_reduce(const unsigned* in, unsigned n, unsigned* tile_sums)`;
        // `input` holds n elements (the callers check), `tile_sums` ceil(capacity /
        // SCAN_TILE) >= tiles.
        unsafe { launch.launch(grid(tiles, 0)) }.map_err(err("scan_reduce"))?;
        let mut launch = gpu.stream.launch_builder(&self.scan_tile_sums);
        launch.arg(&mut *tile_sums).arg(&tiles).arg(&mut *total);
        // SAFETY: matches `scan_tile_sums(unsigned* tile_sums, unsigned tiles, unsigned* total)`;
        // one block loops over the `tiles` entries; `total` holds one element.
        unsafe { launch.launch(grid(1, 0)) }.map_err(err("scan_tile_sums"))?;
        let mut launch = gpu.stream.launch_builder(&self.scan_downsweep);
        launch.arg(&input).arg(&output).arg(&n).arg(&*tile_sums);
        // SAFETY: matches `scan_downsweep(const unsigned* in, unsigned* out, unsigned n, const
        // unsigned* tile_sums)`; block b reads tile_sums[b] for b < tiles, and its own tile of
        // `input` below n before writing the same elements of `output`.
        unsafe { launch.launch(grid(tiles, 0)) }.map_err(err("scan_downsweep"))?;
        Ok(())
    }

    /// Sorts `keys[..n]`/`values[..n]` by the digits of `passes` (least
    /// significant first), stable; `keys_alt`/`values_alt` are ping-pong
    /// buffers of at least `n`. The result ends in `keys`/`values` (the
    /// buffers are swapped as needed). `seg_start` (`segments + 1` entries)
    /// serves the segment passes.
    #[allow(clippy::too_many_arguments)]
    pub fn sort_pairs(
        &self,
        gpu: &Gpu,
        keys: &mut CudaSlice<u32>,
        values: &mut CudaSlice<u32>,
        keys_alt: &mut CudaSlice<u32>,
        values_alt: &mut CudaSlice<u32>,
        n: u32,
        passes: &[SortPass],
        seg_start: &CudaSlice<u32>,
        segments: u32,
        scratch: &mut SortScratch,
    ) -> Result<(), CudaError> {
        let buffers_ok =
            [keys.len(), values.len(), keys_alt.len(), values_alt.len()].iter().all(|&l| l >= n as usize);
        if n == 0 {
            return Ok(());
        }
        let tiles = radix_tiles(n);
        if !buffers_ok || 256 * tiles as u64 > scratch.hist.len() as u64 {
            return Err(CudaError::Usage(format!("radix sort of {n} pairs exceeds its buffers")));
        }
        let hist_len = 256 * tiles;
        let err = |k: &str| CudaError::driver(format!("{}: launching {k}", gpu.label()));
        for pass in passes {
            let from_segment = pass.from_segment as u32;
            let mut launch = gpu.stream.launch_builder(&self.histogram);
            launch
                .arg(&*keys)
                .arg(&*values)
                .arg(&n)
                .arg(&pass.shift)
                .arg(&from_segment)
                .arg(seg_start)
                .arg(&segments)
                .arg(&mut scratch.hist)
                .arg(&tiles);
            // SAFETY: matches `radix_histogram(const unsigned* keys, const unsigned* values,
            // unsigned n, unsigned shift, unsigned from_segment, const unsigned* seg_start,
            // unsigned segments, unsigned* hist, unsigned tiles)`; keys/values hold n pairs,
            // hist 256 * tiles entries (checked above), seg_start segments + 1.
            unsafe { launch.launch(grid(tiles, 0)) }.map_err(err("radix_histogram"))?;
            check_scan_len(hist_len, scratch.hist.len(), scratch.capacity)?;
            {
                let (hist, _write) = scratch.hist.device_ptr_mut(&gpu.stream);
                self.scan_pointers(gpu, hist, hist, hist_len, &mut scratch.tile_sums, &mut scratch.total)?;
            }
            let mut launch = gpu.stream.launch_builder(&self.scatter);
            launch
                .arg(&*keys)
                .arg(&*values)
                .arg(&mut *keys_alt)
                .arg(&mut *values_alt)
                .arg(&n)
                .arg(&pass.shift)
                .arg(&from_segment)
                .arg(seg_start)
                .arg(&segments)
                .arg(&scratch.hist)
                .arg(&tiles);
            // SAFETY: matches `radix_scatter(const unsigned* keys_in, const unsigned* values_in,
            // unsigned* keys_out, unsigned* values_out, unsigned n, unsigned shift, unsigned
            // from_segment, const unsigned* seg_start, unsigned segments, const unsigned*
            // hist_scanned, unsigned tiles)`; the scanned offsets of the n pairs are below n,
            // and the output buffers hold at least n pairs (checked above).
            unsafe { launch.launch(grid(tiles, 0)) }.map_err(err("radix_scatter"))?;
            std::mem::swap(keys, keys_alt);
            std::mem::swap(values, values_alt);
        }
        Ok(())
    }
}

/// One radix pass on the host, tile for tile as the kernels do it: tile
/// histograms digit-major, an exclusive scan, a stable scatter.
#[cfg(test)]
pub(crate) fn reference_pass(
    keys: &[u32],
    values: &[u32],
    digit: impl Fn(u32, u32) -> u32,
) -> (Vec<u32>, Vec<u32>) {
    let n = keys.len();
    let tiles = (n as u32).div_ceil(SORT_TILE).max(1) as usize;
    let mut hist = vec![0u32; 256 * tiles];
    for i in 0..n {
        hist[digit(keys[i], values[i]) as usize * tiles + i / SORT_TILE as usize] += 1;
    }
    let mut sum = 0;
    for h in hist.iter_mut() {
        let c = *h;
        *h = sum;
        sum += c;
    }
    let (mut out_keys, mut out_values) = (vec![0; n], vec![0; n]);
    for i in 0..n {
        let slot = &mut hist[digit(keys[i], values[i]) as usize * tiles + i / SORT_TILE as usize];
        out_keys[*slot as usize] = keys[i];
        out_values[*slot as usize] = values[i];
        *slot += 1;
    }
    (out_keys, out_values)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_cover_code_and_segment_bits() {
        assert_eq!(morton_passes(1).len(), 4);
        assert_eq!(morton_passes(2).last(), Some(&SortPass { shift: 0, from_segment: true }));
        assert_eq!(morton_passes(256).len(), 5);
        assert_eq!(morton_passes(257).len(), 6);
        assert_eq!(morton_passes(u32::MAX).len(), 8);
    }

    #[test]
    fn reference_passes_sort_stably_with_duplicates() {
        let mut s = 7u64;
        let mut next = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 33) as u32
        };
        for n in [0, 1, 5, 4096, 4097, 20_000] {
            // Few distinct keys: long runs of duplicates across tiles.
            let keys: Vec<u32> = (0..n).map(|_| next() % 50 * 0x0101_0101).collect();
            let values: Vec<u32> = (0..n as u32).collect();
            let (mut k, mut v) = (keys.clone(), values.clone());
            for shift in [0, 8, 16, 24] {
                (k, v) = reference_pass(&k, &v, |key, _| (key >> shift) & 0xff);
            }
            let mut expected: Vec<(u32, u32)> = keys.iter().copied().zip(values).collect();
            expected.sort_by_key(|&(key, _)| key);
            assert_eq!(k.into_iter().zip(v).collect::<Vec<_>>(), expected, "n = {n}");
        }
    }

    #[test]
    fn scratch_bytes_match_the_allocation_plan() {
        assert_eq!(SortScratch::bytes(0, 0), 4 * (256 + 1 + 1));
        assert_eq!(SortScratch::bytes(10_000, 20_000), 4 * (768 + 10 + 1));
    }
}
