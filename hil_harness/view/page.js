"use strict";
// uvisi view: one recorded event, frame by frame. Plain canvas, no library, no network when inline.
(function () {
const D = JSON.parse(document.getElementById("uvisi-data").textContent);
const IMG = JSON.parse(document.getElementById("uvisi-images").textContent);
const F = D.frames, N = D.recording.frames_held, S = 2;          // S: display px per imager px
const $ = (id) => document.getElementById(id);
const fmt = (v, d) => (v === null || v === undefined) ? "-" :
  (typeof v === "number" ? (Number.isInteger(v) ? String(v) : v.toPrecision(d || 5)) : String(v));
// The one way anything reaches the page, on the written and the served page alike: an element
// whose attribute values and children are set as values and text nodes, never parsed as HTML (a
// recording's text -- names, reasons, error messages quoting its configuration -- is data).
// attrs: {name: value} (names from this file only; null/undefined left out), "class", and
// "style" ({property: value}); kids: nodes or strings (text), arrays of them flattened.
function el(tag, attrs, ...kids) {
  const e = document.createElement(tag);
  for (const [name, v] of Object.entries(attrs || {})) {
    if (v === null || v === undefined) continue;
    if (name === "class") e.className = String(v);
    else if (name === "style") for (const [p, x] of Object.entries(v)) e.style.setProperty(p, String(x));
    else e.setAttribute(name, String(v));
  }
  for (const c of kids.flat()) if (c !== null && c !== undefined) e.append(c instanceof Node ? c : String(c));
  return e;
}
function warn(text) { $("warnings").append(el("div", { class: "warn", "data-warning": "" }, text)); }
const state = { k: 0, playing: null, lo: null, hi: null, cache: new Map(), stageCache: new Map() };

// ---------------------------------------------------------------- image decoding
function b64bytes(s) {
  const bin = atob(s), out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out;
}
async function inflate(bytes) {
  const ds = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
  return new Uint8Array(await new Response(ds).arrayBuffer());
}
// byte planes (little-endian, plane j = byte j of every pixel) -> typed array of the stored dtype
function unplane(planes, shape, dtype) {
  const n = shape[0] * shape[1], w = Number(dtype[1]);
  if (planes.length !== n * w) throw new Error(`image: ${planes.length} bytes, expected ${n * w}`);
  const Arr = { u1: Uint8Array, i1: Int8Array, u2: Uint16Array, i2: Int16Array, u4: Uint32Array,
                i4: Int32Array }[dtype];
  const out = new Arr(n);
  for (let i = 0; i < n; i++) {
    let v = 0;
    for (let j = 0; j < w; j++) v += planes[j * n + i] * 2 ** (8 * j);
    out[i] = v;                    // typed-array assignment wraps: two's complement for signed
  }
  return out;
}
async function decode(entry) {
  const bytes = typeof entry.data === "string" ? b64bytes(entry.data) : entry.data;
  return { shape: entry.shape, dtype: entry.dtype, pixels: unplane(await inflate(bytes), entry.shape,
           entry.dtype) };
}
async function frameImage(k) {
  if (!D.recording.has_frames) return null;
  if (state.cache.has(k)) return state.cache.get(k);
  let p;
  if (IMG.mode === "inline") {
    p = IMG.frames[k] ? decode(IMG.frames[k]) : Promise.resolve(null);
  } else {
    p = fetch(`frames/${k}`).then((r) => {
      if (!r.ok) throw new Error(`frame ${k}: HTTP ${r.status}`);
      return r.arrayBuffer();
    }).then((b) => decode({ shape: D.image_shape, dtype: "u2", data: new Uint8Array(b) }));
  }
  state.cache.set(k, p);
  if (state.cache.size > 64) state.cache.delete(state.cache.keys().next().value);
  return p;
}
async function stageImages(k) {
  if (state.stageCache.has(k)) return state.stageCache.get(k);
  let p;
  if (IMG.mode === "inline") {
    p = Promise.resolve((IMG.stages && IMG.stages[String(k)]) || []);
  } else {
    p = fetch(`stages/${k}`).then((r) => (r.ok ? r.json() : { stages: [], mismatch: null })).then((o) => {
      if (o.mismatch !== null && D.stage_mismatch === null) {
        D.stage_mismatch = o.mismatch;
        warn(`The replay of the stages differs from the recording from frame ${o.mismatch}.`);
      }
      if (o.error && !state.stageError) {
        state.stageError = o.error;
        warn(`The stages could not be replayed (${o.error}): only the recording's own stage frame ` +
             "is shown.");
      }
      return o.stages;
    });
  }
  p = p.then((list) => Promise.all(list.map(async (e) => Object.assign({ name: e.name },
                                                                       await decode(e)))));
  state.stageCache.set(k, p);
  if (state.stageCache.size > 16) state.stageCache.delete(state.stageCache.keys().next().value);
  return p;
}
async function starsOf(k) {               // the catalogued stars of frame k (fetched when served)
  if (!D.stars) return [];
  if (IMG.mode === "inline") return D.stars[k] || [];
  if (!state.starCache) state.starCache = new Map();
  if (!state.starCache.has(k)) {
    state.starCache.set(k, fetch(`stars/${k}`).then((r) => (r.ok ? r.json() : [])));
    if (state.starCache.size > 64) state.starCache.delete(state.starCache.keys().next().value);
  }
  return (await state.starCache.get(k)) || [];
}
function percentile(pix, q) {
  const a = Float64Array.from(pix).sort();
  return a[Math.min(a.length - 1, Math.max(0, Math.floor(q / 100 * (a.length - 1))))];
}
function toCanvas(img, lo, hi, cv) {
  const [h, w] = img.shape;
  cv.width = w; cv.height = h;
  const ctx = cv.getContext("2d"), id = ctx.createImageData(w, h), g = 255 / Math.max(1, hi - lo);
  for (let i = 0; i < w * h; i++) {
    const v = Math.max(0, Math.min(255, (img.pixels[i] - lo) * g));
    id.data[4 * i] = id.data[4 * i + 1] = id.data[4 * i + 2] = v; id.data[4 * i + 3] = 255;
  }
  ctx.putImageData(id, 0, 0);
  return cv;
}

// ---------------------------------------------------------------- the frame and its overlays
const COLORS = { window: "#39f", cand: "#ff0", chosen: "#0f0", truth: "#f0f", pred: "#0ff",
                 star: "#f80", object: "#f33", ellipse: "#0ff", stars: "rgba(255,160,0,0.8)" };
function legend() {
  const items = [["window", "processing window"], ["cand", "candidates (rank)"],
                 ["chosen", "TP's choice"], ["truth", "truth: object"], ["pred", "TP prediction + gate"],
                 ["star", "star gate"], ["object", "object gate"],
                 ["ellipse", D.covariance === "diagonal" ? "EKF 1-sigma ellipse (recorded diagonal only)" :
                  "EKF 1-sigma ellipse"]];
  $("legend").replaceChildren(...items.map(([c, t]) =>
    el("span", {}, el("i", { style: { background: COLORS[c] } }), t)));
}
const off = document.createElement("canvas");
async function drawFrame() {
  const k = state.k, cv = $("frame"), ctx = cv.getContext("2d");
  const img = await frameImage(k);
  const stars = $("show-stars").checked ? await starsOf(k) : [];
  if (k !== state.k) return;
  cv.width = D.image_shape[1] * S; cv.height = D.image_shape[0] * S;
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.fillStyle = "#000"; ctx.fillRect(0, 0, cv.width, cv.height);
  const v = state.view = zoomView(k, cv);
  ctx.setTransform(v.z, 0, 0, v.z, v.tx, v.ty);
  if (img) {
    if (state.lo === null) autoContrast(img);
    toCanvas(img, state.lo, state.hi, off);
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(off, 0, 0, cv.width, cv.height);
  } else {
    ctx.fillStyle = "#888"; ctx.font = "14px sans-serif";
    ctx.fillText(D.recording.has_frames ? "no image for this frame" :
                 "recorded with --no-frames: no images", 20, 30);
  }
  state.img = img;
  overlays(ctx, k, stars, v.z);
  ctx.setTransform(1, 0, 0, 1, 0, 0);
}
// the zoom: magnification z about the TP's prediction for the frame (else the window's centre,
// else the image centre), kept inside the image; canvas px = z * (imager px * S) + (tx, ty)
function zoomView(k, cv) {
  const z = Number($("zoom").value) || 1;
  if (z <= 1) return { z: 1, tx: 0, ty: 0 };
  const w = F.window, comp = w.compaction[k] || 1;
  let r = F.pred_row[k], c = F.pred_col[k];
  if (r === null && w.row0[k] !== null) { r = w.row0[k] + w.rows[k] * comp / 2; c = w.col0[k] + w.cols[k] * comp / 2; }
  if (r === null) { r = D.image_shape[0] / 2; c = D.image_shape[1] / 2; }
  const clamp = (v, lo, hi) => Math.min(hi, Math.max(lo, v));
  const tx = clamp(cv.width / 2 - z * c * S, cv.width * (1 - z), 0);
  const ty = clamp(cv.height / 2 - z * r * S, cv.height * (1 - z), 0);
  return { z, tx, ty };
}
function box(ctx, r0, c0, h, w, color, dash) {
  ctx.strokeStyle = color; ctx.setLineDash(dash || []);
  ctx.strokeRect(c0 * S, r0 * S, w * S, h * S); ctx.setLineDash([]);
}
function cross(ctx, r, c, color, size) {
  const x = c * S, y = r * S, s = size || 6;
  ctx.strokeStyle = color; ctx.beginPath();
  ctx.moveTo(x - s, y); ctx.lineTo(x + s, y); ctx.moveTo(x, y - s); ctx.lineTo(x, y + s); ctx.stroke();
}
function overlays(ctx, k, stars, z) {
  ctx.lineWidth = 1.5 / (z || 1); ctx.font = `${11 / (z || 1)}px sans-serif`;
  const w = F.window, comp = w.compaction[k] || 1;
  if (w.row0[k] !== null) box(ctx, w.row0[k], w.col0[k], w.rows[k] * comp, w.cols[k] * comp, COLORS.window);
  ctx.strokeStyle = COLORS.stars;
  for (const [r, c] of stars) { ctx.beginPath(); ctx.arc(c * S, r * S, 5, 0, 7); ctx.stroke(); }
  const ci = D.candidate_columns.indexOf("row"), cj = D.candidate_columns.indexOf("col");
  for (const row of D.candidates[k]) {
    const chosen = row[0] === F.object_index[k] + 1;
    ctx.strokeStyle = chosen ? COLORS.chosen : COLORS.cand;
    ctx.beginPath(); ctx.arc(row[cj] * S, row[ci] * S, chosen ? 9 : 7, 0, 7); ctx.stroke();
    ctx.fillStyle = ctx.strokeStyle; ctx.fillText(String(row[0]), row[cj] * S + 9, row[ci] * S - 6);
  }
  if (F.in_field[k] && F.truth_row[k] !== null) cross(ctx, F.truth_row[k], F.truth_col[k], COLORS.truth, 8);
  const tp = D.tp[k], g = (tp && tp.mode === "opportunity") ? D.gate.opp_gate_px : D.gate.gate_px;
  if (F.pred_row[k] !== null) {
    cross(ctx, F.pred_row[k], F.pred_col[k], COLORS.pred, 5);
    box(ctx, F.pred_row[k] - g, F.pred_col[k] - g, 2 * g, 2 * g, COLORS.pred, [3, 2]);
  }
  if (tp && $("show-gates").checked) {
    for (const [, pair, kind, r, c] of tp.gates) {
      if (r === null) continue;
      box(ctx, r - D.gate.gate_px, c - D.gate.gate_px, 2 * D.gate.gate_px, 2 * D.gate.gate_px,
          kind ? COLORS.object : COLORS.star);
      ctx.fillStyle = kind ? COLORS.object : COLORS.star;
      ctx.fillText(`${kind ? "O" : "S"}${pair}`, (c + D.gate.gate_px) * S + 2, (r + D.gate.gate_px) * S + 10);
    }
  }
  const e = D.ellipse[k];
  if (e) {
    ctx.strokeStyle = COLORS.ellipse; ctx.beginPath();
    ctx.ellipse(e[1] * S, e[0] * S, Math.max(1, e[2] * S), Math.max(1, e[3] * S), e[4], 0, 7);
    ctx.stroke();
  }
}
function autoContrast(img) {
  state.lo = Math.round(percentile(img.pixels, 1));
  state.hi = Math.max(state.lo + 1, Math.round(percentile(img.pixels, 99.9)));
  $("lo").value = state.lo; $("hi").value = state.hi;
}
function stagePixel(name, r, c) {          // the value of pixel (r, c) of a stage image shown
  const s = (state.stages || []).find((x) => x.name === name);
  return s ? s.pixels[r * s.shape[1] + c] : null;
}
function pixelAt(r, c) {                    // the 12-bit value of pixel (r, c) of the frame shown
  const img = state.img;
  if (!img || r < 0 || c < 0 || r >= img.shape[0] || c >= img.shape[1]) return null;
  return img.pixels[r * img.shape[1] + c];
}

// ---------------------------------------------------------------- panels
function field(name, label, value) {
  const list = Array.isArray(value);
  const v = (value === null || value === undefined) ? "" : (list ? value.join(" ") : value);
  const shown = list ? (value.join(", ") || "-") : fmt(value);
  return [el("dt", {}, label), el("dd", { "data-field": name, "data-value": v }, shown)];
}
function why(k) {
  const tp = D.tp[k], oi = F.object_index[k];
  if (!F.has_command[k]) return F.skip[k] ? `no TP step: ${F.skip_reason[k]}` : "no track command";
  if (oi < 0) {
    return F.status_names[k].includes("coasting") ? "no candidate chosen: coasting on the prediction"
      : "no candidate chosen";
  }
  if (tp && tp.mode === "opportunity") {
    return "opportunity mode: the highest-ranked candidate inside the angular gate";
  }
  if (F.decided_frame[k] < 0) return `candidate ${oi + 1}: no star/object decision yet`;
  const rule = tp && tp.decision_rule ? D.rules[String(tp.decision_rule)] : "an unrecorded rule";
  return `candidate ${oi + 1} is in the object gate of pair ${tp ? tp.object_pair : "?"}, decided ` +
         `at frame ${F.decided_frame[k]} by ${rule}`;
}
function hypotheses(tp) {                   // one line per gate pair: what the TP holds it to be
  const pairs = {};
  for (const [, pair, kind, , , missed, obs] of tp.gates || []) {
    pairs[pair] = pairs[pair] || { s: null, o: null };
    pairs[pair][kind ? "o" : "s"] = { missed, obs };
  }
  const gate = (g) => (g ? `obs ${g.obs} missed ${g.missed}` : "-");
  const lines = Object.entries(pairs).map(([p, v]) => {
    const what = v.s && v.o ? "star or object? (undecided)" :
      v.o ? (Number(p) === tp.object_pair ? "object (decided)" : "object gate only") : "star gate only";
    return `pair ${p}: ${what} [star ${gate(v.s)}, object ${gate(v.o)}]`;
  });
  return lines.length ? lines : ["none"];
}
function tpPanel(k) {
  const tp = D.tp[k] || {};
  const rows = [
    ["frame", "frame", F.k[k]], ["t", "t (s)", F.t[k]], ["imager", "imager", F.imager[k]],
    ["skip", "skipped", F.skip_reason[k] || "no"], ["locked", "locked", F.locked[k]],
    ["status", "status word", F.status[k]], ["status_names", "status", F.status_names[k]],
    ["mode", "mode", F.mode[k]],
    ["object_index", "chosen candidate (rank)", F.object_index[k] >= 0 ? F.object_index[k] + 1 : "none"],
    ["why", "why", why(k)], ["decision_rule", "decision rule", tp.decision_rule || 0],
    ["object_pair", "object pair", tp.object_pair], ["decided_frame", "decided at frame", F.decided_frame[k]],
    ["n_star_gates", "live star gates", F.n_star_gates[k]],
    ["n_object_gates", "live object gates", F.n_object_gates[k]],
    ["hypotheses", "hypotheses", hypotheses(tp)],
    ["pred_row", "prediction row (this frame)", F.pred_row[k]], ["pred_col", "prediction col", F.pred_col[k]],
    ["next_row", "prediction row (next)", F.next_row[k]], ["next_col", "prediction col (next)", F.next_col[k]],
    ["ekf_running", "EKF running", tp.ekf_running], ["sigma_pos", "EKF sigma pos (m)", F.sigma_pos[k]],
    ["error_urad", "track error (urad, truth)", F.error_urad[k]], ["alpha", "alpha", F.alpha[k]],
    ["n_candidates", "candidates", F.n_candidates[k]], ["n_blobs", "blobs", F.n_blobs[k]]];
  $("tp-state").replaceChildren(...rows.flatMap(([name, label, v]) => field(name, label, v)));
}
function candTable(k) {
  const cols = D.candidate_columns;
  $("cand-table").tHead.replaceChildren(el("tr", {}, cols.map((c) => el("th", {}, c)), el("th", {}, "TP")));
  const rows = D.candidates[k];
  $("cand-table").tBodies[0].replaceChildren(...rows.map((r) => {
    const chosen = r[0] === F.object_index[k] + 1;
    return el("tr", { "data-rank": r[0], class: chosen ? "chosen" : null },
      r.map((v, i) => el("td", { "data-col": cols[i], "data-value": v === null ? "" : v }, fmt(v))),
      el("td", { "data-col": "chosen" }, chosen ? "chosen" : ""));
  }));
  $("cand-note").textContent = rows.length ? `(${rows.length}, best GOF first)` :
    (F.skip[k] ? `(none: ${F.skip_reason[k]})` : "(none reported)");
}
function budgetPanel(k) {
  const cv = $("budget"), ctx = cv.getContext("2d"), per = {}, rows = D.budget.frames[k] || [];
  for (const [i, ms] of rows) { const p = D.budget.stages[i].split("/")[0]; per[p] = (per[p] || 0) + ms; }
  ctx.clearRect(0, 0, cv.width, cv.height); ctx.font = "11px sans-serif";
  const procs = Object.keys(D.processors), x0 = 60, w = cv.width - x0 - 10;
  procs.forEach((p, j) => {
    const y = 8 + j * 26, ms = per[p] || 0;
    ctx.fillStyle = "#333"; ctx.fillText(p, 2, y + 12);
    ctx.fillStyle = "#eee"; ctx.fillRect(x0, y, w, 16);
    ctx.fillStyle = ms > D.period_ms ? "#d33" : "#48c"; ctx.fillRect(x0, y, Math.min(1, ms / D.period_ms) * w, 16);
    ctx.fillStyle = "#000"; ctx.textAlign = "right";
    ctx.fillText(`${ms.toFixed(2)} ms`, x0 + w - 4, y + 12); ctx.textAlign = "left";
  });
  $("budget-table").tBodies[0].replaceChildren(...rows.map(([i, ms]) => el("tr", {},
    el("td", { style: { "text-align": "left" } }, D.budget.stages[i]),
    el("td", { "data-stage": D.budget.stages[i] }, fmt(ms, 4)))));
}
async function stagesPanel(k) {
  const list = await stageImages(k);
  if (k !== state.k) return;
  state.stages = list;
  const box = $("stages");
  box.replaceChildren();
  $("stage-note").textContent = list.length ? `(frame ${k}, ${list[0].shape[0]} x ${list[0].shape[1]} processed px)` :
    `(${D.stage_note})`;
  for (const s of list) {
    let lo = Infinity, hi = -Infinity;
    for (const v of s.pixels) { if (v < lo) lo = v; if (v > hi) hi = v; }
    const fig = document.createElement("figure"), cv = document.createElement("canvas");
    toCanvas(s, lo, hi === lo ? lo + 1 : hi, cv);
    fig.appendChild(cv);
    fig.append(el("figcaption", {}, `${s.name} [${lo}, ${hi}]`));
    box.appendChild(fig);
  }
}

// ---------------------------------------------------------------- strips (whole event)
function chosenGof() {
  const gi = D.candidate_columns.indexOf("gof");
  return D.candidates.map((rows, k) => {
    const r = rows.find((x) => x[0] === F.object_index[k] + 1);
    return r ? r[gi] : null;
  });
}
const STRIP_X0 = 110, STRIP_W = 780;        // frame 0 .. N-1 drawn at x = STRIP_X0 .. + STRIP_W
const STRIPS = [["track error (urad, truth)", () => F.error_urad], ["candidates", () => F.n_candidates],
                ["alpha", () => F.alpha], ["GOF of the chosen", chosenGof],
                ["locked", () => F.locked.map((v) => (v < 0 ? null : v))]];
function drawStrips() {
  const box = $("strips");
  if (!box.children.length) {
    for (const [name] of STRIPS.concat([["faults / uplinks / switches"]])) {
      const cv = document.createElement("canvas");
      cv.className = "strip"; cv.width = 900; cv.height = 44; cv.dataset.strip = name;
      cv.addEventListener("click", (ev) => {          // the inverse of STRIP_X below
        const r = cv.getBoundingClientRect(), x = (ev.clientX - r.left) * cv.width / r.width;
        go((x - STRIP_X0) / STRIP_W * Math.max(1, N - 1));
      });
      box.appendChild(cv);
    }
  }
  const cvs = box.children, xs = (k) => STRIP_X0 + (k / Math.max(1, N - 1)) * STRIP_W;
  STRIPS.forEach(([name, get], j) => {
    const ctx = cvs[j].getContext("2d"), v = get(), ok = v.filter((x) => x !== null && isFinite(x));
    const lo = Math.min(0, ...ok), hi = Math.max(lo + 1e-9, ...ok);
    ctx.clearRect(0, 0, 900, 44); ctx.fillStyle = "#fff"; ctx.fillRect(110, 0, 790, 44);
    ctx.fillStyle = "#333"; ctx.font = "11px sans-serif"; ctx.fillText(name, 2, 18);
    ctx.fillStyle = "#777"; ctx.fillText(fmt(hi, 3), 2, 34);
    ctx.strokeStyle = "#36c"; ctx.beginPath();
    let pen = false;
    v.forEach((y, k) => {
      if (y === null || !isFinite(y)) { pen = false; return; }
      const Y = 40 - (y - lo) / (hi - lo) * 36;
      if (pen) ctx.lineTo(xs(k), Y); else ctx.moveTo(xs(k), Y);
      pen = true;
    });
    ctx.stroke();
    cursor(ctx, xs(state.k));
  });
  const ctx = cvs[STRIPS.length].getContext("2d");
  ctx.clearRect(0, 0, 900, 44); ctx.fillStyle = "#fff"; ctx.fillRect(110, 0, 790, 44);
  ctx.fillStyle = "#333"; ctx.fillText("faults / uplinks", 2, 18);
  ctx.fillStyle = "#777"; ctx.fillText("red: refused", 2, 34);
  for (const e of D.events) {
    ctx.fillStyle = /refused|rejected/.test(e.verdict) ? "#d22" : e.kind.startsWith("uplink") ? "#2a2" :
      e.kind.startsWith("switch") ? "#a2a" : "#e80";
    ctx.fillRect(xs(e.frame) - 1, 4, 3, 36);
  }
  F.skip.forEach((s, k) => { if (s) { ctx.fillStyle = "#999"; ctx.fillRect(xs(k), 38, 2, 6); } });
  cursor(ctx, xs(state.k));
}
function cursor(ctx, x) {
  ctx.strokeStyle = "#e00"; ctx.beginPath(); ctx.moveTo(x, 0); ctx.lineTo(x, 44); ctx.stroke();
}
function eventList() {
  $("events").replaceChildren(D.events.length ? el("ul", {}, D.events.map((e) =>
    el("li", { "data-frame": e.frame }, `frame ${e.frame} (t = ${fmt(e.t, 4)} s): ` +
       `${e.kind} ${e.verdict} ${e.text}`))) : el("p", {}, "no faults, uplinks or switches in this event"));
  for (const li of $("events").querySelectorAll("li")) li.addEventListener("click", () => go(Number(li.dataset.frame)));
}

// ---------------------------------------------------------------- navigation
let shown = Promise.resolve();
function go(k) {
  k = Math.max(0, Math.min(N - 1, Math.round(Number(k) || 0)));
  state.k = k;
  $("slider").value = k; $("frame-number").textContent = k; $("frame-time").textContent = fmt(F.t[k], 4);
  $("imager").textContent = `${F.imager[k]}${F.skip[k] ? ` (${F.skip_reason[k]})` : ""}`;
  if (location.hash !== `#frame=${k}`) history.replaceState(null, "", `#frame=${k}`);
  tpPanel(k); candTable(k); budgetPanel(k); drawStrips();
  const drawn = drawFrame().then(() => {
    if (window.uvisiView.firstFrameMs === null) window.uvisiView.firstFrameMs = performance.now();
  });
  shown = Promise.all([drawn, stagesPanel(k)]).then(() => { document.body.dataset.frame = k; })
    .catch((err) => { console.error(err); throw err; });
  return shown;
}
function fromHash() {
  const m = /frame=(\d+)/.exec(location.hash);
  return m ? Number(m[1]) : 0;
}
function play() {
  if (state.playing) { clearInterval(state.playing); state.playing = null; $("play").textContent = "play"; return; }
  $("play").textContent = "pause";
  state.playing = setInterval(() => { if (state.k >= N - 1) play(); else go(state.k + 1); },
                              1000 / Number($("rate").value));
}
function init() {
  const r = D.recording;
  $("title").textContent = `${r.scenario} (${r.name})`;
  $("facts").textContent = `${N} frames held of ${r.frames_planned} planned; seed ${r.seed}; sequence ` +
    `${r.sequence}, record ${r.record}; run ${r.run_id}` + (r.lock_frame !== null && r.lock_frame !== undefined ?
    `; locked at frame ${r.lock_frame}` : "");
  const warnings = [];
  if (!r.complete) warnings.push(`Incomplete recording (complete = False): the event was interrupted; ` +
    `it holds ${N} of ${r.frames_planned} planned frames.`);
  if (!r.has_frames) warnings.push("Recorded with --no-frames: no images; everything else is shown.");
  if (D.stage_mismatch !== null && D.stage_mismatch !== undefined) warnings.push(`The replay of the ` +
    `stages differs from the recording from frame ${D.stage_mismatch}: later stages are not the recorded run's.`);
  $("warnings").replaceChildren();
  for (const w of warnings) warn(w);
  $("slider").max = Math.max(0, N - 1); $("frame-last").textContent = Math.max(0, N - 1);
  $("slider").addEventListener("input", () => go($("slider").value));
  $("prev").addEventListener("click", () => go(state.k - 1));
  $("next").addEventListener("click", () => go(state.k + 1));
  $("play").addEventListener("click", play);
  $("rate").addEventListener("change", () => { if (state.playing) { play(); play(); } });
  for (const id of ["lo", "hi"]) $(id).addEventListener("change", () => {
    state.lo = Math.max(0, Math.min(4094, Number($("lo").value)));
    state.hi = Math.max(state.lo + 1, Math.min(4095, Number($("hi").value)));
    drawFrame();
  });
  $("auto").addEventListener("click", () => { if (state.img) { autoContrast(state.img); drawFrame(); } });
  $("show-stars").addEventListener("change", drawFrame);
  $("show-gates").addEventListener("change", drawFrame);
  $("zoom").addEventListener("change", drawFrame);
  if (!D.stars) { $("show-stars").disabled = true; $("show-stars").parentElement.title = "not recorded"; }
  $("frame").addEventListener("mousemove", (ev) => {
    const cv = $("frame"), b = cv.getBoundingClientRect(), vw = state.view || { z: 1, tx: 0, ty: 0 };
    const x = (ev.clientX - b.left) / b.width * cv.width, y = (ev.clientY - b.top) / b.height * cv.height;
    const c = Math.floor((x - vw.tx) / vw.z / S), rr = Math.floor((y - vw.ty) / vw.z / S);
    const v = pixelAt(rr, c);
    $("pixel-readout").textContent = v === null ? "" : `pixel row ${rr}, col ${c}: ${v} counts`;
  });
  document.addEventListener("keydown", (ev) => {
    if (ev.target.tagName === "INPUT" && ev.target.type !== "range") return;
    if (ev.key === "ArrowRight") { go(state.k + 1); ev.preventDefault(); }
    else if (ev.key === "ArrowLeft") { go(state.k - 1); ev.preventDefault(); }
    else if (ev.key === "Home") go(0);
    else if (ev.key === "End") go(N - 1);
    else if (ev.key === " ") { play(); ev.preventDefault(); }
    else if (ev.key === "+" || ev.key === "-") {
      const zs = [...$("zoom").options].map((o) => o.value), i = zs.indexOf($("zoom").value);
      $("zoom").value = zs[Math.max(0, Math.min(zs.length - 1, i + (ev.key === "+" ? 1 : -1)))];
      drawFrame();
    }
  });
  window.addEventListener("hashchange", () => go(fromHash()));
  legend(); eventList();
  if (N === 0) { warn("No frame recorded."); return; }
  go(fromHash());
}
// for tests and the console: the frame shown, a pixel's stored value, a promise of the current draw
// (firstFrameMs: performance.now() when the first frame was drawn, the load time bench/ measures)
window.uvisiView = { go, get frame() { return state.k; }, pixel: pixelAt, stagePixel, shown: () => shown, data: D,
                     firstFrameMs: null, get view() { return state.view; } };
init();
})();
