//! Drone profiles: the physical constants the dynamics need (ALGORITHMS.md §5, §10).
//!
//! ```toml
//! name = "DJI Mini 2"
//! structure = "quad"            # quad | hexa | octo | y6
//! blades = 2                    # blades per propeller, n
//! mass_kg = 0.249
//! k_v = 2.27e-5                 # thrust coefficient, N/Hz² of rotation frequency (self-calibrated on hover)
//! k_h = 2.72e-7                 # optional: drag-torque coefficient, N·m/Hz² (0 = unknown)
//! i_z = 7.5e-4                  # optional: yaw moment of inertia, kg·m² (0 = unknown)
//! lambda_h = 0.01               # horizontal quadratic drag, N·s²/m²
//! lambda_v = 0.02               # vertical quadratic drag, N·s²/m²
//! bpf_min_hz = 200.0            # BPF search range
//! bpf_max_hz = 500.0
//! wake_loss_per_mps = 0.02       # optional: thrust a rotor loses in the others' wake, per m/s (0 = unknown)
//! ```

use std::path::Path;

use serde::Deserialize;

use crate::config::{check, line_of, parse_toml, read_text, ConfigError};

/// Standard gravity, m/s².
pub const G: f64 = 9.806_65;

/// The profiles built into the tracker, by name, with their TOML text: one per drone type the
/// bundled classifier knows (`tracker/models/drone-id-chip.json`), so a recognised type brings
/// its profile. Each holds nominal published-style values only (mass, layout, blades, hover
/// BPF; `k_v` from those, recalibrated on every hover).
pub const BUNDLED: &[(&str, &str)] = &[
    ("dji-mini-2", include_str!("../profiles/dji-mini-2.toml")),
    ("fpv-5in", include_str!("../profiles/fpv-5in.toml")),
    ("camera-quad-1kg", include_str!("../profiles/camera-quad-1kg.toml")),
    ("hexacopter", include_str!("../profiles/hexacopter.toml")),
    ("toy-70g", include_str!("../profiles/toy-70g.toml")),
    ("consumer-400g", include_str!("../profiles/consumer-400g.toml")),
];

/// Rotor layout; it fixes the rotor count and which rotors turn alike (paper §III-B).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Structure {
    /// Four rotors.
    Quad,
    /// Six rotors.
    Hexa,
    /// Eight rotors.
    Octo,
    /// Six rotors on three arms, coaxial pairs.
    Y6,
}

impl Structure {
    /// Number of rotors N.
    pub fn rotors(self) -> usize {
        match self {
            Structure::Quad => 4,
            Structure::Hexa | Structure::Y6 => 6,
            Structure::Octo => 8,
        }
    }
}

/// A drone profile with every coefficient in SI units.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    /// Display name.
    pub name: String,
    /// Rotor layout.
    pub structure: Structure,
    /// Blades per propeller, n.
    pub blades: u32,
    /// Mass m, kg.
    pub mass_kg: f64,
    /// Thrust coefficient k_v, N/Hz² (of rotation frequency): T_i = k_v f_i².
    pub k_v: f64,
    /// Drag-torque coefficient k_h, N·m/Hz²; 0 when unknown (only the yaw-size estimator
    /// needs it).
    pub k_h: f64,
    /// Yaw moment of inertia I_z, kg·m²; 0 when unknown (only the yaw-size estimator needs it).
    pub i_z: f64,
    /// Horizontal quadratic drag λ_h, N·s²/m².
    pub lambda_h: f64,
    /// Vertical quadratic drag λ_v, N·s²/m².
    pub lambda_v: f64,
    /// Lowest plausible BPF, Hz.
    pub bpf_min_hz: f64,
    /// Highest plausible BPF, Hz.
    pub bpf_max_hz: f64,
    /// Wake loss: fraction of its thrust a rotor downstream of the others loses per m/s of
    /// horizontal airspeed (times how far downstream it sits); 0 when unknown. In cruise the
    /// rear rotors spin faster to make up for it: the speed cue of ALGORITHMS.md §5.
    pub wake_loss_per_mps: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProfileFile {
    name: toml::Spanned<String>,
    structure: Structure,
    blades: toml::Spanned<u32>,
    mass_kg: toml::Spanned<f64>,
    k_v: toml::Spanned<f64>,
    k_h: Option<toml::Spanned<f64>>,
    i_z: Option<toml::Spanned<f64>>,
    lambda_h: toml::Spanned<f64>,
    lambda_v: toml::Spanned<f64>,
    bpf_min_hz: toml::Spanned<f64>,
    bpf_max_hz: toml::Spanned<f64>,
    wake_loss_per_mps: Option<toml::Spanned<f64>>,
}

impl Profile {
    /// Reads and checks a profile file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        Self::parse(&read_text(path)?, path)
    }

    /// Parses and checks profile TOML `text` (`path` names it in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self, ConfigError> {
        let f: ProfileFile = parse_toml(text, path)?;
        // Upper limits far beyond any multirotor, so that no value can overflow the dynamics.
        let positive = |v: &toml::Spanned<f64>, what: &str, max: f64| {
            check(
                v,
                |x| x > 0.0 && x <= max,
                &format!("{what} must be positive and at most {max}"),
                text,
                path,
            )
        };
        let non_negative = |v: &toml::Spanned<f64>, what: &str, max: f64| {
            check(
                v,
                |x| (0.0..=max).contains(&x),
                &format!("{what} must be 0 to {max}"),
                text,
                path,
            )
        };
        if f.name.get_ref().trim().is_empty() {
            return Err(ConfigError {
                path: path.to_path_buf(),
                line: Some(line_of(text, f.name.span().start)),
                message: "name must not be empty (the tracker's messages name the profile)".into(),
            });
        }
        let blades = *f.blades.get_ref();
        if !(1..=8).contains(&blades) {
            return Err(ConfigError {
                path: path.to_path_buf(),
                line: Some(line_of(text, f.blades.span().start)),
                message: format!("blades must be 1 to 8 (got {blades})"),
            });
        }
        let bpf_min_hz = check(
            &f.bpf_min_hz,
            |x| (10.0..=10_000.0).contains(&x),
            "bpf_min_hz must be 10 to 10000 Hz",
            text,
            path,
        )?;
        let bpf_max_hz = check(
            &f.bpf_max_hz,
            |x| x > bpf_min_hz && x <= 10_000.0,
            "bpf_max_hz must exceed bpf_min_hz and be at most 10000 Hz",
            text,
            path,
        )?;
        let profile = Self {
            name: f.name.into_inner(),
            structure: f.structure,
            blades,
            mass_kg: positive(&f.mass_kg, "mass_kg", 1000.0)?,
            k_v: positive(&f.k_v, "k_v", 1.0)?,
            k_h: match &f.k_h {
                Some(v) => positive(v, "k_h", 1.0)?,
                None => 0.0,
            },
            i_z: match &f.i_z {
                Some(v) => positive(v, "i_z", 1000.0)?,
                None => 0.0,
            },
            lambda_h: non_negative(&f.lambda_h, "lambda_h", 100.0)?,
            lambda_v: non_negative(&f.lambda_v, "lambda_v", 100.0)?,
            bpf_min_hz,
            bpf_max_hz,
            wake_loss_per_mps: match &f.wake_loss_per_mps {
                Some(v) => non_negative(v, "wake_loss_per_mps", 1.0)?,
                None => 0.0,
            },
        };
        // Mass and k_v fix the hover BPF; one outside the search range is a wrong profile.
        let hover = profile.hover_bpf_hz();
        if !(hover >= profile.bpf_min_hz && hover <= profile.bpf_max_hz) {
            return Err(ConfigError {
                path: path.to_path_buf(),
                line: Some(line_of(text, f.k_v.span().start)),
                message: format!(
                    "the hover BPF of mass_kg and k_v, {hover:.1} Hz, is outside bpf_min_hz..bpf_max_hz"
                ),
            });
        }
        Ok(profile)
    }

    /// Number of rotors N.
    pub fn rotors(&self) -> usize {
        self.structure.rotors()
    }

    /// The built-in DJI Mini 2 profile (the paper's drone), same as `profiles/dji-mini-2.toml`.
    pub fn dji_mini_2() -> Self {
        Self::bundled("dji-mini-2").expect("the Mini 2 profile is bundled")
    }

    /// The bundled profile called `name` (one of [`BUNDLED`]: the drone classifier's classes),
    /// the same as `profiles/<name>.toml`; `None` for another name.
    pub fn bundled(name: &str) -> Option<Self> {
        let (_, text) = BUNDLED.iter().find(|(n, _)| *n == name)?;
        let file = format!("profiles/{name}.toml");
        Some(Self::parse(text, Path::new(&file)).expect("the bundled profiles are valid"))
    }

    /// The profile a `--profile` argument names: a TOML file if `arg` is one, else the
    /// bundled profile of that name. The error says which it tried.
    pub fn from_arg(arg: &Path) -> anyhow::Result<Self> {
        if arg.is_file() {
            return Ok(Self::load(arg)?);
        }
        arg.to_str().and_then(Self::bundled).ok_or_else(|| {
            anyhow::anyhow!(
                "profile `{}`: no such file, and no bundled profile has that name (bundled: {})",
                arg.display(),
                BUNDLED.iter().map(|(n, _)| *n).collect::<Vec<_>>().join(", ")
            )
        })
    }

    /// Σ max(0, −cos θᵢ) over the arm directions θᵢ for a flight nose-first between two arms
    /// (arms at (i + ½)·360°/N): how many rotors' worth sit downstream. 1.414 for a quad X.
    pub fn downstream_sum(&self) -> f64 {
        let n = self.rotors();
        (0..n)
            .map(|i| {
                let theta = (i as f64 + 0.5) * std::f64::consts::TAU / n as f64;
                (-theta.cos()).max(0.0)
            })
            .sum()
    }

    /// Thrust excess ρ − 1 of cruise per m/s of horizontal speed: w·Σ dᵢ / N (the wake model
    /// of [`crate::dynamics::speed_from_wake`]); 0 without a wake coefficient.
    pub fn wake_excess_per_mps(&self) -> f64 {
        self.wake_loss_per_mps * self.downstream_sum() / self.rotors() as f64
    }

    /// Relative BPF split f_rear / f_front − 1 of cruise per m/s: the rotors farthest
    /// downstream (cos(π/N) for a flight nose-first between two arms) lose w·cos(π/N)·v of
    /// their thrust and spin (1 − w·cos(π/N)·v)^(−½) times faster than the front ones for
    /// the same thrust, ≈ w·cos(π/N)/2 per m/s; 0 without a wake coefficient. N is the rotor
    /// count, one rotor per arm (a Y6's coaxial pairs are not modelled, as in
    /// [`Self::downstream_sum`]).
    pub fn wake_split_per_mps(&self) -> f64 {
        self.wake_loss_per_mps * (std::f64::consts::PI / self.rotors() as f64).cos() / 2.0
    }

    /// BPF of every rotor at hover with the profile's k_v, Hz: n·sqrt(m g / (N k_v)).
    pub fn hover_bpf_hz(&self) -> f64 {
        self.blades as f64 * (self.mass_kg * G / (self.rotors() as f64 * self.k_v)).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bundled_profiles_parse() {
        let mini = Profile::dji_mini_2();
        assert_eq!(mini.rotors(), 4);
        // The paper: hover rotor 164 Hz, BPF ≈ 328 Hz.
        assert!((mini.hover_bpf_hz() - 328.0).abs() < 3.0, "{}", mini.hover_bpf_hz());
        for name in ["dji-fpv.toml", "hexa-x.toml"] {
            let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("profiles").join(name);
            let prof = Profile::load(&p).unwrap();
            let hover = prof.hover_bpf_hz();
            assert!(hover > prof.bpf_min_hz && hover < prof.bpf_max_hz, "{name}: {hover}");
        }
        // Every bundled profile equals its file, and its window holds the hover BPF with the
        // Mini 2's margins (× 0.6 … × 1.55 within a few per cent).
        for (name, _) in BUNDLED {
            let file = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("profiles/{name}.toml"));
            let prof = Profile::bundled(name).unwrap();
            assert_eq!(prof, Profile::load(&file).unwrap(), "{name}");
            assert_eq!(Profile::from_arg(Path::new(name)).unwrap(), prof);
            assert_eq!(Profile::from_arg(&file).unwrap(), prof);
            let hover = prof.hover_bpf_hz();
            let (lo, hi) = (prof.bpf_min_hz / hover, prof.bpf_max_hz / hover);
            assert!((0.57..0.64).contains(&lo) && (1.5..1.6).contains(&hi), "{name}: {lo} {hi}");
        }
        let e = Profile::from_arg(Path::new("no-such-drone")).unwrap_err().to_string();
        assert!(e.contains("no-such-drone") && e.contains("fpv-5in"), "{e}");
    }

    #[test]
    fn bad_values_name_file_and_line() {
        let good = include_str!("../profiles/dji-mini-2.toml");
        let bad = good.replace("mass_kg = 0.249", "mass_kg = -0.249");
        let line = bad.lines().position(|l| l.starts_with("mass_kg")).unwrap() + 1;
        let e = Profile::parse(&bad, Path::new("p.toml")).unwrap_err();
        assert_eq!(e.line, Some(line));
        assert!(
            e.to_string().starts_with(&format!("p.toml:{line}: mass_kg must be positive")),
            "{e}"
        );

        for (from, to, message) in [
            ("mass_kg = 0.249", "mass_kg = 1e300", "mass_kg must be positive and at most"),
            ("", "i_z = nan", "i_z must be positive"),
            ("k_v = 2.27e-5", "k_v = 1e-320", "hover BPF"),
            ("bpf_min_hz = 200.0", "bpf_min_hz = 1e-300", "bpf_min_hz must be 10 to"),
            ("", "wake_loss_per_mps = 1e9", "wake_loss_per_mps must be"),
            ("name = \"DJI Mini 2\"", "name = \" \"", "name must not be empty"),
        ] {
            // An empty `from` appends the line (the bundled profile has no wake constant, k_h
            // or i_z).
            let bad =
                if from.is_empty() { format!("{good}{to}\n") } else { good.replace(from, to) };
            let line = bad.lines().position(|l| l.starts_with(to)).unwrap() + 1;
            let e = Profile::parse(&bad, Path::new("p.toml")).unwrap_err();
            assert_eq!(e.line, Some(line), "{to}: {e}");
            assert!(e.message.contains(message), "{to}: {e}");
        }

        let bad = good.replace("structure = \"quad\"", "structure = \"tri\"");
        let line = bad.lines().position(|l| l.starts_with("structure")).unwrap() + 1;
        let e = Profile::parse(&bad, Path::new("p.toml")).unwrap_err();
        assert_eq!(e.line, Some(line), "{e}");

        let bad = good.replace("bpf_max_hz = 500.0", "bpf_max_hz = 100.0");
        let e = Profile::parse(&bad, Path::new("p.toml")).unwrap_err();
        assert!(e.message.contains("bpf_max_hz must exceed"), "{e}");

        let missing: String =
            good.lines().filter(|l| !l.starts_with("k_v")).map(|l| format!("{l}\n")).collect();
        let e = Profile::parse(&missing, Path::new("p.toml")).unwrap_err();
        assert!(e.message.contains("k_v"), "{e}");
    }
}
