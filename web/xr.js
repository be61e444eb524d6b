// WebXR for the gshaptics viewer: stand inside the registered scene at true scale in a headset,
// with a VR controller as the haptic tool (`gshaptics serve --device xr`) and contact rendered as
// controller vibration. Imported by app.js; the desktop page is unchanged without an XR device.
//
// Frames: the world frame of the collision pipeline (metres for a registered scene) sits under
// `view.root`; in a session the root turns the scene's up axis onto the headset's up (+y of the
// 'local-floor' space) and places the tool's start point in front of the user. The controller's
// grip pose is taken back into the world frame and sent as {"type":"tool","center","rotation"}.

import * as THREE from "three";
import { VRButton } from "three/addons/webxr/VRButton.js";

/// Vibration from force. A controller's actuator renders no force, only vibration: this maps the
/// rendered |F| to a pulse intensity in [0, 1] - a stated approximation, not a force:
///   v = 0                               for |F| <= F_min (0.05 N: below it, no contact felt)
///   v = min(1, |F| / F_full) ^ 0.6      above, with F_full = f_max / 3 (10 N for the default 30 N)
/// The exponent 0.6 is compressive, after Stevens' power law for vibrotactile magnitude
/// (Stevens, "On the psychophysical law", Psychological Review 1957: exponent ~0.6 for 250 Hz
/// vibration on the finger), so that light contacts stay perceptible. Contact onset adds one
/// full-intensity pulse of 40 ms (a "click", after Kuchenbecker et al., "Improving contact
/// realism through event-based haptic feedback", IEEE TVCG 2006).
///
/// Texture and material (`serve --materials`): a state frame's "vibration" carries the texture
/// force's RMS over the last 20 ms and the material's vibration level (force/material.h). The
/// relief's own frequencies (v / lambda, 10-100 Hz and more) lie above the display rate the
/// actuator takes pulses at, and a controller's actuator plays one carrier, so texture reaches
/// the hand as its envelope: an intensity that rises with the relief and the speed of the slide,
///   v_texture = min(1, rms / textureFull) ^ 0.6     (textureFull 0.5 N: a strong relief)
/// added to the contact's v and the material's level (sum clipped to 1).
export const VIBRATION = { fMin: 0.05, fullFraction: 1 / 3, exponent: 0.6, onsetValue: 1.0, onsetMs: 40, textureFull: 0.5 };

export function vibrationFor(forceN, fMax) {
  if (!(forceN > VIBRATION.fMin)) return 0;
  const full = Math.max(VIBRATION.fMin * 2, fMax * VIBRATION.fullFraction);
  return Math.pow(Math.min(1, forceN / full), VIBRATION.exponent);
}

/// The pulse intensity of a state frame in contact: the force's (vibrationFor), the texture's
/// envelope and the material's level, summed and clipped to [0, 1]. `vibration`: the frame's
/// "vibration" object (absent without a material map).
export function contactVibration(forceN, fMax, vibration) {
  const v = vibrationFor(forceN, fMax);
  if (!(v > 0) || !vibration) return v;
  const rms = Number(vibration.texture_rms) || 0;
  const texture = rms > 0 ? Math.pow(Math.min(1, rms / VIBRATION.textureFull), VIBRATION.exponent) : 0;
  const level = Math.min(1, Math.max(0, Number(vibration.level) || 0));
  return Math.min(1, v + texture + level);
}

/// Quality presets for a standalone headset: the render's pixel scale (WebXR framebuffer scale
/// factor, and the desktop pixel ratio), Spark's splat sharpness cut (maxStdDev: smaller splats,
/// less fill) and the splat budget (Spark's level-of-detail tree, built when the scene loads,
/// drawing about `splats` splats per frame; 0: every splat, no LoD). Spark's own default budget
/// in WebXR is 500K-750K splats. `?quality=low|medium|high` in the page's URL, and
/// `?splat-budget=N` to set the budget alone (N splats; 0: all).
export const QUALITY = {
  high: { scale: 1.0, maxStdDev: Math.sqrt(8), splats: 0 },
  medium: { scale: 0.75, maxStdDev: 2.5, splats: 500000 },
  low: { scale: 0.5, maxStdDev: 2.0, splats: 150000 },
};

/// The quality preset of the URL, with its budget overridden by ?splat-budget=N.
export function qualityFromUrl() {
  const params = new URLSearchParams(location.search);
  const name = params.get("quality") in QUALITY ? params.get("quality") : "high";
  const preset = { name, ...QUALITY[name] };
  const budget = Number(params.get("splat-budget"));
  if (params.has("splat-budget") && Number.isFinite(budget) && budget >= 0) preset.splats = Math.round(budget);
  return preset;
}

/// `?xr-emulate=quest3`: installs IWER (the Immersive Web Emulation Runtime, npm `iwer`) so the
/// page can be tried and tested without a headset. Returns the emulated device (or null).
export async function maybeEmulateXR() {
  const which = new URLSearchParams(location.search).get("xr-emulate");
  if (!which) return null;
  const iwer = await import("iwer");
  const config = { quest3: iwer.metaQuest3, quest2: iwer.metaQuest2, questpro: iwer.metaQuestPro }[which] || iwer.metaQuest3;
  const device = new iwer.XRDevice(config);
  device.installRuntime({ forceInstall: true });
  return device;
}

const Y = new THREE.Vector3(0, 1, 0);

/// Adds the Enter VR button when the browser offers immersive-vr, and handles the session:
/// placement (grab-and-drag the world with the left grip, reset with the left trigger), the
/// right controller as the tool (when `steer`), vibration, frame rate.
export async function setupXR(view, ws, { steer }) {
  if (!navigator.xr || !(await navigator.xr.isSessionSupported("immersive-vr").catch(() => false))) return false;
  const { renderer, root, hello } = view;
  renderer.xr.enabled = true;
  renderer.xr.setReferenceSpaceType("local-floor");
  renderer.xr.setFramebufferScaleFactor(view.quality.scale);
  const button = VRButton.createButton(renderer);
  button.id = "VRButton";
  document.body.appendChild(button);
  const xr = view.xr = {
    active: false, steer, sent: 0, lastSend: 0, controller: false, pose: null,
    pulses: [], pulseCount: 0, vibrating: false, lastContacts: 0, actuator: null, home: null,
    drag: null,
  };
  const anchor = vec3(hello.tool_start || [0.5 * (hello.bounds.min[0] + hello.bounds.max[0]),
    0.5 * (hello.bounds.min[1] + hello.bounds.max[1]), 0.5 * (hello.bounds.min[2] + hello.bounds.max[2])]);

  const place = () => {
    // Up onto +y, then the tool's start point 1.2 m high and 0.45 m in front of the user.
    root.quaternion.setFromUnitVectors(view.up, Y);
    const want = new THREE.Vector3(0, 1.2, -0.45);
    root.position.copy(want.sub(anchor.clone().applyQuaternion(root.quaternion)));
    root.updateMatrixWorld(true);
  };
  renderer.xr.addEventListener("sessionstart", () => {
    xr.active = true;
    place();
    document.body.dataset.xr = "1";
  });
  renderer.xr.addEventListener("sessionend", () => {
    xr.active = false;
    stopVibration(xr, "session ended");
    root.position.set(0, 0, 0);
    root.quaternion.identity();
    root.updateMatrixWorld(true);
    document.body.dataset.xr = "0";
  });

  // Called from the animation loop with each XR frame.
  view.onXRFrame = (frame) => {
    const space = renderer.xr.getReferenceSpace();
    const session = frame.session;
    let tool = null, nav = null;
    for (const src of session.inputSources) {
      if (!src.gripSpace) continue;
      if (src.handedness === "left") nav = src;
      else if (!tool) tool = src;
    }
    xr.actuator = tool && tool.gamepad ? (tool.gamepad.hapticActuators || [])[0] || tool.gamepad.vibrationActuator || null : null;
    // Placement with the left controller: hold the grip to drag the world; trigger resets.
    if (nav) {
      const p = frame.getPose(nav.gripSpace, space);
      const squeeze = nav.gamepad && nav.gamepad.buttons[1] && nav.gamepad.buttons[1].pressed;
      const trigger = nav.gamepad && nav.gamepad.buttons[0] && nav.gamepad.buttons[0].pressed;
      if (p && squeeze) {
        const at = vec3([p.transform.position.x, p.transform.position.y, p.transform.position.z]);
        if (xr.drag) root.position.add(at.clone().sub(xr.drag));
        xr.drag = at;
        root.updateMatrixWorld(true);
      } else {
        xr.drag = null;
      }
      if (trigger) place();
    }
    const pose = tool ? frame.getPose(tool.gripSpace, space) : null;
    xr.controller = !!pose;
    if (!pose || !steer) return;
    const t = pose.transform;
    const pXR = new THREE.Vector3(t.position.x, t.position.y, t.position.z);
    const qXR = new THREE.Quaternion(t.orientation.x, t.orientation.y, t.orientation.z, t.orientation.w);
    const p = root.worldToLocal(pXR.clone());
    const q = root.quaternion.clone().invert().multiply(qXR);
    xr.pose = { xr: pXR.toArray(), world: p.toArray() };
    const now = performance.now();
    if (ws.readyState === WebSocket.OPEN && now - xr.lastSend >= 1000 / 90) {
      ws.send(JSON.stringify({ type: "tool", center: [p.x, p.y, p.z], rotation: [q.w, q.x, q.y, q.z] }));
      xr.lastSend = now;
      xr.sent++;
    }
  };

  // World <-> XR for tests and the console.
  view.worldToXR = (a) => root.localToWorld(vec3(a)).toArray();
  return true;
}

function vec3(a) { return new THREE.Vector3(a[0], a[1], a[2]); }

function pulse(xr, value, ms, kind) {
  xr.pulseCount++;
  xr.pulses.push({ t: performance.now(), value, ms, kind });
  if (xr.pulses.length > 400) xr.pulses.splice(0, xr.pulses.length - 400);
  if (xr.actuator && xr.actuator.pulse) xr.actuator.pulse(value, ms).catch(() => {});
}

function stopVibration(xr, why) {
  if (!xr.vibrating) return;
  xr.vibrating = false;
  pulse(xr, 0, 0, why || "stop");
}

/// Drives the controller's actuator from a state message (display rate): onset click, then the
/// force curve, held for 1.5 display periods so consecutive pulses join; a stop when the force ends.
export function vibrate(view, m, forceN) {
  const xr = view.xr;
  if (!xr || !xr.active || !xr.steer) return;
  const contacts = m.counts.contacts;
  if (!xr.controller) {
    stopVibration(xr, "no controller");
  } else {
    if (contacts > 0 && xr.lastContacts === 0 && forceN > VIBRATION.fMin) {
      pulse(xr, VIBRATION.onsetValue, VIBRATION.onsetMs, "onset");
      xr.vibrating = true;
    }
    const v = contactVibration(forceN, view.hello.f_max, m.vibration);
    if (v > 0) {
      pulse(xr, v, 1.5 * 1000 / view.hello.display_hz, m.vibration ? "material" : "force");
      xr.vibrating = true;
    } else {
      stopVibration(xr, "stop");
    }
  }
  xr.lastContacts = contacts;
}
