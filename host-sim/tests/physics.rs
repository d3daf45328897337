//! The simulator against physics: geometry, spreading, image sources, obstacles, and the
//! drone's sound against its own truth and the paper's calibration.
use std::f64::consts::{PI, TAU};

use host_sim::obstacle::Obstacle;
use host_sim::propagation::{self, Fixed, Medium, PathKind, PreparedSource, Receiver};
use host_sim::room::{Image, Room};
use host_sim::scenario::Scenario;
use host_sim::sound::{rms_pa_to_spl, SourceSignal};
use nalgebra::Vector3;

const FS: f64 = 48_000.0;
const C: f64 = 343.0;

fn free_field(absorption: f64) -> Medium<'static> {
    Medium {
        c_mps: C,
        absorption_per_m_hz2: absorption,
        room: None,
        obstacles: &[],
        diffraction_ref_hz: 500.0,
    }
}

fn receiver(position: Vector3<f64>) -> Receiver {
    Receiver { position, t0_s: 0.0, dt_s: 1.0 / FS, extra_delay_s: 0.0 }
}

/// Source signal from t = −0.5 s, `seconds` long, sample k = f(t_k).
fn signal(seconds: f64, f: impl Fn(f64) -> f64) -> SourceSignal {
    let t0 = -0.5;
    let n = ((seconds + 0.5) * FS) as usize;
    SourceSignal {
        t0_s: t0,
        sample_rate_hz: FS,
        samples: (0..n).map(|k| f(t0 + k as f64 / FS) as f32).collect(),
    }
}

fn render_at(
    medium: &Medium,
    sig: &SourceSignal,
    source: Vector3<f64>,
    paths: &[PathKind],
    mic: Vector3<f64>,
    n: usize,
) -> Vec<f32> {
    let mut out = vec![0.0f32; n];
    let prepared = PreparedSource::new(sig);
    propagation::render(medium, &prepared, &Fixed(source), paths, &receiver(mic), 128, &mut out);
    out
}

/// Phase (rad) of the component at `hz` over `x[from..from + n]` (n a whole number of periods
/// of every tone present).
fn phase_at(x: &[f32], hz: f64, from: usize, n: usize) -> f64 {
    let (mut re, mut im) = (0.0, 0.0);
    for (k, &v) in x.iter().enumerate().skip(from).take(n) {
        let a = TAU * hz * k as f64 / FS;
        re += v as f64 * a.cos();
        im -= v as f64 * a.sin();
    }
    im.atan2(re)
}

fn rms(x: &[f32]) -> f64 {
    (x.iter().map(|&v| (v as f64).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
}

#[test]
fn static_source_inter_microphone_delays_match_geometry() {
    let tones = [500.0, 1500.0];
    let sig = signal(0.6, |t| tones.iter().map(|f| (TAU * f * t).sin()).sum());
    let mics: Vec<Vector3<f64>> = host_sim::array::preset_positions("respeaker-6mic")
        .unwrap()
        .iter()
        .map(|p| Vector3::new(1.0 + p[0], 2.0 + p[1], 0.05))
        .collect();
    let medium = free_field(host_sim::air::Air::default().absorption_quadratic_coefficient());
    let direct = [PathKind::Image(Image::DIRECT)];
    let mut worst: f64 = 0.0;
    for source in
        [Vector3::new(4.0, 5.3, 2.0), Vector3::new(-2.2, 3.1, 0.9), Vector3::new(1.3, 1.4, 3.0)]
    {
        let outs: Vec<Vec<f32>> =
            mics.iter().map(|m| render_at(&medium, &sig, source, &direct, *m, 24_000)).collect();
        for hz in tones {
            let p0 = phase_at(&outs[0], hz, 4_800, 9_600);
            for (i, m) in mics.iter().enumerate().skip(1) {
                let pi = phase_at(&outs[i], hz, 4_800, 9_600);
                // Later arrival = phase lag.
                let mut d = p0 - pi;
                d -= TAU * (d / TAU).round();
                let measured = d / (TAU * hz) * FS;
                let geometry = ((source - m).norm() - (source - mics[0]).norm()) / C * FS;
                worst = worst.max((measured - geometry).abs());
                assert!(
                    (measured - geometry).abs() < 0.02,
                    "source {source:?}, mic {i}, {hz} Hz: {measured:.4} vs {geometry:.4} samples"
                );
            }
        }
    }
    eprintln!("static source: worst inter-microphone delay error {worst:.5} samples");
}

#[test]
fn free_field_level_falls_6_db_per_doubling_of_distance() {
    let sig = signal(0.6, |t| (TAU * 700.0 * t).sin() + 0.5 * (TAU * 1900.0 * t).sin());
    let medium = free_field(0.0);
    let direct = [PathKind::Image(Image::DIRECT)];
    let source = Vector3::new(0.0, 0.0, 2.0);
    let level = |r: f64| {
        let dir = Vector3::new(0.6, 0.8, 0.0);
        let out = render_at(&medium, &sig, source, &direct, source + dir * r, 24_000);
        20.0 * rms(&out[4_800..]).log10()
    };
    // At 1 m the level is the source's own; each doubling takes 20·log10(2) dB.
    let l1 = level(1.0);
    assert!((l1 - 20.0 * rms(&sig.samples[24_000..]).log10()).abs() < 0.01, "{l1}");
    for r in [2.0, 4.0, 8.0] {
        let drop = l1 - level(r);
        let want = 20.0 * r.log10();
        assert!((drop - want).abs() < 0.02, "{r} m: {drop:.3} dB vs {want:.3} dB");
    }
}

/// A band-limited pulse (Hann-windowed sinc, cut-off 4.8 kHz, ±0.4 ms) centred on t = 0.
fn pulse(t: f64) -> f64 {
    let fc = 4_800.0;
    let half = 0.4e-3;
    if t.abs() >= half {
        return 0.0;
    }
    let x = TAU * fc * t;
    let sinc = if x.abs() < 1e-12 { 1.0 } else { x.sin() / x };
    sinc * (0.5 + 0.5 * (PI * t / half).cos())
}

#[test]
fn image_source_arrivals_match_the_analytic_ones() {
    let room = Room {
        size_m: [5.0, 4.0, 3.0],
        absorption: [0.1, 0.19, 0.3, 0.4, 0.05, 0.6],
        reflection_order: 1,
        late_tail: false,
    };
    let medium = Medium {
        c_mps: C,
        absorption_per_m_hz2: 0.0,
        room: Some(&room),
        obstacles: &[],
        diffraction_ref_hz: 500.0,
    };
    let s = Vector3::new(1.1, 1.3, 1.2);
    let m = Vector3::new(3.7, 2.9, 1.9);
    // Analytic images of first order: mirror in each wall, β = sqrt(1 − α).
    let mirror = |axis: usize, wall: f64| {
        let mut p = s;
        p[axis] = 2.0 * wall - s[axis];
        p
    };
    let analytic: Vec<(Vector3<f64>, f64)> = vec![
        (s, 1.0),
        (mirror(0, 0.0), 0.9f64.sqrt()),
        (mirror(0, 5.0), 0.81f64.sqrt()),
        (mirror(1, 0.0), 0.7f64.sqrt()),
        (mirror(1, 4.0), 0.6f64.sqrt()),
        (mirror(2, 0.0), 0.95f64.sqrt()),
        (mirror(2, 3.0), 0.4f64.sqrt()),
    ];
    let mut arrivals: Vec<f64> = analytic.iter().map(|(p, _)| (p - m).norm() / C).collect();
    arrivals.sort_by(f64::total_cmp);
    assert!(
        arrivals.windows(2).all(|w| w[1] - w[0] > 0.3e-3),
        "test geometry must separate arrivals"
    );

    let sig = signal(0.2, pulse);
    let paths = medium.path_kinds();
    assert_eq!(paths.len(), 7);
    let out = render_at(&medium, &sig, s, &paths, m, 4_800);
    let expected_with = |shift_samples: f64, gain: f64, which: usize| -> Vec<f64> {
        (0..out.len())
            .map(|k| {
                let t = k as f64 / FS;
                analytic
                    .iter()
                    .enumerate()
                    .map(|(j, (p, beta))| {
                        let r = (p - m).norm();
                        let (dt, g) =
                            if j == which { (shift_samples / FS, gain) } else { (0.0, 1.0) };
                        g * beta / r * pulse(t - r / C - dt)
                    })
                    .sum()
            })
            .collect()
    };
    let expected = expected_with(0.0, 1.0, usize::MAX);
    let peak = expected.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    let deviation =
        |e: &[f64]| out.iter().zip(e).fold(0.0f64, |a, (&y, &e)| a.max((y as f64 - e).abs()));
    let tolerance = 0.003 * peak;
    let worst = deviation(&expected);
    eprintln!("image sources: largest deviation {:.4} % of the direct peak", 100.0 * worst / peak);
    assert!(
        worst < tolerance,
        "largest deviation {:.3} % of the direct peak",
        100.0 * worst / peak
    );
    // The comparison is sharp enough to see any one image 0.05 sample late or 2 % too loud.
    for j in 0..analytic.len() {
        assert!(
            deviation(&expected_with(0.05, 1.0, j)) > tolerance,
            "image {j}: delay not resolved"
        );
        assert!(
            deviation(&expected_with(0.0, 1.02, j)) > tolerance,
            "image {j}: level not resolved"
        );
    }
}

#[test]
fn a_box_between_source_and_array_removes_the_direct_path() {
    let opaque = [Obstacle {
        name: "wall".into(),
        min: Vector3::new(1.0, -1.5, 0.0),
        max: Vector3::new(1.3, 1.5, 1.5),
        loss_db: 300.0,
    }];
    let medium = Medium {
        c_mps: C,
        absorption_per_m_hz2: 0.0,
        room: None,
        obstacles: &opaque,
        diffraction_ref_hz: 500.0,
    };
    let s = Vector3::new(0.0, 0.0, 1.0);
    let m = Vector3::new(3.0, 0.0, 1.0);
    let sig = signal(0.1, pulse);
    let paths = medium.path_kinds();
    let out = render_at(&medium, &sig, s, &paths, m, 2_400);
    let direct_k = (3.0 / C * FS).round() as usize;
    let near_direct = out[direct_k - 3..=direct_k + 3].iter().fold(0.0f32, |a, &b| a.max(b.abs()));
    assert!(near_direct < 1e-6, "direct path still heard: {near_direct}");
    // The diffracted path over the top edge (z = 1.5): up at x = 1, across, down at x = 1.3.
    let detour = (1.0f64 + 0.25).sqrt() + 0.3 + (1.7f64.powi(2) + 0.25).sqrt();
    let k = (detour / C * FS).round() as usize;
    let fresnel = 2.0 * (detour - 3.0) * 500.0 / C;
    let want = 10f64.powf(-10.0 * (3.0 + 20.0 * fresnel).log10() / 20.0) / detour;
    let got = out[k - 2..=k + 2].iter().fold(0.0f32, |a, &b| a.max(b)) as f64;
    assert!((got - want).abs() < 0.03 * want, "diffracted arrival {got:.5} vs {want:.5}");
    // Without the box the direct path is back at full strength.
    let clear = render_at(&free_field(0.0), &sig, s, &[PathKind::Image(Image::DIRECT)], m, 2_400);
    let direct = clear[direct_k - 2..=direct_k + 2].iter().fold(0.0f32, |a, &b| a.max(b)) as f64;
    assert!((direct - 1.0 / 3.0).abs() < 0.01 / 3.0, "{direct}");
}

/// A hover scenario: one array 1 m below the drone, free field, `seconds` long.
fn hover_scenario(extra_drone: &str, seconds: f64) -> Scenario {
    let text = format!(
        r#"
        duration_s = {seconds}
        seed = 3
        [drone]
        preset = "dji-mini-2"
        {extra_drone}
        [path]
        kind = "hover"
        position = [0.0, 0.0, 2.0]
        [[array]]
        id = 7
        position = [0.0, 0.0, 1.0]
        self_noise_db = 0.0
        gain_mismatch_db = 0.0
        phase_mismatch_us = 0.0
        [render]
        rotor_sources = "centre"
        "#
    );
    Scenario::from_toml(&text, "hover-test").unwrap()
}

/// Frequency of the largest spectral peak of `x` in `[lo, hi]` Hz (Hann window, zero-padded
/// DFT scanned at 0.02 Hz steps).
fn peak_hz(x: &[f32], lo: f64, hi: f64) -> f64 {
    let n = x.len();
    let w: Vec<f64> =
        (0..n).map(|k| x[k] as f64 * (0.5 - 0.5 * (TAU * k as f64 / n as f64).cos())).collect();
    let mut best = (0.0, lo);
    let mut f = lo;
    while f <= hi {
        let (mut re, mut im) = (0.0, 0.0);
        let (sd, cd) = (TAU * f / FS).sin_cos();
        let (mut c, mut s) = (1.0, 0.0);
        for v in &w {
            re += v * c;
            im += v * s;
            let nc = c * cd - s * sd;
            s = s * cd + c * sd;
            c = nc;
        }
        let p = re * re + im * im;
        if p > best.0 {
            best = (p, f);
        }
        f += 0.02;
    }
    best.1
}

#[test]
fn truth_rotor_speeds_times_blades_are_the_bpf_heard() {
    // A drone of another hover speed, so a hard-wired 328 Hz could not pass.
    let scenario = hover_scenario("hover_rotor_hz = 150.0\nrotor_jitter = 0.0005", 2.5);
    let sim = host_sim::simulate(&scenario, &indicatif::ProgressBar::hidden()).unwrap();
    let rows = &sim.truth.rows[50..];
    let truth_bpf =
        rows.iter().map(|r| r.rotor_hz.iter().sum::<f64>() / r.rotor_hz.len() as f64).sum::<f64>()
            / rows.len() as f64
            * sim.truth.blades as f64;
    let x = &sim.arrays[0].channels[0][24_000..];
    for harmonic in [1.0, 2.0] {
        let heard = peak_hz(x, harmonic * (truth_bpf - 6.0), harmonic * (truth_bpf + 6.0));
        assert!(
            (heard - harmonic * truth_bpf).abs() < 0.1 * harmonic,
            "harmonic {harmonic}: heard {heard:.3} Hz, truth {:.3} Hz",
            harmonic * truth_bpf
        );
    }
    assert!((truth_bpf - 300.0).abs() < 1.0, "{truth_bpf}");
}

#[test]
fn hovering_mini_2_has_the_papers_bpf_and_level() {
    let scenario = hover_scenario("", 2.5);
    let sim = host_sim::simulate(&scenario, &indicatif::ProgressBar::hidden()).unwrap();
    let x = &sim.arrays[0].channels[0][24_000..];
    let bpf = peak_hz(x, 250.0, 400.0);
    assert!((bpf - 328.0).abs() < 0.05 * 328.0, "BPF {bpf:.2} Hz");
    // The array is 1 m below the drone: the level there is the level at 1 m.
    let spl = rms_pa_to_spl(rms(x));
    eprintln!("hovering mini 2: BPF {bpf:.2} Hz, {spl:.2} dB SPL at 1 m");
    assert!((spl - 77.0).abs() < 2.0, "{spl:.2} dB SPL at 1 m");
}

#[test]
fn every_shipped_scenario_loads() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let mut count = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let s = Scenario::load(&path).unwrap_or_else(|e| panic!("{e:#}"));
            assert!(s.duration_s > 10.0 && !s.arrays.is_empty(), "{}", path.display());
            count += 1;
        }
    }
    assert!(count >= 23, "{count} scenarios");
    let speed = Scenario::load(&dir.join("speed-sweep-3.0.toml")).unwrap();
    let base = Scenario::load(&dir.join("square10-los.toml")).unwrap();
    assert!(speed.plan.duration_s() < base.plan.duration_s(), "the sweep overrides the speed");
    assert_eq!(speed.room, base.room);
}

#[test]
fn a_bad_scenario_names_its_file_and_line() {
    let dir = std::env::temp_dir().join(format!("host-sim-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bad.toml");
    std::fs::write(
        &path,
        "seed = 1\n[drone]\npreset = \"dji-mini-2\"\n[path]\nkind = \"square\"\nside_m = \"ten\"\n",
    )
    .unwrap();
    let e = format!("{:#}", Scenario::load(&path).unwrap_err());
    assert!(e.contains("bad.toml:6: side_m: invalid type") && !e.contains('\n'), "{e}");
    std::fs::write(&path, "[drone]\npreset = \"dji-mini-3\"\n[path]\nkind = \"hover\"\nposition = [0, 0, 1]\n[[array]]\nid = 1\nposition = [0, 0, 0]\n").unwrap();
    let e = format!("{:#}", Scenario::load(&path).unwrap_err());
    assert!(e.contains("bad.toml") && e.contains("dji-mini-3"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A source moving in a straight line at constant velocity.
struct Linear {
    start: Vector3<f64>,
    velocity: Vector3<f64>,
}

impl host_sim::propagation::Trajectory for Linear {
    fn position(&self, t_s: f64) -> Vector3<f64> {
        self.start + self.velocity * t_s
    }
}

#[test]
fn a_moving_source_is_heard_doppler_shifted_and_drifting_clocks_rescale_frequency() {
    let f0 = 1000.0;
    let sig = signal(1.2, |t| (TAU * f0 * t).sin());
    let prepared = PreparedSource::new(&sig);
    let medium = free_field(0.0);
    let direct = [PathKind::Image(Image::DIRECT)];
    // Approaching head-on at 10 m/s, then (second case) receding, mic far enough ahead/behind.
    for (v, drift_ppm) in [(10.0, 0.0), (-10.0, 0.0), (0.0, 200.0)] {
        let source =
            Linear { start: Vector3::new(-20.0, 0.0, 0.0), velocity: Vector3::new(v, 0.0, 0.0) };
        let rx = Receiver {
            position: Vector3::zeros(),
            t0_s: 0.0,
            dt_s: 1.0 / (FS * (1.0 + drift_ppm * 1e-6)),
            extra_delay_s: 0.0,
        };
        let mut out = vec![0.0f32; 48_000];
        propagation::render(&medium, &prepared, &source, &direct, &rx, 128, &mut out);
        // Frequency in the array's own samples (nominal rate FS).
        let heard = peak_hz(&out[8_000..40_000], f0 - 40.0, f0 + 40.0);
        let want = f0 * C / (C - v) / (1.0 + drift_ppm * 1e-6);
        assert!(
            (heard - want).abs() < 0.05,
            "v {v} m/s, drift {drift_ppm} ppm: heard {heard:.3} Hz, expected {want:.3} Hz"
        );
    }
}

#[test]
fn simulate_writes_the_contracted_files() {
    let scenario = hover_scenario("", 0.5);
    let sim = host_sim::simulate(&scenario, &indicatif::ProgressBar::hidden()).unwrap();
    let dir = std::env::temp_dir().join(format!("host-sim-out-{}", std::process::id()));
    sim.write(&dir).unwrap();
    // WAV: 32-bit float pascals, one channel per microphone, bit-identical to the recording.
    let mut wav = hound::WavReader::open(dir.join("array-7.wav")).unwrap();
    let spec = wav.spec();
    assert_eq!((spec.channels, spec.sample_rate, spec.bits_per_sample), (6, 48_000, 32));
    assert_eq!(spec.sample_format, hound::SampleFormat::Float);
    let samples: Vec<f32> = wav.samples::<f32>().map(Result::unwrap).collect();
    assert_eq!(samples.len(), 6 * 24_000);
    for (i, ch) in sim.arrays[0].channels.iter().enumerate() {
        assert!(ch.iter().enumerate().all(|(k, &v)| samples[k * 6 + i] == v), "channel {i}");
    }
    let truth = std::fs::read_to_string(dir.join("truth.csv")).unwrap();
    let header = truth.lines().next().unwrap();
    assert!(header.starts_with("t,x,y,z,vx,vy,vz,yaw,"), "{header}");
    assert!(
        header.contains("rotor1_hz") && header.contains("rotor4_hz") && header.ends_with("los_7")
    );
    assert_eq!(truth.lines().count(), 1 + 51);
    let site = host_sim::site::Site::load(&dir.join("site.toml")).unwrap();
    assert_eq!(site, sim.site);
    assert_eq!(site.arrays[0].id, 7);
    assert_eq!(site.arrays[0].position, [0.0, 0.0, 1.0]);
    std::fs::remove_dir_all(&dir).ok();
}

/// An array under a ceiling, facing down (`facing = "down"`): the directions its pipeline
/// reports, turned into the world by the pose the site file gives the tracker (roll 180°),
/// point at the hovering drone. Oracle: the geometry.
#[test]
fn an_array_facing_down_hears_the_drone_where_its_site_pose_says() {
    let text = r#"
        duration_s = 3.0
        seed = 5
        [drone]
        preset = "dji-mini-2"
        [path]
        kind = "hover"
        position = [3.0, 1.5, 1.5]
        [[array]]
        id = 4
        position = [0.5, 0.0, 5.0]
        yaw_deg = -40.0
        facing = "down"
        self_noise_db = 0.0
        gain_mismatch_db = 0.0
        phase_mismatch_us = 0.0
        [render]
        rotor_sources = "centre"
    "#;
    let scenario = Scenario::from_toml(text, "facing-down").unwrap();
    let bar = indicatif::ProgressBar::hidden();
    let (sim, links) =
        host_sim::eval::link::simulate_links(&scenario, &host_sim::Options::default(), &bar, 20.0)
            .unwrap();
    let site_text = sim.site.to_toml().unwrap();
    assert!(site_text.contains("roll_deg = 180.0"), "{site_text}");
    let site =
        aim_tracker::site::Site::parse(&site_text, std::path::Path::new("site.toml")).unwrap();
    let pose = site.array(4).unwrap();
    let (frames, errors) = host_sim::eval::link::decode_frames(&links[0]);
    assert_eq!(errors, 0);
    let truth: [f64; 3] = [3.0 - 0.5, 1.5, 1.5 - 5.0];
    let r = (truth[0] * truth[0] + truth[1] * truth[1] + truth[2] * truth[2]).sqrt();
    let mut checked = 0;
    for f in &frames {
        let aim_wire::Body::Doa(d) = &f.body else { continue };
        let v = aim_tracker::observation::unit_vector(
            f64::from(d.azimuth_rad()),
            f64::from(d.zenith_rad()),
        );
        let w = pose.to_world(v);
        let cos = (w[0] * truth[0] + w[1] * truth[1] + w[2] * truth[2]) / r;
        let off_deg = cos.clamp(-1.0, 1.0).acos().to_degrees();
        assert!(off_deg < 3.0, "frame {}: {off_deg:.2}° off the drone", f.header.seq);
        checked += 1;
    }
    assert!(checked >= 10, "{checked} DoA frames");
}
