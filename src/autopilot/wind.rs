//! The wind the flight stack reports (WIND_COV, the ULog's `wind`): the
//! estimated external force explained by the airframe's nominal drag
//! ([`crate::estimation::wind`]), solved every [`PERIOD_S`] in the air and
//! low-passed with time constant [`TAU_S`]; reported once it has filtered
//! for [`SETTLE_S`] after liftoff, forgotten on the ground (where the
//! estimator restarts too). An airframe without body-horizontal drag
//! coefficients reports no wind at all, as PX4 sends no WIND_COV without a
//! wind estimate.

use crate::airframe::Airframe;
use crate::estimation::wind::{DragModel, WindFilter, wind_from_force};
use crate::signals::{SensorReadings, WindEstimate, WrenchEstimate};

/// How often the drag model is solved [s] (50 Hz: the force estimate's
/// bandwidth is a few Hz).
pub(super) const PERIOD_S: f64 = 0.02;
/// The low-pass time constant [s] (MAVLink's "1 Hz low-passed wind").
pub(super) const TAU_S: f64 = 1.0;
/// Filtering time after liftoff before the wind is reported [s].
pub(super) const SETTLE_S: f64 = 3.0;

/// The wind estimate's state.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct WindMonitor {
    model: DragModel,
    filter: WindFilter,
    /// When the drag model is next solved [s].
    next_s: f64,
}

impl WindMonitor {
    /// For `airframe`'s nominal drag (its `[aero]` table).
    pub(super) fn new(airframe: &Airframe) -> Self {
        let a = &airframe.aero;
        Self {
            model: DragModel {
                c_dx: a.c_dx,
                c_dy: a.c_dy,
                k_d: a.k_d,
            },
            filter: WindFilter::new(TAU_S, SETTLE_S),
            next_s: f64::NEG_INFINITY,
        }
    }

    /// One step: in the air, solve for the wind from the force `estimate`
    /// and the `readings` when due; on the ground, forget.
    pub(super) fn update(&mut self, airborne: bool, readings: &SensorReadings, estimate: &WrenchEstimate) {
        if !airborne || !self.model.can_explain_a_force() {
            self.filter.reset();
            self.next_s = f64::NEG_INFINITY;
            return;
        }
        let m = &readings.measurement;
        if m.time_s < self.next_s {
            return;
        }
        self.next_s = m.time_s + PERIOD_S - 1e-9;
        let rotor_speed_sum = readings.rotor_speeds_rad_s.sum();
        if let Some(s) = wind_from_force(
            &self.model,
            &estimate.force_ned,
            &m.velocity_ned,
            &m.attitude,
            rotor_speed_sum,
        ) {
            self.filter.update(m.time_s, &s.wind_ned);
        }
    }

    /// The wind, once settled.
    pub(super) fn estimate(&self) -> Option<WindEstimate> {
        self.filter.settled()
    }
}
