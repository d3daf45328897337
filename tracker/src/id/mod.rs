//! Drone detection and type identification from recordings (issue 16, ALGORITHMS.md §10):
//! `aim id train | eval | classify`.
//!
//! - [`audio`]: a WAV file (mono or multichannel, 16 or 48 kHz, integer or float) to one
//!   16 kHz channel;
//! - [`chip`]: the feature vector of a window of the chip's `Mfcc` frames (what `aim track`
//!   classifies live), and those frames computed from a recording by the chip's pipeline;
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
pub mod chip;
pub mod clip;
pub mod dataset;
pub mod metrics;
pub mod model;

/// Name of the class of recordings without a drone.
pub const NONE_CLASS: &str = "none";

/// The bundled drone classifier: trained with `aim id train --features chip` on host-sim's
/// simulated drones and negatives (`host-sim id-dataset`; seeds and command in BENCHMARKS.md,
/// "Issue 16 on the chip"; the current one: "Session 24: a second comb in the `Mfcc` frame").
pub fn default_model() -> model::Model {
    model::Model::from_json(
        include_str!("../../models/drone-id-chip.json"),
        std::path::Path::new("tracker/models/drone-id-chip.json"),
    )
    .expect("the bundled model is valid")
}

/// The profiles the tracker may switch to, by class: `DIR/<class>.toml` for every class of
/// `classes` that has one in `dir`, else the bundled profile of that name
/// ([`crate::profile::BUNDLED`]: all six types of the bundled model). Profiles hold published
/// or calibrated values, never the simulator's.
pub fn class_profiles(
    dir: Option<&std::path::Path>,
    classes: &[String],
) -> anyhow::Result<Vec<(String, crate::profile::Profile)>> {
    if let Some(d) = dir.filter(|d| !d.is_dir()) {
        anyhow::bail!("--id-profiles {}: no such folder", d.display());
    }
    let mut out = Vec::new();
    for c in classes.iter().filter(|c| *c != NONE_CLASS) {
        let file = dir.map(|d| d.join(format!("{c}.toml"))).filter(|p| p.is_file());
        if let Some(p) = file {
            out.push((c.clone(), crate::profile::Profile::load(&p)?));
        } else if let Some(p) = crate::profile::Profile::bundled(c) {
            out.push((c.clone(), p));
        }
    }
    Ok(out)
}
