//! The hostile-input suite: hundreds of malformed, oversized and careless
//! inputs (scenes, meshes, images, command lines; see `cases.rs`), each run
//! through the `atoll` binary in a folder of its own, under a memory limit
//! and a timeout. For every case: the exit code the README promises, a
//! message naming the file (and its line for syntax errors), no panic, no
//! signal, no timeout, an image already at the output path byte-identical
//! when the run fails, and no stray file left beside it. Every failure is
//! listed at the end, not just the first.

mod cases;
mod templates;

use std::os::unix::fs::symlink;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use cases::{Case, Entry};

/// Address space each run may reserve: a small render needs a few hundred
/// MiB; allocations sized by a lying header fail well before the machine's
/// memory is at risk.
const MEMORY_LIMIT: u64 = 4 << 30;

/// Wall time each run may take (a debug build on a loaded 2-core runner
/// renders each case in well under a second).
const TIMEOUT: Duration = Duration::from_secs(30);

/// How a run ended.
struct Outcome {
    code: Option<i32>,
    signal: Option<i32>,
    timed_out: bool,
    stderr: String,
    seconds: f64,
}

/// Fills `dir` with the case's files and a stand-in for a user's image at
/// `out.png`; returns that image's bytes.
fn populate(dir: &Path, case: &Case, index: usize) -> Vec<u8> {
    for (name, entry) in &case.files {
        let path = dir.join(name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).unwrap();
        }
        match entry {
            Entry::Bytes(b) => std::fs::write(&path, b).unwrap(),
            Entry::Link(target) => symlink(target, &path).unwrap(),
            Entry::Fifo => {
                let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
                // SAFETY: a valid NUL-terminated path.
                assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0, "mkfifo {}", path.display());
            }
            Entry::Sparse(len) => std::fs::File::create(&path).unwrap().set_len(*len).unwrap(),
            Entry::Dir => std::fs::create_dir_all(&path).unwrap(),
        }
    }
    // Random bytes, different for every case (a simple xorshift).
    let mut x = 0x9e37_79b9_7f4a_7c15u64 ^ (index as u64).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    let precious: Vec<u8> = (0..257)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect();
    std::fs::write(dir.join("out.png"), &precious).unwrap();
    precious
}

/// Runs `atoll` with the case's arguments in `dir`, its address space
/// limited and its time bounded; stdout and stderr go to files in `logs`.
fn run(dir: &Path, logs: &Path, case: &Case) -> Outcome {
    let stdout = std::fs::File::create(logs.join("stdout")).unwrap();
    let stderr_path = logs.join("stderr");
    let stderr = std::fs::File::create(&stderr_path).unwrap();
    let mut command = Command::new(env!("CARGO_BIN_EXE_atoll"));
    command
        .args(&case.args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(stdout)
        .stderr(stderr)
        .env_remove("RUST_BACKTRACE")
        .env_remove("ATOLL_LOG")
        .env("NO_COLOR", "1");
    // SAFETY: only async-signal-safe calls (setrlimit) between fork and exec.
    unsafe {
        command.pre_exec(|| {
            let limit = |resource, value: u64| {
                let l = libc::rlimit { rlim_cur: value as libc::rlim_t, rlim_max: value as libc::rlim_t };
                if libc::setrlimit(resource, &l) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            };
            limit(libc::RLIMIT_AS, MEMORY_LIMIT)?;
            // No core files from a crash; no output file past 1 GiB.
            limit(libc::RLIMIT_CORE, 0)?;
            limit(libc::RLIMIT_FSIZE, 1 << 30)
        });
    }
    let start = Instant::now();
    let mut child = command.spawn().expect("atoll starts");
    let (status, timed_out) = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break (status, false);
        }
        if start.elapsed() > TIMEOUT {
            let _ = child.kill();
            break (child.wait().unwrap(), true);
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    Outcome {
        code: status.code(),
        signal: status.signal(),
        timed_out,
        stderr: String::from_utf8_lossy(&std::fs::read(&stderr_path).unwrap()).into_owned(),
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// `FILE:LINE:` somewhere in `text` (any line from 1).
fn has_file_line(text: &str, file: &str) -> bool {
    text.match_indices(&format!("{file}:")).any(|(i, m)| {
        let rest = &text[i + m.len()..];
        let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
        digits > 0 && rest[digits..].starts_with(':') && !rest.starts_with('0')
    })
}

/// What is wrong with how `case` went: empty when it went as it must.
fn judge(case: &Case, dir: &Path, precious: &[u8], o: &Outcome) -> Vec<String> {
    let mut wrong = Vec::new();
    if o.timed_out {
        wrong.push(format!("timed out after {:.0} s", o.seconds));
    }
    if let Some(signal) = o.signal {
        wrong.push(format!("killed by signal {signal}"));
    }
    let code = o.code.unwrap_or(-1);
    if !o.timed_out && o.signal.is_none() && !case.codes.contains(&code) {
        wrong.push(format!("exit code {code}, expected one of {:?}", case.codes));
    }
    for bad in ["panicked", "RUST_BACKTRACE", "thread '"] {
        if o.stderr.contains(bad) {
            wrong.push(format!("panic text '{bad}'"));
        }
    }
    for text in &case.always {
        if !o.stderr.contains(text.as_str()) {
            wrong.push(format!("stderr does not say '{text}'"));
        }
    }
    if code != 0 {
        for text in &case.on_failure {
            if !o.stderr.contains(text.as_str()) {
                wrong.push(format!("stderr does not say '{text}'"));
            }
        }
        if let Some(file) = &case.line_in {
            // A file that ends too early has no line to blame.
            let at_end = o.stderr.contains("end of file") || o.stderr.contains("truncated");
            if !(has_file_line(&o.stderr, file) || at_end && o.stderr.contains(file.as_str())) {
                wrong.push(format!("stderr does not say {file}:LINE:"));
            }
        }
        if o.stderr.trim().is_empty() {
            wrong.push("failed without a message".into());
        }
    }
    let writes_out_png = case.args.windows(2).any(|w| w[0] == "-o" && w[1] == "out.png");
    match std::fs::read(dir.join("out.png")) {
        Ok(bytes) if code == 0 && writes_out_png => {
            if !bytes.starts_with(b"\x89PNG") {
                wrong.push("succeeded but out.png is no PNG".into());
            }
        }
        Ok(bytes) if bytes != precious => wrong.push("the existing out.png was changed".into()),
        Ok(_) => {}
        Err(e) => wrong.push(format!("the existing out.png is gone: {e}")),
    }
    let mut expected: Vec<&str> = case.files.iter().map(|(n, _)| n.split('/').next().unwrap()).collect();
    expected.push("out.png");
    expected.extend(case.creates.iter().map(String::as_str));
    for entry in std::fs::read_dir(dir).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        if !expected.contains(&name.as_str()) {
            wrong.push(format!("stray file '{name}' left in the folder"));
        }
    }
    wrong
}

/// The last lines of stderr, for the failure table.
fn tail(stderr: &str) -> String {
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    lines[lines.len().saturating_sub(3)..].join(" | ")
}

#[test]
fn hostile_inputs() {
    let root = tempfile::Builder::new().prefix("atoll-hostile-").tempdir().unwrap();
    let scratch = root.path().join("scratch");
    std::fs::create_dir(&scratch).unwrap();
    let cases = cases::all(&scratch);
    // Some cases write beside their folder (`../film.png`): each folder is
    // one level below a folder of its own.
    let next = AtomicUsize::new(0);
    let failures = Mutex::new(Vec::new());
    let slowest = Mutex::new((0.0f64, String::new()));
    let workers = std::thread::available_parallelism().map_or(2, |n| n.get()).clamp(2, 8);
    let started = Instant::now();
    std::thread::scope(|s| {
        for _ in 0..workers {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(case) = cases.get(i) else { break };
                let home: PathBuf = root.path().join(format!("{i:04}"));
                let dir = home.join("case");
                let logs = home.join("logs");
                std::fs::create_dir_all(&dir).unwrap();
                std::fs::create_dir_all(&logs).unwrap();
                let precious = populate(&dir, case, i);
                let outcome = run(&dir, &logs, case);
                let wrong = judge(case, &dir, &precious, &outcome);
                {
                    let mut slow = slowest.lock().unwrap();
                    if outcome.seconds > slow.0 {
                        *slow = (outcome.seconds, format!("{} / {}", case.class, case.name));
                    }
                }
                if !wrong.is_empty() {
                    failures.lock().unwrap().push((i, wrong.join("; "), tail(&outcome.stderr)));
                }
                // Sparse files and pipes need not outlive their case.
                let _ = std::fs::remove_dir_all(&home);
            });
        }
    });
    let mut failures = failures.into_inner().unwrap();
    failures.sort();
    let mut per_class: Vec<(&str, usize, usize)> = Vec::new();
    for (i, case) in cases.iter().enumerate() {
        let failed = failures.iter().any(|f| f.0 == i) as usize;
        match per_class.iter_mut().find(|c| c.0 == case.class) {
            Some(c) => {
                c.1 += 1;
                c.2 += failed;
            }
            None => per_class.push((case.class, 1, failed)),
        }
    }
    let slowest = slowest.into_inner().unwrap();
    eprintln!(
        "{} cases on {workers} threads in {:.1} s (slowest {:.1} s: {}); per class (cases, failed):",
        cases.len(),
        started.elapsed().as_secs_f64(),
        slowest.0,
        slowest.1
    );
    for (class, n, failed) in &per_class {
        eprintln!("  {class:<20} {n:>4} {failed:>4}");
    }
    if !failures.is_empty() {
        eprintln!("\n{} failures:", failures.len());
        eprintln!("{:<5} {:<20} {:<60} what went wrong  [stderr's end]", "case", "class", "name");
        for (i, wrong, stderr) in &failures {
            let case = &cases[*i];
            eprintln!("{i:<5} {:<20} {:<60} {wrong}  [{stderr}]", case.class, case.name);
        }
        panic!("{} of {} hostile inputs were mishandled (table above)", failures.len(), cases.len());
    }
}
