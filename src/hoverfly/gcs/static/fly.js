// The Fly screen: a gamepad or joystick (browser Gamepad API) or the keyboard, mapped to roll,
// pitch, yaw and throttle, sent as "sticks" over the WebSocket at 50 Hz; the backend turns them
// into the seed-001 radio override (maintenance port) or MSP_SET_RAW_RC (MSP port).
//
// Safety, as the ground-station reference (section 3.5) and cfclient's history ask:
// - nothing is sent until, after the input appeared, the sticks were seen centred and the
//   throttle at zero (a pad's first samples can be anything: cfclient #156);
// - arming needs the ARM button, pressed with the throttle at zero; a disarm by the controller
//   (failsafe, landing) clears the request, so it never re-arms by itself;
// - losing the pad, the page, the socket or the focus of the tab stops sending: the backend stops
//   its override within 250 ms and the controller's own link timeout and failsafe take over;
// - nothing is sent while calibrating.

const $ = (id) => document.getElementById(id);

const SEND_PERIOD_MS = 20;     // 50 Hz, the rate of a typical RC link frame
const RENDER_EVERY = 4;        // redraw the cockpit every 4th tick (12.5 Hz): the main thread stays free for sending
const CENTRE_TOL = 0.1;        // |stick| below this counts as centred for the interlock
const THROTTLE_LOW = 0.05;     // throttle below this counts as low for the interlock
const THROTTLE_DEADBAND = 0.03; // the throttle's bottom this far reads as exactly zero, the only value that arms
const SAFE_TICKS = 5;          // centred + low seen this many sends in a row (100 ms) before sending
const DEADBAND = 0.02;
const KEY_RATE_PER_S = 0.6;    // keyboard throttle ramp
const KEY_DEFLECTION = 0.5;    // arrow keys: half stick, Shift: full
const FUNCTIONS = ["roll", "pitch", "yaw", "throttle"];
// Standard-mapping pads, mode 2: left stick yaw (axis 0) and throttle (axis 1, up = -1), right
// stick roll (axis 2) and pitch (axis 3, up = -1): inverted so stick up is full throttle / forward.
const DEFAULT_MAP = { roll: 2, pitch: 3, yaw: 0, throttle: 1 };
const DEFAULT_INVERT = { roll: false, pitch: true, yaw: false, throttle: true };
const STORE_KEY = "hoverfly-fly-mapping";

export function applyExpo(x, expo) {
  return x * (1 - expo) + x * x * x * expo;
}

// One raw axis to -1..1 around its calibrated centre, with a small deadband.
export function centred(raw, cal) {
  const c = cal ? cal.centre : 0;
  const lo = cal ? cal.min : -1;
  const hi = cal ? cal.max : 1;
  let n = raw >= c ? (raw - c) / Math.max(hi - c, 1e-6) : (raw - c) / Math.max(c - lo, 1e-6);
  n = Math.max(-1, Math.min(1, n));
  if (Math.abs(n) < DEADBAND) return 0;
  return n;
}

// The throttle axis end to end (it has no centre): 0..1 after the invert.
export function throttleOf(raw, cal, invert) {
  const lo = cal ? cal.min : -1;
  const hi = cal ? cal.max : 1;
  let t = (raw - lo) / Math.max(hi - lo, 1e-6);
  t = Math.max(0, Math.min(1, t));
  if (invert) t = 1 - t;
  return t < THROTTLE_DEADBAND ? 0 : t;
}

// Sticks from a pad's axes under a mapping: {roll, pitch, yaw, throttle}.
export function sticksFromAxes(axes, mapping, invert, cal, expo) {
  const out = {};
  for (const f of FUNCTIONS) {
    const k = mapping[f];
    const raw = k >= 0 && k < axes.length && Number.isFinite(axes[k]) ? axes[k] : (f === "throttle" ? NaN : 0);
    const c = cal && cal[k];
    if (f === "throttle") {
      // A missing or broken throttle axis reads as full: it then can never pass the interlock.
      out.throttle = Number.isNaN(raw) ? 1 : throttleOf(raw, c, invert.throttle);
    } else {
      const n = centred(raw, c);
      out[f] = applyExpo(invert[f] ? -n : n, expo);
    }
  }
  return out;
}

export function initFly(ctx) {
  const { api, showMessage } = ctx;
  const st = {
    source: "gamepad",
    padIndex: null,
    padId: "",
    ready: false,          // the interlock has been passed since the input appeared
    safeTicks: 0,
    lost: null,            // why the input was lost, until a new one is ready
    armRequested: false,
    calibrating: 0,        // 0 none, 1 centre step, 2 range step
    sticks: { roll: 0, pitch: 0, yaw: 0, throttle: 0 },
    sending: false,
    sent: 0,
    sendHz: 0,
    fcArmed: false,
    lastSentMs: 0,
    maxGapMs: 0,           // longest time between two sends in the current second
    gapMs: 0,              // ... in the last whole second (the backend gives up after 250 ms)
    armButtonWas: false,
    armButtonSeen: false,  // the ARM button's state has been seen since the interlock passed
  };
  const keys = new Set();
  let shiftHeld = false;
  let keyThrottle = 0;
  let lastTickMs = performance.now();
  let renderCount = 0;
  let mapping = { ...DEFAULT_MAP };
  let invert = { ...DEFAULT_INVERT };
  let cal = {};            // axis index -> {centre, min, max}
  let armButton = -1;      // pad button that toggles ARM, -1 = none
  let calWork = null;

  // ---- mapping UI ------------------------------------------------------------------------

  function loadMapping() {
    try {
      const saved = JSON.parse(localStorage.getItem(STORE_KEY) || "null");
      if (saved && saved.mapping) {
        mapping = { ...DEFAULT_MAP, ...saved.mapping };
        invert = { ...DEFAULT_INVERT, ...saved.invert };
        cal = saved.cal || {};
        armButton = Number.isInteger(saved.armButton) ? saved.armButton : -1;
        if (saved.expo !== undefined) $("fly-expo").value = saved.expo;
      }
    } catch (e) {
      // a broken store is replaced by the defaults
    }
  }

  function saveMapping() {
    localStorage.setItem(STORE_KEY, JSON.stringify({ mapping, invert, cal, expo: expo(), armButton }));
  }

  function fillAxisSelects(n) {
    for (const f of FUNCTIONS) {
      const sel = $(`map-${f}`);
      if (sel.options.length === n) continue;
      sel.replaceChildren(...Array.from({ length: n }, (_, i) => {
        const o = document.createElement("option");
        o.value = String(i);
        o.textContent = `axis ${i}`;
        return o;
      }));
    }
    showMapping();
  }

  function fillButtonSelect(n) {
    const sel = $("map-arm");
    if (sel.options.length === n + 1) return;
    sel.replaceChildren(new Option("none (on-screen only)", "-1"),
      ...Array.from({ length: n }, (_, i) => new Option(`button ${i}`, String(i))));
    sel.value = String(armButton);
  }

  function showMapping() {
    $("map-arm").value = String(armButton);
    for (const f of FUNCTIONS) {
      $(`map-${f}`).value = String(mapping[f]);
      $(`inv-${f}`).checked = !!invert[f];
    }
  }

  for (const f of FUNCTIONS) {
    $(`map-${f}`).addEventListener("change", () => {
      mapping[f] = Number($(`map-${f}`).value);
      saveMapping();
      resetInterlock("mapping changed");
    });
    $(`inv-${f}`).addEventListener("change", () => {
      invert[f] = $(`inv-${f}`).checked;
      saveMapping();
      resetInterlock("mapping changed");
    });
  }
  $("map-arm").addEventListener("change", () => {
    armButton = Number($("map-arm").value);
    st.armButtonSeen = false; // a button held while mapping it does not count as a press
    saveMapping();
  });
  $("fly-expo").addEventListener("change", saveMapping);
  $("fly-map-reset").onclick = () => {
    mapping = { ...DEFAULT_MAP };
    invert = { ...DEFAULT_INVERT };
    cal = {};
    armButton = -1;
    saveMapping();
    showMapping();
    resetInterlock("mapping changed");
  };

  function expo() {
    const e = Number($("fly-expo").value);
    return Number.isFinite(e) ? Math.max(0, Math.min(1, e)) : 0;
  }

  // ---- input ------------------------------------------------------------------------------

  function pads() {
    try {
      return navigator.getGamepads ? [...navigator.getGamepads()] : [];
    } catch (e) {
      return [];
    }
  }

  function currentPad() {
    if (st.padIndex === null) return null;
    const p = pads()[st.padIndex];
    return p && p.connected !== false ? p : null;
  }

  // SAFETY: every path that loses the input ends here: stop sending, drop the arm request, and
  // demand the interlock again before anything is sent.
  function lose(why) {
    const wasSending = st.sending;
    st.ready = false;
    st.safeTicks = 0;
    st.sending = false;
    st.armRequested = false;
    if (why) {
      st.lost = why;
      if (wasSending) showMessage(`${why}: stopped sending sticks; the controller's failsafe takes over`);
    }
  }

  function resetInterlock(why) {
    if (why && st.armRequested) showMessage(`${why}: arm request dropped`);
    lose(null);
    st.lost = null;
  }

  window.addEventListener("gamepadconnected", (ev) => {
    if (st.source === "gamepad" && st.padIndex === null) pickPad(ev.gamepad);
  });
  window.addEventListener("gamepaddisconnected", (ev) => {
    if (ev.gamepad && ev.gamepad.index === st.padIndex) {
      st.padIndex = null;
      lose(`gamepad "${ev.gamepad.id}" disconnected`);
    }
  });

  function pickPad(p) {
    st.padIndex = p.index;
    st.padId = p.id || `gamepad ${p.index}`;
    st.lost = null;
    lose(null);
    fillAxisSelects(Math.max(4, p.axes.length));
    fillButtonSelect(p.buttons ? p.buttons.length : 0);
    st.armButtonSeen = false;
  }

  window.addEventListener("keydown", (ev) => {
    if (st.source !== "keyboard" || ctx.screen !== "fly") return;
    if (ev.target && (ev.target.tagName === "INPUT" || ev.target.tagName === "SELECT")) return;
    const k = ev.key.toLowerCase();
    if (["w", "s", "a", "d", "x", "arrowup", "arrowdown", "arrowleft", "arrowright"].includes(k)) {
      keys.add(k);
      ev.preventDefault();
    }
    if (k === "x") keyThrottle = 0;
    shiftHeld = ev.shiftKey;
  });
  window.addEventListener("keyup", (ev) => {
    keys.delete(ev.key.toLowerCase());
    shiftHeld = ev.shiftKey;
  });
  // SAFETY: keys released while the window is not focused never arrive: treat them all as let go.
  window.addEventListener("blur", () => {
    keys.clear();
    shiftHeld = false;
  });

  function readKeyboard(dtS) {
    if (keys.has("w")) keyThrottle = Math.min(1, keyThrottle + KEY_RATE_PER_S * dtS);
    if (keys.has("s")) keyThrottle = Math.max(0, keyThrottle - KEY_RATE_PER_S * dtS);
    const d = shiftHeld ? 1 : KEY_DEFLECTION;
    const axis = (neg, pos) => (keys.has(pos) ? d : 0) - (keys.has(neg) ? d : 0);
    return {
      roll: axis("arrowleft", "arrowright"),
      pitch: axis("arrowdown", "arrowup"),
      yaw: axis("a", "d"),
      throttle: keyThrottle,
    };
  }

  // ---- aux channels: the flight mode the pilot picked, from the controller's mode ranges ----

  let auxCache = { key: null, aux: [] };

  function auxValues() {
    const byName = ctx.params && ctx.params.byName;
    const mode = $("fly-mode").value;
    // Without the mode ranges (parameters not read yet) the backend's own defaults stand.
    if (!byName || !byName.size) return [];
    const key = `${mode}|${[...byName.keys()].filter((n) => /_(ch|min_us|max_us)$/.test(n))
      .map((n) => byName.get(n).value).join(",")}`;
    if (auxCache.key !== key) auxCache = { key, aux: auxFor(mode, (n) => (byName.get(n) ? byName.get(n).value : null)) };
    return auxCache.aux;
  }

  // ---- the 50 Hz loop ---------------------------------------------------------------------

  function tick() {
    const now = performance.now();
    const dtS = Math.min(0.1, (now - lastTickMs) / 1000);
    lastTickMs = now;
    let sticks = null;

    if (st.source === "gamepad") {
      if (st.padIndex === null) {
        const p = pads().find((g) => g && g.connected !== false);
        if (p) pickPad(p);
      }
      if (st.padIndex !== null) {
        const p = currentPad();
        if (!p) {
          // SAFETY: a pad that vanished from getGamepads() without an event is lost too.
          st.padIndex = null;
          lose(`gamepad "${st.padId}" no longer reported`);
        } else {
          if (st.calibrating === 2 && calWork) {
            p.axes.forEach((v, i) => {
              calWork.min[i] = Math.min(calWork.min[i] ?? v, v);
              calWork.max[i] = Math.max(calWork.max[i] ?? v, v);
            });
          }
          padButton(p);
          sticks = sticksFromAxes(p.axes, mapping, invert, cal, expo());
        }
      }
    } else {
      sticks = readKeyboard(dtS);
    }

    if (sticks) st.sticks = sticks;
    const linkUp = ctx.linkUp();

    if (!st.sending) st.lastSentMs = 0;
    if (!sticks || st.calibrating || document.hidden) {
      st.sending = false;
      if (st.calibrating || document.hidden) st.armRequested = false;
    } else if (!st.ready) {
      const safe = Math.abs(sticks.roll) < CENTRE_TOL && Math.abs(sticks.pitch) < CENTRE_TOL
        && Math.abs(sticks.yaw) < CENTRE_TOL && sticks.throttle < THROTTLE_LOW;
      st.safeTicks = safe ? st.safeTicks + 1 : 0;
      if (st.safeTicks >= SAFE_TICKS) {
        st.ready = true;
        st.lost = null;
      }
      st.sending = false;
    } else if (!mayControl()) {
      st.sending = false;
    } else if (!linkUp) {
      // SAFETY: no link, no arm request carried over to when it returns.
      st.sending = false;
      st.armRequested = false;
    } else {
      const msg = {
        t: "sticks",
        roll: round(sticks.roll),
        pitch: round(sticks.pitch),
        yaw: round(sticks.yaw),
        throttle: round(sticks.throttle),
        arm: st.armRequested,
        aux: auxValues(),
      };
      st.sending = ctx.socket.send(msg);
      if (st.sending) {
        st.sent++;
        if (st.lastSentMs) st.maxGapMs = Math.max(st.maxGapMs, now - st.lastSentMs);
        st.lastSentMs = now;
      }
    }
    if (++renderCount % RENDER_EVERY === 0) render();
  }

  // SAFETY: the Fly screen takes control of a disarmed controller only: a pad left plugged in while
  // configuring sends nothing, and a craft already armed by its own receiver is not taken over
  // (the override replaces the receiver, and would disarm it). Once in control, sticks keep going
  // from any screen while armed, so a look at Status does not drop the craft.
  function mayControl() {
    if (st.sending) return ctx.screen === "fly" || st.armRequested || st.fcArmed;
    return ctx.screen === "fly" && !st.fcArmed;
  }

  function round(x) {
    return Math.round(x * 1000) / 1000;
  }

  // A deadline schedule rather than setInterval: on a busy machine a late tick is followed by a
  // prompt one, so the rate the backend sees stays near 50 Hz instead of drifting down.
  let nextTickMs = performance.now();
  function loop() {
    try {
      tick();
    } finally {
      const now = performance.now();
      nextTickMs += SEND_PERIOD_MS;
      if (nextTickMs < now - 5 * SEND_PERIOD_MS) nextTickMs = now; // after a stall, do not burst
      setTimeout(loop, Math.max(0, nextTickMs - now));
    }
  }
  setInterval(() => {
    st.sendHz = st.sent;
    st.sent = 0;
    st.gapMs = st.maxGapMs;
    st.maxGapMs = 0;
  }, 1000);

  // ---- arming -----------------------------------------------------------------------------

  async function disarm() {
    st.armRequested = false;
    try { await api("POST", "/api/rc/arm", { arm: false }); } catch (e) { /* shown by api() */ }
  }

  function tryArm() {
    // SAFETY: an explicit press, with the throttle at zero, on a ready input and a live link.
    if (!st.ready || !st.sending) {
      showMessage("not armed: the input is not ready (centre the sticks, throttle to zero) or the link is down");
      return;
    }
    if (st.sticks.throttle > 0) {
      showMessage("not armed: the throttle must be at zero to arm");
      return;
    }
    // The request rides in the sticks messages, so the backend judges it against the throttle of
    // the same message (POST /api/rc/arm could arrive after a later throttle change and be judged
    // on that). A refusal comes back on the socket and drops the request (below).
    st.armRequested = true;
  }

  $("fly-arm").onclick = () => {
    // focus leaves the button, so the Space that disarms cannot also press it (and re-arm)
    $("fly-arm").blur();
    return st.armRequested ? disarm() : tryArm();
  };

  // A pad button mapped to ARM toggles like the on-screen button, on its press edge only: a button
  // already held when the pad appears (or when the interlock passes) does nothing until released.
  function padButton(p) {
    const k = armButton;
    const pressed = k >= 0 && k < p.buttons.length && !!(p.buttons[k] && (p.buttons[k].pressed || p.buttons[k] === 1));
    const edge = pressed && st.armButtonSeen && !st.armButtonWas;
    st.armButtonWas = pressed;
    st.armButtonSeen = st.ready;
    if (edge) {
      if (st.armRequested) disarm();
      else tryArm();
    }
  }

  // Space disarms from the Fly screen whatever the input (it never arms).
  window.addEventListener("keydown", (ev) => {
    if (ev.code !== "Space" || ctx.screen !== "fly") return;
    if (ev.target && ev.target.tagName === "BUTTON") ev.preventDefault();
    if (st.armRequested) disarm();
  });
  window.addEventListener("keyup", (ev) => {
    if (ev.code === "Space" && ctx.screen === "fly" && ev.target && ev.target.tagName === "BUTTON") ev.preventDefault();
  });

  // SAFETY: the backend refused the arm request (or dropped it, e.g. after sticks went stale):
  // the page drops it as well, so arming again takes a new press with the throttle at zero.
  ctx.socket.on("error", (text) => {
    if (st.armRequested && /arm/i.test(text)) {
      st.armRequested = false;
      showMessage(`arm request dropped: ${text}`);
    }
  });

  ctx.onStop(() => {
    st.armRequested = false;
  });

  ctx.onTelemetry((t) => {
    const armed = !!t.armed;
    // SAFETY: a disarm by the controller (failsafe, landing, switch) clears the request, so a
    // later frame cannot re-arm it without a new press.
    if (st.fcArmed && !armed && st.armRequested) {
      st.armRequested = false;
      showMessage("the controller disarmed: press ARM again to fly", "info");
    }
    st.fcArmed = armed;
  });

  ctx.socket.on("state", (open) => {
    if (!open) lose(st.sending ? "the ground station's socket closed" : null);
  });
  document.addEventListener("visibilitychange", () => {
    if (document.hidden) lose(st.sending ? "the page was hidden" : null);
  });
  window.addEventListener("pagehide", () => lose(null));

  $("fly-source").addEventListener("change", () => {
    st.source = $("fly-source").value;
    keyThrottle = 0;
    keys.clear();
    st.padIndex = null;
    resetInterlock(null);
  });

  // ---- calibration ------------------------------------------------------------------------

  $("fly-calibrate").onclick = () => {
    if (st.armRequested || st.fcArmed) {
      showMessage("disarm before calibrating");
      return;
    }
    if (st.source !== "gamepad" || !currentPad()) {
      showMessage("connect a gamepad (and press a button on it) before calibrating");
      return;
    }
    lose(null);
    st.calibrating = 1;
    $("fly-cal-next").hidden = false;
    $("fly-cal-step").textContent = "Step 1 of 2: leave roll, pitch and yaw centred and pull the throttle fully down, then press Next. Nothing is sent while calibrating.";
  };

  $("fly-cal-next").onclick = () => {
    const p = currentPad();
    if (!p) {
      st.calibrating = 0;
      $("fly-cal-next").hidden = true;
      $("fly-cal-step").textContent = "calibration cancelled: the gamepad went away";
      return;
    }
    if (st.calibrating === 1) {
      calWork = { centre: [...p.axes], min: [...p.axes], max: [...p.axes] };
      st.calibrating = 2;
      $("fly-cal-step").textContent = "Step 2 of 2: move every stick to all its ends, then press Next.";
      return;
    }
    const next = {};
    p.axes.forEach((_, i) => {
      const lo = calWork.min[i];
      const hi = calWork.max[i];
      if (hi - lo > 0.2) next[i] = { centre: calWork.centre[i], min: lo, max: hi };
    });
    const missing = FUNCTIONS.filter((f) => !next[mapping[f]]);
    st.calibrating = 0;
    $("fly-cal-next").hidden = true;
    if (missing.length) {
      $("fly-cal-step").textContent = `calibration not kept: ${missing.join(", ")} did not move through a range`;
      return;
    }
    cal = next;
    saveMapping();
    $("fly-cal-step").textContent = "calibration kept. Centre the sticks and pull the throttle down to start sending.";
  };

  // ---- view -------------------------------------------------------------------------------

  function stateText() {
    if (st.calibrating) return ["calibrating: not sending", "calibrating"];
    if (st.lost && !st.ready) return [`LOST: ${st.lost}`, "lost"];
    if (st.source === "gamepad" && st.padIndex === null) return ["no gamepad: connect one and press a button", "none"];
    if (!st.ready) return ["waiting: centre the sticks and pull the throttle to zero", "interlock"];
    if (!ctx.linkUp()) return ["no link: not sending", "nolink"];
    if (!st.sending && st.fcArmed) return ["standby: the controller is armed and this page is not flying it: not taking over", "standby"];
    if (!st.sending && ctx.screen !== "fly") return ["standby: sticks are sent only from the Fly screen", "standby"];
    if (st.fcArmed) return ["ARMED", "armed"];
    if (st.armRequested) return ["arming…", "arming"];
    if (st.ready && st.sticks.throttle > 0) return ["ready, disarmed (throttle up: lower it to arm)", "ready"];
    return ["ready, disarmed", "ready"];
  }

  // While an arm request waits, the controller's own reasons (Status screen's list) say why.
  function armRefusal() {
    const flags = (ctx.status && ctx.status.arming_flags) || [];
    if (!st.armRequested || st.fcArmed || !flags.length) return "";
    return `the controller does not arm: ${flags.map((f) => f.text || f.name).join("; ")}`;
  }

  function render() {
    // The state text is kept current on every screen (it is what a test or a glance reads);
    // the rest is drawn only while the Fly screen is shown.
    const [text, code] = stateText();
    const chip = $("fly-chip");
    chip.hidden = !st.sending;
    chip.textContent = st.armRequested || st.fcArmed ? "sticks: flying" : "sticks: sending";
    const el = $("fly-state");
    el.textContent = text;
    el.dataset.state = code;
    el.className = `big ${code === "armed" ? "error-text" : code === "lost" || code === "nolink" ? "warn" : ""}`;
    const arm = $("fly-arm");
    arm.disabled = !(st.armRequested || (st.ready && st.sending));
    arm.textContent = st.armRequested ? "DISARM" : "ARM";
    arm.classList.toggle("armed", st.armRequested);
    $("fly-hint").textContent = st.ready && !st.armRequested && st.sticks.throttle > 0
      ? "throttle must be at zero to arm" : armRefusal();
    $("fly-gamepad").textContent = st.source === "keyboard" ? "keyboard"
      : st.padIndex === null ? "none" : `${st.padId} (#${st.padIndex})`;
    $("fly-sending").textContent = st.sending ? `yes, ${st.sendHz} Hz, longest gap ${Math.round(st.gapMs)} ms` : "no";
    if (ctx.screen !== "fly") return;
    $("fly-link").textContent = !ctx.socket.open ? "ground station offline"
      : !ctx.linkUp() ? "controller link down" : ctx.telemetryFresh() ? "ok" : "no telemetry";
    const t = ctx.telemetry;
    $("fly-fc").textContent = t ? `${t.armed ? "armed" : "disarmed"}, ${t.mode || "—"}${t.link_ok === false ? ", RX link lost" : ""}`
      : "—";
    // What the backend does with the sticks: "sending" (the override or MSP RC goes out), "stopped"
    // (sticks went stale: the controller's failsafe has it), "off"; and the controller's refusal.
    const ov = (t && t.override) || (ctx.status && ctx.status.override) || "—";
    const refusal = ctx.status && ctx.status.override_refusal;
    $("fly-override").textContent = refusal ? `${ov}: ${refusal}` : ov;
    $("fly-override").className = refusal ? "error-text" : "";
    const s = st.sticks;
    $("fly-values").textContent = `roll ${s.roll.toFixed(2)}  pitch ${s.pitch.toFixed(2)}  yaw ${s.yaw.toFixed(2)}  throttle ${s.throttle.toFixed(2)}`;
    drawSticks(s);
  }

  function drawSticks(s) {
    const c = $("fly-sticks");
    const g = c.getContext("2d");
    const w = c.width;
    const h = c.height;
    g.clearRect(0, 0, w, h);
    const size = Math.min(w / 2 - 30, h - 30);
    const boxes = [
      { x: w / 4, label: "yaw / throttle", px: s.yaw, py: s.throttle * 2 - 1 },
      { x: (3 * w) / 4, label: "roll / pitch", px: s.roll, py: s.pitch },
    ];
    for (const b of boxes) {
      const x0 = b.x - size / 2;
      const y0 = (h - size) / 2 - 6;
      g.strokeStyle = "#343a46";
      g.lineWidth = 1;
      g.strokeRect(x0, y0, size, size);
      g.beginPath();
      g.moveTo(b.x, y0);
      g.lineTo(b.x, y0 + size);
      g.moveTo(x0, y0 + size / 2);
      g.lineTo(x0 + size, y0 + size / 2);
      g.stroke();
      g.fillStyle = st.sending ? "#4fa3ff" : "#8b94a3";
      g.beginPath();
      g.arc(b.x + (b.px * size) / 2, y0 + size / 2 - (b.py * size) / 2, 7, 0, 2 * Math.PI);
      g.fill();
      g.fillStyle = "#8b94a3";
      g.font = "12px sans-serif";
      g.textAlign = "center";
      g.fillText(b.label, b.x, y0 + size + 16);
    }
  }

  loadMapping();
  fillAxisSelects(4);
  fillButtonSelect(0);
  loop();
}

// AUX1..4 (-1..1, AUX1 = channel 5) that put the controller in `mode` ("angle", "horizon", "acro")
// by its own mode ranges (get(name) reads a parameter): horizon takes priority over angle, as in
// Betaflight; every other switch with a range (failsafe, autopilot, air mode) is kept out of it.
// AUX1 is the arm switch, which the backend sets from the arm request. [] when no choice works.
export function auxFor(mode, get) {
  const CANDIDATES_US = [1000, 1500, 2000, 1200, 1800];
  const inRange = (key, aux) => {
    const ch = get(`${key}_ch`);
    if (!ch || ch < 5 || ch > 8 || get(`${key}_min_us`) === null) return false;
    const us = 1500 + 500 * aux[ch - 5];
    return us >= get(`${key}_min_us`) && us <= get(`${key}_max_us`);
  };
  const others = ["fs_switch", "ap", "airmode"].filter((k) => get(`${k}_ch`));
  const chans = new Set();
  for (const k of ["angle", "horizon", ...others]) {
    const ch = get(`${k}_ch`);
    if (ch >= 6 && ch <= 8) chans.add(ch);
  }
  const list = [...chans];
  const aux = [-1, -1, -1, -1];
  const total = CANDIDATES_US.length ** list.length;
  for (let n = 0; n < total; n++) {
    let m = n;
    for (const ch of list) {
      aux[ch - 5] = (CANDIDATES_US[m % CANDIDATES_US.length] - 1500) / 500;
      m = Math.floor(m / CANDIDATES_US.length);
    }
    const active = inRange("horizon", aux) ? "horizon" : inRange("angle", aux) ? "angle" : "acro";
    if (active === mode && !others.some((k) => inRange(k, aux))) return [...aux];
  }
  return [];
}
