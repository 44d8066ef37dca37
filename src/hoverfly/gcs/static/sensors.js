// The Sensors screen: live uPlot charts of gyro, accelerometer, attitude, setpoints and motor
// outputs from the 50 Hz telemetry. Every message is kept (the buffers fill even while another
// screen is shown), and the charts redraw once per animation frame while this screen is visible.

const $ = (id) => document.getElementById(id);

const AXIS_COLOURS = ["#ff6b6b", "#51cf66", "#4dabf7", "#fcc419", "#cc5de8", "#ff922b", "#20c997", "#f06595"];
const MAX_WINDOW_S = 30;
const CHART_HEIGHT = 190; // two rows of charts fit a 768 px laptop screen
// Redraws at most 20 times a second: every sample is kept and drawn, and the main thread (which
// also sends the Fly screen's sticks, and the backend gives up on them after 250 ms) is not spent
// redrawing faster than the eye reads. #sensor-rate shows the slowest redraw of the last second.
const MIN_REDRAW_MS = 50;

const CHARTS = [
  { key: "gyro_dps", title: "Gyro", unit: "deg/s", names: ["roll", "pitch", "yaw"] },
  { key: "acc_g", title: "Accelerometer", unit: "g", names: ["x", "y", "z"] },
  // yaw on its own right-hand scale: a heading of 0..360 would flatten roll and pitch
  { key: "attitude_deg", title: "Attitude", unit: "deg", names: ["roll", "pitch", "yaw"], ownScale: 2 },
  { key: "setpoint_dps", title: "Rate setpoints", unit: "deg/s", names: ["roll", "pitch", "yaw"] },
  { key: "motors", title: "Motor outputs", unit: "", names: null },
];

export function initSensors(ctx) {
  const time = [];
  const series = {};      // key -> array of arrays (one per component)
  for (const c of CHARTS) series[c.key] = [];
  let charts = null;
  let paused = false;
  let dirty = false;
  let t0 = null;
  let rxInWindow = 0;
  let windowStartMs = performance.now();

  function windowS() {
    return Number($("sensor-window").value) || 10;
  }

  function makeChart(c, box, width) {
    const n = c.names ? c.names.length : Math.max(1, series[c.key].length);
    const names = c.names || Array.from({ length: n }, (_, i) => `M${i + 1}`);
    const axis = { stroke: "#8b94a3", grid: { stroke: "#2a3039", width: 1 }, ticks: { stroke: "#2a3039" } };
    const axes = [{ ...axis, label: "s" }, { ...axis, label: c.unit, size: 56 }];
    if (c.ownScale !== undefined) axes.push({ ...axis, scale: "own", side: 1, size: 50, grid: { show: false },
      label: `${names[c.ownScale]} (${c.unit})` });
    const opts = {
      width,
      height: CHART_HEIGHT,
      legend: { live: true },
      cursor: { drag: { x: false, y: false } },
      scales: { x: { time: false } },
      axes,
      series: [{ label: "t", value: (u, v) => (v == null ? "—" : v.toFixed(2)) },
        ...names.map((name, i) => ({ label: name, stroke: AXIS_COLOURS[i % AXIS_COLOURS.length], width: 1.5,
          scale: i === c.ownScale ? "own" : "y", value: (u, v) => (v == null ? "—" : v.toFixed(2)) }))],
    };
    return new window.uPlot(opts, dataFor(c, 0, n), box);
  }

  // uPlot wants one array per series, each as long as the time array: a component the telemetry
  // has not carried (null, or fewer motors) is drawn as a gap.
  function dataFor(c, from, n) {
    const arrs = series[c.key];
    const out = [time.slice(from)];
    for (let i = 0; i < n; i++) out.push(arrs[i] ? arrs[i].slice(from) : new Array(time.length - from).fill(null));
    return out;
  }

  function build() {
    const root = $("sensor-charts");
    root.replaceChildren();
    charts = [];
    if (!window.uPlot) {
      root.textContent = "uPlot did not load (static/vendor/uPlot.iife.min.js): no charts";
      return;
    }
    for (const c of CHARTS) {
      const card = document.createElement("div");
      card.className = "chart";
      card.id = `chart-${c.key}`;
      const h = document.createElement("h2");
      h.textContent = `${c.title}${c.unit ? " (" + c.unit + ")" : ""}`;
      const note = document.createElement("span");
      note.className = "dim";
      h.append(note);
      const box = document.createElement("div");
      card.append(h, box);
      root.append(card);
      charts.push({ c, box, note, plot: null, n: 0 });
    }
    for (const ch of charts) {
      ch.n = Math.max(1, series[ch.c.key].length);
      ch.plot = makeChart(ch.c, ch.box, Math.max(300, ch.box.clientWidth - 4));
    }
  }


  function resize() {
    if (!charts) return;
    for (const ch of charts) ch.plot.setSize({ width: Math.max(300, ch.box.clientWidth - 4), height: CHART_HEIGHT });
  }
  window.addEventListener("resize", resize);

  function trim() {
    const keepFrom = time.length ? time[time.length - 1] - MAX_WINDOW_S : 0;
    let k = 0;
    while (k < time.length && time[k] < keepFrom) k++;
    if (k > 50) {
      time.splice(0, k);
      for (const key in series) for (const arr of series[key]) arr.splice(0, k);
    }
  }

  ctx.onTelemetry((t) => {
    const nowS = performance.now() / 1000;
    if (t0 === null) t0 = nowS;
    time.push(nowS - t0);
    for (const c of CHARTS) {
      const v = Array.isArray(t[c.key]) ? t[c.key] : [];
      const arrs = series[c.key];
      while (arrs.length < v.length) arrs.push(new Array(time.length - 1).fill(null));
      for (let i = 0; i < arrs.length; i++) arrs[i].push(i < v.length && typeof v[i] === "number" ? v[i] : null);
    }
    trim();
    rxInWindow++;
    dirty = true;
  });

  let lastDrawMs = 0;
  let drawMs = 0; // the slowest redraw of the last second, shown so a slow laptop is visible

  function frame(nowMs) {
    if (ctx.screen === "sensors" && !paused && dirty && charts && nowMs - lastDrawMs >= MIN_REDRAW_MS) {
      dirty = false;
      lastDrawMs = nowMs;
      const t0 = performance.now();
      const last = time.length ? time[time.length - 1] : 0;
      const from = last - windowS();
      let k = 0;
      while (k < time.length && time[k] < from) k++;
      for (const ch of charts) {
        const arrs = series[ch.c.key];
        if (!ch.c.names && Math.max(1, arrs.length) !== ch.n) {
          // the motor count is known only from telemetry: rebuild that chart's series once
          ch.plot.destroy();
          ch.box.replaceChildren();
          ch.n = Math.max(1, arrs.length);
          ch.plot = makeChart(ch.c, ch.box, Math.max(300, ch.box.clientWidth - 4));
        }
        ch.plot.setData(dataFor(ch.c, k, ch.c.names ? ch.c.names.length : ch.n));
        // an empty chart says why rather than looking broken
        const none = !arrs.some((a) => a.length && a[a.length - 1] !== null);
        ch.note.textContent = none ? "  not carried by this link" : "";
      }
      // uPlot draws in a microtask after setData: measure after it
      queueMicrotask(() => { drawMs = Math.max(drawMs, performance.now() - t0); });
    }
    requestAnimationFrame(frame);
  }
  requestAnimationFrame(frame);

  setInterval(() => {
    const now = performance.now();
    const hz = (rxInWindow * 1000) / (now - windowStartMs);
    rxInWindow = 0;
    windowStartMs = now;
    $("sensor-rate").textContent = `telemetry ${hz.toFixed(0)} Hz, ${time.length} samples kept, redraw ≤ ${drawMs.toFixed(0)} ms`;
    drawMs = 0;
  }, 1000);

  $("sensor-pause").onclick = () => {
    paused = !paused;
    $("sensor-pause").textContent = paused ? "Resume" : "Pause";
  };
  $("sensor-window").addEventListener("change", () => { dirty = true; });

  ctx.onScreen(({ to }) => {
    if (to !== "sensors") return;
    // uPlot needs the container's width, known only once the screen is visible
    requestAnimationFrame(() => {
      if (!charts) build();
      else resize();
      dirty = true;
    });
  });
}
