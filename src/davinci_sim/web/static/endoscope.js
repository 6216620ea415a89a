// The endoscope drawn in the page with three.js, from the server's scene and pose messages
// (web/endoscope_stream.py): the same compiled model the server renders, the same cameras.
//
// A MuJoCo camera looks along its -z with y up, as a three.js camera does: each eye's
// camera takes the streamed pose as it is, and its projection from the model's vertical
// field of view, the image's aspect and MuJoCo's clip planes. Colours are used as linear
// values and written without an sRGB transfer, as MuJoCo's renderer does.
//
// Lighting follows the law of MuJoCo's renderer (OpenGL's classic lighting model): the
// geom's colour as the material's ambient and diffuse colour, the material's specular and
// shininess (x 128), MuJoCo's headlight (a directional light from the eye along its view,
// with its ambient) and the model's lights (spot: the cosine to the axis raised to the
// exponent inside the cutoff, attenuation 1/(a0 + a1 d + a2 d^2)). It is evaluated per
// vertex here (vertexGlsl), the cheap way on a software WebGL, where three.js's per-pixel
// Phong with the scene's three spot lights took 230 ms a frame; so a large flat face (a
// box's: four corners) lacks the spot's highlight the server's image shows in its middle.

const MAX_LIGHTS = 4;  // the headlight and the model's lights (the scene has three)

// The scene message's lights as the shader takes them: MuJoCo's headlight (a directional
// light along the eye's view) first, then the model's, at most MAX_LIGHTS.
function sceneLights(m) {
  const head = { ...m.headlight, directional: true, attenuation: [1, 0, 0], cutoff_deg: 180, exponent: 0 };
  return [head, ...m.lights].slice(0, MAX_LIGHTS);
}

// The vertex shader of a scene's lights (lightUniforms' list: the headlight first): the law
// above, one block per active light with its kind fixed, a spot's attenuation left out where
// it is MuJoCo's default (1, 0, 0: a factor of exactly 1). A loop over the lights with a
// branch on each one's kind took ~5 ms more a left-eye frame on Chromium's software WebGL
// (2-core machine, ~15k vertices); this draws the same pixels. An inactive light adds
// nothing (its colours are zero), so it has no block.
function vertexGlsl(lights) {
  const blocks = lights.map((l, k) => {
    if (!l.active) return "";
    let where;
    if (l.directional) {
      where = `    vec3 l = -lightDir[${k}]; float factor = 1.0;\n`;
    } else {
      const [a0, a1, a2] = l.attenuation;
      where = `    vec3 d = lightPos[${k}] - world.xyz; float dist = length(d); vec3 l = d / dist;\n` +
        (a0 === 1 && a1 === 0 && a2 === 0 ? "    float factor = 1.0;\n"
          : `    vec3 a = lightAttenuation[${k}];\n` +
            "    float factor = 1.0 / max(a.x + a.y * dist + a.z * dist * dist, 1e-6);\n") +
        `    float cosAxis = dot(-l, lightDir[${k}]);\n` +
        `    factor *= cosAxis >= lightCosCutoff[${k}] ? pow(max(cosAxis, 0.0), lightExponent[${k}]) : 0.0;\n`;
    }
    return `  {\n${where}` +
      "    float nl = max(dot(n, l), 0.0);\n" +
      "    float nh = max(dot(n, normalize(l + v)), 0.0);\n" +
      `    vec3 spec = nl > 0.0 ? lightSpecular[${k}] * material.x * pow(nh, material.y) : vec3(0.0);\n` +
      `    c += factor * (lightAmbient[${k}] * rgba.rgb + nl * lightDiffuse[${k}] * rgba.rgb + spec);\n  }\n`;
  });
  return `
attribute vec4 rgba;
attribute vec2 material;  // specular, shininess (x 128)
uniform vec3 lightPos[${MAX_LIGHTS}];
uniform vec3 lightDir[${MAX_LIGHTS}];
uniform vec3 lightAmbient[${MAX_LIGHTS}];
uniform vec3 lightDiffuse[${MAX_LIGHTS}];
uniform vec3 lightSpecular[${MAX_LIGHTS}];
uniform vec3 lightAttenuation[${MAX_LIGHTS}];
uniform float lightCosCutoff[${MAX_LIGHTS}];
uniform float lightExponent[${MAX_LIGHTS}];
varying vec4 shade;
void main() {
  vec4 world = modelMatrix * vec4(position, 1.0);
  vec3 n = normalize(mat3(modelMatrix) * normal);
  vec3 v = normalize(cameraPosition - world.xyz);
  vec3 c = vec3(0.0);
${blocks.join("")}  shade = vec4(min(c, vec3(1.0)), rgba.a);
  gl_Position = projectionMatrix * viewMatrix * world;
}`;
}

const FRAGMENT_GLSL = `
varying vec4 shade;
void main() { gl_FragColor = shade; }`;

// Segmentation (the fidelity test's): each pixel the id + 1 of the geom drawn there, in red
// (low byte) and green (high byte); 0 where nothing is.
const SEGMENT_VERTEX_GLSL = `
attribute float geomId;
varying vec4 shade;
void main() {
  float id = geomId + 1.0;
  shade = vec4(mod(id, 256.0) / 255.0, floor(id / 256.0) / 255.0, 0.0, 1.0);
  gl_Position = projectionMatrix * modelViewMatrix * vec4(position, 1.0);
}`;

const POSE_MAGIC = 0xFFFFFFFF;
const POSE_HEADER_BYTES = 16;

export function isPoseMessage(buffer) {
  return buffer.byteLength >= POSE_HEADER_BYTES && new DataView(buffer).getUint32(0, true) === POSE_MAGIC;
}

export async function loadThree() {
  const THREE = await import("/vendor/three.module.js");
  const probe = document.createElement("canvas");
  if (!probe.getContext("webgl2")) throw new Error("this browser has no WebGL2");
  return THREE;
}

// Round shapes as polygons: thin ones (the task's wire and labels, under THIN_M of radius)
// with fewer sides, and thin capsules with one ring per cap, since a software WebGL's time
// goes with the triangles (about 1 us each on the 2-core machine; the seed path's wire at
// two rings per cap took 6.9 ms of a 22 ms left-eye frame, at one ring 4.1 ms). Its caps
// mostly sit inside the next segment's. A polygon of n sides drawn with its radius times
// n_radius(n) has the circle's mean width (perimeter / pi), so silhouettes keep their area.
const THIN_M = 0.0015;
const sides = (r) => (r < THIN_M ? 10 : 12);
const nRadius = (n) => Math.PI / (n * Math.sin(Math.PI / n));

function geometryOf(THREE, g) {
  const s = g.size;
  const n = sides(s[0]), r = s[0] * nRadius(n);
  switch (g.shape) {
    case "box": return new THREE.BoxGeometry(2 * s[0], 2 * s[1], 2 * s[2]);
    case "sphere": return new THREE.SphereGeometry(r, n, n - 4);
    case "ellipsoid": return new THREE.SphereGeometry(nRadius(12), 12, 8).scale(s[0], s[1], s[2]);
    // three.js's cylinders and capsules run along y, MuJoCo's along z: +90 deg about x.
    case "cylinder": return new THREE.CylinderGeometry(r, r, 2 * s[1], n).rotateX(Math.PI / 2);
    case "capsule": return new THREE.CapsuleGeometry(r, 2 * s[1], n < 12 ? 1 : 3, n).rotateX(Math.PI / 2);
    case "plane": return new THREE.PlaneGeometry(2 * s[0], 2 * s[1]);
    case "mesh": {
      const geometry = new THREE.BufferGeometry();
      geometry.setAttribute("position", new THREE.Float32BufferAttribute(g.vertices, 3));
      geometry.setIndex(g.faces);
      geometry.computeVertexNormals();
      return geometry;
    }
    default: return null;
  }
}

// The geoms of one body as one indexed geometry: positions and normals (already in the
// body's frame), each geom's colour (rgba) and material (specular, shininess x 128).
function mergeGeoms(THREE, items) {
  let nv = 0, ni = 0;
  for (const { geometry } of items) {
    nv += geometry.attributes.position.count;
    ni += geometry.index ? geometry.index.count : geometry.attributes.position.count;
  }
  const position = new Float32Array(3 * nv), normal = new Float32Array(3 * nv);
  const rgba = new Float32Array(4 * nv), material = new Float32Array(2 * nv);
  const geomId = new Float32Array(nv);
  const index = new Uint32Array(ni);
  let v0 = 0, i0 = 0;
  for (const { geometry, g } of items) {
    const n = geometry.attributes.position.count;
    position.set(geometry.attributes.position.array, 3 * v0);
    normal.set(geometry.attributes.normal.array, 3 * v0);
    for (let k = 0; k < n; k++) {
      rgba.set(g.rgba, 4 * (v0 + k));
      material[2 * (v0 + k)] = g.specular; material[2 * (v0 + k) + 1] = 128 * g.shininess;
      geomId[v0 + k] = g.id;
    }
    const idx = geometry.index ? geometry.index.array : Array.from({ length: n }, (_, k) => k);
    for (let k = 0; k < idx.length; k++) index[i0 + k] = idx[k] + v0;
    v0 += n; i0 += idx.length;
    geometry.dispose();
  }
  const merged = new THREE.BufferGeometry();
  merged.setAttribute("position", new THREE.BufferAttribute(position, 3));
  merged.setAttribute("normal", new THREE.BufferAttribute(normal, 3));
  merged.setAttribute("rgba", new THREE.BufferAttribute(rgba, 4));
  merged.setAttribute("material", new THREE.BufferAttribute(material, 2));
  merged.setAttribute("geomId", new THREE.BufferAttribute(geomId, 1));
  merged.setIndex(new THREE.BufferAttribute(index, 1));
  merged.computeBoundingSphere();
  return merged;
}

function setPose(object, values, offset) {
  object.position.set(values[offset], values[offset + 1], values[offset + 2]);
  // (MuJoCo's quaternions are w, x, y, z; three.js's x, y, z, w)
  object.quaternion.set(values[offset + 4], values[offset + 5], values[offset + 6], values[offset + 3]);
}

export class EndoscopeView {
  constructor(THREE, canvas, sceneMessage) {
    this.THREE = THREE;
    this.canvas = canvas;
    this.message = sceneMessage;
    THREE.ColorManagement.enabled = false;
    const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, powerPreference: "high-performance" });
    renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
    renderer.setPixelRatio(1);
    renderer.autoClear = false;
    this.renderer = renderer;
    const cam = sceneMessage.cameras[0];
    this.width = cam.width; this.height = cam.height;
    this.scene = new THREE.Scene();
    const haze = sceneMessage.haze;
    this.scene.background = new THREE.Color(haze[0], haze[1], haze[2]);
    this.bodies = new Map();
    for (const [id, pose] of Object.entries(sceneMessage.bodies)) {
      const group = new THREE.Group();
      setPose(group, pose, 0);
      this.scene.add(group);
      this.bodies.set(Number(id), group);
    }
    const lights = sceneLights(sceneMessage);
    this.lights = this.lightUniforms(lights);
    const vertexShader = vertexGlsl(lights);
    // One mesh per body and kind (opaque, transparent): its geoms merged in the body's frame,
    // with their colours and materials as vertex attributes. On Chromium's software WebGL a
    // left-eye frame took 25 ms so (24 draw calls) and 33 ms with the static geoms one mesh
    // each for finer culling (120 calls), measured on the 2-core machine.
    const parts = new Map();
    for (const g of sceneMessage.geoms) {
      const geometry = geometryOf(THREE, g);
      if (!geometry) continue;
      const local = new THREE.Object3D();
      setPose(local, [...g.pos, ...g.quat], 0);
      local.updateMatrix();
      geometry.applyMatrix4(local.matrix);
      const key = `${g.body}/${g.rgba[3] < 1 ? "t" : "o"}`;
      if (!parts.has(key)) parts.set(key, { body: g.body, transparent: g.rgba[3] < 1, items: [] });
      parts.get(key).items.push({ geometry, g });
    }
    for (const part of parts.values()) {
      const material = new THREE.ShaderMaterial({
        uniforms: this.lights,  // (shared: one update reaches every material)
        vertexShader, fragmentShader: FRAGMENT_GLSL,
        transparent: part.transparent,
      });
      const mesh = new THREE.Mesh(mergeGeoms(THREE, part.items), material);
      mesh.userData.geoms = part.items.map((item) => item.g.id);
      this.bodies.get(part.body).add(mesh);
    }
    this.moving = sceneMessage.layout.bodies.map((id) => this.bodies.get(id));
    this.cameras = sceneMessage.cameras.map((c) =>
      new THREE.PerspectiveCamera(c.fovy_deg, c.width / c.height, sceneMessage.znear, sceneMessage.zfar));
    this.time = null; this.tick = null; this.fresh = false;
    this.targets = null;
  }

  // The lights' uniforms (sceneLights' list: 0 is the headlight, its direction set per eye).
  lightUniforms(all) {
    const THREE = this.THREE;
    const vec = (f) => ({ value: all.map((l) => (l.active ? new THREE.Vector3(...f(l)) : new THREE.Vector3())) });
    return {
      nLights: { value: all.length },
      lightPos: { value: all.map(() => new THREE.Vector3()) },
      lightDir: { value: all.map(() => new THREE.Vector3(0, 0, -1)) },
      lightAmbient: vec((l) => l.ambient),
      lightDiffuse: vec((l) => l.diffuse),
      lightSpecular: vec((l) => l.specular),
      lightAttenuation: { value: all.map((l) => new THREE.Vector3(...l.attenuation)) },
      lightCosCutoff: { value: all.map((l) => Math.cos((Math.min(l.cutoff_deg, 180) * Math.PI) / 180)) },
      lightExponent: { value: all.map((l) => l.exponent) },
    };
  }

  // A pose message (ArrayBuffer): moving bodies, the two cameras, the lights.
  applyPoses(buffer) {
    const view = new DataView(buffer);
    this.tick = view.getUint32(4, true);
    this.time = view.getFloat64(8, true);
    const v = new Float32Array(buffer, POSE_HEADER_BYTES);
    let k = 0;
    for (const body of this.moving) { setPose(body, v, k); k += 7; }
    for (const camera of this.cameras) { setPose(camera, v, k); k += 7; }
    const { lightPos, lightDir, nLights } = this.lights;
    for (let j = 1; j < nLights.value; j++) {
      lightPos.value[j].set(v[k], v[k + 1], v[k + 2]);
      lightDir.value[j].set(v[k + 3], v[k + 4], v[k + 5]);
      k += 6;
    }
    this.fresh = true;
  }

  // Draw one eye (0 left, 1 right) into the current viewport or render target.
  renderEye(eye) {
    const camera = this.cameras[eye];
    camera.updateMatrixWorld();
    // (MuJoCo's headlight shines from the eye along its view)
    this.lights.lightDir.value[0].set(0, 0, -1).applyQuaternion(camera.quaternion);
    this.lights.lightPos.value[0].copy(camera.position);
    this.renderer.clear();
    this.renderer.render(this.scene, camera);
  }

  // Draw the view: "left", "sbs" (left | right) or "anaglyph" (red: the left eye's
  // luminance, green and blue: the right eye's, as the server-image path composes it).
  draw(mode) {
    const { renderer, width: w, height: h } = this;
    const cw = mode === "sbs" ? 2 * w : w;
    if (this.canvas.width !== cw || this.canvas.height !== h) renderer.setSize(cw, h, false);
    if (mode === "sbs") {
      renderer.setScissorTest(true);
      for (const eye of [0, 1]) {
        renderer.setViewport(eye * w, 0, w, h); renderer.setScissor(eye * w, 0, w, h);
        this.renderEye(eye);
      }
      renderer.setScissorTest(false);
    } else if (mode === "anaglyph") {
      this.drawAnaglyph();
    } else {
      renderer.setViewport(0, 0, w, h);
      this.renderEye(0);
    }
    this.fresh = false;
  }

  drawAnaglyph() {
    const THREE = this.THREE, { renderer, width: w, height: h } = this;
    if (!this.targets) {
      this.targets = [0, 1].map(() => new THREE.WebGLRenderTarget(w, h));
      this.compose = new THREE.ShaderMaterial({
        uniforms: { left: { value: this.targets[0].texture }, right: { value: this.targets[1].texture } },
        vertexShader: "varying vec2 uv0; void main() { uv0 = uv; gl_Position = vec4(position.xy, 0.0, 1.0); }",
        fragmentShader: `uniform sampler2D left; uniform sampler2D right; varying vec2 uv0;
          void main() { vec3 l = texture2D(left, uv0).rgb; vec3 r = texture2D(right, uv0).rgb;
            gl_FragColor = vec4(dot(l, vec3(0.299, 0.587, 0.114)), r.g, r.b, 1.0); }`,
        depthTest: false, depthWrite: false,
      });
      this.quadScene = new THREE.Scene();
      this.quadScene.add(new THREE.Mesh(new THREE.PlaneGeometry(2, 2), this.compose));
      this.quadCamera = new THREE.OrthographicCamera(-1, 1, 1, -1, 0, 1);
    }
    for (const eye of [0, 1]) {
      renderer.setRenderTarget(this.targets[eye]);
      renderer.setViewport(0, 0, w, h);
      this.renderEye(eye);
    }
    renderer.setRenderTarget(null);
    renderer.setViewport(0, 0, w, h);
    renderer.clear();
    renderer.render(this.quadScene, this.quadCamera);
  }

  // The geom id drawn at each pixel of eye (0 left, 1 right), -1 where none: an Int32Array,
  // rows from the image's top, as MuJoCo's segmentation render gives them.
  segmentation(eye = 0) {
    const THREE = this.THREE, { renderer, width: w, height: h } = this;
    const target = new THREE.WebGLRenderTarget(w, h);
    const material = new THREE.ShaderMaterial({ vertexShader: SEGMENT_VERTEX_GLSL, fragmentShader: FRAGMENT_GLSL });
    const background = this.scene.background;
    this.scene.background = new THREE.Color(0, 0, 0);
    this.scene.overrideMaterial = material;
    renderer.setRenderTarget(target);
    renderer.setViewport(0, 0, w, h);
    this.renderEye(eye);
    const pixels = new Uint8Array(4 * w * h);
    renderer.readRenderTargetPixels(target, 0, 0, w, h, pixels);
    renderer.setRenderTarget(null);
    this.scene.overrideMaterial = null; this.scene.background = background;
    target.dispose(); material.dispose();
    const ids = new Int32Array(w * h);
    for (let y = 0; y < h; y++) {
      const row = (h - 1 - y) * w;  // (GL's rows start at the bottom)
      for (let x = 0; x < w; x++) {
        const i = 4 * (row + x);
        ids[y * w + x] = pixels[i] + 256 * pixels[i + 1] - 1;
      }
    }
    return ids;
  }

  dispose() {
    this.renderer.dispose();
    for (const t of this.targets || []) t.dispose();
  }
}
