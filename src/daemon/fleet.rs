//! A fleet's configuration (`--count N`, `--fleet FILE`): which vehicles one
//! process runs on one simulated clock. Each is exactly the [`Config`] a lone
//! daemon started with `--instance i` runs (system id i+1, PX4 SITL's ports
//! for instance i, the same airframe, speed and options), except its spawn
//! point (`home`) and its state directory (`ROOT/i`). Pure: no sockets.
//!
//! # The fleet file
//!
//! ```toml
//! home = [47.397742, 8.545594, 488.0]   # optional (else --home): LAT, LON, ALT of the fleet's origin, on the ground
//! proximity_m = 2.0                      # optional (else 2 m; --proximity overrides both)
//!
//! [[vehicle]]
//! instance = 0                           # PX4 SITL instance i: system id i+1, ports 18570+i and 14580+i
//! airframe = "octo"                      # optional (else --airframe); a relative path is read from the file's directory
//! offset_m = [0.0, 5.0]                  # optional: spawn NORTH, EAST of the origin [m]; else 3 m x instance north
//! params = { MPC_XY_CRUISE = 8.0 }       # optional: set at start, over the vehicle's stored parameter file
//! count = 4                              # optional: instances instance..instance+count-1
//! spacing_m = [3.0, 0.0]                 # optional: NORTH, EAST [m] between them (else 3 m north)
//! ```
//!
//! `count`, `offset_m` and `spacing_m` are read as a headless fleet's
//! ([`crate::scenario::placement`]: one set of rules), numbering the
//! vehicles by instance.
//!
//! Errors name the file, the line and column, the field (`vehicle[2].instance`,
//! entries counted from 1 as campaign paths count them) and the problem, as
//! [`crate::tomlfile`] reports every TOML file.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use serde::Deserialize;
use toml::{Spanned, Value};

use super::{Config, LinkSpec};
use crate::airframe::Airframe;
use crate::geo::GeoPoint;
use crate::params::{PARAMS, ParamStore, ParamType, ParamValue};
use crate::scenario::placement::Placement;
use crate::tomlfile::{self, FileError};

/// Default root of the vehicles' state directories (`ROOT/i`), as a lone
/// vehicle's default `rotorpilot-state/i`.
pub const DEFAULT_STATE_ROOT: &str = "rotorpilot-state";

/// Default distance [m] below which two vehicles' proximity is reported.
pub const DEFAULT_PROXIMITY_M: f64 = 2.0;

/// The highest instance: system ids (instance + 1) stop at 250 here (the
/// ids above are left to ground stations and companions).
pub const MAX_INSTANCE: u8 = 249;

/// The vehicles one process runs, all on one simulated clock, in one world
/// whose NED origin is `origin`.
#[derive(Clone, Debug)]
pub struct FleetConfig {
    /// Each vehicle as a lone daemon with `--instance i` would run it, except
    /// its `home` (its own spawn point, on the ground at `origin`'s altitude)
    /// and its state directory; ordered by instance, instances distinct.
    pub vehicles: Vec<Config>,
    /// The fleet's home: the world's NED origin; the ground is at its altitude.
    pub origin: GeoPoint,
    /// Two vehicles closer than this [m] (between centres) have their
    /// proximity reported.
    pub proximity_m: f64,
}

/// Where a fleet's vehicles send a link's datagrams before anyone talks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Remote {
    /// PX4 SITL's remote for the vehicle's instance ([`LinkSpec::px4_gcs`], [`LinkSpec::px4_api`]).
    Px4,
    /// This address, for every vehicle (`--gcs-remote HOST:PORT`).
    To(SocketAddr),
    /// Nowhere: serve whoever talks (`--gcs-remote none`).
    Nowhere,
}

impl Remote {
    fn apply(self, mut link: LinkSpec) -> LinkSpec {
        match self {
            Remote::Px4 => {}
            Remote::To(a) => link.remote = Some(a),
            Remote::Nowhere => link.remote = None,
        }
        link
    }
}

/// What the command line gives every vehicle of a fleet.
#[derive(Clone, Debug)]
pub struct FleetOptions {
    /// Every setting a vehicle shares (airframe unless the file names one,
    /// speed, reset flags, logs, timeouts); its instance, home, links, state
    /// directory and parameter overrides are set per vehicle.
    pub base: Config,
    /// The GCS link's remote for every vehicle (`--gcs-remote`).
    pub gcs_remote: Remote,
    /// The API link's remote for every vehicle (`--api-remote`).
    pub api_remote: Remote,
    /// Vehicle i keeps its parameters and plans in `state_root/i`.
    pub state_root: PathBuf,
    /// `--home`: the fleet's origin (over the file's `home`).
    pub home: Option<GeoPoint>,
    /// `--proximity`: over the file's `proximity_m`.
    pub proximity_m: Option<f64>,
}

impl FleetOptions {
    /// The vehicle of `instance`, spawned at NED `(north, east, 0)` [m] from `origin`.
    fn vehicle(&self, instance: u8, airframe: &str, origin: GeoPoint, north_east_m: [f64; 2]) -> Config {
        let mut c = self.base.clone();
        c.instance = instance;
        c.airframe = airframe.to_string();
        c.home = origin.offset(&Vector3::new(north_east_m[0], north_east_m[1], 0.0));
        c.links = vec![
            self.gcs_remote.apply(LinkSpec::px4_gcs(instance)),
            self.api_remote.apply(LinkSpec::px4_api(instance)),
        ];
        c.state_dir = self.state_root.join(instance.to_string());
        c.param_overrides = Vec::new();
        c
    }
}

/// Instances `first..=first+n-1` fit the system ids, or why not:
/// "instances 0..299 need system ids up to 300; the most is 250 (instances 0..249)".
fn check_ids(first: u64, n: u64) -> Result<(), String> {
    let last = first + n.max(1) - 1;
    if last <= u64::from(MAX_INSTANCE) {
        return Ok(());
    }
    let most = format!(
        "the most is {} (instances 0..{MAX_INSTANCE})",
        u16::from(MAX_INSTANCE) + 1
    );
    Err(if n > 1 {
        format!("instances {first}..{last} need system ids up to {}; {most}", last + 1)
    } else {
        format!("instance {first} needs system id {}; {most}", first + 1)
    })
}

impl FleetConfig {
    /// A lone vehicle: today's daemon exactly (its home is the origin).
    #[must_use]
    pub fn lone(c: Config) -> Self {
        Self {
            origin: c.home,
            vehicles: vec![c],
            proximity_m: DEFAULT_PROXIMITY_M,
        }
    }

    /// `--instance first --count n`: instances `first..first+n-1` with the
    /// options' airframe, in PX4's layout ([`Placement::px4`]: instance i
    /// spawned 3 m x i north of the origin, `--home`, else PX4's).
    ///
    /// # Errors
    /// `n` is 0, the instances pass [`MAX_INSTANCE`], the airframe does not load.
    pub fn counted(opts: &FleetOptions, first: u8, n: u32) -> anyhow::Result<Self> {
        anyhow::ensure!(n >= 1, "--count must be at least 1");
        check_ids(u64::from(first), u64::from(n)).map_err(|p| anyhow::anyhow!("--count {n}: {p}"))?;
        Airframe::load(&opts.base.airframe)?;
        let origin = opts.home.unwrap_or(GeoPoint::PX4_SITL_HOME);
        let place = Placement::px4(u64::from(first), n as usize);
        let vehicles = (0..n)
            .map(|k| {
                let i = first + u8::try_from(k).unwrap_or(MAX_INSTANCE);
                opts.vehicle(i, &opts.base.airframe, origin, place.spawn(k as usize))
            })
            .collect();
        Ok(Self {
            vehicles,
            origin,
            proximity_m: opts.proximity_m.unwrap_or(DEFAULT_PROXIMITY_M),
        })
    }

    /// Read a fleet file (format in the [module docs](self)).
    ///
    /// # Errors
    /// [`FileError`] naming the file, the field with its line, and the problem.
    pub fn from_file(path: &Path, opts: &FleetOptions) -> Result<Self, FileError> {
        let text = tomlfile::read(path)?;
        let dir = path.parent().unwrap_or(Path::new(""));
        Self::from_toml(&text, &path.display().to_string(), dir, opts)
    }

    /// Parse fleet TOML; `file` labels errors, relative airframe paths are
    /// read from `dir`.
    ///
    /// # Errors
    /// As [`Self::from_file`].
    pub fn from_toml(text: &str, file: &str, dir: &Path, opts: &FleetOptions) -> Result<Self, FileError> {
        let raw: RawFleet = tomlfile::parse(text, file)?;
        let mut r = Reader {
            text,
            file,
            dir,
            opts,
            taken: Vec::new(),
            airframes: HashMap::new(),
        };
        let origin = match (opts.home, raw.home) {
            (Some(h), _) => h,
            (None, None) => GeoPoint::PX4_SITL_HOME,
            (None, Some(h)) => r.home(&h)?,
        };
        let proximity_m = match (opts.proximity_m, raw.proximity_m) {
            (Some(d), _) => d,
            (None, None) => DEFAULT_PROXIMITY_M,
            (None, Some(d)) if d.get_ref().is_finite() && *d.get_ref() > 0.0 => *d.get_ref(),
            (None, Some(d)) => {
                return Err(r.at(
                    d.span().start,
                    format!("proximity_m: must be a finite distance > 0 m, got {}", d.get_ref()),
                ));
            }
        };
        let entries = match raw.vehicle {
            Some(v) if !v.get_ref().is_empty() => v.into_inner(),
            Some(v) => {
                return Err(r.at(
                    v.span().start,
                    "vehicle: no vehicles: a fleet needs at least one [[vehicle]]".into(),
                ));
            }
            None => {
                return Err(FileError::invalid(
                    file,
                    "vehicle",
                    "no [[vehicle]] entries: a fleet needs at least one vehicle",
                ));
            }
        };
        let mut vehicles = Vec::new();
        for (k, entry) in entries.into_iter().enumerate() {
            vehicles.extend(r.entry(k + 1, entry, origin)?);
        }
        vehicles.sort_by_key(|c| c.instance);
        Ok(Self {
            vehicles,
            origin,
            proximity_m,
        })
    }

    /// One line per vehicle (instance, system id, airframe, spawn north and
    /// east of the origin [m], each link's bind -> remote, state directory,
    /// parameters set at start), under a line on the fleet: what `--check`
    /// prints.
    #[must_use]
    pub fn to_text(&self) -> String {
        let o = &self.origin;
        let mut s = format!(
            "{} vehicle{} on one clock; origin {:.7}, {:.7}, {:.1} m AMSL; proximity {} m\n",
            self.vehicles.len(),
            if self.vehicles.len() == 1 { "" } else { "s" },
            o.lat_deg,
            o.lon_deg,
            o.alt_amsl_m,
            self.proximity_m
        );
        let _ = writeln!(
            s,
            "{:>8} {:>5}  {:<12} {:>9} {:>9}  links (bind -> remote)",
            "instance", "sysid", "airframe", "north_m", "east_m"
        );
        for c in &self.vehicles {
            let ned = c.home.ned_from(&self.origin);
            let links: Vec<String> = c
                .links
                .iter()
                .map(|l| {
                    let remote = l
                        .remote
                        .map_or_else(|| "(whoever talks)".to_string(), |r| r.to_string());
                    format!("{} {} -> {remote}", l.name, l.bind)
                })
                .collect();
            let _ = write!(
                s,
                "{:>8} {:>5}  {:<12} {:>9.2} {:>9.2}  {}  state {}",
                c.instance,
                c.system_id(),
                c.airframe,
                ned.x + 0.0,
                ned.y + 0.0,
                links.join(", "),
                c.state_dir.display()
            );
            if !c.param_overrides.is_empty() {
                let p: Vec<String> = c.param_overrides.iter().map(|(n, v)| format!("{n}={v}")).collect();
                let _ = write!(s, "  params {}", p.join(" "));
            }
            s.push('\n');
        }
        s
    }
}

/// A fleet file being read: its text for error positions, what was taken.
struct Reader<'a> {
    text: &'a str,
    file: &'a str,
    dir: &'a Path,
    opts: &'a FleetOptions,
    /// `(first, last, entry number, offset of its instance)` of each entry read.
    taken: Vec<(u8, u8, usize, usize)>,
    /// Each airframe loaded once: `Err` holds its message.
    airframes: HashMap<String, Result<(), String>>,
}

impl Reader<'_> {
    /// An error at byte `offset` (the line of the field).
    fn at(&self, offset: usize, message: String) -> FileError {
        tomlfile::error_at(self.text, self.file, offset, message)
    }

    /// The file's `home = [LAT, LON, ALT]`.
    fn home(&self, h: &Spanned<Vec<f64>>) -> Result<GeoPoint, FileError> {
        match h.get_ref()[..] {
            [lat_deg, lon_deg, alt_amsl_m] => Some(GeoPoint {
                lat_deg,
                lon_deg,
                alt_amsl_m,
            }),
            _ => None,
        }
        .filter(GeoPoint::is_valid)
        .ok_or_else(|| {
            self.at(
                h.span().start,
                format!(
                    "home: expected [LAT, LON, ALT] (degrees, degrees, metres AMSL), got {:?}",
                    h.get_ref()
                ),
            )
        })
    }

    /// The first instance of entry `k` (counted from 1): given and in range.
    fn first_instance(&self, k: usize, entry_at: usize, v: &RawVehicle) -> Result<u8, FileError> {
        let field = format!("vehicle[{k}].instance");
        let Some(instance) = &v.instance else {
            return Err(self.at(
                entry_at,
                format!("{field}: missing: which PX4 SITL instance (system id instance + 1)?"),
            ));
        };
        let at = instance.span().start;
        let first = *instance.get_ref();
        if first < 0 {
            return Err(self.at(at, format!("{field}: must be in 0..={MAX_INSTANCE}, got {first}")));
        }
        check_ids(first.unsigned_abs(), 1).map_err(|p| self.at(at, format!("{field}: {p}")))?;
        // in 0..=MAX_INSTANCE, checked above
        Ok(u8::try_from(first).unwrap_or(MAX_INSTANCE))
    }

    /// The last of the `n` instances of entry `k` from `first`: within the
    /// system ids and taken by no earlier entry, which it then takes.
    fn take_instances(&mut self, k: usize, first: u8, n: usize, v: &RawVehicle) -> Result<u8, FileError> {
        let field = |name: &str| format!("vehicle[{k}].{name}");
        if let Some(c) = &v.count {
            check_ids(u64::from(first), n as u64)
                .map_err(|p| self.at(c.span().start, format!("{}: {p}", field("count"))))?;
        }
        let at = v.instance.as_ref().map_or(0, |i| i.span().start);
        // within MAX_INSTANCE, checked above
        let last = u8::try_from(usize::from(first) + n - 1).unwrap_or(MAX_INSTANCE);
        if let Some(&(a, b, j, other_at)) = self.taken.iter().find(|(a, b, ..)| *a <= last && first <= *b) {
            let x = a.max(first);
            let mine = if n > 1 {
                format!("instances {first}..{last} include instance {x}, already")
            } else {
                format!("instance {x} is already")
            };
            let (line, _) = tomlfile::line_column(self.text, other_at);
            let theirs = if a == b {
                format!("line {line}")
            } else {
                format!("line {line}: instances {a}..{b}")
            };
            return Err(self.at(at, format!("{}: {mine} vehicle[{j}]'s ({theirs})", field("instance"))));
        }
        self.taken.push((first, last, k, at));
        Ok(last)
    }

    /// The airframe of entry `k`, loaded (once per name) to check it.
    fn airframe(&mut self, k: usize, entry_at: usize, v: &RawVehicle) -> Result<String, FileError> {
        let (name, at, field) = match &v.airframe {
            Some(a) => (
                airframe_path(a.get_ref(), self.dir),
                a.span().start,
                format!("vehicle[{k}].airframe"),
            ),
            None => (
                self.opts.base.airframe.clone(),
                entry_at,
                format!("vehicle[{k}].airframe: not given, and --airframe does not load"),
            ),
        };
        let loaded = self
            .airframes
            .entry(name.clone())
            .or_insert_with(|| Airframe::load(&name).map(|_| ()).map_err(|e| e.to_string()));
        match loaded {
            Ok(()) => Ok(name),
            Err(e) => {
                let message = format!("{field}: {e}");
                Err(self.at(at, message))
            }
        }
    }

    /// The vehicles of entry `k` (counted from 1), placed by
    /// [`Placement`] (numbered by instance).
    fn entry(&mut self, k: usize, entry: Spanned<RawVehicle>, origin: GeoPoint) -> Result<Vec<Config>, FileError> {
        let entry_at = entry.span().start;
        let v = entry.into_inner();
        let first = self.first_instance(k, entry_at, &v)?;
        let place = Placement::read(
            k,
            u64::from(first),
            v.count.as_ref(),
            v.offset_m.as_ref(),
            v.spacing_m.as_ref(),
        )
        .map_err(|(o, m)| self.at(o, m))?;
        let last = self.take_instances(k, first, place.count(), &v)?;
        let airframe = self.airframe(k, entry_at, &v)?;
        let params = param_overrides(v.params, &format!("vehicle[{k}].params")).map_err(|(o, m)| self.at(o, m))?;
        Ok((first..=last)
            .enumerate()
            .map(|(n, i)| {
                let mut c = self.opts.vehicle(i, &airframe, origin, place.spawn(n));
                c.param_overrides.clone_from(&params);
                c
            })
            .collect())
    }
}

/// An airframe path relative to the fleet file's directory; a built-in name
/// or an absolute path as given (a path is what [`Airframe::load`] takes for
/// one: it contains `/` or ends in `.toml`).
fn airframe_path(name: &str, dir: &Path) -> String {
    let is_path = name.contains('/') || name.ends_with(".toml");
    if is_path && Path::new(name).is_relative() && !dir.as_os_str().is_empty() {
        dir.join(name).display().to_string()
    } else {
        name.to_string()
    }
}

/// A vehicle's `params` table as `(name, value)` in the file's order, each
/// checked as the parameter store checks a PARAM_SET (known name, its type,
/// finite, in range); `Err((offset, message))` otherwise.
fn param_overrides(
    params: Option<std::collections::BTreeMap<Spanned<String>, Spanned<Value>>>,
    field: &str,
) -> Result<Vec<(String, f64)>, (usize, String)> {
    let mut list: Vec<_> = params.unwrap_or_default().into_iter().collect();
    list.sort_by_key(|(k, _)| k.span().start);
    list.into_iter()
        .map(|(name, value)| {
            let at = name.span().start;
            let name = name.into_inner();
            let fail = |p: String| (at, format!("{field}.{name}: {p}"));
            let spec = PARAMS
                .iter()
                .find(|s| s.name == name)
                .ok_or_else(|| fail(format!("unknown parameter{}", crate::params::did_you_mean(&name))))?;
            if name == "MAV_SYS_ID" {
                return Err(fail(
                    "set by the instance (system id = instance + 1), as PX4 SITL does".into(),
                ));
            }
            let v = match (spec.kind, value.get_ref()) {
                (ParamType::Int32, Value::Integer(i)) => {
                    ParamValue::Int32(i32::try_from(*i).map_err(|_| fail(format!("{i} does not fit an INT32")))?)
                }
                (ParamType::Real32, Value::Integer(i)) => ParamValue::Real32(*i as f32),
                (ParamType::Real32, Value::Float(x)) => ParamValue::Real32(*x as f32),
                (kind, other) => {
                    return Err(fail(format!(
                        "is {kind}: give {}, got {other}",
                        if kind == ParamType::Int32 {
                            "an integer"
                        } else {
                            "a number"
                        }
                    )));
                }
            };
            ParamStore::check(spec, v).map_err(|e| fail(e.to_string()))?;
            Ok((name.clone(), v.as_f64()))
        })
        .collect()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFleet {
    home: Option<Spanned<Vec<f64>>>,
    proximity_m: Option<Spanned<f64>>,
    vehicle: Option<Spanned<Vec<Spanned<RawVehicle>>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawVehicle {
    instance: Option<Spanned<i64>>,
    airframe: Option<Spanned<String>>,
    offset_m: Option<Spanned<Vec<f64>>>,
    params: Option<std::collections::BTreeMap<Spanned<String>, Spanned<Value>>>,
    count: Option<Spanned<i64>>,
    spacing_m: Option<Spanned<Vec<f64>>>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The options of a bare command line (`rotorpilot --fleet F`).
    fn opts() -> FleetOptions {
        FleetOptions {
            base: Config::px4_sitl(0),
            gcs_remote: Remote::Px4,
            api_remote: Remote::Px4,
            state_root: PathBuf::from(DEFAULT_STATE_ROOT),
            home: None,
            proximity_m: None,
        }
    }

    fn fixture(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures/fleets")
            .join(name)
    }

    /// The fixture's path as errors print it, and its error.
    fn fixture_error(name: &str) -> (String, String) {
        let path = fixture(name);
        let e = FleetConfig::from_file(&path, &opts()).unwrap_err();
        (path.display().to_string(), e.to_string())
    }

    /// The error of fleet TOML `text` (labelled `f.toml`), as printed.
    fn error(text: &str) -> String {
        FleetConfig::from_toml(text, "f.toml", Path::new(""), &opts())
            .map(|f| format!("accepted: {} vehicles", f.vehicles.len()))
            .unwrap_or_else(|e| e.to_string())
    }

    /// NED [m] of a vehicle's spawn point from the fleet's origin.
    fn spawn(f: &FleetConfig, i: usize) -> Vector3<f64> {
        f.vehicles[i].home.ned_from(&f.origin)
    }

    #[test]
    fn a_file_with_two_groups_gives_each_vehicle_its_instance_ports_home_and_state() {
        let f = FleetConfig::from_file(&fixture("two-groups.toml"), &opts()).unwrap();
        let instances: Vec<u8> = f.vehicles.iter().map(|c| c.instance).collect();
        assert_eq!(instances, [0, 1, 2, 3, 10, 11]);
        let ids: Vec<u8> = f.vehicles.iter().map(Config::system_id).collect();
        assert_eq!(ids, [1, 2, 3, 4, 11, 12]);
        assert_eq!(f.proximity_m, 1.5);
        assert_eq!(
            f.origin,
            GeoPoint {
                lat_deg: 47.397_742,
                lon_deg: 8.545_594,
                alt_amsl_m: 500.0
            }
        );
        let port = |c: &Config, l: usize| (c.links[l].bind.port(), c.links[l].remote.map(|r| r.port()));
        for (c, i) in f.vehicles.iter().zip(instances) {
            let i16 = u16::from(i);
            assert_eq!(c.links.len(), 2, "{i}");
            assert_eq!(port(c, 0), (18570 + i16, Some(14550)), "{i}");
            // PX4's px4-rc.mavlink: beyond instance 9 every API link sends to 14549
            let api_remote = if i > 9 { 14549 } else { 14540 + i16 };
            assert_eq!(port(c, 1), (14580 + i16, Some(api_remote)), "{i}");
            assert_eq!(c.state_dir, PathBuf::from(format!("rotorpilot-state/{i}")));
            // the same ground everywhere
            assert!((c.home.alt_amsl_m - 500.0).abs() < 1e-9, "{i}");
        }
        assert_eq!(f.vehicles[4].links[1].remote, Some("127.0.0.1:14549".parse().unwrap()));
        // 3 m x instance north, or the group's offset and 3 m north per vehicle
        let expected = [[0.0, 0.0], [3.0, 0.0], [6.0, 0.0], [9.0, 0.0], [-6.0, 5.0], [-3.0, 5.0]];
        for (i, [n, e]) in expected.into_iter().enumerate() {
            assert!(
                (spawn(&f, i) - Vector3::new(n, e, 0.0)).norm() < 1e-6,
                "{i}: {}",
                spawn(&f, i)
            );
        }
        let airframes: Vec<&str> = f.vehicles.iter().map(|c| c.airframe.as_str()).collect();
        assert_eq!(airframes, ["quad", "quad", "quad", "quad", "octo", "octo"]);
        let set = vec![("MPC_XY_CRUISE".to_string(), 8.0), ("CTRL_TYPE".to_string(), 2.0)];
        assert!(f.vehicles[..4].iter().all(|c| c.param_overrides.is_empty()));
        assert_eq!(f.vehicles[4].param_overrides, set);
        assert_eq!(f.vehicles[5].param_overrides, set);
    }

    #[test]
    fn a_duplicate_instance_names_the_entry_that_has_it() {
        let (file, e) = fixture_error("duplicate-instance.toml");
        assert_eq!(
            e,
            format!("{file}:10:12: vehicle[3].instance: instance 3 is already vehicle[1]'s (line 2: instances 0..3)")
        );
        assert_eq!(
            error("[[vehicle]]\ninstance = 4\n[[vehicle]]\ninstance = 2\ncount = 5\n"),
            "f.toml:4:12: vehicle[2].instance: instances 2..6 include instance 4, already vehicle[1]'s (line 2)"
        );
    }

    #[test]
    fn an_unknown_airframe_is_reported_once_at_its_line() {
        let (file, e) = fixture_error("unknown-airframe.toml");
        assert_eq!(
            e,
            format!(
                "{file}:6:12: vehicle[2].airframe: unknown airframe `octa`: not a file and not a built-in \
                 airframe (quad, hexa, octo, fsr-quad, hexa-ppnnpn)"
            )
        );
        // --airframe for the entries that name none
        let o = FleetOptions {
            base: Config {
                airframe: "nope".into(),
                ..Config::px4_sitl(0)
            },
            ..opts()
        };
        let e = FleetConfig::from_toml("\n[[vehicle]]\ninstance = 1\n", "f.toml", Path::new(""), &o).unwrap_err();
        assert_eq!(
            e.to_string(),
            "f.toml:2:1: vehicle[1].airframe: not given, and --airframe does not load: unknown airframe `nope`: \
             not a file and not a built-in airframe (quad, hexa, octo, fsr-quad, hexa-ppnnpn)"
        );
    }

    #[test]
    fn more_vehicles_than_system_ids_are_refused() {
        let (file, e) = fixture_error("too-many.toml");
        assert_eq!(
            e,
            format!(
                "{file}:7:9: vehicle[2].count: instances 200..259 need system ids up to 260; \
                 the most is 250 (instances 0..249)"
            )
        );
        assert_eq!(
            error("[[vehicle]]\ninstance = 250\n"),
            "f.toml:2:12: vehicle[1].instance: instance 250 needs system id 251; the most is 250 (instances 0..249)"
        );
        // the last one that fits
        assert_eq!(
            error("[[vehicle]]\ninstance = 240\ncount = 10\n"),
            "accepted: 10 vehicles"
        );
        let e = FleetConfig::counted(&opts(), 0, 300).unwrap_err().to_string();
        assert_eq!(
            e,
            "--count 300: instances 0..299 need system ids up to 300; the most is 250 (instances 0..249)"
        );
        let e = FleetConfig::counted(&opts(), 200, 51).unwrap_err().to_string();
        assert_eq!(
            e,
            "--count 51: instances 200..250 need system ids up to 251; the most is 250 (instances 0..249)"
        );
        assert_eq!(FleetConfig::counted(&opts(), 200, 50).unwrap().vehicles.len(), 50);
    }

    #[test]
    fn other_mistakes_name_the_field_and_the_line() {
        let cases = [
            (
                "[[vehicle]]\ninstance = 0\nnorth = 3\n",
                "f.toml:3:1: unknown field `north`",
            ),
            ("homes = [1, 2, 3]\n", "f.toml:1:1: unknown field `homes`"),
            (
                "proximity_m = 1\n",
                "f.toml: vehicle: no [[vehicle]] entries: a fleet needs at least one vehicle",
            ),
            (
                "vehicle = []\n",
                "f.toml:1:11: vehicle: no vehicles: a fleet needs at least one [[vehicle]]",
            ),
            (
                "[[vehicle]]\nairframe = \"quad\"\n",
                "f.toml:1:1: vehicle[1].instance: missing: which PX4 SITL instance (system id instance + 1)?",
            ),
            (
                "[[vehicle]]\ninstance = -1\n",
                "f.toml:2:12: vehicle[1].instance: must be in 0..=249, got -1",
            ),
            (
                "[[vehicle]]\ninstance = 0\ncount = 0\n",
                "f.toml:3:9: vehicle[1].count: must be 1 to 100000, got 0",
            ),
            (
                "[[vehicle]]\ninstance = 0\noffset_m = [nan, 1.0]\n",
                "f.toml:3:12: vehicle[1].offset_m: expected [NORTH, EAST] in metres, two finite numbers, got [NaN, 1.0]",
            ),
            (
                "[[vehicle]]\ninstance = 0\noffset_m = [1.0, inf]\n",
                "f.toml:3:12: vehicle[1].offset_m: expected [NORTH, EAST] in metres, two finite numbers, got [1.0, inf]",
            ),
            (
                "[[vehicle]]\ninstance = 0\noffset_m = [1.0]\n",
                "f.toml:3:12: vehicle[1].offset_m: expected [NORTH, EAST] in metres, two finite numbers, got [1.0]",
            ),
            (
                "home = [95.0, 8.0, 400.0]\n[[vehicle]]\ninstance = 0\n",
                "f.toml:1:8: home: expected [LAT, LON, ALT] (degrees, degrees, metres AMSL), got [95.0, 8.0, 400.0]",
            ),
            (
                "proximity_m = 0.0\n[[vehicle]]\ninstance = 0\n",
                "f.toml:1:15: proximity_m: must be a finite distance > 0 m, got 0",
            ),
            (
                "[[vehicle]]\ninstance = 0\nparams = { MPC_XY_CRUSE = 8.0 }\n",
                "f.toml:3:12: vehicle[1].params.MPC_XY_CRUSE: unknown parameter (did you mean MPC_XY_CRUISE?)",
            ),
            (
                "[[vehicle]]\ninstance = 0\nparams = { CTRL_TYPE = 1.5 }\n",
                "f.toml:3:12: vehicle[1].params.CTRL_TYPE: is INT32: give an integer, got 1.5",
            ),
            (
                "[[vehicle]]\ninstance = 0\nparams = { MPC_XY_CRUISE = 1e6 }\n",
                "f.toml:3:12: vehicle[1].params.MPC_XY_CRUISE: MPC_XY_CRUISE = 1000000 is outside [0.5, 20] m/s",
            ),
            (
                "[[vehicle]]\ninstance = 0\n[vehicle.params]\nMAV_SYS_ID = 7\n",
                "f.toml:4:1: vehicle[1].params.MAV_SYS_ID: set by the instance (system id = instance + 1), as PX4 SITL does",
            ),
        ];
        for (text, want) in cases {
            let got = error(text);
            assert!(got.starts_with(want), "{text}\n got: {got}\nwant: {want}");
        }
    }

    #[test]
    fn vehicles_spawned_on_top_of_each_other_are_not_an_error() {
        let text =
            "[[vehicle]]\ninstance = 0\noffset_m = [1.0, 1.0]\n[[vehicle]]\ninstance = 1\noffset_m = [1.0, 1.0]\n";
        let f = FleetConfig::from_toml(text, "f.toml", Path::new(""), &opts()).unwrap();
        assert_eq!(f.vehicles[0].home, f.vehicles[1].home);
    }

    #[test]
    fn the_command_line_overrides_home_and_proximity_and_applies_to_every_vehicle() {
        let home = GeoPoint {
            lat_deg: 10.0,
            lon_deg: 20.0,
            alt_amsl_m: 30.0,
        };
        let o = FleetOptions {
            home: Some(home),
            proximity_m: Some(4.0),
            api_remote: Remote::To("127.0.0.1:9000".parse().unwrap()),
            gcs_remote: Remote::Nowhere,
            state_root: PathBuf::from("/tmp/fleet"),
            base: Config {
                speed: 5.0,
                reset_params: true,
                log_dir: Some(PathBuf::from("logs")),
                ..Config::px4_sitl(0)
            },
        };
        let f = FleetConfig::from_file(&fixture("two-groups.toml"), &o).unwrap();
        assert_eq!((f.origin, f.proximity_m), (home, 4.0));
        for c in &f.vehicles {
            assert_eq!(c.links[0].remote, None);
            assert_eq!(c.links[1].remote, Some("127.0.0.1:9000".parse().unwrap()));
            assert_eq!(c.state_dir, Path::new("/tmp/fleet").join(c.instance.to_string()));
            assert_eq!((c.speed, c.reset_params), (5.0, true));
            assert_eq!(c.log_dir.as_deref(), Some(Path::new("logs")));
            assert!((c.home.alt_amsl_m - 30.0).abs() < 1e-9);
        }
        assert!((spawn(&f, 3) - Vector3::new(9.0, 0.0, 0.0)).norm() < 1e-6);
    }

    #[test]
    fn counted_fleets_spawn_by_absolute_instance() {
        let f = FleetConfig::counted(&opts(), 5, 3).unwrap();
        assert_eq!(f.origin, GeoPoint::PX4_SITL_HOME);
        assert_eq!(f.proximity_m, DEFAULT_PROXIMITY_M);
        for (k, c) in f.vehicles.iter().enumerate() {
            let i = 5 + u8::try_from(k).unwrap();
            assert_eq!(c.instance, i);
            assert_eq!(c.links[0].bind.port(), 18570 + u16::from(i));
            assert_eq!(c.state_dir, PathBuf::from(format!("rotorpilot-state/{i}")));
            assert!((spawn(&f, k) - Vector3::new(3.0 * f64::from(i), 0.0, 0.0)).norm() < 1e-6);
        }
        // a second process continues the first one's layout
        let all = FleetConfig::counted(&opts(), 0, 200).unwrap();
        let second = FleetConfig::counted(&opts(), 100, 100).unwrap();
        assert_eq!(all.vehicles[100].home, second.vehicles[0].home);
        assert_eq!(all.vehicles[199].links, second.vehicles[99].links);
        // --count 1: a fleet of one, spawned by its instance
        let one = FleetConfig::counted(&opts(), 4, 1).unwrap();
        assert_eq!(one.vehicles.len(), 1);
        assert!((spawn(&one, 0) - Vector3::new(12.0, 0.0, 0.0)).norm() < 1e-6);
        // the airframe is checked before any vehicle starts
        let o = FleetOptions {
            base: Config {
                airframe: "nope".into(),
                ..Config::px4_sitl(0)
            },
            ..opts()
        };
        let e = FleetConfig::counted(&o, 0, 2).unwrap_err().to_string();
        assert!(e.starts_with("unknown airframe `nope`"), "{e}");
    }

    #[test]
    fn a_lone_vehicle_is_its_own_origin() {
        let mut c = Config::px4_sitl(7);
        c.home = GeoPoint {
            lat_deg: 1.0,
            lon_deg: 2.0,
            alt_amsl_m: 3.0,
        };
        let f = FleetConfig::lone(c.clone());
        assert_eq!(f.origin, c.home);
        assert_eq!(f.vehicles.len(), 1);
        assert_eq!(f.vehicles[0].links, c.links);
        assert_eq!(f.vehicles[0].state_dir, c.state_dir);
    }

    #[test]
    fn relative_airframe_paths_are_read_from_the_files_directory() {
        let dir = std::env::temp_dir().join(format!("rotorpilot-fleet-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("frames")).unwrap();
        let (quad, _) = Airframe::load_text("quad").unwrap();
        std::fs::write(dir.join("frames/my-quad.toml"), quad).unwrap();
        let fleet = dir.join("fleet.toml");
        std::fs::write(
            &fleet,
            "[[vehicle]]\ninstance = 0\nairframe = \"frames/my-quad.toml\"\n",
        )
        .unwrap();
        let f = FleetConfig::from_file(&fleet, &opts());
        let _ = std::fs::remove_dir_all(&dir);
        let f = f.unwrap();
        assert_eq!(
            f.vehicles[0].airframe,
            dir.join("frames/my-quad.toml").display().to_string()
        );
        // a built-in name stays a name
        assert_eq!(airframe_path("octo", &dir), "octo");
        assert_eq!(airframe_path("/abs/a.toml", &dir), "/abs/a.toml");
    }

    #[test]
    fn the_check_listing_shows_each_vehicle() {
        let f = FleetConfig::from_file(&fixture("two-groups.toml"), &opts()).unwrap();
        let text = f.to_text();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 2 + 6, "{text}");
        assert!(
            lines[0]
                .starts_with("6 vehicles on one clock; origin 47.3977420, 8.5455940, 500.0 m AMSL; proximity 1.5 m")
        );
        let v10: Vec<&str> = lines[6].split_whitespace().collect();
        assert_eq!(&v10[..5], ["10", "11", "octo", "-6.00", "5.00"], "{}", lines[6]);
        assert!(lines[6].contains("GCS 0.0.0.0:18580 -> 127.0.0.1:14550, API 0.0.0.0:14590 -> 127.0.0.1:14549"));
        assert!(lines[6].ends_with("state rotorpilot-state/10  params MPC_XY_CRUISE=8 CTRL_TYPE=2"));
    }
}
