// The page's 3D picture: a sphere frame (sandbox/render/sphere_frame.py) drawn with WebGL2 as the sandbox's renderer
// draws it (sandbox/render/spheres.py): the picture without its particles (a texture), the lid where the scene has
// one (the box's cross-section at its height tinted, its outline drawn at its depth), then each particle projected
// through the frame's pinhole camera, a disc of max(radius x focal / depth, R_MIN) pixels over the pixels whose
// centres lie on it, the sphere's front surface depth-tested per pixel, shaded (ambient 0.3, diffuse, a specular
// highlight) or flat. Two draws a frame: a full-screen pass and one instanced draw of every sphere.
"use strict";

const SPHERE_HEADER = 21;  // b"S", frame, seq, time, n
const SPHERE_CAMERA = 144;  // 36 f32
const SPHERE_RECORD = 12;  // x, y, z, r (u16: 65,535ths of the span and of the largest radius), R, G, B, shaded (u8)
const DEPTH_SCALE = 64.0;  // world units: depth z is stored as z / (z + DEPTH_SCALE), in order and within [0, 1)

const sphereVertex = `#version 300 es
in vec2 corner;
in vec3 place;
in float size01;
in vec4 col;
uniform vec3 eye, right, up, fwd, spanLo, span;
uniform float focal, rmin, rMax;
uniform vec2 axis, size;
out vec2 vCentre;
out float vR, vZ, vRad;
out vec4 vCol;
void main() {
  vec3 pos = spanLo + place * span;
  float rad = col.a > 0.5 ? size01 * rMax : -size01 * rMax;  // negative: drawn flat
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

// The picture under the spheres: the backdrop (top row first in the texture), and the lid at its height where on.
const backdropVertex = `#version 300 es
void main() {
  vec2 corner = vec2(float((gl_VertexID & 1) * 4 - 1), float((gl_VertexID & 2) * 2 - 1));
  gl_Position = vec4(corner, 0.0, 1.0);
}`;

const backdropFragment = `#version 300 es
precision highp float;
uniform sampler2D under;
uniform vec3 eye, right, up, fwd, lidColour;
uniform float focal, lidOn, lidHeight, depthScale;
uniform vec2 axis, size;
uniform vec4 box;
out vec4 colour;
void main() {
  ivec2 px = ivec2(gl_FragCoord.xy);
  vec3 c = texelFetch(under, ivec2(px.x, int(size.y) - 1 - px.y), 0).rgb;
  float depth = 1.0;
  if (lidOn > 0.5) {
    vec3 ray = normalize(fwd * focal + right * (gl_FragCoord.x - axis.x) + up * (gl_FragCoord.y - axis.y));
    if (abs(ray.y) > 1e-6) {
      float s = (lidHeight - eye.y) / ray.y;
      vec2 u = (eye + s * ray).xz;
      if (s > 0.0 && all(greaterThanEqual(u, box.xy)) && all(lessThanEqual(u, box.zw))) {
        float edge = min(min(u.x - box.x, u.y - box.y), min(box.z - u.x, box.w - u.y));
        c = c * 0.85 + 0.1;
        if (edge < 1.5 * s / focal) {
          c = lidColour;
          float z = s * dot(ray, fwd);
          depth = z / (z + depthScale);
        }
      }
    }
  }
  gl_FragDepth = depth;
  colour = vec4(c, 1.0);
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
  const link = (vertex, fragment) => {
    const p = gl.createProgram();
    gl.attachShader(p, shader(gl.VERTEX_SHADER, vertex));
    gl.attachShader(p, shader(gl.FRAGMENT_SHADER, fragment));
    gl.linkProgram(p);
    return gl.getProgramParameter(p, gl.LINK_STATUS) ? p : null;
  };
  const program = link(sphereVertex, sphereFragment), backdrop = link(backdropVertex, backdropFragment);
  if (!program || !backdrop) return false;
  const texture = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, texture);
  for (const [key, value] of [[gl.TEXTURE_MIN_FILTER, gl.NEAREST], [gl.TEXTURE_MAG_FILTER, gl.NEAREST]]) gl.texParameteri(gl.TEXTURE_2D, key, value);
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
  for (const [name, size, type, offset] of [["place", 3, gl.UNSIGNED_SHORT, 0], ["size01", 1, gl.UNSIGNED_SHORT, 6], ["col", 4, gl.UNSIGNED_BYTE, 8]]) {
    gl.enableVertexAttribArray(at(name));
    gl.vertexAttribPointer(at(name), size, type, true, SPHERE_RECORD, offset);
    gl.vertexAttribDivisor(at(name), 1);
  }
  const where = {}, backWhere = {};
  for (const name of ["eye", "right", "up", "fwd", "focal", "rmin", "axis", "size", "light", "specular", "depthScale", "spanLo", "span", "rMax"]) {
    where[name] = gl.getUniformLocation(program, name);
  }
  for (const name of ["under", "eye", "right", "up", "fwd", "focal", "axis", "size", "lidOn", "lidHeight", "box", "lidColour", "depthScale"]) {
    backWhere[name] = gl.getUniformLocation(backdrop, name);
  }
  gl.enable(gl.DEPTH_TEST);
  gl.depthFunc(gl.LESS);
  const empty = gl.createVertexArray();
  return { canvas, gl, records, where, program, backdrop, backWhere, vao, empty, texture, uploaded: -1 };
}

// The camera's uniforms, from the frame's camera block `cam` (Float32Array), into the program at `where`.
function sphereCamera(gl, where, cam, width, height) {
  gl.uniform3fv(where.eye, cam.subarray(0, 3));
  gl.uniform3fv(where.right, cam.subarray(3, 6));
  gl.uniform3fv(where.up, cam.subarray(6, 9));
  gl.uniform3fv(where.fwd, cam.subarray(9, 12));
  gl.uniform1f(where.focal, cam[12]);
  gl.uniform2f(where.axis, cam[13], cam[14]);
  gl.uniform2f(where.size, width, height);
  gl.uniform1f(where.depthScale, DEPTH_SCALE);
}

// The picture of the sphere frame in `buffer` over `under` (a canvas: the picture without its particles, changed
// whenever `version` changes), on a canvas of the same size; null where the browser has no WebGL2 (the page then
// asks for pictures).
function drawSpheres(buffer, under, version) {
  if (sphereGL === null) sphereGL = sphereSetup();
  if (!sphereGL) return null;
  const { canvas, gl, records, where, backWhere } = sphereGL;
  const [width, height] = [under.width, under.height];
  if (canvas.width !== width || canvas.height !== height) { canvas.width = width; canvas.height = height; }
  if (sphereGL.uploaded !== version) {
    gl.bindTexture(gl.TEXTURE_2D, sphereGL.texture);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, under);
    sphereGL.uploaded = version;
  }
  const n = new DataView(buffer).getUint32(17, true);
  const cam = new Float32Array(buffer.slice(SPHERE_HEADER, SPHERE_HEADER + SPHERE_CAMERA));
  gl.viewport(0, 0, width, height);
  gl.clearDepth(1.0);
  gl.clear(gl.DEPTH_BUFFER_BIT);
  gl.depthFunc(gl.ALWAYS);  // the backdrop pass writes every pixel and the lid outline's depth
  gl.useProgram(sphereGL.backdrop);
  sphereCamera(gl, backWhere, cam, width, height);
  gl.uniform1i(backWhere.under, 0);
  gl.uniform1f(backWhere.lidOn, cam[20]);
  gl.uniform1f(backWhere.lidHeight, cam[21]);
  gl.uniform4fv(backWhere.box, cam.subarray(22, 26));
  gl.uniform3fv(backWhere.lidColour, cam.subarray(26, 29));
  gl.bindVertexArray(sphereGL.empty);  // no attributes: the pass makes its corners from gl_VertexID
  gl.drawArrays(gl.TRIANGLES, 0, 3);
  gl.depthFunc(gl.LESS);
  gl.useProgram(sphereGL.program);
  sphereCamera(gl, where, cam, width, height);
  gl.uniform3fv(where.light, cam.subarray(15, 18));
  gl.uniform1f(where.specular, cam[18]);
  gl.uniform1f(where.rmin, cam[19]);
  gl.uniform3fv(where.spanLo, cam.subarray(29, 32));
  gl.uniform3fv(where.span, cam.subarray(32, 35));
  gl.uniform1f(where.rMax, cam[35]);
  gl.bindVertexArray(sphereGL.vao);
  const start = SPHERE_HEADER + SPHERE_CAMERA;
  gl.bindBuffer(gl.ARRAY_BUFFER, records);
  gl.bufferData(gl.ARRAY_BUFFER, new Uint8Array(buffer, start, SPHERE_RECORD * n), gl.STREAM_DRAW);
  if (n) gl.drawArraysInstanced(gl.TRIANGLE_STRIP, 0, 4, n);
  return canvas;
}
