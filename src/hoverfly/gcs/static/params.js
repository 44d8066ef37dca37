// The Parameters screen: the controller's whole parameter table (from the schema the backend
// reads out of core/config/params.py), grouped and searchable, with every edit checked against the
// row's range or choices before anything is sent; Apply sends the edits, Save also writes them
// to flash; export the diff against defaults; import a diff file through a preview.

const $ = (id) => document.getElementById(id);

const BACKUP_KEY = "hoverfly-diff-backups";
const BACKUPS_KEPT = 10;

// Parse and check one typed value against its row. Returns {value} or {error} in plain words.
// The backend checks again (params.check, including rules a range cannot express, such as
// rc_map being a permutation): this check is so a mistake is shown before anything is sent.
export function checkValue(p, text) {
  const choices = p.choices || null;
  if (choices && choices.length) {
    const hit = choices.find((c) => String(c) === String(text).trim());
    if (hit === undefined) return { error: `${p.name} must be one of ${choices.join(", ")}` };
    return { value: hit };
  }
  const t = String(text).trim();
  if (t === "") return { error: `${p.name} needs a value` };
  if (!/^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$/.test(t)) return { error: `${p.name}: '${t}' is not a number` };
  const v = Number(t);
  if (!Number.isFinite(v)) return { error: `${p.name}: '${t}' is not a number` };
  const isInt = p.type === "int" || p.type === "bool";
  if (isInt && !Number.isInteger(v)) return { error: `${p.name} takes whole numbers` };
  const unit = p.unit ? ` ${p.unit}` : "";
  if (typeof p.min === "number" && typeof p.max === "number" && (v < p.min || v > p.max)) {
    return { error: `${p.name} = ${t} is out of range: ${p.min} .. ${p.max}${unit}` };
  }
  return { value: v };
}

function same(a, b) {
  if (typeof a === "number" && typeof b === "number") return Math.abs(a - b) <= 1e-9 * Math.max(1, Math.abs(a));
  return String(a) === String(b);
}

function show(v) {
  if (typeof v === "number" && !Number.isInteger(v)) return String(Number(v.toPrecision(7)));
  return String(v);
}

export function initParams(ctx) {
  const { api, showMessage } = ctx;
  let rows = [];               // the table as last read
  const byName = new Map();
  const pending = new Map();   // name -> checked value waiting to be sent
  const invalid = new Map();   // name -> reason
  let loaded = false;
  let previewText = null;

  ctx.params = { byName, reload: load, applyValues };

  async function load() {
    try {
      const list = await api("GET", "/api/params");
      rows = Array.isArray(list) ? list : [];
      byName.clear();
      for (const p of rows) byName.set(p.name, p);
      loaded = true;
      const readable = rows.filter((p) => p.value !== null && p.value !== undefined).length;
      $("param-note").textContent = readable < rows.length ? `${readable} of ${rows.length} readable on this link` : "";
      $("param-note").title = readable < rows.length ? "the others need the MSP/CLI port" : "";
      render();
      loadDiff();
      for (const fn of ctx.paramHandlers) fn(byName);
    } catch (e) {
      $("param-body").replaceChildren(messageRow(`cannot read the parameters: ${e.reason || e.message}`));
    }
  }
  ctx.paramHandlers = [];
  ctx.onParams = (fn) => ctx.paramHandlers.push(fn);

  async function loadDiff() {
    try {
      $("diff-current").textContent = await api("GET", "/api/diff", undefined, { text: true, quiet: true });
    } catch (e) {
      $("diff-current").textContent = `(no diff: ${e.reason || e.message})`;
    }
  }

  function messageRow(text) {
    const tr = document.createElement("tr");
    const td = document.createElement("td");
    td.colSpan = 6;
    td.className = "error-text";
    td.textContent = text;
    tr.append(td);
    return tr;
  }

  function render() {
    const body = $("param-body");
    const groups = new Map();
    for (const p of rows) {
      const g = p.group || "other";
      if (!groups.has(g)) groups.set(g, []);
      groups.get(g).push(p);
    }
    const out = [];
    for (const [g, list] of groups) {
      const head = document.createElement("tr");
      head.className = "group";
      head.dataset.group = g;
      const td = document.createElement("td");
      td.colSpan = 6;
      td.textContent = g;
      head.append(td);
      out.push(head);
      for (const p of list) out.push(rowFor(p));
    }
    body.replaceChildren(...out);
    filter();
    updateButtons();
  }

  function rowFor(p) {
    const tr = document.createElement("tr");
    tr.dataset.name = p.name;
    tr.dataset.group = p.group || "other";
    const name = document.createElement("td");
    name.className = "name";
    name.textContent = p.name;
    if (p.reboot || p.applies === "reboot" || p.applies === "REBOOT") {
      const badge = document.createElement("span");
      badge.className = "badge";
      badge.textContent = "reboot";
      badge.title = "takes effect after a save and reboot";
      name.append(" ", badge);
    }
    let input;
    if (p.choices && p.choices.length) {
      input = document.createElement("select");
      for (const c of p.choices) {
        const o = document.createElement("option");
        o.value = String(c);
        o.textContent = String(c);
        input.append(o);
      }
    } else {
      input = document.createElement("input");
      input.type = "text";
      input.inputMode = "decimal";
      input.spellcheck = false;
    }
    input.dataset.param = p.name;
    if (p.value === null || p.value === undefined) {
      // the link cannot read this row (the seed's maintenance protocol carries only a few)
      input.value = "";
      input.placeholder = "—";
      input.title = "not readable on this link (the MSP/CLI port has every parameter)";
      input.disabled = true;
    } else {
      input.value = show(pending.has(p.name) ? pending.get(p.name) : p.value);
    }
    input.addEventListener("input", () => edited(p, input, tr));
    input.addEventListener("change", () => edited(p, input, tr));
    const val = document.createElement("td");
    val.append(input);
    const err = document.createElement("div");
    err.className = "row-error";
    val.append(err);
    const unit = document.createElement("td");
    unit.textContent = p.unit || "";
    const range = document.createElement("td");
    range.className = "range";
    range.textContent = p.choices && p.choices.length ? "" : `${show(p.min)} .. ${show(p.max)}`;
    const def = document.createElement("td");
    def.className = "default";
    def.textContent = show(p.default);
    if (p.value !== null && p.value !== undefined) {
      // per-row revert: puts the default in the box as an edit, sent with the others
      const revert = document.createElement("button");
      revert.className = "revert";
      revert.textContent = "↺";
      revert.title = `back to the default (${show(p.default)})`;
      revert.dataset.revert = p.name;
      revert.onclick = () => {
        input.value = show(p.default);
        edited(p, input, tr);
      };
      def.append(" ", revert);
    }
    const help = document.createElement("td");
    help.className = "help";
    help.textContent = p.help || "";
    tr.append(name, val, unit, range, def, help);
    classify(p, tr);
    return tr;
  }

  function classify(p, tr) {
    tr.classList.toggle("changed", p.value !== null && p.value !== undefined && !same(p.value, p.default));
    tr.classList.toggle("pending", pending.has(p.name));
    tr.classList.toggle("invalid", invalid.has(p.name));
    tr.querySelector(".row-error").textContent = invalid.get(p.name) || "";
  }

  function edited(p, input, tr) {
    const r = checkValue(p, input.value);
    pending.delete(p.name);
    invalid.delete(p.name);
    if (r.error) invalid.set(p.name, r.error);
    else if (!same(r.value, p.value)) pending.set(p.name, r.value);
    classify(p, tr);
    updateButtons();
  }

  function updateButtons() {
    const n = pending.size;
    const bad = invalid.size;
    const parts = [];
    if (n) parts.push(`${n} edit${n > 1 ? "s" : ""} not sent`);
    if (bad) parts.push(`${bad} invalid`);
    $("param-pending").textContent = parts.join(", ");
    $("param-apply").disabled = n === 0 || bad > 0 || !ctx.linkUp();
    $("param-save").disabled = bad > 0 || !ctx.linkUp();
  }
  ctx.onLink(updateButtons);

  function filter() {
    const q = $("param-search").value.trim().toLowerCase();
    const changedOnly = $("param-changed-only").checked;
    const visibleGroups = new Set();
    for (const tr of $("param-body").querySelectorAll("tr[data-name]")) {
      const p = byName.get(tr.dataset.name);
      const hay = `${p.name} ${p.help || ""} ${p.group || ""}`.toLowerCase();
      const changed = p.value !== null && p.value !== undefined && !same(p.value, p.default);
      const show = (!q || hay.includes(q)) && (!changedOnly || changed || pending.has(p.name));
      tr.hidden = !show;
      if (show) visibleGroups.add(tr.dataset.group);
    }
    for (const tr of $("param-body").querySelectorAll("tr.group")) tr.hidden = !visibleGroups.has(tr.dataset.group);
  }
  $("param-search").addEventListener("input", filter);
  $("param-changed-only").addEventListener("change", filter);

  function refuseWhy() {
    if (invalid.size) {
      const first = invalid.values().next().value;
      return `nothing sent: fix the marked value${invalid.size > 1 ? "s" : ""} first (${first})`;
    }
    if (!ctx.linkUp()) return "nothing sent: no link to the controller";
    if (ctx.armed()) return "nothing sent: configuration changes are refused while armed (disarm first)";
    return null;
  }

  // All-or-nothing on the backend too: either every value lands or none does.
  async function applyValues(values) {
    await api("POST", "/api/params", values);
  }

  async function applyPending() {
    if (!pending.size) return true;
    const why = refuseWhy();
    if (why) {
      showMessage(why);
      return false;
    }
    try {
      await applyValues(Object.fromEntries(pending));
      pending.clear();
      return true;
    } catch (e) {
      return false; // api() has shown the backend's reason; the edits stay for correcting
    }
  }

  $("param-apply").onclick = async () => {
    const needReboot = [...pending.keys()].filter((n) => byName.get(n) && byName.get(n).reboot);
    if (await applyPending()) {
      showMessage(needReboot.length
        ? `parameters applied (not yet saved); ${needReboot.join(", ")} take effect after Save and a reboot`
        : "parameters applied (not yet saved to flash)", "info");
      await load();
    }
  };

  // Before each Save the controller's diff is kept in this browser (the last BACKUPS_KEPT), so a
  // save that went wrong can be undone through the import preview: Betaflight users' most asked
  // for safety net (betaflight-configurator #3242).
  function backups() {
    try {
      const list = JSON.parse(localStorage.getItem(BACKUP_KEY) || "[]");
      return Array.isArray(list) ? list : [];
    } catch (e) {
      return [];
    }
  }

  function showBackups() {
    const sel = $("param-backups");
    const first = sel.options[0];
    sel.replaceChildren(first, ...backups().map((b, i) => {
      const o = document.createElement("option");
      o.value = String(i);
      o.textContent = `before save ${b.at}`;
      return o;
    }));
  }

  async function backup() {
    try {
      const text = await api("GET", "/api/diff", undefined, { text: true, quiet: true });
      const list = backups();
      list.unshift({ at: new Date().toLocaleString(), text });
      localStorage.setItem(BACKUP_KEY, JSON.stringify(list.slice(0, BACKUPS_KEPT)));
      showBackups();
    } catch (e) {
      // no backup is no reason to refuse the save the user asked for
    }
  }

  $("param-backups").addEventListener("change", () => {
    const b = backups()[Number($("param-backups").value)];
    $("param-backups").value = "";
    if (!b) return;
    $("diff-text").value = b.text;
    resetPreview();
    showMessage(`backup from ${b.at} loaded into the import box: press Preview to see what it would change`, "info");
  });
  showBackups();

  $("param-save").onclick = async () => {
    const why = refuseWhy();
    if (why) {
      showMessage(why);
      return;
    }
    await backup();
    if (!(await applyPending())) return;
    try {
      await api("POST", "/api/save", {});
      showMessage("saved to flash", "info");
    } catch (e) {
      // shown by api()
    }
    await load();
  };

  $("param-reload").onclick = () => {
    pending.clear();
    invalid.clear();
    load();
  };

  $("param-export").onclick = async () => {
    try {
      const text = await api("GET", "/api/diff", undefined, { text: true });
      const blob = new Blob([text], { type: "text/plain" });
      const a = document.createElement("a");
      a.href = URL.createObjectURL(blob);
      const stamp = new Date().toISOString().slice(0, 19).replace(/[:T]/g, "-");
      a.download = `hoverfly-diff-${stamp}.txt`;
      document.body.append(a);
      a.click();
      a.remove();
      setTimeout(() => URL.revokeObjectURL(a.href), 1000);
    } catch (e) {
      // shown by api()
    }
  };

  // ---- import through a preview ---------------------------------------------------------

  $("diff-file").addEventListener("change", async () => {
    const f = $("diff-file").files[0];
    if (!f) return;
    if (f.size > 256 * 1024) {
      showMessage(`${f.name} is ${Math.round(f.size / 1024)} KiB: a diff file is a few KiB; not read`);
      return;
    }
    $("diff-text").value = await f.text();
    resetPreview();
  });
  $("diff-text").addEventListener("input", resetPreview);

  function resetPreview() {
    previewText = null;
    $("diff-apply").disabled = true;
    $("diff-preview").replaceChildren();
  }

  $("diff-preview-btn").onclick = async () => {
    resetPreview();
    const text = $("diff-text").value;
    if (!text.trim()) {
      showMessage("paste a diff or open a file first");
      return;
    }
    let changes;
    try {
      changes = await api("POST", "/api/diff/preview", { text });
    } catch (e) {
      const p = document.createElement("p");
      p.className = "error-text";
      p.textContent = `preview refused: ${e.reason || e.message}`;
      $("diff-preview").replaceChildren(p);
      return;
    }
    const list = Array.isArray(changes) ? changes : (changes && changes.changes) || [];
    const errors = (changes && changes.errors) || [];
    const box = $("diff-preview");
    const parts = [];
    if (errors.length) {
      // The backend applies a file all-or-nothing: with an error in it, Apply would be refused,
      // so it stays disabled and the lines to fix are listed.
      const p = document.createElement("div");
      p.id = "diff-errors";
      p.className = "error-text";
      p.textContent = `${errors.length} line${errors.length > 1 ? "s" : ""} cannot be applied; fix the file first:`;
      const ul = document.createElement("ul");
      for (const e of errors) {
        const li = document.createElement("li");
        li.textContent = e.line !== undefined ? `line ${e.line}: ${e.error}` : String(e.error || e);
        ul.append(li);
      }
      p.append(ul);
      parts.push(p);
    }
    if (!list.length) {
      const p = document.createElement("p");
      p.textContent = "nothing would change: every value in the file is already set";
      box.replaceChildren(...parts, p);
      return;
    }
    const table = document.createElement("table");
    table.id = "diff-preview-table";
    const head = document.createElement("tr");
    for (const h of ["Parameter", "Now", "After import"]) {
      const th = document.createElement("th");
      th.textContent = h;
      head.append(th);
    }
    table.append(head);
    for (const c of list) {
      const tr = document.createElement("tr");
      tr.dataset.name = c.name;
      for (const v of [c.name, show(c.old), show(c.new)]) {
        const td = document.createElement("td");
        td.textContent = v;
        tr.append(td);
      }
      table.append(tr);
    }
    const note = document.createElement("p");
    note.className = "dim";
    note.textContent = `${list.length} parameter${list.length > 1 ? "s" : ""} would change. Nothing is sent until you press Apply.`;
    box.replaceChildren(...parts, note, table);
    if (errors.length) return;
    previewText = text;
    $("diff-apply").disabled = false;
  };

  $("diff-apply").onclick = async () => {
    const text = $("diff-text").value;
    if (previewText === null || text !== previewText) {
      showMessage("preview the file again: it changed since the preview");
      resetPreview();
      return;
    }
    if (ctx.armed()) {
      showMessage("nothing sent: configuration changes are refused while armed (disarm first)");
      return;
    }
    try {
      await api("POST", "/api/diff/apply", { text });
      showMessage("diff applied (press Save to keep it after a reboot)", "info");
      resetPreview();
      await load();
    } catch (e) {
      // shown by api()
    }
  };

  ctx.onScreen(({ to }) => {
    if (to === "params" && !loaded) load();
  });
  // A link that comes back may be another controller, or one that rebooted: read the table again
  // (edits not yet sent are kept).
  ctx.onLink((up) => {
    if (up) load();
  });
}
