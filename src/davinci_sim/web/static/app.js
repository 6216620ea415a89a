// The web console's page: connects to the server's websocket, shows the endoscope with a
// heads-up display, the task panel and the console panel, and sends the operator's input.
// Everything the simulation does goes through the server's checked commands (protocol.py).

import {
  KEYMAP, GRIPPER_KEY_OPEN, GRIPPER_CLOSED, keyAxes, keyTurn, isMappedKey, buttonOfKey, toggleOfKey,
  gamepadInput, rumble, rumbleIntensity, sameAxes,
} from "./input.js";
import { EndoscopeView, isPoseMessage, loadThree } from "./endoscope.js";
import { XrConsole } from "./xr.js";

const $ = (id) => document.getElementById(id);
const params = new URLSearchParams(location.search);
const state = {
  ws: null, client: null, operator: null, hello: null, last: null,
  frames: 0, framesAt: performance.now(), fps: 0,
  left: null, right: null, frameTime: 0,
  // Who draws the endoscope: "page" (three.js, from the server's scene and poses) or
  // "server" (its JPEG frames); ?view=server asks for the server's images.
  source: "server", THREE: null, view: null, viewDirty: false, drawing: false,
  drawn: 0, drawLog: [],  // frames drawn, and the last ones' [wall ms, sim time s] (benchmarks)
  pressed: new Set(), axes: [0, 0, 0], turn: [0, 0, 0], gripper: GRIPPER_KEY_OPEN, jawOpen: true,
  hand: null, grippers: {}, inputTargets: [],
  buttons: { clutch: false, camera: false }, gamepadButtons: { clutch: false, camera: false },
  history: [], forceMax: 5, inputSent: 0, lastInputAt: 0,
};
window.davinci = state; // for the browser tests and the curious

// ------------------------------------------------------------------ connection
function connect() {
  const proto = location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(`${proto}://${location.host}/ws`);
  ws.binaryType = "arraybuffer";
  state.ws = ws;
  ws.onopen = () => {
    setConnection("connected", "ok");
    send({ op: "hello", ...(params.get("token") ? { token: params.get("token") } : {}) });
    send(viewMessage());
  };
  ws.onclose = () => {
    setConnection("disconnected — retrying", "bad");
    while (advancing.length) advancing.shift().reject(new Error("advance: the connection closed"));
    setTimeout(connect, 1000);
  };
  ws.onmessage = (event) => {
    if (typeof event.data === "string") onMessage(JSON.parse(event.data));
    else if (isPoseMessage(event.data)) state.view?.applyPoses(event.data);
    else onFrame(event.data);
  };
}

function viewMessage() {
  return { op: "view", stereo: $("mode").value !== "left", source: state.source };
}

function send(message) {
  if (state.ws && state.ws.readyState === WebSocket.OPEN) {
    state.ws.send(JSON.stringify(message));
    return true;
  }
  return false;
}
window.davinciSend = send;

function setConnection(text, cls) {
  const el = $("connection");
  el.textContent = text;
  el.className = `badge ${cls}`;
}

function showMessage(text, cls = "error") {
  const el = $("messages");
  el.innerHTML = "";
  const span = document.createElement("span");
  span.className = cls;
  span.textContent = text;
  el.appendChild(span);
  state.lastMessage = { text, cls, at: Date.now() };
}

function onMessage(m) {
  switch (m.op) {
    case "hello": onHello(m); break;
    case "welcome": state.operator = m.operator; updateControl(); break;
    case "state": onState(m); break;
    case "control": state.operator = m.operator; updateControl(); break;
    case "row": addRow(m.row); refreshCurve(); break;
    case "trainee":
      if (document.activeElement !== $("trainee")) $("trainee").value = m.name;
      refreshCurve();
      break;
    case "error":
      if (m.message.startsWith("view:")) useServerImages(m.message.slice(6));
      showMessage(m.message, "error"); break;
    case "scene": onScene(m); break;
    case "exercise":
      showMessage(`switching to ${m.task}: the console restarts with it (a few seconds), then take control again`, "info");
      break;
    case "pong": state.rtt = performance.now() - m.t; break;
    case "study": onStudy(m); break;
    case "advanced": onAdvanced(m); break;
    default: break;
  }
}

// The trainee's learning curves from the trainee records (when the server has them; the
// server draws a note while the trainee has no attempt).
function refreshCurve() {
  if (!state.hello || !state.hello.records) return;  // no trainee records on this server
  const img = $("curve");
  const query = new URLSearchParams({ n: String(Date.now()) });
  if (params.get("token")) query.set("token", params.get("token"));
  img.onload = () => { img.hidden = false; };
  img.onerror = () => { img.hidden = true; };
  img.src = `records/curve.png?${query}`;
}

// ------------------------------------------------------------------ hello: build the panels
function onHello(m) {
  state.client = m.client;
  if (m.needs_token) {  // the server says nothing more until the page proves the token
    if (!params.get("token")) showMessage("this console needs a token: open it with ?token=…");
    return;
  }
  state.hello = m;
  state.operator = m.operator;
  if (m.page_view && params.get("view") !== "server") startPageView();
  else useServerImages(m.page_view ? "asked for with ?view=server" : "this server offers no scene");
  $("trainee").value = m.trainee || "";
  refreshCurve();
  const cam = m.camera;
  for (const id of ["endoscope", "overlay"]) { $(id).width = cam.width; $(id).height = cam.height; }
  if (m.bedside_port) {
    // (served beyond loopback, the view is behind the page's token: its gate takes it once)
    const token = params.get("token") ? `?token=${encodeURIComponent(params.get("token"))}` : "";
    $("bedside").src = `${location.protocol}//${location.hostname}:${m.bedside_port}/${token}`;
  } else {
    $("bedside-note").textContent = "No 3-D view on this server (started with --no-bedside).";
    $("bedside")?.remove();  // (gone already when the page hears the server again)
  }
  const task = m.task;
  if (task) {
    $("task-name").textContent = task.name;
    $("task-description").textContent = task.description || "";
    const select = $("condition");
    select.innerHTML = "";
    const own = document.createElement("option");
    own.value = "";
    own.textContent = "the task's own";
    select.appendChild(own);
    for (const c of task.conditions) {
      const o = document.createElement("option");
      o.value = c.name; o.textContent = c.name; select.appendChild(o);
    }
    const custom = document.createElement("option");
    custom.value = "__custom"; custom.textContent = "custom…"; select.appendChild(custom);
    const types = $("fixture-type");
    types.innerHTML = "";
    for (const t of task.fixture_types) {
      const o = document.createElement("option"); o.value = t; o.textContent = t; types.appendChild(o);
    }
    if (task.fixture.type) types.value = task.fixture.type;
    showFixtureType(types.value);
    if (task.fixture.B !== undefined) setSlider("B", task.fixture.B);
    const cap = task.fixture.G_max ?? task.fixture.max_force;
    if (cap !== undefined) setSlider("G", cap);
    state.forceMax = Math.max(1, ...task.conditions.map((c) => c.G_max || c.max_force || 0), cap || 0);
    buildRowsHeader(task.metrics);
  }
  // Switching the exercise restarts the server's system with it (the page reconnects).
  const exercises = m.exercises || [];
  $("exercise-row").hidden = exercises.length === 0;
  $("exercise").innerHTML = "";
  for (const name of exercises) {
    const o = document.createElement("option"); o.value = name; o.textContent = name;
    $("exercise").appendChild(o);
  }
  if (task && exercises.includes(task.name)) $("exercise").value = task.name;
  const hands = $("hand");
  hands.innerHTML = "";
  for (const mtm of handChoices()) {
    const o = document.createElement("option");
    o.value = mtm; o.textContent = handLabel(mtm); hands.appendChild(o);
  }
  setHand(state.hand && handChoices().includes(state.hand) ? state.hand : handChoices()[0] || null);
  updateControl();
}

// The hands the keys can drive: the task's first, then the others the server steers.
function handChoices() {
  const hands = state.hello?.hands || [];
  const first = state.hello?.task?.mtm;
  return first && hands.includes(first) ? [first, ...hands.filter((h) => h !== first)] : [...hands];
}

function handLabel(mtm) {
  const side = mtm === "MTML" ? "left hand" : mtm === "MTMR" ? "right hand" : mtm;
  const teleop = Object.values(state.last?.teleops || {}).find((t) => t.mtm === mtm && t.selected);
  const psm = teleop ? teleop.psm : mtm === "MTML" ? "PSM2" : "PSM1";
  return `${side}: ${mtm} → ${psm}`;
}

// The keys drive `mtm` from now on: the other hand stops where it is, with its jaw as it was.
function setHand(mtm) {
  state.hand = mtm;
  if (mtm == null) return;
  if (!(mtm in state.grippers)) state.grippers[mtm] = GRIPPER_KEY_OPEN;
  state.gripper = state.grippers[mtm];
  state.jawOpen = state.gripper > 0;
  $("hand").value = mtm;
  sendInput(false);  // (the other hand, if it was moving, is told to stop)
}

function setSlider(id, value) { $(id).value = value; $(`${id}-out`).textContent = value; }

// The two sliders are the fixture's parameters: viscous B (N·s/m) and G_max (N); spring
// stiffness (N/m) and its force cap (N); none has none.
const FIXTURE_SLIDERS = {
  viscous: { label: "B", unit: "N·s/m", max: 100, step: 1, value: 40, cap: "G<sub>max</sub>" },
  spring: { label: "K", unit: "N/m", max: 500, step: 10, value: 200, cap: "F<sub>max</sub>" },
  adaptive: { label: "B₀", unit: "N·s/m", max: 60, step: 1, value: 40, cap: "G<sub>max</sub>" },
  viscous_elastic: { label: "B", unit: "N·s/m", max: 100, step: 1, value: 15, cap: "F<sub>max</sub>" },
};
// Rota's elastic term when the task's own fixture is of another kind (training.md §4).
const ELASTIC_DEFAULTS = { elastic_gain: 0.8, threshold: 0.002, half: 0.002, slope: 500 };

function showFixtureType(type) {
  const spec = FIXTURE_SLIDERS[type];
  for (const id of ["B", "G"]) $(id).disabled = !spec;
  if (!spec) return;
  $("B-label").textContent = spec.label; $("B-unit").textContent = spec.unit;
  $("G-label").innerHTML = spec.cap;
  $("B").max = spec.max; $("B").step = spec.step; setSlider("B", spec.value);
}

// ------------------------------------------------------------------ state
// What stops the operator (an arm in FAULT, a teleoperation stopped or stuck aligning), with
// its reason and one remedy; only the operator's page can apply it.
const PROBLEM_WORDS = { fault: "in FAULT", stopped: "stopped", aligning: "cannot align" };
function showProblems(problems) {
  $("problems").hidden = problems.length === 0;
  $("recover").disabled = !isOperator();
  $("recover").title = isOperator() ? "" : "take control first";
  const key = JSON.stringify(problems);
  if (key === state.problemsKey) return;
  // (recovered: the error that announced the problem is over too)
  if (problems.length === 0 && state.problemsKey && state.problemsKey !== "[]") $("messages").innerHTML = "";
  state.problemsKey = key;
  const list = $("problem-list");
  list.innerHTML = "";
  for (const p of problems) {
    const li = document.createElement("li");
    li.textContent = `${p.source} ${PROBLEM_WORDS[p.kind] || p.kind}: ${p.reason}`;
    list.appendChild(li);
  }
}

function onState(s) {
  state.last = s;
  state.operator = s.operator;
  $("pages").textContent = `${s.pages} page${s.pages === 1 ? "" : "s"}`;
  const task = s.task;
  if (task) {
    $("phase").textContent = task.progress ? `${task.phase} · ${task.progress}` : task.phase;
    const B = task.guidance_B == null ? "" : ` (B now ${task.guidance_B.toFixed(1)} N·s/m)`;
    $("repetition").textContent = `${task.repetition} (${task.completed} done) — ${task.condition}${B}`;
    // (a kind whose tool distance means nothing to a trainee has no label: not shown)
    $("deviation-label").hidden = $("deviation").hidden = task.distance_label == null;
    $("deviation-label").textContent = task.distance_label ?? "";
    $("deviation").textContent = task.distance == null ? "–" : `${(1000 * task.distance).toFixed(1)} mm`;
    $("progress").textContent = toDo(task);
    showResult(task.last);
  }
  const tip = taskTip(s);
  const f = tip ? Math.hypot(...tip.force) : 0;
  $("force").textContent = tip ? `${f.toFixed(2)} N` : "–";
  state.history.push({ t: s.time, d: task && task.distance != null ? 1000 * task.distance : null, f });
  while (state.history.length && s.time - state.history[0].t > 10) state.history.shift();
  if (state.history.length > 1 && s.time < state.history[state.history.length - 2].t) state.history = [];
  drawPlot();
  if (s.console) {
    $("teleop").checked = s.console.teleop_enabled;
    $("present").checked = !!s.console.buttons.operator_present;
  }
  fillTable("teleops", Object.values(s.teleops).map((t) => [t.mtm, t.psm, t.following ? "following" : t.state, t.clutched ? "clutched" : "", s.sources[t.mtm] || ""]));
  fillTable("arms", Object.entries(s.arms).map(([n, a]) => [n, a.state, a.homed ? "yes" : "no"]));
  showProblems(s.problems || []);
  $("synthetic").classList.toggle("on", !!(s.synthetic && s.synthetic.running));
  $("synthetic").textContent = s.synthetic && s.synthetic.running ? "Stop the synthetic trainee" : "Watch a synthetic trainee";
  updateControl();
  drawOverlay();
  const gp = firstGamepad();
  if (gp && tip && isOperator()) rumble(gp, rumbleIntensity(f, state.forceMax));
}

// What the trainee is to do now: the exercise's own words while it runs.
function toDo(task) {
  if (task.phase === "FINISHED" || task.phase === "RESULTS") return "done: the attempt is scored below; back to the start for the next";
  const kind = state.hello?.task?.kind || "";
  // (the keys each exercise needs beyond moving the tool, in its words)
  if (task.progress && kind === "camera_targeting") return `${task.progress}: hold C (camera pedal) and drag the view with the keys`;
  if (task.progress && kind === "needle_targeting") return `${task.progress}, the tool along its stem (turn it with I/K, J/L, U/O)`;
  if (task.progress && kind === "needle_pickup") return `${task.progress}: the jaws across the needle (turn them with I/K, J/L, U/O; E closes and opens them)`;
  if (task.progress && kind === "needle_drive") return `${task.progress}: turn the needle about its centre with the wrist (I/K, J/L, U/O; E closes and opens the jaws, H switches hands)`;
  if (task.progress) return task.progress;
  if (kind === "peg_transfer" && (task.phase === "IDLE" || task.phase === "READY")) return "pick up a ring to start";
  if ((kind === "needle_pickup" || kind === "needle_drive") && (task.phase === "IDLE" || task.phase === "READY")) return "pick up the needle to start";
  if (kind === "camera_targeting") return task.phase === "READY" ? "ready: hold C (camera pedal) and move the view to start" : "hold the camera still to start";
  if (task.phase === "IDLE") return "bring the tool to the start to begin";
  if (task.phase === "READY") return "ready: go";
  return "–";
}

// The last attempt's score and verdict, and its metrics with their units.
function showResult(last) {
  const box = $("result");
  if (!last || last.repetition == null) { box.hidden = true; return; }
  const key = `${last.repetition}:${last.completion_time}`;
  if (state.resultKey === key) return;
  state.resultKey = key;
  box.hidden = false;
  const verdict = last.passed === true ? "passed" : last.passed === false ? "not passed" : "no pass mark set";
  $("result-score").textContent = last.score == null ? `attempt ${last.repetition}: no score` : `attempt ${last.repetition}: score ${last.score.toFixed(0)} % — ${verdict}`;
  $("result").className = `result ${last.passed === true ? "ok" : last.passed === false ? "bad" : ""}`;
  const body = $("result-metrics");
  body.innerHTML = "";
  for (const m of state.hello?.task?.metrics || []) {
    const v = last[m.name];
    const tr = document.createElement("tr");
    const shown = typeof v === "number" ? displayValue(m, v) : v ?? "–";
    tr.innerHTML = "<td></td><td></td>";
    tr.children[0].textContent = m.label || m.name;
    tr.children[1].textContent = shown;
    body.appendChild(tr);
  }
}

function displayValue(m, v) {
  const [unit, factor] = m.display || (m.unit === "m" ? ["mm", 1000] : [m.unit, 1]);
  const x = v * factor;
  const text = Number.isInteger(x) ? String(x) : Math.abs(x) < 0.005 ? "0" : x.toPrecision(3);
  return unit && unit !== "1" ? `${text} ${unit}` : text;
}

function taskTip(s) {
  const mine = Object.values(s.tips).find((t) => t.mtm === state.hand);
  if (mine) return mine;
  const psm = state.hello?.task?.psm;
  if (psm && s.tips[psm]) return s.tips[psm];
  return Object.values(s.tips)[0] || null;
}

function fillTable(id, rows) {
  const body = $(id).querySelector("tbody");
  body.innerHTML = "";
  for (const r of rows) {
    const tr = document.createElement("tr");
    for (const c of r) { const td = document.createElement("td"); td.textContent = c; tr.appendChild(td); }
    body.appendChild(tr);
  }
}

// ------------------------------------------------------------------ results table
function buildRowsHeader(metrics) {
  state.columns = ["trainee", "condition", "repetition", ...metrics.map((m) => m.name), "score", "passed"];
  state.units = Object.fromEntries([...metrics.map((m) => [m.name, m.unit]), ["score", "%"]]);
  const tr = document.createElement("tr");
  for (const c of state.columns) {
    const th = document.createElement("th");
    th.textContent = state.units[c] && state.units[c] !== "1" ? `${c} (${state.units[c]})` : c;
    tr.appendChild(th);
  }
  const head = $("rows").querySelector("thead");
  head.innerHTML = "";
  head.appendChild(tr);
}

function addRow(row) {
  const tr = document.createElement("tr");
  for (const c of state.columns || Object.keys(row)) {
    const td = document.createElement("td");
    const v = row[c];
    td.textContent = typeof v === "number" && !Number.isInteger(v) ? v.toPrecision(4) : v ?? "–";
    tr.appendChild(td);
  }
  $("rows").querySelector("tbody").appendChild(tr);
  const score = row.score == null ? "" : `: score ${row.score.toFixed(0)} %${row.passed === true ? ", passed" : row.passed === false ? ", not passed" : ""}`;
  showMessage(`repetition ${row.repetition} finished${score}`, "info");
}

// ------------------------------------------------------------------ the endoscope
async function onFrame(buffer) {
  const view = new DataView(buffer);
  const number = view.getUint32(0, true);
  const time = view.getFloat64(4, true);
  const leftLength = view.getUint32(12, true);
  const left = new Blob([new Uint8Array(buffer, 16, leftLength)], { type: "image/jpeg" });
  const rightBytes = new Uint8Array(buffer, 16 + leftLength);
  const l = await createImageBitmap(left);
  // (the right eye comes only while some page shows both: keep the last one otherwise)
  const r = rightBytes.length ? await createImageBitmap(new Blob([rightBytes], { type: "image/jpeg" })) : null;
  state.left?.close?.();
  if (r) { state.right?.close?.(); state.right = r; }
  state.left = l; state.frameNumber = number; state.frameTime = time;
  if (state.view) return;  // (a frame sent before the page drew itself)
  countFrame(time);
  drawEndoscope();
}

// Frames drawn per second, shown in #fps (both ways of drawing count here); simTime: the
// simulation time of what was drawn, s.
function countFrame(simTime) {
  state.drawn += 1;
  state.drawLog.push([Date.now(), simTime]);
  if (state.drawLog.length > 2000) state.drawLog.splice(0, 1000);
  state.frames += 1;
  const now = performance.now();
  if (now - state.framesAt > 1000) {
    state.fps = (1000 * state.frames) / (now - state.framesAt);
    state.frames = 0; state.framesAt = now;
    $("fps").textContent = `${state.fps.toFixed(1)} frames/s`;
  }
}

// ------------------------------------------------------------------ the endoscope, drawn here
async function startPageView() {
  if (state.source === "page") return;
  try {
    state.THREE = state.THREE || await loadThree();
  } catch (e) {
    useServerImages(`the page cannot draw it: ${e.message}`);
    return;
  }
  state.source = "page";
  send(viewMessage());  // the server answers with the scene, then poses
}

function useServerImages(why) {
  state.source = "server";
  state.view?.dispose(); state.view = null;
  $("endoscope3d").hidden = true; $("endoscope").hidden = false;
  $("view-source").textContent = `server images (${why})`;
  send(viewMessage());
}

function onScene(m) {
  if (state.xr) state.xr.stop();  // (a new scene after a reconnect: the headset's view is gone)
  state.view?.dispose(); state.view = null;
  const canvas = $("endoscope3d");
  try {
    state.view = new EndoscopeView(state.THREE, canvas, m);
  } catch (e) {
    useServerImages(`the page cannot draw it: ${e.message}`);
    return;
  }
  canvas.hidden = false; $("endoscope").hidden = true;
  $("view-source").textContent = "drawn in the page (WebGL)";
  state.viewDirty = true;
  if (!state.drawing) { state.drawing = true; requestAnimationFrame(drawPageView); }
  XrConsole.supported().then((yes) => { $("xr").hidden = !yes; });
}

// ------------------------------------------------------------------ the headset (WebXR)
async function toggleHeadset() {
  if (state.xr) { await state.xr.stop(); return; }
  if (!state.view) return;
  if (!isOperator()) { showMessage("take control first: the headset drives the masters"); return; }
  const io = {
    handSpeed: state.hello.hand_speed, turnSpeed: state.hello.turn_speed,
    get forceMax() { return state.forceMax; },
    input: (mtm, axes, turn, gripper) => {
      if (isOperator()) send({ op: "input", mtm, axes, turn, ...(gripper == null ? {} : { gripper }) });
    },
    button: (name, pressed) => { if (isOperator()) send({ op: "button", name, pressed }); },
    force: (mtm) => {  // the guidance force on the tool this master drives, N
      const tip = Object.values(state.last?.tips || {}).find((t) => t.mtm === mtm);
      return tip ? Math.hypot(...tip.force) : 0;
    },
    onEnd: () => { state.xr = null; $("xr").textContent = "Enter headset"; },
    overlay: $("overlay"),
  };
  if ($("mode").value !== "left") {  // (the headset's screens take the left eye's display)
    $("mode").value = "left";
    send(viewMessage());
  }
  const overlay = $("overlay");
  overlay.width = state.view.width; overlay.height = state.view.height;
  drawOverlay();
  try {
    state.xr = await new XrConsole(state.view, io).start();
    $("xr").textContent = "Exit headset";
  } catch (e) {
    state.xr = null;
    showMessage(`the headset did not start: ${e.message}`);
  }
}

// Each display frame: draw when new poses came (or the view mode changed), then the HUD.
function drawPageView() {
  const view = state.view;
  if (!view) { state.drawing = false; return; }
  // (while the headset shows the view, its session draws the frames: not the page too)
  if ((view.fresh || state.viewDirty) && !state.xr) {
    const mode = $("mode").value;
    view.draw(mode);
    state.viewDirty = false;
    state.frameTime = view.time;
    const overlay = $("overlay");
    const width = mode === "sbs" ? 2 * view.width : view.width;
    if (overlay.width !== width || overlay.height !== view.height) {
      overlay.width = width; overlay.height = view.height;
      drawOverlay();  // (resizing cleared it; otherwise each state message redraws it)
    }
    countFrame(view.time);
  }
  requestAnimationFrame(drawPageView);
}

function drawEndoscope() {
  const canvas = $("endoscope");
  const overlay = $("overlay");
  const mode = $("mode").value;
  const w = state.left.width, h = state.left.height;
  const width = mode === "sbs" ? 2 * w : w;
  if (canvas.width !== width) { canvas.width = width; overlay.width = width; }
  canvas.height = h; overlay.height = h;
  const ctx = canvas.getContext("2d", { willReadFrequently: mode === "anaglyph" });
  const stereo = mode !== "left" && state.right;
  if (mode !== "left" && !state.right) { ctx.drawImage(state.left, 0, 0); drawOverlay(); return; }
  if (mode === "sbs" && stereo) {
    ctx.drawImage(state.left, 0, 0); ctx.drawImage(state.right, w, 0);
  } else if (mode === "anaglyph") {
    // Red from the left eye, green and blue from the right: depth with red-cyan glasses.
    ctx.drawImage(state.right, 0, 0);
    const right = ctx.getImageData(0, 0, w, h);
    ctx.drawImage(state.left, 0, 0);
    const left = ctx.getImageData(0, 0, w, h);
    const out = left.data, rd = right.data;
    for (let i = 0; i < out.length; i += 4) {
      out[i] = 0.299 * out[i] + 0.587 * out[i + 1] + 0.114 * out[i + 2];
      out[i + 1] = rd[i + 1];
      out[i + 2] = rd[i + 2];
    }
    ctx.putImageData(left, 0, 0);
  } else {
    ctx.drawImage(state.left, 0, 0);
  }
  drawOverlay();
}

// The heads-up display: on the left image (and its copy in side-by-side).
function drawOverlay() {
  const overlay = $("overlay");
  const ctx = overlay.getContext("2d");
  ctx.clearRect(0, 0, overlay.width, overlay.height);
  const s = state.last;
  if (!s || !$("hud").checked) return;
  const w = state.view ? state.view.width : state.left ? state.left.width : overlay.width;
  const copies = $("mode").value === "sbs" ? [0, w] : [0];
  for (const dx of copies) {
    ctx.save();
    ctx.translate(dx, 0);
    drawHud(ctx, s, w);
    ctx.restore();
  }
}

function drawHud(ctx, s, w) {
  ctx.font = "13px system-ui, sans-serif";
  const lines = [];
  for (const t of Object.values(s.teleops)) {
    if (!t.selected) continue;
    const what = t.following ? "following" : t.state.toLowerCase();
    const source = s.sources[t.mtm] ? ` (${s.sources[t.mtm]})` : "";
    lines.push(`${t.mtm}${source} → ${t.psm}: ${what}${t.clutched ? " · CLUTCH" : ""}`);
  }
  const b = s.console ? s.console.buttons : {};
  lines.push(`head ${b.operator_present ? "present" : "away"} · clutch ${b.clutch ? "down" : "up"} · camera ${b.camera ? "down" : "up"}`);
  if (state.hand && isOperator()) lines.push(`keys → ${handLabel(state.hand)}${b.camera ? " · camera: both hands" : ""}`);
  if (s.task) {
    const d = s.task.distance == null ? "" : ` · ${s.task.distance_label} ${(1000 * s.task.distance).toFixed(1)} mm`;
    lines.push(`${s.task.name} · ${s.task.phase} · rep ${s.task.repetition}${d}`);
    if (s.task.progress && s.task.phase === "RUNNING") lines.push(s.task.progress);
  }
  lines.push(`t = ${s.time.toFixed(1)} s${isOperator() ? " · you operate" : ""}`);
  ctx.fillStyle = "rgba(0,0,0,0.55)";
  ctx.fillRect(6, 6, 12 + Math.max(...lines.map((l) => ctx.measureText(l).width)), 18 * lines.length + 8);
  ctx.fillStyle = "#e8f1ff";
  lines.forEach((l, i) => ctx.fillText(l, 12, 22 + 18 * i));
  if (s.task && s.task.marks) drawMarks(ctx, s.task.marks, w);
  for (const [psm, tip] of Object.entries(s.tips)) {
    if (!tip.pixel) continue;
    const [u, v] = tip.pixel;
    ctx.strokeStyle = "#3ea6ff";
    ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.arc(u, v, 7, 0, 2 * Math.PI); ctx.stroke();
    ctx.fillStyle = "#3ea6ff";
    ctx.fillText(`${psm} (${tip.mtm})`, u + 10, v - 10);
    if (tip.guide && tip.guide.pixel) drawGuide(ctx, u, v, tip.guide);
    const f = Math.hypot(...tip.force);
    if (tip.force_pixel && f > 0.05) drawArrow(ctx, u, v, tip.force_pixel[0], tip.force_pixel[1], f);
  }
}

// An exercise's targets, numbered, the current one ringed with its required tool direction
// (a line from it, the way the tool must point); a camera exercise's crosshair.
function drawMarks(ctx, marks, w) {
  ctx.save();
  if (state.hello?.task?.kind === "camera_targeting") {
    const h = $("overlay").height;
    ctx.strokeStyle = "rgba(255,255,255,0.7)";
    ctx.lineWidth = 1;
    ctx.beginPath();
    ctx.moveTo(w / 2 - 14, h / 2); ctx.lineTo(w / 2 + 14, h / 2);
    ctx.moveTo(w / 2, h / 2 - 14); ctx.lineTo(w / 2, h / 2 + 14);
    ctx.stroke();
  }
  if (marks.wire) {  // the wire, thin and dashed over the scene's (it can hide behind the tool)
    ctx.strokeStyle = "rgba(255,225,77,0.75)"; ctx.lineWidth = 1.5; ctx.setLineDash([4, 4]);
    ctx.beginPath();
    let on = false;
    for (const q of marks.wire.pixels) {
      if (!q) { on = false; continue; }
      if (on) ctx.lineTo(q[0], q[1]); else { ctx.moveTo(q[0], q[1]); on = true; }
    }
    ctx.stroke(); ctx.setLineDash([]);
  }
  for (const peg of marks.pegs || []) {  // the target pegs ringed in green
    if (!peg.pixel || !peg.target) continue;
    ctx.strokeStyle = "#3ecf8e"; ctx.lineWidth = 1.5;
    ctx.beginPath(); ctx.arc(peg.pixel[0], peg.pixel[1], 9, 0, 2 * Math.PI); ctx.stroke();
  }
  ctx.fillStyle = "#ffe14d";
  for (const ring of marks.rings || []) {
    if (ring.pixel) ctx.fillText(`ring ${ring.label}`, ring.pixel[0] + 12, ring.pixel[1] - 8);
  }
  (marks.sutures || []).forEach((pair, k) => {  // the pair to pass ringed: in blue, out green
    if (marks.current_pair !== k) return;
    for (const [m, color] of [[pair.entry, "#4da3ff"], [pair.exit, "#3ecf8e"]]) {
      if (!m.pixel) continue;
      ctx.strokeStyle = ctx.fillStyle = color; ctx.lineWidth = 2;
      ctx.beginPath(); ctx.arc(m.pixel[0], m.pixel[1], 8, 0, 2 * Math.PI); ctx.stroke();
      ctx.fillText(m.label, m.pixel[0] + 10, m.pixel[1] + 14);
    }
  });
  (marks.targets || []).forEach((m, k) => {
    if (!m.pixel) return;
    const [u, v] = m.pixel;
    const current = marks.current === k;
    ctx.strokeStyle = ctx.fillStyle = current ? "#ffe14d" : "rgba(255,160,60,0.8)";
    ctx.lineWidth = current ? 2.5 : 1;
    ctx.beginPath(); ctx.arc(u, v, current ? 12 : 8, 0, 2 * Math.PI); ctx.stroke();
    ctx.fillText(m.label, u + 12, v + 14);
    if (current && m.shaft_pixel) {  // the tool must point this way: its shaft's side
      ctx.setLineDash([5, 3]);
      ctx.beginPath(); ctx.moveTo(u, v); ctx.lineTo(m.shaft_pixel[0], m.shaft_pixel[1]); ctx.stroke();
      ctx.setLineDash([]);
    }
  });
  ctx.restore();
}

// Depth cue for a 2-D screen: a dashed line to the path's closest point, coloured by how
// much deeper (blue: push in) or shallower (red: pull back) the path lies than the tool.
function drawGuide(ctx, u, v, guide) {
  const d = guide.depth_mm;
  const color = Math.abs(d) < 1 ? "#3ecf8e" : d > 0 ? "#4da3ff" : "#ff5a5a";
  ctx.save();
  ctx.strokeStyle = ctx.fillStyle = color;
  ctx.setLineDash([4, 4]);
  ctx.lineWidth = 1.5;
  ctx.beginPath(); ctx.moveTo(u, v); ctx.lineTo(guide.pixel[0], guide.pixel[1]); ctx.stroke();
  ctx.setLineDash([]);
  ctx.beginPath(); ctx.arc(guide.pixel[0], guide.pixel[1], 4, 0, 2 * Math.PI); ctx.fill();
  const hint = Math.abs(d) < 1 ? "on depth" : d > 0 ? "push in" : "pull back";
  ctx.fillText(`depth ${d >= 0 ? "+" : ""}${d.toFixed(1)} mm (${hint})`, u + 10, v + 18);
  ctx.restore();
}

function drawArrow(ctx, x0, y0, x1, y1, f) {
  const a = Math.atan2(y1 - y0, x1 - x0);
  ctx.strokeStyle = ctx.fillStyle = "#ffb020";
  ctx.lineWidth = 3;
  ctx.beginPath(); ctx.moveTo(x0, y0); ctx.lineTo(x1, y1); ctx.stroke();
  ctx.beginPath();
  ctx.moveTo(x1, y1);
  ctx.lineTo(x1 - 10 * Math.cos(a - 0.4), y1 - 10 * Math.sin(a - 0.4));
  ctx.lineTo(x1 - 10 * Math.cos(a + 0.4), y1 - 10 * Math.sin(a + 0.4));
  ctx.closePath(); ctx.fill();
  ctx.fillText(`${f.toFixed(1)} N`, x1 + 6, y1 + 4);
}

function drawPlot() {
  const c = $("plot");
  const ctx = c.getContext("2d");
  ctx.clearRect(0, 0, c.width, c.height);
  const h = state.history;
  if (h.length < 2) return;
  const t1 = h[h.length - 1].t, t0 = t1 - 10;
  const x = (t) => ((t - t0) / 10) * c.width;
  const label = state.last?.task?.distance_label;
  const series = [
    // (a kind without a distance label plots no distance)
    ...(label == null ? [] : [{ key: "d", max: Math.max(5, ...h.map((p) => p.d ?? 0)), color: "#3ea6ff", label: `${label} (mm)` }]),
    { key: "f", max: Math.max(state.forceMax, ...h.map((p) => p.f)), color: "#ffb020", label: "force (N)" },
  ];
  series.forEach((s, k) => {
    ctx.strokeStyle = s.color; ctx.beginPath();
    let started = false;
    for (const p of h) {
      if (p[s.key] == null) { started = false; continue; }
      const y = c.height - 4 - (p[s.key] / s.max) * (c.height - 8);
      if (started) ctx.lineTo(x(p.t), y); else { ctx.moveTo(x(p.t), y); started = true; }
    }
    ctx.stroke();
    ctx.fillStyle = s.color; ctx.font = "11px system-ui";
    ctx.fillText(`${s.label}, max ${s.max.toFixed(1)}`, 6, 12 + 13 * k);
  });
}

// ------------------------------------------------------------------ the study tab
function onStudy(m) {
  state.study = m;
  const bar = $("study-progress");
  bar.max = m.total || 1;
  bar.value = m.done || 0;
  if (m.state === "running") $("study-status").textContent = `${m.done} of ${m.total} trials`;
  if (m.state === "failed") $("study-status").textContent = `failed: ${m.message}`;
  if (m.state === "done") {
    $("study-status").textContent = `${m.total} trials in ${m.seconds} s${m.folder ? `, kept in ${m.folder}` : ""} — `;
    const csv = document.createElement("a");
    csv.href = "study/trials.csv"; csv.textContent = "trials.csv"; csv.download = "trials.csv";
    $("study-status").appendChild(csv);
    $("study-report").textContent = m.report;
    const figures = $("study-figures");
    figures.innerHTML = "";
    for (const f of m.files.filter((name) => name.endsWith(".png"))) {
      const img = document.createElement("img");
      img.src = `study/${f}?t=${Date.now()}`; img.alt = f;
      figures.appendChild(img);
    }
  }
}

// ------------------------------------------------------------------ control and panels
function isOperator() { return state.client != null && state.operator === state.client; }

function updateControl() {
  const button = $("control");
  const mine = isOperator();
  button.textContent = mine ? "Release control" : "Take control";
  button.classList.toggle("on", mine);
  $("operator").textContent = state.operator == null ? "nobody operates" : mine ? "you operate" : `page ${state.operator} operates`;
}

function setupPanels() {
  for (const b of document.querySelectorAll("nav button")) {
    b.onclick = () => {
      document.querySelectorAll("nav button").forEach((x) => x.classList.toggle("active", x === b));
      document.querySelectorAll(".tab").forEach((t) => t.classList.toggle("active", t.id === `tab-${b.dataset.tab}`));
    };
  }
  $("control").onclick = () => send({ op: "control", take: !isOperator() });
  $("trainee").onchange = () => send({ op: "trainee", name: $("trainee").value });
  for (const id of ["B", "G", "scale"]) $(id).oninput = () => { $(`${id}-out`).textContent = $(id).value; };
  $("condition").onchange = () => {
    const v = $("condition").value;
    if (v === "__custom") return;
    send({ op: "condition", condition: v || state.hello.task.fixture });
  };
  $("fixture-type").onchange = () => showFixtureType($("fixture-type").value);
  $("apply").onclick = () => {
    const type = $("fixture-type").value;
    const entry = { type };
    if (type === "viscous") { entry.B = Number($("B").value); entry.G_max = Number($("G").value); }
    if (type === "spring") { entry.stiffness = Number($("B").value); entry.max_force = Number($("G").value); }
    if (type === "adaptive") { entry.B0 = Number($("B").value); entry.G_max = Number($("G").value); }
    if (type === "viscous_elastic") {  // (the elastic term and assistance: the task's, or Rota's)
      const own = state.hello.task.fixture;
      const { name: _, ...rest } = own.type === type ? own : ELASTIC_DEFAULTS;
      entry.B = Number($("B").value);
      Object.assign(entry, rest, { type, B: entry.B, max_force: Number($("G").value) });
    }
    $("condition").value = "__custom";
    send({ op: "condition", condition: entry });
  };
  $("reset").onclick = () => send({ op: "task", action: "reset" });
  $("study-run").onclick = () => send({
    op: "study", action: "start",
    subjects: Number($("study-subjects").value), repetitions: Number($("study-repetitions").value),
  });
  $("synthetic").onclick = () => {
    const running = !!(state.last?.synthetic?.running);
    // Subject 0 of the study's population, as after ten practice repetitions.
    send(running ? { op: "synthetic", action: "stop" } : { op: "synthetic", action: "start", subject: 0, practice: 10 });
  };
  $("teleop").onchange = () => send({ op: "teleop", enable: $("teleop").checked });
  $("scale-apply").onclick = () => send({ op: "teleop", scale: Number($("scale").value) });
  $("present").onchange = () => send({ op: "button", name: "operator_present", pressed: $("present").checked });
  $("recover").onclick = () => send({ op: "recover" });
  for (const b of document.querySelectorAll("[data-arms]")) b.onclick = () => send({ op: "arms", action: b.dataset.arms });
  $("mode").onchange = () => {
    send(viewMessage());
    state.viewDirty = true;
    if (state.left && !state.view) drawEndoscope();
  };
  $("hud").onchange = drawOverlay;
  $("xr").onclick = toggleHeadset;
  // The dropdown shows the exercise served: a choice goes to the server and the dropdown
  // turns back; it shows the new one when the server has restarted with it (its hello), and
  // a refused choice (not the operator) leaves nothing changed but the message.
  $("exercise").onchange = () => {
    const name = $("exercise").value;
    const served = state.hello?.task?.name;
    if (served) $("exercise").value = served;
    if (name && name !== served) send({ op: "exercise", task: name });
  };
  const body = $("keymap").querySelector("tbody");
  for (const k of KEYMAP) {
    const tr = document.createElement("tr");
    tr.innerHTML = "<td></td><td></td>";
    tr.children[0].textContent = k.label; tr.children[1].textContent = k.what;
    body.appendChild(tr);
  }
  $("screen").tabIndex = 0;
  $("hand").onchange = () => setHand($("hand").value);
}

// ------------------------------------------------------------------ operator input
function handMtm() {
  return state.hand || state.hello?.task?.mtm || state.hello?.hands?.[0] || "MTMR";
}

function cameraPedal() { return state.buttons.camera || state.gamepadButtons.camera; }

function onKey(event, down) {
  if (event.target instanceof HTMLInputElement || event.target instanceof HTMLSelectElement) return;
  if (!isMappedKey(event.code)) return;
  event.preventDefault();
  if (down && event.repeat) return;
  if (down) state.pressed.add(event.code); else state.pressed.delete(event.code);
  const button = buttonOfKey(event.code);
  if (button) setButton(button, down, "keys");
  const toggle = toggleOfKey(event.code);
  if (toggle === "jaw" && down) {
    state.jawOpen = !state.jawOpen;
    state.gripper = state.jawOpen ? GRIPPER_KEY_OPEN : GRIPPER_CLOSED;
    if (state.hand) state.grippers[state.hand] = state.gripper;
    sendInput(true);
  }
  if (toggle === "hand" && down) {
    const hands = handChoices();
    if (hands.length > 1) setHand(hands[(hands.indexOf(state.hand) + 1) % hands.length]);
  }
  if (toggle === "present" && down) send({ op: "button", name: "operator_present", pressed: !$("present").checked });
  sendInput(false);
}

function setButton(name, pressed, source) {
  const key = source === "keys" ? "buttons" : "gamepadButtons";
  if (state[key][name] === pressed) return;
  state[key][name] = pressed;
  if (isOperator()) send({ op: "button", name, pressed });
}

function currentAxes() {
  const keys = keyAxes(state.pressed);
  const gp = firstGamepad();
  if (!gp) return keys;
  const g = gamepadInput(gp);
  return keys.map((v, i) => Math.max(-1, Math.min(1, v + g.axes[i])));
}

// Send the rate input when it changes, and again every 100 ms while non-zero (the server's
// hand stops by itself 0.3 s after the last input: a lost page stops the tool).
// With the camera pedal down the keys move both hands together (the ECM teleoperation
// follows the hands' midpoint: the image follows the hands); the wrist keys then do nothing.
function sendInput(force) {
  if (!isOperator()) return;
  const axes = currentAxes();
  const camera = cameraPedal() && (state.hello?.hands || []).length > 1;
  const turn = camera ? [0, 0, 0] : keyTurn(state.pressed);
  const targets = camera ? [...state.hello.hands] : [handMtm()];
  const moving = axes.some((v) => v !== 0) || turn.some((v) => v !== 0);
  const now = performance.now();
  const wasMoving = state.axes.some((v) => v !== 0) || state.turn.some((v) => v !== 0);
  // (other hands with nothing moving: nothing to send; a hand takes its handle when moved)
  const sameTargets = targets.join() === state.inputTargets.join() || (!moving && !wasMoving);
  const same = sameAxes(axes, state.axes) && sameAxes(turn, state.turn) && sameTargets;
  if (!force && same && !(moving && now - state.lastInputAt > 100)) {
    state.inputTargets = targets;
    return;
  }
  for (const old of state.inputTargets) {  // a hand no longer driven stops now
    if (!targets.includes(old)) send({ op: "input", mtm: old, axes: [0, 0, 0], turn: [0, 0, 0] });
  }
  state.axes = axes;
  state.turn = turn;
  state.inputTargets = targets;
  state.lastInputAt = now;
  state.inputSent += 1;
  for (const mtm of targets) {
    const gripper = mtm === handMtm() ? state.gripper : state.grippers[mtm];
    send({ op: "input", mtm, axes, turn, ...(gripper == null ? {} : { gripper }) });
  }
}

// A stepped server (serve --stepped: for scripts that look at each state before they act):
// tick `seconds` of simulated time more. Resolves with the state there. The held input goes
// again first: the hand stops 0.3 s of simulated time after its last input, however long the
// script took to look.
const advancing = [];
state.advance = (seconds) => new Promise((resolve, reject) => {
  sendInput(true);
  if (!send({ op: "advance", seconds })) reject(new Error("advance: the page is not connected"));
  else advancing.push({ resolve, reject });
});

function onAdvanced(m) {
  const waiting = advancing.shift();
  if (!waiting) return;
  if (m.refused) waiting.reject(new Error(m.refused));
  else waiting.resolve(state.last);
}

function firstGamepad() {
  const pads = navigator.getGamepads ? navigator.getGamepads() : [];
  for (const p of pads) if (p && p.connected !== false) return p;
  return null;
}

function pollGamepad() {
  const gp = firstGamepad();
  $("gamepad").textContent = gp ? `gamepad: ${gp.id}` : "no gamepad";
  if (gp && isOperator()) {
    const g = gamepadInput(gp);
    setButton("clutch", g.buttons.clutch, "gamepad");
    setButton("camera", g.buttons.camera, "gamepad");
    if (Math.abs(g.gripper - state.gripper) > 0.02) { state.gripper = g.gripper; sendInput(true); }
  }
  sendInput(false);
  requestAnimationFrame(pollGamepad);
}

// requestAnimationFrame stops in a hidden page; the interval keeps the input alive anyway.
setInterval(() => sendInput(false), 50);

window.addEventListener("keydown", (e) => onKey(e, true));
window.addEventListener("keyup", (e) => onKey(e, false));
window.addEventListener("blur", () => { state.pressed.clear(); sendInput(true); });

setupPanels();
connect();
requestAnimationFrame(pollGamepad);
