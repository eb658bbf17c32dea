// Browser tests in headless Chromium (driven by playwright-core), run by run_browser_tests.sh:
//  1. the map viewer of `ffloc serve`: load it with an API key, upload a query, and check that the
//     pose it shows is the JSON answer of POST /maps/NAME/localize for the same image;
//  2. the report of `ffloc eval --html`: it renders its charts with no script error.
// Both pages must load nothing but what the server or the file holds. Screenshots go to the
// folder given second (viewer.png, report.png).
// Usage: node browser_test.mjs FFLOC_CLI SCREENSHOT_DIR
import { spawn, execFileSync } from "node:child_process";
import { mkdtempSync, mkdirSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import path from "node:path";
import assert from "node:assert/strict";
import { chromium } from "playwright-core";

const [ffloc, screenshots] = process.argv.slice(2);
const executablePath = process.env.CHROMIUM || "/usr/bin/chromium";
const key = "viewer-test-key-0123456789";
const work = mkdtempSync(path.join(tmpdir(), "ffloc_browser_"));
mkdirSync(screenshots, { recursive: true });
let server = null;
let context = null;

function cli(...args) {
  return execFileSync(ffloc, args.map(String), { stdio: ["ignore", "pipe", "pipe"] }).toString();
}

// Starts `ffloc serve` on a free loopback port and resolves with the port once it listens.
function startServer(map, keys) {
  server = spawn(ffloc, ["serve", "--map", `kitchen=${map}`, "--keys", keys, "--port", "0", "--threads", "1"], {
    stdio: ["ignore", "ignore", "pipe"],
  });
  return new Promise((resolve, reject) => {
    let log = "";
    server.stderr.on("data", (chunk) => {
      log += chunk;
      const listening = log.match(/listening on http:\/\/127\.0\.0\.1:(\d+)/);
      if (listening) resolve(Number(listening[1]));
    });
    server.on("exit", (code) => reject(new Error(`ffloc serve exited (${code}): ${log}`)));
  });
}

// Requests that leave the machine fail the test: the pages must carry everything they need.
function refuseTheNetwork(page, outside) {
  return page.route("**/*", (route) => {
    const url = new URL(route.request().url());
    if (url.protocol === "file:" || url.protocol === "data:" || url.protocol === "blob:" || url.hostname === "127.0.0.1") {
      return route.continue();
    }
    outside.push(url.href);
    return route.abort();
  });
}

async function testViewer() {
  cli("synth", "--out", `${work}/synth`, "--seed", 5, "--kind", "indoor", "--size", "320x240", "--mapping-frames", 16,
    "--query-frames", 4, "--quiet");
  const sceneDir = `${work}/synth/scene_000_indoor`;
  cli("map", "--dataset", sceneDir, "-o", `${work}/kitchen.ffmap`, "--quiet", "--threads", 1);
  writeFileSync(`${work}/keys.txt`, `${key} *\n`);
  const port = await startServer(`${work}/kitchen.ffmap`, `${work}/keys.txt`);
  const origin = `http://127.0.0.1:${port}`;

  const manifest = JSON.parse(readFileSync(`${sceneDir}/manifest.json`, "utf8"));
  const query = manifest.frames.find((frame) => frame.split === "query");
  const k = manifest.cameras[query.camera];
  const imagePath = `${sceneDir}/${query.image}`;

  const page = await context.newPage();
  const errors = [];
  const outside = [];
  page.on("pageerror", (error) => errors.push(error.message));
  await refuseTheNetwork(page, outside);
  await page.goto(`${origin}/`);
  // Without a key the server refuses the map list, and the page says so.
  await page.waitForFunction(() => document.getElementById("message").textContent.includes("unauthorized"));
  await page.fill("#key", key);
  await page.dispatchEvent("#key", "change");
  await page.waitForSelector("body[data-scene=loaded]");
  const summary = await page.textContent("#summary");
  assert.match(summary, /^classical, 16 images, [1-9]\d* points shown$/);

  await page.setInputFiles("#file", imagePath);
  await page.waitForSelector("body[data-image=ready]");
  for (const field of ["fx", "fy", "cx", "cy"]) await page.fill(`#${field}`, String(k[field]));
  await page.click("#localize");
  await page.waitForSelector("body[data-answer=shown]", { timeout: 60000 });

  const shown = await page.$$eval("#pose tr", (rows) =>
    rows.map((row) => [...row.cells].map((cell) => ({ value: cell.dataset.value, text: cell.textContent }))));
  const recent = await page.$$eval("#recent tbody tr", (rows) => rows.map((row) => row.cells[1].textContent));

  // The same request as the page's, straight to the server.
  const form = new FormData();
  form.append("image", new Blob([readFileSync(imagePath)]), path.basename(imagePath));
  for (const field of ["fx", "fy", "cx", "cy"]) form.append(field, String(k[field]));
  const response = await fetch(`${origin}/maps/kitchen/localize`, {
    method: "POST", body: form, headers: { Authorization: `Bearer ${key}` },
  });
  assert.equal(response.status, 200);
  const answer = await response.json();
  assert.ok(answer.camera_to_world, `the query has no pose: ${JSON.stringify(answer)}`);
  assert.equal(shown.length, 4);
  for (let r = 0; r < 4; ++r) {
    for (let c = 0; c < 4; ++c) {
      assert.equal(Number(shown[r][c].value), answer.camera_to_world[r][c], `pose[${r}][${c}]`);
      assert.equal(shown[r][c].text, answer.camera_to_world[r][c].toPrecision(7), `shown pose[${r}][${c}]`);
    }
  }
  assert.deepEqual(recent, [answer.status], "the page lists its query with its status");

  // The 3D view drew something: pixels other than the background.
  const drawn = await page.evaluate(() => {
    const source = document.querySelector("#view canvas");
    const copy = document.createElement("canvas");
    copy.width = source.width;
    copy.height = source.height;
    const context2d = copy.getContext("2d");
    context2d.drawImage(source, 0, 0);
    const pixels = context2d.getImageData(0, 0, copy.width, copy.height).data;
    let count = 0;
    for (let i = 0; i < pixels.length; i += 4) if (pixels[i] < 200 || pixels[i + 2] < 200) ++count;
    return count;
  });
  assert.ok(drawn > 500, `the 3D view is nearly empty (${drawn} pixels drawn)`);
  await page.screenshot({ path: path.join(screenshots, "viewer.png") });
  assert.deepEqual(errors, [], "script errors");
  assert.deepEqual(outside, [], "requests outside the server");
  console.log(`viewer: pose shown equals the JSON answer (${answer.status}, ${answer.inliers} inliers); ` +
    `${drawn} pixels drawn; screenshot ${path.join(screenshots, "viewer.png")}`);
}

async function testReport() {
  const report = `${work}/report.html`;
  cli("eval", "--dataset", `${work}/synth/scene_000_indoor`, "--methods", "oracle-depth,classical", "--quiet",
    "--threads", 1, "--html", report);
  const page = await context.newPage();
  const errors = [];
  const outside = [];
  page.on("pageerror", (error) => errors.push(error.message));
  await refuseTheNetwork(page, outside);
  await page.goto(`file://${report}`);
  const curves = await page.$$eval("path.cdf", (paths) => paths.length);
  const thumbnails = await page.$$eval("img[src^='data:image/jpeg']", (images) => images.filter((i) => i.naturalWidth > 0).length);
  const rows = await page.$$eval("table tr", (trs) => trs.length);
  assert.ok(curves >= 4, `${curves} error curves (two methods, translation and rotation)`);
  assert.ok(thumbnails > 0, "no thumbnail decoded");
  assert.ok(rows >= 3, "the summary table has no rows");
  await page.screenshot({ path: path.join(screenshots, "report.png"), fullPage: true });
  assert.deepEqual(errors, [], "script errors");
  assert.deepEqual(outside, [], "requests outside the file");
  console.log(`report: ${curves} curves, ${thumbnails} thumbnails, ${rows} table rows; screenshot ${path.join(screenshots, "report.png")}`);
}

try {
  context = await chromium.launchPersistentContext(path.join(work, "profile"), {
    executablePath,
    headless: true,
    viewport: { width: 1400, height: 900 },
    args: ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
      "--disable-background-networking", "--disable-component-update", "--disable-sync"],
  });
  await testViewer();
  await testReport();
} finally {
  if (context) await context.close();
  if (server) server.kill("SIGTERM");
  rmSync(work, { recursive: true, force: true });
}
