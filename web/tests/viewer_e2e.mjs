// End-to-end test of the viewer in a real browser (Debian's Chromium through playwright-core):
// write a small scene (`gshaptics synth sphere`, ~1300 Gaussians), start `gshaptics serve` on it
// with the mouse device, load the page in a small viewport, lower the tool onto the sphere with
// the page's own key handling, and check that the page loaded the scene without an error, shows
// contacts and a force, that the runtime's own log agrees, and save a screenshot.
//
// Usage: node web/tests/viewer_e2e.mjs PATH/TO/gshaptics OUT_DIR [--no-load]
// By default a CPU-burning process runs beside the test, as on a machine doing something else.
// Every wait is bounded by wall time; the whole test must finish within BUDGET_MS.

import { spawnSync } from "node:child_process";
import { writeFileSync } from "node:fs";
import { join } from "node:path";
import { closeAll, fail, finish, serveLog, openPage, setup, startServe, waitFor } from "./harness.mjs";

const ctx = setup("viewer_e2e.mjs");
const { exe, outDir, t0, left } = ctx;

// The small scene: a 0.1 m sphere of Gaussians in metres, z up.
const scene = join(outDir, "sphere.ply");
const synth = spawnSync(exe, ["synth", "sphere", scene, "--spacing", "0.01"], { encoding: "utf8" });
if (synth.status !== 0) {
  console.error(`FAIL: gshaptics synth: ${synth.stderr}`);
  process.exit(1);
}

// A material map: the sphere's upper half is "skin" (the HUD names it under the tool).
const materials = join(outDir, "materials.json");
writeFileSync(materials, JSON.stringify({ materials: [{ name: "skin", stiffness: 800, vibration: 0.3 }],
  regions: [{ material: "skin", box: { min: [-1, -1, 0], max: [1, 1, 1] } }] }));

// A stylus (four parts, tip at the tool centre point, pointing up): the page draws every part.
const serve = startServe(exe, [scene, "--up", "z-up", "--tool", "stylus:0.04,0.008", "--materials", materials,
  "--port", "0", "--quiet", "--no-plot", "--out", outDir]);
const { server, out } = serve;

let browser;
try {
  const url = await serve.url(left());
  console.log(`server at ${url}`);
  const opened = await openPage({ width: 480, height: 320 });
  browser = opened.browser;
  const page = opened.page;
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
  const parts = await page.evaluate(() => window.gshaptics.tool.children.length);
  if (parts !== 4) fail(`the page draws ${parts} tool part(s), not the stylus's 4`);
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
    felt: document.body.dataset.felt, feltNormal: (document.body.dataset.feltNormal || "").split(",").map(Number),
    feltAt: window.gshaptics.felt.position.toArray(), proxy: window.gshaptics.last.proxy.center,
    material: document.getElementById("material").textContent, materialRow: !document.getElementById("material-row").hidden,
    vibration: window.gshaptics.last.vibration,
  }));
  console.log(`page shows ${shown.contacts} contacts, |F| = ${shown.force} N, rate ${shown.rate}, ${shown.drawn} drawn`);
  if (!(shown.contacts > 0)) fail("contacts counter is not > 0");
  if (!(shown.force > 0)) fail("force is not > 0");
  if (!(shown.drawn > 0)) fail("no colliding Gaussian is drawn");
  if (!(shown.tool[2] < start[2])) fail("the tool did not move down");
  console.log(`HUD material: ${shown.material}`);
  if (!shown.materialRow || shown.material !== "skin") fail(`the HUD does not name the material under the tool: '${shown.material}'`);
  // What a VR controller would play: skin's vibration level, and no texture (it has none).
  console.log(`vibration: ${JSON.stringify(shown.vibration)}`);
  if (!shown.vibration || Math.abs(shown.vibration.level - 0.3) > 1e-3 || shown.vibration.texture_rms !== 0)
    fail(`the state frame does not carry skin's vibration level 0.3 and no texture: ${JSON.stringify(shown.vibration)}`);
  // The felt surface is drawn where the sphere of Gaussians is (radius 0.1 m about the origin,
  // within the discs' thickness), facing out of it (the tool pressed down on its top).
  console.log(`felt surface shown ${shown.felt}, normal ${shown.feltNormal}, at ${shown.feltAt.map((x) => x.toFixed(3))}`);
  if (shown.felt !== "1") fail("the felt surface is not shown while the tool is held");
  else {
    const r = Math.hypot(...shown.feltAt);
    const outward = shown.feltAt.reduce((sum, x, i) => sum + x * shown.feltNormal[i], 0) / r;
    if (!(Math.abs(r - 0.1) < 0.004)) fail(`the felt surface is ${r.toFixed(4)} m from the sphere's centre, not on it`);
    if (!(outward > 0.9)) fail(`the felt surface does not face out of the sphere: ${shown.feltNormal}`);
    if (!(shown.feltNormal[2] > 0.5)) fail(`the felt surface does not face up: ${shown.feltNormal}`);
  }
  // One more frame drawn with the contacts before the screenshot (software GL is slow).
  await page.waitForTimeout(3000);
  const errorShown = await page.evaluate(() => document.body.dataset.error || "");
  if (errorShown) fail(`the page shows an error: ${errorShown}`);
  await page.screenshot({ path: join(outDir, "viewer.png"), timeout: left() });
  console.log(`screenshot ${join(outDir, "viewer.png")}`);
} catch (e) {
  fail(e.message);
} finally {
  await closeAll(ctx, browser, server);
}

// The runtime's own log agrees: ticks with contacts and a non-zero force sent to the device.
await serveLog(ctx, serve);
if (!out.stdout.includes("frames sent")) fail("serve did not report its viewer statistics");
finish(ctx, "viewer e2e");
