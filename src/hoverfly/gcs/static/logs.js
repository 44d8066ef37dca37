// The Logs screen: the flight logs (*.ulg) in the directory `hoverfly gcs --logs DIR` names, and
// `hoverfly log report`'s page for one, made on request and shown in the app.

const $ = (id) => document.getElementById(id);

function size(bytes) {
  if (bytes >= 1 << 20) return `${(bytes / (1 << 20)).toFixed(1)} MiB`;
  if (bytes >= 1 << 10) return `${(bytes / (1 << 10)).toFixed(0)} KiB`;
  return `${bytes} B`;
}

function when(modified) {
  // seconds since the epoch (the file's mtime), shown in the browser's own time zone
  const d = new Date(typeof modified === "number" ? modified * 1000 : modified);
  return Number.isNaN(d.getTime()) ? String(modified) : d.toLocaleString();
}

export function initLogs(ctx) {
  const { api } = ctx;

  async function load() {
    let list;
    try {
      list = await api("GET", "/api/logs");
    } catch (e) {
      $("logs-body").replaceChildren(row(`cannot list the logs: ${e.reason || e.message}`));
      return;
    }
    if (!Array.isArray(list) || !list.length) {
      $("logs-body").replaceChildren(row("no flight logs (*.ulg) in the log directory (hoverfly gcs --logs DIR)"));
      return;
    }
    $("logs-body").replaceChildren(...list.map((l) => {
      const tr = document.createElement("tr");
      tr.dataset.log = l.name;
      const name = document.createElement("td");
      name.className = "mono";
      name.textContent = l.name;
      const sz = document.createElement("td");
      sz.textContent = size(l.size_bytes);
      const mod = document.createElement("td");
      mod.textContent = when(l.modified);
      const act = document.createElement("td");
      const b = document.createElement("button");
      b.dataset.report = l.name;
      b.textContent = l.report ? "Show report" : "Make report";
      b.onclick = () => (l.report ? show(l.name, l.report, null) : make(l.name, b));
      act.append(b);
      tr.append(name, sz, mod, act);
      return tr;
    }));
  }

  function row(text) {
    const tr = document.createElement("tr");
    const td = document.createElement("td");
    td.colSpan = 4;
    td.className = "dim";
    td.textContent = text;
    tr.append(td);
    return tr;
  }

  async function make(name, button) {
    button.disabled = true;
    button.textContent = "making…";
    try {
      const r = await api("POST", "/api/logs/report", { name });
      show(name, r.url, r);
      load();
    } catch (e) {
      button.disabled = false;
      button.textContent = "Make report";
    }
  }

  function show(name, url, r) {
    $("log-report-title").textContent = name;
    const notes = [];
    if (r && typeof r.steps === "number") notes.push(`${r.steps} step${r.steps === 1 ? "" : "s"} found for the step response`);
    if (r && Array.isArray(r.warnings) && r.warnings.length) notes.push(`warnings: ${r.warnings.join("; ")}`);
    $("log-report-notes").textContent = notes.join(". ");
    $("log-report-open").href = url;
    $("log-report-open").hidden = false;
    $("log-report").src = url;
    $("log-report").hidden = false;
  }

  $("logs-refresh").onclick = load;
  ctx.onScreen(({ to }) => {
    if (to === "logs") load();
  });
}
