// A dynmesh stream in a three.js scene: each frame's geometry (and texture) decoded with the
// dynmesh decoder (frames.js, over web/src) into a BufferGeometry, played in a loop at 30 fps.
// three.js comes from a CDN through the import map in index.html: fine for an example; a
// real page would install or vendor it. The stream: ?stream=URL, or stream.dmsh beside the
// page. Decoding runs on the page's thread here, which suits short clips; the player module
// (web/player/api.js) decodes in a worker and plays while the stream downloads.

import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { mergeVertices } from 'three/addons/utils/BufferGeometryUtils.js';
import { MeshFrames } from './frames.js';

const FPS = 30;
const url = new URLSearchParams(location.search).get('stream') ?? 'stream.dmsh';
const status = document.getElementById('status');

const renderer = new THREE.WebGLRenderer({ antialias: true });
renderer.setPixelRatio(devicePixelRatio);
renderer.setSize(innerWidth, innerHeight);
document.body.append(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x20242b);
scene.add(new THREE.HemisphereLight(0xffffff, 0x445566, 2));
const light = new THREE.DirectionalLight(0xffffff, 1.5);
light.position.set(1, 2, 3);
scene.add(light);
const camera = new THREE.PerspectiveCamera(45, innerWidth / innerHeight, 0.001, 1000);
const controls = new OrbitControls(camera, renderer.domElement);
const material = new THREE.MeshStandardMaterial({ color: 0xc8ccd4, side: THREE.DoubleSide, roughness: 0.8 });
const mesh = new THREE.Mesh(new THREE.BufferGeometry(), material);
scene.add(mesh);

/** Puts a decoded frame (and its texture image, or null) on the mesh. */
function show(frame, image) {
  let geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(frame.positions, 3));
  if (frame.index) geometry.setIndex(new THREE.BufferAttribute(frame.index, 1));
  if (frame.uvs) {
    geometry.setAttribute('uv', new THREE.BufferAttribute(frame.uvs, 2));
    geometry = mergeVertices(geometry); // corners welded again but along UV seams: smooth normals
  }
  geometry.computeVertexNormals();
  mesh.geometry.dispose(); // the previous frame's GPU buffers
  mesh.geometry = geometry;
  if (image) {
    // ImageData rows go top first and frames.js measures v from the top: no flip.
    const map = new THREE.DataTexture(image.data, image.width, image.height);
    map.colorSpace = THREE.SRGBColorSpace;
    map.minFilter = map.magFilter = THREE.LinearFilter;
    map.needsUpdate = true;
    material.map?.dispose();
    material.map = map;
    material.color.set(0xffffff);
    material.needsUpdate = true;
  }
}

/** Points the camera at the mesh from the front (+z), far enough to see all of it. */
function frameCamera() {
  mesh.geometry.computeBoundingSphere();
  const { center, radius } = mesh.geometry.boundingSphere;
  controls.target.copy(center);
  camera.position.set(center.x, center.y, center.z + 2.5 * radius);
  camera.near = radius / 100;
  camera.far = radius * 100;
  camera.updateProjectionMatrix();
}

async function play() {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`cannot fetch ${url}: HTTP ${response.status}`);
  const frames = new MeshFrames(new Uint8Array(await response.arrayBuffer()));
  status.textContent = `${url}: ${frames.count} frames${frames.textureNote ? `, ${frames.textureNote}` : ''}`;
  for (let i = 0; ; i = (i + 1) % frames.count) {
    const start = performance.now();
    const frame = frames.frame(i);
    show(frame, frame.uvs ? await frames.image(i) : null);
    if (!mesh.userData.framed) {
      frameCamera(); // once, on the first frame: the user's orbit stays after that
      mesh.userData.framed = true;
    }
    await new Promise((resolve) => setTimeout(resolve, Math.max(0, 1000 / FPS - (performance.now() - start))));
  }
}

renderer.setAnimationLoop(() => {
  controls.update();
  renderer.render(scene, camera);
});
addEventListener('resize', () => {
  camera.aspect = innerWidth / innerHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(innerWidth, innerHeight);
});
play().catch((e) => { status.textContent = `error: ${e.message}`; });
