//! Guidance: the active mode turned into this step's [`Demand`] (a shaped
//! reference, an attitude setpoint, idle or stopped rotors), one file per
//! mode family — `auto` (hold, takeoff, land, return to launch), `orbit`,
//! `follow` (follow target),
//! `offboard` (external setpoints), `mission` (the stored mission),
//! `manual` (the pilot's sticks) and `blind` (Descend without a GPS fix). The
//! [`Navigator`] owns what guidance remembers between steps: the mode and its
//! phase, the reference shaper, the cruise-speed override, the latest
//! offboard setpoint and sticks.

mod auto;
mod blind;
mod follow;
mod manual;
mod mission;
mod offboard;
mod orbit;

pub use mission::ItemDone;

pub use manual::ManualControl;
pub(super) use manual::ManualMode;

pub(super) use mission::{MissionRun, SetHome, item_point_ned};

pub(super) use follow::Follow;
use follow::Target;
pub use follow::{TARGET_STALE_S, TargetFix};
pub use orbit::OrbitYaw;
pub(super) use orbit::{Orbit, OrbitChange};

pub use offboard::{AltitudeReference, AttitudeTarget, GlobalTarget, OffboardSetpoint, RelativeFrame, Targets};

use nalgebra::{UnitQuaternion, Vector2, Vector3};

use super::control_loop::Demand;
use super::position_checks::PositionValidity;
use super::settings::Settings;
use super::status::Announcements;
use super::telemetry::LandedState;
use super::{ClientClock, FlightMode};
use crate::control::{Reference, Setpoint, Shaper, ShaperError, ShaperLimits, TranslationSetpoint, YawSetpoint};
use crate::geo::GeoPoint;
use crate::mission::MissionItem;
use crate::signals::Measurement;
use offboard::LocalSetpoint;

/// The shaped reference has arrived when within this distance [m] of its target...
const REF_ARRIVED_M: f64 = 0.02;
/// ... and slower than this [m/s].
const REF_STOPPED_M_S: f64 = 0.05;

/// What guidance knows at `t_k`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Situation<'a> {
    /// The measurement `x_k`.
    pub(super) meas: &'a Measurement,
    /// The parameters.
    pub(super) settings: &'a Settings,
    /// Home [m], NED.
    pub(super) home_ned: Vector3<f64>,
    /// NED z [m] of the centre of mass at rest on the ground.
    pub(super) rest_z: f64,
    /// Landed, or in ground contact: a mode that does not climb idles.
    pub(super) resting: bool,
    /// Landed (the land detector's output).
    pub(super) landed: bool,
    /// Step [s].
    pub(super) dt: f64,
    /// The clock client timers run on: how the sticks' freshness is timed.
    pub(super) clock: ClientClock,
    /// What offboard thrust 1.0 means [N].
    pub(super) max_thrust_n: f64,
    /// The NED origin.
    pub(super) origin: &'a GeoPoint,
    /// Home.
    pub(super) home: &'a GeoPoint,
    /// The stored mission's items.
    pub(super) mission: &'a [MissionItem],
    /// The stored rally points.
    pub(super) rally: &'a [MissionItem],
    /// The stored geofence plan.
    pub(super) fence: &'a [MissionItem],
}

/// Where Hold flies to (DO_REPOSITION), instead of braking where it is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct HoldTarget {
    /// Target [m], NED.
    pub(super) position_ned: Vector3<f64>,
    /// Heading [rad], `None` = keep.
    pub(super) yaw_rad: Option<f64>,
    /// Ground speed [m/s], `None` = cruise.
    pub(super) speed_m_s: Option<f64>,
}

/// Phases of a return to launch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum RtlPhase {
    /// Climb where the return started (horizontal position [m], NED).
    Climb {
        /// Where the climb happens.
        xy: Vector2<f64>,
    },
    /// Fly to a corner of the way round the geofence at the return altitude.
    Avoid {
        /// Which corner of [`Navigator`]'s route.
        leg: usize,
        /// Heading [rad] on the leg (towards the corner), `None` = keep.
        yaw_rad: Option<f64>,
    },
    /// Fly home at the return altitude.
    Return,
    /// Descend over home to RTL_DESCEND_ALT.
    Descend,
    /// Land at home.
    Land,
}

/// The active mode with its state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Nav {
    /// Hold.
    Hold {
        /// Reposition target, or brake and hold.
        target: Option<HoldTarget>,
    },
    /// Climb to a point, then Hold there (or at `then`).
    Takeoff {
        /// Target [m], NED.
        target_ned: Vector3<f64>,
        /// Where to go after the climb (a reposition given on the ground).
        then: Option<HoldTarget>,
    },
    /// Descend and land at this horizontal position [m], NED.
    Land {
        /// Where.
        xy: Vector2<f64>,
    },
    /// Return to launch (home, or the closest rally point).
    Rtl {
        /// Current phase.
        phase: RtlPhase,
        /// Return altitude [m], NED z.
        z_return: f64,
        /// Where it returns to land [m], NED horizontal.
        dest_xy: Vector2<f64>,
    },
    /// Follow the offboard setpoints.
    Offboard,
    /// Fly the stored mission ([`MissionRun`] holds where it stands).
    Mission,
    /// Fly with the pilot's sticks.
    Manual(ManualMode),
    /// Circle a centre.
    Orbit(Orbit),
    /// Follow a moving target (FOLLOW_TARGET fixes).
    Follow(Follow),
    /// Descend without a position (GPS loss).
    Descend {
        /// What to fly when the position returns before touchdown.
        then: DescendThen,
    },
}

/// What Descend gives way to when the position returns in the air: what
/// was intended when the position was lost.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum DescendThen {
    /// Fly the mission on from the item it stood at (PX4 gives the pilot's
    /// mode back once the position it needs is valid again).
    Mission,
    /// Hold where it is.
    Hold,
    /// Keep landing, with the position (Land where it is).
    Land,
    /// Return to launch.
    Return,
}

/// Whether a shaped reference has reached `target` and stopped.
fn arrived(r: &Reference, target: &Vector3<f64>) -> bool {
    (r.position_ned - target).norm() < REF_ARRIVED_M && r.velocity_ned.norm() < REF_STOPPED_M_S
}

/// Guidance state.
#[derive(Debug)]
pub(super) struct Navigator {
    nav: Nav,
    base_limits: ShaperLimits,
    shaper: Shaper,
    /// The shaper's state is the reference of the previous step (else reset it to the measurement first).
    shaper_live: bool,
    /// DO_CHANGE_SPEED override of MPC_XY_CRUISE [m/s].
    cruise_override: Option<f64>,
    /// Latest offboard setpoint (resolved to local NED) and its arrival time [s].
    offboard: Option<(LocalSetpoint, f64)>,
    /// The runtime declared it lost (wall-clock timing, [`ClientClock::Wall`]).
    offboard_lost: bool,
    /// Attitude target integrated from body-rate setpoints.
    rate_target: Option<UnitQuaternion<f64>>,
    /// Where the mission stands (kept while other modes fly: pause and resume).
    mission: MissionRun,
    /// The corners round the geofence a return flies before its destination
    /// [m], NED horizontal, planned as it starts.
    rtl_route: Vec<Vector2<f64>>,
    /// Latest FOLLOW_TARGET fix, resolved to NED, and its arrival time.
    follow_target: Option<Target>,
    /// Latest sticks and their arrival time [s].
    manual: Option<(ManualControl, f64)>,
    /// The sticks were declared lost (simulated or wall-clock timing).
    manual_lost: bool,
    /// Vertical reference of Altitude and Descend.
    vertical: Option<manual::Vertical>,
    /// Heading setpoint of Altitude, Stabilized and Descend [rad].
    yaw_sp: Option<f64>,
    /// What the modes may rely on of the horizontal solution (as of the latest step).
    position: PositionValidity,
    /// Altitude is flown because Position lost its position (back on its return).
    position_fallback: bool,
}

impl Navigator {
    /// Hold, with the airframe's shaper limits.
    ///
    /// # Errors
    /// Limits the shaper refuses.
    pub(super) fn new(base_limits: ShaperLimits) -> Result<Self, ShaperError> {
        Ok(Self {
            nav: Nav::Hold { target: None },
            base_limits,
            shaper: Shaper::new(base_limits)?,
            shaper_live: false,
            cruise_override: None,
            offboard: None,
            offboard_lost: false,
            rate_target: None,
            mission: MissionRun::default(),
            rtl_route: Vec::new(),
            follow_target: None,
            manual: None,
            manual_lost: false,
            vertical: None,
            yaw_sp: None,
            position: PositionValidity::default(),
            position_fallback: false,
        })
    }

    /// The mode as clients see it.
    pub(super) fn mode(&self) -> FlightMode {
        match self.nav {
            Nav::Hold { .. } => FlightMode::Hold,
            Nav::Takeoff { .. } => FlightMode::Takeoff,
            Nav::Land { .. } => FlightMode::Land,
            Nav::Rtl { .. } => FlightMode::ReturnToLaunch,
            Nav::Offboard => FlightMode::Offboard,
            Nav::Mission => FlightMode::Mission,
            Nav::Manual(mode) => mode.flight_mode(),
            Nav::Orbit(_) => FlightMode::Orbit,
            Nav::Follow(_) => FlightMode::FollowTarget,
            Nav::Descend { .. } => FlightMode::Descend,
        }
    }

    /// The active mode with its state.
    pub(super) fn nav(&self) -> Nav {
        self.nav
    }

    /// What the modes may rely on of the horizontal solution (as of the latest step).
    pub(super) fn position(&self) -> PositionValidity {
        self.position
    }

    /// Whether the position is lost for the autonomous modes (as of the latest step).
    pub(super) fn position_lost(&self) -> bool {
        !self.position.position
    }

    /// Where the mission stands.
    pub(super) fn mission(&self) -> &MissionRun {
        &self.mission
    }

    /// Where the mission stands, to change it (start, set current, reset).
    pub(super) fn mission_mut(&mut self) -> &mut MissionRun {
        &mut self.mission
    }

    /// The mode and the mission's standing, to put back with [`Self::restore`].
    pub(super) fn saved(&self) -> (Nav, MissionRun) {
        (self.nav, self.mission.clone())
    }

    /// Put back what [`Self::saved`] gave (a command that failed half-way).
    pub(super) fn restore(&mut self, (nav, mission): (Nav, MissionRun)) {
        self.nav = nav;
        self.mission = mission;
    }

    /// A DO_SET_HOME the mission flew past, for the autopilot to carry out.
    pub(super) fn take_mission_home(&mut self) -> Option<SetHome> {
        self.mission.new_home.take()
    }

    /// Mission items reached or run since the last call, oldest first.
    pub(super) fn drain_mission_done(&mut self) -> Vec<mission::ItemDone> {
        std::mem::take(&mut self.mission.done)
    }

    /// The landed state (never undefined): Takeoff while a takeoff runs,
    /// OnGround when landed, Landing while descending to land, else InAir.
    pub(super) fn landed_state(&self, armed: bool, landed: bool) -> LandedState {
        let landing = self.landing();
        let taking_off =
            matches!(self.nav, Nav::Takeoff { .. }) || (self.nav == Nav::Mission && self.mission_taking_off());
        if armed && taking_off {
            LandedState::Takeoff
        } else if landed {
            LandedState::OnGround
        } else if armed && landing {
            LandedState::Landing
        } else {
            LandedState::InAir
        }
    }

    /// Whether the active mode is landing: Land, Descend, a return's land
    /// phase, a mission's landing item.
    pub(super) fn landing(&self) -> bool {
        let landing = matches!(
            self.nav,
            Nav::Land { .. }
                | Nav::Descend { .. }
                | Nav::Rtl {
                    phase: RtlPhase::Land,
                    ..
                }
        );
        landing || (self.nav == Nav::Mission && self.mission_landing())
    }

    /// Where the vehicle is meant to be: the live reference, else the measured position [m], NED.
    pub(super) fn current_position(&self, meas: &Measurement) -> Vector3<f64> {
        if self.shaper_live {
            self.shaper.reference().position_ned
        } else {
            meas.position_ned
        }
    }

    /// The cruise speed in force [m/s].
    pub(super) fn cruise_m_s(&self, s: &Settings) -> f64 {
        self.cruise_override.unwrap_or(s.cruise_m_s).min(s.xy_vel_max_m_s)
    }

    /// A new `MPC_XY_CRUISE` replaces a DO_CHANGE_SPEED override.
    pub(super) fn cruise_parameter_changed(&mut self) {
        self.cruise_override = None;
    }

    /// Disarmed: back to Hold (a manual mode is kept, as PX4 keeps the
    /// pilot's mode), the references and rate target dropped.
    pub(super) fn disarmed(&mut self) {
        if !matches!(self.nav, Nav::Manual(_)) {
            self.nav = Nav::Hold { target: None };
        }
        self.restart_references();
    }

    /// The rotors were stopped: the reference restarts from the measurement.
    pub(super) fn drop_reference(&mut self) {
        self.shaper_live = false;
    }

    fn limits(&self, xy: f64, up: f64, down: f64) -> ShaperLimits {
        ShaperLimits {
            max_speed_xy_m_s: xy,
            max_climb_m_s: up,
            max_descent_m_s: down,
            ..self.base_limits
        }
    }

    /// The shaped reference towards `sp` with `limits` (restarted at the measurement when not live).
    fn shape(&mut self, meas: &Measurement, sp: Setpoint, limits: ShaperLimits, dt: f64) -> Reference {
        if *self.shaper.limits() != limits {
            // the limits come from validated parameters; on refusal the old ones stay
            let _ = self.shaper.set_limits(limits);
        }
        if !self.shaper_live {
            self.shaper.reset_to(meas);
            self.shaper_live = true;
        }
        self.shaper.update(&sp, dt)
    }

    fn go_to(
        &mut self,
        meas: &Measurement,
        target: Vector3<f64>,
        yaw: YawSetpoint,
        limits: ShaperLimits,
        dt: f64,
    ) -> Reference {
        self.shape(
            meas,
            Setpoint {
                translation: TranslationSetpoint::Position(target),
                yaw,
            },
            limits,
            dt,
        )
    }

    /// The demand of the active mode at `t_k` (may advance the mode: takeoff
    /// done, RTL phases).
    pub(super) fn guidance(&mut self, armed: bool, cx: &Situation<'_>, say: &mut Announcements) -> Demand {
        let demand = if armed { self.mode_demand(cx, say) } else { Demand::Stop };
        if matches!(demand, Demand::Stop | Demand::Idle) {
            self.shaper_live = false;
            self.vertical = None;
            self.yaw_sp = None;
            self.rate_target = None;
        }
        demand
    }
}
