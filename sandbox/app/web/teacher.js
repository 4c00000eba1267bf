// The teacher's view: every session with a small live picture; pause them all, or send a scene or a setting to all.
"use strict";
const token = new URLSearchParams(location.search).get("token") || "";
const teacher = new URLSearchParams(location.search).get("teacher") || ""; // also kept in a cookie by the page
const q = (extra) => {
  const p = new URLSearchParams(extra || {});
  if (token) p.set("token", token);
  if (teacher) p.set("teacher", teacher);
  return "?" + p;
};
const $ = (id) => document.getElementById(id);
let words = {};

const named = (kind, name) => words[`${kind}_${name}`] ?? name.replaceAll("_", " ");

async function language() {
  // ?lang= first (as the students' page), then the language the page last used, then the browser's
  const asked = new URLSearchParams(location.search).get("lang") || localStorage.getItem("sandbox-lang") || navigator.language || "en";
  const lang = ["en", "fr", "ar"].includes(asked.slice(0, 2)) ? asked.slice(0, 2) : "en";
  words = await (await fetch(`static/i18n/${lang}.json${q()}`)).json();
  document.documentElement.lang = lang;
  document.documentElement.dir = lang === "ar" ? "rtl" : "ltr";
  for (const el of document.querySelectorAll("[data-i18n]")) el.textContent = words[el.dataset.i18n] || el.textContent;
}

async function broadcast(message) {
  const response = await fetch(`api/broadcast${q()}`, { method: "POST", body: JSON.stringify(message) });
  $("status").textContent = response.ok ? `→ ${(await response.json()).sent}` : await response.text();
}

async function refresh() {
  const { sessions } = await (await fetch(`api/sessions${q()}`)).json();
  const rows = sessions.map((s) => {
    const tr = document.createElement("tr");
    const img = document.createElement("img");
    img.src = `api/thumb${q({ sid: s.sid, n: Date.now() })}`;
    img.alt = `${named("scene", s.scene)}, t = ${s.time.toFixed(1)} s`;
    img.width = 240; img.height = 135;
    for (const text of [s.sid, named("scene", s.scene), s.time.toFixed(1)]) {
      const td = document.createElement("td"); td.textContent = text; tr.append(td);
    }
    const td = document.createElement("td"); td.append(img); tr.append(td);
    return tr;
  });
  if (!rows.length) { const tr = document.createElement("tr"); tr.textContent = words.no_sessions || ""; rows.push(tr); }
  $("sessions").replaceChildren(...rows);
}

async function start() {
  await language();
  const { scenes } = await (await fetch(`api/scenes${q()}`)).json();
  $("scene").replaceChildren(...scenes.map((name) => new Option(named("scene", name), name)));
  $("pause-all").onclick = () => broadcast({ t: "action", name: "pause" });
  $("play-all").onclick = () => broadcast({ t: "action", name: "play" });
  $("push-scene").onclick = () => broadcast({ t: "scene", name: $("scene").value });
  $("push-air").onclick = () => broadcast({ t: "set", key: "air", value: Number($("air").value) });
  refresh();
  setInterval(refresh, 3000);
}
start();
