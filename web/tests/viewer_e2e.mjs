// End-to-end test of the viewer in a real browser (Debian's Chromium through playwright-core):
// write a small scene (`gshaptics synth sphere`, ~1300 Gaussians), start `gshaptics serve` on it
// with the mouse device, load the page in a small viewport, lower the tool onto the sphere with
// the page's own key handling, and check that the page loaded the scene without an error, shows
// contacts and a force, that the runtime's own log agrees, and save a screenshot.
//
// Usage: node web/tests/viewer_e2e.mjs PATH/TO/gshaptics OUT_DIR [--no-load]
// By default a CPU-burning process runs beside the test, as on a machine doing something else.
// Every wait is bounded by wall time; the whole test must finish within BUDGET_MS.

import { spawn, spawnSync } from "node:child_process";
import { existsSync, mkdirSync, readFileSync } from "node:fs";
import { join } from "node:path";
import { chromium } from "playwright-core";

const [exe, outDir, flag] = process.argv.slice(2);
const BUDGET_MS = 120000;
const t0 = Date.now();
const left = () => Math.max(1000, BUDGET_MS - (Date.now() - t0));
if (!exe || !outDir) {
  console.error("usage: viewer_e2e.mjs PATH/TO/gshaptics OUT_DIR");
  process.exit(2);
}
const CHROMIUM = "/usr/bin/chromium";
if (!existsSync(CHROMIUM)) {
  console.log(`SKIP: ${CHROMIUM} not installed (scripts/setup.sh installs Debian's chromium)`);
  process.exit(77);
}
mkdirSync(outDir, { recursive: true });

// The small scene: a 0.1 m sphere of Gaussians in metres, z up.
const scene = join(outDir, "sphere.ply");
const synth = spawnSync(exe, ["synth", "sphere", scene, "--spacing", "0.01"], { encoding: "utf8" });
if (synth.status !== 0) {
  console.error(`FAIL: gshaptics synth: ${synth.stderr}`);
  process.exit(1);
}
// Another CPU-heavy process on this machine for the whole test.
const burner = flag === "--no-load" ? null
  : spawn(process.execPath, ["-e", "const e = Date.now() + 600000; while (Date.now() < e) {}"], { stdio: "ignore" });

function fail(msg) {
  console.error(`FAIL: ${msg}`);
  process.exitCode = 1;
}

const server = spawn(exe, ["serve", scene, "--up", "z-up", "--tool-radius", "0.008", "--port", "0", "--quiet", "--no-plot", "--out", outDir],
  { stdio: ["ignore", "pipe", "pipe"] });
let stdout = "", stderr = "";
server.stdout.on("data", (d) => { stdout += d; });
server.stderr.on("data", (d) => { stderr += d; });
const exited = new Promise((resolve) => server.on("exit", (code, sig) => resolve({ code, sig })));

async function waitFor(pred, ms, what) {
  const t0 = Date.now();
  while (Date.now() - t0 < ms) {
    const v = await pred();
    if (v) return v;
    await new Promise((r) => setTimeout(r, 200));
  }
  throw new Error(`timed out after ${ms} ms waiting for ${what}`);
}

let browser;
try {
  const url = await waitFor(() => (stdout.match(/viewer\s+(http:\/\/\S+)/) || [])[1], left(), "the server URL");
  console.log(`server at ${url}`);
  browser = await chromium.launch({
    executablePath: CHROMIUM,
    args: ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
      "--disable-background-networking", "--disable-component-update", "--disable-sync",
      "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
  });
  const page = await browser.newPage({ viewport: { width: 480, height: 320 } });
  page.on("console", (m) => { if (m.type() === "error") console.log(`page error: ${m.text()}`); });
  page.on("pageerror", (e) => console.log(`page exception: ${e.message}`));
  await page.goto(url, { timeout: left() });
  await page.waitForFunction(() => document.getElementById("status").textContent === "connected", null, { timeout: left() });
  await page.waitForFunction(() => window.gshaptics && window.gshaptics.last !== null, null, { timeout: left() });
  await page.waitForFunction(() => document.body.dataset.sceneLoaded === "1" || document.body.dataset.error, null, { timeout: left() });
  const loadState = await page.evaluate(() => ({
    loaded: document.body.dataset.sceneLoaded === "1", error: document.body.dataset.error || "",
    overlay: document.getElementById("loading").hidden,
  }));
  if (!loadState.loaded) throw new Error(`the page did not load the scene: ${loadState.error}`);
  if (!loadState.overlay) fail("the loading indicator is still shown after the scene loaded");
  console.log(`scene loaded after ${((Date.now() - t0) / 1000).toFixed(1)} s`);
  const start = await page.evaluate(() => window.gshaptics.last.tool.center);
  console.log(`tool starts at ${start.map((x) => x.toFixed(3))}`);

  // Lower the tool along the scene's up axis with the page's own keys (E: half a tool radius),
  // until the page shows a contact.
  let contacts = 0;
  const keysUntil = Date.now() + Math.min(60000, left() - 15000);
  while (Date.now() < keysUntil && contacts === 0) {
    await page.keyboard.press("E");
    await page.waitForTimeout(300);
    contacts = Number(await page.evaluate(() => document.body.dataset.contacts || 0));
  }
  if (!(contacts > 0)) throw new Error("the page never showed a contact");
  // Let the soft start and the filters settle, then read the page.
  await page.waitForTimeout(1500);
  const shown = await page.evaluate(() => ({
    contacts: Number(document.getElementById("contacts").textContent),
    force: Number(document.body.dataset.force),
    rate: document.getElementById("rate").textContent,
    drawn: window.gshaptics.contacts.count,
    tool: window.gshaptics.last.tool.center,
  }));
  console.log(`page shows ${shown.contacts} contacts, |F| = ${shown.force} N, rate ${shown.rate}, ${shown.drawn} drawn`);
  if (!(shown.contacts > 0)) fail("contacts counter is not > 0");
  if (!(shown.force > 0)) fail("force is not > 0");
  if (!(shown.drawn > 0)) fail("no colliding Gaussian is drawn");
  if (!(shown.tool[2] < start[2])) fail("the tool did not move down");
  // One more frame drawn with the contacts before the screenshot (software GL is slow).
  await page.waitForTimeout(3000);
  const errorShown = await page.evaluate(() => document.body.dataset.error || "");
  if (errorShown) fail(`the page shows an error: ${errorShown}`);
  await page.screenshot({ path: join(outDir, "viewer.png"), timeout: left() });
  console.log(`screenshot ${join(outDir, "viewer.png")}`);
} catch (e) {
  fail(e.message);
} finally {
  if (browser) await browser.close();
  server.kill("SIGINT");
  if (burner) burner.kill("SIGKILL");
}

const { code } = await exited;
if (code !== 0) fail(`gshaptics serve exited with ${code}: ${stderr.slice(-500)}`);
// The runtime's own log agrees: ticks with contacts and a non-zero force sent to the device.
const logPath = join(outDir, "servo_log.csv");
if (!existsSync(logPath)) {
  fail(`no ${logPath}`);
} else {
  const [header, ...rows] = readFileSync(logPath, "utf8").trim().split("\n");
  const col = Object.fromEntries(header.split(",").map((n, i) => [n, i]));
  let withContact = 0, maxF = 0;
  for (const r of rows) {
    const v = r.split(",").map(Number);
    if (v[col.contacts] > 0) withContact++;
    maxF = Math.max(maxF, Math.hypot(v[col.fx], v[col.fy], v[col.fz]));
  }
  console.log(`runtime log: ${rows.length} ticks, ${withContact} with contacts, max |F| ${maxF.toFixed(3)} N`);
  if (!(withContact > 0)) fail("the runtime's log has no tick with contacts");
  if (!(maxF > 0)) fail("the runtime's log never sent a force");
  const last = rows[rows.length - 1].split(",").map(Number);
  if (Math.hypot(last[col.fx], last[col.fy], last[col.fz]) !== 0) fail("the device was not left at zero force");
}
if (!stdout.includes("frames sent")) fail("serve did not report its viewer statistics");
const wall = (Date.now() - t0) / 1000;
console.log(`wall time ${wall.toFixed(1)} s${burner ? " with a CPU-burning process beside it" : ""} (budget ${BUDGET_MS / 1000} s)`);
if (wall * 1000 > BUDGET_MS) fail(`took ${wall.toFixed(1)} s, over the ${BUDGET_MS / 1000} s budget`);
console.log(process.exitCode ? "viewer e2e: FAILED" : "viewer e2e: OK");
