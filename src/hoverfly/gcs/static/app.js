// The ground station page: navigation, the top bar, the Status screen, and the wiring that hands
// each screen the status (about once a second, over the WebSocket or else polled over HTTP) and
// the telemetry (50 Hz over the WebSocket). Each other screen lives in its own module with an
// init(ctx) function.

import { api, showMessage, clearMessage, Socket } from "./api.js";
import { drawHorizon } from "./horizon.js";
import { initParams } from "./params.js";
import { initReceiver } from "./receiver.js";
import { initMotors } from "./motors.js";
import { initSensors } from "./sensors.js";
import { initMaint } from "./maint.js";
import { initFly } from "./fly.js";
import { initLogs } from "./logs.js";

const $ = (id) => document.getElementById(id);

const STATUS_PERIOD_MS = 1000;
// The controller is judged unreachable when telemetry has been silent this long: at 50 Hz that is
// 25 missed messages, far beyond scheduling noise.
const TELEMETRY_STALE_MS = 500;

const ctx = {
  api,
  showMessage,
  socket: new Socket(),
  status: null,
  telemetry: null,
  screen: "status",
  statusHandlers: [],
  telemetryHandlers: [],
  screenHandlers: [],
  linkHandlers: [],
  onStatus(fn) { this.statusHandlers.push(fn); },
  onTelemetry(fn) { this.telemetryHandlers.push(fn); },
  onScreen(fn) { this.screenHandlers.push(fn); },
  onLink(fn) { this.linkHandlers.push(fn); },
  // True when the page can command the controller: socket up, backend's link up.
  linkUp() {
    return this.socket.open && !!(this.status && this.status.link && this.status.link.connected);
  },
  armed() {
    if (this.telemetry && this.telemetry.armed !== undefined && this.telemetryFresh()) return !!this.telemetry.armed;
    return !!(this.status && this.status.armed);
  },
  telemetryFresh() {
    return this.socket.open && performance.now() - this.socket.lastRxMs < TELEMETRY_STALE_MS;
  },
  // Telemetry is arriving and the backend says it comes from the controller (not a dead link).
  controllerLive() {
    return this.telemetryFresh() && !!this.telemetry && this.telemetry.link_ok !== false;
  },
};
window.hoverflyGcs = ctx; // for debugging from the console; nothing reads it

function call(list, arg) {
  for (const fn of list) {
    try { fn(arg); } catch (e) { console.error(e); }
  }
}

// ---- navigation ---------------------------------------------------------------------------

function showScreen(name) {
  if (!$(`screen-${name}`)) name = "status";
  const previous = ctx.screen;
  for (const el of document.querySelectorAll(".screen")) el.hidden = el.id !== `screen-${name}`;
  for (const b of document.querySelectorAll("#nav button")) b.classList.toggle("active", b.dataset.screen === name);
  ctx.screen = name;
  if (location.hash !== `#${name}`) history.replaceState(null, "", `${location.search}#${name}`);
  call(ctx.screenHandlers, { from: previous, to: name });
}

for (const b of document.querySelectorAll("#nav button")) b.onclick = () => showScreen(b.dataset.screen);

// ---- top bar ------------------------------------------------------------------------------

let lastLinkUp = null;
let linkMessage = null;

function updateTopBar() {
  const s = ctx.status;
  const chip = $("link-state");
  let text;
  let cls;
  if (!ctx.socket.open) {
    text = "ground station offline: reconnecting…";
    cls = "bad";
  } else if (!s) {
    text = "connecting…";
    cls = "warn";
  } else if (!s.link || !s.link.connected) {
    text = `no link${s.link && s.link.error ? ": " + s.link.error : ""}`;
    cls = "bad";
  } else {
    const proto = s.link.protocol ? s.link.protocol.toUpperCase() : "?";
    text = `${proto} on ${s.link.url}`;
    cls = ctx.telemetryFresh() && ctx.telemetry && ctx.telemetry.link_ok !== false ? "ok" : "warn";
    if (cls === "warn") text += " (no telemetry)";
  }
  chip.textContent = text;
  chip.className = `chip ${cls}`;
  chip.dataset.state = cls === "ok" ? "connected" : cls === "warn" ? "degraded" : "disconnected";

  const armedChip = $("armed-state");
  if ((!s && !ctx.telemetry) || !ctx.controllerLive()) {
    armedChip.textContent = "—";
    armedChip.className = "chip";
  } else if (ctx.armed()) {
    armedChip.textContent = "ARMED";
    armedChip.className = "chip armed";
  } else {
    armedChip.textContent = "disarmed";
    armedChip.className = "chip ok";
  }

  const up = ctx.linkUp();
  // Only the backend's link to the controller is announced here; the socket announces itself.
  if (s && s.link && !s.link.connected && ctx.socket.open && !linkMessage) {
    const why = s.link.error ? `: ${s.link.error}` : "";
    linkMessage = lastLinkUp === true
      ? `link to the controller lost${why}; reconnecting (controls that need it are disabled)`
      : `no link to the controller${why}`;
    showMessage(linkMessage);
  } else if (up && linkMessage) {
    clearMessage(linkMessage);
    linkMessage = null;
    if (lastLinkUp === false) showMessage("link to the controller up", "info");
  }
  if (up !== lastLinkUp) {
    lastLinkUp = up;
    call(ctx.linkHandlers, up);
  }
}

$("stop-all").onclick = async () => {
  // SAFETY: both stops are sent whatever the page believes about the motors: the button is for
  // when that belief may be wrong.
  ctx.emergencyStop = performance.now();
  call(ctx.stopHandlers || [], null);
  const results = await Promise.allSettled([
    api("POST", "/api/motor_test/stop", {}),
    api("POST", "/api/rc/arm", { arm: false }),
  ]);
  if (results.every((r) => r.status === "fulfilled")) showMessage("motors stopped, override disarmed", "info");
};
ctx.stopHandlers = [];
ctx.onStop = (fn) => ctx.stopHandlers.push(fn);

// ---- status screen ------------------------------------------------------------------------

function fmt(v, digits, unit) {
  if (v === null || v === undefined || Number.isNaN(v)) return "—";
  if (typeof v !== "number") return String(v);
  return `${v.toFixed(digits)}${unit ? " " + unit : ""}`;
}

function renderStatus(s) {
  const link = s.link || {};
  $("status-url").textContent = link.url || "—";
  $("status-protocol").textContent = link.protocol === "msp" ? "MSP / CLI" : link.protocol === "maint"
    ? "maintenance protocol (seed 001)" : "not detected";
  $("status-link").textContent = link.connected ? "connected" : `down${link.error ? ": " + link.error : ""}`;
  $("status-link").className = link.connected ? "" : "error-text";
  $("status-board").textContent = s.board || "—";
  $("status-version").textContent = s.version || "—";
  $("status-mode").textContent = s.mode || "—";

  const flags = s.arming_flags || [];
  const state = $("arming-state");
  if (s.armed) {
    state.textContent = "ARMED";
    state.className = "big error-text";
  } else if (flags.length) {
    state.textContent = "Arming blocked";
    state.className = "big warn";
  } else {
    state.textContent = link.connected ? "Ready to arm" : "—";
    state.className = "big";
  }
  const ul = $("arming-reasons");
  ul.replaceChildren(...flags.map((f) => {
    const li = document.createElement("li");
    li.dataset.flag = f.name;
    li.textContent = f.text || f.name;
    li.title = f.name;
    return li;
  }));

  const bit = $("bit-flags");
  const bits = s.bit_flags;
  if (Array.isArray(bits) && bits.length) {
    bit.replaceChildren(...bits.map((b) => {
      const el = document.createElement("span");
      const name = typeof b === "string" ? b : b.name;
      const ok = typeof b === "object" && b.ok !== undefined ? b.ok : false;
      el.className = `chip ${ok ? "ok" : "bad"}`;
      el.textContent = typeof b === "object" && b.text ? b.text : name;
      el.title = name;
      return el;
    }));
  } else if (bits && typeof bits === "object" && !Array.isArray(bits)) {
    bit.replaceChildren(...Object.keys(bits).sort().map((k) => {
      const el = document.createElement("span");
      el.className = `chip ${bits[k] ? "bad" : "ok"}`;
      el.textContent = k;
      return el;
    }));
  } else if (typeof bits === "number") {
    // The built-in test word (core/safety/bit.py: bit set = check failing). The backend may name the
    // failing checks in bit_texts; without it each set bit is listed by number.
    const texts = Array.isArray(s.bit_texts) ? s.bit_texts : null;
    if (bits === 0) {
      const el = document.createElement("span");
      el.className = "chip ok";
      el.textContent = "all checks pass";
      bit.replaceChildren(el);
    } else {
      const chips = [];
      for (let k = 0; k < 32; k++) {
        if (!(bits & (1 << k))) continue;
        const el = document.createElement("span");
        el.className = "chip bad";
        el.dataset.bit = String(k);
        el.textContent = texts && texts[chips.length] ? texts[chips.length] : `check ${k} failing`;
        chips.push(el);
      }
      const word = document.createElement("span");
      word.className = "dim mono";
      word.textContent = `0x${(bits >>> 0).toString(16)}`;
      bit.replaceChildren(...chips, word);
    }
  } else {
    bit.textContent = link.connected ? "all clear" : "—";
  }

  $("loop-us").textContent = fmt(s.loop_us, 0, "µs");
  $("jitter-us").textContent = fmt(s.jitter_us, 0, "µs");
  $("battery-v").textContent = fmt(s.battery_v, 2, "V");
  $("rx-lq").textContent = fmt(s.rx_lq, 0, "%");
}

let statusFailures = 0;
let statusAtMs = 0;

function takeStatus(s) {
  statusAtMs = performance.now();
  ctx.status = s;
  renderStatus(s);
  const url = $("connect-url");
  if (s.link && s.link.url && !url.value && document.activeElement !== url) url.value = s.link.url;
  call(ctx.statusHandlers, s);
  updateTopBar();
}

// The WebSocket brings the status about once a second; the HTTP poll covers a closed socket and
// is what notices a backend that has gone away.
async function pollStatus() {
  if (!ctx.socket.open || performance.now() - statusAtMs > 1.5 * STATUS_PERIOD_MS) {
    try {
      const s = await api("GET", "/api/status", undefined, { quiet: statusFailures > 0 });
      statusFailures = 0;
      takeStatus(s);
    } catch (e) {
      statusFailures++;
      if (statusFailures === 1) ctx.status = null;
    }
  }
  updateTopBar();
  setTimeout(pollStatus, STATUS_PERIOD_MS);
}

ctx.socket.on("message", (m) => {
  if (m.t === "status") {
    const { t, ...s } = m;
    takeStatus(s);
  }
});

$("connect-btn").onclick = async () => {
  const url = $("connect-url").value.trim();
  if (!url) {
    showMessage("type the port first: socket://127.0.0.1:5761 for `hoverfly sim`, /dev/ttyACM0 for a Pico on USB");
    return;
  }
  $("connect-btn").disabled = true;
  try {
    await api("POST", "/api/connect", { url });
    showMessage(`connected to ${url}`, "info");
    if (ctx.params) ctx.params.reload();
  } catch (e) {
    // shown by api(): the words say why (not a flight controller, refused, no answer)
  } finally {
    $("connect-btn").disabled = false;
  }
};

$("disconnect-btn").onclick = async () => {
  // SAFETY: the backend stops a motor test and the override when its link closes.
  try { await api("POST", "/api/disconnect", {}); } catch (e) { /* shown by api() */ }
};

// ---- telemetry ----------------------------------------------------------------------------

let attitude = [0, 0, 0];
let hzCount = 0;
let hzStartMs = performance.now();

ctx.socket.on("telemetry", (m) => {
  ctx.telemetry = m;
  if (Array.isArray(m.attitude_deg)) attitude = m.attitude_deg;
  hzCount++;
  call(ctx.telemetryHandlers, m);
});

ctx.socket.on("state", (open) => {
  updateTopBar();
  if (!open) showMessage("the ground station's WebSocket closed: reconnecting (controls are disabled meanwhile)");
  else clearMessage("the ground station's WebSocket closed: reconnecting (controls are disabled meanwhile)");
});

setInterval(() => {
  const now = performance.now();
  const hz = (hzCount * 1000) / (now - hzStartMs);
  hzCount = 0;
  hzStartMs = now;
  ctx.telemetryHz = hz;
  $("telemetry-hz").textContent = ctx.controllerLive() ? `${hz.toFixed(0)} Hz` : "no telemetry";
  updateTopBar();
}, 1000);

function frame() {
  if (ctx.screen === "status") {
    drawHorizon($("horizon"), attitude[0] || 0, attitude[1] || 0, attitude[2] || 0, ctx.controllerLive());
    $("attitude-text").textContent = ctx.controllerLive()
      ? `roll ${fmt(attitude[0], 1)}°  pitch ${fmt(attitude[1], 1)}°  yaw ${fmt(attitude[2], 0)}°`
      : "roll —  pitch —  yaw —";
  }
  if (ctx.screen === "fly") {
    drawHorizon($("fly-horizon"), attitude[0] || 0, attitude[1] || 0, attitude[2] || 0, ctx.controllerLive());
  }
  requestAnimationFrame(frame);
}

// ---- start --------------------------------------------------------------------------------

window.addEventListener("pagehide", () => ctx.socket.close());

initParams(ctx);
initReceiver(ctx);
initMotors(ctx);
initSensors(ctx);
initMaint(ctx);
initFly(ctx);
initLogs(ctx);

ctx.socket.connect();
showScreen((location.hash || "#status").slice(1));
pollStatus();
requestAnimationFrame(frame);
