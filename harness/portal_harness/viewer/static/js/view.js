// The synchronised zoom and pan of every image panel, and drawing one
// panel: nearest neighbour, computed per screen pixel, so that a block of
// scale x scale screen pixels is exactly one image pixel.
"use strict";
window.Portal = window.Portal || {};

(function (P) {
  // Zoom steps: integers from 2 up, so pixel blocks are all the same size.
  var SCALES = [0.125, 0.25, 0.375, 0.5, 0.75, 1, 1.5, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128];

  function View(width, height) {
    this.width = width; // image pixels
    this.height = height;
    this.scale = 1; // screen (canvas) pixels per image pixel
    this.cx = width / 2; // image point at the panel's centre
    this.cy = height / 2;
    this.zoomed = false; // by the user: layouts then keep the view
  }

  // Screen position of image pixel (0, 0) in a panel of W x H canvas pixels.
  View.prototype.origin = function (W, H) {
    return { tx: Math.round(W / 2 - this.cx * this.scale), ty: Math.round(H / 2 - this.cy * this.scale) };
  };

  // The image pixel under canvas pixel (sx, sy) (its centre), maybe outside the image.
  View.prototype.toImage = function (sx, sy, W, H) {
    var o = this.origin(W, H);
    return { x: Math.floor((sx + 0.5 - o.tx) / this.scale), y: Math.floor((sy + 0.5 - o.ty) / this.scale) };
  };

  // The largest zoom step at which the whole image fits the panel.
  View.prototype.fit = function (W, H) {
    var best = SCALES[0];
    for (var i = 0; i < SCALES.length; i++) {
      if (SCALES[i] * this.width <= W && SCALES[i] * this.height <= H) best = SCALES[i];
    }
    this.scale = best;
    this.cx = this.width / 2;
    this.cy = this.height / 2;
  };

  // Zoom by `steps` steps, keeping the image point under (sx, sy) in place.
  View.prototype.zoomAt = function (steps, sx, sy, W, H) {
    var i = SCALES.indexOf(this.scale);
    if (i < 0) i = 5;
    var j = Math.min(Math.max(i + steps, 0), SCALES.length - 1);
    if (j === i) return false;
    var o = this.origin(W, H);
    var px = (sx - o.tx) / this.scale;
    var py = (sy - o.ty) / this.scale;
    this.scale = SCALES[j];
    this.cx = px - (sx - W / 2) / this.scale;
    this.cy = py - (sy - H / 2) / this.scale;
    return true;
  };

  View.prototype.pan = function (dx, dy) {
    this.cx -= dx / this.scale;
    this.cy -= dy / this.scale;
  };

  P.View = View;
  P.ZOOM_STEPS = SCALES;

  var BACKGROUND = [40, 40, 40];
  var DIM = 0.3; // brightness kept outside the highlighted region

  // pixels: RGBA bytes of the image (width x height); overlay: null, or
  // {mask: 0/1 per image pixel} (pixels outside are dimmed), or {tint: RGBA
  // per image pixel} (blended by its alpha / 255); insets: the bundle's
  // rectangles or null.
  P.drawPanel = function (ctx, view, pixels, overlay, insets) {
    var mask = overlay && overlay.mask ? overlay.mask : null;
    var tint = overlay && overlay.tint ? overlay.tint : null;
    var W = ctx.canvas.width;
    var H = ctx.canvas.height;
    var out = ctx.createImageData(W, H);
    var d = out.data;
    var w = view.width;
    var h = view.height;
    var columns = new Int32Array(W);
    var o = view.origin(W, H);
    for (var sx = 0; sx < W; sx++) columns[sx] = Math.floor((sx + 0.5 - o.tx) / view.scale);
    for (var sy = 0; sy < H; sy++) {
      var iy = Math.floor((sy + 0.5 - o.ty) / view.scale);
      var row = sy * W * 4;
      for (sx = 0; sx < W; sx++) {
        var ix = columns[sx];
        var k = row + sx * 4;
        if (pixels === null || ix < 0 || iy < 0 || ix >= w || iy >= h) {
          d[k] = BACKGROUND[0];
          d[k + 1] = BACKGROUND[1];
          d[k + 2] = BACKGROUND[2];
        } else {
          var p = (iy * w + ix) * 4;
          var f = mask !== null && !mask[iy * w + ix] ? DIM : 1;
          d[k] = pixels[p] * f;
          d[k + 1] = pixels[p + 1] * f;
          d[k + 2] = pixels[p + 2] * f;
          if (tint !== null && tint[p + 3]) {
            var a = tint[p + 3] / 255;
            d[k] = d[k] * (1 - a) + tint[p] * a;
            d[k + 1] = d[k + 1] * (1 - a) + tint[p + 1] * a;
            d[k + 2] = d[k + 2] * (1 - a) + tint[p + 2] * a;
          }
        }
        d[k + 3] = 255;
      }
    }
    ctx.putImageData(out, 0, 0);
    if (!insets) return;
    ctx.lineWidth = 1.5;
    ctx.font = "11px sans-serif";
    insets.forEach(function (r) {
      var x = o.tx + r.x * view.scale;
      var y = o.ty + r.y * view.scale;
      ctx.strokeStyle = r.colour;
      ctx.strokeRect(x - 0.75, y - 0.75, r.width * view.scale + 1.5, r.height * view.scale + 1.5);
      ctx.fillStyle = r.colour;
      ctx.fillText(r.name, x + 2, y - 3);
    });
  };
})(window.Portal);
