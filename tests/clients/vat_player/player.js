// A three.js player of springbake's vertex animation textures, and of its glTF caches as
// three.js plays them (morph targets, the pca cache), for the headless-browser test client
// (tests/clients/vat_player.js). window.compare(spec) renders each frame of spec.frames with
// every player from the same orthographic front camera through MeshNormalMaterial's colouring
// (view-space normals as colours) and returns, against the morph cache's image: the
// silhouette's intersection over union and the mean colour difference inside it.
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { EXRLoader } from "three/addons/loaders/EXRLoader.js";

const SIZE = 512;
const canvas = document.getElementById("view");
const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setSize(SIZE, SIZE, false);
renderer.setClearColor(0x000000, 0);

const vertexShader = `
precision highp float;
in vec3 position;
in vec2 uv1;
uniform mat4 modelViewMatrix, projectionMatrix, viewMatrix;
uniform sampler2D posTex, pos2Tex, rotTex;
uniform float frame, frameCount;
uniform bool ldr;
uniform vec3 boundMin, boundMax;
out vec3 vNormal;
void main() {
  // TEXCOORD_1 is the frame-0 texel centre with v from the image's top; three.js's texture
  // loaders put the image's top at v = 1.
  vec2 uv = vec2(uv1.x, 1.0 - (uv1.y + frame / frameCount));
  vec3 offset = texture(posTex, uv).rgb;
  vec4 q = texture(rotTex, uv);
  if (ldr) {
    offset = (offset + texture(pos2Tex, uv).rgb * 0.01) * (boundMax - boundMin) + boundMin;
    q = q * 2.0 - 1.0;
  }
  vec3 up = vec3(0.0, 1.0, 0.0);
  vec3 n = up + 2.0 * cross(q.xyz, cross(q.xyz, up) + q.w * up);
  vNormal = normalize((viewMatrix * vec4(n, 0.0)).xyz);
  gl_Position = projectionMatrix * modelViewMatrix * vec4(position + offset, 1.0);
}`;
// MeshNormalMaterial's colouring: packNormalToRGB of the view-space normal.
const fragmentShader = `
precision highp float;
in vec3 vNormal;
out vec4 colour;
void main() {
  vec3 n = normalize(vNormal);
  if (!gl_FrontFacing) n = -n;
  colour = vec4(n * 0.5 + 0.5, 1.0);
}`;

async function loadTexture(url) {
  const texture = url.endsWith(".exr")
    ? await new EXRLoader().setDataType(THREE.FloatType).loadAsync(url)
    : await new THREE.TextureLoader().loadAsync(url);
  texture.magFilter = THREE.NearestFilter;
  texture.minFilter = THREE.NearestFilter;
  texture.generateMipmaps = false;
  texture.colorSpace = THREE.NoColorSpace;
  return texture;
}

async function vatPlayer(folder, ldr) {
  const [data] = await (await fetch(`${folder}/data/${folder.split("/").pop().replace(/\.vat$/, "")}_data.json`)).json();
  const sb = data.springbake;
  const files = ldr ? sb["8bit"] : sb.float;
  const gltf = await new GLTFLoader().loadAsync(`${folder}/${sb.mesh}`);
  const uniforms = {
    posTex: { value: await loadTexture(`${folder}/${files.position}`) },
    pos2Tex: { value: ldr ? await loadTexture(`${folder}/${files.position2}`) : null },
    rotTex: { value: await loadTexture(`${folder}/${files.rotation}`) },
    frame: { value: 0 },
    frameCount: { value: sb.frame_count },
    ldr: { value: ldr },
    boundMin: { value: new THREE.Vector3(data["Bound Min X"], data["Bound Min Y"], data["Bound Min Z"]) },
    boundMax: { value: new THREE.Vector3(data["Bound Max X"], data["Bound Max Y"], data["Bound Max Z"]) },
  };
  const material = new THREE.RawShaderMaterial({
    glslVersion: THREE.GLSL3, vertexShader, fragmentShader, uniforms, side: THREE.DoubleSide,
  });
  gltf.scene.traverse((o) => {
    if (o.isMesh) { o.material = material; o.frustumCulled = false; }
  });
  return { scene: gltf.scene, fps: sb.fps, setFrame: (f) => { uniforms.frame.value = f; } };
}

async function gltfPlayer(url) {
  const gltf = await new GLTFLoader().loadAsync(url);
  const material = new THREE.MeshNormalMaterial({ side: THREE.DoubleSide });
  gltf.scene.traverse((o) => {
    if (o.isMesh) { o.material = material; o.frustumCulled = false; }
  });
  const mixer = new THREE.AnimationMixer(gltf.scene);
  for (const clip of gltf.animations) {
    // Once and held: a looping action wraps its last frame (t = duration) back to the first.
    const action = mixer.clipAction(clip);
    action.setLoop(THREE.LoopOnce, 1);
    action.clampWhenFinished = true;
    action.play();
  }
  return { scene: gltf.scene, setFrame: (f, fps) => { mixer.setTime(f / fps); gltf.scene.updateMatrixWorld(true); } };
}

function snapshot(player, camera) {
  const scene = new THREE.Scene();
  scene.add(player.scene);
  renderer.render(scene, camera);
  scene.remove(player.scene);
  const gl = renderer.getContext();
  const pixels = new Uint8Array(SIZE * SIZE * 4);
  gl.readPixels(0, 0, SIZE, SIZE, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
  return pixels;
}

function difference(a, b) {
  let both = 0, either = 0, colour = 0;
  for (let i = 0; i < a.length; i += 4) {
    const inA = a[i + 3] > 0, inB = b[i + 3] > 0;
    if (inA || inB) either++;
    if (inA && inB) {
      both++;
      colour += (Math.abs(a[i] - b[i]) + Math.abs(a[i + 1] - b[i + 1]) + Math.abs(a[i + 2] - b[i + 2])) / 3;
    }
  }
  return { iou: either ? both / either : 1, colour: both ? colour / both / 255 : 0, pixels: either };
}

window.compare = async (spec) => {
  const reference = await gltfPlayer(spec.morph);
  const players = {
    vat_float: await vatPlayer(spec.vat, false),
    vat_8bit: await vatPlayer(spec.vat, true),
  };
  if (spec.pca) players.pca = await gltfPlayer(spec.pca);
  const fps = players.vat_float.fps;
  // Front view of the whole motion: the rest box grown by the offsets' bounds.
  const box = new THREE.Box3().setFromObject(players.vat_float.scene);
  const [data] = await (await fetch(`${spec.vat}/data/${spec.vat.split("/").pop().replace(/\.vat$/, "")}_data.json`)).json();
  box.min.add(new THREE.Vector3(data["Bound Min X"], data["Bound Min Y"], data["Bound Min Z"]));
  box.max.add(new THREE.Vector3(data["Bound Max X"], data["Bound Max Y"], data["Bound Max Z"]));
  const centre = box.getCenter(new THREE.Vector3());
  const half = Math.max(box.max.x - box.min.x, box.max.y - box.min.y) * 0.55;
  const camera = new THREE.OrthographicCamera(-half, half, half, -half, 0.01, 1000);
  camera.position.set(centre.x, centre.y, box.max.z + 10);
  camera.lookAt(centre);
  camera.updateMatrixWorld(true);
  const results = [];
  for (const f of spec.frames) {
    reference.setFrame(f, fps);
    const ref = snapshot(reference, camera);
    const row = { frame: f };
    for (const [name, player] of Object.entries(players)) {
      player.setFrame(f, fps);
      row[name] = difference(snapshot(player, camera), ref);
    }
    // The VAT's frame f against the reference's first frame: a player that ignored the frame
    // would be caught by the comparison above, this shows how different frames look.
    players.vat_float.setFrame(f, fps);
    reference.setFrame(0, fps);
    row.vat_float_vs_first = difference(snapshot(players.vat_float, camera), snapshot(reference, camera));
    results.push(row);
  }
  // Leave the 8-bit VAT's last frame on the canvas (the client saves it).
  players.vat_8bit.setFrame(spec.frames[spec.frames.length - 1], fps);
  snapshot(players.vat_8bit, camera);
  return results;
};
window.ready = true;
