//! The tokio runtime of one simulated vehicle: it owns the UDP sockets and
//! the lockstep core, paces simulated time against the wall clock, and shuts
//! down cleanly (shaped like mini-redis: [`bind`] takes a [`Config`] whose
//! addresses may use port 0, [`Daemon::run`] takes the stop trigger).
//!
//! | file | job |
//! |---|---|
//! | `config` | [`Config`], [`LinkSpec`]: the instance and PX4 SITL's port rules, home, speed, state directory |
//! | `sim_thread` | the simulation thread: the only owner of the core, paced against wall time; commands and parameter sets are applied there, between steps |
//! | `link_task` | one task per UDP link: datagrams in, streams and answers out |
//! | `logs` | the run's log directory below `--log-dir` |
//! | `ready` | the one-time `rotorpilot: ready to arm` line on stdout |
//! | `tlog`, `ulog_file` | each link's `.tlog` and the vehicle's `flight.ulg` in the run's log directory |
//! | `recorder` | the run's flight record (`flight.record`, for `rotorpilot replay`) and `--log-csv` CSV (`flight.csv`) |
//! | `saver` | the parameter file and the stored plans, written after each accepted change |
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
//! exits. Both are refused while armed (the autopilot decides).

mod config;
mod fleet;
mod link_task;
mod logs;
mod ready;
mod recorder;
mod saver;
mod sim_thread;
mod tlog;
mod ulog_file;

pub use config::{Config, LinkSpec, parse_home, resolve};
pub use fleet::{
    DEFAULT_PROXIMITY_M, DEFAULT_STATE_ROOT, FLEET_SPACING_M, FleetConfig, FleetOptions, MAX_INSTANCE, Remote,
};

use std::future::Future;
use std::net::SocketAddr;
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
use crate::link::streams::Identity;
use crate::link::{Link, LinkConfig};
use crate::lockstep::Lockstep;
use crate::mission::file::load_plans;
use crate::mission::{MissionType, Plans};
use crate::params::{ParamStore, ParamValue};
use crate::sim::SensorConfig;
use link_task::LinkTask;
use saver::{PlansFile, lock, plan_saver, saver};
use sim_thread::{Event, Sim, SimRequest};

/// A daemon with its sockets bound, ready to [`Daemon::run`].
pub struct Daemon {
    config: Config,
    params: ParamStore,
    warnings: Vec<String>,
    sockets: Vec<(LinkSpec, UdpSocket)>,
    core: Lockstep<Autopilot>,
    /// This run's log directory (`--log-dir`), created at bind.
    log_dir: Option<std::path::PathBuf>,
    /// The flight record (and CSV) in the log directory, started at bind.
    recorder: Option<recorder::Recorder>,
}

impl std::fmt::Debug for Daemon {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Daemon")
            .field("config", &self.config)
            .field("addrs", &self.local_addrs())
            .finish_non_exhaustive()
    }
}

/// Load the airframe, parameters and stored plans and bind every link's socket.
///
/// # Errors
/// Unknown airframe, unreadable parameter file, a plans file that does not
/// read or holds a plan the vehicle refuses, bad speed, a socket that cannot
/// be bound (port in use: try another `--instance`).
pub async fn bind(config: Config) -> anyhow::Result<Daemon> {
    anyhow::ensure!(
        config.speed.is_finite() && config.speed > 0.0 && config.speed <= 1000.0,
        "--speed must be in (0, 1000], got {}",
        config.speed
    );
    anyhow::ensure!(config.instance < 250, "--instance must be below 250");
    let airframe = Airframe::load(&config.airframe)?;
    let path = config.params_path();
    let (mut params, warnings) = if config.reset_params {
        (ParamStore::new(&airframe), Vec::new())
    } else {
        ParamStore::load_or_default(&airframe, &path)?
    };
    // PX4 SITL's rcS sets MAV_SYS_ID to instance + 1 at every start.
    let _ = params.set("MAV_SYS_ID", ParamValue::Int32(i32::from(config.system_id())));
    let sensors = SensorConfig::default();
    let mut core = Lockstep::one_vehicle(&airframe, config.home, &params, sensors)
        .with_context(|| format!("starting the autopilot on {}", airframe.source))?;
    if config.speed > 1.0 {
        // faster than real time: timers that wait for a client run on the wall clock
        core.pilot_mut(sim_thread::VEHICLE).set_client_clock(ClientClock::Wall);
    }
    let plans = if config.reset_plans {
        Plans::default()
    } else {
        load_plans(&config.plans_path()).context(
            "cannot restore the stored mission, geofence and rally points \
             (mend or remove the file, or start with --reset-plans to discard them)",
        )?
    };
    core.pilot_mut(sim_thread::VEHICLE).restore_plans(plans);
    let mut sockets = Vec::new();
    for spec in &config.links {
        let s = UdpSocket::bind(spec.bind).await.with_context(|| {
            format!(
                "{} link: cannot bind {} (in use? try another --instance)",
                spec.name, spec.bind
            )
        })?;
        sockets.push((spec.clone(), s));
    }
    let log_dir = match &config.log_dir {
        Some(base) => Some(logs::create_run_dir(base, config.instance)?),
        None => None,
    };
    let recorder = match &log_dir {
        Some(dir) => Some(recorder::Recorder::create(
            dir,
            &config.airframe,
            config.home,
            &params,
            sensors,
            &mut core,
            config.log_csv,
        )?),
        None => None,
    };
    Ok(Daemon {
        config,
        params,
        warnings,
        sockets,
        core,
        log_dir,
        recorder,
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
    /// The bound address of each link, by name.
    #[must_use]
    pub fn local_addrs(&self) -> Vec<(String, SocketAddr)> {
        self.sockets
            .iter()
            .filter_map(|(spec, s)| s.local_addr().ok().map(|a| (spec.name.clone(), a)))
            .collect()
    }

    /// Warnings from reading the parameter file.
    #[must_use]
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// This run's log directory, when `--log-dir` was given.
    #[must_use]
    pub fn log_dir(&self) -> Option<&std::path::Path> {
        self.log_dir.as_deref()
    }

    /// Where it listens and sends, for the startup message.
    #[must_use]
    pub fn summary(&self) -> String {
        let c = &self.config;
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
        for (spec, sock) in &self.sockets {
            let local = sock
                .local_addr()
                .map_or_else(|_| spec.bind.to_string(), |a| a.to_string());
            let remote = spec
                .remote
                .map_or_else(|| "(whoever talks)".to_string(), |r| r.to_string());
            s.push_str(&format!("  {:<4} link: udp {local} -> {remote}\n", spec.name));
        }
        let plans = self.core.pilot(sim_thread::VEHICLE).plans();
        s.push_str(&format!(
            "  plans: {} (mission {} items, fence {}, rally {})\n",
            c.plans_path().display(),
            plans.get(MissionType::Mission).len(),
            plans.get(MissionType::Fence).len(),
            plans.get(MissionType::Rally).len()
        ));
        if let Some(d) = &self.log_dir {
            s.push_str(&format!("  logs: {}\n", d.display()));
        }
        // last: scripts read the summary up to this line (tests/daemon_runtime.rs)
        s.push_str(&format!("  parameters: {}", c.params_path().display()));
        s
    }

    /// Run until `shutdown` completes or a client sends
    /// PREFLIGHT_REBOOT_SHUTDOWN with p1 = 2; then stop every task and save
    /// the plans and the parameters.
    ///
    /// # Errors
    /// The parameter or plans file cannot be written at shutdown.
    pub async fn run(self, shutdown: impl Future<Output = ()>) -> anyhow::Result<()> {
        let Daemon {
            config,
            params,
            warnings: _,
            sockets,
            mut core,
            log_dir,
            recorder,
        } = self;
        let params = Arc::new(Mutex::new(params));
        // the vehicle's ULog (`--log-dir`), started before the first step
        let ulog = log_dir
            .as_deref()
            .and_then(|d| ulog_file::UlogFile::create(d, &params, &core, sim_thread::VEHICLE));
        let path = config.params_path();
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        }
        let (stop_tx, stop_rx) = watch::channel(false);
        let (exit_tx, mut exit_rx) = mpsc::channel::<()>(1);
        let (sim_tx, sim_rx) = std::sync::mpsc::sync_channel::<SimRequest>(256);
        let (tel_tx, tel_rx) = watch::channel(core.snapshot(sim_thread::VEHICLE));
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

        let mut tasks: Vec<JoinHandle<()>> = Vec::new();
        let sim = Sim {
            core,
            params: params.clone(),
            tel: tel_tx,
            events: ev_tx.clone(),
            speed: config.speed,
            tick: config.tick,
            plans_changed: plans_changed.clone(),
            wall_timers: Vec::new(),
            link_lost: link_lost_tx,
            ulog,
            recorder,
        };
        let (sim_done_tx, sim_done_rx) = oneshot::channel::<()>();
        let sim_thread = std::thread::Builder::new()
            .name("rotorpilot-sim".into())
            .spawn(move || {
                sim.run(&sim_rx);
                let _ = sim_done_tx.send(());
            })
            .context("starting the simulation thread")?;
        tasks.push(tokio::spawn(saver(
            params.clone(),
            path.clone(),
            save.clone(),
            stop_rx.clone(),
        )));
        tasks.push(tokio::spawn(plan_saver(
            tel_rx.clone(),
            plans_file.clone(),
            plans_changed,
            stop_rx.clone(),
        )));
        // issue 13: one stdout line when the vehicle first is ready to arm (ready.rs)
        tasks.push(tokio::spawn(ready::announce(
            config.started,
            tel_rx.clone(),
            stop_rx.clone(),
        )));
        let identity = Identity {
            system_id: config.system_id(),
            component_id: 1,
        };
        for (index, (spec, socket)) in sockets.into_iter().enumerate() {
            let link = Link::new(
                LinkConfig {
                    name: spec.name.clone(),
                    identity,
                    default_remote: spec.remote,
                    rates: spec.rates.clone(),
                    peer_timeout: config.peer_timeout,
                },
                Instant::now().into_std(),
            );
            let task = LinkTask {
                link,
                socket,
                params: params.clone(),
                tel: tel_rx.clone(),
                link_lost: link_lost_rx.clone(),
                sim: sim_tx.clone(),
                events: ev_tx.clone(),
                events_rx: ev_tx.subscribe(),
                save: save.clone(),
                exit: exit_tx.clone(),
                dests: Vec::new(),
                send_errors: 0,
                tlog: log_dir
                    .as_deref()
                    .map(|d| tlog::Tlog::create(d, &tlog::file_name(index, &spec.name)))
                    .unwrap_or_default(),
            };
            tasks.push(tokio::spawn(task.run(stop_rx.clone())));
        }
        drop(exit_tx);

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
        };
        let _ = stop_tx.send(true);
        // never block here; if the queue is full the simulation sees every
        // sender gone once the links have stopped
        let _ = sim_tx.try_send(SimRequest::Stop);
        drop(sim_tx);
        if tokio::time::timeout(Duration::from_millis(800), futures_join(tasks))
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
        // the simulation thread publishes every plan change before it
        // answers it, so the last snapshot holds the plans in force
        let plans = tel_rx.borrow().plans.clone();
        let plans_saved = plans_file.save_final(&plans);
        if plans_saved.is_ok() {
            info!(path = %plans_file.path().display(), "plans saved");
        }
        let snapshot = lock(&params).clone();
        snapshot
            .save(&path)
            .with_context(|| format!("saving parameters to {}", path.display()))?;
        info!(path = %path.display(), "parameters saved");
        plans_saved.context("saving the plans")?;
        anyhow::ensure!(!sim_died, "the simulation thread stopped unexpectedly");
        Ok(())
    }
}

async fn futures_join(tasks: Vec<JoinHandle<()>>) {
    for t in tasks {
        let _ = t.await;
    }
}
