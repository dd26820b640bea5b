//! `atoll serve`: the scene loaded once and rendered progressively on the
//! devices and strategy `atoll render` would use, watched from a browser
//! (a headless GPU server, through an SSH tunnel). The render loop runs on
//! a thread of its own ([`progressive`]); the viewers' server on a small
//! tokio runtime ([`http`]). Only 127.0.0.1 unless `--bind` says
//! otherwise, and then only with a token.

mod display;
mod http;
mod ownership;
mod progressive;
mod view;

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::sync::{mpsc, Arc, Mutex};

use atoll_dist::{Layout, Session};
use atoll_scene::Scene;
use clap::Args;
use tokio::sync::watch;

use crate::multi::{self, DeviceList};
use crate::render::{
    gpu_wavefronts, load_frame, multi_args, open_device, set_waves_for_devices, Frame, RenderArgs,
};
use crate::CliError;
use progressive::{Progressive, Snapshot};
use view::Orbit;

#[derive(Args)]
pub struct ServeArgs {
    #[command(flatten)]
    pub render: RenderArgs,
    /// Port to listen on (0: any free one; the address is printed).
    #[arg(long, default_value_t = 8080)]
    pub port: u16,
    /// Address to listen on. The default, 127.0.0.1, is this machine only
    /// (reach it with `ssh -L 8080:localhost:8080 HOST`); any other needs
    /// --token.
    #[arg(long, default_value_t = IpAddr::V4(Ipv4Addr::LOCALHOST))]
    pub bind: IpAddr,
    /// A secret every request must carry (`?token=…`); `auto` makes a
    /// random one. Printed with the address.
    #[arg(long)]
    pub token: Option<String>,
}

pub fn run(args: ServeArgs) -> Result<(), CliError> {
    if args.render.mpi {
        return Err(CliError::Input("--mpi: atoll serve renders with this process's devices".into()));
    }
    let token = access_token(args.bind, args.token.as_deref())?;
    // Listening first: a port in use is said before the scene is loaded.
    let address = SocketAddr::new(args.bind, args.port);
    let listener = std::net::TcpListener::bind(address)
        .and_then(|l| l.set_nonblocking(true).map(|()| l))
        .map_err(|e| CliError::Runtime(format!("listening on {address}: {e}")))?;
    let address = listener.local_addr().map_err(|e| CliError::Runtime(e.to_string()))?;

    let Frame { scene, mut options, output, .. } = load_frame(&args.render, None)?;
    let (multi::Placed { mut devices, layout, partition }, description) =
        open_for_serving(&args.render, &scene, &mut options)?;
    let target_samples = options.spp;
    let orbit = Orbit::new(&scene.settings.camera, options.resolution, scene.world_bounds());
    let frame = atoll_render::FrameContext::new(&scene, options.clone());
    let ownership = ownership::Ownership::new(scene.clone(), frame, partition);
    let session = Session::prepare(&mut devices, &scene, options, &layout, args.render.ring_transport)
        .map_err(|e| CliError::Runtime(format!("preparing the devices: {e}")))?;

    let (commands, from_viewers) = mpsc::channel();
    let (to_viewers, snapshots) = watch::channel(Arc::new(Snapshot::default()));
    let shared = http::Shared {
        snapshots,
        commands: Arc::new(Mutex::new(commands)),
        token: token.as_deref().map(Arc::from),
        strategy: Arc::from(description.as_str()),
        ownership: Arc::new(ownership),
        scene: Arc::from(
            args.render.scene.as_ref().map_or("Cornell box".into(), |p| p.display().to_string()),
        ),
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| CliError::Runtime(format!("starting the server: {e}")))?;
    std::thread::scope(|scope| {
        let settings = Progressive { target_samples, output, orbit };
        scope.spawn(move || progressive::run(session, settings, from_viewers, to_viewers));
        // Until interrupted; then the viewers' side goes, and with it the
        // commands' sender, which ends the render loop.
        runtime.block_on(async move {
            // Caught from now on (before the address is printed, so that
            // whoever reads it may interrupt at once): Ctrl-C or a stop.
            let signal = |kind| {
                tokio::signal::unix::signal(kind)
                    .map_err(|e| CliError::Runtime(format!("catching signals: {e}")))
            };
            let mut interrupt = signal(tokio::signal::unix::SignalKind::interrupt())?;
            let mut terminate = signal(tokio::signal::unix::SignalKind::terminate())?;
            let listener = tokio::net::TcpListener::from_std(listener)
                .map_err(|e| CliError::Runtime(format!("listening on {address}: {e}")))?;
            print_address(address, token.as_deref());
            axum::serve(listener, http::router(shared))
                .with_graceful_shutdown(async move {
                    tokio::select! {
                        _ = interrupt.recv() => {}
                        _ = terminate.recv() => {}
                    }
                })
                .await
                .map_err(|e| CliError::Runtime(format!("serving: {e}")))
        })
    })
}

/// Where viewers go (and how, from another machine).
fn print_address(address: SocketAddr, token: Option<&str>) {
    let query = token.map_or(String::new(), |t| format!("?token={t}"));
    eprintln!("serving http://{address}/{query}");
    if address.ip().is_loopback() {
        let port = address.port();
        eprintln!("  from elsewhere: ssh -L {port}:localhost:{port} THIS-HOST, then http://localhost:{port}/{query}");
    }
}

/// The token requests must carry: `--token`, a random one for `auto`;
/// none on a loopback address without `--token`. Listening beyond this
/// machine without one is refused.
fn access_token(bind: IpAddr, token: Option<&str>) -> Result<Option<String>, CliError> {
    let token = match token {
        Some("auto") => Some(random_token()?),
        Some(t) if t.len() < 8 || !t.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_') => {
            return Err(CliError::Input(
                "--token: at least 8 letters, digits, '-' or '_' (or auto for a random one)".into(),
            ))
        }
        Some(t) => Some(t.to_owned()),
        None => None,
    };
    if !bind.is_loopback() && token.is_none() {
        return Err(CliError::Input(format!(
            "--bind {bind}: listening beyond this machine needs --token (a secret, or auto for a random one)"
        )));
    }
    Ok(token)
}

/// 128 random bits, as hex.
fn random_token() -> Result<String, CliError> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes).map_err(|e| CliError::Runtime(format!("making a token: {e}")))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// The devices `args` name, placed as `atoll render` would place them,
/// and a line saying how.
fn open_for_serving(
    args: &RenderArgs,
    scene: &Arc<Scene>,
    options: &mut atoll_render::RenderOptions,
) -> Result<(multi::Placed, String), CliError> {
    if let Some(DeviceList(specs)) = &args.devices {
        set_waves_for_devices(args, specs, options);
        let devices = multi::open_devices(specs, args.device.device_memory, args.threads)?;
        let placed = multi::place_on(devices, scene, options, &multi_args(args, specs))?;
        let line = layout_line(&placed.layout, placed.devices.len());
        return Ok((placed, line));
    }
    let selected = open_device(args, scene, options)?;
    let more = gpu_wavefronts(selected.device.as_ref(), args, scene, options)?;
    let line = format!("{}, {} wavefront(s)", selected.description, more.len() + 1);
    let mut devices = vec![selected.device];
    devices.extend(more);
    Ok((multi::Placed { devices, layout: Layout::Replicate, partition: None }, line))
}

fn layout_line(layout: &Layout, devices: usize) -> String {
    match layout {
        Layout::Replicate => format!("replicate on {devices} devices"),
        Layout::Ring { parts, islands, .. } => {
            format!("ring of {} ({}) on {devices} devices", parts.len(), multi::islands_text(*islands))
        }
        Layout::Shared(_) => format!("shared scene memory on {devices} devices"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_guard_every_address_but_loopback() {
        let any = IpAddr::V4(Ipv4Addr::UNSPECIFIED);
        let loopback = IpAddr::V4(Ipv4Addr::LOCALHOST);
        assert!(matches!(access_token(any, None), Err(CliError::Input(m)) if m.contains("needs --token")));
        assert_eq!(access_token(loopback, None).unwrap(), None);
        assert_eq!(access_token(any, Some("secret-42")).unwrap().as_deref(), Some("secret-42"));
        let made = access_token(any, Some("auto")).unwrap().unwrap();
        assert_eq!(made.len(), 32);
        assert_ne!(made, access_token(any, Some("auto")).unwrap().unwrap());
        assert!(access_token(loopback, Some("short")).is_err());
        assert!(access_token(loopback, Some("has space in it")).is_err());
    }
}
