// Plots on canvas: a run's sorted scores (the paper's long tail, §5.2), a tuning run's score
// per trial, and the SAN raster (which sensors and nodes are on when).

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
