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

/// An EXR's RGB pixels, row by row.
pub fn read_exr(path: &Path) -> Vec<[f32; 3]> {
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| Vec::<[f32; 3]>::with_capacity(res.width() * res.height()),
        |px: &mut Vec<[f32; 3]>, _pos, (r, g, b, _a): (f32, f32, f32, f32)| px.push([r, g, b]),
    )
    .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    image.layer_data.channel_data.pixels
}
