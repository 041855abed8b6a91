// A small WebGL2 renderer for the player: one triangle mesh with vertex normals (headlight
// Lambert shading, flat grey or a texture), an optional wireframe overlay, an orbit camera.
//
// Contract: `new Renderer(canvas)`; `setMesh({positions, normals, faces, uvs?})` uploads a
// frame; `setTexture(source|null)` takes anything texImage2D takes (a VideoFrame, a canvas);
// `draw()` renders with the current camera; `fit(lo, hi, front)` frames a box from a side,
// `orbit(dx, dy)` and `zoom(f)` move it; `project(point)` gives a point's normalized device
// coordinates (what the tests check the framing with).
// Throws if the browser has no WebGL2.

const VS = `#version 300 es
in vec3 position; in vec3 normal; in vec2 uv;
uniform mat4 mvp; uniform mat4 view; uniform vec3 target;
out vec3 vnormal; out vec2 vuv;
void main() { vnormal = mat3(view) * normal; vuv = uv; gl_Position = mvp * vec4(position - target, 1.0); }`;

const FS = `#version 300 es
precision highp float;
in vec3 vnormal; in vec2 vuv;
uniform int mode; uniform sampler2D tex; uniform vec3 colour;
out vec4 out_colour;
void main() {
  if (mode == 2) { out_colour = vec4(colour, 1.0); return; }
  float light = 0.25 + 0.75 * abs(normalize(vnormal).z);
  vec3 base = mode == 1 ? texture(tex, vuv).rgb : vec3(0.78, 0.8, 0.84);
  out_colour = vec4(base * (mode == 1 ? 0.55 + 0.45 * light : light), 1.0);
}`;

/** Vertical field of view (radians), and how much larger than the sequence's box the view is
 * made when framing it. */
const FOV = 0.8;
const MARGIN = 1.1;

function compile(gl, type, source) {
  const s = gl.createShader(type);
  gl.shaderSource(s, source);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
}

/** Column-major 4x4 products and the camera matrices. */
function multiply(a, b) {
  const o = new Float32Array(16);
  for (let c = 0; c < 4; c++) for (let r = 0; r < 4; r++) {
    let s = 0;
    for (let k = 0; k < 4; k++) s += a[k * 4 + r] * b[c * 4 + k];
    o[c * 4 + r] = s;
  }
  return o;
}

function perspective(fovy, aspect, near, far) {
  const f = 1 / Math.tan(fovy / 2);
  const o = new Float32Array(16);
  o[0] = f / aspect; o[5] = f; o[10] = (far + near) / (near - far); o[11] = -1; o[14] = (2 * far * near) / (near - far);
  return o;
}

/** View matrix of a camera at `distance` from the origin, turned by yaw and pitch. */
function orbitView(yaw, pitch, distance) {
  const cy = Math.cos(yaw), sy = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch);
  // Rows of the rotation: right, up, back (camera axes in world coordinates).
  const r = [cy, 0, -sy], u = [sy * sp, cp, cy * sp], b = [sy * cp, -sp, cy * cp];
  return new Float32Array([r[0], u[0], b[0], 0, r[1], u[1], b[1], 0, r[2], u[2], b[2], 0, 0, 0, -distance, 1]);
}

export class Renderer {
  /** @param {HTMLCanvasElement} canvas */
  constructor(canvas) {
    const gl = canvas.getContext('webgl2', { antialias: true, preserveDrawingBuffer: true });
    if (!gl) throw new Error('this browser has no WebGL2');
    this.gl = gl;
    this.canvas = canvas;
    const p = gl.createProgram();
    gl.attachShader(p, compile(gl, gl.VERTEX_SHADER, VS));
    gl.attachShader(p, compile(gl, gl.FRAGMENT_SHADER, FS));
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
    this.program = p;
    this.loc = Object.fromEntries(['mvp', 'view', 'mode', 'tex', 'colour', 'target'].map((n) => [n, gl.getUniformLocation(p, n)]));
    this.vao = gl.createVertexArray();
    this.buffers = { position: gl.createBuffer(), normal: gl.createBuffer(), uv: gl.createBuffer(), index: gl.createBuffer(), edges: gl.createBuffer() };
    this.texture = null;
    this.count = 0;
    this.edgeCount = 0;
    this.wireframe = false;
    this.yaw = 0.6; this.pitch = -0.35; this.distance = 3; this.radius = 1; this.target = [0, 0, 0];
    gl.enable(gl.DEPTH_TEST);
  }

  /**
   * Aims the camera at the centre of the box `lo`..`hi` from the side of the horizontal
   * direction `front` (y is up), a little above, and backs it off until every corner is
   * inside the view with a margin (the vertical extent of a standing person included).
   */
  fit(lo, hi, front = [0, 0, 1]) {
    this.target = lo.map((l, k) => (l + hi[k]) / 2);
    this.radius = Math.max(1e-9, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
    this.yaw = Math.atan2(front[0], front[2]);
    this.pitch = -0.15;
    const rotation = orbitView(this.yaw, this.pitch, 0);
    const t = Math.tan(FOV / 2) / MARGIN, aspect = this.aspect();
    let distance = 0;
    for (let c = 0; c < 8; c++) {
      const p = [0, 1, 2].map((k) => ((c >> k) & 1 ? hi[k] : lo[k]) - this.target[k]);
      const [x, y, z] = [0, 1, 2].map((r) => rotation[r] * p[0] + rotation[4 + r] * p[1] + rotation[8 + r] * p[2]);
      // In camera coordinates the corner is (x, y) at depth distance - z.
      distance = Math.max(distance, z + Math.abs(y) / t, z + Math.abs(x) / (t * aspect));
    }
    this.distance = Math.max(distance, 1e-9);
  }

  aspect() {
    return Math.max(1, this.canvas.clientWidth) / Math.max(1, this.canvas.clientHeight);
  }

  /** The camera's projection times view (column-major). */
  matrix() {
    const proj = perspective(FOV, this.aspect(), this.distance / 100, this.distance + 4 * this.radius);
    return multiply(proj, orbitView(this.yaw, this.pitch, this.distance));
  }

  /** Normalized device coordinates [x, y] of a point (within [-1, 1] when in view). */
  project(point) {
    const m = this.matrix(), p = point.map((v, k) => v - this.target[k]);
    const [x, y, , w] = [0, 1, 2, 3].map((r) => m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r]);
    return [x / w, y / w];
  }

  setMesh(mesh) {
    const gl = this.gl, b = this.buffers;
    gl.bindVertexArray(this.vao);
    const attribute = (buffer, name, data, size) => {
      const loc = gl.getAttribLocation(this.program, name);
      if (loc < 0) return;
      if (!data) { gl.disableVertexAttribArray(loc); return; }
      gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
      gl.bufferData(gl.ARRAY_BUFFER, data, gl.DYNAMIC_DRAW);
      gl.enableVertexAttribArray(loc);
      gl.vertexAttribPointer(loc, size, gl.FLOAT, false, 0, 0);
    };
    attribute(b.position, 'position', mesh.positions, 3);
    attribute(b.normal, 'normal', mesh.normals, 3);
    attribute(b.uv, 'uv', mesh.uvs, 2);
    this.hasUvs = Boolean(mesh.uvs);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, b.index);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, mesh.faces, gl.DYNAMIC_DRAW);
    this.count = mesh.faces.length;
    gl.bindVertexArray(null);
    const edges = new Uint32Array(2 * mesh.faces.length);
    for (let t = 0; t < mesh.faces.length; t += 3) {
      for (let k = 0; k < 3; k++) { edges[2 * (t + k)] = mesh.faces[t + k]; edges[2 * (t + k) + 1] = mesh.faces[t + (k + 1) % 3]; }
    }
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, b.edges);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, edges, gl.DYNAMIC_DRAW);
    this.edgeCount = edges.length;
  }

  /** Texture image for the current mesh's UVs, or null for none. */
  setTexture(source) {
    const gl = this.gl;
    if (source === null) { this.textured = false; return; }
    if (!this.texture) this.texture = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, this.texture);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, source);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
    this.textured = true;
  }

  orbit(dx, dy) {
    this.yaw += dx * 0.01;
    this.pitch = Math.max(-1.5, Math.min(1.5, this.pitch + dy * 0.01));
  }

  zoom(factor) {
    this.distance = Math.max(0.2 * this.radius, Math.min(20 * this.radius, this.distance * factor));
  }

  draw() {
    const gl = this.gl, c = this.canvas;
    const w = Math.max(1, Math.floor(c.clientWidth * devicePixelRatio)), h = Math.max(1, Math.floor(c.clientHeight * devicePixelRatio));
    if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
    gl.viewport(0, 0, w, h);
    gl.clearColor(0.125, 0.141, 0.169, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (!this.count) return;
    const view = orbitView(this.yaw, this.pitch, this.distance);
    gl.useProgram(this.program);
    gl.uniformMatrix4fv(this.loc.mvp, false, this.matrix());
    gl.uniformMatrix4fv(this.loc.view, false, view);
    gl.uniform3fv(this.loc.target, this.target);
    gl.bindVertexArray(this.vao);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.buffers.index);
    const textured = this.textured && this.hasUvs;
    if (textured) { gl.activeTexture(gl.TEXTURE0); gl.bindTexture(gl.TEXTURE_2D, this.texture); gl.uniform1i(this.loc.tex, 0); }
    gl.uniform1i(this.loc.mode, textured ? 1 : 0);
    gl.enable(gl.POLYGON_OFFSET_FILL);
    gl.polygonOffset(1, 1);
    gl.drawElements(gl.TRIANGLES, this.count, gl.UNSIGNED_INT, 0);
    gl.disable(gl.POLYGON_OFFSET_FILL);
    if (this.wireframe) {
      gl.uniform1i(this.loc.mode, 2);
      gl.uniform3f(this.loc.colour, 0.1, 0.35, 0.75);
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.buffers.edges);
      gl.drawElements(gl.LINES, this.edgeCount, gl.UNSIGNED_INT, 0);
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.buffers.index);
    }
    gl.bindVertexArray(null);
  }
}
