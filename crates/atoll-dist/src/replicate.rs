//! The replicate strategy: every device holds the whole scene and takes
//! waves of pixels from the frame's handout as it frees up, so faster
//! devices take more of them (the dynamic load balancing of Jaroš et al.
//! 2021).

use atoll_render::integrator::render_waves;
use atoll_render::{Device, Wave};

use crate::render::DeviceReport;

/// One device's frame: waves from `take` until there are none, merged into
/// the path queue as it has room when `merge`; `taken` is told of each. A
/// failure ends it, kept in `report`.
pub(crate) fn run_device<'w>(
    device: &mut dyn Device,
    merge: bool,
    take: &dyn Fn() -> Option<&'w Wave>,
    taken: &dyn Fn(),
    report: &mut DeviceReport,
) {
    let mut waves = 0;
    let rendered = render_waves(device, merge, &mut || {
        let wave = take().copied();
        if wave.is_some() {
            waves += 1;
            taken();
        }
        wave
    });
    report.waves += waves;
    if let Err(e) = rendered {
        report.fail(e);
    }
}
