// Soak test (not in CI): `gshaptics serve` at 1 kHz on the bundled Truck with a browser page
// connected and steering, a second WebSocket client reconnecting every 3 s, and a ROS 2 pair
// (`node --ros2` + `device-sim --ros2`) running beside it, for --minutes (default 30).
// Samples the resident memory of serve and node every 10 s and reports start (after a 60 s
// warm-up) and end, deadline misses, dropped frames and safety events from their summaries.
//
// Usage: node tools/soak.mjs PATH/TO/gshaptics OUT_DIR [--minutes 30]
// Writes OUT_DIR/soak.md (the table for bench/RESULTS.md) and OUT_DIR/rss.csv.

import { spawn } from "node:child_process";
import net from "node:net";
import { existsSync, mkdirSync, readFileSync, writeFileSync } from "node:fs";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath } from "node:url";

const here = dirname(fileURLToPath(import.meta.url));
const { chromium } = await import(join(here, "..", "web", "node_modules", "playwright-core", "index.mjs"));

const args = process.argv.slice(2);
const [exe, outDir] = args;
const minutes = args.includes("--minutes") ? Number(args[args.indexOf("--minutes") + 1]) : 30;
if (!exe || !outDir || !(minutes > 0)) {
  console.error("usage: node tools/soak.mjs PATH/TO/gshaptics OUT_DIR [--minutes 30]");
  process.exit(2);
}
mkdirSync(outDir, { recursive: true });
const seconds = Math.round(minutes * 60);
const env = { ...process.env, CYCLONEDDS_URI: `file://${resolve(here, "..", "config", "cyclonedds-loopback.xml")}` };

function start(name, argv) {
  const p = spawn(exe, argv, { stdio: ["ignore", "pipe", "pipe"], env });
  p.out = "";
  p.err = "";
  p.stdout.on("data", (d) => { p.out += d; });
  p.stderr.on("data", (d) => { p.err += d; });
  p.done = new Promise((res) => p.on("exit", (code) => res(code)));
  p.label = name;
  return p;
}

function rssKiB(pid) {
  try {
    const m = readFileSync(`/proc/${pid}/status`, "utf8").match(/VmRSS:\s+(\d+) kB/);
    return m ? Number(m[1]) : NaN;
  } catch {
    return NaN;
  }
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
// The per-tick logs are capped at 30 s: their memory is reserved up front and touched as they
// fill, so RSS grows by design while they do (about 0.2 kB per tick); after the 60 s warm-up any
// growth is something else.
const serve = start("serve", ["serve", "--port", "0", "--quiet", "--no-plot", "--duration", String(seconds + 600),
  "--log-seconds", "30", "--out", join(outDir, "serve")]);
const node = start("node", ["node", "--ros2", "--quiet", "--no-plot", "--duration", String(seconds + 600),
  "--log-seconds", "30", "--domain", "42", "--out", join(outDir, "node")]);
await sleep(3000);
const device = start("device-sim", ["device-sim", "--ros2", "--quiet", "--duration", String(seconds + 600),
  "--domain", "42", "--wait", "60", "--out", join(outDir, "device")]);

const t0 = Date.now();
while (!/viewer\s+http/.test(serve.out)) {
  if (Date.now() - t0 > 120000) throw new Error(`serve did not start: ${serve.err}`);
  await sleep(200);
}
const url = serve.out.match(/viewer\s+(http:\/\/\S+)/)[1];
console.log(`soak: ${minutes} min; serve at ${url}, ROS 2 node + device-sim on domain 42`);
const browser = await chromium.launch({
  executablePath: "/usr/bin/chromium",
  args: ["--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
});
const page = await browser.newPage({ viewport: { width: 240, height: 160 } });
await page.goto(url, { timeout: 120000 });
await page.waitForFunction(() => window.gshaptics && window.gshaptics.last !== null, null, { timeout: 120000 });
// A second client (outside the browser, whose timers a software-rendered page starves): a raw
// WebSocket handshake, 2.5 s of state frames, then the connection dropped, every 3 s.
const port = Number(new URL(url).port);
let reconnects = 0, refusedHandshakes = 0;
const reconnecter = setInterval(() => {
  const s = net.connect(port, "127.0.0.1", () => {
    s.write(`GET /ws HTTP/1.1\r\nHost: 127.0.0.1:${port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n` +
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n");
  });
  let head = "";
  s.on("data", (d) => { if (head.length < 64) head += d.toString("latin1"); });
  s.on("error", () => {});
  setTimeout(() => {
    if (head.startsWith("HTTP/1.1 101")) reconnects++;
    else refusedHandshakes++;
    s.destroy();
  }, 2500);
}, 3000);

const samples = [];
const startAt = Date.now();
let next = 0;
while (Date.now() - startAt < seconds * 1000) {
  const t = (Date.now() - startAt) / 1000;
  if (t >= next) {
    samples.push({ t, serve: rssKiB(serve.pid), node: rssKiB(node.pid) });
    next += 10;
  }
  // Steer: down into the truck and back up, so contacts come and go.
  for (const k of ["e", "e", "e", "q", "q", "q"]) {
    await page.keyboard.press(k);
    await sleep(400);
  }
}
clearInterval(reconnecter);
samples.push({ t: (Date.now() - startAt) / 1000, serve: rssKiB(serve.pid), node: rssKiB(node.pid) });
await browser.close();
for (const p of [serve, node, device]) p.kill("SIGINT");
const codes = await Promise.all([serve.done, node.done, device.done]);

writeFileSync(join(outDir, "rss.csv"), "t_s,serve_rss_kib,node_rss_kib\n" +
  samples.map((s) => `${s.t.toFixed(1)},${s.serve},${s.node}`).join("\n") + "\n");
const warm = samples.find((s) => s.t >= 60) || samples[0];
const end = samples[samples.length - 1];
const pct = (a, b) => (100 * (b - a) / a).toFixed(2);
const summary = (name) => {
  const f = join(outDir, name, "run_summary.json");
  return existsSync(f) ? JSON.parse(readFileSync(f, "utf8")) : null;
};
const sv = summary("serve"), nd = summary("node");
const row = (label, s, rss0, rss1) => {
  if (!s) return `| ${label} | (no summary) |`;
  const r = s.runtime;
  const safety = r.watchdog_ticks + r.invalid_pose_ticks + r.outside_workspace_ticks + r.fades;
  return `| ${label} | ${(r.duration_s / 60).toFixed(1)} min | ${r.ticks} | ${r.achieved_rate_hz.toFixed(1)} Hz | ` +
    `${r.deadline_misses} | ${r.jitter_us.p99.toFixed(1)} us | ${(rss0 / 1024).toFixed(1)} -> ${(rss1 / 1024).toFixed(1)} MiB ` +
    `(${pct(rss0, rss1)} %) | fades ${r.fades}, watchdog ${r.watchdog_ticks}, invalid ${r.invalid_pose_ticks}, ` +
    `outside ${r.outside_workspace_ticks} (${safety} events+ticks) |`;
};
const viewer = sv && sv.viewer ? sv.viewer : {};
const md = [
  `Soak, ${minutes} min (tools/soak.mjs), exit codes serve/node/device-sim ${codes.join("/")}:`,
  "",
  "| process | length | ticks | rate | deadline misses | jitter p99 | RSS after 60 s -> end | safety |",
  "|---|---|---|---|---|---|---|---|",
  row("serve (Truck, page + reconnecting client)", sv, warm.serve, end.serve),
  row("node --ros2 (with device-sim)", nd, warm.node, end.node),
  "",
  `Viewer: ${viewer.frames_sent ?? "?"} frames sent, ${viewer.frames_dropped ?? "?"} dropped for slow clients, ` +
  `${reconnects} reconnections by the second client (${refusedHandshakes} failed), ${viewer.tool_messages ?? "?"} tool messages; refused ` +
  `host/origin/token/connections ${viewer.refused_host}/${viewer.refused_origin}/${viewer.refused_token}/` +
  `${viewer.refused_connections}, rate-limited ${viewer.rate_limited}, idle closed ${viewer.idle_closed}.`,
  "",
].join("\n");
writeFileSync(join(outDir, "soak.md"), md);
console.log(md);
const flat = Math.abs(end.serve - warm.serve) / warm.serve <= 0.02 && Math.abs(end.node - warm.node) / warm.node <= 0.02;
console.log(flat ? "memory flat within 2 %" : "MEMORY NOT FLAT within 2 %");
process.exit(flat && codes.every((c) => c === 0) ? 0 : 1);
