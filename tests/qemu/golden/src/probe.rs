//! Probe ids: what the instructions of the `cost` binary are charged to.
//!
//! The `insn_probe` QEMU plugin charges every instruction to the id in force, and writes the
//! totals per id when [`Probe::Dump`] runs. The guest switches ids explicitly by calling slot
//! `id` of its probe table; the code of each DSP stage switches to its stage's id (xtask maps
//! the stage code from the ELF's debug information). Host (`xtask`) and guest share this list.

/// What the instructions after a probe belong to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Probe {
    /// Nothing measured (start-up, printing).
    Untracked = 0,
    /// Synthesising the golden input (not part of the pipeline's cost).
    Input = 1,
    /// Pipeline work outside the named stages: the front end (TDM words, DC removal, block
    /// exponent), bookkeeping, the output sink.
    PipelineOther = 2,
    /// Spatial path: Q15 conversion, window and real FFT of every microphone.
    Fft = 3,
    /// PHAT normalisation of every spectrum in the band, cross spectra of every pair averaged
    /// over the blocks of one estimate.
    Phat = 4,
    /// Per pair: lag search over the averaged cross spectrum (the inverse transform) and
    /// sub-sample refinement.
    Inverse = 5,
    /// Direction of arrival: the weighted least-squares fit and the estimate's bookkeeping.
    Doa = 6,
    /// Spectral path: mono mix, decimation, long FFT, BPF peak picking.
    Bpf = 7,
    /// Reference figure: one microfft `rfft_1024`.
    ReferenceRfft = 8,
    /// Encoding outputs into wire frames.
    Encode = 9,
    /// PDM decimation (`aim_dsp::pdm`): PDM bytes to the pipeline's 48 kHz words.
    Pdm = 10,
    /// Drone-identification features of the BPF spectrum (`aim_dsp::idframe`): log-mel, MFCC,
    /// comb features.
    Features = 11,
    /// The synchronisation beacon's detector on microphone 0 (`aim_dsp::beacon`): mixing
    /// decimation filter, overlap-save correlation, peak refinement.
    Beacon = 12,
    /// The audio snippets for inter-array delays (`aim_dsp::snippet`, the pipeline's
    /// `emit_snippets`): reading the BPF path's ring, block-floating quantisation.
    Snippet = 13,
    /// Writes the totals of the section that ends here.
    Dump = 15,
}

/// Number of probe slots (ids `0..SLOTS`).
pub const SLOTS: usize = 16;

impl Probe {
    /// Every probe, in id order.
    pub const ALL: [Probe; 15] = [
        Probe::Untracked,
        Probe::Input,
        Probe::PipelineOther,
        Probe::Fft,
        Probe::Phat,
        Probe::Inverse,
        Probe::Doa,
        Probe::Bpf,
        Probe::ReferenceRfft,
        Probe::Encode,
        Probe::Pdm,
        Probe::Features,
        Probe::Beacon,
        Probe::Snippet,
        Probe::Dump,
    ];

    /// The probe's slot id.
    pub const fn id(self) -> usize {
        self as usize
    }

    /// The probe with slot `id`, if any.
    pub fn from_id(id: usize) -> Option<Probe> {
        Probe::ALL.into_iter().find(|p| p.id() == id)
    }

    /// Short lower-case name, used in budget names.
    pub const fn name(self) -> &'static str {
        match self {
            Probe::Untracked => "untracked",
            Probe::Input => "input",
            Probe::PipelineOther => "other",
            Probe::Fft => "fft",
            Probe::Phat => "phat",
            Probe::Inverse => "inverse",
            Probe::Doa => "doa",
            Probe::Bpf => "bpf",
            Probe::ReferenceRfft => "rfft1024",
            Probe::Encode => "encode",
            Probe::Pdm => "pdm",
            Probe::Features => "features",
            Probe::Beacon => "beacon",
            Probe::Snippet => "snippet",
            Probe::Dump => "dump",
        }
    }

    /// Whether the instructions charged to this probe are the pipeline's.
    pub const fn is_pipeline(self) -> bool {
        matches!(
            self,
            Probe::PipelineOther
                | Probe::Fft
                | Probe::Phat
                | Probe::Inverse
                | Probe::Doa
                | Probe::Bpf
                | Probe::Pdm
                | Probe::Features
                | Probe::Beacon
                | Probe::Snippet
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_distinct_fit_the_table_and_round_trip() {
        for (i, p) in Probe::ALL.iter().enumerate() {
            assert!(p.id() < SLOTS);
            assert_eq!(Probe::from_id(p.id()), Some(*p));
            for q in &Probe::ALL[..i] {
                assert_ne!(p.id(), q.id());
                assert_ne!(p.name(), q.name());
            }
        }
        assert_eq!(Probe::from_id(SLOTS - 2), None);
    }
}
