//! Encoder and deframer throughput on the host (`cargo bench -p aim-wire --bench throughput`).
//! Wall-clock numbers for BENCHMARKS.md; nothing here asserts a time.

#[path = "../tests/common/mod.rs"]
mod common;

use std::hint::black_box;
use std::time::Instant;

use aim_wire::{encode, Deframer, MAX_ENCODED_LEN};

fn main() {
    let mut rng = common::Rng::new(7);
    let frames: Vec<_> = (0..4096u16).map(|seq| common::random_frame(&mut rng, 1, seq)).collect();

    // Encoding: frames per second.
    let mut buf = [0u8; MAX_ENCODED_LEN];
    let rounds = 200;
    let start = Instant::now();
    let mut bytes = 0usize;
    for _ in 0..rounds {
        for f in &frames {
            bytes += encode(black_box(f), &mut buf).unwrap();
        }
    }
    let secs = start.elapsed().as_secs_f64();
    let n = (rounds * frames.len()) as f64;
    println!(
        "encode: {:.0} ns/frame ({:.1} MB/s of wire bytes, mean frame {:.1} B)",
        secs / n * 1e9,
        bytes as f64 / secs / 1e6,
        bytes as f64 / n
    );

    // Deframing a clean stream, and a stream of random bytes.
    let stream: Vec<u8> = frames.iter().flat_map(common::wire).collect();
    let garbage = rng.garbage(stream.len(), 64);
    for (label, input) in [("deframe clean", &stream), ("deframe random", &garbage)] {
        let start = Instant::now();
        let mut decoded = 0u64;
        for _ in 0..rounds {
            let mut d: Deframer = Deframer::new();
            decoded += d.feed(black_box(input)).filter(Result::is_ok).count() as u64;
        }
        let secs = start.elapsed().as_secs_f64();
        println!(
            "{label}: {:.1} MB/s ({} frames per pass)",
            (rounds * input.len()) as f64 / secs / 1e6,
            decoded / rounds as u64
        );
    }
    println!("size_of::<Deframer>() = {} bytes", std::mem::size_of::<Deframer>());
}
