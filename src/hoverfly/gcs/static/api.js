// The page's one door to the backend: JSON calls with the start token, the telemetry WebSocket
// (reconnecting), and the message list where every error ends up in plain words.
//
// The token comes from the URL the backend printed (?token=T, as Jupyter does). It is kept in
// sessionStorage so a reload of the same tab still works, and never written anywhere else.

const params = new URLSearchParams(location.search);
export const token = params.get("token") || sessionStorage.getItem("hoverfly-token") || "";
if (params.get("token")) sessionStorage.setItem("hoverfly-token", params.get("token"));

export class ApiError extends Error {}

// ---- messages -----------------------------------------------------------------------------

const MAX_MESSAGES = 5;

// An error stays until it is closed or pushed out by newer ones: a message that fades before
// the user looks is as good as none. Repeats of the same text are merged, so a link that keeps
// failing does not bury everything else.
export function showMessage(text, kind = "error") {
  const box = document.getElementById("messages");
  for (const el of box.children) {
    if (el.dataset.text === text) {
      const n = Number(el.dataset.count || 1) + 1;
      el.dataset.count = n;
      el.querySelector(".text").textContent = `${text} (×${n})`;
      box.prepend(el);
      return el;
    }
  }
  const el = document.createElement("div");
  el.className = `msg ${kind}`;
  el.dataset.text = text;
  const span = document.createElement("span");
  span.className = "text";
  span.textContent = text;
  const close = document.createElement("button");
  close.className = "close";
  close.textContent = "×";
  close.title = "dismiss";
  close.onclick = () => el.remove();
  el.append(span, close);
  box.prepend(el);
  while (box.children.length > MAX_MESSAGES) box.lastElementChild.remove();
  if (kind === "info") setTimeout(() => el.remove(), 4000);
  return el;
}

export function clearMessage(text) {
  for (const el of document.getElementById("messages").children) {
    if (el.dataset.text === text) el.remove();
  }
}

// ---- JSON API -----------------------------------------------------------------------------

const NO_BACKEND = "cannot reach the ground station backend: is `hoverfly gcs` still running?";

// Every failure becomes an ApiError whose message is the backend's own {"error": "..."} text when
// it sent one, so callers only need `catch (e) { showMessage(e.message) }`.
export async function api(method, path, body, { quiet = false, text = false } = {}) {
  const opts = { method, headers: { "X-Hoverfly-Token": token } };
  if (body !== undefined) {
    opts.headers["Content-Type"] = "application/json";
    opts.body = JSON.stringify(body);
  }
  let res;
  try {
    res = await fetch(path, opts);
  } catch (e) {
    const err = new ApiError(NO_BACKEND);
    if (!quiet) showMessage(err.message);
    throw err;
  }
  if (res.ok) clearMessage(NO_BACKEND);
  const raw = await res.text();
  let data = raw;
  const isJson = (res.headers.get("content-type") || "").includes("json");
  if (isJson && raw) {
    try { data = JSON.parse(raw); } catch (e) { data = raw; }
  }
  if (!res.ok) {
    let why = (data && typeof data === "object" && data.error) ? data.error : "";
    if (!why) why = (typeof data === "string" && data && data.length < 200) ? data : res.statusText;
    if ((res.status === 401 || res.status === 403) && !why.includes("URL")) {
      why = `${why || "refused"} (open the page from the link \`hoverfly gcs\` printed: it carries the token)`;
    }
    const err = new ApiError(`${method} ${path}: ${why}`);
    err.status = res.status;
    err.reason = why;
    if (!quiet) showMessage(err.message);
    throw err;
  }
  return text ? raw : data;
}

// ---- telemetry WebSocket --------------------------------------------------------------------

// One socket for the page's life: telemetry in, sticks out. It reconnects with a capped backoff,
// and says so, so nothing sits waiting on a dead link.
export class Socket {
  constructor() {
    this.ws = null;
    this.open = false;
    this.listeners = { telemetry: [], state: [], message: [], error: [] };
    this.retryMs = 500;
    this.closedByPage = false;
    this.rxCount = 0;
    this.lastRxMs = 0;
  }

  on(kind, fn) { this.listeners[kind].push(fn); }

  emit(kind, arg) {
    for (const fn of this.listeners[kind]) {
      try { fn(arg); } catch (e) { console.error(e); }
    }
  }

  connect() {
    const proto = location.protocol === "https:" ? "wss:" : "ws:";
    const url = `${proto}//${location.host}/ws?token=${encodeURIComponent(token)}`;
    let ws;
    try {
      ws = new WebSocket(url);
    } catch (e) {
      this.scheduleRetry();
      return;
    }
    this.ws = ws;
    ws.onopen = () => {
      this.open = true;
      this.retryMs = 500;
      this.emit("state", true);
    };
    ws.onmessage = (ev) => {
      let msg;
      try { msg = JSON.parse(ev.data); } catch (e) { return; }
      this.rxCount++;
      this.lastRxMs = performance.now();
      if (msg.t === "telemetry") this.emit("telemetry", msg);
      else if (msg.t === "error") {
        showMessage(msg.error || "error from the ground station");
        this.emit("error", msg.error || "");
      }
      else this.emit("message", msg);
    };
    ws.onclose = () => {
      const was = this.open;
      this.open = false;
      this.ws = null;
      if (was) this.emit("state", false);
      if (!this.closedByPage) this.scheduleRetry();
    };
    ws.onerror = () => {};
  }

  scheduleRetry() {
    setTimeout(() => this.connect(), this.retryMs);
    this.retryMs = Math.min(this.retryMs * 2, 4000);
  }

  send(obj) {
    if (!this.open || !this.ws) return false;
    try {
      this.ws.send(JSON.stringify(obj));
      return true;
    } catch (e) {
      return false;
    }
  }

  close() {
    this.closedByPage = true;
    if (this.ws) this.ws.close();
  }
}
