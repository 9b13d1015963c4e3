// A design (`sanlab design`, §6.3): its bodies as a scatter of two of their numbers (free
// numbers in the file's units, or the score), each filled by its score, the robust tuned speed
// (cm/s) on the search's seed; the reference (the file's defaults) and the chosen body marked.
// A click on a point, or a row of the table under it, opens that body's gait in the gait view.

import { Scatter } from "./plots.js";
import { attempt, fmt, fmtDate, gaitHref, h, shortId } from "./util.js";

const SCORE = "score";

export class DesignView {
  constructor(app, designId) {
    this.app = app;
    this.designId = designId;
    this.design = null;
    this.axes = null; // [x, y]: a free number's index (as a string) or "score"
  }

  async mount(root) {
    this.root = root;
    this.head = h("div");
    this.xSel = h("select", { id: "design-x", onchange: () => this.setAxes([this.xSel.value, this.ySel.value]) });
    this.ySel = h("select", { id: "design-y", onchange: () => this.setAxes([this.xSel.value, this.ySel.value]) });
    this.canvas = h("canvas", { id: "design-plot", class: "plot scatter" });
    this.scatter = new Scatter(this.canvas);
    this.canvas.addEventListener("click", (e) => {
      const p = this.pointAt(e.offsetX, e.offsetY);
      if (p && p.open) location.hash = gaitHref(p.open);
    });
    this.canvas.addEventListener("mousemove", (e) => {
      const p = this.pointAt(e.offsetX, e.offsetY);
      this.canvas.title = p ? this.describe(p) : "";
      this.canvas.style.cursor = p && p.open ? "pointer" : "default";
    });
    this.table = h("table", { id: "design-bodies", class: "grid-table" });
    root.replaceChildren(
      this.head,
      h("div", { class: "toolbar" }, h("label", {}, "x ", this.xSel), h("label", {}, "y ", this.ySel)),
      this.canvas,
      h("p", { class: "meta", id: "design-legend" },
        "Each body of the search is a point filled by its robust tuned speed on the search's seed (hollow: pruned after phase 1); ",
        h("b", { style: "color: #1e3a6e" }, "the square"), " is the reference (the file's defaults), ",
        h("b", { style: "color: #d62728" }, "the ring"), " the chosen body (the best on the validation seeds). Click a point to open its gait."),
      h("h3", {}, "Bodies"),
      this.table);
    await this.refresh();
    this.app.loaded(this.design ? "design" : "design-error");
  }

  async refresh() {
    const d = await attempt(() => this.app.api.request("design", { design: this.designId }));
    if (!d) {
      if (!this.design) this.head.replaceChildren(h("h2", {}, `Design ${shortId(this.designId)}`), h("p", { class: "muted" }, "cannot show this design (see the message above)"));
      return;
    }
    this.design = d;
    const s = d.settings, pts = d.points;
    const ref = pts.find((p) => p.reference), chosen = pts.find((p) => p.chosen);
    const bodies = pts.filter((p) => !p.reference).length;
    const seeds = d.seeds.join(", ");
    this.head.replaceChildren(
      h("h2", {}, `Design ${d.design_id}: ${d.creature} `, h("span", { class: `status-${d.status}` }, d.status)),
      h("p", { class: "meta", id: "design-meta" },
        `${d.source} · ${s.strategy} · ${bodies} of ${s.designs} bodies scored · ${s.controllers} SANs, ${s.top} chain(s) of ${s.trials} trials a body · ` +
        `seed ${d.seed}, validated on seed${d.seeds.length === 1 ? "" : "s"} ${seeds} · ${fmtDate(d.created)} UTC`),
      h("p", { class: "meta", id: "design-summary" },
        chosen
          ? `chosen: body ${chosen.body}, ${fmt(chosen.validation_mean)} cm/s on the validation seeds; the reference ${fmt(ref?.validation_mean)} cm/s`
          : `no body chosen yet${d.status === "running" ? " (running)" : d.status === "interrupted" ? " (interrupted: run the same command again to continue)" : ""}` +
            (ref ? `; the reference ${fmt(ref.score)} cm/s on the search's seed` : "")));
    const options = () => [...d.free.map((f, k) => h("option", { value: String(k) }, f.unit ? `${f.name} (${f.unit})` : f.name)),
      h("option", { value: SCORE }, "robust tuned speed (cm/s)")];
    this.xSel.replaceChildren(...options());
    this.ySel.replaceChildren(...options());
    const keep = this.axes && this.axes.every((a) => a === SCORE || Number(a) < d.free.length);
    this.setAxes(keep ? this.axes : ["0", d.free.length > 1 ? "1" : SCORE]);
    this.renderTable();
  }

  // The axes [x, y]: a free number's index (as a string) or "score"; redraws.
  setAxes(axes) {
    this.axes = axes;
    this.xSel.value = axes[0];
    this.ySel.value = axes[1];
    const d = this.design;
    const axis = (a) => {
      if (a === SCORE) {
        const top = Math.max(0, ...d.points.map((p) => p.score ?? 0));
        return { label: "robust tuned speed (cm/s)", lo: 0, hi: top > 0 ? top * 1.05 : 1, of: (p) => p.score ?? 0 };
      }
      const f = d.free[Number(a)], span = f.max - f.min || 1;
      return { label: f.unit ? `${f.name} (${f.unit})` : f.name, lo: f.min - 0.04 * span, hi: f.max + 0.04 * span,
        of: (p) => p.values[Number(a)] };
    };
    const [x, y] = axes.map(axis);
    this.scatter.set({ x, y, points: d.points.map((p) => ({ ...p, x: x.of(p), y: y.of(p) })) });
    this.scatter.draw();
  }

  // The body under (u, v) CSS px of the scatter, or null.
  pointAt(u, v) {
    const i = this.scatter.pointAt(u, v);
    return i < 0 ? null : this.design.points[i];
  }

  // The body's point centre (CSS px of the scatter): for tests.
  pointPx(body) {
    return this.scatter.px(this.design.points.findIndex((p) => p.body === body));
  }

  describe(p) {
    const d = this.design;
    const values = d.free.map((f, k) => `${f.name} ${fmt(p.values[k], 4)}${f.unit ? ` ${f.unit}` : ""}`).join(", ");
    const mark = p.reference ? " (reference)" : p.chosen ? " (chosen)" : "";
    const why = p.invalid ? ` (invalid: ${p.invalid})` : p.pruned ? " (pruned)" : "";
    return `body ${p.body}${mark}: ${fmt(p.score)} cm/s${why}` +
      (p.validation_mean !== null ? `, ${fmt(p.validation_mean)} on the validation seeds` : "") + `; ${values}` +
      (p.open ? ` (click to open ${p.open_kind === "robust" ? "its robust gait" : p.open_kind === "tuned" ? "its best tuned gait" : "its best phase-1 gait"} ${p.open})` : "");
  }

  renderTable() {
    const d = this.design;
    const head = h("thead", {}, h("tr", {}, ...["body", ...d.free.map((f) => (f.unit ? `${f.name} (${f.unit})` : f.name)),
      `seed ${d.seed} (cm/s)`, "validation (cm/s)", "gait"].map((c) => h("th", {}, c))));
    const rows = d.points.map((p) => h("tr", { class: `body-row${p.chosen ? " chosen" : ""}`, dataset: { body: p.body },
      onclick: () => p.open && (location.hash = gaitHref(p.open)) },
    h("td", {}, p.body + (p.chosen ? " (chosen)" : "")),
    ...p.values.map((v) => h("td", { class: "mono" }, fmt(v, 4))),
    h("td", p.invalid ? { title: p.invalid } : {}, p.invalid ? "0 (invalid)" : p.pruned ? "0 (pruned)" : fmt(p.score)),
    h("td", {}, fmt(p.validation_mean)),
    h("td", {}, p.open ? h("a", { href: gaitHref(p.open), onclick: (e) => e.stopPropagation() }, p.open) : "–",
      p.open && p.open_kind !== "robust" ? h("span", { class: "muted" }, ` (${p.open_kind})`) : null)));
    this.table.replaceChildren(head, h("tbody", {}, ...rows));
  }

  onLibrary(msg) {
    const mine = (msg.designs || []).find((r) => r[0] === this.design?.design_id);
    if (mine && (mine[1] !== this.design.status || mine[2] !== this.scoreCount())) this.refresh();
  }

  scoreCount() {
    return this.design.points.reduce((n, p) => n + (p.score !== null ? 1 : 0) + Object.keys(p.validation).length, 0);
  }

  tick() {
    if (this.design && Math.max(1, Math.round(this.canvas.clientWidth)) !== this.scatter.drawnW) this.scatter.draw();
  }
}
