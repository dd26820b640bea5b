//! The CUDA device (issue 3). Empty until the CPU foundation has landed.
