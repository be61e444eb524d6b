// What the browser end-to-end tests share: the command line, the wall-time budget, the
// CPU-burning neighbour, `gshaptics serve` as a child process, a bounded waitFor, headless
// Chromium (Debian's, through playwright-core) on a small viewport, the runtime's servo log, and
// the closing wall-time check. Each test keeps its own steps and assertions.

import { spawn } from "node:child_process";
import { existsSync, mkdirSync, readFileSync } from "node:fs";
import { join } from "node:path";
import { chromium } from "playwright-core";

export const CHROMIUM = "/usr/bin/chromium";
export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// Usage: node TEST.mjs PATH/TO/gshaptics OUT_DIR [--no-load]. Exits 2 on a bad command line and
// 77 (skipped) without Chromium. By default a CPU-burning process runs beside the test.
export function setup(testName, budgetMs = 120000) {
  const [exe, outDir, flag] = process.argv.slice(2);
  const t0 = Date.now();
  if (!exe || !outDir) {
    console.error(`usage: ${testName} PATH/TO/gshaptics OUT_DIR [--no-load]`);
    process.exit(2);
  }
  if (!existsSync(CHROMIUM)) {
    console.log(`SKIP: ${CHROMIUM} not installed (scripts/setup.sh installs Debian's chromium)`);
    process.exit(77);
  }
  mkdirSync(outDir, { recursive: true });
  const burner = flag === "--no-load" ? null
    : spawn(process.execPath, ["-e", "const e = Date.now() + 600000; while (Date.now() < e) {}"], { stdio: "ignore" });
  return {
    exe, outDir, burner, t0, budgetMs,
    // Time left in the budget (at least 1 s, so a late step still gets a bounded wait).
    left: () => Math.max(1000, budgetMs - (Date.now() - t0)),
  };
}

export function fail(msg) {
  console.error(`FAIL: ${msg}`);
  process.exitCode = 1;
}

// Polls `pred` until it returns something truthy, for at most `ms`; throws naming `what`.
export async function waitFor(pred, ms, what, everyMs = 100) {
  const start = Date.now();
  while (Date.now() - start < ms) {
    const v = await pred();
    if (v) return v;
    await sleep(everyMs);
  }
  throw new Error(`timed out after ${ms} ms waiting for ${what}`);
}

// `gshaptics serve ARGS`, its output collected; url() waits for the viewer's address.
export function startServe(exe, args) {
  const server = spawn(exe, ["serve", ...args], { stdio: ["ignore", "pipe", "pipe"] });
  const out = { stdout: "", stderr: "" };
  server.stdout.on("data", (d) => { out.stdout += d; });
  server.stderr.on("data", (d) => { out.stderr += d; });
  const exited = new Promise((resolve) => server.on("exit", (code, sig) => resolve({ code, sig })));
  const url = (ms) => waitFor(() => (out.stdout.match(/viewer\s+(http:\/\/\S+)/) || [])[1], ms, "the server URL");
  return { server, out, exited, url };
}

// Headless Chromium with software GL and one page of the given size; page errors are printed.
export async function openPage(viewport) {
  const browser = await chromium.launch({
    executablePath: CHROMIUM,
    args: ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
      "--disable-background-networking", "--disable-component-update", "--disable-sync",
      "--use-angle=swiftshader", "--enable-unsafe-swiftshader"],
  });
  const page = await browser.newPage({ viewport });
  page.on("console", (m) => { if (m.type() === "error") console.log(`page error: ${m.text()}`); });
  page.on("pageerror", (e) => console.log(`page exception: ${e.message}`));
  return { browser, page };
}

// The runtime's servo_log.csv: ticks, ticks with contacts, the largest and the last |F|.
// null (after a FAIL) when the file is missing.
export function readServoLog(outDir) {
  const logPath = join(outDir, "servo_log.csv");
  if (!existsSync(logPath)) {
    fail(`no ${logPath}`);
    return null;
  }
  const [header, ...rows] = readFileSync(logPath, "utf8").trim().split("\n");
  const col = Object.fromEntries(header.split(",").map((n, i) => [n, i]));
  const force = (v) => Math.hypot(v[col.fx], v[col.fy], v[col.fz]);
  let withContact = 0, maxF = 0;
  for (const row of rows) {
    const v = row.split(",").map(Number);
    if (v[col.contacts] > 0) withContact++;
    maxF = Math.max(maxF, force(v));
  }
  return { ticks: rows.length, withContact, maxF, lastF: force(rows[rows.length - 1].split(",").map(Number)) };
}

// The checks every test ends with: serve exited cleanly, its log has contact ticks and a force
// and ends at zero force; then the wall time against the budget and the verdict line.
export function checkServeAndLog(ctx, exitCode, out) {
  if (exitCode !== 0) fail(`gshaptics serve exited with ${exitCode}: ${out.stderr.slice(-500)}`);
  const log = readServoLog(ctx.outDir);
  if (log) {
    if (!(log.withContact > 0)) fail("the runtime's log has no tick with contacts");
    if (!(log.maxF > 0)) fail("the runtime's log never sent a force");
    if (log.lastF !== 0) fail("the device was not left at zero force");
  }
  return log;
}

// The end every test shares: the browser closed, serve stopped (SIGINT: it writes its outputs),
// the CPU-burning neighbour killed.
export async function closeAll(ctx, browser, server) {
  if (browser) await browser.close();
  server.kill("SIGINT");
  if (ctx.burner) ctx.burner.kill("SIGKILL");
}

// serve's exit and its log, checked (checkServeAndLog) and summarised; null after a FAIL.
export async function serveLog(ctx, serve) {
  const { code } = await serve.exited;
  const log = checkServeAndLog(ctx, code, serve.out);
  if (log) console.log(`runtime log: ${log.ticks} ticks, ${log.withContact} with contacts, max |F| ${log.maxF.toFixed(3)} N`);
  return log;
}

export function finish(ctx, verdict) {
  const wall = (Date.now() - ctx.t0) / 1000;
  console.log(`wall time ${wall.toFixed(1)} s${ctx.burner ? " with a CPU-burning process beside it" : ""} (budget ${ctx.budgetMs / 1000} s)`);
  if (wall * 1000 > ctx.budgetMs) fail(`took ${wall.toFixed(1)} s, over the ${ctx.budgetMs / 1000} s budget`);
  console.log(process.exitCode ? `${verdict}: FAILED` : `${verdict}: OK`);
  return wall;
}
