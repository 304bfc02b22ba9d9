//! The land detector: PX4's multicopter land detector (`MulticopterLandDetector`)
//! reduced to what this world needs, on measurements and the commanded thrust
//! only (the flight stack never sees the plant's contact).
//!
//! ```text
//! still           = |v_z| < 0.25 m/s, |v_xy| < 1.5 m/s, |(p, q)| < 20 deg/s   (x 2.5 while landed, PX4's)
//! near the ground = |z - z_rest| <= 0.1 m     z_rest: where the centre of mass rests (below)
//! low thrust      = u_T <= 0.3 m g            (the last command; PX4's maybe-landed level)
//! ground contact  = still and near the ground
//! landed         <- ground contact and low thrust, for 0.25 s
//! flying         <- not both, for 0.05 s      (trying to fly counts, as in PX4)
//! ```
//!
//! `z_rest` is the first measurement (the vehicle boots on the ground), then
//! follows the measurement (through its noise) while landed with low thrust.
//! A height estimate that wanders (the navigation filter on GNSS height)
//! can be off it by more than 0.1 m when the vehicle touches down, so the
//! ground is also found as PX4 finds it (`hit_ground`): still while
//! commanded down, `v_z,ref >= 1.1 LNDMC_Z_VEL_MAX`, for 1/3 s
//! (`LNDMC_TRIG_TIME / 3`) means the ground stopped the vehicle, and
//! `z_rest` becomes the measured height there — if the thrust is then
//! below `0.9 m g`: only the ground holds a still vehicle up on less than
//! its weight. (In the air a correction of the height estimate can stop a
//! descent for as long, the controller braking with more than its weight.)
//! PX4 tells ground contact from a range sensor or from the thrust and its
//! integrators; this world's ground is flat, so the height at which the
//! vehicle last rested does that job. PX4 cuts the thrust on ground contact
//! so the low-thrust condition can pass; the navigator does the same
//! ([`super::navigator`]: a mode that is not climbing idles on ground contact).

use super::TIME_EPS;
use crate::signals::Measurement;

/// Vertical speed below which the vehicle is still [m/s] (PX4's `LNDMC_Z_VEL_MAX`).
const Z_VEL_MAX_M_S: f64 = 0.25;
/// Horizontal speed below which the vehicle is still [m/s] (`LNDMC_XY_VEL_MAX`).
const XY_VEL_MAX_M_S: f64 = 1.5;
/// Roll/pitch rate below which the vehicle is still [rad/s] (`LNDMC_ROT_MAX`, 20 deg/s).
const ROT_MAX_RAD_S: f64 = 20.0 * std::f64::consts::PI / 180.0;
/// The limits above are this much wider while landed (PX4's hysteresis).
const LANDED_WIDENING: f64 = 2.5;
/// Near the ground: at most this far [m] from the height the vehicle rests at.
const NEAR_GROUND_M: f64 = 0.1;
/// Low thrust: at most this fraction of the nominal weight (PX4's maybe-landed threshold, about 0.3 of hover).
const LOW_THRUST_FRACTION: f64 = 0.3;
/// Ground contact with low thrust this long [s] means landed.
pub(super) const LAND_DETECT_S: f64 = 0.25;
/// Not resting (no ground contact, or more than low thrust) this long [s] means flying.
const TAKEOFF_DETECT_S: f64 = 0.05;
/// Rate [1/sample] at which the resting height follows the measurement while landed.
const REST_FILTER: f64 = 0.02;
/// Commanded down at least this fast [m/s] is a descent (PX4's `_in_descend`: 1.1 `LNDMC_Z_VEL_MAX`).
const IN_DESCEND_M_S: f64 = 1.1 * Z_VEL_MAX_M_S;
/// Still while descending this long [s] means the ground (PX4's ground-contact
/// hysteresis, a third of `LNDMC_TRIG_TIME` = 1 s).
const HIT_GROUND_S: f64 = 1.0 / 3.0;
/// The ground carries the vehicle when it is still on less thrust than this share of its weight.
const HIT_GROUND_THRUST_FRACTION: f64 = 0.9;

/// A change of the landed state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum LandEvent {
    /// Landed after flying.
    Landed,
    /// Flying after being landed.
    TookOff,
}

/// The detector's state.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct LandDetector {
    landed: bool,
    ground_contact: bool,
    /// Since when the conditions for a change hold [s].
    since_s: Option<f64>,
    /// NED z [m] of the centre of mass resting on the ground, learned from
    /// the first measurement (the vehicle boots on the ground) and while landed.
    rest_z: Option<f64>,
    /// Since when the vehicle is still while commanded down, in flight [s].
    stopped_since_s: Option<f64>,
}

impl LandDetector {
    /// Landed, as the vehicle boots.
    pub(super) fn new() -> Self {
        Self {
            landed: true,
            ground_contact: true,
            since_s: None,
            rest_z: None,
            stopped_since_s: None,
        }
    }

    /// Landed.
    pub(super) fn landed(&self) -> bool {
        self.landed
    }

    /// Still, at the height it rests at.
    pub(super) fn ground_contact(&self) -> bool {
        self.ground_contact
    }

    /// Whether the resting height has been learned (from a first measurement).
    pub(super) fn has_rest_height(&self) -> bool {
        self.rest_z.is_some()
    }

    /// NED z [m] of the centre of mass at rest (the measurement's until one arrives).
    pub(super) fn rest_z(&self, m: &Measurement) -> f64 {
        self.rest_z.unwrap_or(m.position_ned.z)
    }

    /// Update with the measurement at `t_k`, the collective thrust
    /// commanded over the last step [N] and the vertical velocity the last
    /// step's reference asked for `v_z,ref` [m/s, NED: positive down];
    /// `weight_n` is the nominal weight.
    pub(super) fn update(
        &mut self,
        m: &Measurement,
        thrust_n: f64,
        weight_n: f64,
        commanded_vz_m_s: f64,
    ) -> Option<LandEvent> {
        let now = m.time_s;
        let mut rest_z = *self.rest_z.get_or_insert(m.position_ned.z);
        let widen = if self.landed { LANDED_WIDENING } else { 1.0 };
        let v = &m.velocity_ned;
        let still = v.z.abs() < Z_VEL_MAX_M_S * widen
            && v.xy().norm() < XY_VEL_MAX_M_S * widen
            && m.rate_frd.xy().norm() < ROT_MAX_RAD_S * widen;
        let mut near_ground = (m.position_ned.z - rest_z).abs() <= NEAR_GROUND_M;
        if !self.landed && still && commanded_vz_m_s >= IN_DESCEND_M_S {
            let since = *self.stopped_since_s.get_or_insert(now);
            if !near_ground
                && now - since >= HIT_GROUND_S - TIME_EPS
                && thrust_n <= HIT_GROUND_THRUST_FRACTION * weight_n
            {
                // the ground stopped the descent: it is here, whatever the height says
                rest_z = m.position_ned.z;
                self.rest_z = Some(rest_z);
                near_ground = true;
            }
        } else {
            self.stopped_since_s = None;
        }
        self.ground_contact = still && near_ground;
        let resting = self.ground_contact && thrust_n <= LOW_THRUST_FRACTION * weight_n;
        let (change, hold_s) = if self.landed {
            (!resting, TAKEOFF_DETECT_S)
        } else {
            (resting, LAND_DETECT_S)
        };
        if !change {
            self.since_s = None;
        } else if now - *self.since_s.get_or_insert(now) >= hold_s - TIME_EPS {
            self.since_s = None;
            self.landed = !self.landed;
            return Some(if self.landed {
                LandEvent::Landed
            } else {
                LandEvent::TookOff
            });
        }
        if self.landed && resting {
            // follow the resting height through the measurement noise
            self.rest_z = Some(rest_z + REST_FILTER * (m.position_ned.z - rest_z));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{UnitQuaternion, Vector3};

    fn at(t: f64, z: f64, vz: f64) -> Measurement {
        Measurement {
            time_s: t,
            position_ned: Vector3::new(0.0, 0.0, z),
            velocity_ned: Vector3::new(0.0, 0.0, vz),
            attitude: UnitQuaternion::identity(),
            rate_frd: Vector3::zeros(),
        }
    }

    #[test]
    fn landing_needs_contact_and_low_thrust_for_a_while_flying_needs_neither() {
        let mut d = LandDetector::new();
        let w = 20.0;
        assert_eq!(d.update(&at(0.0, -0.24, 0.0), 0.0, w, 0.0), None);
        assert!(d.landed() && d.ground_contact());
        // spooling up on the ground: trying to fly is flying after 0.05 s (PX4),
        // while the ground contact lasts
        let mut t = 0.001;
        let mut event = None;
        while event.is_none() && t < 1.0 {
            event = d.update(&at(t, -0.24, 0.0), 25.0, w, 0.0);
            t += 0.001;
        }
        assert_eq!(event, Some(LandEvent::TookOff));
        assert!((t - 0.052).abs() < 0.0015, "{t}");
        assert!(d.ground_contact());
        // rising: no contact
        d.update(&at(t, -0.5, -1.0), 25.0, w, 0.0);
        assert!(!d.ground_contact());
        // back at the resting height, still, but high thrust: not landed
        for k in 0..1000 {
            assert_eq!(d.update(&at(1.0 + k as f64 * 1e-3, -0.24, 0.0), 19.6, w, 0.0), None);
        }
        assert!(d.ground_contact() && !d.landed());
        // low thrust: landed after 0.25 s
        let start = 3.0;
        let mut k = 0;
        while d
            .update(&at(start + k as f64 * 1e-3, -0.24, 0.0), 1.0, w, 0.0)
            .is_none()
        {
            k += 1;
            assert!(k < 1000);
        }
        assert!((k as f64 * 1e-3 - LAND_DETECT_S).abs() < 1.5e-3, "{k}");
        assert_eq!(d.rest_z(&at(3.0, -2.24, 0.0)), -0.24);
    }

    #[test]
    fn a_slow_climb_is_a_takeoff_and_the_resting_height_stays_on_the_ground() {
        let mut d = LandDetector::new();
        d.update(&at(0.0, -0.24, 0.0), 0.0, 20.0, 0.0);
        // climbing at 0.5 m/s (within the landed stillness limit) on hover thrust
        let mut events = Vec::new();
        for k in 1..4000 {
            let t = k as f64 * 1e-3;
            events.extend(d.update(&at(t, -0.24 - 0.5 * t, -0.5), 20.0, 20.0, 0.0));
        }
        assert_eq!(events, vec![LandEvent::TookOff]);
        assert!(!d.ground_contact());
        assert_eq!(d.rest_z(&at(4.0, -2.24, 0.0)), -0.24);
    }

    #[test]
    fn descending_above_the_ground_with_low_thrust_is_not_landed() {
        let mut d = LandDetector::new();
        d.update(&at(0.0, -0.24, 0.0), 0.0, 20.0, 0.0);
        d.update(&at(0.001, -3.0, -2.0), 20.0, 20.0, 0.0);
        assert_eq!(
            d.update(&at(0.1, -3.0, -2.0), 20.0, 20.0, 0.0),
            Some(LandEvent::TookOff)
        );
        // sinking at 0.5 m/s, 20 cm above the resting height, thrust low: no contact
        for k in 0..2000 {
            assert_eq!(d.update(&at(0.2 + k as f64 * 1e-3, -0.44, 0.5), 2.0, 20.0, 0.0), None);
        }
        // hovering still 20 cm up with low thrust (a light vehicle): not landed either
        for k in 0..2000 {
            assert_eq!(d.update(&at(3.0 + k as f64 * 1e-3, -0.44, 0.0), 2.0, 20.0, 0.0), None);
        }
        assert!(!d.ground_contact() && !d.landed());
    }

    /// GIVEN a vehicle flying down at land speed whose height estimate
    /// reads 0.5 m above where it rested at boot when it touches down
    /// WHEN it stops while still commanded down (0.7 m/s), with low thrust
    /// THEN it is not near the ground by the height, but after 1/3 s still
    /// the ground is where it stopped: contact, then landed 0.25 s later;
    /// a stop of less than 1/3 s (the start of a descent) is no contact, nor
    /// a longer one on more thrust than the weight (braking in the air).
    #[test]
    fn stopped_while_commanded_down_is_the_ground_whatever_the_height_says() {
        let mut d = LandDetector::new();
        d.update(&at(0.0, -0.24, 0.0), 0.0, 20.0, 0.0);
        assert_eq!(d.update(&at(0.1, -3.0, -1.0), 20.0, 20.0, 0.0), None);
        assert_eq!(
            d.update(&at(0.2, -3.0, -1.0), 20.0, 20.0, 0.0),
            Some(LandEvent::TookOff)
        );
        // a descent starting from a hover: still for 0.3 s while commanded down
        for k in 0..300 {
            assert_eq!(d.update(&at(1.0 + k as f64 * 1e-3, -3.0, 0.1), 20.0, 20.0, 0.7), None);
            assert!(!d.ground_contact());
        }
        assert_eq!(d.update(&at(1.3, -2.9, 0.7), 20.0, 20.0, 0.7), None);
        // a descent the controller brakes (its height estimate corrected
        // upwards): still for a second while commanded down, on more than
        // the weight: the air, not the ground
        for k in 0..1000 {
            assert_eq!(d.update(&at(1.4 + k as f64 * 1e-3, -2.8, 0.0), 20.5, 20.0, 0.7), None);
            assert!(!d.ground_contact());
        }
        assert_eq!(d.update(&at(2.5, -2.7, 0.7), 20.0, 20.0, 0.7), None);
        // stopped 0.5 m above the boot height, commanded down, thrust low
        let start = 2.0;
        let mut k = 0;
        let landed = loop {
            let t = start + k as f64 * 1e-3;
            if let Some(e) = d.update(&at(t, -0.74, 0.0), 2.0, 20.0, 0.7) {
                break (e, t - start);
            }
            k += 1;
            assert!(k < 2000, "never landed");
        };
        assert_eq!(landed.0, LandEvent::Landed);
        assert!((landed.1 - HIT_GROUND_S - LAND_DETECT_S).abs() < 2e-3, "{landed:?}");
        assert!((d.rest_z(&at(4.0, 0.0, 0.0)) - -0.74).abs() < 1e-9);
    }
}
