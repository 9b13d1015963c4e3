// Live mode: the server runs the gait in real time and streams its frames; the page plays them
// from a short buffer. A creature with eyes chases the follow point, which the user drags with
// the mouse or a finger (paper §3.2, Figure 10); any creature can be watched on a chosen terrain.

import { View, cameraFor, drawFrame, fitCanvas, linkColors, scaleFor } from "./draw.js";
import { Raster } from "./plots.js";
import { attempt, fmt, gaitHref, h, shortId } from "./util.js";

const TRAIL_S = 20; // s of centre-of-mass trail kept
const RASTER_S = 4; // s of SAN activity shown

export class LiveView {
  constructor(app, gaitId) {
    this.app = app;
    this.gaitId = gaitId;
    this.queue = []; // frames not yet shown
    this.shown = null; // the frame on screen
    this.playhead = null; // simulated time on screen (s)
    this.last = null;
    this.track = []; // [t, com x, com y, follow x, follow y] of every frame received (tests read it)
    this.history = []; // recent frames (trail, raster)
    this.received = 0;
    this.displayed = 0;
    this.fps = 0;
    this.stats = null;
    this.dragging = false;
    this.follow = null;
    this.pendingFollow = null;
    this.offs = [];
  }

  async mount(root) {
    this.root = root;
    root.replaceChildren(h("h2", {}, `Live: ${shortId(this.gaitId)}`), h("p", { class: "muted", id: "live-status" }, "compiling the creature's step… (the first start of a creature takes a while)"));
    this.offs.push(this.app.api.on("live.frames", (m) => this.onFrames(m)));
    this.offs.push(this.app.api.on("live.reset", (m) => this.setup(m)));
    this.offs.push(this.app.api.on("live.stats", (m) => (this.stats = m)));
    this.offs.push(this.app.api.on("live.error", (m) => { this.statusLine(m.error); }));
    const d = await attempt(() => this.app.api.request("live.start", { gait: this.gaitId }));
    if (!d) {
      root.replaceChildren(h("h2", {}, `Live: ${shortId(this.gaitId)}`), h("p", { class: "muted" }, "cannot run this gait live (see the message above)"));
      this.app.loaded("live-error");
      return;
    }
    this.build(d);
    this.setup(d);
    this.app.loaded("live");
  }

  unmount() {
    for (const off of this.offs) off();
    this.app.api.notify("live.stop");
  }

  statusLine(text) {
    const el = document.getElementById("live-status");
    if (el) el.textContent = text;
  }

  build(d) {
    const c = d.creature;
    this.canvas = h("canvas", { id: "live-stage", class: "stage live" });
    this.rasterCanvas = h("canvas", { id: "live-raster", class: "raster" });
    this.raster = new Raster(this.rasterCanvas, c);
    this.statsEl = h("span", { id: "live-stats", class: "mono" });
    const terrain = d.vertical
      ? h("label", {}, "terrain ", h("select", { id: "live-terrain", onchange: (e) => this.setTerrain(e.target.value) },
          h("option", { value: "" }, "the creature's own"), ...this.app.info.terrains.map((t) => h("option", { value: t }, t))))
      : null;
    const hint = c.eyes.length
      ? "Drag the red follow point (mouse or finger): the creature sees it only through its binary eyes."
      : "This creature has no eyes: watch it run, and change the ground under it.";
    this.root.replaceChildren(
      h("h2", {}, `Live: ${d.gait.gait} `, h("span", { class: "mono muted" }, d.gait.id), ` · ${c.name}`),
      h("p", { class: "muted", id: "live-status" }, hint),
      h("div", { class: "controls" }, terrain, h("a", { href: gaitHref(d.gait.id) }, "back to playback"), this.statsEl),
      this.canvas,
      h("h3", {}, `SAN activity, last ${RASTER_S} s`),
      this.rasterCanvas);
    this.canvas.addEventListener("pointerdown", (e) => this.pointer(e, "down"));
    this.canvas.addEventListener("pointermove", (e) => this.pointer(e, "move"));
    this.canvas.addEventListener("pointerup", (e) => this.pointer(e, "up"));
    this.canvas.addEventListener("pointercancel", (e) => this.pointer(e, "up"));
  }

  setup(d) {
    this.desc = d;
    this.colors = linkColors(d.creature);
    this.queue = [];
    this.history = [];
    this.shown = null;
    this.playhead = null;
    this.scale = null;
    this.cam = null;
    this.follow = d.follow;
  }

  async setTerrain(kind) {
    await attempt(() => this.app.api.request("live.terrain", { terrain: kind || "flat" }));
  }

  onFrames(m) {
    if (!m.finite) {
      this.statusLine("the simulation went non-finite; starting again from rest");
      return;
    }
    for (let k = 0; k < m.t.length; k++) {
      const f = { t: m.t[k], links: m.links[k], contacts: m.contacts[k], touching: m.touching[k], com: m.com[k],
        bits: m.bits[k], nodes: m.nodes[k], follow: m.follow };
      this.queue.push(f);
      this.track.push([f.t, f.com[0], f.com[1], m.follow ? m.follow[0] : null, m.follow ? m.follow[1] : null]);
      this.received++;
    }
    if (this.track.length > 20000) this.track.splice(0, this.track.length - 20000);
  }

  pointer(e, kind) {
    if (!this.desc || !this.desc.creature.eyes.length || !this.view) return;
    const r = this.canvas.getBoundingClientRect();
    const [x, y] = this.view.world(e.clientX - r.left, e.clientY - r.top);
    if (kind === "down") {
      this.dragging = true;
      this.canvas.setPointerCapture(e.pointerId);
    } else if (kind === "up") {
      this.dragging = false;
    }
    if (kind === "down" || (kind === "move" && this.dragging) || kind === "up") {
      this.follow = [x, y];
      this.pendingFollow = [x, y];
    }
  }

  tick(now) {
    if (!this.desc || !this.canvas) return;
    if (this.pendingFollow) {
      // at most one update per displayed frame
      this.app.api.notify("live.follow", { x: this.pendingFollow[0], y: this.pendingFollow[1] });
      this.pendingFollow = null;
    }
    const dt = this.last === null ? 0 : (now - this.last) / 1000;
    this.last = now;
    if (this.queue.length) {
      const newest = this.queue[this.queue.length - 1].t;
      if (this.playhead === null) this.playhead = this.queue[0].t;
      else this.playhead += dt;
      // fell far behind (a stalled tab): jump ahead rather than play in slow motion
      if (newest - this.playhead > 1.0) this.playhead = newest - 0.3;
      let f = null;
      while (this.queue.length && this.queue[0].t <= this.playhead + 1e-9) f = this.queue.shift();
      if (f) {
        this.shown = f;
        this.history.push(f);
        this.displayed++;
        const keep = Math.round(TRAIL_S * 60);
        if (this.history.length > keep) this.history.splice(0, this.history.length - keep);
      }
    }
    this.countFps(now);
    this.draw();
  }

  countFps(now) {
    if (!this.fpsWindow) this.fpsWindow = { t: now, n: this.displayed };
    if (now - this.fpsWindow.t >= 1000) {
      this.fps = ((this.displayed - this.fpsWindow.n) * 1000) / (now - this.fpsWindow.t);
      this.fpsWindow = { t: now, n: this.displayed };
      const s = this.stats;
      this.statsEl.textContent = `${this.fps.toFixed(0)} frames/s shown · t = ${this.shown ? this.shown.t.toFixed(1) : "–"} s` +
        (s ? ` · simulated/real time ${s.ratio.toFixed(2)} (could run ${s.capacity.toFixed(1)}x)` : "");
    }
  }

  draw() {
    const f = this.shown;
    if (!f) return;
    const c = this.desc.creature;
    const { ctx, w, h: ht } = fitCanvas(this.canvas);
    if (!this.scale) this.scale = scaleFor(c, f.links, w, ht) * (c.eyes.length ? 0.6 : 1);
    // The camera follows the centre of mass smoothly, but holds still while the user drags,
    // so that the point stays under the pointer.
    const target = cameraFor(c, this.desc.terrain, f.com, w, ht, this.scale);
    if (!this.cam) this.cam = target;
    else if (!this.dragging) {
      const a = 0.04;
      this.cam = [this.cam[0] + a * (target[0] - this.cam[0]), this.cam[1] + a * (target[1] - this.cam[1])];
    }
    this.view = new View(w, ht, this.scale, this.cam[0], this.cam[1]);
    const shown = { ...f, follow: c.eyes.length ? this.follow : null };
    drawFrame(ctx, this.view, c, shown, { terrain: this.desc.terrain, colors: this.colors,
      trail: this.history.map((x) => x.com) });
    const n = Math.round(RASTER_S * 60);
    const recent = this.history.slice(-n);
    this.raster.drawRecent(recent.map((x) => x.bits), recent.map((x) => x.nodes));
  }

  // For tests: where a world point is on the canvas now (CSS px from the canvas's corner).
  toPx(x, y) {
    return this.view ? this.view.px(x, y) : null;
  }
}
