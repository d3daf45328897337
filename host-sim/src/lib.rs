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
pub mod beacon;
pub mod bpf_bench;
pub mod drones;
pub mod eval;
pub mod filter;
pub mod flight;
pub mod iddata;
pub mod noise;
pub mod obstacle;
pub mod path;
pub mod profile;
pub mod propagation;
pub mod reverb;
pub mod room;
pub mod roomnoise;
pub mod scenario;
pub mod site;
pub mod sound;
pub mod survey;
pub mod tonal;
pub mod truth;
pub mod wav;
pub mod window;

use array::Clock;
use filter::Gaussian;
use flight::{ControlGains, FlightLog};
use propagation::{Fixed, Medium, PathKind, Receiver, Trajectory};
use scenario::{RotorSources, Scenario};
use site::{Site, SiteArray, SiteBeacon, SiteObstacle, SiteRoom};
use sound::SignalBlocks as _;
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
    /// Rotation of the array x axis from ENU +x towards +y, rad.
    pub yaw_rad: f64,
    /// The array faces down (roll 180° about its x axis), else up.
    pub facing_down: bool,
    /// The array's sample clock against true time.
    pub clock: Clock,
    /// The link is down over `[from, to)`, s of the array's clock ([`array::ArrayConfig`]).
    pub link_down_s: Option<[f64; 2]>,
    /// One channel per microphone, sound pressure in pascals.
    pub channels: Vec<Vec<f32>>,
}

impl ArrayRecording {
    /// The recording of `array` of `scenario` before any sound: its description, no channels.
    pub fn empty_for(scenario: &Scenario, array: &array::ArrayConfig) -> Self {
        ArrayRecording {
            id: array.id,
            sample_rate_hz: scenario.sample_rate_hz,
            geometry: array.geometry.clone(),
            positions: array.positions.clone(),
            position_m: array.position_m.into(),
            yaw_rad: array.yaw_rad,
            facing_down: array.facing_down,
            clock: array.clock,
            link_down_s: array.link_down_s,
            channels: Vec::new(),
        }
    }

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
    /// The site file's content: what a real site would know (no clocks, no airframe).
    pub site: Site,
    /// The airframe this run drew from the scenario's population (truth only).
    pub airframe: profile::Airframe,
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
pub(crate) fn sub_seed(seed: u64, stream: u64) -> u64 {
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

/// Simulates `scenario`, keeping every microphone's whole recording in memory.
pub fn simulate_with(
    scenario: &Scenario,
    options: &Options,
    progress: &ProgressBar,
) -> anyhow::Result<Simulation> {
    let mut keep =
        Keep(scenario.arrays.iter().map(|a| vec![Vec::new(); a.positions.len()]).collect());
    let mut sim = simulate_to(scenario, options, progress, &mut keep)?;
    for (a, channels) in sim.arrays.iter_mut().zip(keep.0) {
        a.channels = channels;
    }
    Ok(sim)
}

/// Receives a simulation's audio block by block.
pub trait AudioSink {
    /// The next block of array `array` (index in the scenario): `channels[m]` holds microphone
    /// m's next samples, Pa. Blocks come in time order, every array's block of one instant
    /// before the next instant's; all channels of a block have the same length.
    fn block(&mut self, array: usize, channels: &[&[f32]]) -> anyhow::Result<()>;
}

/// The sink of [`simulate_with`]: appends every block to its recording.
struct Keep(Vec<Vec<Vec<f32>>>);

impl AudioSink for Keep {
    fn block(&mut self, array: usize, channels: &[&[f32]]) -> anyhow::Result<()> {
        for (kept, new) in self.0[array].iter_mut().zip(channels) {
            kept.extend_from_slice(new);
        }
        Ok(())
    }
}

/// Output samples per microphone rendered at a time (one second at 48 kHz): the simulation's
/// memory holds this much output and every source's signal over this span plus the longest
/// path's delay, whatever the duration.
pub const OUTPUT_BLOCK: usize = 48_000;

/// Simulates `scenario`, handing the audio to `sink` block by block ([`OUTPUT_BLOCK`] samples
/// per microphone) as it is rendered, so memory does not grow with the duration (but for the
/// flight log and the truth). The samples are the same bits [`simulate_with`] keeps. The
/// returned simulation's `channels` are empty: the audio went to `sink`.
pub fn simulate_to(
    scenario: &Scenario,
    options: &Options,
    progress: &ProgressBar,
    sink: &mut dyn AudioSink,
) -> anyhow::Result<Simulation> {
    let fs = scenario.sample_rate_hz as f64;
    let c = scenario.air.speed_of_sound_mps();
    let n_out = (scenario.duration_s * fs).round() as usize;

    // The room's late tail (one response per microphone, arrays in order), if it has one.
    let tail = scenario.room.as_ref().filter(|r| r.late_tail).map(|r| {
        let air = if scenario.render.absorption {
            scenario.air.absorption_quadratic_coefficient()
        } else {
            0.0
        };
        let arrays: Vec<(Vec<Vector3<f64>>, u64)> = scenario
            .arrays
            .iter()
            .map(|a| {
                let pos = (0..a.positions.len()).map(|m| a.mic_position(m)).collect();
                (pos, sub_seed(scenario.seed, 400 + a.id as u64))
            })
            .collect();
        reverb::LateTail::new(r, c, air, fs, &arrays, OUTPUT_BLOCK)
    });
    let tail_reach_s = tail.as_ref().map_or(0.0, |t| t.reach_s(fs));

    // Time span the sources must cover: every array's recording, less the longest path delay.
    let max_path_m = longest_path_m(scenario);
    let pre_roll = (max_path_m / c).max(tail_reach_s) + 0.05;
    let offsets = scenario.arrays.iter().map(|a| a.clock.offset_s);
    let t_first = offsets.clone().fold(0.0f64, f64::min) - pre_roll;
    let t_last = offsets.fold(0.0f64, f64::max) + scenario.duration_s * 1.001 + 0.05;

    // Flight, by the airframe this seed draws.
    let airframe =
        scenario.population.draw(scenario.drone.rotor_count(), sub_seed(scenario.seed, 2));
    let dt = 1.0 / scenario.render.control_rate_hz;
    let log = flight::fly(
        &scenario.drone,
        &airframe,
        &scenario.plan,
        scenario.yaw_rad,
        &ControlGains::default(),
        flight::Span { t0_s: t_first - 0.01, t1_s: t_last + 0.01, dt_s: dt },
        sub_seed(scenario.seed, 1),
    );

    // Source signals on the grid t_first + k / fs, generated block by block into windows.
    let n_src = ((t_last - t_first) * fs).ceil() as usize + 4;
    let rotors = scenario.drone.rotor_count();
    let mut rotor_gens: Vec<sound::Propeller> = (0..rotors)
        .map(|i| {
            sound::Propeller::new(
                &scenario.drone,
                airframe.shaft_line_boost_db[i],
                &log,
                i,
                t_first,
                fs,
                n_src,
                sub_seed(scenario.seed, 100 + i as u64),
            )
        })
        .collect();
    let mode = scenario.render.rotor_sources;
    let mut trajectories: Vec<(Box<dyn Trajectory + '_>, Reach)> = Vec::new();
    if mode != RotorSources::Centre {
        let reach = if mode == RotorSources::Each { Reach::All } else { Reach::Direct };
        for i in 0..rotors {
            trajectories.push((Box::new(RotorPath { log: &log, rotor: i }), reach));
        }
    }
    if mode != RotorSources::Each {
        let reach = if mode == RotorSources::Centre { Reach::All } else { Reach::Indirect };
        trajectories.push((Box::new(CentrePath(&log)), reach));
    }
    let mut noise_gens: Vec<noise::BandNoise> = Vec::new();
    for (i, n) in scenario.noise.iter().enumerate() {
        noise_gens.push(n.blocks(fs, n_src, sub_seed(scenario.seed, 200 + i as u64)));
        trajectories.push((Box::new(Fixed(n.position_m)), Reach::All));
    }
    if let Some(d) = &scenario.diffuse_noise {
        // Plane waves centred on the arrays' centroid.
        let centre = scenario.arrays.iter().map(|a| a.position_m).sum::<Vector3<f64>>()
            / scenario.arrays.len() as f64;
        for (i, u) in d.directions().iter().enumerate() {
            noise_gens.push(d.blocks(fs, n_src, sub_seed(scenario.seed, 300 + i as u64)));
            let position = centre + u * noise::DIFFUSE_DISTANCE_M;
            trajectories.push((Box::new(Fixed(position)), Reach::FreeDirect));
        }
    }
    let mut windows: Vec<window::SourceWindow> =
        trajectories.iter().map(|_| window::SourceWindow::new(t_first, fs, n_src)).collect();

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
        /// The microphone's fixed output when dead (0) or stuck, Pa.
        fault: Option<f32>,
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
                fault: if a.dead_mics.contains(&m) {
                    Some(0.0)
                } else if a.stuck_mics.contains(&m) {
                    Some(array::STUCK_PA)
                } else {
                    None
                },
            });
        }
    }

    // The longest delay any path can have, s: the bound of `longest_path_m` over where the
    // drone really flew, with margin. A read before it would be an error, never a silent zero.
    let max_delay_s = (1.25 * longest_path_bound_m(scenario, &log) / c).max(tail_reach_s) + 0.05;
    let max_extra_s = jobs.iter().map(|j| j.receiver.extra_delay_s.abs()).fold(0.0, f64::max);

    progress.set_length((jobs.len() * n_out) as u64);
    progress.set_position(0);
    let block = scenario.render.block_samples;
    // Per microphone: its output block and its self-noise generator.
    let states: Vec<std::sync::Mutex<(Vec<f32>, Gaussian)>> = jobs
        .iter()
        .map(|j| {
            let g = Gaussian::new(StdRng::seed_from_u64(j.seed));
            std::sync::Mutex::new((Vec::with_capacity(OUTPUT_BLOCK), g))
        })
        .collect();
    let outside = std::sync::Mutex::new(None::<propagation::OutsideWindow>);
    let run_job = |i: usize, ci: usize, n: usize, views: &[propagation::SourceView]| {
        let job = &jobs[i];
        let mut state = states[i].lock().expect("no panics while held");
        let (out, g) = &mut *state;
        out.clear();
        out.resize(n, 0.0);
        let mut rx = job.receiver;
        rx.t0_s += (ci * OUTPUT_BLOCK) as f64 * rx.dt_s;
        for ((traj, reach), view) in trajectories.iter().zip(views) {
            let (m, p): (&Medium, &[PathKind]) = match reach {
                Reach::All => (&medium, &paths),
                Reach::Direct => (&medium, &direct_paths),
                Reach::Indirect => (&medium, &indirect),
                Reach::FreeDirect => (&free, &free_direct),
            };
            let rendered = propagation::render_window(m, view, traj.as_ref(), p, &rx, block, out);
            if let Err(e) = rendered {
                *outside.lock().expect("no panics while held") = Some(e);
            }
        }
        for b in &scenario.beacons {
            b.render(&medium, &paths, &rx, out);
        }
        if let Some(tail) = &tail {
            // The sources the room reverberates: all but the straight-only rotor paths and
            // the diffuse field's plane waves.
            let sources: Vec<&propagation::SourceView> = trajectories
                .iter()
                .zip(views)
                .filter(|((_, r), _)| matches!(r, Reach::All | Reach::Indirect))
                .map(|(_, v)| v)
                .collect();
            let q0 = ((rx.t0_s - t_first) * fs).round() as isize;
            if let Err(e) = tail.add(i, &sources, q0, out) {
                *outside.lock().expect("no panics while held") = Some(e);
            }
        }
        for y in out.iter_mut() {
            *y = *y * job.gain + (g.sample() * job.noise_rms) as f32;
        }
        if let Some(v) = job.fault {
            out.fill(v);
        }
        progress.inc(n as u64);
    };
    let threads = match options.threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    }
    .min(jobs.len().max(1));

    let mut rotor_block: Vec<Vec<f32>> = vec![Vec::new(); rotors];
    let mut noise_block: Vec<f32> = Vec::new();
    for ci in 0..n_out.div_ceil(OUTPUT_BLOCK) {
        let n = OUTPUT_BLOCK.min(n_out - ci * OUTPUT_BLOCK);
        // The signal indices this block can read, over every microphone's clock.
        let (mut q_lo, mut q_hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for j in &jobs {
            let t0 = j.receiver.t0_s + (ci * OUTPUT_BLOCK) as f64 * j.receiver.dt_s;
            let t1 = t0 + n as f64 * j.receiver.dt_s;
            q_lo = q_lo.min((t0 - max_delay_s - max_extra_s - t_first) * fs);
            q_hi = q_hi.max((t1 + max_extra_s - t_first) * fs);
        }
        let need_lo = (q_lo.floor() - 8.0).max(0.0) as usize;
        let need_hi = ((q_hi.ceil() + 8.0).max(0.0) as usize).min(n_src);
        // Generate up to one past the last needed sample (its second difference needs it).
        let have = windows.first().map_or(n_src, window::SourceWindow::end);
        let more = (need_hi + 2).min(n_src).saturating_sub(have);
        if more > 0 {
            let mut e = 0;
            for (buf, gen) in rotor_block.iter_mut().zip(rotor_gens.iter_mut()) {
                buf.resize(more, 0.0);
                gen.fill(buf);
            }
            if mode != RotorSources::Centre {
                for buf in &rotor_block {
                    windows[e].push(buf);
                    e += 1;
                }
            }
            if mode != RotorSources::Each {
                // The rotors' sum, added in rotor order.
                let (first, rest) = rotor_block.split_first_mut().expect("a drone has rotors");
                for other in rest.iter() {
                    for (a, b) in first.iter_mut().zip(other) {
                        *a += b;
                    }
                }
                windows[e].push(first);
                e += 1;
            }
            for gen in &mut noise_gens {
                noise_block.resize(more, 0.0);
                gen.fill(&mut noise_block);
                windows[e].push(&noise_block);
                e += 1;
            }
        }
        for w in &mut windows {
            w.trim(need_lo);
        }
        let views: Vec<propagation::SourceView> = windows.iter().map(|w| w.view()).collect();
        if threads <= 1 {
            for i in 0..jobs.len() {
                run_job(i, ci, n, &views);
            }
        } else {
            let next = std::sync::atomic::AtomicUsize::new(0);
            std::thread::scope(|s| {
                for _ in 0..threads {
                    s.spawn(|| loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        if i >= jobs.len() {
                            break;
                        }
                        run_job(i, ci, n, &views);
                    });
                }
            });
        }
        if let Some(e) = *outside.lock().expect("no panics while held") {
            anyhow::bail!(
                "internal error: a path needed source samples {}..={} outside the window kept \
                 ({}..{}); the delay bound is too short for this scenario",
                e.needed_from,
                e.needed_to,
                need_lo,
                need_hi
            );
        }
        for ai in 0..scenario.arrays.len() {
            let guards: Vec<_> = (0..jobs.len())
                .filter(|&i| jobs[i].array == ai)
                .map(|i| states[i].lock().expect("no panics while held"))
                .collect();
            let channels: Vec<&[f32]> = guards.iter().map(|g| g.0.as_slice()).collect();
            sink.block(ai, &channels)?;
        }
    }
    progress.finish_and_clear();

    let arrays = scenario.arrays.iter().map(|a| ArrayRecording::empty_for(scenario, a)).collect();
    let mut truth = make_truth(scenario, &log);
    truth.airframe = Some(airframe.clone());
    let site = make_site(scenario, c);
    drop(windows);
    drop(trajectories);
    Ok(Simulation { name: scenario.name.clone(), arrays, truth, site, airframe, flight: log })
}

/// Simulates `scenario` straight into `dir` (created if missing): `array-<id>.wav` written
/// block by block as [`Simulation::write`] would write them (the same bytes), then the truth
/// and site files. Memory does not grow with the duration but for the flight log and the
/// truth. A sample that is not finite stops the run, and so does `stop` once it is set (an
/// [`aim_tracker::exit::Interrupted`] error); either way no WAV file is left behind.
pub fn write_streamed(
    scenario: &Scenario,
    options: &Options,
    progress: &ProgressBar,
    dir: &Path,
    stop: Option<&std::sync::atomic::AtomicBool>,
) -> anyhow::Result<Simulation> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let arrays: Vec<(u8, usize)> =
        scenario.arrays.iter().map(|a| (a.id, a.positions.len())).collect();
    let mut sink = wav::WavSink::create(dir, &arrays, scenario.sample_rate_hz)?.until(stop);
    let sim = simulate_to(scenario, options, progress, &mut sink)?;
    sink.finish()?;
    sim.write_truth_and_site(dir)?;
    Ok(sim)
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
    path_bound_in_box(s, lo, hi)
}

/// The longest path bound for sound within the box `lo`..`hi` (widened to the room): its
/// diagonal times the reflection order, or the diffuse field's distance.
fn path_bound_in_box(s: &Scenario, mut lo: Vector3<f64>, mut hi: Vector3<f64>) -> f64 {
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

/// An upper bound of the longest path any simulated sound takes, m, from where the drone
/// really flew (every logged position, widened by the rotors' reach) rather than the plan.
fn longest_path_bound_m(s: &Scenario, log: &FlightLog) -> f64 {
    let reach = log.rotors.iter().map(|r| r.position_m.norm()).fold(0.0, f64::max) + 0.5;
    let mut pts: Vec<Vector3<f64>> = s.arrays.iter().map(|a| a.position_m).collect();
    pts.extend(s.noise.iter().map(|n| n.position_m));
    let (mut lo, mut hi) = (pts[0], pts[0]);
    for p in pts.iter().chain(log.samples.iter().map(|x| &x.position)) {
        lo = lo.inf(&(p - Vector3::repeat(reach)));
        hi = hi.sup(&(p + Vector3::repeat(reach)));
    }
    path_bound_in_box(s, lo, hi).max(longest_path_m(s))
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
    Truth {
        blades: s.drone.blades,
        array_ids: s.arrays.iter().map(|a| a.id).collect(),
        clocks: s.arrays.iter().map(|a| a.clock).collect(),
        airframe: None,
        rows,
    }
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
                roll_deg: if a.facing_down { 180.0 } else { 0.0 },
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
        // What a site surveys and publishes; never the speaker's (or any array's) clock.
        beacons: s
            .beacons
            .iter()
            .map(|b| SiteBeacon {
                id: b.id,
                position: b.position_m.into(),
                period_s: b.period_s,
                sequence: aim_dsp::beacon::SEQUENCE_NAME.into(),
                level_db: b.level_db,
            })
            .collect(),
    }
}

impl Simulation {
    /// Writes `array-<id>.wav` (32-bit float, pascals, one channel per microphone),
    /// `truth.csv`, `truth.toml` (clocks, airframe) and `site.toml` into `dir` (created if
    /// missing).
    pub fn write(&self, dir: &Path) -> anyhow::Result<()> {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        for a in &self.arrays {
            let path = dir.join(format!("array-{}.wav", a.id));
            wav::write_wav(&path, a).with_context(|| format!("writing {}", path.display()))?;
        }
        self.write_truth_and_site(dir)
    }

    /// Writes `truth.csv`, `truth.toml` and `site.toml` into `dir`.
    pub fn write_truth_and_site(&self, dir: &Path) -> anyhow::Result<()> {
        let truth = dir.join("truth.csv");
        std::fs::write(&truth, self.truth.to_csv())
            .with_context(|| format!("writing {}", truth.display()))?;
        let truth = dir.join("truth.toml");
        std::fs::write(&truth, self.truth.to_toml())
            .with_context(|| format!("writing {}", truth.display()))?;
        let site = dir.join("site.toml");
        std::fs::write(&site, self.site.to_toml()?)
            .with_context(|| format!("writing {}", site.display()))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every key path of a TOML value ("array.clock_offset_s" style), and every number in it.
    fn walk(v: &toml::Value, prefix: &str, keys: &mut Vec<String>, numbers: &mut Vec<f64>) {
        match v {
            toml::Value::Table(t) => {
                for (k, x) in t {
                    let p = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
                    keys.push(p.clone());
                    walk(x, &p, keys, numbers);
                }
            }
            toml::Value::Array(a) => a.iter().for_each(|x| walk(x, prefix, keys, numbers)),
            toml::Value::Float(f) => numbers.push(*f),
            toml::Value::Integer(i) => numbers.push(*i as f64),
            _ => {}
        }
    }

    /// The site file audit: what `site.toml` says is only what a real site knows (where the
    /// arrays, room and obstacles are, the nominal rate, the air's speed of sound). The arrays'
    /// clock offsets and drifts and the drawn airframe go to `truth.toml` instead.
    #[test]
    fn site_file_holds_nothing_from_the_truth() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
        // Five arrays with their own clocks, a beacon, and an airframe drawn from a wide
        // population.
        let mut overrides = toml::Table::new();
        let airframe: toml::Table = toml::from_str(
            "wake_spread = 0.3\ncg_offset_mm = 2.0\nthrust_spread = 0.03\nchipped_probability = 1.0",
        )
        .unwrap();
        overrides.insert("airframe".into(), toml::Value::Table(airframe));
        let s = Scenario::load_with(&dir.join("zigzag10-los.toml"), 7, &overrides).unwrap();
        assert!(s.arrays.iter().any(|a| a.clock.offset_s != 0.0 && a.clock.drift_ppm != 0.0));
        let site: toml::Value = toml::from_str(&make_site(&s, 343.0).to_toml().unwrap()).unwrap();
        let (mut keys, mut numbers) = (Vec::new(), Vec::new());
        walk(&site, "", &mut keys, &mut numbers);
        let allowed = [
            "sample_rate_hz",
            "speed_of_sound_mps",
            "array",
            "array.id",
            "array.geometry",
            "array.positions",
            "array.position",
            "array.yaw_deg",
            "room",
            "room.size",
            "obstacle",
            "obstacle.name",
            "obstacle.min",
            "obstacle.max",
            "obstacle.loss_db",
            "beacon",
            "beacon.id",
            "beacon.position",
            "beacon.period_s",
            "beacon.sequence",
            "beacon.level_db",
        ];
        for k in &keys {
            assert!(allowed.contains(&k.as_str()), "site.toml carries `{k}`");
        }
        let airframe = s.population.draw(s.drone.rotor_count(), sub_seed(s.seed, 2));
        assert!(airframe.chipped_rotor.is_some());
        let mut secrets: Vec<f64> =
            s.arrays.iter().flat_map(|a| [a.clock.offset_s, a.clock.drift_ppm]).collect();
        secrets.extend([airframe.wake_gain, airframe.cg_offset_m[0], airframe.cg_offset_m[1]]);
        // The beacon's own clock and start are the loudspeaker's, not the site's.
        assert!(!s.beacons.is_empty());
        secrets.extend(s.beacons.iter().flat_map(|b| [b.clock_drift_ppm, b.start_s]));
        secrets.extend(&airframe.thrust_factor);
        for x in secrets.iter().filter(|x| **x != 0.0 && **x != 1.0) {
            assert!(!numbers.contains(x), "site.toml holds the truth's value {x}");
        }
        // …and the truth file has them.
        let mut truth = make_truth(&s, &flight_stub(&s));
        truth.airframe = Some(airframe.clone());
        let t: toml::Value = toml::from_str(&truth.to_toml()).unwrap();
        let (mut tk, mut tn) = (Vec::new(), Vec::new());
        walk(&t, "", &mut tk, &mut tn);
        assert!(tk.contains(&"array.clock_drift_ppm".to_string()));
        assert!(tn.contains(&s.arrays[1].clock.offset_s) && tn.contains(&airframe.wake_gain));
    }

    /// A one-sample flight log at the plan's start (enough for `make_truth`'s shape).
    fn flight_stub(s: &Scenario) -> FlightLog {
        FlightLog {
            t0_s: 0.0,
            dt_s: 1.0,
            samples: vec![flight::FlightSample {
                t_s: 0.0,
                position: s.plan.at(0.0).position,
                velocity: Vector3::zeros(),
                acceleration: Vector3::zeros(),
                attitude: nalgebra::UnitQuaternion::identity(),
                rotor_hz: vec![164.0; 4],
            }],
            rotors: s.drone.rotors(),
        }
    }
}
