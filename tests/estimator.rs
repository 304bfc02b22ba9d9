//! Momentum-based estimator: gains against doc section 9, discrete step
//! responses against doc section 7's continuous table, and open-loop runs of
//! the fsr-quad plant with a known external wrench and a wrong nominal mass.

use nalgebra::{Complex, DMatrix, DVector, Matrix3, UnitQuaternion, Vector3};
use rotorpilot::airframe::Airframe;
use rotorpilot::estimation::gains::{
    binomial_gains, butterworth_gains, chain_gains, coefficients_from_gains, gains_for, polynomial_coefficients,
};
use rotorpilot::estimation::metrics::step_metrics;
use rotorpilot::estimation::{
    ChainFilter, Discretization, EstimatorConfig, EstimatorError, EstimatorInput, MomentumEstimator, Polynomial,
    input_from, step_response,
};
use rotorpilot::math::{euler_zyx, rate_map};
use rotorpilot::signals::ActuatorCommand;
use rotorpilot::signals::{ControlWrench, GRAVITY};
use rotorpilot::signals::{NominalModel, WrenchEstimate};
use rotorpilot::sim::{ExternalWrench, Plant, PlantConfig, RigidBodyState};

const H: f64 = 1e-3;

fn assert_close(a: &[f64], b: &[f64], tol: f64, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}");
    for (x, y) in a.iter().zip(b) {
        assert!((x - y).abs() <= tol, "{what}: {a:?} vs {b:?}");
    }
}

// ---------------------------------------------------------------- gains

#[test]
fn gains_match_doc_section_9() {
    let k = |p: Polynomial, r| gains_for(&p, r, 10.0).unwrap();
    assert_close(&k(Polynomial::Butterworth, 1), &[10.0], 1e-12, "butterworth r=1");
    assert_close(
        &k(Polynomial::Butterworth, 2),
        &[7.0711, 14.1421],
        5e-5,
        "butterworth r=2",
    );
    assert_close(
        &k(Polynomial::Butterworth, 3),
        &[5.0, 10.0, 20.0],
        1e-12,
        "butterworth r=3",
    );
    assert_close(&k(Polynomial::Binomial, 3), &[3.3333, 10.0, 30.0], 5e-5, "binomial r=3");
    // doc section 7: r = 5 Butterworth omega_c [0.309, 0.618, 1, 1.618, 3.236]
    assert_close(
        &k(Polynomial::Butterworth, 5),
        &[3.09, 6.18, 10.0, 16.18, 32.36],
        5e-3,
        "butterworth r=5",
    );
}

#[test]
fn closed_forms_equal_coefficient_route() {
    for r in 1..=20 {
        for wc in [1.0, 10.0, 25.0] {
            for (poly, closed) in [
                (Polynomial::Butterworth, butterworth_gains(r, wc).unwrap()),
                (Polynomial::Binomial, binomial_gains(r, wc).unwrap()),
            ] {
                let c = polynomial_coefficients(&poly, r, wc).unwrap();
                let route = chain_gains(&c).unwrap();
                for (a, b) in route.iter().zip(&closed) {
                    assert!((a - b).abs() <= 1e-10 * b, "{poly:?} r={r}: {route:?} vs {closed:?}");
                }
                let back = coefficients_from_gains(&closed);
                for (a, b) in back.iter().zip(&c) {
                    assert!((a - b).abs() <= 1e-10 * b, "{poly:?} r={r}: prod K != c");
                }
            }
        }
    }
}

/// The continuous chain `gamma_1' = K_1 (w - gamma_r)`, `gamma_i' = K_i (gamma_{i-1} - gamma_r)`
/// as `x' = A x + B w`, `y = gamma_r`.
fn chain_state_space(k: &[f64]) -> (DMatrix<f64>, DVector<f64>) {
    let r = k.len();
    let mut a = DMatrix::zeros(r, r);
    for i in 0..r {
        if i > 0 {
            a[(i, i - 1)] += k[i];
        }
        a[(i, r - 1)] -= k[i];
    }
    let mut b = DVector::zeros(r);
    b[0] = k[0];
    (a, b)
}

fn eval_poly(c: &[f64], s: Complex<f64>) -> Complex<f64> {
    // s^r + c_{r-1} s^{r-1} + ... + c_0 (Horner)
    let mut acc = Complex::new(1.0, 0.0);
    for cj in c.iter().rev() {
        acc = acc * s + *cj;
    }
    acc
}

/// G(s) rebuilt from the chain equals `c_0 / poly(s)`, its denominator
/// `det(sI - A)` equals the target polynomial, and the DC gain is 1.
#[test]
fn transfer_function_rebuilt_from_chain() {
    for poly in [
        Polynomial::Butterworth,
        Polynomial::Binomial,
        Polynomial::Custom(vec![6.0, 11.0, 6.0]),
    ] {
        for r in [1, 2, 3, 5, 8, 12, 20] {
            let r = if let Polynomial::Custom(c) = &poly {
                if r != 3 {
                    continue;
                }
                c.len()
            } else {
                r
            };
            let wc = 10.0;
            let c = polynomial_coefficients(&poly, r, wc).unwrap();
            let k = gains_for(&poly, r, wc).unwrap();
            let (a, b) = chain_state_space(&k);
            // DC gain: -A^-1 B, last entry
            let x0 = a.clone().lu().solve(&(-&b)).unwrap();
            assert!((x0[r - 1] - 1.0).abs() < 1e-9, "{poly:?} r={r}: DC gain {}", x0[r - 1]);
            for w in [0.0, 0.3, 1.0, 3.0, 10.0, 30.0] {
                let s = Complex::new(0.2, w * wc / 10.0);
                let m: DMatrix<Complex<f64>> = DMatrix::from_fn(r, r, |i, j| {
                    let d = if i == j { s } else { Complex::new(0.0, 0.0) };
                    d - Complex::new(a[(i, j)], 0.0)
                });
                let bc: DVector<Complex<f64>> = b.map(|x| Complex::new(x, 0.0));
                let lu = m.clone().lu();
                let g = lu.solve(&bc).unwrap()[r - 1];
                let target = Complex::new(c[0], 0.0) / eval_poly(&c, s);
                assert!(
                    (g - target).norm() <= 1e-9 * target.norm(),
                    "{poly:?} r={r} s={s}: {g} vs {target}"
                );
                let det = lu.determinant();
                let p = eval_poly(&c, s);
                assert!(
                    (det - p).norm() <= 1e-9 * p.norm(),
                    "{poly:?} r={r} s={s}: det {det} vs {p}"
                );
            }
        }
    }
}

// ---------------------------------------------------------------- discrete step responses

/// Doc section 7 table (units of 1/omega_c): (r, Butterworth OS %, t2%, binomial OS %, t2%).
const STEP_TABLE: [(usize, f64, f64, f64, f64); 6] = [
    (1, 0.0, 3.91, 0.0, 3.91),
    (2, 4.3, 5.96, 0.0, 5.83),
    (3, 8.2, 6.64, 0.0, 7.52),
    (5, 12.8, 10.84, 0.0, 10.58),
    (10, 17.8, 20.57, 0.0, 17.51),
    (20, 21.2, 37.60, 0.0, 30.22),
];

fn metrics_of(poly: &Polynomial, r: usize, d: Discretization) -> (f64, f64) {
    let wc = 10.0;
    let k = gains_for(poly, r, wc).unwrap();
    let n = 8001;
    let y = step_response(&k, d, H, n).unwrap();
    let t: Vec<f64> = (0..n).map(|i| i as f64 * H).collect();
    let m = step_metrics(&t, &y, 0.0, 0.0, 1.0).unwrap();
    (m.overshoot_percent, m.settling_time_s.expect("settles within 8 s"))
}

#[test]
fn trapezoidal_step_response_matches_continuous_table() {
    let wc = 10.0;
    for (r, b_os, b_t2, n_os, n_t2) in STEP_TABLE {
        for (poly, os_doc, t2_doc) in [
            (Polynomial::Butterworth, b_os, b_t2),
            (Polynomial::Binomial, n_os, n_t2),
        ] {
            let (os, t2) = metrics_of(&poly, r, Discretization::Trapezoidal);
            let t2_doc = t2_doc / wc;
            assert!(
                (t2 - t2_doc).abs() <= 0.02 * t2_doc + 0.001,
                "{poly:?} r={r}: t2% {t2:.4} s vs {t2_doc:.4} s"
            );
            assert!(
                (os - os_doc).abs() <= 0.3,
                "{poly:?} r={r}: overshoot {os:.3} % vs {os_doc} %"
            );
        }
    }
}

#[test]
fn forward_euler_is_stable_and_close_at_1_khz() {
    let wc = 10.0;
    for (r, b_os, b_t2, n_os, n_t2) in STEP_TABLE {
        for (poly, os_doc, t2_doc) in [
            (Polynomial::Butterworth, b_os, b_t2),
            (Polynomial::Binomial, n_os, n_t2),
        ] {
            let (os, t2) = metrics_of(&poly, r, Discretization::ForwardEuler);
            let t2_doc = t2_doc / wc;
            // doc section 7: r = 20 Butterworth settles in 4.05 s with Euler vs 3.76 s continuous
            assert!(
                (t2 - t2_doc).abs() <= 0.1 * t2_doc,
                "{poly:?} r={r}: t2% {t2:.4} vs {t2_doc:.4}"
            );
            // the lightly damped r = 20 Butterworth poles are the most distorted
            assert!(
                (os - os_doc).abs() <= 1.5,
                "{poly:?} r={r}: overshoot {os:.3} vs {os_doc}"
            );
        }
    }
}

/// Through the whole estimator: a vehicle already moving (q(0) != 0) feels a
/// constant force from t_0; the force estimate is the chain's step response.
#[test]
fn estimator_force_step_is_the_chain_step_response() {
    let nominal = NominalModel {
        mass_kg: 1.5,
        inertia_kg_m2: Matrix3::from_diagonal(&Vector3::new(1.2416, 1.2416, 2.4832)),
    };
    let config = EstimatorConfig {
        order: 5,
        ..EstimatorConfig::default()
    };
    let mut est = MomentumEstimator::new(config.clone(), nominal).unwrap();
    let f = Vector3::new(0.5, -0.3, 0.8);
    let v0 = Vector3::new(3.0, -2.0, 1.0);
    let hover = ControlWrench::new(1.5 * GRAVITY, Vector3::zeros());
    let k = config.gains().unwrap();
    let reference = step_response(&k, Discretization::Trapezoidal, H, 3000).unwrap();
    for (i, r) in reference.iter().enumerate() {
        let t = i as f64 * H;
        let x = EstimatorInput::from_euler_rates(t, v0 + f * (t / 1.5), Vector3::zeros(), Vector3::zeros(), &hover);
        let e = est.update(&x);
        for a in 0..3 {
            assert!((e.force_ned[a] - f[a] * r).abs() < 1e-9, "t={t} axis {a}");
        }
        assert!(e.torque_frd.norm() < 1e-12 && e.torque_rpy.norm() < 1e-12);
    }
    assert!((est.estimate().mass_kg - (1.5 + 0.8 / GRAVITY)).abs() < 1e-3);
}

// ---------------------------------------------------------------- plant runs

fn fsr_plant(true_mass: f64) -> (Plant, NominalModel) {
    let af = Airframe::load("fsr-quad").unwrap();
    let mut cfg = PlantConfig::default();
    cfg.environment.ground_effect = false;
    cfg.environment.ceiling_effect = false;
    let mut plant = Plant::new(&af, cfg);
    plant.set_true_mass(true_mass);
    let nominal = NominalModel {
        mass_kg: af.mass_kg,
        inertia_kg_m2: af.inertia_kg_m2,
    };
    (plant, nominal)
}

/// One open-loop hover run: thrust `m_r g / (cos phi cos theta)` (no vertical
/// acceleration), torque cancelling the known external torque plus small
/// sinusoids, starting with nonzero velocity and rate.
struct HoverRun {
    times: Vec<f64>,
    estimates: Vec<WrenchEstimate>,
    /// What the estimator should converge to at each sample:
    /// `[f_e + (m - m_r)(a - g e3); Q^T tau_e^b; tau_e^b]`.
    effective: Vec<[f64; 9]>,
    /// The same filtered by a chain identical to the estimator's.
    filtered: Vec<[f64; 9]>,
}

const TRUE_MASS: f64 = 1.25;

fn external() -> ExternalWrench {
    ExternalWrench {
        force_ned: Vector3::new(0.5, 0.5, 0.0),
        torque_frd: Vector3::new(0.03, -0.02, 0.2),
    }
}

fn hover_run(config: &EstimatorConfig, seconds: f64, switch_nominal_at: Option<f64>) -> HoverRun {
    let (mut plant, nominal) = fsr_plant(TRUE_MASS);
    plant.set_state(RigidBodyState {
        position_ned: Vector3::new(0.0, 0.0, -50.0),
        velocity_ned: Vector3::new(1.0, -0.5, 0.2),
        attitude: UnitQuaternion::identity(),
        rate_frd: Vector3::new(0.02, -0.01, 0.05),
    });
    let ext = external();
    let mut est = MomentumEstimator::new(config.clone(), nominal).unwrap();
    let mut est_q = MomentumEstimator::new(config.clone(), nominal).unwrap();
    let mut reference = ChainFilter::<9>::new(&config.gains().unwrap(), config.discretization, H).unwrap();
    let mut m_nom = nominal.mass_kg;
    let mut applied = ControlWrench::default();
    let mut prev_eff: Option<[f64; 9]> = None;
    let n = (seconds / H).round() as usize;
    let mut run = HoverRun {
        times: Vec::new(),
        estimates: Vec::new(),
        effective: Vec::new(),
        filtered: Vec::new(),
    };
    for _ in 0..=n {
        let meas = plant.truth();
        let t = meas.time_s;
        if let Some(ts) = switch_nominal_at
            && (t - ts).abs() < 0.5 * H
        {
            let mut new = nominal;
            new.mass_kg = est.estimate().mass_kg;
            est.set_nominal(new).unwrap();
            est_q.set_nominal(new).unwrap();
            m_nom = new.mass_kg;
        }
        let e = est.update(&input_from(&meas, &applied));
        let eq = est_q.update_measured(&meas, &applied);
        let gap = flat(&e)
            .iter()
            .zip(&flat(&eq))
            .fold(0.0_f64, |g, (a, b)| g.max((a - b).abs()));
        assert!(gap < 1e-9, "t={t}: update_measured differs by {gap:e}");
        let eta = euler_zyx(&meas.attitude);
        let cmd = ControlWrench::new(
            TRUE_MASS * GRAVITY / (eta.x.cos() * eta.y.cos()),
            -ext.torque_frd + Vector3::new(0.05 * (2.0 * t).cos(), 0.04 * (1.3 * t).cos(), 0.03 * (0.7 * t).cos()),
        );
        // effective wrench over the coming interval, evaluated at this sample with the
        // command held since the previous one
        let r = meas.attitude * Vector3::z();
        let acc = Vector3::new(0.0, 0.0, GRAVITY) + (ext.force_ned - applied.thrust_n * r) / TRUE_MASS;
        let f_eff = ext.force_ned + (m_nom - TRUE_MASS) * (acc - Vector3::new(0.0, 0.0, GRAVITY));
        let t_rpy = rate_map(&eta).transpose() * ext.torque_frd;
        let tb = ext.torque_frd;
        let eff = [f_eff.x, f_eff.y, f_eff.z, t_rpy.x, t_rpy.y, t_rpy.z, tb.x, tb.y, tb.z];
        if let Some(p) = prev_eff {
            // the force at t_{k-1} with u_{k-1} and at t_k with u_{k-1}: trapezoid
            let mut u = [0.0; 9];
            for c in 0..9 {
                u[c] = 0.5 * H * (p[c] + eff[c]);
            }
            reference.advance(&u);
        }
        run.times.push(t);
        run.estimates.push(e);
        run.effective.push(eff);
        run.filtered.push(reference.output());
        // the force at t_k with the new command, for the next interval's left end
        let acc_next = Vector3::new(0.0, 0.0, GRAVITY) + (ext.force_ned - cmd.thrust_n * r) / TRUE_MASS;
        let f_next = ext.force_ned + (m_nom - TRUE_MASS) * (acc_next - Vector3::new(0.0, 0.0, GRAVITY));
        let mut next = eff;
        next[..3].copy_from_slice(f_next.as_slice());
        prev_eff = Some(next);
        plant.step(&ActuatorCommand::Wrench(cmd), &ext).unwrap();
        applied = cmd;
    }
    run
}

fn flat(e: &WrenchEstimate) -> [f64; 9] {
    [
        e.force_ned.x,
        e.force_ned.y,
        e.force_ned.z,
        e.torque_rpy.x,
        e.torque_rpy.y,
        e.torque_rpy.z,
        e.torque_frd.x,
        e.torque_frd.y,
        e.torque_frd.z,
    ]
}

/// Doc section 7: with nominal 1.5 kg and true 1.25 kg near hover the
/// estimate converges to `f_z = (m_r - m) g = -2.4525` N, mass 1.25 kg; the
/// body torque to the injected `tau_e^b`, the RPY torque to `Q^T tau_e^b`.
#[test]
fn open_loop_plant_wrong_mass_and_known_wrench() {
    for config in [
        EstimatorConfig::default(),
        EstimatorConfig {
            order: 1,
            discretization: Discretization::ForwardEuler,
            ..EstimatorConfig::default()
        },
        EstimatorConfig {
            order: 5,
            polynomial: Polynomial::Binomial,
            ..EstimatorConfig::default()
        },
    ] {
        let run = hover_run(&config, 6.0, None);
        let ext = external();
        // mean delay of G(s): c_1 / c_0 = 1 / K_1 [s]
        let delay = 1.0 / config.gains().unwrap()[0];
        let mut worst_ref: f64 = 0.0;
        for (k, e) in run.estimates.iter().enumerate() {
            // whole run, from t_0 (the vehicle starts moving: q(0) != 0): the
            // estimate is the effective wrench through G(s)
            let est = flat(e);
            for (a, b) in est.iter().zip(&run.filtered[k]) {
                worst_ref = worst_ref.max((a - b).abs());
            }
            if run.times[k] < 3.0 {
                continue;
            }
            let what = format!("{config:?} t={}", run.times[k]);
            assert!((e.force_ned.z + 2.4525).abs() < 1e-3, "{what}: f_z {}", e.force_ned.z);
            assert!(
                (e.mass_kg - TRUE_MASS).abs() < 0.005 * TRUE_MASS,
                "{what}: mass {}",
                e.mass_kg
            );
            assert!((e.mass_kg - TRUE_MASS).abs() < 1e-4, "{what}: mass {}", e.mass_kg);
            assert!(
                (e.torque_frd - ext.torque_frd).norm() < 1e-5,
                "{what}: {:?}",
                e.torque_frd
            );
            let eff = &run.effective[k];
            // Q^T tau_e^b varies with the attitude: allow for the filter's lag
            assert!(
                (e.torque_rpy - Vector3::new(eff[3], eff[4], eff[5])).norm() < 0.015 * delay,
                "{what}: {:?} vs {eff:?}",
                e.torque_rpy
            );
            // x, y: f_e plus (m - m_r) a_xy, which varies with the tilt (+-0.05 N here);
            // the estimate lags it by the filter's delay
            assert!(
                (e.force_ned.x - eff[0]).abs() < 0.2 * delay && (e.force_ned.y - eff[1]).abs() < 0.2 * delay,
                "{what}: {:?} vs {eff:?}",
                e.force_ned
            );
        }
        // forward Euler integrates d by its left end: an O(h d') difference
        let tol = match config.discretization {
            Discretization::Trapezoidal => 1e-5,
            Discretization::ForwardEuler => 1e-3,
        };
        assert!(
            worst_ref < tol,
            "{config:?}: estimate vs filtered effective wrench {worst_ref:e}"
        );
    }
}

/// `set_nominal` in flight: the force estimate does not jump, then settles
/// to zero vertical force once the nominal mass is right.
#[test]
fn set_nominal_in_flight_is_continuous() {
    let run = hover_run(&EstimatorConfig::default(), 7.0, Some(3.0));
    let k_switch = run.times.iter().position(|t| (t - 3.0).abs() < 0.5 * H).unwrap();
    for k in k_switch - 5..k_switch + 5 {
        let jump = (run.estimates[k + 1].force_ned - run.estimates[k].force_ned).norm();
        assert!(jump < 1e-3, "force estimate jumps by {jump} at t={}", run.times[k]);
    }
    let last = run.estimates.last().unwrap();
    assert!(
        last.force_ned.z.abs() < 1e-3,
        "f_z after the switch {}",
        last.force_ned.z
    );
    assert!((last.mass_kg - TRUE_MASS).abs() < 1e-4);
    assert!((last.force_ned.x - 0.5).abs() < 0.01);
}

#[test]
fn deterministic() {
    let a = hover_run(&EstimatorConfig::default(), 1.0, Some(0.5));
    let b = hover_run(&EstimatorConfig::default(), 1.0, Some(0.5));
    assert_eq!(a.estimates, b.estimates);
    assert_eq!(a.times, b.times);
}

/// Pitching through 90 deg after the estimate has settled: the body-frame
/// torque and the force estimates stay right (the RPY channels coast near the
/// singularity), everything stays finite; both input paths.
#[test]
fn body_variant_through_pitch_90() {
    let (mut plant, nominal) = fsr_plant(1.5);
    let ext = external();
    plant.set_state(RigidBodyState {
        position_ned: Vector3::new(0.0, 0.0, -500.0),
        velocity_ned: Vector3::zeros(),
        attitude: UnitQuaternion::from_euler_angles(0.0, 0.8, 0.3),
        rate_frd: Vector3::new(0.0, 0.25, 0.0),
    });
    let mut est = MomentumEstimator::new(EstimatorConfig::default(), nominal).unwrap();
    let mut est_q = MomentumEstimator::new(EstimatorConfig::default(), nominal).unwrap();
    let mut applied = ControlWrench::default();
    // cancel the external torque: a steady pitch rate
    let cmd = ControlWrench::new(5.0, -ext.torque_frd);
    let (mut max_pitch, mut min_cos, mut t_cross): (f64, f64, f64) = (0.0, 1.0, 0.0);
    for _ in 0..=6000 {
        let meas = plant.truth();
        let eta = euler_zyx(&meas.attitude);
        if eta.y.cos().abs() < min_cos {
            min_cos = eta.y.cos().abs();
            t_cross = meas.time_s;
        }
        max_pitch = max_pitch.max(eta.y);
        let e = est.update(&input_from(&meas, &applied));
        let eq = est_q.update_measured(&meas, &applied);
        for e in [e, eq] {
            assert!(flat(&e).iter().all(|x| x.is_finite()), "t={}: {e:?}", meas.time_s);
            if meas.time_s > 2.5 {
                let t = meas.time_s;
                assert!(
                    (e.torque_frd - ext.torque_frd).norm() < 1e-5,
                    "t={t}: {:?}",
                    e.torque_frd
                );
                assert!((e.force_ned - ext.force_ned).norm() < 1e-5, "t={t}: {:?}", e.force_ned);
                assert!((e.mass_kg - 1.5).abs() < 1e-6);
            }
        }
        plant.step(&ActuatorCommand::Wrench(cmd), &ext).unwrap();
        applied = cmd;
    }
    // the run did pass the singularity, after the estimate had settled
    assert!(
        max_pitch > 1.55 && min_cos < 1e-3,
        "max pitch {max_pitch}, min |cos| {min_cos}"
    );
    assert!(t_cross > 3.0 && t_cross < 5.5, "crossed at {t_cross} s");
}

/// A non-finite sample makes the affected channels coast instead of
/// poisoning the estimator.
#[test]
fn non_finite_input_coasts() {
    let nominal = NominalModel {
        mass_kg: 1.5,
        inertia_kg_m2: Matrix3::from_diagonal(&Vector3::new(1.2416, 1.2416, 2.4832)),
    };
    let mut est = MomentumEstimator::new(EstimatorConfig::default(), nominal).unwrap();
    let f = Vector3::new(0.5, 0.0, 0.0);
    let hover = ControlWrench::new(1.5 * GRAVITY, Vector3::new(0.0, 0.0, 0.0));
    let input = |t: f64| EstimatorInput::from_euler_rates(t, f * (t / 1.5), Vector3::zeros(), Vector3::zeros(), &hover);
    for i in 0..3000 {
        est.update(&input(i as f64 * H));
    }
    let mut bad = input(3.0);
    bad.velocity_ned.x = f64::NAN;
    bad.torque_frd.z = f64::INFINITY;
    let e = est.update(&bad);
    assert!(flat(&e).iter().all(|x| x.is_finite()));
    for i in 3001..4000 {
        let e = est.update(&input(i as f64 * H));
        assert!((e.force_ned.x - 0.5).abs() < 1e-3, "{e:?}");
    }
}

// ---------------------------------------------------------------- configuration

#[test]
fn invalid_configurations_are_refused_with_messages() {
    let nominal = NominalModel {
        mass_kg: 1.5,
        inertia_kg_m2: Matrix3::from_diagonal(&Vector3::new(1.2416, 1.2416, 2.4832)),
    };
    let base = EstimatorConfig::default();
    let cases: Vec<(EstimatorConfig, &str)> = vec![
        (
            EstimatorConfig {
                order: 0,
                ..base.clone()
            },
            "between 1 and 20, got 0",
        ),
        (
            EstimatorConfig {
                order: 21,
                ..base.clone()
            },
            "got 21",
        ),
        (
            EstimatorConfig {
                cutoff_rad_s: 0.0,
                ..base.clone()
            },
            "cutoff",
        ),
        (
            EstimatorConfig {
                cutoff_rad_s: f64::NAN,
                ..base.clone()
            },
            "cutoff",
        ),
        (
            EstimatorConfig {
                cutoff_rad_s: f64::INFINITY,
                ..base.clone()
            },
            "cutoff",
        ),
        (
            EstimatorConfig {
                sample_time_s: 0.0,
                ..base.clone()
            },
            "sample time",
        ),
        (
            EstimatorConfig {
                polynomial: Polynomial::Custom(vec![1.0, 2.0]),
                ..base.clone()
            },
            "needs 3 coefficients",
        ),
        (
            EstimatorConfig {
                polynomial: Polynomial::Custom(vec![1.0, 0.0, 3.0]),
                ..base.clone()
            },
            "c_1 = 0",
        ),
        (
            EstimatorConfig {
                polynomial: Polynomial::Custom(vec![2.0, 1.0, 1.0]),
                ..base.clone()
            },
            "not Hurwitz",
        ),
        (
            EstimatorConfig {
                order: 20,
                cutoff_rad_s: 200.0,
                discretization: Discretization::ForwardEuler,
                ..base.clone()
            },
            "forward Euler is unstable",
        ),
    ];
    for (config, needle) in cases {
        let err = MomentumEstimator::new(config.clone(), nominal).unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains(needle), "{config:?}: '{msg}' lacks '{needle}'");
    }
    // the same order-20 cutoff is fine with the trapezoidal rule
    assert!(
        MomentumEstimator::new(
            EstimatorConfig {
                order: 20,
                cutoff_rad_s: 200.0,
                ..base.clone()
            },
            nominal
        )
        .is_ok()
    );
    // a valid custom polynomial: (s + 1)(s + 2)(s + 3), DC gain 1
    let est = MomentumEstimator::new(
        EstimatorConfig {
            polynomial: Polynomial::Custom(vec![6.0, 11.0, 6.0]),
            ..base.clone()
        },
        nominal,
    )
    .unwrap();
    assert_eq!(est.gains(), &[6.0 / 11.0, 11.0 / 6.0, 6.0]);
    let bad_mass = NominalModel {
        mass_kg: -1.0,
        ..nominal
    };
    assert_eq!(
        MomentumEstimator::new(base, bad_mass).unwrap_err(),
        EstimatorError::NominalMass(-1.0)
    );
}

#[test]
fn config_round_trips_through_serde() {
    let c = EstimatorConfig {
        order: 3,
        polynomial: Polynomial::Custom(vec![6.0, 11.0, 6.0]),
        cutoff_rad_s: 10.0,
        discretization: Discretization::ForwardEuler,
        sample_time_s: 0.002,
    };
    let json = serde_json::to_string(&c).unwrap();
    assert!(
        json.contains("\"forward_euler\"") && json.contains("\"custom\""),
        "{json}"
    );
    let back: EstimatorConfig = serde_json::from_str(&json).unwrap();
    assert_eq!(back, c);
    let d: EstimatorConfig = serde_json::from_str("{\"order\": 5}").unwrap();
    assert_eq!(d.polynomial, Polynomial::Butterworth);
    assert_eq!(d.discretization, Discretization::Trapezoidal);
}

#[test]
fn reset_starts_over() {
    let nominal = NominalModel {
        mass_kg: 1.5,
        inertia_kg_m2: Matrix3::from_diagonal(&Vector3::new(1.2416, 1.2416, 2.4832)),
    };
    let mut est = MomentumEstimator::new(EstimatorConfig::default(), nominal).unwrap();
    let hover = ControlWrench::new(1.5 * GRAVITY, Vector3::zeros());
    let x = |t: f64| {
        EstimatorInput::from_euler_rates(t, Vector3::new(t, 0.0, 0.0), Vector3::zeros(), Vector3::zeros(), &hover)
    };
    let first: Vec<WrenchEstimate> = (0..100).map(|i| est.update(&x(i as f64 * H))).collect();
    assert!(first[99].force_ned.x > 0.0);
    est.reset();
    assert!(!est.is_initialized() && est.estimate().force_ned == Vector3::zeros());
    let again: Vec<WrenchEstimate> = (0..100).map(|i| est.update(&x(i as f64 * H))).collect();
    assert_eq!(first, again);
}
