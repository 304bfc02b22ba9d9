//! The vehicle daemon's command line (`rotorpilot` without a command):
//! [`DaemonArgs`], the daemon configuration they describe (a lone vehicle
//! or a fleet), and running it until Ctrl-C, SIGTERM or a client's shutdown.

use std::path::PathBuf;

use crate::airframe::DEFAULT_AIRFRAME;
use crate::daemon::{Config, DEFAULT_STATE_ROOT, FleetConfig, FleetOptions, LinkSpec, Remote, parse_home, resolve};

/// Options of the vehicle daemon (`rotorpilot` without a command).
#[derive(Debug, Clone, clap::Args)]
pub struct DaemonArgs {
    /// Built-in airframe name (quad, hexa, hexa-ppnnpn, octo, fsr-quad) or path to a TOML file.
    #[arg(long, default_value = DEFAULT_AIRFRAME)]
    pub airframe: String,
    /// PX4 SITL instance N: system id N+1, ports 18570+N and 14580+N, state in rotorpilot-state/N.
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=249))]
    pub instance: u8,
    /// Home and NED origin: LAT,LON,ALT (degrees, degrees, metres AMSL).
    #[arg(long, value_name = "LAT,LON,ALT", allow_hyphen_values = true)]
    pub home: Option<String>,
    /// Simulated time runs FACTOR times faster than wall time (0 < FACTOR <= 1000).
    #[arg(long, default_value_t = 1.0, value_name = "FACTOR", allow_negative_numbers = true)]
    pub speed: f64,
    /// Extra link, repeatable: udpout:HOST:PORT (send there) or udpin:HOST:PORT (listen there).
    #[arg(long = "link", value_name = "udpout:HOST:PORT|udpin:HOST:PORT")]
    pub links: Vec<String>,
    /// Where parameters and plans persist: a lone vehicle's own directory
    /// (default rotorpilot-state/N); with --count or --fleet, the root of one
    /// directory per vehicle, DIR/N for instance N (default rotorpilot-state).
    #[arg(long, value_name = "DIR")]
    pub state_dir: Option<PathBuf>,
    /// Start from default parameters (the saved file is overwritten).
    #[arg(long)]
    pub reset_params: bool,
    /// Start with no mission, geofence or rally points (the saved file is overwritten).
    #[arg(long)]
    pub reset_plans: bool,
    /// Override the GCS link's bind address (default 0.0.0.0:18570+N).
    #[arg(long, value_name = "HOST:PORT")]
    pub gcs_bind: Option<String>,
    /// Override the GCS link's remote, or `none` (default 127.0.0.1:14550).
    #[arg(long, value_name = "HOST:PORT")]
    pub gcs_remote: Option<String>,
    /// Override the API link's bind address (default 0.0.0.0:14580+N).
    #[arg(long, value_name = "HOST:PORT")]
    pub api_bind: Option<String>,
    /// Override the API link's remote, or `none` (default 127.0.0.1:14540+N).
    #[arg(long, value_name = "HOST:PORT")]
    pub api_remote: Option<String>,
    /// Write this run's flight record (for `rotorpilot replay`), ULog and
    /// per-link .tlog files into a new directory below DIR (default: no logs).
    #[arg(long, value_name = "DIR")]
    pub log_dir: Option<PathBuf>,
    /// With --log-dir: also write the per-step flight CSV (as `simulate --csv`).
    #[arg(long, requires = "log_dir")]
    pub log_csv: bool,
    /// Run N vehicles in one process on one simulated clock: instances
    /// K..K+N-1 (K = --instance), each exactly as `--instance i` runs alone
    /// (system id i+1, PX4's ports for i, state in --state-dir/i), spawned
    /// 3 m x i north of --home as PX4's sitl_multiple_run.sh spawns them.
    /// --count 1 is a fleet of one, spawned 3 m x K north. Every option
    /// applies to each vehicle, except --gcs-bind, --api-bind and --link.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=250))]
    pub count: Option<u32>,
    /// Run the fleet a TOML file describes: [[vehicle]] entries with an
    /// instance and optionally airframe, offset_m = [NORTH, EAST], params =
    /// { NAME = value }, count and spacing_m = [NORTH, EAST] (as a headless
    /// fleet file places its vehicles); optional top-level home = [LAT, LON, ALT]
    /// and proximity_m. Command-line options apply to every vehicle, as with
    /// --count (--airframe to the entries that name none); --home and
    /// --proximity override the file's.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["count", "instance"])]
    pub fleet: Option<PathBuf>,
    /// Report two vehicles of the fleet closer than M metres (default 2).
    #[arg(long, value_name = "M")]
    pub proximity: Option<f64>,
    /// Print the vehicles these options run (instance, system id, airframe,
    /// spawn point, links, state directory, parameters set) and exit
    /// without starting any, after the checks a start makes before it
    /// reads a state directory or binds a socket (speed, instances,
    /// airframes, parameters): checks a fleet file or a command line.
    #[arg(long)]
    pub check: bool,
}

impl DaemonArgs {
    /// The daemon configuration these options describe.
    ///
    /// # Errors
    /// A malformed home, link or address.
    pub fn config(&self) -> anyhow::Result<Config> {
        let mut c = Config::px4_sitl(self.instance);
        c.airframe.clone_from(&self.airframe);
        if let Some(h) = &self.home {
            c.home = parse_home(h)?;
        }
        c.speed = self.speed;
        if let Some(d) = &self.state_dir {
            c.state_dir.clone_from(d);
        }
        c.reset_params = self.reset_params;
        c.reset_plans = self.reset_plans;
        c.log_dir.clone_from(&self.log_dir);
        c.log_csv = self.log_csv;
        let remote = |flag: &str, s: &str| -> anyhow::Result<Option<std::net::SocketAddr>> {
            if s == "none" {
                Ok(None)
            } else {
                address(flag, s).map(Some)
            }
        };
        if let Some(b) = &self.gcs_bind {
            c.links[0].bind = address("--gcs-bind", b)?;
        }
        if let Some(r) = &self.gcs_remote {
            c.links[0].remote = remote("--gcs-remote", r)?;
        }
        if let Some(b) = &self.api_bind {
            c.links[1].bind = address("--api-bind", b)?;
        }
        if let Some(r) = &self.api_remote {
            c.links[1].remote = remote("--api-remote", r)?;
        }
        for l in &self.links {
            c.links.push(LinkSpec::parse(l)?);
        }
        Ok(c)
    }

    /// The vehicles these options describe: the lone vehicle of
    /// [`Self::config`] without --count and --fleet, else the fleet
    /// ([`FleetConfig`]).
    ///
    /// # Errors
    /// As [`Self::config`]; with a fleet, an option that names one vehicle's
    /// socket, instances beyond the system ids, an airframe that does not
    /// load, a fleet file's errors (file, field with its line, problem).
    pub fn fleet_config(&self) -> anyhow::Result<FleetConfig> {
        if let Some(m) = self.proximity {
            anyhow::ensure!(
                m.is_finite() && m > 0.0,
                "--proximity must be a finite distance > 0 m, got {m}"
            );
        }
        let fleet = match (&self.fleet, self.count) {
            (None, None) => {
                let mut f = FleetConfig::lone(self.config()?);
                f.proximity_m = self.proximity.unwrap_or(f.proximity_m);
                return Ok(f);
            }
            (Some(_), _) => "--fleet",
            (None, Some(_)) => "--count",
        };
        for (given, flag) in [
            (self.gcs_bind.is_some(), "--gcs-bind"),
            (self.api_bind.is_some(), "--api-bind"),
            (!self.links.is_empty(), "--link"),
        ] {
            anyhow::ensure!(
                !given,
                "{flag} cannot be used with {fleet}: it names one vehicle's socket, and a fleet binds \
                 PX4's ports for each instance i (GCS 18570+i, API 14580+i); --gcs-remote and \
                 --api-remote apply to every vehicle"
            );
        }
        let remote = |flag: &str, s: Option<&str>| -> anyhow::Result<Remote> {
            Ok(match s {
                None => Remote::Px4,
                Some("none") => Remote::Nowhere,
                Some(a) => Remote::To(address(flag, a)?),
            })
        };
        let opts = FleetOptions {
            base: self.config()?,
            gcs_remote: remote("--gcs-remote", self.gcs_remote.as_deref())?,
            api_remote: remote("--api-remote", self.api_remote.as_deref())?,
            state_root: self.state_dir.clone().unwrap_or_else(|| DEFAULT_STATE_ROOT.into()),
            home: self.home.as_deref().map(parse_home).transpose()?,
            proximity_m: self.proximity,
        };
        match &self.fleet {
            Some(path) => Ok(FleetConfig::from_file(path, &opts)?),
            None => FleetConfig::counted(&opts, self.instance, self.count.unwrap_or(1)),
        }
    }
}

/// The address an option gives, its error naming the option and what it takes.
fn address(flag: &str, s: &str) -> anyhow::Result<std::net::SocketAddr> {
    let takes = if flag.ends_with("-remote") {
        "HOST:PORT or none"
    } else {
        "HOST:PORT"
    };
    resolve(s).map_err(|e| anyhow::anyhow!("{flag} takes {takes}: {}", crate::error::error_chain(&e)))
}

/// Run the vehicle until Ctrl-C or SIGTERM (or a client's shutdown command).
pub(super) fn run(args: &DaemonArgs) -> anyhow::Result<()> {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env()
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("info"));
    // A second call (tests running several daemons) keeps the first subscriber.
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_target(false)
        .try_init();
    let fleet = args.fleet_config()?;
    // The links share one thread (no cross-thread wake-ups: an idle vehicle
    // stays cheap); the simulation has its own thread (see `daemon`).
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
    rt.block_on(async {
        let daemon = crate::daemon::bind_fleet(fleet).await?;
        for w in daemon.warnings() {
            eprintln!("rotorpilot: {w}");
        }
        println!("{}", daemon.summary());
        daemon.run(shutdown_signal()).await
    })
}

/// Ctrl-C or SIGTERM.
async fn shutdown_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        match signal(SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = tokio::signal::ctrl_c() => {}
                    _ = term.recv() => {}
                }
            }
            Err(_) => {
                let _ = tokio::signal::ctrl_c().await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = tokio::signal::ctrl_c().await;
    }
}
