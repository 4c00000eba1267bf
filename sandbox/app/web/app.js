// The classroom page: shows this tab's session (in 2D the page draws the particles from the session's particle
// frames over the picture the sandbox's renderer draws without them; in 3D it shows the renderer's pictures;
// streamed over a WebSocket one at a time: the page asks for the next when it has drawn the last, so the frame rate
// follows the network and the server), and its panel from the shared description (sandbox/app/panel.py). Every
// string the page shows comes from a message catalogue (static/i18n/*.json).
"use strict";

const params = new URLSearchParams(location.search);
const token = params.get("token") || "";
const $ = (id) => document.getElementById(id);
let words = {};
let socket = null;
let sid = null;
let currentScene = "";
let refused = false; // the server said why it closed: that stays on screen
let sessionKey = ""; // the session's key: only this tab's socket is given it, and the state routes ask for it
let paused = false;
let tools = [];
let settingKeys = "";
let lastSummary = null;
let lastReadoutsShown = 0;

function t(key, values) {
  let text = words[key] ?? key;
  for (const [k, v] of Object.entries(values || {})) text = text.replaceAll(`{${k}}`, v);
  return text;
}

// a scene's, material's or phase's name in the page's language (the catalogue's "scene_NAME" ...), else the name
function named(kind, name) { return words[`${kind}_${name}`] ?? String(name).replaceAll("_", " "); }

const LANGUAGES = ["en", "fr", "ar"];
const RIGHT_TO_LEFT = ["ar"];
let lessons = {};  // scene -> {happens, explore, physics} in the page's language (en: the scene's own words)
let lessonOf = {};  // the scene's own lesson, as the server sent it

async function setLanguage(lang) {
  const query = token ? "?token=" + token : "";
  words = await (await fetch(`static/i18n/${lang}.json${query}`)).json();
  lessons = lang === "en" ? {} : await (await fetch(`static/i18n/lessons.${lang}.json${query}`)).json();
  document.documentElement.lang = lang;
  document.documentElement.dir = RIGHT_TO_LEFT.includes(lang) ? "rtl" : "ltr";  // the layout mirrored
  localStorage.setItem("sandbox-lang", lang);
  $("lang").value = lang;
  send({ t: "lang", lang });  // the picture's charts speak it too
  for (const el of document.querySelectorAll("[data-i18n]")) el.textContent = t(el.dataset.i18n);
  for (const el of document.querySelectorAll("[data-i18n-label]:not(canvas)")) el.ariaLabel = t(el.dataset.i18nLabel);
  $("pause").textContent = t(paused ? "play" : "pause");
  fillTools();
  settingKeys = "";  // relabel the sliders
  for (const option of $("scene").options) option.textContent = named("scene", option.value);
  for (const option of $("material").options) option.textContent = named("material", option.value);
  showLesson();
  $("legend").dataset.key = "";  // the legend's words again, in this language
}

function showLesson() {
  const lesson = lessons[currentScene] || lessonOf;
  for (const part of ["happens", "explore", "physics"]) $(part).textContent = lesson[part] || "";
  $("lesson-box").hidden = !lesson.happens;
}

// a swatch's label: a material ("candle wax"), or a material and its phase ("water solid", "wax melt")
function swatchLabel(label) {
  const words_ = label.split(" ");
  const phase = words_[words_.length - 1];
  if (words_.length > 1 && ["solid", "melt", "vapour"].includes(phase)) {
    return `${named("material", words_.slice(0, -1).join("_"))} ${named("phase", phase)}`;
  }
  return named("material", label.replaceAll(" ", "_"));
}

function probeText(p) {
  if (!p) return "-";
  const parts = [named("material", p.material), named("phase", p.phase)];
  if (p.temperature !== null) parts.push(t("probe_heat", { temperature: p.temperature.toFixed(1), melt: p.melt }));
  parts.push(t("probe_speed", { speed: p.speed }));
  return parts.join(t("list_separator"));
}

function chooseLanguage() {
  const asked = params.get("lang") || localStorage.getItem("sandbox-lang") || navigator.language || "en";
  const lang = asked.slice(0, 2).toLowerCase();
  return LANGUAGES.includes(lang) ? lang : "en";
}

function say(text) { $("status").textContent = text; }

function send(message) {
  if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(message));
}

function connect(scene) {
  const proto = location.protocol === "https:" ? "wss:" : "ws:";
  const query = new URLSearchParams({ scene: scene || "" });
  if (token) query.set("token", token);
  socket = new WebSocket(`${proto}//${location.host}/ws?${query}`);
  socket.binaryType = "arraybuffer";
  say(t("connecting"));
  socket.onmessage = (event) => (typeof event.data === "string" ? onText(JSON.parse(event.data)) : onBinary(event.data));
  socket.onclose = () => { if (!refused) say(t("disconnected")); };  // "full" and other refusals stay on screen
}

// What the session sends as bytes, told apart by the first byte (sandbox/app/serve_session.py): "F" a JPEG picture;
// where the page draws the particles, "B" the picture without them (PNG), "C" the charts' band (x0, row0, PNG) and
// "P" a particle frame (sandbox/render/particle_frame.py), after "L" its light where particles glow
// (sandbox/render/light_frame.py, drawn by light.js), "S" a sphere frame (sandbox/render/sphere_frame.py, drawn by
// spheres.js). They are handled in order, one at a time.
let pictures = Promise.resolve();
function onBinary(buffer) { pictures = pictures.then(() => onBytes(buffer)).catch(() => {}); }

const base = document.createElement("canvas");  // the picture without its particles, where the page draws them
let band = null;  // where the charts' band lies on it ({x, y, w, h}): drawn again over 3D spheres, as the renderer
let baseVersion = 0;  // counts the changes to `base` (the 3D drawing uploads it again only after one)
let light = null;  // the light frame of the next particle frame, where particles glow (light.js)
async function bitmapOf(bytes, type) { return createImageBitmap(new Blob([bytes], { type })); }

async function onBytes(buffer) {
  const kind = String.fromCharCode(new Uint8Array(buffer, 0, 1)[0]);
  if (kind === "F") {
    const bitmap = await bitmapOf(buffer.slice(1), "image/jpeg");
    const context = pictureContext(bitmap.width, bitmap.height);
    context.drawImage(bitmap, 0, 0);
    bitmap.close();
    shown(context);
  } else if (kind === "B") {
    const bitmap = await bitmapOf(buffer.slice(1), "image/png");
    base.width = bitmap.width; base.height = bitmap.height;
    base.getContext("2d").drawImage(bitmap, 0, 0);
    bitmap.close();
    baseVersion += 1;
  } else if (kind === "C") {
    const at = new DataView(buffer, 1, 4);
    const bitmap = await bitmapOf(buffer.slice(5), "image/png");
    band = { x: at.getUint16(0, true), y: at.getUint16(2, true), w: bitmap.width, h: bitmap.height };
    base.getContext("2d").drawImage(bitmap, band.x, band.y);
    bitmap.close();
    baseVersion += 1;
  } else if (kind === "L") {
    light = buffer;  // the light of the particle frame that follows
  } else if (kind === "P") {
    const context = pictureContext(base.width, base.height);
    context.drawImage(base, 0, 0);
    drawParticles(context, buffer);
    if (light !== null && !drawLight(context, light)) { send({ t: "nogl" }); light = null; return; }
    light = null;
    shown(context, buffer);
  } else if (kind === "S") {
    const spheres = drawSpheres(buffer, base, baseVersion);  // the whole picture, over the backdrop
    if (spheres === null) { send({ t: "nogl" }); return; }  // no WebGL2 here: the session sends pictures instead
    const context = pictureContext(base.width, base.height);
    context.drawImage(spheres, 0, 0);
    if (band) context.drawImage(base, band.x, band.y, band.w, band.h, band.x, band.y, band.w, band.h);
    shown(context, buffer);
  }
}

function pictureContext(width, height) {
  const canvas = $("picture");
  if (canvas.width !== width) { canvas.width = width; canvas.height = height; }
  return canvas.getContext("2d");
}

// a picture on the screen (`frame`: the frame the page drew it from, whose header gives its particles and time)
function shown(context, frame = null) {
  const canvas = $("picture");
  if (frame) {
    const view = new DataView(frame);
    canvas.dataset.particles = String(view.getUint32(17, true));
    canvas.dataset.time = String(view.getFloat64(9, true));
  }
  if (document.activeElement === canvas) {  // the keyboard's pointer, where the arrows have put it
    const x = keyboardPoint.x * canvas.width, y = keyboardPoint.y * canvas.height;
    context.lineWidth = 3;
    for (const [colour, r] of [["#000", 13], ["#fff", 10]]) {
      context.strokeStyle = colour;
      context.beginPath();
      context.arc(x, y, r, 0, 2 * Math.PI);
      context.moveTo(x - r - 6, y); context.lineTo(x - r + 4, y); context.moveTo(x + r - 4, y); context.lineTo(x + r + 6, y);
      context.stroke();
    }
  }
  canvas.dataset.frames = String(Number(canvas.dataset.frames || 0) + 1);
  if (canvas.dataset.frames === "1") say(t("connected"));  // "Ready." only with a picture to show
  requestAnimationFrame(() => send({ t: "ready" }));  // the next picture, once this one is on the screen
}

function onText(msg) {
  if (msg.t === "hello") { sid = msg.sid; sessionKey = msg.key || ""; send({ t: "lang", lang: $("lang").value || "en" }); }
  else if (msg.t === "scene") onScene(msg);
  else if (msg.t === "info") onInfo(msg);
  else if (msg.t === "paused") { paused = msg.paused; $("pause").textContent = t(paused ? "play" : "pause"); }
  else if (msg.t === "error") {
    if (["full", "per_client", "idle", "start_failed", "session_ended"].includes(msg.key)) refused = true;
    say(msg.key ? t(msg.key, { text: msg.text || "" }) : msg.text);
  }
  else if (msg.t === "notice") say(t(msg.key, { text: msg.text || "" }));
}

let sceneDim = 2;  // 3: a drag on the picture turns its camera (shift: pans), the wheel zooms
function onScene(msg) {
  sceneDim = msg.dim || 2;
  band = null;  // the new scene's band comes with its first pictures
  $("hint").dataset.i18n = sceneDim === 3 ? "canvas_hint_3d" : "canvas_hint";  // kept across a change of language
  $("hint").textContent = t($("hint").dataset.i18n);
  $("scene").value = msg.scene;
  currentScene = msg.scene;
  lessonOf = msg.lesson || {};
  showLesson();
  tools = msg.tools || [];
  history.length = 0;
  fillTools(msg.tool);
  $("material").replaceChildren(...(msg.materials || []).map((name) => new Option(named("material", name), name)));
  settingKeys = "";
}

function fillTools(start) {
  const select = $("tool");
  const offered = ["none", ...tools];
  const current = select.value;
  select.replaceChildren(...offered.map((name) => new Option(named("tool", name), name)));
  // a new scene starts with its own tool (the one its lesson speaks of); a new language keeps the tool in hand
  if (start && offered.includes(start)) select.value = start;
  else select.value = offered.includes(current) ? current : tools[0] || "none";
  $("material-row").hidden = select.value !== "spawn";
}

function readoutLabel(r) {
  return r.key === "temperature_of" ? t("r_temperature_of", { words: named("body", r.words) }) : t("r_" + r.key);
}

const history = [];  // [time s, mean temperature °C] for the page's chart

function showLegend(legend) {
  const box = $("legend");
  const key = JSON.stringify(legend || {});
  if (box.dataset.key === key) return;
  box.dataset.key = key;
  const parts = [];
  if (legend && legend.kind === "bar") {
    const caption = document.createElement("span");
    caption.textContent = `${t("legend_" + legend.quantity)} (${legend.unit})`;
    const bar = document.createElement("span");
    bar.className = "bar";
    bar.style.background = `linear-gradient(to right, ${legend.colors.join(", ")})`;
    bar.dir = "ltr";  // a colour scale runs from low to high left to right in every language
    const ends = document.createElement("span");
    ends.textContent = `${legend.lo} … ${legend.hi}`;
    parts.push(caption, bar, ends);
  } else if (legend && legend.kind === "swatches") {
    legend.labels.forEach((label, k) => {
      const item = document.createElement("span");
      const swatch = document.createElement("span");
      swatch.className = "swatch";
      swatch.style.background = legend.colors[k];
      item.append(swatch, swatchLabel(label));
      parts.push(item);
    });
  }
  box.replaceChildren(...parts);
}

function drawChart() {
  const svg = $("chart");
  const points = history.filter(([, v]) => v !== null);
  if (points.length < 2) { svg.replaceChildren(); return; }
  const [x0, x1] = [points[0][0], points[points.length - 1][0]];
  const values = points.map(([, v]) => v);
  let lo = Math.min(...values), hi = Math.max(...values);
  if (hi - lo < 1) { lo -= 0.5; hi += 0.5; }
  const X = (tm) => 50 + 420 * (tm - x0) / Math.max(x1 - x0, 1e-9);
  const Y = (v) => 150 - 140 * (v - lo) / (hi - lo);
  const ns = "http://www.w3.org/2000/svg";
  const el = (name, attrs, text) => {
    const e = document.createElementNS(ns, name);
    for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
    if (text !== undefined) e.textContent = text;
    return e;
  };
  svg.replaceChildren(
    el("line", { x1: 50, y1: 10, x2: 50, y2: 150, class: "axis" }),
    el("line", { x1: 50, y1: 150, x2: 470, y2: 150, class: "axis" }),
    el("text", { x: 45, y: 16, "text-anchor": "end" }, hi.toFixed(1)),
    el("text", { x: 45, y: 150, "text-anchor": "end" }, lo.toFixed(1)),
    el("text", { x: 50, y: 168, "text-anchor": "middle" }, x0.toFixed(1)),
    el("text", { x: 470, y: 168, "text-anchor": "end" }, x1.toFixed(1) + " s"),
    el("polyline", { class: "line", points: points.map(([tm, v]) => `${X(tm).toFixed(1)},${Y(v).toFixed(1)}`).join(" ") }),
  );
}

function onInfo(msg) {
  if (!msg.readouts) return;  // a picture's clock only: the readouts come with every few pictures
  const now = performance.now();
  showLegend(msg.legend);
  const mean = msg.readouts.find((r) => r.key === "temperature");
  if (mean) {
    if (history.length && msg.time < history[history.length - 1][0]) history.length = 0;  // reset or a new scene
    history.push([msg.time, mean.value]);
    if (history.length > 600) history.splice(0, history.length - 600);
  }
  if (now - lastReadoutsShown > 1000) {  // once a second: readable, and not a flood for a screen reader
    lastReadoutsShown = now;
    const rows = [];
    // where some numbers are set by the model's rule (a mesoscale scene's heat and phases), each says what it is
    const marked = msg.readouts.some((r) => r.source === "rule");
    for (const r of msg.readouts) {
      const dt = document.createElement("dt");
      dt.textContent = readoutLabel(r);
      if (marked && (r.source === "measured" || r.source === "rule")) {
        const badge = document.createElement("span");
        badge.className = "source " + r.source;
        badge.textContent = t("source_" + r.source);
        badge.title = t("source_" + r.source + "_title");
        dt.append(" ", badge);
      }
      const dd = document.createElement("dd");
      dd.dataset.key = r.key;
      const unit = r.unit === "C" ? "°C" : r.unit;
      dd.textContent = r.value === null ? "-" : `${r.value.toFixed(r.digits)}${unit ? " " + unit : ""}`;
      rows.push(dt, dd);
    }
    $("readouts").replaceChildren(...rows);
    $("probe").textContent = probeText(msg.probe);
    drawChart();
  }
  const summary = t(msg.summary.key, { ...msg.summary, trend: t("trend_" + (msg.summary.trend || "steady")) });
  lastSummary = summary;
  $("picture").setAttribute("aria-label", t("picture_label", { summary }));  // read when asked, never announced
  // the live region speaks when the state changes in words (the trend, a quarter more melted or boiled), not as
  // the numbers run: a screen reader is not talked over every frame
  const s = msg.summary;
  const state = [s.key, s.trend, Math.floor((s.molten || 0) / 25), Math.floor((s.gas || 0) / 25)].join("|");
  if (state !== onInfo.state && now - (onInfo.spoken || -1e9) > 3000) {
    onInfo.state = state;
    speak(summary);
  }
  fillSettings(msg.settings);
}

function speak(text) {
  onInfo.spoken = performance.now();
  $("summary").textContent = text;
}

function settingLabel(s) {
  const label = s.key.startsWith("source") ? t("s_source", { words: named("source", s.words) })
    : s.key.startsWith("wall") ? t("s_wall", { words: named("wall", s.words.replace(/ temperature$/, "")) })
    : t("s_" + s.key);
  return label + (s.unit ? ` (${s.unit.replace(/^C$/, "°C").replace(/^deg$/, "°").replace(/^x$/, "×")})` : "");
}

function fillSettings(settings) {
  const keys = settings.map((s) => s.key).join(",");
  if (keys !== settingKeys) {
    settingKeys = keys;
    const rows = settings.map((s) => {
      const row = document.createElement("div");
      row.className = "row";
      const label = document.createElement("label");
      label.htmlFor = "set-" + s.key;
      label.textContent = settingLabel(s);
      const input = document.createElement("input");
      Object.assign(input, { type: "range", id: "set-" + s.key, min: s.lo, max: s.hi, step: s.step, value: s.value });
      const out = document.createElement("output");
      out.id = "out-" + s.key;
      out.setAttribute("aria-live", "off");  // the slider itself says its value; an <output> would speak every change
      input.addEventListener("input", () => { out.textContent = Number(input.value).toFixed(1); send({ t: "set", key: s.key, value: Number(input.value) }); });
      row.append(label, input, out);
      return row;
    });
    $("settings").replaceChildren(...rows);
  }
  for (const s of settings) {
    const input = $("set-" + s.key);
    if (input && document.activeElement !== input && input.dataset.dragging !== "1") input.value = s.value;
    const out = $("out-" + s.key);
    if (out) out.textContent = Number(s.value).toFixed(1);
  }
}

// ---------------------------------------------------------------- the tools on the picture
function fraction(event) {
  const box = $("picture").getBoundingClientRect();
  return { x: Math.min(Math.max((event.clientX - box.left) / box.width, 0), 1), y: Math.min(Math.max((event.clientY - box.top) / box.height, 0), 1) };
}
let stroking = false;
const keyboardPoint = { x: 0.5, y: 0.6 };
function toolMessage(point, down) {
  const message = { t: "tool", tool: $("tool").value, x: point.x, y: point.y, radius: Number($("brush").value), down };
  if (message.tool === "spawn" && $("material").value) message.material = $("material").value;
  return message;
}
let turning = null;  // a 3D drag: where the pointer was, and whether it pans
function viewMessage(move, dx, dy) {
  const clamp = (v) => Math.min(Math.max(v, -1), 1);
  return { t: "view", move, dx: clamp(dx), dy: clamp(dy) };
}
function setupPicture() {
  const canvas = $("picture");
  canvas.addEventListener("pointerdown", (e) => {
    if (sceneDim === 3 && $("tool").value === "none") {  // 3D without a tool: the drag turns the picture
      turning = { ...fraction(e), pan: e.shiftKey || e.button === 1 };
      canvas.setPointerCapture(e.pointerId);
      return;
    }
    if ($("tool").value === "none") return;
    stroking = true;
    canvas.setPointerCapture(e.pointerId);
    send(toolMessage(fraction(e), true));
  });
  canvas.addEventListener("pointermove", (e) => {
    const p = fraction(e);
    if (turning) {
      send(viewMessage(turning.pan ? "pan" : "orbit", p.x - turning.x, p.y - turning.y));
      turning.x = p.x;
      turning.y = p.y;
      return;
    }
    send({ t: "pointer", x: p.x, y: p.y });
    if (stroking) send(toolMessage(p, true));
  });
  canvas.addEventListener("wheel", (e) => {
    if (sceneDim !== 3) return;
    send(viewMessage("zoom", 0, -e.deltaY / 1000));
    e.preventDefault();
  }, { passive: false });
  const end = (e) => {
    turning = null;
    if (stroking) { stroking = false; send(toolMessage(fraction(e), false)); }
  };
  canvas.addEventListener("pointerup", end);
  canvas.addEventListener("pointercancel", end);
  canvas.addEventListener("keydown", (e) => {  // the keyboard's pointer: arrows move it, Enter held uses the tool
    const step = e.shiftKey ? 0.1 : 0.02;
    const moves = { ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, -step], ArrowDown: [0, step] };
    const turns = sceneDim === 3 && $("tool").value === "none";
    if (turns && (moves[e.key] || e.key === "+" || e.key === "-")) {  // 3D without a tool: arrows turn, + - zoom
      if (moves[e.key]) send(viewMessage("orbit", 2 * moves[e.key][0], 2 * moves[e.key][1]));
      else send(viewMessage("zoom", 0, e.key === "+" ? 0.1 : -0.1));
      e.preventDefault();
    } else if (moves[e.key]) {
      keyboardPoint.x = Math.min(Math.max(keyboardPoint.x + moves[e.key][0], 0), 1);
      keyboardPoint.y = Math.min(Math.max(keyboardPoint.y + moves[e.key][1], 0), 1);
      send({ t: "pointer", ...keyboardPoint });
      if (stroking) send(toolMessage(keyboardPoint, true));
      e.preventDefault();
    } else if (e.key === "Enter" && $("tool").value !== "none") {
      stroking = true;
      send(toolMessage(keyboardPoint, true));
      e.preventDefault();
    }
  });
  canvas.addEventListener("keyup", (e) => {
    if (e.key === "Enter" && stroking) { stroking = false; send(toolMessage(keyboardPoint, false)); }
  });
}

function setupControls() {
  $("pause").addEventListener("click", () => send({ t: "action", name: paused ? "play" : "pause" }));
  for (const name of ["step", "reset", "undo"]) $(name).addEventListener("click", () => send({ t: "action", name }));
  // the scene picker opens a scene when it is confirmed: picked with the mouse, or Enter after the arrows (an
  // arrow key alone, which browsers report as a change, only moves through the list)
  let byKeys = false;
  const openPicked = () => { if ($("scene").value !== currentScene) send({ t: "scene", name: $("scene").value }); };
  $("scene").addEventListener("keydown", (e) => {
    if (e.key === "Enter") { byKeys = false; openPicked(); e.preventDefault(); }
    else if (!["Tab", "Shift"].includes(e.key)) byKeys = true;
  });
  $("scene").addEventListener("pointerdown", () => { byKeys = false; });
  $("scene").addEventListener("change", () => { if (byKeys) say(t("scene_confirm")); else openPicked(); });
  $("describe").addEventListener("click", () => { if (lastSummary) speak(lastSummary); });
  $("tool").addEventListener("change", () => { $("material-row").hidden = $("tool").value !== "spawn"; });
  $("lang").addEventListener("change", () => setLanguage($("lang").value));
  $("brush").addEventListener("input", () => { $("brush-value").textContent = $("brush").value; });
  $("download").addEventListener("click", () => {
    if (!sid) return;
    const a = document.createElement("a");
    a.href = `api/state?sid=${sid}&key=${encodeURIComponent(sessionKey)}${token ? "&token=" + token : ""}`;
    a.download = ($("scene").value || "sandbox") + ".npz";
    a.click();
  });
  $("upload").addEventListener("change", async () => {
    const file = $("upload").files[0];
    if (!file || !sid) return;
    const response = await fetch(`api/state?sid=${sid}&key=${encodeURIComponent(sessionKey)}${token ? "&token=" + token : ""}`, { method: "POST", body: file });
    if (!response.ok) say(await response.text());
    $("upload").value = "";
  });
}

async function start() {
  await setLanguage(chooseLanguage());
  const response = await fetch(`api/scenes${token ? "?token=" + token : ""}`);
  const { scenes, default: first } = await response.json();
  const wanted = params.get("scene");
  $("scene").replaceChildren(...scenes.map((name) => new Option(named("scene", name), name)));
  $("scene").value = scenes.includes(wanted) ? wanted : first;
  setupControls();
  setupPicture();
  connect($("scene").value);
}

start();
