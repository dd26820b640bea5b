//! The integrator's stages as functions of one record. Devices map them over
//! their queues (the CPU device with rayon); the CUDA kernels of the same
//! names implement the same arithmetic.

pub mod generate;
pub mod shade;
