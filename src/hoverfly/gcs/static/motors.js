// The Motors screen: the props-off motor test. Sliders stay disabled until "propellers removed" is
// ticked (Betaflight's and QGroundControl's convention), and a motor runs only while its slider is
// held: releasing it (pointer up, or the slider losing keyboard focus) springs it back to zero.
// While any slider is up the page repeats its request every REFRESH_MS; the backend stops the test
// when the repeats stop (its dead-man), so a closed tab or a dead page stops the motors too.

import { token } from "./api.js";

const $ = (id) => document.getElementById(id);

const NEED_CONFIRMATION = "tick \"propellers removed\" to enable the sliders";
const REFRESH_MS = 100; // well inside the backend's 500 ms dead-man, so one late request does not stop a test

export function initMotors(ctx) {
  const { api, showMessage } = ctx;
  let sliders = [];
  let outs = [];
  let running = false;        // the backend has been asked to spin something and not yet to stop
  let refreshQueued = false;
  let held = null;            // the slider under the pointer
  let chain = Promise.resolve();
  let capPct = 100;           // the controller's motor_test_pct: a slider above it would promise what never runs

  // One request at a time, in order: a refresh still in flight can never land after the stop
  // that was meant to end it.
  function enqueue(fn) {
    chain = chain.then(fn, fn);
    return chain;
  }

  function values() {
    return sliders.map((s) => Number(s.value) / 100);
  }

  function anyUp() {
    return sliders.some((s) => Number(s.value) > 0);
  }

  function build(n) {
    const box = $("motor-sliders");
    sliders = [];
    outs = [];
    const out = [];
    for (let i = 0; i < n; i++) {
      const col = document.createElement("div");
      col.className = "motor";
      const label = document.createElement("b");
      label.textContent = `Motor ${i + 1}`;
      const s = document.createElement("input");
      s.type = "range";
      s.min = "0";
      s.max = String(capPct);
      s.step = "1";
      s.value = "0";
      s.id = `motor-slider-${i + 1}`;
      s.dataset.motor = String(i + 1);
      s.setAttribute("aria-label", `motor ${i + 1} test output, percent`);
      const pctEl = document.createElement("span");
      pctEl.className = "pct mono";
      pctEl.textContent = "0 %";
      const o = document.createElement("span");
      o.className = "out";
      o.id = `motor-out-${i + 1}`;
      o.textContent = "—";
      s.addEventListener("pointerdown", () => { held = s; });
      s.addEventListener("input", () => {
        pctEl.textContent = `${s.value} %`;
        changed();
      });
      // SAFETY: the dead-man: a slider let go of by the keyboard drops to zero.
      s.addEventListener("blur", () => release(s));
      col.append(label, s, pctEl, o);
      out.push(col);
      sliders.push(s);
      outs.push({ pct: pctEl, out: o });
    }
    box.replaceChildren(...out);
    gate();
  }

  // The controller caps every test output at motor_test_pct (core/command/motortest.py): the sliders
  // end there and the page says why, instead of a slider at 80 % that runs the motor at 30 %.
  async function readCap() {
    let rows;
    try {
      rows = await api("GET", "/api/params", undefined, { quiet: true });
    } catch (e) {
      return;
    }
    const row = rows.find((r) => r.name === "motor_test_pct");
    const el = $("motor-cap");
    if (!row || typeof row.value !== "number") {
      el.textContent = "The controller caps test outputs at motor_test_pct (not readable over this link).";
      return;
    }
    capPct = Math.max(0, Math.min(100, Math.floor(row.value)));
    el.textContent = `Capped at ${capPct} % by the controller's motor_test_pct (Parameters screen).`;
    for (const s of sliders) {
      if (Number(s.value) > capPct) s.value = String(capPct);
      s.max = String(capPct);
    }
  }

  function release(s) {
    if (Number(s.value) === 0) return;
    s.value = "0";
    s.dispatchEvent(new Event("input"));
  }

  // SAFETY: the dead-man: a slider let go of by the pointer drops to zero.
  window.addEventListener("pointerup", () => {
    if (held) release(held);
    held = null;
  });
  window.addEventListener("pointercancel", () => {
    if (held) release(held);
    held = null;
  });

  function refusal() {
    if (!ctx.linkUp()) return "no link to the controller";
    if (ctx.armed()) return "refused: the craft is armed. Disarm before testing motors.";
    if (!$("motor-props-removed").checked) return NEED_CONFIRMATION;
    return null;
  }

  // Enable or disable the sliders from the confirmation, the link and the arming state; any
  // reason to refuse also stops a running test.
  function gate() {
    const why = refusal();
    for (const s of sliders) s.disabled = why !== null;
    // The missing confirmation speaks for itself (the checkbox); any other refusal is spelled out
    // even before it is ticked, so an armed craft says so up front.
    $("motor-refused").textContent = why && why !== NEED_CONFIRMATION ? why : "";
    if (why) stopAll(true);
    updateState();
  }

  function updateState() {
    const el = $("motor-state");
    if (running && anyUp()) {
      el.textContent = `running: ${sliders.map((s, i) => `M${i + 1} ${s.value}%`).join("  ")}`;
      el.className = "warn";
    } else {
      el.textContent = "stopped";
      el.className = "dim";
    }
  }

  function changed() {
    if (refusal()) {
      for (const s of sliders) s.value = "0";
      updateState();
      return;
    }
    if (anyUp()) {
      running = true;
      sendRefresh();
    } else if (running) {
      stopAll(false);
    }
    updateState();
  }

  function sendRefresh() {
    if (refreshQueued) return;
    refreshQueued = true;
    enqueue(async () => {
      refreshQueued = false;
      if (!running || !anyUp() || refusal()) return;
      try {
        await api("POST", "/api/motor_test", { props_removed: true, values: values() }, { quiet: true });
        $("motor-refused").textContent = "";
      } catch (e) {
        // A refusal (armed, no confirmation, link down) zeroes the sliders: the page must not keep
        // showing a motor as commanded when the controller said no.
        $("motor-refused").textContent = `motor test refused: ${e.reason || e.message}`;
        showMessage(`motor test refused: ${e.reason || e.message}`);
        for (const s of sliders) {
          s.value = "0";
          s.dispatchEvent(new Event("input"));
        }
        running = false;
        updateState();
      }
    });
  }

  // Ends a running test (one stop request, queued after any refresh in flight); `zero` also puts
  // the sliders back to 0 when the stop comes from elsewhere than the sliders themselves.
  function stopAll(zero) {
    if (zero) {
      for (const s of sliders) s.value = "0";
      for (const o of outs) o.pct.textContent = "0 %";
    }
    if (!running) return chain;
    running = false;
    updateState();
    return enqueue(async () => {
      try {
        await api("POST", "/api/motor_test/stop", {}, { quiet: true });
      } catch (e) {
        // The backend's dead-man stops the test anyway once the refreshes stop; say so.
        showMessage(`stop request failed (${e.reason || e.message}); the controller stops the test by itself when the page's refreshes stop`);
      }
    });
  }

  function stopNow() {
    for (const s of sliders) s.value = "0";
    for (const o of outs) o.pct.textContent = "0 %";
    running = true; // send the stop even if the page believed nothing ran
    stopAll(false);
  }

  setInterval(() => {
    if (running && anyUp()) sendRefresh();
  }, REFRESH_MS);

  $("motor-props-removed").addEventListener("change", () => {
    if (!$("motor-props-removed").checked) stopNow();
    gate();
  });
  $("motor-stop").onclick = stopNow;
  ctx.onStop(() => {
    for (const s of sliders) s.value = "0";
    for (const o of outs) o.pct.textContent = "0 %";
    running = false;
    updateState();
  });

  // SAFETY: leaving the screen or the page stops the test (the dead-man's other half).
  ctx.onScreen(({ from, to }) => {
    if (to === "motors" && from !== "motors" && !running) readCap();
    if (from === "motors" && to !== "motors") {
      if (running) stopNow();
      $("motor-props-removed").checked = false;
      gate();
    }
  });
  document.addEventListener("visibilitychange", () => {
    if (document.hidden && running) stopNow();
  });
  window.addEventListener("pagehide", () => {
    // The WebSocket closing stops the test on the backend as well; this says it directly.
    if (running) {
      fetch("/api/motor_test/stop", {
        method: "POST", keepalive: true,
        headers: { "X-Hoverfly-Token": token, "Content-Type": "application/json" }, body: "{}",
      }).catch(() => {});
    }
  });

  ctx.onLink(gate);
  ctx.onStatus(gate);
  let lastArmed = false;
  ctx.onTelemetry((t) => {
    const armed = !!t.armed;
    if (armed !== lastArmed) {
      lastArmed = armed;
      gate();
    }
    if (!Array.isArray(t.motors)) return;
    if (t.motors.length && t.motors.length !== sliders.length && !running) build(t.motors.length);
    if (ctx.screen !== "motors") return;
    t.motors.forEach((v, i) => {
      if (!outs[i]) return;
      outs[i].out.textContent = v <= 1.0001 ? `out ${(v * 100).toFixed(0)} %` : `out ${Math.round(v)} µs`;
    });
  });

  build(4);
}
