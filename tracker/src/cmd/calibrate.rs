//! `aim calibrate FRAMES --reference REF.csv --site SITE.toml [--out SITE_CAL.toml]`: the
//! site's calibration of each array's zenith (`aim_tracker::zenith`).
//!
//! FRAMES is a recording of the arrays while a source (a drone, or a loudspeaker playing
//! one) moves through the room; REF.csv says where it was (a header naming `t`, `x`, `y`, `z`;
//! world ENU m; `t` in s on the arrays' time base: the site's `clock_offset_s` plus the sample
//! index over the rate, so 0 at the first sample of an array with no offset). For each array,
//! the median of (measured − true) zenith per 5° of the measured zenith becomes its
//! `zenith_correction_deg`, which the intake subtracts from every bearing of that array. Frames
//! whose path crosses a site `[[obstacle]]` are left out. stdout: the site file with the corrections (or `--out`); stderr:
//! each array's bins. Aim for a few minutes of source at the heights and distances drones fly
//! at, in line of sight; bins with fewer than `--min-frames` frames give no point.

use std::io::Write as _;
use std::path::PathBuf;

use aim_tracker::link::FrameSource;
use aim_tracker::site::Site;
use aim_tracker::zenith::{self, FitConfig, Reference};
use anyhow::Context as _;

/// Arguments of `aim calibrate`.
#[derive(clap::Args)]
pub struct Args {
    /// Recording of the arrays' frames during the calibration (`aim record`), `-` for stdin.
    frames: String,
    /// Where the source was: CSV with columns t, x, y, z (s on the arrays' time base; ENU m).
    #[arg(long)]
    reference: PathBuf,
    /// The site file (any correction it already has is ignored by the fit and replaced).
    #[arg(long)]
    site: PathBuf,
    /// Write the calibrated site file here instead of stdout.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Width of a bin of measured zenith, degrees.
    #[arg(long, default_value_t = 5.0)]
    bin_deg: f64,
    /// Fewest frames a bin needs to give a point of the correction.
    #[arg(long, default_value_t = 20)]
    min_frames: usize,
    /// Widest spread a bin may have to give a point (median absolute deviation of measured −
    /// true), degrees.
    #[arg(long, default_value_t = zenith::MAX_MAD_DEG)]
    max_mad_deg: f64,
}

/// Runs `aim calibrate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if !(args.bin_deg.is_finite() && (0.5..=30.0).contains(&args.bin_deg)) {
        anyhow::bail!("--bin-deg {} must be 0.5 to 30 degrees", args.bin_deg);
    }
    if args.min_frames == 0 {
        anyhow::bail!("--min-frames must be at least 1");
    }
    let site_text = std::fs::read_to_string(&args.site)
        .with_context(|| format!("reading {}", args.site.display()))?;
    let site = Site::parse(&site_text, &args.site)?;
    let ref_text = std::fs::read_to_string(&args.reference)
        .with_context(|| format!("reading {}", args.reference.display()))?;
    let reference = Reference::parse(&ref_text, &args.reference)?;
    let mut source = FrameSource::new(aim_tracker::link::open_input(&args.frames)?);
    let (bearings, stats) = zenith::bearings_of(&site, &mut source)
        .with_context(|| format!("reading {}", args.frames))?;
    if bearings.is_empty() {
        anyhow::bail!(
            "{}: no Doa frame of an array of {} ({} frames read, {} of them from arrays the \
             site does not have)",
            args.frames,
            args.site.display(),
            stats.frames,
            stats.unknown_array
        );
    }
    if !(args.max_mad_deg.is_finite() && args.max_mad_deg > 0.0) {
        anyhow::bail!("--max-mad-deg {} must be positive", args.max_mad_deg);
    }
    let config = FitConfig {
        bin_deg: args.bin_deg,
        min_frames: args.min_frames,
        max_mad_deg: args.max_mad_deg,
    };
    let obstacles = aim_tracker::site::obstacles(&site_text, &args.site)?;
    let fits = zenith::calibrate(&site, &obstacles, &bearings, &reference, config);
    let mut err = std::io::stderr().lock();
    // Each array on its own: one array with a wrong clock offset in the site file is not
    // hidden by the others.
    for f in &fits {
        let mine: Vec<_> = bearings.iter().filter(|b| b.array_id == f.array_id).copied().collect();
        match zenith::time_check(&site, &obstacles, &mine, &reference, args.bin_deg) {
            Some(check) => {
                writeln!(
                    err,
                    "array {}: time check: spread about the reference {:.2}°; best {:.2}° with \
                     its times {:+.2} s",
                    f.array_id, check.spread_deg, check.best_spread_deg, check.best_shift_s
                )?;
                let name = format!("{} (array {})", args.reference.display(), f.array_id);
                check.verdict(&name).map_err(anyhow::Error::msg)?;
            }
            None => writeln!(
                err,
                "array {}: time check skipped: fewer than 20 frames against the reference",
                f.array_id
            )?,
        }
    }
    if fits.is_empty() {
        anyhow::bail!(
            "no Doa frame of an array of {} falls within the reference's times ({} bearings, \
             reference {:.3}–{:.3} s): is the reference on the arrays' time base?",
            args.site.display(),
            bearings.len(),
            reference.t[0],
            reference.t[reference.t.len() - 1]
        );
    }
    let mut corrections = Vec::new();
    for f in &fits {
        writeln!(
            err,
            "array {}: {} frames against the reference, {} points",
            f.array_id,
            f.frames,
            f.correction.to_degrees().len()
        )?;
        writeln!(err, "  zenith (deg)  frames  measured − true: median  MAD")?;
        for b in &f.bins {
            let used = b.no_point(&config).map(|why| format!("  ({why}: no point)"));
            let used = used.unwrap_or_default();
            writeln!(
                err,
                "  {:>11.1}  {:>6}  {:>+22.2}  {:>4.2}{used}",
                b.centre_deg, b.frames, b.median_deg, b.mad_deg
            )?;
        }
        if f.correction.is_empty() {
            writeln!(
                err,
                "  no bin gives a point: array {} left without a correction",
                f.array_id
            )?;
        }
        corrections.push((f.array_id, f.correction.clone()));
    }
    if corrections.iter().all(|c| c.1.is_empty()) {
        anyhow::bail!(
            "no bin of any array gives a point (see the bins above): record longer, or closer to \
             the heights and distances drones fly at, or check the reference"
        );
    }
    let text = zenith::site_with_corrections(&site_text, &args.site, &corrections)?;
    match &args.out {
        Some(path) => {
            std::fs::write(path, &text).with_context(|| format!("writing {}", path.display()))?;
            writeln!(err, "wrote {}", path.display())?;
        }
        None => std::io::stdout().lock().write_all(text.as_bytes())?,
    }
    Ok(())
}
