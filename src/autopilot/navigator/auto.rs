//! The automatic modes: Hold, Takeoff,
//! Land and Return to launch, as PX4 flies them.

use nalgebra::{Vector2, Vector3};

use super::{HoldTarget, Nav, Navigator, REF_ARRIVED_M, RtlPhase, Situation, arrived};
use crate::autopilot::control_loop::Demand;
use crate::autopilot::fence_avoidance::{self, Route};
use crate::autopilot::geofence::Fence;
use crate::autopilot::status::{Announcements, Severity};
use crate::control::{Reference, Setpoint, ShaperLimits, TranslationSetpoint, YawSetpoint};
use crate::signals::Measurement;

/// Landing aims this far [m] below the resting height so the descent never slows before touchdown.
const LAND_SINK_M: f64 = 5.0;
/// A takeoff is complete when the vehicle is also within this height [m] of its target.
const TAKEOFF_ACCEPT_M: f64 = 0.25;
/// The return's way round the geofence keeps this many NAV_ACC_RAD off the zones (PX4's margin for a multicopter).
const FENCE_MARGIN_ACC_RADII: f64 = 2.0;
/// A leg round the geofence shorter than this [m] keeps the heading.
const YAW_MIN_LEG_M: f64 = 1.0;

impl Navigator {
    /// Hold where it is.
    pub(in crate::autopilot) fn enter_hold(&mut self) {
        self.nav = Nav::Hold { target: None };
    }

    /// Hold at a target (a reposition in the air).
    pub(in crate::autopilot) fn enter_hold_at(&mut self, target: HoldTarget) {
        self.nav = Nav::Hold { target: Some(target) };
    }

    /// Climb to `target_ned`, then hold there or at `then`.
    pub(in crate::autopilot) fn enter_takeoff(&mut self, target_ned: Vector3<f64>, then: Option<HoldTarget>) {
        self.nav = Nav::Takeoff { target_ned, then };
    }

    /// Land below where the vehicle is meant to be.
    pub(in crate::autopilot) fn enter_land(&mut self, meas: &Measurement, landed: bool, say: &mut Announcements) {
        let p = self.current_position(meas);
        self.nav = Nav::Land { xy: p.xy() };
        if !landed {
            say.announce(Severity::Info, "Landing at current position");
        }
    }

    /// Return: climb to at least RTL_RETURN_ALT above home where it is, fly
    /// home — or to the closest rally point when one is closer than home
    /// (PX4's RTL_TYPE 0) — round the geofence's zones, descend to
    /// RTL_DESCEND_ALT, land. The way round is planned here, once, from where
    /// the return starts ([`fence_avoidance`], margin 2 NAV_ACC_RAD); without
    /// one the line is straight.
    pub(in crate::autopilot) fn enter_rtl(&mut self, cx: &Situation<'_>, say: &mut Announcements) {
        let p = self.current_position(cx.meas);
        let z_return = p.z.min(cx.home_ned.z - cx.settings.rtl_return_alt_m);
        let rally = cx
            .rally
            .iter()
            .filter_map(|r| r.geo_point(cx.home.alt_amsl_m))
            .map(|g| g.ned_from(cx.origin).xy())
            .min_by(|a, b| (a - p.xy()).norm().total_cmp(&(b - p.xy()).norm()))
            .filter(|r| (r - p.xy()).norm() < (cx.home_ned.xy() - p.xy()).norm());
        let dest_xy = rally.unwrap_or_else(|| cx.home_ned.xy());
        self.nav = Nav::Rtl {
            phase: RtlPhase::Climb { xy: p.xy() },
            z_return,
            dest_xy,
        };
        self.rtl_route.clear();
        if !cx.landed {
            let to = if rally.is_some() { "rally point" } else { "launch" };
            say.announce(
                Severity::Info,
                format!("Return to {to} at {:.1} m above home", cx.home_ned.z - z_return),
            );
            let fence = Fence::from_items(cx.fence, cx.origin);
            let margin_m = FENCE_MARGIN_ACC_RADII * cx.settings.acceptance_radius_m;
            self.take_route(fence_avoidance::plan(&fence, margin_m, p.xy(), dest_xy), say);
        }
    }

    /// Keep the way round the geofence of a return starting, and say what it
    /// is, as PX4 does: avoiding, or flying straight without a way (with
    /// why: PX4 says that when the fence or the destination changes, in
    /// longer words than one STATUSTEXT holds).
    fn take_route(&mut self, route: Route, say: &mut Announcements) {
        match route {
            Route::NoFence | Route::Direct => {}
            Route::Around(path) => {
                self.rtl_route = path;
                say.announce(Severity::Info, "RTL: avoiding geofence");
            }
            Route::Straight(why) => {
                if let Some(code) = why.fence_code() {
                    say.announce(
                        Severity::Warning,
                        format!("Geofence data invalid (code {code}), RTL flies directly"),
                    );
                } else if why == fence_avoidance::Unplanned::DestinationOutside {
                    say.announce(Severity::Warning, "RTL destination breaches geofence, flying directly");
                }
                say.announce(Severity::Critical, "RTL: no geofence avoidance path; flying directly");
            }
        }
    }

    /// The phase after the climb or a corner round the geofence: the next
    /// corner (heading towards it from `from`), else the destination.
    fn after_corner(&self, next: usize, from: Vector2<f64>) -> RtlPhase {
        match self.rtl_route.get(next) {
            Some(corner) => {
                let d = corner - from;
                RtlPhase::Avoid {
                    leg: next,
                    yaw_rad: (d.norm() >= YAW_MIN_LEG_M).then(|| d.y.atan2(d.x)),
                }
            }
            None => RtlPhase::Return,
        }
    }

    /// DO_CHANGE_SPEED: `Some` speed becomes the cruise speed, `None` restores
    /// MPC_XY_CRUISE; a reposition in progress takes it.
    pub(in crate::autopilot) fn set_cruise(&mut self, speed_m_s: Option<f64>) {
        self.cruise_override = speed_m_s;
        if let Nav::Hold { target: Some(t), .. } = &mut self.nav {
            t.speed_m_s = None;
        }
    }

    /// The demand of the active mode: Hold, Takeoff, Land, RTL here, Offboard in `offboard`.
    pub(super) fn mode_demand(&mut self, cx: &Situation<'_>, say: &mut Announcements) -> Demand {
        let (meas, s, dt) = (cx.meas, cx.settings, cx.dt);
        let cruise = self.cruise_m_s(s);
        // the automatic modes' vertical speeds (PX4's MPC_Z_V_AUTO_UP/DN)
        let (climb, descent) = (s.auto_climb_m_s, s.auto_descent_m_s);
        let normal = self.limits(cruise, climb, descent);
        match self.nav {
            Nav::Hold { target, .. } => {
                if cx.resting {
                    return Demand::Idle;
                }
                let r = match target {
                    None => self.shape(
                        meas,
                        Setpoint {
                            translation: TranslationSetpoint::Hold,
                            yaw: YawSetpoint::Hold,
                        },
                        normal,
                        dt,
                    ),
                    Some(t) => {
                        let limits = self.limits(t.speed_m_s.unwrap_or(cruise), climb, descent);
                        let yaw = t.yaw_rad.map_or(YawSetpoint::Hold, YawSetpoint::Angle);
                        self.go_to(meas, t.position_ned, yaw, limits, dt)
                    }
                };
                Demand::Track(r)
            }
            Nav::Takeoff { target_ned, then } => {
                let height_m = cx.home_ned.z - meas.position_ned.z;
                let limits = self.limits(cruise, s.takeoff_climb_m_s(height_m), descent);
                let r = self.go_to(meas, target_ned, YawSetpoint::Hold, limits, dt);
                if arrived(&r, &target_ned) && (meas.position_ned.z - target_ned.z).abs() < TAKEOFF_ACCEPT_M {
                    self.nav = Nav::Hold {
                        target: Some(then.unwrap_or(HoldTarget {
                            position_ned: target_ned,
                            yaw_rad: None,
                            speed_m_s: None,
                        })),
                    };
                    say.announce(Severity::Info, "Takeoff complete, holding position");
                }
                Demand::Track(r)
            }
            Nav::Land { xy } => {
                if cx.resting {
                    Demand::Idle
                } else {
                    Demand::Track(self.descend(cx, xy))
                }
            }
            Nav::Rtl {
                phase,
                z_return,
                dest_xy,
            } => {
                if cx.resting {
                    return Demand::Idle;
                }
                Demand::Track(self.rtl(cx, phase, z_return, dest_xy, normal, say))
            }
            Nav::Offboard => self.offboard_demand(cx),
            Nav::Mission => self.mission_demand(cx, say),
            Nav::Manual(mode) => self.manual_demand(cx, mode),
            Nav::Orbit(orbit) => self.orbit_demand(cx, orbit),
            Nav::Follow(f) => self.follow_demand(cx, f),
            Nav::Descend { .. } => self.descend_demand(cx),
        }
    }

    /// Descend to land at `xy`, at PX4's landing speed for the height
    /// ([`crate::autopilot::settings::Settings::land_descent_m_s`]: MPC_Z_VEL_MAX_DN above MPC_LAND_ALT1,
    /// slowing linearly to MPC_LAND_SPEED at MPC_LAND_ALT2).
    pub(super) fn descend(&mut self, cx: &Situation<'_>, xy: Vector2<f64>) -> Reference {
        let s = cx.settings;
        let speed = s.land_descent_m_s(cx.rest_z - cx.meas.position_ned.z);
        let target = Vector3::new(xy.x, xy.y, cx.rest_z + LAND_SINK_M);
        let limits = self.limits(self.cruise_m_s(s), s.auto_climb_m_s, speed);
        self.go_to(cx.meas, target, YawSetpoint::Hold, limits, cx.dt)
    }

    fn rtl(
        &mut self,
        cx: &Situation<'_>,
        phase: RtlPhase,
        z_return: f64,
        dest_xy: Vector2<f64>,
        normal: ShaperLimits,
        say: &mut Announcements,
    ) -> Reference {
        let (meas, dt) = (cx.meas, cx.dt);
        let home = Vector3::new(dest_xy.x, dest_xy.y, cx.home_ned.z);
        let z_descend = home.z - cx.settings.rtl_descend_alt_m;
        let set_phase = |nav: &mut Navigator, phase: RtlPhase| {
            nav.nav = Nav::Rtl {
                phase,
                z_return,
                dest_xy,
            };
        };
        match phase {
            RtlPhase::Climb { xy } => {
                let target = Vector3::new(xy.x, xy.y, z_return);
                let r = self.go_to(meas, target, YawSetpoint::Hold, normal, dt);
                if arrived(&r, &target) {
                    let next = self.after_corner(0, xy);
                    set_phase(self, next);
                }
                r
            }
            RtlPhase::Avoid { leg, yaw_rad } => {
                let corner = self.rtl_route.get(leg).copied().unwrap_or(home.xy());
                let target = Vector3::new(corner.x, corner.y, z_return);
                let yaw = yaw_rad.map_or(YawSetpoint::Hold, YawSetpoint::Angle);
                let r = self.go_to(meas, target, yaw, normal, dt);
                let near = (meas.position_ned.xy() - corner).norm() <= cx.settings.acceptance_radius_m;
                if arrived(&r, &target) && near {
                    let next = self.after_corner(leg + 1, corner);
                    set_phase(self, next);
                }
                r
            }
            RtlPhase::Return => {
                let target = Vector3::new(home.x, home.y, z_return);
                let r = self.go_to(meas, target, YawSetpoint::Hold, normal, dt);
                let near = (meas.position_ned.xy() - home.xy()).norm() <= cx.settings.acceptance_radius_m;
                if arrived(&r, &target) && near {
                    if z_return < z_descend - REF_ARRIVED_M {
                        set_phase(self, RtlPhase::Descend);
                    } else {
                        set_phase(self, RtlPhase::Land);
                        say.announce(Severity::Info, "RTL: landing");
                    }
                }
                r
            }
            RtlPhase::Descend => {
                let target = Vector3::new(home.x, home.y, z_descend);
                let r = self.go_to(meas, target, YawSetpoint::Hold, normal, dt);
                if arrived(&r, &target) {
                    set_phase(self, RtlPhase::Land);
                    say.announce(Severity::Info, "RTL: landing");
                }
                r
            }
            RtlPhase::Land => self.descend(cx, home.xy()),
        }
    }
}
