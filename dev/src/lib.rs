//! What only lensblur's benchmarks and tests use, kept out of the library: the benchmark
//! ([`bench`](mod@bench): quality against ray-traced truth, the single-image Cycles suite, large frames,
//! depth from defocus, performance, sequences, the peers and Blender's Defocus node) and the
//! device self-check ([`selfcheck`](mod@selfcheck): every device pass against its CPU reference, run by the
//! tests and by the GPU kit). The command line's `lensblur bench` and `lensblur self-check`
//! call into it.
pub mod bench;
pub mod selfcheck;
