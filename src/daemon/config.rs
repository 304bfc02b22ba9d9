//! What one daemon runs: the airframe, the instance and PX4 SITL's port
//! rules for it, home, the speed factor, the links, the state directory.

use std::net::{IpAddr, Ipv4Addr, SocketAddr, ToSocketAddrs as _};
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context as _, bail};

use crate::geo::GeoPoint;
use crate::link::streams::{self, Rates};

/// One UDP link of the daemon.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkSpec {
    /// Name for logs and the startup summary.
    pub name: String,
    /// Where the socket binds (port 0: any free port).
    pub bind: SocketAddr,
    /// Where to send from boot, before anyone talks.
    pub remote: Option<SocketAddr>,
    /// Default stream rates.
    pub rates: Rates,
}

impl LinkSpec {
    /// PX4 SITL's GCS link of instance `n`: bound to 18570+n, sending to
    /// 127.0.0.1:14550 (the same for every instance, as PX4).
    #[must_use]
    pub fn px4_gcs(n: u8) -> Self {
        Self {
            name: "GCS".into(),
            bind: SocketAddr::new(IpAddr::V4(Ipv4Addr::UNSPECIFIED), 18570 + u16::from(n)),
            remote: Some(SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), 14550)),
            rates: streams::gcs_rates(),
        }
    }

    /// PX4 SITL's API/offboard link of instance `n`: bound to 14580+n,
    /// sending to 127.0.0.1:14540+n (14549 for n > 9, PX4's
    /// `px4-rc.mavlink` rule to keep ports from overlapping).
    #[must_use]
    pub fn px4_api(n: u8) -> Self {
        let remote = if n > 9 { 14549 } else { 14540 + u16::from(n) };
        Self {
            name: "API".into(),
            bind: SocketAddr::new(IpAddr::V4(Ipv4Addr::UNSPECIFIED), 14580 + u16::from(n)),
            remote: Some(SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), remote)),
            rates: streams::api_rates(),
        }
    }

    /// An extra link from `udpout:HOST:PORT` (send to HOST:PORT from an
    /// ephemeral port) or `udpin:HOST:PORT` (bind there, serve whoever talks).
    /// Extra links stream at the GCS rates.
    ///
    /// # Errors
    /// Not one of those two forms, or a host that does not resolve.
    pub fn parse(spec: &str) -> anyhow::Result<Self> {
        let (kind, addr) = spec
            .split_once(':')
            .with_context(|| format!("link `{spec}`: expected udpout:HOST:PORT or udpin:HOST:PORT"))?;
        let addr = resolve(addr).with_context(|| format!("link `{spec}`"))?;
        match kind {
            "udpout" => Ok(Self {
                name: spec.to_string(),
                bind: SocketAddr::new(
                    if addr.is_ipv4() {
                        IpAddr::V4(Ipv4Addr::UNSPECIFIED)
                    } else {
                        IpAddr::V6(std::net::Ipv6Addr::UNSPECIFIED)
                    },
                    0,
                ),
                remote: Some(addr),
                rates: streams::gcs_rates(),
            }),
            "udpin" => Ok(Self {
                name: spec.to_string(),
                bind: addr,
                remote: None,
                rates: streams::gcs_rates(),
            }),
            _ => bail!("link `{spec}`: expected udpout:HOST:PORT or udpin:HOST:PORT"),
        }
    }
}

/// `HOST:PORT` to one address (IPv4 preferred).
///
/// # Errors
/// It does not resolve.
pub fn resolve(s: &str) -> anyhow::Result<SocketAddr> {
    let addrs: Vec<SocketAddr> = s
        .to_socket_addrs()
        .with_context(|| format!("`{s}` is not HOST:PORT"))?
        .collect();
    addrs
        .iter()
        .find(|a| a.is_ipv4())
        .or(addrs.first())
        .copied()
        .with_context(|| format!("`{s}` does not resolve"))
}

/// `LAT,LON,ALT` (degrees, degrees, metres AMSL).
///
/// # Errors
/// Not three numbers, or not a valid position.
pub fn parse_home(s: &str) -> anyhow::Result<GeoPoint> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--home `{s}`: expected LAT,LON,ALT"))?;
    let [lat_deg, lon_deg, alt_amsl_m] = v[..] else {
        bail!("--home `{s}`: expected three numbers LAT,LON,ALT");
    };
    anyhow::ensure!(
        lat_deg.is_finite() && lat_deg.abs() <= 90.0,
        "--home `{s}`: latitude {lat_deg} is out of range (-90 to 90 degrees)"
    );
    anyhow::ensure!(
        lon_deg.is_finite() && lon_deg.abs() <= 180.0,
        "--home `{s}`: longitude {lon_deg} is out of range (-180 to 180 degrees)"
    );
    anyhow::ensure!(
        alt_amsl_m.is_finite(),
        "--home `{s}`: altitude {alt_amsl_m} is not a number of metres"
    );
    Ok(GeoPoint {
        lat_deg,
        lon_deg,
        alt_amsl_m,
    })
}

/// Everything one daemon needs.
#[derive(Clone, Debug)]
pub struct Config {
    /// Airframe name or TOML path.
    pub airframe: String,
    /// PX4 SITL instance: system id = instance + 1.
    pub instance: u8,
    /// Home and NED origin.
    pub home: GeoPoint,
    /// Simulated seconds per wall second.
    pub speed: f64,
    /// The UDP links.
    pub links: Vec<LinkSpec>,
    /// Where the parameter file and the stored plans live.
    pub state_dir: PathBuf,
    /// Start from default parameters (the file is overwritten on the first save).
    pub reset_params: bool,
    /// Start with no mission, geofence or rally points (the file is
    /// overwritten at start).
    pub reset_plans: bool,
    /// A learned peer is forgotten after this long without a frame from it.
    pub peer_timeout: Duration,
    /// Wall-time period of the simulation batches.
    pub tick: Duration,
    /// Where flight logs go (`--log-dir`): each run writes into a directory
    /// of its own below this one ([`crate::daemon::logs`]); `None`: no logs.
    pub log_dir: Option<PathBuf>,
    /// Also write the per-step flight CSV (`simulate --csv`'s format) into
    /// the run's log directory (`--log-csv`; large: one row per step).
    pub log_csv: bool,
    /// When the process started (the configuration is made first thing):
    /// the ready line counts from here.
    pub started: std::time::Instant,
    /// Parameters set at start over the stored file (a fleet file's
    /// `params`), in the file's order: name and value, applied with the
    /// parameter's own type (the fleet file checked name, type and range).
    pub param_overrides: Vec<(String, f64)>,
}

impl Config {
    /// PX4 SITL instance `n` with its GCS and API links, the default airframe
    /// and home, real time, state under `rotorpilot-state/n`.
    #[must_use]
    pub fn px4_sitl(n: u8) -> Self {
        Self {
            airframe: crate::airframe::DEFAULT_AIRFRAME.to_string(),
            instance: n,
            home: GeoPoint::PX4_SITL_HOME,
            speed: 1.0,
            links: vec![LinkSpec::px4_gcs(n), LinkSpec::px4_api(n)],
            state_dir: PathBuf::from("rotorpilot-state").join(n.to_string()),
            reset_params: false,
            reset_plans: false,
            peer_timeout: Duration::from_secs(30),
            tick: Duration::from_millis(4),
            log_dir: None,
            log_csv: false,
            started: std::time::Instant::now(),
            param_overrides: Vec::new(),
        }
    }

    /// MAVLink system id (PX4 SITL: instance + 1).
    #[must_use]
    pub fn system_id(&self) -> u8 {
        self.instance.saturating_add(1)
    }

    /// The parameter file.
    #[must_use]
    pub fn params_path(&self) -> PathBuf {
        self.state_dir.join("params.toml")
    }

    /// The stored mission, geofence and rally points
    /// ([`crate::mission::file::save_plans`]).
    #[must_use]
    pub fn plans_path(&self) -> PathBuf {
        self.state_dir.join("missions.json")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn px4_sitl_ports() {
        let c = Config::px4_sitl(0);
        assert_eq!(c.system_id(), 1);
        assert_eq!(c.links[0].bind.port(), 18570);
        assert_eq!(c.links[0].remote, Some("127.0.0.1:14550".parse().unwrap()));
        assert_eq!(c.links[1].bind.port(), 14580);
        assert_eq!(c.links[1].remote, Some("127.0.0.1:14540".parse().unwrap()));
        assert_eq!(c.state_dir, PathBuf::from("rotorpilot-state/0"));
        assert_eq!(c.params_path(), PathBuf::from("rotorpilot-state/0/params.toml"));
        assert_eq!(c.plans_path(), PathBuf::from("rotorpilot-state/0/missions.json"));
        let c = Config::px4_sitl(3);
        assert_eq!(c.system_id(), 4);
        assert_eq!(c.links[0].bind.port(), 18573);
        assert_eq!(c.links[0].remote.unwrap().port(), 14550);
        assert_eq!(c.links[1].bind.port(), 14583);
        assert_eq!(c.links[1].remote.unwrap().port(), 14543);
        // PX4's px4-rc.mavlink: instances above 9 all send to 14549
        assert_eq!(LinkSpec::px4_api(12).remote.unwrap().port(), 14549);
    }

    #[test]
    fn link_and_home_options() {
        let l = LinkSpec::parse("udpout:127.0.0.1:14600").unwrap();
        assert_eq!(l.remote, Some("127.0.0.1:14600".parse().unwrap()));
        assert_eq!(l.bind.port(), 0);
        let l = LinkSpec::parse("udpin:0.0.0.0:14601").unwrap();
        assert_eq!(l.remote, None);
        assert_eq!(l.bind, "0.0.0.0:14601".parse().unwrap());
        assert!(LinkSpec::parse("tcp:127.0.0.1:1").is_err());
        assert!(LinkSpec::parse("udpout:nohost").is_err());
        let h = parse_home("47.5, 8.6, 400").unwrap();
        assert_eq!((h.lat_deg, h.lon_deg, h.alt_amsl_m), (47.5, 8.6, 400.0));
        assert!(parse_home("47.5,8.6").is_err());
        assert!(parse_home("95,8.6,0").is_err());
    }
}
