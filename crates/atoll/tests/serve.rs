//! `atoll serve` against its own HTTP and WebSocket clients: a viewer
//! watches the render converge to the image `atoll render` writes, a
//! camera move starts the accumulation again, viewers come and go without
//! touching the render, and tokens and addresses are checked. One test
//! loads the page in headless Chromium (ignored unless asked for:
//! `scripts/test.sh` installs Debian's chromium and runs it).

mod common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use futures_util::{SinkExt, StreamExt};
use serde_json::Value;
use tokio_tungstenite::tungstenite::Message;

const FRAME: [&str; 8] = ["--device", "cpu", "--threads", "2", "--res", "48x32", "--spp", "12"];

/// A running `atoll serve`, stopped when dropped.
struct Server {
    child: Child,
    /// `127.0.0.1:PORT`
    address: String,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Starts `atoll serve ARGS --port 0` in `dir` and waits for its address.
fn serve(dir: &Path, args: &[&str]) -> Server {
    let mut child = Command::new(env!("CARGO_BIN_EXE_atoll"))
        .arg("serve")
        .args(args)
        .args(["--port", "0"])
        .current_dir(dir)
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .expect("atoll runs");
    let said = first_line_with(&mut child, "serving http://", Duration::from_secs(120));
    match said.as_deref().and_then(|l| l.strip_prefix("serving http://")) {
        Some(rest) => Server { address: rest.split('/').next().unwrap().to_owned(), child },
        None => panic!("atoll serve printed no address: {:?}", child.wait_with_output()),
    }
}

/// The first line of `child`'s stderr containing `text`, within `patience`
/// (the rest of its stderr is read and dropped, so that it never blocks).
fn first_line_with(child: &mut Child, text: &str, patience: Duration) -> Option<String> {
    let stderr = child.stderr.take()?;
    let (lines, heard) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = lines.send(line);
        }
    });
    let deadline = Instant::now() + patience;
    while let Ok(line) = heard.recv_timeout(deadline.saturating_duration_since(Instant::now())) {
        if line.contains(text) {
            return Some(line);
        }
    }
    None
}

/// One HTTP/1.1 request: the status and body.
fn http(address: &str, method: &str, target: &str, headers: &[&str]) -> (u16, String) {
    let mut stream = TcpStream::connect(address).unwrap();
    let extra: String = headers.iter().map(|h| format!("{h}\r\n")).collect();
    let request = format!("{method} {target} HTTP/1.1\r\nHost: {address}\r\nContent-Length: 0\r\n{extra}Connection: close\r\n\r\n");
    stream.write_all(request.as_bytes()).unwrap();
    let mut response = String::new();
    stream.read_to_string(&mut response).unwrap();
    let status = response.split(' ').nth(1).and_then(|s| s.parse().ok()).unwrap_or(0);
    let body = response.split_once("\r\n\r\n").map_or("", |(_, b)| b).to_owned();
    (status, body)
}

type Socket = tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

async fn connect(address: &str, query: &str) -> Result<Socket, tokio_tungstenite::tungstenite::Error> {
    tokio_tungstenite::connect_async(format!("ws://{address}/ws{query}")).await.map(|(socket, _)| socket)
}

/// The next frame's figures and image, skipping other messages.
async fn next_frame(socket: &mut Socket) -> (Value, Vec<u8>) {
    let mut figures: Option<Value> = None;
    loop {
        let message = tokio::time::timeout(Duration::from_secs(60), socket.next())
            .await
            .expect("a frame within a minute")
            .expect("the socket stays open")
            .unwrap();
        match message {
            Message::Text(text) => {
                let value: Value = serde_json::from_str(&text).unwrap();
                if value["type"] == "frame" {
                    figures = Some(value);
                }
            }
            Message::Binary(jpeg) => {
                if let Some(figures) = figures.take() {
                    return (figures, jpeg.to_vec());
                }
            }
            _ => {}
        }
    }
}

/// Frames until one satisfies `done`; every frame seen.
async fn frames_until(socket: &mut Socket, done: impl Fn(&Value) -> bool) -> Vec<(Value, Vec<u8>)> {
    let mut seen = Vec::new();
    loop {
        let frame = next_frame(socket).await;
        let finished = done(&frame.0);
        seen.push(frame);
        if finished {
            return seen;
        }
    }
}

fn mean_of_jpeg(bytes: &[u8]) -> f64 {
    let image = image::load_from_memory(bytes).unwrap().to_rgb8();
    image.as_raw().iter().map(|&b| b as f64).sum::<f64>() / image.as_raw().len() as f64
}

#[test]
fn a_viewer_watches_the_render_reach_the_rendered_image_and_moves_the_camera() {
    let dir = common::scratch("serve", "viewer");
    let rendered = common::atoll(&dir, &[&["render", "-q", "-o", "rendered.exr"], &FRAME[..]].concat());
    assert!(rendered.status.success(), "{}", String::from_utf8_lossy(&rendered.stderr));
    let server = serve(&dir, &[&["-o", "served.exr"], &FRAME[..]].concat());

    // The page is served, standing alone (no other addresses to fetch).
    let (status, page) = http(&server.address, "GET", "/", &[]);
    assert_eq!(status, 200);
    assert!(page.contains("<canvas") && page.contains("new WebSocket"), "{page}");
    assert!(!page.contains("http://") && !page.contains("https://"), "the page needs no network");

    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async {
        let mut viewer = connect(&server.address, "").await.unwrap();
        let frames = frames_until(&mut viewer, |f| f["samples"] == 12).await;
        let (last, jpeg) = frames.last().unwrap();
        assert_eq!((last["width"].as_u64(), last["height"].as_u64()), (Some(48), Some(32)));
        assert_eq!(last["epoch"], 0);
        assert!(last["samples_per_second"].as_f64().unwrap() > 0.0, "{last}");
        assert_eq!(last["devices"][0]["name"], "cpu");
        assert_eq!(last["frame_bytes"].as_u64(), Some(jpeg.len() as u64));
        let dark = mean_of_jpeg(jpeg);
        // Another viewer at the same time sees the same render.
        let mut second = connect(&server.address, "").await.unwrap();
        let (figures, _) = next_frame(&mut second).await;
        assert_eq!(
            (figures["epoch"].as_u64(), figures["samples"].as_u64()),
            (Some(0), Some(12)),
            "{figures}"
        );

        // Saved now, the film is the image `atoll render` writes.
        let (status, body) = http(&server.address, "POST", "/save?format=exr", &[]);
        assert_eq!(status, 200, "{body}");
        let (saved, reference) =
            (common::read_exr(&dir.join("served.exr")), common::read_exr(&dir.join("rendered.exr")));
        assert_eq!(saved.len(), reference.len());
        for (a, b) in saved.iter().zip(&reference) {
            for c in 0..3 {
                assert!((a[c] - b[c]).abs() <= 1e-5 * a[c].abs().max(1.0), "{a:?} against {b:?}");
            }
        }
        let (status, body) = http(&server.address, "POST", "/save?format=gif", &[]);
        assert_eq!(status, 400, "{body}");

        // Two stops brighter, for this viewer alone.
        viewer.send(Message::Text(r#"{"type":"display","exposure":2,"curve":"clip"}"#.into())).await.unwrap();
        let (_, brighter) = next_frame(&mut viewer).await;
        assert!(mean_of_jpeg(&brighter) > dark * 1.3, "{} against {dark}", mean_of_jpeg(&brighter));
        drop(second);

        // The false-colour view: one device holds everything, one colour.
        viewer.send(Message::Text(r#"{"type":"ownership","on":true}"#.into())).await.unwrap();
        let (figures, owned) = next_frame(&mut viewer).await;
        assert_eq!(figures["view"], "ownership");
        let owned = image::load_from_memory(&owned).unwrap().to_rgb8();
        let lit: Vec<&image::Rgb<u8>> = owned.pixels().filter(|p| p[0] > 40).collect();
        assert!(lit.len() > owned.pixels().len() / 2, "the box fills the view");
        // The first owner's red (linear 0.9, 0.2, 0.15: about 1.9 times the green in sRGB).
        let reddish = lit.iter().filter(|p| p[0] as f32 > 1.5 * p[1].max(p[2]) as f32).count();
        assert!(reddish * 100 >= lit.len() * 95, "{reddish} of {} lit pixels red", lit.len());
        viewer.send(Message::Text(r#"{"type":"ownership","on":false}"#.into())).await.unwrap();
        let (figures, _) = next_frame(&mut viewer).await;
        assert_eq!(figures["view"], "render");

        // A move renders the frame again from the moved camera.
        viewer.send(Message::Text(r#"{"type":"display","exposure":0,"curve":"clip"}"#.into())).await.unwrap();
        viewer.send(Message::Text(r#"{"type":"move","yaw":0.3}"#.into())).await.unwrap();
        let frames = frames_until(&mut viewer, |f| f["epoch"] == 1 && f["samples"] == 12).await;
        assert!(mean_of_jpeg(&frames.last().unwrap().1) != dark, "the view moved");
        let (status, body) = http(&server.address, "POST", "/save?format=exr", &[]);
        assert_eq!(status, 200, "{body}");
        assert_ne!(
            common::read_exr(&dir.join("served.exr")),
            reference,
            "the saved film is the moved camera's"
        );

        // A viewer that goes away leaves the render alone; a new one sees it.
        drop(viewer);
        let mut again = connect(&server.address, "").await.unwrap();
        let (figures, _) = next_frame(&mut again).await;
        assert_eq!(
            (figures["epoch"].as_u64(), figures["samples"].as_u64()),
            (Some(1), Some(12)),
            "{figures}"
        );
        // Nonsense from a viewer is ignored.
        again.send(Message::Text("{not json".into())).await.unwrap();
        again.send(Message::Text(r#"{"type":"move","yaw":"far"}"#.into())).await.unwrap();
        let (status, _) = http(&server.address, "GET", "/", &[]);
        assert_eq!(status, 200);
    });
}

#[test]
fn a_move_starts_the_accumulation_again() {
    let dir = common::scratch("serve", "move");
    let server = serve(&dir, &["--device", "cpu", "--threads", "2", "--res", "32x24", "--spp", "1000000"]);
    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async {
        let mut viewer = connect(&server.address, "").await.unwrap();
        let frames = frames_until(&mut viewer, |f| f["samples"].as_u64().unwrap() >= 64).await;
        let before = frames.last().unwrap().0["samples"].as_u64().unwrap();
        let asked = Instant::now();
        viewer.send(Message::Text(r#"{"type":"move","pitch":0.2,"dolly":0.5}"#.into())).await.unwrap();
        let frames = frames_until(&mut viewer, |f| f["epoch"] == 1).await;
        let after = frames.last().unwrap().0["samples"].as_u64().unwrap();
        assert!(after < before, "{after} samples after the move, {before} before");
        eprintln!("first frame {:.3} s after the move", asked.elapsed().as_secs_f64());
        // Back to the scene's camera: a third accumulation.
        viewer.send(Message::Text(r#"{"type":"reset"}"#.into())).await.unwrap();
        frames_until(&mut viewer, |f| f["epoch"] == 2).await;
    });
}

#[test]
fn a_ring_shows_its_parts_in_their_colours() {
    let dir = common::scratch("serve", "ring");
    let args = ["--devices", "cpu:2", "--strategy", "ring", "--threads", "1", "--res", "48x32", "--spp", "4"];
    let server = serve(&dir, &args);
    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async {
        let mut viewer = connect(&server.address, "").await.unwrap();
        let hello = viewer.next().await.unwrap().unwrap();
        assert!(hello.to_text().unwrap().contains("ring of 2"), "{hello}");
        viewer.send(Message::Text(r#"{"type":"ownership","on":true}"#.into())).await.unwrap();
        let frames = frames_until(&mut viewer, |f| f["view"] == "ownership").await;
        let owned = image::load_from_memory(&frames.last().unwrap().1).unwrap().to_rgb8();
        // The first part's red and the second's blue (linear 0.15, 0.45, 0.9).
        let red = owned.pixels().filter(|p| p[0] as f32 > 1.5 * p[1].max(p[2]) as f32).count();
        let blue = owned.pixels().filter(|p| p[2] as f32 > 1.3 * p[0].max(p[1]) as f32).count();
        let all = owned.pixels().len();
        assert!(red * 20 > all && blue * 20 > all, "{red} red and {blue} blue of {all} pixels");
    });
}

#[test]
fn an_interrupt_stops_the_server_and_its_render() {
    let dir = common::scratch("serve", "interrupt");
    let mut server =
        serve(&dir, &["--device", "cpu", "--threads", "1", "--res", "32x24", "--spp", "1000000"]);
    // SAFETY: a signal to the child this test started (still running: not waited for).
    assert_eq!(unsafe { libc::kill(server.child.id() as i32, libc::SIGINT) }, 0);
    let asked = Instant::now();
    while server.child.try_wait().unwrap().is_none() {
        assert!(asked.elapsed() < Duration::from_secs(20), "still running 20 s after the interrupt");
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(server.child.try_wait().unwrap().unwrap().success());
}

#[test]
fn every_request_needs_the_token_when_there_is_one() {
    let dir = common::scratch("serve", "token");
    let server = serve(&dir, &[&["--token", "sesame-1234"], &FRAME[..]].concat());
    let address = &server.address;
    assert_eq!(http(address, "GET", "/", &[]).0, 401);
    assert_eq!(http(address, "GET", "/?token=sesame-123", &[]).0, 401);
    assert_eq!(http(address, "POST", "/save", &[]).0, 401);
    assert_eq!(http(address, "GET", "/?token=sesame-1234", &[]).0, 200);
    assert_eq!(http(address, "GET", "/", &["Authorization: Bearer sesame-1234"]).0, 200);
    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async {
        let refused = connect(address, "").await;
        assert!(refused.is_err(), "a WebSocket without the token is refused");
        let mut viewer = connect(address, "?token=sesame-1234").await.unwrap();
        let (figures, _) = next_frame(&mut viewer).await;
        assert_eq!(figures["type"], "frame");
    });
}

#[test]
fn listening_beyond_this_machine_needs_a_token() {
    let dir = common::scratch("serve", "bind");
    let out = common::atoll(&dir, &["serve", "--bind", "0.0.0.0", "--port", "0"]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("--bind 0.0.0.0: listening beyond this machine needs --token"), "{stderr}");
    let out = common::atoll(&dir, &["serve", "--token", "short"]);
    assert_eq!(out.status.code(), Some(2), "{}", String::from_utf8_lossy(&out.stderr));
}

/// One Chrome DevTools Protocol call on `socket` (to the page's session
/// when given); its result. Events in between are skipped.
async fn devtools(socket: &mut Socket, id: u64, method: &str, params: Value, session: Option<&str>) -> Value {
    let mut call = serde_json::json!({ "id": id, "method": method, "params": params });
    if let Some(session) = session {
        call["sessionId"] = Value::from(session);
    }
    socket.send(Message::Text(call.to_string().into())).await.unwrap();
    loop {
        let message = tokio::time::timeout(Duration::from_secs(60), socket.next())
            .await
            .expect("Chromium answers")
            .expect("Chromium stays up")
            .unwrap();
        let Message::Text(text) = message else { continue };
        let answer: Value = serde_json::from_str(&text).unwrap();
        if answer["id"] == id {
            assert!(answer.get("error").is_none(), "{method}: {answer}");
            return answer["result"].clone();
        }
    }
}

/// Headless Chromium, stopped when dropped, with the address of its
/// DevTools WebSocket.
struct Browser {
    child: Child,
    devtools: String,
    _profile: tempfile::TempDir,
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn chromium() -> Browser {
    let profile = tempfile::tempdir().unwrap();
    let mut child = Command::new("chromium")
        .args([
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--remote-debugging-port=0",
        ])
        // Only this machine: the page must need nothing from elsewhere.
        .arg("--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1")
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .arg("about:blank")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("chromium runs (Debian's chromium package)");
    let said = first_line_with(&mut child, "ws://", Duration::from_secs(60));
    match said.as_deref().and_then(|l| l.find("ws://").map(|at| l[at..].trim().to_owned())) {
        Some(devtools) => Browser { child, devtools, _profile: profile },
        None => {
            let _ = child.kill();
            let _ = child.wait();
            panic!("chromium printed no DevTools address");
        }
    }
}

fn mean_rgb(image: &image::RgbImage) -> [f64; 3] {
    let mut sum = [0f64; 3];
    for p in image.pixels() {
        for c in 0..3 {
            sum[c] += p[c] as f64;
        }
    }
    sum.map(|s| s / (image.width() * image.height()) as f64)
}

#[test]
#[ignore = "needs chromium (scripts/test.sh installs it and runs this)"]
fn the_page_in_a_browser_shows_the_rendered_image() {
    use base64::Engine;
    let dir = common::scratch("serve", "browser");
    let frame = ["--device", "cpu", "--threads", "2", "--res", "96x64", "--spp", "16"];
    let rendered = common::atoll(&dir, &[&["render", "-q", "-o", "rendered.png"], &frame[..]].concat());
    assert!(rendered.status.success(), "{}", String::from_utf8_lossy(&rendered.stderr));
    let server = serve(&dir, &frame);
    let browser = chromium();
    let runtime = tokio::runtime::Runtime::new().unwrap();
    let canvas = runtime.block_on(async {
        let (mut socket, _) = tokio_tungstenite::connect_async(&browser.devtools).await.unwrap();
        let url = format!("http://{}/", server.address);
        let target = devtools(&mut socket, 1, "Target.createTarget", serde_json::json!({ "url": url }), None).await;
        let attached = devtools(
            &mut socket,
            2,
            "Target.attachToTarget",
            serde_json::json!({ "targetId": target["targetId"], "flatten": true }),
            None,
        )
        .await;
        let session = attached["sessionId"].as_str().unwrap().to_owned();
        // Until the canvas shows the last sample (the page marks what it drew).
        let started = Instant::now();
        let mut id = 3;
        loop {
            let drawn = devtools(
                &mut socket,
                id,
                "Runtime.evaluate",
                serde_json::json!({ "expression": "document.body.dataset.drawn || ''", "returnByValue": true }),
                Some(&session),
            )
            .await;
            id += 1;
            if drawn["result"]["value"] == "16" {
                break;
            }
            assert!(started.elapsed() < Duration::from_secs(60), "the page drew no converged frame: {drawn}");
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        let url = devtools(
            &mut socket,
            id,
            "Runtime.evaluate",
            serde_json::json!({ "expression": "document.getElementById('image').toDataURL('image/png')", "returnByValue": true }),
            Some(&session),
        )
        .await;
        url["result"]["value"].as_str().unwrap().to_owned()
    });
    let png = base64::engine::general_purpose::STANDARD
        .decode(canvas.strip_prefix("data:image/png;base64,").expect("a PNG data URL"))
        .unwrap();
    let shown = image::load_from_memory(&png).unwrap().to_rgb8();
    let reference = image::open(dir.join("rendered.png")).unwrap().to_rgb8();
    assert_eq!(shown.dimensions(), reference.dimensions());
    // The page's image is a JPEG of the same film, shown as `atoll render`'s PNG maps it.
    let (a, b) = (mean_rgb(&shown), mean_rgb(&reference));
    for c in 0..3 {
        assert!((a[c] - b[c]).abs() < 2.0, "channel means {a:?} on the page, {b:?} rendered");
    }
    let squared: f64 =
        shown.as_raw().iter().zip(reference.as_raw()).map(|(&x, &y)| (x as f64 - y as f64).powi(2)).sum();
    let rmse = (squared / shown.as_raw().len() as f64).sqrt();
    assert!(rmse < 9.0, "per-pixel RMSE {rmse:.2} levels");
}
