// End-to-end test of the viewer in VR with an emulated headset: IWER (the Immersive Web
// Emulation Runtime, npm `iwer`, loaded by the page with ?xr-emulate=quest3) under headless
// Chromium through playwright-core. `gshaptics serve --device xr` on the bundled Truck; the page
// enters an immersive-vr session, the test moves the emulated right controller down into the
// Truck and checks: contacts and a non-zero force in the page's state; vibration pulses while in
// contact (also seen by the emulated actuator), stopped after it; the controller ceasing to report
// fades the force to zero (the XR device's watchdog); and the runtime's own log agrees.
//
// The page draws the Truck through Spark's level-of-detail tree with a 3000-splat budget
// (?quality=low&splat-budget=3000): software GL in headless Chromium draws all 116K splats at
// ~0.4 frames/s, and the controller's pose only reaches the runtime once per XR frame.
//
// Usage: node web/tests/xr_e2e.mjs PATH/TO/gshaptics OUT_DIR [--no-load]
// By default a CPU-burning process runs beside the test, as on a machine doing something else.
// Every wait is bounded by wall time; the whole test must finish within BUDGET_MS.

import { readFileSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { closeAll, fail, finish, serveLog, openPage, setup, sleep, startServe, waitFor } from "./harness.mjs";

const ctx = setup("xr_e2e.mjs");
const { exe, outDir, t0, left } = ctx;
const serve = startServe(exe, ["--device", "xr", "--port", "0", "--quiet", "--no-plot", "--out", outDir]);
const { server } = serve;

let browser;
const report = {};
try {
  const url = await serve.url(left());
  const opened = await openPage({ width: 320, height: 240 });
  browser = opened.browser;
  const page = opened.page;
  await page.goto(`${url}?xr-emulate=quest3&quality=low&splat-budget=3000`, { timeout: left() });
  await page.waitForFunction(() => window.gshaptics && window.gshaptics.xrAvailable === true, null, { timeout: left() });
  await page.waitForFunction(() => document.body.dataset.sceneLoaded === "1" || document.body.dataset.error, null, { timeout: left() });
  const err = await page.evaluate(() => document.body.dataset.error || "");
  if (err) throw new Error(`the page shows an error: ${err}`);
  console.log(`scene loaded after ${((Date.now() - t0) / 1000).toFixed(1)} s`);

  // Enter VR with the page's own button (a user gesture).
  await page.click("#VRButton", { timeout: left() });
  await page.waitForFunction(() => window.gshaptics.xr && window.gshaptics.xr.active, null, { timeout: left() });
  console.log("immersive-vr session started");

  // The emulated right controller, moved in the XR space: start above the object (the tool's
  // start point), then down along the scene's up, in XR coordinates from the page's own placement.
  const setController = (p) => page.evaluate((q) => {
    const c = window.gshapticsXR.controllers.right;
    c.connected = true;
    c.position.set(q[0], q[1], q[2]);
  }, p);
  const hello = await page.evaluate(() => window.gshaptics.hello);
  const r = hello.tool.axes[0];
  const toXR = (w) => page.evaluate((a) => window.gshaptics.worldToXR(a), w);
  const start = hello.tool_start, up = hello.up;
  const at = (k) => start.map((x, i) => x - k * r * up[i]);  // k tool radii below the start
  await setController(await toXR(at(0)));
  await page.waitForFunction(() => window.gshaptics.xr.sent > 3, null, { timeout: left() });
  let contacts = 0, k = 0;
  while (contacts === 0 && k < 20 && left() > 40000) {
    k += 1;
    await setController(await toXR(at(k)));
    await sleep(400);
    contacts = Number(await page.evaluate(() => document.body.dataset.contacts || 0));
  }
  if (!(contacts > 0)) throw new Error(`no contact after lowering the controller ${k} tool radii`);
  await setController(await toXR(at(k + 0.5)));  // press a little further in
  await page.waitForFunction(() => Number(document.body.dataset.force) > 0.1, null, { timeout: Math.min(15000, left()) });
  await sleep(1000);
  const inContact = await page.evaluate(() => {
    const v = window.gshaptics, xr = v.xr;
    const act = window.gshapticsXR.controllers.right.inputSource.gamepad.hapticActuators[0];
    const sym = Object.getOwnPropertySymbols(act)[0];
    return {
      contacts: Number(document.body.dataset.contacts), force: Number(document.body.dataset.force),
      pulses: xr.pulses.filter((p) => p.value > 0).length, onset: xr.pulses.some((p) => p.kind === "onset"),
      actuator: act[sym].lastPulse, fps: v.perf.fps, splats: v.perf.splats, sent: xr.sent,
      rotation: v.last.tool.rotation,
    };
  });
  Object.assign(report, { contact: inContact });
  console.log(`in contact: ${inContact.contacts} contacts, |F| ${inContact.force} N, ${inContact.pulses} vibration pulses ` +
    `(onset ${inContact.onset}), actuator last pulse ${JSON.stringify(inContact.actuator)}, ${inContact.fps.toFixed(1)} fps, ` +
    `${inContact.splats} splats, ${inContact.sent} controller poses sent`);
  if (!(inContact.contacts > 0)) fail("no contacts in the page's state");
  if (!(inContact.force > 0)) fail("no force in the page's state");
  if (!(inContact.pulses > 0)) fail("no vibration pulse during contact");
  if (!inContact.onset) fail("no onset pulse");
  if (!(inContact.actuator && inContact.actuator.value > 0)) fail("the emulated actuator got no pulse");

  // Lift the controller out: the force ends, a stop pulse, and no vibration after it.
  await setController(await toXR(at(0)));
  await page.waitForFunction(() => Number(document.body.dataset.force) === 0, null, { timeout: Math.min(15000, left()) });
  const tLift = await page.evaluate(() => performance.now());
  await sleep(1500);
  const lifted = await page.evaluate((t) => {
    const xr = window.gshaptics.xr;
    const after = xr.pulses.filter((p) => p.t > t);
    return { after: after.filter((p) => p.value > 0).length, stop: xr.pulses.some((p) => p.value === 0), vibrating: xr.vibrating };
  }, tLift + 200);
  Object.assign(report, { lifted });
  console.log(`lifted: stop pulse ${lifted.stop}, ${lifted.after} pulses after, vibrating ${lifted.vibrating}`);
  if (!lifted.stop) fail("no stop pulse when the contact ended");
  if (lifted.after > 0) fail("vibration went on after the contact ended");

  // Back into contact, then the controller stops reporting: the XR device times out, the force fades.
  await setController(await toXR(at(k + 0.5)));
  await page.waitForFunction(() => Number(document.body.dataset.force) > 0.1, null, { timeout: Math.min(15000, left()) });
  await page.evaluate(() => { window.gshapticsXR.controllers.right.connected = false; });
  const tLost = Date.now();
  await page.waitForFunction(() => Number(document.body.dataset.force) === 0, null, { timeout: Math.min(15000, left()) });
  report.fade_s = (Date.now() - tLost) / 1000;
  console.log(`controller lost: force zero after ${report.fade_s.toFixed(2)} s`);
  await page.screenshot({ path: join(outDir, "xr.png"), timeout: left() });
} catch (e) {
  fail(e.message);
} finally {
  await closeAll(ctx, browser, server);
}

const log = await serveLog(ctx, serve);
if (log) {
  const summary = JSON.parse(readFileSync(join(outDir, "run_summary.json"), "utf8"));
  Object.assign(report, { log_ticks: log.ticks, log_contact_ticks: log.withContact, log_max_force: log.maxF,
    watchdog_ticks: summary.runtime.watchdog_ticks });
  console.log(`watchdog ${summary.runtime.watchdog_ticks} ticks`);
  if (!(summary.runtime.watchdog_ticks > 0)) fail("the XR device's watchdog never tripped");
  if (!summary.device.startsWith("xr controller")) fail(`device is ${summary.device}`);
}
report.wall_s = (Date.now() - t0) / 1000;
writeFileSync(join(outDir, "xr_e2e.json"), JSON.stringify(report, null, 2) + "\n");
finish(ctx, "xr e2e");
