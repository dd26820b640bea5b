//! The renderer: ray record, sampling, camera, BSDFs, lights, film, the
//! wavefront integrator and the `Device` trait with its CPU implementation.
