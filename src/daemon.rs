//! The tokio runtime of one simulated vehicle: it owns the UDP sockets and the
//! autopilot, paces simulated time against the wall clock, and shuts down
//! cleanly (shaped like mini-redis: [`bind`] takes a [`Config`] whose
//! addresses may use port 0, [`Daemon::run`] takes the stop trigger).
//!
//! Tasks and channels:
//! - **sim**: a dedicated OS thread, the only owner of the autopilot
//!   ([`Core`]), so the simulation never blocks the links (and the links'
//!   runtime can stay on one thread). Every [`Config::tick`] of wall time it
//!   runs the 1 kHz steps that are due so that simulated time = `speed` x wall
//!   time (batched: no per-step syscall; requests are served between chunks of
//!   steps), then publishes a [`Telemetry`] snapshot on a `watch` and status
//!   texts on a `broadcast`. Between ticks it sleeps in `recv_timeout` on its
//!   bounded request channel, so a command is served at once. Each command or
//!   parameter set carries a `oneshot` for its outcome. If the machine cannot
//!   keep up, simulated time falls behind instead of bursting (a warning says so).
//! - **link** (one per socket): owns a [`Link`] (the protocol, sans I/O) and
//!   its socket: receives datagrams, sends the streams when due (wall-time
//!   rates; heartbeats keep going at 1 Hz even if the simulation is slow),
//!   forwards commands to sim and sends the ACKs.
//! - **saver**: writes the parameter file (atomic) after each accepted set,
//!   off the link tasks; the file is written once more at shutdown.
//!
//! Parameters live in a `std::sync::Mutex<ParamStore>`: links read it to
//! answer requests, sim writes it (and applies the change to the autopilot,
//! undoing the set if the autopilot refuses the combination). The lock is
//! never held across an `.await`.
//!
//! PREFLIGHT_REBOOT_SHUTDOWN: reboot (p1 = 1) rebuilds the autopilot from the
//! current parameters, on the ground at the configured home, disarmed; the
//! telemetry clock keeps counting so `time_boot_ms` stays monotonic for the
//! clients already connected. Shutdown (p1 = 2) stops the daemon, as PX4 SITL
//! exits.

use std::future::Future;
use std::net::{IpAddr, Ipv4Addr, SocketAddr, ToSocketAddrs as _};
use std::path::PathBuf;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::{Context as _, bail};
use mavlink::dialects::common::MavMessage;
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use tokio::net::UdpSocket;

use tokio::sync::{Notify, broadcast, mpsc, oneshot, watch};
use tokio::task::JoinHandle;
use tokio::time::Instant;
use tracing::{debug, info, warn};

use crate::airframe::Airframe;
use crate::autopilot::{Autopilot, AutopilotCommand, CommandOutcome, StatusText, Telemetry};
use crate::geo::GeoPoint;
use crate::link::streams::{self, Identity, Rates};
use crate::link::{Effect, Link, LinkConfig, Outgoing, To};
use crate::params::{ParamStore, ParamValue};

/// One simulated step [s] (1 kHz).
pub const STEP_S: f64 = 1e-3;

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
    let p = GeoPoint {
        lat_deg,
        lon_deg,
        alt_amsl_m,
    };
    anyhow::ensure!(p.is_valid(), "--home `{s}` is not a valid position");
    Ok(p)
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
    /// Where the parameter file lives.
    pub state_dir: PathBuf,
    /// Start from default parameters (the file is overwritten on the first save).
    pub reset_params: bool,
    /// A learned peer is forgotten after this long without a frame from it.
    pub peer_timeout: Duration,
    /// Wall-time period of the simulation batches.
    pub tick: Duration,
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
            peer_timeout: Duration::from_secs(30),
            tick: Duration::from_millis(4),
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
}

/// What the daemon needs of the autopilot ([`Autopilot`]; tests may fake it).
pub trait Core: Send {
    /// Execute a command.
    fn command(&mut self, command: AutopilotCommand) -> CommandOutcome;
    /// Apply the parameters.
    ///
    /// # Errors
    /// A combination the autopilot refuses (nothing changed then).
    fn apply_params(&mut self, params: &ParamStore) -> Result<(), String>;
    /// Advance one step ([`STEP_S`]).
    fn step(&mut self);
    /// The telemetry snapshot.
    fn telemetry(&self) -> Telemetry;
    /// Events to announce.
    fn drain_status_texts(&mut self) -> Vec<StatusText>;
}

impl Core for Autopilot {
    fn command(&mut self, command: AutopilotCommand) -> CommandOutcome {
        Autopilot::command(self, command)
    }
    fn apply_params(&mut self, params: &ParamStore) -> Result<(), String> {
        Autopilot::apply_params(self, params).map_err(|e| e.to_string())
    }
    fn step(&mut self) {
        Autopilot::step(self);
    }
    fn telemetry(&self) -> Telemetry {
        Autopilot::telemetry(self)
    }
    fn drain_status_texts(&mut self) -> Vec<StatusText> {
        Autopilot::drain_status_texts(self)
    }
}

/// Builds a fresh [`Core`] from the parameters (at boot and on reboot).
pub type CoreFactory = Box<dyn Fn(&ParamStore) -> anyhow::Result<Box<dyn Core>> + Send>;

/// A daemon with its sockets bound, ready to [`Daemon::run`].
pub struct Daemon {
    config: Config,
    params: ParamStore,
    warnings: Vec<String>,
    sockets: Vec<(LinkSpec, UdpSocket)>,
    core: Box<dyn Core>,
    factory: CoreFactory,
}

impl std::fmt::Debug for Daemon {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Daemon")
            .field("config", &self.config)
            .field("addrs", &self.local_addrs())
            .finish_non_exhaustive()
    }
}

/// Load the airframe and parameters and bind every link's socket.
///
/// # Errors
/// Unknown airframe, unreadable parameter file, bad speed, a socket that
/// cannot be bound (port in use: try another `--instance`).
pub async fn bind(config: Config) -> anyhow::Result<Daemon> {
    let airframe = Airframe::load(&config.airframe)?;
    let home = config.home;
    let frame = airframe.clone();
    let factory: CoreFactory = Box::new(move |p: &ParamStore| {
        let a = Autopilot::new(&frame, home, p)?;
        Ok(Box::new(a) as Box<dyn Core>)
    });
    bind_with(config, &airframe, factory).await
}

/// [`bind`] with a given airframe (for parameter defaults) and autopilot factory.
///
/// # Errors
/// As [`bind`].
pub async fn bind_with(config: Config, airframe: &Airframe, factory: CoreFactory) -> anyhow::Result<Daemon> {
    anyhow::ensure!(
        config.speed.is_finite() && config.speed > 0.0 && config.speed <= 1000.0,
        "--speed must be in (0, 1000], got {}",
        config.speed
    );
    anyhow::ensure!(config.instance < 250, "--instance must be below 250");
    let path = config.params_path();
    let (mut params, warnings) = if config.reset_params {
        (ParamStore::new(airframe), Vec::new())
    } else {
        ParamStore::load_or_default(airframe, &path)?
    };
    // PX4 SITL's rcS sets MAV_SYS_ID to instance + 1 at every start.
    let _ = params.set("MAV_SYS_ID", ParamValue::Int32(i32::from(config.system_id())));
    let core = factory(&params).context("starting the autopilot")?;
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
    Ok(Daemon {
        config,
        params,
        warnings,
        sockets,
        core,
        factory,
    })
}

/// Bind and run until `shutdown` completes (or a client sends shutdown).
///
/// # Errors
/// As [`bind`] and [`Daemon::run`].
pub async fn run(config: Config, shutdown: impl Future<Output = ()>) -> anyhow::Result<()> {
    bind(config).await?.run(shutdown).await
}

/// Messages from the link tasks to sim.
#[derive(Debug)]
enum SimRequest {
    Command {
        command: AutopilotCommand,
        reply: Option<oneshot::Sender<CommandOutcome>>,
    },
    SetParam {
        name: String,
        value: ParamValue,
        reply: oneshot::Sender<Result<ParamValue, String>>,
    },
    Reboot,
    Stop,
}

/// Messages to every link task.
#[derive(Clone, Debug)]
enum Event {
    StatusText(StatusText),
    ParamValue(Arc<MavMessage>),
}

fn lock(p: &Mutex<ParamStore>) -> MutexGuard<'_, ParamStore> {
    // A panic while holding the lock leaves the store consistent (every
    // mutation is a single checked set), so a poisoned lock is still usable.
    p.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
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
        s.push_str(&format!("  parameters: {}", c.params_path().display()));
        s
    }

    /// Run until `shutdown` completes or a client sends
    /// PREFLIGHT_REBOOT_SHUTDOWN with p1 = 2; then stop every task and save
    /// the parameters.
    ///
    /// # Errors
    /// The parameter file cannot be written at shutdown.
    pub async fn run(self, shutdown: impl Future<Output = ()>) -> anyhow::Result<()> {
        let Daemon {
            config,
            params,
            warnings: _,
            sockets,
            core,
            factory,
        } = self;
        let params = Arc::new(Mutex::new(params));
        let path = config.params_path();
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        }
        let (stop_tx, stop_rx) = watch::channel(false);
        let (exit_tx, mut exit_rx) = mpsc::channel::<()>(1);
        let (sim_tx, sim_rx) = std::sync::mpsc::sync_channel::<SimRequest>(256);
        let (tel_tx, tel_rx) = watch::channel(core.telemetry());
        let (ev_tx, _) = broadcast::channel::<Event>(256);
        let save = Arc::new(Notify::new());
        // Save once at start: a --reset-params run overwrites the old file,
        // and the state directory shows the parameters in force.
        save.notify_one();

        let mut tasks: Vec<JoinHandle<()>> = Vec::new();
        let sim = Sim {
            core,
            factory,
            params: params.clone(),
            tel: tel_tx,
            events: ev_tx.clone(),
            speed: config.speed,
            tick: config.tick,
            time_offset_s: 0.0,
            last_time_s: 0.0,
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
        let identity = Identity {
            system_id: config.system_id(),
            component_id: 1,
        };
        for (spec, socket) in sockets {
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
                sim: sim_tx.clone(),
                events: ev_tx.clone(),
                events_rx: ev_tx.subscribe(),
                save: save.clone(),
                exit: exit_tx.clone(),
                dests: Vec::new(),
                send_errors: 0,
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
        let all = async {
            futures_join(tasks).await;
            if !sim_died {
                let _ = sim_done.await;
            }
        };
        if tokio::time::timeout(Duration::from_millis(800), all).await.is_err() {
            warn!("some tasks did not stop in time");
        } else {
            let _ = sim_thread.join();
        }
        let snapshot = lock(&params).clone();
        snapshot
            .save(&path)
            .with_context(|| format!("saving parameters to {}", path.display()))?;
        info!(path = %path.display(), "parameters saved");
        anyhow::ensure!(!sim_died, "the simulation thread stopped unexpectedly");
        Ok(())
    }
}

async fn futures_join(tasks: Vec<JoinHandle<()>>) {
    for t in tasks {
        let _ = t.await;
    }
}

/// Writes the parameter file whenever notified (coalescing bursts).
async fn saver(params: Arc<Mutex<ParamStore>>, path: PathBuf, save: Arc<Notify>, mut stop: watch::Receiver<bool>) {
    loop {
        tokio::select! {
            () = save.notified() => {}
            _ = stop.changed() => return,
        }
        let snapshot = lock(&params).clone();
        let p = path.clone();
        match tokio::task::spawn_blocking(move || snapshot.save(&p)).await {
            Ok(Ok(())) => debug!(path = %path.display(), "parameters saved"),
            Ok(Err(e)) => warn!(error = %e, "cannot save parameters"),
            Err(e) => warn!(error = %e, "parameter saver failed"),
        }
    }
}

/// The simulation task's state.
struct Sim {
    core: Box<dyn Core>,
    factory: CoreFactory,
    params: Arc<Mutex<ParamStore>>,
    tel: watch::Sender<Telemetry>,
    events: broadcast::Sender<Event>,
    speed: f64,
    tick: Duration,
    /// Added to the autopilot's clock after a reboot, so telemetry time stays monotonic.
    time_offset_s: f64,
    last_time_s: f64,
}

/// Steps run between two looks at the request queue.
const CHUNK: u64 = 50;
/// At most this much wall time is spent stepping per tick; the rest waits.
const MAX_BATCH_WALL: Duration = Duration::from_millis(20);

impl Sim {
    /// The simulation loop (on its own thread) until [`SimRequest::Stop`] or
    /// every sender is gone.
    fn run(mut self, rx: &Receiver<SimRequest>) {
        let start = std::time::Instant::now();
        let mut base = start;
        let mut base_steps: u64 = 0;
        let mut steps: u64 = 0;
        let mut next_tick = start;
        let mut last_lag_warning: Option<std::time::Instant> = None;
        loop {
            let now = std::time::Instant::now();
            if now < next_tick {
                match rx.recv_timeout(next_tick - now) {
                    Ok(SimRequest::Stop) | Err(RecvTimeoutError::Disconnected) => return,
                    Ok(r) => self.handle(r),
                    Err(RecvTimeoutError::Timeout) => {}
                }
                continue;
            }
            next_tick += self.tick;
            if next_tick <= now {
                next_tick = now + self.tick;
            }
            let target = base_steps + (now.duration_since(base).as_secs_f64() * self.speed / STEP_S) as u64;
            let mut due = target.saturating_sub(steps);
            // More than a second of wall time behind: stop trying to catch
            // up, let simulated time lag instead.
            let limit = ((self.speed / STEP_S) as u64).max(1000);
            if due > limit {
                if last_lag_warning.is_none_or(|t| now.duration_since(t) > Duration::from_secs(10)) {
                    warn!(
                        behind_s = due as f64 * STEP_S,
                        "simulation cannot keep up with --speed; slowing down"
                    );
                    last_lag_warning = Some(now);
                }
                base = now;
                base_steps = steps;
                due = 0;
            }
            while due > 0 {
                let n = due.min(CHUNK);
                for _ in 0..n {
                    self.core.step();
                }
                steps += n;
                due -= n;
                loop {
                    match rx.try_recv() {
                        Ok(SimRequest::Stop) => return,
                        Ok(r) => self.handle(r),
                        Err(_) => break,
                    }
                }
                if now.elapsed() > MAX_BATCH_WALL {
                    break;
                }
            }
            self.publish();
        }
    }

    fn publish(&mut self) {
        let mut t = self.core.telemetry();
        t.time_s += self.time_offset_s;
        // never backwards, whatever happens inside
        if t.time_s < self.last_time_s {
            t.time_s = self.last_time_s;
        }
        self.last_time_s = t.time_s;
        self.tel.send_replace(t);
        for s in self.core.drain_status_texts() {
            info!(text = %s.text, "status");
            let _ = self.events.send(Event::StatusText(s));
        }
    }

    fn handle(&mut self, r: SimRequest) {
        match r {
            SimRequest::Command { command, reply } => {
                let outcome = self.core.command(command);
                // Publish before answering: a client that acts on the ACK (disarm,
                // then shutdown) must find the links already seeing the new state.
                self.publish();
                // setpoints stream without a reply: log only their refusals
                if reply.is_some() || outcome != CommandOutcome::Accepted {
                    debug!(?command, ?outcome, "command");
                }
                if let Some(tx) = reply {
                    let _ = tx.send(outcome);
                }
            }
            SimRequest::SetParam { name, value, reply } => {
                let outcome = {
                    let mut p = lock(&self.params);
                    let old = p.get(&name).map(|(_, v)| v);
                    match p.set(&name, value) {
                        Err(e) => Err(e.to_string()),
                        Ok(stored) => match self.core.apply_params(&p) {
                            Ok(()) => Ok(stored),
                            Err(e) => {
                                if let Some(old) = old {
                                    let _ = p.set(&name, old);
                                }
                                Err(e)
                            }
                        },
                    }
                };
                match &outcome {
                    Ok(v) => info!(%name, value = %v, "parameter set"),
                    Err(e) => info!(%name, error = %e, "parameter refused"),
                }
                self.publish();
                let _ = reply.send(outcome);
            }
            // the loop returns on Stop before handing requests here
            SimRequest::Stop => {}
            SimRequest::Reboot => {
                let p = lock(&self.params).clone();
                match (self.factory)(&p) {
                    Ok(core) => {
                        self.time_offset_s = self.last_time_s;
                        self.core = core;
                        info!("rebooted: simulation reset");
                        let _ = self.events.send(Event::StatusText(StatusText {
                            severity: crate::autopilot::Severity::Info,
                            text: "Rebooted: simulation reset".into(),
                        }));
                        self.publish();
                    }
                    Err(e) => warn!(error = %e, "reboot failed"),
                }
            }
        }
    }
}

/// One link's task state.
struct LinkTask {
    link: Link,
    socket: UdpSocket,
    params: Arc<Mutex<ParamStore>>,
    tel: watch::Receiver<Telemetry>,
    sim: SyncSender<SimRequest>,
    events: broadcast::Sender<Event>,
    events_rx: broadcast::Receiver<Event>,
    save: Arc<Notify>,
    exit: mpsc::Sender<()>,
    dests: Vec<SocketAddr>,
    send_errors: u64,
}

/// How long a link waits for the autopilot's answer before ACKing FAILED.
const COMMAND_TIMEOUT: Duration = Duration::from_secs(1);

fn unix_time_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

impl LinkTask {
    async fn run(mut self, mut stop: watch::Receiver<bool>) {
        let name = self.link.config().name.clone();
        let mut buf = vec![0u8; 65_536];
        loop {
            let deadline = self
                .link
                .next_deadline()
                .map_or_else(|| Instant::now() + Duration::from_secs(1), Instant::from_std);
            tokio::select! {
                biased;
                _ = stop.changed() => break,
                r = self.socket.recv_from(&mut buf) => match r {
                    Ok((n, from)) => {
                        let effects = {
                            let t = self.tel.borrow();
                            let p = lock(&self.params);
                            self.link.on_datagram(Instant::now().into_std(), from, &buf[..n], &t, &*p)
                        };
                        self.flush().await;
                        for e in effects {
                            if !self.effect(e).await {
                                return;
                            }
                        }
                    }
                    Err(e) => {
                        debug!(link = %name, error = %e, "recv failed");
                        // do not spin if the error persists
                        tokio::time::sleep(Duration::from_millis(10)).await;
                    }
                },
                ev = self.events_rx.recv() => match ev {
                    Ok(Event::StatusText(s)) => {
                        self.link.status_text(&s);
                        self.flush().await;
                    }
                    Ok(Event::ParamValue(m)) => self.link.broadcast_param(Instant::now().into_std(), &m),
                    Err(broadcast::error::RecvError::Lagged(n)) => warn!(link = %name, missed = n, "events dropped"),
                    Err(broadcast::error::RecvError::Closed) => break,
                },
                () = tokio::time::sleep_until(deadline) => {
                    {
                        let t = self.tel.borrow();
                        self.link.poll(Instant::now().into_std(), &t, unix_time_us());
                    }
                    self.flush().await;
                }
            }
        }
        let s = self.link.stats();
        debug!(link = %name, frames_in = s.frames_in, ignored = s.ignored, "link stopped");
    }

    /// Hand a request to the simulation thread without blocking this task
    /// (the queue only fills if the simulation is stuck). False when it is gone.
    fn to_sim(&self, r: SimRequest) -> Result<(), bool> {
        match self.sim.try_send(r) {
            Ok(()) => Ok(()),
            Err(TrySendError::Full(_)) => Err(true),
            Err(TrySendError::Disconnected(_)) => Err(false),
        }
    }

    /// Carry out one effect; false when the daemon is going down.
    async fn effect(&mut self, e: Effect) -> bool {
        match e {
            Effect::Autopilot { command, ack: None } => {
                // Offboard setpoints: a dropped one is replaced by the next
                // (MAVSDK streams at 20 Hz).
                let _ = self.to_sim(SimRequest::Command { command, reply: None });
            }
            Effect::Autopilot {
                command,
                ack: Some(ticket),
            } => {
                let (tx, rx) = oneshot::channel();
                let outcome = match self.to_sim(SimRequest::Command {
                    command,
                    reply: Some(tx),
                }) {
                    Err(false) => return false,
                    Err(true) => CommandOutcome::TemporarilyRejected("simulation busy"),
                    Ok(()) => match tokio::time::timeout(COMMAND_TIMEOUT, rx).await {
                        Ok(Ok(o)) => o,
                        Ok(Err(_)) => return false,
                        Err(_) => CommandOutcome::Failed("autopilot did not answer"),
                    },
                };
                self.link.on_outcome(ticket, &outcome);
                self.flush().await;
            }
            Effect::SetParam { ticket, value } => {
                let (tx, rx) = oneshot::channel();
                let outcome = match self.to_sim(SimRequest::SetParam {
                    name: ticket.name.clone(),
                    value,
                    reply: tx,
                }) {
                    Err(false) => return false,
                    Err(true) => Err("simulation busy".to_string()),
                    Ok(()) => match tokio::time::timeout(COMMAND_TIMEOUT, rx).await {
                        Ok(Ok(o)) => o,
                        Ok(Err(_)) => return false,
                        Err(_) => Err("autopilot did not answer".to_string()),
                    },
                };
                let changed = {
                    let p = lock(&self.params);
                    self.link.on_param_set(&ticket, outcome, &*p)
                };
                self.flush().await;
                if let Some(m) = changed {
                    let _ = self.events.send(Event::ParamValue(Arc::new(m)));
                    self.save.notify_one();
                }
            }
            Effect::Reboot => {
                self.flush().await;
                let _ = self.to_sim(SimRequest::Reboot);
            }
            Effect::Shutdown => {
                self.flush().await;
                let _ = self.exit.try_send(());
            }
        }
        true
    }

    async fn flush(&mut self) {
        let out = self.link.drain();
        if out.is_empty() {
            return;
        }
        let now = Instant::now().into_std();
        if out.iter().any(|o| o.to == To::All) {
            self.link.destinations(now, &mut self.dests);
        }
        for Outgoing { to, bytes } in out {
            match to {
                To::Peer(a) => self.send(&bytes, a).await,
                To::All => {
                    for i in 0..self.dests.len() {
                        let a = self.dests[i];
                        self.send(&bytes, a).await;
                    }
                }
            }
        }
    }

    async fn send(&mut self, bytes: &[u8], to: SocketAddr) {
        if let Err(e) = self.socket.send_to(bytes, to).await {
            self.send_errors += 1;
            // rate-limited: the first, then every 1000th
            if self.send_errors % 1000 == 1 {
                debug!(link = %self.link.config().name, %to, error = %e, count = self.send_errors, "send failed");
            }
        }
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
