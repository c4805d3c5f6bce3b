// The experiment's charts in SVG, drawn here (no chart library): the error
// of each strategy over render time at one point (the error figure's mean
// curves and replicate range) and the efficiency or equal-error speed-up
// relative to light sampling against the swept axis (the summary's rows).
// Hovering a marker shows its values.
"use strict";
window.Portal = window.Portal || {};

(function (P) {
  var NS = "http://www.w3.org/2000/svg";
  var W = 560;
  var H = 340;
  var M = { left: 64, right: 16, top: 14, bottom: 44 };
  var DASHES = ["", "6 3", "2 3", "8 3 2 3", "1 5"];

  function el(name, attrs, parent) {
    var node = document.createElementNS(NS, name);
    Object.keys(attrs || {}).forEach(function (k) {
      node.setAttribute(k, attrs[k]);
    });
    if (parent) parent.appendChild(node);
    return node;
  }

  function tooltip() {
    var tip = document.getElementById("chart-tooltip");
    if (!tip) {
      tip = document.createElement("div");
      tip.id = "chart-tooltip";
      document.body.appendChild(tip);
    }
    return tip;
  }

  function hover(node, text) {
    node.addEventListener("mouseenter", function (e) {
      var tip = tooltip();
      tip.textContent = text;
      tip.style.display = "block";
      tip.style.left = e.pageX + 12 + "px";
      tip.style.top = e.pageY + 12 + "px";
    });
    node.addEventListener("mouseleave", function () {
      tooltip().style.display = "none";
    });
  }

  // Ticks of a log axis: the decades, with 2 and 5 between them when the
  // range spans less than two decades.
  function tickLabel(v) {
    return v >= 1e-3 && v < 1e5 ? String(Number(v.toPrecision(3))) : v.toExponential(0).replace("+", "");
  }

  function logTicks(lo, hi) {
    var ticks = [];
    var steps = Math.log10(hi / lo) < 2 ? [1, 2, 5] : [1];
    for (var e = Math.floor(Math.log10(lo)); e <= Math.ceil(Math.log10(hi)); e++) {
      steps.forEach(function (m) {
        var v = m * Math.pow(10, e);
        if (v >= lo * 0.999 && v <= hi * 1.001) ticks.push(v);
      });
    }
    return ticks;
  }

  function linearTicks(lo, hi) {
    var step = Math.pow(10, Math.floor(Math.log10((hi - lo) / 4 || 1)));
    if ((hi - lo) / step > 10) step *= 2;
    var ticks = [];
    for (var v = Math.ceil(lo / step) * step; v <= hi + step * 1e-6; v += step) ticks.push(v);
    return ticks;
  }

  function padded(values, log) {
    var lo = Math.min.apply(null, values);
    var hi = Math.max.apply(null, values);
    if (log) {
      if (lo === hi) return [lo / 2, hi * 2];
      return [lo / Math.pow(hi / lo, 0.05), hi * Math.pow(hi / lo, 0.05)];
    }
    var pad = (hi - lo) * 0.05 || Math.abs(lo) * 0.1 || 1;
    return [lo - pad, hi + pad];
  }

  function axis(range, a, b, log) {
    var lo = range[0];
    var hi = range[1];
    return log
      ? function (v) {
          return a + ((Math.log(v) - Math.log(lo)) / (Math.log(hi) - Math.log(lo))) * (b - a);
        }
      : function (v) {
          return a + ((v - lo) / (hi - lo)) * (b - a);
        };
  }

  // The SVG, its axes and grid; returns the two scales.
  function frame(container, spec) {
    container.textContent = "";
    var svg = el("svg", { width: W, height: H, viewBox: "0 0 " + W + " " + H, class: "chart" }, container);
    var x = axis(spec.xRange, M.left, W - M.right, spec.xLog);
    var y = axis(spec.yRange, H - M.bottom, M.top, true);
    var grid = el("g", { class: "grid" }, svg);
    (spec.xTicks || (spec.xLog ? logTicks : linearTicks)(spec.xRange[0], spec.xRange[1])).forEach(function (t) {
      var tx = x(typeof t === "number" ? t : t[0]);
      el("line", { x1: tx, x2: tx, y1: M.top, y2: H - M.bottom }, grid);
      var label = el("text", { x: tx, y: H - M.bottom + 14, "text-anchor": "middle" }, grid);
      label.textContent = typeof t === "number" ? tickLabel(t) : t[1];
    });
    logTicks(spec.yRange[0], spec.yRange[1]).forEach(function (t) {
      var ty = y(t);
      el("line", { x1: M.left, x2: W - M.right, y1: ty, y2: ty }, grid);
      var label = el("text", { x: M.left - 4, y: ty + 4, "text-anchor": "end" }, grid);
      label.textContent = tickLabel(t);
    });
    el("rect", { x: M.left, y: M.top, width: W - M.left - M.right, height: H - M.top - M.bottom, class: "frame" }, svg);
    var xl = el("text", { x: (M.left + W - M.right) / 2, y: H - 8, "text-anchor": "middle", class: "label" }, svg);
    xl.textContent = spec.xLabel;
    var yl = el("text", { x: 14, y: (M.top + H - M.bottom) / 2, "text-anchor": "middle", class: "label" }, svg);
    yl.setAttribute("transform", "rotate(-90 14 " + (M.top + H - M.bottom) / 2 + ")");
    yl.textContent = spec.yLabel;
    return { svg: svg, x: x, y: y };
  }

  function legend(container, entries) {
    var div = document.createElement("div");
    div.className = "legend";
    entries.forEach(function (e) {
      var item = document.createElement("span");
      var swatch = document.createElement("span");
      swatch.className = "swatch";
      swatch.style.background = e.colour;
      if (e.dash) {
        var on = Number(e.dash.split(" ")[0]);
        swatch.style.background =
          "repeating-linear-gradient(90deg," + e.colour + " 0 " + on + "px, transparent " + on + "px " + (on + 3) + "px)";
      }
      item.appendChild(swatch);
      item.appendChild(document.createTextNode(e.label));
      div.appendChild(item);
    });
    container.appendChild(div);
  }

  function strategyInfo(bundle) {
    var out = {};
    bundle.strategies.forEach(function (s) {
      out[s.name] = s;
    });
    return out;
  }

  function positive(v) {
    return typeof v === "number" && v > 0 && isFinite(v);
  }

  P.errorChart = function (container, bundle, pointId, region) {
    var data = (bundle.curves[pointId] || {})[region];
    if (!data) {
      container.textContent = "no error curves for region " + region + " at this point";
      return;
    }
    var info = strategyInfo(bundle);
    var xs = [];
    var ys = [];
    Object.keys(data.strategies).forEach(function (s) {
      var c = data.strategies[s];
      c.t.forEach(function (t, i) {
        if (positive(t) && positive(c.lo[i]) && positive(c.hi[i])) {
          xs.push(t);
          ys.push(c.lo[i], c.hi[i]);
        }
      });
    });
    if (positive(data.floor)) ys.push(data.floor);
    if (!xs.length) {
      container.textContent = "no positive values to draw";
      return;
    }
    var f = frame(container, {
      xRange: padded(xs, true),
      yRange: padded(ys, true),
      xLog: true,
      xLabel: "render time (s)",
      yLabel: bundle.curve_metric_label + " (" + region + ")",
    });
    if (positive(data.floor)) {
      var fy = f.y(data.floor);
      var floor = el("line", { x1: M.left, x2: W - M.right, y1: fy, y2: fy, class: "floor" }, f.svg);
      hover(floor, "reference noise: " + P.format(data.floor));
    }
    bundle.strategies.forEach(function (s) {
      var c = data.strategies[s.name];
      if (!c) return;
      var idx = c.t.map((_, i) => i).filter(function (i) {
        return positive(c.t[i]) && positive(c.v[i]);
      });
      if (c.replicates > 1) {
        var band = idx.map((i) => f.x(c.t[i]) + "," + f.y(Math.max(c.lo[i], 1e-300)));
        idx
          .slice()
          .reverse()
          .forEach(function (i) {
            band.push(f.x(c.t[i]) + "," + f.y(c.hi[i]));
          });
        el("polygon", { points: band.join(" "), fill: s.colour, opacity: 0.18 }, f.svg);
      }
      el("polyline", { points: idx.map((i) => f.x(c.t[i]) + "," + f.y(c.v[i])).join(" "), stroke: s.colour, class: "line" }, f.svg);
      idx.forEach(function (i) {
        var m = el("circle", { cx: f.x(c.t[i]), cy: f.y(c.v[i]), r: 3.5, fill: s.colour, class: "marker" }, f.svg);
        m.dataset.strategy = s.name;
        m.dataset.value = c.v[i];
        var text = info[s.name].label + ": t = " + P.format(c.t[i]) + " s, " + bundle.curve_metric_label + " = " + P.format(c.v[i]);
        if (c.replicates > 1) text += " (range " + P.format(c.lo[i]) + " to " + P.format(c.hi[i]) + ", " + c.replicates + " replicates)";
        hover(m, text);
      });
    });
    legend(
      container,
      bundle.strategies
        .filter(function (s) {
          return data.strategies[s.name];
        })
        .map(function (s) {
          return { colour: s.colour, label: s.label };
        }),
    );
  };

  function facetKey(bundle, row) {
    return bundle.facet_keys
      .map(function (k) {
        return k.split(".").pop() + "=" + row[k];
      })
      .join(", ");
  }

  var MEASURES = {
    efficiency_vs_light: { se: "efficiency_vs_light_stderr", bound: "bound", label: "efficiency relative to light" },
    speedup_equal_error: { se: "speedup_equal_error_stderr", bound: "speedup_bound", label: "speed-up at light's final error" },
  };
  P.MEASURES = MEASURES;

  P.efficiencyChart = function (container, bundle, region, measure, currentPoint) {
    var m = MEASURES[measure];
    var rows = bundle.summary.filter(function (r) {
      return r.region === region && positive(r[measure]);
    });
    if (!rows.length) {
      container.textContent = "no " + m.label + " in region " + region;
      return;
    }
    var info = strategyInfo(bundle);
    var titles = {};
    bundle.points.forEach(function (p) {
      titles[p.id] = p.title;
    });
    var groups = [];
    rows.forEach(function (r) {
      var g = facetKey(bundle, r);
      if (groups.indexOf(g) < 0) groups.push(g);
    });
    var byAxis = bundle.axis_label !== null && rows.every((r) => typeof r.axis === "number");
    var names = bundle.strategies.map((s) => s.name);
    var xOf = function (r) {
      if (byAxis) return r.axis;
      var g = groups.indexOf(facetKey(bundle, r));
      return names.indexOf(r.strategy) + (g - (groups.length - 1) / 2) * (0.7 / Math.max(groups.length, 1));
    };
    var xLog = byAxis && rows.every((r) => r.axis > 0);
    var ys = [1];
    rows.forEach(function (r) {
      ys.push(r[measure]);
      var se = r[m.se];
      if (positive(se)) ys.push(r[measure] + se, Math.max(r[measure] - se, r[measure] * 0.1));
    });
    var axisValues = byAxis ? rows.map((r) => r.axis) : [];
    var f = frame(container, {
      xRange: byAxis ? padded(axisValues, xLog) : [-0.6, names.length - 0.4],
      yRange: padded(ys, true),
      xLog: xLog,
      xTicks: byAxis
        ? axisValues.filter((v, i, a) => a.indexOf(v) === i)
        : bundle.strategies.map((s, i) => [i, s.label]),
      xLabel: byAxis ? bundle.axis_label : "strategy",
      yLabel: m.label + " (" + region + ")",
    });
    var one = f.y(1);
    el("line", { x1: M.left, x2: W - M.right, y1: one, y2: one, class: "one" }, f.svg);
    bundle.strategies.forEach(function (s) {
      groups.forEach(function (g, gi) {
        var mine = rows
          .filter((r) => r.strategy === s.name && facetKey(bundle, r) === g)
          .sort((a, b) => xOf(a) - xOf(b));
        if (!mine.length) return;
        if (byAxis && mine.length > 1) {
          el(
            "polyline",
            {
              points: mine.map((r) => f.x(xOf(r)) + "," + f.y(r[measure])).join(" "),
              stroke: s.colour,
              "stroke-dasharray": DASHES[gi % DASHES.length],
              class: "line",
            },
            f.svg,
          );
        }
        // With an axis the colour is the strategy's and facets are dashes; without
        // one, strategies are along x and the colour is the facet combination's
        // (as in the efficiency figure).
        var colour = byAxis ? s.colour : bundle.facet_colours[gi % bundle.facet_colours.length];
        mine.forEach(function (r) {
          var x = f.x(xOf(r));
          var v = r[measure];
          var se = r[m.se];
          if (positive(se)) {
            el("line", { x1: x, x2: x, y1: f.y(v + se), y2: f.y(Math.max(v - se, v * 0.1)), stroke: colour, class: "bar" }, f.svg);
          }
          var bound = r[m.bound] || "";
          var y = f.y(v);
          var current = r.point === currentPoint;
          var size = current ? 6 : 4;
          var marker =
            bound === ""
              ? el("circle", { cx: x, cy: y, r: size, fill: colour }, f.svg)
              : el(
                  "path",
                  {
                    d:
                      bound === "lower"
                        ? "M" + x + "," + (y - size) + "l" + size + "," + 1.7 * size + "h" + -2 * size + "z"
                        : "M" + x + "," + (y + size) + "l" + size + "," + -1.7 * size + "h" + -2 * size + "z",
                    fill: "white",
                    stroke: colour,
                  },
                  f.svg,
                );
          marker.setAttribute("class", "marker" + (current ? " current" : ""));
          marker.dataset.strategy = s.name;
          marker.dataset.point = r.point;
          marker.dataset.value = v;
          var text =
            info[s.name].label + " at " + (titles[r.point] || r.point) + ": " + m.label + " = " + P.format(v) +
            (positive(se) ? " \u00b1 " + P.format(se, 2) : "") +
            (bound ? " (" + bound + " bound)" : "") + ", relMSE " + P.format(r.rel_mse) + ", " + P.format(r.time_s) + " s";
          hover(marker, text);
        });
      });
    });
    var entries = byAxis
      ? bundle.strategies.map((s) => ({ colour: s.colour, label: s.label }))
      : groups.map((g, gi) => ({ colour: bundle.facet_colours[gi % bundle.facet_colours.length], label: g || "all" }));
    if (byAxis && groups.length > 1) {
      groups.forEach((g, gi) => entries.push({ colour: "#444", label: g, dash: DASHES[gi % DASHES.length] }));
    }
    legend(container, entries);
  };
})(window.Portal);
