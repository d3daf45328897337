//! AIM on-chip signal processing: a streaming pipeline from TDM microphone words to direction of
//! arrival (GCC-PHAT, weighted least squares) and blade-passing-frequency (BPF) peaks.
//!
//! `no_std`, no allocation, no `unsafe`, fixed memory sized at compile time, all f32 maths
//! through `libm` so the host and the Cortex-M target compute the same bits.
//!
//! ```
//! use aim_dsp::{Config, Geometry, Output, Pipeline};
//! let config = Config::new(Geometry::respeaker_6mic(), 48_000);
//! let mut pipeline = Pipeline::new(&config).unwrap();
//! let words = [0i32; 8 * 256]; // one DMA half-buffer: 256 TDM frames of 8 slots
//! let mut outputs = 0;
//! pipeline.push(&words, &mut |_o: Output| outputs += 1);
//! ```
//!
//! Stages (one module each): [`frontend`] (TDM words → Q31 → DC removal → Q15 with a block
//! exponent), [`gcc_phat`] (PHAT cross spectra, lag search, sub-sample refinement),
//! [`doa`] (least-squares direction), [`bpf`] (decimation, long spectrum), [`comb`] (whitening,
//! rotor combs, detection),
//! [`features`] (drone-identification features of 16 kHz frames: log-mel, MFCC, BPF harmonics),
//! [`idframe`] (the same kinds of features from the BPF path's spectrum: the chip's MFCC output),
//! [`snippet`] (the mean signal at 8 kHz for inter-array delays), [`pipeline`] (the streaming
//! glue).
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod beacon;
pub mod bpf;
pub mod comb;
mod config;
pub mod doa;
mod error;
pub mod features;
pub mod fft;
pub mod frontend;
pub mod gcc_phat;
mod geometry;
pub mod idframe;
mod output;
pub mod pdm;
pub mod pipeline;
pub mod snippet;
mod trig;
pub mod window;

pub use config::Config;
pub use error::ConfigError;
pub use geometry::{
    Geometry, CIRCLE_8MIC_RADIUS_M, RESPEAKER_4MIC_SIDE_M, RESPEAKER_6MIC_RADIUS_M,
};
pub use idframe::IdFeatures;
pub use output::{Doa, Health, Output, Peak, Peaks};
pub use pipeline::{GapStats, Pipeline};
pub use snippet::Snippet;

/// Fewest microphones an array may have.
pub const MIN_MICS: usize = 4;
/// Most microphones an array may have.
pub const MAX_MICS: usize = 8;
/// Microphone pairs of the largest array.
pub const MAX_PAIRS: usize = MAX_MICS * (MAX_MICS - 1) / 2;
/// Largest spatial block / FFT length, samples.
pub const MAX_BLOCK_LEN: usize = 1024;
/// Most FFT bins in the GCC-PHAT band.
pub const MAX_BAND_BINS: usize = 192;
/// Largest pair lag searched, samples (aperture / c · fs + 1).
pub const MAX_LAG: usize = 48;
/// Most harmonics per BPF peak group.
pub const MAX_HARMONICS: usize = 12;
