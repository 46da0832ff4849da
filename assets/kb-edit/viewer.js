// A small WebGL viewer of citygen's GLB: triangles with normals and a base colour per
// material, lit by one sun, turned with the mouse. Written for the kb editor (no library).
"use strict";

function Viewer(canvas) {
  const gl = canvas.getContext("webgl", { antialias: true, preserveDrawingBuffer: true });
  this.canvas = canvas;
  this.gl = gl;
  this.meshes = [];
  this.yaw = 0.7;
  this.pitch = 0.45;
  this.dist = 50;
  this.centre = [0, 0, 0];
  if (!gl) return;
  gl.getExtension("OES_element_index_uint");
  const vs = `attribute vec3 p; attribute vec3 n; uniform mat4 m; varying vec3 vn;
    void main() { vn = n; gl_Position = m * vec4(p, 1.0); }`;
  const fs = `precision mediump float; varying vec3 vn; uniform vec4 c;
    void main() { vec3 l = normalize(vec3(0.4, 0.8, 0.45));
      float d = 0.45 + 0.55 * max(dot(normalize(vn), l), 0.0);
      gl_FragColor = vec4(pow(c.rgb * d, vec3(1.0 / 2.2)), c.a); }`;
  const sh = (type, src) => {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    return s;
  };
  const prog = gl.createProgram();
  gl.attachShader(prog, sh(gl.VERTEX_SHADER, vs));
  gl.attachShader(prog, sh(gl.FRAGMENT_SHADER, fs));
  gl.linkProgram(prog);
  this.prog = prog;
  this.loc = {
    p: gl.getAttribLocation(prog, "p"),
    n: gl.getAttribLocation(prog, "n"),
    m: gl.getUniformLocation(prog, "m"),
    c: gl.getUniformLocation(prog, "c"),
  };
  let drag = null;
  canvas.addEventListener("mousedown", (e) => { drag = [e.clientX, e.clientY]; });
  window.addEventListener("mouseup", () => { drag = null; });
  window.addEventListener("mousemove", (e) => {
    if (!drag) return;
    this.yaw += (e.clientX - drag[0]) * 0.01;
    this.pitch = Math.max(-1.4, Math.min(1.4, this.pitch + (e.clientY - drag[1]) * 0.01));
    drag = [e.clientX, e.clientY];
    this.draw();
  });
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    this.dist *= Math.exp(e.deltaY * 0.001);
    this.draw();
  }, { passive: false });
}

// Reads a GLB (ArrayBuffer) and uploads its triangles.
Viewer.prototype.show = function (buf) {
  const gl = this.gl;
  if (!gl) return;
  const dv = new DataView(buf);
  if (dv.getUint32(0, true) !== 0x46546c67) throw new Error("not a GLB");
  const jsonLen = dv.getUint32(12, true);
  const doc = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 20, jsonLen)));
  const binStart = 20 + jsonLen + 8;
  const view = (acc, Type, comps) => {
    const bv = doc.bufferViews[acc.bufferView];
    const off = binStart + (bv.byteOffset || 0) + (acc.byteOffset || 0);
    return new Type(buf, off, acc.count * comps);
  };
  for (const m of this.meshes) { gl.deleteBuffer(m.pb); gl.deleteBuffer(m.nb); gl.deleteBuffer(m.ib); }
  this.meshes = [];
  const lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  for (const mesh of doc.meshes || []) {
    for (const prim of mesh.primitives) {
      if (prim.mode !== undefined && prim.mode !== 4) continue;
      const pa = doc.accessors[prim.attributes.POSITION];
      const na = doc.accessors[prim.attributes.NORMAL];
      const ia = doc.accessors[prim.indices];
      if (!pa || !na || !ia) continue;
      const pos = view(pa, Float32Array, 3);
      for (let i = 0; i < pos.length; i += 3)
        for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], pos[i + k]); hi[k] = Math.max(hi[k], pos[i + k]); }
      const idx = ia.componentType === 5125 ? view(ia, Uint32Array, 1) : view(ia, Uint16Array, 1);
      const mat = (doc.materials || [])[prim.material] || {};
      const c = ((mat.pbrMetallicRoughness || {}).baseColorFactor) || [0.8, 0.8, 0.8, 1];
      const pb = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, pb);
      gl.bufferData(gl.ARRAY_BUFFER, pos, gl.STATIC_DRAW);
      const nb = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, nb);
      gl.bufferData(gl.ARRAY_BUFFER, view(na, Float32Array, 3), gl.STATIC_DRAW);
      const ib = gl.createBuffer();
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ib);
      gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, idx, gl.STATIC_DRAW);
      this.meshes.push({ pb, nb, ib, count: idx.length, u32: ia.componentType === 5125, c });
    }
  }
  if (this.meshes.length) {
    this.centre = [0, 1, 2].map((k) => (lo[k] + hi[k]) / 2);
    const size = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
    this.dist = size * 1.2 + 5;
  }
  this.draw();
};

function mul(a, b) {
  const r = new Array(16).fill(0);
  for (let i = 0; i < 4; i++)
    for (let j = 0; j < 4; j++)
      for (let k = 0; k < 4; k++) r[j * 4 + i] += a[k * 4 + i] * b[j * 4 + k];
  return r;
}

Viewer.prototype.draw = function () {
  const gl = this.gl;
  if (!gl) return;
  const w = this.canvas.width, h = this.canvas.height;
  gl.viewport(0, 0, w, h);
  gl.clearColor(0.86, 0.9, 0.95, 1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  gl.enable(gl.DEPTH_TEST);
  if (!this.meshes.length) return;
  const f = 1 / Math.tan(0.5), near = this.dist * 0.02, far = this.dist * 10;
  const proj = [f * h / w, 0, 0, 0, 0, f, 0, 0, 0, 0, (far + near) / (near - far), -1, 0, 0, 2 * far * near / (near - far), 0];
  const cy = Math.cos(this.yaw), sy = Math.sin(this.yaw), cp = Math.cos(this.pitch), sp = Math.sin(this.pitch);
  // Rotate about Y (yaw) then X (pitch), push back by dist, around the centre.
  const ry = [cy, 0, -sy, 0, 0, 1, 0, 0, sy, 0, cy, 0, 0, 0, 0, 1];
  const rx = [1, 0, 0, 0, 0, cp, sp, 0, 0, -sp, cp, 0, 0, 0, 0, 1];
  const t = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -this.centre[0], -this.centre[1], -this.centre[2], 1];
  const back = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, -this.dist, 1];
  const m = mul(proj, mul(back, mul(rx, mul(ry, t))));
  gl.useProgram(this.prog);
  gl.uniformMatrix4fv(this.loc.m, false, new Float32Array(m));
  for (const s of this.meshes) {
    gl.uniform4fv(this.loc.c, s.c);
    gl.bindBuffer(gl.ARRAY_BUFFER, s.pb);
    gl.enableVertexAttribArray(this.loc.p);
    gl.vertexAttribPointer(this.loc.p, 3, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ARRAY_BUFFER, s.nb);
    gl.enableVertexAttribArray(this.loc.n);
    gl.vertexAttribPointer(this.loc.n, 3, gl.FLOAT, false, 0, 0);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, s.ib);
    gl.drawElements(gl.TRIANGLES, s.count, s.u32 ? gl.UNSIGNED_INT : gl.UNSIGNED_SHORT, 0);
  }
};
