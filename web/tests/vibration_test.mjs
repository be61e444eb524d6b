// Unit test of the VR controller's vibration curve (web/xr.js): contact, texture envelope and
// material level. Runs under node (no browser): node web/tests/vibration_test.mjs
let xr;
try {
  xr = await import("../xr.js");
} catch (e) {
  console.log(`skipped: web/xr.js does not load (${e.code || e.message}; scripts/setup.sh runs npm ci)`);
  process.exit(77);
}
const { VIBRATION, vibrationFor, contactVibration } = xr;

let failed = 0;
function check(ok, what) {
  if (!ok) {
    failed++;
    console.error(`FAIL: ${what}`);
  } else {
    console.log(`ok: ${what}`);
  }
}
const near = (a, b, tol = 1e-12) => Math.abs(a - b) <= tol;

const fMax = 30;
// Without a material map the curve is the force's alone.
check(contactVibration(2, fMax, undefined) === vibrationFor(2, fMax), "no map: the force's curve");
check(near(vibrationFor(10, fMax), 1), "10 N of a 30 N device: full intensity");
check(near(vibrationFor(1, fMax), Math.pow(0.1, 0.6)), "1 N: (1/10)^0.6");
// No contact force: nothing, whatever the texture says (the tool is off the surface).
check(contactVibration(0, fMax, { texture_rms: 0.4, level: 0.5 }) === 0, "no force: no vibration");
// The texture's envelope rises with its RMS and adds to the contact's.
const base = vibrationFor(1, fMax);
const weak = contactVibration(1, fMax, { texture_rms: 0.02, level: 0 });
const strong = contactVibration(1, fMax, { texture_rms: 0.1, level: 0 });
check(weak > base && strong > weak, `texture adds, rising with its RMS (${base.toFixed(3)} < ${weak.toFixed(3)} < ${strong.toFixed(3)})`);
check(near(strong - base, Math.pow(0.1 / VIBRATION.textureFull, VIBRATION.exponent), 1e-12), "texture term (rms / 0.5 N)^0.6");
// The material's level adds; the sum is clipped to 1; a level outside [0, 1] is clipped.
check(near(contactVibration(1, fMax, { texture_rms: 0, level: 0.25 }) - base, 0.25), "level adds");
check(contactVibration(5, fMax, { texture_rms: 0.5, level: 1 }) === 1, "sum clipped to 1");
check(near(contactVibration(1, fMax, { texture_rms: 0, level: 7 }), Math.min(1, base + 1)), "level clipped to 1");
check(contactVibration(1, fMax, { texture_rms: "x", level: null }) === base, "malformed fields read as 0");
if (failed > 0) {
  console.error(`${failed} failed`);
  process.exit(1);
}
