//! Drone detection and type identification from recordings (issue 16, ALGORITHMS.md §10):
//! `aim id train | eval | classify`.
//!
//! - [`audio`]: a WAV file (mono or multichannel, 16 or 48 kHz, integer or float) to one
//!   16 kHz channel;
//! - [`clip`]: a clip's feature vector from the per-frame features of `aim_dsp::features` (the
//!   same code the chip would run) aggregated over the clip;
//! - [`dataset`]: a folder of labelled recordings, one subfolder per class;
//! - [`model`]: the classifier (a small multilayer perceptron) and its JSON file;
//! - [`metrics`]: confusion matrix, precision and recall, the detection ROC.
//!
//! Departure from the paper: the paper band-passes around each type's BPF and trains an LSTM on
//! the MFCC sequence. Here one feature vector per clip (MFCC and log-mel statistics over the
//! clip plus BPF-harmonic features: comb fundamental, shaft-line structure, harmonic envelope)
//! feeds a one-hidden-layer perceptron: the BPF comb features do what the per-type band-pass
//! does, without a filter bank per known type, and a clip-level model needs far less training
//! data than a sequence model.
pub mod audio;
pub mod clip;
pub mod dataset;
pub mod metrics;
pub mod model;

/// Name of the class of recordings without a drone.
pub const NONE_CLASS: &str = "none";
