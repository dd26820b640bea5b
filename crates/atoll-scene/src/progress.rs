//! What has been done so far towards a frame after loading: scene bytes
//! copied to devices and triangles BVHs were built over. Counted
//! process-wide, as the loaders count what they read, so that a progress
//! line can show the preparing's rates without a sink threaded through
//! every device and builder; a reader takes the difference between two
//! looks ([`Prepared::since`]).

use std::sync::atomic::{AtomicU64, Ordering};

static BYTES_COPIED: AtomicU64 = AtomicU64::new(0);
static TRIANGLES_BUILT: AtomicU64 = AtomicU64::new(0);

/// `bytes` of scene data (tables, BVH nodes) reached a device.
pub fn copied(bytes: u64) {
    BYTES_COPIED.fetch_add(bytes, Ordering::Relaxed);
}

/// A BVH was built over `triangles` more triangles.
pub fn built(triangles: u64) {
    TRIANGLES_BUILT.fetch_add(triangles, Ordering::Relaxed);
}

/// Totals since the process began, or the difference of two looks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Prepared {
    pub bytes_copied: u64,
    pub triangles_built: u64,
}

impl Prepared {
    /// The totals now.
    pub fn now() -> Prepared {
        Prepared {
            bytes_copied: BYTES_COPIED.load(Ordering::Relaxed),
            triangles_built: TRIANGLES_BUILT.load(Ordering::Relaxed),
        }
    }

    /// What was done between `earlier` and `self`.
    pub fn since(self, earlier: Prepared) -> Prepared {
        Prepared {
            bytes_copied: self.bytes_copied.saturating_sub(earlier.bytes_copied),
            triangles_built: self.triangles_built.saturating_sub(earlier.triangles_built),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn looks_apart_give_what_was_done_between() {
        let before = Prepared::now();
        copied(1000);
        built(12);
        // Other tests may count at once: at least what was added here.
        let done = Prepared::now().since(before);
        assert!(done.bytes_copied >= 1000 && done.triangles_built >= 12, "{done:?}");
        assert_eq!(before.since(Prepared::now()), Prepared::default());
    }
}
