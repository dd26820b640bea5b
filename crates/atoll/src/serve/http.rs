//! The viewers' side of `atoll serve`: one page (shipped inside the
//! binary), a WebSocket per viewer carrying frames (JPEG) and figures
//! (JSON) one way and camera moves and display settings the other, and a
//! save request. With a token, every request and WebSocket must carry it
//! (`?token=` or `Authorization: Bearer`); nothing else of the machine is
//! served.

use std::collections::HashMap;
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Query, Request, State};
use axum::http::{header, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use futures_util::{SinkExt, StreamExt};
use serde_json::{json, Value};
use tokio::sync::watch;

use super::display::{Display, ToneCurve};
use super::ownership::Ownership;
use super::progressive::{Command, Snapshot};
use super::view::Move;

/// The page: HTML, style and script in one file, no network needed.
const PAGE: &str = include_str!("page.html");

/// Most frames a viewer gets a second: the film is read back at most this
/// often anyway, and encoding takes a core.
const MOST_FRAMES_PER_SECOND: f64 = 4.0;

/// What every handler shares.
#[derive(Clone)]
pub struct Shared {
    pub snapshots: watch::Receiver<Arc<Snapshot>>,
    /// To the render loop (a std channel: the loop is a plain thread).
    pub commands: Arc<Mutex<Sender<Command>>>,
    pub token: Option<Arc<str>>,
    /// One line about the devices and strategy, for the page.
    pub strategy: Arc<str>,
    /// The false-colour view of who holds what.
    pub ownership: Arc<Ownership>,
    pub scene: Arc<str>,
}

/// The routes, behind the token check.
pub fn router(shared: Shared) -> Router {
    Router::new()
        .route("/", get(page))
        .route("/ws", get(viewer))
        .route("/save", post(save))
        .layer(middleware::from_fn_with_state(shared.clone(), check_token))
        .with_state(shared)
}

/// Refuses requests without the token (when there is one).
async fn check_token(State(shared): State<Shared>, request: Request, next: Next) -> Response {
    let Some(token) = &shared.token else { return next.run(request).await };
    let from_query = request
        .uri()
        .query()
        .and_then(|q| q.split('&').find_map(|kv| kv.strip_prefix("token=")))
        .map(str::to_owned);
    let from_header = request
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer "))
        .map(str::to_owned);
    let given = from_query.or(from_header);
    match given.is_some_and(|g| same_secret(g.as_bytes(), token.as_bytes())) {
        true => next.run(request).await,
        false => (StatusCode::UNAUTHORIZED, "a token is needed: open the address atoll serve printed\n")
            .into_response(),
    }
}

/// Compares without stopping at the first difference, so that timing
/// tells nothing of how much of a guess was right.
fn same_secret(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

async fn page() -> Html<&'static str> {
    Html(PAGE)
}

/// Writes the film as it is now, beside the output the command line
/// named (`?format=exr|png`, default exr); answers with the path.
async fn save(State(shared): State<Shared>, Query(query): Query<HashMap<String, String>>) -> Response {
    let extension = match query.get("format").map_or("exr", String::as_str) {
        "exr" => "exr",
        "png" => "png",
        other => {
            let message = format!("format {other:?}: use exr or png");
            return (StatusCode::BAD_REQUEST, Json(json!({ "error": message }))).into_response();
        }
    };
    let (reply, answer) = std::sync::mpsc::channel();
    let sent =
        shared.commands.lock().unwrap_or_else(|p| p.into_inner()).send(Command::Save { extension, reply });
    if sent.is_err() {
        return (StatusCode::SERVICE_UNAVAILABLE, Json(json!({ "error": "the renderer stopped" })))
            .into_response();
    }
    let saved = tokio::task::spawn_blocking(move || answer.recv_timeout(Duration::from_secs(600))).await;
    match saved {
        Ok(Ok(Ok(path))) => Json(json!({ "path": path.display().to_string() })).into_response(),
        Ok(Ok(Err(e))) => (StatusCode::INTERNAL_SERVER_ERROR, Json(json!({ "error": e }))).into_response(),
        _ => (StatusCode::SERVICE_UNAVAILABLE, Json(json!({ "error": "the renderer did not answer" })))
            .into_response(),
    }
}

async fn viewer(State(shared): State<Shared>, upgrade: WebSocketUpgrade) -> Response {
    upgrade.on_upgrade(move |socket| watch_render(socket, shared))
}

/// One viewer: a frame and its figures whenever the render has moved on
/// (at most [`MOST_FRAMES_PER_SECOND`]), or the viewer's display settings
/// changed; its moves go to the render loop. A viewer that goes away
/// leaves the render as it is.
async fn watch_render(socket: WebSocket, shared: Shared) {
    let (mut sink, mut incoming) = socket.split();
    let mut snapshots = shared.snapshots.clone();
    let mut view = View::default();
    let mut redraw = true;
    let mut last_frame: Option<Instant> = None;
    let mut shown_epoch = None;
    let intro = json!({ "type": "hello", "strategy": &*shared.strategy, "scene": &*shared.scene });
    if sink.send(Message::Text(intro.to_string().into())).await.is_err() {
        return;
    }
    loop {
        if redraw {
            // A moved camera's first frame goes at once; others wait their turn.
            let moved = shown_epoch != Some(snapshots.borrow().epoch);
            let pace = Duration::from_secs_f64(1.0 / MOST_FRAMES_PER_SECOND);
            if let Some(wait) = last_frame.and_then(|t| pace.checked_sub(t.elapsed())).filter(|_| !moved) {
                tokio::time::sleep(wait).await;
            }
            let snapshot = snapshots.borrow_and_update().clone();
            shown_epoch = Some(snapshot.epoch);
            // Nothing to show before the first pass (or its failure).
            if snapshot.target_samples == 0 && snapshot.error.is_none() {
                redraw = false;
                continue;
            }
            // The ownership view is drawn once per camera.
            let image = match view.ownership {
                false => Image::Render(view.display),
                true if view.ownership_epoch == Some(snapshot.epoch) => Image::None,
                true => Image::Ownership(shared.ownership.clone()),
            };
            if view.ownership {
                view.ownership_epoch = Some(snapshot.epoch);
            }
            let encoded = tokio::task::spawn_blocking(move || {
                let start = Instant::now();
                let frame = frame_of(&snapshot, image);
                let bytes = frame.1.as_ref().map_or(0, Vec::len);
                tracing::debug!(
                    "frame of {bytes} bytes encoded in {:.1} ms",
                    start.elapsed().as_secs_f64() * 1e3
                );
                frame
            })
            .await;
            let Ok((figures, jpeg)) = encoded else { return };
            if sink.send(Message::Text(figures.to_string().into())).await.is_err() {
                return;
            }
            if let Some(jpeg) = jpeg {
                if sink.send(Message::Binary(jpeg.into())).await.is_err() {
                    return;
                }
            }
            last_frame = Some(Instant::now());
            redraw = false;
        }
        tokio::select! {
            changed = snapshots.changed() => {
                if changed.is_err() {
                    return;
                }
                redraw = true;
            }
            message = incoming.next() => {
                let Some(Ok(message)) = message else { return };
                if let Message::Text(text) = message {
                    redraw |= act_on(&text, &mut view, &shared);
                }
            }
        }
    }
}

/// What one viewer asked to see.
#[derive(Clone, Copy, Debug, Default)]
struct View {
    display: Display,
    /// The false-colour ownership view instead of the render.
    ownership: bool,
    /// The camera (epoch) of the ownership view last sent.
    ownership_epoch: Option<u64>,
}

/// The image a frame carries.
enum Image {
    /// The render, as the viewer's display settings show it.
    Render(Display),
    /// The ownership view from the snapshot's camera.
    Ownership(Arc<Ownership>),
    /// Figures only (the image sent last still stands).
    None,
}

/// The figures of `snapshot` and its image (none before the first samples).
fn frame_of(snapshot: &Snapshot, image: Image) -> (Value, Option<Vec<u8>>) {
    let view = if matches!(image, Image::Render(_)) { "render" } else { "ownership" };
    let jpeg = match image {
        _ if snapshot.pixels.is_empty() => None,
        Image::Render(display) => display.jpeg(&snapshot.pixels, snapshot.resolution).ok(),
        Image::Ownership(ownership) => {
            Display::default().jpeg(&ownership.view(&snapshot.camera), snapshot.resolution).ok()
        }
        Image::None => None,
    };
    let devices: Vec<Value> = snapshot
        .devices
        .iter()
        .map(|d| {
            json!({
                "name": d.name,
                "busy_seconds": d.busy_seconds,
                "scene_bytes": d.scene_bytes,
                "frame_bytes": d.frame_bytes,
            })
        })
        .collect();
    let figures = json!({
        "type": "frame",
        "view": view,
        "epoch": snapshot.epoch,
        "samples": snapshot.samples,
        "target_samples": snapshot.target_samples,
        "width": snapshot.resolution.x,
        "height": snapshot.resolution.y,
        "samples_per_second": snapshot.samples_per_second,
        "devices": devices,
        "error": snapshot.error,
        "frame_bytes": jpeg.as_ref().map_or(0, |j| j.len()),
    });
    (figures, jpeg)
}

/// Applies a viewer's message; whether its own frame must be drawn again
/// (display settings changed). Unknown or malformed messages are ignored:
/// a viewer cannot stop the render.
fn act_on(text: &str, view: &mut View, shared: &Shared) -> bool {
    let Ok(message) = serde_json::from_str::<Value>(text) else { return false };
    let number =
        |key: &str| message.get(key).and_then(Value::as_f64).filter(|v| v.is_finite()).unwrap_or(0.0) as f32;
    let command = match message.get("type").and_then(Value::as_str) {
        Some("display") => {
            view.display.exposure_ev = number("exposure").clamp(-20.0, 20.0);
            view.display.curve =
                message.get("curve").and_then(Value::as_str).and_then(ToneCurve::parse).unwrap_or_default();
            return true;
        }
        Some("ownership") => {
            view.ownership = message.get("on").and_then(Value::as_bool).unwrap_or(false);
            view.ownership_epoch = None;
            return true;
        }
        Some("move") => Command::Move(Move {
            yaw: number("yaw").clamp(-10.0, 10.0),
            pitch: number("pitch").clamp(-10.0, 10.0),
            pan_x: number("pan_x").clamp(-10.0, 10.0),
            pan_y: number("pan_y").clamp(-10.0, 10.0),
            dolly: number("dolly").clamp(-10.0, 10.0),
        }),
        Some("reset") => Command::Reset,
        _ => return false,
    };
    let _ = shared.commands.lock().unwrap_or_else(|p| p.into_inner()).send(command);
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn secrets_compare_whole() {
        assert!(same_secret(b"abc", b"abc"));
        assert!(!same_secret(b"abc", b"abd"));
        assert!(!same_secret(b"abc", b"abcd"));
        assert!(!same_secret(b"", b"a"));
    }
}
