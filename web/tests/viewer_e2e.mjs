// End-to-end test of the viewer in a real browser (Debian's Chromium through playwright-core):
// start `gshaptics serve` on the bundled Truck with the mouse device, load the page, lower the
// tool into the truck with the page's own key handling, and check that the page shows contacts
// and a force, that the runtime's own log agrees, and save a screenshot.
//
// Usage: node web/tests/viewer_e2e.mjs PATH/TO/gshaptics OUT_DIR
// Software GL renders about one frame per second here: timeouts are generous, and the test uses
// a single browser (two Chromium instances at once can die on a 2-core machine).

import { spawn } from "node:child_process";
import { existsSync, mkdirSync, readFileSync } from "node:fs";
import { join } from "node:path";
import { chromium } from "playwright-core";

const [exe, outDir] = process.argv.slice(2);
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

function fail(msg) {
  console.error(`FAIL: ${msg}`);
  process.exitCode = 1;
}

const server = spawn(exe, ["serve", "--port", "0", "--quiet", "--no-plot", "--out", outDir],
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
  const url = await waitFor(() => (stdout.match(/viewer\s+(http:\/\/\S+)/) || [])[1], 120000, "the server URL");
  console.log(`server at ${url}`);
  browser = await chromium.launch({
    executablePath: CHROMIUM,
    args: ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
      "--disable-background-networking", "--disable-component-update", "--disable-sync",
      "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
  });
  const page = await browser.newPage({ viewport: { width: 1100, height: 720 } });
  page.on("console", (m) => { if (m.type() === "error") console.log(`page error: ${m.text()}`); });
  page.on("pageerror", (e) => console.log(`page exception: ${e.message}`));
  await page.goto(url, { timeout: 120000 });
  await page.waitForFunction(() => document.getElementById("status").textContent === "connected", null, { timeout: 120000 });
  await page.waitForFunction(() => window.gshaptics && window.gshaptics.last !== null, null, { timeout: 120000 });
  const start = await page.evaluate(() => window.gshaptics.last.tool.center);
  console.log(`tool starts at ${start.map((x) => x.toFixed(3))}`);

  // Lower the tool along the scene's up axis with the page's own keys (E: half a tool radius),
  // until the page shows a contact.
  let contacts = 0;
  for (let i = 0; i < 120 && contacts === 0; i++) {
    await page.keyboard.press("E");
    await page.waitForTimeout(500);
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
  await page.screenshot({ path: join(outDir, "viewer.png"), timeout: 120000 });
  console.log(`screenshot ${join(outDir, "viewer.png")}`);
} catch (e) {
  fail(e.message);
} finally {
  if (browser) await browser.close();
  server.kill("SIGINT");
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
console.log(process.exitCode ? "viewer e2e: FAILED" : "viewer e2e: OK");
