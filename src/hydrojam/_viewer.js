// hydrojam's 3D viewer of an HTML report (hydrojam/_html.py): three.js and its OrbitControls,
// vendored in hydrojam/_vendor/three and embedded in the page, are loaded from the page itself
// (blob URLs), so the page opens offline from a file. Each <div class="hj-scene"> names the
// <script type="application/json"> holding its surfaces: groups of triangles (positions float32,
// indices uint32, optional per-vertex RGB uint8, all base64) or line segments, each with a colour
// and an opacity; a check box per group shows or hides it. The page's address may end in
// #azimuth=DEG&elevation=DEG&hide=GROUP,...: the initial view turned by those angles about the
// vertical and the horizontal (what a mouse drag does), those groups hidden (their boxes unticked).
const source = (id) => document.getElementById(id).textContent;
const moduleUrl = (text) => URL.createObjectURL(new Blob([text], { type: "text/javascript" }));
const bytes = (b64) => Uint8Array.from(atob(b64), (c) => c.charCodeAt(0));

const threeUrl = moduleUrl(source("hj-three"));
const THREE = await import(threeUrl);
const { OrbitControls } = await import(moduleUrl(source("hj-orbit").replace(/from\s*['"]three['"]/g, `from '${threeUrl}'`)));
THREE.ColorManagement.enabled = false;  // the colours given are the colours shown

const hash = new URLSearchParams(location.hash.slice(1));
const turn = (name) => THREE.MathUtils.degToRad(Number(hash.get(name) || 0));
const hidden = (hash.get("hide") || "").split(",");

function build(el) {
  const data = JSON.parse(source(el.dataset.scene));
  const canvas = el.querySelector("canvas");
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setSize(canvas.clientWidth, canvas.clientHeight, false);
  renderer.setClearColor(0xffffff, 1);
  const scene = new THREE.Scene();
  scene.add(new THREE.AmbientLight(0xffffff, 1.6));
  const camera = new THREE.PerspectiveCamera(30, canvas.clientWidth / canvas.clientHeight, 0.1, 1e5);
  camera.up.set(...data.up);
  const headlight = new THREE.DirectionalLight(0xffffff, 1.6);
  headlight.position.set(0.3, 0.6, 1.0);
  camera.add(headlight);
  scene.add(camera);
  const box = new THREE.Box3();
  const toggles = el.querySelector(".hj-toggles");
  for (const g of data.groups) {
    const geom = new THREE.BufferGeometry();
    geom.setAttribute("position", new THREE.BufferAttribute(new Float32Array(bytes(g.positions).buffer), 3));
    geom.setIndex(new THREE.BufferAttribute(new Uint32Array(bytes(g.indices).buffer), 1));
    const color = new THREE.Color(...g.color);
    let obj;
    if (g.kind === "lines") {
      obj = new THREE.LineSegments(geom, new THREE.LineBasicMaterial({ color, transparent: true, opacity: g.opacity }));
    } else {
      if (g.colors) geom.setAttribute("color", new THREE.BufferAttribute(bytes(g.colors), 3, true));
      geom.computeVertexNormals();
      const clear = g.opacity < 1;
      obj = new THREE.Mesh(geom, new THREE.MeshLambertMaterial({
        color: g.colors ? 0xffffff : color, vertexColors: Boolean(g.colors), side: THREE.DoubleSide,
        transparent: clear, opacity: g.opacity, depthWrite: !clear,
      }));
      obj.renderOrder = clear ? 1 : 0;
    }
    scene.add(obj);
    box.expandByObject(obj);
    const label = document.createElement("label");
    const check = document.createElement("input");
    check.type = "checkbox";
    check.checked = !hidden.includes(g.name);
    obj.visible = check.checked;
    check.dataset.group = g.name;
    check.addEventListener("change", () => { obj.visible = check.checked; draw(); });
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
  function draw() { renderer.render(scene, camera); }
  controls.addEventListener("change", draw);
  el.querySelector(".hj-reset").addEventListener("click", () => { controls.reset(); draw(); });
  controls.saveState();
  draw();
}

for (const el of document.querySelectorAll(".hj-scene")) {
  try {
    build(el);
  } catch (err) {
    el.querySelector(".hj-toggles").textContent = `the 3D view cannot be drawn here: ${err.message}`;
    throw err;
  }
}
document.body.dataset.hjReady = "1";
