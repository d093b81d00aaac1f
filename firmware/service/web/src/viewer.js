// The 3D viewer: a processed scan's mesh.ply in three.js (bundled from npm at build time,
// served by the device: no CDN, works offline). Renders on demand, not in a loop, so an
// open page costs the device's visitors no CPU while nobody turns the model.
import * as THREE from 'three';
import { PLYLoader } from 'three/examples/jsm/loaders/PLYLoader.js';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';

let state = null;

function setup(canvas) {
  // preserveDrawingBuffer: the page (and its test) can read back what is shown.
  const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x1b2127);
  const camera = new THREE.PerspectiveCamera(35, 1, 1, 20000);
  camera.up.set(0, 0, 1);  // the cabinet's world frame: z up along the slide
  scene.add(new THREE.HemisphereLight(0xffffff, 0x445566, 1.2));
  const key = new THREE.DirectionalLight(0xffffff, 1.6);
  camera.add(key);
  key.position.set(0.5, 1, 0.5);
  scene.add(camera);
  const controls = new OrbitControls(camera, canvas);
  const render = () => {
    const { clientWidth: w, clientHeight: h } = canvas;
    if (w > 0 && h > 0 && (canvas.width !== w || canvas.height !== h)) {
      renderer.setSize(w, h, false);
      camera.aspect = w / h;
      camera.updateProjectionMatrix();
    }
    renderer.render(scene, camera);
  };
  controls.addEventListener('change', render);
  window.addEventListener('resize', render);
  return { renderer, scene, camera, controls, render, mesh: null };
}

// Shows the PLY bytes; returns what was drawn.
export function showMesh(canvas, bytes) {
  if (!state) state = setup(canvas);
  const geometry = new PLYLoader().parse(bytes);
  // `process` writes double-precision vertices; WebGL takes 32-bit floats only.
  for (const name of Object.keys(geometry.attributes)) {
    const attribute = geometry.getAttribute(name);
    if (attribute.array instanceof Float64Array) {
      geometry.setAttribute(name, new THREE.BufferAttribute(Float32Array.from(attribute.array), attribute.itemSize));
    }
  }
  if (!geometry.getAttribute('normal')) geometry.computeVertexNormals();
  geometry.computeBoundingBox();
  if (state.mesh) {
    state.scene.remove(state.mesh);
    state.mesh.geometry.dispose();
  }
  const material = new THREE.MeshStandardMaterial({
    color: 0xd8c3a5, roughness: 0.7, metalness: 0.0, side: THREE.DoubleSide,
  });
  state.mesh = new THREE.Mesh(geometry, material);
  state.scene.add(state.mesh);
  // Frame the body from the front (the camera looks along +y), a little from above.
  const box = geometry.boundingBox;
  const centre = box.getCenter(new THREE.Vector3());
  const size = box.getSize(new THREE.Vector3());
  const distance = (Math.max(size.x, size.y, size.z) / 2) / Math.tan((35 / 2) * Math.PI / 180) * 1.25;
  state.camera.position.set(centre.x, centre.y - distance, centre.z + 0.15 * distance);
  state.controls.target.copy(centre);
  state.controls.update();
  state.render();
  const index = geometry.getIndex();
  return {
    vertices: geometry.getAttribute('position').count,
    triangles: index ? index.count / 3 : geometry.getAttribute('position').count / 3,
  };
}
