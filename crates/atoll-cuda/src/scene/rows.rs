//! Tables made where they are needed: a [`RowTable`] is a length and a
//! function that writes any range of its rows, so an upload writes the
//! rows straight into page-locked staging memory (the host never holds the
//! whole table: no fresh pages to fault in and clear, no second copy),
//! and a host build fills a vector the same way.

use rayon::prelude::*;

/// Fewest rows one parallel task fills.
pub(crate) const MIN_ROWS: usize = 1 << 14;

type Fill<'a, W> = dyn Fn(usize, &mut [W]) + Sync + 'a;

/// A table of `rows` rows of `words` words each: `fill(first, out)` writes
/// rows `first..` into `out` (a whole number of rows, all of them written).
pub(crate) struct RowTable<'a, W> {
    pub rows: usize,
    pub words: usize,
    fill: Box<Fill<'a, W>>,
}

impl<'a, W: bytemuck::Pod + Send + Sync> RowTable<'a, W> {
    pub fn new(rows: usize, words: usize, fill: impl Fn(usize, &mut [W]) + Sync + 'a) -> Self {
        RowTable { rows, words, fill: Box::new(fill) }
    }

    /// Rows that are consecutive segments (a mesh's vertices, a range of
    /// its triangles), segment `k` of `counts[k]` rows:
    /// `fill_segment(k, first, out)` writes its rows from `first` on.
    pub fn segments(
        counts: impl IntoIterator<Item = usize>,
        words: usize,
        fill_segment: impl Fn(usize, usize, &mut [W]) + Sync + 'a,
    ) -> Self {
        let mut starts = vec![0usize];
        for c in counts {
            starts.push(starts.last().unwrap() + c);
        }
        let rows = *starts.last().unwrap();
        RowTable::new(rows, words, move |mut row, mut out: &mut [W]| {
            // The segment holding `row`: the last start at or before it
            // (empty segments share their start with the next one).
            let mut k = starts.partition_point(|&s| s <= row) - 1;
            while !out.is_empty() {
                let take = (starts[k + 1] - row).min(out.len() / words);
                let (head, rest) = std::mem::take(&mut out).split_at_mut(take * words);
                fill_segment(k, row - starts[k], head);
                (row, out, k) = (row + take, rest, k + 1);
            }
        })
    }

    /// Words of the whole table.
    pub fn len(&self) -> usize {
        self.rows * self.words
    }

    /// Writes rows `first..` into `out`, in parallel tasks of
    /// [`MIN_ROWS`] rows or more.
    pub fn fill_par(&self, first: usize, out: &mut [W]) {
        out.par_chunks_mut(MIN_ROWS * self.words)
            .enumerate()
            .for_each(|(i, chunk)| (self.fill)(first + i * MIN_ROWS, chunk));
    }

    /// The whole table in host memory.
    pub fn to_vec(&self) -> Vec<W> {
        let mut v = vec![W::zeroed(); self.len()];
        self.fill_par(0, &mut v);
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_fill_any_range_as_the_whole() {
        // Segments of 0, 3, 0, 5 and 1 rows of 2 words: word = (segment, row).
        let counts = [0usize, 3, 0, 5, 1];
        let t = RowTable::<u32>::segments(counts, 2, |k, first, out| {
            for (i, row) in out.chunks_mut(2).enumerate() {
                row.copy_from_slice(&[k as u32, (first + i) as u32]);
            }
        });
        assert_eq!(t.rows, 9);
        let whole = t.to_vec();
        assert_eq!(&whole[..8], &[1, 0, 1, 1, 1, 2, 3, 0]);
        assert_eq!(&whole[16..], &[4, 0]);
        for first in 0..t.rows {
            for last in first..=t.rows {
                let mut part = vec![99u32; 2 * (last - first)];
                (t.fill)(first, &mut part);
                assert_eq!(part, whole[2 * first..2 * last], "rows {first}..{last}");
            }
        }
    }
}
