//! A scenario with a `[wind]` table flies in it: the quad with aerodynamic
//! coefficients hovering in a 5 m/s wind from the west is pushed east (its
//! steady error points east), the momentum estimator finds the drag the world
//! applies (the true external force is the aerodynamic one), and a bad
//! `[wind]` value is refused naming the file and field.

use rotorpilot::scenario::{Scenario, lockstep, run};

fn hover(wind: &str) -> Scenario {
    let text = format!(
        "airframe = \"quad\"\ncontroller = \"geometric\"\nduration_s = 10.0\n\
         [reference]\nkind = \"hover\"\nposition_ned = [0.0, 0.0, -5.0]\n\
         [world]\nground_effect = false\n{wind}"
    );
    Scenario::from_toml(&text, "hover-wind.toml", None).unwrap()
}

const WEST_5: &str = "[wind]\nspeed_m_s = 5.0\nfrom_deg = 270.0\n";

#[test]
fn a_hover_in_a_west_wind_is_pushed_east_and_the_estimator_sees_the_drag() {
    let calm = run(&hover(""), None).unwrap();
    let windy_scenario = hover(WEST_5);
    assert_eq!(windy_scenario.wind.speed_m_s, 5.0);
    let windy = run(&windy_scenario, None).unwrap();
    assert!(calm.finite && windy.finite && windy.upright);
    // calm: nothing to find, no error
    assert!(calm.est_force_ned[1].abs() < 1e-3, "{:?}", calm.est_force_ned);
    assert!(calm.final_pos_err_ned[1].abs() < 1e-4, "{:?}", calm.final_pos_err_ned);
    // windy: the vehicle sits east of its setpoint (error = position - reference)
    let east = windy.final_pos_err_ned[1];
    assert!(east > 0.005, "pushed east by {east} m: {:?}", windy.final_pos_err_ned);
    // the estimate is the aerodynamic force the world applies (the true external force)
    let mut core = lockstep(&windy_scenario).unwrap();
    for _ in 0..10_000 {
        core.step();
    }
    let truth = core.world().truth(0);
    assert_eq!(truth.force_ned, nalgebra::Vector3::zeros(), "nothing injected");
    assert!(truth.aero_force_ned.y > 0.1, "{}", truth.aero_force_ned);
    assert!((truth.wind_ned - nalgebra::Vector3::new(0.0, 5.0, 0.0)).norm() < 1e-12);
    let est = windy.est_force_ned;
    let f = truth.external_force_ned();
    assert!(
        (est[1] - f.y).abs() < 0.05 * f.y && (est[0] - f.x).abs() < 0.01,
        "estimate {est:?} vs true {f}"
    );
}

#[test]
fn a_bad_wind_value_is_refused_naming_the_field() {
    let text = "airframe = \"quad\"\nduration_s = 1.0\n[reference]\nkind = \"hover\"\nposition_ned = [0.0, 0.0, -5.0]\n\
                [wind]\nspeed_m_s = -3.0\n";
    let e = Scenario::from_toml(text, "bad-wind.toml", None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bad-wind.toml") && e.contains("wind.speed_m_s") && e.contains(">= 0"),
        "{e}"
    );
    let text = text.replace("speed_m_s = -3.0", "[wind.gust]\nduration_s = 0.0");
    let e = Scenario::from_toml(&text, "bad-gust.toml", None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("wind.gust.duration_s"), "{e}");
    let text = "airframe = \"quad\"\nduration_s = 1.0\n[reference]\nkind = \"hover\"\nposition_ned = [0.0, 0.0, -5.0]\n[wind]\nspeeed_m_s = 3.0\n";
    let e = Scenario::from_toml(text, "typo.toml", None).unwrap_err().to_string();
    assert!(e.contains("typo.toml") && e.contains("speeed_m_s"), "{e}");
}
