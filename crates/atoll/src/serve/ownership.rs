//! The viewers' false-colour view: every surface in the colour of the
//! ring part (device) holding it, from the viewer's camera; one colour
//! where every device holds the whole scene. Traced on the host over a BVH
//! of the whole scene, built when a viewer first asks for the view.

use std::sync::{Arc, OnceLock};

use atoll_bvh::SceneBvh;
use atoll_dist::ownership::ownership_view_of;
use atoll_dist::Partition;
use atoll_render::camera::CameraRays;
use atoll_render::FrameContext;
use atoll_scene::{Camera, Scene};
use glam::Vec3;

pub struct Ownership {
    scene: Arc<Scene>,
    /// The served frame (its camera replaced by each view's).
    frame: FrameContext,
    /// A ring's parts; `None`: every device holds everything.
    partition: Option<Partition>,
    bvh: OnceLock<SceneBvh>,
}

impl Ownership {
    pub fn new(scene: Arc<Scene>, frame: FrameContext, partition: Option<Partition>) -> Ownership {
        Ownership { scene, frame, partition, bvh: OnceLock::new() }
    }

    /// The view from `camera`, as mean radiance per pixel (colours in [0, 1]).
    pub fn view(&self, camera: &Camera) -> Vec<Vec3> {
        let bvh = self.bvh.get_or_init(|| SceneBvh::build(&self.scene));
        let camera = CameraRays::new(camera, self.frame.options.resolution);
        let frame = FrameContext { camera, ..self.frame.clone() };
        let owner = |instance: u32, mesh: u32, triangle: u32| match &self.partition {
            Some(p) => p.owner(instance, mesh, triangle),
            None => Some(0),
        };
        ownership_view_of(&self.scene, &frame, bvh, &owner).pixels()
    }
}
