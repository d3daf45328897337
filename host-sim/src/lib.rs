//! AIM acoustic world simulator.
//!
//! `host-sim` builds the sound field a set of microphone arrays hears while a multirotor flies
//! a path in a room: the drone flies by rigid-body physics under a cascaded controller
//! ([`flight`]), each rotor sings at its own speed ([`sound`]), and the sound reaches every
//! microphone over the direct path, the room's image sources and around obstacles with a
//! moving-source fractional delay ([`propagation`], [`room`], [`obstacle`]), joined by noise
//! sources and the microphones' own imperfections ([`noise`], [`array`]).
//!
//! ```no_run
//! let scenario = host_sim::scenario::Scenario::load("host-sim/scenarios/square10-los.toml".as_ref())?;
//! let sim = host_sim::simulate(&scenario, &indicatif::ProgressBar::hidden())?;
//! sim.write(std::path::Path::new("out"))?;
//! # anyhow::Ok(())
//! ```
use std::path::Path;

use anyhow::Context as _;
use indicatif::ProgressBar;
use nalgebra::Vector3;
use rand::{rngs::StdRng, Rng, SeedableRng};

pub mod air;
pub mod array;
pub mod bpf_bench;
pub mod eval;
pub mod filter;
pub mod flight;
pub mod noise;
pub mod obstacle;
pub mod path;
pub mod profile;
pub mod propagation;
pub mod room;
pub mod scenario;
pub mod site;
pub mod sound;
pub mod tonal;
pub mod truth;

use array::Clock;
use filter::Gaussian;
use flight::{ControlGains, FlightLog};
use propagation::{Fixed, Medium, PathKind, PreparedSource, Receiver, Trajectory};
use scenario::{RotorSources, Scenario};
use site::{Site, SiteArray, SiteObstacle, SiteRoom};
use sound::SourceSignal;
use truth::{Truth, TruthRow};

/// Digital full scale of the simulated microphones, Pa: 120 dB SPL (a MEMS microphone of
/// −26 dBFS sensitivity at 94 dB SPL). Used when converting to TDM words.
pub const DEFAULT_FULL_SCALE_PA: f64 = 20.0;

/// What one array recorded.
#[derive(Clone, Debug)]
pub struct ArrayRecording {
    /// Array id.
    pub id: u8,
    /// Nominal sample rate, Hz (the array's own clock; see `clock`).
    pub sample_rate_hz: u32,
    /// Geometry preset name, or `custom`.
    pub geometry: String,
    /// Microphone positions, array frame (x right, y forward), m.
    pub positions: Vec<[f64; 2]>,
    /// Array centre, ENU m.
    pub position_m: [f64; 3],
    /// Rotation of the array x axis from ENU +x towards +y, rad. The array faces up.
    pub yaw_rad: f64,
    /// The array's sample clock against true time.
    pub clock: Clock,
    /// One channel per microphone, sound pressure in pascals.
    pub channels: Vec<Vec<f32>>,
}

impl ArrayRecording {
    /// Interleaved TDM words as the firmware's DMA delivers them: frames of `tdm_slots` 32-bit
    /// words, microphone i in slot i (unused slots zero), 24-bit samples left-justified
    /// (`sample << 8`), `full_scale_pa` mapping to digital full scale, clipped.
    pub fn tdm_words(&self, full_scale_pa: f64, tdm_slots: usize) -> Vec<i32> {
        let len = self.channels.first().map_or(0, Vec::len);
        let mut words = vec![0i32; len * tdm_slots];
        for (i, ch) in self.channels.iter().enumerate().take(tdm_slots) {
            for (k, &x) in ch.iter().enumerate() {
                words[k * tdm_slots + i] = tdm_word(x, full_scale_pa);
            }
        }
        words
    }
}

/// The TDM word a 24-bit microphone sends for a sound pressure `pa` (Pa): `full_scale_pa`
/// maps to 8 388 607 counts, rounded, saturated at the 24-bit range, NaN as silence, and
/// left-justified in the 32-bit slot (`counts << 8`). Used for simulated arrays and for float
/// recordings given to `host-sim analyze`, so both feed the pipeline the same words.
pub fn tdm_word(pa: f32, full_scale_pa: f64) -> i32 {
    let counts = (f64::from(pa) * (8_388_607.0 / full_scale_pa)).round();
    let counts = if counts.is_nan() { 0.0 } else { counts.clamp(-8_388_608.0, 8_388_607.0) };
    (counts as i32) << 8
}

/// The result of a simulation.
#[derive(Clone, Debug)]
pub struct Simulation {
    /// Scenario name.
    pub name: String,
    /// One recording per array, in scenario order.
    pub arrays: Vec<ArrayRecording>,
    /// Ground truth of the flight.
    pub truth: Truth,
    /// The site file's content.
    pub site: Site,
    /// The flight at the control rate (covers the recordings' whole time span).
    pub flight: FlightLog,
}

/// Knobs of a simulation run that do not change its result.
#[derive(Clone, Copy, Debug, Default)]
pub struct Options {
    /// Worker threads (0: as many as the machine has).
    pub threads: usize,
}

/// A progress bar on stderr for long runs (`label` leads the line), hidden when stderr is not a
/// terminal. Its length is set by [`simulate`].
pub fn progress_bar(label: &str) -> ProgressBar {
    use std::io::IsTerminal as _;
    let progress = if std::io::stderr().is_terminal() {
        ProgressBar::with_draw_target(None, indicatif::ProgressDrawTarget::stderr())
    } else {
        ProgressBar::hidden()
    };
    let template = format!("{{spinner}} {label} [{{bar:40}}] {{percent:>3}}% eta {{eta}}");
    if let Ok(style) = indicatif::ProgressStyle::with_template(&template) {
        progress.set_style(style.progress_chars("=> "));
    }
    progress
}

/// Simulates `scenario` with default options; `progress` (length set here, in output samples)
/// advances as audio is rendered.
pub fn simulate(scenario: &Scenario, progress: &ProgressBar) -> anyhow::Result<Simulation> {
    simulate_with(scenario, &Options::default(), progress)
}

/// Seed of a named random stream of the scenario.
fn sub_seed(seed: u64, stream: u64) -> u64 {
    let mut r = StdRng::seed_from_u64(seed ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    r.random()
}

/// A rotor hub moving with the flight.
struct RotorPath<'a> {
    log: &'a FlightLog,
    rotor: usize,
}

impl Trajectory for RotorPath<'_> {
    fn position(&self, t_s: f64) -> Vector3<f64> {
        self.log.rotor_position(self.rotor, t_s)
    }
}

/// The drone's centre of mass.
struct CentrePath<'a>(&'a FlightLog);

impl Trajectory for CentrePath<'_> {
    fn position(&self, t_s: f64) -> Vector3<f64> {
        self.0.position(t_s)
    }
}

/// Which of the medium's paths a source takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Reach {
    /// Every path: direct, reflections, diffraction.
    All,
    /// The straight path only.
    Direct,
    /// Every path but the straight one: reflections and diffraction.
    Indirect,
    /// The direct path in free field (the diffuse field's plane waves).
    FreeDirect,
}

/// One sound source to render: its signal, where it is, and which paths it takes.
struct Emitter<'a> {
    signal: PreparedSource<'a>,
    trajectory: Box<dyn Trajectory + 'a>,
    reach: Reach,
}

/// Simulates `scenario`.
pub fn simulate_with(
    scenario: &Scenario,
    options: &Options,
    progress: &ProgressBar,
) -> anyhow::Result<Simulation> {
    let fs = scenario.sample_rate_hz as f64;
    let c = scenario.air.speed_of_sound_mps();
    let n_out = (scenario.duration_s * fs).round() as usize;

    // Time span the sources must cover: every array's recording, less the longest path delay.
    let max_path_m = longest_path_m(scenario);
    let pre_roll = max_path_m / c + 0.05;
    let offsets = scenario.arrays.iter().map(|a| a.clock.offset_s);
    let t_first = offsets.clone().fold(0.0f64, f64::min) - pre_roll;
    let t_last = offsets.fold(0.0f64, f64::max) + scenario.duration_s * 1.001 + 0.05;

    // Flight.
    let dt = 1.0 / scenario.render.control_rate_hz;
    let log = flight::fly(
        &scenario.drone,
        &scenario.plan,
        scenario.yaw_rad,
        &ControlGains::default(),
        flight::Span { t0_s: t_first - 0.01, t1_s: t_last + 0.01, dt_s: dt },
        sub_seed(scenario.seed, 1),
    );

    // Source signals on the grid t_first + k / fs.
    let n_src = ((t_last - t_first) * fs).ceil() as usize + 4;
    let mut signals: Vec<(SourceSignal, Box<dyn Trajectory + '_>, Reach)> = Vec::new();
    let rotors = scenario.drone.rotor_count();
    let rotor_signal = |i: usize| {
        sound::propeller(
            &scenario.drone,
            &log,
            i,
            t_first,
            fs,
            n_src,
            sub_seed(scenario.seed, 100 + i as u64),
        )
    };
    let mode = scenario.render.rotor_sources;
    let per_rotor: Vec<SourceSignal> = (0..rotors).map(rotor_signal).collect();
    if mode != RotorSources::Centre {
        let reach = if mode == RotorSources::Each { Reach::All } else { Reach::Direct };
        for (i, s) in per_rotor.iter().enumerate() {
            signals.push((s.clone(), Box::new(RotorPath { log: &log, rotor: i }), reach));
        }
    }
    if mode != RotorSources::Each {
        let mut sum = per_rotor[0].clone();
        for s in &per_rotor[1..] {
            for (a, b) in sum.samples.iter_mut().zip(&s.samples) {
                *a += b;
            }
        }
        let reach = if mode == RotorSources::Centre { Reach::All } else { Reach::Indirect };
        signals.push((sum, Box::new(CentrePath(&log)), reach));
    }
    drop(per_rotor);
    for (i, n) in scenario.noise.iter().enumerate() {
        let s = n.signal(t_first, fs, n_src, sub_seed(scenario.seed, 200 + i as u64));
        signals.push((s, Box::new(Fixed(n.position_m)), Reach::All));
    }
    if let Some(d) = &scenario.diffuse_noise {
        // Plane waves centred on the arrays' centroid.
        let centre = scenario.arrays.iter().map(|a| a.position_m).sum::<Vector3<f64>>()
            / scenario.arrays.len() as f64;
        for (i, u) in d.directions().iter().enumerate() {
            let s = d.signal(t_first, fs, n_src, sub_seed(scenario.seed, 300 + i as u64));
            let position = centre + u * noise::DIFFUSE_DISTANCE_M;
            signals.push((s, Box::new(Fixed(position)), Reach::FreeDirect));
        }
    }
    let emitters: Vec<Emitter> = signals
        .iter()
        .map(|(s, t, d)| Emitter {
            signal: PreparedSource::new(s),
            trajectory: Box::new(Borrowed(t.as_ref())),
            reach: *d,
        })
        .collect();

    let medium = Medium {
        c_mps: c,
        absorption_per_m_hz2: if scenario.render.absorption {
            scenario.air.absorption_quadratic_coefficient()
        } else {
            0.0
        },
        room: scenario.room.as_ref(),
        obstacles: &scenario.obstacles,
        diffraction_ref_hz: scenario.render.diffraction_ref_hz,
    };
    let free = Medium { room: None, obstacles: &[], ..medium.clone() };
    let paths = medium.path_kinds();
    let is_direct = |k: &PathKind| match k {
        PathKind::Image(i) => i.order == 0,
        PathKind::Diffracted => false,
    };
    let direct_paths: Vec<PathKind> = paths.iter().copied().filter(is_direct).collect();
    let indirect: Vec<PathKind> = paths.iter().copied().filter(|k| !is_direct(k)).collect();
    let free_direct = [PathKind::Image(room::Image::DIRECT)];

    // Jobs: one per microphone.
    struct Job {
        array: usize,
        receiver: Receiver,
        gain: f32,
        noise_rms: f64,
        seed: u64,
    }
    let mut jobs = Vec::new();
    for (ai, a) in scenario.arrays.iter().enumerate() {
        let mut rng = StdRng::seed_from_u64(sub_seed(scenario.seed, 1000 + a.id as u64));
        let mut g = Gaussian::new(StdRng::seed_from_u64(rng.random()));
        for m in 0..a.positions.len() {
            let gain_db = g.sample() * a.gain_mismatch_db;
            let extra = g.sample() * a.phase_mismatch_us * 1e-6;
            jobs.push(Job {
                array: ai,
                receiver: Receiver {
                    position: a.mic_position(m),
                    t0_s: a.clock.offset_s,
                    dt_s: 1.0 / (fs * (1.0 + a.clock.drift_ppm * 1e-6)),
                    extra_delay_s: extra,
                },
                gain: 10f64.powf(gain_db / 20.0) as f32,
                noise_rms: sound::spl_to_rms_pa(a.self_noise_db),
                seed: rng.random(),
            });
        }
    }

    progress.set_length((jobs.len() * n_out) as u64);
    progress.set_position(0);
    let block = scenario.render.block_samples;
    const CHUNK: usize = 48_000;
    let run_job = |job: &Job| -> Vec<f32> {
        let mut out = vec![0.0f32; n_out];
        for (ci, chunk) in out.chunks_mut(CHUNK).enumerate() {
            let mut rx = job.receiver;
            rx.t0_s += (ci * CHUNK) as f64 * rx.dt_s;
            for e in &emitters {
                let (m, p): (&Medium, &[PathKind]) = match e.reach {
                    Reach::All => (&medium, &paths),
                    Reach::Direct => (&medium, &direct_paths),
                    Reach::Indirect => (&medium, &indirect),
                    Reach::FreeDirect => (&free, &free_direct),
                };
                propagation::render(m, &e.signal, e.trajectory.as_ref(), p, &rx, block, chunk);
            }
            progress.inc(chunk.len() as u64);
        }
        let mut g = Gaussian::new(StdRng::seed_from_u64(job.seed));
        for y in &mut out {
            *y = *y * job.gain + (g.sample() * job.noise_rms) as f32;
        }
        out
    };
    let threads = match options.threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    }
    .min(jobs.len().max(1));
    let mut outputs: Vec<Option<Vec<f32>>> = (0..jobs.len()).map(|_| None).collect();
    if threads <= 1 {
        for (j, o) in jobs.iter().zip(outputs.iter_mut()) {
            *o = Some(run_job(j));
        }
    } else {
        let next = std::sync::atomic::AtomicUsize::new(0);
        let results = std::sync::Mutex::new(&mut outputs);
        std::thread::scope(|s| {
            for _ in 0..threads {
                s.spawn(|| loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    let Some(job) = jobs.get(i) else { break };
                    let y = run_job(job);
                    results.lock().expect("no worker panics while holding the lock")[i] = Some(y);
                });
            }
        });
    }
    let mut outputs = outputs.into_iter().map(|o| o.expect("every job ran"));
    let mut arrays = Vec::new();
    for (ai, a) in scenario.arrays.iter().enumerate() {
        let channels: Vec<Vec<f32>> = jobs
            .iter()
            .filter(|j| j.array == ai)
            .map(|_| outputs.next().expect("one per job"))
            .collect();
        arrays.push(ArrayRecording {
            id: a.id,
            sample_rate_hz: scenario.sample_rate_hz,
            geometry: a.geometry.clone(),
            positions: a.positions.clone(),
            position_m: a.position_m.into(),
            yaw_rad: a.yaw_rad,
            clock: a.clock,
            channels,
        });
    }
    progress.finish_and_clear();

    let truth = make_truth(scenario, &log);
    let site = make_site(scenario, c);
    drop(emitters);
    drop(signals);
    Ok(Simulation { name: scenario.name.clone(), arrays, truth, site, flight: log })
}

/// A borrowed trajectory behind a box.
struct Borrowed<'a>(&'a (dyn Trajectory + 'a));

impl Trajectory for Borrowed<'_> {
    fn position(&self, t_s: f64) -> Vector3<f64> {
        self.0.position(t_s)
    }
    fn is_static(&self) -> bool {
        self.0.is_static()
    }
}

/// An upper bound of the longest path any simulated sound takes, m.
fn longest_path_m(s: &Scenario) -> f64 {
    let mut pts: Vec<Vector3<f64>> = s.arrays.iter().map(|a| a.position_m).collect();
    pts.extend(s.noise.iter().map(|n| n.position_m));
    let t_end = s.plan.duration_s();
    let mut t = 0.0;
    while t <= t_end {
        pts.push(s.plan.at(t).position);
        t += 0.5;
    }
    let mut lo = pts[0];
    let mut hi = pts[0];
    for p in &pts {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    if let Some(r) = &s.room {
        lo = lo.inf(&Vector3::zeros());
        hi = hi.sup(&Vector3::from(r.size_m));
    }
    let diag = (hi - lo).norm() + 1.0;
    let order = s.room.as_ref().map_or(0, |r| r.reflection_order) as f64;
    let diffuse = if s.diffuse_noise.is_some() { noise::DIFFUSE_DISTANCE_M + diag } else { 0.0 };
    // The diffracted path is at most twice the box-to-box diagonal.
    (diag * (order + 1.0) * 2.0).max(diffuse)
}

fn make_truth(s: &Scenario, log: &FlightLog) -> Truth {
    let rows_n = (s.duration_s * s.truth_rate_hz).floor() as usize + 1;
    let mut rows = Vec::with_capacity(rows_n);
    for k in 0..rows_n {
        let t = k as f64 / s.truth_rate_hz;
        let (i, f) = log.locate(t);
        // Nearest logged sample (the truth rate divides the control rate in every preset).
        let smp = &log.samples[if f < 0.5 { i } else { (i + 1).min(log.samples.len() - 1) }];
        let (roll, pitch, yaw) = smp.attitude.euler_angles();
        let los = s
            .arrays
            .iter()
            .map(|a| obstacle::blocking(&s.obstacles, &smp.position, &a.position_m).first.is_none())
            .collect();
        rows.push(TruthRow {
            t_s: t,
            position: smp.position.into(),
            velocity: smp.velocity.into(),
            acceleration: smp.acceleration.into(),
            yaw_rad: yaw,
            roll_rad: roll,
            pitch_rad: pitch,
            rotor_hz: smp.rotor_hz.clone(),
            los,
        });
    }
    Truth { blades: s.drone.blades, array_ids: s.arrays.iter().map(|a| a.id).collect(), rows }
}

fn make_site(s: &Scenario, c: f64) -> Site {
    Site {
        sample_rate_hz: s.sample_rate_hz,
        speed_of_sound_mps: c,
        arrays: s
            .arrays
            .iter()
            .map(|a| SiteArray {
                id: a.id,
                geometry: a.geometry.clone(),
                // Rounded to the nanometre so the file reads well.
                positions: a.positions.iter().map(|p| p.map(|v| (v * 1e9).round() / 1e9)).collect(),
                position: a.position_m.into(),
                yaw_deg: a.yaw_rad.to_degrees(),
                clock_offset_s: a.clock.offset_s,
                clock_drift_ppm: a.clock.drift_ppm,
            })
            .collect(),
        room: s.room.as_ref().map(|r| SiteRoom { size: r.size_m }),
        obstacles: s
            .obstacles
            .iter()
            .map(|o| SiteObstacle {
                name: o.name.clone(),
                min: o.min.into(),
                max: o.max.into(),
                loss_db: o.loss_db,
            })
            .collect(),
    }
}

impl Simulation {
    /// Writes `array-<id>.wav` (32-bit float, pascals, one channel per microphone),
    /// `truth.csv` and `site.toml` into `dir` (created if missing).
    pub fn write(&self, dir: &Path) -> anyhow::Result<()> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for a in &self.arrays {
            let path = dir.join(format!("array-{}.wav", a.id));
            write_wav(&path, a).with_context(|| format!("writing {}", path.display()))?;
        }
        let truth = dir.join("truth.csv");
        std::fs::write(&truth, self.truth.to_csv())
            .with_context(|| format!("writing {}", truth.display()))?;
        let site = dir.join("site.toml");
        std::fs::write(&site, self.site.to_toml()?)
            .with_context(|| format!("writing {}", site.display()))?;
        Ok(())
    }
}

fn write_wav(path: &Path, a: &ArrayRecording) -> anyhow::Result<()> {
    let spec = hound::WavSpec {
        channels: a.channels.len() as u16,
        sample_rate: a.sample_rate_hz,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(path, spec)?;
    let len = a.channels.first().map_or(0, Vec::len);
    for k in 0..len {
        for ch in &a.channels {
            w.write_sample(ch[k])?;
        }
    }
    w.finalize()?;
    Ok(())
}
