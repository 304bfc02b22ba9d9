//! The geofence as PX4's navigator checks it: the stored fence plan
//! (MAV_MISSION_TYPE_FENCE) — polygons (`MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION`
//! 5001 / `_EXCLUSION` 5002, param1 = vertex count, that many consecutive
//! items) and circles (`MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION` 5003 /
//! `_EXCLUSION` 5004, param1 = radius [m]) — plus `GF_MAX_HOR_DIST` and
//! `GF_MAX_VER_DIST` around home (0 = off). Pure geometry in local NED: the
//! geographic points are placed around the NED origin (flat earth,
//! [`GeoPoint::ned_from`]); zones are vertical prisms (PX4's fences have no
//! floor or ceiling of their own).
//!
//! ```text
//! inside  = (no inclusion zone  or  p in some inclusion zone)  and  p in no exclusion zone
//! circle:   |p_xy - c_xy| <= r
//! polygon:  odd number of edge crossings of the ray from p_xy towards +east (even-odd rule)
//! max dist: |p_xy - home_xy| <= GF_MAX_HOR_DIST,  (home_z - p_z) <= GF_MAX_VER_DIST   (NED: up = -z)
//! ```
//! The check is on the current position only: PX4 also predicts the
//! position a braking distance ahead (`GF_PREDICT`); this does not.

use nalgebra::{Vector2, Vector3};

use crate::geo::GeoPoint;
use crate::mission::MissionItem;

use crate::mission::cmd::{
    FENCE_CIRCLE_EXCLUSION as CIRCLE_EXCLUSION, FENCE_CIRCLE_INCLUSION as CIRCLE_INCLUSION,
    FENCE_POLYGON_VERTEX_EXCLUSION as POLYGON_EXCLUSION, FENCE_POLYGON_VERTEX_INCLUSION as POLYGON_INCLUSION,
};

/// One zone, horizontal, in local NED [m].
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Zone {
    /// A polygon (vertices north, east, in order; closed implicitly).
    Polygon(Vec<Vector2<f64>>),
    /// A circle.
    Circle {
        /// Centre (north, east) [m].
        centre: Vector2<f64>,
        /// Radius [m].
        radius_m: f64,
    },
}

impl Zone {
    /// Whether the horizontal point `p` (north, east) [m] lies inside (the border counts as inside for circles).
    pub(super) fn contains(&self, p: Vector2<f64>) -> bool {
        match self {
            Zone::Circle { centre, radius_m } => (p - centre).norm() <= *radius_m,
            Zone::Polygon(v) => polygon_contains(v, p),
        }
    }
}

/// Even-odd rule: count the edges crossed by the ray from `p` towards +east (+y).
fn polygon_contains(v: &[Vector2<f64>], p: Vector2<f64>) -> bool {
    let mut inside = false;
    let n = v.len();
    for i in 0..n {
        let (a, b) = (v[i], v[(i + n - 1) % n]);
        // edge a-b straddles the north coordinate of p, and crosses east of it
        if (a.x > p.x) != (b.x > p.x) {
            let y_cross = a.y + (p.x - a.x) * (b.y - a.y) / (b.x - a.x);
            if p.y < y_cross {
                inside = !inside;
            }
        }
    }
    inside
}

/// How the fence is breached.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Breach {
    /// Outside every inclusion zone.
    OutsideInclusion,
    /// Inside an exclusion zone.
    InsideExclusion,
    /// Farther than `GF_MAX_HOR_DIST` from home.
    MaxHorizontalDistance,
    /// Higher than `GF_MAX_VER_DIST` above home.
    MaxAltitude,
}

impl Breach {
    /// What the STATUSTEXT says.
    pub(super) fn describe(self) -> &'static str {
        match self {
            Breach::OutsideInclusion => "outside geofence",
            Breach::InsideExclusion => "inside exclusion zone",
            Breach::MaxHorizontalDistance => "max distance exceeded",
            Breach::MaxAltitude => "max altitude exceeded",
        }
    }
}

/// The fence in local NED.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Fence {
    /// Inclusion zones: inside one of them is inside.
    pub(super) inclusion: Vec<Zone>,
    /// Exclusion zones: inside any of them is a breach.
    pub(super) exclusion: Vec<Zone>,
}

impl Fence {
    /// The zones of the fence plan `items` placed around `origin`. A polygon
    /// whose items run out before its vertex count (or that is interrupted by
    /// another kind of item) is dropped: it has no shape. Return points are
    /// not zones.
    pub(super) fn from_items(items: &[MissionItem], origin: &GeoPoint) -> Self {
        let mut fence = Fence::default();
        let xy = |it: &MissionItem| {
            GeoPoint {
                lat_deg: it.x,
                lon_deg: it.y,
                alt_amsl_m: origin.alt_amsl_m,
            }
            .ned_from(origin)
            .xy()
        };
        let mut i = 0;
        while i < items.len() {
            let it = &items[i];
            match it.command {
                POLYGON_INCLUSION | POLYGON_EXCLUSION => {
                    let count = f64::from(it.params[0]).max(0.0) as usize;
                    let run = items[i..]
                        .iter()
                        .take(count)
                        .take_while(|v| v.command == it.command)
                        .count();
                    if count >= 3 && run == count {
                        let zone = Zone::Polygon(items[i..i + count].iter().map(xy).collect());
                        if it.command == POLYGON_INCLUSION {
                            fence.inclusion.push(zone);
                        } else {
                            fence.exclusion.push(zone);
                        }
                    }
                    i += run.max(1);
                }
                CIRCLE_INCLUSION | CIRCLE_EXCLUSION => {
                    let zone = Zone::Circle {
                        centre: xy(it),
                        radius_m: f64::from(it.params[0]),
                    };
                    if it.command == CIRCLE_INCLUSION {
                        fence.inclusion.push(zone);
                    } else {
                        fence.exclusion.push(zone);
                    }
                    i += 1;
                }
                _ => i += 1,
            }
        }
        fence
    }

    /// The zones' verdict on the horizontal point `p` (north, east) [m].
    pub(super) fn zones_breach(&self, p: Vector2<f64>) -> Option<Breach> {
        if !self.inclusion.is_empty() && !self.inclusion.iter().any(|z| z.contains(p)) {
            return Some(Breach::OutsideInclusion);
        }
        if self.exclusion.iter().any(|z| z.contains(p)) {
            return Some(Breach::InsideExclusion);
        }
        None
    }
}

/// The distance limits around home (`GF_MAX_HOR_DIST`, `GF_MAX_VER_DIST`; 0 = off) [m].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct DistanceLimits {
    /// Largest horizontal distance from home [m], 0 = none.
    pub(super) max_horizontal_m: f64,
    /// Largest height above home [m], 0 = none.
    pub(super) max_vertical_m: f64,
}

impl DistanceLimits {
    /// The lowest NED z allowed (`home_z - GF_MAX_VER_DIST`), if limited.
    pub(super) fn min_z_ned(&self, home_ned: &Vector3<f64>) -> Option<f64> {
        (self.max_vertical_m > 0.0).then(|| home_ned.z - self.max_vertical_m)
    }

    /// The limits' verdict on `p` [m], NED, with home at `home_ned`.
    pub(super) fn breach(&self, p: &Vector3<f64>, home_ned: &Vector3<f64>) -> Option<Breach> {
        if self.min_z_ned(home_ned).is_some_and(|z| p.z < z) {
            return Some(Breach::MaxAltitude);
        }
        if self.max_horizontal_m > 0.0 && (p.xy() - home_ned.xy()).norm() > self.max_horizontal_m {
            return Some(Breach::MaxHorizontalDistance);
        }
        None
    }
}

/// The whole check: distance limits first, then the zones.
pub(super) fn check(
    fence: &Fence,
    limits: &DistanceLimits,
    p: &Vector3<f64>,
    home_ned: &Vector3<f64>,
) -> Option<Breach> {
    limits.breach(p, home_ned).or_else(|| fence.zones_breach(p.xy()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn item(command: u16, p1: f32, ned_n: f64, ned_e: f64) -> MissionItem {
        let g = GeoPoint::PX4_SITL_HOME.offset(&Vector3::new(ned_n, ned_e, 0.0));
        MissionItem {
            frame: 0,
            command,
            autocontinue: true,
            params: [p1, 0.0, 0.0, 0.0],
            x: g.lat_deg,
            y: g.lon_deg,
            z: 0.0,
        }
    }

    fn square(command: u16, n0: f64, e0: f64, side: f64) -> Vec<MissionItem> {
        [(0.0, 0.0), (side, 0.0), (side, side), (0.0, side)]
            .iter()
            .map(|(n, e)| item(command, 4.0, n0 + n, e0 + e))
            .collect()
    }

    #[test]
    fn inclusion_and_exclusion_polygons_and_circles() {
        let mut items = square(POLYGON_INCLUSION, -50.0, -50.0, 100.0);
        items.extend(square(POLYGON_EXCLUSION, 10.0, 10.0, 10.0));
        items.push(item(CIRCLE_INCLUSION, 20.0, 0.0, 200.0));
        items.push(item(CIRCLE_EXCLUSION, 5.0, -30.0, -30.0));
        let f = Fence::from_items(&items, &GeoPoint::PX4_SITL_HOME);
        assert_eq!((f.inclusion.len(), f.exclusion.len()), (2, 2));
        let at = |n: f64, e: f64| f.zones_breach(Vector2::new(n, e));
        assert_eq!(at(0.0, 0.0), None);
        assert_eq!(at(15.0, 15.0), Some(Breach::InsideExclusion));
        assert_eq!(at(-30.0, -31.0), Some(Breach::InsideExclusion));
        assert_eq!(at(0.0, 60.0), Some(Breach::OutsideInclusion));
        assert_eq!(at(0.0, 210.0), None, "inside the second inclusion zone");
        assert_eq!(at(49.0, 49.0), None);
        assert_eq!(at(51.0, 0.0), Some(Breach::OutsideInclusion));
    }

    /// MAVSDK's `geofence.py` example uploads its polygon with a
    /// zero-radius inclusion circle at latitude 0, longitude 0 ("the circle
    /// object is necessary"); PX4 stores it, and inside the polygon is inside.
    #[test]
    fn a_zero_radius_circle_beside_a_polygon_changes_nothing() {
        let mut items = square(POLYGON_INCLUSION, -50.0, -50.0, 100.0);
        items.push(MissionItem {
            x: 0.0,
            y: 0.0,
            ..item(CIRCLE_INCLUSION, 0.0, 0.0, 0.0)
        });
        assert_eq!(
            crate::mission::validate(crate::mission::MissionType::Fence, &items[4]),
            Ok(())
        );
        let f = Fence::from_items(&items, &GeoPoint::PX4_SITL_HOME);
        assert_eq!(f.zones_breach(Vector2::new(0.0, 0.0)), None);
        assert_eq!(f.zones_breach(Vector2::new(60.0, 0.0)), Some(Breach::OutsideInclusion));
    }

    #[test]
    fn concave_polygon() {
        // an L: the notch (north-east quarter) is outside
        let pts = [
            (0.0, 0.0),
            (20.0, 0.0),
            (20.0, 10.0),
            (10.0, 10.0),
            (10.0, 20.0),
            (0.0, 20.0),
        ];
        let items: Vec<_> = pts.iter().map(|(n, e)| item(POLYGON_INCLUSION, 6.0, *n, *e)).collect();
        let f = Fence::from_items(&items, &GeoPoint::PX4_SITL_HOME);
        assert_eq!(f.zones_breach(Vector2::new(5.0, 15.0)), None);
        assert_eq!(f.zones_breach(Vector2::new(15.0, 5.0)), None);
        assert_eq!(f.zones_breach(Vector2::new(15.0, 15.0)), Some(Breach::OutsideInclusion));
    }

    #[test]
    fn truncated_polygon_is_dropped_and_no_zone_is_no_breach() {
        let mut items = square(POLYGON_INCLUSION, 0.0, 0.0, 10.0);
        items.truncate(3);
        let f = Fence::from_items(&items, &GeoPoint::PX4_SITL_HOME);
        assert!(f.inclusion.is_empty());
        assert_eq!(f.zones_breach(Vector2::new(1000.0, 0.0)), None);
    }

    #[test]
    fn distance_limits() {
        let home = Vector3::new(0.0, 0.0, -1.0);
        let l = DistanceLimits {
            max_horizontal_m: 30.0,
            max_vertical_m: 10.0,
        };
        assert_eq!(l.breach(&Vector3::new(29.0, 0.0, -10.5), &home), None);
        assert_eq!(
            l.breach(&Vector3::new(29.0, 0.0, -11.5), &home),
            Some(Breach::MaxAltitude)
        );
        assert_eq!(
            l.breach(&Vector3::new(25.0, 25.0, -5.0), &home),
            Some(Breach::MaxHorizontalDistance)
        );
        assert_eq!(
            DistanceLimits::default().breach(&Vector3::new(1e4, 0.0, -1e3), &home),
            None
        );
    }
}
