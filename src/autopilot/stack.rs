//! The [`Autopilot`]: the flight stack's state, its construction from the
//! parameters, and one step in order — detect landing, hold or run the
//! estimator, supervise, guide, control.

use std::borrow::Cow;

use nalgebra::Vector3;

use super::battery::BatteryMonitor;
use super::commander::Commander;
use super::control_loop::{ControlLoop, ControlOutput, RotorAllocation};
use super::error::AutopilotError;
use super::estimate::EstimateFeedback;
use super::failsafe::{Failsafe, cause};
use super::land_detector::LandDetector;
use super::navigation::{FilterNavigation, NavSource, ideal_navigation_report, nav_config};
use super::navigator::{DescendThen, Navigator};
use super::position_checks::{PositionChecks, PositionLoss, PositionValidity};
use super::rotor_monitor::{RotorEvent, RotorMonitor, RotorStatus};
use super::settings::FailsafeAction;
use super::settings::Settings;
use super::status::{Announcements, Severity, StatusText};
use super::telemetry::{OrbitStatus, RotorOutputs, Telemetry, VehicleType};
use super::vibration::VibrationMonitor;
use super::wind::WindMonitor;
use crate::airframe::{Actuation, Airframe};
use crate::control::{ControlGains, ControllerKind, GainError, RelaxedHoverError, ShaperLimits};
use crate::estimation::{Discretization, EstimatorConfig, MomentumEstimator};
use crate::geo::GeoPoint;
use crate::mission::{MissionResult, PlanChange, Plans};
use crate::params::ParamStore;
use crate::signals::{ActuatorCommand, GRAVITY, GpsFix, MAX_ROTORS, NominalModel, SensorReadings, WrenchEstimate};

/// The gains for the airframe flown with the nominal mass `MDL_MASS`
/// ([`ControlGains::for_airframe`]) and the loop frequency scales
/// `CTRL_POS_SCALE`, `CTRL_ATT_SCALE` (stiffness x s^2, damping and the
/// passivity coupling x s: every pole of the loop moves by the factor s,
/// damping ratios unchanged). On the navigation filter the geometric law's
/// `w_d_dot` is low-passed at [`FILTER_OMEGA_DOT_D_CUTOFF_HZ`] unless the
/// airframe sets a cutoff of its own.
fn control_gains(airframe: &Airframe, s: &Settings, nav: NavSource) -> Result<ControlGains, GainError> {
    let mut g = ControlGains::for_airframe(airframe, s.model_mass_kg)?;
    if nav == NavSource::Filter && g.geometric.omega_dot_d_cutoff_hz == 0.0 {
        g.geometric.omega_dot_d_cutoff_hz = FILTER_OMEGA_DOT_D_CUTOFF_HZ;
    }
    let (p, a) = (s.position_scale, s.attitude_scale);
    let (p2, a2) = (p * p, a * a);
    let h = &mut g.hierarchical;
    h.kp_pos_per_s2 *= p2;
    h.kd_pos_per_s *= p;
    h.kp_att_per_s2 *= a2;
    h.kd_att_per_s *= a;
    let geo = &mut g.geometric;
    geo.kp_n_per_m *= p2;
    geo.kv_n_s_per_m *= p;
    geo.kr_n_m_per_rad *= a2;
    geo.komega_n_m_s_per_rad *= a;
    let pa = &mut g.passivity;
    pa.sigma_p_per_s *= p;
    pa.dp_n_s_per_m *= p;
    pa.kp_n_per_m *= p2;
    pa.sigma_per_s *= a;
    pa.do_n_m_s_per_rad *= a;
    pa.ko_n_m_per_rad *= a2;
    g.validate()?;
    Ok(g)
}

/// Cutoff [Hz] of the geometric law's `w_d_dot` low-pass on the navigation
/// filter: its solution is propagated by 250 Hz IMU samples, so the desired
/// attitude moves in kinks 4 ms apart and its raw second difference at 1 kHz
/// is a train of spikes (in hover on a quad: 0.45 N m of roll torque RMS,
/// rotors hitting both limits). At 10 Hz (a 16 ms time constant, under the
/// rotors' lag) the torque is calm and the tracking unchanged.
const FILTER_OMEGA_DOT_D_CUTOFF_HZ: f64 = 10.0;

fn estimator_config(s: &Settings, dt: f64) -> EstimatorConfig {
    EstimatorConfig {
        order: s.estimator_order,
        polynomial: s.estimator_polynomial.clone(),
        cutoff_rad_s: s.estimator_cutoff_rad_s,
        discretization: Discretization::Trapezoidal,
        sample_time_s: dt,
    }
}

/// The flight stack of one vehicle.
///
/// Each [`Self::step`] takes the sensor readings at `t_k`, detects landing,
/// updates the estimator (held while resting on the ground), supervises,
/// decides the [`Demand`] for the mode and the estimate to feed back, and
/// returns what the actuators get over `[t_k, t_{k+1})`.
#[derive(Debug)]
pub struct Autopilot {
    pub(super) airframe: Airframe,
    pub(super) settings: Settings,
    dt: f64,
    control: ControlLoop,
    feedback: EstimateFeedback,
    pub(super) navigator: Navigator,
    pub(super) land: LandDetector,
    pub(super) battery: BatteryMonitor,
    /// Commanded versus ESC-reported rotor speeds.
    rotors: RotorMonitor,
    pub(super) origin: GeoPoint,
    pub(super) home: GeoPoint,
    /// `home` in local NED [m] around `origin`, kept with it: read several
    /// times a step, and each conversion costs a cosine.
    home_ned: Vector3<f64>,
    /// Whether home's altitude still waits for the resting height.
    home_altitude: HomeAltitude,
    /// Arming and the commands' gates.
    pub(super) commander: Commander,
    /// The time of the latest readings [s].
    pub(super) now_s: f64,
    pub(super) say: Announcements,
    /// The stored mission, geofence and rally points.
    pub(super) plans: Plans,
    /// The failsafes: data link, battery, geofence, the client clock.
    pub(super) failsafe: Failsafe,
    /// The wind estimate (the estimated force through the nominal drag).
    wind: WindMonitor,
    /// The failsafe in force, if any (PX4's `vehicle_status.failsafe`).
    pub(super) in_failsafe: Option<FailsafeInForce>,
    /// A failsafe the pilot took over from by selecting a mode while its
    /// cause lasts (PX4 keeps its action in the failsafe framework's list,
    /// the user takeover active): the next failsafe, a lost position's
    /// Descend included, ends the takeover and the more severe action of the
    /// two is in force. Forgotten when its cause clears or on disarming.
    pub(super) taken_over: Option<FailsafeInForce>,
    /// The navigation filter flown on (`RP_NAV_SRC` = 1, read at boot);
    /// `None`: the readings' own navigation solution.
    navigation: Option<Box<FilterNavigation>>,
    /// The commander's checks of the filter's horizontal accuracy (unused on the ideal solution).
    position_checks: PositionChecks,
    /// The IMU's vibration metrics (PX4's `vehicle_imu_status`), from the raw samples.
    vibration: VibrationMonitor,
}

/// A failsafe in force: an action the pilot did not command, taken by the
/// flight stack (PX4's failsafe framework: `vehicle_status.failsafe` is
/// true while its selected action is not `None`). It starts when a failsafe
/// acts (the one runner, or the flight stack replacing a mode it cannot fly
/// without a position) and ends when the vehicle disarms, when the pilot
/// selects a mode (PX4's user takeover), or when a lost position returns
/// and the mode the pilot meant is flown again. A failsafe taken over while
/// its cause lasts comes back with the next failsafe (PX4: a new action
/// ends the takeover, the most severe action in force is flown).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FailsafeInForce {
    /// Why: the failsafe's cause (`no GPS fix`, `GCS connection lost`,
    /// `battery critical`, ...; one of [`super::FAILSAFE_CAUSES`]).
    pub cause: String,
    /// What it has the vehicle do (Hold, Return, Land; a descent without
    /// position gives way to it); `None` for a mode replaced because the
    /// position was lost.
    pub(super) action: Option<DescendThen>,
    /// What it triggered, as announced (`Return`, `Land`, `Descend`, ...;
    /// one of [`super::FAILSAFE_ACTIONS`]).
    pub triggered: &'static str,
}

impl Autopilot {
    /// An autopilot for `airframe` stepping by `dt_s` [s], disarmed on the
    /// ground at `home` (the NED origin), in Hold, with `params` applied.
    ///
    /// # Errors
    /// Invalid home, or parameters that give invalid gains or estimator settings.
    pub fn new(airframe: &Airframe, home: GeoPoint, params: &ParamStore, dt_s: f64) -> Result<Self, AutopilotError> {
        if !home.is_valid() {
            return Err(AutopilotError::InvalidHome {
                lat_deg: home.lat_deg,
                lon_deg: home.lon_deg,
                alt_amsl_m: home.alt_amsl_m,
            });
        }
        let settings = Settings::from_store(params)?;
        // the nominal model (MDL_MASS) is set by `apply_params` below
        let control = ControlLoop::new(
            airframe,
            settings.controller,
            control_gains(airframe, &settings, NavSource::from_params(params))?,
            estimator_config(&settings, dt_s),
        )?;
        let mut ap = Self {
            airframe: airframe.clone(),
            battery: BatteryMonitor::new(settings.battery_cells),
            rotors: RotorMonitor::new(
                match airframe.actuation {
                    Actuation::Rotors => airframe.rotor_count(),
                    Actuation::Ideal => 0,
                },
                airframe.rotor.time_constant_s,
                airframe.rotor.speed_min_rad_s,
                airframe.rotor.speed_max_rad_s,
            ),
            settings,
            dt: dt_s,
            control,
            feedback: EstimateFeedback::default(),
            navigator: Navigator::new(ShaperLimits::for_airframe(airframe))?,
            land: LandDetector::new(),
            origin: home,
            // until the first measurement: resting on its gear at the origin
            home: GeoPoint {
                alt_amsl_m: home.alt_amsl_m + airframe.gear_height_m,
                ..home
            },
            home_ned: Vector3::zeros(),
            home_altitude: HomeAltitude::Assumed,
            commander: Commander::default(),
            now_s: 0.0,
            say: Announcements::default(),
            plans: Plans::default(),
            failsafe: Failsafe::default(),
            wind: WindMonitor::new(airframe),
            in_failsafe: None,
            taken_over: None,
            navigation: match NavSource::from_params(params) {
                NavSource::Ideal => None,
                NavSource::Filter => Some(Box::new(FilterNavigation::new(nav_config(params), home))),
            },
            position_checks: PositionChecks::default(),
            vibration: VibrationMonitor::default(),
        };
        ap.home_ned = ap.home.ned_from(&ap.origin);
        ap.apply_params(params)?;
        Ok(ap)
    }

    /// Apply every flight-stack parameter at once, in flight too: `CTRL_TYPE`
    /// (bumpless switch), the gain scales and `MDL_MASS` (gains recomputed,
    /// nominal model of controller and estimator changed),
    /// `EST_ORDER/POLY/CUTOFF` (estimator rebuilt; with `EST_COMP` on in
    /// flight the fed-back estimate cross-fades, see `estimate`), `EST_COMP`,
    /// and the navigation values (altitudes, speeds, timeouts). Call it
    /// after every accepted parameter change.
    ///
    /// # Errors
    /// A combination the controller or estimator refuses; nothing is changed then.
    pub fn apply_params(&mut self, params: &ParamStore) -> Result<(), AutopilotError> {
        let s = Settings::from_store(params)?;
        let now = self.now_s;
        let nominal = NominalModel {
            mass_kg: s.model_mass_kg,
            inertia_kg_m2: self.airframe.inertia_kg_m2,
        };
        let nominal_changed = nominal != *self.control.nominal();
        let gains = control_gains(&self.airframe, &s, self.nav_source())?;
        let config = estimator_config(&s, self.dt);
        let rebuilt = if &config == self.control.estimator().config() {
            if nominal_changed {
                // whether the estimator accepts the model, asked of a copy
                self.control.estimator().clone().set_nominal(nominal)?;
            }
            None
        } else {
            Some(MomentumEstimator::new(config, nominal)?)
        };
        // Everything is valid: commit.
        self.control.controller_mut().set_gains(gains)?;
        self.control.switch_controller(s.controller);
        if let Some(e) = rebuilt {
            if s.feedback && !self.land.landed() {
                let from = self.feedback.current(
                    &self.control.estimate(),
                    now,
                    self.settings.feedback,
                    self.control.nominal().mass_kg,
                );
                let duration = EstimateFeedback::fade_duration_s(s.estimator_order, s.estimator_cutoff_rad_s);
                self.feedback.start_fade(from, now, duration);
            }
            self.control.replace_estimator(e);
        }
        if nominal_changed {
            self.control.set_nominal(nominal)?;
        }
        self.battery.set_cells(s.battery_cells);
        if s.cruise_m_s != self.settings.cruise_m_s {
            self.navigator.cruise_parameter_changed();
        }
        self.settings = s;
        Ok(())
    }

    /// One step at `t_k` (the readings' time): the land detector on the
    /// measurement and last step's thrust; the estimator restarted while
    /// resting on the ground, else updated; offboard-loss and auto-disarm
    /// supervision; guidance for the mode; the controller and allocation.
    pub fn step(&mut self, readings: &SensorReadings) -> &ControlOutput {
        if let Some(nav) = self.navigation.as_deref_mut() {
            nav.update(readings);
        }
        self.vibration.update(&readings.raw);
        let readings = self.navigated(readings);
        let readings = &*readings;
        let m = &readings.measurement;
        let now = m.time_s;
        self.now_s = now;
        if !self.commander.armed() {
            // disarmed (a failsafe's disarm shows for the step it acted)
            self.in_failsafe = None;
            self.taken_over = None;
        }
        let weight = self.control.nominal().mass_kg * GRAVITY;
        // a filter still aligning gives no solution to learn the resting
        // height from; after that the detector needs only the height
        let land_reads = match self.navigation.as_deref() {
            None => true,
            Some(nav) if self.land.has_rest_height() => nav.height_ready(),
            Some(nav) => nav.ready(),
        };
        if land_reads {
            let commanded_vz = self.control.commanded_vz_m_s();
            let event = self
                .land
                .update(m, self.control.last_applied().thrust_n, weight, commanded_vz);
            self.commander.land_event(event, now, &mut self.say);
            if self.home_altitude == HomeAltitude::Assumed {
                self.home_at_rest(m);
            }
        }
        if self.land.landed() || self.land.ground_contact() {
            // The ground's reaction is no external wrench worth estimating:
            // restart from every resting sample, estimate from liftoff on.
            self.control.reset_estimator();
            self.feedback.cancel_fade();
        }
        let estimate = self.control.sense(m);
        let airborne = !(self.land.landed() || self.land.ground_contact());
        self.wind.update(airborne, readings, &estimate);
        self.battery.update(&readings.battery, self.dt);
        self.supervise_battery(readings);
        let rotor_events = self.rotors.update(now, &readings.rotor_speeds_rad_s);
        if !rotor_events.is_empty() {
            self.rotors_changed(&rotor_events, m);
        }
        if self.land.ground_contact() && self.control.relaxed_hover().is_some_and(|f| !f.landed()) {
            // on the ground before relaxed hover's touchdown height (the
            // ground is higher than where the vehicle last rested)
            self.control.cut_relaxed_hover();
        }
        self.supervise(m);
        // the position; the sticks' loss is a client timer (in `supervise`)
        let position = self.position_validity(readings);
        let armed = self.commander.armed();
        let cx = situation!(self, m);
        let mode = self.navigator.mode();
        self.navigator.supervise_position(position, armed, &cx, &mut self.say);
        if self
            .taken_over
            .as_ref()
            .is_some_and(|f| !self.failsafe_cause_lasts(&f.cause))
        {
            self.taken_over = None;
        }
        if self.navigator.mode() != mode {
            if let Some(then) = self.navigator.descending_then()
                && let Some(f) = self.taken_over.take()
            {
                // the pilot's mode replaced by Descend (PX4's mode fallback,
                // a new failsafe): the takeover ends, and the failsafe taken
                // over, its cause still there, is in force again; the more
                // severe of the two follows when the position returns
                let then = f.action.map_or(then, |a| a.most_severe(then));
                self.navigator.set_descend_then(then);
                self.say.announce(
                    Severity::Critical,
                    format!("Failsafe: {}, triggering {}", f.cause, FailsafeAction::Descend.name()),
                );
                self.in_failsafe = Some(FailsafeInForce {
                    cause: f.cause,
                    action: Some(then),
                    triggered: FailsafeAction::Descend.name(),
                });
            } else if let Some(then) = self.navigator.descending_then()
                && let Some(f) = self.in_failsafe.as_mut()
                && let Some(action) = f.action
            {
                // a failsafe's own mode replaced: that failsafe stays in
                // force (PX4: its action, the most severe, falls back to
                // Descend), and it is what follows when the position returns
                let then = action.most_severe(then);
                f.action = Some(then);
                self.navigator.set_descend_then(then);
            } else if self.navigator.flying_blind() {
                // a mode it cannot fly without a position, replaced
                self.enter_blind_failsafe();
            } else if self
                .in_failsafe
                .as_ref()
                .is_some_and(|f| PositionLoss::is_cause(&f.cause))
            {
                // the position is back and what was meant is flown again
                self.in_failsafe = None;
            }
        }
        let cx = situation!(self, m);
        let demand = self.navigator.guidance(self.commander.armed(), &cx, &mut self.say);
        if let Some(h) = self.navigator.take_mission_home() {
            self.mission_set_home(h, m);
        }
        let feedback = self.settings.feedback.then(|| self.feedback.feed_back(&estimate, now));
        let out = self.control.act(m, &demand, feedback.as_ref(), self.dt);
        self.rotors.commanded(&out.actuator);
        self.control.output()
    }

    /// The rotor monitor changed its verdict on some rotors: announce each
    /// (Critical failed, Warning degraded, Info recovered), reallocate over
    /// what remains ([`ControlLoop::set_rotor_gains`]), and react in the air:
    /// a quad with one dead rotor (rank-deficient allocation) flies relaxed
    /// hover ([`ControlLoop::engage_relaxed_hover`]): yaw given up, it holds
    /// the point where the failure was detected and descends at
    /// `MPC_LAND_SPEED` in Land mode, rotors stopped at touchdown, disarmed as
    /// after any landing; when relaxed hover cannot fly it (e.g. no
    /// rotational drag in the airframe) it lands at once. Any other rotor
    /// that got worse triggers `COM_ACT_FAIL_ACT` (0 warn only and keep the
    /// mode, 1 Hold, 2 Land, 3 Return, 4 Terminate), as PX4 flies on with
    /// what its allocator can give: also when no hover holds the heading any
    /// more ([`RotorAllocation::LostYaw`]), where the heading is left free and
    /// the yaw gets what roll, pitch and thrust leave.
    fn rotors_changed(&mut self, events: &[RotorEvent], m: &crate::signals::Measurement) {
        let gains: Vec<f64> = self.rotors.status().iter().map(|r| r.thrust_fraction()).collect();
        let allocation = self.control.set_rotor_gains(&gains).clone();
        let flying = self.commander.armed() && !self.land.landed();
        // relaxed hover: land on the ground below the point of detection
        // (the resting height the land detector learned, plus the gear)
        let relaxed = match &allocation {
            RotorAllocation::RelaxedHover { .. } if flying => {
                let ground_z = self.land.rest_z(m) + self.airframe.gear_height_m;
                let target = Vector3::new(m.position_ned.x, m.position_ned.y, ground_z);
                Some(
                    self.control
                        .engage_relaxed_hover(target, self.settings.land_speed_m_s)
                        .map(|_| ()),
                )
            }
            _ => None,
        };
        let what = match (&allocation, &relaxed) {
            (RotorAllocation::Full | RotorAllocation::Reduced { .. }, _) => "reallocated",
            (RotorAllocation::LostYaw { .. }, _) => "heading free",
            (RotorAllocation::RelaxedHover { .. }, Some(Ok(()))) => "yaw given up, descending",
            (RotorAllocation::RelaxedHover { .. }, _) => "no hover",
        };
        let mut worse = false;
        for e in events {
            let label = self.airframe.motor_of_rotor(e.index);
            match e.to {
                RotorStatus::Failed => {
                    worse = true;
                    self.say
                        .announce(Severity::Critical, format!("Motor {label} failed: {what}"));
                }
                RotorStatus::Degraded { thrust_fraction } => {
                    worse |= thrust_fraction < e.from.thrust_fraction();
                    self.say.announce(
                        Severity::Warning,
                        format!("Motor {label} degraded: {:.0}% thrust, {what}", 100.0 * thrust_fraction),
                    );
                }
                RotorStatus::Healthy => {
                    self.say.announce(Severity::Info, format!("Motor {label} recovered"));
                }
            }
        }
        if !flying || !worse {
            return;
        }
        // the emergency landings go through the one failsafe runner (a
        // landing under way goes on; without a fix it descends blind)
        match relaxed {
            Some(Ok(())) => {
                self.say
                    .announce(Severity::Emergency, "Rotor loss: yaw given up, emergency descent");
                self.failsafe_action(cause::ROTOR_LOSS, FailsafeAction::Land, m);
            }
            Some(Err(e)) => {
                // (a STATUSTEXT holds 50 characters: the reason in short)
                let why = match e {
                    RelaxedHoverError::NoRotationalDrag => "no rotational drag",
                    RelaxedHoverError::NoEquilibrium(_) => "no equilibrium",
                    _ => "no relaxed hover",
                };
                self.say
                    .announce(Severity::Emergency, format!("Rotor loss: yaw lost, landing: {why}"));
                self.failsafe_action(cause::ROTOR_LOSS, FailsafeAction::Land, m);
            }
            None => {
                let action = self.settings.actuator_failure_action;
                self.failsafe_action(cause::ROTOR_FAILURE, action, m);
            }
        }
    }

    /// `readings` as the flight stack flies on them: as read with the ideal
    /// navigation source, else with the filter's solution in place of the
    /// readings' own ([`FilterNavigation::readings`]; the filter is fed in
    /// [`Self::step`] only, so a reading between steps sees the latest estimate).
    pub(super) fn navigated<'a>(&self, readings: &'a SensorReadings) -> Cow<'a, SensorReadings> {
        match self.navigation.as_deref() {
            None => Cow::Borrowed(readings),
            Some(nav) => Cow::Owned(nav.readings(readings)),
        }
    }

    /// The commander's verdict on the horizontal solution at the instant
    /// of `readings` ([`super::position_checks`]): on the ideal solution
    /// the GNSS fix alone; on the filter its validity and accuracy against
    /// `COM_POS_FS_EPH` and `COM_VEL_FS_EVH`, with PX4's hysteresis.
    fn position_validity(&mut self, readings: &SensorReadings) -> PositionValidity {
        let fix = readings.gps.fix != GpsFix::None;
        let Some(nav) = self.navigation.as_deref() else {
            return PositionValidity::all(fix);
        };
        let f = &self.settings.failsafe;
        self.position_checks.update(
            readings.measurement.time_s,
            &nav.horizontal_accuracy(fix),
            f.position_eph_max_m,
            f.velocity_evh_max_m_s,
        )
    }

    /// Where the navigation solution comes from (`RP_NAV_SRC` at boot).
    #[must_use]
    pub fn nav_source(&self) -> NavSource {
        if self.navigation.is_some() {
            NavSource::Filter
        } else {
            NavSource::Ideal
        }
    }

    /// The navigation filter, when the stack flies on it.
    #[must_use]
    pub fn navigation(&self) -> Option<&FilterNavigation> {
        self.navigation.as_deref()
    }

    /// The navigation solution the stack flies on at the instant of `readings`.
    #[must_use]
    pub fn solution(&self, readings: &SensorReadings) -> crate::signals::Measurement {
        match self.navigation.as_deref() {
            None => readings.measurement,
            Some(nav) => nav.measurement(readings.measurement.time_s),
        }
    }

    /// The rotor monitor's verdict per rotor (rotor 1 first).
    #[must_use]
    pub fn rotor_status(&self) -> &[RotorStatus] {
        self.rotors.status()
    }

    /// What the allocation flies with after rotor faults.
    #[must_use]
    pub fn rotor_allocation(&self) -> &RotorAllocation {
        self.control.rotor_allocation()
    }

    /// What the latest [`Self::step`] decided.
    #[must_use]
    pub fn output(&self) -> &ControlOutput {
        self.control.output()
    }

    /// The ESCs of `rotors` (indices from 0) report healthy again (a
    /// MAV_CMD_INJECT_FAILURE motor OK): while disarmed, with the rotors
    /// stopped and nothing to judge them by, the monitor takes them back
    /// (announced "Motor N recovered", the allocation whole again), so the
    /// vehicle arms as PX4 arms once its ESCs report healthy. Armed, the
    /// monitor's own evidence takes a rotor back once it follows its command.
    pub fn esc_reports_healthy(&mut self, rotors: &[usize], m: &crate::signals::Measurement) {
        if self.commander.armed() {
            return;
        }
        let events = self.rotors.reported_healthy(rotors, m.time_s);
        if !events.is_empty() {
            self.rotors_changed(&events, m);
        }
    }

    /// The actuators refused the last command (not finite) and the world
    /// stopped the rotors: announce it, disarm, start the loop over.
    pub fn rotors_stopped(&mut self, why: &str) {
        self.say
            .announce(Severity::Critical, format!("Simulation fault: {why}"));
        if self.commander.armed() {
            self.disarm_now("Disarmed: simulation fault");
        }
        self.navigator.drop_reference();
        self.control.rotors_stopped();
        self.rotors.resync();
    }

    /// A snapshot for telemetry (SI units, NED/FRD) at the instant of `readings`.
    #[must_use]
    pub fn telemetry(&self, readings: &SensorReadings) -> Telemetry {
        let readings = self.navigated(readings);
        let readings = &*readings;
        let m = &readings.measurement;
        let max_thrust = self.max_thrust_n();
        let thrust = self.control.last_applied().thrust_n;
        Telemetry {
            time_s: m.time_s,
            vehicle_type: VehicleType::from_rotor_count(self.airframe.rotor_count()),
            armed: self.commander.armed(),
            mode: self.navigator.mode(),
            failsafe: self.in_failsafe.is_some(),
            landed: self.navigator.landed_state(self.commander.armed(), self.land.landed()),
            position_ned: m.position_ned,
            velocity_ned: m.velocity_ned,
            acceleration_ned: readings.acceleration_ned,
            attitude: m.attitude,
            rate_frd: m.rate_frd,
            global: self.origin.offset(&m.position_ned),
            origin: self.origin,
            home: self.home,
            home_ned: self.home_ned(),
            gps_fix: readings.gps.fix,
            gps_satellites: readings.gps.satellites,
            battery_voltage_v: readings.battery.voltage_v,
            battery_current_a: readings.battery.current_a,
            battery_consumed_mah: self.battery.consumed_mah(),
            battery_remaining: self.battery.remaining(&readings.battery),
            battery_warning: self.battery_warning(),
            throttle: if max_thrust > 0.0 {
                (thrust / max_thrust).clamp(0.0, 1.0)
            } else {
                0.0
            },
            estimate: self.control.estimate(),
            wind: self.wind.estimate(),
            prearm_ok: self.prearm_failure(m).is_none(),
            mission: self.mission_status(),
            failed_rotors: rotor_mask(self.rotors.status(), |r| r == RotorStatus::Failed),
            degraded_rotors: rotor_mask(self.rotors.status(), |r| matches!(r, RotorStatus::Degraded { .. })),
            orbit: self.navigator.orbit().map(|o| OrbitStatus {
                radius_m: o.velocity_m_s.signum() * o.radius_m,
                centre: self.origin.offset(&o.centre_ned),
                yaw: o.yaw,
            }),
            navigation: match self.navigation.as_deref() {
                Some(nav) => nav.report(),
                None => ideal_navigation_report(readings.gps.fix),
            },
            vibration: self.vibration.metrics(),
            rotor_outputs: self.rotor_outputs(),
        }
    }

    /// The latest step's rotor commands as motor outputs ([`RotorOutputs`]),
    /// by motor number ([`crate::airframe::RotorGeometry::motor`]):
    /// each commanded speed placed between idle and full speed; every rotor
    /// stopped while the actuators get no speeds (disarmed, rotors stopped),
    /// and a rotor the allocation has taken out (thrust fraction 0, flagged
    /// failed) stopped whatever the allocator left in its slot.
    fn rotor_outputs(&self) -> RotorOutputs {
        if self.airframe.actuation != Actuation::Rotors {
            return RotorOutputs::default();
        }
        let n = self.airframe.rotor_count().min(MAX_ROTORS);
        let mut out = RotorOutputs {
            count: n,
            ..RotorOutputs::default()
        };
        let ActuatorCommand::RotorSpeeds(w) = self.control.output().actuator else {
            return out;
        };
        let removed = |i: usize| match self.control.rotor_allocation() {
            RotorAllocation::Full => false,
            RotorAllocation::Reduced { gains }
            | RotorAllocation::LostYaw { gains, .. }
            | RotorAllocation::RelaxedHover { gains } => gains.get(i).is_some_and(|g| *g <= 0.0),
        };
        let (lo, hi) = (self.airframe.rotor.speed_min_rad_s, self.airframe.rotor.speed_max_rad_s);
        for i in 0..n {
            let u = (w[i] - lo) / (hi - lo);
            // channel N - 1 is motor N
            let slot = self.airframe.motor_of_rotor(i) - 1;
            if !removed(i) && u.is_finite() && slot < n {
                out.commands[slot] = Some(u.clamp(0.0, 1.0));
            }
        }
        out
    }

    /// The stored plans (mission, geofence, rally points).
    #[must_use]
    pub fn plans(&self) -> &Plans {
        &self.plans
    }

    /// Store or clear plans, whole or not at all (see [`Plans::apply`]); a
    /// new or cleared mission restarts from its first item, and a mission
    /// being flown that is cleared gives way to Hold. The new plan's id.
    ///
    /// # Errors
    /// The MAV_MISSION_RESULT naming why nothing changed.
    pub fn change_plans(&mut self, change: PlanChange) -> Result<u32, MissionResult> {
        if let PlanChange::Store { items, .. } = &change
            && let Some((seq, alt)) = above_ceiling(items, self.home.alt_amsl_m, self.settings.max_target_amsl_m)
        {
            self.say.announce(
                Severity::Critical,
                format!("Plan rejected: item {seq} at {alt:.0} m > RP_ALT_MAX_AMSL"),
            );
            return Err(MissionResult::InvalidParam7);
        }
        let touches_mission = match &change {
            PlanChange::Store { kind, .. } => *kind == crate::mission::MissionType::Mission,
            PlanChange::Clear(k) => k.is_none_or(|k| k == crate::mission::MissionType::Mission),
        };
        let id = self.plans.apply(change)?;
        if touches_mission {
            self.mission_replaced();
        }
        Ok(id)
    }

    /// Take `plans` as stored (loaded from the state dir, or kept over a
    /// reboot); the mission starts from its first item.
    pub fn restore_plans(&mut self, plans: Plans) {
        self.plans = plans;
        self.mission_replaced();
    }

    /// Mission items reached (MISSION_ITEM_REACHED) or run (items done at
    /// once) since the last call, oldest first.
    pub fn drain_mission_done(&mut self) -> Vec<super::ItemDone> {
        self.navigator.drain_mission_done()
    }

    // ----- accessors ------------------------------------------------------------------------------

    /// The airframe it flies.
    #[must_use]
    pub fn airframe(&self) -> &Airframe {
        &self.airframe
    }

    /// Step length [s].
    #[must_use]
    pub fn dt_s(&self) -> f64 {
        self.dt
    }

    /// Armed.
    #[must_use]
    pub fn armed(&self) -> bool {
        self.commander.armed()
    }

    /// The landed state clients are told (MAV_LANDED_STATE).
    #[must_use]
    pub fn landed_state(&self) -> super::LandedState {
        self.navigator.landed_state(self.commander.armed(), self.land.landed())
    }

    /// The mission's progress (MISSION_CURRENT's content).
    #[must_use]
    pub fn mission_progress(&self) -> super::MissionStatus {
        self.mission_status()
    }

    /// The mode as clients see it.
    #[must_use]
    pub fn mode(&self) -> super::FlightMode {
        self.navigator.mode()
    }

    /// The failsafe in force now, if any ([`FailsafeInForce`]).
    #[must_use]
    pub fn failsafe_in_force(&self) -> Option<&FailsafeInForce> {
        self.in_failsafe.as_ref()
    }

    /// A failsafe acts for `cause`, having the vehicle do `action`, as
    /// announced (`triggered`): in force from now (a new cause is a new
    /// failsafe; the same cause takes its new action).
    pub(super) fn enter_failsafe(&mut self, cause: &str, action: Option<DescendThen>, triggered: &'static str) {
        match &mut self.in_failsafe {
            Some(f) if f.cause == cause => {
                f.action = action.or(f.action);
                f.triggered = triggered;
            }
            _ => {
                self.in_failsafe = Some(FailsafeInForce {
                    cause: cause.into(),
                    action,
                    triggered,
                });
            }
        }
    }

    /// A mode replaced for the lost position (Descend, or Altitude in place
    /// of Position): the failsafe in force from now.
    pub(super) fn enter_blind_failsafe(&mut self) {
        let action = if self.navigator.mode() == super::FlightMode::Altitude {
            super::failsafe::ALTITUDE_FALLBACK
        } else {
            FailsafeAction::Descend.name()
        };
        self.enter_failsafe(self.navigator.position().loss.cause(), None, action);
    }

    /// The NED origin (where the vehicle booted).
    #[must_use]
    pub fn origin(&self) -> GeoPoint {
        self.origin
    }

    /// The control law flying.
    #[must_use]
    pub fn controller_kind(&self) -> ControllerKind {
        self.control.controller().kind()
    }

    /// The latest wrench estimate.
    #[must_use]
    pub fn estimate(&self) -> WrenchEstimate {
        self.control.estimate()
    }

    /// The wind estimate, once settled in the air (`None` on the ground or
    /// without a drag model to explain the force by).
    #[must_use]
    pub fn wind(&self) -> Option<crate::signals::WindEstimate> {
        self.wind.estimate()
    }

    /// The wrench estimator (its configuration and nominal model, which a flight log's sidecar records).
    #[must_use]
    pub fn estimator(&self) -> &MomentumEstimator {
        self.control.estimator()
    }

    /// Status texts since the last call, oldest first (at most the latest 64).
    pub fn drain_status_texts(&mut self) -> Vec<StatusText> {
        self.say.drain()
    }

    /// Whether the estimator has had its first sample (a prearm check).
    pub(super) fn control_initialised(&self) -> bool {
        self.control.estimator().is_initialized()
    }

    /// The controller starts over (disarmed).
    pub(super) fn reset_controller(&mut self) {
        self.control.controller_mut().reset();
    }

    /// Home's altitude becomes where the vehicle rests (the land detector's
    /// resting height, learned from the first measurement: the vehicle boots
    /// on the ground), as PX4 sets home from the vehicle's position, so
    /// relative altitudes read 0 on the ground and "take off to 5 m" means
    /// 5 m above the resting point: `alt_home = alt_origin - z_rest` (NED z
    /// down). Its latitude and longitude stay the given home's.
    fn home_at_rest(&mut self, m: &crate::signals::Measurement) {
        self.home.alt_amsl_m = self.origin.alt_amsl_m - self.land.rest_z(m);
        self.home_ned = self.home.ned_from(&self.origin);
        self.home_altitude = HomeAltitude::Set;
    }

    /// Home is `home` from now on (set by a client or the mission).
    pub(super) fn set_home(&mut self, home: GeoPoint) {
        self.home = home;
        self.home_ned = self.home.ned_from(&self.origin);
        self.home_altitude = HomeAltitude::Set;
    }

    /// Home in local NED [m].
    pub(super) fn home_ned(&self) -> Vector3<f64> {
        self.home_ned
    }

    /// The largest collective thrust [N] (what offboard thrust 1.0 means):
    /// the rotors' at full speed, or for ideal actuation the controller's cap.
    #[must_use]
    pub fn max_thrust_n(&self) -> f64 {
        match self.airframe.actuation {
            Actuation::Rotors => self.airframe.max_thrust_n(),
            Actuation::Ideal => {
                self.control.controller().gains().limits.max_thrust_g * self.control.nominal().mass_kg * GRAVITY
            }
        }
    }
}

/// Where home's altitude stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum HomeAltitude {
    /// Assumed: the vehicle on its gear at the NED origin (`z = -gear_height`), until the first step.
    Assumed,
    /// Where the vehicle rested at boot, or set by a client.
    Set,
}

/// Bit `i` set for each rotor `i` (from 0) whose status passes `pick`.
fn rotor_mask(status: &[RotorStatus], pick: impl Fn(RotorStatus) -> bool) -> u16 {
    status
        .iter()
        .enumerate()
        .filter(|(i, r)| *i < 16 && pick(**r))
        .fold(0, |m, (i, _)| m | (1 << i))
}

/// The first item of a plan whose point lies above `max_amsl_m` [m AMSL]
/// (`RP_ALT_MAX_AMSL`), with its altitude AMSL: relative frames are read
/// above `home_alt_amsl_m`, as the mission flies them. Items without a point
/// (DO_JUMP, speed changes, ...) have no altitude to check.
fn above_ceiling(items: &[crate::mission::MissionItem], home_alt_amsl_m: f64, max_amsl_m: f64) -> Option<(usize, f64)> {
    items
        .iter()
        .enumerate()
        .filter(|(_, item)| item.has_position())
        .map(|(seq, item)| (seq, item.alt_amsl(home_alt_amsl_m)))
        .find(|(_, alt)| *alt > max_amsl_m)
}
