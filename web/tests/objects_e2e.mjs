// End-to-end test of a rigid object in the viewer (issue 72), in a real browser (Debian's
// Chromium through playwright-core): write a box of Gaussians on a floor of Gaussians
// (`gshaptics synth box-on-floor`), start `gshaptics serve` with the box cut as an object
// (--object, MuJoCo), let the page's mouse device carry the tool beside the box and push it
// along +x, and check that the page's splat mesh of the box moves with the box's pose, that the
// pose the server streams moved the same way, and that the static floor's mesh stayed put.
//
// Usage: node web/tests/objects_e2e.mjs PATH/TO/gshaptics OUT_DIR [--no-load]
// Every wait is bounded by wall time; the whole test must finish within its budget.

import { spawnSync } from "node:child_process";
import { join } from "node:path";
import { closeAll, fail, finish, serveLog, openPage, setup, sleep, startServe, waitFor } from "./harness.mjs";

const ctx = setup("objects_e2e.mjs");
const { exe, outDir, t0, left } = ctx;

// The scene: a 10 x 8 x 6 cm box standing at the origin on a floor (z up), Gaussians every 1 cm.
const scene = join(outDir, "box_on_floor.ply");
const synth = spawnSync(exe, ["synth", "box-on-floor", scene, "--spacing", "0.01"], { encoding: "utf8" });
const spec = (synth.stdout.match(/--object (\S+)/) || [])[1];
if (synth.status !== 0 || !spec) {
  console.error(`FAIL: gshaptics synth box-on-floor: ${synth.stderr}${synth.stdout}`);
  process.exit(1);
}

// A light box (0.2 kg, mu 0.3: it slides under 0.6 N) and a 1 cm sphere as the tool.
const serve = startServe(exe, [scene, "--up", "z-up", "--object", `${spec}:mass=0.2:friction=0.3`,
  "--tool-radius", "0.01", "--port", "0", "--quiet", "--no-plot", "--out", outDir]);
const { server } = serve;

// Moves the page's mouse-device target to `to` in steps of at most `step` m every 50 ms (the
// page sends its target to the server 30 times a second).
async function glide(page, to, step = 0.004) {
  for (;;) {
    const done = await page.evaluate(([x, y, z, s]) => {
      const t = window.gshaptics.target;
      const d = [x - t.x, y - t.y, z - t.z], n = Math.hypot(...d);
      if (n <= s) { t.set(x, y, z); return true; }
      t.set(t.x + (s * d[0]) / n, t.y + (s * d[1]) / n, t.z + (s * d[2]) / n);
      return false;
    }, [...to, step]);
    if (done) return;
    await sleep(50);
  }
}

let browser;
try {
  const url = await serve.url(left());
  console.log(`server at ${url}`);
  const opened = await openPage({ width: 400, height: 300 });
  browser = opened.browser;
  const page = opened.page;
  await page.goto(url, { timeout: left() });
  await page.waitForFunction(() => window.gshaptics && window.gshaptics.last !== null && window.gshaptics.target, null, { timeout: left() });
  await page.waitForFunction(() => document.body.dataset.sceneLoaded === "1" || document.body.dataset.error, null, { timeout: left() });
  const loaded = await page.evaluate(() => ({
    error: document.body.dataset.error || "", objects: window.gshaptics.objects.length,
    splats: window.gshaptics.objects.map((g) => g.userData.mesh.numSplats || 0),
    hello: window.gshaptics.hello.objects,
  }));
  if (loaded.error) throw new Error(`the page shows an error: ${loaded.error}`);
  if (loaded.objects !== 1) throw new Error(`the page draws ${loaded.objects} object meshes, not 1`);
  console.log(`scene and object loaded after ${((Date.now() - t0) / 1000).toFixed(1)} s; object ${JSON.stringify(loaded.hello[0])}, ${loaded.splats[0]} splats`);
  const rest = await page.evaluate(() => window.gshaptics.objects[0].position.toArray());
  const floorAt = await page.evaluate(() => window.gshaptics.splat.position.toArray());
  if (Math.abs(rest[0]) > 0.005 || Math.abs(rest[1]) > 0.005 || Math.abs(rest[2] - 0.03) > 0.005)
    fail(`the box's mesh is not at its rest origin (0, 0, 0.03) m: ${rest.map((x) => x.toFixed(4))}`);

  // Around the box to its -x side at mid-height, then push it along +x by about 5 cm.
  const start = await page.evaluate(() => window.gshaptics.target.toArray());
  await glide(page, [-0.12, 0, start[2]], 0.01);
  await glide(page, [-0.12, 0, 0.03], 0.01);
  await glide(page, [0.02, 0, 0.03]);
  const moved = await waitFor(async () => {
    const x = await page.evaluate(() => window.gshaptics.objects[0].position.x);
    return x - rest[0] > 0.02 ? x : null;
  }, Math.min(30000, left() - 15000), "the box's mesh to move 2 cm along +x");
  const state = await page.evaluate(() => ({
    pose: window.gshaptics.last.objects[0], mesh: window.gshaptics.objects[0].position.toArray(),
    floor: window.gshaptics.splat.position.toArray(), tool: window.gshaptics.last.tool.center,
  }));
  console.log(`box mesh at ${state.mesh.map((x) => x.toFixed(4))} (moved ${(1000 * (moved - rest[0])).toFixed(1)} mm), ` +
    `streamed pose ${state.pose.map((x) => x.toFixed(4))}, tool at ${state.tool.map((x) => x.toFixed(4))}`);
  // What the page draws is what the server streams: the mesh sits at the streamed pose.
  if (!state.pose || Math.hypot(state.pose[0] - state.mesh[0], state.pose[1] - state.mesh[1], state.pose[2] - state.mesh[2]) > 1e-6)
    fail("the box's mesh is not at the pose in the last state frame");
  // Pushed along +x, it slid rather than jumped: still on the floor, close to the push line.
  if (Math.abs(state.mesh[2] - rest[2]) > 0.005) fail(`the box left the floor: z ${state.mesh[2].toFixed(4)} m`);
  if (Math.abs(state.mesh[1]) > 0.02) fail(`the box went sideways: y ${state.mesh[1].toFixed(4)} m`);
  // The tool never went into the box: its centre stays a tool radius off the box's -x face.
  if (!(state.tool[0] < state.mesh[0] - 0.05)) fail(`the tool centre ${state.tool[0].toFixed(4)} m is inside the box (face at ${(state.mesh[0] - 0.05).toFixed(4)} m)`);
  if (state.floor.some((x, k) => Math.abs(x - floorAt[k]) > 1e-9)) fail("the static floor's mesh moved");
  await page.screenshot({ path: join(outDir, "objects.png"), timeout: left() });
  console.log(`screenshot ${join(outDir, "objects.png")}`);
} catch (e) {
  fail(e.message);
} finally {
  await closeAll(ctx, browser, server);
}

await serveLog(ctx, serve);
finish(ctx, "objects e2e");
