//! The simulated battery pack: it discharges with the power the rotors draw,
//! and its terminal voltage and current are what the battery monitor reads.
//!
//! ```text
//! P = T^1.5 / sqrt(2 rho A) / (FM eta)          momentum theory: total thrust T [N], disk area A [m^2]
//! I = P / V + I_avionics                        [A]
//! consumed += I dt / 3.6                        [mAh]
//! soc = max(1 - consumed / capacity, min)       PX4 SITL's SIM_BAT_MIN_PCT: never below `min`
//! V = n (3.5 + 0.7 soc) - n R_cell I            [V]: 4.2 V per cell full, 3.5 V empty
//! ```
//! With `rho` = 1.225 kg/m^3, figure of merit `FM` = 0.65, motor and ESC
//! efficiency `eta` = 0.8, `I_avionics` = 0.3 A, `R_cell` = 10 mOhm. An
//! x500-class quad at hover draws about 16 A from 4S.

/// Air density [kg/m^3].
const RHO: f64 = 1.225;
/// Rotor figure of merit times motor/ESC efficiency.
const EFFICIENCY: f64 = 0.65 * 0.8;
/// Current drawn by the electronics [A].
const AVIONICS_A: f64 = 0.3;
/// Internal resistance per cell [Ohm].
const CELL_R_OHM: f64 = 0.010;
/// Cell voltage at 0 % and 100 % charge [V].
const CELL_EMPTY_V: f64 = 3.5;
const CELL_FULL_V: f64 = 4.2;

/// Pack state.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Battery {
    cells: f64,
    capacity_mah: f64,
    min_fraction: f64,
    consumed_mah: f64,
    current_a: f64,
    voltage_v: f64,
}

impl Battery {
    /// A full pack.
    pub(super) fn new(cells: f64, capacity_mah: f64, min_fraction: f64) -> Self {
        let mut b = Self {
            cells,
            capacity_mah,
            min_fraction,
            consumed_mah: 0.0,
            current_a: AVIONICS_A,
            voltage_v: 0.0,
        };
        b.voltage_v = b.open_circuit_v() - b.cells * CELL_R_OHM * b.current_a;
        b
    }

    /// Change the pack (parameters); the charge used is kept, the terminal
    /// voltage follows at once.
    pub(super) fn configure(&mut self, cells: f64, capacity_mah: f64, min_fraction: f64) {
        self.cells = cells;
        self.capacity_mah = capacity_mah;
        self.min_fraction = min_fraction.clamp(0.0, 1.0);
        self.voltage_v = (self.open_circuit_v() - self.cells * CELL_R_OHM * self.current_a).max(0.0);
    }

    /// Remaining charge, `min_fraction..1`.
    pub(super) fn remaining(&self) -> f64 {
        (1.0 - self.consumed_mah / self.capacity_mah).clamp(self.min_fraction, 1.0)
    }

    fn open_circuit_v(&self) -> f64 {
        self.cells * (CELL_EMPTY_V + (CELL_FULL_V - CELL_EMPTY_V) * self.remaining())
    }

    /// Advance by `dt` [s] with total rotor thrust `thrust_n` [N] over disk area `disk_area_m2` [m^2].
    pub(super) fn update(&mut self, thrust_n: f64, disk_area_m2: f64, dt: f64) {
        let t = if thrust_n.is_finite() { thrust_n.max(0.0) } else { 0.0 };
        let power_w = if disk_area_m2 > 0.0 {
            t * t.sqrt() / (2.0 * RHO * disk_area_m2).sqrt() / EFFICIENCY
        } else {
            0.0
        };
        let ocv = self.open_circuit_v();
        self.current_a = power_w / ocv.max(1.0) + AVIONICS_A;
        // stop counting at the floor, as PX4's simulated battery does
        if self.remaining() > self.min_fraction {
            self.consumed_mah += self.current_a * dt / 3.6;
        }
        self.voltage_v = (self.open_circuit_v() - self.cells * CELL_R_OHM * self.current_a).max(0.0);
    }

    /// Terminal voltage [V].
    pub(super) fn voltage_v(&self) -> f64 {
        self.voltage_v
    }

    /// Current [A].
    pub(super) fn current_a(&self) -> f64 {
        self.current_a
    }

    /// Charge used [mAh].
    #[cfg(test)]
    fn consumed_mah(&self) -> f64 {
        self.consumed_mah
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_pack_hover_draw_and_floor() {
        let mut b = Battery::new(4.0, 5000.0, 0.5);
        assert!((b.voltage_v() - 16.8).abs() < 0.05);
        assert_eq!(b.remaining(), 1.0);
        // x500 hover: 19.6 N over four 0.1396 m rotors
        let area = 4.0 * std::f64::consts::PI * 0.1396f64.powi(2);
        b.update(19.62, area, 0.001);
        assert!(b.current_a() > 10.0 && b.current_a() < 25.0, "{}", b.current_a());
        for _ in 0..3_600_000 {
            b.update(19.62, area, 0.001);
        }
        assert!((b.remaining() - 0.5).abs() < 1e-3, "stops at the floor");
        assert!(b.voltage_v() > 14.0 && b.voltage_v() < 15.2, "{}", b.voltage_v());
        assert!(b.consumed_mah() <= 2501.0);
    }
}
