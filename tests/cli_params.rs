//! `docs/parameters.md` is exactly what `rotorpilot params --markdown`
//! prints from the parameter table, and `rotorpilot params --json` lists
//! every parameter a client reads over MAVLink (`PARAMS`, in index order).

mod common;

/// What `rotorpilot ARGS` prints (it must succeed).
fn rotorpilot(args: &[&str]) -> String {
    let out = common::bin::run(args);
    assert!(out.ok(), "rotorpilot {args:?}: {}", out.stderr);
    out.stdout
}

#[test]
fn docs_parameters_md_is_the_generated_reference() {
    let generated = rotorpilot(&["params", "--markdown"]);
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/parameters.md");
    let committed = std::fs::read_to_string(path).unwrap_or_default();
    if committed != generated {
        let line = committed
            .lines()
            .zip(generated.lines())
            .position(|(a, b)| a != b)
            .unwrap_or_else(|| committed.lines().count().min(generated.lines().count()));
        panic!(
            "docs/parameters.md differs from the parameter table (first at line {}): regenerate it with\n    {}",
            line + 1,
            rotorpilot::cli::params::REGENERATE
        );
    }
}

#[test]
fn json_lists_every_parameter_in_index_order() {
    let json: serde_json::Value = serde_json::from_str(&rotorpilot(&["params", "--json"])).expect("JSON");
    let list = json.as_array().expect("a list");
    assert_eq!(list.len(), rotorpilot::params::PARAMS.len());
    for (i, (p, spec)) in list.iter().zip(rotorpilot::params::PARAMS.iter()).enumerate() {
        assert_eq!(p["name"], spec.name);
        assert_eq!(p["index"], i);
        assert_eq!(p["type"], spec.kind.name());
        assert_eq!(p["default"].as_f64(), Some(spec.default), "{}", spec.name);
        assert_eq!(p["min"].as_f64(), Some(spec.min), "{}", spec.name);
        assert_eq!(p["max"].as_f64(), Some(spec.max), "{}", spec.name);
        assert_eq!(p["reboot_required"], spec.reboot_required);
    }
    let nav_dll = list.iter().find(|p| p["name"] == "NAV_DLL_ACT").expect("NAV_DLL_ACT");
    let values: Vec<i64> = nav_dll["values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["value"].as_i64().unwrap())
        .collect();
    assert_eq!(values, [0, 1, 2, 3, 5, 6]);
}
