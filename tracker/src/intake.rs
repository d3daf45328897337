//! Decoded wire frames → tracker inputs: sample indices become seconds (the array's clock
//! through the site's offset and drift), wire units become radians, samples and linear
//! amplitudes.

use std::collections::HashMap;

use aim_wire::{Body, Frame};

use crate::observation::{Bearing, BpfPeak, Input, Spectrum};
use crate::site::Site;

/// Converts frames of the arrays of one site.
#[derive(Clone, Debug)]
pub struct FrameConverter {
    site: Site,
    default_rate_hz: u32,
    rates: HashMap<u8, u32>,
    /// Frames from arrays missing in the site.
    pub unknown_array_frames: u64,
}

impl FrameConverter {
    /// A converter for `site`; sample rates come from each array's `Hello`, until then from
    /// the site file, else 48 kHz.
    pub fn new(site: Site) -> Self {
        let default_rate_hz = site.sample_rate_hz.unwrap_or(48_000);
        Self { site, default_rate_hz, rates: HashMap::new(), unknown_array_frames: 0 }
    }

    /// The tracker input a frame carries, if any (`Hello` updates the sample rate, `Health`
    /// carries no observation).
    pub fn convert(&mut self, frame: &Frame) -> Option<Input> {
        let id = frame.header.array_id;
        let Some(array) = self.site.array(u16::from(id)) else {
            self.unknown_array_frames += 1;
            return None;
        };
        let fs = f64::from(*self.rates.get(&id).unwrap_or(&self.default_rate_hz));
        // An output describes the samples [index, index + span): it is stamped at their middle.
        let time = |span: u32| {
            array.sample_time(frame.header.sample_index as f64 + 0.5 * f64::from(span), fs)
        };
        match &frame.body {
            Body::Hello(h) => {
                if h.sample_rate_hz > 0 {
                    self.rates.insert(id, h.sample_rate_hz);
                }
                None
            }
            Body::Doa(d) => Some(Input::Bearing(Bearing {
                t: time(d.span_samples),
                array_id: u16::from(id),
                azimuth_rad: f64::from(d.azimuth_rad()),
                zenith_rad: f64::from(d.zenith_rad()),
                residual: f64::from(d.residual_samples()),
                quality: f64::from(d.quality()),
            })),
            Body::Peaks(p) => Some(Input::Spectrum(Spectrum {
                t: time(p.span_samples),
                array_id: u16::from(id),
                // "No rotor signature": no groups (the chip's detection decision stands).
                peaks: p
                    .peaks
                    .iter()
                    .filter(|q| p.is_rotor() && q.freq_hz() > 0.0)
                    .map(|q| BpfPeak {
                        hz: f64::from(q.freq_hz()),
                        amplitude: 10f64.powf(f64::from(q.amplitude_db()) / 20.0),
                    })
                    .collect(),
            })),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::site::ArrayPose;
    use aim_wire::{Doa, Header, Hello, Peak, Peaks};

    #[test]
    fn units_and_times() {
        let mut pose = ArrayPose::new(3, [0.0; 3], 0.0, 0.0, 0.0);
        pose.clock_offset_s = 1.0;
        let site = Site { arrays: vec![pose], room: None, sample_rate_hz: None };
        let mut c = FrameConverter::new(site);
        let header = Header { array_id: 3, seq: 0, sample_index: 16_000 };
        let hello =
            Frame { header, body: Body::Hello(Hello::new([0, 1, 0], 16_000, 1024, &[[0.0, 0.0]])) };
        assert!(c.convert(&hello).is_none());
        let doa = Doa { span_samples: 1600, ..Doa::new(0.5, 1.0, 0.25, 0.8) };
        let Some(Input::Bearing(b)) = c.convert(&Frame { header, body: Body::Doa(doa) }) else {
            panic!()
        };
        // 16 000 samples at 16 kHz after an offset of 1 s, stamped 800 samples later.
        assert!((b.t - 2.05).abs() < 1e-12, "{}", b.t);
        assert!((b.azimuth_rad - 0.5).abs() < 2e-4 && (b.zenith_rad - 1.0).abs() < 2e-4);
        assert!((b.residual - 0.25).abs() < 1e-6 && (b.quality - 0.8).abs() < 0.004);
        let mut peaks = heapless::Vec::new();
        peaks.push(Peak::new(328.25, -20.0, 1.0)).unwrap();
        let p = Peaks {
            span_samples: 0,
            bpf_chz: 32825,
            peaks,
            detection: aim_wire::Detection::Rotor,
            quality: [200].into_iter().collect(),
        };
        let Some(Input::Spectrum(s)) = c.convert(&Frame { header, body: Body::Peaks(p.clone()) })
        else {
            panic!()
        };
        assert!((s.peaks[0].hz - 328.25).abs() < 1e-4 && (s.peaks[0].amplitude - 0.1).abs() < 1e-6);
        let none = Peaks { detection: aim_wire::Detection::NoRotor, ..p.clone() };
        let Some(Input::Spectrum(s)) = c.convert(&Frame { header, body: Body::Peaks(none) }) else {
            panic!()
        };
        assert!(s.peaks.is_empty(), "no rotor signature carries no groups");
        let stranger = Frame { header: Header { array_id: 9, ..header }, body: Body::Doa(doa) };
        assert!(c.convert(&stranger).is_none() && c.unknown_array_frames == 1);
    }
}
