//! `atoll render --mpi` under Open MPI's `mpirun`, processes on this
//! machine standing in for nodes: the image equals one process's (each
//! wave rendered once, whichever rank took it), ranks with unequal devices
//! all take waves, and a rank that fails stops every rank with a clear
//! error instead of a hang, leaving an existing image untouched.
//!
//! Needs an atoll built with `--features mpi` and `mpirun` (Debian's
//! openmpi-bin); `scripts/test.sh` installs both.
#![cfg(feature = "mpi")]

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const ATOLL: &str = env!("CARGO_BIN_EXE_atoll");
const FRAME: [&str; 6] = ["--spp", "4", "--res", "64x48", "--max-depth", "5"];

fn scratch(name: &str) -> PathBuf {
    common::scratch("mpi", name)
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The frame's arguments, unless `args` give their own samples per pixel.
fn frame_unless_given(args: &[&str]) -> &'static [&'static str] {
    if args.contains(&"--spp") {
        &[]
    } else {
        &FRAME
    }
}

/// `atoll render FRAME ARGS -o OUTPUT` once, without MPI.
fn render_alone(dir: &Path, args: &[&str], output: &str) -> Output {
    Command::new(ATOLL)
        .arg("render")
        .args(frame_unless_given(args))
        .args(args)
        .args(["-q", "-o", output])
        .current_dir(dir)
        .output()
        .expect("atoll runs")
}

/// `mpirun` with one `-n N atoll render --mpi FRAME ARGS -o OUTPUT` per
/// entry of `ranks` (mpirun's `A : B` form: ranks with different
/// arguments; FRAME left out where ARGS give `--spp`), killed after two
/// minutes so that a hang fails the test.
fn mpirun(dir: &Path, ranks: &[(usize, &[&str])], output: &str) -> Output {
    let mut command = Command::new("timeout");
    command.args(["120", "mpirun", "--oversubscribe"]);
    for (i, (n, args)) in ranks.iter().enumerate() {
        if i > 0 {
            command.arg(":");
        }
        command
            .args(["-n", &n.to_string(), ATOLL, "render", "--mpi"])
            .args(frame_unless_given(args))
            .args(*args);
        command.args(["-q", "-o", output]);
    }
    command
        .current_dir(dir)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .output()
        .expect("mpirun runs (Debian's openmpi-bin)")
}

/// Every pixel equal up to the rounding of summing in another order (a
/// wave rendered twice or never would double or zero its pixels).
fn assert_same_pixels(dir: &Path, a: &str, b: &str) {
    let (a, b) = (common::read_exr(&dir.join(a)), common::read_exr(&dir.join(b)));
    assert_eq!(a.len(), b.len());
    let worst = a
        .iter()
        .zip(&b)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs() / p[c].abs().max(1e-3)))
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-4, "largest relative pixel difference {worst}");
    assert!(a.iter().any(|p| p[0] > 0.0), "the image is not black");
}

/// One row of the device table rank 0 prints.
#[derive(Debug)]
struct Row {
    rank: usize,
    ring: usize,
    member: usize,
    waves: usize,
    /// Millions of path and shadow rays traced, as printed.
    rays: (String, String),
    sent: String,
}

fn table(stdout: &str) -> Vec<Row> {
    stdout
        .lines()
        .skip_while(|l| !l.starts_with("rank"))
        .skip(1)
        .map_while(|row| {
            // rank device ring member scene-mem (2) frame-mem (2) waves rays shadow busy idle wait send sent (2)
            let f: Vec<&str> = row.split_whitespace().collect();
            Some(Row {
                rank: f.first()?.parse().ok()?,
                ring: f.get(2)?.parse().ok()?,
                member: f.get(3)?.parse().ok()?,
                waves: f.get(8)?.parse().ok()?,
                rays: (f.get(9)?.to_string(), f.get(10)?.to_string()),
                sent: f.get(15..17)?.join(" "),
            })
        })
        .collect()
}

/// Per rank, the waves its devices took.
fn waves_by_rank(stdout: &str, ranks: usize) -> Vec<usize> {
    let mut waves = vec![0; ranks];
    for row in table(stdout) {
        waves[row.rank] += row.waves;
    }
    waves
}

#[test]
fn ranks_render_the_image_of_one_process() {
    let dir = scratch("same");
    // Waves of 256 pixels: 48 in the frame, so that a rank that starts
    // late (three processes on CI's two cores) still finds some left.
    let alone = render_alone(&dir, &["--device", "cpu", "--wave-size", "256"], "alone.exr");
    assert!(alone.status.success(), "{}", text(&alone.stderr));

    let out = mpirun(&dir, &[(3, &["--device", "cpu", "--threads", "1", "--wave-size", "256"])], "three.exr");
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stdout}{stderr}");
    assert!(stdout.contains("on 3 ranks (3 devices)"), "{stdout}");
    // CPU films are in host memory already: MPI sums them, and no line
    // speaks of a device-to-device film sum.
    assert!(!stderr.contains("films"), "{stderr}");
    assert_same_pixels(&dir, "alone.exr", "three.exr");
    let waves = waves_by_rank(&stdout, 3);
    assert!(waves.iter().all(|&w| w > 0), "every rank takes waves: {waves:?}\n{stdout}");
}

#[test]
fn unequal_ranks_share_the_waves_and_warm_up_alone() {
    let dir = scratch("unequal");
    // Four times the samples of the other tests: a rank is refused waves
    // when its warm-up speed says its next wave would outlast the others'
    // rest of the frame, and three processes' warm-ups on CI's two cores
    // can make one look several times slower than it is.
    const LONGER_FRAME: [&str; 6] = ["--spp", "16", "--res", "64x48", "--max-depth", "5"];
    let alone = render_alone(&dir, &[&LONGER_FRAME[..], &["--device", "cpu"]].concat(), "alone.exr");
    assert!(alone.status.success(), "{}", text(&alone.stderr));

    // Rank 0 renders on two CPU devices, rank 1 on one taking smaller
    // waves, rank 2 on a ring of two devices that each hold half the scene.
    let out = mpirun(
        &dir,
        &[
            (1, &[&LONGER_FRAME[..], &["--devices", "cpu:2", "--threads", "1", "--warmup"]].concat()),
            (
                1,
                &[
                    &LONGER_FRAME[..],
                    &[
                        "--device",
                        "cpu",
                        "--threads",
                        "1",
                        "--warmup",
                        "--wave-size",
                        "1000",
                        "--film-transport",
                        "host",
                    ],
                ]
                .concat(),
            ),
            (
                1,
                &[
                    &LONGER_FRAME[..],
                    &["--devices", "cpu:2", "--strategy", "ring", "--threads", "1", "--warmup"],
                ]
                .concat(),
            ),
        ],
        "mixed.exr",
    );
    let stdout = text(&out.stdout);
    assert!(out.status.success(), "{stdout}{}", text(&out.stderr));
    assert!(stdout.contains("on 3 ranks (5 devices)"), "{stdout}");
    assert_same_pixels(&dir, "alone.exr", "mixed.exr");
    let waves = waves_by_rank(&stdout, 3);
    assert!(waves.iter().all(|&w| w > 0), "every rank takes waves: {waves:?}\n{stdout}");
}

#[test]
fn a_failing_rank_stops_them_all_and_keeps_the_old_image() {
    let dir = scratch("fail");
    std::fs::write(dir.join("kept.exr"), b"an earlier image").unwrap();

    // Rank 1's device is too small for the scene, and every rank is told
    // to hold the whole scene: rank 1 cannot prepare.
    let out = mpirun(
        &dir,
        &[
            (1, &["--device", "cpu", "--ring-ranks", "1"]),
            (1, &["--device", "cpu", "--ring-ranks", "1", "--device-memory", "1K"]),
        ],
        "kept.exr",
    );
    let stderr = text(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert_ne!(out.status.code(), Some(124), "timed out: a rank waited forever\n{stderr}");
    // Rank 0 gathers what failed where (rank 1 may be stopped by mpirun
    // before it prints).
    assert!(stderr.contains("ranks could not render their share"), "{stderr}");
    assert!(stderr.contains("rank 1: cpu: scene needs"), "{stderr}");
    assert_eq!(std::fs::read(dir.join("kept.exr")).unwrap(), b"an earlier image");

    // Rank 1 renders another frame.
    let other = ["--spp", "8", "--res", "64x48", "--max-depth", "5", "--device", "cpu"];
    let out = mpirun(&dir, &[(1, &["--device", "cpu"]), (1, &other)], "kept.exr");
    let stderr = text(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(stderr.contains("the ranks render different frames"), "{stderr}");
    assert_eq!(std::fs::read(dir.join("kept.exr")).unwrap(), b"an earlier image");

    // Rank 1 cannot read its scene.
    let out = mpirun(&dir, &[(1, &[]), (1, &["missing.pbrt"])], "kept.exr");
    let stderr = text(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert_ne!(out.status.code(), Some(124), "timed out: a rank waited forever\n{stderr}");
    assert_eq!(out.status.code(), Some(2), "a bad scene is an input error\n{stderr}");
    assert!(stderr.contains("1 of 2 ranks could not load the scene"), "{stderr}");
    assert!(stderr.contains("rank 1: missing.pbrt"), "{stderr}");
    assert_eq!(std::fs::read(dir.join("kept.exr")).unwrap(), b"an earlier image");
}

#[test]
fn rings_of_ranks_render_the_image_of_one_process() {
    let dir = scratch("rings");
    let scene = ["landscape:1"];
    let alone = render_alone(&dir, &[&scene[..], &["--device", "cpu"]].concat(), "alone.exr");
    assert!(alone.status.success(), "{}", text(&alone.stderr));

    // Four ranks, rings of two: two islands sharing the waves.
    let args =
        [&scene[..], &["--device", "cpu", "--threads", "1", "--ring-ranks", "2", "--ownership", "own.png"]]
            .concat();
    let out = mpirun(&dir, &[(4, &args)], "rings.exr");
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stdout}{stderr}");
    assert!(stderr.contains("strategy: rings of 2 ranks (2 islands)"), "{stderr}");
    // CPU ranks have no device-to-device transport: one line says so.
    let notice = "note: ring queues go through host memory: not every rank has a GPU with NCCL";
    assert_eq!(stderr.matches(notice).count(), 1, "{stderr}");
    assert!(stderr.contains("ownership view: own.png") && dir.join("own.png").exists(), "{stderr}");
    assert_same_pixels(&dir, "alone.exr", "rings.exr");
    let rows = table(&stdout);
    assert_eq!(rows.len(), 4, "{stdout}");
    for (rank, row) in rows.iter().enumerate() {
        assert_eq!((row.rank, row.ring, row.member), (rank, rank / 2, rank % 2), "{stdout}");
        assert!(row.waves > 0, "every member of a spread ring makes queues: {stdout}");
        assert_ne!(row.sent, "0 B", "queues went between ranks: {stdout}");
    }
    // Every ray is traced by every member of its ring.
    assert_eq!(rows[0].rays, rows[1].rays, "{stdout}");
    assert_eq!(rows[2].rays, rows[3].rays, "{stdout}");

    // Two ranks of two devices each: every device holds its rank's part,
    // a member of a ring of its own (two islands, each on a communicator of
    // its own, stepping at once); a rank with fewer devices sets how many.
    let args = [&scene[..], &["--devices", "cpu:2", "--threads", "1", "--ring-ranks", "2"]].concat();
    let out = mpirun(&dir, &[(2, &args)], "devices.exr");
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stdout}{stderr}");
    assert!(stderr.contains("strategy: rings of 2 ranks (2 islands)"), "{stderr}");
    assert_same_pixels(&dir, "alone.exr", "devices.exr");
    let rows = table(&stdout);
    let places: Vec<(usize, usize, usize)> = rows.iter().map(|r| (r.rank, r.ring, r.member)).collect();
    assert_eq!(places, [(0, 0, 0), (0, 1, 0), (1, 0, 1), (1, 1, 1)], "{stdout}");
    assert!(rows.iter().all(|r| r.waves > 0), "{stdout}");
    assert_eq!((&rows[0].rays, &rows[1].rays), (&rows[2].rays, &rows[3].rays), "{stdout}");
    let one = [&scene[..], &["--devices", "cpu", "--threads", "1", "--ring-ranks", "2"]].concat();
    let out = mpirun(&dir, &[(1, &args), (1, &one)], "fewer.exr");
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stdout}{stderr}");
    assert!(stderr.contains("strategy: rings of 2 ranks (1 island)"), "{stderr}");
    assert_same_pixels(&dir, "alone.exr", "fewer.exr");

    // Two-level rings: each rank's share split over two of its four
    // devices, a queue visiting both before it goes on to the other rank;
    // its other two devices form a second ring (island).
    let args =
        [&scene[..], &["--devices", "cpu:4", "--threads", "1", "--ring-ranks", "2", "--ring-size", "2"]]
            .concat();
    let out = mpirun(&dir, &[(2, &args)], "two-level.exr");
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stdout}{stderr}");
    assert!(stderr.contains("strategy: rings of 2 ranks × 2 devices (2 islands); parts "), "{stderr}");
    assert_eq!(stderr.split("; parts ").nth(1).map(|p| p.split(", ").count()), Some(4), "{stderr}");
    assert_same_pixels(&dir, "alone.exr", "two-level.exr");
    let rows = table(&stdout);
    let places: Vec<(usize, usize, usize)> = rows.iter().map(|r| (r.rank, r.ring, r.member)).collect();
    let expected = [(0, 0, 0), (0, 0, 1), (0, 1, 0), (0, 1, 1), (1, 0, 2), (1, 0, 3), (1, 1, 2), (1, 1, 3)];
    assert_eq!(places, expected, "{stdout}");
    assert!(rows.iter().all(|r| r.sent != "0 B"), "queues went between members: {stdout}");
    // Every ray is traced by all four members of its ring.
    for ring in 0..2 {
        let rays: Vec<&(String, String)> = rows.iter().filter(|r| r.ring == ring).map(|r| &r.rays).collect();
        assert!(rays.windows(2).all(|w| w[0] == w[1]), "{stdout}");
    }

    // A ring of three, member 0 making and shading every queue, warmed up.
    let args = [
        &scene[..],
        &["--device", "cpu", "--threads", "1", "--ring-ranks", "3", "--ring-order", "home", "--warmup"],
    ]
    .concat();
    let out = mpirun(&dir, &[(3, &args)], "home.exr");
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stdout}{stderr}");
    assert_same_pixels(&dir, "alone.exr", "home.exr");
    let waves: Vec<usize> = table(&stdout).iter().map(|r| r.waves).collect();
    assert!(waves[0] > 0 && waves[1..] == [0, 0], "{stdout}");
}

#[test]
fn a_scene_too_big_for_a_rank_is_split_over_ranks() {
    let dir = scratch("auto");
    let alone = render_alone(&dir, &["--device", "cpu"], "alone.exr");
    assert!(alone.status.success(), "{}", text(&alone.stderr));
    // The Cornell box takes about 8 KiB on a CPU device: two parts of it fit.
    let out =
        mpirun(&dir, &[(2, &["--device", "cpu", "--threads", "1", "--device-memory", "5K"])], "split.exr");
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stdout}{stderr}");
    assert!(stderr.contains("strategy: rings of 2 ranks (1 island)"), "{stderr}");
    assert_same_pixels(&dir, "alone.exr", "split.exr");

    // A part per rank would not fit either: each rank's devices split its share.
    let devices = ["--devices", "cpu:2", "--threads", "1", "--ring-ranks", "2", "--device-memory", "3K"];
    let out = mpirun(&dir, &[(2, &devices)], "split.exr");
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stdout}{stderr}");
    assert!(stderr.contains("strategy: rings of 2 ranks × 2 devices (1 island)"), "{stderr}");
    assert_same_pixels(&dir, "alone.exr", "split.exr");

    // Three ranks cannot form rings of two; ranks must ask for the same rings.
    let out = mpirun(&dir, &[(3, &["--device", "cpu", "--ring-ranks", "2"])], "bad.exr");
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--ring-ranks 2: must divide the 3 ranks"), "{stderr}");
    let out =
        mpirun(&dir, &[(1, &["--device", "cpu", "--ring-ranks", "2"]), (1, &["--device", "cpu"])], "bad.exr");
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--ring-ranks differs between ranks"), "{stderr}");
    assert!(!dir.join("bad.exr").exists());
}

/// `atoll bench --nccl-ranks` checks its ranks before any GPU work: one
/// process is too few, and ranks without a GPU are refused, each with exit
/// 2 and a message (its measurement runs on the GPU machine).
#[test]
fn nccl_bench_refuses_too_few_ranks_and_ranks_without_gpus() {
    let dir = scratch("nccl-bench");
    for (n, want) in [("1", "start two or more processes with mpirun"), ("2", "every rank needs a GPU")] {
        let out = Command::new("timeout")
            .args([
                "120",
                "mpirun",
                "--oversubscribe",
                "-n",
                n,
                ATOLL,
                "bench",
                "--nccl-ranks",
                "--device",
                "cpu",
            ])
            .current_dir(&dir)
            .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
            .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
            .output()
            .expect("mpirun runs (Debian's openmpi-bin)");
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{n} ranks: {err}");
        assert!(err.contains(&format!("--nccl-ranks: {want}")), "{n} ranks: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}
