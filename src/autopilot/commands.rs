//! Commands: what each [`AutopilotCommand`] does and when it is refused
//! (PX4 behaviour, doc `mavlink-compat.md` sections 3, 5 and 8).

use nalgebra::Vector3;

use super::pilot::{HoldTarget, Nav};
use super::{AutopilotCommand, CommandOutcome, FlightMode, OffboardSetpoint, Severity};
use crate::geo::GeoPoint;

/// DO_CHANGE_SPEED's "back to the default speed" value.
const SPEED_DEFAULT: f64 = -2.0;

fn finite3(v: &Vector3<f64>) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Whether a setpoint can be followed: every given part finite, something given.
fn setpoint_valid(sp: &OffboardSetpoint) -> bool {
    match sp {
        OffboardSetpoint::Local {
            position_ned,
            velocity_ned,
            acceleration_ned,
            yaw_rad,
            yaw_rate_rad_s,
        } => {
            let parts = [position_ned, velocity_ned, acceleration_ned];
            parts.iter().any(|p| p.is_some())
                && parts.iter().all(|p| p.is_none_or(|v| finite3(&v)))
                && yaw_rad.is_none_or(f64::is_finite)
                && yaw_rate_rad_s.is_none_or(f64::is_finite)
        }
        OffboardSetpoint::Attitude {
            attitude,
            rate_frd,
            thrust_normalised,
        } => {
            thrust_normalised.is_finite()
                && attitude.is_none_or(|q| q.coords.iter().all(|x| x.is_finite()))
                && rate_frd.is_none_or(|w| finite3(&w))
        }
    }
}

impl super::Autopilot {
    /// Carry out a command. Accepted commands take effect from the next
    /// [`Self::step`]; refusals leave everything as it was and, for arming,
    /// takeoff and mode changes, queue a STATUSTEXT saying why.
    ///
    /// | command | refused |
    /// |---|---|
    /// | `Arm` | TemporarilyRejected when a prearm check fails (not landed, estimator not initialised, home invalid, mode not armable: Offboard without fresh setpoints); `force` skips the checks |
    /// | `Disarm` | TemporarilyRejected in the air unless forced (forced: rotors stop, the vehicle falls) |
    /// | `Takeoff` | Denied for a non-finite altitude; TemporarilyRejected when disarmed |
    /// | `Land`, `ReturnToLaunch` | TemporarilyRejected when disarmed |
    /// | `SetMode` | Takeoff, Land, RTL as above; Offboard TemporarilyRejected without a setpoint within COM_OF_LOSS_T; Mission TemporarilyRejected (no mission) |
    /// | `Reposition` | Denied for non-finite parts or lat/lon out of range; TemporarilyRejected when disarmed |
    /// | `ChangeSpeed` | Denied when not finite |
    /// | `SetHome` | Denied for an invalid point |
    /// | `Offboard` | Denied when a given part is not finite, or nothing is given |
    ///
    /// Disarmed, Hold and Position are always accepted. Selecting the active
    /// mode again is accepted and changes nothing.
    pub fn command(&mut self, cmd: AutopilotCommand) -> CommandOutcome {
        match cmd {
            AutopilotCommand::Arm { force } => self.arm(force),
            AutopilotCommand::Disarm { force } => self.disarm(force),
            AutopilotCommand::Takeoff { altitude_amsl_m } => self.takeoff(altitude_amsl_m),
            AutopilotCommand::Land => self.land(),
            AutopilotCommand::ReturnToLaunch => self.return_to_launch(),
            AutopilotCommand::SetMode(mode) => self.set_mode(mode),
            AutopilotCommand::Reposition {
                lat_deg,
                lon_deg,
                alt_amsl_m,
                yaw_rad,
                speed_m_s,
            } => self.reposition(lat_deg, lon_deg, alt_amsl_m, yaw_rad, speed_m_s),
            AutopilotCommand::ChangeSpeed { speed_m_s } => self.change_speed(speed_m_s),
            AutopilotCommand::SetHome(point) => self.set_home(point),
            AutopilotCommand::Offboard(sp) => self.offboard_setpoint(sp),
        }
    }

    fn refuse(&mut self, severity: Severity, text: &str, outcome: CommandOutcome) -> CommandOutcome {
        self.announce(severity, text);
        outcome
    }

    fn not_armed(&mut self, what: &str) -> CommandOutcome {
        self.refuse(
            Severity::Critical,
            &format!("{what} denied: vehicle not armed"),
            CommandOutcome::TemporarilyRejected("vehicle not armed"),
        )
    }

    fn arm(&mut self, force: bool) -> CommandOutcome {
        if self.armed {
            return CommandOutcome::Accepted;
        }
        if !force && let Some(why) = self.prearm_failure() {
            return self.refuse(
                Severity::Critical,
                &format!("Arming denied: {why}"),
                CommandOutcome::TemporarilyRejected(why),
            );
        }
        self.arm_now();
        CommandOutcome::Accepted
    }

    fn disarm(&mut self, force: bool) -> CommandOutcome {
        if !self.armed {
            return CommandOutcome::Accepted;
        }
        if !force && !self.landed {
            return self.refuse(
                Severity::Critical,
                "Disarming denied: not landed",
                CommandOutcome::TemporarilyRejected("vehicle in the air"),
            );
        }
        self.disarm_now("Disarmed by external command");
        CommandOutcome::Accepted
    }

    /// Take off to `altitude_amsl_m` (None: home + MIS_TAKEOFF_ALT; lower
    /// targets raised to that; a vehicle already higher keeps its altitude).
    fn takeoff(&mut self, altitude_amsl_m: Option<f64>) -> CommandOutcome {
        if altitude_amsl_m.is_some_and(|a| !a.is_finite()) {
            return CommandOutcome::Denied("invalid takeoff altitude");
        }
        if !self.armed {
            return self.not_armed("Takeoff");
        }
        let home = self.home_ned();
        let min_alt = self.settings.takeoff_alt_m;
        let mut z = home.z - min_alt;
        if let Some(a) = altitude_amsl_m {
            let z_asked = self.origin.alt_amsl_m - a;
            if z_asked > z {
                self.announce(
                    Severity::Info,
                    format!("Using minimum takeoff altitude: {min_alt:.2} m"),
                );
            } else {
                z = z_asked;
            }
        }
        let here = self.current_position();
        let z = z.min(here.z);
        self.nav = Nav::Takeoff {
            target_ned: Vector3::new(here.x, here.y, z),
            then: None,
        };
        self.announce(Severity::Info, format!("Takeoff to {:.1} m above home", home.z - z));
        CommandOutcome::Accepted
    }

    fn land(&mut self) -> CommandOutcome {
        if !self.armed {
            return self.not_armed("Land");
        }
        if !matches!(self.nav, Nav::Land { .. }) {
            self.enter_land();
        }
        CommandOutcome::Accepted
    }

    fn return_to_launch(&mut self) -> CommandOutcome {
        if !self.armed {
            return self.not_armed("Return");
        }
        if !matches!(self.nav, Nav::Rtl { .. }) {
            self.enter_rtl();
        }
        CommandOutcome::Accepted
    }

    fn set_mode(&mut self, mode: FlightMode) -> CommandOutcome {
        if mode == self.mode() {
            return CommandOutcome::Accepted;
        }
        match mode {
            FlightMode::Hold | FlightMode::Position => {
                self.nav = Nav::Hold {
                    position_mode: mode == FlightMode::Position,
                    target: None,
                };
                CommandOutcome::Accepted
            }
            FlightMode::Takeoff => self.takeoff(None),
            FlightMode::Land => self.land(),
            FlightMode::ReturnToLaunch => self.return_to_launch(),
            FlightMode::Offboard => {
                if self.offboard_fresh() {
                    self.nav = Nav::Offboard;
                    self.rate_target = None;
                    CommandOutcome::Accepted
                } else {
                    self.refuse(
                        Severity::Critical,
                        "Switching to Offboard denied: no offboard signal",
                        CommandOutcome::TemporarilyRejected("no offboard signal"),
                    )
                }
            }
            FlightMode::Mission => self.refuse(
                Severity::Critical,
                "Switching to Mission denied: no mission",
                CommandOutcome::TemporarilyRejected("no mission"),
            ),
        }
    }

    /// DO_REPOSITION: fly to the point in Hold; `None` parts keep the current
    /// value. On the ground (armed) it takes off first, to at least
    /// MIS_TAKEOFF_ALT, as PX4 does.
    fn reposition(
        &mut self,
        lat_deg: Option<f64>,
        lon_deg: Option<f64>,
        alt_amsl_m: Option<f64>,
        yaw_rad: Option<f64>,
        speed_m_s: Option<f64>,
    ) -> CommandOutcome {
        let parts = [lat_deg, lon_deg, alt_amsl_m, yaw_rad, speed_m_s];
        if parts.iter().flatten().any(|x| !x.is_finite()) {
            return CommandOutcome::Denied("invalid reposition value");
        }
        if lat_deg.is_some_and(|l| l.abs() > 90.0) || lon_deg.is_some_and(|l| l.abs() > 180.0) {
            return CommandOutcome::Denied("invalid reposition position");
        }
        if !self.armed {
            return self.not_armed("Reposition");
        }
        let here = self.current_position();
        let here_geo = self.origin.offset(&here);
        let point = GeoPoint {
            lat_deg: lat_deg.unwrap_or(here_geo.lat_deg),
            lon_deg: lon_deg.unwrap_or(here_geo.lon_deg),
            alt_amsl_m: alt_amsl_m.unwrap_or(here_geo.alt_amsl_m),
        };
        let mut target = point.ned_from(&self.origin);
        // keep the unchanged parts exact (no round trip through degrees)
        if lat_deg.is_none() && lon_deg.is_none() {
            target.x = here.x;
            target.y = here.y;
        }
        if alt_amsl_m.is_none() {
            target.z = here.z;
        }
        let hold = HoldTarget {
            position_ned: target,
            yaw_rad,
            speed_m_s: speed_m_s
                .filter(|s| *s > 0.0)
                .map(|s| s.min(self.settings.xy_vel_max_m_s)),
        };
        if self.landed {
            let home = self.home_ned();
            let z = target.z.min(home.z - self.settings.takeoff_alt_m).min(here.z);
            self.nav = Nav::Takeoff {
                target_ned: Vector3::new(here.x, here.y, z),
                then: Some(hold),
            };
            self.announce(Severity::Info, format!("Takeoff to {:.1} m above home", home.z - z));
        } else {
            self.nav = Nav::Hold {
                position_mode: false,
                target: Some(hold),
            };
        }
        CommandOutcome::Accepted
    }

    /// DO_CHANGE_SPEED: a positive speed becomes the cruise speed (capped at
    /// MPC_XY_VEL_MAX), -2 restores MPC_XY_CRUISE, other values change nothing.
    fn change_speed(&mut self, speed_m_s: f64) -> CommandOutcome {
        if !speed_m_s.is_finite() {
            return CommandOutcome::Denied("invalid speed");
        }
        if speed_m_s == SPEED_DEFAULT {
            self.cruise_override = None;
        } else if speed_m_s > 0.0 {
            self.cruise_override = Some(speed_m_s.min(self.settings.xy_vel_max_m_s));
        } else {
            return CommandOutcome::Accepted;
        }
        if let Nav::Hold { target: Some(t), .. } = &mut self.nav {
            t.speed_m_s = None;
        }
        CommandOutcome::Accepted
    }

    /// Home here (on the ground: the ground under the vehicle) or at `point`.
    fn set_home(&mut self, point: Option<GeoPoint>) -> CommandOutcome {
        let home = match point {
            Some(p) if p.is_valid() => p,
            Some(_) => return CommandOutcome::Denied("invalid home position"),
            None => {
                let mut p = self.vehicle.plant().state().position_ned;
                if self.landed {
                    p.z = self.vehicle.plant().world().ground_z_ned;
                }
                self.origin.offset(&p)
            }
        };
        self.home = home;
        CommandOutcome::Accepted
    }

    fn offboard_setpoint(&mut self, sp: OffboardSetpoint) -> CommandOutcome {
        if !setpoint_valid(&sp) {
            return CommandOutcome::Denied("invalid offboard setpoint");
        }
        if !matches!(sp, OffboardSetpoint::Attitude { attitude: None, .. }) {
            self.rate_target = None;
        }
        self.offboard = Some((sp, self.time_s()));
        CommandOutcome::Accepted
    }
}
