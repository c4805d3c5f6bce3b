// Tone mapping and the relative-error map of the viewer: the browser's
// copy of portal_harness.core.display.to_srgb8, which the browser tests pin
// pixel for pixel against the Python function.
"use strict";
window.Portal = window.Portal || {};

(function (P) {
  // The sRGB OETF as colour-science's eotf_inverse_sRGB writes it.
  function oetf(linear) {
    return linear <= 0.0031308 ? linear * 12.92 : 1.055 * Math.pow(linear, 1 / 2.4) - 0.055;
  }

  function encode8(value, exposure) {
    var linear = Math.min(Math.max(value * exposure, 0), 1);
    var v = Math.min(Math.max(oetf(linear), 0), 1);
    return Math.floor(v * 255 + 0.5);
  }

  // rgb: Float32Array of width * height * 3 linear values; out: RGBA bytes.
  P.toSrgb8 = function (rgb, exposure, out) {
    var n = rgb.length / 3;
    for (var i = 0; i < n; i++) {
      out[4 * i] = encode8(rgb[3 * i], exposure);
      out[4 * i + 1] = encode8(rgb[3 * i + 1], exposure);
      out[4 * i + 2] = encode8(rgb[3 * i + 2], exposure);
      out[4 * i + 3] = 255;
    }
    return out;
  };

  // Per pixel, Y(|x - ref|) / (Y(ref) + epsilon): Y the luminance with the
  // harness's weights (display.luminance), epsilon metrics.REL_EPSILON.
  P.relativeError = function (rgb, ref, weights, epsilon) {
    var n = rgb.length / 3;
    var out = new Float32Array(n);
    for (var i = 0; i < n; i++) {
      var d = 0;
      var r = 0;
      for (var c = 0; c < 3; c++) {
        d += weights[c] * Math.abs(rgb[3 * i + c] - ref[3 * i + c]);
        r += weights[c] * ref[3 * i + c];
      }
      out[i] = d / (Math.max(r, 0) + epsilon);
    }
    return out;
  };

  // False colour of values in [0, max], linear, through the bundle's colour map.
  P.falseColour = function (values, max, colours, out) {
    var last = colours.length - 1;
    for (var i = 0; i < values.length; i++) {
      var t = values[i] / max;
      var k = Math.round(Math.min(Math.max(t, 0), 1) * last);
      var col = colours[k];
      out[4 * i] = col[0];
      out[4 * i + 1] = col[1];
      out[4 * i + 2] = col[2];
      out[4 * i + 3] = 255;
    }
    return out;
  };

  P.luminance = function (rgb, i, weights) {
    return weights[0] * rgb[3 * i] + weights[1] * rgb[3 * i + 1] + weights[2] * rgb[3 * i + 2];
  };
})(window.Portal);
