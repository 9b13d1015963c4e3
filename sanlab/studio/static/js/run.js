// A run: its settings, its score distribution (and tuning trace), its top gaits as a grid
// of small looping animations playing side by side, its gait modes (one animation per mode, of
// its best gait) and, for a search, its MAP-Elites archive as a heat map.

import { View, cameraFor, drawFrame, fitCanvas, frameOf, linkColors, scaleFor, smoothTrack } from "./draw.js";
import { HeatMap, drawProgress, drawScores, drawTrace } from "./plots.js";
import { attempt, flags, fmt, fmtDate, gaitHref, h, progress, shortId } from "./util.js";

const MODES_SHOWN = 12;

// One gait's looping animation in a small canvas. playback(id): where its frames come from (a
// promise; default: the studio's playback request).
export class Tile {
  constructor(app, gait, playback = null) {
    this.app = app;
    this.gait = gait;
    this.playback = playback || ((id) => this.app.api.request("playback", { gait: id }));
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
    const data = await attempt(() => this.playback(this.gait.id));
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

// A mode's tile: the animation of its best gait, captioned with the mode's name and size.
class ModeTile extends Tile {
  constructor(app, mode, playback) {
    super(app, { gait: mode.best, id: mode.best, mode }, playback);
    this.el.classList.add("mode-tile");
    this.el.dataset.mode = mode.name;
  }

  setCaption(g) {
    const m = g.mode;
    this.caption.replaceChildren(
      h("b", { class: "mode-name" }, m.name), " ", h("span", { class: "muted" }, `${m.size} gait${m.size === 1 ? "" : "s"}`), " · best ",
      h("span", { class: "mono" }, m.best), " ", h("span", {}, `${fmt(m.speed_cm_s)} cm/s`));
  }
}

export class RunView {
  constructor(app, runId) {
    this.app = app;
    this.runId = runId;
    this.n = 10;
    this.tiles = new Map(); // RUN#IDX -> Tile
    this.modeTiles = new Map(); // the best gait's RUN#IDX -> ModeTile
    this.playbacks = new Map(); // RUN#IDX -> promise of its playback (top and mode tiles share them)
    this.heat = null;
  }

  playback(id) {
    if (!this.playbacks.has(id)) {
      const p = this.app.api.request("playback", { gait: id });
      p.catch(() => this.playbacks.delete(id));
      this.playbacks.set(id, p);
    }
    return this.playbacks.get(id);
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
      this.grid,
      this.extrasNote = h("p", { id: "extras-note", class: "muted", hidden: true }),
      this.modesSection(), this.archiveSection());
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
      this.head.replaceChildren(h("h2", {}, `Run ${shortId(this.runId)}`), h("p", { class: "muted" }, "not found in this library"));
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
    await Promise.all([this.refreshTop(), this.refreshExtras()]);
  }

  modesSection() {
    this.modesHead = h("h3", {}, "Modes");
    this.modesNote = h("p", { id: "modes-note", class: "muted", hidden: true });
    this.modeGrid = h("div", { id: "mode-grid", class: "gait-grid" });
    this.modesMore = h("p", { id: "modes-more", class: "muted", hidden: true });
    this.modesBox = h("section", { id: "modes", hidden: true }, this.modesHead, this.modesNote, this.modeGrid, this.modesMore);
    return this.modesBox;
  }

  archiveSection() {
    this.archiveHead = h("h3", { id: "archive-head" }, "Archive");
    this.heatCanvas = h("canvas", { id: "archive-map", class: "plot heat" });
    this.progressCanvas = h("canvas", { id: "archive-progress", class: "plot" });
    this.archiveStats = h("p", { id: "archive-stats", class: "meta" });
    // offsetX/Y: from the canvas's padding edge, where its drawing starts (inside the border)
    this.heatCanvas.addEventListener("click", (e) => {
      const elite = this.eliteAt(e.offsetX, e.offsetY);
      if (elite) location.hash = gaitHref(elite.gait);
    });
    this.heatCanvas.addEventListener("mousemove", (e) => {
      const elite = this.eliteAt(e.offsetX, e.offsetY);
      this.heatCanvas.title = elite
        ? `cell [${elite.cell}]: ${elite.gait}, score ${fmt(elite.score, 4)}; ${this.heat.archive.names.map((n, k) => `${n} ${fmt(elite.measures[k])}`).join(", ")} (click to open)`
        : "";
      this.heatCanvas.style.cursor = elite ? "pointer" : "default";
    });
    this.archiveBox = h("section", { id: "archive", hidden: true }, this.archiveHead,
      h("div", { class: "plots" },
        h("div", {}, h("h3", {}, "Best score per cell (blank: empty; click a cell to open its elite)"), this.heatCanvas),
        h("div", {}, h("h3", {}, "Coverage and QD-score against evaluations"), this.progressCanvas, this.archiveStats)));
    return this.archiveBox;
  }

  // The elite of the cell under (u, v) CSS px of the heat map, or null (an empty cell, outside).
  eliteAt(u, v) {
    if (!this.heat) return null;
    const c = this.heat.cellAt(u, v);
    return c ? this.elites.get(`${c[0]},${c[1]}`) || null : null;
  }

  // The modes and the archive: a tuning run has neither; only a search has an archive. Calls
  // arriving while one is in flight (a running search commits often) make one more after it.
  async refreshExtras() {
    if (this.extrasBusy) { this.extrasAgain = true; return; }
    this.extrasBusy = true;
    try {
      const kind = this.run.kind;
      this.extrasNote.hidden = kind !== "tune";
      this.extrasNote.textContent = kind === "tune" ? "Modes and the archive are not available for a tuning run (its gaits are one gait's tuned copies)." : "";
      this.modesBox.hidden = kind === "tune";
      this.archiveBox.hidden = kind !== "search";
      await Promise.all([kind !== "tune" ? this.refreshModes() : null, kind === "search" ? this.refreshArchive() : null]);
    } finally {
      this.extrasBusy = false;
    }
    if (this.extrasAgain) {
      this.extrasAgain = false;
      await this.refreshExtras();
    }
  }

  async refreshModes() {
    const res = await attempt(() => this.app.api.request("modes", { run: this.runId, n: MODES_SHOWN }));
    if (!res) return;
    const shown = res.modes.length;
    this.modesHead.textContent = `Modes: ${res.total} among the gaits scoring at least ${fmt(res.threshold)}` +
      (res.total ? " (each its best gait, best first)" : "");
    let note = "";
    if (!res.total && res.missing) note = `This run was stored before sanlab computed behaviour descriptors: its ${res.missing} useful gaits have none, so they cannot be grouped (search again to get them).`;
    else if (!res.total) note = "No useful gaits to group yet.";
    else if (res.missing) note = `${res.missing} useful gaits stored without descriptors are left out.`;
    this.modesNote.textContent = note;
    this.modesNote.hidden = !note;
    this.modesMore.hidden = res.total <= shown;
    this.modesMore.textContent = res.total > shown ? `and ${res.total - shown} more modes (\`sanlab modes ${res.run_id} --top ${res.total}\` lists them all)` : "";
    const keep = new Map();
    for (const m of res.modes) {
      let t = this.modeTiles.get(m.best);
      if (!t) {
        t = new ModeTile(this.app, m, (id) => this.playback(id));
        t.load();
      }
      t.gait = { gait: m.best, id: m.best, mode: m };
      t.el.dataset.mode = m.name;
      t.setCaption(t.gait);
      keep.set(m.best, t);
    }
    this.modeTiles = keep;
    this.modeGrid.replaceChildren(...[...keep.values()].map((t) => t.el));
  }

  async refreshArchive() {
    const a = await attempt(() => this.app.api.request("archive", { run: this.runId }));
    if (!a) return;
    const [bx, by] = a.bins;
    const cells = `${bx} × ${by} cells of ${a.names[0]} by ${a.names[1]}`;
    this.archiveHead.textContent = a.own ? `Archive (MAP-Elites): ${cells}` : `Archive, binned into the default grid: ${cells}`;
    this.elites = new Map(a.elites.map((e) => [`${e.cell[0]},${e.cell[1]}`, e]));
    this.heat = new HeatMap(this.heatCanvas, a);
    this.heat.draw();
    this.archive = a;
    drawProgress(this.progressCanvas, a.progress);
    const s = a.stats;
    this.archiveStats.textContent = `coverage ${(100 * s.coverage).toFixed(1)} % (${s.elites} of ${s.cells} cells filled) · QD-score ${fmt(s.qd_score, 4)}` +
      (a.own ? "" : " · the run is not a MAP-Elites search: its evaluations are binned into the default grid");
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
        t = new Tile(this.app, g, (id) => this.playback(id));
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
    for (const t of this.modeTiles.values()) t.draw(now);
    if (this.heat && Math.max(1, Math.round(this.heatCanvas.clientWidth)) !== this.heat.drawnW) {
      this.heat.draw();
      drawProgress(this.progressCanvas, this.archive.progress);
    }
  }
}
