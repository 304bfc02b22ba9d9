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
//! the cell of the packs this simulator flies ([`lipo_cell`]).

use serde::Serialize;

use crate::signals::{BatteryReading, lipo_cell};

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
        let cell = (reading.voltage_v + n * lipo_cell::R_OHM * reading.current_a) / n;
        let soc = lipo_cell::charge(cell);
        if soc.is_finite() { soc.clamp(0.0, 1.0) } else { 0.0 }
    }
}

/// The battery warning level (PX4's `battery_status.warning`; BATTERY_STATUS
/// `charge_state` is it plus one).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub enum BatteryWarning {
    /// Above `BAT_LOW_THR`.
    #[default]
    None,
    /// Below `BAT_LOW_THR`.
    Low,
    /// Below `BAT_CRIT_THR`.
    Critical,
    /// Below `BAT_EMERGEN_THR`.
    Emergency,
}

/// `BAT_LOW_THR`, `BAT_CRIT_THR`, `BAT_EMERGEN_THR` (fractions of a full charge).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct BatteryThresholds {
    pub(super) low: f64,
    pub(super) critical: f64,
    pub(super) emergency: f64,
}

impl BatteryThresholds {
    /// PX4's `determineWarning`: the worst threshold the remaining charge
    /// `soc` (0..1) is below (`soc < emergency`: Emergency, `< critical`:
    /// Critical, `< low`: Low).
    pub(super) fn level(&self, soc: f64) -> BatteryWarning {
        if soc < self.emergency {
            BatteryWarning::Emergency
        } else if soc < self.critical {
            BatteryWarning::Critical
        } else if soc < self.low {
            BatteryWarning::Low
        } else {
            BatteryWarning::None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_from_px4_defaults() {
        let t = BatteryThresholds {
            low: 0.15,
            critical: 0.07,
            emergency: 0.05,
        };
        assert_eq!(t.level(0.5), BatteryWarning::None);
        assert_eq!(t.level(0.15), BatteryWarning::None);
        assert_eq!(t.level(0.149), BatteryWarning::Low);
        assert_eq!(t.level(0.069), BatteryWarning::Critical);
        assert_eq!(t.level(0.049), BatteryWarning::Emergency);
        assert!(BatteryWarning::Emergency > BatteryWarning::Critical);
    }

    #[test]
    fn remaining_undoes_the_load_drop() {
        let m = BatteryMonitor::new(4.0);
        // 50 % open circuit (3.85 V per cell) minus 4 cells x 10 mOhm x 20 A
        let r = BatteryReading {
            voltage_v: 4.0 * 3.85 - 4.0 * 0.010 * 20.0,
            current_a: 20.0,
        };
        assert!((m.remaining(&r) - 0.5).abs() < 1e-9);
    }
}
