//! The report page as one HTML string: the verdict, the north/east path
//! (SVG), the modes and arming timeline and the events table are rendered
//! here; the time series go into the page as JSON and `report/report.js`
//! draws them with uPlot. Every script and style is inlined (uPlot's
//! minified build and CSS from `report/vendor/`, pinned by
//! `tools/vendor_report_assets.sh`): the page loads nothing.

use std::fmt::Write as _;

use serde::Serialize;

use super::{EventKind, FlightReport, Series, command_name};

/// uPlot's minified IIFE build (MIT, `report/vendor/LICENSE-uPlot`).
const UPLOT_JS: &str = include_str!("../../../report/vendor/uPlot.iife.min.js");
/// uPlot's stylesheet.
const UPLOT_CSS: &str = include_str!("../../../report/vendor/uPlot.min.css");
/// uPlot's licence, quoted in the page beside its code.
const UPLOT_LICENSE: &str = include_str!("../../../report/vendor/LICENSE-uPlot");
/// The page's own script: the plots from the JSON data.
const REPORT_JS: &str = include_str!("../../../report/report.js");
/// The page's own stylesheet.
const REPORT_CSS: &str = include_str!("../../../report/report.css");

/// `s` with HTML's special characters escaped.
fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&#39;"),
            c => o.push(c),
        }
    }
    o
}

/// `x` rounded to a thousandth (mm, mrad, mN: finer than a page shows); NaN stays NaN.
fn milli(x: f64) -> f64 {
    (x * 1000.0).round() / 1000.0
}

/// The series as the script reads them (NaN becomes `null`: a gap).
#[derive(Serialize)]
struct PlotData<'a> {
    t: Vec<f64>,
    names: &'a [String],
    columns: Vec<Vec<f64>>,
    rotor_unit: &'a str,
    events: Vec<(f64, EventKind, &'a str)>,
}

/// JSON that may sit inside a `<script>` element (`</` written `<\/`).
fn script_json<T: Serialize>(v: &T) -> String {
    serde_json::to_string(v)
        .unwrap_or_else(|_| "{}".into())
        .replace("</", "<\\/")
}

fn fmt_s(t: f64) -> String {
    format!("{t:.2} s")
}

/// A share 0..1 as a percentage: to 0.1 %, or to 0.001 % under 0.1 % (a
/// step or two of a long flight is not shown as 0.0 %).
fn fmt_percent(share: f64) -> String {
    let percent = 100.0 * share;
    if percent < 0.1 {
        format!("{percent:.3}")
    } else {
        format!("{percent:.1}")
    }
}

/// Metres to a decimetre, with no minus sign on a value that rounds to 0
/// (a landing item at `-0.0 m`).
fn fmt_dm(x: f64) -> String {
    let s = format!("{x:.1}");
    if s == "-0.0" { "0.0".into() } else { s }
}

/// The page.
#[must_use]
pub fn page(r: &FlightReport) -> String {
    let mut h = String::with_capacity(2 << 20);
    let title = esc(&r.meta.title);
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\
         <title>{title} - rotorpilot flight report</title>\n<style>{UPLOT_CSS}\n{REPORT_CSS}</style></head>\n<body>\n"
    );
    verdict(&mut h, r);
    path(&mut h, r);
    timeline(&mut h, r);
    h.push_str(
        "<section id=\"plots\"><h2>Over time</h2><p class=\"hint\">Drag to zoom (double-click resets), \
         the cursor is shared; vertical lines: failsafes (red), failures injected (orange), items reached \
         (green), other texts (grey).</p><div id=\"plot-grid\"></div></section>\n",
    );
    events(&mut h, r);
    let s = &r.series;
    let data = PlotData {
        t: s.t.iter().map(|t| milli(*t)).collect(),
        names: &s.names,
        columns: s
            .columns
            .iter()
            .map(|c| c.iter().map(|x| milli(*x)).collect())
            .collect(),
        rotor_unit: &s.rotor_unit,
        events: r
            .events
            .iter()
            .map(|e| (milli(e.t_s), e.kind, e.text.as_str()))
            .collect(),
    };
    let _ = write!(
        h,
        "<footer>rotorpilot {} &middot; plots by uPlot 1.6.32 (MIT licence, below)<pre class=\"licence\">{}</pre></footer>\n\
         <script>{UPLOT_JS}</script>\n<script type=\"application/json\" id=\"report-data\">{}</script>\n\
         <script>{REPORT_JS}</script>\n</body></html>\n",
        esc(&r.meta.rotorpilot),
        esc(UPLOT_LICENSE),
        script_json(&data)
    );
    h
}

fn verdict(h: &mut String, r: &FlightReport) {
    let m = &r.meta;
    let v = &r.verdict;
    h.push_str("<header id=\"verdict\">");
    let failsafes: Vec<_> = r.events.iter().filter(|e| e.kind == EventKind::Failsafe).collect();
    let failures: Vec<_> = r.events.iter().filter(|e| e.kind == EventKind::Failure).collect();
    let reached = v.items.iter().filter(|i| i.reached_s.is_some()).count();
    let badge = match v.outcome.as_deref() {
        Some(o) => format!("<span class=\"badge {}\">{}</span>", esc(o), esc(&o.to_uppercase())),
        None => String::new(),
    };
    let _ = write!(h, "<h1>{badge}{}</h1>", esc(&m.title));
    let _ = write!(
        h,
        "<p class=\"meta\">{} ({}) &middot; airframe {} &middot; {} simulated &middot; rotorpilot {}</p>",
        esc(&m.source),
        esc(&m.method),
        esc(&m.airframe),
        fmt_s(r.duration_s),
        esc(&m.rotorpilot)
    );
    if let Some(c) = &m.reproduce {
        let _ = write!(h, "<p class=\"meta\">reproduce: <code>{}</code></p>", esc(c));
    }
    h.push_str("<ul class=\"summary\">");
    for reason in &v.reasons {
        let _ = write!(h, "<li class=\"bad\">{}</li>", esc(reason));
    }
    if !v.items.is_empty() {
        let _ = write!(h, "<li>mission: {reached} of {} items reached</li>", v.items.len());
    }
    match v.max_tracking_error {
        Some((e, t)) => {
            let _ = write!(
                h,
                "<li>largest tracking error {e:.3} m at {} (distance from the reference {})</li>",
                fmt_s(t),
                v.tracking_counted
            );
        }
        None => h.push_str("<li>no reference tracked in the air</li>"),
    }
    if let Some(l) = &v.rotor_limit {
        let _ = match l.first_s {
            Some(t) => write!(
                h,
                "<li class=\"{}\">rotor commands at a limit {} % of the time in the air, first at {} ({})</li>",
                if l.share >= 0.01 { "bad" } else { "" },
                fmt_percent(l.share),
                fmt_s(t),
                l.counted
            ),
            None => write!(
                h,
                "<li>rotor commands at a limit: never in the air ({})</li>",
                l.counted
            ),
        };
    }
    let _ = write!(
        h,
        "<li class=\"{}\">failsafes: {}</li>",
        if failsafes.is_empty() { "" } else { "bad" },
        if failsafes.is_empty() {
            "none".to_string()
        } else {
            failsafes
                .iter()
                .map(|e| format!("{} at {}", esc(&e.text), fmt_s(e.t_s)))
                .collect::<Vec<_>>()
                .join("; ")
        }
    );
    let _ = write!(
        h,
        "<li>failures injected: {}</li>",
        if failures.is_empty() {
            "none".to_string()
        } else {
            failures
                .iter()
                .map(|e| format!("{} at {}", esc(&e.text), fmt_s(e.t_s)))
                .collect::<Vec<_>>()
                .join("; ")
        }
    );
    let _ = write!(h, "<li>at the end: {}</li>", esc(&v.final_state));
    for n in &m.notes {
        let _ = write!(h, "<li class=\"note\">{}</li>", esc(n));
    }
    h.push_str("</ul>");
    if !v.items.is_empty() {
        h.push_str(
            "<table class=\"items\"><thead><tr><th>item</th><th>command</th><th>reached at</th>\
             <th title=\"distance from the true position to the item's point at the first reach, as the summaries' m off\">off at first reach</th><th>times</th></tr></thead><tbody>",
        );
        for i in &v.items {
            let _ = write!(
                h,
                "<tr class=\"{}\"><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                if i.reached_s.is_some() { "ok" } else { "never" },
                i.seq,
                esc(&command_name(i.command)),
                i.reached_s.map_or("-".into(), fmt_s),
                i.distance_m.map_or(String::new(), |d| format!("{d:.2} m")),
                i.times
            );
        }
        h.push_str("</tbody></table>");
    }
    h.push_str("</header>\n");
}

/// North/east bounds of everything drawn, with a margin: (n_min, n_max, e_min, e_max).
fn bounds(r: &FlightReport) -> (f64, f64, f64, f64) {
    let mut b = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut add = |n: f64, e: f64| {
        if n.is_finite() && e.is_finite() {
            b = (b.0.min(n), b.1.max(n), b.2.min(e), b.3.max(e));
        }
    };
    let s = &r.series;
    for (n, e) in s.column("n").iter().zip(s.column("e")) {
        add(*n, *e);
    }
    for (n, e) in s.column("ref_n").iter().zip(s.column("ref_e")) {
        add(*n, *e);
    }
    for p in &r.plans.mission {
        add(p.n, p.e);
    }
    for f in &r.plans.fence {
        for p in &f.points {
            let rad = f.radius_m.unwrap_or(0.0);
            add(p[0] - rad, p[1] - rad);
            add(p[0] + rad, p[1] + rad);
        }
    }
    for p in &r.plans.rally {
        add(p[0], p[1]);
    }
    let span = (b.1 - b.0).max(b.3 - b.2).max(10.0);
    let pad = span * 0.08;
    (b.0 - pad, b.1 + pad, b.2 - pad, b.3 + pad)
}

fn path(h: &mut String, r: &FlightReport) {
    let (n0, n1, e0, e1) = bounds(r);
    let (w, ht) = (e1 - e0, n1 - n0);
    let unit = w.max(ht) / 100.0;
    // x = east, y = -north: north up
    let _ = write!(
        h,
        "<section id=\"path\"><h2>Path, north up (true position; m from home)</h2>\
         <svg id=\"path-svg\" viewBox=\"{e0:.3} {:.3} {w:.3} {ht:.3}\" preserveAspectRatio=\"xMidYMid meet\">",
        -n1
    );
    // a grid line every power of ten that gives 2..20 lines
    let step = 10f64.powf((w.max(ht) / 2.0).log10().floor()).max(1.0);
    let mut g = String::new();
    let mut x = (e0 / step).ceil() * step;
    while x <= e1 {
        let _ = write!(
            g,
            "<line class=\"grid\" x1=\"{x:.3}\" y1=\"{:.3}\" x2=\"{x:.3}\" y2=\"{:.3}\"/>",
            -n1, -n0
        );
        x += step;
    }
    let mut y = (n0 / step).ceil() * step;
    while y <= n1 {
        let _ = write!(
            g,
            "<line class=\"grid\" x1=\"{e0:.3}\" y1=\"{:.3}\" x2=\"{e1:.3}\" y2=\"{:.3}\"/>",
            -y, -y
        );
        y += step;
    }
    h.push_str(&g);
    for f in &r.plans.fence {
        let class = if f.inclusion { "fence-in" } else { "fence-out" };
        match f.radius_m {
            Some(rad) => {
                if let Some(c) = f.points.first() {
                    let _ = write!(
                        h,
                        "<circle class=\"{class}\" cx=\"{:.3}\" cy=\"{:.3}\" r=\"{rad:.3}\"/>",
                        c[1], -c[0]
                    );
                }
            }
            None => {
                let pts: Vec<String> = f.points.iter().map(|p| format!("{:.3},{:.3}", p[1], -p[0])).collect();
                let _ = write!(h, "<polygon class=\"{class}\" points=\"{}\"/>", pts.join(" "));
            }
        }
    }
    if r.plans.mission.len() > 1 {
        let pts: Vec<String> = r
            .plans
            .mission
            .iter()
            .map(|p| format!("{:.3},{:.3}", p.e, -p.n))
            .collect();
        let _ = write!(h, "<polyline class=\"plan\" points=\"{}\"/>", pts.join(" "));
    }
    let s = &r.series;
    let points = |n: &str, e: &str| -> Vec<String> {
        s.column(n)
            .iter()
            .zip(s.column(e))
            .filter(|(n, e)| n.is_finite() && e.is_finite())
            .map(|(n, e)| format!("{:.2},{:.2}", e, -n))
            .collect()
    };
    // the reference tracked, where there was one (a plain scenario's curve, a mission's legs)
    let reference = points("ref_n", "ref_e");
    if !reference.is_empty() {
        let _ = write!(
            h,
            "<polyline id=\"reference\" class=\"reference\" data-points=\"{}\" points=\"{}\"/>",
            reference.len(),
            reference.join(" ")
        );
    }
    let track = points("n", "e");
    let _ = write!(
        h,
        "<polyline id=\"track\" class=\"track\" data-points=\"{}\" points=\"{}\"/>",
        track.len(),
        track.join(" ")
    );
    let _ = write!(
        h,
        "<g class=\"home\"><rect x=\"{:.3}\" y=\"{:.3}\" width=\"{:.3}\" height=\"{:.3}\"/>\
         <text x=\"{:.3}\" y=\"{:.3}\" font-size=\"{:.3}\">H</text></g>",
        -unit,
        -unit,
        2.0 * unit,
        2.0 * unit,
        1.5 * unit,
        -1.5 * unit,
        3.0 * unit
    );
    for p in &r.plans.rally {
        let _ = write!(
            h,
            "<g class=\"rally\"><polygon points=\"{:.3},{:.3} {:.3},{:.3} {:.3},{:.3}\"/>\
             <text x=\"{:.3}\" y=\"{:.3}\" font-size=\"{:.3}\">R</text></g>",
            p[1],
            -p[0] - 1.5 * unit,
            p[1] - 1.3 * unit,
            -p[0] + unit,
            p[1] + 1.3 * unit,
            -p[0] + unit,
            p[1] + 1.8 * unit,
            -p[0],
            3.0 * unit
        );
    }
    for p in &r.plans.mission {
        let reached = r
            .verdict
            .items
            .get(usize::from(p.seq))
            .is_some_and(|i| i.reached_s.is_some());
        let _ = write!(
            h,
            "<g class=\"item {}\"><title>item {} {} at {} m</title><circle cx=\"{:.3}\" cy=\"{:.3}\" r=\"{:.3}\"/>\
             <text x=\"{:.3}\" y=\"{:.3}\" font-size=\"{:.3}\">{}</text></g>",
            if reached { "reached" } else { "missed" },
            p.seq,
            esc(&command_name(p.command)),
            fmt_dm(p.alt_m),
            p.e,
            -p.n,
            1.2 * unit,
            p.e + 1.6 * unit,
            -p.n - 1.0 * unit,
            3.5 * unit,
            p.seq
        );
    }
    h.push_str("</svg>");
    let _ = writeln!(
        h,
        "<p class=\"legend\"><span class=\"k track\"></span> flown &middot; <span class=\"k reference\"></span> \
         reference &middot; <span class=\"k plan\"></span> mission \
         ({} items; green reached, red not) &middot; <span class=\"k fence-in\"></span> fence (inclusion) \
         <span class=\"k fence-out\"></span> (exclusion): {} &middot; R rally points: {} &middot; H home \
         &middot; grid {step} m</p></section>",
        r.plans.mission.len(),
        r.plans.fence.len(),
        r.plans.rally.len()
    );
}

/// A colour for a label (the same label, the same colour).
fn colour(label: &str) -> String {
    let hash = label
        .bytes()
        .fold(7u32, |h, b| h.wrapping_mul(31).wrapping_add(u32::from(b)));
    format!("hsl({}, 55%, 62%)", hash % 360)
}

fn timeline(h: &mut String, r: &FlightReport) {
    let d = r.duration_s.max(1e-9);
    let row = |h: &mut String, name: &str, spans: &[super::Span]| {
        let _ = write!(
            h,
            "<div class=\"tl-row\" id=\"tl-{name}\"><span class=\"tl-name\">{name}</span><div class=\"tl-bar\">"
        );
        for s in spans {
            let left = s.from_s / d * 100.0;
            let width = ((s.to_s - s.from_s) / d * 100.0).max(0.15);
            let bg = match s.label.as_str() {
                "armed" => "#e4572e".to_string(),
                "disarmed" => "#bbb".to_string(),
                l => colour(l),
            };
            let _ = write!(
                h,
                "<div class=\"tl-span\" style=\"left:{left:.3}%;width:{width:.3}%;background:{bg}\" \
                 title=\"{} from {} to {}\">{}</div>",
                esc(&s.label),
                fmt_s(s.from_s),
                fmt_s(s.to_s),
                esc(&s.label)
            );
        }
        h.push_str("</div></div>");
    };
    h.push_str("<section id=\"timeline\"><h2>Flight modes and arming</h2>");
    row(h, "mode", &r.modes);
    row(h, "arming", &r.arming);
    h.push_str("<div class=\"tl-row\" id=\"tl-events\"><span class=\"tl-name\">events</span><div class=\"tl-bar\">");
    for e in &r.events {
        let _ = write!(
            h,
            "<div class=\"tl-tick {:?}\" style=\"left:{:.3}%\" title=\"{} {}\"></div>",
            e.kind,
            e.t_s / d * 100.0,
            fmt_s(e.t_s),
            esc(&e.text)
        );
    }
    let _ = writeln!(
        h,
        "</div></div><div class=\"tl-axis\"><span>0 s</span><span>{}</span></div></section>",
        fmt_s(r.duration_s)
    );
}

fn events(h: &mut String, r: &FlightReport) {
    let _ = write!(
        h,
        "<section id=\"events\"><h2>Events ({}): status texts, failures injected, failsafes, items reached</h2>\
         <table><thead><tr><th>time</th><th>kind</th><th>severity</th><th>text</th></tr></thead><tbody>",
        r.events.len()
    );
    for e in &r.events {
        let kind = serde_json::to_value(e.kind)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default();
        let _ = write!(
            h,
            "<tr class=\"{kind}\"><td>{}</td><td>{kind}</td><td>{}</td><td>{}</td></tr>",
            fmt_s(e.t_s),
            esc(&e.severity),
            esc(&e.text)
        );
    }
    h.push_str("</tbody></table></section>\n");
}

/// The number of samples a page's series hold (for tests and the CLI's line).
#[must_use]
pub fn samples(s: &Series) -> usize {
    s.t.len()
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_small_share_is_not_shown_as_zero() {
        assert_eq!(super::fmt_percent(0.000_03), "0.003");
        assert_eq!(super::fmt_percent(0.031), "3.1");
        assert_eq!(super::fmt_percent(0.0), "0.000");
    }

    #[test]
    fn a_height_that_rounds_to_zero_has_no_minus_sign() {
        assert_eq!(super::fmt_dm(-0.0), "0.0");
        assert_eq!(super::fmt_dm(-0.04), "0.0");
        assert_eq!(super::fmt_dm(-0.05), "-0.1");
        assert_eq!(super::fmt_dm(12.34), "12.3");
    }
}
