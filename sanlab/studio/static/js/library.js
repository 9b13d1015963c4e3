// The library view: every run, filterable; the designs (`sanlab design`), when there are any;
// and a form to start a phase-1 search.

import { attempt, fmt, fmtDate, h, progress, showError } from "./util.js";

export class LibraryView {
  constructor(app) {
    this.app = app;
    this.runs = [];
    this.designs = [];
    this.filter = { text: "", kind: "" };
  }

  async mount(root) {
    this.root = root;
    this.table = h("tbody");
    this.count = h("span", { class: "muted" });
    const text = h("input", { id: "filter", type: "search", placeholder: "filter: creature, run id, status…",
      oninput: (e) => { this.filter.text = e.target.value.trim().toLowerCase(); this.renderRows(); } });
    const kind = h("select", { id: "filter-kind", onchange: (e) => { this.filter.kind = e.target.value; this.renderRows(); } },
      h("option", { value: "" }, "all kinds"), h("option", { value: "search" }, "search"),
      h("option", { value: "tune" }, "tune"), h("option", { value: "import" }, "import"));
    root.replaceChildren(
      h("section", {},
        h("h2", {}, "Library ", this.count),
        h("div", { class: "toolbar" }, text, kind),
        h("table", { id: "runs", class: "grid-table" },
          h("thead", {}, h("tr", {}, ...["run", "kind", "creature", "seed", "progress", "best score", "best speed (cm/s)", "date (UTC)", "parent", "status"].map((c) => h("th", {}, c)))),
          this.table)),
      this.designsSection(),
      this.searchForm());
    await this.refresh();
    this.app.loaded("library");
  }

  async refresh() {
    const [runs, designs] = await Promise.all([attempt(() => this.app.api.request("runs")),
      attempt(() => this.app.api.request("designs"))]);
    if (designs) {
      this.designs = designs;
      this.renderDesigns();
    }
    if (!runs) return;
    this.runs = runs;
    this.renderRows();
  }

  designsSection() {
    this.designTable = h("tbody");
    this.designsBox = h("section", { id: "designs-box", hidden: true },
      h("h2", {}, "Designs"),
      h("p", { class: "muted" }, "Free numbers of a creature file searched with its controllers (`sanlab design`, §6.3); a design's bodies as a scatter."),
      h("table", { id: "designs", class: "grid-table" },
        h("thead", {}, h("tr", {}, ...["design", "creature", "file", "free numbers", "bodies", "best (cm/s)", "reference (cm/s)", "date (UTC)", "status"].map((c) => h("th", {}, c)))),
        this.designTable));
    return this.designsBox;
  }

  renderDesigns() {
    this.designsBox.hidden = this.designs.length === 0;
    this.designTable.replaceChildren(...this.designs.map((d) => h("tr", { class: "design-row", dataset: { design: d.design_id },
      onclick: () => (location.hash = `#/design/${d.design_id}`) },
    h("td", {}, h("a", { href: `#/design/${d.design_id}` }, d.design_id)),
    h("td", {}, d.creature),
    h("td", { class: "mono" }, d.source),
    h("td", {}, d.free.join(", ")),
    h("td", {}, `${d.bodies}/${d.planned ?? "?"}`),
    h("td", {}, fmt(d.best_speed_cm_s)),
    h("td", {}, fmt(d.reference_cm_s)),
    h("td", {}, fmtDate(d.created)),
    h("td", { class: `status-${d.status}` }, d.status))));
  }

  onLibrary() {
    this.refresh();
  }

  renderRows() {
    const f = this.filter;
    const rows = this.runs.filter((r) => (!f.kind || r.kind === f.kind) &&
      (!f.text || [r.run_id, r.creature, r.kind, r.status, r.parent || ""].some((s) => s.toLowerCase().includes(f.text))));
    this.count.textContent = `${rows.length} of ${this.runs.length} runs`;
    this.table.replaceChildren(...rows.map((r) => h("tr", { class: "run-row", dataset: { run: r.run_id }, onclick: () => (location.hash = `#/run/${r.run_id}`) },
      h("td", {}, h("a", { href: `#/run/${r.run_id}` }, r.run_id)),
      h("td", {}, r.kind + (r.method ? ` (${r.method})` : "")),
      h("td", {}, r.creature),
      h("td", {}, r.seed ?? "–"),
      h("td", {}, progress(r)),
      h("td", {}, fmt(r.best_score)),
      h("td", {}, fmt(r.best_speed_cm_s)),
      h("td", {}, fmtDate(r.created)),
      h("td", {}, r.parent ? h("a", { href: `#/gait/${encodeURIComponent(r.parent)}`, onclick: (e) => e.stopPropagation() }, r.parent) : "–"),
      h("td", { class: `status-${r.status}` }, r.status))));
  }

  searchForm() {
    const builtins = this.app.info.builtins;
    const creature = h("select", { id: "search-creature" },
      ...builtins.map((b) => h("option", { value: b.name }, `${b.name} (${b.links} links${b.eyes ? ", eyes" : ""})`)));
    const file = h("input", { id: "search-file", type: "file", accept: ".toml,text/plain" });
    const fileInfo = h("span", { id: "search-file-info", class: "muted" });
    const controllers = h("input", { id: "search-n", type: "number", min: 1, value: 200, size: 6 });
    const seconds = h("input", { id: "search-seconds", type: "number", min: 0.05, step: "any", placeholder: "creature's", size: 8 });
    const seed = h("input", { id: "search-seed", type: "number", min: 0, value: 0, size: 6 });
    let upload = null;
    file.addEventListener("change", async () => {
      upload = null;
      fileInfo.textContent = "";
      const f = file.files[0];
      if (!f) return;
      const text = await f.text();
      try {
        const c = await this.app.api.request("check", { text, filename: f.name });
        upload = { text, filename: f.name };
        fileInfo.textContent = `ok ${c.name}: ${c.links} links, ${c.sensors} sensors, ${c.actuators} actuators`;
      } catch (e) {
        fileInfo.textContent = "not a valid creature file";
        showError(e.message);
      }
    });
    const start = async () => {
      const args = { controllers: Number(controllers.value), seed: Number(seed.value) };
      if (seconds.value !== "") args.seconds = Number(seconds.value);
      if (file.files[0]) {
        if (!upload) { showError(`${file.files[0].name}: not a valid creature file (see the message above)`); return; }
        Object.assign(args, upload);
      } else {
        args.creature = creature.value;
      }
      const job = await attempt(() => this.app.api.request("search", args));
      if (job) this.app.jobs.update(job);
    };
    return h("section", { class: "work" },
      h("h2", {}, "Start a search (phase 1)"),
      h("p", { class: "muted" }, "Random sensor-actuator networks on a built-in creature or your own file, stored in this library as they are evaluated (paper §5.2)."),
      h("div", { class: "form" },
        h("label", {}, "creature ", creature),
        h("label", {}, "or a file ", file), fileInfo,
        h("label", {}, "controllers ", controllers),
        h("label", {}, "seconds ", seconds),
        h("label", {}, "seed ", seed),
        h("button", { id: "search-start", onclick: start }, "Start search")));
  }
}
