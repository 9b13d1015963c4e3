// One gait: playback with play/pause, scrub, speed and frame step; the SAN raster synced with
// it; the gait's encoding, parameters, score and speed; export, render and tuning.

import { View, cameraFor, drawFrame, fitCanvas, frameOf, linkColors, scaleFor, smoothTrack } from "./draw.js";
import { Raster } from "./plots.js";
import { attempt, download, flags, fmt, gaitHref, h, shortId, showError } from "./util.js";

const SPEEDS = [0.1, 0.25, 0.5, 1, 2, 4];

export class GaitView {
  constructor(app, gaitId) {
    this.app = app;
    this.gaitId = gaitId;
    this.playing = true;
    this.speed = 1;
    this.pos = 0; // s of simulated time
    this.last = null;
    this.opts = { trail: true, sensors: true, eyes: true };
    this.lastDraw = null; // for tests: what the last drawn frame put where
  }

  async mount(root) {
    this.root = root;
    root.replaceChildren(h("h2", {}, `Gait ${shortId(this.gaitId)}`), h("p", { class: "muted", id: "gait-loading" }, "replaying…"));
    const data = await attempt(() => this.app.api.request("playback", { gait: this.gaitId }));
    if (!data) {
      root.replaceChildren(h("h2", {}, `Gait ${shortId(this.gaitId)}`), h("p", { class: "muted" }, "cannot show this gait (see the message above)"));
      this.app.loaded("gait-error");
      return;
    }
    this.data = data;
    this.colors = linkColors(data.creature);
    const fr = data.frames;
    this.smooth = smoothTrack(fr.com, fr.fps);
    this.duration = fr.t.length / fr.fps;
    this.build();
    this.app.loaded("gait");
  }

  build() {
    const g = this.data.gait, fr = this.data.frames, c = this.data.creature;
    this.canvas = h("canvas", { id: "stage", class: "stage" });
    this.rasterCanvas = h("canvas", { id: "raster", class: "raster" });
    this.raster = new Raster(this.rasterCanvas, c);
    this.rasterCanvas.addEventListener("pointerdown", (e) => {
      const r = this.rasterCanvas.getBoundingClientRect();
      this.seekFrame(this.raster.frameAt(e.clientX - r.left));
    });
    this.playBtn = h("button", { id: "play", onclick: () => this.setPlaying(!this.playing) }, "pause");
    this.scrub = h("input", { id: "scrub", type: "range", min: 0, max: fr.t.length - 1, step: 1, value: 0,
      oninput: () => { this.setPlaying(false); this.seekFrame(Number(this.scrub.value)); } });
    this.timeLabel = h("span", { id: "time", class: "mono" });
    const speed = h("select", { id: "speed", onchange: (e) => (this.speed = Number(e.target.value)) },
      ...SPEEDS.map((s) => h("option", { value: s, selected: s === 1 }, `${s}x`)));
    const toggle = (key, label) => h("label", {}, h("input", { type: "checkbox", checked: this.opts[key], id: `show-${key}`,
      onchange: (e) => { this.opts[key] = e.target.checked; this.drawn = -1; } }), ` ${label}`);
    const step = (d) => () => { this.setPlaying(false); this.seekFrame(this.frame + d); };
    const renderBtn = (kind) => h("button", { class: "render", dataset: { kind }, onclick: () => this.render(kind) }, kind.toUpperCase());
    this.renderOut = h("span", { id: "render-out", class: "muted" });
    const eyes = c.eyes.length > 0;
    this.root.replaceChildren(
      h("h2", {}, `Gait ${g.gait} `, h("span", { class: "mono muted" }, g.id), ` · ${g.creature}`),
      h("div", { class: "gait-page" }, h("div", { class: "player" },
        this.canvas,
        h("div", { class: "controls" },
          this.playBtn,
          h("button", { id: "step-back", title: "previous frame", onclick: step(-1) }, "◀|"),
          h("button", { id: "step-fwd", title: "next frame", onclick: step(1) }, "|▶"),
          this.scrub, this.timeLabel, speed,
          toggle("trail", "trail"), toggle("sensors", "touch sensors"), eyes ? toggle("eyes", "eyes & follow point") : null),
        h("h3", {}, "SAN activity (rows: sensors grey, hidden nodes blue, actuator nodes orange; click to seek)"),
        this.rasterCanvas),
      h("div", { class: "side" },
        h("table", { class: "kv" },
          ...[["kind", g.kind === "pattern" ? "pattern (open loop, no SAN)" : "SAN"],
            ["score", fmt(g.score, 4)], ["speed", `${fmt(g.speed_cm_s)} cm/s`],
            ["pattern ceiling", g.ceiling ? h("span", { id: "ceiling" }, `${fmt(g.ceiling.speed_cm_s)} cm/s`,
              g.kind === "san" && g.ceiling.fraction !== null ? ` (this gait: ${Math.round(100 * g.ceiling.fraction)} %)` : "",
              g.ceiling.verdict === "robust" && !g.ceiling.fell ? "" : " (not vouched for by an audit)") : "none stored (sanlab ceiling)"],
            ["rank", g.rank], ["flags", flags(g)],
            ["metric", g.metric], ["evaluated for", `${fmt(g.seconds)} s`], ["run", h("a", { href: `#/run/${g.run_id}` }, g.run_id)],
            ["parent", g.parent ? h("a", { href: gaitHref(g.parent) }, g.parent) : "–"]]
            .map(([k, v]) => h("tr", {}, h("th", {}, k), h("td", {}, v)))),
        h("h3", {}, "Encoding"), h("code", { id: "encoding", class: "encoding" }, g.encoding),
        h("h3", {}, "Parameters"), h("pre", { class: "params" }, JSON.stringify(g.params, null, 1)),
        h("div", { class: "actions" },
          h("button", { id: "export", onclick: () => this.exportJson() }, "Export JSON"),
          renderBtn("gif"), renderBtn("mp4"), renderBtn("png"),
          g.kind === "pattern" ? null : h("a", { id: "live-link", class: "button", href: gaitHref(g.id, "live") }, eyes ? "Steer live" : "Run live"),
          this.renderOut),
        g.kind === "pattern" ? null : this.tuneForm())));
    this.seekFrame(0);
  }

  tuneForm() {
    const method = h("select", { id: "tune-method" }, h("option", { value: "sa" }, "simulated annealing"), h("option", { value: "sga" }, "stochastic gradient ascent"));
    const trials = h("input", { id: "tune-trials", type: "number", min: 1, value: 200, size: 6 });
    const seed = h("input", { id: "tune-seed", type: "number", min: 0, value: 0, size: 5 });
    const vertical = this.data.creature.plane === "vertical";
    const terrain = h("select", { id: "tune-terrain", disabled: !vertical }, ...["flat", "rough", "hill"].map((t) => h("option", { value: t }, t)));
    const start = async () => {
      const job = await attempt(() => this.app.api.request("tune", { gait: this.data.gait.id, method: method.value,
        trials: Number(trials.value), seed: Number(seed.value), terrain: terrain.value }));
      if (job) this.app.jobs.update(job);
    };
    return h("div", { class: "work" }, h("h3", {}, "Fine-tune (phase 2, §5.3)"),
      h("div", { class: "form" }, h("label", {}, "method ", method), h("label", {}, "trials ", trials),
        h("label", {}, "seed ", seed), h("label", {}, "terrain ", terrain),
        h("button", { id: "tune-start", onclick: start }, "Start tuning")));
  }

  async exportJson() {
    const id = this.data.gait.id;
    const res = await fetch(`/api/export?gait=${encodeURIComponent(id)}`);
    if (!res.ok) {
      const body = await res.json().catch(() => ({ error: res.statusText }));
      showError(body.error);
      return;
    }
    download(await res.blob(), `${id.replace(/[/#]/g, "_")}.json`);
  }

  async render(kind) {
    this.renderOut.textContent = `rendering ${kind}…`;
    const out = await attempt(() => this.app.api.request("render", { gait: this.data.gait.id, kind }));
    if (!out) { this.renderOut.textContent = ""; return; }
    this.renderOut.replaceChildren(h("a", { href: out.url, download: out.name, id: `rendered-${kind}` }, out.name));
    const res = await fetch(out.url);
    if (res.ok) download(await res.blob(), out.name);
  }

  setPlaying(on) {
    this.playing = on;
    if (this.playBtn) this.playBtn.textContent = on ? "pause" : "play";
  }

  seekFrame(k) {
    const n = this.data.frames.t.length;
    this.frame = ((k % n) + n) % n;
    this.pos = this.frame / this.data.frames.fps;
    this.drawn = -1;
  }

  // For tests and the console: show simulated time t (s), paused.
  seek(t) {
    this.setPlaying(false);
    const fr = this.data.frames;
    let k = 0;
    while (k + 1 < fr.t.length && fr.t[k + 1] <= t + 1e-9) k++;
    this.seekFrame(k);
    this.draw();
    return this.lastDraw;
  }

  tick(now) {
    if (!this.data || !this.canvas) return;
    if (this.last !== null && this.playing) {
      this.pos = (this.pos + ((now - this.last) / 1000) * this.speed) % this.duration;
      this.frame = Math.min(this.data.frames.t.length - 1, Math.floor(this.pos * this.data.frames.fps + 1e-6));
    }
    this.last = now;
    const w = this.canvas.clientWidth;
    if (this.frame !== this.drawn || w !== this.drawnW) this.draw();
  }

  draw() {
    const fr = this.data.frames, c = this.data.creature;
    const k = this.frame;
    const { ctx, w, h: ht } = fitCanvas(this.canvas);
    if (!this.scale || this.drawnW !== w) this.scale = scaleFor(c, fr.links[0], w, ht);
    const [cx, cy] = cameraFor(c, this.data.terrain, this.smooth[k], w, ht, this.scale);
    const view = new View(w, ht, this.scale, cx, cy);
    const f = frameOf(fr, k);
    drawFrame(ctx, view, c, f, { terrain: this.data.terrain, colors: this.colors, trail: this.opts.trail ? fr.com.slice(0, k + 1) : null,
      sensors: this.opts.sensors, eyes: this.opts.eyes, follow: this.opts.eyes, followPath: this.opts.eyes });
    this.raster.drawAll(fr.bits, fr.nodes, k);
    this.scrub.value = k;
    this.timeLabel.textContent = `${fr.t[k].toFixed(3)} s / ${this.duration.toFixed(2)} s`;
    this.drawn = k;
    this.drawnW = w;
    const root = f.links[0];
    this.lastDraw = { frame: k, t: fr.t[k], root: root.slice(), rootPx: view.px(root[0], root[1]),
      scale: view.scale, center: [view.cx, view.cy], size: [w, ht] };
  }
}
