//! Air: the speed of sound and the atmospheric absorption of ISO 9613-1.

/// The state of the air the sound travels through.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Air {
    /// Temperature, degrees Celsius.
    pub temperature_c: f64,
    /// Relative humidity, percent.
    pub humidity_percent: f64,
    /// Static pressure, pascals.
    pub pressure_pa: f64,
}

impl Default for Air {
    fn default() -> Self {
        Self { temperature_c: 20.0, humidity_percent: 50.0, pressure_pa: 101_325.0 }
    }
}

impl Air {
    /// Speed of sound, m/s: `331.3 · sqrt(1 + T_C / 273.15)` (the formula `ALGORITHMS.md` uses).
    pub fn speed_of_sound_mps(&self) -> f64 {
        331.3 * (1.0 + self.temperature_c / 273.15).sqrt()
    }

    /// Pure-tone atmospheric absorption of ISO 9613-1:1993 (eq. 5), dB per metre, at `hz`.
    ///
    /// At 20 °C, 70 % RH, 101.325 kPa this gives 0.005 dB/m at 1 kHz and 0.023 dB/m at 4 kHz.
    pub fn absorption_db_per_m(&self, hz: f64) -> f64 {
        const T0: f64 = 293.15; // reference temperature, K
        const T01: f64 = 273.16; // triple-point isotherm, K
        const PR: f64 = 101_325.0; // reference pressure, Pa
        let t = self.temperature_c + 273.15;
        let pa = self.pressure_pa / PR;
        // Molar concentration of water vapour, percent (ISO 9613-1 annex B).
        let c = -6.8346 * (T01 / t).powf(1.261) + 4.6151;
        let h = self.humidity_percent * 10f64.powf(c) / pa;
        // Relaxation frequencies of oxygen and nitrogen, Hz.
        let fr_o = pa * (24.0 + 4.04e4 * h * (0.02 + h) / (0.391 + h));
        let fr_n = pa
            * (t / T0).powf(-0.5)
            * (9.0 + 280.0 * h * (-4.170 * ((t / T0).powf(-1.0 / 3.0) - 1.0)).exp());
        let f2 = hz * hz;
        8.686
            * f2
            * (1.84e-11 / pa * (t / T0).sqrt()
                + (t / T0).powf(-2.5)
                    * (0.01275 * (-2239.1 / t).exp() / (fr_o + f2 / fr_o)
                        + 0.1068 * (-3352.0 / t).exp() / (fr_n + f2 / fr_n)))
    }

    /// Coefficient `a` of the quadratic absorption law `α(f) ≈ a · f²` (dB per metre per Hz²),
    /// fitted at 4 kHz. The quadratic law is what the simulator's per-path absorption filter
    /// (`propagation`) can represent; it is exact in shape below about 2 kHz and within a factor
    /// of 1.5 up to 8 kHz at room conditions.
    pub fn absorption_quadratic_coefficient(&self) -> f64 {
        const FIT_HZ: f64 = 4000.0;
        self.absorption_db_per_m(FIT_HZ) / (FIT_HZ * FIT_HZ)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speed_of_sound_at_20_c_is_343() {
        let c = Air::default().speed_of_sound_mps();
        assert!((c - 343.2).abs() < 0.2, "{c}");
    }

    #[test]
    fn absorption_matches_iso_9613_table() {
        // ISO 9613-2 table 2, 20 °C, 70 % RH (octave bands): 500 Hz 2.8 dB/km, 1 kHz 5.0,
        // 2 kHz 9.0, 4 kHz 22.9, 8 kHz 76.6.
        let air = Air { humidity_percent: 70.0, ..Air::default() };
        for (hz, db_per_km) in
            [(500.0, 2.8), (1000.0, 5.0), (2000.0, 9.0), (4000.0, 22.9), (8000.0, 76.6)]
        {
            let got = air.absorption_db_per_m(hz) * 1000.0;
            assert!((got - db_per_km).abs() / db_per_km < 0.05, "{hz} Hz: {got} dB/km");
        }
    }
}
