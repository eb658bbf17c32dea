// The map viewer of `ffloc serve` (docs/server.md): draws a map's cameras and points with three.js,
// sends dropped images to POST /maps/NAME/localize and draws the answers. Everything it loads
// comes from the server itself.
import * as THREE from "/viewer/three.module.min.js";

const $ = (id) => document.getElementById(id);
const colours = { mapping: 0x78909c, points: 0x5c6bc0, localized: 0x2e7d32, uncertain: 0xef6c00, last: 0xe91e63 };

// ---- HTTP -----------------------------------------------------------------------------------
const keyInput = $("key");
keyInput.value = sessionStorage.getItem("ffloc-key") || "";

async function request(path, init = {}) {
  const headers = new Headers(init.headers || {});
  if (keyInput.value) headers.set("Authorization", "Bearer " + keyInput.value.trim());
  const response = await fetch(path, { ...init, headers });
  const body = await response.json().catch(() => ({ error: "HTTP " + response.status }));
  if (!response.ok) throw new Error(body.error || "HTTP " + response.status);
  return body;
}

function say(text) { $("message").textContent = text; }

// ---- 3D view ----------------------------------------------------------------------------------
const view = $("view");
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setClearColor(0xfafafa);
view.prepend(renderer.domElement);
const scene3d = new THREE.Scene();
const camera = new THREE.PerspectiveCamera(50, 1, 0.01, 1000);
let mapGroup = new THREE.Group();
let queryGroup = new THREE.Group();
scene3d.add(mapGroup, queryGroup);

// An orbit around `target`: drag rotates, shift-drag or right-drag pans, the wheel zooms.
const orbit = { target: new THREE.Vector3(), radius: 5, azimuth: 0.8, elevation: 0.5, up: new THREE.Vector3(0, 1, 0) };

function placeCamera() {
  const up = orbit.up.clone().normalize();
  const side = new THREE.Vector3(1, 0, 0);
  if (Math.abs(side.dot(up)) > 0.9) side.set(0, 0, 1);
  const forward = new THREE.Vector3().crossVectors(side, up).normalize();
  side.crossVectors(up, forward).normalize();
  const direction = forward.clone().multiplyScalar(Math.cos(orbit.elevation) * Math.cos(orbit.azimuth))
    .addScaledVector(side, Math.cos(orbit.elevation) * Math.sin(orbit.azimuth))
    .addScaledVector(up, Math.sin(orbit.elevation));
  camera.position.copy(orbit.target).addScaledVector(direction, orbit.radius);
  camera.up.copy(up);
  camera.lookAt(orbit.target);
  camera.near = orbit.radius / 1000;
  camera.far = orbit.radius * 100;
  camera.updateProjectionMatrix();
}

let drag = null;
renderer.domElement.addEventListener("pointerdown", (e) => {
  drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2 };
  renderer.domElement.setPointerCapture(e.pointerId);
});
renderer.domElement.addEventListener("pointermove", (e) => {
  if (!drag) return;
  const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
  drag.x = e.clientX;
  drag.y = e.clientY;
  if (drag.pan) {
    const scale = orbit.radius / view.clientHeight;
    const right = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 0);
    const up = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 1);
    orbit.target.addScaledVector(right, -dx * scale).addScaledVector(up, dy * scale);
  } else {
    orbit.azimuth -= dx * 0.008;
    orbit.elevation = Math.max(-1.5, Math.min(1.5, orbit.elevation + dy * 0.008));
  }
  render();
});
renderer.domElement.addEventListener("pointerup", () => { drag = null; });
renderer.domElement.addEventListener("contextmenu", (e) => e.preventDefault());
renderer.domElement.addEventListener("wheel", (e) => {
  e.preventDefault();
  orbit.radius *= Math.exp(e.deltaY * 0.001);
  render();
}, { passive: false });

function render() {
  const width = view.clientWidth, height = view.clientHeight;
  renderer.setSize(width, height, false);
  camera.aspect = width / Math.max(1, height);
  placeCamera();
  renderer.render(scene3d, camera);
}
window.addEventListener("resize", render);

function matrixOf(rows) {
  const m = new THREE.Matrix4();
  m.set(...rows[0], ...rows[1], ...rows[2], ...rows[3]);
  return m;
}

// A camera as a pyramid of lines: apex at the centre, base the image's corners at depth `size`
// (OpenCV axes: x right, y down, z forward), then into the world by camera_to_world.
function frustum(rows, k, size, colour, width = 1) {
  const corners = [[0, 0], [k.width, 0], [k.width, k.height], [0, k.height]].map(([u, v]) =>
    new THREE.Vector3((u - k.cx) / k.fx * size, (v - k.cy) / k.fy * size, size));
  const apex = new THREE.Vector3();
  const points = [];
  for (let i = 0; i < 4; ++i) points.push(apex, corners[i], corners[i], corners[(i + 1) % 4]);
  const geometry = new THREE.BufferGeometry().setFromPoints(points);
  geometry.applyMatrix4(matrixOf(rows));
  return new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({ color: colour, linewidth: width }));
}

let glyphSize = 0.1;

function drawMap(sceneJson) {
  scene3d.remove(mapGroup);
  mapGroup = new THREE.Group();
  const centres = sceneJson.cameras.map((c) => new THREE.Vector3(c.camera_to_world[0][3], c.camera_to_world[1][3], c.camera_to_world[2][3]));
  const centre = new THREE.Vector3();
  centres.forEach((c) => centre.add(c));
  if (centres.length) centre.divideScalar(centres.length);
  // Camera spacing sets the glyph size, so a map in millimetres reads like one in metres.
  const distances = centres.map((c) => c.distanceTo(centre)).sort((a, b) => a - b);
  const spread = distances.length ? distances[Math.floor(distances.length * 0.9)] || distances[distances.length - 1] : 1;
  glyphSize = Math.max(spread, 1e-6) * 0.08;
  // The mapping cameras' mean "up" (OpenCV: -y) is the view's up.
  const up = new THREE.Vector3();
  for (const c of sceneJson.cameras) {
    up.x -= c.camera_to_world[0][1];
    up.y -= c.camera_to_world[1][1];
    up.z -= c.camera_to_world[2][1];
    mapGroup.add(frustum(c.camera_to_world, c.intrinsics, glyphSize, colours.mapping));
  }
  if (sceneJson.points.length) {
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.Float32BufferAttribute(sceneJson.points, 3));
    mapGroup.add(new THREE.Points(geometry, new THREE.PointsMaterial({ color: colours.points, size: 2, sizeAttenuation: false })));
  }
  scene3d.add(mapGroup);
  orbit.target.copy(centre);
  orbit.up.copy(up.lengthSq() > 0 ? up.normalize() : new THREE.Vector3(0, 1, 0));
  orbit.radius = Math.max(spread, 1e-3) * 3.5;
}

function drawQueries(recent) {
  scene3d.remove(queryGroup);
  queryGroup = new THREE.Group();
  recent.forEach((entry, i) => {
    const answer = entry.answer;
    if (!answer.camera_to_world) return;
    const last = i === recent.length - 1;
    const colour = last ? colours.last : colours[answer.status] || colours.uncertain;
    queryGroup.add(frustum(answer.camera_to_world, entry.intrinsics, glyphSize * (last ? 1.6 : 1.2), colour));
  });
  scene3d.add(queryGroup);
}

// ---- Panels ---------------------------------------------------------------------------------
function showRecent(recent) {
  const body = $("recent").tBodies[0];
  body.replaceChildren();
  for (const entry of [...recent].reverse()) {
    const a = entry.answer;
    const row = body.insertRow();
    row.insertCell().textContent = a.name;
    const status = row.insertCell();
    status.textContent = a.status;
    status.className = a.status;
    row.insertCell().textContent = a.inliers;
    row.insertCell().textContent = a.timings_ms ? a.timings_ms.total.toFixed(0) : "";
  }
}

// The pose as the answer gives it: each cell shows 7 significant digits and keeps the exact
// number in data-value.
function showAnswer(answer) {
  const parts = [`<b class="${answer.status}">${answer.status}</b>`];
  if (answer.reason) parts.push(`(${answer.reason})`);
  parts.push(`${answer.inliers} inliers of ${answer.pnp_correspondences}`);
  if (answer.timings_ms) parts.push(`${answer.timings_ms.total.toFixed(0)} ms`);
  $("answer").innerHTML = parts.join(" ");
  const table = $("pose");
  table.replaceChildren();
  if (!answer.camera_to_world) return;
  table.createCaption().textContent = "camera_to_world";
  for (const row of answer.camera_to_world) {
    const tr = table.insertRow();
    for (const value of row) {
      const cell = tr.insertCell();
      cell.dataset.value = String(value);
      cell.textContent = value.toPrecision(7);
    }
  }
}

let currentMap = "";

// Scene answers can arrive out of order (the key changed twice, a query answered meanwhile): an
// older answer would draw a stale list of queries over a newer one. Only the latest request
// draws, and a superseded call resolves when the latest has drawn.
let sceneTicket = 0;
let latestScene = Promise.resolve();

function loadScene() {
  if (!currentMap) return Promise.resolve();
  const ticket = ++sceneTicket;
  latestScene = request(`/maps/${encodeURIComponent(currentMap)}/scene`).then((sceneJson) => {
    if (ticket !== sceneTicket) return latestScene;
    drawMap(sceneJson);
    drawQueries(sceneJson.recent);
    showRecent(sceneJson.recent);
    $("summary").textContent = `${sceneJson.method}, ${sceneJson.cameras.length} images, ${sceneJson.points.length / 3} points shown`;
    render();
    document.body.dataset.scene = "loaded";
  });
  return latestScene;
}

async function loadMaps() {
  try {
    const { maps } = await request("/maps");
    const select = $("map");
    select.replaceChildren(...maps.map((m) => new Option(`${m.name} (${m.method})`, m.name)));
    currentMap = maps.length ? maps[0].name : "";
    say(maps.length ? "" : "this key may use no map");
    await loadScene();
  } catch (error) {
    say(error.message);
  }
}

$("map").addEventListener("change", (e) => { currentMap = e.target.value; loadScene().catch((error) => say(error.message)); });
keyInput.addEventListener("change", () => { sessionStorage.setItem("ffloc-key", keyInput.value); loadMaps(); });

// ---- The query ------------------------------------------------------------------------------
let queryFile = null;
const drop = $("drop"), fileInput = $("file");
drop.addEventListener("click", () => fileInput.click());
drop.addEventListener("dragover", (e) => { e.preventDefault(); drop.classList.add("over"); });
drop.addEventListener("dragleave", () => drop.classList.remove("over"));
drop.addEventListener("drop", (e) => {
  e.preventDefault();
  drop.classList.remove("over");
  if (e.dataTransfer.files.length) chooseFile(e.dataTransfer.files[0]);
});
fileInput.addEventListener("change", () => { if (fileInput.files.length) chooseFile(fileInput.files[0]); });

// A guess the user should correct: principal point at the centre, a 60 degree horizontal view.
function chooseFile(file) {
  queryFile = file;
  const preview = $("preview");
  preview.onload = () => {
    const w = preview.naturalWidth, h = preview.naturalHeight;
    if (!$("fx").value) {
      const f = (w / 2 / Math.tan(Math.PI / 6)).toFixed(1);
      $("fx").value = f;
      $("fy").value = f;
      $("cx").value = ((w - 1) / 2).toFixed(1);
      $("cy").value = ((h - 1) / 2).toFixed(1);
    }
    $("localize").disabled = false;
    document.body.dataset.image = "ready";
  };
  preview.src = URL.createObjectURL(file);
  preview.hidden = false;
}

$("localize").addEventListener("click", async () => {
  if (!queryFile || !currentMap) return;
  const form = new FormData();
  form.append("image", queryFile, queryFile.name);
  form.append("name", queryFile.name);
  for (const field of ["fx", "fy", "cx", "cy"]) form.append(field, $(field).value);
  if ($("distortion").value.trim()) form.append("distortion", $("distortion").value.trim());
  say("localizing...");
  document.body.dataset.answer = "waiting";
  try {
    const answer = await request(`/maps/${encodeURIComponent(currentMap)}/localize`, { method: "POST", body: form });
    showAnswer(answer);
    say("");
    await loadScene();
    document.body.dataset.answer = "shown";
  } catch (error) {
    $("answer").innerHTML = `<b class="error">error</b> ${error.message.replace(/</g, "&lt;")}`;
    $("pose").replaceChildren();
    say("");
    document.body.dataset.answer = "error";
  }
});

loadMaps();
