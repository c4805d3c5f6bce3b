// The relMSE of each image per region: the image shown (its own value,
// reference noise included, from the index) and the summary's mean over
// replicates of the final images (reference noise removed, sweep.py).
"use strict";
window.Portal = window.Portal || {};

(function (P) {
  P.format = function (v, digits) {
    if (v === null || v === undefined) return "-";
    if (typeof v !== "number") return String(v);
    if (v === 0) return "0";
    var a = Math.abs(v);
    return a >= 1e4 || a < 1e-3 ? v.toExponential((digits || 3) - 1) : v.toPrecision(digits || 3);
  };

  function summaryRow(bundle, point, strategy, region) {
    for (var i = 0; i < bundle.summary.length; i++) {
      var r = bundle.summary[i];
      if (r.point === point && r.strategy === strategy && r.region === region) return r;
    }
    return null;
  }

  function withError(v, se) {
    var text = P.format(v);
    return se === null || se === undefined ? text : text + " \u00b1 " + P.format(se, 2);
  }

  function cell(tr, lines, cls) {
    var td = document.createElement("td");
    if (cls) td.className = cls;
    lines.forEach(function (line, i) {
      if (i) td.appendChild(document.createElement("br"));
      var span = document.createElement("span");
      span.className = line[0];
      span.textContent = line[1];
      td.appendChild(span);
    });
    tr.appendChild(td);
    return td;
  }

  // highlighted: the region drawn over the images, or "".
  P.metricsTable = function (container, bundle, point, currentName, highlighted) {
    container.textContent = "";
    var table = document.createElement("table");
    table.id = "metrics-table";
    var head = document.createElement("tr");
    ["region", "pixels"].forEach(function (t) {
      var th = document.createElement("th");
      th.textContent = t;
      head.appendChild(th);
    });
    var strategies = point.images.filter(function (e) {
      return e.name !== "reference";
    });
    strategies.forEach(function (e) {
      var th = document.createElement("th");
      th.textContent = e.label;
      if (e.name === currentName) th.className = "current";
      head.appendChild(th);
    });
    table.appendChild(head);
    point.regions.forEach(function (region) {
      var tr = document.createElement("tr");
      tr.dataset.region = region.name;
      if (region.name === highlighted) tr.className = "highlighted";
      cell(tr, [["name", region.title]]);
      cell(tr, [["pixels", String(region.pixels)]]);
      strategies.forEach(function (e) {
        var row = summaryRow(bundle, point.id, e.name, region.name);
        var lines = [["shown", "image: " + P.format(e.rel_mse[region.name])]];
        if (e.flip) lines.push(["flip", "FLIP: " + P.format(e.flip[region.name])]);
        if (row && row.rel_mse !== null) {
          lines.push(["final", "mean: " + withError(row.rel_mse, row.rel_mse_stderr) + " (" + row.replicates + ")"]);
          var bound = row.bound === "lower" ? "\u2265 " : "";
          lines.push(["efficiency", "vs light: " + bound + withError(row.efficiency_vs_light, row.efficiency_vs_light_stderr)]);
        }
        var td = cell(tr, lines, e.name === currentName ? "current" : "");
        td.dataset.strategy = e.name;
      });
      table.appendChild(tr);
    });
    var caption = document.createElement("caption");
    caption.textContent =
      "relMSE per region. image: the image shown (reference noise included); FLIP: its mean FLIP as shown at " +
      "exposure 0; mean: the final images over " +
      "replicates, reference noise removed, \u00b1 one standard error; vs light: efficiency relative to light " +
      "sampling (\u2265: a lower bound)";
    table.appendChild(caption);
    container.appendChild(table);
  };
})(window.Portal);
