//! The battery monitor: what the flight stack makes of the power module's
//! voltage and current (PX4's `Battery` library, reduced).
//!
//! ```text
//! consumed += I dt / 3.6                                   [mAh]
//! soc = clamp(((V + n R_cell I) / n - V_empty) / (V_full - V_empty), 0, 1)
//! ```
//! The open-circuit cell voltage is the terminal voltage corrected for the
//! internal resistance under load (PX4's `BAT1_R_INTERNAL`), interpolated
//! between empty (3.5 V) and full (4.2 V) per cell, with `R_cell` = 10 mOhm:
//! the values of the packs this simulator flies.

use crate::signals::BatteryReading;

/// Cell voltage when empty [V] (PX4's `BAT1_V_EMPTY`).
const CELL_EMPTY_V: f64 = 3.5;
/// Cell voltage when full [V] (PX4's `BAT1_V_CHARGED`).
const CELL_FULL_V: f64 = 4.2;
/// Internal resistance per cell [Ohm].
const CELL_R_OHM: f64 = 0.010;

/// The monitor's state.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct BatteryMonitor {
    /// Cells in series (`BAT1_N_CELLS`).
    cells: f64,
    /// Charge used since boot [mAh].
    consumed_mah: f64,
}

impl BatteryMonitor {
    /// Nothing used yet.
    pub(super) fn new(cells: f64) -> Self {
        Self {
            cells,
            consumed_mah: 0.0,
        }
    }

    /// A new cell count (`BAT1_N_CELLS`); the charge used is kept.
    pub(super) fn set_cells(&mut self, cells: f64) {
        self.cells = cells;
    }

    /// Count the current of one step of `dt` [s].
    pub(super) fn update(&mut self, reading: &BatteryReading, dt: f64) {
        if reading.current_a.is_finite() {
            self.consumed_mah += reading.current_a * dt / 3.6;
        }
    }

    /// Charge used [mAh].
    pub(super) fn consumed_mah(&self) -> f64 {
        self.consumed_mah
    }

    /// Remaining charge 0..1 from the load-corrected cell voltage.
    pub(super) fn remaining(&self, reading: &BatteryReading) -> f64 {
        let n = self.cells;
        let cell = (reading.voltage_v + n * CELL_R_OHM * reading.current_a) / n;
        let soc = (cell - CELL_EMPTY_V) / (CELL_FULL_V - CELL_EMPTY_V);
        if soc.is_finite() { soc.clamp(0.0, 1.0) } else { 0.0 }
    }
}
