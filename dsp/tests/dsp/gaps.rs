//! Gaps in the input (`Pipeline::gap`): the sample clock jumps by the lost frames, outputs whose
//! span would cross the gap are dropped and counted, everything else is untouched.

use crate::common;

use aim_dsp::{Config, Doa, Geometry, Output, Peaks, Pipeline};
use common::{doas, to_tdm};

const SLOTS: usize = 8;
const AZ_DEG: f64 = 70.0;
const ZEN_DEG: f64 = 40.0;

/// A plane wave of band-limited noise plus a harmonic comb from (AZ_DEG, ZEN_DEG), 48 kHz.
fn plane_wave(geometry: &Geometry, frames: usize, seed: u64) -> Vec<i32> {
    let channels =
        common::plane_wave(geometry, 48_000.0, frames, (AZ_DEG, ZEN_DEG), 250, 7_000.0, seed);
    to_tdm(&channels, SLOTS)
}

fn peaks(outputs: &[Output]) -> Vec<Peaks> {
    outputs.iter().filter_map(|o| if let Output::Peaks(p) = o { Some(*p) } else { None }).collect()
}

fn snippets(out: &[Output]) -> Vec<aim_dsp::Snippet> {
    out.iter().filter_map(|o| if let Output::Snippet(x) = o { Some(*x) } else { None }).collect()
}

fn snippet_span(x: &aim_dsp::Snippet) -> u32 {
    (aim_dsp::snippet::SNIPPET_LEN * usize::from(x.decimation)) as u32
}

fn end(index: u64, span: u32) -> u64 {
    index + u64::from(span)
}

/// Runs `words` with the frames `[gap_at, gap_at + lost)` left out and `Pipeline::gap(lost)`
/// in their place; `split_words` more words of frame `gap_at` are pushed before the gap (an
/// incomplete frame, whose index then counts as used).
fn run_with_gap(
    config: &Config,
    words: &[i32],
    gap_at: usize,
    split_words: usize,
    lost: usize,
) -> (Vec<Output>, Pipeline) {
    let mut p = Pipeline::new(config).unwrap();
    let mut out = common::run(&mut p, &words[..gap_at * SLOTS + split_words]);
    p.gap(lost as u64);
    let resume = (gap_at + usize::from(split_words > 0) + lost) * SLOTS;
    out.extend(common::run(&mut p, &words[resume..]));
    (out, p)
}

#[test]
fn a_gap_drops_the_outputs_spanning_it_counts_them_and_keeps_the_clock() {
    let g = Geometry::circle_8mic();
    let config = Config::new(g, 48_000);
    let frames = 131_072;
    let words = plane_wave(&g, frames, 7);
    let mut reference = Pipeline::new(&config).unwrap();
    let ref_out = common::run(&mut reference, &words);
    assert_eq!(reference.gap_stats(), aim_dsp::GapStats::default(), "no gap, nothing counted");

    // Mid-way through the sixth DoA average (blocks of 1024, 8 per DoA: 40 960..49 152), in
    // the block that starts at 43 008.
    let (gap_at, lost) = (43_960usize, 5_000usize);
    let resume = (gap_at + lost) as u64;
    let (out, p) = run_with_gap(&config, &words, gap_at, 0, lost);
    let span = config.average_blocks * config.block_len as u32;

    // Before the gap: the same outputs, bit for bit.
    let before = |o: &&Output| match o {
        Output::Doa(d) => end(d.sample_index, d.span_samples) <= gap_at as u64,
        Output::Peaks(k) => end(k.sample_index, k.span_samples) <= gap_at as u64,
        Output::Mfcc(f) => end(f.sample_index, f.span_samples) <= gap_at as u64,
        Output::Beacon(b) => end(b.sample_index, aim_dsp::beacon::LEN as u32) <= gap_at as u64,
        Output::Snippet(x) => end(x.sample_index, snippet_span(x)) <= gap_at as u64,
        Output::Health(_) => false,
    };
    let ref_before: Vec<_> = ref_out.iter().filter(before).collect();
    let gap_before: Vec<_> = out.iter().filter(before).collect();
    assert_eq!(doas(&ref_out).iter().filter(|d| end(d.sample_index, span) <= 40_960).count(), 5);
    assert_eq!(gap_before, ref_before);

    // No output spans the gap; DoAs after it are stamped on the real clock, from the first
    // frame after the gap on, one per average.
    for o in &out {
        let (start, stop) = match o {
            Output::Doa(d) => (d.sample_index, end(d.sample_index, d.span_samples)),
            Output::Peaks(k) => (k.sample_index, end(k.sample_index, k.span_samples)),
            Output::Mfcc(f) => (f.sample_index, end(f.sample_index, f.span_samples)),
            Output::Beacon(b) => (b.sample_index, end(b.sample_index, aim_dsp::beacon::LEN as u32)),
            Output::Snippet(x) => (x.sample_index, end(x.sample_index, snippet_span(x))),
            Output::Health(_) => continue,
        };
        assert!(stop <= gap_at as u64 || start >= resume, "{o:?} spans the gap");
    }
    let after: Vec<Doa> = doas(&out).into_iter().filter(|d| d.sample_index >= resume).collect();
    let expected: Vec<u64> = (0..)
        .map(|k| resume + k * u64::from(span))
        .take_while(|&s| end(s, span) <= frames as u64)
        .collect();
    assert_eq!(expected.len(), 10);
    assert_eq!(after.iter().map(|d| d.sample_index).collect::<Vec<_>>(), expected);
    for d in &after {
        let daz =
            (f64::from(d.azimuth_rad).to_degrees() - AZ_DEG + 540.0).rem_euclid(360.0) - 180.0;
        let dzen = f64::from(d.zenith_rad).to_degrees() - ZEN_DEG;
        assert!(daz.abs() < 2.0 && dzen.abs() < 2.0, "after the gap: {d:?}");
    }

    // BPF windows (4096 samples at 8 kHz = 24 576 input samples, hop 12 288): the spectral path
    // was fed 43 008 samples before the gap (the partial block is dropped) and 80 blocks after.
    // Of its windows starting at 0, 12 288, …, 98 304 (9), those at 24 576 and 36 864 hold
    // samples from both sides of the gap: dropped. The rest keep their stamps, shifted by the
    // 5 952 samples skipped (952 of the partial block, 5 000 lost) after the gap.
    let k = peaks(&out);
    let stamps: Vec<u64> = k.iter().map(|x| x.sample_index).collect();
    let shifted: Vec<u64> = [49_152u64, 61_440, 73_728, 86_016, 98_304].map(|c| c + 5_952).into();
    assert_eq!(stamps, [&[0u64, 12_288][..], &shifted].concat());
    // Counting oracle: a contiguous stream as long as what the spectral path was fed gives
    // as many analyses as were kept and dropped.
    let mut contiguous = Pipeline::new(&config).unwrap();
    let fed = 43_008 + 80 * 1024;
    let all = peaks(&common::run(&mut contiguous, &words[..fed * SLOTS])).len();
    assert_eq!(all, 9);
    let stats = p.gap_stats();
    assert_eq!((stats.gaps, stats.frames_lost), (1, lost as u64));
    // One DoA average abandoned (blocks 40 960.. and the partial block) and two BPF windows.
    assert_eq!(stats.outputs_dropped, 1 + (all - k.len()) as u32);
    assert_eq!(stats.outputs_dropped, 3);

    // Snippets (256 samples at 8 kHz = 1 536 input samples): the 43 008 samples before the gap
    // are 28 whole snippets, kept as they were; after the gap the stream goes on contiguous
    // from the first sample after it (43 008 + 5 952 on the real clock), 53 snippets in the 80
    // blocks; none dropped (the gap fell on a snippet boundary of the spectral path's count).
    let expected: Vec<u64> =
        (0..28u64).map(|k| k * 1536).chain((0..53u64).map(|k| 43_008 + 5_952 + k * 1536)).collect();
    assert_eq!(snippets(&out).iter().map(|x| x.sample_index).collect::<Vec<_>>(), expected);

    // Health keeps coming, stamped on the real clock.
    let health: Vec<_> = out
        .iter()
        .filter_map(|o| if let Output::Health(h) = o { Some(*h) } else { None })
        .collect();
    assert_eq!(health.len(), 2, "122 blocks processed: one Health per 48");
    assert_eq!(health[0].sample_index, 0);
    assert_eq!(health[1].sample_index, resume + (48 - 42) * 1024);
}

#[test]
fn a_gap_after_an_odd_frame_and_inside_a_frame_keeps_exact_stamps() {
    // At 48 kHz the front end decimates by two: an odd frame count leaves a pair open, and a
    // push that ends inside a frame leaves it incomplete. Both cases resume on the exact index.
    let g = Geometry::respeaker_6mic();
    let config = Config::new(g, 48_000);
    let frames = 65_536;
    let words = plane_wave(&g, frames, 11);
    let span = u64::from(config.average_blocks * config.block_len as u32);
    for (gap_at, split_words, lost) in
        [(20_001usize, 0usize, 1usize), (20_001, 3, 777), (20_000, 5, 4_097)]
    {
        let (out, p) = run_with_gap(&config, &words, gap_at, split_words, lost);
        let resume = (gap_at + usize::from(split_words > 0) + lost) as u64;
        let after: Vec<u64> =
            doas(&out).iter().map(|d| d.sample_index).filter(|&s| s >= resume).collect();
        let expected: Vec<u64> =
            (0..).map(|k| resume + k * span).take_while(|&s| s + span <= frames as u64).collect();
        assert!(expected.len() >= 4);
        assert_eq!(after, expected, "gap at {gap_at} (+{split_words} words), {lost} lost");
        let before = doas(&out).iter().filter(|d| d.sample_index < resume).count();
        assert_eq!(before, 2, "the two averages that ended at 16 384 before the gap");
        // Dropped: the DoA average in progress and the BPF windows a contiguous stream of the
        // blocks the pipeline processed would have produced but this run did not.
        let fed = (gap_at / 1024 + (frames - resume as usize) / 1024) * 1024;
        let mut contiguous = Pipeline::new(&config).unwrap();
        let whole = common::run(&mut contiguous, &words[..fed * SLOTS]);
        let windows_dropped = (peaks(&whole).len() - peaks(&out).len()) as u32;
        assert!(windows_dropped >= 1, "a window spans the gap");
        // The snippet in progress at the gap (the spectral path had not completed it).
        let snippets_dropped = (snippets(&whole).len() - snippets(&out).len()) as u32;
        assert_eq!(snippets_dropped, 1, "the snippet spanning the gap");
        let stats = p.gap_stats();
        assert_eq!(
            (stats.gaps, stats.frames_lost, stats.outputs_dropped),
            (1, lost as u64, 1 + windows_dropped + snippets_dropped)
        );
    }
}

#[test]
fn a_gap_of_nothing_changes_nothing() {
    let g = Geometry::respeaker_4mic();
    let config = Config::new(g, 48_000);
    let words = plane_wave(&g, 32_768, 5);
    let mut reference = Pipeline::new(&config).unwrap();
    let a = common::run(&mut reference, &words);
    let (b, p) = run_with_gap(&config, &words, 10_000, 0, 0);
    assert_eq!(a, b);
    assert_eq!(p.gap_stats(), aim_dsp::GapStats::default());
}
