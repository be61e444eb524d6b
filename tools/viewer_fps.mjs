// Frame rate of the viewer page for a quality setting, in headless Chromium (software GL):
// serves the bundled Truck (or SCENE) with `gshaptics serve --device xr`, opens the page with the
// given query (e.g. "quality=low&splat-budget=3000", add "&xr-emulate=quest3" and --enter-vr for
// the emulated VR session) at 320x240, waits for the scene, and reports the page's own frame
// counter over 8 s. Software GL says nothing about a headset's GPU; this compares settings.
//
// Usage: node tools/viewer_fps.mjs PATH/TO/gshaptics QUERY [--enter-vr] [SCENE]

import { spawn } from "node:child_process";
import { chromium } from "../web/node_modules/playwright-core/index.mjs";

const [exe, query, ...rest] = process.argv.slice(2);
if (!exe || query === undefined) {
  console.error("usage: node tools/viewer_fps.mjs PATH/TO/gshaptics QUERY [--enter-vr] [SCENE]");
  process.exit(2);
}
const enterVr = rest.includes("--enter-vr");
const scene = rest.filter((a) => a !== "--enter-vr");
const server = spawn(exe, ["serve", ...scene, "--device", "xr", "--port", "0", "--quiet", "--no-plot", "--out", "runs/viewer_fps"],
  { stdio: ["ignore", "pipe", "inherit"] });
let stdout = "";
server.stdout.on("data", (d) => { stdout += d; });
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const t0 = Date.now();
while (!/viewer\s+(http:\/\/\S+)/.test(stdout) && Date.now() - t0 < 60000) await sleep(100);
const url = (stdout.match(/viewer\s+(http:\/\/\S+)/) || [])[1];
const browser = await chromium.launch({ executablePath: "/usr/bin/chromium",
  args: ["--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"] });
try {
  const page = await browser.newPage({ viewport: { width: 320, height: 240 } });
  await page.goto(`${url}?${query}`);
  await page.waitForFunction(() => document.body.dataset.sceneLoaded === "1", null, { timeout: 120000 });
  if (enterVr) {
    await page.click("#VRButton", { timeout: 60000 });
    await page.waitForFunction(() => window.gshaptics.xr && window.gshaptics.xr.active, null, { timeout: 60000 });
  }
  const count = () => page.evaluate(() => ({ t: performance.now(), n: window.gshaptics.perf.total }));
  const a = await count();
  await sleep(8000);
  const b = await count();
  const fps = (1000 * (b.n - a.n)) / (b.t - a.t);
  const perf = await page.evaluate(() => window.gshaptics.perf);
  console.log(JSON.stringify({ query, vr: enterVr, fps: Number(fps.toFixed(2)), splats: perf.splats, budget: perf.budget || 0 }));
} finally {
  await browser.close();
  server.kill("SIGINT");
}
