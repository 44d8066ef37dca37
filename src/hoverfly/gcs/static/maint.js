// The Maintenance screen: every seed-001 command as a form (from GET /api/maint/commands, so the
// page holds no copy of the command table) and telemetry by header field (GET /api/maint/fields,
// POST /api/maint/read): tick the fields, read once or every half second, see the values by name.

const $ = (id) => document.getElementById(id);

// Ranges of the seed's wire types (struct codes in protocols/maintenance.py): the backend checks
// again; this only catches a typo before anything is sent.
const INT_RANGE = { B: [0, 255], H: [0, 65535], I: [0, 4294967295], int: [-2147483648, 2147483647] };
const MOTOR_COMMANDS = /^(set_motor|set_all_motors|control_motors)/;
const POLL_MS = 500;

function argSpecs(cmd) {
  // Accept {args: [{name, type, min, max}]}, {args: ["name", ...], format: "BHH"} or {arg_names, format}.
  const raw = cmd.args || cmd.arg_names || [];
  const fmt = cmd.format || cmd.fmt || "";
  return raw.map((a, i) => {
    if (typeof a === "string") return { name: a, type: fmt[i] || "f" };
    return { name: a.name, type: a.type || a.fmt || fmt[i] || "f", min: a.min, max: a.max, unit: a.unit,
      choices: a.choices };
  });
}

export function checkArg(spec, text) {
  const t = String(text).trim();
  if (spec.choices && spec.choices.length) {
    const i = spec.choices.findIndex((c) => String(c) === t);
    if (i < 0) return { error: `${spec.name} must be one of ${spec.choices.join(", ")}` };
    return { value: typeof spec.choices[i] === "number" ? spec.choices[i] : i };
  }
  if (t === "" || !/^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$/.test(t)) return { error: `${spec.name}: '${t}' is not a number` };
  const v = Number(t);
  const type = spec.type === "float" ? "f" : spec.type;
  let lo = spec.min;
  let hi = spec.max;
  if (type !== "f") {
    if (!Number.isInteger(v)) return { error: `${spec.name} takes whole numbers` };
    const r = INT_RANGE[type] || INT_RANGE.int;
    if (lo === undefined || lo === null) lo = r[0];
    if (hi === undefined || hi === null) hi = r[1];
  }
  if ((lo !== undefined && lo !== null && v < lo) || (hi !== undefined && hi !== null && v > hi)) {
    return { error: `${spec.name} = ${t} is out of range: ${lo} .. ${hi}${spec.unit ? " " + spec.unit : ""}` };
  }
  return { value: v };
}

function showValue(v) {
  if (Array.isArray(v)) return `[${v.map(showValue).join(", ")}]`;
  if (typeof v === "number" && !Number.isInteger(v)) return String(Number(v.toPrecision(6)));
  if (v && typeof v === "object") return JSON.stringify(v);
  return String(v);
}

function replyText(r) {
  if (r === null || r === undefined) return "(empty reply)";
  if (typeof r !== "object") return String(r);
  const values = r.values && typeof r.values === "object" ? r.values : r;
  const lines = [];
  for (const k of Object.keys(values)) lines.push(`${k.padEnd(20)} ${showValue(values[k])}`);
  const head = r.cmd_id !== undefined ? `reply to command ${r.cmd_id}${r.refused ? " (REFUSED)" : ""}\n` : "";
  return head + (lines.join("\n") || "(no values)");
}

export function initMaint(ctx) {
  const { api, showMessage } = ctx;
  let loaded = false;
  let polling = null;
  let busy = false;

  async function load() {
    let commands;
    try {
      commands = await api("GET", "/api/maint/commands", undefined, { quiet: true });
    } catch (e) {
      $("maint-commands").textContent = `no command list: ${e.reason || e.message}`;
      $("maint-commands").className = "error-text";
      return;
    }
    loaded = true;
    renderCommands(Array.isArray(commands) ? commands : commands.commands || []);
    let fields = [];
    try {
      fields = await api("GET", "/api/maint/fields", undefined, { quiet: true });
    } catch (e) {
      $("maint-reply").textContent = `no header field list: ${e.reason || e.message}`;
    }
    renderFields(Array.isArray(fields) && fields.length ? fields : SEED_FIELDS);
  }

  function renderCommands(commands) {
    const box = $("maint-commands");
    box.className = "";
    const guard = document.createElement("label");
    guard.className = "confirm";
    guard.innerHTML = '<input id="maint-props-removed" type="checkbox"> propellers removed: allow the motor commands';
    const out = [guard];
    commands.forEach((cmd, k) => {
      const id = cmd.id !== undefined ? cmd.id : k;
      if (cmd.name === "none") return; // "no command" is the telemetry read on the right
      const specs = argSpecs(cmd);
      const form = document.createElement("form");
      form.className = "maint-cmd";
      form.dataset.command = cmd.name;
      const title = document.createElement("div");
      title.className = "title";
      title.textContent = `${id} ${cmd.name}`;
      if (cmd.help) {
        const help = document.createElement("span");
        help.className = "dim";
        help.textContent = ` ${cmd.help}`;
        title.append(help);
      }
      const row = document.createElement("div");
      row.className = "row";
      const inputs = specs.map((s) => {
        const l = document.createElement("label");
        l.textContent = `${s.name} `;
        let input;
        if (s.choices && s.choices.length) {
          input = document.createElement("select");
          for (const c of s.choices) {
            const o = document.createElement("option");
            o.textContent = String(c);
            input.append(o);
          }
        } else {
          input = document.createElement("input");
          input.type = "text";
          input.placeholder = s.type === "f" || s.type === "float" ? "0.0" : "0";
        }
        input.name = s.name;
        input.dataset.arg = s.name;
        l.append(input);
        row.append(l);
        return input;
      });
      const send = document.createElement("button");
      send.type = "submit";
      send.textContent = "Send";
      row.append(send);
      form.append(title, row);
      form.addEventListener("submit", async (ev) => {
        ev.preventDefault();
        const args = [];
        for (let i = 0; i < specs.length; i++) {
          const r = checkArg(specs[i], inputs[i].value);
          if (r.error) {
            showMessage(`${cmd.name} not sent: ${r.error}`);
            inputs[i].focus();
            return;
          }
          args.push(r.value);
        }
        // SAFETY: the seed's motor commands drive the outputs directly; they need the same
        // explicit confirmation as the motor test, and are never sent while armed.
        if (MOTOR_COMMANDS.test(cmd.name)) {
          if (!$("maint-props-removed").checked) {
            showMessage(`${cmd.name} not sent: tick "propellers removed" first`);
            return;
          }
          if (ctx.armed()) {
            showMessage(`${cmd.name} not sent: refused while armed`);
            return;
          }
        }
        try {
          const r = await api("POST", "/api/maint/command", { name: cmd.name, args });
          $("maint-reply").textContent = `${cmd.name}: ok\n${replyText(r)}`;
        } catch (e) {
          $("maint-reply").textContent = `${cmd.name}: ${e.reason || e.message}`;
        }
      });
      out.push(form);
    });
    box.replaceChildren(...out);
  }

  function renderFields(fields) {
    const box = $("maint-fields");
    box.replaceChildren(...fields.map((f) => {
      const name = typeof f === "string" ? f : f.name;
      const l = document.createElement("label");
      const c = document.createElement("input");
      c.type = "checkbox";
      c.dataset.field = name;
      c.checked = /^body_(roll|pitch|yaw)$|^motors_armed$/.test(name);
      l.append(c, ` ${name}`);
      if (f && f.help) l.title = f.help;
      return l;
    }));
  }

  function selectedFields() {
    return [...document.querySelectorAll("#maint-fields input:checked")].map((c) => c.dataset.field);
  }

  async function read() {
    if (busy) return;
    const fields = selectedFields();
    if (!fields.length) {
      $("maint-reply").textContent = "tick at least one header field";
      return;
    }
    busy = true;
    try {
      const r = await api("POST", "/api/maint/read", { fields }, { quiet: polling !== null });
      $("maint-reply").textContent = replyText(r);
    } catch (e) {
      $("maint-reply").textContent = `read failed: ${e.reason || e.message}`;
      stopPolling();
    } finally {
      busy = false;
    }
  }

  function stopPolling() {
    if (polling !== null) clearInterval(polling);
    polling = null;
    $("maint-poll").checked = false;
  }

  $("maint-read").onclick = read;
  $("maint-fields-none").onclick = () => {
    for (const c of document.querySelectorAll("#maint-fields input")) c.checked = false;
  };
  $("maint-poll").addEventListener("change", () => {
    if ($("maint-poll").checked) polling = setInterval(read, POLL_MS);
    else stopPolling();
  });

  // The seed's commands travel only on a maintenance port; on an MSP/CLI port the backend refuses
  // them, so the screen says so up front rather than after each Send.
  ctx.onStatus((s) => {
    const proto = s.link && s.link.protocol;
    const note = $("maint-note");
    note.hidden = proto !== "msp";
    note.textContent = proto === "msp"
      ? "This port speaks MSP + CLI: the seed-001 commands and header-field telemetry need the maintenance port (hoverfly sim serves it on its --maint-port, 5762 by default; on a Pico, UART0 through the HC-05, /dev/rfcomm0)."
      : "";
  });

  ctx.onScreen(({ to }) => {
    if (to === "maint" && !loaded) load();
    if (to !== "maint") stopPolling();
  });
}

// The seed's 57 header fields, in header order (seed 001, protocols/maintenance.py FIELDS): used
// only when the backend cannot list them (GET /api/maint/fields failed), so the screen still
// shows what can be asked for.
const SEED_FIELDS = [
  "raw_accel_x", "raw_accel_y", "raw_accel_z", "raw_gyro_x", "raw_gyro_y", "raw_gyro_z",
  "raw_magn_x", "raw_magn_y", "raw_magn_z", "filtered_accel_x", "filtered_accel_y", "filtered_accel_z",
  "filtered_gyro_x", "filtered_gyro_y", "filtered_gyro_z", "filtered_magn_x", "filtered_magn_y", "filtered_magn_z",
  "throttle_signal", "roll_signal", "pitch_signal", "throttle_set_point", "roll_set_point", "pitch_set_point",
  "body_roll", "body_pitch", "body_yaw", "roll_PID_error", "roll_PID_p", "roll_PID_i", "roll_PID_d", "roll_PID_u",
  "pitch_PID_error", "pitch_PID_p", "pitch_PID_i", "pitch_PID_d", "pitch_PID_u",
  "yaw_PID_error", "yaw_PID_p", "yaw_PID_i", "yaw_PID_d", "yaw_PID_u",
  "motor1_signal", "motor2_signal", "motor3_signal", "motor4_signal", "motors_armed", "builtin_test_status",
  "motor_params", "js_params", "PID_params", "ptf1_params", "imu_type", "i2c_read", "sw_ver", "imu_offset",
  "throttle_params",
];
