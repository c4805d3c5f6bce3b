// The experiments page of portal-harness serve: the list (polled), one
// experiment's renders (followed live through its event stream), the
// submit form and the cancel buttons. Plain DOM; text from the server is
// always set as text, never as HTML.
"use strict";

const state = { selected: null, source: null, rows: new Map() };

const EXAMPLE = `name: tiny_lampshade
scene: scenes/lampshade.yaml
integrator: direct
strategies: [light, antishadow]
sweep:
  params.s_L: [0.15, 0.6]
fixed:
  params.s_P: 0.3
  film.width: 32
  film.height: 32
budget: {time_s: 1, threads: 1, seed: 1, snapshots: {every: 0.25}}
reference: {strategy: light, spp: 256, seed: 7}
axis: {param: params.s_L, divide_by: params.s_P, label: light/portal ratio}
`;

function token() {
  return document.getElementById("token").value.trim();
}

function headers(extra) {
  const h = Object.assign({}, extra || {});
  if (token()) h["Authorization"] = "Bearer " + token();
  return h;
}

// What the browser loads itself (EventSource, images, links) cannot carry a
// header: off loopback the service takes the token as ?token=.
function withToken(url) {
  const t = new URLSearchParams(location.search).get("token");
  return t ? url + (url.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(t) : url;
}

function el(tag, attrs, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === "class") node.className = v;
    else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else node.setAttribute(k, v);
  }
  for (const c of children) node.append(c instanceof Node ? c : document.createTextNode(String(c)));
  return node;
}

function bar(progress, id) {
  const inner = el("div", id ? { id } : {});
  inner.style.width = (100 * (progress || 0)).toFixed(1) + "%";
  const outer = el("div", { class: "bar", role: "progressbar", "aria-valuemin": "0", "aria-valuemax": "100" }, inner);
  outer.setAttribute("aria-valuenow", String(Math.round(100 * (progress || 0))));
  return outer;
}

function setBar(outer, progress) {
  outer.firstChild.style.width = (100 * progress).toFixed(1) + "%";
  outer.setAttribute("aria-valuenow", String(Math.round(100 * progress)));
}

async function getJSON(url) {
  const r = await fetch(withToken(url), { headers: headers() });
  if (!r.ok) throw new Error(url + ": " + r.status + " " + (await r.text()));
  return r.json();
}

async function refreshList() {
  const error = document.getElementById("list-error");
  let list;
  try {
    list = await getJSON("/api/experiments");
    error.hidden = true;
  } catch (e) {
    error.textContent = String(e);
    error.hidden = false;
    return;
  }
  const body = document.querySelector("#experiments tbody");
  body.replaceChildren();
  for (const x of list) {
    const cancel = el("button", { class: "cancel", onclick: (ev) => { ev.stopPropagation(); cancelExperiment(x.id); } },
                      "cancel");
    cancel.disabled = !(x.status === "queued" || x.status === "running");
    const row = el("tr", { "data-id": x.id, onclick: () => select(x.id) },
      el("td", {}, el("a", { href: "#" + x.id }, x.name)),
      el("td", { class: "status status-" + x.status }, x.status),
      el("td", {}, bar(x.progress)),
      el("td", {}, x.submitted.replace("T", " ").slice(0, 19)),
      el("td", {}, cancel));
    if (x.id === state.selected) row.classList.add("selected");
    body.append(row);
  }
}

async function cancelExperiment(id) {
  const r = await fetch("/api/experiments/" + id, { method: "DELETE", headers: headers() });
  if (!r.ok) alert("cancel: " + r.status + " " + (await r.text()));
  refreshList();
  if (id === state.selected) select(id);
}

async function submit(ev) {
  ev.preventDefault();
  const out = document.getElementById("submit-result");
  out.hidden = false;
  out.className = "message";
  out.textContent = "submitting...";
  sessionStorage.setItem("portal-token", token());
  const r = await fetch("/api/experiments", {
    method: "POST",
    headers: headers({ "Content-Type": "application/yaml" }),
    body: document.getElementById("yaml").value,
  });
  const text = await r.text();
  let data = {};
  try { data = JSON.parse(text); } catch (e) { data = { message: text }; }
  if (r.status === 202) {
    out.textContent = "queued: " + data.id + " (" + data.runs + " runs)";
    await refreshList();
    select(data.id);
    return;
  }
  out.className = "message error";
  const where = [data.file, data.line, data.column].filter((v) => v !== null && v !== undefined).join(":");
  out.textContent = r.status + ": " + (where ? where + ": " : "") + (data.key ? data.key + ": " : "") +
                    (data.message || text);
}

function runRow(run) {
  const image = el("td", {});
  const cells = {
    status: el("td", { class: "status status-" + run.status }, run.status),
    bar: bar(run.progress),
    spp: el("td", {}, run.spp ?? ""),
    time: el("td", {}, run.time_s != null ? Number(run.time_s).toFixed(2) : ""),
    image,
  };
  const tr = el("tr", { "data-key": run.key },
    el("td", {}, run.role), el("td", {}, run.point), el("td", {}, run.strategy), el("td", {}, run.replicate),
    cells.status, el("td", {}, cells.bar), cells.spp, cells.time, image);
  state.rows.set(run.key, { tr, cells, run });
  showRunDetails(run.key, run);
  return tr;
}

function showRunDetails(key, run) {
  const row = state.rows.get(key);
  if (!row) return;
  const { cells } = row;
  cells.status.textContent = run.status;
  cells.status.className = "status status-" + run.status;
  cells.image.replaceChildren();
  if (run.status === "done") {
    const url = withToken("/api/runs/" + key + "/image.png");
    cells.image.append(el("a", { href: url, target: "_blank" }, el("img", { class: "thumb", src: url, alt: key })),
                       " ", el("a", { href: withToken("/api/runs/" + key + "/image.exr") }, "exr"));
  } else if (run.status === "failed") {
    const details = el("details", {}, el("summary", {}, run.error || "failed"));
    if (run.stderr_tail) details.append(el("pre", {}, run.stderr_tail));
    cells.image.append(details);
  }
}

async function select(id) {
  state.selected = id;
  if (state.source) state.source.close();
  state.rows.clear();
  document.querySelectorAll("#experiments tr").forEach((tr) => tr.classList.toggle("selected", tr.dataset.id === id));
  let view;
  try {
    view = await getJSON("/api/experiments/" + id);
  } catch (e) {
    return;
  }
  document.getElementById("detail").hidden = false;
  document.getElementById("detail-title").textContent = view.name + " (" + view.id + ")";
  showExperiment(view);
  const body = document.querySelector("#runs tbody");
  body.replaceChildren(...view.runs.map(runRow));
  links(view);
  if (view.status === "queued" || view.status === "running") follow(id);
}

function showExperiment(view) {
  const status = document.getElementById("detail-status");
  status.textContent = "status: " + view.status + (view.restarts ? " (resumed " + view.restarts + "x)" : "");
  status.className = "status status-" + view.status;
  setBar(document.getElementById("detail-bar").parentNode, view.progress || 0);
  const error = document.getElementById("detail-error");
  error.hidden = !view.error;
  error.textContent = view.error || "";
}

async function links(view) {
  const base = "/api/experiments/" + view.id;
  const p = document.getElementById("detail-links");
  p.replaceChildren(
    el("a", { href: withToken(base + "/summary.csv") }, "summary.csv"),
    el("a", { href: withToken(base + "/summary.json") }, "summary.json"),
    el("a", { href: withToken(base + "/log"), target: "_blank" }, "sweep log"),
    el("a", { href: withToken(base + "/experiment.yaml"), target: "_blank" }, "experiment.yaml"),
    el("a", { href: withToken("/viewer/viewer.html?bundle=" + encodeURIComponent(base + "/viewer/")) },
       "comparison viewer"));
  const figures = document.getElementById("figures");
  figures.replaceChildren();
  if (view.status !== "done" && view.status !== "failed") return;
  let names = [];
  try { names = await getJSON(base + "/figures"); } catch (e) { return; }
  for (const name of names.filter((n) => n.endsWith(".png"))) {
    const url = withToken(base + "/figures/" + name);
    figures.append(el("a", { href: url, target: "_blank" }, el("img", { src: url, alt: name, title: name })));
  }
}

function follow(id) {
  const source = new EventSource(withToken("/api/experiments/" + id + "/events"));
  state.source = source;
  source.addEventListener("summary", (ev) => {
    // The state at connection, in one event (the rows come from the view the page loaded).
    const data = JSON.parse(ev.data);
    showExperiment(data);
  });
  source.addEventListener("progress", (ev) => {
    const data = JSON.parse(ev.data);
    if (data.key === undefined) {
      setBar(document.getElementById("detail-bar").parentNode, data.progress);
      return;
    }
    const row = state.rows.get(data.key);
    if (!row) return;
    setBar(row.cells.bar, data.progress);
    if (data.spp != null) row.cells.spp.textContent = data.spp;
    if (data.time_s != null) row.cells.time.textContent = Number(data.time_s).toFixed(2);
  });
  source.addEventListener("status", (ev) => {
    const data = JSON.parse(ev.data);
    if (data.key === undefined) {
      document.getElementById("detail-status").textContent = "status: " + data.status;
      document.getElementById("detail-status").className = "status status-" + data.status;
      return;
    }
    if (!state.rows.has(data.key)) {
      // A render the sweep planned after the page loaded (a reference, a pilot).
      getJSON("/api/experiments/" + id).then((view) => {
        const run = view.runs.find((r) => r.key === data.key);
        if (run && !state.rows.has(run.key)) document.querySelector("#runs tbody").append(runRow(run));
      }).catch(() => {});
      return;
    }
    const row = state.rows.get(data.key);
    Object.assign(row.run, { status: data.status, error: data.error, stderr_tail: data.stderr_tail });
    showRunDetails(data.key, row.run);
  });
  source.addEventListener("end", () => {
    source.close();
    if (state.source === source) state.source = null;
    refreshList();
    if (state.selected === id) {
      getJSON("/api/experiments/" + id).then((view) => { showExperiment(view); links(view); }).catch(() => {});
    }
  });
}

document.getElementById("yaml").value = EXAMPLE;
document.getElementById("token").value = sessionStorage.getItem("portal-token") || "";
document.getElementById("submit-form").addEventListener("submit", submit);
refreshList();
setInterval(refreshList, 3000);
if (location.hash.length > 1) select(location.hash.slice(1));
