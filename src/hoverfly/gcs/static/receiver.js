// The Receiver and modes screen: live channel bars from telemetry, the channel map (rc_map, shown
// and typed as Betaflight's AETR1234 letters) and the AUX mode ranges (the *_ch / *_min_us /
// *_max_us parameter rows), each drawn over the live position of its channel.

const $ = (id) => document.getElementById(id);

// rc_map's digits are the receiver channel of each function, in this order (core/config/params.py).
const FUNCTIONS = ["A", "E", "R", "T", "1", "2", "3", "4"];
const FUNCTION_NAMES = { A: "roll", E: "pitch", R: "yaw", T: "throttle", 1: "AUX1", 2: "AUX2", 3: "AUX3", 4: "AUX4" };
const MODE_NAMES = { arm: "ARM", angle: "ANGLE", horizon: "HORIZON", airmode: "AIR MODE", fs_switch: "FAILSAFE",
  ap: "AUTOPILOT" };
const PULSE_MIN_US = 900;
const PULSE_MAX_US = 2100;

// 12435678 -> "AETR1234": the letter of the function each receiver channel 1..8 carries.
export function mapLetters(rcMap) {
  const digits = String(rcMap);
  if (!/^[1-8]{8}$/.test(digits)) return null;
  const letters = new Array(8).fill("?");
  for (let f = 0; f < 8; f++) letters[Number(digits[f]) - 1] = FUNCTIONS[f];
  return letters.join("");
}

// "AETR1234" -> 12435678, or an error in words (each letter once, as Betaflight's `map` wants).
export function mapDigits(letters) {
  const s = String(letters).trim().toUpperCase();
  if (s.length !== 8) return { error: "the map needs 8 letters, one per receiver channel (e.g. AETR1234)" };
  const digits = new Array(8);
  for (let c = 0; c < 8; c++) {
    const f = FUNCTIONS.indexOf(s[c]);
    if (f < 0) return { error: `'${s[c]}' is not one of A E R T 1 2 3 4` };
    if (digits[f] !== undefined) return { error: `'${s[c]}' is used twice: each function takes one channel` };
    digits[f] = c + 1;
  }
  return { value: Number(digits.join("")) };
}

function pct(us) {
  return (100 * (Math.min(Math.max(us, PULSE_MIN_US), PULSE_MAX_US) - PULSE_MIN_US)) / (PULSE_MAX_US - PULSE_MIN_US);
}

export function initReceiver(ctx) {
  const { showMessage } = ctx;
  let letters = "AETR1234";
  let bars = [];
  let modes = [];       // [{key, ch, min, max, el}]
  const edits = {};     // param name -> value waiting for "Apply mode ranges"

  function buildBars(n) {
    const box = $("rc-bars");
    bars = [];
    const out = [];
    for (let i = 0; i < n; i++) {
      const row = document.createElement("div");
      row.className = "rcbar";
      row.dataset.channel = String(i + 1); // 1-based, as the *_ch parameters count (AUX1 = 5)
      const label = document.createElement("span");
      const track = document.createElement("div");
      track.className = "track";
      const fill = document.createElement("div");
      fill.className = "fill";
      track.append(fill);
      const val = document.createElement("span");
      val.className = "val";
      val.textContent = "—";
      row.append(label, track, val);
      out.push(row);
      bars.push({ label, fill, val });
    }
    box.replaceChildren(...out);
    labelBars();
  }

  // Telemetry's rc is Betaflight's rcData: after the channel map, in function order (roll, pitch,
  // yaw, throttle, AUX1...), so the bars are labelled as Betaflight's Receiver tab labels them and
  // each shows which receiver channel feeds it.
  function labelBars() {
    bars.forEach((b, i) => {
      const letter = i < 8 ? FUNCTIONS[i] : null;
      const name = i < 4 ? FUNCTION_NAMES[letter] : `AUX${i - 3}`;
      const from = letter ? letters.indexOf(letter) + 1 : i + 1;
      b.label.textContent = `${name[0].toUpperCase()}${name.slice(1)}`;
      b.label.title = `${name}: receiver channel ${from}`;
      b.label.dataset.receiverChannel = String(from);
    });
  }

  function buildModes(byName) {
    const box = $("aux-ranges");
    modes = [];
    const out = [];
    for (const [name, p] of byName) {
      if (!name.endsWith("_ch")) continue;
      const key = name.slice(0, -3);
      const min = byName.get(`${key}_min_us`);
      const max = byName.get(`${key}_max_us`);
      const el = document.createElement("div");
      el.className = "aux";
      el.dataset.mode = key;
      const title = document.createElement("div");
      const b = document.createElement("b");
      b.textContent = MODE_NAMES[key] || key.toUpperCase();
      const help = document.createElement("span");
      help.className = "dim";
      help.textContent = p.help || "";
      title.append(b, " ", help);
      const row = document.createElement("div");
      row.className = "row";
      row.append(field("channel", p));
      if (min && max) row.append(field("from", min), field("to", max));
      el.append(title, row);
      const track = document.createElement("div");
      track.className = "track";
      const range = document.createElement("div");
      range.className = "range";
      const marker = document.createElement("div");
      marker.className = "marker";
      track.append(range, marker);
      if (min && max) el.append(track);
      out.push(el);
      modes.push({ key, ch: p, min, max, el, range, marker });
    }
    if (!out.length) {
      const p = document.createElement("p");
      p.className = "dim";
      p.textContent = "no mode channels in this controller's parameter table";
      out.push(p);
    }
    box.replaceChildren(...out);
    drawRanges();
  }

  function field(label, p) {
    const l = document.createElement("label");
    l.textContent = `${label} `;
    const input = document.createElement("input");
    input.type = "text";
    input.dataset.param = p.name;
    input.dataset.screen = "receiver";
    input.title = `${p.name}: ${p.min} .. ${p.max} ${p.unit || ""}`;
    if (p.value === null || p.value === undefined) {
      // not readable on this link (the seed's maintenance port carries no mode ranges)
      input.disabled = true;
      input.placeholder = "—";
    } else {
      input.value = String(p.value);
    }
    input.addEventListener("input", () => {
      const v = Number(input.value);
      const ok = input.value.trim() !== "" && Number.isInteger(v) && v >= p.min && v <= p.max;
      input.classList.toggle("bad", !ok);
      input.style.borderColor = ok ? "" : "var(--bad)";
      if (ok && v !== p.value) edits[p.name] = v;
      else delete edits[p.name];
      if (!ok) input.title = `${p.name} must be a whole number ${p.min} .. ${p.max} ${p.unit || ""}`;
      $("aux-apply").disabled = !Object.keys(edits).length || document.querySelector("#aux-ranges input.bad") !== null;
      drawRanges();
    });
    l.append(input);
    return l;
  }

  function value(p) {
    return p.name in edits ? edits[p.name] : p.value;
  }
  // a range drawn only when both ends are known
  const known = (p) => p && value(p) !== null && value(p) !== undefined;

  function drawRanges() {
    for (const m of modes) {
      m.range.hidden = !known(m.min) || !known(m.max);
      if (m.range.hidden) continue;
      const lo = pct(value(m.min));
      const hi = pct(value(m.max));
      m.range.style.left = `${Math.min(lo, hi)}%`;
      m.range.style.width = `${Math.abs(hi - lo)}%`;
    }
  }

  $("aux-apply").onclick = async () => {
    if (ctx.armed()) {
      showMessage("nothing sent: configuration changes are refused while armed (disarm first)");
      return;
    }
    try {
      await ctx.params.applyValues({ ...edits });
      for (const k of Object.keys(edits)) delete edits[k];
      $("aux-apply").disabled = true;
      showMessage("mode ranges applied (Save on the Parameters screen keeps them)", "info");
      ctx.params.reload();
    } catch (e) {
      // shown by api()
    }
  };

  $("rc-map-apply").onclick = async () => {
    const r = mapDigits($("rc-map").value);
    if (r.error) {
      showMessage(`channel map not sent: ${r.error}`);
      return;
    }
    if (ctx.armed()) {
      showMessage("nothing sent: configuration changes are refused while armed (disarm first)");
      return;
    }
    try {
      await ctx.params.applyValues({ rc_map: r.value });
      showMessage(`channel map ${$("rc-map").value.toUpperCase()} applied`, "info");
      ctx.params.reload();
    } catch (e) {
      // shown by api()
    }
  };

  ctx.onParams((byName) => {
    const m = byName.get("rc_map");
    const mapKnown = !!m && m.value !== null && m.value !== undefined;
    $("rc-map").disabled = !mapKnown;
    $("rc-map-apply").disabled = !mapKnown;
    if (!mapKnown) $("rc-map-text").textContent = "the channel map is not readable on this link";
    if (mapKnown) {
      letters = mapLetters(m.value) || letters;
      $("rc-map").value = letters;
      $("rc-map-text").textContent = `rc_map = ${m.value}`;
      labelBars();
    }
    for (const k of Object.keys(edits)) delete edits[k];
    $("aux-apply").disabled = true;
    buildModes(byName);
  });

  ctx.onTelemetry((t) => {
    if (ctx.screen !== "receiver" || !Array.isArray(t.rc)) return;
    if (bars.length !== t.rc.length) buildBars(t.rc.length);
    t.rc.forEach((us, i) => {
      bars[i].fill.style.width = `${pct(us)}%`;
      bars[i].val.textContent = String(Math.round(us));
    });
    for (const m of modes) {
      const ch = value(m.ch);
      const us = ch >= 1 && ch <= t.rc.length ? t.rc[ch - 1] : null;
      m.marker.hidden = us === null;
      if (us !== null) m.marker.style.left = `calc(${pct(us)}% - 1px)`;
      const active = us !== null && m.min && us >= value(m.min) && us <= value(m.max);
      m.el.classList.toggle("active", !!active);
    }
  });

  buildBars(8);
}
