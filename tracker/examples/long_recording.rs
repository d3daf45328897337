//! Writes a synthetic recording of one array's link for long-run benchmarks of `aim replay`
//! and `aim track` (memory over hours): a drone hovering and circling in turns above array 1
//! at (0, 0, 0), with the DSP's frame rates at 48 kHz (a bearing every 8192 samples, a
//! spectrum every 24 576, a Health every 48 000).
//!
//! ```text
//! cargo run --release -p aim-tracker --example long_recording -- HOURS OUT.aimraw
//! aim replay OUT.aimraw --site SITE.toml   # SITE: one [[array]] id = 1 at the origin
//! ```

use std::io::Write as _;

use aim_wire::{Body, Doa, Frame, Header, Health, Hello, Peak, Peaks, MAX_ENCODED_LEN};

fn main() -> std::io::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let (Some(hours), Some(out)) = (args.get(1).and_then(|h| h.parse::<f64>().ok()), args.get(2))
    else {
        eprintln!("usage: long_recording HOURS OUT.aimraw");
        std::process::exit(2);
    };
    let fs = 48_000u64;
    let end = (hours * 3600.0 * fs as f64) as u64;
    let mut file = std::io::BufWriter::new(std::fs::File::create(out)?);
    let mut seq = 0u16;
    let mut put = |file: &mut std::io::BufWriter<std::fs::File>, index: u64, body: Body| {
        let frame = Frame { header: Header { array_id: 1, seq, sample_index: index }, body };
        seq = seq.wrapping_add(1);
        let mut buf = [0u8; MAX_ENCODED_LEN];
        let n = aim_wire::encode(&frame, &mut buf).expect("frame fits");
        file.write_all(&buf[..n])
    };
    put(&mut file, 0, Body::Hello(Hello::new([0, 1, 0], 48_000, 1024, &[[0.0463, 0.0]])))?;
    let (doa_step, peaks_step, health_step) = (8192u64, 24_576u64, 48_000u64);
    let mut next = [0u64, 0, 0];
    loop {
        let index = *next.iter().min().expect("three streams");
        if index >= end {
            break;
        }
        let t = index as f64 / fs as f64;
        // 60 s cycles: 20 s hover, 40 s of a 4 m circle at 2.5 m height.
        let phase = t % 60.0;
        let angle = if phase < 20.0 { 0.0 } else { (phase - 20.0) / 40.0 * std::f64::consts::TAU };
        let p = [4.0 * angle.cos(), 4.0 * angle.sin(), 2.5];
        if index == next[0] {
            let az = p[1].atan2(p[0]) as f32;
            let zen = (p[0].hypot(p[1])).atan2(p[2]) as f32;
            let wobble = (0.01 * (t * 7.3).sin()) as f32;
            let doa =
                Doa { span_samples: 8192, pairs_used: 15, ..Doa::new(az + wobble, zen, 0.2, 0.8) };
            put(&mut file, index, Body::Doa(doa))?;
            next[0] += doa_step;
        }
        if index == next[1] {
            let bpf = if phase < 20.0 { 328.0 } else { 331.0 } + (0.3 * (t * 3.1).sin()) as f32;
            let peaks = Peaks {
                span_samples: 24_576,
                bpf_chz: (bpf * 100.0) as u32,
                peaks: [Peak::new(bpf, -20.0, 0.9)].into_iter().collect(),
                detection: aim_wire::Detection::Rotor,
                quality: [230].into_iter().collect(),
            };
            put(&mut file, index, Body::Peaks(peaks))?;
            next[1] += peaks_step;
        }
        if index == next[2] {
            let health = Health { blocks: (index / 1024) as u32, ..Health::default() };
            put(&mut file, index, Body::Health(health))?;
            next[2] += health_step;
        }
    }
    file.flush()
}
