//! Refusing a scene that cannot fit the device before anything of it is
//! built. A generated scene's sizes follow from its parameters, a file
//! scene's from its text and mesh headers (checked by the loader through
//! [`Room::size_check`]); the device's byte model (the estimate placement
//! plans with) over them is compared with the device's memory in
//! milliseconds, rather than after a build that takes minutes and the host
//! memory of the whole scene.

use std::path::Path;

use atoll_bvh::ByteModel;
use atoll_render::Device;
use atoll_scene::input::SizeCheck;
use atoll_scene::SceneSizes;

use crate::CliError;

/// The sizes of the scene at `source` where they are known without
/// building it (a generated landscape); `None` otherwise.
pub(crate) fn known_sizes(source: Option<&Path>) -> Result<Option<SceneSizes>, CliError> {
    let Some(landscape) = source.and_then(|s| s.to_str()).and_then(crate::load::parse_landscape) else {
        return Ok(None);
    };
    let landscape = landscape?;
    // A landscape the scene model cannot hold is refused when it is loaded.
    if landscape.check().is_err() {
        return Ok(None);
    }
    Ok(Some(landscape.estimate().sizes()))
}

/// What a device, or a set of devices together, can hold, for checks made
/// before a scene is built: the smallest of what is free on each (host
/// memory available, for devices that draw on it) and its budget
/// (`--device-memory`).
#[derive(Clone, Debug)]
pub(crate) struct Room {
    /// e.g. `cuda:0`, or `the 2 devices cuda:0, cuda:1`.
    device: String,
    /// The devices' byte models: the scene needs at least the least of them.
    models: Vec<ByteModel>,
    capacity: u64,
    /// Which limit `capacity` is, for messages.
    limit: String,
}

impl Room {
    /// `None` where nothing bounds the device's memory.
    pub fn of(device: &dyn Device, budget: Option<u64>) -> Option<Room> {
        let free = device.free_memory();
        let host = if free.is_none() { atoll_render::device::host_memory_available() } else { None };
        let capacity = free.into_iter().chain(host).chain(budget).min()?;
        let limit = if budget == Some(capacity) {
            "its --device-memory budget"
        } else if host == Some(capacity) {
            "host memory available"
        } else {
            "its free memory"
        };
        Some(Room { device: device.name(), models: vec![device.byte_model()], capacity, limit: limit.into() })
    }

    /// What `devices` hold together however the scene is split over them
    /// (a bound below which no strategy can go): each piece of hardware
    /// counted once, devices that draw on host memory sharing what the
    /// host has, and where `host_tier` (scene memory shared over devices
    /// of their own memory, whose coldest chunks may stay on the host) the
    /// host's share for chunks as well. `None` where nothing bounds them.
    pub fn of_devices(devices: &[Box<dyn Device>], budget: Option<u64>, host_tier: bool) -> Option<Room> {
        if let [device] = devices {
            // One GPU sharing its scene memory with the host keeps chunks
            // there too: counted below.
            if !(host_tier && device.free_memory().is_some()) {
                return Room::of(device.as_ref(), budget);
            }
        }
        let host = atoll_render::device::host_memory_available();
        let leaders: Vec<&dyn Device> = devices
            .iter()
            .enumerate()
            .filter(|(i, d)| !devices[..*i].iter().any(|e| d.shares_memory_with(e.as_ref())))
            .map(|(_, d)| d.as_ref())
            .collect();
        let mut capacity = 0u64;
        let on_host = leaders.iter().filter(|d| d.free_memory().is_none()).count() as u64;
        for device in leaders.iter().filter(|d| d.free_memory().is_some()) {
            let free = device.free_memory().expect("memory of its own");
            capacity = capacity.saturating_add(budget.map_or(free, |b| b.min(free)));
        }
        if on_host > 0 {
            let budgets = budget.map(|b| b.saturating_mul(on_host));
            capacity = capacity.saturating_add(host.into_iter().chain(budgets).min()?);
        }
        let mut limit = String::from("their memory together");
        if host_tier && on_host == 0 {
            // The shared strategy's own rule for the host's share.
            capacity = capacity.saturating_add(host?.saturating_sub(host? / 4));
            limit.push_str(", host memory for chunks included");
        }
        let names: Vec<String> = devices.iter().map(|d| d.name()).collect();
        let mut models: Vec<ByteModel> = devices.iter().map(|d| d.byte_model()).collect();
        if host_tier {
            // Shared scene memory holds only what stays resident.
            models.extend(devices.iter().map(|d| d.shared_byte_model()));
        }
        Some(Room {
            device: format!("the {} devices {}", devices.len(), names.join(", ")),
            models,
            capacity,
            limit,
        })
    }

    /// `Err(why)` when a scene of `counts` cannot fit.
    pub fn check(&self, counts: &SceneSizes) -> Result<(), String> {
        let needed = self.models.iter().map(|m| m.bytes(counts)).min().unwrap_or(0);
        if needed <= self.capacity {
            return Ok(());
        }
        Err(format!(
            "does not fit {}: it needs about {needed} bytes ({} triangles in {} objects, {} instances; \
             estimated before building it), more than the {} bytes of {}",
            self.device, counts.triangles, counts.objects, counts.instances, self.capacity, self.limit
        ))
    }

    /// The same check for a loader ([`atoll_scene::input::LoadBudget::with_size_check`]).
    pub fn size_check(self) -> SizeCheck {
        Box::new(move |sizes: &SceneSizes| self.check(sizes))
    }
}

/// Refuses a scene of `counts` that `room` cannot hold; none bounds a
/// device without a limit.
pub(crate) fn check_fits(source: &Path, counts: &SceneSizes, room: Option<&Room>) -> Result<(), CliError> {
    let Some(room) = room else { return Ok(()) };
    room.check(counts).map_err(|why| CliError::Runtime(format!("{}: {why}", source.display())))
}

#[cfg(test)]
mod tests {
    use super::*;
    use atoll_render::CpuDevice;

    #[test]
    fn a_landscape_that_cannot_fit_the_budget_is_refused_from_its_sizes() {
        let source = Path::new("landscape:100");
        let counts = known_sizes(Some(source)).unwrap().expect("a landscape's sizes are known");
        let device = CpuDevice::new();
        let needed = device.byte_model().bytes(&counts);
        // The estimate is the byte model's charge for the built scene.
        let scene = atoll_scene::landscape::Landscape::new(100).build();
        let whole = atoll_bvh::ScenePart::whole(&scene);
        assert_eq!(needed, atoll_bvh::part_bytes(&scene, &whole, &device.byte_model()));
        assert!(check_fits(source, &counts, Room::of(&device, Some(needed)).as_ref()).is_ok());
        let Err(CliError::Runtime(message)) =
            check_fits(source, &counts, Room::of(&device, Some(needed - 1)).as_ref())
        else {
            panic!("not refused")
        };
        assert!(message.contains("estimated before building it") && message.contains("--device-memory"));
        // A CPU device without a budget has the host's memory.
        let host = atoll_render::device::host_memory_available();
        assert_eq!(
            check_fits(source, &counts, Room::of(&device, None).as_ref()).is_ok(),
            host.is_none_or(|h| needed <= h)
        );
        assert!(known_sizes(Some(Path::new("scene.pbrt"))).unwrap().is_none());
        assert!(known_sizes(None).unwrap().is_none());
    }
}
