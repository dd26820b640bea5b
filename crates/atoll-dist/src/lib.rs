//! Distribution strategies over many devices (issue 4). Empty until the
//! single-device renderer has landed.
