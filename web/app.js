// gshaptics viewer: the original 3DGS scene (Spark on three.js) in the collision pipeline's world
// frame, its rigid objects (--object) at their live poses, the tool ellipsoid at its live pose, the colliding Gaussians, the force arrow and live
// counters, fed by `gshaptics serve` over a WebSocket (protocol: docs/viewer_protocol.md).
// With the mouse device, the page steers the tool: drag the tool, or use the keys in #help.

import * as THREE from "three";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";
import { SparkRenderer, SplatMesh } from "@sparkjsdev/spark";
import { maybeEmulateXR, qualityFromUrl, setupXR, vibrate } from "./xr.js";

const $ = (id) => document.getElementById(id);
const MAX_SHOWN = 2048;
const PLOT_SAMPLES = 300;

const view = {
  hello: null, scene: null, camera: null, renderer: null, controls: null, splat: null,
  tool: null, contacts: null, arrow: null, target: null, showFelt: true, up: null, upChoices: [], upIndex: 0,
  history: [], last: null, dragging: false, dragPlane: new THREE.Plane(), dragOffset: new THREE.Vector3(),
};
window.gshaptics = view; // for tests and the console
view.quality = qualityFromUrl();
view.perf = { fps: 0, frames: 0, since: performance.now(), splats: 0 };
// ?xr-emulate=quest3: an emulated headset (IWER) before anything asks for navigator.xr.
const xrEmulation = maybeEmulateXR().then((d) => { window.gshapticsXR = d; return d; })
  .catch((e) => { showError(`XR emulation failed: ${e.message}`); return null; });

// Errors show in the page, not only in the console: a scene the renderer cannot read, a server
// that stopped, a script error.
function showError(text) {
  const el = $("error");
  el.hidden = false;
  el.textContent = text;
  document.body.dataset.error = text;
}
addEventListener("error", (e) => showError(`page error: ${e.message}`));
addEventListener("unhandledrejection", (e) => showError(`page error: ${e.reason && e.reason.message ? e.reason.message : e.reason}`));

function setLoading(text, fraction) {
  const el = $("loading");
  if (text === null) { el.hidden = true; return; }
  el.hidden = false;
  $("loading-text").textContent = text;
  if (fraction !== undefined) $("loading-bar").style.width = `${Math.round(100 * Math.min(1, fraction))}%`;
}

const ws = new WebSocket(`ws://${location.host}/ws`);
ws.onopen = () => { $("status").textContent = "connected"; setLoading("waiting for the scene description…"); };
ws.onclose = () => {
  $("status").textContent = "disconnected";
  $("status").style.color = "#e77";
  showError("The connection to gshaptics closed: the server stopped (Ctrl-C, end of --duration) or " +
    "the network dropped. Restart `gshaptics serve` and reload.");
};
ws.onmessage = (ev) => {
  const m = JSON.parse(ev.data);
  if (m.type === "hello") xrEmulation.then(() => init(m));
  else if (m.type === "state" && view.hello) update(m);
};

function vec(a) { return new THREE.Vector3(a[0], a[1], a[2]); }

function init(h) {
  view.hello = h;
  if (h.renderer === "proxy") {
    $("prefiltered-label").textContent = "proxy gap / constraints";
    $("contacts-label").textContent = "Gaussians holding the proxy";
  }
  $("scene-name").textContent = `${h.scene_name}: ${h.gaussians_kept.toLocaleString()} of ` +
    `${h.gaussians_in_file.toLocaleString()} Gaussians collide (opacity filter); device: ${h.device}`;
  const lo = vec(h.bounds.min), hi = vec(h.bounds.max);
  const extent = hi.clone().sub(lo).length();
  view.up = vec(h.up).normalize();
  view.upChoices = [view.up.clone(), new THREE.Vector3(0, 0, 1), new THREE.Vector3(0, 1, 0), new THREE.Vector3(0, -1, 0)];

  const scene = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera(55, innerWidth / innerHeight, extent * 1e-3, extent * 50);
  camera.up.copy(view.up);
  const side = new THREE.Vector3(1, 0.7, 0).applyQuaternion(new THREE.Quaternion().setFromUnitVectors(new THREE.Vector3(0, 0, 1), view.up));
  // Frame the whole scene first (its 1-99 % box fits the view, seen from the side and above);
  // then the view follows the tool (F toggles), keeping this distance until the user zooms.
  const center = lo.clone().add(hi).multiplyScalar(0.5);
  const dist = 0.5 * extent / Math.tan(THREE.MathUtils.degToRad(55 / 2)) * 0.9;
  camera.position.copy(center).addScaledVector(side.normalize(), dist).addScaledVector(view.up, 0.45 * dist);
  view.follow = true;
  const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(Math.min(devicePixelRatio, 2) * view.quality.scale);
  renderer.setSize(innerWidth, innerHeight);
  $("view").appendChild(renderer.domElement);
  const quality = view.quality;
  scene.add(new SparkRenderer({ renderer, maxStdDev: quality.maxStdDev,
    ...(quality.splats > 0 ? { lodSplatCount: quality.splats } : {}) }));
  // Everything in the world frame hangs under one root: identity on the desktop; in VR it turns
  // the scene's up onto the headset's up and places the scene around the user (xr.js).
  const root = new THREE.Group();
  scene.add(root);
  const controls = new OrbitControls(camera, renderer.domElement);
  controls.target.copy(center);
  controls.update();

  // The scene file as stored, placed by the registration: x_world = s R x_file + t (paper eq. 3).
  setLoading(`loading ${h.scene_name}…`, 0);
  const splat = new SplatMesh({
    url: h.scene_url, fileType: h.file_type, ...(quality.splats > 0 ? { lod: true } : {}),
    onProgress: (e) => {
      if (e && e.total > 0) setLoading(`loading ${h.scene_name}: ${(e.loaded / 1e6).toFixed(1)} of ${(e.total / 1e6).toFixed(1)} MB`, e.loaded / e.total);
    },
  });
  // Rigid objects (--object): each one its own splat mesh (world frame at rest), under a group
  // placed at the object's live pose: x_world = R (x_rest - rest_origin) + p.
  const objects = (h.objects || []).map((o, i) => {
    const group = new THREE.Group();
    group.name = `object-${i}`;
    group.position.set(...o.rest_origin);
    const mesh = new SplatMesh({ url: o.url, fileType: o.file_type });
    mesh.position.set(-o.rest_origin[0], -o.rest_origin[1], -o.rest_origin[2]);
    group.add(mesh);
    group.userData.mesh = mesh;
    return group;
  });
  Promise.all([splat.initialized, ...objects.map((g) => g.userData.mesh.initialized)]).then(() => {
    view.perf.splats = splat.numSplats || (splat.packedSplats && splat.packedSplats.numSplats) || h.gaussians_in_file;
    view.perf.budget = quality.splats;
    setLoading(null);
    view.splatFrames = 0;  // "scene loaded" once frames with the splats have been drawn (below)
  }).catch((err) => {
    setLoading(null);
    showError(`The scene ${h.scene_name} could not be shown: ${err && err.message ? err.message : err}. ` +
      "The haptic loop still runs; the contacts and the force are drawn without the splats.");
  });
  const reg = h.registration;
  splat.scale.setScalar(reg.scale);
  splat.quaternion.set(reg.rotation[1], reg.rotation[2], reg.rotation[3], reg.rotation[0]);
  splat.position.set(...reg.translation);
  root.add(splat);
  for (const g of objects) root.add(g);

  const tool = toolShape(h.tool, 0x66ccff, 0.45, 1000); // overlays: drawn after the splats, visible inside the surface
  root.add(tool);
  // The proxy (god-object): a ghost of the tool where the force model holds it, on the surface.
  const proxy = toolShape(h.tool, 0x99ff99, 0.35, 999);
  proxy.visible = false;
  root.add(proxy);
  // What the hand feels, beside what the eye sees: the surface the force model holds the tool on,
  // a disc at the proxy's contact point facing the force (drawn over the splats; V hides it).
  const felt = new THREE.Mesh(new THREE.RingGeometry(0.55, 1, 40),
    new THREE.MeshBasicMaterial({ color: 0xffee55, transparent: true, opacity: 0.55, side: THREE.DoubleSide, depthTest: false }));
  felt.add(new THREE.Mesh(new THREE.CircleGeometry(0.55, 40),
    new THREE.MeshBasicMaterial({ color: 0xffee55, transparent: true, opacity: 0.18, side: THREE.DoubleSide, depthTest: false })));
  felt.traverse((o) => { o.renderOrder = 999; });
  felt.visible = false;
  root.add(felt);
  // The torque about the tool centre point: a curved arrow turning about its axis (right hand).
  const twist = torqueArrow();
  root.add(twist);
  const contacts = new THREE.InstancedMesh(new THREE.SphereGeometry(1, 10, 6),
    new THREE.MeshBasicMaterial({ color: 0xff2244, transparent: true, opacity: 0.85, depthTest: false }), MAX_SHOWN);
  contacts.count = 0;
  contacts.renderOrder = 1001;
  contacts.frustumCulled = false; // its bounding sphere would be cached from the first (empty) frame
  root.add(contacts);
  const arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 0, 0xffaa00);
  arrow.visible = false;
  arrow.traverse((o) => {
    o.renderOrder = 1002;
    if (o.material) Object.assign(o.material, { depthTest: false, transparent: true });
  });
  root.add(arrow);
  // A desktop device's workspace, mapped into the scene (its placement at start; the clutch and
  // bubble navigation move it during the run).
  if (h.workspace_box) {
    const box = new THREE.Box3(vec(h.workspace_box.min), vec(h.workspace_box.max));
    const helper = new THREE.Box3Helper(box, 0x88aaff);
    helper.renderOrder = 998;
    helper.material.depthTest = false;
    helper.material.transparent = true;
    helper.name = "workspace";
    root.add(helper);
  }

  Object.assign(view, { scene, camera, renderer, controls, splat, objects, tool, proxy, felt, contacts, arrow, twist, extent, root });
  addEventListener("resize", () => {
    camera.aspect = innerWidth / innerHeight;
    camera.updateProjectionMatrix();
    renderer.setSize(innerWidth, innerHeight);
  });
  if (h.mouse) setupMouseDevice(h);
  $("help").innerHTML = h.mouse
    ? "Drag the blue tool; arrows: view plane, W/S: depth, Q/E: up/down (Shift 5x), U: camera up axis, F: follow on/off, V: felt surface on/off; drag elsewhere orbits."
    : "The device drives the tool. U: camera up axis; F: follow the tool on/off; V: the felt surface on/off; drag orbits.";
  const regions = materialRegions(h.material_regions || []);
  root.add(regions);
  if (h.material_regions) {
    $("material-row").hidden = false;
    $("help").innerHTML += " M: the material regions on/off.";
  }
  addEventListener("keydown", (e) => {
    if (e.key.toLowerCase() === "f") view.follow = !view.follow;
    if (e.key.toLowerCase() === "v") view.showFelt = !view.showFelt;
    if (e.key.toLowerCase() === "m") regions.visible = !regions.visible;
  });
  renderer.setAnimationLoop((time, frame) => {
    if (frame && view.onXRFrame) view.onXRFrame(frame);
    else controls.update();
    renderer.render(scene, camera);
    // The splats are sorted off the main thread: the first frame after loading may draw none, so
    // the flag waits for the second drawn frame.
    if (view.splatFrames !== undefined && !document.body.dataset.sceneLoaded && ++view.splatFrames >= 2)
      document.body.dataset.sceneLoaded = "1";
    countFrame();
  });
  setupXR(view, ws, { steer: !!h.xr }).then((ok) => {
    view.xrAvailable = ok;
    if (h.xr) $("help").innerHTML = ok
      ? "Enter VR (button below): the right controller is the tool and vibrates on contact; left grip drags the world, left trigger resets it."
      : "--device xr: this browser offers no immersive VR session (open the page in a headset's browser).";
  }).catch((e) => showError(`WebXR: ${e.message}`));
}

// The material map's regions as wireframes (boxes from their 8 world corners, spheres), one
// colour per material; hidden until M (--materials gives them in the hello).
function materialRegions(list) {
  const group = new THREE.Group();
  group.visible = false;
  const colours = [0xff7f0e, 0x2ca02c, 0x9467bd, 0x8c564b, 0xe377c2, 0x17becf];
  const names = [...new Set(list.map((r) => r.material))];
  const edges = [[0, 1], [2, 3], [4, 5], [6, 7], [0, 2], [1, 3], [4, 6], [5, 7], [0, 4], [1, 5], [2, 6], [3, 7]];
  for (const r of list) {
    const material = new THREE.LineBasicMaterial({ color: colours[names.indexOf(r.material) % colours.length] });
    if (r.box) {
      const pts = edges.flatMap(([a, b]) => [vec(r.box.corners[a]), vec(r.box.corners[b])]);
      group.add(new THREE.LineSegments(new THREE.BufferGeometry().setFromPoints(pts), material));
    } else if (r.sphere) {
      const s = new THREE.LineSegments(new THREE.WireframeGeometry(new THREE.SphereGeometry(r.sphere.radius, 16, 8)), material);
      s.position.copy(vec(r.sphere.center));
      group.add(s);
    }
  }
  return group;
}

function countFrame() {
  const p = view.perf, now = performance.now();
  p.frames++;
  p.total = (p.total || 0) + 1;
  if (now - p.since >= 1000) {
    p.fps = (1000 * p.frames) / (now - p.since);
    p.frames = 0;
    p.since = now;
    const el = $("perf");
    if (el) el.textContent = `${p.fps.toFixed(1)} fps${view.xr && view.xr.active ? " (VR)" : ""} / ` +
      `${p.splats.toLocaleString()}${p.budget ? `, LoD budget ${p.budget.toLocaleString()}` : ""} (${view.quality.name})`;
  }
}

// The tool as wireframe ellipsoids: one at the tool centre point, or every part of a compound
// tool placed in the tool frame (hello.tool.parts).
function toolShape(t, color, opacity, order) {
  const group = new THREE.Group();
  const material = new THREE.MeshBasicMaterial({ color, wireframe: true, transparent: true, opacity, depthTest: false });
  const parts = t.parts || [{ center: [0, 0, 0], axes: t.axes, rotation: [1, 0, 0, 0] }];
  for (const p of parts) {
    const mesh = new THREE.Mesh(new THREE.SphereGeometry(1, 16, 10), material);
    mesh.position.set(...p.center);
    mesh.quaternion.set(p.rotation[1], p.rotation[2], p.rotation[3], p.rotation[0]);
    mesh.scale.set(...p.axes);
    mesh.renderOrder = order;
    group.add(mesh);
  }
  group.name = `tool-parts-${parts.length}`;
  return group;
}

// A unit curved arrow about +z: three quarters of a ring turning counter-clockwise, a cone at its end.
function torqueArrow() {
  const group = new THREE.Group();
  const material = new THREE.MeshBasicMaterial({ color: 0xff66cc, transparent: true, depthTest: false });
  const ring = new THREE.Mesh(new THREE.TorusGeometry(1, 0.05, 6, 36, 1.5 * Math.PI), material);
  const head = new THREE.Mesh(new THREE.ConeGeometry(0.15, 0.4, 12), material);
  head.position.set(0, -1, 0); // the ring's end, at 270 degrees
  head.rotation.z = -Math.PI / 2; // the cone's +y turned to +x: the way the ring turns there
  for (const o of [ring, head]) {
    o.renderOrder = 1002;
    group.add(o);
  }
  group.visible = false;
  group.name = "torque";
  return group;
}

const zAxis = new THREE.Vector3(0, 0, 1);

const tmpM = new THREE.Matrix4(), tmpQ = new THREE.Quaternion(), tmpP = new THREE.Vector3(), tmpS = new THREE.Vector3();

const followDelta = new THREE.Vector3();

function update(m) {
  view.last = m;
  if (m.material !== undefined) $("material").textContent = m.material;
  const c = vec(m.tool.center);
  view.tool.position.copy(c);
  // Follow: the orbit centre glides to the tool, and the camera moves with it, so the tool stays
  // in the middle of the view at the distance the user chose. Not while the tool is dragged.
  if (view.follow && !view.dragging) {
    followDelta.copy(c).sub(view.controls.target).multiplyScalar(0.15);
    view.controls.target.add(followDelta);
    view.camera.position.add(followDelta);
  }
  const q = m.tool.rotation;
  view.tool.quaternion.set(q[1], q[2], q[3], q[0]);
  if (view.target === null) view.target = c.clone();
  if (m.proxy) {  // shown while it holds the tool away from the device's pose
    const p = vec(m.proxy.center);
    view.proxy.position.copy(p);
    view.proxy.quaternion.copy(view.tool.quaternion);
    view.proxy.visible = p.distanceTo(c) > 0.02 * view.hello.tool.axes[0];
  }
  showFelt(m);
  // The objects at their live poses ([px, py, pz, qw, qx, qy, qz]; absent until they first move).
  (m.objects || []).forEach((p, i) => {
    const g = view.objects[i];
    if (!g) return;
    g.position.set(p[0], p[1], p[2]);
    g.quaternion.set(p[4], p[5], p[6], p[3]);
  });

  const n = Math.min(m.contacts.length, MAX_SHOWN);
  for (let i = 0; i < n; i++) {
    const k = m.contacts[i]; // [index, cx, cy, cz, ax, ay, az, qw, qx, qy, qz]
    tmpP.set(k[1], k[2], k[3]);
    // True k-sigma semi-axes, with a floor so that flat splats still show as thin disks.
    const floor = 0.03 * view.hello.tool.axes[0];
    tmpS.set(Math.max(k[4], floor), Math.max(k[5], floor), Math.max(k[6], floor));
    tmpQ.set(k[8], k[9], k[10], k[7]);
    view.contacts.setMatrixAt(i, tmpM.compose(tmpP, tmpQ, tmpS));
  }
  view.contacts.count = n;
  view.contacts.instanceMatrix.needsUpdate = true;

  const f = vec(m.force);
  const fm = f.length();
  view.arrow.visible = fm > 1e-6;
  if (view.arrow.visible) {
    const len = 0.25 * view.extent * Math.min(1, fm / view.hello.f_max) + 1e-6;
    view.arrow.position.copy(c);
    view.arrow.setDirection(f.clone().normalize());
    view.arrow.setLength(len, 0.2 * len, 0.1 * len);
  }

  // Torque about the tool centre point: the ring's size grows with |tau| up to the safety limit.
  const tau = m.torque ? vec(m.torque) : new THREE.Vector3();
  const tm = tau.length();
  view.twist.visible = tm > 1e-6;
  if (view.twist.visible) {
    const size = view.hello.tool.axes[0] * (1.2 + 1.8 * Math.min(1, tm / (view.hello.tau_max || 0.5)));
    view.twist.position.copy(c);
    view.twist.quaternion.setFromUnitVectors(zAxis, tau.clone().normalize());
    view.twist.scale.setScalar(size);
  }
  document.body.dataset.torque = tm.toFixed(5);

  $("candidates").textContent = m.counts.candidates;
  if (view.hello.renderer === "proxy") {
    // The proxy (god-object) reports what holds it: the gap to the device and the Gaussians it
    // rests on, not the paper's pre-filter and K_min counts (it runs neither per tick).
    const gap = vec(m.proxy.center).distanceTo(vec(m.tool.center));
    $("prefiltered").textContent = `${(gap * 1000).toFixed(1)} mm, ${m.proxy.constraints} plane(s)`;
  } else {
    $("prefiltered").textContent = m.counts.prefiltered;
  }
  $("contacts").textContent = m.counts.contacts;
  $("force").textContent = `${fm.toFixed(2)} N`;
  $("query").textContent = `${m.query_us.toFixed(1)} µs (p99 ${m.stats.query_p99_us.toFixed(1)})`;
  $("rate").textContent = `${m.stats.rate_hz.toFixed(1)} / ${m.stats.set_rate_hz} Hz`;
  $("jitter").textContent = `${m.stats.jitter_p99_us.toFixed(1)} µs, ${m.stats.deadline_misses} misses`;
  $("stale").textContent = `${m.stats.stale_ticks} / ${m.stats.fades}`;
  $("tool").textContent = m.tool.center.map((x) => x.toFixed(3)).join(", ");
  document.body.dataset.contacts = m.counts.contacts;
  document.body.dataset.force = fm.toFixed(4);
  vibrate(view, m, fm);

  view.history.push([m.counts.contacts, fm]);
  if (view.history.length > PLOT_SAMPLES) view.history.shift();
  drawPlot();
}

// The point of the tool posed at `center` (tool rotation `q`, a THREE.Quaternion) farthest along
// world direction `w`: the support point over its parts (ellipsoids; a one-part tool is its own).
function supportPoint(center, q, w) {
  const parts = view.hello.tool.parts || [{ center: [0, 0, 0], axes: view.hello.tool.axes, rotation: [1, 0, 0, 0] }];
  const wt = w.clone().applyQuaternion(q.clone().invert());
  let best = null, bestDot = -Infinity;
  for (const part of parts) {
    const qp = new THREE.Quaternion(part.rotation[1], part.rotation[2], part.rotation[3], part.rotation[0]);
    const wp = wt.clone().applyQuaternion(qp.clone().invert());
    const a = part.axes;
    const aw = new THREE.Vector3(a[0] * wp.x, a[1] * wp.y, a[2] * wp.z);
    const sp = new THREE.Vector3(a[0] * aw.x, a[1] * aw.y, a[2] * aw.z).divideScalar(Math.max(aw.length(), 1e-12));
    const st = sp.applyQuaternion(qp).add(vec(part.center));
    const d = st.dot(wt);
    if (d > bestDot) { bestDot = d; best = st; }
  }
  return best.applyQuaternion(q).add(center);
}

// The felt surface: where the proxy's tool meets what holds it, i.e. the tool's point farthest
// against the force the model asks for (its contact normal) with the tool where the proxy holds
// it, a disc 1.5 tool radii wide in the plane across that normal. Shown while the model holds
// the tool with a force.
function showFelt(m) {
  const d = m.desired ? vec(m.desired) : new THREE.Vector3();
  const on = view.showFelt && m.proxy && m.proxy.constraints > 0 && d.length() > 0.05;
  view.felt.visible = !!on;
  document.body.dataset.felt = on ? "1" : "0";
  if (!on) {
    $("felt").textContent = "–";
    return;
  }
  const n = d.normalize();
  const r = Math.min(...view.hello.tool.axes);
  view.felt.position.copy(supportPoint(vec(m.proxy.center), view.tool.quaternion, n.clone().negate()));
  view.felt.quaternion.setFromUnitVectors(zAxis, n);
  view.felt.scale.setScalar(1.5 * r);
  document.body.dataset.feltNormal = n.toArray().map((x) => x.toFixed(3)).join(",");
  $("felt").textContent = `the tool ${(vec(m.proxy.center).distanceTo(vec(m.tool.center)) * 1000).toFixed(1)} mm past it`;
}

function drawPlot() {
  const cv = $("plot"), g = cv.getContext("2d");
  g.clearRect(0, 0, cv.width, cv.height);
  const h = view.history;
  if (h.length < 2) return;
  const maxC = Math.max(10, ...h.map((x) => x[0]));
  const maxF = Math.max(1, ...h.map((x) => x[1]));
  const line = (idx, max, color) => {
    g.strokeStyle = color;
    g.beginPath();
    h.forEach((x, i) => {
      const px = (i / (PLOT_SAMPLES - 1)) * cv.width, py = cv.height - 4 - (x[idx] / max) * (cv.height - 8);
      i ? g.lineTo(px, py) : g.moveTo(px, py);
    });
    g.stroke();
  };
  line(0, maxC, "#4fc3f7");
  line(1, maxF, "#ff7043");
  g.fillStyle = "#888";
  g.fillText(`${maxC} contacts / ${maxF.toFixed(1)} N`, 4, 11);
}

// ---- the mouse/keyboard device ----------------------------------------------------------------

function sendTool() {
  if (ws.readyState === WebSocket.OPEN && view.target)
    ws.send(JSON.stringify({ type: "tool", center: [view.target.x, view.target.y, view.target.z] }));
}

function moveTool(delta) {
  if (!view.target) return;
  view.target.add(delta);
  sendTool();
}

function setupMouseDevice(h) {
  setInterval(sendTool, 1000 / 30); // the device's input rate; also keeps the watchdog fed
  const el = view.renderer.domElement, ray = new THREE.Raycaster(), ndc = new THREE.Vector2();
  const pick = (e) => {
    const r = el.getBoundingClientRect();
    ndc.set(((e.clientX - r.left) / r.width) * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
    ray.setFromCamera(ndc, view.camera);
  };
  el.addEventListener("pointerdown", (e) => {
    pick(e);
    if (!view.target || ray.intersectObject(view.tool).length === 0) return;
    view.dragging = true;
    view.controls.enabled = false;
    const normal = view.camera.getWorldDirection(new THREE.Vector3());
    view.dragPlane.setFromNormalAndCoplanarPoint(normal, view.target);
    const hit = new THREE.Vector3();
    ray.ray.intersectPlane(view.dragPlane, hit);
    view.dragOffset.copy(view.target).sub(hit);
    el.setPointerCapture(e.pointerId);
  });
  el.addEventListener("pointermove", (e) => {
    if (!view.dragging) return;
    pick(e);
    const hit = new THREE.Vector3();
    if (ray.ray.intersectPlane(view.dragPlane, hit)) {
      view.target.copy(hit.add(view.dragOffset));
      sendTool();
    }
  });
  el.addEventListener("pointerup", () => { view.dragging = false; view.controls.enabled = true; });
  addEventListener("keydown", (e) => {
    const step = h.step * (e.shiftKey ? 5 : 1);
    const cam = view.camera;
    const fwd = cam.getWorldDirection(new THREE.Vector3());
    const right = fwd.clone().cross(cam.up).normalize();
    const screenUp = right.clone().cross(fwd).normalize();
    const k = e.key.toLowerCase();
    const moves = {
      arrowleft: right.clone().multiplyScalar(-step), arrowright: right.clone().multiplyScalar(step),
      arrowup: screenUp.clone().multiplyScalar(step), arrowdown: screenUp.clone().multiplyScalar(-step),
      w: fwd.clone().multiplyScalar(step), s: fwd.clone().multiplyScalar(-step),
      q: view.up.clone().multiplyScalar(step), e: view.up.clone().multiplyScalar(-step),
    };
    if (k in moves) {
      moveTool(moves[k]);
      e.preventDefault();
    } else if (k === "r" && view.last) {
      view.target = null;
    } else if (k === "u") {
      view.upIndex = (view.upIndex + 1) % view.upChoices.length;
      cam.up.copy(view.upChoices[view.upIndex]);
      view.controls.update();
    }
  });
}
