//! What the command-line test files share: running the binary, and a
//! scratch folder per test. (Not every file uses every helper.)
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the atoll binary with `args` in `dir`.
pub fn atoll(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_atoll")).args(args).current_dir(dir).output().expect("atoll runs")
}

/// A fresh scratch folder for test `name` of test file `suite`, unique to
/// this process.
pub fn scratch(suite: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("atoll-{suite}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
