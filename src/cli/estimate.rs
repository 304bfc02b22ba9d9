//! `rotorpilot estimate LOG`: the momentum-based estimator over a recorded
//! flight's CSV for several orders and polynomials, each run on a thread of
//! its own; the estimates written as CSV, the metrics printed. The nominal
//! model is the one the log's sidecar records, unless the options say
//! otherwise.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context as _;

use crate::airframe::Airframe;
use crate::estimation::sweep::{SweepResult, estimate_log, sweep_config, sweep_result};
use crate::estimation::{Discretization, EstimatorConfig, Polynomial};
use crate::logs::csv::{FlightLog, write_estimates};
use crate::logs::meta::{LogMeta, meta_path};
use crate::signals::{NominalModel, WrenchEstimate};

/// The arguments of `rotorpilot estimate`.
#[derive(Debug, Clone, clap::Args)]
pub struct EstimateArgs {
    /// Flight log CSV (as `rotorpilot simulate --csv` writes it).
    pub log: PathBuf,
    /// Orders r to run (comma-separated, 1..=20).
    #[arg(long, value_delimiter = ',', default_value = "1,2,3,5,10,20")]
    pub order: Vec<usize>,
    /// Polynomials (comma-separated): butterworth, binomial.
    #[arg(long, value_delimiter = ',', default_value = "butterworth")]
    pub poly: Vec<String>,
    /// Cutoff omega_c [rad/s].
    #[arg(long, default_value_t = 10.0)]
    pub cutoff: f64,
    /// Forward Euler instead of the trapezoidal rule.
    #[arg(long)]
    pub euler: bool,
    /// Airframe whose nominal mass and inertia the estimator assumes
    /// (default: the one the log's sidecar LOG.meta.json records; without
    /// a sidecar, fsr-quad, with a warning).
    #[arg(long)]
    pub airframe: Option<String>,
    /// Nominal mass [kg] (overrides the sidecar's or the airframe's).
    #[arg(long, value_name = "KG")]
    pub mass: Option<f64>,
    /// Nominal inertia diagonal [kg m^2], body FRD, e.g. 0.03,0.03,0.05
    /// (overrides the sidecar's or the airframe's).
    #[arg(long, value_name = "IXX,IYY,IZZ")]
    pub inertia: Option<String>,
    /// Where to write the estimates (default: LOG with `-estimates.csv`).
    #[arg(long)]
    pub output: Option<PathBuf>,
    /// Print a JSON list, one object per order and polynomial.
    #[arg(long)]
    pub json: bool,
}

/// Run `rotorpilot estimate`.
///
/// # Errors
/// A bad option, an unreadable log or sidecar, an unstable estimator, an
/// estimates file that cannot be written.
pub(super) fn run(args: &EstimateArgs) -> anyhow::Result<()> {
    let nominal = estimate_nominal(&args.log, args.airframe.as_deref(), args.mass, args.inertia.as_deref())?;
    let polys = args
        .poly
        .iter()
        .map(|p| crate::estimation::sweep::parse_poly(p))
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| anyhow::anyhow!("--poly: {e}"))?;
    let disc = if args.euler {
        Discretization::ForwardEuler
    } else {
        Discretization::Trapezoidal
    };
    estimate(
        &args.log,
        &args.order,
        &polys,
        args.cutoff,
        disc,
        nominal,
        args.output.as_deref(),
        args.json,
    )
}

/// One estimator run per cell over `log`, with its metrics, in the order of
/// `cells`: each run on a thread of its own (they are independent), so a
/// sweep uses every core; `bar` counts finished runs.
fn run_cells(
    log: &FlightLog,
    cells: &[EstimatorConfig],
    nominal: &NominalModel,
    bar: &indicatif::ProgressBar,
) -> anyhow::Result<Vec<(SweepResult, Vec<WrenchEstimate>)>> {
    let run = |c: &EstimatorConfig| {
        let est = estimate_log(&log.rows, c.clone(), *nominal)?;
        bar.inc(1);
        Ok((sweep_result(&log.rows, c, nominal, &est), est))
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
    log: &Path,
    airframe: Option<&str>,
    mass: Option<f64>,
    inertia: Option<&str>,
) -> anyhow::Result<NominalModel> {
    let inertia = inertia.map(parse_inertia).transpose()?;
    if let Some(m) = mass {
        anyhow::ensure!(
            m.is_finite() && m > 0.0,
            "--mass must be a finite number > 0 kg, got {m}"
        );
    }
    let mut nominal = match airframe {
        Some(a) => Airframe::load(a)?.nominal(),
        None => match LogMeta::read_beside(log).map_err(anyhow::Error::msg)? {
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
                        meta_path(log).display(),
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
    path: &Path,
    orders: &[usize],
    polys: &[Polynomial],
    cutoff: f64,
    disc: Discretization,
    nominal: NominalModel,
    output: Option<&Path>,
    json: bool,
) -> anyhow::Result<()> {
    let log = FlightLog::from_file(path)?;
    let cells: Vec<_> = polys
        .iter()
        .flat_map(|p| {
            orders
                .iter()
                .map(move |r| sweep_config(*r, p.clone(), cutoff, log.step_s, disc))
        })
        .collect();
    let (_, max_step) = log.step_range();
    for c in &cells {
        // the estimator takes each sample's own step: it must be stable at the largest
        let widest = EstimatorConfig {
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
        Path::to_path_buf,
    );
    let mut w = std::io::BufWriter::new(
        std::fs::File::create(&out_path).with_context(|| format!("cannot create {}", out_path.display()))?,
    );
    write_estimates(&mut w, &log, &series).context("writing the estimates")?;
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
