// robofleet replay page: draws a scene (robofleet.viz.replay.scene) on canvases.
// Self-contained: the data is embedded in the page, nothing is fetched.
"use strict";

const MARGIN = { left: 58, right: 12, top: 8, bottom: 40 };
const SPEEDS = [0.05, 0.1, 0.25, 0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500];
const EVENT_COLORS = ["#d62728", "#ff7f0e", "#9467bd", "#2ca02c", "#8c564b", "#e377c2", "#17becf", "#7f7f7f"];
const TRAIL_ROBOT_LIMIT = 300;
const TYPED = { f4: Float32Array, i4: Int32Array, u1: Uint8Array };

// ---- data --------------------------------------------------------------------------------
async function decodeArray(enc) {
  if (!enc) return null;
  const text = atob(enc.data);
  const bytes = new Uint8Array(text.length);
  for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
  let buffer = await new Response(stream).arrayBuffer();
  const width = TYPED[enc.dtype].BYTES_PER_ELEMENT;
  if (enc.shuffle && width > 1) {  // bytes grouped by plane: value i's byte b is at b * n + i
    const planes = new Uint8Array(buffer), out = new Uint8Array(planes.length), n = planes.length / width;
    for (let b = 0; b < width; b++) {
      const base = b * n;
      for (let i = 0; i < n; i++) out[i * width + b] = planes[base + i];
    }
    buffer = out.buffer;
  }
  const array = new TYPED[enc.dtype](buffer);
  array.shape = enc.shape;
  return array;
}

// Events are columns ordered by frame: frame, kind (into kinds), robot (-1: none), step,
// text (into texts, -1: none).
async function decodeEvents(doc) {
  const ev = { kinds: doc.kinds, texts: doc.texts };
  for (const k of ["frame", "kind", "robot", "step", "text"]) ev[k] = await decodeArray(doc[k]);
  ev.length = ev.frame.length;
  ev.counts = new Array(ev.kinds.length).fill(0);
  for (let i = 0; i < ev.length; i++) ev.counts[ev.kind[i]]++;
  return ev;
}

function eventsUpTo(ev, frame) {  // the number of events at frames <= frame
  let lo = 0, hi = ev.length;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (ev.frame[mid] <= frame) lo = mid + 1; else hi = mid; }
  return lo;
}

function eventText(ev, i, names) {
  const robot = ev.robot[i], text = ev.text[i], step = ev.step[i];
  const detail = [step >= 0 ? `step ${step}` : null, text >= 0 ? ev.texts[text] : null].filter((x) => x).join(", ");
  return `${ev.kinds[ev.kind[i]]}${robot >= 0 ? " · " + names[robot] : ""}${detail ? " · " + detail : ""}`;
}

async function decodeScene(doc) {
  const s = Object.assign({}, doc);
  s.steps = await decodeArray(doc.steps);
  s.times = await decodeArray(doc.times);
  s.positions = await decodeArray(doc.positions);
  s.robot_colors = await decodeArray(doc.robot_colors);
  s.status = await decodeArray(doc.status);
  s.coordinates = {};
  for (const [k, v] of Object.entries(doc.coordinates)) s.coordinates[k] = await decodeArray(v);
  s.fields = [];
  for (const f of doc.fields) s.fields.push(Object.assign({}, f, { values: await decodeArray(f.values) }));
  s.events = await decodeEvents(doc.events);
  s.layers = [];
  for (const layer of doc.layers) {
    const arrays = {};
    for (const [k, v] of Object.entries(layer.arrays)) arrays[k] = await decodeArray(v);
    s.layers.push(Object.assign({}, layer, { arrays }));
  }
  return s;
}

// ---- small helpers -------------------------------------------------------------------------
function el(tag, attrs, text) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}

function niceStep(range, target) {
  const raw = range / Math.max(1, target);
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p;
  return 10 * p;
}

function formatNumber(v, digits) {
  if (v === null || v === undefined || Number.isNaN(v)) return "–";
  if (!Number.isFinite(v)) return v > 0 ? "∞" : "−∞";
  const a = Math.abs(v);
  if (a !== 0 && (a >= 1e5 || a < 1e-3)) return v.toExponential(2);
  return Number(v.toFixed(digits === undefined ? 3 : digits)).toString();
}

function eventColor(kind, kinds) {
  return EVENT_COLORS[kinds.indexOf(kind) % EVENT_COLORS.length];
}

// ---- the replay ----------------------------------------------------------------------------
class Replay {
  constructor(scene) {
    this.s = scene;
    this.N = scene.n_robots;
    this.F = scene.n_frames;
    this.D = scene.dim;
    this.frame = 0;
    this.playing = false;
    this.simTime = 0;
    this.hovered = -1;
    this.selected = -1;
    this.hidden = new Set(scene.hidden || []);
    if (this.N > TRAIL_ROBOT_LIMIT) this.hidden.add("trails");
    this.eventKinds = scene.events.kinds;
    this.views = [];
    this.dirty = true;
    this.drawCount = 0;
    this.stepPerTick = false;
    this.buildViews();
    this.buildPanels();
    this.buildControls();
    this.bindKeys();
    window.addEventListener("resize", () => { this.resize(); });
    window.addEventListener("hashchange", () => this.readHash());
    this.resize();
    this.readHash();
    requestAnimationFrame((t) => this.tick(t));
  }

  // -- coordinates --
  coord(view, f, i) {
    const v = view.spec;
    if (v.source === "positions") {
      const base = (f * this.N + i) * this.D;
      return [this.s.positions[base + v.axes[0]], this.s.positions[base + v.axes[1]]];
    }
    const c = this.s.coordinates[v.source];
    const base = (f * this.N + i) * 2;
    return [c[base + v.axes[0]], c[base + v.axes[1]]];
  }

  toScreen(view, x, y) { return [view.ox + view.sc * x, view.oy - view.sc * y]; }
  toWorld(view, X, Y) { return [(X - view.ox) / view.sc, (view.oy - Y) / view.sc]; }

  robotColor(f, i) {
    if (this.s.status) {
      const st = this.s.statuses[this.s.status[f * this.N + i]];
      if (st && st.color) return st.color;
    }
    return this.s.palette[this.s.robot_colors[i]];
  }

  styleColor(value, robot) {
    if (value === "robot") return robot >= 0 ? this.s.palette[this.s.robot_colors[robot]] : "#444444";
    return value;
  }

  // -- views --
  buildViews() {
    const box = document.getElementById("views");
    this.s.views.forEach((spec, index) => {
      const wrap = el("div", { class: "view" });
      wrap.appendChild(el("div", { class: "vname" }, spec.name));
      const canvas = el("canvas", { "data-view": String(index) });
      wrap.appendChild(canvas);
      box.appendChild(wrap);
      const view = { index, spec, canvas, ctx: canvas.getContext("2d"), zoom: 1,
                     cx: (spec.lo[0] + spec.hi[0]) / 2, cy: (spec.lo[1] + spec.hi[1]) / 2, sc: 1, ox: 0, oy: 0, w: 0, h: 0 };
      this.views.push(view);
      this.bindPointer(view);
    });
  }

  resize() {
    const dpr = window.devicePixelRatio || 1;
    for (const v of this.views) {
      const r = v.canvas.getBoundingClientRect();
      v.w = Math.max(50, r.width); v.h = Math.max(50, r.height);
      v.canvas.width = Math.round(v.w * dpr); v.canvas.height = Math.round(v.h * dpr);
      v.dpr = dpr;
      this.updateTransform(v);
    }
    this.drawTimeline();
    this.dirty = true;
  }

  updateTransform(v) {
    const pw = v.w - MARGIN.left - MARGIN.right, ph = v.h - MARGIN.top - MARGIN.bottom;
    const spanX = Math.max(1e-9, v.spec.hi[0] - v.spec.lo[0]), spanY = Math.max(1e-9, v.spec.hi[1] - v.spec.lo[1]);
    const fit = 0.96 * Math.min(pw / spanX, ph / spanY);
    v.sc = fit * v.zoom;
    v.ox = MARGIN.left + pw / 2 - v.sc * v.cx;
    v.oy = MARGIN.top + ph / 2 + v.sc * v.cy;
    v.canvas.dataset.transform = [v.sc, v.ox, v.oy].join(" ");
  }

  resetView(v) {
    v.zoom = 1; v.cx = (v.spec.lo[0] + v.spec.hi[0]) / 2; v.cy = (v.spec.lo[1] + v.spec.hi[1]) / 2;
    this.updateTransform(v); this.dirty = true;
  }

  bindPointer(v) {
    const c = v.canvas;
    let drag = null;
    c.addEventListener("wheel", (ev) => {
      ev.preventDefault();
      const r = c.getBoundingClientRect();
      const X = ev.clientX - r.left, Y = ev.clientY - r.top;
      const [wx, wy] = this.toWorld(v, X, Y);
      v.zoom = Math.min(1e4, Math.max(0.1, v.zoom * Math.exp(-ev.deltaY * 0.0015)));
      this.updateTransform(v);
      const [nx, ny] = this.toWorld(v, X, Y);
      v.cx += wx - nx; v.cy += wy - ny;
      this.updateTransform(v); this.dirty = true;
    }, { passive: false });
    c.addEventListener("mousedown", (ev) => { drag = { x: ev.clientX, y: ev.clientY, moved: false }; c.classList.add("dragging"); });
    window.addEventListener("mouseup", (ev) => {
      if (!drag) return;
      c.classList.remove("dragging");
      if (!drag.moved) { this.selected = this.pick(v, ev); this.showInspector(); this.dirty = true; }
      drag = null;
    });
    c.addEventListener("mousemove", (ev) => {
      if (drag) {
        const dx = ev.clientX - drag.x, dy = ev.clientY - drag.y;
        if (Math.abs(dx) + Math.abs(dy) > 2) drag.moved = true;
        if (drag.moved) {
          v.cx -= dx / v.sc; v.cy += dy / v.sc; drag.x = ev.clientX; drag.y = ev.clientY;
          this.updateTransform(v); this.dirty = true;
        }
        return;
      }
      const found = this.pick(v, ev);
      if (found !== this.hovered) { this.hovered = found; this.showInspector(); this.dirty = true; }
    });
    c.addEventListener("mouseleave", () => { if (this.hovered >= 0) { this.hovered = -1; this.showInspector(); this.dirty = true; } });
    c.addEventListener("dblclick", () => this.resetView(v));
  }

  pick(v, ev) {
    if (this.hidden.has("robots")) return -1;
    const r = v.canvas.getBoundingClientRect();
    const X = ev.clientX - r.left, Y = ev.clientY - r.top;
    const reach = Math.max(this.robotPixels(v), 6) + 3;
    let best = -1, bestD = reach * reach;
    for (let i = 0; i < this.N; i++) {
      const [x, y] = this.coord(v, this.frame, i);
      const dx = v.ox + v.sc * x - X, dy = v.oy - v.sc * y - Y;
      const d = dx * dx + dy * dy;
      if (d < bestD) { bestD = d; best = i; }
    }
    return best;
  }

  robotPixels(v) {
    return this.s.radius > 0 ? Math.max(1.5, this.s.radius * v.sc) : this.s.point_px;
  }

  // -- drawing --
  draw() {
    for (const v of this.views) this.drawView(v);
    this.drawCount++;
    document.body.dataset.frame = String(this.frame);
  }

  drawView(v) {
    const ctx = v.ctx;
    ctx.setTransform(v.dpr, 0, 0, v.dpr, 0, 0);
    ctx.drawImage(this.staticLayer(v), 0, 0, v.w, v.h);
    ctx.save();
    ctx.beginPath();
    ctx.rect(MARGIN.left, MARGIN.top, v.w - MARGIN.left - MARGIN.right, v.h - MARGIN.top - MARGIN.bottom);
    ctx.clip();
    const order = ["polygons", "reveal", "ellipses", "segments"];
    for (const kind of order) {
      for (const layer of this.s.layers) {
        if (layer.kind === kind && layer.view === v.index && !this.hidden.has(layer.group)) this.drawLayer(v, layer);
      }
    }
    if (!this.hidden.has("trails") && this.s.trail > 0) this.drawTrails(v);
    if (!this.hidden.has("robots")) this.drawRobots(v);
    for (const layer of this.s.layers) if (layer.kind === "marks" && layer.view === v.index && !this.hidden.has(layer.group)) this.drawLayer(v, layer);
    this.drawHighlight(v);
    ctx.restore();
  }

  // The background, grid, axes and static shapes, redrawn only when the view or the layers change.
  staticLayer(v) {
    const key = [v.w, v.h, v.dpr, v.sc, v.ox, v.oy, [...this.hidden].sort().join(",")].join("|");
    if (v.staticKey === key) return v.staticCanvas;
    if (!v.staticCanvas) v.staticCanvas = document.createElement("canvas");
    const c = v.staticCanvas;
    c.width = v.canvas.width; c.height = v.canvas.height;
    const main = v.ctx;
    v.ctx = c.getContext("2d");
    const ctx = v.ctx;
    ctx.setTransform(v.dpr, 0, 0, v.dpr, 0, 0);
    ctx.fillStyle = "#ffffff";
    ctx.fillRect(0, 0, v.w, v.h);
    ctx.save();
    ctx.beginPath();
    ctx.rect(MARGIN.left, MARGIN.top, v.w - MARGIN.left - MARGIN.right, v.h - MARGIN.top - MARGIN.bottom);
    ctx.clip();
    this.drawGrid(v);
    for (const shape of this.s.shapes) if (shape.view === v.index && !this.hidden.has(shape.group)) this.drawShape(v, shape);
    ctx.restore();
    this.drawAxes(v);
    v.ctx = main;
    v.staticKey = key;
    return c;
  }

  visibleRange(v) {
    const [x0, y1] = this.toWorld(v, MARGIN.left, MARGIN.top);
    const [x1, y0] = this.toWorld(v, v.w - MARGIN.right, v.h - MARGIN.bottom);
    return { x0, x1, y0, y1 };
  }

  drawGrid(v) {
    const ctx = v.ctx, r = this.visibleRange(v);
    ctx.strokeStyle = "#eeeeee"; ctx.lineWidth = 1;
    ctx.beginPath();
    const sx = niceStep(r.x1 - r.x0, 8), sy = niceStep(r.y1 - r.y0, 6);
    for (let x = Math.ceil(r.x0 / sx) * sx; x <= r.x1; x += sx) { const X = v.ox + v.sc * x; ctx.moveTo(X, 0); ctx.lineTo(X, v.h); }
    for (let y = Math.ceil(r.y0 / sy) * sy; y <= r.y1; y += sy) { const Y = v.oy - v.sc * y; ctx.moveTo(0, Y); ctx.lineTo(v.w, Y); }
    ctx.stroke();
  }

  drawAxes(v) {
    const ctx = v.ctx, r = this.visibleRange(v);
    const left = MARGIN.left, bottom = v.h - MARGIN.bottom;
    ctx.strokeStyle = "#333"; ctx.fillStyle = "#333"; ctx.lineWidth = 1;
    ctx.beginPath(); ctx.moveTo(left, MARGIN.top); ctx.lineTo(left, bottom); ctx.lineTo(v.w - MARGIN.right, bottom); ctx.stroke();
    ctx.font = "11px system-ui, sans-serif";
    const sx = niceStep(r.x1 - r.x0, 8), sy = niceStep(r.y1 - r.y0, 6);
    ctx.textAlign = "center"; ctx.textBaseline = "top";
    for (let x = Math.ceil(r.x0 / sx) * sx; x <= r.x1; x += sx) {
      const X = v.ox + v.sc * x;
      ctx.beginPath(); ctx.moveTo(X, bottom); ctx.lineTo(X, bottom + 4); ctx.stroke();
      ctx.fillText(formatNumber(Math.abs(x) < sx * 1e-6 ? 0 : x, 6), X, bottom + 5);
    }
    ctx.textAlign = "right"; ctx.textBaseline = "middle";
    for (let y = Math.ceil(r.y0 / sy) * sy; y <= r.y1; y += sy) {
      const Y = v.oy - v.sc * y;
      ctx.beginPath(); ctx.moveTo(left - 4, Y); ctx.lineTo(left, Y); ctx.stroke();
      ctx.fillText(formatNumber(Math.abs(y) < sy * 1e-6 ? 0 : y, 6), left - 6, Y);
    }
    ctx.font = "12px system-ui, sans-serif";
    ctx.textAlign = "center"; ctx.textBaseline = "bottom";
    ctx.fillText(v.spec.labels[0], left + (v.w - left - MARGIN.right) / 2, v.h - 3);
    ctx.save(); ctx.translate(13, MARGIN.top + (bottom - MARGIN.top) / 2); ctx.rotate(-Math.PI / 2);
    ctx.textBaseline = "middle"; ctx.fillText(v.spec.labels[1], 0, 0); ctx.restore();
  }

  applyStroke(ctx, style, robot) {
    ctx.strokeStyle = this.styleColor(style.stroke || "#000000", robot);
    ctx.lineWidth = style.width || 1;
    ctx.setLineDash(style.dash || []);
  }

  drawShape(v, shape) {
    const ctx = v.ctx, st = shape.style, pts = shape.points;
    ctx.globalAlpha = st.alpha === undefined ? 1 : st.alpha;
    if (shape.kind === "polygon" || shape.kind === "polyline") {
      ctx.beginPath();
      pts.forEach((p, k) => { const X = v.ox + v.sc * p[0], Y = v.oy - v.sc * p[1]; if (k === 0) ctx.moveTo(X, Y); else ctx.lineTo(X, Y); });
      if (shape.kind === "polygon") ctx.closePath();
      if (st.fill && shape.kind === "polygon") { ctx.fillStyle = this.styleColor(st.fill, shape.robot); ctx.fill(); }
      ctx.globalAlpha = st.stroke_alpha === undefined ? 1 : st.stroke_alpha;
      if (st.stroke) { this.applyStroke(ctx, st, shape.robot); ctx.stroke(); ctx.setLineDash([]); }
    } else if (shape.kind === "points") {
      for (const p of pts) this.marker(ctx, st, v.ox + v.sc * p[0], v.oy - v.sc * p[1], shape.robot);
    } else if (shape.kind === "text") {
      ctx.fillStyle = st.fill || "#000"; ctx.font = `${st.size || 12}px system-ui, sans-serif`;
      ctx.textAlign = "center"; ctx.textBaseline = "middle";
      ctx.fillText(shape.text, v.ox + v.sc * pts[0][0], v.oy - v.sc * pts[0][1]);
    }
    ctx.globalAlpha = 1;
  }

  marker(ctx, st, X, Y, robot) {
    const size = st.size || 6, half = size / 2;
    const fill = st.fill ? this.styleColor(st.fill, robot) : null;
    const stroke = st.stroke ? this.styleColor(st.stroke, robot) : null;
    ctx.lineWidth = st.width || 1; ctx.setLineDash([]);
    ctx.beginPath();
    switch (st.marker) {
      case "x":
        ctx.moveTo(X - half, Y - half); ctx.lineTo(X + half, Y + half); ctx.moveTo(X + half, Y - half); ctx.lineTo(X - half, Y + half);
        ctx.strokeStyle = stroke || fill || "#000"; ctx.stroke(); return;
      case "plus":
        ctx.moveTo(X - half, Y); ctx.lineTo(X + half, Y); ctx.moveTo(X, Y - half); ctx.lineTo(X, Y + half);
        ctx.strokeStyle = stroke || fill || "#000"; ctx.stroke(); return;
      case "square": ctx.rect(X - half, Y - half, size, size); break;
      case "star":
        for (let k = 0; k < 10; k++) {
          const a = -Math.PI / 2 + (k * Math.PI) / 5, rr = k % 2 ? half * 0.45 : half;
          if (k === 0) ctx.moveTo(X + rr * Math.cos(a), Y + rr * Math.sin(a)); else ctx.lineTo(X + rr * Math.cos(a), Y + rr * Math.sin(a));
        }
        ctx.closePath(); break;
      case "triangle": ctx.moveTo(X, Y - half); ctx.lineTo(X + half, Y + half); ctx.lineTo(X - half, Y + half); ctx.closePath(); break;
      case "ring": ctx.arc(X, Y, half, 0, 2 * Math.PI); ctx.strokeStyle = stroke || fill || "#000"; ctx.stroke(); return;
      default: ctx.arc(X, Y, half, 0, 2 * Math.PI);
    }
    if (fill) { ctx.fillStyle = fill; ctx.fill(); }
    if (stroke) { ctx.strokeStyle = stroke; ctx.stroke(); }
  }

  drawLayer(v, layer) {
    const ctx = v.ctx, a = layer.arrays, st = layer.style, f = this.frame;
    ctx.globalAlpha = 1;
    if (layer.kind === "reveal") {
      const xy = a.xy, fr = a.frame;
      for (let p = 0; p < fr.length; p++) if (fr[p] >= 0 && fr[p] <= f) this.marker(ctx, st, v.ox + v.sc * xy[2 * p], v.oy - v.sc * xy[2 * p + 1], -1);
      return;
    }
    const start = a.offsets[f], end = a.offsets[f + 1];
    if (layer.kind === "polygons") {
      for (let p = start; p < end; p++) {
        const robot = a.robot[p];
        ctx.beginPath();
        for (let k = a.polygon[p]; k < a.polygon[p + 1]; k++) {
          const X = v.ox + v.sc * a.vertices[2 * k], Y = v.oy - v.sc * a.vertices[2 * k + 1];
          if (k === a.polygon[p]) ctx.moveTo(X, Y); else ctx.lineTo(X, Y);
        }
        ctx.closePath();
        if (st.fill) { ctx.globalAlpha = st.alpha === undefined ? 1 : st.alpha; ctx.fillStyle = this.styleColor(st.fill, robot); ctx.fill(); }
        ctx.globalAlpha = 0.8;
        if (st.stroke) { this.applyStroke(ctx, st, robot); ctx.stroke(); }
      }
      ctx.globalAlpha = 1;
    } else if (layer.kind === "ellipses") {
      for (let e = start; e < end; e++) {
        const robot = a.robot[e];
        ctx.beginPath();
        ctx.ellipse(v.ox + v.sc * a.xy[2 * e], v.oy - v.sc * a.xy[2 * e + 1], Math.max(0.5, v.sc * a.shape[3 * e] / 2),
                    Math.max(0.5, v.sc * a.shape[3 * e + 1] / 2), -a.shape[3 * e + 2], 0, 2 * Math.PI);
        this.applyStroke(ctx, st, robot); ctx.stroke();
      }
      ctx.setLineDash([]);
    } else if (layer.kind === "segments") {
      for (let k = start; k < end; k++) {
        const robot = a.robot ? a.robot[k] : -1;
        const X0 = v.ox + v.sc * a.xy[4 * k], Y0 = v.oy - v.sc * a.xy[4 * k + 1];
        const X1 = v.ox + v.sc * a.xy[4 * k + 2], Y1 = v.oy - v.sc * a.xy[4 * k + 3];
        ctx.globalAlpha = st.alpha === undefined ? 1 : st.alpha;
        this.applyStroke(ctx, st, robot);
        ctx.beginPath(); ctx.moveTo(X0, Y0); ctx.lineTo(X1, Y1); ctx.stroke();
        if (st.arrow) this.arrowHead(ctx, X0, Y0, X1, Y1, st, robot);
      }
      ctx.setLineDash([]); ctx.globalAlpha = 1;
    } else if (layer.kind === "marks") {
      for (let k = start; k < end; k++) this.marker(ctx, st, v.ox + v.sc * a.xy[2 * k], v.oy - v.sc * a.xy[2 * k + 1], a.robot ? a.robot[k] : -1);
    }
  }

  arrowHead(ctx, X0, Y0, X1, Y1, st, robot) {
    const ang = Math.atan2(Y1 - Y0, X1 - X0), size = 8;
    ctx.setLineDash([]);
    ctx.beginPath();
    ctx.moveTo(X1, Y1);
    ctx.lineTo(X1 - size * Math.cos(ang - 0.4), Y1 - size * Math.sin(ang - 0.4));
    ctx.lineTo(X1 - size * Math.cos(ang + 0.4), Y1 - size * Math.sin(ang + 0.4));
    ctx.closePath();
    ctx.fillStyle = this.styleColor(st.stroke || "#000", robot); ctx.fill();
  }

  drawTrails(v) {
    const ctx = v.ctx, f = this.frame, from = Math.max(0, f - this.s.trail);
    if (f === from) return;
    ctx.lineWidth = 1; ctx.globalAlpha = 0.6; ctx.setLineDash([]);
    for (let i = 0; i < this.N; i++) {
      ctx.beginPath();
      for (let k = from; k <= f; k++) {
        const [x, y] = this.coord(v, k, i);
        const X = v.ox + v.sc * x, Y = v.oy - v.sc * y;
        if (k === from) ctx.moveTo(X, Y); else ctx.lineTo(X, Y);
      }
      ctx.strokeStyle = this.s.palette[this.s.robot_colors[i]];
      ctx.stroke();
    }
    ctx.globalAlpha = 1;
  }

  drawRobots(v) {
    const ctx = v.ctx, f = this.frame, N = this.N, rPx = this.robotPixels(v);
    const markers = this.s.robot_markers, special = [];
    const src = v.spec.source === "positions" ? this.s.positions : this.s.coordinates[v.spec.source];
    const stride = v.spec.source === "positions" ? this.D : 2, ax = v.spec.axes[0], ay = v.spec.axes[1];
    const buckets = new Map();  // fill colour and alpha → flat screen coordinates
    for (let i = 0; i < N; i++) {
      if (markers && markers[i] && markers[i] !== "circle") { special.push(i); continue; }
      const st = this.s.status ? this.s.statuses[this.s.status[f * N + i]] : null;
      const key = this.robotColor(f, i) + "|" + (st && st.alpha !== undefined ? st.alpha : 1);
      let list = buckets.get(key);
      if (!list) { list = []; buckets.set(key, list); }
      const base = (f * N + i) * stride;
      list.push(v.ox + v.sc * src[base + ax], v.oy - v.sc * src[base + ay]);
    }
    const useRects = rPx < 2.2, side = 2 * rPx;
    for (const [key, list] of buckets) {
      const bar = key.indexOf("|");
      ctx.globalAlpha = Number(key.slice(bar + 1)); ctx.fillStyle = key.slice(0, bar);
      ctx.beginPath();
      for (let k = 0; k < list.length; k += 2) {
        const X = list[k], Y = list[k + 1];
        if (useRects) ctx.rect(X - rPx, Y - rPx, side, side);
        else { ctx.moveTo(X + rPx, Y); ctx.arc(X, Y, rPx, 0, 2 * Math.PI); }
      }
      ctx.fill();
    }
    ctx.globalAlpha = 1;
    const heading = this.s.fields.find((fd) => fd.name === "heading" && fd.per_robot);
    for (const i of special) {
      const [x, y] = this.coord(v, f, i);
      const X = v.ox + v.sc * x, Y = v.oy - v.sc * y, size = Math.max(12, 2.6 * rPx);
      let h = v.spec.source === "positions" ? Math.PI / 2 : 0;
      if (heading && v.spec.source === "positions" && Number.isFinite(heading.values[f * N + i])) h = heading.values[f * N + i];
      ctx.beginPath();
      ctx.moveTo(X + size * 0.6 * Math.cos(-h), Y + size * 0.6 * Math.sin(-h));
      ctx.lineTo(X + size * 0.45 * Math.cos(-h + 2.4), Y + size * 0.45 * Math.sin(-h + 2.4));
      ctx.lineTo(X + size * 0.45 * Math.cos(-h - 2.4), Y + size * 0.45 * Math.sin(-h - 2.4));
      ctx.closePath(); ctx.fillStyle = this.robotColor(f, i); ctx.fill();
    }
    if (this.s.status) {  // statuses drawn with a cross (failed robots)
      ctx.lineWidth = 2; ctx.strokeStyle = "#000";
      for (let i = 0; i < N; i++) {
        const st = this.s.statuses[this.s.status[f * N + i]];
        if (!st || !st.cross) continue;
        const [x, y] = this.coord(v, f, i);
        const X = v.ox + v.sc * x, Y = v.oy - v.sc * y, h = Math.max(5, rPx * 1.2);
        ctx.beginPath(); ctx.moveTo(X - h, Y - h); ctx.lineTo(X + h, Y + h); ctx.moveTo(X + h, Y - h); ctx.lineTo(X - h, Y + h); ctx.stroke();
      }
    }
  }

  drawHighlight(v) {
    const ctx = v.ctx;
    for (const [i, color] of [[this.selected, "#000"], [this.hovered, "#555"]]) {
      if (i < 0) continue;
      const [x, y] = this.coord(v, this.frame, i);
      ctx.beginPath(); ctx.arc(v.ox + v.sc * x, v.oy - v.sc * y, this.robotPixels(v) + 5, 0, 2 * Math.PI);
      ctx.lineWidth = 2; ctx.strokeStyle = color; ctx.setLineDash([]); ctx.stroke();
    }
  }

  // -- panels --
  buildPanels() {
    document.getElementById("subtitle").textContent = [this.s.subtitle, ...this.s.notes].filter(Boolean).join(" · ");
    const legend = document.getElementById("legend");
    for (const row of this.s.legend) {
      const line = el("div", { class: "row" });
      const swatch = el("canvas", { width: "18", height: "14" });
      this.drawSwatch(swatch.getContext("2d"), row);
      line.appendChild(swatch); line.appendChild(el("span", {}, row.label));
      legend.appendChild(line);
    }
    const layers = document.getElementById("layers");
    const groups = ["robots", ...(this.s.trail > 0 ? ["trails"] : []), ...this.s.groups];
    for (const g of groups) {
      const id = "layer-" + g.replace(/[^a-z0-9]+/gi, "-");
      const line = el("label", { class: "row" });
      const box = el("input", { type: "checkbox", id, "data-group": g });
      box.checked = !this.hidden.has(g);
      box.addEventListener("change", () => { if (box.checked) this.hidden.delete(g); else this.hidden.add(g); this.dirty = true; });
      line.appendChild(box); line.appendChild(el("span", {}, g));
      layers.appendChild(line);
    }
  }

  drawSwatch(ctx, row) {
    ctx.clearRect(0, 0, 18, 14);
    ctx.lineWidth = 1.5; ctx.strokeStyle = row.stroke; ctx.fillStyle = row.color;
    ctx.setLineDash(row.dash ? [3, 2] : []);
    ctx.beginPath();
    if (row.marker === "line") { ctx.moveTo(1, 7); ctx.lineTo(17, 7); ctx.stroke(); }
    else if (row.marker === "arrow") { ctx.moveTo(1, 7); ctx.lineTo(14, 7); ctx.stroke(); ctx.beginPath(); ctx.moveTo(17, 7); ctx.lineTo(12, 4); ctx.lineTo(12, 10); ctx.fill(); }
    else if (row.marker === "ring") { ctx.arc(9, 7, 5, 0, 2 * Math.PI); ctx.stroke(); }
    else if (row.marker === "ellipse") { ctx.ellipse(9, 7, 8, 5, 0, 0, 2 * Math.PI); ctx.stroke(); }
    else if (row.marker === "circle") { ctx.arc(9, 7, 5, 0, 2 * Math.PI); ctx.fill(); }
    else if (row.marker === "hollow") { ctx.arc(9, 7, 5, 0, 2 * Math.PI); ctx.stroke(); }
    else if (row.marker === "dot") { ctx.arc(9, 7, 2, 0, 2 * Math.PI); ctx.fill(); }
    else this.marker(ctx, { marker: row.marker, size: 11, fill: row.marker === "x" || row.marker === "plus" ? null : row.color,
                            stroke: row.marker === "x" || row.marker === "plus" ? row.color : null, width: 2 }, 9, 7, -1);
    ctx.setLineDash([]);
  }

  showInspector() {
    const box = document.getElementById("inspect");
    const i = this.hovered >= 0 ? this.hovered : this.selected;
    box.innerHTML = "";
    if (i < 0) { box.appendChild(el("p", { class: "hint" }, "Hover or click a robot.")); return; }
    const f = this.frame, s = this.s, table = el("table");
    const add = (k, v) => { const tr = el("tr"); tr.appendChild(el("td", {}, k)); tr.appendChild(el("td", {}, v)); table.appendChild(tr); };
    add("robot", s.robot_names[i] + (i === this.selected ? " (pinned)" : ""));
    add("time", `${formatNumber(s.times[f])} ${s.time_unit} (step ${s.steps[f]})`);
    const names = ["x", "y", "z"];
    const base = (f * this.N + i) * this.D;
    const pos = [];
    for (let d = 0; d < this.D; d++) pos.push(`${names[d]} = ${formatNumber(s.positions[base + d])}`);
    add("position", `${pos.join(", ")} ${s.length_unit}`);
    if (s.status) add("status", s.statuses[s.status[f * this.N + i]].name);
    for (const fd of s.fields) {
      const value = fd.per_robot ? fd.values[f * this.N + i] : fd.values[f];
      const shown = fd.labels && Number.isFinite(value) && fd.labels[Math.round(value)] !== undefined ? fd.labels[Math.round(value)]
        : formatNumber(value, fd.digits) + (fd.unit ? " " + fd.unit : "");
      add(fd.name, shown);
    }
    const ev = s.events;
    let last = eventsUpTo(ev, f) - 1;
    while (last >= 0 && ev.robot[last] !== i) last--;
    if (last >= 0) {
      const detail = [`step ${ev.step[last]}`, ev.text[last] >= 0 ? ev.texts[ev.text[last]] : null].filter((x) => x).join(", ");
      add("last event", `${ev.kinds[ev.kind[last]]} at t = ${formatNumber(s.times[ev.frame[last]])} ${s.time_unit} (${detail})`);
    }
    box.appendChild(table);
  }

  showEvents() {
    const box = document.getElementById("events");
    const ev = this.s.events;
    if (!ev.length) { box.innerHTML = '<p class="hint">No events recorded.</p>'; return; }
    const upto = eventsUpTo(ev, this.frame);
    const from = Math.max(0, upto - 6), to = Math.min(ev.length, upto + 2);
    const key = `${from}-${to}|${upto}|${this.frame}`;
    if (key === this.eventsKey) return;
    this.eventsKey = key;
    box.innerHTML = "";
    box.appendChild(el("p", { class: "hint" }, ev.kinds.map((k, j) => `${k}: ${ev.counts[j]}`).join(" · ")));
    for (let i = from; i < to; i++) {
      const frame = ev.frame[i], kind = ev.kinds[ev.kind[i]], robot = ev.robot[i];
      const line = el("div", { class: "event" + (frame === this.frame ? " current" : "") },
        `t = ${formatNumber(this.s.times[frame])} ${this.s.time_unit}: ${eventText(ev, i, this.s.robot_names)}`);
      line.style.borderLeft = `4px solid ${eventColor(kind, this.eventKinds)}`;
      if (frame > this.frame) line.style.opacity = "0.5";
      line.addEventListener("click", () => { this.pause(); this.setFrame(frame); if (robot >= 0) { this.selected = robot; this.showInspector(); } });
      box.appendChild(line);
    }
  }

  drawTimeline() {
    const c = document.getElementById("timeline");
    const r = c.getBoundingClientRect(), dpr = window.devicePixelRatio || 1;
    c.width = Math.max(10, Math.round(r.width * dpr)); c.height = Math.round(10 * dpr);
    const ctx = c.getContext("2d");
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, r.width, 10);
    const ev = this.s.events, stride = Math.max(1, Math.floor(ev.length / 3000));
    for (let k = 0; k < ev.length; k += stride) {
      ctx.fillStyle = eventColor(ev.kinds[ev.kind[k]], this.eventKinds);
      ctx.fillRect(((r.width - 2) * ev.frame[k]) / Math.max(1, this.F - 1), 0, 2, 10);
    }
  }

  // -- controls --
  buildControls() {
    const slider = document.getElementById("slider");
    slider.max = String(this.F - 1);
    slider.addEventListener("input", () => { this.pause(); this.setFrame(Number(slider.value)); });
    document.getElementById("play").addEventListener("click", () => this.toggle());
    document.getElementById("back").addEventListener("click", () => { this.pause(); this.setFrame(this.frame - 1); });
    document.getElementById("forward").addEventListener("click", () => { this.pause(); this.setFrame(this.frame + 1); });
    document.getElementById("first").addEventListener("click", () => { this.pause(); this.setFrame(0); });
    document.getElementById("last").addEventListener("click", () => { this.pause(); this.setFrame(this.F - 1); });
    const select = document.getElementById("speed");
    const duration = this.s.times[this.F - 1] - this.s.times[0];
    const wanted = duration > 0 ? duration / 15 : 1;
    let best = 0;
    SPEEDS.forEach((sp, k) => { select.appendChild(el("option", { value: String(sp) }, `${sp}×`)); if (Math.abs(Math.log(sp / wanted)) < Math.abs(Math.log(SPEEDS[best] / wanted))) best = k; });
    select.selectedIndex = best;
    this.speed = SPEEDS[best];
    select.addEventListener("change", () => { this.speed = Number(select.value); });
  }

  changeSpeed(delta) {
    const select = document.getElementById("speed");
    select.selectedIndex = Math.min(SPEEDS.length - 1, Math.max(0, select.selectedIndex + delta));
    this.speed = Number(select.value);
  }

  bindKeys() {
    window.addEventListener("keydown", (ev) => {
      if (ev.target && ev.target.tagName === "SELECT") return;
      const big = ev.shiftKey ? 10 : 1;
      const keys = {
        " ": () => this.toggle(), ArrowRight: () => { this.pause(); this.setFrame(this.frame + big); },
        ArrowLeft: () => { this.pause(); this.setFrame(this.frame - big); }, Home: () => { this.pause(); this.setFrame(0); },
        End: () => { this.pause(); this.setFrame(this.F - 1); }, "+": () => this.changeSpeed(1), "=": () => this.changeSpeed(1),
        "-": () => this.changeSpeed(-1), "0": () => this.views.forEach((v) => this.resetView(v)),
        Escape: () => { this.selected = -1; this.showInspector(); this.dirty = true; },
      };
      const action = keys[ev.key];
      if (action) { ev.preventDefault(); action(); }
    });
  }

  toggle() { if (this.playing) this.pause(); else this.play(); }

  play() {
    if (this.frame >= this.F - 1) this.setFrame(0);
    this.playing = true; this.simTime = this.s.times[this.frame]; this.lastTick = null;
    document.getElementById("play").textContent = "| |";
  }

  pause() {
    if (!this.playing) return;
    this.playing = false;
    document.getElementById("play").textContent = "▶";
    this.writeHash();
  }

  setFrame(k, keepHash) {
    k = Math.max(0, Math.min(this.F - 1, Math.round(k)));
    if (k !== this.frame) { this.frame = k; this.dirty = true; }
    if (!this.playing && !keepHash) this.writeHash();
    this.updateReadout();
  }

  updateReadout() {
    const s = this.s;
    document.getElementById("slider").value = String(this.frame);
    document.getElementById("clock").textContent =
      `t = ${formatNumber(s.times[this.frame], 2)} ${s.time_unit} · frame ${this.frame + 1}/${this.F} · step ${s.steps[this.frame]}`;
    document.body.dataset.frame = String(this.frame);
  }

  readHash() {
    const m = /frame=(\d+)/.exec(window.location.hash);
    if (m) { this.pause(); this.setFrame(Number(m[1]), true); }
  }

  writeHash() {
    const hash = "#frame=" + this.frame;
    if (window.location.hash !== hash) history.replaceState(null, "", hash);
  }

  tick(now) {
    if (this.playing) {
      if (this.stepPerTick) {
        this.setFrame(this.frame + 1 >= this.F ? 0 : this.frame + 1);
      } else if (this.lastTick !== null) {
        this.simTime += ((now - this.lastTick) / 1000) * this.speed;
        let k = this.frame;
        while (k + 1 < this.F && this.s.times[k + 1] <= this.simTime) k++;
        if (k >= this.F - 1) { this.setFrame(this.F - 1); this.pause(); } else this.setFrame(k);
      }
      this.lastTick = now;
    }
    if (this.dirty) {
      this.dirty = false;
      this.draw();
      this.showEvents();
      if (this.hovered >= 0 || this.selected >= 0) this.showInspector();
    }
    requestAnimationFrame((t) => this.tick(t));
  }

  // Frames drawn per second while advancing one frame per animation frame (benchmarks).
  measureFps(seconds) {
    return new Promise((resolve) => {
      const wasPlaying = this.playing;
      this.stepPerTick = true; this.playing = true;
      const start = performance.now(), count0 = this.drawCount;
      setTimeout(() => {
        const frames = this.drawCount - count0, elapsed = (performance.now() - start) / 1000;
        this.stepPerTick = false; this.playing = wasPlaying;
        resolve(frames / elapsed);
      }, seconds * 1000);
    });
  }
}

async function main() {
  const doc = JSON.parse(document.getElementById("replay-data").textContent);
  const scene = await decodeScene(doc);
  document.body.dataset.nFrames = String(scene.n_frames);
  document.body.dataset.nRobots = String(scene.n_robots);
  const replay = new Replay(scene);
  window.replay = replay;
  replay.updateReadout();
  replay.draw();
  replay.dirty = false;
  replay.showEvents();
  document.body.dataset.ready = "1";
}

main().catch((err) => {
  const box = document.getElementById("error");
  box.hidden = false;
  box.textContent = "This replay could not be shown: " + err;
  console.error(err);
});
