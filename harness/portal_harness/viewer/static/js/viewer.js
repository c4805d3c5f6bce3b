// The comparison viewer: the reference and each strategy of a point side by
// side or one at a time (number keys), synchronised zoom and pan down to
// single pixels, exposure in stops, relative-error maps, the insets, the
// relMSE per region and the experiment's charts.
//
// Keys: 1 reference, 2.. strategies (single view); g side by side; e cycles
// images, relative error and FLIP; i insets; + / - exposure by half a
// stop, 0 resets it; f fit; [ ] the previous and next point; arrows pan.
"use strict";
window.Portal = window.Portal || {};

(function (P) {
  var S = {
    base: null,
    bundle: null,
    point: 0,
    current: 0, // index into the point's images
    layout: "grid",
    stops: 0,
    errorKind: "", // "" images, "relative" or "flip": the strategies' error maps
    errorMax: 1, // of the relative error; FLIP is in [0, 1]
    insets: true,
    region: "", // highlighted region, "" for none
    chartRegion: "lit",
    measure: "efficiency_vs_light",
    view: null,
    loaded: {}, // image number -> {width, height, rgb}
    toned: {}, // image number -> {exposure, pixels}
    errors: {}, // kind + image number -> values, or {max, pixels}
    overlay: null, // the highlighted region (drawPanel's overlay)
    draws: 0,
  };
  var $ = function (id) {
    return document.getElementById(id);
  };

  function point() {
    return S.bundle.points[S.point];
  }

  function exposure() {
    return (point().exposure || 1) * Math.pow(2, S.stops);
  }

  function shownEntries() {
    var images = point().images;
    if (!images.length) return [];
    return S.layout === "single" ? [images[S.current]] : images;
  }

  function message(text) {
    $("message").textContent = text || "";
  }

  function tonedPixels(number) {
    var e = exposure();
    var cached = S.toned[number];
    if (cached && cached.exposure === e) return cached.pixels;
    var img = S.loaded[number];
    var pixels = P.toSrgb8(img.rgb, e, new Uint8ClampedArray(img.width * img.height * 4));
    S.toned[number] = { exposure: e, pixels: pixels };
    return pixels;
  }

  function referenceNumber() {
    return point().images[0].image;
  }

  function errorValues(entry, kind) {
    if (kind === "flip") return entry.flip_image === null || entry.flip_image === undefined ? null : S.loaded[entry.flip_image].rgb;
    var key = "relative" + entry.image;
    if (!S.errors[key]) {
      var ref = S.loaded[referenceNumber()];
      S.errors[key] = P.relativeError(S.loaded[entry.image].rgb, ref.rgb, S.bundle.luminance_weights, S.bundle.error_epsilon);
    }
    return S.errors[key];
  }

  function errorMax() {
    return S.errorKind === "flip" ? 1 : S.errorMax;
  }

  function errorPixels(entry) {
    var values = errorValues(entry, S.errorKind);
    if (values === null) return null;
    var key = "pixels-" + S.errorKind + entry.image;
    var cached = S.errors[key];
    if (!cached) cached = S.errors[key] = { max: null, pixels: new Uint8ClampedArray(values.length * 4) };
    if (cached.max !== errorMax()) {
      P.falseColour(values, errorMax(), S.bundle.error_colormap.colours, cached.pixels);
      cached.max = errorMax();
    }
    return cached.pixels;
  }

  function panelPixels(entry, i) {
    if (entry.image === null || !S.loaded[entry.image]) return null;
    var isReference = S.layout === "single" ? S.current === 0 : i === 0;
    return S.errorKind && !isReference ? errorPixels(entry) : tonedPixels(entry.image);
  }

  function caption(entry, index) {
    var text = index + 1 + "  " + entry.label;
    if (entry.image === null) return text + " (" + entry.status + ")";
    var parts = [];
    if (typeof entry.time_s === "number") parts.push(P.format(entry.time_s) + " s");
    if (typeof entry.spp === "number") parts.push(entry.spp + " spp");
    if (entry.rel_mse && typeof entry.rel_mse.image === "number") parts.push("relMSE " + P.format(entry.rel_mse.image));
    return text + (parts.length ? " (" + parts.join(", ") + ")" : "");
  }

  // Canvas size of a panel, in canvas pixels (one per CSS pixel: the page
  // asks for exact pixels, so it does not scale with devicePixelRatio).
  function panelSize(count) {
    var avail = Math.max($("images").clientWidth, 320);
    var w = S.bundle.width;
    var h = S.bundle.height;
    // At most four across, in rows as even as they can be (6: 3 + 3, 7: 4 + 3).
    var across = Math.ceil(count / Math.ceil(count / 4));
    // Panels have a 2 px border each side and 10 px between them (viewer.css).
    var width = Math.floor((avail - 10 * (across - 1)) / across) - 4;
    width = count === 1 ? Math.min(width, 1024) : Math.max(Math.min(width, 520), 220);
    var height = Math.min(Math.round((width * h) / w), count === 1 ? 760 : 520);
    return { width: width, height: height };
  }

  function buildPanels() {
    var container = $("images");
    container.textContent = "";
    container.className = S.layout;
    var entries = shownEntries();
    var size = panelSize(entries.length);
    entries.forEach(function (entry, i) {
      var index = S.layout === "single" ? S.current : i;
      var panel = document.createElement("div");
      panel.className = "panel" + (index === S.current ? " current" : "");
      panel.dataset.index = index;
      panel.dataset.name = entry.name;
      var title = document.createElement("div");
      title.className = "caption";
      title.textContent = caption(entry, index);
      var canvas = document.createElement("canvas");
      canvas.width = size.width;
      canvas.height = size.height;
      canvas.style.width = size.width + "px";
      canvas.style.height = size.height + "px";
      panel.appendChild(title);
      panel.appendChild(canvas);
      container.appendChild(panel);
      attachMouse(canvas);
    });
    // Until the user zooms, every layout shows the whole image as large as it fits.
    if (!S.view.zoomed) S.view.fit(size.width, size.height);
  }

  function draw() {
    if (point().missing) return;
    var entries = shownEntries();
    var canvases = $("images").querySelectorAll("canvas");
    entries.forEach(function (entry, i) {
      var ctx = canvases[i].getContext("2d");
      P.drawPanel(ctx, S.view, panelPixels(entry, i), S.overlay, S.insets ? S.bundle.insets : null);
    });
    $("colourbar").style.display = S.errorKind ? "" : "none";
    S.draws += 1;
    document.body.dataset.draws = S.draws;
    document.body.dataset.scale = S.view.scale;
  }

  function drawColourbar() {
    var canvas = $("colourbar-canvas");
    var ctx = canvas.getContext("2d");
    var colours = S.bundle.error_colormap.colours;
    for (var x = 0; x < canvas.width; x++) {
      var c = colours[Math.round((x / (canvas.width - 1)) * (colours.length - 1))];
      ctx.fillStyle = "rgb(" + c[0] + "," + c[1] + "," + c[2] + ")";
      ctx.fillRect(x, 0, 1, canvas.height);
    }
    var flip = S.errorKind === "flip";
    $("colourbar-label").textContent = flip
      ? "FLIP (" + S.bundle.flip.dynamic_range + ", " + S.bundle.flip.ppd + " pixels per degree) of the images as shown at exposure 0:"
      : "relative error |x \u2212 ref| / (ref + " + S.bundle.error_epsilon + "), luminance:";
    $("colourbar-max").textContent = (flip ? "" : "\u2265 ") + P.format(errorMax());
    $("colourbar-mid").textContent = P.format(errorMax() / 2);
  }

  var CLASSES = "*classes";
  var CLASS_ALPHA = 150;

  function hexColour(text) {
    var v = parseInt(text.slice(1), 16);
    return [(v >> 16) & 255, (v >> 8) & 255, v & 255];
  }

  function classLegend() {
    var div = $("class-legend");
    div.textContent = "";
    point()
      .regions.filter((r) => r.kind === "class")
      .forEach(function (r) {
        var item = document.createElement("span");
        var swatch = document.createElement("span");
        swatch.className = "swatch";
        swatch.style.background = S.bundle.class_colours[r.name] || "#000000";
        item.appendChild(swatch);
        item.appendChild(document.createTextNode(r.title + " (" + r.pixels + " px)"));
        div.appendChild(item);
      });
    var note = document.createElement("span");
    note.textContent = "pixels of no class (under 95% of their samples in one) are not tinted";
    div.appendChild(note);
  }

  function setMask() {
    var region = point().regions.filter((r) => r.name === S.region)[0];
    var count = S.bundle.width * S.bundle.height;
    if (S.region === CLASSES) {
      // Each pixel of a region class (the pure ones regions.py measures) in its class colour.
      var tint = new Uint8ClampedArray(count * 4);
      point()
        .regions.filter((r) => r.kind === "class")
        .forEach(function (r) {
          var rgb = hexColour(S.bundle.class_colours[r.name] || "#000000");
          var m = P.decodeMask(r.mask, count);
          for (var i = 0; i < count; i++) {
            if (!m[i]) continue;
            tint.set([rgb[0], rgb[1], rgb[2], CLASS_ALPHA], 4 * i);
          }
        });
      S.overlay = { tint: tint };
      classLegend();
      return;
    }
    $("class-legend").textContent = "";
    S.overlay = region ? { mask: P.decodeMask(region.mask, count) } : null;
  }

  function updateTable() {
    P.metricsTable($("metrics"), S.bundle, point(), point().images[S.current].name, S.region);
  }

  function updateCharts() {
    P.errorChart($("chart-error"), S.bundle, point().id, S.chartRegion);
    P.efficiencyChart($("chart-efficiency"), S.bundle, S.chartRegion, S.measure, point().id);
  }

  function loadPoint() {
    var p = point();
    if (p.missing) {
      message(p.title + ": " + p.missing);
      $("images").textContent = "";
      return Promise.resolve();
    }
    document.body.dataset.loading = "1";
    var numbers = [];
    p.images.forEach(function (e) {
      if (e.image !== null) numbers.push(e.image);
      if (e.flip_image !== undefined && e.flip_image !== null) numbers.push(e.flip_image);
    });
    return Promise.all(
      numbers.map(function (n) {
        return P.loadImage(S.base, n).then(function (img) {
          S.loaded[n] = img;
        });
      }),
    ).then(function () {
      document.body.dataset.loading = "0";
    });
  }

  function fillSelect(select, options, value) {
    select.textContent = "";
    options.forEach(function (o) {
      var opt = document.createElement("option");
      opt.value = o[0];
      opt.textContent = o[1];
      select.appendChild(opt);
    });
    select.value = value;
  }

  function refreshRegionChoices() {
    var regions = point().regions.map((r) => [r.name, r.title + " (" + r.pixels + " px)"]);
    var hasClasses = point().regions.some((r) => r.kind === "class");
    if (hasClasses) regions.push([CLASSES, "region classes, in colour"]);
    if (!regions.some((r) => r[0] === S.region)) S.region = "";
    fillSelect($("region"), [["", "none"]].concat(regions), S.region);
    var names = Object.keys(S.bundle.curves[point().id] || {});
    if (names.indexOf(S.chartRegion) < 0) S.chartRegion = names.indexOf("lit") >= 0 ? "lit" : names[0] || "image";
    fillSelect(
      $("chart-region"),
      point().regions.map((r) => [r.name, r.title]),
      S.chartRegion,
    );
  }

  function selectPoint(i) {
    S.point = i;
    S.current = Math.max(Math.min(S.current, point().images.length - 1), 0);
    S.toned = {};
    S.errors = {};
    $("point").value = String(i);
    refreshRegionChoices();
    setMask();
    message("");
    return loadPoint().then(function () {
      if (point().missing) return;
      buildPanels();
      draw();
      updateTable();
      updateCharts();
    });
  }

  function render() {
    if (point().missing) return; // a point without a reference has nothing to show
    buildPanels();
    draw();
    updateTable();
  }

  function setStops(stops) {
    S.stops = Math.min(Math.max(Math.round(stops * 4) / 4, -12), 12);
    $("exposure").value = String(S.stops);
    $("exposure-value").textContent = (S.stops >= 0 ? "+" : "") + S.stops + " stops";
    draw();
  }

  function canvasPoint(canvas, e) {
    var rect = canvas.getBoundingClientRect();
    return {
      x: ((e.clientX - rect.left) * canvas.width) / rect.width,
      y: ((e.clientY - rect.top) * canvas.height) / rect.height,
    };
  }

  function showPixel(canvas, e) {
    var at = canvasPoint(canvas, e);
    var px = S.view.toImage(at.x, at.y, canvas.width, canvas.height);
    var info = $("pixel-info");
    if (px.x < 0 || px.y < 0 || px.x >= S.bundle.width || px.y >= S.bundle.height) {
      info.textContent = "";
      return;
    }
    var i = px.y * S.bundle.width + px.x;
    var lines = ["pixel (" + px.x + ", " + px.y + ")"];
    point().images.forEach(function (entry, k) {
      var img = entry.image === null ? null : S.loaded[entry.image];
      if (!img) return;
      var rgb = [img.rgb[3 * i], img.rgb[3 * i + 1], img.rgb[3 * i + 2]];
      var line = k + 1 + " " + entry.label + ": " + rgb.map((v) => P.format(v, 4)).join("  ");
      if (k > 0) {
        line += "   rel. error " + P.format(errorValues(entry, "relative")[i]);
        var flip = errorValues(entry, "flip");
        if (flip) line += "   FLIP " + P.format(flip[i]);
      }
      lines.push(line);
    });
    info.textContent = lines.join("\n");
    info.dataset.x = px.x;
    info.dataset.y = px.y;
  }

  var drag = null; // the last mouse position of a pan in progress
  window.addEventListener("mouseup", function () {
    drag = null;
  });

  function attachMouse(canvas) {
    canvas.addEventListener(
      "wheel",
      function (e) {
        e.preventDefault();
        var at = canvasPoint(canvas, e);
        if (S.view.zoomAt(e.deltaY < 0 ? 1 : -1, at.x, at.y, canvas.width, canvas.height)) {
          S.view.zoomed = true;
          draw();
        }
        showPixel(canvas, e);
      },
      { passive: false },
    );
    canvas.addEventListener("mousedown", function (e) {
      drag = { x: e.clientX, y: e.clientY };
      e.preventDefault();
    });
    canvas.addEventListener("mousemove", function (e) {
      if (drag) {
        var scale = canvas.width / canvas.getBoundingClientRect().width;
        S.view.pan((e.clientX - drag.x) * scale, (e.clientY - drag.y) * scale);
        S.view.zoomed = true;
        drag = { x: e.clientX, y: e.clientY };
        draw();
      }
      showPixel(canvas, e);
    });
  }

  function setErrorKind(kind) {
    S.errorKind = kind;
    $("error-kind").value = kind;
    drawColourbar();
    draw();
  }

  function setLayout(layout) {
    S.layout = layout;
    $("layout").value = layout;
    render();
  }

  function onKey(e) {
    if (e.target && (e.target.tagName === "INPUT" || e.target.tagName === "SELECT") && e.target.type !== "range" && e.target.type !== "checkbox") return;
    if (e.ctrlKey || e.metaKey || e.altKey) return;
    var k = e.key;
    if (k >= "1" && k <= "9") {
      var i = Number(k) - 1;
      if (i < point().images.length) {
        S.current = i;
        setLayout("single");
      }
    } else if (k === "g") setLayout(S.layout === "grid" ? "single" : "grid");
    else if (k === "[" || k === "]") {
      var next = S.point + (k === "]" ? 1 : -1);
      if (next < 0 || next >= S.bundle.points.length) return;
      selectPoint(next);
    } else if (k.indexOf("Arrow") === 0) {
      // Pan by a tenth of the first panel.
      var canvas = $("images").querySelector("canvas");
      var step = canvas ? canvas.width / 10 : 40;
      var d = { ArrowLeft: [step, 0], ArrowRight: [-step, 0], ArrowUp: [0, step], ArrowDown: [0, -step] }[k];
      if (!d) return;
      S.view.pan(d[0], d[1]);
      S.view.zoomed = true;
      draw();
    }
    else if (k === "e") setErrorKind({ "": "relative", relative: "flip", flip: "" }[S.errorKind]);
    else if (k === "i") {
      S.insets = !S.insets;
      $("insets").checked = S.insets;
      draw();
    } else if (k === "+" || k === "=") setStops(S.stops + 0.5);
    else if (k === "-" || k === "_") setStops(S.stops - 0.5);
    else if (k === "0") setStops(0);
    else if (k === "f") {
      S.view.zoomed = false;
      render();
    } else return;
    e.preventDefault();
  }

  function wireControls() {
    var b = S.bundle;
    fillSelect(
      $("point"),
      b.points.map((p, i) => [String(i), p.title]),
      "0",
    );
    $("point").addEventListener("change", (e) => selectPoint(Number(e.target.value)));
    $("layout").addEventListener("change", (e) => setLayout(e.target.value));
    $("exposure").addEventListener("input", (e) => setStops(Number(e.target.value)));
    $("error-kind").addEventListener("change", (e) => setErrorKind(e.target.value));
    $("error-max").addEventListener("change", function (e) {
      S.errorMax = Number(e.target.value);
      drawColourbar();
      draw();
    });
    $("insets").addEventListener("change", function (e) {
      S.insets = e.target.checked;
      draw();
    });
    $("region").addEventListener("change", function (e) {
      S.region = e.target.value;
      setMask();
      draw();
      updateTable();
    });
    $("chart-region").addEventListener("change", function (e) {
      S.chartRegion = e.target.value;
      updateCharts();
    });
    $("measure").addEventListener("change", function (e) {
      S.measure = e.target.value;
      updateCharts();
    });
    $("fit").addEventListener("click", function () {
      S.view.zoomed = false;
      render();
    });
    // A control keeps the focus after a change and would swallow the keys.
    document.querySelectorAll("header select, header input").forEach(function (el) {
      el.addEventListener("change", function () {
        el.blur();
      });
    });
    document.addEventListener("keydown", onKey);
    window.addEventListener("resize", render);
  }

  // What the tests (and a curious user, from the console) can ask.
  P.viewer = {
    state: function () {
      var canvas = $("images").querySelector("canvas");
      var o = canvas ? S.view.origin(canvas.width, canvas.height) : null;
      return {
        point: S.point,
        current: S.current,
        layout: S.layout,
        stops: S.stops,
        exposure: exposure(),
        errorKind: S.errorKind,
        insets: S.insets,
        scale: S.view.scale,
        tx: o && o.tx,
        ty: o && o.ty,
        shown: shownEntries().map((e) => e.image),
        draws: S.draws,
      };
    },
    selectPoint: selectPoint,
  };

  function start() {
    try {
      S.base = P.bundleUrl();
    } catch (err) {
      message(err.message);
      return;
    }
    P.loadBundle(S.base)
      .then(function (bundle) {
        S.bundle = bundle;
        document.title = bundle.experiment + ": portal-lights viewer";
        $("title").textContent = bundle.experiment;
        S.view = new P.View(bundle.width, bundle.height);
        wireControls();
        drawColourbar();
        return selectPoint(0);
      })
      .then(function () {
        document.body.dataset.ready = "1";
      })
      .catch(function (err) {
        message(String(err.message || err));
        document.body.dataset.ready = "error";
      });
  }

  document.addEventListener("DOMContentLoaded", start);
})(window.Portal);
