//! Thin-lens distributed ray tracing of billboard scenes: the ground truth.
