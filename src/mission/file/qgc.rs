//! QGroundControl `.plan` files, read as MAVSDK's
//! `mission_raw.import_qgroundcontrol_mission` reads them
//! (`src/mavsdk/plugins/mission_raw/mission_import.cpp`), so a headless
//! flight of a `.plan` flies what MAVSDK would have uploaded, bit for bit.
//!
//! ```json
//! {"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
//!  "mission": {"version": 2, "firmwareType": 12, "plannedHomePosition": [47.397742, 8.5455939, 488],
//!              "items": [{"type": "SimpleItem", "command": 22, "frame": 3, "autoContinue": true,
//!                         "params": [0, 0, 0, null, 47.397742, 8.5455939, 10]}]},
//!  "geoFence": {"version": 2,
//!               "polygons": [{"inclusion": true, "polygon": [[47.398, 8.545], [47.398, 8.546], [47.397, 8.546]], "version": 1}],
//!               "circles": [{"inclusion": false, "circle": {"center": [47.3977, 8.5456], "radius": 8}, "version": 1}]},
//!  "rallyPoints": {"version": 2, "points": [[47.3980, 8.5450, 15]]}}
//! ```
//!
//! | part | items |
//! |---|---|
//! | `version` | must be 1 |
//! | `mission` (required, `version` 2) | each SimpleItem as written: `command`, `frame`, `autoContinue`, `params[0..4]` → p1..p4 (null → NaN, as f32), `params[4]`, `params[5]` → x, y, `params[6]` → z; the first item is not preceded by `plannedHomePosition` (that is for ArduPilot) |
//! | | a ComplexItem `survey` version 5: its `TransectStyleComplexItem.Items`, each a SimpleItem; any other complex item is refused |
//! | `geoFence` (`version` 2) | polygons (`inclusion` missing: true): one item per vertex, 5001 inclusion / 5002 exclusion, p1 = vertex count; then circles: 5003 / 5004, p1 = radius; frame 0 (MAV_FRAME_GLOBAL), other params 0, z 0, autocontinue off |
//! | `rallyPoints` (`version` 2) | each `[lat, lon, alt]`: 5100 in frame 3, params 0, autocontinue off |
//!
//! x and y as MAVSDK sends them in MISSION_ITEM_INT: global frames
//! `round(v * 1e7)` degE7, MAV_FRAME_MISSION (2) the value as f32 cut to an
//! integer (`static_cast<int32_t>`), null 0. Where this reader is stricter
//! than MAVSDK (it never changes what a well-formed file gives):
//! `params` must hold 7 entries (MAVSDK reads missing ones as null); a
//! positional command in a global frame with a null latitude or longitude is
//! refused (MAVSDK would send 0°, off the coast of Africa); a survey item that
//! does not read is an error, not skipped; a circle needs its `inclusion`
//! (MAVSDK reads a missing one as exclusion); null fence and rally
//! coordinates are refused; and a missing `geoFence` or `rallyPoints` means
//! none (MAVSDK refuses the file).

use super::{Json, Map, Origin, PlanFile, Shape, check_plan, join};
use crate::mission::quantise_deg;
use crate::mission::{MissionItem, MissionType, cmd, frame};

use super::MissionFileError;

/// Read `.plan` text; `file` labels errors.
///
/// # Errors
/// Not JSON, a version other than MAVSDK's, a missing or mistyped field, a
/// complex item other than a survey version 5, or an item the vehicle would
/// refuse: each names the file, the JSON path and the problem.
pub fn parse_qgc_plan(text: &str, file: &str) -> Result<PlanFile, MissionFileError> {
    let j = Json { file };
    let root = j.parse(text)?;
    let root = j.object(&root, "")?;
    j.version(root, "", 1, ".plan file")?;

    let mission = root
        .get("mission")
        .ok_or_else(|| j.invalid("mission", "missing (a .plan holds a `mission` object)"))?;
    let mission = j.object(mission, "mission")?;
    j.version(mission, "mission", 2, "mission")?;
    let mut items = Vec::new();
    if let Some(list) = mission.get("items") {
        for (i, it) in j.array(list, "mission.items")?.iter().enumerate() {
            mission_item(&j, it, &format!("mission.items[{i}]"), &mut items)?;
        }
    }
    let list = Origin::Json {
        base: "mission.items".into(),
        shape: Shape::Simple,
    };
    let mission = check_plan(file, MissionType::Mission, items, &list)?;

    let fence = match root.get("geoFence") {
        Some(g) => geofence(&j, g)?,
        None => Vec::new(),
    };
    let list = Origin::Json {
        base: "geoFence".into(),
        shape: Shape::Circle,
    };
    let fence = check_plan(file, MissionType::Fence, fence, &list)?;

    let rally = match root.get("rallyPoints") {
        Some(r) => rally_points(&j, r)?,
        None => Vec::new(),
    };
    let list = Origin::Json {
        base: "rallyPoints.points".into(),
        shape: Shape::Rally,
    };
    let rally = check_plan(file, MissionType::Rally, rally, &list)?;
    Ok(PlanFile { mission, fence, rally })
}

/// One entry of `mission.items` (a SimpleItem, or a survey's items), appended to `out`.
fn mission_item(
    j: &Json<'_>,
    v: &serde_json::Value,
    path: &str,
    out: &mut Vec<(MissionItem, Origin)>,
) -> Result<(), MissionFileError> {
    let obj = j.object(v, path)?;
    let kind = j.required(obj, path, "type")?;
    match kind.as_str() {
        Some("SimpleItem") => {
            out.push((simple_item(j, obj, path)?, simple_origin(path)));
            Ok(())
        }
        Some("ComplexItem") => complex_item(j, obj, path, out),
        _ => Err(j.invalid(
            &join(path, "type"),
            format!(
                "expected \"SimpleItem\" or \"ComplexItem\", found {}",
                super::show(kind)
            ),
        )),
    }
}

fn simple_origin(path: &str) -> Origin {
    Origin::Json {
        base: path.to_string(),
        shape: Shape::Simple,
    }
}

/// A SimpleItem's fields, as MAVSDK's `import_simple_mission_item`.
fn simple_item(j: &Json<'_>, obj: &Map, path: &str) -> Result<MissionItem, MissionFileError> {
    let command: u16 = j.whole(j.required(obj, path, "command")?, &join(path, "command"))?;
    let autocontinue = j.boolean(j.required(obj, path, "autoContinue")?, &join(path, "autoContinue"))?;
    let frame_no: u8 = j.whole(j.required(obj, path, "frame")?, &join(path, "frame"))?;
    let params_path = join(path, "params");
    let params = j.array(j.required(obj, path, "params")?, &params_path)?;
    if params.len() != 7 {
        return Err(j.invalid(
            &params_path,
            format!(
                "expected 7 params (p1 to p4, latitude / x, longitude / y, altitude / z), found {}",
                params.len()
            ),
        ));
    }
    let mut p = [None; 7];
    for (k, v) in params.iter().enumerate() {
        p[k] = j.number_or_null(v, &format!("{params_path}[{k}]"))?;
    }
    let f32_or_nan = |v: Option<f64>| v.map_or(f32::NAN, |v| v as f32);
    let mut item = MissionItem {
        frame: frame_no,
        command,
        autocontinue,
        params: [f32_or_nan(p[0]), f32_or_nan(p[1]), f32_or_nan(p[2]), f32_or_nan(p[3])],
        x: 0.0,
        y: 0.0,
        z: f32_or_nan(p[6]),
    };
    let positional = item.has_position() && frame::is_global(frame_no);
    let coordinate = |k: usize, what: &str| -> Result<f64, MissionFileError> {
        match p[k] {
            None if positional => Err(j.invalid(
                &format!("{params_path}[{k}]"),
                format!("null {what}: command {command} needs a position (MAVSDK would send 0°)"),
            )),
            None => Ok(0.0),
            // static_cast<int32_t>(asFloat()): cut to an integer, saturating here
            Some(v) if frame_no == frame::MISSION => Ok(f64::from((v as f32) as i32)),
            Some(v) if frame::is_global(frame_no) => Ok(quantise_deg(v)),
            // an unsupported frame: the check refuses the frame
            Some(v) => Ok(v),
        }
    };
    item.x = coordinate(4, "latitude")?;
    item.y = coordinate(5, "longitude")?;
    Ok(item)
}

/// A ComplexItem: only `survey` version 5 (its `TransectStyleComplexItem.Items`).
fn complex_item(
    j: &Json<'_>,
    obj: &Map,
    path: &str,
    out: &mut Vec<(MissionItem, Origin)>,
) -> Result<(), MissionFileError> {
    let type_path = join(path, "complexItemType");
    let kind = j.required(obj, path, "complexItemType")?;
    if kind.as_str() != Some("survey") {
        return Err(j.invalid(
            &type_path,
            format!(
                "complex item {} is not supported: only \"survey\" (version 5) is, as in MAVSDK \
                 (convert it to simple items in QGroundControl)",
                super::show(kind)
            ),
        ));
    }
    let version_path = join(path, "version");
    let version = j.required(obj, path, "version")?;
    if j.whole::<i64>(version, &version_path).ok() != Some(5) {
        return Err(j.invalid(
            &version_path,
            format!(
                "survey version {} is not supported (version 5 is, as in MAVSDK)",
                super::show(version)
            ),
        ));
    }
    let transect_path = join(path, "TransectStyleComplexItem");
    let transect = j.object(j.required(obj, path, "TransectStyleComplexItem")?, &transect_path)?;
    let items_path = join(&transect_path, "Items");
    let items = j.array(j.required(transect, &transect_path, "Items")?, &items_path)?;
    if items.is_empty() {
        return Err(j.invalid(&items_path, "no survey items"));
    }
    for (k, it) in items.iter().enumerate() {
        let at = format!("{items_path}[{k}]");
        let sub = j.object(it, &at)?;
        out.push((simple_item(j, sub, &at)?, simple_origin(&at)));
    }
    Ok(())
}

/// `[lat, lon, ...]` at `path`: the two coordinates, quantised.
fn lat_lon(j: &Json<'_>, v: &serde_json::Value, path: &str, len: usize) -> Result<(f64, f64), MissionFileError> {
    let a = j.array(v, path)?;
    if a.len() < len {
        let what = if len == 3 {
            "[latitude, longitude, altitude]"
        } else {
            "[latitude, longitude]"
        };
        return Err(j.invalid(path, format!("expected {what}, found {} entries", a.len())));
    }
    let lat = j.number(&a[0], &format!("{path}[0]"))?;
    let lon = j.number(&a[1], &format!("{path}[1]"))?;
    Ok((quantise_deg(lat), quantise_deg(lon)))
}

/// A fence or rally item at a position, frame and command given, params zero.
fn point_item(command: u16, frame_no: u8, (x, y): (f64, f64), p1: f32, z: f32) -> MissionItem {
    MissionItem {
        frame: frame_no,
        command,
        autocontinue: false,
        params: [p1, 0.0, 0.0, 0.0],
        x,
        y,
        z,
    }
}

/// `geoFence`: polygon vertices, then circles.
fn geofence(j: &Json<'_>, v: &serde_json::Value) -> Result<Vec<(MissionItem, Origin)>, MissionFileError> {
    let g = j.object(v, "geoFence")?;
    j.version(g, "geoFence", 2, "geoFence")?;
    let mut out = Vec::new();
    if let Some(polygons) = g.get("polygons") {
        for (i, poly) in j.array(polygons, "geoFence.polygons")?.iter().enumerate() {
            let base = format!("geoFence.polygons[{i}]");
            let obj = j.object(poly, &base)?;
            let inclusion = match obj.get("inclusion") {
                None | Some(serde_json::Value::Null) => true,
                Some(b) => j.boolean(b, &join(&base, "inclusion"))?,
            };
            let command = if inclusion {
                cmd::FENCE_POLYGON_VERTEX_INCLUSION
            } else {
                cmd::FENCE_POLYGON_VERTEX_EXCLUSION
            };
            let vertices_path = join(&base, "polygon");
            let vertices = j.array(j.required(obj, &base, "polygon")?, &vertices_path)?;
            let count = vertices.len() as f32;
            for (k, vertex) in vertices.iter().enumerate() {
                let at = lat_lon(j, vertex, &format!("{vertices_path}[{k}]"), 2)?;
                out.push((
                    point_item(command, frame::GLOBAL, at, count, 0.0),
                    Origin::Json {
                        base: base.clone(),
                        shape: Shape::Vertex { vertex: k },
                    },
                ));
            }
        }
    }
    if let Some(circles) = g.get("circles") {
        for (i, c) in j.array(circles, "geoFence.circles")?.iter().enumerate() {
            let base = format!("geoFence.circles[{i}]");
            let obj = j.object(c, &base)?;
            let inclusion = j.boolean(j.required(obj, &base, "inclusion")?, &join(&base, "inclusion"))?;
            let circle_path = join(&base, "circle");
            let circle = j.object(j.required(obj, &base, "circle")?, &circle_path)?;
            let at = lat_lon(
                j,
                j.required(circle, &circle_path, "center")?,
                &join(&circle_path, "center"),
                2,
            )?;
            let radius_path = join(&circle_path, "radius");
            let radius = j.number_or_null(j.required(circle, &circle_path, "radius")?, &radius_path)?;
            let command = if inclusion {
                cmd::FENCE_CIRCLE_INCLUSION
            } else {
                cmd::FENCE_CIRCLE_EXCLUSION
            };
            out.push((
                point_item(command, frame::GLOBAL, at, radius.map_or(f32::NAN, |r| r as f32), 0.0),
                Origin::Json {
                    base,
                    shape: Shape::Circle,
                },
            ));
        }
    }
    Ok(out)
}

/// `rallyPoints`: 5100 in frame 3 at each `[lat, lon, alt]`.
fn rally_points(j: &Json<'_>, v: &serde_json::Value) -> Result<Vec<(MissionItem, Origin)>, MissionFileError> {
    let r = j.object(v, "rallyPoints")?;
    j.version(r, "rallyPoints", 2, "rallyPoints")?;
    let mut out = Vec::new();
    if let Some(points) = r.get("points") {
        for (i, p) in j.array(points, "rallyPoints.points")?.iter().enumerate() {
            let base = format!("rallyPoints.points[{i}]");
            let at = lat_lon(j, p, &base, 3)?;
            let alt = j.number_or_null(&j.array(p, &base)?[2], &format!("{base}[2]"))?;
            out.push((
                point_item(
                    cmd::RALLY_POINT,
                    frame::GLOBAL_RELATIVE_ALT,
                    at,
                    0.0,
                    alt.map_or(f32::NAN, |a| a as f32),
                ),
                Origin::Json {
                    base,
                    shape: Shape::Rally,
                },
            ));
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::tests::fixture;
    use super::*;
    use crate::mission::MAX_ITEMS;

    fn read(name: &str) -> String {
        std::fs::read_to_string(fixture(name)).unwrap()
    }

    fn err(text: &str) -> String {
        parse_qgc_plan(text, "t.plan").unwrap_err().to_string()
    }

    /// A .plan around `items` (JSON array text), with empty fence and rally.
    fn plan_with(items: &str) -> String {
        format!(
            r#"{{"fileType": "Plan", "version": 1,
                "mission": {{"version": 2, "items": {items}}},
                "geoFence": {{"version": 2, "polygons": [], "circles": []}},
                "rallyPoints": {{"version": 2, "points": []}}}}"#
        )
    }

    fn simple(command: u32, frame: u8, params: &str) -> String {
        format!(
            r#"{{"type": "SimpleItem", "autoContinue": true, "command": {command}, "frame": {frame}, "params": {params}}}"#
        )
    }

    #[test]
    fn mavsdk_pythons_example_mission_imports_as_mavsdk_uploads_it() {
        let p = parse_qgc_plan(&read("example-mission.plan"), "example-mission.plan").unwrap();
        let shape: Vec<(u16, u8)> = p.mission.iter().map(|i| (i.command, i.frame)).collect();
        assert_eq!(shape, [(22, 3), (16, 3), (16, 3), (16, 3), (20, 2)]);
        assert!(p.fence.is_empty() && p.rally.is_empty());
        assert!(p.mission.iter().all(|i| i.autocontinue));
        // plannedHomePosition is not prepended (PX4)
        let t = p.mission[0];
        assert_eq!(t.params[..3], [0.0, 0.0, 0.0]);
        assert!(t.params[3].is_nan(), "null param 4 is NaN");
        assert_eq!((t.x_int(), t.y_int(), t.z), (473_977_420, 85_455_939, 50.0));
        // a 15-digit coordinate is quantised to the degE7 MAVSDK sends
        let w = p.mission[1];
        assert_eq!((w.x_int(), w.y_int()), (473_982_266, 85_455_604));
        assert_eq!(w.x, 473_982_266.0 / 1e7);
        assert_eq!(w.y, 85_455_604.0 / 1e7);
        // RTL in frame 2: x/y are cut to integers, not scaled
        let rtl = p.mission[4];
        assert_eq!((rtl.x, rtl.y, rtl.z, rtl.params), (0.0, 0.0, 0.0, [0.0; 4]));
    }

    #[test]
    fn fences_and_rally_points_import_as_mavsdk_builds_them() {
        let p = parse_qgc_plan(&read("fence-rally.plan"), "fence-rally.plan").unwrap();
        let fence: Vec<(u16, u8, f32)> = p.fence.iter().map(|i| (i.command, i.frame, i.params[0])).collect();
        assert_eq!(
            fence,
            [
                // inclusion polygon of 4 vertices, exclusion polygon of 3 (no `inclusion`: true)
                (5001, 0, 4.0),
                (5001, 0, 4.0),
                (5001, 0, 4.0),
                (5001, 0, 4.0),
                (5002, 0, 3.0),
                (5002, 0, 3.0),
                (5002, 0, 3.0),
                (5001, 0, 3.0),
                (5001, 0, 3.0),
                (5001, 0, 3.0),
                // then the circles
                (5003, 0, 120.0),
                (5004, 0, 8.5),
            ]
        );
        for f in &p.fence {
            assert_eq!(
                (f.params[1..].to_vec(), f.z, f.autocontinue),
                (vec![0.0; 3], 0.0, false)
            );
        }
        assert_eq!((p.fence[1].x_int(), p.fence[1].y_int()), (473_985_000, 85_462_000));
        assert_eq!((p.fence[11].x_int(), p.fence[11].y_int()), (473_979_000, 85_452_500));
        let rally: Vec<(u16, u8, i32, i32, f32)> = p
            .rally
            .iter()
            .map(|r| (r.command, r.frame, r.x_int(), r.y_int(), r.z))
            .collect();
        assert_eq!(
            rally,
            [
                (5100, 3, 473_980_000, 85_450_000, 15.0),
                (5100, 3, 473_975_000, 85_460_000, 20.5)
            ]
        );
        assert!(p.rally.iter().all(|r| !r.autocontinue && r.params == [0.0; 4]));
    }

    #[test]
    fn a_survey_version_5_contributes_its_items_in_place() {
        let survey = format!(
            r#"{{"type": "ComplexItem", "complexItemType": "survey", "version": 5,
                 "TransectStyleComplexItem": {{"Items": [{}, {}]}}}}"#,
            simple(16, 3, "[0, 0, 0, null, 47.3981, 8.5451, 20]"),
            simple(16, 3, "[0, 0, 0, null, 47.3982, 8.5452, 20]")
        );
        let items = format!(
            "[{}, {survey}, {}]",
            simple(22, 3, "[0, 0, 0, null, 47.397742, 8.545594, 20]"),
            simple(20, 2, "[0, 0, 0, 0, 0, 0, 0]")
        );
        let p = parse_qgc_plan(&plan_with(&items), "s.plan").unwrap();
        let cmds: Vec<u16> = p.mission.iter().map(|i| i.command).collect();
        assert_eq!(cmds, [22, 16, 16, 20]);
        assert_eq!(p.mission[2].x_int(), 473_982_000);

        let e = err(&plan_with(&items.replace("\"version\": 5", "\"version\": 4")));
        assert!(
            e.contains("mission.items[1].version: survey version 4 is not supported"),
            "{e}"
        );
        let e = err(&plan_with(&items.replace("\"survey\"", "\"CorridorScan\"")));
        assert!(
            e.contains("mission.items[1].complexItemType: complex item \"CorridorScan\" is not supported"),
            "{e}"
        );
        let e = err(&plan_with(&items.replace(
            "[0, 0, 0, null, 47.3982, 8.5452, 20]",
            "[0, 0, 0, null, 97.3982, 8.5452, 20]",
        )));
        assert!(
            e.starts_with("t.plan: mission.items[1].TransectStyleComplexItem.Items[1].params[4]: latitude 97.3982"),
            "{e}"
        );
        let empty = plan_with(
            r#"[{"type": "ComplexItem", "complexItemType": "survey", "version": 5, "TransectStyleComplexItem": {"Items": []}}]"#,
        );
        assert!(err(&empty).contains("TransectStyleComplexItem.Items: no survey items"));
    }

    #[test]
    fn params_null_is_nan_frame_2_values_are_cut_like_mavsdk() {
        // DO_CHANGE_SPEED as MAVSDK's Mission plugin writes it; a gimbal item with x = flags
        let items = format!(
            "[{}, {}]",
            simple(178, 2, "[1, 10, -1, 0, 0, 0, null]"),
            simple(1000, 2, "[-10.5, 45, null, null, 12.9, -3.7, 0]")
        );
        let p = parse_qgc_plan(&plan_with(&items), "f2.plan").unwrap();
        assert_eq!(p.mission[0].params, [1.0, 10.0, -1.0, 0.0]);
        assert!(p.mission[0].z.is_nan());
        let g = p.mission[1];
        assert_eq!((g.params[0], g.params[1], g.x, g.y), (-10.5, 45.0, 12.0, -3.0));
        assert!(g.params[2].is_nan() && g.params[3].is_nan());
        // f32 rounding of params as asFloat() does
        let p = parse_qgc_plan(
            &plan_with(&format!("[{}]", simple(16, 3, "[0.1, 0, 0, 0, 47, 8, 12.3]"))),
            "r",
        )
        .unwrap();
        assert_eq!((p.mission[0].params[0], p.mission[0].z), (0.1_f32, 12.3_f32));
    }

    #[test]
    fn versions_other_than_mavsdks_are_refused_by_name() {
        let good = read("example-mission.plan");
        let e = err(&good.replace("\"version\": 1\n}", "\"version\": 2\n}"));
        assert!(
            e.contains("t.plan: version: .plan file version 2 is not supported (version 1 is"),
            "{e}"
        );
        let e = err(&good.replace(
            "\"vehicleType\": 2,\n        \"version\": 2",
            "\"vehicleType\": 2,\n        \"version\": 3",
        ));
        assert!(e.contains("mission.version: mission version 3 is not supported"), "{e}");
        let e = err(&good.replace(
            "\"polygons\": [\n        ],\n        \"version\": 2",
            "\"polygons\": []",
        ));
        assert!(e.contains("geoFence.version: missing"), "{e}");
        let e = err(&good.replace(
            "\"points\": [\n        ],\n        \"version\": 2",
            "\"points\": [], \"version\": \"2\"",
        ));
        assert!(
            e.contains("rallyPoints.version: rallyPoints version \"2\" is not supported"),
            "{e}"
        );
        assert!(err(r#"{"version": 1}"#).contains("t.plan: mission: missing"));
        assert!(err("[1, 2]").contains("t.plan: (top level): expected an object, found an array"));
    }

    #[test]
    fn missing_fence_and_rally_sections_mean_none() {
        let p = parse_qgc_plan(
            &format!(
                r#"{{"version": 1, "mission": {{"version": 2, "items": [{}]}}}}"#,
                simple(22, 3, "[0, 0, 0, null, 47.397742, 8.545594, 10]")
            ),
            "m.plan",
        )
        .unwrap();
        assert_eq!((p.mission.len(), p.fence.len(), p.rally.len()), (1, 0, 0));
    }

    #[test]
    fn every_problem_names_the_file_the_json_path_and_what_is_wrong() {
        let wp = |params: &str| {
            plan_with(&format!(
                "[{}, {}]",
                simple(22, 3, "[0,0,0,null,47.39,8.54,10]"),
                simple(16, 3, params)
            ))
        };
        for (text, want) in [
            (
                "{\"version\": 1,\n \"mission\": [}".to_string(),
                "t.plan:2:14: expected value",
            ),
            (
                wp("[0, 0, 0, null, 123.4, 8.5, 10]"),
                "t.plan: mission.items[1].params[4]: latitude 123.4 is not within ±90° (MAV_MISSION_INVALID_PARAM5_X)",
            ),
            (
                wp("[0, 0, 0, null, 47.4, -181, 10]"),
                "mission.items[1].params[5]: longitude -181 is not within ±180°",
            ),
            (
                wp("[0, 0, 0, null, 47.4, 8.5, null]"),
                "mission.items[1].params[6]: altitude NaN is not a number (MAV_MISSION_INVALID_PARAM7)",
            ),
            (
                wp("[-2, 0, 0, null, 47.4, 8.5, 10]"),
                "mission.items[1].params[0]: param1 = -2 is refused: command 16 needs a hold time ≥ 0 s",
            ),
            (
                wp("[0, 0, 0, null, null, 8.5, 10]"),
                "mission.items[1].params[4]: null latitude: command 16 needs a position",
            ),
            (
                wp("[0, 0, 0, null, 47.4, 8.5]"),
                "mission.items[1].params: expected 7 params",
            ),
            (
                wp("[0, 0, \"x\", null, 47.4, 8.5, 10]"),
                "mission.items[1].params[2]: expected a number or null, found \"x\"",
            ),
            (
                wp("[0, 0, 0, null, 1e300, 8.5, 10]"),
                "mission.items[1].params[4]: latitude 1e300 is not within ±90°",
            ),
            (
                plan_with(&format!("[{}]", simple(16, 2, "[0,0,0,0,0,0,0]"))),
                "mission.items[0].frame: command 16 needs a position, and frame 2",
            ),
            (
                plan_with(&format!("[{}]", simple(16, 1, "[0,0,0,0,0,0,0]"))),
                "mission.items[0].frame: frame 1 is not supported",
            ),
            (
                plan_with(&format!("[{}]", simple(5001, 0, "[4,0,0,0,47,8,0]"))),
                "mission.items[0].command: command 5001 is not a mission command",
            ),
            (
                plan_with(&format!("[{}]", simple(70000, 3, "[0,0,0,0,47,8,0]"))),
                "mission.items[0].command: expected a whole number that fits u16, found 70000",
            ),
            (
                plan_with(&format!(
                    "[{}]",
                    simple(16, 3, "[0,0,0,0,47,8,0]").replace("true", "\"yes\"")
                )),
                "mission.items[0].autoContinue: expected true or false",
            ),
            (
                plan_with(r#"[{"type": "SimpleItem", "command": 16, "frame": 3, "params": [0,0,0,0,47,8,0]}]"#),
                "mission.items[0].autoContinue: missing",
            ),
            (
                plan_with(r#"[{"type": "Waypoint"}]"#),
                "mission.items[0].type: expected \"SimpleItem\" or \"ComplexItem\", found \"Waypoint\"",
            ),
            (plan_with(r#"[{"command": 16}]"#), "mission.items[0].type: missing"),
            (
                plan_with(r#"[7]"#),
                "mission.items[0]: expected an object, found a number",
            ),
            (
                plan_with(r#"{"a": 1}"#),
                "mission.items: expected an array, found an object",
            ),
        ] {
            let e = err(&text);
            assert!(e.contains(want), "want `{want}` in\n{e}");
        }
    }

    #[test]
    fn fence_and_rally_problems_name_their_json_paths() {
        let with = |fence: &str, rally: &str| {
            format!(
                r#"{{"version": 1, "mission": {{"version": 2, "items": []}},
                    "geoFence": {{"version": 2, {fence}}}, "rallyPoints": {{"version": 2, "points": {rally}}}}}"#
            )
        };
        for (text, want) in [
            (
                with(r#""polygons": [{"polygon": [[47.1, 8.1], [47.2, 8.2]]}]"#, "[]"),
                "geoFence.polygons[0].polygon: param1 = 2 is refused: command 5001 needs a vertex count of 3 or more",
            ),
            (
                with(
                    r#""polygons": [{"polygon": [[47.1, 8.1], [47.2, 8.2], [95, 8.3]]}]"#,
                    "[]",
                ),
                "geoFence.polygons[0].polygon[2][0]: latitude 95 is not within ±90°",
            ),
            (
                with(r#""polygons": [{"polygon": [[47.1, 8.1], [47.2], [47.3, 8.3]]}]"#, "[]"),
                "geoFence.polygons[0].polygon[1]: expected [latitude, longitude], found 1 entries",
            ),
            (
                with(
                    r#""polygons": [{"polygon": [[47.1, 8.1], [47.2, null], [47.3, 8.3]]}]"#,
                    "[]",
                ),
                "geoFence.polygons[0].polygon[1][1]: expected a number, found null",
            ),
            (
                with(r#""polygons": [{"inclusion": "yes", "polygon": []}]"#, "[]"),
                "geoFence.polygons[0].inclusion: expected true or false",
            ),
            (
                with(
                    r#""circles": [{"inclusion": true, "circle": {"center": [47.1, 8.1], "radius": -5}}]"#,
                    "[]",
                ),
                "geoFence.circles[0].circle.radius: param1 = -5 is refused: command 5003 needs a radius ≥ 0 m",
            ),
            (
                with(
                    r#""circles": [{"inclusion": true, "circle": {"center": [47.1, 8.1], "radius": null}}]"#,
                    "[]",
                ),
                "geoFence.circles[0].circle.radius: param1 = NaN",
            ),
            (
                with(
                    r#""circles": [{"inclusion": true, "circle": {"center": [47.1, 200], "radius": 5}}]"#,
                    "[]",
                ),
                "geoFence.circles[0].circle.center[1]: longitude 200 is not within ±180°",
            ),
            (
                with(r#""circles": [{"circle": {"center": [47.1, 8.1], "radius": 5}}]"#, "[]"),
                "geoFence.circles[0].inclusion: missing",
            ),
            (
                with(r#""circles": [{"inclusion": false, "circle": {"radius": 5}}]"#, "[]"),
                "geoFence.circles[0].circle.center: missing",
            ),
            (
                with(r#""circles": []"#, "[[47.1, 8.1, null]]"),
                "rallyPoints.points[0][2]: altitude NaN is not a number",
            ),
            (
                with(r#""circles": []"#, "[[47.1, 8.1]]"),
                "rallyPoints.points[0]: expected [latitude, longitude, altitude], found 2 entries",
            ),
            (
                with(r#""circles": []"#, "[[47.1, 8.1, 5], [-91, 8.1, 5]]"),
                "rallyPoints.points[1][0]: latitude -91 is not within ±90°",
            ),
        ] {
            let e = parse_qgc_plan(&text, "f.plan").unwrap_err().to_string();
            assert!(e.starts_with("f.plan: ") && e.contains(want), "want `{want}` in\n{e}");
        }
    }

    #[test]
    fn more_items_than_the_vehicle_stores_is_refused_at_the_list() {
        let one = simple(16, 3, "[0, 0, 0, null, 47.39, 8.54, 10]");
        let items = format!("[{}]", vec![one.as_str(); MAX_ITEMS + 1].join(","));
        let e = err(&plan_with(&items));
        assert!(e.contains("t.plan: mission.items: more than 20000 items"), "{e}");
        let items = format!("[{}]", vec![one.as_str(); MAX_ITEMS].join(","));
        assert_eq!(
            parse_qgc_plan(&plan_with(&items), "t").unwrap().mission.len(),
            MAX_ITEMS
        );
    }

    #[test]
    fn no_input_makes_it_panic() {
        // truncations and byte flips of a real file: errors or plans, never a panic
        let good = read("fence-rally.plan");
        for cut in (0..good.len()).step_by(7) {
            if good.is_char_boundary(cut) {
                let _ = parse_qgc_plan(&good[..cut], "cut.plan");
            }
        }
        for v in ["null", "1", "\"s\"", "[]", "{}", "true", "-1e999", "1e999"] {
            let _ = parse_qgc_plan(v, "v.plan");
            let _ = parse_qgc_plan(&plan_with(&format!("[{v}]")), "v.plan");
            let _ = parse_qgc_plan(
                &plan_with(&format!(
                    "[{}]",
                    simple(16, 3, &format!("[{v},{v},{v},{v},{v},{v},{v}]"))
                )),
                "v.plan",
            );
        }
    }
}
