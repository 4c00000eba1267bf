// The page's 3D picture: a sphere frame (sandbox/render/sphere_frame.py) drawn with WebGL2 as the sandbox's renderer
// draws it (sandbox/render/spheres.py): each particle projected through the frame's pinhole camera, a disc of
// max(radius x focal / depth, R_MIN) pixels over the pixels whose centres lie on it, the sphere's front surface
// depth-tested per pixel, shaded (ambient 0.3, diffuse, a specular highlight) or flat. One instanced draw a frame.
"use strict";

const SPHERE_HEADER = 21;  // b"S", frame, seq, time, n
const SPHERE_CAMERA = 80;  // 20 f32
const SPHERE_RECORD = 20;  // x, y, z, r (f32), RGBA (u8 x 4)
const DEPTH_SCALE = 64.0;  // world units: depth z is stored as z / (z + DEPTH_SCALE), in order and within [0, 1)

const sphereVertex = `#version 300 es
in vec2 corner;
in vec3 pos;
in float rad;
in vec4 col;
uniform vec3 eye, right, up, fwd;
uniform float focal, rmin;
uniform vec2 axis, size;
out vec2 vCentre;
out float vR, vZ, vRad;
out vec4 vCol;
void main() {
  vec3 rel = pos - eye;
  float z = dot(rel, fwd);
  float zc = max(z, 1e-6);
  vec2 centre = axis + focal * vec2(dot(rel, right), dot(rel, up)) / zc;
  float r = max(abs(rad) * focal / zc, rmin);
  vCentre = centre; vR = r; vZ = z; vRad = rad; vCol = col;
  vec2 p = centre + corner * (r + 1.0);
  gl_Position = z > 1e-3 ? vec4(p / size * 2.0 - 1.0, 0.0, 1.0) : vec4(2.0, 2.0, 2.0, 1.0);
}`;

const sphereFragment = `#version 300 es
precision highp float;
in vec2 vCentre;
in float vR, vZ, vRad;
in vec4 vCol;
uniform vec3 right, up, fwd, light;
uniform float specular, depthScale;
out vec4 colour;
void main() {
  vec2 u = (gl_FragCoord.xy - vCentre) / vR;
  float q = dot(u, u);
  if (q > 1.0) discard;
  float nz = sqrt(1.0 - q);
  float zs = max(vZ - abs(vRad) * nz, 0.0);
  gl_FragDepth = zs / (zs + depthScale);
  vec3 c = vCol.rgb;
  if (vRad > 0.0) {
    vec3 normal = u.x * right + u.y * up - nz * fwd;
    float diffuse = max(dot(normal, light), 0.0);
    float highlight = pow(max(dot(normal, normalize(light - fwd)), 0.0), 32.0);
    c = c * (0.3 + 0.7 * diffuse) + specular * highlight;
  }
  colour = vec4(clamp(c, 0.0, 1.0), 1.0);
}`;

let sphereGL = null;  // {canvas, gl, program, records, where}; false: this browser has no WebGL2

function sphereSetup() {
  const canvas = document.createElement("canvas");
  const gl = canvas.getContext("webgl2", { antialias: false, depth: true, premultipliedAlpha: true, preserveDrawingBuffer: true });
  if (!gl) return false;
  const shader = (type, source) => {
    const s = gl.createShader(type);
    gl.shaderSource(s, source);
    gl.compileShader(s);
    return s;
  };
  const program = gl.createProgram();
  gl.attachShader(program, shader(gl.VERTEX_SHADER, sphereVertex));
  gl.attachShader(program, shader(gl.FRAGMENT_SHADER, sphereFragment));
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) return false;
  gl.useProgram(program);
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  const corners = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, corners);
  gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([-1, -1, 1, -1, -1, 1, 1, 1]), gl.STATIC_DRAW);
  const at = (name) => gl.getAttribLocation(program, name);
  gl.enableVertexAttribArray(at("corner"));
  gl.vertexAttribPointer(at("corner"), 2, gl.FLOAT, false, 0, 0);
  const records = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, records);
  for (const [name, size, type, normalized, offset] of [["pos", 3, gl.FLOAT, false, 0], ["rad", 1, gl.FLOAT, false, 12], ["col", 4, gl.UNSIGNED_BYTE, true, 16]]) {
    gl.enableVertexAttribArray(at(name));
    gl.vertexAttribPointer(at(name), size, type, normalized, SPHERE_RECORD, offset);
    gl.vertexAttribDivisor(at(name), 1);
  }
  const where = {};
  for (const name of ["eye", "right", "up", "fwd", "focal", "rmin", "axis", "size", "light", "specular", "depthScale"]) {
    where[name] = gl.getUniformLocation(program, name);
  }
  gl.enable(gl.DEPTH_TEST);
  gl.depthFunc(gl.LESS);
  return { canvas, gl, records, where };
}

// The spheres of the sphere frame in `buffer` on a transparent canvas of width x height pixels, to draw over the
// picture without its particles; null where the browser has no WebGL2 (the page then asks for pictures).
function drawSpheres(buffer, width, height) {
  if (sphereGL === null) sphereGL = sphereSetup();
  if (!sphereGL) return null;
  const { canvas, gl, records, where } = sphereGL;
  if (canvas.width !== width || canvas.height !== height) { canvas.width = width; canvas.height = height; }
  const n = new DataView(buffer).getUint32(17, true);
  const cam = new Float32Array(buffer.slice(SPHERE_HEADER, SPHERE_HEADER + SPHERE_CAMERA));
  gl.uniform3fv(where.eye, cam.subarray(0, 3));
  gl.uniform3fv(where.right, cam.subarray(3, 6));
  gl.uniform3fv(where.up, cam.subarray(6, 9));
  gl.uniform3fv(where.fwd, cam.subarray(9, 12));
  gl.uniform1f(where.focal, cam[12]);
  gl.uniform2f(where.axis, cam[13], cam[14]);
  gl.uniform3fv(where.light, cam.subarray(15, 18));
  gl.uniform1f(where.specular, cam[18]);
  gl.uniform1f(where.rmin, cam[19]);
  gl.uniform2f(where.size, width, height);
  gl.uniform1f(where.depthScale, DEPTH_SCALE);
  gl.viewport(0, 0, width, height);
  gl.clearColor(0, 0, 0, 0);
  gl.clearDepth(1.0);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  const start = SPHERE_HEADER + SPHERE_CAMERA;
  gl.bindBuffer(gl.ARRAY_BUFFER, records);
  gl.bufferData(gl.ARRAY_BUFFER, new Uint8Array(buffer, start, SPHERE_RECORD * n), gl.STREAM_DRAW);
  if (n) gl.drawArraysInstanced(gl.TRIANGLE_STRIP, 0, 4, n);
  return canvas;
}
