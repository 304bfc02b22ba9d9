//! Airframes, allocation and failure analysis against the origin report and
//! `docs/model.md` sections 3 and 9.

mod common;

use nalgebra::{DMatrix, Vector3};
use proptest::prelude::*;
use rotorpilot::airframe::{Airframe, AirframeError, HoverVerdict, analyse_failures, hover_margins};
use rotorpilot::signals::{ControlWrench, GRAVITY};

const S2: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// An airframe file with the doc's sample coefficients (l = 0.25 m,
/// c_T = 1e-5, c_Q = 5e-7, omega in [0, 1000]) for a given layout.
fn sample_airframe(mass: f64, rotors: &[(f64, &str)]) -> Airframe {
    let mut text = format!(
        "name = \"sample\"\nactuation = \"rotors\"\n[body]\nmass_kg = {mass}\ninertia_diag_kg_m2 = [0.03, 0.03, 0.05]\n\
         gear_height_m = 0.2\n[rotor]\nthrust_coefficient_n_s2 = 1e-5\ntorque_coefficient_n_m_s2 = 5e-7\nradius_m = 0.09\n\
         time_constant_s = 0.02\nspeed_min_rad_s = 0.0\nspeed_max_rad_s = 1000.0\n[ground_effect]\nbody_coefficient = 0.0\n\
         [ceiling_effect]\nk1 = 2.5\nk2_m = 0.099\n"
    );
    for (angle, spin) in rotors {
        text.push_str(&format!(
            "[[rotors]]\nangle_deg = {angle}\narm_m = 0.25\nspin = \"{spin}\"\n"
        ));
    }
    Airframe::from_toml(&text, "sample.toml").expect("sample airframe is valid")
}

fn octo(mass: f64) -> Airframe {
    let r: Vec<(f64, &str)> = (0..8)
        .map(|i| (45.0 * f64::from(i), if i % 2 == 0 { "cw" } else { "ccw" }))
        .collect();
    sample_airframe(mass, &r)
}

fn quad_x(mass: f64) -> Airframe {
    sample_airframe(mass, &[(45.0, "ccw"), (135.0, "cw"), (225.0, "ccw"), (315.0, "cw")])
}

fn hexa_x(mass: f64) -> Airframe {
    let r: Vec<(f64, &str)> = (0..6)
        .map(|i| (30.0 + 60.0 * f64::from(i), if i % 2 == 0 { "cw" } else { "ccw" }))
        .collect();
    sample_airframe(mass, &r)
}

fn assert_matrix_eq(a: &DMatrix<f64>, b: &DMatrix<f64>, tol: f64) {
    assert_eq!(a.shape(), b.shape());
    for (x, y) in a.iter().zip(b.iter()) {
        assert!((x - y).abs() <= tol, "{a}\n!=\n{b}");
    }
}

/// GIVEN the shipped octo WHEN its B is built THEN it is the report's matrix entry for entry.
#[test]
fn octo_matrix_is_the_reports() {
    let a = Airframe::load("octo").unwrap();
    let (l, ct, cq) = (0.25, 1e-5, 5e-7);
    let k = S2 * l * ct;
    #[rustfmt::skip]
    let report = DMatrix::from_row_slice(4, 8, &[
        ct, ct, ct, ct, ct, ct, ct, ct,
        0.0, -k, -l * ct, -k, 0.0, k, l * ct, k,
        l * ct, k, 0.0, -k, -l * ct, -k, 0.0, k,
        -cq, cq, -cq, cq, -cq, cq, -cq, cq,
    ]);
    assert_matrix_eq(&a.effectiveness(), &report, 1e-20);
    // doc section 9 numbers
    let row2 = [0.0, -1.767767, -2.5, -1.767767, 0.0, 1.767767, 2.5, 1.767767];
    for (i, v) in row2.iter().enumerate() {
        assert!((a.effectiveness()[(1, i)] - v * 1e-6).abs() < 1e-12);
    }
    // B^+ row i = [12500, -1e5 sin a_i, 1e5 cos a_i, 2.5e5 s_i]
    let alloc = a.allocator();
    for (i, r) in a.rotors.iter().enumerate() {
        let row = alloc.b_pinv().row(i);
        let expect = [
            12500.0,
            -1e5 * r.angle_rad.sin(),
            1e5 * r.angle_rad.cos(),
            2.5e5 * r.spin.sign(),
        ];
        for (x, e) in row.iter().zip(expect) {
            assert!((x - e).abs() < 1e-6, "B+ row {i}: {row} vs {expect:?}");
        }
    }
}

#[test]
fn quad_and_hexa_match_doc_section_3() {
    let (l, ct, cq) = (0.25, 1e-5, 5e-7);
    let k = S2 * l * ct;
    #[rustfmt::skip]
    let quad = DMatrix::from_row_slice(4, 4, &[
        ct, ct, ct, ct,
        -k, -k, k, k,
        k, -k, -k, k,
        cq, -cq, cq, -cq,
    ]);
    assert_matrix_eq(&quad_x(1.5).effectiveness(), &quad, 1e-18);
    let h = 3f64.sqrt() / 2.0;
    #[rustfmt::skip]
    let hexa = DMatrix::from_row_slice(4, 6, &[
        ct, ct, ct, ct, ct, ct,
        -0.5 * l * ct, -l * ct, -0.5 * l * ct, 0.5 * l * ct, l * ct, 0.5 * l * ct,
        h * l * ct, 0.0, -h * l * ct, -h * l * ct, 0.0, h * l * ct,
        -cq, cq, -cq, cq, -cq, cq,
    ]);
    assert_matrix_eq(&hexa_x(1.5).effectiveness(), &hexa, 1e-18);
}

fn hover_speeds(a: &Airframe, w: ControlWrench) -> Vec<f64> {
    let alloc = a.allocator();
    let sol = alloc.allocate(&w);
    assert!(!sol.saturated);
    (0..a.rotor_count()).map(|i| sol.speed_cmd_rad_s[i]).collect()
}

/// Doc section 9 rotor-speed table.
#[test]
fn hover_rotor_speeds_match_doc_section_9() {
    let hover = |m: f64| ControlWrench::new(m * GRAVITY, Vector3::zeros());
    let close = |v: &[f64], e: f64| v.iter().all(|x| (x - e).abs() < 1e-3);
    assert!(close(&hover_speeds(&octo(1.5), hover(1.5)), 428.8794));
    assert!(close(&hover_speeds(&octo(1.25), hover(1.25)), 391.5115));
    assert!(close(&hover_speeds(&quad_x(1.5), hover(1.5)), 606.527));
    assert!(close(&hover_speeds(&quad_x(1.25), hover(1.25)), 553.681));
    assert!(close(&hover_speeds(&hexa_x(1.5), hover(1.5)), 495.227));
    assert!(close(&hover_speeds(&hexa_x(1.25), hover(1.25)), 452.079));
    let yaw = hover_speeds(
        &octo(1.25),
        ControlWrench::new(1.25 * GRAVITY, Vector3::new(0.0, 0.0, -0.2)),
    );
    for (i, w) in yaw.iter().enumerate() {
        let expect = if i % 2 == 0 { 450.867 } else { 321.374 };
        assert!((w - expect).abs() < 1e-3, "rotor {}: {w} vs {expect}", i + 1);
    }
}

proptest! {
    /// B alloc(w) = w whenever the request is unsaturated.
    #[test]
    fn allocation_round_trip(thrust in 5.0f64..25.0, tx in -0.5f64..0.5, ty in -0.5f64..0.5, tz in -0.05f64..0.05, frame in 0usize..3) {
        let a = match frame { 0 => Airframe::load("quad").unwrap(), 1 => Airframe::load("hexa").unwrap(), _ => Airframe::load("octo").unwrap() };
        let req = ControlWrench::new(thrust, Vector3::new(tx, ty, tz));
        let sol = a.allocator().allocate(&req);
        if !sol.saturated {
            let back = a.allocator().forward(&sol.speed_sq);
            prop_assert!((back.to_vector() - req.to_vector()).norm() < 1e-9 * thrust);
            prop_assert!(sol.unallocated.to_vector().norm() < 1e-9 * thrust);
        } else {
            // what is reported undelivered is exactly the difference
            let back = a.allocator().forward(&sol.speed_sq);
            prop_assert!((back.to_vector() + sol.unallocated.to_vector() - req.to_vector()).norm() < 1e-9);
        }
    }
}

/// GIVEN a request whose yaw part saturates WHEN allocated THEN roll and pitch
/// are delivered in full and yaw is scaled down.
#[test]
fn saturation_keeps_roll_pitch_before_yaw() {
    let a = Airframe::load("quad").unwrap();
    let req = ControlWrench::new(2.0 * GRAVITY, Vector3::new(0.8, -0.6, 1.5));
    let sol = a.allocator().allocate(&req);
    assert!(sol.saturated);
    assert!((sol.achieved.torque_frd.x - 0.8).abs() < 1e-9, "{:?}", sol.achieved);
    assert!((sol.achieved.torque_frd.y + 0.6).abs() < 1e-9);
    assert!((sol.achieved.thrust_n - req.thrust_n).abs() < 1e-9);
    assert!(sol.achieved.torque_frd.z > 0.0 && sol.achieved.torque_frd.z < 1.5);
    assert!(sol.yaw_scale < 1.0 && (sol.roll_pitch_scale - 1.0).abs() < 1e-12);
    // an impossible roll request is scaled, thrust shifted within 30 %, yaw dropped last
    let big = ControlWrench::new(2.0 * GRAVITY, Vector3::new(10.0, 0.0, 0.2));
    let sol = a.allocator().allocate(&big);
    assert!(sol.roll_pitch_scale < 1.0 && sol.roll_pitch_scale > 0.0);
    assert!(sol.thrust_shift_n.abs() <= 0.3 * big.thrust_n + 1e-9);
    assert!(sol.achieved.torque_frd.x > 2.0, "{:?}", sol.achieved);
    assert!(sol.yaw_scale < 1e-9, "{}", sol.yaw_scale);
    for i in 0..4 {
        assert!(sol.speed_cmd_rad_s[i] >= 100.0 - 1e-9 && sol.speed_cmd_rad_s[i] <= 1000.0 + 1e-9);
    }
}

/// GIVEN thrust far beyond what the rotors give WHEN a roll torque is also asked
/// THEN thrust is cut, not roll: attitude control survives an absurd thrust request.
#[test]
fn impossible_thrust_gives_way_to_roll_and_pitch() {
    let a = Airframe::load("quad").unwrap();
    let max_thrust = 4.0 * a.rotor.c_t * a.rotor.speed_max_rad_s.powi(2);
    let req = ControlWrench::new(1.6 * max_thrust, Vector3::new(0.5, -0.3, 0.0));
    let sol = a.allocator().allocate(&req);
    assert!(sol.saturated);
    assert!(
        (sol.roll_pitch_scale - 1.0).abs() < 1e-12,
        "sigma {}",
        sol.roll_pitch_scale
    );
    assert!((sol.achieved.torque_frd.x - 0.5).abs() < 1e-9 && (sol.achieved.torque_frd.y + 0.3).abs() < 1e-9);
    assert!(
        sol.achieved.thrust_n < max_thrust && sol.achieved.thrust_n > 0.8 * max_thrust,
        "{:?}",
        sol.achieved
    );
}

/// Doc section 3 failure oracle (m = 1.25 kg, omega in [0, 1000]).
#[test]
fn rotor_failure_verdicts_match_doc_section_3() {
    let o = octo(1.25);
    let (lo, hi) = o.speed_sq_bounds();
    let intact = hover_margins(&o.effectiveness(), 1.25 * GRAVITY, lo, hi).unwrap();
    assert!(
        (intact.yaw_n_m[0] - 0.613).abs() < 1e-3 && (intact.yaw_n_m[1] - 0.613).abs() < 1e-3,
        "{intact:?}"
    );
    assert!((intact.roll_n_m[0] - 2.62).abs() < 0.01, "{intact:?}");
    let failures = analyse_failures(&o);
    assert_eq!(failures.len(), 8);
    let mut worst_rp = f64::INFINITY;
    for f in &failures {
        assert_eq!(f.rank, 4);
        assert_eq!(f.verdict, HoverVerdict::Feasible);
        let m = f.margins.unwrap();
        worst_rp = worst_rp.min(m.roll_n_m[0].min(m.roll_n_m[1]).min(m.pitch_n_m[0]).min(m.pitch_n_m[1]));
        assert!((m.yaw_n_m[0].min(m.yaw_n_m[1]) - 0.613).abs() < 1e-3, "{m:?}");
    }
    assert!((worst_rp - 1.08).abs() < 0.01, "worst roll/pitch margin {worst_rp}");
    for f in analyse_failures(&hexa_x(1.25)) {
        assert_eq!(
            (f.rank, f.verdict),
            (4, HoverVerdict::Boundary),
            "hexa rotor {}",
            f.rotor
        );
    }
    for f in analyse_failures(&quad_x(1.25)) {
        assert_eq!((f.rank, f.verdict), (3, HoverVerdict::RankDeficient));
    }
}

#[test]
fn airframe_json_report_has_the_documented_keys() {
    let out = common::bin::run(&["airframe", "octo", "--json"]);
    assert!(out.ok(), "{}", out.stderr);
    let v: serde_json::Value = serde_json::from_str(&out.stdout).unwrap();
    for key in [
        "allocation",
        "rank",
        "wrench_rank",
        "dof_ground",
        "dof_flying",
        "underactuated",
        "hover_rotor_speeds",
        "rotor_failure",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
    assert_eq!(v["rank"], 4);
    assert_eq!(v["wrench_rank"], 4);
    assert_eq!(v["dof_ground"], 8);
    assert_eq!(v["dof_flying"], 14);
    assert_eq!(v["underactuated"], true);
    assert_eq!(v["allocation"][1][2].as_f64().unwrap(), -2.5e-6);
    assert_eq!(v["rotor_failure"].as_array().unwrap().len(), 8);
    let text = common::bin::run(&["airframe", "quad"]).stdout;
    assert!(text.contains("rank B = 4") && text.contains("underactuated: yes") && text.contains("rank deficient"));
}

#[test]
fn every_shipped_airframe_loads() {
    for (name, _) in rotorpilot::airframe::BUILTIN {
        let a = Airframe::load(name).unwrap();
        assert_eq!(&a.name, name);
    }
    assert!(matches!(Airframe::load("nope"), Err(AirframeError::Unknown { .. })));
}

/// The `[aero]` table is optional (every coefficient 0 when absent, and when
/// a key is left out) and its values reach `airframe.aero` as written.
#[test]
fn aero_coefficients_are_read_and_default_to_zero() {
    // the shipped quad's text without any `[aero]` table it may have
    let text = Airframe::load_text("quad").unwrap().0;
    let plain = match text.find("\n[aero]") {
        Some(at) => {
            let rest = &text[at + 1..];
            let end = rest.find("\n[").map_or(text.len(), |e| at + 1 + e + 1);
            format!("{}{}", &text[..at + 1], &text[end..])
        }
        None => text.clone(),
    };
    let without = Airframe::from_toml(&plain, "plain.toml").unwrap();
    assert_eq!(without.aero, rotorpilot::airframe::AeroCoefficients::default());
    assert!(without.aero.is_zero());
    let table = "[aero]\nc_dx = 0.005\nc_dy = 0.006\nc_dz = 0.01\nk_d = 1.19e-4\nk_z = 2.32e-4\nk_h = 3.39e-3\n";
    let with = Airframe::from_toml(&format!("{plain}\n{table}"), "with-aero.toml").unwrap();
    let a = with.aero;
    assert_eq!(
        [a.c_dx, a.c_dy, a.c_dz, a.k_d, a.k_z, a.k_h, a.k_flap],
        [0.005, 0.006, 0.01, 1.19e-4, 2.32e-4, 3.39e-3, 0.0]
    );
    assert!(!a.is_zero());
}

/// A non-positive rotor constant is refused with the whole message: the
/// file, the line and column of the value, the field and the problem, from
/// the library and from the CLI (exit status 1, no panic).
#[test]
fn non_positive_rotor_constants_are_refused_at_their_line() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/airframes");
    for (file, line_column, field, got) in [
        (
            "zero-thrust-coefficient.toml",
            "22:27",
            "rotor.thrust_coefficient_n_s2",
            "0",
        ),
        (
            "negative-torque-coefficient.toml",
            "23:29",
            "rotor.torque_coefficient_n_m_s2",
            "-0.00000013677728",
        ),
        ("zero-time-constant.toml", "25:19", "rotor.time_constant_s", "0"),
        ("negative-radius.toml", "24:12", "rotor.radius_m", "-0.1396"),
    ] {
        let path = format!("{dir}/{file}");
        let want = format!("{path}:{line_column}: {field}: must be a finite number > 0, got {got}");
        let err = Airframe::load(&path).expect_err(file).to_string();
        assert_eq!(err, want, "{file}");
        let out = common::bin::run(&["airframe", &path]);
        assert_eq!(out.code, Some(1), "{file}");
        assert_eq!(out.stderr, format!("rotorpilot: {want}\n"), "{file}");
    }
}

/// Every malformed fixture is refused with the file, the field and the problem named.
#[test]
fn malformed_airframes_get_named_errors() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/airframes");
    let cases = [
        ("negative-mass.toml", "body.mass_kg", "must be a finite number > 0"),
        ("missing-mass.toml", "mass_kg", "missing field"),
        ("duplicate-angle.toml", "rotors[2].angle_deg", "duplicate rotor angle"),
        ("unknown-key.toml", "colour", "unknown field"),
        ("overlapping-rotors.toml", "rotor.radius_m", "overlap"),
        ("same-spin.toml", "rotors", "rank 3"),
        ("cannot-hover.toml", "body.mass_kg", "cannot hover"),
        ("bad-spin.toml", "clockwise", "unknown variant"),
        ("wrong-type.toml", "fast", "invalid type"),
        (
            "impossible-inertia.toml",
            "body.inertia_diag_kg_m2",
            "triangle inequality",
        ),
        ("not-toml.toml", "not-toml.toml:2", ""),
        ("negative-aero.toml", "aero.k_d", "must be a finite number >= 0"),
        ("unknown-aero-key.toml", "c_d", "unknown field"),
        ("motor-repeated.toml", "rotors[3].motor", "motor 4 is rotors[2] already"),
        ("motor-out-of-range.toml", "rotors[4].motor", "from 1 to 4, got 5"),
        (
            "motor-partial.toml",
            "rotors[2].motor",
            "missing: rotors[1] gives its motor number",
        ),
    ];
    for (file, field, problem) in cases {
        let path = format!("{dir}/{file}");
        let err = Airframe::load(&path).expect_err(file).to_string();
        assert!(err.contains(file), "{file}: error does not name the file: {err}");
        assert!(err.contains(field), "{file}: error does not name `{field}`: {err}");
        assert!(err.contains(problem), "{file}: error does not say `{problem}`: {err}");
    }
    // the CLI prints it and exits non-zero, without a panic
    let out = common::bin::run(&["airframe", &format!("{dir}/negative-mass.toml")]);
    assert!(!out.ok());
    let err = out.stderr;
    assert!(
        err.contains("negative-mass.toml") && err.contains("body.mass_kg") && !err.contains("panicked"),
        "{err}"
    );
}

/// An airframe's `[control]` table is the control laws' to check: a bad gain
/// is refused by them, naming the file and the gain, by the `airframe`
/// command, by a scenario that flies it and by the daemon's start.
#[test]
fn an_airframe_with_a_bad_gain_is_refused_where_it_would_fly() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/airframes");
    let path = format!("{dir}/bad-gain.toml");
    let a = Airframe::load(&path).expect("the airframe itself is valid");
    let err = rotorpilot::control::ControlGains::for_airframe(&a, a.mass_kg)
        .unwrap_err()
        .to_string();
    assert!(err.contains("geometric.kp_n_per_m[1]") && err.contains("-355"), "{err}");
    let typo = Airframe::from_toml(
        &std::fs::read_to_string(&path)
            .unwrap()
            .replace("[control.geometric]", "[control.geometrik]"),
        "typo.toml",
    )
    .unwrap();
    let err = rotorpilot::control::ControlGains::for_airframe(&typo, typo.mass_kg)
        .unwrap_err()
        .to_string();
    assert!(err.contains("geometrik"), "{err}");
    let state = common::scratch_path("bad-gain");
    let state = state.display().to_string();
    let daemon = [
        "--airframe",
        &path,
        "--state-dir",
        &state,
        "--gcs-bind",
        "127.0.0.1:0",
        "--api-bind",
        "127.0.0.1:0",
    ];
    for args in [&["airframe", path.as_str()][..], &daemon[..]] {
        let out = common::bin::run(args);
        assert!(!out.ok(), "{args:?}");
        let err = out.stderr;
        assert!(
            err.contains("bad-gain.toml") && err.contains("kp_n_per_m[1]") && !err.contains("panicked"),
            "{args:?}: {err}"
        );
    }
}

/// The shipped airframes number their motors as PX4 numbers the same
/// places (output Motor N, `CA_ROTOR{N-1}`): quad-X 1 front right, 2 rear
/// left, 3 front left, 4 rear right; hexa-X 1 right, 2 left, 3 front left,
/// 4 rear right, 5 front right, 6 rear left; the report's octocopter, which
/// PX4 has not, in its file's order.
#[test]
fn shipped_airframes_number_their_motors_as_px4() {
    let quad_x = [45.0, 225.0, 315.0, 135.0];
    let hexa_x = [90.0, 270.0, 330.0, 150.0, 30.0, 210.0];
    let octo: Vec<f64> = (0..8).map(|i| f64::from(i) * 45.0).collect();
    for (name, angles) in [
        ("quad", &quad_x[..]),
        ("fsr-quad", &quad_x[..]),
        ("hexa", &hexa_x[..]),
        ("hexa-ppnnpn", &hexa_x[..]),
        ("octo", &octo[..]),
    ] {
        let af = Airframe::load(name).unwrap();
        assert_eq!(af.rotor_count(), angles.len(), "{name}");
        for (k, want) in angles.iter().enumerate() {
            let motor = k + 1;
            let rotor = af
                .rotor_of_motor(motor)
                .unwrap_or_else(|| panic!("{name}: no motor {motor}"));
            assert_eq!(af.motor_of_rotor(rotor), motor);
            let got = af.rotors[rotor].angle_rad.to_degrees().rem_euclid(360.0);
            assert!(
                (got - want).abs() < 1e-9,
                "{name} motor {motor}: at {got} deg, PX4's at {want}"
            );
        }
    }
}
