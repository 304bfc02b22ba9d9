//! The simulated battery pack: it discharges with the power the rotors draw,
//! and its terminal voltage and current are what the battery monitor reads.
//!
//! ```text
//! P = T^1.5 / sqrt(2 rho A) / (FM eta)          momentum theory: total thrust T [N], disk area A [m^2]
//! I = P / V_oc + I_avionics                     [A]
//! soc -= I dt / (3.6 C)                         C [mAh]; PX4 SITL's SIM_BAT_MIN_PCT: never below `min`
//! V_oc = (n - n_failed) (3.5 + 0.7 soc)         [V]: 4.2 V per cell full, 3.5 V empty
//! V = V_oc - n R_cell I                         [V]
//! ```
//! With `rho` = 1.225 kg/m^3, figure of merit `FM` = 0.65, motor and ESC
//! efficiency `eta` = 0.8, `I_avionics` = 0.3 A, `R_cell` = 10 mOhm. An
//! x500-class quad at hover draws about 16 A from 4S. A failed cell
//! (`n_failed` = 1, an injected fault) gives no voltage: a monitor that
//! counts `n` cells reads a low charge. The cell is [`lipo_cell`].

use crate::signals::lipo_cell;

/// Air density [kg/m^3].
const RHO: f64 = 1.225;
/// Rotor figure of merit times motor/ESC efficiency.
const EFFICIENCY: f64 = 0.65 * 0.8;
/// Current drawn by the electronics [A].
const AVIONICS_A: f64 = 0.3;

/// Pack state.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Battery {
    /// `1 / (sqrt(2 rho A) FM eta)`: power per `T^1.5` [W/N^1.5] (0 without rotors).
    power_per_thrust: f64,
    cells: f64,
    capacity_mah: f64,
    min_fraction: f64,
    /// Cells that give no voltage (0 or 1: an injected fault).
    failed_cells: f64,
    /// State of charge, `min_fraction..1`.
    soc: f64,
    current_a: f64,
    voltage_v: f64,
}

impl Battery {
    /// A full pack for rotors of total disk area `disk_area_m2` [m^2].
    pub(super) fn new(disk_area_m2: f64, cells: f64, capacity_mah: f64, min_fraction: f64) -> Self {
        let power_per_thrust = if disk_area_m2 > 0.0 {
            1.0 / (2.0 * RHO * disk_area_m2).sqrt() / EFFICIENCY
        } else {
            0.0
        };
        let mut b = Self {
            power_per_thrust,
            cells,
            capacity_mah,
            min_fraction: min_fraction.clamp(0.0, 1.0),
            failed_cells: 0.0,
            soc: 1.0,
            current_a: AVIONICS_A,
            voltage_v: 0.0,
        };
        b.voltage_v = b.terminal_v();
        b
    }

    /// Change the pack (parameters); the charge left is kept (at least the
    /// new floor), the terminal voltage follows at once.
    pub(super) fn configure(&mut self, cells: f64, capacity_mah: f64, min_fraction: f64) {
        self.cells = cells;
        self.capacity_mah = capacity_mah;
        self.min_fraction = min_fraction.clamp(0.0, 1.0);
        self.soc = self.soc.max(self.min_fraction);
        self.voltage_v = self.terminal_v();
    }

    /// Remaining charge, `min_fraction..1`.
    #[cfg(test)]
    fn remaining(&self) -> f64 {
        self.soc
    }

    /// Fail one cell (`true`) or mend it; the terminal voltage follows at once.
    pub(super) fn set_cell_failed(&mut self, failed: bool) {
        self.failed_cells = if failed { 1.0_f64.min(self.cells) } else { 0.0 };
        self.voltage_v = self.terminal_v();
    }

    fn open_circuit_v(&self) -> f64 {
        (self.cells - self.failed_cells) * lipo_cell::open_circuit_v(self.soc)
    }

    fn terminal_v(&self) -> f64 {
        (self.open_circuit_v() - self.cells * lipo_cell::R_OHM * self.current_a).max(0.0)
    }

    /// Advance by `dt` [s] with total rotor thrust `thrust_n` [N].
    pub(super) fn update(&mut self, thrust_n: f64, dt: f64) {
        let t = if thrust_n.is_finite() { thrust_n.max(0.0) } else { 0.0 };
        let power_w = t * t.sqrt() * self.power_per_thrust;
        self.current_a = power_w / self.open_circuit_v().max(1.0) + AVIONICS_A;
        // stop draining at the floor, as PX4's simulated battery does
        self.soc = (self.soc - self.current_a * dt / (3.6 * self.capacity_mah)).max(self.min_fraction);
        self.voltage_v = self.terminal_v();
    }

    /// Terminal voltage [V].
    pub(super) fn voltage_v(&self) -> f64 {
        self.voltage_v
    }

    /// Current [A].
    pub(super) fn current_a(&self) -> f64 {
        self.current_a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_pack_hover_draw_and_floor() {
        // x500 hover: 19.6 N over four 0.1396 m rotors
        let area = 4.0 * std::f64::consts::PI * 0.1396f64.powi(2);
        let mut b = Battery::new(area, 4.0, 5000.0, 0.5);
        assert!((b.voltage_v() - 16.8).abs() < 0.05);
        assert_eq!(b.remaining(), 1.0);
        b.update(19.62, 0.001);
        assert!(b.current_a() > 10.0 && b.current_a() < 25.0, "{}", b.current_a());
        for _ in 0..3_600_000 {
            b.update(19.62, 0.001);
        }
        assert!((b.remaining() - 0.5).abs() < 1e-3, "stops at the floor");
        assert!(b.voltage_v() > 14.0 && b.voltage_v() < 15.2, "{}", b.voltage_v());
        // 2500 mAh at about 16 A: 9.4 min, then the floor
        let mut fresh = Battery::new(area, 4.0, 5000.0, 0.0);
        for _ in 0..60_000 {
            fresh.update(19.62, 0.001);
        }
        let used_mah = (1.0 - fresh.remaining()) * 5000.0;
        assert!((used_mah - fresh.current_a() * 60.0 / 3.6).abs() < 3.0, "{used_mah}");
    }

    #[test]
    fn a_failed_cell_takes_its_voltage_and_mending_gives_it_back() {
        let mut b = Battery::new(0.25, 4.0, 5000.0, 0.0);
        let whole = b.voltage_v();
        b.set_cell_failed(true);
        // 3 of 4 cells at 4.2 V, the avionics' current through 4 cells' resistance
        assert!(
            (b.voltage_v() - (12.6 - 4.0 * lipo_cell::R_OHM * AVIONICS_A)).abs() < 1e-9,
            "{}",
            b.voltage_v()
        );
        b.set_cell_failed(false);
        assert_eq!(b.voltage_v(), whole);
    }
}
