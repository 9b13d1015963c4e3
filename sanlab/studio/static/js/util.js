// Small helpers shared by the views: building elements, formatting numbers, showing errors.

// h("div", {class: "x", onclick: fn}, child, "text", ...) -> an element.
export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === undefined || v === null || v === false) continue;
    if (k.startsWith("on")) el.addEventListener(k.slice(2), v);
    else if (k === "class") el.className = v;
    else if (k === "dataset") Object.assign(el.dataset, v);
    else if (k in el && typeof v !== "string") el[k] = v;
    else el.setAttribute(k, v === true ? "" : v);
  }
  for (const c of children.flat()) {
    if (c === null || c === undefined || c === false) continue;
    el.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return el;
}

export function fmt(x, digits = 3) {
  if (x === null || x === undefined || Number.isNaN(x)) return "–";
  if (typeof x !== "number") return String(x);
  return Math.abs(x) >= 1000 ? x.toFixed(0) : x.toPrecision(digits);
}

// A run's progress as the library counts it (Run.progress): "32/32 evaluated", "16/16 trials".
export function progress(run) {
  const p = run.progress;
  return `${p.done}/${p.planned ?? "?"} ${p.unit}`;
}

export function fmtDate(iso) {
  return iso ? iso.slice(0, 19).replace("T", " ") : "–";
}

export function flags(g) {
  const out = [];
  if (g.fell) out.push("fell");
  if (g.nonfinite) out.push("non-finite");
  if (g.reproduced === false) out.push("not reproduced");
  if (g.resolution_dependent) out.push("resolution-dependent");
  if (g.audit === "undecided") out.push("audit undecided");
  return out.join(", ") || "–";
}

// An id from the address bar as a heading shows it: a real one whole, anything longer than an id
// (a pasted page, 100,000 characters) cut, with its length.
export function shortId(id, keep = 24) {
  const s = String(id);
  return s.length <= keep ? s : `${s.slice(0, keep)}… (${s.length.toLocaleString("en")} characters)`;
}

// Hash routes use gait ids (RUN/RANK, RUN#IDX) as one path segment.
export const gaitHref = (id, view = "gait") => `#/${view}/${encodeURIComponent(id)}`;

// Errors are shown at the top of the page until dismissed (the last five).
export function showError(message) {
  const box = document.getElementById("errors");
  const item = h("div", { class: "error", role: "alert" },
    h("span", { class: "error-text" }, message),
    h("button", { class: "dismiss", title: "dismiss", onclick: () => item.remove() }, "×"));
  box.append(item);
  while (box.children.length > 5) box.firstChild.remove();
  return item;
}

export function clearErrors() {
  document.getElementById("errors").replaceChildren();
}

// Run a promise-returning action, showing its error (if any) in the page.
export async function attempt(fn) {
  try {
    return await fn();
  } catch (e) {
    showError(e.message || String(e));
    return undefined;
  }
}

// Save a Blob under a file name (the browser's download).
export function download(blob, name) {
  const url = URL.createObjectURL(blob);
  const a = h("a", { href: url, download: name });
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
}
