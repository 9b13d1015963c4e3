// The page's one WebSocket to the studio: requests with ids and their replies, and pushes.
//
//   const data = await api.request("runs");          // rejects with Error(one line) on failure
//   api.on("library", msg => ...);                    // pushed messages by type
//
// It reconnects on its own (the server may be restarted); requests made while disconnected wait.
// At most MAX_IN_FLIGHT requests are out at once, the rest wait their turn: the server answers
// more than its own bound (sanlab/studio/app.py, MAX_IN_FLIGHT = 16) with "busy", and a run page
// asks for a dozen mode animations at once. The margin leaves room for notifications.
const MAX_IN_FLIGHT = 12;

export class Api {
  constructor(url) {
    this.url = url;
    this.nextId = 1;
    this.pending = new Map();
    this.handlers = new Map();
    this.queue = [];
    this.waiting = []; // requests not yet sent: [id, text, {resolve, reject}]
    this.ws = null;
    this.connected = false;
    this.connect();
  }

  connect() {
    const ws = new WebSocket(this.url);
    this.ws = ws;
    ws.onopen = () => {
      this.connected = true;
      this.emit("status", { connected: true });
      for (const text of this.queue.splice(0)) ws.send(text);
    };
    ws.onmessage = (ev) => this.receive(ev.data);
    ws.onclose = () => {
      const was = this.connected;
      this.connected = false;
      for (const [, p] of this.pending) p.reject(new Error("the connection to the studio was lost"));
      this.pending.clear();
      for (const [, , p] of this.waiting.splice(0)) p.reject(new Error("the connection to the studio was lost"));
      if (was) this.emit("status", { connected: false });
      setTimeout(() => this.connect(), 1000);
    };
  }

  receive(text) {
    let msg;
    try {
      msg = JSON.parse(text);
    } catch (e) {
      this.emit("error", { error: "the studio sent something that is not JSON" });
      return;
    }
    if (msg.type === "reply") {
      const p = this.pending.get(msg.id);
      if (p) {
        this.pending.delete(msg.id);
        this.sendWaiting();
        if (msg.ok) p.resolve(msg.data);
        else p.reject(new Error(msg.error));
      } else if (!msg.ok) {
        this.emit("error", { error: msg.error }); // an answer to a message without id
      }
      return;
    }
    this.emit(msg.type, msg);
  }

  send(text) {
    if (this.connected) this.ws.send(text);
    else this.queue.push(text);
  }

  request(op, args = {}) {
    const id = this.nextId++;
    return new Promise((resolve, reject) => {
      this.waiting.push([id, JSON.stringify({ id, op, ...args }), { resolve, reject }]);
      this.sendWaiting();
    });
  }

  sendWaiting() {
    while (this.waiting.length && this.pending.size < MAX_IN_FLIGHT) {
      const [id, text, p] = this.waiting.shift();
      this.pending.set(id, p);
      this.send(text);
    }
  }

  // Fire and forget (no reply on success; an error still comes back and is shown).
  notify(op, args = {}) {
    this.send(JSON.stringify({ op, ...args }));
  }

  // Send a raw text message (for tests of the server's handling of malformed input).
  sendRaw(text) {
    this.send(text);
  }

  on(type, fn) {
    if (!this.handlers.has(type)) this.handlers.set(type, new Set());
    this.handlers.get(type).add(fn);
    return () => this.handlers.get(type).delete(fn);
  }

  emit(type, msg) {
    for (const fn of this.handlers.get(type) || []) fn(msg);
  }
}
