"use strict";
// uvisi label: click the object on each frame. Every change is posted to the server, which rewrites
// the labels file before it answers; the page shows a label once the server has kept it.
// Plain canvas, no library. Positions are full-resolution pixels, 0-based, pixel centres at +0.5.
(function () {
const $ = (id) => document.getElementById(id);
const BOX_W = 960, BOX_H = 640;       // the frame at zoom 1 fits this box (canvas px)
const ZOOMS = [1, 2, 4, 8];
const COLORS = { label: "#3f3", previous: "rgba(0, 200, 255, 0.7)", absent: "#f33" };
const state = { D: null, g: 0, view: null, frames: new Map(), queue: Promise.resolve(), pending: 0,
                saved: 0, finished: false, drag: null };

// ---------------------------------------------------------------- frames
function shapeOf(g) { const f = state.D.frames[g]; return [f[2], f[3]]; }
async function frameData(g) {          // {h, w, px: Float32Array (row-major), ...render cache}
  if (!state.frames.has(g)) {
    const [h, w] = shapeOf(g);
    state.frames.set(g, fetch(`frames/${g}`).then((r) => {
      if (!r.ok) throw new Error(`frame ${g}: HTTP ${r.status}`);
      return r.arrayBuffer();
    }).then((b) => {
      const px = new Float32Array(b);  // little-endian float32, as every browser's host is
      if (px.length !== h * w) throw new Error(`frame ${g}: ${px.length} pixels, expected ${h * w}`);
      return { h, w, px };
    }));
    if (state.frames.size > 24) state.frames.delete(state.frames.keys().next().value);
  }
  return state.frames.get(g);
}
function sortedSample(img) {           // up to ~200k finite pixels, sorted (the percentiles' sample)
  if (!img.sorted) {
    const step = Math.max(1, Math.floor(img.px.length / 200000)), a = [];
    for (let i = 0; i < img.px.length; i += step) if (Number.isFinite(img.px[i])) a.push(img.px[i]);
    img.sorted = Float64Array.from(a).sort();
  }
  return img.sorted;
}
function percentile(sorted, q) {
  if (!sorted.length) return 0;
  return sorted[Math.min(sorted.length - 1, Math.max(0, Math.round(q / 100 * (sorted.length - 1))))];
}
function stretch() {                   // the contrast inputs: [low %, high %], low < high
  let lo = Number($("lo").value), hi = Number($("hi").value);
  lo = Number.isFinite(lo) ? Math.max(0, Math.min(100, lo)) : 1;
  hi = Number.isFinite(hi) ? Math.max(0, Math.min(100, hi)) : 99.5;
  return lo < hi ? [lo, hi] : [Math.min(lo, hi), Math.max(lo, hi) + 1e-9];
}
function rendered(img) {               // the frame as grey levels (percentile stretch), cached
  const [qlo, qhi] = stretch(), key = `${qlo}/${qhi}`;
  if (img.off && img.key === key) return img.off;
  const s = sortedSample(img), lo = percentile(s, qlo), hi = percentile(s, qhi);
  const gain = 255 / (hi > lo ? hi - lo : 1), n = img.px.length;
  const off = img.off || document.createElement("canvas");
  off.width = img.w; off.height = img.h;
  const ctx = off.getContext("2d"), id = ctx.createImageData(img.w, img.h);
  for (let i = 0; i < n; i++) {
    const v = img.px[i], y = Number.isFinite(v) ? Math.max(0, Math.min(255, (v - lo) * gain)) : 0;
    id.data.fill(y, 4 * i, 4 * i + 3); id.data[4 * i + 3] = 255;
  }
  ctx.putImageData(id, 0, 0);
  Object.assign(img, { off, key, range: [lo, hi] });
  return off;
}

// ---------------------------------------------------------------- the view
// zoom z; (r0, c0) the image point at the canvas's top-left corner; h, w the frame's shape.
// canvas x = (col - c0) * z * canvas.width / w, and y likewise with rows.
function clampView(v) {
  v.r0 = Math.min(Math.max(0, v.r0), v.h - v.h / v.z);
  v.c0 = Math.min(Math.max(0, v.c0), v.w - v.w / v.z);
  return v;
}
function viewAbout(z, r, c, h, w) { return clampView({ z, r0: r - h / (2 * z), c0: c - w / (2 * z), h, w }); }
function sizeCanvas(h, w) {
  const s = Math.min(BOX_W / w, BOX_H / h), cv = $("frame");
  cv.width = Math.max(1, Math.round(w * s)); cv.height = Math.max(1, Math.round(h * s));
}
function fractionOf(ev, el) {          // the pointer's place across an element, 0..1 each way
  const b = el.getBoundingClientRect();
  return [(ev.clientX - b.left) / b.width, (ev.clientY - b.top) / b.height];
}
function toImage(ev) {                 // the image position under the pointer
  const v = state.view, [fx, fy] = fractionOf(ev, $("frame"));
  return { row: v.r0 + fy * v.h / v.z, col: v.c0 + fx * v.w / v.z };
}
function zoomTo(z, r, c) {             // about (r, c): by default the frame's label, else the view's centre
  const v = state.view, lab = state.D.labels[state.g];
  if (r === undefined) {
    if (Array.isArray(lab)) [r, c] = lab;
    else { r = v.r0 + v.h / (2 * v.z); c = v.c0 + v.w / (2 * v.z); }
  }
  state.view = viewAbout(z, r, c, v.h, v.w);
  $("zoom").value = String(z);
  return draw();
}
function zoomStep(d) {
  const i = ZOOMS.indexOf(state.view.z);
  return ZOOMS[Math.max(0, Math.min(ZOOMS.length - 1, i + d))];
}

// ---------------------------------------------------------------- drawing
function marker(ctx, pos, k, color, size) {   // a circle and four ticks, the pixel itself left clear
  const v = state.view, x = (pos[1] - v.c0) * k[0], y = (pos[0] - v.r0) * k[1];
  ctx.strokeStyle = color; ctx.lineWidth = 1.5; ctx.beginPath();
  ctx.arc(x, y, size, 0, 2 * Math.PI);
  for (const [dx, dy] of [[1, 0], [-1, 0], [0, 1], [0, -1]]) {
    ctx.moveTo(x + dx * size * 0.4, y + dy * size * 0.4); ctx.lineTo(x + dx * size * 1.8, y + dy * size * 1.8);
  }
  ctx.stroke();
}
function previousLabel(g) {            // the label of the frame before, in the same file
  const f = state.D.frames;
  return g > 0 && f[g - 1][0] === f[g][0] && Array.isArray(state.D.labels[g - 1]) ? state.D.labels[g - 1] : null;
}
async function draw() {
  const g = state.g, img = await frameData(g);
  if (g !== state.g) return;
  const cv = $("frame"), ctx = cv.getContext("2d"), v = state.view, off = rendered(img);
  const k = [cv.width / img.w * v.z, cv.height / img.h * v.z];
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.fillStyle = "#000"; ctx.fillRect(0, 0, cv.width, cv.height);
  ctx.imageSmoothingEnabled = k[0] < 1;          // shrunk: averaged, so a faint spot stays seen
  ctx.setTransform(k[0], 0, 0, k[1], -v.c0 * k[0], -v.r0 * k[1]);
  ctx.drawImage(off, 0, 0);
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  const prev = previousLabel(g), lab = state.D.labels[g];
  if (prev) marker(ctx, prev, k, COLORS.previous, 6);
  if (Array.isArray(lab)) marker(ctx, lab, k, COLORS.label, 9);
  if (lab === "absent") {
    ctx.strokeStyle = COLORS.absent; ctx.lineWidth = 4; ctx.strokeRect(2, 2, cv.width - 4, cv.height - 4);
    ctx.fillStyle = COLORS.absent; ctx.font = "bold 16px sans-serif"; ctx.fillText("absent", 12, 26);
  }
  $("range").textContent = `black ${img.range[0].toPrecision(5)}, white ${img.range[1].toPrecision(5)}`;
  document.body.dataset.frame = String(g);
}
function where() {
  const g = state.g, [i, k, h, w] = state.D.frames[g], f = state.D.files[i], lab = state.D.labels[g];
  $("where").textContent = `${f.name}: frame ${k} (${k + 1} of ${f.frames}) - ${h} x ${w} px - ` +
    `frame ${g + 1} of ${state.D.frames.length} in all`;
  const ls = $("label-state");
  ls.className = Array.isArray(lab) ? "point" : lab === "absent" ? "absent" : "";
  ls.textContent = Array.isArray(lab) ? `label: row ${lab[0].toFixed(2)}, col ${lab[1].toFixed(2)}` :
    lab === "absent" ? "label: absent (the object is not in this frame)" : "not labelled";
}
function strip() {
  const cv = $("strip"), ctx = cv.getContext("2d"), L = state.D.labels, F = state.D.frames;
  const w = cv.width / L.length, gap = w > 3 ? 1 : 0;
  ctx.clearRect(0, 0, cv.width, cv.height);
  L.forEach((lab, g) => {
    ctx.fillStyle = lab === null ? "#ccc" : lab === "absent" ? "#d33" : "#2a2";
    ctx.fillRect(g * w, 5, Math.max(1, w - gap), cv.height - 10);
    if (g > 0 && F[g][0] !== F[g - 1][0]) { ctx.fillStyle = "#000"; ctx.fillRect(g * w - 1, 0, 2, cv.height); }
  });
  ctx.strokeStyle = "#06f"; ctx.lineWidth = 2;
  ctx.strokeRect(state.g * w + 1, 1, Math.max(2, w - 2), cv.height - 2);
  const c = state.D.counts;
  $("counts").textContent = `${c.labelled} labelled, ${c.absent} absent, ${c.unlabelled} not labelled ` +
    `(${L.length} frames in ${state.D.files.length} file${state.D.files.length === 1 ? "" : "s"})`;
}
function status(text, error) {
  $("status").textContent = text; $("status").className = error ? "error" : "";
}
function readout(ev) {
  const img = state.img, p = toImage(ev);
  const r = Math.floor(p.row), c = Math.floor(p.col);
  const v = img && r >= 0 && c >= 0 && r < img.h && c < img.w ? img.px[r * img.w + c] : null;
  $("readout").textContent = v === null ? "" : `row ${p.row.toFixed(2)}, col ${p.col.toFixed(2)} ` +
    `(pixel ${r}, ${c}): ${v}`;
}

// ---------------------------------------------------------------- navigation and changes
function go(g) {
  const N = state.D.frames.length;
  g = Math.max(0, Math.min(N - 1, Math.round(Number(g) || 0)));
  const [h, w] = shapeOf(g), v = state.view;
  if (!v || v.h !== h || v.w !== w) {            // a frame of another shape: the whole frame
    sizeCanvas(h, w);
    state.view = viewAbout(1, h / 2, w / 2, h, w);
    $("zoom").value = "1";
  }
  state.g = g;
  if (location.hash !== `#frame=${g}`) history.replaceState(null, "", `#frame=${g}`);
  where(); strip();
  frameData(g).then((img) => { if (g === state.g) state.img = img; });
  return draw().catch((e) => status(String(e.message || e), true));
}
async function post(path, body) {
  const r = await fetch(path, { method: "POST", headers: { "Content-Type": "application/json" },
                                body: JSON.stringify(body) });
  const o = await r.json().catch(() => null);
  if (!r.ok) throw new Error((o && o.error) || `HTTP ${r.status}`);
  return o;
}
function change(kind, row, col) {      // queued: the server sees the changes in the order made
  if (state.finished) return;
  const g = state.g, body = { frame: g, kind };
  if (kind === "point") Object.assign(body, { row, col });
  state.pending++;
  state.queue = state.queue.then(() => post("label", body)).then((o) => {
    state.D.labels[o.frame] = o.label; state.D.counts = o.counts; state.saved++;
    status(`saved frame ${o.frame}: ${o.label === null ? "cleared" : o.label === "absent" ? "absent" :
      `row ${o.label[0]}, col ${o.label[1]}`}`);
    if (o.frame === state.g) { where(); draw(); }
    strip();
  }).catch((e) => status(`not saved: ${e.message || e}`, true)).finally(() => { state.pending--; });
  if ($("advance").checked && kind !== "clear") go(g + 1);
}
function finish() {
  state.queue = state.queue.then(() => post("done", {})).then((o) => {
    state.finished = true;
    document.body.classList.add("finished");
    for (const e of document.querySelectorAll("button, input, select")) e.disabled = true;
    status(`${o.summary}. The server has stopped: close this page.`);
    document.body.dataset.finished = "1";
  }).catch((e) => status(`Done failed: ${e.message || e}`, true));
}

// ---------------------------------------------------------------- input
function onKey(ev) {
  const t = ev.target;
  if (state.finished || ev.ctrlKey || ev.metaKey || ev.altKey || t.tagName === "SELECT" ||
      (t.tagName === "INPUT" && t.type !== "checkbox")) return;
  const last = state.D.frames.length - 1, clear = () => change("clear");
  const act = { ArrowRight: () => go(state.g + 1), n: () => go(state.g + 1), ArrowLeft: () => go(state.g - 1),
                p: () => go(state.g - 1), Home: () => go(0), End: () => go(last),
                a: () => change("absent"), u: clear, Backspace: clear,
                "+": () => zoomTo(zoomStep(1)), "=": () => zoomTo(zoomStep(1)),
                "-": () => zoomTo(zoomStep(-1)) }[ev.key];
  if (act) { act(); ev.preventDefault(); }
}
function bindPointer() {
  const cv = $("frame");
  cv.addEventListener("mousedown", (ev) => {
    if (ev.button !== 0 || state.finished) return;
    state.drag = { x: ev.clientX, y: ev.clientY, r0: state.view.r0, c0: state.view.c0, moved: false };
    ev.preventDefault();
  });
  window.addEventListener("mousemove", (ev) => {
    const d = state.drag, v = state.view;
    if (d && !d.moved && Math.hypot(ev.clientX - d.x, ev.clientY - d.y) > 4) { d.moved = true; cv.classList.add("panning"); }
    if (d && d.moved) {              // drag: the image follows the pointer
      const b = cv.getBoundingClientRect();
      v.c0 = d.c0 - (ev.clientX - d.x) / b.width * v.w / v.z;
      v.r0 = d.r0 - (ev.clientY - d.y) / b.height * v.h / v.z;
      clampView(v); draw();
    }
    if (ev.target === cv) readout(ev);
  });
  window.addEventListener("mouseup", (ev) => {
    const d = state.drag;
    state.drag = null; cv.classList.remove("panning");
    if (d && !d.moved && ev.target === cv) { const p = toImage(ev); change("point", p.row, p.col); }
  });
  cv.addEventListener("wheel", (ev) => {   // zoom about the point under the pointer
    ev.preventDefault();
    const v = state.view, z = zoomStep(ev.deltaY < 0 ? 1 : -1);
    if (z === v.z) return;
    const p = toImage(ev), [fx, fy] = fractionOf(ev, cv);
    state.view = clampView({ z, r0: p.row - fy * v.h / z, c0: p.col - fx * v.w / z, h: v.h, w: v.w });
    $("zoom").value = String(z); draw();
  }, { passive: false });
  $("strip").addEventListener("click", (ev) => go(Math.floor(fractionOf(ev, $("strip"))[0] * state.D.labels.length)));
}
async function init() {
  const r = await fetch("data.json");
  if (!r.ok) throw new Error(`data.json: HTTP ${r.status}`);
  state.D = await r.json();
  $("out").textContent = `${state.D.out} (labeller ${state.D.labeller})`;
  $("prev").addEventListener("click", () => go(state.g - 1));
  $("next").addEventListener("click", () => go(state.g + 1));
  $("absent").addEventListener("click", () => change("absent"));
  $("clear").addEventListener("click", () => change("clear"));
  $("done").addEventListener("click", finish);
  $("zoom").addEventListener("change", () => { $("zoom").blur(); zoomTo(Number($("zoom").value)); });
  for (const id of ["lo", "hi"]) $(id).addEventListener("change", () => draw());
  document.addEventListener("keydown", onKey);
  bindPointer();
  const m = /frame=(\d+)/.exec(location.hash);    // else the first frame not labelled
  go(m ? Number(m[1]) : Math.max(0, state.D.labels.indexOf(null)));
}
// for tests and the console: the frame shown, the view, the labels as the server keeps them, the
// changes not yet answered, and a promise of every change made so far being answered
window.uvisiLabel = { go, get frame() { return state.g; }, get view() { return state.view; },
                      get labels() { return state.D.labels; }, get pending() { return state.pending; },
                      get saved() { return state.saved; }, settled: () => state.queue };
init().catch((e) => status(String(e.message || e), true));
})();
