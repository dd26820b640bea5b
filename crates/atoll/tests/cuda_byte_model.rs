//! The CUDA device's byte model against the partitioner (no GPU needed):
//! atoll-dist plans with what the device says a part costs, so the two
//! must agree.

use atoll_bvh::part_bytes;
use atoll_dist::{partition, PartitionOptions};

/// What the GPU partitioner charges a part (its byte model, plus the rows
/// every GPU's tables keep for the whole scene) covers the part's own
/// memory plan on the device, and not by much: a part that the plan says
/// fits is not refused by the device (landscape, memory-balanced and
/// work-balanced parts).
#[test]
fn gpu_parts_fit_what_the_partitioner_charged() {
    use atoll_cuda::scene::{byte_model, part_plan, scene_wide_rows, HEADROOM};
    let scene = atoll_scene::landscape::Landscape::new(4).build();
    let model = byte_model();
    let none = PartitionOptions::default();
    for k in [2, 3] {
        let memory = partition(&scene, k, &model, &none).unwrap();
        let work =
            atoll_dist::work::partition_work_balanced(&scene, k, glam::UVec2::new(320, 180), &model, &none)
                .unwrap();
        for part in memory.parts.iter().chain(&work.parts) {
            let device = part_plan(&scene, part).total() - HEADROOM;
            let charged = part_bytes(&scene, part, &model) + scene_wide_rows(&scene);
            assert!(
                device <= charged,
                "k {k}: the device plans {device} bytes, the partitioner charged {charged}"
            );
            assert!(device as f64 > 0.95 * charged as f64, "k {k}: {device} of {charged} charged");
        }
    }
}
