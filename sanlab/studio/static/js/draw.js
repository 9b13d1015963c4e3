// Drawing a creature on a canvas: the view (world metres <-> canvas pixels), the ground or the
// water's grid, the centre-of-mass trail, the links, contacts (touch sensors lit when on), eye
// cones (lit when the eye sees the follow point) and the follow point. Colours follow sanlab's
// renderer (sanlab/render/draw.py) so that the studio and rendered files look alike.

export const COLORS = {
  background: "#fbfaf6",
  groundFill: "#e6e0d2",
  groundLine: "#605646",
  tick: "#a09684",
  grid: "#e2e2de",
  gridAxis: "#c8c8c2",
  text: "#282828",
  muted: "#6e6e6e",
  root: "#1e3a6e",
  limbs: ["#2e75cc", "#009282", "#8c56be", "#c85a50", "#5a8c28"],
  jointRing: "#191919",
  jointFill: "#ffffff",
  contactOn: "#f58014",
  contactOff: "#a5a5a5",
  muscle: "#c83c3c",
  spring: "#787878",
  trail: "#b9b9c8",
  follow: "#d62728",
  followPath: "#f0b4b4",
  eyeOn: "rgba(245, 128, 20, 0.30)",
  eyeOff: "rgba(120, 120, 120, 0.08)",
  sensor: "#6e6e6e",
  hidden: "#2e75cc",
  actuator: "#f58014",
  nodeOff: "#ecece8",
  cursor: "#d62728",
};

// A colour per link: roots navy, each subtree hanging from a root in its own hue.
export function linkColors(creature) {
  const out = [];
  const branch = [];
  let next = 0;
  creature.links.forEach((l, i) => {
    if (l.parent === null) {
      out.push(l.kind === "point" ? COLORS.limbs[0] : COLORS.root);
      return;
    }
    const p = l.parent;
    if (creature.links[p].parent === null) branch[i] = next++;
    else branch[i] = branch[p];
    out.push(COLORS.limbs[branch[i] % COLORS.limbs.length]);
  });
  return out;
}

// World (m, y up) <-> canvas CSS pixels (y down). (cx, cy): the world point at the centre.
export class View {
  constructor(w, h, scale, cx, cy) {
    Object.assign(this, { w, h, scale, cx, cy });
  }
  px(x, y) {
    return [this.w / 2 + (x - this.cx) * this.scale, this.h / 2 - (y - this.cy) * this.scale];
  }
  world(u, v) {
    return [this.cx + (u - this.w / 2) / this.scale, this.cy - (v - this.h / 2) / this.scale];
  }
}

// Size the canvas's backing store to its CSS size times the device pixel ratio; returns the
// context scaled so that drawing is in CSS pixels.
export function fitCanvas(canvas) {
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(canvas.clientWidth));
  const h = Math.max(1, Math.round(canvas.clientHeight));
  if (canvas.width !== Math.round(w * dpr) || canvas.height !== Math.round(h * dpr)) {
    canvas.width = Math.round(w * dpr);
    canvas.height = Math.round(h * dpr);
  }
  const ctx = canvas.getContext("2d");
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  return { ctx, w, h };
}

function rot(a, p) {
  const c = Math.cos(a), s = Math.sin(a);
  return [c * p[0] - s * p[1], s * p[0] + c * p[1]];
}

// Points [[x, y], ...] in link i's frame -> world, for one frame's link placements.
export function toWorld(links, i, pts) {
  const [x, y, a] = links[i];
  return pts.map((p) => {
    const r = rot(a, p);
    return [x + r[0], y + r[1]];
  });
}

// The outline of the creature in one frame, in world coordinates (for framing the camera).
export function outline(creature, links) {
  const pts = [];
  creature.links.forEach((l, i) => pts.push(...toWorld(links, i, l.points)));
  return pts;
}

export function bounds(pts) {
  let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
  for (const [x, y] of pts) {
    if (x === null || y === null) continue;
    x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y);
  }
  return [x0, y0, x1, y1];
}

// Ground height under x (m) from the server's sampled profile.
export function groundAt(terrain, x) {
  if (!terrain || terrain.kind === "flat" || terrain.kind === "none") return 0;
  const u = (x - terrain.x0) / terrain.dx;
  const n = terrain.h.length;
  if (u <= 0) return terrain.h[0];
  if (u >= n - 1) return terrain.h[n - 1];
  const i = Math.floor(u), f = u - i;
  return terrain.h[i] * (1 - f) + terrain.h[i + 1] * f;
}

// A scale (px per m) that shows the creature large: its width about 1/2.8 of the picture,
// its height at most 0.6 of it (as sanlab's renderer frames it).
export function scaleFor(creature, links, w, h) {
  const [x0, y0, x1, y1] = bounds(outline(creature, links));
  const cw = Math.max(x1 - x0, 0.05), ch = Math.max(y1 - y0, 0.05);
  const horizontal = creature.plane === "horizontal";
  return Math.min(w / (cw * (horizontal ? 4.5 : 2.8)), (h * (horizontal ? 0.35 : 0.6)) / ch);
}

// The camera centre for a centre-of-mass position: on the vertical plane the ground keeps a band
// at the bottom of the picture.
export function cameraFor(creature, terrain, com, w, h, scale) {
  if (creature.plane === "horizontal") return [com[0], com[1]];
  const g = groundAt(terrain, com[0]);
  return [com[0], g + (0.3 * h) / scale];
}

function nice(x) {
  const e = Math.pow(10, Math.floor(Math.log10(x)));
  for (const m of [1, 2, 5, 10]) if (m * e >= x) return m * e;
  return 10 * e;
}

function fmtLen(m) {
  if (m >= 1) return `${+m.toFixed(2)} m`;
  return `${+(m * 100).toFixed(1)} cm`;
}

function drawGround(ctx, view, terrain) {
  const [wx0] = view.world(0, 0);
  const [wx1] = view.world(view.w, 0);
  const step = nice(90 / view.scale);
  if (!terrain || terrain.kind === "none") {
    // the horizontal plane: a grid in metres
    ctx.lineWidth = 1;
    const [, wy1] = view.world(0, 0);
    const [, wy0] = view.world(0, view.h);
    for (let x = Math.floor(wx0 / step) * step; x <= wx1; x += step) {
      const [u] = view.px(x, 0);
      ctx.strokeStyle = Math.abs(x) < step / 2 ? COLORS.gridAxis : COLORS.grid;
      ctx.beginPath(); ctx.moveTo(u, 0); ctx.lineTo(u, view.h); ctx.stroke();
    }
    for (let y = Math.floor(wy0 / step) * step; y <= wy1; y += step) {
      const [, v] = view.px(0, y);
      ctx.strokeStyle = Math.abs(y) < step / 2 ? COLORS.gridAxis : COLORS.grid;
      ctx.beginPath(); ctx.moveTo(0, v); ctx.lineTo(view.w, v); ctx.stroke();
    }
    ctx.fillStyle = COLORS.muted;
    ctx.font = "11px system-ui, sans-serif";
    ctx.fillText(`grid ${fmtLen(step)}`, 8, view.h - 8);
    return;
  }
  const n = Math.max(2, Math.ceil(view.w / 3));
  ctx.beginPath();
  for (let k = 0; k <= n; k++) {
    const x = wx0 + ((wx1 - wx0) * k) / n;
    const [u, v] = view.px(x, groundAt(terrain, x));
    if (k === 0) ctx.moveTo(u, v); else ctx.lineTo(u, v);
  }
  ctx.lineTo(view.w, view.h + 2);
  ctx.lineTo(0, view.h + 2);
  ctx.closePath();
  ctx.fillStyle = COLORS.groundFill;
  ctx.fill();
  ctx.beginPath();
  for (let k = 0; k <= n; k++) {
    const x = wx0 + ((wx1 - wx0) * k) / n;
    const [u, v] = view.px(x, groundAt(terrain, x));
    if (k === 0) ctx.moveTo(u, v); else ctx.lineTo(u, v);
  }
  ctx.strokeStyle = COLORS.groundLine;
  ctx.lineWidth = 1.5;
  ctx.stroke();
  // distance ticks, labelled in metres: they show the motion when the camera follows
  ctx.fillStyle = COLORS.tick;
  ctx.strokeStyle = COLORS.tick;
  ctx.lineWidth = 1;
  ctx.font = "10px system-ui, sans-serif";
  for (let x = Math.floor(wx0 / step) * step; x <= wx1; x += step) {
    const [u, v] = view.px(x, groundAt(terrain, x));
    ctx.beginPath(); ctx.moveTo(u, v); ctx.lineTo(u, v + 6); ctx.stroke();
    ctx.fillText(`${+x.toFixed(2)}`, u + 2, v + 15);
  }
}

function drawEyes(ctx, view, creature, links, bits, follow) {
  const r = Math.max(40, Math.min(view.w, view.h) * 0.22);
  for (const e of creature.eyes) {
    const [p] = toWorld(links, e.link, [e.at]);
    let ax;
    if (e.axis) {
      const a = links[e.axis[0]], b = links[e.axis[1]];
      ax = Math.atan2(b[1] - a[1], b[0] - a[0]);
    } else {
      ax = links[e.link][2];
    }
    const [u, v] = view.px(p[0], p[1]);
    const on = bits && bits[e.sensor] > 0;
    ctx.beginPath();
    ctx.moveTo(u, v);
    // canvas angles run clockwise (y down): negate
    ctx.arc(u, v, r, -(ax + e.max), -(ax + e.min), false);
    ctx.closePath();
    ctx.fillStyle = on ? COLORS.eyeOn : COLORS.eyeOff;
    ctx.fill();
    ctx.strokeStyle = on ? COLORS.contactOn : "rgba(120,120,120,0.35)";
    ctx.lineWidth = 1;
    ctx.stroke();
  }
  if (follow) {
    const [u, v] = view.px(follow[0], follow[1]);
    ctx.beginPath(); ctx.arc(u, v, 7, 0, 2 * Math.PI);
    ctx.fillStyle = COLORS.follow; ctx.fill();
    ctx.beginPath(); ctx.arc(u, v, 11, 0, 2 * Math.PI);
    ctx.strokeStyle = COLORS.follow; ctx.lineWidth = 2; ctx.stroke();
  }
}

// Draw one frame. f: {links [L][3], contacts [C][2], touching [C], com [2], bits [S], u [A],
// follow [2] or null}. opts: terrain, trail ([[x, y], ...] of the centre of mass), eyes,
// sensors, follow (booleans: draw them), followPath.
export function drawFrame(ctx, view, creature, f, opts = {}) {
  const colors = opts.colors || linkColors(creature);
  ctx.fillStyle = COLORS.background;
  ctx.fillRect(0, 0, view.w, view.h);
  drawGround(ctx, view, opts.terrain);
  if (opts.followPath && creature.follow_path) {
    ctx.beginPath();
    creature.follow_path.forEach(([x, y], k) => {
      const [u, v] = view.px(x, y);
      if (k === 0) ctx.moveTo(u, v); else ctx.lineTo(u, v);
    });
    ctx.strokeStyle = COLORS.followPath; ctx.lineWidth = 2; ctx.stroke();
  }
  if (opts.trail && opts.trail.length > 1) {
    ctx.beginPath();
    opts.trail.forEach(([x, y], k) => {
      const [u, v] = view.px(x, y);
      if (k === 0) ctx.moveTo(u, v); else ctx.lineTo(u, v);
    });
    ctx.strokeStyle = COLORS.trail; ctx.lineWidth = 2; ctx.stroke();
  }
  if (opts.eyes !== false && creature.eyes.length) drawEyes(ctx, view, creature, f.links, f.bits, opts.follow !== false ? f.follow : null);
  else if (opts.follow !== false && f.follow) drawEyes(ctx, view, { eyes: [] }, f.links, f.bits, f.follow);

  const size = creature.size * view.scale;
  const lw = Math.max(2, Math.min(9, size * 0.06));
  for (const s of creature.springs) {
    const [a] = toWorld(f.links, s.a[0], [s.a[1]]), [b] = toWorld(f.links, s.b[0], [s.b[1]]);
    const [ua, va] = view.px(...a), [ub, vb] = view.px(...b);
    ctx.beginPath(); ctx.moveTo(ua, va); ctx.lineTo(ub, vb);
    ctx.strokeStyle = COLORS.spring; ctx.lineWidth = Math.max(1, lw * 0.3); ctx.stroke();
  }
  const order = creature.links.map((_, i) => i).sort((i, j) => (creature.links[i].kind !== "polygon") - (creature.links[j].kind !== "polygon"));
  for (const i of order) {
    const l = creature.links[i];
    const pts = toWorld(f.links, i, l.points).map(([x, y]) => view.px(x, y));
    ctx.fillStyle = colors[i];
    ctx.strokeStyle = colors[i];
    if (l.kind === "polygon") {
      ctx.beginPath();
      pts.forEach(([u, v], k) => (k ? ctx.lineTo(u, v) : ctx.moveTo(u, v)));
      ctx.closePath();
      ctx.fill();
      ctx.strokeStyle = "rgba(0,0,0,0.35)"; ctx.lineWidth = Math.max(1, lw * 0.35); ctx.stroke();
    } else if (l.kind === "segment") {
      ctx.beginPath(); ctx.moveTo(...pts[0]); ctx.lineTo(...pts[1]);
      ctx.lineWidth = lw; ctx.lineCap = "round"; ctx.stroke();
    } else {
      ctx.beginPath(); ctx.arc(pts[0][0], pts[0][1], Math.max(4, lw * 1.3), 0, 2 * Math.PI); ctx.fill();
    }
  }
  for (const m of creature.muscles) {
    const [a] = toWorld(f.links, m.a[0], [m.a[1]]), [b] = toWorld(f.links, m.b[0], [m.b[1]]);
    const u = f.u ? f.u[m.actuator] : 0.5;
    ctx.beginPath(); ctx.moveTo(...view.px(...a)); ctx.lineTo(...view.px(...b));
    ctx.strokeStyle = COLORS.muscle; ctx.globalAlpha = 0.45 + 0.55 * u;
    ctx.lineWidth = Math.max(1.5, lw * 0.3 * (1 + 1.5 * u)); ctx.stroke(); ctx.globalAlpha = 1;
  }
  if (opts.sensors !== false && f.contacts) {
    const touchOf = new Map(creature.touch.map((t) => [t.contact, t.sensor]));
    f.contacts.forEach((c, k) => {
      const [u, v] = view.px(c[0], c[1]);
      const sensor = touchOf.get(k);
      const lit = sensor !== undefined ? f.bits && f.bits[sensor] > 0 : f.touching && f.touching[k] > 0;
      ctx.beginPath(); ctx.arc(u, v, Math.max(2.5, lw * (sensor !== undefined ? 0.75 : 0.5)), 0, 2 * Math.PI);
      ctx.fillStyle = lit ? COLORS.contactOn : COLORS.contactOff; ctx.fill();
    });
  }
  creature.links.forEach((l, i) => {
    if (l.parent === null) return;
    const [u, v] = view.px(f.links[i][0], f.links[i][1]);
    const r = Math.max(2.5, lw * 0.55);
    ctx.beginPath(); ctx.arc(u, v, r, 0, 2 * Math.PI); ctx.fillStyle = COLORS.jointRing; ctx.fill();
    ctx.beginPath(); ctx.arc(u, v, r * 0.55, 0, 2 * Math.PI); ctx.fillStyle = COLORS.jointFill; ctx.fill();
  });
  if (f.com) {
    const [u, v] = view.px(f.com[0], f.com[1]);
    const r = Math.max(3, lw * 0.8);
    ctx.beginPath(); ctx.arc(u, v, r, 0, 2 * Math.PI); ctx.fillStyle = "#fff"; ctx.fill();
    ctx.beginPath(); ctx.moveTo(u, v); ctx.arc(u, v, r, 0, Math.PI / 2); ctx.closePath();
    ctx.fillStyle = COLORS.jointRing; ctx.fill();
    ctx.beginPath(); ctx.moveTo(u, v); ctx.arc(u, v, r, Math.PI, 1.5 * Math.PI); ctx.closePath(); ctx.fill();
    ctx.beginPath(); ctx.arc(u, v, r, 0, 2 * Math.PI); ctx.strokeStyle = COLORS.jointRing; ctx.lineWidth = 1; ctx.stroke();
  }
  // a scale bar, so that sizes can be read
  const bar = nice(60 / view.scale);
  ctx.fillStyle = COLORS.muted; ctx.strokeStyle = COLORS.muted; ctx.lineWidth = 2;
  const bx = view.w - 12 - bar * view.scale;
  ctx.beginPath(); ctx.moveTo(bx, 14); ctx.lineTo(view.w - 12, 14); ctx.stroke();
  ctx.font = "10px system-ui, sans-serif";
  ctx.fillText(fmtLen(bar), bx, 28);
}

// A frame object out of a playback's per-frame arrays.
export function frameOf(frames, k) {
  return {
    links: frames.links[k], contacts: frames.contacts[k], touching: frames.touching[k], com: frames.com[k],
    bits: frames.bits[k], nodes: frames.nodes[k], u: frames.u ? frames.u[k] : null,
    follow: frames.follow ? frames.follow[k] : null, t: frames.t[k],
  };
}

// Centre-of-mass x (and y) smoothed over +-0.4 s: a steady camera over a jerky gait.
export function smoothTrack(com, fps, sigma = 0.4) {
  const r = Math.max(1, Math.round(sigma * fps));
  const n = com.length;
  const out = [];
  for (let k = 0; k < n; k++) {
    let sx = 0, sy = 0, m = 0;
    for (let j = Math.max(0, k - r); j <= Math.min(n - 1, k + r); j++) {
      if (com[j][0] === null) continue;
      sx += com[j][0]; sy += com[j][1]; m++;
    }
    out.push(m ? [sx / m, sy / m] : com[k]);
  }
  return out;
}
