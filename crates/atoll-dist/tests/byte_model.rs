//! Checks `ByteModel::CPU` against what building a `SceneBvh` really
//! allocates, counted by a global allocator (which is why this is its own
//! test binary with a single test: nothing else may allocate meanwhile).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

use atoll_bvh::{part_bytes, part_geometry_bytes, ByteModel, SceneBvh, ScenePart};
use atoll_scene::procedural::{bench_scene, bench_scene_flat};

struct Counting;

static NOW: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator, only counting sizes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let now = NOW.fetch_add(layout.size(), Relaxed) + layout.size();
        PEAK.fetch_max(now, Relaxed);
        // SAFETY: the caller's layout is passed on unchanged.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        NOW.fetch_sub(layout.size(), Relaxed);
        // SAFETY: `ptr` came from `alloc` above with this layout.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

#[test]
fn cpu_model_covers_the_build_peak_and_what_stays() {
    // One object (a flattened scene): one BLAS build, so the peak does not
    // depend on how many builds rayon runs at once. Then instanced objects.
    for (name, scene, tolerance) in
        [("flat", bench_scene_flat(30_000), 1.0), ("instanced", bench_scene(30_000), 0.9)]
    {
        let part = ScenePart::whole(&scene);
        let base = NOW.load(Relaxed);
        PEAK.store(base, Relaxed);
        let bvh = SceneBvh::build_part(&scene, &part);
        let peak = (PEAK.load(Relaxed) - base) as f64;
        let kept = (NOW.load(Relaxed) - base) as f64;
        drop(bvh);
        // The geometry is the host scene's on the CPU: allocated before.
        let model =
            |m: &ByteModel| (part_bytes(&scene, &part, m) - part_geometry_bytes(&scene, &part)) as f64;
        let resident = model(&ByteModel { scratch_per_triangle: 0, ..ByteModel::CPU });
        let with_scratch = model(&ByteModel::CPU);
        eprintln!("{name}: kept {kept}, modelled {resident}; peak {peak}, modelled {with_scratch}");
        assert!((0.9 * kept..1.3 * kept).contains(&resident), "{name}: kept {kept}, modelled {resident}");
        assert!(
            (tolerance * peak..1.3 * peak).contains(&with_scratch),
            "{name}: peak {peak}, modelled {with_scratch}"
        );
    }
}
