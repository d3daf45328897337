//! The DSP chain's integration tests, one test binary: each module below was a binary of its
//! own, and each instantiated the whole generic pipeline again (about 40–50 s of a cold CI
//! build apiece; BENCHMARKS.md "CI time").
//!
//! Run one module with its name as the filter: `cargo test -p aim-dsp --test dsp gaps`.

mod common;

mod bpf_accuracy;
mod gaps;
mod pipeline;
mod snippets;
mod spatial_accuracy;
