// The studio page: routes (#/, #/run/ID, #/gait/ID, #/live/ID, #/design/ID), the jobs panel, the one
// animation loop, and `window.studio` (the views and the API, for tests and the console).

import { Api } from "./api.js";
import { DesignView } from "./design.js";
import { GaitView } from "./gait.js";
import { LibraryView } from "./library.js";
import { LiveView } from "./live.js";
import { RunView } from "./run.js";
import { gaitHref, h, showError } from "./util.js";

class JobsPanel {
  constructor(app, el) {
    this.app = app;
    this.el = el;
    this.jobs = new Map();
  }

  update(job) {
    this.jobs.set(job.id, job);
    this.render();
  }

  render() {
    const items = [...this.jobs.values()].reverse().slice(0, 6).map((j) => {
      const frac = j.total ? Math.min(1, j.done / j.total) : 0;
      const link = j.status === "done" && j.result
        ? (j.result.run_id ? h("a", { href: `#/run/${j.result.run_id}`, class: "job-result" }, `run ${j.result.run_id}`)
          : h("a", { href: gaitHref(j.result.gait), class: "job-result" }, `gait ${j.result.gait}`))
        : j.run_id ? h("a", { href: `#/run/${j.run_id}` }, `run ${j.run_id}`) : null;
      const cancel = j.status === "queued" || j.status === "running"
        ? h("button", { class: "job-cancel", title: "stop after the batch in flight (resumable)",
          onclick: () => this.app.api.request("job.cancel", { job: j.id }).catch((e) => showError(e.message)) }, "Cancel")
        : null;
      return h("div", { class: `job job-${j.status}`, dataset: { job: j.id, status: j.status } },
        h("div", { class: "job-label" }, j.label, " · ", h("b", {}, j.status), " ", link,
          j.error ? h("span", { class: "job-error" }, ` ${j.error}`) : null,
          j.resume ? h("span", { class: "muted" }, " · continue with ", h("code", { class: "job-resume" }, j.resume)) : null),
        h("progress", { max: 1, value: frac }),
        h("span", { class: "muted mono" }, `${j.done ?? 0}/${j.total ?? "?"}` +
          (j.best !== null && j.best !== undefined ? ` · best ${j.best.toPrecision(3)}` : "") +
          (j.rate ? ` · ${j.rate.toFixed(0)}/s` : "")), cancel);
    });
    this.el.replaceChildren(...items);
    this.el.hidden = items.length === 0;
  }
}

class App {
  constructor() {
    const proto = location.protocol === "https:" ? "wss:" : "ws:";
    this.api = new Api(`${proto}//${location.host}/ws`);
    this.root = document.getElementById("view");
    this.jobs = new JobsPanel(this, document.getElementById("jobs"));
    this.view = null;
    this.api.on("error", (m) => showError(m.error));
    this.api.on("job", (m) => {
      this.jobs.update(m.job);
      if (m.job.status === "failed") showError(`${m.job.label}: ${m.job.error}`);
    });
    this.api.on("library", (m) => this.view && this.view.onLibrary && this.view.onLibrary(m));
    this.api.on("status", (s) => {
      document.getElementById("conn").textContent = s.connected ? "" : "disconnected: reconnecting…";
    });
    // Until the first reply (hello) has come, start() does the routing.
    this.started = false;
    window.addEventListener("hashchange", () => this.started && this.route());
    const loop = (now) => {
      if (this.view && this.view.tick) {
        try { this.view.tick(now); } catch (e) { console.error(e); }
      }
      requestAnimationFrame(loop);
    };
    requestAnimationFrame(loop);
  }

  async start() {
    this.info = await this.api.request("hello");
    document.getElementById("library-path").textContent = this.info.library;
    document.getElementById("version").textContent = `sanlab ${this.info.version}`;
    for (const j of await this.api.request("jobs")) this.jobs.update(j);
    this.started = true;
    this.route();
  }

  // Views mark the body when they have what they need (tests wait for it).
  loaded(name) {
    document.body.dataset.view = name;
  }

  route() {
    const parts = location.hash.replace(/^#\/?/, "").split("/");
    const [kind, arg] = [parts[0], decodeURIComponent(parts.slice(1).join("/"))];
    if (this.view && this.view.unmount) this.view.unmount();
    document.body.dataset.view = "loading";
    if (kind === "run" && arg) this.view = new RunView(this, arg);
    else if (kind === "gait" && arg) this.view = new GaitView(this, arg);
    else if (kind === "live" && arg) this.view = new LiveView(this, arg);
    else if (kind === "design" && arg) this.view = new DesignView(this, arg);
    else this.view = new LibraryView(this);
    window.studio.view = this.view;
    this.view.mount(this.root);
  }
}

const app = new App();
window.studio = { app, api: app.api, view: null, showError };
app.start().catch((e) => showError(e.message || String(e)));
