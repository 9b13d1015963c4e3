// A run: its settings, its score distribution (and tuning trace), and its top gaits as a grid
// of small looping animations playing side by side.

import { View, cameraFor, drawFrame, fitCanvas, frameOf, linkColors, scaleFor, smoothTrack } from "./draw.js";
import { drawScores, drawTrace } from "./plots.js";
import { attempt, flags, fmt, fmtDate, gaitHref, h, progress } from "./util.js";

// One gait's looping animation in a small canvas.
export class Tile {
  constructor(app, gait) {
    this.app = app;
    this.gait = gait;
    this.canvas = h("canvas", { class: "tile-canvas" });
    this.caption = h("div", { class: "caption" });
    this.el = h("a", { class: "tile", href: gaitHref(gait.gait), dataset: { gait: gait.gait, id: gait.id } },
      this.canvas, this.caption);
    this.setCaption(gait);
    this.data = null;
  }

  setCaption(g) {
    this.caption.replaceChildren(
      h("b", {}, `#${g.rank}`), " ", h("span", { class: "mono" }, g.id), " ",
      h("span", {}, `${fmt(g.speed_cm_s)} cm/s`), " ", h("span", { class: "muted" }, flags(g)));
  }

  async load() {
    const data = await attempt(() => this.app.api.request("playback", { gait: this.gait.id }));
    if (!data) return;
    this.data = data;
    this.colors = linkColors(data.creature);
    this.smooth = smoothTrack(data.frames.com, data.frames.fps);
    this.el.dataset.playing = "1";
  }

  draw(now) {
    if (!this.data) return;
    const { ctx, w, h: ht } = fitCanvas(this.canvas);
    const fr = this.data.frames;
    const n = fr.t.length;
    const k = Math.floor(((now / 1000) * fr.fps) % n);
    if (!this.scale || this.w !== w) {
      this.w = w;
      this.scale = scaleFor(this.data.creature, fr.links[0], w, ht) * 0.8;
    }
    const [cx, cy] = cameraFor(this.data.creature, this.data.terrain, this.smooth[k], w, ht, this.scale);
    const view = new View(w, ht, this.scale, cx, cy);
    drawFrame(ctx, view, this.data.creature, frameOf(fr, k), {
      terrain: this.data.terrain, trail: fr.com.slice(0, k + 1), colors: this.colors, followPath: true,
    });
  }
}

export class RunView {
  constructor(app, runId) {
    this.app = app;
    this.runId = runId;
    this.n = 10;
    this.tiles = new Map(); // RUN#IDX -> Tile
  }

  async mount(root) {
    this.root = root;
    this.head = h("div");
    this.scores = h("canvas", { id: "scores", class: "plot" });
    this.trace = h("canvas", { id: "trace", class: "plot" });
    this.traceBox = h("div", { hidden: true }, h("h3", {}, "Tuning trace (score per trial; orange: best so far)"), this.trace);
    this.grid = h("div", { id: "gait-grid", class: "gait-grid" });
    this.nInput = h("input", { id: "grid-n", type: "number", min: 1, max: 200, value: this.n, size: 4,
      onchange: () => this.setN(Number(this.nInput.value)) });
    root.replaceChildren(
      this.head,
      h("div", { class: "plots" },
        h("div", {}, h("h3", {}, "Score distribution (sorted, best first: the long tail of §5.2)"), this.scores),
        this.traceBox),
      h("h3", {}, "Top gaits ", h("label", { class: "muted" }, "show ", this.nInput),
        h("button", { id: "grid-more", onclick: () => this.setN(this.n + 10) }, "more")),
      this.grid);
    await this.refresh();
    this.app.loaded("run");
  }

  setN(n) {
    this.n = Math.max(1, Math.min(200, n || 10));
    this.nInput.value = this.n;
    this.refreshTop();
  }

  async refresh() {
    const run = await attempt(() => this.app.api.request("run", { run: this.runId }));
    if (!run) {
      this.head.replaceChildren(h("h2", {}, `Run ${this.runId}`), h("p", { class: "muted" }, "not found in this library"));
      return;
    }
    this.run = run;
    const p = run.params || {};
    this.head.replaceChildren(
      h("h2", {}, `Run ${run.run_id}: ${run.creature} `, h("span", { class: `status-${run.status}` }, run.status)),
      h("p", { class: "meta" },
        `${run.kind}${run.method ? ` (${run.method})` : ""} · seed ${run.seed ?? "–"} · ${progress(run)} · metric ${run.metric ?? "–"} · ${fmt(run.seconds)} s each · best ${fmt(run.best_score)} (${fmt(run.best_speed_cm_s)} cm/s) · ${fmtDate(run.created)} UTC`,
        run.parent ? [" · from ", h("a", { href: gaitHref(run.parent) }, run.parent)] : null,
        p.source ? ` · ${p.source}` : null));
    drawScores(this.scores, run.scores, this.n);
    this.traceBox.hidden = !run.trace.length;
    if (run.trace.length) drawTrace(this.trace, run.trace);
    await this.refreshTop();
  }

  async refreshTop() {
    // Requests can overtake each other (asking for 3 then 13 gaits): only the latest counts.
    const seq = (this.seq = (this.seq || 0) + 1);
    const top = await attempt(() => this.app.api.request("top", { run: this.runId, n: this.n }));
    if (!top || seq !== this.seq) return;
    const keep = new Map();
    const els = [];
    for (const g of top) {
      let t = this.tiles.get(g.id);
      if (!t) {
        t = new Tile(this.app, g);
        t.load();
      }
      t.gait = g;
      t.el.href = gaitHref(g.gait);
      t.el.dataset.gait = g.gait;
      t.setCaption(g);
      keep.set(g.id, t);
      els.push(t.el);
    }
    this.tiles = keep;
    this.grid.replaceChildren(...els);
  }

  onLibrary(msg) {
    const mine = msg.runs.find((r) => r[0] === this.run?.run_id);
    if (mine && this.run && (mine[2] !== this.run.evaluated || mine[3] !== this.run.trials || mine[1] !== this.run.status)) this.refresh();
  }

  tick(now) {
    for (const t of this.tiles.values()) t.draw(now);
  }
}
