//! The on-disk cache of compiled kernels.
//!
//! Compiling the wavefront kernels takes NVRTC a noticeable fraction of a
//! second each; the cache makes every run after the first start at once. An
//! entry is keyed by a hash of everything that decides the output (spliced
//! source, options, target, NVRTC version), so editing a kernel or updating
//! the toolkit simply misses. Entries are written to a temporary name and
//! renamed (readers never see half a file); an entry that fails its checksum
//! is treated as a miss and rewritten. The cache is an optimisation only:
//! every failure to read or write it is logged and ignored.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

/// FNV-1a, 64 bit. Written here rather than taken from `std::hash`: std's
/// `DefaultHasher` (SipHash) is explicitly not stable across Rust releases,
/// and a cache key must mean the same thing to every build that reads it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Fnv1a64(u64);

impl Fnv1a64 {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;

    pub(crate) fn new() -> Self {
        Fnv1a64(Self::OFFSET)
    }

    pub(crate) fn write(&mut self, bytes: &[u8]) -> &mut Self {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(Self::PRIME);
        }
        self
    }

    /// Writes `bytes` followed by a separator, so that ("ab","c") and
    /// ("a","bc") hash differently.
    pub(crate) fn field(&mut self, bytes: &[u8]) -> &mut Self {
        self.write(&(bytes.len() as u64).to_le_bytes()).write(bytes)
    }

    pub(crate) fn finish(&self) -> u64 {
        self.0
    }
}

impl Default for Fnv1a64 {
    fn default() -> Self {
        Self::new()
    }
}

/// FNV-1a 64 of one byte string.
pub(crate) fn fnv1a64(bytes: &[u8]) -> u64 {
    Fnv1a64::new().write(bytes).finish()
}

/// First bytes of every entry; bump the digit when the format changes.
const MAGIC: &[u8; 8] = b"ATOLLK1\n";
const HEADER: usize = MAGIC.len() + 16;

/// The cache directory from the environment: `$ATOLL_KERNEL_CACHE` (`off`
/// disables the cache), else `$XDG_CACHE_HOME/atoll/kernels`, else
/// `~/.cache/atoll/kernels`; `None` when none can be formed.
pub(crate) fn default_dir() -> Option<PathBuf> {
    let env = |k: &str| std::env::var_os(k).filter(|v| !v.is_empty());
    if let Some(dir) = env("ATOLL_KERNEL_CACHE") {
        return (dir != "off").then(|| PathBuf::from(dir));
    }
    if let Some(xdg) = env("XDG_CACHE_HOME") {
        return Some(PathBuf::from(xdg).join("atoll/kernels"));
    }
    env("HOME").map(|home| PathBuf::from(home).join(".cache/atoll/kernels"))
}

/// A directory of compiled kernels.
#[derive(Clone, Debug)]
pub struct KernelCache {
    dir: PathBuf,
}

impl KernelCache {
    pub fn new(dir: impl Into<PathBuf>) -> Self {
        KernelCache { dir: dir.into() }
    }

    /// The cache of [`default_dir`], if any.
    pub(crate) fn from_env() -> Option<Self> {
        default_dir().map(Self::new)
    }

    /// Where entry `key` lives; `ext` (`ptx`, `cubin`) only helps humans.
    pub(crate) fn path(&self, key: u64, ext: &str) -> PathBuf {
        self.dir.join(format!("{key:016x}.{ext}"))
    }

    /// The entry for `key`, or `None` on a miss, an unreadable file or a
    /// corrupt one (bad magic, length or checksum).
    pub(crate) fn get(&self, key: u64, ext: &str) -> Option<Vec<u8>> {
        let path = self.path(key, ext);
        let bytes = std::fs::read(&path).ok()?;
        match decode(&bytes) {
            Some(payload) => Some(payload.to_vec()),
            None => {
                tracing::warn!("kernel cache: {} is corrupt; recompiling", path.display());
                None
            }
        }
    }

    /// Stores `payload` under `key`. Failures are logged, never returned:
    /// a read-only cache directory must not stop a render.
    pub(crate) fn put(&self, key: u64, ext: &str, payload: &[u8]) {
        if let Err(e) = self.try_put(key, ext, payload) {
            tracing::warn!("kernel cache: cannot write to {}: {e}", self.dir.display());
        }
    }

    fn try_put(&self, key: u64, ext: &str, payload: &[u8]) -> std::io::Result<()> {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        std::fs::create_dir_all(&self.dir)?;
        let path = self.path(key, ext);
        // Unique per process and call: concurrent writers never share a temp file.
        let tmp = self.dir.join(format!(
            ".{key:016x}.{}.{}.tmp",
            std::process::id(),
            COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let mut bytes = Vec::with_capacity(HEADER + payload.len());
        bytes.extend_from_slice(MAGIC);
        bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        bytes.extend_from_slice(&fnv1a64(payload).to_le_bytes());
        bytes.extend_from_slice(payload);
        std::fs::write(&tmp, &bytes)
            .and_then(|_| std::fs::rename(&tmp, &path))
            .inspect_err(|_| drop(std::fs::remove_file(&tmp)))
    }
}

fn decode(bytes: &[u8]) -> Option<&[u8]> {
    if bytes.len() < HEADER || &bytes[..MAGIC.len()] != MAGIC {
        return None;
    }
    let len = u64::from_le_bytes(bytes[8..16].try_into().ok()?);
    let sum = u64::from_le_bytes(bytes[16..24].try_into().ok()?);
    let payload = &bytes[HEADER..];
    (payload.len() as u64 == len && fnv1a64(payload) == sum).then_some(payload)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv_matches_reference_vectors() {
        // From the FNV reference test suite.
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn fields_are_delimited() {
        let a = Fnv1a64::new().field(b"ab").field(b"c").finish();
        let b = Fnv1a64::new().field(b"a").field(b"bc").finish();
        assert_ne!(a, b);
    }

    #[test]
    fn round_trip_and_corruption_is_a_miss() {
        let dir = std::env::temp_dir().join(format!("atoll-kcache-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let cache = KernelCache::new(&dir);
        assert_eq!(cache.get(7, "ptx"), None);
        cache.put(7, "ptx", b"// ptx text");
        assert_eq!(cache.get(7, "ptx").as_deref(), Some(&b"// ptx text"[..]));
        // Flip a payload byte: the checksum fails, so it is a miss.
        let path = cache.path(7, "ptx");
        let mut bytes = std::fs::read(&path).unwrap();
        *bytes.last_mut().unwrap() ^= 1;
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(cache.get(7, "ptx"), None);
        // Truncated to less than a header: a miss too.
        std::fs::write(&path, b"ATOLL").unwrap();
        assert_eq!(cache.get(7, "ptx"), None);
        // Rewriting repairs it; no temporary files are left behind.
        cache.put(7, "ptx", b"again");
        assert_eq!(cache.get(7, "ptx").as_deref(), Some(&b"again"[..]));
        let leftovers = std::fs::read_dir(&dir)
            .unwrap()
            .filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().ends_with(".tmp"));
        assert_eq!(leftovers.count(), 0);
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn unwritable_directory_is_not_an_error() {
        // A path under a regular file cannot be created; `put` only logs.
        let file = std::env::temp_dir().join(format!("atoll-kcache-file-{}", std::process::id()));
        std::fs::write(&file, b"x").unwrap();
        let cache = KernelCache::new(file.join("sub"));
        cache.put(1, "ptx", b"data");
        assert_eq!(cache.get(1, "ptx"), None);
        std::fs::remove_file(&file).ok();
    }
}
