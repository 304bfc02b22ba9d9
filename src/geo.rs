//! Flat-earth conversion between NED around home and WGS-84 latitude,
//! longitude and AMSL altitude (equirectangular, accurate to centimetres
//! within a few kilometres of home: good enough for SITL, and said so).
//!
//! `north = (lat - lat0) R`, `east = (lon - lon0) R cos(lat0)`, `down = alt0 - alt`,
//! with `R = 6 371 000 m` and angles in radians.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Mean Earth radius [m].
pub const EARTH_RADIUS_M: f64 = 6_371_000.0;

/// A geographic point.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GeoPoint {
    /// Latitude [deg].
    pub lat_deg: f64,
    /// Longitude [deg].
    pub lon_deg: f64,
    /// Altitude above mean sea level [m].
    pub alt_amsl_m: f64,
}

impl GeoPoint {
    /// PX4's default SITL home (Zurich): 47.397742, 8.545594, 488 m AMSL.
    pub const PX4_SITL_HOME: GeoPoint = GeoPoint {
        lat_deg: 47.397_742,
        lon_deg: 8.545_594,
        alt_amsl_m: 488.0,
    };

    /// Whether all three are finite and the angles in range.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        self.lat_deg.is_finite()
            && self.lon_deg.is_finite()
            && self.alt_amsl_m.is_finite()
            && self.lat_deg.abs() <= 90.0
            && self.lon_deg.abs() <= 180.0
    }

    /// NED offset [m] of `self` from `origin`.
    #[must_use]
    pub fn ned_from(&self, origin: &GeoPoint) -> Vector3<f64> {
        let lat0 = origin.lat_deg.to_radians();
        Vector3::new(
            (self.lat_deg - origin.lat_deg).to_radians() * EARTH_RADIUS_M,
            (self.lon_deg - origin.lon_deg).to_radians() * EARTH_RADIUS_M * lat0.cos(),
            origin.alt_amsl_m - self.alt_amsl_m,
        )
    }

    /// The point at NED offset `ned` [m] from `self`.
    #[must_use]
    pub fn offset(&self, ned: &Vector3<f64>) -> GeoPoint {
        let lat0 = self.lat_deg.to_radians();
        GeoPoint {
            lat_deg: self.lat_deg + (ned.x / EARTH_RADIUS_M).to_degrees(),
            lon_deg: self.lon_deg + (ned.y / (EARTH_RADIUS_M * lat0.cos())).to_degrees(),
            alt_amsl_m: self.alt_amsl_m - ned.z,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_scale() {
        let home = GeoPoint::PX4_SITL_HOME;
        let ned = Vector3::new(120.0, -35.5, -20.0);
        let p = home.offset(&ned);
        assert!((p.ned_from(&home) - ned).norm() < 1e-9);
        assert!((p.alt_amsl_m - 508.0).abs() < 1e-12);
        // one degree of latitude is about 111.2 km
        let north = GeoPoint {
            lat_deg: home.lat_deg + 1.0,
            ..home
        };
        assert!((north.ned_from(&home).x - 111_194.9).abs() < 1.0);
    }
}
