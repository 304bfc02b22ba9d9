//! QGC WPL 110 text: the waypoint files of MAVProxy (`wp save`, `wp load`),
//! Mission Planner and pymavlink's `mavwp.MAVWPLoader`.
//!
//! ```text
//! QGC WPL 110
//! # seq current frame command p1 p2 p3 p4 x y z autocontinue
//! 0 1 0 16 0 0 0 0 47.397742 8.545594 488.0 1
//! 1 0 3 22 0 0 0 0 47.397742 8.545594 10.0 1
//! 2 0 3 20 0 0 0 0 0 0 0 1
//! ```
//!
//! The first line is the header `QGC WPL 110`; then one item per line, twelve
//! fields separated by tabs or spaces; empty lines and lines starting with
//! `#` are skipped (as `MAVWPLoader` does). Every item is kept, seq 0
//! included: MAVProxy's files begin with a home item, which `wp load` uploads
//! and PX4 flies as an ordinary waypoint. `seq` must count 0, 1, 2... in file
//! order; `current` is read and ignored (the vehicle keeps its own). A
//! command 0 at seq 0 is a waypoint (16), as `MAVWPLoader` reads Mission
//! Planner's home item.
//!
//! Values as MAVProxy uploads them (MISSION_ITEM_INT): p1..p4 and z as f32;
//! x and y in global frames quantised to degE7 (`round(v * 1e7)`; MAVProxy
//! itself cuts `int(v * 1e7)`, so one coordinate in about sixteen with seven
//! decimals lands 1e-7° (about 1 cm) nearer zero there), in other frames the value as
//! written. A file of fence items only (5000 to 5004, MAVProxy `fence save`)
//! is a geofence, of rally points only (5100) a rally plan; anything else is
//! a mission.

use super::{MissionFileError, Origin, PlanFile, check_plan, wpl_field};
use crate::mission::quantise_deg;
use crate::mission::{MissionItem, MissionType, cmd, frame};

/// The header line.
const HEADER: &str = "QGC WPL 110";

/// Read QGC WPL 110 text; `file` labels errors.
///
/// # Errors
/// A bad header, a line without twelve fields, a field that is not a number
/// of its kind, a seq out of order, or an item the vehicle would refuse: each
/// names the file, the line, the field and the problem.
pub fn parse_wpl(text: &str, file: &str) -> Result<PlanFile, MissionFileError> {
    let line_error = |line: usize, field: String, problem: String| MissionFileError::Line {
        file: file.to_string(),
        line,
        field,
        problem,
    };
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l));
    let header = lines.next().map_or("", |(_, l)| l.trim());
    if header != HEADER {
        let problem = if header.is_empty() {
            format!("empty first line: a QGC WPL 110 file starts with the line `{HEADER}`")
        } else if header.starts_with("QGC WPL") {
            format!("`{header}` files are not read: save it as `{HEADER}` (MAVProxy `wp save`)")
        } else if header.starts_with('{') {
            format!("expected `{HEADER}`, found JSON: a QGroundControl plan? name it .plan")
        } else {
            let shown: String = header.chars().take(40).collect();
            format!("expected `{HEADER}`, found `{shown}`")
        };
        return Err(line_error(1, "header".into(), problem));
    }

    let mut items: Vec<(MissionItem, Origin)> = Vec::new();
    for (line_no, raw) in lines {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.len() != 12 {
            return Err(line_error(
                line_no,
                "line".into(),
                format!(
                    "{} fields; an item has 12: seq current frame command p1 p2 p3 p4 x y z autocontinue",
                    fields.len()
                ),
            ));
        }
        let whole = |k: usize, max: i64| -> Result<i64, MissionFileError> {
            match fields[k].parse::<i64>() {
                Ok(v) if (0..=max).contains(&v) => Ok(v),
                _ => Err(line_error(
                    line_no,
                    wpl_field(k),
                    format!("`{}` is not a whole number from 0 to {max}", fields[k]),
                )),
            }
        };
        let number = |k: usize| -> Result<f64, MissionFileError> {
            fields[k]
                .parse::<f64>()
                .map_err(|_| line_error(line_no, wpl_field(k), format!("`{}` is not a number", fields[k])))
        };
        let expected = items.len();
        let seq = whole(0, i64::from(u16::MAX))?;
        if usize::try_from(seq).ok() != Some(expected) {
            return Err(line_error(
                line_no,
                wpl_field(0),
                format!("seq {seq} out of order: expected {expected} (items count from 0 in file order)"),
            ));
        }
        let _current = whole(1, 1)?;
        let frame_no = whole(2, i64::from(u8::MAX))? as u8;
        let mut command = whole(3, i64::from(u16::MAX))? as u16;
        if command == 0 && seq == 0 {
            // MAVWPLoader: Mission Planner's home item
            command = cmd::NAV_WAYPOINT;
        }
        let params = [
            number(4)? as f32,
            number(5)? as f32,
            number(6)? as f32,
            number(7)? as f32,
        ];
        let (mut x, mut y) = (number(8)?, number(9)?);
        if frame::is_global(frame_no) {
            x = quantise_deg(x);
            y = quantise_deg(y);
        }
        let z = number(10)? as f32;
        let autocontinue = whole(11, 1)? == 1;
        items.push((
            MissionItem {
                frame: frame_no,
                command,
                autocontinue,
                params,
                x,
                y,
                z,
            },
            Origin::Line(line_no),
        ));
    }

    let all = |f: fn(u16) -> bool| !items.is_empty() && items.iter().all(|(it, _)| f(it.command));
    let kind = if all(|c| (cmd::FENCE_RETURN_POINT..=cmd::FENCE_CIRCLE_EXCLUSION).contains(&c)) {
        MissionType::Fence
    } else if all(|c| c == cmd::RALLY_POINT) {
        MissionType::Rally
    } else {
        MissionType::Mission
    };
    let list = Origin::Line(1);
    let checked = check_plan(file, kind, items, &list)?;
    let mut out = PlanFile::default();
    match kind {
        MissionType::Mission => out.mission = checked,
        MissionType::Fence => out.fence = checked,
        MissionType::Rally => out.rally = checked,
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::tests::fixture;
    use super::*;
    use crate::mission::MAX_ITEMS;

    fn err(text: &str) -> String {
        parse_wpl(text, "w.txt").unwrap_err().to_string()
    }

    const TAKEOFF: &str = "1 0 3 22 0 0 0 0 47.397742 8.545594 10 1";

    #[test]
    fn mavproxys_file_with_its_home_item_loads_every_item() {
        let p = parse_wpl(&std::fs::read_to_string(fixture("mavproxy-home.txt")).unwrap(), "h.txt").unwrap();
        let shape: Vec<(u16, u8)> = p.mission.iter().map(|i| (i.command, i.frame)).collect();
        assert_eq!(shape, [(16, 0), (22, 3), (16, 3), (16, 3), (20, 3)]);
        let home = p.mission[0];
        assert_eq!((home.x_int(), home.y_int(), home.z), (473_977_420, 85_455_940, 488.0));
        assert_eq!(home.x, 47.397_742);
        assert_eq!((p.mission[3].x_int(), p.mission[3].y_int()), (473_981_000, 85_461_000));
        assert!(p.mission.iter().all(|i| i.autocontinue && i.params == [0.0; 4]));
        assert!(p.fence.is_empty() && p.rally.is_empty());
    }

    #[test]
    fn spaces_comments_blank_lines_crlf_and_mission_planners_home_are_read() {
        let text = "QGC WPL 110\r\n\r\n# a comment\r\n0  1 0 0 0 0 0 0 47.3977 8.5456 488 1\r\n   # indented comment\r\n\
                    1\t0\t3\t16\t0.5\t2\t0\tnan\t47.39801234567\t8.54560000004\t12.3\t0\r\n2 0 2 178 1 7.5 -1 0 0.4 -2.9 0 1\r\n";
        let p = parse_wpl(text, "s.txt").unwrap();
        assert_eq!(p.mission.len(), 3);
        assert_eq!(p.mission[0].command, 16, "command 0 at seq 0 is a waypoint");
        let w = p.mission[1];
        assert_eq!(
            (w.params[0], w.params[1], w.z, w.autocontinue),
            (0.5, 2.0, 12.3_f32, false)
        );
        assert!(w.params[3].is_nan());
        assert_eq!((w.x_int(), w.y_int()), (473_980_123, 85_456_000));
        assert_eq!(w.x, 473_980_123.0 / 1e7);
        // frame 2: x and y as written
        let s = p.mission[2];
        assert_eq!((s.x, s.y, s.params), (0.4, -2.9, [1.0, 7.5, -1.0, 0.0]));
    }

    #[test]
    fn a_file_of_fence_or_rally_items_is_that_plan() {
        let fence = "QGC WPL 110\n0 0 0 5001 3 0 0 0 47.1 8.1 0 0\n1 0 0 5001 3 0 0 0 47.2 8.1 0 0\n2 0 0 5001 3 0 0 0 47.2 8.2 0 0\n3 0 0 5003 50 0 0 0 47.15 8.15 0 0\n";
        let p = parse_wpl(fence, "f.txt").unwrap();
        assert_eq!((p.mission.len(), p.fence.len(), p.rally.len()), (0, 4, 0));
        let rally = "QGC WPL 110\n0 0 3 5100 0 0 0 0 47.1 8.1 15 0\n";
        let p = parse_wpl(rally, "r.txt").unwrap();
        assert_eq!((p.mission.len(), p.fence.len(), p.rally.len()), (0, 0, 1));
        // mixed: a mission, and the fence vertex in it is named
        let e = err(&format!(
            "QGC WPL 110\n0 0 3 22 0 0 0 0 47.1 8.1 10 1\n{}",
            "1 0 0 5001 3 0 0 0 47.2 8.1 0 0\n"
        ));
        assert!(
            e.contains("w.txt:3: field 4 (command): command 5001 is not a mission command"),
            "{e}"
        );
        // an empty file is an empty mission
        assert_eq!(parse_wpl("QGC WPL 110\n", "e.txt").unwrap(), PlanFile::default());
    }

    #[test]
    fn every_problem_names_the_file_the_line_the_field_and_what_is_wrong() {
        for (text, want) in [
            (String::new(), "w.txt:1: header: empty first line"),
            (
                "QGC WPL 100\n".into(),
                "w.txt:1: header: `QGC WPL 100` files are not read",
            ),
            (
                "waypoints\n".into(),
                "w.txt:1: header: expected `QGC WPL 110`, found `waypoints`",
            ),
            (
                "QGC WPL 110\n0 1 0 16 0 0 0 0 47 8 488\n".to_string(),
                "w.txt:2: line: 11 fields; an item has 12",
            ),
            (
                format!("QGC WPL 110\n{TAKEOFF}\n"),
                "w.txt:2: field 1 (seq): seq 1 out of order: expected 0",
            ),
            (
                "QGC WPL 110\n0 1 0 16 0 0 0 0 47 8 488 1\n\n2 0 3 16 0 0 0 0 47 8 10 1\n".to_string(),
                "w.txt:4: field 1 (seq): seq 2 out of order: expected 1",
            ),
            (
                "QGC WPL 110\n-1 1 0 16 0 0 0 0 47 8 488 1\n".into(),
                "w.txt:2: field 1 (seq): `-1` is not a whole number from 0 to 65535",
            ),
            (
                "QGC WPL 110\n0 2 0 16 0 0 0 0 47 8 488 1\n".into(),
                "field 2 (current): `2` is not a whole number from 0 to 1",
            ),
            (
                "QGC WPL 110\n0 1 300 16 0 0 0 0 47 8 488 1\n".into(),
                "field 3 (frame): `300` is not a whole number from 0 to 255",
            ),
            (
                "QGC WPL 110\n0 1 0 16.0 0 0 0 0 47 8 488 1\n".into(),
                "field 4 (command): `16.0` is not a whole number",
            ),
            (
                "QGC WPL 110\n0 1 0 16 0 0 0 0 47.3.9 8 488 1\n".into(),
                "w.txt:2: field 9 (x / latitude): `47.3.9` is not a number",
            ),
            (
                "QGC WPL 110\n0 1 0 16 0 0 0 0 47 8 high 1\n".into(),
                "field 11 (z / altitude): `high` is not a number",
            ),
            (
                "QGC WPL 110\n0 1 0 16 0 0 0 0 47 8 488 yes\n".into(),
                "field 12 (autocontinue): `yes` is not a whole number from 0 to 1",
            ),
            (
                "QGC WPL 110\n0 1 0 16 0 0 0 0 97 8 488 1\n".into(),
                "w.txt:2: field 9 (x / latitude): latitude 97 is not within ±90° (MAV_MISSION_INVALID_PARAM5_X)",
            ),
            (
                "QGC WPL 110\n0 1 0 16 0 0 0 0 47 -190 488 1\n".into(),
                "field 10 (y / longitude): longitude -190 is not within ±180°",
            ),
            (
                "QGC WPL 110\n0 1 0 16 0 0 0 0 47 8 inf 1\n".into(),
                "field 11 (z / altitude): altitude inf is not a number",
            ),
            (
                "QGC WPL 110\n0 1 0 16 0 -3 0 0 47 8 10 1\n".into(),
                "field 6 (param2): param2 = -3 is refused: command 16 needs an acceptance radius ≥ 0 m",
            ),
            (
                "QGC WPL 110\n0 1 2 16 0 0 0 0 47 8 10 1\n".into(),
                "field 3 (frame): command 16 needs a position, and frame 2",
            ),
            (
                "QGC WPL 110\n0 1 3 9999 0 0 0 0 47 8 10 1\n".into(),
                "field 4 (command): command 9999 is not a mission command",
            ),
        ] {
            let e = err(&text);
            assert!(e.contains(want), "want `{want}` in\n{e}");
        }
    }

    #[test]
    fn more_items_than_the_vehicle_stores_is_refused_at_the_first_extra_line() {
        let mut text = String::from("QGC WPL 110\n");
        for i in 0..=MAX_ITEMS {
            text.push_str(&format!("{i} 0 3 16 0 0 0 0 47.39 8.54 10 1\n"));
        }
        let e = err(&text);
        assert!(
            e.contains(&format!("w.txt:{}: item: more than 20000 items", MAX_ITEMS + 2)),
            "{e}"
        );
    }

    #[test]
    fn no_input_makes_it_panic() {
        let good = std::fs::read_to_string(fixture("mavproxy-home.txt")).unwrap();
        for cut in 0..good.len() {
            if good.is_char_boundary(cut) {
                let _ = parse_wpl(&good[..cut], "cut.txt");
            }
        }
        for junk in [
            "\u{0}",
            "QGC WPL 110\n\u{feff}",
            "QGC WPL 110\n0 0 0 0 0 0 0 0 0 0 0 0 0",
            "QGC WPL 110\n99999999999999999999 1 0 16 0 0 0 0 47 8 488 1",
        ] {
            let _ = parse_wpl(junk, "j.txt");
        }
    }
}
