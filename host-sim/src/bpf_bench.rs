//! The BPF detector on realistic sound: drones that are not clean combs and non-drone sources,
//! in reverberant halls over a room's background, scored from the `Peaks` frames' bytes read
//! through the tracker's intake (the path `aim track` uses).
//!
//! A **drone case** flies an airframe ([`airframes`]) back and forth (2 m legs at 1 m/s with
//! pauses: rotor speeds change with the manoeuvres, hold per-rotor trim offsets of up to ±4 %
//! and wander smoothly by up to ±2 % within seconds, [`wander`]). Its sound is the simulator's propeller model per rotor
//! (`sound::propeller`: BPF harmonics, shaft-rate lines, BPF-modulated broadband) plus the
//! motor whine at the electrical frequency (7 pole pairs × shaft rate, two lines), heard at
//! `distance_m` in a hall: direct sound `1/r`, the [`Hall`] reverberator's tail at the
//! diffuse-field level `(r / r_c)²` of the direct (critical distance
//! `r_c = 0.057 √(V / RT60)`), over [`background`] noise (brown/pink tilt, mains hum) at
//! `background_db`. The mono pressure feeds all six microphones of a ReSpeaker 6 at 16 kHz
//! (a plane wave from the zenith: the BPF path sees the mean of the microphones).
//!
//! Truth: per rotor, blades × its speed averaged over the frame's analysis window with the
//! Hann window's power as weight ([`true_bpf`]). A frame is
//! **correct** when its BPF lies within 2 Hz of some rotor's; an **octave error** when instead
//! it lies within 2 % of ½, ⅓, 2 or 3 times some rotor's.
//!
//! `AIM_BPF_DEBUG=1` prints every drone frame's BPF and the rotors' true BPFs on stderr.
use nalgebra::Vector3;

use aim_dsp::{Config, Geometry, Output, Pipeline};
use aim_tracker::intake::{Intake, IntakeConfig, Released};
use aim_tracker::observation::Input;
use aim_tracker::site::{ArrayPose, Site};
use aim_wire::{from_dsp, Body, Deframer, Encoder, MAX_ENCODED_LEN};

use crate::flight::{fly, ControlGains, FlightLog, Span};
use crate::path::{FlightPlan, Heading};
use crate::profile::{Airframe, DroneProfile};
use crate::sound::propeller;
use crate::tonal::{add, background, scale_to_spl, DiffuseHall, Negative};

/// Sample rate of the bench, Hz.
pub const FS: u32 = 16_000;

/// The airframes of the bench: (name, profile). BPFs 150–700 Hz, two- and three-blade,
/// shaft-rate lines 8–12 dB below the BPF (the half-BPF line of a two-blade rotor), the ESC's
/// fast speed-loop error (0.5 %, 0.1 s correlation) in the flight; the slow wander and the
/// rotors' trim differences are added by [`wander`].
pub fn airframes() -> Vec<DroneProfile> {
    let base = DroneProfile::dji_mini_2();
    let make = |name: &str, blades: u32, rotor_hz: f64, mass: f64, shaft_db: f64| DroneProfile {
        name: name.into(),
        blades,
        hover_rotor_hz: rotor_hz,
        max_rotor_hz: 2.0 * rotor_hz,
        mass_kg: mass,
        rotor_jitter: 0.005,
        rotor_jitter_time_s: 0.1,
        shaft_line_db: shaft_db,
        harmonic_slope_db: -3.0,
        ..base.clone()
    };
    vec![
        make("mini-2blade-328", 2, 164.0, 0.249, -8.0),
        make("bebop-3blade-400", 3, 133.0, 0.40, -10.0),
        make("mambo-2blade-620", 2, 310.0, 0.063, -10.0),
        make("large-2blade-165", 2, 82.0, 1.2, -12.0),
        make("fpv-3blade-690", 3, 230.0, 0.35, -10.0),
    ]
}

/// Trim spread of the rotors' speeds: each rotor holds its own offset, uniform within ± this
/// fraction (centre of gravity, motor and propeller differences; the Mambo's four lines at
/// 590–650 Hz are ±5 %).
pub const TRIM_SPREAD: f64 = 0.04;
/// Slow wander of each rotor's speed: standard deviation (fraction of the speed) and
/// correlation time, s; smoothed by two one-pole low-passes of [`WANDER_SMOOTH_S`] (the motor
/// and propeller inertia and the speed loop).
///
/// 1 % over 1 s (speeds within ±2 % at 2σ, changing within seconds; was 2.5 % over 2 s). No
/// published per-rotor speed record of an indoor hover was at hand, so the figure follows
/// from what the airframe's own loops allow. Thrust goes as speed², so a collective wander
/// of σ changes the vertical acceleration by 2σ·g: 1 % is 0.2 m/s², held for the 1 s
/// correlation time about 0.1 m of height, the scatter of a consumer drone's altitude hold
/// indoors; 2.5 % over 2 s would be 0.5 m/s² and about 1 m, which an altitude-hold loop
/// with a bandwidth near 1 Hz does not let happen. A differential wander is a torque the
/// attitude loop (tens of Hz) cancels within a fraction of a second: what remains between
/// rotors is the steady trim ([`TRIM_SPREAD`]) and the fast speed-loop error of the flight
/// model (0.5 %, 0.1 s). At 2.5 % / 2 s a 600 Hz BPF moved 15–20 Hz within one 0.512 s
/// window, so no rotor line would be resolvable on a 1 s window, while the four rotor
/// lines of a real Mambo (590–650 Hz) are (issue 19); the issue's own synthetic check uses
/// ±0.3 %.
pub const WANDER: (f64, f64) = (0.01, 1.0);
/// Time constant of the wander's smoothing, s.
pub const WANDER_SMOOTH_S: f64 = 0.25;

/// Applies each rotor's trim offset ([`TRIM_SPREAD`]) and slow wander ([`WANDER`]) to the
/// rotor speeds of `log` (the sound and the truth both read them; the flight's dynamics are
/// not re-flown: the bench scores the spectrum only).
pub fn wander(log: &mut FlightLog, seed: u64) {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x5EED_7A1D);
    let rotors = log.samples.first().map_or(0, |s| s.rotor_hz.len());
    let dt = log.dt_s;
    let (sigma, tau) = WANDER;
    let decay = (-dt / tau).exp();
    let kick = sigma * (1.0 - decay * decay).sqrt();
    let smooth = 1.0 - (-dt / WANDER_SMOOTH_S).exp();
    for r in 0..rotors {
        let trim = rng.random_range(-TRIM_SPREAD..=TRIM_SPREAD);
        // Start the process in its stationary state.
        let mut ou = sigma * gauss(&mut rng);
        let (mut s1, mut s2) = (ou, ou);
        for sample in &mut log.samples {
            ou = ou * decay + kick * gauss(&mut rng);
            s1 += smooth * (ou - s1);
            s2 += smooth * (s1 - s2);
            sample.rotor_hz[r] *= 1.0 + trim + s2;
        }
    }
}

fn gauss(rng: &mut impl rand::Rng) -> f64 {
    // Box–Muller.
    let u1: f64 = rng.random_range(f64::EPSILON..1.0);
    let u2: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Seeds the detector's constants were chosen on (`--seeds tune`; seeds 3–16 were used as
/// extra tuning seeds through `bpf_cache`).
pub const TUNING_SEEDS: [u64; 2] = [1, 2];
/// Seeds the bench reports (`--seeds eval`), declared in session 16 before any run on them.
/// The bench's hall became [`crate::tonal::DiffuseHall`] in that session; 101–103, the
/// evaluation seeds until then, had been looked at while the detector was tuned, and 201–204
/// were run once with a line search of ±0.4 % before it was set to ±0.3 % on tuning seeds
/// 9–16 (BENCHMARKS.md, issue 19, session 16).
pub const EVALUATION_SEEDS: [u64; 4] = [301, 302, 303, 304];

/// Frames at the start of a clip that are not scored: the detector reports a comb only after
/// it has passed in `aim_dsp::comb::MIN_AGE` consecutive analyses (1.28 s of sound).
pub const SETTLING_FRAMES: usize = aim_dsp::comb::MIN_AGE as usize - 1;

/// A hall: reverberation time and volume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HallSpec {
    /// RT60, s.
    pub rt60_s: f64,
    /// Volume, m³.
    pub volume_m3: f64,
}

impl HallSpec {
    /// Critical distance, m.
    pub fn critical_distance_m(self) -> f64 {
        0.057 * (self.volume_m3 / self.rt60_s).sqrt()
    }
}

/// The halls of the bench: a gym-like hall (0.8 s, 3000 m³) and a reverberant one (1.6 s,
/// 6000 m³).
pub const HALLS: [HallSpec; 2] =
    [HallSpec { rt60_s: 0.8, volume_m3: 3000.0 }, HallSpec { rt60_s: 1.6, volume_m3: 6000.0 }];

/// Background levels of the bench, dB SPL.
pub const BACKGROUNDS_DB: [f64; 3] = [55.0, 62.0, 70.0];

/// What one clip's frames scored.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Score {
    /// Peaks frames (after the first [`SETTLING_FRAMES`] of the clip, before which the detector
    /// cannot report a comb).
    pub frames: usize,
    /// Frames with a BPF.
    pub with_bpf: usize,
    /// Frames whose BPF is within 2 Hz of a true rotor BPF.
    pub correct: usize,
    /// Frames whose BPF is an octave (½, ⅓, 2, 3 ×) of a true rotor BPF.
    pub octave: usize,
}

impl std::ops::AddAssign for Score {
    fn add_assign(&mut self, o: Self) {
        self.frames += o.frames;
        self.with_bpf += o.with_bpf;
        self.correct += o.correct;
        self.octave += o.octave;
    }
}

/// The groups of every `Peaks` frame as the tracker's intake delivers them: (frame time s,
/// group frequencies Hz strongest first; empty for "no rotor signature").
pub fn frames_through_intake(pressure: &[f64]) -> anyhow::Result<Vec<(f64, Vec<f64>)>> {
    let geometry = Geometry::respeaker_6mic();
    let mics = geometry.len();
    let config = Config::new(geometry, FS);
    let mut pipeline = Pipeline::new(&config)?;
    let mut encoder = Encoder::new(1);
    let mut bytes = Vec::new();
    let mut frame = [0u8; MAX_ENCODED_LEN];
    let hello = Body::Hello(from_dsp::hello(&config, [0, 1, 0]));
    let n = encoder.encode(0, hello, &mut frame).map_err(|e| anyhow::anyhow!("{e:?}"))?;
    bytes.extend_from_slice(&frame[..n]);
    let mut words = Vec::with_capacity(256 * 8);
    let mut error = None;
    for chunk in pressure.chunks(256) {
        words.clear();
        for &p in chunk {
            let w = crate::tdm_word(p as f32, crate::DEFAULT_FULL_SCALE_PA);
            words.extend(std::iter::repeat_n(w, mics));
            words.extend(std::iter::repeat_n(0, 8 - mics));
        }
        pipeline.push(&words, &mut |o| {
            if !matches!(o, Output::Peaks(_)) {
                return;
            }
            match from_dsp::encode_output(&mut encoder, &o, &Default::default(), &mut frame) {
                Ok(n) => bytes.extend_from_slice(&frame[..n]),
                Err(e) => error = Some(e),
            }
        });
    }
    if let Some(e) = error {
        anyhow::bail!("encoding a Peaks frame: {e:?}");
    }
    let site = Site {
        arrays: vec![ArrayPose::new(1, [0.0; 3], 0.0, 0.0, 0.0)],
        room: None,
        sample_rate_hz: Some(FS),
    };
    let mut intake = Intake::new(site, IntakeConfig::default());
    let mut deframer: Deframer = Deframer::default();
    let mut out = Vec::new();
    let mut sink = |r: Released| {
        if let Released::Input(Input::Spectrum(s)) = r {
            out.push((s.t, s.peaks.iter().map(|p| p.hz).collect()));
        }
    };
    for b in bytes {
        if let Some(Ok(f)) = deframer.push(b) {
            intake.push(&f, &mut sink).map_err(|e| anyhow::anyhow!("{e}"))?;
        }
    }
    intake.finish(&mut sink);
    Ok(out)
}

/// Hall, distance and background applied to a source's pressure at 1 m.
pub fn in_hall(
    source: &[f64],
    hall: HallSpec,
    distance_m: f64,
    background_db: f64,
    seed: u64,
) -> Vec<f64> {
    let direct: Vec<f64> = source.iter().map(|v| v / distance_m).collect();
    let mut tail = DiffuseHall::new(hall.rt60_s, hall.volume_m3, f64::from(FS), seed ^ 0x7A11)
        .process(&direct);
    let p_direct = direct.iter().map(|v| v * v).sum::<f64>() / direct.len().max(1) as f64;
    let p_tail = tail.iter().map(|v| v * v).sum::<f64>() / tail.len().max(1) as f64;
    let want = p_direct * (distance_m / hall.critical_distance_m()).powi(2);
    if p_tail > 0.0 {
        let g = (want / p_tail).sqrt();
        tail.iter_mut().for_each(|v| *v *= g);
    }
    let mut x = direct;
    add(&mut x, &tail, 1.0);
    add(&mut x, &background(f64::from(FS), source.len(), background_db, seed ^ 0xB6), 1.0);
    x
}

/// A back-and-forth flight of `profile` for `duration_s`.
pub fn flight(profile: &DroneProfile, duration_s: f64, seed: u64) -> anyhow::Result<FlightLog> {
    let a = Vector3::new(0.0, 0.0, 1.5);
    let b = Vector3::new(2.0, 0.0, 1.5);
    let plan = FlightPlan::new(&[a, b, a, b, a, b], 1.0, 1.5, 1.0, 0.5, 5.0, Heading::Fixed)
        .map_err(|e| anyhow::anyhow!(e))?;
    let span = Span { t0_s: 0.0, t1_s: duration_s + 1.0, dt_s: 0.005 };
    let airframe = Airframe::nominal(profile.rotor_count());
    let mut log = fly(profile, &airframe, &plan, 0.0, &ControlGains::default(), span, seed);
    wander(&mut log, seed);
    Ok(log)
}

/// The drone's sound at 1 m: propellers and motor whine, `duration_s` at [`FS`].
pub fn drone_sound(
    profile: &DroneProfile,
    log: &FlightLog,
    duration_s: f64,
    seed: u64,
) -> Vec<f64> {
    let mut x = vec![0.0; (duration_s * f64::from(FS)) as usize];
    for rotor in rotor_sounds(profile, log, duration_s, seed) {
        add(&mut x, &rotor, 1.0);
    }
    x
}

/// Each rotor's sound at 1 m (propeller and its motor's whine), `duration_s` at [`FS`].
pub fn rotor_sounds(
    profile: &DroneProfile,
    log: &FlightLog,
    duration_s: f64,
    seed: u64,
) -> Vec<Vec<f64>> {
    let fs = f64::from(FS);
    let len = (duration_s * fs) as usize;
    (0..profile.rotor_count())
        .map(|r| {
            let seed = seed.wrapping_add(r as u64 * 7919);
            let s = propeller(profile, 0.0, log, r, 0.0, fs, len, seed);
            let mut rotor: Vec<f64> = s.samples.iter().map(|&v| f64::from(v)).collect();
            let rms = (rotor.iter().map(|v| v * v).sum::<f64>() / len as f64).sqrt();
            // Motor whine: 7 pole pairs, the electrical line and its double, 12 and 18 dB
            // below the rotor's sound.
            let mut phase = 0.0f64;
            for (t, v) in rotor.iter_mut().enumerate() {
                let f = 7.0 * log.rotor_hz(r, t as f64 / fs);
                let tau = std::f64::consts::TAU;
                *v += rms * (0.25 * (tau * phase).sin() + 0.125 * (2.0 * tau * phase + 1.0).sin());
                phase += f / fs;
                phase -= phase.floor();
            }
            rotor
        })
        .collect()
}

/// The true BPF of rotor `r` in the analysis window centred on `t_mid`: blades × its speed,
/// averaged with the weight the Hann-windowed spectrum gives each instant (the window squared).
pub fn true_bpf(log: &FlightLog, r: usize, blades: f64, t_mid: f64) -> f64 {
    let window_s = 4096.0 / 8000.0;
    let n = 64;
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..n {
        let x = (i as f64 + 0.5) / n as f64;
        let w = (std::f64::consts::PI * x).sin().powi(4);
        num += w * log.rotor_hz(r, t_mid - window_s / 2.0 + window_s * x);
        den += w;
    }
    blades * num / den
}

/// Scores one drone clip.
pub fn drone_case(
    profile: &DroneProfile,
    hall: HallSpec,
    distance_m: f64,
    background_db: f64,
    duration_s: f64,
    seed: u64,
) -> anyhow::Result<Score> {
    let log = flight(profile, duration_s, seed)?;
    let source = drone_sound(profile, &log, duration_s, seed);
    let heard = in_hall(&source, hall, distance_m, background_db, seed);
    let frames = frames_through_intake(&heard)?;
    let blades = f64::from(profile.blades);
    let mut score = Score::default();
    for (t_mid, groups) in frames.iter().skip(SETTLING_FRAMES) {
        let t_mid = *t_mid;
        score.frames += 1;
        let Some(&f) = groups.first() else { continue };
        score.with_bpf += 1;
        let truths: Vec<f64> =
            (0..profile.rotor_count()).map(|r| true_bpf(&log, r, blades, t_mid)).collect();
        if std::env::var_os("AIM_BPF_DEBUG").is_some() {
            eprintln!("{} t {t_mid:.2} f {f:.1} truths {truths:.1?}", profile.name);
        }
        match classify(f, &truths) {
            Verdict::Correct => score.correct += 1,
            Verdict::Octave => score.octave += 1,
            Verdict::Wrong => {}
        }
    }
    Ok(score)
}

/// How a frame's BPF compares with the rotors' true BPFs (module doc: the scoring).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Within 2 Hz of some rotor's BPF.
    Correct,
    /// Not correct, but within 2 % of ½, ⅓, 2 or 3 times some rotor's.
    Octave,
    /// Neither.
    Wrong,
}

/// Scores a frame's BPF `bpf_hz` against the rotors' true BPFs `truths_hz` (both Hz).
pub fn classify(bpf_hz: f64, truths_hz: &[f64]) -> Verdict {
    let f = bpf_hz;
    if truths_hz.iter().any(|&b| (f - b).abs() <= 2.0) {
        Verdict::Correct
    } else if truths_hz
        .iter()
        .any(|&b| [0.5, 1.0 / 3.0, 2.0, 3.0].iter().any(|&k| (f - k * b).abs() <= 0.02 * k * b))
    {
        Verdict::Octave
    } else {
        Verdict::Wrong
    }
}

/// Scores one non-drone clip: the source at `level_db` at the array (direct), in `hall` at
/// 3 m, over the background.
pub fn negative_case(
    kind: Negative,
    hall: HallSpec,
    level_db: f64,
    background_db: f64,
    duration_s: f64,
    seed: u64,
) -> anyhow::Result<Score> {
    let fs = f64::from(FS);
    let len = (duration_s * fs) as usize;
    let distance_m: f64 = 3.0;
    let mut source = kind.signal(fs, len, level_db, seed);
    // `level_db` is the direct sound at the array: the source at 1 m is `distance_m` louder.
    scale_to_spl(&mut source, level_db + 20.0 * distance_m.log10());
    let heard = in_hall(&source, hall, distance_m, background_db, seed);
    let frames = frames_through_intake(&heard)?;
    let mut score = Score::default();
    for (_, groups) in frames.iter().skip(SETTLING_FRAMES) {
        score.frames += 1;
        score.with_bpf += usize::from(!groups.is_empty());
    }
    Ok(score)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn airframes_fly_and_span_the_bpf_range() {
        let bpfs: Vec<f64> =
            airframes().iter().map(|p| f64::from(p.blades) * p.hover_rotor_hz).collect();
        assert!(bpfs.iter().all(|&b| (150.0..=700.0).contains(&b)), "{bpfs:?}");
        for p in airframes() {
            p.validate().unwrap();
        }
    }
}
