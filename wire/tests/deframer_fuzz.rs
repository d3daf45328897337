//! The deframer against a million random and mutated inputs (seeded, so every run is the same
//! run): it never panics, accounts for every chunk, and recovers every frame that garbage or
//! mutations did not touch. Plus proptest on arbitrary byte strings, for shrinking.

mod common;

use aim_wire::{DecodeError, Deframer, Frame, LinkStats};
use common::{chunk_count, random_frame, wire, Rng};
use proptest::prelude::*;

/// Inputs per family; three families, so 1.05 million inputs in all.
const CASES_PER_FAMILY: usize = 350_000;

/// Feeds `stream` in random chunk sizes (the deframer must not care where reads split) and
/// returns the frames decoded and the final statistics.
fn deframe(rng: &mut Rng, stream: &[u8]) -> (Vec<Frame>, LinkStats) {
    let mut deframer: Deframer = Deframer::new();
    let mut frames = Vec::new();
    let mut rest = stream;
    while !rest.is_empty() {
        let n = 1 + rng.below(rest.len().min(64));
        let (now, later) = rest.split_at(n);
        frames.extend(deframer.feed(now).flatten());
        rest = later;
    }
    deframer.finish();
    let stats = *deframer.stats();
    // Every byte seen; every chunk between delimiters is one outcome, a frame or an error.
    assert_eq!(stats.bytes, stream.len() as u64);
    assert_eq!(stats.frames + stats.errors(), chunk_count(stream), "chunk accounting");
    (frames, stats)
}

/// A pool of encoded random frames of every kind, with distinct sequence numbers.
fn frame_pool(rng: &mut Rng) -> Vec<(Frame, Vec<u8>)> {
    (0..4096u16)
        .map(|seq| {
            let array_id = rng.byte();
            let frame = random_frame(rng, array_id, seq);
            let bytes = wire(&frame);
            (frame, bytes)
        })
        .collect()
}

#[test]
fn a_million_random_and_mutated_inputs() {
    let mut rng = Rng::new(0x00A1_3000_5EED);
    let pool = frame_pool(&mut rng);
    let mut inputs = 0usize;

    // 1. Valid frames embedded in garbage (which itself contains delimiters now and then):
    //    every frame comes out, in order, and nothing else does.
    for _ in 0..CASES_PER_FAMILY {
        let mut stream = Vec::new();
        let mut embedded = Vec::new();
        for _ in 0..1 + rng.below(4) {
            let len = rng.below(48);
            stream.extend(rng.garbage(len, 16));
            let (frame, bytes) = &pool[rng.below(pool.len())];
            stream.extend_from_slice(bytes);
            embedded.push(frame.clone());
        }
        let len = rng.below(48);
        stream.extend(rng.garbage(len, 16));
        let (frames, stats) = deframe(&mut rng, &stream);
        assert_eq!(frames, embedded, "stream {stream:02x?}");
        assert_eq!(stats.frames, embedded.len() as u64);
        inputs += 1;
    }

    // 2. Valid streams with random mutations (flip, zero, insert, delete): every frame whose
    //    bytes (delimiters included) were not touched comes out; no frame that was not sent does.
    for _ in 0..CASES_PER_FAMILY {
        let count = 1 + rng.below(5);
        let picked: Vec<&(Frame, Vec<u8>)> =
            (0..count).map(|_| &pool[rng.below(pool.len())]).collect();
        // Each byte remembers which frame it belongs to; inserted bytes belong to none.
        let mut stream: Vec<(u8, Option<usize>)> = picked
            .iter()
            .enumerate()
            .flat_map(|(i, (_, bytes))| bytes.iter().map(move |&b| (b, Some(i))))
            .collect();
        let mut touched = vec![false; count];
        for _ in 0..1 + rng.below(3) {
            let at = rng.below(stream.len() + 1);
            match rng.below(4) {
                0 if at < stream.len() => {
                    let flip = 1 + rng.below(255) as u8;
                    stream[at].0 ^= flip;
                    if let Some(i) = stream[at].1 {
                        touched[i] = true;
                    }
                }
                1 if at < stream.len() && stream[at].0 != 0 => {
                    stream[at].0 = 0;
                    if let Some(i) = stream[at].1 {
                        touched[i] = true;
                    }
                }
                2 => {
                    // Inserting between two bytes of one frame touches it.
                    let before = at.checked_sub(1).and_then(|s| stream.get(s)).and_then(|b| b.1);
                    let after = stream.get(at).and_then(|b| b.1);
                    if let (Some(i), Some(j)) = (before, after) {
                        if i == j {
                            touched[i] = true;
                        }
                    }
                    stream.insert(at, (rng.byte(), None));
                }
                _ if at < stream.len() => {
                    if let Some(i) = stream[at].1 {
                        touched[i] = true;
                    }
                    stream.remove(at);
                }
                _ => {}
            }
        }
        let bytes: Vec<u8> = stream.iter().map(|b| b.0).collect();
        let (frames, _) = deframe(&mut rng, &bytes);
        // Recovered frames are a subsequence of the sent ones...
        let mut next = 0;
        for frame in &frames {
            let found = picked[next..].iter().position(|(f, _)| f == frame);
            let found =
                found.unwrap_or_else(|| panic!("phantom frame {frame:?} from {bytes:02x?}"));
            next += found + 1;
        }
        // ...that contains every untouched one.
        for (i, (frame, _)) in picked.iter().enumerate() {
            if !touched[i] {
                assert!(frames.contains(frame), "untouched frame {i} lost in {bytes:02x?}");
            }
        }
        inputs += 1;
    }

    // 3. Pure random bytes, sometimes dense in delimiters, sometimes with none for a long time
    //    (oversize chunks): no panic, and the accounting holds (checked in `deframe`).
    for _ in 0..CASES_PER_FAMILY {
        let max_len = if rng.below(100) == 0 { 2000 } else { 200 };
        let len = rng.below(max_len);
        let zero_every = [2, 16, 256, 100_000][rng.below(4)];
        let stream = rng.garbage(len, zero_every);
        let (frames, _) = deframe(&mut rng, &stream);
        assert!(frames.is_empty(), "a frame out of random bytes: {stream:02x?}");
        inputs += 1;
    }

    assert!(inputs >= 1_000_000, "{inputs} inputs");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2048, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic_and_are_all_accounted_for(
        stream in proptest::collection::vec(any::<u8>(), 0..4096)
    ) {
        let mut deframer: Deframer = Deframer::new();
        let outcomes: Vec<Result<Frame, DecodeError>> = deframer.feed(&stream).collect();
        let tail = deframer.finish();
        let stats = deframer.stats();
        prop_assert_eq!(outcomes.len() as u64 + u64::from(tail.is_some()), chunk_count(&stream));
        prop_assert_eq!(stats.frames + stats.errors(), chunk_count(&stream));
    }

    #[test]
    fn a_frame_after_any_prefix_is_recovered(
        prefix in proptest::collection::vec(any::<u8>(), 0..1024), seed in any::<u64>()
    ) {
        let frame = random_frame(&mut Rng::new(seed), 7, 1);
        let mut deframer: Deframer = Deframer::new();
        let _ = deframer.feed(&prefix).count();
        let out: Vec<_> = deframer.feed(&wire(&frame)).filter_map(Result::ok).collect();
        prop_assert_eq!(out, vec![frame]);
    }
}
