//! host-sim's room against an independent room simulator: golden figures from
//! pyroomacoustics' image-source method (`tools/reverb/oracle_ir.py`, committed as
//! `tests/data/room_oracle.json`; this test needs no Python). The same static geometry and wall
//! absorption are simulated here with images to order 3 and the statistical late tail
//! (`host_sim::reverb`) in place of pyroomacoustics' images to order 35–58.
use host_sim::reverb;
use host_sim::room::Room;
use nalgebra::Vector3;
use serde_json::Value;

fn oracle() -> Value {
    let text = include_str!("data/room_oracle.json");
    serde_json::from_str(text).expect("golden file parses")
}

fn vec3(v: &Value) -> Vector3<f64> {
    let a: Vec<f64> =
        v.as_array().expect("array").iter().map(|x| x.as_f64().expect("number")).collect();
    Vector3::new(a[0], a[1], a[2])
}

fn room_of(r: &Value, order: u32, late_tail: bool) -> Room {
    let size = vec3(&r["size_m"]);
    Room {
        size_m: [size.x, size.y, size.z],
        absorption: [r["alpha"].as_f64().expect("alpha"); 6],
        reflection_order: order,
        late_tail,
    }
}

#[test]
fn early_images_have_pyroomacoustics_delays_and_gains() {
    // Every image of order ≤ 2 (25 of them): its delay at each microphone within 1 ns and its
    // pressure gain within 1e-6 (the golden file stores pyroomacoustics' float32 damping).
    let o = oracle();
    let c = o["c_mps"].as_f64().expect("c");
    for r in o["rooms"].as_array().expect("rooms") {
        let room = room_of(r, 2, false);
        let s = vec3(&r["source_m"]);
        let mics: Vec<Vector3<f64>> =
            r["mics_m"].as_array().expect("mics").iter().map(vec3).collect();
        let mut ours: Vec<(u32, f64, Vec<f64>)> = room
            .images()
            .iter()
            .map(|im| {
                let p = im.apply(&s);
                (im.order, im.reflection_gain, mics.iter().map(|m| (p - m).norm() / c).collect())
            })
            .collect();
        let golden = r["images"].as_array().expect("images");
        assert_eq!(ours.len(), golden.len(), "{}", r["name"]);
        for g in golden {
            let delays: Vec<f64> = g["delays_s"]
                .as_array()
                .expect("delays")
                .iter()
                .map(|x| x.as_f64().expect("d"))
                .collect();
            let pos = ours
                .iter()
                .position(|o| o.2.iter().zip(&delays).all(|(a, b)| (a - b).abs() < 1e-9))
                .unwrap_or_else(|| panic!("{}: no image with delays {delays:?}", r["name"]));
            let (order, gain, _) = ours.remove(pos);
            assert_eq!(u64::from(order), g["order"].as_u64().expect("order"));
            assert!((gain - g["gain"].as_f64().expect("gain")).abs() < 1e-6);
        }
    }
}

#[test]
fn decay_and_direct_to_reverberant_ratio_match_pyroomacoustics() {
    // Tolerances: T30 within 6 %, direct-to-reverberant ratio within 1 dB, per microphone.
    let o = oracle();
    let c = o["c_mps"].as_f64().expect("c");
    let fs = o["fs_hz"].as_f64().expect("fs");
    for r in o["rooms"].as_array().expect("rooms") {
        let room = room_of(r, 3, true);
        let s = vec3(&r["source_m"]);
        let mics: Vec<Vector3<f64>> =
            r["mics_m"].as_array().expect("mics").iter().map(vec3).collect();
        for (mi, (m, g)) in mics.iter().zip(r["mics"].as_array().expect("mics")).enumerate() {
            let h = reverb::impulse_response(&room, c, &s, m, fs, 17 + mi as u64);
            let e: Vec<f64> = h.iter().map(|x| x * x).collect();
            let t30 = reverb::t30_from_energy(&e, fs).expect("decays 35 dB");
            let want = g["t30_s"].as_f64().expect("t30");
            let k = ((s - m).norm() / c * fs).round() as usize;
            let w = (0.0025 * fs).round() as usize;
            let direct: f64 = e[k.saturating_sub(w)..=k + w].iter().sum();
            let drr = 10.0 * (direct / (e.iter().sum::<f64>() - direct)).log10();
            let want_drr = g["drr_db"].as_f64().expect("drr");
            eprintln!(
                "{} mic {mi}: T30 {t30:.3} s (pyroomacoustics {want:.3}), DRR {drr:.2} dB ({want_drr:.2})",
                r["name"]
            );
            assert!(
                (t30 / want - 1.0).abs() < 0.06,
                "{} mic {mi}: T30 {t30:.3} vs {want:.3}",
                r["name"]
            );
            assert!(
                (drr - want_drr).abs() < 1.0,
                "{} mic {mi}: DRR {drr:.2} vs {want_drr:.2}",
                r["name"]
            );
        }
    }
}
