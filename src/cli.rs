//! Command-line interface: `rotorpilot <command>`.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::airframe::{Airframe, AirframeReport, DEFAULT_AIRFRAME};

/// rotorpilot: software-in-the-loop multirotor autopilot.
#[derive(Debug, Parser)]
#[command(name = "rotorpilot", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Print an airframe's allocation matrix, ranks, degrees of freedom, hover
    /// rotor speeds and single-rotor-failure verdicts.
    Airframe {
        /// Built-in airframe name (quad, hexa, octo, fsr-quad) or path to a TOML file.
        #[arg(default_value = DEFAULT_AIRFRAME)]
        airframe: String,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Fly a scenario file flat out in lockstep and print a summary.
    Simulate {
        /// Scenario TOML (see tools/scenarios/).
        scenario: std::path::PathBuf,
        /// Print the summary as one JSON object.
        #[arg(long)]
        json: bool,
        /// Write the full time series to this CSV file.
        #[arg(long)]
        csv: Option<std::path::PathBuf>,
    },
    /// Run the momentum-based estimator over a recorded flight for several
    /// orders and polynomials; write the estimates as CSV and print metrics.
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
        /// Airframe whose nominal mass and inertia the estimator assumes.
        #[arg(long, default_value = "fsr-quad")]
        airframe: String,
        /// Nominal mass [kg] (overrides the airframe's).
        #[arg(long)]
        mass: Option<f64>,
        /// Nominal inertia diagonal Ixx,Iyy,Izz [kg m^2] (overrides the airframe's).
        #[arg(long, value_delimiter = ',', num_args = 3)]
        inertia: Option<Vec<f64>>,
        /// Where to write the estimates (default: LOG with `-estimates.csv`).
        #[arg(long)]
        output: Option<std::path::PathBuf>,
        /// Print a JSON list, one object per order and polynomial.
        #[arg(long)]
        json: bool,
    },
}

/// Run the CLI; errors are printed to stderr and give exit code 1.
#[must_use]
pub fn run(cli: Cli) -> ExitCode {
    match execute(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("rotorpilot: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn execute(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Some(Command::Airframe { airframe, json }) => {
            let a = Airframe::load(&airframe)?;
            let report = AirframeReport::new(&a);
            if json {
                println!("{}", serde_json::to_string_pretty(&report)?);
            } else {
                print!("{}", report.to_text());
            }
            Ok(())
        }
        Some(Command::Simulate { scenario, json, csv }) => simulate(&scenario, json, csv.as_deref()),
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
            let mut nominal = Airframe::load(&airframe)?.nominal();
            if let Some(m) = mass {
                anyhow::ensure!(m.is_finite() && m > 0.0, "--mass must be a finite number > 0, got {m}");
                nominal.mass_kg = m;
            }
            if let Some(i) = inertia {
                anyhow::ensure!(
                    i.iter().all(|x| x.is_finite() && *x > 0.0),
                    "--inertia must be three numbers > 0, got {i:?}"
                );
                nominal.inertia_kg_m2 = nalgebra::Matrix3::from_diagonal(&nalgebra::Vector3::new(i[0], i[1], i[2]));
            }
            let polys = poly
                .iter()
                .map(|p| crate::flightlog::parse_poly(p))
                .collect::<Result<Vec<_>, _>>()
                .map_err(|e| anyhow::anyhow!("--poly: {e}"))?;
            let disc = if euler {
                crate::estimation::Discretization::ForwardEuler
            } else {
                crate::estimation::Discretization::Trapezoidal
            };
            estimate(&log, &order, &polys, cutoff, disc, nominal, output.as_deref(), json)
        }
        None => {
            anyhow::bail!("no command given; try `rotorpilot --help` (the MAVLink daemon is not built yet)")
        }
    }
}

fn simulate(path: &std::path::Path, json: bool, csv: Option<&std::path::Path>) -> anyhow::Result<()> {
    use anyhow::Context as _;
    use std::io::Write as _;
    let scenario = crate::scenario::Scenario::from_file(path)?;
    let mut writer = match csv {
        Some(p) => Some(std::io::BufWriter::new(
            std::fs::File::create(p).with_context(|| format!("cannot create {}", p.display()))?,
        )),
        None => None,
    };
    let start = std::time::Instant::now();
    let mut summary = crate::scenario::run(&scenario, writer.as_mut().map(|w| w as &mut dyn std::io::Write))?;
    summary.wall_time_s = start.elapsed().as_secs_f64();
    if let Some(mut w) = writer {
        w.flush().context("writing the CSV")?;
    }
    if json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print!("{}", summary.to_text());
    }
    Ok(())
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
    let log = crate::flightlog::FlightLog::from_file(path)?;
    let cells: Vec<_> = polys
        .iter()
        .flat_map(|p| {
            orders
                .iter()
                .map(move |r| crate::flightlog::sweep_config(*r, p.clone(), cutoff, log.step_s, disc))
        })
        .collect();
    for c in &cells {
        c.gains()
            .map_err(|e| anyhow::anyhow!("order {} {:?}: {e}", c.order, c.polynomial))?;
    }
    let bar = indicatif::ProgressBar::new(cells.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{msg:>20} [{bar:30}] {pos}/{len} ({elapsed})")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut results = Vec::new();
    let mut series = Vec::new();
    for c in &cells {
        bar.set_message(format!("r = {} {:?}", c.order, c.polynomial));
        let est = crate::flightlog::estimate_log(&log, c.clone(), nominal)?;
        results.push(crate::flightlog::sweep_result(&log, c, &nominal, &est));
        series.push(est);
        bar.inc(1);
    }
    bar.finish_and_clear();

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
    let mut header = vec!["time_s".to_string()];
    for r in &results {
        for ch in [
            "fn", "fe", "fd", "tx", "ty", "tz", "t_roll", "t_pitch", "t_yaw", "mass_kg",
        ] {
            header.push(format!("{}{}_{ch}", r.poly, r.order));
        }
    }
    writeln!(w, "{}", header.join(","))?;
    for (k, row) in log.rows.iter().enumerate() {
        let mut fields = vec![format!("{}", row.input.time_s)];
        for s in &series {
            let e = &s[k];
            for v in e.force_ned.iter().chain(e.torque_frd.iter()).chain(e.torque_rpy.iter()) {
                fields.push(format!("{v}"));
            }
            fields.push(format!("{}", e.mass_kg));
        }
        writeln!(w, "{}", fields.join(","))?;
    }
    w.flush().context("writing the estimates")?;

    if json {
        println!("{}", serde_json::to_string_pretty(&results)?);
        return Ok(());
    }
    println!(
        "{}: {} rows, step {} s; nominal mass {} kg; estimates written to {}",
        path.display(),
        log.rows.len(),
        log.step_s,
        nominal.mass_kg,
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
