//! Golden input and parity report for AIM's on-target checks.
//!
//! The host (`cargo xtask qemu`) and the QEMU Cortex-M4F binaries (`tests/qemu/m4f`) both run
//! [`report::write_parity`]: the same code synthesises the same input, runs the same DSP and
//! prints every output as bit patterns. Any difference between the two texts is a difference
//! between what the host computes and what the chip computes.
//!
//! Everything here is `no_std`, allocation-free and deterministic: the input is synthesised in
//! integer arithmetic only (a phase accumulator, an integer sine, an xorshift PRNG), so it is
//! identical on both sides by construction, whatever the floating-point code does.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod pdm;
pub mod probe;
pub mod report;
pub mod scenario;

/// The DSP crate the reports run, for the host side (`xtask`) to name `Pipeline`.
pub use aim_dsp;
/// The wire crate whose encode path the reports run.
pub use aim_wire;
pub mod signal;
