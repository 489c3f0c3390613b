// rotorbench serve: the pages' behaviour. Served by the app itself (CSP script-src 'self').
"use strict";

const LAYOUT = {margin: {l: 60, r: 20, t: 30, b: 40}, height: 230,
                font: {size: 11}, showlegend: false};
const CONFIG = {displaylogo: false, responsive: true};

async function getJSON(url) {
  const resp = await fetch(url, {credentials: "same-origin"});
  if (!resp.ok) throw new Error(`${url}: ${resp.status} ${await resp.text()}`);
  return resp.json();
}

function el(tag, attrs = {}, text = "") {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (text) e.textContent = text;
  return e;
}

function fail(box, err) {
  box.replaceChildren(el("p", {class: "error"}, String(err)));
}

async function runPage() {
  const box = document.getElementById("plots");
  if (!box) return;
  try {
    const data = await getJSON(box.dataset.series);  // preloaded while plotly.js loads
    box.replaceChildren();
    for (const p of data.plots) {
      const div = el("div", {class: "plot", id: "plot-" + p.key});
      box.appendChild(div);
      // a flight plot has several traces (gyro and setpoint, one per motor): a legend
      const traces = (p.traces || [{name: p.title, t: p.t, y: p.y}]).map(
        (tr) => ({x: tr.t, y: tr.y, type: "scatter", mode: "lines", line: {width: 1},
                  name: tr.name}));
      await Plotly.newPlot(div, traces,
                           {...LAYOUT, showlegend: traces.length > 1,
                            title: {text: `${p.title} (${p.unit})`},
                            xaxis: {title: {text: "t (s)"}}}, CONFIG);
    }
    box.dataset.painted = String(data.plots.length);
  } catch (err) { fail(box, err); }
  const fits = document.getElementById("fits");
  try {
    const f = await getJSON(fits.dataset.fits);
    fits.replaceChildren(fitTable(f));
    fits.dataset.done = "1";
  } catch (err) { fail(fits, err); }
}

function fmt(v, digits = 4) {
  return (typeof v === "number") ? Number(v.toPrecision(digits)).toString() : String(v);
}

function fitTable(f) {
  const wrap = el("div");
  if (f.step) {
    wrap.appendChild(el("h3", {}, `step response (${f.step.signal}, first-order plus delay)`));
    const t = el("table", {class: "kv", id: "fit-step"});
    for (const k of ["latency_up_ms", "tau_up_ms", "t63_up_ms", "latency_down_ms",
                     "tau_down_ms", "t63_down_ms", "gain_up", "gain_down"]) {
      if (f.step[k] === undefined || f.step[k] === null) continue;
      const tr = el("tr"); tr.append(el("th", {}, k), el("td", {}, fmt(f.step[k])));
      t.appendChild(tr);
    }
    wrap.appendChild(t);
    const n = (f.step.edges || []).length;
    wrap.appendChild(el("p", {}, `${n} edges fitted one by one`));
  } else {
    wrap.appendChild(el("p", {}, "step fit: " + (f.step_why || "n/a")));
  }
  if (f.static) {
    wrap.appendChild(el("h3", {}, "static curves"));
    const t = el("table", {class: "kv", id: "fit-static"});
    for (const [k, v] of Object.entries(f.static)) {
      if (v === null || typeof v === "object") continue;
      const tr = el("tr"); tr.append(el("th", {}, k), el("td", {}, fmt(v)));
      t.appendChild(tr);
    }
    wrap.appendChild(t);
  } else {
    wrap.appendChild(el("p", {}, "static curves: " + (f.static_why || "n/a")));
  }
  return wrap;
}

async function comparePage() {
  const box = document.getElementById("compare");
  if (!box) return;
  try {
    const d = await getJSON(box.dataset.compare);
    const curves = [["thrust_vs_rpm", "thrust vs speed", "rpm", "N"],
                    ["current_a_vs_thrust", "current vs thrust", "N", "A"],
                    ["efficiency_g_w_vs_thrust", "efficiency vs thrust", "N", "g/W"]];
    for (const [key, title, xu, yu] of curves) {
      const traces = d.static.filter(s => s[key]).map(s => (
        {x: s[key].x, y: s[key].y, type: "scatter", mode: "lines+markers", name: s.run_id}));
      await Plotly.newPlot(document.getElementById(key), traces,
        {...LAYOUT, height: 300, showlegend: true, title: {text: title},
         xaxis: {title: {text: xu}}, yaxis: {title: {text: yu}}}, CONFIG);
    }
    const steps = [];
    for (const s of d.steps.filter(s => s.t)) {
      if (s.up) steps.push({x: s.t, y: s.up, type: "scatter", mode: "lines",
                            name: `${s.run_id} rising (${s.up_edges})`});
      if (s.down) steps.push({x: s.t, y: s.down, type: "scatter", mode: "lines",
                              line: {dash: "dash"}, name: `${s.run_id} falling (${s.down_edges})`});
    }
    await Plotly.newPlot(document.getElementById("steps"), steps,
      {...LAYOUT, height: 300, showlegend: true, title: {text: "mean step responses, normalised (solid rising, dashed falling)"},
       xaxis: {title: {text: "t after the command edge (s)"}}}, CONFIG);
    const why = d.steps.filter(s => s.why).map(s => `${s.run_id}: ${s.why}`);
    document.getElementById("compare-notes").textContent = why.join("; ");
    box.dataset.painted = String(d.static.length);
  } catch (err) { fail(box, err); }
}

async function benchesPage() {
  // one panel per constant: each bench's value with its U (k = 2); red: |E_n| > 1
  // against every other bench, orange: against some
  const box = document.getElementById("benches");
  if (!box) return;
  try {
    const d = await getJSON(box.dataset.benches);
    for (const c of d.constants) {
      const others = c.benches.length - 1;
      const color = b => b.flagged_pairs === 0 ? "#1f3a5f"
        : (b.flagged_pairs === others ? "#b00020" : "#e07b00");
      const div = el("div", {class: "plot", id: "bench-" + c.constant});
      box.appendChild(div);
      await Plotly.newPlot(div, [{
        x: c.benches.map(b => b.bench), y: c.benches.map(b => b.value), type: "scatter",
        mode: "markers", marker: {size: 9, color: c.benches.map(color)},
        error_y: {type: "data", array: c.benches.map(b => b.U === null ? 0 : b.U),
                  visible: true}}],
        {...LAYOUT, height: 260, title: {text: `${c.constant} (${c.unit})`},
         yaxis: {exponentformat: "e"}}, CONFIG);
    }
    box.dataset.painted = String(d.constants.length);
  } catch (err) { fail(box, err); }
}

function runsPage() {
  const table = document.getElementById("runs");
  if (!table) return;
  const form = document.getElementById("compare-form");
  form.addEventListener("submit", () => {
    const ids = [...document.querySelectorAll("input.pick:checked")].map(c => c.value);
    document.getElementById("compare-runs").value = ids.join(",");
  });
  async function poll() {
    try {
      const live = await getJSON(table.dataset.live);
      for (const r of live) {
        const row = table.querySelector(`tr[data-run="${CSS.escape(r.run_id)}"]`);
        if (!row) continue;
        row.querySelector(".status").textContent = r.status;
        const latest = Object.entries(r.latest || {}).filter(([k]) => k !== "t_s")
          .map(([k, v]) => `${k} ${fmt(v, 3)}`).join(", ");
        row.querySelector(".live").textContent =
          `${r.elapsed_s === null ? "" : fmt(r.elapsed_s, 3) + " s"} ${latest}`;
      }
      table.dataset.polled = String(Number(table.dataset.polled || 0) + 1);
    } catch (err) { /* the next poll tries again */ }
  }
  poll();
  setInterval(poll, 2000);
}

document.addEventListener("DOMContentLoaded", () => {
  runsPage(); runPage(); comparePage(); benchesPage();
});
