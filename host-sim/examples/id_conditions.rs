//! The drawn distance and background of `host-sim id-dataset`'s drone clips, for looking at
//! where a classifier fails: `id_conditions SEED CLIPS` prints `class seed distance_m
//! background_db` per drone clip, with the dataset's default ranges (3–15 m, 55–70 dB), from
//! `host_sim::iddata::drone_conditions` (the draws `drone_scene` makes).
use host_sim::drones::DroneType;
use host_sim::iddata::{clip_seed, drone_conditions, Options};

fn main() {
    let a: Vec<u64> = std::env::args().skip(1).map(|s| s.parse().expect("SEED CLIPS")).collect();
    let (base, clips) = (a[0], a[1]);
    let o = Options::default();
    for (c, &ty) in DroneType::ALL.iter().enumerate() {
        for i in 0..clips {
            let seed = base + i;
            let (distance, bg) = drone_conditions(ty, clip_seed(c, seed), &o);
            println!("{} {seed} {distance:.2} {bg:.1}", ty.name());
        }
    }
}
