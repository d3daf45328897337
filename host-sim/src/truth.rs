//! Ground truth of a simulated flight, written as `truth.csv`.
//!
//! Columns: `t` (s, scenario time), `x,y,z` (ENU m, centre of mass), `vx,vy,vz` (m/s), `yaw`
//! (rad, body x from ENU +x towards +y), `roll,pitch` (rad), `ax,ay,az` (m/s²),
//! `rotor1_hz .. rotorN_hz` (rotor speeds in revolutions per second, paper numbering; times the
//! blade count gives each rotor's BPF), then `los_<id>` per array (1 when the straight line from
//! the drone's centre to the array centre crosses no obstacle).
//!
//! `truth.toml` ([`Truth::to_toml`]) holds the rest of what only the simulation knows: each
//! array's sample clock against true time and the airframe the run drew from its population.
//! Neither reaches the site file.
use std::fmt::Write as _;

use crate::array::Clock;
use crate::profile::Airframe;

/// One row of the truth.
#[derive(Clone, Debug, PartialEq)]
pub struct TruthRow {
    /// Scenario time, s.
    pub t_s: f64,
    /// Position, ENU m.
    pub position: [f64; 3],
    /// Velocity, m/s.
    pub velocity: [f64; 3],
    /// Acceleration, m/s².
    pub acceleration: [f64; 3],
    /// Heading, rad.
    pub yaw_rad: f64,
    /// Roll, rad.
    pub roll_rad: f64,
    /// Pitch, rad.
    pub pitch_rad: f64,
    /// Rotor speeds, Hz (revolutions per second).
    pub rotor_hz: Vec<f64>,
    /// Line of sight to each array, in the order of `Truth::array_ids`.
    pub los: Vec<bool>,
}

/// The truth table.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Truth {
    /// Blades per propeller (BPF = blades × rotor speed).
    pub blades: u32,
    /// Array ids of the `los` columns.
    pub array_ids: Vec<u8>,
    /// Each array's sample clock against true time, in the order of `array_ids` (empty: every
    /// array on true time).
    pub clocks: Vec<Clock>,
    /// The airframe flown, if known.
    pub airframe: Option<Airframe>,
    /// Rows in time order.
    pub rows: Vec<TruthRow>,
}

impl Truth {
    /// True time, s, of the instant array number `array_index` (order of `array_ids`) calls
    /// `t_array` seconds by its own sample clock (sample index over nominal rate).
    pub fn true_time(&self, array_index: usize, t_array: f64) -> f64 {
        self.clocks
            .get(array_index)
            .map_or(t_array, |c| c.offset_s + t_array / (1.0 + c.drift_ppm * 1e-6))
    }

    /// `truth.toml`: every array's clock (`[[array]]` id, clock_offset_s, clock_drift_ppm) and
    /// the airframe (`[airframe]`, [`Airframe`]'s fields).
    pub fn to_toml(&self) -> String {
        let mut s = String::from(
            "# AIM simulation truth: what only the simulator knows (never in site.toml).\n",
        );
        if let Some(a) = &self.airframe {
            let _ = writeln!(s, "[airframe]\n{}", a.to_toml());
        }
        for (id, c) in self.array_ids.iter().zip(&self.clocks) {
            let _ = writeln!(
                s,
                "[[array]]\nid = {id}\nclock_offset_s = {:?}\nclock_drift_ppm = {:?}\n",
                c.offset_s, c.drift_ppm
            );
        }
        s
    }

    /// The CSV text (header row first).
    pub fn to_csv(&self) -> String {
        let rotors = self.rows.first().map_or(0, |r| r.rotor_hz.len());
        let mut s = String::from("t,x,y,z,vx,vy,vz,yaw,roll,pitch,ax,ay,az");
        for i in 1..=rotors {
            let _ = write!(s, ",rotor{i}_hz");
        }
        for id in &self.array_ids {
            let _ = write!(s, ",los_{id}");
        }
        s.push('\n');
        for r in &self.rows {
            let _ = write!(
                s,
                "{:.4},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5},{:.6},{:.6},{:.6},{:.4},{:.4},{:.4}",
                r.t_s,
                r.position[0],
                r.position[1],
                r.position[2],
                r.velocity[0],
                r.velocity[1],
                r.velocity[2],
                r.yaw_rad,
                r.roll_rad,
                r.pitch_rad,
                r.acceleration[0],
                r.acceleration[1],
                r.acceleration[2]
            );
            for f in &r.rotor_hz {
                let _ = write!(s, ",{f:.4}");
            }
            for l in &r.los {
                let _ = write!(s, ",{}", u8::from(*l));
            }
            s.push('\n');
        }
        s
    }
}
