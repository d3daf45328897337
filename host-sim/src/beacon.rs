//! The synchronisation beacon's loudspeaker: a static source that plays the published
//! `aim-beacon-v1` waveform ([`aim_dsp::beacon`]) every `period_s` of its OWN clock.
//!
//! The speaker's clock runs `clock_drift_ppm` fast (truth only: it never reaches the site
//! file); emission k starts at true time `start_s + k · period_s / (1 + drift)` and plays the
//! waveform at 48 kHz of that clock. `level_db` is the RMS level of an emission in dB SPL at
//! 1 m.
//!
//! Rendering goes through the same [`Medium`] as the drone: every path the scenario's medium
//! has (direct, room images, the diffracted path around a box), its length, reflection and
//! obstacle gains, 1/r spreading and the same zero-phase air-absorption smoother
//! `1 + b (z⁻¹ − 2 + z)`. The one difference is the fractional delay: the waveform is a
//! closed-form function of time ([`aim_dsp::beacon::waveform_at`]), so each output sample
//! evaluates it at its exact emission time instead of reading a sampled signal through the
//! cubic Lagrange interpolator, whose phase error at 18 kHz (0.375 fs) would shift the
//! arrival by a fraction of a sample depending on the fractional delay (`tests::
//! lagrange_would_bias_the_beacon` measures it).
use std::sync::OnceLock;

use nalgebra::Vector3;

use crate::array::ArrayConfig;
use crate::propagation::{Fixed, Medium, PathKind, Receiver};

/// One beacon loudspeaker (scenario `[[beacon]]`).
#[derive(Clone, Debug, PartialEq)]
pub struct BeaconSpeaker {
    /// Beacon id (site file).
    pub id: u8,
    /// Loudspeaker position, ENU m.
    pub position_m: Vector3<f64>,
    /// RMS level of an emission, dB SPL at 1 m.
    pub level_db: f64,
    /// Repetition period on the speaker's clock, s.
    pub period_s: f64,
    /// The speaker clock's rate error, ppm (positive: fast). Truth only.
    pub clock_drift_ppm: f64,
    /// True time of the first emission, s.
    pub start_s: f64,
}

/// RMS of the unit waveform over one emission.
pub fn waveform_rms() -> f64 {
    static RMS: OnceLock<f64> = OnceLock::new();
    *RMS.get_or_init(|| {
        let n = aim_dsp::beacon::LEN;
        let sum: f64 = (0..n).map(|i| aim_dsp::beacon::waveform_at(i as f64).powi(2)).sum();
        (sum / n as f64).sqrt()
    })
}

impl BeaconSpeaker {
    /// Checks the values; names the problem.
    pub fn validate(&self) -> Result<(), String> {
        let len_s = aim_dsp::beacon::LEN as f64 / f64::from(aim_dsp::beacon::SAMPLE_RATE_HZ);
        if !(self.period_s.is_finite() && self.period_s > len_s) {
            return Err(format!(
                "beacon {}: period_s must exceed the emission ({len_s} s), got {}",
                self.id, self.period_s
            ));
        }
        if !(self.level_db.is_finite()
            && self.clock_drift_ppm.abs() < 1000.0
            && self.start_s.is_finite()
            && self.start_s >= 0.0
            && self.position_m.iter().all(|v| v.is_finite()))
        {
            return Err(format!(
                "beacon {}: level, position and start_s >= 0 must be finite, drift under 1000 ppm",
                self.id
            ));
        }
        Ok(())
    }

    /// True time at which emission `k` starts, s.
    pub fn emission_s(&self, k: u64) -> f64 {
        self.start_s + k as f64 * self.period_s / self.rate_factor()
    }

    fn rate_factor(&self) -> f64 {
        1.0 + self.clock_drift_ppm * 1e-6
    }

    /// Peak pressure of the waveform at 1 m, Pa.
    pub fn amplitude_pa(&self) -> f64 {
        crate::sound::spl_to_rms_pa(self.level_db) / waveform_rms()
    }

    /// Adds the beacon as heard at `rx` over `paths` of `medium` into `out` (Pa), output
    /// sample j at true time `rx.t0_s + j · rx.dt_s`.
    pub fn render(&self, medium: &Medium, paths: &[PathKind], rx: &Receiver, out: &mut [f32]) {
        let fs = f64::from(aim_dsp::beacon::SAMPLE_RATE_HZ) * self.rate_factor();
        let len = aim_dsp::beacon::LEN as f64;
        let amp = self.amplitude_pa();
        let source = Fixed(self.position_m);
        let n = out.len();
        let t_end = rx.t0_s + n as f64 * rx.dt_s;
        let period = self.period_s / self.rate_factor();
        for kind in paths {
            let Some((tau, st)) = medium.retarded(kind, &source, rx.t0_s, &rx.position) else {
                continue;
            };
            let gain = amp * st.gain / st.length_m.max(0.05);
            let b = medium.absorption_b(st.length_m, fs);
            let delay = tau + rx.extra_delay_s;
            // Emissions heard in [t0, t_end): start + k·period + delay within (t0 − len, t_end).
            let first = ((rx.t0_s - delay - self.start_s - (len + 1.0) / fs) / period).ceil();
            let last = ((t_end - delay - self.start_s) / period).floor();
            let first = first.max(0.0) as u64;
            if last < 0.0 {
                continue;
            }
            for k in first..=last as u64 {
                let te = self.emission_s(k) + delay;
                let j0 = ((te - 1.0 / fs - rx.t0_s) / rx.dt_s).floor().max(0.0) as usize;
                let j1 =
                    (((te + (len + 1.0) / fs - rx.t0_s) / rx.dt_s).ceil().max(0.0) as usize).min(n);
                for (j, y) in out.iter_mut().enumerate().take(j1).skip(j0) {
                    let u = (rx.t0_s + j as f64 * rx.dt_s - te) * fs;
                    let w = aim_dsp::beacon::waveform_at;
                    let s = w(u);
                    let d2 = if b > 0.0 { w(u - 1.0) - 2.0 * s + w(u + 1.0) } else { 0.0 };
                    *y += (gain * (s + b * d2)) as f32;
                }
            }
        }
    }

    /// Geometric truth of what the chip reports (`aim_dsp::beacon`: the arrival of the
    /// emission's centre, less LEN/2 samples of the board's clock): the fractional sample index
    /// of `array`'s own clock at which the centre of emission `k` reaches microphone `mic`
    /// along the straight line, less `LEN / 2`; speed of sound `c_mps`, nominal rate `fs`.
    /// Equal to the first sample's arrival when the speaker and the array run at the same
    /// rate; otherwise the two differ by (drift_array − drift_speaker) · LEN / 2 (0.15 sample
    /// at 100 ppm). Evaluation only (never in the product).
    pub fn reported_arrival_on_clock(
        &self,
        k: u64,
        array: &ArrayConfig,
        mic: usize,
        c_mps: f64,
        fs: f64,
    ) -> f64 {
        let half = aim_dsp::beacon::LEN as f64 / 2.0;
        let centre = self.emission_s(k) + half / (fs * self.rate_factor());
        let t = centre + (array.mic_position(mic) - self.position_m).norm() / c_mps;
        (t - array.clock.offset_s) * fs * (1.0 + array.clock.drift_ppm * 1e-6) - half
    }

    /// Geometric truth: the sample index (fractional) of `array`'s own clock at which the first
    /// sample of emission `k` reaches microphone `mic` along the straight line, speed of sound
    /// `c_mps`, nominal rate `fs`. Evaluation only (never in the product).
    pub fn arrival_on_clock(
        &self,
        k: u64,
        array: &ArrayConfig,
        mic: usize,
        c_mps: f64,
        fs: f64,
    ) -> f64 {
        let t = self.emission_s(k) + (array.mic_position(mic) - self.position_m).norm() / c_mps;
        (t - array.clock.offset_s) * fs * (1.0 + array.clock.drift_ppm * 1e-6)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::propagation::{self, PreparedSource};
    use crate::room::Image;
    use crate::sound::SourceSignal;

    fn free(absorption: f64) -> Medium<'static> {
        Medium {
            c_mps: 343.0,
            absorption_per_m_hz2: absorption,
            room: None,
            obstacles: &[],
            diffraction_ref_hz: 500.0,
        }
    }

    /// Arrival measured from a rendered signal by correlating with the exact waveform on a fine
    /// grid around the expected arrival (a measurement independent of the chip's detector).
    /// `ratio`: the waveform's samples per output sample (speaker over receiver rate).
    fn measured_arrival(out: &[f32], guess: f64, ratio: f64) -> f64 {
        let corr = |d: f64| -> f64 {
            let lo = guess.floor() as isize - 8;
            (lo..lo + aim_dsp::beacon::LEN as isize + 16)
                .filter(|&j| j >= 0 && (j as usize) < out.len())
                .map(|j| {
                    f64::from(out[j as usize])
                        * aim_dsp::beacon::waveform_at((j as f64 - d) * ratio)
                })
                .sum()
        };
        // Golden-section-free search: scan ±1 sample by 1/1000, then refine by 1e-5.
        let mut best = (f64::MIN, guess);
        for step in [1e-3, 1e-5] {
            let c = best.1;
            for i in -1000..=1000 {
                let d = c + i as f64 * step;
                let v = corr(d);
                if v > best.0 {
                    best = (v, d);
                }
            }
        }
        best.1
    }

    fn speaker() -> BeaconSpeaker {
        BeaconSpeaker {
            id: 1,
            position_m: Vector3::new(1.0, 2.0, 1.5),
            level_db: 60.0,
            period_s: 0.25,
            clock_drift_ppm: 40.0,
            start_s: 0.013,
        }
    }

    #[test]
    fn rendered_arrival_matches_geometry_and_clock() {
        // Oracle: emission time + |B − M| / c, on a receiver clock with offset and drift. The
        // rendered signal's arrival (fine correlation with the exact waveform) must match it to
        // 0.01 sample (0.2 µs) with and without air absorption (a zero-phase smoother).
        let s = speaker();
        for (absorption, mic) in
            [(0.0, Vector3::new(9.3, 5.1, 0.05)), (1.3e-9, Vector3::new(13.0, -4.0, 0.1))]
        {
            let medium = free(absorption);
            let fs = 48_000.0;
            let (offset, drift) = (0.0213, -37.0);
            let rx = Receiver {
                position: mic,
                t0_s: offset,
                dt_s: 1.0 / (fs * (1.0 + drift * 1e-6)),
                extra_delay_s: 0.0,
            };
            let mut out = vec![0.0f32; 30_000];
            s.render(&medium, &[PathKind::Image(Image::DIRECT)], &rx, &mut out);
            for k in 0..2 {
                let t = s.emission_s(k) + (mic - s.position_m).norm() / 343.0;
                let truth = (t - offset) * fs * (1.0 + drift * 1e-6);
                let ratio = (1.0 + 40e-6) / (1.0 + drift * 1e-6);
                let got = measured_arrival(&out, truth, ratio);
                assert!(
                    (got - truth).abs() < 0.01,
                    "absorption {absorption} k {k}: {got} vs {truth}"
                );
            }
        }
    }

    #[test]
    fn lagrange_would_bias_the_beacon() {
        // The same emission rendered through `propagation::render` from the waveform sampled at
        // 48 kHz (cubic Lagrange fractional delay): its arrival error depends on the
        // fractional delay. Asserted to be larger than the exact render's bound, which is why
        // the beacon is rendered in closed form.
        let fs = 48_000.0;
        let samples: Vec<f32> =
            (0..4000).map(|i| aim_dsp::beacon::waveform_at(i as f64 - 100.0) as f32).collect();
        let signal = SourceSignal { t0_s: 0.0, sample_rate_hz: fs, samples };
        let prepared = PreparedSource::new(&signal);
        let mut worst: f64 = 0.0;
        for frac in [0.1, 0.25, 0.4, 0.5] {
            let dist = (20.0 + frac) / fs * 343.0;
            let mic = Vector3::new(dist, 0.0, 0.0);
            let rx = Receiver { position: mic, t0_s: 0.0, dt_s: 1.0 / fs, extra_delay_s: 0.0 };
            let mut out = vec![0.0f32; 5000];
            propagation::render(
                &free(0.0),
                &prepared,
                &Fixed(Vector3::zeros()),
                &[PathKind::Image(Image::DIRECT)],
                &rx,
                propagation::DEFAULT_BLOCK,
                &mut out,
            );
            let truth = 100.0 + 20.0 + frac;
            worst = worst.max((measured_arrival(&out, truth, 1.0) - truth).abs());
        }
        println!("cubic Lagrange at 18 kHz: worst arrival error {worst:.4} samples");
        assert!(worst > 0.01, "{worst}");
    }
}
