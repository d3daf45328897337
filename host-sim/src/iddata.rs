//! Labelled recordings for drone identification (`host-sim id-dataset`): one folder per class
//! (the six [`DroneType`]s and `none`), one WAV per clip, as a user would bring recordings of
//! their own to `aim id train`.
//!
//! A drone clip ([`drone_scene`]) is one drone drawn from its type's population
//! ([`Draw`]: airframe spread, manoeuvre ±30 %, Doppler of cruise) at a distance uniform in
//! `distance_m`, in a hall: the direct sound falls as 1/r, the reverberant tail (a
//! Freeverb-style hall of RT60 uniform in 0.3–1.5 s, [`Hall`]) has the power of a diffuse field
//! of critical distance `r_c` uniform in 2–6 m (tail/direct power `(r / r_c)²`), the room's
//! background ([`room_background`]: the classic room noise, or coloured noise of random
//! spectral tilt with 0–3 random bands of noise, [`RoomNoise`]) is uniform in `background_db`, and with probability
//! `second_source_probability` a second tonal source (desk fan, pump, vacuum, machinery,
//! vehicle or mains hum, [`Negative`]) plays at 55–70 dB. A `none` clip is one of the nine
//! [`Negative`]s at 55–75 dB with its hall tail (direct-to-reverberant ratio uniform in
//! −10..+5 dB) over the background, or (one clip in ten) the background alone.
//!
//! Every clip is simulated 0.5 s longer and the first 0.5 s dropped, so the hall's tail is
//! established from the first sample. Channels beyond the first carry the same sound plus
//! their own microphone self-noise (30 dB SPL, white). Samples are 16-bit integers with full
//! scale at 2 Pa (100 dB SPL peak), or 32-bit float pascals.
use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _};
use rand::{rngs::StdRng, Rng, SeedableRng};

use crate::drones::{Draw, DroneType};
use crate::roomnoise::RoomNoise;
use crate::sound::spl_to_rms_pa;
use crate::tonal::{add, scale_to_spl, Hall, Negative};

/// Name of the no-drone class.
pub const NONE_CLASS: &str = "none";
/// Pressure of 16-bit full scale, Pa.
pub const I16_FULL_SCALE_PA: f64 = 2.0;
/// Seconds simulated and dropped before each clip (the hall's tail builds up).
const PRE_ROLL_S: f64 = 0.5;

/// Sample format of the written WAV files.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SampleFormat {
    /// 16-bit integers, full scale 2 Pa (100 dB SPL peak; `I16_FULL_SCALE_PA`).
    I16,
    /// 32-bit float, pascals.
    F32,
}

/// What a dataset holds.
#[derive(Clone, Debug)]
pub struct Options {
    /// Clips per class.
    pub clips_per_class: usize,
    /// First clip seed; clip i of every class has seed `seed_base + i` (mixed with the class).
    pub seed_base: u64,
    /// Clip length, s.
    pub secs: f64,
    /// Sample rate, Hz.
    pub rate_hz: u32,
    /// Channels per file.
    pub channels: u16,
    /// Sample format.
    pub format: SampleFormat,
    /// Drone distance range, m.
    pub distance_m: (f64, f64),
    /// Background level range, dB SPL.
    pub background_db: (f64, f64),
    /// Probability of a second tonal source in a drone clip.
    pub second_source_probability: f64,
    /// Classes to write (names of [`class_names`]); empty: all. A class's clips are the same
    /// whichever others are written.
    pub only: Vec<String>,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            clips_per_class: 100,
            seed_base: 1000,
            secs: 1.0,
            rate_hz: 16_000,
            channels: 1,
            format: SampleFormat::I16,
            distance_m: (3.0, 15.0),
            background_db: (55.0, 70.0),
            second_source_probability: 0.3,
            only: Vec::new(),
        }
    }
}

impl Options {
    /// Checks the options; names the first bad one.
    pub fn validate(&self) -> anyhow::Result<()> {
        if self.clips_per_class == 0 {
            bail!("--clips must be at least 1");
        }
        if self.seed_base.checked_add(self.clips_per_class as u64 - 1).is_none() {
            bail!(
                "--seed {} + --clips {} runs past the largest seed",
                self.seed_base,
                self.clips_per_class
            );
        }
        // `aim id` reads 0.25 s or more, at 16 or 48 kHz.
        if !(self.secs.is_finite() && (0.25..=600.0).contains(&self.secs)) {
            bail!("--secs must be in 0.25..=600 (aim id reads 0.25 s or more), got {}", self.secs);
        }
        if ![16_000, 48_000].contains(&self.rate_hz) {
            bail!(
                "--rate must be 16000 or 48000 Hz (the rates aim id reads), got {}",
                self.rate_hz
            );
        }
        if self.channels == 0 || self.channels > 16 {
            bail!("--channels must be in 1..=16, got {}", self.channels);
        }
        let (a, b) = self.distance_m;
        if !(a.is_finite() && b.is_finite() && 0.5 <= a && a <= b && b <= 1000.0) {
            bail!("distance range must satisfy 0.5 <= min <= max <= 1000 m, got {a}..{b}");
        }
        let (a, b) = self.background_db;
        // 16-bit clips saturate at 2 Pa (`I16_FULL_SCALE_PA`, 100 dB SPL peak); a background
        // near it leaves no room for the drone.
        if !(a.is_finite() && b.is_finite() && 0.0 <= a && a <= b && b <= MAX_BACKGROUND_DB) {
            bail!(
                "background range must satisfy 0 <= min <= max <= {MAX_BACKGROUND_DB} dB SPL, got {a}..{b}"
            );
        }
        if !(0.0..=1.0).contains(&self.second_source_probability) {
            bail!("--second-source must be in 0..=1");
        }
        if let Some(bad) = self.only.iter().find(|c| !class_names().contains(&c.as_str())) {
            bail!("unknown class {bad}; the classes are {}", class_names().join(", "));
        }
        Ok(())
    }
}

/// Loudest background `host-sim id-dataset` accepts, dB SPL.
pub const MAX_BACKGROUND_DB: f64 = 90.0;

/// A seed of its own for clip `seed` of class `class` (SplitMix64 of both).
pub fn clip_seed(class: usize, seed: u64) -> u64 {
    let mut z = seed ^ ((class as u64 + 1) << 48) ^ 0x9E37_79B9_7F4A_7C15;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn uniform(rng: &mut StdRng, (a, b): (f64, f64)) -> f64 {
    if b > a {
        rng.random_range(a..b)
    } else {
        a
    }
}

fn power(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>() / x.len().max(1) as f64
}

/// `x` plus its hall tail at `tail_to_direct` power ratio, the pre-roll dropped.
fn with_hall(x: &[f64], fs: f64, rt60_s: f64, tail_to_direct: f64, pre: usize) -> Vec<f64> {
    let tail = Hall::new(rt60_s, fs).process(x);
    let (pd, pt) = (power(&x[pre..]), power(&tail[pre..]));
    let g = if pt > 0.0 { (pd * tail_to_direct / pt).sqrt() } else { 0.0 };
    x[pre..].iter().zip(&tail[pre..]).map(|(a, b)| a + g * b).collect()
}

/// Sources that may play as a second tonal source in a drone clip.
const SECOND_SOURCES: [Negative; 6] = [
    Negative::DeskFan,
    Negative::Pump,
    Negative::Vacuum,
    Negative::Machinery,
    Negative::Vehicle,
    Negative::MainsHum,
];

/// The first draws of a drone clip: the airframe, the distance (m) and the background (dB SPL).
fn drone_draws(ty: DroneType, rng: &mut StdRng, o: &Options) -> (Draw, f64, f64) {
    let draw = Draw::new(ty, rng.random());
    let distance = uniform(rng, o.distance_m);
    let bg_db = uniform(rng, o.background_db);
    (draw, distance, bg_db)
}

/// The distance (m) and background (dB SPL) of the drone clip [`drone_scene`] makes of `seed`.
pub fn drone_conditions(ty: DroneType, seed: u64, o: &Options) -> (f64, f64) {
    let (_, distance, bg_db) = drone_draws(ty, &mut StdRng::seed_from_u64(seed), o);
    (distance, bg_db)
}

/// A drone clip at the listener, Pa, `len` samples at `fs` (module docs).
pub fn drone_scene(ty: DroneType, seed: u64, fs: f64, len: usize, o: &Options) -> Vec<f64> {
    let mut rng = StdRng::seed_from_u64(seed);
    let (draw, distance, bg_db) = drone_draws(ty, &mut rng, o);
    let rt60 = rng.random_range(0.3..1.5);
    let rc = rng.random_range(2.0..6.0);
    let pre = (PRE_ROLL_S * fs) as usize;
    let total = len + pre;
    let direct: Vec<f64> =
        draw.sound(fs, total, rng.random()).iter().map(|v| v / distance).collect();
    let mut x = with_hall(&direct, fs, rt60, (distance / rc).powi(2), pre);
    add(&mut x, &room_background(fs, len, bg_db, rng.random()), 1.0);
    if rng.random::<f64>() < o.second_source_probability {
        let src = SECOND_SOURCES[rng.random_range(0..SECOND_SOURCES.len())];
        let spl = rng.random_range(55.0..70.0);
        add(&mut x, &src.signal(fs, len, spl, rng.random()), 1.0);
    }
    x
}

/// A no-drone clip at the listener, Pa (module docs).
pub fn none_scene(seed: u64, fs: f64, len: usize, o: &Options) -> Vec<f64> {
    let mut rng = StdRng::seed_from_u64(seed);
    let bg_db = uniform(&mut rng, o.background_db);
    let mut x = if rng.random::<f64>() < 0.1 {
        vec![0.0; len]
    } else {
        let src = Negative::ALL[rng.random_range(0..Negative::ALL.len())];
        let spl = rng.random_range(55.0..75.0);
        let pre = (PRE_ROLL_S * fs) as usize;
        let mut s = src.signal(fs, len + pre, spl, rng.random());
        let drr_db: f64 = rng.random_range(-10.0..5.0);
        s = with_hall(&s, fs, rng.random_range(0.3..1.5), 10f64.powf(-drr_db / 10.0), pre);
        scale_to_spl(&mut s, spl);
        s
    };
    add(&mut x, &room_background(fs, len, bg_db, rng.random()), 1.0);
    x
}

/// The room's background of a clip, drawn from `seed` alone ([`RoomNoise`]: classic room
/// noise, or coloured noise of random tilt with random bands), at `spl_db`.
pub fn room_background(fs: f64, len: usize, spl_db: f64, seed: u64) -> Vec<f64> {
    let mut rng = StdRng::seed_from_u64(seed);
    RoomNoise::draw(&mut rng).signal(fs, len, spl_db, rng.random())
}

/// Class names in order: the six drone types, then `none`.
pub fn class_names() -> Vec<&'static str> {
    DroneType::ALL.iter().map(|t| t.name()).chain([NONE_CLASS]).collect()
}

/// Writes `x` (Pa) as a WAV of `o.channels` channels (extra channels with self-noise).
fn write_clip(path: &Path, x: &[f64], o: &Options, seed: u64) -> anyhow::Result<()> {
    let spec = hound::WavSpec {
        channels: o.channels,
        sample_rate: o.rate_hz,
        bits_per_sample: match o.format {
            SampleFormat::I16 => 16,
            SampleFormat::F32 => 32,
        },
        sample_format: match o.format {
            SampleFormat::I16 => hound::SampleFormat::Int,
            SampleFormat::F32 => hound::SampleFormat::Float,
        },
    };
    let mut noise = crate::filter::Gaussian::new(StdRng::seed_from_u64(seed ^ 0x5eed));
    let self_noise = spl_to_rms_pa(30.0);
    let mut w = hound::WavWriter::create(path, spec)
        .with_context(|| format!("cannot create {}", path.display()))?;
    for &v in x {
        for c in 0..o.channels {
            let s = if c == 0 { v } else { v + self_noise * noise.sample() };
            match o.format {
                SampleFormat::I16 => {
                    let q = (s / I16_FULL_SCALE_PA * 32767.0).round().clamp(-32768.0, 32767.0);
                    w.write_sample(q as i16)?;
                }
                SampleFormat::F32 => w.write_sample(s as f32)?,
            }
        }
    }
    w.finalize().with_context(|| format!("cannot finish {}", path.display()))?;
    Ok(())
}

/// Writes the dataset under `dir` (`dir/<class>/<class>-<seed>.wav`); returns the files
/// written per class.
pub fn write_dataset(dir: &Path, o: &Options) -> anyhow::Result<Vec<(String, Vec<PathBuf>)>> {
    o.validate()?;
    let fs = f64::from(o.rate_hz);
    let len = (o.secs * fs).round() as usize;
    let mut out = Vec::new();
    for (class, name) in class_names().into_iter().enumerate() {
        if !o.only.is_empty() && !o.only.iter().any(|c| c == name) {
            continue;
        }
        let folder = dir.join(name);
        std::fs::create_dir_all(&folder)
            .with_context(|| format!("cannot create {}", folder.display()))?;
        let mut files = Vec::new();
        for i in 0..o.clips_per_class {
            let seed = o.seed_base + i as u64;
            let s = clip_seed(class, seed);
            let x = match DroneType::ALL.get(class) {
                Some(&ty) => drone_scene(ty, s, fs, len, o),
                None => none_scene(s, fs, len, o),
            };
            let path = folder.join(format!("{name}-{seed}.wav"));
            write_clip(&path, &x, o, s)?;
            files.push(path);
        }
        out.push((name.to_string(), files));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sound::rms_pa_to_spl;

    /// A drone clip's level: at least the background's, and its direct sound as the 1/r law
    /// says (checked on a drone without background: the drone alone at 10 m).
    #[test]
    fn scenes_have_their_levels() {
        let o = Options { background_db: (60.0, 60.0), ..Options::default() };
        let fs = 16_000.0;
        let x = none_scene(4, fs, 16_000, &o);
        assert!(rms_pa_to_spl(power(&x).sqrt()) >= 59.0);
        // Background far below the drone, no hall tail to speak of at 1 m.
        let quiet = Options {
            background_db: (0.0, 0.0),
            distance_m: (1.0, 1.0),
            second_source_probability: 0.0,
            ..Options::default()
        };
        let x = drone_scene(DroneType::Hexa, 5, fs, 16_000, &quiet);
        let spl = rms_pa_to_spl(power(&x).sqrt());
        // 83 dB ± population spread (±4 dB of manoeuvre level, rc ≥ 2 m adds ≤ 1 dB).
        assert!((spl - 83.0).abs() < 6.0, "{spl}");
    }

    #[test]
    fn dataset_folders_files_and_bad_options() {
        let dir = std::env::temp_dir().join(format!("aim-iddata-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let o = Options { clips_per_class: 2, secs: 0.25, channels: 2, ..Options::default() };
        let written = write_dataset(&dir, &o).unwrap();
        assert_eq!(written.len(), 7);
        for (name, files) in &written {
            assert_eq!(files.len(), 2);
            let r = hound::WavReader::open(&files[0]).unwrap();
            assert_eq!(r.spec().channels, 2);
            assert_eq!(r.spec().sample_rate, 16_000);
            assert_eq!(r.len(), 2 * 4000, "{name}");
        }
        // One class alone: the same clip, byte for byte.
        let dir1 = dir.with_extension("none");
        let only = Options { only: vec![NONE_CLASS.to_string()], ..o.clone() };
        let one = write_dataset(&dir1, &only).unwrap();
        assert_eq!(one.len(), 1);
        assert_eq!(std::fs::read(&one[0].1[1]).unwrap(), std::fs::read(&written[6].1[1]).unwrap());
        std::fs::remove_dir_all(&dir1).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        let unknown = Options { only: vec!["blimp".into()], ..Options::default() };
        assert!(write_dataset(&dir, &unknown).unwrap_err().to_string().contains("blimp"));
        let bad = Options { clips_per_class: 0, ..Options::default() };
        assert!(write_dataset(&dir, &bad).unwrap_err().to_string().contains("--clips"));
        // What `aim id` could not read, or a seed range that wraps, is refused up front.
        let rate = Options { rate_hz: 44_100, ..Options::default() };
        assert!(write_dataset(&dir, &rate).unwrap_err().to_string().contains("--rate"));
        let short = Options { secs: 0.1, ..Options::default() };
        assert!(write_dataset(&dir, &short).unwrap_err().to_string().contains("--secs"));
        let loud = Options { background_db: (55.0, 500.0), ..Options::default() };
        assert!(write_dataset(&dir, &loud).unwrap_err().to_string().contains("background"));
        let wrap = Options { seed_base: u64::MAX - 5, clips_per_class: 10, ..Options::default() };
        assert!(write_dataset(&dir, &wrap).unwrap_err().to_string().contains("--seed"));
        assert!(!dir.exists());
    }
}
