// Loading a bundle (portal_harness/viewer/bundle.py) with <script> tags only:
// Chrome forbids fetch() of file:// URLs, and a report must open from disk.
"use strict";
window.Portal = window.Portal || {};

(function (P) {
  var images = {};
  var pending = {};

  // The data folder: ?bundle=URL, default data/ (the report's). Only a path
  // on the page's own origin is taken: a link must not make the page run
  // scripts from elsewhere.
  P.bundleUrl = function () {
    var given = new URLSearchParams(window.location.search).get("bundle");
    var url = given === null || given === "" ? "data/" : given;
    if (/^[a-zA-Z][a-zA-Z0-9+.-]*:/.test(url) || url.indexOf("//") === 0 || url.indexOf("\\") >= 0) {
      throw new Error("?bundle= must be a path on this site, not " + url);
    }
    return url.charAt(url.length - 1) === "/" ? url : url + "/";
  };

  P.loadScript = function (url) {
    return new Promise(function (resolve, reject) {
      var script = document.createElement("script");
      script.src = url;
      script.onload = function () {
        script.remove();
        resolve();
      };
      script.onerror = function () {
        script.remove();
        reject(new Error("cannot load " + url));
      };
      document.head.appendChild(script);
    });
  };

  P.loadBundle = function (base) {
    return P.loadScript(base + "bundle.js").then(function () {
      if (!window.PORTAL_BUNDLE) throw new Error(base + "bundle.js did not define PORTAL_BUNDLE");
      return window.PORTAL_BUNDLE;
    });
  };

  function decodeFloat32(text) {
    var bytes = atob(text);
    var buffer = new ArrayBuffer(bytes.length);
    var view = new Uint8Array(buffer);
    for (var i = 0; i < bytes.length; i++) view[i] = bytes.charCodeAt(i);
    // Little-endian in the file, as every browser's host is.
    return new Float32Array(buffer);
  }

  // Called by each img/N.js.
  window.PORTAL_IMAGE = function (number, payload) {
    images[number] = {
      width: payload.width,
      height: payload.height,
      channels: payload.channels,
      rgb: decodeFloat32(payload.values), // every channel's, interleaved (RGB, or one for a FLIP map)
    };
  };

  P.loadImage = function (base, number) {
    if (images[number]) return Promise.resolve(images[number]);
    if (!pending[number]) {
      pending[number] = P.loadScript(base + "img/" + number + ".js").then(function () {
        delete pending[number];
        if (!images[number]) throw new Error("image " + number + " did not register");
        return images[number];
      });
    }
    return pending[number];
  };

  // A region mask of the bundle: base64 of packed bits, most significant first.
  P.decodeMask = function (text, count) {
    var bytes = atob(text);
    var mask = new Uint8Array(count);
    for (var i = 0; i < count; i++) mask[i] = (bytes.charCodeAt(i >> 3) >> (7 - (i & 7))) & 1;
    return mask;
  };
})(window.Portal);
