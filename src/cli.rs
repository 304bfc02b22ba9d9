//! Command-line interface: `rotorpilot <command>`.

pub mod params;
mod replay;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::airframe::{Airframe, AirframeReport, DEFAULT_AIRFRAME};

/// rotorpilot: software-in-the-loop multirotor autopilot.
///
/// Without a command it runs one simulated vehicle that speaks MAVLink 2 over
/// UDP where PX4 SITL does (GCS link 18570+N -> 14550, API link 14580+N ->
/// 14540+N; all API links beyond instance 9 send to 14549, as PX4), until
/// Ctrl-C or SIGTERM; with --count N or --fleet FILE, a fleet of such
/// vehicles in one process on one simulated clock.
#[derive(Debug, Parser)]
#[command(name = "rotorpilot", version, about, args_conflicts_with_subcommands = true)]
pub struct Cli {
    /// What to do (none: run the vehicle).
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Options of the vehicle daemon.
    #[command(flatten)]
    pub daemon: DaemonArgs,
}

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
    pub state_dir: Option<std::path::PathBuf>,
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
    pub log_dir: Option<std::path::PathBuf>,
    /// With --log-dir: also write the per-step flight CSV (as `simulate --csv`).
    #[arg(long, requires = "log_dir")]
    pub log_csv: bool,
    /// Run N vehicles in one process on one simulated clock: instances
    /// K..K+N-1 (K = --instance), each exactly as `--instance i` runs alone
    /// (system id i+1, PX4's ports for i, state in --state-dir/i), spawned
    /// 3 m x i north of --home as PX4's sitl_multiple_run.sh spawns them.
    /// --count 1 is a fleet of one, spawned 3 m x K north. Every option
    /// applies to each vehicle, except --gcs-bind, --api-bind and --link.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub count: Option<u32>,
    /// Run the fleet a TOML file describes: [[vehicle]] entries with an
    /// instance and optionally airframe, offset_m = [NORTH, EAST], params =
    /// { NAME = value } and count; optional top-level home = [LAT, LON, ALT]
    /// and proximity_m. Command-line options apply to every vehicle, as with
    /// --count (--airframe to the entries that name none); --home and
    /// --proximity override the file's.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["count", "instance"])]
    pub fleet: Option<std::path::PathBuf>,
    /// Report two vehicles of the fleet closer than M metres (default 2).
    #[arg(long, value_name = "M")]
    pub proximity: Option<f64>,
    /// Print the vehicles these options run (instance, system id, airframe,
    /// spawn point, links, state directory, parameters set) and exit
    /// without starting any: checks a fleet file.
    #[arg(long)]
    pub check: bool,
}

impl DaemonArgs {
    /// The daemon configuration these options describe.
    ///
    /// # Errors
    /// A malformed home, link or address.
    pub fn config(&self) -> anyhow::Result<crate::daemon::Config> {
        use crate::daemon::{Config, LinkSpec, parse_home, resolve};
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
        let remote = |s: &str| -> anyhow::Result<Option<std::net::SocketAddr>> {
            if s == "none" { Ok(None) } else { resolve(s).map(Some) }
        };
        if let Some(b) = &self.gcs_bind {
            c.links[0].bind = resolve(b)?;
        }
        if let Some(r) = &self.gcs_remote {
            c.links[0].remote = remote(r)?;
        }
        if let Some(b) = &self.api_bind {
            c.links[1].bind = resolve(b)?;
        }
        if let Some(r) = &self.api_remote {
            c.links[1].remote = remote(r)?;
        }
        for l in &self.links {
            c.links.push(LinkSpec::parse(l)?);
        }
        Ok(c)
    }

    /// The vehicles these options describe: the lone vehicle of
    /// [`Self::config`] without --count and --fleet, else the fleet
    /// ([`crate::daemon::FleetConfig`]).
    ///
    /// # Errors
    /// As [`Self::config`]; with a fleet, an option that names one vehicle's
    /// socket, instances beyond the system ids, an airframe that does not
    /// load, a fleet file's errors (file, field with its line, problem).
    pub fn fleet_config(&self) -> anyhow::Result<crate::daemon::FleetConfig> {
        use crate::daemon::{DEFAULT_STATE_ROOT, FleetConfig, FleetOptions, Remote, parse_home, resolve};
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
        let remote = |s: Option<&str>| -> anyhow::Result<Remote> {
            Ok(match s {
                None => Remote::Px4,
                Some("none") => Remote::Nowhere,
                Some(a) => Remote::To(resolve(a)?),
            })
        };
        let opts = FleetOptions {
            base: self.config()?,
            gcs_remote: remote(self.gcs_remote.as_deref())?,
            api_remote: remote(self.api_remote.as_deref())?,
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

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Print an airframe's allocation matrix, ranks, degrees of freedom, hover
    /// rotor speeds and single-rotor-failure verdicts.
    Airframe {
        /// Built-in airframe name (quad, hexa, hexa-ppnnpn, octo, fsr-quad) or path to a TOML file.
        #[arg(default_value = DEFAULT_AIRFRAME)]
        airframe: String,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Fly a scenario or a mission flat out in lockstep and print a summary
    /// (for a mission: each item reached, when and how far off, and a
    /// pass/fail verdict; the exit status is 1 on fail). Several files, a
    /// directory or a [campaign] table make a campaign: flown on every core,
    /// one line per scenario, optionally one shard of it (exit status 2 when
    /// a file or variant cannot be read or flown).
    Simulate(crate::simulate::SimulateArgs),
    /// Run the momentum-based estimator over a recorded flight for several
    /// orders and polynomials; write the estimates as CSV and print metrics.
    /// The nominal model is the one the log's sidecar LOG.meta.json records
    /// (docs/logs.md). Time must increase; the step may vary (each sample is
    /// integrated over its own interval).
    Estimate {
        /// Flight log CSV (as `rotorpilot simulate --csv` writes it).
        log: std::path::PathBuf,
        /// Orders r to run (comma-separated, 1..=20).
        #[arg(long, value_delimiter = ',', default_value = "1,2,3,5,10,20")]
        order: Vec<usize>,
        /// Polynomials (comma-separated): butterworth, binomial.
        #[arg(long, value_delimiter = ',', default_value = "butterworth")]
        poly: Vec<String>,
        /// Cutoff omega_c [rad/s].
        #[arg(long, default_value_t = 10.0)]
        cutoff: f64,
        /// Forward Euler instead of the trapezoidal rule.
        #[arg(long)]
        euler: bool,
        /// Airframe whose nominal mass and inertia the estimator assumes
        /// (default: the one the log's sidecar LOG.meta.json records; without
        /// a sidecar, fsr-quad, with a warning).
        #[arg(long)]
        airframe: Option<String>,
        /// Nominal mass [kg] (overrides the sidecar's or the airframe's).
        #[arg(long, value_name = "KG")]
        mass: Option<f64>,
        /// Nominal inertia diagonal [kg m^2], body FRD, e.g. 0.03,0.03,0.05
        /// (overrides the sidecar's or the airframe's).
        #[arg(long, value_name = "IXX,IYY,IZZ")]
        inertia: Option<String>,
        /// Where to write the estimates (default: LOG with `-estimates.csv`).
        #[arg(long)]
        output: Option<std::path::PathBuf>,
        /// Print a JSON list, one object per order and polynomial.
        #[arg(long)]
        json: bool,
    },
    /// Re-fly a daemon's flight record (`flight.record` in its `--log-dir`
    /// run directory) headless and flat out, bit for bit: `--csv` writes the
    /// same per-step CSV as the live flight's `flight.csv`.
    Replay {
        /// The flight record.
        record: std::path::PathBuf,
        /// Write the per-step CSV (`simulate --csv`'s format) here.
        #[arg(long)]
        csv: Option<std::path::PathBuf>,
        /// Print the summary as one JSON object.
        #[arg(long)]
        json: bool,
        /// Write the replayed flight's PX4 ULog (the topics of the daemon's
        /// `flight.ulg`) here.
        #[arg(long)]
        ulog: Option<std::path::PathBuf>,
        /// Replay a record written by another rotorpilot version (with a
        /// warning) instead of refusing it.
        #[arg(long)]
        any_version: bool,
    },
    /// Print the parameter reference (every parameter: type, default, range,
    /// unit, description, values, reboot required) as text, JSON or Markdown.
    Params(params::ParamsArgs),
}

/// Run the CLI; errors are printed to stderr and give exit code 1.
#[must_use]
pub fn run(cli: Cli) -> ExitCode {
    match execute(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rotorpilot: {}", error_chain(&e));
            ExitCode::FAILURE
        }
    }
}

/// An error and its causes as one line, `outer: cause: cause` (as anyhow's
/// `{:#}`), each cause left out when the text so far already says it (an
/// error whose message quotes its source, e.g. `file X: Not a directory (os
/// error 20)`, would otherwise print its cause twice).
#[must_use]
pub fn error_chain(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let c = cause.to_string();
        if text.is_empty() {
            text = c;
        } else if !text.contains(&c) {
            text.push_str(": ");
            text.push_str(&c);
        }
    }
    text
}

fn execute(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Some(Command::Airframe { airframe, json }) => {
            let a = Airframe::load(&airframe)?;
            // the airframe file's [control] table is the control laws' to check
            crate::control::ControlGains::for_airframe(&a, a.mass_kg)
                .map_err(|e| anyhow::anyhow!("{}: {e}", a.source))?;
            let report = AirframeReport::new(&a);
            if json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                print!("{}", report.to_text());
            }
            Ok(())
        }
        Some(Command::Simulate(args)) => match crate::simulate::main(&args) {
            0 => Ok(()),
            // 1: a mission failed its verdict, 2: a scenario could not be read or flown (printed)
            status => std::process::exit(i32::from(status)),
        },
        Some(Command::Estimate {
            log,
            order,
            poly,
            cutoff,
            euler,
            airframe,
            mass,
            inertia,
            output,
            json,
        }) => {
            let nominal = estimate_nominal(&log, airframe.as_deref(), mass, inertia.as_deref())?;
            let polys = poly
                .iter()
                .map(|p| crate::estimation::sweep::parse_poly(p))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| anyhow::anyhow!("--poly: {e}"))?;
            let disc = if euler {
                crate::estimation::Discretization::ForwardEuler
            } else {
                crate::estimation::Discretization::Trapezoidal
            };
            estimate(&log, &order, &polys, cutoff, disc, nominal, output.as_deref(), json)
        }
        Some(Command::Replay {
            record,
            csv,
            ulog,
            json,
            any_version,
        }) => replay::run(&record, csv.as_deref(), ulog.as_deref(), json, any_version),
        Some(Command::Params(args)) => params::run(&args),
        None if cli.daemon.check => {
            print!("{}", cli.daemon.fleet_config()?.to_text());
            Ok(())
        }
        None => run_daemon(&cli.daemon),
    }
}

/// Run the vehicle until Ctrl-C or SIGTERM (or a client's shutdown command).
fn run_daemon(args: &DaemonArgs) -> anyhow::Result<()> {
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

/// One estimator run per cell over `log`, with its metrics, in the order of
/// `cells`: each run on a thread of its own (they are independent), so a
/// sweep uses every core; `bar` counts finished runs.
fn run_cells(
    log: &crate::logs::csv::FlightLog,
    cells: &[crate::estimation::EstimatorConfig],
    nominal: &crate::signals::NominalModel,
    bar: &indicatif::ProgressBar,
) -> anyhow::Result<
    Vec<(
        crate::estimation::sweep::SweepResult,
        Vec<crate::signals::WrenchEstimate>,
    )>,
> {
    let run = |c: &crate::estimation::EstimatorConfig| {
        let est = crate::estimation::sweep::estimate_log(&log.rows, c.clone(), *nominal)?;
        bar.inc(1);
        Ok((crate::estimation::sweep::sweep_result(&log.rows, c, nominal, &est), est))
    };
    std::thread::scope(|scope| {
        let handles: Vec<_> = cells.iter().map(|c| scope.spawn(move || run(c))).collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    })
}

/// The airframe `estimate` assumes for a log without a sidecar (the origin report's).
const ESTIMATE_FALLBACK_AIRFRAME: &str = "fsr-quad";

/// The nominal model `estimate` runs with: `--airframe`'s, else the log's
/// sidecar's ([`crate::logs::meta::LogMeta`]), else [`ESTIMATE_FALLBACK_AIRFRAME`]'s
/// with a warning on stderr (unless `--mass` and `--inertia` give it all);
/// then `--mass` and `--inertia` override.
///
/// # Errors
/// An unreadable or invalid sidecar, an unknown airframe, a bad `--mass` or `--inertia`.
fn estimate_nominal(
    log: &std::path::Path,
    airframe: Option<&str>,
    mass: Option<f64>,
    inertia: Option<&str>,
) -> anyhow::Result<crate::signals::NominalModel> {
    let inertia = inertia.map(parse_inertia).transpose()?;
    if let Some(m) = mass {
        anyhow::ensure!(
            m.is_finite() && m > 0.0,
            "--mass must be a finite number > 0 kg, got {m}"
        );
    }
    let mut nominal = match airframe {
        Some(a) => Airframe::load(a)?.nominal(),
        None => match crate::logs::meta::LogMeta::read_beside(log).map_err(anyhow::Error::msg)? {
            Some(meta) => meta.nominal(),
            None => {
                let n = Airframe::load(ESTIMATE_FALLBACK_AIRFRAME)?.nominal();
                if mass.is_none() || inertia.is_none() {
                    let i = n.inertia_kg_m2;
                    eprintln!(
                        "rotorpilot: warning: {} has no sidecar {} saying what flew it: assuming the \
                         {ESTIMATE_FALLBACK_AIRFRAME} airframe's nominal mass {} kg and inertia {},{},{} kg m^2; \
                         a wrong mass shows as a false vertical force. Give --airframe NAME, or --mass KG and \
                         --inertia IXX,IYY,IZZ",
                        log.display(),
                        crate::logs::meta::meta_path(log).display(),
                        n.mass_kg,
                        i[(0, 0)],
                        i[(1, 1)],
                        i[(2, 2)]
                    );
                }
                n
            }
        },
    };
    if let Some(m) = mass {
        nominal.mass_kg = m;
    }
    if let Some(i) = inertia {
        nominal.inertia_kg_m2 = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::from(i));
    }
    Ok(nominal)
}

/// `--inertia IXX,IYY,IZZ` [kg m^2]: three numbers > 0, separated by commas
/// (or spaces, in one quoted argument).
///
/// # Errors
/// Not three finite numbers > 0 (the message quotes the argument).
fn parse_inertia(text: &str) -> anyhow::Result<[f64; 3]> {
    let values: Vec<Option<f64>> = text
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| t.parse::<f64>().ok().filter(|v| v.is_finite() && *v > 0.0))
        .collect();
    match values.as_slice() {
        [Some(x), Some(y), Some(z)] => Ok([*x, *y, *z]),
        _ => anyhow::bail!(
            "--inertia `{text}`: expected the diagonal IXX,IYY,IZZ as three numbers > 0 kg m^2 separated by commas, \
             e.g. --inertia 0.03,0.03,0.05"
        ),
    }
}

#[allow(clippy::too_many_arguments)]
fn estimate(
    path: &std::path::Path,
    orders: &[usize],
    polys: &[crate::estimation::Polynomial],
    cutoff: f64,
    disc: crate::estimation::Discretization,
    nominal: crate::signals::NominalModel,
    output: Option<&std::path::Path>,
    json: bool,
) -> anyhow::Result<()> {
    use anyhow::Context as _;
    use std::io::Write as _;
    let log = crate::logs::csv::FlightLog::from_file(path)?;
    let cells: Vec<_> = polys
        .iter()
        .flat_map(|p| {
            orders
                .iter()
                .map(move |r| crate::estimation::sweep::sweep_config(*r, p.clone(), cutoff, log.step_s, disc))
        })
        .collect();
    let (_, max_step) = log.step_range();
    for c in &cells {
        // the estimator takes each sample's own step: it must be stable at the largest
        let widest = crate::estimation::EstimatorConfig {
            sample_time_s: max_step.max(c.sample_time_s),
            ..c.clone()
        };
        for c in [c, &widest] {
            c.gains()
                .map_err(|e| anyhow::anyhow!("order {} {:?}: {e}", c.order, c.polynomial))?;
        }
    }
    let bar = indicatif::ProgressBar::new(cells.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg:>20} [{bar:30}] {pos}/{len} ({elapsed})")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_message(format!("{} runs", cells.len()));
    let runs = run_cells(&log, &cells, &nominal, &bar)?;
    bar.finish_and_clear();
    let (results, series): (Vec<_>, Vec<_>) = runs
        .into_iter()
        .map(|(result, est)| {
            let label = format!("{}{}", result.poly, result.order);
            (result, (label, est))
        })
        .unzip();

    let out_path = output.map_or_else(
        || {
            let stem = path
                .file_stem()
                .map_or_else(|| "log".into(), |s| s.to_string_lossy().into_owned());
            path.with_file_name(format!("{stem}-estimates.csv"))
        },
        std::path::Path::to_path_buf,
    );
    let mut w = std::io::BufWriter::new(
        std::fs::File::create(&out_path).with_context(|| format!("cannot create {}", out_path.display()))?,
    );
    crate::logs::csv::write_estimates(&mut w, &log, &series).context("writing the estimates")?;
    w.flush().context("writing the estimates")?;

    if json {
        println!("{}", serde_json::to_string_pretty(&results)?);
        return Ok(());
    }
    let step = if log.is_regular() {
        format!("step {} s", log.step_s)
    } else {
        let (lo, hi) = log.step_range();
        format!("step varying {lo:.4e}..{hi:.4e} s (each sample integrated over its own)")
    };
    let i = nominal.inertia_kg_m2;
    println!(
        "{}: {} rows, {step}; nominal mass {} kg, inertia {},{},{} kg m^2; estimates written to {}",
        path.display(),
        log.rows.len(),
        nominal.mass_kg,
        i[(0, 0)],
        i[(1, 1)],
        i[(2, 2)],
        out_path.display()
    );
    println!(
        "{:>12} {:>3} {:>9} {:>8} {:>10} {:>10}  {:>27}  {:>9}",
        "poly", "r", "settle_s", "OS_%", "rms_f_N", "rms_t_Nm", "final force NED [N]", "mass_kg"
    );
    let opt = |v: Option<f64>, p: usize| v.map_or_else(|| "-".to_string(), |x| format!("{x:.p$}"));
    for r in &results {
        println!(
            "{:>12} {:>3} {:>9} {:>8} {:>10} {:>10}  [{:>7.4}, {:>7.4}, {:>8.4}]  {:>9.5}",
            r.poly,
            r.order,
            opt(r.settle_s, 3),
            opt(r.overshoot_pct, 1),
            opt(r.rms_force_error_n, 4),
            opt(r.rms_torque_error_n_m, 4),
            r.final_force_ned[0],
            r.final_force_ned[1],
            r.final_force_ned[2],
            r.mass_kg
        );
    }
    Ok(())
}
