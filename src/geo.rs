//! Flat-earth conversion between NED around home and WGS-84 latitude,
//! longitude and AMSL altitude (equirectangular, accurate to centimetres
//! within a few kilometres of home: good enough for SITL, and said so).
//!
//! `north = (lat - lat0) R`, `east = (lon - lon0) R cos(lat0)`, `down = alt0 - alt`,
//! with `R = 6 371 000 m` and angles in radians.
//!
//! Also the Earth's magnetic field at a point ([`earth_field_ned_gauss`]): one
//! model for the simulated magnetometer and for any flight-stack code that
//! needs the declination, so the two never disagree.
//!
//! And the ISA atmosphere: the pressure PX4's simulated barometer makes
//! ([`isa`]) and the pressure altitude PX4 reads back ([`pressure_altitude_m`]),
//! side by side with their deliberately different sea-level temperatures.

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

/// IGRF-13 degree-1 Gauss coefficients for epoch 2020.0 [nT]: the tilted
/// dipole `g10`, `g11`, `h11` (IAGA, International Geomagnetic Reference
/// Field, 13th generation).
const IGRF_2020_G10_NT: f64 = -29_404.8;
const IGRF_2020_G11_NT: f64 = -1_450.9;
const IGRF_2020_H11_NT: f64 = 4_652.5;

/// The Earth's magnetic field at `at` [gauss], NED: the IGRF-13 2020.0
/// tilted dipole on the surface of a spherical Earth (`r = a`; the latitude
/// taken as geocentric), with colatitude `theta` and longitude `phi`:
///
/// ```text
/// B_r     = 2 (g10 cos theta + (g11 cos phi + h11 sin phi) sin theta)
/// B_theta =    g10 sin theta - (g11 cos phi + h11 sin phi) cos theta
/// B_phi   =    g11 sin phi - h11 cos phi
/// N = -B_theta,  E = B_phi,  D = -B_r          (1 gauss = 1e5 nT)
/// ```
///
/// A dipole gets the intensity and inclination within a few per cent over
/// the populated latitudes but the declination only within some 20 degrees
/// (at PX4's SITL home it gives 48.6 uT, 66 deg down, -14 deg where the
/// World Magnetic Model says 48.4 uT, 63.6 deg, +3 deg); the altitude is
/// ignored (the field changes by 0.05 % per kilometre).
#[must_use]
pub fn earth_field_ned_gauss(at: &GeoPoint) -> Vector3<f64> {
    let theta = (90.0 - at.lat_deg).to_radians();
    let phi = at.lon_deg.to_radians();
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    let m = IGRF_2020_G11_NT * cp + IGRF_2020_H11_NT * sp;
    let b_r = 2.0 * (IGRF_2020_G10_NT * ct + m * st);
    let b_theta = IGRF_2020_G10_NT * st - m * ct;
    let b_phi = IGRF_2020_G11_NT * sp - IGRF_2020_H11_NT * cp;
    Vector3::new(-b_theta, b_phi, -b_r) * 1e-5
}

/// ISA sea-level pressure [Pa].
pub const ISA_P0_PA: f64 = 101_325.0;
/// ISA temperature lapse rate in the troposphere [K/m].
pub const ISA_LAPSE_K_M: f64 = 0.0065;
/// ISA pressure exponent `g / (R L)` as PX4 rounds it.
pub const ISA_EXPONENT: f64 = 5.256;
/// Sea-level temperature [K] of PX4's simulated barometer (`sensor_baro_sim`).
pub const ISA_T0_SIM_K: f64 = 288.0;
/// Sea-level temperature [K] of PX4's pressure altitude (`vehicle_air_data`:
/// 15 degC), the ISA's own.
pub const ISA_T0_K: f64 = 288.15;

/// The ISA troposphere at `alt_amsl_m` [m], as PX4's simulated barometer
/// computes it: pressure [Pa] and temperature [degC],
/// `T = T0 - L h`, `p = p0 (T / T0)^5.256`, with PX4's `T0` = 288 K
/// ([`ISA_T0_SIM_K`]).
///
/// PX4 is not symmetric here, and neither are we: its simulator makes the
/// pressure with 288 K, its flight stack reads the altitude back with
/// 288.15 K ([`pressure_altitude_m`]), so a barometer's pressure altitude
/// reads 0.05 % high (0.25 m at 488 m), as on a PX4 SITL vehicle.
#[must_use]
pub fn isa(alt_amsl_m: f64) -> (f64, f64) {
    let t = ISA_T0_SIM_K - ISA_LAPSE_K_M * alt_amsl_m;
    (ISA_P0_PA * (t / ISA_T0_SIM_K).powf(ISA_EXPONENT), t - 273.15)
}

/// The pressure altitude [m] of a static pressure `pressure_pa` [Pa] in
/// the ISA troposphere, as PX4 derives its barometric altitude:
/// `h = T0 / L (1 - (p / p0)^(1 / 5.256))` with `T0` = 288.15 K
/// ([`ISA_T0_K`]; the inverse of [`isa`] but for its 288 K).
#[must_use]
pub fn pressure_altitude_m(pressure_pa: f64) -> f64 {
    ISA_T0_K / ISA_LAPSE_K_M * (1.0 - (pressure_pa / ISA_P0_PA).powf(1.0 / ISA_EXPONENT))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_dipole_field_at_px4_home_and_at_the_poles() {
        let b = earth_field_ned_gauss(&GeoPoint::PX4_SITL_HOME);
        let total = b.norm();
        let inclination = b.z.atan2(b.xy().norm()).to_degrees();
        let declination = b.y.atan2(b.x).to_degrees();
        // the World Magnetic Model at Zurich: 0.484 G, 63.6 deg; the dipole's own figures
        assert!((total - 0.484).abs() < 0.01, "{total}");
        assert!((inclination - 63.6).abs() < 3.0, "{inclination}");
        assert!((declination + 14.0).abs() < 1.0, "{declination}");
        // the geographic north pole: nearly straight down, about twice the equator's
        let pole = earth_field_ned_gauss(&GeoPoint {
            lat_deg: 90.0,
            lon_deg: 0.0,
            alt_amsl_m: 0.0,
        });
        assert!((pole.z - 2.0 * 0.294_048).abs() < 1e-6, "{pole}");
        let equator = earth_field_ned_gauss(&GeoPoint {
            lat_deg: 0.0,
            lon_deg: 0.0,
            alt_amsl_m: 0.0,
        });
        assert!((equator.x - 0.294_048).abs() < 1e-6, "{equator}");
    }

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
