//! Watches a running `atoll serve` as a viewer would, for measurements
//! (`scripts/serve-bench`): the samples per second the viewer sees (wall
//! clock, from its first frame to the last sample), bytes per frame, and
//! how long a camera move takes to show.
//!
//!   serve_watch ADDRESS [MOVES]
//!
//! prints `viewer: …` lines: the rate until the frame's samples are all
//! in, then for each of MOVES (default 3) moves the seconds until the first
//! frame of the moved camera, and its bytes.

use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use serde_json::Value;
use tokio_tungstenite::tungstenite::Message;

type Socket = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// The next frame's figures (the image that follows is counted, not kept).
async fn next_figures(socket: &mut Socket) -> Result<Value, String> {
    loop {
        let message = tokio::time::timeout(Duration::from_secs(600), socket.next())
            .await
            .map_err(|_| "no frame for 10 minutes".to_string())?
            .ok_or("the server closed the socket")?
            .map_err(|e| e.to_string())?;
        if let Message::Text(text) = message {
            let value: Value = serde_json::from_str(&text).map_err(|e| e.to_string())?;
            if value["type"] == "frame" {
                return Ok(value);
            }
        }
    }
}

async fn watch(address: &str, moves: usize) -> Result<(), String> {
    let url = format!("ws://{address}/ws");
    let (mut socket, _) = tokio_tungstenite::connect_async(&url).await.map_err(|e| format!("{url}: {e}"))?;
    let first = next_figures(&mut socket).await?;
    let (start, first_samples) = (Instant::now(), first["samples"].as_u64().unwrap_or(0));
    let pixels = first["width"].as_f64().unwrap_or(0.0) * first["height"].as_f64().unwrap_or(0.0);
    let target = first["target_samples"].as_u64().unwrap_or(0);
    let (mut frames, mut bytes) = (0u64, 0u64);
    let mut last = first;
    while last["samples"].as_u64() != Some(target) {
        last = next_figures(&mut socket).await?;
        frames += 1;
        bytes += last["frame_bytes"].as_u64().unwrap_or(0);
    }
    let seconds = start.elapsed().as_secs_f64();
    let samples = (target - first_samples) as f64 * pixels;
    println!(
        "viewer: {:.2} M samples/s over {seconds:.2} s ({} to {target} spp); server's own figure {:.2} M samples/s",
        samples / seconds / 1e6,
        first_samples,
        last["samples_per_second"].as_f64().unwrap_or(0.0) / 1e6
    );
    println!("viewer: {frames} frames, {:.0} KiB a frame", bytes as f64 / frames.max(1) as f64 / 1024.0);
    for i in 0..moves {
        let asked = Instant::now();
        let step = if i % 2 == 0 { r#"{"type":"move","yaw":0.2}"# } else { r#"{"type":"move","yaw":-0.2}"# };
        socket.send(Message::Text(step.into())).await.map_err(|e| e.to_string())?;
        let epoch = last["epoch"].as_u64().unwrap_or(0) + 1;
        loop {
            last = next_figures(&mut socket).await?;
            if last["epoch"].as_u64() == Some(epoch) {
                break;
            }
        }
        println!(
            "viewer: move {}: first frame after {:.3} s ({} spp, {:.0} KiB)",
            i + 1,
            asked.elapsed().as_secs_f64(),
            last["samples"],
            last["frame_bytes"].as_f64().unwrap_or(0.0) / 1024.0
        );
    }
    Ok(())
}

fn main() {
    let mut args = std::env::args().skip(1);
    let Some(address) = args.next() else {
        eprintln!("usage: serve_watch ADDRESS [MOVES]");
        std::process::exit(2);
    };
    let moves = args.next().and_then(|m| m.parse().ok()).unwrap_or(3);
    let runtime = tokio::runtime::Runtime::new().expect("a runtime");
    if let Err(e) = runtime.block_on(watch(&address, moves)) {
        eprintln!("serve_watch: {e}");
        std::process::exit(1);
    }
}
