// The flight report page's plots (rotorpilot report): reads the JSON in
// #report-data and draws each panel with uPlot (inlined before this
// script). Sets window.__report = {plots: [{id, series, points}]} and
// document.body.dataset.ready = "1" when every plot is drawn (the
// browser test reads both).
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("report-data").textContent);
  var t = data.t;
  function col(name) {
    var k = data.names.indexOf(name);
    return k < 0 ? null : data.columns[k];
  }
  function neg(c) {
    return c.map(function (x) { return x === null ? null : -x; });
  }
  var palette = ["#1f6fd1", "#e4572e", "#2a9d4b", "#9b5de5", "#f0a500", "#17becf", "#8c564b", "#e377c2",
                 "#7f7f7f", "#bcbd22", "#1a1a1a", "#ff7f0e"];
  var rotorNames = data.names.filter(function (n) { return /^w\d+$/.test(n); });
  // each panel: id, title, unit, and its lines [label, column values, colour index, dashed]
  var panels = [
    ["altitude", "Altitude above home", "m", [
      ["true", neg(col("d")), 0], ["setpoint", neg(col("ref_d")), 1, true], ["estimated", neg(col("est_d")), 2]]],
    ["speed", "Speed", "m/s", [
      ["horizontal", col("vh"), 0], ["down (NED)", col("vd"), 1], ["horizontal setpoint", col("ref_vh"), 0, true]]],
    ["attitude", "Attitude (ZYX Euler, true) and setpoint", "deg", [
      ["roll", col("roll"), 0], ["pitch", col("pitch"), 1], ["yaw", col("yaw"), 2],
      ["roll sp", col("roll_sp"), 0, true], ["pitch sp", col("pitch_sp"), 1, true], ["yaw sp", col("yaw_sp"), 2, true]]],
    ["tracking", "Tracking error (distance from the reference)", "m", [["error", col("err"), 3]]],
    ["rotors", "Rotor speeds commanded", data.rotor_unit,
      rotorNames.map(function (n, k) { return ["rotor " + n.slice(1), col(n), k]; })],
    ["force", "External force, NED: estimate vs injected truth", "N", [
      ["est N", col("f_n"), 0], ["est E", col("f_e"), 1], ["est D", col("f_d"), 2],
      ["true N", col("tf_n"), 0, true], ["true E", col("tf_e"), 1, true], ["true D", col("tf_d"), 2, true]]],
    ["torque", "External torque, FRD: estimate vs injected truth", "N m", [
      ["est x", col("tq_x"), 0], ["est y", col("tq_y"), 1], ["est z", col("tq_z"), 2],
      ["true x", col("ttq_x"), 0, true], ["true y", col("ttq_y"), 1, true], ["true z", col("ttq_z"), 2, true]]],
    ["mass", "Mass: estimate vs true", "kg", [["estimate", col("mass"), 0], ["true", col("true_mass"), 1, true]]],
    ["battery", "Battery remaining", "0..1", [["remaining", col("battery"), 2]]]
  ];
  var eventColour = { failsafe: "#d33", failure: "#f08000", reached: "#2a9d4b", text: "#aaa" };
  var markers = {
    hooks: {
      draw: [function (u) {
        var ctx = u.ctx;
        ctx.save();
        ctx.lineWidth = 1;
        data.events.forEach(function (e) {
          var x = Math.round(u.valToPos(e[0], "x", true));
          if (x < u.bbox.left || x > u.bbox.left + u.bbox.width) { return; }
          ctx.strokeStyle = eventColour[e[1]] || "#aaa";
          ctx.beginPath();
          ctx.moveTo(x, u.bbox.top);
          ctx.lineTo(x, u.bbox.top + u.bbox.height);
          ctx.stroke();
        });
        ctx.restore();
      }]
    }
  };
  var grid = document.getElementById("plot-grid");
  var width = Math.max(560, Math.min(680, grid.clientWidth - 20));
  var made = [];
  panels.forEach(function (p) {
    var lines = p[3].filter(function (l) { return l[1] !== null; });
    var div = document.createElement("div");
    div.className = "plot";
    div.id = "plot-" + p[0];
    var h3 = document.createElement("h3");
    h3.textContent = p[1] + " [" + p[2] + "]";
    div.appendChild(h3);
    grid.appendChild(div);
    var series = [{ label: "t [s]" }].concat(lines.map(function (l) {
      return { label: l[0], stroke: palette[l[2] % palette.length], width: 1.25, dash: l[3] ? [6, 4] : undefined,
               spanGaps: false };
    }));
    var opts = { width: width, height: 220, series: series, plugins: [markers],
                 cursor: { sync: { key: "flight" } }, scales: { x: { time: false } },
                 axes: [{ label: "t [s]" }, { label: p[2] }] };
    new uPlot(opts, [t].concat(lines.map(function (l) { return l[1]; })), div);
    var points = 0;
    lines.forEach(function (l) { l[1].forEach(function (v) { if (v !== null) { points++; } }); });
    made.push({ id: p[0], series: lines.length, points: points });
  });
  window.__report = { plots: made, samples: t.length, events: data.events.length };
  document.body.dataset.ready = "1";
})();
