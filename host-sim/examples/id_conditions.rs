//! The drawn distance and background of `host-sim id-dataset`'s drone clips, for looking at
//! where a classifier fails: `id_conditions SEED CLIPS` prints `class seed distance_m
//! background_db` per drone clip, with the dataset's default ranges (3–15 m, 55–70 dB).
//! It repeats the first draws of `host_sim::iddata::drone_scene`.
use host_sim::drones::DroneType;
use host_sim::iddata::clip_seed;
use rand::{rngs::StdRng, Rng, SeedableRng};

fn main() {
    let a: Vec<u64> = std::env::args().skip(1).map(|s| s.parse().expect("SEED CLIPS")).collect();
    let (base, clips) = (a[0], a[1]);
    for (c, ty) in DroneType::ALL.iter().enumerate() {
        for i in 0..clips {
            let seed = base + i;
            let mut rng = StdRng::seed_from_u64(clip_seed(c, seed));
            let _airframe: u64 = rng.random();
            let distance = rng.random_range(3.0..15.0);
            let bg: f64 = rng.random_range(55.0..70.0);
            println!("{} {seed} {distance:.2} {bg:.1}", ty.name());
        }
    }
}
