// hydrojam's 3D viewer of an HTML report (hydrojam/_html.py): three.js and its OrbitControls,
// vendored in hydrojam/_vendor/three and embedded in the page (zlib, base64), are inflated and
// loaded from the page itself (blob URLs), so the page opens offline from a file. Each
// <div class="hj-scene"> names the <script type="application/json"> holding its surfaces: groups
// of triangles or line segments, each with a colour and an opacity, their arrays in one zlib
// buffer (base64): positions as uint16 steps over the group's box (origin + step * q), indices
// uint16 or uint32, optional per-vertex RGB uint8; a check box per group shows or hides it.
// A view is built when it first comes near the window (or is clicked); every view draws through
// one shared WebGL renderer and copies its picture to its own 2D canvas, so a page holds any
// number of views within the browser's limit of live WebGL contexts (about 16).
// The page's address may end in #azimuth=DEG&elevation=DEG&hide=GROUP,...: the initial view
// turned by those angles about the vertical and the horizontal (what a mouse drag does), those
// groups hidden (their boxes unticked).
const source = (id) => document.getElementById(id).textContent;
const moduleUrl = (text) => URL.createObjectURL(new Blob([text], { type: "text/javascript" }));
const bytes = (b64) => Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));
const inflate = async (b64) =>
  new Response(new Blob([bytes(b64)]).stream().pipeThrough(new DecompressionStream("deflate"))).arrayBuffer();
const script = async (id) => new TextDecoder().decode(await inflate(source(id)));

const threeUrl = moduleUrl(await script("hj-three"));
const THREE = await import(threeUrl);
const { OrbitControls } = await import(moduleUrl((await script("hj-orbit")).replace(/from\s*['"]three['"]/g, `from '${threeUrl}'`)));
THREE.ColorManagement.enabled = false;  // the colours given are the colours shown

const hash = new URLSearchParams(location.hash.slice(1));
const turn = (name) => THREE.MathUtils.degToRad(Number(hash.get(name) || 0));
const hidden = (hash.get("hide") || "").split(",");

let shared = null;  // the one WebGL renderer, made with the first view
function webgl() {
  if (!shared) {
    shared = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    shared.outputColorSpace = THREE.LinearSRGBColorSpace;
    shared.setClearColor(0xffffff, 1);
  }
  return shared;
}

// a view's picture: drawn by the shared renderer at the canvas's size, copied to the canvas
function paint(v) {
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(1, Math.round(v.canvas.clientWidth * dpr));
  const h = Math.max(1, Math.round(v.canvas.clientHeight * dpr));
  if (v.canvas.width !== w || v.canvas.height !== h) {
    v.canvas.width = w;
    v.canvas.height = h;
    v.camera.aspect = w / h;
    v.camera.updateProjectionMatrix();
  }
  const r = webgl();
  r.setPixelRatio(1);
  r.setSize(w, h, false);
  r.render(v.scene, v.camera);
  v.ctx.clearRect(0, 0, w, h);
  v.ctx.drawImage(r.domElement, 0, 0, w, h);
}

function schedule(v) {
  if (v.pending) return;
  v.pending = true;
  requestAnimationFrame(() => { v.pending = false; paint(v); });
}

function geometry(g, buffer) {
  const array = (Type, [offset, count]) => new Type(buffer, offset, count);
  const q = array(Uint16Array, g.positions);
  const xyz = new Float32Array(q.length);
  for (let i = 0; i < q.length; i++) xyz[i] = g.origin[i % 3] + g.step[i % 3] * q[i];
  const geom = new THREE.BufferGeometry();
  geom.setAttribute("position", new THREE.BufferAttribute(xyz, 3));
  geom.setIndex(new THREE.BufferAttribute(array(g.indices[2] === 2 ? Uint16Array : Uint32Array, g.indices), 1));
  if (g.colors) geom.setAttribute("color", new THREE.BufferAttribute(array(Uint8Array, g.colors), 3, true));
  return geom;
}

async function build(el) {
  const data = JSON.parse(source(el.dataset.scene));
  const buffer = await inflate(data.data);
  const canvas = el.querySelector("canvas");
  const v = { canvas, ctx: canvas.getContext("2d"), scene: new THREE.Scene(), pending: false };
  v.scene.add(new THREE.AmbientLight(0xffffff, 1.6));
  const camera = new THREE.PerspectiveCamera(30, canvas.clientWidth / canvas.clientHeight, 0.1, 1e5);
  v.camera = camera;
  camera.up.set(...data.up);
  const headlight = new THREE.DirectionalLight(0xffffff, 1.6);
  headlight.position.set(0.3, 0.6, 1.0);
  camera.add(headlight);
  v.scene.add(camera);
  const box = new THREE.Box3();
  const toggles = el.querySelector(".hj-toggles");
  for (const g of data.groups) {
    const geom = geometry(g, buffer);
    const color = new THREE.Color(...g.color);
    let obj;
    if (g.kind === "lines") {
      obj = new THREE.LineSegments(geom, new THREE.LineBasicMaterial({ color, transparent: true, opacity: g.opacity }));
    } else {
      geom.computeVertexNormals();
      const clear = g.opacity < 1;
      obj = new THREE.Mesh(geom, new THREE.MeshLambertMaterial({
        color: g.colors ? 0xffffff : color, vertexColors: Boolean(g.colors), side: THREE.DoubleSide,
        transparent: clear, opacity: g.opacity, depthWrite: !clear,
      }));
      obj.renderOrder = clear ? 1 : 0;
    }
    v.scene.add(obj);
    box.expandByObject(obj);
    const label = document.createElement("label");
    const check = document.createElement("input");
    check.type = "checkbox";
    check.checked = !hidden.includes(g.name);
    obj.visible = check.checked;
    check.dataset.group = g.name;
    check.addEventListener("change", () => { obj.visible = check.checked; schedule(v); });
    label.append(check, " " + g.label);
    toggles.append(label);
  }
  const centre = box.getCenter(new THREE.Vector3());
  const radius = box.getSize(new THREE.Vector3()).length() / 2;
  const view = new THREE.Vector3(...data.view).normalize();
  view.applyAxisAngle(camera.up, turn("azimuth"));
  view.applyAxisAngle(new THREE.Vector3().crossVectors(camera.up, view).normalize(), -turn("elevation"));
  camera.position.copy(centre).addScaledVector(view, 0.85 * radius / Math.sin(THREE.MathUtils.degToRad(15)));
  camera.near = radius / 100;
  camera.far = radius * 100;
  camera.updateProjectionMatrix();
  const controls = new OrbitControls(camera, canvas);
  controls.target.copy(centre);
  controls.update();
  controls.addEventListener("change", () => schedule(v));
  el.querySelector(".hj-reset").addEventListener("click", () => { controls.reset(); schedule(v); });
  controls.saveState();
  new ResizeObserver(() => schedule(v)).observe(canvas);
  paint(v);
  el.dataset.hjDrawn = "1";
}

const built = new Map();  // element -> the promise of its build
function show(el) {
  if (!built.has(el)) {
    built.set(el, build(el).catch((err) => {
      el.querySelector(".hj-toggles").textContent = `the 3D view cannot be drawn here: ${err.message}`;
      console.error(err);
    }));
  }
  return built.get(el);
}

const scenes = [...document.querySelectorAll(".hj-scene")];
for (const el of scenes) el.addEventListener("pointerdown", () => show(el), { once: true });
let first = true;
const near = new IntersectionObserver(async (entries) => {
  await Promise.all(entries.filter((e) => e.isIntersecting).map((e) => show(e.target)));
  if (first) { first = false; document.body.dataset.hjReady = "1"; }  // the views in sight are drawn
}, { rootMargin: "300px 0px" });
for (const el of scenes) near.observe(el);
