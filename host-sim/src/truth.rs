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
//! Neither reaches the site file. [`Truth::parse`] reads both back (for re-scoring stored runs,
//! `host-sim bench --rescore`).
use std::fmt::Write as _;

use anyhow::{anyhow, bail, Context as _};

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

    /// Reads a truth back from the text of `truth.csv` ([`Truth::to_csv`]) and of `truth.toml`
    /// ([`Truth::to_toml`]): the rows, the array ids of the `los_<id>` columns and each array's
    /// clock. Not read back: the airframe (`None`) and the blade count (0), which the metrics
    /// do not use. Values come back at the CSV's printed precision (0.1 ms, 10 µm, 1 mm/s).
    /// Errors name the file (`csv_name`, `toml_name`) and the line.
    pub fn parse(
        csv: &str,
        csv_name: &str,
        toml_text: &str,
        toml_name: &str,
    ) -> anyhow::Result<Self> {
        let mut lines = csv.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
        let (_, header) = lines.next().ok_or_else(|| anyhow!("{csv_name}: empty, no header"))?;
        let columns: Vec<&str> = header.split(',').map(str::trim).collect();
        const FIXED: [&str; 13] =
            ["t", "x", "y", "z", "vx", "vy", "vz", "yaw", "roll", "pitch", "ax", "ay", "az"];
        if columns.len() < FIXED.len() || columns[..FIXED.len()] != FIXED {
            bail!("{csv_name}:1: header must start with {}", FIXED.join(","));
        }
        let mut rotors = 0;
        let mut array_ids = Vec::new();
        for (i, c) in columns[FIXED.len()..].iter().enumerate() {
            if array_ids.is_empty() && *c == format!("rotor{}_hz", i + 1) {
                rotors += 1;
            } else if let Some(id) = c.strip_prefix("los_") {
                array_ids.push(
                    id.parse::<u8>()
                        .with_context(|| format!("{csv_name}:1: column `{c}`: array id"))?,
                );
            } else {
                bail!("{csv_name}:1: unexpected column `{c}`");
            }
        }
        let mut rows = Vec::new();
        for (n, line) in lines {
            let v: Vec<&str> = line.split(',').map(str::trim).collect();
            if v.len() != columns.len() {
                bail!("{csv_name}:{}: {} fields, the header has {}", n + 1, v.len(), columns.len());
            }
            let num = |i: usize| -> anyhow::Result<f64> {
                v[i].parse::<f64>().with_context(|| {
                    format!(
                        "{csv_name}:{}: column `{}`: `{}` is not a number",
                        n + 1,
                        columns[i],
                        v[i]
                    )
                })
            };
            let f: Vec<f64> = (0..FIXED.len() + rotors).map(num).collect::<anyhow::Result<_>>()?;
            let los = v[FIXED.len() + rotors..]
                .iter()
                .zip(&columns[FIXED.len() + rotors..])
                .map(|(x, c)| match *x {
                    "0" => Ok(false),
                    "1" => Ok(true),
                    other => {
                        Err(anyhow!("{csv_name}:{}: column `{c}`: `{other}` is not 0 or 1", n + 1))
                    }
                })
                .collect::<anyhow::Result<Vec<bool>>>()?;
            rows.push(TruthRow {
                t_s: f[0],
                position: [f[1], f[2], f[3]],
                velocity: [f[4], f[5], f[6]],
                yaw_rad: f[7],
                roll_rad: f[8],
                pitch_rad: f[9],
                acceleration: [f[10], f[11], f[12]],
                rotor_hz: f[FIXED.len()..].to_vec(),
                los,
            });
        }

        #[derive(serde::Deserialize)]
        struct ArrayClock {
            id: u8,
            clock_offset_s: f64,
            clock_drift_ppm: f64,
        }
        #[derive(serde::Deserialize)]
        struct TruthToml {
            #[serde(default)]
            array: Vec<ArrayClock>,
        }
        let t: TruthToml = toml::from_str(toml_text).with_context(|| format!("in {toml_name}"))?;
        let clocks = if t.array.is_empty() {
            Vec::new()
        } else {
            array_ids
                .iter()
                .map(|id| {
                    t.array
                        .iter()
                        .find(|a| a.id == *id)
                        .map(|a| Clock { offset_s: a.clock_offset_s, drift_ppm: a.clock_drift_ppm })
                        .ok_or_else(|| {
                            anyhow!(
                                "{toml_name}: no [[array]] with id = {id} (a column of {csv_name})"
                            )
                        })
                })
                .collect::<anyhow::Result<Vec<Clock>>>()?
        };
        Ok(Truth { blades: 0, array_ids, clocks, airframe: None, rows })
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

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Truth {
        let row = |t: f64, los: bool| TruthRow {
            t_s: t,
            position: [1.234_567, -2.5, 1.2 + t],
            velocity: [0.3, -0.25, 0.012_345],
            acceleration: [0.1, 0.0, -0.05],
            yaw_rad: 0.712_345,
            roll_rad: -0.01,
            pitch_rad: 0.02,
            rotor_hz: vec![164.1, 163.9, 164.4, 163.6],
            los: vec![los, true],
        };
        Truth {
            blades: 2,
            array_ids: vec![1, 7],
            clocks: vec![
                Clock { offset_s: 0.012_5, drift_ppm: 40.0 },
                Clock { offset_s: -0.3, drift_ppm: -12.5 },
            ],
            airframe: None,
            rows: vec![row(0.0, true), row(0.1, false), row(0.2, true)],
        }
    }

    #[test]
    fn parse_reads_back_what_to_csv_and_to_toml_write() {
        let t = sample();
        let back = Truth::parse(&t.to_csv(), "truth.csv", &t.to_toml(), "truth.toml").unwrap();
        assert_eq!(back.array_ids, t.array_ids);
        assert_eq!(back.clocks, t.clocks);
        assert_eq!(back.rows.len(), t.rows.len());
        for (a, b) in back.rows.iter().zip(&t.rows) {
            assert_eq!(a.los, b.los);
            assert_eq!(a.rotor_hz.len(), b.rotor_hz.len());
            // The CSV's printed precision: 0.1 ms, 10 µm, 10 µm/s, 1 µrad, 0.1 mm/s², 0.1 mHz.
            assert!((a.t_s - b.t_s).abs() <= 0.5e-4);
            for k in 0..3 {
                assert!((a.position[k] - b.position[k]).abs() <= 0.5e-5);
                assert!((a.velocity[k] - b.velocity[k]).abs() <= 0.5e-5);
                assert!((a.acceleration[k] - b.acceleration[k]).abs() <= 0.5e-4);
            }
            assert!((a.yaw_rad - b.yaw_rad).abs() <= 0.5e-6);
            for (x, y) in a.rotor_hz.iter().zip(&b.rotor_hz) {
                assert!((x - y).abs() <= 0.5e-4);
            }
        }
    }

    #[test]
    fn parse_errors_name_the_file_line_and_column() {
        let t = sample();
        let csv = t.to_csv().replacen("-2.50000", "-2.5x", 1);
        let e = format!(
            "{:#}",
            Truth::parse(&csv, "a/truth.csv", &t.to_toml(), "a/truth.toml").unwrap_err()
        );
        assert!(e.contains("a/truth.csv:2") && e.contains("column `y`"), "{e}");
        let toml = t.to_toml().replace("id = 7", "id = 8");
        let e =
            format!("{:#}", Truth::parse(&t.to_csv(), "truth.csv", &toml, "b.toml").unwrap_err());
        assert!(e.contains("b.toml") && e.contains("id = 7"), "{e}");
        let e = format!("{:#}", Truth::parse("t,x\n", "c.csv", "", "c.toml").unwrap_err());
        assert!(e.contains("c.csv:1"), "{e}");
    }
}
