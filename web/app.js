// The classification page: pick or drop a photograph, the server finds the sphere
// (POST /v1/locate), the user checks or corrects the circle and the white reference, then
// POST /v1/models/{name}/classify answers with probabilities, pictures and neighbours.
"use strict";

const $ = (id) => document.getElementById(id);

const state = {
  file: null,
  picture: null, // an <img> (or the server's preview) drawn in image coordinates
  width: 0,
  height: 0,
  circle: null, // {cx, cy, r} in image pixels
  rect: null, // white card {x, y, w, h} in image pixels
  drag: null, // what the pointer moves: "centre", "rim", "rect"
  models: [],
  chosen: 0, // counts photos chosen, so that a late answer for an earlier one is dropped
  candidates: [], // the circles detection found, most confident first (POST /v1/locate)
  candidate: 0, // which of them is shown
  view: null, // the part of the photograph shown {x, y, w, h} (pixel edges); null: all of it
};

const MIN_RADIUS = 32;
// A circle drawn smaller than this many CSS pixels across is zoomed to: its handles would
// almost touch.
const SMALL_CIRCLE_CSS = 120;

// ---- messages -------------------------------------------------------------------------

function status(text) {
  $("status").textContent = text;
}

function showError(title, detail) {
  let text = detail || "";
  // Problem details often begin by restating their title ("unsupported image format: …").
  if (text.toLowerCase().startsWith(title.toLowerCase())) {
    text = text.slice(title.length).replace(/^[\s:;,.—-]+/, "");
  }
  $("error-title").textContent = title;
  $("error-detail").textContent = text;
  $("error").hidden = false;
  // Where the user looks: the error, wherever the page was scrolled to.
  $("error").scrollIntoView({ block: "nearest" });
}

/** What locating the sphere said: stays until another photograph is chosen. */
function showNote(text) {
  $("note").textContent = text || "";
  $("note").hidden = !text;
}

function clearError() {
  $("error").hidden = true;
}

/** Throws {title, detail} from a problem document (or whatever the server said). */
async function fail(response) {
  let problem = { title: `HTTP ${response.status}`, detail: response.statusText };
  try {
    const body = await response.json();
    problem = { title: body.title || problem.title, detail: body.detail || "" };
  } catch (_) {
    // Not JSON: keep the status line.
  }
  throw problem;
}

async function post(url, form) {
  let response;
  try {
    response = await fetch(url, { method: "POST", body: form });
  } catch (e) {
    throw { title: "The server cannot be reached", detail: String(e) };
  }
  if (!response.ok) {
    await fail(response);
  }
  return response.json();
}

// ---- models ---------------------------------------------------------------------------

async function loadModels() {
  try {
    const response = await fetch("/v1/models");
    if (!response.ok) {
      await fail(response);
    }
    const list = await response.json();
    state.models = list.models;
    const select = $("model");
    select.replaceChildren();
    for (const m of list.models) {
      const option = document.createElement("option");
      option.value = m.name;
      option.textContent = `${m.name} (${m.classes.length} classes)`;
      option.selected = m.name === list.default_model;
      select.append(option);
    }
  } catch (problem) {
    showError(problem.title || "Models", problem.detail || String(problem));
  }
}

// ---- the photograph -------------------------------------------------------------------

function loadBrowserImage(file) {
  return new Promise((resolve) => {
    const img = new Image();
    const url = URL.createObjectURL(file);
    img.onload = () => resolve(img);
    img.onerror = () => {
      URL.revokeObjectURL(url);
      resolve(null);
    };
    img.src = url;
  });
}

function loadDataUrl(url) {
  return new Promise((resolve, reject) => {
    const img = new Image();
    img.onload = () => resolve(img);
    img.onerror = () => reject({ title: "Preview", detail: "the server's preview does not load" });
    img.src = url;
  });
}

/** One of the page's example photographs, chosen as if it were the user's own. */
async function chooseExample(button) {
  try {
    const response = await fetch(button.dataset.example);
    if (!response.ok) {
      await fail(response);
    }
    const blob = await response.blob();
    await choose(new File([blob], button.dataset.name, { type: blob.type }));
  } catch (problem) {
    showError(problem.title || "Example", problem.detail || String(problem));
  }
}

async function choose(file) {
  if (!file) {
    return;
  }
  clearError();
  showNote("");
  $("result").hidden = true;
  document.body.classList.remove("answered");
  $("stage").hidden = true;
  const ticket = ++state.chosen;
  state.file = file;
  state.rect = null;
  state.view = null;
  $("white-rect").value = "";
  $("normals").value = "";
  if (whiteMode() === "rect") {
    // The card outlined belonged to the last photograph.
    const none = document.querySelector('input[name="white-mode"][value="none"]');
    none.checked = true;
    none.dispatchEvent(new Event("change"));
  }
  status(`Finding the sphere in ${file.name}…`);
  try {
    const shown = await loadBrowserImage(file);
    const form = new FormData();
    form.append("image", file);
    if (!shown) {
      form.append("include", "preview");
    }
    const located = await post("/v1/locate", form);
    if (ticket !== state.chosen) {
      return;
    }
    state.width = located.width;
    state.height = located.height;
    state.picture = shown || (await loadDataUrl(located.preview));
    const g = located.geometry;
    state.candidates = located.candidates || [];
    state.candidate = 0;
    $("next-candidate").hidden = state.candidates.length < 2;
    state.circle = g
      ? { cx: g.cx, cy: g.cy, r: g.r }
      : {
          cx: (located.width - 1) / 2,
          cy: (located.height - 1) / 2,
          r: Math.max(MIN_RADIUS, Math.min(located.width, located.height) / 3),
        };
    $("stage").hidden = false;
    syncInputs();
    // A small ball is shown zoomed, so that its handles can be told apart.
    const small = g && 2 * g.r * cssScaleFor(state.width, state.height) < SMALL_CIRCLE_CSS;
    zoom(small);
    const found = g
      ? `Sphere found (confidence ${g.confidence !== undefined ? g.confidence.toFixed(2) : "n/a"}). Check the circle, then Classify.`
      : "No sphere found automatically: drag the circle onto the sphere (by its centre dot or its rim), then Classify.";
    status(small ? `${found} Zoomed to the circle: it is small in the photograph.` : found);
    if (located.warnings.length) {
      showNote(`Note: ${located.warnings.join(" ")}`);
    }
    // What the status asks to check, on screen: the status, then the picture and its circle.
    $("classify").focus({ preventScroll: true });
    $("status").scrollIntoView({ block: "start" });
  } catch (problem) {
    if (ticket === state.chosen) {
      status("");
      showError(problem.title || "Error", problem.detail || String(problem));
    }
  }
}

// ---- drawing --------------------------------------------------------------------------

/** Canvas pixels per image pixel, and the canvas's CSS pixels per canvas pixel. */
function scales() {
  const canvas = $("canvas");
  const box = canvas.getBoundingClientRect();
  return { toCanvas: canvas.width / view().w, cssPerCanvas: box.width / canvas.width };
}

/** The part of the photograph on the canvas, in image pixels (edges: pixel 0 spans 0…1). */
function view() {
  return state.view || { x: 0, y: 0, w: state.width, h: state.height };
}

/** A square around the circle, four radii wide, inside the photograph. */
function viewAround({ cx, cy, r }) {
  const side = Math.min(Math.max(4 * r, 64), state.width, state.height);
  const place = (c, n) => Math.min(Math.max(c + 0.5 - side / 2, 0), n - side);
  return { x: place(cx, state.width), y: place(cy, state.height), w: side, h: side };
}

/** Zoom to the circle, or back to the whole photograph. */
function zoom(on) {
  state.view = on && state.circle ? viewAround(state.circle) : null;
  const button = $("zoom");
  button.setAttribute("aria-pressed", String(Boolean(state.view)));
  button.textContent = state.view ? "Show the whole photograph" : "Zoom to the circle";
  draw();
}

/** CSS pixels per image pixel when a part `w` × `h` of the photograph fills the canvas. */
function cssScaleFor(w, h) {
  const cssWidth = $("canvas").parentElement.clientWidth || 600;
  return Math.min(cssWidth / w, (window.innerHeight * 0.7) / h);
}

function draw() {
  const canvas = $("canvas");
  const ratio = window.devicePixelRatio || 1;
  const v = view();
  const cssScale = cssScaleFor(v.w, v.h);
  canvas.width = Math.max(1, Math.round(v.w * cssScale * ratio));
  canvas.height = Math.max(1, Math.round(v.h * cssScale * ratio));
  canvas.style.width = `${Math.round(v.w * cssScale)}px`;
  const ctx = canvas.getContext("2d");
  const k = canvas.width / v.w;
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  // The picture may be the server's smaller preview: its own pixels per image pixel.
  const s = (state.picture.naturalWidth || state.picture.width) / state.width;
  ctx.drawImage(state.picture, v.x * s, v.y * s, v.w * s, v.h * s, 0, 0, canvas.width, canvas.height);
  const line = Math.max(2, 2 * ratio);
  if (state.rect) {
    const { x, y, w, h } = state.rect;
    ctx.lineWidth = line;
    ctx.setLineDash([6 * ratio, 4 * ratio]);
    ctx.strokeStyle = "#ffd400";
    ctx.strokeRect((x - v.x) * k, (y - v.y) * k, w * k, h * k);
    ctx.setLineDash([]);
  }
  const { cx, cy, r } = state.circle;
  // Pixel centres are at integer coordinates: pixel (0, 0) spans −½…½.
  const px = (c) => (c + 0.5 - v.x) * k;
  const py = (c) => (c + 0.5 - v.y) * k;
  ctx.lineWidth = line;
  ctx.strokeStyle = "#00e0ff";
  ctx.beginPath();
  ctx.arc(px(cx), py(cy), r * k, 0, 2 * Math.PI);
  ctx.stroke();
  for (const [x, y] of [[cx, cy], [cx + r, cy]]) {
    ctx.fillStyle = "#00e0ff";
    ctx.beginPath();
    ctx.arc(px(x), py(y), 6 * ratio, 0, 2 * Math.PI);
    ctx.fill();
    ctx.strokeStyle = "#003040";
    ctx.stroke();
  }
}

function syncInputs() {
  const { cx, cy, r } = state.circle;
  $("cx").value = cx.toFixed(1);
  $("cy").value = cy.toFixed(1);
  $("r").value = r.toFixed(1);
  if (state.rect) {
    const { x, y, w, h } = state.rect;
    $("white-rect").value = [x, y, w, h].map((v) => Math.round(v)).join(",");
  }
}

/** The next circle detection found (the first again after the last). */
function nextCandidate() {
  if (state.candidates.length < 2) {
    return;
  }
  state.candidate = (state.candidate + 1) % state.candidates.length;
  const c = state.candidates[state.candidate];
  setCircle(c.cx, c.cy, c.r);
  if (state.view) {
    zoom(true);
  }
  const seen = c.rim_visible < 0.999 ? `, ${Math.round(100 * c.rim_visible)} % of its rim in the picture` : "";
  status(`Circle ${state.candidate + 1} of ${state.candidates.length} (confidence ${c.confidence.toFixed(2)}${seen}). Check it, then Classify.`);
}

function setCircle(cx, cy, r) {
  if (![cx, cy, r].every(Number.isFinite)) {
    return;
  }
  state.circle = { cx, cy, r: Math.max(1, r) };
  syncInputs();
  draw();
}

// ---- pointer and keyboard -------------------------------------------------------------

function imagePoint(event) {
  const canvas = $("canvas");
  const box = canvas.getBoundingClientRect();
  const v = view();
  const x = v.x + ((event.clientX - box.left) / box.width) * v.w - 0.5;
  const y = v.y + ((event.clientY - box.top) / box.height) * v.h - 0.5;
  return { x, y };
}

function whiteMode() {
  return document.querySelector('input[name="white-mode"]:checked').value;
}

function onPointerDown(event) {
  if (!state.circle) {
    return;
  }
  const p = imagePoint(event);
  const { cx, cy, r } = state.circle;
  const { toCanvas, cssPerCanvas } = scales();
  const grab = 14 / (toCanvas * cssPerCanvas); // 14 CSS pixels, in image pixels
  const fromCentre = Math.hypot(p.x - cx, p.y - cy);
  if (Math.hypot(p.x - (cx + r), p.y - cy) < grab || Math.abs(fromCentre - r) < grab / 2) {
    state.drag = { what: "rim" };
  } else if (fromCentre < grab || (whiteMode() !== "rect" && fromCentre < r)) {
    state.drag = { what: "centre", dx: cx - p.x, dy: cy - p.y };
  } else if (whiteMode() === "rect") {
    state.drag = { what: "rect", x0: p.x, y0: p.y };
  } else {
    return;
  }
  $("canvas").setPointerCapture(event.pointerId);
  event.preventDefault();
}

function onPointerMove(event) {
  const drag = state.drag;
  if (!drag) {
    return;
  }
  const p = imagePoint(event);
  const { cx, cy, r } = state.circle;
  if (drag.what === "centre") {
    setCircle(p.x + drag.dx, p.y + drag.dy, r);
  } else if (drag.what === "rim") {
    setCircle(cx, cy, Math.hypot(p.x - cx, p.y - cy));
  } else {
    const clamp = (v, n) => Math.min(Math.max(v, 0), n);
    const x0 = clamp(Math.min(drag.x0, p.x) + 0.5, state.width);
    const y0 = clamp(Math.min(drag.y0, p.y) + 0.5, state.height);
    const x1 = clamp(Math.max(drag.x0, p.x) + 0.5, state.width);
    const y1 = clamp(Math.max(drag.y0, p.y) + 0.5, state.height);
    state.rect = { x: x0, y: y0, w: Math.max(1, x1 - x0), h: Math.max(1, y1 - y0) };
    syncInputs();
    draw();
  }
}

function onPointerUp() {
  state.drag = null;
}

function onKey(event) {
  if (!state.circle) {
    return;
  }
  // "+" needs Shift on many keyboards, so Shift scales the arrows only.
  const step = event.shiftKey ? 10 : 1;
  const { cx, cy, r } = state.circle;
  const moves = {
    ArrowLeft: [-step, 0, 0],
    ArrowRight: [step, 0, 0],
    ArrowUp: [0, -step, 0],
    ArrowDown: [0, step, 0],
    "+": [0, 0, 1],
    "=": [0, 0, 1],
    "-": [0, 0, -1],
    _: [0, 0, -1],
    PageUp: [0, 0, 10],
    PageDown: [0, 0, -10],
  };
  const move = moves[event.key];
  if (!move) {
    return;
  }
  event.preventDefault();
  setCircle(cx + move[0], cy + move[1], r + move[2]);
  status(`Circle: centre (${state.circle.cx.toFixed(1)}, ${state.circle.cy.toFixed(1)}), radius ${state.circle.r.toFixed(1)}`);
}

// ---- classify -------------------------------------------------------------------------

function whiteFields(form) {
  const mode = whiteMode();
  if (mode === "value") {
    form.append("white", $("white-value").value);
  } else if (mode === "rect") {
    form.append("white_rect", $("white-rect").value);
  }
  if (mode === "rect") {
    form.append("white_reflectance", $("white-reflectance").value);
  }
}

async function classify() {
  if (!state.file) {
    return;
  }
  clearError();
  const button = $("classify");
  button.disabled = true;
  status("Classifying…");
  try {
    const form = new FormData();
    form.append("image", state.file);
    const normals = $("normals").files[0];
    if (normals) {
      form.append("normals", normals);
    } else {
      // The circle itself, not its rounded display: the page answers as the API does.
      const c = state.circle || { cx: $("cx").value, cy: $("cy").value, r: $("r").value };
      form.append("cx", String(c.cx));
      form.append("cy", String(c.cy));
      form.append("r", String(c.r));
    }
    whiteFields(form);
    form.append("include", "explain,images");
    const model = encodeURIComponent($("model").value);
    const answer = await post(`/v1/models/${model}/classify`, form);
    show(answer);
    status(`Classified in ${answer.timing_ms.total.toFixed(0)} ms by ${answer.model.name} v${answer.model.version}.`);
  } catch (problem) {
    status("");
    // No answer stays beside an error: it was for other inputs.
    $("result").hidden = true;
    showError(problem.title || "Error", problem.detail || String(problem));
  } finally {
    button.disabled = false;
  }
}

function element(tag, text, className) {
  const e = document.createElement(tag);
  if (text !== undefined) {
    e.textContent = text;
  }
  if (className) {
    e.className = className;
  }
  return e;
}

function showBars(probabilities, label) {
  const bars = $("bars");
  bars.replaceChildren();
  for (const { label: name, p } of probabilities) {
    const li = element("li", undefined, name === label ? "top" : "");
    const percent = `${(100 * p).toFixed(1)} %`;
    li.setAttribute("aria-label", `${name}: ${percent}`);
    const track = element("span", undefined, "track");
    const fill = element("span", undefined, "fill");
    fill.style.width = `${Math.max(0, Math.min(100, 100 * p))}%`;
    fill.style.display = "block";
    track.append(fill);
    track.setAttribute("aria-hidden", "true");
    li.append(element("span", name, "name"), track, element("span", percent, "value"));
    bars.append(li);
  }
}

function showImages(images) {
  const subbands = $("subbands");
  subbands.replaceChildren();
  const equivalent = images && images.equivalent_sphere;
  $("equivalent-figure").hidden = !equivalent;
  if (equivalent) {
    $("equivalent").src = equivalent;
  } else {
    $("equivalent").removeAttribute("src");
  }
  if (!images) {
    $("annulus").removeAttribute("src");
    return;
  }
  $("annulus").src = images.annulus;
  const words = { h: "horizontal", v: "vertical", d: "diagonal" };
  for (const band of images.subbands) {
    const figure = element("figure");
    const img = element("img");
    img.src = band.image;
    img.alt = `Wavelet subband, scale ${band.scale}, ${words[band.orientation] || band.orientation}`;
    figure.append(img, element("figcaption", `scale ${band.scale}, ${words[band.orientation] || band.orientation}`));
    subbands.append(figure);
  }
}

function showNeighbours(explain) {
  const list = $("neighbours");
  list.replaceChildren();
  for (const n of explain || []) {
    const li = element("li");
    if (n.thumbnail) {
      const img = element("img");
      img.src = n.thumbnail;
      img.alt = `Training image: class ${n.class} under ${n.illumination}`;
      li.append(img);
    }
    li.append(element("strong", n.class), document.createTextNode(` ${n.illumination}`));
    li.append(element("div", `distance ${n.distance.toFixed(2)}`, "small"));
    list.append(li);
  }
}

function showEstimate(ward) {
  $("estimate-box").hidden = !ward;
  const rows = $("estimate");
  rows.replaceChildren();
  if (!ward) {
    return;
  }
  const format = (v) => (v < 0.01 && v > 0 ? v.toExponential(1) : v.toFixed(3));
  const parameters = [
    ["ρd (diffuse)", "rho_d"],
    ["ρs (specular)", "rho_s"],
    ["α (roughness; 0 is a mirror)", "alpha"],
    ["ρs / (ρd + ρs)", "specular_fraction"],
  ];
  // A parameter the answer does not state (ρd and ρs without white) is left out: the note
  // under the table says why, once.
  for (const [name, key] of parameters.filter(([, key]) => ward[key])) {
    const i = ward[key];
    const row = element("tr");
    const head = element("th", name);
    head.scope = "row";
    row.append(head, element("td", format(i.value)), element("td", `${format(i.low)} – ${format(i.high)}`));
    rows.append(row);
  }
  $("estimate-note").textContent = ward.unknown || "";
  $("estimate-note").hidden = !ward.unknown;
}

function showDomain(domain) {
  $("domain-box").hidden = domain.in_domain;
  $("domain-reasons").replaceChildren(...domain.reasons.map((text) => element("li", text)));
  $("bars-note").hidden = domain.in_domain;
  $("bars").classList.toggle("unreliable", !domain.in_domain);
}

function showSet(set, label) {
  $("set-box").hidden = !set;
  if (!set) {
    return;
  }
  const n = set.labels.length;
  $("set-caption").textContent = n === 1
    ? `Prediction set (${Math.round(100 * set.coverage)} %): one class. Under light the model never saw, the set holds the true class ${Math.round(100 * set.coverage)} % of the time.`
    : `Prediction set (${Math.round(100 * set.coverage)} %): ${n} classes the model cannot tell apart here; one of them is the true class ${Math.round(100 * set.coverage)} % of the time.`;
  $("set").replaceChildren(...set.labels.map((name) => element("li", name, name === label ? "top" : "")));
}

// A material's download link: its Ward parameters (and colour) as GET /v1/material.gltf.
function materialLink(m) {
  const name = m.name.toLowerCase().replace(/[^a-z0-9_-]/g, "-").slice(0, 64);
  const query = { ...m.ward, name };
  if (m.colour) {
    query.colour = m.colour.join(",");
  }
  return `/v1/material.gltf?${new URLSearchParams(query)}`;
}

function materialWords(m) {
  return m.source === "estimate" ? "the estimated parameters" : `class ${m.name}'s parameters`;
}

// The material a download holds (the estimate when it agrees with the class named, else
// the class's, with the estimate offered beside it), rendered by the service.
function showMaterial(material) {
  $("rendered-box").hidden = !material;
  if (!material) {
    return;
  }
  const shown = material.download;
  $("rendered").src = `/v1/preview?${new URLSearchParams({ ...shown.ward, size: 192 })}`;
  $("rendered").alt = `A sphere of ${materialWords(shown)}, rendered`;
  $("rendered-caption").textContent =
    `How it looks: ${materialWords(shown)} rendered by the service under a procedural sky (GET /v1/preview).`;
  $("gltf").href = materialLink(shown);
  $("gltf").textContent = `Download ${shown.source === "estimate" ? "the estimate" : shown.name} for a renderer (glTF)`;
  const other = material.alternative;
  $("gltf-alternative").hidden = !other;
  if (other) {
    $("gltf-alternative").href = materialLink(other);
    $("gltf-alternative").textContent = `Download ${materialWords(other)} instead (glTF)`;
  }
  $("material-note").textContent = material.note.charAt(0).toUpperCase() + material.note.slice(1) + ".";
}

// The surface's colour: a swatch of the albedo, or why it is unknown.
function showColour(colour) {
  const known = Boolean(colour.srgb);
  $("swatch").hidden = !known;
  if (known) {
    $("swatch").style.background = colour.srgb;
    $("swatch").title = colour.srgb;
  }
  $("colour-text").textContent = known
    ? `Colour (${colour.note}): ${colour.srgb}, linear RGB over white ${colour.rgb.map((c) => c.toFixed(2)).join(", ")}`
    : `Colour ${colour.note}.`;
}

function show(answer) {
  $("label").textContent = answer.label;
  showDomain(answer.domain);
  showSet(answer.prediction_set, answer.label);
  // The description without the class's name again ("white shiny: …" after white_shiny).
  const named = answer.label.replace(/_/g, " ").toLowerCase();
  const description = answer.class.description;
  $("description").textContent = description.toLowerCase().startsWith(named)
    ? description.slice(named.length).replace(/^[\s:;,—-]+/, "")
    : description;
  const w = answer.class.ward;
  $("ward").textContent = w
    ? `Ward parameters: ρd = ${w.rho_d}, ρs = ${w.rho_s}, α = ${w.alpha}`
    : "";
  showEstimate(answer.ward);
  showMaterial(answer.material);
  showColour(answer.colour);
  showBars(answer.probabilities, answer.label);
  const warnings = $("warnings");
  warnings.replaceChildren(...answer.warnings.map((text) => element("li", text)));
  $("warnings-box").hidden = answer.warnings.length === 0;
  showImages(answer.images);
  $("equivalent-classifier").textContent = {
    objects: "Read by the model's classifier for objects, trained on such spheres of objects.",
    with_white: "Read by the model's classifier for spheres (it has none for objects).",
    without_white: "Read by the model's classifier without white.",
  }[answer.classifier] || "";
  showNeighbours(answer.explain);
  $("result").hidden = false;
  const beside = document.body.classList.contains("answered") || window.innerWidth >= 1120;
  document.body.classList.add("answered");
  state.picture && draw();
  if (!beside) {
    $("result-title").scrollIntoView({ behavior: "smooth", block: "start" });
  }
}

// ---- wiring ---------------------------------------------------------------------------

function wire() {
  const drop = $("drop");
  $("file").addEventListener("change", (e) => choose(e.target.files[0]));
  drop.addEventListener("dragover", (e) => {
    e.preventDefault();
    drop.classList.add("over");
  });
  drop.addEventListener("dragleave", () => drop.classList.remove("over"));
  // The drop itself bubbles to the document's handler, which takes it from anywhere.
  drop.addEventListener("drop", () => drop.classList.remove("over"));
  // A photo dropped anywhere on the page is taken, not opened by the browser.
  document.addEventListener("dragover", (e) => e.preventDefault());
  document.addEventListener("drop", (e) => {
    e.preventDefault();
    if (e.dataTransfer.files.length) {
      choose(e.dataTransfer.files[0]);
    }
  });
  const canvas = $("canvas");
  canvas.addEventListener("pointerdown", onPointerDown);
  canvas.addEventListener("pointermove", onPointerMove);
  canvas.addEventListener("pointerup", onPointerUp);
  canvas.addEventListener("pointercancel", onPointerUp);
  canvas.addEventListener("keydown", onKey);
  for (const id of ["cx", "cy", "r"]) {
    $(id).addEventListener("change", () =>
      setCircle(Number($("cx").value), Number($("cy").value), Number($("r").value)),
    );
  }
  $("white-rect").addEventListener("change", () => {
    const [x, y, w, h] = $("white-rect").value.split(",").map(Number);
    state.rect = [x, y, w, h].every(Number.isFinite) ? { x, y, w, h } : null;
    draw();
  });
  // The card's rectangle and reflectance mean something only with a card (also when the
  // browser restores a choice of the card on reload).
  const showWhiteFields = () => {
    $("rect-help").hidden = whiteMode() !== "rect";
    $("white-reflectance-field").hidden = whiteMode() !== "rect";
  };
  showWhiteFields();
  for (const radio of document.querySelectorAll('input[name="white-mode"]')) {
    radio.addEventListener("change", () => {
      showWhiteFields();
      if (whiteMode() === "value") {
        $("white-value").focus();
      }
    });
  }
  for (const button of document.querySelectorAll("[data-example]")) {
    button.addEventListener("click", () => chooseExample(button));
  }
  $("classify").addEventListener("click", classify);
  $("next-candidate").addEventListener("click", nextCandidate);
  $("zoom").addEventListener("click", () => zoom(!state.view));
  window.addEventListener("resize", () => state.picture && draw());
  loadModels();
}

document.addEventListener("DOMContentLoaded", wire);
