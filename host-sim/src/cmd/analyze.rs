//! `host-sim analyze WAV --array PRESET|FILE [--jsonl]`: runs the on-chip pipeline (`aim-dsp`)
//! on a recording and prints its outputs.
//!
//! The samples become 24-bit TDM words as a real microphone would deliver them (mic i in slot
//! i of 8-slot frames, left-justified): 32-bit float WAVs hold sound pressure in pascals (the
//! simulator's recordings) and are scaled so that `--full-scale-pa` (default 20 Pa, i.e. a
//! microphone of −26 dBFS sensitivity at 94 dB SPL, full scale at 120 dB SPL) is digital full
//! scale, then rounded and saturated to 24 bits; integer PCM is shifted into place (16- and
//! 24-bit exactly, 32-bit truncated to its top 24 bits).
//!
//! With `--jsonl` every output is one JSON object per line (the contract in DESIGN.md):
//!
//! ```text
//! {"kind":"doa","t":0.0,"span_s":0.171,"azimuth_deg":37.2,"zenith_deg":61.0,"quality":0.83,"residual_samples":0.04}
//! {"kind":"peaks","t":0.0,"span_s":0.512,"bpf_hz":328.1,"peaks":[{"hz":328.1,"amp":0.012,"harmonicity":1.0}]}
//! {"kind":"health","t":0.0,"clipped_samples":0,"peak_dbfs":-21.3,"block_exponent":-3}
//! ```
//!
//! `t` is the time of the first sample the output describes (sample index / sample rate, s);
//! `span_s` the duration it covers. Without `--jsonl` the same is printed as aligned text.
//!
//! With `--frames FILE` the outputs are also written as the board would send them over its
//! link (a `Hello`, then one frame per output, encoded by `aim_wire::from_dsp` as the firmware
//! encodes them), the bytes `aim record` stores: `aim frames`, `aim replay` and `aim calibrate`
//! read them. A recording made during a survey thus calibrates a site (`aim calibrate FILE
//! --reference ... --site ...`).
//! An existing `FILE` is removed when the run starts (`FILE` may not be one of the run's
//! inputs). The bytes go to `FILE.part`, renamed to `FILE` when the recording is through; a
//! recording that fails half-way leaves its frames so far in `FILE.part` and no `FILE`.
use std::io::{BufWriter, Write as _};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use aim_dsp::{Config, Geometry, Output, Pipeline};

use host_sim::eval::link::{BoardEncoder, CHUNK_FRAMES, TDM_SLOTS};

/// Arguments of `host-sim analyze`.
#[derive(clap::Args)]
pub struct Args {
    /// Recording: one channel per microphone, 16 or 48 kHz; float (Pa) or integer PCM.
    wav: PathBuf,
    /// Array geometry: a preset (`respeaker6`, `respeaker4`, `circle8`) or a TOML file with
    /// `positions = [[x, y], ...]` in metres (array frame, mic i = WAV channel i).
    #[arg(long)]
    array: String,
    /// One JSON object per output line.
    #[arg(long)]
    jsonl: bool,
    /// Sound pressure that maps to digital full scale for float recordings, Pa.
    #[arg(long, default_value_t = host_sim::DEFAULT_FULL_SCALE_PA)]
    full_scale_pa: f64,
    /// Also write the frames the board would send for this recording (a Hello, then one frame
    /// per output) to this file, as `aim record` stores a link: for `aim frames`, `aim
    /// replay`, `aim calibrate`. An existing FILE is replaced; the bytes go to FILE.part until
    /// the recording is through.
    #[arg(long, value_name = "FILE")]
    frames: Option<PathBuf>,
    /// The array id written into `--frames` (the site file's `[[array]] id`).
    #[arg(long, default_value_t = 1, requires = "frames")]
    id: u8,
}

/// Runs `host-sim analyze`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if !(args.full_scale_pa.is_finite() && args.full_scale_pa > 0.0) {
        bail!("--full-scale-pa must be a positive number of pascals, not {}", args.full_scale_pa);
    }
    let geometry = load_array(&args.array)?;
    let mut reader = hound::WavReader::open(&args.wav)
        .with_context(|| format!("reading {}", args.wav.display()))?;
    let spec = reader.spec();
    let channels = spec.channels as usize;
    // A mono clip (one microphone, 16 or 48 kHz) feeds every microphone of the array: the
    // BPF path hears it as it is; a plane wave from the zenith says nothing about direction,
    // so DoA outputs are not printed.
    let mono = channels == 1 && geometry.len() > 1;
    if mono {
        eprintln!(
            "{}: one channel: fed to all {} microphones of `{}`; BPF path only, DoA skipped",
            args.wav.display(),
            geometry.len(),
            args.array
        );
    }
    if channels != geometry.len() && !mono {
        bail!(
            "{}: {} channels, but array `{}` has {} microphones",
            args.wav.display(),
            channels,
            args.array,
            geometry.len()
        );
    }
    let config = Config::new(geometry, spec.sample_rate);
    let mut pipeline = Pipeline::new(&config).with_context(|| {
        format!("{}: cannot run the pipeline on this recording", args.wav.display())
    })?;
    let fs = f64::from(spec.sample_rate);
    let converter = Converter::new(&spec, args.full_scale_pa)
        .with_context(|| format!("{}: unsupported sample format", args.wav.display()))?;

    let progress = progress_bar(u64::from(reader.duration()))?;
    let stdout = std::io::stdout();
    let mut out = BufWriter::new(stdout.lock());
    let link = match &args.frames {
        Some(path) => {
            // FILE is removed at the start: it must not be one of this run's inputs.
            let same = |input: &Path| {
                let c = |p: &Path| std::fs::canonicalize(p).ok();
                c(path).is_some_and(|a| c(input) == Some(a))
            };
            if same(&args.wav) || same(Path::new(&args.array)) {
                bail!(
                    "--frames {}: that is an input of this run; name another file",
                    path.display()
                );
            }
            Some(LinkFile::create(path, args.id, &config)?)
        }
        None => None,
    };
    let mut printer =
        Printer { fs, jsonl: args.jsonl, error: None, counts: [0; 3], skip_doa: mono, link };
    let mut feed = Feed {
        channels,
        copies: if mono { geometry.len() } else { 1 },
        pipeline: &mut pipeline,
        printer: &mut printer,
        progress: &progress,
        words: Vec::new(),
        slot: 0,
        frames: 0,
    };
    let wav = args.wav.display();
    let declared = u64::from(reader.duration());
    // A cut-off file: its header declares more samples than it holds.
    let cut = |k: usize, e: hound::Error| {
        anyhow::anyhow!(
            "{wav}: cannot read sample {} of channel {} ({:.6} s; the header declares {declared} \
             per channel; is the file cut short?): {e}",
            k / channels,
            k % channels,
            (k / channels) as f64 / fs
        )
    };
    let fed = (|| -> anyhow::Result<(usize, usize)> {
        if matches!(spec.sample_format, hound::SampleFormat::Float) {
            for (k, s) in reader.samples::<f32>().enumerate() {
                let x = s.map_err(|e| cut(k, e))?;
                if !x.is_finite() {
                    // Not silence: a recording with NaN or infinite pressure is broken.
                    bail!(
                        "{wav}: sample {} of channel {} ({:.6} s) is {x}, not a pressure",
                        k / channels,
                        k % channels,
                        (k / channels) as f64 / fs
                    );
                }
                feed.word(converter.float(x), &mut out)?;
            }
        } else {
            for (k, s) in reader.samples::<i32>().enumerate() {
                feed.word(converter.int(s.map_err(|e| cut(k, e))?), &mut out)?;
            }
        }
        let counts = feed.finish(&mut out)?;
        out.flush().context("writing to stdout")?;
        Ok(counts)
    })();
    let (frames, slot) = fed.inspect_err(|_| {
        if let Some(link) = printer.link.take() {
            let part = link.abandon();
            eprintln!("note: the frames of the audio read so far are in {}", part.display());
        }
    })?;
    if let Some(link) = printer.link.take() {
        link.finish()?;
    }
    progress.finish_and_clear();
    if slot != 0 {
        eprintln!("warning: the recording ends inside a frame ({slot} of {channels} channels)");
    }
    if printer.counts[0] + printer.counts[1] == 0 {
        eprintln!(
            "warning: {wav}: no output; {:.3} s of audio is shorter than one analysis (about \
             0.17 s for a direction, 0.512 s for the BPF)",
            frames as f64 / fs
        );
    }
    eprintln!(
        "{}: {:.2} s, {} doa, {} peaks, {} health outputs",
        args.wav.display(),
        frames as f64 / fs,
        printer.counts[0],
        printer.counts[1],
        printer.counts[2]
    );
    Ok(())
}

/// Collects WAV samples into TDM frames and hands them to the pipeline a chunk at a time.
struct Feed<'a> {
    channels: usize,
    /// Microphones each WAV channel feeds (the array's count for a mono clip, else 1).
    copies: usize,
    pipeline: &'a mut Pipeline,
    printer: &'a mut Printer,
    progress: &'a ProgressBar,
    words: Vec<i32>,
    slot: usize,
    frames: usize,
}

impl Feed<'_> {
    fn word(&mut self, word: i32, out: &mut impl std::io::Write) -> anyhow::Result<()> {
        self.words.extend(std::iter::repeat_n(word, self.copies));
        self.slot += 1;
        if self.slot == self.channels {
            self.words.resize(self.words.len() + TDM_SLOTS - self.channels * self.copies, 0);
            self.slot = 0;
            self.frames += 1;
            if self.frames.is_multiple_of(CHUNK_FRAMES) {
                self.flush(out)?;
                self.progress.set_position(self.frames as u64);
            }
        }
        Ok(())
    }

    fn flush(&mut self, out: &mut impl std::io::Write) -> anyhow::Result<()> {
        let printer = &mut *self.printer;
        self.pipeline.push(&self.words, &mut |o| printer.print(out, o));
        self.words.clear();
        if let Some(e) = printer.error.take() {
            return Err(e).context("writing to stdout");
        }
        match printer.link.as_mut().and_then(|l| l.error.take()) {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// Pushes the last partial chunk; returns (frames, channels of an incomplete last frame).
    fn finish(mut self, out: &mut impl std::io::Write) -> anyhow::Result<(usize, usize)> {
        self.flush(out)?;
        Ok((self.frames, self.slot))
    }
}

fn progress_bar(frames: u64) -> anyhow::Result<ProgressBar> {
    use std::io::IsTerminal as _;
    let bar = if std::io::stderr().is_terminal() {
        ProgressBar::with_draw_target(Some(frames), ProgressDrawTarget::stderr())
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{spinner} analysing [{bar:40}] {percent:>3}% eta {eta}")
            .context("progress template")?
            .progress_chars("=> "),
    );
    Ok(bar)
}

/// WAV sample → TDM word (24-bit sample left-justified in i32).
struct Converter {
    /// Float: pascals at digital full scale.
    full_scale_pa: f64,
    /// Integer PCM: bits per sample.
    bits: u16,
}

impl Converter {
    fn new(spec: &hound::WavSpec, full_scale_pa: f64) -> anyhow::Result<Self> {
        match spec.sample_format {
            hound::SampleFormat::Float if spec.bits_per_sample == 32 => {}
            hound::SampleFormat::Int if (8..=32).contains(&spec.bits_per_sample) => {}
            _ => bail!("{:?} with {} bits per sample", spec.sample_format, spec.bits_per_sample),
        }
        Ok(Self { full_scale_pa, bits: spec.bits_per_sample })
    }

    fn float(&self, pa: f32) -> i32 {
        host_sim::tdm_word(pa, self.full_scale_pa)
    }

    fn int(&self, s: i32) -> i32 {
        if self.bits >= 24 {
            (s << (32 - self.bits)) & !0xFF
        } else {
            s << (32 - self.bits)
        }
    }
}

/// `--frames`: the link's bytes, written as the pipeline gives its outputs. They go to
/// `FILE.part`, renamed to `FILE` once the whole recording is through: a recording that
/// fails half-way leaves its frames so far in `FILE.part`, never a `FILE` that looks whole.
struct LinkFile {
    path: PathBuf,
    part: PathBuf,
    file: BufWriter<std::fs::File>,
    encoder: BoardEncoder,
    /// The first error (writing or encoding).
    error: Option<anyhow::Error>,
}

impl LinkFile {
    /// Removes a `path` left by an earlier run (so a failed run leaves no `FILE` that looks
    /// like its output), creates `path`.part and writes the board's `Hello` (array `id`, the
    /// recording's geometry and rate).
    fn create(path: &Path, id: u8, config: &Config) -> anyhow::Result<Self> {
        match std::fs::remove_file(path) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(e)
                    .with_context(|| format!("--frames: cannot replace {}", path.display()));
            }
            _ => {}
        }
        let mut part = path.as_os_str().to_owned();
        part.push(".part");
        let part = PathBuf::from(part);
        let file = std::fs::File::create(&part)
            .with_context(|| format!("--frames: creating {}", part.display()))?;
        let (encoder, hello) = BoardEncoder::new(id, config)?;
        let mut file = BufWriter::new(file);
        file.write_all(&hello).with_context(|| format!("writing {}", part.display()))?;
        Ok(Self { path: path.to_owned(), part, file, encoder, error: None })
    }

    /// One output as the firmware sends it.
    fn send(&mut self, output: &Output) {
        if self.error.is_some() {
            return;
        }
        let mut buf = [0u8; aim_wire::MAX_ENCODED_LEN];
        let sent = self
            .encoder
            .encode(output, &mut buf)
            .map_err(|e| anyhow::anyhow!("encoding a frame: {e:?}"))
            .and_then(|n| Ok(self.file.write_all(&buf[..n])?));
        if let Err(e) = sent {
            self.error = Some(e.context(format!("--frames {}", self.part.display())));
        }
    }

    /// Flushes what was written so far to `FILE.part` (after an error elsewhere); its path.
    fn abandon(mut self) -> PathBuf {
        // The error that stopped the run is the one reported; this flush is best effort.
        let _ = self.file.flush();
        self.part
    }

    /// Flushes the file and renames it to `FILE`; the first error met on the way, if any.
    fn finish(mut self) -> anyhow::Result<()> {
        if let Some(e) = self.error {
            return Err(e);
        }
        self.file.flush().with_context(|| format!("writing {}", self.part.display()))?;
        std::fs::rename(&self.part, &self.path)
            .with_context(|| format!("renaming {} to {}", self.part.display(), self.path.display()))
    }
}

/// Prints pipeline outputs; keeps the first write error (the pipeline's sink cannot fail).
struct Printer {
    fs: f64,
    jsonl: bool,
    error: Option<std::io::Error>,
    counts: [usize; 3],
    /// Leave DoA outputs out (a mono clip fed to every microphone).
    skip_doa: bool,
    /// `--frames`: every output that is printed (and the snippets) is also sent here.
    link: Option<LinkFile>,
}

impl Printer {
    fn print(&mut self, out: &mut impl std::io::Write, o: Output) {
        if self.error.is_some() {
            return;
        }
        if let Some(link) = &mut self.link {
            if !(self.skip_doa && matches!(o, Output::Doa(_))) {
                link.send(&o);
            }
        }
        let line = match o {
            Output::Doa(_) if self.skip_doa => return,
            // Audio for the host's inter-array delays, not an analysis result.
            Output::Snippet(_) => return,
            Output::Doa(d) => {
                self.counts[0] += 1;
                let t = d.sample_index as f64 / self.fs;
                let span = f64::from(d.span_samples) / self.fs;
                let (az, zen) =
                    (f64::from(d.azimuth_rad).to_degrees(), f64::from(d.zenith_rad).to_degrees());
                if self.jsonl {
                    serde_json::json!({
                        "kind": "doa", "t": t, "span_s": span, "azimuth_deg": az, "zenith_deg": zen,
                        "quality": d.quality, "residual_samples": d.residual, "pairs_used": d.pairs_used,
                    })
                    .to_string()
                } else {
                    format!(
                        "{t:9.3} s  doa    azimuth {az:7.2}°  zenith {zen:6.2}°  quality {:.2}  residual {:.3} samples",
                        d.quality, d.residual
                    )
                }
            }
            Output::Peaks(p) => {
                self.counts[1] += 1;
                let t = p.sample_index as f64 / self.fs;
                let span = f64::from(p.span_samples) / self.fs;
                let peaks = &p.peaks[..usize::from(p.count)];
                if self.jsonl {
                    let list: Vec<_> = peaks
                        .iter()
                        .map(|k| serde_json::json!({"hz": k.hz, "amp": k.amplitude, "harmonicity": k.harmonicity, "quality": k.quality}))
                        .collect();
                    serde_json::json!({"kind": "peaks", "t": t, "span_s": span, "rotor": p.rotor, "bpf_hz": p.bpf_hz, "peaks": list})
                        .to_string()
                } else {
                    if !p.rotor {
                        format!("{t:9.3} s  peaks  no rotor signature")
                    } else {
                        let mut s = format!("{t:9.3} s  peaks  bpf {:8.2} Hz ", p.bpf_hz);
                        for k in peaks {
                            s += &format!(
                                " [{:.2} Hz, amp {:.2e}, harm {:.2}, quality {:.2}]",
                                k.hz, k.amplitude, k.harmonicity, k.quality
                            );
                        }
                        s
                    }
                }
            }
            Output::Mfcc(f) => {
                let t = f.sample_index as f64 / self.fs;
                let hz = |h: &aim_dsp::features::HarmonicFeatures| {
                    f64::from(aim_dsp::features::F0_REF_HZ) * f64::from(h.log2_f0).exp2()
                };
                let f0 = hz(&f.harmonic);
                // The second comb (none: salience 0).
                let second =
                    (f.second.salience_db > 0.0).then(|| (hz(&f.second), f.second.salience_db));
                if self.jsonl {
                    serde_json::json!({
                        "kind": "mfcc", "t": t, "mfcc_db": f.mfcc_db.to_vec(),
                        "log_mel_db": f.log_mel_db.to_vec(), "comb_f0_hz": f0,
                        "comb_salience_db": f.harmonic.salience_db,
                        "second_comb_f0_hz": second.map(|s| s.0),
                        "second_comb_salience_db": second.map(|s| s.1),
                    })
                    .to_string()
                } else {
                    let mut line = format!(
                        "{t:9.3} s  mfcc   c0 {:7.1} dB  c1 {:6.1} dB  comb f0 {f0:7.1} Hz  salience {:.1} dB",
                        f.mfcc_db[0], f.mfcc_db[1], f.harmonic.salience_db
                    );
                    if let Some((f0, salience)) = second {
                        line += &format!("  second {f0:7.1} Hz  {salience:.1} dB");
                    }
                    line
                }
            }
            Output::Beacon(b) => {
                let arrival = b.sample_index as f64 + f64::from(b.fraction);
                let t = arrival / self.fs;
                if self.jsonl {
                    serde_json::json!({
                        "kind": "beacon", "t": t, "arrival_samples": arrival,
                        "quality": b.quality, "level_db": b.level_db,
                    })
                    .to_string()
                } else {
                    format!(
                        "{t:9.6} s  beacon arrival {arrival:.4} samples  quality {:.3}  level {:.1} dBFS",
                        b.quality, b.level_db
                    )
                }
            }
            Output::Health(h) => {
                self.counts[2] += 1;
                let t = h.sample_index as f64 / self.fs;
                if self.jsonl {
                    serde_json::json!({
                        "kind": "health", "t": t, "blocks": h.blocks, "clipped_samples": h.clipped_samples,
                        "peak_dbfs": h.peak_dbfs, "block_exponent": h.block_exponent,
                    })
                    .to_string()
                } else {
                    format!(
                        "{t:9.3} s  health clipped {}  peak {:.1} dBFS  exponent {}",
                        h.clipped_samples, h.peak_dbfs, h.block_exponent
                    )
                }
            }
        };
        if let Err(e) = writeln!(out, "{line}") {
            self.error = Some(e);
        }
    }
}

/// `--array`: a preset name or a TOML file.
fn load_array(spec: &str) -> anyhow::Result<Geometry> {
    if let Some(g) = preset(spec) {
        return Ok(g);
    }
    let path = Path::new(spec);
    if !path.exists() {
        bail!("--array {spec}: neither a preset (respeaker6, respeaker4, circle8) nor an existing file");
    }
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    parse_array_file(&text).with_context(|| format!("array file {}", path.display()))
}

/// Geometry presets by name (the site file's spellings are accepted too).
fn preset(name: &str) -> Option<Geometry> {
    match name {
        "respeaker6" | "respeaker-6mic" | "respeaker_6mic" => Some(Geometry::respeaker_6mic()),
        "respeaker4" | "respeaker-4mic" | "respeaker_4mic" => Some(Geometry::respeaker_4mic()),
        "circle8" | "circle-8mic" | "circle_8mic" => Some(Geometry::circle_8mic()),
        _ => None,
    }
}

/// The array file: `positions = [[x, y], ...]` (metres), or `geometry = "<preset>"`.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ArrayFile {
    geometry: Option<toml::Spanned<String>>,
    /// Exactly two numbers per microphone (serde alone reads `[x, y, z]` as `[x, y]`).
    positions: Option<toml::Spanned<Vec<aim_tracker::config::Coords<2>>>>,
}

fn parse_array_file(text: &str) -> anyhow::Result<Geometry> {
    // toml's errors name the line and column already.
    let file: ArrayFile =
        toml::from_str(text).map_err(|e| anyhow::anyhow!("{}", e.to_string().trim_end()))?;
    let line_of = |offset: usize| text[..offset.min(text.len())].matches('\n').count() + 1;
    match (file.geometry, file.positions) {
        (Some(_), Some(p)) => {
            bail!(
                "line {}: give either `geometry` or `positions`, not both",
                line_of(p.span().start)
            )
        }
        (None, None) => {
            bail!("needs `positions = [[x, y], ...]` (metres) or `geometry = \"respeaker6\"`")
        }
        (Some(g), None) => preset(g.get_ref()).ok_or_else(|| {
            anyhow::anyhow!(
                "line {}: unknown geometry `{}` (respeaker6, respeaker4, circle8)",
                line_of(g.span().start),
                g.get_ref()
            )
        }),
        (None, Some(p)) => {
            let xy: Vec<[f32; 2]> =
                p.get_ref().iter().map(|c| [c[0] as f32, c[1] as f32]).collect();
            Geometry::from_positions(&xy)
                .map_err(|e| anyhow::anyhow!("line {}: positions: {e}", line_of(p.span().start)))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn array_files_parse_or_name_their_line() {
        let g = parse_array_file(
            "# square\npositions = [[0.0, 0.0], [0.1, 0.0], [0.1, 0.1], [0.0, 0.1]]\n",
        )
        .unwrap();
        assert_eq!(g.len(), 4);
        assert_eq!(parse_array_file("geometry = \"circle8\"").unwrap(), Geometry::circle_8mic());
        let e = format!(
            "{:#}",
            parse_array_file("\n\npositions = [[0.0, 0.0], [0.1, 0.0], [0.2, 0.0]]").unwrap_err()
        );
        assert!(e.contains("line 3") && e.contains("3 microphones"), "{e}");
        let e = format!(
            "{:#}",
            parse_array_file("positions = [[0.0, 0.0],\n [0.1, \"x\"]]").unwrap_err()
        );
        assert!(e.contains("line 2"), "{e}");
        // A third number is refused at its line, not dropped.
        let e = format!(
            "{:#}",
            parse_array_file("positions = [[0.0, 0.0],\n [0.1, 0.0, 1.0], [0.1, 0.1], [0.0, 0.1]]")
                .unwrap_err()
        );
        assert!(e.contains("line 2") && e.contains("2 numbers"), "{e}");
        let e = format!("{:#}", parse_array_file("\ngeometry = \"hexagon\"").unwrap_err());
        assert!(e.contains("line 2") && e.contains("hexagon"), "{e}");
        let e = format!("{:#}", parse_array_file("radius = 3").unwrap_err());
        assert!(e.contains("radius"), "{e}");
    }

    #[test]
    fn samples_become_left_justified_24_bit_words() {
        let spec = |fmt, bits| hound::WavSpec {
            channels: 1,
            sample_rate: 48_000,
            bits_per_sample: bits,
            sample_format: fmt,
        };
        let f = Converter::new(&spec(hound::SampleFormat::Float, 32), 20.0).unwrap();
        assert_eq!(f.float(10.0), (4_194_304) << 8); // half of full scale
        assert_eq!(f.float(-100.0), i32::MIN); // saturated
        assert_eq!(f.float(f32::NAN), 0);
        let i16c = Converter::new(&spec(hound::SampleFormat::Int, 16), 20.0).unwrap();
        assert_eq!(i16c.int(-2), -2 << 16);
        let i24 = Converter::new(&spec(hound::SampleFormat::Int, 24), 20.0).unwrap();
        assert_eq!(i24.int(0x12_3456), 0x1234_5600);
        let i32c = Converter::new(&spec(hound::SampleFormat::Int, 32), 20.0).unwrap();
        assert_eq!(i32c.int(0x1234_5678), 0x1234_5600);
        assert!(Converter::new(&spec(hound::SampleFormat::Float, 64), 20.0).is_err());
    }
}
