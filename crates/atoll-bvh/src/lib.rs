//! BVH builders, layouts and CPU traversal.
