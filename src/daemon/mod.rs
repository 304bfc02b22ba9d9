//! The tokio runtime of the simulated vehicles: it owns the UDP sockets and
//! the lockstep core, paces simulated time against the wall clock, and shuts
//! down cleanly (shaped like mini-redis: [`bind`] takes a [`Config`] whose
//! addresses may use port 0, [`Daemon::run`] takes the stop trigger).
//!
//! **A fleet on one clock** ([`bind_fleet`], `rotorpilot --count N` or
//! `--fleet FILE`): every vehicle of a [`FleetConfig`] lives in one world
//! and one lockstep core, stepped by the one simulation thread, and is on
//! the wire exactly what a lone daemon with its `--instance` would be: its
//! own links (PX4's ports for its instance), system id, parameters, state
//! directory, plans, logs and flight record. Each vehicle's channels to the
//! simulation thread are its own (the [`inbox`]: one bounded queue per
//! vehicle, served round robin), so a client flooding one vehicle fills that
//! vehicle's queue only. A lone vehicle is a fleet of one.
//!
//! | file | job |
//! |---|---|
//! | `config` | [`Config`], [`LinkSpec`]: the instance and PX4 SITL's port rules, home, speed, state directory |
//! | `fleet` | [`FleetConfig`]: the vehicles of `--count N` and `--fleet FILE`, their spawn points, the fleet file and its errors |
//! | `sim_thread` | the simulation thread: the only owner of the core, paced against wall time; every input is applied (and recorded) there, between steps; reboot and shutdown are carried out there |
//! | `messages` | what the links and the simulation thread say to each other (`SimRequest`, `Event`), a request's answer and its claim, the parameter store's lock |
//! | `inbox` | the requests of each vehicle's links to the simulation thread: a bounded queue per vehicle, served round robin |
//! | `link_task` | one task per UDP link: datagrams in, streams and answers out |
//! | `logs` | the run's log directory below `--log-dir` |
//! | `ready` | the one-time `rotorpilot: ready to arm` line on stdout |
//! | `tlog`, `ulog_file` | each link's `.tlog` and the vehicle's `flight.ulg` in the run's log directory |
//! | `recorder` | the run's flight record (`flight.record`, for `rotorpilot replay`) and `--log-csv` CSV (`flight.csv`) |
//! | `saver` | the parameter file and the stored plans, written after each accepted change |
//! | `signing` | the MAVLink signing key (`signing.key`, 0600) of each vehicle: read at bind, stored on SETUP_SIGNING, every 10 s and at shutdown |
//!
//! The state directory (`--state-dir`) holds `params.toml` and
//! `missions.json` (the mission, geofence and rally points, kept across
//! restarts as PX4's dataman keeps them). Both are read at start, before the
//! simulation thread runs; a plans file that does not read stops the start
//! with an error naming the file and the field (`--reset-plans` discards it).
//!
//! Parameters live in a `std::sync::Mutex<ParamStore>`: links read it to
//! answer requests, the simulation thread sets them (the core's parameter
//! transaction applies the change or undoes it). The lock is never held
//! across an `.await`.
//!
//! MAV_CMD_INJECT_FAILURE MAVLINK_SIGNAL OFF silences the vehicle's radio:
//! the simulation thread publishes the world's `link_lost` on a `watch`, and
//! every link task sends nothing while it is set (the command's own ACK
//! excepted) but still receives, so that the OK that undoes it arrives.
//!
//! PREFLIGHT_REBOOT_SHUTDOWN: reboot (p1 = 1) restarts the vehicle from the
//! current parameters, on the ground at the configured home, disarmed; the
//! simulated clock keeps counting, so `time_boot_ms` stays monotonic for the
//! clients already connected. Shutdown (p1 = 2) stops the daemon, as PX4 SITL
//! exits. Both are refused while armed (the autopilot decides); both are
//! carried out by the simulation thread (`Sim::power`), reboot before the
//! ACK, shutdown after it.

mod config;
mod files;
mod fleet;
mod inbox;
mod link_task;
mod lock;
mod logs;
mod messages;
mod ready;
mod recorder;
mod saver;
mod signing;
mod sim_thread;
mod supervise;
mod tlog;
mod ulog_file;

pub use config::{Config, LinkSpec, parse_home, resolve};
pub use fleet::{DEFAULT_PROXIMITY_M, DEFAULT_STATE_ROOT, FleetConfig, FleetOptions, MAX_INSTANCE, Remote};

use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::Context as _;
use tokio::net::UdpSocket;
use tokio::sync::{Notify, broadcast, mpsc, oneshot, watch};
use tokio::task::JoinHandle;
use tokio::time::Instant;
use tracing::{info, warn};

use crate::airframe::Airframe;
use crate::autopilot::{Autopilot, ClientClock};
use crate::geo::GeoPoint;
use crate::link::streams::Identity;
use crate::link::{Link, LinkConfig};
use crate::lockstep::{FleetVehicle, Lockstep};
use crate::mission::file::load_plans;
use crate::mission::{MissionType, Plans};
use crate::params::{ParamStore, ParamValue};
use crate::sim::SensorConfig;
use link_task::LinkTask;
use messages::{Event, SimRequest};
use saver::{ParamsFile, PlansFile, plan_saver, saver};
use sim_thread::{Sim, VehicleIo};

/// Fleets this large are stepped on every core ([`Lockstep::set_threads`]).
const PARALLEL_FLEET: usize = 64;

/// One vehicle of a bound daemon.
struct Vehicle {
    config: Config,
    params: ParamStore,
    warnings: Vec<String>,
    sockets: Vec<(LinkSpec, UdpSocket)>,
    /// This run's log directory (`--log-dir`), created at bind.
    log_dir: Option<PathBuf>,
    /// The flight record (and CSV) in the log directory, started at bind.
    recorder: Option<recorder::Recorder>,
    /// The MAVLink signing key (`signing.key` in the state directory), read at bind.
    signing: signing::VehicleSigning,
    /// The state directory's lock, held for the daemon's life.
    state_lock: lock::StateLock,
}

/// A daemon with its sockets bound, ready to [`Daemon::run`].
pub struct Daemon {
    origin: GeoPoint,
    proximity_m: f64,
    vehicles: Vec<Vehicle>,
    core: Lockstep<Autopilot>,
}

impl std::fmt::Debug for Daemon {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Daemon")
            .field("vehicles", &self.vehicles.len())
            .field("addrs", &self.local_addrs())
            .finish_non_exhaustive()
    }
}

/// A vehicle's parameters: its file (or the defaults), MAV_SYS_ID = instance
/// + 1 as PX4 SITL's rcS sets it, then the fleet file's overrides.
fn vehicle_params(config: &Config, airframe: &Airframe) -> anyhow::Result<(ParamStore, Vec<String>)> {
    let path = config.params_path();
    let (mut params, warnings) = if config.reset_params {
        (ParamStore::new(airframe), Vec::new())
    } else {
        // a damaged file is renamed aside, not overwritten (saver::keep_bad_params)
        saver::load_params(airframe, &path)?
    };
    let _ = params.set("MAV_SYS_ID", ParamValue::Int32(i32::from(config.system_id())));
    for (name, value) in &config.param_overrides {
        // checked when the fleet file was read (its type and range)
        let v = match params.get(name).map(|(_, v)| v) {
            Some(ParamValue::Int32(_)) => ParamValue::Int32(*value as i32),
            _ => ParamValue::Real32(*value as f32),
        };
        params
            .set(name, v)
            .map_err(|e| anyhow::anyhow!("parameter {name} = {value}: {e}"))?;
    }
    Ok((params, warnings))
}

/// Everything a start checks before it touches a state directory or a
/// socket (`rotorpilot --check` runs this, so that it refuses what a real
/// start refuses): at least one vehicle, the speed factor, distinct
/// instances below 250, airframes that load, and each vehicle's autopilot
/// built from default parameters with the fleet file's overrides. The saved
/// parameter and plan files and the sockets are left to the start itself.
///
/// # Errors
/// The first problem, naming its vehicle when the fleet has more than one.
pub fn check_fleet(fleet: &FleetConfig) -> anyhow::Result<()> {
    let configs = &fleet.vehicles;
    anyhow::ensure!(!configs.is_empty(), "a fleet needs at least one vehicle");
    let lone = configs.len() == 1;
    let speed = configs[0].speed;
    anyhow::ensure!(
        speed.is_finite() && speed > 0.0 && speed <= 1000.0,
        "--speed must be in (0, 1000], got {speed}"
    );
    let which = |c: &Config| vehicle_prefix(lone, c.instance);
    // two vehicles on one instance would share ports, system id and state
    let mut instances: Vec<u8> = configs.iter().map(|c| c.instance).collect();
    instances.sort_unstable();
    if let Some(w) = instances.windows(2).find(|w| w[0] == w[1]) {
        anyhow::bail!("two vehicles of the fleet are instance {}", w[0]);
    }
    let mut airframes = Vec::with_capacity(configs.len());
    let mut stores = Vec::with_capacity(configs.len());
    for c in configs {
        anyhow::ensure!(c.instance < 250, "{}--instance must be below 250", which(c));
        let airframe = Airframe::load(&c.airframe).map_err(|e| anyhow::anyhow!("{}{e}", which(c)))?;
        // default parameters (no file read): what a fresh state directory starts from
        let fresh = Config {
            reset_params: true,
            ..c.clone()
        };
        let (params, _) = vehicle_params(&fresh, &airframe)
            .map_err(|e| anyhow::anyhow!("{}{}", which(c), crate::error::error_chain(&e)))?;
        airframes.push(airframe);
        stores.push(params);
    }
    let list: Vec<FleetVehicle<'_>> = configs
        .iter()
        .zip(&airframes)
        .zip(&stores)
        .map(|((c, airframe), params)| FleetVehicle {
            airframe,
            home: c.home,
            params,
            sensors: SensorConfig::default(),
        })
        .collect();
    Lockstep::fleet(fleet.origin, &list).map_err(|(i, e)| {
        anyhow::anyhow!(
            "{}starting the autopilot on {}: {e}",
            which(&configs[i]),
            airframes[i].source
        )
    })?;
    Ok(())
}

/// Load the airframe, parameters and stored plans and bind every link's
/// socket of one lone vehicle ([`bind_fleet`] of a fleet of one).
///
/// # Errors
/// Unknown airframe, unreadable parameter file, a plans file that does not
/// read or holds a plan the vehicle refuses, bad speed, a socket that cannot
/// be bound (port in use: try another `--instance`).
pub async fn bind(config: Config) -> anyhow::Result<Daemon> {
    bind_fleet(FleetConfig::lone(config)).await
}

/// [`bind`] every vehicle of `fleet` into one world on one clock.
///
/// # Errors
/// As [`bind`], for any vehicle (the message names its instance when the
/// fleet has more than one); no vehicle at all.
pub async fn bind_fleet(fleet: FleetConfig) -> anyhow::Result<Daemon> {
    check_fleet(&fleet)?;
    let FleetConfig {
        vehicles: configs,
        origin,
        proximity_m,
    } = fleet;
    let lone = configs.len() == 1;
    let speed = configs[0].speed;
    let which = |c: &Config| vehicle_prefix(lone, c.instance);
    let mut airframes = Vec::with_capacity(configs.len());
    let mut stores = Vec::with_capacity(configs.len());
    let mut locks = Vec::with_capacity(configs.len());
    for c in &configs {
        let airframe = Airframe::load(&c.airframe).map_err(|e| anyhow::anyhow!("{}{e}", which(c)))?;
        // one daemon per state directory, before its files are read (lock.rs)
        locks.push(
            lock::StateLock::take(&c.state_dir)
                .map_err(|e| anyhow::anyhow!("{}{}", which(c), crate::error::error_chain(&e)))?,
        );
        let (params, warnings) = vehicle_params(c, &airframe)
            .map_err(|e| anyhow::anyhow!("{}{}", which(c), crate::error::error_chain(&e)))?;
        airframes.push(airframe);
        stores.push((params, warnings));
    }
    let sensors = SensorConfig::default();
    let list: Vec<FleetVehicle<'_>> = configs
        .iter()
        .zip(&airframes)
        .zip(&stores)
        .map(|((c, airframe), (params, _))| FleetVehicle {
            airframe,
            home: c.home,
            params,
            sensors,
        })
        .collect();
    let mut core = Lockstep::fleet(origin, &list).map_err(|(i, e)| {
        anyhow::anyhow!(
            "{}starting the autopilot on {}: {e}",
            which(&configs[i]),
            airframes[i].source
        )
    })?;
    drop(list);
    if !lone {
        core.watch_proximity(proximity_m);
        core.set_labels(configs.iter().map(|c| format!("system {}", c.system_id())).collect());
    }
    if configs.len() >= PARALLEL_FLEET {
        let threads = std::thread::available_parallelism().map_or(1, std::num::NonZero::get);
        core.set_threads(threads)
            .map_err(|e| anyhow::anyhow!("cannot start the stepping threads: {e}"))?;
    }
    let mut vehicles = Vec::with_capacity(configs.len());
    for (i, ((config, (params, warnings)), state_lock)) in configs.into_iter().zip(stores).zip(locks).enumerate() {
        if speed > 1.0 {
            // faster than real time: timers that wait for a client run on the wall clock
            core.pilot_mut(i).set_client_clock(ClientClock::Wall);
        }
        let plans = if config.reset_plans {
            Plans::default()
        } else {
            load_plans(&config.plans_path())
                .context(
                    "cannot restore the stored mission, geofence and rally points \
                     (mend or remove the file, or start with --reset-plans to discard them)",
                )
                .map_err(|e| anyhow::anyhow!("{}{}", which(&config), crate::error::error_chain(&e)))?
        };
        core.pilot_mut(i).restore_plans(plans);
        let vehicle_signing =
            signing::load(&config.state_dir).map_err(|e| anyhow::anyhow!("{}{e:#}", which(&config)))?;
        let mut sockets = Vec::new();
        for spec in &config.links {
            let s = UdpSocket::bind(spec.bind).await.with_context(|| {
                format!(
                    "{}{} link: cannot bind {} (in use? try another --instance)",
                    which(&config),
                    spec.name,
                    spec.bind
                )
            })?;
            sockets.push((spec.clone(), s));
        }
        let log_dir = match &config.log_dir {
            Some(base) => Some(logs::create_run_dir(base, config.instance)?),
            None => None,
        };
        if log_dir.is_some() {
            // the ULog logs the raw sensors from the first step (as the
            // replay's ULog does); otherwise they start when a link first
            // streams one of their messages (`SimRequest::RawSensors`)
            core.enable_raw_sensors(i);
        }
        let recorder = match &log_dir {
            Some(dir) => Some(recorder::Recorder::create(
                dir, &config, &params, sensors, &mut core, i,
            )?),
            None => None,
        };
        vehicles.push(Vehicle {
            config,
            params,
            warnings,
            sockets,
            log_dir,
            recorder,
            signing: vehicle_signing,
            state_lock,
        });
    }
    Ok(Daemon {
        origin,
        proximity_m,
        vehicles,
        core,
    })
}

/// Bind and run until `shutdown` completes (or a client sends shutdown).
///
/// # Errors
/// As [`bind`] and [`Daemon::run`].
pub async fn run(config: Config, shutdown: impl Future<Output = ()>) -> anyhow::Result<()> {
    bind(config).await?.run(shutdown).await
}

impl Daemon {
    /// The bound address of each link of the first vehicle (a lone
    /// vehicle's), by name.
    #[must_use]
    pub fn local_addrs(&self) -> Vec<(String, SocketAddr)> {
        self.vehicle_addrs(0)
    }

    /// The bound address of each link of vehicle `i`, by name.
    #[must_use]
    pub fn vehicle_addrs(&self, i: usize) -> Vec<(String, SocketAddr)> {
        self.vehicles.get(i).map_or_else(Vec::new, |v| {
            v.sockets
                .iter()
                .filter_map(|(spec, s)| s.local_addr().ok().map(|a| (spec.name.clone(), a)))
                .collect()
        })
    }

    /// Warnings from reading the parameter files, each naming its vehicle in a fleet.
    #[must_use]
    pub fn warnings(&self) -> Vec<String> {
        let lone = self.vehicles.len() == 1;
        self.vehicles
            .iter()
            .flat_map(|v| {
                v.warnings
                    .iter()
                    .map(move |w| format!("{}{w}", vehicle_prefix(lone, v.config.instance)))
            })
            .collect()
    }

    /// The configuration of the first vehicle (a lone vehicle's).
    #[must_use]
    pub fn config(&self) -> &Config {
        &self.vehicles[0].config
    }

    /// Each vehicle's configuration, in fleet order.
    pub fn configs(&self) -> impl Iterator<Item = &Config> {
        self.vehicles.iter().map(|v| &v.config)
    }

    /// The first vehicle's log directory of this run, when `--log-dir` was given.
    #[must_use]
    pub fn log_dir(&self) -> Option<&std::path::Path> {
        self.vehicles[0].log_dir.as_deref()
    }

    /// Where it listens and sends, for the startup message.
    #[must_use]
    pub fn summary(&self) -> String {
        if self.vehicles.len() == 1 {
            return self.lone_summary();
        }
        let c = self.config();
        let n = self.vehicles.len();
        let o = self.origin;
        let mut s = format!(
            "rotorpilot: a fleet of {n} vehicles on one clock; home {:.7}, {:.7}, {:.1} m AMSL; speed x{}; \
             proximity reported below {} m\n",
            o.lat_deg, o.lon_deg, o.alt_amsl_m, c.speed, self.proximity_m
        );
        for (i, v) in self.vehicles.iter().enumerate() {
            let c = &v.config;
            let at = self.core.world().origin_ned(i);
            let links: Vec<String> = v
                .sockets
                .iter()
                .map(|(spec, sock)| {
                    let (local, remote) = link_ends(spec, sock);
                    format!("{} {local} -> {remote}", spec.name)
                })
                .collect();
            s.push_str(&format!(
                "  instance {} (system id {}): {} at {:.1} m N, {:.1} m E; {}; state {}\n",
                c.instance,
                c.system_id(),
                c.airframe,
                at.x,
                at.y,
                links.join(", "),
                c.state_dir.display()
            ));
            if let Some(line) = ready::injections(&v.params) {
                s.push_str(&format!("    {line}\n"));
            }
        }
        if let Some(base) = &c.log_dir {
            s.push_str(&format!(
                "  logs: a run directory per vehicle below {}\n",
                base.display()
            ));
        }
        // last: scripts read the summary up to this line (tests/daemon_runtime.rs)
        s.push_str(&format!(
            "  parameters: params.toml in each vehicle's state directory ({} vehicles)",
            n
        ));
        s
    }

    /// The startup message of a lone vehicle.
    fn lone_summary(&self) -> String {
        let v = &self.vehicles[0];
        let c = &v.config;
        let mut s = format!(
            "rotorpilot: {} at {:.7}, {:.7}, {:.1} m AMSL; instance {}, system id {}; speed x{}\n",
            c.airframe,
            c.home.lat_deg,
            c.home.lon_deg,
            c.home.alt_amsl_m,
            c.instance,
            c.system_id(),
            c.speed
        );
        for (spec, sock) in &v.sockets {
            let (local, remote) = link_ends(spec, sock);
            s.push_str(&format!("  {:<4} link: udp {local} -> {remote}\n", spec.name));
        }
        let plans = self.core.pilot(0).plans();
        s.push_str(&format!(
            "  plans: {} (mission {} items, fence {}, rally {})\n",
            c.plans_path().display(),
            plans.get(MissionType::Mission).len(),
            plans.get(MissionType::Fence).len(),
            plans.get(MissionType::Rally).len()
        ));
        if let Some(d) = &v.log_dir {
            s.push_str(&format!("  logs: {}\n", d.display()));
        }
        if let Some(line) = ready::injections(&v.params) {
            s.push_str(&format!("  {line}\n"));
        }
        // last: scripts read the summary up to this line (tests/daemon_runtime.rs)
        s.push_str(&format!("  parameters: {}", c.params_path().display()));
        s
    }

    /// Run until `shutdown` completes or a client sends
    /// PREFLIGHT_REBOOT_SHUTDOWN with p1 = 2; then stop every task and save
    /// every vehicle's plans and parameters.
    ///
    /// # Errors
    /// A parameter or plans file cannot be written at shutdown.
    pub async fn run(self, shutdown: impl Future<Output = ()>) -> anyhow::Result<()> {
        let Daemon {
            origin: _,
            proximity_m: _,
            vehicles,
            mut core,
        } = self;
        let lone = vehicles.len() == 1;
        let (stop_tx, stop_rx) = watch::channel(false);
        let (exit_tx, mut exit_rx) = mpsc::channel::<()>(1);
        let inbox = inbox::inbox::<SimRequest>(vehicles.len());
        let started = vehicles[0].config.started;
        let (speed, tick, peer_timeout) = {
            let c = &vehicles[0].config;
            (c.speed, c.tick, c.peer_timeout)
        };
        let mut tasks: Vec<JoinHandle<()>> = Vec::new();
        let mut ios = Vec::with_capacity(vehicles.len());
        let mut tels = Vec::with_capacity(vehicles.len());
        // what is saved at shutdown, per vehicle
        let mut finals = Vec::with_capacity(vehicles.len());
        let mut links = Vec::new();
        // each link task's name for messages, in the order of `links`
        let mut link_names: Vec<String> = Vec::new();
        // each state directory stays locked until its final save is done (run returns)
        let mut held_locks = Vec::with_capacity(vehicles.len());
        for (i, v) in vehicles.into_iter().enumerate() {
            let config = v.config;
            tasks.push(tokio::spawn(signing::persist(v.signing.clone(), stop_rx.clone())));
            held_locks.push(v.state_lock);
            let params = Arc::new(Mutex::new(v.params));
            // the vehicle's ULog (`--log-dir`), started before the first step
            let ulog = v
                .log_dir
                .as_deref()
                .and_then(|d| ulog_file::UlogFile::create(d, &params, &core, i));
            let path = config.params_path();
            if let Some(dir) = path.parent() {
                std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
            }
            let (tel_tx, tel_rx) = watch::channel(core.snapshot(i));
            let (ev_tx, _) = broadcast::channel::<Event>(256);
            let (link_lost_tx, link_lost_rx) = watch::channel(false);
            let save = Arc::new(Notify::new());
            // Save once at start: a --reset-params run overwrites the old file,
            // and the state directory shows the parameters in force.
            save.notify_one();
            let plans_file = PlansFile::new(config.plans_path());
            let plans_changed = Arc::new(Notify::new());
            // the same for the plans (--reset-plans)
            plans_changed.notify_one();
            ios.push(VehicleIo {
                instance: config.instance,
                system_id: config.system_id(),
                params: params.clone(),
                tel: tel_tx,
                events: ev_tx.clone(),
                plans_changed: plans_changed.clone(),
                wall_timers: Vec::new(),
                link_lost: link_lost_tx,
                ulog,
                recorder: v.recorder,
                health: crate::link::events::Reporter::default(),
                health_forced: false,
            });
            // one writer per file: the saver, links' write-through and the final save share its lock
            let params_file = ParamsFile::new(path.clone());
            tasks.push(tokio::spawn(saver(
                params.clone(),
                params_file.clone(),
                save.clone(),
                ev_tx.clone(),
                stop_rx.clone(),
            )));
            tasks.push(tokio::spawn(plan_saver(
                tel_rx.clone(),
                plans_file.clone(),
                plans_changed,
                ev_tx.clone(),
                stop_rx.clone(),
            )));
            tels.push(tel_rx.clone());
            let identity = Identity {
                system_id: config.system_id(),
                component_id: 1,
            };
            // one store for the vehicle's links: they share the count of the clients' files
            let files = files::VehicleFiles::new(
                config.state_dir.clone(),
                config.log_dir.clone().map(|base| (base, config.instance)),
                v.log_dir.clone(),
            );
            let forwards = link_task::Forwards::for_links(v.sockets.len());
            for (index, ((spec, socket), (forwards, fellows))) in v.sockets.into_iter().zip(forwards).enumerate() {
                let mut link = Link::new(
                    LinkConfig {
                        name: spec.name.clone(),
                        identity,
                        default_remote: spec.remote,
                        rates: spec.rates.clone(),
                        peer_timeout,
                    },
                    Instant::now().into_std(),
                );
                link.set_signing(v.signing.shared.clone(), u8::try_from(index).unwrap_or(u8::MAX));
                // PX4 SITL starts every link with `-f`: each forwards to the vehicle's others
                if let Some(fellows) = fellows {
                    link.set_forwarding(fellows);
                }
                link.set_files(Box::new(files.clone()));
                link_names.push(format!("{}{} link", vehicle_prefix(lone, config.instance), spec.name));
                links.push(LinkTask {
                    link,
                    socket,
                    params: params.clone(),
                    tel: tel_rx.clone(),
                    link_lost: link_lost_rx.clone(),
                    sim: inbox.sender(i),
                    events: ev_tx.clone(),
                    events_rx: ev_tx.subscribe(),
                    save: save.clone(),
                    params_file: params_file.clone(),
                    dests: Vec::new(),
                    send_errors: 0,
                    tlog: v
                        .log_dir
                        .as_deref()
                        .map(|d| tlog::Tlog::create(d, &tlog::file_name(index, &spec.name)))
                        .unwrap_or_default(),
                    signing_changed: v.signing.changed.clone(),
                    forwards,
                });
            }
            // the links are subscribed: they send it once they run
            saver::announce_params_warnings(&v.warnings, &ev_tx);
            finals.push((config.instance, params, params_file, plans_file, tel_rx));
        }
        // stops the simulation thread out of band (a full queue cannot hold it up)
        let stopper = inbox.stopper();
        let sim = Sim {
            core,
            speed,
            tick,
            vehicles: ios,
            exit: exit_tx,
            encounters: Default::default(),
        };
        let (sim_done_tx, sim_done_rx) = oneshot::channel::<()>();
        let sim_thread = std::thread::Builder::new()
            .name("rotorpilot-sim".into())
            .spawn(move || {
                // a fleet's loop runs on a stepping thread (`StepThreads`)
                sim.core.threads().run(|| sim.run(&inbox));
                let _ = sim_done_tx.send(());
            })
            .context("starting the simulation thread")?;
        // one stdout line when the vehicles first are ready to arm (ready.rs)
        tasks.push(tokio::spawn(ready::announce(started, tels, stop_rx.clone())));
        // watched: a link task that ends while running stops the daemon (supervise.rs)
        let mut link_tasks = supervise::LinkTasks::default();
        for (name, task) in link_names.into_iter().zip(links) {
            link_tasks.spawn(name, task.run(stop_rx.clone()));
        }
        let mut link_died: Option<String> = None;

        let mut sim_done = sim_done_rx;
        let sim_died = tokio::select! {
            () = shutdown => {
                info!("shutting down");
                false
            }
            Some(()) = exit_rx.recv() => {
                info!("shutdown requested by a client");
                false
            }
            _ = &mut sim_done => {
                tracing::error!("the simulation thread stopped; shutting down");
                true
            }
            why = link_tasks.ended() => {
                // a link task also ends when the simulation thread is gone:
                // then that is the reason to give, not the link
                if tokio::time::timeout(Duration::from_millis(200), &mut sim_done).await.is_ok() {
                    tracing::error!("the simulation thread stopped; shutting down");
                    true
                } else {
                    tracing::error!("{why}; shutting down");
                    link_died = Some(why);
                    false
                }
            }
        };
        let _ = stop_tx.send(true);
        stopper.stop();
        if tokio::time::timeout(Duration::from_millis(800), async {
            futures_join(tasks).await;
            link_tasks.join_all().await;
        })
        .await
        .is_err()
        {
            warn!("some tasks did not stop in time");
        }
        // The simulation thread ends within one batch of steps (told to stop,
        // or every sender gone) and writes the end of its logs (the record's
        // end line, the CSV and ULog tails) as it drops: wait for it on its
        // own, so that slow link or saver tasks cannot cut the logs short.
        let sim_ended = sim_died
            || tokio::time::timeout(Duration::from_secs(5), &mut sim_done)
                .await
                .is_ok();
        if sim_ended {
            let _ = sim_thread.join();
        } else {
            warn!("the simulation thread did not stop in time: its logs may end early");
        }
        // every vehicle's files, even when one fails; the first error is returned
        let mut first_error: Option<anyhow::Error> = None;
        for (instance, params, params_file, plans_file, tel_rx) in finals {
            let path = params_file.path().to_path_buf();
            let who = vehicle_prefix(lone, instance);
            // the simulation thread publishes every plan change before it
            // answers it, so the last snapshot holds the plans in force
            let plans = tel_rx.borrow().plans.clone();
            let plans_saved = plans_file.save_final(&plans);
            if plans_saved.is_ok() {
                info!(path = %plans_file.path().display(), "plans saved");
            }
            let saved = params_file
                .save_final(&params)
                .with_context(|| format!("{who}saving parameters to {}", path.display()));
            if saved.is_ok() {
                info!(path = %path.display(), "parameters saved");
            }
            let result = saved.and(plans_saved.with_context(|| format!("{who}saving the plans")));
            if let Err(e) = result {
                tracing::error!("{e:#}");
                first_error.get_or_insert(e);
            }
        }
        if let Some(e) = first_error {
            return Err(e);
        }
        anyhow::ensure!(!sim_died, "the simulation thread stopped unexpectedly");
        if let Some(why) = link_died {
            anyhow::bail!("{why}");
        }
        Ok(())
    }
}

/// What names a vehicle in a message: nothing for a lone vehicle, else
/// `vehicle instance N: `.
fn vehicle_prefix(lone: bool, instance: u8) -> String {
    if lone {
        String::new()
    } else {
        format!("vehicle instance {instance}: ")
    }
}

/// A link's bound address and where it sends, as the banner shows them.
fn link_ends(spec: &LinkSpec, sock: &UdpSocket) -> (String, String) {
    let local = sock
        .local_addr()
        .map_or_else(|_| spec.bind.to_string(), |a| a.to_string());
    let remote = spec
        .remote
        .map_or_else(|| "(whoever talks)".to_string(), |r| r.to_string());
    (local, remote)
}

async fn futures_join(tasks: Vec<JoinHandle<()>>) {
    for t in tasks {
        let _ = t.await;
    }
}
