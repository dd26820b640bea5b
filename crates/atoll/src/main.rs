//! `atoll`: render, inspect and benchmark scenes.

mod bench;
mod compare;
mod device;
mod gen;
mod info;
mod load;
mod multi;
mod preflight;
#[cfg(feature = "mpi")]
mod ranked;
mod render;
mod serve;
mod streams;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// A path tracer for scenes too large for one GPU.
#[derive(Parser)]
#[command(name = "atoll", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Let scene files name files outside their own folder (absolute
    /// paths, `..`, `file://` URIs): for scenes from trusted sources only.
    #[arg(long, global = true)]
    allow_outside_paths: bool,
    /// Render a scene whose images, environment maps or spectrum files
    /// cannot be read, each replaced by a stand-in with a warning (pbrt-v4
    /// and, without this, atoll stop with an error).
    #[arg(long, global = true)]
    allow_missing: bool,
    /// Most bytes all the files of one scene may have together, e.g. 512G
    /// (default 256G): stops scenes that read without end.
    #[arg(long, global = true, value_parser = device::parse_size, value_name = "SIZE")]
    max_scene_bytes: Option<u64>,
    /// Most triangles the shapes of one scene may generate: subdivision
    /// surfaces, tessellated spheres and patches (default 268435456).
    #[arg(long, global = true, value_parser = clap::value_parser!(u64).range(1..), value_name = "COUNT")]
    max_generated_triangles: Option<u64>,
}

// Every subcommand reads negative numbers as values (`--spp -1` is then
// refused by the argument's own range, naming it), not as unknown flags.
#[derive(Subcommand)]
enum Command {
    /// Render a scene (the built-in Cornell box when none is given).
    #[command(allow_negative_numbers = true)]
    Render(Box<render::RenderArgs>),
    /// Render a scene progressively and watch it in a browser (127.0.0.1:8080 unless told otherwise).
    #[command(allow_negative_numbers = true)]
    Serve(Box<serve::ServeArgs>),
    /// Print counts, bounds, memory estimate and BVH statistics of a scene.
    #[command(allow_negative_numbers = true)]
    Info(info::InfoArgs),
    /// Measure BVH build, traversal and path-tracing speed.
    #[command(allow_negative_numbers = true)]
    Bench(bench::BenchArgs),
    /// Compare two EXR renders: channel means and per-pixel relative errors.
    #[command(allow_negative_numbers = true)]
    Compare(compare::CompareArgs),
    /// Generate a procedural benchmark scene: print its size or write it as PBRT-v4.
    #[command(allow_negative_numbers = true)]
    Gen(gen::GenArgs),
}

/// Failures the command line reports, with their exit codes.
#[derive(Debug)]
pub enum CliError {
    /// The scene (or an argument naming it) is wrong: exit code 2.
    Input(String),
    /// Anything else (device, output): exit code 1.
    Runtime(String),
    /// Already said (by MPI rank 0, for every rank): exit with this code.
    Reported(u8),
    /// A bug: a panic while reading a scene: exit code 70 (sysexits'
    /// EX_SOFTWARE).
    Internal(String),
}

/// Output piped into a reader that stops early (`atoll info … | head`)
/// ends the process as it ends Unix tools, by SIGPIPE, instead of a panic
/// in `println!` (Rust ignores the signal, so writes fail instead). Not
/// for the server or MPI and NCCL ranks: their sockets must see a peer
/// that went away as an error to handle, not as the end of the process.
fn end_quietly_when_stdout_closes() {
    #[cfg(unix)]
    // SAFETY: sets one signal's disposition back to the system default, at
    // start-up; no handler of ours runs.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("ATOLL_LOG").unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        // Colour only on a terminal, and never with NO_COLOR set (no-color.org).
        .with_ansi(
            std::io::IsTerminal::is_terminal(&std::io::stderr()) && std::env::var_os("NO_COLOR").is_none(),
        )
        .with_target(false)
        .without_time()
        .init();
    load::install_panic_hook();
    let cli = Cli::parse();
    atoll_scene::input::allow_outside_paths(cli.allow_outside_paths);
    atoll_scene::input::allow_missing_files(cli.allow_missing);
    if let Some(bytes) = cli.max_scene_bytes {
        atoll_scene::input::set_max_scene_bytes(bytes);
    }
    if let Some(triangles) = cli.max_generated_triangles {
        atoll_scene::input::set_max_generated_triangles(triangles);
    }
    let over_sockets = match &cli.command {
        Some(Command::Serve(_)) => true,
        Some(Command::Render(args)) => args.mpi,
        Some(Command::Bench(args)) => args.nccl_ranks,
        _ => false,
    };
    if !over_sockets {
        end_quietly_when_stdout_closes();
    }
    let result = match cli.command {
        Some(Command::Render(args)) => render::run(*args),
        Some(Command::Serve(args)) => serve::run(*args),
        Some(Command::Info(args)) => info::run(args),
        Some(Command::Bench(args)) => bench::run(args),
        Some(Command::Compare(args)) => compare::run(args),
        Some(Command::Gen(args)) => gen::run(args),
        None => render::run(render::RenderArgs::default()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(CliError::Input(message)) => {
            eprintln!("error: {message}");
            ExitCode::from(2)
        }
        Err(CliError::Runtime(message)) => {
            eprintln!("error: {message}");
            ExitCode::from(1)
        }
        Err(CliError::Reported(code)) => ExitCode::from(code),
        Err(CliError::Internal(message)) => {
            eprintln!("atoll: {message}");
            ExitCode::from(70)
        }
    }
}
