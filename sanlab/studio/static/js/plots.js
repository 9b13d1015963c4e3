// Plots on canvas: a run's sorted scores (the paper's long tail, §5.2), a tuning run's score
// per trial, the SAN raster (which sensors and nodes are on when), a search's MAP-Elites
// archive (a heat map of its cells, and its coverage and QD-score as it grew), and a design's
// bodies (a scatter of two free numbers, coloured by score).

import { COLORS, fitCanvas } from "./draw.js";

function axes(ctx, w, h, pad, lo, hi, xlabel, ylabel, n) {
  ctx.fillStyle = "#fff";
  ctx.fillRect(0, 0, w, h);
  ctx.strokeStyle = COLORS.gridAxis;
  ctx.lineWidth = 1;
  ctx.beginPath();
  ctx.moveTo(pad.l, pad.t); ctx.lineTo(pad.l, h - pad.b); ctx.lineTo(w - pad.r, h - pad.b);
  ctx.stroke();
  ctx.fillStyle = COLORS.muted;
  ctx.font = "10px system-ui, sans-serif";
  ctx.fillText(hi.toPrecision(3), 2, pad.t + 8);
  ctx.fillText(lo.toPrecision(3), 2, h - pad.b);
  ctx.fillText(xlabel, w - pad.r - ctx.measureText(xlabel).width, h - 4);
  ctx.fillText(`1`, pad.l, h - 4);
  if (n) ctx.fillText(String(n), w - pad.r - ctx.measureText(xlabel).width - 40, h - 4);
  ctx.save(); ctx.translate(10, h / 2 + 20); ctx.rotate(-Math.PI / 2); ctx.fillText(ylabel, 0, 0); ctx.restore();
}

// Scores in idx order (None: not a number) -> sorted, best first, as a curve.
export function drawScores(canvas, scores, highlight = 10) {
  const { ctx, w, h } = fitCanvas(canvas);
  const s = scores.filter((x) => x !== null).sort((a, b) => b - a);
  const pad = { l: 44, r: 8, t: 10, b: 18 };
  if (!s.length) {
    ctx.clearRect(0, 0, w, h);
    ctx.fillStyle = COLORS.muted; ctx.fillText("no scores yet", 10, 20);
    return;
  }
  const hi = Math.max(s[0], 1e-9), lo = Math.min(0, s[s.length - 1]);
  axes(ctx, w, h, pad, lo, hi, "rank", "score", s.length);
  const X = (k) => pad.l + ((w - pad.l - pad.r) * k) / Math.max(1, s.length - 1);
  const Y = (v) => h - pad.b - ((h - pad.t - pad.b) * (v - lo)) / (hi - lo || 1);
  ctx.fillStyle = "rgba(245,128,20,0.12)";
  ctx.fillRect(pad.l, pad.t, X(Math.min(highlight, s.length) - 1) - pad.l + 1, h - pad.t - pad.b);
  ctx.beginPath();
  s.forEach((v, k) => (k ? ctx.lineTo(X(k), Y(v)) : ctx.moveTo(X(k), Y(v))));
  ctx.strokeStyle = COLORS.hidden; ctx.lineWidth = 1.5; ctx.stroke();
  const q = (p) => s[Math.min(s.length - 1, Math.floor((p / 100) * s.length))];
  ctx.fillStyle = COLORS.text;
  ctx.font = "11px system-ui, sans-serif";
  ctx.fillText(`${s.length} scored; best ${s[0].toPrecision(3)}, top 5% above ${q(5).toPrecision(3)}, median ${q(50).toPrecision(3)}`, pad.l + 6, pad.t + 12);
}

// A tuning trace [[trial, score, accepted], ...]: every trial (accepted ones darker), and the
// best score so far.
export function drawTrace(canvas, trace) {
  const { ctx, w, h } = fitCanvas(canvas);
  const pts = trace.filter((p) => p[1] !== null);
  const pad = { l: 44, r: 8, t: 10, b: 18 };
  if (!pts.length) {
    ctx.clearRect(0, 0, w, h);
    return;
  }
  let hi = -Infinity, lo = Infinity;
  for (const p of pts) { hi = Math.max(hi, p[1]); lo = Math.min(lo, p[1]); }
  if (hi === lo) { hi += 1e-3; lo -= 1e-3; }
  axes(ctx, w, h, pad, lo, hi, "trial", "score", trace.length);
  const n = trace.length;
  const X = (k) => pad.l + ((w - pad.l - pad.r) * k) / Math.max(1, n - 1);
  const Y = (v) => h - pad.b - ((h - pad.t - pad.b) * (v - lo)) / (hi - lo);
  for (const [t, v, acc] of pts) {
    ctx.fillStyle = acc ? COLORS.hidden : "rgba(120,120,120,0.35)";
    ctx.fillRect(X(t) - 1, Y(v) - 1, acc ? 3 : 2, acc ? 3 : 2);
  }
  let best = -Infinity;
  ctx.beginPath();
  pts.forEach(([t, v, acc], k) => {
    if (acc) best = Math.max(best, v);
    if (best > -Infinity) (k ? ctx.lineTo(X(t), Y(best)) : ctx.moveTo(X(t), Y(best)));
  });
  ctx.strokeStyle = COLORS.actuator; ctx.lineWidth = 1.5; ctx.stroke();
}

// The SAN raster: rows = sensors, hidden nodes, actuator nodes; one column per frame.
// bits [F][S], nodes [F][H + A]. Drawn once into an image; `cursor` redraws only the marker.
export class Raster {
  constructor(canvas, creature) {
    this.canvas = canvas;
    this.creature = creature;
    this.rows = [
      ...creature.sensors.map((n) => [n, "s", COLORS.sensor]),
      ...creature.hidden.map((n) => [n, "h", COLORS.hidden]),
      ...creature.actuators.map((n) => [n, "a", COLORS.actuator]),
    ];
    this.label = 34;
  }

  // Full-run raster (playback); k: the current frame.
  drawAll(bits, nodes, k) {
    const { ctx, w, h } = fitCanvas(this.canvas);
    const F = bits.length;
    this.F = F;
    if (!this.image || this.image.width !== w || this.image.height !== h) {
      this.image = document.createElement("canvas");
      this.image.width = w; this.image.height = h;
      this.paint(this.image.getContext("2d"), w, h, bits, nodes, 0, F);
    }
    ctx.clearRect(0, 0, w, h);
    ctx.drawImage(this.image, 0, 0);
    const x = this.label + ((w - this.label) * (k + 0.5)) / F;
    ctx.strokeStyle = COLORS.cursor; ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.moveTo(x, 0); ctx.lineTo(x, h); ctx.stroke();
  }

  // Frame index under a canvas x (CSS px), for seeking by clicking the raster.
  frameAt(x) {
    const w = this.canvas.clientWidth;
    return Math.max(0, Math.min(this.F - 1, Math.floor(((x - this.label) / (w - this.label)) * this.F)));
  }

  // Rolling raster of the last frames (live mode): bits/nodes arrays of recent frames.
  drawRecent(bits, nodes) {
    const { ctx, w, h } = fitCanvas(this.canvas);
    ctx.clearRect(0, 0, w, h);
    this.paint(ctx, w, h, bits, nodes, 0, bits.length);
  }

  paint(ctx, w, h, bits, nodes, k0, k1) {
    const R = this.rows.length;
    const rh = h / R;
    const n = Math.max(1, k1 - k0);
    const cw = (w - this.label) / n;
    ctx.fillStyle = "#fff";
    ctx.fillRect(0, 0, w, h);
    ctx.font = `${Math.min(11, rh * 0.9)}px system-ui, sans-serif`;
    const S = this.creature.sensors.length;
    this.rows.forEach(([name, kind, color], r) => {
      const y = r * rh;
      ctx.fillStyle = COLORS.nodeOff;
      ctx.fillRect(this.label, y + 0.5, w - this.label, Math.max(1, rh - 1));
      ctx.fillStyle = COLORS.muted;
      ctx.fillText(name, 2, y + rh * 0.8);
      ctx.fillStyle = color;
      for (let k = k0; k < k1; k++) {
        const on = kind === "s" ? bits[k][r] : nodes[k][r - S];
        if (on > 0) ctx.fillRect(this.label + (k - k0) * cw, y + 0.5, Math.max(1, cw + 0.5), Math.max(1, rh - 1));
      }
    });
  }
}

// A colour for t in [0, 1]: viridis (dark blue to yellow), five stops interpolated.
const VIRIDIS = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
export function viridis(t) {
  const x = Math.max(0, Math.min(1, t)) * (VIRIDIS.length - 1);
  const i = Math.min(VIRIDIS.length - 2, Math.floor(x)), f = x - i;
  const c = VIRIDIS[i].map((a, k) => Math.round(a + (VIRIDIS[i + 1][k] - a) * f));
  return `rgb(${c[0]},${c[1]},${c[2]})`;
}

const label = (name, unit) => (unit ? `${name} (${unit})` : name);

// A MAP-Elites archive as a heat map: cell [i, j] of descriptor names[0] (x, to the right) by
// names[1] (y, up), coloured by its best score (viridis, from the lowest filled cell's score to
// the highest); empty cells are left blank. archive: the studio's `archive` reply.
export class HeatMap {
  constructor(canvas, archive) {
    this.canvas = canvas;
    this.archive = archive;
    this.pad = { l: 50, r: 78, t: 10, b: 34 };
  }

  // The plot's rectangle and a cell's size, in CSS pixels.
  layout() {
    const w = this.canvas.clientWidth, h = this.canvas.clientHeight, p = this.pad;
    const [bx, by] = this.archive.bins;
    const pw = Math.max(1, w - p.l - p.r), ph = Math.max(1, h - p.t - p.b);
    return { w, h, x0: p.l, y0: p.t, pw, ph, cw: pw / bx, ch: ph / by };
  }

  // The centre of cell [i, j] (CSS px from the canvas's top left).
  cellPx(i, j) {
    const L = this.layout();
    return [L.x0 + (i + 0.5) * L.cw, L.y0 + L.ph - (j + 0.5) * L.ch];
  }

  // The cell [i, j] under (u, v) CSS px, or null outside the grid.
  cellAt(u, v) {
    const L = this.layout();
    const i = Math.floor((u - L.x0) / L.cw), j = Math.floor((L.y0 + L.ph - v) / L.ch);
    const [bx, by] = this.archive.bins;
    return i >= 0 && j >= 0 && i < bx && j < by ? [i, j] : null;
  }

  draw() {
    const { ctx, w, h } = fitCanvas(this.canvas);
    const a = this.archive, L = this.layout();
    const [bx, by] = a.bins;
    this.drawnW = w;
    ctx.fillStyle = "#fff";
    ctx.fillRect(0, 0, w, h);
    let lo = Infinity, hi = -Infinity;
    for (const col of a.best) for (const v of col) if (v !== null) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    this.scoreRange = hi >= lo ? [lo, hi] : null;
    if (bx <= 64 && by <= 64) { // the cells' outlines, faint
      ctx.strokeStyle = COLORS.nodeOff; ctx.lineWidth = 1;
      ctx.beginPath();
      for (let i = 0; i <= bx; i++) { const x = L.x0 + i * L.cw; ctx.moveTo(x, L.y0); ctx.lineTo(x, L.y0 + L.ph); }
      for (let j = 0; j <= by; j++) { const y = L.y0 + j * L.ch; ctx.moveTo(L.x0, y); ctx.lineTo(L.x0 + L.pw, y); }
      ctx.stroke();
    }
    a.best.forEach((col, i) => col.forEach((v, j) => {
      if (v === null) return;
      ctx.fillStyle = viridis(hi > lo ? (v - lo) / (hi - lo) : 1);
      ctx.fillRect(L.x0 + i * L.cw, L.y0 + L.ph - (j + 1) * L.ch, Math.ceil(L.cw), Math.ceil(L.ch));
    }));
    ctx.strokeStyle = COLORS.gridAxis;
    ctx.strokeRect(L.x0 - 0.5, L.y0 - 0.5, L.pw + 1, L.ph + 1);
    // axes: each descriptor's name, unit and range
    const [[xlo, xhi], [ylo, yhi]] = a.ranges;
    ctx.fillStyle = COLORS.muted;
    ctx.font = "10px system-ui, sans-serif";
    const xl = label(a.names[0], a.units[0]), yl = label(a.names[1], a.units[1]);
    ctx.fillText(fmtNum(xlo), L.x0, L.y0 + L.ph + 12);
    const xh = fmtNum(xhi);
    ctx.fillText(xh, L.x0 + L.pw - ctx.measureText(xh).width, L.y0 + L.ph + 12);
    const right = (text, y) => ctx.fillText(text, L.x0 - 3 - ctx.measureText(text).width, y);
    right(fmtNum(yhi), L.y0 + 8);
    right(fmtNum(ylo), L.y0 + L.ph);
    ctx.fillStyle = COLORS.text;
    ctx.font = "11px system-ui, sans-serif";
    ctx.fillText(xl, L.x0 + (L.pw - ctx.measureText(xl).width) / 2, h - 6);
    ctx.save();
    ctx.translate(14, L.y0 + (L.ph + ctx.measureText(yl).width) / 2);
    ctx.rotate(-Math.PI / 2);
    ctx.fillText(yl, 0, 0);
    ctx.restore();
    colourScale(ctx, L, this.scoreRange, "score", 14);
    if (!this.scoreRange) {
      ctx.fillStyle = COLORS.muted; ctx.font = "11px system-ui, sans-serif";
      ctx.fillText("no cell filled yet", L.x0 + 8, L.y0 + 16);
    }
  }
}

// A viridis bar right of the plot area of layout L, its ends labelled with range [lo, hi] (none:
// nothing scored yet) and its side with `name`, centred `shift` px below the bar's middle.
function colourScale(ctx, L, range, name, shift) {
  const sx = L.x0 + L.pw + 12, sw = 10;
  for (let k = 0; k < L.ph; k++) {
    ctx.fillStyle = viridis(1 - k / L.ph);
    ctx.fillRect(sx, L.y0 + k, sw, 1.5);
  }
  ctx.fillStyle = COLORS.muted;
  ctx.font = "10px system-ui, sans-serif";
  if (range) {
    ctx.fillText(fmtNum(range[1]), sx + sw + 3, L.y0 + 8);
    ctx.fillText(fmtNum(range[0]), sx + sw + 3, L.y0 + L.ph);
  }
  ctx.save(); ctx.translate(sx + sw + 12, L.y0 + L.ph / 2 + shift); ctx.rotate(-Math.PI / 2); ctx.fillText(name, 0, 0); ctx.restore();
}

function fmtNum(x) {
  if (x === null || x === undefined) return "–";
  return Math.abs(x) >= 1000 ? x.toFixed(0) : +x.toPrecision(3) + "";
}

// How an archive grew: coverage (share of cells filled, navy, left axis) and QD-score (sum of
// the elites' scores, orange, right axis) after each generation, against evaluations.
export function drawProgress(canvas, progress) {
  const { ctx, w, h } = fitCanvas(canvas);
  const pad = { l: 40, r: 52, t: 22, b: 18 };
  ctx.fillStyle = "#fff";
  ctx.fillRect(0, 0, w, h);
  ctx.font = "10px system-ui, sans-serif";
  if (!progress.length) {
    ctx.fillStyle = COLORS.muted; ctx.fillText("no generation yet", 10, 20);
    return;
  }
  const n = progress[progress.length - 1].evaluations;
  const cmax = Math.max(1e-9, ...progress.map((p) => p.coverage));
  const qmax = Math.max(1e-12, ...progress.map((p) => p.qd_score));
  const X = (e) => pad.l + ((w - pad.l - pad.r) * e) / Math.max(1, n);
  const Y = (v, top) => h - pad.b - ((h - pad.t - pad.b) * v) / top;
  ctx.strokeStyle = COLORS.gridAxis; ctx.lineWidth = 1;
  ctx.beginPath();
  ctx.moveTo(pad.l, pad.t); ctx.lineTo(pad.l, h - pad.b); ctx.lineTo(w - pad.r, h - pad.b); ctx.lineTo(w - pad.r, pad.t);
  ctx.stroke();
  const line = (key, top, color) => {
    ctx.beginPath();
    ctx.moveTo(X(0), Y(0, top));
    for (const p of progress) ctx.lineTo(X(p.evaluations), Y(p[key], top));
    ctx.strokeStyle = color; ctx.lineWidth = 1.5; ctx.stroke();
    ctx.fillStyle = color;
    for (const p of progress) ctx.fillRect(X(p.evaluations) - 1.5, Y(p[key], top) - 1.5, 3, 3);
  };
  line("coverage", cmax, COLORS.root);
  line("qd_score", qmax, COLORS.actuator);
  ctx.fillStyle = COLORS.root;
  ctx.fillText(`${+(100 * cmax).toPrecision(3)} %`, 2, pad.t + 8);
  ctx.fillText("0", 2, h - pad.b);
  ctx.fillStyle = COLORS.actuator;
  ctx.fillText(fmtNum(qmax), w - pad.r + 4, pad.t + 8);
  ctx.fillText("0", w - pad.r + 4, h - pad.b);
  ctx.fillStyle = COLORS.muted;
  ctx.fillText("0", pad.l, h - 4);
  const xl = `${n} evaluations`;
  ctx.fillText(xl, w - pad.r - ctx.measureText(xl).width, h - 4);
  ctx.font = "11px system-ui, sans-serif";
  ctx.fillStyle = COLORS.root; ctx.fillText("coverage", pad.l + 6, 14);
  ctx.fillStyle = COLORS.actuator; ctx.fillText("QD-score", pad.l + 70, 14);
}

// A design's bodies as a scatter (sanlab design): each body a point at two of its numbers
// (free numbers in the file's units, or the score), filled by its score (viridis, from the lowest
// score to the highest; grey: not scored), the reference (the file's defaults) a navy square,
// the chosen body ringed in red, a pruned body a hollow circle. set({x, y, points}): x and y
// {label, lo, hi}; points [{x, y, score, reference, chosen, pruned}] (x, y in the axes' units).
export class Scatter {
  constructor(canvas) {
    this.canvas = canvas;
    this.pad = { l: 56, r: 78, t: 14, b: 36 };
    this.data = null;
  }

  set(data) {
    this.data = data;
  }

  layout() {
    const w = this.canvas.clientWidth, h = this.canvas.clientHeight, p = this.pad;
    return { w, h, x0: p.l, y0: p.t, pw: Math.max(1, w - p.l - p.r), ph: Math.max(1, h - p.t - p.b) };
  }

  // Point i's centre, CSS px from the canvas's top left.
  px(i) {
    const L = this.layout(), { x, y, points } = this.data, q = points[i];
    const f = (v, a) => (a.hi > a.lo ? (v - a.lo) / (a.hi - a.lo) : 0.5);
    return [L.x0 + f(q.x, x) * L.pw, L.y0 + L.ph - f(q.y, y) * L.ph];
  }

  // The index of the point nearest (u, v) CSS px within 10 px, or -1; the chosen body and the
  // reference win ties (they are drawn on top).
  pointAt(u, v) {
    if (!this.data) return -1;
    let best = -1, bestD = 100;
    this.data.points.forEach((q, i) => {
      const [a, b] = this.px(i);
      const d = (a - u) ** 2 + (b - v) ** 2 - (q.chosen || q.reference ? 1 : 0);
      if (d <= bestD) { best = i; bestD = d; }
    });
    return best;
  }

  draw() {
    const { ctx, w, h } = fitCanvas(this.canvas);
    this.drawnW = w;
    ctx.fillStyle = "#fff";
    ctx.fillRect(0, 0, w, h);
    if (!this.data) return;
    const L = this.layout(), { x, y, points } = this.data;
    ctx.strokeStyle = COLORS.gridAxis; ctx.lineWidth = 1;
    ctx.strokeRect(L.x0 - 0.5, L.y0 - 0.5, L.pw + 1, L.ph + 1);
    ctx.fillStyle = COLORS.muted;
    ctx.font = "10px system-ui, sans-serif";
    ctx.fillText(fmtNum(x.lo), L.x0, L.y0 + L.ph + 12);
    const xh = fmtNum(x.hi);
    ctx.fillText(xh, L.x0 + L.pw - ctx.measureText(xh).width, L.y0 + L.ph + 12);
    const right = (text, v) => ctx.fillText(text, L.x0 - 3 - ctx.measureText(text).width, v);
    right(fmtNum(y.hi), L.y0 + 8);
    right(fmtNum(y.lo), L.y0 + L.ph);
    ctx.fillStyle = COLORS.text;
    ctx.font = "11px system-ui, sans-serif";
    ctx.fillText(x.label, L.x0 + (L.pw - ctx.measureText(x.label).width) / 2, h - 6);
    ctx.save();
    ctx.translate(14, L.y0 + (L.ph + ctx.measureText(y.label).width) / 2);
    ctx.rotate(-Math.PI / 2);
    ctx.fillText(y.label, 0, 0);
    ctx.restore();
    let lo = Infinity, hi = -Infinity;
    for (const q of points) if (q.score !== null) { lo = Math.min(lo, q.score); hi = Math.max(hi, q.score); }
    this.scoreRange = hi >= lo ? [lo, hi] : null;
    const fill = (q) => (q.score === null ? COLORS.contactOff : viridis(hi > lo ? (q.score - lo) / (hi - lo) : 1));
    // ordinary bodies first, then the reference and the chosen body on top
    const order = points.map((q, i) => i).sort((a, b) => rankOf(points[a]) - rankOf(points[b]));
    for (const i of order) {
      const q = points[i], [u, v] = this.px(i);
      ctx.lineWidth = 1;
      if (q.reference) {
        ctx.fillStyle = fill(q);
        ctx.fillRect(u - 6, v - 6, 12, 12);
        ctx.strokeStyle = COLORS.root; ctx.lineWidth = 2.5;
        ctx.strokeRect(u - 6, v - 6, 12, 12);
      } else {
        ctx.beginPath(); ctx.arc(u, v, 5, 0, 2 * Math.PI);
        if (q.pruned) { ctx.strokeStyle = COLORS.muted; ctx.stroke(); }
        else { ctx.fillStyle = fill(q); ctx.fill(); ctx.strokeStyle = "rgba(40,40,40,0.6)"; ctx.stroke(); }
      }
      if (q.chosen) {
        ctx.beginPath(); ctx.arc(u, v, 10, 0, 2 * Math.PI);
        ctx.strokeStyle = COLORS.follow; ctx.lineWidth = 2.5; ctx.stroke();
      }
    }
    colourScale(ctx, L, this.scoreRange, "speed (cm/s)", 40);
    if (!points.length) {
      ctx.fillStyle = COLORS.muted; ctx.font = "11px system-ui, sans-serif";
      ctx.fillText("no body scored yet", L.x0 + 8, L.y0 + 16);
    }
  }
}

const rankOf = (q) => (q.chosen ? 2 : q.reference ? 1 : 0);
