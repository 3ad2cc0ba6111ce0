// marie monitor: draws the state the server reduces from the event stream.
// Live: one EventSource on /api/live (snapshot, state, lagged). Replay: the state at time T
// from /api/replay/state?at_ms=T, T moved by play/pause, speed and the slider.
// A click on a binding asks the live operation for its properties (/api/props); with faults
// allowed, a button per fault kind the monitor names (/api/info) posts it (/api/fault); with
// changes allowed, a form adds or removes a datamanager's replica on a node (/api/replicas).
// Plain JavaScript, no build step; every element has a stable id, class or data attribute
// (browser tests query them).
"use strict";

const token = new URLSearchParams(location.search).get("token");
const withToken = (path) =>
  token ? path + (path.includes("?") ? "&" : "?") + "token=" + encodeURIComponent(token) : path;
const $ = (sel) => document.querySelector(sel);
const esc = (s) =>
  String(s ?? "").replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[c]);
const fmtMs = (ms) => (ms == null ? "" : (ms / 1000).toFixed(1) + " s");
// an event time (ms of its node's clock), shown from the first event of the stream
const fmtAt = (ms) => (ms == null ? "" : fmtMs(ms - ((latest && latest.start_ms) || 0)));

let selectedOp = null;
let latest = null;
// what /api/info says the page may offer
let offers = { properties: false, operation_faults: false, stoppable_nodes: [], cuttable: false };
// whether the page may add and remove datamanagers' replicas (/api/info)
let changesAllowed = false;
// the fault kinds by what they aim at (/api/info): a button per kind
let faultKinds = { operation: [], node: [], cut: [], datamanager: [] };
// what each kind does, for its button's title (a kind without one is titled by its name)
const FAULT_TITLES = {
  kill: "kill its actor: its supervisor restarts it",
  panic: "make it panic: its supervisor restarts it",
  hang: "stop it answering: the dispatcher's deadline kills it",
  slow: "make its steps come five times slower: it keeps answering, its control suffers",
  "stop-node": "kill its process (SIGKILL), as a crash would",
  "freeze-node": "freeze its process (SIGSTOP) for 5 s, then let it go on (SIGCONT)",
  partition: "cut it off from every other node for 5 s, both ways, then heal",
};
// a node button's label, by kind
const NODE_FAULT_LABELS = { "stop-node": "stop", "freeze-node": "freeze", partition: "cut off" };
// the live properties of the selected binding: {op, node, address, groups} or {error}
let liveProps = null;

// Replace an element's content only when it changed: a redraw ten times a second must not
// swallow a click on the element under the pointer.
function setHtml(el, html) {
  if (el.drawnHtml !== html) {
    el.innerHTML = html;
    el.drawnHtml = html; // a property, not an attribute: the DOM does not hold it twice
  }
}

async function getJson(path) {
  const res = await fetch(withToken(path), { cache: "no-store" });
  if (!res.ok) throw new Error(path + ": " + res.status);
  return res.json();
}

// --- drawing -----------------------------------------------------------------------------

// How long the latest render took (ms, its script's part: the DOM updates, not the browser's
// layout after), and how many renders there were: on <body> for whoever measures the page.
let renders = 0;

function render(state) {
  const t0 = performance.now();
  latest = state;
  renderHeader(state);
  renderTree(state.mission);
  renderControl(state);
  renderBindings(state.bindings);
  refreshProps(state.bindings);
  renderCluster(state.cluster);
  renderNoMajority(state.no_majority || {});
  renderStrength(state.strength || {});
  renderReplicaForm(state);
  renderRobot(state.robot);
  renderTimeline(state.timeline);
  document.body.dataset.renders = String(++renders);
  document.body.dataset.renderMs = (performance.now() - t0).toFixed(2);
}

function renderHeader(state) {
  const m = state.mission;
  $("#mission-name").textContent = m.name ? "mission " + m.name : "no run yet";
  $("#clock").textContent = fmtAt(state.at_ms) + " · " + state.events + " events" +
    (state.missed ? " · " + state.missed + " missed" : "");
  const out = $("#outcome");
  const o = m.outcome;
  const verdict = o ? o.outcome : m.name ? "running" : "waiting";
  out.dataset.outcome = verdict;
  out.textContent = o ? verdict + (o.reason ? ": " + o.reason : "") : verdict;
  out.title = o && o.judgement ? o.judgement : "";
}

function flags(list, cls) {
  return (list || []).map((f) => `<span class="flag ${cls || ""}" data-flag="${esc(f)}">${esc(f)}</span>`).join("");
}

function renderTree(m) {
  setHtml($("#flags"), flags(m.flags, "status"));
  setHtml($("#tree"), m.actions
    .map((a) => {
      const ops = a.ops
        .map((o) => `<li class="op" data-op="${esc(o.name)}" data-ended="${esc(o.ended || "waiting")}">` +
          `${esc(o.key)}${a.ends_on.includes(o.key) ? " <span class=\"ends\" title=\"ends the action\">(ends)</span>" : ""}` +
          `${o.ended ? " · " + esc(o.ended) : ""}${o.flags.length ? " " + flags(o.flags) : ""}</li>`)
        .join("");
      const when = a.when.length ? `<div class="when">when ${flags(a.when)}</div>` : "";
      const span = a.started_ms != null ? ` ${fmtMs(a.started_ms)}${a.ended_ms != null ? "–" + fmtMs(a.ended_ms) : ""}` : "";
      return `<li class="action" data-action="${esc(a.name)}" data-state="${a.state}">` +
        `<span class="name">${esc(a.name)}</span><span class="state">${a.state}${span}</span>` +
        `${when}<ul class="ops">${ops}</ul></li>`;
    })
    .join(""));
}

// --- the behaviour tree ----------------------------------------------------------------------
// A run that announces its behaviour tree (state.tree, issue 24) gets it drawn instead of the
// list of actions (#tree: still drawn, hidden, and shown again for a stream without a tree).
// One compact row per item, indented by its depth, in a scrolling list; nothing collapsed.
// Built once per plan; an update then touches only the rows whose item changed (a
// signature of what a row shows), so a tree of hundreds of items costs an update a few
// hundred string comparisons and the DOM writes of what changed.
const ctree = { key: null, rows: [], sigs: [], builds: 0 };
// a retry's attempts in all, from its detail (`3 attempts, 2.0 s apart`)
const attemptsOf = (detail) => parseInt(detail || "", 10) || null;
const times = (n) => (n > 1 ? " ×" + n : "");

function renderControl(state) {
  const t0 = performance.now();
  const t = state.tree;
  const list = $("#control-tree");
  const has = !!(t && t.items && t.items.length);
  list.hidden = !has;
  $("#control-summary").hidden = !has;
  $("#tree").hidden = has;
  if (!has) {
    if (ctree.key !== null) {
      list.replaceChildren();
      Object.assign(ctree, { key: null, rows: [], sigs: [] });
    }
    return;
  }
  const key = state.mission.name + "#" + t.plan + "#" + t.items.length;
  if (key !== ctree.key) buildControl(list, t.items, key);
  const actions = new Map(state.mission.actions.map((a) => [a.name, a]));
  let updated = 0;
  const running = [];
  for (const n of t.items) {
    const a = n.kind === "action" ? actions.get(n.label) : undefined;
    const sig = itemSig(n, a);
    if (sig !== ctree.sigs[n.id]) {
      drawNode(ctree.rows[n.id], n, a);
      ctree.sigs[n.id] = sig;
      updated++;
    }
    if (n.running && n.kind === "action") running.push(n);
  }
  setHtml($("#control-summary"), `${t.items.length} items · ` +
    (running.length
      ? "running " + running.map((n) => `<button type="button" class="goto" data-id="${n.id}" title="show it">${esc(n.label)}</button>`).join(" ")
      : "nothing runs"));
  list.dataset.updated = String(updated);
  list.dataset.renderMs = (performance.now() - t0).toFixed(2);
}

// The rows of a new plan, in one parse.
function buildControl(list, items, key) {
  list.innerHTML = items
    .map((n) => `<li class="titem" data-id="${n.id}" data-kind="${esc(n.kind)}" data-depth="${n.depth}" ` +
      `data-label="${esc(n.label)}" data-state="waiting" style="--depth:${n.depth}">` +
      `<span class="st"></span><span class="kind">${esc(n.kind)}</span><span class="label">${esc(n.label)}</span>` +
      `<span class="marks"></span><span class="detail">${esc(n.detail)}</span></li>`)
    .join("");
  ctree.rows = Array.from(list.children, (li) => ({
    li, marks: li.querySelector(".marks"), detail: li.querySelector(".detail"),
  }));
  ctree.sigs = [];
  ctree.key = key;
  list.dataset.builds = String(++ctree.builds);
  list.dataset.items = String(items.length);
}

// What a row shows of item `n` (and of its action `a`): equal signatures, equal rows.
function itemSig(n, a) {
  return [n.running, n.ended, n.starts, n.attempt, n.gave_up, n.timeouts, n.fallbacks,
    n.conditions_lost, n.recoveries, n.told,
    a ? a.ops.map((o) => o.key + ":" + (o.ended || "")).join(",") : ""].join("|");
}

function drawNode(row, n, a) {
  const { li } = row;
  li.dataset.state = n.running ? "running" : n.ended || "waiting";
  const marks = [];
  if (n.starts > 1) marks.push(`<span class="mark starts" title="started ${n.starts} times">run ${n.starts}</span>`);
  if (n.kind === "retry") {
    const [at, of] = n.attempt || [1, attemptsOf(n.detail)];
    if (of && (n.attempt || n.running || n.ended)) {
      marks.push(`<span class="mark attempt" data-attempt="${at}/${of}">attempt ${at} of ${of}</span>`);
    }
  }
  if (n.gave_up) marks.push(`<span class="mark gave-up">gave up</span>`);
  if (n.timeouts) marks.push(`<span class="mark timeout" data-timeouts="${n.timeouts}">timed out${times(n.timeouts)}</span>`);
  if (n.fallbacks) marks.push(`<span class="mark fallback" data-fallbacks="${n.fallbacks}">fell back${times(n.fallbacks)}</span>`);
  if (n.conditions_lost) marks.push(`<span class="mark condition-lost">condition lost${times(n.conditions_lost)}</span>`);
  if (n.recoveries) marks.push(`<span class="mark recovery">recovered${times(n.recoveries)}</span>`);
  row.marks.innerHTML = marks.join("");
  // an action's operations, each as far as it got (after the flags it waits for, if any:
  // a detail `when wall-found; ultrasonic, localizer`)
  if (a && a.ops.length) {
    const when = /^when [^;]*/.exec(n.detail || "");
    row.detail.innerHTML = (when ? `<span class="when">${esc(when[0])}</span> ` : "") + a.ops
      .map((o) => `<span class="op" data-op="${esc(o.name)}" data-ended="${esc(o.ended || "waiting")}">${esc(o.key)}</span>`)
      .join(" ");
  }
  const told = (n.decisions || []).map((d) => `\n${fmtMs(d.run_ms)} ${d.text}`).join("");
  li.title = n.label + (n.detail ? " — " + n.detail : "") +
    (n.told > (n.decisions || []).length ? `\n(${n.told} decisions, the latest:)` : "") + told;
}

$("#control-summary").addEventListener("click", (ev) => {
  const button = ev.target.closest("button.goto");
  const row = button && ctree.rows[Number(button.dataset.id)];
  if (row) row.li.scrollIntoView({ block: "center" });
});

function renderBindings(bindings) {
  // epochs are fencing tokens (a run's start in ms × 1000, plus one per binding): shown
  // from the lowest one of the table, the full value on hover
  const epochs = Object.values(bindings).map((b) => b.epoch).filter((e) => e > 0);
  const base = epochs.length ? Math.min(...epochs) : 0;
  const epochText = (e) => (e > 0 && base > 0 ? "+" + (e - base) : String(e));
  const rows = Object.values(bindings).map((b) => {
    const hist = b.history.length
      ? `<tr class="history-row" data-op="${esc(b.operation)}"><td colspan="8"><ul class="history">` +
        b.history.map((h) => `<li class="${h.type}" data-type="${h.type}">${fmtAt(h.at_ms)} ${esc(describeStep(h))}</li>`).join("") +
        `</ul></td></tr>`
      : "";
    const target = `data-op="${esc(b.operation)}" data-node="${esc(b.node)}" data-address="${esc(b.address)}"`;
    const faults = offers.operation_faults && b.status === "bound"
      ? faultKinds.operation.map((k) =>
        `<button type="button" class="fault" data-fault="${esc(k)}" ${target} title="${esc(FAULT_TITLES[k] || k)}">${esc(k)}</button>`).join("")
      : "";
    return `<tr class="binding${selectedOp === b.operation ? " selected" : ""}" data-op="${esc(b.operation)}" ` +
      `data-status="${b.status}" data-rebinds="${b.rebinds}" data-epoch="${b.epoch}">` +
      `<td>${esc(b.operation)}</td><td class="address">${esc(b.address)}</td><td>${esc(b.node)}</td>` +
      `<td>${esc(b.version)}</td><td class="epoch" title="epoch ${b.epoch}">${epochText(b.epoch)}</td><td>${b.rebinds}</td><td>${b.status}</td>` +
      `<td class="faults">${faults}</td></tr>${hist}`;
  });
  setHtml($("#bindings tbody"), rows.join(""));
  renderProps(bindings);
}

function describeStep(h) {
  switch (h.type) {
    case "lost": return "lost: " + h.cause;
    case "rebound": return `rebound ${h.from} → ${h.to} (${h.to_node}) after ${h.downtime_ms} ms: ${h.cause}`;
    case "gave_up": return `gave up after ${h.waited_ms} ms: ${h.cause}`;
    default: return h.type;
  }
}

function renderProps(bindings) {
  const box = $("#props");
  const b = selectedOp && bindings[selectedOp];
  if (!b) { box.hidden = true; setHtml(box, ""); return; }
  box.hidden = false;
  box.dataset.op = b.operation;
  // the live answer, while it is the bound instance's
  const asked = liveProps && liveProps.op === b.operation && liveProps.address === b.address ? liveProps : null;
  box.dataset.live = asked ? (asked.error ? "error" : "true") : "false";
  const cands = b.candidates
    .map((c) => `<tr class="candidate" data-verdict="${c.verdict.type}"><td>${esc(c.address)}</td><td>${esc(c.node)}</td>` +
      `<td>${esc(c.version)}</td><td>${esc(c.schema.join(", "))}</td><td>${flags(c.flags)}</td>` +
      `<td>${esc(c.verdict.type)}${c.verdict.reason ? ": " + esc(c.verdict.reason) : ""}</td></tr>`)
    .join("");
  setHtml(box, `<strong>${esc(b.operation)}</strong> — bound to ${esc(b.address)} on ${esc(b.node)}, version ${esc(b.version)}, epoch ${b.epoch}, ` +
    `${b.rebinds} rebind(s), ${b.status}` +
    (asked ? liveHtml(asked) : offers.properties ? `<p class="asking">asking the operation…</p>` : "") +
    (cands ? `<h3>the dispatcher's choice</h3><table class="candidates"><thead><tr><th>address</th><th>node</th><th>version</th><th>parameters</th><th>flags</th><th>verdict</th></tr></thead><tbody>${cands}</tbody></table>` : ""));
}

// a property value: {"Float": 0.6} -> 0.6
const val = (v) => (v && typeof v === "object" ? Object.values(v)[0] : v);

function liveHtml(p) {
  if (p.error) return `<p class="live-error">${esc(p.error)}</p>`;
  const g = {};
  for (const reply of p.groups) Object.assign(g, reply);
  const id = g.Identification || {}, loc = g.Location || {}, gen = g.General || {}, spec = g.Specific || { params: [] };
  const params = spec.params.map((d) => {
    const range = d.min != null || d.max != null ? `[${d.min ?? "−∞"}, ${d.max ?? "+∞"}]` : "";
    const ty = typeof d.ty === "object" ? Object.keys(d.ty)[0] + " " + JSON.stringify(Object.values(d.ty)[0]) : d.ty;
    return `<tr class="param" data-param="${esc(d.name)}"><td>${esc(d.name)}</td><td>${esc(ty)}</td>` +
      `<td>${esc(val(d.default))}${d.unit ? " " + esc(d.unit) : ""}</td><td>${esc(range)}</td>` +
      `<td>${esc(val((spec.previous || {})[d.name]))}</td><td class="current">${esc(val((spec.current || {})[d.name]))}</td>` +
      `<td>${esc(d.description)}${d.read_only ? " (read-only)" : ""}</td></tr>`;
  }).join("");
  return `<div class="live-props" data-version="${esc(id.version)}" data-in-use="${gen.in_use}">` +
    `<p>${esc(id.name)} (id ${esc(id.id)}) version ${esc(id.version)} — ${esc(id.description)}</p>` +
    `<p>on ${esc(loc.node)} at ${esc(loc.address)} · up ${fmtMs(gen.uptime_ms)} · ${gen.in_use ? "in use" : "idle"} · ` +
    `${gen.activations} activation(s) · epoch ${gen.epoch} · deadline ${gen.deadline_ms} ms</p>` +
    `<table class="params"><thead><tr><th>parameter</th><th>type</th><th>default</th><th>range</th><th>previous</th><th>current</th><th></th></tr></thead>` +
    `<tbody>${params}</tbody></table>` +
    (spec.flags && spec.flags.length ? `<p>flags: ${flags(spec.flags.map((f) => f.name))}</p>` : "") +
    `</div>`;
}

// Ask again when the selected binding moved to another instance (a rebind).
function refreshProps(bindings) {
  const b = selectedOp && bindings[selectedOp];
  if (b && b.address && !askProps.inFlight && (!liveProps || liveProps.address !== b.address)) askProps(b);
}

async function askProps(b) {
  if (!offers.properties || !b) return;
  askProps.inFlight = true;
  try {
    await askPropsOf(b);
  } finally {
    askProps.inFlight = false;
  }
}

async function askPropsOf(b) {
  const answer = await fetchProps({ operation: b.operation, node: b.node, address: b.address });
  liveProps = { op: b.operation, address: b.address, ...answer };
  if (latest) renderProps(latest.bindings);
}

// /api/props for {operation, node?, address?}: {groups} or {error}.
async function fetchProps(op) {
  const q = new URLSearchParams({ operation: op.operation });
  if (op.node) q.set("node", op.node);
  if (op.address) q.set("address", op.address);
  try {
    const res = await fetch(withToken("/api/props?" + q), { cache: "no-store" });
    const body = await res.json().catch(() => ({ error: res.status + " " + res.statusText }));
    return res.ok ? { groups: body } : { error: body.error || String(res.status) };
  } catch (e) {
    return { error: "cannot reach the monitor: " + e };
  }
}

// Whether a node is up (one woken from a freeze is up again, and may be faulted as any other).
function isUp(n) {
  return n.status === "up";
}

// A node's latest wake from a freeze past its peers' deadline: its operations restarted as
// new incarnations then.
function woke(n) {
  if (!n.woke) return "";
  return ` <span class="woke" title="its operations restarted as new incarnations">` +
    `(woke at ${fmtAt(n.woke.at_ms)} from a ${(n.woke.silent_ms / 1000).toFixed(1)} s freeze)</span>`;
}

// A node's latest return after it was lost (restarted, or heard again): when, after how long.
function back(n) {
  if (!n.back) return "";
  return ` <span class="back" title="lost, then seen again by a peer">` +
    `(back at ${fmtAt(n.back.at_ms)} after ${(n.back.down_ms / 1000).toFixed(1)} s down)</span>`;
}

// The replicated datamanagers without a leader now, in the words marie ls says them.
function renderNoMajority(lost) {
  setHtml($("#no-majority"), Object.entries(lost)
    .map(([dm, v]) => `<div class="no-majority" data-dm="${esc(dm)}" ` +
      `data-missing="${esc(v.missing.join(","))}">no majority: ${esc(v.words)}</div>`)
    .join(""));
}

// Each replicated datamanager's way back to full strength: the lost replicas caught up,
// and when every replica was current again, as its leader told it.
function renderStrength(strength) {
  setHtml($("#strength"), Object.entries(strength)
    .map(([dm, v]) => {
      const caught = Object.entries(v.caught_up)
        .map(([node, ms]) => `<span class="caught-up" data-node="${esc(node)}">` +
          `replica on ${esc(node)} caught up ${(ms / 1000).toFixed(1)} s after its loss</span>`);
      const restored = v.restored
        ? [`<span class="restored" data-after-ms="${v.restored.after_ms}">redundancy restored at ` +
          `${fmtAt(v.restored.at_ms)}: all ${v.restored.replicas} replicas current ` +
          `${(v.restored.after_ms / 1000).toFixed(1)} s after the first loss</span>`]
        : [];
      return `<div class="strength" data-dm="${esc(dm)}">${esc(dm)}: ` +
        caught.concat(restored).join("; ") + `</div>`;
    })
    .join(""));
}

// The form that adds or removes a replica, when the page may: the replicated datamanagers
// and the nodes the page knows of, offered (any name may be typed: the cluster answers).
function renderReplicaForm(state) {
  const form = $("#replicas");
  form.hidden = !changesAllowed;
  if (!changesAllowed) return;
  const dms = new Set([...Object.keys(state.strength || {}), ...Object.keys(state.no_majority || {})]);
  const nodes = [];
  for (const n of Object.values(state.cluster)) {
    if (isUp(n)) nodes.push(n.name);
    for (const m of Object.values(n.modules)) if (m.dm && m.dm.role) dms.add(m.name);
  }
  const options = (names) => [...names].sort().map((x) => `<option value="${esc(x)}"></option>`).join("");
  setHtml($("#replica-dms"), options(dms));
  setHtml($("#replica-nodes"), options(nodes));
}

function renderCluster(cluster) {
  setHtml($("#cluster"), Object.values(cluster)
    .map((n) => {
      const mods = Object.values(n.modules);
      const kinds = faultKinds.node.concat(offers.cuttable ? (faultKinds.cut || []) : []);
      const stop = offers.stoppable_nodes.includes(n.name) && isUp(n)
        ? kinds.map((k) =>
          ` <button type="button" class="node-fault ${esc(k)}" data-fault="${esc(k)}" data-node="${esc(n.name)}" ` +
          `title="${esc(FAULT_TITLES[k] || k)}">${esc(NODE_FAULT_LABELS[k] || k)}</button>`).join("")
        : "";
      return `<div class="node" data-node="${esc(n.name)}" data-status="${n.status}">` +
        `<strong>${esc(n.name)}</strong> <span class="status">${n.status}</span>${woke(n)}${back(n)} ${esc(n.address || "")}${stop}` +
        `<div class="modules">${mods.length} module(s): ` +
        mods.map((m) => `<span class="module" data-kind="${m.kind}" data-module="${esc(m.name)}" ` +
          `data-node="${esc(n.name)}" data-address="${esc(m.address)}"` +
          `${m.kind === "operation" && offers.properties ? ' title="its properties"' : ""}>${esc(m.name)}</span>` +
          dmState(m) + dmFaults(m, n)).join(", ") +
        `</div></div>`;
    })
    .join(""));
}

// What a datamanager holds, as last asked: durability, records, journal; for one kept in
// replicas, its role and term and how far each replica lags.
function dmState(m) {
  const d = m.dm;
  if (!d) return "";
  const journal = d.durability === "memory" ? "in memory" : `${esc(d.durability)}, journal ${bytes(d.journal_bytes)}`;
  // each other replica's node: a click puts it and the datamanager in the replicas' form
  const replicas = d.role
    ? ` · ${esc(d.role)} (term ${d.term}); replicas: ` +
      Object.entries(d.lag).map(([node, lag]) =>
        `<span class="replica" data-dm="${esc(m.name)}" data-node="${esc(node)}">${esc(node)}</span> lag ${lag}`).join(", ")
    : "";
  return ` <span class="dm-state">(${d.records} records, ${journal}${replicas})</span>`;
}

function bytes(n) {
  if (n >= 1 << 20) return (n / (1 << 20)).toFixed(1) + " MiB";
  if (n >= 1 << 10) return (n / 1024).toFixed(1) + " KiB";
  return n + " B";
}

// A datamanager's fault buttons (kill, panic, hang: its supervisor restarts it), when the
// page may inject faults and its node is up.
function dmFaults(m, n) {
  if (m.kind !== "datamanager" || !offers.operation_faults || !isUp(n)) return "";
  return faultKinds.datamanager.map((k) =>
    ` <button type="button" class="fault dm-fault" data-fault="${esc(k)}" data-op="${esc(m.name)}" ` +
    `data-node="${esc(n.name)}" data-address="${esc(m.address)}" ` +
    `title="${esc(FAULT_TITLES[k] || k)} (datamanager ${esc(m.name)})">${esc(k)}</button>`).join("");
}

const pts = (list) => (list || []).map((p) => p[0].toFixed(3) + "," + p[1].toFixed(3)).join(" ");

function renderRobot(r) {
  const w = r.world;
  const svg = $("#world");
  svg.dataset.hasWorld = w ? "true" : "false";
  if (w) {
    setHtml($("#walls"), w.walls.map(([a, b]) => `<line x1="${a[0]}" y1="${a[1]}" x2="${b[0]}" y2="${b[1]}"></line>`).join(""));
    setHtml($("#dock"), w.dock ? `<polygon points="${pts(w.dock)}"></polygon>` : "");
    setHtml($("#goal"), w.goal ? `<polygon points="${pts(w.goal)}"></polygon>` : "");
  }
  // the server sends at most 1000 points of the driven path (thinned evenly)
  const path = r.path || [];
  $("#path").setAttribute("points", pts(path));
  $("#path").dataset.points = String(path.length);
  $("#planned-path").setAttribute("points", pts(r.planned_path));
  $("#dock-found").setAttribute("points", pts(r.dock_found));
  setHtml($("#echoes"), (r.echoes || []).map((p) => `<circle cx="${p[0]}" cy="${p[1]}" r="0.04"></circle>`).join(""));
  const fw = $("#followed-wall");
  if (r.followed_wall) {
    const [a, b] = r.followed_wall;
    fw.setAttribute("x1", a[0]); fw.setAttribute("y1", a[1]); fw.setAttribute("x2", b[0]); fw.setAttribute("y2", b[1]);
    fw.setAttribute("visibility", "visible");
  } else fw.setAttribute("visibility", "hidden");
  const fp = $("#footprint");
  if (r.pose && w && w.cart) {
    const { x, y, heading } = r.pose;
    const [l, wd] = [w.cart.length / 2, w.cart.width / 2];
    const c = Math.cos(heading), s = Math.sin(heading);
    const corners = [[l, wd], [-l, wd], [-l, -wd], [l, -wd]].map(([u, v]) => [x + u * c - v * s, y + u * s + v * c]);
    fp.setAttribute("points", pts(corners));
  } else fp.setAttribute("points", "");
  fitView(svg, r);
  $("#robot-info").textContent = r.pose
    ? `pose (${r.pose.x.toFixed(2)}, ${r.pose.y.toFixed(2)}, ${(r.pose.heading * 180 / Math.PI).toFixed(0)}°) · ${r.poses} poses · ${r.collisions} collision(s)`
    : w ? "no pose yet" : "no robot in this run";
}

function fitView(svg, r) {
  const all = [];
  if (r.world) {
    r.world.walls.forEach(([a, b]) => all.push(a, b));
    all.push(...(r.world.dock || []), ...(r.world.goal || []));
  }
  all.push(...(r.path || []), ...(r.planned_path || []), ...(r.dock_found || []));
  if (r.pose) all.push([r.pose.x, r.pose.y]);
  if (!all.length) return;
  let [x0, y0, x1, y1] = [Infinity, Infinity, -Infinity, -Infinity];
  for (const [x, y] of all) { x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y); }
  const m = 0.5;
  // the frame flips y (world y up): the view spans -y1..-y0
  svg.setAttribute("viewBox", `${x0 - m} ${-y1 - m} ${x1 - x0 + 2 * m} ${y1 - y0 + 2 * m}`);
}

function renderTimeline(t) {
  const list = $("#timeline");
  const atBottom = list.scrollTop + list.clientHeight >= list.scrollHeight - 4;
  setHtml(list, (t.dropped ? `<li class="dropped">${t.dropped} earlier entries dropped</li>` : "") +
    t.entries
      .map((e) => `<li class="entry ${e.class}" data-class="${e.class}"><span class="at">${fmtAt(e.at_ms)}</span>` +
        `<span class="src">${esc(e.node)}</span>${esc(e.text)}</li>`)
      .join(""));
  if (atBottom) list.scrollTop = list.scrollHeight;
}

$("#cluster").addEventListener("click", (ev) => {
  const button = ev.target.closest("button.dm-fault");
  if (!button) return;
  const d = button.dataset;
  injectFault({ fault: d.fault, operation: d.op, node: d.node || null, address: d.address || null });
});

$("#bindings tbody").addEventListener("click", (ev) => {
  const button = ev.target.closest("button.fault");
  if (button) {
    const d = button.dataset;
    injectFault({ fault: d.fault, operation: d.op, node: d.node || null, address: d.address || null });
    return;
  }
  const row = ev.target.closest("tr.binding");
  if (!row) return;
  selectedOp = selectedOp === row.dataset.op ? null : row.dataset.op;
  liveProps = null;
  if (latest) {
    renderBindings(latest.bindings);
    refreshProps(latest.bindings);
  }
});

$("#cluster").addEventListener("click", (ev) => {
  const button = ev.target.closest("button.node-fault");
  if (button) {
    injectFault({ fault: button.dataset.fault, node: button.dataset.node });
    return;
  }
  // a datamanager, or one of its replicas: into the replicas' form
  const replica = ev.target.closest(".dm-state .replica, .module[data-kind=\"datamanager\"]");
  if (replica && changesAllowed) {
    $("#replica-dm").value = replica.dataset.dm || replica.dataset.module;
    $("#replica-node").value = replica.dataset.node;
    return;
  }
  const module = ev.target.closest(".module[data-kind=\"operation\"]");
  if (module && offers.properties) {
    const d = module.dataset;
    showModuleProps({ operation: d.module, node: d.node, address: d.address });
  }
});

// The properties of any operation in the cluster panel (bound or not), asked of it now.
async function showModuleProps(op) {
  const box = $("#module-props");
  box.hidden = false;
  box.dataset.op = op.operation;
  box.dataset.node = op.node;
  box.dataset.live = "pending";
  box.innerHTML = `<strong>${esc(op.operation)}</strong> on ${esc(op.node)}: asking…`;
  const answer = await fetchProps(op);
  box.dataset.live = answer.error ? "error" : "true";
  box.innerHTML = `<button type="button" class="close" title="close">×</button>` +
    `<strong>${esc(op.operation)}</strong> on ${esc(op.node)}` + liveHtml(answer);
}

$("#module-props").addEventListener("click", (ev) => {
  if (ev.target.closest("button.close")) $("#module-props").hidden = true;
});

// Post a fault; its answer (or refusal) goes to #control-result.
function injectFault(request) {
  return postControl("/api/fault", request, "asking: " + request.fault + " " + (request.operation || request.node) + "…");
}

// Add or remove the replica the form names (a blank name is the monitor's to refuse); the
// form waits for the answer, which can take a while: a replica added catches up first.
async function changeReplicas(change) {
  const form = $("#replicas");
  if (form.dataset.busy === "true") return;
  const dm = $("#replica-dm").value.trim();
  const node = $("#replica-node").value.trim();
  form.dataset.busy = "true";
  form.querySelectorAll("button").forEach((b) => { b.disabled = true; });
  try {
    await postControl("/api/replicas", { change, dm, node },
      `asking: ${change} the replica of ${dm || "?"} on ${node || "?"}…` +
      (change === "add" ? " (it catches up before it votes)" : ""));
  } finally {
    form.dataset.busy = "false";
    form.querySelectorAll("button").forEach((b) => { b.disabled = false; });
  }
}

$("#replicas").addEventListener("submit", (ev) => {
  ev.preventDefault();
  changeReplicas("add");
});
$("#replica-remove").addEventListener("click", () => changeReplicas("remove"));

// Post `request` as JSON to the control route `path`; its answer (or refusal) goes to
// #control-result (`data-ok`: pending, then true or false).
async function postControl(path, request, asking) {
  const out = $("#control-result");
  out.hidden = false;
  out.dataset.ok = "pending";
  out.textContent = asking;
  try {
    const res = await fetch(withToken(path), {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      body: JSON.stringify(request),
    });
    const body = await res.json().catch(() => ({ error: res.status + " " + res.statusText }));
    out.dataset.ok = String(res.ok);
    out.textContent = res.ok ? body.done : "refused: " + (body.error || res.status);
  } catch (e) {
    out.dataset.ok = "false";
    out.textContent = "cannot reach the monitor: " + e;
  }
}

function banner(text) {
  const b = $("#banner");
  b.textContent = text;
  b.hidden = false;
  clearTimeout(banner.timer);
  banner.timer = setTimeout(() => { b.hidden = true; }, 5000);
}

// --- live ----------------------------------------------------------------------------------

function live() {
  const source = new EventSource(withToken("/api/live"));
  const take = (ev) => render(JSON.parse(ev.data));
  source.addEventListener("snapshot", take);
  source.addEventListener("state", take);
  source.addEventListener("lagged", (ev) => {
    const { missed } = JSON.parse(ev.data);
    $("#banner").dataset.missed = String(missed);
    banner(`this page fell behind and skipped ${missed} update(s); resynchronised from a snapshot`);
  });
  source.onerror = () => banner("the live connection was interrupted; reconnecting…");
}

// --- replay --------------------------------------------------------------------------------

async function replay() {
  const info = await getJson("/api/replay/info");
  $("#replay-controls").hidden = false;
  const slider = $("#slider");
  slider.min = String(info.start_ms);
  slider.max = String(info.end_ms);
  slider.value = String(info.start_ms);
  let t = info.start_ms;
  let playing = false;
  let inFlight = false;
  let wanted = null;
  let last = performance.now();

  async function show(at) {
    wanted = at;
    if (inFlight) return;
    inFlight = true;
    try {
      while (wanted !== null) {
        const ask = wanted;
        wanted = null;
        render(await getJson("/api/replay/state?at_ms=" + Math.round(ask)));
        $("#replay-time").textContent = fmtMs(ask - info.start_ms) + " / " + fmtMs(info.duration_ms);
        $("#replay-time").dataset.atMs = String(Math.round(ask));
      }
    } catch (e) {
      banner(String(e));
    } finally {
      inFlight = false;
    }
  }

  function setPlaying(p) {
    playing = p;
    const b = $("#play");
    b.dataset.playing = String(p);
    b.textContent = p ? "pause" : "play";
    last = performance.now();
  }

  $("#play").addEventListener("click", () => {
    if (!playing && t >= info.end_ms) t = info.start_ms;
    setPlaying(!playing);
  });
  slider.addEventListener("input", () => {
    t = Number(slider.value);
    show(t);
  });
  setInterval(() => {
    const now = performance.now();
    const dt = now - last;
    last = now;
    if (!playing) return;
    t = Math.min(info.end_ms, t + dt * Number($("#speed").value));
    slider.value = String(Math.round(t));
    show(t);
    if (t >= info.end_ms) setPlaying(false);
  }, 100);
  show(t);
}

// --- start ---------------------------------------------------------------------------------

(async () => {
  try {
    const info = await getJson("/api/info");
    offers = info.offers || offers;
    faultKinds = info.fault_kinds || faultKinds;
    changesAllowed = info.changes_allowed === true;
    document.body.dataset.faults = String(info.faults_allowed);
    document.body.dataset.changes = String(changesAllowed);
    const mode = $("#mode");
    mode.dataset.mode = info.mode;
    mode.textContent = info.mode;
    if (info.mode === "replay") await replay();
    else live();
  } catch (e) {
    banner("cannot reach the monitor: " + e);
  }
})();
