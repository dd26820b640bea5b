//! The render loop behind `atoll serve`: passes of samples on prepared
//! devices ([`Session`]), as many samples a pass as fill about
//! [`PASS_SECONDS`], one sample after every camera move so the view
//! answers at once; a snapshot of the film for the viewers at most every
//! [`SNAPSHOT_SECONDS`]. Viewers never block it: they read the latest
//! snapshot when they like, and their commands wait for the next pass.

use std::path::PathBuf;
use std::sync::mpsc::{Receiver, RecvTimeoutError, TryRecvError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use atoll_dist::Session;
use atoll_render::camera::CameraRays;
use atoll_scene::Camera;
use glam::{UVec2, Vec3};
use tokio::sync::watch;

use super::view::{Move, Orbit};

/// How long a pass aims to take: long enough that the pause between
/// passes (threads joined, waves cut) costs little, short enough that
/// commands are answered quickly.
const PASS_SECONDS: f64 = 0.5;

/// Most often the film is read back for viewers.
const SNAPSHOT_SECONDS: f64 = 0.25;

/// Reading the film back stalls the passes (on a GPU, one film per
/// wavefront comes over PCIe and is summed): snapshots are spaced so that
/// they take at most this share of the time.
const SNAPSHOT_SHARE: f64 = 0.03;

/// What viewers ask the render loop for.
pub enum Command {
    /// Move the camera (accumulation starts again).
    Move(Move),
    /// Put the camera back where the scene has it.
    Reset,
    /// Write the film as it is now to the output path, with the extension
    /// given (`exr` or `png`); the path written, or why not.
    Save { extension: &'static str, reply: std::sync::mpsc::Sender<Result<PathBuf, String>> },
}

/// One device's line in the viewers' table.
#[derive(Clone, Debug, Default)]
pub struct DeviceRow {
    pub name: String,
    /// Busy seconds since the accumulation started.
    pub busy_seconds: f64,
    pub scene_bytes: u64,
    pub frame_bytes: u64,
}

/// What viewers see: the film's mean radiance and the figures beside it.
#[derive(Clone, Debug, Default)]
pub struct Snapshot {
    /// Counts camera moves: viewers tell a restarted accumulation by it.
    pub epoch: u64,
    pub samples: u32,
    pub target_samples: u32,
    pub resolution: UVec2,
    pub pixels: Arc<Vec<Vec3>>,
    /// Camera samples per second since this accumulation started, by the
    /// wall clock (snapshots and all) until its last pass.
    pub samples_per_second: f64,
    pub devices: Vec<DeviceRow>,
    /// The camera these samples are from.
    pub camera: Camera,
    /// A device failed: the loop has stopped.
    pub error: Option<String>,
}

/// The loop's settings.
pub struct Progressive {
    /// Stop adding samples here (the frame's spp); moves start again.
    pub target_samples: u32,
    /// Where saves go (its extension replaced by the one asked for).
    pub output: PathBuf,
    pub orbit: Orbit,
}

/// Runs passes until every sender of `commands` is gone, publishing
/// snapshots to `viewers`.
pub fn run(
    mut session: Session<'_>,
    settings: Progressive,
    commands: Receiver<Command>,
    viewers: watch::Sender<Arc<Snapshot>>,
) {
    let Progressive { target_samples, output, orbit: home } = settings;
    let resolution = session.options().resolution;
    let prepared: Vec<(u64, u64)> =
        session.prepared().iter().map(|p| (p.scene_bytes, p.frame_bytes)).collect();
    let names: Vec<String> = session.devices().iter().map(|d| d.name()).collect();
    let mut orbit = home.clone();
    let mut epoch = 0u64;
    let mut per_pass = 1u32;
    let mut started = Instant::now();
    let mut last_pass_end = started;
    let mut last_snapshot: Option<Instant> = None;
    let mut snapshot_seconds = 0f64;
    let mut error: Option<String> = None;
    loop {
        // Waiting for commands only once there is nothing to render; then
        // every command that came (a drag sends many moves), in order.
        let idle = session.samples() >= target_samples || error.is_some();
        let first = match idle {
            true => match commands.recv_timeout(Duration::from_millis(100)) {
                Ok(c) => Some(c),
                Err(RecvTimeoutError::Timeout) => None,
                Err(RecvTimeoutError::Disconnected) => return,
            },
            false => None,
        };
        let mut pending: Vec<Command> = first.into_iter().collect();
        loop {
            match commands.try_recv() {
                Ok(command) => pending.push(command),
                Err(TryRecvError::Empty) => break,
                // The viewers' side is gone (the server stopped).
                Err(TryRecvError::Disconnected) => return,
            }
        }
        let mut moved = None;
        for command in pending {
            match command {
                Command::Move(step) => moved = Some(moved.as_ref().unwrap_or(&orbit).moved(step)),
                Command::Reset => moved = Some(home.clone()),
                Command::Save { extension, reply } => {
                    let _ = reply.send(save(&mut session, &output, extension));
                }
            }
        }
        if let (Some(next), None) = (moved, &error) {
            orbit = next;
            let rays = CameraRays::new(&orbit.camera(), resolution);
            if let Err(e) = session.restart(Some(&rays)) {
                error = Some(e.to_string());
            }
            epoch += 1;
            per_pass = 1;
            started = Instant::now();
            last_snapshot = None;
        }
        if session.samples() < target_samples && error.is_none() {
            let count = per_pass.min(target_samples - session.samples());
            match session.render_samples(count) {
                Ok(seconds) => {
                    last_pass_end = Instant::now();
                    // Aim the next pass at PASS_SECONDS, at most doubling.
                    let fit = (count as f64 * PASS_SECONDS / seconds.max(1e-6)).floor() as u32;
                    per_pass = fit.clamp(1, count.saturating_mul(2).max(1));
                }
                Err(e) => error = Some(e.to_string()),
            }
        }
        let interval = SNAPSHOT_SECONDS.max(snapshot_seconds / SNAPSHOT_SHARE);
        let due = last_snapshot.is_none_or(|t| t.elapsed().as_secs_f64() >= interval);
        let finished = session.samples() >= target_samples;
        // Nothing new since the last snapshot: no read-back.
        let shown = viewers.borrow();
        let new = (shown.epoch, shown.samples, shown.error.is_some())
            != (epoch, session.samples(), error.is_some());
        drop(shown);
        if new && (due || finished || error.is_some()) {
            let reading = Instant::now();
            let pixels = match session.film() {
                Ok(film) => film.pixels(),
                Err(e) => {
                    error.get_or_insert(e.to_string());
                    Vec::new()
                }
            };
            let samples = session.samples();
            let busy: Vec<f64> = match session.stats() {
                Ok(stats) => stats.iter().map(|s| s.busy_seconds).collect(),
                Err(e) => {
                    error.get_or_insert(e.to_string());
                    vec![0.0; names.len()]
                }
            };
            let devices = names
                .iter()
                .zip(&busy)
                .zip(&prepared)
                .map(|((name, &busy_seconds), &(scene_bytes, frame_bytes))| DeviceRow {
                    name: name.clone(),
                    busy_seconds,
                    scene_bytes,
                    frame_bytes,
                })
                .collect();
            let pixel_count = resolution.x as f64 * resolution.y as f64;
            let snapshot = Snapshot {
                epoch,
                samples,
                target_samples,
                resolution,
                pixels: Arc::new(pixels),
                samples_per_second: pixel_count * samples as f64
                    / (last_pass_end - started).as_secs_f64().max(1e-9),
                devices,
                camera: orbit.camera(),
                error: error.clone(),
            };
            viewers.send_replace(Arc::new(snapshot));
            snapshot_seconds = reading.elapsed().as_secs_f64();
            tracing::debug!("film read for viewers in {:.1} ms", snapshot_seconds * 1e3);
            last_snapshot = Some(Instant::now());
        }
    }
}

/// Writes the film now: `output` with `extension`.
fn save(session: &mut Session<'_>, output: &std::path::Path, extension: &str) -> Result<PathBuf, String> {
    let path = output.with_extension(extension);
    let film = session.film().map_err(|e| e.to_string())?;
    film.write(&path).map_err(|e| e.to_string())?;
    Ok(path)
}
