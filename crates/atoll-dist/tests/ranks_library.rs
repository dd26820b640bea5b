//! atoll as a library under MPI: a program that initialised MPI itself
//! hands atoll a communicator of its own, and only that communicator's
//! processes render together. Here `mpirun` starts four processes; each
//! half of the world renders a frame of its own (of different spp: were
//! the halves mixed, the ranks would refuse the frame or hang), and each
//! half's film equals one process's.
//!
//! The test starts itself under `mpirun` (Debian's openmpi-bin).
#![cfg(feature = "mpi")]

use std::process::Command;
use std::sync::Arc;

use atoll_dist::ranks::Ranks;
use atoll_dist::{render_multi, Layout};
use atoll_render::{CpuDevice, Device, RenderOptions};
use glam::UVec2;
use mpi::topology::Color;
use mpi::traits::*;

/// Set in the processes `mpirun` starts.
const UNDER_MPI: &str = "ATOLL_RANKS_LIBRARY_TEST";
const NAME: &str = "halves_of_the_world_render_frames_of_their_own";

#[test]
fn halves_of_the_world_render_frames_of_their_own() {
    if std::env::var_os(UNDER_MPI).is_none() {
        let exe = std::env::current_exe().expect("the test's own path");
        let out = Command::new("timeout")
            .args(["120", "mpirun", "--oversubscribe", "-n", "4"])
            .arg(exe)
            .args(["--exact", NAME, "--nocapture", "--test-threads", "1"])
            .env(UNDER_MPI, "1")
            .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
            .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
            .output()
            .expect("mpirun runs (Debian's openmpi-bin)");
        let stdout = String::from_utf8_lossy(&out.stdout);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{stdout}{stderr}");
        // Each half's rank 0 checked its film against one process's.
        for spp in [2, 4] {
            assert_eq!(
                stdout.matches(&format!("half of {spp} spp: film of one process")).count(),
                1,
                "{stdout}"
            );
        }
        return;
    }

    let (universe, _) = mpi::initialize_with_threading(mpi::Threading::Multiple).expect("MPI starts once");
    let world = universe.world();
    let half = world.split_by_color(Color::with_value(world.rank() % 2)).expect("every rank has a half");
    let ranks = Ranks::with_communicator(&half).expect("a caller's communicator");
    assert_eq!(ranks.size(), 2);
    assert_eq!(ranks.rank(), world.rank() as usize / 2);

    let scene = Arc::new(atoll_scene::cornell::builtin_cornell_box());
    let mut options = RenderOptions::from_scene(&scene);
    options.resolution = UVec2::new(32, 24);
    options.spp = 2 + 2 * (world.rank() % 2) as u32;
    let cpu =
        || -> Vec<Box<dyn Device>> { vec![Box::new(CpuDevice::new().with_threads(1).expect("a pool"))] };
    let out =
        ranks.render(&mut cpu(), &scene, options.clone(), &Layout::Replicate).expect("the half renders");
    if ranks.is_root() {
        let alone =
            render_multi(&mut cpu(), &scene, options.clone(), &Layout::Replicate, None, &mut |_, _| {})
                .expect("one process renders");
        assert_eq!(out.film.spp, alone.film.spp);
        // Equal up to the rounding of summing waves in another order.
        for (a, b) in out.film.sum.iter().zip(&alone.film.sum) {
            let scale = a.abs().max(b.abs()).max_element().max(1e-3);
            assert!((*a - *b).abs().max_element() <= 1e-4 * scale, "{a} against {b}");
        }
        assert!(out.film.sum.iter().any(|p| p.max_element() > 0.0), "the film has light");
        println!("half of {} spp: film of one process", options.spp);
    }
    drop(ranks);
}
